//! `stiff compensate`: the command that puts the real robot (legs with errors, corrected springs, under the
//! process wrench) on the target, checked against closed forms, against an independent forward solve, on
//! paper 000 s. 5.2's milling path, and through the whole loop (synthesise, diagnose, correct, compensate).

use crate::common;
use common::{csv_columns, run_stiff};

use nalgebra::{Matrix2, Vector2};

const ORTHOGLIDE: &str = "manipulators/orthoglide-3puu.toml";
const SLIDER: &str = "tests/models/compensate-slider.toml";
const PLANAR: &str = "tests/models/compensate-planar.toml";
const PLANAR_ERRORS: &str = "tests/models/compensate-planar-errors.toml";
/// Paper 000 s. 5.2: milling from Q2 to Q5 (its labels; Figures 10-11 say Q4) under the cutting wrench.
const MILLING: [&str; 4] = ["--path", "-73.65,-73.65,-73.65", "-73.65,126.35,-73.65", "41"];
const CUTTING: &str = "215,-10,-25,1000,21500,0";
const COMMAND: [&str; 3] = ["command_x_mm", "command_y_mm", "command_z_mm"];
const TARGET: [&str; 3] = ["x_mm", "y_mm", "z_mm"];

fn statuses(text: &str) -> Vec<String> {
    let mut reader = csv::Reader::from_reader(text.as_bytes());
    let k = reader.headers().unwrap().iter().position(|h| h == "status").unwrap();
    reader.records().map(|r| r.unwrap()[k].to_string()).collect()
}

/// One slider with its actuator spring k_act in series with a mount spring (k_x, k_y, k_z) at the platform:
/// a force moves the platform by Fx (1/k_act + 1/k_x) along x, Fy/k_y and Fz/k_z across. The command that
/// reaches x_T is x_T - Fx (1/k_act + 1/k_x) (the mirror command already, the problem being linear); y and
/// z are not commanded, so their errors stay.
#[test]
fn a_slider_is_commanded_short_by_its_series_compliance() {
    let (k_act, k_x, k_y, k_z) = (2000.0, 5000.0, 3000.0, 4000.0);
    let (fx, fy, fz) = (300.0, -200.0, 50.0);
    let out =
        run_stiff(&["compensate", SLIDER, "--path", "-20,0,0", "30,0,0", "6", "--wrench", "300,-200,50,0,0,0", "-q"]);
    assert!(statuses(&out).iter().all(|s| s == "ok"), "{out}");
    let rows = csv_columns(
        &out,
        &[
            "x_mm",
            "command_x_mm",
            "leg1_actuator1_mm",
            "uncompensated_dx_mm",
            "residual_dx_mm",
            "residual_dy_mm",
            "residual_dz_mm",
            "iterations",
        ],
    );
    let shift = fx * (1.0 / k_act + 1.0 / k_x);
    for r in rows {
        assert!((r[3] - shift).abs() < 1e-12, "uncompensated {} vs {shift}", r[3]);
        assert!((r[1] - (r[0] - shift)).abs() < 1e-12, "command {} vs {}", r[1], r[0] - shift);
        // The actuator is the slider's travel from its base at -100 mm to the platform at the command.
        assert!((r[2] - r[1]).abs() < 1e-12, "actuator {} vs command {}", r[2], r[1]);
        assert!(r[4].abs() < 1e-8, "residual along the commanded axis {}", r[4]);
        assert!((r[5] - fy / k_y).abs() < 1e-12 && (r[6] - fz / k_z).abs() < 1e-12, "{r:?}");
        assert_eq!(r[7], 0.0, "a linear problem is solved by the mirror command");
    }
}

