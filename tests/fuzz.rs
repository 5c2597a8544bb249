//! Mutation fuzzing of the `stiff` binary: a batch tool runs unattended, so no input may make it panic,
//! hang or abort, and no row whose status says it is fine may carry a non-finite number.
//!
//! Each case starts from a valid command on shipped inputs (models, grids, points, error files, measured
//! data, plot inputs, command-line values) and applies one to three mutations: a number replaced by an
//! extreme value (0, -1, 1e308, 5e-324, 2^32, nan, inf, ...), a line deleted or duplicated, a file
//! truncated, an array lengthened. The binary runs with a per-case timeout; at most 256 KB of its stdout is
//! read before the pipe is closed (so a huge request must stop at the closed pipe, as `head` expects).
//! A case fails on: exit code 101 or "panicked" on stderr (panic), death by a signal (abort), the
//! timeout (hang), or a CSV row with status `ok` holding a non-finite number. A mutated grid that asks for
//! more than a million points (up to the 1e10 a grid may hold) is a legitimate long job, not a hang, when
//! nothing stops it early (output to a file, or every pose unreachable so nothing reaches the closed pipe):
//! such a case is stopped after `LONG_JOB_WINDOW` (2 s) and passes if it did nothing else wrong by then.
//!
//! `cargo test --test suite fuzz::` runs a short seeded campaign (2,000 cases, about ten seconds). The long run (docs/GUIDE.md, "Fuzzing"):
//! `STIFF_FUZZ_CASES=20000 STIFF_FUZZ_SEED=1 cargo test --release --test suite fuzz:: -- --nocapture`.

use crate::common;
use common::run_with_deadline;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// Values that break naive numerics: zero, signs, the extremes of f64, 2^32 (wraps 32-bit counts), and
/// non-finite text.
const EXTREMES: [&str; 18] = [
    "0",
    "-1",
    "1e308",
    "-1e308",
    "5e-324",
    "1e-300",
    "4294967296",
    "4294967297",
    "nan",
    "inf",
    "-inf",
    "-0.0",
    "1e200",
    "1e-200",
    "1e18",
    "18446744073709551616",
    "0.5",
    "1000000",
];

/// Longest a case may run (the slowest shipped commands take well under a second in release).
const TIMEOUT: Duration = Duration::from_secs(20);
/// How long a legitimate long job (a grid of more than a million points) runs before it is stopped: its
/// outcome is a pass unless it panicked, aborted or wrote a bad row by then, so running it to `TIMEOUT`
/// would spend that whole time (a synth over such a grid took 20 of the campaign's 30 CPU seconds) to learn
/// nothing a shorter window does not.
const LONG_JOB_WINDOW: Duration = Duration::from_secs(2);
/// Stdout read before the pipe is closed.
const STDOUT_LIMIT: usize = 256 * 1024;

#[derive(Debug)]
#[allow(dead_code)] // the fields are read through Debug in the report
enum Failure {
    Panic(String),
    Signal(i32),
    Hang,
    NonFiniteOk(String),
}

struct Case {
    args: Vec<String>,
    /// Files written into the case's folder before the run: (name, content).
    files: Vec<(String, String)>,
}

/// The package's folder, read when the test runs (cargo sets it for the test process): a test binary that
/// a build cache kept from an earlier copy of the repository must not read that copy's deleted folder, as
/// the compile-time `env!` would.
fn root() -> PathBuf {
    std::env::var_os("CARGO_MANIFEST_DIR").map_or_else(|| std::env::current_dir().unwrap(), PathBuf::from)
}

fn shipped(path: &str) -> String {
    std::fs::read_to_string(root().join(path)).unwrap()
}

/// Byte ranges of the numbers in a text (a sign, digits, a fraction, an exponent).
fn numbers(text: &str) -> Vec<(usize, usize)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts = b[i].is_ascii_digit() && (i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_'));
        if starts {
            let start = if i > 0 && b[i - 1] == b'-' { i - 1 } else { i };
            let mut j = i;
            while j < b.len() && (b[j].is_ascii_digit() || b[j] == b'.') {
                j += 1;
            }
            if j < b.len() && (b[j] == b'e' || b[j] == b'E') {
                let mut k = j + 1;
                if k < b.len() && (b[k] == b'-' || b[k] == b'+') {
                    k += 1;
                }
                if k < b.len() && b[k].is_ascii_digit() {
                    j = k;
                    while j < b.len() && b[j].is_ascii_digit() {
                        j += 1;
                    }
                }
            }
            if !(j < b.len() && (b[j].is_ascii_alphabetic() || b[j] == b'_')) {
                out.push((start, j));
            }
            i = j.max(i + 1);
        } else {
            i += 1;
        }
    }
    out
}

