//! Serial arms as their URDF means them, checked against computations written here from the file's numbers:
//! every mass of the tree weighs on the link it hangs from (a branch held at its URDF zero, a gripper fixed
//! beyond the tip: the joints' gravity loads summed as m g x (c - p) over the bodies each joint carries); a
//! rigid joint is rigid (a planar arm with its middle joint rigid: C = sum over elastic joints of
//! J_i J_i^T / k_i, rank 2, its loaded equilibrium against a Newton solve of the two springs' statics); a
//! mimic joint is a transmission its master's spring drives (C = (J_1 + m J_2)(J_1 + m J_2)^T / k, the URDF
//! relation kept under load); the arm's own answer (C = J_e K_e^-1 J_e^T, Newton on the elastic coordinates)
//! equals the leg route (K = S^-1 through the platform) on the FANUC and its loaded tangent equals
//! differences of equilibria; and bad trees are located errors.

use std::path::Path;

use rand::Rng;
use stiff::kinematics::frame::{Frame, Mat6, Vec3, Vec6};
use stiff::model::grid::PosePoint;
use stiff::platform::manipulator::Manipulator;
use stiff::study::point::{unloaded_point, Status};

use crate::common::rng;
use crate::serial::{random_angles, FANUC};

/// A model of `urdf` (written to a temporary folder) with the `[leg.urdf]` table's `extra` lines and the
/// description's `top` lines.
fn arm(urdf: &str, root: &str, tip: &str, extra: &str, top: &str) -> (tempfile::TempDir, Result<Manipulator, String>) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("arm.urdf"), urdf).unwrap();
    let toml = format!(
        "name = \"arm\"\n{top}\n[[leg]]\nname = \"arm\"\n[leg.urdf]\nfile = \"arm.urdf\"\nroot = \"{root}\"\ntip = \"{tip}\"\n{extra}\n"
    );
    let path = dir.path().join("arm.toml");
    std::fs::write(&path, toml).unwrap();
    let m = stiff::model::load_manipulator(&path).map_err(|e| e.to_string());
    (dir, m)
}

/// The arm placed at the controller's angles `q`: its frame and state.
fn placed(m: &Manipulator, q: &[f64]) -> (Frame, stiff::platform::manipulator::ManipulatorState) {
    let mut state = m.new_state();
    let frame = m.pose_at_joints(q, &mut state).expect("a finite pose");
    m.place(&frame, &mut state).unwrap();
    (frame, state)
}

fn pose_point(frame: &Frame) -> PosePoint {
    PosePoint {
        position: frame.pos,
        rotation: stiff::kinematics::frame::rotation_vector(&frame.rot),
        ..PosePoint::default()
    }
}

/// Planar arm in the x-y plane, joints about z: links of 400, 300 and 200 mm.
const PLANAR3: &str = r#"<robot name="planar3">
  <link name="base"/><link name="a"/><link name="b"/><link name="c"/><link name="tool"/>
  <joint name="J1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/><limit lower="-3" upper="3"/></joint>
  <joint name="J2" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0.4 0 0"/><axis xyz="0 0 1"/></joint>
  <joint name="J3" type="revolute"><parent link="b"/><child link="c"/><origin xyz="0.3 0 0"/><axis xyz="0 0 1"/></joint>
  <joint name="T" type="fixed"><parent link="c"/><child link="tool"/><origin xyz="0.2 0 0"/></joint>
</robot>"#;

/// The planar arm's joint origins and tip (mm) at angles `a`.
fn planar3_points(a: [f64; 3]) -> [Vec3; 4] {
    let (l, mut p, mut angle) = ([400.0, 300.0, 200.0], Vec3::zeros(), 0.0);
    let mut out = [Vec3::zeros(); 4];
    for k in 0..3 {
        out[k] = p;
        angle += a[k];
        p += Vec3::new(angle.cos(), angle.sin(), 0.0) * l[k];
    }
    out[3] = p;
    out
}

