//! Measurements of a serial arm as a lab records them: per row the controller's joint coordinates
//! (`q_<joint>`, rad or mm), and either where a target on the tool was, in the instrument's frame
//! (`mx_mm,my_mm,mz_mm`, or `_m`; several targets as a `target` column or as several groups `mx1_mm ...`,
//! `mx2_mm ...`), or the tool point's displacement under the row's wrench in the base frame
//! (`dx_mm,dy_mm,dz_mm`: a differential measurement, the wrench's effect alone). Optional: the wrench at the
//! reference point (`Fx_N .. Mz_Nmm`, zero where absent), `sigma_mm`, `setup` (the instrument was moved: one
//! registration per set-up), `set` (`fit` or `check`: check rows are never fitted), `pose_id` (the row's
//! name), `gravity_x,gravity_y,gravity_z` (gravity's direction in the base frame: a base that is not level),
//! `payload_kg` with optional `payload_cx_mm,payload_cy_mm,payload_cz_mm` (a mass the tool carries at that
//! row, its centre in the tool frame: its weight joins the row's wrench). A target's orientation in the
//! instrument's frame may be given beside its position (a 6-dof probe, a rigid body of markers): a unit
//! quaternion `mqw,mqx,mqy,mqz`, roll-pitch-yaw `mroll_deg,mpitch_deg,myaw_deg` (or `_rad`; fixed axes x, y,
//! z as URDF's), or a rotation vector `mrx_rad,mry_rad,mrz_rad` (as a UR controller reports its tool), with the
//! group's suffix (`mqw1`, `mroll1_deg`, `mrx1_rad`), and its standard deviation `sigma_mrad`.
//! Every error is located.

use std::path::Path;

use crate::columns::{DISPLACEMENT, JOINT_PREFIX, ORIENTATION, POSE_ID, POSITION, SIGMA, WRENCH};
use crate::kinematics::frame::{Frame, Mat3, Vec3, Vec6};
use crate::model::error::{open_input, InputError};
use crate::platform::manipulator::Manipulator;

use super::data::{checked_number, checked_sigma};

/// The column naming a row's instrument set-up.
pub const SETUP: &str = "setup";
/// The column saying whether a row is fitted (`fit`) or held out (`check`).
pub const SET: &str = "set";
/// The column naming the row's target, where one group of measured columns holds several targets.
pub const TARGET: &str = "target";
/// Gravity's direction in the base frame at a row (any length: an accelerometer's reading).
pub const GRAVITY: [&str; 3] = ["gravity_x", "gravity_y", "gravity_z"];
/// A mass carried by the tool at a row, kg.
pub const PAYLOAD_KG: &str = "payload_kg";
/// Its centre in the tool frame, mm (the reference point where absent).
pub const PAYLOAD_CENTRE: [&str; 3] = ["payload_cx_mm", "payload_cy_mm", "payload_cz_mm"];
/// The standard deviation of a measured orientation, per axis of its rotation vector, mrad.
pub const SIGMA_MRAD: &str = "sigma_mrad";

/// What a row measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Observed {
    /// A target's position in the instrument's frame, mm.
    Position {
        /// The target (index into `PositionData::targets`).
        target: usize,
        /// The instrument set-up (index into `PositionData::setups`).
        setup: usize,
        /// Measured position, mm.
        at: Vec3,
    },
    /// A target's orientation in the instrument's frame (the rotation from the target's axes to the
    /// instrument's), measured on the same line as its position.
    Orientation {
        /// The target (index into `PositionData::targets`).
        target: usize,
        /// The instrument set-up (index into `PositionData::setups`).
        setup: usize,
        /// Measured orientation.
        at: Mat3,
    },
    /// The tool point's displacement under the row's wrench, base frame, mm.
    Displacement(Vec3),
}

impl Observed {
    /// True for an orientation (its residual in rad, not mm).
    pub fn is_orientation(&self) -> bool {
        matches!(self, Observed::Orientation { .. })
    }

    /// The target and set-up of a measurement in the instrument's frame (None for a displacement).
    pub fn target_and_setup(&self) -> Option<(usize, usize)> {
        match *self {
            Observed::Position { target, setup, .. } | Observed::Orientation { target, setup, .. } => {
                Some((target, setup))
            }
            Observed::Displacement(_) => None,
        }
    }
}

