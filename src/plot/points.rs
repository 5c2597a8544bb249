//! Pictures of a quantity over poses (a map, an assembly over a grid or points, a tolerance study), chosen
//! by where the poses lie: named poses as a labelled dot chart, a full grid as colour maps over its
//! sections, poses on a line as a line chart against their coordinate, other poses as markers coloured by
//! value. A single unnamed pose has no picture: it is refused with what to do instead.

use anyhow::{anyhow, bail, Result};

use super::png::Raster;
use super::scale::ColourScale;
use super::svg::{axes, label, text_width, tick_label, unit_of, Axis, Svg};
use super::table::{Table, TableKind};
use super::{distinct, heading, parse_section, OptionError, PlotOptions, AXES};
use crate::output::table::names;

/// Above this many cells in one section, the section is drawn as one embedded image (a rectangle per cell
/// makes a 1M-point map a 5 MB SVG that viewers take seconds to draw).
pub const RASTER_CELLS: usize = 2500;

/// Grey of a pose without a value (its status is not ok).
const NO_VALUE: &str = "#d0d0d0";

/// The values drawn and how they are named.
pub struct Quantity {
    /// Axis or colour-bar label with its unit, e.g. `c_tran_max [mm/N]`.
    pub label: String,
    /// The unit alone (`mm/N`; empty for a dimensionless column).
    pub unit: String,
    /// One value per row; None where the row has none.
    pub values: Vec<Option<f64>>,
}

/// The column drawn: `column` where given, else the table's default (a map's largest translational
/// compliance, a tolerance study's mean displacement, an assembly's non-linear displacement length).
pub fn quantity(t: &Table, kind: TableKind, column: Option<&str>) -> Result<Quantity> {
    let named = |c: &str| -> Result<Quantity> {
        if !t.has(c) {
            return Err(OptionError::Column { column: c.into(), columns: t.header.join(",") }.into());
        }
        Ok(Quantity { label: label(c), unit: unit_of(c).1, values: t.numbers(c)? })
    };
    match (column, default_column(kind)) {
        (Some(c), _) => named(c),
        (None, Some(c)) => named(c),
        (None, None) => {
            let parts: Vec<Vec<Option<f64>>> = ["dx_mm", "dy_mm", "dz_mm"]
                .iter()
                .map(|c| t.numbers(&format!("{}_{c}", names::NONLINEAR)))
                .collect::<Result<_>>()?;
            let values = (0..t.len())
                .map(|i| Some((parts[0][i]?.powi(2) + parts[1][i]?.powi(2) + parts[2][i]?.powi(2)).sqrt()))
                .collect();
            Ok(Quantity {
                label: "assembly displacement |(nl_dx, nl_dy, nl_dz)| [mm]".into(),
                unit: "mm".into(),
                values,
            })
        }
    }
}

/// The column a picture of this table draws by default; None for an assembly, whose default is the
/// length of its non-linear displacement (`quantity`).
pub fn default_column(kind: TableKind) -> Option<&'static str> {
    match kind {
        TableKind::Samples => Some("displacement_mean_mm"),
        TableKind::Compensation => Some("uncompensated_error_mm"),
        TableKind::Assembly => None,
        TableKind::Map | TableKind::Curve => Some(names::C_TRAN_MAX),
    }
}

/// Where the poses lie.
enum Shape {
    /// A full lattice over two or three axes.
    Grid,
    /// On one line: the coordinate of each pose along it, and its label.
    Line(Vec<f64>, String),
    /// Anywhere else: drawn on the plane of the two axes they spread most over.
    Scatter(usize, usize),
    /// Several rows at one pose.
    OnePose,
}

/// The distinct coordinates of the poses along each axis, sorted.
type Levels = [Vec<f64>; 3];

/// The rows' positions, one column per axis, as the table keeps them.
type Positions<'a> = [&'a [f64]; 3];

fn levels_of(pos: &Positions) -> Levels {
    [distinct(pos[0]), distinct(pos[1]), distinct(pos[2])]
}

