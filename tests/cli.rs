//! The `stiff` command from the outside: golden output, thread independence, streaming edge cases and
//! refusal of bad input (clear message, non-zero exit, no output left behind).

use std::path::{Path, PathBuf};

use assert_cmd::Command;
use clap::CommandFactory;

const MODEL: &str = "manipulators/orthoglide-3puu.toml";

fn stiff() -> Command {
    Command::cargo_bin("stiff").unwrap()
}

fn temp_dir() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(String::from).collect();
    (header, lines.map(|l| l.split(',').map(String::from).collect()).collect())
}

#[test]
fn command_line_definition_is_consistent() {
    stiff::cli::Cli::command().debug_assert();
}

/// Regression guard for a small grid, established after the closed-form and Table 1 tests pass
/// (scripts/regenerate-golden): every number within 1e-9 relative of the golden file.
#[test]
fn small_grid_matches_golden_file() {
    let dir = temp_dir();
    let out = dir.path().join("small.csv");
    stiff()
        .args(["map", MODEL, "--grid", "manipulators/grids/orthoglide-small.toml", "--stiffness", "-q", "-o"])
        .arg(&out)
        .assert()
        .success();
    let (h1, r1) = read_csv(&out);
    let (h0, r0) = read_csv(Path::new("tests/golden/orthoglide-3puu-small.csv"));
    assert_eq!(h1, h0);
    assert_eq!(r1.len(), 125);
    assert_eq!(r1.len(), r0.len());
    // Matrix entries are compared on the scale of their block, sqrt(M_ii M_jj), not their own size, so that
    // round-off in near-zero couplings does not count; every other number on its own size.
    let column = |name: &str| h0.iter().position(|c| c == name);
    let diagonal = |row: &[String], m: char, i: char| {
        h0.iter().position(|c| c.starts_with(&format!("{m}{i}{i}_"))).map(|k| row[k].parse::<f64>().unwrap().abs())
    };
    for (a, b) in r1.iter().zip(&r0) {
        for (k, (x, y)) in a.iter().zip(b).enumerate() {
            match (x.parse::<f64>(), y.parse::<f64>()) {
                (Ok(x), Ok(y)) => {
                    let name = &h0[k];
                    let chars: Vec<char> = name.chars().collect();
                    let scale = match chars.as_slice() {
                        [m @ ('C' | 'K'), i, j, '_', ..] if i.is_ascii_digit() && j.is_ascii_digit() => {
                            (diagonal(b, *m, *i).unwrap() * diagonal(b, *m, *j).unwrap()).sqrt()
                        }
                        _ => y.abs().max(1e-12),
                    };
                    assert!((x - y).abs() <= 1e-9 * scale + 1e-15, "{name}: {x} vs golden {y}");
                }
                _ => assert_eq!(x, y, "column {}", h0[k]),
            }
        }
    }
    assert!(column("condition").is_some());
}

/// Synthetic measurements draw each pose's noise from a generator seeded by the seed and the pose's index,
/// so the file is the same for one and two threads (300 poses: two runs of 256, some unreachable).
#[test]
fn synthetic_measurements_are_the_same_for_one_and_two_threads() {
    let dir = temp_dir();
    let grid = dir.path().join("g.toml");
    std::fs::write(&grid, "[box]\nfrom = [-80, -80, 0]\nto = [400, 130, 0]\npoints = [20, 15, 1]\n").unwrap();
    let mut outputs = Vec::new();
    for threads in ["1", "2"] {
        let out = dir.path().join(format!("t{threads}.csv"));
        stiff()
            .args(["synth", MODEL, "--grid"])
            .arg(&grid)
            .args(["--effect", "tool-offset=0.05,0,0", "--noise", "0.002", "--seed", "7"])
            .args(["--wrenches", "100,0,0,0,0,0;0,0,-200,0,0,0", "--threads", threads, "-q", "-o"])
            .arg(&out)
            .assert()
            .success();
        outputs.push(std::fs::read_to_string(&out).unwrap());
    }
    assert_eq!(outputs[0], outputs[1]);
    let rows = outputs[0].lines().count() - 1;
    assert!(rows > 100 && rows < 2 * 300, "some poses measured, some left out: {rows} rows");
}

