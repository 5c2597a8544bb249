//! Calibration of a serial arm against what a lab measures (`positions.rs`): where a target on the tool was,
//! in an instrument's frame, at configurations given by the controller's joint coordinates, under the arm's
//! own weight and the rows' wrenches; or the tool point's displacement under a wrench. A parallel robot's
//! legs are calibrated by the same routine from positions at commanded poses, its legs' actuators read as
//! the joints (`platform_statics`), its first order completed by its exact loaded equilibrium
//! (`exact.rs`).
//!
//! The set-up is fitted, not blamed: each instrument set-up's frame (a rotation and a translation) and each
//! target's place on the tool are nuisance parameters of every fit. The effects a serial arm can miss are
//! then offered one at a time and kept where the data need them (forward selection by F-tests at
//! alpha / candidates, as the other diagnosis does with its tests):
//! - `joint-offset:J`: the encoder's zero, added to the controller's angle (absolute data only: a
//!   displacement does not see it);
//! - `joint-compliance:J`: a compliance about (along) the joint's axis added to the model's, the joint
//!   turning by it times the load it carries (the links' weight, the payload, the wrench);
//! - `backlash:J`: play that follows the sign of the joint's load, the joint turning by b sign(load).
//!
//! Compliance and backlash act at first order about the model's own loaded equilibrium (the deflections of
//! robots are a thousandth of their reach, so the second order is a millionth). A direction the data cannot
//! see (a vertical first axis makes the base's yaw and joint 1's offset one parameter) is found from the
//! rank of the fit's Jacobian and reported, never fitted. Gross rows (a misfit no plausible model gives,
//! against a median-based scale) are named and left out. Rows marked `check` are never fitted; the report
//! gives the position error of fit and check rows after the registration alone and after each effect.
//!
//! The stages, each a file: the effects' vocabulary (`effect.rs`), what the rows need from the model
//! (`problem.rs`), a row's prediction (`predict.rs`), one fit and its parameters (`fit.rs`, on the shared
//! least-squares driver), a parallel robot's exact completion (`exact.rs`), the selection and the gross rows
//! (`select.rs`), the report and the corrected description (`report.rs`), synthetic data (`synth.rs`) and a
//! plan's signatures (`signatures.rs`); the options, the result and the failures are `options.rs`. This file
//! holds the entry point, `calibrate`, in its steps.

mod effect;
mod exact;
mod fit;
mod options;
mod predict;
mod problem;
mod report;
mod residuals;
mod select;
mod signatures;
mod synth;

pub use effect::{ArmEffect, ArmKind};
pub use options::{Calibration, CalibrationError, CalibrationOptions, Rebuild};
pub use problem::joint_names;
pub use report::{arm_corrections, corrected_model, correction_table, text};
pub use residuals::RowResidual;
pub use signatures::{signatures, Signatures};
pub use synth::{
    configurations, synthesize_leg_positions, synthesize_positions, Configuration, PositionSynth, SynthRow,
};

use fit::PositionFit;
use problem::PositionProblem;
use select::{choose_effects, error_stats, gross_rows, gross_rows_against, nested_test, Screen, Selection};

use std::borrow::Cow;

use super::positions::{Observed, PositionData, PositionRow};
use super::stats::chi2_sf;
use crate::kinematics::frame::{Frame, Vec3};
pub use crate::output::calibration::{
    AcceptedEffect, CalibrationReport, CalibrationVerdict, CandidateTest, ErrorStats, GrossRow, Nuisance, Stage,
};
use crate::platform::manipulator::Manipulator;

/// A parallel robot's rows that give its actuators' readings: each row's pose becomes the rigid robot's at
/// those readings (`Manipulator::pose_at_actuators`), the commanded pose only its start, so that what the
/// controller did not reach is not taken for an effect.
fn at_actuator_readings(m: &Manipulator, data: &PositionData) -> Result<PositionData, CalibrationError> {
    let mut out = data.clone();
    let mut state = m.new_state();
    let mut last: Option<(usize, Frame)> = None;
    for r in &mut out.rows {
        let Some(start) = r.pose.filter(|_| !r.joints.is_empty()) else { continue };
        let pose = match last.filter(|(line, _)| *line == r.line) {
            Some((_, pose)) => pose,
            None => m.pose_at_actuators(&r.joints, &start, &mut state).ok_or_else(|| CalibrationError::Row {
                name: r.name.clone(),
                line: r.line,
                why: "the actuators' readings give no pose near the commanded one (a reading outside the reach, or \
                      far from the commanded pose)"
                    .into(),
            })?,
        };
        last = Some((r.line, pose));
        r.pose = Some(pose);
    }
    Ok(out)
}

