//! The command line: subcommands, progress on stderr, errors with what to do.

use std::io::IsTerminal;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use crate::kinematics::frame::{Vec3, Vec6};
use crate::model::grid::{PointSet, PosePoint};
use crate::model::load_manipulator;
use crate::output::report::point_report;
use crate::output::sink::Sink;
use crate::study::map::{run_map, MapOptions};
use crate::study::point::unloaded_point;

#[derive(Parser, Debug)]
#[command(name = "stiff", version, about = "Stiffness of parallel robots: maps, points (units: mm, N, N mm, rad)")]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Compliance map over a grid or a list of points, as CSV (one row per point, in input order).
    Map(MapArgs),
    /// Stiffness and compliance matrices at one pose, printed with units.
    Point(PointArgs),
}

#[derive(Args, Debug)]
pub struct MapArgs {
    /// Manipulator description (TOML), e.g. manipulators/orthoglide-3puu.toml.
    pub model: PathBuf,
    /// Grid file (TOML): a [box] and/or named [[point]]s.
    #[arg(long, conflicts_with = "points", required_unless_present = "points")]
    pub grid: Option<PathBuf>,
    /// Points file (CSV) with columns x_mm,y_mm,z_mm (optional: name, pose_r*_rad, Fx_N..Mz_Nmm).
    #[arg(long)]
    pub points: Option<PathBuf>,
    /// Output CSV; `-` or absent: stdout. Written to a temporary file and renamed on success.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Also write the 21 entries of the stiffness matrix (K11..K66).
    #[arg(long)]
    pub stiffness: bool,
    #[command(flatten)]
    pub run: RunArgs,
}

#[derive(Args, Debug)]
pub struct RunArgs {
    /// Worker threads (default: all cores). The output is the same for any number.
    #[arg(long)]
    pub threads: Option<usize>,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

#[derive(Args, Debug)]
pub struct PointArgs {
    /// Manipulator description (TOML).
    pub model: PathBuf,
    /// Platform reference point x,y,z in mm.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub at: Vec3,
    /// Platform orientation as a rotation vector rx,ry,rz in rad (default 0,0,0).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub orientation: Option<Vec3>,
    /// A wrench Fx,Fy,Fz,Mx,My,Mz (N, N mm) whose linear deflection to report.
    #[arg(long, value_parser = parse_vec6, allow_hyphen_values = true)]
    pub wrench: Option<Vec6>,
}

fn parse_numbers(s: &str, n: usize) -> Result<Vec<f64>, String> {
    let v: Result<Vec<f64>, _> = s.split(',').map(|t| t.trim().parse::<f64>()).collect();
    match v {
        Ok(v) if v.len() == n && v.iter().all(|x| x.is_finite()) => Ok(v),
        _ => Err(format!("expected {n} comma-separated numbers, got `{s}`")),
    }
}

fn parse_vec3(s: &str) -> Result<Vec3, String> {
    parse_numbers(s, 3).map(|v| Vec3::from_column_slice(&v))
}

fn parse_vec6(s: &str) -> Result<Vec6, String> {
    parse_numbers(s, 6).map(|v| Vec6::from_column_slice(&v))
}

pub fn run() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Map(a) => map(a),
        Command::Point(a) => point(a),
    }
}

fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    let mut b = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        if n == 0 {
            bail!("--threads must be at least 1");
        }
        b = b.num_threads(n);
    }
    b.build().context("cannot start the worker threads")
}

fn progress_bar(len: Option<u64>, quiet: bool) -> ProgressBar {
    if quiet || !std::io::stderr().is_terminal() {
        return ProgressBar::with_draw_target(len, ProgressDrawTarget::hidden());
    }
    let bar = match len {
        Some(n) => ProgressBar::new(n),
        None => ProgressBar::new_spinner(),
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{elapsed_precise} [{wide_bar}] {human_pos}/{human_len} points, {per_sec}, eta {eta}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar
}

fn map(a: MapArgs) -> Result<()> {
    let model = load_manipulator(&a.model)?;
    let mut points = match (&a.grid, &a.points) {
        (Some(g), None) => PointSet::from_grid_file(g)?,
        (None, Some(p)) => PointSet::from_points_csv(p)?,
        _ => bail!("give exactly one of --grid and --points"),
    };
    let pool = thread_pool(a.run.threads)?;
    let mut sink = Sink::create(a.output.as_deref())?;
    let bar = progress_bar(points.len, a.run.quiet);
    let summary = run_map(&pool, &model, &mut points, MapOptions { stiffness: a.stiffness }, sink.writer(), &bar)?;
    sink.finish()?;
    bar.finish_and_clear();
    if !a.run.quiet {
        eprintln!(
            "{} points: {} ok, {} unreachable, {} singular",
            summary.points, summary.ok, summary.unreachable, summary.singular
        );
    }
    Ok(())
}

fn point(a: PointArgs) -> Result<()> {
    let model = load_manipulator(&a.model)?;
    let p =
        PosePoint { name: None, position: a.at, rotation: a.orientation.unwrap_or_else(Vec3::zeros), wrench: a.wrench };
    let mut state = model.new_state();
    let r = unloaded_point(&model, &p, &mut state);
    print!("{}", point_report(&model.name, &p, &r));
    Ok(())
}
