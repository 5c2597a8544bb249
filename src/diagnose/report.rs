//! What `stiff diagnose` writes: a report for a person, JSON for a program, and the corrected description.

use std::fmt::Write;

use crate::output::diagnosis::{
    finite, Ambiguity, CandidateReport, Correlations, DiagnosisReport, EffectReport, Indistinguishable, LeftOutRow,
    NominalTest, PoseResidual, ResidualRms,
};

use super::select::{Diagnosis, SigmaSource, Verdict};
use crate::model::effect::{Effect, Form, Kind, Target, TargetKind};

fn source_text(s: &SigmaSource) -> String {
    match s {
        SigmaSource::Column => "the data's sigma_mm column".into(),
        SigmaSource::Given => "the noise level given".into(),
        SigmaSource::Repeats { dof } => format!("repeated rows ({dof} degrees of freedom of pure error)"),
    }
}

/// The verdict in one sentence, with the numbers that back it (and what is left ambiguous after named
/// effects).
pub fn sentence(d: &Diagnosis) -> String {
    let main = verdict_sentence(d);
    match (&d.ambiguous, d.verdict) {
        (Some((names, advice)), Verdict::Effect | Verdict::Unexplained) => format!(
            "{main} What is left cannot be told between {} (their fitted predictions differ by less than the noise \
             can show); {advice}.",
            names.join(", ")
        ),
        _ => main,
    }
}

fn verdict_sentence(d: &Diagnosis) -> String {
    let names = || d.accepted.iter().map(|a| a.effect.to_string()).collect::<Vec<_>>().join(" and ");
    match d.verdict {
        Verdict::None => format!(
            "none: the residuals of the nominal model are within the noise (p = {:.3}); no effect is named.",
            d.nominal_p
        ),
        Verdict::Effect if d.final_p < d.alpha => format!(
            "effect: {} explains most of the discrepancy; the residuals left are beyond the noise by a little \
             (p = {:.2e}, below {} but above {:.0e}: a correct model fails so in {}% of data sets).",
            names(),
            d.final_p,
            d.alpha,
            d.alpha * d.alpha,
            100.0 * d.alpha
        ),
        Verdict::Effect => {
            format!("effect: {} explains the discrepancy (residuals left: p = {:.3}).", names(), d.final_p)
        }
        Verdict::Ambiguous => {
            let (names, advice) = d.ambiguous.clone().unwrap_or_default();
            format!(
                "ambiguous: {} explain the data equally well (their fitted predictions differ by less than the \
                 noise can show); {advice}.",
                names.join(", ")
            )
        }
        Verdict::Unexplained => {
            let partial = names();
            format!(
                "unexplained: the discrepancy is significant (nominal p = {:.2e}) and no candidate of the library \
                 explains it{} (residuals left: p = {:.2e}).",
                d.nominal_p,
                if partial.is_empty() { String::new() } else { format!(" (partly: {partial})") },
                d.final_p
            )
        }
        Verdict::Noise => {
            format!("noise: the misfit is not the model's: {}.", d.noise_note.clone().unwrap_or_default())
        }
    }
}

/// One line per pair of candidates with the same signature on this data.
fn indistinguishable_lines(d: &Diagnosis) -> Vec<String> {
    d.indistinguishable
        .iter()
        .map(|(kept, same)| format!("on this data {kept} and {same} are indistinguishable: reported as {kept}"))
        .collect()
}

