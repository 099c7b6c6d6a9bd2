//! The figure of a joint EEM fit: every component's excitation (absorption) and
//! emission loadings, and the scores of every sample.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::common::TAB10;
use super::common::{Draw, DrawResult, anchored, bold, draw_text, font, render_named};
use super::{ImageFormat, Layout};
use crate::error::Result;
use crate::fit::joint::JointFit;

/// Size of the components figure in pixels.
pub const SIZE: (u32, u32) = (1500, 560);

const TITLE_HEIGHT: i32 = 50;

struct Components<'a> {
    fit: &'a JointFit,
}

/// Renders the components figure (excitation, emission, scores) as PNG or SVG bytes.
pub fn components(fit: &JointFit, format: ImageFormat) -> Result<Vec<u8>> {
    Ok(render_named(&Components { fit }, "components", SIZE, format)?.0)
}

fn colour(c: usize) -> RGBColor {
    TAB10[c % TAB10.len()]
}

impl Draw for Components<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<Layout, DB> {
        let fit = self.fit;
        let (width, height) = SIZE;
        draw_text(
            root,
            &format!(
                "Joint fit of {} samples, {} components: explained {:.2} %, core consistency {:.1} %",
                fit.samples.len(),
                fit.components.len(),
                100.0 * fit.explained_variance,
                fit.core_consistency
            ),
            (width as i32 / 2, TITLE_HEIGHT / 2),
            &anchored(bold(21.0), HPos::Center, VPos::Center),
        )?;
        let area = root.clone().shrink(
            (0, TITLE_HEIGHT),
            (width, (height as i32 - TITLE_HEIGHT) as u32),
        );
        let panels = area.split_evenly((1, 3));
        let spectra = |panel: &DrawingArea<DB, Shift>,
                       title: &str,
                       pick: &dyn Fn(usize) -> (Vec<f64>, Vec<f64>)|
         -> DrawResult<(), DB> {
            let curves: Vec<(Vec<f64>, Vec<f64>)> = (0..fit.components.len()).map(pick).collect();
            let lo = curves.iter().map(|c| c.0[0]).fold(f64::INFINITY, f64::min);
            let hi = curves
                .iter()
                .map(|c| c.0[c.0.len() - 1])
                .fold(f64::NEG_INFINITY, f64::max);
            let top = curves
                .iter()
                .flat_map(|c| c.1.iter().copied())
                .fold(0.0, f64::max)
                .max(f64::MIN_POSITIVE);
            let mut chart = ChartBuilder::on(panel)
                .caption(title, font(17.0))
                .margin(12)
                .x_label_area_size(45)
                .y_label_area_size(60)
                .build_cartesian_2d(lo..hi, 0.0..top * 1.05)?;
            chart
                .configure_mesh()
                .light_line_style(RGBColor(235, 235, 235))
                .bold_line_style(RGBColor(215, 215, 215))
                .x_desc("wavelength (nm)")
                .label_style(font(14.0))
                .axis_desc_style(font(15.0))
                .draw()?;
            for (c, (x, y)) in curves.iter().enumerate() {
                chart
                    .draw_series(LineSeries::new(
                        x.iter().copied().zip(y.iter().copied()),
                        colour(c).stroke_width(3),
                    ))?
                    .label(format!("C{}", c + 1))
                    .legend(move |(px, py)| {
                        PathElement::new(vec![(px, py), (px + 20, py)], colour(c).stroke_width(3))
                    });
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(RGBColor(200, 200, 200))
                .label_font(font(14.0))
                .position(SeriesLabelPosition::UpperRight)
                .draw()?;
            Ok(())
        };
        spectra(&panels[0], "excitation (absorption) a(λ), max 1", &|c| {
            let s = &fit.components[c].absorption;
            (s.wavelength_nm.clone(), s.value.clone())
        })?;
        spectra(&panels[1], "emission e(λ), ∫e dλ = 1", &|c| {
            let s = &fit.components[c].emission;
            (s.wavelength_nm.clone(), s.value.clone())
        })?;
        // Scores: one marker per sample and component, samples in input order.
        let n = fit.samples.len();
        let top = fit
            .scores
            .iter()
            .flat_map(|r| r.iter().copied())
            .fold(0.0, f64::max)
            .max(f64::MIN_POSITIVE);
        let mut chart = ChartBuilder::on(&panels[2])
            .caption("scores per sample", font(17.0))
            .margin(12)
            .x_label_area_size(60)
            .y_label_area_size(70)
            .build_cartesian_2d(-0.5..n as f64 - 0.5, 0.0..top * 1.05)?;
        let names = fit.samples.clone();
        chart
            .configure_mesh()
            .light_line_style(RGBColor(235, 235, 235))
            .bold_line_style(RGBColor(215, 215, 215))
            .x_labels(n.min(12))
            .x_label_formatter(&|v| {
                let i = v.round();
                if (v - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < names.len() {
                    names[i as usize].clone()
                } else {
                    String::new()
                }
            })
            .y_label_formatter(&|v| format!("{v:.1e}"))
            .label_style(font(12.0))
            .axis_desc_style(font(15.0))
            .draw()?;
        for c in 0..fit.components.len() {
            chart.draw_series(
                fit.scores
                    .iter()
                    .enumerate()
                    .map(|(s, row)| Circle::new((s as f64, row[c]), 5, colour(c).filled())),
            )?;
        }
        Ok(Layout::default())
    }
}
