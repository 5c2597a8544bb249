//! CSV tables: every column name, once, with its unit; the `Record` through which a study's row type
//! writes its header and its cells from the same code (`Row`); numbers in shortest round-trip form, so the
//! bytes are the same for any thread count; one rule for a missing value: an empty cell.

use std::fmt::Display;

use crate::kinematics::frame::{Mat6, Vec6};

/// Column names shared by several tables (`crate::columns`).
pub use crate::columns as names;

/// Which 6x6 matrix a block of columns holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Matrix {
    /// Compliance, `C{i}{j}_{unit}`.
    Compliance,
    /// Stiffness, `K{i}{j}_{unit}`.
    Stiffness,
}

/// Where a row's cells go: `Header` keeps their names, `Cells` writes their values. A row type names each
/// cell as it writes it (`Row::record`), so its header and its cells cannot disagree.
pub trait Record {
    /// A number; an empty cell where it is not finite.
    fn number(&mut self, name: impl Display, v: f64);
    /// A number or an empty cell.
    fn optional(&mut self, name: impl Display, v: Option<f64>);
    /// A count or an empty cell.
    fn count(&mut self, name: impl Display, v: Option<u64>);
    /// A text, quoted where CSV needs it.
    fn text(&mut self, name: impl Display, v: &str);
    /// A triangle of a 6x6 matrix.
    fn matrix(&mut self, which: Matrix, m: Option<&Mat6>, part: Triangle);
    /// Free directions in one field (`push_free_directions`).
    fn free_directions(&mut self, name: impl Display, free: &[Vec6]);

    /// Six numbers, or six empty cells.
    fn six(&mut self, names: [&str; 6], v: Option<&Vec6>) {
        for (k, name) in names.iter().enumerate() {
            self.optional(name, v.map(|v| v[k]));
        }
    }

    /// Six numbers under `prefix_` + the displacement names, or six empty cells.
    fn prefixed_six(&mut self, prefix: &str, names: [&str; 6], v: Option<&Vec6>) {
        for (k, name) in names.iter().enumerate() {
            self.optional(format_args!("{prefix}_{name}"), v.map(|v| v[k]));
        }
    }
}

/// A table's row: `Layout` is what fixes the columns before the first row (options, counts of legs).
pub trait Row {
    /// What fixes the columns.
    type Layout;
    /// Names and writes every cell, in order; the cells written must not depend on the row's values.
    fn record(&self, layout: &Self::Layout, r: &mut impl Record);
}

/// What a column holds: the type a columnar file (Parquet) gives it. An empty CSV cell is a null in any kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CellKind {
    /// A real number (f64).
    Number,
    /// A non-negative count (u64).
    Count,
    /// Text.
    Text,
}

/// One column of a table: its name (with its unit as a suffix, `x_mm`) and what it holds.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Column {
    /// The header name.
    pub name: String,
    /// What its cells hold.
    pub kind: CellKind,
}

/// The header line of `row`'s table (any row of it, typically a blank one).
pub fn header<T: Row>(row: &T, layout: &T::Layout) -> String {
    header_line(&selected_columns(row, layout, None))
}

/// Every column name of `row`'s table, in order.
pub fn column_names<T: Row>(row: &T, layout: &T::Layout) -> Vec<String> {
    selected_columns(row, layout, None).into_iter().map(|c| c.name).collect()
}

/// The columns of `row`'s table that `selection` keeps (all where None), in order.
pub fn selected_columns<T: Row>(row: &T, layout: &T::Layout, selection: Option<&Selection>) -> Vec<Column> {
    let mut h = Header(Vec::new());
    row.record(layout, &mut h);
    h.0.into_iter().enumerate().filter(|(k, _)| selection.is_none_or(|s| s.keep[*k])).map(|(_, c)| c).collect()
}

/// The CSV header line of these columns.
pub fn header_line(columns: &[Column]) -> String {
    let mut s = columns.iter().map(|c| c.name.as_str()).collect::<Vec<_>>().join(",");
    s.push('\n');
    s
}

