//! A diagnosis: residual arrows at every pose before and after the accepted effects (two panels, each with
//! its own scale, so that small "after" residuals stay visible), per-axis RMS, and each candidate's delta
//! BIC with the accepted effects set apart from the rejected candidates.

use anyhow::Result;

use super::svg::{frame, nice_below, text_width, tick_label, Axis, Svg};
use super::{distinct, extent, heading, PlotOptions, AXES};
use crate::output::diagnosis::{DiagnosisReport, ResidualRms};

/// Residual arrows, RMS bars and delta-BIC bars of a diagnosis.
pub fn diagnosis(v: &DiagnosisReport, o: &PlotOptions) -> Result<String> {
    let pos: Vec<[f64; 3]> = v.residuals.iter().map(|r| r.position_mm).collect();
    let accepted = accepted_labels(v);
    let what = format!(
        "diagnosis of {}: verdict {}{}",
        v.model,
        v.verdict,
        if accepted.is_empty() { String::new() } else { format!(" ({})", accepted.join(", ")) }
    );
    let plane = view_plane(&pos);
    let third = 3 - plane.0 - plane.1;
    let all_levels = distinct(&pos.iter().map(|p| p[third]).collect::<Vec<_>>());
    let levels: Vec<f64> = if all_levels.len() <= MAX_LEVELS {
        all_levels.clone()
    } else {
        (0..MAX_LEVELS).map(|k| all_levels[k * (all_levels.len() - 1) / (MAX_LEVELS - 1)]).collect()
    };
    let panel = if levels.len() > 3 { 170.0 } else { 230.0 };
    let quiver_width = 60.0 + levels.len() as f64 * (panel + 60.0);
    let labels = v.candidates.iter().map(|c| {
        let shown =
            if accepted.contains(&c.candidate) { format!("{} (accepted)", c.candidate) } else { c.candidate.clone() };
        text_width(&shown, 9.0)
    });
    let bic_left = 70.0 + 200.0 + 60.0 + labels.fold(0.0, f64::max);
    let width = quiver_width.max(bic_left + 190.0 + 30.0);
    let mut s = Svg::new(width, 0.0);
    let mut y = heading(&mut s, width, o, &what) + 30.0;
    let before: Vec<[f64; 3]> = v.residuals.iter().map(|r| r.before_mm).collect();
    let after: Vec<[f64; 3]> = v.residuals.iter().map(|r| r.after_mm).collect();
    let layout = Quivers { pos: &pos, plane, third, levels: &levels, panel };
    y = layout.draw(&mut s, &before, y, ("before the accepted effects", "#c0392b", "before")) + 40.0;
    y = layout.draw(&mut s, &after, y, ("after the accepted effects", "#1f5fa8", "after")) + 50.0;
    let size = 240.0;
    rms_bars(&mut s, &v.rms_mm, (70.0, y, size));
    let bottom = delta_bic_bars(&mut s, v, &accepted, (bic_left, y, size));
    s.height = bottom.max(y + size + 100.0) + 10.0;
    if levels.len() < all_levels.len() {
        s.text(
            10.0,
            s.height - 6.0,
            &format!("{} of {} levels of {} shown", levels.len(), all_levels.len(), AXES[third]),
            10.0,
            "start",
            0.0,
        );
    }
    Ok(s.finish())
}

/// Most levels of the third axis drawn as panels of residual arrows.
const MAX_LEVELS: usize = 6;

/// The labels of the accepted effects, as the candidate table names them.
fn accepted_labels(v: &DiagnosisReport) -> Vec<String> {
    v.effects
        .iter()
        .map(|e| if e.target.is_empty() { e.name.clone() } else { format!("{}:{}", e.name, e.target) })
        .collect()
}

/// The plane the arrows are drawn on: the two axes the poses spread most over (the third is cut into
/// levels, one panel each, so that poses at different levels never draw over each other).
fn view_plane(pos: &[[f64; 3]]) -> (usize, usize) {
    let spread = |k: usize| extent(pos.iter().map(|p| p[k]));
    let mut order = [0usize, 1, 2];
    order.sort_by(|a, b| spread(*b).total_cmp(&spread(*a)));
    (order[0].min(order[1]), order[0].max(order[1]))
}

/// Panels of residual arrows, one per level of the third axis, on shared axes.
struct Quivers<'a> {
    pos: &'a [[f64; 3]],
    plane: (usize, usize),
    third: usize,
    levels: &'a [f64],
    panel: f64,
}

