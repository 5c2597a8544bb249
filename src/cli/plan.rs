//! `stiff plan`: which measurements to take so that `diagnose` can name and separate the effects.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;

use super::args::{arm_points, point_set_any, write_stdout, ModelArgs, OutputArgs};
use super::parse::parse_wrench_list;
use crate::diagnose::plan::{plan, plan_arm, plan_table, write_plan, Plan, PlanOptions};

/// Worked examples on shipped files, shown after `--help` (tests/cli.rs runs each of them).
pub(crate) const EXAMPLES: &str = "Examples:
  stiff plan manipulators/orthoglide-3puu.toml --grid manipulators/grids/orthoglide-small.toml --loads \"200,0,0,0,0,0;-200,0,0,0,0,0;0,200,0,0,0,0;0,-200,0,0,0,0;0,0,200,0,0,0;0,0,-200,0,0,0\" --budget 30 --noise 0.002 -o plan.csv
  stiff synth manipulators/orthoglide-3puu.toml --points plan.csv --effect backlash:1=0.01 --noise 0.002 --seed 1 -o planned.csv
  stiff plan manipulators/fanuc-r2000ic.toml --candidates manipulators/grids/fanuc-r2000ic-cable-tests.csv --budget 15 --noise 0.05 -o arm-plan.csv

Exit status: 0 success, 1 the run failed, 2 usage error.";

#[derive(Args, Debug)]
pub(crate) struct PlanArgs {
    #[command(flatten)]
    pub(crate) model: ModelArgs,
    #[command(flatten)]
    pub(crate) poses: CandidateArgs,
    /// The loads to choose from: Fx,Fy,Fz,Mx,My,Mz (N, N mm) separated by `;` (for a serial arm's
    /// configurations, optional: the arm's own weight alone where not given).
    #[arg(long, allow_hyphen_values = true)]
    pub(crate) loads: Option<String>,
    /// Measurements to choose (pose and load pairs, each at most once).
    #[arg(long)]
    pub(crate) budget: usize,
    /// Effects to plan for, comma-separated: NAME (every target) or NAME:TARGET (default: every candidate
    /// of the library the candidates can show, drift excepted).
    #[arg(long, value_delimiter = ',')]
    pub(crate) effects: Vec<String>,
    /// Standard deviation of the measurement noise, mm.
    #[arg(long)]
    pub(crate) noise: f64,
    /// A serial arm's calibration: the instrument measures the target's orientation too, with this standard
    /// deviation about each axis (mrad); the plan weighs what the orientations tell beside the positions.
    #[arg(long, value_name = "MRAD")]
    pub(crate) orientation_noise: Option<f64>,
    /// A parallel robot's plan for the calibration of its legs from positions in an instrument's frame at
    /// the candidate poses (`stiff diagnose` on `synth --positions` data), instead of displacements under
    /// loads; `--loads` is then optional (each pose under its own wrench where none are given).
    #[arg(long)]
    pub(crate) positions: bool,
    /// Choose the measurements at random with this seed instead: a baseline to compare a plan with.
    #[arg(long, value_name = "SEED")]
    pub(crate) random: Option<u64>,
    #[command(flatten)]
    pub(crate) output: OutputArgs,
}

/// Where the candidate poses come from.
#[derive(Args, Debug)]
#[group(required = true, multiple = false)]
pub(crate) struct CandidateArgs {
    /// Candidate poses (CSV with x_mm,y_mm,z_mm, optional name), or a serial arm's configurations (one
    /// column q_<joint> per joint: the plan is then for the calibration of joint-space data).
    #[arg(long)]
    pub(crate) candidates: Option<PathBuf>,
    /// Candidate poses from a grid file (TOML).
    #[arg(long)]
    pub(crate) grid: Option<PathBuf>,
}

