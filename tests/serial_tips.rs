//! A tree with several tips is one robot: a torso on a waist joint carrying two arms, each hand a reference
//! point. Checked against computations written here from the file's numbers: the waist carries both arms'
//! weight (its gravity load is the sum of m g x (c - p) over every body above it, both arms included); the
//! sag is the solution of k_i theta_i = tau_i(q + theta) over the three springs at the deflected
//! configuration (Newton's method here, with its own difference Jacobian), seen at each hand; each hand's
//! compliance is the sum over the springs on its path of J_i J_i^T / k_i (the other shoulder's spring does
//! not move it); a map writes a row per tip; and bad trees are located errors.

use nalgebra::Matrix3;
use stiff::kinematics::frame::{Frame, Mat6, Vec3, Vec6};
use stiff::model::grid::PosePoint;
use stiff::platform::manipulator::Manipulator;
use stiff::study::point::{unloaded_point, Status};

/// A torso on a waist joint (about z, gravity along -y: the arm moves in a vertical plane) with a left arm
/// (3 kg, a 1 kg hand) and a right arm (2 kg), lengths in m.
const TORSO: &str = r#"<robot name="torso2">
  <link name="base"><inertial><mass value="40"/></inertial></link>
  <link name="torso"><inertial><origin xyz="0 0.3 0"/><mass value="10"/></inertial></link>
  <link name="arm_l"><inertial><origin xyz="0.15 0 0"/><mass value="3"/></inertial></link>
  <link name="arm_r"><inertial><origin xyz="-0.12 0 0"/><mass value="2"/></inertial></link>
  <link name="hand_l"><inertial><origin xyz="0.05 0 0"/><mass value="1"/></inertial></link>
  <link name="hand_r"/>
  <joint name="waist" type="revolute"><parent link="base"/><child link="torso"/><axis xyz="0 0 1"/></joint>
  <joint name="shoulder_l" type="revolute"><parent link="torso"/><child link="arm_l"/><origin xyz="0.2 0.5 0"/><axis xyz="0 0 1"/></joint>
  <joint name="shoulder_r" type="revolute"><parent link="torso"/><child link="arm_r"/><origin xyz="-0.2 0.5 0"/><axis xyz="0 0 1"/></joint>
  <joint name="wrist_l" type="fixed"><parent link="arm_l"/><child link="hand_l"/><origin xyz="0.35 0 0"/></joint>
  <joint name="wrist_r" type="fixed"><parent link="arm_r"/><child link="hand_r"/><origin xyz="-0.3 0 0"/></joint>
</robot>"#;

/// Springs (N mm/rad) of the waist and the two shoulders.
const K: [f64; 3] = [5.0e6, 2.0e6, 1.0e6];

const JOINTS: &str = "joints = { waist = { stiffness = 5.0e6 }, shoulder_l = { stiffness = 2.0e6 }, shoulder_r = { stiffness = 1.0e6 } }";

/// The description of the tree (written with the URDF to a temporary folder) with the `[leg.urdf]` lines
/// `urdf_lines` after `file` and `root`.
fn tree_files(urdf: &str, urdf_lines: &str, top: &str) -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tree.urdf"), urdf).unwrap();
    let toml = format!(
        "name = \"tree\"\ngravity = [0, -9.81, 0]\n{top}\n[[leg]]\nname = \"body\"\n[leg.urdf]\nfile = \"tree.urdf\"\nroot = \"base\"\n{urdf_lines}\n"
    );
    let path = dir.path().join("tree.toml");
    std::fs::write(&path, toml).unwrap();
    (dir, path)
}

fn torso_model() -> (tempfile::TempDir, Manipulator) {
    let (dir, path) = tree_files(TORSO, &format!("tips = [\"hand_l\", \"hand_r\"]\n{JOINTS}"), "");
    let m = stiff::model::load_manipulator(&path).unwrap();
    (dir, m)
}