/// A rigid joint is rigid: the planar arm with springs on J1 (given in `joints`) and J3 (a calibration's
/// added compliance, as `diagnose --model-out` writes it) has the compliance sum_i J_i J_i^T / k_i over
/// those two (J_i = (-(y - y_i), x - x_i, 0, 0, 0, 1) at the tip), rank 2, status `rigid_directions` with four
/// rigid directions that C maps to nothing; and its loaded equilibrium under an in-plane tip force fixed in
/// the base frame is the solution of k_i theta_i = [(p_tip - p_i) x F]_z over the two springs at the
/// deflected configuration (Newton's method here, with its own difference Jacobian), to 1e-9 mm.
#[test]
fn a_rigid_middle_joint_leaves_a_planar_arm_rigid_along_its_directions() {
    let (k1, c3) = (2.0e7, 1.0 / 5.0e6);
    let (_dir, m) = arm(
        PLANAR3,
        "base",
        "tool",
        &format!("joints = {{ J1 = {{ stiffness = {k1} }} }}"),
        &format!("[[joint_correction]]\njoint = \"J3\"\ncompliance = {c3}\n"),
    );
    let m = m.unwrap();
    let a = [0.3, -0.8, 1.1];
    let (frame, mut state) = placed(&m, &a);
    let r = unloaded_point(&m, &pose_point(&frame), &mut state);
    assert_eq!(r.status, Status::RigidDirections, "{r:?}");
    assert_eq!(r.rank, Some(2));
    assert!(r.stiffness.is_none() && r.free.is_empty());
    let p = planar3_points(a);
    let column = |i: usize| Vec6::new(-(p[3].y - p[i].y), p[3].x - p[i].x, 0.0, 0.0, 0.0, 1.0);
    let want: Mat6 = column(0) * column(0).transpose() / k1 + column(2) * column(2).transpose() * c3;
    let c = r.compliance.unwrap();
    assert!((c - want).norm() < 1e-12 * want.norm(), "{c} vs {want}");
    assert_eq!(r.rigid.len(), 4);
    for w in &r.rigid {
        assert!((c * w).norm() < 1e-9 * c.norm(), "{w} is not rigid");
    }
    // Loaded: the two springs' statics solved here.
    let force = Vec3::new(30.0, -55.0, 0.0);
    let statics = |t: [f64; 2]| -> [f64; 2] {
        let p = planar3_points([a[0] + t[0], a[1], a[2] + t[1]]);
        let torque = |i: usize| (p[3] - p[i]).cross(&force).z;
        [torque(0) - k1 * t[0], torque(2) - t[1] / c3]
    };
    let mut t = [0.0f64; 2];
    for _ in 0..30 {
        let f = statics(t);
        let h = 1e-7;
        let d = |i: usize| {
            let mut up = t;
            up[i] += h;
            let mut down = t;
            down[i] -= h;
            let (u, d) = (statics(up), statics(down));
            [(u[0] - d[0]) / (2.0 * h), (u[1] - d[1]) / (2.0 * h)]
        };
        let (j0, j1) = (d(0), d(1));
        let det = j0[0] * j1[1] - j1[0] * j0[1];
        t[0] -= (f[0] * j1[1] - j1[0] * f[1]) / det;
        t[1] -= (j0[0] * f[1] - f[0] * j0[1]) / det;
    }
    let tip = planar3_points([a[0] + t[0], a[1], a[2] + t[1]])[3];
    let d = m.deflect(&frame, &Vec6::new(force.x, force.y, 0.0, 0.0, 0.0, 0.0), None, &mut state).unwrap();
    assert!(d.stable);
    assert!((d.pose.pos - tip).norm() < 1e-9, "{} vs {tip}", d.pose.pos);
    assert!((d.displacement[5] - (t[0] + t[1])).abs() < 1e-12, "the tool turns by the two springs' angles");
}

