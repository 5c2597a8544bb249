//! What a user reads off loaded results must be the loaded model's own numbers: the tangent stiffness is
//! not symmetric under a moment, so its compliance is its full inverse; the tangent stiffness is the
//! derivative of the equilibrium wrench (checked against central differences of equilibria under wrenches
//! with moments, and for the 3-PRPaR, whose parallelogram spring depends on the parallelogram angle).

use crate::common;
use std::path::Path;

use common::*;
use stiff::kinematics::frame::{skew, Frame, Mat3, Mat6, Vec3, Vec6};
use stiff::platform::manipulator::Manipulator;

/// Paper 000 s. 5.2's groove-milling wrench (N, N mm).
const MILLING: [f64; 6] = [215.0, -10.0, -25.0, 1000.0, 21500.0, 0.0];

fn load(path: &str) -> Manipulator {
    stiff::model::load_manipulator(Path::new(path)).unwrap()
}

/// The loaded equilibrium under `wrench` at `commanded` and, by central differences of the holding wrench
/// between equilibria at poses displaced from it (steps 1e-4 mm and 1e-7 rad), the tangent stiffness.
fn tangent_and_differences(m: &Manipulator, commanded: &Frame, wrench: &Vec6) -> (Mat6, Mat6) {
    let mut s = m.new_state();
    m.place(commanded, &mut s).unwrap();
    let d = m.deflect(commanded, wrench, None, &mut s).unwrap();
    (d.held.stiffness, held_differences(m, &mut s, &d.pose))
}

/// Under the milling wrench (a moment of 21.5 N m) the Orthoglide's tangent stiffness equals central
/// differences of the equilibria to 1e-6, and its antisymmetric part is not negligible.
#[test]
fn orthoglide_tangent_stiffness_under_the_milling_wrench_matches_differences() {
    let m = orthoglide();
    for x in [0.0, -73.65, 40.0] {
        let (k, fd) =
            tangent_and_differences(&m, &Frame::translation(Vec3::new(x, -0.5 * x, 0.3 * x)), &MILLING.into());
        assert!(scaled_rel_diff(&k, &fd, 300.0) < 1e-6, "at {x}: {k}\nvs differences\n{fd}");
        let antisymmetric = (k - k.transpose()).abs().max();
        assert!(antisymmetric > 1e-3 * k.abs().max() / 300.0, "the moment makes K non-symmetric");
    }
}

/// Stewart-Gough platform B under a wrench whose load terms are about 5% of the stiffness: tangent stiffness
/// against differences of equilibria to 1e-6.
#[test]
fn stewart_gough_b_tangent_stiffness_under_a_large_wrench_matches_differences() {
    let m = load("manipulators/stewart-gough-b.toml");
    let home = Frame::translation(Vec3::new(0.0, 0.0, 300.0));
    let wrench = Vec6::new(1.5e6, -1e6, -7.5e6, 1e8, -1.5e8, 5e7);
    let (k, fd) = tangent_and_differences(&m, &home, &wrench);
    let k0 = m.unloaded(&home, &mut m.new_state()).unwrap().stiffness;
    let load_share = scaled_rel_diff(&k, &k0, 300.0);
    assert!((0.02..0.2).contains(&load_share), "load terms are {load_share} of K");
    assert!(scaled_rel_diff(&k, &fd, 300.0) < 1e-6, "{k}\nvs differences\n{fd}");
}

