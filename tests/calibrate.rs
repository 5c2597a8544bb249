//! Calibration against what a lab measures (`stiff diagnose` with joint-space data,
//! `src/diagnose/calibrate.rs`). The synthetic data are made here from the FANUC's modified DH table with
//! tests/serial.rs's own kinematics and gravity torques (never by stiff): a hidden instrument frame and target,
//! encoder offsets, a joint's compliance, gross rows and noise, a third of the configurations held out. The
//! real data are the FANUC's 43 measured deflections (tests/reference/fanuc-r2000ic/).

use std::path::Path;

use rand::Rng;
use stiff::diagnose::calibrate::{
    self, ArmEffect, ArmKind, Calibration, CalibrationOptions as Options, CalibrationVerdict as Verdict,
};
use stiff::diagnose::positions::PositionData;
use stiff::kinematics::frame::{rotation_from_vector, Mat3, Vec3};
use stiff::platform::manipulator::Manipulator;

use crate::common::rng;
use crate::serial::{
    dh_gravity_torques_changed, dh_kinematics, dh_kinematics_changed, model_angles, random_angles, FANUC, K_JOINT,
};

const JOINTS: [&str; 6] = ["J1", "J2", "J3", "J4", "J5", "J6"];

/// What the synthetic robot and instrument hide.
#[derive(Clone)]
struct Hidden {
    /// The instrument's frame: base point p is seen at R p + t (R from this rotation vector).
    rotation: Vec3,
    translation: Vec3,
    /// The target in the tool frame, mm.
    target: Vec3,
    /// Added to the controller's angles, rad.
    offsets: [f64; 6],
    /// Factors on the source's joint compliances.
    compliance: [f64; 6],
    /// A mass (kg) carried at the tool, its centre in the tool frame (mm).
    payload: (f64, Vec3),
    /// Gravity in the base frame, m/s^2 (a base that is not level).
    gravity: Vec3,
    /// Play per joint, rad: the joint turned by it in the sense of its load, b sign(tau).
    play: [f64; 6],
    /// A joint's geometry (0-based joint, `[dx, dy, dz, rx, ry, rz]`: the fixed transform leading to it
    /// moved by a translation in mm, then turned by a rotation vector, in the joint's frame).
    geometry: Option<(usize, [f64; 6])>,
    /// A compliance at the frame leading to a joint (0-based joint, `[cx, cy, cz, crx, cry, crz]`, mm/N and
    /// rad/(N mm)): a spring Tx Ty Tz Rx Ry Rz along and about that frame's axes (`loaded_with_frame`).
    frame: Option<(usize, [f64; 6])>,
    /// A force on the tool point (N, base frame), read by the frame spring's route alone
    /// (`weights_potential`).
    tool_force: Vec3,
}

impl Hidden {
    fn registration_only() -> Hidden {
        Hidden {
            rotation: Vec3::new(0.1, -0.2, 0.3),
            translation: Vec3::new(1500.0, -300.0, 200.0),
            target: Vec3::new(20.0, -10.0, 30.0),
            offsets: [0.0; 6],
            compliance: [1.0; 6],
            payload: (0.0, Vec3::zeros()),
            gravity: Vec3::new(0.0, 0.0, -9.81),
            play: [0.0; 6],
            geometry: None,
            frame: None,
            tool_force: Vec3::zeros(),
        }
    }

    /// The change of the fixed transform leading to the frame spring's joint where the spring sits at
    /// `theta` (Tx Ty Tz Rx Ry Rz), after the geometry where both are at that joint; the geometry alone
    /// otherwise.
    fn change_with_frame(&self, theta: &[f64; 6]) -> crate::serial::GeometryChange {
        let Some((j, _)) = self.frame else { return self.geometry_change() };
        let mut spring = nalgebra::Matrix4::identity();
        spring.fixed_view_mut::<3, 1>(0, 3).copy_from(&Vec3::new(theta[0], theta[1], theta[2]));
        let turn = |axis: Vec3, angle: f64| {
            let mut m = nalgebra::Matrix4::identity();
            m.fixed_view_mut::<3, 3>(0, 0).copy_from(&rotation_from_vector(&(axis * angle)));
            m
        };
        spring = spring * turn(Vec3::x(), theta[3]) * turn(Vec3::y(), theta[4]) * turn(Vec3::z(), theta[5]);
        match self.geometry_change() {
            Some((g, m)) if g == j => Some((j, m * spring)),
            Some(_) => panic!("the simulator holds a geometry and a frame spring at one joint only"),
            None => Some((j, spring)),
        }
    }

    /// The geometry as the simulator's change of a joint's fixed transform: T(d) R(r).
    fn geometry_change(&self) -> crate::serial::GeometryChange {
        self.geometry.map(|(j, g)| {
            let mut m = nalgebra::Matrix4::identity();
            m.fixed_view_mut::<3, 3>(0, 0).copy_from(&rotation_from_vector(&Vec3::new(g[3], g[4], g[5])));
            m.fixed_view_mut::<3, 1>(0, 3).copy_from(&Vec3::new(g[0], g[1], g[2]));
            (j, m)
        })
    }
}

/// The measured target of a configuration (controller angles `t` as commanded): the DH table at the
/// true angles, the target carried by the flange frame, under the links' and the payload's weight the
/// loaded equilibrium of the joints' springs (`loaded_angles`), `gravity` or not, seen in the instrument's
/// frame.
fn measured_target(h: &Hidden, t: &[f64; 6], gravity: bool) -> Vec3 {
    measured_pose(h, t, gravity, &Vec3::zeros()).0
}

/// The joints' torques at model angles `q` under the links' weight and the payload's (its force m g at
/// the tool point p, its moment (R c) x F: (z_k x (p - o_k)) . F + z_k . M), N mm.
fn loaded_torques(h: &Hidden, q: &[f64; 6]) -> nalgebra::Vector6<f64> {
    let (tool, frames) = dh_kinematics_changed(q, h.geometry_change());
    let rotation = frames[5].fixed_view::<3, 3>(0, 0).into_owned();
    let mut tau = dh_gravity_torques_changed(q, &h.gravity, h.geometry_change());
    let force = h.gravity * h.payload.0;
    let moment = (rotation * h.payload.1).cross(&force);
    for (k, f) in frames.iter().enumerate() {
        let (z, o) = (Vec3::new(f[(0, 2)], f[(1, 2)], f[(2, 2)]), Vec3::new(f[(0, 3)], f[(1, 3)], f[(2, 3)]));
        tau[k] += z.cross(&(tool - o)).dot(&force) + z.dot(&moment);
    }
    tau
}

/// The model angles where the joints' springs hold the weights: K_k (q_k - q0_k) = tau_k(q) c_k (the
/// source's stiffnesses K_k, the hidden factors c_k on their compliances), each joint's play b_k taken up in
/// the sense of its load, the torques at the loaded angles themselves (not at q0: the exact equilibrium,
/// not its first order), by fixed-point iterations, each shrinking the change by about the sag's relative
/// size (1e-3).
fn loaded_angles(h: &Hidden, q0: &[f64; 6]) -> [f64; 6] {
    let mut q = *q0;
    for _ in 0..100 {
        let tau = loaded_torques(h, &q);
        let sign = |t: f64| if t == 0.0 { 0.0 } else { t.signum() };
        let next: [f64; 6] =
            std::array::from_fn(|k| q0[k] + tau[k] * h.compliance[k] / K_JOINT[k] + h.play[k] * sign(tau[k]));
        let change = (0..6).map(|k| (next[k] - q[k]).abs()).fold(0.0, f64::max);
        q = next;
        if change < 1e-16 {
            break;
        }
    }
    q
}

/// The potential of the loads (N mm: minus the sum of m g . x over the links' masses and the payload's
/// centre, and minus F . x of the tool's force at the tool point) at model angles `q` with the frame spring at `theta`.
fn weights_potential(h: &Hidden, q: &[f64; 6], theta: &[f64; 6]) -> f64 {
    let (_, frames) = dh_kinematics_changed(q, h.change_with_frame(theta));
    let point = |f: &nalgebra::Matrix4<f64>, c: &Vec3| {
        let p = f * nalgebra::Vector4::new(c.x, c.y, c.z, 1.0);
        Vec3::new(p.x, p.y, p.z)
    };
    let links: f64 = crate::serial::MASSES
        .iter()
        .enumerate()
        .map(|(i, (kg, c))| -(h.gravity * *kg).dot(&point(&frames[i], &Vec3::new(c[0], c[1], c[2]))))
        .sum();
    let tool = crate::serial::TOOL;
    let centre = Vec3::new(tool[0], tool[1], tool[2]) + h.payload.1;
    let tool_point = point(&frames[5], &Vec3::new(tool[0], tool[1], tool[2]));
    links - (h.gravity * h.payload.0).dot(&point(&frames[5], &centre)) - h.tool_force.dot(&tool_point)
}

/// The exact loaded equilibrium with a compliance at a joint's frame (`Hidden::frame`): the joint angles
/// and the frame spring's coordinates where the springs hold the weights, K_k (q_k - q0_k) = -dV/dq_k
/// (scaled by the hidden factors on the joints' compliances) and theta_i / c_i = -dV/dtheta_i (zero where
/// c_i is zero: rigid), V the weights' potential (`weights_potential`) differentiated by central
/// differences (its own route: no Jacobian of stiff's), by fixed-point iterations. Play is not modelled
/// here.
fn loaded_with_frame(h: &Hidden, q0: &[f64; 6]) -> ([f64; 6], [f64; 6]) {
    let c = h.frame.expect("a frame spring").1;
    let (mut q, mut theta) = (*q0, [0.0; 6]);
    let step = 1e-6;
    for _ in 0..200 {
        let along = |k: usize| {
            let (mut qa, mut qb, mut ta, mut tb) = (q, q, theta, theta);
            if k < 6 {
                qa[k] += step;
                qb[k] -= step;
            } else {
                ta[k - 6] += step;
                tb[k - 6] -= step;
            }
            -(weights_potential(h, &qa, &ta) - weights_potential(h, &qb, &tb)) / (2.0 * step)
        };
        let next_q: [f64; 6] = std::array::from_fn(|k| q0[k] + along(k) * h.compliance[k] / K_JOINT[k]);
        let next_theta: [f64; 6] = std::array::from_fn(|i| if c[i] > 0.0 { c[i] * along(6 + i) } else { 0.0 });
        let change = (0..6).map(|k| (next_q[k] - q[k]).abs().max((next_theta[k] - theta[k]).abs())).fold(0.0, f64::max);
        (q, theta) = (next_q, next_theta);
        // The central differences' round-off (about 3e-3 N mm on potentials of 1e7 N mm) leaves about 1e-12
        // of a coordinate: converged well above it, 2e-8 mm at the tool.
        if change < 1e-11 {
            break;
        }
    }
    (q, theta)
}

/// As `measured_target`, with the target's axes in the instrument's frame: R_instrument R_flange R_axes at
/// the loaded angles, `axes` the rotation vector of R_axes in the DH flange frame.
fn measured_pose(h: &Hidden, t: &[f64; 6], gravity: bool, axes: &Vec3) -> (Vec3, Mat3) {
    let truth: [f64; 6] = std::array::from_fn(|k| t[k] + h.offsets[k]);
    let q0 = model_angles(&truth);
    let (q, change) = match (gravity, h.frame.is_some()) {
        (true, true) => {
            let (q, theta) = loaded_with_frame(h, &q0);
            (q, h.change_with_frame(&theta))
        }
        (true, false) => (loaded_angles(h, &q0), h.geometry_change()),
        (false, _) => (q0, h.geometry_change()),
    };
    let (tool, frames) = dh_kinematics_changed(&q, change);
    let rotation = frames[5].fixed_view::<3, 3>(0, 0).into_owned();
    let x = tool + rotation * h.target;
    let instrument = rotation_from_vector(&h.rotation);
    (instrument * x + h.translation, instrument * rotation * rotation_from_vector(axes))
}

/// A joint-space measurement file of `configurations` random configurations (a third held out: every third
/// `check`), noise `sigma` per coordinate, rows `gross` moved 5 mm along a random direction.
fn synthetic(h: &Hidden, configurations: usize, sigma: f64, gross: &[usize], gravity: bool, seed: u64) -> String {
    let mut r = rng(seed);
    let mut csv = String::from("pose_id,q_J1,q_J2,q_J3,q_J4,q_J5,q_J6,mx_mm,my_mm,mz_mm,set\n");
    for c in 0..configurations {
        let t = random_angles(&mut r);
        let mut m = measured_target(h, &t, gravity);
        for a in 0..3 {
            m[a] += sigma * normal(&mut r);
        }
        if gross.contains(&c) {
            let d = Vec3::new(normal(&mut r), normal(&mut r), normal(&mut r));
            m += d.normalize() * 5.0;
        }
        let q: Vec<String> = t.iter().map(|v| format!("{v:?}")).collect();
        let set = if c % 3 == 2 { "check" } else { "fit" };
        csv += &format!("c{c},{},{:?},{:?},{:?},{set}\n", q.join(","), m.x, m.y, m.z);
    }
    csv
}

/// A standard normal number (Box-Muller).
fn normal(r: &mut rand::rngs::StdRng) -> f64 {
    let (u, v): (f64, f64) = (r.random_range(1e-12..1.0), r.random_range(0.0..1.0));
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// The FANUC model (its joints' springs and gravity, or rigid without gravity), read from the shipped files.
fn fanuc(rigid: bool, dir: &Path) -> Manipulator {
    if !rigid {
        return stiff::model::load_manipulator(Path::new(FANUC)).unwrap();
    }
    let urdf = std::fs::canonicalize("manipulators/fanuc-r2000ic.urdf").unwrap();
    let toml = format!(
        "name = \"rigid FANUC\"\n[[leg]]\nname = \"arm\"\n[leg.urdf]\nfile = {:?}\nroot = \"base_link\"\ntip = \"link_6\"\n\
         tool = {{ translation = [6.9, 245.3, 319.3] }}\ncontroller = {{ J3 = \"-(J2 + J3)\", J4 = \"-J4\", J5 = \"-J5\", J6 = \"-J6\" }}\n",
        urdf.display()
    );
    std::fs::write(dir.join("rigid.toml"), toml).unwrap();
    stiff::model::load_manipulator(&dir.join("rigid.toml")).unwrap()
}

fn calibrate_text(
    m: &Manipulator,
    csv: &str,
    dir: &Path,
    candidates: &[ArmEffect],
    options: &Options,
) -> (PositionData, Calibration) {
    let path = dir.join("data.csv");
    std::fs::write(&path, csv).unwrap();
    let names = &m.joint_space.as_ref().unwrap().names;
    let data = PositionData::read(&path, names).unwrap();
    let c = calibrate::calibrate(m, &data, candidates, options).unwrap();
    (data, c)
}

fn options(sigma: Option<f64>) -> Options {
    Options { alpha: 0.01, sigma, sigma_rad: None, fitted: Vec::new(), max_effects: 6, rebuild: None, progress: None }
}

fn effect(kind: ArmKind, joint: &str) -> ArmEffect {
    ArmEffect { kind, joint: JOINTS.iter().position(|j| *j == joint).unwrap() }
}

/// Registration alone, on a rigid FANUC, from noise-free positions: the instrument's frame and the target's
/// place are recovered to round-off (the positions to 1e-9 mm, the rotation to 1e-12 rad), nothing is named,
/// and the offset of J1 is reported not identifiable: J1's axis is vertical, so turning it is turning the
/// instrument about that axis.
#[test]
fn registration_alone_is_recovered_to_round_off_and_a_vertical_first_axis_is_not_identifiable() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(true, dir.path());
    let h = Hidden::registration_only();
    let csv = synthetic(&h, 30, 0.0, &[], false, 5);
    let (_, c) = calibrate_text(&m, &csv, dir.path(), &[], &options(Some(0.01)));
    assert_eq!(c.report.verdict, Verdict::None, "{}", calibrate::text(&c.report, "rigid"));
    let fitted = |name: &str| c.report.nuisance.iter().find(|n| n.name.contains(name)).unwrap().value;
    let (t, rv, target) = (fitted("translation"), fitted("rotation"), fitted("target"));
    assert!((Vec3::from(t) - h.translation).norm() < 1e-9, "{t:?}");
    assert!((Vec3::from(rv) * 1e-3 - h.rotation).norm() < 1e-12, "{rv:?}");
    assert!((Vec3::from(target) - h.target).norm() < 1e-9, "{target:?}");
    for stage in &c.report.stages {
        assert!(stage.fit.max < 1e-9 && stage.check.max < 1e-9, "{stage:?}");
    }
    let j1 =
        c.report.not_identifiable.iter().find(|n| n.starts_with("joint-offset:J1:")).expect("J1's offset reported");
    assert!(j1.contains("rotation about z"), "{j1}");
}

