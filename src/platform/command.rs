//! Commanding a real robot through a controller that knows only the nominal geometry (compliance error
//! compensation, paper 000 s. 5.2 and its ref. [73]): the controller turns a commanded platform pose into
//! actuator coordinates by the nominal inverse kinematics; the real robot (legs with errors, corrected
//! springs, a payload) holds its actuators there and settles under the process wrench.

use super::compliance::analyse;
use super::leg::{Leg, LegState};
use super::manipulator::{Manipulator, ManipulatorState, PoseFailure};
use crate::kinematics::chain::{JointKind, Role};
use crate::kinematics::frame::{weigh_rotations, Frame, Mat6, Vec6};
use crate::linalg::{span_basis, Orthonormal6};
use nalgebra::DMatrix;

/// How far from its reading an actuated coordinate may be left by `Manipulator::pose_at_actuators`, relative
/// to the length scale: a few hundred times round-off, which Newton's quadratic steps reach from any pose
/// near the solution.
const ACTUATOR_TOLERANCE: f64 = 1e-13;

/// The directions the actuators move the platform in (`Manipulator::commanded_directions`).
#[derive(Clone, Debug, PartialEq)]
pub enum Directions {
    /// An orthonormal basis of them (weighted coordinates: rotations times the length scale).
    Span(Vec<Vec6>),
    /// None, or the platform also moves with the actuators locked (the stiffness K is singular).
    Singular,
    /// The kinematics is not finite there.
    NotFinite,
}

impl Manipulator {
    /// After the nominal manipulator placed `nominal` for a command: sets this (real) manipulator's
    /// actuators where that placement put them, every leg starting its loaded equilibrium from the nominal
    /// placement (a caller with earlier solutions then applies their extrapolated departures from it,
    /// `LegState::apply_combined_offsets`). The real legs must have the nominal legs' coordinates (errors built
    /// in by fixed transforms and parameter values, `Leg::with_errors`).
    pub fn take_command(&self, nominal: &ManipulatorState, state: &mut ManipulatorState) {
        for (real, placed) in state.legs.iter_mut().zip(&nominal.legs) {
            real.take_command(placed);
        }
    }

    /// The platform twists (at the reference point, base frame) that a unit change of each actuated
    /// coordinate causes with the others held, for the rigid robot at `pose` (placing it there): the
    /// forward kinematic Jacobian dt/da, in the order of the legs and their actuated coordinates. Leg i's
    /// actuator moves its end by u (its actuator twist); the other legs accept the platform motion through
    /// their passive joints, which their stiffness K_j annihilates, so K t = K_i u and t = K^-1 K_i u
    /// exactly (any springs, as long as K is regular). None where K is singular.
    pub fn actuator_motions(
        &self,
        pose: &Frame,
        state: &mut ManipulatorState,
    ) -> Result<Option<Vec<Vec6>>, PoseFailure> {
        let mut stiffness: Vec<Mat6> = Vec::with_capacity(self.legs.len());
        let total = self.unloaded_each(pose, state, |_, r| stiffness.push(r.stiffness))?;
        let Some(compliance) =
            analyse(&total.stiffness, &total.magnitude, self.length_scale, true).compliance().copied()
        else {
            return Ok(None);
        };
        let mut motions = Vec::new();
        for ((leg, s), k) in self.legs.iter().zip(state.legs.iter_mut()).zip(&stiffness) {
            motions.extend(leg.actuator_twists(pose, s).iter().map(|u| compliance * (k * u)));
        }
        Ok(Some(motions))
    }

    /// The pose of the rigid robot whose actuators read `readings` (every actuated coordinate, leg by leg, in
    /// order): Newton's method from `start` on the inverse kinematics, each step moving the platform by the
    /// actuators' motions (`actuator_motions`, the forward kinematic Jacobian) times what the readings
    /// differ from the placement's coordinates. None where a placement fails, K is singular, the readings do
    /// not cover every actuated coordinate, or 30 steps leave a coordinate further than `ACTUATOR_TOLERANCE`
    /// (relative to the length scale) from its reading.
    pub fn pose_at_actuators(&self, readings: &[f64], start: &Frame, state: &mut ManipulatorState) -> Option<Frame> {
        let tolerance = ACTUATOR_TOLERANCE * self.length_scale.max(1.0);
        let mut pose = *start;
        let mut previous = f64::INFINITY;
        for _ in 0..30 {
            let motions = self.actuator_motions(&pose, state).ok()??;
            let placed: Vec<f64> = state.actuators().flatten().copied().collect();
            if placed.len() != readings.len() || motions.len() != readings.len() {
                return None;
            }
            let mut step = Vec6::zeros();
            let mut largest = 0.0f64;
            for ((motion, at), reading) in motions.iter().zip(&placed).zip(readings) {
                step += motion * (reading - at);
                largest = largest.max((reading - at).abs());
            }
            // Within the tolerance, or at the round-off floor (no longer falling) well within a placement's.
            if largest <= tolerance || (largest >= previous && largest <= 1e3 * tolerance) {
                return Some(pose);
            }
            previous = largest;
            if !largest.is_finite() {
                return None;
            }
            pose = crate::kinematics::frame::apply_twist(&pose, &step);
        }
        None
    }

