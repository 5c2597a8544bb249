//! `stiff sweep`: many designs of one description, each mapped over a workspace and summarised in a row.

use std::path::PathBuf;

use anyhow::{anyhow, bail, Result};
use clap::{ArgMatches, Args};

use super::args::{progress_bar, thread_pool, LoadArgs, ModelArgs, OutputArgs, PointsArgs, RunArgs};
use super::parse::{parse_parameter_range, parse_sample};
use super::shard::{write_shard_preamble, ShardArgs};
use crate::model::build::parameter_values;
use crate::model::error::read_text;
use crate::study::sweep::{
    run_sweep, sweep_layout, sweep_table, Description, DesignSet, ParameterRange, SweepOptions, Workspace,
};

/// Worked examples on shipped files, shown after `--help` (tests/cli.rs runs each of them).
pub(crate) const EXAMPLES: &str = "Examples:
  stiff sweep manipulators/orthoglide-3puu.toml --vary k_act=10000:40000:7 --vary d_leg=10:16:4 --grid manipulators/grids/orthoglide-q.toml -o designs.csv
  stiff sweep manipulators/orthoglide-3puu.toml --vary L=280:340 --vary d_leg=10:16 --sample lhs:50 --seed 7 --grid manipulators/grids/orthoglide-small.toml --threshold 1e-3 -o lhs.csv
  stiff sweep manipulators/navaro2.toml --vary mode=1:2:2 --grid manipulators/grids/navaro2-workspace.toml --maps maps/ -o modes.csv

A design sets parameters of the description ([parameters], in that file's units) as --set does; a design
whose description cannot be built is a row with status `invalid` and the reason. Statistics are over the
points where the map has a value: max, mean and p95 (linear between ranks, numpy's default) of
c_tran_max_mm_per_N, c_rot_max_rad_per_Nmm and, with a wrench, deflection_mm; worst_* is the point of
largest c_tran_max; counts per status; reachable_fraction = 1 - unreachable / points.

Exit status: 0 success (invalid designs and failed points are rows), 1 the run failed, 2 usage error.";

#[derive(Args, Debug)]
pub(crate) struct SweepArgs {
    #[command(flatten)]
    pub(crate) model: ModelArgs,
    /// Designs file (CSV): one column per parameter, named as in [parameters], and optionally a `design`
    /// column of names.
    #[arg(long, conflicts_with_all = ["vary", "sample"], required_unless_present = "vary")]
    pub(crate) designs: Option<PathBuf>,
    /// A parameter's range NAME=FROM:TO:COUNT (repeatable): the full factorial of the values, the first
    /// --vary varying slowest. With --sample, NAME=FROM:TO (a COUNT is not used).
    #[arg(long, value_name = "NAME=FROM:TO:COUNT", value_parser = parse_parameter_range)]
    pub(crate) vary: Vec<ParameterRange>,
    /// Instead of the factorial, lhs:N: a Latin hypercube of N designs over the --vary ranges.
    #[arg(long, value_name = "lhs:N", value_parser = parse_sample, requires = "vary")]
    pub(crate) sample: Option<u64>,
    /// Seed of --sample (the same seed gives the same designs).
    #[arg(long, default_value_t = 1, requires = "sample")]
    pub(crate) seed: u64,
    #[command(flatten)]
    pub(crate) points: PointsArgs,
    #[command(flatten)]
    pub(crate) load: LoadArgs,
    /// Also count the points where c_tran_max is at most this (mm/N), and for a box grid the workspace
    /// volume they stand for (points x the grid's cell volume, mm^3).
    #[arg(long, value_name = "C_MM_PER_N")]
    pub(crate) threshold: Option<f64>,
    /// Also write each design's whole map into this folder (created if needed), as design-INDEX.csv:
    /// the rows `stiff map --set ...` writes for that design.
    #[arg(long, value_name = "DIR")]
    pub(crate) maps: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) output: OutputArgs,
    #[command(flatten)]
    pub(crate) shard: ShardArgs,
    #[command(flatten)]
    pub(crate) run: RunArgs,
}

pub(crate) fn run(a: SweepArgs, matches: &ArgMatches) -> Result<()> {
    // The description with --set must build: a file that never builds is an error, not a sweep of
    // invalid designs.
    let nominal = a.model.load_model()?;
    let source = read_text(&a.model.model)?;
    let known = parameter_values(&a.model.model, &source)?;
    let mut designs = match (&a.designs, a.sample) {
        (Some(file), _) => DesignSet::from_csv(file)?,
        (None, Some(n)) => DesignSet::latin_hypercube(&a.vary, n, a.seed).map_err(|e| anyhow!("--sample {e}"))?,
        (None, None) => DesignSet::factorial(&a.vary).map_err(|e| anyhow!("--vary {e}"))?,
    };
    if let Some(p) = designs.repeated_parameter() {
        bail!("parameter `{p}` is given twice (one --vary or one designs column per parameter)");
    }
    for p in &designs.parameters {
        if !known.contains_key(p) {
            let names: Vec<&str> = known.keys().map(String::as_str).collect();
            bail!("no parameter `{p}` in {} (its parameters: {})", a.model.model.display(), names.join(", "));
        }
    }
    if let Some(c) = a.threshold {
        if !(c > 0.0 && c.is_finite()) {
            bail!("--threshold must be a positive compliance (mm/N), got {c}");
        }
    }
    let mut points = a.points.load(&nominal.manipulator)?;
    let map = a.load.map_options(&points, false)?;
    let shard = a.shard.plan(|| Ok(designs.len()), 1, &a.output, None)?;
    if let Some(s) = &shard {
        designs.keep_portion(s.portion.clone());
    }
    if let Some(dir) = &a.maps {
        std::fs::create_dir_all(dir).map_err(|e| anyhow!("--maps {}: {}", dir.display(), e.kind()))?;
    }
    let options = SweepOptions { map, threshold: a.threshold, maps: a.maps.clone() };
    let workspace = Workspace::read(&mut points, &options.map)?;
    let pool = thread_pool(a.run.threads)?;
    let table = sweep_table(&sweep_layout(&designs, &workspace, &options));
    let mut sink = a.output.open(&table)?;
    write_shard_preamble(&shard, &mut sink, matches, "sweep", table)?;
    let bar = progress_bar(Some(designs.len()), a.run.quiet);
    let base = a.model.set.iter().cloned().collect();
    let description = Description { path: &a.model.model, source: &source, base };
    let summary = run_sweep(&pool, description, &mut designs, &workspace, &options, sink.writer(), &bar)?;
    sink.finish()?;
    bar.finish_and_clear();
    if !a.run.quiet {
        eprintln!("{}", summary.line());
    }
    Ok(())
}