/// Rotation by `a` about z, on the plane's vectors.
fn turned(a: f64, x: f64, y: f64) -> Vec3 {
    Vec3::new(a.cos() * x - a.sin() * y, a.sin() * x + a.cos() * y, 0.0)
}

/// The tree at joint angles `a` (waist, shoulder_l, shoulder_r; rad): the shoulders' origins, the hands'
/// points, and every body's mass and centre with the joints that carry it (mm).
struct Placed {
    shoulder: [Vec3; 2],
    hand: [Vec3; 2],
    bodies: Vec<(f64, Vec3, [bool; 3])>,
}

fn place(a: [f64; 3]) -> Placed {
    let o_l = turned(a[0], 200.0, 500.0);
    let o_r = turned(a[0], -200.0, 500.0);
    let (al, ar) = (a[0] + a[1], a[0] + a[2]);
    Placed {
        shoulder: [o_l, o_r],
        hand: [o_l + turned(al, 350.0, 0.0), o_r + turned(ar, -300.0, 0.0)],
        bodies: vec![
            (10.0, turned(a[0], 0.0, 300.0), [true, false, false]),
            (3.0, o_l + turned(al, 150.0, 0.0), [true, true, false]),
            (1.0, o_l + turned(al, 400.0, 0.0), [true, true, false]),
            (2.0, o_r + turned(ar, -120.0, 0.0), [true, false, true]),
        ],
    }
}

/// Each joint's load (N mm about z) from the bodies' weight and a force `f` (N) at hand `tip`, at angles `a`.
fn loads(a: [f64; 3], tip: usize, f: Vec3) -> [f64; 3] {
    let p = place(a);
    let origin = [Vec3::zeros(), p.shoulder[0], p.shoulder[1]];
    let g = Vec3::new(0.0, -9.81, 0.0);
    let mut out = [0.0; 3];
    for (k, o) in origin.iter().enumerate() {
        for (kg, c, carried) in &p.bodies {
            if carried[k] {
                out[k] += (c - o).cross(&(g * *kg)).z;
            }
        }
        if k == 0 || k == tip + 1 {
            out[k] += (p.hand[tip] - o).cross(&f).z;
        }
    }
    out
}

/// The springs' deflections at equilibrium from angles `a` under the weight and a force `f` at hand `tip`:
/// Newton's method on k_i t_i = tau_i(a + t), its Jacobian by central differences.
fn equilibrium(a: [f64; 3], tip: usize, f: Vec3) -> [f64; 3] {
    equilibrium_with(K, a, tip, f)
}

/// As `equilibrium`, with springs `k`.
fn equilibrium_with(k: [f64; 3], a: [f64; 3], tip: usize, f: Vec3) -> [f64; 3] {
    let residual = |t: [f64; 3]| -> nalgebra::Vector3<f64> {
        let tau = loads([a[0] + t[0], a[1] + t[1], a[2] + t[2]], tip, f);
        nalgebra::Vector3::from_fn(|i, _| tau[i] - k[i] * t[i])
    };
    let mut t = [0.0; 3];
    for _ in 0..40 {
        let h = 1e-7;
        let jac = Matrix3::from_fn(|i, j| {
            let (mut up, mut down) = (t, t);
            up[j] += h;
            down[j] -= h;
            (residual(up)[i] - residual(down)[i]) / (2.0 * h)
        });
        let step = jac.lu().solve(&residual(t)).unwrap();
        for i in 0..3 {
            t[i] -= step[i];
        }
    }
    t
}

fn pose_point(frame: &Frame) -> PosePoint {
    PosePoint {
        position: frame.pos,
        rotation: stiff::kinematics::frame::rotation_vector(&frame.rot),
        ..PosePoint::default()
    }
}

const ANGLES: [[f64; 3]; 3] = [[0.3, -0.8, 1.1], [-0.2, 0.4, -0.5], [1.0, -1.2, 0.7]];

