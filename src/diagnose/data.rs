//! Measured deflections (CSV): `pose_id,x_mm,y_mm,z_mm,Fx_N,Fy_N,Fz_N,Mx_Nmm,My_Nmm,Mz_Nmm,dx_mm,dy_mm,dz_mm`,
//! optionally `sigma_mm` and `order` (or `time`, for the drift effect), any order, extra columns (measured rotations among them) ignored: the measurement
//! model predicts the measured point's translation only. Every error is located.

use std::path::Path;

use crate::kinematics::frame::{Vec3, Vec6};
use crate::model::error::{open_input, InputError};
use crate::output::table::names;

/// The columns a measurement file must have, in the order `stiff synth` writes them.
pub const REQUIRED: [&str; 13] = {
    let (p, w, d) = (names::POSITION, names::WRENCH, names::DISPLACEMENT);
    [names::POSE_ID, p[0], p[1], p[2], w[0], w[1], w[2], w[3], w[4], w[5], d[0], d[1], d[2]]
};

/// Largest magnitude a measured number may have (mm, N, N mm): residuals are squared and weighted, and
/// 1e100 squared is still far from overflowing.
pub const MAX_MAGNITUDE: f64 = 1e100;
/// Smallest measurement standard deviation accepted, mm (a picometre: below any instrument; a smaller one
/// makes weights whose squares overflow).
pub const MIN_SIGMA_MM: f64 = 1e-9;

/// A measured number read from `text` in `column`, or why it is not one: finite and within
/// `MAX_MAGNITUDE` (residuals are squared and weighted: a value beyond 1e100 overflows there, and is no
/// measurement of a robot in mm, N or N mm).
pub fn checked_number(text: &str, column: &str) -> Result<f64, String> {
    let v: f64 = text.parse().map_err(|_| format!("`{text}` in column `{column}` is not a number"))?;
    if !v.is_finite() {
        return Err(format!("column `{column}`: {}", crate::model::error::not_finite(text)));
    }
    if v.abs() > MAX_MAGNITUDE {
        return Err(format!("column `{column}`: {text} is beyond {MAX_MAGNITUDE:e}, not a measurement"));
    }
    Ok(v)
}

/// A row's `sigma_mm`, or why it is not one.
pub fn checked_sigma(s: f64) -> Result<f64, String> {
    if (MIN_SIGMA_MM..=MAX_MAGNITUDE).contains(&s) {
        Ok(s)
    } else {
        Err(format!("sigma_mm must lie in [{MIN_SIGMA_MM:e}, {MAX_MAGNITUDE:e}] mm, got {s}"))
    }
}

/// One measured row: a commanded pose, the wrench applied there and the measured displacement.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Measurement {
    /// The id grouping rows of one pose.
    pub pose_id: String,
    /// Commanded reference point, mm.
    pub position: Vec3,
    /// Applied wrench at the reference point, N and N mm.
    pub wrench: Vec6,
    /// Measured minus commanded position of the reference point, mm.
    pub displacement: Vec3,
    /// The row's standard deviation, mm (the `sigma_mm` column), when given.
    pub sigma: Option<f64>,
    /// Where the row comes in the order of measurement (the `order` or `time` column), when given.
    pub order: Option<f64>,
    /// Line in the file (for messages).
    pub line: usize,
}

/// The rows of one pose.
#[derive(Clone, Debug, PartialEq)]
pub struct Pose {
    /// The pose's id.
    pub id: String,
    /// Its commanded reference point, mm.
    pub position: Vec3,
    /// Its rows in the dataset.
    pub rows: Vec<usize>,
}

/// A measurement file: its rows, and the poses they group into.
#[derive(Clone, Debug, PartialEq)]
pub struct Dataset {
    /// The rows, in file order.
    pub rows: Vec<Measurement>,
    /// The poses, in order of first appearance.
    pub poses: Vec<Pose>,
}