#[test]
fn the_map_is_the_same_for_one_and_two_threads() {
    let dir = temp_dir();
    let grid = dir.path().join("g.toml");
    // 2,601 points: several runs of warm starts, some of them unreachable (beyond the legs' reach).
    std::fs::write(&grid, "[box]\nfrom = [-80, -80, 0]\nto = [400, 130, 0]\npoints = [51, 51, 1]\n").unwrap();
    let mut outputs = Vec::new();
    for threads in ["1", "2"] {
        let out = dir.path().join(format!("t{threads}.csv"));
        stiff()
            .args(["map", MODEL, "--grid"])
            .arg(&grid)
            .args(["--threads", threads, "-q", "-o"])
            .arg(&out)
            .assert()
            .success();
        outputs.push(std::fs::read(&out).unwrap());
    }
    assert_eq!(outputs[0], outputs[1]);
    let text = String::from_utf8(outputs.remove(0)).unwrap();
    assert!(text.contains(",unreachable,"), "the grid reaches past the workspace");
    assert!(text.contains(",ok,"));
    assert_eq!(text.lines().count(), 2602);
}

#[test]
fn points_csv_keeps_input_order_names_and_reports_unreachable_points_as_rows() {
    let dir = temp_dir();
    let pts = dir.path().join("p.csv");
    std::fs::write(&pts, "name,x_mm,y_mm,z_mm\nQ2,126.35,126.35,126.35\n\"far, away\",900,0,0\nQ0,0,0,0\n").unwrap();
    let output = stiff().args(["map", MODEL, "--points"]).arg(&pts).arg("-q").output().unwrap();
    assert!(output.status.success());
    let text = String::from_utf8(output.stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].starts_with("index,name,x_mm,y_mm,z_mm,status,rank,free_directions,condition,c_tran_max_mm_per_N"));
    assert!(
        lines[0].contains(",C11_mm_per_N,")
            && lines[0].contains(",C14_mm_per_Nmm,")
            && lines[0].contains(",C66_rad_per_Nmm")
    );
    assert!(lines[1].starts_with("0,Q2,126.35,126.35,126.35,ok,6,,"));
    assert!(
        lines[2].starts_with("1,\"far, away\",900.0,0.0,0.0,unreachable,,,,,"),
        "rank and condition are empty where not computed: {}",
        lines[2]
    );
    assert!(lines[3].starts_with("2,Q0,0.0,0.0,0.0,ok,6,"));
}

/// A points file is text: its fields are read with the white space around them dropped (Unicode's, as a
/// reader of text trims), and a field that is not UTF-8 text is refused where it is, line and column, even in
/// a column the run does not use: the points are read field by field from bytes, not as whole strings.
#[test]
fn points_csv_fields_are_trimmed_text_and_bytes_that_are_not_text_are_located() {
    use stiff::model::error::InputError;
    use stiff::model::grid::PointSet;
    let dir = temp_dir();
    let read = |bytes: &[u8]| {
        let path = dir.path().join("p.csv");
        std::fs::write(&path, bytes).unwrap();
        let mut points = PointSet::from_points_csv(&path).unwrap();
        let mut out = Vec::new();
        points.next_block(10, &mut out).map(|_| out)
    };
    let points = read(" name , x_mm,y_mm , z_mm \n  Q2 ,\t126.35, 1e1 ,\u{a0}-3\u{a0}\n".as_bytes()).unwrap();
    assert_eq!(points.len(), 1);
    assert_eq!(points[0].name.as_deref(), Some("Q2"));
    assert_eq!(points[0].position, stiff::kinematics::frame::Vec3::new(126.35, 10.0, -3.0));
    for (bytes, line, column) in
        [(&b"x_mm,y_mm,z_mm\n1,2,3\n1,2,\xff\n"[..], 3, 3), (&b"x_mm,y_mm,z_mm,note\n1,2,3,\xc3\n"[..], 2, 4)]
    {
        match read(bytes) {
            Err(InputError::At { line: l, column: c, message, .. }) => {
                assert_eq!((l, c), (line, column), "{message}");
                assert!(message.contains("UTF-8"), "{message}");
            }
            other => panic!("not refused where the bytes are: {:?}", other.map(|p| p.len())),
        }
    }
}

