//! Pictures of studies, drawn from what the studies write (their CSV, or diagnose's JSON), so `--plot` on a
//! study and `stiff plot FILE` afterwards give the same picture: a colour map of a map column over grid
//! sections, a force-deflection curve with its events, the displacements along an assembly path (paper 000
//! Figures 10-11), and a diagnosis (residual arrows before and after, per-axis RMS, the candidates' delta BIC).
pub mod svg;

use crate::output::diagnosis::{DiagnosisReport, ResidualRms};
use anyhow::{anyhow, bail, Context, Result};

use crate::output::table::names;

use svg::{axes, frame, label, tick_label, unit_of, viridis, Axis, Svg};

/// A CSV held as text cells.
pub struct Table {
    /// Column names.
    pub header: Vec<String>,
    /// Cells, row by row.
    pub rows: Vec<Vec<String>>,
}

impl Table {
    /// Parses a CSV a study wrote.
    pub fn parse(text: &str) -> Result<Table> {
        let mut reader = csv::ReaderBuilder::new().from_reader(text.as_bytes());
        let header = reader.headers()?.iter().map(String::from).collect();
        let rows =
            reader.records().map(|r| r.map(|r| r.iter().map(String::from).collect())).collect::<Result<_, _>>()?;
        Ok(Table { header, rows })
    }

    /// Whether a column of this name exists.
    pub fn has(&self, c: &str) -> bool {
        self.header.iter().any(|h| h == c)
    }

    fn index(&self, c: &str) -> Result<usize> {
        self.header
            .iter()
            .position(|h| h == c)
            .ok_or_else(|| anyhow!("no column `{c}` (columns: {})", self.header.join(", ")))
    }

    /// A numeric column; empty or non-numeric cells are None.
    fn numbers(&self, c: &str) -> Result<Vec<Option<f64>>> {
        let i = self.index(c)?;
        Ok(self.rows.iter().map(|r| r.get(i).and_then(|v| v.parse::<f64>().ok()).filter(|v| v.is_finite())).collect())
    }

    fn texts(&self, c: &str) -> Result<Vec<String>> {
        let i = self.index(c)?;
        Ok(self.rows.iter().map(|r| r.get(i).cloned().unwrap_or_default()).collect())
    }
}

/// What to draw and how.
#[derive(Clone, Debug, Default)]
pub struct PlotOptions {
    /// Map: the column to colour (default: largest translational compliance).
    pub column: Option<String>,
    /// Map: a planar section `axis=value`, e.g. `z=0`.
    pub section: Option<String>,
    /// Curve: the displacement axis (x, y, z, rx, ry, rz; default: the one that moves most).
    pub direction: Option<String>,
}

/// The map column drawn when `--plot-column` is not given.
const DEFAULT_MAP_COLUMN: &str = names::C_TRAN_MAX;

/// Draws a study's output: a map, curve or assemble CSV, or a diagnose JSON.
pub fn plot_text(text: &str, o: &PlotOptions) -> Result<String> {
    if text.trim_start().starts_with('{') {
        let report: DiagnosisReport =
            serde_json::from_str(text).context("reading the diagnosis JSON (written by stiff diagnose --json?)")?;
        return diagnosis(&report);
    }
    let t = Table::parse(text)?;
    // Each study's table has a column no other has (`output::table::names`).
    if t.has(names::LOAD_FACTOR) {
        curve(&t, o)
    } else if t.has(&format!("{}_{}", names::NONLINEAR, names::DISPLACEMENT[0])) {
        assembly(&t)
    } else if t.has(DEFAULT_MAP_COLUMN) || o.column.as_deref().is_some_and(|c| t.has(c)) {
        map(&t, o)
    } else {
        bail!("not a map, curve, assemble CSV or diagnose JSON (columns: {})", t.header.join(", "))
    }
}

const AXES: [&str; 3] = ["x", "y", "z"];

fn distinct(values: &[f64]) -> Vec<f64> {
    let mut v: Vec<f64> = values.to_vec();
    v.sort_by(f64::total_cmp);
    v.dedup_by(|a, b| (*a - *b).abs() <= 1e-9 * (1.0 + a.abs()));
    v
}

/// Largest minus smallest value (negative infinity when there is none).
fn extent(values: impl Iterator<Item = f64>) -> f64 {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    hi - lo
}

fn spacing(values: &[f64]) -> f64 {
    let d = distinct(values);
    d.windows(2).map(|w| w[1] - w[0]).fold(f64::INFINITY, f64::min)
}

