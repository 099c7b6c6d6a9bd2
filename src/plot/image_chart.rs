//! The image fits' chart (`scripts/image-chart.sh`): wall time of each run (log) against
//! the ΔE2000 of its fitted image against the truth, one panel per light, the median as a
//! filled marker and the 99th percentile as the same marker outlined, one colour per
//! method, one marker shape per image, each method's medians joined across images.

use plotters::coord::Shift;
use plotters::coord::combinators::BindKeyPoints;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::common::{
    Draw, DrawResult, anchored, bold, draw_text, draw_title, font, format_significant, render_named,
};
use super::evaluation::{colour, log_grid, log_range, unique};
use super::{ImageFormat, Layout};
use crate::error::{Error, Result};

/// Size of the chart in pixels.
pub const IMAGE_CHART_SIZE: (u32, u32) = (1400, 900);

/// One run under one light.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageChartPoint {
    /// The image's label (its size, `64²`).
    pub image: String,
    /// The method (`shared`, `shared K=2`, `per-pixel`).
    pub method: String,
    /// The light.
    pub light: String,
    /// Wall time of the run (s).
    pub seconds: f64,
    /// Median ΔE2000 over the pixels.
    pub median: f64,
    /// 99th percentile.
    pub p99: f64,
}

/// Renders the chart of `points`.
pub fn image_chart(points: &[ImageChartPoint], format: ImageFormat) -> Result<Vec<u8>> {
    if points.is_empty() {
        return Err(Error::invalid("image chart", "no points to plot"));
    }
    Ok(render_named(
        &ImageChart { points },
        "image chart",
        IMAGE_CHART_SIZE,
        format,
    )?
    .0)
}

struct ImageChart<'a> {
    points: &'a [ImageChartPoint],
}

/// Labelled ticks of a log axis over [lo, hi]: 1, 2 and 5 of every decade.
fn ticks(lo: f64, hi: f64) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && hi > lo) {
        return Vec::new();
    }
    let (first, last) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    (first..=last)
        .flat_map(|n| {
            [1.0, 2.0, 5.0].map(|m| format!("{m}e{n}").parse().unwrap_or(m * 10f64.powi(n)))
        })
        .filter(|v| *v >= lo && *v <= hi)
        .collect()
}

/// Draws the marker of image `shape` (circle, triangle, square, diamond, repeating) at
/// `at`: filled for a median, outlined for a 99th percentile.
fn size_marker<DB: DrawingBackend, CT: CoordTranslate>(
    area: &DrawingArea<DB, CT>,
    at: CT::From,
    shape: usize,
    filled: bool,
    c: RGBColor,
) -> DrawResult<(), DB>
where
    CT::From: Clone + 'static,
{
    let s = 7;
    let points: Vec<(i32, i32)> = match shape % 4 {
        0 => {
            return if filled {
                area.draw(&Circle::new(at, s, c.filled()))
            } else {
                area.draw(&Circle::new(at, s, c.stroke_width(2)))
            };
        }
        1 => vec![(0, -s - 2), (s + 1, s), (-s - 1, s)],
        2 => vec![
            (-s + 1, -s + 1),
            (s - 1, -s + 1),
            (s - 1, s - 1),
            (-s + 1, s - 1),
        ],
        _ => vec![(0, -s - 2), (s + 1, 0), (0, s + 2), (-s - 1, 0)],
    };
    if filled {
        area.draw(&(EmptyElement::at(at) + Polygon::new(points, c.filled())))
    } else {
        let mut closed = points.clone();
        closed.push(points[0]);
        area.draw(&(EmptyElement::at(at) + PathElement::new(closed, c.stroke_width(2))))
    }
}