/// The unit a column's name ends with (`x_mm` -> `mm`, `C14_mm_per_Nmm` -> `mm_per_Nmm`), None for a
/// dimensionless column (`status`, `load_factor`, `iterations`). Names carry their unit as their last
/// `_`-separated part, or as `A_per_B`.
pub fn unit_of(name: &str) -> Option<&str> {
    const UNITS: [&str; 5] = ["mm", "rad", "N", "Nmm", "kg"];
    let parts: Vec<&str> = name.split('_').collect();
    let n = parts.len();
    if n >= 4 && parts[n - 2] == "per" && UNITS.contains(&parts[n - 3]) && UNITS.contains(&parts[n - 1]) {
        let start = name.len() - parts[n - 3..].iter().map(|p| p.len() + 1).sum::<usize>() + 1;
        return Some(&name[start..]);
    }
    (n >= 2 && UNITS.contains(&parts[n - 1])).then(|| parts[n - 1])
}

/// Appends `row` as one CSV line.
pub fn write_row<T: Row>(row: &T, layout: &T::Layout, out: &mut String) {
    write_selected_row(row, layout, None, out);
}

/// Appends the cells of `row` that `selection` keeps (all where None) as one CSV line.
pub fn write_selected_row<T: Row>(row: &T, layout: &T::Layout, selection: Option<&Selection>, out: &mut String) {
    let mut cells = Cells { out, first: true, keep: selection.map(|s| s.keep.as_slice()), index: 0 };
    row.record(layout, &mut cells);
    out.push('\n');
}

/// A group's test on a column name.
pub type ColumnTest = Box<dyn Fn(&str) -> bool>;

/// Which columns of a table are written (`--columns`): a mask over the table's columns, in table order.
#[derive(Clone, Debug, PartialEq)]
pub struct Selection {
    keep: Vec<bool>,
}

impl Selection {
    /// Keeps the columns of `names` that `wanted` lists, by name or by group (`group(item)` gives a group's
    /// test on a column name, None for an item that is not a group). An item that is neither a column nor a
    /// group is an error that lists both.
    pub fn new(
        names: &[String],
        wanted: &[&str],
        group: impl Fn(&str) -> Option<ColumnTest>,
        groups: &[&str],
    ) -> Result<Selection, String> {
        let mut keep = vec![false; names.len()];
        for item in wanted {
            let item = item.trim();
            let hits: Vec<usize> = match group(item) {
                Some(test) => (0..names.len()).filter(|&k| test(&names[k])).collect(),
                None => names.iter().position(|n| n == item).into_iter().collect(),
            };
            if hits.is_empty() {
                return Err(format!(
                    "`{item}` is neither a column of this table nor a group (groups: {}; columns: {})",
                    groups.join(", "),
                    names.join(",")
                ));
            }
            for k in hits {
                keep[k] = true;
            }
        }
        Ok(Selection { keep })
    }
}

/// Collects the columns.
struct Header(Vec<Column>);

impl Header {
    fn push(&mut self, name: impl Display, kind: CellKind) {
        self.0.push(Column { name: name.to_string(), kind });
    }
}

impl Record for Header {
    fn number(&mut self, name: impl Display, _: f64) {
        self.push(name, CellKind::Number);
    }
    fn optional(&mut self, name: impl Display, _: Option<f64>) {
        self.push(name, CellKind::Number);
    }
    fn count(&mut self, name: impl Display, _: Option<u64>) {
        self.push(name, CellKind::Count);
    }
    fn text(&mut self, name: impl Display, _: &str) {
        self.push(name, CellKind::Text);
    }
    fn matrix(&mut self, which: Matrix, _: Option<&Mat6>, part: Triangle) {
        for &(i, j) in matrix_entries(part) {
            match which {
                Matrix::Compliance => self.push(format_args!("C{i}{j}_{}", compliance_unit(i, j)), CellKind::Number),
                Matrix::Stiffness => self.push(format_args!("K{i}{j}_{}", stiffness_unit(i, j)), CellKind::Number),
            }
        }
    }
    fn free_directions(&mut self, name: impl Display, _: &[Vec6]) {
        self.push(name, CellKind::Text);
    }
}

