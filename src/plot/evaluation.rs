//! Charts of the method evaluation: speed against accuracy, and success rate
//! against each swept condition.

use plotters::coord::Shift;
use plotters::coord::combinators::BindKeyPoints;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::common::{
    Draw, DrawResult, TAB10, anchored, bold, draw_text, draw_title, font, format_significant,
    render_named,
};
use super::{ImageFormat, Layout};
use crate::error::Result;
use crate::evaluate::bench::BenchRow;
use crate::evaluate::stability::{Summary, Sweep};

/// Size of the speed-accuracy chart in pixels.
pub const SPEED_ACCURACY_SIZE: (u32, u32) = (1400, 640);
/// Size of the stability chart in pixels.
pub const STABILITY_SIZE: (u32, u32) = (1400, 900);

pub(super) fn colour(k: usize) -> RGBColor {
    TAB10[k % TAB10.len()]
}

/// Number of distinct method markers (they repeat after this many methods).
pub const MARKER_SHAPES: usize = 9;

/// Draws marker number `shape` (one per method) at `at` on any drawing area: filled
/// circle, filled triangle, ×, filled square, ring, hollow diamond, +, hollow square,
/// hollow downward triangle. Outlines are drawn as paths, so every hollow marker really
/// is hollow (plotters' `TriangleMarker` fills regardless of the style).
fn marker<DB: DrawingBackend, CT: CoordTranslate>(
    area: &DrawingArea<DB, CT>,
    at: CT::From,
    shape: usize,
    c: RGBColor,
) -> DrawResult<(), DB>
where
    CT::From: Clone + 'static,
{
    let s = 7;
    let outline = |points: Vec<(i32, i32)>| {
        let mut closed = points.clone();
        closed.push(points[0]);
        EmptyElement::at(at.clone()) + PathElement::new(closed, c.stroke_width(2))
    };
    match shape % MARKER_SHAPES {
        0 => area.draw(&Circle::new(at, s, c.filled())),
        1 => area.draw(&TriangleMarker::new(at, s + 2, c.filled())),
        2 => area.draw(&Cross::new(at, s, c.stroke_width(3))),
        3 => area.draw(&(EmptyElement::at(at) + Rectangle::new([(-s, -s), (s, s)], c.filled()))),
        4 => area.draw(&Circle::new(at, s, c.stroke_width(2))),
        5 => {
            let d = s + 2;
            area.draw(&outline(vec![(0, -d), (d, 0), (0, d), (-d, 0)]))
        }
        6 => {
            let d = s + 1;
            area.draw(
                &(EmptyElement::at(at)
                    + PathElement::new(vec![(-d, 0), (d, 0)], c.stroke_width(3))
                    + PathElement::new(vec![(0, -d), (0, d)], c.stroke_width(3))),
            )
        }
        7 => area.draw(&outline(vec![(-s, -s), (s, -s), (s, s), (-s, s)])),
        _ => {
            let d = s + 2;
            area.draw(&outline(vec![(-d, -d * 2 / 3), (d, -d * 2 / 3), (0, d)]))
        }
    }
}

/// m·10ⁿ, exactly as the decimal literal (products with powi drift, 6 × 0.1 ≠ 0.6).
fn decimal(m: u32, n: i32) -> f64 {
    format!("{m}e{n}")
        .parse()
        .unwrap_or_else(|_| m as f64 * 10f64.powi(n))
}

/// Labelled ticks of a log axis over [lo, hi]: every decade, and 2 and 5 within each
/// decade when the range spans less than two decades (every integer multiple when even
/// that leaves fewer than three ticks).
pub fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && hi > lo) {
        return Vec::new();
    }
    let inside = |v: &f64| *v >= lo * (1.0 - 1e-12) && *v <= hi * (1.0 + 1e-12);
    let first = lo.log10().floor() as i32;
    let last = hi.log10().ceil() as i32;
    let with = |multiples: &[u32]| -> Vec<f64> {
        (first..=last)
            .flat_map(|n| multiples.iter().map(move |&m| decimal(m, n)))
            .filter(inside)
            .collect()
    };
    let mut ticks = with(&[1]);
    if hi / lo < 100.0 {
        ticks = with(&[1, 2, 5]);
    }
    if ticks.len() < 3 {
        ticks = with(&[1, 2, 3, 4, 5, 6, 7, 8, 9]);
    }
    ticks
}

