//! `stiff sweep`: a design's summary row is its map reduced (checked against `stiff map --set` runs reduced
//! here, independently), the Orthoglide's compliance falls as 1/k_act when its links are rigid, Latin
//! hypercubes are reproducible and stratified, and a design that cannot be built is a row, not an abort.

use crate::common;

use common::{csv_columns, run_stiff};

const MODEL: &str = "manipulators/orthoglide-3puu.toml";
const GRID: &str = "manipulators/grids/orthoglide-small.toml";

/// Rows of a CSV as text cells, with the header.
fn table(text: &str) -> (Vec<String>, Vec<Vec<String>>) {
    let mut reader = csv::Reader::from_reader(text.as_bytes());
    let header = reader.headers().unwrap().iter().map(str::to_string).collect();
    let rows = reader.records().map(|r| r.unwrap().iter().map(str::to_string).collect()).collect();
    (header, rows)
}

fn cell<'a>(header: &[String], row: &'a [String], name: &str) -> &'a str {
    &row[header.iter().position(|h| h == name).unwrap_or_else(|| panic!("no column {name}"))]
}

fn number(header: &[String], row: &[String], name: &str) -> f64 {
    cell(header, row, name).parse().unwrap_or_else(|_| panic!("{name} = `{}`", cell(header, row, name)))
}

/// The 95th percentile as numpy computes it by default: sorted values, position 0.95 (n - 1), linear
/// between the two neighbouring ranks.
fn numpy_p95(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let h = 0.95 * (v.len() - 1) as f64;
    let (lo, hi) = (h.floor() as usize, h.ceil() as usize);
    v[lo] + (h - lo as f64) * (v[hi] - v[lo])
}

fn close(a: f64, b: f64, what: &str) {
    assert!((a - b).abs() <= 1e-12 * b.abs().max(1e-300), "{what}: sweep {a} vs map {b}");
}

/// Physics: a design is the description with its parameter values, so each summary row must be the
/// reduction of the map `stiff map --set NAME=VALUE` writes for that design. The reduction here is
/// written independently of the program's: statuses counted from the status column, statistics over the
/// non-empty cells, the worst point by the largest c_tran_max, the threshold count.
#[test]
fn a_sweep_row_is_its_map_reduced() {
    let dir = tempfile::tempdir().unwrap();
    let maps = dir.path().join("maps");
    let threshold = 7e-4;
    let sweep = run_stiff(&[
        "sweep",
        MODEL,
        "--vary",
        "k_act=8000:32000:3",
        "--grid",
        GRID,
        "--threshold",
        &threshold.to_string(),
        "--maps",
        maps.to_str().unwrap(),
        "-q",
    ]);
    let (h, rows) = table(&sweep);
    assert_eq!(rows.len(), 3);
    for (i, (row, k_act)) in rows.iter().zip(["8000", "20000", "32000"]).enumerate() {
        assert_eq!(cell(&h, row, "index"), i.to_string());
        assert_eq!(cell(&h, row, "status"), "ok");
        close(number(&h, row, "k_act"), k_act.parse().unwrap(), "k_act");
        let map = run_stiff(&["map", MODEL, "--set", &format!("k_act={k_act}"), "--grid", GRID, "-q"]);
        // --maps writes the very map `stiff map` writes.
        assert_eq!(std::fs::read_to_string(maps.join(format!("design-{i}.csv"))).unwrap(), map);
        let (mh, mrows) = table(&map);
        assert_eq!(number(&h, row, "points"), mrows.len() as f64);
        for status in ["ok", "unreachable", "singular", "ill_conditioned", "not_converged", "unstable"] {
            let n = mrows.iter().filter(|r| cell(&mh, r, "status") == status).count();
            assert_eq!(number(&h, row, &format!("{status}_points")), n as f64, "{status}");
        }
        for column in ["c_tran_max_mm_per_N", "c_rot_max_rad_per_Nmm", "deflection_mm"] {
            let values: Vec<f64> = mrows.iter().filter_map(|r| cell(&mh, r, column).parse::<f64>().ok()).collect();
            assert!(!values.is_empty());
            let max = values.iter().cloned().fold(f64::MIN, f64::max);
            let mean = values.iter().sum::<f64>() / values.len() as f64;
            close(number(&h, row, &format!("max_{column}")), max, column);
            close(number(&h, row, &format!("mean_{column}")), mean, column);
            close(number(&h, row, &format!("p95_{column}")), numpy_p95(&values), column);
        }
        let tran = |r: &Vec<String>| cell(&mh, r, "c_tran_max_mm_per_N").parse::<f64>().unwrap_or(f64::MIN);
        let worst = mrows.iter().reduce(|a, b| if tran(b) > tran(a) { b } else { a }).unwrap();
        for axis in ["x_mm", "y_mm", "z_mm"] {
            assert_eq!(cell(&h, row, &format!("worst_{axis}")), cell(&mh, worst, axis));
        }
        let conditions: Vec<f64> = mrows.iter().filter_map(|r| cell(&mh, r, "condition").parse().ok()).collect();
        close(number(&h, row, "min_condition"), conditions.iter().cloned().fold(f64::MAX, f64::min), "min");
        close(number(&h, row, "max_condition"), conditions.iter().cloned().fold(f64::MIN, f64::max), "max");
        let under = mrows.iter().filter(|r| tran(r) != f64::MIN && tran(r) <= threshold).count();
        assert_eq!(number(&h, row, "under_threshold_points"), under as f64);
        // The small grid is 5 x 5 x 5 over 120 mm: a cell is 30 mm on a side.
        close(number(&h, row, "under_threshold_volume_mm3"), under as f64 * 30f64.powi(3), "volume");
    }
    let counts: Vec<f64> = rows.iter().map(|r| number(&h, r, "under_threshold_points")).collect();
    assert!(counts[0] < counts[2], "a stiffer actuator puts more of the workspace under the threshold: {counts:?}");
}