/// The poses' shape (at least two poses with finite positions).
fn shape(pos: &Positions, levels: &Levels) -> Shape {
    let n = pos[0].len();
    let counts: Vec<usize> = levels.iter().map(Vec::len).collect();
    let varying: Vec<usize> = (0..3).filter(|&a| counts[a] > 1).collect();
    if varying.len() == 1 {
        let a = varying[0];
        return Shape::Line(pos[a].to_vec(), format!("{} [mm]", AXES[a]));
    }
    if counts.iter().product::<usize>() == n {
        return Shape::Grid;
    }
    // Collinear: every pose within a small tolerance of the line through the first and the farthest pose.
    let p = |i: usize| [pos[0][i], pos[1][i], pos[2][i]];
    let d = |a: [f64; 3], b: [f64; 3]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
    let first = p(0);
    let far = (0..n).max_by(|&i, &j| d(first, p(i)).total_cmp(&d(first, p(j)))).unwrap_or(0);
    let length = d(first, p(far));
    if length == 0.0 {
        return Shape::OnePose;
    }
    let dir = [(p(far)[0] - first[0]) / length, (p(far)[1] - first[1]) / length, (p(far)[2] - first[2]) / length];
    let along: Vec<f64> = (0..n).map(|i| (0..3).map(|k| (p(i)[k] - first[k]) * dir[k]).sum()).collect();
    let off_line = (0..n).map(|i| {
        let q = [first[0] + along[i] * dir[0], first[1] + along[i] * dir[1], first[2] + along[i] * dir[2]];
        d(q, p(i))
    });
    if off_line.fold(0.0, f64::max) <= 1e-9 * length.max(1.0) {
        let from = format!("({}, {}, {})", tick_label(first[0]), tick_label(first[1]), tick_label(first[2]));
        return Shape::Line(along, format!("distance along the line from {from} mm [mm]"));
    }
    let spread = |a: usize| super::extent(pos[a].iter().copied());
    let mut order = [0usize, 1, 2];
    order.sort_by(|a, b| spread(*b).total_cmp(&spread(*a)));
    Shape::Scatter(order[0].min(order[1]), order[0].max(order[1]))
}

/// Whether the table's poses are a path: two or more unnamed poses on one line.
pub fn is_path(t: &Table) -> Result<bool> {
    let pos = t.positions()?;
    Ok(pos[0].len() >= 2
        && !all_named(t)?
        && pos.iter().all(|c| c.iter().all(|v| v.is_finite()))
        && matches!(shape(&pos, &levels_of(&pos)), Shape::Line(..)))
}

/// Whether every row has a name.
fn all_named(t: &Table) -> Result<bool> {
    Ok(t.has(names::NAME) && t.text_cells(names::NAME)?.all(|s| !s.is_empty()))
}

/// The picture of `q` over the table's poses.
pub fn picture(t: &Table, q: &Quantity, o: &PlotOptions) -> Result<String> {
    let pos = t.positions()?;
    let n = t.len();
    if n == 0 {
        bail!("the table has no rows: nothing to draw");
    }
    if (0..n).any(|i| pos.iter().any(|c| !c[i].is_finite())) {
        bail!("every row needs a position (x_mm, y_mm, z_mm) to be drawn");
    }
    if all_named(t)? {
        return dot_chart(&t.texts(names::NAME)?, q, o);
    }
    if n == 1 {
        bail!(
            "a single point has no map picture: its numbers are the table's one row (`stiff point` reports a \
             pose in full)"
        );
    }
    let levels = levels_of(&pos);
    let shape = shape(&pos, &levels);
    if o.section.is_some() && !matches!(shape, Shape::Grid) {
        bail!("--section cuts a grid, and these points are not a full grid");
    }
    match shape {
        Shape::Grid => grid_map(&pos, &levels, q, o),
        Shape::Line(along, axis_label) => line_chart(&along, &axis_label, q, o),
        Shape::Scatter(u, v) => scatter(&pos, (u, v), q, o),
        Shape::OnePose => {
            bail!("every row is at the same pose: there is no map to draw (`stiff point` reports a pose)")
        }
    }
}

/// The colour scale of the values drawn.
fn colour_scale(values: &[f64], q: &Quantity, o: &PlotOptions) -> Result<ColourScale> {
    ColourScale::new(values, o.scale, o.range, &q.label)
}

