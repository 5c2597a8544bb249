//! The leg seam (DESIGN.md, paper 000 eq 66-67): a leg, asked where the platform is, answers with the
//! wrench it exerts on the platform and its tangent stiffness there, both at the platform's reference point
//! and in the base frame. Aggregation and every study talk to legs only through this.

use crate::kinematics::chain::{Chain, ChainJacobians, Coordinates};
use crate::kinematics::frame::{point_shift, shift_magnitude, shift_stiffness, skew, Frame, Mat3, Mat6, Vec3, Vec6};
use crate::kinematics::ik::{self, IkWorkspace};
use crate::vjm::equilibrium::{EquilibriumFailure, EquilibriumWorkspace, Linearization, LoadedChain};
use crate::vjm::spring::SpringGroup;
use crate::vjm::stiffness::{leg_stiffness, passive_range, spring_compliance_at_end};

use super::msa_leg::{MsaLeg, MsaState};

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
    OutOfReach { condition: Option<usize> },
    /// The springs do not restrain the directions the passive joints leave (eq 9 bordered matrix singular).
    SingularChain,
    /// The loaded equilibrium was not found, even with continuation.
    NotConverged { iterations: usize, residual: f64 },
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

/// A VJM leg: a serial chain from the base to the leg's end frame, and where that frame sits on the platform.
#[derive(Clone, Debug)]
pub struct VjmLeg {
    pub name: String,
    /// Base frame -> leg end frame.
    pub chain: Chain,
    /// The copy's frame (identity for a leg written once): the frame of the leg as written, in the base
    /// frame; errors given in the leg's own frame are carried by it.
    pub place: Frame,
    /// The leg's end frame in the platform frame (the platform frame's origin is the reference point).
    pub attachment: Frame,
    pub springs: Vec<SpringGroup>,
    /// Rest values theta0 of the virtual coordinates (spring preload), one per virtual coordinate.
    pub preload: Vec<f64>,
    /// Gravity (m/s^2) acting on the chain's masses.
    pub gravity: Vec3,
    /// mm per rad, to weigh rotations against translations.
    pub length_scale: f64,
}

/// Per-leg state carried from one pose to the next: warm starts of inverse kinematics and of the loaded
/// equilibrium, and buffers.
#[derive(Clone, Debug)]
pub struct LegState {
    pub coords: Coordinates,
    /// True when `coords` holds a solved configuration usable as a warm start.
    pub warm: bool,
    /// Wrench the platform applies to the leg's end at the last equilibrium (N, N mm, at the end point).
    pub end_wrench: Vec6,
    /// The leg-end frame of the last solved equilibrium (or placement), the start of a continuation.
    last_target: Frame,
    /// The configuration before a warm-started attempt, restored if that attempt fails.
    saved: Coordinates,
    /// The rigid configuration found by `place`.
    placed: Coordinates,
    ik: IkWorkspace,
    jac: ChainJacobians,
    equilibrium: EquilibriumWorkspace,
    msa: MsaState,
}

#[derive(Clone, Debug)]
pub enum Leg {
    Vjm(VjmLeg),
    Msa(MsaLeg),
}

impl Leg {
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

