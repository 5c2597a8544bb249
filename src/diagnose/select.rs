//! The diagnosis: is the nominal model's misfit beyond the noise (chi-square with known sigma, lack-of-fit
//! F test with repeats)? Which candidate effects are identifiable on this data, how well does each explain
//! it (fit, SSR, BIC, extra-sum-of-squares F test, parameters with standard errors), and which to accept,
//! forward stepwise up to three: F test significant at alpha / (number of candidates), delta BIC < -10,
//! plausible values at least 3 standard errors from neutral, and a better leave-pose-out prediction.
//! Verdicts: `effect`, `none`, `ambiguous` (two candidates the data cannot tell apart), `unexplained`.

use nalgebra::{DMatrix, DVector};
use statrs::distribution::{ChiSquared, ContinuousCDF, FisherSnedecor};

use super::data::Dataset;
use super::error::{DiagnoseError, PoseError};
use super::fit::{effects_of, fit, jacobian, Candidate, Fit, Problem};
use crate::kinematics::frame::{Vec3, Vec6};
use crate::model::effect::{Effect, Kind, Target};

/// How the selection runs.
#[derive(Clone, Debug)]
pub struct Options {
    /// Significance level (candidates are tested at alpha / their number).
    pub alpha: f64,
    /// Predictions follow the loaded equilibrium.
    pub loaded: bool,
    /// Most effects named.
    pub max_effects: usize,
}

impl Default for Options {
    fn default() -> Self {
        Options { alpha: 0.01, loaded: false, max_effects: 3 }
    }
}

/// Where the noise level comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum SigmaSource {
    /// The data's sigma_mm column.
    Column,
    /// Given with the command (the noise level of the instrument).
    Given,
    /// Pooled from repeated rows (same pose and wrench): degrees of freedom of the pure error.
    Repeats {
        /// Degrees of freedom of the pure error.
        dof: usize,
    },
}

/// What the diagnosis concludes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Effects explain the discrepancy.
    Effect,
    /// The nominal model is within the noise.
    None,
    /// Two candidates explain it equally well.
    Ambiguous,
    /// Something is left that no candidate explains.
    Unexplained,
}

impl Verdict {
    /// The verdict's name in reports and JSON.
    pub fn as_str(self) -> &'static str {
        match self {
            Verdict::Effect => "effect",
            Verdict::None => "none",
            Verdict::Ambiguous => "ambiguous",
            Verdict::Unexplained => "unexplained",
        }
    }
}

/// One candidate evaluated at one step (added to the effects accepted before it).
#[derive(Clone, Debug)]
pub struct CandidateRow {
    /// `NAME[:TARGET]`.
    pub label: String,
    /// Number of parameters.
    pub dim: usize,
    /// Whether the data can fix its parameters.
    pub identifiable: bool,
    /// Why not identifiable, or empty.
    pub note: String,
    /// Condition number of its signature.
    pub condition: f64,
    /// Share of the signature outside what the accepted effects already explain (0..1).
    pub orthogonal: f64,
    /// Weighted sum of squared residuals with it.
    pub ssr: f64,
    /// Delta BIC against the model without it.
    pub delta_bic: f64,
    /// Its F statistic.
    pub f: f64,
    /// The F test's p-value.
    pub p_value: f64,
    /// Fitted values.
    pub values: Vec<f64>,
    /// Their standard errors.
    pub se: Vec<f64>,
    /// Physically possible values.
    pub plausible: bool,
    /// Some value at least `SIGNIFICANT_T` standard errors from neutral.
    pub significant_params: bool,
    /// Passes every test.
    pub passes: bool,
    /// How the residuals change when this candidate is fitted (for parallel-signature checks).
    change: DVector<f64>,
    candidate: Candidate,
    fit: Option<Fit>,
}