/// Calibrates the arm `m` against `data`: registration fitted, effects selected among `candidates` (all
/// of the arm's joints' where empty), gross rows left out, check rows reported.
pub fn calibrate(
    m: &Manipulator,
    data: &PositionData,
    candidates: &[ArmEffect],
    options: &CalibrationOptions,
) -> Result<Calibration, CalibrationError> {
    let prepared = prepared(m, data, options.sigma_rad)?;
    let data = &*prepared;
    let mut problem = PositionProblem::new(m, data, options.sigma, options.sigma_rad)?;
    problem.rebuild = options.rebuild.clone();
    problem.progress = options.progress.clone();
    // No effect at all is offered where none may be selected (a validation: the model as it is).
    let defaulted = candidates.is_empty() && options.max_effects > 0;
    let candidates: Vec<ArmEffect> = match (candidates.is_empty(), options.max_effects) {
        (_, 0) => Vec::new(),
        (true, _) => problem.default_candidates(),
        (false, _) => candidates.to_vec(),
    };
    offered(&problem, &candidates, options)?;
    let sigma_known = data.rows.iter().all(|r| {
        r.sigma.is_some()
            || match r.observed {
                Observed::Orientation { .. } => options.sigma_rad.is_some(),
                _ => options.sigma.is_some(),
            }
    });
    let usable = |r: &usize| !problem.unusable.iter().any(|(k, _)| k == r);
    let fit_rows: Vec<usize> = (0..data.rows.len()).filter(|&r| !data.rows[r].check).filter(usable).collect();
    // A set-up whose frame its fit rows cannot fix is named and its rows kept out of the fit and the verdict:
    // its check rows would be predicted through an arbitrary frame and called gross.
    let mut unplaced = unplaceable_setups(&problem, data, &fit_rows);
    let fit_rows: Vec<usize> = fit_rows.into_iter().filter(|r| placed(data, &unplaced, *r)).collect();
    let (candidates, one_sided) = problem.two_sided_play(candidates, &fit_rows);
    check_fittable(&problem, data, &fit_rows, &unplaced, options)?;
    let (mut kept, selection, screen) = screened_selection(&problem, &fit_rows, &candidates, options, sigma_known)?;
    let (mut gross, mut kept_gross) = (screen.gross, screen.kept_why);
    // A set-up that its gross rows left without enough rows to fix its frame: set aside as well (its
    // unseen directions move none of the rows fitted, so the fit stands; its held-out rows would be
    // predicted through an arbitrary frame).
    for (s, why) in unplaceable_setups(&problem, data, &kept) {
        if !unplaced.iter().any(|(k, _)| *k == s) {
            unplaced.push((s, why.replacen("its fit rows", "its fit rows, without its gross ones,", 1)));
        }
    }
    kept.retain(|r| placed(data, &unplaced, *r));
    gross.retain(|r| placed(data, &unplaced, *r));
    let check_rows: Vec<usize> = (0..data.rows.len())
        .filter(|&r| data.rows[r].check)
        .filter(usable)
        .filter(|r| placed(data, &unplaced, *r))
        .collect();
    let Selection { mut model, mut fit, steps, mut hidden, stopped } = selection;
    hidden.extend(one_sided);
    if problem.absolute {
        offsets_for_geometries(&problem, &kept, &candidates, options, sigma_known, &mut model, &mut fit);
    }
    // The first order completed by the exact equilibrium of the model with the effects built in.
    let fit = problem.fit_exact(&kept, &model, &fit.params).unwrap_or(fit);
    hidden.extend(fit.held.iter().map(|&k| match fit.tied.iter().find(|(t, _)| *t == k) {
        Some((_, d)) => format!(
            "{}: moves with others where no point moves ({}); held at its nominal value (rigid, for a spring), \
             the effect fitted in the directions the rows see",
            problem.parameter_name(k, &model),
            problem.describe_hidden(d, &model)
        ),
        None => format!(
            "{}: fitted below zero, held at zero (a compliance or a play is not negative; rigid there)",
            problem.parameter_name(k, &model)
        ),
    }));
    let residuals = problem.residuals(&model, &fit.params);
    // Held-out rows are judged by the same rule against the fitted rows' scale: a gross one is named and left
    // out of the held-out errors too.
    let Screen { gross: gross_checks, kept_why } = gross_rows_against(&problem, &residuals, &kept, &check_rows);
    kept_gross.extend(kept_why.into_iter().map(|why| format!("held out: {why}")));
    let all_checks = check_rows.clone();
    let check_rows: Vec<usize> = check_rows.into_iter().filter(|r| !gross_checks.contains(r)).collect();
    gross.extend(&gross_checks);
    let scale = (fit.rss / fit.dof() as f64).sqrt();
    let variance = scale * scale;
    let mut accepted = accepted_effects(&problem, &model, &fit, variance);
    let nuisance =
        if problem.absolute { nuisance_values(&problem, data, &fit, variance, &unplaced) } else { Vec::new() };
    // The directions of a set-up set aside are all unseen: said once, by its line in `not_used`.
    hidden.retain(|h| !unplaced.iter().any(|(s, _)| h.contains(&format!("set-up {}'s", data.setups[*s]))));
    let stages = stage_errors(&problem, options, &model, &fit, [&kept, &check_rows, &all_checks]);
    if !check_rows.is_empty() && stages.len() == model.len() - options.fitted.len() + 1 {
        for (k, a) in accepted[options.fitted.len()..].iter_mut().enumerate() {
            a.confirmed = Some(stages[k + 1].check.rms < stages[k].check.rms);
        }
    }
    let noisy = sigma_known && chi2_sf(fit.rss, fit.dof()) < options.alpha;
    let verdict = match (noisy, model.len() > options.fitted.len()) {
        (true, _) => CalibrationVerdict::Unexplained,
        (false, true) => CalibrationVerdict::Effect,
        (false, false) => CalibrationVerdict::None,
    };
    let report = CalibrationReport {
        verdict,
        accepted,
        steps,
        nuisance,
        not_identifiable: hidden,
        left_out: gross_report(data, &gross, &residuals),
        stages,
        unusable: problem.unusable.iter().map(|(_, why)| why.clone()).collect(),
        residual_scale: scale,
        sigma_known,
        rows: (kept.len(), check_rows.len()),
        unread: data.unread.clone(),
        stopped,
        not_used_count: data.not_used.len() + unplaced.len(),
        not_used: data.not_used.iter().cloned().chain(unplaced.iter().map(|(_, why)| why.clone())).collect(),
        notes: data
            .notes
            .iter()
            .cloned()
            .chain(kept_gross)
            .chain(defaulted.then(|| {
                // Where the noise is not given, the weights' units: the fitted rows' scale divides them.
                let held_out = held_out_scale(&problem, &residuals, &check_rows);
                not_offered(&problem, held_out.map(|v| if sigma_known { v } else { v / scale }), sigma_known)
            }))
            .collect(),
    };
    let leg_corrections = problem
        .space
        .is_none()
        .then(|| model.iter().zip(&fit.params.effects).map(|(e, values)| problem.model_form(e, values)).collect());
    let base = problem.in_base_axes(&residuals, &fit.params);
    let rows = residuals::row_residuals(data, &residuals, &base, &problem.unusable, &gross, &unplaced);
    Ok(Calibration { report, effects: model, values: fit.params.effects.clone(), leg_corrections, rows })
}

