//! A force-deflection curve: force against displacement along one direction, stable branches solid and
//! unstable ones dashed, events marked where the curve study places them.
//!
//! The style follows the `stable` column, and a change of stability lies where its event says
//! (`study::curve`): buckling and restabilisation at their `event_load_factor`, bisected between two rows;
//! a leg's change of stability at its row. The picture splits the curve there, interpolating linearly in
//! the load factor between the two rows, and puts the event's mark on the same point, so a dashed branch
//! never starts before its buckling mark.

use anyhow::Result;

use super::svg::{axes, label, Axis, Svg};
use super::table::Table;
use super::{extent, heading, OptionError, PlotOptions};
use crate::output::table::names;

/// Events placed between two rows at their `event_load_factor` (the others sit at their row).
const BETWEEN_ROWS: [&str; 2] = ["buckling", "restabilised"];

/// A point of the drawn curve, in data units.
#[derive(Clone, Copy)]
struct At {
    x: f64,
    y: f64,
}

/// The rows of a curve seen along one direction.
struct Rows {
    x: Vec<f64>,
    y: Vec<f64>,
    load: Vec<f64>,
    stable: Vec<bool>,
    events: Vec<String>,
    event_at: Vec<Option<f64>>,
}

impl Rows {
    /// Where an event of row `i` lies on the curve: between rows `i - 1` and `i` at its load factor for a
    /// buckling or a restabilisation, at the row for the others.
    fn place(&self, i: usize, event: &str) -> At {
        let here = At { x: self.x[i], y: self.y[i] };
        if i == 0 || !BETWEEN_ROWS.contains(&event) {
            return here;
        }
        let (a, b) = (self.load[i - 1], self.load[i]);
        let f = match self.event_at[i] {
            Some(e) if b != a => ((e - a) / (b - a)).clamp(0.0, 1.0),
            _ => 1.0,
        };
        At { x: self.x[i - 1] + f * (self.x[i] - self.x[i - 1]), y: self.y[i - 1] + f * (self.y[i] - self.y[i - 1]) }
    }

    /// The curve as runs of equal stability, each ending where the next begins (at the event's place).
    fn runs(&self) -> Vec<(bool, Vec<At>)> {
        let mut runs: Vec<(bool, Vec<At>)> = Vec::new();
        for i in 0..self.x.len() {
            if !(self.x[i].is_finite() && self.y[i].is_finite()) {
                continue;
            }
            let here = At { x: self.x[i], y: self.y[i] };
            match runs.last_mut() {
                Some((flag, points)) if *flag == self.stable[i] => points.push(here),
                Some((_, points)) => {
                    let change = self.events[i].split(';').find(|e| BETWEEN_ROWS.contains(e)).unwrap_or("");
                    let split = self.place(i, change);
                    points.push(split);
                    runs.push((self.stable[i], vec![split, here]));
                }
                None => runs.push((self.stable[i], vec![here])),
            }
        }
        runs
    }
}

/// The directions a curve can be drawn along, in the order of the displacement and wrench columns.
const DIRECTIONS: [&str; 6] = ["x", "y", "z", "rx", "ry", "rz"];

/// The index of a `--direction` value (x, y, z, rx, ry, rz).
fn direction_index(d: &str) -> Result<usize, OptionError> {
    DIRECTIONS.iter().position(|n| *n == d).ok_or_else(|| OptionError::Direction(d.to_string()))
}

/// Checks a curve picture's options before the curve is computed, so that a bad option fails before any
/// output is written (as `check_map_options` does for a map).
pub fn check_curve_options(o: &PlotOptions) -> Result<()> {
    if let Some(d) = &o.direction {
        direction_index(d)?;
    }
    Ok(())
}

/// Force against displacement along one direction.
pub fn curve(t: &Table, o: &PlotOptions) -> Result<String> {
    let directions = DIRECTIONS;
    let (disp, force) = (names::DISPLACEMENT, names::WRENCH);
    let k = match &o.direction {
        Some(d) => direction_index(d)?,
        None => {
            let range = |c: &str| extent(t.numbers(c).unwrap_or_default().into_iter().flatten());
            (0..3).max_by(|a, b| range(disp[*a]).total_cmp(&range(disp[*b]))).unwrap_or(0)
        }
    };
    let rows = Rows {
        x: t.numbers_or_nan(disp[k])?.to_vec(),
        y: t.numbers_or_nan(force[k])?.to_vec(),
        load: t.numbers_or_nan(names::LOAD_FACTOR)?.to_vec(),
        stable: t.texts(names::STABLE)?.iter().map(|s| s == "true").collect(),
        events: t.texts(names::EVENT)?,
        event_at: t.numbers(&format!("{}_load_factor", names::EVENT))?,
    };
    let (x, y, events) = (&rows.x, &rows.y, &rows.events);
    let runs = rows.runs();
    let (w, h) = (680.0, 460.0);
    let mut s = Svg::new(w, h);
    let top = heading(&mut s, w, o, &format!("force-deflection along {}", directions[k])) + 16.0;
    let ay_probe = Axis::new(y.iter().copied(), 0.0, 1.0);
    let left = 40.0 + ay_probe.widest_label(11.0);
    let legend_width = 110.0;
    let ax = Axis::new(x.iter().copied(), left, w - 30.0 - legend_width);
    let ay = Axis::new(y.iter().copied(), h - 60.0, top);
    let mut drawn = [false, false];
    for (flag, points) in &runs {
        let pts: Vec<(f64, f64)> = points.iter().map(|p| (ax.px(p.x), ay.px(p.y))).collect();
        if pts.len() >= 2 {
            drawn[usize::from(*flag)] = true;
        }
        if *flag {
            s.polyline(&pts, "#1f5fa8", 2.0, false, "stable");
        } else {
            s.polyline(&pts, "#c0392b", 2.0, true, "unstable");
        }
    }
    for (i, row_events) in events.iter().enumerate() {
        for e in row_events.split(';').filter(|e| !e.is_empty()) {
            let p = rows.place(i, e);
            if p.x.is_finite() && p.y.is_finite() {
                let (px, py) = (ax.px(p.x), ay.px(p.y));
                s.circle(px, py, 5.0, "#e67e22", "event");
                s.text(px + 8.0, py - 8.0, e, 11.0, "start", 0.0);
            }
        }
    }
    axes(&mut s, &ax, &ay, &label(disp[k]), &label(force[k]));
    legend(&mut s, (w - 20.0 - legend_width, top + 10.0), drawn, events.iter().any(|e| !e.is_empty()));
    Ok(s.finish())
}

/// The legend of what is drawn only: `drawn` says whether an unstable and a stable branch are drawn.
fn legend(s: &mut Svg, (lx, top): (f64, f64), drawn: [bool; 2], any_event: bool) {
    let mut ly = top;
    if drawn[1] {
        s.line((lx, ly), (lx + 30.0, ly), "#1f5fa8", 2.0, "legend");
        s.text(lx + 35.0, ly + 4.0, "stable", 11.0, "start", 0.0);
        ly += 18.0;
    }
    if drawn[0] {
        s.polyline(&[(lx, ly), (lx + 30.0, ly)], "#c0392b", 2.0, true, "legend");
        s.text(lx + 35.0, ly + 4.0, "unstable", 11.0, "start", 0.0);
        ly += 18.0;
    }
    if any_event {
        s.circle(lx + 15.0, ly, 5.0, "#e67e22", "legend");
        s.text(lx + 35.0, ly + 4.0, "event", 11.0, "start", 0.0);
    }
}
