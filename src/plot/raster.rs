//! Pictures as PNG (`--plot FILE.png`) for documents that do not take SVG: the SVG rendered by resvg at
//! twice its size, its text first turned into outlines of DejaVu Sans embedded in the binary (the `dejavu`
//! crate, read by `glyphs.rs`), so no system font or text engine is needed and the result is the same on
//! every machine.

use anyhow::{anyhow, Result};
use resvg::{tiny_skia, usvg};

use super::glyphs::Font;
use super::svg::escape;

/// Pixels per SVG unit: 192 dpi for a picture laid out at 96.
const SCALE: f32 = 2.0;

/// The PNG of an SVG picture.
pub fn svg_to_png(svg: &str) -> Result<Vec<u8>> {
    let font = Font::parse(dejavu::sans::regular())?;
    let outlined = text_as_outlines(svg, &font)?;
    let tree = usvg::Tree::from_str(&outlined, &usvg::Options::default())
        .map_err(|e| anyhow!("cannot render the picture: {e}"))?;
    let size = tree.size().to_int_size().scale_by(SCALE).ok_or_else(|| anyhow!("the picture has no size"))?;
    let mut pixmap = tiny_skia::Pixmap::new(size.width(), size.height())
        .ok_or_else(|| anyhow!("the picture is too large to render ({} x {} px)", size.width(), size.height()))?;
    pixmap.fill(tiny_skia::Color::WHITE);
    resvg::render(&tree, tiny_skia::Transform::from_scale(SCALE, SCALE), &mut pixmap.as_mut());
    pixmap.encode_png().map_err(|e| anyhow!("cannot encode the PNG: {e}"))
}

/// The SVG with each `<text>` element replaced by a `<path>` of its glyphs: placed at its x, y, font-size
/// (16 px where unstated, SVG's default) and text-anchor (start, middle, end), keeping its transform and
/// its paint (fill, stroke, stroke-width, paint-order); a text whose attributes cannot be read is left out
/// of the picture rather than drawn in the wrong place.
pub fn text_as_outlines(svg: &str, font: &Font) -> Result<String> {
    let doc = roxmltree::Document::parse(svg).map_err(|e| anyhow!("cannot render the picture: {e}"))?;
    let mut out = String::with_capacity(svg.len());
    let mut copied = 0;
    for node in doc.descendants().filter(|n| n.has_tag_name("text")) {
        let range = node.range();
        if range.start < copied {
            continue; // a text inside a text (invalid SVG): drawn with its outer one
        }
        out.push_str(&svg[copied..range.start]);
        copied = range.end;
        let number = |name: &str, default: f64| match node.attribute(name) {
            None => Some(default),
            Some(v) => v.trim().trim_end_matches("px").parse::<f64>().ok().filter(|v| v.is_finite()),
        };
        let (Some(x), Some(y), Some(size)) = (number("x", 0.0), number("y", 0.0), number("font-size", 16.0)) else {
            continue;
        };
        let text: String = node.descendants().filter(|n| n.is_text()).filter_map(|n| n.text()).collect();
        let width = size * font.text_width(&text);
        let start = match node.attribute("text-anchor") {
            Some("middle") => x - width / 2.0,
            Some("end") => x - width,
            _ => x,
        };
        out.push_str(&format!(r#"<path d="{}""#, font.text_path(&text, size, start, y)));
        for name in ["class", "transform", "fill", "stroke", "stroke-width", "paint-order"] {
            if let Some(v) = node.attribute(name) {
                out.push_str(&format!(r#" {name}="{}""#, escape(v)));
            }
        }
        out.push_str("/>");
    }
    out.push_str(&svg[copied..]);
    Ok(out)
}
