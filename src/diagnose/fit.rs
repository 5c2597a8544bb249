//! Predictions of the measured displacements with effects, their weighted residuals, and the
//! Levenberg-Marquardt fit of effect parameters (numerical Jacobian, so every signature is the real
//! model's derivative), with the covariance of the parameters.

use std::sync::Mutex;

use nalgebra::{DMatrix, DVector};

use super::data::Dataset;
use super::error::{DiagnoseError, PoseError};
use super::lm::{self, LeastSquares};
use super::measurement::{gravity_of, PoseModel};
use crate::kinematics::frame::{Frame, Mat6, Vec3, Vec6};
use crate::model::effect::{scaled, with_model_effects, Effect, Form, Kind, Target};
use crate::platform::manipulator::{Manipulator, ManipulatorState};

/// The model, the data and what does not change between fits.
pub struct Problem<'a> {
    /// The model predicting.
    pub model: &'a Manipulator,
    /// The description's own measurement-model terms (`[[effect]]` entries that are not spring scalings).
    pub terms: &'a [Effect],
    /// The measurements.
    pub data: &'a Dataset,
    /// 1 / sigma per row (mm^-1).
    pub weights: Vec<f64>,
    /// Predictions follow the loaded equilibrium instead of C w.
    pub loaded_mode: bool,
    gravity: Vec3,
    poses: Vec<PoseModel>,
    /// Per pose: where the platform settles with no wrench (a payload, preloads, weighed chain masses), the
    /// zero of the linear prediction; zero for a model unloaded at rest.
    rest: Vec<Vec6>,
    /// Per row: the displacement of the loaded equilibrium (when computed).
    loaded: Option<Vec<Vec6>>,
    /// Per row: the tangent compliance at that equilibrium (when computed): what a small added load or end
    /// error moves the loaded platform by.
    tangent: Option<Vec<Mat6>>,
    /// Per row: index of its pose.
    pose_of: Vec<usize>,
    /// Per spring scaling (kind and target), per row: the derivative of the loaded response's non-linear
    /// part (loaded - C w) by the logarithm of the factor, computed when first needed (loaded mode).
    slopes: Mutex<Vec<Slope>>,
    /// Per set of model-form effects fitted (kinds, targets and values): what the loaded equilibrium of the
    /// robot with them built in differs by from their linearised prediction, per row (`correct`).
    corrections: Mutex<Vec<Correction>>,
}

/// The loaded equilibrium's difference from the linearised prediction at one set of model-form effects:
/// added to every later prediction with those effects (nearest values), so that a fit sees the exact
/// response where the first order is not enough (added loads: a payload's weight changes the tangent it
/// acts through; its moment turns with the platform).
struct Correction {
    effects: Vec<Effect>,
    per_row: Vec<Vec3>,
}

/// One factor's linearisation of the loaded response's non-linear part N (loaded - C w) about a centre c in
/// the factor's logarithm, per row: N(c) - N(0), the slope S(c) and the curvature (for the size of what the
/// linearisation neglects). A prediction at log factor x uses the centre nearest x:
/// N(x) - N(0) = (N(c) - N(0)) + S(c) (x - c) + O((x - c)^2).
struct Slope {
    kind: Kind,
    target: Target,
    factor: usize,
    centre: f64,
    offset: Vec<Vec6>,
    per_row: Vec<Vec6>,
    curvature: Vec<Vec6>,
}

/// A linearisation of the non-linear part is re-centred at the fitted factor where what it neglects exceeds
/// this many standard deviations at some row: the fit's prediction is then that of the loaded equilibrium
/// to a tenth of the noise, however far the factor is from 1 (a first order about the nominal model
/// mispredicted link compliances of 0.535 and 1.6 by several sigma at 1 um).
const RECENTRE_SIGMA: f64 = 0.1;

/// Step in the logarithm of a compliance factor by which the non-linear part's derivative is differenced
/// (central): it is smooth in the factor, and 10% keeps the difference far above the equilibria's 1e-8.
const LOG_FACTOR_STEP: f64 = 0.1;

