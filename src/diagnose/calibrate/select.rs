//! Which effects the data need: forward selection by F tests at alpha / candidates with strong evidence
//! (`choose_effects`), backward elimination and swaps; the gross rows left out of every fit; the position
//! errors of a set of rows.

use super::effect::{ArmEffect, ArmKind};
use super::fit::PositionFit;
use super::options::{CalibrationError, CalibrationOptions};
use super::problem::PositionProblem;
use crate::diagnose::stats::{bic_unknown_noise, chi2_sf, f_sf, robust_scale, GROSS_FACTOR_POSITIONS, STRONG_EVIDENCE};
use crate::kinematics::frame::Vec3;
use crate::output::calibration::{CandidateTest, ErrorStats};
use rayon::prelude::*;

/// The error statistics of `rows` (unweighted residuals, mm).
pub(super) fn error_stats(residuals: &[Option<Vec3>], base: Option<&[Option<Vec3>]>, rows: &[usize]) -> ErrorStats {
    let r: Vec<Vec3> = rows.iter().filter_map(|&k| residuals[k]).collect();
    if r.is_empty() {
        return ErrorStats::default();
    }
    let n = r.len() as f64;
    let mut lengths: Vec<f64> = r.iter().map(|v| v.norm()).collect();
    lengths.sort_by(f64::total_cmp);
    let rms_axis = [0, 1, 2].map(|a| (r.iter().map(|v| v[a] * v[a]).sum::<f64>() / n).sqrt());
    // The 95th percentile by the nearest rank.
    let percentile = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(((0.95 * v.len() as f64).ceil() as usize).clamp(1, v.len().max(1)) - 1).copied().unwrap_or(f64::NAN)
    };
    let p95 = percentile(lengths.clone());
    // In the base's axes: horizontally (x-y) and vertically (z), as field users report a robot's accuracy.
    let in_base: Vec<Vec3> = base.map_or(Vec::new(), |b| rows.iter().filter_map(|&k| b[k]).collect());
    let (p95_horizontal, p95_vertical) = match in_base.is_empty() {
        true => (f64::NAN, f64::NAN),
        false => (
            percentile(in_base.iter().map(|v| v.x.hypot(v.y)).collect()),
            percentile(in_base.iter().map(|v| v.z.abs()).collect()),
        ),
    };
    ErrorStats {
        p95_horizontal,
        p95_vertical,
        rows: r.len(),
        rms_axis,
        rms: (lengths.iter().map(|l| l * l).sum::<f64>() / n).sqrt(),
        p95,
        max: *lengths.last().expect("not empty"),
        max_axis: [0, 1, 2].map(|a| r.iter().map(|v| v[a].abs()).fold(0.0, f64::max)),
    }
}

/// A screen that finds more than this share of a kind's rows gross (and more than one) leaves none of them
/// out, and says so: a model or a set-up that misses that many rows misses an effect, not a few bad
/// measurements (a target's place fitted along a direction no row sees once screened 317 of 321 rows).
pub(super) const MOST_GROSS_SHARE: f64 = 0.1;

/// The gross rows of a screen, and why rows beyond the scale were kept where there were too many of them.
#[derive(Debug, Default)]
pub(super) struct Screen {
    pub(super) gross: Vec<usize>,
    pub(super) kept_why: Vec<String>,
}

/// The gross rows among `rows`: weighted misfit beyond `stats::GROSS_FACTOR_POSITIONS` robust standard deviations.
pub(super) fn gross_rows(problem: &PositionProblem, residuals: &[Option<Vec3>], rows: &[usize]) -> Screen {
    gross_rows_against(problem, residuals, rows, rows)
}

