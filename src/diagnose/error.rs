//! Why a diagnosis (or synthetic data) cannot be made: typed up to the command line, which words the flags.

use std::fmt;

use crate::platform::loaded::DeflectionFailure;
use crate::platform::manipulator::PoseFailure;

/// Why the model cannot be evaluated at a measured pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PoseError {
    /// A leg fails there (unreachable, singular leg, ...).
    Fails(PoseFailure),
    /// The manipulator is singular or ill-conditioned there: it has no compliance to predict with.
    NoCompliance,
    /// No loaded equilibrium under the row's wrench.
    NoLoadedEquilibrium(DeflectionFailure),
    /// The effects' predicted displacement is not finite.
    NotFinite,
}

impl fmt::Display for PoseError {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        match self {
            PoseError::Fails(e) => write!(f, "it fails there ({e})"),
            PoseError::NoCompliance => f.write_str("the manipulator is singular or ill-conditioned there"),
            PoseError::NoLoadedEquilibrium(e) => write!(f, "no loaded equilibrium under the row's wrench: {e}"),
            PoseError::NotFinite => f.write_str("the predicted displacement is not finite"),
        }
    }
}

/// Why `diagnose` cannot run on this model and data.
#[derive(Clone, Debug, PartialEq)]
pub enum DiagnoseError {
    /// The model cannot be evaluated at a pose of the data.
    Pose {
        /// The pose's id in the data.
        pose_id: String,
        /// The line of its first row.
        line: usize,
        /// Why.
        why: PoseError,
    },
    /// A given noise level outside [MIN_SIGMA_MM, MAX_MAGNITUDE].
    NoiseOutOfRange {
        /// The noise level given, mm.
        sigma: f64,
    },
    /// No sigma column, no noise level given and no repeated rows to estimate it from.
    NoiseUnknown,
    /// A prediction during the fits failed (a candidate's springs made a pose fail).
    Prediction(PoseError),
    /// Fewer measurements than a candidate has parameters (plus one).
    TooFewMeasurements {
        /// Rows in the data.
        rows: usize,
    },
}

impl fmt::Display for DiagnoseError {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        use super::data::{MAX_MAGNITUDE, MIN_SIGMA_MM};
        match self {
            DiagnoseError::Pose { pose_id, line, why } => write!(f, "line {line}: pose `{pose_id}`: {why}"),
            DiagnoseError::NoiseOutOfRange { sigma } => {
                write!(f, "the noise must lie in [{MIN_SIGMA_MM:e}, {MAX_MAGNITUDE:e}] mm, got {sigma:e}")
            }
            DiagnoseError::NoiseUnknown => f.write_str(
                "the noise level is unknown: give a sigma_mm column, the noise level, or repeated rows (same pose \
                 and wrench)",
            ),
            DiagnoseError::Prediction(e) => write!(f, "a prediction with a candidate effect failed: {e}"),
            DiagnoseError::TooFewMeasurements { rows } => {
                write!(f, "{rows} measurements are too few for the candidates' parameters")
            }
        }
    }
}

impl std::error::Error for DiagnoseError {}

impl From<PoseError> for DiagnoseError {
    fn from(e: PoseError) -> Self {
        DiagnoseError::Prediction(e)
    }
}