/// One measured row (a line of a file with several targets gives one row per target).
#[derive(Clone, Debug, PartialEq)]
pub struct PositionRow {
    /// Its name (`pose_id`, or the line number).
    pub name: String,
    /// Line in the file.
    pub line: usize,
    /// The controller's joint coordinates, in the arm's joint-space order; for a parallel robot its
    /// actuators' readings where the data give them (leg by leg), else empty.
    pub joints: Vec<f64>,
    /// A parallel robot's commanded pose (its actuators set where the nominal inverse kinematics puts
    /// them for it); None for a serial arm, whose configuration is `joints`.
    pub pose: Option<Frame>,
    /// The wrench at the reference point (N, N mm).
    pub wrench: Vec6,
    /// What was measured.
    pub observed: Observed,
    /// The row's standard deviation per coordinate when given: mm for a position or displacement, rad for
    /// an orientation.
    pub sigma: Option<f64>,
    /// Held out (`set` = `check`): never fitted.
    pub check: bool,
    /// Gravity's direction in the base frame at this row (an accelerometer on a base that is not level),
    /// where given; the model's otherwise.
    pub gravity: Option<Vec3>,
    /// The configuration (distinct joint coordinates or commanded poses, in order of appearance) the row was
    /// measured at.
    pub configuration: usize,
    /// A mass the tool carries at this row (kg) and its centre in the tool frame (mm), whose weight is not
    /// yet in `wrench` (`PositionData::with_payload_weights` puts it there).
    pub payload: Option<(f64, Vec3)>,
}

impl PositionRow {
    /// Where the nominal model puts the row's reference point: a parallel robot's pose (commanded, or found
    /// from its actuators' readings), a serial arm's forward kinematics at its joint coordinates.
    pub fn nominal_frame(
        &self,
        m: &Manipulator,
        state: &mut crate::platform::manipulator::ManipulatorState,
    ) -> Option<Frame> {
        self.pose.or_else(|| m.pose_at_joints(&self.joints, state))
    }
}

/// A file of measured rows.
#[derive(Clone, Debug, PartialEq)]
pub struct PositionData {
    /// The rows, in file order.
    pub rows: Vec<PositionRow>,
    /// Target names (absolute data), in order of appearance.
    pub targets: Vec<String>,
    /// Set-up names (absolute data), in order of appearance.
    pub setups: Vec<String>,
    /// Distinct configurations.
    pub configurations: usize,
    /// Columns of the file that no rule reads (an orientation, a timestamp): named in the report, so that
    /// a measurement is not taken as used when it was not.
    pub unread: Vec<String>,
    /// The columns giving orientations (named in the report where they cannot be weighed).
    pub orientation_columns: Vec<String>,
    /// Measurements of the file not used, each with its line and why (a target with an empty cell: not
    /// measured there): named in the report and counted in the JSON, never dropped silently.
    pub not_used: Vec<String>,
    /// What the reading changed, said in the report (rows without a `sigma_mm` given the file's median).
    pub notes: Vec<String>,
}

/// True when a measurement file's header names joint coordinates: it is read by `PositionData::read` with
/// the arm's joints.
pub fn is_joint_space(header: &[String]) -> bool {
    header.iter().any(|h| h.starts_with(JOINT_PREFIX))
}

/// True when a measurement file's header names positions in an instrument's frame (`mx_mm,my_mm,mz_mm` or a
/// group of them).
pub fn has_positions(header: &[String]) -> bool {
    !position_groups(header).is_empty()
}

/// One group of measured position columns: the target it names (its suffix) and the columns of x, y, z, and
/// the factor to mm.
struct Group {
    suffix: String,
    columns: [usize; 3],
    to_mm: f64,
}

fn position_groups(header: &[String]) -> Vec<Group> {
    let mut groups = Vec::new();
    for (k, h) in header.iter().enumerate() {
        let Some(rest) = h.strip_prefix("mx") else { continue };
        for (unit, to_mm) in [("_mm", 1.0), ("_m", 1000.0)] {
            let Some(suffix) = rest.strip_suffix(unit) else { continue };
            let find = |axis: &str| header.iter().position(|c| *c == format!("m{axis}{suffix}{unit}"));
            if let (Some(y), Some(z)) = (find("y"), find("z")) {
                groups.push(Group { suffix: suffix.to_string(), columns: [k, y, z], to_mm });
            }
        }
    }
    groups
}

/// How a group's orientation is written.
enum OrientationColumns {
    /// A unit quaternion: the columns of w, x, y, z.
    Quaternion([usize; 4]),
    /// Roll, pitch, yaw about fixed x, y, z, and the factor to radians.
    RollPitchYaw([usize; 3], f64),
    /// A rotation vector (axis times angle), rad.
    RotationVector([usize; 3]),
}

/// The orientation columns of the position group with `suffix`, if it has them.
fn orientation_columns(header: &[String], suffix: &str) -> Option<OrientationColumns> {
    let find = |name: String| header.iter().position(|c| *c == name);
    let quaternion: Option<Vec<usize>> = ["w", "x", "y", "z"].iter().map(|a| find(format!("mq{a}{suffix}"))).collect();
    if let Some(q) = quaternion {
        return Some(OrientationColumns::Quaternion([q[0], q[1], q[2], q[3]]));
    }
    for (unit, to_rad) in [("_rad", 1.0), ("_deg", std::f64::consts::PI / 180.0)] {
        let angles: Option<Vec<usize>> =
            ["roll", "pitch", "yaw"].iter().map(|a| find(format!("m{a}{suffix}{unit}"))).collect();
        if let Some(a) = angles {
            return Some(OrientationColumns::RollPitchYaw([a[0], a[1], a[2]], to_rad));
        }
    }
    let vector: Option<Vec<usize>> = ["x", "y", "z"].iter().map(|a| find(format!("mr{a}{suffix}_rad"))).collect();
    vector.map(|v| OrientationColumns::RotationVector([v[0], v[1], v[2]]))
}