/// The gross rows among `tested`, against the robust scale of the rows `scaled` (a held-out row is judged
/// by the fitted rows' scale). Positions and orientations are judged each against their own kind's scale,
/// so that a stated sigma of one kind that is off does not make the other's rows look gross; where more
/// than `MOST_GROSS_SHARE` of a kind's tested rows would be gross, none of them is, and the screen says why.
pub(super) fn gross_rows_against(
    problem: &PositionProblem,
    residuals: &[Option<Vec3>],
    scaled: &[usize],
    tested: &[usize],
) -> Screen {
    let misfit = |r: usize| residuals[r].map_or(f64::INFINITY, |v| v.norm() * problem.weight[r]);
    let turning = |r: &usize| problem.data.rows[*r].observed.is_orientation();
    let mut screen = Screen::default();
    for kind in [false, true] {
        let mut sorted: Vec<f64> =
            scaled.iter().filter(|r| turning(r) == kind).map(|&r| misfit(r)).filter(|m| m.is_finite()).collect();
        if sorted.len() < 5 {
            continue;
        }
        sorted.sort_by(f64::total_cmp);
        let scale = robust_scale(&sorted);
        let of_kind = tested.iter().filter(|r| turning(r) == kind).count();
        let gross: Vec<usize> = tested
            .iter()
            .copied()
            .filter(|r| turning(r) == kind && misfit(*r) > GROSS_FACTOR_POSITIONS * scale)
            .collect();
        if gross.len() > 1 && gross.len() as f64 > MOST_GROSS_SHARE * of_kind as f64 {
            let what = if kind { "orientation" } else { "position" };
            screen.kept_why.push(format!(
                "{} of {of_kind} {what} rows lie beyond {GROSS_FACTOR_POSITIONS} robust standard deviations of the \
                 fit, more than {:.0}% of them: none is left out as gross (a model or a set-up that misses this \
                 many rows misses something, not a few bad measurements; the errors below include them)",
                gross.len(),
                100.0 * MOST_GROSS_SHARE
            ));
            continue;
        }
        screen.gross.extend(gross);
    }
    screen.gross.sort_unstable();
    screen
}

/// The test of adding an effect to a fit of residual sum `rss0` (weighted) and rank `rank0`, giving `with`: its F
/// statistic against the residual's own scale, and its p-value; where the noise is known, the larger of the
/// F test's and the chi-square test's of the drop (both must reject: the drop must stand out from what is
/// left and from the noise, so that round-off on noise-free data is never a discovery).
pub(super) fn nested_test(rss0: f64, rank0: usize, with: &PositionFit, sigma_known: bool) -> (f64, f64) {
    // The parameters the data see: an effect of several parameters counts the directions it adds.
    let added = with.rank.saturating_sub(rank0).max(1);
    let drop = (rss0 - with.rss).max(0.0);
    let statistic = drop / added as f64 / (with.rss / with.dof() as f64).max(1e-300);
    let mut p = f_sf(statistic, added, with.dof());
    if sigma_known {
        p = p.max(chi2_sf(drop, added));
    }
    (statistic, p)
}

/// What a selection ends with: the effects in the model (the fitted ones first, then in the order accepted),
/// its fit, every step's tests and the directions found hidden.
pub(super) struct Selection {
    pub(super) model: Vec<ArmEffect>,
    pub(super) fit: PositionFit,
    pub(super) steps: Vec<Vec<CandidateTest>>,
    pub(super) hidden: Vec<String>,
    /// Why the forward selection stopped the last time (the limit of effects, or the best candidate's test).
    pub(super) stopped: String,
}

