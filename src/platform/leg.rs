//! The leg seam (ARCHITECTURE.md, paper 000 eq 66-67): a leg, asked where the platform is, answers with the
//! wrench it exerts on the platform and its tangent stiffness there, both at the platform's reference point
//! and in the base frame. Aggregation and every study talk to legs only through this: the dispatch between
//! a VJM leg (`vjm_leg.rs`) and an MSA leg (`msa_leg.rs`), their warm-start state (`leg_state.rs`) and the
//! assembly-only operations (`assembly.rs`) live beside it.

use crate::kinematics::chain::{ChainJacobians, Coordinates};
use crate::kinematics::frame::{point_shift, shift_magnitude, shift_stiffness, skew, Frame, Mat3, Mat6, Vec3, Vec6};
use crate::kinematics::ik::{self, IkWorkspace, Needs};
use crate::vjm::equilibrium::{EquilibriumWorkspace, Linearization};
use crate::vjm::spring::SpringGroup;

use super::leg_state::PlacementTrail;
pub use super::leg_state::{LegState, LoadedOffsets};
use super::msa_leg::{MsaLeg, MsaState};
pub use super::vjm_leg::VjmLeg;

/// What a leg answers for one platform pose.
#[derive(Clone, Copy, Debug)]
pub struct LegResponse {
    /// Wrench the leg exerts on the platform, at the reference point (N, N mm).
    pub wrench: Vec6,
    /// Tangent stiffness at the reference point, base frame: minus the derivative of `wrench` with respect
    /// to the platform's displacement (singular on its own, never inverted).
    pub stiffness: Mat6,
    /// Size of the terms that made each diagonal entry of `stiffness` (`frame::shift_magnitude`), for
    /// telling round-off from small stiffness (`compliance::analyse`).
    pub magnitude: Vec6,
    /// The leg's equilibrium is stable with its end held (always true unloaded).
    pub stable: bool,
    /// Newton iterations of the equilibrium (0 unloaded).
    pub iterations: usize,
}

/// Why a leg could not answer at a pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LegFailure {
    /// Inverse kinematics found no configuration reaching the pose.
    Unreachable(ik::IkFailure),
    /// An MSA leg's geometry has no value at the pose: a reach condition (its index) is negative (eq 20),
    /// or a formula is not finite there.
    OutOfReach {
        /// The reach condition that failed (None: a formula was not finite).
        condition: Option<usize>,
    },
    /// The springs do not restrain the directions the passive joints leave (eq 9 bordered matrix singular).
    SingularChain,
    /// The loaded equilibrium was not found, even with continuation.
    NotConverged {
        /// Newton iterations spent.
        iterations: usize,
        /// The largest remaining residual (mm or rad).
        residual: f64,
    },
    /// The leg's model has no finite stiffness at this pose (parameters at the edge of doubles).
    NotFinite,
}

impl std::fmt::Display for LegFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LegFailure::Unreachable(e) => write!(f, "unreachable: {e}"),
            LegFailure::OutOfReach { condition: Some(k) } => {
                write!(f, "out of reach: reach condition {} of the MSA leg is negative at this pose", k + 1)
            }
            LegFailure::OutOfReach { condition: None } => {
                write!(f, "out of reach: a formula of the MSA leg has no finite value at this pose")
            }
            LegFailure::SingularChain => write!(
                f,
                "the leg's springs do not restrain a direction its passive joints leave free (check the springs \
                 and passive joints of this leg)"
            ),
            LegFailure::NotFinite => write!(
                f,
                "its model has no finite stiffness at this pose (a parameter at the edge of what doubles hold, \
                 e.g. a modulus of 5e-324 or a length of 1e200?)"
            ),
            LegFailure::NotConverged { iterations, residual } => write!(
                f,
                "its loaded equilibrium was not found after {iterations} Newton iterations (residual {residual:.3e}); \
                 try a smaller load or more steps"
            ),
        }
    }
}

/// A leg of a parallel manipulator, by the model that computes it.
#[derive(Clone, Debug)]
pub enum Leg {
    /// A serial chain with virtual springs (VJM).
    Vjm(VjmLeg),
    /// A structure of beams and joints (MSA).
    Msa(MsaLeg),
}

impl Leg {
    /// The leg's name.
    pub fn name(&self) -> &str {
        match self {
            Leg::Vjm(l) => &l.name,
            Leg::Msa(l) => &l.name,
        }
    }

