//! Commanding a real robot through a controller that knows only the nominal geometry (compliance error
//! compensation, paper 000 s. 5.2 and its ref. [73]): the controller turns a commanded platform pose into
//! actuator coordinates by the nominal inverse kinematics; the real robot (legs with errors, corrected
//! springs, a payload) holds its actuators there and settles under the process wrench.

use super::compliance::analyse;
use super::leg::{Leg, LegState};
use super::manipulator::{Manipulator, ManipulatorState, PoseFailure};
use crate::kinematics::chain::{JointKind, Role};
use crate::kinematics::frame::{Frame, Mat6, Vec6};

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
    /// Makes every later placement converge past the usual tolerance (`IkWorkspace::polish`), so that the
    /// actuators follow commands changed by less than it.
    pub fn polish_placements(&mut self) {
        for leg in &mut self.legs {
            leg.ik.polish = true;
        }
    }

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
        self.ik.invalidate();
        // An MSA leg's placement (its answer there, the structure's buffers) lives in its MSA state; a VJM
        // leg has none, and copying the empty one would still move its whole size.
        if nominal.msa.placed.is_some() {
            self.msa.clone_from(&nominal.msa);
        }
    }
}
