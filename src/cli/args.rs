//! Argument groups shared by several commands, and what they set up: the model, the run (threads,
//! progress), pictures and standard output.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use super::parse::{parse_assignment, parse_vec3};
use crate::kinematics::frame::Vec3;
use crate::model::error::read_text;
use crate::model::grid::PointSet;
use crate::model::{parse_with, Model};
use crate::output::sink::Sink;
use crate::output::table::{Column, Selection};
use crate::platform::manipulator::Manipulator;

#[derive(Args, Debug)]
pub(crate) struct ModelArgs {
    /// Manipulator description (TOML), e.g. manipulators/orthoglide-3puu.toml.
    pub(crate) model: PathBuf,
    /// Replace a parameter of the description for this run, e.g. --set mode=1 (repeatable).
    #[arg(long = "set", value_name = "NAME=VALUE", value_parser = parse_assignment)]
    pub(crate) set: Vec<(String, f64)>,
    /// A tree with several tips (`tips = [...]` in its `[leg.urdf]`): the tip that is this run's reference
    /// point. Without it `map` writes a row per tip (a `tip` column) and the other commands use the first.
    #[arg(long, value_name = "LINK")]
    pub(crate) tip: Option<String>,
}

impl ModelArgs {
    /// A picture's title for a run of `m` with these arguments: the model's name and file, the `--set`
    /// values, and what the run adds (a wrench, a path).
    pub(crate) fn title(&self, m: &Manipulator, run: &str) -> String {
        let mut title = format!("{} ({})", m.name, self.model.display());
        for (name, value) in &self.set {
            title.push_str(&format!(", {name} = {value}"));
        }
        if !run.is_empty() {
            title.push_str(", ");
            title.push_str(run);
        }
        title
    }

    pub(crate) fn load(&self) -> Result<Manipulator> {
        Ok(self.load_model()?.manipulator)
    }

    /// The description with its measurement-model terms (diagnose, synth).
    pub(crate) fn load_model(&self) -> Result<Model> {
        let source = read_text(&self.model)?;
        let overrides = self.set.iter().cloned().collect();
        let mut model = parse_with(&self.model, &source, &overrides, 0)?;
        say_carried_mass(&model.manipulator);
        if let Some(tip) = &self.tip {
            let m = &model.manipulator;
            model.manipulator = match m.tips() {
                [] => bail!("--tip {tip}: {} is not a serial arm read from URDF: it has no tips", m.name),
                tips => m.at_tip(tip).ok_or_else(|| {
                    anyhow::anyhow!("--tip {tip}: {} has no tip named `{tip}` (tips: {})", m.name, tips.join(", "))
                })?,
            };
        }
        Ok(model)
    }

    /// The description read again with some text appended, as `load_model` reads it (`--set`, `--tip`): a
    /// calibration rebuilds its arm with the corrections it writes (`CalibrationOptions::rebuild`).
    pub(crate) fn rebuild(&self) -> Result<crate::diagnose::calibrate::Rebuild> {
        let source = read_text(&self.model)?;
        let overrides = self.set.iter().cloned().collect();
        Ok(crate::diagnose::calibrate::Rebuild::of_description(&self.model, source, overrides, self.tip.clone()))
    }

    /// The tips whose rows a map writes: every tip of a tree (the one `--tip` names, where given); none
    /// for a manipulator with one reference point.
    pub(crate) fn map_tips(&self, m: &Manipulator) -> Vec<String> {
        match (m.tips().len() > 1, &self.tip) {
            (false, _) => Vec::new(),
            (true, Some(_)) => m.tips()[..1].to_vec(),
            (true, None) => m.tips().to_vec(),
        }
    }
}

/// Says on stderr, once per run, the mass a serial arm carries and how much of it hangs off the root-to-tip
/// path, where some does (docs/GUIDE.md: what a URDF arm's weight includes): bodies a user may not know the model
/// carries (a branch, a tool beyond the tip).
fn say_carried_mass(m: &Manipulator) {
    static SAID: std::sync::Once = std::sync::Once::new();
    let Some(space) = &m.joint_space else { return };
    let c = space.carried;
    if c.off_path_kg <= 0.0 {
        return;
    }
    SAID.call_once(|| {
        eprintln!(
            "note: {}: the arm carries {:.6} kg on its moving links, {:.6} kg of it off the root-to-tip path (branches held at their URDF zero, bodies beyond the tip); {:.6} kg weighs on the base",
            m.name, c.kg, c.off_path_kg, c.on_base_kg
        );
    });
}

