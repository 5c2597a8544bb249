//! Calibration of a serial arm against what a lab measures (`positions.rs`): where a target on the tool was,
//! in an instrument's frame, at configurations given by the controller's joint coordinates, under the arm's
//! own weight and the rows' wrenches; or the tool point's displacement under a wrench. A parallel robot's
//! legs are calibrated by the same routine from positions at commanded poses, its legs' actuators read as
//! the joints (`platform_statics`), its first order completed by its exact loaded equilibrium
//! (`Problem::exact_misses`).
//!
//! The set-up is fitted, not blamed: each instrument set-up's frame (a rotation and a translation) and each
//! target's place on the tool are nuisance parameters of every fit. The effects a serial arm can miss are
//! then offered one at a time and kept where the data need them (forward selection by F-tests at
//! alpha / candidates, as the other diagnosis does with its tests):
//! - `joint-offset:J`: the encoder's zero, added to the controller's angle (absolute data only: a
//!   displacement does not see it);
//! - `joint-compliance:J`: a compliance about (along) the joint's axis added to the model's, the joint
//!   turning by it times the load it carries (the links' weight, the payload, the wrench);
//! - `backlash:J`: play that follows the sign of the joint's load, the joint turning by b sign(load).
//!
//! Compliance and backlash act at first order about the model's own loaded equilibrium (the deflections of
//! robots are a thousandth of their reach, so the second order is a millionth). A direction the data cannot
//! see (a vertical first axis makes the base's yaw and joint 1's offset one parameter) is found from the
//! rank of the fit's Jacobian and reported, never fitted. Gross rows (a misfit no plausible model gives,
//! against a median-based scale) are named and left out. Rows marked `check` are never fitted; the report
//! gives the position error of fit and check rows after the registration alone and after each effect.

use nalgebra::{DMatrix, DVector};
use statrs::distribution::{ChiSquared, ContinuousCDF, FisherSnedecor};

use super::positions::{Observed, PositionData, PositionRow};
use crate::kinematics::frame::{rotation_from_vector, skew, Frame, Mat3, Mat6, Vec3, Vec6};
use crate::model::effect::{Effect, Kind, Target};
use crate::platform::manipulator::{ArmStatics, Manipulator, ManipulatorState};

/// Relative singular value of the column-scaled Jacobian below which a direction is not identifiable: a
/// combination of parameters that moves the points by less than a millionth of what each does alone would
/// amplify the noise a millionfold.
const IDENTIFIABLE: f64 = 1e-6;
/// A row whose misfit exceeds this many robust standard deviations (per coordinate) is gross.
const GROSS_FACTOR: f64 = 12.0;
/// The median length of a 3-vector of unit-variance normal coordinates (the chi distribution's, 3 dof).
const CHI3_MEDIAN: f64 = 1.5382;
/// Rows each way of a joint's load that its play needs to be offered (`two_sided_play`).
const MIN_PLAY_ROWS: usize = 3;
/// How much lower the BIC of a model with an effect must be than without it for the effect to be accepted
/// (strong evidence on Kass and Raftery's scale; the other diagnosis asks the same).
const STRONG_EVIDENCE: f64 = 10.0;
/// Most refits of a parallel robot's first order completed by its exact misses (`Problem::fit_exact`).
const EXACT_PASSES: usize = 8;
/// A joint load below this fraction of the row's largest is round-off (`load_of`).
const LOAD_ROUND_OFF: f64 = 1e-9;

/// What kind of effect a candidate is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
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

impl ArmEffect {
    /// Its name as given on the command line (`joint-offset:J2`, `payload`).
    pub fn label(&self, joints: &[String]) -> String {
        let kind = match self.kind {
            ArmKind::JointOffset => "joint-offset",
            ArmKind::JointCompliance => "joint-compliance",
            ArmKind::Backlash => "backlash",
            ArmKind::JointGeometry => "joint-geometry",
            ArmKind::FrameCompliance => "frame-compliance",
            ArmKind::Payload => return "payload".into(),
            ArmKind::Drift => return "drift".into(),
            ArmKind::ToolCompliance => return "tool-compliance".into(),
        };
        format!("{kind}:{}", joints[self.joint])
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

/// Options of a calibration.
#[derive(Clone, Debug)]
pub struct Options {
    /// Significance level of the selection (each step tests at alpha / candidates).
    pub alpha: f64,
    /// Standard deviation of a measured coordinate, mm, where the rows do not give one.
    pub sigma: Option<f64>,
    /// Standard deviation of a measured orientation about each axis, rad, where the rows do not give one.
    pub sigma_rad: Option<f64>,
    /// Effects always fitted (a fixed list, as a geometric calibration fits its parameters).
    pub fitted: Vec<ArmEffect>,
    /// Most effects selected.
    pub max_effects: usize,
}

/// The parameters of one fit.
#[derive(Clone, Debug)]
struct Params {
    rotations: Vec<Mat3>,
    translations: Vec<Vec3>,
    targets: Vec<Vec3>,
    /// Each target's axes in the tool frame (fitted for the targets whose orientation is measured).
    turns: Vec<Mat3>,
    /// Each effect's parameters.
    effects: Vec<Vec<f64>>,
}

/// A fit: its parameters, weighted residual sum of squares, rows, rank, covariance (unscaled) and the
/// directions it could not see.
#[derive(Clone, Debug)]
struct Fit {
    params: Params,
    rss: f64,
    observations: usize,
    rank: usize,
    /// (J^T J)^+ of the weighted Jacobian, in the parameters' order.
    covariance: DMatrix<f64>,
    /// Directions of the parameters the data cannot see: (parameter index, weight) of each, in the
    /// column-scaled parameters.
    hidden: Vec<Vec<(usize, f64)>>,
}

impl Fit {
    fn dof(&self) -> usize {
        self.observations.saturating_sub(self.rank).max(1)
    }
}

/// An effect accepted, with its value and standard error.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Accepted {
    /// `joint-offset:J2` and so on.
    pub label: String,
    /// Its kind.
    pub kind: ArmKind,
    /// The joint's name.
    pub joint: String,
    /// The fitted values: rad (mm) for an offset or backlash, rad/(N mm) (mm/N) added compliance; mm and
    /// rad for a joint's geometry (translation, then rotation vector, in the joint's frame); kg and kg mm for a
    /// payload (its mass, then its first moment in the tool frame).
    pub values: Vec<f64>,
    /// Their standard errors, same units (null for a direction the data cannot see).
    pub se: Vec<f64>,
    /// The value in the unit a user reads (mrad, mm, N m/rad ...), with its standard error.
    pub shown: String,
    /// For an effect selected where rows are held out: whether adding it lowered their RMS error (an
    /// effect the fit rows need but the check rows do not confirm is named as such).
    pub confirmed: Option<bool>,
}

/// One step of the selection: each candidate's test.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Tested {
    /// The candidate.
    pub label: String,
    /// F statistic of adding it (null where not identifiable).
    pub f: Option<f64>,
    /// Its p-value.
    pub p: Option<f64>,
    /// Why it was not tested, where it was not.
    pub note: Option<String>,
}

/// Position errors of a set of rows (mm): RMS per axis, RMS, 95th percentile and maximum of the length.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct ErrorStats {
    /// Rows.
    pub rows: usize,
    /// RMS of x, y, z.
    pub rms_axis: [f64; 3],
    /// RMS of the length.
    pub rms: f64,
    /// 95th percentile of the length.
    pub p95: f64,
    /// Largest length.
    pub max: f64,
    /// Largest magnitude of x, y, z.
    pub max_axis: [f64; 3],
}

/// The errors after one stage of the model (the registration alone, then each accepted effect).
#[derive(Clone, Debug, serde::Serialize)]
pub struct Stage {
    /// `registration`, `+ joint-offset:J2` and so on.
    pub model: String,
    /// Parameters the data see (the fit's rank: an effect's directions the data cannot see do not count).
    pub parameters: usize,
    /// On the rows fitted (gross rows left out).
    pub fit: ErrorStats,
    /// On the rows held out (gross ones left out).
    pub check: ErrorStats,
    /// On every row held out, gross ones included (the figure to compare with a calibration that keeps them).
    pub check_all: ErrorStats,
    /// The orientation errors of the rows fitted and held out (mrad: the rotation vector from the measured
    /// orientation to the predicted), where orientations are measured.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orientation: Option<[ErrorStats; 2]>,
}

/// A nuisance parameter's fitted value.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Nuisance {
    /// `setup A: translation` and so on.
    pub name: String,
    /// Values (mm, or mrad for a rotation vector).
    pub value: [f64; 3],
    /// Standard errors.
    pub se: [f64; 3],
}

/// The verdict of a calibration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    /// No effect needed: the registration explains the data (within the noise, where it is known).
    None,
    /// Effects named, and the rest within the noise (or the noise is not known).
    Effect,
    /// The rest is above the stated noise after the effects named.
    Unexplained,
}

/// A calibration's outcome.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Calibration {
    /// The verdict.
    pub verdict: Verdict,
    /// Effects always fitted, then those selected, with values.
    pub accepted: Vec<Accepted>,
    /// The selection's steps: at each, every candidate's test.
    pub steps: Vec<Vec<Tested>>,
    /// Registration and targets.
    pub nuisance: Vec<Nuisance>,
    /// Directions no fit could see, named by their parameters.
    pub not_identifiable: Vec<String>,
    /// Gross rows left out.
    pub left_out: Vec<GrossRow>,
    /// Rows the model has no prediction for (no loaded equilibrium there), left out: the reason.
    pub unusable: Vec<String>,
    /// Errors per stage.
    pub stages: Vec<Stage>,
    /// RMS of the weighted residual per coordinate after the final fit (1 where sigma was right).
    pub residual_scale: f64,
    /// Whether the noise level was given (sigma_mm or --sigma).
    pub sigma_known: bool,
    /// Rows fitted and held out.
    pub rows: (usize, usize),
    /// The data's columns no rule read.
    pub unread: Vec<String>,
    /// A parallel robot's accepted effects as the model-form effects a description holds (`model_form`;
    /// None for one it holds not), in the order of `accepted`; None for a serial arm.
    #[serde(skip)]
    pub leg_corrections: Option<Vec<Option<Effect>>>,
}

/// A joint's load as the effects read it: zero where it is round-off (below `LOAD_ROUND_OFF` of the row's
/// largest joint load: a vertical first axis carries no weight, and the sign of its round-off is no play).
fn load_of(s: &ArmStatics, joint: usize) -> f64 {
    let largest = s.loads.iter().fold(0.0f64, |a, l| a.max(l.abs()));
    let load = s.loads[joint];
    if load.abs() <= LOAD_ROUND_OFF * largest {
        0.0
    } else {
        load
    }
}

/// The joints a calibration of `m` names: a serial arm's, or a parallel robot's legs by number (1-based, as
/// `[[actuator_offset]]` and the diagnosis's effects name them), each leg's actuator its joint.
pub fn joint_names(m: &Manipulator) -> Vec<String> {
    match &m.joint_space {
        Some(space) => space.names.clone(),
        None => (1..=m.legs.len()).map(|k| k.to_string()).collect(),
    }
}

/// A parallel robot's statics at a commanded pose, read as a serial arm's are, its legs' actuators for
/// joints: per actuator, the platform's twist per unit of its offset, C K_i a_i (the end-point error a_i of
/// leg i seen through the other legs, paper 000 eq 60), and the load it carries, a_i . K_i C w (power
/// conjugate to a_i; w the row's wrench with the payload's weight, at the reference point); and at zero
/// wrench where `zero` asks. Also each leg's C K_i (the platform's twist per unit end-point error) and its
/// actuator twist a_i. First order about the unloaded commanded pose; what the load's change of C and K_i
/// and the effects' own second order leave is completed by `Problem::exact_misses`.
fn platform_statics(
    m: &Manipulator,
    pose: &Frame,
    wrench: &Vec6,
    zero: Option<&Vec6>,
    state: &mut ManipulatorState,
) -> Result<PlatformStatics, String> {
    let model = super::measurement::PoseModel::at(m, pose, state).map_err(|e| e.to_string())?;
    let moves: Vec<Mat6> = model.legs.iter().map(|k| model.compliance * k).collect();
    let columns: Vec<Vec6> = moves.iter().zip(&model.actuators).map(|(c, a)| c * a).collect();
    let under = |w: &Vec6| {
        let total = w + m.weight(pose).0;
        ArmStatics {
            frame: *pose,
            loads: columns.iter().map(|c| c.dot(&total)).collect(),
            columns: columns.clone(),
            joint_frames: Vec::new(),
            transmitted: Vec::new(),
        }
    };
    Ok(PlatformStatics { statics: under(wrench), zero: zero.map(under), moves, actuators: model.actuators })
}

/// What `platform_statics` gives.
struct PlatformStatics {
    statics: ArmStatics,
    zero: Option<ArmStatics>,
    /// Each leg's C K_i.
    moves: Vec<Mat6>,
    /// Each leg's actuator twist a_i.
    actuators: Vec<Vec6>,
}

/// How far a unit of effect `e` turns its joint in a row: nothing for an offset (it moves the configuration
/// instead) nor for a geometry or payload (they act otherwise, `Problem::unit_moves`), the load for a
/// compliance, the load's sign for play; for a displacement row, the difference between the row's wrench and
/// zero wrench (`zero`). `payload` is the weight of a payload being fitted, at the reference point: the
/// joints carry it too.
fn effect_gain(e: &ArmEffect, s: &ArmStatics, zero: &Option<ArmStatics>, payload: &Vec6) -> f64 {
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

/// What each row needs from the model, computed once: the model's own deflection (the twist of the
/// reference point under the row's loads from its springs; for a displacement row, minus that at zero
/// wrench).
struct Problem<'a> {
    m: &'a Manipulator,
    /// The manipulator under each gravity direction the rows give (a base that is not level), and which of
    /// them each row is measured under (None: `m`).
    tilted: Vec<(Vec3, Manipulator)>,
    tilt_of: Vec<Option<usize>>,
    /// A serial arm's joint space; None for a parallel robot, whose rows give commanded poses and whose
    /// "joints" are its legs' actuators.
    space: Option<&'a crate::platform::manipulator::JointSpace>,
    data: &'a PositionData,
    /// The joints' names: a serial arm's, or a parallel robot's legs by number (1-based, as `[[actuator_offset]]`
    /// and the diagnosis's effects name them).
    joints: Vec<String>,
    /// Per row of a parallel robot, each leg's C K_i: the platform's twist per unit end-point error of the
    /// leg (paper 000 eq 60); empty for a serial arm.
    leg_moves: Vec<Vec<Mat6>>,
    deflection: Vec<Vec6>,
    /// Rows without a prediction (no loaded equilibrium there), and why.
    unusable: Vec<(usize, String)>,
    /// Per row, the arm's statics at its configuration (and at zero wrench for a displacement).
    statics: Vec<(ArmStatics, Option<ArmStatics>)>,
    /// Per row, the model's tangent compliance at its loaded equilibrium (positions of a compliant model).
    compliance: Vec<Option<crate::kinematics::frame::Mat6>>,
    weight: Vec<f64>,
    absolute: bool,
    prismatic: Vec<bool>,
    /// Per target, the index of its turn among the fitted ones (None: its orientation is not measured).
    turn_of: Vec<Option<usize>>,
    /// A parallel robot's misses of its first order, per set of effects (`exact_misses`).
    misses: std::cell::RefCell<Vec<(Vec<ArmEffect>, Vec<Vec6>)>>,
}

