//! The first order completed by the exact loaded equilibrium: the miss of the first-order prediction against
//! the robot with the effects a description holds built in, kept per set of effects and refitted
//! (`PositionProblem::fit_exact`) until the fit is that of the model with them built in. A parallel robot's
//! effects are built in as its description's effects; a serial arm is read again from its description with
//! the corrections `--model-out` writes (`CalibrationOptions::rebuild`), so the written model reproduces the
//! fit.

use super::effect::{ArmEffect, ArmKind, Seen};
use super::fit::{Params, PositionFit};
use super::problem::PositionProblem;
use crate::diagnose::positions::Observed;
use crate::kinematics::frame::{rotation_vector, Frame, Vec3, Vec6};
use crate::model::effect::{Effect, Kind, Target};
use crate::platform::manipulator::{Manipulator, ManipulatorState};

/// Most refits of the first order completed by its exact misses (`PositionProblem::fit_exact`).
const EXACT_PASSES: usize = 8;

/// The refits stop where the kept misses move no row by more than this share of its standard deviation.
const EXACT_TOLERANCE: f64 = 1e-3;

impl PositionProblem<'_> {
    /// The miss kept for these effects at row `r` (`exact_misses`), zero where none is kept.
    /// Where none is kept for exactly these, the one kept for their longest leading part: the selection tries
    /// each candidate after the model it has (whose misses `select` keeps), so a candidate is judged against
    /// the model's exact prediction, its own first order added.
    pub(super) fn kept_miss(&self, effects: &[ArmEffect], r: usize) -> Vec6 {
        let misses = self.misses.read().unwrap_or_else(std::sync::PoisonError::into_inner);
        let exact = misses.iter().find(|(e, _)| e == effects);
        let leading = || misses.iter().filter(|(e, _)| effects.starts_with(e)).max_by_key(|(e, _)| e.len());
        exact.or_else(leading).map_or_else(Vec6::zeros, |(_, m)| m[r])
    }

    /// A parallel robot's effects act at first order (`unit_moves`): an actuator offset of 1 mm on legs of
    /// 300 mm leaves about 3 um of second order, an actuator's compliance and a payload the change of C and
    /// K_i with the pose. This is, per row, the twist (reference point, base frame) from that first-order
    /// prediction with `effects` at `params` to the loaded equilibrium of the robot with the effects a
    /// description holds built in (actuator offsets, added actuator compliances as factors on their springs,
    /// a payload of positive mass), as `stiff synth` and every study compute it; the effects no description
    /// holds (a leg's end-point error, play) stay first order. None where none is built in or a row has no
    /// equilibrium. A serial arm's: `arm_misses`.
    pub(super) fn exact_misses(&self, effects: &[ArmEffect], fit: &PositionFit) -> Option<Vec<Vec6>> {
        let params = &fit.params;
        if self.space.is_some() {
            return self.arm_misses(effects, fit);
        }
        let built: Vec<(&ArmEffect, &Vec<f64>, Effect)> =
            effects.iter().zip(&params.effects).filter_map(|(e, v)| Some((e, v, self.model_form(e, v)?))).collect();
        if built.is_empty() {
            return None;
        }
        let model_form: Vec<Effect> = built.iter().map(|(_, _, f)| f.clone()).collect();
        let mut real: Vec<Option<Manipulator>> = vec![None; self.tilted.len() + 1];
        let mut state = self.m.new_state();
        let mut misses = Vec::with_capacity(self.data.rows.len());
        for (r, row) in self.data.rows.iter().enumerate() {
            if super::problem::same_line(self.data, &self.tilt_of, r) {
                misses.push(misses[r - 1]);
                continue;
            }
            let (Some(pose), Observed::Position { .. } | Observed::Orientation { .. }) = (row.pose, row.observed)
            else {
                misses.push(Vec6::zeros());
                continue;
            };
            let robot = real[self.tilt_of[r].map_or(0, |t| t + 1)]
                .get_or_insert_with(|| crate::model::effect::with_model_effects(self.arm(r), &model_form));
            if self.unusable.iter().any(|(u, _)| *u == r) {
                misses.push(Vec6::zeros());
                continue;
            }
            robot.place(&pose, &mut state).ok()?;
            let exact = robot.deflect(&pose, &row.wrench, None, &mut state).ok()?.displacement;
            // The first order of the built-in effects, as a twist: what a point at the reference point sees
            // (its translation) and what the tool's turn sees (its rotation).
            let (s, zero) = &self.statics[r];
            let payload = self.fitted_payload_weight(r, effects, params, s, zero);
            let mut linear = self.deflection[r];
            for (e, v, _) in &built {
                let moves = self.unit_moves(r, e, s, zero, &Seen::Point(Vec3::zeros()), &payload);
                let turns = self.unit_moves(r, e, s, zero, &Seen::Turn, &payload);
                for ((m, t), value) in moves.iter().zip(&turns).zip(v.iter()) {
                    linear += Vec6::new(m.x, m.y, m.z, t.x, t.y, t.z) * *value;
                }
            }
            misses.push(exact - linear);
        }
        Some(misses)
    }

    /// A parallel robot's effect `e` at `values` as the description's model-form effect every study builds in
    /// (`model::effect::with_model_effects`): an actuator offset, an added actuator compliance as the factor
    /// on its spring (where it has one and stays positive), a payload of positive mass (stored as (m, m c),
    /// as the fit's parameters are); None for the others, which no description holds.
    pub(super) fn model_form(&self, e: &ArmEffect, values: &[f64]) -> Option<Effect> {
        let leg = Target::Leg(e.joint);
        match e.kind {
            ArmKind::JointOffset => Some(Effect { kind: Kind::ActuatorOffset, target: leg, values: values.to_vec() }),
            ArmKind::JointCompliance => {
                let nominal = self.nominal_compliance(e.joint).filter(|n| n + values[0] > 0.0)?;
                let factor = (nominal + values[0]) / nominal;
                Some(Effect { kind: Kind::ActuatorCompliance, target: leg, values: vec![factor] })
            }
            ArmKind::Payload if values[0] > 0.0 => {
                Some(Effect { kind: Kind::GravityOffset, target: Target::None, values: values.to_vec() })
            }
            _ => None,
        }
    }

    /// The fit of `effects` on `rows` from `start`, its first order completed by its misses (`exact_misses`):
    /// kept for these effects and refitted until the prediction moves by less than `EXACT_TOLERANCE` of a
    /// standard deviation. Each pass shrinks the miss by about the effects' relative size (an offset of 1 mm
    /// on legs of 300 mm: 300 times), so a few passes reach round-off; at most `EXACT_PASSES`. The misses
    /// kept last are those at the fit returned: its predictions are the exact model's.
    pub(super) fn fit_exact(&self, rows: &[usize], effects: &[ArmEffect], start: &Params) -> Option<PositionFit> {
        let mut fit = self.fit(rows, effects, start)?;
        for pass in 0..=EXACT_PASSES {
            let Some(misses) = self.exact_misses(effects, &fit) else { break };
            let kept: Vec<Vec6> = (0..misses.len()).map(|r| self.kept_miss(effects, r)).collect();
            let moved = rows
                .iter()
                .map(|&r| {
                    let change = misses[r] - kept[r];
                    let seen = match self.data.rows[r].observed {
                        Observed::Position { target, .. } => {
                            Seen::Point(self.statics[r].0.frame.rot * fit.params.targets[target])
                        }
                        Observed::Orientation { .. } => Seen::Turn,
                        Observed::Displacement(_) => Seen::Point(Vec3::zeros()),
                    };
                    seen.of(&change).norm() * self.weight[r]
                })
                .fold(0.0, f64::max);
            let mut all = self.misses.write().unwrap_or_else(std::sync::PoisonError::into_inner);
            all.retain(|(e, _)| e != effects);
            all.push((effects.to_vec(), misses));
            drop(all);
            if moved.is_nan() || moved <= EXACT_TOLERANCE || pass == EXACT_PASSES {
                break;
            }
            fit = self.fit(rows, effects, &fit.params)?;
        }
        Some(fit)
    }

    /// A serial arm's misses: per row, what the first order (`body`, with the effects a description holds)
    /// misses of the loaded equilibrium of the arm read again with those effects written in
    /// (`arm_corrections`, `CalibrationOptions::rebuild`): the body's point for a position (its lever
    /// turned by the whole loaded rotation, not its first order) as a translation, the tool's turn for an
    /// orientation as a rotation. The effects no description holds (a drift, a tool's spring) stay
    /// first order. Without effects to write, the model's own (the lever's second order). None where the
    /// corrected description cannot be built (a compliance below zero) or a row has no equilibrium.
    fn arm_misses(&self, effects: &[ArmEffect], fit: &PositionFit) -> Option<Vec<Vec6>> {
        // The effects a description holds, with their values and which of their parameters the data see (a
        // spring's unseen direction is written rigid).
        let written: Vec<usize> = (0..effects.len()).filter(|&k| written_in_description(effects[k].kind)).collect();
        let kept_effects: Vec<ArmEffect> = written.iter().map(|&k| effects[k]).collect();
        let kept_params =
            Params { effects: written.iter().map(|&k| fit.params.effects[k].clone()).collect(), ..fit.params.clone() };
        let corrected = match written.is_empty() {
            true => None,
            false => {
                let first = |k: usize| self.nuisance_count() + effects[..k].iter().map(ArmEffect::size).sum::<usize>();
                let seen: Vec<Vec<bool>> = written
                    .iter()
                    .map(|&k| (first(k)..first(k) + effects[k].size()).map(|j| fit.sees(j)).collect())
                    .collect();
                let joints: Vec<String> = kept_effects.iter().map(|e| self.joints[e.joint].clone()).collect();
                let text = super::report::arm_corrections(&kept_effects, &kept_params.effects, &seen, &joints);
                Some((self.rebuild.as_ref()?.0)(&text).ok()?)
            }
        };
        let variants: Vec<Manipulator> = match &corrected {
            Some(m) => self.tilted.iter().map(|(key, _)| key.of(m)).collect(),
            None => Vec::new(),
        };
        let arm = |r: usize| match (&corrected, self.tilt_of[r]) {
            (None, _) => self.arm(r),
            (Some(m), None) => m,
            (Some(_), Some(t)) => &variants[t],
        };
        // The corrected arm's state is its own (a frame compliance adds coordinates).
        let mut state = self.m.new_state();
        let mut exact_state = corrected.as_ref().unwrap_or(self.m).new_state();
        let mut loaded: Option<(Frame, Option<Frame>)> = None;
        let mut misses = Vec::with_capacity(self.data.rows.len());
        for (r, row) in self.data.rows.iter().enumerate() {
            if self.unusable.iter().any(|(u, _)| *u == r) {
                misses.push(Vec6::zeros());
                loaded = None;
                continue;
            }
            // A repeated measurement misses as its first does (`PositionProblem::repeat_of`).
            if let Some(k) = self.repeat_of[r] {
                misses.push(misses[k]);
                loaded = None;
                continue;
            }
            // The rows of one line share its equilibrium.
            if !(super::problem::same_line(self.data, &self.tilt_of, r) && loaded.is_some()) {
                let (m, state) = (arm(r), &mut exact_state);
                let frame = row.nominal_frame(m, state)?;
                // A rigid arm stays where its joints put it.
                let settled = |w: &Vec6, state: &mut ManipulatorState| match m.deflects() {
                    false => Some(frame),
                    true => Some(m.deflect(&frame, w, None, state).ok()?.pose),
                };
                m.place(&frame, state).ok()?;
                let under = settled(&row.wrench, state)?;
                let zero = match row.observed {
                    Observed::Displacement(_) => Some(settled(&Vec6::zeros(), state)?),
                    _ => None,
                };
                loaded = Some((under, zero));
            }
            let (under, zero) = loaded.expect("computed above");
            let body = self.body(r, &kept_effects, &kept_params, &mut state, false)?;
            let miss = match (row.observed, zero) {
                (Observed::Position { target, .. }, _) => {
                    let exact = under.pos + under.rot * fit.params.targets[target];
                    let d = exact - body.y;
                    Vec6::new(d.x, d.y, d.z, 0.0, 0.0, 0.0)
                }
                (Observed::Orientation { .. }, _) => {
                    let exact = rotation_vector(&(under.rot * body.statics.0.frame.rot.transpose()));
                    let d = exact - body.y;
                    Vec6::new(0.0, 0.0, 0.0, d.x, d.y, d.z)
                }
                (Observed::Displacement(_), zero) => {
                    let d = under.pos - zero.map_or(under.pos, |z| z.pos) - body.y;
                    Vec6::new(d.x, d.y, d.z, 0.0, 0.0, 0.0)
                }
            };
            misses.push(miss);
        }
        Some(misses)
    }
}

/// Whether a description holds a serial arm's effect of this kind (`arm_corrections` writes it).
fn written_in_description(kind: ArmKind) -> bool {
    super::report::not_written(kind).is_none()
}
