//! Serial arms described in URDF: the chain read from URDF equals the same robot written by hand from its
//! modified Denavit-Hartenberg table (forward kinematics and compliance at random configurations), the
//! compliance is Salisbury's C = J K_theta^-1 J^T computed here independently (paper 002, rigid links),
//! poses are given as the controller's joint angles, and the shipped FANUC R-2000iC reproduces the 43
//! measured deflections of tests/reference/fanuc-r2000ic/ as an independent computation with the source's
//! stiffnesses does. Bad URDF input is a located error.

use std::path::Path;

use nalgebra::{Matrix3x6, Matrix6};
use rand::Rng;
use stiff::kinematics::frame::{Frame, Mat6, Vec3, Vec6};
use stiff::platform::manipulator::Manipulator;

use crate::common::{rng, run_with_deadline};

pub(crate) const FANUC: &str = "manipulators/fanuc-r2000ic.toml";

/// The source's modified DH rows (alpha(i-1), a(i-1) in mm, theta offset, d(i) in mm), its tool point in frame
/// 6 (mm) and its identified joint stiffnesses (N mm/rad): tests/reference/fanuc-r2000ic/README.md.
pub(crate) const DH: [(f64, f64, f64, f64); 6] = [
    (0.0, 0.0, 0.0, 670.0),
    (-std::f64::consts::FRAC_PI_2, 312.0, -std::f64::consts::FRAC_PI_2, 0.0),
    (0.0, 1075.0, 0.0, 0.0),
    (-std::f64::consts::FRAC_PI_2, 225.0, 0.0, 1280.0),
    (std::f64::consts::FRAC_PI_2, 0.0, 0.0, 0.0),
    (-std::f64::consts::FRAC_PI_2, 0.0, 0.0, 215.0),
];
pub(crate) const TOOL: [f64; 3] = [6.9, 245.3, 319.3];
pub(crate) const K_JOINT: [f64; 6] =
    [9.339417645e8, 4.129256136e9, 1.907534091e9, 2.332046026e8, 4.043588275e8, 7.961815940e7];

/// Craig's modified DH transform of one row: Rx(alpha) Tx(a) Rz(theta) Tz(d), as a 4x4 matrix.
fn mdh(alpha: f64, a: f64, theta: f64, d: f64) -> nalgebra::Matrix4<f64> {
    let (ca, sa, ct, st) = (alpha.cos(), alpha.sin(), theta.cos(), theta.sin());
    nalgebra::Matrix4::new(
        ct,
        -st,
        0.0,
        a,
        st * ca,
        ct * ca,
        -sa,
        -sa * d,
        st * sa,
        ct * sa,
        ca,
        ca * d,
        0.0,
        0.0,
        0.0,
        1.0,
    )
}

/// The tool point and each joint's frame (axis z, origin) from the DH table at model angles q.
pub(crate) fn dh_kinematics(q: &[f64; 6]) -> (Vec3, Vec<nalgebra::Matrix4<f64>>) {
    dh_kinematics_changed(q, None)
}

/// A change of the fixed transform leading to joint `.0` (0-based): a homogeneous transform in the joint's
/// frame before its motion (z its axis, x where the DH table's offset turns it), `G = T(d) R(r)`.
pub(crate) type GeometryChange = Option<(usize, nalgebra::Matrix4<f64>)>;

/// As `dh_kinematics`, with the fixed transform leading to one joint changed: link k's transform is
/// Rx(alpha) Tx(a) Tz(d) Rz(offset) Rz(q) (the table's, Rz and Tz commuting), the change G put between
/// Rz(offset) and the joint's motion Rz(q).
pub(crate) fn dh_kinematics_changed(q: &[f64; 6], change: GeometryChange) -> (Vec3, Vec<nalgebra::Matrix4<f64>>) {
    let mut m = nalgebra::Matrix4::identity();
    let mut frames = Vec::new();
    for (k, (alpha, a, offset, d)) in DH.iter().enumerate() {
        match change {
            Some((j, g)) if j == k => m *= mdh(*alpha, *a, *offset, *d) * g * mdh(0.0, 0.0, q[k], 0.0),
            _ => m *= mdh(*alpha, *a, q[k] + offset, *d),
        }
        frames.push(m);
    }
    let tool = m * nalgebra::Vector4::new(TOOL[0], TOOL[1], TOOL[2], 1.0);
    (Vec3::new(tool.x, tool.y, tool.z), frames)
}

/// The geometric Jacobian at the tool point (rows: translation mm/rad, rotation), from the DH frames.
pub(crate) fn dh_jacobian(q: &[f64; 6]) -> Matrix6<f64> {
    let (p, frames) = dh_kinematics(q);
    let mut j = Matrix6::zeros();
    for (k, f) in frames.iter().enumerate() {
        let z = Vec3::new(f[(0, 2)], f[(1, 2)], f[(2, 2)]);
        let o = Vec3::new(f[(0, 3)], f[(1, 3)], f[(2, 3)]);
        let v = z.cross(&(p - o));
        j.set_column(k, &Vec6::new(v.x, v.y, v.z, z.x, z.y, z.z));
    }
    j
}

/// The source's controller-to-model map: q1 = t1, q2 = t2, q3 = -(t2 + t3), q4 = -t4, q5 = -t5, q6 = -t6.
pub(crate) fn model_angles(t: &[f64; 6]) -> [f64; 6] {
    [t[0], t[1], -(t[1] + t[2]), -t[3], -t[4], -t[5]]
}

fn fanuc() -> Manipulator {
    stiff::model::load_manipulator(Path::new(FANUC)).unwrap()
}

/// The arm's unloaded stiffness at the controller's angles `t`, placed through its joint space.
fn stiffness_at(m: &Manipulator, t: &[f64; 6]) -> (Frame, Mat6) {
    let mut state = m.new_state();
    let frame = m.pose_at_joints(t, &mut state).expect("a finite pose");
    (frame, m.unloaded(&frame, &mut state).unwrap().stiffness)
}

pub(crate) fn random_angles(r: &mut rand::rngs::StdRng) -> [f64; 6] {
    // Within the joint limits, away from the wrist's singularity (q5 = 0).
    let t: [f64; 6] = std::array::from_fn(|k| match k {
        0 => r.random_range(-3.0..3.0),
        1 => r.random_range(-0.9..1.2),
        2 => r.random_range(-1.5..1.5),
        4 => r.random_range(0.2..1.8) * if r.random_bool(0.5) { 1.0 } else { -1.0 },
        _ => r.random_range(-3.0..3.0),
    });
    t
}

/// Forward kinematics from URDF (fixed-axis roll-pitch-yaw origins, metres) equals the DH table computed
/// here (mm) to 1e-9 mm, and the compliance equals Salisbury's C = J K^-1 J^T with J from the DH frames to
/// 1e-10 relative, at 100 random configurations given as the controller's angles.
#[test]
fn urdf_arm_matches_its_dh_table_and_salisbury() {
    let m = fanuc();
    let mut r = rng(46);
    let k_inv = Matrix6::from_diagonal(&Vec6::from_iterator(K_JOINT.iter().map(|k| 1.0 / k)));
    for _ in 0..100 {
        let t = random_angles(&mut r);
        let q = model_angles(&t);
        let (frame, k) = stiffness_at(&m, &t);
        let (p, frames) = dh_kinematics(&q);
        assert!((frame.pos - p).norm() < 1e-9, "{t:?}: {} vs {p}", frame.pos);
        let last = frames[5];
        let rot = nalgebra::Matrix3::from_fn(|i, j| last[(i, j)]);
        assert!((frame.rot - rot).norm() < 1e-12, "{t:?}: orientation");
        let j = dh_jacobian(&q);
        assert_compliance_close(&k.try_inverse().unwrap(), &(j * k_inv * j.transpose()), &format!("{t:?}"));
    }
}