/// Forward selection on `rows`: effects offered one at a time, each step accepting the best one whose F
/// test passes at alpha / the candidates tested.
pub(super) fn choose_effects(
    problem: &PositionProblem,
    rows: &[usize],
    candidates: &[ArmEffect],
    options: &CalibrationOptions,
    sigma_known: bool,
) -> Result<Selection, CalibrationError> {
    let mut model = options.fitted.clone();
    let start = problem.start(rows, &model);
    let too_few =
        || CalibrationError::TooFew("the fit found no pose for a row, or too few rows for the parameters".into());
    let mut fit = problem.fit_exact(rows, &model, &start).ok_or_else(too_few)?;
    let mut steps = Vec::new();
    let mut hidden: Vec<String> = fit.hidden.iter().map(|d| problem.describe_hidden(d, &model)).collect();
    let mut stopped = String::new();
    // Rounds of forward selection, backward elimination and swaps: an effect chosen early, while the model
    // still missed others, can absorb parts of several and leave each too weak to pass alone; a swap frees
    // them, and the next forward steps take them.
    for _ in 0..3 {
        loop {
            if options.max_effects == 0 {
                stopped = "no effect offered: the model as it is, only the set-up fitted (a validation)".into();
                break;
            }
            if model.len() >= options.fitted.len() + options.max_effects {
                stopped = format!(
                    "at the limit of {} effects: the candidates left were not tested (a model this large rarely \
                     helps; name the effects with --fit to test further)",
                    options.max_effects
                );
                break;
            }
            if let Some(bar) = &problem.progress {
                bar.set_message(format!("testing candidates beside the model's {} effects", model.len()));
            }
            let (step, best, tested) = forward_step(problem, rows, candidates, &model, &fit, sigma_known);
            let threshold = options.alpha / tested.max(1) as f64;
            stopped = match &best {
                None => "no candidate left that the data can tell from the model".to_string(),
                Some((statistic, p, c, f)) => format!(
                    "the best candidate left, {} (F {statistic:.3}, p {p:.2e}, BIC {:+.1}), needs p below {threshold:.2e} and the BIC lower by more than {STRONG_EVIDENCE}",
                    c.label(&problem.joints),
                    bic(f) - bic(&fit)
                ),
            };
            // Accepted when its test passes and the evidence for it is strong (the BIC lower by more than 10,
            // as the other diagnosis asks): an effect of six parameters on few rows must pay for them.
            let accept = best
                .filter(|(_, p, _, f)| accepted(*p, threshold, f, &fit))
                .map(|(statistic, _, c, f)| (statistic, c, f));
            steps.push(step);
            match accept {
                Some((_, c, f)) => {
                    model.push(c);
                    // The model completed by its exact misses, against which the next candidates are
                    // judged (`kept_miss`).
                    fit = problem.fit_exact(rows, &model, &f.params).unwrap_or(f);
                }
                None => break,
            }
        }
        // Backward elimination and swaps, until the swaps change nothing (a swap may leave an effect that the
        // others make unnecessary, which the next elimination drops).
        let mut swapped = false;
        for _ in 0..3 {
            eliminate_backward(problem, rows, options, sigma_known, &mut model, &mut fit);
            // Swaps: an effect chosen early, while the model still missed others, may do the work of a simpler
            // one (a joint's geometry standing in for the offset of the joint before it): the accepted effect
            // whose replacement by a candidate with fewer parameters lowers the BIC (n ln(rss/n) + rank ln n)
            // most is replaced (or one of as many parameters that explains more).
            let best = best_swap(problem, rows, candidates, options, &model, &fit);
            match best {
                Some((_, k, c, f)) => {
                    model[k] = c;
                    fit = f;
                    swapped = true;
                }
                None => break,
            }
        }
        // Once the swaps settle, a split: an effect of several parameters doing the work of a few simpler
        // ones together (a joint's geometry standing in for its offset and the offset of the joint before
        // it), replaced by them where the BIC says so; the next round's steps then judge the model anew.
        if let Some((_, smaller, f)) = best_split(problem, rows, candidates, options, sigma_known, &model, &fit) {
            model = smaller;
            fit = problem.fit_exact(rows, &model, &f.params).unwrap_or(f);
            swapped = true;
        }
        if !swapped {
            break;
        }
    }
    // Each candidate's first reason once (a later step finds the same direction again).
    for t in steps.iter().flatten() {
        if let Some(note) = &t.note {
            if !hidden.iter().any(|h| h.starts_with(&format!("{}: ", t.label))) {
                hidden.push(format!("{}: {}", t.label, note));
            }
        }
    }
    Ok(Selection { model, fit, steps, hidden, stopped })
}

/// A fit's BIC with the noise unknown: n ln(rss / n) + rank ln n.
fn bic(f: &PositionFit) -> f64 {
    bic_unknown_noise(f.rss, f.observations, f.rank)
}

/// Whether a candidate tested at p-value `p` against `threshold`, its fit `with` beside the model's `fit`,
/// is accepted: its test passes and the evidence for it is strong (the BIC lower by more than
/// `STRONG_EVIDENCE`, as the other diagnosis asks: an effect of six parameters on few rows must pay for
/// them).
fn accepted(p: f64, threshold: f64, with: &PositionFit, fit: &PositionFit) -> bool {
    p < threshold && bic(with) < bic(fit) - STRONG_EVIDENCE
}

/// How many of a split's first candidates are each tried as its first replacement (`best_split`).
const SPLIT_STARTS: usize = 3;

