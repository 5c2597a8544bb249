//! `stiff sweep`: many designs of one description, each mapped over the same workspace and reduced to one
//! summary row (dimensional synthesis). A design is a set of parameter values applied as `--set` applies
//! one; designs come from a full factorial, a seeded Latin hypercube or a CSV.
//!
//! Designs are the streamed items (`batch::Study`): workers take designs, and each design's points are
//! solved in order by the worker that has it, warm-started from point to point as `stiff map` does, so a
//! design's figures are its map's figures whatever the thread count.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::io::Write;
use std::ops::Range;
use std::path::{Path, PathBuf};

use anyhow::Result;
use indicatif::ProgressBar;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};

use super::map::{map_columns, map_given_point, map_table, MapColumns, MapOptions, MapRow};
use super::point::{LoadedHistory, PointResult, Status};
use crate::batch::{stream, Source, Study, Tally};
use crate::model::error::{open_input, InputError};
use crate::model::grid::{PointSet, PosePoint};
use crate::model::parse_with;
use crate::output::sink::Sink;
use crate::output::table::{names, selected_columns, write_row, write_selected_row, Column, Record, Row};

/// Most designs in one sweep (a factorial grows fast: split it, or sample it).
pub const MAX_DESIGNS: u64 = 10_000_000;
/// Most points a sweep's workspace may have (held in memory, shared by every design).
pub const MAX_SWEEP_POINTS: u64 = 10_000_000;

/// One design: a value for each of the sweep's parameters, and a name where the designs file gives one.
#[derive(Clone, Debug, PartialEq)]
pub struct Design {
    /// The design's name (`design` column of a designs file).
    pub name: Option<String>,
    /// The parameters' values, in the order of `DesignSet::parameters`.
    pub values: Vec<f64>,
}

/// A parameter varied over a range: `NAME=FROM:TO:COUNT`.
#[derive(Clone, Debug, PartialEq)]
pub struct ParameterRange {
    /// The parameter (a `[parameters]` entry of the description).
    pub name: String,
    /// First value.
    pub from: f64,
    /// Last value.
    pub to: f64,
    /// Values from `from` to `to`, evenly spaced, for a factorial (a Latin hypercube does not use it).
    pub count: Option<u64>,
}

/// The designs of a sweep, read in blocks (`batch::Source`).
pub struct DesignSet {
    /// The parameters each design sets, in column order.
    pub parameters: Vec<String>,
    designs: Vec<Design>,
    next: usize,
    end: usize,
}

impl DesignSet {
    /// The parameter that appears twice, if one does (each must be one column).
    pub fn repeated_parameter(&self) -> Option<&str> {
        let p = &self.parameters;
        (1..p.len()).find(|&k| p[..k].contains(&p[k])).map(|k| p[k].as_str())
    }

    fn new(parameters: Vec<String>, designs: Vec<Design>) -> DesignSet {
        let end = designs.len();
        DesignSet { parameters, designs, next: 0, end }
    }

    /// Every combination of the ranges' values, the first range varying slowest (nested loops in the
    /// order given).
    pub fn factorial(ranges: &[ParameterRange]) -> Result<DesignSet, String> {
        let mut total = 1u64;
        for r in ranges {
            let count = r.count.ok_or_else(|| format!("`{}` needs a count (NAME=FROM:TO:COUNT)", r.name))?;
            total = total.checked_mul(count).filter(|&t| t <= MAX_DESIGNS).ok_or_else(|| {
                format!("the factorial has more than {MAX_DESIGNS} designs: fewer values, or --sample lhs:N")
            })?;
        }
        let value = |r: &ParameterRange, i: u64| -> f64 {
            match r.count {
                Some(n) if n > 1 => r.from + (r.to - r.from) * i as f64 / (n - 1) as f64,
                _ => r.from,
            }
        };
        let designs = (0..total)
            .map(|mut d| {
                let mut values = vec![0.0; ranges.len()];
                for (k, r) in ranges.iter().enumerate().rev() {
                    let n = r.count.expect("checked above");
                    values[k] = value(r, d % n);
                    d /= n;
                }
                Design { name: None, values }
            })
            .collect();
        Ok(DesignSet::new(ranges.iter().map(|r| r.name.clone()).collect(), designs))
    }