/// Two actuated sliders with axial springs k_i along u_i in the plane (a third leg holds z and the
/// rotations): the actuators set u_i . c (nominal inverse kinematics), a force F moves the platform by
/// K^-1 F, K = sum k_i u_i u_i^T, and leg a's base moved by 0.3 mm along u_1 moves it by d with u_1 . d = 0.3,
/// u_2 . d = 0. The command that reaches T is T - d - K^-1 F.
#[test]
fn a_planar_mechanism_is_commanded_against_its_offset_and_its_compliance() {
    let (k1, k2) = (1500.0, 4000.0);
    let u = |deg: f64| Vector2::new(deg.to_radians().cos(), deg.to_radians().sin());
    let (u1, u2) = (u(20.0), u(100.0));
    let k = u1 * u1.transpose() * k1 + u2 * u2.transpose() * k2;
    let f = Vector2::new(300.0, -200.0);
    let offset = Matrix2::from_rows(&[u1.transpose(), u2.transpose()]).try_inverse().unwrap() * Vector2::new(0.3, 0.0);
    let error = offset + k.try_inverse().unwrap() * f;
    let args = ["compensate", PLANAR, "--errors", PLANAR_ERRORS, "--path", "-20,-10,0", "30,15,0", "5"];
    let out = run_stiff(&[&args[..], &["--wrench", "300,-200,0,0,0,0", "-q"]].concat());
    assert!(statuses(&out).iter().all(|s| s == "ok"), "{out}");
    let names = [
        "x_mm",
        "y_mm",
        "command_x_mm",
        "command_y_mm",
        "leg1_actuator1_mm",
        "leg2_actuator1_mm",
        "uncompensated_dx_mm",
        "uncompensated_dy_mm",
        "residual_dx_mm",
        "residual_dy_mm",
        "residual_dz_mm",
    ];
    for r in csv_columns(&out, &names) {
        let (t, c) = (Vector2::new(r[0], r[1]), Vector2::new(r[2], r[3]));
        assert!((Vector2::new(r[6], r[7]) - error).norm() < 1e-11, "uncompensated {r:?} vs {error}");
        assert!((c - (t - error)).norm() < 1e-9, "command {c} vs {}", t - error);
        assert!((r[4] - u1.dot(&c)).abs() < 1e-9 && (r[5] - u2.dot(&c)).abs() < 1e-9, "{r:?}");
        assert!(Vector2::new(r[8], r[9]).norm() < 1e-8 && r[10].abs() < 1e-12, "residual {r:?}");
    }
}

/// With no load, no errors and no payload the real robot is the nominal one: the command is the target,
/// bit for bit, and the forward solve puts the platform there.
#[test]
fn zero_load_and_no_errors_command_the_target_exactly() {
    let out = run_stiff(&["compensate", ORTHOGLIDE, "--path", "-60,-60,-60", "60,60,60", "13", "-q"]);
    assert!(statuses(&out).iter().all(|s| s == "ok"), "{out}");
    let rows = csv_columns(&out, &[&TARGET[..], &COMMAND[..], &["residual_error_mm", "iterations"]].concat());
    assert!(rows.len() > 10);
    for r in rows {
        assert_eq!(&r[0..3], &r[3..6], "the command is the target");
        assert!(r[6] < 1e-10 && r[7] == 0.0, "{r:?}");
    }
}

/// The largest value of a column over the rows.
fn largest(text: &str, column: &str) -> f64 {
    csv_columns(text, &[column]).iter().map(|r| r[0]).fold(0.0, f64::max)
}

/// Paper 000 s. 5.2: along the milling path under the cutting wrench, with the actuators' 1 mm offsets
/// (Case A) or 1 degree turns (Case B), the robot misses the path by millimetres; Newton's command puts the
/// reference point on it within a micrometre (1e-6 mm) at every target, as the forward solve of the
/// command's actuator coordinates shows and, by another route, `stiff assemble` of the same legs with
/// errors at the commands under the same wrench (its total displacement from the command, eq 71 with the
/// load; within 2e-8 mm: both place the command to round-off, so what is left is the command's own residual,
/// within Newton's 1e-8 mm; found 9.9e-9 mm, where placements to inverse kinematics' tolerance, about 1e-6
/// mm, allowed 1e-5); the mirror command
/// leaves a residual between the two.
#[test]
fn the_milling_path_is_compensated_below_a_micrometre_in_cases_a_and_b() {
    let dir = tempfile::tempdir().unwrap();
    let commands_file = dir.path().join("commands.csv").display().to_string();
    for case in ["a", "b"] {
        let errors = format!("manipulators/errors/orthoglide-case-{case}.toml");
        let out = run_stiff(
            &[&["compensate", ORTHOGLIDE, "--errors", &errors][..], &MILLING, &["--wrench", CUTTING, "-q"]].concat(),
        );
        assert!(statuses(&out).iter().all(|s| s == "ok"), "case {case}: {out}");
        let (before, mirror, after) = (
            largest(&out, "uncompensated_error_mm"),
            largest(&out, "mirror_error_mm"),
            largest(&out, "residual_error_mm"),
        );
        eprintln!("case {case}: largest error {before:.4} mm uncompensated, {mirror:.3e} mirror, {after:.3e} Newton");
        assert!(before > 0.5, "case {case}: the errors are of paper 000's size ({before} mm)");
        assert!(after < 1e-6, "case {case}: Newton's residual {after} mm");
        assert!(mirror > 1e3 * after && mirror < before / 10.0, "case {case}: mirror {mirror} mm");
        let rows = csv_columns(&out, &[&TARGET[..], &COMMAND[..]].concat());
        let mut commands = String::from("x_mm,y_mm,z_mm\n");
        for r in &rows {
            commands.push_str(&format!("{},{},{}\n", r[3], r[4], r[5]));
        }
        std::fs::write(&commands_file, commands).unwrap();
        let assembled = run_stiff(&[
            "assemble",
            ORTHOGLIDE,
            "--errors",
            &errors,
            "--points",
            &commands_file,
            "--wrench",
            CUTTING,
            "-q",
        ]);
        let totals = csv_columns(&assembled, &["x_mm", "y_mm", "z_mm", "total_dx_mm", "total_dy_mm", "total_dz_mm"]);
        for (t, a) in rows.iter().zip(&totals) {
            let miss = (0..3).map(|k| (a[k] + a[3 + k] - t[k]).powi(2)).sum::<f64>().sqrt();
            assert!(miss < 2e-8, "case {case}: assemble puts the command {a:?} {miss} mm from the target {t:?}");
        }
    }
}

