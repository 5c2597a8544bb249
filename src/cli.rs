//! The command line: subcommands, progress on stderr, errors with what to do.

use std::io::IsTerminal;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use crate::kinematics::frame::{Frame, Vec3, Vec6};
use crate::model::assembly_errors::ErrorSet;
use crate::model::error::read_text;
use crate::model::grid::{PointSet, PosePoint};
use crate::model::{parse_with, Model};
use crate::output::sink::Sink;
use crate::platform::manipulator::Manipulator;
use crate::study::assemble::{path_points, run_assemble, AssembleOptions, LegErrors};
use crate::study::curve::{curve_header, push_curve_row, run_curve, Control, MAX_INTERVALS};
use crate::study::map::{run_map, MapOptions};
use crate::study::point::point_report;
use crate::study::point::{loaded_point, unloaded_point, LoadedHistory};

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
    /// Force-deflection curve at one pose (loaded mode), as CSV.
    Curve(CurveArgs),
    /// Assembly of legs with geometric errors (paper 000 s. 4.2): platform displacement, internal loads,
    /// joint deflections, linear and non-linear, with an optional external wrench; tolerance studies.
    Assemble(AssembleArgs),
    /// Where measured deflections and the model disagree: names the missing effect (or none), fits it,
    /// and writes the corrected model.
    Diagnose(DiagnoseArgs),
    /// Synthetic measurements with hidden effects, in the format `diagnose` reads.
    Synth(SynthArgs),
    /// An SVG picture of a study's output (map, curve or assemble CSV, or diagnose JSON).
    Plot(PlotArgs),
}

#[derive(Args, Debug)]
pub struct PlotArgs {
    /// A CSV written by map, curve or assemble, or a JSON written by diagnose --json.
    pub input: PathBuf,
    /// The SVG to write.
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub style: PlotStyle,
}

/// How to draw (maps and curves).
#[derive(Args, Debug, Default)]
pub struct PlotStyle {
    /// Map: the column to colour (default c_tran_max_mm_per_N).
    #[arg(long = "plot-column")]
    pub column: Option<String>,
    /// Map: a planar section AXIS=VALUE (mm), e.g. z=0; default: every section (up to six) of a 3-D grid.
    #[arg(long)]
    pub section: Option<String>,
    /// Curve: the direction to draw (x, y, z, rx, ry, rz; default: the one that moves most).
    #[arg(long)]
    pub direction: Option<String>,
}

impl PlotStyle {
    fn options(&self) -> crate::plot::PlotOptions {
        crate::plot::PlotOptions {
            column: self.column.clone(),
            section: self.section.clone(),
            direction: self.direction.clone(),
        }
    }
}

/// Draws `text` (a study's output) into the SVG file `path`.
fn write_plot(text: &str, path: &std::path::Path, style: &PlotStyle) -> Result<()> {
    let svg = crate::plot::plot_text(text, &style.options())?;
    let mut sink = Sink::create(Some(path))?;
    sink.writer().write_all(svg.as_bytes())?;
    sink.finish()?;
    Ok(())
}

/// A picture is drawn from the CSV a study writes, so `--plot` needs `-o FILE`: checked before the run.
fn plot_needs_output(plot: &Option<PathBuf>, output: &Option<PathBuf>, what: &str) -> Result<()> {
    match (plot, output.as_deref()) {
        (Some(_), None) => bail!("{what} --plot needs -o FILE (the picture is drawn from the CSV written)"),
        (Some(_), Some(p)) if p == std::path::Path::new("-") => bail!("{what} --plot needs -o FILE, not stdout"),
        _ => Ok(()),
    }
}

/// The output file just written, for its picture.
fn written(output: &Option<PathBuf>) -> Result<String> {
    let path = output.as_deref().expect("checked by plot_needs_output");
    Ok(read_text(path)?)
}

