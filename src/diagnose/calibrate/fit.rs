//! One fit of a calibration: its parameters (set-ups' frames and targets on their manifolds, then the
//! effects'), their start (Kabsch's registration from the nominal tool points) and the Levenberg-Marquardt
//! fit from it.

use nalgebra::{DMatrix, DVector};

use super::effect::ArmEffect;
use super::problem::PositionProblem;
use crate::diagnose::positions::Observed;
use crate::kinematics::frame::{rotation_from_vector, Mat3, Vec3};
use crate::platform::manipulator::ManipulatorState;

/// Relative singular value of the column-scaled Jacobian below which a direction is not identifiable: a
/// combination of parameters that moves the points by less than a millionth of what each does alone would
/// amplify the noise a millionfold.
const IDENTIFIABLE: f64 = 1e-6;

/// The parameters of one fit.
#[derive(Clone, Debug)]
pub(super) struct Params {
    pub(super) rotations: Vec<Mat3>,
    pub(super) translations: Vec<Vec3>,
    pub(super) targets: Vec<Vec3>,
    /// Each target's axes in the tool frame (fitted for the targets whose orientation is measured).
    pub(super) turns: Vec<Mat3>,
    /// Each effect's parameters.
    pub(super) effects: Vec<Vec<f64>>,
}

/// A fit: its parameters, weighted residual sum of squares, rows, rank, covariance (unscaled) and the
/// directions it could not see.
#[derive(Clone, Debug)]
pub(super) struct PositionFit {
    pub(super) params: Params,
    pub(super) rss: f64,
    pub(super) observations: usize,
    pub(super) rank: usize,
    /// (J^T J)^+ of the weighted Jacobian, in the parameters' order.
    pub(super) covariance: DMatrix<f64>,
    /// Directions of the parameters the data cannot see: (parameter index, weight) of each, in the
    /// column-scaled parameters.
    pub(super) hidden: Vec<Vec<(usize, f64)>>,
}

impl PositionFit {
    pub(super) fn dof(&self) -> usize {
        self.observations.saturating_sub(self.rank).max(1)
    }
}

