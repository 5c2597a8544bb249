//! A batch tool runs unattended: every input a mutation fuzzer found to crash, hang or mislead `stiff` is
//! pinned here, each test named after what it guards. The physics is simple: numbers at the edge of what
//! doubles hold (a modulus of 5e-324, a length of 1e200, a load of 1e308) give no finite stiffness, so the
//! answer is a located error or a row status, never a panic (exit 101), an endless loop or a NaN under `ok`.

use crate::common;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_stiff"))
}

/// Runs stiff with a deadline; panics (failing the test) on a hang.
fn run_in(dir: &Path, args: &[&str], deadline: Duration) -> Output {
    let done = common::run_with_deadline(Command::new(bin()).args(args).current_dir(dir), usize::MAX, deadline)
        .unwrap_or_else(|| panic!("stiff {} did not finish within {deadline:?} (a hang)", args.join(" ")));
    Output { status: done.status, stdout: done.stdout, stderr: done.stderr.into_bytes() }
}

/// The package's folder, read when the test runs (cargo sets it for the test process): a test binary that
/// a build cache kept from an earlier copy of the repository must not read that copy's deleted folder, as
/// the compile-time `env!` would.
fn root() -> PathBuf {
    std::env::var_os("CARGO_MANIFEST_DIR").map_or_else(|| std::env::current_dir().unwrap(), PathBuf::from)
}

fn run(args: &[&str]) -> Output {
    run_in(&root(), args, Duration::from_secs(60))
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Exit 1 with a message, never a panic, and no Rust debug text in the message.
fn refused(o: &Output) -> String {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(1), "expected a refusal (exit 1), got {:?}: {e}", o.status);
    assert!(!e.contains("panicked") && e.starts_with("error: "), "{e}");
    assert!(!e.contains(" { ") && !e.contains("Some(") && !e.contains("Unreachable("), "debug text in: {e}");
    e
}

/// Every `ok` row of a CSV holds finite numbers only; returns the statuses seen.
fn statuses_with_finite_ok_rows(csv: &str) -> Vec<String> {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let status = header.iter().position(|h| *h == "status").unwrap();
    let mut seen = Vec::new();
    for l in lines {
        let f: Vec<&str> = l.split(',').collect();
        if f[status] == "ok" {
            assert!(
                f.iter().all(|v| v.parse::<f64>().is_ok_and(|x| x.is_finite()) || v.parse::<f64>().is_err()),
                "non-finite number under ok: {l}"
            );
            assert!(!l.contains("nan") && !l.contains("inf"), "non-finite text under ok: {l}");
        }
        seen.push(f[status].to_string());
    }
    seen
}

const PRPAR: &str = "manipulators/orthoglide-3prpar.toml";
const PUU: &str = "manipulators/orthoglide-3puu.toml";
const PUU_MSA: &str = "manipulators/orthoglide-3puu-msa.toml";
const SMALL: &str = "manipulators/grids/orthoglide-small.toml";

/// Regression: parameters at the edge of doubles made the 3-PRPaR's parallelogram spring panic ("a bar chain
/// is regular", "a beam's compliance is positive definite"). They are refused where the spring is built.
#[test]
fn extreme_parallelogram_parameters_are_refused_not_panicking() {
    for set in ["bar_gap=4294967296", "E=5e-324", "bar_d=1e-100", "L=1e-300"] {
        let e = refused(&run(&["map", PRPAR, "--grid", SMALL, "--set", set, "-q"]));
        assert!(e.contains("orthoglide-3prpar.toml, line"), "{set}: {e}");
    }
}