/// A mimic joint is a transmission: J2 follows J1 (multiplier 2, offset 0.1 rad) and J1's spring k drives
/// both, so the tip's compliance is (J_1 + 2 J_2)(J_1 + 2 J_2)^T / k, and under a tip force the deflected
/// arm keeps q2 = 2 q1 + 0.1: the tip is where the scalar statics k theta = [(p - o_1) x F]_z +
/// 2 [(p - o_2) x F]_z (solved here) puts it with both joints moved.
#[test]
fn a_mimic_joint_follows_its_masters_deflection() {
    let urdf = r#"<robot name="mimic">
  <link name="base"/><link name="a"/><link name="b"/><link name="tool"/>
  <joint name="J1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/></joint>
  <joint name="J2" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0.4 0 0"/><axis xyz="0 0 1"/>
    <mimic joint="J1" multiplier="2" offset="0.1"/></joint>
  <joint name="T" type="fixed"><parent link="b"/><child link="tool"/><origin xyz="0.3 0 0"/></joint>
</robot>"#;
    let k = 4.0e7;
    let (_dir, m) = arm(urdf, "base", "tool", &format!("joints = {{ J1 = {{ stiffness = {k} }} }}"), "");
    let m = m.unwrap();
    let points = |q1: f64| {
        let q2 = 2.0 * q1 + 0.1;
        let o2 = Vec3::new(q1.cos(), q1.sin(), 0.0) * 400.0;
        (o2, o2 + Vec3::new((q1 + q2).cos(), (q1 + q2).sin(), 0.0) * 300.0)
    };
    for q1 in [0.2, -0.7, 1.3] {
        let (frame, mut state) = placed(&m, &[q1]);
        let (o2, p) = points(q1);
        assert!((frame.pos - p).norm() < 1e-9);
        let r = unloaded_point(&m, &pose_point(&frame), &mut state);
        // Along J_1 + 2 J_2, with the tip's rotation 1 + 2 = 3 per unit of J1's coordinate.
        let j =
            Vec6::new(-p.y, p.x, 0.0, 0.0, 0.0, 1.0) + Vec6::new(-(p.y - o2.y), p.x - o2.x, 0.0, 0.0, 0.0, 1.0) * 2.0;
        let want = j * j.transpose() / k;
        assert_eq!(r.status, Status::RigidDirections);
        assert_eq!(r.rank, Some(1));
        assert!((r.compliance.unwrap() - want).norm() < 1e-12 * want.norm());
        let force = Vec3::new(-80.0, 45.0, 0.0);
        let statics = |t: f64| {
            let (o2, p) = points(q1 + t);
            p.cross(&force).z + 2.0 * (p - o2).cross(&force).z - k * t
        };
        let mut t = 0.0;
        for _ in 0..40 {
            let h = 1e-7;
            t -= statics(t) / ((statics(t + h) - statics(t - h)) / (2.0 * h));
        }
        let d = m.deflect(&frame, &Vec6::new(force.x, force.y, 0.0, 0.0, 0.0, 0.0), None, &mut state).unwrap();
        assert!((d.pose.pos - points(q1 + t).1).norm() < 1e-9, "{} vs {}", d.pose.pos, points(q1 + t).1);
    }
}

