//! The measurement model: the displacement of the measured point under a wrench, predicted from the real
//! model's compliance C, the legs' stiffnesses K_i and their actuator twists a_i at each pose, with the
//! measurement-model effects of `model::effect` added (paper 000 eq 60 for end-point errors): gravity C (m g);
//! leg-geometry C K_i eps_i; preload C K_i a_i theta0; backlash C K_i a_i b sign(a_i . F_i) with F_i = K_i C w
//! the leg's load; tool-offset r + dp + dphi x r; loaded-nonlinearity lambda (loaded - linear). Spring
//! scalings are not terms here: they change the manipulator itself (`model::effect::scaled`).

use super::error::PoseError;
use crate::kinematics::frame::{Frame, Mat6, Vec3, Vec6};
use crate::model::effect::{Effect, Kind, Target};
use crate::platform::compliance::analyse;
use crate::platform::manipulator::{Manipulator, ManipulatorState};

/// What the model says at one pose: compliance, the legs' stiffnesses at the reference point and each
/// leg's first actuator twist (zero for a leg without one).
#[derive(Clone, Debug)]
pub struct PoseModel {
    /// Compliance of the manipulator at the pose.
    pub compliance: Mat6,
    /// Each leg's stiffness at the reference point.
    pub legs: Vec<Mat6>,
    /// Each leg's first actuator twist (zero without one).
    pub actuators: Vec<Vec6>,
}

impl PoseModel {
    /// Evaluates the model at `pose` (unloaded).
    pub fn at(m: &Manipulator, pose: &Frame, state: &mut ManipulatorState) -> Result<PoseModel, PoseError> {
        let mut legs = Vec::with_capacity(m.legs.len());
        let total = m.unloaded_each(pose, state, |_, r| legs.push(r.stiffness)).map_err(PoseError::Fails)?;
        let Some(&compliance) = analyse(&total.stiffness, &total.magnitude, m.length_scale, true).compliance() else {
            return Err(PoseError::NoCompliance);
        };
        let actuators = m
            .legs
            .iter()
            .zip(state.legs.iter_mut())
            .map(|(l, s)| l.actuator_twists(pose, s).first().copied().unwrap_or_else(Vec6::zeros))
            .collect();
        Ok(PoseModel { compliance, legs, actuators })
    }

    /// The platform displacement (at the reference point) caused by leg k's end-point error `eps` (eq 60).
    fn end_error(&self, k: usize, eps: &Vec6) -> Vec6 {
        self.compliance * (self.legs[k] * eps)
    }

    /// The displacement of the measured point under wrench `w`, with the measurement-model effects
    /// (`loaded`: the displacement of the loaded equilibrium, used instead of C w when given or in part by
    /// loaded-nonlinearity).
    pub fn displacement(
        &self,
        w: &Vec6,
        loaded: Option<&Vec6>,
        effects: &[Effect],
        loaded_mode: bool,
        g: &Vec3,
    ) -> Vec3 {
        let linear = self.compliance * w;
        let mut d = match (loaded_mode, loaded) {
            (true, Some(l)) => *l,
            _ => linear,
        };
        let mut tool = Vec3::zeros();
        for e in effects {
            match (&e.kind, &e.target) {
                (Kind::Gravity, _) => {
                    let f = g * e.values[0];
                    d += self.compliance * Vec6::new(f.x, f.y, f.z, 0.0, 0.0, 0.0);
                }
                (Kind::LegGeometry, Target::Leg(k)) => d += self.end_error(*k, &Vec6::from_column_slice(&e.values)),
                (Kind::Preload, Target::Leg(k)) => d += self.end_error(*k, &(self.actuators[*k] * e.values[0])),
                (Kind::Backlash, Target::Leg(k)) => {
                    // The actuator's load, power-conjugate to its twist, picks the side of the clearance.
                    let force = self.actuators[*k].dot(&(self.legs[*k] * linear));
                    let side = if force.abs() > 1e-9 { force.signum() } else { 0.0 };
                    d += self.end_error(*k, &(self.actuators[*k] * (e.values[0] * side)));
                }
                (Kind::LoadedNonlinearity, _) => {
                    if let (false, Some(l)) = (loaded_mode, loaded) {
                        d += (l - linear) * e.values[0];
                    }
                }
                (Kind::ToolOffset, _) => tool = Vec3::new(e.values[0], e.values[1], e.values[2]),
                _ => {}
            }
        }
        let rotation = Vec3::new(d[3], d[4], d[5]);
        Vec3::new(d[0], d[1], d[2]) + tool + rotation.cross(&tool)
    }
}

/// Gravity for the gravity effect: the model's, or standard gravity along -z when the model gives none.
pub fn gravity_of(m: &Manipulator) -> Vec3 {
    m.gravity.unwrap_or(Vec3::new(0.0, 0.0, -9.81))
}
