//! The calibration's options, its result beside its report, and its failures.

use super::effect::ArmEffect;
use crate::model::effect::Effect;
use crate::output::calibration::CalibrationReport;

/// CalibrationOptions of a calibration.
#[derive(Clone, Debug)]
pub struct CalibrationOptions {
    /// Significance level of the selection (each step tests at alpha / candidates).
    pub alpha: f64,
    /// Standard deviation of a measured coordinate, mm, where the rows do not give one.
    pub sigma: Option<f64>,
    /// Standard deviation of a measured orientation about each axis, rad, where the rows do not give one.
    pub sigma_rad: Option<f64>,
    /// Effects always fitted (a fixed list, as a geometric calibration fits its parameters).
    pub fitted: Vec<ArmEffect>,
    /// Most effects selected.
    pub max_effects: usize,
}

/// A calibration's outcome: its report (what `--json` writes and the text reports) beside the effects
/// accepted, typed, in the report's order, which the corrected description is written from.
#[derive(Clone, Debug)]
pub struct Calibration {
    /// What the calibration found, as written.
    pub report: CalibrationReport,
    /// The effects of `report.accepted`, in its order.
    pub effects: Vec<ArmEffect>,
    /// A parallel robot's accepted effects as the model-form effects a description holds (`model_form`; None
    /// for one it holds not), in the order of `effects`; None for a serial arm.
    pub leg_corrections: Option<Vec<Option<Effect>>>,
    /// Every row of the data with its residual under the model selected (`--residuals`).
    pub rows: Vec<super::residuals::RowResidual>,
}

/// The failures of a calibration.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationError {
    /// The model is not a serial arm with a joint space.
    #[error("{0} is not a serial arm read from URDF: joint-space measurements need one")]
    NotAnArm(String),
    /// A row's configuration has no finite pose or no loaded equilibrium.
    #[error("{name} (line {line}): {why}")]
    Row {
        /// The row's name.
        name: String,
        /// Its line.
        line: usize,
        /// What failed.
        why: String,
    },
    /// Too few rows to fit what must be fitted.
    #[error("{0}")]
    TooFew(String),
    /// An effect named that the robot cannot have here.
    #[error("{0}")]
    NotOffered(String),
}