/// The report printed on stdout: verdict, nominal test, accepted effects, candidate table, residual RMS.
pub fn text(d: &Diagnosis, model: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "stiff diagnose: {model}");
    let _ = writeln!(
        s,
        "{} rows ({} observations); noise sigma {:.4} mm from {}",
        d.rows,
        d.observations,
        d.sigma,
        source_text(&d.sigma_source)
    );
    let test = match d.sigma_source {
        SigmaSource::Repeats { .. } => "lack-of-fit F",
        _ => "chi-square",
    };
    if !d.left_out.is_empty() {
        let _ = writeln!(
            s,
            "{} rows left out of every fit as gross errors (no plausible model fits them):",
            d.left_out.len()
        );
        for l in &d.left_out {
            let _ = writeln!(s, "  {}, left out", l.describe());
        }
    }
    let _ =
        writeln!(s, "nominal model: {test} = {}, p = {}", exponent(d.nominal_statistic, 4), exponent(d.nominal_p, 3));
    let _ = writeln!(s, "\nverdict: {}\n", sentence(d));
    for line in indistinguishable_lines(d) {
        let _ = writeln!(s, "{line}");
    }
    for a in &d.accepted {
        let _ = writeln!(
            s,
            "accepted {} (given the others: p = {}, delta BIC {})",
            a.effect,
            exponent(a.p_value, 2),
            fixed(a.delta_bic, 1)
        );
        for (k, (v, e)) in a.params.iter().zip(&a.se).enumerate() {
            let _ = writeln!(
                s,
                "  parameter {}: {} +- {} (1 standard error, joint fit)",
                k + 1,
                fixed(*v, 6),
                fixed(*e, 6)
            );
        }
        let _ = writeln!(s, "  ({})", a.effect.kind.values().1);
    }
    let (labels, corr) = &d.correlations;
    if labels.len() > 1 {
        let _ = writeln!(s, "correlations of the fitted parameters (joint fit):");
        for (label, row) in labels.iter().zip(corr) {
            let cells: Vec<String> = row.iter().map(|v| format!("{:>6}", fixed(*v, 2))).collect();
            let _ = writeln!(s, "  {label:<28} {}", cells.join(" "));
        }
    }
    let _ = writeln!(s, "candidates (each against the nominal model):");
    let _ = writeln!(
        s,
        "  {:<26} {:>4} {:>5} {:>10} {:>12} {:>10} {:>10}  values / note",
        "candidate", "dim", "ident", "cond", "delta BIC", "F", "p"
    );
    for r in &d.table {
        let values: Vec<String> =
            r.values.iter().zip(&r.se).map(|(v, e)| format!("{}+-{}", fixed(*v, 4), exponent(*e, 2))).collect();
        let _ = writeln!(
            s,
            "  {:<26} {:>4} {:>5} {:>10} {:>12} {:>10} {:>10}  {}{}",
            r.label,
            r.dim,
            if r.identifiable { "yes" } else { "no" },
            exponent(r.condition, 2),
            fixed(r.delta_bic, 1),
            exponent(r.f, 3),
            exponent(r.p_value, 2),
            if r.identifiable { values.join(" ") } else { r.note.clone() },
            if r.passes { "  [passes]" } else { "" }
        );
    }
    let axes =
        |v: &crate::kinematics::frame::Vec3| format!("x {}  y {}  z {}", fixed(v.x, 4), fixed(v.y, 4), fixed(v.z, 4));
    let _ =
        writeln!(s, "\nresidual RMS (mm), fitting data: before {}  after {}", axes(&d.rms_before), axes(&d.rms_after));
    let _ = writeln!(
        s,
        "residual RMS (mm), held-out poses: before {}  after {}",
        axes(&d.heldout_before),
        axes(&d.heldout_after)
    );
    s
}

/// `v` with `digits` decimals, or `-` where it is not a finite number (a report never prints NaN or inf).
fn fixed(v: f64, digits: usize) -> String {
    if v.is_finite() {
        format!("{v:.digits$}")
    } else {
        "-".into()
    }
}

/// `v` in exponent form with `digits` decimals, or `-` where it is not a finite number.
fn exponent(v: f64, digits: usize) -> String {
    if v.is_finite() {
        format!("{v:.digits$e}")
    } else {
        "-".into()
    }
}