/// Every mass of the tree weighs on the link it hangs from: a 5 kg camera on a branch off link `a` (through
/// a revolute joint held at its URDF zero) and a 2 kg gripper fixed beyond the tip link `b`. Each joint's
/// gravity load (`arm_statics`) is the sum over the bodies it carries of w . ((c - o) x m g), computed here
/// from the file's numbers (N mm); the model says what it carries and how much is off the path.
#[test]
fn masses_off_the_path_weigh_on_the_link_they_hang_from() {
    let urdf = r#"<robot name="branch">
  <link name="base"><inertial><mass value="20"/></inertial></link>
  <link name="a"><inertial><origin xyz="0.2 0 0.01"/><mass value="3"/></inertial></link>
  <link name="b"><inertial><origin xyz="0.15 0 0"/><mass value="1.5"/><inertia ixx="0.01" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="camera"><inertial><origin xyz="0.1 0.05 0"/><mass value="5"/></inertial></link>
  <link name="gripper"><inertial><origin xyz="0.05 0 0.02"/><mass value="2"/></inertial></link>
  <joint name="J1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 1 0"/></joint>
  <joint name="J2" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0.4 0 0"/><axis xyz="0 1 0"/></joint>
  <joint name="pan" type="revolute"><parent link="a"/><child link="camera"/><origin xyz="0.1 0 0.1"/><axis xyz="0 0 1"/></joint>
  <joint name="mount" type="fixed"><parent link="b"/><child link="gripper"/><origin xyz="0.3 0 0"/></joint>
</robot>"#;
    let joints = "joints = { J1 = { stiffness = 1e8 }, J2 = { stiffness = 5e7 } }";
    let (dir, m) = arm(urdf, "base", "b", joints, "gravity = [0, 0, -9.81]");
    let m = m.unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
        .current_dir(dir.path())
        .args(["point", "arm.toml", "--joints=0.1,0.2", "--wrench=0,0,0,0,0,0"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert_eq!(
        err.matches("the arm carries 11.500000 kg on its moving links, 7.000000 kg of it off").count(),
        1,
        "{err}"
    );
    let carried = m.joint_space.as_ref().unwrap().carried;
    assert!((carried.kg - 11.5).abs() < 1e-12 && (carried.off_path_kg - 7.0).abs() < 1e-12, "{carried:?}");
    assert!((carried.on_base_kg - 20.0).abs() < 1e-12, "{carried:?}");
    let g = Vec3::new(0.0, 0.0, -9.81);
    let mut r = rng(7);
    for _ in 0..10 {
        let q: [f64; 2] = [r.random_range(-1.5..1.5), r.random_range(-2.0..2.0)];
        // Rotations about y: a link's frame after J1 and after J2 (z up, x along the arm at zero).
        let ry = |t: f64| stiff::kinematics::frame::rotation_about(&Vec3::y(), t);
        let (ra, rb) = (ry(q[0]), ry(q[0] + q[1]));
        let o2 = ra * Vec3::new(400.0, 0.0, 0.0);
        let bodies: [(f64, Vec3, bool); 4] = [
            (3.0, ra * Vec3::new(200.0, 0.0, 10.0), false),
            (5.0, ra * Vec3::new(200.0, 50.0, 100.0), false),
            (1.5, o2 + rb * Vec3::new(150.0, 0.0, 0.0), true),
            (2.0, o2 + rb * Vec3::new(350.0, 0.0, 20.0), true),
        ];
        let load = |origin: Vec3, beyond_j2_only: bool| -> f64 {
            bodies
                .iter()
                .filter(|(_, _, after_j2)| *after_j2 || !beyond_j2_only)
                .map(|(kg, c, _)| Vec3::y().dot(&(c - origin).cross(&(g * *kg))))
                .sum()
        };
        let mut state = m.new_state();
        let s = m.arm_statics(&q, &Vec6::zeros(), &mut state).unwrap();
        let want = [load(Vec3::zeros(), false), load(o2, true)];
        for (k, (got, want)) in s.loads.iter().zip(want).enumerate() {
            assert!((got - want).abs() < 1e-9 * want.abs().max(1.0), "joint {k}: {got} vs {want}");
        }
    }
}

/// The arm's own route equals the leg route on the FANUC: the compliance J_e K_e^-1 J_e^T against the
/// inverse of the platform's K = S^-1 (1e-10 relative), and the loaded tangent compliance of the arm's
/// Newton solve against central differences of its equilibria under the sag plus a wrench (1e-6 relative).
#[test]
fn the_arm_route_equals_the_leg_route_and_differences_of_equilibria() {
    let m = stiff::model::load_manipulator(Path::new(FANUC)).unwrap();
    assert!(m.is_serial_arm());
    let mut r = rng(11);
    for _ in 0..20 {
        let t = random_angles(&mut r);
        let (frame, mut state) = placed(&m, &t);
        let c = m.arm_unloaded(&frame, &mut state).unwrap().unwrap().compliance;
        let k = m.unloaded(&frame, &mut state).unwrap().stiffness;
        let leg = k.try_inverse().unwrap();
        assert!((c - leg).norm() < 1e-10 * c.norm(), "{c} vs {leg}");
        let w = Vec6::new(150.0, -80.0, 300.0, 2.0e4, -1.0e4, 5.0e3);
        let d = m.deflect(&frame, &w, None, &mut state).unwrap();
        let tangent = d.compliance.unwrap();
        for i in 0..6 {
            let h = if i < 3 { 10.0 } else { 1.0e4 };
            let mut up = w;
            up[i] += h;
            let mut down = w;
            down[i] -= h;
            // The increment between the two equilibria in the tangent's own coordinates: the translation and
            // the base-frame rotation vector log(R_up R_down^T).
            let at = |w: &Vec6, state: &mut _| m.deflect(&frame, w, None, state).unwrap().pose;
            let column = at(&down, &mut state).error_to(&at(&up, &mut state)) / (2.0 * h);
            let want = tangent.column(i).into_owned();
            assert!((column - want).norm() < 1e-6 * want.norm(), "column {i}: {column} vs {want}");
        }
    }
}

/// Bad trees are located errors: a second link of the same name, a joint that closes a loop, a mimic whose
/// master is not in the file, mimics that form a loop, a tip that is not in the tree, a non-finite inertia;
/// nothing is built. (An inertia that is not positive semi-definite is read: it is not used, and real files
/// carry them, TIAGo's antennas among them.)
#[test]
fn bad_trees_are_located_errors() {
    let base = r#"<link name="base"/><link name="a"/><link name="b"/>
  <joint name="J1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/></joint>
  <joint name="J2" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/></joint>"#;
    let cases: [(&str, &str, &str); 6] = [
        (r#"<link name="a"/>"#, "b", "a second link named `a` (the first is on line 2)"),
        (
            r#"<joint name="L" type="fixed"><parent link="b"/><child link="base"/></joint>"#,
            "b",
            "closes a loop through link",
        ),
        (
            r#"<link name="c"/><joint name="J3" type="revolute"><parent link="b"/><child link="c"/><axis xyz="0 0 1"/><mimic joint="nowhere"/></joint>"#,
            "c",
            "joint `J3` mimics `nowhere`, which is not a joint of the file",
        ),
        (
            r#"<link name="c"/><link name="d"/><joint name="J3" type="revolute"><parent link="b"/><child link="c"/><axis xyz="0 0 1"/><mimic joint="J4"/></joint>
  <joint name="J4" type="revolute"><parent link="c"/><child link="d"/><axis xyz="0 0 1"/><mimic joint="J3"/></joint>"#,
            "d",
            "the <mimic> joints form a loop: J3 -> J4 -> J3",
        ),
        ("", "hand", "no link named `hand`"),
        (
            r#"<link name="c"><inertial><mass value="1"/><inertia ixx="nan" iyy="0.1" izz="0.1"/></inertial></link><joint name="J3" type="fixed"><parent link="b"/><child link="c"/></joint>"#,
            "b",
            "`ixx=\"nan\"` is not 1 finite numbers",
        ),
    ];
    for (extra, tip, says) in cases {
        let urdf = format!("<robot name=\"bad\">\n  {base}\n  {extra}\n</robot>");
        let (_dir, m) = arm(&urdf, "base", tip, "", "");
        let e = m.err().unwrap_or_else(|| panic!("{extra} was accepted"));
        assert!(e.contains("arm.urdf") && e.contains(says), "{extra}: {e}");
        if !says.starts_with("no link") {
            assert!(e.contains("line "), "{e}");
        }
    }
}

/// Units a user gets wrong: joint values outside the URDF's limits (degrees given as radians) get one
/// warning per file naming the first such row and joint, and the run goes on with the values as given; a
/// points file with both a pose and joint coordinates says which it used.
#[test]
fn joint_values_outside_the_limits_are_said_once() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("arm.urdf"), PLANAR3).unwrap();
    let toml = "name = \"arm\"\n[[leg]]\nname = \"arm\"\n[leg.urdf]\nfile = \"arm.urdf\"\nroot = \"base\"\ntip = \"tool\"\njoints = { J1 = { stiffness = 1e7 }, J2 = { stiffness = 1e7 }, J3 = { stiffness = 1e7 } }\n";
    std::fs::write(dir.path().join("arm.toml"), toml).unwrap();
    let run = |points: &str| {
        std::fs::write(dir.path().join("p.csv"), points).unwrap();
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
            .current_dir(dir.path())
            .args(["map", "arm.toml", "--points", "p.csv", "-o", "out.csv", "-q"])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8(out.stderr).unwrap()
    };
    let err = run("q_J1,q_J2,q_J3\n0.3,0.2,0.1\n45,10,5\n90,0,0\n");
    assert_eq!(err.matches("warning:").count(), 1, "{err}");
    assert!(err.contains("p.csv, line 3") && err.contains("joint `J1` is at 45") && err.contains("[-3, 3]"), "{err}");
    let err = run("x_mm,y_mm,z_mm,q_J1,q_J2,q_J3\n1,2,3,0.3,0.2,0.1\n");
    assert!(!err.contains("warning:") && err.contains("the joint coordinates are used"), "{err}");
}

/// What `diagnose --model-out` writes for an otherwise rigid arm (compliance added to two joints by
/// `[[joint_correction]]`) loads and predicts: the FANUC with no joint spring but J2 and J3 given added
/// compliances has C = c2 J_2 J_2^T + c3 J_3 J_3^T (the DH Jacobian of tests/serial.rs), rank 2, and a loaded
/// equilibrium under its own weight (stable, `rigid_directions`), at random configurations.
#[test]
fn a_calibrated_model_of_a_rigid_arm_loads_and_predicts() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy("manipulators/fanuc-r2000ic.urdf", dir.path().join("fanuc-r2000ic.urdf")).unwrap();
    let source = std::fs::read_to_string(FANUC).unwrap();
    let rigid: String = source.lines().filter(|l| !l.starts_with("joints =")).map(|l| format!("{l}\n")).collect();
    let (c2, c3) = (3.0e-10, 5.0e-10);
    let toml = format!(
        "{rigid}\n[[joint_correction]]\njoint = \"J2\"\ncompliance = {c2}\n\n[[joint_correction]]\njoint = \"J3\"\ncompliance = {c3}\n"
    );
    std::fs::write(dir.path().join("c.toml"), toml).unwrap();
    let m = stiff::model::load_manipulator(&dir.path().join("c.toml")).unwrap();
    let mut r = rng(3);
    for _ in 0..10 {
        let t = random_angles(&mut r);
        let (frame, mut state) = placed(&m, &t);
        let j = crate::serial::dh_jacobian(&crate::serial::model_angles(&t));
        let (j2, j3) = (j.column(1).into_owned(), j.column(2).into_owned());
        let want: Mat6 = j2 * j2.transpose() * c2 + j3 * j3.transpose() * c3;
        let u = unloaded_point(&m, &pose_point(&frame), &mut state);
        assert_eq!((u.status, u.rank), (Status::RigidDirections, Some(2)));
        assert!((u.compliance.unwrap() - want).norm() < 1e-9 * want.norm());
        let d = m.deflect(&frame, &Vec6::zeros(), None, &mut state).unwrap();
        assert!(d.stable && d.displacement.norm() > 0.0 && d.displacement.iter().all(|v| v.is_finite()));
    }
}