impl<'a> Problem<'a> {
    /// Evaluates the model at every pose of `data` once (and the loaded equilibrium of every row when asked or
    /// needed); a pose it cannot evaluate is a data error.
    pub fn new(
        model: &'a Manipulator,
        terms: &'a [Effect],
        data: &'a Dataset,
        weights: Vec<f64>,
        loaded_mode: bool,
        with_loaded: bool,
    ) -> Result<Self, DiagnoseError> {
        let mut pose_of = vec![0; data.rows.len()];
        for (k, p) in data.poses.iter().enumerate() {
            for &r in &p.rows {
                pose_of[r] = k;
            }
        }
        let mut state = model.new_state();
        let fails = |id: &str, line: usize, why: PoseError| DiagnoseError::Pose { pose_id: id.into(), line, why };
        let poses = data
            .poses
            .iter()
            .map(|p| {
                PoseModel::at(model, &Frame::translation(p.position), &mut state)
                    .map_err(|why| fails(&p.id, data.rows[p.rows[0]].line, why))
            })
            .collect::<Result<Vec<_>, _>>()?;
        // The linear nominal (`--linear`) is first order throughout: where the only load at rest is a
        // payload, its rest displacement is C times the payload's weight, as the gravity effects are
        // predicted there (a corrected file carrying the payload `--model-out` wrote then diagnoses as the
        // effect did). Preloads and weighed chain masses settle exactly.
        let payload_only = model.payload.is_some() && model.legs.iter().all(|l| l.unloaded_at_placement());
        let rest = if !loaded_mode && payload_only {
            data.poses
                .iter()
                .zip(&poses)
                .map(|(p, pm)| pm.compliance * model.weight(&Frame::translation(p.position)).0)
                .collect()
        } else if model.loaded_at_rest() {
            data.poses
                .iter()
                .map(|p| {
                    settled(model, p.position, &Vec6::zeros(), &mut state)
                        .map(|d| d.displacement)
                        .map_err(|e| fails(&p.id, data.rows[p.rows[0]].line, e))
                })
                .collect::<Result<Vec<_>, _>>()?
        } else {
            vec![Vec6::zeros(); data.poses.len()]
        };
        let (loaded, tangent) = if with_loaded || loaded_mode {
            let rows = data.rows.iter().zip(&pose_of).map(|(r, &k)| {
                let d = settled(model, r.position, &r.wrench, &mut state).map_err(|e| fails(&r.pose_id, r.line, e))?;
                let c = d.compliance.or_else(|| d.held.stiffness.try_inverse()).unwrap_or(poses[k].compliance);
                Ok((d.displacement, (c + c.transpose()) * 0.5))
            });
            let both: Vec<(Vec6, Mat6)> = rows.collect::<Result<_, DiagnoseError>>()?;
            let (l, t): (Vec<Vec6>, Vec<Mat6>) = both.into_iter().unzip();
            (Some(l), Some(t))
        } else {
            (None, None)
        };
        Ok(Problem {
            model,
            terms,
            data,
            weights,
            loaded_mode,
            gravity: gravity_of(model),
            poses,
            rest,
            loaded,
            tangent,
            pose_of,
            slopes: Mutex::new(Vec::new()),
            corrections: Mutex::new(Vec::new()),
        })
    }