/// A picture option that cannot be used: the command line names its flag (`PlotOptions` field).
#[derive(Clone, Debug, PartialEq)]
pub enum OptionError {
    /// The section is not AXIS=VALUE with a finite value.
    Section(String),
    /// The map has no such column.
    Column {
        /// The column asked for.
        column: String,
        /// The columns the map has.
        columns: String,
    },
    /// The curve direction is not one of x, y, z, rx, ry, rz.
    Direction(String),
}

impl std::fmt::Display for OptionError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            OptionError::Section(why) => f.write_str(why),
            OptionError::Column { column, columns } => {
                write!(f, "the map has no column `{column}` (columns: {columns})")
            }
            OptionError::Direction(d) => write!(f, "`{d}` is not one of x, y, z, rx, ry, rz"),
        }
    }
}

impl std::error::Error for OptionError {}

/// A section AXIS=VALUE: the axis (0, 1, 2 for x, y, z) and the value (mm).
pub fn parse_section(s: &str) -> Result<(usize, f64), OptionError> {
    let bad = |why: String| OptionError::Section(why);
    let (a, v) = s.split_once('=').ok_or_else(|| bad("wants AXIS=VALUE, e.g. z=0".into()))?;
    let axis = AXES.iter().position(|x| *x == a.trim()).ok_or_else(|| bad("the axis must be x, y or z".into()))?;
    let v: f64 = v.trim().parse().map_err(|_| bad(format!("value `{v}` is not a number")))?;
    if !v.is_finite() {
        return Err(bad(format!("value `{v}` is not a finite number")));
    }
    Ok((axis, v))
}

/// Checks a map picture's options against the header of the map that will be written, before the map is
/// computed (a bad `--section` used to fail after a million-point map was written).
pub fn check_map_options(header: &str, o: &PlotOptions) -> Result<()> {
    if let Some(s) = &o.section {
        parse_section(s)?;
    }
    let column = o.column.as_deref().unwrap_or(DEFAULT_MAP_COLUMN);
    if !header.trim_end().split(',').any(|h| h == column) {
        return Err(OptionError::Column { column: column.into(), columns: header.trim_end().into() }.into());
    }
    Ok(())
}

