//! Gross errors in measured data: a row that no plausible model fits (a typing or export error, a target
//! knocked between readings) is named and left out of every fit, instead of dominating the sums of squares
//! and turning every verdict into `unexplained`.
//!
//! The decision is robust: each row's misfit is the length of its weighted residual (in standard
//! deviations), compared with a scale taken from the median of all rows' misfits, which a minority of gross
//! rows cannot move. A row is gross where its misfit exceeds `stats::GROSS_FACTOR_DEFLECTIONS` times that scale (and the
//! stated noise level, where it is known). The rows are first screened against the nominal model; once the
//! effects are fitted, every row is screened again against the corrected model (an effect can make clean
//! rows look far off the nominal, and hide a gross row under its own misfit), until the set left out no
//! longer changes.

use nalgebra::DVector;

use super::data::Dataset;
use super::error::DiagnoseError;
use super::fit::Problem;
use super::select::{diagnose, noise, Diagnosis, Options, SigmaSource, Verdict};
use super::stats::{robust_scale, GROSS_FACTOR_DEFLECTIONS};
use crate::kinematics::frame::{Vec3, Vec6};
use crate::model::effect::Effect;
use crate::platform::manipulator::Manipulator;

/// Rounds of screening and fitting at most: each one changes the set left out, or the screening ends.
pub const MAX_ROUNDS: usize = 3;

/// A measured row left out as a gross error.
#[derive(Clone, Debug, PartialEq)]
pub struct LeftOut {
    /// Its index among the data file's rows (0 for the first row after the header).
    pub row: usize,
    /// Its line in the file.
    pub line: usize,
    /// Its pose.
    pub pose_id: String,
    /// The wrench applied, N and N mm.
    pub wrench: Vec6,
    /// How far the measured displacement lies from the model's prediction, mm.
    pub misfit_mm: f64,
}

impl LeftOut {
    /// "row 7 (line 8), pose Q0 under 100 N along y: 9.2e18 mm from the model".
    pub fn describe(&self) -> String {
        format!(
            "row {} (line {}), pose {} under {}: {} mm from the model",
            self.row + 1,
            self.line,
            self.pose_id,
            load_text(&self.wrench),
            significant(self.misfit_mm)
        )
    }
}

/// A wrench in words: a single force or moment component by its axis, else the force and moment vectors.
fn load_text(w: &Vec6) -> String {
    let nonzero: Vec<usize> = (0..6).filter(|&i| w[i] != 0.0).collect();
    let axes = ["x", "y", "z"];
    match nonzero.as_slice() {
        [] => "no load".into(),
        [i] if *i < 3 => format!("{} N along {}", significant(w[*i]), axes[*i]),
        [i] => format!("{} N mm about {}", significant(w[*i]), axes[*i - 3]),
        _ => format!(
            "({}, {}, {}) N and ({}, {}, {}) N mm",
            significant(w[0]),
            significant(w[1]),
            significant(w[2]),
            significant(w[3]),
            significant(w[4]),
            significant(w[5])
        ),
    }
}

/// Four significant digits, plain for everyday sizes and with an exponent beyond them.
fn significant(v: f64) -> String {
    if v != 0.0 && (v.abs() >= 1e6 || v.abs() < 1e-3) {
        format!("{v:.3e}")
    } else {
        let text = format!("{v:.4}");
        let text = text.trim_end_matches('0').trim_end_matches('.');
        text.to_string()
    }
}

/// The rows of `rows` whose weighted residuals `r` (three per row, in the order of `rows`) are gross against
/// the robust scale of `scale_rows` (positions in `rows`: the rows trusted for the scale), with `floor` the
/// smallest scale allowed (1 where the weights are 1 / sigma of a known noise level, else 0).
fn gross_among(rows: &[usize], r: &DVector<f64>, scale_rows: &[usize], floor: f64) -> Vec<usize> {
    let misfit = |i: usize| Vec3::new(r[3 * i], r[3 * i + 1], r[3 * i + 2]).norm();
    let mut trusted: Vec<f64> = scale_rows.iter().map(|&i| misfit(i)).filter(|m| m.is_finite()).collect();
    if trusted.is_empty() {
        return Vec::new();
    }
    trusted.sort_by(f64::total_cmp);
    let scale = robust_scale(&trusted).max(floor);
    // A zero scale (more than half the rows fitted exactly, and no noise level known) decides nothing.
    if scale.is_nan() || scale <= 0.0 {
        return Vec::new();
    }
    // A misfit that is not a number (an overflow) is gross too.
    let gross = |m: f64| m.is_nan() || m > GROSS_FACTOR_DEFLECTIONS * scale;
    (0..rows.len()).filter(|&i| gross(misfit(i))).map(|i| rows[i]).collect()
}

