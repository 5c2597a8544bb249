//! The command line as a newcomer meets it: help with worked examples that run, options that apply,
//! `--version` with its commit, `-` for standard input, exit statuses that say what happened.

use std::path::Path;

use assert_cmd::Command;

fn stiff() -> Command {
    Command::cargo_bin("stiff").unwrap()
}

const COMMANDS: [&str; 11] =
    ["map", "point", "curve", "assemble", "compensate", "diagnose", "synth", "plan", "plot", "sweep", "merge"];

/// Every cell of the selected table (`some`, a header row then data rows) equals the full table's cell of
/// the same column and row.
fn assert_same_cells(full: &[Vec<String>], some: &[Vec<String>]) {
    assert_eq!(full.len(), some.len(), "same rows");
    for (row_full, row_some) in full.iter().zip(some).skip(1) {
        for (k, name) in some[0].iter().enumerate() {
            let j = full[0].iter().position(|h| h == name).unwrap();
            assert_eq!(row_some[k], row_full[j], "{name}");
        }
    }
}

/// Splits an example line into arguments (double quotes group, as a shell would).
fn shell_words(line: &str) -> Vec<String> {
    let mut words = Vec::new();
    let (mut current, mut quoted) = (String::new(), false);
    for c in line.chars() {
        match c {
            '"' => quoted = !quoted,
            ' ' if !quoted => {
                if !current.is_empty() {
                    words.push(std::mem::take(&mut current));
                }
            }
            _ => current.push(c),
        }
    }
    if !current.is_empty() {
        words.push(current);
    }
    words
}