impl OrientationColumns {
    fn columns(&self) -> Vec<usize> {
        match self {
            OrientationColumns::Quaternion(c) => c.to_vec(),
            OrientationColumns::RollPitchYaw(c, _) | OrientationColumns::RotationVector(c) => c.to_vec(),
        }
    }

    /// The rotation a row's cells give, or why they give none.
    fn rotation(&self, value: impl Fn(usize) -> Result<f64, InputError>) -> Result<Result<Mat3, String>, InputError> {
        Ok(match self {
            OrientationColumns::Quaternion(c) => {
                let q = [value(c[0])?, value(c[1])?, value(c[2])?, value(c[3])?];
                let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
                // A recorded quaternion is unit to its printed digits; one far from it is not a rotation.
                if (norm - 1.0).abs() > 1e-3 {
                    Err(format!("the quaternion (mqw,mqx,mqy,mqz) has length {norm}, not 1"))
                } else {
                    let unit =
                        nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]));
                    Ok(unit.to_rotation_matrix().into_inner())
                }
            }
            OrientationColumns::RollPitchYaw(c, to_rad) => {
                let a = [value(c[0])?, value(c[1])?, value(c[2])?].map(|v| v * to_rad);
                Ok(crate::model::urdf::rpy_matrix(a[0], a[1], a[2]))
            }
            OrientationColumns::RotationVector(c) => {
                Ok(crate::kinematics::frame::rotation_from_vector(&Vec3::new(value(c[0])?, value(c[1])?, value(c[2])?)))
            }
        })
    }
}

/// Errors located in the file being read.
struct Located<'p>(&'p Path);

impl Located<'_> {
    fn at(&self, line: usize, column: usize, message: String) -> InputError {
        InputError::At { path: self.0.to_path_buf(), line, column, message }
    }
}

/// Where each kind of column is in a measurement file's header, read once and checked: what the rows give
/// (joints or a commanded pose), what they measured (positions in groups, with orientations, or
/// displacements), and the optional columns.
struct Columns {
    header: Vec<String>,
    joints: Vec<usize>,
    /// A commanded pose's position and rotation vector (the rotation's optional).
    pose: Option<Vec<Option<usize>>>,
    groups: Vec<Group>,
    orientations: Vec<Option<OrientationColumns>>,
    displacement: Option<Vec<usize>>,
    wrench: Vec<Option<usize>>,
    sigma: Option<usize>,
    sigma_mrad: Option<usize>,
    setup: Option<usize>,
    set: Option<usize>,
    id: Option<usize>,
    target: Option<usize>,
    gravity: Option<Vec<usize>>,
    payload: Option<usize>,
    centre: Vec<Option<usize>>,
}

/// One line's values, which every row of the line shares.
struct LineValues {
    joints: Vec<f64>,
    /// A commanded pose's six numbers.
    commanded: Option<Vec<f64>>,
    pose: Option<Frame>,
    wrench: Vec6,
    sigma: Option<f64>,
    sigma_rad: Option<f64>,
    check: bool,
    gravity: Option<Vec3>,
    payload: Option<(f64, Vec3)>,
}