fn extreme(r: &mut StdRng) -> &'static str {
    EXTREMES[r.random_range(0..EXTREMES.len())]
}

/// One mutation of a text: a number replaced, a line deleted or duplicated, the text truncated, or an
/// element added to an array.
fn mutate(text: &str, r: &mut StdRng) -> String {
    let lines: Vec<&str> = text.lines().collect();
    match r.random_range(0..10) {
        0..=5 => {
            let spots = numbers(text);
            if spots.is_empty() {
                return text.to_string();
            }
            let (a, b) = spots[r.random_range(0..spots.len())];
            format!("{}{}{}", &text[..a], extreme(r), &text[b..])
        }
        6 if !lines.is_empty() => {
            let k = r.random_range(0..lines.len());
            lines.iter().enumerate().filter(|(i, _)| *i != k).map(|(_, l)| format!("{l}\n")).collect()
        }
        7 if !lines.is_empty() => {
            let k = r.random_range(0..lines.len());
            lines
                .iter()
                .enumerate()
                .map(|(i, l)| if i == k { format!("{l}\n{l}\n") } else { format!("{l}\n") })
                .collect()
        }
        8 => {
            let cut = r.random_range(0..=text.len());
            let cut = (0..=cut).rev().find(|&c| text.is_char_boundary(c)).unwrap_or(0);
            text[..cut].to_string()
        }
        _ => match text.match_indices(']').map(|(i, _)| i).collect::<Vec<_>>() {
            v if v.is_empty() => text.to_string(),
            v => {
                let at = v[r.random_range(0..v.len())];
                format!("{}, {}{}", &text[..at], extreme(r), &text[at..])
            }
        },
    }
}

/// A command-line value mutated: a number of it replaced, or the whole value replaced.
fn mutate_value(v: &str, r: &mut StdRng) -> String {
    if r.random_bool(0.3) {
        return extreme(r).to_string();
    }
    mutate(v, r).trim_end().to_string()
}

const MODELS: [&str; 7] = [
    "manipulators/orthoglide-3puu.toml",
    "manipulators/orthoglide-3prpar.toml",
    "manipulators/orthoglide-3puu-msa.toml",
    "manipulators/stewart-gough-a.toml",
    "manipulators/stewart-gough-b.toml",
    "manipulators/navaro2.toml",
    "manipulators/navaro2-leg-passive.toml",
];

const SMALL_GRID: &str =
    "[box]\nfrom = [-40, -40, -40]\nto = [40, 40, 40]\npoints = [2, 2, 2]\nwrench = [215, -10, -25, 1000, 21500, 0]\n";