/// Runs `examples` (lines starting with `stiff `) in order, as printed, on the shipped files; files they write
/// go to `dir` (an example may read what the one before it wrote). Returns how many ran.
fn run_examples(examples: &[&str], dir: &Path) -> usize {
    for example in examples {
        let words = shell_words(example);
        let args: Vec<String> = words[1..]
            .iter()
            .map(|w| {
                let written = [".csv", ".svg", ".json", ".toml", "/"].iter().any(|e| w.ends_with(e));
                if written && !Path::new(w).exists() {
                    dir.join(w).display().to_string()
                } else {
                    w.clone()
                }
            })
            .collect();
        let out = stiff().args(&args).output().unwrap();
        let expected_failure = example.contains("--fail-on");
        assert!(
            out.status.success() || expected_failure,
            "`{example}` failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    examples.len()
}

/// Every example printed by a command's `--help` runs as printed, on the shipped files, in order (an
/// example may read what the one before it wrote). Files the examples write go to a temporary folder.
#[test]
fn every_help_example_runs() {
    let dir = tempfile::tempdir().unwrap();
    let mut ran = 0;
    for command in COMMANDS {
        let help = stiff().args([command, "--help"]).output().unwrap();
        let help = String::from_utf8(help.stdout).unwrap();
        let examples: Vec<&str> = help.lines().map(str::trim).filter(|l| l.starts_with("stiff ")).collect();
        assert!(!examples.is_empty(), "`stiff {command} --help` shows examples");
        ran += run_examples(&examples, dir.path());
    }
    assert!(ran >= 14, "{ran} examples");
}

/// README's five-minute tour runs as printed, and what it says the diagnosis finds is what it finds.
#[test]
fn the_readme_tour_runs_as_printed() {
    let readme = std::fs::read_to_string("README.md").unwrap();
    let tour = &readme[readme.find("## A five-minute tour").expect("README has a tour")..];
    let block = tour.split("```").nth(1).expect("the tour's commands in a code block");
    let examples: Vec<&str> = block.lines().map(str::trim).filter(|l| l.starts_with("stiff ")).collect();
    let dir = tempfile::tempdir().unwrap();
    assert_eq!(run_examples(&examples, dir.path()), 6);
    for picture in ["cube.svg", "curve.svg", "verdict.svg"] {
        assert!(dir.path().join(picture).exists(), "{picture}");
    }
    let last = shell_words(examples[4]);
    let args: Vec<String> = last[1..]
        .iter()
        .map(|w| if w.ends_with(".csv") { dir.path().join(w).display().to_string() } else { w.clone() })
        .collect();
    let report = String::from_utf8(stiff().args(&args[..4]).output().unwrap().stdout).unwrap();
    assert!(report.contains("verdict: effect") && report.contains("actuator-compliance:2"), "{report}");
}

/// A default is printed once, by clap (`[default: ...]`), not also in the option's text.
#[test]
fn defaults_are_printed_once() {
    for command in COMMANDS {
        let help = String::from_utf8(stiff().args([command, "--help"]).output().unwrap().stdout).unwrap();
        for line in help.lines().filter(|l| l.contains("[default:")) {
            assert!(!line.contains("(default"), "`stiff {command} --help`: default printed twice: {line}");
        }
    }
}

/// The top-level description names every command.
#[test]
fn the_description_names_every_command() {
    let help = String::from_utf8(stiff().arg("--help").output().unwrap().stdout).unwrap();
    let about = help.lines().next().unwrap();
    for word in ["maps", "pose", "curves", "assembly", "compensation", "diagnosis", "synthetic", "plans", "pictures"] {
        assert!(about.contains(word), "`{about}` names {word}");
    }
}

/// An option that does not apply to a command is refused (the curve's `--direction` on a map).
#[test]
fn options_that_do_not_apply_are_refused() {
    let out = stiff()
        .args(["map", "manipulators/orthoglide-3puu.toml", "--grid", "manipulators/grids/orthoglide-small.toml"])
        .args(["--direction", "x"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "a usage error");
    assert!(String::from_utf8_lossy(&out.stderr).contains("--direction"));
}

/// `--version` prints the version and the commit the binary was built from ("unknown" outside a checkout).
#[test]
fn version_names_the_commit() {
    let out = String::from_utf8(stiff().arg("--version").output().unwrap().stdout).unwrap();
    let (name, rest) = out.trim().split_once(' ').unwrap();
    assert_eq!(name, "stiff");
    assert!(rest.starts_with(env!("CARGO_PKG_VERSION")), "{out}");
    let commit = rest.split_once('(').and_then(|(_, c)| c.strip_suffix(')')).expect("(commit)");
    let hex = commit.trim_end_matches("-modified");
    assert!(hex == "unknown" || (hex.len() == 12 && hex.chars().all(|c| c.is_ascii_hexdigit())), "{commit}");
}

/// The build script that records the commit leaves the git index it watches as it found it: in a fresh
/// clone a plain `git status` rewrites .git/index (it refreshes the entries' file times), so README's second
/// command ran the script again and compiled the whole crate a second time (about 90 CPU s). The script, run
/// in a fresh clone of a one-commit repository, must leave the index's bytes and modification time alone,
/// and still name the commit.
#[test]
fn the_build_script_leaves_the_git_index_it_watches_untouched() {
    let git = |dir: &Path, args: &[&str]| {
        let ok =
            std::process::Command::new("git").args(args).current_dir(dir).output().is_ok_and(|o| o.status.success());
        assert!(ok, "git {}", args.join(" "));
    };
    if std::process::Command::new("git").arg("--version").output().is_err() {
        eprintln!("git is not installed: the build script names no commit, and watches no index");
        return;
    }
    // The build script compiled last beside this test binary (target/<profile>/build/stiff-*/
    // build-script-build; older ones are earlier versions of build.rs, kept by the build cache).
    let profile_dir = std::env::current_exe().unwrap().parent().unwrap().parent().unwrap().to_path_buf();
    let script = std::fs::read_dir(profile_dir.join("build"))
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path().join("build-script-build")))
        .filter(|p| p.parent().unwrap().file_name().unwrap().to_string_lossy().starts_with("stiff-"))
        .filter_map(|p| Some((std::fs::metadata(&p).ok()?.modified().ok()?, p)))
        .max()
        .map(|(_, p)| p)
        .unwrap_or_else(|| panic!("no build script under {}", profile_dir.display()));
    let scripts = [script];
    let dir = tempfile::tempdir().unwrap();
    let origin = dir.path().join("origin");
    std::fs::create_dir(&origin).unwrap();
    std::fs::write(origin.join("a.txt"), "a\n").unwrap();
    git(&origin, &["init", "-q"]);
    git(&origin, &["add", "a.txt"]);
    git(&origin, &["-c", "user.name=stiff", "-c", "user.email=stiff@localhost", "commit", "-q", "-m", "a"]);
    for (k, script) in scripts.iter().enumerate() {
        let clone = dir.path().join(format!("clone{k}"));
        git(dir.path(), &["clone", "-q", "origin", clone.to_str().unwrap()]);
        let index = clone.join(".git/index");
        let before = (std::fs::read(&index).unwrap(), std::fs::metadata(&index).unwrap().modified().unwrap());
        let out = std::process::Command::new(script).current_dir(&clone).output().unwrap();
        let printed = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success() && printed.contains("STIFF_GIT_COMMIT="), "{printed}");
        assert!(!printed.contains("STIFF_GIT_COMMIT=unknown"), "the clone's commit is named: {printed}");
        let after = (std::fs::read(&index).unwrap(), std::fs::metadata(&index).unwrap().modified().unwrap());
        assert!(before == after, "{} rewrote the clone's .git/index", script.display());
    }
}

