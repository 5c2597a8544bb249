//! `stiff map`: a compliance map over a grid or points.

use std::path::PathBuf;

use anyhow::Result;
use clap::{ArgMatches, Args};

use super::args::{
    name_plot_flag, plot_file, plot_needs_output, progress_bar, select_columns, thread_pool, wrench_text, written,
    LoadArgs, MapStyle, ModelArgs, OutputArgs, PlotStyle, PointsArgs, RunArgs,
};
use super::shard::{write_shard_preamble, ShardArgs};
use crate::study::map::{map_columns, map_header, map_selection, map_table, run_map};

/// Worked examples on shipped files, shown after `--help` (tests/cli.rs runs each of them).
pub(crate) const EXAMPLES: &str = "Examples:
  stiff map manipulators/orthoglide-3puu.toml --grid manipulators/grids/orthoglide-cube.toml -o cube.csv
  stiff map manipulators/orthoglide-3puu.toml --grid manipulators/grids/orthoglide-q.toml --loaded --stiffness -o q.csv
  stiff map manipulators/navaro2.toml --grid manipulators/grids/navaro2-workspace.toml -o navaro.csv --plot navaro.svg

Exit status: 0 success (points that fail are rows with their status), 1 the run failed, 2 usage error.";

#[derive(Args, Debug)]
pub(crate) struct MapArgs {
    #[command(flatten)]
    pub(crate) model: ModelArgs,
    #[command(flatten)]
    pub(crate) points: PointsArgs,
    #[command(flatten)]
    pub(crate) output: OutputArgs,
    /// Also write the 21 entries of the stiffness matrix (K11..K66).
    #[arg(long)]
    pub(crate) stiffness: bool,
    #[command(flatten)]
    pub(crate) load: LoadArgs,
    /// The columns to write: names or groups (pose, status, principal, deflection, C, K), comma-separated,
    /// written in the table's order [default: all]. For very large maps `--columns pose,status,principal`
    /// writes 12 columns instead of 33 or more.
    #[arg(long, value_delimiter = ',')]
    pub(crate) columns: Option<Vec<String>>,
    /// Also draw the map (SVG, or PNG for a .png name): colour maps over grid sections, or the picture its
    /// points call for (line chart, markers, named dot chart).
    #[arg(long)]
    pub(crate) plot: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) style: MapStyle,
    #[command(flatten)]
    pub(crate) shard: ShardArgs,
    #[command(flatten)]
    pub(crate) run: RunArgs,
}

pub(crate) fn run(a: MapArgs, matches: &ArgMatches) -> Result<()> {
    let model = a.model.load()?;
    let mut points = a.points.load(&model)?;
    let shard = a.shard.split_points(&mut points, crate::batch::RUN, &a.output, a.plot.as_ref())?;
    let pool = thread_pool(a.run.threads)?;
    let mut options = a.load.map_options(&points, a.stiffness)?;
    options.tips = a.model.map_tips(&model);
    let columns = map_columns(&points, &options);
    options.selection = select_columns(&a.columns, |w| map_selection(&columns, w))?;
    let table = map_table(&columns, options.selection.as_ref());
    let mut sink = a.output.open(&table)?;
    write_shard_preamble(&shard, &mut sink, matches, "map", table)?;
    plot_needs_output(&a.plot, &a.output.output, "map")?;
    if a.plot.is_some() {
        let header = map_header(&columns, options.selection.as_ref());
        crate::plot::check_map_options(&header, &a.style.style().options()).map_err(name_plot_flag)?;
    }
    let bar = progress_bar(points.len, a.run.quiet);
    let summary = run_map(&pool, &model, &mut points, options, sink.writer(), &bar)?;
    sink.finish()?;
    bar.finish_and_clear();
    if let Some(plot) = &a.plot {
        let load = match (a.load.wrench, a.load.loaded) {
            (Some(w), _) => format!("loaded by wrench {} (N, N mm)", wrench_text(&w)),
            (None, true) => "loaded by each point's reference wrench".into(),
            (None, false) if points.has_wrench => "deflections under each point's reference wrench".into(),
            (None, false) => "unloaded".into(),
        };
        let style = PlotStyle { title: Some(a.model.title(&model, &load)), ..a.style.style() };
        plot_file(written(&a.output.output), plot, &style)?;
    }
    if !a.run.quiet {
        eprintln!("{}", summary.line());
    }
    Ok(())
}