/// The colour bar at (x, y) of height `h`: ticks with both ends, the unit, and the no-value swatch when
/// some pose has no value.
fn colour_bar(s: &mut Svg, scale: &ColourScale, (x, y, h): (f64, f64, f64), q: &Quantity, missing: bool) {
    const STEPS: usize = 64;
    for k in 0..STEPS {
        let f = k as f64 / (STEPS - 1) as f64;
        let step = h / STEPS as f64;
        s.rect(x, y + h - (k + 1) as f64 * step, 16.0, step + 0.5, &super::svg::viridis(f), "colorbar");
    }
    let (ticks, labels) = colour_bar_labels(scale);
    for (t, label) in ticks.iter().zip(&labels.0) {
        let py = y + h * (1.0 - scale.fraction(*t));
        s.line((x + 16.0, py), (x + 20.0, py), "#333", 1.0, "tick");
        s.text(x + 23.0, py + 4.0, label, 10.0, "start", 0.0);
    }
    let unit = match (&labels.1, scale.scale) {
        (Some(power), _) => format!("[{power} {}]", q.unit),
        (None, super::scale::Scale::Log) => format!("[{}, log]", q.unit),
        (None, super::scale::Scale::Linear) => format!("[{}]", q.unit),
    };
    s.text(x, y - 10.0, &unit, 11.0, "start", 0.0);
    if missing {
        s.rect(x, y + h + 14.0, 16.0, 10.0, NO_VALUE, "legend");
        s.text(x + 20.0, y + h + 23.0, "no value (status not ok)", 10.0, "start", 0.0);
    }
}

/// The colour bar's ticks and labels: on a linear scale, multiples of one power of ten where the values
/// call for one (named in the unit, `[10⁻⁴ mm/N]`); on a log scale, decades as powers of ten and the ends
/// as numbers.
fn colour_bar_labels(scale: &ColourScale) -> (Vec<f64>, (Vec<String>, Option<String>)) {
    let ticks = scale.ticks();
    let labels = match scale.scale {
        super::scale::Scale::Linear => {
            let (labels, multiplier) = super::svg::tick_labels(&ticks);
            (labels, multiplier.map(|m| m.trim_start_matches('×').to_string()))
        }
        super::scale::Scale::Log => {
            let last = ticks.len() - 1;
            let label = |(k, t): (usize, &f64)| {
                let e = t.log10().round();
                if k != 0 && k != last && (t / 10f64.powf(e) - 1.0).abs() < 1e-9 {
                    super::svg::power_of_ten(e as i32)
                } else {
                    tick_label(*t)
                }
            };
            (ticks.iter().enumerate().map(label).collect(), None)
        }
    };
    (ticks, labels)
}

/// Width the colour bar and its labels take.
fn colour_bar_width(scale: &ColourScale) -> f64 {
    let widest = colour_bar_labels(scale).1 .0.iter().map(|l| text_width(l, 10.0)).fold(0.0, f64::max);
    (23.0 + widest).max(text_width("no value (status not ok)", 10.0) + 20.0) + 20.0
}

/// The sections a grid picture shows: the one `--section` names (an error listing the sections where the
/// grid has none there), else every level of the one axis with a single value, or up to six levels of z.
fn sections(all_levels: &Levels, o: &PlotOptions) -> Result<(usize, Vec<f64>)> {
    Ok(match &o.section {
        Some(s) => {
            let (axis, v) = parse_section(s)?;
            let levels = &all_levels[axis];
            let nearest = levels
                .iter()
                .copied()
                .min_by(|a, b| (a - v).abs().total_cmp(&(b - v).abs()))
                .ok_or_else(|| anyhow!("empty map"))?;
            let tol = 0.01 * super::spacing(levels).min(1e9);
            if (nearest - v).abs() > tol.max(1e-9 * (1.0 + v.abs())) {
                let shown: Vec<String> = levels.iter().take(12).map(|l| tick_label(*l)).collect();
                bail!("no grid section at {} = {v} mm (sections: {})", AXES[axis], shown.join(", "));
            }
            (axis, vec![nearest])
        }
        None => {
            let axis = (0..3).find(|&a| all_levels[a].len() == 1).unwrap_or(2);
            let levels = all_levels[axis].clone();
            let picked: Vec<f64> =
                if levels.len() <= 6 { levels } else { (0..6).map(|k| levels[k * (levels.len() - 1) / 5]).collect() };
            (axis, picked)
        }
    })
}

