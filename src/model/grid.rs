//! Where to evaluate: a box grid or named points in TOML (`manipulators/grids/`), or a CSV of points from
//! any other tool. Points are read in blocks, so a map never holds all of them in memory.

use crate::columns as names;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use super::error::{is_stdin, not_finite, open_input, read_text, InputError, Locator};
use crate::kinematics::frame::{Frame, Vec3, Vec6};

/// One pose to evaluate.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PosePoint {
    /// The point's name, where the input gives one.
    pub name: Option<String>,
    /// Platform reference point, mm.
    pub position: Vec3,
    /// Platform orientation as a rotation vector, rad.
    pub rotation: Vec3,
    /// Reference wrench (N, N mm) at the reference point, if the input gives one.
    pub wrench: Option<Vec6>,
    /// A serial arm's joint coordinates as its controller gives them (rad, or mm for a prismatic joint), in
    /// the order of `PointSet::joint_names` (the arm's own order once `PointSet::order_joints` has run); empty
    /// where the pose is given as a pose. The study puts the pose where forward kinematics puts it.
    pub joints: Vec<f64>,
}

impl PosePoint {
    /// The platform frame of this pose.
    pub fn frame(&self) -> Frame {
        Frame::from_position_rotvec(self.position, self.rotation)
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct GridFile {
    #[serde(rename = "box", default)]
    boxgrid: Option<Spanned<BoxSpec>>,
    #[serde(rename = "point", default)]
    points: Vec<PointSpec>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BoxSpec {
    /// First corner, mm.
    from: Spanned<Vec<f64>>,
    /// Last corner, mm.
    to: Spanned<Vec<f64>>,
    /// Number of points along x, y, z (each at least 1). `steps`, its former name, is still read.
    #[serde(alias = "steps")]
    points: Spanned<Vec<i64>>,
    /// Fixed platform orientation, rotation vector in rad.
    #[serde(default)]
    orientation: Option<Spanned<Vec<f64>>>,
    /// Reference wrench (Fx, Fy, Fz in N, Mx, My, Mz in N mm).
    #[serde(default)]
    wrench: Option<Spanned<Vec<f64>>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PointSpec {
    name: String,
    at: Spanned<Vec<f64>>,
    #[serde(default)]
    orientation: Option<Spanned<Vec<f64>>>,
    #[serde(default)]
    wrench: Option<Spanned<Vec<f64>>>,
}

/// Most points a grid may hold: at the fastest model's ~200,000 points/s on two cores, 1e10 points are
/// 14 hours of computing, a long cluster job; a larger request is a typo or wants splitting (docs/GUIDE.md).
pub const MAX_GRID_POINTS: u64 = 10_000_000_000;

#[derive(Clone, Debug)]
struct BoxGrid {
    from: Vec3,
    to: Vec3,
    steps: [usize; 3],
    /// Per axis, the decimal places in which `from`, `to` and the spacing are exact (None: not a short
    /// decimal), so that coordinates are computed in integers and written as the decimals the user meant.
    decimals: [Option<u32>; 3],
    rotation: Vec3,
    wrench: Option<Vec6>,
}

impl BoxGrid {
    fn len(&self) -> u64 {
        self.steps.iter().map(|&s| s as u64).product()
    }

    /// Point `i`, x varying fastest, then y, then z.
    fn point(&self, i: u64) -> PosePoint {
        let nx = self.steps[0] as u64;
        let ny = self.steps[1] as u64;
        let idx = [i % nx, (i / nx) % ny, i / (nx * ny)];
        let mut p = Vec3::zeros();
        for k in 0..3 {
            p[k] = match (self.steps[k], self.decimals[k]) {
                (1, _) => self.from[k],
                // -73.65 + 10 * i in hundredths: -7365 + 1000 i, then one correctly rounded division, so
                // the coordinate is the double nearest the decimal (-63.65, not -63.650000000000006).
                (n, Some(d)) => {
                    let scale = 10f64.powi(d as i32);
                    let (from, to) = ((self.from[k] * scale).round() as i128, (self.to[k] * scale).round() as i128);
                    let units = from + (to - from) * idx[k] as i128 / (n as i128 - 1);
                    units as f64 / scale
                }
                (n, None) => self.from[k] + (self.to[k] - self.from[k]) * idx[k] as f64 / (n - 1) as f64,
            };
        }
        PosePoint { name: None, position: p, rotation: self.rotation, wrench: self.wrench, joints: Vec::new() }
    }
}

/// The fewest decimal places (up to 9) in which `from`, `to` and the spacing of `n` points between them
/// are all exact decimals, e.g. 2 for -73.65 .. 126.35 in 21 points; None where there is none (a third of a
/// millimetre) or the numbers are too large for exact integer arithmetic.
fn grid_decimals(from: f64, to: f64, n: usize) -> Option<u32> {
    if n < 2 {
        return None;
    }
    (0..=9u32).find(|&d| {
        let scale = 10f64.powi(d as i32);
        let (f, t) = (from * scale, to * scale);
        let exact = |v: f64| v.abs() < 1e15 && (v - v.round()).abs() <= 4.0 * f64::EPSILON * v.abs().max(1.0);
        if !(exact(f) && exact(t)) {
            return false;
        }
        let span = t.round() as i128 - f.round() as i128;
        span % (n as i128 - 1) == 0
    })
}

/// Columns of a points CSV.
// A points file uses the column names the studies write (`output::table::names`), so a map's output is a
// valid points file.
const WRENCH_COLUMNS: [&str; 6] = names::WRENCH;
const ORIENTATION_COLUMNS: [&str; 3] = names::ORIENTATION;

struct CsvColumns {
    name: Option<usize>,
    /// The position's columns; None where the poses are given by joint coordinates alone.
    xyz: Option<[usize; 3]>,
    /// The `q_<joint>` columns.
    joints: Vec<usize>,
    orientation: Option<[usize; 3]>,
    wrench: Option<[usize; 6]>,
}

enum Source {
    Grid {
        grid: Option<BoxGrid>,
        named: Vec<PosePoint>,
        next: u64,
    },
    Csv {
        path: PathBuf,
        reader: csv::Reader<Box<dyn std::io::Read + Send>>,
        columns: CsvColumns,
        record: csv::ByteRecord,
    },
}

/// The joint space whose limits a points file's joint coordinates are checked against, and what to do with
/// the first row outside them (the command prints a warning).
pub struct LimitWatch {
    /// The arm's joints, in the order the points are read in (`PointSet::order_joints` has run).
    pub space: crate::platform::manipulator::JointSpace,
    /// Called once, with the file, line and what is outside.
    pub warn: Box<dyn FnMut(String) + Send>,
}

/// A stream of poses, read in blocks.
pub struct PointSet {
    /// True when the input sets an orientation (the map then reports it).
    pub has_orientation: bool,
    /// True when the input gives reference wrenches (the map then reports deflections).
    pub has_wrench: bool,
    /// Number of points, when known in advance.
    pub len: Option<u64>,
    /// The joints of the points file's `q_<joint>` columns, in their order (empty: poses are given as poses).
    pub joint_names: Vec<String>,
    /// True when a points file gives both a pose (`x_mm`, ...) and joint coordinates (`q_<joint>`): the
    /// joint coordinates are used.
    pub pose_and_joints: bool,
    source: Source,
    /// Where the joint coordinates read are checked against the arm's limits, the first row outside them
    /// handed to the watch's warning (once).
    limit_watch: Option<LimitWatch>,
    /// The input index of the next point read.
    next_index: u64,
    /// The index where reading stops (a shard's portion), if before the end.
    end_index: Option<u64>,
}

impl PointSet {
    /// Points given in memory (a path along a line, say), named or not.
    pub fn from_points(points: Vec<PosePoint>) -> Self {
        PointSet {
            has_orientation: points.iter().any(|p| p.rotation != Vec3::zeros()),
            has_wrench: points.iter().any(|p| p.wrench.is_some()),
            len: Some(points.len() as u64),
            joint_names: Vec::new(),
            pose_and_joints: false,
            source: Source::Grid { grid: None, named: points, next: 0 },
            limit_watch: None,
            next_index: 0,
            end_index: None,
        }
    }

    /// A grid file (TOML): a `[box]`, named `[[point]]`s, or both (box points first).
    pub fn from_grid_file(path: &Path) -> Result<Self, InputError> {
        let source = read_text(path)?;
        let loc = Locator { path, source: &source };
        let file: GridFile = toml::from_str(&source).map_err(|e| loc.syntax(e))?;
        let grid = match &file.boxgrid {
            None => None,
            Some(b) => {
                let s = b.get_ref();
                let from: [f64; 3] = loc.finite_array(&s.from, "from")?;
                let to: [f64; 3] = loc.finite_array(&s.to, "to")?;
                let counts = s.points.get_ref();
                if counts.len() != 3 {
                    return Err(loc.at(s.points.span(), format!("`points` needs 3 numbers, got {}", counts.len())));
                }
                let mut steps = [0usize; 3];
                for k in 0..3 {
                    let n = counts[k];
                    if n < 1 {
                        return Err(
                            loc.at(s.points.span(), format!("`points` must be at least 1 along each axis, got {n}"))
                        );
                    }
                    if n == 1 && from[k] != to[k] {
                        return Err(loc.at(s.points.span(), "one point along an axis needs `from` equal to `to` on it"));
                    }
                    steps[k] = n as usize;
                }
                let total = steps.iter().try_fold(1u64, |a, &n| a.checked_mul(n as u64));
                if total.is_none_or(|t| t > MAX_GRID_POINTS) {
                    return Err(loc.at(
                        s.points.span(),
                        format!(
                            "{} x {} x {} points is more than a grid may hold ({MAX_GRID_POINTS}: 14 hours of \
                             computing at 200,000 points/s); split it into several grids",
                            steps[0], steps[1], steps[2]
                        ),
                    ));
                }
                Some(BoxGrid {
                    from: Vec3::from(from),
                    to: Vec3::from(to),
                    steps,
                    decimals: [0, 1, 2].map(|k| grid_decimals(from[k], to[k], steps[k])),
                    rotation: Vec3::from(loc.optional_array(&s.orientation, "orientation")?.unwrap_or([0.0; 3])),
                    wrench: loc.optional_array(&s.wrench, "wrench")?.map(Vec6::from),
                })
            }
        };
        let named: Vec<PosePoint> = file
            .points
            .iter()
            .map(|p| {
                Ok(PosePoint {
                    name: Some(p.name.clone()),
                    position: Vec3::from(loc.finite_array(&p.at, "at")?),
                    rotation: Vec3::from(loc.optional_array(&p.orientation, "orientation")?.unwrap_or([0.0; 3])),
                    wrench: loc.optional_array(&p.wrench, "wrench")?.map(Vec6::from),
                    joints: Vec::new(),
                })
            })
            .collect::<Result<_, InputError>>()?;
        if grid.is_none() && named.is_empty() {
            return Err(loc.whole("a grid needs a [box] or at least one [[point]]"));
        }
        let b = file.boxgrid.as_ref().map(|b| b.get_ref());
        let has_orientation =
            b.is_some_and(|b| b.orientation.is_some()) || file.points.iter().any(|p| p.orientation.is_some());
        let has_wrench = b.is_some_and(|b| b.wrench.is_some()) || file.points.iter().any(|p| p.wrench.is_some());
        let len = grid.as_ref().map_or(0, |g| g.len()) + named.len() as u64;
        Ok(Self {
            has_orientation,
            has_wrench,
            len: Some(len),
            joint_names: Vec::new(),
            pose_and_joints: false,
            source: Source::Grid { grid, named, next: 0 },
            limit_watch: None,
            next_index: 0,
            end_index: None,
        })
    }

    /// A CSV with columns `x_mm,y_mm,z_mm`, optionally `name`, `pose_rx_rad,pose_ry_rad,pose_rz_rad` and
    /// `Fx_N,Fy_N,Fz_N,Mx_Nmm,My_Nmm,Mz_Nmm`.
    pub fn from_points_csv(path: &Path) -> Result<Self, InputError> {
        let file = open_input(path)?;
        // Fields are trimmed as they are parsed (`read_source`): the reader's own trimming of fields copies
        // every record into a newly allocated one.
        let mut reader = csv::ReaderBuilder::new().trim(csv::Trim::Headers).comment(Some(b'#')).from_reader(file);
        let whole = |m: String| InputError::Whole { path: path.to_path_buf(), message: m };
        let headers = reader.headers().map_err(|e| whole(format!("cannot read the header: {e}")))?.clone();
        let find = |n: &str| headers.iter().position(|h| h == n);
        let need = |n: &str| {
            find(n).ok_or_else(|| {
                whole(format!("no column `{n}` (columns: {})", headers.iter().collect::<Vec<_>>().join(",")))
            })
        };
        // A serial arm's poses may be given by its joint coordinates (`q_<joint>` columns) instead.
        let joint_columns: Vec<(usize, String)> = headers
            .iter()
            .enumerate()
            .filter_map(|(i, h)| h.strip_prefix(crate::columns::JOINT_PREFIX).map(|n| (i, n.to_string())))
            .collect();
        let xyz = if joint_columns.is_empty() || find(names::POSITION[0]).is_some() {
            Some([need(names::POSITION[0])?, need(names::POSITION[1])?, need(names::POSITION[2])?])
        } else {
            None
        };
        let group = |names: &[&str]| -> Result<Option<Vec<usize>>, InputError> {
            let found: Vec<Option<usize>> = names.iter().map(|n| find(n)).collect();
            match found.iter().filter(|f| f.is_some()).count() {
                0 => Ok(None),
                n if n == names.len() => Ok(Some(found.into_iter().flatten().collect())),
                _ => Err(whole(format!("give all of the columns {} or none", names.join(",")))),
            }
        };
        let orientation = group(&ORIENTATION_COLUMNS)?.map(|v| [v[0], v[1], v[2]]);
        let wrench = group(&WRENCH_COLUMNS)?.map(|v| [v[0], v[1], v[2], v[3], v[4], v[5]]);
        let joint_names = joint_columns.iter().map(|(_, n)| n.clone()).collect();
        let joints = joint_columns.iter().map(|(i, _)| *i).collect();
        let pose_and_joints = xyz.is_some() && !joint_columns.is_empty();
        let columns = CsvColumns { name: find(names::NAME), xyz, joints, orientation, wrench };
        Ok(Self {
            has_orientation: columns.orientation.is_some(),
            has_wrench: columns.wrench.is_some(),
            len: None,
            joint_names,
            pose_and_joints,
            source: Source::Csv { path: path.to_path_buf(), reader, columns, record: csv::ByteRecord::new() },
            limit_watch: None,
            next_index: 0,
            end_index: None,
        })
    }

    /// Reads the joint coordinates in the order `order` gives (`order[k]`: the position among today's
    /// `joint_names` of the k-th joint wanted), so that every point's `joints` follows an arm's own order.
    pub fn order_joints(&mut self, order: &[usize]) {
        self.joint_names = order.iter().map(|&i| self.joint_names[i].clone()).collect();
        if let Source::Csv { columns, .. } = &mut self.source {
            columns.joints = order.iter().map(|&i| columns.joints[i]).collect();
        }
    }

    /// Checks the joint coordinates read from now on against `watch`'s limits (a points file of a serial arm).
    pub fn watch_limits(&mut self, watch: LimitWatch) {
        self.limit_watch = Some(watch);
    }

    /// The volume each point of a box grid stands for (mm^3: the product of its three spacings), where the
    /// points are a box with more than one point along every axis and nothing else.
    pub fn cell_volume(&self) -> Option<f64> {
        match &self.source {
            Source::Grid { grid: Some(g), named, .. } if named.is_empty() && g.steps.iter().all(|&n| n > 1) => {
                Some((0..3).map(|k| (g.to[k] - g.from[k]).abs() / (g.steps[k] - 1) as f64).product())
            }
            _ => None,
        }
    }

    /// The input index of the next point read (where a shard's portion starts, before reading).
    pub fn next_index(&self) -> u64 {
        self.next_index
    }

    /// The number of points: known for a grid or a path, counted for a points file (a pass over its
    /// records, each checked as CSV only), which must be a file: standard input cannot be read twice.
    pub fn count(&mut self) -> Result<u64, InputError> {
        if let Some(n) = self.len {
            return Ok(n);
        }
        let Source::Csv { path, .. } = &self.source else { unreachable!("grids know their length") };
        if is_stdin(path) {
            return Err(InputError::Whole {
                path: path.clone(),
                message: "the points must be counted before the run, so they must be in a file, not standard input"
                    .into(),
            });
        }
        let mut reader = csv::ReaderBuilder::new().comment(Some(b'#')).from_reader(open_input(path)?);
        let mut record = csv::ByteRecord::new();
        let mut n = 0u64;
        loop {
            match reader.read_byte_record(&mut record) {
                Ok(false) => break,
                Ok(true) => n += 1,
                Err(e) => {
                    let line = e.position().map_or(0, |p| p.line()) as usize;
                    return Err(InputError::At { path: path.clone(), line, column: 1, message: e.to_string() });
                }
            }
        }
        self.len = Some(n);
        Ok(n)
    }

    /// Keeps only the points with input indices in `portion` (a shard's): the ones before it are skipped
    /// (read, for a points file, and checked), reading stops at its end, and `len` becomes its length.
    pub fn keep_portion(&mut self, portion: std::ops::Range<u64>) -> Result<(), InputError> {
        let mut skipped = Vec::new();
        while self.next_index < portion.start {
            skipped.clear();
            let n = (portion.start - self.next_index).min(SKIP_BLOCK as u64) as usize;
            if self.read_block(n, &mut skipped)? == 0 {
                break;
            }
        }
        self.end_index = Some(portion.end);
        self.len = Some(portion.end.saturating_sub(portion.start));
        Ok(())
    }

    /// Appends up to `n` points to `out`; returns how many were added (0 at the end).
    pub fn next_block(&mut self, n: usize, out: &mut Vec<PosePoint>) -> Result<usize, InputError> {
        let n = match self.end_index {
            Some(end) => n.min(end.saturating_sub(self.next_index) as usize),
            None => n,
        };
        self.read_block(n, out)
    }

    fn read_block(&mut self, n: usize, out: &mut Vec<PosePoint>) -> Result<usize, InputError> {
        let added = self.read_source(n, out)?;
        self.next_index += added as u64;
        Ok(added)
    }

    fn read_source(&mut self, n: usize, out: &mut Vec<PosePoint>) -> Result<usize, InputError> {
        let watch = &mut self.limit_watch;
        match &mut self.source {
            Source::Grid { grid, named, next } => {
                let in_grid = grid.as_ref().map_or(0, |g| g.len());
                let total = in_grid + named.len() as u64;
                let end = (*next + n as u64).min(total);
                for i in *next..end {
                    out.push(match grid {
                        Some(g) if i < in_grid => g.point(i),
                        _ => named[(i - in_grid) as usize].clone(),
                    });
                }
                let added = (end - *next) as usize;
                *next = end;
                Ok(added)
            }
            Source::Csv { path, reader, columns, record } => {
                let mut added = 0;
                while added < n {
                    match reader.read_byte_record(record) {
                        Ok(false) => break,
                        Ok(true) => {}
                        Err(e) => {
                            let line = e.position().map_or(0, |p| p.line()) as usize;
                            return Err(InputError::At { path: path.clone(), line, column: 1, message: e.to_string() });
                        }
                    }
                    let line = record.position().map_or(0, |p| p.line()) as usize;
                    let at =
                        |column: usize, message: String| InputError::At { path: path.clone(), line, column, message };
                    // The record must be text, as a reader of string records would require (the fields read
                    // are checked one by one as well).
                    let not_text = |i: usize| at(i + 1, "this field is not UTF-8 text: save the file as UTF-8".into());
                    let Ok(whole) = std::str::from_utf8(record.as_slice()) else {
                        let bad = record.iter().position(|f| std::str::from_utf8(f).is_err());
                        return Err(not_text(bad.unwrap_or(0)));
                    };
                    // Each field a slice of the record's text, checked once above (its ends fall between
                    // characters: the separators are ASCII).
                    let text = |i: usize| -> Result<&str, InputError> {
                        match record.range(i) {
                            Some(r) => whole.get(r).map(str::trim).ok_or_else(|| not_text(i)),
                            None => Ok(""),
                        }
                    };
                    let field = |i: usize| -> Result<f64, InputError> {
                        let t = text(i)?;
                        match t.parse::<f64>() {
                            Ok(v) if v.is_finite() => Ok(v),
                            _ => Err(at(i + 1, not_finite(t))),
                        }
                    };
                    let position = match columns.xyz {
                        Some(c) => Vec3::new(field(c[0])?, field(c[1])?, field(c[2])?),
                        None => Vec3::zeros(),
                    };
                    // Sized once: collecting from a fallible iterator would start small and grow.
                    let mut joints = Vec::with_capacity(columns.joints.len());
                    for &c in &columns.joints {
                        joints.push(field(c)?);
                    }
                    if let Some(w) = watch.as_mut() {
                        if let Some(outside) = w.space.outside_limits(&joints) {
                            (w.warn)(format!("{}, line {line}: {outside}", path.display()));
                            *watch = None;
                        }
                    }
                    let rotation = match &columns.orientation {
                        Some(c) => Vec3::new(field(c[0])?, field(c[1])?, field(c[2])?),
                        None => Vec3::zeros(),
                    };
                    let wrench = match &columns.wrench {
                        Some(c) => {
                            let mut w = Vec6::zeros();
                            for k in 0..6 {
                                w[k] = field(c[k])?;
                            }
                            Some(w)
                        }
                        None => None,
                    };
                    let name = columns.name.map(|i| text(i).map(str::to_string)).transpose()?;
                    out.push(PosePoint { name, position, rotation, wrench, joints });
                    added += 1;
                }
                Ok(added)
            }
        }
    }
}

/// Points read at a time while skipping to a shard's portion.
const SKIP_BLOCK: usize = 4096;

/// Points along the straight line from `from` to `to` (mm), `count` of them, unnamed (a name is the
/// user's: a path's rows are told apart by their index, and its picture is the path's).
pub fn path_points(
    from: &crate::kinematics::frame::Vec3,
    to: &crate::kinematics::frame::Vec3,
    count: usize,
) -> Vec<PosePoint> {
    (0..count)
        .map(|k| {
            let a = if count > 1 { k as f64 / (count - 1) as f64 } else { 0.0 };
            PosePoint {
                name: None,
                position: from + (to - from) * a,
                rotation: crate::kinematics::frame::Vec3::zeros(),
                wrench: None,
                joints: Vec::new(),
            }
        })
        .collect()
}
