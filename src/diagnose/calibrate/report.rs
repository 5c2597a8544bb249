//! A calibration as its reader sees it: the parameters named, the values in the units a user reads, the
//! text report, and the corrected description (`corrected_model`) with what was found as
//! `[[joint_correction]]`, `[[payload]]` and the leg tables.

use super::effect::{ArmEffect, ArmKind};
use super::options::Calibration;
use super::problem::PositionProblem;
use crate::output::calibration::{AcceptedEffect, CalibrationReport, CandidateTest, ErrorStats, Stage};

impl PositionProblem<'_> {
    /// The name of parameter `k` of a fit with `effects`.
    pub(super) fn parameter_name(&self, k: usize, effects: &[ArmEffect]) -> String {
        let setups = if self.absolute { self.data.setups.len() } else { 0 };
        let axis = ["x", "y", "z"];
        let setup_name = |s: usize| match self.data.setups[s].as_str() {
            "" => "the instrument".to_string(),
            name => format!("set-up {name}"),
        };
        if k < 6 * setups {
            let (s, a) = (k / 6, k % 6);
            return if a < 3 {
                format!("{}'s translation {}", setup_name(s), axis[a])
            } else {
                format!("{}'s rotation about {}", setup_name(s), axis[a - 3])
            };
        }
        let k = k - 6 * setups;
        let targets = if self.absolute { self.data.targets.len() } else { 0 };
        let target_name = |t: usize| match self.data.targets[t].as_str() {
            "" => "the target".to_string(),
            t => format!("target {t}"),
        };
        if k < 3 * targets {
            return format!("{}'s place {}", target_name(k / 3), axis[k % 3]);
        }
        let k = k - 3 * targets;
        let turns = if self.absolute { self.turn_count() } else { 0 };
        if k < 3 * turns {
            let t = self.turn_of.iter().position(|&o| o == Some(k / 3)).expect("a turn's target");
            return format!("{}'s turn about the tool's {}", target_name(t), axis[k % 3]);
        }
        let mut k = k - 3 * turns;
        for e in effects {
            if k < e.size() {
                let part = match e.kind {
                    ArmKind::JointGeometry => {
                        let what = [
                            "translation x",
                            "translation y",
                            "translation z",
                            "rotation x",
                            "rotation y",
                            "rotation z",
                        ];
                        format!(" {}", what[k])
                    }
                    ArmKind::Payload => [" mass", " moment x", " moment y", " moment z"][k].to_string(),
                    ArmKind::FrameCompliance => {
                        let what = ["along x", "along y", "along z", "about x", "about y", "about z"];
                        format!(" {}", what[k])
                    }
                    ArmKind::Drift => [" x", " y", " z"][k].to_string(),
                    ArmKind::ToolCompliance => [" along x", " along y", " along z"][k].to_string(),
                    _ => String::new(),
                };
                return format!("{}{part}", e.label(&self.joints));
            }
            k -= e.size();
        }
        "?".into()
    }

    pub(super) fn describe_hidden(&self, direction: &[(usize, f64)], effects: &[ArmEffect]) -> String {
        direction
            .iter()
            .map(|(k, w)| format!("{w:+.3} {}", self.parameter_name(*k, effects)))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The value of an accepted effect as a user reads it.
    pub(super) fn shown(&self, e: &ArmEffect, values: &[f64], ses: &[f64]) -> String {
        let prismatic = self.prismatic[e.joint];
        let (value, se) = (values[0], ses[0]);
        let listed = |values: &[f64], ses: &[f64], scale: f64, digits: usize| {
            let part = |v: f64, s: f64| {
                let number = |x: f64| if x.abs() < 1e6 { format!("{x:.digits$}") } else { format!("{x:.3e}") };
                if s.is_finite() {
                    format!("{} +- {}", number(v * scale), number(s * scale))
                } else {
                    format!("{} (not seen)", number(v * scale))
                }
            };
            values.iter().zip(ses).map(|(v, s)| part(*v, *s)).collect::<Vec<_>>().join(", ")
        };
        match e.kind {
            ArmKind::JointGeometry if self.space.is_none() => format!(
                "the leg's end-point error: translation ({}) mm, rotation ({}) mrad, base axes at the reference point",
                listed(&values[..3], &ses[..3], 1.0, 4),
                listed(&values[3..], &ses[3..], 1e3, 3)
            ),
            ArmKind::JointGeometry => format!(
                "translation ({}) mm, rotation ({}) mrad, in the joint's frame",
                listed(&values[..3], &ses[..3], 1.0, 4),
                listed(&values[3..], &ses[3..], 1e3, 3)
            ),
            ArmKind::Drift => format!("({}) um per row, along the base's x, y, z", listed(values, ses, 1e3, 4)),
            ArmKind::ToolCompliance => {
                format!("({}) um/N along the tool frame's x, y, z", listed(values, ses, 1e3, 4))
            }
            ArmKind::FrameCompliance => format!(
                "compliance along the frame's axes ({}) um/N, about them ({}) urad/(N m)",
                listed(&values[..3], &ses[..3], 1e3, 4),
                listed(&values[3..], &ses[3..], 1e9, 4)
            ),
            // Given as (m, c), its centre in the tool frame (`accepted_effects`).
            ArmKind::Payload => format!(
                "{} kg at ({}) mm in the tool frame",
                listed(&values[..1], &ses[..1], 1.0, 3),
                listed(&values[1..], &ses[1..], 1.0, 1)
            ),
            ArmKind::JointOffset | ArmKind::Backlash if prismatic => format!("{} mm", listed(values, ses, 1.0, 4)),
            ArmKind::JointOffset | ArmKind::Backlash => format!("{} mrad", listed(values, ses, 1e3, 3)),
            ArmKind::JointCompliance => {
                let (unit, stiffness_unit, to_user) =
                    if prismatic { ("mm/N", "N/mm", 1.0) } else { ("rad/(N m)", "N m/rad", 1e3) };
                // Scientific notation with the standard error where the data see the value.
                let pm = |v: f64, s: f64, digits: usize| {
                    if s.is_finite() {
                        format!("{v:.digits$e} +- {s:.digits$e}")
                    } else {
                        format!("{v:.digits$e} (not seen)")
                    }
                };
                let added = format!("added compliance {} {unit}", pm(value * to_user, se * to_user, 4));
                match self.nominal_compliance(e.joint) {
                    Some(nominal) => {
                        let total = nominal + value;
                        format!(
                            "{added}: stiffness {} {stiffness_unit} (the model's {:.4e}; factor {} on its compliance)",
                            pm(1.0 / (total * to_user), se / (total * total * to_user), 4),
                            1.0 / (nominal * to_user),
                            listed(&[total / nominal], &[se / nominal], 1.0, 3)
                        )
                    }
                    None => {
                        let k = 1.0 / (value * to_user);
                        format!("{added}: stiffness {k:.4e} {stiffness_unit} (the model has it rigid)")
                    }
                }
            }
        }
    }
}