/// Colour maps of a full grid over its sections (small multiples on shared axes, at most six sections).
fn grid_map(pos: &Positions, all_levels: &Levels, q: &Quantity, o: &PlotOptions) -> Result<String> {
    let (axis, levels) = sections(all_levels, o)?;
    let (u, v) = match axis {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    // The picture needs memory in proportion to what it draws: the rows drawn are visited, never copied.
    let on = |i: usize, level: f64| (pos[axis][i] - level).abs() <= 1e-9 * (1.0 + level.abs());
    let drawn = || (0..q.values.len()).filter(|&i| levels.iter().any(|l| on(i, *l)));
    let (lo, hi) =
        drawn().filter_map(|i| q.values[i]).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(x), b.max(x)));
    let negative = drawn().filter_map(|i| q.values[i]).find(|x| *x <= 0.0);
    let scale = colour_scale(&[lo, hi, negative.unwrap_or(hi)], q, o)?;
    let missing = drawn().any(|i| q.values[i].is_none());
    let (du, dv) = (super::spacing(&all_levels[u]), super::spacing(&all_levels[v]));
    // Shared axes: every section on the same ranges (those of the rows drawn).
    let range =
        |c: &[f64]| drawn().map(|i| c[i]).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(x), b.max(x)));
    let ((u_lo, u_hi), (v_lo, v_hi)) = (range(pos[u]), range(pos[v]));
    let (us, vs) = ([u_lo, u_hi], [v_lo, v_hi]);
    let cols = levels.len().min(3);
    let rows = levels.len().div_ceil(3);
    let panel = 240.0;
    let ay_probe = Axis::new(vs.iter().map(|x| x - dv / 2.0).chain(vs.iter().map(|x| x + dv / 2.0)), 0.0, 1.0);
    let left = 40.0 + ay_probe.widest_label(11.0);
    let gap = left + 20.0;
    let bar_width = colour_bar_width(&scale);
    let width = left + cols as f64 * panel + (cols - 1) as f64 * gap + 30.0 + bar_width;
    let mut s = Svg::new(width, 0.0);
    let total = all_levels[axis].len();
    let what = if levels.len() < total {
        format!("{} over {} of {total} sections {} = const", q.label, levels.len(), AXES[axis])
    } else {
        format!("{} over sections {} = const", q.label, AXES[axis])
    };
    let top = heading(&mut s, width, o, &what) + 24.0;
    let height = top + rows as f64 * (panel + 70.0);
    s.height = height;
    let mut extremes = Extremes::default();
    for (k, level) in levels.iter().enumerate() {
        let x0 = left + (k % 3) as f64 * (panel + gap);
        let y0 = top + (k / 3) as f64 * (panel + 70.0);
        let members = || drawn().filter(|&i| on(i, *level));
        let ax = Axis::new(us.iter().map(|x| x - du / 2.0).chain(us.iter().map(|x| x + du / 2.0)), x0, x0 + panel);
        let ay = Axis::new(vs.iter().map(|x| x - dv / 2.0).chain(vs.iter().map(|x| x + dv / 2.0)), y0 + panel, y0);
        let fill = |i: usize| q.values[i].map_or(NO_VALUE.to_string(), |x| scale.colour(x));
        if members().count() > RASTER_CELLS && uniform(&all_levels[u]) && uniform(&all_levels[v]) {
            // A full grid: every section holds every level of u and v.
            let (su, sv) = (all_levels[u].as_slice(), all_levels[v].as_slice());
            raster_section(&mut s, &mut members(), (pos[u], pos[v]), (su, sv), (&ax, &ay), (du, dv), &|i| fill(i));
        } else {
            for i in members() {
                let (cx, cy) = (ax.px(pos[u][i] - du / 2.0), ay.px(pos[v][i] + dv / 2.0));
                let (w, h) = (ax.px(pos[u][i] + du / 2.0) - cx, ay.px(pos[v][i] - dv / 2.0) - cy);
                // A hair of overlap so anti-aliasing leaves no seams between cells.
                s.rect(cx, cy, w + 0.6, h + 0.6, &fill(i), "cell");
            }
        }
        for i in members() {
            if let Some(x) = q.values[i] {
                extremes.see(Extreme {
                    value: x,
                    at: (ax.px(pos[u][i]), ay.px(pos[v][i])),
                    centre: (x0 + panel / 2.0, y0 + panel / 2.0),
                });
            }
        }
        axes(&mut s, &ax, &ay, &format!("{} [mm]", AXES[u]), &format!("{} [mm]", AXES[v]));
        s.text(x0 + panel / 2.0, y0 - 8.0, &format!("{} = {} mm", AXES[axis], tick_label(*level)), 12.0, "middle", 0.0);
    }
    mark_extremes(&mut s, &extremes);
    colour_bar(&mut s, &scale, (width - bar_width, top + 10.0, 200.0), q, missing);
    Ok(s.finish())
}

