//! What a calibration's rows need from the model, computed once (`PositionProblem::new`): each row's
//! statics (a serial arm's at its controller angles, a parallel robot's at its commanded pose, its legs'
//! actuators read as joints), the model's own deflection and tangent compliance there, the rows' weights;
//! and what the problem offers: its candidates, its nuisance parameters (set-ups, targets, turns).

use super::effect::{effect_gain, ArmEffect, ArmKind};
use super::options::CalibrationError;
use crate::diagnose::positions::{Observed, PositionData, PositionRow};
use crate::kinematics::frame::{Frame, Mat6, Vec3, Vec6};
use crate::platform::manipulator::{ArmStatics, Manipulator, ManipulatorState};

/// Rows each way of a joint's load that its play needs to be offered (`two_sided_play`).
const MIN_PLAY_ROWS: usize = 3;

/// A parallel robot's statics at a commanded pose, read as a serial arm's are, its legs' actuators for
/// joints: per actuator, the platform's twist per unit of its offset, C K_i a_i (the end-point error a_i of
/// leg i seen through the other legs, paper 000 eq 60), and the load it carries, a_i . K_i C w (power
/// conjugate to a_i; w the row's wrench with the payload's weight, at the reference point); and at zero
/// wrench where `zero` asks. Also each leg's C K_i (the platform's twist per unit end-point error) and its
/// actuator twist a_i. First order about the unloaded commanded pose; what the load's change of C and K_i
/// and the effects' own second order leave is completed by `PositionProblem::exact_misses`.
pub(super) fn platform_statics(
    m: &Manipulator,
    pose: &Frame,
    wrench: &Vec6,
    zero: Option<&Vec6>,
    state: &mut ManipulatorState,
) -> Result<PlatformStatics, String> {
    let model = crate::diagnose::measurement::PoseModel::at(m, pose, state).map_err(|e| e.to_string())?;
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
pub(super) struct PlatformStatics {
    pub(super) statics: ArmStatics,
    pub(super) zero: Option<ArmStatics>,
    /// Each leg's C K_i.
    pub(super) moves: Vec<Mat6>,
    /// Each leg's actuator twist a_i.
    pub(super) actuators: Vec<Vec6>,
}

/// What each row needs from the model, computed once: the model's own deflection (the twist of the
/// reference point under the row's loads from its springs; for a displacement row, minus that at zero
/// wrench).
pub(super) struct PositionProblem<'a> {
    pub(super) m: &'a Manipulator,
    /// The manipulator under each gravity direction the rows give (a base that is not level) and at each
    /// tip of a tree they measure, and which of them each row is measured by (None: `m`).
    pub(super) tilted: Vec<(RowArm, Manipulator)>,
    pub(super) tilt_of: Vec<Option<usize>>,
    /// A serial arm's joint space; None for a parallel robot, whose rows give commanded poses and whose
    /// "joints" are its legs' actuators.
    pub(super) space: Option<&'a crate::platform::manipulator::JointSpace>,
    pub(super) data: &'a PositionData,
    /// The joints' names: a serial arm's, or a parallel robot's legs by number (1-based, as `[[actuator_offset]]`
    /// and the diagnosis's effects name them).
    pub(super) joints: Vec<String>,
    /// Per row of a parallel robot, each leg's C K_i: the platform's twist per unit end-point error of the
    /// leg (paper 000 eq 60); empty for a serial arm.
    pub(super) leg_moves: Vec<Vec<Mat6>>,
    pub(super) deflection: Vec<Vec6>,
    /// Rows without a prediction (no loaded equilibrium there), and why.
    pub(super) unusable: Vec<(usize, String)>,
    /// Per row, the arm's statics at its configuration (and at zero wrench for a displacement).
    pub(super) statics: Vec<(ArmStatics, Option<ArmStatics>)>,
    /// Per row, the model's tangent compliance at its loaded equilibrium (positions of a compliant model).
    pub(super) compliance: Vec<Option<crate::kinematics::frame::Mat6>>,
    pub(super) weight: Vec<f64>,
    pub(super) absolute: bool,
    pub(super) prismatic: Vec<bool>,
    /// Per target, the index of its turn among the fitted ones (None: its orientation is not measured).
    pub(super) turn_of: Vec<Option<usize>>,
    /// Per row of a serial arm, an earlier position row whose prediction it shares (`repeats`).
    pub(super) repeat_of: Vec<Option<usize>>,
    /// Per row, some later row shares its prediction.
    pub(super) repeated: Vec<bool>,
    /// A parallel robot's misses of its first order, per set of effects (`exact_misses`).
    pub(super) misses: std::sync::RwLock<Vec<(Vec<ArmEffect>, Vec<Vec6>)>>,
    /// A serial arm's description rebuilt with corrections (`CalibrationOptions::rebuild`), for its exact
    /// misses; None: the effects stay first order.
    pub(super) rebuild: Option<super::options::Rebuild>,
    /// Counts the fits and names the selection's steps (`CalibrationOptions::progress`).
    pub(super) progress: Option<indicatif::ProgressBar>,
}