/// Two encoder offsets, one joint 1.8 times as compliant as the source's and a 20 kg payload, under the arm's
/// own weight, behind a hidden instrument frame and target, with 0.05 mm noise, one gross row in 60
/// configurations and a third held out: the four effects are named (and nothing else), each value (the
/// payload's mass) within its 95% interval in at least 90% of the values over the seeds, the gross row named,
/// and the held-out rows' RMS error at the noise (the length of a 3-vector of 0.05 mm noise has an RMS of
/// 0.087 mm).
#[test]
fn offsets_a_compliance_and_a_gross_row_are_named_and_the_held_out_rows_sit_at_the_noise() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let mut h = Hidden::registration_only();
    h.offsets[1] = 1.5e-3;
    h.offsets[4] = -2.0e-3;
    h.compliance[2] = 1.8;
    h.payload = (20.0, Vec3::new(30.0, 0.0, 100.0));
    let c3 = 1.0 / K_JOINT[2];
    let truth = [
        (effect(ArmKind::JointOffset, "J2"), 1.5e-3),
        (effect(ArmKind::JointOffset, "J5"), -2.0e-3),
        (effect(ArmKind::JointCompliance, "J3"), 0.8 * c3),
        (ArmEffect { kind: ArmKind::Payload, joint: 0 }, 20.0),
    ];
    let (mut checks, mut covered) = (0, 0);
    // Six seeds here (the suite's time); the note of issue 47 reports 30 through `stiff synth`.
    for seed in 0..6 {
        let gross = [7 + seed as usize];
        let csv = synthetic(&h, 60, 0.05, &gross, true, 100 + seed);
        let (data, c) = calibrate_text(&m, &csv, dir.path(), &[], &options(Some(0.05)));
        let report = calibrate::text(&c.report, "FANUC");
        assert_eq!(c.report.verdict, Verdict::Effect, "seed {seed}: {report}");
        let mut named: Vec<String> = c.report.accepted.iter().map(|a| a.label.clone()).collect();
        named.sort();
        assert_eq!(
            named,
            ["joint-compliance:J3", "joint-offset:J2", "joint-offset:J5", "payload"],
            "seed {seed}: {report}"
        );
        for (e, value) in truth {
            let a =
                c.report.accepted.iter().find(|a| a.label == e.label(&m.joint_space.as_ref().unwrap().names)).unwrap();
            checks += 1;
            covered += usize::from((a.values[0] - value).abs() <= 1.96 * a.se[0]);
        }
        // The payload as the text prints it, in the JSON too: its mass, then its centre in the tool frame
        // (not the first moment m c it is fitted as), each with its standard error.
        let payload = c.report.accepted.iter().find(|a| a.label == "payload").unwrap();
        for (k, truth) in [30.0, 0.0, 100.0].iter().enumerate() {
            let (v, se) = (payload.values[k + 1], payload.se[k + 1]);
            assert!((v - truth).abs() < 4.0 * se, "seed {seed}: centre {k} {v} +- {se}: {report}");
            assert!(report.contains(&format!("{v:.1} +- {se:.1}")), "seed {seed}: {v:.1} +- {se:.1} in {report}");
        }
        // Named whether fitted or held out (a held-out row is judged against the fitted rows' scale).
        let held = if data.rows[gross[0]].check { ", held out" } else { "" };
        let gross_name = format!("c{} (line {}{held})", gross[0], gross[0] + 2);
        assert_eq!(c.report.left_out.iter().map(|l| l.row.clone()).collect::<Vec<_>>(), [gross_name], "{report}");
        let last = c.report.stages.last().unwrap();
        assert!(last.check.rms < 0.087 * 1.35, "seed {seed}: {report}");
        assert!(last.fit.rms < 0.087 * 1.25, "seed {seed}: {report}");
    }
    assert!(covered as f64 >= 0.9 * checks as f64, "95% intervals cover {covered} of {checks}");
}

/// Null data: the registration alone hidden, 0.05 mm noise: no effect is named (20 seeds, each of which
/// would name a false one with probability at most alpha = 1%), and the report names the candidates the
/// defaults do not offer.
#[test]
fn null_data_names_no_effect() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let h = Hidden::registration_only();
    let mut named = 0;
    for seed in 0..20 {
        let csv = synthetic(&h, 45, 0.05, &[], true, 500 + seed);
        let (_, c) = calibrate_text(&m, &csv, dir.path(), &[], &options(Some(0.05)));
        named += usize::from(c.report.verdict != Verdict::None);
        let report = calibrate::text(&c.report, "FANUC");
        assert!(c.report.left_out.is_empty(), "{report}");
        // The default candidates say what they leave out, for a user to name.
        assert!(report.contains("note: not offered by default: frame-compliance at each joint"), "{report}");
        // With what the held-out rows leave, against the noise: at it on null data.
        let left = report.split("held out, the model leaves ").nth(1).expect("the held-out scale");
        let left: f64 = left.split(' ').next().unwrap().parse().unwrap();
        assert!((0.6..1.5).contains(&left), "{left}: {report}");
    }
    assert!(named <= 1, "{named} of 20 null data sets named an effect");
    // Candidates named: none is left out by default, and nothing says so.
    let csv = synthetic(&h, 45, 0.05, &[], true, 500);
    let (_, c) = calibrate_text(&m, &csv, dir.path(), &[effect(ArmKind::JointOffset, "J2")], &options(Some(0.05)));
    assert!(!c.report.notes.iter().any(|n| n.contains("not offered")), "{:?}", c.report.notes);
}

/// A screen never leaves out a large share of the rows as gross: with the instrument moved by 3 mm between
/// the fitted rows and the held-out ones (a set-up change the file does not mark), every held-out row misses
/// the fit by far more than the fitted rows' robust scale. They are not screened as gross (the share is
/// above `MOST_GROSS_SHARE`, 10%); the report says so, and the held-out errors include them. One gross row in
/// the same data unmoved is still left out.
#[test]
fn a_large_share_of_rows_beyond_the_scale_is_kept_and_named_not_screened_as_gross() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let h = Hidden::registration_only();
    let moved: String = synthetic(&h, 60, 0.05, &[], true, 41)
        .lines()
        .map(|line| {
            let mut cells: Vec<String> = line.split(',').map(String::from).collect();
            if cells[10] == "check" {
                cells[7] = format!("{:?}", cells[7].parse::<f64>().unwrap() + 3.0);
            }
            cells.join(",") + "\n"
        })
        .collect();
    let csv = moved;
    let (_, c) = calibrate_text(&m, &csv, dir.path(), &[], &options(Some(0.05)));
    let report = calibrate::text(&c.report, "FANUC");
    assert!(c.report.left_out.is_empty(), "{report}");
    assert!(c.report.notes.iter().any(|n| n.contains("none is left out as gross")), "{report}");
    assert!(report.contains("held out: 20 of 20 position rows lie beyond"), "{report}");
    // The note on the candidates not offered gives what the held-out rows leave: far above the noise.
    let left = report.split("held out, the model leaves ").nth(1).expect("the held-out scale");
    assert!(left.split(' ').next().unwrap().parse::<f64>().unwrap() > 10.0, "{report}");
    let last = c.report.stages.last().unwrap();
    assert!(last.check.rms > 2.9 && last.fit.rms < 0.1, "{report}");
    // The same data unmoved, with one gross row: screened as before.
    let csv = synthetic(&h, 60, 0.05, &[10], true, 41);
    let (_, c) = calibrate_text(&m, &csv, dir.path(), &[], &options(Some(0.05)));
    assert_eq!(c.report.left_out.len(), 1, "{}", calibrate::text(&c.report, "FANUC"));
    assert!(!c.report.notes.iter().any(|n| n.contains("left out as gross")), "{:?}", c.report.notes);
}

/// The FANUC's real deflections (the cable force's, a differential measurement) with every joint's
/// compliance fitted: trained on the rows whose index is not 2 mod 3, the held-out third's RMS error is
/// 0.415 mm, as an independent least-squares fit of Salisbury's model gives (SOURCE: 0.415 mm); fitted on all
/// 43, the stiffnesses are the independent fit's (8.61e5, 2.72e6, 1.96e6, 2.71e5, 4.25e5, 2.06e5 N m/rad, to
/// the 3 digits it was given) with an RMS length of 0.372 mm and a largest component of 0.880 mm.
#[test]
fn the_fanuc_deflections_give_the_independent_fits_stiffnesses_and_held_out_error() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let read = |name: &str| -> Vec<Vec<f64>> {
        let text = std::fs::read_to_string(format!("tests/reference/fanuc-r2000ic/{name}")).unwrap();
        text.lines().skip(1).map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect()
    };
    let (angles, forces, moved) = (read("joint_angles.csv"), read("forces.csv"), read("deltaX.csv"));
    let table = |held_out: bool| {
        let mut csv = String::from("q_J1,q_J2,q_J3,q_J4,q_J5,q_J6,Fx_N,Fy_N,Fz_N,dx_mm,dy_mm,dz_mm,set\n");
        for i in 0..angles.len() {
            let cells: Vec<String> = angles[i].iter().chain(&forces[i]).map(|v| format!("{v:?}")).collect();
            let d: Vec<String> = moved[i].iter().map(|v| format!("{:?}", v * 1000.0)).collect();
            let set = if held_out && i % 3 == 2 { "check" } else { "fit" };
            csv += &format!("{},{},{set}\n", cells.join(","), d.join(","));
        }
        csv
    };
    let names: Vec<String> = JOINTS.iter().map(|j| j.to_string()).collect();
    let every = Options {
        fitted: JOINTS.iter().map(|j| effect(ArmKind::JointCompliance, j)).collect(),
        max_effects: 0,
        ..options(None)
    };
    let (_, split) = calibrate_text(&m, &table(true), dir.path(), &[], &every);
    let check = &split.report.stages[0].check;
    assert_eq!(check.rows, 14);
    assert!((check.rms - 0.415).abs() < 0.0015, "held-out RMS {}", check.rms);
    let (_, all) = calibrate_text(&m, &table(false), dir.path(), &[], &every);
    let independent = [8.61e5, 2.72e6, 1.96e6, 2.71e5, 4.25e5, 2.06e5];
    for (k, a) in all.report.accepted.iter().enumerate() {
        assert_eq!(a.label, format!("joint-compliance:{}", names[k]));
        let stiffness = 1.0 / ((1.0 / K_JOINT[k] + a.values[0]) * 1e3);
        assert!(
            (stiffness / independent[k] - 1.0).abs() < 0.006,
            "{}: {stiffness:.4e} N m/rad vs {:.3e}",
            a.label,
            independent[k]
        );
        assert!(a.se[0] > 0.0 && a.shown.contains("stiffness"), "{}", a.shown);
    }
    let fit = &all.report.stages[0].fit;
    // The nominal part of the prediction is the loaded equilibrium (with and without the cable), Salisbury's
    // is linear: they differ at second order, a few micrometres here.
    let largest = fit.max_axis.iter().fold(0.0f64, |a, b| a.max(*b));
    assert!((fit.rms - 0.372).abs() < 0.0015 && (largest - 0.880).abs() < 0.003, "{fit:?}");
}

/// The command line: joint-space data go to the calibration (its report and JSON, a held-out fraction drawn
/// by configuration; from a file or standard input, which the header's peek must not consume), and what it
/// cannot do or read is refused with what to do, nothing written.
#[test]
fn diagnose_takes_joint_space_data_from_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let h = Hidden::registration_only();
    std::fs::write(dir.path().join("d.csv"), synthetic(&h, 30, 0.05, &[], true, 9).replace(",check\n", ",fit\n"))
        .unwrap();
    let stiff = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
            .args(["diagnose", FANUC, "--data"])
            .arg(dir.path().join("d.csv"))
            .args(args)
            .output()
            .unwrap()
    };
    let json = dir.path().join("c.json");
    let out = stiff(&["--sigma", "0.05", "--check-fraction", "0.3", "--seed", "4", "--json", json.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(text.contains("21 rows fitted, 9 held out") && text.contains("verdict: none"), "{text}");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["calibration"]["verdict"], "none");
    assert_eq!(v["calibration"]["stages"][0]["check"]["rows"], 9);
    // From standard input too (read once: its header chooses the calibration).
    let piped = assert_cmd::Command::new(env!("CARGO_BIN_EXE_stiff"))
        .args(["diagnose", FANUC, "--data", "-", "--sigma", "0.05"])
        .write_stdin(std::fs::read(dir.path().join("d.csv")).unwrap())
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&piped.stdout).contains("30 rows fitted, 0 held out"), "{piped:?}");
    // Regression: a row at a singular configuration (every angle zero: the wrist straight and J4 and J6 on
    // one axis) failed the whole calibration. A serial arm with a spring at every joint has its loaded
    // equilibrium there too (K_e dtheta = J_e^T w + tau_g), so the row is predicted; its made-up
    // measurement (2.7 m from the arm's tool) is then named as gross, and the others fitted.
    let rows = std::fs::read_to_string(dir.path().join("d.csv")).unwrap();
    let (header, rest) = rows.split_once('\n').unwrap();
    let with_singular = format!("{header}\nwrist,0,0,0,0,0,0,1000,0,1000,fit\n{rest}");
    std::fs::write(dir.path().join("s.csv"), with_singular).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
        .args(["diagnose", FANUC, "--sigma", "0.05", "--data"])
        .arg(dir.path().join("s.csv"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(text.contains("30 rows fitted") && text.contains("gross row left out: wrist (line 2)"), "{text}");
    let refused = |args: &[&str], says: &str| {
        let out = stiff(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
    };
    refused(&["--linear"], "--linear is not available for measured positions");
    refused(&["--fit", "joint-offset:J9"], "`J9` is not a joint of the arm (J1, J2, J3, J4, J5, J6)");
    refused(&["--candidates", "stretch:J1"], "the effects of a serial arm are");
    refused(&["--check-fraction", "1.5"], "--check-fraction must lie in [0, 1)");
    std::fs::write(dir.path().join("d.csv"), "q_J1,q_J2,mx_mm,my_mm,mz_mm\n0,0,1,2,3\n").unwrap();
    refused(&[], "missing q_J3, q_J4, q_J5, q_J6");
    std::fs::write(dir.path().join("d.csv"), "q_J1,q_J2,q_J3,q_J4,q_J5,q_J6,x\n0,0,0,0,0,0,1\n").unwrap();
    refused(&[], "no measured columns");
}

/// `--model-out` writes what the calibration found into the description (`[[joint_correction]]` offsets and
/// compliances, `[[payload]]`), so that every study sees it: the corrected arm at the controller's angles is
/// the nominal arm at those angles plus the offsets (forward kinematics, exactly), its joint's compliance is
/// the nominal plus the added one, it carries the payload, and the same data calibrate to `none` against it,
/// with the held-out rows at the noise.
#[test]
fn the_corrections_written_by_model_out_are_what_every_study_sees() {
    let dir = tempfile::tempdir().unwrap();
    let mut h = Hidden::registration_only();
    h.offsets[1] = 1.5e-3;
    h.offsets[4] = -2.0e-3;
    h.compliance[2] = 1.8;
    h.payload = (20.0, Vec3::new(30.0, 0.0, 100.0));
    let data = dir.path().join("d.csv");
    std::fs::write(&data, synthetic(&h, 60, 0.05, &[], true, 77)).unwrap();
    let corrected = dir.path().join("corrected.toml");
    let run = |model: &Path, extra: &[&str]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
            .arg("diagnose")
            .arg(model)
            .args(["--sigma", "0.05", "--data"])
            .arg(&data)
            .args(extra)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8(out.stdout).unwrap()
    };
    let first = run(Path::new(FANUC), &["--model-out", corrected.to_str().unwrap()]);
    assert!(first.contains("verdict: effect"), "{first}");
    let text = std::fs::read_to_string(&corrected).unwrap();
    assert!(text.contains("[[joint_correction]]") && text.contains("[[payload]]"), "{text}");
    let nominal = fanuc(false, dir.path());
    let m = stiff::model::load_manipulator(&corrected).unwrap();
    // The offsets found, read back from the file, move the arm as the controller's angles plus them do.
    let offset = |joint: &str| -> f64 {
        let at = text.find(&format!("joint = \"{joint}\"\noffset = ")).unwrap_or_else(|| panic!("{joint}: {text}"));
        let rest = &text[at..];
        rest.lines().nth(1).unwrap().trim_start_matches("offset = ").parse().unwrap()
    };
    let (d2, d5) = (offset("J2"), offset("J5"));
    assert!((d2 - 1.5e-3).abs() < 1e-4 && (d5 + 2.0e-3).abs() < 1e-4, "{d2} {d5}");
    let t = [0.3, 0.2, -0.4, 0.5, 1.1, -0.7];
    let shifted = [t[0], t[1] + d2, t[2], t[3], t[4] + d5, t[5]];
    let a = m.pose_at_joints(&t, &mut m.new_state()).unwrap();
    let b = nominal.pose_at_joints(&shifted, &mut nominal.new_state()).unwrap();
    assert!((a.pos - b.pos).norm() < 1e-9 && (a.rot - b.rot).norm() < 1e-12);
    let added = m.joint_compliance("J3").unwrap() - nominal.joint_compliance("J3").unwrap();
    assert!((added / (0.8 / K_JOINT[2]) - 1.0).abs() < 0.05, "{added}");
    // The mass written is the one reported, within 4 of its standard errors of the hidden 20 kg.
    let payload = m.payload.unwrap();
    let line = first.lines().find(|l| l.starts_with("effect: payload: ")).unwrap();
    let numbers: Vec<f64> = line["effect: payload: ".len()..].split(' ').filter_map(|w| w.parse().ok()).collect();
    assert!((payload.mass_kg - numbers[0]).abs() < 1e-3 && (numbers[0] - 20.0).abs() < 4.0 * numbers[1], "{line}");
    let again = run(&corrected, &[]);
    assert!(again.contains("verdict: none"), "{again}");
}

/// A `[[joint_correction]]` the description cannot hold is a located error: a joint not on the arm, a
/// compliance that leaves the joint's negative, a file with no URDF arm to correct.
#[test]
fn joint_corrections_that_cannot_apply_are_located_errors() {
    let dir = tempfile::tempdir().unwrap();
    let source = std::fs::read_to_string(FANUC).unwrap();
    let urdf = std::fs::canonicalize("manipulators/fanuc-r2000ic.urdf").unwrap();
    let source = source.replace("file = \"fanuc-r2000ic.urdf\"", &format!("file = {:?}", urdf.display().to_string()));
    let error = |extra: &str| {
        let path = dir.path().join("m.toml");
        std::fs::write(&path, format!("{source}\n{extra}")).unwrap();
        stiff::model::load_manipulator(&path).unwrap_err().to_string()
    };
    let e = error("[[joint_correction]]\njoint = \"J9\"\noffset = 0.001\n");
    assert!(e.contains("m.toml, line") && e.contains("joint `J9` in `joint_correction` is not on the chain"), "{e}");
    let e = error("[[joint_correction]]\njoint = \"J3\"\ncompliance = -1e-6\n");
    assert!(e.contains("joint `J3`: its compliance with the correction added is") && e.contains("not positive"), "{e}");
    let parallel = std::fs::read_to_string("manipulators/orthoglide-3puu.toml").unwrap();
    std::fs::write(
        dir.path().join("chain.toml"),
        format!("{parallel}\n[[joint_correction]]\njoint = \"J1\"\noffset = 0.1\n"),
    )
    .unwrap();
    let e = stiff::model::load_manipulator(&dir.path().join("chain.toml")).unwrap_err().to_string();
    assert!(e.contains("corrects the joints of a serial arm read from URDF"), "{e}");
}

/// A points file in `dir` of 60 random FANUC configurations (`c0`, `c1`, ...), drawn with `seed`.
fn random_configurations(dir: &Path, seed: u64) -> std::path::PathBuf {
    let mut r = rng(seed);
    let mut points = String::from("name,q_J1,q_J2,q_J3,q_J4,q_J5,q_J6\n");
    for k in 0..60 {
        let t: Vec<String> = random_angles(&mut r).iter().map(|v| format!("{v:?}")).collect();
        points += &format!("c{k},{}\n", t.join(","));
    }
    let path = dir.join("q.csv");
    std::fs::write(&path, points).unwrap();
    path
}

/// `stiff synth` on joint-space points writes data as a lab records them, from the robot with the hidden
/// changes built into its description and measured at its loaded equilibrium under its own weight (not the
/// calibration's first-order model): a hidden instrument frame and target, two offsets, a compliance, a
/// payload, gross rows and held-out configurations. The calibration names the four effects with values
/// within 4 standard errors, finds the instrument and target to 0.1 mm, names exactly the rows synth made
/// gross (its `hidden_gross` column), and leaves the held-out rows at the noise.
#[test]
fn synth_writes_joint_space_data_that_the_calibration_explains() {
    let dir = tempfile::tempdir().unwrap();
    let points = random_configurations(dir.path(), 21);
    let data = dir.path().join("data.csv");
    let c3 = 0.8 / K_JOINT[2];
    synth_four_effects(&points, "0.05", 4, &data);
    let m = fanuc(false, dir.path());
    let names = &m.joint_space.as_ref().unwrap().names;
    let d = PositionData::read(&data, names).unwrap();
    let c = calibrate::calibrate(&m, &d, &[], &options(Some(0.05))).unwrap();
    let report = calibrate::text(&c.report, "FANUC");
    let mut named: Vec<&str> = c.report.accepted.iter().map(|a| a.label.as_str()).collect();
    named.sort();
    assert_eq!(named, ["joint-compliance:J3", "joint-offset:J2", "joint-offset:J5", "payload"], "{report}");
    for (label, truth) in
        [("joint-offset:J2", 1.5e-3), ("joint-offset:J5", -2.0e-3), ("joint-compliance:J3", c3), ("payload", 20.0)]
    {
        let a = c.report.accepted.iter().find(|a| a.label == label).unwrap();
        assert!((a.values[0] - truth).abs() < 4.0 * a.se[0], "{label}: {report}");
    }
    let translation = Vec3::from(c.report.nuisance.iter().find(|n| n.name.contains("translation")).unwrap().value);
    let target = Vec3::from(c.report.nuisance.iter().find(|n| n.name.contains("target")).unwrap().value);
    assert!(
        (translation - Vec3::new(1500.0, -300.0, 200.0)).norm() < 0.1
            && (target - Vec3::new(20.0, -10.0, 30.0)).norm() < 0.1,
        "{report}"
    );
    let text = std::fs::read_to_string(&data).unwrap();
    let mut made: Vec<String> =
        text.lines().skip(1).filter(|l| l.ends_with(",1")).map(|l| l.split(',').next().unwrap().to_string()).collect();
    let mut found: Vec<String> =
        c.report.left_out.iter().map(|g| g.row.split(' ').next().unwrap().to_string()).collect();
    made.sort();
    found.sort();
    assert!(!made.is_empty() && made == found, "made gross {made:?}, named {found:?}");
    assert!(c.report.stages.last().unwrap().check.rms < 0.087 * 1.35, "{report}");
}

/// Regression: after forward selection and backward elimination, a swap replaced an effect by a simpler one
/// (a joint's geometry by an offset) and left it in the model although the others made it unnecessary: on
/// these configurations (tests/reference/calibration/) the calibration named joint-offset:J3 (-0.005 +-
/// 0.013 mrad) beside the four hidden effects. Elimination now runs again after each swap: exactly the four.
#[test]
fn a_swap_does_not_leave_an_effect_the_others_make_unnecessary() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data.csv");
    synth_four_effects(Path::new("tests/reference/calibration/fanuc-configurations-2008.csv"), "0.02", 2008, &data);
    let m = fanuc(false, dir.path());
    let d = PositionData::read(&data, &m.joint_space.as_ref().unwrap().names).unwrap();
    let c = calibrate::calibrate(&m, &d, &[], &options(Some(0.05))).unwrap();
    let mut named: Vec<&str> = c.report.accepted.iter().map(|a| a.label.as_str()).collect();
    named.sort();
    assert_eq!(
        named,
        ["joint-compliance:J3", "joint-offset:J2", "joint-offset:J5", "payload"],
        "{}",
        calibrate::text(&c.report, "FANUC")
    );
}

