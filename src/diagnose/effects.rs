//! The library of physical effects a measurement may show that the nominal model lacks, each a
//! parameterised change of the description (named as on the command line: `NAME[:TARGET]=V1,V2,...`), and
//! the prediction of the reference point's displacement under a wrench with effects applied.
//!
//! Spring scalings (actuator-compliance, link-compliance) change the legs' springs, so every study sees
//! them; the others are terms of the measurement model, evaluated from the real model's compliance C, the
//! legs' stiffnesses K_i and their actuator twists a_i at each pose (paper 000 eq 60 for end-point errors):
//! gravity C (m g); leg-geometry C K_i eps_i; preload C K_i a_i theta0; backlash C K_i a_i b sign(a_i . F_i)
//! with F_i = K_i C w the leg's load; tool-offset r + dp + dphi x r; loaded-nonlinearity lambda (loaded - linear).

use std::fmt;

use crate::kinematics::frame::{Frame, Mat6, Vec3, Vec6};
use crate::platform::compliance::analyse;
use crate::platform::leg::Leg;
use crate::platform::manipulator::{Manipulator, ManipulatorState};

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Kind {
    ActuatorCompliance,
    LinkCompliance,
    Gravity,
    LegGeometry,
    Preload,
    LoadedNonlinearity,
    Backlash,
    ToolOffset,
}

pub const KINDS: [Kind; 8] = [
    Kind::ActuatorCompliance,
    Kind::LinkCompliance,
    Kind::Gravity,
    Kind::LegGeometry,
    Kind::Preload,
    Kind::LoadedNonlinearity,
    Kind::Backlash,
    Kind::ToolOffset,
];

impl Kind {
    pub fn name(self) -> &'static str {
        match self {
            Kind::ActuatorCompliance => "actuator-compliance",
            Kind::LinkCompliance => "link-compliance",
            Kind::Gravity => "gravity",
            Kind::LegGeometry => "leg-geometry",
            Kind::Preload => "preload",
            Kind::LoadedNonlinearity => "loaded-nonlinearity",
            Kind::Backlash => "backlash",
            Kind::ToolOffset => "tool-offset",
        }
    }

    pub fn parse(name: &str) -> Option<Kind> {
        KINDS.iter().copied().find(|k| k.name() == name)
    }

    /// Number of values, and what they mean (for messages and reports).
    pub fn values(self) -> (usize, &'static str) {
        match self {
            Kind::ActuatorCompliance => (1, "compliance factor of the leg's actuator spring (1 = nominal)"),
            Kind::LinkCompliance => (1, "compliance factor of the spring group (1 = nominal)"),
            Kind::Gravity => (1, "mass carried at the reference point, kg, under the model's gravity"),
            Kind::LegGeometry => (6, "the leg's end-point error eps: dx, dy, dz (mm), rx, ry, rz (rad)"),
            Kind::Preload => (1, "preload theta0 of the leg's actuator spring, mm"),
            Kind::LoadedNonlinearity => (1, "share of the loaded (large-deflection) response, 1 = all"),
            Kind::Backlash => (1, "half clearance of the leg's actuator, mm"),
            Kind::ToolOffset => (3, "offset of the measured point from the reference point, mm"),
        }
    }

    /// What a target names: a leg (1-based), a spring group, or nothing.
    pub fn target(self) -> TargetKind {
        match self {
            Kind::ActuatorCompliance | Kind::LegGeometry | Kind::Preload | Kind::Backlash => TargetKind::Leg,
            Kind::LinkCompliance => TargetKind::Group,
            _ => TargetKind::None,
        }
    }

    /// The parameter values of the nominal model (no effect).
    pub fn neutral(self) -> f64 {
        match self {
            Kind::ActuatorCompliance | Kind::LinkCompliance => 1.0,
            _ => 0.0,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TargetKind {
    Leg,
    Group,
    None,
}

#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Target {
    None,
    /// A leg, 0-based (written 1-based).
    Leg(usize),
    /// A spring group by name, in every leg.
    Group(String),
}

impl fmt::Display for Target {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        match self {
            Target::None => Ok(()),
            Target::Leg(k) => write!(f, "{}", k + 1),
            Target::Group(g) => f.write_str(g),
        }
    }
}

/// One effect with its values.
#[derive(Clone, Debug, PartialEq)]
pub struct Effect {
    pub kind: Kind,
    pub target: Target,
    pub values: Vec<f64>,
}

impl fmt::Display for Effect {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str(self.kind.name())?;
        if self.target != Target::None {
            write!(f, ":{}", self.target)?;
        }
        f.write_str("=")?;
        let v: Vec<String> = self.values.iter().map(|v| format!("{v}")).collect();
        f.write_str(&v.join(","))
    }
}

