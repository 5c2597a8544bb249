//! A VJM leg: a serial chain with virtual springs from the base to the leg's end frame (paper 001 s. 3),
//! its placement by inverse kinematics, its unloaded stiffness (eq 9) and its loaded equilibrium (paper
//! 000 eq 31-47), answered through the leg seam (`leg.rs`).

use crate::kinematics::chain::{Chain, ChainJacobians, Coordinates};
use crate::kinematics::frame::{interpolate, shift_magnitude, shift_stiffness, Frame, Vec3, Vec6};
use crate::kinematics::ik::{self, Needs};
use crate::vjm::equilibrium::{EquilibriumFailure, LoadedChain};
use crate::vjm::spring::SpringGroup;
use crate::vjm::stiffness::{leg_stiffness, passive_range, spring_compliance_at_end};

use super::leg::*;

/// A VJM leg: a serial chain from the base to the leg's end frame, and where that frame sits on the platform.
#[derive(Clone, Debug)]
pub struct VjmLeg {
    /// The leg's name.
    pub name: String,
    /// Base frame -> leg end frame.
    pub chain: Chain,
    /// The copy's frame (identity for a leg written once): the frame of the leg as written, in the base
    /// frame; errors given in the leg's own frame are carried by it.
    pub place: Frame,
    /// The leg's end frame in the platform frame (the platform frame's origin is the reference point).
    pub attachment: Frame,
    /// Its spring groups (blocks of K_theta).
    pub springs: Vec<SpringGroup>,
    /// Rest values theta0 of the virtual coordinates (spring preload), one per virtual coordinate.
    pub preload: Vec<f64>,
    /// Gravity (m/s^2) acting on the chain's masses.
    pub gravity: Vec3,
    /// mm per rad, to weigh rotations against translations.
    pub length_scale: f64,
    /// The actuated coordinates a cold inverse kinematics starts from (a serial arm's stated seed, which
    /// picks its elbow and wrist branch); empty: all zero.
    pub home: Vec<f64>,
}
/// Puts the state at actuated coordinates `q` with the springs at rest and no passive joint moved, as the
/// warm start of the next placement (which then keeps `q`'s branch); false where `q` is not one value per
/// actuated coordinate.
fn seed_at(q: &[f64], state: &mut LegState) -> bool {
    if q.len() != state.coords.actuated.len() {
        return false;
    }
    state.coords.actuated.copy_from_slice(q);
    state.coords.passive.iter_mut().for_each(|t| *t = 0.0);
    state.coords.virtual_.iter_mut().for_each(|t| *t = 0.0);
    state.ik.invalidate();
    state.placements.clear();
    state.warm = true;
    true
}

impl VjmLeg {
    pub(super) fn target(&self, platform: &Frame) -> Frame {
        platform.compose(&self.attachment)
    }

    /// The platform frame where the leg's actuated coordinates `q` put its end (springs at rest, no passive
    /// joint moved), with `state` seeded there, so that placing the leg for that frame starts from `q` and
    /// keeps its branch (a serial arm's elbow and wrist). None where `q` is not one value per actuated
    /// coordinate or the frame is not finite.
    pub(super) fn pose_at_joints(&self, q: &[f64], state: &mut LegState) -> Option<Frame> {
        if !seed_at(q, state) {
            return None;
        }
        // Evaluated whole, as inverse kinematics would at its start: placing the leg at this frame then
        // converges on this evaluation, and the leg's answer uses it.
        let end = state.ik.evaluate_at(&self.chain, &state.coords).end;
        let platform = end.compose(&self.attachment.inverse());
        (platform.pos.iter().chain(platform.rot.iter()).all(|v| v.is_finite())).then_some(platform)
    }

    /// The rigid chain at actuated coordinates `q` (springs at rest), at its end point: its end frame, the
    /// twist of the end point per unit of each actuated coordinate, each actuated coordinate's load from the chain's weight,
    /// and each actuated joint's frame before its motion. None as `pose_at_joints`.
    pub(super) fn statics(&self, q: &[f64], state: &mut LegState) -> Option<super::manipulator::ArmStatics> {
        if !seed_at(q, state) {
            return None;
        }
        self.chain.evaluate(&state.coords, &mut state.jac);
        let end = state.jac.end;
        if !end.pos.iter().chain(end.rot.iter()).all(|v| v.is_finite()) {
            return None;
        }
        let mut loads = vec![0.0; q.len()];
        state.jac.add_actuated_loads(&Vec6::zeros(), &self.gravity, &mut loads);
        Some(super::manipulator::ArmStatics {
            frame: end,
            columns: state.jac.actuated.clone(),
            loads,
            joint_frames: self.chain.actuated_joint_frames(&state.coords),
            transmitted: state.jac.actuated_transmitted_weights(&self.gravity, q.len()),
        })
    }

    pub(super) fn has_masses(&self) -> bool {
        self.chain.elements().iter().any(|e| matches!(e, crate::kinematics::chain::Element::Mass { .. }))
    }

