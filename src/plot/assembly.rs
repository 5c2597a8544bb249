//! Displacements along a path (paper 000 Figures 10-11): one panel per axis x, y, z, with the target path
//! and a line per series. An assembly draws the assembly errors' displacement, the cutting load's, the
//! total and the superposition; a compensation (`compensation.rs`) the error without and with it.

use anyhow::Result;

use super::svg::{axes, text_width, Axis, Svg};
use super::table::Table;
use super::{extent, heading, PlotOptions, AXES};

/// The series of an assembly path: assembly errors, cutting load, total, superposition (columns
/// `{name}_dx_mm` ...).
pub const SERIES: [&str; 4] = ["nl", "load", "total", "super"];

/// One line on every panel: the columns `{columns}_dx_mm` ... along the path.
pub struct Series {
    /// The columns' prefix.
    pub columns: &'static str,
    /// The legend's text.
    pub name: String,
    /// Its colour.
    pub colour: &'static str,
    /// Drawn dashed.
    pub dashed: bool,
}

/// The path picture of an assembly table whose poses lie on a line.
pub fn assembly_path(t: &Table, o: &PlotOptions) -> Result<String> {
    let series = [
        ("nl", "assembly errors (non-linear)", "#8e44ad", false),
        ("load", "cutting load", "#27ae60", false),
        ("total", "total", "#c0392b", false),
        ("super", "superposition", "#2c3e50", true),
    ]
    .into_iter()
    .map(|(columns, name, colour, dashed)| Series { columns, name: name.into(), colour, dashed })
    .collect();
    path_panels(t, o, "displacement along the path (target = 0)", series)
}

/// Panels x, y, z of the series a table has, along the coordinate its poses vary most in.
pub fn path_panels(t: &Table, o: &PlotOptions, what: &str, series: Vec<Series>) -> Result<String> {
    let coords = t.positions()?;
    // Along the path: the coordinate that varies most.
    let range = |v: &[f64]| extent(v.iter().copied());
    let along = (0..3).max_by(|a, b| range(coords[*a]).total_cmp(&range(coords[*b]))).unwrap_or(0);
    let s_values = coords[along];
    let series: Vec<Series> = series.into_iter().filter(|s| t.has(&format!("{}_dx_mm", s.columns))).collect();
    let data: Vec<Vec<Vec<Option<f64>>>> = AXES
        .iter()
        .map(|a| series.iter().map(|s| t.numbers(&format!("{}_d{a}_mm", s.columns))).collect::<Result<_>>())
        .collect::<Result<_>>()?;
    // Rows in order along the path (a points file may list them in any order).
    let mut order: Vec<usize> = (0..s_values.len()).collect();
    order.sort_by(|a, b| s_values[*a].total_cmp(&s_values[*b]));
    let widest_tick = data
        .iter()
        .map(|d| Axis::new(d.iter().flatten().flatten().copied().chain([0.0]), 0.0, 1.0))
        .map(|a| a.widest_label(11.0))
        .fold(0.0, f64::max);
    let (panel_w, panel_h) = (600.0, 200.0);
    let left = 40.0 + widest_tick;
    let w = left + panel_w + 30.0;
    let mut s = Svg::new(w, 0.0);
    let mut top = heading(&mut s, w, o, what) + 14.0;
    // The legend in rows above the panels: only the series drawn.
    let mut entries: Vec<(&str, &str, bool)> = vec![("target path", "#999", false)];
    entries.extend(series.iter().map(|s| (s.name.as_str(), s.colour, s.dashed)));
    let mut lx = left;
    for (name, colour, dashed) in entries {
        let need = 30.0 + text_width(name, 11.0) + 18.0;
        if lx + need > w - 10.0 {
            lx = left;
            top += 18.0;
        }
        s.polyline(
            &[(lx, top), (lx + 25.0, top)],
            colour,
            if name == "target path" { 1.0 } else { 2.0 },
            dashed,
            "legend",
        );
        s.text(lx + 30.0, top + 4.0, name, 11.0, "start", 0.0);
        lx += need;
    }
    top += 22.0;
    s.height = top + 3.0 * (panel_h + 60.0) + 10.0;
    for (row, a) in AXES.iter().enumerate() {
        let y0 = top + row as f64 * (panel_h + 60.0);
        let ax = Axis::new(s_values.iter().copied(), left, left + panel_w);
        let ay = Axis::new(data[row].iter().flatten().flatten().copied().chain(std::iter::once(0.0)), y0 + panel_h, y0);
        s.line((ax.from, ay.px(0.0)), (ax.to, ay.px(0.0)), "#999", 1.0, "target");
        for (line, d) in series.iter().zip(&data[row]) {
            let pts: Vec<(f64, f64)> =
                order.iter().filter_map(|&i| d[i].map(|y| (ax.px(s_values[i]), ay.px(y)))).collect();
            s.polyline(&pts, line.colour, 2.0, line.dashed, "series");
        }
        axes(&mut s, &ax, &ay, &format!("{} [mm] along the path", AXES[along]), &format!("d{a} [mm]"));
    }
    Ok(s.finish())
}
