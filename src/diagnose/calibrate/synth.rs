//! `stiff synth`'s joint-space data: the robot with the hidden changes built into its description measured at
//! its loaded equilibrium, seen by an instrument with noise, gross rows, drift and held-out rows.

use super::effect::load_of;
use super::options::CalibrationError;
use crate::kinematics::frame::{rotation_from_vector, Frame, Mat3, Vec3, Vec6};
use crate::platform::manipulator::{Manipulator, ManipulatorState};

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

/// The controller's angles at which the arm sits when commanded to `commanded` with `play` per joint: each
/// joint's model coordinate moved by its play in the sense of the load it carries there (none where that
/// load is round-off); None where the statics or the controller's map fail there.
pub(super) fn with_play(
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
    let compliant = m.deflects();
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
pub(super) fn measured_rows(
    configurations: &[Configuration],
    s: &PositionSynth,
    mut measure: impl FnMut(&Configuration) -> Option<Frame>,
) -> (Vec<SynthRow>, usize) {
    use crate::diagnose::synth::normal as standard_normal;
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