impl<'a> PositionProblem<'a> {
    /// The problem of calibrating `m` against `data`, rows weighted by their own sigma or the one given for
    /// their kind (positions `sigma`, orientations `sigma_rad`).
    pub(super) fn new(
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
        let tips = row_tips(m, data)?;
        let (tilted, tilt_of) = row_arms(m, data, &tips);
        let arm_of = |k: usize| tilt_of[k].map_or(m, |t| &tilted[t].1);
        // One state for every row, in the rows' order: each placement starts from the last.
        let mut state = m.new_state();
        let Deflections { deflection, compliance, mut unusable } =
            deflections(m, data, (&arm_of, &tilt_of), &mut state);
        let RowStatics { statics, leg_moves, mut prismatic } =
            row_statics(m, data, (&arm_of, &tilt_of), &mut unusable, &mut state)?;
        let joints = joint_names(m);
        prismatic.resize(joints.len(), false);
        let weight = weights(data, sigma, sigma_rad);
        let repeat_of = match space {
            Some(_) => repeats(data, &tilt_of, &weight, &deflection),
            None => vec![None; data.rows.len()],
        };
        Ok(PositionProblem {
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
            repeated: {
                let mut repeated = vec![false; repeat_of.len()];
                repeat_of.iter().flatten().for_each(|&k| repeated[k] = true);
                repeated
            },
            repeat_of,
            absolute: data.absolute(),
            prismatic,
            turn_of: turns_of(data),
            misses: std::sync::RwLock::new(Vec::new()),
            rebuild: None,
            progress: None,
        })
    }
}

