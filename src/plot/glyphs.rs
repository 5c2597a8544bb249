//! Text as outlines, for pictures rendered to PNG without a text engine: the glyphs of a TrueType font
//! (DejaVu Sans, embedded by the `dejavu` crate) read from its tables (Apple's TrueType Reference Manual,
//! tables `head`, `maxp`, `hhea`, `hmtx`, `cmap` formats 4 and 12, `loca` and `glyf`, simple and composite
//! glyphs) and set side by side at their advance widths, as SVG path data. Left out, as a picture's labels
//! need neither: kerning, ligatures, hinting and right-to-left scripts.

use anyhow::{bail, Result};

/// A TrueType font's tables, read in place.
pub struct Font<'a> {
    units_per_em: f64,
    long_offsets: bool,
    glyph_count: u16,
    metrics_count: u16,
    /// The character map's subtable: format 12 (all of Unicode) where the font has one, else format 4.
    cmap: CharacterMap<'a>,
    hmtx: &'a [u8],
    loca: &'a [u8],
    glyf: &'a [u8],
}

/// Where characters are looked up: the `cmap` subtable chosen when the font is read.
enum CharacterMap<'a> {
    Full(&'a [u8]),
    Basic(&'a [u8]),
    None,
}

/// A point of an outline in font units and whether it lies on the curve (else it is a quadratic
/// Bézier control point).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutlinePoint {
    /// Font units, rightwards.
    pub x: f64,
    /// Font units, upwards from the baseline.
    pub y: f64,
    /// On the curve, else a control point.
    pub on_curve: bool,
}

fn u16_at(d: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_be_bytes([*d.get(at)?, *d.get(at + 1)?]))
}

fn i16_at(d: &[u8], at: usize) -> Option<i16> {
    u16_at(d, at).map(|v| v as i16)
}

fn u32_at(d: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_be_bytes([*d.get(at)?, *d.get(at + 1)?, *d.get(at + 2)?, *d.get(at + 3)?]))
}

/// A composite glyph nests at most this deep (fonts nest one or two levels; a loop is a broken font).
const MOST_NESTING: usize = 8;

impl<'a> Font<'a> {
    /// The font in `data` (a TrueType file), or what it lacks.
    pub fn parse(data: &'a [u8]) -> Result<Font<'a>> {
        let table = |tag: &[u8; 4]| -> Result<&'a [u8]> {
            let count = u16_at(data, 4).unwrap_or(0) as usize;
            for k in 0..count {
                let record = 12 + 16 * k;
                if data.get(record..record + 4) == Some(&tag[..]) {
                    let (offset, length) = (u32_at(data, record + 8), u32_at(data, record + 12));
                    if let (Some(o), Some(l)) = (offset, length) {
                        if let Some(t) = data.get(o as usize..o as usize + l as usize) {
                            return Ok(t);
                        }
                    }
                }
            }
            bail!("the font has no readable `{}` table", String::from_utf8_lossy(tag))
        };
        let (head, maxp, hhea) = (table(b"head")?, table(b"maxp")?, table(b"hhea")?);
        let font = Font {
            units_per_em: u16_at(head, 18).unwrap_or(0) as f64,
            long_offsets: i16_at(head, 50) == Some(1),
            glyph_count: u16_at(maxp, 4).unwrap_or(0),
            metrics_count: u16_at(hhea, 34).unwrap_or(0),
            cmap: character_map(table(b"cmap")?),
            hmtx: table(b"hmtx")?,
            loca: table(b"loca")?,
            glyf: table(b"glyf")?,
        };
        if font.units_per_em <= 0.0 || font.metrics_count == 0 {
            bail!("the font's head or hhea table is empty");
        }
        Ok(font)
    }

    /// Font units per em: a glyph set at size s (px) is scaled by s / units_per_em.
    pub fn units_per_em(&self) -> f64 {
        self.units_per_em
    }

    /// The glyph of a character (0, the font's "missing" glyph, where the font has none).
    pub fn glyph(&self, c: char) -> u16 {
        match self.cmap {
            CharacterMap::Full(sub) => format12(sub, c as u32),
            CharacterMap::Basic(sub) => u16::try_from(c as u32).map_or(0, |code| format4_glyph(sub, code)),
            CharacterMap::None => 0,
        }
    }

    /// A glyph's advance width (font units).
    pub fn advance(&self, glyph: u16) -> f64 {
        let entry = glyph.min(self.metrics_count - 1) as usize;
        u16_at(self.hmtx, 4 * entry).unwrap_or(0) as f64
    }

    /// The width of a text at size 1 (ems): the sum of its characters' advances.
    pub fn text_width(&self, text: &str) -> f64 {
        text.chars().map(|c| self.advance(self.glyph(c))).sum::<f64>() / self.units_per_em
    }

