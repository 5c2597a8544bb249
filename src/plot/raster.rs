//! Pictures as PNG (`--plot FILE.png`) for documents that do not take SVG: the SVG rendered by resvg at
//! twice its size, its text set in DejaVu Sans embedded in the binary (the `dejavu` crate), so no system
//! font is needed or looked up and the result is the same on every machine.

use anyhow::{anyhow, Result};
use resvg::{tiny_skia, usvg};

/// Pixels per SVG unit: 192 dpi for a picture laid out at 96.
const SCALE: f32 = 2.0;

/// The PNG of an SVG picture.
pub fn svg_to_png(svg: &str) -> Result<Vec<u8>> {
    let mut options = usvg::Options { font_family: "DejaVu Sans".into(), ..usvg::Options::default() };
    let fonts = options.fontdb_mut();
    fonts.load_font_data(dejavu::sans::regular().to_vec());
    fonts.set_sans_serif_family("DejaVu Sans");
    let tree = usvg::Tree::from_str(svg, &options).map_err(|e| anyhow!("cannot render the picture: {e}"))?;
    let size = tree.size().to_int_size().scale_by(SCALE).ok_or_else(|| anyhow!("the picture has no size"))?;
    let mut pixmap = tiny_skia::Pixmap::new(size.width(), size.height())
        .ok_or_else(|| anyhow!("the picture is too large to render ({} x {} px)", size.width(), size.height()))?;
    pixmap.fill(tiny_skia::Color::WHITE);
    resvg::render(&tree, tiny_skia::Transform::from_scale(SCALE, SCALE), &mut pixmap.as_mut());
    pixmap.encode_png().map_err(|e| anyhow!("cannot encode the PNG: {e}"))
}
