//! The `[[effect]]` entries of a description, and `--effect NAME[:TARGET]=V1,V2,...` on the command line:
//! physical effects a measurement may show that the nominal model lacks (found by `stiff diagnose`, injected
//! by `stiff synth`). Effects with a model form (`Form::Model`: spring scalings, a payload, an actuator
//! offset) are built into the manipulator, so every study sees them (`with_model_effects`); the others are
//! terms of the measurement model that `diagnose` and `synth` evaluate (`diagnose::measurement`).

use std::fmt;

use crate::kinematics::frame::Vec3;
use crate::platform::manipulator::{Manipulator, Payload, SpringSet};

/// An effect of the library.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Kind {
    /// A leg's actuator spring softer or stiffer (compliance factor).
    ActuatorCompliance,
    /// A spring group softer or stiffer (compliance factor).
    LinkCompliance,
    /// The axial and the bending (with torsion) compliance of a group's beam springs, two factors.
    LinkSections,
    /// A mass carried at the reference point under the model's gravity.
    Gravity,
    /// A mass carried by the platform with its centre of mass away from the reference point.
    GravityOffset,
    /// A leg's end-point error (six values).
    LegGeometry,
    /// An actuator further along its axis than commanded (an encoder zero offset). In a VJM leg the
    /// actuator spring sits in series on the actuator's axis (paper 001 eq 1, V_a(q + theta)), so a preload
    /// theta0 of that spring is exactly this offset: `preload` is read as its other name.
    ActuatorOffset,
    /// A share of the loaded (large-deflection) response.
    LoadedNonlinearity,
    /// A clearance of a leg's actuator, taken up by the sign of its load.
    Backlash,
    /// The measured point offset from the reference point.
    ToolOffset,
    /// The measuring instrument's frame rotated against the robot's base frame (registration error).
    FrameRotation,
    /// A compliance in series at the tool (tool holder, platform): translation per unit force.
    ToolCompliance,
    /// A drift of the measurements over their order (thermal growth, instrument drift).
    Drift,
}

/// Every kind, in the order candidates are listed.
pub const KINDS: [Kind; 13] = [
    Kind::ActuatorCompliance,
    Kind::LinkCompliance,
    Kind::LinkSections,
    Kind::Gravity,
    Kind::GravityOffset,
    Kind::LegGeometry,
    Kind::ActuatorOffset,
    Kind::LoadedNonlinearity,
    Kind::Backlash,
    Kind::ToolOffset,
    Kind::FrameRotation,
    Kind::ToolCompliance,
    Kind::Drift,
];

/// How an effect reaches the studies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Form {
    /// A change of the robot's model that every study sees (a spring scaled, a payload, an actuator offset).
    Model,
    /// A term of the measurement only (how the instrument or the data differ from the robot): diagnose and
    /// synth use it, map, curve and assemble have nothing to change.
    Measurement,
}

