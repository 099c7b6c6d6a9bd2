//! Charts of the method evaluation (issue 6): speed against accuracy, and success rate
//! against each swept condition.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::common::{
    Draw, DrawResult, anchored, bold, draw_text, font, format_significant, render_named,
};
use super::{ImageFormat, Layout};
use crate::error::Result;
use crate::evaluate::bench::BenchRow;
use crate::evaluate::stability::{Summary, Sweep};

/// Size of the speed-accuracy chart in pixels.
pub const SPEED_ACCURACY_SIZE: (u32, u32) = (1400, 640);
/// Size of the stability chart in pixels.
pub const STABILITY_SIZE: (u32, u32) = (1400, 900);

const PALETTE: [RGBColor; 10] = [
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

fn colour(k: usize) -> RGBColor {
    PALETTE[k % PALETTE.len()]
}

/// Draws marker number `shape` (one per method) at `at` on any drawing area.
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
    match shape % 7 {
        0 => area.draw(&Circle::new(at, s, c.filled())),
        1 => area.draw(&TriangleMarker::new(at, s + 2, c.filled())),
        2 => area.draw(&Cross::new(at, s, c.stroke_width(3))),
        3 => area.draw(&(EmptyElement::at(at) + Rectangle::new([(-s, -s), (s, s)], c.filled()))),
        4 => area.draw(&Circle::new(at, s, c.stroke_width(2))),
        5 => area.draw(&TriangleMarker::new(at, s + 2, c.stroke_width(2))),
        _ => area
            .draw(&(EmptyElement::at(at) + Rectangle::new([(-s, -s), (s, s)], c.stroke_width(2)))),
    }
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

fn unique(items: impl Iterator<Item = String>) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for i in items {
        if !out.contains(&i) {
            out.push(i);
        }
    }
    out
}

/// Log-axis limits padded around the positive finite values.
fn log_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
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
        draw_text(
            root,
            "Speed against accuracy (median of repeated fits; line: Pareto front per input)",
            (width as i32 / 2, 22),
            &anchored(bold(21.0), HPos::Center, VPos::Center),
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
                .build_cartesian_2d((t_lo..t_hi).log_scale(), (e_lo..e_hi).log_scale())?;
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
        draw_text(
            &legend,
            "method",
            (10, y),
            &anchored(bold(15.0), HPos::Left, VPos::Center),
        )?;
        for (k, m) in methods.iter().enumerate() {
            y += 24;
            marker(&legend, (20, y), k, RGBColor(60, 60, 60))?;
            draw_text(
                &legend,
                m,
                (38, y),
                &anchored(font(14.0), HPos::Left, VPos::Center),
            )?;
        }
        y += 36;
        draw_text(
            &legend,
            "input",
            (10, y),
            &anchored(bold(15.0), HPos::Left, VPos::Center),
        )?;
        for (k, input) in inputs.iter().enumerate() {
            y += 22;
            legend.draw(&Rectangle::new(
                [(12, y - 7), (28, y + 7)],
                colour(k).filled(),
            ))?;
            draw_text(
                &legend,
                input,
                (38, y),
                &anchored(font(14.0), HPos::Left, VPos::Center),
            )?;
        }
        Ok(Layout::default())
    }
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
        draw_text(
            root,
            "Success rate (truth recovered within 10 % and ΔE2000 ≤ 1) against each condition",
            (width as i32 / 2, 22),
            &anchored(bold(21.0), HPos::Center, VPos::Center),
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
