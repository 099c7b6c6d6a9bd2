//! The spectra figure: fitted absorption a(λ), emission e(λ) (scaled to peak 1),
//! reflectance r(λ) and diagonal d(λ) = (1 − c·a)·r, with the measured diagonal as points
//! and the data's own excitation and emission profiles, so a user sees whether the shapes
//! agree.
//!
//! The data profiles are row and column sums of the measured Stokes cells (outside the
//! guard band), each divided by the same sum over the fitted matrix and multiplied by the
//! fitted curve. A Stokes row holds only part of the emission band, so a plain row sum
//! would shrink where the band is cut; this ratio cancels that coverage. Where the data
//! follow the model the points lie on the curves.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::common::{
    Draw, DrawResult, anchored, bold, draw_text, font, format_significant, format_tick,
    render as render_figure, tick_step,
};
use super::{Comparison, FigureKind, ImageFormat, Layout};
use crate::error::Result;
use crate::material::Material;
use crate::measurement::CellKind;

/// Size of the spectra figure in pixels.
pub const SIZE: (u32, u32) = (1000, 560);

const TITLE_HEIGHT: i32 = 44;
const CHART_WIDTH: i32 = 680;

/// Colours of absorption and emission per fluorophore (cycled).
const FLUOROPHORE_COLOURS: [(RGBColor, RGBColor); 2] = [
    (RGBColor(31, 119, 180), RGBColor(214, 39, 40)),
    (RGBColor(148, 103, 189), RGBColor(255, 127, 14)),
];
const REFLECTANCE_COLOUR: RGBColor = RGBColor(44, 160, 44);
const DIAGONAL_COLOUR: RGBColor = RGBColor(70, 70, 70);

/// Rows whose fitted sum is below this fraction of the largest row are left out of the
/// profiles: there the ratio is noise over noise.
const PROFILE_MIN_SIGNAL: f64 = 0.03;

/// The data's excitation and emission profiles, on the scale of the plotted curves.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Profiles {
    /// (excitation nm, value) per usable row.
    pub excitation: Vec<(f64, f64)>,
    /// (emission nm, value) per usable column.
    pub emission: Vec<(f64, f64)>,
}

/// The combined excitation shape Σ k·a(λ), scaled to peak 1 on the excitation grid (a(λ)
/// itself for one fluorophore). None when the material does not fluoresce.
fn excitation_reference(material: &Material, grid: &[f64]) -> Option<Vec<f64>> {
    let v: Vec<f64> = grid
        .iter()
        .map(|&l| {
            material
                .fluorophores
                .iter()
                .map(|f| f.k() * f.absorption.eval_zero_outside(l))
                .sum()
        })
        .collect();
    normalise(v)
}

/// The combined emission shape Σ k·(Σa)·e(λ), scaled to peak 1 on the emission grid
/// (e(λ)/max e for one fluorophore).
fn emission_reference(material: &Material, ex_grid: &[f64], em_grid: &[f64]) -> Option<Vec<f64>> {
    let weights: Vec<f64> = material
        .fluorophores
        .iter()
        .map(|f| {
            f.k()
                * ex_grid
                    .iter()
                    .map(|&l| f.absorption.eval_zero_outside(l))
                    .sum::<f64>()
        })
        .collect();
    let v: Vec<f64> = em_grid
        .iter()
        .map(|&l| {
            material
                .fluorophores
                .iter()
                .zip(&weights)
                .map(|(f, w)| w * f.emission.eval_zero_outside(l))
                .sum()
        })
        .collect();
    normalise(v)
}

fn normalise(v: Vec<f64>) -> Option<Vec<f64>> {
    let max = v.iter().cloned().fold(0.0, f64::max);
    (max > 0.0 && max.is_finite()).then(|| v.into_iter().map(|x| x / max).collect())
}