    /// The frame of the leg as written (before its copy moved it), in the base frame.
    /// The leg's spring groups: (name, whether it is an actuator's spring). An MSA leg has none (its
    /// elasticity is in its beams and elastic joints).
    pub fn spring_groups(&self) -> impl Iterator<Item = (&str, bool)> {
        let springs: &[SpringGroup] = match self {
            Leg::Vjm(v) => &v.springs,
            Leg::Msa(_) => &[],
        };
        springs.iter().map(|s| (s.name.as_str(), s.actuator))
    }

    /// Whether the leg has an actuator spring (effects on the actuator act through it).
    pub fn has_actuator_spring(&self) -> bool {
        self.spring_groups().any(|(_, actuator)| actuator)
    }

    /// The compliance of the leg's first actuator spring along (about) its axis, mm/N (rad/(N mm)), where it
    /// has a one-coordinate actuator spring.
    pub fn actuator_compliance(&self) -> Option<f64> {
        match self {
            Leg::Vjm(v) => v.springs.iter().find(|s| s.actuator && s.dim == 1).map(|s| s.compliance[(0, 0)]),
            Leg::Msa(_) => None,
        }
    }

    /// Multiplies the compliance of the spring groups `select(name, actuator)` picks by `factor`.
    pub fn scale_springs(&mut self, select: impl Fn(&str, bool) -> bool, factor: f64) {
        if let Leg::Vjm(v) = self {
            for s in v.springs.iter_mut().filter(|s| select(&s.name, s.actuator)) {
                s.scale_compliance(factor);
            }
        }
    }

    /// Scales the axial and the bending (with torsion) compliance of the beam springs `select(name,
    /// actuator)` picks (`SpringGroup::scale_beam_parts`).
    pub fn scale_beam_parts(&mut self, select: impl Fn(&str, bool) -> bool, axial: f64, bending: f64) {
        if let Leg::Vjm(v) = self {
            for s in v.springs.iter_mut().filter(|s| select(&s.name, s.actuator)) {
                s.scale_beam_parts(axial, bending);
            }
        }
    }

    /// Moves the leg's actuator by `offset` (mm or rad) from where it is commanded: the rest value of its
    /// actuator spring, which sits in series on the actuator's axis (V_a(q + theta), paper 001 eq 1), so the
    /// loaded answers see the leg's end pulled as by the offset. A leg without an actuator spring is left.
    pub fn offset_actuator(&mut self, offset: f64) {
        if let Leg::Vjm(v) = self {
            if let Some(s) = v.springs.iter().find(|s| s.actuator) {
                v.preload[s.first] += offset;
            }
        }
    }

    /// The frame of the leg's copy (identity for a leg written once).
    pub fn copy_frame(&self) -> Frame {
        match self {
            Leg::Vjm(l) => l.place,
            Leg::Msa(l) => l.place,
        }
    }

    /// mm per rad: how this leg weighs rotations against translations.
    pub fn length_scale(&self) -> f64 {
        match self {
            Leg::Vjm(l) => l.length_scale,
            Leg::Msa(l) => l.length_scale,
        }
    }

    /// A fresh state (no warm start).
    pub fn new_state(&self) -> LegState {
        let zeros = match self {
            Leg::Vjm(l) => Coordinates::zeros(&l.chain),
            Leg::Msa(_) => Coordinates::default(),
        };
        LegState {
            coords: zeros.clone(),
            warm: false,
            end_wrench: Vec6::zeros(),
            last_target: Frame::IDENTITY,
            saved: zeros.clone(),
            checkpoint: (zeros.clone(), Vec6::zeros()),
            placed: zeros,
            placements: PlacementTrail::default(),
            ik: IkWorkspace::default(),
            jac: ChainJacobians::default(),
            equilibrium: EquilibriumWorkspace::default(),
            msa: MsaState::default(),
            offset_sums: Vec::new(),
        }
    }

    /// Places the leg for a commanded platform pose: inverse kinematics of the rigid leg (springs undeformed),
    /// warm-started from the state's previous solution, else from the home configuration (all zero). Fixes
    /// the actuated coordinates for the loaded answers that follow.
    pub fn place(&self, platform: &Frame, state: &mut LegState, needs: Needs) -> Result<usize, LegFailure> {
        self.place_along(platform, None, state, needs)
    }