/// An accepted effect.
#[derive(Clone, Debug)]
pub struct Accepted {
    /// The effect with its fitted values.
    pub effect: Effect,
    /// For leg-geometry: the directions of eps the data sees (6 x r), in which `params` are coordinates.
    pub basis: Option<DMatrix<f64>>,
    /// `NAME[:TARGET]`.
    pub label: String,
    /// Fitted parameters (coordinates for leg-geometry) with standard errors.
    pub params: Vec<f64>,
    /// Standard errors of `params`.
    pub se: Vec<f64>,
    /// The F test's p-value when accepted.
    pub p_value: f64,
    /// Delta BIC when accepted.
    pub delta_bic: f64,
}

/// The outcome of `diagnose`.
#[derive(Clone, Debug)]
pub struct Diagnosis {
    /// The verdict.
    pub verdict: Verdict,
    /// The noise level used, mm.
    pub sigma: f64,
    /// Where it comes from.
    pub sigma_source: SigmaSource,
    /// Measurement rows.
    pub rows: usize,
    /// Observations (three per row).
    pub observations: usize,
    /// Nominal test statistic and p-value (chi-square, or lack-of-fit F with repeats).
    pub nominal_statistic: f64,
    /// The nominal test's p-value.
    pub nominal_p: f64,
    /// The effects accepted, in order.
    pub accepted: Vec<Accepted>,
    /// Candidate table of the first step (each candidate alone against the nominal model).
    pub table: Vec<CandidateRow>,
    /// For `ambiguous`: the two candidates, and where their predictions differ most (advice).
    pub ambiguous: Option<(String, String, String)>,
    /// Residual RMS per axis (mm) on the data, before and after the accepted effects.
    pub rms_before: Vec3,
    /// After the accepted effects.
    pub rms_after: Vec3,
    /// Leave-pose-out residual RMS per axis (mm): nominal, and with the accepted effects refitted
    /// without the held-out pose.
    pub heldout_before: Vec3,
    /// Held-out, with the accepted effects refitted.
    pub heldout_after: Vec3,
    /// p-value of the residuals left after the accepted effects.
    pub final_p: f64,
    /// Per pose: its position, and the residual (mm) of its row with the largest nominal residual, before and
    /// after the accepted effects (for the picture).
    pub per_pose: Vec<(Vec3, Vec3, Vec3)>,
}

/// The candidates for this model and data (leg-geometry restricted to what the data can see).
pub fn candidates(problem: &Problem, loaded: bool) -> Vec<Candidate> {
    let m = problem.model;
    let mut out = Vec::new();
    for k in 0..m.legs.len() {
        if m.legs[k].has_actuator_spring() {
            out.push(Candidate { kind: Kind::ActuatorCompliance, target: Target::Leg(k), basis: None });
        }
    }
    for g in m.link_spring_groups() {
        out.push(Candidate { kind: Kind::LinkCompliance, target: Target::Group(g), basis: None });
    }
    out.push(Candidate { kind: Kind::Gravity, target: Target::None, basis: None });
    let all: Vec<usize> = (0..problem.data.rows.len()).collect();
    for k in 0..m.legs.len() {
        if let Some(basis) = visible_end_errors(problem, k, &all) {
            out.push(Candidate { kind: Kind::LegGeometry, target: Target::Leg(k), basis: Some(basis) });
        }
    }
    for k in 0..m.legs.len() {
        if m.legs[k].has_actuator_spring() {
            out.push(Candidate { kind: Kind::Preload, target: Target::Leg(k), basis: None });
            out.push(Candidate { kind: Kind::Backlash, target: Target::Leg(k), basis: None });
        }
    }
    if !loaded {
        out.push(Candidate { kind: Kind::LoadedNonlinearity, target: Target::None, basis: None });
    }
    out.push(Candidate { kind: Kind::ToolOffset, target: Target::None, basis: None });
    // A candidate that changes no prediction cannot be named by any data of this design (a compliance
    // factor where no row is loaded, backlash where no actuator carries load): not offered.
    out.retain(|c| has_signature(problem, c, &all));
    out
}

// The thresholds of selection, each with its reason.