const POINTS: &str = "name,x_mm,y_mm,z_mm,Fx_N,Fy_N,Fz_N,Mx_Nmm,My_Nmm,Mz_Nmm\nQ0,0,0,0,100,0,0,0,0,0\nQ1,-73.65,-73.65,-73.65,0,50,0,0,1000,0\nfar,126.35,126.35,126.35,0,0,-80,0,0,0\n";
/// A serial arm's joint-space calibration data as a lab records them: the FANUC's first 12 cable-test
/// configurations under their cable forces, a target's position and orientation in an instrument's frame
/// (made by `stiff synth` with a hidden registration and target, 0.05 mm and 0.1 mrad of noise), every
/// third held out.
const JOINT_DATA: &str = "pose_id,q_J1,q_J2,q_J3,q_J4,q_J5,q_J6,Fx_N,Fy_N,Fz_N,Mx_Nmm,My_Nmm,Mz_Nmm,mx_mm,my_mm,mz_mm,sigma_mm,mqw,mqx,mqy,mqz,sigma_mrad,set\n\
c1,-1.04704047,-0.291347812,-0.504923753,0.066113072,-1.0983357,2.5293137,-120.211077,-78.2152317,-14.6909088,0,0,0,2523.89277,-934.7781,897.008426,0.05,-0.0560938849,0.652784974,0.755429352,0.00719353848,0.1,fit\n\
c2,-1.06658816,-0.224327169,-0.521102955,-0.110112823,-1.33432167,2.22323531,-89.9578569,-71.6908204,-8.30556451,0,0,0,2531.28771,-924.072429,903.273498,0.05,-0.184837885,0.774635355,0.600341192,0.0732494182,0.1,fit\n\
c3,-1.12313683,-0.45778241,-0.022759093,-0.256039801,-1.44387598,2.2168474,-217.09672,-171.850258,-182.833952,0,0,0,2571.87625,-1033.30615,1539.3291,0.05,0.00852820132,0.798719616,0.582138202,0.15195183,0.1,check\n\
c4,-1.12153112,-0.677170296,0.010733775,-0.265691472,-1.17040034,2.21388034,-223.940903,-180.616859,-198.00609,0,0,0,2525.60135,-1000.94037,1556.45156,0.05,0.159083757,0.800129617,0.557438551,0.154101318,0.1,fit\n\
c5,-1.18418844,0.043388885,-0.445303305,-0.398092149,-0.757315816,2.46398603,-349.506472,19.6320668,-120.231882,0,0,0,2859.11439,-1574.45402,1142.55673,0.05,0.158644631,0.80014203,0.557501492,0.154261787,0.1,fit\n\
c6,-1.11772631,0.027209683,-0.61866686,-0.081018184,-0.156817833,2.40855437,-503.250062,47.7942755,-146.690982,0,0,0,2893.7614,-1573.82349,1037.78181,0.05,0.348059655,0.719104556,0.601332599,0.0119256071,0.1,check\n\
c7,-1.01684628,0.16395623,-0.629749701,0.47193703,-0.122365034,1.78374395,-473.736406,52.8576597,-106.870173,0,0,0,3113.88783,-1583.22957,1028.56745,0.05,0.36547107,0.715895409,0.5947279,0.0149460651,0.1,fit\n\
c8,-0.993109798,0.085974919,-0.469301583,0.423888115,-0.308452039,1.77650083,-534.934494,54.4999478,-206.279533,0,0,0,3115.50935,-1603.99044,1228.18004,0.05,0.360581299,0.738876392,0.569247577,1.12620513e-05,0.1,fit\n\
c9,-0.89966487,0.068155107,-0.271939751,0.843430361,-0.966528433,1.84784989,-737.93751,52.9250161,-457.397879,0,0,0,2986.411,-1601.49224,1325.56019,0.05,0.214845393,0.671703021,0.650405354,-0.282186791,0.1,check\n\
c10,-1.01852179,0.288118953,-0.039147735,0.260630017,-1.48595587,2.42934124,-430.890842,46.5759513,-273.547472,0,0,0,2964.56504,-1593.77941,1414.7752,0.05,-0.022784964,0.680283907,0.725953505,-0.0984182889,0.1,fit\n\
c11,-1.17821942,-0.908059903,-0.183102492,0.284925,-1.3496282,2.11741599,-470.677917,-469.304041,-346.216674,0,0,0,2052.76235,-879.150638,951.16655,0.05,-0.0217033127,0.817919607,0.563248714,-0.115270847,0.1,fit\n\
c12,-1.44542933,-0.800146196,-0.083130032,0.103620198,-1.41436247,2.42159198,-276.020095,-976.224977,-575.029118,0,0,0,1970.91261,-1008.10991,1164.76563,0.05,-0.0218987976,0.827511317,0.559863474,-0.0360326683,0.1,check\n";
/// A parallel robot's calibration data: the Orthoglide's commanded poses under the milling wrench, a target's
/// position in an instrument's frame (made by `stiff synth --positions` with a hidden registration, target
/// and actuator offset, 0.002 mm of noise), every third held out.
const LEG_DATA: &str = "pose_id,x_mm,y_mm,z_mm,Fx_N,Fy_N,Fz_N,Mx_Nmm,My_Nmm,Mz_Nmm,mx_mm,my_mm,mz_mm,sigma_mm,set\n\
c0,-60.0,-60.0,-60.0,215.0,-10.0,-25.0,1000.0,21500.0,0.0,927.8465376387719,157.01372816927392,-83.96880366524184,0.002,fit\n\
c12,0.0,0.0,-60.0,215.0,-10.0,-25.0,1000.0,21500.0,0.0,1002.1108307039029,197.0577634871761,-92.35563720336174,0.002,fit\n\
c24,60.0,60.0,-60.0,215.0,-10.0,-25.0,1000.0,21500.0,0.0,1076.5830463464995,237.13837275997454,-100.72458951033178,0.002,check\n\
c36,-30.0,0.0,-30.0,215.0,-10.0,-25.0,1000.0,21500.0,0.0,979.2617475920645,201.7342017279403,-56.86179111197436,0.002,fit\n\
c48,30.0,60.0,-30.0,215.0,-10.0,-25.0,1000.0,21500.0,0.0,1053.621292854992,241.81648816220314,-65.17130844118762,0.002,fit\n\
c60,-60.0,0.0,0.0,215.0,-10.0,-25.0,1000.0,21500.0,0.0,956.4507067665098,206.39557310645216,-21.44285728010121,0.002,check\n\
c72,0.0,60.0,0.0,215.0,-10.0,-25.0,1000.0,21500.0,0.0,1030.7351597239322,246.4774793289033,-29.677134112009565,0.002,fit\n\
c84,60.0,-30.0,30.0,215.0,-10.0,-25.0,1000.0,21500.0,0.0,1065.0415443586053,140.30403098631405,-18.929336107808055,0.002,fit\n\
c96,-30.0,60.0,30.0,215.0,-10.0,-25.0,1000.0,21500.0,0.0,1007.8821415158054,251.12223528561717,5.745913265690788,0.002,check\n\
c108,30.0,-30.0,60.0,215.0,-10.0,-25.0,1000.0,21500.0,0.0,1042.1882946460505,145.0031216340131,16.60748069875844,0.002,fit\n";
/// The same rows with the actuators' readings (`q_1,q_2,q_3`: the Orthoglide's inverse kinematics of the
/// commanded poses), from which the calibration finds the poses.
const LEG_READINGS: &str = "pose_id,x_mm,y_mm,z_mm,q_1,q_2,q_3,Fx_N,Fy_N,Fz_N,Mx_Nmm,My_Nmm,Mz_Nmm,mx_mm,my_mm,mz_mm,sigma_mm,set\n\
c0,-60.0,-60.0,-60.0,-48.170948,-48.170948,-48.170948,215.0,-10.0,-25.0,1000.0,21500.0,0.0,927.8465376387719,157.01372816927392,-83.96880366524184,0.002,fit\n\
c12,0.0,0.0,-60.0,5.857059,5.857059,-60.000000,215.0,-10.0,-25.0,1000.0,21500.0,0.0,1002.1108307039029,197.0577634871761,-92.35563720336174,0.002,fit\n\
c24,60.0,60.0,-60.0,71.829052,71.829052,-48.170948,215.0,-10.0,-25.0,1000.0,21500.0,0.0,1076.5830463464995,237.13837275997454,-100.72458951033178,0.002,check\n\
c36,-30.0,0.0,-30.0,-28.546150,2.914577,-28.546150,215.0,-10.0,-25.0,1000.0,21500.0,0.0,979.2617475920645,201.7342017279403,-56.86179111197436,0.002,fit\n\
c48,30.0,60.0,-30.0,37.339019,62.914577,-22.660981,215.0,-10.0,-25.0,1000.0,21500.0,0.0,1053.621292854992,241.81648816220314,-65.17130844118762,0.002,fit\n\
c60,-60.0,0.0,0.0,-60.000000,5.857059,5.857059,215.0,-10.0,-25.0,1000.0,21500.0,0.0,956.4507067665098,206.39557310645216,-21.44285728010121,0.002,check\n\
c72,0.0,60.0,0.0,5.857059,60.000000,5.857059,215.0,-10.0,-25.0,1000.0,21500.0,0.0,1030.7351597239322,246.4774793289033,-29.677134112009565,0.002,fit\n\
c84,60.0,-30.0,30.0,62.914577,-22.660981,37.339019,215.0,-10.0,-25.0,1000.0,21500.0,0.0,1065.0415443586053,140.30403098631405,-18.929336107808055,0.002,fit\n\
c96,-30.0,60.0,30.0,-22.660981,62.914577,37.339019,215.0,-10.0,-25.0,1000.0,21500.0,0.0,1007.8821415158054,251.12223528561717,5.745913265690788,0.002,check\n\
c108,30.0,-30.0,60.0,37.339019,-22.660981,62.914577,215.0,-10.0,-25.0,1000.0,21500.0,0.0,1042.1882946460505,145.0031216340131,16.60748069875844,0.002,fit\n";
const DATA: &str = "pose_id,x_mm,y_mm,z_mm,Fx_N,Fy_N,Fz_N,Mx_Nmm,My_Nmm,Mz_Nmm,dx_mm,dy_mm,dz_mm,sigma_mm\n\
p0,0,0,0,200,0,0,0,0,0,0.056,0.0001,0.0002,0.002\np0,0,0,0,-200,0,0,0,0,0,-0.056,0,0.0001,0.002\n\
p0,0,0,0,0,200,0,0,0,0,0.0001,0.056,0,0.002\np0,0,0,0,0,0,200,0,0,0,0,0.0001,0.057,0.002\n\
p1,40,-30,20,200,0,0,0,0,0,0.07,0.002,0.003,0.002\np1,40,-30,20,0,200,0,0,0,0,0.002,0.06,0.001,0.002\n\
p1,40,-30,20,0,0,200,0,0,0,0.003,0.001,0.065,0.002\np2,-50,20,60,200,0,0,0,0,0,0.05,0.001,0.01,0.002\n\
p2,-50,20,60,0,200,0,0,0,0,0.001,0.06,0.004,0.002\np2,-50,20,60,0,0,200,0,0,0,0.01,0.004,0.08,0.002\n";