/// Regression: the MSA beam stiffness panicked for d_foot = 1e200, and its null space looped for ever on
/// E = 5e-324 or d_leg = 1e-200 (nalgebra's SVD has no iteration cap on non-finite input).
#[test]
fn extreme_msa_parameters_end_with_an_answer() {
    for set in ["d_foot=1e200", "E=5e-324", "d_leg=1e-200", "d_foot=1e-300"] {
        let o = run(&["map", PUU_MSA, "--grid", SMALL, "--set", set, "-q"]);
        match o.status.code() {
            Some(0) => {
                statuses_with_finite_ok_rows(&String::from_utf8(o.stdout).unwrap());
            }
            _ => {
                refused(&o);
            }
        }
    }
    // Poses astronomically far away: a status, not a hang.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("far.csv"), "x_mm,y_mm,z_mm\n5e18,0,0\n1e300,0,0\n").unwrap();
    for model in [PUU, PUU_MSA] {
        let m = root().join(model).display().to_string();
        let o = run_in(dir.path(), &["map", &m, "--points", "far.csv", "-q"], Duration::from_secs(60));
        let seen = statuses_with_finite_ok_rows(&String::from_utf8(o.stdout).unwrap());
        assert!(seen.iter().all(|s| s != "ok"), "{model}: {seen:?}");
    }
}

/// Regression: printing a report to a full disk panicked ("failed printing to stdout"). It is an error.
#[test]
fn a_full_stdout_is_an_error_not_a_panic() {
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
    let o =
        Command::new(bin()).args(["point", PUU, "--at", "0,0,0"]).current_dir(root()).stdout(full).output().unwrap();
    assert!(refused(&o).contains("No space left"));
}

/// Regression: `-o` renamed a temporary file over the target, which replaces a device node or a FIFO by a
/// plain file (as root, `-o /dev/null` destroyed /dev/null). A path that exists and is not a regular file is
/// written through. Tested on a FIFO, so that a regression cannot harm the machine's devices.
#[test]
fn output_to_a_fifo_is_written_through_not_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read_to_string(fifo).unwrap())
    };
    let o = run(&["map", PUU, "--grid", SMALL, "-q", "-o", fifo.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = reader.join().unwrap();
    assert_eq!(text.lines().count(), 126);
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo(), "the FIFO is still a FIFO");
}

/// Regression: `-o results.csv`, a symbolic link to a file kept elsewhere (results on another disk), replaced
/// the link by a regular file and left its target untouched. The target is written (atomically, through a
/// temporary file beside it) and the link stays; a link to a missing file creates that file; a dangling link
/// into a missing folder is a clear error and nothing is written anywhere.
#[test]
fn output_through_a_symbolic_link_writes_its_target_and_keeps_the_link() {
    use std::os::unix::fs::symlink;
    let dir = tempfile::tempdir().unwrap();
    let elsewhere = dir.path().join("other-disk");
    std::fs::create_dir(&elsewhere).unwrap();
    let target = elsewhere.join("results.csv");
    std::fs::write(&target, "old contents\n").unwrap();
    let link = dir.path().join("results.csv");
    symlink(&target, &link).unwrap();
    let o = run(&["map", PUU, "--grid", SMALL, "-q", "-o", link.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink(), "the link is still a link");
    let written = std::fs::read_to_string(&target).unwrap();
    assert_eq!(written.lines().count(), 126, "the target holds the map");
    assert!(written.starts_with("index,name,x_mm,"), "{}", &written[..40]);
    let leftovers = |d: &Path| {
        std::fs::read_dir(d)
            .unwrap()
            .filter(|e| e.as_ref().unwrap().file_name().to_string_lossy().ends_with(".partial"))
            .count()
    };
    assert_eq!(leftovers(&elsewhere) + leftovers(dir.path()), 0, "no temporary file left");

    // A relative link to a file that does not exist yet: the file is created where the link points.
    let relative = dir.path().join("relative.csv");
    symlink("other-disk/new.csv", &relative).unwrap();
    let o = run(&["map", PUU, "--grid", SMALL, "-q", "-o", relative.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::symlink_metadata(&relative).unwrap().file_type().is_symlink());
    assert_eq!(std::fs::read_to_string(elsewhere.join("new.csv")).unwrap().lines().count(), 126);

    // A dangling link into a folder that does not exist: refused before any work, nothing created.
    let dangling = dir.path().join("dangling.csv");
    symlink(dir.path().join("no-such-folder/out.csv"), &dangling).unwrap();
    let o = run(&["map", PUU, "--grid", SMALL, "-q", "-o", dangling.to_str().unwrap()]);
    let e = refused(&o);
    assert!(e.contains("symbolic link") && e.contains("no-such-folder") && e.contains("does not exist"), "{e}");
    assert!(!dir.path().join("no-such-folder").exists());
    assert!(std::fs::symlink_metadata(&dangling).unwrap().file_type().is_symlink(), "the link is untouched");
}

/// Regression: `map ... | head -1` computed the whole map, then failed with "Broken pipe". A closed pipe
/// stops the run quietly (exit 0), as ripgrep and xsv do: a grid of 1e9 points ends at once.
#[test]
fn a_closed_pipe_stops_a_huge_map_quietly() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("g.toml"),
        "[box]\nfrom = [-60, -60, -60]\nto = [60, 60, 60]\npoints = [1000, 1000, 1000]\n",
    )
    .unwrap();
    let mut child = Command::new(bin())
        .args(["map", root().join(PUU).to_str().unwrap(), "--grid", "g.toml", "-q"])
        .current_dir(dir.path())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut out = child.stdout.take().unwrap();
    let mut first = [0u8; 4096];
    out.read_exact(&mut first).unwrap();
    drop(out);
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        assert!(start.elapsed() < Duration::from_secs(60), "the map went on after its reader left");
        std::thread::sleep(Duration::from_millis(10));
    }
    let status = child.wait().unwrap();
    let mut err = String::new();
    child.stderr.take().unwrap().read_to_string(&mut err).unwrap();
    assert!(status.success() && err.is_empty(), "{status:?} {err}");
}