/// A signature (weighted residuals per unit parameter) below this times sqrt(observations) is none: its
/// effect would need values beyond any physical size to move a residual by one sigma.
const NO_SIGNATURE: f64 = 1e-9;
/// A signature whose columns are this ill-conditioned cannot fix all the candidate's parameters.
const RANK_DEFICIENT: f64 = 1e8;
/// A candidate whose signature keeps less than this share outside what the accepted effects explain is
/// absorbed by them.
const ABSORBED_SHARE: f64 = 0.05;
/// A fitted value counts as away from neutral when at least this many standard errors from it.
const SIGNIFICANT_T: f64 = 3.0;
/// Delta BIC below -10: "very strong" evidence (Kass and Raftery 1995, Bayes factors, JASA 90:773).
const STRONG_BIC: f64 = 10.0;
/// Two passing candidates whose residual changes are this parallel (cosine), with BIC within
/// `STRONG_BIC`, explain the same thing: ambiguous.
const PARALLEL_CHANGES: f64 = 0.95;
/// One signature lies inside another when its residual after projection is below this share.
const NESTED_SHARE: f64 = 1e-3;

/// Smallest change of a weighted residual (in units of sigma) by a probe-sized effect that counts as a
/// signature: far below anything a fit could use, far above the round-off of a prediction.
const SIGNATURE_FLOOR: f64 = 1e-9;

/// A typical size of each effect (its value away from neutral) at which its signature is looked for.
fn probe_step(kind: Kind) -> f64 {
    match kind {
        Kind::ActuatorCompliance | Kind::LinkCompliance => 1.0, // compliance doubled
        Kind::Gravity => 1.0,                                   // 1 kg
        Kind::LegGeometry | Kind::Preload | Kind::Backlash | Kind::ToolOffset => 0.01, // mm (basis units)
        Kind::LoadedNonlinearity => 1.0,                        // the whole loaded response
    }
}

/// Whether some value of the candidate, one coordinate at a time at its probe size, changes a prediction.
pub fn has_signature(problem: &Problem, c: &Candidate, rows: &[usize]) -> bool {
    let Ok(base) = problem.residuals(&[], rows) else { return false };
    (0..c.dim()).any(|i| {
        let mut p = c.neutral();
        p[i] += probe_step(c.kind);
        match problem.residuals(&[c.effect(&p)], rows) {
            Ok(r) => (r - &base).amax() > SIGNATURE_FLOOR,
            Err(_) => false,
        }
    })
}

/// Step of the end-point error (mm, and mm / length scale for rotations) by which the signature of a
/// leg-geometry error is differentiated: the predictions are linear in it, so only round-off matters.
const END_ERROR_STEP: f64 = 1e-3;
/// Singular values of the end-error signature below this share of the largest are directions the data
/// cannot see (round-off of the differences is ~1e-10 of the largest).
const VISIBLE_SHARE: f64 = 1e-6;

/// The directions of leg k's end-point error that change the predictions (SVD of the signature). Rotations
/// are weighed by the model's length scale (mm/rad), so that a rotation and a translation of the same
/// effect on the end point compare alike; the basis is returned in (mm, rad), its columns orthonormal in
/// the metric diag(1, 1, 1, L^2, L^2, L^2) (L the length scale), in which the invisible directions are
/// orthogonal to them.
fn visible_end_errors(problem: &Problem, k: usize, rows: &[usize]) -> Option<DMatrix<f64>> {
    let full = Candidate { kind: Kind::LegGeometry, target: Target::Leg(k), basis: Some(DMatrix::identity(6, 6)) };
    let base = problem.residuals(&[], rows).ok()?;
    let scale = problem.model.length_scale;
    let unit = |c: usize| if c < 3 { 1.0 } else { 1.0 / scale };
    let mut s = DMatrix::zeros(base.len(), 6);
    for c in 0..6 {
        let mut p = vec![0.0; 6];
        p[c] = END_ERROR_STEP * unit(c);
        let r = problem.residuals(&[full.effect(&p)], rows).ok()?;
        s.set_column(c, &((&base - r) / END_ERROR_STEP));
    }
    let svd = crate::linalg::capped_svd(s, false, true)?;
    let v_t = svd.v_t?;
    let top = svd.singular_values.max();
    let keep: Vec<usize> =
        (0..svd.singular_values.len()).filter(|&i| svd.singular_values[i] > VISIBLE_SHARE * top && top > 0.0).collect();
    if keep.is_empty() {
        return None;
    }
    Some(DMatrix::from_fn(6, keep.len(), |r, c| v_t[(keep[c], r)] * unit(r)))
}