/// Regressions from fuzzed descriptions: `file = "/dev/zero"` was read until memory ran out, and a NaN tool
/// rotation or a tool 1e300 mm long was accepted and then reported as an unreachable pose. Each is refused
/// when the model is read, with what is wrong.
#[test]
fn endless_files_and_non_finite_tools_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("arm.urdf"), PLANAR3).unwrap();
    let load = |file: &str, tool: &str| {
        let toml = format!(
            "name = \"arm\"\n[[leg]]\nname = \"arm\"\n[leg.urdf]\nfile = \"{file}\"\nroot = \"base\"\ntip = \"tool\"\n{tool}\n"
        );
        std::fs::write(dir.path().join("arm.toml"), toml).unwrap();
        stiff::model::load_manipulator(&dir.path().join("arm.toml")).map(|_| ()).map_err(|e| e.to_string())
    };
    assert!(load("arm.urdf", "").is_ok());
    let e = load("/dev/zero", "").unwrap_err();
    assert!(e.contains("/dev/zero: not a regular file"), "{e}");
    let e = load(".", "").unwrap_err();
    assert!(e.contains("not a regular file"), "{e}");
    let e = load("arm.urdf", "tool = { rotation_axis = \"z\", rotation_deg = nan }").unwrap_err();
    assert!(e.contains("arm.toml, line 8") && e.contains("NaN is not a finite number"), "{e}");
    let e = load("arm.urdf", "tool = { translation = [1e300, 0, 0] }").unwrap_err();
    assert!(e.contains("arm.toml, line 8") && e.contains("ten kilometres"), "{e}");
}

