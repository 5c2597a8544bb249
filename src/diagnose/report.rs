//! What `stiff diagnose` writes: a report for a person, JSON for a program, and the corrected description.

use std::fmt::Write;

use crate::output::diagnosis::{
    finite, Ambiguity, CandidateReport, DiagnosisReport, EffectReport, NominalTest, PoseResidual, ResidualRms,
};

use super::select::{Diagnosis, SigmaSource, Verdict};

fn source_text(s: &SigmaSource) -> String {
    match s {
        SigmaSource::Column => "the data's sigma_mm column".into(),
        SigmaSource::Given => "the noise level given".into(),
        SigmaSource::Repeats { dof } => format!("repeated rows ({dof} degrees of freedom of pure error)"),
    }
}

/// The verdict in one sentence, with the numbers that back it.
pub fn sentence(d: &Diagnosis) -> String {
    match d.verdict {
        Verdict::None => format!(
            "none: the residuals of the nominal model are within the noise (p = {:.3}); no effect is named.",
            d.nominal_p
        ),
        Verdict::Effect => {
            let names: Vec<String> = d.accepted.iter().map(|a| a.effect.to_string()).collect();
            format!("effect: {} explains the discrepancy (residuals left: p = {:.3}).", names.join(" and "), d.final_p)
        }
        Verdict::Ambiguous => {
            let (a, b, advice) = d.ambiguous.clone().unwrap_or_default();
            format!("ambiguous: {a} and {b} explain the data equally well (nearly parallel signatures); {advice}.")
        }
        Verdict::Unexplained => {
            let partial: Vec<String> = d.accepted.iter().map(|a| a.effect.to_string()).collect();
            format!(
                "unexplained: the discrepancy is significant (p = {:.2e}) and no candidate of the library explains it{}.",
                d.nominal_p,
                if partial.is_empty() { String::new() } else { format!(" (partly: {})", partial.join(", ")) }
            )
        }
    }
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
    let _ = writeln!(s, "nominal model: {test} = {:.4e}, p = {:.3e}", d.nominal_statistic, d.nominal_p);
    let _ = writeln!(s, "\nverdict: {}\n", sentence(d));
    for a in &d.accepted {
        let _ = writeln!(s, "accepted {} (p = {:.2e}, delta BIC {:.1})", a.effect, a.p_value, a.delta_bic);
        for (k, (v, e)) in a.params.iter().zip(&a.se).enumerate() {
            let _ = writeln!(s, "  parameter {}: {v:.6} +- {e:.6} (1 standard error)", k + 1);
        }
        let _ = writeln!(s, "  ({})", a.effect.kind.values().1);
    }
    let _ = writeln!(s, "candidates (each against the nominal model):");
    let _ = writeln!(
        s,
        "  {:<26} {:>4} {:>5} {:>10} {:>12} {:>10} {:>10}  values / note",
        "candidate", "dim", "ident", "cond", "delta BIC", "F", "p"
    );
    for r in &d.table {
        let values: Vec<String> = r.values.iter().zip(&r.se).map(|(v, e)| format!("{v:.4}+-{e:.2e}")).collect();
        let _ = writeln!(
            s,
            "  {:<26} {:>4} {:>5} {:>10.2e} {:>12.1} {:>10.3e} {:>10.2e}  {}{}",
            r.label,
            r.dim,
            if r.identifiable { "yes" } else { "no" },
            r.condition,
            r.delta_bic,
            r.f,
            r.p_value,
            if r.identifiable { values.join(" ") } else { r.note.clone() },
            if r.passes { "  [passes]" } else { "" }
        );
    }
    let axes = |v: &crate::kinematics::frame::Vec3| format!("x {:.4}  y {:.4}  z {:.4}", v.x, v.y, v.z);
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

/// The diagnosis as the JSON file `--json` writes (`output::diagnosis`).
pub fn json(d: &Diagnosis, model: &str) -> DiagnosisReport {
    let arr = |v: &crate::kinematics::frame::Vec3| [v.x, v.y, v.z];
    let effects = d
        .accepted
        .iter()
        .map(|a| EffectReport {
            name: a.effect.kind.name().into(),
            target: a.effect.target.to_string(),
            values: a.effect.values.clone(),
            meaning: a.effect.kind.values().1.into(),
            parameters: a.params.clone(),
            standard_errors: a.se.iter().map(|v| finite(*v)).collect(),
            p_value: a.p_value,
            delta_bic: a.delta_bic,
        })
        .collect();
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
            .map(|(a, b, advice)| Ambiguity { candidates: [a.clone(), b.clone()], separate_by: advice.clone() }),
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
    }
}

/// The description with the accepted effects appended as `[[effect]]` tables; file references made
/// absolute so the corrected file works from anywhere.
pub fn corrected_model(source: &str, model_dir: &std::path::Path, d: &Diagnosis) -> String {
    let mut out = String::with_capacity(source.len() + 400);
    for line in source.lines() {
        let trimmed = line.trim_start();
        let reference = ["from", "parameters_from"].iter().find_map(|k| {
            let rest = trimmed.strip_prefix(k)?.trim_start().strip_prefix('=')?.trim();
            let path = rest.strip_prefix('"')?.split('"').next()?;
            Some((k, path))
        });
        match reference {
            Some((k, path)) if !std::path::Path::new(path).is_absolute() => {
                let abs = model_dir.join(path);
                let _ = writeln!(out, "{k} = {:?}", abs.to_string_lossy());
            }
            _ => {
                out.push_str(line);
                out.push('\n');
            }
        }
    }
    let _ = writeln!(out, "\n# Added by stiff diagnose: {}", sentence(d));
    for a in &d.accepted {
        let _ = writeln!(out, "\n[[effect]]\nname = \"{}\"", a.effect.kind.name());
        if a.effect.kind.target() != crate::model::effect::TargetKind::None {
            let _ = writeln!(out, "target = \"{}\"", a.effect.target);
        }
        let values: Vec<String> = a.effect.values.iter().map(|v| format!("{v:e}")).collect();
        let _ = writeln!(out, "values = [{}]   # {}", values.join(", "), a.effect.kind.values().1);
    }
    out
}