#[derive(Args, Debug)]
pub struct DiagnoseArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// Measurements (CSV): pose_id,x_mm,y_mm,z_mm,Fx_N,...,Mz_Nmm,dx_mm,dy_mm,dz_mm[,sigma_mm].
    #[arg(long)]
    pub data: PathBuf,
    /// Measurement standard deviation, mm (when the data has no sigma_mm column).
    #[arg(long)]
    pub sigma: Option<f64>,
    /// Predict by the loaded equilibrium instead of the linear C w.
    #[arg(long)]
    pub loaded: bool,
    /// Significance level (default 0.01; candidates are tested at alpha / their number).
    #[arg(long, default_value_t = 0.01)]
    pub alpha: f64,
    /// Write the verdict, accepted effects and candidate table as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the model description with the accepted effects added.
    #[arg(long)]
    pub model_out: Option<PathBuf>,
    /// Also draw the diagnosis (SVG): residual arrows before and after, per-axis RMS, candidates' delta BIC.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct SynthArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// A hidden effect NAME[:TARGET]=V1,V2,... (repeatable), e.g. actuator-compliance:2=1.5, tool-offset=0.05,0,0.
    #[arg(long = "effect", value_name = "NAME[:TARGET]=VALUES")]
    pub effects: Vec<String>,
    /// Grid file (TOML).
    #[arg(long, conflicts_with = "points", required_unless_present = "points")]
    pub grid: Option<PathBuf>,
    /// Points file (CSV).
    #[arg(long)]
    pub points: Option<PathBuf>,
    /// Wrenches applied at every pose: Fx,Fy,Fz,Mx,My,Mz (N, N mm) separated by `;`.
    #[arg(long, allow_hyphen_values = true)]
    pub wrenches: String,
    /// Standard deviation of the measurement noise, mm.
    #[arg(long)]
    pub noise: f64,
    #[arg(long)]
    pub seed: u64,
    /// Measurements per pose and wrench.
    #[arg(long, default_value_t = 1)]
    pub repeats: usize,
    /// Output CSV; `-` or absent: stdout.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct AssembleArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// Error file (TOML): per leg, eps, a base error and/or parameter values, e.g.
    /// manipulators/errors/orthoglide-case-a.toml.
    #[arg(long)]
    pub errors: PathBuf,
    /// Grid file (TOML).
    #[arg(long, conflicts_with_all = ["points", "path"], required_unless_present_any = ["points", "path"])]
    pub grid: Option<PathBuf>,
    /// Points file (CSV) with columns x_mm,y_mm,z_mm (optional: name).
    #[arg(long, conflicts_with = "path")]
    pub points: Option<PathBuf>,
    /// A straight path: FROM x,y,z (mm), TO x,y,z (mm), number of points.
    #[arg(long, num_args = 3, value_names = ["FROM", "TO", "STEPS"], allow_hyphen_values = true)]
    pub path: Option<Vec<String>>,
    /// External wrench Fx,Fy,Fz,Mx,My,Mz (N, N mm): adds the load, total and superposition columns.
    #[arg(long, value_parser = parse_vec6, allow_hyphen_values = true)]
    pub wrench: Option<Vec6>,
    /// Factor on every error (default 1).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Tolerance study: this many random draws of the errors within +-(scale x the given values).
    #[arg(long, default_value_t = 0)]
    pub samples: usize,
    /// Seed of the random draws (with --samples).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output CSV; `-` or absent: stdout.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Also draw the displacements along the path (SVG, paper 000 Figures 10-11).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    #[command(flatten)]
    pub run: RunArgs,
}

