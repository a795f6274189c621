//! Figures as PNG and SVG (plotters), shared by the campaign report and `manifold plot`.
//!
//! Text is drawn with the DejaVu Sans font shipped in `assets/fonts` (no system font lookup), so
//! the figures look the same on every machine.

use crate::error::{Error, Result};
use image::ImageEncoder;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

const FONT: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");

fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
            .map_err(|_| ())
            .expect("the shipped font parses");
    });
}

/// What a drawing function returns: plotters' errors as text.
pub type DrawResult = std::result::Result<(), String>;

/// A plotters error as text.
pub fn err<E: std::fmt::Debug>(e: E) -> String {
    format!("{e:?}")
}

/// Renders one figure of `size` pixels to `dir/{name}.png` and `dir/{name}.svg` (creating `dir`).
pub fn render(
    dir: &Path,
    name: &str,
    size: (u32, u32),
    draw_png: impl Fn(DrawingArea<BitMapBackend, Shift>) -> DrawResult,
    draw_svg: impl Fn(DrawingArea<SVGBackend, Shift>) -> DrawResult,
) -> Result<()> {
    register_font();
    std::fs::create_dir_all(dir).map_err(|e| Error::file(dir, format!("cannot create: {e}")))?;
    let png = dir.join(format!("{name}.png"));
    let svg = dir.join(format!("{name}.svg"));
    crate::files::write_atomically(&png, &png_bytes(size, draw_png)?)?;
    let mut text = String::new();
    draw_svg(SVGBackend::with_string(&mut text, size).into_drawing_area())
        .map_err(|e| Error::file(&svg, format!("cannot draw: {e}")))?;
    crate::files::write_atomically(&svg, text.as_bytes())
}

/// Renders one figure of `size` pixels as a PNG file in memory (for a page to inline).
pub fn png_bytes(
    size: (u32, u32),
    draw: impl Fn(DrawingArea<BitMapBackend, Shift>) -> DrawResult,
) -> Result<Vec<u8>> {
    register_font();
    let mut rgb = vec![0u8; size.0 as usize * size.1 as usize * 3];
    draw(BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area())
        .map_err(|e| Error::Input(format!("cannot draw a figure: {e}")))?;
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(&rgb, size.0, size.1, image::ColorType::Rgb8)
        .map_err(|e| Error::Input(format!("cannot encode a figure as PNG: {e}")))?;
    Ok(png)
}