/// Upper-tail probabilities by the distributions' survival functions: `1 - cdf` underflows to 0 beyond
/// p ~ 1e-16, which made every strong effect look equally (infinitely) significant.
fn chi2_sf(x: f64, dof: usize) -> f64 {
    ChiSquared::new(dof.max(1) as f64).map(|d| d.sf(x)).unwrap_or(f64::NAN)
}

fn f_sf(x: f64, d1: usize, d2: usize) -> f64 {
    if d1 == 0 || d2 == 0 || !x.is_finite() {
        return if x.is_infinite() { 0.0 } else { 1.0 };
    }
    FisherSnedecor::new(d1 as f64, d2 as f64).map(|d| d.sf(x.max(0.0))).unwrap_or(f64::NAN)
}

/// Per-axis sums of squares (mm^2) of the weighted residuals `r` of `rows`, turned back into mm.
fn axis_squares(problem: &Problem, rows: &[usize], r: &DVector<f64>) -> Vec3 {
    let mut s = Vec3::zeros();
    for (i, &row) in rows.iter().enumerate() {
        for c in 0..3 {
            s[c] += (r[3 * i + c] / problem.weights[row]).powi(2);
        }
    }
    s
}

/// Per-axis RMS (mm) of the weighted residuals `r` of `rows`.
fn rms(problem: &Problem, rows: &[usize], r: &DVector<f64>) -> Vec3 {
    (axis_squares(problem, rows, r) / rows.len().max(1) as f64).map(f64::sqrt)
}

/// The noise level and where it comes from, and the weights.
pub fn noise(data: &Dataset, sigma: Option<f64>) -> Result<(Vec<f64>, f64, SigmaSource), DiagnoseError> {
    if data.rows.iter().all(|r| r.sigma.is_some()) {
        let w: Vec<f64> = data.rows.iter().map(|r| 1.0 / r.sigma.expect("checked")).collect();
        let typical = data.rows.iter().map(|r| r.sigma.expect("checked")).sum::<f64>() / data.rows.len() as f64;
        return Ok((w, typical, SigmaSource::Column));
    }
    if let Some(s) = sigma {
        if !(super::data::MIN_SIGMA_MM..=super::data::MAX_MAGNITUDE).contains(&s) {
            return Err(DiagnoseError::NoiseOutOfRange { sigma: s });
        }
        return Ok((vec![1.0 / s; data.rows.len()], s, SigmaSource::Given));
    }
    let groups = data.repeats();
    let (mut ss, mut dof) = (0.0, 0usize);
    for g in &groups {
        let mean: Vec3 = g.iter().map(|&r| data.rows[r].displacement).sum::<Vec3>() / g.len() as f64;
        ss += g.iter().map(|&r| (data.rows[r].displacement - mean).norm_squared()).sum::<f64>();
        dof += 3 * (g.len() - 1);
    }
    if dof < 3 || ss <= 0.0 {
        return Err(DiagnoseError::NoiseUnknown);
    }
    let s = (ss / dof as f64).sqrt();
    Ok((vec![1.0 / s; data.rows.len()], s, SigmaSource::Repeats { dof }))
}

struct Step<'a> {
    problem: &'a Problem<'a>,
    rows: Vec<usize>,
    n: usize,
    ln_n: f64,
}

