//! `stiff map`: the manipulator's unloaded stiffness at every point of a grid, as CSV rows in input order.

use std::borrow::Cow;
use std::io::Write;

use anyhow::Result;
use indicatif::ProgressBar;

use super::point::{loaded_point, unloaded_point, LoadedHistory, PointResult, Status};
use crate::batch::{stream, Study, Tally};
use crate::kinematics::frame::Vec6;
use crate::model::grid::PointSet;
use crate::model::grid::PosePoint;
use crate::output::table::{
    column_names, header_line, names, selected_columns, write_selected_row, Column, ColumnTest, Matrix, Record, Row,
    Selection, Triangle,
};
use crate::platform::manipulator::{Manipulator, ManipulatorState};

/// What `stiff map` computes.
#[derive(Clone, Debug, Default)]
pub struct MapOptions {
    /// Also write the 21 entries of the stiffness matrix.
    pub stiffness: bool,
    /// Loaded mode: the equilibrium under this wrench at every point (or, with `use_point_wrench`, under
    /// each point's reference wrench).
    pub wrench: Option<Vec6>,
    /// Loaded mode under each point's own wrench.
    pub use_point_wrench: bool,
    /// The columns written (`--columns`), all where None.
    pub selection: Option<Selection>,
    /// A tree with several tips: the tips whose rows the map writes, each point once per tip in this order
    /// (a `tip` column); empty for a manipulator with one reference point.
    pub tips: Vec<String>,
}

/// The groups `--columns` knows, in table order.
pub const COLUMN_GROUPS: [&str; 6] = ["pose", "status", "principal", "deflection", "C", "K"];

/// A group's test on a column name (None: not a group).
fn column_group(name: &str) -> Option<ColumnTest> {
    let matrix = |letter: char| -> ColumnTest {
        Box::new(move |c: &str| c.starts_with(letter) && c[1..].starts_with(|d: char| d.is_ascii_digit()))
    };
    Some(match name {
        "pose" => Box::new(|c: &str| {
            [names::INDEX, names::NAME, names::TIP].contains(&c)
                || names::POSITION.contains(&c)
                || names::ORIENTATION.contains(&c)
        }),
        "status" => Box::new(|c: &str| ["status", "rank", "free_directions", "condition"].contains(&c)),
        "principal" => Box::new(|c: &str| c.starts_with("c_tran_") || c.starts_with("c_rot_")),
        "deflection" => Box::new(|c: &str| names::DISPLACEMENT.contains(&c) || c == "deflection_mm"),
        "C" => matrix('C'),
        "K" => matrix('K'),
        _ => return None,
    })
}

/// The selection `--columns` asks of a map with these columns: names or groups (`COLUMN_GROUPS`).
pub fn map_selection(c: &MapColumns, wanted: &[&str]) -> Result<Selection, String> {
    let point = PosePoint::default();
    let names = column_names(&MapRow { index: 0, tip: None, point: &point, result: &PointResult::blank() }, c);
    Selection::new(&names, wanted, column_group, &COLUMN_GROUPS)
}

/// How many points ended with each status.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MapSummary {
    /// Points in the map.
    pub points: u64,
    /// Points with status ok.
    pub ok: u64,
    /// Unreachable points.
    pub unreachable: u64,
    /// Singular points (platform or leg).
    pub singular: u64,
    /// Points whose loaded equilibrium was not found.
    pub not_converged: u64,
    /// Points whose loaded equilibrium is unstable.
    pub unstable: u64,
    /// Ill-conditioned points.
    pub ill_conditioned: u64,
    /// Points whose numbers overflowed.
    pub overflow: u64,
    /// Points of a serial arm rigid along some direction.
    pub rigid_directions: u64,
}

impl MapSummary {
    /// Counts a point with this status.
    pub fn add(&mut self, s: Status) {
        self.points += 1;
        match s {
            Status::Ok => self.ok += 1,
            Status::Unreachable => self.unreachable += 1,
            Status::Singular | Status::SingularLeg => self.singular += 1,
            Status::NotConverged => self.not_converged += 1,
            Status::Unstable => self.unstable += 1,
            Status::IllConditioned => self.ill_conditioned += 1,
            Status::Overflow => self.overflow += 1,
            Status::RigidDirections => self.rigid_directions += 1,
        }
    }
}