/// Unlabelled grid lines of a log axis: every integer multiple of each decade in range.
pub(super) fn log_grid(lo: f64, hi: f64) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && hi > lo) {
        return Vec::new();
    }
    let (first, last) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    (first..=last)
        .flat_map(|n| (1..10).map(move |m| decimal(m, n)))
        .filter(|v| *v >= lo && *v <= hi)
        .collect()
}

struct SpeedAccuracy<'a> {
    rows: &'a [BenchRow],
}

/// Renders the speed-accuracy chart: median time per fit (log) against the largest
/// ΔE2000 (left) and the relative fluorescent residual (right), one marker per method,
/// one colour per input, each input's Pareto front as a line.
pub fn speed_accuracy(rows: &[BenchRow], format: ImageFormat) -> Result<Vec<u8>> {
    Ok(render_named(
        &SpeedAccuracy { rows },
        "speed-accuracy",
        SPEED_ACCURACY_SIZE,
        format,
    )?
    .0)
}

pub(super) fn unique(items: impl Iterator<Item = String>) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for i in items {
        if !out.contains(&i) {
            out.push(i);
        }
    }
    out
}

/// Log-axis limits padded around the positive finite values.
pub(super) fn log_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(l, h), v| (l.min(v), h.max(v)));
    if lo.is_finite() && hi > 0.0 {
        (lo / 2.0, hi * 2.0)
    } else {
        (1e-3, 1.0)
    }
}

impl Draw for SpeedAccuracy<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<Layout, DB> {
        let (width, height) = SPEED_ACCURACY_SIZE;
        let inputs = unique(self.rows.iter().map(|r| r.input.clone()));
        let methods = unique(self.rows.iter().map(|r| r.method.clone()));
        draw_title(
            root,
            "Speed against accuracy (median of repeated fits; line: Pareto front per input)",
            (width as i32 / 2, 22),
        )?;
        let legend_w = 250;
        let plot_area = root
            .clone()
            .shrink((0, 44), (width - legend_w, height - 44));
        let panels = plot_area.split_evenly((1, 2));
        let (t_lo, t_hi) = log_range(self.rows.iter().map(|r| r.median_ms));
        type Metric = fn(&BenchRow) -> f64;
        let metrics: [(&str, Metric); 2] = [
            ("largest ΔE2000 over D65, A, F11, UV (log)", |r| {
                r.max_delta_e
            }),
            ("relative residual of the fluorescent cells (log)", |r| {
                r.rel_residual
            }),
        ];
        for (panel, (label, metric)) in panels.iter().zip(metrics) {
            let (e_lo, e_hi) = log_range(self.rows.iter().map(metric));
            let mut chart = ChartBuilder::on(panel)
                .margin(14)
                .x_label_area_size(50)
                .y_label_area_size(80)
                .build_cartesian_2d(
                    (t_lo..t_hi).log_scale(),
                    (e_lo..e_hi)
                        .log_scale()
                        .with_key_points(log_ticks(e_lo, e_hi))
                        .with_light_points(log_grid(e_lo, e_hi)),
                )?;
            chart
                .configure_mesh()
                .light_line_style(RGBColor(235, 235, 235))
                .bold_line_style(RGBColor(215, 215, 215))
                .x_desc("median time per fit (ms, log)")
                .y_desc(label)
                .x_label_formatter(&|v| format_significant(*v, 2))
                .y_label_formatter(&|v| format_significant(*v, 2))
                .label_style(font(14.0))
                .axis_desc_style(font(15.0))
                .draw()?;
            for (k, input) in inputs.iter().enumerate() {
                let c = colour(k);
                // The Pareto front of this metric: sorted by time, keep each point that
                // lowers the error.
                let mut pts: Vec<(f64, f64)> = self
                    .rows
                    .iter()
                    .filter(|r| &r.input == input)
                    .map(|r| (r.median_ms, metric(r)))
                    .filter(|p| p.0 > 0.0 && p.1 > 0.0 && p.1.is_finite())
                    .collect();
                pts.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
                let mut front = Vec::new();
                let mut best = f64::INFINITY;
                for p in pts {
                    if p.1 < best {
                        best = p.1;
                        front.push(p);
                    }
                }
                chart.draw_series(LineSeries::new(front, c.mix(0.6).stroke_width(2)))?;
                for r in self.rows.iter().filter(|r| &r.input == input) {
                    let e = metric(r);
                    if r.median_ms > 0.0 && e > 0.0 && e.is_finite() {
                        let shape = methods.iter().position(|m| m == &r.method).unwrap_or(0);
                        marker(chart.plotting_area(), (r.median_ms, e), shape, c)?;
                    }
                }
            }
        }
        // Legend: methods (marker shape), inputs (colour).
        let legend = root
            .clone()
            .shrink(((width - legend_w) as i32, 60), (legend_w, height - 60));
        let mut y = 10;
        legend_text(&legend, "method", true, y)?;
        for (k, m) in methods.iter().enumerate() {
            y += 24;
            marker(&legend, (20, y), k, RGBColor(60, 60, 60))?;
            legend_text(&legend, m, false, y)?;
        }
        y += 36;
        legend_text(&legend, "input", true, y)?;
        for (k, input) in inputs.iter().enumerate() {
            y += 22;
            legend.draw(&Rectangle::new(
                [(12, y - 7), (28, y + 7)],
                colour(k).filled(),
            ))?;
            legend_text(&legend, input, false, y)?;
        }
        Ok(Layout::default())
    }
}