/// A valid command and its input files, then mutated.
fn case(r: &mut StdRng) -> Case {
    let model = MODELS[r.random_range(0..MODELS.len())];
    let model_path = root().join(model).display().to_string();
    let m = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<String>>();
    let mut files: Vec<(String, String)> = Vec::new();
    let mut args: Vec<String> = match r.random_range(0..16) {
        0 | 1 => {
            files.push(("grid.toml".into(), SMALL_GRID.into()));
            m(&["map", &model_path, "--grid", "grid.toml"])
        }
        2 => {
            files.push(("points.csv".into(), POINTS.into()));
            m(&["map", &model_path, "--points", "points.csv", "--stiffness"])
        }
        3 => {
            files.push(("grid.toml".into(), SMALL_GRID.into()));
            m(&["map", &model_path, "--grid", "grid.toml", "--wrench", "215,-10,-25,1000,21500,0"])
        }
        4 => m(&["point", &model_path, "--at", "10,-20,5", "--wrench", "100,0,0,0,2000,0"]),
        5 => m(&[
            "curve",
            &model_path,
            "--at",
            "0,0,0",
            "--wrench-direction",
            "1,0,0,0,0,0",
            "--max",
            "2000",
            "--intervals",
            "4",
        ]),
        6 => m(&[
            "curve",
            &model_path,
            "--at",
            "0,0,0",
            "--displacement-direction",
            "0,0,1,0,0,0",
            "--max",
            "0.5",
            "--intervals",
            "4",
        ]),
        7 => {
            files.push(("errors.toml".into(), shipped("manipulators/errors/orthoglide-case-b.toml")));
            files.push(("points.csv".into(), POINTS.into()));
            let samples = if r.random_bool(0.3) { "--samples=3" } else { "--scale=1" };
            m(&[
                "assemble",
                &root().join(MODELS[0]).display().to_string(),
                "--errors",
                "errors.toml",
                "--points",
                "points.csv",
                samples,
                "--seed=1",
            ])
        }
        8 => {
            files.push(("data.csv".into(), DATA.into()));
            m(&["diagnose", &root().join(MODELS[0]).display().to_string(), "--data", "data.csv"])
        }
        9 => {
            files.push(("grid.toml".into(), SMALL_GRID.into()));
            m(&[
                "synth",
                &root().join(MODELS[0]).display().to_string(),
                "--grid",
                "grid.toml",
                "--wrenches",
                "100,0,0,0,0,0;0,0,-100,0,0,0",
                "--noise",
                "0.002",
                "--seed",
                "3",
                "--effect",
                "actuator-compliance:2=1.5",
            ])
        }
        10 => {
            let (name, text) = if r.random_bool(0.5) {
                ("curve.csv", shipped("tests/golden/curve-small.csv"))
            } else {
                ("map.csv", shipped("tests/golden/orthoglide-3puu-small.csv"))
            };
            files.push((name.into(), text));
            m(&["plot", name, "-o", "out.svg"])
        }
        11 => {
            files.push(("errors.toml".into(), shipped("manipulators/errors/orthoglide-case-a.toml")));
            files.push(("points.csv".into(), POINTS.into()));
            let method = if r.random_bool(0.5) { "--method=newton" } else { "--method=mirror" };
            m(&[
                "compensate",
                &root().join(MODELS[0]).display().to_string(),
                "--errors",
                "errors.toml",
                "--points",
                "points.csv",
                method,
                "--scale=1",
            ])
        }
        12 => {
            files.push(("designs.csv".into(), "design,k_act,d_leg\nsoft,10000,10\nstiff,40000,16\n".into()));
            files.push(("grid.toml".into(), SMALL_GRID.into()));
            let designs = if r.random_bool(0.5) { "--designs=designs.csv" } else { "--vary=k_act=1000:50000:3" };
            let shard = ["--shard=1/1", "--shard=2/3", "--threshold=1e-3", "--sample=lhs:3"][r.random_range(0..4)];
            let sample_ok = designs.starts_with("--vary") || !shard.starts_with("--sample");
            let mut a = m(&["sweep", &root().join(MODELS[0]).display().to_string(), designs, "--grid", "grid.toml"]);
            if sample_ok {
                a.push(shard.into());
            }
            a
        }
        13 => {
            // Two shards of one run, written as `--shard` writes them, for the merge's reader.
            let shard = |k: u64, rows: &str| {
                format!(
                    "# stiff shard {k}/2 run 5a5a\n# stiff portion 0..2 (input indices, end excluded)\n# stiff run \
                     items = 2\n# stiff kinds ctn\nindex,name,x_mm\n{rows}"
                )
            };
            files.push(("s1.csv".into(), shard(1, "0,a,1.5\n")));
            files.push(("s2.csv".into(), shard(2, "1,\"b,c\",-2e-3\n")));
            // Sometimes only listing the missing shards, sometimes a shard given twice.
            let mut a = m(&["merge", "merged.csv", "s1.csv", "s2.csv"]);
            match r.random_range(0..3) {
                0 => a.push("--missing".into()),
                1 => a.push("s1.csv".into()),
                _ => {}
            }
            a
        }
        14 => {
            // A serial arm's calibration (URDF, joint-space data with orientations), or its plan; a parallel
            // robot's.
            files.push(("joints.csv".into(), JOINT_DATA.into()));
            files.push(("legs.csv".into(), if r.random_bool(0.5) { LEG_DATA } else { LEG_READINGS }.into()));
            let fanuc = root().join("manipulators/fanuc-r2000ic.toml").display().to_string();
            let orthoglide = root().join("manipulators/orthoglide-3puu.toml").display().to_string();
            match r.random_range(0..5) {
                // A parallel robot's legs calibrated from positions at commanded poses, or such data made.
                3 => m(&["diagnose", &orthoglide, "--data", "legs.csv", "--check-fraction=0.3", "--seed=2"]),
                4 => {
                    files.push(("grid.toml".into(), SMALL_GRID.into()));
                    m(&[
                        "synth",
                        &orthoglide,
                        "--grid",
                        "grid.toml",
                        "--positions",
                        "--effect",
                        "registration=0.1,0,0.2,500,0,300",
                        "--effect",
                        "actuator-offset:2=0.4",
                        "--noise=0.002",
                        "--seed=1",
                        "--check-every=3",
                        "-o",
                        "legs-out.csv",
                    ])
                }
                0 => m(&["diagnose", &fanuc, "--data", "joints.csv"]),
                1 => m(&[
                    "diagnose",
                    &fanuc,
                    "--data",
                    "joints.csv",
                    "--check-fraction=0.3",
                    "--seed=2",
                    "--sigma-mrad=0.1",
                ]),
                _ => m(&[
                    "plan",
                    &fanuc,
                    "--candidates",
                    "joints.csv",
                    "--budget=4",
                    "--noise=0.05",
                    "--orientation-noise=0.1",
                ]),
            }
        }
        _ => {
            // The model itself mutated (copied with its neighbours, which it may reference).
            files.push((format!("model:{model}"), shipped(model)));
            files.push(("grid.toml".into(), SMALL_GRID.into()));
            m(&["map", "MODEL", "--grid", "grid.toml"])
        }
    };
    // One to three mutations of files or command-line values.
    for _ in 0..r.random_range(1..=3) {
        let choice = r.random_range(0..(files.len() + 2));
        if choice < files.len() {
            let text = &mut files[choice].1;
            *text = mutate(text, r);
        } else if choice == files.len() {
            // A command-line value (not the subcommand or a path).
            let k = r.random_range(1..args.len());
            if !args[k].contains('/') && !args[k].ends_with(".csv") && !args[k].ends_with(".toml") {
                args[k] = mutate_value(&args[k], r);
            }
        } else {
            // An option added with an extreme value.
            match r.random_range(0..4) {
                0 => args.extend([
                    "--threads".into(),
                    ["0", "1", "2", "1000000", "4294967297"][r.random_range(0..5)].into(),
                ]),
                1 => args.extend([
                    "--set".into(),
                    format!(
                        "{}={}",
                        ["E", "L", "d_leg", "d_foot", "k_act", "bar_d", "bar_gap", "mode", "h", "R", "k_theta"]
                            [r.random_range(0..11)],
                        extreme(r)
                    ),
                ]),
                // Device nodes are tested apart (tests/robustness.rs): a regression here must not replace the
                // machine's /dev/null.
                2 => args.extend(["-o".into(), ["out.csv", "-", "missing/out.csv", "."][r.random_range(0..4)].into()]),
                _ => args.extend(["--quiet".into()]),
            }
        }
    }
    Case { args, files }
}

