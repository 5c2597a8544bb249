//! Predictions of the measured displacements with effects, their weighted residuals, and the
//! Levenberg-Marquardt fit of effect parameters (numerical Jacobian, so every signature is the real
//! model's derivative), with the covariance of the parameters.

use nalgebra::{DMatrix, DVector};

use super::data::Dataset;
use super::error::{DiagnoseError, PoseError};
use super::measurement::{gravity_of, PoseModel};
use crate::kinematics::frame::{Frame, Vec3, Vec6};
use crate::model::effect::{scaled, Effect, Kind, Target};
use crate::platform::manipulator::Manipulator;

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
    /// Per row: the displacement of the loaded equilibrium (when computed).
    loaded: Option<Vec<Vec6>>,
    /// Per row: index of its pose.
    pose_of: Vec<usize>,
}

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
        let poses =
            data.poses
                .iter()
                .map(|p| {
                    PoseModel::at(model, &Frame::translation(p.position), &mut state).map_err(|why| {
                        DiagnoseError::Pose { pose_id: p.id.clone(), line: data.rows[p.rows[0]].line, why }
                    })
                })
                .collect::<Result<Vec<_>, _>>()?;
        let loaded = if with_loaded || loaded_mode {
            let mut out = Vec::with_capacity(data.rows.len());
            for r in &data.rows {
                let pose = Frame::translation(r.position);
                let d = model.deflect(&pose, &r.wrench, None, &mut state).map_err(|e| DiagnoseError::Pose {
                    pose_id: r.pose_id.clone(),
                    line: r.line,
                    why: PoseError::NoLoadedEquilibrium(e),
                })?;
                out.push(d.displacement);
            }
            Some(out)
        } else {
            None
        };
        Ok(Problem { model, terms, data, weights, loaded_mode, gravity: gravity_of(model), poses, loaded, pose_of })
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
            // With scaled springs the loaded response moves with the linear one (first order).
            let loaded = self.loaded.as_ref().map(|l| l[r] + (pm.compliance - self.poses[k].compliance) * row.wrench);
            out.push(pm.displacement(&row.wrench, loaded.as_ref(), &terms, self.loaded_mode, &self.gravity));
        }
        Ok(out)
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

/// An effect to fit: its kind, target and, for a leg's end-point error, the directions the data can see
/// (an orthonormal basis of eps, 6 x r); its parameters are the coordinates in that basis.
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
    /// Number of parameters.
    pub fn dim(&self) -> usize {
        self.basis.as_ref().map_or(self.kind.values().0, |b| b.ncols())
    }

    /// The parameters of no effect.
    pub fn neutral(&self) -> Vec<f64> {
        vec![if self.basis.is_some() { 0.0 } else { self.kind.neutral() }; self.dim()]
    }

    /// The effect with parameters `p`.
    pub fn effect(&self, p: &[f64]) -> Effect {
        let values = match &self.basis {
            Some(b) => (b * DVector::from_column_slice(p)).iter().copied().collect(),
            None => p.to_vec(),
        };
        Effect { kind: self.kind, target: self.target.clone(), values }
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

/// Levenberg-Marquardt from the neutral values (or `start`), on `rows`.
pub fn fit(problem: &Problem, cands: &[Candidate], rows: &[usize], start: Option<&[f64]>) -> Result<Fit, PoseError> {
    let mut theta: Vec<f64> = match start {
        Some(s) => s.to_vec(),
        None => cands.iter().flat_map(|c| c.neutral()).collect(),
    };
    let mut r = problem.residuals(&effects_of(cands, &theta), rows)?;
    let mut ssr = r.norm_squared();
    let mut mu = 1e-3;
    let mut jac = jacobian(problem, cands, &theta, 0, rows)?;
    for _ in 0..60 {
        if theta.is_empty() {
            break;
        }
        let jtj = jac.transpose() * &jac;
        let g = jac.transpose() * &r;
        let mut improved = false;
        for _ in 0..12 {
            let mut a = jtj.clone();
            for k in 0..a.nrows() {
                a[(k, k)] += mu * jtj[(k, k)].max(1e-12);
            }
            let Some(step) = a.cholesky().map(|c| c.solve(&(-&g))) else {
                mu *= 10.0;
                continue;
            };
            let trial: Vec<f64> = theta.iter().zip(step.iter()).map(|(t, s)| t + s).collect();
            let Ok(rt) = problem.residuals(&effects_of(cands, &trial), rows) else {
                mu *= 10.0;
                continue;
            };
            let st = rt.norm_squared();
            if st < ssr {
                let done = (ssr - st) <= 1e-12 * ssr.max(1e-300)
                    || step.norm() <= 1e-12 * (1.0 + trial.iter().map(|v| v.abs()).fold(0.0, f64::max));
                theta = trial;
                r = rt;
                ssr = st;
                mu = (mu / 10.0).max(1e-12);
                improved = !done;
                break;
            }
            mu *= 10.0;
        }
        if !improved {
            break;
        }
        jac = jacobian(problem, cands, &theta, 0, rows)?;
    }
    let covariance = (jac.transpose() * &jac).try_inverse();
    Ok(Fit { theta, ssr, covariance, residuals: r })
}
