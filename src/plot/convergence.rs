//! The convergence figure: the fit's objective per solver iteration, from the cost
//! history kept in the material's `fit` block.

use plotters::coord::Shift;
use plotters::coord::ranged1d::ValueFormatter;
use plotters::coord::types::{RangedCoordf64, RangedCoordi32};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::common::{
    Draw, DrawResult, TAB10, anchored, draw_text, draw_title, font, format_significant,
    render as render_figure,
};
use super::{FigureKind, ImageFormat, Layout};
use crate::error::Result;
use crate::material::{FitReport, Material};

/// Size of the convergence figure in pixels.
pub const SIZE: (u32, u32) = (900, 500);

const TITLE_HEIGHT: i32 = 44;
const LINE_COLOUR: RGBColor = TAB10[0];
/// Most cost-axis labels (plotters' hint; it picks 1-2-5 steps giving at most this many).
const Y_LABELS: usize = 8;
/// Fewest significant digits of a cost label.
const MIN_DIGITS: usize = 2;

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

/// The cost axis: its range and whether it is logarithmic.
#[derive(Debug, Clone, Copy, PartialEq)]
enum CostAxis {
    Linear(f64, f64),
    Log(f64, f64),
}

impl CostAxis {
    /// The axis for the finite costs of `points` (iteration, cost): logarithmic when
    /// [`wants_log_axis`], else linear with 5 % padding (±10 % of the value when flat).
    fn of(points: &[(i32, f64)]) -> CostAxis {
        let costs: Vec<f64> = points.iter().map(|p| p.1).collect();
        let min = costs.iter().copied().fold(f64::INFINITY, f64::min);
        let max = costs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if wants_log_axis(&costs) {
            return CostAxis::Log(min * 0.8, max * 1.25);
        }
        if min.is_finite() && max > min {
            let pad = 0.05 * (max - min);
            CostAxis::Linear(min - pad, max + pad)
        } else if min.is_finite() {
            let pad = min.abs().max(1e-12) * 0.1;
            CostAxis::Linear(min - pad, min + pad)
        } else {
            CostAxis::Linear(0.0, 1.0)
        }
    }

    /// The tick values plotters labels on this axis.
    fn ticks(&self) -> Vec<f64> {
        match *self {
            CostAxis::Linear(lo, hi) => RangedCoordf64::from(lo..hi).key_points(Y_LABELS),
            CostAxis::Log(lo, hi) => {
                let axis: LogCoord<f64> = (lo..hi).log_scale().into();
                axis.key_points(Y_LABELS)
            }
        }
    }

    /// Significant digits that give every tick its own label: a cost that barely moves
    /// (1.2000e-3 to 1.2004e-3) needs more than the two that name a falling one.
    fn label_digits(&self) -> usize {
        distinct_digits(&self.ticks())
    }

    /// The tick labels, as drawn.
    fn labels(&self) -> Vec<String> {
        let digits = self.label_digits();
        self.ticks()
            .iter()
            .map(|v| format_significant(*v, digits))
            .collect()
    }
}

/// The fewest significant digits (at least [`MIN_DIGITS`]) at which [`format_significant`]
/// writes each of `values` differently; 17 (every f64 its own text) when none fewer do.
fn distinct_digits(values: &[f64]) -> usize {
    (MIN_DIGITS..17)
        .find(|&digits| {
            let labels: Vec<String> = values
                .iter()
                .map(|v| format_significant(*v, digits))
                .collect();
            labels
                .iter()
                .enumerate()
                .all(|(i, l)| !labels[..i].contains(l))
        })
        .unwrap_or(17)
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
        let area = root.clone().shrink(
            (0, TITLE_HEIGHT),
            (width, (height as i32 - TITLE_HEIGHT) as u32),
        );
        let axis = CostAxis::of(&points);
        let digits = axis.label_digits();
        let longest = axis
            .labels()
            .iter()
            .map(|l| l.chars().count())
            .max()
            .unwrap_or(0);
        let mut builder = ChartBuilder::on(&area);
        builder
            .margin(14)
            .margin_right(30)
            .x_label_area_size(50)
            // Room for the longest tick label (≈ 9 px a character at 15 px) and the axis title.
            .y_label_area_size((45 + 9 * longest as u32).max(90));
        let x_labels = (x_hi as usize + 1).min(10);
        let y_desc = "cost (fit objective)";
        let y_label = |v: &f64| format_significant(*v, digits);
        match axis {
            CostAxis::Log(lo, hi) => {
                let mut chart = builder.build_cartesian_2d(0..x_hi, (lo..hi).log_scale())?;
                draw_costs(
                    &mut chart,
                    &points,
                    x_labels,
                    &format!("{y_desc}, log scale"),
                    &y_label,
                )?;
            }
            CostAxis::Linear(lo, hi) => {
                let mut chart = builder.build_cartesian_2d(0..x_hi, lo..hi)?;
                draw_costs(&mut chart, &points, x_labels, y_desc, &y_label)?;
            }
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
        .y_labels(Y_LABELS)
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

#[cfg(test)]
mod tests {
    use super::*;

    fn labels_of(costs: &[f64]) -> (CostAxis, Vec<String>) {
        let points: Vec<(i32, f64)> = costs
            .iter()
            .enumerate()
            .map(|(n, &c)| (n as i32, c))
            .collect();
        let axis = CostAxis::of(&points);
        (axis, axis.labels())
    }

    fn assert_distinct(labels: &[String]) {
        assert!(labels.len() >= 2, "too few ticks: {labels:?}");
        for (i, label) in labels.iter().enumerate() {
            assert!(
                !labels[..i].contains(label),
                "label {label} repeats: {labels:?}"
            );
        }
    }

    #[test]
    fn a_nearly_flat_cost_gets_distinct_labels_that_name_the_ticks() {
        // A fit polishing its last digits: 1.2e-3 changing by 4 parts in a million. Two
        // significant digits would print "1.2e-3" on every tick.
        let costs: Vec<f64> = (0..12)
            .map(|n| 1.2e-3 * (1.0 + 4e-6 * (-(n as f64) / 3.0).exp()))
            .collect();
        let (axis, labels) = labels_of(&costs);
        assert!(matches!(axis, CostAxis::Linear(..)), "{axis:?}");
        assert_distinct(&labels);
        // Each label reads back as its tick to within half a tick step.
        let ticks = axis.ticks();
        let step = ticks[1] - ticks[0];
        for (tick, label) in ticks.iter().zip(&labels) {
            let read: f64 = label.parse().unwrap();
            assert!((read - tick).abs() <= 0.5 * step, "{label} for {tick}");
        }
    }

    #[test]
    fn flat_and_falling_costs_get_distinct_labels_on_either_axis() {
        for costs in [
            vec![0.5; 6],
            vec![3.0, 3.0 - 1e-9, 3.0 - 2e-9],
            vec![1e4, 1e4 + 0.01, 1e4 + 0.02],
            vec![2.0, 0.9, 0.4, 0.2, 0.11, 0.1, 0.0999],
            vec![1.0, 0.5, 0.06, 1.01e-2, 1.0e-2],
        ] {
            let (_, labels) = labels_of(&costs);
            assert_distinct(&labels);
        }
        // A wide descent keeps the short two-digit labels.
        let (axis, labels) = labels_of(&[2.0, 0.9, 0.4, 0.2, 0.11, 0.1, 0.0999]);
        assert!(matches!(axis, CostAxis::Log(..)) || labels.iter().all(|l| l.len() <= 4));
    }
}