/// Runs a case in its own folder; None when nothing went wrong.
fn run(bin: &Path, c: &Case, dir: &Path) -> Option<Failure> {
    let mut args = c.args.clone();
    for (name, text) in &c.files {
        if let Some(path) = name.strip_prefix("model:") {
            // Copy the manipulators folder (a model may reference its neighbours), then write the mutated
            // text over that model.
            copy_dir(&root().join("manipulators"), &dir.join("manipulators"));
            std::fs::write(dir.join(path), text).unwrap();
            for a in args.iter_mut().filter(|a| *a == "MODEL") {
                *a = dir.join(path).display().to_string();
            }
        } else {
            std::fs::write(dir.join(name), text).unwrap();
        }
    }
    let grid = c.files.iter().find(|(n, _)| n == "grid.toml").map(|(_, t)| requested_points(t));
    let long_job = grid.unwrap_or(0.0) > 1e6;
    let deadline = if long_job { LONG_JOB_WINDOW } else { TIMEOUT };
    let Some(done) = run_with_deadline(Command::new(bin).args(&args).current_dir(dir), STDOUT_LIMIT, deadline) else {
        return (!long_job).then_some(Failure::Hang);
    };
    let (status, out, err) = (done.status, done.stdout, done.stderr);
    if status.code() == Some(101) || err.contains("panicked") {
        return Some(Failure::Panic(err.lines().take(3).collect::<Vec<_>>().join(" | ")));
    }
    #[cfg(unix)]
    {
        use std::os::unix::process::ExitStatusExt;
        if let Some(sig) = status.signal() {
            return Some(Failure::Signal(sig));
        }
    }
    let mut texts = vec![String::from_utf8_lossy(&out).into_owned()];
    for name in ["out.csv"] {
        if let Ok(t) = std::fs::read_to_string(dir.join(name)) {
            texts.push(t);
        }
    }
    texts.iter().find_map(|t| non_finite_ok_row(t)).map(Failure::NonFiniteOk)
}