impl Columns {
    /// The columns of `header`: `joints` the names of the `q_<name>` columns, `poses` whether each row gives
    /// a commanded pose.
    fn of(header: Vec<String>, joints: &[String], poses: bool, at: &Located) -> Result<Columns, InputError> {
        // A repeated column would count its rows twice (and shrink every standard error by sqrt(2)).
        for (k, h) in header.iter().enumerate() {
            if let Some(first) = header[..k].iter().position(|f| f == h).filter(|_| !h.is_empty()) {
                return Err(at.at(
                    1,
                    k + 1,
                    format!("the column `{h}` is given twice (columns {} and {}): keep one", first + 1, k + 1),
                ));
            }
        }
        let find = |name: &str| header.iter().position(|h| h == name);
        let joint_columns = joint_columns(&header, joints, poses, at)?;
        let pose = pose_columns(&header, poses, at)?;
        let groups = position_groups(&header);
        for (k, g) in groups.iter().enumerate() {
            if let Some(first) = groups[..k].iter().find(|f| f.suffix == g.suffix) {
                return Err(at.at(
                    1,
                    g.columns[0] + 1,
                    format!(
                        "`{}` and `{}` give the same target's position (in mm and in m): keep one",
                        header[first.columns[0]], header[g.columns[0]]
                    ),
                ));
            }
        }
        let displacement: Option<Vec<usize>> = DISPLACEMENT[..3].iter().map(|c| find(c)).collect();
        if groups.is_empty() && displacement.is_none() {
            return Err(at.at(
                1,
                1,
                "no measured columns: give the target's position in the instrument's frame (mx_mm,my_mm,mz_mm or mx_m,my_m,mz_m; several targets mx1_mm,... or a `target` column) or the displacement under the row's wrench (dx_mm,dy_mm,dz_mm)".into(),
            ));
        }
        if !groups.is_empty() && displacement.is_some() {
            return Err(at.at(
                1,
                1,
                "both positions (mx...) and displacements (dx_mm...): one file holds one kind of measurement".into(),
            ));
        }
        let target = find(TARGET);
        if target.is_some() && groups.len() > 1 {
            return Err(at.at(
                1,
                1,
                "a `target` column names the target of one group of mx/my/mz columns, not of several".into(),
            ));
        }
        let payload = find(PAYLOAD_KG);
        let centre: Vec<Option<usize>> = PAYLOAD_CENTRE.iter().map(|c| find(c)).collect();
        if payload.is_none() && centre.iter().any(Option::is_some) {
            return Err(at.at(
                1,
                1,
                format!("a payload's centre ({}) needs its mass ({PAYLOAD_KG})", PAYLOAD_CENTRE.join(",")),
            ));
        }
        let orientations = groups.iter().map(|g| orientation_columns(&header, &g.suffix)).collect();
        Ok(Columns {
            joints: joint_columns,
            pose,
            groups,
            orientations,
            displacement,
            wrench: WRENCH.iter().map(|c| find(c)).collect(),
            sigma: find(SIGMA),
            sigma_mrad: find(SIGMA_MRAD),
            setup: find(SETUP),
            set: find(SET),
            id: find(POSE_ID),
            target,
            gravity: GRAVITY.iter().map(|c| find(c)).collect(),
            payload,
            centre,
            header,
        })
    }

    /// The header's columns no rule reads.
    fn unread(&self) -> Vec<String> {
        let mut read: Vec<usize> = self.joints.clone();
        read.extend(self.pose.iter().flatten().flatten());
        read.extend(self.groups.iter().flat_map(|g| g.columns));
        read.extend(self.orientations.iter().flatten().flat_map(OrientationColumns::columns));
        read.extend(self.sigma_mrad.iter().filter(|_| self.orientations.iter().any(Option::is_some)));
        read.extend(self.displacement.iter().flatten());
        read.extend(self.wrench.iter().flatten());
        read.extend([self.sigma, self.setup, self.set, self.id, self.target, self.payload].iter().flatten());
        read.extend(self.gravity.iter().flatten());
        read.extend(self.centre.iter().flatten());
        (0..self.header.len()).filter(|c| !read.contains(c)).map(|c| self.header[c].clone()).collect()
    }

    /// The names of the orientation columns read.
    fn orientation_names(&self) -> Vec<String> {
        self.orientations
            .iter()
            .flatten()
            .flat_map(OrientationColumns::columns)
            .map(|c| self.header[c].clone())
            .collect()
    }

    /// Column `c` of `record` (at `line`) as a number, its error located.
    fn number(&self, record: &csv::StringRecord, line: usize, c: usize, at: &Located) -> Result<f64, InputError> {
        checked_number(record.get(c).unwrap_or(""), &self.header[c]).map_err(|e| at.at(line, c + 1, e))
    }