/// The mirror command c = T - e(T) misses by e(T - e) - e(T) ~ -(de/dc) e: both factors are proportional to
/// the errors, so halving every leg error divides the mirror's residual by about 4 (no load, so the errors
/// are the only source).
#[test]
fn the_mirror_residual_is_second_order_in_the_errors() {
    for case in ["a", "b"] {
        let errors = format!("manipulators/errors/orthoglide-case-{case}.toml");
        let residual = |scale: &str| {
            let out = run_stiff(
                &[
                    &["compensate", ORTHOGLIDE, "--errors", &errors, "--scale", scale, "--method", "mirror"][..],
                    &MILLING,
                    &["-q"],
                ]
                .concat(),
            );
            csv_columns(&out, &["residual_error_mm", "mirror_error_mm"])
        };
        let (full, half) = (residual("1"), residual("0.5"));
        for (f, h) in full.iter().zip(&half) {
            assert!((f[0] - f[1]).abs() <= 1e-8, "the forward solve confirms the mirror's residual: {f:?}");
            let ratio = f[0] / h[0];
            assert!((3.6..4.4).contains(&ratio), "case {case}: residual {} then {} (ratio {ratio})", f[0], h[0]);
        }
    }
}

/// Targets are solved in runs fixed by the input (warm starts and the Jacobian carried within a run), so
/// the bytes do not depend on the thread count; 600 targets span three runs.
#[test]
fn rows_do_not_depend_on_the_thread_count() {
    let args = [
        "compensate",
        ORTHOGLIDE,
        "--errors",
        "manipulators/errors/orthoglide-case-b.toml",
        "--path",
        "-73.65,-73.65,-73.65",
        "-73.65,126.35,-73.65",
        "600",
        "--wrench",
        CUTTING,
        "-q",
    ];
    let one = run_stiff(&[&args[..], &["--threads", "1"]].concat());
    let two = run_stiff(&[&args[..], &["--threads", "2"]].concat());
    assert_eq!(one, two);
}