/// The data's excitation and emission profiles (see the module doc).
pub fn data_profiles(material: &Material, c: &Comparison) -> Profiles {
    let m = &c.measured;
    let (n_ex, n_em) = (m.n_excitation(), m.n_emission());
    let (Some(ex_ref), Some(em_ref)) = (
        excitation_reference(material, &m.excitation_nm),
        emission_reference(material, &m.excitation_nm, &m.emission_nm),
    ) else {
        return Profiles::default();
    };
    let mut row_sums = vec![(0.0, 0.0); n_ex];
    let mut column_sums = vec![(0.0, 0.0); n_em];
    for (i, row) in row_sums.iter_mut().enumerate() {
        for (j, column) in column_sums.iter_mut().enumerate() {
            if c.kind(i, j) == CellKind::Stokes {
                let (measured, fitted) = (m.get(i, j), c.fitted.get(i, j));
                row.0 += measured;
                row.1 += fitted;
                column.0 += measured;
                column.1 += fitted;
            }
        }
    }
    let profile = |sums: &[(f64, f64)], grid: &[f64], reference: &[f64]| {
        let largest = sums.iter().map(|s| s.1).fold(0.0, f64::max);
        sums.iter()
            .zip(grid)
            .zip(reference)
            .filter(|((s, _), _)| largest > 0.0 && s.1 > PROFILE_MIN_SIGNAL * largest)
            .map(|((s, &l), r)| (l, r * s.0 / s.1))
            .filter(|(_, v)| v.is_finite())
            .collect::<Vec<_>>()
    };
    Profiles {
        excitation: profile(&row_sums, &m.excitation_nm, &ex_ref),
        emission: profile(&column_sums, &m.emission_nm, &em_ref),
    }
}

struct SpectraFigure<'a> {
    material: &'a Material,
    comparison: Option<&'a Comparison>,
}

/// Renders the spectra figure.
pub(crate) fn render(
    material: &Material,
    comparison: Option<&Comparison>,
    format: ImageFormat,
) -> Result<(Vec<u8>, Layout)> {
    render_figure(
        &SpectraFigure {
            material,
            comparison,
        },
        FigureKind::Spectra,
        SIZE,
        format,
    )
}

/// What a legend entry's sample looks like.
enum Glyph {
    Line(RGBColor),
    Dashed(RGBColor),
    Dot(RGBColor),
    Ring(RGBColor),
    Triangle(RGBColor),
}

impl Draw for SpectraFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<Layout, DB> {
        let material = self.material;
        let (width, height) = SIZE;
        let title = match self.comparison {
            Some(c) if c.measured.name != material.name => {
                format!(
                    "{}: fitted spectra vs data {}",
                    material.name, c.measured.name
                )
            }
            Some(_) => format!("{}: fitted spectra vs measured data", material.name),
            None => format!("{}: fitted spectra", material.name),
        };
        draw_text(
            root,
            &title,
            (width as i32 / 2, TITLE_HEIGHT / 2 + 2),
            &anchored(bold(21.0), HPos::Center, VPos::Center),
        )?;

        // Curves, in plot coordinates.
        let mut legend: Vec<(Glyph, String)> = Vec::new();
        let mut lines: Vec<(Vec<(f64, f64)>, Glyph)> = Vec::new();
        let several = material.fluorophores.len() > 1;
        for (n, f) in material.fluorophores.iter().enumerate() {
            let (abs_colour, em_colour) = FLUOROPHORE_COLOURS[n % FLUOROPHORE_COLOURS.len()];
            let tag = if several {
                format!("{}", n + 1)
            } else {
                String::new()
            };
            let a: Vec<(f64, f64)> = f
                .absorption
                .wavelength_nm
                .iter()
                .copied()
                .zip(f.absorption.value.iter().copied())
                .collect();
            let e_max = f.emission.max();
            let e_scale = if e_max > 0.0 { 1.0 / e_max } else { 0.0 };
            let e: Vec<(f64, f64)> = f
                .emission
                .wavelength_nm
                .iter()
                .copied()
                .zip(f.emission.value.iter().map(|v| v * e_scale))
                .collect();
            lines.push((a, Glyph::Line(abs_colour)));
            lines.push((e, Glyph::Line(em_colour)));
            legend.push((Glyph::Line(abs_colour), format!("a{tag}(λ) absorption")));
            legend.push((
                Glyph::Line(em_colour),
                format!("e{tag}(λ) emission ÷ {} /nm", format_significant(e_max, 3)),
            ));
        }
        // Without a diagonal in the data (solution EEMs) the fit cannot know r or d.
        let reflectance_known = match self.comparison {
            Some(c) => c.measured.has_diagonal,
            None => !material.fit.as_ref().is_some_and(|f| {
                f.undetermined
                    .iter()
                    .any(|u| u.to_ascii_lowercase().contains("reflectance"))
            }),
        };
        let r: Vec<(f64, f64)> = material
            .reflectance
            .wavelength_nm
            .iter()
            .copied()
            .zip(material.reflectance.value.iter().copied())
            .collect();
        if reflectance_known {
            lines.push((r, Glyph::Line(REFLECTANCE_COLOUR)));
            legend.push((
                Glyph::Line(REFLECTANCE_COLOUR),
                "r(λ) reflectance".to_string(),
            ));
        }
        if reflectance_known && !material.fluorophores.is_empty() {
            let d: Vec<(f64, f64)> = material
                .sample_wavelengths()
                .iter()
                .map(|&l| (l, material.diagonal(l)))
                .collect();
            lines.push((d, Glyph::Dashed(DIAGONAL_COLOUR)));
            legend.push((
                Glyph::Dashed(DIAGONAL_COLOUR),
                "d(λ) = (1 − c·a)·r, fitted diagonal".to_string(),
            ));
        }