impl Kind {
    /// The name on the command line and in `[[effect]]`.
    pub fn name(self) -> &'static str {
        match self {
            Kind::ActuatorCompliance => "actuator-compliance",
            Kind::LinkCompliance => "link-compliance",
            Kind::LinkSections => "link-sections",
            Kind::Gravity => "gravity",
            Kind::GravityOffset => "gravity-offset",
            Kind::LegGeometry => "leg-geometry",
            Kind::ActuatorOffset => "actuator-offset",
            Kind::LoadedNonlinearity => "loaded-nonlinearity",
            Kind::Backlash => "backlash",
            Kind::ToolOffset => "tool-offset",
            Kind::FrameRotation => "frame-rotation",
            Kind::ToolCompliance => "tool-compliance",
            Kind::Drift => "drift",
        }
    }

    /// The kind of this name (`preload` is the actuator offset's other name, see `Kind::ActuatorOffset`).
    pub fn parse(name: &str) -> Option<Kind> {
        if name == "preload" {
            return Some(Kind::ActuatorOffset);
        }
        KINDS.iter().copied().find(|k| k.name() == name)
    }

    /// Number of values, and what they mean (for messages and reports).
    pub fn values(self) -> (usize, &'static str) {
        match self {
            Kind::ActuatorCompliance => (1, "compliance factor of the leg's actuator spring (1 = nominal)"),
            Kind::LinkCompliance => (1, "compliance factor of the spring group (1 = nominal)"),
            Kind::LinkSections => (
                2,
                "axial, and bending with torsion, compliance factors of the group's beams (1 = nominal; a diameter \
                 times s gives s^-2 and s^-4)",
            ),
            Kind::Gravity => (1, "mass carried at the reference point, kg, under the model's gravity"),
            Kind::GravityOffset => {
                (4, "mass carried by the platform, kg, and its centre of mass in the platform frame, mm (x, y, z)")
            }
            Kind::LegGeometry => (6, "the leg's end-point error eps: dx, dy, dz (mm), rx, ry, rz (rad)"),
            Kind::ActuatorOffset => {
                (1, "where the leg's actuator sits minus where it is commanded, mm (prismatic) or rad (revolute)")
            }
            Kind::LoadedNonlinearity => (1, "share of the loaded (large-deflection) response, 1 = all"),
            Kind::Backlash => (1, "half clearance of the leg's actuator, mm"),
            Kind::ToolOffset => (3, "offset of the measured point from the reference point, mm"),
            Kind::FrameRotation => (3, "rotation vector of the instrument's frame against the base frame, rad"),
            Kind::ToolCompliance => (1, "series compliance at the tool, mm/N (translation per unit force)"),
            Kind::Drift => (3, "drift of the measured point per unit of the data's `order` column, mm (x, y, z)"),
        }
    }

    /// What a target names: a leg (1-based), a spring group, or nothing.
    pub fn target(self) -> TargetKind {
        match self {
            Kind::ActuatorCompliance | Kind::LegGeometry | Kind::ActuatorOffset | Kind::Backlash => TargetKind::Leg,
            Kind::LinkCompliance | Kind::LinkSections => TargetKind::Group,
            _ => TargetKind::None,
        }
    }

    /// Spring scalings change the legs' compliance; the other kinds add to the displacement.
    pub fn scales_springs(self) -> bool {
        matches!(self, Kind::ActuatorCompliance | Kind::LinkCompliance | Kind::LinkSections)
    }

    /// Whether the effect is a change of the robot (written into the model) or of the measurement.
    pub fn form(self) -> Form {
        match self {
            Kind::ActuatorCompliance
            | Kind::LinkCompliance
            | Kind::LinkSections
            | Kind::Gravity
            | Kind::GravityOffset
            | Kind::ActuatorOffset => Form::Model,
            _ => Form::Measurement,
        }
    }

    /// Effects that act through a leg's actuator spring (its compliance, its rest length, its clearance).
    pub fn needs_actuator_spring(self) -> bool {
        matches!(self, Kind::ActuatorCompliance | Kind::ActuatorOffset | Kind::Backlash)
    }

    /// The parameter values of the nominal model (no effect).
    pub fn neutral(self) -> f64 {
        match self {
            Kind::ActuatorCompliance | Kind::LinkCompliance | Kind::LinkSections => 1.0,
            _ => 0.0,
        }
    }
}

/// What a target names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TargetKind {
    /// A leg, by number.
    Leg,
    /// A spring group, by name.
    Group,
    /// Nothing: the effect takes no target.
    None,
}

/// The target of an effect.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Target {
    /// No target.
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
    /// What kind of effect.
    pub kind: Kind,
    /// What it acts on.
    pub target: Target,
    /// Its values (`Kind::values` gives their meaning; gravity-offset is stored as (m, m c), see
    /// `Effect::user_values`).
    pub values: Vec<f64>,
}

impl fmt::Display for Effect {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str(self.kind.name())?;
        if self.target != Target::None {
            write!(f, ":{}", self.target)?;
        }
        f.write_str("=")?;
        let v: Vec<String> = self.user_values().iter().map(|v| format!("{v}")).collect();
        f.write_str(&v.join(","))
    }
}

/// Below this mass (kg) a gravity-offset effect has no centre to speak of (its first moment is reported
/// as a centre of zero).
const NO_MASS_KG: f64 = 1e-12;