impl Step<'_> {
    /// Fits accepted + c; fills a table row.
    fn evaluate(&self, accepted: &[Candidate], base: &Fit, c: &Candidate, alpha_c: f64) -> CandidateRow {
        let mut cands = accepted.to_vec();
        cands.push(c.clone());
        let k0 = base.theta.len();
        let dim = c.dim();
        let mut row = CandidateRow {
            label: c.label(),
            dim,
            identifiable: false,
            note: String::new(),
            condition: f64::INFINITY,
            orthogonal: 0.0,
            ssr: base.ssr,
            delta_bic: 0.0,
            f: 0.0,
            p_value: 1.0,
            values: c.neutral(),
            se: vec![f64::NAN; dim],
            plausible: false,
            significant_params: false,
            passes: false,
            change: DVector::zeros(0),
            candidate: c.clone(),
            fit: None,
        };
        // Signature at the accepted fit, the candidate neutral.
        let mut theta: Vec<f64> = base.theta.clone();
        theta.extend(c.neutral());
        let sig = match jacobian(self.problem, &cands, &theta, k0, &self.rows) {
            Ok(s) => s,
            Err(e) => {
                row.note = e.to_string();
                return row;
            }
        };
        let Some(svd) = crate::linalg::capped_svd(sig.clone(), false, false) else {
            row.note = "its signature is not finite on this data (extreme values?)".into();
            return row;
        };
        let (top, low) = (svd.singular_values.max(), svd.singular_values.min());
        row.condition = if low > 0.0 { top / low } else { f64::INFINITY };
        // What the accepted effects already explain: their signature columns.
        let own = sig.norm();
        row.orthogonal = if k0 == 0 {
            1.0
        } else {
            match jacobian(self.problem, &cands, &theta, 0, &self.rows) {
                Ok(all) => {
                    let q = all.columns(0, k0).into_owned().qr().q();
                    let rest = &sig - &q * (q.transpose() * &sig);
                    rest.norm() / own.max(1e-300)
                }
                Err(_) => 0.0,
            }
        };
        // NaN (a signature that is not finite) is no signature either.
        if own.is_nan() || own <= NO_SIGNATURE * (self.n as f64).sqrt() {
            row.note = "no signature on this data".into();
            return row;
        }
        if row.condition > RANK_DEFICIENT {
            row.note = format!("rank-deficient signature (condition {:.1e})", row.condition);
            return row;
        }
        if row.orthogonal < ABSORBED_SHARE {
            row.note = "absorbed by the effects already accepted".into();
            return row;
        }
        row.identifiable = true;
        let mut start = base.theta.clone();
        start.extend(c.neutral());
        let Ok(f) = fit(self.problem, &cands, &self.rows, Some(&start)) else {
            row.note = "fit failed".into();
            return row;
        };
        let k1 = f.theta.len();
        row.ssr = f.ssr;
        row.delta_bic = (f.ssr - base.ssr) + dim as f64 * self.ln_n;
        let d2 = self.n.saturating_sub(k1);
        row.f = ((base.ssr - f.ssr).max(0.0) / dim as f64) / (f.ssr / d2.max(1) as f64);
        row.p_value = f_sf(row.f, dim, d2);
        row.values = f.theta[k0..].to_vec();
        let scale = (f.ssr / d2.max(1) as f64).max(1.0);
        row.se = match &f.covariance {
            Some(cov) => (k0..k1).map(|i| (cov[(i, i)] * scale).max(0.0).sqrt()).collect(),
            None => vec![f64::NAN; dim],
        };
        let neutral = c.neutral();
        let t_max =
            row.values.iter().zip(&row.se).zip(&neutral).map(|((v, s), n)| (v - n).abs() / s).fold(0.0, f64::max);
        row.significant_params = t_max >= SIGNIFICANT_T;
        row.plausible = plausible(c, &row.values, &row.se);
        row.change = &base.residuals - &f.residuals;
        row.passes = row.p_value < alpha_c && row.delta_bic < -STRONG_BIC && row.plausible && row.significant_params;
        row.fit = Some(f);
        row
    }
}

/// Physically possible values (within two standard errors): a compliance factor between 1/20 and 20 (a
/// spring 20 times softer or stiffer than modelled is a wrong model, not an effect), a non-negative mass and
/// clearance, a share of the loaded response between 0 and 5.
fn plausible(c: &Candidate, v: &[f64], se: &[f64]) -> bool {
    match c.kind {
        Kind::ActuatorCompliance | Kind::LinkCompliance => v[0] > 0.05 && v[0] < 20.0,
        Kind::Gravity | Kind::Backlash => v[0] + 2.0 * se[0] >= 0.0,
        Kind::LoadedNonlinearity => v[0] > 0.0 && v[0] < 5.0,
        _ => v.iter().all(|x| x.is_finite()),
    }
}