impl Effect {
    /// Checks and builds an effect for manipulator `m` (targets resolved, value count checked).
    pub fn new(kind: Kind, target: Option<&str>, values: Vec<f64>, m: &Manipulator) -> Result<Effect, String> {
        let (n, meaning) = kind.values();
        if values.len() != n || !values.iter().all(|v| v.is_finite()) {
            return Err(format!("`{}` takes {n} finite value(s): {meaning}", kind.name()));
        }
        let target = match (kind.target(), target) {
            (TargetKind::None, None) => Target::None,
            (TargetKind::None, Some(t)) => return Err(format!("`{}` takes no target (got `{t}`)", kind.name())),
            (_, None) => return Err(format!("`{}` needs a target: `{}:TARGET=...`", kind.name(), kind.name())),
            (TargetKind::Leg, Some(t)) => {
                let k: usize = t.parse().map_err(|_| format!("`{}`: target `{t}` is not a leg number", kind.name()))?;
                if k == 0 || k > m.legs.len() {
                    return Err(format!("`{}`: leg {k} does not exist (legs 1 to {})", kind.name(), m.legs.len()));
                }
                if !matches!(m.legs[k - 1], Leg::Vjm(_)) && kind != Kind::LegGeometry {
                    return Err(format!("`{}` needs a VJM leg (leg {k} is MSA)", kind.name()));
                }
                Target::Leg(k - 1)
            }
            (TargetKind::Group, Some(g)) => {
                let known = m.legs.iter().any(|l| matches!(l, Leg::Vjm(v) if v.springs.iter().any(|s| s.name == g)));
                if !known {
                    return Err(format!("`{}`: no spring group named `{g}`", kind.name()));
                }
                Target::Group(g.to_string())
            }
        };
        if matches!(kind, Kind::ActuatorCompliance | Kind::LinkCompliance) && !(values[0] > 0.0) {
            return Err(format!("`{}`: a compliance factor must be positive", kind.name()));
        }
        Ok(Effect { kind, target, values })
    }

    /// Parses `NAME[:TARGET]=V1,V2,...`.
    pub fn parse(text: &str, m: &Manipulator) -> Result<Effect, String> {
        let (head, values) = text.split_once('=').ok_or_else(|| format!("`{text}`: expected NAME[:TARGET]=V1,..."))?;
        let (name, target) = match head.split_once(':') {
            Some((n, t)) => (n, Some(t)),
            None => (head, None),
        };
        let kind = Kind::parse(name.trim()).ok_or_else(|| {
            let names: Vec<&str> = KINDS.iter().map(|k| k.name()).collect();
            format!("unknown effect `{name}` (known: {})", names.join(", "))
        })?;
        let values = values
            .split(',')
            .map(|v| v.trim().parse::<f64>().map_err(|_| format!("`{text}`: `{v}` is not a number")))
            .collect::<Result<Vec<_>, _>>()?;
        Effect::new(kind, target.map(str::trim), values, m)
    }

    pub fn scales_springs(&self) -> bool {
        matches!(self.kind, Kind::ActuatorCompliance | Kind::LinkCompliance)
    }
}

/// The manipulator with the spring scalings of `effects` applied (compliance times the factor).
pub fn scaled(m: &Manipulator, effects: &[Effect]) -> Manipulator {
    let mut out = m.clone();
    for e in effects.iter().filter(|e| e.scales_springs()) {
        for (k, leg) in out.legs.iter_mut().enumerate() {
            let Leg::Vjm(v) = leg else { continue };
            for s in v.springs.iter_mut() {
                let hit = match (&e.kind, &e.target) {
                    (Kind::ActuatorCompliance, Target::Leg(t)) => *t == k && s.actuator,
                    (Kind::LinkCompliance, Target::Group(g)) => &s.name == g,
                    _ => false,
                };
                if hit {
                    s.scale_compliance(e.values[0]);
                }
            }
        }
    }
    out
}

/// What the model says at one pose: compliance, the legs' stiffnesses at the reference point and each
/// leg's first actuator twist (zero for a leg without one).
#[derive(Clone, Debug)]
pub struct PoseModel {
    pub compliance: Mat6,
    pub legs: Vec<Mat6>,
    pub actuators: Vec<Vec6>,
}

impl PoseModel {
    pub fn at(m: &Manipulator, pose: &Frame, state: &mut ManipulatorState) -> Result<PoseModel, String> {
        let mut legs = Vec::with_capacity(m.legs.len());
        let total =
            m.unloaded_each(pose, state, |_, r| legs.push(r.stiffness)).map_err(|e| format!("it fails there ({e})"))?;
        let Some(&compliance) = analyse(&total.stiffness, &total.magnitude, m.length_scale, true).compliance() else {
            return Err("the manipulator is singular or ill-conditioned there".into());
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