/// A candidate tested best: its F statistic, its p-value, the candidate and its fit.
type Best = (f64, f64, ArmEffect, PositionFit);

/// One forward step: every candidate not in `model` fitted beside it and tested against `fit`. Returns each
/// candidate's test, the best tested (smallest p-value; the larger F among equal ones) with its fit, and
/// how many were tested.
fn forward_step(
    problem: &PositionProblem,
    rows: &[usize],
    candidates: &[ArmEffect],
    model: &[ArmEffect],
    fit: &PositionFit,
    sigma_known: bool,
) -> (Vec<CandidateTest>, Option<Best>, usize) {
    let mut step = Vec::new();
    let mut best: Option<Best> = None;
    let untested: Vec<ArmEffect> = candidates.iter().filter(|c| !model.contains(c)).copied().collect();
    let mut tested = 0;
    // The candidates' fits are independent: made in parallel, read in the candidates' order (the same
    // outcome for any number of threads).
    let fits: Vec<Option<PositionFit>> = untested
        .par_iter()
        .map(|c| {
            let mut trial = model.to_vec();
            trial.push(*c);
            let mut start = fit.params.clone();
            start.effects.push(vec![0.0; c.size()]);
            problem.fit(rows, &trial, &start)
        })
        .collect();
    for (c, f) in untested.iter().zip(fits) {
        let mut trial = model.to_vec();
        trial.push(*c);
        let label = c.label(&problem.joints);
        let Some(f) = f else {
            step.push(CandidateTest { label, f: None, p: None, note: Some("a row has no pose with it".into()) });
            continue;
        };
        let own_params = problem.nuisance_count() + model.iter().map(ArmEffect::size).sum::<usize>();
        let held_whole = (own_params..own_params + c.size()).all(|k| f.held.contains(&k));
        // A parameter held at zero by its bound counts as one the data see (it is held by the bound, not by
        // the data); one tied to others (held at its nominal value) does not.
        if held_whole || f.rank + f.bounded() <= fit.rank + fit.bounded() {
            // The candidate's parameters follow the nuisance ones and the model's.
            let own = problem.nuisance_count() + model.iter().map(ArmEffect::size).sum::<usize>();
            let own = own..own + c.size();
            let alone = f.hidden.iter().any(|d| d.len() == 1 && own.contains(&d[0].0));
            let tied: Vec<String> = f
                .tied
                .iter()
                .filter(|(k, _)| own.contains(k))
                .map(|(_, d)| problem.describe_hidden(d, &trial))
                .collect();
            let note = if !tied.is_empty() && own.clone().all(|k| f.held.contains(&k)) {
                format!(
                    "not identifiable from these rows: its parameters move with others where no point moves ({})",
                    tied.join("); (")
                )
            } else if own.clone().all(|k| f.held.contains(&k)) {
                "fitted below zero and held at zero (a compliance or a play is not negative): it adds nothing".into()
            } else if alone {
                // Its column is zero: a compliance or play whose joint carries no load (or the same sign of
                // load in every row, for play), or an offset that moves nothing measured.
                "moves no measured point in these rows (its joint's load is zero, or of one sign for play)".into()
            } else {
                // The directions that hold the candidate (the model's own hidden ones are reported
                // once, for the model).
                let with: Vec<String> = f
                    .hidden
                    .iter()
                    .filter(|d| d.iter().any(|(k, _)| own.contains(k)))
                    .map(|d| problem.describe_hidden(d, &trial))
                    .collect();
                match with.len() {
                    1 => format!("not identifiable from these rows: one combination ({}) moves no point", with[0]),
                    n => format!(
                        "not identifiable from these rows: {n} combinations move no point: ({})",
                        with.join("); (")
                    ),
                }
            };
            step.push(CandidateTest { label, f: None, p: None, note: Some(note) });
            continue;
        }
        // A candidate whose parameters still move with others in a direction no row sees (the fit holds one
        // of its parameters per such direction, `PositionProblem::fit`, up to its limit of held ones) has no
        // values of its own there: the fit would split them as its smallest change, 120 mrad and 1.56 m at
        // a column's base. Not accepted; a direction within its own parameters alone (held at the start) is.
        let own = own_params..own_params + c.size();
        let mixed: Vec<String> = f
            .hidden
            .iter()
            .filter(|d| d.iter().any(|(k, _)| own.contains(k)) && d.iter().any(|(k, _)| !own.contains(k)))
            .map(|d| problem.describe_hidden(d, &trial))
            .collect();
        if !mixed.is_empty() {
            let note = format!(
                "not identifiable from these rows: its parameters move with others where no point moves ({})",
                mixed.join("); (")
            );
            step.push(CandidateTest { label, f: None, p: None, note: Some(note) });
            continue;
        }
        tested += 1;
        let (statistic, p) = nested_test(fit.rss, fit.rank, &f, sigma_known);
        let values = f.params.effects.last().expect("the candidate's values");
        if let Some(why) = unphysical(problem, c, values) {
            step.push(CandidateTest { label, f: Some(statistic), p: Some(p), note: Some(why) });
            continue;
        }
        step.push(CandidateTest { label, f: Some(statistic), p: Some(p), note: None });
        // The smallest p-value is the best (it weighs an effect's drop by the directions it adds); the
        // larger F among equal p-values.
        if best.as_ref().is_none_or(|b| p < b.1 || (p == b.1 && statistic > b.0)) {
            best = Some((statistic, p, *c, f));
        }
    }
    (step, best, tested)
}

