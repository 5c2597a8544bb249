//! One fit of a calibration: its parameters (set-ups' frames and targets on their manifolds, then the
//! effects'), their start (Kabsch's registration from the nominal tool points) and the Levenberg-Marquardt
//! fit from it.

use std::cell::RefCell;

use nalgebra::{DMatrix, DVector};

use super::effect::{ArmEffect, ArmKind};
use super::problem::PositionProblem;
use crate::diagnose::lm::{self, LeastSquares};
use crate::diagnose::positions::Observed;
use crate::kinematics::frame::{rotation_from_vector, Mat3, Vec3};
use crate::platform::manipulator::ManipulatorState;

/// Most parameters held at zero in one fit (`PositionProblem::fit`): each round holds at least one more.
const MOST_HELD: usize = 24;

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
    /// Parameters held at zero: a spring's compliance or a play fitted below zero (`held_below_zero`), and
    /// those in `tied`.
    pub(super) held: Vec<usize>,
    /// The effects' parameters held at zero (their nominal value; rigid, for a spring) because they moved
    /// with others in a direction no row sees (`tied_to_others`), each with that direction.
    pub(super) tied: Vec<(usize, Vec<(usize, f64)>)>,
    /// Each parameter's column scale (`lm::Solution::scales`).
    scales: Vec<f64>,
}

impl PositionFit {
    /// Whether the data see parameter `k` (it is in no hidden direction; a held one is seen).
    pub(super) fn sees(&self, k: usize) -> bool {
        !self.hidden.iter().any(|d| d.iter().any(|(i, _)| *i == k))
    }

    pub(super) fn dof(&self) -> usize {
        self.observations.saturating_sub(self.rank).max(1)
    }