/// A colour map of one column over planar sections of the grid (one panel per section).
fn map(t: &Table, o: &PlotOptions) -> Result<String> {
    let column = o.column.clone().unwrap_or_else(|| DEFAULT_MAP_COLUMN.to_string());
    let values = t.numbers(&column)?;
    let coords: Vec<Vec<f64>> = names::POSITION
        .iter()
        .map(|c| t.numbers(c).map(|v| v.into_iter().map(|x| x.unwrap_or(f64::NAN)).collect()))
        .collect::<Result<_>>()?;
    // The section axis: given, else the single-valued axis, else z (small multiples over its values).
    let (axis, levels) = match &o.section {
        Some(s) => {
            let (axis, v) = parse_section(s)?;
            let a = AXES[axis];
            let levels = distinct(&coords[axis]);
            let nearest = levels
                .iter()
                .copied()
                .min_by(|a, b| (a - v).abs().total_cmp(&(b - v).abs()))
                .ok_or_else(|| anyhow!("empty map"))?;
            let tol = 0.01 * spacing(&coords[axis]).min(1e9);
            if (nearest - v).abs() > tol.max(1e-9 * (1.0 + v.abs())) {
                let shown: Vec<String> = levels.iter().take(12).map(|l| tick_label(*l)).collect();
                bail!("no grid section at {a} = {v} mm (sections: {})", shown.join(", "));
            }
            (axis, vec![nearest])
        }
        None => {
            let axis = (0..3).find(|&a| distinct(&coords[a]).len() == 1).unwrap_or(2);
            let levels = distinct(&coords[axis]);
            let picked: Vec<f64> =
                if levels.len() <= 6 { levels } else { (0..6).map(|k| levels[k * (levels.len() - 1) / 5]).collect() };
            (axis, picked)
        }
    };
    let (u, v) = match axis {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    // The colour scale covers the sections drawn.
    let drawn = |i: usize| levels.iter().any(|l| (coords[axis][i] - l).abs() <= 1e-9 * (1.0 + l.abs()));
    let finite: Vec<f64> = (0..values.len()).filter(|&i| drawn(i)).filter_map(|i| values[i]).collect();
    let (lo, hi) = finite.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(*x), b.max(*x)));
    let (lo, hi) = if lo.is_finite() && hi > lo {
        (lo, hi)
    } else if lo.is_finite() {
        (lo - 0.5 * lo.abs().max(1e-12), hi + 0.5 * hi.abs().max(1e-12))
    } else {
        (0.0, 1.0)
    };
    let cols = levels.len().min(3);
    let rows = levels.len().div_ceil(3);
    let (panel, gap, left, top) = (240.0, 80.0, 80.0, 50.0);
    let width = left + cols as f64 * (panel + gap) + 120.0;
    let height = top + rows as f64 * (panel + gap) + 10.0;
    let mut s = Svg::new(width, height);
    s.text(width / 2.0, 22.0, &format!("{} over sections {} = const", label(&column), AXES[axis]), 14.0, "middle", 0.0);
    let (du, dv) = (spacing(&coords[u]), spacing(&coords[v]));
    for (k, level) in levels.iter().enumerate() {
        let x0 = left + (k % 3) as f64 * (panel + gap);
        let y0 = top + (k / 3) as f64 * (panel + gap);
        let members: Vec<usize> =
            (0..values.len()).filter(|&i| (coords[axis][i] - level).abs() <= 1e-9 * (1.0 + level.abs())).collect();
        let us: Vec<f64> = members.iter().map(|&i| coords[u][i]).collect();
        let vs: Vec<f64> = members.iter().map(|&i| coords[v][i]).collect();
        let (du, dv) = (if du.is_finite() { du } else { 1.0 }, if dv.is_finite() { dv } else { 1.0 });
        let ax = Axis::new(us.iter().map(|x| x - du / 2.0).chain(us.iter().map(|x| x + du / 2.0)), x0, x0 + panel);
        let ay = Axis::new(vs.iter().map(|x| x - dv / 2.0).chain(vs.iter().map(|x| x + dv / 2.0)), y0 + panel, y0);
        for &i in &members {
            let (cx, cy) = (ax.px(coords[u][i] - du / 2.0), ay.px(coords[v][i] + dv / 2.0));
            let (w, h) = (ax.px(coords[u][i] + du / 2.0) - cx, ay.px(coords[v][i] - dv / 2.0) - cy);
            let fill = match values[i] {
                Some(x) => viridis((x - lo) / (hi - lo)),
                None => "#d0d0d0".to_string(),
            };
            // A hair of overlap so anti-aliasing leaves no seams between cells.
            s.rect(cx, cy, w + 0.6, h + 0.6, &fill, "cell");
        }
        axes(&mut s, &ax, &ay, &format!("{} [mm]", AXES[u]), &format!("{} [mm]", AXES[v]));
        s.text(x0 + panel / 2.0, y0 - 8.0, &format!("{} = {} mm", AXES[axis], tick_label(*level)), 12.0, "middle", 0.0);
    }
    // Colour bar with its unit; grey = no value (status not ok).
    let (bx, by, bh) = (width - 100.0, top, 200.0);
    for k in 0..50 {
        let f = k as f64 / 49.0;
        s.rect(bx, by + bh * (1.0 - f) - bh / 50.0, 16.0, bh / 50.0 + 0.5, &viridis(f), "colorbar");
    }
    let bar = Axis { lo, hi, from: by + bh, to: by };
    for tv in bar.ticks() {
        s.text(bx + 20.0, bar.px(tv) + 4.0, &tick_label(tv), 10.0, "start", 0.0);
    }
    let (_, unit) = unit_of(&column);
    s.text(bx + 8.0, by + bh + 18.0, &format!("[{unit}]"), 11.0, "middle", 0.0);
    s.rect(bx, by + bh + 28.0, 16.0, 10.0, "#d0d0d0", "legend");
    s.text(bx + 20.0, by + bh + 37.0, "not ok", 10.0, "start", 0.0);
    Ok(s.finish())
}