/// The waist carries both arms: its gravity load is the sum over the torso and both arms' bodies, the same
/// seen from either hand; each shoulder carries its own arm.
#[test]
fn the_waist_of_a_two_arm_tree_carries_both_arms_weight() {
    let (_dir, m) = torso_model();
    assert_eq!(m.tips(), ["hand_l", "hand_r"]);
    let names = &m.joint_space.as_ref().unwrap().names;
    assert_eq!(names, &["waist", "shoulder_l", "shoulder_r"]);
    let carried = m.joint_space.as_ref().unwrap().carried;
    assert!((carried.kg - 16.0).abs() < 1e-12 && carried.off_path_kg == 0.0, "{carried:?}");
    assert!((carried.on_base_kg - 40.0).abs() < 1e-12, "{carried:?}");
    for tip in ["hand_l", "hand_r"] {
        let mt = m.at_tip(tip).unwrap();
        for a in ANGLES {
            let mut state = mt.new_state();
            let s = mt.arm_statics(&a, &Vec6::zeros(), &mut state).unwrap();
            let want = loads(a, 0, Vec3::zeros());
            for (k, (got, want)) in s.loads.iter().zip(want).enumerate() {
                assert!((got - want).abs() < 1e-9 * want.abs().max(1.0), "{tip}, joint {k}: {got} vs {want}");
            }
            let hand = place(a).hand[if tip == "hand_l" { 0 } else { 1 }];
            assert!((s.frame.pos - hand).norm() < 1e-9, "{tip}: {} vs {hand}", s.frame.pos);
        }
    }
}

/// The sag under the tree's weight is one equilibrium of all three springs, seen at each hand; a force at
/// one hand moves the other through the waist only.
#[test]
fn each_hand_sees_the_one_equilibrium_of_the_tree() {
    let (_dir, m) = torso_model();
    for a in ANGLES {
        for (f, at) in [(Vec3::zeros(), 0), (Vec3::new(40.0, -25.0, 0.0), 0), (Vec3::new(-30.0, 60.0, 0.0), 1)] {
            let t = equilibrium(a, at, f);
            let deflected = place([a[0] + t[0], a[1] + t[1], a[2] + t[2]]);
            for (k, tip) in ["hand_l", "hand_r"].iter().enumerate() {
                let mt = m.at_tip(tip).unwrap();
                let mut state = mt.new_state();
                let frame = mt.pose_at_joints(&a, &mut state).unwrap();
                mt.place(&frame, &mut state).unwrap();
                // The force acts at the hand that is the reference point; rows of the other hand see the
                // weight alone.
                if f != Vec3::zeros() && k != at {
                    continue;
                }
                let d = mt.deflect(&frame, &Vec6::new(f.x, f.y, 0.0, 0.0, 0.0, 0.0), None, &mut state).unwrap();
                assert!(d.stable);
                assert!(
                    (d.pose.pos - deflected.hand[k]).norm() < 1e-9,
                    "{tip} at {a:?} under {f}: {} vs {}",
                    d.pose.pos,
                    deflected.hand[k]
                );
                let turn = t[0] + t[k + 1];
                assert!(
                    (d.displacement[5] - turn).abs() < 1e-12,
                    "{tip} turns by the waist's and its shoulder's angles"
                );
            }
        }
    }
}

/// Each hand's compliance is the sum of J_i J_i^T / k_i over the waist and its own shoulder (the other
/// shoulder's spring does not move it): rank 2 in the plane, rigid along the other four directions.
#[test]
fn each_hands_compliance_sums_the_springs_on_its_path() {
    let (_dir, m) = torso_model();
    for a in ANGLES {
        let p = place(a);
        for (k, tip) in ["hand_l", "hand_r"].iter().enumerate() {
            let mt = m.at_tip(tip).unwrap();
            let mut state = mt.new_state();
            let frame = mt.pose_at_joints(&a, &mut state).unwrap();
            let r = unloaded_point(&mt, &pose_point(&frame), &mut state);
            assert_eq!(r.status, Status::RigidDirections, "{r:?}");
            assert_eq!(r.rank, Some(2));
            let h = p.hand[k];
            let column = |o: Vec3| Vec6::new(-(h.y - o.y), h.x - o.x, 0.0, 0.0, 0.0, 1.0);
            let (waist, shoulder) = (column(Vec3::zeros()), column(p.shoulder[k]));
            let want: Mat6 = waist * waist.transpose() / K[0] + shoulder * shoulder.transpose() / K[k + 1];
            let c = r.compliance.unwrap();
            assert!((c - want).norm() < 1e-12 * want.norm(), "{tip}: {c} vs {want}");
        }
    }
}

