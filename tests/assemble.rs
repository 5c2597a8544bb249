//! `stiff assemble` (paper 000 s. 4.2-4.3): Tables 3 and 4, loads that sum to zero, linear against
//! non-linear assembly, parameter errors against the equivalent base error, MSA legs against VJM legs.

use std::path::Path;
use stiff::kinematics::frame::{Frame, Vec3, Vec6};
use stiff::model::assembly_errors::ErrorSet;
use stiff::model::grid::PosePoint;
use stiff::platform::manipulator::Manipulator;
use stiff::study::assemble::{assemble_point, place_with_errors, AssembleOptions, Assembled};

const VJM: &str = "manipulators/orthoglide-3puu.toml";
const CASE_A: &str = "manipulators/errors/orthoglide-case-a.toml";
const CASE_B: &str = "manipulators/errors/orthoglide-case-b.toml";

/// Paper 000's labels (tests/reference/README.md): Q1 = +126.35, Q2 = -73.65.
const POINTS: [(&str, [f64; 3]); 5] = [
    ("Q0", [0.0, 0.0, 0.0]),
    ("Q1", [126.35, 126.35, 126.35]),
    ("Q2", [-73.65, -73.65, -73.65]),
    ("Q3", [126.35, 126.35, -73.65]),
    ("Q4", [-73.65, -73.65, 126.35]),
];

fn load(model: &str) -> Manipulator {
    stiff::model::load_manipulator(Path::new(model)).unwrap()
}

fn point(at: [f64; 3]) -> PosePoint {
    PosePoint { name: None, position: Vec3::from(at), rotation: Vec3::zeros(), wrench: None, joints: Vec::new() }
}

fn assemble(model: &str, errors: &str, at: [f64; 3], scale: f64, wrench: Option<Vec6>) -> Assembled {
    let m = load(model);
    let set = ErrorSet::load(Path::new(errors), Path::new(model), &m).unwrap();
    let perturbed = set.perturbed_legs(scale).unwrap();
    let o = AssembleOptions { wrench, scale, samples: 0, seed: 0, selection: None };
    assemble_point(&m, &set, &perturbed, &point(at), &o, &mut m.new_state()).unwrap()
}

/// Table 4 (Case A, 1 mm actuator offsets) to its printed digits: the platform shift, zero internal loads,
/// and the largest passive-joint change in degrees.
#[test]
fn table_4_case_a() {
    let table = [
        ([1.00, 1.00, 1.00], 0.18),
        ([0.50, 0.50, 0.50], 0.14),
        ([2.02, 2.02, 2.02], 0.42),
        ([0.73, 0.73, 0.27], 0.20),
        ([0.56, 0.56, 1.28], 0.26),
    ];
    for ((name, at), (d, dq)) in POINTS.iter().zip(table) {
        let a = assemble(VJM, CASE_A, *at, 1.0, None);
        for (k, published) in d.iter().enumerate() {
            assert!((a.displacement[k] - published).abs() <= 0.005, "{name}: {} vs {published}", a.displacement);
        }
        assert!(a.displacement.fixed_rows::<3>(3).norm() < 1e-12, "{name}: no rotation");
        for l in &a.loads {
            assert!(l.norm() < 1e-8, "{name}: internal load {l}");
        }
        let j = a.joints.unwrap();
        assert!(
            (j.passive_max.to_degrees() - dq).abs() <= 0.005,
            "{name}: dq_max {} vs {dq}",
            j.passive_max.to_degrees()
        );
        assert!(j.spring_torque_max < 1e-6 && j.spring_rotation_max < 1e-12);
    }
}

/// Table 3 (Case B): the end-point errors of a 1 degree rotation of each actuator about its own axis (the
/// line inferred in tests/reference/README.md), through each chain's kinematics, all 15 rows within 0.02 mm,
/// rotations 1 degree about the chain's axis.
#[test]
fn table_3_case_b_end_point_errors() {
    let text = std::fs::read_to_string("tests/reference/paper000-table3-case-b-eps.csv").unwrap();
    let m = load(VJM);
    let set = ErrorSet::load(Path::new(CASE_B), Path::new(VJM), &m).unwrap();
    let perturbed = set.perturbed_legs(1.0).unwrap();
    let mut rows = 0;
    for line in text.lines().filter(|l| !l.starts_with('#')).skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let at = POINTS.iter().find(|(n, _)| *n == f[0]).unwrap().1;
        let chain: usize = f[1].parse().unwrap();
        let v: Vec<f64> = f[2..8].iter().map(|x| x.parse().unwrap()).collect();
        let mut state = m.new_state();
        let placed =
            place_with_errors(&m, &set, &perturbed, &Frame::translation(Vec3::from(at)), 1.0, &mut state).unwrap();
        let eps = placed.errors[chain - 1].total();
        for k in 0..3 {
            assert!((eps[k] - v[k]).abs() <= 0.02, "{line}: {eps}");
            assert!((eps[3 + k].to_degrees() - v[3 + k]).abs() < 1e-9, "{line}: {eps}");
        }
        rows += 1;
    }
    assert_eq!(rows, 15);
}