    /// The values of `record` (at `line`) every row of its line shares.
    fn line(&self, record: &csv::StringRecord, line: usize, at: &Located) -> Result<LineValues, InputError> {
        let text = |c: usize| record.get(c).unwrap_or("");
        let number = |c: usize| self.number(record, line, c, at);
        let joints: Vec<f64> = self.joints.iter().map(|&c| number(c)).collect::<Result<_, _>>()?;
        let commanded: Option<Vec<f64>> = self
            .pose
            .as_ref()
            .map(|columns| columns.iter().map(|c| c.map_or(Ok(0.0), number)).collect::<Result<_, _>>())
            .transpose()?;
        let pose = commanded
            .as_ref()
            .map(|v| Frame::from_position_rotvec(Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5])));
        let mut wrench = Vec6::zeros();
        for (k, c) in self.wrench.iter().enumerate() {
            if let Some(c) = *c {
                wrench[k] = if text(c).is_empty() { 0.0 } else { number(c)? };
            }
        }
        let sigma = match self.sigma {
            Some(c) if !text(c).is_empty() => Some(checked_sigma(number(c)?).map_err(|e| at.at(line, c + 1, e))?),
            _ => None,
        };
        let sigma_rad = match self.sigma_mrad {
            Some(c) if !text(c).is_empty() => {
                let s = number(c)?;
                if !(s > 0.0 && s.is_finite()) {
                    return Err(at.at(line, c + 1, format!("{SIGMA_MRAD} is a standard deviation: > 0, not {s}")));
                }
                Some(s * 1e-3)
            }
            _ => None,
        };
        let check = match self.set.map(text) {
            None | Some("") | Some("fit") => false,
            Some("check") => true,
            Some(other) => {
                return Err(at.at(line, self.set.unwrap_or(0) + 1, format!("set is `fit` or `check`, not `{other}`")))
            }
        };
        let gravity = match &self.gravity {
            Some(g) => {
                let v = Vec3::new(number(g[0])?, number(g[1])?, number(g[2])?);
                if v.norm() == 0.0 {
                    return Err(at.at(
                        line,
                        g[0] + 1,
                        "the gravity direction (gravity_x,gravity_y,gravity_z) is zero".into(),
                    ));
                }
                Some(v.normalize())
            }
            None => None,
        };
        let payload = match self.payload {
            Some(c) if !text(c).is_empty() => {
                let kg = number(c)?;
                if kg < 0.0 {
                    return Err(at.at(line, c + 1, format!("{PAYLOAD_KG} is a mass: >= 0, not {kg}")));
                }
                let mut centre = Vec3::zeros();
                for (k, column) in self.centre.iter().enumerate() {
                    if let Some(column) = *column {
                        centre[k] = if text(column).is_empty() { 0.0 } else { number(column)? };
                    }
                }
                (kg > 0.0).then_some((kg, centre))
            }
            _ => None,
        };
        Ok(LineValues { joints, commanded, pose, wrench, sigma, sigma_rad, check, gravity, payload })
    }

    /// The rows of `record`'s line (a displacement; or a position, and its orientation where given, per
    /// target seen), each named (`pose_id`, else its number), with its configuration, set-up and target
    /// labels numbered in the order first met.
    fn push_rows(
        &self,
        record: &csv::StringRecord,
        line: usize,
        values: LineValues,
        at: &Located,
        data: &mut PositionData,
        configurations: &mut Vec<Vec<f64>>,
    ) -> Result<(), InputError> {
        let text = |c: usize| record.get(c).unwrap_or("");
        let number = |c: usize| self.number(record, line, c, at);
        let name = self
            .id
            .map(text)
            .filter(|t| !t.is_empty())
            .map_or_else(|| format!("row {}", data.rows.len() + 1), String::from);
        let LineValues { joints, commanded, pose, wrench, sigma, sigma_rad, check, gravity, payload } = values;
        let identity = commanded.unwrap_or_else(|| joints.clone());
        let configuration = match configurations.iter().position(|c| *c == identity) {
            Some(k) => k,
            None => {
                configurations.push(identity);
                configurations.len() - 1
            }
        };
        let row = |observed: Observed| PositionRow {
            name: name.clone(),
            line,
            joints: joints.clone(),
            pose,
            wrench,
            observed,
            sigma: match observed {
                Observed::Orientation { .. } => sigma_rad,
                _ => sigma,
            },
            check,
            gravity,
            configuration,
            payload,
        };
        if let Some(d) = &self.displacement {
            data.rows.push(row(Observed::Displacement(Vec3::new(number(d[0])?, number(d[1])?, number(d[2])?))));
            return Ok(());
        }
        let setup_name = self.setup.map(text).unwrap_or("").to_string();
        let setup = index_of(&mut data.setups, setup_name);
        for (g, orientation) in self.groups.iter().zip(&self.orientations) {
            // A group with an empty cell is a target not seen at that row: said, not dropped silently.
            if let Some(&c) = g.columns.iter().find(|&&c| text(c).is_empty()) {
                let target = match self.target {
                    Some(t) if !text(t).is_empty() => format!("target `{}`", text(t)),
                    _ if g.suffix.is_empty() => "the target".to_string(),
                    _ => format!("target `{}`", g.suffix),
                };
                data.not_used.push(format!(
                    "line {line} ({name}): {target} not measured there (an empty `{}` cell)",
                    self.header[c]
                ));
                continue;
            }
            let target_name = match self.target {
                Some(c) => text(c).to_string(),
                None => g.suffix.clone(),
            };
            let target = index_of(&mut data.targets, target_name);
            let v = [number(g.columns[0])?, number(g.columns[1])?, number(g.columns[2])?];
            data.rows.push(row(Observed::Position { target, setup, at: Vec3::new(v[0], v[1], v[2]) * g.to_mm }));
            // Its orientation, where this row gives one (empty cells: not seen).
            let Some(o) = orientation else { continue };
            let columns = o.columns();
            if columns.iter().any(|&c| text(c).is_empty()) {
                continue;
            }
            match o.rotation(number)? {
                Ok(turn) => data.rows.push(row(Observed::Orientation { target, setup, at: turn })),
                Err(why) => return Err(at.at(line, columns[0] + 1, why)),
            }
        }
        Ok(())
    }
}