    /// The linearisation of (loaded - C w) in ln(factor) about `centre`, for every row, for factor `i` of the
    /// spring scaling `e` (its values ignored; the other factors neutral): computed when first needed, and
    /// kept.
    fn linearisation(&self, e: &Effect, i: usize, centre: f64) -> Result<(), PoseError> {
        let mut cache = self.slopes.lock().unwrap_or_else(|p| p.into_inner());
        let same = |s: &Slope| s.kind == e.kind && s.target == e.target && s.factor == i && s.centre == centre;
        if cache.iter().any(same) {
            return Ok(());
        }
        let part = |log_factor: f64| -> Result<Vec<Vec6>, PoseError> {
            let mut values = vec![1.0; e.values.len()];
            values[i] = log_factor.exp();
            let m = scaled(self.model, &[Effect { values, ..e.clone() }]);
            let mut state = m.new_state();
            let mut compliance = Vec::with_capacity(self.poses.len());
            for p in &self.data.poses {
                compliance.push(PoseModel::at(&m, &Frame::translation(p.position), &mut state)?.compliance);
            }
            let rows = self.data.rows.iter().zip(&self.pose_of);
            rows.map(|(r, &k)| {
                let d = settled(&m, r.position, &r.wrench, &mut state)?;
                Ok(d.displacement - compliance[k] * r.wrench)
            })
            .collect()
        };
        let (plus, minus) = (part(centre + LOG_FACTOR_STEP)?, part(centre - LOG_FACTOR_STEP)?);
        let nominal: Vec<Vec6> = match &self.loaded {
            Some(l) => (0..self.data.rows.len())
                .map(|r| l[r] - self.poses[self.pose_of[r]].compliance * self.data.rows[r].wrench)
                .collect(),
            None => vec![Vec6::zeros(); self.data.rows.len()],
        };
        let at_centre = if centre == 0.0 { nominal.clone() } else { part(centre)? };
        let h = LOG_FACTOR_STEP;
        cache.push(Slope {
            kind: e.kind,
            target: e.target.clone(),
            factor: i,
            centre,
            offset: at_centre.iter().zip(&nominal).map(|(c, n)| c - n).collect(),
            per_row: plus.iter().zip(&minus).map(|(a, b)| (a - b) / (2.0 * h)).collect(),
            curvature: plus.iter().zip(&minus).zip(&at_centre).map(|((a, b), c)| (a + b - 2.0 * c) / (h * h)).collect(),
        });
        Ok(())
    }