/// At a kinematic singularity a six-joint arm with a spring at every joint cannot move its tool along one
/// direction: its compliance J K^-1 J^T has rank 5 and that direction is rigid, not free (every motion it
/// can make is resisted by a spring). The FANUC with its wrist straight (every angle zero, J4 and J6 on one
/// axis): `rigid_directions`, rank 5, one rigid wrench, which the compliance maps to nothing, and no free
/// direction; a thousandth of a radian away the arm is `ill_conditioned`, never `singular`.
#[test]
fn a_singular_configuration_is_rigid_along_one_direction_not_free() {
    let m = stiff::model::load_manipulator(Path::new(FANUC)).unwrap();
    let (frame, mut state) = placed(&m, &[0.0; 6]);
    let r = unloaded_point(&m, &pose_point(&frame), &mut state);
    assert_eq!((r.status, r.rank, r.rigid.len(), r.free.len()), (Status::RigidDirections, Some(5), 1, 0), "{r:?}");
    let c = r.compliance.unwrap();
    // The rigid wrench in N and N mm: its moment weighed by the length scale, as the directions are unit.
    assert!((c * r.rigid[0]).norm() < 1e-9 * c.norm() * m.length_scale, "{}", c * r.rigid[0]);
    let (frame, mut state) = placed(&m, &[0.0, 0.0, 0.0, 0.0, 1e-3, 0.0]);
    let r = unloaded_point(&m, &pose_point(&frame), &mut state);
    assert_eq!((r.status, r.free.len()), (Status::IllConditioned, 0), "{r:?}");
}