/// Backward elimination: an effect selected early that later ones make unnecessary (a proxy for the effect
/// found after it) is dropped, the least needed first, while its removal's test does not reject.
fn eliminate_backward(
    problem: &PositionProblem,
    rows: &[usize],
    options: &CalibrationOptions,
    sigma_known: bool,
    model: &mut Vec<ArmEffect>,
    fit: &mut PositionFit,
) {
    loop {
        let selected = options.fitted.len()..model.len();
        let threshold = options.alpha / selected.len().max(1) as f64;
        let mut weakest: Option<(f64, usize, PositionFit)> = None;
        let fits: Vec<(usize, Option<PositionFit>)> = selected
            .into_par_iter()
            .map(|k| {
                let mut without = model.clone();
                without.remove(k);
                let mut start = fit.params.clone();
                start.effects.remove(k);
                (k, problem.fit(rows, &without, &start))
            })
            .collect();
        for (k, f) in fits {
            let Some(f) = f else { continue };
            let (_, p) = nested_test(f.rss, f.rank, fit, sigma_known);
            if p >= threshold && weakest.as_ref().is_none_or(|w| p > w.0) {
                weakest = Some((p, k, f));
            }
        }
        match weakest {
            Some((_, k, f)) => {
                model.remove(k);
                *fit = f;
            }
            None => break,
        }
    }
}

/// The best swap: the accepted effect whose replacement by a candidate with as many or fewer parameters
/// lowers the BIC most, with the candidate and its fit; None where none lowers it.
fn best_swap(
    problem: &PositionProblem,
    rows: &[usize],
    candidates: &[ArmEffect],
    options: &CalibrationOptions,
    model: &[ArmEffect],
    fit: &PositionFit,
) -> Option<(f64, usize, ArmEffect, PositionFit)> {
    let mut best: Option<(f64, usize, ArmEffect, PositionFit)> = None;
    let swaps: Vec<(usize, ArmEffect)> = (options.fitted.len()..model.len())
        .flat_map(|k| {
            candidates.iter().filter(move |c| !model.contains(c) && c.size() <= model[k].size()).map(move |c| (k, *c))
        })
        .collect();
    let fits: Vec<Option<PositionFit>> = swaps
        .par_iter()
        .map(|&(k, c)| {
            let mut swapped = model.to_vec();
            swapped[k] = c;
            let mut start = fit.params.clone();
            start.effects[k] = vec![0.0; c.size()];
            problem.fit(rows, &swapped, &start)
        })
        .collect();
    for ((k, c), f) in swaps.into_iter().zip(fits) {
        let Some(f) = f.filter(|f| unphysical(problem, &c, &f.params.effects[k]).is_none()) else { continue };
        let gain = bic(fit) - bic(&f);
        if gain > 0.0 && best.as_ref().is_none_or(|b| gain > b.0) {
            best = Some((gain, k, c, f));
        }
    }
    best
}