/// The joint columns, in the order of `joints`: a serial arm's, every one; at commanded poses the actuators'
/// readings, all or none.
fn joint_columns(header: &[String], joints: &[String], poses: bool, at: &Located) -> Result<Vec<usize>, InputError> {
    let given: Vec<String> = header.iter().filter_map(|h| h.strip_prefix(JOINT_PREFIX)).map(String::from).collect();
    // At commanded poses the actuators' readings are optional: without them the rows read no joints.
    let joints: &[String] = if poses && given.is_empty() { &[] } else { joints };
    if joints.is_empty() && !given.is_empty() {
        return Err(at.at(
            1,
            1,
            format!(
                "joint coordinates ({JOINT_PREFIX}{}) are a serial arm's; a parallel robot's rows give the commanded pose ({})",
                given[0],
                POSITION.join(",")
            ),
        ));
    }
    let missing: Vec<&String> = joints.iter().filter(|j| !given.contains(j)).collect();
    let extra: Vec<&String> = given.iter().filter(|g| !joints.contains(g)).collect();
    if !missing.is_empty() || !extra.is_empty() {
        let list = |v: &[&String]| {
            if v.is_empty() {
                "none".to_string()
            } else {
                v.iter().map(|n| format!("{JOINT_PREFIX}{n}")).collect::<Vec<_>>().join(", ")
            }
        };
        return Err(at.at(
            1,
            1,
            match poses {
                false => format!(
                    "the joint columns must be {JOINT_PREFIX} and each of the arm's joints ({}): missing {}; not joints of the arm {}",
                    joints.join(", "),
                    list(&missing),
                    list(&extra)
                ),
                true => format!(
                    "the actuators' readings are {JOINT_PREFIX} and the number of each leg with one actuator ({}), all of them or none: missing {}; not such legs {}",
                    joints.join(", "),
                    list(&missing),
                    list(&extra)
                ),
            },
        ));
    }
    Ok(joints
        .iter()
        .map(|j| header.iter().position(|h| *h == format!("{JOINT_PREFIX}{j}")).expect("checked"))
        .collect())
}

/// A parallel robot's rows are commanded poses: the position's columns, and the orientation's where given
/// (all three or none). None where the rows give joints.
fn pose_columns(header: &[String], poses: bool, at: &Located) -> Result<Option<Vec<Option<usize>>>, InputError> {
    if !poses {
        return Ok(None);
    }
    let columns: Vec<Option<usize>> =
        POSITION.iter().chain(ORIENTATION.iter()).map(|c| header.iter().position(|h| h == c)).collect();
    let missing: Vec<&str> = POSITION.iter().zip(&columns).filter(|(_, c)| c.is_none()).map(|(n, _)| *n).collect();
    if !missing.is_empty() {
        return Err(at.at(
            1,
            1,
            format!(
                "each row gives the platform's commanded pose: {} (and {} where it turns); missing {}",
                POSITION.join(","),
                ORIENTATION.join(","),
                missing.join(", ")
            ),
        ));
    }
    let turns = columns[3..].iter().filter(|c| c.is_some()).count();
    if turns != 0 && turns != 3 {
        return Err(at.at(1, 1, format!("the commanded orientation needs all of {}", ORIENTATION.join(","))));
    }
    Ok(Some(columns))
}

impl PositionData {
    /// Reads a measurement file; `joints` are a serial arm's joint names (the columns `q_<name>` must be
    /// exactly these), or empty for a parallel robot, whose rows give the commanded pose instead (`x_mm,
    /// y_mm, z_mm`, and `pose_rx_rad, pose_ry_rad, pose_rz_rad` where it turns).
    pub fn read(path: &Path, joints: &[String]) -> Result<PositionData, InputError> {
        PositionData::read_from(path, open_input(path)?, joints)
    }

    /// As `read`, from `input` (the contents of `path`, named in messages).
    pub fn read_from(path: &Path, input: impl std::io::Read, joints: &[String]) -> Result<PositionData, InputError> {
        PositionData::read_rows(path, input, joints, joints.is_empty())
    }

    /// A parallel robot's measurements from `input`: commanded poses, and where the data give them its
    /// actuators' readings, `q_<leg>` for each of `legs` (the legs by number), every one or none. A
    /// row's `joints` are then its readings, in the order of `legs`, from which the calibration finds the pose
    /// the commanded one only starts.
    pub fn read_at_poses(path: &Path, input: impl std::io::Read, legs: &[String]) -> Result<PositionData, InputError> {
        PositionData::read_rows(path, input, legs, true)
    }