    /// `samples` designs of a Latin hypercube over the ranges, drawn from `seed`: each range cut into
    /// `samples` equal strata, each stratum used by exactly one design, at a uniform place inside it; the
    /// strata paired at random between parameters. The same seed gives the same designs.
    pub fn latin_hypercube(ranges: &[ParameterRange], samples: u64, seed: u64) -> Result<DesignSet, String> {
        if samples == 0 || samples > MAX_DESIGNS {
            return Err(format!("lhs:N needs 1 <= N <= {MAX_DESIGNS}"));
        }
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let n = samples as usize;
        let mut columns = Vec::with_capacity(ranges.len());
        for r in ranges {
            let mut strata: Vec<usize> = (0..n).collect();
            strata.shuffle(&mut rng);
            let column: Vec<f64> = strata
                .iter()
                .map(|&s| {
                    let u: f64 = rng.random_range(0.0..1.0);
                    r.from + (r.to - r.from) * (s as f64 + u) / n as f64
                })
                .collect();
            columns.push(column);
        }
        let designs = (0..n).map(|i| Design { name: None, values: columns.iter().map(|c| c[i]).collect() }).collect();
        Ok(DesignSet::new(ranges.iter().map(|r| r.name.clone()).collect(), designs))
    }

    /// A CSV with one column per parameter (the header names them) and an optional `design` column of
    /// names; every value a finite number.
    pub fn from_csv(path: &Path) -> Result<DesignSet, InputError> {
        let mut reader =
            csv::ReaderBuilder::new().trim(csv::Trim::All).comment(Some(b'#')).from_reader(open_input(path)?);
        let whole = |m: String| InputError::Whole { path: path.to_path_buf(), message: m };
        let headers = reader.headers().map_err(|e| whole(format!("cannot read the header: {e}")))?.clone();
        let name_column = headers.iter().position(|h| h == DESIGN);
        let parameter_columns: Vec<usize> = (0..headers.len()).filter(|&i| Some(i) != name_column).collect();
        let parameters: Vec<String> = parameter_columns.iter().map(|&i| headers[i].to_string()).collect();
        if parameters.iter().any(String::is_empty) {
            return Err(whole("every parameter column needs a name in the header".into()));
        }
        let mut designs = Vec::new();
        for record in reader.records() {
            let record = record.map_err(|e| {
                let line = e.position().map_or(0, |p| p.line()) as usize;
                InputError::At { path: path.to_path_buf(), line, column: 1, message: e.to_string() }
            })?;
            let line = record.position().map_or(0, |p| p.line()) as usize;
            let values = parameter_columns
                .iter()
                .map(|&i| {
                    let t = record.get(i).unwrap_or("");
                    match t.parse::<f64>() {
                        Ok(v) if v.is_finite() => Ok(v),
                        _ => Err(InputError::At {
                            path: path.to_path_buf(),
                            line,
                            column: i + 1,
                            message: crate::model::error::not_finite(t),
                        }),
                    }
                })
                .collect::<Result<Vec<f64>, InputError>>()?;
            designs.push(Design { name: name_column.and_then(|i| record.get(i)).map(str::to_string), values });
            if designs.len() as u64 > MAX_DESIGNS {
                return Err(whole(format!("more than {MAX_DESIGNS} designs: split the file")));
            }
        }
        if designs.is_empty() {
            return Err(whole("no designs (one row per design below the header)".into()));
        }
        Ok(DesignSet::new(parameters, designs))
    }

    /// Number of designs.
    pub fn len(&self) -> u64 {
        self.designs.len() as u64
    }

    /// True when there are no designs.
    pub fn is_empty(&self) -> bool {
        self.designs.is_empty()
    }