impl PositionProblem<'_> {
    /// The candidates without the play of a joint whose load keeps one sign in nearly every row of `rows`:
    /// play is told from an offset (or from nothing, in a displacement) only by rows loading the joint both
    /// ways, at least `MIN_PLAY_ROWS` and a tenth of the rows each way; with fewer it would fit a few rows'
    /// misfit. Returns the candidates kept and a note for each left out.
    pub(super) fn two_sided_play(&self, candidates: Vec<ArmEffect>, rows: &[usize]) -> (Vec<ArmEffect>, Vec<String>) {
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
    pub(super) fn arm(&self, r: usize) -> &Manipulator {
        self.tilt_of[r].map_or(self.m, |t| &self.tilted[t].1)
    }

    /// Nuisance parameters: per set-up a translation and a rotation, per target a place on the tool.
    /// The effects offered where none are named: every joint's offset, compliance, play and geometry and the
    /// payload for positions; compliance and play for displacements (which see no geometry).
    pub(super) fn default_candidates(&self) -> Vec<ArmEffect> {
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
    pub(super) fn default_leg_candidates(&self) -> Vec<ArmEffect> {
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
    pub(super) fn offers(&self, e: &ArmEffect) -> bool {
        self.space.is_some() || e.kind != ArmKind::FrameCompliance
    }

    /// The model's compliance of joint `j` along (about) its axis, where it has a spring there: a serial
    /// arm's joint, a parallel robot's leg's actuator.
    pub(super) fn nominal_compliance(&self, j: usize) -> Option<f64> {
        match self.space {
            Some(_) => self.m.joint_compliance(&self.joints[j]),
            None => self.m.legs[j].actuator_compliance(),
        }
    }

    pub(super) fn nuisance_count(&self) -> usize {
        if self.absolute {
            6 * self.data.setups.len() + 3 * self.data.targets.len() + 3 * self.turn_count()
        } else {
            0
        }
    }

    /// How many targets' turns are fitted (those whose orientation is measured).
    pub(super) fn turn_count(&self) -> usize {
        self.turn_of.iter().flatten().count()
    }

    /// The index of the first parameter of target `t`'s turn.
    pub(super) fn turn_parameter(&self, t: usize) -> Option<usize> {
        self.turn_of[t].map(|k| 6 * self.data.setups.len() + 3 * self.data.targets.len() + 3 * k)
    }

    /// A row's statics at controller angles `joints` under its wrench, and at zero wrench for a displacement.
    pub(super) fn statics_at(
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
    pub(super) fn measured(&self, r: usize) -> Vec3 {
        match self.data.rows[r].observed {
            Observed::Position { at, .. } => at,
            Observed::Orientation { .. } => Vec3::zeros(),
            Observed::Displacement(d) => d,
        }
    }
}

/// Per row, an earlier position row measured again (the same configuration, wrench, gravity, arm, target,
/// set-up, weight and model deflection): a serial arm predicts both alike (but for a drift, which moves with
/// the row's line), so a fit predicts a repeated measurement once.
pub(super) fn repeats(
    data: &PositionData,
    arm_of: &[Option<usize>],
    weight: &[f64],
    deflection: &[Vec6],
) -> Vec<Option<usize>> {
    let mut first: std::collections::HashMap<Vec<u64>, usize> = std::collections::HashMap::new();
    data.rows
        .iter()
        .enumerate()
        .map(|(r, row)| {
            let Observed::Position { target, setup, .. } = row.observed else { return None };
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
            let mut key =
                vec![row.configuration as u64, target as u64, setup as u64, arm_of[r].map_or(0, |a| a as u64 + 1)];
            key.extend(bits(&row.joints));
            key.extend(bits(row.wrench.as_slice()));
            key.extend(bits(row.gravity.map_or([f64::NAN; 3], |g| [g.x, g.y, g.z]).as_slice()));
            key.extend(bits(&[weight[r]]));
            key.extend(bits(deflection[r].as_slice()));
            match first.entry(key) {
                std::collections::hash_map::Entry::Occupied(k) => Some(*k.get()),
                std::collections::hash_map::Entry::Vacant(v) => {
                    v.insert(r);
                    None
                }
            }
        })
        .collect()
}

/// What a row is measured by, where it is not `m` itself: gravity along another direction (a base that is
/// not level) and the tip of a tree its target is on (0: the first).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct RowArm {
    gravity: Option<Vec3>,
    tip: usize,
}

impl RowArm {
    /// `m` measured so: under this gravity direction, at this tip.
    pub(super) fn of(&self, m: &Manipulator) -> Manipulator {
        let tilted = self.gravity.map_or_else(|| m.clone(), |g| m.with_gravity_direction(&g));
        match self.tip {
            0 => tilted,
            tip => tilted.at_tip(&m.tips()[tip]).expect("a tip of the model"),
        }
    }
}

/// Per row, the tip of a tree its target is on (the index among `m`'s tips; 0 for a manipulator with one
/// reference point, and for a displacement, which is the reference point's): a target names its tip by
/// its name, the tip's link name or that name, `/` and a label (`hand_l/marker2`; a group suffix's leading
/// `_` is not read: `mx_hand_l_mm`). A target of a tree that names no tip is an error, naming the tips.
pub(super) fn row_tips(m: &Manipulator, data: &PositionData) -> Result<Vec<usize>, CalibrationError> {
    let tips = m.tips();
    if tips.len() < 2 {
        return Ok(vec![0; data.rows.len()]);
    }
    let tip_of = |name: &str| {
        let name = name.trim_start_matches('_');
        tips.iter().position(|t| name == t || name.strip_prefix(t.as_str()).is_some_and(|rest| rest.starts_with('/')))
    };
    let of_target = data
        .targets
        .iter()
        .map(|t| {
            tip_of(t).ok_or_else(|| {
                CalibrationError::NotOffered(format!(
                    "target `{t}`: {} is a tree with several tips ({}), and a target names the tip it is on: name it `<tip>` or `<tip>/<label>` (a `target` cell, or the suffix of mx<suffix>_mm)",
                    m.name,
                    tips.join(", ")
                ))
            })
        })
        .collect::<Result<Vec<usize>, _>>()?;
    Ok(data.rows.iter().map(|r| r.observed.target_and_setup().map_or(0, |(t, _)| of_target[t])).collect())
}

/// The manipulator each row is measured by where it is not `m` itself (gravity along another direction,
/// another tip of a tree: `RowArm`), each once, and which of them each row is measured by (None: `m`).
pub(super) fn row_arms(
    m: &Manipulator,
    data: &PositionData,
    tips: &[usize],
) -> (Vec<(RowArm, Manipulator)>, Vec<Option<usize>>) {
    let mut arms: Vec<(RowArm, Manipulator)> = Vec::new();
    let arm_of = data
        .rows
        .iter()
        .zip(tips)
        .map(|(r, &tip)| {
            let key = RowArm { gravity: r.gravity, tip };
            (key != RowArm { gravity: None, tip: 0 }).then(|| match arms.iter().position(|(k, _)| *k == key) {
                Some(k) => k,
                None => {
                    arms.push((key, key.of(m)));
                    arms.len() - 1
                }
            })
        })
        .collect();
    (arms, arm_of)
}

/// A row's failure, located.
pub(super) fn failed(r: &PositionRow, why: String) -> CalibrationError {
    CalibrationError::Row { name: r.name.clone(), line: r.line, why }
}

/// The rows of one line of the file (several targets, a position and its orientation) share its
/// configuration, wrench and gravity: their equilibrium and statics are those of the line's first, where
/// they are measured by the same arm (`arm_of`: a tree's targets on different tips are not).
pub(super) fn same_line(data: &PositionData, arm_of: &[Option<usize>], k: usize) -> bool {
    k > 0 && data.rows[k - 1].line == data.rows[k].line && arm_of[k - 1] == arm_of[k]
}

/// What `deflections` gives.
pub(super) struct Deflections {
    pub(super) deflection: Vec<Vec6>,
    pub(super) compliance: Vec<Option<Mat6>>,
    pub(super) unusable: Vec<(usize, String)>,
}

/// Per row, the model's own deflection under its loads (a twist at the reference point; for a displacement,
/// less that at zero wrench) and its tangent compliance there (positions of a compliant model); the rows
/// whose loaded equilibrium the model cannot find (a singular configuration, a load past a limit) are left
/// out and named: the model has no prediction there.
pub(super) fn deflections<'m>(
    m: &Manipulator,
    data: &PositionData,
    (arm_of, arm_index): (&dyn Fn(usize) -> &'m Manipulator, &[Option<usize>]),
    state: &mut ManipulatorState,
) -> Deflections {
    let compliant = m.deflects();
    let under = |m: &Manipulator,
                 r: &PositionRow,
                 wrench: &Vec6,
                 state: &mut ManipulatorState|
     -> Result<(Vec6, Option<Mat6>), CalibrationError> {
        let frame =
            r.nominal_frame(m, state).ok_or_else(|| failed(r, "the joint coordinates give no finite pose".into()))?;
        m.place(&frame, state).map_err(|e| failed(r, e.to_string()))?;
        let d = m.deflect(&frame, wrench, None, state).map_err(|e| failed(r, e.to_string()))?;
        if !d.stable {
            return Err(failed(r, "the loaded equilibrium is unstable".into()));
        }
        Ok((d.displacement, d.compliance.or_else(|| d.held.stiffness.try_inverse())))
    };
    let mut out = Deflections {
        deflection: Vec::with_capacity(data.rows.len()),
        compliance: Vec::with_capacity(data.rows.len()),
        unusable: Vec::new(),
    };
    for (k, r) in data.rows.iter().enumerate() {
        if same_line(data, arm_index, k) {
            if let Some((_, why)) = out.unusable.last().filter(|(u, _)| *u == k - 1) {
                out.unusable.push((k, why.clone()));
            }
            out.deflection.push(out.deflection[k - 1]);
            out.compliance.push(out.compliance[k - 1]);
            continue;
        }
        let arm = arm_of(k);
        let found = match (compliant, r.observed) {
            (false, _) => Ok((Vec6::zeros(), None)),
            (true, Observed::Position { .. } | Observed::Orientation { .. }) => under(arm, r, &r.wrench, state),
            (true, Observed::Displacement(_)) => under(arm, r, &r.wrench, state)
                .and_then(|(d, _)| Ok((d - under(arm, r, &Vec6::zeros(), state)?.0, None))),
        };
        let (d, c) = found.unwrap_or_else(|e| {
            out.unusable.push((k, e.to_string()));
            (Vec6::zeros(), None)
        });
        out.deflection.push(d);
        out.compliance.push(c);
    }
    out
}

/// Each row's weight: 1 / its sigma, or the one given for its kind (1 where none is).
pub(super) fn weights(data: &PositionData, sigma: Option<f64>, sigma_rad: Option<f64>) -> Vec<f64> {
    data.rows
        .iter()
        .map(|r| {
            let given = match r.observed {
                Observed::Orientation { .. } => sigma_rad,
                _ => sigma,
            };
            1.0 / r.sigma.or(given).unwrap_or(1.0)
        })
        .collect()
}

/// What `row_statics` gives.
pub(super) struct RowStatics {
    pub(super) statics: Vec<(ArmStatics, Option<ArmStatics>)>,
    pub(super) leg_moves: Vec<Vec<Mat6>>,
    pub(super) prismatic: Vec<bool>,
}

/// Per row, the arm's statics at its configuration (and at zero wrench for a displacement), a parallel
/// robot's read at its commanded pose with each leg's C K_i; and which joints are prismatic.
pub(super) fn row_statics<'m>(
    m: &Manipulator,
    data: &PositionData,
    (arm_of, arm_index): (&dyn Fn(usize) -> &'m Manipulator, &[Option<usize>]),
    unusable: &mut Vec<(usize, String)>,
    state: &mut ManipulatorState,
) -> Result<RowStatics, CalibrationError> {
    let space = m.joint_space.as_ref();
    let mut out = RowStatics {
        statics: Vec::with_capacity(data.rows.len()),
        leg_moves: Vec::with_capacity(if space.is_some() { 0 } else { data.rows.len() }),
        prismatic: Vec::new(),
    };
    for (k, r) in data.rows.iter().enumerate() {
        if same_line(data, arm_index, k) {
            out.statics.push(out.statics[k - 1].clone());
            if space.is_none() {
                out.leg_moves.push(out.leg_moves[k - 1].clone());
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
                let s = at(&r.wrench, state)?;
                if out.prismatic.is_empty() {
                    out.prismatic = s.columns.iter().map(|c| c.fixed_rows::<3>(3).norm() == 0.0).collect();
                }
                (s, zero.map(|w| at(&w, state)).transpose()?)
            }
            (None, Some(pose)) => {
                // A row the model has no pose model for is already named unusable (its equilibrium failed
                // too, or will be): it keeps zero effects.
                match platform_statics(m, &pose, &r.wrench, zero.as_ref(), state) {
                    Ok(p) => {
                        if out.prismatic.is_empty() {
                            out.prismatic = p.actuators.iter().map(|a| a.fixed_rows::<3>(3).norm() == 0.0).collect();
                        }
                        out.leg_moves.push(p.moves);
                        (p.statics, p.zero)
                    }
                    Err(why) => {
                        if !unusable.iter().any(|(u, _)| *u == k) {
                            unusable.push((k, failed(r, why).to_string()));
                        }
                        let legs = m.legs.len();
                        out.leg_moves.push(vec![Mat6::zeros(); legs]);
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
        out.statics.push((s, z));
    }
    Ok(out)
}

/// Per target, the index of its turn among the fitted ones: the targets whose orientation is measured.
pub(super) fn turns_of(data: &PositionData) -> Vec<Option<usize>> {
    let mut turns = 0;
    (0..data.targets.len())
        .map(|t| {
            let oriented =
                data.rows.iter().any(|r| matches!(r.observed, Observed::Orientation { target, .. } if target == t));
            oriented.then(|| {
                turns += 1;
                turns - 1
            })
        })
        .collect()
}

/// The joints a calibration of `m` names: a serial arm's, or a parallel robot's legs by number (1-based, as
/// `[[actuator_offset]]` and the diagnosis's effects name them), each leg's actuator its joint.
pub fn joint_names(m: &Manipulator) -> Vec<String> {
    match &m.joint_space {
        Some(space) => space.names.clone(),
        None => (1..=m.legs.len()).map(|k| k.to_string()).collect(),
    }
}