    fn glyph_data(&self, glyph: u16) -> &'a [u8] {
        if glyph >= self.glyph_count {
            return &[];
        }
        let g = glyph as usize;
        let (start, end) = if self.long_offsets {
            (u32_at(self.loca, 4 * g).map(|v| v as usize), u32_at(self.loca, 4 * g + 4).map(|v| v as usize))
        } else {
            (u16_at(self.loca, 2 * g).map(|v| 2 * v as usize), u16_at(self.loca, 2 * g + 2).map(|v| 2 * v as usize))
        };
        match (start, end) {
            (Some(s), Some(e)) if s < e => self.glyf.get(s..e).unwrap_or(&[]),
            _ => &[],
        }
    }

    /// A glyph's contours (font units, y up), components of a composite glyph placed by their offsets and
    /// scales; a broken glyph gives what could be read of it.
    pub fn contours(&self, glyph: u16) -> Vec<Vec<OutlinePoint>> {
        let mut contours = Vec::new();
        self.add_contours(glyph, [1.0, 0.0, 0.0, 1.0, 0.0, 0.0], 0, &mut contours);
        contours
    }

    /// Appends a glyph's contours, each point taken through the affine map [a, b, c, d, e, f]:
    /// (x, y) -> (a x + c y + e, b x + d y + f).
    fn add_contours(&self, glyph: u16, m: [f64; 6], depth: usize, out: &mut Vec<Vec<OutlinePoint>>) {
        let d = self.glyph_data(glyph);
        let Some(count) = i16_at(d, 0) else { return };
        let map = |x: f64, y: f64, on_curve: bool| OutlinePoint {
            x: m[0] * x + m[2] * y + m[4],
            y: m[1] * x + m[3] * y + m[5],
            on_curve,
        };
        if count >= 0 {
            if let Some(simple) = simple_glyph(d, count as usize) {
                out.extend(simple.into_iter().map(|c| c.into_iter().map(|p| map(p.x, p.y, p.on_curve)).collect()));
            }
            return;
        }
        if depth >= MOST_NESTING {
            return;
        }
        // Composite: components until one lacks MORE_COMPONENTS (0x20).
        let mut at = 10;
        loop {
            let (Some(flags), Some(component)) = (u16_at(d, at), u16_at(d, at + 2)) else { return };
            at += 4;
            let (dx, dy) = if flags & 0x1 != 0 {
                let r = (i16_at(d, at), i16_at(d, at + 2));
                at += 4;
                match r {
                    (Some(x), Some(y)) => (x as f64, y as f64),
                    _ => return,
                }
            } else {
                let r = (d.get(at).copied(), d.get(at + 1).copied());
                at += 2;
                match r {
                    (Some(x), Some(y)) => (x as i8 as f64, y as i8 as f64),
                    _ => return,
                }
            };
            // ARGS_ARE_XY_VALUES (0x2) clear: the arguments match points, which no label glyph needs; placed
            // without an offset.
            let (dx, dy) = if flags & 0x2 != 0 { (dx, dy) } else { (0.0, 0.0) };
            let f2dot14 = |at: usize| i16_at(d, at).map(|v| v as f64 / 16384.0);
            let scale = if flags & 0x8 != 0 {
                at += 2;
                f2dot14(at - 2).map(|s| [s, 0.0, 0.0, s])
            } else if flags & 0x40 != 0 {
                at += 4;
                f2dot14(at - 4).zip(f2dot14(at - 2)).map(|(sx, sy)| [sx, 0.0, 0.0, sy])
            } else if flags & 0x80 != 0 {
                at += 8;
                (|| Some([f2dot14(at - 8)?, f2dot14(at - 6)?, f2dot14(at - 4)?, f2dot14(at - 2)?]))()
            } else {
                Some([1.0, 0.0, 0.0, 1.0])
            };
            let Some([a, b, c, e]) = scale else { return };
            // The component's map, then this glyph's: m o (x -> [a c; b e] x + (dx, dy)).
            let inner = [
                m[0] * a + m[2] * b,
                m[1] * a + m[3] * b,
                m[0] * c + m[2] * e,
                m[1] * c + m[3] * e,
                m[0] * dx + m[2] * dy + m[4],
                m[1] * dx + m[3] * dy + m[5],
            ];
            self.add_contours(component, inner, depth + 1, out);
            if flags & 0x20 == 0 {
                return;
            }
        }
    }

    /// SVG path data of a text set at `size` (px) with its baseline's start at (x, y), y down as SVG's.
    pub fn text_path(&self, text: &str, size: f64, x: f64, y: f64) -> String {
        let s = size / self.units_per_em;
        let mut d = String::new();
        let mut pen = x;
        let n = |v: f64| (v * 100.0).round() / 100.0;
        for c in text.chars() {
            let glyph = self.glyph(c);
            for contour in self.contours(glyph) {
                let place = |p: &OutlinePoint| (n(pen + s * p.x), n(y - s * p.y));
                write_contour(&mut d, &contour, &place);
            }
            pen += s * self.advance(glyph);
        }
        d
    }
}