/// What a row sees of a small motion of the tool: a target's point (its lever from the reference point, base
/// axes) or, for an orientation, the tool's turn.
#[derive(Clone, Copy, Debug)]
enum Seen {
    Point(Vec3),
    Turn,
}

impl Seen {
    /// What a twist of the tool at the reference point (translation, rotation) moves: the point by
    /// v + w x lever, the orientation by w.
    fn of(&self, twist: &Vec6) -> Vec3 {
        let rotation = twist.fixed_rows::<3>(3).into_owned();
        match self {
            Seen::Point(lever) => twist.fixed_rows::<3>(0) + rotation.cross(lever),
            Seen::Turn => rotation,
        }
    }

    /// The twist at the reference point `p` of a rigid motion turning by `w` about the point `o` and moving
    /// by `v`, as `of` reads it.
    fn rigid(&self, v: Vec3, w: Vec3, o: &Vec3, p: &Vec3) -> Vec3 {
        let t = v + w.cross(&(p - o));
        self.of(&Vec6::new(t.x, t.y, t.z, w.x, w.y, w.z))
    }
}

/// A gross row left out of the fits.
#[derive(Clone, Debug, serde::Serialize)]
pub struct GrossRow {
    /// The row: its name and line, `held out` and `orientation` where it is one.
    pub row: String,
    /// Its misfit against the model selected: mm for a position, mrad for an orientation.
    pub misfit: f64,
    /// The misfit's unit.
    pub unit: &'static str,
}

/// The failures of a calibration.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationError {
    /// The model is not a serial arm with a joint space.
    #[error("{0} is not a serial arm read from URDF: joint-space measurements need one")]
    NotAnArm(String),
    /// A row's configuration has no finite pose or no loaded equilibrium.
    #[error("{name} (line {line}): {why}")]
    Row {
        /// The row's name.
        name: String,
        /// Its line.
        line: usize,
        /// What failed.
        why: String,
    },
    /// Too few rows to fit what must be fitted.
    #[error("{0}")]
    TooFew(String),
    /// An effect named that the robot cannot have here.
    #[error("{0}")]
    NotOffered(String),
}

impl<'a> Problem<'a> {
    fn new(
        m: &'a Manipulator,
        data: &'a PositionData,
        sigma: Option<f64>,
        sigma_rad: Option<f64>,
    ) -> Result<Self, CalibrationError> {
        if data.rows.is_empty() {
            return Err(CalibrationError::TooFew("no rows: nothing to calibrate or plan with".into()));
        }
        let space = m.joint_space.as_ref();
        if space.is_none() && data.rows.iter().any(|r| r.pose.is_none()) {
            return Err(CalibrationError::NotAnArm(m.name.clone()));
        }
        let compliant = m.legs.iter().any(|l| l.spring_groups().next().is_some());
        let mut tilted: Vec<(Vec3, Manipulator)> = Vec::new();
        let tilt_of: Vec<Option<usize>> = data
            .rows
            .iter()
            .map(|r| {
                r.gravity.map(|g| match tilted.iter().position(|(d, _)| *d == g) {
                    Some(k) => k,
                    None => {
                        tilted.push((g, m.with_gravity_direction(&g)));
                        tilted.len() - 1
                    }
                })
            })
            .collect();
        let arm_of = |k: usize| tilt_of[k].map_or(m, |t| &tilted[t].1);
        let mut state = m.new_state();
        let mut deflection = Vec::with_capacity(data.rows.len());
        let failed = |r: &PositionRow, why: String| CalibrationError::Row { name: r.name.clone(), line: r.line, why };
        let mut compliance = Vec::with_capacity(data.rows.len());
        let under = |m: &Manipulator,
                     r: &PositionRow,
                     wrench: &Vec6,
                     state: &mut ManipulatorState|
         -> Result<(Vec6, Option<crate::kinematics::frame::Mat6>), CalibrationError> {
            let frame = r
                .nominal_frame(m, state)
                .ok_or_else(|| failed(r, "the joint coordinates give no finite pose".into()))?;
            m.place(&frame, state).map_err(|e| failed(r, e.to_string()))?;
            let d = m.deflect(&frame, wrench, None, state).map_err(|e| failed(r, e.to_string()))?;
            if !d.stable {
                return Err(failed(r, "the loaded equilibrium is unstable".into()));
            }
            Ok((d.displacement, d.held.stiffness.try_inverse()))
        };
        // A row whose loaded equilibrium the model cannot find (a singular configuration, a load past a
        // limit) is left out and named: the model has no prediction there.
        let mut unusable: Vec<(usize, String)> = Vec::new();
        // The rows of one line of the file (several targets, a position and its orientation) share its
        // configuration, wrench and gravity: their equilibrium and statics are those of the line's first.
        let same_line = |k: usize| k > 0 && data.rows[k - 1].line == data.rows[k].line;
        for (k, r) in data.rows.iter().enumerate() {
            if same_line(k) {
                if let Some((_, why)) = unusable.last().filter(|(u, _)| *u == k - 1) {
                    unusable.push((k, why.clone()));
                }
                deflection.push(deflection[k - 1]);
                compliance.push(compliance[k - 1]);
                continue;
            }
            let arm = arm_of(k);
            let found = match (compliant, r.observed) {
                (false, _) => Ok((Vec6::zeros(), None)),
                (true, Observed::Position { .. } | Observed::Orientation { .. }) => {
                    under(arm, r, &r.wrench, &mut state)
                }
                (true, Observed::Displacement(_)) => under(arm, r, &r.wrench, &mut state)
                    .and_then(|(d, _)| Ok((d - under(arm, r, &Vec6::zeros(), &mut state)?.0, None))),
            };
            let (d, c) = found.unwrap_or_else(|e| {
                unusable.push((k, e.to_string()));
                (Vec6::zeros(), None)
            });
            deflection.push(d);
            compliance.push(c);
        }
        let weight = data
            .rows
            .iter()
            .map(|r| {
                let given = match r.observed {
                    Observed::Orientation { .. } => sigma_rad,
                    _ => sigma,
                };
                1.0 / r.sigma.or(given).unwrap_or(1.0)
            })
            .collect();
        let mut statics: Vec<(ArmStatics, Option<ArmStatics>)> = Vec::with_capacity(data.rows.len());
        let mut leg_moves: Vec<Vec<Mat6>> = Vec::with_capacity(if space.is_some() { 0 } else { data.rows.len() });
        let mut prismatic = Vec::new();
        for (k, r) in data.rows.iter().enumerate() {
            if same_line(k) {
                statics.push(statics[k - 1].clone());
                if space.is_none() {
                    leg_moves.push(leg_moves[k - 1].clone());
                    let why = unusable.iter().find(|(u, _)| *u == k - 1).map(|(_, why)| why.clone());
                    if let Some(why) = why.filter(|_| !unusable.iter().any(|(u, _)| *u == k)) {
                        unusable.push((k, why));
                    }
                }
                continue;
            }
            let m = arm_of(k);
            let zero = match r.observed {
                Observed::Displacement(_) => Some(Vec6::zeros()),
                Observed::Position { .. } | Observed::Orientation { .. } => None,
            };
            let (s, z) = match (space, r.pose) {
                (Some(_), _) | (None, None) => {
                    let at = |w: &Vec6, state: &mut ManipulatorState| {
                        m.arm_statics(&r.joints, w, state)
                            .ok_or_else(|| failed(r, "the joint coordinates give no finite pose".into()))
                    };
                    let s = at(&r.wrench, &mut state)?;
                    if prismatic.is_empty() {
                        prismatic = s.columns.iter().map(|c| c.fixed_rows::<3>(3).norm() == 0.0).collect();
                    }
                    (s, zero.map(|w| at(&w, &mut state)).transpose()?)
                }
                (None, Some(pose)) => {
                    // A row the model has no pose model for is already named unusable (its equilibrium
                    // failed too, or will be): it keeps zero effects.
                    match platform_statics(m, &pose, &r.wrench, zero.as_ref(), &mut state) {
                        Ok(p) => {
                            if prismatic.is_empty() {
                                prismatic = p.actuators.iter().map(|a| a.fixed_rows::<3>(3).norm() == 0.0).collect();
                            }
                            leg_moves.push(p.moves);
                            (p.statics, p.zero)
                        }
                        Err(why) => {
                            if !unusable.iter().any(|(u, _)| *u == k) {
                                unusable.push((k, failed(r, why).to_string()));
                            }
                            let legs = m.legs.len();
                            leg_moves.push(vec![Mat6::zeros(); legs]);
                            let still = ArmStatics {
                                frame: pose,
                                columns: vec![Vec6::zeros(); legs],
                                loads: vec![0.0; legs],
                                joint_frames: Vec::new(),
                                transmitted: Vec::new(),
                            };
                            (still.clone(), zero.map(|_| still))
                        }
                    }
                }
            };
            statics.push((s, z));
        }
        let joints = joint_names(m);
        prismatic.resize(joints.len(), false);
        let mut turns = 0;
        let turn_of = (0..data.targets.len())
            .map(|t| {
                let oriented =
                    data.rows.iter().any(|r| matches!(r.observed, Observed::Orientation { target, .. } if target == t));
                oriented.then(|| {
                    turns += 1;
                    turns - 1
                })
            })
            .collect();
        Ok(Problem {
            m,
            tilted,
            tilt_of,
            space,
            data,
            joints,
            leg_moves,
            deflection,
            statics,
            compliance,
            unusable,
            weight,
            absolute: data.absolute(),
            prismatic,
            turn_of,
            misses: std::cell::RefCell::new(Vec::new()),
        })
    }

    /// The candidates without the play of a joint whose load keeps one sign in nearly every row of `rows`:
    /// play is told from an offset (or from nothing, in a displacement) only by rows loading the joint both
    /// ways, at least `MIN_PLAY_ROWS` and a tenth of the rows each way; with fewer it would fit a few rows'
    /// misfit. Returns the candidates kept and a note for each left out.
    fn two_sided_play(&self, candidates: Vec<ArmEffect>, rows: &[usize]) -> (Vec<ArmEffect>, Vec<String>) {
        // An orientation shares its position row's load: counted once.
        let rows: Vec<usize> = rows.iter().copied().filter(|&r| !self.data.rows[r].observed.is_orientation()).collect();
        let mut notes = Vec::new();
        let kept = candidates
            .into_iter()
            .filter(|e| {
                if e.kind != ArmKind::Backlash {
                    return true;
                }
                let (mut up, mut down) = (0, 0);
                for &r in &rows {
                    let (s, zero) = &self.statics[r];
                    let g = effect_gain(e, s, zero, &Vec6::zeros());
                    up += usize::from(g > 0.0);
                    down += usize::from(g < 0.0);
                }
                let needed = MIN_PLAY_ROWS.max(rows.len().div_ceil(10));
                let both = match self.absolute {
                    true => up.min(down) >= needed,
                    false => up + down >= needed,
                };
                if !both {
                    notes.push(format!(
                        "{}: its joint's load changes sign in too few rows ({up} one way, {down} the other; {needed} each needed) to tell play from {}",
                        e.label(&self.joints),
                        if self.absolute { "an offset" } else { "noise" }
                    ));
                }
                both
            })
            .collect();
        (kept, notes)
    }

    /// The manipulator row `r` was measured under (its gravity's direction).
    fn arm(&self, r: usize) -> &Manipulator {
        self.tilt_of[r].map_or(self.m, |t| &self.tilted[t].1)
    }

    /// Nuisance parameters: per set-up a translation and a rotation, per target a place on the tool.
    /// The effects offered where none are named: every joint's offset, compliance, play and geometry and the
    /// payload for positions; compliance and play for displacements (which see no geometry).
    fn default_candidates(&self) -> Vec<ArmEffect> {
        if self.space.is_none() {
            return self.default_leg_candidates();
        }
        let kinds: &[ArmKind] = if self.absolute {
            &[ArmKind::JointOffset, ArmKind::JointCompliance, ArmKind::Backlash, ArmKind::JointGeometry]
        } else {
            &[ArmKind::JointCompliance, ArmKind::Backlash]
        };
        // A compliance at a link's frame (six parameters, many of them tied to the registration and to the
        // joints' compliances) is offered when asked for (`--candidates`, `--fit`): offered by default on the
        // TIAGo's 37 training postures, three of them were accepted and the held-out error grew.
        let mut all: Vec<ArmEffect> =
            (0..self.joints.len()).flat_map(|j| kinds.iter().map(move |&kind| ArmEffect { kind, joint: j })).collect();
        // A drift is offered when asked for, too: offered by default on the TIAGo's training postures (a
        // protocol whose order follows the configurations), it was accepted in place of the arm's geometry
        // and the held-out error doubled.
        if self.absolute {
            all.push(ArmEffect { kind: ArmKind::Payload, joint: 0 });
        }
        all
    }

    /// A parallel robot's: every actuator's offset, compliance and play (of the legs that have an actuator
    /// moving the platform) and the payload (positions); compliance and play for displacements. A leg's
    /// geometry (its end-point error, six parameters) is offered when asked for (`--candidates`, `--fit`):
    /// the legs' end-point errors overlap each other's and the actuators' offsets (on a platform that only
    /// translates, two legs' errors move it as a third leg's offset does), and offered by default, on the
    /// Orthoglide with actuators 1 and 3 offset and 2 compliant, legs 2's and 3's geometries were named
    /// instead in 29 of 30 seeds.
    fn default_leg_candidates(&self) -> Vec<ArmEffect> {
        let actuated = |j: usize| self.statics.iter().any(|(s, _)| s.columns[j] != Vec6::zeros());
        let mut all = Vec::new();
        for j in 0..self.joints.len() {
            let kinds: &[ArmKind] = match (self.absolute, actuated(j)) {
                (true, true) => &[ArmKind::JointOffset, ArmKind::JointCompliance, ArmKind::Backlash],
                (false, true) => &[ArmKind::JointCompliance, ArmKind::Backlash],
                (_, false) => &[],
            };
            all.extend(kinds.iter().map(|&kind| ArmEffect { kind, joint: j }));
        }
        if self.absolute {
            all.push(ArmEffect { kind: ArmKind::Payload, joint: 0 });
        }
        all
    }