/// The data as the fit reads them: a parallel robot's rows at the pose its actuators' readings give, each
/// row's payload weighed into its load, and orientations without a standard deviation left out; borrowed
/// where none of these changes them.
fn prepared<'d>(
    m: &Manipulator,
    data: &'d PositionData,
    sigma_rad: Option<f64>,
) -> Result<Cow<'d, PositionData>, CalibrationError> {
    let mut data = Cow::Borrowed(data);
    if m.joint_space.is_none() && data.rows.iter().any(|r| !r.joints.is_empty()) {
        data = Cow::Owned(at_actuator_readings(m, &data)?);
    }
    if data.rows.iter().any(|r| r.payload.is_some()) {
        data = Cow::Owned(data.with_payload_weights(m));
    }
    let stripped = match data.without_unweighted_orientations(sigma_rad) {
        Cow::Owned(d) => Some(d),
        Cow::Borrowed(_) => None,
    };
    if let Some(d) = stripped {
        data = Cow::Owned(d);
    }
    Ok(data)
}

/// Every effect named (`candidates`, `options.fitted`) is one the robot can have.
fn offered(
    problem: &PositionProblem,
    candidates: &[ArmEffect],
    options: &CalibrationOptions,
) -> Result<(), CalibrationError> {
    if let Some(e) = candidates.iter().chain(&options.fitted).find(|e| !problem.offers(e)) {
        return Err(CalibrationError::NotOffered(format!(
            "{}: {}",
            e.label(&problem.joints),
            if problem.space.is_some() {
                "a serial arm has no such effect"
            } else {
                "a parallel robot's legs are calibrated by joint-offset, joint-compliance and backlash of their \
                 actuators, joint-geometry (the leg's end-point error), payload, tool-compliance and drift; a \
                 compliance at a frame is a serial arm's (for a leg's links, diagnose displacements under load: \
                 link-compliance)"
            }
        )));
    }
    Ok(())
}