/// Bad targets are rows with a status, never an abort: a path that leaves the Orthoglide's workspace midway
/// (x = 350 mm and beyond cannot be placed), where under the cutting wrench the target x = 300 mm can still
/// be commanded (the robot then misses it by tens of millimetres) but the command that would reach it lies
/// beyond the workspace; a target off the one axis a slider commands; and a load beyond the limit load,
/// where no equilibrium exists (about 12.8 kN along -z at Q0, where `stiff curve` finds the limit point).
#[test]
fn bad_targets_become_row_statuses() {
    let out = run_stiff(&["compensate", ORTHOGLIDE, "--path", "0,0,0", "400,0,0", "9", "-q"]);
    assert_eq!(statuses(&out), [&["ok"; 7][..], &["unreachable"; 2]].concat(), "{out}");
    let out = run_stiff(&["compensate", ORTHOGLIDE, "--path", "0,0,0", "400,0,0", "9", "--wrench", CUTTING, "-q"]);
    assert_eq!(statuses(&out), [&["ok"; 6][..], &["unreachable"; 3]].concat(), "{out}");
    let at_300 = &csv_columns(&out, &["uncompensated_error_mm", "command_x_mm"])[6];
    assert!(at_300[0] > 10.0 && at_300[1].is_nan(), "the target is commanded, its compensation is not: {at_300:?}");
    let out = run_stiff(&["compensate", SLIDER, "--path", "0,0,0", "0,10,0", "3", "-q"]);
    assert_eq!(statuses(&out), ["ok", "unreachable", "unreachable"], "{out}");
    let out =
        run_stiff(&["compensate", ORTHOGLIDE, "--path", "0,0,0", "10,0,0", "3", "--wrench", "0,0,-3e4,0,0,0", "-q"]);
    assert!(statuses(&out).iter().all(|s| s == "not_converged"), "{out}");
    let rows = csv_columns(&out, &["command_x_mm", "uncompensated_error_mm"]);
    assert!(rows.iter().all(|r| r[0].is_nan() && r[1].is_nan()), "nothing is written for a load with no equilibrium");
}

/// The loaded equilibria solved per target, from a run's summary line on stderr.
fn equilibria_per_target(summary: &str) -> f64 {
    let before = summary.split(" loaded equilibria per target").next().unwrap();
    before.rsplit(' ').next().unwrap().parse().unwrap()
}

/// `--commands-only` answers a target by the command extrapolated from the last targets where its forward
/// solve meets the tolerance with the robot stable: a controller's commands, not a cheaper approximation of
/// them. Along the milling path sampled every 0.1 mm with Case B errors under the cutting wrench, every
/// command meets the same 1e-8 mm tolerance as the full rows' (so the two commands differ by about that,
/// the robot's compliance Jacobian being near the identity), the actuators follow within that times their
/// ratio to the platform's motion, the forward solve's residual is below the tolerance, and the
/// uncompensated and mirror columns are empty at every target. The run solves about one loaded
/// equilibrium per target where the full rows take three (its summary line).
#[test]
fn commands_only_gives_the_full_rows_commands_from_one_equilibrium_per_target() {
    let path = ["--path", "-73.65,-73.65,-73.65", "-73.65,126.35,-73.65", "2001"];
    let args = [
        &["compensate", ORTHOGLIDE, "--errors", "manipulators/errors/orthoglide-case-b.toml"][..],
        &path,
        &["--wrench", CUTTING],
    ]
    .concat();
    let run = |extra: &[&str]| {
        let o = assert_cmd::Command::cargo_bin("stiff").unwrap().args(&args).args(extra).output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        (String::from_utf8(o.stdout).unwrap(), String::from_utf8(o.stderr).unwrap())
    };
    let (full, full_summary) = run(&[]);
    let (lean, lean_summary) = run(&["--commands-only"]);
    assert!(statuses(&full).iter().chain(&statuses(&lean)).all(|s| s == "ok"));
    let (full_equilibria, lean_equilibria) =
        (equilibria_per_target(&full_summary), equilibria_per_target(&lean_summary));
    assert!(full_equilibria >= 2.9, "{full_summary}");
    assert!(lean_equilibria < 1.05, "{lean_summary}");
    let actuators = ["leg1_actuator1_mm", "leg2_actuator1_mm", "leg3_actuator1_mm"];
    let columns =
        [&COMMAND[..], &actuators, &["residual_error_mm", "uncompensated_error_mm", "mirror_error_mm"]].concat();
    let (full, lean) = (csv_columns(&full, &columns), csv_columns(&lean, &columns));
    assert_eq!(full.len(), 2001);
    assert_eq!(full.len(), lean.len());
    for (k, (f, l)) in full.iter().zip(&lean).enumerate() {
        for c in 0..6 {
            assert!((f[c] - l[c]).abs() < 1e-7, "target {k}, {}: {} vs {}", columns[c], f[c], l[c]);
        }
        assert!(l[6] < 1e-8, "target {k}: residual {} mm", l[6]);
        assert!(f[7] > 0.5 && l[7].is_nan() && l[8].is_nan(), "target {k}: {f:?} {l:?}");
    }
}