    /// Whether the robot can have effect `e`: a compliance at a frame is a serial arm's (a parallel robot's
    /// legs are not read as chains of frames here).
    fn offers(&self, e: &ArmEffect) -> bool {
        self.space.is_some() || e.kind != ArmKind::FrameCompliance
    }

    /// The model's compliance of joint `j` along (about) its axis, where it has a spring there: a serial
    /// arm's joint, a parallel robot's leg's actuator.
    fn nominal_compliance(&self, j: usize) -> Option<f64> {
        match self.space {
            Some(_) => self.m.joint_compliance(&self.joints[j]),
            None => self.m.legs[j].actuator_compliance(),
        }
    }

    fn nuisance_count(&self) -> usize {
        if self.absolute {
            6 * self.data.setups.len() + 3 * self.data.targets.len() + 3 * self.turn_count()
        } else {
            0
        }
    }

    /// How many targets' turns are fitted (those whose orientation is measured).
    fn turn_count(&self) -> usize {
        self.turn_of.iter().flatten().count()
    }

    /// The index of the first parameter of target `t`'s turn.
    fn turn_parameter(&self, t: usize) -> Option<usize> {
        self.turn_of[t].map(|k| 6 * self.data.setups.len() + 3 * self.data.targets.len() + 3 * k)
    }

    /// The prediction of row `r` and its derivative in every parameter (3 x p, weighted by the row's weight
    /// along with the residual).
    fn predict(
        &self,
        r: usize,
        effects: &[ArmEffect],
        params: &Params,
        state: &mut ManipulatorState,
        jacobian: Option<&mut DMatrix<f64>>,
    ) -> Option<Vec3> {
        let row = &self.data.rows[r];
        // A serial arm's offsets move its configuration (exactly); a parallel robot's act through their
        // first-order moves (`unit_moves`).
        let mut joints = row.joints.clone();
        for (e, v) in effects.iter().zip(&params.effects) {
            if e.kind == ArmKind::JointOffset && self.space.is_some() {
                joints[e.joint] += v[0];
            }
        }
        // The arm's statics at the configuration: the row's own (computed once) unless offsets move it.
        let fresh;
        let (s, zero) = if joints == row.joints {
            &self.statics[r]
        } else {
            fresh = self.statics_at(r, row, &joints, state)?;
            &fresh
        };
        // The model's own deflection (and a parallel robot's kept miss), a twist at the reference point. A
        // parallel robot's turn carries the target's lever exactly (an Orthoglide under a milling moment turns
        // by 0.05 rad, whose second order on a lever of 10 mm is 12 um); a serial arm's sag turns its tool by
        // about 1e-3 rad, whose second order is below 1e-4 mm, and keeps the first order it was validated with
        // (its selection on data with unscreened gross rows is sensitive to such round-off-size changes).
        let deflected = self.deflection[r] + self.kept_miss(effects, r);
        let loaded_rot = self.tool_turned(r, s);
        let (seen, tool) = match row.observed {
            Observed::Position { target, .. } => {
                let lever = loaded_rot * params.targets[target];
                (Seen::Point(lever), s.frame.pos + lever)
            }
            Observed::Orientation { .. } => (Seen::Turn, Vec3::zeros()),
            Observed::Displacement(_) => (Seen::Point(Vec3::zeros()), Vec3::zeros()),
        };
        // A payload being fitted weighs on every joint: its wrench at the reference point, (m g, (R s) x g).
        let payload = |s: &ArmStatics| self.fitted_payload_weight(r, effects, params, s, zero);
        // The body's point (target, or the tool point of a displacement) under the loads, before registration;
        // for an orientation, the tool's turn under them (base axes). A parallel robot's first order is
        // completed by the miss kept for these effects (`exact_misses`).
        let mut y = match (seen, self.space) {
            // The lever already turned with the deflection (a parallel robot).
            (Seen::Point(_), None) => tool + deflected.fixed_rows::<3>(0),
            // A serial arm's lever turned at first order, v + w x lever; an orientation turns by w.
            _ => tool + seen.of(&deflected),
        };
        for (e, v) in effects.iter().zip(&params.effects) {
            for (unit, value) in self.unit_moves(r, e, s, zero, &seen, &payload(s)).iter().zip(v) {
                y += unit * *value;
            }
        }
        let (rotation, translation) = match row.observed {
            Observed::Position { setup, .. } | Observed::Orientation { setup, .. } => {
                (params.rotations[setup], params.translations[setup])
            }
            Observed::Displacement(_) => (Mat3::identity(), Vec3::zeros()),
        };
        // An orientation is predicted as the target's axes in the instrument's frame, R exp(y) R_tool R_target;
        // its prediction is its rotation vector away from the measured one (`measured` gives zero for it).
        let turned = match row.observed {
            Observed::Orientation { target, at, .. } => {
                let axes = rotation * rotation_from_vector(&y) * s.frame.rot;
                Some((axes, crate::kinematics::frame::rotation_vector(&(axes * params.turns[target] * at.transpose()))))
            }
            _ => None,
        };
        let prediction = match turned {
            Some((_, off)) => off,
            None => rotation * y + translation,
        };
        if let Some(jac) = jacobian {
            let w = self.weight[r];
            jac.fill(0.0);
            let mut k = 0;
            if let Some((target, setup)) = row.observed.target_and_setup() {
                let base = 6 * setup;
                if let Some((axes, _)) = turned {
                    // A small rotation d after R turns the prediction by d (to first order about a small
                    // misfit); the target's turn e in the tool's axes by R exp(y) R_tool e.
                    jac.view_mut((0, base + 3), (3, 3)).copy_from(&(Mat3::identity() * w));
                    if let Some(t) = self.turn_parameter(target) {
                        jac.view_mut((0, t), (3, 3)).copy_from(&(axes * w));
                    }
                } else {
                    let ry = rotation * y;
                    for a in 0..3 {
                        jac[(a, base + a)] = w;
                    }
                    // A small rotation d applied after R: d(R y) = d x (R y) = -[R y]x d.
                    let cross = -skew(&ry) * w;
                    jac.view_mut((0, base + 3), (3, 3)).copy_from(&cross);
                    let t = 6 * self.data.setups.len() + 3 * target;
                    jac.view_mut((0, t), (3, 3)).copy_from(&(rotation * loaded_rot * w));
                }
                k = self.nuisance_count();
            }
            for e in effects {
                let columns = match (e.kind, self.space) {
                    (ArmKind::JointOffset, Some(space)) => {
                        // The offset turns every model coordinate the controller map ties to its angle; the
                        // body's point moves with each by its twist column (the loads' change with it is of
                        // second order, left to the iterations, which evaluate the prediction exactly).
                        let rates = space.coordinate_rates(&joints, e.joint);
                        let mut column = Vec3::zeros();
                        for (rate, c) in rates.iter().zip(&s.columns) {
                            if *rate != 0.0 && zero.is_none() {
                                column += seen.of(c) * *rate;
                            }
                        }
                        vec![column]
                    }
                    (ArmKind::Payload, _) => {
                        // Its weight loads the compliances being fitted too (their term is the compliance
                        // times the joint's load, payload included): the derivative has that part as well.
                        let mut columns = self.unit_moves(r, e, s, zero, &seen, &payload(s));
                        let g = self.arm(r).weight_gravity();
                        for (k, column) in columns.iter_mut().enumerate() {
                            let unit = if k == 0 {
                                Vec6::new(g.x, g.y, g.z, 0.0, 0.0, 0.0)
                            } else {
                                let m = self.tool_turned(r, s).column(k - 1).into_owned().cross(&g);
                                Vec6::new(0.0, 0.0, 0.0, m.x, m.y, m.z)
                            };
                            for (other, v) in effects.iter().zip(&params.effects) {
                                if other.kind == ArmKind::JointCompliance && zero.is_none() {
                                    let joint = &s.columns[other.joint];
                                    *column += seen.of(joint) * (v[0] * joint.dot(&unit));
                                }
                            }
                        }
                        columns
                    }
                    _ => self.unit_moves(r, e, s, zero, &seen, &payload(s)),
                };
                for column in columns {
                    jac.view_mut((0, k), (3, 1)).copy_from(&(rotation * column * w));
                    k += 1;
                }
            }
        }
        Some(prediction)
    }

    /// The weight of a payload being fitted (`effects`, `params`) at the reference point of row `r`, (m g,
    /// (R s) x g) with s = m c its first moment in the tool frame: the joints carry it too. Zero without
    /// one, and for a displacement (the weight is in both states).
    fn fitted_payload_weight(
        &self,
        r: usize,
        effects: &[ArmEffect],
        params: &Params,
        s: &ArmStatics,
        zero: &Option<ArmStatics>,
    ) -> Vec6 {
        let Some(k) = effects.iter().position(|e| e.kind == ArmKind::Payload) else { return Vec6::zeros() };
        if zero.is_some() {
            return Vec6::zeros();
        }
        let (v, g) = (&params.effects[k], self.arm(r).weight_gravity());
        let moment = (self.tool_turned(r, s) * Vec3::new(v[1], v[2], v[3])).cross(&g);
        let force = g * v[0];
        Vec6::new(force.x, force.y, force.z, moment.x, moment.y, moment.z)
    }

    /// The tool's axes at row `r` under the model's own loads, for a parallel robot: a payload's centre turns
    /// with them, so its moment (R c) x g sees the centre's component along gravity once the load turns the
    /// tool (an Orthoglide under the milling moment turns by 0.05 rad: 20 kg 50 mm above the reference point
    /// then weigh 490 N mm, which the unturned axes put on the centre's other components). A serial arm's
    /// axes as the unloaded kinematics gives them (see `predict`).
    fn tool_turned(&self, r: usize, s: &ArmStatics) -> Mat3 {
        match self.space {
            Some(_) => s.frame.rot,
            None => rotation_from_vector(&self.deflection[r].fixed_rows::<3>(3).into_owned()) * s.frame.rot,
        }
    }

    /// The miss kept for these effects at row `r` (`exact_misses`), zero where none is kept.
    /// Where none is kept for exactly these, the one kept for their longest leading part: the selection tries
    /// each candidate after the model it has (whose misses `select` keeps), so a candidate is judged against
    /// the model's exact prediction, its own first order added.
    fn kept_miss(&self, effects: &[ArmEffect], r: usize) -> Vec6 {
        let misses = self.misses.borrow();
        let exact = misses.iter().find(|(e, _)| e == effects);
        let leading = || misses.iter().filter(|(e, _)| effects.starts_with(e)).max_by_key(|(e, _)| e.len());
        exact.or_else(leading).map_or_else(Vec6::zeros, |(_, m)| m[r])
    }

    /// A parallel robot's effects act at first order (`unit_moves`): an actuator offset of 1 mm on legs of
    /// 300 mm leaves about 3 um of second order, an actuator's compliance and a payload the change of C and
    /// K_i with the pose. This is, per row, the twist (reference point, base frame) from that first-order
    /// prediction with `effects` at `params` to the loaded equilibrium of the robot with the effects a
    /// description holds built in (actuator offsets, added actuator compliances as factors on their springs,
    /// a payload of positive mass), as `stiff synth` and every study compute it; the effects no description
    /// holds (a leg's end-point error, play) stay first order. None where none is built in, for a serial arm
    /// (whose offsets are exact and whose compliances act at first order about its loaded equilibrium), or
    /// where a row has no equilibrium.
    fn exact_misses(&self, effects: &[ArmEffect], params: &Params) -> Option<Vec<Vec6>> {
        if self.space.is_some() {
            return None;
        }
        let built: Vec<(&ArmEffect, &Vec<f64>, Effect)> =
            effects.iter().zip(&params.effects).filter_map(|(e, v)| Some((e, v, self.model_form(e, v)?))).collect();
        if built.is_empty() {
            return None;
        }
        let model_form: Vec<Effect> = built.iter().map(|(_, _, f)| f.clone()).collect();
        let mut real: Vec<Option<Manipulator>> = vec![None; self.tilted.len() + 1];
        let mut state = self.m.new_state();
        let mut misses = Vec::with_capacity(self.data.rows.len());
        for (r, row) in self.data.rows.iter().enumerate() {
            if r > 0 && self.data.rows[r - 1].line == row.line {
                misses.push(misses[r - 1]);
                continue;
            }
            let (Some(pose), Observed::Position { .. } | Observed::Orientation { .. }) = (row.pose, row.observed)
            else {
                misses.push(Vec6::zeros());
                continue;
            };
            let robot = real[self.tilt_of[r].map_or(0, |t| t + 1)]
                .get_or_insert_with(|| crate::model::effect::with_model_effects(self.arm(r), &model_form));
            if self.unusable.iter().any(|(u, _)| *u == r) {
                misses.push(Vec6::zeros());
                continue;
            }
            robot.place(&pose, &mut state).ok()?;
            let exact = robot.deflect(&pose, &row.wrench, None, &mut state).ok()?.displacement;
            // The first order of the built-in effects, as a twist: what a point at the reference point sees
            // (its translation) and what the tool's turn sees (its rotation).
            let (s, zero) = &self.statics[r];
            let payload = self.fitted_payload_weight(r, effects, params, s, zero);
            let mut linear = self.deflection[r];
            for (e, v, _) in &built {
                let moves = self.unit_moves(r, e, s, zero, &Seen::Point(Vec3::zeros()), &payload);
                let turns = self.unit_moves(r, e, s, zero, &Seen::Turn, &payload);
                for ((m, t), value) in moves.iter().zip(&turns).zip(v.iter()) {
                    linear += Vec6::new(m.x, m.y, m.z, t.x, t.y, t.z) * *value;
                }
            }
            misses.push(exact - linear);
        }
        Some(misses)
    }