/// `stiff map` of a tree writes each point once per tip, a `tip` column naming it, the index the point's;
/// `--tip` keeps one tip's rows. The sag's displacement is the equilibrium's (solved here).
#[test]
fn a_map_of_a_tree_writes_a_row_per_tip() {
    let (dir, path) = tree_files(TORSO, &format!("tips = [\"hand_l\", \"hand_r\"]\n{JOINTS}"), "");
    let points = dir.path().join("q.csv");
    let mut text = String::from("q_waist,q_shoulder_r,q_shoulder_l\n");
    for a in ANGLES {
        text.push_str(&format!("{},{},{}\n", a[0], a[2], a[1]));
    }
    std::fs::write(&points, text).unwrap();
    let run = |extra: &[&str]| -> Vec<csv::StringRecord> {
        let out = dir.path().join("map.csv");
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
            .args(["map", path.to_str().unwrap(), "--points", points.to_str().unwrap(), "--wrench=0,0,0,0,0,0", "-o"])
            .arg(&out)
            .args(extra)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let mut reader = csv::Reader::from_path(&out).unwrap();
        let header = reader.headers().unwrap().clone();
        assert_eq!(&header[2], "tip", "{header:?}");
        let rows: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
        let column = |name: &str| header.iter().position(|h| h == name).unwrap();
        for row in &rows {
            let i: usize = row[column("index")].parse().unwrap();
            let a = ANGLES[i];
            let t = equilibrium(a, 0, Vec3::zeros());
            let k = if &row[column("tip")] == "hand_l" { 0 } else { 1 };
            let moved = place([a[0] + t[0], a[1] + t[1], a[2] + t[2]]).hand[k] - place(a).hand[k];
            for (axis, name) in ["dx_mm", "dy_mm"].iter().enumerate() {
                let got: f64 = row[column(name)].parse().unwrap();
                assert!(
                    (got - moved[axis]).abs() < 1e-9,
                    "row {i} {}: {name} {got} vs {}",
                    &row[column("tip")],
                    moved[axis]
                );
            }
        }
        rows
    };
    let both = run(&[]);
    let tips: Vec<(&str, &str)> = both.iter().map(|r| (r.get(0).unwrap(), r.get(2).unwrap())).collect();
    assert_eq!(
        tips,
        [("0", "hand_l"), ("0", "hand_r"), ("1", "hand_l"), ("1", "hand_r"), ("2", "hand_l"), ("2", "hand_r")]
    );
    let right = run(&["--tip", "hand_r"]);
    assert!(right.len() == 3 && right.iter().all(|r| &r[2] == "hand_r"));
}