#[test]
fn point_prints_both_matrices_with_units() {
    let out = stiff().args(["point", MODEL, "--at", "0,0,0"]).output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("Stiffness K") && text.contains("Compliance C"));
    assert!(text.contains("Fx [N]") && text.contains("rx [rad]") && text.contains("Mz [Nmm]"));
    assert!(text.contains("2.7945e-4"), "{text}");
}

fn model_with(edit: impl Fn(&str) -> String) -> (tempfile::TempDir, PathBuf) {
    let dir = temp_dir();
    let path = dir.path().join("model.toml");
    std::fs::write(&path, edit(&std::fs::read_to_string(MODEL).unwrap())).unwrap();
    (dir, path)
}

/// Runs a map that must fail; returns stderr after checking the exit code and that no output is left.
fn refused(model: &Path, grid_args: &[&str], out_dir: &Path) -> String {
    let out = out_dir.join("result.csv");
    let o = stiff().arg("map").arg(model).args(grid_args).arg("-q").arg("-o").arg(&out).output().unwrap();
    assert!(!o.status.success(), "accepted");
    assert!(!out.exists(), "an output file was left behind");
    let leftovers: Vec<_> = std::fs::read_dir(out_dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains("partial"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left behind");
    String::from_utf8(o.stderr).unwrap()
}

const GRID: [&str; 2] = ["--grid", "manipulators/grids/orthoglide-q.toml"];

#[test]
fn malformed_toml_is_refused_with_its_line_and_column() {
    let (dir, m) = model_with(|t| t.replace("k_act = 20491", "k_act = 20491 ["));
    let e = refused(&m, &GRID, dir.path());
    assert!(e.contains("model.toml") && e.contains("line 18, column 15"), "{e}");
}

#[test]
fn unknown_key_is_refused_with_its_line() {
    let (dir, m) = model_with(|t| format!("{t}\nthis_key_does_not_exist = 3\n"));
    let e = refused(&m, &GRID, dir.path());
    assert!(e.contains("unknown field `this_key_does_not_exist`") && e.contains("line 57"), "{e}");
}

#[test]
fn missing_parameter_is_refused_where_it_is_used() {
    let (dir, m) = model_with(|t| t.replace("stiffness = \"k_act\"", "stiffness = \"k_actuator\""));
    let e = refused(&m, &GRID, dir.path());
    assert!(e.contains("unknown parameter `k_actuator`") && e.contains("line 42, column"), "{e}");
}

#[test]
fn spring_matrices_must_be_symmetric_positive_definite() {
    let bad_row = "{ type = \"spring6\", name = \"leg\", stiffness_matrix = [[1,2,0,0,0,0],[2,1,0,0,0,0],[0,0,1,0,0,0],[0,0,0,1,0,0],[0,0,0,0,1,0],[0,0,0,0,0,1]] },";
    let leg_line = |t: &str| t.lines().find(|l| l.contains("name = \"leg\", beam")).unwrap().to_string();
    let (dir, m) = model_with(|t| t.replace(&leg_line(t), bad_row));
    let e = refused(&m, &GRID, dir.path());
    assert!(e.contains("not positive definite") && e.contains("line 50"), "{e}");
    let unsym = bad_row.replace("[2,1,0,0,0,0]", "[0,1,0,0,0,0]");
    let (dir, m) = model_with(|t| t.replace(&leg_line(t), &unsym));
    let e = refused(&m, &GRID, dir.path());
    assert!(e.contains("not symmetric"), "{e}");
}

#[test]
fn a_grid_with_zero_points_along_an_axis_is_refused() {
    let dir = temp_dir();
    let grid = dir.path().join("zero.toml");
    std::fs::write(&grid, "[box]\nfrom = [0, 0, 0]\nto = [1, 1, 1]\npoints = [2, 0, 2]\n").unwrap();
    let e = refused(Path::new(MODEL), &["--grid", grid.to_str().unwrap()], dir.path());
    assert!(e.contains("zero.toml, line 4") && e.contains("`points` must be at least 1"), "{e}");
}

#[test]
fn a_bad_number_in_a_points_file_is_refused_with_its_line() {
    let dir = temp_dir();
    let pts = dir.path().join("p.csv");
    std::fs::write(&pts, "x_mm,y_mm,z_mm\n0,0,0\n1,nan,2\n").unwrap();
    let e = refused(Path::new(MODEL), &["--points", pts.to_str().unwrap()], dir.path());
    assert!(e.contains("p.csv, line 3, column 2"), "{e}");
    std::fs::write(&pts, "x_mm,y_mm\n0,0\n").unwrap();
    let e = refused(Path::new(MODEL), &["--points", pts.to_str().unwrap()], dir.path());
    assert!(e.contains("no column `z_mm`"), "{e}");
}

#[test]
fn an_unwritable_output_path_is_refused_before_any_work() {
    let o = stiff().args(["map", MODEL, "--grid", GRID[1], "-q", "-o", "/nonexistent-folder/x.csv"]).output().unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8(o.stderr).unwrap().contains("does not exist"));
}

#[test]
fn an_existing_output_is_replaced_only_on_success() {
    let dir = temp_dir();
    let out = dir.path().join("keep.csv");
    std::fs::write(&out, "previous result\n").unwrap();
    let (_d, bad) = model_with(|t| format!("{t}\noops = 1\n"));
    let o = stiff().arg("map").arg(&bad).args(GRID).arg("-q").arg("-o").arg(&out).output().unwrap();
    assert!(!o.status.success());
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "previous result\n");
}