/// `c` equals `expected` to 1e-10 relative to the size of each block (translations in mm/N, rotations in
/// rad/(N mm)).
fn assert_compliance_close(c: &Mat6, expected: &Mat6, context: &str) {
    for (rows, cols) in [(0..3, 0..3), (0..3, 3..6), (3..6, 3..6)] {
        let scale = rows
            .clone()
            .flat_map(|i| cols.clone().map(move |jj| (i, jj)))
            .map(|(i, jj)| expected[(i, jj)].abs())
            .fold(0.0, f64::max);
        for i in rows.clone() {
            for jj in cols.clone() {
                assert!(
                    (c[(i, jj)] - expected[(i, jj)]).abs() <= 1e-10 * scale,
                    "{context}: C{i}{jj} {} vs {}",
                    c[(i, jj)],
                    expected[(i, jj)]
                );
            }
        }
    }
}

/// The FANUC description rewritten by `change` into `dir` (its URDF named by absolute path), and read.
fn fanuc_changed(dir: &Path, change: impl Fn(String) -> String) -> (std::path::PathBuf, Manipulator) {
    let urdf = std::env::current_dir().unwrap().join("manipulators/fanuc-r2000ic.urdf");
    let text = std::fs::read_to_string(FANUC)
        .unwrap()
        .replace("file = \"fanuc-r2000ic.urdf\"", &format!("file = {:?}", urdf.display().to_string()));
    let path = dir.join("changed.toml");
    std::fs::write(&path, change(text)).unwrap();
    let m = stiff::model::load_manipulator(&path).unwrap();
    (path, m)
}

/// A gravity compensator makes a joint's equivalent stiffness depend on its configuration (paper 000 s. 5):
/// J2's stiffness given as k2 (1.5 + 0.5 cos 2q) and J3's compliance as (1 + 0.3 sin q) / k3, q each joint's
/// own (model) coordinate, give Salisbury's C = J K(q)^-1 J^T with those values computed here, at 30 random
/// configurations (1e-10 relative); where the formula gives no positive stiffness (k2 cos q at cos q < 0)
/// the map's row says the leg has no stiffness there (`singular_leg`), never a row that looks fine.
#[test]
fn a_joints_stiffness_may_be_a_formula_of_its_own_coordinate() {
    let dir = tempfile::tempdir().unwrap();
    let (_, m) = fanuc_changed(dir.path(), |t| {
        t.replace("J2 = { stiffness = \"k2\" }", "J2 = { stiffness = \"k2 * (1.5 + 0.5 * cos(2 * q))\" }")
            .replace("J3 = { stiffness = \"k3\" }", "J3 = { compliance = \"(1 + 0.3 * sin(q)) / k3\" }")
    });
    let mut r = rng(47);
    for _ in 0..30 {
        let t = random_angles(&mut r);
        let q = model_angles(&t);
        let mut k = K_JOINT;
        k[1] *= 1.5 + 0.5 * (2.0 * q[1]).cos();
        k[2] /= 1.0 + 0.3 * q[2].sin();
        let k_inv = Matrix6::from_diagonal(&Vec6::from_iterator(k.iter().map(|k| 1.0 / k)));
        let j = dh_jacobian(&q);
        let (_, stiffness) = stiffness_at(&m, &t);
        assert_compliance_close(&stiffness.try_inverse().unwrap(), &(j * k_inv * j.transpose()), &format!("{t:?}"));
    }
    let (model, _) =
        fanuc_changed(dir.path(), |t| t.replace("J2 = { stiffness = \"k2\" }", "J2 = { stiffness = \"k2 * cos(q)\" }"));
    let points = dir.path().join("q.csv");
    std::fs::write(&points, "q_J1,q_J2,q_J3,q_J4,q_J5,q_J6\n0,0.5,0,0,1,0\n0,2.5,-2.5,0,1,0\n").unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
        .args(["map", model.to_str().unwrap(), "--points", points.to_str().unwrap(), "-q"])
        .output()
        .unwrap();
    let rows = String::from_utf8(out.stdout).unwrap();
    let statuses: Vec<&str> = rows.lines().skip(1).map(|l| l.split(',').nth(8).unwrap()).collect();
    assert_eq!(statuses, ["ok", "singular_leg"], "{rows}");
}

/// The FANUC measurements (tests/reference/fanuc-r2000ic/): a cable pulled the tool point with a known force
/// at 43 configurations. The measurement is differential (the self-weight's sag is the same with and
/// without the cable), so `stiff map --loaded` with each row's force minus the same map at zero force is the
/// prediction. With the source's joint stiffnesses it leaves an RMS residual length of 0.423 mm (a rigid
/// robot: 1.725 mm), as Salisbury's model computed here independently does (0.4229 mm); the largest residual
/// component is 0.925 mm (the largest residual length is 1.215 mm, at row 17).
#[test]
fn the_fanuc_measurements_are_reproduced_with_the_sources_stiffnesses() {
    let read = |name: &str| -> Vec<[f64; 3]> {
        let text = std::fs::read_to_string(format!("tests/reference/fanuc-r2000ic/{name}")).unwrap();
        text.lines()
            .skip(1)
            .map(|l| {
                let v: Vec<f64> = l.split(',').map(|x| x.trim().parse().unwrap()).collect();
                [v[0], v[1], v[2]]
            })
            .collect()
    };
    let angles: Vec<[f64; 6]> = std::fs::read_to_string("tests/reference/fanuc-r2000ic/joint_angles.csv")
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.trim().parse().unwrap()).collect();
            std::array::from_fn(|k| v[k])
        })
        .collect();
    let (forces, measured) = (read("forces.csv"), read("deltaX.csv"));
    assert_eq!((angles.len(), forces.len(), measured.len()), (43, 43, 43));
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, with_force: bool| {
        let mut text = String::from("q_J1,q_J2,q_J3,q_J4,q_J5,q_J6,Fx_N,Fy_N,Fz_N,Mx_Nmm,My_Nmm,Mz_Nmm\n");
        for (t, f) in angles.iter().zip(&forces) {
            let f = if with_force { *f } else { [0.0; 3] };
            let cells: Vec<String> = t.iter().chain(&f).chain(&[0.0; 3]).map(|v| v.to_string()).collect();
            text.push_str(&(cells.join(",") + "\n"));
        }
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        path
    };
    let map = |points: &Path| -> Vec<[f64; 3]> {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
            .args(["map", FANUC, "--points", points.to_str().unwrap(), "--loaded", "-q"])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let rows = crate::common::csv_columns(&String::from_utf8(out.stdout).unwrap(), &["dx_mm", "dy_mm", "dz_mm"]);
        rows.iter().map(|r| [r[0], r[1], r[2]]).collect()
    };
    let (loaded, sag) = (map(&write("force.csv", true)), map(&write("zero.csv", false)));
    let k_inv = Matrix6::from_diagonal(&Vec6::from_iterator(K_JOINT.iter().map(|k| 1.0 / k)));
    let (mut stiff_sq, mut salisbury_sq, mut rigid_sq, mut largest_component) = (0.0, 0.0, 0.0, 0.0f64);
    for i in 0..43 {
        let m = Vec3::from(measured[i]) * 1000.0;
        let predicted = Vec3::from(loaded[i]) - Vec3::from(sag[i]);
        let q = model_angles(&angles[i]);
        let jt: Matrix3x6<f64> = dh_jacobian(&q).fixed_rows::<3>(0).into();
        let salisbury = jt * k_inv * jt.transpose() * Vec3::from(forces[i]);
        // The self-weight's sag changes the configuration by a few 1e-4 rad: the two agree to 1%.
        assert!(
            (predicted - salisbury).norm() <= 0.01 * salisbury.norm() + 1e-3,
            "row {i}: {predicted} vs {salisbury}"
        );
        stiff_sq += (predicted - m).norm_squared();
        salisbury_sq += (salisbury - m).norm_squared();
        rigid_sq += m.norm_squared();
        largest_component = largest_component.max((predicted - m).amax());
    }
    let rms = |s: f64| (s / 43.0).sqrt();
    assert!((rms(salisbury_sq) - 0.4229).abs() < 5e-5, "Salisbury: {}", rms(salisbury_sq));
    assert!((rms(stiff_sq) - 0.423).abs() < 1e-3, "stiff: {} mm RMS", rms(stiff_sq));
    assert!((rms(rigid_sq) - 1.725).abs() < 5e-4, "rigid: {}", rms(rigid_sq));
    assert!((largest_component - 0.925).abs() < 5e-3, "largest component {largest_component}");
}