pub(crate) fn run(a: PlanArgs) -> Result<()> {
    let model = a.model.load_model()?;
    let loads = parse_wrench_list(a.loads.as_deref()).map_err(|e| anyhow::anyhow!("--loads: {e}"))?;
    // The same bounds as a measurement's sigma in diagnose: below a picometre the weights' squares overflow.
    use crate::diagnose::data::{MAX_MAGNITUDE, MIN_SIGMA_MM};
    if !(MIN_SIGMA_MM..=MAX_MAGNITUDE).contains(&a.noise) {
        let e = crate::diagnose::error::DiagnoseError::NoiseOutOfRange { sigma: a.noise };
        bail!("--noise: {e}");
    }
    if a.budget == 0 {
        bail!("--budget must be at least 1");
    }
    let m = &model.manipulator;
    let mut set = arm_points(m, point_set_any(&a.poses.grid, &a.poses.candidates)?, a.poses.candidates.as_deref())?;
    let mut poses = Vec::new();
    while set.next_block(4096, &mut poses)? > 0 {}
    let arm = !set.joint_names.is_empty();
    if !arm && m.joint_space.is_some() {
        bail!(
            "{} is a serial arm: its plan is for calibration data, from candidate configurations (--candidates with one column q_<joint> per joint)",
            m.name
        );
    }
    let positions = arm || a.positions;
    if !positions && loads.is_empty() {
        bail!("give --loads: the loads the measurements may be taken under");
    }
    let orientation_noise = match a.orientation_noise {
        None => None,
        Some(_) if !positions => {
            bail!("--orientation-noise is for a calibration from positions (a serial arm's candidates with q_<joint> columns, or --positions)")
        }
        Some(s) if (MIN_SIGMA_MM..=MAX_MAGNITUDE).contains(&s) => Some(s * 1e-3),
        Some(s) => bail!("--orientation-noise must lie in [{MIN_SIGMA_MM:e}, {MAX_MAGNITUDE:e}] mrad, got {s}"),
    };
    let o = PlanOptions {
        loads,
        budget: a.budget,
        effects: a.effects.clone(),
        noise: a.noise,
        orientation_noise,
        random: a.random,
    };
    let mut sink = a.output.open(&plan_table(&set.joint_names))?;
    let p = if arm {
        plan_arm(m, &crate::diagnose::calibrate::configurations(&poses), None, &o)?
    } else if positions {
        let frames: Vec<crate::kinematics::frame::Frame> = poses.iter().map(|p| p.frame()).collect();
        plan_arm(m, &crate::diagnose::calibrate::configurations(&poses), Some(&frames), &o)?
    } else {
        plan(&model, &poses, &o)?
    };
    let mut rows = String::new();
    write_plan(&p, &mut rows);
    sink.writer().write_all(rows.as_bytes())?;
    sink.finish()?;
    let how = if a.random.is_some() { "chosen at random" } else { "greedy D-optimal on the effects' parameters" };
    let noise = match a.orientation_noise {
        Some(o) => format!("{:e} mm and {o:e} mrad", a.noise),
        None => format!("{:e} mm", a.noise),
    };
    write_stdout(&report(&p, how, &noise, positions))
}

/// What the plan achieves, for a person.
fn report(p: &Plan, how: &str, noise: &str, calibration: bool) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{} of {} candidate measurements ({how}); noise {noise}; log det of the information {:.2}",
        p.measurements.len(),
        p.candidates,
        p.log_det
    );
    let units = match calibration {
        false => "factor - 1 for compliance factors",
        true => "rad or mm for offsets and play, rad/(N mm) or mm/N for compliances added at a joint or the tool, mm and rad for geometry, kg and kg mm for the payload, mm per row for a drift",
    };
    let _ = writeln!(s, "smallest size detectable at 5 sigma (weakest direction; {units}):");
    let _ = writeln!(s, "  {:<26} {:>4} {:>14} {:>18}", "effect", "dim", "alone", "beside the others");
    for d in &p.detectable {
        let _ = writeln!(s, "  {:<26} {:>4} {:>14.4e} {:>18.4e}", d.label, d.dim, d.alone, d.beside_others);
    }
    if !p.unseen.is_empty() {
        let _ = writeln!(s, "not seen by any candidate (not planned for): {}", p.unseen.join(", "));
    }
    if p.inseparable.is_empty() {
        let _ = writeln!(s, "every pair of effects is separable on this plan");
    }
    for (a, b, sine) in &p.inseparable {
        let _ =
            writeln!(s, "inseparable on this plan: {a} and {b} (sine of the smallest angle between them {sine:.1e})");
    }
    s
}