#[derive(Args, Debug)]
pub(crate) struct RunArgs {
    /// Worker threads (default and 0: all cores; at most 1024). The output is the same for any number.
    #[arg(long)]
    pub(crate) threads: Option<usize>,
    /// No progress bar.
    #[arg(long, short)]
    pub(crate) quiet: bool,
}

/// What a picture of a table over poses shows (map, plot, and assemble, whose `--scale` scales its errors).
#[derive(Args, Debug, Default)]
pub(crate) struct PointsStyle {
    /// Picture: the column drawn [default: c_tran_max_mm_per_N for a map, displacement_mean_mm for a
    /// tolerance study, the length of (nl_dx, nl_dy, nl_dz) for an assembly].
    #[arg(long = "plot-column")]
    pub(crate) column: Option<String>,
    /// Picture of a grid: a planar section AXIS=VALUE (mm), e.g. z=0 [default: every section (up to six) of a
    /// 3-D grid].
    #[arg(long)]
    pub(crate) section: Option<String>,
    /// Picture: the values of the first and the last colour, MIN,MAX [default: the data's range]; values
    /// outside take the end colours (to compare pictures on one scale).
    #[arg(long, value_parser = parse_range, allow_hyphen_values = true)]
    pub(crate) range: Option<(f64, f64)>,
}

impl PointsStyle {
    /// The picture options these give.
    pub(crate) fn style(&self) -> PlotStyle {
        PlotStyle {
            column: self.column.clone(),
            section: self.section.clone(),
            range: self.range,
            ..PlotStyle::default()
        }
    }
}

/// How to draw a map.
#[derive(Args, Debug, Default)]
pub(crate) struct MapStyle {
    #[command(flatten)]
    pub(crate) points: PointsStyle,
    /// Picture: colours evenly in the value or in its logarithm (positive values only).
    #[arg(long, value_enum, default_value_t = ColourScaleArg::Linear)]
    pub(crate) scale: ColourScaleArg,
}

/// `--scale`.
#[derive(Clone, Copy, Debug, Default, clap::ValueEnum)]
pub(crate) enum ColourScaleArg {
    /// Evenly in the value.
    #[default]
    Linear,
    /// Evenly in the value's logarithm.
    Log,
}

/// `MIN,MAX` with MIN < MAX.
fn parse_range(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s.split_once(',').ok_or_else(|| format!("`{s}` is not MIN,MAX"))?;
    let parse = |v: &str| v.trim().parse::<f64>().map_err(|_| format!("`{v}` is not a number"));
    let (lo, hi) = (parse(a)?, parse(b)?);
    if !(lo.is_finite() && hi.is_finite() && lo < hi) {
        return Err(format!("`{s}`: MIN and MAX must be finite with MIN < MAX"));
    }
    Ok((lo, hi))
}

impl MapStyle {
    /// The picture options these give.
    pub(crate) fn style(&self) -> PlotStyle {
        PlotStyle {
            scale: match self.scale {
                ColourScaleArg::Linear => crate::plot::Scale::Linear,
                ColourScaleArg::Log => crate::plot::Scale::Log,
            },
            ..self.points.style()
        }
    }
}

/// How to draw a picture: a map's column, section and colours, a curve's direction, the title.
#[derive(Debug, Default)]
pub(crate) struct PlotStyle {
    pub(crate) column: Option<String>,
    pub(crate) section: Option<String>,
    pub(crate) direction: Option<String>,
    pub(crate) scale: crate::plot::Scale,
    pub(crate) range: Option<(f64, f64)>,
    pub(crate) title: Option<String>,
}

impl PlotStyle {
    pub(crate) fn options(&self) -> crate::plot::PlotOptions {
        crate::plot::PlotOptions {
            column: self.column.clone(),
            section: self.section.clone(),
            direction: self.direction.clone(),
            scale: self.scale,
            range: self.range,
            title: self.title.clone(),
        }
    }
}