    /// Keeps only the designs with indices in `portion` (a shard's).
    pub fn keep_portion(&mut self, portion: Range<u64>) {
        self.next = (portion.start as usize).min(self.designs.len());
        self.end = (portion.end as usize).min(self.designs.len()).max(self.next);
    }
}

impl Source for DesignSet {
    type Item = Design;

    fn next_block(&mut self, n: usize, out: &mut Vec<Design>) -> Result<usize, InputError> {
        let end = (self.next + n).min(self.end);
        out.extend_from_slice(&self.designs[self.next..end]);
        let added = end - self.next;
        self.next = end;
        Ok(added)
    }

    fn first_index(&self) -> u64 {
        self.next as u64
    }
}

/// The name column of a designs file and of the summary.
pub const DESIGN: &str = "design";

/// What a sweep computes at each design.
#[derive(Clone, Debug, Default)]
pub struct SweepOptions {
    /// The map at each design (unloaded, or loaded under a wrench or each point's wrench).
    pub map: MapOptions,
    /// Count (and measure the volume of) the points where `c_tran_max` is at most this (mm/N).
    pub threshold: Option<f64>,
    /// Also write each design's whole map into this folder, as `design-INDEX.csv`.
    pub maps: Option<PathBuf>,
}

/// The workspace every design is mapped over, read once.
pub struct Workspace {
    /// The points, in input order.
    pub points: Vec<PosePoint>,
    /// The map's optional columns over these points.
    pub columns: MapColumns,
    /// The volume a point of a box grid stands for (mm^3), for the volume under the threshold.
    pub cell_volume: Option<f64>,
}

impl Workspace {
    /// Reads every point of `points` (at most `MAX_SWEEP_POINTS`).
    pub fn read(points: &mut PointSet, options: &MapOptions) -> Result<Workspace> {
        let columns = map_columns(points, options);
        let cell_volume = points.cell_volume();
        let mut all = Vec::new();
        while points.next_block(4096, &mut all)? > 0 {
            if all.len() as u64 > MAX_SWEEP_POINTS {
                anyhow::bail!(
                    "the workspace has more than {MAX_SWEEP_POINTS} points, each mapped at every design: sweep \
                     over a coarser grid, then map the best designs finely"
                );
            }
        }
        Ok(Workspace { points: all, columns, cell_volume })
    }
}

/// Max, mean and 95th percentile of a column over the points where the map has a value.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Statistics {
    /// Largest value.
    pub max: Option<f64>,
    /// Arithmetic mean (sum in point order over the count).
    pub mean: Option<f64>,
    /// 95th percentile, linear between the two nearest ranks (position 0.95 (n - 1) in the sorted values:
    /// numpy's and pandas' default).
    pub p95: Option<f64>,
}

impl Statistics {
    /// Of the finite values (the ones a map writes).
    pub fn of(values: &mut [f64]) -> Statistics {
        if values.is_empty() {
            return Statistics::default();
        }
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        values.sort_by(f64::total_cmp);
        let position = 0.95 * (values.len() - 1) as f64;
        let below = position.floor() as usize;
        let above = (below + 1).min(values.len() - 1);
        let p95 = values[below] + (values[above] - values[below]) * (position - below as f64);
        Statistics { max: values.last().copied(), mean: Some(mean), p95: Some(p95) }
    }
}

/// What a design's map reduces to.
#[derive(Clone, Debug, Default)]
pub struct DesignSummary {
    /// Points of each status, in `Status::ALL` order.
    pub counts: [u64; Status::ALL.len()],
    /// Points mapped.
    pub points: u64,
    /// `c_tran_max` (mm/N).
    pub c_tran: Statistics,
    /// `c_rot_max` (rad/(N mm)).
    pub c_rot: Statistics,
    /// The deflection's length (mm), under a wrench.
    pub deflection: Statistics,
    /// The point of largest `c_tran_max`, the first where several tie.
    pub worst: Option<PosePoint>,
    /// Smallest and largest condition number.
    pub condition: (Option<f64>, Option<f64>),
    /// Points where `c_tran_max` is at most the threshold.
    pub under_threshold: u64,
}