    /// Of the kept linearisations for factor `i` of `e`, the one whose centre is nearest log factor `x`.
    fn nearest<'c>(cache: &'c [Slope], e: &Effect, i: usize, x: f64) -> Option<&'c Slope> {
        cache
            .iter()
            .filter(|s| s.kind == e.kind && s.target == e.target && s.factor == i)
            .min_by(|a, b| (a.centre - x).abs().total_cmp(&(b.centre - x).abs()))
    }

    /// The non-linear part's change, N(x) - N(0) per row, for factor `i` of `e` at log factor `x`, from the
    /// kept linearisation whose centre is nearest `x` (the centre 0 first).
    fn nonlinear_change(&self, e: &Effect, i: usize, x: f64) -> Result<Vec<Vec6>, PoseError> {
        self.linearisation(e, i, 0.0)?;
        let cache = self.slopes.lock().unwrap_or_else(|p| p.into_inner());
        let s = Self::nearest(&cache, e, i, x).expect("made above");
        Ok(s.offset.iter().zip(&s.per_row).map(|(o, d)| o + d * (x - s.centre)).collect())
    }

    /// Where the linearisations of the non-linear part are not accurate enough at the fitted `effects`: the
    /// spring scalings' factors (their effect, factor index and log factor) whose nearest centre neglects a
    /// term 1/2 curvature (x - c)^2 above a tenth of a row's standard deviation somewhere. Loaded mode only.
    pub fn to_recentre(&self, effects: &[Effect]) -> Vec<(Effect, usize, f64)> {
        if !(self.loaded_mode && self.loaded.is_some()) {
            return Vec::new();
        }
        let cache = self.slopes.lock().unwrap_or_else(|p| p.into_inner());
        let mut out = Vec::new();
        for e in effects.iter().filter(|e| e.scales_springs()) {
            for (i, v) in e.values.iter().enumerate() {
                let x = v.ln();
                let Some(s) = Self::nearest(&cache, e, i, x) else { continue };
                let gap = x - s.centre;
                let neglected = s
                    .curvature
                    .iter()
                    .zip(&self.weights)
                    .map(|(k, w)| 0.5 * k.fixed_rows::<3>(0).amax() * gap * gap * w)
                    .fold(0.0, f64::max);
                if neglected > RECENTRE_SIGMA && x.is_finite() {
                    out.push((e.clone(), i, x));
                }
            }
        }
        out
    }

    /// Makes the linearisations `to_recentre` asked for (centred at the fitted log factors).
    pub fn recentre(&self, at: &[(Effect, usize, f64)]) -> Result<(), PoseError> {
        for (e, i, x) in at {
            self.linearisation(e, *i, *x)?;
        }
        Ok(())
    }

    /// Observations of `rows` (three translations per row).
    pub fn observations(&self, rows: &[usize]) -> usize {
        3 * rows.len()
    }

    /// Predicted displacements (mm) of `rows` with the model's own effects and `effects`.
    pub fn predict(&self, effects: &[Effect], rows: &[usize]) -> Result<Vec<Vec3>, PoseError> {
        let scalings: Vec<Effect> = effects.iter().filter(|e| e.scales_springs()).cloned().collect();
        let terms: Vec<Effect> = self.terms.iter().chain(effects).filter(|e| !e.scales_springs()).cloned().collect();
        let mut poses: Vec<Option<PoseModel>> = vec![None; self.poses.len()];
        let changed = if scalings.is_empty() { None } else { Some(scaled(self.model, &scalings)) };
        let mut state = changed.as_ref().map(|m| m.new_state());
        // Loaded mode: the non-linear part moves with each factor too (first order in its logarithm).
        let changes: Vec<Vec<Vec6>> = if self.loaded_mode && self.loaded.is_some() {
            let each = scalings.iter().flat_map(|e| e.values.iter().enumerate().map(move |(i, v)| (e, i, v.ln())));
            each.map(|(e, i, log_factor)| self.nonlinear_change(e, i, log_factor)).collect::<Result<_, PoseError>>()?
        } else {
            Vec::new()
        };
        let mut out = Vec::with_capacity(rows.len());
        for &r in rows {
            let k = self.pose_of[r];
            let row = &self.data.rows[r];
            let pm = match (&changed, &mut state) {
                (Some(m), Some(s)) => {
                    if poses[k].is_none() {
                        poses[k] = Some(PoseModel::at(m, &Frame::translation(row.position), s)?);
                    }
                    poses[k].as_ref().expect("just set")
                }
                _ => &self.poses[k],
            };
            let linear = self.rest[k] + self.poses[k].compliance * row.wrench;
            // Scaled springs move the response by (C' - C) w, and the loaded one's non-linear part by its
            // slope in each factor's logarithm.
            let change =
                (pm.compliance - self.poses[k].compliance) * row.wrench + changes.iter().map(|c| c[r]).sum::<Vec6>();
            let (base, nonlinear) = match (&self.loaded, self.loaded_mode) {
                (Some(l), true) => (l[r] + change, None),
                (Some(l), false) => (linear + change, Some(l[r] - linear)),
                (None, _) => (linear + change, None),
            };
            // Loaded mode: a term that loads the platform acts through the compliance where it stands.
            let tangent = match (&self.tangent, self.loaded_mode) {
                (Some(t), true) => Some(t[r] + (pm.compliance - self.poses[k].compliance)),
                _ => None,
            };
            out.push(pm.displacement(row, &base, nonlinear.as_ref(), &terms, &self.gravity, tangent.as_ref()));
        }
        if let Some(c) = self.correction_for(effects) {
            for (o, &r) in out.iter_mut().zip(rows) {
                *o += c[r];
            }
        }
        Ok(out)
    }

    /// The model-form effects of a set (those `with_model_effects` builds into the robot).
    fn model_form(effects: &[Effect]) -> Vec<Effect> {
        effects.iter().filter(|e| e.kind.form() == Form::Model).cloned().collect()
    }

    /// The kept correction for these effects: of those made for exactly their model-form kinds and
    /// targets, the one whose values are nearest. Loaded mode only.
    fn correction_for(&self, effects: &[Effect]) -> Option<Vec<Vec3>> {
        if !self.loaded_mode {
            return None;
        }
        let mine = Self::model_form(effects);
        if mine.is_empty() {
            return None;
        }
        let cache = self.corrections.lock().unwrap_or_else(|p| p.into_inner());
        let same = |c: &&Correction| {
            c.effects.len() == mine.len()
                && c.effects.iter().zip(&mine).all(|(a, b)| a.kind == b.kind && a.target == b.target)
        };
        let distance = |c: &Correction| -> f64 {
            c.effects
                .iter()
                .zip(&mine)
                .flat_map(|(a, b)| a.values.iter().zip(&b.values).map(|(x, y)| (x - y).powi(2)))
                .sum()
        };
        cache.iter().filter(same).min_by(|a, b| distance(a).total_cmp(&distance(b))).map(|c| c.per_row.clone())
    }

    /// Compares the prediction with `effects` against the loaded equilibrium of the robot with their
    /// model-form part built in (exactly what `synth` computes); where some row misses by more than
    /// `RECENTRE_SIGMA` standard deviations, keeps the difference at these values as a correction of later
    /// predictions and returns true (the caller refits). Loaded mode only.
    pub fn correct(&self, effects: &[Effect]) -> Result<bool, PoseError> {
        let mine = Self::model_form(effects);
        if !(self.loaded_mode && self.loaded.is_some()) || mine.is_empty() {
            return Ok(false);
        }
        let all: Vec<usize> = (0..self.data.rows.len()).collect();
        let robot = with_model_effects(self.model, &mine);
        let exact = Problem::new(&robot, self.terms, self.data, self.weights.clone(), true, true)
            .map_err(|e| match e {
                DiagnoseError::Pose { why, .. } => why,
                _ => PoseError::NotFinite,
            })?
            .predict(&[], &all)?;
        let predicted = self.predict(&mine, &all)?;
        let miss = (0..all.len()).map(|r| (exact[r] - predicted[r]).amax() * self.weights[r]).fold(0.0, f64::max);
        if miss.is_nan() || miss <= RECENTRE_SIGMA {
            return Ok(false);
        }
        let applied = self.correction_for(&mine).unwrap_or_else(|| vec![Vec3::zeros(); all.len()]);
        let per_row = (0..all.len()).map(|r| applied[r] + exact[r] - predicted[r]).collect();
        self.corrections.lock().unwrap_or_else(|p| p.into_inner()).push(Correction { effects: mine, per_row });
        Ok(true)
    }

    /// Weighted residuals (measured - predicted) / sigma, three per row.
    pub fn residuals(&self, effects: &[Effect], rows: &[usize]) -> Result<DVector<f64>, PoseError> {
        let p = self.predict(effects, rows)?;
        let mut r = DVector::zeros(3 * rows.len());
        for (i, (&row, pred)) in rows.iter().zip(&p).enumerate() {
            let d = self.data.rows[row].displacement - pred;
            for c in 0..3 {
                r[3 * i + c] = d[c] * self.weights[row];
            }
        }
        Ok(r)
    }
}