#[derive(Args, Debug)]
pub struct MapArgs {
    #[command(flatten)]
    pub model: ModelArgs,
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
    /// Loaded mode: at every point, the equilibrium under this wrench Fx,Fy,Fz,Mx,My,Mz (N, N mm) at the
    /// reference point; the map then reports its displacement and the tangent compliance there.
    #[arg(long, value_parser = parse_vec6, allow_hyphen_values = true, conflicts_with = "loaded")]
    pub wrench: Option<Vec6>,
    /// Loaded mode under each point's reference wrench (from the grid or the points file).
    #[arg(long)]
    pub loaded: bool,
    /// Also draw the map (SVG): a colour map over grid sections.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    #[command(flatten)]
    pub style: PlotStyle,
    #[command(flatten)]
    pub run: RunArgs,
}

#[derive(Args, Debug)]
pub struct CurveArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// Commanded platform reference point x,y,z in mm.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub at: Vec3,
    /// Commanded orientation as a rotation vector rx,ry,rz in rad (default 0,0,0).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub orientation: Option<Vec3>,
    /// Force control: the wrench is load_factor * W (Fx,Fy,Fz in N, Mx,My,Mz in N mm).
    #[arg(long, value_parser = parse_vec6, allow_hyphen_values = true, conflicts_with = "displacement_direction", required_unless_present = "displacement_direction")]
    pub wrench_direction: Option<Vec6>,
    /// Displacement control: the displacement is load_factor * D (dx,dy,dz in mm, rx,ry,rz in rad).
    #[arg(long, value_parser = parse_vec6, allow_hyphen_values = true)]
    pub displacement_direction: Option<Vec6>,
    /// Largest load factor.
    #[arg(long)]
    pub max: f64,
    /// Number of steps from 0 to --max.
    #[arg(long, default_value_t = 50)]
    pub steps: usize,
    /// Output CSV; `-` or absent: stdout.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// No summary on stderr.
    #[arg(long, short)]
    pub quiet: bool,
    /// Also draw the curve (SVG).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// The direction to draw (x, y, z, rx, ry, rz; default: the one that moves most).
    #[arg(long)]
    pub direction: Option<String>,
}

#[derive(Args, Debug)]
pub struct ModelArgs {
    /// Manipulator description (TOML), e.g. manipulators/orthoglide-3puu.toml.
    pub model: PathBuf,
    /// Replace a parameter of the description for this run, e.g. --set mode=1 (repeatable).
    #[arg(long = "set", value_name = "NAME=VALUE", value_parser = parse_assignment)]
    pub set: Vec<(String, f64)>,
}

impl ModelArgs {
    fn load(&self) -> Result<Manipulator> {
        Ok(self.load_model()?.manipulator)
    }

    /// The description with its measurement-model terms (diagnose, synth).
    fn load_model(&self) -> Result<Model> {
        let source = read_text(&self.model)?;
        let overrides = self.set.iter().cloned().collect();
        Ok(parse_with(&self.model, &source, &overrides, 0)?)
    }
}

fn parse_assignment(s: &str) -> Result<(String, f64), String> {
    let (name, value) = s.split_once('=').ok_or_else(|| format!("expected NAME=VALUE, got `{s}`"))?;
    let value: f64 = value.trim().parse().map_err(|_| format!("`{}` is not a number", value.trim()))?;
    if !value.is_finite() {
        return Err(format!("`{s}`: the value must be finite"));
    }
    Ok((name.trim().to_string(), value))
}

#[derive(Args, Debug)]
pub struct RunArgs {
    /// Worker threads (default and 0: all cores; at most 1024). The output is the same for any number.
    #[arg(long)]
    pub threads: Option<usize>,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

#[derive(Args, Debug)]
pub struct PointArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// Platform reference point x,y,z in mm.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub at: Vec3,
    /// Platform orientation as a rotation vector rx,ry,rz in rad (default 0,0,0).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub orientation: Option<Vec3>,
    /// A wrench Fx,Fy,Fz,Mx,My,Mz (N, N mm): reports its linear deflection C w and the loaded equilibrium
    /// under it (displacement, tangent stiffness and its full inverse).
    #[arg(long, value_parser = parse_vec6, allow_hyphen_values = true)]
    pub wrench: Option<Vec6>,
}

