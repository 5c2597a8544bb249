//! The effects a calibration can name (`ArmKind`, `ArmEffect`: what each is and how it is written on the
//! command line), and how far a unit of each turns its joint in a row (`effect_gain`, from the joint's
//! load). Where each effect moves what a row measures is `predict.rs`; where one is chosen, `select.rs`.

use crate::kinematics::frame::{Vec3, Vec6};
use crate::platform::manipulator::ArmStatics;

/// What kind of effect a candidate is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ArmKind {
    /// An encoder's zero offset.
    JointOffset,
    /// A compliance about the joint's axis.
    JointCompliance,
    /// Play following the sign of the joint's load.
    Backlash,
    /// A change of the fixed transform leading to the joint (3 translations, 3 rotations in the joint's
    /// frame before its motion), fitted in the directions the data can see.
    JointGeometry,
    /// A mass carried at the tool (its mass and first moment in the tool frame), seen through the model's
    /// compliance.
    Payload,
    /// A compliance where the model is rigid, at the frame leading to the joint (a link, a column or a
    /// mounting bends there): 3 translational and 3 rotational compliances along the frame's axes, under the
    /// wrench everything beyond it puts through it.
    FrameCompliance,
    /// The measurements drifting over their order (thermal growth of the robot or the instrument, the
    /// instrument settling): the target seen moved by a constant rate per row of the file, base frame axes.
    Drift,
    /// A compliance in series at the tool (a tool holder, a flange): the target moved along each of the tool
    /// frame's axes by a compliance times the force the tool carries there (the row's wrench, a payload).
    ToolCompliance,
}

/// A candidate effect on one joint.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ArmEffect {
    /// Its kind.
    pub kind: ArmKind,
    /// The joint (index in the arm's joint space).
    pub joint: usize,
}

impl ArmKind {
    /// Its name on the command line and in the calibration's JSON.
    pub fn name(self) -> &'static str {
        match self {
            ArmKind::JointOffset => "joint-offset",
            ArmKind::JointCompliance => "joint-compliance",
            ArmKind::Backlash => "backlash",
            ArmKind::JointGeometry => "joint-geometry",
            ArmKind::FrameCompliance => "frame-compliance",
            ArmKind::Payload => "payload",
            ArmKind::Drift => "drift",
            ArmKind::ToolCompliance => "tool-compliance",
        }
    }
}

impl ArmEffect {
    /// Its name as given on the command line (`joint-offset:J2`, `payload`).
    pub fn label(&self, joints: &[String]) -> String {
        match self.kind {
            ArmKind::Payload | ArmKind::Drift | ArmKind::ToolCompliance => self.kind.name().into(),
            kind => format!("{}:{}", kind.name(), joints[self.joint]),
        }
    }

    /// How many parameters it has.
    pub fn size(&self) -> usize {
        match self.kind {
            ArmKind::JointOffset | ArmKind::JointCompliance | ArmKind::Backlash => 1,
            ArmKind::JointGeometry | ArmKind::FrameCompliance => 6,
            ArmKind::Payload => 4,
            ArmKind::Drift | ArmKind::ToolCompliance => 3,
        }
    }

    /// Reads `KIND:JOINT` or `payload`.
    pub fn parse(text: &str, joints: &[String]) -> Result<ArmEffect, String> {
        if text == "payload" {
            return Ok(ArmEffect { kind: ArmKind::Payload, joint: 0 });
        }
        if text == "drift" {
            return Ok(ArmEffect { kind: ArmKind::Drift, joint: 0 });
        }
        if text == "tool-compliance" {
            return Ok(ArmEffect { kind: ArmKind::ToolCompliance, joint: 0 });
        }
        let (kind, joint) = text.split_once(':').ok_or_else(|| format!("`{text}`: give KIND:JOINT or payload"))?;
        let kind = match kind {
            "joint-offset" => ArmKind::JointOffset,
            "joint-compliance" => ArmKind::JointCompliance,
            "backlash" => ArmKind::Backlash,
            "joint-geometry" => ArmKind::JointGeometry,
            "frame-compliance" => ArmKind::FrameCompliance,
            other => {
                return Err(format!(
                    "`{other}`: the effects of a serial arm are joint-offset, joint-compliance, backlash, joint-geometry, frame-compliance (KIND:JOINT), payload, tool-compliance and drift"
                ))
            }
        };
        let joint = joints.iter().position(|j| j == joint).ok_or_else(|| {
            // A parallel robot's joints are its legs' actuators, named by the leg's number.
            let legs = joints.iter().all(|j| j.parse::<usize>().is_ok());
            let what = if legs { "a leg of the robot (its legs by number: " } else { "a joint of the arm (" };
            format!("`{joint}` is not {what}{})", joints.join(", "))
        })?;
        Ok(ArmEffect { kind, joint })
    }
}

/// A joint's load as the effects read it: zero where it is round-off (`ArmStatics::load`, the rule the
/// model's play follows).
pub(super) fn load_of(s: &ArmStatics, joint: usize) -> f64 {
    s.load(joint)
}

/// How far a unit of effect `e` turns its joint in a row: nothing for an offset (it moves the configuration
/// instead) nor for a geometry or payload (they act otherwise, `PositionProblem::unit_moves`), the load for a
/// compliance, the load's sign for play; for a displacement row, the difference between the row's wrench and
/// zero wrench (`zero`). `payload` is the weight of a payload being fitted, at the reference point: the
/// joints carry it too.
pub(super) fn effect_gain(e: &ArmEffect, s: &ArmStatics, zero: &Option<ArmStatics>, payload: &Vec6) -> f64 {
    let sign = |l: f64| if l == 0.0 { 0.0 } else { l.signum() };
    let carried = s.columns[e.joint].dot(payload);
    let load = load_of(s, e.joint) + carried;
    let zero_load = zero.as_ref().map(|z| load_of(z, e.joint) + carried);
    match (e.kind, zero_load) {
        (
            ArmKind::JointOffset
            | ArmKind::JointGeometry
            | ArmKind::Payload
            | ArmKind::FrameCompliance
            | ArmKind::Drift
            | ArmKind::ToolCompliance,
            _,
        ) => 0.0,
        (ArmKind::JointCompliance, None) => load,
        (ArmKind::JointCompliance, Some(z)) => load - z,
        (ArmKind::Backlash, None) => sign(load),
        (ArmKind::Backlash, Some(z)) => sign(load) - sign(z),
    }
}

/// What a row sees of a small motion of the tool: a target's point (its lever from the reference point, base
/// axes) or, for an orientation, the tool's turn.
#[derive(Clone, Copy, Debug)]
pub(super) enum Seen {
    Point(Vec3),
    Turn,
}

impl Seen {
    /// What a twist of the tool at the reference point (translation, rotation) moves: the point by
    /// v + w x lever, the orientation by w.
    pub(super) fn of(&self, twist: &Vec6) -> Vec3 {
        let rotation = twist.fixed_rows::<3>(3).into_owned();
        match self {
            Seen::Point(lever) => twist.fixed_rows::<3>(0) + rotation.cross(lever),
            Seen::Turn => rotation,
        }
    }

    /// The twist at the reference point `p` of a rigid motion turning by `w` about the point `o` and moving
    /// by `v`, as `of` reads it.
    pub(super) fn rigid(&self, v: Vec3, w: Vec3, o: &Vec3, p: &Vec3) -> Vec3 {
        let t = v + w.cross(&(p - o));
        self.of(&Vec6::new(t.x, t.y, t.z, w.x, w.y, w.z))
    }
}
