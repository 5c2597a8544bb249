//! A small SVG writer and linear axes: plots need rectangles, lines, polylines, circles, embedded images and
//! text; text is left to the viewer's generic sans-serif font, measured with Helvetica's advance widths.

use std::fmt::Write;

/// An SVG document being written.
pub struct Svg {
    /// Width, px.
    pub width: f64,
    /// Height, px.
    pub height: f64,
    body: String,
}

/// Text made safe inside an element or a quoted attribute.
pub(super) fn escape(t: &str) -> String {
    t.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// Numbers in SVG attributes: two decimals are a hundredth of a pixel.
fn n(v: f64) -> String {
    let r = (v * 100.0).round() / 100.0;
    if r == r.trunc() {
        format!("{}", r as i64)
    } else {
        format!("{r}")
    }
}

impl Svg {
    /// An empty picture of this size.
    pub fn new(width: f64, height: f64) -> Svg {
        Svg { width, height, body: String::new() }
    }

    /// A filled rectangle.
    pub fn rect(&mut self, x: f64, y: f64, w: f64, h: f64, fill: &str, class: &str) {
        let _ = writeln!(
            self.body,
            r#"<rect class="{class}" x="{}" y="{}" width="{}" height="{}" fill="{fill}"/>"#,
            n(x),
            n(y),
            n(w),
            n(h)
        );
    }

    /// A line segment from one point to another.
    pub fn line(&mut self, (x1, y1): (f64, f64), (x2, y2): (f64, f64), stroke: &str, width: f64, class: &str) {
        let _ = writeln!(
            self.body,
            r#"<line class="{class}" x1="{}" y1="{}" x2="{}" y2="{}" stroke="{stroke}" stroke-width="{}"/>"#,
            n(x1),
            n(y1),
            n(x2),
            n(y2),
            n(width)
        );
    }

    /// A polyline; `dashed` draws it in dashes (an unstable branch, an estimate).
    pub fn polyline(&mut self, points: &[(f64, f64)], stroke: &str, width: f64, dashed: bool, class: &str) {
        if points.len() < 2 {
            return;
        }
        let pts: Vec<String> = points.iter().map(|(x, y)| format!("{},{}", n(*x), n(*y))).collect();
        let dash = if dashed { r#" stroke-dasharray="6,4""# } else { "" };
        let _ = writeln!(
            self.body,
            r#"<polyline class="{class}" points="{}" fill="none" stroke="{stroke}" stroke-width="{}"{dash}/>"#,
            pts.join(" "),
            n(width)
        );
    }

    /// A filled circle.
    pub fn circle(&mut self, x: f64, y: f64, r: f64, fill: &str, class: &str) {
        let _ =
            writeln!(self.body, r#"<circle class="{class}" cx="{}" cy="{}" r="{}" fill="{fill}"/>"#, n(x), n(y), n(r));
    }

    /// A circle's outline.
    pub fn circle_outline(&mut self, x: f64, y: f64, r: f64, stroke: &str, class: &str) {
        let _ = writeln!(
            self.body,
            r#"<circle class="{class}" cx="{}" cy="{}" r="{}" fill="none" stroke="{stroke}" stroke-width="1.5"/>"#,
            n(x),
            n(y),
            n(r)
        );
    }

    /// An embedded image (a `data:` URI) stretched over the rectangle, its pixels drawn as squares.
    pub fn image(&mut self, x: f64, y: f64, w: f64, h: f64, href: &str, class: &str) {
        let _ = writeln!(
            self.body,
            r#"<image class="{class}" x="{}" y="{}" width="{}" height="{}" preserveAspectRatio="none" image-rendering="pixelated" style="image-rendering:pixelated" href="{href}"/>"#,
            n(x),
            n(y),
            n(w),
            n(h)
        );
    }

    /// Text; `anchor` is start, middle or end; `rotate` turns it (degrees) about its anchor.
    pub fn text(&mut self, x: f64, y: f64, t: &str, size: f64, anchor: &str, rotate: f64) {
        let transform = if rotate != 0.0 {
            format!(r#" transform="rotate({} {} {})""#, n(rotate), n(x), n(y))
        } else {
            String::new()
        };
        let _ = writeln!(
            self.body,
            r#"<text class="label" x="{}" y="{}" font-size="{}" text-anchor="{anchor}"{transform}>{}</text>"#,
            n(x),
            n(y),
            n(size),
            escape(t)
        );
    }

    /// Text on a white halo, readable over any colour.
    pub fn halo_text(&mut self, x: f64, y: f64, t: &str, size: f64, anchor: &str) {
        let _ = writeln!(
            self.body,
            r#"<text class="label" x="{}" y="{}" font-size="{}" text-anchor="{anchor}" stroke="white" stroke-width="3" paint-order="stroke">{}</text>"#,
            n(x),
            n(y),
            n(size),
            escape(t)
        );
    }

    /// An arrow from (x1, y1) to (x2, y2).
    pub fn arrow(&mut self, x1: f64, y1: f64, x2: f64, y2: f64, stroke: &str, class: &str) {
        let (dx, dy) = (x2 - x1, y2 - y1);
        let len = (dx * dx + dy * dy).sqrt();
        self.line((x1, y1), (x2, y2), stroke, 1.5, class);
        if len > 1e-9 {
            let (ux, uy) = (dx / len, dy / len);
            let head = 5.0f64.min(0.5 * len);
            let (hx, hy) = (x2 - ux * head, y2 - uy * head);
            let pts =
                [(x2, y2), (hx - uy * head * 0.5, hy + ux * head * 0.5), (hx + uy * head * 0.5, hy - ux * head * 0.5)];
            let p: Vec<String> = pts.iter().map(|(x, y)| format!("{},{}", n(*x), n(*y))).collect();
            let _ = writeln!(self.body, r#"<polygon class="{class}-head" points="{}" fill="{stroke}"/>"#, p.join(" "));
        }
    }

    /// The SVG document.
    pub fn finish(self) -> String {
        format!(
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" font-family=\"sans-serif\">\n<rect class=\"background\" x=\"0\" y=\"0\" width=\"{w}\" height=\"{h}\" fill=\"white\"/>\n{}</svg>\n",
            self.body,
            w = n(self.width),
            h = n(self.height)
        )
    }
}

/// A linear axis: data range to pixels, with round tick values.
#[derive(Clone, Debug)]
pub struct Axis {
    /// Smallest value shown.
    pub lo: f64,
    /// Largest value shown.
    pub hi: f64,
    /// Pixel of `lo`.
    pub from: f64,
    /// Pixel of `hi`.
    pub to: f64,
}

impl Axis {
    /// An axis over the data range (widened when empty or degenerate), onto pixels from..to.
    pub fn new(values: impl IntoIterator<Item = f64>, from: f64, to: f64) -> Axis {
        let (mut lo, mut hi) = values
            .into_iter()
            .filter(|v| v.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
        if !lo.is_finite() {
            (lo, hi) = (0.0, 1.0);
        }
        if hi - lo <= 1e-12 * (lo.abs() + hi.abs()).max(1e-300) {
            let pad = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
            (lo, hi) = (lo - pad, hi + pad);
        }
        let pad = 0.04 * (hi - lo);
        Axis { lo: lo - pad, hi: hi + pad, from, to }
    }

    /// The pixel of a value.
    pub fn px(&self, v: f64) -> f64 {
        self.from + (v - self.lo) / (self.hi - self.lo) * (self.to - self.from)
    }

    /// The ticks with their labels, and the power of ten they are multiples of where one is named
    /// (`tick_labels`).
    pub fn labels(&self) -> (Vec<(f64, String)>, Option<String>) {
        let ticks = self.ticks();
        let (labels, multiplier) = tick_labels(&ticks);
        (ticks.into_iter().zip(labels).collect(), multiplier)
    }

    /// The width of the widest tick label at this font size.
    pub fn widest_label(&self, size: f64) -> f64 {
        self.labels().0.iter().map(|(_, l)| text_width(l, size)).fold(0.0, f64::max)
    }

    /// Round tick values inside the range (about five).
    pub fn ticks(&self) -> Vec<f64> {
        let span = self.hi - self.lo;
        let raw = span / 5.0;
        let mag = 10f64.powf(raw.log10().floor());
        let step = [1.0, 2.0, 2.5, 5.0, 10.0].iter().map(|m| m * mag).find(|s| span / s <= 6.0).unwrap_or(10.0 * mag);
        let first = (self.lo / step).ceil() as i64;
        let last = (self.hi / step).floor() as i64;
        (first..=last).map(|k| k as f64 * step).collect()
    }
}

/// The largest round length (1, 2 or 5 times a power of ten) not above `v`; 0 for 0.
pub fn nice_below(v: f64) -> f64 {
    if !(v.is_finite() && v > 0.0) {
        return 0.0;
    }
    let mag = 10f64.powf(v.log10().floor());
    [5.0, 2.0, 1.0].iter().map(|m| m * mag).find(|x| *x <= v * (1.0 + 1e-12)).unwrap_or(mag)
}

/// Tick labels as matplotlib prints them: where the largest tick is below 1e-2 or from 1e5 in size, every
/// tick is shown as a multiple of one power of ten, named once (`×10⁻⁴`), instead of `3.00e6` on each.
pub fn tick_labels(ticks: &[f64]) -> (Vec<String>, Option<String>) {
    let largest = ticks.iter().fold(0.0f64, |m, t| m.max(t.abs()));
    if largest == 0.0 || (1e-2..1e5).contains(&largest) {
        return (ticks.iter().map(|t| tick_label(*t)).collect(), None);
    }
    let e = largest.log10().floor() as i32;
    let scale = 10f64.powi(e);
    (ticks.iter().map(|t| tick_label(t / scale)).collect(), Some(format!("×10{}", superscript(e))))
}

/// `10^e` as a power of ten with superscript digits (`10⁻⁴`).
pub fn power_of_ten(e: i32) -> String {
    format!("10{}", superscript(e))
}

fn superscript(e: i32) -> String {
    e.to_string()
        .chars()
        .map(|c| match c {
            '-' => '⁻',
            '0' => '⁰',
            '1' => '¹',
            '2' => '²',
            '3' => '³',
            '4' => '⁴',
            '5' => '⁵',
            '6' => '⁶',
            '7' => '⁷',
            '8' => '⁸',
            _ => '⁹',
        })
        .collect()
}

/// A number on a picture: short and readable.
pub fn tick_label(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        format!("{v:.2e}")
    } else {
        // Five significant digits (126.35 mm, 0.0013245), trailing zeros dropped.
        let decimals = (4 - a.log10().floor() as i32).clamp(0, 7) as usize;
        let s = format!("{v:.decimals$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    }
}

/// Draws a frame with ticks and labels for x (bottom) and y (left) axes.
pub fn axes(svg: &mut Svg, x: &Axis, y: &Axis, x_label: &str, y_label: &str) {
    frame(svg, x, y, x_label, y_label, true, true);
}

/// A frame with numeric ticks on either axis or none (a category axis labels itself); an empty label is
/// left out.
pub fn frame(svg: &mut Svg, x: &Axis, y: &Axis, x_label: &str, y_label: &str, x_ticks: bool, y_ticks: bool) {
    let (left, right, top, bottom) = (x.from, x.to, y.to, y.from);
    for (x1, y1, x2, y2) in
        [(left, bottom, right, bottom), (left, top, left, bottom), (left, top, right, top), (right, top, right, bottom)]
    {
        svg.line((x1, y1), (x2, y2), "#333", 1.0, "frame");
    }
    if x_ticks {
        let (labels, multiplier) = x.labels();
        for (t, l) in labels {
            let p = x.px(t);
            svg.line((p, bottom), (p, bottom + 4.0), "#333", 1.0, "tick");
            svg.text(p, bottom + 16.0, &l, 11.0, "middle", 0.0);
        }
        if let Some(m) = multiplier {
            svg.text(right, bottom + 30.0, &m, 10.0, "end", 0.0);
        }
    }
    if y_ticks {
        let (labels, multiplier) = y.labels();
        for (t, l) in labels {
            let p = y.px(t);
            svg.line((left - 4.0, p), (left, p), "#333", 1.0, "tick");
            svg.text(left - 6.0, p + 4.0, &l, 11.0, "end", 0.0);
        }
        if let Some(m) = multiplier {
            svg.text(left, top - 4.0, &m, 10.0, "start", 0.0);
        }
    }
    svg.text((left + right) / 2.0, bottom + 34.0, x_label, 12.0, "middle", 0.0);
    if !y_label.is_empty() {
        // Left of the widest tick label, so that the two never overlap.
        let widest = if y_ticks { y.widest_label(11.0) } else { 0.0 };
        svg.text(left - 6.0 - widest - 10.0, (top + bottom) / 2.0, y_label, 12.0, "middle", -90.0);
    }
}

/// The width of a text in the viewer's sans-serif font: the advance widths of Helvetica (Arial has the
/// same) in 1/1000 em, widened by 15% to cover DejaVu Sans, the sans-serif of most Linux viewers, whose
/// digits are 14% wider; characters not listed count as a full em.
pub fn text_width(t: &str, size: f64) -> f64 {
    let advance = |c: char| -> f64 {
        match c {
            ' ' | '.' | ',' | ':' | ';' | '!' | '|' | 'i' | 'j' | 'l' | 'f' | 't' | 'I' | '/' | '[' | ']' => 278.0,
            '(' | ')' | '-' | 'r' | '\'' => 333.0,
            '0'..='9' | '_' | '$' | '?' | 'a' | 'b' | 'd' | 'e' | 'g' | 'h' | 'n' | 'o' | 'p' | 'q' | 'u' | 'L' => {
                556.0
            }
            'c' | 'k' | 's' | 'v' | 'x' | 'y' | 'z' | 'J' => 500.0,
            '=' | '+' | '<' | '>' | '~' | '^' => 584.0,
            'w' | 'C' | 'D' | 'H' | 'N' | 'R' | 'U' => 722.0,
            'm' | 'M' => 833.0,
            'W' => 944.0,
            'G' | 'O' | 'Q' => 778.0,
            'A' | 'B' | 'E' | 'K' | 'P' | 'S' | 'V' | 'X' | 'Y' => 667.0,
            'F' | 'T' | 'Z' => 611.0,
            _ => 1000.0,
        }
    };
    1.15 * t.chars().map(advance).sum::<f64>() / 1000.0 * size
}

/// A perceptually ordered colour map (viridis, by anchor interpolation) for t in [0, 1].
pub fn viridis(t: f64) -> String {
    const A: [(f64, f64, f64); 6] = [
        (68.0, 1.0, 84.0),
        (65.0, 68.0, 135.0),
        (42.0, 120.0, 142.0),
        (34.0, 168.0, 132.0),
        (122.0, 209.0, 81.0),
        (253.0, 231.0, 37.0),
    ];
    let t = t.clamp(0.0, 1.0) * (A.len() - 1) as f64;
    let k = (t.floor() as usize).min(A.len() - 2);
    let f = t - k as f64;
    let c = |a: f64, b: f64| (a + (b - a) * f).round() as u8;
    format!("#{:02x}{:02x}{:02x}", c(A[k].0, A[k + 1].0), c(A[k].1, A[k + 1].1), c(A[k].2, A[k + 1].2))
}

/// "c_tran_max_mm_per_N" -> ("c_tran_max", "mm/N"): a column's quantity and its unit for labels (the unit
/// read as the tables write it, `output::table::unit_of`).
pub fn unit_of(column: &str) -> (String, String) {
    match crate::output::table::unit_of(column) {
        Some(unit) => {
            (column[..column.len() - unit.len() - 1].to_string(), unit.replace("_per_", "/").replace("Nmm", "N mm"))
        }
        None => (column.to_string(), String::new()),
    }
}

/// `quantity [unit]`.
pub fn label(column: &str) -> String {
    let (q, u) = unit_of(column);
    if u.is_empty() {
        q
    } else {
        format!("{q} [{u}]")
    }
}