    /// A parallel robot's effect `e` at `values` as the description's model-form effect every study builds in
    /// (`model::effect::with_model_effects`): an actuator offset, an added actuator compliance as the factor
    /// on its spring (where it has one and stays positive), a payload of positive mass (stored as (m, m c),
    /// as the fit's parameters are); None for the others, which no description holds.
    fn model_form(&self, e: &ArmEffect, values: &[f64]) -> Option<Effect> {
        let leg = Target::Leg(e.joint);
        match e.kind {
            ArmKind::JointOffset => Some(Effect { kind: Kind::ActuatorOffset, target: leg, values: values.to_vec() }),
            ArmKind::JointCompliance => {
                let nominal = self.nominal_compliance(e.joint).filter(|n| n + values[0] > 0.0)?;
                let factor = (nominal + values[0]) / nominal;
                Some(Effect { kind: Kind::ActuatorCompliance, target: leg, values: vec![factor] })
            }
            ArmKind::Payload if values[0] > 0.0 => {
                Some(Effect { kind: Kind::GravityOffset, target: Target::None, values: values.to_vec() })
            }
            _ => None,
        }
    }

    /// The fit of `effects` on `rows` from `start`, a parallel robot's first order completed by its misses
    /// (`exact_misses`): kept for these effects and refitted until the prediction moves by less than a tenth
    /// of a standard deviation. Each pass shrinks the miss by about the effects' relative size (an offset
    /// of 1 mm on legs of 300 mm: 300 times), so a few passes reach round-off; at most `EXACT_PASSES`.
    fn fit_exact(&self, rows: &[usize], effects: &[ArmEffect], start: &Params) -> Option<Fit> {
        let mut fit = self.fit(rows, effects, start)?;
        for _ in 0..EXACT_PASSES {
            let Some(misses) = self.exact_misses(effects, &fit.params) else { break };
            let kept: Vec<Vec6> = (0..misses.len()).map(|r| self.kept_miss(effects, r)).collect();
            let moved = rows
                .iter()
                .map(|&r| {
                    let change = misses[r] - kept[r];
                    let seen = match self.data.rows[r].observed {
                        Observed::Position { target, .. } => {
                            Seen::Point(self.statics[r].0.frame.rot * fit.params.targets[target])
                        }
                        Observed::Orientation { .. } => Seen::Turn,
                        Observed::Displacement(_) => Seen::Point(Vec3::zeros()),
                    };
                    seen.of(&change).norm() * self.weight[r]
                })
                .fold(0.0, f64::max);
            let mut all = self.misses.borrow_mut();
            all.retain(|(e, _)| e != effects);
            all.push((effects.to_vec(), misses));
            drop(all);
            if moved.is_nan() || moved <= 0.1 {
                break;
            }
            fit = self.fit(rows, effects, &fit.params)?;
        }
        Some(fit)
    }

    /// How the body's point (before registration), or the tool's turn for an orientation, moves per unit of
    /// each parameter of effect `e` in row `r` (`s` the arm's statics there, `zero` at zero wrench for a
    /// displacement, `seen` what the row sees, `payload` the weight of a payload being fitted); an offset's are
    /// found by differences in `predict`.
    fn unit_moves(
        &self,
        r: usize,
        e: &ArmEffect,
        s: &ArmStatics,
        zero: &Option<ArmStatics>,
        seen: &Seen,
        payload: &Vec6,
    ) -> Vec<Vec3> {
        let point = |c: &Vec6| seen.of(c);
        let turning = matches!(seen, Seen::Turn);
        match e.kind {
            // A serial arm's offset moves its configuration (`predict`); a parallel robot's actuator offset
            // moves the platform by C K_i a_i per unit (a displacement does not see it).
            ArmKind::JointOffset if self.space.is_some() || zero.is_some() => vec![Vec3::zeros()],
            ArmKind::JointOffset => vec![point(&s.columns[e.joint])],
            // A parallel robot's leg geometry: its end-point error eps (base axes, at the reference point)
            // moves the platform by C K_i eps (paper 000 eq 60).
            ArmKind::JointGeometry if self.space.is_none() => {
                if zero.is_some() {
                    return vec![Vec3::zeros(); 6];
                }
                let moves = &self.leg_moves[r][e.joint];
                (0..6).map(|k| point(&moves.column(k).into_owned())).collect()
            }
            ArmKind::JointCompliance | ArmKind::Backlash => {
                vec![point(&s.columns[e.joint]) * effect_gain(e, s, zero, payload)]
            }
            ArmKind::JointGeometry => {
                // The fixed transform before the joint moved by (v, w) in the joint's frame: everything after it
                // moves rigidly, R v + (R w) x (x - o) at the point x (a displacement does not see it).
                if zero.is_some() {
                    return vec![Vec3::zeros(); 6];
                }
                let f = &s.joint_frames[e.joint];
                (0..6)
                    .map(|k| {
                        let axis = f.rot.column(k % 3).into_owned();
                        if k < 3 {
                            seen.rigid(axis, Vec3::zeros(), &f.pos, &s.frame.pos)
                        } else {
                            seen.rigid(Vec3::zeros(), axis, &f.pos, &s.frame.pos)
                        }
                    })
                    .collect()
            }
            ArmKind::FrameCompliance => {
                // The wrench through the frame (for a displacement, its change with the row's wrench), in the
                // frame's axes: each compliance turns one of its components into a motion of everything beyond.
                let f = &s.joint_frames[e.joint];
                let through = |st: &ArmStatics| {
                    st.transmitted[e.joint]
                        + crate::platform::manipulator::moved_wrench(payload, &(st.frame.pos - f.pos))
                };
                let mut w = through(s);
                if let Some(z) = zero {
                    w -= z.transmitted[e.joint];
                }
                (0..6)
                    .map(|k| {
                        let axis = f.rot.column(k % 3).into_owned();
                        let local = axis.dot(&Vec3::new(w[3 * (k / 3)], w[3 * (k / 3) + 1], w[3 * (k / 3) + 2]));
                        if k < 3 {
                            seen.rigid(axis * local, Vec3::zeros(), &f.pos, &s.frame.pos)
                        } else {
                            seen.rigid(Vec3::zeros(), axis * local, &f.pos, &s.frame.pos)
                        }
                    })
                    .collect()
            }
            ArmKind::Payload => {
                // Its weight at the reference point, (m g, (R s) x g) with s = m c its first moment, seen through
                // the model's tangent compliance (a rigid model, or a displacement, does not see it).
                let Some(c) = &self.compliance[r] else { return vec![Vec3::zeros(); 4] };
                let g = self.arm(r).weight_gravity();
                let mut moves = vec![point(&(c * Vec6::new(g.x, g.y, g.z, 0.0, 0.0, 0.0)))];
                for k in 0..3 {
                    let moment = self.tool_turned(r, s).column(k).into_owned().cross(&g);
                    moves.push(point(&(c * Vec6::new(0.0, 0.0, 0.0, moment.x, moment.y, moment.z))));
                }
                moves
            }
            // The instrument's position readings drift; the tool's turn is not one of them.
            ArmKind::Drift if turning => vec![Vec3::zeros(); 3],
            // A rate per row of the file (its line: the targets of one line were seen together), from the
            // first row; what is common to every row is the registration's.
            ArmKind::Drift => {
                let t = (self.data.rows[r].line - self.data.rows[0].line) as f64;
                (0..3).map(|k| Vec3::ith(k, t)).collect()
            }
            // It moves the tool along its own axes (a spring in translation): no turn.
            ArmKind::ToolCompliance if turning => vec![Vec3::zeros(); 3],
            // The force through the tool: the row's wrench, the description's payload and one being fitted
            // (for a displacement, the wrench's alone: the weights are in both states).
            ArmKind::ToolCompliance => {
                let row = &self.data.rows[r];
                let mut force = row.wrench.fixed_rows::<3>(0).into_owned();
                if zero.is_none() {
                    force += (self.arm(r).weight(&s.frame).0 + payload).fixed_rows::<3>(0);
                }
                (0..3)
                    .map(|k| {
                        let axis = s.frame.rot.column(k).into_owned();
                        axis * axis.dot(&force)
                    })
                    .collect()
            }
        }
    }

    /// A row's statics at controller angles `joints` under its wrench, and at zero wrench for a displacement.
    fn statics_at(
        &self,
        r: usize,
        row: &PositionRow,
        joints: &[f64],
        state: &mut ManipulatorState,
    ) -> Option<(ArmStatics, Option<ArmStatics>)> {
        let arm = self.arm(r);
        let s = arm.arm_statics(joints, &row.wrench, state)?;
        let zero = match row.observed {
            Observed::Displacement(_) => Some(arm.arm_statics(joints, &Vec6::zeros(), state)?),
            Observed::Position { .. } | Observed::Orientation { .. } => None,
        };
        Some((s, zero))
    }

    /// What row `r` measured, as its prediction is written: a position or displacement (mm); for an
    /// orientation zero, its prediction being the rotation vector from the measured orientation (rad).
    fn measured(&self, r: usize) -> Vec3 {
        match self.data.rows[r].observed {
            Observed::Position { at, .. } => at,
            Observed::Orientation { .. } => Vec3::zeros(),
            Observed::Displacement(d) => d,
        }
    }

    /// The unweighted residual (measured minus predicted) of every row, None where a row has no pose.
    fn residuals(&self, effects: &[ArmEffect], params: &Params) -> Vec<Option<Vec3>> {
        let mut state = self.m.new_state();
        (0..self.data.rows.len())
            .map(|r| self.predict(r, effects, params, &mut state, None).map(|p| self.measured(r) - p))
            .collect()
    }

    /// The starting parameters: each set-up's frame from the nominal tool points (Kabsch's fit of the
    /// rotation), targets at the tool point, effects zero.
    fn start(&self, rows: &[usize], effects: &[ArmEffect]) -> Params {
        let setups = self.data.setups.len();
        let mut params = Params {
            rotations: vec![Mat3::identity(); setups],
            translations: vec![Vec3::zeros(); setups],
            targets: vec![Vec3::zeros(); self.data.targets.len()],
            turns: vec![Mat3::identity(); self.data.targets.len()],
            effects: effects.iter().map(|e| vec![0.0; e.size()]).collect(),
        };
        if !self.absolute {
            return params;
        }
        let mut state = self.m.new_state();
        for s in 0..setups {
            let pairs: Vec<(Vec3, Vec3)> = rows
                .iter()
                .filter(|&&r| matches!(self.data.rows[r].observed, Observed::Position { setup, .. } if setup == s))
                .filter_map(|&r| {
                    let f = self.data.rows[r].nominal_frame(self.m, &mut state)?;
                    Some((f.pos, self.measured(r)))
                })
                .collect();
            if pairs.is_empty() {
                continue;
            }
            let n = pairs.len() as f64;
            let (ca, cb) = pairs.iter().fold((Vec3::zeros(), Vec3::zeros()), |(a, b), (p, q)| (a + p / n, b + q / n));
            // Kabsch: the rotation nearest the cross-covariance sum (q - cb) (p - ca)^T.
            let h = pairs.iter().fold(Mat3::zeros(), |h, (p, q)| h + (q - cb) * (p - ca).transpose());
            let rotation = nearest_rotation(&h);
            params.rotations[s] = rotation;
            params.translations[s] = cb - rotation * ca;
        }
        // Each measured target's axes in the tool frame: the mean (projected back to a rotation) of
        // R_tool^T R^T M over its rows, M the measured orientation.
        for t in (0..self.data.targets.len()).filter(|&t| self.turn_of[t].is_some()) {
            let mut sum = Mat3::zeros();
            for &r in rows {
                if let Observed::Orientation { target, setup, at } = self.data.rows[r].observed {
                    if target == t {
                        if let Some(f) = self.data.rows[r].nominal_frame(self.m, &mut state) {
                            sum += f.rot.transpose() * params.rotations[setup].transpose() * at;
                        }
                    }
                }
            }
            params.turns[t] = nearest_rotation(&sum);
        }
        params
    }

    /// Levenberg-Marquardt over the parameters on `rows`, from `start`.
    fn fit(&self, rows: &[usize], effects: &[ArmEffect], start: &Params) -> Option<Fit> {
        let p = self.nuisance_count() + effects.iter().map(ArmEffect::size).sum::<usize>();
        let n = 3 * rows.len();
        let mut params = start.clone();
        let mut state = self.m.new_state();
        let mut jac_row = DMatrix::zeros(3, p);
        let evaluate =
            |params: &Params, state: &mut ManipulatorState, jac_row: &mut DMatrix<f64>, with_jacobian: bool| {
                let mut jac = DMatrix::zeros(if with_jacobian { n } else { 0 }, p);
                let mut e = DVector::zeros(n);
                for (i, &r) in rows.iter().enumerate() {
                    let prediction = self.predict(r, effects, params, state, with_jacobian.then_some(&mut *jac_row))?;
                    let residual = (self.measured(r) - prediction) * self.weight[r];
                    e.fixed_rows_mut::<3>(3 * i).copy_from(&residual);
                    if with_jacobian {
                        jac.view_mut((3 * i, 0), (3, p)).copy_from(&*jac_row);
                    }
                }
                Some((jac, e))
            };
        let mut lambda = 1e-6;
        let (mut jac, mut e) = evaluate(&params, &mut state, &mut jac_row, true)?;
        let mut rss = e.norm_squared();
        if p == 0 {
            // Nothing to fit (displacements, no effect): the model as it is.
            return Some(Fit {
                params,
                rss,
                observations: n,
                rank: 0,
                covariance: DMatrix::zeros(0, 0),
                hidden: Vec::new(),
            });
        }
        for _ in 0..100 {
            let scale = column_scales(&jac);
            let scaled = DMatrix::from_fn(n, p, |i, j| jac[(i, j)] / scale[j]);
            let svd = scaled.clone().svd(true, true);
            let (u, v_t) = (svd.u.as_ref()?, svd.v_t.as_ref()?);
            let top = svd.singular_values.max();
            let ue = u.transpose() * &e;
            let mut improved = false;
            while lambda < 1e12 {
                let mut step = DVector::zeros(p);
                for (k, &s) in svd.singular_values.iter().enumerate() {
                    if s > IDENTIFIABLE * top {
                        let damped = s / (s * s + lambda * top * top);
                        step += v_t.row(k).transpose() * (ue[k] * damped);
                    }
                }
                let step = step.component_div(&scale);
                let trial = self.apply(&params, &step);
                if let Some((_, e_trial)) = evaluate(&trial, &mut state, &mut jac_row, false) {
                    let rss_trial = e_trial.norm_squared();
                    if rss_trial < rss {
                        let converged = rss - rss_trial <= 1e-10 * rss.max(1e-300);
                        params = trial;
                        rss = rss_trial;
                        // A floor on the damping: steps along directions the data barely see (below a
                        // hundredth of a percent of the best seen) stay damped.
                        lambda = (lambda / 10.0).max(1e-8);
                        improved = !converged;
                        break;
                    }
                }
                lambda *= 10.0;
            }
            if !improved {
                break;
            }
            (jac, e) = evaluate(&params, &mut state, &mut jac_row, true)?;
            rss = e.norm_squared();
        }
        // Rank and covariance at the solution, on the column-scaled Jacobian.
        let scale = column_scales(&jac);
        let scaled = DMatrix::from_fn(n, p, |i, j| jac[(i, j)] / scale[j]);
        let svd = scaled.svd(false, true);
        let v_t = svd.v_t.as_ref()?;
        let top = svd.singular_values.max();
        let mut covariance = DMatrix::zeros(p, p);
        let mut hidden = Vec::new();
        let mut rank = 0;
        for (k, &s) in svd.singular_values.iter().enumerate() {
            let v = v_t.row(k).transpose();
            if s > IDENTIFIABLE * top {
                rank += 1;
                covariance += &v * v.transpose() / (s * s);
            } else {
                // Named in the column-scaled parameters (each column's effect on the points at unit norm), so
                // that a rotation and a translation weigh alike.
                hidden.push((0..p).filter(|&j| v[j].abs() > 0.05).map(|j| (j, v[j])).collect());
            }
        }
        let covariance = DMatrix::from_fn(p, p, |i, j| covariance[(i, j)] / (scale[i] * scale[j]));
        Some(Fit { params, rss, observations: n, rank, covariance, hidden })
    }