/// The source's link masses (kg) and centres of mass in their DH frames (mm).
pub(crate) const MASSES: [(f64, [f64; 3]); 6] = [
    (262.614, [-13.9, 76.5, -110.7]),
    (156.154, [424.8, 42.87, 216.3]),
    (149.341, [134.2, 241.5, 39.1]),
    (10.190, [0.0, 1.9, -105.5]),
    (17.698, [0.0, 54.3, -27.7]),
    (41.450, [0.5, -33.6, 265.4]),
];

/// The joints' gravity torques at model angles q (N mm, g = 9.81 m/s^2 along -z): tau_k = sum over links
/// i >= k of (z_k x (c_i - o_k)) . (m_i g).
pub(crate) fn dh_gravity_torques(q: &[f64; 6]) -> Vec6 {
    dh_gravity_torques_along(q, &Vec3::new(0.0, 0.0, -9.81))
}

/// As `dh_gravity_torques`, under gravity `g` (m/s^2, base frame).
pub(crate) fn dh_gravity_torques_along(q: &[f64; 6], g: &Vec3) -> Vec6 {
    dh_gravity_torques_changed(q, g, None)
}

/// As `dh_gravity_torques_along`, the arm's geometry changed as `dh_kinematics_changed` changes it.
pub(crate) fn dh_gravity_torques_changed(q: &[f64; 6], g: &Vec3, change: GeometryChange) -> Vec6 {
    let (_, frames) = dh_kinematics_changed(q, change);
    let mut tau = Vec6::zeros();
    for (i, (kg, c)) in MASSES.iter().enumerate() {
        let f = frames[i];
        let centre = f * nalgebra::Vector4::new(c[0], c[1], c[2], 1.0);
        let centre = Vec3::new(centre.x, centre.y, centre.z);
        let weight = g * *kg;
        for k in 0..=i {
            let fk = frames[k];
            let (z, o) = (Vec3::new(fk[(0, 2)], fk[(1, 2)], fk[(2, 2)]), Vec3::new(fk[(0, 3)], fk[(1, 3)], fk[(2, 3)]));
            tau[k] += z.cross(&(centre - o)).dot(&weight);
        }
    }
    tau
}

/// The links' own weight: with gravity set, a loaded map at zero wrench is the sag under self-weight. For the
/// FANUC at its first measured configuration the sag equals, to first order, C_q applied to the gravity
/// torques of the links computed here from the source's masses (tau = sum_i J_i(c_i)^T m_i g over the links
/// beyond each joint): the tool point moves by J K^-1 tau, within 1% of the loaded equilibrium's sag.
#[test]
fn self_weight_sags_the_arm_as_its_gravity_torques_say() {
    let t = [-1.047040472, -0.291347812, -0.504923753, 0.066113072, -1.098335698, 2.529313699];
    let q = model_angles(&t);
    let (p, _) = dh_kinematics(&q);
    let tau = dh_gravity_torques(&q);
    let j = dh_jacobian(&q);
    let dq = Vec6::from_iterator((0..6).map(|k| tau[k] / K_JOINT[k]));
    let sag_first_order: Vec3 = (j * dq).fixed_rows::<3>(0).into();
    let dir = tempfile::tempdir().unwrap();
    let points = dir.path().join("q.csv");
    let cells: Vec<String> = t.iter().map(|v| v.to_string()).collect();
    std::fs::write(&points, format!("q_J1,q_J2,q_J3,q_J4,q_J5,q_J6\n{}\n", cells.join(","))).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
        .args(["map", FANUC, "--points", points.to_str().unwrap(), "--wrench", "0,0,0,0,0,0", "-q"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    let c = crate::common::csv_columns(&text, &["x_mm", "y_mm", "z_mm", "dx_mm", "dy_mm", "dz_mm"]);
    let row = &c[0];
    assert!((Vec3::new(row[0], row[1], row[2]) - p).norm() < 1e-9, "the row carries the pose");
    let sag = Vec3::new(row[3], row[4], row[5]);
    assert!(sag.norm() > 0.5, "{sag}");
    assert!((sag - sag_first_order).norm() < 0.01 * sag_first_order.norm(), "{sag} vs {sag_first_order}");
    // Unloaded compliance does not see the weight.
    let unloaded = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
        .args(["map", FANUC, "--points", points.to_str().unwrap(), "-q"])
        .output()
        .unwrap();
    assert!(String::from_utf8(unloaded.stdout).unwrap().contains(",ok,"));
}

/// A URDF tree with branches off the path, a fixed joint folded into the transforms and a `<mimic>` joint:
/// the chain from root to tip is the path only, the fixed joint's offset moves the tool, and the mimic joint
/// turns with its master (multiplier 2, offset 0.1 rad): a planar arm whose tool point is known in closed
/// form, (L1 cos a + L2 cos(a + 2a + 0.1), L1 sin a + L2 sin(3a + 0.1)) with the fixed offset along x.
#[test]
fn a_urdf_tree_with_a_fixed_and_a_mimic_joint_gives_the_path_from_root_to_tip() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = r#"<robot name="planar">
  <link name="base"/><link name="a"/><link name="b"/><link name="c"/><link name="camera"/><link name="d"/>
  <joint name="J1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/></joint>
  <joint name="J2" type="continuous"><parent link="a"/><child link="b"/><origin xyz="0.4 0 0"/><axis xyz="0 0 1"/>
    <mimic joint="J1" multiplier="2" offset="0.1"/></joint>
  <joint name="mount" type="fixed"><parent link="b"/><child link="c"/><origin xyz="0.3 0 0"/></joint>
  <joint name="cam" type="fixed"><parent link="a"/><child link="camera"/><origin xyz="0 0.1 0"/></joint>
  <joint name="other" type="revolute"><parent link="base"/><child link="d"/><axis xyz="1 0 0"/></joint>
</robot>"#;
    std::fs::write(dir.path().join("planar.urdf"), urdf).unwrap();
    let toml = "name = \"planar\"\n[[leg]]\nname = \"arm\"\n[leg.urdf]\nfile = \"planar.urdf\"\nroot = \"base\"\ntip = \"c\"\njoints = { J1 = { stiffness = 1e6 } }\n";
    std::fs::write(dir.path().join("planar.toml"), toml).unwrap();
    let m = stiff::model::load_manipulator(&dir.path().join("planar.toml")).unwrap();
    assert_eq!(m.joint_space.as_ref().unwrap().names, vec!["J1".to_string()]);
    for a in [0.0, 0.3, -1.1, 2.5] {
        let mut state = m.new_state();
        let f = m.pose_at_joints(&[a], &mut state).unwrap();
        let want = Vec3::new(
            400.0 * f64::cos(a) + 300.0 * f64::cos(3.0 * a + 0.1),
            400.0 * f64::sin(a) + 300.0 * f64::sin(3.0 * a + 0.1),
            0.0,
        );
        assert!((f.pos - want).norm() < 1e-9, "{a}: {} vs {want}", f.pos);
    }
}

/// Regression: a fixed joint does not move, so its axis is never read; descriptions in use write
/// `<axis xyz="0 0 0"/>` there (TIAGo's torso_fixed_joint), and such a file was refused for a zero axis.
/// The fixed joint's origin still moves the tool (a planar arm: the tool at (L1 cos a + L2, L1 sin a)), and a
/// moving joint with a zero axis is still refused, located.
#[test]
fn a_fixed_joints_zero_axis_is_not_read() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = |axis: &str| {
        format!(
            r#"<robot name="planar">
  <link name="base"/><link name="a"/><link name="b"/>
  <joint name="J1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="{axis}"/></joint>
  <joint name="mount" type="fixed"><parent link="a"/><child link="b"/><origin xyz="0.4 0 0"/><axis xyz="0 0 0"/></joint>
</robot>"#
        )
    };
    let toml = "name = \"planar\"\n[[leg]]\nname = \"arm\"\n[leg.urdf]\nfile = \"planar.urdf\"\nroot = \"base\"\ntip = \"b\"\n";
    std::fs::write(dir.path().join("planar.toml"), toml).unwrap();
    std::fs::write(dir.path().join("planar.urdf"), urdf("0 0 1")).unwrap();
    let m = stiff::model::load_manipulator(&dir.path().join("planar.toml")).unwrap();
    let f = m.pose_at_joints(&[0.7], &mut m.new_state()).unwrap();
    assert!((f.pos - Vec3::new(400.0 * 0.7f64.cos(), 400.0 * 0.7f64.sin(), 0.0)).norm() < 1e-9, "{}", f.pos);
    std::fs::write(dir.path().join("planar.urdf"), urdf("0 0 0")).unwrap();
    let e = stiff::model::load_manipulator(&dir.path().join("planar.toml")).unwrap_err().to_string();
    assert!(e.contains("planar.urdf, line 3") && e.contains("joint `J1`: the axis must not be zero"), "{e}");
}

