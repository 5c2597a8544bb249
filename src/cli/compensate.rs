//! `stiff compensate`: the commands that put the real robot's tool on the targets under the process load.

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::{ArgMatches, Args, ValueEnum};

use super::args::{
    plot_file, plot_needs_output, progress_bar, thread_pool, wrench_text, written, ModelArgs, OutputArgs, PlotStyle,
    PosesArgs, RunArgs,
};
use super::parse::parse_vec6;
use super::shard::{write_shard_preamble, ShardArgs};
use crate::kinematics::frame::Vec6;
use crate::model::assembly_errors::ErrorSet;
use crate::platform::leg::Leg;
use crate::study::assemble::LegErrors;
use crate::study::compensate::{
    compensate_table, run_compensate, CompensateOptions, Method, RealRobot, COMPENSATE_RUN,
};

/// Worked examples on shipped files, shown after `--help` (tests/cli.rs runs each of them).
pub(crate) const EXAMPLES: &str = "Examples:
  stiff compensate manipulators/orthoglide-3puu.toml --errors manipulators/errors/orthoglide-case-a.toml --path -73.65,-73.65,-73.65 -73.65,126.35,-73.65 41 --wrench 215,-10,-25,1000,21500,0 -o commands.csv --plot commands.svg
  stiff compensate manipulators/orthoglide-3puu.toml --errors manipulators/errors/orthoglide-case-b.toml --path -73.65,-73.65,-73.65 -73.65,126.35,-73.65 41 --wrench 215,-10,-25,1000,21500,0 --method mirror -o mirror.csv
  stiff compensate manipulators/orthoglide-3puu.toml --errors manipulators/errors/orthoglide-case-b.toml --path -73.65,-73.65,-73.65 -73.65,126.35,-73.65 2001 --wrench 215,-10,-25,1000,21500,0 --commands-only -o controller.csv
  stiff compensate manipulators/stewart-gough-b.toml --points manipulators/grids/stewart-gough-home.csv --wrench 100,0,-500,0,2000,0 -o stewart.csv

Exit status: 0 success (targets that fail are rows with their status), 1 the run failed, 2 usage error.";

/// `--method`.
#[derive(Clone, Copy, Debug, Default, ValueEnum)]
pub(crate) enum MethodArg {
    /// Newton's method on the command until the robot reaches the target (within 1e-9 mm).
    #[default]
    Newton,
    /// The first-order correction: command = target - the error predicted at the target.
    Mirror,
}

#[derive(Args, Debug)]
pub(crate) struct CompensateArgs {
    #[command(flatten)]
    pub(crate) model: ModelArgs,
    #[command(flatten)]
    pub(crate) poses: PosesArgs,
    /// The process wrench Fx,Fy,Fz,Mx,My,Mz (N, N mm) at the reference point, at every target [default:
    /// each target's own wrench from the grid or points file, zero where it gives none].
    #[arg(long, value_parser = parse_vec6, allow_hyphen_values = true)]
    pub(crate) wrench: Option<Vec6>,
    /// Error file (TOML) of the real robot's legs, as `assemble` reads it, e.g.
    /// manipulators/errors/orthoglide-case-b.toml [default: no leg errors].
    #[arg(long)]
    pub(crate) errors: Option<PathBuf>,
    /// Factor on every leg error of --errors.
    #[arg(long, default_value_t = 1.0, requires = "errors")]
    pub(crate) scale: f64,
    /// How the command is computed.
    #[arg(long, value_enum, default_value_t = MethodArg::Newton)]
    pub(crate) method: MethodArg,
    /// Only what a controller needs: the command, its actuator coordinates and the forward solve that
    /// checks it (residual, stability). The uncompensated and mirror errors are not computed (their columns
    /// stay empty): along a fine path one loaded equilibrium per target instead of three, about 1.4 times
    /// faster. Newton's method only; not with --plot, whose lines are those errors.
    #[arg(long, conflicts_with = "plot")]
    pub(crate) commands_only: bool,
    #[command(flatten)]
    pub(crate) output: OutputArgs,
    /// Also draw the table (SVG, or PNG for a .png name): along a --path, the error along the path without
    /// compensation, with the mirror command and with the command written (paper 000 Figures 10-11 with the
    /// compensation); over a grid or points, the uncompensated error (see --plot-column).
    #[arg(long)]
    pub(crate) plot: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) style: super::args::PointsStyle,
    #[command(flatten)]
    pub(crate) shard: ShardArgs,
    #[command(flatten)]
    pub(crate) run: RunArgs,
}

