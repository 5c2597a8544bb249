//! The leg seam (DESIGN.md, paper 000 eq 66-67): a leg, asked where the platform is, answers with the
//! wrench it exerts on the platform and its tangent stiffness there, both at the platform's reference point
//! and in the base frame. Aggregation and every study talk to legs only through this.

use crate::kinematics::chain::{Chain, ChainJacobians, Coordinates};
use crate::kinematics::frame::{point_shift, shift_stiffness, Frame, Mat6, Vec6};
use crate::kinematics::ik::{self, IkWorkspace};
use crate::vjm::spring::SpringGroup;
use crate::vjm::stiffness::{leg_stiffness, passive_range, spring_compliance_at_end};

/// What a leg answers for one platform pose.
#[derive(Clone, Copy, Debug)]
pub struct LegResponse {
    /// Wrench the leg exerts on the platform, at the reference point (N, N mm).
    pub wrench: Vec6,
    /// Tangent stiffness at the reference point, base frame (singular on its own, never inverted).
    pub stiffness: Mat6,
    /// Rank of the passive-joint Jacobian, and its smallest pivot ratio (the rank tolerance in use).
    pub passive_rank: usize,
    pub passive_pivot_ratio: f64,
}

/// Why a leg could not answer at a pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LegFailure {
    /// Inverse kinematics found no configuration reaching the pose.
    Unreachable(ik::IkFailure),
    /// The springs do not restrain the directions the passive joints leave (eq 9 bordered matrix singular).
    SingularChain,
}

/// A VJM leg: a serial chain from the base to the leg's end frame, and where that frame sits on the platform.
#[derive(Clone, Debug)]
pub struct VjmLeg {
    pub name: String,
    /// Base frame -> leg end frame.
    pub chain: Chain,
    /// The leg's end frame in the platform frame (the platform frame's origin is the reference point).
    pub attachment: Frame,
    pub springs: Vec<SpringGroup>,
    /// mm per rad, to weigh rotations against translations.
    pub length_scale: f64,
}

/// Per-leg state carried from one pose to the next: the warm start of inverse kinematics and buffers.
#[derive(Clone, Debug)]
pub struct LegState {
    pub coords: Coordinates,
    /// True when `coords` holds a solved configuration usable as a warm start.
    pub warm: bool,
    /// The configuration before a warm-started attempt, restored if that attempt fails.
    saved: Coordinates,
    ik: IkWorkspace,
    jac: ChainJacobians,
}

#[derive(Clone, Debug)]
pub enum Leg {
    Vjm(VjmLeg),
}

impl Leg {
    pub fn name(&self) -> &str {
        match self {
            Leg::Vjm(l) => &l.name,
        }
    }

    pub fn new_state(&self) -> LegState {
        match self {
            Leg::Vjm(l) => LegState {
                coords: Coordinates::zeros(&l.chain),
                warm: false,
                saved: Coordinates::zeros(&l.chain),
                ik: IkWorkspace::default(),
                jac: ChainJacobians::default(),
            },
        }
    }

    /// Places the leg for a commanded platform pose: inverse kinematics of the rigid leg (springs at rest),
    /// warm-started from the state's previous solution, else from the home configuration (all zero).
    pub fn place(&self, platform: &Frame, state: &mut LegState) -> Result<usize, LegFailure> {
        match self {
            Leg::Vjm(l) => l.place(platform, state),
        }
    }

    /// The leg's answer at the pose it was placed for, with springs at rest: zero wrench and the unloaded
    /// stiffness of paper 001 eq (9), moved to the reference point by paper 000 eq (54)-(55).
    pub fn respond_unloaded(&self, platform: &Frame, state: &mut LegState) -> Result<LegResponse, LegFailure> {
        match self {
            Leg::Vjm(l) => l.respond_unloaded(platform, state),
        }
    }
}

impl Leg {
    /// After `place`: the platform twist at the reference point that a unit change of each actuated
    /// coordinate would cause if it alone moved the leg's end (its end-point error per unit actuator offset,
    /// paper 000 s. 4.2), in the base frame.
    pub fn actuator_twists(&self, platform: &Frame, state: &mut LegState) -> Vec<Vec6> {
        match self {
            Leg::Vjm(l) => {
                let jac = l.evaluation(state);
                // A twist at EP seen at RP: inverse of point_shift(v), v = EP - RP.
                let back = point_shift(&(platform.pos - jac.end.pos));
                jac.actuated.iter().map(|t| back * t).collect()
            }
        }
    }
}

impl VjmLeg {
    /// The chain's Jacobians at the state's configuration, reusing inverse kinematics' last evaluation.
    fn evaluation<'a>(&self, state: &'a mut LegState) -> &'a ChainJacobians {
        if state.ik.solution().is_some() {
            return state.ik.solution().expect("checked just above");
        }
        self.chain.evaluate(&state.coords, &mut state.jac);
        state.jac.fill_virtual();
        &state.jac
    }

    fn target(&self, platform: &Frame) -> Frame {
        platform.compose(&self.attachment)
    }

    fn place(&self, platform: &Frame, state: &mut LegState) -> Result<usize, LegFailure> {
        let target = self.target(platform);
        state.coords.virtual_.iter_mut().for_each(|t| *t = 0.0);
        if state.warm {
            state.saved.clone_from(&state.coords);
            match ik::solve(&self.chain, &target, &mut state.coords, &mut state.ik, self.length_scale) {
                Ok(n) => return Ok(n),
                Err(_) => {
                    state.coords.clone_from(&state.saved);
                    state.ik.invalidate();
                }
            }
        }
        // Cold start from home.
        state.ik.invalidate();
        state.coords.actuated.iter_mut().for_each(|t| *t = 0.0);
        state.coords.passive.iter_mut().for_each(|t| *t = 0.0);
        match ik::solve(&self.chain, &target, &mut state.coords, &mut state.ik, self.length_scale) {
            Ok(n) => {
                state.warm = true;
                Ok(n)
            }
            Err(e) => {
                state.warm = false;
                Err(LegFailure::Unreachable(e))
            }
        }
    }

    fn respond_unloaded(&self, platform: &Frame, state: &mut LegState) -> Result<LegResponse, LegFailure> {
        let jac = self.evaluation(state);
        let s = spring_compliance_at_end(&jac.virtual_, &self.springs);
        let range = passive_range(&jac.passive, self.length_scale);
        let k_end = leg_stiffness(&s, &range).ok_or(LegFailure::SingularChain)?;
        // Move from the leg's end point EP to the reference point RP: K_RP = A^T K_EP A, v = EP - RP.
        let stiffness = shift_stiffness(&k_end, &(jac.end.pos - platform.pos));
        Ok(LegResponse {
            wrench: Vec6::zeros(),
            stiffness,
            passive_rank: range.rank,
            passive_pivot_ratio: range.smallest_pivot_ratio,
        })
    }
}