/// Physics: with rigid links (E a billion times steel's) the Orthoglide at Q0 deflects only in its
/// actuators, three orthogonal springs in series with nothing: c_tran_max = 1/k_act exactly, and with
/// real links it still falls as k_act rises.
#[test]
fn compliance_at_q0_falls_as_one_over_the_actuator_stiffness() {
    let dir = tempfile::tempdir().unwrap();
    let q0 = dir.path().join("q0.csv");
    std::fs::write(&q0, "name,x_mm,y_mm,z_mm\nQ0,0,0,0\n").unwrap();
    let vary = ["--vary", "k_act=5000:45000:5", "--points", q0.to_str().unwrap(), "-q"];
    let rigid = run_stiff(&[&["sweep", MODEL, "--set", "E=2.1e14"][..], &vary[..]].concat());
    for r in csv_columns(&rigid, &["k_act", "max_c_tran_max_mm_per_N"]) {
        let product = r[0] * r[1];
        assert!((product - 1.0).abs() < 1e-6, "k_act c_tran_max = {product} at k_act = {}", r[0]);
    }
    let real = csv_columns(&run_stiff(&[&["sweep", MODEL][..], &vary[..]].concat()), &["max_c_tran_max_mm_per_N"]);
    for pair in real.windows(2) {
        assert!(pair[1][0] < pair[0][0], "{real:?}");
    }
    // The links add compliance in series: more than 1/k_act at every design.
    assert!(real[0][0] > 1.0 / 5000.0);
}

/// A Latin hypercube is a function of its seed, and stratified: each parameter's range cut into N equal
/// strata holds exactly one design in each.
#[test]
fn latin_hypercubes_are_reproducible_and_stratified() {
    let run = |seed: &str| {
        run_stiff(&[
            "sweep",
            MODEL,
            "--vary",
            "L=280:340",
            "--vary",
            "d_leg=10:16:9",
            "--sample",
            "lhs:12",
            "--seed",
            seed,
            "--grid",
            GRID,
            "-q",
        ])
    };
    let (a, b, c) = (run("7"), run("7"), run("8"));
    assert_eq!(a, b, "same seed, same designs");
    assert_ne!(a, c, "another seed, other designs");
    let designs = csv_columns(&a, &["L", "d_leg"]);
    assert_eq!(designs.len(), 12);
    for (k, (from, to)) in [(280.0, 340.0), (10.0, 16.0)].into_iter().enumerate() {
        let mut strata: Vec<usize> =
            designs.iter().map(|d| ((d[k] - from) / (to - from) * 12.0).floor() as usize).collect();
        strata.sort();
        assert_eq!(strata, (0..12).collect::<Vec<_>>(), "parameter {k}");
    }
}

/// A design whose description cannot be built (a negative beam diameter) is a row with status `invalid`
/// and the reason; the designs around it are mapped; names come from the designs file.
#[test]
fn a_design_that_cannot_be_built_is_a_row() {
    let dir = tempfile::tempdir().unwrap();
    let designs = dir.path().join("designs.csv");
    std::fs::write(&designs, "design,d_leg,k_act\nthin,10,20000\nbroken,-3,20000\nthick,16,20000\n").unwrap();
    let out = run_stiff(&["sweep", MODEL, "--designs", designs.to_str().unwrap(), "--grid", GRID, "-q"]);
    let (h, rows) = table(&out);
    let names: Vec<&str> = rows.iter().map(|r| cell(&h, r, "design")).collect();
    assert_eq!(names, ["thin", "broken", "thick"]);
    assert_eq!(cell(&h, &rows[1], "status"), "invalid");
    assert!(cell(&h, &rows[1], "message").contains("diameter"), "{}", cell(&h, &rows[1], "message"));
    assert_eq!(cell(&h, &rows[1], "points"), "");
    for r in [&rows[0], &rows[2]] {
        assert_eq!(cell(&h, r, "status"), "ok");
        assert_eq!(number(&h, r, "points"), 125.0);
    }
}

/// Usage errors name what to fix: an unknown parameter (with the known ones), a factorial without a
/// count, --loaded without wrenches.
#[test]
fn sweep_usage_errors_say_what_to_do() {
    let fails = |args: &[&str], says: &str| {
        let o = assert_cmd::Command::cargo_bin("stiff").unwrap().args(args).output().unwrap();
        assert!(!o.status.success(), "{args:?} should fail");
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains(says), "{args:?}: {e}");
    };
    fails(&["sweep", MODEL, "--vary", "k_ac=1:2:2", "--grid", GRID], "no parameter `k_ac`");
    fails(&["sweep", MODEL, "--vary", "k_act=1:2", "--grid", GRID], "needs a count");
    fails(&["sweep", MODEL, "--vary", "k_act=1:2:0", "--grid", GRID], "COUNT");
    fails(&["sweep", MODEL, "--vary", "k_act=1:2:2", "--grid", GRID, "--threshold=-1"], "--threshold");
    fails(&["sweep", MODEL, "--vary", "k_act=1:2:2", "--sample", "mc:3", "--grid", GRID], "lhs:N");
    fails(&["sweep", MODEL, "--vary", "k_act=1:2:2", "--vary", "k_act=3:4:2", "--grid", GRID], "given twice");
}