/// Whether a coordinate's distinct values are evenly spaced (a raster pixel per grid step).
fn uniform(sorted_distinct: &[f64]) -> bool {
    let step = super::spacing(sorted_distinct);
    sorted_distinct.windows(2).all(|w| ((w[1] - w[0]) - step).abs() <= 1e-6 * step.abs().max(1e-12))
}

/// One section as an embedded image, a pixel per grid cell: `members` the rows of the section, `su` and `sv`
/// the section's sorted distinct coordinates.
fn raster_section(
    s: &mut Svg,
    members: &mut dyn Iterator<Item = usize>,
    (pu, pv): (&[f64], &[f64]),
    (su, sv): (&[f64], &[f64]),
    (ax, ay): (&Axis, &Axis),
    (du, dv): (f64, f64),
    fill: &dyn Fn(usize) -> String,
) {
    let (u0, v0) = (su[0], sv[0]);
    let (nu, nv) = (su.len(), sv.len());
    let mut image = Raster::new(nu, nv, [255, 255, 255]);
    for i in members {
        let iu = ((pu[i] - u0) / du).round() as usize;
        let iv = ((pv[i] - v0) / dv).round() as usize;
        let colour = fill(i);
        let hex = |k: usize| u8::from_str_radix(&colour[k..k + 2], 16).unwrap_or(0);
        image.set(iu, nv.saturating_sub(1 + iv), [hex(1), hex(3), hex(5)]);
    }
    let (x, y) = (ax.px(u0 - du / 2.0), ay.px(sv[nv - 1] + dv / 2.0));
    let (w, h) = (ax.px(su[nu - 1] + du / 2.0) - x, ay.px(v0 - dv / 2.0) - y);
    s.image(x, y, w, h, &image.data_uri(), "cells");
}

/// The smallest and the largest value drawn so far, kept as the values stream by (a million-point section
/// keeps two, not a million).
#[derive(Default)]
struct Extremes {
    lowest: Option<Extreme>,
    highest: Option<Extreme>,
}

impl Extremes {
    /// Of equal values the first is the smallest and the last the largest, as `min_by` and `max_by` choose.
    fn see(&mut self, e: Extreme) {
        if self.lowest.as_ref().is_none_or(|l| e.value < l.value) {
            self.lowest = Some(Extreme { ..e });
        }
        if self.highest.as_ref().is_none_or(|h| e.value >= h.value) {
            self.highest = Some(e);
        }
    }
}

/// A value drawn at a pixel, in a panel with this centre.
struct Extreme {
    value: f64,
    at: (f64, f64),
    centre: (f64, f64),
}

/// Marks the smallest and the largest value drawn, each with its value, the label turned toward the
/// panel's centre so that it stays inside the panel.
fn mark_extremes(s: &mut Svg, extremes: &Extremes) {
    for (which, p) in [("min", &extremes.lowest), ("max", &extremes.highest)] {
        if let Some(e) = p {
            let (x, y) = e.at;
            s.circle_outline(x, y, 5.0, "#ffffff", "extreme");
            s.circle_outline(x, y, 6.5, "#000000", "extreme");
            let (tx, anchor) = if x > e.centre.0 { (x - 9.0, "end") } else { (x + 9.0, "start") };
            let ty = if y < e.centre.1 { y + 18.0 } else { y - 8.0 };
            s.halo_text(tx, ty, &format!("{which} {}", tick_label(e.value)), 10.0, anchor);
        }
    }
}

/// Poses on a line: the value against the coordinate along it, missing values marked on the axis.
fn line_chart(along: &[f64], axis_label: &str, q: &Quantity, o: &PlotOptions) -> Result<String> {
    let mut order: Vec<usize> = (0..along.len()).collect();
    order.sort_by(|a, b| along[*a].total_cmp(&along[*b]));
    let ys: Vec<f64> = q.values.iter().flatten().copied().collect();
    let (w, h) = (680.0, 440.0);
    let ay_probe = Axis::new(ys.iter().copied(), 0.0, 1.0);
    let left = 40.0 + ay_probe.widest_label(11.0);
    let mut s = Svg::new(w, h);
    let top = heading(&mut s, w, o, &format!("{} along the line", q.label)) + 16.0;
    let ax = Axis::new(along.iter().copied(), left, w - 30.0);
    let ay = Axis::new(ys.iter().copied(), h - 60.0, top);
    // Consecutive poses with values as one polyline; a pose without a value breaks it.
    let mut run: Vec<(f64, f64)> = Vec::new();
    for &i in &order {
        match q.values[i] {
            Some(y) => {
                let p = (ax.px(along[i]), ay.px(y));
                s.circle(p.0, p.1, 2.5, "#1f5fa8", "point");
                run.push(p);
            }
            None => {
                s.polyline(&run, "#1f5fa8", 1.5, false, "series");
                run.clear();
                s.text(ax.px(along[i]), ay.from - 4.0, "x", 10.0, "middle", 0.0);
            }
        }
    }
    s.polyline(&run, "#1f5fa8", 1.5, false, "series");
    axes(&mut s, &ax, &ay, axis_label, &q.label);
    if q.values.iter().any(Option::is_none) {
        s.text(w - 30.0, top - 4.0, "x on the axis: no value (status not ok)", 10.0, "end", 0.0);
    }
    Ok(s.finish())
}