fn stiff_in(dir: &Path, args: &[&str]) -> (bool, String) {
    let done = run_with_deadline(
        std::process::Command::new(env!("CARGO_BIN_EXE_stiff")).args(args).current_dir(dir),
        usize::MAX,
        std::time::Duration::from_secs(60),
    )
    .expect("no hang");
    (done.status.success(), done.stderr)
}

/// Bad input is a located error and nothing is written: a URDF that does not parse, a root and tip that
/// are not connected, a floating joint on the path, a mimic loop, a joint in the stiffness table that is not
/// on the chain, and joint columns missing or extra.
#[test]
fn bad_urdf_input_is_a_located_error() {
    let dir = tempfile::tempdir().unwrap();
    let good = r#"<robot name="r"><link name="base"/><link name="a"/><link name="b"/><link name="x"/>
<joint name="J1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/></joint>
<joint name="J2" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0.5 0 0"/><axis xyz="0 1 0"/></joint>
</robot>"#;
    let cases: [(&str, String, &str, &str); 6] = [
        ("not-xml", "<robot><link name=\"base\">".to_string(), "", "not a URDF"),
        ("disconnected", good.to_string(), "tip = \"x\"", "are not connected"),
        (
            "floating",
            good.replace("type=\"revolute\"><parent link=\"a\"", "type=\"floating\"><parent link=\"a\""),
            "",
            "joint `J2` is `floating`",
        ),
        (
            "mimic-loop",
            good.replace("<axis xyz=\"0 0 1\"/></joint>", "<axis xyz=\"0 0 1\"/><mimic joint=\"J2\"/></joint>")
                .replace("<axis xyz=\"0 1 0\"/></joint>", "<axis xyz=\"0 1 0\"/><mimic joint=\"J1\"/></joint>"),
            "",
            "loop",
        ),
        (
            "unknown-joint",
            good.to_string(),
            "joints = { J9 = { stiffness = 1e6 } }",
            "joint `J9` in `joints` is not on the chain",
        ),
        ("good", good.to_string(), "", ""),
    ];
    for (name, urdf, extra, message) in cases {
        std::fs::write(dir.path().join(format!("{name}.urdf")), urdf).unwrap();
        let tip = if extra.starts_with("tip") { extra.to_string() } else { "tip = \"b\"".into() };
        let extra = if extra.starts_with("tip") { "" } else { extra };
        let toml = format!(
            "name = \"r\"\n[[leg]]\nname = \"arm\"\n[leg.urdf]\nfile = \"{name}.urdf\"\nroot = \"base\"\n{tip}\n{extra}\n"
        );
        std::fs::write(dir.path().join(format!("{name}.toml")), toml).unwrap();
        std::fs::write(dir.path().join("q.csv"), "q_J1,q_J2\n0.1,0.2\n").unwrap();
        let (ok, err) =
            stiff_in(dir.path(), &["map", &format!("{name}.toml"), "--points", "q.csv", "-q", "-o", "out.csv"]);
        if message.is_empty() {
            assert!(ok, "{name}: {err}");
            std::fs::remove_file(dir.path().join("out.csv")).unwrap();
        } else {
            assert!(!ok && err.contains(message) && err.contains(name), "{name}: {err}");
            assert!(!dir.path().join("out.csv").exists(), "{name}: nothing written");
        }
    }
    // Joint columns missing or extra, and joint columns for a robot that has no joint space.
    for (columns, message) in
        [("q_J1\n0.1\n", "missing q_J2"), ("q_J1,q_J2,q_J3\n0.1,0.2,0.3\n", "not joints of the arm q_J3")]
    {
        std::fs::write(dir.path().join("q.csv"), columns).unwrap();
        let (ok, err) = stiff_in(dir.path(), &["map", "good.toml", "--points", "q.csv", "-q", "-o", "out.csv"]);
        assert!(!ok && err.contains(message) && err.contains("q.csv"), "{err}");
        assert!(!dir.path().join("out.csv").exists());
    }
    let root = std::env::current_dir().unwrap();
    std::fs::write(dir.path().join("q.csv"), "q_J1,q_J2\n0.1,0.2\n").unwrap();
    let puu = root.join("manipulators/orthoglide-3puu.toml");
    let (ok, err) = stiff_in(dir.path(), &["map", puu.to_str().unwrap(), "--points", "q.csv", "-q"]);
    assert!(!ok && err.contains("not a serial arm read from URDF"), "{err}");
}

/// The planar arm's link lengths (mm) and masses (kg: mid-link 1, mid-link 2, at its end) of
/// `write_planar_arm`.
const PLANAR_L1: f64 = 800.0;
const PLANAR_L2: f64 = 600.0;
const PLANAR_MASSES: (f64, f64, f64) = (40.0, 25.0, 15.0);