impl DesignSummary {
    /// Reduces the map results of `points` (in order).
    pub fn of(points: &[Cow<PosePoint>], results: &[PointResult], threshold: Option<f64>) -> DesignSummary {
        let mut s = DesignSummary { points: points.len() as u64, ..DesignSummary::default() };
        let (mut tran, mut rot, mut deflection) = (Vec::new(), Vec::new(), Vec::new());
        let mut worst: Option<(f64, usize)> = None;
        for (i, r) in results.iter().enumerate() {
            let k = Status::ALL.iter().position(|&x| x == r.status).expect("every status is listed");
            s.counts[k] += 1;
            if let Some(p) = r.principal {
                let t = p.translation_max;
                if t.is_finite() {
                    tran.push(t);
                    if worst.is_none_or(|(w, _)| t > w) {
                        worst = Some((t, i));
                    }
                    if threshold.is_some_and(|c| t <= c) {
                        s.under_threshold += 1;
                    }
                }
                if p.rotation_max.is_finite() {
                    rot.push(p.rotation_max);
                }
            }
            if let Some(d) = r.deflection.map(|d| d.fixed_rows::<3>(0).norm()).filter(|d| d.is_finite()) {
                deflection.push(d);
            }
            if let Some(c) = r.condition.filter(|c| c.is_finite()) {
                s.condition.0 = Some(s.condition.0.map_or(c, |m: f64| m.min(c)));
                s.condition.1 = Some(s.condition.1.map_or(c, |m: f64| m.max(c)));
            }
        }
        s.c_tran = Statistics::of(&mut tran);
        s.c_rot = Statistics::of(&mut rot);
        s.deflection = Statistics::of(&mut deflection);
        s.worst = worst.map(|(_, i)| points[i].clone().into_owned());
        s
    }
}

/// A design's outcome: its description failed to build (why), or its map's summary.
pub enum DesignOutcome {
    /// The description with these values is not a manipulator (a spring non-positive, a formula failing).
    Invalid(String),
    /// The map's summary.
    Mapped(Box<DesignSummary>),
}

/// Which optional columns a sweep has; fixed before the first row.
#[derive(Clone, Debug)]
pub struct SweepLayout {
    /// The parameters each design sets.
    pub parameters: Vec<String>,
    /// The map's optional columns (orientation of the worst point, deflection).
    pub map: MapColumns,
    /// A threshold was given.
    pub threshold: bool,
    /// The workspace is a box grid with a volume per point.
    pub volume: bool,
}

/// One summary row.
pub struct SweepRow<'a> {
    /// Design number in input order.
    pub index: u64,
    /// The design.
    pub design: &'a Design,
    /// What became of it.
    pub outcome: &'a DesignOutcome,
    /// The volume a workspace point stands for (mm^3).
    pub cell_volume: Option<f64>,
}