    /// As `place`, the start extrapolated from the placements before as a function of `along` where given
    /// (`Manipulator::place_along`), else of the leg's target. Returns the inverse kinematics' iterations.
    pub fn place_along(
        &self,
        platform: &Frame,
        along: Option<&Frame>,
        state: &mut LegState,
        needs: Needs,
    ) -> Result<usize, LegFailure> {
        match self {
            Leg::Vjm(l) => l.place(platform, state, needs, along),
            Leg::Msa(l) => l.place(platform, &mut state.msa).map(|_| 0),
        }
    }

    /// True when the leg carries no load at the pose it was placed for (no preload, no weight), so that
    /// `respond_unloaded` is its exact answer there.
    pub fn unloaded_at_placement(&self) -> bool {
        match self {
            Leg::Vjm(l) => l.preload.iter().all(|t| *t == 0.0) && (l.gravity == Vec3::zeros() || !l.has_masses()),
            Leg::Msa(l) => l.template.unloaded(),
        }
    }

    /// The leg's answer at the pose it was placed for, with springs at rest: zero wrench and the unloaded
    /// stiffness of paper 001 eq (9), moved to the reference point by paper 000 eq (54)-(55).
    pub fn respond_unloaded(&self, platform: &Frame, state: &mut LegState) -> Result<LegResponse, LegFailure> {
        match self {
            Leg::Vjm(l) => l.respond_unloaded(platform, state),
            Leg::Msa(l) => l.respond(platform, &state.msa),
        }
    }

    /// The leg's answer with the platform at `platform` (displaced from where the leg was placed): its
    /// loaded equilibrium with the actuators held (paper 000 eq 32-36), the wrench it exerts and its
    /// tangent stiffness (eq 45-47), warm-started from the state's last equilibrium.
    pub fn respond(&self, platform: &Frame, state: &mut LegState) -> Result<LegResponse, LegFailure> {
        match self {
            Leg::Vjm(l) => l.respond(platform, state),
            Leg::Msa(l) => l.respond(platform, &state.msa),
        }
    }

    /// Linearises the leg's equilibrium with the platform at `platform` (Newton on the whole manipulator),
    /// into `lin`'s buffers (a `LegLinear::default()` the first time, then reused).
    pub fn linearize_into(
        &self,
        platform: &Frame,
        state: &mut LegState,
        lin: &mut LegLinear,
    ) -> Result<(), LegFailure> {
        match self {
            Leg::Vjm(l) => {
                state.ik.invalidate();
                let target = l.target(platform);
                let chain = lin.lin.get_or_insert_with(Linearization::empty);
                if !l.loaded_chain().linearize_into(
                    &target,
                    &state.coords,
                    &state.end_wrench,
                    &mut state.equilibrium,
                    chain,
                ) {
                    return Err(LegFailure::SingularChain);
                }
                let v = chain.end - platform.pos;
                let at_rp = at_reference_point(&chain.wrench, &chain.stiffness(), &v);
                lin.shift = point_shift(&v);
                lin.corrected_force = corrected_force(chain, platform);
                lin.stiffness = at_rp.stiffness;
                lin.magnitude = at_rp.magnitude;
                lin.distance = chain.distance_from_equilibrium(l.length_scale, l.chain.length_coordinates());
                Ok(())
            }
            // Linear: the answer at `platform` is exact, nothing inside the leg to correct.
            Leg::Msa(l) => {
                let r = l.respond(platform, &state.msa)?;
                *lin = LegLinear {
                    lin: None,
                    shift: Mat6::identity(),
                    corrected_force: -r.wrench,
                    stiffness: r.stiffness,
                    magnitude: r.magnitude,
                    distance: 0.0,
                };
                Ok(())
            }
        }
    }

    /// A chord step of the manipulator's Newton method: `lin` made afresh at the leg's current state except
    /// its stiffness and sensitivities, which stay those of the full linearisation it was made by (see
    /// `LoadedChain::refresh`). A linear MSA leg is linearised afresh (exact, and cheap). False where the
    /// leg's workspace no longer holds that linearisation's factorisation: `linearize_into` must come first.
    pub fn refresh(&self, platform: &Frame, state: &mut LegState, lin: &mut LegLinear) -> Result<bool, LegFailure> {
        match (self, &mut lin.lin) {
            (Leg::Vjm(l), Some(chain)) => {
                state.ik.invalidate();
                let target = l.target(platform);
                let loaded = l.loaded_chain();
                match loaded.refresh(&target, &state.coords, &state.end_wrench, &mut state.equilibrium, chain) {
                    None => return Ok(false),
                    Some(false) => return Err(LegFailure::SingularChain),
                    Some(true) => {}
                }
                lin.corrected_force = corrected_force(chain, platform);
                lin.distance = chain.distance_from_equilibrium(l.length_scale, l.chain.length_coordinates());
                Ok(true)
            }
            (Leg::Vjm(_), None) => Ok(false),
            (Leg::Msa(_), _) => self.linearize_into(platform, state, lin).map(|_| true),
        }
    }

