//! Every row's residual after the calibration (`stiff diagnose --residuals FILE`): what a field user needs
//! to compute their own figures (the 95th percentile horizontally and vertically, per set-up, per day), and
//! why a row was left out.

use crate::diagnose::positions::{Observed, PositionData};
use crate::kinematics::frame::Vec3;
use crate::output::table::{Record, Row};

/// One row of the data with its residual (measured minus predicted) under the model selected.
#[derive(Clone, Debug)]
pub struct RowResidual {
    /// The row's name (`pose_id`, or its number).
    pub name: String,
    /// Its line in the file.
    pub line: usize,
    /// Its set-up's name (empty for one set-up, or a displacement).
    pub setup: String,
    /// Its target's name (empty for one target, or a displacement).
    pub target: String,
    /// `fit` or `check`.
    pub set: &'static str,
    /// `position`, `orientation` or `displacement`.
    pub observed: &'static str,
    /// A position's residual in the instrument's frame, a displacement's in the base frame (mm); None for an
    /// orientation or where the model has no prediction.
    pub error_mm: Option<Vec3>,
    /// A position's or displacement's residual in the robot base's axes (mm).
    pub base_mm: Option<Vec3>,
    /// An orientation's residual, the rotation vector from measured to predicted (mrad).
    pub turn_mrad: Option<Vec3>,
    /// Why the row is not among the fitted or held-out rows the report's figures use (empty where it is).
    pub left_out: String,
}

/// The rows of `data` with their residuals (`residuals`, and `base` in the base's axes) and each left-out
/// row's reason: `unusable` (no prediction), `gross`, or a set-up in `unplaced`.
pub(super) fn row_residuals(
    data: &PositionData,
    residuals: &[Option<Vec3>],
    base: &[Option<Vec3>],
    unusable: &[(usize, String)],
    gross: &[usize],
    unplaced: &[(usize, String)],
) -> Vec<RowResidual> {
    data.rows
        .iter()
        .enumerate()
        .map(|(r, row)| {
            let (setup, target) = row.observed.target_and_setup().map_or((None, None), |(t, s)| (Some(s), Some(t)));
            let left_out = if let Some((_, why)) = unusable.iter().find(|(k, _)| *k == r) {
                format!("no prediction: {why}")
            } else if setup.is_some_and(|s| unplaced.iter().any(|(k, _)| *k == s)) {
                "its set-up cannot be placed".to_string()
            } else if gross.contains(&r) {
                "gross".to_string()
            } else {
                String::new()
            };
            let turning = row.observed.is_orientation();
            RowResidual {
                name: row.name.clone(),
                line: row.line,
                setup: setup.map_or(String::new(), |s| data.setups[s].clone()),
                target: target.map_or(String::new(), |t| data.targets[t].clone()),
                set: if row.check { "check" } else { "fit" },
                observed: match row.observed {
                    Observed::Position { .. } => "position",
                    Observed::Orientation { .. } => "orientation",
                    Observed::Displacement(_) => "displacement",
                },
                error_mm: residuals[r].filter(|_| !turning),
                base_mm: base[r],
                turn_mrad: residuals[r].filter(|_| turning).map(|v| v * 1e3),
                left_out,
            }
        })
        .collect()
}

impl Row for RowResidual {
    type Layout = ();

    fn record(&self, _: &(), r: &mut impl Record) {
        r.text("name", &self.name);
        r.count("line", Some(self.line as u64));
        r.text("setup", &self.setup);
        r.text("target", &self.target);
        r.text("set", self.set);
        r.text("observed", self.observed);
        for (k, axis) in ["ex_mm", "ey_mm", "ez_mm"].iter().enumerate() {
            r.optional(axis, self.error_mm.map(|e| e[k]));
        }
        r.optional("e_mm", self.error_mm.map(|e| e.norm()));
        for (k, axis) in ["base_ex_mm", "base_ey_mm", "base_ez_mm"].iter().enumerate() {
            r.optional(axis, self.base_mm.map(|e| e[k]));
        }
        r.optional("base_exy_mm", self.base_mm.map(|e| e.x.hypot(e.y)));
        for (k, axis) in ["erx_mrad", "ery_mrad", "erz_mrad"].iter().enumerate() {
            r.optional(axis, self.turn_mrad.map(|e| e[k]));
        }
        r.optional("er_mrad", self.turn_mrad.map(|e| e.norm()));
        r.text("left_out", &self.left_out);
    }
}
