//! The JSON file `stiff diagnose --json` writes for a calibration (joint-space data, or a parallel robot's
//! positions at commanded poses) and `stiff plot` reads: one serde type for both, so the writer and the
//! reader cannot disagree on a key. A number that is not defined (the standard error of a direction the data
//! cannot see) is NaN here and `null` in the file, and reads back as NaN.

use serde::{Deserialize, Serialize};

/// A calibration as written to JSON: the description calibrated and what the calibration found.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CalibrationFile {
    /// The description calibrated.
    pub model: String,
    /// The calibration.
    pub calibration: CalibrationReport,
}

/// An effect accepted, with its value and standard error.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct AcceptedEffect {
    /// `joint-offset:J2` and so on.
    pub label: String,
    /// Its kind, as the command line names it (`joint-offset`, `payload`).
    pub kind: String,
    /// The joint's name.
    pub joint: String,
    /// The fitted values: rad (mm) for an offset or backlash, rad/(N mm) (mm/N) added compliance; mm and
    /// rad for a joint's geometry (translation, then rotation vector, in the joint's frame); for a
    /// payload (its mass, kg, then its centre in the tool frame, mm: as the text prints them).
    #[serde(deserialize_with = "null_is_nan::floats")]
    pub values: Vec<f64>,
    /// Their standard errors, same units (null for a direction the data cannot see).
    #[serde(deserialize_with = "null_is_nan::floats")]
    pub se: Vec<f64>,
    /// The value in the unit a user reads (mrad, mm, N m/rad ...), with its standard error.
    pub shown: String,
    /// For an effect selected where rows are held out: whether adding it lowered their RMS error (an
    /// effect the fit rows need but the check rows do not confirm is named as such).
    pub confirmed: Option<bool>,
}

/// One step of the selection: each candidate's test.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CandidateTest {
    /// The candidate.
    pub label: String,
    /// F statistic of adding it (null where not identifiable).
    pub f: Option<f64>,
    /// Its p-value.
    pub p: Option<f64>,
    /// Why it was not tested, where it was not.
    pub note: Option<String>,
}

/// Position errors of a set of rows (mm): RMS per axis, RMS, 95th percentile and maximum of the length.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct ErrorStats {
    /// Rows.
    pub rows: usize,
    /// RMS of x, y, z.
    #[serde(deserialize_with = "null_is_nan::three")]
    pub rms_axis: [f64; 3],
    /// RMS of the length.
    #[serde(deserialize_with = "null_is_nan::float")]
    pub rms: f64,
    /// 95th percentile of the length.
    #[serde(deserialize_with = "null_is_nan::float")]
    pub p95: f64,
    /// Largest length.
    #[serde(deserialize_with = "null_is_nan::float")]
    pub max: f64,
    /// Largest magnitude of x, y, z.
    #[serde(deserialize_with = "null_is_nan::three")]
    pub max_axis: [f64; 3],
    /// 95th percentile of the error in the robot base's horizontal (x-y) plane, mm (positions only: a set-up's
    /// error turned back from the instrument's frame).
    #[serde(default = "not_given", deserialize_with = "null_is_nan::float")]
    pub p95_horizontal: f64,
    /// 95th percentile of the error's magnitude along the base's vertical (z), mm.
    #[serde(default = "not_given", deserialize_with = "null_is_nan::float")]
    pub p95_vertical: f64,
}

/// A figure an older file does not hold.
fn not_given() -> f64 {
    f64::NAN
}

/// The errors after one stage of the model (the registration alone, then each accepted effect).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Stage {
    /// `registration`, `+ joint-offset:J2` and so on.
    pub model: String,
    /// Parameters the data see (the fit's rank: an effect's directions the data cannot see do not count).
    pub parameters: usize,
    /// On the rows fitted (gross rows left out).
    pub fit: ErrorStats,
    /// On the rows held out (gross ones left out).
    pub check: ErrorStats,
    /// On every row held out, gross ones included (the figure to compare with a calibration that keeps them).
    pub check_all: ErrorStats,
    /// The orientation errors of the rows fitted and held out (mrad: the rotation vector from the measured
    /// orientation to the predicted), where orientations are measured.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orientation: Option<[ErrorStats; 2]>,
}