    fn apply(&self, params: &Params, step: &DVector<f64>) -> Params {
        let mut next = params.clone();
        let mut k = 0;
        if self.absolute {
            for s in 0..self.data.setups.len() {
                next.translations[s] += Vec3::new(step[k], step[k + 1], step[k + 2]);
                let turn = Vec3::new(step[k + 3], step[k + 4], step[k + 5]);
                // A rotation built from products drifts off orthogonality: project it back.
                next.rotations[s] = nearest_rotation(&(rotation_from_vector(&turn) * params.rotations[s]));
                // The translation follows the rotation about the origin, as d(R y + t) = d x (R y) + dt says.
                k += 6;
            }
            for t in 0..self.data.targets.len() {
                next.targets[t] += Vec3::new(step[k], step[k + 1], step[k + 2]);
                k += 3;
            }
            // A target's turn e is taken in the tool's axes: R_target becomes exp(e) R_target.
            for t in (0..self.data.targets.len()).filter(|&t| self.turn_of[t].is_some()) {
                let turn = Vec3::new(step[k], step[k + 1], step[k + 2]);
                next.turns[t] = nearest_rotation(&(rotation_from_vector(&turn) * params.turns[t]));
                k += 3;
            }
        }
        for values in &mut next.effects {
            for v in values {
                *v += step[k];
                k += 1;
            }
        }
        next
    }

    /// The name of parameter `k` of a fit with `effects`.
    fn parameter_name(&self, k: usize, effects: &[ArmEffect]) -> String {
        let setups = if self.absolute { self.data.setups.len() } else { 0 };
        let axis = ["x", "y", "z"];
        let setup_name = |s: usize| match self.data.setups[s].as_str() {
            "" => "the instrument".to_string(),
            name => format!("set-up {name}"),
        };
        if k < 6 * setups {
            let (s, a) = (k / 6, k % 6);
            return if a < 3 {
                format!("{}'s translation {}", setup_name(s), axis[a])
            } else {
                format!("{}'s rotation about {}", setup_name(s), axis[a - 3])
            };
        }
        let k = k - 6 * setups;
        let targets = if self.absolute { self.data.targets.len() } else { 0 };
        let target_name = |t: usize| match self.data.targets[t].as_str() {
            "" => "the target".to_string(),
            t => format!("target {t}"),
        };
        if k < 3 * targets {
            return format!("{}'s place {}", target_name(k / 3), axis[k % 3]);
        }
        let k = k - 3 * targets;
        let turns = if self.absolute { self.turn_count() } else { 0 };
        if k < 3 * turns {
            let t = self.turn_of.iter().position(|&o| o == Some(k / 3)).expect("a turn's target");
            return format!("{}'s turn about the tool's {}", target_name(t), axis[k % 3]);
        }
        let mut k = k - 3 * turns;
        for e in effects {
            if k < e.size() {
                let part = match e.kind {
                    ArmKind::JointGeometry => {
                        let what = [
                            "translation x",
                            "translation y",
                            "translation z",
                            "rotation x",
                            "rotation y",
                            "rotation z",
                        ];
                        format!(" {}", what[k])
                    }
                    ArmKind::Payload => [" mass", " moment x", " moment y", " moment z"][k].to_string(),
                    ArmKind::FrameCompliance => {
                        let what = ["along x", "along y", "along z", "about x", "about y", "about z"];
                        format!(" {}", what[k])
                    }
                    ArmKind::Drift => [" x", " y", " z"][k].to_string(),
                    ArmKind::ToolCompliance => [" along x", " along y", " along z"][k].to_string(),
                    _ => String::new(),
                };
                return format!("{}{part}", e.label(&self.joints));
            }
            k -= e.size();
        }
        "?".into()
    }