pub(crate) fn run(a: CompensateArgs, matches: &ArgMatches) -> Result<()> {
    let model = a.model.load_model()?;
    let m = &model.manipulator;
    if let Some(leg) = m.legs.iter().find(|l| matches!(l, Leg::Msa(_))) {
        bail!(
            "leg `{}` is an MSA leg: its actuators are elastic joints, not coordinates a controller sets, so \
             compensate has no command to change (it needs VJM legs with actuated joints)",
            leg.name()
        );
    }
    if m.actuator_units().iter().all(Vec::is_empty) {
        bail!("the model has no actuated coordinate (no joint with role = \"actuated\"): nothing to command");
    }
    if !a.scale.is_finite() {
        bail!("--scale must be a finite number");
    }
    let set = match &a.errors {
        Some(path) => Some(ErrorSet::load(path, &a.model.model, m)?),
        None => None,
    };
    let perturbed = match &set {
        Some(s) => s.perturbed_legs(a.scale)?,
        None => Vec::new(),
    };
    let mut points = a.poses.load(m)?;
    let shard = a.shard.split_points(&mut points, COMPENSATE_RUN, &a.output, a.plot.as_ref())?;
    if a.wrench.is_some() && points.has_wrench {
        bail!(
            "the targets carry their own wrenches (Fx_N..Mz_Nmm) and --wrench gives another: drop --wrench to use \
             each target's, or the wrench columns to use --wrench"
        );
    }
    let method = match a.method {
        MethodArg::Newton => Method::Newton,
        MethodArg::Mirror => Method::Mirror,
    };
    if a.commands_only && method == Method::Mirror {
        bail!(
            "--commands-only leaves out the mirror command's solve, which is what --method mirror writes: drop \
             one of them"
        );
    }
    let options = CompensateOptions { wrench: a.wrench, method, scale: a.scale, commands_only: a.commands_only };
    plot_needs_output(&a.plot, &a.output.output, "compensate")?;
    if let Some(s) = &a.style.section {
        crate::plot::parse_section(s).map_err(|e| anyhow::anyhow!("--section: {e}"))?;
    }
    if !model.measurement_terms.is_empty() && !a.run.quiet {
        eprintln!(
            "note: the model's measurement-model terms ({}) correct measured data, they do not change the robot's \
             description: compensate leaves them out",
            model.measurement_terms.iter().map(|t| t.to_string()).collect::<Vec<_>>().join(", ")
        );
    }
    let pool = thread_pool(a.run.threads)?;
    let table = compensate_table(m);
    let mut sink = a.output.open(&table)?;
    write_shard_preamble(&shard, &mut sink, matches, "compensate", table)?;
    let bar = progress_bar(points.len, a.run.quiet);
    let errors = set.as_ref().map(|set| (LegErrors { set, perturbed: &perturbed }, a.scale));
    let robot = RealRobot { nominal: m, errors };
    let summary = run_compensate(&pool, &robot, &mut points, &options, sink.writer(), &bar)?;
    sink.finish()?;
    bar.finish_and_clear();
    if let Some(plot) = &a.plot {
        let mut run = match &a.errors {
            Some(e) => format!("errors {} x {}", e.display(), a.scale),
            None => "no leg errors".into(),
        };
        match &a.wrench {
            Some(w) => run.push_str(&format!(", wrench {} (N, N mm)", wrench_text(w))),
            None if points.has_wrench => run.push_str(", each target's wrench"),
            None => run.push_str(", unloaded"),
        }
        run.push_str(&format!(", {} method", method.as_str()));
        let style = PlotStyle { title: Some(a.model.title(m, &run)), ..a.style.style() };
        plot_file(written(&a.output.output), plot, &style)?;
    }
    if !a.run.quiet {
        eprintln!("{}", summary.line());
    }
    Ok(())
}