/// A compliance at the frame leading to a joint, about that frame's z axis (the joint's own axis), is the
/// joint's compliance: the moment about the axis through the frame is the load the joint carries. Data made
/// by `stiff synth` with J2 0.5 times more compliant than the source says (its loaded equilibrium), fitted
/// with `frame-compliance:J2` alone: its rotation about z recovers the added compliance within 4 standard
/// errors, through the wrench transmitted by the links beyond J2 rather than through the joint's load.
#[test]
fn a_frame_compliance_about_the_joints_axis_is_the_joints_compliance() {
    let dir = tempfile::tempdir().unwrap();
    let added = 0.5 / K_JOINT[1];
    let data = dir.path().join("data.csv");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
        .args(["synth", FANUC, "--points", "tests/reference/calibration/fanuc-configurations-2008.csv"])
        .args(["--effect", "registration=0.1,-0.2,0.3,1500,-300,200", "--effect", "target=20,-10,30"])
        .args(["--effect", &format!("joint-compliance:J2={added}"), "--noise", "0.01", "--seed", "3", "-o"])
        .arg(&data)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let m = fanuc(false, dir.path());
    let d = PositionData::read(&data, &m.joint_space.as_ref().unwrap().names).unwrap();
    let fitted = vec![effect(ArmKind::FrameCompliance, "J2")];
    let c = calibrate::calibrate(&m, &d, &[], &Options { fitted, max_effects: 0, ..options(Some(0.01)) }).unwrap();
    let a = &c.report.accepted[0];
    assert!(
        a.se[5].is_finite() && (a.values[5] - added).abs() < 4.0 * a.se[5],
        "{}",
        calibrate::text(&c.report, "FANUC")
    );
    assert!(a.se[5] < 0.1 * added, "{}", a.shown);
}

/// A base that is not level: gravity 15 degrees off the base's -z. The rows give its direction as an
/// accelerometer reads it (`gravity_x,gravity_y,gravity_z`), and the joints' loads follow it: J3's compliance,
/// 1.8 times the source's, is found within 4 standard errors, the registration absorbing nothing of it.
/// Without the columns (the model's gravity along -z) the same data need more than that one effect, or
/// give it a value away from the truth.
#[test]
fn a_tilted_bases_gravity_direction_loads_the_joints() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let mut h = Hidden::registration_only();
    h.compliance[2] = 1.8;
    let tilt = 15f64.to_radians();
    h.gravity = Vec3::new(0.0, 9.81 * tilt.sin(), -9.81 * tilt.cos());
    let csv = synthetic(&h, 60, 0.02, &[], true, 31);
    let direction = h.gravity.normalize();
    let mut lines = csv.lines();
    let header = lines.next().unwrap().replace(",set", ",gravity_x,gravity_y,gravity_z,set");
    let mut tilted = format!("{header}\n");
    for line in lines {
        let (rest, set) = line.rsplit_once(',').unwrap();
        tilted += &format!("{rest},{},{},{},{set}\n", direction.x, direction.y, direction.z);
    }
    let truth = 0.8 / K_JOINT[2];
    let (_, c) = calibrate_text(&m, &tilted, dir.path(), &[], &options(Some(0.02)));
    let report = calibrate::text(&c.report, "FANUC");
    assert_eq!(
        c.report.accepted.iter().map(|a| a.label.as_str()).collect::<Vec<_>>(),
        ["joint-compliance:J3"],
        "{report}"
    );
    assert!((c.report.accepted[0].values[0] - truth).abs() < 4.0 * c.report.accepted[0].se[0], "{report}");
    let (_, level) = calibrate_text(&m, &csv, dir.path(), &[], &options(Some(0.02)));
    let right = level.report.accepted.len() == 1
        && level.report.accepted[0].label == "joint-compliance:J3"
        && (level.report.accepted[0].values[0] - truth).abs() < 4.0 * level.report.accepted[0].se[0];
    assert!(
        !right,
        "the level model should not explain tilted data as well: {}",
        calibrate::text(&level.report, "FANUC")
    );
}

/// `stiff synth` on the FANUC at the configurations `points`: a hidden instrument frame and target, J2 and J5
/// offsets (1.5 and -2 mrad), J3 0.8 of the source's compliance more compliant, a 20 kg payload at (30, 0,
/// 100) mm, a share `gross` of rows 5 mm off, 0.05 mm noise, every third configuration held out; into `data`.
fn synth_four_effects(points: &Path, gross: &str, seed: u64, data: &Path) {
    let c3 = 0.8 / K_JOINT[2];
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
        .args(["synth", FANUC, "--points"])
        .arg(points)
        .args(["--effect", "registration=0.1,-0.2,0.3,1500,-300,200", "--effect", "target=20,-10,30"])
        .args(["--effect", "joint-offset:J2=0.0015", "--effect", "joint-offset:J5=-0.002"])
        .args(["--effect", &format!("joint-compliance:J3={c3}"), "--effect", "payload=20,30,0,100"])
        .args(["--effect", &format!("gross={gross},5"), "--noise", "0.05", "--seed", &seed.to_string()])
        .args(["--check-every", "3", "-o"])
        .arg(data)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

/// The plan's signatures are the calibration's first-order sensitivities: the derivative of the measured
/// target in an encoder's offset (J2) and in a joint's added compliance (J3) at random configurations under
/// the arm's own weight equals central finite differences of this file's own generator (DH kinematics and
/// gravity torques, never stiff), to 1% of the derivative's size (weighted by 1/noise; one sign for all
/// rows, the residual's or the prediction's). The calibration holds the model's own sag at the configuration
/// commanded (an offset of a milliradian moves it by a few micrometres), which the generator does not:
/// they differ by that, 0.1% to 0.8% here.
#[test]
fn the_plans_signatures_are_finite_differences_of_the_measured_target() {
    let m = fanuc(false, Path::new("."));
    let mut r = rng(31);
    let noise = 0.05;
    let angles: Vec<[f64; 6]> = (0..8).map(|_| random_angles(&mut r)).collect();
    let configurations: Vec<calibrate::Configuration> =
        angles.iter().enumerate().map(|(k, t)| (format!("c{k}"), t.to_vec(), Default::default())).collect();
    let effects = [effect(ArmKind::JointOffset, "J2"), effect(ArmKind::JointCompliance, "J3")];
    let found = calibrate::signatures(&m, &configurations, None, &effects, noise, None).unwrap();
    assert_eq!(found.usable.len(), 8);
    assert_eq!(found.nuisance.ncols(), 9, "an instrument's frame and a target's place");
    let level = Hidden {
        rotation: Vec3::zeros(),
        translation: Vec3::zeros(),
        target: Vec3::zeros(),
        ..Hidden::registration_only()
    };
    let difference = |change: &dyn Fn(&mut Hidden, f64), h: f64, t: &[f64; 6]| -> Vec3 {
        let (mut up, mut down) = (level.clone(), level.clone());
        change(&mut up, h);
        change(&mut down, -h);
        (measured_target(&up, t, true) - measured_target(&down, t, true)) / (2.0 * h) / noise
    };
    assert_signatures_are_differences(&found, &angles, 1, (3, 0), difference);
}

/// The signatures `found` of an offset of joint `offset_joint` and of J3's added compliance (the effects in
/// that order) equal `difference`, the central differences of this file's generator under a change of
/// `Hidden`, at each configuration of `angles`: rows `first..first + 3` of each candidate's `per`, to 1% of
/// the difference's size, with one sign for all rows (the residual's or the prediction's).
fn assert_signatures_are_differences(
    found: &calibrate::Signatures,
    angles: &[[f64; 6]],
    offset_joint: usize,
    (per, first): (usize, usize),
    difference: impl Fn(&dyn Fn(&mut Hidden, f64), f64, &[f64; 6]) -> Vec3,
) {
    let offset = |h: &mut Hidden, d: f64| h.offsets[offset_joint] = d;
    // The hidden compliance is a factor on the source's: an added compliance c is the factor 1 + c k3.
    let compliance = |h: &mut Hidden, c: f64| h.compliance[2] = 1.0 + c * K_JOINT[2];
    for (e, (change, step)) in
        [(&offset as &dyn Fn(&mut Hidden, f64), 1e-6), (&compliance, 1e-12)].into_iter().enumerate()
    {
        let signature = &found.effects[e].1;
        let mut sign = 0.0;
        for (i, t) in angles.iter().enumerate() {
            let fd = difference(change, step, t);
            let s = Vec3::from_fn(|a, _| signature[(per * i + first + a, 0)]);
            if sign == 0.0 {
                sign = s.dot(&fd).signum();
            }
            assert!((s * sign - fd).norm() <= 1e-2 * fd.norm(), "{} at c{i}: {s} vs {fd}", found.effects[e].0);
        }
    }
}

/// `stiff plan` on the FANUC's 43 measured configurations, each under the arm's own weight: the plan's rows
/// are candidates with their angles in the arm's order and the pose forward kinematics gives; J1's
/// compliance is reported unseen (J1's axis is vertical: gravity puts no torque on it); the greedy plan's
/// information (log det) is larger than that of five random choices of the same size.
#[test]
fn plan_chooses_calibration_configurations_of_a_serial_arm() {
    let run = |extra: &[&str]| -> (String, String) {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("plan.csv");
        let done = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
            .args(["plan", FANUC, "--candidates", "manipulators/grids/fanuc-r2000ic-cable-tests.csv"])
            .args(["--budget", "15", "--noise", "0.05", "--loads", "0,0,0,0,0,0", "-o"])
            .arg(&out)
            .args(extra)
            .output()
            .unwrap();
        assert!(done.status.success(), "{}", String::from_utf8_lossy(&done.stderr));
        (String::from_utf8(done.stdout).unwrap(), std::fs::read_to_string(&out).unwrap())
    };
    let log_det = |report: &str| -> f64 { report.lines().next().unwrap().rsplit(' ').next().unwrap().parse().unwrap() };
    let (report, table) = run(&[]);
    assert!(report.contains("not seen by any candidate (not planned for): joint-compliance:J1"), "{report}");
    assert!(table.starts_with("name,q_J1,q_J2,q_J3,q_J4,q_J5,q_J6,x_mm,y_mm,z_mm,"), "{table}");
    let candidates = std::fs::read_to_string("manipulators/grids/fanuc-r2000ic-cable-tests.csv").unwrap();
    let rows =
        crate::common::csv_columns(&table, &["q_J1", "q_J2", "q_J3", "q_J4", "q_J5", "q_J6", "x_mm", "y_mm", "z_mm"]);
    assert_eq!(rows.len(), 15);
    for row in &rows {
        let t: [f64; 6] = std::array::from_fn(|k| row[k]);
        assert!(candidates.contains(&format!("{:?}", t[0])), "{t:?} is a candidate");
        let (p, _) = dh_kinematics(&model_angles(&t));
        assert!((Vec3::new(row[6], row[7], row[8]) - p).norm() < 1e-9);
    }
    let planned = log_det(&report);
    for seed in 1..=5 {
        let random = log_det(&run(&["--random", &seed.to_string()]).0);
        assert!(planned > random, "plan {planned} vs random seed {seed}: {random}");
    }
}

/// `stiff synth` on the shipped 43 cable-test configurations into `data`, every third held out, with the
/// effects and options `set_up` and `robot` give.
fn synth_cable_tests(data: &Path, set_up: &[&str], robot: &[&str]) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
        .args(["synth", FANUC, "--points", "manipulators/grids/fanuc-r2000ic-cable-tests.csv"])
        .args(set_up)
        .args(robot)
        .args(["--check-every", "3", "-q", "-o"])
        .arg(data)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

/// `stiff synth` with two `registration` effects measures the configurations in two blocks, the instrument
/// moved between them, and writes a `setup` column; the calibration fits one frame per set-up: each within
/// 0.25 mm and 0.25 mrad of the hidden one (five standard errors at 0.05 mm of noise), and names the hidden
/// offset.
#[test]
fn synth_with_two_setups_gives_each_its_own_registration() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("two.csv");
    synth_cable_tests(
        &data,
        &["--effect", "registration=0.1,0,0.2,1500,0,300", "--effect", "registration=-0.2,0.1,0,-800,900,100"],
        &["--effect", "target=20,0,30", "--effect", "joint-offset:J2=0.001", "--noise", "0.05", "--seed", "4"],
    );
    let text = std::fs::read_to_string(&data).unwrap();
    assert!(text.lines().next().unwrap().contains(",set,setup,"), "{text}");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
        .args(["diagnose", FANUC, "--data"])
        .arg(&data)
        .output()
        .unwrap();
    let report = String::from_utf8(out.stdout).unwrap();
    assert!(report.contains("effect: joint-offset:J2: "), "{report}");
    let values = |line: &str| -> Vec<f64> {
        let l = report.lines().find(|l| l.starts_with(line)).unwrap_or_else(|| panic!("{line}: {report}"));
        l[line.len()..].split('(').next().unwrap().split_whitespace().map(|v| v.parse().unwrap()).collect()
    };
    for (setup, rotation, translation) in
        [("s1", [100.0, 0.0, 200.0], [1500.0, 0.0, 300.0]), ("s2", [-200.0, 100.0, 0.0], [-800.0, 900.0, 100.0])]
    {
        let t = values(&format!("fitted set-up {setup}: translation, mm: "));
        let r = values(&format!("fitted set-up {setup}: rotation vector, mrad: "));
        for k in 0..3 {
            assert!((t[k] - translation[k]).abs() < 0.25 && (r[k] - rotation[k]).abs() < 0.25, "{setup}: {t:?} {r:?}");
        }
    }
}