/// Row `r` is not of a set-up set aside as one that cannot be placed (`unplaced`).
fn placed(data: &PositionData, unplaced: &[(usize, String)], r: usize) -> bool {
    data.rows[r].observed.target_and_setup().is_none_or(|(_, setup)| !unplaced.iter().any(|(s, _)| *s == setup))
}

/// The fitted rows can fit what every fit fits: each set-up and target seen, more coordinates than the
/// registration's and the fixed effects' parameters.
/// The set-ups whose frame the fit rows cannot fix, with why: fewer than three configurations measured in
/// position (two, where an orientation is measured too) leave some of its six parameters unseen; so do rows
/// all at one tool orientation along one line (the turn about the line moves none of them). None where no
/// set-up could be placed (the data are then too few as a whole, said as such).
fn unplaceable_setups(problem: &PositionProblem, data: &PositionData, fit_rows: &[usize]) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let frame = |r: &usize| problem.statics[*r].0.frame;
    // Two tool orientations within this (rad) are one: a translational robot's, or an arm's at one pose.
    const SAME_TURN: f64 = 1e-9;
    let turn_between = |a: &usize, b: &usize| {
        crate::kinematics::frame::rotation_vector(&(frame(a).rot.transpose() * frame(b).rot)).norm()
    };
    for (k, name) in data.setups.iter().enumerate() {
        let named = if name.is_empty() { "the set-up".to_string() } else { format!("set-up `{name}`") };
        let own: Vec<usize> = fit_rows
            .iter()
            .copied()
            .filter(|&r| matches!(data.rows[r].observed, Observed::Position { setup, .. } if setup == k))
            .collect();
        let all = data.rows.iter().filter(|r| r.observed.target_and_setup().is_some_and(|(_, s)| s == k)).count();
        let oriented = fit_rows
            .iter()
            .any(|&r| matches!(data.rows[r].observed, Observed::Orientation { setup, .. } if setup == k));
        let configurations =
            own.iter().map(|&r| data.rows[r].configuration).collect::<std::collections::BTreeSet<_>>().len();
        // Too few configurations is said by the count (below).
        let one_turn = !own.is_empty() && own.iter().all(|r| turn_between(&own[0], r) <= SAME_TURN);
        if oriented || !one_turn || configurations < 3 {
            continue;
        }
        // At one orientation the rows' points are the reference points moved by one lever: collinear
        // reference points, collinear measured points.
        let points: Vec<Vec3> = own.iter().map(|r| frame(r).pos).collect();
        let centre = points.iter().fold(Vec3::zeros(), |a, p| a + p) / points.len() as f64;
        let scatter = points
            .iter()
            .fold(crate::kinematics::frame::Mat3::zeros(), |a, p| a + (p - centre) * (p - centre).transpose());
        // The scatter's eigenvalues are squared lengths: the middle one within 1e-12 of the largest is a
        // point 1 um off a line of 1 m (the eigenvalues' own round-off is 1e-16 of the largest).
        let Some(spread) = crate::platform::compliance::symmetric_eigenvalues3(&scatter) else { continue };
        if spread[1] <= 1e-12 * spread[2] {
            out.push((
                k,
                format!("{named} cannot be placed: its fit rows lie on one line at one tool orientation (a turn about the line moves none of them); its {all} rows are left out of the fit and the verdict"),
            ));
        }
    }
    for (k, name) in data.setups.iter().enumerate() {
        if out.iter().any(|(s, _)| *s == k) {
            continue;
        }
        let rows: Vec<&PositionRow> = fit_rows
            .iter()
            .map(|&r| &data.rows[r])
            .filter(|r| r.observed.target_and_setup().is_some_and(|(_, s)| s == k))
            .collect();
        let mut configurations: Vec<usize> = rows.iter().map(|r| r.configuration).collect();
        configurations.sort_unstable();
        configurations.dedup();
        let oriented = rows.iter().any(|r| matches!(r.observed, Observed::Orientation { .. }));
        let needed = if oriented { 2 } else { 3 };
        // A set-up with no fit row at all is refused with its own message (`check_fittable`).
        if !rows.is_empty() && configurations.len() < needed {
            let named = if name.is_empty() { "the set-up".to_string() } else { format!("set-up `{name}`") };
            let all = data.rows.iter().filter(|r| r.observed.target_and_setup().is_some_and(|(_, s)| s == k)).count();
            out.push((
                k,
                format!(
                    "{named} cannot be placed: its fit rows measure {} configuration{} ({needed} are needed to fix its frame{}); its {all} rows are left out of the fit and the verdict",
                    configurations.len(),
                    if configurations.len() == 1 { "" } else { "s" },
                    if oriented { " with an orientation" } else { ", or 2 with an orientation" }
                ),
            ));
        }
    }
    // Where no set-up can be placed the whole fit is short of rows: `check_fittable` and the fit say how many
    // coordinates there are against how many parameters.
    let with_rows = (0..data.setups.len())
        .filter(|&k| fit_rows.iter().any(|&r| data.rows[r].observed.target_and_setup().is_some_and(|(_, s)| s == k)))
        .count();
    if out.len() == with_rows {
        out.clear();
    }
    out
}