/// The description (`source`, read from `model_dir`) with the calibration's corrections added, so that every
/// study of the corrected file sees them: a serial arm's as `arm_corrections` writes them (the text the fit
/// rebuilt the arm from, so the file reproduces the fit), a parallel robot's as leg tables; what no
/// description holds (a drift, a tool's spring) as a comment saying so. An effect the held-out rows do
/// not confirm (their RMS error grows with it) is left out, as a comment, unless `unconfirmed` asks for it.
pub fn corrected_model(
    source: &str,
    model_dir: &std::path::Path,
    written_dir: Option<&std::path::Path>,
    c: &Calibration,
    unconfirmed: bool,
) -> String {
    use std::fmt::Write;
    let mut out = crate::diagnose::report::with_references(source, model_dir, written_dir);
    let report = &c.report;
    let kept: Vec<usize> =
        (0..report.accepted.len()).filter(|&k| unconfirmed || report.accepted[k].confirmed != Some(false)).collect();
    let _ = writeln!(
        out,
        "\n# Added by stiff diagnose (calibration, verdict {}): {}",
        report.verdict.as_str(),
        if kept.is_empty() {
            "no effect".to_string()
        } else {
            kept.iter().map(|&k| report.accepted[k].label.clone()).collect::<Vec<_>>().join(", ")
        }
    );
    for a in report.accepted.iter().filter(|a| !unconfirmed && a.confirmed == Some(false)) {
        let _ = writeln!(
            out,
            "\n# {}: {} (not written: the held-out rows do not confirm it, their RMS error grows with it; \
             --write-unconfirmed writes it)",
            a.label, a.shown
        );
    }
    if let Some(legs) = &c.leg_corrections {
        for &k in &kept {
            match &legs[k] {
                Some(effect) => crate::diagnose::report::write_correction(&mut out, effect),
                None => out.push_str(&leg_not_written(&report.accepted[k], c.effects[k].kind)),
            }
        }
        return out;
    }
    for &k in &kept {
        let Some(why) = not_written(c.effects[k].kind) else { continue };
        let a = &report.accepted[k];
        let _ = writeln!(out, "\n# {}: {} (not written: {why})", a.label, a.shown);
    }
    let accepted: Vec<&AcceptedEffect> = kept.iter().map(|&k| &report.accepted[k]).collect();
    let effects: Vec<ArmEffect> = kept.iter().map(|&k| c.effects[k]).collect();
    let values: Vec<Vec<f64>> = kept.iter().map(|&k| c.values[k].clone()).collect();
    let seen: Vec<Vec<bool>> = accepted.iter().map(|a| a.se.iter().map(|s| s.is_finite()).collect()).collect();
    let joints: Vec<String> = accepted.iter().map(|a| a.joint.clone()).collect();
    out.push_str(&arm_corrections(&effects, &values, &seen, &joints));
    out
}