    fn describe_hidden(&self, direction: &[(usize, f64)], effects: &[ArmEffect]) -> String {
        direction
            .iter()
            .map(|(k, w)| format!("{w:+.3} {}", self.parameter_name(*k, effects)))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The value of an accepted effect as a user reads it.
    fn shown(&self, e: &ArmEffect, values: &[f64], ses: &[f64]) -> String {
        let prismatic = self.prismatic[e.joint];
        let (value, se) = (values[0], ses[0]);
        let listed = |values: &[f64], ses: &[f64], scale: f64, digits: usize| {
            let part = |v: f64, s: f64| {
                let number = |x: f64| if x.abs() < 1e6 { format!("{x:.digits$}") } else { format!("{x:.3e}") };
                if s.is_finite() {
                    format!("{} +- {}", number(v * scale), number(s * scale))
                } else {
                    format!("{} (not seen)", number(v * scale))
                }
            };
            values.iter().zip(ses).map(|(v, s)| part(*v, *s)).collect::<Vec<_>>().join(", ")
        };
        match e.kind {
            ArmKind::JointGeometry if self.space.is_none() => format!(
                "the leg's end-point error: translation ({}) mm, rotation ({}) mrad, base axes at the reference point",
                listed(&values[..3], &ses[..3], 1.0, 4),
                listed(&values[3..], &ses[3..], 1e3, 3)
            ),
            ArmKind::JointGeometry => format!(
                "translation ({}) mm, rotation ({}) mrad, in the joint's frame",
                listed(&values[..3], &ses[..3], 1.0, 4),
                listed(&values[3..], &ses[3..], 1e3, 3)
            ),
            ArmKind::Drift => format!("({}) um per row, along the base's x, y, z", listed(values, ses, 1e3, 4)),
            ArmKind::ToolCompliance => {
                format!("({}) um/N along the tool frame's x, y, z", listed(values, ses, 1e3, 4))
            }
            ArmKind::FrameCompliance => format!(
                "compliance along the frame's axes ({}) um/N, about them ({}) urad/(N m)",
                listed(&values[..3], &ses[..3], 1e3, 4),
                listed(&values[3..], &ses[3..], 1e9, 4)
            ),
            ArmKind::Payload => {
                let centre: Vec<f64> = values[1..].iter().map(|s| s / value).collect();
                let centre_se: Vec<f64> = ses[1..].iter().map(|s| s / value.abs()).collect();
                format!(
                    "{} kg at ({}) mm in the tool frame",
                    listed(&values[..1], &ses[..1], 1.0, 3),
                    listed(&centre, &centre_se, 1.0, 1)
                )
            }
            ArmKind::JointOffset | ArmKind::Backlash if prismatic => format!("{} mm", listed(values, ses, 1.0, 4)),
            ArmKind::JointOffset | ArmKind::Backlash => format!("{} mrad", listed(values, ses, 1e3, 3)),
            ArmKind::JointCompliance => {
                let (unit, stiffness_unit, to_user) =
                    if prismatic { ("mm/N", "N/mm", 1.0) } else { ("rad/(N m)", "N m/rad", 1e3) };
                // Scientific notation with the standard error where the data see the value.
                let pm = |v: f64, s: f64, digits: usize| {
                    if s.is_finite() {
                        format!("{v:.digits$e} +- {s:.digits$e}")
                    } else {
                        format!("{v:.digits$e} (not seen)")
                    }
                };
                let added = format!("added compliance {} {unit}", pm(value * to_user, se * to_user, 4));
                match self.nominal_compliance(e.joint) {
                    Some(nominal) => {
                        let total = nominal + value;
                        format!(
                            "{added}: stiffness {} {stiffness_unit} (the model's {:.4e}; factor {} on its compliance)",
                            pm(1.0 / (total * to_user), se / (total * total * to_user), 4),
                            1.0 / (nominal * to_user),
                            listed(&[total / nominal], &[se / nominal], 1.0, 3)
                        )
                    }
                    None => {
                        let k = 1.0 / (value * to_user);
                        format!("{added}: stiffness {k:.4e} {stiffness_unit} (the model has it rigid)")
                    }
                }
            }
        }
    }
}

/// Each column's norm, the scale its parameter is fitted and judged in; a column of zeros (a parameter that
/// moves nothing here) keeps scale 1, so that round-off in the steps is not blown up by dividing by it.
/// The rotation nearest `m` (Frobenius norm): U V^T of its SVD, with the sign that keeps it proper.
fn nearest_rotation(m: &Mat3) -> Mat3 {
    let svd = m.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else { return Mat3::identity() };
    let mut d = Mat3::identity();
    if (u * v_t).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    u * d * v_t
}

fn column_scales(jac: &DMatrix<f64>) -> DVector<f64> {
    DVector::from_iterator(jac.ncols(), jac.column_iter().map(|c| if c.norm() > 0.0 { c.norm() } else { 1.0 }))
}

/// The error statistics of `rows` (unweighted residuals, mm).
fn stats(residuals: &[Option<Vec3>], rows: &[usize]) -> ErrorStats {
    let r: Vec<Vec3> = rows.iter().filter_map(|&k| residuals[k]).collect();
    if r.is_empty() {
        return ErrorStats::default();
    }
    let n = r.len() as f64;
    let mut lengths: Vec<f64> = r.iter().map(|v| v.norm()).collect();
    lengths.sort_by(f64::total_cmp);
    let rms_axis = [0, 1, 2].map(|a| (r.iter().map(|v| v[a] * v[a]).sum::<f64>() / n).sqrt());
    // The 95th percentile by the nearest rank.
    let p95 = lengths[((0.95 * n).ceil() as usize).clamp(1, lengths.len()) - 1];
    ErrorStats {
        rows: r.len(),
        rms_axis,
        rms: (lengths.iter().map(|l| l * l).sum::<f64>() / n).sqrt(),
        p95,
        max: *lengths.last().expect("not empty"),
        max_axis: [0, 1, 2].map(|a| r.iter().map(|v| v[a].abs()).fold(0.0, f64::max)),
    }
}

/// The gross rows among `rows`: weighted misfit beyond `GROSS_FACTOR` robust standard deviations.
fn gross_rows(problem: &Problem, residuals: &[Option<Vec3>], rows: &[usize]) -> Vec<usize> {
    gross_rows_against(problem, residuals, rows, rows)
}

/// The gross rows among `tested`, against the robust scale of the rows `scaled` (a held-out row is judged
/// by the fitted rows' scale). Positions and orientations are judged each against their own kind's scale,
/// so that a stated sigma of one kind that is off does not make the other's rows look gross.
fn gross_rows_against(problem: &Problem, residuals: &[Option<Vec3>], scaled: &[usize], tested: &[usize]) -> Vec<usize> {
    let misfit = |r: usize| residuals[r].map_or(f64::INFINITY, |v| v.norm() * problem.weight[r]);
    let turning = |r: &usize| problem.data.rows[*r].observed.is_orientation();
    let mut gross = Vec::new();
    for kind in [false, true] {
        let mut sorted: Vec<f64> =
            scaled.iter().filter(|r| turning(r) == kind).map(|&r| misfit(r)).filter(|m| m.is_finite()).collect();
        if sorted.len() < 5 {
            continue;
        }
        sorted.sort_by(f64::total_cmp);
        let scale = sorted[sorted.len() / 2] / CHI3_MEDIAN;
        gross.extend(tested.iter().copied().filter(|r| turning(r) == kind && misfit(*r) > GROSS_FACTOR * scale));
    }
    gross.sort_unstable();
    gross
}

/// The test of adding an effect to a fit of residual sum `rss0` (weighted) and rank `rank0`, giving `with`: its F
/// statistic against the residual's own scale, and its p-value; where the noise is known, the larger of the
/// F test's and the chi-square test's of the drop (both must reject: the drop must stand out from what is
/// left and from the noise, so that round-off on noise-free data is never a discovery).
fn test(rss0: f64, rank0: usize, with: &Fit, sigma_known: bool) -> (f64, f64) {
    // The parameters the data see: an effect of several parameters counts the directions it adds.
    let added = with.rank.saturating_sub(rank0).max(1) as f64;
    let drop = (rss0 - with.rss).max(0.0);
    let statistic = drop / added / (with.rss / with.dof() as f64).max(1e-300);
    // Survival functions, not 1 - cdf: strong candidates' p-values are far below 1e-16 and are compared.
    let mut p = FisherSnedecor::new(added, with.dof() as f64).map_or(1.0, |d| d.sf(statistic));
    if sigma_known {
        p = p.max(ChiSquared::new(added).map_or(1.0, |d| d.sf(drop)));
    }
    (statistic, p)
}

/// What a selection ends with: the effects in the model (the fitted ones first, then in the order accepted),
/// its fit, every step's tests and the directions found hidden.
struct Selection {
    model: Vec<ArmEffect>,
    fit: Fit,
    steps: Vec<Vec<Tested>>,
    hidden: Vec<String>,
}

/// Forward selection on `rows`: effects offered one at a time, each step accepting the best one whose F
/// test passes at alpha / the candidates tested.
fn select(
    problem: &Problem,
    rows: &[usize],
    candidates: &[ArmEffect],
    options: &Options,
    sigma_known: bool,
) -> Result<Selection, CalibrationError> {
    let mut model = options.fitted.clone();
    let start = problem.start(rows, &model);
    let too_few =
        || CalibrationError::TooFew("the fit found no pose for a row, or too few rows for the parameters".into());
    let mut fit = problem.fit(rows, &model, &start).ok_or_else(too_few)?;
    let mut steps = Vec::new();
    let mut hidden: Vec<String> = fit.hidden.iter().map(|d| problem.describe_hidden(d, &model)).collect();
    let bic = |f: &Fit| {
        let n = f.observations as f64;
        n * (f.rss / n).max(1e-300).ln() + f.rank as f64 * n.ln()
    };
    // Rounds of forward selection, backward elimination and swaps: an effect chosen early, while the model
    // still missed others, can absorb parts of several and leave each too weak to pass alone; a swap frees
    // them, and the next forward steps take them.
    for _ in 0..3 {
        while model.len() < options.fitted.len() + options.max_effects {
            let mut step = Vec::new();
            let mut best: Option<(f64, f64, ArmEffect, Fit)> = None;
            let untested: Vec<ArmEffect> = candidates.iter().filter(|c| !model.contains(c)).copied().collect();
            let mut tested = 0;
            for c in &untested {
                let mut trial = model.clone();
                trial.push(*c);
                let mut start = fit.params.clone();
                start.effects.push(vec![0.0; c.size()]);
                let label = c.label(&problem.joints);
                let Some(f) = problem.fit(rows, &trial, &start) else {
                    step.push(Tested { label, f: None, p: None, note: Some("a row has no pose with it".into()) });
                    continue;
                };
                if f.rank <= fit.rank {
                    // The candidate's parameters follow the nuisance ones and the model's.
                    let own = problem.nuisance_count() + model.iter().map(ArmEffect::size).sum::<usize>();
                    let own = own..own + c.size();
                    let alone = f.hidden.iter().any(|d| d.len() == 1 && own.contains(&d[0].0));
                    let note = if alone {
                        // Its column is zero: a compliance or play whose joint carries no load (or the same sign of
                        // load in every row, for play), or an offset that moves nothing measured.
                        "moves no measured point in these rows (its joint's load is zero, or of one sign for play)"
                            .into()
                    } else {
                        // The directions that hold the candidate (the model's own hidden ones are reported
                        // once, for the model).
                        let with: Vec<String> = f
                            .hidden
                            .iter()
                            .filter(|d| d.iter().any(|(k, _)| own.contains(k)))
                            .map(|d| problem.describe_hidden(d, &trial))
                            .collect();
                        match with.len() {
                            1 => format!(
                                "not identifiable from these rows: one combination ({}) moves no point",
                                with[0]
                            ),
                            n => format!(
                                "not identifiable from these rows: {n} combinations move no point: ({})",
                                with.join("); (")
                            ),
                        }
                    };
                    step.push(Tested { label, f: None, p: None, note: Some(note) });
                    continue;
                }
                tested += 1;
                let (statistic, p) = test(fit.rss, fit.rank, &f, sigma_known);
                step.push(Tested { label, f: Some(statistic), p: Some(p), note: None });
                // The smallest p-value is the best (it weighs an effect's drop by the directions it adds); the
                // larger F among equal p-values.
                if best.as_ref().is_none_or(|b| p < b.1 || (p == b.1 && statistic > b.0)) {
                    best = Some((statistic, p, *c, f));
                }
            }
            let threshold = options.alpha / tested.max(1) as f64;
            // Accepted when its test passes and the evidence for it is strong (the BIC lower by more than 10,
            // as the other diagnosis asks): an effect of six parameters on few rows must pay for them.
            let accept = best
                .filter(|(_, p, _, f)| *p < threshold && bic(f) < bic(&fit) - STRONG_EVIDENCE)
                .map(|(statistic, _, c, f)| (statistic, c, f));
            steps.push(step);
            match accept {
                Some((_, c, f)) => {
                    model.push(c);
                    // A parallel robot's model completed by its exact misses, against which the next
                    // candidates are judged (`kept_miss`); a serial arm's fit is already exact.
                    fit = match problem.space {
                        None => problem.fit_exact(rows, &model, &f.params).unwrap_or(f),
                        Some(_) => f,
                    };
                }
                None => break,
            }
        }
        // Backward elimination and swaps, until the swaps change nothing (a swap may leave an effect that the
        // others make unnecessary, which the next elimination drops).
        let mut swapped = false;
        for _ in 0..3 {
            // Backward elimination: an effect selected early that later ones make unnecessary (a proxy for the
            // effect found after it) is dropped, the least needed first, while its removal's test does not reject.
            loop {
                let selected = options.fitted.len()..model.len();
                let threshold = options.alpha / selected.len().max(1) as f64;
                let mut weakest: Option<(f64, usize, Fit)> = None;
                for k in selected {
                    let mut without = model.clone();
                    without.remove(k);
                    let mut start = fit.params.clone();
                    start.effects.remove(k);
                    let Some(f) = problem.fit(rows, &without, &start) else { continue };
                    let (_, p) = test(f.rss, f.rank, &fit, sigma_known);
                    if p >= threshold && weakest.as_ref().is_none_or(|w| p > w.0) {
                        weakest = Some((p, k, f));
                    }
                }
                match weakest {
                    Some((_, k, f)) => {
                        model.remove(k);
                        fit = f;
                    }
                    None => break,
                }
            }
            // Swaps: an effect chosen early, while the model still missed others, may do the work of a simpler
            // one (a joint's geometry standing in for the offset of the joint before it): the accepted effect
            // whose replacement by a candidate with fewer parameters lowers the BIC (n ln(rss/n) + rank ln n)
            // most is replaced (or one of as many parameters that explains more).
            let mut best: Option<(f64, usize, ArmEffect, Fit)> = None;
            for k in options.fitted.len()..model.len() {
                for c in candidates.iter().filter(|c| !model.contains(c) && c.size() <= model[k].size()) {
                    let mut swapped = model.clone();
                    swapped[k] = *c;
                    let mut start = fit.params.clone();
                    start.effects[k] = vec![0.0; c.size()];
                    let Some(f) = problem.fit(rows, &swapped, &start) else { continue };
                    let gain = bic(&fit) - bic(&f);
                    if gain > 0.0 && best.as_ref().is_none_or(|b| gain > b.0) {
                        best = Some((gain, k, *c, f));
                    }
                }
            }
            match best {
                Some((_, k, c, f)) => {
                    model[k] = c;
                    fit = f;
                    swapped = true;
                }
                None => break,
            }
        }
        if !swapped {
            break;
        }
    }
    // Each candidate's first reason once (a later step finds the same direction again).
    for t in steps.iter().flatten() {
        if let Some(note) = &t.note {
            if !hidden.iter().any(|h| h.starts_with(&format!("{}: ", t.label))) {
                hidden.push(format!("{}: {}", t.label, note));
            }
        }
    }
    Ok(Selection { model, fit, steps, hidden })
}

/// A parallel robot's rows that give its actuators' readings: each row's pose becomes the rigid robot's at
/// those readings (`Manipulator::pose_at_actuators`), the commanded pose only its start, so that what the
/// controller did not reach is not taken for an effect.
fn at_actuator_readings(m: &Manipulator, data: &PositionData) -> Result<PositionData, CalibrationError> {
    let mut out = data.clone();
    let mut state = m.new_state();
    let mut last: Option<(usize, Frame)> = None;
    for r in &mut out.rows {
        let Some(start) = r.pose.filter(|_| !r.joints.is_empty()) else { continue };
        let pose = match last.filter(|(line, _)| *line == r.line) {
            Some((_, pose)) => pose,
            None => m.pose_at_actuators(&r.joints, &start, &mut state).ok_or_else(|| CalibrationError::Row {
                name: r.name.clone(),
                line: r.line,
                why: "the actuators' readings give no pose near the commanded one (a reading outside the reach, or \
                      far from the commanded pose)"
                    .into(),
            })?,
        };
        last = Some((r.line, pose));
        r.pose = Some(pose);
    }
    Ok(out)
}

/// Calibrates the arm `m` against `data`: registration fitted, effects selected among `candidates` (all
/// of the arm's joints' where empty), gross rows left out, check rows reported.
pub fn calibrate(
    m: &Manipulator,
    data: &PositionData,
    candidates: &[ArmEffect],
    options: &Options,
) -> Result<Calibration, CalibrationError> {
    let solved;
    let data = if m.joint_space.is_none() && data.rows.iter().any(|r| !r.joints.is_empty()) {
        solved = at_actuator_readings(m, data)?;
        &solved
    } else {
        data
    };
    let weighed;
    let data = if data.rows.iter().any(|r| r.payload.is_some()) {
        weighed = data.with_payload_weights(m);
        &weighed
    } else {
        data
    };
    let weighed_orientations = data.without_unweighted_orientations(options.sigma_rad);
    let data = &weighed_orientations;
    let problem = Problem::new(m, data, options.sigma, options.sigma_rad)?;
    let candidates: Vec<ArmEffect> =
        if candidates.is_empty() { problem.default_candidates() } else { candidates.to_vec() };
    if let Some(e) = candidates.iter().chain(&options.fitted).find(|e| !problem.offers(e)) {
        return Err(CalibrationError::NotOffered(format!(
            "{}: {}",
            e.label(&problem.joints),
            if problem.space.is_some() {
                "a serial arm has no such effect"
            } else {
                "a parallel robot's legs are calibrated by joint-offset, joint-compliance and backlash of their \
                 actuators, joint-geometry (the leg's end-point error), payload, tool-compliance and drift; a \
                 compliance at a frame is a serial arm's (for a leg's links, diagnose displacements under load: \
                 link-compliance)"
            }
        )));
    }
    let sigma_known = data.rows.iter().all(|r| {
        r.sigma.is_some()
            || match r.observed {
                Observed::Orientation { .. } => options.sigma_rad.is_some(),
                _ => options.sigma.is_some(),
            }
    });
    let usable = |r: &usize| !problem.unusable.iter().any(|(k, _)| k == r);
    let fit_rows: Vec<usize> = (0..data.rows.len()).filter(|&r| !data.rows[r].check).filter(usable).collect();
    let check_rows: Vec<usize> = (0..data.rows.len()).filter(|&r| data.rows[r].check).filter(usable).collect();
    let (candidates, one_sided) = problem.two_sided_play(candidates, &fit_rows);
    if fit_rows.is_empty() {
        let why: Vec<String> = problem.unusable.iter().map(|(_, why)| why.clone()).collect();
        return Err(CalibrationError::TooFew(format!(
            "no row to fit: every row is held out (set = check) or has no prediction{}",
            if why.is_empty() { String::new() } else { format!(" ({})", why.join("; ")) }
        )));
    }
    // A set-up or target seen only in held-out rows has no registration or place to predict them with.
    for (names, what, of) in [
        (
            &data.setups,
            "set-up",
            (|o: &Observed| o.target_and_setup().map(|(_, setup)| setup)) as fn(&Observed) -> Option<usize>,
        ),
        (&data.targets, "target", |o: &Observed| o.target_and_setup().map(|(target, _)| target)),
    ] {
        for (k, name) in names.iter().enumerate() {
            if !fit_rows.iter().any(|&r| of(&data.rows[r].observed) == Some(k)) {
                let named = if name.is_empty() { format!("the {what}") } else { format!("{what} `{name}`") };
                return Err(CalibrationError::TooFew(format!(
                    "{named} has no fitted rows (only check rows, or rows without a prediction): its {} cannot be fitted; mark some of its rows `fit`",
                    if what == "set-up" { "frame" } else { "place on the tool" }
                )));
            }
        }
    }
    let p = problem.nuisance_count() + options.fitted.iter().map(ArmEffect::size).sum::<usize>();
    if 3 * fit_rows.len() <= p {
        return Err(CalibrationError::TooFew(format!(
            "{} fitted rows give {} coordinates, too few for the {p} parameters of the registration and the effects fitted",
            fit_rows.len(),
            3 * fit_rows.len()
        )));
    }
    // Gross rows: screened against the registration alone (a fit that gross rows pull is screened again),
    // then against the model selected, until the set stops changing.
    let mut gross: Vec<usize> = Vec::new();
    for _ in 0..3 {
        let kept: Vec<usize> = fit_rows.iter().filter(|r| !gross.contains(r)).copied().collect();
        let start = problem.start(&kept, &options.fitted);
        let Some(f) = problem.fit(&kept, &options.fitted, &start) else { break };
        let next = gross_rows(&problem, &problem.residuals(&options.fitted, &f.params), &fit_rows);
        if next == gross {
            break;
        }
        gross = next;
    }
    let mut outcome = None;
    for _ in 0..3 {
        let kept: Vec<usize> = fit_rows.iter().filter(|r| !gross.contains(r)).copied().collect();
        let selection = select(&problem, &kept, &candidates, options, sigma_known)?;
        let next = gross_rows(&problem, &problem.residuals(&selection.model, &selection.fit.params), &fit_rows);
        let settled = next == gross;
        outcome = Some((kept, selection));
        if settled {
            break;
        }
        gross = next;
    }
    let (kept, Selection { mut model, mut fit, steps, mut hidden }) = outcome.expect("at least one selection");
    hidden.extend(one_sided);
    // A joint's geometry holds its offset (a leg's end-point error along its actuator, an arm joint's turn
    // about its own axis). Chosen while other effects were still missing, or with a parallel robot's offset
    // at first order (an offset of 0.5 mm leaves 1 um of second order, which a geometry's other directions
    // absorb), it may stand in for the offset alone: where the offset, each fitted exactly, explains the data
    // as well (the geometry's other directions do not pass at alpha), the offset is kept instead.
    if problem.absolute {
        for k in options.fitted.len()..model.len() {
            let offset = ArmEffect { kind: ArmKind::JointOffset, joint: model[k].joint };
            if model[k].kind != ArmKind::JointGeometry || model.contains(&offset) || !candidates.contains(&offset) {
                continue;
            }
            let mut simpler = model.clone();
            simpler[k] = offset;
            let mut start = fit.params.clone();
            start.effects[k] = vec![0.0];
            let (Some(with_offset), Some(with_geometry)) =
                (problem.fit_exact(&kept, &simpler, &start), problem.fit_exact(&kept, &model, &fit.params))
            else {
                continue;
            };
            let (_, p) = test(with_offset.rss, with_offset.rank, &with_geometry, sigma_known);
            if with_offset.rank > with_geometry.rank.saturating_sub(model[k].size()) && p >= options.alpha {
                model = simpler;
                fit = with_offset;
            }
        }
    }
    // A parallel robot's first order completed (a serial arm's fit is final).
    let fit = match problem.space {
        None => problem.fit_exact(&kept, &model, &fit.params).unwrap_or(fit),
        Some(_) => fit,
    };
    let residuals = problem.residuals(&model, &fit.params);
    // Held-out rows are judged by the same rule against the fitted rows' scale: a gross one is named and left
    // out of the held-out errors too.
    let gross_checks = gross_rows_against(&problem, &residuals, &kept, &check_rows);
    let all_checks = check_rows.clone();
    let check_rows: Vec<usize> = check_rows.into_iter().filter(|r| !gross_checks.contains(r)).collect();
    gross.extend(&gross_checks);
    let scale = (fit.rss / fit.dof() as f64).sqrt();
    let variance = scale * scale;
    let nuisance_count = problem.nuisance_count();
    // A parameter in a direction the data cannot see has no standard error.
    let seen = |k: usize| !fit.hidden.iter().any(|d| d.iter().any(|(j, _)| *j == k));
    let mut k = nuisance_count;
    let mut accepted = Vec::new();
    for (i, e) in model.iter().enumerate() {
        let values = fit.params.effects[i].clone();
        let se: Vec<f64> = (k..k + e.size())
            .map(|j| if seen(j) { (fit.covariance[(j, j)] * variance).sqrt() } else { f64::NAN })
            .collect();
        k += e.size();
        accepted.push(Accepted {
            label: e.label(&problem.joints),
            kind: e.kind,
            joint: match e.kind {
                ArmKind::Payload | ArmKind::Drift | ArmKind::ToolCompliance => String::new(),
                _ => problem.joints[e.joint].clone(),
            },
            shown: problem.shown(e, &values, &se),
            values,
            se,
            confirmed: None,
        });
    }
    let se3 = |k: usize, factor: f64| [0, 1, 2].map(|a| (fit.covariance[(k + a, k + a)] * variance).sqrt() * factor);
    let mut nuisance = Vec::new();
    if problem.absolute {
        for (s, name) in data.setups.iter().enumerate() {
            let label = if name.is_empty() { "instrument".to_string() } else { format!("set-up {name}") };
            let rotation = crate::kinematics::frame::rotation_vector(&fit.params.rotations[s]);
            nuisance.push(Nuisance {
                name: format!("{label}: translation, mm"),
                value: fit.params.translations[s].into(),
                se: se3(6 * s, 1.0),
            });
            nuisance.push(Nuisance {
                name: format!("{label}: rotation vector, mrad"),
                value: (rotation * 1e3).into(),
                se: se3(6 * s + 3, 1e3),
            });
        }
        for (t, name) in data.targets.iter().enumerate() {
            let label = if name.is_empty() { "target".to_string() } else { format!("target {name}") };
            nuisance.push(Nuisance {
                name: format!("{label}: place in the tool frame, mm"),
                value: fit.params.targets[t].into(),
                se: se3(6 * data.setups.len() + 3 * t, 1.0),
            });
            if let Some(k) = problem.turn_parameter(t) {
                let turn = crate::kinematics::frame::rotation_vector(&fit.params.turns[t]);
                nuisance.push(Nuisance {
                    name: format!("{label}: axes in the tool frame, rotation vector, mrad"),
                    value: (turn * 1e3).into(),
                    se: se3(k, 1e3),
                });
            }
        }
    }
    // The rows of `rows` that are orientations (`turning`) or positions and displacements.
    let only = |rows: &[usize], turning: bool| -> Vec<usize> {
        rows.iter().copied().filter(|&k| data.rows[k].observed.is_orientation() == turning).collect()
    };
    let oriented = data.rows.iter().any(|r| r.observed.is_orientation());
    // Errors after the registration alone, then after each effect in the order accepted.
    let mut stages = Vec::new();
    let registration: Vec<ArmEffect> = options.fitted.clone();
    let mut staged = registration.clone();
    let order: Vec<ArmEffect> = model[options.fitted.len()..].to_vec();
    for k in 0..=order.len() {
        if k > 0 {
            staged.push(order[k - 1]);
        }
        let label = if k == 0 {
            let first = if problem.absolute { "registration" } else { "model" };
            match options.fitted.len() {
                0 => first.to_string(),
                n => format!("{first} + {n} fitted"),
            }
        } else {
            format!("+ {}", order[k - 1].label(&problem.joints))
        };
        let f = if k == order.len() {
            Some(fit.clone())
        } else {
            problem.fit_exact(&kept, &staged, &problem.start(&kept, &staged))
        };
        let Some(f) = f else { continue };
        let r = problem.residuals(&staged, &f.params);
        let in_mrad: Vec<Option<Vec3>> = r.iter().map(|v| v.map(|v| v * 1e3)).collect();
        stages.push(Stage {
            model: label,
            parameters: f.rank,
            fit: stats(&r, &only(&kept, false)),
            check: stats(&r, &only(&check_rows, false)),
            check_all: stats(&r, &only(&all_checks, false)),
            orientation: oriented
                .then(|| [stats(&in_mrad, &only(&kept, true)), stats(&in_mrad, &only(&check_rows, true))]),
        });
    }
    if !check_rows.is_empty() && stages.len() == order.len() + 1 {
        for (k, a) in accepted[options.fitted.len()..].iter_mut().enumerate() {
            a.confirmed = Some(stages[k + 1].check.rms < stages[k].check.rms);
        }
    }
    let noisy = sigma_known && ChiSquared::new(fit.dof() as f64).is_ok_and(|d| d.sf(fit.rss) < options.alpha);
    let verdict = match (noisy, model.len() > options.fitted.len()) {
        (true, _) => Verdict::Unexplained,
        (false, true) => Verdict::Effect,
        (false, false) => Verdict::None,
    };
    Ok(Calibration {
        verdict,
        accepted,
        steps,
        nuisance,
        not_identifiable: hidden,
        left_out: gross
            .iter()
            .map(|&r| {
                let turning = data.rows[r].observed.is_orientation();
                GrossRow {
                    row: format!(
                        "{} (line {}{}{})",
                        data.rows[r].name,
                        data.rows[r].line,
                        if data.rows[r].check { ", held out" } else { "" },
                        if turning { ", orientation" } else { "" }
                    ),
                    misfit: residuals[r].map_or(f64::NAN, |v| v.norm()) * if turning { 1e3 } else { 1.0 },
                    unit: if turning { "mrad" } else { "mm" },
                }
            })
            .collect(),
        stages,
        unusable: problem.unusable.iter().map(|(_, why)| why.clone()).collect(),
        residual_scale: scale,
        sigma_known,
        rows: (kept.len(), check_rows.len()),
        unread: data.unread.clone(),
        leg_corrections: problem
            .space
            .is_none()
            .then(|| model.iter().zip(&fit.params.effects).map(|(e, values)| problem.model_form(e, values)).collect()),
    })
}

/// The description (`source`, read from `model_dir`) with the calibration's corrections added, so that every
/// study of the corrected file sees them: offsets, compliances and geometry as `[[joint_correction]]` tables,
/// a payload as `[[payload]]`; play, which no model holds, as a comment.
pub fn corrected_model(source: &str, model_dir: &std::path::Path, c: &Calibration) -> String {
    use std::fmt::Write;
    let mut out = super::report::with_absolute_references(source, model_dir);
    let _ = writeln!(
        out,
        "\n# Added by stiff diagnose (calibration, verdict {}): {}",
        verdict_word(c.verdict),
        if c.accepted.is_empty() {
            "no effect".to_string()
        } else {
            c.accepted.iter().map(|a| a.label.clone()).collect::<Vec<_>>().join(", ")
        }
    );
    for (k, a) in c.accepted.iter().enumerate() {
        if let Some(legs) = &c.leg_corrections {
            match &legs[k] {
                Some(effect) => super::report::write_correction(&mut out, effect),
                None => out.push_str(&leg_not_written(a)),
            }
            continue;
        }
        match a.kind {
            ArmKind::Backlash => {
                let _ = writeln!(
                    out,
                    "\n# {}: {} (not written: a description of a URDF arm holds no play yet)",
                    a.label, a.shown
                );
            }
            ArmKind::Drift => {
                let _ = writeln!(
                    out,
                    "\n# {}: {} (not written: a drift belongs to the measurements, not the robot)",
                    a.label, a.shown
                );
            }
            ArmKind::ToolCompliance => {
                let _ = writeln!(
                    out,
                    "\n# {}: {} (not written: a description of a URDF arm holds no spring at its tool yet)",
                    a.label, a.shown
                );
            }
            ArmKind::FrameCompliance => match spring_compliances(&a.values, &a.se) {
                Some(values) => {
                    if a.values.iter().any(|v| *v < 0.0) {
                        let _ = writeln!(
                            out,
                            "\n# {}: {} (below zero within two standard errors: rigid)",
                            a.label, a.shown
                        );
                    }
                    out.push_str(&correction_table(a.kind, &a.joint, &values));
                }
                None => {
                    let _ = writeln!(
                        out,
                        "\n# {}: {} (not written: a compliance below zero by more than two standard errors is no \
                         spring; fit it with --fit naming fewer effects, or measure more configurations)",
                        a.label, a.shown
                    );
                }
            },
            kind => out.push_str(&correction_table(kind, &a.joint, &a.values)),
        }
    }
    out
}

/// A parallel robot's accepted effect that no description holds (`model_form` gives none), as a comment
/// saying why it is not written.
fn leg_not_written(a: &Accepted) -> String {
    let why = match a.kind {
        ArmKind::JointCompliance => {
            "the leg's actuator has no spring to scale, or its compliance would fall below zero"
        }
        ArmKind::Payload => "a payload's mass must be above zero",
        ArmKind::JointGeometry => "a description holds no leg's end-point error; stiff assemble takes it",
        ArmKind::Backlash => "a description holds no play yet",
        ArmKind::Drift => "a drift belongs to the measurements, not the robot",
        _ => "a description holds no spring there",
    };
    format!("\n# {}: {} (not written: {why})\n", a.label, a.shown)
}

/// Fitted compliances as a spring's: a value below zero within two standard errors (or not seen) is zero,
/// rigid in that direction; None where one is below zero by more.
fn spring_compliances(values: &[f64], se: &[f64]) -> Option<Vec<f64>> {
    values
        .iter()
        .zip(se.iter().map(Some).chain(std::iter::repeat(None)))
        .map(|(v, se)| match (*v >= 0.0, se.filter(|s| s.is_finite())) {
            (true, _) => Some(*v),
            (false, Some(s)) if *v >= -2.0 * s => Some(0.0),
            (false, None) => Some(0.0),
            _ => None,
        })
        .collect()
}

/// One effect as the description's table: `[[joint_correction]]` for an offset, compliance, geometry or
/// frame compliance, `[[payload]]` for a payload (`values` its mass and first moment in the tool frame);
/// play has none.
pub fn correction_table(kind: ArmKind, joint: &str, values: &[f64]) -> String {
    let list = |v: &[f64]| v.iter().map(|x| format!("{x:?}")).collect::<Vec<_>>().join(", ");
    match kind {
        ArmKind::JointOffset => format!("\n[[joint_correction]]\njoint = {joint:?}\noffset = {:?}\n", values[0]),
        ArmKind::JointCompliance => format!("\n[[joint_correction]]\njoint = {joint:?}\ncompliance = {:?}\n", values[0]),
        ArmKind::JointGeometry => format!(
            "\n# The directions the data did not see are kept at the fit's smallest change.\n[[joint_correction]]\njoint = {joint:?}\ngeometry = [{}]\n",
            list(values)
        ),
        ArmKind::Payload => {
            let centre: Vec<f64> = values[1..].iter().map(|s| s / values[0]).collect();
            format!("\n[[payload]]\nmass_kg = {:?}\ncentre = [{}]\n", values[0], list(&centre))
        }
        ArmKind::FrameCompliance => {
            format!("\n[[joint_correction]]\njoint = {joint:?}\nframe_compliance = [{}]\n", list(values))
        }
        ArmKind::Backlash | ArmKind::Drift | ArmKind::ToolCompliance => String::new(),
    }
}

fn verdict_word(v: Verdict) -> &'static str {
    match v {
        Verdict::None => "none",
        Verdict::Effect => "effect",
        Verdict::Unexplained => "unexplained",
    }
}