/// The number of points a grid file's `points` asks for (0 where it cannot be read).
fn requested_points(grid: &str) -> f64 {
    grid.lines()
        .find_map(|l| l.trim().strip_prefix("points = [")?.strip_suffix(']').map(str::to_string))
        .map(|s| s.split(',').map(|v| v.trim().parse::<f64>().unwrap_or(0.0)).product())
        .unwrap_or(0.0)
}

/// A complete CSV row whose `status` is `ok` and which holds a non-finite number.
fn non_finite_ok_row(text: &str) -> Option<String> {
    let mut lines = text.split_inclusive('\n').filter(|l| l.ends_with('\n'));
    let header: Vec<&str> = lines.next()?.trim_end().split(',').collect();
    let status = header.iter().position(|h| *h == "status")?;
    for line in lines {
        let fields: Vec<&str> = line.trim_end().split(',').collect();
        if fields.get(status) != Some(&"ok") {
            continue;
        }
        let bad = fields.iter().any(|f| {
            let f = f.trim();
            f.eq_ignore_ascii_case("nan")
                || f.to_ascii_lowercase().contains("inf") && f.parse::<f64>().is_ok()
                || f.parse::<f64>().is_ok_and(|v| !v.is_finite())
        });
        if bad {
            return Some(line.chars().take(300).collect());
        }
    }
    None
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let target = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &target);
        } else {
            std::fs::copy(e.path(), target).unwrap();
        }
    }
}

