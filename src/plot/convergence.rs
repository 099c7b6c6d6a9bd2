//! The convergence figure: the fit's objective per solver iteration, from the cost
//! history kept in the material's `fit` block.

use plotters::coord::Shift;
use plotters::coord::ranged1d::ValueFormatter;
use plotters::coord::types::RangedCoordi32;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::common::{
    Draw, DrawResult, TAB10, anchored, draw_text, draw_title, font, format_significant,
    format_tick, render as render_figure, tick_step,
};
use super::{FigureKind, ImageFormat, Layout};
use crate::error::Result;
use crate::material::{FitReport, Material};

/// Size of the convergence figure in pixels.
pub const SIZE: (u32, u32) = (900, 500);

const TITLE_HEIGHT: i32 = 44;
const LINE_COLOUR: RGBColor = TAB10[0];

struct ConvergenceFigure<'a> {
    material: &'a Material,
    fit: &'a FitReport,
}

/// Renders the convergence figure.
pub(crate) fn render(
    material: &Material,
    fit: &FitReport,
    format: ImageFormat,
) -> Result<(Vec<u8>, Layout)> {
    render_figure(
        &ConvergenceFigure { material, fit },
        FigureKind::Convergence,
        format,
    )
}

/// True when the costs are positive and span more than a factor of 20, so a logarithmic
/// axis shows the whole descent.
pub fn wants_log_axis(costs: &[f64]) -> bool {
    let finite: Vec<f64> = costs.iter().copied().filter(|c| c.is_finite()).collect();
    let min = finite.iter().copied().fold(f64::INFINITY, f64::min);
    let max = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    min > 0.0 && max / min > 20.0
}

impl Draw for ConvergenceFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<Layout, DB> {
        let fit = self.fit;
        let (width, height) = SIZE;
        let solver = if fit.solver.is_empty() {
            "solver"
        } else {
            fit.solver.as_str()
        };
        let status = if fit.converged {
            "converged"
        } else {
            "not converged"
        };
        // Hand-written fit blocks may omit the count; the history has one cost per step.
        let iterations = if fit.iterations > 0 {
            fit.iterations
        } else {
            fit.cost_history.len().saturating_sub(1) as u64
        };
        draw_title(
            root,
            &format!(
                "{}: convergence of {solver} ({iterations} iterations, {status})",
                self.material.name
            ),
            (width as i32 / 2, TITLE_HEIGHT / 2 + 2),
        )?;
        let points: Vec<(i32, f64)> = fit
            .cost_history
            .iter()
            .enumerate()
            .filter(|(_, c)| c.is_finite())
            .map(|(n, &c)| (n as i32, c))
            .collect();
        let last = points.last().map(|p| p.1).unwrap_or(f64::NAN);
        // An integer axis keeps iteration ticks whole.
        let x_hi = (fit.cost_history.len() as i32 - 1).max(1);
        let min = points.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
        let max = points.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
        let area = root.clone().shrink(
            (0, TITLE_HEIGHT),
            (width, (height as i32 - TITLE_HEIGHT) as u32),
        );
        let mut builder = ChartBuilder::on(&area);
        builder
            .margin(14)
            .margin_right(30)
            .x_label_area_size(50)
            .y_label_area_size(90);
        let x_labels = (x_hi as usize + 1).min(10);
        let y_desc = "cost (fit objective)";
        if wants_log_axis(&fit.cost_history) {
            let mut chart =
                builder.build_cartesian_2d(0..x_hi, (min * 0.8..max * 1.25).log_scale())?;
            draw_costs(
                &mut chart,
                &points,
                x_labels,
                &format!("{y_desc}, log scale"),
                &|v| format_significant(*v, 2),
            )?;
        } else {
            let (lo, hi) = if min.is_finite() && max > min {
                let pad = 0.05 * (max - min);
                (min - pad, max + pad)
            } else if min.is_finite() {
                (
                    min - min.abs().max(1e-12) * 0.1,
                    min + min.abs().max(1e-12) * 0.1,
                )
            } else {
                (0.0, 1.0)
            };
            let step_y = tick_step(lo, hi, 7);
            let mut chart = builder.build_cartesian_2d(0..x_hi, lo..hi)?;
            draw_costs(&mut chart, &points, x_labels, y_desc, &|v| {
                format_tick(*v, step_y)
            })?;
        }
        draw_text(
            root,
            &format!(
                "final cost {}   (first {})",
                format_significant(last, 4),
                format_significant(points.first().map(|p| p.1).unwrap_or(f64::NAN), 4)
            ),
            (width as i32 - 40, TITLE_HEIGHT + 34),
            &anchored(font(15.0), HPos::Right, VPos::Center),
        )?;
        Ok(Layout::default())
    }
}

/// Draws the grid, the axes and the cost per iteration (line and points) on `chart`, whose
/// cost axis is linear or logarithmic.
fn draw_costs<DB: DrawingBackend, Y>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<RangedCoordi32, Y>>,
    points: &[(i32, f64)],
    x_labels: usize,
    y_desc: &str,
    y_label: &dyn Fn(&f64) -> String,
) -> DrawResult<(), DB>
where
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    chart
        .configure_mesh()
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(215, 215, 215))
        .x_labels(x_labels)
        .y_labels(8)
        .y_label_formatter(y_label)
        .x_desc("iteration")
        .y_desc(y_desc)
        .label_style(font(15.0))
        .axis_desc_style(font(16.0))
        .draw()?;
    chart.draw_series(LineSeries::new(
        points.iter().copied(),
        LINE_COLOUR.stroke_width(3),
    ))?;
    chart.draw_series(
        points
            .iter()
            .map(|&p| Circle::new(p, 3, LINE_COLOUR.filled())),
    )?;
    Ok(())
}