/// `-` reads standard input: a points file, a grid, measurements, a study's output to draw.
#[test]
fn a_dash_reads_standard_input() {
    let points = std::fs::read("manipulators/grids/stewart-gough-home.csv").unwrap();
    let from_stdin = stiff()
        .args(["map", "manipulators/stewart-gough-b.toml", "--points", "-", "-q"])
        .write_stdin(points)
        .output()
        .unwrap();
    let from_file = stiff()
        .args([
            "map",
            "manipulators/stewart-gough-b.toml",
            "--points",
            "manipulators/grids/stewart-gough-home.csv",
            "-q",
        ])
        .output()
        .unwrap();
    assert!(from_stdin.status.success());
    assert_eq!(from_stdin.stdout, from_file.stdout);

    let grid = std::fs::read("manipulators/grids/orthoglide-small.toml").unwrap();
    let map = stiff()
        .args(["map", "manipulators/orthoglide-3puu.toml", "--grid", "-", "-q"])
        .write_stdin(grid)
        .output()
        .unwrap();
    assert!(map.status.success());
    let dir = tempfile::tempdir().unwrap();
    let svg = dir.path().join("m.svg");
    stiff().args(["plot", "-", "-o"]).arg(&svg).write_stdin(map.stdout.clone()).assert().success();
    assert!(std::fs::read_to_string(&svg).unwrap().contains("<svg"));

    let data = stiff()
        .args(["synth", "manipulators/orthoglide-3puu.toml", "--grid", "manipulators/grids/orthoglide-small.toml"])
        .args(["--wrenches", "200,0,0,0,0,0;0,0,-200,0,0,0", "--noise", "0.002", "--seed", "1", "-q"])
        .output()
        .unwrap();
    let verdict = stiff()
        .args(["diagnose", "manipulators/orthoglide-3puu.toml", "--data", "-"])
        .write_stdin(data.stdout)
        .output()
        .unwrap();
    assert!(verdict.status.success(), "{}", String::from_utf8_lossy(&verdict.stderr));
    assert!(String::from_utf8_lossy(&verdict.stdout).contains("verdict"));
}

/// Null data diagnoses as none (exit 0 with `--fail-on effect`); data with a hidden effect fails the gate
/// (exit 1, after the report), and passes `--fail-on unexplained` once the effect is named.
#[test]
fn fail_on_turns_the_verdict_into_the_exit_status() {
    let dir = tempfile::tempdir().unwrap();
    let synth = |effect: Option<&str>, name: &str| {
        let path = dir.path().join(name);
        let mut cmd = stiff();
        cmd.args(["synth", "manipulators/orthoglide-3puu.toml", "--grid", "manipulators/grids/orthoglide-small.toml"])
            .args(["--wrenches", "200,0,0,0,0,0;0,200,0,0,0,0;0,0,-200,0,0,0", "--noise", "0.002", "--seed", "3"])
            .args(["-q", "-o"])
            .arg(&path);
        if let Some(e) = effect {
            cmd.args(["--effect", e]);
        }
        cmd.assert().success();
        path
    };
    let null = synth(None, "null.csv");
    let hidden = synth(Some("actuator-compliance:2=1.5"), "hidden.csv");
    let diagnose = |data: &Path, gate: &str| {
        stiff()
            .args(["diagnose", "manipulators/orthoglide-3puu.toml", "--data"])
            .arg(data)
            .args(["--fail-on", gate])
            .output()
            .unwrap()
    };
    assert_eq!(diagnose(&null, "effect").status.code(), Some(0));
    let gated = diagnose(&hidden, "effect");
    assert_eq!(gated.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&gated.stdout).contains("actuator-compliance:2"), "the report is written first");
    assert!(String::from_utf8_lossy(&gated.stderr).contains("verdict `effect`"));
    assert_eq!(diagnose(&hidden, "unexplained").status.code(), Some(0), "the effect is named, nothing unexplained");
}

/// `stiff point` exits 1 where the pose has no compliance and says why; a singular pose's free directions
/// are described: Stewart-Gough A at home turns freely about any axis through the point where its six leg
/// lines meet, (0, 0, h R / (R - r)) = (0, 0, 500) mm for R = 200, r = 80, h = 300 (paper 002 eq 10).
#[test]
fn point_exits_nonzero_where_the_pose_has_no_compliance() {
    let ok = stiff().args(["point", "manipulators/orthoglide-3puu.toml", "--at", "0,0,0"]).output().unwrap();
    assert_eq!(ok.status.code(), Some(0));

    let far = stiff().args(["point", "manipulators/orthoglide-3puu.toml", "--at", "900,0,0"]).output().unwrap();
    assert_eq!(far.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&far.stdout).contains("why: leg"), "the reason is in the report");
    assert!(String::from_utf8_lossy(&far.stderr).contains("unreachable"));

    let singular = stiff().args(["point", "manipulators/stewart-gough-a.toml", "--at", "0,0,300"]).output().unwrap();
    assert_eq!(singular.status.code(), Some(1));
    let report = String::from_utf8_lossy(&singular.stdout);
    assert!(report.contains("free rotations about any axis through (0.0000, 0.0000, 500.0000) mm"), "{report}");
}