fn parse_numbers(s: &str, n: usize) -> Result<Vec<f64>, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != n {
        return Err(format!("expected {n} comma-separated numbers, got {} in `{s}`", parts.len()));
    }
    parts
        .iter()
        .map(|t| match t.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            Ok(_) => Err(crate::model::error::not_finite(t)),
            Err(_) => Err(format!("`{t}` is not a number")),
        })
        .collect()
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
        Command::Curve(a) => curve(a),
        Command::Assemble(a) => assemble(a),
        Command::Diagnose(a) => diagnose(a),
        Command::Synth(a) => synth(a),
        Command::Plot(a) => {
            let text = read_text(&a.input)?;
            write_plot(&text, &a.output, &a.style)
        }
    }
}

/// Most tolerance samples per point (`assemble --samples`): each row waits for all of its samples.
const MAX_SAMPLES: usize = 10_000_000;

/// Most worker threads a run starts: each holds its own buffers and a run in flight, and starting a
/// million of them hangs the pool setup.
const MAX_THREADS: usize = 1024;

fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    let mut b = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        if n > MAX_THREADS {
            bail!(
                "--threads {n} is more than stiff starts ({MAX_THREADS}): this machine has {cores} cores, and \
                 threads beyond the cores only add overhead (0 means all cores)"
            );
        }
        // 0: all cores (rayon's default), as ripgrep reads it.
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

/// The poses of `--grid` or `--points` (clap keeps the two exclusive).
fn point_set(grid: &Option<PathBuf>, points: &Option<PathBuf>) -> Result<PointSet> {
    Ok(match (grid, points) {
        (Some(g), None) => PointSet::from_grid_file(g)?,
        (None, Some(p)) => PointSet::from_points_csv(p)?,
        _ => bail!("give exactly one of --grid and --points"),
    })
}

fn map(a: MapArgs) -> Result<()> {
    let model = a.model.load()?;
    let mut points = point_set(&a.grid, &a.points)?;
    let pool = thread_pool(a.run.threads)?;
    let mut sink = Sink::create(a.output.as_deref())?;
    let bar = progress_bar(points.len, a.run.quiet);
    if a.loaded && !points.has_wrench {
        bail!("--loaded needs reference wrenches in the grid or points file (or give --wrench)");
    }
    let options = MapOptions { stiffness: a.stiffness, wrench: a.wrench, use_point_wrench: a.loaded };
    plot_needs_output(&a.plot, &a.output, "map")?;
    if a.plot.is_some() {
        let header = crate::study::map::map_header(&crate::study::map::map_columns(&points, &options));
        crate::plot::check_map_options(&header, &a.style.options())?;
    }
    let summary = run_map(&pool, &model, &mut points, options, sink.writer(), &bar)?;
    sink.finish()?;
    bar.finish_and_clear();
    if let Some(plot) = &a.plot {
        write_plot(&written(&a.output)?, plot, &a.style)?;
    }
    if !a.run.quiet {
        eprintln!("{}", summary.line());
    }
    Ok(())
}