/// Writes cell values (names unused: they are formatted only by `Header`).
struct Cells<'a> {
    out: &'a mut String,
    first: bool,
    /// The columns written (all where None), and the index of the next cell.
    keep: Option<&'a [bool]>,
    index: usize,
}

impl Cells<'_> {
    /// The buffer for the next cell, or None where the selection drops it.
    fn next(&mut self) -> Option<&mut String> {
        let k = self.index;
        self.index += 1;
        if self.keep.is_some_and(|keep| !keep.get(k).copied().unwrap_or(false)) {
            return None;
        }
        if !self.first {
            self.out.push(',');
        }
        self.first = false;
        Some(self.out)
    }
}

impl Record for Cells<'_> {
    fn number(&mut self, _: impl Display, v: f64) {
        if let Some(out) = self.next() {
            push_number(out, v);
        }
    }
    fn optional(&mut self, _: impl Display, v: Option<f64>) {
        if let (Some(out), Some(v)) = (self.next(), v) {
            push_number(out, v);
        }
    }
    fn count(&mut self, _: impl Display, v: Option<u64>) {
        if let (Some(out), Some(v)) = (self.next(), v) {
            out.push_str(itoa::Buffer::new().format(v));
        }
    }
    fn text(&mut self, _: impl Display, v: &str) {
        if let Some(out) = self.next() {
            push_text(out, v);
        }
    }
    fn matrix(&mut self, _: Matrix, m: Option<&Mat6>, part: Triangle) {
        for &(i, j) in matrix_entries(part) {
            if let (Some(out), Some(m)) = (self.next(), m) {
                push_number(out, m[(i - 1, j - 1)]);
            }
        }
    }
    fn free_directions(&mut self, _: impl Display, free: &[Vec6]) {
        if let Some(out) = self.next() {
            push_free_directions(out, free);
        }
    }
}

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

/// Which entries of a 6x6 matrix a block of columns holds (1-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Triangle {
    /// The 21 entries on and above the diagonal, row by row: all a symmetric matrix has.
    Upper,
    /// The 15 entries below it, row by row: what a non-symmetric matrix (a loaded tangent stiffness and its
    /// inverse) adds, appended after the upper ones so that loaded tables keep the unloaded columns in order.
    Lower,
}

/// The entries of a triangle, row by row (1-based): a fixed table, since every row of a map writes them.
pub fn matrix_entries(part: Triangle) -> &'static [(usize, usize)] {
    const UPPER: [(usize, usize); 21] = triangle(true);
    const LOWER: [(usize, usize); 15] = triangle(false);
    match part {
        Triangle::Upper => &UPPER,
        Triangle::Lower => &LOWER,
    }
}

/// The upper triangle with its diagonal (N = 21), or the strict lower triangle (N = 15), row by row.
const fn triangle<const N: usize>(upper: bool) -> [(usize, usize); N] {
    let mut out = [(0, 0); N];
    let (mut i, mut k) = (1, 0);
    while i <= 6 {
        let mut j = 1;
        while j <= 6 {
            if (upper && j >= i) || (!upper && j < i) {
                out[k] = (i, j);
                k += 1;
            }
            j += 1;
        }
        i += 1;
    }
    out
}