/// Regression: the loaded compliance was a Cholesky inverse, which reads one triangle of a non-symmetric
/// K (|C K - I| up to 0.22). The written C must be K's inverse: C K = I to 1e-9 on every loaded row of a
/// map under the milling wrench, both read back from the CSV (36 entries each).
#[test]
fn loaded_map_writes_the_inverse_of_the_tangent_stiffness() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("loaded.csv");
    assert_cmd::Command::cargo_bin("stiff")
        .unwrap()
        .args(["map", "manipulators/orthoglide-3puu.toml", "--grid", "manipulators/grids/orthoglide-small.toml"])
        .args(["--wrench", "215,-10,-25,1000,21500,0", "--stiffness", "-q", "-o"])
        .arg(&out)
        .assert()
        .success();
    let text = std::fs::read_to_string(&out).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = |prefix: &str| header.iter().position(|h| h.starts_with(prefix)).unwrap_or_else(|| panic!("{prefix}"));
    let mut rows = 0;
    let mut worst_asymmetry = 0.0f64;
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f[column("status")], "ok");
        let matrix = |m: char| Mat6::from_fn(|i, j| f[column(&format!("{m}{}{}_", i + 1, j + 1))].parse().unwrap());
        let (c, k) = (matrix('C'), matrix('K'));
        // C K is dimensionless on its diagonal blocks, mm/rad and rad/mm off them: weigh by 300 mm.
        let d = Vec6::new(1.0, 1.0, 1.0, 300.0, 300.0, 300.0);
        let e = Mat6::from_fn(|i, j| ((c * k)[(i, j)] - if i == j { 1.0 } else { 0.0 }) * d[i] / d[j]);
        assert!(e.abs().max() < 1e-9, "|C K - I| = {:e} on {line}", e.abs().max());
        worst_asymmetry = worst_asymmetry.max((c - c.transpose()).abs().max() / c.abs().max());
        rows += 1;
    }
    assert_eq!(rows, 125);
    assert!(worst_asymmetry > 1e-4, "loaded C is not symmetric, and all 36 entries are written");
}

/// The antisymmetric part of the rotational block of the tangent stiffness under a pure moment M at the
/// reference point is -1/2 [M]x for base-frame rotation vectors (legs ending at the reference point carry
/// no [F]x[v]x term with no force): the moment's own geometric stiffness.
#[test]
fn antisymmetric_part_under_a_pure_moment_is_half_the_moment() {
    let m = orthoglide();
    let moment = Vec3::new(3000.0, -21500.0, 8000.0);
    let mut s = m.new_state();
    let at = Frame::translation(Vec3::new(10.0, -20.0, 5.0));
    m.place(&at, &mut s).unwrap();
    let d = m.deflect(&at, &Vec6::new(0.0, 0.0, 0.0, moment.x, moment.y, moment.z), None, &mut s).unwrap();
    let k = d.held.stiffness;
    let rot: Mat3 = k.fixed_view::<3, 3>(3, 3).into();
    let antisymmetric = (rot - rot.transpose()) * 0.5;
    let expected = -skew(&moment) * 0.5;
    assert!((antisymmetric - expected).abs().max() < 1e-6 * moment.norm(), "{antisymmetric}\nvs\n{expected}");
}

/// The 3-PRPaR's parallelogram spring depends on the parallelogram angle: with its derivative in the
/// Newton matrix the loaded stiffness is the derivative of the equilibrium wrench, at Q0, Q1 and Q2 of
/// paper 001 (platform displaced by 0.5 mm along each axis, as Table 2), to 1e-6.
#[test]
fn prpar_loaded_stiffness_matches_differences_with_the_posture_dependent_spring() {
    let m = load("manipulators/orthoglide-3prpar.toml");
    for x in [0.0, -73.65, 126.35] {
        let commanded = Frame::translation(Vec3::new(x, x, x));
        let actual = Frame::translation(Vec3::new(x + 0.5, x + 0.5, x + 0.5));
        let mut s = m.new_state();
        m.place(&commanded, &mut s).unwrap();
        let k = m.hold(&actual, &mut s).unwrap().stiffness;
        let fd = held_differences(&m, &mut s, &actual);
        assert!(scaled_rel_diff(&k, &fd, 300.0) < 1e-6, "at {x}: {k}\nvs differences\n{fd}");
    }
}