fn check_fittable(
    problem: &PositionProblem,
    data: &PositionData,
    fit_rows: &[usize],
    unplaced: &[(usize, String)],
    options: &CalibrationOptions,
) -> Result<(), CalibrationError> {
    if fit_rows.is_empty() {
        let why: Vec<String> = problem.unusable.iter().map(|(_, why)| why.clone()).collect();
        return Err(CalibrationError::TooFew(format!(
            "no row to fit: every row is held out (set = check) or has no prediction{}",
            if why.is_empty() { String::new() } else { format!(" ({})", why.join("; ")) }
        )));
    }
    // A set-up or target seen only in held-out rows has no registration or place to predict them with.
    for (names, what, of) in [
        (
            &data.setups,
            "set-up",
            (|o: &Observed| o.target_and_setup().map(|(_, setup)| setup)) as fn(&Observed) -> Option<usize>,
        ),
        (&data.targets, "target", |o: &Observed| o.target_and_setup().map(|(target, _)| target)),
    ] {
        for (k, name) in names.iter().enumerate() {
            let set_aside = what == "set-up" && unplaced.iter().any(|(s, _)| *s == k);
            if !set_aside && !fit_rows.iter().any(|&r| of(&data.rows[r].observed) == Some(k)) {
                let named = if name.is_empty() { format!("the {what}") } else { format!("{what} `{name}`") };
                return Err(CalibrationError::TooFew(format!(
                    "{named} has no fitted rows (only check rows, or rows without a prediction): its {} cannot be fitted; mark some of its rows `fit`",
                    if what == "set-up" { "frame" } else { "place on the tool" }
                )));
            }
        }
    }
    let p = problem.nuisance_count() + options.fitted.iter().map(ArmEffect::size).sum::<usize>();
    if 3 * fit_rows.len() <= p {
        return Err(CalibrationError::TooFew(format!(
            "{} fitted rows give {} coordinates, too few for the {p} parameters of the registration and the effects fitted",
            fit_rows.len(),
            3 * fit_rows.len()
        )));
    }
    Ok(())
}