    /// Multiplies the compliance of the spring groups `select(name, actuator)` picks by `factor`.
    pub fn scale_springs(&mut self, select: impl Fn(&str, bool) -> bool, factor: f64) {
        if let Leg::Vjm(v) = self {
            for s in v.springs.iter_mut().filter(|s| select(&s.name, s.actuator)) {
                s.scale_compliance(factor);
            }
        }
    }

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
            placed: zeros,
            ik: IkWorkspace::default(),
            jac: ChainJacobians::default(),
            equilibrium: EquilibriumWorkspace::default(),
            msa: MsaState::default(),
        }
    }

    /// Places the leg for a commanded platform pose: inverse kinematics of the rigid leg (springs undeformed),
    /// warm-started from the state's previous solution, else from the home configuration (all zero). Fixes
    /// the actuated coordinates for the loaded answers that follow.
    pub fn place(&self, platform: &Frame, state: &mut LegState) -> Result<usize, LegFailure> {
        match self {
            Leg::Vjm(l) => l.place(platform, state),
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

    /// Linearises the leg's equilibrium with the platform at `platform` (Newton on the whole manipulator).
    pub fn linearize(&self, platform: &Frame, state: &mut LegState) -> Result<LegLinear, LegFailure> {
        match self {
            Leg::Vjm(l) => {
                state.ik.invalidate();
                let target = l.target(platform);
                let loaded = l.loaded_chain();
                let lin = loaded
                    .linearize(&target, &state.coords, &state.end_wrench, &mut state.equilibrium)
                    .ok_or(LegFailure::SingularChain)?;
                let v = lin.end - platform.pos;
                let corrected = lin.wrench + Vec6::from_fn(|r, _| lin.correction[lin.correction.len() - 6 + r]);
                let corrected_force = at_reference_point(&corrected, &Mat6::zeros(), &v).wrench;
                let at_rp = at_reference_point(&lin.wrench, &lin.stiffness(), &v);
                let distance = lin.distance_from_equilibrium(l.length_scale);
                Ok(LegLinear {
                    shift: point_shift(&v),
                    corrected_force,
                    stiffness: at_rp.stiffness,
                    magnitude: at_rp.magnitude,
                    distance,
                    lin: Some(lin),
                })
            }
            // Linear: the answer at `platform` is exact, nothing inside the leg to correct.
            Leg::Msa(l) => {
                let r = l.respond(platform, &state.msa)?;
                Ok(LegLinear {
                    lin: None,
                    shift: Mat6::identity(),
                    corrected_force: -r.wrench,
                    stiffness: r.stiffness,
                    magnitude: r.magnitude,
                    distance: 0.0,
                })
            }
        }
    }

    /// The fraction of a Newton step (platform twist `platform_step`) that keeps the leg's coordinate
    /// changes within the solver's largest step.
    pub fn step_fraction(&self, lin: &LegLinear, platform_step: &Vec6) -> f64 {
        match (self, &lin.lin) {
            (Leg::Vjm(l), Some(chain)) => l.loaded_chain().damping(chain, &(lin.shift * platform_step)),
            _ => 1.0,
        }
    }

    /// Applies `fraction` of the Newton step in which the platform moves by `platform_step`.
    pub fn advance(&self, lin: &LegLinear, platform_step: &Vec6, fraction: f64, state: &mut LegState) {
        if let (Leg::Vjm(l), Some(chain)) = (self, &lin.lin) {
            let end_twist = lin.shift * platform_step;
            l.loaded_chain().advance(chain, &end_twist, fraction, &mut state.coords, &mut state.end_wrench);
        }
    }

    /// Stability with its end held of the leg's last linearised equilibrium (in its state).
    pub fn stable(&self, state: &LegState) -> bool {
        match self {
            Leg::Vjm(l) => l.loaded_chain().stable(&state.equilibrium),
            Leg::Msa(_) => true,
        }
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
                // A twist at EP seen at RP: inverse of point_shift(v), v = EP - RP.
                let back = point_shift(&(platform.pos - jac.end.pos));
                jac.actuated.iter().map(|t| back * t).collect()
            }
        }
    }
}

/// A leg's end-point error eps_i at the reference point (paper 000 eq 69) by source: given directly, from
/// the base error, and from the parameter errors through the leg's own kinematics.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EndErrors {
    pub direct: Vec6,
    pub base: Vec6,
    pub parameters: Vec6,
}

impl EndErrors {
    pub fn total(&self) -> Vec6 {
        self.direct + self.base + self.parameters
    }
}