/// One word, one meaning: a grid's `points` and `--path FROM TO POINTS` count points, `curve --intervals`
/// counts intervals (intervals + 1 rows). The former names (`steps` in a grid, `curve --steps`) are still
/// read and give the same bytes.
#[test]
fn points_and_intervals_are_named_for_what_they_count() {
    let dir = tempfile::tempdir().unwrap();
    let mut maps = Vec::new();
    for key in ["points", "steps"] {
        let grid = dir.path().join(format!("{key}.toml"));
        std::fs::write(&grid, format!("[box]\nfrom = [-20, -20, 0]\nto = [20, 20, 0]\n{key} = [3, 2, 1]\n")).unwrap();
        let out =
            stiff().args(["map", "manipulators/orthoglide-3puu.toml", "--grid"]).arg(&grid).arg("-q").output().unwrap();
        assert!(out.status.success());
        maps.push(out.stdout);
    }
    assert_eq!(maps[0], maps[1]);
    assert_eq!(String::from_utf8_lossy(&maps[0]).lines().count(), 1 + 3 * 2, "3 x 2 x 1 points");
    let mut curves = Vec::new();
    for flag in ["--intervals", "--steps"] {
        let out = stiff()
            .args(["curve", "manipulators/orthoglide-3puu.toml", "--at", "0,0,0", "--wrench-direction", "0,0,-1,0,0,0"])
            .args(["--max", "100", flag, "4", "-q"])
            .output()
            .unwrap();
        assert!(out.status.success());
        curves.push(out.stdout);
    }
    assert_eq!(curves[0], curves[1]);
    assert_eq!(String::from_utf8_lossy(&curves[0]).lines().count(), 1 + 5, "4 intervals, 5 rows");
    let path = stiff()
        .args([
            "assemble",
            "manipulators/orthoglide-3puu.toml",
            "--errors",
            "manipulators/errors/orthoglide-case-a.toml",
        ])
        .args(["--path", "0,0,0", "10,0,0", "4", "-q"])
        .output()
        .unwrap();
    assert_eq!(String::from_utf8_lossy(&path.stdout).lines().count(), 1 + 4, "a path of 4 points");
    let help = String::from_utf8(stiff().args(["assemble", "--help"]).output().unwrap().stdout).unwrap();
    assert!(help.contains("--path <FROM> <TO> <POINTS>"), "{help}");
}

/// A loaded map keeps the unloaded map's columns in their places and appends what loading adds: the lower
/// triangles of the (non-symmetric) tangent compliance and stiffness, then the Newton iterations.
#[test]
fn loaded_maps_append_their_extra_columns() {
    let header = |extra: &[&str]| {
        let out = stiff()
            .args(["map", "manipulators/orthoglide-3puu.toml", "--grid", "manipulators/grids/orthoglide-small.toml"])
            .args(["--stiffness", "-q"])
            .args(extra)
            .output()
            .unwrap();
        assert!(out.status.success());
        String::from_utf8(out.stdout).unwrap().lines().next().unwrap().split(',').map(String::from).collect::<Vec<_>>()
    };
    let unloaded = header(&[]);
    let loaded = header(&["--loaded"]);
    assert_eq!(loaded[..unloaded.len()], unloaded[..], "the unloaded columns first, in order");
    let extra = &loaded[unloaded.len()..];
    assert_eq!(extra.len(), 15 + 15 + 1);
    assert_eq!(extra[0], "C21_mm_per_N");
    assert_eq!(extra[15], "K21_N_per_mm");
    assert_eq!(extra[30], "iterations");
}

/// Shell completions and the manual page come from the same definitions as `--help`: every command is in
/// them.
#[test]
fn completions_and_man_page_list_every_command() {
    let bash = String::from_utf8(stiff().args(["completions", "bash"]).output().unwrap().stdout).unwrap();
    let zsh = String::from_utf8(stiff().args(["completions", "zsh"]).output().unwrap().stdout).unwrap();
    let man = String::from_utf8(stiff().arg("man").output().unwrap().stdout).unwrap();
    assert!(man.contains(".TH stiff 1"), "{}", &man[..200.min(man.len())]);
    for command in COMMANDS {
        assert!(bash.contains(command) && zsh.contains(command) && man.contains(command), "{command}");
    }
    assert!(bash.contains("--intervals") && bash.contains("--fail-on"));
    assert_eq!(stiff().args(["completions", "cmd.exe"]).output().unwrap().status.code(), Some(2));
}

/// Under force control a row's wrench is load_factor * W exactly: components that are zero in W are written
/// as 0.0 in every row (no round-off, no -0.0), and the others are the load factor times W's.
#[test]
fn curve_wrenches_are_exact_multiples_of_the_direction() {
    let out = stiff()
        .args(["curve", "manipulators/orthoglide-3puu.toml", "--at", "0,0,0", "--wrench-direction", "0,0,-1000,0,0,0"])
        .args(["--max", "5", "--intervals", "4", "-q"])
        .output()
        .unwrap();
    let text = String::from_utf8(out.stdout).unwrap();
    for line in text.lines().skip(1) {
        let cells: Vec<&str> = line.split(',').collect();
        let factor: f64 = cells[2].parse().unwrap();
        for (k, cell) in cells[3..9].iter().enumerate() {
            let expected = if k == 2 { -1000.0 * factor } else { 0.0 };
            assert_eq!(cell.parse::<f64>().unwrap(), expected, "{line}");
        }
        assert!(!cells.contains(&"-0.0"), "{line}");
    }
}