impl Effect {
    /// The values as a user writes them (`Kind::values`). Stored values are the same except for
    /// gravity-offset, kept as (m, m c): the first moment m c is linear in what a measurement sees (c x m g),
    /// and has a signature where m = 0, so a fit can start from no effect.
    pub fn user_values(&self) -> Vec<f64> {
        match self.kind {
            Kind::GravityOffset => {
                let m = self.values[0];
                let c = |k: usize| if m.abs() > NO_MASS_KG { self.values[k] / m } else { 0.0 };
                vec![m, c(1), c(2), c(3)]
            }
            _ => self.values.clone(),
        }
    }
}

/// Why an effect cannot be built for a manipulator.
#[derive(Clone, Debug, PartialEq)]
pub enum EffectError {
    /// `NAME[:TARGET]=V1,...` did not have that shape.
    Syntax(String),
    /// No effect of that name.
    UnknownKind(String),
    /// A value is not a number.
    NotANumber {
        /// The whole effect as written.
        text: String,
        /// The value that is not a number.
        value: String,
    },
    /// Wrong number of values, or a non-finite one.
    Values {
        /// The effect.
        kind: Kind,
    },
    /// A target given to an effect that takes none.
    UnexpectedTarget {
        /// The effect.
        kind: Kind,
        /// The target given.
        target: String,
    },
    /// No target given to an effect that needs one.
    MissingTarget {
        /// The effect.
        kind: Kind,
    },
    /// The target is not a leg number, or no such leg.
    NoLeg {
        /// The effect.
        kind: Kind,
        /// The target given.
        target: String,
        /// The number of legs.
        legs: usize,
    },
    /// The leg has no actuator spring (an MSA leg, or a chain without `actuator = true`).
    NoActuatorSpring {
        /// The effect.
        kind: Kind,
        /// The leg, 0-based.
        leg: usize,
    },
    /// No spring group of that name.
    NoGroup {
        /// The effect.
        kind: Kind,
        /// The group named.
        group: String,
    },
    /// A compliance factor that is zero or negative.
    NotPositive {
        /// The effect.
        kind: Kind,
    },
}

impl fmt::Display for EffectError {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        match self {
            EffectError::Syntax(text) => write!(f, "`{text}`: expected NAME[:TARGET]=V1,..."),
            EffectError::UnknownKind(name) => {
                let names: Vec<&str> = KINDS.iter().map(|k| k.name()).collect();
                write!(f, "unknown effect `{name}` (known: {})", names.join(", "))
            }
            EffectError::NotANumber { text, value } => write!(f, "`{text}`: `{value}` is not a number"),
            EffectError::Values { kind } => {
                let (n, meaning) = kind.values();
                write!(f, "`{}` takes {n} finite value(s): {meaning}", kind.name())
            }
            EffectError::UnexpectedTarget { kind, target } => {
                write!(f, "`{}` takes no target (got `{target}`)", kind.name())
            }
            EffectError::MissingTarget { kind } => {
                write!(f, "`{}` needs a target: `{}:TARGET=...`", kind.name(), kind.name())
            }
            EffectError::NoLeg { kind, target, legs } => {
                write!(f, "`{}`: target `{target}` is not a leg (legs 1 to {legs})", kind.name())
            }
            EffectError::NoActuatorSpring { kind, leg } => write!(
                f,
                "`{}` needs a leg with an actuator spring; leg {} has none (an MSA leg, or a chain without \
                 `actuator = true`)",
                kind.name(),
                leg + 1
            ),
            EffectError::NoGroup { kind, group } => write!(f, "`{}`: no spring group named `{group}`", kind.name()),
            EffectError::NotPositive { kind } => write!(f, "`{}`: a compliance factor must be positive", kind.name()),
        }
    }
}

impl std::error::Error for EffectError {}