/// Regression: an interrupted run left a hidden `.stiff-XXXXXX.partial` of hundreds of MB beside its
/// target. SIGINT and SIGTERM remove it.
#[test]
fn an_interrupted_run_leaves_no_partial_file() {
    for signal in ["-INT", "-TERM"] {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("g.toml"),
            "[box]\nfrom = [-60, -60, -60]\nto = [60, 60, 60]\npoints = [400, 400, 400]\n",
        )
        .unwrap();
        let mut child = Command::new(bin())
            .args(["map", root().join(PUU).to_str().unwrap(), "--grid", "g.toml", "-q", "-o", "out.csv"])
            .current_dir(dir.path())
            .spawn()
            .unwrap();
        let partial = || {
            std::fs::read_dir(dir.path())
                .unwrap()
                .filter_map(|e| e.ok())
                .any(|e| e.file_name().to_string_lossy().ends_with(".partial"))
        };
        let start = Instant::now();
        while !partial() {
            assert!(start.elapsed() < Duration::from_secs(30), "no partial file appeared");
            std::thread::sleep(Duration::from_millis(10));
        }
        std::thread::sleep(Duration::from_millis(200));
        assert!(Command::new("kill").args([signal, &child.id().to_string()]).status().unwrap().success());
        let status = child.wait().unwrap();
        assert!(!status.success(), "{signal}: interrupted");
        assert!(!partial() && !dir.path().join("out.csv").exists(), "{signal}: the partial file is removed");
    }
}

/// Regression (fuzzing): `curve ... --plot c.svg --direction=-1 -o c.csv` exited 1 on `--direction` after
/// the curve had run and `c.csv` had been written, so a failed run left an output behind. The picture's
/// options are checked before the curve runs, as map and assemble check theirs: nothing is written.
#[test]
fn a_bad_curve_picture_option_fails_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let m = root().join(PRPAR).display().to_string();
    let o = run_in(
        dir.path(),
        &[
            "curve",
            &m,
            "--at",
            "0,0,0",
            "--wrench-direction",
            "1e-300,215,1e-300,1e-300,0,1e-300",
            "--max",
            "10",
            "--steps",
            "5",
            "--plot",
            "c.svg",
            "--direction=-1",
            "-o",
            "c.csv",
        ],
        Duration::from_secs(60),
    );
    let e = refused(&o);
    assert!(e.contains("--direction") && e.contains("`-1`"), "{e}");
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert!(left.is_empty(), "a failed run wrote {left:?}");
}

