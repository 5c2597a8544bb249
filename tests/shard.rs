//! `--shard K/N` and `stiff merge`: the shards of a run, merged in any order, are byte for byte the file the
//! unsharded run writes, for every batch command (whose warm starts, seeds and Newton Jacobians begin
//! afresh at each run of points, so a shard cut at whole runs solves each row exactly as the whole run);
//! a merge refuses a missing, foreign or repeated shard and names it.

use std::path::{Path, PathBuf};

use assert_cmd::Command;

const MODEL: &str = "manipulators/orthoglide-3puu.toml";

fn stiff(args: &[&str]) -> std::process::Output {
    Command::cargo_bin("stiff").unwrap().args(args).output().unwrap()
}

fn ok(args: &[&str]) {
    let o = stiff(args);
    assert!(o.status.success(), "stiff {}: {}", args.join(" "), String::from_utf8_lossy(&o.stderr));
}

fn fails(args: &[&str], says: &str) {
    let o = stiff(args);
    assert_eq!(o.status.code(), Some(1), "stiff {} should fail", args.join(" "));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains(says), "stiff {}: `{e}` should say `{says}`", args.join(" "));
}

/// Runs `command` whole into `dir/whole.EXT` and in `n` shards, merges them (listed last shard first)
/// into `dir/merged.EXT`; returns (whole, merged, shard files).
fn whole_and_merged(dir: &Path, command: &[&str], n: usize, ext: &str) -> (Vec<u8>, Vec<u8>, Vec<PathBuf>) {
    let whole = dir.join(format!("whole.{ext}"));
    ok(&[command, &["-q", "-o", whole.to_str().unwrap()]].concat());
    let mut shards = Vec::new();
    for k in 1..=n {
        let file = dir.join(format!("shard{k}.csv"));
        let shard = format!("{k}/{n}");
        ok(&[command, &["-q", "--shard", &shard, "-o", file.to_str().unwrap(), "--threads", "1"]].concat());
        shards.push(file);
    }
    let merged = dir.join(format!("merged.{ext}"));
    let mut args = vec!["merge".to_string(), merged.display().to_string()];
    args.extend(shards.iter().rev().map(|s| s.display().to_string()));
    ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    (std::fs::read(whole).unwrap(), std::fs::read(merged).unwrap(), shards)
}

/// A points file of `n` poses along a line through the Orthoglide's workspace (several runs of 256).
fn points_file(dir: &Path, n: usize) -> String {
    let mut text = String::from("x_mm,y_mm,z_mm\n");
    for i in 0..n {
        let t = i as f64 / (n - 1) as f64;
        text.push_str(&format!("{},{},{}\n", -60.0 + 120.0 * t, 40.0 - 80.0 * t, 30.0 * (6.0 * t).sin()));
    }
    let path = dir.join("points.csv");
    std::fs::write(&path, text).unwrap();
    path.display().to_string()
}

#[test]
fn merged_shards_of_a_map_are_the_whole_map() {
    let dir = tempfile::tempdir().unwrap();
    let points = points_file(dir.path(), 700);
    // Loaded: each row warm-starts from the previous ones of its run, so a cut off a run boundary would show.
    let command = ["map", MODEL, "--points", &points, "--wrench", "215,-10,-25,1000,21500,0"];
    let (whole, merged, shards) = whole_and_merged(dir.path(), &command, 3, "csv");
    assert_eq!(whole, merged);
    // 700 points are 3 runs of 256: one run per shard, each row with its global index.
    let first_index = |s: &PathBuf| {
        let text = std::fs::read_to_string(s).unwrap();
        text.lines().filter(|l| !l.starts_with('#')).nth(1).map(|l| l.split(',').next().unwrap().to_string())
    };
    let firsts: Vec<Option<String>> = shards.iter().map(first_index).collect();
    assert_eq!(firsts, [Some("0".to_string()), Some("256".to_string()), Some("512".to_string())]);
    // Typed and compressed outputs: the merge writes what -o writes.
    for ext in ["csv.gz", "parquet"] {
        let (whole, merged, _) = whole_and_merged(dir.path(), &command, 2, ext);
        assert_eq!(whole, merged, "{ext}");
    }
}