/// A compliance at the frame leading to J3 (the upper arm bending about the frame's y under its weight),
/// hidden by `stiff synth` (which builds it into the description as `frame_compliance`): the calibration
/// offered it names it, its value about y within four standard errors of the hidden 2e-9 rad/(N mm),
/// `--model-out` writes it as a spring (a component below zero within two standard errors written as
/// rigid), and the corrected description leaves nothing to name on the same data.
#[test]
fn a_frame_compliance_found_by_the_calibration_is_written_as_a_spring() {
    let dir = tempfile::tempdir().unwrap();
    let (data, fixed) = (dir.path().join("fc.csv"), dir.path().join("fixed.toml"));
    let stiff = |args: &[&str]| -> String {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff")).args(args).output().unwrap();
        assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8(out.stdout).unwrap()
    };
    let (d, f) = (data.to_str().unwrap(), fixed.to_str().unwrap());
    stiff(
        &[
            "synth",
            FANUC,
            "--points",
            "manipulators/grids/fanuc-r2000ic-cable-tests.csv",
            "--effect",
            "registration=0.1,0,0.2,1500,0,300",
        ]
        .into_iter()
        .chain(["--effect", "target=20,0,30", "--effect", "frame-compliance:J3=0,0,0,0,2e-9,0", "--noise", "0.02"])
        .chain(["--seed", "2", "-q", "-o", d])
        .collect::<Vec<_>>(),
    );
    let json = dir.path().join("c.json");
    stiff(
        &[
            "diagnose",
            FANUC,
            "--data",
            d,
            "--candidates",
            "frame-compliance:J3,joint-compliance:J2,joint-compliance:J3",
        ]
        .into_iter()
        .chain(["--model-out", f, "--json", json.to_str().unwrap()])
        .collect::<Vec<_>>(),
    );
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let accepted = &v["calibration"]["accepted"][0];
    assert_eq!(accepted["label"], "frame-compliance:J3", "{v}");
    let (value, se) = (accepted["values"][4].as_f64().unwrap(), accepted["se"][4].as_f64().unwrap());
    assert!((value - 2e-9).abs() < 4.0 * se, "{value} +- {se}");
    let corrected = std::fs::read_to_string(&fixed).unwrap();
    assert!(corrected.contains("joint = \"J3\"\nframe_compliance = ["), "{corrected}");
    assert!(stiff(&["diagnose", f, "--data", d]).contains("verdict: none"));
}

/// A per-row payload (`payload_kg`, `payload_cx_mm..`): every second configuration measured with 60 kg
/// carried 150 mm along the tool's z, made by this file's own generator (its torques on the DH chain). With
/// the payload columns the calibration needs no effect (`none`, residual at the noise: its weight is in
/// each row's load); without them, the same positions need one (the payload's sag, up to a millimetre, is
/// then unexplained by the model).
#[test]
fn a_per_row_payload_is_weighed_into_the_rows_load() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let mut r = rng(50);
    let mut with = String::from("pose_id,q_J1,q_J2,q_J3,q_J4,q_J5,q_J6,mx_mm,my_mm,mz_mm,payload_kg,payload_cz_mm\n");
    let mut without = String::from("pose_id,q_J1,q_J2,q_J3,q_J4,q_J5,q_J6,mx_mm,my_mm,mz_mm\n");
    for c in 0..60 {
        let t = random_angles(&mut r);
        let kg = if c % 2 == 1 { 60.0 } else { 0.0 };
        let h = Hidden { payload: (kg, Vec3::new(0.0, 0.0, 150.0)), ..Hidden::registration_only() };
        let p = measured_target(&h, &t, true);
        let q: Vec<String> = t.iter().map(|v| format!("{v:?}")).collect();
        let row = format!("c{c},{},{:?},{:?},{:?}", q.join(","), p.x, p.y, p.z);
        with += &format!("{row},{kg},150\n");
        without += &format!("{row}\n");
    }
    let (_, c) = calibrate_text(&m, &with, dir.path(), &[], &options(Some(0.05)));
    assert_eq!(c.report.verdict, Verdict::None, "{:?}", c.report.accepted.iter().map(|a| &a.shown).collect::<Vec<_>>());
    let rms = c.report.stages.last().unwrap().fit.rms;
    assert!(rms < 0.05, "fit RMS {rms} mm with the payloads weighed");
    let (_, c) = calibrate_text(&m, &without, dir.path(), &[], &options(Some(0.05)));
    assert_ne!(c.report.verdict, Verdict::None, "the payloads' sag left out must show");
}

/// Measurements drifting over their order (thermal growth, an instrument settling): this file's generator
/// moves the target seen by (4, 0, -3) um per row, base axes, over 60 configurations with 0.05 mm of
/// noise. The calibration offered it (`--candidates`: it is not offered by default) names `drift` alone
/// beside the offsets, compliances and payload, each rate within four standard errors, and writes it into
/// no description (it belongs to the measurements).
#[test]
fn a_drift_over_the_measurements_order_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let rate = Vec3::new(0.004, 0.0, -0.003);
    let h = Hidden::registration_only();
    let mut r = rng(51);
    let mut csv = String::from("pose_id,q_J1,q_J2,q_J3,q_J4,q_J5,q_J6,mx_mm,my_mm,mz_mm\n");
    for c in 0..60 {
        let t = random_angles(&mut r);
        let noise = Vec3::new(r.random_range(-1.0..1.0), r.random_range(-1.0..1.0), r.random_range(-1.0..1.0))
            * 0.05
            * 3f64.sqrt();
        let p = measured_target(&h, &t, true) + rotation_from_vector(&h.rotation) * rate * c as f64 + noise;
        let q: Vec<String> = t.iter().map(|v| format!("{v:?}")).collect();
        csv += &format!("c{c},{},{:?},{:?},{:?}\n", q.join(","), p.x, p.y, p.z);
    }
    let mut offered: Vec<ArmEffect> =
        JOINTS.iter().flat_map(|j| [effect(ArmKind::JointOffset, j), effect(ArmKind::JointCompliance, j)]).collect();
    offered.extend([ArmEffect { kind: ArmKind::Payload, joint: 0 }, ArmEffect { kind: ArmKind::Drift, joint: 0 }]);
    let (_, c) = calibrate_text(&m, &csv, dir.path(), &offered, &options(Some(0.05)));
    let names: Vec<&str> = c.report.accepted.iter().map(|a| a.label.as_str()).collect();
    assert_eq!(names, ["drift"], "{:?}", c.report.accepted.iter().map(|a| &a.shown).collect::<Vec<_>>());
    let a = &c.report.accepted[0];
    for k in 0..3 {
        assert!((a.values[k] - rate[k]).abs() < 4.0 * a.se[k], "{}", a.shown);
    }
    let corrected = calibrate::corrected_model("name = \"x\"\n", dir.path(), None, &c, false);
    assert!(corrected.contains("# drift: ") && !corrected.contains("[[joint_correction]]"), "{corrected}");
}

/// A column no rule reads (a target's orientation, a timestamp) is named in the report, so that nobody
/// takes a measurement as used that was not; the columns read are not named.
#[test]
fn columns_the_calibration_does_not_read_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let h = Hidden::registration_only();
    let csv = synthetic(&h, 20, 0.05, &[], true, 12);
    let mut lines = csv.lines();
    let mut text = format!("{},mrx_rad,stamp\n", lines.next().unwrap());
    for (k, l) in lines.enumerate() {
        text += &format!("{l},0.1,{k}\n");
    }
    std::fs::write(dir.path().join("o.csv"), text).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
        .args(["diagnose", FANUC, "--data"])
        .arg(dir.path().join("o.csv"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report = String::from_utf8(out.stdout).unwrap();
    assert!(report.contains("columns not read (no rule uses them): mrx_rad, stamp\n"), "{report}");
}

/// A compliance at the frame leading to J3 (the upper arm's mounting bends), hidden by the simulator's own
/// equilibrium (`loaded_with_frame`: the loads' potential differentiated by central differences, a spring
/// Tx Ty Tz Rx Ry Rz along and about the frame's axes), the tool pulled by 2 kN in a random direction on
/// every second configuration, each component moving the target by 0.1 mm or more (the noise 0.01 mm), 40
/// seeds, `frame-compliance:J3` offered (it is not by default): named in every seed, and each of its six
/// compliances within two standard errors of the truth in at least 216 of the 240 draws (90%; 95%
/// expected, a seed's six not independent). Run once over 200 seeds: every parameter seen, 1,142 of 1,200
/// covered (95.2%), errors RMS 1.03 standard errors. (Under the weight alone a combination of its
/// translations moves the target as the instrument's translation does: the next test.) The simulator's route is checked first: with the frame rigid it gives
/// the analytic equilibrium's target (`loaded_angles`) to 1e-8 mm.
#[test]
fn a_compliance_at_a_joints_frame_is_named_and_covered_by_its_standard_errors() {
    let rigid = Hidden { frame: Some((1, [0.0; 6])), ..softer_j2() };
    let mut r = rng(3);
    for _ in 0..5 {
        let t = random_angles(&mut r);
        let (a, b) = (measured_target(&rigid, &t, true), measured_target(&softer_j2(), &t, true));
        assert!((a - b).norm() < 1e-8, "{a} by differences, {b} by the analytic torques");
    }
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let o = Options { rebuild: fanuc_rebuild(), ..options(Some(0.01)) };
    let truth = [2e-4, 1e-4, 3e-4, 3e-10, 2e-10, 2e-10];
    let h = Hidden { frame: Some((2, truth)), ..Hidden::registration_only() };
    let offered = [effect(ArmKind::FrameCompliance, "J3")];
    let mut coverage = Coverage::default();
    for seed in 0..40 {
        // Every second configuration pulled at the tool by 2 kN in a random direction (a cable test): under
        // the weight alone a combination of the frame's translations is the instrument's, held rigid.
        let mut r = rng(9300 + seed);
        let csv = frame_rows(&h, &mut r, true);
        let (_, c) = calibrate_text(&m, &csv, dir.path(), &offered, &o);
        let a = c.report.accepted.iter().find(|a| a.label == "frame-compliance:J3");
        let a = a.unwrap_or_else(|| panic!("seed {seed}: not named: {}", calibrate::text(&c.report, "FANUC")));
        coverage.add(&a.values, &a.se, &truth);
    }
    let (covered, draws, rms) = (coverage.covered, coverage.draws, coverage.rms());
    println!("frame compliance: {covered} of {draws} seen parameters within two standard errors; error in standard errors rms {rms:.2}");
    assert!(draws == 240 && covered >= 216, "{covered} of {draws}");
}

/// 40 configurations of the robot `h` hides, measured with 0.01 mm of noise, every third held out; with
/// `pulled`, every second one pulled at the tool by 2 kN in a random direction (a cable test), the force in
/// the file's columns.
fn frame_rows(h: &Hidden, r: &mut rand::rngs::StdRng, pulled: bool) -> String {
    let forces = if pulled { "Fx_N,Fy_N,Fz_N," } else { "" };
    let mut csv = format!("pose_id,q_J1,q_J2,q_J3,q_J4,q_J5,q_J6,{forces}mx_mm,my_mm,mz_mm,set\n");
    for k in 0..40 {
        let t = random_angles(r);
        let mut force = Vec3::zeros();
        if pulled {
            let d = Vec3::new(normal(r), normal(r), normal(r));
            force = if k % 2 == 1 { d.normalize() * 2000.0 } else { Vec3::zeros() };
        }
        let mut p = measured_target(&Hidden { tool_force: force, ..h.clone() }, &t, true);
        for a in 0..3 {
            p[a] += 0.01 * normal(r);
        }
        let q: Vec<String> = t.iter().map(|v| format!("{v:?}")).collect();
        let set = if k % 3 == 2 { "check" } else { "fit" };
        let force = if pulled { format!("{:?},{:?},{:?},", force.x, force.y, force.z) } else { String::new() };
        csv += &format!("c{k},{},{force}{:?},{:?},{:?},{set}\n", q.join(","), p.x, p.y, p.z);
    }
    csv
}

/// The same compliance at J3's frame under the weight alone (no force at the tool): the force through the
/// frame is the weight beyond it, of one size and direction in the base at every row, so a combination of
/// the spring's translations moves the target as the instrument's translation does, and no row tells them
/// apart. The candidate is fitted in the directions the rows see, one compliance of that combination held
/// at its nominal value (rigid: the one that reaches zero first along it, so that the others stay
/// physical) and said so: named in at least 18 of 20 seeds, each held direction at zero with no standard
/// error, the rows explained to the noise (residual below 1.3 sigma), the turns' compliances, which the
/// weight's moment sees, within two standard errors of the truth in at least 90% of their draws, and the
/// model written reproducing the fit to 1e-6 mm and diagnosed `none` again. Run once over 200 seeds: named
/// in 200, every residual below 1.3 sigma, the turns 571 of 600 (95.2%, errors RMS 1.01 standard errors).
/// (Before, the candidate was refused whole as not identifiable; holding its largest part instead pushed
/// the others below zero and left 5 sigma, and so, in 1 seed of 66, did judging the bound before the tie.)
#[test]
fn a_frame_compliance_under_the_weight_alone_is_named_in_the_directions_the_rows_see() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let o = Options { rebuild: fanuc_rebuild(), ..options(Some(0.01)) };
    let truth = [2e-4, 1e-4, 3e-4, 3e-10, 2e-10, 2e-10];
    let h = Hidden { frame: Some((2, truth)), ..Hidden::registration_only() };
    let offered = [effect(ArmKind::FrameCompliance, "J3")];
    let (mut coverage, mut named, mut held) = (Coverage::default(), 0, Vec::new());
    for seed in 0..20 {
        let mut r = rng(9700 + seed);
        let csv = frame_rows(&h, &mut r, false);
        if seed == 0 {
            // The model written holds the held directions rigid and reproduces the fit.
            let written = write_and_validate(dir.path(), &csv, "frame-compliance:J3", &["frame-compliance:J3"]);
            assert!(written.model.contains("frame_compliance = ["), "{}", written.model);
            assert!(written.worst < 1e-6, "{} mm: {}\n{}", written.worst, written.report, written.validation);
            assert!(
                written.again.contains("verdict: none"),
                "{}\n{}\n{}",
                written.report,
                written.validation,
                written.again
            );
        }
        let (_, c) = calibrate_text(&m, &csv, dir.path(), &offered, &o);
        let report = calibrate::text(&c.report, "FANUC");
        let Some(a) = c.report.accepted.iter().find(|a| a.label == "frame-compliance:J3") else { continue };
        named += 1;
        let unseen: Vec<usize> = (0..6).filter(|&k| a.se[k].is_nan()).collect();
        for &k in &unseen {
            assert_eq!(a.values[k], 0.0, "seed {seed}: {report}");
        }
        assert!(report.contains("moves with others where no point moves"), "seed {seed}: {report}");
        // Holding the combination loses nothing: the rows are explained to the noise.
        assert!(c.report.residual_scale < 1.3, "seed {seed}: {report}");
        // The turns, which the weight's moment (changing with the posture) sees, against the truth; the
        // translations left in the held combination take the held one's share (the data cannot say whose).
        coverage.add(&a.values[3..], &a.se[3..], &truth[3..]);
        held.push(unseen);
    }
    let (covered, draws, rms) = (coverage.covered, coverage.draws, coverage.rms());
    println!(
        "frame compliance, weight alone: named in {named} of 20; held {held:?}; {covered} of {draws} seen within two standard errors, rms {rms:.2}"
    );
    assert!(named >= 18, "named in {named} of 20");
    assert!(covered as f64 >= 0.9 * draws as f64, "{covered} of {draws}");
}