        let mut diagonal_points = Vec::new();
        let mut profiles = Profiles::default();
        if let Some(c) = self.comparison {
            let m = &c.measured;
            diagonal_points = m
                .diagonal()
                .into_iter()
                .map(|(i, j)| (m.emission_nm[j], m.get(i, j)))
                .filter(|(_, v)| v.is_finite())
                .collect();
            profiles = data_profiles(material, c);
            if !diagonal_points.is_empty() {
                legend.push((Glyph::Dot(BLACK), "measured diagonal".to_string()));
            }
            if !profiles.excitation.is_empty() {
                legend.push((
                    Glyph::Ring(FLUOROPHORE_COLOURS[0].0),
                    "data excitation profile".to_string(),
                ));
            }
            if !profiles.emission.is_empty() {
                legend.push((
                    Glyph::Triangle(FLUOROPHORE_COLOURS[0].1),
                    "data emission profile".to_string(),
                ));
            }
        }

        // Axis ranges covering every curve and point.
        let all_points = lines
            .iter()
            .flat_map(|(p, _)| p.iter())
            .chain(diagonal_points.iter())
            .chain(profiles.excitation.iter())
            .chain(profiles.emission.iter())
            .filter(|(x, y)| x.is_finite() && y.is_finite());
        let (mut x_lo, mut x_hi, mut y_hi) = (f64::INFINITY, f64::NEG_INFINITY, 1.0f64);
        for &(x, y) in all_points {
            x_lo = x_lo.min(x);
            x_hi = x_hi.max(x);
            y_hi = y_hi.max(y);
        }
        if !(x_lo.is_finite() && x_hi > x_lo) {
            (x_lo, x_hi) = (x_lo.min(380.0), x_lo.max(380.0) + 400.0);
        }
        let y_hi = (y_hi * 1.05).min(2.0);
        let y_lo = -0.03;

