//! Calibration of a parallel robot's legs against positions in an instrument's frame at commanded poses
//! (`stiff diagnose` with `x_mm,y_mm,z_mm` and `mx_mm,my_mm,mz_mm` columns, `src/diagnose/calibrate.rs`).
//! The synthetic data come from the Orthoglide 3-PUU's own kinematics written here, not from stiff: leg i's
//! actuator slides along base axis e_i and its parallelogram of length L keeps the platform point p at
//! |p - (q_i - L) e_i| = L (paper 001's geometry: at q = 0 every leg lies along its actuator and p = 0); the
//! platform only translates.

use std::path::Path;

use rand::Rng;
use stiff::diagnose::calibrate::{
    self, ArmEffect, ArmKind, Calibration, CalibrationOptions as Options, CalibrationVerdict as Verdict,
};
use stiff::diagnose::positions::PositionData;
use stiff::kinematics::frame::{rotation_from_vector, Mat3, Vec3};
use stiff::platform::manipulator::Manipulator;

use crate::common::rng;

/// The Orthoglide's leg length, mm (manipulators/orthoglide-3puu.toml).
const L: f64 = 310.25;
const MODEL: &str = "manipulators/orthoglide-3puu.toml";

/// The actuators' coordinates that put the platform point at `p` (the branch with the legs pointing back
/// along their actuators): q_i = p_i + L - sqrt(L^2 - |p|^2 + p_i^2).
fn inverse(p: &Vec3) -> [f64; 3] {
    std::array::from_fn(|i| p[i] + L - (L * L - p.norm_squared() + p[i] * p[i]).sqrt())
}

/// Where the platform point is with the actuators at `q`: Newton's method on the three constraints
/// (p_i - q_i + L)^2 + sum_{j != i} p_j^2 = L^2, from the point the nominal coordinates command.
fn forward(q: &[f64; 3], start: &Vec3) -> Vec3 {
    let mut p = *start;
    for _ in 0..50 {
        let mut f = Vec3::zeros();
        let mut jac = Mat3::zeros();
        for i in 0..3 {
            let mut c = p;
            c[i] -= q[i] - L;
            f[i] = c.norm_squared() - L * L;
            for j in 0..3 {
                jac[(i, j)] = 2.0 * c[j];
            }
        }
        let step = jac.lu().solve(&f).expect("a regular pose");
        p -= step;
        if step.norm() < 1e-13 {
            break;
        }
    }
    p
}

/// What the synthetic robot and instrument hide.
struct Hidden {
    /// The instrument's frame: base point p is seen at R p + t (R from this rotation vector).
    rotation: Vec3,
    translation: Vec3,
    /// The target's place on the platform, mm.
    target: Vec3,
    /// Each actuator's offset (where it sits minus where it is commanded), mm.
    offsets: [f64; 3],
}

