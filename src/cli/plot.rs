//! `stiff plot`: an SVG picture of a study's output.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use super::args::{write_plot, PlotStyle};
use crate::model::error::read_text;

#[derive(Args, Debug)]
pub(crate) struct PlotArgs {
    /// A CSV written by map, curve or assemble, or a JSON written by diagnose --json.
    pub(crate) input: PathBuf,
    /// The SVG to write.
    #[arg(short, long)]
    pub(crate) output: PathBuf,
    #[command(flatten)]
    pub(crate) style: PlotStyle,
}

pub(crate) fn run(a: PlotArgs) -> Result<()> {
    let text = read_text(&a.input)?;
    write_plot(&text, &a.output, &a.style)
}