/// The selection on the fitted rows without their gross ones, and the gross rows: screened against the
/// registration alone (a fit that gross rows pull is screened again), then against the model selected,
/// until the set stops changing. Returns the rows kept, the selection and the gross rows.
fn screened_selection(
    problem: &PositionProblem,
    fit_rows: &[usize],
    candidates: &[ArmEffect],
    options: &CalibrationOptions,
    sigma_known: bool,
) -> Result<(Vec<usize>, Selection, Screen), CalibrationError> {
    let mut screen = Screen::default();
    for _ in 0..3 {
        let kept: Vec<usize> = fit_rows.iter().filter(|r| !screen.gross.contains(r)).copied().collect();
        let start = problem.start(&kept, &options.fitted);
        let Some(f) = problem.fit(&kept, &options.fitted, &start) else { break };
        let next = gross_rows(problem, &problem.residuals(&options.fitted, &f.params), fit_rows);
        let settled = next.gross == screen.gross;
        screen = next;
        if settled {
            break;
        }
    }
    let mut outcome = None;
    for _ in 0..3 {
        let kept: Vec<usize> = fit_rows.iter().filter(|r| !screen.gross.contains(r)).copied().collect();
        let selection = choose_effects(problem, &kept, candidates, options, sigma_known)?;
        let next = gross_rows(problem, &problem.residuals(&selection.model, &selection.fit.params), fit_rows);
        let settled = next.gross == screen.gross;
        outcome = Some((kept, selection));
        screen = next;
        if settled {
            break;
        }
    }
    let (kept, selection) = outcome.expect("at least one selection");
    Ok((kept, selection, screen))
}

/// A joint's geometry holds its offset (a leg's end-point error along its actuator, an arm joint's turn
/// about its own axis). Chosen while other effects were still missing, or with a parallel robot's offset
/// at first order (an offset of 0.5 mm leaves 1 um of second order, which a geometry's other directions
/// absorb), it may stand in for the offset alone: where the offset, each fitted exactly, explains the data
/// as well (the geometry's other directions do not pass at alpha), the offset is kept instead.
fn offsets_for_geometries(
    problem: &PositionProblem,
    kept: &[usize],
    candidates: &[ArmEffect],
    options: &CalibrationOptions,
    sigma_known: bool,
    model: &mut Vec<ArmEffect>,
    fit: &mut PositionFit,
) {
    for k in options.fitted.len()..model.len() {
        let offset = ArmEffect { kind: ArmKind::JointOffset, joint: model[k].joint };
        if model[k].kind != ArmKind::JointGeometry || model.contains(&offset) || !candidates.contains(&offset) {
            continue;
        }
        let mut simpler = model.clone();
        simpler[k] = offset;
        let mut start = fit.params.clone();
        start.effects[k] = vec![0.0];
        let (Some(with_offset), Some(with_geometry)) =
            (problem.fit_exact(kept, &simpler, &start), problem.fit_exact(kept, model, &fit.params))
        else {
            continue;
        };
        let (_, p) = nested_test(with_offset.rss, with_offset.rank, &with_geometry, sigma_known);
        if with_offset.rank > with_geometry.rank.saturating_sub(model[k].size()) && p >= options.alpha {
            *model = simpler;
            *fit = with_offset;
        }
    }
}