    /// The reader: `joints` the names of the `q_<name>` columns (all required for a serial arm; all or none
    /// at `poses`), `poses` whether each row gives a commanded pose. The header is read once, into the
    /// columns of each kind (`Columns::of`); then each line's values (`Columns::line`) and its rows, each
    /// named and given its configuration, set-up and target (`Columns::push_rows`).
    fn read_rows(
        path: &Path,
        input: impl std::io::Read,
        joints: &[String],
        poses: bool,
    ) -> Result<PositionData, InputError> {
        let at = Located(path);
        let mut reader = csv::ReaderBuilder::new().trim(csv::Trim::All).from_reader(input);
        let header: Vec<String> =
            reader.headers().map_err(|e| at.at(1, 1, e.to_string()))?.iter().map(String::from).collect();
        let columns = Columns::of(header, joints, poses, &at)?;
        let mut data = PositionData {
            rows: Vec::new(),
            targets: Vec::new(),
            setups: Vec::new(),
            configurations: 0,
            unread: columns.unread(),
            orientation_columns: columns.orientation_names(),
            not_used: Vec::new(),
            notes: Vec::new(),
        };
        // The configurations seen so far: joint coordinates, or a commanded pose's six numbers.
        let mut configurations: Vec<Vec<f64>> = Vec::new();
        for record in reader.records() {
            let record = record.map_err(|e| at.at(e.position().map_or(0, |p| p.line() as usize), 1, e.to_string()))?;
            let line = record.position().map_or(0, |p| p.line() as usize);
            let values = columns.line(&record, line, &at)?;
            columns.push_rows(&record, line, values, &at, &mut data, &mut configurations)?;
        }
        if data.rows.is_empty() {
            return Err(InputError::Whole { path: path.to_path_buf(), message: "no measurements".into() });
        }
        data.configurations = configurations.len();
        data.fill_missing_sigmas(columns.sigma.is_some());
        Ok(data)
    }

    /// Rows whose `sigma_mm` cell is empty where others give one take the median of those given (one empty
    /// cell would otherwise leave the file without a noise level, and the test of what is left off), said
    /// in the notes with the rows' lines.
    fn fill_missing_sigmas(&mut self, has_column: bool) {
        let is_position = |r: &PositionRow| !matches!(r.observed, Observed::Orientation { .. });
        let mut given: Vec<f64> = self.rows.iter().filter(|r| is_position(r)).filter_map(|r| r.sigma).collect();
        let missing: Vec<usize> =
            self.rows.iter().filter(|r| is_position(r) && r.sigma.is_none()).map(|r| r.line).collect();
        if !has_column || given.is_empty() || missing.is_empty() {
            return;
        }
        given.sort_by(f64::total_cmp);
        let median = given[given.len() / 2];
        for r in self.rows.iter_mut().filter(|r| is_position(r) && r.sigma.is_none()) {
            r.sigma = Some(median);
        }
        let mut lines: Vec<usize> = missing;
        lines.dedup();
        let shown: Vec<String> = lines.iter().take(10).map(|l| l.to_string()).collect();
        let more = if lines.len() > 10 { format!(" and {} more", lines.len() - 10) } else { String::new() };
        self.notes.push(format!(
            "{} rows without a {SIGMA} (lines {}{more}) take the file's median sigma, {median} mm",
            lines.len(),
            shown.join(", ")
        ));
    }

    /// Holds out a fraction of the configurations (all rows measured at each), drawn with `seed`: those
    /// rows become `check` rows. Rows the file already marks stay as marked.
    pub fn hold_out(&mut self, fraction: f64, seed: u64) {
        use rand::seq::SliceRandom;
        use rand::SeedableRng;
        let mut order: Vec<usize> = (0..self.configurations).collect();
        order.shuffle(&mut rand::rngs::StdRng::seed_from_u64(seed));
        let held = &order[..((fraction * self.configurations as f64).round() as usize).min(self.configurations)];
        for r in &mut self.rows {
            r.check |= held.contains(&r.configuration);
        }
    }

    /// The data with each row's payload weighed into its wrench: the weight m g (g the row's gravity
    /// direction with `m`'s magnitude, or `m`'s gravity) at the reference point, with its moment (R c) x F
    /// about it, R the tool's orientation at the row's configuration (nominal kinematics).
    pub fn with_payload_weights(&self, m: &Manipulator) -> PositionData {
        let mut out = self.clone();
        let mut state = m.new_state();
        let g = m.weight_gravity();
        for r in &mut out.rows {
            let Some((kg, centre)) = r.payload.take() else { continue };
            let Some(frame) = r.nominal_frame(m, &mut state) else { continue };
            let force = r.gravity.map_or(g, |d| d * g.norm()) * kg;
            let moment = (frame.rot * centre).cross(&force);
            r.wrench += Vec6::new(force.x, force.y, force.z, moment.x, moment.y, moment.z);
        }
        out
    }

