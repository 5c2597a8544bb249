//! `stiff curve`: a force-deflection curve at one pose.

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;

use super::args::{
    check_picture_path, name_plot_flag, wrench_text, write_plot, ModelArgs, OutputArgs, PlotStyle, PoseArgs,
};
use super::parse::parse_vec6;
use crate::kinematics::frame::Vec6;
use crate::study::curve::{curve_header, curve_table, push_curve_row, run_curve_from, Control, MAX_INTERVALS};

/// Worked examples on shipped files, shown after `--help` (tests/cli.rs runs each of them).
pub(crate) const EXAMPLES: &str = "Examples:
  stiff curve manipulators/orthoglide-3puu.toml --at 0,0,0 --wrench-direction 0,0,-1000,0,0,0 --max 5 -o c.csv
  stiff curve manipulators/orthoglide-3prpar.toml --at 0,0,0 --displacement-direction 1,0,0,0,0,0 --max 0.5 -o d.csv --plot d.svg

Exit status: 0 success (a curve that stops early still writes its rows), 1 the run failed, 2 usage error.";

#[derive(Args, Debug)]
#[command(group = clap::ArgGroup::new("control").required(true).multiple(false))]
pub(crate) struct CurveArgs {
    #[command(flatten)]
    pub(crate) model: ModelArgs,
    #[command(flatten)]
    pub(crate) pose: PoseArgs,
    /// Force control: the wrench is load_factor * W (Fx,Fy,Fz in N, Mx,My,Mz in N mm).
    #[arg(long, group = "control", value_parser = parse_vec6, allow_hyphen_values = true)]
    pub(crate) wrench_direction: Option<Vec6>,
    /// Displacement control: the displacement is load_factor * D (dx,dy,dz in mm, rx,ry,rz in rad).
    #[arg(long, group = "control", value_parser = parse_vec6, allow_hyphen_values = true)]
    pub(crate) displacement_direction: Option<Vec6>,
    /// Largest load factor.
    #[arg(long)]
    pub(crate) max: f64,
    /// Number of equal intervals from 0 to --max (intervals + 1 rows). `--steps`, its former name, is still read.
    #[arg(long, alias = "steps", default_value_t = 50)]
    pub(crate) intervals: usize,
    #[command(flatten)]
    pub(crate) output: OutputArgs,
    /// No summary on stderr.
    #[arg(long, short)]
    pub(crate) quiet: bool,
    /// Also draw the curve (SVG, or PNG for a .png name).
    #[arg(long)]
    pub(crate) plot: Option<PathBuf>,
    /// The direction to draw (x, y, z, rx, ry, rz; default: the one that moves most).
    #[arg(long)]
    pub(crate) direction: Option<String>,
}

pub(crate) fn run(a: CurveArgs) -> Result<()> {
    let model = a.model.load()?;
    let mut state = model.new_state();
    let pose = a.pose.resolve(&model, &mut state)?;
    let at = pose.frame();
    let control = match (a.wrench_direction, a.displacement_direction) {
        (Some(w), None) => Control::Force(w),
        (None, Some(d)) => Control::Displacement(d),
        _ => bail!("give exactly one of --wrench-direction and --displacement-direction"),
    };
    if !(1..=MAX_INTERVALS).contains(&a.intervals) {
        bail!("--intervals must lie between 1 and {MAX_INTERVALS} (each row is a loaded equilibrium)");
    }
    if !(a.max.is_finite() && a.max > 0.0) {
        bail!("--max must be a positive finite number, got {}", a.max);
    }
    // The picture's options and file are checked before the curve runs: a bad one must not fail the run
    // after its table is written.
    let style = PlotStyle { direction: a.direction.clone(), ..PlotStyle::default() };
    if let Some(p) = &a.plot {
        crate::plot::curve::check_curve_options(&style.options()).map_err(name_plot_flag)?;
        check_picture_path(p)?;
    }
    let mut sink = a.output.open(&curve_table())?;
    // Rows are written as they become final; the picture, if asked, is drawn from the same text.
    let mut picture = a.plot.as_ref().map(|_| curve_header());
    let writer = sink.writer();
    writer.write_all(curve_header().as_bytes())?;
    let mut line = String::new();
    let what = match control {
        Control::Force(w) => format!("load factor up to {} times the wrench {} (N, N mm)", a.max, wrench_text(&w)),
        Control::Displacement(d) => {
            format!("load factor up to {} times the displacement {} (mm, rad)", a.max, wrench_text(&d))
        }
    };
    let title = a
        .model
        .title(&model, &format!("at ({}, {}, {}) mm, {what}", pose.position[0], pose.position[1], pose.position[2]));
    let summary = run_curve_from(&model, &at, state, control, a.max, a.intervals, &mut |r| {
        line.clear();
        push_curve_row(&mut line, r);
        if let Some(p) = picture.as_mut() {
            p.push_str(&line);
        }
        writer.write_all(line.as_bytes())
    })?;
    sink.finish()?;
    if let (Some(plot), Some(text)) = (&a.plot, &picture) {
        let style = PlotStyle { title: Some(title), ..style };
        write_plot(text.as_bytes(), plot, &style)?;
    }
    if !a.quiet {
        eprintln!("{}", summary.text(model.length_scale));
    }
    Ok(())
}