/// Force against displacement along one direction: stable branches solid, unstable dashed, events marked.
fn curve(t: &Table, o: &PlotOptions) -> Result<String> {
    let names = ["x", "y", "z", "rx", "ry", "rz"];
    let (disp, force) = (names::DISPLACEMENT, names::WRENCH);
    let k = match &o.direction {
        Some(d) => names.iter().position(|n| n == d).ok_or_else(|| OptionError::Direction(d.clone()))?,
        None => {
            let range = |c: &str| extent(t.numbers(c).unwrap_or_default().into_iter().flatten());
            (0..3).max_by(|a, b| range(disp[*a]).total_cmp(&range(disp[*b]))).unwrap_or(0)
        }
    };
    let x: Vec<f64> = t.numbers(disp[k])?.into_iter().map(|v| v.unwrap_or(f64::NAN)).collect();
    let y: Vec<f64> = t.numbers(force[k])?.into_iter().map(|v| v.unwrap_or(f64::NAN)).collect();
    let stable = t.texts(names::STABLE)?;
    let events = t.texts(names::EVENT)?;
    let (w, h, left, top) = (640.0, 440.0, 90.0, 40.0);
    let mut s = Svg::new(w, h);
    let ax = Axis::new(x.iter().copied(), left, w - 30.0);
    let ay = Axis::new(y.iter().copied(), h - 60.0, top);
    s.text(w / 2.0, 22.0, &format!("force-deflection along {}", names[k]), 14.0, "middle", 0.0);
    // Consecutive rows of equal stability as one polyline, each joined to the next segment's first point.
    let mut start = 0;
    while start < x.len() {
        let flag = &stable[start];
        let mut end = start;
        while end + 1 < x.len() && &stable[end + 1] == flag {
            end += 1;
        }
        let last = (end + 1).min(x.len() - 1);
        let pts: Vec<(f64, f64)> = (start..=last)
            .filter(|&i| x[i].is_finite() && y[i].is_finite())
            .map(|i| (ax.px(x[i]), ay.px(y[i])))
            .collect();
        let unstable = flag != "true";
        s.polyline(
            &pts,
            if unstable { "#c0392b" } else { "#1f5fa8" },
            2.0,
            unstable,
            if unstable { "unstable" } else { "stable" },
        );
        start = end + 1;
    }
    for (i, e) in events.iter().enumerate() {
        if !e.is_empty() && x[i].is_finite() && y[i].is_finite() {
            s.circle(ax.px(x[i]), ay.px(y[i]), 5.0, "#e67e22", "event");
            s.text(ax.px(x[i]) + 8.0, ay.px(y[i]) - 8.0, e, 11.0, "start", 0.0);
        }
    }
    axes(&mut s, &ax, &ay, &label(disp[k]), &label(force[k]));
    s.line((w - 200.0, top + 10.0), (w - 170.0, top + 10.0), "#1f5fa8", 2.0, "legend");
    s.text(w - 165.0, top + 14.0, "stable", 11.0, "start", 0.0);
    s.polyline(&[(w - 200.0, top + 28.0), (w - 170.0, top + 28.0)], "#c0392b", 2.0, true, "legend");
    s.text(w - 165.0, top + 32.0, "unstable", 11.0, "start", 0.0);
    Ok(s.finish())
}

/// Displacements along an assembly path (paper 000 Figures 10-11): one panel per axis x, y, z.
fn assembly(t: &Table) -> Result<String> {
    let coords: Vec<Vec<f64>> = names::POSITION
        .iter()
        .map(|c| t.numbers(c).map(|v| v.into_iter().map(|x| x.unwrap_or(f64::NAN)).collect()))
        .collect::<Result<_>>()?;
    // Along the path: the coordinate that varies most.
    let range = |v: &Vec<f64>| extent(v.iter().copied());
    let along = (0..3).max_by(|a, b| range(&coords[*a]).total_cmp(&range(&coords[*b]))).unwrap_or(0);
    let s_values = &coords[along];
    let series: Vec<(&str, &str, &str, bool)> = vec![
        ("nl_d", "assembly errors (non-linear)", "#8e44ad", false),
        ("load_d", "cutting load", "#27ae60", false),
        ("total_d", "total", "#c0392b", false),
        ("super_d", "superposition", "#2c3e50", true),
    ];
    let series: Vec<_> = series.into_iter().filter(|(p, ..)| t.has(&format!("{p}x_mm"))).collect();
    let (w, panel_h, left, top) = (760.0, 210.0, 90.0, 40.0);
    let h = top + 3.0 * (panel_h + 60.0) + 40.0;
    let mut s = Svg::new(w, h);
    s.text(w / 2.0 - 60.0, 22.0, "displacement along the path (target = 0)", 14.0, "middle", 0.0);
    for (row, a) in AXES.iter().enumerate() {
        let y0 = top + row as f64 * (panel_h + 60.0);
        let data: Vec<Vec<Option<f64>>> =
            series.iter().map(|(p, ..)| t.numbers(&format!("{p}{a}_mm"))).collect::<Result<_>>()?;
        let ax = Axis::new(s_values.iter().copied(), left, w - 250.0);
        let ay = Axis::new(data.iter().flatten().flatten().copied().chain(std::iter::once(0.0)), y0 + panel_h, y0);
        s.line((ax.from, ay.px(0.0)), (ax.to, ay.px(0.0)), "#999", 1.0, "target");
        for ((_, _, colour, dashed), d) in series.iter().zip(&data) {
            let pts: Vec<(f64, f64)> =
                s_values.iter().zip(d).filter_map(|(x, y)| y.map(|y| (ax.px(*x), ay.px(y)))).collect();
            s.polyline(&pts, colour, 2.0, *dashed, "series");
        }
        axes(&mut s, &ax, &ay, &format!("{} [mm] along the path", AXES[along]), &format!("d{a} [mm]"));
    }
    let lx = w - 235.0;
    s.line((lx, top + 10.0), (lx + 25.0, top + 10.0), "#999", 1.0, "legend");
    s.text(lx + 30.0, top + 14.0, "target path", 11.0, "start", 0.0);
    for (k, (_, name, colour, dashed)) in series.iter().enumerate() {
        let yy = top + 28.0 + 18.0 * k as f64;
        s.polyline(&[(lx, yy), (lx + 25.0, yy)], colour, 2.0, *dashed, "legend");
        s.text(lx + 30.0, yy + 4.0, name, 11.0, "start", 0.0);
    }
    Ok(s.finish())
}