impl PositionProblem<'_> {
    /// The starting parameters: each set-up's frame from the nominal tool points (Kabsch's fit of the
    /// rotation), targets at the tool point, effects zero.
    pub(super) fn start(&self, rows: &[usize], effects: &[ArmEffect]) -> Params {
        let setups = self.data.setups.len();
        let mut params = Params {
            rotations: vec![Mat3::identity(); setups],
            translations: vec![Vec3::zeros(); setups],
            targets: vec![Vec3::zeros(); self.data.targets.len()],
            turns: vec![Mat3::identity(); self.data.targets.len()],
            effects: effects.iter().map(|e| vec![0.0; e.size()]).collect(),
        };
        if !self.absolute {
            return params;
        }
        let mut state = self.m.new_state();
        for s in 0..setups {
            let pairs: Vec<(Vec3, Vec3)> = rows
                .iter()
                .filter(|&&r| matches!(self.data.rows[r].observed, Observed::Position { setup, .. } if setup == s))
                .filter_map(|&r| {
                    let f = self.data.rows[r].nominal_frame(self.m, &mut state)?;
                    Some((f.pos, self.measured(r)))
                })
                .collect();
            if pairs.is_empty() {
                continue;
            }
            let n = pairs.len() as f64;
            let (ca, cb) = pairs.iter().fold((Vec3::zeros(), Vec3::zeros()), |(a, b), (p, q)| (a + p / n, b + q / n));
            // Kabsch: the rotation nearest the cross-covariance sum (q - cb) (p - ca)^T.
            let h = pairs.iter().fold(Mat3::zeros(), |h, (p, q)| h + (q - cb) * (p - ca).transpose());
            let rotation = nearest_rotation(&h);
            params.rotations[s] = rotation;
            params.translations[s] = cb - rotation * ca;
        }
        // Each measured target's axes in the tool frame: the mean (projected back to a rotation) of
        // R_tool^T R^T M over its rows, M the measured orientation.
        for t in (0..self.data.targets.len()).filter(|&t| self.turn_of[t].is_some()) {
            let mut sum = Mat3::zeros();
            for &r in rows {
                if let Observed::Orientation { target, setup, at } = self.data.rows[r].observed {
                    if target == t {
                        if let Some(f) = self.data.rows[r].nominal_frame(self.m, &mut state) {
                            sum += f.rot.transpose() * params.rotations[setup].transpose() * at;
                        }
                    }
                }
            }
            params.turns[t] = nearest_rotation(&sum);
        }
        params
    }

    /// Levenberg-Marquardt over the parameters on `rows`, from `start`.
    pub(super) fn fit(&self, rows: &[usize], effects: &[ArmEffect], start: &Params) -> Option<PositionFit> {
        let p = self.nuisance_count() + effects.iter().map(ArmEffect::size).sum::<usize>();
        let n = 3 * rows.len();
        let mut params = start.clone();
        let mut state = self.m.new_state();
        let mut jac_row = DMatrix::zeros(3, p);
        let evaluate =
            |params: &Params, state: &mut ManipulatorState, jac_row: &mut DMatrix<f64>, with_jacobian: bool| {
                let mut jac = DMatrix::zeros(if with_jacobian { n } else { 0 }, p);
                let mut e = DVector::zeros(n);
                for (i, &r) in rows.iter().enumerate() {
                    let prediction = self.predict(r, effects, params, state, with_jacobian.then_some(&mut *jac_row))?;
                    let residual = (self.measured(r) - prediction) * self.weight[r];
                    e.fixed_rows_mut::<3>(3 * i).copy_from(&residual);
                    if with_jacobian {
                        jac.view_mut((3 * i, 0), (3, p)).copy_from(&*jac_row);
                    }
                }
                Some((jac, e))
            };
        let mut lambda = 1e-6;
        let (mut jac, mut e) = evaluate(&params, &mut state, &mut jac_row, true)?;
        let mut rss = e.norm_squared();
        if p == 0 {
            // Nothing to fit (displacements, no effect): the model as it is.
            return Some(PositionFit {
                params,
                rss,
                observations: n,
                rank: 0,
                covariance: DMatrix::zeros(0, 0),
                hidden: Vec::new(),
            });
        }
        for _ in 0..100 {
            let scale = column_scales(&jac);
            let scaled = DMatrix::from_fn(n, p, |i, j| jac[(i, j)] / scale[j]);
            let svd = scaled.clone().svd(true, true);
            let (u, v_t) = (svd.u.as_ref()?, svd.v_t.as_ref()?);
            let top = svd.singular_values.max();
            let ue = u.transpose() * &e;
            let mut improved = false;
            while lambda < 1e12 {
                let mut step = DVector::zeros(p);
                for (k, &s) in svd.singular_values.iter().enumerate() {
                    if s > IDENTIFIABLE * top {
                        let damped = s / (s * s + lambda * top * top);
                        step += v_t.row(k).transpose() * (ue[k] * damped);
                    }
                }
                let step = step.component_div(&scale);
                let trial = self.apply(&params, &step);
                if let Some((_, e_trial)) = evaluate(&trial, &mut state, &mut jac_row, false) {
                    let rss_trial = e_trial.norm_squared();
                    if rss_trial < rss {
                        let converged = rss - rss_trial <= 1e-10 * rss.max(1e-300);
                        params = trial;
                        rss = rss_trial;
                        // A floor on the damping: steps along directions the data barely see (below a
                        // hundredth of a percent of the best seen) stay damped.
                        lambda = (lambda / 10.0).max(1e-8);
                        improved = !converged;
                        break;
                    }
                }
                lambda *= 10.0;
            }
            if !improved {
                break;
            }
            (jac, e) = evaluate(&params, &mut state, &mut jac_row, true)?;
            rss = e.norm_squared();
        }
        // Rank and covariance at the solution, on the column-scaled Jacobian.
        let scale = column_scales(&jac);
        let scaled = DMatrix::from_fn(n, p, |i, j| jac[(i, j)] / scale[j]);
        let svd = scaled.svd(false, true);
        let v_t = svd.v_t.as_ref()?;
        let top = svd.singular_values.max();
        let mut covariance = DMatrix::zeros(p, p);
        let mut hidden = Vec::new();
        let mut rank = 0;
        for (k, &s) in svd.singular_values.iter().enumerate() {
            let v = v_t.row(k).transpose();
            if s > IDENTIFIABLE * top {
                rank += 1;
                covariance += &v * v.transpose() / (s * s);
            } else {
                // Named in the column-scaled parameters (each column's effect on the points at unit norm), so
                // that a rotation and a translation weigh alike.
                hidden.push((0..p).filter(|&j| v[j].abs() > 0.05).map(|j| (j, v[j])).collect());
            }
        }
        let covariance = DMatrix::from_fn(p, p, |i, j| covariance[(i, j)] / (scale[i] * scale[j]));
        Some(PositionFit { params, rss, observations: n, rank, covariance, hidden })
    }

    pub(super) fn apply(&self, params: &Params, step: &DVector<f64>) -> Params {
        let mut next = params.clone();
        let mut k = 0;
        if self.absolute {
            for s in 0..self.data.setups.len() {
                next.translations[s] += Vec3::new(step[k], step[k + 1], step[k + 2]);
                let turn = Vec3::new(step[k + 3], step[k + 4], step[k + 5]);
                // A rotation built from products drifts off orthogonality: project it back.
                next.rotations[s] = nearest_rotation(&(rotation_from_vector(&turn) * params.rotations[s]));
                // The translation follows the rotation about the origin, as d(R y + t) = d x (R y) + dt says.
                k += 6;
            }
            for t in 0..self.data.targets.len() {
                next.targets[t] += Vec3::new(step[k], step[k + 1], step[k + 2]);
                k += 3;
            }
            // A target's turn e is taken in the tool's axes: R_target becomes exp(e) R_target.
            for t in (0..self.data.targets.len()).filter(|&t| self.turn_of[t].is_some()) {
                let turn = Vec3::new(step[k], step[k + 1], step[k + 2]);
                next.turns[t] = nearest_rotation(&(rotation_from_vector(&turn) * params.turns[t]));
                k += 3;
            }
        }
        for values in &mut next.effects {
            for v in values {
                *v += step[k];
                k += 1;
            }
        }
        next
    }
}

/// Each column's norm, the scale its parameter is fitted and judged in; a column of zeros (a parameter that
/// moves nothing here) keeps scale 1, so that round-off in the steps is not blown up by dividing by it.
/// The rotation nearest `m` (Frobenius norm): U V^T of its SVD, with the sign that keeps it proper.
pub(super) fn nearest_rotation(m: &Mat3) -> Mat3 {
    let svd = m.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else { return Mat3::identity() };
    let mut d = Mat3::identity();
    if (u * v_t).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    u * d * v_t
}

pub(super) fn column_scales(jac: &DMatrix<f64>) -> DVector<f64> {
    DVector::from_iterator(jac.ncols(), jac.column_iter().map(|c| if c.norm() > 0.0 { c.norm() } else { 1.0 }))
}