/// `stiff point --json` holds the report's content for programs: C K = I on an ok pose (unloaded, and
/// loaded where the tangent matrices are not symmetric), the loaded displacement, and for a singular pose
/// its status, rank and free motions; written to `-o FILE` as well as stdout.
#[test]
fn point_json_holds_the_report() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("q0.json");
    stiff()
        .args(["point", "manipulators/orthoglide-3puu.toml", "--at", "0,0,0", "--wrench", "215,-10,-25,1000,21500,0"])
        .args(["--json", "-o"])
        .arg(&file)
        .assert()
        .success();
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
    for part in ["unloaded", "loaded"] {
        let r = &v[part];
        assert_eq!(r["status"], "ok");
        let m = |key: &str| nalgebra::Matrix6::<f64>::from_fn(|i, j| r[key][i][j].as_f64().unwrap());
        let product = m("compliance") * m("stiffness");
        assert!((product - nalgebra::Matrix6::identity()).abs().max() < 1e-9, "{part}: C K = {product}");
    }
    assert!(v["loaded"]["deflection"][0].as_f64().unwrap().abs() > 0.0);
    let singular =
        stiff().args(["point", "manipulators/stewart-gough-a.toml", "--at", "0,0,300", "--json"]).output().unwrap();
    assert_eq!(singular.status.code(), Some(1));
    let v: serde_json::Value = serde_json::from_slice(&singular.stdout).unwrap();
    assert_eq!(v["unloaded"]["status"], "singular");
    assert_eq!(v["unloaded"]["rank"], 3);
    assert_eq!(v["unloaded"]["free_directions"].as_array().unwrap().len(), 3);
    assert!(v["unloaded"]["free_motions"][0].as_str().unwrap().contains("(0.0000, 0.0000, 500.0000) mm"));
}

/// The output's name chooses its encoding: a shipped map written as `.csv`, `.csv.gz` and `.csv.zst` holds
/// the same bytes once decompressed (by the reference decoders, not ours), and stiff reads the compressed
/// files back (a points file, a picture).
#[test]
fn compressed_outputs_hold_the_same_table() {
    use std::io::Read;
    let dir = tempfile::tempdir().unwrap();
    let mut tables = Vec::new();
    for name in ["m.csv", "m.csv.gz", "m.csv.zst"] {
        let path = dir.path().join(name);
        stiff()
            .args(["map", "manipulators/orthoglide-3puu.toml", "--grid", "manipulators/grids/orthoglide-small.toml"])
            .args(["--stiffness", "-q", "-o"])
            .arg(&path)
            .assert()
            .success();
        let bytes = std::fs::read(&path).unwrap();
        let mut text = String::new();
        match name {
            "m.csv.gz" => {
                flate2::read::GzDecoder::new(&bytes[..]).read_to_string(&mut text).unwrap();
            }
            "m.csv.zst" => {
                zstd::Decoder::new(&bytes[..]).unwrap().read_to_string(&mut text).unwrap();
            }
            _ => text = String::from_utf8(bytes.clone()).unwrap(),
        }
        if name != "m.csv" {
            assert!(bytes.len() * 2 < text.len(), "{name} is compressed ({} of {} bytes)", bytes.len(), text.len());
        }
        tables.push(text);
    }
    assert_eq!(tables[0], tables[1]);
    assert_eq!(tables[0], tables[2]);
    let again = stiff()
        .args(["map", "manipulators/orthoglide-3puu.toml", "--points"])
        .arg(dir.path().join("m.csv.zst"))
        .arg("-q")
        .output()
        .unwrap();
    assert!(again.status.success());
    assert_eq!(String::from_utf8_lossy(&again.stdout).lines().count(), tables[0].lines().count());
    let svg = dir.path().join("m.svg");
    stiff().args(["plot"]).arg(dir.path().join("m.csv.gz")).arg("-o").arg(&svg).assert().success();
}