/// A compliance at the tool (a tool holder): this file's generator carries 80 kg at the tool on every
/// second configuration (given per row, `payload_kg`) and moves the target by 3e-4 mm/N times the force
/// along the flange frame's z (0.24 mm at most, the noise 0.0115 mm). Offered (`--candidates`, beside
/// every joint's compliance), `tool-compliance` is named in each of 40 seeds (with another effect in at
/// most 2: alpha 1% per step); its z compliance lies within two standard errors of the hidden 3e-4 mm/N
/// in at least 34 of 40 (the 1% lower bound of 40 draws at 95%), and x and y, hidden zero on the bound a
/// compliance has, come back held at zero or within two standard errors of it in at least 76 of 80. Run
/// once over 200 seeds: z 192 of 200 (96%, errors RMS 0.98 standard errors), x and y 392 of 400, another
/// effect named beside it in 1.
#[test]
fn a_compliance_at_the_tool_is_named_from_the_force_it_carries_and_covered() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let h = Hidden::registration_only();
    let hidden = [0.0, 0.0, 3e-4];
    let mut offered: Vec<ArmEffect> = JOINTS.iter().map(|j| effect(ArmKind::JointCompliance, j)).collect();
    offered.push(ArmEffect { kind: ArmKind::ToolCompliance, joint: 0 });
    let (mut coverage, mut at_zero, mut extra) = (Coverage::default(), 0, 0);
    for seed in 0..40 {
        let mut r = rng(52 + 1000 * seed);
        let mut csv = String::from("pose_id,q_J1,q_J2,q_J3,q_J4,q_J5,q_J6,mx_mm,my_mm,mz_mm,payload_kg\n");
        for c in 0..60 {
            let t = random_angles(&mut r);
            let kg = if c % 2 == 1 { 80.0 } else { 0.0 };
            let loaded = Hidden { payload: (kg, Vec3::zeros()), ..Hidden::registration_only() };
            let (_, frames) = dh_kinematics(&model_angles(&t));
            let axis = Vec3::new(frames[5][(0, 2)], frames[5][(1, 2)], frames[5][(2, 2)]);
            let holder = axis * (hidden[2] * axis.dot(&(h.gravity * kg)));
            let noise =
                Vec3::new(r.random_range(-1.0..1.0), r.random_range(-1.0..1.0), r.random_range(-1.0..1.0)) * 0.02;
            let p = measured_target(&loaded, &t, true) + rotation_from_vector(&h.rotation) * holder + noise;
            let q: Vec<String> = t.iter().map(|v| format!("{v:?}")).collect();
            csv += &format!("c{c},{},{:?},{:?},{:?},{kg}\n", q.join(","), p.x, p.y, p.z);
        }
        let (_, c) = calibrate_text(&m, &csv, dir.path(), &offered, &options(Some(0.02 / 3f64.sqrt())));
        let a = c.report.accepted.iter().find(|a| a.label == "tool-compliance");
        let a = a.unwrap_or_else(|| {
            panic!("seed {seed}: tool-compliance not named: {}", calibrate::text(&c.report, "FANUC"))
        });
        extra += usize::from(c.report.accepted.len() > 1);
        // z, the hidden compliance, against its standard error; x and y, hidden zero on the bound a
        // compliance has, come back held at zero (rigid: no standard error) or within two of zero.
        coverage.add(&a.values[2..], &a.se[2..], &hidden[2..]);
        for k in 0..2 {
            let held = a.se[k].is_nan() && a.values[k] == 0.0;
            at_zero += usize::from(held || a.values[k].abs() <= 2.0 * a.se[k]);
        }
    }
    let (covered, rms) = (coverage.covered, coverage.rms());
    println!("tool compliance: named with more in {extra} seeds; z: {covered} within two standard errors (error rms {rms:.2} of them); x, y: {at_zero} held at zero or within two of it");
    assert!(extra <= 2, "{extra} seeds named more");
    assert!(coverage.draws == 40 && covered >= 34 && at_zero >= 76, "z {covered} of 40, x and y {at_zero} of 80");
}

/// Regression: `plan` on a serial arm with a candidates file of joint columns and no rows panicked (the
/// calibration's problem read its first row's statics); it is an error that says there is nothing to plan
/// with, and nothing is written.
#[test]
fn a_plan_without_candidate_configurations_is_an_error_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let (candidates, plan) = (dir.path().join("none.csv"), dir.path().join("plan.csv"));
    std::fs::write(&candidates, "q_J1,q_J2,q_J3,q_J4,q_J5,q_J6\n").unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
        .args(["plan", FANUC, "--candidates"])
        .arg(&candidates)
        .args(["--budget", "1", "--noise", "0.05", "-o"])
        .arg(&plan)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("nothing to calibrate or plan with") && !err.contains("panicked"), "{err}");
    assert!(!plan.exists());
}

/// How a synthetic file writes the target's orientation.
#[derive(Clone, Copy, PartialEq)]
enum Written {
    Quaternion,
    RollPitchYawDegrees,
    RotationVector,
}

/// A joint-space file with the target's orientation beside its position: `sigma_mm` and `sigma_mrad` noise
/// (the orientation turned by a random rotation vector of that deviation per axis), the target's axes
/// `axes` in the DH flange frame, under the arm's weight where `gravity`, every third configuration held out.
fn synthetic_oriented(
    h: &Hidden,
    configurations: usize,
    noise: (f64, f64),
    axes: &Vec3,
    (written, gravity): (Written, bool),
    seed: u64,
) -> String {
    let mut r = rng(seed);
    let columns = match written {
        Written::Quaternion => "mqw,mqx,mqy,mqz",
        Written::RollPitchYawDegrees => "mroll_deg,mpitch_deg,myaw_deg",
        Written::RotationVector => "mrx_rad,mry_rad,mrz_rad",
    };
    let mut csv =
        format!("pose_id,q_J1,q_J2,q_J3,q_J4,q_J5,q_J6,mx_mm,my_mm,mz_mm,{columns},sigma_mm,sigma_mrad,set\n");
    for c in 0..configurations {
        let t = random_angles(&mut r);
        let (mut p, seen) = measured_pose(h, &t, gravity, axes);
        for a in 0..3 {
            p[a] += noise.0 * normal(&mut r);
        }
        let turn = Vec3::new(normal(&mut r), normal(&mut r), normal(&mut r)) * noise.1 * 1e-3;
        let seen = rotation_from_vector(&turn) * seen;
        let angles: Vec<f64> = match written {
            Written::Quaternion => {
                let q = nalgebra::UnitQuaternion::from_matrix(&seen);
                vec![q.w, q.i, q.j, q.k]
            }
            // R = Rz(yaw) Ry(pitch) Rx(roll).
            Written::RollPitchYawDegrees => vec![
                seen[(2, 1)].atan2(seen[(2, 2)]).to_degrees(),
                (-seen[(2, 0)]).asin().to_degrees(),
                seen[(1, 0)].atan2(seen[(0, 0)]).to_degrees(),
            ],
            // Axis times angle, from the quaternion: 2 atan2(|v|, w) v / |v|.
            Written::RotationVector => {
                let q = nalgebra::UnitQuaternion::from_matrix(&seen);
                let v = Vec3::new(q.i, q.j, q.k);
                (v * (2.0 * v.norm().atan2(q.w) / v.norm())).as_slice().to_vec()
            }
        };
        let q: Vec<String> = t.iter().chain(&[p.x, p.y, p.z]).chain(&angles).map(|v| format!("{v:?}")).collect();
        let set = if c % 3 == 2 { "check" } else { "fit" };
        csv += &format!("c{c},{},{},{},{set}\n", q.join(","), noise.0.max(0.01), noise.1.max(0.01));
    }
    csv
}

/// A measured orientation predicted exactly: a rigid FANUC, noise-free positions and orientations (as
/// quaternions) behind a hidden instrument frame, target and target axes, with encoder offsets on J2, J5 and
/// J4 fitted (J6's is the target's place and turn about the flange's axis: never identifiable). The instrument's frame comes back to 1e-9 mm and 1e-12 rad, the offsets to 1e-11 rad, and the
/// orientations' misfit is round-off (below 1e-8 mrad). The same file written as roll-pitch-yaw in degrees, or
/// as rotation vectors, is the same measurement: the offsets agree to 1e-11 rad.
#[test]
fn orientations_are_predicted_exactly_and_read_alike_as_quaternions_roll_pitch_yaw_or_rotation_vectors() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(true, dir.path());
    let h = Hidden { offsets: [0.0, 1.0e-3, 0.0, 1.5e-3, -2.0e-3, 0.0], ..Hidden::registration_only() };
    let axes = Vec3::new(0.2, -0.1, 0.3);
    let fitted = vec![
        effect(ArmKind::JointOffset, "J2"),
        effect(ArmKind::JointOffset, "J5"),
        effect(ArmKind::JointOffset, "J4"),
    ];
    let o = Options { fitted, max_effects: 0, ..options(None) };
    let mut offsets = Vec::new();
    for written in [Written::Quaternion, Written::RollPitchYawDegrees, Written::RotationVector] {
        let csv = synthetic_oriented(&h, 30, (0.0, 0.0), &axes, (written, false), 8);
        let (data, c) = calibrate_text(&m, &csv, dir.path(), &[], &o);
        let report = calibrate::text(&c.report, "rigid");
        assert!(data.unread.is_empty(), "{:?}", data.unread);
        let nuisance = |name: &str| Vec3::from(c.report.nuisance.iter().find(|n| n.name.contains(name)).unwrap().value);
        assert!((nuisance("translation") - h.translation).norm() < 1e-9, "{report}");
        assert!((nuisance("rotation") * 1e-3 - h.rotation).norm() < 1e-12, "{report}");
        assert!((nuisance("place") - h.target).norm() < 1e-9, "{report}");
        for (a, truth) in c.report.accepted.iter().zip([1.0e-3, -2.0e-3, 1.5e-3]) {
            assert!((a.values[0] - truth).abs() < 1e-11, "{}: {:e}\n{report}", a.label, a.values[0]);
        }
        let stage = c.report.stages.last().unwrap();
        let [fit, check] = stage.orientation.as_ref().expect("orientation errors");
        assert!(fit.rows == 20 && check.rows == 10, "{report}");
        assert!(fit.max < 1e-8 && check.max < 1e-8, "{report}");
        assert!(stage.fit.max < 1e-9, "{report}");
        offsets.push(c.report.accepted.iter().map(|a| a.values[0]).collect::<Vec<_>>());
    }
    for other in &offsets[1..] {
        for (q, o) in offsets[0].iter().zip(other) {
            assert!((q - o).abs() < 1e-11, "{offsets:?}");
        }
    }
}

/// What a measured orientation adds: J4's offset turns the wrist, which the positions see only through the
/// wrist's lever to the target, the orientations at full strength. Under the arm's own weight with 0.05 mm
/// and 0.1 mrad noise, the offset's standard error with orientations is below 0.8 of the one from the
/// positions alone (their information adds), and both estimates lie within four standard errors of the
/// hidden 1 mrad. On null data (the registration alone hidden) the selection names nothing in any of three
/// seeds, and where J4's offset is hidden it names that alone.
#[test]
fn a_measured_orientation_sharpens_a_wrist_offset_and_names_nothing_on_null_data() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let axes = Vec3::new(-0.3, 0.2, 0.1);
    let mut h = Hidden::registration_only();
    h.offsets[3] = 1.0e-3;
    let fitted = vec![effect(ArmKind::JointOffset, "J4")];
    let o = Options { fitted, max_effects: 0, ..options(None) };
    let csv = synthetic_oriented(&h, 45, (0.05, 0.1), &axes, (Written::Quaternion, true), 21);
    let (_, with) = calibrate_text(&m, &csv, dir.path(), &[], &o);
    // The same rows without their orientation columns.
    let positions: String = csv
        .lines()
        .map(|l| {
            let cells: Vec<&str> = l.split(',').collect();
            [&cells[..10], &cells[14..15], &cells[16..]].concat().join(",") + "\n"
        })
        .collect();
    assert!(positions.starts_with("pose_id,q_J1,q_J2,q_J3,q_J4,q_J5,q_J6,mx_mm,my_mm,mz_mm,sigma_mm,set\n"));
    let (_, without) = calibrate_text(&m, &positions, dir.path(), &[], &o);
    let (a, b) = (&with.report.accepted[0], &without.report.accepted[0]);
    assert!(
        a.se[0] < 0.8 * b.se[0],
        "with {:e} +- {:e}, without {:e} +- {:e}",
        a.values[0],
        a.se[0],
        b.values[0],
        b.se[0]
    );
    for e in [a, b] {
        assert!((e.values[0] - 1.0e-3).abs() < 4.0 * e.se[0], "{:e} +- {:e}", e.values[0], e.se[0]);
    }
    let (_, c) = calibrate_text(&m, &csv, dir.path(), &[], &options(None));
    let named: Vec<&str> = c.report.accepted.iter().map(|a| a.label.as_str()).collect();
    assert_eq!(named, ["joint-offset:J4"], "{}", calibrate::text(&c.report, "FANUC"));
    let h = Hidden::registration_only();
    for seed in 0..3 {
        let csv = synthetic_oriented(&h, 45, (0.05, 0.1), &axes, (Written::Quaternion, true), 300 + seed);
        let (_, c) = calibrate_text(&m, &csv, dir.path(), &[], &options(None));
        assert_eq!(c.report.verdict, Verdict::None, "seed {seed}: {}", calibrate::text(&c.report, "FANUC"));
    }
}

/// An orientation needs its standard deviation to be weighed against the positions: without a sigma_mrad
/// column or --sigma-mrad the report names the orientation columns as not read and says what to give, and
/// the positions are calibrated; with --sigma-mrad the report gives the orientation errors in mrad. A
/// quaternion that is not unit is a located error and nothing is written.
#[test]
fn orientations_without_a_standard_deviation_are_named_and_a_bad_quaternion_is_located() {
    let dir = tempfile::tempdir().unwrap();
    let h = Hidden::registration_only();
    let csv = synthetic_oriented(&h, 20, (0.05, 0.1), &Vec3::zeros(), (Written::Quaternion, true), 4);
    let without: String = csv
        .lines()
        .map(|l| {
            let cells: Vec<&str> = l.split(',').collect();
            [&cells[..15], &cells[16..]].concat().join(",") + "\n"
        })
        .collect();
    let path = dir.path().join("o.csv");
    std::fs::write(&path, &without).unwrap();
    let run = |extra: &[&str], path: &Path| {
        std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
            .args(["diagnose", FANUC, "--data"])
            .arg(path)
            .args(extra)
            .output()
            .unwrap()
    };
    let out = run(&[], &path);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report = String::from_utf8(out.stdout).unwrap();
    assert!(
        report.contains(
            "mqw, mqx, mqy, mqz (orientations without a standard deviation: give a sigma_mrad column or --sigma-mrad)"
        ),
        "{report}"
    );
    assert!(!report.contains("orientation error, mrad"), "{report}");
    let out = run(&["--sigma-mrad", "0.1"], &path);
    let report = String::from_utf8(out.stdout).unwrap();
    assert!(report.contains("orientation error, mrad") && !report.contains("columns not read"), "{report}");
    // The quaternion of the second data row stretched by 1%.
    let mut lines: Vec<String> = without.lines().map(String::from).collect();
    let mut cells: Vec<String> = lines[2].split(',').map(String::from).collect();
    cells[10] = format!("{:?}", cells[10].parse::<f64>().unwrap() * 1.01 + 0.01);
    lines[2] = cells.join(",");
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, lines.join("\n") + "\n").unwrap();
    let json = dir.path().join("v.json");
    let out = run(&["--sigma-mrad", "0.1", "--json", json.to_str().unwrap()], &bad);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.csv, line 3, column 11") && err.contains("not 1"), "{err}");
    assert!(!json.exists());
}

/// `stiff synth --orientation-noise` measures the target's orientation too (its axes hidden by
/// `target-axes`), and the calibration explains it: a 2 mrad offset of J4 and an added compliance of
/// 1e-9 rad/(N mm) at J2 behind a hidden instrument, target and target axes, 0.05 mm and 0.1 mrad noise,
/// on the shipped 43 cable-test configurations. Both effects are named and nothing else, each within four
/// standard errors, the target's axes within 0.1 mrad, and the held-out orientations' RMS error at the noise
/// (the length of a 3-vector of 0.1 mrad noise has an RMS of 0.17 mrad).
#[test]
fn synth_measures_orientations_that_the_calibration_explains() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("p.csv");
    synth_cable_tests(
        &data,
        &["--effect", "registration=0.1,0,0.2,1500,0,300", "--effect", "target=20,0,30"],
        &[
            "--effect",
            "target-axes=0.1,0.2,-0.3",
            "--effect",
            "joint-offset:J4=0.002",
            "--effect",
            "joint-compliance:J2=1e-9",
            "--noise",
            "0.05",
            "--orientation-noise",
            "0.1",
            "--seed",
            "3",
        ],
    );
    let m = fanuc(false, dir.path());
    let d = PositionData::read(&data, &m.joint_space.as_ref().unwrap().names).unwrap();
    let c = calibrate::calibrate(&m, &d, &[], &options(None)).unwrap();
    let report = calibrate::text(&c.report, "FANUC");
    let mut named: Vec<&str> = c.report.accepted.iter().map(|a| a.label.as_str()).collect();
    named.sort();
    assert_eq!(named, ["joint-compliance:J2", "joint-offset:J4"], "{report}");
    for (label, truth) in [("joint-offset:J4", 2e-3), ("joint-compliance:J2", 1e-9)] {
        let a = c.report.accepted.iter().find(|a| a.label == label).unwrap();
        assert!((a.values[0] - truth).abs() < 4.0 * a.se[0], "{label}: {report}");
    }
    let axes = Vec3::from(c.report.nuisance.iter().find(|n| n.name.contains("axes")).unwrap().value);
    assert!((axes - Vec3::new(100.0, 200.0, -300.0)).norm() < 0.1, "{report}");
    let [_, check] = c.report.stages.last().unwrap().orientation.clone().unwrap();
    assert!(check.rows == 14 && check.rms < 0.17 * 1.35, "{report}");
}

/// Regression: a row's misfit was judged gross against one robust scale over positions and orientations
/// together, so where one kind's stated sigma is off, the other's rows were judged on the wrong scale. Here
/// the orientations' sigma is stated ten times too large (1 mrad for 0.1 mrad of noise): against the pooled
/// scale an orientation turned by 3 mrad (3 stated sigma, 30 real) passed as sound and pulled the fit;
/// judged against the orientations' own scale it is named gross, and no other row is.
#[test]
fn a_gross_orientation_is_judged_against_the_orientations_own_scale() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let csv = synthetic_oriented(
        &Hidden::registration_only(),
        45,
        (0.05, 0.1),
        &Vec3::zeros(),
        (Written::Quaternion, true),
        17,
    );
    let mut lines: Vec<String> = csv.lines().map(String::from).collect();
    for (k, line) in lines.iter_mut().enumerate().skip(1) {
        let mut cells: Vec<String> = line.split(',').map(String::from).collect();
        cells[15] = "1".into();
        if k == 8 {
            // Turned by 3 mrad about the instrument's x: q' = (cos a/2, sin a/2, 0, 0) q.
            let q: Vec<f64> = cells[10..14].iter().map(|v| v.parse().unwrap()).collect();
            let (c, s) = ((1.5e-3f64).cos(), (1.5e-3f64).sin());
            let turned = [c * q[0] - s * q[1], c * q[1] + s * q[0], c * q[2] - s * q[3], c * q[3] + s * q[2]];
            for (cell, v) in cells[10..14].iter_mut().zip(turned) {
                *cell = format!("{v:?}");
            }
        }
        *line = cells.join(",");
    }
    assert!(lines[0].split(',').nth(15) == Some("sigma_mrad"));
    let (_, c) = calibrate_text(&m, &(lines.join("\n") + "\n"), dir.path(), &[], &options(None));
    let named: Vec<(&str, &str)> = c.report.left_out.iter().map(|g| (g.row.as_str(), g.unit.as_str())).collect();
    assert_eq!(named, [("c7 (line 9, orientation)", "mrad")], "{}", calibrate::text(&c.report, "FANUC"));
    // About 3 mrad off, in the unit given.
    assert!((c.report.left_out[0].misfit - 3.0).abs() < 0.5, "{}", c.report.left_out[0].misfit);
}