/// The option changes which solves are made, not what a target's status says: along the path of
/// `bad_targets_become_row_statuses` that leaves the workspace (sampled every 0.4 mm, so that the targets
/// before the edge are answered by the extrapolated command alone, and the first target beyond it falls
/// back to the full procedure after them), with and without the cutting wrench, and under a load with no
/// equilibrium, the statuses are the full rows'. The bytes do not depend on the thread count. With --plot
/// (whose lines are the skipped errors) or --method mirror it is refused.
#[test]
fn commands_only_keeps_statuses_and_refuses_what_needs_the_mirror() {
    let fine = ["--path", "0,0,0", "400,0,0", "1001"];
    for (path, extra) in
        [(&fine, &[][..]), (&fine, &["--wrench", CUTTING]), (&MILLING, &["--wrench", "0,0,-3e4,0,0,0"])]
    {
        let args = [&["compensate", ORTHOGLIDE][..], path, extra].concat();
        let full = run_stiff(&[&args[..], &["-q"]].concat());
        let o = assert_cmd::Command::cargo_bin("stiff").unwrap().args(&args).arg("--commands-only").output().unwrap();
        let lean = String::from_utf8(o.stdout).unwrap();
        assert_eq!(statuses(&full), statuses(&lean), "{extra:?}");
        if extra.is_empty() {
            let summary = String::from_utf8(o.stderr).unwrap();
            assert!(statuses(&lean).iter().filter(|s| *s == "unreachable").count() > 100, "{summary}");
            assert!(equilibria_per_target(&summary) < 1.5, "mostly one equilibrium per target: {summary}");
        }
    }
    let args = [
        &["compensate", ORTHOGLIDE, "--errors", "manipulators/errors/orthoglide-case-a.toml"][..],
        &["--path", "-73.65,-73.65,-73.65", "-73.65,126.35,-73.65", "600", "--wrench", CUTTING, "--commands-only"],
        &["-q"],
    ]
    .concat();
    let one = run_stiff(&[&args[..], &["--threads", "1"]].concat());
    assert_eq!(one, run_stiff(&[&args[..], &["--threads", "2"]].concat()));
    let refused = |extra: &[&str]| {
        let o = assert_cmd::Command::cargo_bin("stiff").unwrap().args(&args).args(extra).output().unwrap();
        (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned())
    };
    let (code, message) = refused(&["--plot", "x.svg", "-o", "x.csv"]);
    assert_eq!(code, Some(2), "{message}");
    assert!(message.contains("--plot"), "{message}");
    let (code, message) = refused(&["--method", "mirror"]);
    assert_eq!(code, Some(1), "{message}");
    assert!(message.contains("--method mirror"), "{message}");
}

/// The whole loop, through the command line: measurements of a robot whose leg 2 actuator is 1.4 times
/// more compliant than the description says are diagnosed, the corrected description is written, and the
/// milling path is compensated once with the description and once with the corrected one. Both command
/// sets are then run on the hidden truth (the description with that actuator's compliance scaled, its
/// loaded map at the commands under the cutting wrench): where the robot's reference point lands, minus the
/// target, must be at least 10 times smaller with the corrected description's commands.
#[test]
fn a_description_corrected_by_diagnose_compensates_ten_times_better() {
    let dir = tempfile::tempdir().unwrap();
    let file = |name: &str| dir.path().join(name).display().to_string();
    let source = std::fs::read_to_string(ORTHOGLIDE).unwrap();
    std::fs::write(
        file("truth.toml"),
        format!("{source}\n[[effect]]\nname = \"actuator-compliance\"\ntarget = \"2\"\nvalues = [1.4]\n"),
    )
    .unwrap();
    let wrenches = "200,0,0,0,0,0;-200,0,0,0,0,0;0,200,0,0,0,0;0,-200,0,0,0,0;0,0,200,0,0,0;0,0,-200,0,0,0";
    run_stiff(&[
        "synth",
        ORTHOGLIDE,
        "--grid",
        "manipulators/grids/orthoglide-small.toml",
        "--effect",
        "actuator-compliance:2=1.4",
        "--wrenches",
        wrenches,
        "--noise",
        "0.001",
        "--seed",
        "5",
        "-q",
        "-o",
        &file("data.csv"),
    ]);
    let report =
        run_stiff(&["diagnose", ORTHOGLIDE, "--data", &file("data.csv"), "--model-out", &file("corrected.toml")]);
    assert!(report.contains("actuator-compliance:2"), "{report}");
    let landing_error = |model: &str| -> f64 {
        let commands = run_stiff(&[&["compensate", model][..], &MILLING, &["--wrench", CUTTING, "-q"]].concat());
        assert!(statuses(&commands).iter().all(|s| s == "ok"), "{commands}");
        let rows = csv_columns(&commands, &[&TARGET[..], &COMMAND[..]].concat());
        let mut points = String::from("x_mm,y_mm,z_mm,Fx_N,Fy_N,Fz_N,Mx_Nmm,My_Nmm,Mz_Nmm\n");
        for r in &rows {
            points.push_str(&format!("{},{},{},{CUTTING}\n", r[3], r[4], r[5]));
        }
        std::fs::write(file("commands.csv"), points).unwrap();
        let map = run_stiff(&["map", &file("truth.toml"), "--points", &file("commands.csv"), "--loaded", "-q"]);
        let reached = csv_columns(&map, &["x_mm", "y_mm", "z_mm", "dx_mm", "dy_mm", "dz_mm"]);
        rows.iter()
            .zip(&reached)
            .map(|(t, p)| {
                ((p[0] + p[3] - t[0]).powi(2) + (p[1] + p[4] - t[1]).powi(2) + (p[2] + p[5] - t[2]).powi(2)).sqrt()
            })
            .fold(0.0, f64::max)
    };
    let (nominal, corrected) = (landing_error(ORTHOGLIDE), landing_error(&file("corrected.toml")));
    eprintln!(
        "largest landing error on the truth: {nominal:.3e} mm with the description, {corrected:.3e} mm corrected"
    );
    assert!(corrected * 10.0 <= nominal, "{corrected} mm corrected vs {nominal} mm nominal");
}