/// The loaded equilibrium under `wrench` with the platform commanded to `position`: the legs placed there
/// first (their actuators fixed by the rigid inverse kinematics), then the platform settles.
pub fn settled(
    m: &Manipulator,
    position: Vec3,
    wrench: &Vec6,
    state: &mut ManipulatorState,
) -> Result<crate::platform::loaded::Deflection, PoseError> {
    let pose = Frame::translation(position);
    m.place(&pose, state).map_err(PoseError::Fails)?;
    m.deflect(&pose, wrench, None, state).map_err(PoseError::NoLoadedEquilibrium)
}

/// An effect to fit: its kind, target and, for a leg's end-point error, the directions the data can see
/// (an orthonormal basis of eps, 6 x r); its parameters are the coordinates in that basis (gravity-offset
/// has a basis too: its mass and its first moment across gravity, `select::centre_basis`). A compliance
/// factor is fitted as its logarithm, so it stays positive whatever the data (a factor that walked to -2.7
/// made a fit fail); gravity-offset as (m, m c), which is linear in what is measured.
#[derive(Clone, Debug, PartialEq)]
pub struct Candidate {
    /// The effect's kind.
    pub kind: Kind,
    /// Its target.
    pub target: Target,
    /// For leg geometry: the visible directions (6 x dim); the parameters are coordinates along them.
    pub basis: Option<DMatrix<f64>>,
}

