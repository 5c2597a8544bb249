//! CSV rows of a map: every column names its unit; numbers in shortest round-trip form, so the bytes are
//! the same for any thread count.

use crate::kinematics::frame::{Mat6, Vec6};
use crate::model::grid::PosePoint;
use crate::study::point::PointResult;

/// Unit of entry (i, j) (1-based) of a 6x6 compliance matrix: it maps a wrench (N, N mm) to a displacement
/// (mm, rad).
pub fn compliance_unit(i: usize, j: usize) -> &'static str {
    match (i <= 3, j <= 3) {
        (true, true) => "mm_per_N",
        (true, false) => "mm_per_Nmm",
        (false, true) => "rad_per_N",
        (false, false) => "rad_per_Nmm",
    }
}

/// Unit of entry (i, j) of a stiffness matrix: it maps a displacement (mm, rad) to a wrench (N, N mm).
pub fn stiffness_unit(i: usize, j: usize) -> &'static str {
    match (i <= 3, j <= 3) {
        (true, true) => "N_per_mm",
        (true, false) => "N_per_rad",
        (false, true) => "Nmm_per_mm",
        (false, false) => "Nmm_per_rad",
    }
}

/// Upper triangle, row by row: (1,1), (1,2), ... (6,6).
pub fn upper_triangle() -> impl Iterator<Item = (usize, usize)> {
    (1..=6).flat_map(|i| (i..=6).map(move |j| (i, j)))
}

/// The entries a map writes of a 6x6 matrix (1-based): all 36 row by row where it is not symmetric
/// (loaded tangent stiffness and its inverse), else the 21 of the upper triangle.
pub fn matrix_entries(full: bool) -> Vec<(usize, usize)> {
    if full {
        (1..=6).flat_map(|i| (1..=6).map(move |j| (i, j))).collect()
    } else {
        upper_triangle().collect()
    }
}

/// Which optional columns a map has; fixed by the input before the first row.
#[derive(Clone, Copy, Debug)]
pub struct MapColumns {
    pub orientation: bool,
    pub stiffness: bool,
    pub deflection: bool,
    /// Loaded mode: the compliance is the tangent compliance at the loaded equilibrium (all 36 entries of
    /// it and of K, which are not symmetric), the deflection that equilibrium's displacement; appends the
    /// Newton iteration count.
    pub loaded: bool,
}

pub fn map_header(c: &MapColumns) -> String {
    let mut h: Vec<String> = vec!["index".into(), "name".into(), "x_mm".into(), "y_mm".into(), "z_mm".into()];
    if c.orientation {
        h.extend(["pose_rx_rad", "pose_ry_rad", "pose_rz_rad"].map(String::from));
    }
    h.extend(["status", "rank", "free_directions", "condition"].map(String::from));
    h.extend(["c_tran_max_mm_per_N", "c_tran_min_mm_per_N", "c_rot_max_rad_per_Nmm"].map(String::from));
    if c.deflection {
        h.extend(["dx_mm", "dy_mm", "dz_mm", "rx_rad", "ry_rad", "rz_rad", "deflection_mm"].map(String::from));
    }
    let entries = matrix_entries(c.loaded);
    h.extend(entries.iter().map(|&(i, j)| format!("C{i}{j}_{}", compliance_unit(i, j))));
    if c.stiffness {
        h.extend(entries.iter().map(|&(i, j)| format!("K{i}{j}_{}", stiffness_unit(i, j))));
    }
    if c.loaded {
        h.push("iterations".into());
    }
    let mut s = h.join(",");
    s.push('\n');
    s
}

/// Appends one number in shortest round-trip form; nothing for a non-finite one (one rule for missing
/// values everywhere: an empty cell).
pub fn push_number(out: &mut String, v: f64) {
    if v.is_finite() {
        let mut b = ryu::Buffer::new();
        out.push_str(b.format_finite(v));
    }
}

/// The free directions of a singular manipulator in one field: unit twists `dx dy dz rx ry rz` (mm and
/// rad, scaled alike by the model's length scale before normalising) separated by `;`. Empty where K is
/// regular.
pub fn push_free_directions(out: &mut String, free: &[Vec6]) {
    for (i, t) in free.iter().enumerate() {
        if i > 0 {
            out.push(';');
        }
        for (k, v) in t.iter().enumerate() {
            if k > 0 {
                out.push(' ');
            }
            push_number(out, *v);
        }
    }
}

/// Appends a text field, quoted where CSV needs it.
pub fn push_text(out: &mut String, t: &str) {
    if t.contains([',', '"', '\n', '\r']) {
        out.push('"');
        out.push_str(&t.replace('"', "\"\""));
        out.push('"');
    } else {
        out.push_str(t);
    }
}

fn push_optional(out: &mut String, v: Option<f64>) {
    out.push(',');
    if let Some(v) = v {
        push_number(out, v);
    }
}

fn push_matrix(out: &mut String, m: Option<&Mat6>, full: bool) {
    for (i, j) in matrix_entries(full) {
        push_optional(out, m.map(|m| m[(i - 1, j - 1)]));
    }
}

pub fn push_map_row(out: &mut String, c: &MapColumns, index: u64, p: &PosePoint, r: &PointResult) {
    out.push_str(itoa::Buffer::new().format(index));
    out.push(',');
    if let Some(n) = &p.name {
        push_text(out, n);
    }
    for k in 0..3 {
        out.push(',');
        push_number(out, p.position[k]);
    }
    if c.orientation {
        for k in 0..3 {
            out.push(',');
            push_number(out, p.rotation[k]);
        }
    }
    out.push(',');
    out.push_str(r.status.as_str());
    out.push(',');
    if let Some(rank) = r.rank {
        out.push_str(itoa::Buffer::new().format(rank));
    }
    out.push(',');
    push_free_directions(out, &r.free);
    push_optional(out, r.condition.filter(|c| c.is_finite()));
    let pc = r.principal;
    push_optional(out, pc.map(|p| p.translation_max));
    push_optional(out, pc.map(|p| p.translation_min));
    push_optional(out, pc.map(|p| p.rotation_max));
    if c.deflection {
        let d: Option<Vec6> = r.deflection;
        for k in 0..6 {
            push_optional(out, d.map(|d| d[k]));
        }
        push_optional(out, d.map(|d| d.fixed_rows::<3>(0).norm()));
    }
    push_matrix(out, r.compliance.as_ref(), c.loaded);
    if c.stiffness {
        push_matrix(out, r.stiffness.as_ref(), c.loaded);
    }
    if c.loaded {
        out.push(',');
        out.push_str(itoa::Buffer::new().format(r.iterations));
    }
    out.push('\n');
}