/// Regression: size requests beyond what the machine can do hung or aborted (`curve --intervals 4294967297`
/// allocated 721 GB, `--threads 1000000` hung the pool setup, `assemble --samples 4294967297` never wrote a row, `points = [2^32, 2^32, 1]` wrapped to zero
/// points). They are refused up front, saying the limit.
#[test]
fn impossible_sizes_are_refused_with_their_limit() {
    let e = refused(&run(&[
        "curve",
        PUU,
        "--at",
        "0,0,0",
        "--wrench-direction",
        "1,0,0,0,0,0",
        "--max",
        "1",
        "--intervals",
        "4294967297",
    ]));
    assert!(e.contains("1000000"), "{e}");
    let e = refused(&run(&["map", PUU, "--grid", SMALL, "--threads", "1000000"]));
    assert!(e.contains("1024"), "{e}");
    let e = refused(&run(&[
        "assemble",
        PUU,
        "--errors",
        "manipulators/errors/orthoglide-case-a.toml",
        "--grid",
        SMALL,
        "--samples",
        "4294967297",
    ]));
    assert!(e.contains("10000000"), "{e}");
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("g.toml"),
        "[box]\nfrom = [0, 0, 0]\nto = [10, 10, 0]\npoints = [4294967296, 4294967296, 1]\n",
    )
    .unwrap();
    let m = root().join(PUU).display().to_string();
    let e = refused(&run_in(dir.path(), &["map", &m, "--grid", "g.toml"], Duration::from_secs(60)));
    assert!(e.contains("g.toml, line 4") && e.contains("split it"), "{e}");
}

/// Regression: grid arrays of the wrong length were truncated and `nan` in a grid gave NaN rows marked ok.
/// Every reader applies one rule: exactly the numbers asked for, all finite, or a located error.
#[test]
fn grid_arrays_must_have_their_length_and_be_finite() {
    let dir = tempfile::tempdir().unwrap();
    let m = root().join(PUU).display().to_string();
    for (grid, what) in [
        ("[box]\nfrom = [0, 0, 0, 9]\nto = [10, 10, 10]\npoints = [2, 2, 2]\n", "`from` needs 3 numbers, got 4"),
        (
            "[box]\nfrom = [0, 0, 0]\nto = [10, 10, 10]\npoints = [2, 2, 2]\nwrench = [1, 2, 3, 4, 5, 6, 7]\n",
            "`wrench` needs 6",
        ),
        (
            "[box]\nfrom = [0, 0, 0]\nto = [10, 10, 10]\npoints = [2, 2, 2]\nwrench = [1, nan, 3, 4, 5, 6]\n",
            "not a finite number",
        ),
        ("[[point]]\nname = \"p\"\nat = [0, inf, 0]\n", "not a finite number"),
    ] {
        std::fs::write(dir.path().join("g.toml"), grid).unwrap();
        let e = refused(&run_in(dir.path(), &["map", &m, "--grid", "g.toml"], Duration::from_secs(60)));
        assert!(e.contains(what) && e.contains("g.toml, line"), "{grid}: {e}");
    }
    let e = refused(&run(&["point", PUU, "--at", "nan,0,0"]).clone_with_code());
    assert!(e.contains("`nan` is not a finite number"), "{e}");
}