/// Why a description cannot hold a serial arm's effect of this kind; None for the kinds `arm_corrections`
/// writes.
pub(super) fn not_written(kind: ArmKind) -> Option<&'static str> {
    match kind {
        ArmKind::Drift => Some("a drift belongs to the measurements, not the robot"),
        ArmKind::ToolCompliance => Some("a description of a URDF arm holds no spring at its tool yet"),
        ArmKind::JointOffset
        | ArmKind::JointCompliance
        | ArmKind::JointGeometry
        | ArmKind::Payload
        | ArmKind::FrameCompliance
        | ArmKind::Backlash => None,
    }
}

/// A serial arm's effects (`effects` at `values`, each on joint `joints[k]`) as the tables a description
/// holds: offsets, compliances, geometries and frame compliances as `[[joint_correction]]`, a payload as
/// `[[payload]]`, a play as `[[joint_correction]] play`; nothing for the effects no description holds (a
/// drift, a tool's spring). A frame
/// compliance's direction the data did not see (`seen` false: the fit's number there is its smallest change,
/// 31 mm/N or 1e20 as it fell) or whose value is below zero is written rigid, as the description had it.
/// The fit rebuilds the arm from this text (`CalibrationOptions::rebuild`), and `--model-out` appends it.
pub fn arm_corrections(effects: &[ArmEffect], values: &[Vec<f64>], seen: &[Vec<bool>], joints: &[String]) -> String {
    let mut out = String::new();
    for (k, e) in effects.iter().enumerate() {
        let values = match e.kind {
            ArmKind::FrameCompliance => values[k]
                .iter()
                .zip(seen[k].iter().chain(std::iter::repeat(&true)))
                .map(|(v, seen)| if *seen && *v > 0.0 { *v } else { 0.0 })
                .collect(),
            _ => values[k].clone(),
        };
        out.push_str(&correction_table(e.kind, &joints[k], &values));
    }
    out
}

/// A parallel robot's accepted effect that no description holds (`model_form` gives none), as a comment
/// saying why it is not written.
pub(super) fn leg_not_written(a: &AcceptedEffect, kind: ArmKind) -> String {
    let why = match kind {
        ArmKind::JointCompliance => {
            "the leg's actuator has no spring to scale, or its compliance would fall below zero"
        }
        ArmKind::Payload => "a payload's mass must be above zero",
        ArmKind::JointGeometry => "a description holds no leg's end-point error; stiff assemble takes it",
        ArmKind::Backlash => "a description holds no play of a leg's actuator yet",
        ArmKind::Drift => "a drift belongs to the measurements, not the robot",
        _ => "a description holds no spring there",
    };
    format!("\n# {}: {} (not written: {why})\n", a.label, a.shown)
}