/// The calibration as text: the verdict, the effects with values, the registration, what could not be
/// seen, the gross rows, and the errors of fit and check rows per stage.
pub fn text(c: &Calibration, model: &str) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let verdict = verdict_word(c.verdict);
    let _ = writeln!(s, "Calibration of {model}: {} rows fitted, {} held out", c.rows.0, c.rows.1);
    if let Some(last) = c.stages.last() {
        if let Some([fit, check]) = &last.orientation {
            let _ = writeln!(
                s,
                "  (each a position or an orientation: {} and {} fitted, {} and {} held out, gross rows left out)",
                last.fit.rows, fit.rows, last.check.rows, check.rows
            );
        }
    }
    if !c.unread.is_empty() {
        let _ = writeln!(s, "columns not read (no rule uses them): {}", c.unread.join(", "));
    }
    let _ = writeln!(s, "verdict: {verdict}");
    if c.accepted.is_empty() {
        let _ = writeln!(s, "effects: none needed");
    }
    for a in &c.accepted {
        let held_out = match a.confirmed {
            Some(true) => "; the held-out rows confirm it (their RMS error falls)",
            Some(false) => "; NOT confirmed: the held-out rows' RMS error grows with it",
            None => "",
        };
        let _ = writeln!(s, "effect: {}: {}{held_out}", a.label, a.shown);
    }
    let _ = writeln!(
        s,
        "residual: {:.4} {} per coordinate after the fit{}",
        c.residual_scale,
        if c.sigma_known { "sigma" } else { "mm" },
        if c.sigma_known { "" } else { " (the noise level was not given: no test of what is left)" }
    );
    for n in &c.nuisance {
        let _ = writeln!(
            s,
            "fitted {}: {:.4} {:.4} {:.4} (+- {:.2e} {:.2e} {:.2e})",
            n.name, n.value[0], n.value[1], n.value[2], n.se[0], n.se[1], n.se[2]
        );
    }
    for h in &c.not_identifiable {
        let _ = writeln!(s, "not identifiable: {h}");
    }
    for why in &c.unusable {
        let _ = writeln!(s, "row left out, no prediction: {why}");
    }
    for g in &c.left_out {
        let _ = writeln!(s, "gross row left out: {}: {:.4} {} from the model", g.row, g.misfit, g.unit);
    }
    for (k, step) in c.steps.iter().enumerate() {
        let mut tested: Vec<&Tested> = step.iter().filter(|t| t.f.is_some()).collect();
        tested.sort_by(|a, b| a.p.partial_cmp(&b.p).unwrap_or(std::cmp::Ordering::Equal));
        let best: Vec<String> = tested
            .iter()
            .take(3)
            .map(|t| format!("{} F {:.3} p {:.2e}", t.label, t.f.unwrap_or(f64::NAN), t.p.unwrap_or(f64::NAN)))
            .collect();
        let _ = writeln!(s, "step {}: {} candidates tested; best {}", k + 1, tested.len(), best.join(", "));
    }
    let _ = writeln!(s, "position error, mm (check: held out; all: held out with its gross rows):");
    let _ =
        writeln!(s, "                                   rows      rms_x    rms_y    rms_z    rms      p95      max");
    for st in &c.stages {
        let with_gross = if st.check_all.rows > st.check.rows { st.check_all.rows } else { 0 };
        for (set, e) in [("fit", &st.fit), ("check", &st.check), ("all", &st.check_all)] {
            if e.rows == 0 || (set == "all" && with_gross == 0) {
                continue;
            }
            stage_line(&mut s, st, set, e);
        }
    }
    if c.stages.iter().any(|st| st.orientation.is_some()) {
        let _ = writeln!(s, "orientation error, mrad (the rotation vector from measured to predicted):");
        let _ = writeln!(
            s,
            "                                   rows      rms_x    rms_y    rms_z    rms      p95      max"
        );
        for st in &c.stages {
            for (set, e) in ["fit", "check"].iter().zip(st.orientation.iter().flatten()) {
                if e.rows > 0 {
                    stage_line(&mut s, st, set, e);
                }
            }
        }
    }
    s
}