/// A plan for an instrument that measures orientations too (`plan --orientation-noise`): its signatures'
/// orientation rows are the derivative of the measured orientation (its rotation vector) in J4's offset and
/// J3's added compliance, equal to central finite differences of this file's own generator to 1% (weighted
/// by 1/noise, one sign for all rows); the target's axes join the nuisance parameters (12 columns); and on
/// the 43 cable-test configurations the plan detects J4's offset beside J5's and J2's compliance at a smaller
/// size with orientations at 0.1 mrad than from positions alone.
#[test]
fn a_plan_with_orientations_weighs_what_they_tell() {
    let m = fanuc(false, Path::new("."));
    let mut r = rng(33);
    let (noise, turn_noise) = (0.05, 1e-4);
    let angles: Vec<[f64; 6]> = (0..6).map(|_| random_angles(&mut r)).collect();
    let configurations: Vec<calibrate::Configuration> =
        angles.iter().enumerate().map(|(k, t)| (format!("c{k}"), t.to_vec(), Default::default())).collect();
    let effects = [effect(ArmKind::JointOffset, "J4"), effect(ArmKind::JointCompliance, "J3")];
    let found = calibrate::signatures(&m, &configurations, None, &effects, noise, Some(turn_noise)).unwrap();
    assert_eq!((found.usable.len(), found.rows_per_candidate, found.nuisance.ncols()), (6, 6, 12));
    let level = Hidden { rotation: Vec3::zeros(), translation: Vec3::zeros(), ..Hidden::registration_only() };
    let difference = |change: &dyn Fn(&mut Hidden, f64), h: f64, t: &[f64; 6]| -> Vec3 {
        let (mut up, mut down) = (level.clone(), level.clone());
        change(&mut up, h);
        change(&mut down, -h);
        let (a, b) = (measured_pose(&up, t, true, &Vec3::zeros()).1, measured_pose(&down, t, true, &Vec3::zeros()).1);
        stiff::kinematics::frame::rotation_vector(&(a * b.transpose())) / (2.0 * h) / turn_noise
    };
    assert_signatures_are_differences(&found, &angles, 3, (6, 3), difference);
    let detectable = |extra: &[&str]| -> f64 {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
            .args(["plan", FANUC, "--candidates", "manipulators/grids/fanuc-r2000ic-cable-tests.csv"])
            .args([
                "--budget",
                "15",
                "--noise",
                "0.05",
                "--effects",
                "joint-offset:J4,joint-offset:J5,joint-compliance:J2",
            ])
            .args(["-o", "-"])
            .args(extra)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let report = String::from_utf8(out.stdout).unwrap();
        let line = report.lines().find(|l| l.trim_start().starts_with("joint-offset:J4")).expect("J4's line");
        line.split_whitespace().last().unwrap().parse().unwrap()
    };
    let (with, without) = (detectable(&["--orientation-noise", "0.1"]), detectable(&[]));
    assert!(with < without, "J4's offset detectable at {with:e} rad with orientations, {without:e} without");
}

/// Play (`backlash:J`): the generator turns J2 by 1 mrad in the sense of its load (the weight's torque,
/// whose sign follows the arm's lean) at every configuration, behind a hidden instrument frame and target,
/// with 0.05 mm noise over 60 random configurations, a third held out. The calibration names J2's play and
/// nothing else, its value within four standard errors of 1 mrad; the same data without the play name
/// nothing.
#[test]
fn a_joints_play_is_named_from_the_sign_of_its_load() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let mut h = Hidden::registration_only();
    h.play[1] = 1e-3;
    let csv = synthetic(&h, 60, 0.05, &[], true, 41);
    let (_, c) = calibrate_text(&m, &csv, dir.path(), &[], &options(Some(0.05)));
    let report = calibrate::text(&c.report, "FANUC");
    let named: Vec<&str> = c.report.accepted.iter().map(|a| a.label.as_str()).collect();
    assert_eq!(named, ["backlash:J2"], "{report}");
    let a = &c.report.accepted[0];
    assert!((a.values[0] - 1e-3).abs() < 4.0 * a.se[0], "{report}");
    let csv = synthetic(&Hidden::registration_only(), 60, 0.05, &[], true, 41);
    let (_, c) = calibrate_text(&m, &csv, dir.path(), &[], &options(Some(0.05)));
    assert_eq!(c.report.verdict, Verdict::None, "{}", calibrate::text(&c.report, "FANUC"));
}

/// `stiff synth --effect backlash:J2=0.001` measures each configuration with J2's model coordinate 1 mrad off
/// in the sense of its load there (play, which no description holds), at the robot's exact loaded
/// equilibrium; the calibration names J2's play alone, within four standard errors of 1 mrad.
#[test]
fn synth_hides_a_joints_play_that_the_calibration_names() {
    let dir = tempfile::tempdir().unwrap();
    let points = random_configurations(dir.path(), 43);
    let data = dir.path().join("play.csv");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
        .args(["synth", FANUC, "--points"])
        .arg(&points)
        .args(["--effect", "registration=0.1,-0.2,0.3,1500,-300,200", "--effect", "target=20,-10,30"])
        .args(["--effect", "backlash:J2=0.001", "--noise", "0.05", "--seed", "5", "--check-every", "3", "-q", "-o"])
        .arg(&data)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let m = fanuc(false, dir.path());
    let d = PositionData::read(&data, &m.joint_space.as_ref().unwrap().names).unwrap();
    let c = calibrate::calibrate(&m, &d, &[], &options(Some(0.05))).unwrap();
    let report = calibrate::text(&c.report, "FANUC");
    let named: Vec<&str> = c.report.accepted.iter().map(|a| a.label.as_str()).collect();
    assert_eq!(named, ["backlash:J2"], "{report}");
    assert!((c.report.accepted[0].values[0] - 1e-3).abs() < 4.0 * c.report.accepted[0].se[0], "{report}");
}

/// Regressions from fuzzed position files (the physics: every measurement either enters the fit with its
/// weight or is named as left out; none counts twice). A blank `mx_mm` cell dropped its row with no message:
/// it is named with its line and counted in the JSON. A repeated `mx_mm` column, or `mx_mm..` beside
/// `mx_m..`, counted every row twice (standard errors shrunk by sqrt(2)): located errors. One blank `sigma_mm`
/// cell turned the statistical test off for the whole file: that row takes the file's median sigma, said.
#[test]
fn position_files_name_every_measurement_they_do_not_use_and_count_none_twice() {
    let dir = tempfile::tempdir().unwrap();
    let h = Hidden::registration_only();
    let data = synthetic(&h, 20, 0.05, &[], true, 5).replace(",check\n", ",fit\n");
    let run = |csv: &str, json: bool| {
        std::fs::write(dir.path().join("d.csv"), csv).unwrap();
        let mut command = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"));
        command.args(["diagnose", FANUC, "--data"]).arg(dir.path().join("d.csv"));
        if json {
            command.arg("--json").arg(dir.path().join("c.json"));
        }
        let out = command.output().unwrap();
        let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
        (out.status.success(), text(&out.stdout), text(&out.stderr))
    };
    // A blank cell on the fourth line: named, counted, the other 19 rows fitted.
    let mut lines: Vec<String> = data.lines().map(String::from).collect();
    let cells: Vec<&str> = lines[3].split(',').collect();
    let blanked: Vec<String> =
        cells.iter().enumerate().map(|(i, c)| if i == 8 { String::new() } else { c.to_string() }).collect();
    lines[3] = blanked.join(",");
    let (ok, text, err) = run(&(lines.join("\n") + "\n"), true);
    assert!(ok, "{err}");
    assert!(
        text.contains("19 rows fitted")
            && text
                .contains("measurement not used: line 4 (c2): the target not measured there (an empty `my_mm` cell)"),
        "{text}"
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("c.json")).unwrap()).unwrap();
    assert_eq!(v["calibration"]["not_used_count"], 1);
    // Repeated columns: located errors, nothing fitted.
    // The file with its header line and each data line (numbered from 1) rewritten.
    let edited = |header: &dyn Fn(&str) -> String, row: &dyn Fn(usize, &str) -> String| -> String {
        let mut lines = data.lines();
        let mut out = header(lines.next().unwrap()) + "\n";
        for (k, l) in lines.enumerate() {
            out += &(row(k + 1, l) + "\n");
        }
        out
    };
    let cells = |l: &str| l.split(',').map(String::from).collect::<Vec<_>>();
    let twice = edited(&|h| h.replacen("mx_mm,", "mx_mm,mx_mm,", 1), &|_, l| {
        let c = cells(l);
        format!("{},{}", c[..8].join(","), c[7..].join(","))
    });
    let (ok, _, err) = run(&twice, false);
    assert!(!ok && err.contains("line 1, column 9") && err.contains("the column `mx_mm` is given twice"), "{err}");
    let metres = edited(&|h| format!("{h},mx_m,my_m,mz_m"), &|_, l| {
        let m: Vec<String> = cells(l)[7..10].iter().map(|v| (v.parse::<f64>().unwrap() / 1000.0).to_string()).collect();
        format!("{l},{}", m.join(","))
    });
    let (ok, _, err) = run(&metres, false);
    assert!(!ok && err.contains("`mx_mm` and `mx_m` give the same target's position"), "{err}");
    // A blank sigma cell: the row takes the file's median, the test of what is left stays on.
    let with_sigma =
        edited(&|h| format!("{h},sigma_mm"), &|k, l| if k == 5 { format!("{l},") } else { format!("{l},0.05") });
    let (ok, text, err) = run(&with_sigma, false);
    assert!(ok, "{err}");
    assert!(text.contains("note: 1 rows without a sigma_mm (lines 6) take the file's median sigma, 0.05 mm"), "{text}");
    assert!(!text.contains("the noise level was not given"), "{text}");
}

/// Regression: a model named by a bare file name (its folder the working folder) kept its URDF's relative
/// path when `--model-out` wrote the corrected model to another folder, which then could not be read. The
/// written model names the URDF relative to itself (`../fanuc-r2000ic.urdf`), and loads where it is written
/// and where the two folders are moved together.
#[test]
fn a_model_written_elsewhere_finds_its_urdf_relative_to_itself() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy("manipulators/fanuc-r2000ic.urdf", dir.path().join("fanuc-r2000ic.urdf")).unwrap();
    std::fs::copy(FANUC, dir.path().join("arm.toml")).unwrap();
    let h = Hidden::registration_only();
    std::fs::write(dir.path().join("d.csv"), synthetic(&h, 20, 0.05, &[], true, 2)).unwrap();
    std::fs::create_dir(dir.path().join("out")).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
        .current_dir(dir.path())
        .args(["diagnose", "arm.toml", "--data", "d.csv", "--sigma", "0.05", "--model-out", "out/c.toml"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    stiff::model::load_manipulator(&dir.path().join("out/c.toml")).unwrap();
    // The reference is relative to the written file, so the folders can move together.
    let written = std::fs::read_to_string(dir.path().join("out/c.toml")).unwrap();
    assert!(written.contains("file = \"../fanuc-r2000ic.urdf\""), "{written}");
    let moved = tempfile::tempdir().unwrap();
    std::fs::create_dir(moved.path().join("out")).unwrap();
    std::fs::copy(dir.path().join("fanuc-r2000ic.urdf"), moved.path().join("fanuc-r2000ic.urdf")).unwrap();
    std::fs::copy(dir.path().join("out/c.toml"), moved.path().join("out/c.toml")).unwrap();
    drop(dir);
    stiff::model::load_manipulator(&moved.path().join("out/c.toml")).unwrap();
}

/// The report says why the selection stopped: on data with nothing but the registration, the best
/// candidate left with its test, against the threshold it had to pass (alpha over the candidates tested).
#[test]
fn the_report_says_why_the_selection_stopped() {
    let dir = tempfile::tempdir().unwrap();
    let h = Hidden::registration_only();
    std::fs::write(dir.path().join("d.csv"), synthetic(&h, 20, 0.05, &[], true, 3)).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
        .args(["diagnose", FANUC, "--sigma", "0.05", "--data"])
        .arg(dir.path().join("d.csv"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && text.contains("verdict: none"), "{text}");
    let line = text.lines().find(|l| l.starts_with("selection stopped: ")).unwrap_or_else(|| panic!("{text}"));
    assert!(line.contains("the best candidate left, ") && line.contains("needs p below"), "{line}");
}

/// Regression: check rows of a set-up whose frame its fit rows cannot fix (two configurations measured in
/// position: a frame has six parameters, two points fix five) were predicted through an arbitrary frame,
/// reported as gross rows up to a metre off, and the run said `effect`. The set-up is named as one that
/// cannot be placed, with the reason, and its rows are kept out of the fit and the verdict.
#[test]
fn a_set_up_the_fit_cannot_place_is_named_and_kept_out_of_the_verdict() {
    let dir = tempfile::tempdir().unwrap();
    let h = Hidden::registration_only();
    let data = synthetic(&h, 24, 0.05, &[], true, 8).replace(",check\n", ",fit\n");
    let rows: String = data
        .lines()
        .enumerate()
        .map(|(k, l)| match k {
            0 => format!("{l},setup\n"),
            // The last three rows: a second set-up, two fitted, one held out (its frame unknown to the fit).
            22 | 23 => format!("{l},b\n"),
            24 => format!("{},b\n", l.replace(",fit", ",check")),
            _ => format!("{l},a\n"),
        })
        .collect();
    std::fs::write(dir.path().join("d.csv"), rows).unwrap();
    let data = dir.path().join("d.csv");
    let text = crate::common::run_stiff(&["diagnose", FANUC, "--sigma", "0.05", "--data", data.to_str().unwrap()]);
    assert!(
        text.contains("set-up `b` cannot be placed: its fit rows measure 2 configurations (3 are needed"),
        "{text}"
    );
    assert!(text.contains("21 rows fitted, 0 held out") && text.contains("verdict: none"), "{text}");
    assert!(!text.contains("gross row left out"), "{text}");
}

/// A repeated measurement is predicted once (the fit's shortcut for files of many repeats): least squares over
/// k repeats of a configuration equals least squares over their mean with sigma / sqrt(k) (the normal
/// equations are the same), so the fit of 12 configurations measured 5 times each (noise 0.05 mm) gives the
/// values of the fit of the 12 means, weighted so, to 1e-6 of a standard error (3e-9 of the values here: the
/// two fits sum their rows in different orders, and the fit's conditioning carries that round-off into the
/// values; tighter convergence of the fit or of its exact passes does not move it). (The standard errors differ
/// where they are scaled by the residual: the repeats' scatter about their means is in the one, not the other.)
#[test]
fn repeated_measurements_fit_as_their_means_do() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let mut h = Hidden::registration_only();
    h.compliance[1] = 1.7;
    let mut r = rng(41);
    let (mut repeated, mut means) = (String::new(), String::new());
    let header = "pose_id,q_J1,q_J2,q_J3,q_J4,q_J5,q_J6,mx_mm,my_mm,mz_mm,sigma_mm\n";
    repeated += header;
    means += header;
    for c in 0..12 {
        let t = random_angles(&mut r);
        let truth = measured_target(&h, &t, true);
        let q: Vec<String> = t.iter().map(|v| format!("{v:?}")).collect();
        let mut sum = Vec3::zeros();
        for _ in 0..5 {
            let mut seen = truth;
            for a in 0..3 {
                seen[a] += 0.05 * normal(&mut r);
            }
            sum += seen;
            repeated += &format!("c{c},{},{:?},{:?},{:?},0.05\n", q.join(","), seen.x, seen.y, seen.z);
        }
        let mean = sum / 5.0;
        means += &format!("c{c},{},{:?},{:?},{:?},{:?}\n", q.join(","), mean.x, mean.y, mean.z, 0.05 / 5f64.sqrt());
    }
    let fitted = [effect(ArmKind::JointCompliance, "J2"), effect(ArmKind::JointOffset, "J3")];
    let options = Options { fitted: fitted.to_vec(), max_effects: 0, ..options(None) };
    let (_, a) = calibrate_text(&m, &repeated, dir.path(), &[], &options);
    let (_, b) = calibrate_text(&m, &means, dir.path(), &[], &options);
    assert_eq!(a.report.accepted.len(), 2);
    for (x, y) in a.report.accepted.iter().zip(&b.report.accepted) {
        assert_eq!(x.label, y.label);
        assert!((x.values[0] - y.values[0]).abs() <= 1e-6 * y.se[0], "{}: {} vs {}", x.label, x.values[0], y.values[0]);
    }
}

/// Regression: a set-up with three configurations, one of them a gross row: once the screening leaves it
/// fewer than three points its frame has more parameters than they fix, and its held-out row was predicted through an arbitrary
/// frame and called a gross row metres off (2,528 mm in a file of 22 set-ups). The set-up is named as one
/// its gross rows leave unplaceable, its rows kept out of the figures and the verdict. `--residuals` writes
/// every row with its residual (instrument frame and base axes) and why it is left out, and the report gives
/// the 95th percentiles horizontally and vertically.
#[test]
fn a_set_up_its_gross_rows_leave_unplaceable_is_named_and_residuals_are_written() {
    let dir = tempfile::tempdir().unwrap();
    let h = Hidden::registration_only();
    let data = synthetic(&h, 25, 0.05, &[22], true, 9).replace(",check\n", ",fit\n");
    let rows: String = data
        .lines()
        .enumerate()
        .map(|(k, l)| match k {
            0 => format!("{l},setup\n"),
            // The last four rows: a second set-up, three fitted (the first of them gross), one held out.
            22..=24 => format!("{l},b\n"),
            25 => format!("{},b\n", l.replace(",fit", ",check")),
            _ => format!("{l},a\n"),
        })
        .collect();
    std::fs::write(dir.path().join("d.csv"), rows).unwrap();
    let residuals = dir.path().join("residuals.csv");
    let data = dir.path().join("d.csv");
    let text = crate::common::run_stiff(&[
        "diagnose",
        FANUC,
        "--sigma",
        "0.05",
        "--data",
        data.to_str().unwrap(),
        "--residuals",
        residuals.to_str().unwrap(),
    ]);
    assert!(text.contains("set-up `b` cannot be placed: its fit rows, without its gross ones, measure "), "{text}");
    assert!(!text.contains("gross row left out"), "{text}");
    assert!(text.contains("verdict: none") && text.contains("p95_xy    p95_z"), "{text}");
    let mut reader = csv::Reader::from_path(&residuals).unwrap();
    let header = reader.headers().unwrap().clone();
    let column = |name: &str| header.iter().position(|h| h == name).unwrap_or_else(|| panic!("{name}: {header:?}"));
    let rows: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
    assert_eq!(rows.len(), 25);
    for row in &rows {
        let b = &row[column("setup")] == "b";
        assert_eq!(&row[column("left_out")] == "its set-up cannot be placed", b, "{row:?}");
        // The length is the residual's, and the base-axes residual has the same length (a rotation).
        let e: Vec<f64> = ["ex_mm", "ey_mm", "ez_mm", "e_mm", "base_ex_mm", "base_ey_mm", "base_ez_mm"]
            .iter()
            .map(|c| row[column(c)].parse().unwrap())
            .collect();
        assert!((e[0].hypot(e[1]).hypot(e[2]) - e[3]).abs() < 1e-12 * e[3].max(1.0));
        assert!((e[4].hypot(e[5]).hypot(e[6]) - e[3]).abs() < 1e-9 * e[3].max(1.0));
        if !b {
            assert!(e[3] < 0.5, "{row:?}");
        }
    }
}

/// A calibrated model validated on new data: the corrections `--model-out` wrote from one file (an offset
/// of J2, J3 1.8 times as compliant, a 20 kg payload; noise 0.05 mm) are checked on a second file of the same
/// hidden robot measured from another instrument station with another target (its frame and place unknown
/// to the model). `--validate` fits only that set-up: the corrected model's held-out rows sit at the noise
/// (RMS of a 3-vector of 0.05 mm per axis: 0.087 mm) with verdict `none`, while the nominal model's, its
/// set-up fitted alike, miss by the hidden effects (`unexplained`, several times the noise). Neither run
/// offers an effect, and a validation with --candidates is refused.
#[test]
fn a_calibrated_model_is_validated_on_new_data_by_fitting_only_the_set_up() {
    let dir = tempfile::tempdir().unwrap();
    let mut h = Hidden::registration_only();
    h.offsets[1] = 1.5e-3;
    h.compliance[2] = 1.8;
    h.payload = (20.0, Vec3::new(30.0, 0.0, 100.0));
    let first = dir.path().join("first.csv");
    std::fs::write(&first, synthetic(&h, 60, 0.05, &[], true, 91)).unwrap();
    h.rotation = Vec3::new(-0.4, 0.1, 1.2);
    h.translation = Vec3::new(-800.0, 2100.0, -150.0);
    h.target = Vec3::new(-15.0, 40.0, 55.0);
    // The second file marks no rows `check`: --validate holds out half of its configurations.
    let second = dir.path().join("second.csv");
    let unmarked: String = synthetic(&h, 40, 0.05, &[], true, 92)
        .lines()
        .map(|l| l.rsplit_once(',').unwrap().0.to_string() + "\n")
        .collect();
    std::fs::write(&second, unmarked).unwrap();
    let corrected = dir.path().join("corrected.toml");
    let run = |model: &Path, data: &Path, extra: &[&str]| {
        let json = dir.path().join("c.json");
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
            .arg("diagnose")
            .arg(model)
            .args(["--sigma", "0.05", "--data"])
            .arg(data)
            .arg("--json")
            .arg(&json)
            .args(extra)
            .output()
            .unwrap();
        let text = String::from_utf8(out.stdout).unwrap();
        assert!(out.status.success(), "{}{text}", String::from_utf8_lossy(&out.stderr));
        let c: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        (text, c["calibration"].clone())
    };
    let (text, _) = run(Path::new(FANUC), &first, &["--model-out", corrected.to_str().unwrap()]);
    assert!(text.contains("verdict: effect"), "{text}");
    let held_out =
        |c: &serde_json::Value| c["stages"].as_array().unwrap().last().unwrap()["check"]["rms"].as_f64().unwrap();
    let (text, c) = run(&corrected, &second, &["--validate"]);
    assert!(text.contains("verdict: none"), "{text}");
    assert!(c["accepted"].as_array().unwrap().is_empty(), "{text}");
    assert_eq!(c["rows"][1].as_u64(), Some(20), "{text}");
    let rms = held_out(&c);
    assert!(rms < 0.087 * 1.3, "held-out RMS {rms}\n{text}");
    let (text, c) = run(Path::new(FANUC), &second, &["--validate"]);
    assert!(text.contains("verdict: unexplained"), "{text}");
    assert!(held_out(&c) > 3.0 * rms && c["accepted"].as_array().unwrap().is_empty(), "{text}");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
        .args(["diagnose", FANUC, "--validate", "--candidates", "payload", "--data"])
        .arg(&second)
        .output()
        .unwrap();
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("--candidates"));
}