fn cosine(a: &DVector<f64>, b: &DVector<f64>) -> f64 {
    a.dot(b) / (a.norm() * b.norm()).max(1e-300)
}

/// True when one candidate's signature lies (almost) inside the other's and has fewer parameters: nested,
/// so parsimony (BIC) decides. Equal signatures of equal size are not nested but indistinguishable.
fn nested(problem: &Problem, a: &Candidate, b: &Candidate, rows: &[usize]) -> bool {
    if a.dim() == b.dim() {
        return false;
    }
    let sig = |c: &Candidate| jacobian(problem, std::slice::from_ref(c), &c.neutral(), 0, rows).ok();
    let (Some(sa), Some(sb)) = (sig(a), sig(b)) else { return false };
    let inside = |x: &DMatrix<f64>, y: &DMatrix<f64>| {
        let q = y.clone().qr().q();
        (x - &q * (q.transpose() * x)).norm() <= NESTED_SHARE * x.norm()
    };
    inside(&sa, &sb) || inside(&sb, &sa)
}

/// Leave-pose-out residuals of the model with `cands` refitted without each pose (from `start`).
fn heldout(problem: &Problem, cands: &[Candidate], start: &[f64]) -> Result<(f64, Vec3), PoseError> {
    let data = problem.data;
    let mut ssr = 0.0;
    let mut axis = Vec3::zeros();
    let mut count = 0usize;
    for p in &data.poses {
        let train: Vec<usize> = (0..data.rows.len()).filter(|r| data.rows[*r].pose_id != p.id).collect();
        let theta = if cands.is_empty() { Vec::new() } else { fit(problem, cands, &train, Some(start))?.theta };
        let r = problem.residuals(&effects_of(cands, &theta), &p.rows)?;
        ssr += r.norm_squared();
        axis += axis_squares(problem, &p.rows, &r);
        count += p.rows.len();
    }
    Ok((ssr, (axis / count.max(1) as f64).map(f64::sqrt)))
}

/// Where two fitted candidates' predictions differ most: among the data's poses, with each data wrench,
/// its reverse and its double, the pose and load that would separate them.
fn separating_advice(problem: &Problem, a: &CandidateRow, b: &CandidateRow) -> String {
    let data = problem.data;
    let (Some(fa), Some(fb)) = (&a.fit, &b.fit) else { return String::new() };
    let ka = fa.theta.len() - a.dim;
    let ea = a.candidate.effect(&fa.theta[ka..]);
    let eb = b.candidate.effect(&fb.theta[fb.theta.len() - b.dim..]);
    let mut best = (0.0, String::new());
    for factor in [-1.0, 1.0, 2.0] {
        let mut scaled = data.clone();
        for r in scaled.rows.iter_mut() {
            r.wrench *= factor;
        }
        let Ok(p) =
            Problem::new(problem.model, problem.terms, &scaled, problem.weights.clone(), problem.loaded_mode, false)
        else {
            continue;
        };
        let rows: Vec<usize> = (0..scaled.rows.len()).collect();
        let (Ok(pa), Ok(pb)) =
            (p.predict(std::slice::from_ref(&ea), &rows), p.predict(std::slice::from_ref(&eb), &rows))
        else {
            continue;
        };
        for (i, (x, y)) in pa.iter().zip(&pb).enumerate() {
            let d = (x - y).norm();
            if d > best.0 {
                let row = &scaled.rows[i];
                let w: Vec6 = row.wrench;
                best = (
                    d,
                    format!(
                        "at pose {} with the wrench ({:.0}, {:.0}, {:.0} N, {:.0}, {:.0}, {:.0} N mm) they differ by {:.4} mm",
                        row.pose_id, w[0] + 0.0, w[1] + 0.0, w[2] + 0.0, w[3] + 0.0, w[4] + 0.0, w[5] + 0.0, d
                    ),
                );
            }
        }
    }
    best.1
}