/// One line of the table of errors per stage.
fn stage_line(s: &mut String, st: &Stage, set: &str, e: &ErrorStats) {
    use std::fmt::Write;
    let _ = writeln!(
        s,
        "  {:<28} {:<5} {:>5} {:8.4} {:8.4} {:8.4} {:8.4} {:8.4} {:8.4}",
        format!("{} ({} par.)", st.model, st.parameters),
        set,
        e.rows,
        e.rms_axis[0],
        e.rms_axis[1],
        e.rms_axis[2],
        e.rms,
        e.p95,
        e.max
    );
}

/// What `stiff synth` hides in joint-space data beyond the robot's changes (which the model it is given
/// carries, as `[[joint_correction]]` and `[[payload]]`): the instrument's frame, the target, noise, gross
/// rows and held-out rows.
#[derive(Clone, Debug)]
pub struct PositionSynth {
    /// The instrument's frame in each set-up (it is moved between them): a base point p is seen at R p + t,
    /// R from the rotation vector (rad), t in mm. The configurations are measured in that many contiguous
    /// blocks, one per set-up; none: the base frame itself.
    pub setups: Vec<(Vec3, Vec3)>,
    /// The target in the tool frame, mm.
    pub target: Vec3,
    /// Standard deviation of the noise per coordinate, mm.
    pub noise: f64,
    /// The fraction of rows made gross, and by how far (mm, along a random direction).
    pub gross: (f64, f64),
    /// Every this many configurations is a `check` row (0: none).
    pub check_every: usize,
    /// The measurements' drift: the target seen moved by this much per row written (mm, base frame axes).
    pub drift: Vec3,
    /// Where the target's orientation is measured too: its axes in the tool frame (a rotation vector, rad)
    /// and the noise about each axis (rad).
    pub orientation: Option<(Vec3, f64)>,
    /// Play per joint (rad, or mm for a prismatic joint; empty: none), which no description holds: at each
    /// configuration the joint's model coordinate sits this far off in the sense of the load it carries
    /// there (`backlash:J`'s model, `ArmStatics::loads` at the commanded angles).
    pub play: Vec<f64>,
    /// The seed of the noise, gross rows and directions.
    pub seed: u64,
}

/// One configuration to measure: its name, the controller's angles and the wrench at the reference point.
pub type Configuration = (String, Vec<f64>, Vec6);

/// The configurations of a points file's joint rows (in the arm's order): each row's name (`c` and its
/// index where it has none), angles and wrench (zero where it gives none).
pub fn configurations(points: &[crate::model::grid::PosePoint]) -> Vec<Configuration> {
    points
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let name = p.name.clone().filter(|n| !n.is_empty()).unwrap_or_else(|| format!("c{k}"));
            (name, p.joints.clone(), p.wrench.unwrap_or_else(Vec6::zeros))
        })
        .collect()
}

/// What measuring a target's position (and orientation) at each candidate configuration would tell a
/// calibration, to first order about the nominal arm: the derivative of the three coordinates (and three
/// rotations) in every parameter, weighted by 1/noise.
pub struct Signatures {
    /// The candidates with a prediction (the others have no loaded equilibrium), as indices into the
    /// configurations given.
    pub usable: Vec<usize>,
    /// Rows per usable candidate: 3 (a position), or 6 (a position, then an orientation).
    pub rows_per_candidate: usize,
    /// The registration's and the target's columns (9, or 12 with the target's axes): fitted in every
    /// calibration.
    pub nuisance: DMatrix<f64>,
    /// Each effect's label and columns.
    pub effects: Vec<(String, DMatrix<f64>)>,
}

/// The signatures (`Signatures`) of `effects` (where empty: the effects `calibrate` offers by default, play
/// where the candidates load its joint both ways) at `configurations`, one instrument and one target; with
/// `orientation_noise` (rad), the target's orientation measured too. `poses`: a parallel robot's commanded
/// pose for each configuration (its joints empty).
pub fn signatures(
    m: &Manipulator,
    configurations: &[Configuration],
    poses: Option<&[Frame]>,
    effects: &[ArmEffect],
    noise: f64,
    orientation_noise: Option<f64>,
) -> Result<Signatures, CalibrationError> {
    let mut state = m.new_state();
    let mut rows = Vec::with_capacity(configurations.len());
    for (k, (name, joints, wrench)) in configurations.iter().enumerate() {
        // Where the nominal robot puts the target (its tool point, its axes the tool's): the registration's
        // and the target's starts are then the identity, the point about which the first order is taken.
        let pose = poses.map(|p| p[k]);
        let frame = pose.or_else(|| m.pose_at_joints(joints, &mut state));
        let row = |observed: Observed, sigma: f64| PositionRow {
            name: name.clone(),
            line: k + 2,
            joints: joints.clone(),
            pose,
            wrench: *wrench,
            observed,
            sigma: Some(sigma),
            check: false,
            gravity: None,
            configuration: k,
            payload: None,
        };
        let at = frame.map_or(Vec3::zeros(), |f| f.pos);
        rows.push(row(Observed::Position { target: 0, setup: 0, at }, noise));
        if let Some(sigma) = orientation_noise {
            let at = frame.map_or(Mat3::identity(), |f| f.rot);
            rows.push(row(Observed::Orientation { target: 0, setup: 0, at }, sigma));
        }
    }
    let data = PositionData {
        rows,
        targets: vec![String::new()],
        setups: vec![String::new()],
        configurations: configurations.len(),
        unread: Vec::new(),
        orientation_columns: Vec::new(),
    };
    let problem = Problem::new(m, &data, Some(noise), orientation_noise)?;
    // A configuration is usable where its rows have a prediction (its position and orientation share one
    // equilibrium); the rows of each usable one follow each other.
    let per = if orientation_noise.is_some() { 2 } else { 1 };
    let usable: Vec<usize> =
        (0..configurations.len()).filter(|c| !problem.unusable.iter().any(|(k, _)| k / per == *c)).collect();
    let usable_rows: Vec<usize> = usable.iter().flat_map(|c| per * c..per * c + per).collect();
    let effects = if effects.is_empty() {
        problem.two_sided_play(problem.default_candidates(), &usable_rows).0
    } else {
        effects.to_vec()
    };
    let params = problem.start(&usable_rows, &effects);
    let p = problem.nuisance_count() + effects.iter().map(ArmEffect::size).sum::<usize>();
    let mut all = DMatrix::zeros(3 * usable_rows.len(), p);
    let mut row = DMatrix::zeros(3, p);
    for (i, &r) in usable_rows.iter().enumerate() {
        problem.predict(r, &effects, &params, &mut state, Some(&mut row)).ok_or_else(|| CalibrationError::Row {
            name: data.rows[r].name.clone(),
            line: data.rows[r].line,
            why: "the joint coordinates give no finite pose".into(),
        })?;
        all.view_mut((3 * i, 0), (3, p)).copy_from(&row);
    }
    let nuisance = problem.nuisance_count();
    let mut at = nuisance;
    let effects = effects
        .iter()
        .map(|e| {
            let block = all.columns(at, e.size()).into_owned();
            at += e.size();
            (e.label(&problem.joints), block)
        })
        .collect();
    Ok(Signatures { usable, rows_per_candidate: 3 * per, nuisance: all.columns(0, nuisance).into_owned(), effects })
}

/// The controller's angles at which the arm sits when commanded to `commanded` with `play` per joint: each
/// joint's model coordinate moved by its play in the sense of the load it carries there (none where that
/// load is round-off); None where the statics or the controller's map fail there.
fn with_play(
    m: &Manipulator,
    commanded: &[f64],
    wrench: &Vec6,
    play: &[f64],
    state: &mut ManipulatorState,
) -> Option<Vec<f64>> {
    let space = m.joint_space.as_ref()?;
    let statics = m.arm_statics(commanded, wrench, state)?;
    let mut q = space.model_coordinates(commanded);
    for (j, b) in play.iter().enumerate() {
        let load = load_of(&statics, j);
        if load != 0.0 {
            q[j] += b * load.signum();
        }
    }
    space.controller_angles(&q)
}

/// One synthetic row: the configuration's index, the measured target (mm) and its orientation where
/// measured, whether it was made gross, whether it is held out, and its set-up.
pub type SynthRow = (usize, (Vec3, Option<Mat3>), bool, bool, usize);

/// Joint-space measurements of `m` (the robot as it really is: its offsets, compliances, geometry and payload
/// built into the description) at the controller's angles of each configuration: the target where the arm's
/// loaded equilibrium under its own weight and the configuration's wrench puts it, seen in the instrument's
/// frame, with noise and gross rows. A configuration without a loaded equilibrium is left out and counted.
pub fn synthesize_positions(
    m: &Manipulator,
    configurations: &[Configuration],
    s: &PositionSynth,
) -> Result<(Vec<SynthRow>, usize), CalibrationError> {
    if m.joint_space.is_none() {
        return Err(CalibrationError::NotAnArm(m.name.clone()));
    }
    let compliant = m.legs.iter().any(|l| l.spring_groups().next().is_some());
    let mut state = m.new_state();
    Ok(measured_rows(configurations, s, |(_, commanded, wrench)| {
        let played;
        let joints = if s.play.iter().any(|b| *b != 0.0) {
            played = with_play(m, commanded, wrench, &s.play, &mut state)?;
            &played
        } else {
            commanded
        };
        let frame = m.pose_at_joints(joints, &mut state)?;
        if !compliant {
            return Some(frame);
        }
        m.place(&frame, &mut state).ok()?;
        m.deflect(&frame, wrench, None, &mut state).ok().filter(|d| d.stable).map(|d| d.pose)
    }))
}

/// A parallel robot's measurements at commanded poses (`poses`, one per configuration, whose joints are
/// empty): `real` (the robot with the hidden changes built in: actuator offsets, spring scalings, a payload)
/// has its actuators placed by the inverse kinematics for the commanded pose and settles under the
/// configuration's wrench and its payload's weight; its target is seen as `synthesize_positions` sees a
/// serial arm's. Play is not made here (`s.play` is not read).
pub fn synthesize_leg_positions(
    real: &Manipulator,
    configurations: &[Configuration],
    poses: &[Frame],
    s: &PositionSynth,
) -> (Vec<SynthRow>, usize) {
    let mut state = real.new_state();
    let mut next = poses.iter();
    measured_rows(configurations, s, |(_, _, wrench)| {
        let pose = next.next()?;
        real.place(pose, &mut state).ok()?;
        real.deflect(pose, wrench, None, &mut state).ok().filter(|d| d.stable).map(|d| d.pose)
    })
}

/// The rows of `configurations` where `measure` puts the reference point (None: left out and counted), the
/// target seen by the instrument of its set-up with noise, gross rows, drift and held-out rows as `s` says.
fn measured_rows(
    configurations: &[Configuration],
    s: &PositionSynth,
    mut measure: impl FnMut(&Configuration) -> Option<Frame>,
) -> (Vec<SynthRow>, usize) {
    use super::synth::normal as standard_normal;
    use rand::{Rng, SeedableRng};
    let setups: Vec<(Mat3, Vec3)> = match s.setups.is_empty() {
        true => vec![(Mat3::identity(), Vec3::zeros())],
        false => s.setups.iter().map(|(r, t)| (rotation_from_vector(r), *t)).collect(),
    };
    let (mut rows, mut skipped) = (Vec::new(), 0);
    for (k, configuration) in configurations.iter().enumerate() {
        let mut r = rand::rngs::StdRng::seed_from_u64(crate::batch::point_seed(s.seed, k as u64));
        let Some(loaded) = measure(configuration) else {
            skipped += 1;
            continue;
        };
        let setup = k * setups.len() / configurations.len();
        let (rotation, translation) = setups[setup];
        let drifted = s.drift * rows.len() as f64;
        let mut at = rotation * (loaded.pos + loaded.rot * s.target + drifted) + translation;
        for a in 0..3 {
            at[a] += s.noise * standard_normal(&mut r);
        }
        let gross = r.random_bool(s.gross.0.clamp(0.0, 1.0));
        if gross {
            let d = Vec3::new(standard_normal(&mut r), standard_normal(&mut r), standard_normal(&mut r));
            at += d.normalize() * s.gross.1;
        }
        // The target's axes seen turned by the noise: exp(n) R R_tool R_axes, n normal per axis.
        let seen = s.orientation.map(|(axes, noise)| {
            let n = Vec3::from_fn(|_, _| noise * standard_normal(&mut r));
            rotation_from_vector(&n) * rotation * loaded.rot * rotation_from_vector(&axes)
        });
        let held = s.check_every > 0 && k % s.check_every == s.check_every - 1;
        rows.push((k, (at, seen), gross, held, setup));
    }
    (rows, skipped)
}