/// A Parquet output holds the CSV table's values: the same columns in the same order, every number bit for
/// bit (read by stiff's reader, which reads pyarrow's files bit for bit: `parquet.rs`), counts as unsigned
/// integers (Arrow's uint64), texts (a name holding a comma and quotes) as texts, empty cells as nulls, and
/// each column's unit, the suffix of its name, in the field metadata of the Arrow schema Arrow readers take
/// (`ARROW:schema`, decoded here by `arrow_fields` from Arrow's format). A picture drawn from the Parquet
/// file is the picture drawn from the CSV.
#[test]
fn a_parquet_map_holds_the_csv_values_with_their_units() {
    let dir = tempfile::tempdir().unwrap();
    let points = dir.path().join("p.csv");
    let rows = "name,x_mm,y_mm,z_mm,Fx_N,Fy_N,Fz_N,Mx_Nmm,My_Nmm,Mz_Nmm\n\"a,\"\"b\"\"\",0,0,0,100,0,0,0,0,0\n\
                far,900,0,0,100,0,0,0,0,0\nc,10,-20,5,-50,20,0,0,0,1000\n";
    std::fs::write(&points, rows).unwrap();
    let write = |name: &str| {
        let path = dir.path().join(name);
        stiff()
            .args(["map", "manipulators/orthoglide-3puu.toml", "--stiffness", "--loaded", "-q", "--points"])
            .arg(&points)
            .arg("-o")
            .arg(&path)
            .assert()
            .success();
        path
    };
    let csv_path = write("m.csv");
    let gz_path = write("m.csv.gz");
    let parquet_path = write("m.parquet");
    let mut reader = csv::Reader::from_path(&csv_path).unwrap();
    let header: Vec<String> = reader.headers().unwrap().iter().map(String::from).collect();
    let rows: Vec<Vec<String>> = reader.records().map(|r| r.unwrap().iter().map(String::from).collect()).collect();
    let gz = csv::Reader::from_reader(flate2::read::GzDecoder::new(std::fs::File::open(&gz_path).unwrap()))
        .into_records()
        .map(|r| r.unwrap().iter().map(String::from).collect::<Vec<_>>())
        .collect::<Vec<_>>();
    assert_eq!(gz, rows, "the .csv.gz table is the CSV table");
    assert_eq!(rows[0][1], "a,\"b\"", "the quoted name read back by the csv crate");
    assert!(rows[1].iter().any(String::is_empty), "the unreachable point has empty cells");

    crate::parquet::assert_columns_are_csv(&parquet_path, &csv_path);
    let fields = arrow_fields(&crate::parquet::footer_value(&parquet_path, "ARROW:schema"));
    assert_eq!(fields.iter().map(|f| f.name.as_str()).collect::<Vec<_>>(), header);
    let units = ["mm_per_Nmm", "mm_per_N", "rad_per_Nmm", "rad_per_N", "N_per_mm", "N_per_rad", "Nmm_per_mm"];
    for field in &fields {
        let name = &field.name;
        let expected = units
            .iter()
            .chain(&["Nmm_per_rad", "mm", "rad", "Nmm", "N"])
            .find(|u| name.ends_with(&format!("_{u}")))
            .copied();
        assert_eq!(field.unit.as_deref(), expected, "{name}");
        assert!(field.nullable, "{name}");
    }
    let arrow_type = |name: &str| fields.iter().find(|f| f.name == name).unwrap().type_code;
    // Arrow's Type union: Int 2 (here 64 bits, unsigned), FloatingPoint 3 (double), Utf8 5.
    assert_eq!(arrow_type("iterations"), (2, Some(64), Some(false)));
    assert_eq!(arrow_type("status"), (5, None, None));
    assert_eq!(arrow_type("C21_mm_per_N"), (3, Some(2), None));
    assert!(header.iter().any(|h| h == "iterations") && header.iter().any(|h| h == "C21_mm_per_N"));

    let picture = |table: &Path, svg: &str| {
        let svg = dir.path().join(svg);
        stiff().arg("plot").arg(table).arg("-o").arg(&svg).assert().success();
        std::fs::read_to_string(svg).unwrap()
    };
    assert_eq!(picture(&parquet_path, "p.svg"), picture(&csv_path, "c.svg"));
}

/// One field of an Arrow schema: its name, nullability, type (union member, then bit width or precision,
/// then signedness where the type has them) and `unit` metadata.
struct ArrowField {
    name: String,
    nullable: bool,
    type_code: (u8, Option<i32>, Option<bool>),
    unit: Option<String>,
}