/// A nuisance parameter's fitted value.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Nuisance {
    /// `setup A: translation` and so on.
    pub name: String,
    /// Values (mm, or mrad for a rotation vector).
    #[serde(deserialize_with = "null_is_nan::three")]
    pub value: [f64; 3],
    /// Standard errors.
    #[serde(deserialize_with = "null_is_nan::three")]
    pub se: [f64; 3],
}

/// The verdict of a calibration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CalibrationVerdict {
    /// No effect needed: the registration explains the data (within the noise, where it is known).
    None,
    /// Effects named, and the rest within the noise (or the noise is not known).
    Effect,
    /// The rest is above the stated noise after the effects named.
    Unexplained,
}

impl CalibrationVerdict {
    /// Its word, as the file writes it.
    pub fn as_str(self) -> &'static str {
        match self {
            CalibrationVerdict::None => "none",
            CalibrationVerdict::Effect => "effect",
            CalibrationVerdict::Unexplained => "unexplained",
        }
    }
}

/// A calibration's outcome.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CalibrationReport {
    /// The verdict.
    pub verdict: CalibrationVerdict,
    /// Effects always fitted, then those selected, with values.
    pub accepted: Vec<AcceptedEffect>,
    /// The selection's steps: at each, every candidate's test.
    pub steps: Vec<Vec<CandidateTest>>,
    /// Registration and targets.
    pub nuisance: Vec<Nuisance>,
    /// Directions no fit could see, named by their parameters.
    pub not_identifiable: Vec<String>,
    /// Gross rows left out.
    pub left_out: Vec<GrossRow>,
    /// Rows the model has no prediction for (no loaded equilibrium there), left out: the reason.
    pub unusable: Vec<String>,
    /// Errors per stage.
    pub stages: Vec<Stage>,
    /// RMS of the weighted residual per coordinate after the final fit (1 where sigma was right).
    #[serde(deserialize_with = "null_is_nan::float")]
    pub residual_scale: f64,
    /// Whether the noise level was given (sigma_mm or --sigma).
    pub sigma_known: bool,
    /// Rows fitted and held out.
    pub rows: (usize, usize),
    /// The data's columns no rule read.
    pub unread: Vec<String>,
    /// Why the selection of effects stopped.
    #[serde(default)]
    pub stopped: String,
    /// Measurements of the file not used, each with its line and why (an empty cell).
    #[serde(default)]
    pub not_used: Vec<String>,
    /// How many measurements of the file were not used (`not_used`'s length).
    #[serde(default)]
    pub not_used_count: usize,
    /// What reading the file changed (rows given the file's median sigma).
    #[serde(default)]
    pub notes: Vec<String>,
}

/// A gross row left out of the fits.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct GrossRow {
    /// The row: its name and line, `held out` and `orientation` where it is one.
    pub row: String,
    /// Its misfit against the model selected: mm for a position, mrad for an orientation.
    #[serde(deserialize_with = "null_is_nan::float")]
    pub misfit: f64,
    /// The misfit's unit.
    pub unit: String,
}

/// serde_json writes a NaN as `null`; these read it back as NaN.
mod null_is_nan {
    use serde::{Deserialize, Deserializer};

    pub fn float<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
    }

    pub fn floats<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
        Ok(Vec::<Option<f64>>::deserialize(d)?.into_iter().map(|v| v.unwrap_or(f64::NAN)).collect())
    }

    pub fn three<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
        Ok(<[Option<f64>; 3]>::deserialize(d)?.map(|v| v.unwrap_or(f64::NAN)))
    }
}
