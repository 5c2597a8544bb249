//! The measurement model: the displacement of the measured point under a wrench, predicted from the real
//! model's compliance C, the legs' stiffnesses K_i and their actuator twists a_i at each pose, with the
//! measurement-model effects of `model::effect` added (paper 000 eq 60 for end-point errors): gravity C (m g)
//! (with an offset centre, C (m g, c x m g)); leg-geometry C K_i eps_i; actuator-offset C K_i a_i delta;
//! backlash C K_i a_i b sign(a_i . F_i) with F_i = K_i C w the leg's load; tool-offset r + dp + dphi x r;
//! loaded-nonlinearity lambda (loaded - linear); frame-rotation omega x p; tool-compliance c F; drift v t.
//! Spring scalings are not terms here: they change the manipulator itself (`model::effect::scaled`).

use super::data::Measurement;
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
    /// Unloaded: with the legs' unloaded K_i this is the rigid motion the error forces (J^-1 for a robot that
    /// is not over-constrained), which a load changes only at second order.
    fn end_error(&self, k: usize, eps: &Vec6) -> Vec6 {
        self.compliance * (self.legs[k] * eps)
    }

    /// The displacement of the measured point in row `row`: `base` is the model's own displacement of the
    /// reference point (its loaded equilibrium, or its rest displacement plus C w), `nonlinear` the loaded
    /// minus the linear response (for loaded-nonlinearity, when the base is linear), and `effects` add their
    /// terms. Backlash picks its side by the actuator's load under the row's wrench. `tangent`: the tangent
    /// compliance at the row's loaded equilibrium, through which an added load acts (loaded mode), else the
    /// unloaded C.
    pub fn displacement(
        &self,
        row: &Measurement,
        base: &Vec6,
        nonlinear: Option<&Vec6>,
        effects: &[Effect],
        g: &Vec3,
        tangent: Option<&Mat6>,
    ) -> Vec3 {
        let w = &row.wrench;
        // A load added to a loaded platform moves it by the compliance where it stands.
        let c = tangent.unwrap_or(&self.compliance);
        let mut d = *base;
        // The measured point, wherever the tool-offset stands in the list (frame-rotation turns it).
        let tool = effects.iter().rev().find(|e| e.kind == Kind::ToolOffset).map_or(Vec3::zeros(), |e| {
            let v = &e.values;
            Vec3::new(v[0], v[1], v[2])
        });
        let mut measured = Vec3::zeros();
        for e in effects {
            let v = &e.values;
            match (&e.kind, &e.target) {
                // A mass's weight at the reference point: force m g, moment (R m c) x g (gravity-offset is
                // stored as (m, m c); plain gravity has c = 0), its arm turned with the platform by the
                // model's own deflection there: a centre along gravity weighs only as the platform turns.
                (Kind::Gravity | Kind::GravityOffset, _) => {
                    let f = g * v[0];
                    let turn = crate::kinematics::frame::rotation_from_vector(&Vec3::new(base[3], base[4], base[5]));
                    let m = if v.len() == 4 { (turn * Vec3::new(v[1], v[2], v[3])).cross(g) } else { Vec3::zeros() };
                    d += c * Vec6::new(f.x, f.y, f.z, m.x, m.y, m.z);
                }
                (Kind::LegGeometry, Target::Leg(k)) => d += self.end_error(*k, &Vec6::from_column_slice(v)),
                (Kind::ActuatorOffset, Target::Leg(k)) => d += self.end_error(*k, &(self.actuators[*k] * v[0])),
                (Kind::Backlash, Target::Leg(k)) => {
                    // The actuator's load, power-conjugate to its twist, picks the side of the clearance.
                    let force = self.actuators[*k].dot(&(self.legs[*k] * (self.compliance * w)));
                    let side = if force.abs() > 1e-9 { force.signum() } else { 0.0 };
                    d += self.end_error(*k, &(self.actuators[*k] * (v[0] * side)));
                }
                (Kind::LoadedNonlinearity, _) => {
                    if let Some(n) = nonlinear {
                        d += n * v[0];
                    }
                }
                // The instrument reads positions p' = p + omega x p: a displacement picks up omega x p.
                (Kind::FrameRotation, _) => measured += Vec3::new(v[0], v[1], v[2]).cross(&(row.position + tool)),
                (Kind::ToolCompliance, _) => measured += Vec3::new(w[0], w[1], w[2]) * v[0],
                (Kind::Drift, _) => measured += Vec3::new(v[0], v[1], v[2]) * row.order.unwrap_or(0.0),
                _ => {}
            }
        }
        let rotation = Vec3::new(d[3], d[4], d[5]);
        Vec3::new(d[0], d[1], d[2]) + tool + rotation.cross(&tool) + measured
    }
}

/// Gravity for the gravity effects: what a payload of the model weighs under.
pub fn gravity_of(m: &Manipulator) -> Vec3 {
    m.weight_gravity()
}
