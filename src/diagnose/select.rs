//! The diagnosis: is the nominal model's misfit beyond the noise (chi-square with known sigma, lack-of-fit
//! F test with repeats)? Which candidate effects are identifiable on this data, how well does each explain
//! it (fit, SSR, BIC, extra-sum-of-squares F test, parameters with standard errors), and which to accept:
//! forward stepwise up to three (F test significant at alpha / (number of candidates), delta BIC < -10,
//! plausible values at least 3 standard errors from neutral, a better leave-pose-out prediction), then
//! backward elimination and swaps, so the simplest sufficient set wins; standard errors and correlations from
//! the joint fit. Verdicts: `effect`, `none`, `ambiguous` (candidates whose fitted predictions the data
//! cannot tell apart), `unexplained`, `noise` (a residual variance that grows with the load).

use nalgebra::{DMatrix, DVector};

use super::data::Dataset;
use super::error::{DiagnoseError, PoseError};
use super::fit::{effects_of, fit, jacobian, Candidate, Fit, Problem};
use super::measurement::gravity_of;
use super::stats::{chi2_sf, f_sf, STRONG_EVIDENCE};
use crate::kinematics::frame::{Vec3, Vec6};
use crate::linalg::{outside_span, span_basis};
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
        Options { alpha: 0.01, loaded: true, max_effects: 3 }
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
    /// The residuals' variance grows with the load: the noise level is mis-stated, not the model.
    Noise,
}