/// `stiff curve` under displacement control at Q0: units in the header, a row per step, and an initial
/// slope equal to the map's K11 (the loaded stiffness starts at the unloaded one).
#[test]
fn curve_starts_at_the_unloaded_stiffness() {
    let dir = temp_dir();
    let out = dir.path().join("c.csv");
    stiff()
        .args(["curve", MODEL, "--at", "0,0,0", "--displacement-direction", "1,0,0,0,0,0", "--max", "0.5"])
        .args(["--intervals", "10", "-q", "-o"])
        .arg(&out)
        .assert()
        .success();
    let (h, rows) = read_csv(&out);
    // The documented columns (docs/GUIDE.md), spelled out so a change of the format is a decision, not an accident.
    let documented = "step,control,load_factor,Fx_N,Fy_N,Fz_N,Mx_Nmm,My_Nmm,Mz_Nmm,dx_mm,dy_mm,dz_mm,rx_rad,ry_rad,\
        rz_rad,k_tran_min_N_per_mm,k_rot_min_Nmm_per_rad,k_scaled_min_N_per_mm,mode_dx,mode_dy,mode_dz,mode_rx,mode_ry,\
        mode_rz,stable,instability,iterations,status,residual,event,event_load_factor";
    assert_eq!(h.join(","), documented);
    assert_eq!(rows.len(), 11);
    let fx: f64 = rows[1][3].parse().unwrap();
    let dx: f64 = rows[1][9].parse().unwrap();
    let k = stiff::model::load_manipulator(Path::new(MODEL)).unwrap();
    let k11 = k.unloaded(&stiff::kinematics::frame::Frame::IDENTITY, &mut k.new_state()).unwrap().stiffness[(0, 0)];
    assert!(((fx / dx) - k11).abs() < 0.01 * k11, "slope {} vs K11 {k11}", fx / dx);
    let stable = h.iter().position(|c| c == "stable").unwrap();
    assert!(rows.iter().all(|r| r[stable] == "true"));
}