/// A planar two-joint arm in the vertical x-z plane (joints J1, J2 about y, gravity along -z; masses
/// `PLANAR_MASSES` at the middle of each link and at its end) as `planar.urdf` and `planar.toml` in `dir`,
/// J1 and J2 of stiffness `k` (N mm/rad), with four stiff joints X1-X4 after the end mass (no load) so that
/// the tool has rank 6, and `extra` appended to the description.
fn write_planar_arm(dir: &Path, k: [f64; 2], extra: &str) {
    let (l1, l2) = (PLANAR_L1, PLANAR_L2);
    let (m1, m2, tip) = PLANAR_MASSES;
    let urdf = format!(
        r#"<robot name="planar">
  <link name="base"/>
  <link name="a"><inertial><origin xyz="{h1} 0 0"/><mass value="{m1}"/></inertial></link>
  <link name="b"><inertial><origin xyz="{h2} 0 0"/><mass value="{m2}"/></inertial></link>
  <link name="c"><inertial><origin xyz="0 0 0"/><mass value="{tip}"/></inertial></link>
  <joint name="J1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 1 0"/></joint>
  <joint name="J2" type="revolute"><parent link="a"/><child link="b"/><origin xyz="{l1m} 0 0"/><axis xyz="0 1 0"/></joint>
  <joint name="end" type="fixed"><parent link="b"/><child link="c"/><origin xyz="{l2m} 0 0"/></joint>
  <link name="d"/><link name="e"/><link name="f"/><link name="g"/>
  <joint name="X1" type="prismatic"><parent link="c"/><child link="d"/><axis xyz="0 1 0"/></joint>
  <joint name="X2" type="revolute"><parent link="d"/><child link="e"/><axis xyz="1 0 0"/></joint>
  <joint name="X3" type="revolute"><parent link="e"/><child link="f"/><axis xyz="0 0 1"/></joint>
  <joint name="X4" type="prismatic"><parent link="f"/><child link="g"/><axis xyz="1 0 0"/></joint>
</robot>"#,
        h1 = l1 / 2000.0,
        h2 = l2 / 2000.0,
        l1m = l1 / 1000.0,
        l2m = l2 / 1000.0
    );
    std::fs::write(dir.join("planar.urdf"), urdf).unwrap();
    let (k1, k2) = (k[0], k[1]);
    let toml = format!(
        "name = \"planar\"\ngravity = [0, 0, -9.81]\n[[leg]]\nname = \"arm\"\n[leg.urdf]\nfile = \"planar.urdf\"\nroot = \"base\"\ntip = \"g\"\njoints = {{ J1 = {{ stiffness = {k1:e} }}, J2 = {{ stiffness = {k2:e} }}, X1 = {{ stiffness = 1e4 }}, X2 = {{ stiffness = 1e9 }}, X3 = {{ stiffness = 1e9 }}, X4 = {{ stiffness = 1e4 }} }}\n{extra}"
    );
    std::fs::write(dir.join("planar.toml"), toml).unwrap();
}

/// Play is a model term every loaded study sees: a joint with play b sits b off in the sense of the load
/// it carries at the commanded configuration. On the planar arm, J2 carries the weight of link 2 and the
/// end mass, whose torque about y has the sign of cos(q1 + q2) (the outer link leaning out along +x or -x
/// of its joint); the sag map of the arm with 2 mrad of play at J2 therefore puts its tool where the arm
/// without play, commanded 2 mrad further in that sense, puts its own (to 1e-9 mm: the same equilibrium),
/// for links leaning either way; the unloaded map does not see it, and a play below zero is refused.
#[test]
fn a_joints_play_turns_it_in_the_sense_of_its_load_in_every_loaded_study() {
    let dir = tempfile::tempdir().unwrap();
    let play = 2e-3;
    // The tool where the map puts it: its commanded pose, moved by the sag where loaded (zero wrench).
    let tool = |q: [f64; 2], loaded: bool| -> Vec3 {
        std::fs::write(dir.path().join("q.csv"), format!("q_J1,q_J2,q_X1,q_X2,q_X3,q_X4\n{},{},0,0,0,0\n", q[0], q[1]))
            .unwrap();
        let mut args = vec!["map", "planar.toml", "--points", "q.csv", "-q"];
        if loaded {
            args.extend(["--wrench", "0,0,0,0,0,0"]);
        }
        let done = std::process::Command::new(env!("CARGO_BIN_EXE_stiff")).args(&args).current_dir(dir.path()).output();
        let done = done.unwrap();
        assert!(done.status.success(), "{}", String::from_utf8_lossy(&done.stderr));
        let out = String::from_utf8(done.stdout).unwrap();
        let r = &crate::common::csv_columns(&out, &["x_mm", "y_mm", "z_mm"])[0];
        let pose = Vec3::new(r[0], r[1], r[2]);
        match loaded {
            true => pose + Vec3::from_row_slice(&crate::common::csv_columns(&out, &["dx_mm", "dy_mm", "dz_mm"])[0]),
            false => pose,
        }
    };
    let k = [4e7, 1.5e7];
    for q in [[0.3f64, -0.5], [-0.2, 0.9], [1.0, 1.2], [0.4, 2.0]] {
        // The weight pulls the outer link down: rotation about y by phi takes x to (cos phi, 0, -sin phi), so a
        // link leaning along +x (cos > 0) is turned towards +phi by its weight.
        let sense = (q[0] + q[1]).cos().signum();
        write_planar_arm(dir.path(), k, "");
        let (turned, without, unloaded) = (tool([q[0], q[1] + sense * play], true), tool(q, true), tool(q, false));
        write_planar_arm(dir.path(), k, &format!("[[joint_correction]]\njoint = \"J2\"\nplay = {play}\n"));
        let with_play = tool(q, true);
        assert!((with_play - turned).norm() < 1e-9, "{q:?}: {with_play} with play, {turned} turned by it");
        assert!((with_play - without).norm() > 0.5, "{q:?}: the play moves the tool ({with_play} against {without})");
        assert_eq!(tool(q, false), unloaded, "{q:?}: unloaded, no load and no play");
    }
    write_planar_arm(dir.path(), k, "[[joint_correction]]\njoint = \"J2\"\nplay = -1e-3\n");
    let (ok, err) = stiff_in(dir.path(), &["map", "planar.toml", "--points", "q.csv", "-q"]);
    assert!(!ok && err.contains("a play is a width, zero or above"), "{err}");
}