impl Quivers<'_> {
    /// One row of panels for `residual`, from height `y0`; returns the height below it. One scale for the
    /// row: the longest arrow is 45% of the closest spacing of two poses in a panel (at most a fifth of
    /// the panel), and the frame is widened by that length so every arrow ends inside it. A key of a round
    /// length.
    fn draw(&self, s: &mut Svg, residual: &[[f64; 3]], y0: f64, (title, colour, class): (&str, &str, &str)) -> f64 {
        let (u, w) = self.plane;
        let size = self.panel;
        let on = |i: usize, level: f64| (self.pos[i][self.third] - level).abs() <= 1e-9 * (1.0 + level.abs());
        let drawn: Vec<usize> = (0..self.pos.len()).filter(|&i| self.levels.iter().any(|l| on(i, *l))).collect();
        let longest =
            drawn.iter().map(|&i| (residual[i][u].powi(2) + residual[i][w].powi(2)).sqrt()).fold(0.0, f64::max);
        let probe_x = Axis::new(self.pos.iter().map(|p| p[u]), 0.0, size);
        let probe_y = Axis::new(self.pos.iter().map(|p| p[w]), 0.0, size);
        let step_px = |axis: &Axis, k: usize| {
            let d = distinct(&self.pos.iter().map(|p| p[k]).collect::<Vec<_>>());
            d.windows(2).map(|p| (axis.px(p[1]) - axis.px(p[0])).abs()).fold(f64::INFINITY, f64::min)
        };
        let reach = (0.45 * step_px(&probe_x, u).min(step_px(&probe_y, w))).min(0.2 * size).max(8.0);
        let scale = if longest > 0.0 { reach / longest } else { 0.0 };
        s.text(10.0, y0 - 8.0, &format!("residuals {title}"), 12.0, "start", 0.0);
        let top = y0 + 12.0;
        for (k, level) in self.levels.iter().enumerate() {
            let x0 = 70.0 + k as f64 * (size + 60.0);
            let inner_x = Axis::new(self.pos.iter().map(|p| p[u]), x0 + reach, x0 + size - reach);
            let inner_y = Axis::new(self.pos.iter().map(|p| p[w]), top + size - reach, top + reach);
            let ax = widen(&inner_x, x0, x0 + size);
            let ay = widen(&inner_y, top + size, top);
            let mut placed: Vec<(f64, f64)> = Vec::new();
            for &i in drawn.iter().filter(|&&i| on(i, *level)) {
                let (mut px, mut py) = (ax.px(self.pos[i][u]), ay.px(self.pos[i][w]));
                // Repeated poses: spread on a small ring around their place.
                let twins = placed.iter().filter(|q| (q.0 - px).abs() < 0.5 && (q.1 - py).abs() < 0.5).count();
                placed.push((px, py));
                if twins > 0 {
                    px += 4.0 * (twins as f64 * 2.4).cos();
                    py += 4.0 * (twins as f64 * 2.4).sin();
                }
                let d = residual[i];
                s.circle(px, py, 1.8, "#555", "pose");
                s.arrow(px, py, px + d[u] * scale, py - d[w] * scale, colour, class);
            }
            frame(s, &ax, &ay, &format!("{} [mm]", AXES[u]), &format!("{} [mm]", AXES[w]), true, true);
            s.text(
                x0 + size / 2.0,
                top - 6.0,
                &format!("{} = {} mm", AXES[self.third], tick_label(*level)),
                11.0,
                "middle",
                0.0,
            );
        }
        let key = nice_below(longest);
        let ky = top + size + 48.0;
        if key > 0.0 {
            s.line((70.0, ky), (70.0 + key * scale, ky), colour, 2.0, "key");
            s.text(70.0 + key * scale + 6.0, ky + 4.0, &format!("{} mm residual", tick_label(key)), 10.0, "start", 0.0);
        } else {
            s.text(70.0, ky + 4.0, "no residual", 10.0, "start", 0.0);
        }
        ky
    }
}

/// An axis over the same values with its pixel range widened to from..to.
fn widen(a: &Axis, from: f64, to: f64) -> Axis {
    let per_px = (a.hi - a.lo) / (a.to - a.from);
    Axis { lo: a.lo + (from - a.from) * per_px, hi: a.hi + (to - a.to) * per_px, from, to }
}

/// Residual RMS per axis: fit before / held-out before / fit after / held-out after.
fn rms_bars(s: &mut Svg, rms: &ResidualRms, (bx, y0, size): (f64, f64, f64)) {
    let (rb, ra, hb, ha) = (rms.fit_before, rms.fit_after, rms.heldout_before, rms.heldout_after);
    let bw = 200.0;
    let rms_axis =
        Axis::new(rb.iter().chain(&ra).chain(&hb).chain(&ha).copied().chain(std::iter::once(0.0)), y0 + size, y0);
    let cat = Axis { lo: -0.5, hi: 2.5, from: bx, to: bx + bw };
    let series = [
        ("fit, before", "#c0392b"),
        ("held out, before", "#e8a09a"),
        ("fit, after", "#1f5fa8"),
        ("held out, after", "#9fbfe6"),
    ];
    for k in 0..3 {
        let c = cat.px(k as f64);
        for (j, value) in [rb[k], hb[k], ra[k], ha[k]].into_iter().enumerate() {
            let off = -18.0 + 12.0 * j as f64;
            let top_px = rms_axis.px(value);
            s.rect(c + off - 5.0, top_px, 10.0, rms_axis.px(0.0) - top_px, series[j].1, "rms-bar");
        }
        s.text(c, y0 + size + 16.0, AXES[k], 11.0, "middle", 0.0);
    }
    frame(s, &cat, &rms_axis, "", "residual RMS [mm]", false, true);
    s.text(bx + bw / 2.0, y0 - 10.0, "residual RMS per axis", 12.0, "middle", 0.0);
    for (j, (label, colour)) in series.iter().enumerate() {
        let ly = y0 + size + 34.0 + 14.0 * j as f64;
        s.rect(bx, ly - 8.0, 10.0, 10.0, colour, "legend");
        s.text(bx + 14.0, ly, label, 10.0, "start", 0.0);
    }
}

