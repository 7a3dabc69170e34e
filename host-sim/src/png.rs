//! PNG figures: plotters' bitmap backend draws into memory and the `png` crate encodes the
//! pixels, so the command line does not carry an image library for one file format.

use plotters::coord::Shift;
use plotters::prelude::{BitMapBackend, DrawingArea, IntoDrawingArea};
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

/// The drawing area of a figure of [`draw_png`]: 8-bit RGB pixels in memory.
pub type PngArea<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// Draws a `width` x `height` pixel figure with `draw` (which fills, plots and presents the
/// area it is given) and writes it to `path` as an 8-bit RGB PNG.
pub fn draw_png(
    path: &Path,
    (width, height): (u32, u32),
    draw: impl for<'a> FnOnce(&PngArea<'a>) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let mut pixels = vec![0u8; 3 * width as usize * height as usize];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, (width, height)).into_drawing_area();
        draw(&root)?;
        root.present()
            .map_err(|e| anyhow::anyhow!("plot {}: {e}", path.display()))?;
    }
    // the file and the encoder: any error names the file once
    let write = || -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        let file = File::create(path)?;
        let mut enc = png::Encoder::new(BufWriter::new(file), width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header()?;
        w.write_image_data(&pixels)?;
        w.finish()?;
        Ok(())
    };
    write().map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}

/// Tick label of a log10 axis drawn linearly (the coordinate is log10 of the value): the value
/// 10^v, `1eN` at a whole power of ten (`1e0`, never `1e-0`), else two decimals between 0.01
/// and 1000 and two significant digits outside.
pub fn pow10_label(v: &f64) -> String {
    let x = 10f64.powf(*v);
    let r = v.round();
    if (v - r).abs() < 1e-9 {
        // `as` maps -0.0 to 0: a log10 of exactly 0 computed as -0.0 is labelled 1e0
        format!("1e{}", r as i64)
    } else if (0.01..1000.0).contains(&x) {
        format!("{x:.2}")
    } else {
        format!("{x:.1e}")
    }
}