/// A tip that is not in the tree, named twice, or not below the root; a tool for a link that is not a tip;
/// a payload on a tree; a pose for a tree: each a located error, and no file written.
#[test]
fn bad_tips_are_located_errors() {
    let two_roots = TORSO.replace("</robot>", "<link name=\"cart\"/><link name=\"lamp\"/><joint name=\"pole\" type=\"fixed\"><parent link=\"cart\"/><child link=\"lamp\"/></joint></robot>");
    let cases: [(&str, String, &str, &str); 7] = [
        (TORSO, "tips = [\"hand_l\", \"hand_x\"]".into(), "", "no link named `hand_x`"),
        (TORSO, "tips = [\"hand_l\", \"hand_l\"]".into(), "", "tip `hand_l` is named twice"),
        (&two_roots, "tips = [\"hand_l\", \"lamp\"]".into(), "", "links `base` and `lamp` are not connected"),
        (
            TORSO,
            "tips = [\"hand_l\", \"hand_r\"]\ntools = { hand_x = { translation = [0, 0, 10] } }".into(),
            "",
            "`hand_x` is not one of the tips",
        ),
        (TORSO, "tips = []".into(), "", "`tips` names no link"),
        (TORSO, "tip = \"hand_l\"\ntips = [\"hand_r\"]".into(), "", "exactly one of `tip`"),
        (
            TORSO,
            "tips = [\"hand_l\", \"hand_r\"]".into(),
            "[[payload]]\nmass_kg = 2\n",
            "a tree with several tips has none",
        ),
    ];
    for (urdf, lines, top, message) in cases {
        let (_dir, path) = tree_files(urdf, &lines, top);
        let e = stiff::model::load_manipulator(&path).err().map(|e| e.to_string()).unwrap_or_default();
        assert!(e.contains(message), "{lines}: {e}");
        assert!(e.contains("tree."), "the error names the file: {e}");
    }
    let (dir, path) = tree_files(TORSO, &format!("tips = [\"hand_l\", \"hand_r\"]\n{JOINTS}"), "");
    let out = dir.path().join("map.csv");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
        .args(["point", path.to_str().unwrap(), "--at", "100,800,0"])
        .output()
        .unwrap();
    assert!(!o.status.success());
    let o2 = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
        .args(["map", path.to_str().unwrap(), "--tip", "hand_x", "--points"])
        .arg(dir.path().join("none.csv"))
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o2.stderr);
    assert!(err.contains("no tip named `hand_x` (tips: hand_l, hand_r)"), "{err}");
    assert!(!out.exists());
}