impl Candidate {
    /// A candidate without a basis.
    pub fn new(kind: Kind, target: Target) -> Candidate {
        Candidate { kind, target, basis: None }
    }

    /// Number of parameters.
    pub fn dim(&self) -> usize {
        self.basis.as_ref().map_or(self.kind.values().0, |b| b.ncols())
    }

    /// Whether the parameter is the logarithm of the effect's value.
    fn logarithmic(&self) -> bool {
        self.kind.scales_springs()
    }

    /// The parameters of no effect.
    pub fn neutral(&self) -> Vec<f64> {
        let v = if self.basis.is_some() || self.logarithmic() { 0.0 } else { self.kind.neutral() };
        vec![v; self.dim()]
    }

    /// The effect with parameters `p`.
    pub fn effect(&self, p: &[f64]) -> Effect {
        let values = match &self.basis {
            Some(b) => (b * DVector::from_column_slice(p)).iter().copied().collect(),
            None if self.logarithmic() => p.iter().map(|v| v.exp()).collect(),
            None => p.to_vec(),
        };
        Effect { kind: self.kind, target: self.target.clone(), values }
    }

    /// The values a user reads for parameters `p` with standard errors `se` (the delta method through the
    /// exponential of a logarithmic factor; a gravity-offset's centre c = (m c) / m; leg-geometry's
    /// coordinates as they are).
    pub fn reported(&self, p: &[f64], se: &[f64]) -> (Vec<f64>, Vec<f64>) {
        if self.kind == Kind::LegGeometry {
            return (p.to_vec(), se.to_vec());
        }
        let effect = self.effect(p);
        let values = effect.user_values();
        let se = match self.kind {
            _ if self.logarithmic() => values.iter().zip(se).map(|(v, s)| v * s).collect(),
            Kind::GravityOffset => {
                // c = s / m with s = m c: dc = ds / m - s dm / m^2 (their covariance neglected); the moment's
                // standard error in each base axis from the fitted directions (across gravity, and along it
                // where the data see it).
                let (m, b) = (p[0], self.basis.as_ref().expect("gravity-offset has its basis"));
                let mut out = vec![se[0]];
                for r in 1..4 {
                    let ds = (1..b.ncols()).map(|c| (b[(r, c)] * se[c]).powi(2)).sum::<f64>().sqrt();
                    out.push(((ds / m).powi(2) + (effect.values[r] * se[0] / (m * m)).powi(2)).sqrt());
                }
                out
            }
            _ => se.to_vec(),
        };
        (values, se)
    }

    /// `NAME[:TARGET]`, as on the command line.
    pub fn label(&self) -> String {
        match &self.target {
            Target::None => self.kind.name().to_string(),
            t => format!("{}:{t}", self.kind.name()),
        }
    }
}

/// Effects of a set of candidates for a concatenated parameter vector.
pub fn effects_of(cands: &[Candidate], theta: &[f64]) -> Vec<Effect> {
    let mut at = 0;
    cands
        .iter()
        .map(|c| {
            let e = c.effect(&theta[at..at + c.dim()]);
            at += c.dim();
            e
        })
        .collect()
}

/// A Levenberg-Marquardt fit of candidates' parameters.
#[derive(Clone, Debug)]
pub struct Fit {
    /// The fitted parameters, candidates concatenated.
    pub theta: Vec<f64>,
    /// Weighted sum of squared residuals (chi-square with known sigma).
    pub ssr: f64,
    /// Covariance of theta: (J^T J)^-1 for weighted residuals (None if singular).
    pub covariance: Option<DMatrix<f64>>,
    /// The weighted residuals at the fit.
    pub residuals: DVector<f64>,
}