/// Internal loads sum to zero (no external wrench after assembly, eq 63), here where they are large: Case
/// B on the parallelogram robot, whose legs over-constrain the platform.
#[test]
fn internal_loads_sum_to_zero() {
    for (_, at) in POINTS {
        let a = assemble("manipulators/orthoglide-3prpar.toml", CASE_B, at, 1.0, None);
        let sum: Vec6 = a.loads.iter().sum();
        let largest = a.loads.iter().map(weigh).fold(0.0, f64::max);
        assert!(largest > 1.0, "Case B loads the 3-PRPaR: {largest}");
        assert!(weigh(&sum) < 1e-9 * largest, "sum {sum}");
    }
}

fn weigh(w: &Vec6) -> f64 {
    // Forces in N, moments in N mm over 300 mm.
    (w.fixed_rows::<3>(0).norm_squared() + (w.fixed_rows::<3>(3) / 300.0).norm_squared()).sqrt()
}

/// The linear assembly (eq 60) is the first-order part of the non-linear one (eq 71): halving the errors
/// quarters their difference.
#[test]
fn linear_and_nonlinear_assembly_agree_to_second_order() {
    for (model, errors) in [(VJM, CASE_B), ("manipulators/orthoglide-3prpar.toml", CASE_B), (VJM, CASE_A)] {
        let gap = |s: f64| {
            let a = assemble(model, errors, [40.0, -20.0, 30.0], s, None);
            weigh(&(a.nonlinear.unwrap() - a.displacement))
        };
        let (g1, g2, g4) = (gap(0.4), gap(0.2), gap(0.1));
        for (a, b) in [(g1, g2), (g2, g4)] {
            let ratio = a / b;
            assert!((ratio - 4.0).abs() < 0.4, "{model} {errors}: gaps {g1} {g2} {g4}");
        }
    }
}

/// A parameter error goes through the leg's own kinematics: a model with an extra base offset parameter,
/// changed by 1 mm, gives the same end errors, assembly and non-linear assembly as Case A's base translation.
#[test]
fn parameter_errors_equal_the_equivalent_base_error() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(VJM).unwrap();
    let text = text.replace("t_z = -0.4", "t_z = -0.4\noff_x = 0").replace(
        "chain = [\n",
        "chain = [\n  { type = \"fixed\", name = \"offset\", translation = [\"off_x\", 0, 0] },\n",
    );
    let model = dir.path().join("offset.toml");
    std::fs::write(&model, text).unwrap();
    let errors = dir.path().join("off.toml");
    std::fs::write(&errors, "[[leg]]\nname = \"*\"\nparameters = { off_x = 1 }\n").unwrap();
    let model = model.to_str().unwrap();
    for (_, at) in POINTS {
        let a = assemble(model, errors.to_str().unwrap(), at, 1.0, None);
        let b = assemble(VJM, CASE_A, at, 1.0, None);
        // Within the inverse kinematics' tolerance (the two models place their legs independently).
        assert!((a.displacement - b.displacement).norm() < 1e-6, "{} vs {}", a.displacement, b.displacement);
        assert!((a.nonlinear.unwrap() - b.nonlinear.unwrap()).norm() < 1e-6);
    }
}

/// The same assembly on the 3-PUU written by MSA (base errors move an MSA leg rigidly): the linear
/// displacement equals the VJM model's to 1e-8; MSA legs are linear, so their non-linear assembly departs
/// from the linear one only through the composition of finite rotations (second order: 0.3-0.6% with Case
/// B's 1 degree, under 0.1% at a tenth of it).
#[test]
fn msa_legs_assemble_like_vjm_legs() {
    let msa = "manipulators/orthoglide-3puu-msa.toml";
    for (_, at) in POINTS {
        let a = assemble(msa, CASE_B, at, 1.0, None);
        let b = assemble(VJM, CASE_B, at, 1.0, None);
        assert!(
            weigh(&(a.displacement - b.displacement)) < 1e-8 * weigh(&b.displacement),
            "{} vs {}",
            a.displacement,
            b.displacement
        );
        assert!(a.joints.is_none());
        let small = assemble(msa, CASE_B, at, 0.1, None);
        assert!(weigh(&(small.nonlinear.unwrap() - small.displacement)) < 1e-3 * weigh(&small.displacement));
    }
}

/// With the milling wrench (paper 000 s. 5.2): the total is the loaded equilibrium of the legs with
/// errors; superposition (load alone + assembly alone) is close to it, the gap of second order.
#[test]
fn superposition_of_load_and_assembly_errors() {
    let w = Vec6::new(215.0, -10.0, -25.0, 1000.0, 21500.0, 0.0);
    let a = assemble(VJM, CASE_A, [-73.65, 26.35, -73.65], 1.0, Some(w));
    let (load, total, sup) = a.loaded.unwrap();
    assert!(load.fixed_rows::<3>(0).norm() > 0.2, "the cut deflects the tool: {load}");
    let gap = (total - sup).fixed_rows::<3>(0).norm();
    assert!(gap < 0.05 * total.fixed_rows::<3>(0).norm(), "superposition within 5%: gap {gap}");
    assert!(gap > 1e-6, "but not exact (the errors change the geometry the load acts on)");
}