/// The diagnosis as the JSON file `--json` writes (`output::diagnosis`).
pub fn json(d: &Diagnosis, model: &str) -> DiagnosisReport {
    let arr = |v: &crate::kinematics::frame::Vec3| [v.x, v.y, v.z];
    let effects = d
        .accepted
        .iter()
        .map(|a| EffectReport {
            name: a.effect.kind.name().into(),
            target: a.effect.target.to_string(),
            values: a.effect.user_values(),
            meaning: a.effect.kind.values().1.into(),
            parameters: a.params.clone(),
            standard_errors: a.se.iter().map(|v| finite(*v)).collect(),
            p_value: a.p_value,
            delta_bic: a.delta_bic,
        })
        .collect();
    let (labels, corr) = &d.correlations;
    let correlations = (!labels.is_empty()).then(|| Correlations {
        parameters: labels.clone(),
        matrix: corr.iter().map(|row| row.iter().map(|v| finite(*v)).collect()).collect(),
    });
    let candidates = d
        .table
        .iter()
        .map(|r| CandidateReport {
            candidate: r.label.clone(),
            dim: r.dim,
            identifiable: r.identifiable,
            note: r.note.clone(),
            condition: finite(r.condition),
            orthogonal_share: r.orthogonal,
            ssr: finite(r.ssr),
            delta_bic: finite(r.delta_bic),
            f: finite(r.f),
            p_value: finite(r.p_value),
            values: r.values.iter().map(|v| finite(*v)).collect(),
            standard_errors: r.se.iter().map(|v| finite(*v)).collect(),
            plausible: r.plausible,
            passes: r.passes,
        })
        .collect();
    DiagnosisReport {
        model: model.into(),
        verdict: d.verdict.as_str().into(),
        sentence: sentence(d),
        sigma_mm: d.sigma,
        sigma_source: source_text(&d.sigma_source),
        rows: d.rows,
        nominal: NominalTest { statistic: d.nominal_statistic, p_value: d.nominal_p },
        effects,
        final_p_value: d.final_p,
        ambiguous: d
            .ambiguous
            .as_ref()
            .map(|(names, advice)| Ambiguity { candidates: names.clone(), separate_by: advice.clone() }),
        indistinguishable: d
            .indistinguishable
            .iter()
            .map(|(kept, same)| Indistinguishable { reported_as: kept.clone(), same_as: same.clone() })
            .collect(),
        correlations,
        noise: d.noise_note.clone(),
        candidates,
        residuals: d
            .per_pose
            .iter()
            .map(|(p, b, a)| PoseResidual { position_mm: arr(p), before_mm: arr(b), after_mm: arr(a) })
            .collect(),
        rms_mm: ResidualRms {
            fit_before: arr(&d.rms_before),
            fit_after: arr(&d.rms_after),
            heldout_before: arr(&d.heldout_before),
            heldout_after: arr(&d.heldout_after),
        },
        left_out_count: d.left_out.len(),
        left_out: d
            .left_out
            .iter()
            .map(|l| LeftOutRow {
                row: l.row + 1,
                line: l.line,
                pose_id: l.pose_id.clone(),
                wrench: l.wrench.into(),
                misfit_mm: l.misfit_mm,
                description: l.describe(),
            })
            .collect(),
    }
}

/// The description with the accepted effects appended as `[[effect]]` tables, its references to other files
/// made to work from where it is written (`with_references`).
pub fn corrected_model(
    source: &str,
    model_dir: &std::path::Path,
    written_dir: Option<&std::path::Path>,
    d: &Diagnosis,
) -> String {
    let mut out = with_references(source, model_dir, written_dir);
    let _ = writeln!(out, "\n# Added by stiff diagnose: {}", sentence(d));
    for a in &d.accepted {
        write_correction(&mut out, &a.effect);
    }
    out
}