fn assemble(a: AssembleArgs) -> Result<()> {
    let model = a.model.load()?;
    let set = ErrorSet::load(&a.errors, &a.model.model, &model)?;
    if !(a.scale.is_finite()) {
        bail!("--scale must be a finite number");
    }
    let perturbed = set.perturbed_legs(a.scale)?;
    let mut points = match &a.path {
        None => point_set(&a.grid, &a.points)?,
        Some(path) => {
            let from = parse_vec3(&path[0]).map_err(|e| anyhow::anyhow!("--path FROM: {e}"))?;
            let to = parse_vec3(&path[1]).map_err(|e| anyhow::anyhow!("--path TO: {e}"))?;
            let steps: usize =
                path[2].parse().map_err(|_| anyhow::anyhow!("--path STEPS: `{}` is not a count", path[2]))?;
            if steps == 0 {
                bail!("--path needs at least one step");
            }
            PointSet::from_points(path_points(&from, &to, steps))
        }
    };
    let pool = thread_pool(a.run.threads)?;
    let mut sink = Sink::create(a.output.as_deref())?;
    let bar = progress_bar(points.len, a.run.quiet);
    let options = AssembleOptions { wrench: a.wrench, scale: a.scale, samples: a.samples, seed: a.seed };
    if a.samples > MAX_SAMPLES {
        bail!(
            "--samples {} is more than a point may take ({MAX_SAMPLES}: about 5 s per point at 2 million \
             assemblies/s; the spread converges long before)",
            a.samples
        );
    }
    if a.plot.is_some() && a.samples > 0 {
        bail!("--plot draws an assembly path, not a tolerance study (--samples)");
    }
    plot_needs_output(&a.plot, &a.output, "assemble")?;
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
        write_plot(&written(&a.output)?, plot, &PlotStyle::default())?;
    }
    if !a.run.quiet {
        eprintln!("{} points: {} assembled", summary.points, summary.ok);
    }
    Ok(())
}

fn diagnose(a: DiagnoseArgs) -> Result<()> {
    use crate::diagnose::{data::Dataset, error::DiagnoseError, fit::Problem, report, select};
    let model = a.model.load_model()?;
    let data = Dataset::read(&a.data)?;
    if !(a.alpha > 0.0 && a.alpha < 1.0) {
        bail!("--alpha must lie in (0, 1)");
    }
    let (weights, sigma, source) = select::noise(&data, a.sigma).map_err(|e| match e {
        // The command line says how to give the noise level: its flag.
        DiagnoseError::NoiseUnknown => anyhow::anyhow!("{}: {e}: --sigma MM", a.data.display()),
        DiagnoseError::NoiseOutOfRange { .. } => anyhow::anyhow!("--sigma: {e}"),
        e => anyhow::anyhow!("{}: {e}", a.data.display()),
    })?;
    let needs_loaded = !a.loaded;
    let problem = Problem::new(&model.manipulator, &model.measurement_terms, &data, weights, a.loaded, needs_loaded)
        .map_err(|e| anyhow::anyhow!("{}, {e}", a.data.display()))?;
    let options = select::Options { alpha: a.alpha, loaded: a.loaded, max_effects: 3 };
    // The outputs are opened before the work, so an unwritable path fails at once.
    let json_sink = a.json.as_deref().map(|p| Sink::create(Some(p))).transpose()?;
    let model_sink = a.model_out.as_deref().map(|p| Sink::create(Some(p))).transpose()?;
    let plot_sink = a.plot.as_deref().map(|p| Sink::create(Some(p))).transpose()?;
    let d = select::diagnose(&problem, sigma, source, &options)
        .map_err(|e| anyhow::anyhow!("{}: {e}", a.data.display()))?;
    let name = a.model.model.display().to_string();
    write_stdout(&report::text(&d, &name))?;
    let json = report::json(&d, &name);
    if let Some(mut sink) = json_sink {
        serde_json::to_writer_pretty(&mut *sink.writer(), &json)?;
        sink.finish()?;
    }
    if let Some(mut sink) = plot_sink {
        let svg = crate::plot::plot_text(&json.to_string(), &PlotStyle::default().options())?;
        sink.writer().write_all(svg.as_bytes())?;
        sink.finish()?;
    }
    if let Some(mut sink) = model_sink {
        let source = read_text(&a.model.model)?;
        let dir = a.model.model.parent().map(|p| p.to_path_buf()).unwrap_or_default();
        let dir = std::fs::canonicalize(&dir).unwrap_or(dir);
        sink.writer().write_all(report::corrected_model(&source, &dir, &d).as_bytes())?;
        sink.finish()?;
    }
    Ok(())
}