/// The FANUC's description read again with text appended, as `stiff diagnose` rebuilds it with the
/// corrections it writes.
fn fanuc_rebuild() -> Option<calibrate::Rebuild> {
    let source = std::fs::read_to_string(FANUC).unwrap();
    Some(calibrate::Rebuild::of_description(Path::new(FANUC), source, Default::default(), None))
}

/// The hidden robot of the exactness tests: the registration, J2 1.5352 times as compliant as the source
/// says (the factor the blinded benchmark got back as 1.541 +- 0.001 when compliances acted at first order
/// about the nominal sag), J3's encoder 1.2 mrad off and 20 kg carried 100 mm along the tool's z.
fn softer_j2() -> Hidden {
    let mut h = Hidden::registration_only();
    h.compliance[1] = 1.5352;
    h.offsets[2] = 1.2e-3;
    h.payload = (20.0, Vec3::new(0.0, 0.0, 100.0));
    h
}

/// The candidates `softer_j2`'s hidden effects stand among: both compliances and both offsets of J2 and
/// J3, and the payload.
fn softer_j2_candidates() -> Vec<ArmEffect> {
    vec![
        effect(ArmKind::JointCompliance, "J2"),
        effect(ArmKind::JointCompliance, "J3"),
        effect(ArmKind::JointOffset, "J2"),
        effect(ArmKind::JointOffset, "J3"),
        ArmEffect { kind: ArmKind::Payload, joint: 0 },
    ]
}

/// The calibration fits the model with its effects built in, not their first order: on noise-free data
/// from this file's exact equilibrium of the joints' springs under the weights (`loaded_angles`), the
/// effects fitted by name come back to round-off of the sag (J2's factor 1.5352 to 1e-6, the offset to
/// 1e-9 rad, the mass to 1e-5 kg) and every residual is below 1e-6 mm. The same fit with the effects at
/// first order about the model's sag (no rebuilt description) leaves J2's factor off by more than 1e-4.
#[test]
fn effects_fitted_on_exact_data_come_back_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let h = softer_j2();
    let csv = synthetic(&h, 40, 0.0, &[], true, 7);
    let fitted = vec![
        effect(ArmKind::JointCompliance, "J2"),
        effect(ArmKind::JointOffset, "J3"),
        ArmEffect { kind: ArmKind::Payload, joint: 0 },
    ];
    let c2 = 1.0 / K_JOINT[1];
    let factor_of = |rebuild: Option<calibrate::Rebuild>| {
        let o = Options { fitted: fitted.clone(), rebuild, ..options(Some(0.01)) };
        let (_, c) = calibrate_text(&m, &csv, dir.path(), &fitted, &o);
        let value = |label: &str| c.report.accepted.iter().find(|a| a.label == label).unwrap().values.clone();
        ((c2 + value("joint-compliance:J2")[0]) / c2, value("joint-offset:J3")[0], value("payload")[0], c)
    };
    let (factor, offset, mass, c) = factor_of(fanuc_rebuild());
    let report = calibrate::text(&c.report, "FANUC");
    assert!((factor - 1.5352).abs() < 1e-6, "factor {factor}: {report}");
    assert!((offset - 1.2e-3).abs() < 1e-9, "offset {offset}: {report}");
    assert!((mass - 20.0).abs() < 1e-5, "mass {mass}: {report}");
    for stage in [&c.report.stages.last().unwrap().fit, &c.report.stages.last().unwrap().check] {
        assert!(stage.max < 1e-6, "{report}");
    }
    let (first_order, ..) = factor_of(None);
    assert!((first_order - 1.5352).abs() > 1e-4, "first order {first_order}");
}

/// At SNR >= 100 (J2's extra sag is up to a millimetre, the noise 0.01 mm), over 100 seeds: candidates
/// the hidden effects stand among (both compliances, both offsets, the payload) name J2's compliance,
/// J3's offset and the payload, never fewer, more in at most 5 seeds (alpha 1%); J2's factor errs by its
/// standard errors with mean 0 and RMS 1, and lies within two of them of 1.5352 in about 95% of the seeds
/// (printed; over 600 seeds 571 of 598).
#[test]
fn a_compliance_factor_is_named_and_covered_by_its_standard_errors_over_seeds() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let h = softer_j2();
    let c2 = 1.0 / K_JOINT[1];
    let (seeds, mut covered, mut z, mut extra) = (100, 0, Vec::new(), 0);
    let o = Options { rebuild: fanuc_rebuild(), ..options(Some(0.01)) };
    let candidates = softer_j2_candidates();
    for seed in 0..seeds {
        let csv = synthetic(&h, 40, 0.01, &[], true, 5000 + seed);
        let (_, c) = calibrate_text(&m, &csv, dir.path(), &candidates, &o);
        let report = calibrate::text(&c.report, "FANUC");
        let mut named: Vec<String> = c.report.accepted.iter().map(|a| a.label.clone()).collect();
        named.sort();
        if named != ["joint-compliance:J2", "joint-offset:J3", "payload"] {
            assert!(named.len() > 3, "seed {seed}: a hidden effect missed: {report}");
            extra += 1;
            continue;
        }
        let a = c.report.accepted.iter().find(|a| a.label == "joint-compliance:J2").unwrap();
        let (factor, se) = ((c2 + a.values[0]) / c2, a.se[0] / c2);
        covered += usize::from((factor - 1.5352).abs() <= 2.0 * se);
        z.push((factor - 1.5352) / se);
    }
    let mean = z.iter().sum::<f64>() / z.len() as f64;
    let rms = (z.iter().map(|v| v * v).sum::<f64>() / z.len() as f64).sqrt();
    println!("J2's factor within two standard errors in {covered} of {} seeds; its error in standard errors: mean {mean:.3}, rms {rms:.3}; {extra} seeds named more", z.len());
    // A fit with the right standard errors errs by them with mean 0 and RMS 1 (t with ~100 degrees of
    // freedom: 1.01); over 100 seeds the RMS scatters by 7% and the coverage of 95.4% by 2 points: the
    // bounds are 3 of those from the truth. (Here the first order's bias is 0.2 standard errors; its
    // exactness is `effects_fitted_on_exact_data_come_back_exactly`'s.)
    assert!(extra <= 5, "{extra} seeds named an effect not hidden");
    assert!(mean.abs() < 0.3 && (0.8..1.25).contains(&rms), "mean {mean}, rms {rms}");
    assert!(covered as f64 >= 0.89 * z.len() as f64, "covered in {covered} of {} seeds", z.len());
}

/// The model `--model-out` writes reproduces the fit: validated on the same data (only the set-up fitted,
/// on the same rows), every row's residual is the calibration's to 1e-6 mm, fitted and held-out rows alike.
#[test]
fn the_written_model_reproduces_the_calibrations_residuals() {
    let dir = tempfile::tempdir().unwrap();
    let written =
        write_and_validate(dir.path(), &synthetic(&softer_j2(), 40, 0.01, &[], true, 11), "joint-compliance:J2", &[]);
    println!("the written model's residuals differ from the fit's by at most {:.2e} mm", written.worst);
    assert!(written.worst < 1e-6, "{} mm\n{}\n{}", written.worst, written.report, written.validation);
}

/// Play is a model term (`[[joint_correction]] play`, every loaded study seeing the joint turned by it in the
/// sense of its load): J2's play of 1 mrad found in data that hide it is written so, the model written
/// reproduces the fit's residuals to 1e-6 mm (validated on the same rows), and the same data diagnosed with
/// it name nothing more. (Before, play was written as a comment: the model written named it again.)
#[test]
fn a_found_play_is_written_as_a_model_term_that_reproduces_the_fit() {
    let dir = tempfile::tempdir().unwrap();
    let mut h = Hidden::registration_only();
    h.play[1] = 1e-3;
    let written = write_and_validate(dir.path(), &synthetic(&h, 60, 0.01, &[], true, 41), "backlash:J2", &[]);
    assert!(written.model.contains("joint = \"J2\"\nplay = 0.00"), "{}", written.model);
    println!("the written model's residuals differ from the fit's by at most {:.2e} mm", written.worst);
    assert!(written.worst < 1e-6, "{} mm\n{}\n{}", written.worst, written.report, written.validation);
    assert!(written.again.contains("verdict: none"), "{}", written.again);
}

/// What `write_and_validate` found.
struct WrittenModel {
    report: String,
    model: String,
    validation: String,
    /// The written model diagnosed again on the same data, every default candidate offered.
    again: String,
    /// The largest difference between a row's residual in the fit and in the validation, mm.
    worst: f64,
}

/// `csv` calibrated (sigma 0.01 mm, `--model-out`, `--residuals`), its report naming `named`; the model
/// written validated on the same data (`--validate`) and diagnosed again.
fn write_and_validate(dir: &Path, csv: &str, named: &str, candidates: &[&str]) -> WrittenModel {
    let data = dir.join("d.csv");
    std::fs::write(&data, csv).unwrap();
    let (r1, r2, model) = (dir.join("r1.csv"), dir.join("r2.csv"), dir.join("c.toml"));
    let p = |p: &Path| p.to_str().unwrap().to_string();
    let run = |args: &[String]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff")).args(args).output().unwrap();
        assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8(out.stdout).unwrap()
    };
    let common = ["--data".to_string(), p(&data), "--sigma".into(), "0.01".into()];
    let mut first = vec!["diagnose".to_string(), FANUC.into()];
    first.extend(common.iter().cloned().chain(["--residuals".into(), p(&r1), "--model-out".into(), p(&model)]));
    if !candidates.is_empty() {
        first.extend(["--candidates".to_string(), candidates.join(",")]);
    }
    let report = run(&first);
    assert!(report.contains(named), "{report}");
    let mut second = vec!["diagnose".to_string(), p(&model), "--validate".into()];
    second.extend(common.iter().cloned().chain(["--residuals".into(), p(&r2)]));
    let validation = run(&second);
    let mut third = vec!["diagnose".to_string(), p(&model)];
    third.extend(common.iter().cloned());
    let again = run(&third);
    let columns = ["ex_mm", "ey_mm", "ez_mm"];
    let (a, b) = (
        crate::common::csv_columns(&std::fs::read_to_string(&r1).unwrap(), &columns),
        crate::common::csv_columns(&std::fs::read_to_string(&r2).unwrap(), &columns),
    );
    assert!(!a.is_empty() && a.len() == b.len());
    let worst = a.iter().zip(&b).flat_map(|(x, y)| x.iter().zip(y).map(|(u, v)| (u - v).abs())).fold(0.0, f64::max);
    WrittenModel { report, model: std::fs::read_to_string(&model).unwrap(), validation, again, worst }
}

/// Regression: an impossible value was accepted and written (a compliance whose total fell below zero,
/// shown as `stiffness -1.4438e4 N m/rad`, after which the written file was refused; a negative play). A
/// robot whose J2 rises under the weights (its compliance -0.5 times the source's) and whose J3 has play
/// of -1 mrad (taken up against its load) is none: the compliance is tested and not accepted, saying the
/// joint's compliance would not be above zero; the play is held at zero and said so; the model written
/// loads.
#[test]
fn a_compliance_below_zero_or_a_negative_play_is_never_accepted() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let mut h = Hidden::registration_only();
    h.compliance[1] = -0.5;
    h.play[2] = -1e-3;
    let csv = synthetic(&h, 40, 0.01, &[], true, 3);
    let candidates = [effect(ArmKind::JointCompliance, "J2"), effect(ArmKind::Backlash, "J3")];
    let o = Options { rebuild: fanuc_rebuild(), ..options(Some(0.01)) };
    let (_, c) = calibrate_text(&m, &csv, dir.path(), &candidates, &o);
    let report = calibrate::text(&c.report, "FANUC");
    assert!(c.report.accepted.is_empty(), "{report}");
    let first = &c.report.steps[0];
    let j2 = first.iter().find(|t| t.label == "joint-compliance:J2").unwrap();
    assert!(j2.note.as_deref().is_some_and(|n| n.contains("not above zero")), "{report}");
    assert!(report.contains("not physical: joint-compliance:J2: not accepted"), "{report}");
    assert!(report.contains("not physical: backlash:J3: fitted below zero and held at zero"), "{report}");
    let written = dir.path().join("c.toml");
    let source = std::fs::read_to_string(FANUC).unwrap();
    let model_dir = std::fs::canonicalize("manipulators").unwrap();
    std::fs::write(&written, calibrate::corrected_model(&source, &model_dir, None, &c, false)).unwrap();
    stiff::model::load_manipulator(&written).unwrap();
}