impl Leg {
    /// After `place`: where the leg with errors puts the platform's reference point when its actuated and
    /// passive coordinates keep their nominal values (eq 69: g*(q0, theta0) = t0 + eps), as a twist at the
    /// reference point. `base` is the leg's rigid base error (a frame in the base frame); `perturbed` the leg
    /// rebuilt with its parameter errors (a VJM leg of the same structure).
    pub fn end_errors(
        &self,
        platform: &Frame,
        state: &LegState,
        direct: &Vec6,
        base: &Frame,
        perturbed: Option<&Leg>,
    ) -> Result<EndErrors, LegFailure> {
        // The whole leg moved rigidly by `base` carries the platform with it: P' = base P.
        let base_error = platform.error_to(&base.compose(platform));
        let parameters = match (self, perturbed) {
            (_, None) => Vec6::zeros(),
            (Leg::Vjm(l), Some(Leg::Vjm(p))) if p.chain.elements().len() == l.chain.elements().len() => {
                let end = p.chain.end_frame(&state.coords);
                platform.error_to(&end.compose(&p.attachment.inverse()))
            }
            // An MSA leg's geometry is solved from the pose, so its parameters do not move its end: the error
            // file refuses parameter errors for it (`ErrorSet::load`), so only a rebuild that does not match lands here.
            _ => return Err(LegFailure::SingularChain),
        };
        Ok(EndErrors { direct: *direct, base: base_error, parameters })
    }

    /// After `place`: the leg's joints when its end is moved by `dt` (a twist at the reference point) from
    /// the placement with the actuators held (paper 000 eq 64-65, from K_Cq and K_Ctheta of eq 46). None for
    /// an MSA leg (its joints are not coordinates of a chain).
    pub fn joint_deflections(
        &self,
        platform: &Frame,
        dt: &Vec6,
        state: &mut LegState,
    ) -> Option<super::assembly::JointDeflections> {
        let Leg::Vjm(l) = self else { return None };
        let target = l.target(platform);
        let lin = l.loaded_chain().linearize(&target, &state.coords, &Vec6::zeros(), &mut state.equilibrium)?;
        let twist = point_shift(&(lin.end - platform.pos)) * dt;
        let delta = &lin.sensitivity * nalgebra::DVector::from_column_slice(twist.as_slice());
        let n_q = state.coords.passive.len();
        let mut out =
            super::assembly::JointDeflections { passive_max: delta.rows(0, n_q).amax(), ..Default::default() };
        let theta = delta.rows(n_q, state.coords.virtual_.len());
        let kinds = l.chain.virtual_kinds();
        for g in &l.springs {
            let th = nalgebra::DVector::from_fn(g.dim, |r, _| theta[g.first + r]);
            let k = g.stiffness.view((0, 0), (g.dim, g.dim));
            let tau = k * &th;
            for r in 0..g.dim {
                if kinds[g.first + r] == crate::kinematics::chain::JointKind::Prismatic {
                    out.spring_deflection_max = out.spring_deflection_max.max(th[r].abs());
                    out.spring_force_max = out.spring_force_max.max(tau[r].abs());
                } else {
                    out.spring_rotation_max = out.spring_rotation_max.max(th[r].abs());
                    out.spring_torque_max = out.spring_torque_max.max(tau[r].abs());
                }
            }
        }
        Some(out)
    }

    /// The same leg with its errors built in, for the non-linear assembly (eq 69-72): a VJM leg's chain
    /// (its parameter-perturbed version if given) moved by the base error and by the direct end error (a
    /// rigid motion about the reference point of `platform`).
    pub fn with_errors(&self, platform: &Frame, direct: &Vec6, base: &Frame, perturbed: Option<&Leg>) -> Leg {
        match (self, perturbed) {
            (Leg::Vjm(l), p) => {
                let chain = match p {
                    Some(Leg::Vjm(p)) => &p.chain,
                    _ => &l.chain,
                };
                let r = crate::kinematics::frame::rotation_from_vector(&Vec3::new(direct[3], direct[4], direct[5]));
                let about_rp =
                    Frame::new(r, platform.pos + Vec3::new(direct[0], direct[1], direct[2]) - r * platform.pos);
                Leg::Vjm(VjmLeg { chain: chain.prepended(*base).prepended(about_rp), ..l.clone() })
            }
            (Leg::Msa(_), _) => self.clone(),
        }
    }
}