impl MapSummary {
    /// `N points: a ok, b unreachable, ...`, listing only the statuses that occurred.
    pub fn line(&self) -> String {
        let counts = [
            (self.ok, "ok"),
            (self.unreachable, "unreachable"),
            (self.singular, "singular"),
            (self.ill_conditioned, "ill_conditioned"),
            (self.not_converged, "not_converged"),
            (self.unstable, "unstable"),
            (self.overflow, "overflow"),
            (self.rigid_directions, "rigid_directions"),
        ];
        let parts: Vec<String> = counts.iter().filter(|(n, _)| *n > 0).map(|(n, s)| format!("{n} {s}")).collect();
        format!("{} points: {}", self.points, parts.join(", "))
    }
}

impl Tally for MapSummary {
    fn merge(&mut self, o: &MapSummary) {
        self.points += o.points;
        self.ok += o.ok;
        self.unreachable += o.unreachable;
        self.singular += o.singular;
        self.not_converged += o.not_converged;
        self.unstable += o.unstable;
        self.ill_conditioned += o.ill_conditioned;
        self.overflow += o.overflow;
        self.rigid_directions += o.rigid_directions;
    }
}

/// Which optional columns a map has; fixed by the input before the first row.
#[derive(Clone, Copy, Debug)]
pub struct MapColumns {
    /// Each point is a row per tip of a tree, named in a `tip` column.
    pub tips: bool,
    /// The points give orientations.
    pub orientation: bool,
    /// Also the stiffness matrix.
    pub stiffness: bool,
    /// The deflection under the point's (or the map's) wrench.
    pub deflection: bool,
    /// Loaded mode: the compliance is the tangent compliance at the loaded equilibrium, the deflection that
    /// equilibrium's displacement; the lower triangles of C and K (not symmetric under load) and the
    /// Newton iteration count are appended after the unloaded columns.
    pub loaded: bool,
}

/// One row of a map: a point and what the study found there.
pub struct MapRow<'a> {
    /// Row number in input order (the point's: a tree's tips share it).
    pub index: u64,
    /// The tip of a tree whose row this is.
    pub tip: Option<&'a str>,
    /// The point as requested.
    pub point: &'a PosePoint,
    /// What was found there.
    pub result: &'a PointResult,
}

impl Row for MapRow<'_> {
    type Layout = MapColumns;

    fn record(&self, c: &MapColumns, r: &mut impl Record) {
        let (p, res) = (self.point, self.result);
        let tip = c.tips.then(|| self.tip.unwrap_or(""));
        super::point::record_pose_at(r, self.index, tip, p, c.orientation);
        r.text(names::STATUS, res.status.as_str());
        r.count("rank", res.rank.map(|k| k as u64));
        r.free_directions("free_directions", &res.free);
        r.optional("condition", res.condition.filter(|c| c.is_finite()));
        let pc = res.principal;
        r.optional(names::C_TRAN_MAX, pc.map(|p| p.translation_max));
        r.optional("c_tran_min_mm_per_N", pc.map(|p| p.translation_min));
        r.optional("c_rot_max_rad_per_Nmm", pc.map(|p| p.rotation_max));
        if c.deflection {
            r.six(names::DISPLACEMENT, res.deflection.as_ref());
            r.optional("deflection_mm", res.deflection.map(|d| d.fixed_rows::<3>(0).norm()));
        }
        r.matrix(Matrix::Compliance, res.compliance.as_ref(), Triangle::Upper);
        if c.stiffness {
            r.matrix(Matrix::Stiffness, res.stiffness.as_ref(), Triangle::Upper);
        }
        // Loaded mode appends what it adds, so the unloaded columns keep their places: the lower triangles
        // of the non-symmetric tangent matrices, then the Newton iterations.
        if c.loaded {
            r.matrix(Matrix::Compliance, res.compliance.as_ref(), Triangle::Lower);
            if c.stiffness {
                r.matrix(Matrix::Stiffness, res.stiffness.as_ref(), Triangle::Lower);
            }
            r.count(names::ITERATIONS, Some(res.iterations as u64));
        }
    }
}

/// The header line of a map with these columns.
pub fn map_header(c: &MapColumns, selection: Option<&Selection>) -> String {
    header_line(&map_table(c, selection))
}

/// The columns a map with these options writes, in order.
pub fn map_table(c: &MapColumns, selection: Option<&Selection>) -> Vec<Column> {
    let point = PosePoint::default();
    selected_columns(&MapRow { index: 0, tip: None, point: &point, result: &PointResult::blank() }, c, selection)
}

/// The columns a map of these points with these options writes (known before the first row).
pub fn map_columns(points: &PointSet, options: &MapOptions) -> MapColumns {
    let loaded = options.wrench.is_some() || options.use_point_wrench;
    MapColumns {
        tips: !options.tips.is_empty(),
        orientation: points.has_orientation,
        stiffness: options.stiffness,
        deflection: points.has_wrench || loaded,
        loaded,
    }
}