impl Row for SweepRow<'_> {
    type Layout = SweepLayout;

    fn record(&self, l: &SweepLayout, r: &mut impl Record) {
        r.count(names::INDEX, Some(self.index));
        r.text(DESIGN, self.design.name.as_deref().unwrap_or(""));
        for (name, v) in l.parameters.iter().zip(&self.design.values) {
            r.number(name, *v);
        }
        let (summary, message) = match self.outcome {
            DesignOutcome::Invalid(m) => (None, m.as_str()),
            DesignOutcome::Mapped(s) => (Some(&**s), ""),
        };
        r.text(names::STATUS, if summary.is_some() { "ok" } else { "invalid" });
        r.text("message", message);
        r.count("points", summary.map(|s| s.points));
        for (k, status) in Status::ALL.iter().enumerate() {
            r.count(format!("{}_points", status.as_str()), summary.map(|s| s.counts[k]));
        }
        let reachable = summary.filter(|s| s.points > 0).map(|s| {
            let unreachable = s.counts[Status::ALL.iter().position(|&x| x == Status::Unreachable).expect("listed")];
            (s.points - unreachable) as f64 / s.points as f64
        });
        r.optional("reachable_fraction", reachable);
        let mut statistics = |column: &str, of: fn(&DesignSummary) -> &Statistics| {
            let st = summary.map(of).copied().unwrap_or_default();
            r.optional(format!("max_{column}"), st.max);
            r.optional(format!("mean_{column}"), st.mean);
            r.optional(format!("p95_{column}"), st.p95);
        };
        statistics(names::C_TRAN_MAX, |s| &s.c_tran);
        statistics("c_rot_max_rad_per_Nmm", |s| &s.c_rot);
        if l.map.deflection {
            statistics("deflection_mm", |s| &s.deflection);
        }
        let worst = summary.and_then(|s| s.worst.as_ref());
        for k in 0..3 {
            r.optional(format!("worst_{}", names::POSITION[k]), worst.map(|p| p.position[k]));
        }
        if l.map.orientation {
            for k in 0..3 {
                r.optional(format!("worst_{}", names::ORIENTATION[k]), worst.map(|p| p.rotation[k]));
            }
        }
        r.optional("min_condition", summary.and_then(|s| s.condition.0));
        r.optional("max_condition", summary.and_then(|s| s.condition.1));
        if l.threshold {
            r.count("under_threshold_points", summary.map(|s| s.under_threshold));
            if l.volume {
                let volume = summary.zip(self.cell_volume).map(|(s, v)| s.under_threshold as f64 * v);
                r.optional("under_threshold_volume_mm3", volume);
            }
        }
    }
}

/// The columns of a sweep's summary.
pub fn sweep_table(l: &SweepLayout) -> Vec<Column> {
    let design = Design { name: None, values: vec![0.0; l.parameters.len()] };
    let outcome = DesignOutcome::Invalid(String::new());
    selected_columns(&SweepRow { index: 0, design: &design, outcome: &outcome, cell_volume: None }, l, None)
}

/// Designs by outcome, and the first failure to write a design's map (which stops the command).
#[derive(Debug, Default)]
pub struct SweepSummary {
    /// Designs swept.
    pub designs: u64,
    /// Designs whose description did not build.
    pub invalid: u64,
    /// Points mapped over all designs.
    pub points: u64,
    /// The first design map that could not be written.
    pub map_error: Option<String>,
}

impl Tally for SweepSummary {
    fn merge(&mut self, o: &SweepSummary) {
        self.designs += o.designs;
        self.invalid += o.invalid;
        self.points += o.points;
        if self.map_error.is_none() {
            self.map_error.clone_from(&o.map_error);
        }
    }
}

impl SweepSummary {
    /// `N designs (k invalid), P points`.
    pub fn line(&self) -> String {
        format!("{} designs ({} invalid), {} points mapped", self.designs, self.invalid, self.points)
    }
}

/// The description a sweep varies: its file (for messages and `from` paths), its text, and the `--set`
/// values every design starts from.
pub struct Description<'a> {
    /// The model file.
    pub path: &'a Path,
    /// Its text.
    pub source: &'a str,
    /// Parameter values given for the whole sweep (a design's own values replace them).
    pub base: BTreeMap<String, f64>,
}

struct SweepStudy<'a> {
    description: Description<'a>,
    parameters: Vec<String>,
    workspace: &'a Workspace,
    options: &'a SweepOptions,
    layout: SweepLayout,
}