#[test]
fn merged_shards_of_assemble_compensate_synth_and_sweep_are_the_whole_runs() {
    let dir = tempfile::tempdir().unwrap();
    let errors = ["--errors", "manipulators/errors/orthoglide-case-b.toml"];
    let wrench = ["--wrench", "215,-10,-25,1000,21500,0"];
    let path = ["--path", "-73.65,-73.65,-73.65", "-73.65,126.35,-73.65", "600"];
    let long_path = ["--path", "-73.65,-73.65,-73.65", "-73.65,126.35,-73.65", "2100"];
    let points = points_file(dir.path(), 700);
    let runs: Vec<Vec<&str>> = vec![
        [&["assemble", MODEL][..], &errors, &path, &wrench].concat(),
        [&["assemble", MODEL][..], &errors, &["--grid", "manipulators/grids/orthoglide-small.toml", "--samples", "20"]]
            .concat(),
        // Past one run of the compensation's longer runs (`COMPENSATE_RUN`, 2,048 targets).
        [&["compensate", MODEL][..], &errors, &long_path, &wrench].concat(),
        vec![
            "synth",
            MODEL,
            "--points",
            &points,
            "--effect",
            "tool-offset=0.05,0,0",
            "--wrenches",
            "200,0,0,0,0,0;0,200,0,0,0,0",
            "--noise",
            "0.002",
            "--seed",
            "7",
        ],
        vec![
            "sweep",
            MODEL,
            "--vary",
            "k_act=10000:40000:4",
            "--vary",
            "d_leg=10:16:2",
            "--grid",
            "manipulators/grids/orthoglide-small.toml",
        ],
    ];
    for command in runs {
        let (whole, merged, _) = whole_and_merged(dir.path(), &command, 3, "csv");
        assert_eq!(String::from_utf8(whole).unwrap(), String::from_utf8(merged).unwrap(), "{command:?}");
    }
}

#[test]
fn a_merge_refuses_missing_foreign_and_repeated_shards() {
    let dir = tempfile::tempdir().unwrap();
    let d = |name: &str| dir.path().join(name).display().to_string();
    let grid = ["--grid", "manipulators/grids/orthoglide-small.toml", "-q"];
    for k in 1..=3 {
        ok(&[&["map", MODEL][..], &grid, &["--shard", &format!("{k}/3"), "-o", &d(&format!("s{k}.csv"))]].concat());
    }
    // Another run: the same command with another actuator stiffness.
    ok(&[&["map", MODEL, "--set", "k_act=1000"][..], &grid, &["--shard", "2/3", "-o", &d("other2.csv")]].concat());
    let out = d("out.csv");
    fails(&["merge", &out, &d("s1.csv"), &d("s3.csv")], "shard 2 of 3 is missing");
    fails(&["merge", &out, &d("s1.csv"), &d("other2.csv"), &d("s3.csv")], "other2.csv");
    fails(&["merge", &out, &d("s1.csv"), &d("s2.csv"), &d("s2.csv"), &d("s3.csv")], "shard 2/3 is given twice");
    fails(&["merge", &out, MODEL], "not a shard file");
    assert!(!Path::new(&out).exists(), "a refused merge writes nothing");
    let missing = stiff(&["merge", "--missing", &out, &d("s2.csv")]);
    assert_eq!(String::from_utf8_lossy(&missing.stdout), "1,3\n");
    // What a shard cannot do, said before any work.
    fails(&[&["map", MODEL][..], &grid, &["--shard", "1/2", "-o", &d("s.parquet")]].concat(), "CSV");
    fails(
        &[&["map", MODEL][..], &grid, &["--shard", "1/2", "-o", &d("s.csv"), "--plot", &d("s.svg")]].concat(),
        "--plot",
    );
    let usage = stiff(&[&["map", MODEL][..], &grid, &["--shard", "3/2"]].concat());
    assert_eq!(usage.status.code(), Some(2), "K > N is a usage error");
}

/// Regression: the merge held every shard file open at once, so a run of more shards than the process may
/// open files (the usual limit is 1,024) could not be merged. Under a limit of 64 open files, 300 shards of
/// a one-point map (the last holds the point's run, the others are empty, as `--shard K/300` writes them)
/// merge into the whole map.
#[test]
fn a_merge_opens_one_shard_at_a_time() {
    let dir = tempfile::tempdir().unwrap();
    let d = |name: &str| dir.path().join(name).display().to_string();
    std::fs::write(d("one.csv"), "x_mm,y_mm,z_mm\n10,-5,20\n").unwrap();
    let map = ["map", MODEL, "--points", &d("one.csv"), "-q"];
    ok(&[&map[..], &["-o", &d("whole.csv")]].concat());
    ok(&[&map[..], &["--shard", "300/300", "-o", &d("s300.csv")]].concat());
    let last = std::fs::read_to_string(d("s300.csv")).unwrap();
    let header_start = last.find("\nindex,").unwrap() + 1;
    let header_end = header_start + last[header_start..].find('\n').unwrap() + 1;
    let mut files = Vec::new();
    for k in 1..300 {
        let empty = last[..header_end].replacen("shard 300/300", &format!("shard {k}/300"), 1);
        std::fs::write(d(&format!("s{k}.csv")), empty).unwrap();
        files.push(d(&format!("s{k}.csv")));
    }
    files.push(d("s300.csv"));
    let bin = assert_cmd::cargo::cargo_bin("stiff");
    let script = format!("ulimit -n 64 && exec \"{}\" merge \"{}\" \"$@\"", bin.display(), d("merged.csv"));
    let o = std::process::Command::new("sh").arg("-c").arg(&script).arg("sh").args(&files).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read(d("merged.csv")).unwrap(), std::fs::read(d("whole.csv")).unwrap());
}