/// A planar two-joint arm in the vertical x-z plane (joints about y, gravity along -z), point masses at the
/// middle of each link and at its end, read from URDF (four stiff joints after the end mass, which carry no
/// load, give the tool the other four directions, so that its stiffness has rank 6). Its sag under its own weight, computed here from the
/// potential energy V = sum m g z + 1/2 k1 t1^2 + 1/2 k2 t2^2: to first order t = K^-1 tau(q) (the gravity
/// torques at the commanded angles); exactly, the root of dV/dt = 0 found here by Newton's method on the two
/// angles. `map --wrench 0,0,0,0,0,0` gives the exact one to 1e-9 mm, and differs from the first order by
/// the second-order term (checked to be above 1e-3 mm, so the comparison tells them apart). Made soft and
/// heavy and commanded upright, the arm is an inverted pendulum past its limit (m g L > k): its
/// equilibrium at the commanded pose is reported `unstable`, never `ok`.
#[test]
fn self_weight_of_a_planar_arm_against_its_closed_form() {
    let (l1, l2) = (PLANAR_L1, PLANAR_L2);
    let (m1, m2, tip) = PLANAR_MASSES;
    let dir = tempfile::tempdir().unwrap();
    let write_model = |k1: f64, k2: f64| write_planar_arm(dir.path(), [k1, k2], "");
    let map = |q: [f64; 2]| -> (String, Vec3) {
        std::fs::write(dir.path().join("q.csv"), format!("q_J1,q_J2,q_X1,q_X2,q_X3,q_X4\n{},{},0,0,0,0\n", q[0], q[1]))
            .unwrap();
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
            .args(["map", "planar.toml", "--points", "q.csv", "--wrench", "0,0,0,0,0,0", "-q"])
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let text = String::from_utf8(out.stdout).unwrap();
        let row = text.lines().nth(1).unwrap().to_string();
        let c = crate::common::csv_columns(&text, &["dx_mm", "dy_mm", "dz_mm"]);
        (row, Vec3::new(c[0][0], c[0][1], c[0][2]))
    };
    // Rotation about y by phi turns x to (cos phi, 0, -sin phi): heights of the masses and the tip.
    let tip_of =
        |p1: f64, p2: f64| Vec3::new(l1 * p1.cos() + l2 * (p1 + p2).cos(), 0.0, -l1 * p1.sin() - l2 * (p1 + p2).sin());
    // dV/dt for V = g [m1 z(l1/2) + m2 z(l1 + l2/2 along 2) + tip z(end)] + springs, z = -(...) sin(...).
    let gradient = |q: [f64; 2], t: [f64; 2], k: [f64; 2]| {
        let (p1, p2) = (q[0] + t[0], q[0] + t[0] + q[1] + t[1]);
        // dz/dp1 and dz/dp2 of each mass (p2 here the absolute angle of link 2).
        let (dz1_1, dz2_1, dzt_1) = (-l1 / 2.0 * p1.cos(), -l1 * p1.cos(), -l1 * p1.cos());
        let (dz2_2, dzt_2) = (-l2 / 2.0 * p2.cos(), -l2 * p2.cos());
        let w = |m: f64| m * 9.81; // the weight in N (kg times m/s^2); heights in mm, so V in N mm
        let d_abs1 = w(m1) * dz1_1 + w(m2) * (dz2_1 + dz2_2) + w(tip) * (dzt_1 + dzt_2);
        let d_abs2 = w(m2) * dz2_2 + w(tip) * dzt_2;
        // t1 moves both absolute angles, t2 only the second.
        [d_abs1 + k[0] * t[0], d_abs2 + k[1] * t[1]]
    };
    let k = [4e7, 1.5e7];
    write_model(k[0], k[1]);
    for q in [[0.3, -0.5], [-0.2, 0.9], [1.0, -1.4]] {
        // First order: t = -K^-1 dV/dt at t = 0 (the gravity torques).
        let g0 = gradient(q, [0.0, 0.0], [0.0, 0.0]);
        let first = [-g0[0] / k[0], -g0[1] / k[1]];
        // Exact: Newton on the two angles with a central-difference Hessian.
        let mut t = first;
        for _ in 0..30 {
            let r = gradient(q, t, k);
            let h = 1e-7;
            let col = |i: usize| {
                let (mut a, mut b) = (t, t);
                a[i] += h;
                b[i] -= h;
                let (ga, gb) = (gradient(q, a, k), gradient(q, b, k));
                [(ga[0] - gb[0]) / (2.0 * h), (ga[1] - gb[1]) / (2.0 * h)]
            };
            let (c0, c1) = (col(0), col(1));
            let det = c0[0] * c1[1] - c1[0] * c0[1];
            t = [t[0] - (c1[1] * r[0] - c1[0] * r[1]) / det, t[1] - (-c0[1] * r[0] + c0[0] * r[1]) / det];
        }
        let base = tip_of(q[0], q[1]);
        let exact = tip_of(q[0] + t[0], q[1] + t[1]) - base;
        let linear = tip_of(q[0] + first[0], q[1] + first[1]) - base;
        let (row, sag) = map(q);
        assert!(row.contains(",ok,"), "{row}");
        assert!((sag - exact).norm() < 1e-9 * exact.norm().max(1.0) + 1e-9, "{q:?}: {sag} vs exact {exact}");
        assert!((exact - linear).norm() > 1e-3, "{q:?}: the first order is {linear}, exact {exact}: too close to tell");
    }
    // Soft and heavy, commanded upright (q1 = -pi/2 points link 1 up): gravity's destabilising stiffness
    // (about 6.3e5 N mm/rad at joint 1, 1.6e5 at joint 2) exceeds the springs'.
    write_model(2e5, 1e5);
    let (row, _) = map([-std::f64::consts::FRAC_PI_2, 0.0]);
    assert!(row.contains(",unstable,") || row.contains(",not_converged,"), "{row}");
}