/// Paper 001 Table 1's loaded Q0 off-diagonal entries, read from the symmetric part of the full inverse
/// (the table prints symmetric blocks): k_tran -0.0105e-4 (published -0.02e-4), k_rot -0.0258e-7
/// (published -0.02e-7; the Cholesky inverse used to give -0.015e-7). The two triangles differ under
/// load: C45 = -0.058e-7, C54 = 0.007e-7.
#[test]
fn table_1_loaded_q0_off_diagonals_from_the_full_inverse() {
    let m = orthoglide();
    let mut s = m.new_state();
    m.place(&Frame::IDENTITY, &mut s).unwrap();
    let k = m.hold(&Frame::translation(Vec3::new(0.5, 0.5, 0.5)), &mut s).unwrap().stiffness;
    let c = k.try_inverse().unwrap();
    let sym = (c + c.transpose()) * 0.5;
    assert!((sym[(0, 1)] * 1e4 - -0.02).abs() < 0.011, "k_tran off {:e}", sym[(0, 1)]);
    assert!((sym[(3, 4)] * 1e7 - -0.02).abs() < 0.007, "k_rot off {:e}", sym[(3, 4)]);
    assert!((sym[(3, 4)] * 1e7 - -0.0258).abs() < 0.0005, "k_rot off {:e}", sym[(3, 4)]);
    assert!((c[(3, 4)] - c[(4, 3)]).abs() > 0.05e-7, "the loaded compliance is not symmetric");
}

/// Paper 001 Table 2's loaded rows and Table 3's forces for the 3-PRPaR (platform displaced by 0.5 mm along
/// each axis), predicted with the parallelogram spring's derivative in the equilibrium. Reached
/// (1e-4 mm/N, 1e-7 rad/(N mm); published in brackets): Q0 k_tran 2.729 (2.74), k_rot 1.880 (1.88);
/// Q1 k_tran 9.736 / 5.848 (9.55 / 5.52), k_rot 2.132 / -0.306 (2.05 / -0.31); Q2 k_tran 16.15 / -7.62
/// (16.7 / -7.9); F 1894 / 230 / 10637 N (1823 / 248 / 9418). Not reached: Q2 k_rot 2.01 / 0.90 (2.50 /
/// 1.28). In this model the parallelogram's two bars (7.5 mm, fitted at Q0 unloaded) buckle at Q2 between
/// 0.15 and 0.2 mm of that displacement (`stiff curve`): the Q2 row is an unstable equilibrium, so reported,
/// and its rotational compliance is off the paper's.
#[test]
fn prpar_table_2_loaded_rows_and_table_3_forces() {
    let m = load("manipulators/orthoglide-3prpar.toml");
    // (x, k_tran diag, off, tolerance; k_rot diag, off, tolerance; F, tolerance; legs stable)
    let rows = [
        (0.0, 2.74e-4, None, 0.01, 1.88e-7, None, 0.01, 1823.0, 0.05, true),
        (-73.65, 9.55e-4, Some(5.52e-4), 0.07, 2.05e-7, Some(-0.31e-7), 0.05, 248.0, 0.08, true),
        (126.35, 16.7e-4, Some(-7.9e-4), 0.04, 2.50e-7, Some(1.28e-7), 0.31, 9418.0, 0.14, false),
    ];
    for (x, td, to, ttol, rd, ro, rtol, f, ftol, stable) in rows {
        let mut s = m.new_state();
        m.place(&Frame::translation(Vec3::new(x, x, x)), &mut s).unwrap();
        let h = m.hold(&Frame::translation(Vec3::new(x + 0.5, x + 0.5, x + 0.5)), &mut s).unwrap();
        let c = h.stiffness.try_inverse().unwrap();
        let c = (c + c.transpose()) * 0.5;
        let rel = |a: f64, b: f64| (a - b).abs() / b.abs();
        assert!(rel(c[(0, 0)], td) < ttol, "{x}: k_tran {:e} vs {td:e}", c[(0, 0)]);
        assert!(rel(c[(3, 3)], rd) < rtol, "{x}: k_rot {:e} vs {rd:e}", c[(3, 3)]);
        if let Some(to) = to {
            assert!(rel(c[(0, 1)], to) < ttol, "{x}: k_tran off {:e} vs {to:e}", c[(0, 1)]);
        }
        if let Some(ro) = ro {
            assert!(rel(c[(3, 4)], ro) < rtol, "{x}: k_rot off {:e} vs {ro:e}", c[(3, 4)]);
        }
        assert!(rel(h.force[0], f) < ftol, "{x}: F {} vs {f}", h.force[0]);
        assert_eq!(h.legs_stable(), stable, "{x}");
    }
}