/// One commanded pose of the platform (`point`, `curve`): a reference point and orientation, or a serial
/// arm's joint coordinates.
#[derive(Args, Debug)]
#[command(group = clap::ArgGroup::new("pose").required(true).multiple(false).args(["at", "joints"]))]
pub(crate) struct PoseArgs {
    /// Commanded platform reference point x,y,z in mm.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub(crate) at: Option<Vec3>,
    /// Commanded orientation as a rotation vector rx,ry,rz in rad [default: 0,0,0].
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, requires = "at")]
    pub(crate) orientation: Option<Vec3>,
    /// A serial arm's joint coordinates as its controller gives them (rad, or mm for a prismatic joint), one
    /// per joint in the order the description's URDF chain lists them (the FANUC: J1,...,J6): the pose is
    /// where forward kinematics puts the tool, and the arm is placed in exactly that configuration.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub(crate) joints: Option<Vec<f64>>,
}

impl PoseArgs {
    /// The pose asked for, with `state` seeded at the joint coordinates where they are given (so that placing
    /// `m` at the pose keeps that configuration).
    pub(crate) fn resolve(
        &self,
        m: &crate::platform::manipulator::Manipulator,
        state: &mut crate::platform::manipulator::ManipulatorState,
    ) -> Result<crate::model::grid::PosePoint> {
        use crate::model::grid::PosePoint;
        match (&self.joints, self.at) {
            (Some(q), _) => {
                let Some(space) = &m.joint_space else {
                    bail!("--joints: {} is not a serial arm read from URDF: give --at", m.name);
                };
                if q.len() != space.names.len() || q.iter().any(|v| !v.is_finite()) {
                    bail!(
                        "--joints needs {} finite numbers, one per joint ({}), got {}",
                        space.names.len(),
                        space.names.join(", "),
                        q.len()
                    );
                }
                let given = PosePoint { joints: q.clone(), ..PosePoint::default() };
                match crate::study::point::pose_of_joints(m, &given, state) {
                    Some(p) => Ok(PosePoint { joints: Vec::new(), ..p.into_owned() }),
                    None => bail!("--joints: these joint coordinates give no finite pose"),
                }
            }
            (None, Some(_)) if m.tips().len() > 1 => bail!(
                "--at: {} is a tree with several tips ({}): a pose places one of them, not the tree; give --joints ({})",
                m.name,
                m.tips().join(", "),
                m.joint_space.as_ref().map_or(String::new(), |s| s.names.join(", "))
            ),
            (None, Some(at)) => Ok(PosePoint {
                position: at,
                rotation: self.orientation.unwrap_or_else(Vec3::zeros),
                ..PosePoint::default()
            }),
            (None, None) => bail!("give --at or --joints"),
        }
    }
}

/// Where the poses come from: a grid file or a points file (exactly one: the usage line shows the choice).
#[derive(Args, Debug)]
#[group(required = true, multiple = false)]
pub(crate) struct PointsArgs {
    /// Grid file (TOML): a [box] and/or named [[point]]s.
    #[arg(long)]
    pub(crate) grid: Option<PathBuf>,
    /// Points file (CSV) with columns x_mm,y_mm,z_mm (optional: name; a map also reads pose_r*_rad and
    /// Fx_N..Mz_Nmm).
    #[arg(long)]
    pub(crate) points: Option<PathBuf>,
}

impl PointsArgs {
    /// The points of `--grid` or `--points` for `m`: poses, or a serial arm's joint coordinates (`q_<joint>`
    /// columns), checked against its joints and read in its order.
    pub(crate) fn load(&self, m: &Manipulator) -> Result<PointSet> {
        arm_points(m, point_set_any(&self.grid, &self.points)?, self.points.as_deref())
    }
}