/// One closed contour as M, Q and L commands: two control points in a row imply the on-curve point
/// half-way between them; a contour starts at its first on-curve point, or, made of control points alone,
/// at the point half-way between its first two.
fn write_contour(d: &mut String, contour: &[OutlinePoint], place: &impl Fn(&OutlinePoint) -> (f64, f64)) {
    use std::fmt::Write;
    let len = contour.len();
    let Some(from) = contour.iter().position(|p| p.on_curve) else {
        if len < 2 {
            return;
        }
        let (a, b) = (contour[0], contour[1]);
        let mid = OutlinePoint { x: (a.x + b.x) / 2.0, y: (a.y + b.y) / 2.0, on_curve: true };
        let opened: Vec<OutlinePoint> = std::iter::once(mid).chain(contour[1..].iter().copied()).chain([a]).collect();
        return write_contour(d, &opened, place);
    };
    let start = place(&contour[from]);
    let _ = write!(d, "M{} {}", start.0, start.1);
    let mut control: Option<(f64, f64)> = None;
    for k in 1..=len {
        let p = &contour[(from + k) % len];
        let at = place(p);
        match (control, p.on_curve) {
            (None, true) => {
                let _ = write!(d, "L{} {}", at.0, at.1);
            }
            (Some(c), true) => {
                let _ = write!(d, "Q{} {} {} {}", c.0, c.1, at.0, at.1);
                control = None;
            }
            (None, false) => control = Some(at),
            (Some(c), false) => {
                let mid = ((c.0 + at.0) / 2.0, (c.1 + at.1) / 2.0);
                let _ = write!(d, "Q{} {} {} {}", c.0, c.1, mid.0, mid.1);
                control = Some(at);
            }
        }
    }
    d.push('Z');
}

/// A simple glyph's contours (font units), None where its data is cut short.
fn simple_glyph(d: &[u8], contour_count: usize) -> Option<Vec<Vec<OutlinePoint>>> {
    let mut ends = Vec::with_capacity(contour_count);
    for k in 0..contour_count {
        ends.push(u16_at(d, 10 + 2 * k)? as usize);
    }
    let point_count = ends.last().map_or(0, |&e| e + 1);
    let instructions = u16_at(d, 10 + 2 * contour_count)? as usize;
    let mut at = 12 + 2 * contour_count + instructions;
    // Flags, each with a repeat count where bit 3 is set.
    let mut flags = Vec::with_capacity(point_count);
    while flags.len() < point_count {
        let f = *d.get(at)?;
        at += 1;
        flags.push(f);
        if f & 0x8 != 0 {
            let repeat = *d.get(at)?;
            at += 1;
            for _ in 0..repeat {
                flags.push(f);
            }
        }
    }
    flags.truncate(point_count);
    // Coordinates as deltas: a byte (bit 1 or 2 set; bit 4 or 5 its sign) or a word (else; bit 4 or 5 set
    // repeats the previous value).
    let mut read_axis = |short: u8, same: u8| -> Option<Vec<f64>> {
        let mut value = 0i32;
        let mut values = Vec::with_capacity(point_count);
        for &f in &flags {
            if f & short != 0 {
                let delta = *d.get(at)? as i32;
                at += 1;
                value += if f & same != 0 { delta } else { -delta };
            } else if f & same == 0 {
                value += i16_at(d, at)? as i32;
                at += 2;
            }
            values.push(value as f64);
        }
        Some(values)
    };
    let xs = read_axis(0x2, 0x10)?;
    let ys = read_axis(0x4, 0x20)?;
    let mut contours = Vec::with_capacity(contour_count);
    let mut begin = 0;
    for &end in &ends {
        if end < begin || end >= point_count {
            return None;
        }
        contours
            .push((begin..=end).map(|k| OutlinePoint { x: xs[k], y: ys[k], on_curve: flags[k] & 0x1 != 0 }).collect());
        begin = end + 1;
    }
    Some(contours)
}

/// The Unicode subtable of a `cmap` table: format 12 (platform 3 encoding 10, or Unicode full
/// repertoire) first, else format 4 (platform 3 encoding 1, or Unicode BMP).
fn character_map(cmap: &[u8]) -> CharacterMap<'_> {
    let mut found = CharacterMap::None;
    for k in 0..u16_at(cmap, 2).unwrap_or(0) as usize {
        let record = 4 + 8 * k;
        let (platform, encoding) = (u16_at(cmap, record), u16_at(cmap, record + 2));
        let Some(sub) = u32_at(cmap, record + 4).and_then(|o| cmap.get(o as usize..)) else { continue };
        match (platform, encoding, u16_at(sub, 0)) {
            (Some(3), Some(10), Some(12)) | (Some(0), Some(4), Some(12)) => return CharacterMap::Full(sub),
            (Some(3), Some(1), Some(4)) | (Some(0), Some(3), Some(4)) => found = CharacterMap::Basic(sub),
            _ => {}
        }
    }
    found
}