/// The gross rows of `problem`'s data under the model with `effects`: every row's residual, the scale from
/// the rows not in `suspect` (all rows at the first screening), `floor` as in `gross_among`.
pub fn gross_rows(
    problem: &Problem,
    effects: &[Effect],
    suspect: &[usize],
    floor: f64,
) -> Result<Vec<LeftOut>, super::error::PoseError> {
    let all: Vec<usize> = (0..problem.data.rows.len()).collect();
    let r = problem.residuals(effects, &all)?;
    let trusted: Vec<usize> = all.iter().copied().filter(|i| !suspect.contains(i)).collect();
    let gross = gross_among(&all, &r, if trusted.is_empty() { &all } else { &trusted }, floor);
    Ok(gross
        .into_iter()
        .map(|i| {
            let row = &problem.data.rows[i];
            let weight = problem.weights[i];
            let misfit = Vec3::new(r[3 * i], r[3 * i + 1], r[3 * i + 2]).norm() / weight;
            LeftOut {
                row: i,
                line: row.line,
                pose_id: row.pose_id.clone(),
                wrench: row.wrench,
                misfit_mm: if misfit.is_finite() { misfit } else { f64::MAX },
            }
        })
        .collect())
}

/// The data without the rows left out (their poses kept where other rows remain).
pub fn without(data: &Dataset, left_out: &[LeftOut]) -> Dataset {
    let keep: Vec<usize> = (0..data.rows.len()).filter(|i| !left_out.iter().any(|l| l.row == *i)).collect();
    let mut clean = Dataset { rows: Vec::with_capacity(keep.len()), poses: Vec::new() };
    for &i in &keep {
        let row = data.rows[i].clone();
        let index = clean.rows.len();
        match clean.poses.iter_mut().find(|p| p.id == row.pose_id) {
            Some(p) => p.rows.push(index),
            None => clean.poses.push(super::data::Pose {
                id: row.pose_id.clone(),
                position: row.position,
                rows: vec![index],
            }),
        }
        clean.rows.push(row);
    }
    clean
}

/// The diagnosis of `data` with its gross rows left out: screened against the nominal model, diagnosed,
/// screened again against the corrected model, until the rows left out no longer change (at most
/// `MAX_ROUNDS` diagnoses; one where nothing is left out and the verdict is `none` or `effect`). The noise
/// level is estimated without the rows left out. Returns the diagnosis (its `left_out` filled in).
pub fn diagnose_screened(
    model: &Manipulator,
    terms: &[Effect],
    data: &Dataset,
    sigma: Option<f64>,
    options: &Options,
) -> Result<Diagnosis, DiagnoseError> {
    let (weights, sigma_all, source) = noise(data, sigma)?;
    // Weights of 1 / sigma: a row within a few standard deviations is never gross, whatever the median.
    let floor = if matches!(source, SigmaSource::Repeats { .. }) { 0.0 } else { 1.0 };
    let full = Problem::new(model, terms, data, weights, options.loaded, true)?;
    let mut left_out = gross_rows(&full, &[], &[], floor)?;
    let mut round = 1;
    loop {
        let mut d = if left_out.is_empty() {
            diagnose(&full, sigma_all, source.clone(), options)?
        } else {
            let clean = without(data, &left_out);
            let (weights, sigma_used, source) = noise(&clean, sigma)?;
            let problem = Problem::new(model, terms, &clean, weights, options.loaded, true)?;
            diagnose(&problem, sigma_used, source, options)?
        };
        let settled = left_out.is_empty() && matches!(d.verdict, Verdict::None | Verdict::Effect);
        if settled || round == MAX_ROUNDS {
            d.left_out = left_out;
            return Ok(d);
        }
        let effects: Vec<Effect> = d.accepted.iter().map(|a| a.effect.clone()).collect();
        let suspect: Vec<usize> = left_out.iter().map(|l| l.row).collect();
        let again = gross_rows(&full, &effects, &suspect, floor)?;
        if again.iter().map(|l| l.row).eq(suspect.iter().copied()) {
            // The same rows: their misfits as the corrected model sees them.
            d.left_out = again;
            return Ok(d);
        }
        left_out = again;
        round += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pure noise leaves nothing out; one row a million standard deviations off is left out and the scale
    /// comes from the others; data fitted exactly, with no noise level to compare with, decides nothing.
    #[test]
    fn only_rows_far_beyond_the_robust_scale_are_gross() {
        let rows: Vec<usize> = (0..40).collect();
        // A deterministic spread of misfits of about one standard deviation.
        let mut r = DVector::from_fn(120, |i, _| ((i * 7919 % 97) as f64 / 48.5 - 1.0) * 1.7);
        let all: Vec<usize> = (0..40).collect();
        assert!(gross_among(&rows, &r, &all, 1.0).is_empty());
        r[3 * 7] = -9.2e18;
        r[3 * 30 + 2] = f64::INFINITY;
        assert_eq!(gross_among(&rows, &r, &all, 1.0), vec![7, 30]);
        let exact = DVector::from_fn(120, |i, _| if i == 5 { 1e-3 } else { 0.0 });
        assert!(gross_among(&rows, &exact, &all, 0.0).is_empty());
        assert_eq!(gross_among(&rows, &exact, &all, 1e-6), vec![1]);
    }

    #[test]
    fn loads_are_described_by_their_axis() {
        assert_eq!(load_text(&Vec6::new(0.0, 100.0, 0.0, 0.0, 0.0, 0.0)), "100 N along y");
        assert_eq!(load_text(&Vec6::new(0.0, 0.0, 0.0, 0.0, 0.0, -2500.0)), "-2500 N mm about z");
        assert_eq!(significant(-9.2e18), "-9.200e18");
    }
}
