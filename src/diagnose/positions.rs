//! Measurements of a serial arm as a lab records them: per row the controller's joint coordinates
//! (`q_<joint>`, rad or mm), and either where a target on the tool was, in the instrument's frame
//! (`mx_mm,my_mm,mz_mm`, or `_m`; several targets as a `target` column or as several groups `mx1_mm ...`,
//! `mx2_mm ...`), or the tool point's displacement under the row's wrench in the base frame
//! (`dx_mm,dy_mm,dz_mm`: a differential measurement, the wrench's effect alone). Optional: the wrench at the
//! reference point (`Fx_N .. Mz_Nmm`, zero where absent), `sigma_mm`, `setup` (the instrument was moved: one
//! registration per set-up), `set` (`fit` or `check`: check rows are never fitted), `pose_id` (the row's
//! name), `gravity_x,gravity_y,gravity_z` (gravity's direction in the base frame: a base that is not level),
//! `payload_kg` with optional `payload_cx_mm,payload_cy_mm,payload_cz_mm` (a mass the tool carries at that
//! row, its centre in the tool frame: its weight joins the row's wrench). Every error is located.

use std::path::Path;

use crate::columns::{DISPLACEMENT, JOINT_PREFIX, POSE_ID, SIGMA, WRENCH};
use crate::kinematics::frame::{Vec3, Vec6};
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
    /// The tool point's displacement under the row's wrench, base frame, mm.
    Displacement(Vec3),
}

/// One measured row (a line of a file with several targets gives one row per target).
#[derive(Clone, Debug, PartialEq)]
pub struct PositionRow {
    /// Its name (`pose_id`, or the line number).
    pub name: String,
    /// Line in the file.
    pub line: usize,
    /// The controller's joint coordinates, in the arm's joint-space order.
    pub joints: Vec<f64>,
    /// The wrench at the reference point (N, N mm).
    pub wrench: Vec6,
    /// What was measured.
    pub observed: Observed,
    /// The row's standard deviation per coordinate, mm, when given.
    pub sigma: Option<f64>,
    /// Held out (`set` = `check`): never fitted.
    pub check: bool,
    /// Gravity's direction in the base frame at this row (an accelerometer on a base that is not level),
    /// where given; the model's otherwise.
    pub gravity: Option<Vec3>,
    /// The configuration (distinct joint coordinates, in order of appearance) the row was measured at.
    pub configuration: usize,
    /// A mass the tool carries at this row (kg) and its centre in the tool frame (mm), whose weight is not
    /// yet in `wrench` (`PositionData::with_payload_weights` puts it there).
    pub payload: Option<(f64, Vec3)>,
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
}