/// Regression: loads of 1e308 gave NaN or infinite rows marked `ok` (or `stable`). A result that overflows
/// is a row status.
#[test]
fn astronomical_loads_give_statuses_not_nan_rows() {
    let o = run(&["map", PUU, "--grid", SMALL, "--wrench", "1e308,0,0,0,0,0", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let seen = statuses_with_finite_ok_rows(&String::from_utf8(o.stdout).unwrap());
    assert!(seen.iter().all(|s| s != "ok"), "{seen:?}");
    let o = run(&[
        "curve",
        PUU,
        "--at",
        "0,0,0",
        "--wrench-direction",
        "1,0,0,0,0,0",
        "--max",
        "1e308",
        "--intervals",
        "3",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout).unwrap();
    statuses_with_finite_ok_rows(&text);
    assert!(!text.contains("nan") && !text.contains("inf"), "{text}");
    let synth = |extra: &[&str]| {
        let mut args = vec!["synth", PUU, "--grid", SMALL, "--wrenches", "100,0,0,0,0,0", "--noise", "0"];
        args.extend(["--seed", "1", "--effect", "gravity=1e308"]);
        args.extend(extra);
        run(&args)
    };
    // A payload of 1e308 kg has no loaded equilibrium anywhere: refused, saying so.
    let o = synth(&[]);
    assert!(refused(&o).contains("no pose has a loaded equilibrium"), "{}", refused(&o));
    // Synthetic measurements must stay readable by diagnose: an overflowing linear prediction is refused (it
    // used to write rows with empty displacement cells).
    let o = synth(&["--linear"]);
    assert!(refused(&o).contains("not a measurement"));
}

/// Regression: one measured value of 1e308, or `--sigma 1e-300`, sent diagnose's SVD into an endless loop.
/// Measurements beyond 1e100 and noise below a picometre are refused, located.
#[test]
fn absurd_measurements_are_refused_not_looping() {
    let dir = tempfile::tempdir().unwrap();
    let data = "pose_id,x_mm,y_mm,z_mm,Fx_N,Fy_N,Fz_N,Mx_Nmm,My_Nmm,Mz_Nmm,dx_mm,dy_mm,dz_mm\n\
                p0,0,0,0,200,0,0,0,0,0,0.056,0.0001,1e308\np0,0,0,0,0,200,0,0,0,0,0.0001,0.056,0\n";
    std::fs::write(dir.path().join("d.csv"), data).unwrap();
    let m = root().join(PUU).display().to_string();
    let e =
        refused(&run_in(dir.path(), &["diagnose", &m, "--data", "d.csv", "--sigma", "0.002"], Duration::from_secs(60)));
    assert!(e.contains("d.csv, line 2") && e.contains("dz_mm"), "{e}");
    std::fs::write(dir.path().join("d.csv"), data.replace("1e308", "0.0002")).unwrap();
    let e = refused(&run_in(
        dir.path(),
        &["diagnose", &m, "--data", "d.csv", "--sigma", "1e-300"],
        Duration::from_secs(60),
    ));
    assert!(e.contains("noise"), "{e}");
}

/// Regression: ~10,000 nested parentheses in a formula overflowed the parser's stack (an abort).
#[test]
fn a_deeply_nested_formula_is_a_located_error() {
    let text = std::fs::read_to_string(root().join(PUU)).unwrap();
    let nested = format!("L = \"{}310.25{}\"", "(".repeat(2000), ")".repeat(2000));
    let line = text.lines().find(|l| l.starts_with("L = ")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("m.toml"), text.replace(line, &nested)).unwrap();
    let e = refused(&run_in(
        dir.path(),
        &["map", "m.toml", "--grid", root().join(SMALL).to_str().unwrap()],
        Duration::from_secs(60),
    ));
    assert!(e.contains("m.toml, line") && e.contains("levels deep"), "{e}");
}

/// Regression: a missing file printed its cause twice.
#[test]
fn a_missing_file_is_reported_once() {
    let e = refused(&run(&["map", "no-such-model.toml", "--grid", SMALL]));
    assert_eq!(e.matches("No such file").count() + e.matches("not found").count(), 1, "{e}");
}

trait CloneWithCode {
    fn clone_with_code(&self) -> Output;
}

impl CloneWithCode for Output {
    /// clap refuses a bad value with exit 2 (usage); the message rule is the same.
    fn clone_with_code(&self) -> Output {
        let mut o = self.clone();
        if o.status.code() == Some(2) {
            use std::os::unix::process::ExitStatusExt;
            o.status = std::process::ExitStatus::from_raw(1 << 8);
        }
        o
    }
}

/// Regression: options that can only fail at the end (`--section`, `--plot-column`) failed after the whole
/// map was computed and written. They are checked before the run, and nothing is left behind.
#[test]
fn picture_options_are_checked_before_the_map_runs() {
    let dir = tempfile::tempdir().unwrap();
    let m = root().join(PUU).display().to_string();
    let g = root().join(SMALL).display().to_string();
    for bad in [["--section", "q=5"], ["--plot-column", "no_such_column"]] {
        let args = ["map", &m, "--grid", &g, "-o", "out.csv", "--plot", "out.svg", bad[0], bad[1]];
        let e = refused(&run_in(dir.path(), &args, Duration::from_secs(60)));
        assert!(e.contains(bad[0]), "{e}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "nothing left behind");
    }
}

/// Regression: error files accepted arrays of the wrong length (truncated) and `nan`, and their semantic
/// errors pointed at line 1 column 1. The same rule as grids, located at the value.
#[test]
fn error_file_values_are_checked_and_located() {
    let dir = tempfile::tempdir().unwrap();
    let m = root().join(PUU).display().to_string();
    let p = root().join("manipulators/grids/stewart-gough-home.csv").display().to_string();
    for (body, what) in [
        ("eps = { translation_mm = [0, 0, 0, 5] }", "`translation_mm` needs 3 numbers, got 4"),
        ("eps = { rotation_deg = [0, nan, 0] }", "not a finite number"),
        ("base = { rotation_axis = [1, 0], rotation_deg = 1 }", "`rotation_axis` needs 3"),
        ("base = { rotation_axis = [1, 0, 0], rotation_deg = inf }", "not a finite number"),
    ] {
        std::fs::write(dir.path().join("e.toml"), format!("description = \"x\"\n[[leg]]\nname = \"*\"\n{body}\n"))
            .unwrap();
        let e = refused(&run_in(
            dir.path(),
            &["assemble", &m, "--errors", "e.toml", "--points", &p],
            Duration::from_secs(60),
        ));
        assert!(e.contains(what) && e.contains("e.toml, line 4"), "{body}: {e}");
    }
}

/// Regression: a file written on Windows (CR LF line ends) had every located error one line early: the csv
/// crate reports the line of a record after a CR LF line end one line early (rust-csv issue #395). A bad
/// number on line 3 of a points file, of joint-space measurements and of pose measurements is now named at
/// line 3, and the same files with LF line ends give the same messages.
#[test]
fn a_crlf_file_names_the_faulty_line() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "points.csv",
            "x_mm,y_mm,z_mm\r\n0,0,0\r\n0,nan,0\r\n",
            vec!["map", "manipulators/orthoglide-3puu.toml", "--points"],
        ),
        (
            "joints.csv",
            "q_J1,q_J2,q_J3,q_J4,q_J5,q_J6,mx_mm,my_mm,mz_mm\r\n0,0,0,0,0,0,1,2,3\r\n0,0,0,0,0,0,nan,2,3\r\n",
            vec!["diagnose", "manipulators/fanuc-r2000ic.toml", "--data"],
        ),
        (
            "poses.csv",
            "pose_id,x_mm,y_mm,z_mm,Fx_N,Fy_N,Fz_N,Mx_Nmm,My_Nmm,Mz_Nmm,dx_mm,dy_mm,dz_mm\r\n\
             a,0,0,0,100,0,0,0,0,0,0.01,0,0\r\nb,0,0,0,100,0,0,0,0,0,nan,0,0\r\n",
            vec!["diagnose", "manipulators/orthoglide-3puu.toml", "--data"],
        ),
    ];
    for (name, text, args) in cases {
        let mut messages = Vec::new();
        for (file, body) in
            [(format!("crlf-{name}"), text.to_string()), (format!("lf-{name}"), text.replace("\r\n", "\n"))]
        {
            let path = dir.path().join(&file);
            std::fs::write(&path, body).unwrap();
            let mut a: Vec<&str> = args.clone();
            let p = path.to_str().unwrap();
            a.push(p);
            a.extend(["-o", "/dev/null"].iter().filter(|_| args[0] == "map"));
            let e = refused(&run(&a));
            assert!(e.contains(&format!("{file}, line 3")), "{e}");
            messages.push(e.replace(&file, "FILE"));
        }
        assert_eq!(messages[0], messages[1]);
    }
}

/// Positions in an instrument's frame (`mx_mm`, ...) at a parallel robot's poses are calibrated (its legs'
/// effects, tests/calibrate_legs.rs); too few of them to fit the instrument's frame and the target's place
/// are refused saying how many coordinates there are against how many parameters, instead of naming a
/// missing wrench column (as before the calibration of legs existed).
#[test]
fn absolute_positions_for_a_parallel_robot_too_few_to_register_say_how_many_are_needed() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("abs.csv");
    std::fs::write(&path, "pose_id,x_mm,y_mm,z_mm,mx_mm,my_mm,mz_mm\na,0,0,0,1,2,3\n").unwrap();
    let e = refused(&run(&["diagnose", "manipulators/orthoglide-3puu.toml", "--data", path.to_str().unwrap()]));
    assert!(e.contains("1 fitted rows give 3 coordinates, too few for the 9 parameters"), "{e}");
}