/// The fields of an `ARROW:schema` value, read as Arrow's format defines it: base64 of an IPC message
/// (0xFFFFFFFF, the flatbuffer's length, the flatbuffer) whose root `Message` (header slot 2) is a `Schema`
/// (fields slot 1) of `Field` tables (name 0, nullable 1, type_type 2, type 3, children 5, custom_metadata 6).
fn arrow_fields(encoded: &str) -> Vec<ArrowField> {
    let alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let sextets: Vec<u32> =
        encoded.trim_end_matches('=').chars().map(|c| alphabet.find(c).expect("base64") as u32).collect();
    let mut bytes = Vec::new();
    for chunk in sextets.chunks(4) {
        let n = chunk.iter().enumerate().fold(0u32, |n, (k, s)| n | s << (18 - 6 * k));
        bytes.extend(n.to_be_bytes()[1..chunk.len()].iter().copied());
    }
    assert_eq!(&bytes[..4], &[0xFF; 4], "continuation marker");
    let length = u32::from_le_bytes(bytes[4..8].try_into().unwrap()) as usize;
    let fb = &bytes[8..8 + length];
    let u32_at = |at: usize| u32::from_le_bytes(fb[at..at + 4].try_into().unwrap()) as usize;
    let deref = |at: usize| at + u32_at(at);
    // The position of a table's field `slot`, if present.
    let slot = |table: usize, slot: usize| -> Option<usize> {
        let vtable = (table as i64 - i32::from_le_bytes(fb[table..table + 4].try_into().unwrap()) as i64) as usize;
        let vtable_size = u16::from_le_bytes(fb[vtable..vtable + 2].try_into().unwrap()) as usize;
        let entry = 4 + 2 * slot;
        if entry >= vtable_size {
            return None;
        }
        let offset = u16::from_le_bytes(fb[vtable + entry..vtable + entry + 2].try_into().unwrap()) as usize;
        (offset != 0).then_some(table + offset)
    };
    let string = |at: usize| {
        let s = deref(at);
        String::from_utf8(fb[s + 4..s + 4 + u32_at(s)].to_vec()).unwrap()
    };
    let vector = |at: usize| {
        let v = deref(at);
        (0..u32_at(v)).map(move |k| deref(v + 4 + 4 * k)).collect::<Vec<_>>()
    };
    let message = deref(0);
    assert_eq!(fb[slot(message, 1).unwrap()], 1, "a Schema message");
    let schema = deref(slot(message, 2).unwrap());
    vector(slot(schema, 1).unwrap())
        .into_iter()
        .map(|field| {
            let type_type = fb[slot(field, 2).unwrap()];
            let type_table = deref(slot(field, 3).unwrap());
            let int_at = |s| slot(type_table, s).map(|at| i32::from_le_bytes(fb[at..at + 4].try_into().unwrap()));
            let type_code = match type_type {
                2 => (2, int_at(0), Some(slot(type_table, 1).is_some_and(|at| fb[at] != 0))),
                3 => (3, slot(type_table, 0).map(|at| i16::from_le_bytes([fb[at], fb[at + 1]]) as i32), None),
                other => (other, None, None),
            };
            assert!(slot(field, 5).is_some(), "Arrow's C++ reader needs the children vector");
            let unit = slot(field, 6).and_then(|m| {
                vector(m)
                    .into_iter()
                    .find(|&kv| string(slot(kv, 0).unwrap()) == "unit")
                    .map(|kv| string(slot(kv, 1).unwrap()))
            });
            ArrowField {
                name: string(slot(field, 0).unwrap()),
                nullable: slot(field, 1).is_some_and(|at| fb[at] != 0),
                type_code,
                unit,
            }
        })
        .collect()
}