/// The identifiable candidates' delta BIC on a signed log scale: accepted effects dark green and labelled,
/// candidates that pass the test but were not accepted light green, the rest grey; the -10 line red.
fn delta_bic_bars(s: &mut Svg, v: &DiagnosisReport, accepted: &[String], (cx, y0, size): (f64, f64, f64)) -> f64 {
    let rows: Vec<(String, f64, bool)> = v
        .candidates
        .iter()
        .filter(|c| c.identifiable)
        .filter_map(|c| Some((c.candidate.clone(), c.delta_bic?, c.passes)))
        .collect();
    let cw = 190.0;
    let n = rows.len().max(1) as f64;
    // Signed logarithmic scale: delta BIC spans from -10 to -1e5 and more.
    let slog = |d: f64| d.signum() * (1.0 + d.abs()).log10();
    let bic = Axis::new(rows.iter().map(|r| slog(r.1)).chain([0.0, slog(-10.0)]), cx, cx + cw);
    let row_h = (size / n).min(28.0);
    for (k, (name, d, passes)) in rows.iter().enumerate() {
        let yy = y0 + row_h * k as f64;
        let (a, b) = (bic.px(0.0), bic.px(slog(*d)));
        let is_accepted = accepted.contains(name);
        let (fill, class) = match (is_accepted, passes) {
            (true, _) => ("#1e7b45", "bic-bar accepted"),
            (false, true) => ("#8fd19e", "bic-bar"),
            (false, false) => ("#b8c0c4", "bic-bar"),
        };
        s.rect(a.min(b), yy + 0.15 * row_h, (a - b).abs(), 0.7 * row_h, fill, class);
        let shown = if is_accepted { format!("{name} (accepted)") } else { name.clone() };
        s.text(cx - 6.0, yy + 0.65 * row_h, &shown, 9.0, "end", 0.0);
    }
    let bottom = y0 + row_h * n;
    s.line((bic.px(slog(-10.0)), y0), (bic.px(slog(-10.0)), bottom), "#c0392b", 1.0, "threshold");
    let ay_cat = Axis { lo: 0.0, hi: 1.0, from: bottom, to: y0 };
    frame(s, &bic, &ay_cat, "", "", false, false);
    s.text(cx + cw / 2.0, y0 - 10.0, "delta BIC (signed log scale)", 12.0, "middle", 0.0);
    for e in 0..8 {
        for sign in [-1.0, 1.0] {
            let d = sign * 10f64.powi(e);
            let x = slog(d);
            if x >= bic.lo && x <= bic.hi && e % 2 == 1 {
                let p = bic.px(x);
                s.line((p, bottom), (p, bottom + 4.0), "#333", 1.0, "tick");
                s.text(p, bottom + 16.0, &format!("{}1e{e}", if sign < 0.0 { "-" } else { "" }), 9.0, "middle", 0.0);
            }
        }
    }
    // The legend lists what is drawn.
    let present =
        |a: bool, p: bool| rows.iter().any(|(name, _, passes)| accepted.contains(name) == a && (a || *passes == p));
    let legend: Vec<(&str, &str)> = [
        (present(true, true), ("#1e7b45", "accepted effect")),
        (present(false, true), ("#8fd19e", "passes, not accepted")),
        (present(false, false), ("#b8c0c4", "fails the test")),
    ]
    .into_iter()
    .filter(|(shown, _)| *shown)
    .map(|(_, entry)| entry)
    .collect();
    let mut ly = bottom + 34.0;
    for (colour, label) in legend {
        s.rect(cx, ly - 8.0, 10.0, 10.0, colour, "legend");
        s.text(cx + 14.0, ly, label, 10.0, "start", 0.0);
        ly += 14.0;
    }
    s.line((cx, ly - 4.0), (cx + 10.0, ly - 4.0), "#c0392b", 1.0, "legend");
    s.text(cx + 14.0, ly, "delta BIC = -10", 10.0, "start", 0.0);
    ly
}