/// Runs `cases` seeded cases and returns the failures with the command that caused each.
fn campaign(seed: u64, cases: usize) -> Vec<(String, Failure)> {
    let bin = std::env::var("STIFF_FUZZ_BIN")
        .map(PathBuf::from)
        .unwrap_or_else(|_| PathBuf::from(env!("CARGO_BIN_EXE_stiff")));
    let mut r = StdRng::seed_from_u64(seed);
    let mut failures = Vec::new();
    let mut slowest = (0.0f64, 0usize);
    for k in 0..cases {
        let c = case(&mut r);
        let dir = tempfile::tempdir().unwrap();
        let start = Instant::now();
        let outcome = run(&bin, &c, dir.path());
        if start.elapsed().as_secs_f64() > slowest.0 {
            slowest = (start.elapsed().as_secs_f64(), k);
        }
        if let Some(f) = outcome {
            let files: Vec<String> = c.files.iter().map(|(n, t)| format!("{n}:\n{t}")).collect();
            failures.push((format!("case {k}: stiff {}\n{}", c.args.join(" "), files.join("\n")), f));
        }
    }
    eprintln!("fuzz: slowest case {} took {:.2} s", slowest.1, slowest.0);
    failures
}

/// The seeded campaign CI runs; `STIFF_FUZZ_CASES` and `STIFF_FUZZ_SEED` make it the long one.
#[test]
fn no_input_makes_stiff_panic_hang_abort_or_write_non_finite_ok_rows() {
    let cases = std::env::var("STIFF_FUZZ_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(2000);
    let seed = std::env::var("STIFF_FUZZ_SEED").ok().and_then(|v| v.parse().ok()).unwrap_or(20261123);
    let start = Instant::now();
    let failures = campaign(seed, cases);
    eprintln!(
        "fuzz: {cases} cases (seed {seed}) in {:.1} s, {} failures",
        start.elapsed().as_secs_f64(),
        failures.len()
    );
    for (what, f) in failures.iter().take(10) {
        eprintln!("{f:?}\n  {what}\n");
    }
    assert!(failures.is_empty(), "{} of {cases} fuzz cases failed (first ones above)", failures.len());
}

#[test]
fn mutations_find_every_number() {
    let spots = numbers("a = [1, -2.5e3, 7]\nx_1 = 3\nk = \"k_act\"\n");
    let found: Vec<&str> = spots.iter().map(|&(a, b)| &"a = [1, -2.5e3, 7]\nx_1 = 3\nk = \"k_act\"\n"[a..b]).collect();
    assert_eq!(found, ["1", "-2.5e3", "7", "3"]);
}