/// Poses anywhere: markers coloured by value on the plane of the two axes they spread most over.
fn scatter(pos: &Positions, (u, v): (usize, usize), q: &Quantity, o: &PlotOptions) -> Result<String> {
    let finite: Vec<f64> = q.values.iter().flatten().copied().collect();
    let scale = colour_scale(&finite, q, o)?;
    let missing = q.values.iter().any(Option::is_none);
    let bar_width = colour_bar_width(&scale);
    let plot = 420.0;
    let ay_probe = Axis::new(pos[v].iter().copied(), 0.0, 1.0);
    let left = 40.0 + ay_probe.widest_label(11.0);
    let width = left + plot + 40.0 + bar_width;
    let mut s = Svg::new(width, 0.0);
    let third = 3 - u - v;
    let what = format!("{} at {} points, seen along {}", q.label, q.values.len(), AXES[third]);
    let top = heading(&mut s, width, o, &what) + 16.0;
    s.height = top + plot + 60.0;
    let ax = Axis::new(pos[u].iter().copied(), left, left + plot);
    let ay = Axis::new(pos[v].iter().copied(), top + plot, top);
    let mut extremes = Extremes::default();
    for ((pu, pv), value) in pos[u].iter().zip(pos[v]).zip(&q.values) {
        let (x, y) = (ax.px(*pu), ay.px(*pv));
        let fill = value.map_or(NO_VALUE.to_string(), |val| scale.colour(val));
        s.circle(x, y, 5.0, &fill, "point");
        if let Some(val) = value {
            extremes.see(Extreme {
                value: *val,
                at: (x, y),
                centre: ((ax.from + ax.to) / 2.0, (ay.from + ay.to) / 2.0),
            });
        }
    }
    axes(&mut s, &ax, &ay, &format!("{} [mm]", AXES[u]), &format!("{} [mm]", AXES[v]));
    mark_extremes(&mut s, &extremes);
    colour_bar(&mut s, &scale, (width - bar_width, top + 10.0, 200.0), q, missing);
    Ok(s.finish())
}

/// Named poses: one row per name, a dot at its value.
fn dot_chart(point_names: &[String], q: &Quantity, o: &PlotOptions) -> Result<String> {
    let values: Vec<f64> = q.values.iter().flatten().copied().collect();
    let label_width = point_names.iter().map(|n| text_width(n, 11.0)).fold(0.0, f64::max);
    let left = 30.0 + label_width;
    let row_h = 22.0;
    let width = left + 460.0;
    let mut s = Svg::new(width, 0.0);
    let top = heading(&mut s, width, o, &format!("{} at {} named points", q.label, point_names.len())) + 16.0;
    let plot_h = row_h * point_names.len() as f64;
    s.height = top + plot_h + 60.0;
    let ax = Axis::new(values.iter().copied().chain(std::iter::once(0.0)), left, width - 30.0);
    let ay = Axis { lo: 0.0, hi: point_names.len() as f64, from: top + plot_h, to: top };
    for (k, name) in point_names.iter().enumerate() {
        let y = top + row_h * (k as f64 + 0.5);
        s.line((left, y), (width - 30.0, y), "#e4e4e4", 1.0, "grid");
        s.text(left - 8.0, y + 4.0, name, 11.0, "end", 0.0);
        match q.values[k] {
            Some(v) => s.circle(ax.px(v), y, 4.5, "#1f5fa8", "point"),
            None => s.text(ax.px(ax.lo) + 6.0, y + 4.0, "no value (status not ok)", 10.0, "start", 0.0),
        }
    }
    super::svg::frame(&mut s, &ax, &ay, &q.label, "", true, false);
    Ok(s.finish())
}