impl Draw for ImageChart<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<Layout, DB> {
        let (width, height) = IMAGE_CHART_SIZE;
        let lights = unique(self.points.iter().map(|p| p.light.clone()));
        let methods = unique(self.points.iter().map(|p| p.method.clone()));
        let images = unique(self.points.iter().map(|p| p.image.clone()));
        draw_title(
            root,
            "Image fits: wall time against ΔE2000 of the fitted image against the truth",
            (width as i32 / 2, 22),
        )?;
        let legend_w = 240;
        let area = root
            .clone()
            .shrink((0, 44), (width - legend_w, height - 44));
        let cols = lights.len().clamp(1, 2);
        let rows = lights.len().div_ceil(cols).max(1);
        let panels = area.split_evenly((rows, cols));
        let (t_lo, t_hi) = log_range(self.points.iter().map(|p| p.seconds));
        let (e_lo, e_hi) = log_range(self.points.iter().flat_map(|p| [p.median, p.p99]));
        let positive = |v: f64| v.is_finite() && v > 0.0;
        for (panel, light) in panels.iter().zip(&lights) {
            let mut chart = ChartBuilder::on(panel)
                .margin(12)
                .caption(format!("under {}", light.to_uppercase()), bold(16.0))
                .x_label_area_size(46)
                .y_label_area_size(70)
                .build_cartesian_2d(
                    (t_lo..t_hi)
                        .log_scale()
                        .with_key_points(ticks(t_lo, t_hi))
                        .with_light_points(log_grid(t_lo, t_hi)),
                    (e_lo..e_hi)
                        .log_scale()
                        .with_key_points(ticks(e_lo, e_hi))
                        .with_light_points(log_grid(e_lo, e_hi)),
                )?;
            chart
                .configure_mesh()
                .light_line_style(RGBColor(235, 235, 235))
                .bold_line_style(RGBColor(215, 215, 215))
                .x_desc("wall time (s, log)")
                .y_desc("ΔE2000 against the truth (log)")
                .x_label_formatter(&|v| format_significant(*v, 2))
                .y_label_formatter(&|v| format_significant(*v, 2))
                .label_style(font(13.0))
                .axis_desc_style(font(14.0))
                .draw()?;
            let here: Vec<&ImageChartPoint> =
                self.points.iter().filter(|p| &p.light == light).collect();
            for (k, method) in methods.iter().enumerate() {
                let c = colour(k);
                let mine: Vec<&&ImageChartPoint> =
                    here.iter().filter(|p| &p.method == method).collect();
                // The method's medians across image sizes.
                chart.draw_series(LineSeries::new(
                    mine.iter()
                        .filter(|p| positive(p.seconds) && positive(p.median))
                        .map(|p| (p.seconds, p.median)),
                    c.mix(0.5).stroke_width(1),
                ))?;
                for p in mine.iter().filter(|p| positive(p.seconds)) {
                    let shape = images.iter().position(|i| i == &p.image).unwrap_or(0);
                    if positive(p.median) && positive(p.p99) {
                        chart.draw_series(LineSeries::new(
                            [(p.seconds, p.median), (p.seconds, p.p99)],
                            c.mix(0.35).stroke_width(1),
                        ))?;
                    }
                    if positive(p.p99) {
                        size_marker(chart.plotting_area(), (p.seconds, p.p99), shape, false, c)?;
                    }
                    if positive(p.median) {
                        size_marker(chart.plotting_area(), (p.seconds, p.median), shape, true, c)?;
                    }
                }
            }
        }
        let legend = root
            .clone()
            .shrink(((width - legend_w) as i32, 60), (legend_w, height - 60));
        let entry = |text: &str, y: i32| {
            draw_text(
                &legend,
                text,
                (38, y),
                &anchored(font(14.0), HPos::Left, VPos::Center),
            )
        };
        let heading = |text: &str, y: i32| {
            draw_text(
                &legend,
                text,
                (10, y),
                &anchored(bold(15.0), HPos::Left, VPos::Center),
            )
        };
        let grey = RGBColor(60, 60, 60);
        let mut y = 10;
        heading("method", y)?;
        for (k, m) in methods.iter().enumerate() {
            y += 24;
            legend.draw(&Rectangle::new(
                [(12, y - 7), (28, y + 7)],
                colour(k).filled(),
            ))?;
            entry(m, y)?;
        }
        y += 36;
        heading("image", y)?;
        for (k, image) in images.iter().enumerate() {
            y += 24;
            size_marker(&legend, (20, y), k, true, grey)?;
            entry(image, y)?;
        }
        y += 36;
        heading("marker", y)?;
        y += 24;
        size_marker(&legend, (20, y), 0, true, grey)?;
        entry("median", y)?;
        y += 24;
        size_marker(&legend, (20, y), 0, false, grey)?;
        entry("99th percentile", y)?;
        y += 24;
        entry("line: one method", y)?;
        Ok(Layout::default())
    }
}