/// Residual arrows over the workspace (before red, after blue) on the plane of the two axes the poses
/// spread most over; per-axis RMS before and after; the candidates' delta BIC.
pub fn diagnosis(v: &DiagnosisReport) -> Result<String> {
    let pos: Vec<[f64; 3]> = v.residuals.iter().map(|r| r.position_mm).collect();
    let spread = |k: usize| extent(pos.iter().map(|p| p[k]));
    let mut order = [0usize, 1, 2];
    order.sort_by(|a, b| spread(*b).total_cmp(&spread(*a)));
    let (u, w_axis) = (order[0].min(order[1]), order[0].max(order[1]));
    let (width, height) = (1010.0, 470.0);
    let mut s = Svg::new(width, height);
    let named: Vec<String> = v
        .effects
        .iter()
        .map(|e| if e.target.is_empty() { e.name.clone() } else { format!("{}:{}", e.name, e.target) })
        .collect();
    let title = format!(
        "verdict: {}{}",
        v.verdict,
        if named.is_empty() { String::new() } else { format!(" ({})", named.join(", ")) }
    );
    s.text(width / 2.0, 20.0, &title, 13.0, "middle", 0.0);
    let (y0, size) = (60.0, 330.0);
    quiver(&mut s, v, (u, w_axis), y0, size);
    rms_bars(&mut s, &v.rms_mm, y0, size);
    delta_bic_bars(&mut s, v, y0, size);
    Ok(s.finish())
}

/// Residual arrows at each pose on the plane of axes `(u, w)`: before red, after blue, with a key.
fn quiver(s: &mut Svg, v: &DiagnosisReport, (u, w_axis): (usize, usize), y0: f64, size: f64) {
    let pos: Vec<[f64; 3]> = v.residuals.iter().map(|r| r.position_mm).collect();
    let before: Vec<[f64; 3]> = v.residuals.iter().map(|r| r.before_mm).collect();
    let after: Vec<[f64; 3]> = v.residuals.iter().map(|r| r.after_mm).collect();
    let x0 = 80.0;
    let ax = Axis::new(pos.iter().map(|p| p[u]), x0, x0 + size);
    let ay = Axis::new(pos.iter().map(|p| p[w_axis]), y0 + size, y0);
    let longest = before.iter().chain(&after).map(|d| (d[u] * d[u] + d[w_axis] * d[w_axis]).sqrt()).fold(0.0, f64::max);
    let scale = if longest > 0.0 { 0.12 * size / longest } else { 1.0 };
    for (p, (b, a)) in pos.iter().zip(before.iter().zip(&after)) {
        let (px, py) = (ax.px(p[u]), ay.px(p[w_axis]));
        s.circle(px, py, 2.0, "#555", "pose");
        s.arrow(px, py, px + b[u] * scale, py - b[w_axis] * scale, "#c0392b", "before");
        s.arrow(px, py, px + a[u] * scale, py - a[w_axis] * scale, "#1f5fa8", "after");
    }
    axes(s, &ax, &ay, &format!("{} [mm]", AXES[u]), &format!("{} [mm]", AXES[w_axis]));
    let key = longest / 2.0;
    s.line((x0, y0 + size + 50.0), (x0 + key * scale, y0 + size + 50.0), "#333", 2.0, "key");
    s.text(
        x0 + key * scale + 6.0,
        y0 + size + 54.0,
        &format!("{} mm residual (largest residual per pose: red before, blue after)", tick_label(key)),
        10.0,
        "start",
        0.0,
    );
}

