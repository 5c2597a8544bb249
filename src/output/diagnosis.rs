//! The JSON file `stiff diagnose --json` writes and `stiff plot` reads: one serde type for both, so the
//! writer and the reader cannot disagree on a key. Numbers that may be undefined (a condition number, a
//! standard error without a covariance) are `null` in the file and `None` here.

use serde::{Deserialize, Serialize};

/// A diagnosis as written to JSON.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DiagnosisReport {
    /// The model file diagnosed.
    pub model: String,
    /// `none`, `effect`, `ambiguous`, `unexplained` or `noise`.
    pub verdict: String,
    /// The verdict in one sentence.
    pub sentence: String,
    /// The measurement standard deviation used, mm.
    pub sigma_mm: f64,
    /// Where it comes from.
    pub sigma_source: String,
    /// Measurement rows.
    pub rows: usize,
    /// The nominal model's test.
    pub nominal: NominalTest,
    /// The effects accepted, in order.
    pub effects: Vec<EffectReport>,
    /// p-value of the residuals left after the accepted effects.
    pub final_p_value: f64,
    /// For an ambiguous verdict: the tied candidates and how to separate them.
    pub ambiguous: Option<Ambiguity>,
    /// Candidates with the same signature on this data: each reported as the first of its pair.
    #[serde(default)]
    pub indistinguishable: Vec<Indistinguishable>,
    /// Correlations of the accepted effects' parameters in their joint fit.
    #[serde(default)]
    pub correlations: Option<Correlations>,
    /// For the `noise` verdict: how the residual variance grows with the load.
    #[serde(default)]
    pub noise: Option<String>,
    /// The candidate table of the first step.
    pub candidates: Vec<CandidateReport>,
    /// Per pose, the residual of its row with the largest nominal residual.
    pub residuals: Vec<PoseResidual>,
    /// Residual RMS per axis.
    pub rms_mm: ResidualRms,
    /// How many rows were left out of the fits as gross errors.
    #[serde(default)]
    pub left_out_count: usize,
    /// The rows left out, each with how far it lies from the model.
    #[serde(default)]
    pub left_out: Vec<LeftOutRow>,
}

/// A measured row left out of the fits as a gross error.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LeftOutRow {
    /// Its number among the data rows (1 for the first after the header).
    pub row: usize,
    /// Its line in the file.
    pub line: usize,
    /// Its pose.
    pub pose_id: String,
    /// The wrench applied (Fx, Fy, Fz in N, Mx, My, Mz in N mm).
    pub wrench: [f64; 6],
    /// How far its measured displacement lies from the model's prediction, mm.
    pub misfit_mm: f64,
    /// The same in words.
    pub description: String,
}

/// The nominal model against the data.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NominalTest {
    /// Chi-square, or lack-of-fit F with repeats.
    pub statistic: f64,
    /// Its p-value.
    pub p_value: f64,
}

/// An accepted effect.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EffectReport {
    /// The effect's kind, as on the command line.
    pub name: String,
    /// Its target (a leg number, a spring group) or empty.
    pub target: String,
    /// Its values, in the units `meaning` gives.
    pub values: Vec<f64>,
    /// What the values mean.
    pub meaning: String,
    /// The fitted values as reported (for leg geometry: coordinates in the visible directions).
    pub parameters: Vec<f64>,
    /// Their standard errors, from the joint fit of every accepted effect.
    pub standard_errors: Vec<Option<f64>>,
    /// The F test's p-value of this effect given the other accepted ones.
    pub p_value: f64,
    /// Delta BIC of this effect given the other accepted ones.
    pub delta_bic: f64,
}

/// Two candidates no data of this design can tell apart.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Indistinguishable {
    /// The one reported.
    pub reported_as: String,
    /// The one with the same signature.
    pub same_as: String,
}

/// Correlations of the accepted effects' parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Correlations {
    /// The parameters, `NAME[:TARGET]` with `[k]` for an effect of several values.
    pub parameters: Vec<String>,
    /// The correlation matrix, rows in the order of `parameters`.
    pub matrix: Vec<Vec<Option<f64>>>,
}

/// Candidates that explain the same thing as well as the data can tell.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Ambiguity {
    /// Their labels, the best-fitting first.
    pub candidates: Vec<String>,
    /// Where their predictions differ most: advice for the next experiment.
    pub separate_by: String,
}

/// One row of the candidate table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CandidateReport {
    /// `NAME[:TARGET]`.
    pub candidate: String,
    /// Number of parameters.
    pub dim: usize,
    /// Whether the data can fix its parameters.
    pub identifiable: bool,
    /// Why not, or what else to know.
    pub note: String,
    /// Condition number of its signature.
    pub condition: Option<f64>,
    /// Share of its signature outside what accepted effects explain.
    pub orthogonal_share: f64,
    /// Weighted sum of squared residuals with it.
    pub ssr: Option<f64>,
    /// Delta BIC against the model without it.
    pub delta_bic: Option<f64>,
    /// Its F statistic.
    pub f: Option<f64>,
    /// The F test's p-value.
    pub p_value: Option<f64>,
    /// Fitted values.
    pub values: Vec<Option<f64>>,
    /// Their standard errors.
    pub standard_errors: Vec<Option<f64>>,
    /// Physically possible values.
    pub plausible: bool,
    /// Passes every test.
    pub passes: bool,
}

/// A pose's residual before and after the accepted effects.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseResidual {
    /// Commanded position.
    pub position_mm: [f64; 3],
    /// Residual before.
    pub before_mm: [f64; 3],
    /// Residual after.
    pub after_mm: [f64; 3],
}

/// Residual RMS per axis (x, y, z), mm.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ResidualRms {
    /// On the fitting data, nominal.
    pub fit_before: [f64; 3],
    /// On the fitting data, with the accepted effects.
    pub fit_after: [f64; 3],
    /// Leave-pose-out, nominal.
    pub heldout_before: [f64; 3],
    /// Leave-pose-out, with the accepted effects refitted.
    pub heldout_after: [f64; 3],
}

/// `Some(v)` for a finite number, else `None` (written as null).
pub fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}