/// Regression: an effect the held-out rows do not confirm (their RMS error grows with it) stayed in the
/// written model. On one seed of `softer_j2`'s data J3's compliance is accepted beside the three hidden
/// effects and not confirmed: the written model leaves it out, saying so, and writes it when asked
/// (`--write-unconfirmed`).
#[test]
fn an_effect_the_held_out_rows_do_not_confirm_is_not_written_unless_asked() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let candidates = softer_j2_candidates();
    let o = Options { rebuild: fanuc_rebuild(), ..options(Some(0.01)) };
    let (_, c) = calibrate_text(&m, &synthetic(&softer_j2(), 40, 0.01, &[], true, 5062), dir.path(), &candidates, &o);
    let report = calibrate::text(&c.report, "FANUC");
    let j3 = c.report.accepted.iter().find(|a| a.label == "joint-compliance:J3").expect(&report);
    assert_eq!(j3.confirmed, Some(false), "{report}");
    let source = std::fs::read_to_string(FANUC).unwrap();
    let model_dir = std::fs::canonicalize("manipulators").unwrap();
    let table = "joint = \"J3\"\ncompliance = ";
    let without = calibrate::corrected_model(&source, &model_dir, None, &c, false);
    assert!(!without.contains(table) && without.contains("# joint-compliance:J3: "), "{without}");
    assert!(without.contains("joint = \"J2\"\ncompliance = "), "{without}");
    let with = calibrate::corrected_model(&source, &model_dir, None, &c, true);
    assert!(with.contains(table), "{with}");
}

/// Regression: an effect the report called not identifiable was accepted (a 120 mrad, 1.56 m geometry of a
/// column's base). The fixed transform before J1 moves the whole arm as the instrument's frame does: its
/// translations and its turn about the vertical are the registration's, in directions no row tells apart;
/// only its tilts are seen, through the weight's lever that they turn. A compliance at J1's frame likewise
/// moves with the registration in part. Neither is accepted (each is refused whole, or tested in the
/// directions the rows see only, and found wanting), and J2's compliance, which the data hold, is named.
/// Fitted in by force, the geometry at J1 keeps the combinations that move with the registration at their
/// nominal value (its translations at zero, no standard error) and says so; the instrument's translation is
/// then fitted, seen, where before the geometry took a share of it; its turns cover zero and the fit is
/// as good as without them.
#[test]
fn a_candidate_whose_values_move_with_the_registration_is_not_accepted() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let candidates = [
        effect(ArmKind::JointGeometry, "J1"),
        effect(ArmKind::FrameCompliance, "J1"),
        effect(ArmKind::JointCompliance, "J2"),
    ];
    let o = Options { rebuild: fanuc_rebuild(), ..options(Some(0.01)) };
    let mut h = Hidden::registration_only();
    h.compliance[1] = 1.5;
    let csv = synthetic(&h, 40, 0.01, &[], true, 4);
    let (_, c) = calibrate_text(&m, &csv, dir.path(), &candidates, &o);
    let report = calibrate::text(&c.report, "FANUC");
    let named: Vec<&str> = c.report.accepted.iter().map(|a| a.label.as_str()).collect();
    assert_eq!(named, ["joint-compliance:J2"], "{report}");
    let geometry = effect(ArmKind::JointGeometry, "J1");
    let forced = Options { fitted: vec![geometry, effect(ArmKind::JointCompliance, "J2")], max_effects: 0, ..o };
    let (_, c) = calibrate_text(&m, &csv, dir.path(), &[], &forced);
    let report = calibrate::text(&c.report, "FANUC");
    let g = c.report.accepted.iter().find(|a| a.label == "joint-geometry:J1").unwrap();
    // Translation x y z (mm), rotation x y z (rad), in J1's frame.
    for a in 0..3 {
        assert!(g.values[a] == 0.0 && g.se[a].is_nan(), "component {a}: {} +- {}: {report}", g.values[a], g.se[a]);
    }
    // Its turns, barely seen (the weight's lever they turn is second order, left to the exact passes), are
    // fitted with wide standard errors that cover the truth, zero; and fitting them costs the fit nothing.
    // (Regression: the effects' first order turned the unloaded target, which differs from the set-up's
    // turn of the loaded one by the sag; the tilts seemed seen through that difference, came back at 6
    // standard errors, and the fit ended at 1.31 sigma where the model without them gives 0.97.)
    for a in 3..6 {
        let (v, se) = (g.values[a], g.se[a]);
        assert!(se.is_finite() && v.abs() < 3.0 * se, "rotation {a}: {v} +- {se}: {report}");
    }
    assert!(c.report.residual_scale < 1.1, "{report}");
    // The instrument's translation is then the set-up's own, seen (before, the geometry took a share of it
    // and the instrument's translation was reported not seen).
    let instrument = c.report.nuisance.iter().find(|n| n.name.starts_with("instrument: translation")).unwrap();
    assert!(instrument.se.iter().all(|se| se.is_finite()), "{report}");
    let tied = c.report.not_identifiable.iter().filter(|l| l.starts_with("joint-geometry:J1 translation")).count();
    assert_eq!(tied, 3, "{report}");
    assert!(report.contains("moves with others where no point moves"), "{report}");
}

/// Two encoder offsets on adjacent joints, under the arm's weight, behind a hidden instrument frame and
/// target, 0.05 mm noise: the later joint's geometry (six parameters) explains both as well as the two
/// offsets do, and was named in their place (4 of 4 such sets of a blinded benchmark; here, before the
/// split of `select.rs::best_split`, in all 9 sets here). The two offsets are named, nothing else, each value within 4
/// standard errors, for three pairs of joints over three seeds each.
#[test]
fn two_offsets_on_adjacent_joints_are_named_as_offsets_not_as_a_geometry() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let names = &m.joint_space.as_ref().unwrap().names;
    let mut h = Hidden::registration_only();
    for (a, b) in [(1usize, 2usize), (2, 3), (3, 4)] {
        h.offsets = [0.0; 6];
        h.offsets[a] = 1.5e-3;
        h.offsets[b] = -2.0e-3;
        for seed in 0..3 {
            let csv = synthetic(&h, 60, 0.05, &[], true, 300 + seed);
            let (_, c) = calibrate_text(&m, &csv, dir.path(), &[], &options(Some(0.05)));
            let report = calibrate::text(&c.report, "FANUC");
            let mut named: Vec<&str> = c.report.accepted.iter().map(|e| e.label.as_str()).collect();
            named.sort();
            let expected = [effect(ArmKind::JointOffset, JOINTS[a]), effect(ArmKind::JointOffset, JOINTS[b])];
            let labels: Vec<String> = expected.iter().map(|e| e.label(names)).collect();
            assert_eq!(named, labels, "J{} and J{}, seed {seed}: {report}", a + 1, b + 1);
            for (j, label) in [a, b].iter().zip(&labels) {
                let e = c.report.accepted.iter().find(|e| &e.label == label).unwrap();
                // Offsets are reported on the controller's angles, where they were hidden.
                let truth = h.offsets[*j];
                assert!(
                    (e.values[0] - truth).abs() < 4.0 * e.se[0],
                    "{label}: {} +- {} vs {truth}: {report}",
                    e.values[0],
                    e.se[0]
                );
            }
        }
    }
}

/// How often fitted values lie within two standard errors of the truth, over the parameters the data see
/// (a finite standard error), and the errors in standard errors.
#[derive(Default)]
struct Coverage {
    draws: usize,
    covered: usize,
    errors: Vec<f64>,
}

impl Coverage {
    fn add(&mut self, values: &[f64], se: &[f64], truth: &[f64]) {
        for ((v, s), t) in values.iter().zip(se).zip(truth).filter(|((_, s), _)| s.is_finite()) {
            self.draws += 1;
            self.covered += usize::from((v - t).abs() <= 2.0 * s);
            self.errors.push((v - t) / s);
        }
    }

    /// The errors' RMS, in standard errors.
    fn rms(&self) -> f64 {
        (self.errors.iter().map(|v| v * v).sum::<f64>() / self.errors.len() as f64).sqrt()
    }
}

/// The model with the effects `c` found, fitted from the start on the same data: nothing more to name.
fn assert_corrected_names_nothing_more(
    m: &Manipulator,
    data: &PositionData,
    c: &calibrate::Calibration,
    o: &Options,
    what: &str,
) {
    let corrected = Options { fitted: c.effects.clone(), ..o.clone() };
    let again = calibrate::calibrate(m, data, &[], &corrected).unwrap();
    let more: Vec<&str> = again.report.accepted[c.effects.len()..].iter().map(|a| a.label.as_str()).collect();
    assert!(more.is_empty(), "{what}: the corrected model names {more:?}");
}

/// Every effect kind the exact simulator of this file hides, one at a time at SNR >= 100 (each moves the
/// target by a millimetre or more, the noise 0.01 mm), 40 seeds per kind, the default candidates: the
/// effect is named in every seed (alone in all but a few: alpha 1% per step), the model corrected by it
/// (fitted from the start) names nothing more on the same data in every seed, and its value lies within two
/// standard errors of the truth in about 95% of the seeds (printed per kind). 34 of 40 is the 1% lower
/// bound of 40 draws covered with probability 95%. Over 200 seeds (run once): offset 188 (94%, errors in
/// standard errors RMS 0.99), payload 189 (94.5%, 1.02), play 184 (92%, 1.12; 169, 84.5% and 1.38 while a
/// description held no play and its fit stayed first order about the model's sag: it is now the loaded
/// equilibrium of the arm with the play written in). A joint's compliance has its own test over 100 seeds
/// (`a_compliance_factor_is_named_and_covered_by_its_standard_errors_over_seeds`).
#[test]
fn each_effect_kind_is_named_and_covered_by_its_standard_errors_and_its_corrected_model_names_none() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let names = &m.joint_space.as_ref().unwrap().names;
    let o = Options { rebuild: fanuc_rebuild(), ..options(Some(0.01)) };
    type Kind = (&'static str, ArmEffect, f64, fn(&mut Hidden));
    let kinds: [Kind; 3] = [
        ("offset", effect(ArmKind::JointOffset, "J3"), 1.2e-3, |h| h.offsets[2] = 1.2e-3),
        ("play", effect(ArmKind::Backlash, "J2"), 1e-3, |h| h.play[1] = 1e-3),
        ("payload", ArmEffect { kind: ArmKind::Payload, joint: 0 }, 40.0, |h| {
            h.payload = (40.0, Vec3::new(0.0, 0.0, 100.0))
        }),
    ];
    for (kind, e, truth, hide) in kinds {
        let mut h = Hidden::registration_only();
        hide(&mut h);
        let label = e.label(names);
        let (mut coverage, mut exact, mut extra) = (Coverage::default(), 0, 0);
        for seed in 0..40 {
            // Play is seen through the rows whose load has the less common sign: 60 configurations.
            let configurations = if kind == "play" { 60 } else { 40 };
            let csv = synthetic(&h, configurations, 0.01, &[], true, 7000 + seed);
            let (data, c) = calibrate_text(&m, &csv, dir.path(), &[], &o);
            let report = calibrate::text(&c.report, "FANUC");
            let a = c.report.accepted.iter().find(|a| a.label == label);
            let a = a.unwrap_or_else(|| panic!("{kind}, seed {seed}: {label} not named: {report}"));
            exact += usize::from(c.report.accepted.len() == 1);
            extra += usize::from(c.report.accepted.len() > 1);
            coverage.add(&a.values[..1], &a.se[..1], &[truth]);
            assert_corrected_names_nothing_more(&m, &data, &c, &o, &format!("{kind}, seed {seed}"));
        }
        let (covered, rms) = (coverage.covered, coverage.rms());
        println!("{kind}: named in 40 of 40 seeds (alone in {exact}); within two standard errors in {covered} of 40; error in standard errors rms {rms:.2}");
        assert!(extra <= 2, "{kind}: {extra} seeds named more");
        assert!(coverage.draws == 40 && covered >= 34, "{kind}: covered in {covered} of 40");
    }
}

/// A joint's geometry, hidden by the simulator's own kinematics (the DH table with the fixed transform
/// leading to J3 changed by T(d) R(r) in the joint's frame, `dh_kinematics_changed`), at SNR >= 100 (each
/// component moves the target by a millimetre or more, the noise 0.01 mm), 40 seeds, the default
/// candidates: `joint-geometry:J3` is named in every seed, the model corrected by it names nothing more,
/// and each of its parameters the data see lies within two standard errors of the truth in about 95% of
/// the draws: at least 216 of the 240 (90%: below the 1% lower bound of 240 independent draws at 95%,
/// about 220, since a seed's six are not independent). Run once over 200 seeds: named alone in 199 of 200,
/// every parameter seen, 1,136 of 1,200 covered (94.7%), errors RMS 1.00 standard errors: the simulator's
/// frame for the change (the DH table's, turned by its offset) is the description's joint frame.
#[test]
fn a_joints_geometry_is_named_and_covered_by_its_standard_errors() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let o = Options { rebuild: fanuc_rebuild(), ..options(Some(0.01)) };
    let truth = [1.5, -1.0, 2.0, 1.0e-3, -1.5e-3, 1.2e-3];
    let h = Hidden { geometry: Some((2, truth)), ..Hidden::registration_only() };
    let (mut coverage, mut alone) = (Coverage::default(), 0);
    for seed in 0..40 {
        let csv = synthetic(&h, 40, 0.01, &[], true, 9100 + seed);
        let (data, c) = calibrate_text(&m, &csv, dir.path(), &[], &o);
        let report = calibrate::text(&c.report, "FANUC");
        let a = c.report.accepted.iter().find(|a| a.label == "joint-geometry:J3");
        let a = a.unwrap_or_else(|| panic!("seed {seed}: joint-geometry:J3 not named: {report}"));
        alone += usize::from(c.report.accepted.len() == 1);
        coverage.add(&a.values, &a.se, &truth);
        assert_corrected_names_nothing_more(&m, &data, &c, &o, &format!("seed {seed}"));
    }
    let (covered, draws, rms) = (coverage.covered, coverage.draws, coverage.rms());
    println!("geometry: named in 40 of 40 seeds (alone in {alone}); {covered} of {draws} seen parameters within two standard errors; error in standard errors rms {rms:.2}");
    assert!(draws == 240 && covered >= 216, "{covered} of {draws}");
}

/// A target's place the rows cannot tell from the instrument's translation is not given a standard error it
/// does not have: every configuration at one tool orientation (J1 fixed, J4 and J6 at zero, J5 turning back
/// what J2 and J3 turn), so the target's lever R_tool t is one vector in every row, which the instrument's
/// translation takes; on noise-level data the arm's sag under its own weight turns the tool by too little to
/// separate them. Their components are reported `not-seen` (no standard error in the JSON), the
/// combinations are named under not identifiable, the fit keeps the target's start there (the tool point),
/// and the rows sit at the noise.
#[test]
fn a_target_place_no_row_sees_is_reported_not_seen_and_kept_at_its_start() {
    let dir = tempfile::tempdir().unwrap();
    let m = fanuc(false, dir.path());
    let h = Hidden::registration_only();
    let mut r = rng(77);
    let mut csv = String::from("pose_id,q_J1,q_J2,q_J3,q_J4,q_J5,q_J6,mx_mm,my_mm,mz_mm,set\n");
    for c in 0..45 {
        // The model's q5 = -t5 and q3 = -(t2 + t3): J2, J3 and J5 parallel (q4 = 0) and q2 + q3 + q5 fixed.
        let t3: f64 = r.random_range(-1.0..1.0);
        let t = [0.3, r.random_range(-0.5..0.8), t3, 0.0, -1.5 - t3, 0.0];
        let mut p = measured_target(&h, &t, true);
        for a in 0..3 {
            p[a] += 0.05 * normal(&mut r);
        }
        let q: Vec<String> = t.iter().map(|v| format!("{v:?}")).collect();
        let set = if c % 3 == 2 { "check" } else { "fit" };
        csv += &format!("c{c},{},{:?},{:?},{:?},{set}\n", q.join(","), p.x, p.y, p.z);
    }
    let (_, c) = calibrate_text(&m, &csv, dir.path(), &[], &options(Some(0.05)));
    let report = calibrate::text(&c.report, "FANUC");
    let target = c.report.nuisance.iter().find(|n| n.name.starts_with("target")).unwrap();
    assert!(target.se.iter().all(|e| e.is_nan()), "{report}");
    assert!(Vec3::from(target.value).norm() < 5.0, "kept near its start, the tool point: {report}");
    assert!(report.contains("fitted target: place in the tool frame, mm:") && report.contains("not-seen"), "{report}");
    assert!(c.report.not_identifiable.iter().any(|n| n.contains("the target's place") && !n.contains(':')), "{report}");
    assert!(c.report.left_out.is_empty(), "{report}");
    assert!(c.report.stages.last().unwrap().check.rms < 0.087 * 1.35, "{report}");
    // The rows at several tool orientations see it: a standard error again, the place recovered.
    let csv = synthetic(&h, 45, 0.05, &[], true, 77);
    let (_, c) = calibrate_text(&m, &csv, dir.path(), &[], &options(Some(0.05)));
    let target = c.report.nuisance.iter().find(|n| n.name.starts_with("target")).unwrap();
    assert!(target.se.iter().all(|e| e.is_finite()), "{}", calibrate::text(&c.report, "FANUC"));
    assert!((Vec3::from(target.value) - h.target).norm() < 0.1, "{:?}", target.value);
}