impl Verdict {
    /// The verdict's name in reports and JSON.
    pub fn as_str(self) -> &'static str {
        match self {
            Verdict::Effect => "effect",
            Verdict::None => "none",
            Verdict::Ambiguous => "ambiguous",
            Verdict::Unexplained => "unexplained",
            Verdict::Noise => "noise",
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
    /// How the weighted predictions change when this candidate is fitted: w (pred_with - pred_without),
    /// noise-free (the fitted alternative's own prediction).
    change: DVector<f64>,
    /// An orthonormal basis of what the accepted effects and this candidate can fit, around the accepted
    /// fit (their signatures' span), for the separation of another candidate's fitted prediction from it.
    span: DMatrix<f64>,
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
    /// Fitted values as reported (`Candidate::reported`: factors, kg, mm; coordinates for leg-geometry).
    pub params: Vec<f64>,
    /// Their standard errors, from the joint fit of every accepted effect.
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
    /// Tied candidates (the best first) and where the first two's predictions differ most (advice): the
    /// verdict `ambiguous` when the tie is at the first step, else what is left after the accepted effects.
    pub ambiguous: Option<(Vec<String>, String)>,
    /// Candidates with the same signature on this data as an earlier one (left out of the table):
    /// (reported as, indistinguishable from it).
    pub indistinguishable: Vec<(String, String)>,
    /// Correlations of the accepted effects' parameters in the joint fit: (parameter labels, matrix).
    pub correlations: (Vec<String>, Vec<Vec<f64>>),
    /// For the `noise` verdict or a warning: how the residual variance grows with the load.
    pub noise_note: Option<String>,
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
    /// The significance level the diagnosis ran at.
    pub alpha: f64,
    /// Per pose: its position, and the residual (mm) of its row with the largest nominal residual, before and
    /// after the accepted effects (for the picture).
    pub per_pose: Vec<(Vec3, Vec3, Vec3)>,
    /// Rows of the data left out of every fit as gross errors (`screen`), with how far each lies from the
    /// model.
    pub left_out: Vec<super::screen::LeftOut>,
}

/// The candidates for this model and data (leg-geometry restricted to what the data can see), each
/// offered only where it changes a prediction.
pub fn candidates(problem: &Problem, loaded: bool) -> Vec<Candidate> {
    let m = problem.model;
    let actuated: Vec<usize> = (0..m.legs.len()).filter(|&k| m.legs[k].has_actuator_spring()).collect();
    let mut out = Vec::new();
    for &k in &actuated {
        out.push(Candidate::new(Kind::ActuatorCompliance, Target::Leg(k)));
    }
    for g in m.link_spring_groups() {
        for kind in [Kind::LinkCompliance, Kind::LinkSections] {
            out.push(Candidate::new(kind, Target::Group(g.clone())));
        }
    }
    out.push(Candidate::new(Kind::Gravity, Target::None));
    out.push(Candidate { kind: Kind::GravityOffset, target: Target::None, basis: Some(centre_basis(problem)) });
    let all: Vec<usize> = (0..problem.data.rows.len()).collect();
    for k in 0..m.legs.len() {
        if let Some(basis) = visible_end_errors(problem, k, &all) {
            out.push(Candidate { kind: Kind::LegGeometry, target: Target::Leg(k), basis: Some(basis) });
        }
    }
    for &k in &actuated {
        out.push(Candidate::new(Kind::ActuatorOffset, Target::Leg(k)));
        out.push(Candidate::new(Kind::Backlash, Target::Leg(k)));
    }
    if !loaded {
        out.push(Candidate::new(Kind::LoadedNonlinearity, Target::None));
    }
    for kind in [Kind::ToolOffset, Kind::FrameRotation, Kind::ToolCompliance, Kind::Drift] {
        out.push(Candidate::new(kind, Target::None));
    }
    // A candidate that changes no prediction cannot be named by any data of this design (a compliance
    // factor where no row is loaded, backlash where no actuator carries load, drift without an order): not
    // offered.
    out.retain(|c| has_signature(problem, c, &all));
    out
}

/// Gravity-offset's parameters: the mass and its first moment m c across gravity, and along it where the data
/// see that: a centre moved along gravity changes the payload's moment only as the platform turns under the
/// load (r = R c), so on a rigid or purely translating platform no measurement sees it, and it is left out
/// (reported as 0); where the platform's turn under the rows' wrenches makes it visible, leaving it out
/// would put its share on the moment across gravity (a centre 121 mm below the platform moved the fitted
/// one by 6 standard errors), so it is fitted. Maps the parameters to the stored values (m, m c).
fn centre_basis(problem: &Problem) -> DMatrix<f64> {
    let g = gravity_of(problem.model).normalize();
    let helper = if g.x.abs() < 0.9 { Vec3::x() } else { Vec3::y() };
    let e1 = g.cross(&helper).normalize();
    let e2 = g.cross(&e1);
    let basis = |columns: usize| {
        DMatrix::from_fn(4, columns, |r, c| match (r, c) {
            (0, 0) => 1.0,
            (0, _) | (_, 0) => 0.0,
            (r, 1) => e1[r - 1],
            (r, 2) => e2[r - 1],
            (r, _) => g[r - 1],
        })
    };
    let full = Candidate { kind: Kind::GravityOffset, target: Target::None, basis: Some(basis(4)) };
    let rows: Vec<usize> = (0..problem.data.rows.len()).collect();
    let seen_along = signature(problem, &full, &rows).is_some_and(|sig| {
        let norms: Vec<f64> = sig.column_iter().map(|c| c.norm()).collect();
        let largest = norms.iter().copied().fold(0.0, f64::max);
        // The moment along gravity moves a prediction (beyond round-off of the others), and not only as the
        // moments across it do.
        let visible = norms[3] > NO_SIGNATURE * (sig.nrows() as f64).sqrt() && norms[3] > SIGNATURE_FLOOR * largest;
        visible && norms.iter().all(|n| *n > 0.0) && {
            let scaled = DMatrix::from_fn(sig.nrows(), 4, |i, j| sig[(i, j)] / norms[j]);
            let s = scaled.singular_values();
            s.min() * RANK_DEFICIENT > s.max()
        }
    });
    basis(if seen_along { 4 } else { 3 })
}

/// Splits off candidates whose signature on this data equals an earlier candidate's (same number of
/// parameters, each signature inside the other's span): no data of this design can tell them apart, so the
/// later is reported as the earlier, once. Returns (kept, (reported as, indistinguishable)).
pub fn merge_identical(problem: &Problem, cands: Vec<Candidate>) -> (Vec<Candidate>, Vec<(String, String)>) {
    let rows: Vec<usize> = (0..problem.data.rows.len()).collect();
    let sigs: Vec<Option<DMatrix<f64>>> = cands.iter().map(|c| signature(problem, c, &rows)).collect();
    let mut kept: Vec<usize> = Vec::new();
    let mut merged = Vec::new();
    for (i, c) in cands.iter().enumerate() {
        let twin = kept.iter().copied().find(|&k| {
            cands[k].dim() == c.dim()
                && matches!((&sigs[k], &sigs[i]), (Some(a), Some(b)) if inside(a, b, NESTED_SHARE) && inside(b, a, NESTED_SHARE))
        });
        match twin {
            Some(k) => merged.push((cands[k].label(), c.label())),
            None => kept.push(i),
        }
    }
    let kept = kept.into_iter().map(|i| cands[i].clone()).collect();
    (kept, merged)
}

/// A candidate's signature at neutral: the weighted residuals' derivative by its parameters.
fn signature(problem: &Problem, c: &Candidate, rows: &[usize]) -> Option<DMatrix<f64>> {
    jacobian(problem, std::slice::from_ref(c), &c.neutral(), 0, rows).ok()
}

/// Whether the columns of `x` lie in the span of `y`'s, but for a share `share` of their norm.
fn inside(x: &DMatrix<f64>, y: &DMatrix<f64>, share: f64) -> bool {
    outside_span(x, y).is_some_and(|rest| rest.norm() <= share * x.norm())
}

// The thresholds of selection, each with its reason.

/// A signature (weighted residuals per unit parameter) below this times sqrt(observations) is none: its
/// effect would need values beyond any physical size to move a residual by one sigma.
const NO_SIGNATURE: f64 = 1e-9;
/// A signature whose columns are this ill-conditioned cannot fix all the candidate's parameters.
const RANK_DEFICIENT: f64 = 1e8;
/// A candidate whose signature keeps less than this share outside what the accepted effects explain is
/// absorbed by them.
pub(crate) const ABSORBED_SHARE: f64 = 0.05;
/// A fitted value counts as away from neutral when at least this many standard errors from it.
const SIGNIFICANT_T: f64 = 3.0;
/// A rival whose best fit stays within this noise-free separation (sigma^2 units) of the best candidate's
/// fitted prediction is tied with it: the observed excess SSR of the wrong one has mean s and standard
/// deviation about 2 sqrt(s), so at s = 16 it still comes out below zero in 2% of data sets.
const TIE_SEPARATION: f64 = 16.0;
/// One signature lies inside another when its residual after projection is below this share.
const NESTED_SHARE: f64 = 1e-3;

/// Smallest change of a weighted residual (in units of sigma) by a probe-sized effect that counts as a
/// signature: far below anything a fit could use, far above the round-off of a prediction.
const SIGNATURE_FLOOR: f64 = 1e-9;

/// A typical size of each effect (its value away from neutral) at which its signature is looked for.
pub(crate) fn probe_step(kind: Kind) -> f64 {
    match kind {
        Kind::ActuatorCompliance | Kind::LinkCompliance | Kind::LinkSections => 0.7, // log factor: x2
        Kind::Gravity | Kind::GravityOffset => 1.0,                                  // 1 kg, 1 kg mm
        Kind::LegGeometry | Kind::ActuatorOffset | Kind::Backlash | Kind::ToolOffset => 0.01, // mm (basis units)
        Kind::LoadedNonlinearity => 1.0,                                             // the whole loaded response
        Kind::FrameRotation => 1e-4,                                                 // rad
        Kind::ToolCompliance => 1e-4,                                                // mm/N
        Kind::Drift => 1e-3,                                                         // mm per unit of order
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
            span: DMatrix::zeros(0, 0),
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
        let accepted_sig = if k0 == 0 {
            Some(DMatrix::zeros(sig.nrows(), 0))
        } else {
            jacobian(self.problem, &cands, &theta, 0, &self.rows).ok().map(|all| all.columns(0, k0).into_owned())
        };
        row.orthogonal = match &accepted_sig {
            Some(a) => outside_span(&sig, a).map_or(0.0, |rest| rest.norm() / own.max(1e-300)),
            None => 0.0,
        };
        if let Some(a) = &accepted_sig {
            let mut both = a.clone().insert_columns(k0, dim, 0.0);
            both.columns_mut(k0, dim).copy_from(&sig);
            row.span = span_basis(&both).unwrap_or_else(|| DMatrix::zeros(0, 0));
        }
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
        let scale = (f.ssr / d2.max(1) as f64).max(1.0);
        let se_params: Vec<f64> = match &f.covariance {
            Some(cov) => (k0..k1).map(|i| (cov[(i, i)] * scale).max(0.0).sqrt()).collect(),
            None => vec![f64::NAN; dim],
        };
        let params = &f.theta[k0..];
        let t_max =
            params.iter().zip(&se_params).zip(c.neutral()).map(|((v, s), n)| (v - n).abs() / s).fold(0.0, f64::max);
        (row.values, row.se) = c.reported(params, &se_params);
        row.significant_params = t_max >= SIGNIFICANT_T;
        row.plausible = plausible(c, &row.values, &row.se);
        // Residuals are w (measured - predicted): their change is w (pred_with - pred_without).
        row.change = &base.residuals - &f.residuals;
        row.passes =
            row.p_value < alpha_c && row.delta_bic < -STRONG_EVIDENCE && row.plausible && row.significant_params;
        row.fit = Some(f);
        row
    }
}

/// Physically possible values (within two standard errors): a compliance factor between 1/20 and 20 (a
/// spring 20 times softer or stiffer than modelled is a wrong model, not an effect), a non-negative mass,
/// clearance and series compliance, a share of the loaded response between 0 and 5, a centre of mass
/// within 10 length scales of the reference point.
fn plausible(c: &Candidate, v: &[f64], se: &[f64]) -> bool {
    let finite = v.iter().all(|x| x.is_finite());
    finite
        && match c.kind {
            Kind::ActuatorCompliance | Kind::LinkCompliance | Kind::LinkSections => {
                v.iter().all(|f| *f > 0.05 && *f < 20.0)
            }
            Kind::Gravity | Kind::Backlash | Kind::ToolCompliance => v[0] + 2.0 * se[0] >= 0.0,
            Kind::GravityOffset => v[0] + 2.0 * se[0] >= 0.0 && v[1..].iter().all(|c| c.abs() < 1e5),
            Kind::LoadedNonlinearity => v[0] > 0.0 && v[0] < 5.0,
            _ => true,
        }
}

/// True when one candidate's signature lies (almost) inside the other's and has fewer parameters: nested,
/// so parsimony (BIC) decides. Equal signatures of equal size are not nested but indistinguishable.
fn nested(problem: &Problem, a: &Candidate, b: &Candidate, rows: &[usize]) -> bool {
    if a.dim() == b.dim() {
        return false;
    }
    let (Some(sa), Some(sb)) = (signature(problem, a, rows), signature(problem, b, rows)) else { return false };
    inside(&sa, &sb, NESTED_SHARE) || inside(&sb, &sa, NESTED_SHARE)
}

/// The noise-free separation (in units of sigma^2) of candidate `a`'s fitted prediction from everything
/// candidate `b` (with the accepted effects) can fit: || (I - Q_b Q_b^T) change_a ||^2, linearised at the
/// accepted fit. It is the excess SSR `b` would show on average were `a` the truth; the observed excess
/// scatters by about 2 sqrt of it, so below `TIE_SEPARATION` the data cannot say which.
fn separation(a: &CandidateRow, b: &CandidateRow) -> f64 {
    if b.span.nrows() != a.change.len() {
        return f64::INFINITY;
    }
    (&a.change - &b.span * (b.span.transpose() * &a.change)).norm_squared()
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
/// BIC and held-out errors, then backward elimination and swaps), or none, or says the candidates cannot be
/// told apart, or that the noise level is mis-stated.
pub fn diagnose(problem: &Problem, sigma: f64, source: SigmaSource, o: &Options) -> Result<Diagnosis, DiagnoseError> {
    let data = problem.data;
    let rows: Vec<usize> = (0..data.rows.len()).collect();
    let n = problem.observations(&rows);
    let (cands, indistinguishable) = merge_identical(problem, candidates(problem, o.loaded));
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
        indistinguishable,
        correlations: (Vec::new(), Vec::new()),
        noise_note: None,
        rms_before,
        rms_after: rms_before,
        heldout_before,
        heldout_after: heldout_before,
        final_p: p0,
        alpha: o.alpha,
        per_pose: Vec::new(),
        left_out: Vec::new(),
    };
    let step = Step { problem, rows: rows.clone(), n, ln_n: (n as f64).ln() };
    let alpha_c = o.alpha / cands.len().max(1) as f64;
    let current = if p0 < o.alpha {
        let (accepted, current) = select_effects(&step, &cands, o, alpha_c, nominal, cv_current, &mut out)?;
        out.rms_after = rms(problem, &rows, &current.residuals);
        if !accepted.is_empty() {
            out.heldout_after = heldout(problem, &accepted, &current.theta)?.1;
            describe_accepted(&step, &accepted, &current, &mut out);
        }
        out.final_p = chi2_sf(current.ssr, n.saturating_sub(current.theta.len()).max(1));
        if out.verdict != Verdict::Ambiguous {
            // A correct set fails the final test by chance in a share alpha of data sets, mostly with p just
            // below alpha; below alpha^2 something real is left.
            out.verdict = match (accepted.is_empty(), out.final_p) {
                (false, p) if p >= o.alpha * o.alpha => Verdict::Effect,
                _ => Verdict::Unexplained,
            };
            if out.verdict == Verdict::Unexplained {
                if let Some(note) = variance_grows_with_load(problem, &rows, &current.residuals, o.alpha) {
                    out.verdict = Verdict::Noise;
                    out.noise_note = Some(note);
                }
            }
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

/// Fills the accepted effects from their joint fit: values with standard errors from the joint covariance,
/// each effect's F test and delta BIC given the others (dropped from the joint fit), and the parameters'
/// correlations.
fn describe_accepted(step: &Step, accepted: &[Candidate], joint: &Fit, out: &mut Diagnosis) {
    let (n, k) = (step.n, joint.theta.len());
    let dof = n.saturating_sub(k).max(1);
    let scale = (joint.ssr / dof as f64).max(1.0);
    let cov = joint.covariance.as_ref().map(|c| c * scale);
    let se_all: Vec<f64> = (0..k).map(|i| cov.as_ref().map_or(f64::NAN, |c| c[(i, i)].max(0.0).sqrt())).collect();
    let mut at = 0;
    out.accepted.clear();
    let mut labels = Vec::new();
    for (i, c) in accepted.iter().enumerate() {
        let dim = c.dim();
        let params = &joint.theta[at..at + dim];
        let (values, se) = c.reported(params, &se_all[at..at + dim]);
        let (others, start) = without_effect(accepted, &joint.theta, i);
        let without = fit(step.problem, &others, &step.rows, Some(&start)).map(|f| f.ssr).unwrap_or(f64::NAN);
        let f = ((without - joint.ssr).max(0.0) / dim as f64) / (joint.ssr / dof as f64);
        out.accepted.push(Accepted {
            effect: c.effect(params),
            basis: c.basis.clone(),
            label: c.label(),
            params: values,
            se,
            p_value: f_sf(f, dim, dof),
            delta_bic: (joint.ssr - without) + dim as f64 * step.ln_n,
        });
        labels.extend((0..dim).map(|d| if dim == 1 { c.label() } else { format!("{}[{}]", c.label(), d + 1) }));
        at += dim;
    }
    let corr = (0..k)
        .map(|i| (0..k).map(|j| cov.as_ref().map_or(f64::NAN, |c| c[(i, j)] / (se_all[i] * se_all[j]))).collect())
        .collect();
    out.correlations = (labels, corr);
}

/// The rows split by load at the value that best balances the two groups (rows with equal loads kept
/// together): when the residual variance of the more loaded group exceeds the other's beyond chance (F test
/// at alpha), the noise grows with the load and the stated sigma is wrong there. Returns the message, or None.
fn variance_grows_with_load(problem: &Problem, rows: &[usize], r: &DVector<f64>, alpha: f64) -> Option<String> {
    let load = |i: usize| {
        let w = problem.data.rows[rows[i]].wrench;
        Vec3::new(w[0], w[1], w[2]).norm()
    };
    let mut order: Vec<usize> = (0..rows.len()).collect();
    order.sort_by(|a, b| load(*a).total_cmp(&load(*b)));
    // The split: after position k where the load steps up, with min(k, n - k) largest.
    let n = order.len();
    let split =
        (1..n).filter(|&k| load(order[k]) > load(order[k - 1]) * (1.0 + 1e-9) + 1e-12).max_by_key(|&k| k.min(n - k))?;
    if split.min(n - split) < 2 {
        return None;
    }
    let ss = |ix: &[usize]| ix.iter().map(|&i| (0..3).map(|c| r[3 * i + c].powi(2)).sum::<f64>()).sum::<f64>();
    let (low, high) = order.split_at(split);
    let (d_low, d_high) = (3 * low.len(), 3 * high.len());
    let ratio = (ss(high) / d_high as f64) / (ss(low) / d_low as f64).max(1e-300);
    let p = f_sf(ratio, d_high, d_low);
    // A deterministic misfit (an effect outside the library) is not noise, however its size grows with the
    // load: it follows the load (the same residual wherever the same wrench is applied), repeats where a
    // pose and wrench are measured again, or follows the pose smoothly (neighbouring poses under one wrench
    // have alike residuals, where noise makes them independent).
    if p >= alpha
        || residuals_follow_the_load(problem, rows, r, alpha)
        || residuals_repeat(problem, rows, r, alpha)
        || residuals_follow_the_pose(problem, rows, r, alpha)
    {
        return None;
    }
    Some({
        format!(
            "the residual variance of the {} more loaded rows is {ratio:.1} times that of the {} less loaded \
             (F test p = {p:.1e}): the noise grows with the load and the stated sigma does not hold; give each \
             row its own sigma_mm",
            high.len(),
            low.len()
        )
    })
}

/// Whether the mean residual of the rows under each distinct wrench departs from zero beyond their scatter
/// (F test at alpha of the means' sum of squares against the rest).
fn residuals_follow_the_load(problem: &Problem, rows: &[usize], r: &DVector<f64>, alpha: f64) -> bool {
    let wrench = |i: usize| problem.data.rows[rows[i]].wrench;
    groups_explain_residuals(&group_rows(rows.len(), |a, b| same_wrench(&wrench(a), &wrench(b))), r, alpha)
}

/// Whether rows repeated at one pose under one wrench share their residual beyond their scatter (F test at
/// alpha of the repeat groups' means against the scatter within them): noise does not repeat.
fn residuals_repeat(problem: &Problem, rows: &[usize], r: &DVector<f64>, alpha: f64) -> bool {
    let row = |i: usize| &problem.data.rows[rows[i]];
    let groups =
        group_rows(rows.len(), |a, b| row(a).pose_id == row(b).pose_id && same_wrench(&row(a).wrench, &row(b).wrench));
    groups.iter().any(|g| g.len() > 1) && groups_explain_residuals(&groups, r, alpha)
}

/// Whether the residuals follow the pose, tested on pairs of rows whose residuals noise makes independent
/// and a deterministic misfit does not: each row with the row under the same wrench at the nearest other
/// pose (a misfit smooth over the workspace makes their products positive), and each row with the row at
/// its pose under the opposite wrench (a misfit odd or even in the load makes them negative or positive).
/// For independent noise a sum of products S = sum r_i . r_j is zero on average with variance
/// sum_c r_ic^2 r_jc^2 (whatever each row's own variance), so z = S / sqrt(variance) is a standard normal:
/// one-sided for the neighbours, two-sided for the mirror pairs, at alpha / 2 each.
fn residuals_follow_the_pose(problem: &Problem, rows: &[usize], r: &DVector<f64>, alpha: f64) -> bool {
    let row = |i: usize| &problem.data.rows[rows[i]];
    let mut neighbours: Vec<(usize, usize)> = Vec::new();
    let mut mirrors: Vec<(usize, usize)> = Vec::new();
    for i in 0..rows.len() {
        let nearest = (0..rows.len())
            .filter(|&j| row(j).pose_id != row(i).pose_id && same_wrench(&row(i).wrench, &row(j).wrench))
            .min_by(|&a, &b| {
                let d = |j: usize| (row(j).position - row(i).position).norm();
                d(a).total_cmp(&d(b))
            });
        let mirror = (0..rows.len()).find(|&j| {
            row(j).pose_id == row(i).pose_id
                && row(i).wrench.norm() > 0.0
                && same_wrench(&row(i).wrench, &-row(j).wrench)
        });
        for (pairs, other) in [(&mut neighbours, nearest), (&mut mirrors, mirror)] {
            if let Some(j) = other {
                let pair = (i.min(j), i.max(j));
                if !pairs.contains(&pair) {
                    pairs.push(pair);
                }
            }
        }
    }
    let z = |pairs: &[(usize, usize)]| {
        let residual = |i: usize| Vec3::new(r[3 * i], r[3 * i + 1], r[3 * i + 2]);
        let sum: f64 = pairs.iter().map(|&(i, j)| residual(i).dot(&residual(j))).sum();
        let variance: f64 = pairs.iter().map(|&(i, j)| residual(i).component_mul(&residual(j)).norm_squared()).sum();
        (pairs.len() >= 3 && variance > 0.0).then(|| sum / variance.sqrt())
    };
    use statrs::distribution::{ContinuousCDF, Normal};
    let Ok(normal) = Normal::new(0.0, 1.0) else { return false };
    let smooth = z(&neighbours).is_some_and(|z| normal.sf(z) < alpha / 2.0);
    let mirrored = z(&mirrors).is_some_and(|z| 2.0 * normal.sf(z.abs()) < alpha / 2.0);
    smooth || mirrored
}

/// Two wrenches equal to round-off.
fn same_wrench(a: &Vec6, b: &Vec6) -> bool {
    (a - b).norm() <= 1e-9 * (1.0 + a.norm())
}

/// The positions 0..n grouped by `same` (each group in order, groups in order of their first member).
fn group_rows(n: usize, same: impl Fn(usize, usize) -> bool) -> Vec<Vec<usize>> {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for i in 0..n {
        match groups.iter_mut().find(|g| same(g[0], i)) {
            Some(g) => g.push(i),
            None => groups.push(vec![i]),
        }
    }
    groups
}

/// Whether the groups' mean residuals depart from zero beyond the scatter about them (F test at alpha of the
/// means' sum of squares, 3 per group, against the rest).
fn groups_explain_residuals(groups: &[Vec<usize>], r: &DVector<f64>, alpha: f64) -> bool {
    let rows: usize = groups.iter().map(Vec::len).sum();
    let total: f64 = groups.iter().flatten().map(|&i| (0..3).map(|c| r[3 * i + c].powi(2)).sum::<f64>()).sum();
    let means: f64 = groups
        .iter()
        .map(|m| {
            let mean = m.iter().fold(Vec3::zeros(), |acc, &i| acc + Vec3::new(r[3 * i], r[3 * i + 1], r[3 * i + 2]));
            mean.norm_squared() / m.len() as f64
        })
        .sum();
    let (d1, d2) = (3 * groups.len(), 3 * rows.saturating_sub(groups.len()));
    if d2 == 0 {
        return false;
    }
    let f = (means / d1 as f64) / ((total - means).max(1e-300) / d2 as f64);
    f_sf(f, d1, d2) < alpha
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
/// lowers the held-out error, until the residuals are within the noise, nothing passes, the best is tied
/// with others (ambiguous) or `max_effects` are named; then `refine`. Returns the accepted candidates and
/// their joint fit; fills the table and the ambiguity of `out`.
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
        // Every plausible alternative whose best fit the data cannot tell from the best's fitted prediction.
        let tied: Vec<&CandidateRow> = table
            .iter()
            .filter(|r| r.label != best.label && r.fit.is_some() && r.plausible)
            .filter(|r| separation(best, r) < TIE_SEPARATION)
            .filter(|r| !nested(problem, &r.candidate, &best.candidate, rows))
            .collect();
        if let Some(first) = tied.first() {
            let mut names = vec![best.label.clone()];
            names.extend(tied.iter().map(|r| r.label.clone()));
            out.ambiguous = Some((names, separating_advice(problem, best, first)));
            // A tie after an accepted effect leaves that effect named (the rest is reported as ambiguous).
            if accepted.is_empty() {
                out.verdict = Verdict::Ambiguous;
            }
            break;
        }
        let mut trial = accepted.clone();
        trial.push(best.candidate.clone());
        let f = best.fit.clone().expect("a passing candidate was fitted");
        let (cv, _) = heldout(problem, &trial, &f.theta)?;
        if cv >= cv_current {
            break;
        }
        cv_current = cv;
        accepted = trial;
        current = exact_refit(problem, &accepted, rows, f)?;
        let k = current.theta.len();
        if chi2_sf(current.ssr, n.saturating_sub(k).max(1)) >= o.alpha {
            break;
        }
    }
    if out.verdict == Verdict::Ambiguous || accepted.is_empty() {
        return Ok((accepted, current));
    }
    let (accepted, current) = refine(step, cands, accepted, current)?;
    let current = exact_refit(problem, &accepted, &step.rows, current)?;
    Ok((accepted, current))
}

/// The accepted effects refitted where their linearised prediction misses the loaded equilibrium of the
/// robot with them built in by more than a tenth of sigma (`Problem::correct`: the miss at the fitted values
/// is kept as a correction of every later prediction with these effects, and the fit redone), at most
/// `EXACT_REFITS` times: the candidates of the next step, the held-out errors and the final test then see
/// what the accepted effects really do.
fn exact_refit(problem: &Problem, accepted: &[Candidate], rows: &[usize], mut f: Fit) -> Result<Fit, PoseError> {
    for _ in 0..EXACT_REFITS {
        if !problem.correct(&effects_of(accepted, &f.theta))? {
            break;
        }
        f = fit(problem, accepted, rows, Some(&f.theta))?;
    }
    Ok(f)
}

/// Corrections per accepted set: each leaves a miss of the order of the last step's square.
const EXACT_REFITS: usize = 3;

/// Most rounds of backward elimination and swaps (each strictly lowers the BIC, so they end anyway).
const MAX_REFINE: usize = 6;

/// Backward elimination and swaps over the accepted set, so the simplest sufficient set wins where forward
/// selection took a larger effect first (leg-geometry with 5 values where an actuator offset explains the
/// same): drop an effect the others make unnecessary (its removal costs less than `STRONG_EVIDENCE`), else
/// replace one by another candidate where that lowers the BIC with plausible values at least
/// `SIGNIFICANT_T` standard errors from neutral.
fn refine(
    step: &Step,
    cands: &[Candidate],
    mut accepted: Vec<Candidate>,
    mut current: Fit,
) -> Result<(Vec<Candidate>, Fit), PoseError> {
    let (problem, rows) = (step.problem, &step.rows);
    let bic = |f: &Fit| f.ssr + f.theta.len() as f64 * step.ln_n;
    for _ in 0..MAX_REFINE {
        let now = bic(&current);
        // Backward: the effect whose removal costs least, if it costs less than strong evidence.
        let mut drop: Option<(f64, usize, Fit)> = None;
        if accepted.len() > 1 {
            for i in 0..accepted.len() {
                let (set, start) = without_effect(&accepted, &current.theta, i);
                let f = fit(problem, &set, rows, Some(&start))?;
                let cost = bic(&f) - now;
                if cost < STRONG_EVIDENCE && drop.as_ref().is_none_or(|(c, _, _)| cost < *c) {
                    drop = Some((cost, i, f));
                }
            }
        }
        if let Some((_, i, f)) = drop {
            accepted.remove(i);
            current = f;
            continue;
        }
        // Swaps: one accepted effect replaced by another candidate.
        let mut swap: Option<(f64, usize, Candidate, Fit)> = None;
        for i in 0..accepted.len() {
            for c in cands.iter().filter(|c| !accepted.contains(c)) {
                let (mut set, mut start) = without_effect(&accepted, &current.theta, i);
                set.push(c.clone());
                start.extend(c.neutral());
                let Ok(f) = fit(problem, &set, rows, Some(&start)) else { continue };
                let b = bic(&f);
                if b < now && swap.as_ref().is_none_or(|(sb, ..)| b < *sb) && sound(step, &set, &f) {
                    swap = Some((b, i, c.clone(), f));
                }
            }
        }
        let Some((_, i, c, f)) = swap else { break };
        accepted.remove(i);
        accepted.push(c);
        current = f;
    }
    Ok((accepted, current))
}

/// The set without its effect `skip`, and the joint fit's parameters `theta` without that effect's: a start
/// for the smaller fit.
fn without_effect(set: &[Candidate], theta: &[f64], skip: usize) -> (Vec<Candidate>, Vec<f64>) {
    let (mut kept, mut start) = (Vec::new(), Vec::new());
    let mut at = 0;
    for (i, c) in set.iter().enumerate() {
        if i != skip {
            kept.push(c.clone());
            start.extend_from_slice(&theta[at..at + c.dim()]);
        }
        at += c.dim();
    }
    (kept, start)
}

/// Whether the last candidate of `set` has plausible values at least `SIGNIFICANT_T` standard errors from
/// neutral in the joint fit `f`.
fn sound(step: &Step, set: &[Candidate], f: &Fit) -> bool {
    let Some(c) = set.last() else { return false };
    let Some(cov) = &f.covariance else { return false };
    let k = f.theta.len();
    let scale = (f.ssr / step.n.saturating_sub(k).max(1) as f64).max(1.0);
    let from = k - c.dim();
    let se: Vec<f64> = (from..k).map(|i| (cov[(i, i)] * scale).max(0.0).sqrt()).collect();
    let params = &f.theta[from..];
    let t = params.iter().zip(&se).zip(c.neutral()).map(|((v, s), n)| (v - n).abs() / s).fold(0.0, f64::max);
    let (values, se_values) = c.reported(params, &se);
    t >= SIGNIFICANT_T && plausible(c, &values, &se_values)
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