/// One effect as the description's table: `[[joint_correction]]` for an offset, compliance, geometry or
/// frame compliance or play, `[[payload]]` for a payload (`values` its mass and first moment in the tool
/// frame). A play below zero (the fit holds none there, but a value given is written as it is read) is
/// written as none.
pub fn correction_table(kind: ArmKind, joint: &str, values: &[f64]) -> String {
    let list = |v: &[f64]| v.iter().map(|x| format!("{x:?}")).collect::<Vec<_>>().join(", ");
    match kind {
        ArmKind::JointOffset => format!("\n[[joint_correction]]\njoint = {joint:?}\noffset = {:?}\n", values[0]),
        ArmKind::JointCompliance => format!("\n[[joint_correction]]\njoint = {joint:?}\ncompliance = {:?}\n", values[0]),
        ArmKind::JointGeometry => format!(
            "\n# A direction the data did not see: zero where it moved with others (the set-up), else the fit's smallest change.\n[[joint_correction]]\njoint = {joint:?}\ngeometry = [{}]\n",
            list(values)
        ),
        ArmKind::Payload => {
            let centre: Vec<f64> = values[1..].iter().map(|s| s / values[0]).collect();
            format!("\n[[payload]]\nmass_kg = {:?}\ncentre = [{}]\n", values[0], list(&centre))
        }
        ArmKind::FrameCompliance => {
            format!("\n[[joint_correction]]\njoint = {joint:?}\nframe_compliance = [{}]\n", list(values))
        }
        ArmKind::Backlash => {
            format!("\n[[joint_correction]]\njoint = {joint:?}\nplay = {:?}\n", values[0].max(0.0))
        }
        ArmKind::Drift | ArmKind::ToolCompliance => String::new(),
    }
}

/// The calibration as text: the verdict, the effects with values, the registration, what could not be
/// seen, the gross rows, and the errors of fit and check rows per stage.
pub fn text(c: &CalibrationReport, model: &str) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let verdict = c.verdict.as_str();
    let _ = writeln!(s, "Calibration of {model}: {} rows fitted, {} held out", c.rows.0, c.rows.1);
    if let Some(last) = c.stages.last() {
        if let Some([fit, check]) = &last.orientation {
            let _ = writeln!(
                s,
                "  (each a position or an orientation: {} and {} fitted, {} and {} held out, gross rows left out)",
                last.fit.rows, fit.rows, last.check.rows, check.rows
            );
        }
    }
    if !c.unread.is_empty() {
        let _ = writeln!(s, "columns not read (no rule uses them): {}", c.unread.join(", "));
    }
    let _ = writeln!(s, "verdict: {verdict}");
    if c.accepted.is_empty() {
        let _ = writeln!(s, "effects: none needed");
    }
    for a in &c.accepted {
        let held_out = match a.confirmed {
            Some(true) => "; the held-out rows confirm it (their RMS error falls)",
            Some(false) => "; NOT confirmed: the held-out rows' RMS error grows with it",
            None => "",
        };
        let _ = writeln!(s, "effect: {}: {}{held_out}", a.label, a.shown);
    }
    let _ = writeln!(
        s,
        "residual: {:.4} {} per coordinate after the fit{}",
        c.residual_scale,
        if c.sigma_known { "sigma" } else { "mm" },
        if c.sigma_known { "" } else { " (the noise level was not given: no test of what is left)" }
    );
    for n in &c.nuisance {
        let se = n.se.map(|e| if e.is_nan() { "not-seen".to_string() } else { format!("{e:.2e}") });
        let unseen = if n.se.iter().any(|e| e.is_nan()) {
            "; not-seen: it moves with others in a combination no row sees, named under not identifiable, \
             along which the fit kept its start: the tool point for a target, the nominal points' \
             registration for a set-up"
        } else {
            ""
        };
        let _ = writeln!(
            s,
            "fitted {}: {:.4} {:.4} {:.4} (+- {} {} {}{unseen})",
            n.name, n.value[0], n.value[1], n.value[2], se[0], se[1], se[2]
        );
    }
    for h in &c.not_identifiable {
        // A value no robot has (held at zero, or a candidate refused for it) is not a question of the data.
        let physical = h.contains("held at zero") || h.contains(": not accepted:");
        let _ = writeln!(s, "{}: {h}", if physical { "not physical" } else { "not identifiable" });
    }
    for why in &c.unusable {
        let _ = writeln!(s, "row left out, no prediction: {why}");
    }
    // Every measurement of the file not used is named (a long list of occlusions is cut, and counted).
    const SHOWN: usize = 20;
    for why in c.not_used.iter().take(SHOWN) {
        let _ = writeln!(s, "measurement not used: {why}");
    }
    if c.not_used.len() > SHOWN {
        let _ = writeln!(s, "measurement not used: {} more (all in the JSON's `not_used`)", c.not_used.len() - SHOWN);
    }
    for note in &c.notes {
        let _ = writeln!(s, "note: {note}");
    }
    for g in &c.left_out {
        let _ = writeln!(s, "gross row left out: {}: {:.4} {} from the model", g.row, g.misfit, g.unit);
    }
    if !c.stopped.is_empty() {
        let _ = writeln!(s, "selection stopped: {}", c.stopped);
    }
    for (k, step) in c.steps.iter().enumerate() {
        let mut tested: Vec<&CandidateTest> = step.iter().filter(|t| t.f.is_some()).collect();
        tested.sort_by(|a, b| a.p.partial_cmp(&b.p).unwrap_or(std::cmp::Ordering::Equal));
        let best: Vec<String> = tested
            .iter()
            .take(3)
            .map(|t| format!("{} F {:.3} p {:.2e}", t.label, t.f.unwrap_or(f64::NAN), t.p.unwrap_or(f64::NAN)))
            .collect();
        match best.is_empty() {
            true => writeln!(s, "step {}: no candidate tested", k + 1),
            false => writeln!(s, "step {}: {} candidates tested; best {}", k + 1, tested.len(), best.join(", ")),
        }
        .expect("writing to a string");
    }
    let _ = writeln!(
        s,
        "position error, mm (check: held out; all: held out with its gross rows; p95_xy, p95_z: the 95th percentiles in the base's horizontal plane and along its vertical):"
    );
    let _ = writeln!(
        s,
        "                                   rows      rms_x    rms_y    rms_z    rms      p95      max   p95_xy    p95_z"
    );
    for st in &c.stages {
        let with_gross = if st.check_all.rows > st.check.rows { st.check_all.rows } else { 0 };
        for (set, e) in [("fit", &st.fit), ("check", &st.check), ("all", &st.check_all)] {
            if e.rows == 0 || (set == "all" && with_gross == 0) {
                continue;
            }
            stage_line(&mut s, st, set, e);
            if s.ends_with('\n') && e.p95_horizontal.is_finite() {
                s.pop();
                let _ = writeln!(s, " {:8.4} {:8.4}", e.p95_horizontal, e.p95_vertical);
            }
        }
    }
    if c.stages.iter().any(|st| st.orientation.is_some()) {
        let _ = writeln!(s, "orientation error, mrad (the rotation vector from measured to predicted):");
        let _ = writeln!(
            s,
            "                                   rows      rms_x    rms_y    rms_z    rms      p95      max"
        );
        for st in &c.stages {
            for (set, e) in ["fit", "check"].iter().zip(st.orientation.iter().flatten()) {
                if e.rows > 0 {
                    stage_line(&mut s, st, set, e);
                }
            }
        }
    }
    s
}