/// A standard normal number (Box-Muller).
fn normal(r: &mut rand::rngs::StdRng) -> f64 {
    let (u, v): (f64, f64) = (r.random_range(1e-12..1.0), r.random_range(0.0..1.0));
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// A measurement file of `poses` random commanded poses in the Orthoglide's cubic workspace (every third
/// held out), each measured where the actuators with their offsets put the platform, noise `sigma` per
/// coordinate, the poses in `gross` moved 5 mm along a random direction.
fn synthetic(h: &Hidden, poses: usize, sigma: f64, gross: &[usize], seed: u64) -> String {
    let mut r = rng(seed);
    let instrument = rotation_from_vector(&h.rotation);
    let mut csv = String::from("pose_id,x_mm,y_mm,z_mm,mx_mm,my_mm,mz_mm,set\n");
    for c in 0..poses {
        let commanded = Vec3::from_fn(|_, _| r.random_range(-73.65..126.35));
        let q = inverse(&commanded);
        let real: [f64; 3] = std::array::from_fn(|i| q[i] + h.offsets[i]);
        let p = forward(&real, &commanded);
        let mut m = instrument * (p + h.target) + h.translation;
        for a in 0..3 {
            m[a] += sigma * normal(&mut r);
        }
        if gross.contains(&c) {
            m += Vec3::new(normal(&mut r), normal(&mut r), normal(&mut r)).normalize() * 5.0;
        }
        let set = if c % 3 == 2 { "check" } else { "fit" };
        csv += &format!(
            "p{c},{:?},{:?},{:?},{:?},{:?},{:?},{set}\n",
            commanded.x, commanded.y, commanded.z, m.x, m.y, m.z
        );
    }
    csv
}

/// Runs `stiff synth --positions` on `model` at `poses` (`--grid FILE` or `--points FILE`) with the hidden
/// `effects` (each an `--effect` value), 0.002 mm of noise, `seed` and every third pose held out, then `stiff
/// diagnose` on what it wrote: the report's text, its JSON's `calibration` and the data written.
fn synth_and_calibrate(
    model: &str,
    poses: [&str; 2],
    effects: &[&str],
    seed: &str,
) -> (String, serde_json::Value, String) {
    let dir = tempfile::tempdir().unwrap();
    let (data, json) = (dir.path().join("synth.csv"), dir.path().join("c.json"));
    let mut args = vec!["synth", model, poses[0], poses[1], "--positions"];
    for e in effects {
        args.extend(["--effect", e]);
    }
    args.extend(["--noise", "0.002", "--seed", seed, "--check-every", "3", "-o", data.to_str().unwrap()]);
    crate::common::run_stiff(&args);
    let text = crate::common::run_stiff(&[
        "diagnose",
        model,
        "--data",
        data.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    let c: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    (text, c["calibration"].clone(), std::fs::read_to_string(&data).unwrap())
}

fn orthoglide() -> Manipulator {
    stiff::model::load_manipulator(Path::new(MODEL)).unwrap()
}

fn calibrated(m: &Manipulator, csv: &str, dir: &Path, options: &Options) -> (PositionData, Calibration) {
    let path = dir.join("legs.csv");
    std::fs::write(&path, csv).unwrap();
    let data = PositionData::read(&path, &[]).unwrap();
    let c = calibrate::calibrate(m, &data, &[], options).unwrap();
    (data, c)
}

fn offset(leg: usize) -> ArmEffect {
    ArmEffect { kind: ArmKind::JointOffset, joint: leg }
}

fn options(sigma: f64, fitted: Vec<ArmEffect>) -> Options {
    Options { alpha: 0.01, sigma: Some(sigma), sigma_rad: None, fitted, max_effects: 6, rebuild: None, progress: None }
}

/// The three actuators' offsets (up to 1.2 mm) and the instrument's frame, from noise-free positions at 30
/// commanded poses of the independent kinematics above, the offsets fitted as a geometric calibration
/// fits its list: the offsets and every position come back to 1e-9 mm (3e-12 mm in a run). The first order alone
/// misses by the offsets' second order (a few um): the exact loaded equilibrium of the robot with the
/// offsets built in completes it. The target's place on a platform that only translates is the instrument's
/// translation: reported as not identifiable, never fitted.
#[test]
fn a_parallel_robots_actuator_offsets_are_recovered_exactly_from_positions_at_commanded_poses() {
    let dir = tempfile::tempdir().unwrap();
    let m = orthoglide();
    let h = Hidden {
        rotation: Vec3::new(0.2, -0.1, 0.4),
        translation: Vec3::new(800.0, -250.0, 1200.0),
        target: Vec3::new(15.0, -25.0, 40.0),
        offsets: [0.8, -0.5, 1.2],
    };
    let csv = synthetic(&h, 30, 0.0, &[], 3);
    let (_, c) = calibrated(&m, &csv, dir.path(), &options(1e-9, (0..3).map(offset).collect()));
    let report = calibrate::text(&c.report, MODEL);
    for (k, a) in c.report.accepted.iter().take(3).enumerate() {
        assert!(
            (a.values[0] - h.offsets[k]).abs() < 1e-9,
            "leg {}: {} against {}\n{report}",
            k + 1,
            a.values[0],
            h.offsets[k]
        );
    }
    let last = c.report.stages.last().unwrap();
    assert!(last.fit.max < 1e-9 && last.check.max < 1e-9, "{last:?}\n{report}");
    let rotation = c.report.nuisance.iter().find(|n| n.name.contains("rotation")).unwrap().value;
    assert!((Vec3::from(rotation) * 1e-3 - h.rotation).norm() < 1e-9, "{rotation:?}\n{report}");
    assert!(c.report.not_identifiable.iter().any(|n| n.contains("target's place")), "{report}");
    assert_ne!(c.report.verdict, Verdict::Unexplained, "{report}");
}

/// Two actuators' offsets behind a hidden instrument frame, 0.02 mm noise, one gross row in 60 poses and a
/// third held out, every default candidate offered (each actuator's offset, compliance and play, a payload)
/// and each leg's geometry asked for: the two offsets are named and nothing else, each within 4 standard
/// errors (a leg's geometry holds its offset: the offset is kept where its other directions are not needed), the
/// gross row is named, and the held-out rows' RMS error is at the noise (a 3-vector of 0.02 mm noise has
/// an RMS length of 0.035 mm).
#[test]
fn a_parallel_robots_offsets_are_named_among_every_leg_effect_and_confirmed_on_held_out_rows() {
    let dir = tempfile::tempdir().unwrap();
    let m = orthoglide();
    let h = Hidden {
        rotation: Vec3::new(-0.3, 0.1, 0.2),
        translation: Vec3::new(-400.0, 900.0, 150.0),
        target: Vec3::new(-20.0, 10.0, 35.0),
        offsets: [0.8, 0.0, -0.6],
    };
    let csv = synthetic(&h, 60, 0.02, &[7], 11);
    let path = dir.path().join("legs.csv");
    std::fs::write(&path, csv).unwrap();
    let data = PositionData::read(&path, &[]).unwrap();
    let kinds = [ArmKind::JointOffset, ArmKind::JointCompliance, ArmKind::Backlash, ArmKind::JointGeometry];
    let mut candidates: Vec<ArmEffect> =
        (0..3).flat_map(|joint| kinds.iter().map(move |&kind| ArmEffect { kind, joint })).collect();
    candidates.push(ArmEffect { kind: ArmKind::Payload, joint: 0 });
    let c = calibrate::calibrate(&m, &data, &candidates, &options(0.02, Vec::new())).unwrap();
    let report = calibrate::text(&c.report, MODEL);
    let named: Vec<&str> = c.report.accepted.iter().map(|a| a.label.as_str()).collect();
    assert_eq!(c.report.verdict, Verdict::Effect, "{report}");
    let mut sorted = named.clone();
    sorted.sort();
    assert_eq!(sorted, ["joint-offset:1", "joint-offset:3"], "{report}");
    for a in &c.report.accepted {
        let truth = h.offsets[a.joint.parse::<usize>().unwrap() - 1];
        assert!((a.values[0] - truth).abs() < 4.0 * a.se[0], "{}: {} +- {}\n{report}", a.label, a.values[0], a.se[0]);
        assert_eq!(a.confirmed, Some(true), "{report}");
    }
    assert_eq!(c.report.left_out.len(), 1, "{report}");
    assert!(c.report.left_out[0].row.starts_with("p7"), "{report}");
    let last = c.report.stages.last().unwrap();
    assert!(last.check.rms < 0.05, "{last:?}\n{report}");
}

/// From the command line: positions at commanded poses make `stiff diagnose` calibrate the parallel robot;
/// `--model-out` writes the offsets found as `[[actuator_offset]]` tables, and against that description the
/// same data calibrate to `none` with the held-out rows at the noise (every study of the corrected file sees
/// the actuators where the data put them). Actuators' readings without the commanded pose are refused,
/// saying what to give, and a compliance at a frame (a serial arm's effect) is refused by name.
#[test]
fn the_command_line_calibrates_a_parallel_robot_and_its_corrected_description_explains_the_data() {
    let dir = tempfile::tempdir().unwrap();
    let h = Hidden {
        rotation: Vec3::new(0.0, 0.0, 1.5),
        translation: Vec3::new(1000.0, 500.0, 200.0),
        target: Vec3::zeros(),
        offsets: [0.6, -0.7, 0.0],
    };
    let data = dir.path().join("legs.csv");
    std::fs::write(&data, synthetic(&h, 60, 0.02, &[], 5)).unwrap();
    let corrected = dir.path().join("corrected.toml");
    let run = |model: &Path, extra: &[&str]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
            .arg("diagnose")
            .arg(model)
            .args(["--sigma", "0.02", "--data"])
            .arg(&data)
            .args(extra)
            .output()
            .unwrap();
        (out.status.success(), String::from_utf8(out.stdout).unwrap(), String::from_utf8(out.stderr).unwrap())
    };
    let (ok, first, err) = run(Path::new(MODEL), &["--model-out", corrected.to_str().unwrap()]);
    assert!(ok, "{err}");
    assert!(
        first.contains("verdict: effect") && first.contains("joint-offset:1") && first.contains("joint-offset:2"),
        "{first}"
    );
    let text = std::fs::read_to_string(&corrected).unwrap();
    assert_eq!(text.matches("[[actuator_offset]]").count(), 2, "{text}");
    let (ok, second, err) = run(&corrected, &[]);
    assert!(ok, "{err}");
    assert!(second.contains("verdict: none"), "{second}");
    let (ok, _, err) = run(Path::new(MODEL), &["--fit", "frame-compliance:2"]);
    assert!(!ok && err.contains("frame-compliance:2") && err.contains("serial arm"), "{err}");
    std::fs::write(&data, "q_1,q_2,q_3,mx_mm,my_mm,mz_mm\n0,0,0,1,2,3\n").unwrap();
    let (ok, _, err) = run(Path::new(MODEL), &[]);
    assert!(!ok && err.contains("commanded pose: x_mm,y_mm,z_mm"), "{err}");
}

/// `stiff synth --positions` writes a parallel robot's measurements as a lab records them (here the robot's
/// exact loaded equilibrium under the milling wrench, with actuator 1 sitting 0.5 mm off and actuator 2
/// three times as compliant, behind a hidden instrument frame and target, 0.002 mm noise, 2% gross rows
/// of 3 mm, every third pose held out), and `stiff diagnose` names the offset and the compliance, each
/// within 4 standard errors, with the gross rows named and the held-out RMS at the noise (0.0035 mm for a
/// 3-vector). The Orthoglide turns by 0.05 rad under that wrench: the target's lever is carried by the
/// turn exactly (at first order the positions missed by 2e-4 mm and the compliance came out 4.1 times).
#[test]
fn synth_positions_of_a_parallel_robot_round_trip_through_the_calibration() {
    let grid = ["--grid", "manipulators/grids/orthoglide-small.toml"];
    let hidden = [
        "registration=0.1,0.2,-0.3,1000,200,-50",
        "target=10,-5,20",
        "actuator-offset:1=0.5",
        "actuator-compliance:2=3",
        "gross=0.02,3",
    ];
    let (text, c, csv) = synth_and_calibrate(MODEL, grid, &hidden, "4");
    let accepted = c["accepted"].as_array().unwrap();
    let labels: Vec<&str> = accepted.iter().map(|a| a["label"].as_str().unwrap()).collect();
    assert_eq!(labels, ["joint-offset:1", "joint-compliance:2"], "{text}");
    let compliance = 1.0 / 20491.0;
    for (a, truth) in accepted.iter().zip([0.5, 2.0 * compliance]) {
        let (v, se) = (a["values"][0].as_f64().unwrap(), a["se"][0].as_f64().unwrap());
        assert!((v - truth).abs() < 4.0 * se, "{v} +- {se} against {truth}\n{text}");
    }
    let hidden = csv.lines().filter(|l| l.ends_with(",1")).count();
    assert_eq!(c["left_out"].as_array().unwrap().len(), hidden, "{text}");
    let last = c["stages"].as_array().unwrap().last().unwrap().clone();
    assert!(last["check"]["rms"].as_f64().unwrap() < 0.005, "{text}");
}

/// Over 12 seeds of the independent generator (offsets of actuators 1 and 3, 0.02 mm noise, 45 poses, a
/// third held out), the two offsets are named and nothing else in at least 11, and their 95% intervals
/// cover the true values in at least 90% of the values named; on 12 seeds of null data (the instrument's
/// frame and the target alone) the verdict is `none` in at least 11.
#[test]
fn over_seeds_a_parallel_robots_offsets_are_named_with_honest_intervals_and_null_data_name_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let m = orthoglide();
    let (mut exact, mut covered, mut values, mut quiet) = (0, 0, 0, 0);
    for seed in 0..12 {
        let mut h = Hidden {
            rotation: Vec3::new(0.3, -0.2, 0.1),
            translation: Vec3::new(200.0, 300.0, -400.0),
            target: Vec3::new(5.0, 5.0, -10.0),
            offsets: [0.4, 0.0, -0.25],
        };
        let (_, c) = calibrated(&m, &synthetic(&h, 45, 0.02, &[], 100 + seed), dir.path(), &options(0.02, Vec::new()));
        let mut labels: Vec<&str> = c.report.accepted.iter().map(|a| a.label.as_str()).collect();
        labels.sort();
        exact += usize::from(labels == ["joint-offset:1", "joint-offset:3"]);
        for a in c.report.accepted.iter().filter(|a| a.kind == ArmKind::JointOffset.name()) {
            let truth = h.offsets[a.joint.parse::<usize>().unwrap() - 1];
            values += 1;
            covered += usize::from((a.values[0] - truth).abs() < 1.96 * a.se[0]);
        }
        h.offsets = [0.0; 3];
        let (_, c) = calibrated(&m, &synthetic(&h, 45, 0.02, &[], 200 + seed), dir.path(), &options(0.02, Vec::new()));
        quiet += usize::from(c.report.verdict == Verdict::None);
    }
    assert!(exact >= 11, "named exactly in {exact} of 12");
    assert!(covered as f64 >= 0.9 * values as f64, "{covered} of {values} covered");
    assert!(quiet >= 11, "null data: none in {quiet} of 12");
}

/// A payload's centre turns with the platform, so its weight's moment (R c) x g sees the centre's component
/// along gravity once the load turns the platform (the Orthoglide turns by about 0.05 rad under the milling
/// wrench: 20 kg 50 mm above the reference point then weigh about 490 N mm). Measured through `synth
/// --positions` with that payload and an actuator offset, the payload's mass and its whole centre come back
/// within 4 standard errors; with the unturned axes the centre's height was `not seen` and its moment was put
/// on x, 3.5 +- 0.4 mm for 0.
#[test]
fn a_payloads_centre_along_gravity_is_seen_through_the_platforms_turn_under_load() {
    let grid = ["--grid", "manipulators/grids/orthoglide-small.toml"];
    let hidden = [
        "registration=0.1,0.2,-0.3,1000,200,-50",
        "target=10,-5,20",
        "gravity-offset=20,0,0,50",
        "actuator-offset:2=0.3",
    ];
    let (text, c, _) = synth_and_calibrate(MODEL, grid, &hidden, "1");
    let accepted = c["accepted"].as_array().unwrap();
    let payload = accepted.iter().find(|a| a["label"] == "payload").unwrap_or_else(|| panic!("{text}"));
    let number = |v: &serde_json::Value| v.as_f64().unwrap_or(f64::NAN);
    let (values, se): (Vec<f64>, Vec<f64>) =
        (0..4).map(|k| (number(&payload["values"][k]), number(&payload["se"][k]))).unzip();
    // Mass, then the centre c in the tool frame, as the text prints them: (0, 0, 50) mm.
    for (k, truth) in [20.0, 0.0, 0.0, 50.0].iter().enumerate() {
        assert!((values[k] - truth).abs() < 4.0 * se[k], "{k}: {} +- {} against {truth}\n{text}", values[k], se[k]);
    }
}

/// The plan's signatures of the actuators' offsets (what `stiff plan --positions` chooses poses on) are the
/// platform's motion per unit offset: at 8 random poses they equal central finite differences of the
/// independent kinematics' forward solve, q_i -> q_i +- h, to 1e-6 relative.
#[test]
fn a_parallel_robots_plan_signatures_of_offsets_are_finite_differences_of_its_kinematics() {
    let m = orthoglide();
    let mut r = rng(8);
    let poses: Vec<stiff::kinematics::frame::Frame> = (0..8)
        .map(|_| stiff::kinematics::frame::Frame::translation(Vec3::from_fn(|_, _| r.random_range(-70.0..120.0))))
        .collect();
    let configurations: Vec<calibrate::Configuration> =
        (0..8).map(|k| (format!("p{k}"), Vec::new(), stiff::kinematics::frame::Vec6::zeros())).collect();
    let effects: Vec<ArmEffect> = (0..3).map(offset).collect();
    let found = calibrate::signatures(&m, &configurations, Some(&poses), &effects, 1.0, None).unwrap();
    assert_eq!(found.usable.len(), 8);
    let h = 1e-4;
    for (k, pose) in poses.iter().enumerate() {
        let q = inverse(&pose.pos);
        for (leg, (_, block)) in found.effects.iter().enumerate() {
            let moved = |s: f64| {
                let mut shifted = q;
                shifted[leg] += s * h;
                forward(&shifted, &pose.pos)
            };
            let difference = (moved(1.0) - moved(-1.0)) / (2.0 * h);
            let signature = Vec3::new(block[(3 * k, 0)], block[(3 * k + 1, 0)], block[(3 * k + 2, 0)]);
            assert!(
                (signature - difference).norm() < 1e-6 * difference.norm(),
                "pose {k}, leg {}: {signature} against {difference}",
                leg + 1
            );
        }
    }
}

/// A platform that turns: the Stewart-Gough platform B commanded to 80 random poses (turned by up to 0.08
/// rad, `pose_rx_rad..` columns) under random wrenches, measured through `synth --positions` with actuator
/// 3 sitting 0.4 mm off behind a hidden instrument frame and target: the offset alone is named, within 4
/// standard errors; the target's place, which a turning platform shows, comes back within 4 standard
/// errors; and the held-out RMS is at the noise (0.0035 mm for 0.002 mm per coordinate).
#[test]
fn a_turning_platforms_actuator_offset_and_target_are_recovered_from_positions() {
    let dir = tempfile::tempdir().unwrap();
    let mut r = rng(3);
    let mut points =
        String::from("name,x_mm,y_mm,z_mm,pose_rx_rad,pose_ry_rad,pose_rz_rad,Fx_N,Fy_N,Fz_N,Mx_Nmm,My_Nmm,Mz_Nmm\n");
    for k in 0..80 {
        let mut v: Vec<f64> = (0..3).map(|_| r.random_range(-30.0..30.0)).collect();
        v[2] += 300.0;
        v.extend((0..3).map(|_| r.random_range(-0.08..0.08)));
        v.extend((0..3).map(|_| r.random_range(-300.0..300.0)));
        v.extend((0..3).map(|_| r.random_range(-20000.0..20000.0)));
        let cells: Vec<String> = v.iter().map(|x| format!("{x:?}")).collect();
        points += &format!("s{k},{}\n", cells.join(","));
    }
    let poses = dir.path().join("poses.csv");
    std::fs::write(&poses, points).unwrap();
    let hidden = ["registration=0.1,0.2,-0.3,1000,200,-50", "target=10,-5,20", "actuator-offset:3=0.4"];
    let (text, c, _) =
        synth_and_calibrate("manipulators/stewart-gough-b.toml", ["--points", poses.to_str().unwrap()], &hidden, "1");
    let accepted = c["accepted"].as_array().unwrap();
    assert_eq!(accepted.len(), 1, "{text}");
    assert_eq!(accepted[0]["label"], "joint-offset:3", "{text}");
    let (v, se) = (accepted[0]["values"][0].as_f64().unwrap(), accepted[0]["se"][0].as_f64().unwrap());
    assert!((v - 0.4).abs() < 4.0 * se, "{v} +- {se}\n{text}");
    let target =
        c["nuisance"].as_array().unwrap().iter().find(|n| n["name"].as_str().unwrap().contains("target")).unwrap();
    for (k, truth) in [10.0, -5.0, 20.0].iter().enumerate() {
        let (v, se) = (target["value"][k].as_f64().unwrap(), target["se"][k].as_f64().unwrap());
        assert!((v - truth).abs() < 4.0 * se, "target {k}: {v} +- {se}\n{text}");
    }
    let last = c["stages"].as_array().unwrap().last().unwrap();
    assert!(last["check"]["rms"].as_f64().unwrap() < 0.005, "{text}");
}

/// Where the controller does not reach its command (the actuators sit up to 0.05 mm from where the inverse
/// kinematics of the commanded pose puts them) and the rows give the actuators' readings (`q_1,q_2,q_3`,
/// each off the true position by its encoder's offset), the pose is found from the readings: noise-free, the
/// offsets come back to 1e-9 mm and every position to 1e-9 mm. The same rows without the readings leave the
/// controller's misses in the residuals (above 0.01 mm).
#[test]
fn a_parallel_robots_actuator_readings_give_the_pose_the_controller_reached() {
    let dir = tempfile::tempdir().unwrap();
    let m = orthoglide();
    let h = Hidden {
        rotation: Vec3::new(0.2, -0.1, 0.4),
        translation: Vec3::new(800.0, -250.0, 1200.0),
        target: Vec3::zeros(),
        offsets: [0.3, -0.2, 0.5],
    };
    let mut r = rng(21);
    let instrument = rotation_from_vector(&h.rotation);
    let (mut with, mut without) = (
        String::from("pose_id,x_mm,y_mm,z_mm,q_1,q_2,q_3,mx_mm,my_mm,mz_mm\n"),
        String::from("pose_id,x_mm,y_mm,z_mm,mx_mm,my_mm,mz_mm\n"),
    );
    for c in 0..30 {
        let commanded = Vec3::from_fn(|_, _| r.random_range(-73.65..126.35));
        let reached: [f64; 3] = inverse(&commanded).map(|q| q + r.random_range(-0.05..0.05));
        let p = forward(&std::array::from_fn(|i| reached[i] + h.offsets[i]), &commanded);
        let seen = instrument * (p + h.target) + h.translation;
        let pose = format!("p{c},{:?},{:?},{:?}", commanded.x, commanded.y, commanded.z);
        let at = format!("{:?},{:?},{:?}", seen.x, seen.y, seen.z);
        with += &format!("{pose},{:?},{:?},{:?},{at}\n", reached[0], reached[1], reached[2]);
        without += &format!("{pose},{at}\n");
    }
    let options = options(1e-9, (0..3).map(offset).collect());
    let path = dir.path().join("readings.csv");
    std::fs::write(&path, &with).unwrap();
    let legs: Vec<String> = ["1", "2", "3"].map(String::from).to_vec();
    let data = PositionData::read_at_poses(&path, std::fs::File::open(&path).unwrap(), &legs).unwrap();
    let c = calibrate::calibrate(&m, &data, &[], &options).unwrap();
    let report = calibrate::text(&c.report, MODEL);
    for (k, a) in c.report.accepted.iter().take(3).enumerate() {
        assert!((a.values[0] - h.offsets[k]).abs() < 1e-9, "leg {}: {}\n{report}", k + 1, a.values[0]);
    }
    assert!(c.report.stages.last().unwrap().fit.max < 1e-9, "{report}");
    let (_, c) = calibrated(&m, &without, dir.path(), &options);
    assert!(c.report.stages.last().unwrap().fit.max > 0.01, "{}", calibrate::text(&c.report, MODEL));
}

/// Regression: a set-up whose fit rows all lie on one line at one tool orientation (the Orthoglide only
/// translates: its rows are always at one orientation) leaves its frame's turn about that line unseen, and its
/// held-out row off the line was predicted through an arbitrary turn and reported as a gross row 92 mm from
/// the model. The set-up is named as one that cannot be placed, with the reason, and its rows kept out of the
/// fit and the verdict. The data are written here: with no load the platform is at the commanded pose, so a
/// set-up's instrument sees p at R p + t.
#[test]
fn a_set_up_whose_rows_lie_on_one_line_is_named_and_kept_out() {
    let dir = tempfile::tempdir().unwrap();
    let (ra, ta) = (rotation_from_vector(&Vec3::new(0.1, 0.2, -0.3)), Vec3::new(1000.0, 200.0, -50.0));
    let (rb, tb) = (rotation_from_vector(&Vec3::new(0.0, 0.05, 0.3)), Vec3::new(1100.0, 160.0, -43.0));
    let mut r = rng(2);
    let mut csv = String::from("pose_id,x_mm,y_mm,z_mm,mx_mm,my_mm,mz_mm,sigma_mm,set,setup\n");
    let mut row = |name: String, p: Vec3, (rot, t): (&Mat3, &Vec3), set: &str, setup: &str| {
        let m = rot * p + t;
        csv += &format!("{name},{},{},{},{:?},{:?},{:?},0.002,{set},{setup}\n", p.x, p.y, p.z, m.x, m.y, m.z);
    };
    for k in 0..20 {
        let p = Vec3::new(r.random_range(-60.0..60.0), r.random_range(-60.0..60.0), r.random_range(-60.0..60.0));
        row(format!("a{k}"), p, (&ra, &ta), "fit", "a");
    }
    for (k, x) in [-50.0, -10.0, 30.0].iter().enumerate() {
        row(format!("b{k}"), Vec3::new(*x, 10.0, -5.0), (&rb, &tb), "fit", "b");
    }
    row("b_off".into(), Vec3::new(20.0, 40.0, 30.0), (&rb, &tb), "check", "b");
    std::fs::write(dir.path().join("d.csv"), csv).unwrap();
    let data = dir.path().join("d.csv");
    let text = crate::common::run_stiff(&["diagnose", MODEL, "--data", data.to_str().unwrap()]);
    assert!(
        text.contains("set-up `b` cannot be placed: its fit rows lie on one line at one tool orientation"),
        "{text}"
    );
    assert!(text.contains("its 4 rows are left out of the fit and the verdict"), "{text}");
    assert!(text.contains("20 rows fitted, 0 held out") && text.contains("verdict: none"), "{text}");
    assert!(!text.contains("gross row left out"), "{text}");
}
