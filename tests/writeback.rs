//! The write-back round trip: `diagnose --model-out` writes each accepted effect as the model change it is,
//! and every study of the corrected description changes as the effect says, checked against an independent
//! route through the nominal model:
//! - a mass m carried at the reference point is its weight, the wrench (0, 0, -9.81 m, 0, 0, 0) N at the
//!   reference point: the corrected model's loaded map, curve, point and assembly equal the nominal model's
//!   under that wrench added (an assembly measured from the sag under it);
//! - an actuator sitting delta further along its axis than commanded is the leg's base moved by delta along
//!   the actuator's axis (the actuator is the leg's first joint, a slider fixed to the base): the corrected
//!   model's loaded map at zero load and its assembly equal the nominal model's assembly with that base error
//!   (paper 000 s. 5.1, Case A, is such an error);
//!
//! and the corrected description diagnoses as `none` on the same data.

use std::path::{Path, PathBuf};

use crate::common;
use common::{csv_columns as columns, run_stiff as run};

const MODEL: &str = "manipulators/orthoglide-3puu.toml";
const GRID: &str = "manipulators/grids/orthoglide-small.toml";
const WRENCHES: &str =
    "0,0,0,0,0,0;200,0,0,0,0,0;-200,0,0,0,0,0;0,200,0,0,0,0;0,-200,0,0,0,0;0,0,200,0,0,0;0,0,-200,0,0,0";
/// Both routes solve the same equilibrium to Newton's tolerance (1e-8 of the length scale): mm.
const SAME_MM: f64 = 1e-7;

fn assert_same(a: &[Vec<f64>], b: &[Vec<f64>], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: rows");
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        for (u, v) in x.iter().zip(y) {
            assert!((u - v).abs() <= SAME_MM, "{what}, row {i}: {x:?} vs {y:?}");
        }
    }
}

const DISPLACEMENT: [&str; 6] = ["dx_mm", "dy_mm", "dz_mm", "rx_rad", "ry_rad", "rz_rad"];
const ASSEMBLED: [&str; 6] = ["nl_dx_mm", "nl_dy_mm", "nl_dz_mm", "nl_rx_rad", "nl_ry_rad", "nl_rz_rad"];

/// Synthesises data with `effect` hidden, diagnoses it with `--model-out`, and returns the corrected file,
/// the verdict JSON and the data.
fn diagnose_hidden(dir: &Path, effect: &str, seed: &str) -> (PathBuf, serde_json::Value, PathBuf) {
    let data = dir.join("data.csv");
    let d = data.to_str().unwrap();
    run(&["synth", MODEL, "--grid", GRID, "--effect", effect, "--wrenches", WRENCHES, "--noise", "0.002"]
        .into_iter()
        .chain(["--seed", seed, "-q", "-o", d])
        .collect::<Vec<_>>());
    let (fixed, json) = (dir.join("fixed.toml"), dir.join("v.json"));
    run(&["diagnose", MODEL, "--data", d, "--model-out", fixed.to_str().unwrap(), "--json", json.to_str().unwrap()]);
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    (fixed, v, data)
}

/// The corrected description on the same data: nothing left to name.
fn assert_clean(fixed: &Path, data: &Path) {
    let out = run(&["diagnose", fixed.to_str().unwrap(), "--data", data.to_str().unwrap()]);
    assert!(out.contains("verdict: none"), "{out}");
}

