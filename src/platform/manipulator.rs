//! A parallel manipulator: legs summed at the platform reference point (paper 001 s. 3.3, paper 000 eq 54).

use super::leg::{Leg, LegFailure, LegResponse, LegState};
use crate::kinematics::frame::{Frame, Mat6, Vec6};

/// A parallel manipulator: its legs, summed at the platform's reference point.
#[derive(Clone, Debug)]
pub struct Manipulator {
    /// Its name.
    pub name: String,
    /// Its legs.
    pub legs: Vec<Leg>,
    /// mm per rad: weighs rotations against translations in rank decisions.
    pub length_scale: f64,
    /// The model's gravity (m/s^2), when it gives one.
    pub gravity: Option<crate::kinematics::frame::Vec3>,
}

/// Warm starts of every leg, carried from one point to the next by one worker.
#[derive(Clone, Debug)]
pub struct ManipulatorState {
    /// One per leg.
    pub legs: Vec<LegState>,
}

/// The sum over legs at one pose.
#[derive(Clone, Copy, Debug)]
pub struct Aggregate {
    /// Sum of the legs' wrenches at the reference point.
    pub wrench: Vec6,
    /// Sum of their stiffnesses.
    pub stiffness: Mat6,
    /// The size of the legs' terms on each diagonal entry (the sum of their `LegResponse::magnitude`), so
    /// that a diagonal entry that cancelled to round-off can be told from a genuinely small one
    /// (`compliance::analyse`).
    pub magnitude: Vec6,
}

/// Which leg failed, and how.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseFailure {
    /// The leg, 0-based.
    pub leg: usize,
    /// How it failed.
    pub failure: LegFailure,
}

impl std::fmt::Display for PoseFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "leg {}: {}", self.leg + 1, self.failure)
    }
}

impl std::error::Error for PoseFailure {}

/// The springs a compliance scaling acts on.
#[derive(Clone, Copy, Debug)]
pub enum SpringSet<'a> {
    /// The actuator springs of one leg (0-based).
    ActuatorOf(usize),
    /// Every spring group of this name, in every leg.
    Group(&'a str),
}

impl Manipulator {
    /// Multiplies the compliance of a set of springs by `factor` (a model correction such as a softer
    /// actuator). Posture-dependent springs carry the factor into their derivation, so it acts at every pose.
    pub fn scale_compliance(&mut self, set: &SpringSet, factor: f64) {
        for (k, leg) in self.legs.iter_mut().enumerate() {
            match set {
                SpringSet::ActuatorOf(target) if *target == k => leg.scale_springs(|_, actuator| actuator, factor),
                SpringSet::Group(name) => leg.scale_springs(|group, _| group == *name, factor),
                SpringSet::ActuatorOf(_) => {}
            }
        }
    }

    /// Whether some leg has a spring group of this name.
    pub fn has_spring_group(&self, name: &str) -> bool {
        self.legs.iter().any(|l| l.spring_groups().any(|(group, _)| group == name))
    }

    /// The names of the link (not actuator) spring groups, each once, in order of first appearance.
    pub fn link_spring_groups(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for (name, actuator) in self.legs.iter().flat_map(Leg::spring_groups) {
            if !actuator && !out.iter().any(|n| n == name) {
                out.push(name.to_string());
            }
        }
        out
    }

    /// A fresh state (no warm starts).
    pub fn new_state(&self) -> ManipulatorState {
        ManipulatorState { legs: self.legs.iter().map(Leg::new_state).collect() }
    }

    /// Places every leg for the commanded pose (inverse kinematics).
    pub fn place(&self, platform: &Frame, state: &mut ManipulatorState) -> Result<(), PoseFailure> {
        for (i, (leg, s)) in self.legs.iter().zip(state.legs.iter_mut()).enumerate() {
            leg.place(platform, s).map_err(|failure| PoseFailure { leg: i, failure })?;
        }
        Ok(())
    }

    /// Unloaded stiffness at a commanded pose: K = sum_i K_i at the reference point.
    pub fn unloaded(&self, platform: &Frame, state: &mut ManipulatorState) -> Result<Aggregate, PoseFailure> {
        self.unloaded_each(platform, state, |_, _| {})
    }

    /// As `unloaded`, also handing each leg's own answer to `each(leg_index, response)`.
    pub fn unloaded_each(
        &self,
        platform: &Frame,
        state: &mut ManipulatorState,
        mut each: impl FnMut(usize, &LegResponse),
    ) -> Result<Aggregate, PoseFailure> {
        self.place(platform, state)?;
        let mut total = Aggregate { wrench: Vec6::zeros(), stiffness: Mat6::zeros(), magnitude: Vec6::zeros() };
        for (i, (leg, s)) in self.legs.iter().zip(state.legs.iter_mut()).enumerate() {
            let r = leg.respond_unloaded(platform, s).map_err(|failure| PoseFailure { leg: i, failure })?;
            total.wrench += r.wrench;
            total.stiffness += r.stiffness;
            total.magnitude += r.magnitude;
            each(i, &r);
        }
        Ok(total)
    }
}