/// The platform motions the actuators command, found two ways: from the legs' joint twists (screw theory:
/// the twists every leg's joints can follow, `Manipulator::commanded_directions`) and as K^-1 K_i u from the
/// legs' stiffnesses (`actuator_motions`). At random poses of the 3-PUU and the 3-PRPaR (three
/// translations) and of Stewart-Gough B (all six directions) they span the same directions: every motion,
/// weighted, lies in the basis' span to 1e-9 of its size, and the dimensions agree. Stewart-Gough A, whose
/// six leg lines meet in one point (the platform turns about it with the actuators locked), is singular
/// both ways.
#[test]
fn the_directions_from_joint_twists_span_the_actuator_motions() {
    use rand::Rng;
    use stiff::kinematics::frame::{rotation_from_vector, weigh_rotations, Frame, Vec3};
    use stiff::platform::command::Directions;
    let mut r = common::rng(19);
    let load = |path: &str| stiff::model::load_manipulator(std::path::Path::new(path)).unwrap();
    let models = [
        (ORTHOGLIDE, 3, 0.0),
        ("manipulators/orthoglide-3prpar.toml", 3, 0.0),
        ("manipulators/stewart-gough-b.toml", 6, 300.0),
    ];
    for (path, dimension, height) in models {
        let m = load(path);
        for _ in 0..20 {
            let pose = if height > 0.0 {
                let turn = Vec3::from_fn(|_, _| r.random_range(-0.1..0.1));
                Frame::new(
                    rotation_from_vector(&turn),
                    Vec3::new(r.random_range(-20.0..20.0), r.random_range(-20.0..20.0), height),
                )
            } else {
                Frame::translation(Vec3::from_fn(|_, _| r.random_range(-70.0..120.0)))
            };
            let Directions::Span(basis) = m.commanded_directions(&pose, &mut m.new_state()).unwrap() else {
                panic!("{path} at {pose:?}: no directions")
            };
            assert_eq!(basis.len(), dimension, "{path}");
            let motions = m.actuator_motions(&pose, &mut m.new_state()).unwrap().unwrap();
            for motion in motions {
                let w = weigh_rotations(&motion, m.length_scale);
                let rest = basis.iter().fold(w, |rest, q| rest - q * q.dot(&w));
                assert!(rest.norm() <= 1e-9 * w.norm(), "{path}: {:.2e} of {:.2e} outside", rest.norm(), w.norm());
            }
        }
    }
    let a = load("manipulators/stewart-gough-a.toml");
    let home = Frame::translation(Vec3::new(0.0, 0.0, 300.0));
    assert_eq!(a.commanded_directions(&home, &mut a.new_state()).unwrap(), Directions::Singular);
    assert!(a.actuator_motions(&home, &mut a.new_state()).unwrap().is_none());
}
