//! Drawing helpers shared by the figures: rendering to PNG or SVG, text styles, tick
//! placement and number formatting.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::font::FAMILY;
use super::text::TextBitmap;
use super::{FigureKind, ImageFormat, Layout};
use crate::error::{Error, Result};

/// The ten colours of matplotlib's `tab10` palette, which every figure draws from.
pub(crate) const TAB10: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Result of drawing onto a backend.
pub(crate) type DrawResult<T, DB> =
    std::result::Result<T, DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// A figure that can be drawn onto any plotters backend.
pub(crate) trait Draw {
    /// Draws the figure onto `root` (already filled white) and reports where things are.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<Layout, DB>;
}

/// Renders `figure` of `kind` at its size into PNG or SVG bytes, with the layout it drew.
pub(crate) fn render<D: Draw>(
    figure: &D,
    kind: FigureKind,
    format: ImageFormat,
) -> Result<(Vec<u8>, Layout)> {
    render_named(figure, kind.suffix(), kind.size(), format)
}

/// Renders `figure`, named `name` in errors, at `size` into PNG or SVG bytes: for figures
/// outside the per-material set of [`FigureKind`] (the evaluation charts).
pub(crate) fn render_named<D: Draw>(
    figure: &D,
    name: &str,
    size: (u32, u32),
    format: ImageFormat,
) -> Result<(Vec<u8>, Layout)> {
    super::font::ensure_registered()?;
    let failed =
        |e: String| Error::invalid(format!("{name} figure"), format!("could not be drawn: {e}"));
    match format {
        ImageFormat::Png => {
            let (w, h) = size;
            let mut buffer = vec![255u8; w as usize * h as usize * 3];
            let layout = {
                let backend = TextBitmap::new(BitMapBackend::with_buffer(&mut buffer, size))?;
                let root = backend.into_drawing_area();
                root.fill(&WHITE).map_err(|e| failed(e.to_string()))?;
                let layout = figure.draw(&root).map_err(|e| failed(e.to_string()))?;
                root.present().map_err(|e| failed(e.to_string()))?;
                layout
            };
            Ok((encode_png(&buffer, w, h).map_err(failed)?, layout))
        }
        ImageFormat::Svg => {
            let mut svg = String::new();
            let layout = {
                let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
                root.fill(&WHITE).map_err(|e| failed(e.to_string()))?;
                let layout = figure.draw(&root).map_err(|e| failed(e.to_string()))?;
                root.present().map_err(|e| failed(e.to_string()))?;
                layout
            };
            Ok((svg.into_bytes(), layout))
        }
    }
}

/// A line of text to set on a picture: the text, the pixel its centre sits on, its size
/// in pixels and whether it is bold.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Caption {
    /// What it says.
    pub(crate) text: String,
    /// Centre of the text (x, y) in pixels.
    pub(crate) centre: (i32, i32),
    /// Font size in pixels.
    pub(crate) size: f64,
    /// Bold instead of regular.
    pub(crate) bold: bool,
}

/// Sets `captions` in black onto `rgb` (8-bit RGB rows of `size`), in the figures' font
/// and glyph layout: labels on pictures that are not figures, such as the renderer's
/// compare image.
pub(crate) fn draw_captions(rgb: &mut [u8], size: (u32, u32), captions: &[Caption]) -> Result<()> {
    super::font::ensure_registered()?;
    if rgb.len() != size.0 as usize * size.1 as usize * 3 {
        return Err(Error::invalid(
            "captions",
            format!(
                "the picture holds {} bytes, not 3 per pixel of {}×{}",
                rgb.len(),
                size.0,
                size.1
            ),
        ));
    }
    let failed = |e: String| Error::invalid("captions", format!("could not be drawn: {e}"));
    let backend = TextBitmap::new(BitMapBackend::with_buffer(rgb, size))?;
    let root = backend.into_drawing_area();
    for caption in captions {
        let style = if caption.bold {
            bold(caption.size)
        } else {
            font(caption.size)
        };
        draw_text(
            &root,
            &caption.text,
            caption.centre,
            &anchored(style, HPos::Center, VPos::Center),
        )
        .map_err(|e| failed(e.to_string()))?;
    }
    root.present().map_err(|e| failed(e.to_string()))?;
    Ok(())
}

fn encode_png(rgb: &[u8], width: u32, height: u32) -> std::result::Result<Vec<u8>, String> {
    let mut bytes = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut bytes, width, height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
        writer.write_image_data(rgb).map_err(|e| e.to_string())?;
        writer.finish().map_err(|e| e.to_string())?;
    }
    Ok(bytes)
}