/// Residual RMS per axis: fit before / held-out before / fit after / held-out after.
fn rms_bars(s: &mut Svg, rms: &ResidualRms, y0: f64, size: f64) {
    let (rb, ra, hb, ha) = (rms.fit_before, rms.fit_after, rms.heldout_before, rms.heldout_after);
    let (bx, bw) = (490.0, 170.0);
    let rms_axis =
        Axis::new(rb.iter().chain(&ra).chain(&hb).chain(&ha).copied().chain(std::iter::once(0.0)), y0 + size, y0);
    let cat = Axis { lo: -0.5, hi: 2.5, from: bx, to: bx + bw };
    for k in 0..3 {
        let c = cat.px(k as f64);
        for (off, value, colour) in
            [(-18.0, rb[k], "#c0392b"), (-6.0, hb[k], "#e8a09a"), (6.0, ra[k], "#1f5fa8"), (18.0, ha[k], "#9fbfe6")]
        {
            let top_px = rms_axis.px(value);
            s.rect(c + off - 5.0, top_px, 10.0, rms_axis.px(0.0) - top_px, colour, "rms-bar");
        }
        s.text(c, y0 + size + 16.0, AXES[k], 11.0, "middle", 0.0);
    }
    frame(s, &cat, &rms_axis, "axis", "residual RMS [mm]", false, true);
    s.text(bx, y0 - 10.0, "RMS: fit before / held-out before / fit after / held-out after", 9.0, "start", 0.0);
}

/// The identifiable candidates' delta BIC on a signed log scale; passing ones green, the -10 line red.
fn delta_bic_bars(s: &mut Svg, v: &DiagnosisReport, y0: f64, size: f64) {
    let rows: Vec<(String, f64, bool)> = v
        .candidates
        .iter()
        .filter(|c| c.identifiable)
        .filter_map(|c| Some((c.candidate.clone(), c.delta_bic?, c.passes)))
        .collect();
    let (cx, cw) = (760.0, 190.0);
    let n = rows.len().max(1) as f64;
    // Signed logarithmic scale: delta BIC spans from -10 to -1e5 and more.
    let slog = |d: f64| d.signum() * (1.0 + d.abs()).log10();
    let bic = Axis::new(rows.iter().map(|r| slog(r.1)).chain([0.0, slog(-10.0)]), cx, cx + cw);
    let row_h = size / n;
    for (k, (name, d, passes)) in rows.iter().enumerate() {
        let yy = y0 + row_h * k as f64;
        let (a, b) = (bic.px(0.0), bic.px(slog(*d)));
        s.rect(
            a.min(b),
            yy + 0.15 * row_h,
            (a - b).abs(),
            0.7 * row_h,
            if *passes { "#27ae60" } else { "#95a5a6" },
            "bic-bar",
        );
        s.text(cx - 6.0, yy + 0.65 * row_h, name, 9.0, "end", 0.0);
    }
    s.line((bic.px(slog(-10.0)), y0), (bic.px(slog(-10.0)), y0 + size), "#c0392b", 1.0, "threshold");
    let ay_cat = Axis { lo: 0.0, hi: 1.0, from: y0 + size, to: y0 };
    frame(s, &bic, &ay_cat, "delta BIC (log scale; green: passes; red line: -10)", "", false, false);
    for e in 0..8 {
        for sign in [-1.0, 1.0] {
            let d = sign * 10f64.powi(e);
            let x = slog(d);
            if x >= bic.lo && x <= bic.hi && e % 2 == 1 {
                let p = bic.px(x);
                s.line((p, y0 + size), (p, y0 + size + 4.0), "#333", 1.0, "tick");
                s.text(p, y0 + size + 16.0, &format!("{}1e{e}", if sign < 0.0 { "-" } else { "" }), 9.0, "middle", 0.0);
            }
        }
    }
}