/// `points` as `m` takes them: joint coordinates checked against `m`'s joints and put in its order (each
/// row then carries the whole pose forward kinematics gives, orientation included); poses refused where
/// they cannot fix the arm's configuration (more than six joint coordinates). `file` names the points file
/// in messages.
pub(crate) fn arm_points(m: &Manipulator, mut points: PointSet, file: Option<&Path>) -> Result<PointSet> {
    let file = file.map(|p| format!("{}: ", p.display())).unwrap_or_default();
    if points.joint_names.is_empty() {
        if m.tips().len() > 1 {
            bail!(
                "{file}{} is a tree with several tips ({}): a pose places one of them, not the tree; give the points as joint coordinates, one column q_<joint> each ({})",
                m.name,
                m.tips().join(", "),
                m.joint_space.as_ref().map_or(String::new(), |s| s.names.join(", "))
            );
        }
        if let Some(space) = m.joint_space.as_ref().filter(|s| s.names.len() > 6) {
            bail!(
                "{file}{} has {} joint coordinates ({}): a pose does not fix them; give the points as joint coordinates, one column q_<joint> each",
                m.name,
                space.names.len(),
                space.names.join(", ")
            );
        }
    } else {
        let order =
            crate::study::point::joint_order(m, &points.joint_names).map_err(|e| anyhow::anyhow!("{file}{e}"))?;
        points.order_joints(&order);
        points.has_orientation = true;
        if points.pose_and_joints {
            eprintln!(
                "note: {file}the points give both a pose (x_mm, y_mm, z_mm) and joint coordinates (q_<joint>): the joint coordinates are used, the pose columns are not read"
            );
        }
        if let Some(space) = &m.joint_space {
            let warn = Box::new(|message: String| eprintln!("warning: {message}"));
            points.watch_limits(crate::model::grid::LimitWatch { space: space.clone(), warn });
        }
    }
    Ok(points)
}

/// Where the poses come from, a straight path included (assemble, compensate): exactly one of a grid, a
/// points file and a path.
#[derive(Args, Debug)]
#[group(required = true, multiple = false)]
pub(crate) struct PosesArgs {
    /// Grid file (TOML): a [box] and/or named [[point]]s.
    #[arg(long)]
    pub(crate) grid: Option<PathBuf>,
    /// Points file (CSV) with columns x_mm,y_mm,z_mm (optional: name, pose_rx_rad..pose_rz_rad; compensate
    /// also reads a wrench per row, Fx_N..Mz_Nmm).
    #[arg(long)]
    pub(crate) points: Option<PathBuf>,
    /// A straight path: FROM x,y,z (mm), TO x,y,z (mm), number of points.
    #[arg(long, num_args = 3, value_names = ["FROM", "TO", "POINTS"], allow_hyphen_values = true)]
    pub(crate) path: Option<Vec<String>>,
}

impl PosesArgs {
    /// The points of `--grid`, `--points` or `--path` for `m` (joint coordinates as `PointsArgs::load`).
    pub(crate) fn load(&self, m: &Manipulator) -> Result<PointSet> {
        let Some(path) = &self.path else {
            return arm_points(m, point_set_any(&self.grid, &self.points)?, self.points.as_deref());
        };
        let from = parse_vec3(&path[0]).map_err(|e| anyhow::anyhow!("--path FROM: {e}"))?;
        let to = parse_vec3(&path[1]).map_err(|e| anyhow::anyhow!("--path TO: {e}"))?;
        let count: usize =
            path[2].parse().map_err(|_| anyhow::anyhow!("--path POINTS: `{}` is not a count", path[2]))?;
        if count == 0 {
            bail!("--path needs at least one point");
        }
        if count > MAX_PATH_POINTS {
            bail!("--path POINTS: {count} is more than a path takes ({MAX_PATH_POINTS}); split the path");
        }
        arm_points(m, PointSet::from_points(crate::model::grid::path_points(&from, &to, count)), None)
    }
}

/// Most points on a `--path` (held in memory, 64 bytes each).
const MAX_PATH_POINTS: usize = 100_000_000;

/// The load of a map or a sweep: none (unloaded), one wrench at every point, or each point's own.
#[derive(Args, Debug)]
pub(crate) struct LoadArgs {
    /// Loaded mode: at every point, the equilibrium under this wrench Fx,Fy,Fz,Mx,My,Mz (N, N mm) at the
    /// reference point; the map then reports its displacement and the tangent compliance there.
    #[arg(long, value_parser = super::parse::parse_vec6, allow_hyphen_values = true, conflicts_with = "loaded")]
    pub(crate) wrench: Option<crate::kinematics::frame::Vec6>,
    /// Loaded mode under each point's reference wrench (from the grid or the points file).
    #[arg(long)]
    pub(crate) loaded: bool,
}

