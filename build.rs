//! Records the git commit the binary is built from, for `stiff --version` ("unknown" when the source is not
//! a git checkout or git is not installed).
use std::process::Command;

fn main() {
    let commit = Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "unknown".into());
    // Without optional locks, `git status` does not write the refreshed index back: a fresh clone's first
    // status rewrote .git/index, which this script watches, so the next cargo command (README's `cargo test
    // --release` after its build) ran the script again and compiled the whole crate a second time (90 CPU s).
    let dirty = Command::new("git")
        .args(["--no-optional-locks", "status", "--porcelain", "--untracked-files=no"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .is_some_and(|o| !o.stdout.is_empty());
    let suffix = if dirty && commit != "unknown" { "-modified" } else { "" };
    println!("cargo:rustc-env=STIFF_GIT_COMMIT={commit}{suffix}");
    // Rebuild when HEAD moves (a commit, a checkout). Outside a checkout watch only this script: a watched
    // file that does not exist would rerun it, and rebuild the crate, on every build.
    println!("cargo:rerun-if-changed=build.rs");
    for watched in [".git/HEAD", ".git/index"] {
        if std::path::Path::new(watched).exists() {
            println!("cargo:rerun-if-changed={watched}");
        }
    }
}