/// Names the effects that explain where the data and the model disagree (forward selection with F tests,
/// BIC and held-out errors), or none, or says the candidates cannot be told apart.
pub fn diagnose(problem: &Problem, sigma: f64, source: SigmaSource, o: &Options) -> Result<Diagnosis, DiagnoseError> {
    let data = problem.data;
    let rows: Vec<usize> = (0..data.rows.len()).collect();
    let n = problem.observations(&rows);
    let cands = candidates(problem, o.loaded);
    if n <= cands.iter().map(|c| c.dim()).max().unwrap_or(0) + 1 {
        return Err(DiagnoseError::TooFewMeasurements { rows: data.rows.len() });
    }
    let nominal = fit(problem, &[], &rows, None)?;
    let (statistic, p0) = nominal_test(nominal.ssr, n, &source);
    let rms_before = rms(problem, &rows, &nominal.residuals);
    // The nominal model has no parameters: its held-out residuals are its residuals, pose by pose.
    let (cv_current, heldout_before) = heldout(problem, &[], &[])?;
    let mut out = Diagnosis {
        verdict: Verdict::None,
        sigma,
        sigma_source: source,
        rows: data.rows.len(),
        observations: n,
        nominal_statistic: statistic,
        nominal_p: p0,
        accepted: Vec::new(),
        table: Vec::new(),
        ambiguous: None,
        rms_before,
        rms_after: rms_before,
        heldout_before,
        heldout_after: heldout_before,
        final_p: p0,
        per_pose: Vec::new(),
    };
    let step = Step { problem, rows: rows.clone(), n, ln_n: (n as f64).ln() };
    let alpha_c = o.alpha / cands.len() as f64;
    let significant = p0 < o.alpha;
    let current = if significant {
        let (accepted, current) = select_effects(&step, &cands, o, alpha_c, nominal, cv_current, &mut out)?;
        // The accepted effects with their values refitted together.
        for (a, e) in out.accepted.iter_mut().zip(effects_of(&accepted, &current.theta)) {
            a.effect = e;
        }
        out.rms_after = rms(problem, &rows, &current.residuals);
        if out.verdict != Verdict::Ambiguous {
            out.verdict =
                if accepted.is_empty() || out.final_p < o.alpha { Verdict::Unexplained } else { Verdict::Effect };
        }
        current
    } else {
        // Not significant: the candidates are still tabulated (for planning), none is named.
        out.table = cands.iter().map(|c| step.evaluate(&[], &nominal, c, alpha_c)).collect();
        nominal
    };
    out.per_pose = per_pose_residuals(problem, &rows, &current)?;
    Ok(out)
}

/// The nominal model's test: chi-square of its weighted residuals, or with repeated rows the lack-of-fit F
/// against pure error (in units of the pooled sigma, SS_pe = dof).
fn nominal_test(ssr: f64, n: usize, source: &SigmaSource) -> (f64, f64) {
    match *source {
        SigmaSource::Repeats { dof } => {
            let ss_pe = dof as f64;
            let lof_dof = n.saturating_sub(dof).max(1);
            let f = ((ssr - ss_pe).max(0.0) / lof_dof as f64) / (ss_pe / dof as f64);
            (f, f_sf(f, lof_dof, dof))
        }
        _ => (ssr, chi2_sf(ssr, n)),
    }
}