impl LoadArgs {
    /// The map's options for `points` under this load (`--loaded` needs the points' wrenches).
    pub(crate) fn map_options(&self, points: &PointSet, stiffness: bool) -> Result<crate::study::map::MapOptions> {
        if self.loaded && !points.has_wrench {
            bail!(
                "--loaded needs reference wrenches in the grid or points file (columns Fx_N,Fy_N,Fz_N,Mx_Nmm,My_Nmm,Mz_Nmm, or a grid's `wrench`); for one wrench at every point, drop --loaded and give --wrench FX,FY,FZ,MX,MY,MZ"
            );
        }
        Ok(crate::study::map::MapOptions {
            stiffness,
            wrench: self.wrench,
            use_point_wrench: self.loaded,
            selection: None,
            tips: Vec::new(),
        })
    }
}

/// Where a table goes.
#[derive(Args, Debug)]
pub(crate) struct OutputArgs {
    /// Output table; `-` or absent: stdout (CSV). By the file's extension: `.csv`, `.csv.gz`, `.csv.zst`
    /// or `.parquet` (zstd-compressed, typed columns, units in the field metadata). A file is written to a
    /// temporary name and renamed on success.
    #[arg(short, long)]
    pub(crate) output: Option<PathBuf>,
}

impl OutputArgs {
    /// The output of a table with these columns, opened before the work so that an unwritable path fails
    /// at once.
    pub(crate) fn open(&self, columns: &[Column]) -> Result<Sink> {
        Sink::table(self.output.as_deref(), columns)
    }
}

/// Draws the table or diagnosis in the file `input` (CSV, compressed CSV or Parquet; `-` for stdin) into
/// the picture `output`.
pub(crate) fn plot_file(input: &Path, output: &Path, style: &PlotStyle) -> Result<()> {
    if crate::output::sink::is_parquet(input) {
        let file = std::fs::File::open(input).with_context(|| format!("cannot read {}", input.display()))?;
        let svg = crate::plot::plot_parquet(file, &style.options())
            .map_err(name_plot_flag)
            .with_context(|| format!("drawing {}", input.display()))?;
        return write_picture(&svg, output);
    }
    write_plot(crate::model::error::open_input(input)?, output, style)
}

/// A wrench as `(Fx, Fy, Fz, Mx, My, Mz)` for a title.
pub(crate) fn wrench_text(w: &crate::kinematics::frame::Vec6) -> String {
    let parts: Vec<String> = w.iter().map(|v| format!("{v}")).collect();
    format!("({})", parts.join(", "))
}

/// The selection `--columns` asks for (None without it), resolved against a table's columns by `resolve`.
pub(crate) fn select_columns(
    wanted: &Option<Vec<String>>,
    resolve: impl FnOnce(&[&str]) -> Result<Selection, String>,
) -> Result<Option<Selection>> {
    let Some(wanted) = wanted else { return Ok(None) };
    let wanted: Vec<&str> = wanted.iter().map(String::as_str).collect();
    resolve(&wanted).map(Some).map_err(|e| anyhow::anyhow!("--columns: {e}"))
}

/// Most worker threads a run starts: each holds its own buffers and a run in flight, and starting a
/// million of them hangs the pool setup.
const MAX_THREADS: usize = 1024;

pub(crate) fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
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

pub(crate) fn progress_bar(len: Option<u64>, quiet: bool) -> ProgressBar {
    if quiet || !std::io::stderr().is_terminal() {
        return ProgressBar::with_draw_target(len, ProgressDrawTarget::hidden());
    }
    let bar = match len {
        Some(n) => ProgressBar::new(n),
        None => ProgressBar::new_spinner(),
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{elapsed_precise} [{wide_bar}] {human_pos}/{human_len} points, {rate}, eta {eta}",
        )
        .map(|style| style.with_key("rate", write_rate))
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar
}

/// A calibration's progress on stderr where it is a terminal: the time, the fits made and what the
/// selection is doing; it shows after two seconds, so a quick calibration prints none.
pub(crate) fn fit_counter() -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} {spinner} {human_pos} fits: {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    let shown = bar.clone();
    std::thread::spawn(move || {
        std::thread::sleep(std::time::Duration::from_secs(2));
        if !shown.is_finished() {
            shown.set_draw_target(ProgressDrawTarget::stderr());
            shown.enable_steady_tick(std::time::Duration::from_millis(200));
        }
    });
    bar
}

/// The rate as a whole number of points per second with thousands separators (`14,643/s`): indicatif's
/// `{per_sec}` prints four decimals.
fn write_rate(state: &indicatif::ProgressState, w: &mut dyn std::fmt::Write) {
    let _ = w.write_str(&rate_text(state.per_sec()));
}