/// `stiff point --joints` at a FANUC configuration reports the pose the DH table gives for the controller's
/// angles and, under a wrench, a loaded equilibrium whose displacement minus the self-weight's sag (the
/// same command at zero wrench) is the cable's deflection (Salisbury's to 1%); `stiff curve --joints` goes
/// from the one to the other.
#[test]
fn point_takes_a_serial_arms_joint_coordinates() {
    let t = [-1.047040472, -0.291347812, -0.504923753, 0.066113072, -1.098335698, 2.529313699];
    let joints = format!("--joints={}", t.map(|v| v.to_string()).join(","));
    let run = |wrench: &str| -> serde_json::Value {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
            .args(["point", FANUC, &joints, &format!("--wrench={wrench}"), "--json"])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        serde_json::from_slice(&out.stdout).unwrap()
    };
    let (loaded, sag) = (run("-120.2110768,-78.21523168,-14.69090881,0,0,0"), run("0,0,0,0,0,0"));
    let position: Vec<f64> = serde_json::from_value(loaded["pose"]["position_mm"].clone()).unwrap();
    let (p, _) = dh_kinematics(&model_angles(&t));
    assert!((Vec3::new(position[0], position[1], position[2]) - p).norm() < 1e-9, "{position:?} vs {p}");
    let d = |v: &serde_json::Value| -> Vec3 {
        let d: Vec<f64> = serde_json::from_value(v["loaded"]["deflection"].clone()).unwrap();
        Vec3::new(d[0], d[1], d[2])
    };
    let cable = d(&loaded) - d(&sag);
    // Salisbury with the source's stiffnesses at this configuration: 0.44 mm, mostly along -x.
    let k_inv = Matrix6::from_diagonal(&Vec6::from_iterator(K_JOINT.iter().map(|k| 1.0 / k)));
    let jt: Matrix3x6<f64> = dh_jacobian(&model_angles(&t)).fixed_rows::<3>(0).into();
    let salisbury = jt * k_inv * jt.transpose() * Vec3::new(-120.2110768, -78.21523168, -14.69090881);
    assert!((cable - salisbury).norm() < 0.01 * salisbury.norm(), "{cable} vs {salisbury}");
    // `curve --joints` at the same configuration: from the sag (load factor 0) to the cable's load (1), the
    // same displacement as the two loaded points.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
        .args(["curve", FANUC, &joints, "--wrench-direction=-120.2110768,-78.21523168,-14.69090881,0,0,0"])
        .args(["--max", "1", "--intervals", "2", "-q"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let rows = crate::common::csv_columns(&String::from_utf8(out.stdout).unwrap(), &["dx_mm", "dy_mm", "dz_mm"]);
    let along = Vec3::new(rows[2][0] - rows[0][0], rows[2][1] - rows[0][1], rows[2][2] - rows[0][2]);
    assert!((along - cable).norm() < 1e-6, "curve {along} vs point {cable}");
}

/// A six-joint arm given a pose has several inverse-kinematics branches: the wrist flipped, (q4 + pi, -q5,
/// q6 + pi) in the model's angles, puts the tool at the same pose. A stated `seed` (the controller's angles)
/// is where a cold inverse kinematics starts: seeds 0.2 rad away from either branch, given as
/// controller's angles, each place the arm on its own branch (within 1e-6 rad), at the same pose.
#[test]
fn a_stated_seed_picks_the_branch_of_a_pose() {
    let m = fanuc();
    let t = [0.4, 0.2, -0.3, 0.7, -1.1, 0.5];
    let mut state = m.new_state();
    let pose = m.pose_at_joints(&t, &mut state).unwrap();
    let a = model_angles(&t);
    let pi = std::f64::consts::PI;
    let b = [a[0], a[1], a[2], a[3] + pi, -a[4], a[5] + pi];
    // The same tool pose from both branches (DH model computed here).
    let (pa, fa) = dh_kinematics(&a);
    let (pb, fb) = dh_kinematics(&b);
    assert!((pa - pb).norm() < 1e-9 && (fa[5] - fb[5]).norm() < 1e-9, "both branches reach the pose");
    // Controller angles of a model configuration: theta1 = q1, theta2 = q2, theta3 = -(q3 + q2), theta4..6 = -q.
    let controller = |q: &[f64; 6]| [q[0], q[1], -(q[2] + q[1]), -q[3], -q[4], -q[5]];
    let text = std::fs::read_to_string(FANUC).unwrap();
    let urdf = std::env::current_dir().unwrap().join("manipulators/fanuc-r2000ic.urdf");
    let dir = tempfile::tempdir().unwrap();
    for branch in [a, b] {
        let seed: Vec<String> =
            controller(&branch).iter().enumerate().map(|(k, v)| format!("J{} = {}", k + 1, v + 0.2)).collect();
        let model = text
            .replace("file = \"fanuc-r2000ic.urdf\"", &format!("file = {:?}", urdf.display().to_string()))
            .replace("controller = {", &format!("seed = {{ {} }}\ncontroller = {{", seed.join(", ")));
        let path = dir.path().join("seeded.toml");
        std::fs::write(&path, model).unwrap();
        let seeded = stiff::model::load_manipulator(&path).unwrap();
        let mut state = seeded.new_state();
        seeded.unloaded(&pose, &mut state).unwrap();
        let q = &state.legs[0].coords.actuated;
        let wrap = |x: f64| (x + pi).rem_euclid(2.0 * pi) - pi;
        for k in 0..6 {
            assert!(wrap(q[k] - branch[k]).abs() < 1e-6, "seed near {branch:?}: reached {q:?}");
        }
    }
}

/// Every batch study takes a serial arm's joint coordinates and keeps the configuration given: two rows
/// reach the same tool pose on the two wrist branches (the second flipped, (q4 + pi, -q5, q6 + pi) in the
/// model's angles), which a pose alone cannot tell apart.
/// - `compensate` (the arm's own weight is the load): each row's pose is the DH table's for its angles
///   (1e-9 mm), its command keeps the row's branch (within 0.01 rad of the given angles), and its command in
///   the controller's angles (`command_q_<joint>`) maps to the model's command.
/// - `assemble` with the base moved 1 mm along x: the rigid-body translation of the whole arm, linear and
///   non-linear (within 1e-9 mm), although the arm sags under its weight: a regression test, the non-linear
///   columns once held the sag (1.4 mm) as well.
/// - `sweep` of one design: its summary is the map's over the same joint rows (largest c_tran_max and where).
#[test]
fn batch_studies_take_joint_coordinates_and_keep_the_configuration() {
    let a = [0.4, 0.2, -0.3, 0.7, -1.1, 0.5];
    let pi = std::f64::consts::PI;
    let q = model_angles(&a);
    let flipped = [q[0], q[1], q[2], q[3] + pi, -q[4], q[5] + pi];
    // Controller angles of a model configuration (the inverse of `model_angles`).
    let controller = |q: &[f64; 6]| [q[0], q[1], -(q[2] + q[1]), -q[3], -q[4], -q[5]];
    let rows = [controller(&q), controller(&flipped)];
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::from("name,q_J6,q_J5,q_J4,q_J3,q_J2,q_J1\n");
    for (k, t) in rows.iter().enumerate() {
        let cells: Vec<String> = t.iter().rev().map(|v| v.to_string()).collect();
        text.push_str(&format!("r{k},{}\n", cells.join(",")));
    }
    let points = dir.path().join("joints.csv");
    std::fs::write(&points, text).unwrap();
    let fanuc = std::env::current_dir().unwrap().join(FANUC);
    let run = |args: &[&str]| -> String {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
            .arg(args[0])
            .arg(&fanuc)
            .args(["--points", points.to_str().unwrap(), "-q"])
            .args(&args[1..])
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8(out.stdout).unwrap()
    };
    let wrap = |x: f64| (x + pi).rem_euclid(2.0 * pi) - pi;

    let compensated = run(&["compensate"]);
    let actuators: Vec<String> = (1..=6).map(|k| format!("leg1_actuator{k}_rad")).collect();
    let columns: Vec<&str> = ["x_mm", "y_mm", "z_mm"].into_iter().chain(actuators.iter().map(String::as_str)).collect();
    let found = crate::common::csv_columns(&compensated, &columns);
    assert!(compensated.contains(",ok,"), "{compensated}");
    for (given, row) in [q, flipped].iter().zip(&found) {
        let (p, _) = dh_kinematics(given);
        assert!((Vec3::new(row[0], row[1], row[2]) - p).norm() < 1e-9, "pose {row:?} vs {p}");
        for k in 0..6 {
            assert!(wrap(row[3 + k] - given[k]).abs() < 0.01, "command {:?} left the branch {given:?}", &row[3..]);
        }
    }
    // The command in the controller's angles: mapped as the controller maps them (q3 = -(t2 + t3), the
    // wrist reversed), it is the model's command to round-off.
    let angles: Vec<String> = (1..=6).map(|k| format!("command_q_J{k}_rad")).collect();
    let commanded = crate::common::csv_columns(&compensated, &angles.iter().map(String::as_str).collect::<Vec<_>>());
    for (t, row) in commanded.iter().zip(&found) {
        let mapped = model_angles(&std::array::from_fn(|k| t[k]));
        for k in 0..6 {
            assert!((mapped[k] - row[3 + k]).abs() < 1e-12, "controller {t:?} maps to {mapped:?}, not {:?}", &row[3..]);
        }
    }

    std::fs::write(dir.path().join("base.toml"), "[[leg]]\nname = \"arm\"\nbase = { translation_mm = [1, 0, 0] }\n")
        .unwrap();
    let assembled = run(&["assemble", "--errors", "base.toml"]);
    let names = ["dx_mm", "dy_mm", "dz_mm", "nl_dx_mm", "nl_dy_mm", "nl_dz_mm"];
    for row in crate::common::csv_columns(&assembled, &names) {
        for (k, v) in row.iter().enumerate() {
            let expected = if k % 3 == 0 { 1.0 } else { 0.0 };
            assert!((v - expected).abs() < 1e-9, "{}: {v}", names[k]);
        }
    }

    let mapped = crate::common::csv_columns(&run(&["map"]), &["x_mm", "y_mm", "z_mm", "c_tran_max_mm_per_N"]);
    let swept = run(&["sweep", "--vary", "k2=4129256136:4129256136:1"]);
    let summary = crate::common::csv_columns(&swept, &["max_c_tran_max_mm_per_N", "worst_x_mm", "worst_y_mm"]);
    let worst = mapped.iter().max_by(|a, b| a[3].total_cmp(&b[3])).unwrap();
    assert_eq!(summary[0], vec![worst[3], worst[0], worst[1]], "{swept}");
}

/// A map given joint coordinates answers the arm where they put it without placing it again (inverse
/// kinematics would start, and stay, at the configuration given): its unloaded compliance is the one the
/// arm placed at the pose they reach gives, to the bit, and its sag under its own weight (Newton's method
/// from the same rest) the same to round-off, at 50 random configurations of the FANUC.
#[test]
fn an_arm_at_joint_coordinates_answers_as_the_arm_placed_at_their_pose() {
    use stiff::model::grid::PosePoint;
    use stiff::study::{point, warm_start::LoadedHistory};
    let m = fanuc();
    let mut r = rng(71);
    let mut compared = 0;
    for _ in 0..50 {
        let t = random_angles(&mut r);
        let given = PosePoint {
            name: None,
            position: Vec3::zeros(),
            rotation: Vec3::zeros(),
            wrench: None,
            joints: t.to_vec(),
        };
        let (mut a, mut b) = (m.new_state(), m.new_state());
        let placed = point::pose_of_joints(&m, &given, &mut a).expect("a finite pose").into_owned();
        point::pose_of_joints(&m, &given, &mut b).unwrap();
        let at_joints = point::unloaded_at_joints(&m, &placed, &mut a);
        let at_pose = point::unloaded_point(&m, &placed, &mut b);
        assert_eq!(at_joints.status, at_pose.status, "unloaded at {t:?}");
        assert_eq!(at_joints.condition, at_pose.condition, "unloaded at {t:?}");
        assert_eq!(at_joints.compliance, at_pose.compliance, "unloaded at {t:?}");

        point::pose_of_joints(&m, &given, &mut a).unwrap();
        point::pose_of_joints(&m, &given, &mut b).unwrap();
        let zero = Vec6::zeros();
        let history = &mut LoadedHistory::default();
        let sag_joints = point::loaded_at_joints(&m, &placed, &zero, &mut a, history);
        let sag_pose = point::loaded_point(&m, &placed, &zero, &mut b, history);
        assert_eq!(sag_joints.status, sag_pose.status, "sag at {t:?}");
        let (d1, d0) = (sag_joints.deflection.unwrap(), sag_pose.deflection.unwrap());
        assert!(d0.fixed_rows::<3>(0).norm() > 0.1, "the arm sags: {d0}");
        assert!((d1 - d0).norm() <= 1e-12 * d0.norm(), "sag at {t:?}: {d1} vs {d0}");
        if let (Some(c1), Some(c0)) = (sag_joints.compliance, sag_pose.compliance) {
            assert!((c1 - c0).norm() <= 1e-12 * c0.norm(), "tangent compliance at {t:?}");
            compared += 1;
        }
    }
    assert!(compared >= 40, "{compared} tangents compared");
}

/// A 6-dof spring at a named link (`[leg.urdf] links`): a link that bends, in the link's frame. With a
/// compliance C_L at the root link (the base's mounting) and a stiffness K_L at link_3 (the upper arm), the
/// compliance at the tool point is Salisbury's plus, per link, A C_L A^T with A the motion of the tool by
/// the link frame's deflection (v = R t + (R phi) x (p - o), w = R phi; o, R the link frame from the DH
/// table: link i's frame is DH frame i), computed here, at 30 random configurations (1e-10 relative). A link
/// off the chain is a located error naming the chain's links.
#[test]
fn a_six_dof_spring_at_a_named_link_adds_its_compliance_through_the_links_frame() {
    let mut r = rng(48);
    let (k_base, k_arm) = (crate::common::random_spring(&mut r) * 10.0, crate::common::random_spring(&mut r) * 10.0);
    let c_base = k_base.try_inverse().unwrap();
    let rows = |m: &Mat6| {
        let rows: Vec<String> = (0..6)
            .map(|i| format!("[{}]", (0..6).map(|j| format!("{:?}", m[(i, j)])).collect::<Vec<_>>().join(", ")))
            .collect();
        format!("[{}]", rows.join(", "))
    };
    let links = format!(
        "links = {{ base_link = {{ compliance_matrix = {} }}, link_3 = {{ stiffness_matrix = {} }} }}\ncontroller = {{",
        rows(&c_base),
        rows(&k_arm)
    );
    let dir = tempfile::tempdir().unwrap();
    let (_, m) = fanuc_changed(dir.path(), |t| t.replace("controller = {", &links));
    let k_inv = Matrix6::from_diagonal(&Vec6::from_iterator(K_JOINT.iter().map(|k| 1.0 / k)));
    // The tool's motion by a deflection (t, phi) of a spring at frame (R, o).
    let motion = |frame: &nalgebra::Matrix4<f64>, tool: &Vec3| -> Mat6 {
        let rot = frame.fixed_view::<3, 3>(0, 0).into_owned();
        let o = Vec3::new(frame[(0, 3)], frame[(1, 3)], frame[(2, 3)]);
        let mut a = Mat6::zeros();
        a.fixed_view_mut::<3, 3>(0, 0).copy_from(&rot);
        a.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-(tool - o).cross_matrix() * rot));
        a.fixed_view_mut::<3, 3>(3, 3).copy_from(&rot);
        a
    };
    for _ in 0..30 {
        let t = random_angles(&mut r);
        let q = model_angles(&t);
        let (tool, frames) = dh_kinematics(&q);
        let j = dh_jacobian(&q);
        let (a_base, a_arm) = (motion(&nalgebra::Matrix4::identity(), &tool), motion(&frames[2], &tool));
        let expected = j * k_inv * j.transpose()
            + a_base * c_base * a_base.transpose()
            + a_arm * k_arm.try_inverse().unwrap() * a_arm.transpose();
        let (_, stiffness) = stiffness_at(&m, &t);
        assert_compliance_close(&stiffness.try_inverse().unwrap(), &expected, &format!("{t:?}"));
    }
    let (path, _) = fanuc_changed(dir.path(), |t| t.replace("controller = {", &links));
    let text = std::fs::read_to_string(&path).unwrap().replace("link_3 = {", "forearm = {");
    std::fs::write(&path, text).unwrap();
    let e = stiff::model::load_manipulator(&path).unwrap_err().to_string();
    assert!(e.contains("link `forearm` in `links` is not on the chain") && e.contains("link_3"), "{e}");
}