/// The description's text with its references to other files (`from`, `parameters_from`, a URDF `file`),
/// read from `model_dir`, rewritten so that the text still reads them from `written_dir`, the folder it is
/// written to: relative to it where both are given as absolute paths (the pair of folders can then move
/// together), else absolute. A reference already absolute is kept.
pub fn with_references(source: &str, model_dir: &std::path::Path, written_dir: Option<&std::path::Path>) -> String {
    let mut out = String::with_capacity(source.len() + 400);
    for line in source.lines() {
        let trimmed = line.trim_start();
        let reference = ["from", "parameters_from", "file"].iter().find_map(|k| {
            let rest = trimmed.strip_prefix(k)?.trim_start().strip_prefix('=')?.trim();
            let path = rest.strip_prefix('"')?.split('"').next()?;
            Some((k, path))
        });
        match reference {
            Some((k, path)) if !std::path::Path::new(path).is_absolute() => {
                let target = model_dir.join(path);
                let written = written_dir.and_then(|w| relative_path(&target, w)).unwrap_or(target);
                let _ = writeln!(out, "{k} = {:?}", written.to_string_lossy());
            }
            _ => {
                out.push_str(line);
                out.push('\n');
            }
        }
    }
    out
}

/// `target` as a path relative to the folder `from` (both absolute): the components they share dropped,
/// `..` for each of `from`'s left. None where either is relative or they share no root (another drive).
fn relative_path(target: &std::path::Path, from: &std::path::Path) -> Option<std::path::PathBuf> {
    use std::path::Component;
    if !target.is_absolute() || !from.is_absolute() {
        return None;
    }
    let (t, f): (Vec<Component>, Vec<Component>) = (target.components().collect(), from.components().collect());
    if t.first() != f.first() {
        return None;
    }
    let shared = t.iter().zip(&f).take_while(|(a, b)| a == b).count();
    let mut out = std::path::PathBuf::new();
    for c in &f[shared..] {
        match c {
            Component::Normal(_) => out.push(".."),
            // A `..` or `.` in `from` cannot be undone without the file system: keep the absolute path.
            _ => return None,
        }
    }
    for c in &t[shared..] {
        out.push(c.as_os_str());
    }
    Some(out)
}

/// One accepted effect as the model change it is (`[[payload]]`, `[[actuator_offset]]`, a spring scaling
/// as `[[effect]]`, all built into the model every study uses), or as a measurement term `[[effect]]` that
/// only diagnose and synth read, said so in the file.
pub(crate) fn write_correction(out: &mut String, e: &Effect) {
    let v = e.user_values();
    let number = |x: f64| format!("{x:e}");
    match (e.kind, &e.target) {
        (Kind::Gravity | Kind::GravityOffset, _) => {
            let _ = writeln!(out, "\n# {}: a mass carried by the platform, under the model's gravity", e.kind.name());
            let _ = writeln!(out, "[[payload]]\nmass_kg = {}", number(v[0]));
            if e.kind == Kind::GravityOffset {
                let _ = writeln!(
                    out,
                    "centre = [{}, {}, {}]   # mm, platform frame",
                    number(v[1]),
                    number(v[2]),
                    number(v[3])
                );
            }
        }
        (Kind::ActuatorOffset, Target::Leg(k)) => {
            let _ = writeln!(
                out,
                "\n# actuator-offset: leg {}'s actuator sits this far from where it is commanded (mm or rad)",
                k + 1
            );
            let _ = writeln!(out, "[[actuator_offset]]\nleg = {}\noffset = {}", k + 1, number(v[0]));
        }
        _ => {
            let what = match e.kind.form() {
                Form::Model => "a spring scaled: built into the model, every study sees it",
                Form::Measurement => {
                    "a measurement term, not a change of the robot: diagnose and synth add it to the predicted \
                     measurements; map, curve and assemble have nothing to change"
                }
            };
            let _ = writeln!(out, "\n# {}: {what}", e.kind.name());
            let _ = writeln!(out, "[[effect]]\nname = \"{}\"", e.kind.name());
            if e.kind.target() != TargetKind::None {
                let _ = writeln!(out, "target = \"{}\"", e.target);
            }
            let values: Vec<String> = v.iter().map(|x| number(*x)).collect();
            let _ = writeln!(out, "values = [{}]   # {}", values.join(", "), e.kind.values().1);
        }
    }
}