/// Parquet holds tables only: a picture or a report given a `.parquet` name, or a Parquet file given as
/// points, is refused with what to do.
#[test]
fn parquet_is_refused_where_it_is_not_a_table() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.parquet");
    let o = stiff()
        .args(["point", "manipulators/orthoglide-3puu.toml", "--at", "0,0,0", "--json", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("only tables"), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!out.exists());
    stiff()
        .args(["map", "manipulators/orthoglide-3puu.toml", "--grid", "manipulators/grids/orthoglide-small.toml"])
        .args(["-q", "-o"])
        .arg(&out)
        .assert()
        .success();
    let o = stiff().args(["map", "manipulators/orthoglide-3puu.toml", "--points"]).arg(&out).output().unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("read by `stiff plot`"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// `--columns` keeps the listed columns and groups, in the table's order, with the same values as the full
/// table; an unknown name is refused with the groups and columns listed, and a picture of a column not
/// written is refused before the run.
#[test]
fn columns_select_what_a_map_writes() {
    let map = |extra: &[&str]| {
        let out = stiff()
            .args([
                "map",
                "manipulators/orthoglide-3puu.toml",
                "--grid",
                "manipulators/grids/orthoglide-small.toml",
                "-q",
            ])
            .args(extra)
            .output()
            .unwrap();
        (out.status.code(), String::from_utf8(out.stdout).unwrap(), String::from_utf8(out.stderr).unwrap())
    };
    let (_, full, _) = map(&["--stiffness"]);
    let (code, compact, _) = map(&["--stiffness", "--columns", "K11_N_per_mm,pose,principal"]);
    assert_eq!(code, Some(0));
    let table =
        |text: &str| -> Vec<Vec<String>> { text.lines().map(|l| l.split(',').map(String::from).collect()).collect() };
    let (full, compact) = (table(&full), table(&compact));
    assert_eq!(
        compact[0],
        [
            "index",
            "name",
            "x_mm",
            "y_mm",
            "z_mm",
            "c_tran_max_mm_per_N",
            "c_tran_min_mm_per_N",
            "c_rot_max_rad_per_Nmm",
            "K11_N_per_mm"
        ]
    );
    assert_same_cells(&full, &compact);
    let (code, _, err) = map(&["--columns", "pose,nope"]);
    assert_eq!(code, Some(1));
    assert!(err.contains("`nope`") && err.contains("groups: pose, status"), "{err}");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m.csv");
    let (code, _, err) = map(&["--columns", "pose", "-o", out.to_str().unwrap(), "--plot", "m.svg"]);
    assert_eq!(code, Some(1));
    assert!(err.contains("--plot-column") && err.contains("c_tran_max_mm_per_N"), "{err}");
}

/// Either/or options show as a choice in the usage line, and giving both (or neither) is a usage error.
#[test]
fn either_or_options_are_visible_in_the_usage_line() {
    let usage = |command: &str| {
        let help = String::from_utf8(stiff().args([command, "--help"]).output().unwrap().stdout).unwrap();
        help.lines().find(|l| l.starts_with("Usage:")).unwrap().to_string()
    };
    assert!(usage("map").contains("<--grid <GRID>|--points <POINTS>>"));
    assert!(usage("assemble").contains("<--grid <GRID>|--points <POINTS>|--path <FROM> <TO> <POINTS>>"));
    assert!(usage("curve").contains("<--wrench-direction <WRENCH_DIRECTION>|--displacement-direction"));
    let both = stiff()
        .args(["map", "manipulators/orthoglide-3puu.toml", "--grid", "manipulators/grids/orthoglide-small.toml"])
        .args(["--points", "manipulators/grids/stewart-gough-home.csv"])
        .output()
        .unwrap();
    assert_eq!(both.status.code(), Some(2));
    let neither =
        stiff().args(["curve", "manipulators/orthoglide-3puu.toml", "--at", "0,0,0", "--max", "1"]).output().unwrap();
    assert_eq!(neither.status.code(), Some(2));
}

/// `assemble --columns` selects by name and group as `map --columns` does, with the same values.
#[test]
fn columns_select_what_an_assembly_writes() {
    let run = |extra: &[&str]| {
        let out = stiff()
            .args([
                "assemble",
                "manipulators/orthoglide-3puu.toml",
                "--errors",
                "manipulators/errors/orthoglide-case-a.toml",
            ])
            .args(["--grid", "manipulators/grids/orthoglide-small.toml", "--wrench", "215,-10,-25,1000,21500,0", "-q"])
            .args(extra)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let text = String::from_utf8(out.stdout).unwrap();
        text.lines().map(|l| l.split(',').map(String::from).collect::<Vec<_>>()).collect::<Vec<_>>()
    };
    let full = run(&[]);
    let some = run(&["--columns", "super,pose,leg2_force_N"]);
    assert_eq!(some[0][..5], ["index", "name", "x_mm", "y_mm", "z_mm"]);
    assert!(some[0].contains(&"superposition_gap_mm".to_string()) && some[0].contains(&"leg2_force_N".to_string()));
    assert_eq!(some[0].len(), 5 + 1 + 6 + 1);
    assert_same_cells(&full, &some);
    // A picture needs the columns it draws: refused before the run when they are not written.
    let dir = tempfile::tempdir().unwrap();
    let refused = stiff()
        .args([
            "assemble",
            "manipulators/orthoglide-3puu.toml",
            "--errors",
            "manipulators/errors/orthoglide-case-a.toml",
        ])
        .args(["--path", "0,0,0", "10,0,0", "3", "--columns", "pose", "-o"])
        .arg(dir.path().join("a.csv"))
        .arg("--plot")
        .arg(dir.path().join("a.svg"))
        .output()
        .unwrap();
    assert_eq!(refused.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&refused.stderr).contains("nl_dx_mm"));
    assert!(!dir.path().join("a.csv").exists(), "nothing written");
}

/// README is the front page (what stiff is, the two commands, the tour, where to go next) and the reference
/// is docs/GUIDE.md: every link from one to a section of the other, or within one, names a heading that
/// exists (GitHub's anchors: lower case, spaces as hyphens, punctuation dropped).
#[test]
fn readme_and_guide_links_name_headings_that_exist() {
    let anchors = |text: &str| -> Vec<String> {
        text.lines()
            .filter(|l| l.starts_with('#'))
            .map(|l| {
                let t = l.trim_start_matches('#').trim().to_lowercase();
                t.chars()
                    .filter(|c| c.is_alphanumeric() || *c == ' ' || *c == '-' || *c == '_')
                    .collect::<String>()
                    .replace(' ', "-")
            })
            .collect()
    };
    let readme = std::fs::read_to_string("README.md").unwrap();
    let guide = std::fs::read_to_string("docs/GUIDE.md").unwrap();
    assert!(readme.lines().count() <= 200, "README is a front page: {} lines", readme.lines().count());
    let (in_readme, in_guide) = (anchors(&readme), anchors(&guide));
    for (file, text, own, other, prefix) in [
        ("README.md", &readme, &in_readme, &in_guide, "docs/GUIDE.md#"),
        ("docs/GUIDE.md", &guide, &in_guide, &in_readme, "../README.md#"),
    ] {
        for link in text.split("](").skip(1).map(|r| &r[..r.find(')').unwrap_or(0)]) {
            if let Some(a) = link.strip_prefix('#') {
                assert!(own.iter().any(|h| h == a), "{file}: no heading for #{a}");
            } else if let Some(a) = link.strip_prefix(prefix) {
                assert!(other.iter().any(|h| h == a), "{file}: no heading for {link}");
            }
        }
    }
}