/// Appends one number in shortest round-trip form; nothing for a non-finite one (one rule for missing
/// values everywhere: an empty cell).
pub fn push_number(out: &mut String, v: f64) {
    if v == 0.0 {
        // Also -0.0 (a zero load times a negative direction): a zero has no sign worth printing.
        out.push_str("0.0");
    } else if v.is_finite() {
        let mut b = zmij::Buffer::new();
        let s = b.format_finite(v);
        // zmij writes a positive exponent, which only numbers from 1e16 up have, with a sign (1e+16); the
        // tables have always had none.
        match (v.abs() >= 1e16).then(|| s.split_once("e+")).flatten() {
            Some((mantissa, exponent)) => {
                out.push_str(mantissa);
                out.push('e');
                out.push_str(exponent);
            }
            None => out.push_str(s),
        }
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

#[cfg(test)]
mod tests {
    use super::{push_number, unit_of};

    /// The numbers of every table are written as the files written before (and the golden files) have
    /// them: the fewest significant digits that read back to the same double, in plain decimals from 1e-5
    /// up to 1e16 (with `.0` on an integer) and in scientific form outside, with no `+` in a positive
    /// exponent. The digit count is checked against the standard library's shortest form (`{:e}`), an
    /// independent route (the two may break an exact tie between two shortest forms differently), over
    /// every decade a table can hold and across both ends of the plain range.
    #[test]
    fn numbers_are_written_shortest_plain_between_1e_minus_5_and_1e16() {
        let significant = |s: &str| {
            let mantissa = s.split('e').next().unwrap().trim_start_matches('-').replace('.', "");
            mantissa.trim_start_matches('0').trim_end_matches('0').len()
        };
        let mut seed: u64 = 0x9e37_79b9_7f4a_7c15;
        let mut values = vec![1.0, -1.0, 0.5, 1e-5, 9.999999999999999e-6, 1e16, 9999999999999998.0, 1.5e16, 5e-324];
        // The last: ...651.25 exactly, a tie between two shortest forms (...651.2 and ...651.3).
        values.extend([f64::MAX, f64::MIN_POSITIVE, 123456.789, 0.1 + 0.2, -1_283_359_694_162_651.0 - 0.25]);
        for _ in 0..200_000 {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            let mantissa = (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            let decade = (seed % 64) as i32 - 32;
            values.push(mantissa * 10f64.powi(decade));
            values.push(f64::from_bits(seed)); // any bit pattern, subnormals and huge exponents included
        }
        for v in values.into_iter().filter(|v| v.is_finite() && *v != 0.0) {
            let mut written = String::new();
            push_number(&mut written, v);
            assert_eq!(written.parse::<f64>().unwrap(), v, "{written} reads back");
            assert_eq!(significant(&written), significant(&format!("{v:e}")), "{written}: shortest digits");
            assert!(!written.contains('+'), "{written}");
            if (1e-5..1e16).contains(&v.abs()) {
                assert!(!written.contains('e') && written.contains('.'), "{written}: plain");
            } else {
                let scientific = format!("{v:e}");
                assert_eq!(written.split_once('e').unwrap().1, scientific.split_once('e').unwrap().1, "{written}");
            }
        }
        let mut zero = String::new();
        push_number(&mut zero, -0.0);
        assert_eq!(zero, "0.0");
    }

    /// A column's unit is the suffix of its name: a plain unit, or `A_per_B` for a ratio; a name without
    /// one (`status`, `load_factor`, a quantity whose last word is not a unit) has none.
    #[test]
    fn units_are_read_from_column_names() {
        for (name, unit) in [
            ("x_mm", Some("mm")),
            ("pose_rx_rad", Some("rad")),
            ("Fx_N", Some("N")),
            ("Mz_Nmm", Some("Nmm")),
            ("C14_mm_per_Nmm", Some("mm_per_Nmm")),
            ("K66_Nmm_per_rad", Some("Nmm_per_rad")),
            ("c_tran_max_mm_per_N", Some("mm_per_N")),
            ("superposition_gap_mm", Some("mm")),
            ("status", None),
            ("load_factor", None),
            ("iterations", None),
            ("per_mm", Some("mm")),
            ("mm", None),
        ] {
            assert_eq!(unit_of(name), unit, "{name}");
        }
    }
}