/// The effects of `model` with their values and standard errors (none for a direction the data cannot see),
/// as the report gives them.
fn accepted_effects(
    problem: &PositionProblem,
    model: &[ArmEffect],
    fit: &PositionFit,
    variance: f64,
) -> Vec<AcceptedEffect> {
    // A parameter in a direction the data cannot see has no standard error.
    let seen = |k: usize| fit.sees(k) && !fit.held.contains(&k);
    let mut k = problem.nuisance_count();
    let mut accepted = Vec::new();
    for (i, e) in model.iter().enumerate() {
        let mut values = fit.params.effects[i].clone();
        let mut se: Vec<f64> = (k..k + e.size())
            .map(|j| if seen(j) { (fit.covariance[(j, j)] * variance).sqrt() } else { f64::NAN })
            .collect();
        if e.kind == ArmKind::Payload {
            // Fitted as (m, m c), linear in the sag; reported as the text prints it, (m, c), the centre's
            // variance propagated through c = s / m: (var s - 2 c cov(s, m) + c^2 var m) / m^2.
            let m = values[0];
            for a in 1..4 {
                let c = values[a] / m;
                let cov = |x: usize, y: usize| fit.covariance[(k + x, k + y)] * variance;
                let var = (cov(a, a) - 2.0 * c * cov(a, 0) + c * c * cov(0, 0)) / (m * m);
                se[a] = if se[a].is_finite() && se[0].is_finite() { var.max(0.0).sqrt() } else { f64::NAN };
                values[a] = c;
            }
        }
        k += e.size();
        accepted.push(AcceptedEffect {
            label: e.label(&problem.joints),
            kind: e.kind.name().to_string(),
            joint: match e.kind {
                ArmKind::Payload | ArmKind::Drift | ArmKind::ToolCompliance => String::new(),
                _ => problem.joints[e.joint].clone(),
            },
            shown: problem.shown(e, &values, &se),
            values,
            se,
            confirmed: None,
        });
    }
    accepted
}

/// The registration's and targets' fitted values (mm, mrad) with their standard errors.
/// The set-ups in `unplaced` (no rows fitted: their frames unseen) are left out.
fn nuisance_values(
    problem: &PositionProblem,
    data: &PositionData,
    fit: &PositionFit,
    variance: f64,
    unplaced: &[(usize, String)],
) -> Vec<Nuisance> {
    // A component in a direction the data do not see has no standard error (NaN: `not seen`): the fit kept
    // its start there (the tool point for a target, Kabsch's registration for a set-up), and the
    // combinations are named under not identifiable.
    let se3 = |k: usize, factor: f64| {
        [0, 1, 2].map(|a| match fit.sees(k + a) {
            true => (fit.covariance[(k + a, k + a)] * variance).sqrt() * factor,
            false => f64::NAN,
        })
    };
    let mut nuisance = Vec::new();
    for (s, name) in data.setups.iter().enumerate() {
        if unplaced.iter().any(|(u, _)| *u == s) {
            continue;
        }
        let label = if name.is_empty() { "instrument".to_string() } else { format!("set-up {name}") };
        let rotation = crate::kinematics::frame::rotation_vector(&fit.params.rotations[s]);
        nuisance.push(Nuisance {
            name: format!("{label}: translation, mm"),
            value: fit.params.translations[s].into(),
            se: se3(6 * s, 1.0),
        });
        nuisance.push(Nuisance {
            name: format!("{label}: rotation vector, mrad"),
            value: (rotation * 1e3).into(),
            se: se3(6 * s + 3, 1e3),
        });
    }
    for (t, name) in data.targets.iter().enumerate() {
        let label = if name.is_empty() { "target".to_string() } else { format!("target {name}") };
        nuisance.push(Nuisance {
            name: format!("{label}: place in the tool frame, mm"),
            value: fit.params.targets[t].into(),
            se: se3(6 * data.setups.len() + 3 * t, 1.0),
        });
        if let Some(k) = problem.turn_parameter(t) {
            let turn = crate::kinematics::frame::rotation_vector(&fit.params.turns[t]);
            nuisance.push(Nuisance {
                name: format!("{label}: axes in the tool frame, rotation vector, mrad"),
                value: (turn * 1e3).into(),
                se: se3(k, 1e3),
            });
        }
    }
    nuisance
}