    /// The platform motions the actuators command at `pose` (placing the rigid robot there): an orthonormal
    /// basis of the span of `actuator_motions`, in weighted coordinates (rotations times the length scale).
    ///
    /// With VJM legs it comes from the legs' joint twists (screw theory): the platform can move along a
    /// twist only where every leg's joints can follow it, that is along the twists orthogonal to every
    /// leg's constraints (the complement of its joints' twists); the actuators command every such motion
    /// unless the platform can also move with them locked, along twists every leg's passive joints follow
    /// (the complements of the passive twists alone then span less than all six directions: `Singular`, as
    /// K^-1 is there). The joint twists are the placement's own evaluation, so this costs a few small
    /// Gram-Schmidt passes where `actuator_motions` needs every leg's stiffness, the whole one's inverse and
    /// an SVD. A robot with an MSA leg (no joint coordinates) takes that route.
    pub fn commanded_directions(&self, pose: &Frame, state: &mut ManipulatorState) -> Result<Directions, PoseFailure> {
        self.place(pose, state)?;
        // The directions no leg's joints follow (the constraints), and those the passive joints alone do
        // not follow (constraints and actuations).
        let (mut constraints, mut actuations) = (Orthonormal6::default(), Orthonormal6::default());
        for k in 0..self.legs.len() {
            let Some(joints) = self.legs[k].joint_twists(pose, &mut state.legs[k]) else {
                return self.directions_by_stiffness(pose, state);
            };
            let weighted = |t: Vec6| weigh_rotations(&t, self.length_scale);
            let mut follows = Orthonormal6::default();
            if !follows.span(joints.passive().map(weighted)) {
                return Ok(Directions::NotFinite);
            }
            actuations.span_complement_of(&follows);
            if !follows.span(joints.actuated().map(weighted)) {
                return Ok(Directions::NotFinite);
            }
            constraints.span_complement_of(&follows);
        }
        let span: Vec<Vec6> = constraints.complement().collect();
        Ok(match actuations.directions().len() == 6 && !span.is_empty() {
            true => Directions::Span(span),
            false => Directions::Singular,
        })
    }

    /// `commanded_directions` from `actuator_motions`: the span of the motions, weighted.
    fn directions_by_stiffness(&self, pose: &Frame, state: &mut ManipulatorState) -> Result<Directions, PoseFailure> {
        let Some(motions) = self.actuator_motions(pose, state)? else { return Ok(Directions::Singular) };
        let l = self.length_scale;
        let weighted = DMatrix::from_fn(6, motions.len(), |r, c| weigh_rotations(&motions[c], l)[r]);
        Ok(match span_basis(&weighted) {
            Some(basis) if basis.ncols() > 0 => {
                Directions::Span(basis.column_iter().map(|c| Vec6::from_iterator(c.iter().copied())).collect())
            }
            Some(_) => Directions::Singular,
            None => Directions::NotFinite,
        })
    }

    /// The unit of every actuated coordinate, leg by leg: `mm` for a prismatic, `rad` for a revolute joint.
    pub fn actuator_units(&self) -> Vec<Vec<&'static str>> {
        self.legs.iter().map(Leg::actuator_units).collect()
    }
}

impl Leg {
    /// The unit of each of the leg's actuated coordinates (none for an MSA leg, driven through elastic
    /// joints).
    pub fn actuator_units(&self) -> Vec<&'static str> {
        match self {
            Leg::Vjm(l) => l
                .chain
                .kinds(Role::Actuated)
                .iter()
                .map(|k| if *k == JointKind::Prismatic { "mm" } else { "rad" })
                .collect(),
            Leg::Msa(_) => Vec::new(),
        }
    }
}

impl ManipulatorState {
    /// The actuated coordinates of every leg at its last placement (mm or rad), leg by leg.
    pub fn actuators(&self) -> impl Iterator<Item = &[f64]> {
        self.legs.iter().map(|l| l.coords.actuated.as_slice())
    }
}

impl LegState {
    /// The actuators as the nominal leg's placement `nominal` set them, and the placement as the start of
    /// the loaded equilibrium (`Manipulator::take_command`).
    fn take_command(&mut self, nominal: &LegState) {
        self.coords.clone_from(&nominal.coords);
        self.end_wrench = Vec6::zeros();
        self.last_target = nominal.last_target;
        self.warm = true;
        self.placed.clone_from(&nominal.placed);
        self.placements.clear();
        self.ik.invalidate();
        // An MSA leg's placement (its answer there, the structure's buffers) lives in its MSA state; a VJM
        // leg has none, and copying the empty one would still move its whole size.
        if nominal.msa.placed.is_some() {
            self.msa.clone_from(&nominal.msa);
        }
    }
}
