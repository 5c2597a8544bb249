//! `stiff plot`: an SVG picture of a study's output.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use super::args::{check_picture_path, plot_file, MapStyle, PlotStyle};

/// Worked examples on shipped files, shown after `--help` (tests/cli.rs runs each of them).
pub(crate) const EXAMPLES: &str = "Examples:
  stiff map manipulators/orthoglide-3puu.toml --grid manipulators/grids/orthoglide-cube.toml -o cube.csv
  stiff plot cube.csv -o cube.svg --section z=26.35 --plot-column c_rot_max_rad_per_Nmm

Exit status: 0 success, 1 the run failed, 2 usage error.";

#[derive(Args, Debug)]
pub(crate) struct PlotArgs {
    /// A table written by map, curve or assemble (CSV, .csv.gz, .csv.zst or .parquet), or a JSON written
    /// by diagnose --json; `-` reads standard input.
    pub(crate) input: PathBuf,
    /// The picture to write: SVG, or PNG for a .png name (rendered with an embedded font).
    #[arg(short, long)]
    pub(crate) output: PathBuf,
    #[command(flatten)]
    pub(crate) style: MapStyle,
    /// Curve picture: the direction to draw (x, y, z, rx, ry, rz) [default: the one that moves most].
    #[arg(long)]
    pub(crate) direction: Option<String>,
    /// The picture's title, above what it shows (the table does not record its model or load): e.g.
    /// "Orthoglide 3-PUU, unloaded".
    #[arg(long)]
    pub(crate) title: Option<String>,
}

pub(crate) fn run(a: PlotArgs) -> Result<()> {
    let style = PlotStyle { direction: a.direction.clone(), title: a.title.clone(), ..a.style.style() };
    check_picture_path(&a.output)?;
    plot_file(&a.input, &a.output, &style)
}