/// `14643.3446` points per second -> `14,643/s`.
fn rate_text(per_second: f64) -> String {
    let whole = if per_second.is_finite() { per_second.max(0.0).round() as u64 } else { 0 };
    format!("{}/s", indicatif::HumanCount(whole))
}

/// The points of `--grid` or `--points`, poses or joint coordinates.
pub(crate) fn point_set_any(grid: &Option<PathBuf>, points: &Option<PathBuf>) -> Result<PointSet> {
    Ok(match (grid, points) {
        (Some(g), None) => PointSet::from_grid_file(g)?,
        (None, Some(p)) => PointSet::from_points_csv(p)?,
        _ => bail!("give exactly one of --grid and --points"),
    })
}

/// Draws `text` (a study's output) into the SVG file `path`.
pub(crate) fn write_plot(input: impl std::io::Read, path: &Path, style: &PlotStyle) -> Result<()> {
    let svg = crate::plot::plot_reader(input, &style.options()).map_err(name_plot_flag)?;
    write_picture(&svg, path)
}

/// The bytes of a picture file named `path`: PNG where the name ends in `.png`, else the SVG.
pub(crate) fn picture_bytes(svg: &str, path: &Path) -> Result<Vec<u8>> {
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
        crate::plot::raster::svg_to_png(svg)
    } else {
        Ok(svg.as_bytes().to_vec())
    }
}

/// Writes a picture: PNG where the name ends in `.png`, else SVG.
pub(crate) fn write_picture(svg: &str, path: &Path) -> Result<()> {
    let bytes = picture_bytes(svg, path)?;
    let mut sink = Sink::create(Some(path))?;
    sink.writer().write_all(&bytes)?;
    sink.finish()?;
    Ok(())
}

/// Checks before the work that a picture can be written at `path` (its folder exists and takes a file; not a
/// `.parquet` name): a long run must not end on an unwritable picture.
pub(crate) fn check_picture_path(path: &Path) -> Result<()> {
    // Opening the sink creates its temporary file beside the target; dropping it removes it again.
    Sink::create(Some(path)).map(drop)
}

/// A picture is drawn from the CSV a study writes, so `--plot` needs `-o FILE`: checked before the run.
pub(crate) fn plot_needs_output(plot: &Option<PathBuf>, output: &Option<PathBuf>, what: &str) -> Result<()> {
    if let Some(p) = plot {
        check_picture_path(p)?;
    }
    match (plot, output.as_deref()) {
        (Some(_), None) => bail!("{what} --plot needs -o FILE (the picture is drawn from the CSV written)"),
        (Some(_), Some(p)) if p == Path::new("-") => bail!("{what} --plot needs -o FILE, not stdout"),
        _ => Ok(()),
    }
}

/// The output file just written, for its picture.
pub(crate) fn written(output: &Option<PathBuf>) -> &Path {
    output.as_deref().expect("checked by plot_needs_output")
}

/// Writes a report to stdout, reporting a failed write (a full disk, a closed pipe) instead of panicking
/// as `print!` does.
pub(crate) fn write_stdout(text: &str) -> Result<()> {
    use std::io::Write as _;
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes()).and_then(|_| out.flush()).context("cannot write to stdout")
}

/// A picture option's error, said with its flag.
pub(crate) fn name_plot_flag(e: anyhow::Error) -> anyhow::Error {
    use crate::plot::OptionError;
    match e.downcast_ref::<OptionError>() {
        Some(o @ OptionError::Section(_)) => anyhow::anyhow!("--section: {o}"),
        Some(o @ OptionError::Column { .. }) => anyhow::anyhow!("--plot-column: {o}"),
        Some(o @ OptionError::Direction(_)) => anyhow::anyhow!("--direction: {o}"),
        None => e,
    }
}

#[cfg(test)]
mod tests {
    /// The progress rate is a whole number with thousands separators, as ripgrep and hyperfine print rates.
    #[test]
    fn progress_rates_are_whole_numbers() {
        assert_eq!(super::rate_text(14643.3446), "14,643/s");
        assert_eq!(super::rate_text(0.4), "0/s");
        assert_eq!(super::rate_text(f64::INFINITY), "0/s");
    }
}