/// A calibration of the tree measures a marker on each hand (each target names its tip: `mx_hand_l_mm`,
/// `mx_hand_r_mm`): the data are made here from the tree's own statics (the exact equilibrium of the three
/// springs, solved above) with the waist 1.5 and shoulder_l 1.6 times as compliant as the model's, seen in
/// a hidden instrument frame with 0.01 mm noise, the springs ten times the other tests' (a serial arm's
/// compliance is fitted to first order about its nominal sag: at the other tests' sag of 12 mrad at the
/// waist, the second order is 0.04 mm, four times the noise). The two effects are named, nothing else, their values
/// within 3 standard errors (the waist's only if both arms' weight loads it), and the held-out rows sit at
/// the noise. (An encoder offset of a shoulder, the last joint before its hand, would not do: turning the
/// hand about the shoulder is moving its marker on the hand, which the target's fitted place absorbs.)
#[test]
fn a_calibration_of_a_tree_measures_a_target_on_each_hand() {
    use rand::Rng;
    use stiff::diagnose::calibrate::{self, CalibrationOptions, CalibrationVerdict};
    use stiff::diagnose::positions::PositionData;
    let k = [K[0] * 10.0, K[1] * 10.0, K[2] * 10.0];
    let joints = format!(
        "joints = {{ waist = {{ stiffness = {} }}, shoulder_l = {{ stiffness = {} }}, shoulder_r = {{ stiffness = {} }} }}",
        k[0], k[1], k[2]
    );
    let (dir, path) = tree_files(TORSO, &format!("tips = [\"hand_l\", \"hand_r\"]\n{joints}"), "");
    let m = stiff::model::load_manipulator(&path).unwrap();
    let k_true = [k[0] / 1.5, k[1] / 1.6, k[2]];
    let instrument = stiff::kinematics::frame::rotation_from_vector(&Vec3::new(0.2, -0.4, 0.9));
    let shift = Vec3::new(1200.0, -350.0, 80.0);
    let markers = [Vec3::new(20.0, 15.0, 0.0), Vec3::new(-10.0, 25.0, 0.0)];
    let mut r = stiff_rng(5);
    let mut normal = || {
        let (u, v): (f64, f64) = (r.random_range(1e-12..1.0), r.random_range(0.0..1.0));
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    };
    let mut csv = String::from("pose_id,q_waist,q_shoulder_l,q_shoulder_r,mx_hand_l_mm,my_hand_l_mm,mz_hand_l_mm,mx_hand_r_mm,my_hand_r_mm,mz_hand_r_mm,set\n");
    let mut angles = stiff_rng(9);
    for c in 0..45 {
        let q = [angles.random_range(-0.6..0.6), angles.random_range(-1.8..1.8), angles.random_range(-1.8..1.8)];
        let a = q;
        let t = equilibrium_with(k_true, a, 0, Vec3::zeros());
        let bent = [a[0] + t[0], a[1] + t[1], a[2] + t[2]];
        let p = place(bent);
        let mut cells = vec![format!("c{c}"), format!("{:?}", q[0]), format!("{:?}", q[1]), format!("{:?}", q[2])];
        for (k, marker) in markers.iter().enumerate() {
            let turn = bent[0] + bent[k + 1];
            let point = p.hand[k] + turned(turn, marker.x, marker.y) + Vec3::new(0.0, 0.0, marker.z);
            let seen = instrument * point + shift;
            cells.extend((0..3).map(|i| format!("{:?}", seen[i] + 0.01 * normal())));
        }
        cells.push(if c % 3 == 2 { "check" } else { "fit" }.to_string());
        csv += &(cells.join(",") + "\n");
    }
    let path = dir.path().join("data.csv");
    std::fs::write(&path, &csv).unwrap();
    let names = &m.joint_space.as_ref().unwrap().names;
    let data = PositionData::read(&path, names).unwrap();
    let options = CalibrationOptions {
        alpha: 0.01,
        sigma: Some(0.01),
        sigma_rad: None,
        fitted: Vec::new(),
        max_effects: 6,
        rebuild: None,
        progress: None,
    };
    let c = calibrate::calibrate(&m, &data, &[], &options).unwrap();
    let report = calibrate::text(&c.report, "tree");
    assert_eq!(c.report.verdict, CalibrationVerdict::Effect, "{report}");
    let mut named: Vec<&str> = c.report.accepted.iter().map(|a| a.label.as_str()).collect();
    named.sort();
    assert_eq!(named, ["joint-compliance:shoulder_l", "joint-compliance:waist"], "{report}");
    let value =
        |label: &str| c.report.accepted.iter().find(|a| a.label == label).map(|a| (a.values[0], a.se[0])).unwrap();
    let (added, se) = value("joint-compliance:shoulder_l");
    let want = 0.6 / k[1];
    assert!((added - want).abs() <= 3.0 * se, "added compliance {added} +- {se} vs {want}: {report}");
    let (added, se) = value("joint-compliance:waist");
    let want = 0.5 / k[0];
    assert!((added - want).abs() <= 3.0 * se, "waist: added compliance {added} +- {se} vs {want}: {report}");
    // The length of a 3-vector of 0.01 mm noise has an RMS of 0.0173 mm.
    let last = c.report.stages.last().unwrap();
    assert!(last.check.rms < 0.0173 * 1.4 && last.fit.rms < 0.0173 * 1.3, "{report}");
    // A target that names no tip is refused, naming the tips.
    std::fs::write(&path, csv.replace("_hand_r_mm", "_wrist_mm")).unwrap();
    let data = PositionData::read(&path, names).unwrap();
    let e = calibrate::calibrate(&m, &data, &[], &options).err().map(|e| e.to_string()).unwrap_or_default();
    assert!(e.contains("target `_wrist`") && e.contains("(hand_l, hand_r)"), "{e}");
}

fn stiff_rng(seed: u64) -> rand::rngs::StdRng {
    rand::SeedableRng::seed_from_u64(seed)
}