    /// The fraction of a Newton step (platform twist `platform_step`) that keeps the leg's coordinate
    /// changes within the solver's largest step; the step is kept for `advance_measured`.
    pub fn step_fraction(&self, lin: &mut LegLinear, platform_step: &Vec6) -> f64 {
        match (self, &mut lin.lin) {
            (Leg::Vjm(l), Some(chain)) => l.loaded_chain().damping(chain, &(lin.shift * platform_step)),
            _ => 1.0,
        }
    }

    /// Applies `fraction` of the Newton step in which the platform moves by `platform_step`.
    pub fn advance(&self, lin: &mut LegLinear, platform_step: &Vec6, fraction: f64, state: &mut LegState) {
        if let (Leg::Vjm(l), Some(chain)) = (self, &mut lin.lin) {
            let end_twist = lin.shift * platform_step;
            l.loaded_chain().advance(chain, &end_twist, fraction, &mut state.coords, &mut state.end_wrench);
        }
    }

    /// Applies `fraction` of the step `step_fraction` measured last.
    pub fn advance_measured(&self, lin: &LegLinear, fraction: f64, state: &mut LegState) {
        if let (Leg::Vjm(l), Some(chain)) = (self, &lin.lin) {
            l.loaded_chain().advance_measured(chain, fraction, &mut state.coords, &mut state.end_wrench);
        }
    }

    /// Stability with its end held of the leg's last linearised equilibrium (in its state).
    pub fn stable(&self, state: &mut LegState) -> bool {
        match self {
            Leg::Vjm(l) => l.loaded_chain().stable(&mut state.equilibrium),
            Leg::Msa(_) => true,
        }
    }

    /// After `place`: the twists at the reference point (base frame) along which the leg's actuated and
    /// passive joints move its end, the rigid leg's kinematics; None for an MSA leg (its joints are
    /// elements of a structure, not coordinates of a chain) or where the placement failed.
    pub fn joint_twists<'s>(&self, platform: &Frame, state: &'s mut LegState) -> Option<JointTwists<'s>> {
        let Leg::Vjm(l) = self else { return None };
        let jac = state.ik.joints_at_solution(&l.chain, &state.coords)?;
        Some(JointTwists { back: back_to_reference_point(platform, jac), jac })
    }

    /// After `place`: the platform twist at the reference point that a unit change of each actuated
    /// coordinate would cause if it alone moved the leg's end (its end-point error per unit actuator offset,
    /// paper 000 s. 4.2), in the base frame.
    pub fn actuator_twists(&self, platform: &Frame, state: &mut LegState) -> Vec<Vec6> {
        match self {
            // An MSA leg has no actuated coordinate: its actuators are elastic joints, whose offsets enter
            // through their preload.
            Leg::Msa(_) => Vec::new(),
            Leg::Vjm(l) => {
                let jac = l.evaluation(state);
                twists_at_reference_point(&jac.actuated, platform, jac)
            }
        }
    }
}

/// Twists of a chain's joints at its end point EP seen at the platform's reference point RP: the inverse of
/// `point_shift(v)`, v = EP - RP.
fn twists_at_reference_point(twists: &[Vec6], platform: &Frame, jac: &ChainJacobians) -> Vec<Vec6> {
    let back = back_to_reference_point(platform, jac);
    twists.iter().map(|t| back * t).collect()
}

/// The shift that moves a twist at the chain's end point to the platform's reference point.
fn back_to_reference_point(platform: &Frame, jac: &ChainJacobians) -> Mat6 {
    point_shift(&(platform.pos - jac.end.pos))
}

/// The twists of a VJM leg's joints at its placement (`Leg::joint_twists`), at the reference point: the
/// placement's own columns moved there as they are read (nothing is allocated).
pub struct JointTwists<'s> {
    jac: &'s ChainJacobians,
    /// `back_to_reference_point`.
    back: Mat6,
}

