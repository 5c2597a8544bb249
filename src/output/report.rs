//! Human-readable reports for the terminal.

use std::fmt::Write;

use crate::kinematics::frame::{Mat6, Vec6};
use crate::model::grid::PosePoint;
use crate::study::point::PointResult;

fn matrix(out: &mut String, title: &str, m: &Mat6, rows: [&str; 6], cols: [&str; 6]) {
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

const TWIST: [&str; 6] = ["dx [mm]", "dy [mm]", "dz [mm]", "rx [rad]", "ry [rad]", "rz [rad]"];
const WRENCH: [&str; 6] = ["Fx [N]", "Fy [N]", "Fz [N]", "Mx [Nmm]", "My [Nmm]", "Mz [Nmm]"];

/// The report of `stiff point`. `loaded`: `r` is the loaded equilibrium under the point's wrench (its
/// displacement and tangent matrices, not symmetric, every entry shown).
pub fn point_report(model: &str, p: &PosePoint, r: &PointResult, loaded: bool) -> String {
    let mut out = String::new();
    let (x, o) = (p.position, p.rotation);
    let _ = writeln!(out, "{model}");
    let _ = writeln!(
        out,
        "pose: x = {} mm, y = {} mm, z = {} mm; orientation (rotation vector) {} {} {} rad",
        x.x, x.y, x.z, o.x, o.y, o.z
    );
    let rank = r.rank.map_or(String::from("not computed"), |k| k.to_string());
    let condition = r.condition.map_or(String::from("not computed"), |c| format!("{c:.3e}"));
    let _ = writeln!(out, "status: {}, rank {rank}, condition {condition}\n", r.status.as_str());
    if let Some(k) = &r.stiffness {
        matrix(
            &mut out,
            "Stiffness K: wrench (rows) per displacement (columns) at the reference point, base frame",
            k,
            WRENCH,
            TWIST,
        );
    }
    if let Some(c) = &r.compliance {
        matrix(&mut out, "Compliance C = K^-1: displacement (rows) per wrench (columns)", c, TWIST, WRENCH);
    }
    if let Some(pc) = &r.principal {
        let _ = writeln!(
            out,
            "principal compliance (of C's symmetric part): translation max {:.4e} / min {:.4e} mm/N, rotation max {:.4e} rad/(N mm)",
            pc.translation_max, pc.translation_min, pc.rotation_max
        );
    }
    if let (Some(d), Some(w)) = (&r.deflection, &p.wrench) {
        let what = if loaded { "loaded equilibrium displacement" } else { "linear deflection C w" };
        let _ = writeln!(out, "{what} under the wrench {}: {}", fmt6(w), fmt6(d));
    }
    if !r.free.is_empty() {
        let _ = writeln!(out, "free directions (unit twists dx dy dz [mm], rx ry rz [rad]):");
        for f in &r.free {
            let _ = writeln!(out, "  {}", fmt6(f));
        }
    }
    out
}

fn fmt6(v: &Vec6) -> String {
    v.iter().map(|x| format!("{x:.4e}")).collect::<Vec<_>>().join(" ")
}