/// True when a measurement file's header names joint coordinates: it is read by `PositionData::read`.
pub fn is_joint_space(header: &[String]) -> bool {
    header.iter().any(|h| h.starts_with(JOINT_PREFIX))
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

impl PositionData {
    /// Reads a joint-space measurement file; `joints` are the arm's joint names (the columns `q_<name>` must
    /// be exactly these).
    pub fn read(path: &Path, joints: &[String]) -> Result<PositionData, InputError> {
        PositionData::read_from(path, open_input(path)?, joints)
    }

    /// As `read`, from `input` (the contents of `path`, named in messages).
    pub fn read_from(path: &Path, input: impl std::io::Read, joints: &[String]) -> Result<PositionData, InputError> {
        let at = |line: usize, column: usize, message: String| InputError::At {
            path: path.to_path_buf(),
            line,
            column,
            message,
        };
        let mut reader = csv::ReaderBuilder::new().trim(csv::Trim::All).from_reader(input);
        let header: Vec<String> =
            reader.headers().map_err(|e| at(1, 1, e.to_string()))?.iter().map(String::from).collect();
        let find = |name: &str| header.iter().position(|h| h == name);
        let given: Vec<String> = header.iter().filter_map(|h| h.strip_prefix(JOINT_PREFIX)).map(String::from).collect();
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
            return Err(at(
                1,
                1,
                format!(
                    "the joint columns must be {JOINT_PREFIX} and each of the arm's joints ({}): missing {}; not joints of the arm {}",
                    joints.join(", "),
                    list(&missing),
                    list(&extra)
                ),
            ));
        }
        let joint_columns: Vec<usize> =
            joints.iter().map(|j| find(&format!("{JOINT_PREFIX}{j}")).expect("checked")).collect();
        let groups = position_groups(&header);
        let displacement: Option<Vec<usize>> = DISPLACEMENT[..3].iter().map(|c| find(c)).collect();
        if groups.is_empty() && displacement.is_none() {
            return Err(at(
                1,
                1,
                "no measured columns: give the target's position in the instrument's frame (mx_mm,my_mm,mz_mm or mx_m,my_m,mz_m; several targets mx1_mm,... or a `target` column) or the displacement under the row's wrench (dx_mm,dy_mm,dz_mm)".into(),
            ));
        }
        if !groups.is_empty() && displacement.is_some() {
            return Err(at(
                1,
                1,
                "both positions (mx...) and displacements (dx_mm...): one file holds one kind of measurement".into(),
            ));
        }
        let target_column = find(TARGET);
        if target_column.is_some() && groups.len() > 1 {
            return Err(at(
                1,
                1,
                "a `target` column names the target of one group of mx/my/mz columns, not of several".into(),
            ));
        }
        let wrench_columns: Vec<Option<usize>> = WRENCH.iter().map(|c| find(c)).collect();
        let (sigma_column, setup_column, set_column, id_column) = (find(SIGMA), find(SETUP), find(SET), find(POSE_ID));
        let gravity_columns: Option<Vec<usize>> = GRAVITY.iter().map(|c| find(c)).collect();
        let payload_column = find(PAYLOAD_KG);
        let centre_columns: Vec<Option<usize>> = PAYLOAD_CENTRE.iter().map(|c| find(c)).collect();
        if payload_column.is_none() && centre_columns.iter().any(Option::is_some) {
            return Err(at(
                1,
                1,
                format!("a payload's centre ({}) needs its mass ({PAYLOAD_KG})", PAYLOAD_CENTRE.join(",")),
            ));
        }
        let mut read: Vec<usize> = joint_columns.clone();
        read.extend(groups.iter().flat_map(|g| g.columns));
        read.extend(displacement.iter().flatten());
        read.extend(wrench_columns.iter().flatten());
        read.extend(
            [sigma_column, setup_column, set_column, id_column, target_column, payload_column].iter().flatten(),
        );
        read.extend(gravity_columns.iter().flatten());
        read.extend(centre_columns.iter().flatten());
        let unread = (0..header.len()).filter(|c| !read.contains(c)).map(|c| header[c].clone()).collect();
        let mut data =
            PositionData { rows: Vec::new(), targets: Vec::new(), setups: Vec::new(), configurations: 0, unread };
        let mut configurations: Vec<Vec<f64>> = Vec::new();
        for record in reader.records() {
            let record = record.map_err(|e| at(e.position().map_or(0, |p| p.line() as usize), 1, e.to_string()))?;
            let line = record.position().map_or(0, |p| p.line() as usize);
            let text = |c: usize| record.get(c).unwrap_or("");
            let number = |c: usize| -> Result<f64, InputError> {
                checked_number(text(c), &header[c]).map_err(|e| at(line, c + 1, e))
            };
            let joints: Vec<f64> = joint_columns.iter().map(|&c| number(c)).collect::<Result<_, _>>()?;
            let mut wrench = Vec6::zeros();
            for (k, c) in wrench_columns.iter().enumerate() {
                if let Some(c) = *c {
                    wrench[k] = if text(c).is_empty() { 0.0 } else { number(c)? };
                }
            }
            let sigma = match sigma_column {
                Some(c) if !text(c).is_empty() => Some(checked_sigma(number(c)?).map_err(|e| at(line, c + 1, e))?),
                _ => None,
            };
            let check = match set_column.map(text) {
                None | Some("") | Some("fit") => false,
                Some("check") => true,
                Some(other) => {
                    return Err(at(
                        line,
                        set_column.unwrap_or(0) + 1,
                        format!("set is `fit` or `check`, not `{other}`"),
                    ))
                }
            };
            let gravity = match &gravity_columns {
                Some(g) => {
                    let v = Vec3::new(number(g[0])?, number(g[1])?, number(g[2])?);
                    if v.norm() == 0.0 {
                        return Err(at(
                            line,
                            g[0] + 1,
                            "the gravity direction (gravity_x,gravity_y,gravity_z) is zero".into(),
                        ));
                    }
                    Some(v.normalize())
                }
                None => None,
            };
            let payload = match payload_column {
                Some(c) if !text(c).is_empty() => {
                    let kg = number(c)?;
                    if kg < 0.0 {
                        return Err(at(line, c + 1, format!("{PAYLOAD_KG} is a mass: >= 0, not {kg}")));
                    }
                    let mut centre = Vec3::zeros();
                    for (k, column) in centre_columns.iter().enumerate() {
                        if let Some(column) = *column {
                            centre[k] = if text(column).is_empty() { 0.0 } else { number(column)? };
                        }
                    }
                    (kg > 0.0).then_some((kg, centre))
                }
                _ => None,
            };
            let name = id_column
                .map(text)
                .filter(|t| !t.is_empty())
                .map_or_else(|| format!("row {}", data.rows.len() + 1), String::from);
            let configuration = match configurations.iter().position(|c| *c == joints) {
                Some(k) => k,
                None => {
                    configurations.push(joints.clone());
                    configurations.len() - 1
                }
            };
            let mut push = |observed: Observed| {
                data.rows.push(PositionRow {
                    name: name.clone(),
                    line,
                    joints: joints.clone(),
                    wrench,
                    observed,
                    sigma,
                    check,
                    gravity,
                    configuration,
                    payload,
                })
            };
            if let Some(d) = &displacement {
                push(Observed::Displacement(Vec3::new(number(d[0])?, number(d[1])?, number(d[2])?)));
                continue;
            }
            let setup_name = setup_column.map(text).unwrap_or("").to_string();
            let setup = index_of(&mut data.setups, setup_name);
            for g in &groups {
                // A group with an empty cell is a target not seen at that row.
                if g.columns.iter().any(|&c| text(c).is_empty()) {
                    continue;
                }
                let target_name = match target_column {
                    Some(c) => text(c).to_string(),
                    None => g.suffix.clone(),
                };
                let target = index_of(&mut data.targets, target_name);
                let v = [number(g.columns[0])?, number(g.columns[1])?, number(g.columns[2])?];
                push(Observed::Position { target, setup, at: Vec3::new(v[0], v[1], v[2]) * g.to_mm });
            }
        }
        if data.rows.is_empty() {
            return Err(InputError::Whole { path: path.to_path_buf(), message: "no measurements".into() });
        }
        data.configurations = configurations.len();
        Ok(data)
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
            let Some(frame) = m.pose_at_joints(&r.joints, &mut state) else { continue };
            let force = r.gravity.map_or(g, |d| d * g.norm()) * kg;
            let moment = (frame.rot * centre).cross(&force);
            r.wrench += Vec6::new(force.x, force.y, force.z, moment.x, moment.y, moment.z);
        }
        out
    }

    /// True when the rows are positions in an instrument's frame (registration fitted), false when they are
    /// displacements in the base frame.
    pub fn absolute(&self) -> bool {
        matches!(self.rows[0].observed, Observed::Position { .. })
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
