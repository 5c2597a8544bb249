//! The Orthoglide 3-PUU against paper 001 Table 1 (unloaded), paper 000 Table 4 (assembly, Case A), the
//! closed-form kinematics of tests/reference/README.md, and invariances of the model.

use crate::common;
use common::*;
use rand::Rng;
use stiff::kinematics::frame::{block_rotation, Frame, Mat3, Mat6, Vec3, Vec6};
use stiff::model::grid::PosePoint;
use stiff::platform::assembly::linear_assembly;
use stiff::platform::leg::{Leg, LegResponse};
use stiff::platform::manipulator::Manipulator;
use stiff::study::point::{unloaded_point, Status};

fn compliance_at(m: &Manipulator, p: Vec3) -> Mat6 {
    let point = PosePoint { name: None, position: p, rotation: Vec3::zeros(), wrench: None, joints: Vec::new() };
    let r = unloaded_point(m, &point, &mut m.new_state());
    assert_eq!(r.status, Status::Ok);
    r.compliance.unwrap()
}

fn stiffness_at(m: &Manipulator, pose: &Frame) -> Mat6 {
    m.unloaded(pose, &mut m.new_state()).unwrap().stiffness
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// Paper 001 Table 1 prints k_tran = 2.78e-4 mm/N and k_rot = 20.9e-7 rad/(N mm) at Q0, isotropic.
/// The link stiffness is set from beams with parameter set J of tests/reference/README.md (fitted there to
/// the unloaded rows of Tables 1 and 2); here it must reach Q0 within 1%.
#[test]
fn q0_matches_table_1_and_is_isotropic() {
    let c = compliance_at(&orthoglide(), Vec3::zeros());
    for i in 0..3 {
        assert!(rel(c[(i, i)], 2.78e-4) < 0.01, "C{}{} = {}", i + 1, i + 1, c[(i, i)]);
        assert!(rel(c[(i + 3, i + 3)], 20.9e-7) < 0.01, "C{}{} = {}", i + 4, i + 4, c[(i + 3, i + 3)]);
        assert!(rel(c[(i, i)], c[(0, 0)]) < 1e-9 && rel(c[(i + 3, i + 3)], c[(3, 3)]) < 1e-9);
    }
    for i in 0..3 {
        for j in 0..3 {
            if i != j {
                // Published as 0; ours 0.24% of the diagonal.
                assert!(c[(i, j)].abs() < 0.01 * c[(0, 0)]);
                assert!(c[(i + 3, j + 3)].abs() < 0.01 * c[(3, 3)]);
            }
        }
    }
}

/// Q1 and Q2 (paper 001 labels) are predictions, not fitted: reached within 2.0% (Q1 k_tran off-diagonal
/// 5.61 vs 5.5, the largest gap; the independent model of tests/reference/README.md reports 5.61 too). Pinned
/// at 2.5%.
#[test]
fn q1_q2_predictions_against_table_1() {
    let m = orthoglide();
    let published = [(-73.65, [10.9e-4, 5.5e-4, 24.1e-7, 7.5e-7]), (126.35, [71.3e-4, -35.0e-4, 25.8e-7, -7.4e-7])];
    for (x, [td, to, rd, ro]) in published {
        let c = compliance_at(&m, Vec3::new(x, x, x));
        let ours = [c[(0, 0)], c[(0, 1)], c[(3, 3)], c[(3, 4)]];
        for (o, p) in ours.iter().zip([td, to, rd, ro]) {
            assert!(rel(*o, p) < 0.025, "at {x}: {o:e} vs published {p:e}");
        }
        // The symmetric point keeps the published pattern: equal diagonals, equal off-diagonals.
        assert!(rel(c[(1, 1)], c[(0, 0)]) < 1e-9 && rel(c[(1, 2)], c[(0, 1)]) < 1e-9);
    }
}

/// The actuator-to-platform map through the engine's own Jacobians: every actuator shifted by 1 mm (paper
/// 000 Table 4, Case A), assembled by the linear scheme of paper 000 eq 57-65. The platform shift must match
/// the closed form dp = M^-1 (1,1,1), rows of M = e_i + t_i / n_i (tests/reference/README.md), and the printed
/// digits; no internal loads arise.
#[test]
fn case_a_assembly_reproduces_table_4() {
    let m = orthoglide();
    let l = 310.25;
    let table = [
        ([0.0, 0.0, 0.0], [1.00, 1.00, 1.00]),
        ([126.35, 126.35, 126.35], [0.50, 0.50, 0.50]),
        ([-73.65, -73.65, -73.65], [2.02, 2.02, 2.02]),
        ([126.35, 126.35, -73.65], [0.73, 0.73, 0.27]),
        ([-73.65, -73.65, 126.35], [0.56, 0.56, 1.28]),
    ];
    for (p, printed) in table {
        let pose = Frame::translation(Vec3::from(p));
        let mut state = m.new_state();
        let mut legs: Vec<LegResponse> = Vec::new();
        m.unloaded_each(&pose, &mut state, |_, r| legs.push(*r)).unwrap();
        let eps: Vec<Vec6> =
            m.legs.iter().zip(state.legs.iter_mut()).map(|(leg, s)| leg.actuator_twists(&pose, s)[0]).collect();
        let a = linear_assembly(&legs, &eps, m.length_scale).unwrap();
        // Closed form.
        let pv = Vec3::from(p);
        let mut mm = Mat3::zeros();
        for i in 0..3 {
            let e = Vec3::ith(i, 1.0);
            let t = pv - e * pv[i];
            let n = (l * l - t.norm_squared()).sqrt();
            mm.set_row(i, &(e + t / n).transpose());
        }
        let closed = mm.try_inverse().unwrap() * Vec3::new(1.0, 1.0, 1.0);
        for i in 0..3 {
            assert!(
                (a.displacement[i] - closed[i]).abs() < 1e-9,
                "{p:?}: {} vs closed form {}",
                a.displacement,
                closed
            );
            assert!(
                (a.displacement[i] - printed[i]).abs() <= 0.005 + 1e-12,
                "{p:?}: {} vs printed {printed:?}",
                a.displacement
            );
        }
        assert!(a.displacement.fixed_rows::<3>(3).norm() < 1e-12, "the platform must not turn");
        for w in &a.leg_wrenches {
            assert!(w.norm() < 1e-6, "Case A has no internal loads, got {w}");
        }
    }
}

/// Paper 000 eq (54)-(55): a leg that ends at its platform joint, attached there, gives the same stiffness
/// at the reference point as the same leg extended to the reference point by a rigid tool link.
#[test]
fn legs_attached_away_from_the_reference_point() {
    let text = std::fs::read_to_string("manipulators/orthoglide-3puu.toml").unwrap();
    let tool_line = text.lines().find(|l| l.contains("name = \"tool\"")).unwrap();
    let variant = text.replace(tool_line, "").replace(
        "name = \"chain\"\n",
        "name = \"chain\"\nattachment = { translation = [\"-t_x\", \"-t_y\", \"-t_z\"] }\n",
    );
    assert_ne!(variant, text);
    let moved = stiff::model::parse_manipulator(std::path::Path::new("variant.toml"), &variant).unwrap();
    let m = orthoglide();
    let mut r = rng(1);
    for _ in 0..20 {
        let p = Vec3::new(r.random_range(-70.0..120.0), r.random_range(-70.0..120.0), r.random_range(-70.0..120.0));
        let pose = Frame::translation(p);
        let (a, b) = (stiffness_at(&m, &pose), stiffness_at(&moved, &pose));
        assert!(scaled_rel_diff(&b, &a, 300.0) < 1e-9, "at {p}: {a}\n{b}");
    }
}

/// Moving the whole description rigidly (base and commanded pose alike) rotates the stiffness:
/// K' = diag(R, R) K diag(R, R)^T, and a pure translation leaves it unchanged.
#[test]
fn rigid_motion_of_the_whole_description() {
    let m = orthoglide();
    let mut r = rng(2);
    for _ in 0..10 {
        let t = random_frame(&mut r, 500.0);
        let mut moved = m.clone();
        for leg in moved.legs.iter_mut() {
            let Leg::Vjm(v) = leg else { panic!("a VJM leg") };
            v.chain = v.chain.prepended(t);
        }
        let p = Vec3::new(r.random_range(-60.0..60.0), r.random_range(-60.0..60.0), r.random_range(-60.0..60.0));
        let pose = Frame::translation(p);
        let k = stiffness_at(&m, &pose);
        let k_moved = stiffness_at(&moved, &t.compose(&pose));
        let b = block_rotation(&t.rot);
        assert!(scaled_rel_diff(&k_moved, &(b * k * b.transpose()), 300.0) < 1e-8);
    }
}

/// The 3-PRPaR (paper 001 Table 2), its parallelogram spring derived from the two bars. Its two
/// parallelogram numbers (bar diameter 7.50 mm, gap 270.8 mm) are fitted to Table 2 at Q0 by
/// scripts/fit-3prpar (with set J's 8.56 mm bars 196 mm apart Q0 lands at -1.43% / -0.69%), so Q0 is checked
/// within 0.1% as a regression; Q1 and Q2 are predictions: within 6.9% (largest gaps: Q2 k_rot off-diagonal
/// 1.219e-7 vs 1.14e-7, Q1 k_tran off-diagonal 6.15e-4 vs 5.80e-4), pinned at 7.5%. About ten times stiffer
/// in rotation than the 3-PUU, as the paper finds.
#[test]
fn prpar_against_table_2() {
    let m = stiff::model::load_manipulator(std::path::Path::new("manipulators/orthoglide-3prpar.toml")).unwrap();
    let published = [
        (0.0, [2.78e-4, 0.0, 1.94e-7, 0.0], 0.001),
        (-73.65, [9.86e-4, 5.80e-4, 2.06e-7, -0.32e-7], 0.075),
        (126.35, [21.2e-4, -10.2e-4, 2.65e-7, 1.14e-7], 0.075),
    ];
    for (x, [td, to, rd, ro], tol) in published {
        let c = compliance_at(&m, Vec3::new(x, x, x));
        assert!(rel(c[(0, 0)], td) < tol && rel(c[(3, 3)], rd) < tol, "at {x}: {:e} {:e}", c[(0, 0)], c[(3, 3)]);
        if to != 0.0 {
            assert!(rel(c[(0, 1)], to) < tol && rel(c[(3, 4)], ro) < tol, "at {x}: {:e} {:e}", c[(0, 1)], c[(3, 4)]);
        }
        assert!(rel(c[(1, 1)], c[(0, 0)]) < 1e-9 && rel(c[(4, 4)], c[(3, 3)]) < 1e-9);
    }
    let puu = compliance_at(&orthoglide(), Vec3::zeros());
    let prpar = compliance_at(&m, Vec3::zeros());
    assert!(puu[(3, 3)] / prpar[(3, 3)] > 9.0, "the parallelograms stiffen rotations about tenfold");
}