/// A loaded map under the milling wrench: every point solved, the displacement columns present, and the
/// same bytes for one and two threads.
#[test]
fn loaded_map_is_thread_independent() {
    let dir = temp_dir();
    let mut outputs = Vec::new();
    for threads in ["1", "2"] {
        let out = dir.path().join(format!("l{threads}.csv"));
        stiff()
            .args([
                "map",
                MODEL,
                "--grid",
                "manipulators/grids/orthoglide-small.toml",
                "--wrench",
                "215,-10,-25,1000,21500,0",
            ])
            .args(["--threads", threads, "-q", "-o"])
            .arg(&out)
            .assert()
            .success();
        outputs.push(std::fs::read_to_string(&out).unwrap());
    }
    assert_eq!(outputs[0], outputs[1]);
    let lines: Vec<&str> = outputs[0].lines().collect();
    // Loaded maps keep the unloaded column order and append what they add (the 15 entries below the
    // diagonal of the tangent compliance, the Newton iterations last).
    assert!(lines[0].contains(",C66_rad_per_Nmm,C21_mm_per_N,") && lines[0].ends_with(",C65_rad_per_Nmm,iterations"));
    assert!(lines[0].contains(",dx_mm,dy_mm,dz_mm,rx_rad,ry_rad,rz_rad,"));
    assert_eq!(lines.len(), 126);
    assert!(lines[1..].iter().all(|l| l.contains(",ok,6,")));
}

#[test]
fn loaded_without_reference_wrenches_is_refused() {
    let pts = temp_dir();
    let p = pts.path().join("p.csv");
    std::fs::write(&p, "x_mm,y_mm,z_mm\n0,0,0\n").unwrap();
    let o = stiff().args(["map", MODEL, "--points"]).arg(&p).args(["--loaded", "-q"]).output().unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8(o.stderr).unwrap().contains("--loaded needs reference wrenches"));
}

/// NaVARo II maps in both actuation modes through `--set`; poses out of the legs' reach are rows with status
/// `unreachable`; a `--set` naming no parameter, and a malformed MSA description, are refused with a message.
#[test]
fn navaro_maps_in_both_modes_and_bad_msa_input_is_refused() {
    let dir = temp_dir();
    let mut columns = Vec::new();
    for mode in ["1", "2"] {
        let out = dir.path().join(format!("n{mode}.csv"));
        stiff()
            .args(["map", "manipulators/navaro2.toml", "--set", &format!("mode={mode}"), "-q", "--grid"])
            .arg("manipulators/grids/navaro2-workspace.toml")
            .arg("-o")
            .arg(&out)
            .assert()
            .success();
        let (header, rows) = read_csv(&out);
        let status = header.iter().position(|h| h == "status").unwrap();
        let c11 = header.iter().position(|h| h == "C11_mm_per_N").unwrap();
        assert_eq!(rows.len(), 41 * 41);
        let ok: Vec<_> = rows.iter().filter(|r| r[status] == "ok").collect();
        assert!(ok.len() > 300 && rows.iter().any(|r| r[status] == "unreachable"));
        columns.push(ok.iter().map(|r| r[c11].clone()).collect::<Vec<_>>());
    }
    assert_ne!(columns[0], columns[1], "the two modes give different maps");
    let o = stiff().args(["point", "manipulators/navaro2.toml", "--at", "0,0,0", "--set", "modes=1"]).output().unwrap();
    assert!(!o.status.success() && String::from_utf8(o.stderr).unwrap().contains("no parameter `modes`"));
    let bad = dir.path().join("bad.toml");
    let text = std::fs::read_to_string("manipulators/navaro2-leg-passive.toml").unwrap();
    std::fs::write(&bad, text.replace("nodes = [\"15\", \"17\"]", "nodes = [\"15\", \"71\"]")).unwrap();
    let o = stiff().args(["point"]).arg(&bad).args(["--at", "0,0,0"]).output().unwrap();
    let message = String::from_utf8(o.stderr).unwrap();
    assert!(!o.status.success() && message.contains("no node named `71`") && message.contains("line"), "{message}");
}

