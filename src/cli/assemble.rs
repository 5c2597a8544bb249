//! `stiff assemble`: legs with geometric errors put together.

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::{ArgMatches, Args};

use super::args::{
    plot_file, plot_needs_output, progress_bar, select_columns, thread_pool, wrench_text, written, ModelArgs,
    OutputArgs, PlotStyle, PointsStyle, PosesArgs, RunArgs,
};
use super::parse::parse_vec6;
use super::shard::{write_shard_preamble, ShardArgs};
use crate::kinematics::frame::Vec6;
use crate::model::assembly_errors::ErrorSet;
use crate::study::assemble::{assemble_selection, assemble_table, run_assemble, AssembleOptions, LegErrors};

/// Most tolerance samples per point (`assemble --samples`): each row waits for all of its samples.
const MAX_SAMPLES: usize = 10_000_000;

/// Worked examples on shipped files, shown after `--help` (tests/cli.rs runs each of them).
pub(crate) const EXAMPLES: &str = "Examples:
  stiff assemble manipulators/orthoglide-3puu.toml --errors manipulators/errors/orthoglide-case-a.toml --grid manipulators/grids/orthoglide-q.toml -o a.csv
  stiff assemble manipulators/orthoglide-3puu.toml --errors manipulators/errors/orthoglide-case-b.toml --path -200,0,0 300,0,0 26 --wrench 215,-10,-25,1000,21500,0 -o path.csv --plot path.svg
  stiff assemble manipulators/orthoglide-3puu.toml --errors manipulators/errors/orthoglide-case-a.toml --grid manipulators/grids/orthoglide-small.toml --samples 1000 -o tol.csv

Exit status: 0 success, 1 the run failed, 2 usage error.";

#[derive(Args, Debug)]
pub(crate) struct AssembleArgs {
    #[command(flatten)]
    pub(crate) model: ModelArgs,
    /// Error file (TOML): per leg, eps, a base error and/or parameter values, e.g.
    /// manipulators/errors/orthoglide-case-a.toml.
    #[arg(long)]
    pub(crate) errors: PathBuf,
    #[command(flatten)]
    pub(crate) poses: PosesArgs,
    /// External wrench Fx,Fy,Fz,Mx,My,Mz (N, N mm): adds the load, total and superposition columns.
    #[arg(long, value_parser = parse_vec6, allow_hyphen_values = true)]
    pub(crate) wrench: Option<Vec6>,
    /// Factor on every error.
    #[arg(long, default_value_t = 1.0)]
    pub(crate) scale: f64,
    /// Tolerance study: this many random draws of the errors within +-(scale x the given values).
    #[arg(long, default_value_t = 0)]
    pub(crate) samples: usize,
    /// Seed of the random draws (with --samples).
    #[arg(long, default_value_t = 1)]
    pub(crate) seed: u64,
    #[command(flatten)]
    pub(crate) output: OutputArgs,
    /// The columns to write: names or groups (pose, status, linear, nonlinear, loads, joints, load, total,
    /// super, samples), comma-separated, written in the table's order [default: all].
    #[arg(long, value_delimiter = ',')]
    pub(crate) columns: Option<Vec<String>>,
    /// Also draw the table (SVG, or PNG for a .png name): along a --path, the displacements (paper 000 Figures 10-11); over a grid, a
    /// colour map of the chosen column; named points, a dot chart; a tolerance study, its mean displacement.
    #[arg(long)]
    pub(crate) plot: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) style: PointsStyle,
    #[command(flatten)]
    pub(crate) shard: ShardArgs,
    #[command(flatten)]
    pub(crate) run: RunArgs,
}

pub(crate) fn run(a: AssembleArgs, matches: &ArgMatches) -> Result<()> {
    let model = a.model.load()?;
    let set = ErrorSet::load(&a.errors, &a.model.model, &model)?;
    if !(a.scale.is_finite()) {
        bail!("--scale must be a finite number");
    }
    let perturbed = set.perturbed_legs(a.scale)?;
    let mut points = a.poses.load(&model)?;
    let shard = a.shard.split_points(&mut points, crate::batch::RUN, &a.output, a.plot.as_ref())?;
    let pool = thread_pool(a.run.threads)?;
    let mut options =
        AssembleOptions { wrench: a.wrench, scale: a.scale, samples: a.samples, seed: a.seed, selection: None };
    options.selection = select_columns(&a.columns, |w| assemble_selection(model.legs.len(), &options, w))?;
    if a.samples > MAX_SAMPLES {
        bail!(
            "--samples {} is more than a point may take ({MAX_SAMPLES}: about 5 s per point at 2 million \
             assemblies/s; the spread converges long before)",
            a.samples
        );
    }
    plot_needs_output(&a.plot, &a.output.output, "assemble")?;
    if a.plot.is_some() {
        // The picture is drawn from the written table: it needs the poses, what marks the table
        // (the non-linear displacement, or the samples' mean) and the column drawn; checked before the run.
        let header = crate::study::assemble::assemble_header(model.legs.len(), &options);
        let columns: Vec<&str> = header.trim_end().split(',').collect();
        let marks: &[&str] =
            if a.samples > 0 { &["samples", "mean_dx_mm"] } else { &["nl_dx_mm", "nl_dy_mm", "nl_dz_mm"] };
        let chosen = a.style.column.as_deref();
        for needed in ["x_mm", "y_mm", "z_mm"].iter().chain(marks).copied().chain(chosen) {
            if !columns.contains(&needed) {
                bail!(
                    "--plot draws the written columns: `{needed}` is not among them (see --columns, and the \
                     groups pose, nonlinear, samples)"
                );
            }
        }
        if let Some(s) = &a.style.section {
            crate::plot::parse_section(s).map_err(|e| anyhow::anyhow!("--section: {e}"))?;
        }
    }
    let table = assemble_table(model.legs.len(), &options);
    let mut sink = a.output.open(&table)?;
    write_shard_preamble(&shard, &mut sink, matches, "assemble", table)?;
    let bar = progress_bar(points.len, a.run.quiet);
    let summary = run_assemble(
        &pool,
        &model,
        &LegErrors { set: &set, perturbed: &perturbed },
        &mut points,
        &options,
        sink.writer(),
        &bar,
    )?;
    sink.finish()?;
    bar.finish_and_clear();
    if let Some(plot) = &a.plot {
        let mut run = format!("errors {} x {}", a.errors.display(), a.scale);
        if let Some(w) = &a.wrench {
            run.push_str(&format!(", wrench {} (N, N mm)", wrench_text(w)));
        }
        if a.samples > 0 {
            run.push_str(&format!(", {} samples, seed {}", a.samples, a.seed));
        }
        let style = PlotStyle { title: Some(a.model.title(&model, &run)), ..a.style.style() };
        plot_file(written(&a.output.output), plot, &style)?;
    }
    if !a.run.quiet {
        eprintln!("{} points: {} assembled", summary.points, summary.ok);
    }
    Ok(())
}