/// The errors after the registration alone, then after each effect in the order accepted, of the rows
/// `[fitted, held out, held out with their gross ones]`.
fn stage_errors(
    problem: &PositionProblem,
    options: &CalibrationOptions,
    model: &[ArmEffect],
    fit: &PositionFit,
    [kept, check_rows, all_checks]: [&[usize]; 3],
) -> Vec<Stage> {
    let data = problem.data;
    // The rows of `rows` that are orientations (`turning`) or positions and displacements.
    let only = |rows: &[usize], turning: bool| -> Vec<usize> {
        rows.iter().copied().filter(|&k| data.rows[k].observed.is_orientation() == turning).collect()
    };
    let oriented = data.rows.iter().any(|r| r.observed.is_orientation());
    // Errors after the registration alone, then after each effect in the order accepted.
    let mut stages = Vec::new();
    let registration: Vec<ArmEffect> = options.fitted.clone();
    let mut staged = registration.clone();
    let order: Vec<ArmEffect> = model[options.fitted.len()..].to_vec();
    for k in 0..=order.len() {
        if k > 0 {
            staged.push(order[k - 1]);
        }
        let label = if k == 0 {
            let first = if problem.absolute { "registration" } else { "model" };
            match options.fitted.len() {
                0 => first.to_string(),
                n => format!("{first} + {n} fitted"),
            }
        } else {
            format!("+ {}", order[k - 1].label(&problem.joints))
        };
        let f = if k == order.len() {
            Some(fit.clone())
        } else {
            problem.fit_exact(kept, &staged, &problem.start(kept, &staged))
        };
        let Some(f) = f else { continue };
        let r = problem.residuals(&staged, &f.params);
        let base = problem.in_base_axes(&r, &f.params);
        let in_mrad: Vec<Option<Vec3>> = r.iter().map(|v| v.map(|v| v * 1e3)).collect();
        stages.push(Stage {
            model: label,
            parameters: f.rank,
            fit: error_stats(&r, Some(&base), &only(kept, false)),
            check: error_stats(&r, Some(&base), &only(check_rows, false)),
            check_all: error_stats(&r, Some(&base), &only(all_checks, false)),
            orientation: oriented.then(|| {
                [error_stats(&in_mrad, None, &only(kept, true)), error_stats(&in_mrad, None, &only(check_rows, true))]
            }),
        });
    }
    stages
}

/// The gross rows as the report names them, with their misfit against the model selected.
fn gross_report(data: &PositionData, gross: &[usize], residuals: &[Option<Vec3>]) -> Vec<GrossRow> {
    gross
        .iter()
        .map(|&r| {
            let turning = data.rows[r].observed.is_orientation();
            GrossRow {
                row: format!(
                    "{} (line {}{}{})",
                    data.rows[r].name,
                    data.rows[r].line,
                    if data.rows[r].check { ", held out" } else { "" },
                    if turning { ", orientation" } else { "" }
                ),
                misfit: residuals[r].map_or(f64::NAN, |v| v.norm()) * if turning { 1e3 } else { 1.0 },
                unit: if turning { "mrad" } else { "mm" }.to_string(),
            }
        })
        .collect()
}

/// What the default candidates leave out, said where they were offered: the effects a user names with
/// `--candidates` to test them (the held-out rows' errors against the noise say whether something is left).
fn not_offered(problem: &PositionProblem, held_out: Option<f64>, sigma_known: bool) -> String {
    let kinds = match (problem.space.is_some(), problem.absolute) {
        (true, true) => "frame-compliance at each joint (a link, column or mounting bending), drift and tool-compliance",
        (true, false) => "joint-offset, joint-geometry and payload (displacements do not see them), frame-compliance, drift and tool-compliance",
        (false, _) => "joint-geometry of each leg (its end-point error), drift and tool-compliance",
    };
    // What the held-out rows leave, against the noise: above it, something the candidates offered did not
    // name (one of those left out, or another).
    let left = match (held_out, sigma_known) {
        (Some(v), true) => format!("; held out, the model leaves {v:.3} sigma per coordinate (1 at the noise)"),
        (Some(v), false) => {
            format!("; held out, the model leaves {v:.3} sigma per coordinate of the fitted rows' scale")
        }
        (None, _) => String::new(),
    };
    format!(
        "not offered by default: {kinds}; name them with --candidates to test them (the held-out rows' errors \
         below, against the noise, say whether the model leaves something){left}"
    )
}

/// The held-out rows' weighted residual, RMS per coordinate (in sigma where the noise is known); None
/// without held-out rows.
fn held_out_scale(problem: &PositionProblem, residuals: &[Option<Vec3>], rows: &[usize]) -> Option<f64> {
    let weighted: Vec<f64> =
        rows.iter().filter_map(|&r| residuals[r].map(|v| v.norm_squared() * problem.weight[r].powi(2))).collect();
    (!weighted.is_empty()).then(|| (weighted.iter().sum::<f64>() / (3 * weighted.len()) as f64).sqrt())
}