impl SweepStudy<'_> {
    /// Maps design `index`: builds its manipulator, solves every point in order, writes the map file if
    /// asked; the map's rows are what `stiff map` writes for this description with these values.
    fn sweep(&self, index: u64, design: &Design, tally: &mut SweepSummary) -> DesignOutcome {
        let mut overrides = self.description.base.clone();
        for (name, v) in self.parameters.iter().zip(&design.values) {
            overrides.insert(name.clone(), *v);
        }
        let model = match parse_with(self.description.path, self.description.source, &overrides, 0) {
            Ok(m) => m,
            Err(e) => return DesignOutcome::Invalid(e.to_string()),
        };
        let m = &model.manipulator;
        let mut state = (m.new_state(), LoadedHistory::default());
        // Joint coordinates are placed by each design's own forward kinematics (its tool may differ).
        let (points, results): (Vec<Cow<PosePoint>>, Vec<PointResult>) =
            self.workspace.points.iter().map(|p| map_given_point(m, p, &self.options.map, &mut state)).unzip();
        if let Some(dir) = &self.options.maps {
            if let Err(e) = self.write_map(dir, index, &points, &results) {
                if tally.map_error.is_none() {
                    tally.map_error = Some(format!("design {index}'s map: {e:#}"));
                }
            }
        }
        tally.points += results.len() as u64;
        DesignOutcome::Mapped(Box::new(DesignSummary::of(&points, &results, self.options.threshold)))
    }

    fn write_map(&self, dir: &Path, index: u64, points: &[Cow<PosePoint>], results: &[PointResult]) -> Result<()> {
        let columns = &self.workspace.columns;
        let mut sink = Sink::table(Some(&map_file(dir, index)), &map_table(columns, None))?;
        let mut text = crate::output::table::header_line(&map_table(columns, None));
        for (i, (p, r)) in points.iter().zip(results).enumerate() {
            write_selected_row(&MapRow { index: i as u64, tip: None, point: p, result: r }, columns, None, &mut text);
            if text.len() > 1 << 20 {
                sink.writer().write_all(text.as_bytes())?;
                text.clear();
            }
        }
        sink.writer().write_all(text.as_bytes())?;
        sink.finish()
    }
}

/// Where design `index`'s map goes in `dir`.
pub fn map_file(dir: &Path, index: u64) -> PathBuf {
    dir.join(format!("design-{index}.csv"))
}

impl Study for SweepStudy<'_> {
    type Item = Design;
    /// Nothing carries from one design to the next (each has its own manipulator).
    type State = ();
    type Tally = SweepSummary;

    fn columns(&self) -> Vec<Column> {
        sweep_table(&self.layout)
    }

    /// One design per run: designs share nothing, so each is a task of its own.
    fn run_length(&self) -> usize {
        1
    }

    fn new_state(&self) {}

    fn solve(&self, index: u64, design: &Design, _: &mut (), tally: &mut SweepSummary, out: &mut String) {
        let outcome = self.sweep(index, design, tally);
        tally.designs += 1;
        if matches!(outcome, DesignOutcome::Invalid(_)) {
            tally.invalid += 1;
        }
        let row = SweepRow { index, design, outcome: &outcome, cell_volume: self.workspace.cell_volume };
        write_row(&row, &self.layout, out);
    }
}

/// The layout of a sweep of `designs` over `workspace`.
pub fn sweep_layout(designs: &DesignSet, workspace: &Workspace, options: &SweepOptions) -> SweepLayout {
    SweepLayout {
        parameters: designs.parameters.clone(),
        map: workspace.columns,
        threshold: options.threshold.is_some(),
        volume: workspace.cell_volume.is_some(),
    }
}

/// Sweeps `designs` of `description` over `workspace` on `pool`, the summary rows streamed to `out` in
/// design order.
pub fn run_sweep(
    pool: &rayon::ThreadPool,
    description: Description,
    designs: &mut DesignSet,
    workspace: &Workspace,
    options: &SweepOptions,
    out: &mut (dyn Write + Send),
    progress: &ProgressBar,
) -> Result<SweepSummary> {
    let layout = sweep_layout(designs, workspace, options);
    let study = SweepStudy { description, parameters: designs.parameters.clone(), workspace, options, layout };
    let summary = stream(pool, &study, designs, out, progress)?;
    if let Some(e) = &summary.map_error {
        anyhow::bail!("{e}");
    }
    Ok(summary)
}