/// `stiff assemble`: tolerance samples are the same for one and two threads and for the same seed, differ
/// for another seed; a path gives its named points; an unknown leg and parameter errors on an MSA leg are
/// refused with a message.
#[test]
fn assemble_samples_are_reproducible_and_bad_errors_are_refused() {
    let dir = temp_dir();
    let run = |threads: &str, seed: &str, name: &str| {
        let out = dir.path().join(name);
        stiff()
            .args(["assemble", MODEL, "--errors", "manipulators/errors/orthoglide-case-b.toml", "-q"])
            .args(["--grid", "manipulators/grids/orthoglide-small.toml", "--samples", "50", "--seed", seed])
            .args(["--threads", threads, "-o"])
            .arg(&out)
            .assert()
            .success();
        std::fs::read_to_string(out).unwrap()
    };
    let a = run("1", "3", "a.csv");
    assert_eq!(a, run("2", "3", "b.csv"));
    assert_ne!(a, run("2", "4", "c.csv"));
    let (header, rows) = read_csv(&dir.path().join("a.csv"));
    assert_eq!(rows.len(), 125);
    for c in [
        "x_mm",
        "status",
        "mean_dx_mm",
        "mean_rz_rad",
        "displacement_worst_mm",
        "force_max_std_N",
        "moment_max_mean_Nmm",
    ] {
        assert!(header.iter().any(|h| h == c), "{c} in {header:?}");
    }
    // `dx_mm` means one assembly's displacement; a tolerance study's mean has its own name.
    assert!(!header.iter().any(|h| h == "dx_mm"), "{header:?}");
    let out = dir.path().join("path.csv");
    stiff()
        .args(["assemble", MODEL, "--errors", "manipulators/errors/orthoglide-case-a.toml", "-q", "--path"])
        .args(["-73.65,-73.65,-73.65", "-73.65,126.35,-73.65", "11", "--wrench", "215,-10,-25,1000,21500,0", "-o"])
        .arg(&out)
        .assert()
        .success();
    let (header, rows) = read_csv(&out);
    assert_eq!(rows.len(), 11);
    assert_eq!(rows[10][1], "", "a path's points are unnamed (names are the user's)");
    assert_eq!(&rows[10][2..5], ["-73.65", "126.35", "-73.65"], "the last point is TO");
    assert!(header.iter().any(|h| h == "superposition_gap_mm"));
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "[[leg]]\nname = \"chain.7\"\neps = { translation_mm = [1, 0, 0] }\n").unwrap();
    let o = stiff()
        .args(["assemble", MODEL, "--errors"])
        .arg(&bad)
        .args(["--path", "0,0,0", "1,0,0", "2"])
        .output()
        .unwrap();
    let message = String::from_utf8(o.stderr).unwrap();
    assert!(
        !o.status.success() && message.contains("no leg named `chain.7`") && message.contains("line 2"),
        "{message}"
    );
    std::fs::write(&bad, "[[leg]]\nname = \"*\"\nparameters = { L = 311 }\n").unwrap();
    let o = stiff()
        .args(["assemble", "manipulators/orthoglide-3puu-msa.toml", "--errors"])
        .arg(&bad)
        .args(["--path", "0,0,0", "1,0,0", "2"])
        .output()
        .unwrap();
    assert!(!o.status.success() && String::from_utf8(o.stderr).unwrap().contains("MSA leg"));
}

