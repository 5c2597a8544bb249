//! The calibration's options, its result beside its report, and its failures.

use super::effect::ArmEffect;
use crate::model::effect::Effect;
use crate::output::calibration::CalibrationReport;
use crate::platform::manipulator::Manipulator;

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
    /// The description read again with the corrections appended (the text `corrected_tables` writes, the
    /// same `--model-out` writes): a serial arm's fit is then the least-squares fit of that model's loaded
    /// equilibrium (`PositionProblem::exact_misses`). None: its effects stay first order about the loaded
    /// equilibrium of the model as it is.
    pub rebuild: Option<Rebuild>,
    /// Where the calibration says how far it is (each fit counted, each selection step named); None: silent.
    pub progress: Option<indicatif::ProgressBar>,
}

/// Builds the manipulator of the description with some text appended (`CalibrationOptions::rebuild`), or says
/// why it cannot (a compliance that the corrections would make negative).
#[derive(Clone)]
pub struct Rebuild(pub std::sync::Arc<BuildWith>);

/// What `Rebuild` holds: the description's manipulator with the text given appended.
pub type BuildWith = dyn Fn(&str) -> Result<Manipulator, String> + Send + Sync;

impl Rebuild {
    /// The description at `path` whose text is `source`, read as every command reads it (`overrides`: the
    /// `--set` values; `tip`: the tree's tip that is the reference point), with the text given appended.
    pub fn of_description(
        path: &std::path::Path,
        source: String,
        overrides: std::collections::BTreeMap<String, f64>,
        tip: Option<String>,
    ) -> Rebuild {
        let path = path.to_path_buf();
        Rebuild(std::sync::Arc::new(move |extra: &str| {
            let text = format!("{source}\n{extra}");
            let m = crate::model::parse_with(&path, &text, &overrides, 0).map_err(|e| e.to_string())?.manipulator;
            match &tip {
                Some(tip) => m.at_tip(tip).ok_or_else(|| format!("no tip `{tip}`")),
                None => Ok(m),
            }
        }))
    }
}

impl std::fmt::Debug for Rebuild {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Rebuild(..)")
    }
}

/// A calibration's outcome: its report (what `--json` writes and the text reports) beside the effects
/// accepted, typed, in the report's order, which the corrected description is written from.
#[derive(Clone, Debug)]
pub struct Calibration {
    /// What the calibration found, as written.
    pub report: CalibrationReport,
    /// The effects of `report.accepted`, in its order.
    pub effects: Vec<ArmEffect>,
    /// Their fitted parameters, as the fit holds them (a payload's as (m, m c); the report gives (m, c)).
    pub values: Vec<Vec<f64>>,
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
