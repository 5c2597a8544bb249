//! A calibration of a serial arm (`diagnose` on joint-space data): the position error after each stage
//! (the registration alone, then each accepted effect added), as grouped bars of its RMS for the fitted rows
//! and for the held-out rows, with the 95th percentile and the largest error marked on each bar: the gap
//! between model and measurement shrinking, and whether the held-out rows agree. Where orientations were
//! measured, a second panel beside it draws their errors (mrad) alike.

use anyhow::Result;

use super::svg::{frame, text_width, Axis, Svg};
use super::{heading, PlotOptions};
use crate::output::calibration::{CalibrationFile, ErrorStats};

const FIT: &str = "#1f5fa8";
const CHECK: &str = "#e08a2c";

/// Grouped bars of a calibration's errors per stage.
pub fn calibration(v: &CalibrationFile, o: &PlotOptions) -> Result<String> {
    let stages = &v.calibration.stages;
    if stages.is_empty() {
        anyhow::bail!("the calibration has no stages: nothing to draw");
    }
    let held_out = stages.iter().any(|s| s.check.rows > 0);
    let labels: Vec<String> = stages.iter().map(|s| format!("{} ({} par.)", s.model, s.parameters)).collect();
    let label_room = labels.iter().map(|l| text_width(l, 10.0)).fold(0.0, f64::max) + 24.0;
    let group = if held_out { 56.0 } else { 36.0 };
    let (left, plot_height) = (80.0, 280.0);
    let plot_width = (group * stages.len() as f64).max(240.0);
    // The position panel, and the orientation panel where every stage has one.
    let mut panels: Vec<(&str, Vec<[&ErrorStats; 2]>)> =
        vec![("position error [mm]", stages.iter().map(|st| [&st.fit, &st.check]).collect())];
    let orientations: Option<Vec<[&ErrorStats; 2]>> =
        stages.iter().map(|st| st.orientation.as_ref().map(|[f, c]| [f, c])).collect();
    if let Some(errors) = orientations {
        panels.push(("orientation error [mrad]", errors));
    }
    let panel_step = left + plot_width;
    let width = panel_step * panels.len() as f64 + 200.0;
    let mut s = Svg::new(width, 0.0);
    let what = format!("calibration of {}: verdict {}", v.model, v.calibration.verdict.as_str());
    let top = heading(&mut s, width, o, &what) + 30.0;
    for (p, (axis_label, errors)) in panels.iter().enumerate() {
        let from = left + panel_step * p as f64;
        let x = Axis { lo: -0.5, hi: stages.len() as f64 - 0.5, from, to: from + plot_width };
        let y = bar_panel(&mut s, errors, held_out, &x, (top, plot_height));
        for (k, label) in labels.iter().enumerate() {
            s.text(x.px(k as f64) + 4.0, top + plot_height + 10.0, label, 10.0, "end", -90.0);
        }
        frame(&mut s, &x, &y, "", axis_label, false, true);
    }
    let legend_x = panel_step * (panels.len() - 1) as f64 + left + plot_width + 24.0;
    let mut legend: Vec<(&str, &str)> = vec![("fitted rows: RMS", FIT)];
    if held_out {
        legend.push(("held-out rows: RMS", CHECK));
    }
    for (j, (label, colour)) in legend.iter().enumerate() {
        let ly = top + 14.0 + 16.0 * j as f64;
        s.rect(legend_x, ly - 9.0, 10.0, 10.0, colour, "legend");
        s.text(legend_x + 14.0, ly, label, 10.0, "start", 0.0);
    }
    let ly = top + 14.0 + 16.0 * legend.len() as f64;
    s.line((legend_x - 1.0, ly - 4.0), (legend_x + 11.0, ly - 4.0), "#222", 1.5, "legend");
    s.text(legend_x + 14.0, ly, "95th percentile", 10.0, "start", 0.0);
    s.rect(legend_x + 3.0, ly + 10.0, 4.0, 4.0, "#222", "legend");
    s.text(legend_x + 14.0, ly + 16.0, "largest error", 10.0, "start", 0.0);
    s.height = top + plot_height + label_room + 20.0;
    Ok(s.finish())
}

/// One panel's bars: per stage the fitted rows' RMS (and the held-out rows', where there are any), with the
/// 95th percentile as a bar across and the largest error as a dot above it, between `top` and `top +
/// height`. Returns the panel's value axis.
fn bar_panel(s: &mut Svg, errors: &[[&ErrorStats; 2]], held_out: bool, x: &Axis, (top, height): (f64, f64)) -> Axis {
    let values = errors.iter().flatten().filter(|e| e.rows > 0).flat_map(|e| [e.rms, e.p95, e.max]);
    let y = Axis::new(values.chain([0.0]), top + height, top);
    let bar = if held_out { 18.0 } else { 22.0 };
    for (k, [fit, check]) in errors.iter().enumerate() {
        let centre = x.px(k as f64);
        let bars: Vec<(&ErrorStats, &str)> = if held_out { vec![(fit, FIT), (check, CHECK)] } else { vec![(fit, FIT)] };
        for (j, (e, colour)) in bars.iter().enumerate() {
            if e.rows == 0 {
                continue;
            }
            let at = centre - bar * bars.len() as f64 / 2.0 + bar * j as f64 + 2.0;
            let w = bar - 4.0;
            s.rect(at, y.px(e.rms), w, y.px(0.0) - y.px(e.rms), colour, "rms-bar");
            s.line((at - 2.0, y.px(e.p95)), (at + w + 2.0, y.px(e.p95)), "#222", 1.5, "p95");
            s.line((at + w / 2.0, y.px(e.p95)), (at + w / 2.0, y.px(e.max)), "#222", 0.8, "max");
            s.rect(at + w / 2.0 - 2.0, y.px(e.max) - 2.0, 4.0, 4.0, "#222", "max");
        }
    }
    y
}
