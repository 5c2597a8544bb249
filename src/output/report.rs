//! Human-readable reports for the terminal.

use std::fmt::Write;

use crate::kinematics::frame::{Mat6, Vec6};

/// A titled 6x6 matrix with row and column labels.
pub fn matrix(out: &mut String, title: &str, m: &Mat6, rows: [&str; 6], cols: [&str; 6]) {
    let _ = writeln!(out, "{title}");
    let _ = write!(out, "{:>10}", "");
    for c in cols {
        let _ = write!(out, "{c:>13}");
    }
    out.push('\n');
    for (i, r) in rows.iter().enumerate() {
        let _ = write!(out, "{r:>10}");
        for j in 0..6 {
            let _ = write!(out, "{:>13.4e}", m[(i, j)]);
        }
        out.push('\n');
    }
    out.push('\n');
}

/// Labels of a twist's components, with units.
pub const TWIST: [&str; 6] = ["dx [mm]", "dy [mm]", "dz [mm]", "rx [rad]", "ry [rad]", "rz [rad]"];
/// Labels of a wrench's components, with units.
pub const WRENCH: [&str; 6] = ["Fx [N]", "Fy [N]", "Fz [N]", "Mx [Nmm]", "My [Nmm]", "Mz [Nmm]"];

/// Six numbers in one line.
pub fn fmt6(v: &Vec6) -> String {
    v.iter().map(|x| format!("{x:.4e}")).collect::<Vec<_>>().join(" ")
}