fn format4_glyph(sub: &[u8], code: u16) -> u16 {
    let segments = u16_at(sub, 6).unwrap_or(0) as usize / 2;
    let (ends, starts, deltas, ranges) = (14, 16 + 2 * segments, 16 + 4 * segments, 16 + 6 * segments);
    for k in 0..segments {
        let (Some(end), Some(start)) = (u16_at(sub, ends + 2 * k), u16_at(sub, starts + 2 * k)) else { return 0 };
        if code > end {
            continue;
        }
        if code < start {
            return 0;
        }
        let delta = u16_at(sub, deltas + 2 * k).unwrap_or(0);
        let range = u16_at(sub, ranges + 2 * k).unwrap_or(0) as usize;
        if range == 0 {
            return code.wrapping_add(delta);
        }
        // idRangeOffset counts bytes from its own place to the glyph index (the format's addressing).
        let at = ranges + 2 * k + range + 2 * (code - start) as usize;
        return match u16_at(sub, at) {
            Some(0) | None => 0,
            Some(g) => g.wrapping_add(delta),
        };
    }
    0
}

fn format12(sub: &[u8], code: u32) -> u16 {
    let groups = u32_at(sub, 12).unwrap_or(0) as usize;
    for k in 0..groups {
        let at = 16 + 12 * k;
        let (Some(start), Some(end), Some(first)) = (u32_at(sub, at), u32_at(sub, at + 4), u32_at(sub, at + 8)) else {
            return 0;
        };
        if (start..=end).contains(&code) {
            return u16::try_from(first + (code - start)).unwrap_or(0);
        }
    }
    0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn font() -> Font<'static> {
        Font::parse(dejavu::sans::regular()).unwrap()
    }

    /// A glyph's bounding box as its `glyf` header states it (x_min, y_min, x_max, y_max; font units), None
    /// for a glyph without an outline (a space).
    fn stated_bounds(f: &Font, glyph: u16) -> Option<[f64; 4]> {
        let d = f.glyph_data(glyph);
        Some([i16_at(d, 2)? as f64, i16_at(d, 4)? as f64, i16_at(d, 6)? as f64, i16_at(d, 8)? as f64])
    }

    /// A contour of control points alone (TrueType allows it: a circle of four) is a closed curve through
    /// the mid-points of its sides, each control point used once, ending where it starts.
    #[test]
    fn a_contour_of_control_points_alone_uses_each_once() {
        let p = |x: f64, y: f64| OutlinePoint { x, y, on_curve: false };
        let square = [p(0.0, 0.0), p(2.0, 0.0), p(2.0, 2.0), p(0.0, 2.0)];
        let mut d = String::new();
        write_contour(&mut d, &square, &|q: &OutlinePoint| (q.x, q.y));
        assert_eq!(d, "M1 0Q2 0 2 1Q2 2 1 2Q0 2 0 1Q0 0 1 0Z");
    }

    /// Each glyph's outline lies exactly in the bounding box its `glyf` header states (the header is the
    /// font's own, independent record of the outline: a misread flag, delta or component offset moves a
    /// point out of it), for every printable ASCII character and the symbols labels use.
    #[test]
    fn outlines_fill_the_bounds_the_font_states() {
        let f = font();
        let chars = (' '..='~').chain("θ±×·−²³°µμΔσ".chars());
        let mut composites = 0;
        for c in chars {
            let g = f.glyph(c);
            assert!(g != 0 || c == ' ', "{c:?} has a glyph");
            let contours = f.contours(g);
            let Some([x0, y0, x1, y1]) = stated_bounds(&f, g) else { continue };
            composites += (i16_at(f.glyph_data(g), 0).unwrap() < 0) as usize;
            let points: Vec<_> = contours.iter().flatten().collect();
            assert!(!points.is_empty(), "{c:?} has an outline");
            let min_x = points.iter().map(|p| p.x).fold(f64::MAX, f64::min);
            let max_x = points.iter().map(|p| p.x).fold(f64::MIN, f64::max);
            let min_y = points.iter().map(|p| p.y).fold(f64::MAX, f64::min);
            let max_y = points.iter().map(|p| p.y).fold(f64::MIN, f64::max);
            assert_eq!([min_x, min_y, max_x, max_y], [x0, y0, x1, y1], "{c:?}");
        }
        assert!(composites > 0, "composite glyphs are among those checked");
    }
}