/// Regression: `map --loaded` on a grid without reference wrenches advised "(or give --wrench)", and
/// `--loaded --wrench` is refused by the parser. The advice now says to drop `--loaded` and give
/// `--wrench`, and following it works.
#[test]
fn the_advice_for_loaded_without_wrenches_is_runnable() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m.csv");
    let points = dir.path().join("p.csv");
    std::fs::write(&points, "x_mm,y_mm,z_mm\n0,0,0\n10,0,0\n").unwrap();
    let map = |load: &[&str]| {
        let mut args = vec!["map", "manipulators/orthoglide-3puu.toml", "--points", points.to_str().unwrap()];
        args.extend_from_slice(load);
        args.extend(["-q", "-o", out.to_str().unwrap()]);
        run(&args)
    };
    let e = refused(&map(&["--loaded"]));
    assert!(e.contains("drop --loaded and give --wrench FX,FY,FZ,MX,MY,MZ"), "{e}");
    assert!(!out.exists(), "nothing written");
    let o = map(&["--wrench", "10,0,0,0,0,0"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(&out).unwrap().lines().count(), 3);
}

/// A panic in a worker (a bug, which no input should reach) ends a streamed study with an error naming the
/// items it stopped on, for one thread and for two, instead of a hang: the writer waits for every run in
/// input order and the dispatcher for the tokens the writer returns, so a run that never reports would
/// block both for ever. The rows before the failed run may be written; the error says no output was put in
/// place (the CLI's output file is renamed into place only on success).
#[test]
fn a_panicking_worker_ends_the_run_with_an_error_not_a_hang() {
    use stiff::batch::{stream, Source, Study, Tally};
    use stiff::output::table::{CellKind, Column};

    #[derive(Default)]
    struct Count;
    impl Tally for Count {
        fn merge(&mut self, _: &Self) {}
    }
    struct Items(std::ops::Range<u64>);
    impl Source for Items {
        type Item = u64;
        fn next_block(&mut self, n: usize, out: &mut Vec<u64>) -> Result<usize, stiff::model::error::InputError> {
            let before = out.len();
            out.extend(self.0.by_ref().take(n));
            Ok(out.len() - before)
        }
        fn first_index(&self) -> u64 {
            0
        }
    }
    struct PanicsAt(u64);
    impl Study for PanicsAt {
        type Item = u64;
        type State = ();
        type Tally = Count;
        fn columns(&self) -> Vec<Column> {
            vec![Column { name: "index".into(), kind: CellKind::Count }]
        }
        fn new_state(&self) {}
        fn solve(&self, index: u64, _: &u64, _: &mut (), _: &mut Count, out: &mut String) {
            assert!(index != self.0, "a deliberate panic at item {index}");
            out.push_str(&format!("{index}\n"));
        }
    }
    for threads in [1, 2] {
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut out = Vec::new();
            let result =
                stream(&pool, &PanicsAt(3000), &mut Items(0..10_000), &mut out, &indicatif::ProgressBar::hidden());
            let _ = tx.send(result.map(|_| ()).map_err(|e| e.to_string()));
        });
        let outcome = rx.recv_timeout(Duration::from_secs(60)).expect("the study hung after a worker's panic");
        let message = outcome.expect_err("a worker's panic is an error");
        assert!(message.contains("internal error") && message.contains("deliberate panic"), "{message}");
        assert!(message.contains("from input index 2816"), "the run of item 3000 (256 per run): {message}");
    }
}