    pub(super) fn loaded_chain(&self) -> LoadedChain<'_> {
        LoadedChain {
            chain: &self.chain,
            springs: &self.springs,
            gravity: self.gravity,
            preload: &self.preload,
            length_scale: self.length_scale,
        }
    }

    /// The chain's Jacobians at the state's configuration, reusing inverse kinematics' last evaluation.
    pub(super) fn evaluation<'a>(&self, state: &'a mut LegState) -> &'a ChainJacobians {
        if state.ik.solution(&self.chain, &state.coords).is_some() {
            return state.ik.kept().expect("made just above");
        }
        self.chain.evaluate(&state.coords, &mut state.jac);
        state.jac.fill_virtual();
        &state.jac
    }

    /// `evaluation` with the coordinates it was made at, both borrowed from `state`.
    pub(super) fn evaluated<'a>(&self, state: &'a mut LegState) -> (&'a ChainJacobians, &'a Coordinates) {
        self.evaluation(state);
        let state = &*state;
        (state.ik.kept().unwrap_or(&state.jac), &state.coords)
    }

    pub(super) fn place(
        &self,
        platform: &Frame,
        state: &mut LegState,
        needs: Needs,
        along: Option<&Frame>,
    ) -> Result<usize, LegFailure> {
        let target = self.target(platform);
        let key = along.unwrap_or(&target);
        state.end_wrench = Vec6::zeros();
        state.last_target = target;
        // Placement is the nominal geometry (springs undeformed, theta = 0): the actuators are set for the
        // nominal legs; a preload theta0 then acts through the equilibrium, K (theta - theta0).
        if state.coords.virtual_.iter().any(|t| *t != 0.0) {
            state.coords.virtual_.iter_mut().for_each(|t| *t = 0.0);
            state.ik.invalidate();
        }
        if state.warm {
            state.saved.clone_from(&state.coords);
            if state.placements.predict_into(key, &mut state.coords) {
                state.ik.invalidate();
            }
            match ik::solve(&self.chain, &target, &mut state.coords, &mut state.ik, self.length_scale, needs) {
                Ok(n) => {
                    state.placed.clone_from(&state.coords);
                    state.placements.record(key, &state.coords);
                    return Ok(n);
                }
                Err(_) => {
                    state.coords.clone_from(&state.saved);
                    state.ik.invalidate();
                }
            }
        }
        // Cold start from home.
        state.ik.invalidate();
        if self.home.len() == state.coords.actuated.len() {
            state.coords.actuated.copy_from_slice(&self.home);
        } else {
            state.coords.actuated.iter_mut().for_each(|t| *t = 0.0);
        }
        state.coords.passive.iter_mut().for_each(|t| *t = 0.0);
        match ik::solve(&self.chain, &target, &mut state.coords, &mut state.ik, self.length_scale, needs) {
            Ok(n) => {
                state.warm = true;
                state.placed.clone_from(&state.coords);
                state.placements.record(key, &state.coords);
                Ok(n)
            }
            Err(e) => {
                state.warm = false;
                Err(LegFailure::Unreachable(e))
            }
        }
    }

    pub(super) fn respond_unloaded(&self, platform: &Frame, state: &mut LegState) -> Result<LegResponse, LegFailure> {
        // A posture-dependent spring (a parallelogram, a formula of a joint's coordinate) reads the
        // coordinates beside the evaluation.
        let (jac, coords) = self.evaluated(state);
        let s = spring_compliance_at_end(&jac.virtual_, &self.springs, coords);
        let range = passive_range(&jac.passive, self.length_scale);
        let k_end = leg_stiffness(&s, &range).ok_or(LegFailure::SingularChain)?;
        // Move from the leg's end point EP to the reference point RP: K_RP = A^T K_EP A, v = EP - RP.
        let v = jac.end.pos - platform.pos;
        let (stiffness, magnitude) = (shift_stiffness(&k_end, &v), shift_magnitude(&k_end, &v));
        Ok(LegResponse { wrench: Vec6::zeros(), stiffness, magnitude, stable: true, iterations: 0 })
    }

    pub(super) fn respond(&self, platform: &Frame, state: &mut LegState) -> Result<LegResponse, LegFailure> {
        let target = self.target(platform);
        state.ik.invalidate();
        let loaded = self.loaded_chain();
        state.saved.clone_from(&state.coords);
        let saved_wrench = state.end_wrench;
        let answer = match loaded.solve(&target, &mut state.coords, &mut state.end_wrench, &mut state.equilibrium) {
            Ok(a) => a,
            Err(_) => {
                // Continuation (paper 000 s. 3.3): t_i = a_i t + (1 - a_i) t_last, a_i rising to 1.
                state.coords.clone_from(&state.saved);
                state.end_wrench = saved_wrench;
                self.continuation(&loaded, &target, state)?
            }
        };
        state.last_target = target;
        let at_rp = at_reference_point(&answer.wrench, &answer.stiffness, &(answer.end - platform.pos));
        Ok(LegResponse {
            wrench: -at_rp.wrench,
            stiffness: at_rp.stiffness,
            magnitude: at_rp.magnitude,
            stable: answer.stable,
            iterations: answer.iterations,
        })
    }

    pub(super) fn continuation(
        &self,
        loaded: &LoadedChain<'_>,
        target: &Frame,
        state: &mut LegState,
    ) -> Result<crate::vjm::equilibrium::LoadedAnswer, LegFailure> {
        let start = state.last_target;
        let delta = start.error_to(target);
        let mut last_failure = EquilibriumFailure::Singular;
        for &pieces in &[4usize, 16, 64] {
            let (coords0, wrench0) = (state.coords.clone(), state.end_wrench);
            let mut result = None;
            for i in 1..=pieces {
                let a = i as f64 / pieces as f64;
                let t = interpolate(&start, &delta, a);
                match loaded.solve(&t, &mut state.coords, &mut state.end_wrench, &mut state.equilibrium) {
                    Ok(ans) => result = Some(ans),
                    Err(e) => {
                        last_failure = e;
                        result = None;
                        break;
                    }
                }
            }
            if let Some(ans) = result {
                return Ok(ans);
            }
            state.coords = coords0;
            state.end_wrench = wrench0;
        }
        Err(match last_failure {
            EquilibriumFailure::NotConverged { iterations, residual } => {
                LegFailure::NotConverged { iterations, residual }
            }
            EquilibriumFailure::Singular => LegFailure::SingularChain,
        })
    }
}