impl Dataset {
    /// Reads and checks a measurement CSV (columns by name, every number finite and bounded).
    pub fn read(path: &Path) -> Result<Dataset, InputError> {
        Dataset::read_from(path, open_input(path)?)
    }

    /// As `read`, from `input` (the contents of `path`, named in messages).
    pub fn read_from(path: &Path, input: impl std::io::Read) -> Result<Dataset, InputError> {
        let at = |line: usize, column: usize, message: String| InputError::At {
            path: path.to_path_buf(),
            line,
            column,
            message,
        };
        let mut reader = csv::ReaderBuilder::new().trim(csv::Trim::All).from_reader(input);
        let header = reader.headers().map_err(|e| at(1, 1, e.to_string()))?.clone();
        let find = |name: &str| header.iter().position(|h| h == name);
        let mut columns = Vec::with_capacity(REQUIRED.len());
        for name in REQUIRED {
            columns.push(
                find(name)
                    .ok_or_else(|| at(1, 1, format!("missing column `{name}` (needs {})", REQUIRED.join(","))))?,
            );
        }
        let sigma_column = find(names::SIGMA);
        let order_column = find(names::ORDER).or_else(|| find("time"));
        let mut data = Dataset { rows: Vec::new(), poses: Vec::new() };
        for record in reader.records() {
            let record = record.map_err(|e| at(e.position().map_or(0, |p| p.line() as usize), 1, e.to_string()))?;
            let line = record.position().map_or(0, |p| p.line() as usize);
            let number = |c: usize| -> Result<f64, InputError> {
                checked_number(record.get(c).unwrap_or(""), &header[c]).map_err(|e| at(line, c + 1, e))
            };
            let v: Vec<f64> = columns[1..].iter().map(|&c| number(c)).collect::<Result<_, _>>()?;
            let sigma = match sigma_column {
                Some(c) if !record.get(c).unwrap_or("").is_empty() => {
                    Some(checked_sigma(number(c)?).map_err(|e| at(line, c + 1, e))?)
                }
                _ => None,
            };
            let order = match order_column {
                Some(c) if !record.get(c).unwrap_or("").is_empty() => Some(number(c)?),
                _ => None,
            };
            let id = record.get(columns[0]).unwrap_or("").to_string();
            if id.is_empty() {
                return Err(at(line, columns[0] + 1, "empty pose_id".into()));
            }
            let position = Vec3::new(v[0], v[1], v[2]);
            let index = data.rows.len();
            match data.poses.iter_mut().find(|p| p.id == id) {
                Some(p) => {
                    if (p.position - position).norm() > 1e-9 * (1.0 + position.norm()) {
                        return Err(at(
                            line,
                            columns[1] + 1,
                            format!("pose `{id}` was at {} before", p.position.transpose()),
                        ));
                    }
                    p.rows.push(index);
                }
                None => data.poses.push(Pose { id: id.clone(), position, rows: vec![index] }),
            }
            data.rows.push(Measurement {
                pose_id: id,
                position,
                wrench: Vec6::from_column_slice(&v[3..9]),
                displacement: Vec3::new(v[9], v[10], v[11]),
                sigma,
                order,
                line,
            });
        }
        if data.rows.is_empty() {
            return Err(InputError::Whole { path: path.to_path_buf(), message: "no measurements".into() });
        }
        Ok(data)
    }

    /// Groups of repeated rows (same pose and wrench), for the pure-error estimate of the noise.
    pub fn repeats(&self) -> Vec<Vec<usize>> {
        let mut groups: Vec<Vec<usize>> = Vec::new();
        for p in &self.poses {
            for &r in &p.rows {
                let w = self.rows[r].wrench;
                match groups.iter_mut().find(|g| {
                    self.rows[g[0]].pose_id == p.id && (self.rows[g[0]].wrench - w).norm() <= 1e-12 * (1.0 + w.norm())
                }) {
                    Some(g) => g.push(r),
                    None => groups.push(vec![r]),
                }
            }
        }
        groups.retain(|g| g.len() > 1);
        groups
    }
}