/// A map's row at a point as its input gives it (a pose, or a serial arm's joint coordinates): the pose
/// (forward kinematics' where joints are given) and what the map finds there; `unreachable` where the
/// joint coordinates give no finite pose.
pub fn map_given_point<'a>(
    m: &Manipulator,
    p: &'a PosePoint,
    options: &MapOptions,
    state: &mut (ManipulatorState, LoadedHistory),
) -> (Cow<'a, PosePoint>, PointResult) {
    match super::point::pose_of_joints(m, p, &mut state.0) {
        Some(placed) => {
            // At joint coordinates the arm is where `pose_of_joints` seeded it: no placement.
            let r = if p.joints.is_empty() {
                map_point(m, &placed, options, state)
            } else {
                match point_wrench(&placed, options) {
                    None => super::point::unloaded_at_joints(m, &placed, &mut state.0),
                    Some(w) => super::point::loaded_at_joints(m, &placed, &w, &mut state.0, &mut state.1),
                }
            };
            (placed, r)
        }
        None => (Cow::Borrowed(p), PointResult::failed(Status::Unreachable)),
    }
}

/// What the map finds at `p` (unloaded, or loaded as `options` say), warm-started from `state`.
pub fn map_point(
    m: &Manipulator,
    p: &PosePoint,
    options: &MapOptions,
    (state, history): &mut (ManipulatorState, LoadedHistory),
) -> PointResult {
    match point_wrench(p, options) {
        None => unloaded_point(m, p, state),
        Some(w) => loaded_point(m, p, &w, state, history),
    }
}

/// The wrench a loaded map applies at `p` (its own, or the run's; zero where a point has none); None for
/// an unloaded map.
fn point_wrench(p: &PosePoint, options: &MapOptions) -> Option<Vec6> {
    let wrench = if options.use_point_wrench { p.wrench } else { options.wrench };
    (options.wrench.is_some() || options.use_point_wrench).then(|| wrench.unwrap_or_else(Vec6::zeros))
}

/// The map as a streamed study.
struct MapStudy<'a> {
    m: &'a Manipulator,
    options: MapOptions,
    columns: MapColumns,
    /// A tree's tips whose rows are written, each with the tree turned to have its reference point there.
    tip_models: Vec<(String, Manipulator)>,
}

impl Study for MapStudy<'_> {
    type Item = PosePoint;
    /// Warm starts of the legs, and of the loaded equilibrium from the previous points.
    type State = (ManipulatorState, LoadedHistory);
    type Tally = MapSummary;

    fn columns(&self) -> Vec<Column> {
        map_table(&self.columns, self.options.selection.as_ref())
    }

    fn new_state(&self) -> Self::State {
        (self.m.new_state(), LoadedHistory::default())
    }

    fn solve(&self, index: u64, p: &PosePoint, state: &mut Self::State, tally: &mut MapSummary, out: &mut String) {
        if self.tip_models.is_empty() {
            let (p, r) = map_given_point(self.m, p, &self.options, state);
            tally.add(r.status);
            let row = MapRow { index, tip: None, point: &p, result: &r };
            write_selected_row(&row, &self.columns, self.options.selection.as_ref(), out);
            return;
        }
        // The tree's chains share their coordinates (and so one state): each tip's row from the same point.
        for (tip, m) in &self.tip_models {
            let (p, r) = map_given_point(m, p, &self.options, state);
            tally.add(r.status);
            let row = MapRow { index, tip: Some(tip), point: &p, result: &r };
            write_selected_row(&row, &self.columns, self.options.selection.as_ref(), out);
        }
    }
}

/// The map of `m` over `points`, streamed to `out` in input order; the count of each status.
pub fn run_map(
    pool: &rayon::ThreadPool,
    m: &Manipulator,
    points: &mut PointSet,
    options: MapOptions,
    out: &mut (dyn Write + Send),
    progress: &ProgressBar,
) -> Result<MapSummary> {
    let columns = map_columns(points, &options);
    let tip_models = options
        .tips
        .iter()
        .map(|t| m.at_tip(t).map(|turned| (t.clone(), turned)))
        .collect::<Option<Vec<_>>>()
        .ok_or_else(|| {
            anyhow::anyhow!("a tip of the map is not a tip of {} (tips: {})", m.name, m.tips().join(", "))
        })?;
    stream(pool, &MapStudy { m, options, columns, tip_models }, points, out, progress)
}