        let area = root.clone().shrink(
            (0, TITLE_HEIGHT),
            (CHART_WIDTH as u32, (height as i32 - TITLE_HEIGHT) as u32),
        );
        let mut chart = ChartBuilder::on(&area)
            .margin(12)
            .x_label_area_size(50)
            .y_label_area_size(70)
            .build_cartesian_2d(x_lo..x_hi, y_lo..y_hi)?;
        let step_x = tick_step(x_lo, x_hi, 8);
        let step_y = tick_step(0.0, y_hi, 6);
        chart
            .configure_mesh()
            .light_line_style(RGBColor(235, 235, 235))
            .bold_line_style(RGBColor(215, 215, 215))
            .x_labels(9)
            .y_labels(7)
            .x_label_formatter(&|v| format_tick(*v, step_x))
            .y_label_formatter(&|v| format_tick(*v, step_y))
            .x_desc("wavelength λ (nm)")
            .y_desc("a, r, d (fraction); e scaled to peak 1")
            .label_style(font(15.0))
            .axis_desc_style(font(16.0))
            .draw()?;
        for (points, glyph) in lines {
            match glyph {
                Glyph::Dashed(colour) => {
                    chart.draw_series(DashedLineSeries::new(
                        points,
                        8,
                        5,
                        colour.stroke_width(2),
                    ))?;
                }
                Glyph::Line(colour) => {
                    chart.draw_series(LineSeries::new(points, colour.stroke_width(3)))?;
                }
                _ => {}
            }
        }
        chart.draw_series(
            diagonal_points
                .iter()
                .map(|&p| Circle::new(p, 3, BLACK.filled())),
        )?;
        chart.draw_series(
            profiles
                .excitation
                .iter()
                .map(|&p| Circle::new(p, 4, FLUOROPHORE_COLOURS[0].0.stroke_width(2))),
        )?;
        chart.draw_series(
            profiles
                .emission
                .iter()
                .map(|&p| TriangleMarker::new(p, 5, FLUOROPHORE_COLOURS[0].1.filled())),
        )?;

        // Legend and parameters to the right of the chart.
        let x0 = CHART_WIDTH + 10;
        let mut y = TITLE_HEIGHT + 30;
        let style = anchored(font(15.0), HPos::Left, VPos::Center);
        for (glyph, text) in &legend {
            draw_glyph(root, glyph, (x0, y))?;
            draw_text(root, text, (x0 + 40, y), &style)?;
            y += 26;
        }
        y += 18;
        for line in parameter_lines(material, self.comparison) {
            draw_text(root, &line, (x0, y), &style)?;
            y += 23;
        }
        Ok(Layout::default())
    }
}

fn draw_glyph<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    glyph: &Glyph,
    (x, y): (i32, i32),
) -> DrawResult<(), DB> {
    match glyph {
        Glyph::Line(c) => root.draw(&PathElement::new(
            vec![(x, y), (x + 30, y)],
            c.stroke_width(3),
        )),
        Glyph::Dashed(c) => {
            root.draw(&PathElement::new(
                vec![(x, y), (x + 10, y)],
                c.stroke_width(2),
            ))?;
            root.draw(&PathElement::new(
                vec![(x + 15, y), (x + 25, y)],
                c.stroke_width(2),
            ))
        }
        Glyph::Dot(c) => root.draw(&Circle::new((x + 15, y), 3, c.filled())),
        Glyph::Ring(c) => root.draw(&Circle::new((x + 15, y), 4, c.stroke_width(2))),
        Glyph::Triangle(c) => root.draw(&TriangleMarker::new((x + 15, y), 5, c.filled())),
    }
}

/// Text lines with the fitted parameters.
fn parameter_lines(material: &Material, comparison: Option<&Comparison>) -> Vec<String> {
    let mut lines = Vec::new();
    let several = material.fluorophores.len() > 1;
    for (n, f) in material.fluorophores.iter().enumerate() {
        let tag = if several {
            format!("[{}] ", n + 1)
        } else {
            String::new()
        };
        lines.push(format!("{tag}k = c·Q = {}", format_significant(f.k(), 3)));
        let range = f
            .concentration_range
            .map(|[lo, hi]| {
                format!(
                    " (feasible {}–{})",
                    format_significant(lo, 2),
                    format_significant(hi, 2)
                )
            })
            .unwrap_or_default();
        lines.push(format!(
            "{tag}c = {}{range}",
            format_significant(f.concentration, 3)
        ));
        lines.push(format!(
            "{tag}Q = {}, mean emission {} nm",
            format_significant(f.quantum_yield, 3),
            format_significant(f.emission_mean_nm(), 3)
        ));
    }
    if let Some(fit) = &material.fit
        && !fit.gauge.is_empty()
    {
        lines.push(format!("gauge: {}", fit.gauge));
    }
    if let Some(c) = comparison {
        lines.push(format!(
            "profiles from Stokes cells, guard {} nm",
            format_significant(c.guard_nm, 3)
        ));
        if !c.measured.has_diagonal {
            lines.push("no diagonal in the data: r, d unknown".to_string());
        }
    }
    lines
}