/// Regression: on the Orthoglide at (0, 0, 0) with a force along x and a large --max, `stable` was false
/// from step 1 while the eigenvalue column stayed positive, a Newton failure was called a limit point, the
/// load factor ran to 2.9 x --max, and stderr contradicted the CSV. Every flag must now follow from the
/// row's own columns: `stable` = (smallest scaled eigenvalue > 0 and no unstable leg), `instability` names
/// what failed, events mark changes between rows, no row goes beyond --max, and the stderr summary quotes
/// the rows.
#[test]
fn orthoglide_curve_flags_agree_with_their_columns() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("curve.csv");
    let max = 1e6;
    let run = assert_cmd::Command::cargo_bin("stiff")
        .unwrap()
        .args(["curve", "manipulators/orthoglide-3puu.toml", "--at", "0,0,0", "--wrench-direction", "1,0,0,0,0,0"])
        .args(["--max", "1e6", "--intervals", "50", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(run.status.success());
    let stderr = String::from_utf8(run.stderr).unwrap();
    assert!(!stderr.contains('{') && !stderr.contains("NotConverged"), "no debug text: {stderr}");
    let text = std::fs::read_to_string(&out).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let mut previous: Option<(bool, bool)> = None;
    for r in &rows {
        assert_eq!(r[col("status")], "ok");
        let load: f64 = r[col("load_factor")].parse().unwrap();
        assert!(load <= max, "a row beyond --max: {load}");
        let eigen: f64 = r[col("k_scaled_min_N_per_mm")].parse().unwrap();
        let instability = r[col("instability")];
        let legs_stable = !instability.contains("leg");
        let platform_pd = !instability.contains("platform");
        assert_eq!(platform_pd, eigen > 0.0, "row {}: platform flag vs eigenvalue {eigen}", r[0]);
        assert_eq!(r[col("stable")] == "true", platform_pd && legs_stable, "row {}", r[0]);
        let events = r[col("event")];
        if let Some((was_pd, was_legs)) = previous {
            assert_eq!(events.contains("buckling"), was_pd && !platform_pd, "row {}", r[0]);
            assert_eq!(events.contains("leg_unstable"), was_legs && !legs_stable, "row {}", r[0]);
        }
        assert!(!events.contains("limit_point") || r[col("control")] == "displacement" || load > 0.0);
        previous = Some((platform_pd, legs_stable));
    }
    // The summary on stderr is derived from the same rows.
    let first_unstable_leg = rows.iter().find(|r| r[col("instability")].contains("leg")).map(|r| r[0]);
    if let Some(step) = first_unstable_leg {
        assert!(stderr.contains(&format!("from step {step}, leg")), "{stderr}");
    }
    let last_load = rows.last().unwrap()[col("load_factor")];
    if rows.iter().all(|r| !r[col("instability")].contains("platform")) {
        assert!(stderr.contains(&format!("positive definite up to load factor {last_load}")), "{stderr}");
    }
}

/// Regression: a step that found no equilibrium aborted the curve with Rust debug text and lost every row
/// computed before it. Displacement control turning the platform by up to 6 rad (far beyond what the legs'
/// equilibria can follow: the 3-PUU's does not converge at 4.4 rad): the rows before the failure are
/// written, the failing row says `not_converged` with its residual, and the run succeeds.
#[test]
fn a_curve_that_stops_converging_keeps_its_rows() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("curve.csv");
    let run = assert_cmd::Command::cargo_bin("stiff")
        .unwrap()
        .args(["curve", "manipulators/orthoglide-3puu.toml", "--at", "0,0,0", "--displacement-direction"])
        .args(["0,0,0,0,0,1", "--max", "6", "--intervals", "30", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(run.status.success());
    let text = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<&str> = text.lines().skip(1).collect();
    let failed = rows.iter().position(|r| r.contains(",not_converged,")).expect("the legs cannot follow 6 rad");
    assert!(failed >= 10 && failed == rows.len() - 1, "rows before it kept, none after");
    assert!(rows[..failed].iter().all(|r| r.contains(",ok,")));
    let residual = rows[failed].split(',').nth(28).unwrap();
    assert!(residual.parse::<f64>().is_ok_and(|v| v > 0.0), "{}", rows[failed]);
    assert!(String::from_utf8(run.stderr).unwrap().contains("no equilibrium found"));
}

/// Regression: the loaded stiffness is the tangent at the equilibrium. Newton's method accepted a platform
/// step of up to 1e-8 of the length scale (9e-6 mm) and reported the stiffness linearised before it; the
/// pose's error is of the order of the step's square, but the stiffness's is of the order of the step
/// itself, and 628 of the 10,648 points of a 22^3 map under the milling wrench carried errors of 1e-9 to
/// 8e-8 (worst at the starts of the rows, whose warm starts are far). Along three rows of that map, each
/// point's stiffness, as the map writes it (the inverse of its compliance), must equal the one the legs give
/// when held, each solved to its own tolerance, at the pose where the platform settled: to 1e-10.
#[test]
fn a_loaded_map_reports_the_tangent_at_the_equilibrium() {
    use stiff::model::grid::PosePoint;
    use stiff::study::point::{loaded_point, LoadedHistory};
    let m = orthoglide();
    let (mut state, mut history) = (m.new_state(), LoadedHistory::default());
    let step = 120.0 / 21.0;
    let mut worst = 0.0f64;
    for y in [48.0 + 4.0 / 7.0, 54.0 + 2.0 / 7.0, 60.0] {
        for i in 0..22 {
            let p = PosePoint { position: Vec3::new(-60.0 + step * i as f64, y, -100.0 / 7.0), ..Default::default() };
            let r = loaded_point(&m, &p, &MILLING.into(), &mut state, &mut history);
            let compliance = r.compliance.expect("every point of these rows settles");
            let settled = stiff::kinematics::frame::apply_twist(&p.frame(), &r.deflection.unwrap());
            let held = m.hold(&settled, &mut state).unwrap().stiffness;
            worst = worst.max(scaled_rel_diff(&compliance.try_inverse().unwrap(), &held, 300.0));
        }
    }
    assert!(worst < 1e-10, "the stiffness written is {worst:e} (relative) from the tangent at the equilibrium");
}

/// Regression: a loaded map's answer at a pose depended on the order in which the run visited the poses.
/// The equilibrium under a load is a property of the commanded pose alone (a stable equilibrium on the
/// branch of the placement); but inverse kinematics stopped within its tolerance (1e-9 of the length scale,
/// about 1e-6 mm) of the pose, wherever its warm start put it, and the actuators it set carried that miss
/// into every loaded displacement: this row of ten points under the milling wrench, solved forward and
/// backward, moved by 1.5e-7 mm at its first point. Placements are now polished to round-off: both orders,
/// each point's displacement agrees to 1e-11 mm and 1e-12 rad, and its compliance to 1e-10 of its scale.
#[test]
fn a_loaded_answer_does_not_depend_on_the_order_the_poses_are_visited() {
    use stiff::model::grid::PosePoint;
    use stiff::study::point::{loaded_point, LoadedHistory, PointResult};
    let m = orthoglide();
    let row: Vec<PosePoint> = (0..10)
        .map(|i| PosePoint { position: Vec3::new(-60.0 + 120.0 / 9.0 * i as f64, -60.0, 0.0), ..Default::default() })
        .collect();
    let solve = |points: &mut dyn Iterator<Item = &PosePoint>| -> Vec<PointResult> {
        let (mut state, mut history) = (m.new_state(), LoadedHistory::default());
        points.map(|p| loaded_point(&m, p, &MILLING.into(), &mut state, &mut history)).collect()
    };
    let forward = solve(&mut row.iter());
    let mut backward = solve(&mut row.iter().rev());
    backward.reverse();
    for (k, (a, b)) in forward.iter().zip(&backward).enumerate() {
        assert_same_loaded_answer(a, b, &format!("point {k}"));
    }
}

/// Two loaded answers at one pose are the same equilibrium: displacements within 1e-11 mm and 1e-12 rad,
/// compliance within 1e-10 of its scale.
fn assert_same_loaded_answer(
    a: &stiff::study::point::PointResult,
    b: &stiff::study::point::PointResult,
    context: &str,
) {
    let gap = a.deflection.expect("the pose settles") - b.deflection.expect("the pose settles");
    let (translation, rotation) = (gap.fixed_rows::<3>(0).amax(), gap.fixed_rows::<3>(3).amax());
    assert!(translation < 1e-11 && rotation < 1e-12, "{context}: {translation:e} mm, {rotation:e} rad");
    let compliance = scaled_rel_diff(&a.compliance.unwrap(), &b.compliance.unwrap(), 300.0);
    assert!(compliance < 1e-10, "{context}: compliance {compliance:e} (relative)");
}

/// The first point of a grid's line starts with chord steps on the factorisations kept at the first point
/// of the line before (a neighbour, where the last solve's were made at the far end of that line): the
/// equilibrium it reaches is the pose's own. Four lines of five points under the milling wrench, solved in
/// order, each point against the same point solved cold (a fresh state, from its unloaded placement):
/// displacements within 1e-11 mm and 1e-12 rad, compliance within 1e-10 of its scale.
#[test]
fn a_line_started_on_the_line_befores_factorisations_reaches_the_same_equilibrium() {
    use stiff::model::grid::PosePoint;
    use stiff::study::point::{loaded_point, LoadedHistory};
    let m = orthoglide();
    let wrench: Vec6 = MILLING.into();
    let (mut state, mut history) = (m.new_state(), LoadedHistory::default());
    for line in 0..4 {
        for i in 0..5 {
            let position = Vec3::new(-60.0 + 30.0 * i as f64, -60.0 + 13.0 * line as f64, 10.0);
            let p = PosePoint { position, ..Default::default() };
            let run = loaded_point(&m, &p, &wrench, &mut state, &mut history);
            let cold = loaded_point(&m, &p, &wrench, &mut m.new_state(), &mut LoadedHistory::default());
            assert_same_loaded_answer(&run, &cold, &format!("line {line}, point {i}"));
        }
    }
}

/// How far `pose` is from the equilibrium `deflect` finds under `wrench` from the unloaded placement at
/// `commanded`, in a state of its own (no warm start): mm and rad.
fn gap_to_a_fresh_deflect(m: &Manipulator, commanded: &Frame, wrench: &Vec6, pose: &Frame) -> (f64, f64) {
    let mut fresh = m.new_state();
    m.place(commanded, &mut fresh).unwrap();
    let gap = m.deflect(commanded, wrench, None, &mut fresh).unwrap().pose.error_to(pose);
    (gap.fixed_rows::<3>(0).norm(), gap.fixed_rows::<3>(3).norm())
}

/// `settle` (the pose alone, ending on converged chord steps: compensation's evaluations) puts the platform
/// where `deflect` (ending on a full linearisation, the tangent at the equilibrium) does. Along a finely
/// sampled milling line under the milling wrench, each point settled from the run's extrapolated last
/// solutions as `stiff compensate` settles its commands, and compared with an independent `deflect` from
/// the unloaded placement at every point: the poses agree to 1e-10 mm and 1e-11 rad (found: 6e-12 mm,
/// 9e-13 rad), and most points settle in a single chord step, so that this is the path checked.
#[test]
fn a_settled_pose_is_the_deflected_pose() {
    use stiff::study::warm_start::LoadedHistory;
    let m = orthoglide();
    let wrench: Vec6 = MILLING.into();
    // Placements converged past inverse kinematics' usual tolerance (as a controller's are), so that both
    // solves see the same actuator coordinates: placed for a load, as compensation places its commands,
    // to round-off (a placement for a stiffness stops at 1e-14 of the length scale, noise in the
    // extrapolated loaded starts).
    let (mut s, mut history) = (m.new_state(), LoadedHistory::default());
    let (mut single_steps, points) = (0, 400);
    for k in 0..points {
        let commanded = Frame::translation(Vec3::new(-73.65, -73.65 + 0.005 * k as f64, -73.65));
        m.place_for_load(&commanded, &mut s).unwrap();
        let start = history.start(&commanded.pos, &commanded, &mut s.legs);
        let settled = m.settle(&commanded, &wrench, start.as_ref(), &mut s).unwrap();
        history.push(commanded.pos, settled.displacement, &s.legs);
        single_steps += usize::from(settled.iterations == 1);
        let (translation, rotation) = gap_to_a_fresh_deflect(&m, &commanded, &wrench, &settled.pose);
        assert!(translation < 1e-10 && rotation < 1e-11, "point {k}: {translation:e} mm, {rotation:e} rad");
    }
    assert!(single_steps > points * 3 / 4, "{single_steps} of {points} points settled in one chord step");
}

/// `settle_stable` (a compensation's check: the pose and the stability there, ending on a full step within
/// its tolerance) puts the platform where `deflect` does. Along the milling line of
/// `a_settled_pose_is_the_deflected_pose`, each point solved from the run's extrapolated last solutions and
/// compared with an independent `deflect` from the placement: the poses agree to 1e-10 mm and 1e-13 rad
/// (found: 7e-13 mm, 6e-16 rad), and every point is stable. (Ended at the manipulator's Newton tolerance,
/// 1e-8, the stability solve still passes here, at 2e-15 rad; it was the Case B robot of `stiff
/// compensate`, its legs strained by their errors, whose residual rotations moved by 1e-11 rad.)
#[test]
fn a_stability_solves_pose_is_the_deflected_pose() {
    use stiff::study::warm_start::LoadedHistory;
    let m = orthoglide();
    let wrench: Vec6 = MILLING.into();
    let (mut s, mut history) = (m.new_state(), LoadedHistory::default());
    let mut worst = (0.0f64, 0.0f64);
    for k in 0..200 {
        let commanded = Frame::translation(Vec3::new(-73.65, -73.65 + 0.01 * k as f64, -73.65));
        m.place_for_load(&commanded, &mut s).unwrap();
        let start = history.start(&commanded.pos, &commanded, &mut s.legs);
        let (settled, stable) = m.settle_stable(&commanded, &wrench, start.as_ref(), &mut s).unwrap();
        history.push(commanded.pos, settled.displacement, &s.legs);
        assert!(stable, "point {k}");
        let (translation, rotation) = gap_to_a_fresh_deflect(&m, &commanded, &wrench, &settled.pose);
        worst = (worst.0.max(translation), worst.1.max(rotation));
    }
    assert!(worst.0 < 1e-10 && worst.1 < 1e-13, "{:e} mm, {:e} rad", worst.0, worst.1);
}

/// Placements (a compensating controller's among them) are polished past inverse kinematics' tolerance (1e-9
/// of the leg's length scale, about 1e-6 mm) so that a command moved by less still moves the actuators as
/// their derivative says: moved by 1e-8 mm (Newton's command tolerance), every actuator of the 3-PUU moves
/// by its derivative (from a 1e-3 mm difference) times 1e-8 within 1%. Placed again at its own pose, a
/// polished placement is already there: no iteration, actuators unchanged to the bit.
#[test]
fn polished_placements_follow_commands_below_the_ik_tolerance() {
    let m = orthoglide();
    let mut s = m.new_state();
    let actuators = |s: &stiff::platform::manipulator::ManipulatorState| -> Vec<f64> {
        s.actuators().flat_map(|a| a.iter().copied()).collect()
    };
    let at = |dx: f64| Frame::translation(Vec3::new(-20.0 + dx, 15.0, -5.0));
    let place = |dx: f64, s: &mut stiff::platform::manipulator::ManipulatorState| -> Vec<usize> {
        (m.legs.iter().zip(s.legs.iter_mut()))
            .map(|(leg, state)| leg.place(&at(dx), state, stiff::kinematics::ik::Needs::Jacobians).unwrap())
            .collect()
    };
    place(1e-3, &mut s);
    let far = actuators(&s);
    place(0.0, &mut s);
    let base = actuators(&s);
    assert_eq!(place(0.0, &mut s), vec![0; m.legs.len()], "a polished placement placed again iterates");
    assert_eq!(actuators(&s), base, "a polished placement placed again moves");
    place(1e-8, &mut s);
    let near = actuators(&s);
    for k in 0..base.len() {
        let slope = (far[k] - base[k]) / 1e-3;
        let moved = (near[k] - base[k]) / 1e-8;
        assert!((moved - slope).abs() <= 1e-2 * slope.abs().max(1e-3), "actuator {k}: {moved} vs {slope} per mm");
    }
}

/// A compensation's commands are a smooth function of its path's targets but lie unequally spaced, so
/// that placed by their own poses each starts from the last placement, a path's step away (here 0.1 mm,
/// about 1e-4 of the leg's length scale: a Newton step, then a polishing step). Placed along the targets
/// (`place_along`), each leg starts from the cubic extrapolation through its last four placements as a
/// function of the target, within the tolerance: from the fifth command on, at most one polishing step.
/// Either way every leg lands on the same actuator coordinates (within 1e-11 mm: both polished to
/// round-off).
#[test]
fn commands_placed_along_their_targets_start_from_the_extrapolation() {
    use stiff::kinematics::ik::Needs;
    let m = orthoglide();
    let (mut along, mut own) = (m.new_state(), m.new_state());
    // The command's offset from its target: smooth, up to 0.3 mm, so that the commands' spacing varies.
    let offset = |y: f64| Vec3::new(0.3 * (y / 20.0).sin(), 0.2 * (y / 15.0).cos(), 0.1 * y / 200.0);
    let (mut steps_along, mut steps_own) = (Vec::new(), Vec::new());
    for k in 0..40 {
        let target = Frame::translation(Vec3::new(-73.65, -73.65 + 0.1 * k as f64, -73.65));
        let command = Frame::translation(target.pos + offset(target.pos.y));
        for (i, leg) in m.legs.iter().enumerate() {
            let n_along = leg.place_along(&command, Some(&target), &mut along.legs[i], Needs::Pose).unwrap();
            let n_own = leg.place(&command, &mut own.legs[i], Needs::Pose).unwrap();
            let (a, b) = (&along.legs[i].coords.actuated, &own.legs[i].coords.actuated);
            assert!((a[0] - b[0]).abs() < 1e-11, "command {k}, leg {i}: {} vs {} mm", a[0], b[0]);
            if k >= 4 {
                steps_along.push(n_along);
                steps_own.push(n_own);
            }
        }
    }
    assert!(steps_along.iter().all(|&n| n <= 1), "iterations along the targets: {steps_along:?}");
    assert!(steps_own.iter().all(|&n| n >= 2), "iterations by the commands' own poses: {steps_own:?}");
}