/// `[[joint_correction]] frame_compliance` (what a calibration's frame-compliance writes) is a spring at the
/// frame leading to the joint, before its motion: about that frame's z (the joint's axis) it is the joint's
/// own compliance (the same compliance matrix as `compliance =` on the joint, 1e-10); along its x and about
/// its y it adds A C A^T with A the tool's motion by that frame's deflection, the frame from the DH table
/// (frame i turned back by the joint's angle, R_i Rz(-q_i), at o_i), at 30 random configurations. A
/// negative compliance is a located error.
#[test]
fn a_frame_compliance_is_a_spring_at_the_frame_leading_to_the_joint() {
    let dir = tempfile::tempdir().unwrap();
    let c = 3e-10;
    let with =
        |table: &str| fanuc_changed(dir.path(), |t| format!("{t}\n[[joint_correction]]\njoint = \"J3\"\n{table}\n")).1;
    let (about_axis, joint) =
        (with(&format!("frame_compliance = [0, 0, 0, 0, 0, {c:e}]")), with(&format!("compliance = {c:e}")));
    let along = with("frame_compliance = [2e-4, 0, 0, 0, 5e-10, 0]");
    let k_inv = Matrix6::from_diagonal(&Vec6::from_iterator(K_JOINT.iter().map(|k| 1.0 / k)));
    let mut r = rng(49);
    for _ in 0..30 {
        let t = random_angles(&mut r);
        let q = model_angles(&t);
        let compliance = |m: &Manipulator| stiffness_at(m, &t).1.try_inverse().unwrap();
        assert_compliance_close(&compliance(&about_axis), &compliance(&joint), &format!("{t:?}"));
        let (tool, frames) = dh_kinematics(&q);
        let f = frames[2];
        let rot =
            f.fixed_view::<3, 3>(0, 0).into_owned() * nalgebra::Rotation3::from_axis_angle(&Vec3::z_axis(), -q[2]);
        let o = Vec3::new(f[(0, 3)], f[(1, 3)], f[(2, 3)]);
        let mut a = Mat6::zeros();
        a.fixed_view_mut::<3, 3>(0, 0).copy_from(&rot);
        a.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-(tool - o).cross_matrix() * rot));
        a.fixed_view_mut::<3, 3>(3, 3).copy_from(&rot);
        let local = Matrix6::from_diagonal(&Vec6::new(2e-4, 0.0, 0.0, 0.0, 5e-10, 0.0));
        let j = dh_jacobian(&q);
        let expected = j * k_inv * j.transpose() + a * local * a.transpose();
        assert_compliance_close(&compliance(&along), &expected, &format!("{t:?}"));
    }
    let (path, _) = fanuc_changed(dir.path(), |t| t);
    let text = std::fs::read_to_string(&path).unwrap()
        + "\n[[joint_correction]]\njoint = \"J3\"\nframe_compliance = [0, -1e-4, 0, 0, 0, 0]\n";
    std::fs::write(&path, text).unwrap();
    let e = stiff::model::load_manipulator(&path).unwrap_err().to_string();
    assert!(e.contains("joint `J3`: its frame compliance") && e.contains("line"), "{e}");
}