/// The weighted residuals' Jacobian with respect to theta's entries from `from` on (all when 0), by central
/// differences: a candidate's signature is its part of it.
pub fn jacobian(
    problem: &Problem,
    cands: &[Candidate],
    theta: &[f64],
    from: usize,
    rows: &[usize],
) -> Result<DMatrix<f64>, PoseError> {
    let n = problem.observations(rows);
    let mut j = DMatrix::zeros(n, theta.len() - from);
    for k in from..theta.len() {
        let h = 1e-6 * theta[k].abs().max(1e-2);
        let mut t = theta.to_vec();
        t[k] = theta[k] + h;
        let plus = problem.residuals(&effects_of(cands, &t), rows)?;
        t[k] = theta[k] - h;
        let minus = problem.residuals(&effects_of(cands, &t), rows)?;
        j.set_column(k - from, &((plus - minus) / (2.0 * h)));
    }
    Ok(j)
}

/// Levenberg-Marquardt from the neutral values (or `start`), on `rows`; in loaded mode, refitted (at most
/// `RECENTRES` times) from where it ended while a spring scaling's fitted factor is far enough from the
/// centre of its non-linear part's linearisation that the prediction would miss the loaded equilibrium by a
/// tenth of the noise (`Problem::to_recentre`).
pub fn fit(problem: &Problem, cands: &[Candidate], rows: &[usize], start: Option<&[f64]>) -> Result<Fit, PoseError> {
    let mut f = fit_once(problem, cands, rows, start)?;
    for _ in 0..RECENTRES {
        let at = problem.to_recentre(&effects_of(cands, &f.theta));
        if at.is_empty() {
            break;
        }
        problem.recentre(&at)?;
        f = fit_once(problem, cands, rows, Some(&f.theta))?;
    }
    Ok(f)
}

/// Re-centrings of the non-linear part's linearisations per fit: each brings the neglected term down by
/// the square of the factor's step, so two or three suffice.
const RECENTRES: usize = 3;

/// One Levenberg-Marquardt fit from the neutral values (or `start`), on `rows` (`lm::solve`); the
/// covariance only where the data see every parameter.
fn fit_once(problem: &Problem, cands: &[Candidate], rows: &[usize], start: Option<&[f64]>) -> Result<Fit, PoseError> {
    let theta: Vec<f64> = match start {
        Some(s) => s.to_vec(),
        None => cands.iter().flat_map(|c| c.neutral()).collect(),
    };
    let s = lm::solve(&OnCandidates { problem, cands, rows, parameters: theta.len() }, theta)?;
    let covariance = s.full_rank().then_some(s.covariance);
    Ok(Fit { theta: s.point, ssr: s.rss, covariance, residuals: s.residuals })
}

/// The candidates' fit on `rows` as the least-squares core sees it: their parameters, the weighted residuals
/// and the Jacobian of the prediction by central differences (the negated `jacobian`).
struct OnCandidates<'p, 'a> {
    problem: &'p Problem<'a>,
    cands: &'p [Candidate],
    rows: &'p [usize],
    parameters: usize,
}

impl LeastSquares for OnCandidates<'_, '_> {
    type Point = Vec<f64>;
    type Error = PoseError;

    fn parameters(&self) -> usize {
        self.parameters
    }

    fn evaluate(&self, theta: &Vec<f64>, jac: Option<&mut DMatrix<f64>>) -> Result<DVector<f64>, PoseError> {
        let r = self.problem.residuals(&effects_of(self.cands, theta), self.rows)?;
        if let Some(jac) = jac {
            *jac = -jacobian(self.problem, self.cands, theta, 0, self.rows)?;
        }
        Ok(r)
    }

    fn step(&self, theta: &Vec<f64>, step: &DVector<f64>) -> Vec<f64> {
        theta.iter().zip(step.iter()).map(|(t, s)| t + s).collect()
    }
}