fn synth(a: SynthArgs) -> Result<()> {
    use crate::diagnose::synth;
    use crate::model::effect::Effect;
    let model = a.model.load_model()?;
    let effects = a
        .effects
        .iter()
        .map(|e| Effect::parse(e, &model.manipulator))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| anyhow::anyhow!("--effect {e}"))?;
    let wrenches = a
        .wrenches
        .split(';')
        .map(|w| parse_vec6(w.trim()))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| anyhow::anyhow!("--wrenches: {e}"))?;
    if !(a.noise >= 0.0 && a.noise.is_finite()) {
        bail!("--noise must be >= 0 (mm)");
    }
    let mut points = point_set(&a.grid, &a.points)?;
    let options = synth::SynthOptions { effects, wrenches, noise: a.noise, seed: a.seed, repeats: a.repeats };
    let mut sink = Sink::create(a.output.as_deref())?;
    let skipped = synth::synthesize(&model, &mut points, &options, sink.writer())?;
    sink.finish()?;
    if skipped > 0 {
        eprintln!("{skipped} poses left out (unreachable or singular)");
    }
    Ok(())
}

fn point(a: PointArgs) -> Result<()> {
    let model = a.model.load()?;
    let p =
        PosePoint { name: None, position: a.at, rotation: a.orientation.unwrap_or_else(Vec3::zeros), wrench: a.wrench };
    let mut state = model.new_state();
    let r = unloaded_point(&model, &p, &mut state);
    let mut text = point_report(&model.name, &p, &r, false);
    if let Some(w) = &a.wrench {
        let loaded = loaded_point(&model, &p, w, &mut state, &mut LoadedHistory::default());
        text.push_str("\nUnder the wrench: the loaded equilibrium (paper 000 s. 3-4)\n");
        text.push_str(&point_report(&model.name, &p, &loaded, true));
    }
    write_stdout(&text)
}

/// Writes a report to stdout, reporting a failed write (a full disk, a closed pipe) instead of panicking
/// as `print!` does.
fn write_stdout(text: &str) -> Result<()> {
    use std::io::Write as _;
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes()).and_then(|_| out.flush()).context("cannot write to stdout")
}

fn curve(a: CurveArgs) -> Result<()> {
    let model = a.model.load()?;
    let at = Frame::from_position_rotvec(a.at, a.orientation.unwrap_or_else(Vec3::zeros));
    let control = match (a.wrench_direction, a.displacement_direction) {
        (Some(w), None) => Control::Force(w),
        (None, Some(d)) => Control::Displacement(d),
        _ => bail!("give exactly one of --wrench-direction and --displacement-direction"),
    };
    if !(1..=MAX_INTERVALS).contains(&a.steps) {
        bail!("--steps must lie between 1 and {MAX_INTERVALS} (each step is a loaded equilibrium kept in memory)");
    }
    if !(a.max.is_finite() && a.max > 0.0) {
        bail!("--max must be a positive finite number, got {}", a.max);
    }
    let mut sink = Sink::create(a.output.as_deref())?;
    // Rows are written as they become final; the picture, if asked, is drawn from the same text.
    let mut picture = a.plot.as_ref().map(|_| curve_header());
    let writer = sink.writer();
    writer.write_all(curve_header().as_bytes())?;
    let mut line = String::new();
    let summary = run_curve(&model, &at, control, a.max, a.steps, &mut |r| {
        line.clear();
        push_curve_row(&mut line, r);
        if let Some(p) = picture.as_mut() {
            p.push_str(&line);
        }
        writer.write_all(line.as_bytes())
    })?;
    sink.finish()?;
    if let (Some(plot), Some(text)) = (&a.plot, &picture) {
        let style = PlotStyle { direction: a.direction.clone(), ..PlotStyle::default() };
        write_plot(text, plot, &style)?;
    }
    if !a.quiet {
        eprintln!("{}", summary.text(model.length_scale));
    }
    Ok(())
}