impl Effect {
    /// Checks and builds an effect for manipulator `m` (targets resolved, value count checked).
    pub fn new(kind: Kind, target: Option<&str>, values: Vec<f64>, m: &Manipulator) -> Result<Effect, EffectError> {
        let (n, _) = kind.values();
        if values.len() != n || !values.iter().all(|v| v.is_finite()) {
            return Err(EffectError::Values { kind });
        }
        let target = match (kind.target(), target) {
            (TargetKind::None, None) => Target::None,
            (TargetKind::None, Some(t)) => return Err(EffectError::UnexpectedTarget { kind, target: t.into() }),
            (_, None) => return Err(EffectError::MissingTarget { kind }),
            (TargetKind::Leg, Some(t)) => {
                let legs = m.legs.len();
                let k = t.parse::<usize>().ok().filter(|k| (1..=legs).contains(k));
                let Some(k) = k else { return Err(EffectError::NoLeg { kind, target: t.into(), legs }) };
                if kind.needs_actuator_spring() && !m.legs[k - 1].has_actuator_spring() {
                    return Err(EffectError::NoActuatorSpring { kind, leg: k - 1 });
                }
                Target::Leg(k - 1)
            }
            (TargetKind::Group, Some(g)) => {
                if !m.has_spring_group(g) {
                    return Err(EffectError::NoGroup { kind, group: g.into() });
                }
                Target::Group(g.to_string())
            }
        };
        if kind.scales_springs() && values.iter().any(|v| *v <= 0.0) {
            return Err(EffectError::NotPositive { kind });
        }
        let values = match kind {
            Kind::GravityOffset => vec![values[0], values[0] * values[1], values[0] * values[2], values[0] * values[3]],
            _ => values,
        };
        Ok(Effect { kind, target, values })
    }

    /// Parses `NAME[:TARGET]=V1,V2,...`.
    pub fn parse(text: &str, m: &Manipulator) -> Result<Effect, EffectError> {
        let (head, values) = text.split_once('=').ok_or_else(|| EffectError::Syntax(text.into()))?;
        let (name, target) = match head.split_once(':') {
            Some((n, t)) => (n, Some(t)),
            None => (head, None),
        };
        let kind = Kind::parse(name.trim()).ok_or_else(|| EffectError::UnknownKind(name.into()))?;
        let values = values
            .split(',')
            .map(|v| {
                v.trim().parse::<f64>().map_err(|_| EffectError::NotANumber { text: text.into(), value: v.into() })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Effect::new(kind, target.map(str::trim), values, m)
    }

    /// Whether the effect scales springs (applied to the legs) rather than adding a measurement term.
    pub fn scales_springs(&self) -> bool {
        self.kind.scales_springs()
    }
}

/// The manipulator with the model-form effects of `effects` built in (`Form::Model`): compliance times
/// the factor, a payload (gravity, gravity-offset), an actuator offset (the actuator spring's rest value
/// moved, `Leg::offset_actuator`). Measurement terms are left to diagnose and synth.
pub fn with_model_effects(m: &Manipulator, effects: &[Effect]) -> Manipulator {
    let mut out = m.clone();
    for e in effects {
        match (&e.kind, &e.target) {
            (Kind::ActuatorCompliance, Target::Leg(k)) => out.scale_compliance(&SpringSet::ActuatorOf(*k), e.values[0]),
            (Kind::LinkCompliance, Target::Group(g)) => out.scale_compliance(&SpringSet::Group(g), e.values[0]),
            (Kind::LinkSections, Target::Group(g)) => out.scale_beam_parts(g, e.values[0], e.values[1]),
            (Kind::Gravity, _) => out.add_payload(Payload { mass_kg: e.values[0], centre: Vec3::zeros() }),
            (Kind::GravityOffset, _) => {
                let v = e.user_values();
                out.add_payload(Payload { mass_kg: v[0], centre: Vec3::new(v[1], v[2], v[3]) })
            }
            (Kind::ActuatorOffset, Target::Leg(k)) => out.legs[*k].offset_actuator(e.values[0]),
            _ => {}
        }
    }
    out
}

/// The manipulator with only the spring scalings of `effects` applied: what changes its compliance C, the
/// rest being terms the measurement model adds to the displacement (`diagnose::measurement`).
pub fn scaled(m: &Manipulator, effects: &[Effect]) -> Manipulator {
    let scalings: Vec<Effect> = effects.iter().filter(|e| e.scales_springs()).cloned().collect();
    with_model_effects(m, &scalings)
}
