//! The dependency rule of ARCHITECTURE.md, read from the source: every module refers only to modules in
//! layers below its own (never sideways, never up), so there is no import cycle, and above the platform
//! only `model` (which builds the engines) reaches the engines' internals.
//!
//!   cli -> {study, diagnose, plot} -> batch -> {output, model} -> platform -> {vjm, msa} -> beam
//!       -> {kinematics, linalg, expr, columns}

use std::collections::BTreeSet;
use std::path::Path;

/// The layer of each top-level module, lowest first.
const LAYERS: [&[&str]; 8] = [
    &["kinematics", "linalg", "expr", "columns"],
    &["beam"],
    &["vjm", "msa"],
    &["platform"],
    &["output", "model"],
    &["batch"],
    &["study", "diagnose", "plot"],
    &["cli"],
];

/// What lies below the leg seam: how a leg is computed, not what it answers.
const BELOW_THE_SEAM: [&str; 5] = ["vjm", "msa", "beam", "kinematics::chain", "kinematics::ik"];

fn layer(module: &str) -> Option<usize> {
    LAYERS.iter().position(|l| l.contains(&module))
}

/// Rust files under `dir`, recursively.
fn sources(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The top-level module a file belongs to (`src/vjm/spring.rs` -> vjm, `src/cli.rs` -> cli).
fn module_of(path: &Path) -> String {
    let rel = path.strip_prefix("src").unwrap();
    let first = rel.components().next().unwrap().as_os_str().to_string_lossy().to_string();
    first.trim_end_matches(".rs").to_string()
}

/// Every `crate::a` and `crate::a::b` a file refers to outside comments.
fn references(text: &str) -> BTreeSet<(String, String)> {
    let mut out = BTreeSet::new();
    for line in text.lines() {
        let code = line.split("//").next().unwrap_or("");
        let mut rest = code;
        while let Some(at) = rest.find("crate::") {
            rest = &rest[at + "crate::".len()..];
            let path: String = rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':').collect();
            let mut parts = path.split("::").filter(|p| !p.is_empty());
            let top = parts.next().unwrap_or("").to_string();
            let second = parts.next().unwrap_or("").to_string();
            out.insert((top, second));
        }
    }
    out
}

#[test]
fn dependencies_point_down_and_stay_above_the_seam() {
    let mut files = Vec::new();
    sources(Path::new("src"), &mut files);
    files.sort();
    let mut violations = Vec::new();
    let mut edges = 0;
    for file in &files {
        let module = module_of(file);
        if module == "lib" || module == "main" {
            continue;
        }
        let Some(own) = layer(&module) else {
            violations.push(format!("{}: module `{module}` has no layer in ARCHITECTURE.md's rule", file.display()));
            continue;
        };
        let text = std::fs::read_to_string(file).unwrap();
        for (top, second) in references(&text) {
            if top == module {
                continue;
            }
            edges += 1;
            match layer(&top) {
                None => violations.push(format!("{}: refers to unknown module `crate::{top}`", file.display())),
                Some(l) if l >= own => violations.push(format!(
                    "{}: `{module}` (layer {own}) refers to `crate::{top}` (layer {l}): not below it",
                    file.display()
                )),
                Some(_) => {}
            }
            let full = format!("{top}::{second}");
            let below_seam = BELOW_THE_SEAM.iter().any(|b| *b == top || *b == full);
            if own > layer("platform").unwrap() && module != "model" && below_seam {
                violations.push(format!("{}: `{module}` reaches below the leg seam (`crate::{full}`)", file.display()));
            }
        }
    }
    assert!(edges > 50, "the scan found the modules' references ({edges})");
    assert!(violations.is_empty(), "dependency rule broken:\n{}", violations.join("\n"));
}

/// The scan itself: a reference up, sideways and below the seam is each caught.
#[test]
fn the_dependency_scan_sees_every_kind_of_reference() {
    let text = "use crate::platform::leg::Leg;\nlet k = crate::diagnose::measurement::gravity_of(m); // crate::cli\n";
    let refs = references(text);
    assert!(refs.contains(&("platform".into(), "leg".into())));
    assert!(refs.contains(&("diagnose".into(), "measurement".into())));
    assert!(!refs.iter().any(|(t, _)| t == "cli"), "comments are not references");
    assert_eq!(layer("study"), layer("plot"));
    assert!(layer("vjm") < layer("platform") && layer("expr") < layer("msa"));
}