/// The best split: the accepted effect of several parameters whose place is better taken by candidates
/// with fewer parameters in all, found by forward selection among them on the model without it (each
/// accepted as `choose_effects` accepts one), where the BIC comes out lower. The first replacement is tried
/// from each of the `SPLIT_STARTS` best of the first step (the best alone may be a third effect that fits
/// part of both, a payload beside two offsets). Returns the gain, the model (the others, then the
/// replacements) and its fit; None where no split lowers the BIC.
fn best_split(
    problem: &PositionProblem,
    rows: &[usize],
    candidates: &[ArmEffect],
    options: &CalibrationOptions,
    sigma_known: bool,
    model: &[ArmEffect],
    fit: &PositionFit,
) -> Option<(f64, Vec<ArmEffect>, PositionFit)> {
    let mut best: Option<(f64, Vec<ArmEffect>, PositionFit)> = None;
    for k in (options.fitted.len()..model.len()).filter(|&k| model[k].size() > 1) {
        let mut others = model.to_vec();
        let removed = others.remove(k);
        let mut start = fit.params.clone();
        start.effects.remove(k);
        let Some(without) = problem.fit(rows, &others, &start) else { continue };
        // Fewer parameters in all than the effect replaced.
        let offered = |budget: usize| -> Vec<ArmEffect> {
            candidates.iter().filter(|c| **c != removed && c.size() <= budget).copied().collect()
        };
        let first = offered(removed.size() - 1);
        let (tests, _, tested) = forward_step(problem, rows, &first, &others, &without, sigma_known);
        let threshold = options.alpha / tested.max(1) as f64;
        let mut starts: Vec<(f64, ArmEffect)> = tests
            .iter()
            .filter(|t| t.note.is_none())
            .filter_map(|t| Some((t.p?, *first.iter().find(|c| c.label(&problem.joints) == t.label)?)))
            .filter(|(p, _)| *p < threshold)
            .collect();
        starts.sort_by(|a, b| a.0.total_cmp(&b.0));
        for &(p, c) in starts.iter().take(SPLIT_STARTS) {
            let mut smaller = others.clone();
            smaller.push(c);
            let mut start = without.params.clone();
            start.effects.push(vec![0.0; c.size()]);
            let Some(mut f) = problem.fit(rows, &smaller, &start) else { continue };
            if !accepted(p, threshold, &f, &without) {
                continue;
            }
            let mut budget = removed.size() - 1 - c.size();
            while budget > 0 && smaller.len() < options.fitted.len() + options.max_effects {
                let (_, chosen, tested) = forward_step(problem, rows, &offered(budget), &smaller, &f, sigma_known);
                let threshold = options.alpha / tested.max(1) as f64;
                let Some((_, _, c, with)) = chosen.filter(|(_, p, _, g)| accepted(*p, threshold, g, &f)) else {
                    break;
                };
                smaller.push(c);
                budget -= c.size();
                f = with;
            }
            let gain = bic(fit) - bic(&f);
            // One replacement alone is a swap's (`best_swap`).
            if smaller.len() > others.len() + 1 && gain > 0.0 && best.as_ref().is_none_or(|b| gain > b.0) {
                best = Some((gain, smaller, f));
            }
        }
    }
    best
}

/// Why a candidate's fitted values are no robot's, where they are not: a joint's compliance that the added
/// one makes zero or negative (no spring), a payload of no mass or less. Such a candidate is not accepted,
/// and its test says why. (A compliance at a frame or the tool, and a play, are bounded at zero in the fit
/// itself: `PositionProblem::fit`.)
fn unphysical(problem: &PositionProblem, c: &ArmEffect, values: &[f64]) -> Option<String> {
    match c.kind {
        ArmKind::JointCompliance => {
            let nominal = problem.nominal_compliance(c.joint).unwrap_or(0.0);
            let unit = if problem.prismatic[c.joint] { "mm/N" } else { "rad/(N mm)" };
            (nominal + values[0] <= 0.0).then(|| {
                format!(
                    "not accepted: its fitted value leaves the joint's compliance at {:.4e} {unit} (the model's \
                     {nominal:.4e} plus {:.4e}), not above zero: no spring has it",
                    nominal + values[0],
                    values[0]
                )
            })
        }
        ArmKind::Payload => {
            (values[0] <= 0.0).then(|| format!("not accepted: its fitted mass, {:.4} kg, is not above zero", values[0]))
        }
        _ => None,
    }
}