    /// True when the rows are positions in an instrument's frame (registration fitted), false when they are
    /// displacements in the base frame.
    pub fn absolute(&self) -> bool {
        !matches!(self.rows[0].observed, Observed::Displacement(_))
    }

    /// The data without the orientations that have no standard deviation (no `sigma_mrad` cell and no
    /// `sigma_rad` given): an angle cannot be weighed against a length without one. Their columns are named
    /// among the unread ones, saying what to give.
    pub fn without_unweighted_orientations(&self, sigma_rad: Option<f64>) -> std::borrow::Cow<'_, PositionData> {
        let unweighted = |r: &PositionRow| r.observed.is_orientation() && r.sigma.or(sigma_rad).is_none();
        if !self.rows.iter().any(unweighted) {
            return std::borrow::Cow::Borrowed(self);
        }
        let mut out = self.clone();
        out.rows.retain(|r| !unweighted(r));
        out.unread.push(format!(
            "{} (orientations without a standard deviation: give a {SIGMA_MRAD} column or --sigma-mrad)",
            self.orientation_columns.join(", ")
        ));
        std::borrow::Cow::Owned(out)
    }
}

fn index_of(names: &mut Vec<String>, name: String) -> usize {
    match names.iter().position(|n| *n == name) {
        Some(k) => k,
        None => {
            names.push(name);
            names.len() - 1
        }
    }
}

/// The column `stiff synth` adds to its joint-space data: 1 on the rows it made gross (for a test to check
/// the calibration's verdicts; the calibration does not read it).
pub const HIDDEN_GROSS: &str = "hidden_gross";

/// One measured configuration as `stiff synth` writes it, in the format `PositionData::read` reads: the
/// controller's angles, the wrench where the file has one, the target's position (and orientation, as a
/// unit quaternion) in the instrument's frame, the set and the set-up.
pub struct MeasuredRow<'a> {
    /// The row's name (`pose_id`).
    pub name: &'a str,
    /// The controller's angles, in the arm's order (empty for a parallel robot).
    pub joints: &'a [f64],
    /// A parallel robot's commanded pose (None for a serial arm).
    pub pose: Option<&'a Frame>,
    /// The wrench at the reference point.
    pub wrench: &'a Vec6,
    /// The target's position in the instrument's frame, mm.
    pub at: &'a Vec3,
    /// Its orientation there, where measured.
    pub orientation: Option<&'a Mat3>,
    /// Held out (`set` = check).
    pub check: bool,
    /// The set-up (0-based; written `s1`, `s2`, ...).
    pub setup: usize,
    /// Made gross.
    pub gross: bool,
}

/// What fixes a measurement file's columns.
pub struct MeasuredLayout {
    /// The arm's joints, in its order (empty for a parallel robot, whose rows give commanded poses).
    pub joints: Vec<String>,
    /// The rows carry wrenches.
    pub loaded: bool,
    /// The positions' standard deviation written, mm.
    pub sigma_mm: f64,
    /// The orientations' standard deviation written (mrad), where orientations are measured.
    pub sigma_mrad: Option<f64>,
    /// The instrument was moved: a `setup` column.
    pub setups: bool,
}

impl crate::output::table::Row for MeasuredRow<'_> {
    type Layout = MeasuredLayout;

    fn record(&self, l: &MeasuredLayout, r: &mut impl crate::output::table::Record) {
        r.text(POSE_ID, self.name);
        for (name, q) in l.joints.iter().zip(self.joints) {
            r.number(format_args!("{JOINT_PREFIX}{name}"), *q);
        }
        if l.joints.is_empty() {
            let pose = self.pose.copied().unwrap_or_else(|| Frame::translation(Vec3::zeros()));
            let turn = crate::kinematics::frame::rotation_vector(&pose.rot);
            for (k, name) in POSITION.iter().enumerate() {
                r.number(name, pose.pos[k]);
            }
            for (k, name) in ORIENTATION.iter().enumerate() {
                r.number(name, turn[k]);
            }
        }
        if l.loaded {
            r.six(WRENCH, Some(self.wrench));
        }
        for (k, name) in ["mx_mm", "my_mm", "mz_mm"].iter().enumerate() {
            r.number(name, self.at[k]);
        }
        r.number(SIGMA, l.sigma_mm);
        if let Some(sigma) = l.sigma_mrad {
            let q = self.orientation.map(nalgebra::UnitQuaternion::from_matrix);
            for (k, name) in ["mqw", "mqx", "mqy", "mqz"].iter().enumerate() {
                r.optional(name, q.map(|q| [q.w, q.i, q.j, q.k][k]));
            }
            r.number(SIGMA_MRAD, sigma);
        }
        r.text(SET, if self.check { "check" } else { "fit" });
        if l.setups {
            r.text(SETUP, &format!("s{}", self.setup + 1));
        }
        r.count(HIDDEN_GROSS, Some(u64::from(self.gross)));
    }
}
