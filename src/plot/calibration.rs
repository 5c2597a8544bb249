//! A calibration of a serial arm (`diagnose` on joint-space data): the position error after each stage
//! (the registration alone, then each accepted effect added), as grouped bars of its RMS for the fitted rows
//! and for the held-out rows, with the 95th percentile and the largest error marked on each bar: the gap
//! between model and measurement shrinking, and whether the held-out rows agree.

use anyhow::Result;
use serde::Deserialize;

use super::svg::{frame, text_width, Axis, Svg};
use super::{heading, PlotOptions};

/// The part of a calibration's JSON (`diagnose --json` on joint-space data) the picture draws.
#[derive(Deserialize)]
pub struct CalibrationReport {
    /// The description calibrated.
    pub model: String,
    /// The calibration.
    pub calibration: Calibration,
}

/// The verdict and the stages of a calibration.
#[derive(Deserialize)]
pub struct Calibration {
    /// `none`, `effect` or `unexplained`.
    pub verdict: String,
    /// The registration, then each accepted effect added.
    pub stages: Vec<Stage>,
}

/// One stage's errors.
#[derive(Deserialize)]
pub struct Stage {
    /// `registration`, `+ joint-offset:J2`, ...
    pub model: String,
    /// Parameters the data see at this stage.
    pub parameters: usize,
    /// The fitted rows' errors.
    pub fit: Errors,
    /// The held-out rows' errors (gross rows left out).
    pub check: Errors,
}

/// The position error's statistics over some rows, mm.
#[derive(Deserialize)]
pub struct Errors {
    /// Rows.
    pub rows: usize,
    /// RMS of the error's length.
    pub rms: f64,
    /// Its 95th percentile.
    pub p95: f64,
    /// Its largest value.
    pub max: f64,
}

const FIT: &str = "#1f5fa8";
const CHECK: &str = "#e08a2c";

/// Grouped bars of a calibration's errors per stage.
pub fn calibration(v: &CalibrationReport, o: &PlotOptions) -> Result<String> {
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
    let width = left + plot_width + 200.0;
    let mut s = Svg::new(width, 0.0);
    let what = format!("calibration of {}: verdict {}", v.model, v.calibration.verdict);
    let top = heading(&mut s, width, o, &what) + 30.0;
    let shown = |e: &Errors| e.rows > 0;
    let values =
        stages.iter().flat_map(|st| [&st.fit, &st.check]).filter(|e| shown(e)).flat_map(|e| [e.rms, e.p95, e.max]);
    let y = Axis::new(values.chain([0.0]), top + plot_height, top);
    let x = Axis { lo: -0.5, hi: stages.len() as f64 - 0.5, from: left, to: left + plot_width };
    let bar = if held_out { 18.0 } else { 22.0 };
    for (k, st) in stages.iter().enumerate() {
        let centre = x.px(k as f64);
        let bars: Vec<(&Errors, &str)> =
            if held_out { vec![(&st.fit, FIT), (&st.check, CHECK)] } else { vec![(&st.fit, FIT)] };
        for (j, (e, colour)) in bars.iter().enumerate() {
            if !shown(e) {
                continue;
            }
            let at = centre - bar * bars.len() as f64 / 2.0 + bar * j as f64 + 2.0;
            let w = bar - 4.0;
            s.rect(at, y.px(e.rms), w, y.px(0.0) - y.px(e.rms), colour, "rms-bar");
            // The 95th percentile as a bar across, the largest error as a dot above it.
            s.line((at - 2.0, y.px(e.p95)), (at + w + 2.0, y.px(e.p95)), "#222", 1.5, "p95");
            s.line((at + w / 2.0, y.px(e.p95)), (at + w / 2.0, y.px(e.max)), "#222", 0.8, "max");
            s.rect(at + w / 2.0 - 2.0, y.px(e.max) - 2.0, 4.0, 4.0, "#222", "max");
        }
        s.text(centre + 4.0, top + plot_height + 10.0, &labels[k], 10.0, "end", -90.0);
    }
    frame(&mut s, &x, &y, "", "position error [mm]", false, true);
    let legend_x = left + plot_width + 24.0;
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