/// Regular text of `size` px.
pub(crate) fn font(size: f64) -> TextStyle<'static> {
    (FAMILY, size).into_font().color(&BLACK)
}

/// Bold text of `size` px.
pub(crate) fn bold(size: f64) -> TextStyle<'static> {
    (FAMILY, size)
        .into_font()
        .style(FontStyle::Bold)
        .color(&BLACK)
}

/// `style` anchored at (`h`, `v`) of the text.
pub(crate) fn anchored(style: TextStyle<'static>, h: HPos, v: VPos) -> TextStyle<'static> {
    style.pos(Pos::new(h, v))
}

/// Draws `text` with its anchor at `at` (absolute pixels).
pub(crate) fn draw_text<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    text: &str,
    at: (i32, i32),
    style: &TextStyle<'static>,
) -> DrawResult<(), DB> {
    root.draw(&Text::new(text.to_string(), at, style.clone()))
}

/// Draws a figure's title, bold and centred on `at`.
pub(crate) fn draw_title<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    at: (i32, i32),
) -> DrawResult<(), DB> {
    draw_text(
        root,
        title,
        at,
        &anchored(bold(21.0), HPos::Center, VPos::Center),
    )
}

/// A "nice" tick spacing (1, 2 or 5 × 10ⁿ) giving about `target` ticks over [lo, hi].
pub(crate) fn tick_step(lo: f64, hi: f64, target: usize) -> f64 {
    let span = (hi - lo).abs();
    if !(span.is_finite() && span > 0.0) {
        return 1.0;
    }
    let raw = span / target.max(1) as f64;
    let magnitude = 10f64.powf(raw.log10().floor());
    let fraction = raw / magnitude;
    let nice = if fraction < 1.5 {
        1.0
    } else if fraction < 3.5 {
        2.0
    } else if fraction < 7.5 {
        5.0
    } else {
        10.0
    };
    nice * magnitude
}

/// Tick values at multiples of [`tick_step`] inside [lo, hi].
pub(crate) fn ticks(lo: f64, hi: f64, target: usize) -> Vec<f64> {
    let step = tick_step(lo, hi, target);
    let (lo, hi) = (lo.min(hi), lo.max(hi));
    if !(lo.is_finite() && hi.is_finite()) {
        return Vec::new();
    }
    let first = (lo / step - 1e-9).ceil() as i64;
    let last = (hi / step + 1e-9).floor() as i64;
    (first..=last.min(first + 100))
        .map(|k| {
            let v = k as f64 * step;
            // Avoid printing "-0".
            if v.abs() < step * 1e-9 { 0.0 } else { v }
        })
        .collect()
}

/// Formats a tick value with as many decimals as the tick step needs.
pub(crate) fn format_tick(value: f64, step: f64) -> String {
    if value == 0.0 {
        return "0".to_string();
    }
    if step < 1e-4 || value.abs() >= 1e6 {
        return format!("{value:.1e}");
    }
    let decimals = (-step.log10().floor()).max(0.0) as usize;
    format!("{value:.decimals$}")
}

/// Formats a number with about `digits` significant digits, for captions.
pub(crate) fn format_significant(value: f64, digits: usize) -> String {
    if !value.is_finite() {
        return value.to_string();
    }
    if value == 0.0 {
        return "0".to_string();
    }
    let magnitude = value.abs().log10().floor() as i32;
    if !(-4..6).contains(&magnitude) {
        return format!("{value:.prec$e}", prec = digits.saturating_sub(1));
    }
    let decimals = (digits as i32 - 1 - magnitude).max(0) as usize;
    let text = format!("{value:.decimals$}");
    // "10.0" reads as more precise than it is; drop trailing zeros.
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_numbers_inside_the_range() {
        assert_eq!(
            ticks(0.0, 1.0, 5),
            vec![0.0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0]
        );
        assert_eq!(format_tick(0.6000000000000001, 0.2), "0.6");
        assert_eq!(format_tick(-0.004, 0.002), "-0.004");
        assert_eq!(
            ticks(295.0, 785.0, 5),
            vec![300.0, 400.0, 500.0, 600.0, 700.0]
        );
        assert_eq!(format_significant(0.012345, 3), "0.0123");
        assert_eq!(format_significant(612.4, 3), "612");
        assert_eq!(format_significant(10.0, 3), "10");
        assert_eq!(format_significant(0.5, 3), "0.5");
    }
}