impl LegState {
    /// For a linear (MSA) leg, placed nominally: makes it answer as if its end sat `eps` away (the leg's
    /// end-point error). Nothing for a VJM leg, whose errors are built into its chain (`Leg::with_errors`).
    pub fn offset_placement(&mut self, eps: &Vec6) {
        if let Some((placed, _)) = self.msa.placed.as_mut() {
            *placed = apply_twist(placed, eps);
        }
    }
}

impl VjmLeg {
    fn target(&self, platform: &Frame) -> Frame {
        platform.compose(&self.attachment)
    }

    fn has_masses(&self) -> bool {
        self.chain.elements().iter().any(|e| matches!(e, crate::kinematics::chain::Element::Mass { .. }))
    }

    fn loaded_chain(&self) -> LoadedChain<'_> {
        LoadedChain {
            chain: &self.chain,
            springs: &self.springs,
            gravity: self.gravity,
            preload: &self.preload,
            length_scale: self.length_scale,
        }
    }

    /// The chain's Jacobians at the state's configuration, reusing inverse kinematics' last evaluation.
    fn evaluation<'a>(&self, state: &'a mut LegState) -> &'a ChainJacobians {
        if state.ik.solution().is_some() {
            return state.ik.solution().expect("checked just above");
        }
        self.chain.evaluate(&state.coords, &mut state.jac);
        state.jac.fill_virtual();
        &state.jac
    }

    fn place(&self, platform: &Frame, state: &mut LegState) -> Result<usize, LegFailure> {
        let target = self.target(platform);
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
            match ik::solve(&self.chain, &target, &mut state.coords, &mut state.ik, self.length_scale) {
                Ok(n) => {
                    state.placed.clone_from(&state.coords);
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
        state.coords.actuated.iter_mut().for_each(|t| *t = 0.0);
        state.coords.passive.iter_mut().for_each(|t| *t = 0.0);
        match ik::solve(&self.chain, &target, &mut state.coords, &mut state.ik, self.length_scale) {
            Ok(n) => {
                state.warm = true;
                state.placed.clone_from(&state.coords);
                Ok(n)
            }
            Err(e) => {
                state.warm = false;
                Err(LegFailure::Unreachable(e))
            }
        }
    }

    fn respond_unloaded(&self, platform: &Frame, state: &mut LegState) -> Result<LegResponse, LegFailure> {
        // A posture-dependent spring (a parallelogram) needs the passive coordinates; others do not (no copy).
        let passive =
            if self.springs.iter().any(|s| s.posture.is_some()) { state.coords.passive.clone() } else { Vec::new() };
        let jac = self.evaluation(state);
        let s = spring_compliance_at_end(&jac.virtual_, &self.springs, &passive);
        let range = passive_range(&jac.passive, self.length_scale);
        let k_end = leg_stiffness(&s, &range).ok_or(LegFailure::SingularChain)?;
        // Move from the leg's end point EP to the reference point RP: K_RP = A^T K_EP A, v = EP - RP.
        let v = jac.end.pos - platform.pos;
        let (stiffness, magnitude) = (shift_stiffness(&k_end, &v), shift_magnitude(&k_end, &v));
        Ok(LegResponse { wrench: Vec6::zeros(), stiffness, magnitude, stable: true, iterations: 0 })
    }

    fn respond(&self, platform: &Frame, state: &mut LegState) -> Result<LegResponse, LegFailure> {
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

    fn continuation(
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

/// How a leg's loaded equilibrium departs from its placement: carried from one point of a map to the
/// next, it starts the next equilibrium where the last one ended (neighbouring points load the legs
/// alike), which saves Newton iterations over starting from the unloaded placement.
#[derive(Clone, Debug, Default)]
pub struct LoadedOffsets {
    passive: Vec<f64>,
    virtual_: Vec<f64>,
    wrench: Vec6,
}

impl LoadedOffsets {
    /// The linear extrapolation `2 self - older` (the next of three equally spaced points).
    pub fn extrapolate(&self, older: &LoadedOffsets) -> LoadedOffsets {
        let lin = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| 2.0 * x - y).collect();
        LoadedOffsets {
            passive: lin(&self.passive, &older.passive),
            virtual_: lin(&self.virtual_, &older.virtual_),
            wrench: self.wrench * 2.0 - older.wrench,
        }
    }
}

impl LegState {
    /// After a loaded answer: its departure from the placement.
    pub fn loaded_offsets(&self) -> LoadedOffsets {
        LoadedOffsets {
            passive: self.coords.passive.iter().zip(&self.placed.passive).map(|(a, b)| a - b).collect(),
            virtual_: self.coords.virtual_.clone(),
            wrench: self.end_wrench,
        }
    }

    /// After `place`: start the loaded equilibrium from the placement plus `offsets`.
    pub fn apply_loaded_offsets(&mut self, offsets: &LoadedOffsets) {
        if offsets.passive.len() != self.coords.passive.len() || offsets.virtual_.len() != self.coords.virtual_.len() {
            return;
        }
        for (q, d) in self.coords.passive.iter_mut().zip(&offsets.passive) {
            *q += d;
        }
        self.coords.virtual_.copy_from_slice(&offsets.virtual_);
        self.end_wrench = offsets.wrench;
        self.ik.invalidate();
    }
}

/// A wrench the platform applies at a leg's end point, and the leg's tangent stiffness there, seen at the
/// reference point RP, with `v = EP - RP`: the force is unchanged, the moment gains v x F, and the stiffness
/// is A^T K A (paper 000 eq 54-55) plus [F]x [v]x in its rotational block, because the lever arm v turns
/// with the platform.
pub fn at_reference_point(wrench: &Vec6, k_end: &Mat6, v: &Vec3) -> AtReferencePoint {
    let f: Vec3 = wrench.fixed_rows::<3>(0).into();
    let m: Vec3 = wrench.fixed_rows::<3>(3).into();
    let m_rp = m + v.cross(&f);
    let mut stiffness = shift_stiffness(k_end, v);
    let mut magnitude = shift_magnitude(k_end, v);
    let geometric: Mat3 = skew(&f) * skew(v);
    let mut block = stiffness.fixed_view_mut::<3, 3>(3, 3);
    block += geometric;
    let geometric_size = skew(&f).abs() * skew(v).abs();
    for i in 0..3 {
        magnitude[3 + i] += geometric_size[(i, i)];
    }
    AtReferencePoint { wrench: Vec6::new(f.x, f.y, f.z, m_rp.x, m_rp.y, m_rp.z), stiffness, magnitude }
}

/// A leg's wrench and tangent stiffness moved to the reference point, with the size of the stiffness'
/// terms (`frame::shift_magnitude`).
pub struct AtReferencePoint {
    pub wrench: Vec6,
    pub stiffness: Mat6,
    pub magnitude: Vec6,
}

/// A leg's linearised equilibrium seen from the platform: one Newton step of the whole manipulator
/// (platform pose and every leg's configuration together) is built from these.
#[derive(Clone, Debug)]
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
    /// How far the configuration linearised is from the leg's equilibrium (rad or mm, see
    /// `Linearization::distance_from_equilibrium`).
    pub distance: f64,
}

/// The frame a fraction `a` of the way along the twist `delta` from `start` (rotation about a fixed axis).
pub fn interpolate(start: &Frame, delta: &Vec6, a: f64) -> Frame {
    apply_twist(start, &(delta * a))
}

/// `start` moved by a small displacement (translation, base-frame rotation vector): the inverse of
/// `Frame::error_to`.
pub fn apply_twist(start: &Frame, d: &Vec6) -> Frame {
    let r = crate::kinematics::frame::rotation_from_vector(&Vec3::new(d[3], d[4], d[5]));
    Frame::new(r * start.rot, start.pos + Vec3::new(d[0], d[1], d[2]))
}