/// Points with wrenches, for loaded maps.
fn points(dir: &Path, wrench: [f64; 6]) -> PathBuf {
    let path = dir.join("points.toml");
    let mut text = String::new();
    for (i, at) in [[0.0, 0.0, 0.0], [40.0, -30.0, 20.0], [-50.0, 60.0, -40.0]].iter().enumerate() {
        let w: Vec<String> = wrench.iter().map(|v| v.to_string()).collect();
        text += &format!("[[point]]\nname = \"p{i}\"\nat = {at:?}\nwrench = [{}]\n\n", w.join(", "));
    }
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn a_payload_found_by_diagnose_loads_every_study() {
    let dir = tempfile::tempdir().unwrap();
    let (fixed, v, data) = diagnose_hidden(dir.path(), "gravity=5", "3");
    assert_eq!(v["verdict"], "effect", "{}", v["sentence"]);
    assert_eq!(v["effects"][0]["name"], "gravity");
    let mass = v["effects"][0]["values"][0].as_f64().unwrap();
    let se = v["effects"][0]["standard_errors"][0].as_f64().unwrap();
    assert!((mass - 5.0).abs() <= 4.0 * se, "{mass} +- {se}");
    let text = std::fs::read_to_string(&fixed).unwrap();
    assert!(text.contains("[[payload]]") && !text.contains("name = \"gravity\""), "{text}");
    let f = fixed.to_str().unwrap();
    let weight = [0.0, 0.0, -9.81 * mass, 0.0, 0.0, 0.0];
    // Loaded map: the corrected model under 100 N along x = the nominal under it plus the weight.
    let push = [100.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let corrected = run(&["map", f, "--grid", points(dir.path(), push).to_str().unwrap(), "--loaded", "-q"]);
    let both: Vec<f64> = push.iter().zip(&weight).map(|(a, b)| a + b).collect();
    let nominal = run(&[
        "map",
        MODEL,
        "--grid",
        points(dir.path(), both.try_into().unwrap()).to_str().unwrap(),
        "--loaded",
        "-q",
    ]);
    assert_same(&columns(&corrected, &DISPLACEMENT), &columns(&nominal, &DISPLACEMENT), "loaded map");
    // The curve starts where the payload alone puts the platform.
    let curve = run(&["curve", f, "--at", "40,-30,20", "--wrench-direction", "0,0,-1000,0,0,0", "--max", "1"]);
    let start = columns(&curve, &DISPLACEMENT)[0].clone();
    let sag = run(&["map", MODEL, "--grid", points(dir.path(), weight).to_str().unwrap(), "--loaded", "-q"]);
    assert_same(&[start], &columns(&sag, &DISPLACEMENT)[1..2], "curve at zero load");
    // Assembly with errors: the payload is part of the assembled robot, and a robot carrying weight has its
    // assembly measured from its own sag without errors. So the corrected model's assembled displacement is
    // the nominal one's under the weight (its `total_*`, errors and load together) less the weight's alone
    // (its `load_*`); rotations agree to their square, 1e-9 rad here.
    let errors = "manipulators/errors/orthoglide-case-a.toml";
    let q = "manipulators/grids/orthoglide-q.toml";
    let a = run(&["assemble", f, "--errors", errors, "--grid", q, "-q"]);
    let w = weight.map(|x| x.to_string()).join(",");
    let b = run(&["assemble", MODEL, "--errors", errors, "--grid", q, "--wrench", &w, "-q"]);
    let total = ["total_dx_mm", "total_dy_mm", "total_dz_mm", "total_rx_rad", "total_ry_rad", "total_rz_rad"];
    let load = ["load_dx_mm", "load_dy_mm", "load_dz_mm", "load_rx_rad", "load_ry_rad", "load_rz_rad"];
    let errors_alone: Vec<Vec<f64>> = columns(&b, &total)
        .iter()
        .zip(columns(&b, &load))
        .map(|(t, l)| t.iter().zip(&l).map(|(t, l)| t - l).collect())
        .collect();
    assert_same(&columns(&a, &ASSEMBLED), &errors_alone, "assembly");
    assert_clean(&fixed, &data);
}

#[test]
fn an_actuator_offset_found_by_diagnose_moves_every_study() {
    let dir = tempfile::tempdir().unwrap();
    let (fixed, v, data) = diagnose_hidden(dir.path(), "actuator-offset:2=0.02", "4");
    assert_eq!(v["verdict"], "effect", "{}", v["sentence"]);
    assert_eq!((&v["effects"][0]["name"], &v["effects"][0]["target"]), (&"actuator-offset".into(), &"2".into()));
    let offset = v["effects"][0]["values"][0].as_f64().unwrap();
    let text = std::fs::read_to_string(&fixed).unwrap();
    assert!(text.contains("[[actuator_offset]]\nleg = 2\n"), "{text}");
    let f = fixed.to_str().unwrap();
    // The same leg with its base moved by the offset along its actuator's axis (x in the leg's own frame).
    let moved = dir.path().join("moved.toml");
    std::fs::write(&moved, format!("[[leg]]\nname = \"chain.2\"\nbase = {{ translation_mm = [{offset}, 0, 0] }}\n"))
        .unwrap();
    let grid = points(dir.path(), [0.0; 6]);
    let g = grid.to_str().unwrap();
    let corrected = run(&["map", f, "--grid", g, "--loaded", "-q"]);
    let assembled = run(&["assemble", MODEL, "--errors", moved.to_str().unwrap(), "--grid", g, "-q"]);
    let shift = columns(&assembled, &ASSEMBLED);
    assert_same(&columns(&corrected, &DISPLACEMENT), &shift, "loaded map at zero load");
    assert!(shift.iter().all(|r| r[..3].iter().map(|x| x * x).sum::<f64>().sqrt() > 0.1 * offset), "{shift:?}");
    let curve = run(&["curve", f, "--at", "40,-30,20", "--wrench-direction", "0,0,-1000,0,0,0", "--max", "1"]);
    assert_same(&columns(&curve, &DISPLACEMENT)[..1], &shift[1..2], "curve at zero load");
    assert_clean(&fixed, &data);
}

/// Regression: under `--linear` (every prediction first order in the loads), a corrected file carrying the
/// `[[payload]]` that a linear diagnosis of `gravity-offset` wrote diagnosed `unexplained` (tool-offset,
/// leg-geometry) on the same data: its nominal settled the payload's weight exactly (the moment's arm turning
/// with the platform), where the effect had been fitted as C times the weight. The linear nominal's rest
/// displacement under a payload is C times its weight too: the corrected file diagnoses `none`.
#[test]
fn a_payload_written_by_a_linear_diagnosis_is_clean_under_linear() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data.csv");
    let d = data.to_str().unwrap();
    run(&["synth", MODEL, "--grid", GRID, "--effect", "gravity-offset=5,100,0,0", "--wrenches", WRENCHES]
        .into_iter()
        .chain(["--noise", "0.001", "--seed", "4", "--linear", "-q", "-o", d])
        .collect::<Vec<_>>());
    let fixed = dir.path().join("fixed.toml");
    let out = run(&["diagnose", MODEL, "--data", d, "--linear", "--model-out", fixed.to_str().unwrap()]);
    assert!(out.contains("verdict: effect: gravity-offset"), "{out}");
    assert!(std::fs::read_to_string(&fixed).unwrap().contains("[[payload]]"));
    let out = run(&["diagnose", fixed.to_str().unwrap(), "--data", d, "--linear"]);
    assert!(out.contains("verdict: none"), "{out}");
}