/// A legend's text at height `y`: a heading (bold, from the left edge) or an entry
/// (beside its marker).
fn legend_text<DB: DrawingBackend>(
    legend: &DrawingArea<DB, Shift>,
    text: &str,
    heading: bool,
    y: i32,
) -> DrawResult<(), DB> {
    let (style, x) = if heading {
        (bold(15.0), 10)
    } else {
        (font(14.0), 38)
    };
    draw_text(
        legend,
        text,
        (x, y),
        &anchored(style, HPos::Left, VPos::Center),
    )
}

struct Stability<'a> {
    summaries: &'a [Summary],
    sweeps: &'a [Sweep],
}

/// Renders the stability chart: success rate against each swept variable, one panel per
/// sweep, one line per method.
pub fn stability(summaries: &[Summary], sweeps: &[Sweep], format: ImageFormat) -> Result<Vec<u8>> {
    Ok(render_named(
        &Stability { summaries, sweeps },
        "stability",
        STABILITY_SIZE,
        format,
    )?
    .0)
}

impl Draw for Stability<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<Layout, DB> {
        let (width, height) = STABILITY_SIZE;
        let methods = unique(self.summaries.iter().map(|s| s.method.clone()));
        draw_title(
            root,
            "Success rate (truth recovered within 10 % and ΔE2000 ≤ 1) against each condition",
            (width as i32 / 2, 22),
        )?;
        // Legend line under the title.
        let mut x = 120;
        for (k, m) in methods.iter().enumerate() {
            root.draw(&PathElement::new(
                vec![(x, 56), (x + 30, 56)],
                colour(k).stroke_width(3),
            ))?;
            draw_text(
                root,
                m,
                (x + 38, 56),
                &anchored(font(15.0), HPos::Left, VPos::Center),
            )?;
            x += 60 + 9 * m.chars().count() as i32;
        }
        let area = root.clone().shrink((0, 72), (width, height - 72));
        let cols = 4;
        let rows = self.sweeps.len().div_ceil(cols).max(1);
        let panels = area.split_evenly((rows, cols));
        for (panel, &sweep) in panels.iter().zip(self.sweeps) {
            let values = sweep.values();
            let labels: Vec<String> = values.iter().map(|v| sweep.label(*v)).collect();
            let n = values.len().max(1) as f64;
            let mut chart = ChartBuilder::on(panel)
                .margin(10)
                .caption(sweep.variable(), font(16.0))
                .x_label_area_size(36)
                .y_label_area_size(46)
                .build_cartesian_2d(-0.3..(n - 0.7), -0.05..1.05)?;
            let formatter = |v: &f64| {
                let k = v.round();
                if (v - k).abs() < 1e-6 && k >= 0.0 {
                    labels.get(k as usize).cloned().unwrap_or_default()
                } else {
                    String::new()
                }
            };
            chart
                .configure_mesh()
                .light_line_style(RGBColor(240, 240, 240))
                .bold_line_style(RGBColor(220, 220, 220))
                .x_labels(values.len() * 4 + 1)
                .x_label_formatter(&formatter)
                .y_labels(6)
                .y_label_formatter(&|v| format!("{:.0} %", 100.0 * v))
                .label_style(font(12.0))
                .draw()?;
            for (k, method) in methods.iter().enumerate() {
                let pts: Vec<(f64, f64)> = values
                    .iter()
                    .enumerate()
                    .filter_map(|(i, v)| {
                        self.summaries
                            .iter()
                            .find(|s| s.sweep == sweep && s.value == *v && &s.method == method)
                            .map(|s| (i as f64, s.success_rate))
                    })
                    .collect();
                // Offset lines slightly so equal rates stay visible.
                let dy = (k as f64 - 1.5) * 0.008;
                let pts: Vec<(f64, f64)> = pts.into_iter().map(|(x, y)| (x, y + dy)).collect();
                chart.draw_series(LineSeries::new(pts.clone(), colour(k).stroke_width(2)))?;
                chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, colour(k).filled())))?;
            }
        }
        Ok(Layout::default())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pixels marker `shape` paints, as offsets from its centre.
    fn footprint(shape: usize) -> Vec<(i32, i32)> {
        let size = 41u32;
        let mut buffer = vec![255u8; (size * size * 3) as usize];
        {
            let root = BitMapBackend::with_buffer(&mut buffer, (size, size)).into_drawing_area();
            marker(&root, (20, 20), shape, RGBColor(0, 0, 0)).unwrap();
            root.present().unwrap();
        }
        buffer
            .chunks(3)
            .enumerate()
            .filter(|(_, p)| p != &[255, 255, 255])
            .map(|(k, _)| (k as i32 % size as i32 - 20, k as i32 / size as i32 - 20))
            .collect()
    }

    #[test]
    fn every_method_marker_has_its_own_shape() {
        let prints: Vec<Vec<(i32, i32)>> = (0..MARKER_SHAPES).map(footprint).collect();
        for (a, pa) in prints.iter().enumerate() {
            assert!(pa.len() > 10, "marker {a} paints only {} pixels", pa.len());
            for (b, pb) in prints.iter().enumerate().skip(a + 1) {
                let differ = pa.iter().filter(|p| !pb.contains(p)).count()
                    + pb.iter().filter(|p| !pa.contains(p)).count();
                assert!(
                    differ >= 15,
                    "markers {a} and {b} differ in {differ} pixels"
                );
            }
        }
        // The hollow ones leave their centre white; the filled ones cover it.
        for (shape, filled) in [(0, true), (1, true), (3, true), (4, false), (5, false)] {
            assert_eq!(prints[shape].contains(&(0, 0)), filled, "marker {shape}");
        }
        for shape in [7, 8] {
            assert!(!prints[shape].contains(&(0, 0)), "marker {shape}");
        }
        // lbfgs (the 2nd method) and nelder-mead (the 6th) of the benchmark's list.
        let methods: Vec<String> = crate::evaluate::all_methods()
            .into_iter()
            .map(|m| m.name)
            .collect();
        let lbfgs = methods.iter().position(|m| m == "lbfgs").unwrap();
        let nelder = methods.iter().position(|m| m == "nelder-mead").unwrap();
        assert_ne!(lbfgs % MARKER_SHAPES, nelder % MARKER_SHAPES);
        assert!(methods.len() <= MARKER_SHAPES);
    }

    #[test]
    fn log_ticks_label_decades_and_fill_in_short_ranges() {
        assert_eq!(log_ticks(3e-4, 40.0), vec![1e-3, 1e-2, 0.1, 1.0, 10.0]);
        assert_eq!(log_ticks(0.3, 20.0), vec![0.5, 1.0, 2.0, 5.0, 10.0, 20.0]);
        assert_eq!(log_ticks(0.011, 0.9), vec![0.02, 0.05, 0.1, 0.2, 0.5]);
        assert_eq!(log_ticks(0.52, 0.95), vec![0.6, 0.7, 0.8, 0.9]);
        assert!(log_ticks(0.0, 1.0).is_empty());
        assert!(log_ticks(f64::NAN, 1.0).is_empty());
        let grid = log_grid(0.05, 0.5);
        assert_eq!(grid.first(), Some(&0.05));
        assert_eq!(grid.len(), 10);
    }
}