/// Forward selection: at each step the passing candidate with the lowest delta BIC is accepted if it
/// lowers the held-out error, until the residuals are within the noise, nothing passes, two candidates
/// cannot be told apart (ambiguous) or `max_effects` are named. Returns the accepted candidates and their
/// joint fit; fills the table, the accepted effects and the held-out error of `out`.
fn select_effects(
    step: &Step,
    cands: &[Candidate],
    o: &Options,
    alpha_c: f64,
    nominal: Fit,
    mut cv_current: f64,
    out: &mut Diagnosis,
) -> Result<(Vec<Candidate>, Fit), DiagnoseError> {
    let (problem, rows, n) = (step.problem, &step.rows, step.n);
    let mut accepted: Vec<Candidate> = Vec::new();
    let mut current = nominal;
    for _ in 0..o.max_effects {
        let remaining: Vec<&Candidate> = cands.iter().filter(|c| !accepted.contains(c)).collect();
        let table: Vec<CandidateRow> =
            remaining.iter().map(|c| step.evaluate(&accepted, &current, c, alpha_c)).collect();
        if out.table.is_empty() {
            out.table = table.clone();
        }
        let mut passing: Vec<&CandidateRow> = table.iter().filter(|r| r.passes).collect();
        passing.sort_by(|a, b| a.delta_bic.total_cmp(&b.delta_bic));
        let Some(best) = passing.first().copied() else { break };
        // Two candidates explaining the same thing: parallel changes of the residuals, BIC within 10.
        if let Some(rival) = passing.iter().skip(1).find(|r| {
            r.delta_bic - best.delta_bic < STRONG_BIC
                && cosine(&r.change, &best.change) > PARALLEL_CHANGES
                && !nested(problem, &r.candidate, &best.candidate, rows)
        }) {
            out.ambiguous = Some((best.label.clone(), rival.label.clone(), separating_advice(problem, best, rival)));
            out.verdict = Verdict::Ambiguous;
            break;
        }
        let mut trial = accepted.clone();
        trial.push(best.candidate.clone());
        let f = best.fit.clone().expect("a passing candidate was fitted");
        let (cv, cv_axis) = heldout(problem, &trial, &f.theta)?;
        if cv >= cv_current {
            break;
        }
        cv_current = cv;
        out.heldout_after = cv_axis;
        let k0 = current.theta.len();
        accepted = trial;
        out.accepted.push(Accepted {
            effect: best.candidate.effect(&f.theta[k0..]),
            basis: best.candidate.basis.clone(),
            label: best.label.clone(),
            params: f.theta[k0..].to_vec(),
            se: best.se.clone(),
            p_value: best.p_value,
            delta_bic: best.delta_bic,
        });
        current = f;
        let k = current.theta.len();
        out.final_p = chi2_sf(current.ssr, n.saturating_sub(k).max(1));
        if out.final_p >= o.alpha {
            break;
        }
    }
    Ok((accepted, current))
}

/// Per pose: its position and the residual (mm) of its row with the largest nominal residual, before and
/// after the accepted effects (`current`).
fn per_pose_residuals(problem: &Problem, rows: &[usize], current: &Fit) -> Result<Vec<(Vec3, Vec3, Vec3)>, PoseError> {
    let mm =
        |r: &DVector<f64>, row: usize| Vec3::new(r[3 * row], r[3 * row + 1], r[3 * row + 2]) / problem.weights[row];
    let nominal_r = problem.residuals(&[], rows)?;
    let mut out = Vec::new();
    for p in &problem.data.poses {
        let worst =
            p.rows.iter().copied().max_by(|a, b| mm(&nominal_r, *a).norm().total_cmp(&mm(&nominal_r, *b).norm()));
        if let Some(w) = worst {
            out.push((p.position, mm(&nominal_r, w), mm(&current.residuals, w)));
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Regression: p-values were `1 - cdf`, which is 0 below 1e-16. Closed forms: the chi-square
    /// distribution with 2 degrees of freedom has sf(x) = exp(-x/2); the F distribution with d1 = 2 has
    /// sf(x) = (1 + 2x/d2)^(-d2/2).
    #[test]
    fn p_values_keep_their_digits_far_in_the_tail() {
        for x in [1.0, 40.0, 200.0, 1000.0] {
            let exact = (-x / 2.0f64).exp();
            assert!((chi2_sf(x, 2) - exact).abs() <= 1e-10 * exact, "chi2 sf({x}) {} vs {exact}", chi2_sf(x, 2));
        }
        for (x, d2) in [(3.0, 20usize), (200.0, 30), (5000.0, 40)] {
            let exact = (1.0 + 2.0 * x / d2 as f64).powf(-(d2 as f64) / 2.0);
            assert!((f_sf(x, 2, d2) - exact).abs() <= 1e-8 * exact, "F sf({x}) {} vs {exact}", f_sf(x, 2, d2));
        }
    }
}