/// One line of the table of errors per stage.
pub(super) fn stage_line(s: &mut String, st: &Stage, set: &str, e: &ErrorStats) {
    use std::fmt::Write;
    let _ = writeln!(
        s,
        "  {:<28} {:<5} {:>5} {:8.4} {:8.4} {:8.4} {:8.4} {:8.4} {:8.4}",
        format!("{} ({} par.)", st.model, st.parameters),
        set,
        e.rows,
        e.rms_axis[0],
        e.rms_axis[1],
        e.rms_axis[2],
        e.rms,
        e.p95,
        e.max
    );
}

#[cfg(test)]
mod tests {
    use super::{ArmEffect, ArmKind};

    /// Regression: a frame compliance's unseen directions (standard error null) were written as the fit's
    /// numbers there (31 mm/N, 1e20), after which the written model had no equilibrium at any row. They are
    /// written rigid, as is a value below zero (no spring has one; the selection refuses a candidate whose
    /// seen value is below zero by more than two standard errors).
    #[test]
    fn unseen_and_negative_spring_directions_are_written_rigid() {
        let e = ArmEffect { kind: ArmKind::FrameCompliance, joint: 0 };
        let values = vec![1e-3, 31.0, -1e-5, 1e20, 2e-9, 3e-9];
        let seen = vec![true, false, true, false, true, true];
        let text = super::arm_corrections(&[e], &[values], &[seen], &["J2".into()]);
        assert!(text.contains("frame_compliance = [0.001, 0.0, 0.0, 0.0, 2e-9, 3e-9]"), "{text}");
        assert!(text.contains("joint = \"J2\""), "{text}");
    }
}