/// A mimic joint's master may be off the path: a lifting column logged by its bottom stage's coordinate
/// (`lift`, on a branch of its own), its two stages on the path both mimicking it. The model's coordinate
/// is `lift` (mm), the tool rises by twice it (plus the stages' origins), and the lift's spring k drives both
/// stages: the vertical compliance is (1 + 1)^2 / k, everything else rigid.
#[test]
fn a_master_off_the_path_is_a_coordinate_of_the_model() {
    let urdf = r#"<robot name="column">
  <link name="base"/><link name="encoder"/><link name="s1"/><link name="s2"/><link name="tool"/>
  <joint name="lift" type="prismatic"><parent link="base"/><child link="encoder"/><axis xyz="0 0 1"/><limit lower="0" upper="0.5"/></joint>
  <joint name="stage1" type="prismatic"><parent link="base"/><child link="s1"/><origin xyz="0 0 0.3"/><axis xyz="0 0 1"/><mimic joint="lift"/></joint>
  <joint name="stage2" type="prismatic"><parent link="s1"/><child link="s2"/><origin xyz="0 0 0.2"/><axis xyz="0 0 1"/><mimic joint="stage1"/></joint>
  <joint name="T" type="fixed"><parent link="s2"/><child link="tool"/><origin xyz="0.1 0 0"/></joint>
</robot>"#;
    let k = 2.0e4;
    let (_dir, m) = arm(urdf, "base", "tool", &format!("joints = {{ lift = {{ stiffness = {k} }} }}"), "");
    let m = m.unwrap();
    assert_eq!(m.joint_space.as_ref().unwrap().names, vec!["lift".to_string()]);
    let (frame, mut state) = placed(&m, &[120.0]);
    assert!((frame.pos - Vec3::new(100.0, 0.0, 500.0 + 240.0)).norm() < 1e-9, "{}", frame.pos);
    let r = unloaded_point(&m, &pose_point(&frame), &mut state);
    assert_eq!((r.status, r.rank), (Status::RigidDirections, Some(1)));
    let c = r.compliance.unwrap();
    assert!((c[(2, 2)] - 4.0 / k).abs() < 1e-12 * 4.0 / k && (c.norm() - c[(2, 2)]).abs() < 1e-15, "{c}");
}