/// `stiff synth` then `stiff diagnose` from the outside: JSON with the verdict and named effects, sigma
/// from repeats when the data has none, and bad data refused with its location: a missing column, a NaN,
/// an unreachable pose, no way to know the noise, too few rows.
#[test]
fn diagnose_reads_synth_output_and_refuses_bad_data() {
    let dir = temp_dir();
    let data = dir.path().join("d.csv");
    let wrenches = "0,0,0,0,0,0;200,0,0,0,0,0;-200,0,0,0,0,0;0,200,0,0,0,0;0,-200,0,0,0,0;0,0,200,0,0,0;0,0,-200,0,0,0";
    stiff()
        .args([
            "synth",
            MODEL,
            "--effect",
            "actuator-compliance:3=2",
            "--grid",
            "manipulators/grids/orthoglide-small.toml",
        ])
        .args(["--wrenches", wrenches, "--noise", "0.002", "--seed", "9", "--repeats", "2", "-o"])
        .arg(&data)
        .assert()
        .success();
    let json = dir.path().join("v.json");
    stiff().args(["diagnose", MODEL, "--data"]).arg(&data).arg("--json").arg(&json).assert().success();
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["verdict"], "effect");
    assert_eq!(v["effects"][0]["name"], "actuator-compliance");
    assert_eq!(v["effects"][0]["target"], "3");
    // Without the sigma column, the repeats give the noise.
    let text = std::fs::read_to_string(&data).unwrap();
    let sigma_column = text.lines().next().unwrap().split(',').position(|c| c == "sigma_mm").unwrap();
    let strip = |t: &str| {
        let mut out = String::new();
        for l in t.lines() {
            let cells: Vec<&str> =
                l.split(',').enumerate().filter(|(i, _)| *i != sigma_column).map(|(_, c)| c).collect();
            out += &(cells.join(",") + "\n");
        }
        out
    };
    let no_sigma = dir.path().join("n.csv");
    std::fs::write(&no_sigma, strip(&text)).unwrap();
    let o = stiff().args(["diagnose", MODEL, "--data"]).arg(&no_sigma).output().unwrap();
    let out = String::from_utf8(o.stdout).unwrap();
    assert!(o.status.success() && out.contains("repeated rows") && out.contains("actuator-compliance:3"), "{out}");
    let refuse = |content: String, needle: &str| {
        let bad = dir.path().join("bad.csv");
        std::fs::write(&bad, content).unwrap();
        let o = stiff().args(["diagnose", MODEL, "--data"]).arg(&bad).output().unwrap();
        let message = String::from_utf8(o.stderr).unwrap();
        assert!(!o.status.success() && message.contains(needle), "expected `{needle}`: {message}");
    };
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    refuse(lines.iter().map(|l| l.replacen("Fz_N", "Fz", 1) + "\n").collect(), "missing column `Fz_N`");
    lines[3] = lines[3].replacen(",0.0,", ",NaN,", 1);
    refuse(lines.join("\n"), "line 4");
    let header = text.lines().next().unwrap();
    refuse(format!("{header}\nfar,900,0,0,0,0,0,0,0,0,0.1,0,0,0.002,0\n"), "pose `far`");
    refuse(strip(&format!("{header}\np,0,0,0,0,0,0,0,0,0,0.1,0,0,0.002,0\n")), "noise level is unknown");
    refuse(format!("{header}\np,0,0,0,100,0,0,0,0,0,0.1,0,0,0.002,0\n"), "too few");
}

/// Regression: grid coordinates were computed in floating point (-63.650000000000006), so a filter
/// `x_mm == -63.65` selected nothing. They are computed in the grid's own decimals: every coordinate of the
/// 21-point axes from -73.65 to 126.35 is written as exactly -73.65 + 10 k.
#[test]
fn grid_coordinates_are_the_decimals_the_user_meant() {
    let dir = temp_dir();
    let grid = dir.path().join("g.toml");
    std::fs::write(&grid, "[box]\nfrom = [-73.65, -73.65, 0.1]\nto = [126.35, 126.35, 0.1]\npoints = [21, 21, 1]\n")
        .unwrap();
    let out = stiff().args(["map", MODEL, "--grid"]).arg(&grid).arg("-q").output().unwrap();
    let text = String::from_utf8(out.stdout).unwrap();
    let mut xs: Vec<String> = text.lines().skip(1).map(|l| l.split(',').nth(2).unwrap().to_string()).collect();
    xs.dedup();
    xs.sort();
    xs.dedup();
    let mut expected: Vec<String> = (0..21).map(|k| format!("{}", (-7365 + 1000 * k) as f64 / 100.0)).collect();
    expected.sort();
    assert_eq!(xs, expected);
    assert!(text.lines().skip(1).all(|l| l.split(',').nth(4) == Some("0.1")));
    assert!(text.contains(",-63.65,"));
}