impl JointTwists<'_> {
    /// One per actuated coordinate.
    pub fn actuated(&self) -> impl Iterator<Item = Vec6> + '_ {
        self.jac.actuated.iter().map(|t| self.back * t)
    }

    /// One per passive coordinate.
    pub fn passive(&self) -> impl Iterator<Item = Vec6> + '_ {
        self.jac.passive.iter().map(|t| self.back * t)
    }
}

/// The wrench the platform applies to a leg once the leg's own Newton correction is made, at the
/// reference point.
fn corrected_force(lin: &Linearization, platform: &Frame) -> Vec6 {
    wrench_at_reference_point(&lin.corrected_wrench(), &(lin.end - platform.pos))
}

/// A wrench the platform applies at a leg's end point seen at the reference point, `v = EP - RP`: the force
/// is unchanged, the moment gains v x F.
fn wrench_at_reference_point(wrench: &Vec6, v: &Vec3) -> Vec6 {
    let f: Vec3 = wrench.fixed_rows::<3>(0).into();
    let m: Vec3 = wrench.fixed_rows::<3>(3).into();
    let m_rp = m + v.cross(&f);
    Vec6::new(f.x, f.y, f.z, m_rp.x, m_rp.y, m_rp.z)
}

/// A wrench the platform applies at a leg's end point, and the leg's tangent stiffness there, seen at the
/// reference point RP, with `v = EP - RP`: the force is unchanged, the moment gains v x F, and the stiffness
/// is A^T K A (paper 000 eq 54-55) plus [F]x [v]x in its rotational block, because the lever arm v turns
/// with the platform.
pub fn at_reference_point(wrench: &Vec6, k_end: &Mat6, v: &Vec3) -> AtReferencePoint {
    let f: Vec3 = wrench.fixed_rows::<3>(0).into();
    let mut stiffness = shift_stiffness(k_end, v);
    let mut magnitude = shift_magnitude(k_end, v);
    let geometric: Mat3 = skew(&f) * skew(v);
    let mut block = stiffness.fixed_view_mut::<3, 3>(3, 3);
    block += geometric;
    let geometric_size = skew(&f).abs() * skew(v).abs();
    for i in 0..3 {
        magnitude[3 + i] += geometric_size[(i, i)];
    }
    AtReferencePoint { wrench: wrench_at_reference_point(wrench, v), stiffness, magnitude }
}

/// A leg's wrench and tangent stiffness moved to the reference point, with the size of the stiffness'
/// terms (`frame::shift_magnitude`).
pub struct AtReferencePoint {
    /// The wrench at the reference point.
    pub wrench: Vec6,
    /// The tangent stiffness at the reference point.
    pub stiffness: Mat6,
    /// The size of the stiffness' diagonal terms (`frame::shift_magnitude`).
    pub magnitude: Vec6,
}

impl LegLinear {
    /// Sets aside the leg's factorisation of this linearisation in its workspace, for `resume` (an MSA leg,
    /// linear, has none to keep). False where the workspace no longer holds it.
    pub(super) fn keep(&self, state: &mut LegState) -> bool {
        self.lin.as_ref().is_none_or(|lin| state.equilibrium.keep_factorisation(lin))
    }

    /// Makes the factorisation `keep` set aside for this linearisation the leg's current one, for chord
    /// steps on it. False where none was set aside for it.
    pub(super) fn resume(&mut self, state: &mut LegState) -> bool {
        self.lin.as_mut().is_none_or(|lin| state.equilibrium.resume_kept(lin))
    }
}

/// A leg's linearised equilibrium seen from the platform: one Newton step of the whole manipulator
/// (platform pose and every leg's configuration together) is built from these.
#[derive(Clone, Debug, Default)]
pub struct LegLinear {
    /// The VJM chain's linearised equilibrium (None for a linear MSA leg).
    lin: Option<Linearization>,
    /// point_shift(v): a platform twist at the reference point as a twist of the leg's end.
    shift: Mat6,
    /// Wrench the platform applies to the leg once the leg's own correction is made, at the reference point.
    pub corrected_force: Vec6,
    /// Tangent stiffness at the reference point.
    pub stiffness: Mat6,
    /// Size of its diagonal's terms (`LegResponse::magnitude`).
    pub magnitude: Vec6,
    /// How far the configuration linearised is from the leg's equilibrium (relative: rad, or mm over the
    /// leg's length scale, see `Linearization::distance_from_equilibrium`).
    pub distance: f64,
}