    /// How many parameters a bound holds (a compliance or play at zero): they count as seen, held by the
    /// bound rather than the data; a tied one counts as unseen.
    pub(super) fn bounded(&self) -> usize {
        self.held.len() - self.tied.len()
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
                    let f = self.data.rows[r].nominal_frame(self.arm(r), &mut state)?;
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
                        if let Some(f) = self.data.rows[r].nominal_frame(self.arm(r), &mut state) {
                            sum += f.rot.transpose() * params.rotations[setup].transpose() * at;
                        }
                    }
                }
            }
            params.turns[t] = nearest_rotation(&sum);
        }
        params
    }

    /// Levenberg-Marquardt over the parameters on `rows`, from `start` (`lm::solve`), a compliance or a
    /// play bounded below by zero: one fitted below zero in a direction the data see is held at zero (rigid,
    /// no play) and the fit made again, until none is (`held_below_zero`). An effect whose parameters move
    /// with others (the set-up's, or an earlier effect's) in a direction no row sees is fitted in the
    /// directions the rows see: one of its parameters per such direction is held at its nominal value
    /// (`tied_to_others`), so its values are its own, not a share of the others' change.
    pub(super) fn fit(&self, rows: &[usize], effects: &[ArmEffect], start: &Params) -> Option<PositionFit> {
        let mut held: Vec<usize> = Vec::new();
        let mut tied: Vec<(usize, Vec<(usize, f64)>)> = Vec::new();
        let first = start;
        let mut start = start.clone();
        loop {
            let mut fit = self.fit_holding(rows, effects, &start, &held)?;
            fit.tied.clone_from(&tied);
            // Ties first: along a direction no row sees the fit's values are its smallest change, which may
            // lie below zero for no reason the data give; the bound then judges the values the tie leaves.
            let mixed = self.tied_to_others(effects, &fit);
            let below = if mixed.is_empty() { self.held_below_zero(effects, &fit) } else { Vec::new() };
            if (below.is_empty() && mixed.is_empty()) || held.len() >= MOST_HELD {
                return Some(fit);
            }
            // A tied parameter's value was the others' change (the set-up moved to undo it): the fit starts
            // again from where it first started, not from a point that undoing only one side would spoil.
            start = if mixed.is_empty() { fit.params } else { first.clone() };
            held.extend(below);
            for (k, direction) in mixed {
                held.push(k);
                tied.push((k, direction));
            }
            for &k in &held {
                *self.effect_value(&mut start, effects, k) = 0.0;
            }
        }
    }

    /// Per direction of `fit` no row sees that holds an effect's parameters together with others (a
    /// set-up's or target's, or another effect's): the parameter to hold, of the last effect it holds (the
    /// one added after the others), with the direction. Moving along the direction changes no prediction, so
    /// holding one parameter at zero moves the others of the direction with it: for a compliance or play,
    /// bounded below by zero, the one that reaches zero first along the direction (the others then stay
    /// at or above zero, and the fit loses nothing); otherwise the largest in it. A direction within one
    /// effect's own parameters is left to the fit (held at the start), as are the set-up's own.
    fn tied_to_others(&self, effects: &[ArmEffect], fit: &PositionFit) -> Vec<(usize, Vec<(usize, f64)>)> {
        let first = self.nuisance_count();
        let mut bounds = vec![first];
        for e in effects {
            bounds.push(bounds.last().unwrap() + e.size());
        }
        let owner = |k: usize| (k >= first).then(|| bounds.partition_point(|&b| b <= k) - 1);
        let mut values = fit.params.clone();
        // A parameter's value in the column-scaled units the direction is given in.
        let mut scaled = |k: usize| *self.effect_value(&mut values, effects, k) * fit.scales[k];
        let mut tied: Vec<(usize, Vec<(usize, f64)>)> = Vec::new();
        for d in &fit.hidden {
            let Some(last) = d.iter().filter_map(|(k, _)| owner(*k)).max() else { continue };
            if d.iter().all(|(k, _)| owner(*k) == Some(last)) {
                continue;
            }
            let own: Vec<(usize, f64, f64)> = d
                .iter()
                .filter(|(k, _)| owner(*k) == Some(last) && !fit.held.contains(k))
                .map(|&(k, w)| (k, w, scaled(k)))
                .collect();
            let bounded =
                matches!(effects[last].kind, ArmKind::FrameCompliance | ArmKind::ToolCompliance | ArmKind::Backlash);
            // Holding k moves the direction by t = -value_k / w_k; the others stay at or above zero.
            let keeps_bound = |&(k, w, v): &(usize, f64, f64)| {
                let t = -v / w;
                own.iter().all(|&(j, wj, vj)| j == k || vj + t * wj >= 0.0)
            };
            let largest = |a: &&(usize, f64, f64), b: &&(usize, f64, f64)| a.1.abs().total_cmp(&b.1.abs());
            let chosen = match bounded {
                true => own.iter().filter(|c| keeps_bound(c)).max_by(largest).or_else(|| own.iter().max_by(largest)),
                false => own.iter().max_by(largest),
            };
            if let Some(&(k, _, _)) = chosen.filter(|(k, _, _)| !tied.iter().any(|(t, _)| t == k)) {
                tied.push((k, d.clone()));
            }
        }
        tied
    }

    /// The parameters of `fit` (indices) that are a spring's compliance (at a frame, at the tool) or a play,
    /// seen by the data, not held, and below zero.
    fn held_below_zero(&self, effects: &[ArmEffect], fit: &PositionFit) -> Vec<usize> {
        let mut k = self.nuisance_count();
        let mut below = Vec::new();
        for (e, values) in effects.iter().zip(&fit.params.effects) {
            if matches!(e.kind, ArmKind::FrameCompliance | ArmKind::ToolCompliance | ArmKind::Backlash) {
                below.extend((0..e.size()).map(|i| k + i).filter(|&j| values[j - k] < 0.0 && fit.sees(j)));
            }
            k += e.size();
        }
        below.retain(|j| !fit.held.contains(j));
        below
    }

    /// Effect parameter `k` (an index among all the fit's parameters) of `params`.
    fn effect_value<'p>(&self, params: &'p mut Params, effects: &[ArmEffect], k: usize) -> &'p mut f64 {
        let mut at = self.nuisance_count();
        for (e, values) in effects.iter().zip(params.effects.iter_mut()) {
            if k < at + e.size() {
                return &mut values[k - at];
            }
            at += e.size();
        }
        unreachable!("parameter {k} is not an effect's")
    }

    /// Levenberg-Marquardt with the parameters `held` fixed where `start` has them (their columns and steps
    /// zero; they are left out of the directions reported unseen).
    fn fit_holding(
        &self,
        rows: &[usize],
        effects: &[ArmEffect],
        start: &Params,
        held: &[usize],
    ) -> Option<PositionFit> {
        let p = self.nuisance_count() + effects.iter().map(ArmEffect::size).sum::<usize>();
        let on_rows = OnRows {
            problem: self,
            rows,
            effects,
            parameters: p,
            held,
            state: RefCell::new(self.m.new_state()),
            jac_row: RefCell::new(DMatrix::zeros(3, p)),
        };
        let s = lm::solve(&on_rows, start.clone()).ok();
        if let Some(bar) = &self.progress {
            bar.inc(1);
        }
        let s = s?;
        Some(PositionFit {
            params: s.point,
            rss: s.rss,
            observations: 3 * rows.len(),
            rank: s.rank,
            covariance: s.covariance,
            hidden: s.hidden.into_iter().filter(|d| !d.iter().all(|(k, _)| held.contains(k))).collect(),
            held: held.to_vec(),
            tied: Vec::new(),
            scales: s.scales,
        })
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

/// A fit of `effects` on `rows` as the least-squares core sees it: the rows' weighted residuals and their
/// prediction's Jacobian, the set-ups' rotations and targets' turns stepped on their manifold (`apply`).
struct OnRows<'p, 'a> {
    problem: &'p PositionProblem<'a>,
    rows: &'p [usize],
    effects: &'p [ArmEffect],
    parameters: usize,
    /// Parameters held where they start (`PositionProblem::fit`).
    held: &'p [usize],
    /// The evaluations' state (their placements start from the last) and one row's Jacobian.
    state: RefCell<ManipulatorState>,
    jac_row: RefCell<DMatrix<f64>>,
}

impl LeastSquares for OnRows<'_, '_> {
    type Point = Params;
    /// A row without a pose at this point.
    type Error = ();

    fn parameters(&self) -> usize {
        self.parameters
    }

    fn evaluate(&self, params: &Params, jacobian: Option<&mut DMatrix<f64>>) -> Result<DVector<f64>, ()> {
        let (n, p) = (3 * self.rows.len(), self.parameters);
        let (state, jac_row) = (&mut *self.state.borrow_mut(), &mut *self.jac_row.borrow_mut());
        let mut jacobian = jacobian.map(|j| {
            *j = DMatrix::zeros(n, p);
            j
        });
        let mut e = DVector::zeros(n);
        // A repeated measurement's prediction is its first's (`PositionProblem::repeat_of`), made once; a
        // drift moves with the row's line, so with one every row is predicted.
        let shared = !self.effects.iter().any(|e| e.kind == super::effect::ArmKind::Drift);
        let mut made: std::collections::HashMap<usize, (Vec3, Option<DMatrix<f64>>)> = std::collections::HashMap::new();
        for (i, &r) in self.rows.iter().enumerate() {
            let repeat = self.problem.repeat_of[r].filter(|_| shared);
            let kept = repeat.and_then(|k| made.get(&k));
            let prediction = match kept {
                Some((prediction, rows)) => {
                    if let (Some(rows), Some(_)) = (rows, jacobian.as_ref()) {
                        jac_row.copy_from(rows);
                    }
                    *prediction
                }
                None => {
                    let k = repeat.unwrap_or(r);
                    let with = jacobian.is_some().then_some(&mut *jac_row);
                    let prediction = self.problem.predict(k, self.effects, params, state, with).ok_or(())?;
                    if shared && (repeat.is_some() || self.problem.repeated[r]) {
                        made.insert(k, (prediction, jacobian.is_some().then(|| jac_row.clone())));
                    }
                    prediction
                }
            };
            let residual = (self.problem.measured(r) - prediction) * self.problem.weight[r];
            e.fixed_rows_mut::<3>(3 * i).copy_from(&residual);
            if let Some(jac) = jacobian.as_deref_mut() {
                jac.view_mut((3 * i, 0), (3, p)).copy_from(&*jac_row);
            }
        }
        if let Some(jac) = jacobian {
            for &k in self.held {
                jac.column_mut(k).fill(0.0);
            }
        }
        Ok(e)
    }

    fn step(&self, params: &Params, step: &DVector<f64>) -> Params {
        if self.held.is_empty() {
            return self.problem.apply(params, step);
        }
        let mut step = step.clone();
        for &k in self.held {
            step[k] = 0.0;
        }
        self.problem.apply(params, &step)
    }
}
