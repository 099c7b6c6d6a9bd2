//! The spectra figure: fitted absorption a(λ), emission e(λ) (scaled to peak 1),
//! reflectance r(λ) and diagonal d(λ) = (1 − Σc·a)·r, with the measured diagonal as points
//! and the data's own excitation and emission profiles, so a user sees whether the shapes
//! agree.
//!
//! With several fluorophores each has one colour (absorption solid, emission dashed) and
//! the legend numbers them a₁, e₁, a₂, e₂, …. When the material carries continuous forms
//! (a parametric fit), the curves are those forms evaluated every nanometre and the title
//! names the model.
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
    Draw, DrawResult, TAB10, anchored, draw_text, draw_title, font, format_significant,
    format_tick, render as render_figure, tick_step,
};
use super::{Comparison, FigureKind, ImageFormat, Layout};
use crate::error::Result;
use crate::material::{Fluorophore, Material, YieldForm};
use crate::measurement::CellKind;
use crate::parametric::{FluorophoreForms, MaterialForms, SpectralForm};
use crate::spectrum::Spectrum;

/// Size of the spectra figure in pixels.
pub const SIZE: (u32, u32) = (1000, 560);

const TITLE_HEIGHT: i32 = 44;
const CHART_WIDTH: i32 = 680;

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

/// The curve the excitation profile is drawn against, scaled to peak 1 on the excitation
/// grid: the combined row factor Σ c·Q(λ)·a(λ) (Q(λ) = Q, or Φ·λ/λ̄e in the photon form)
/// with several fluorophores, a(λ) itself with one (the profile is then the data's
/// absorption, on the drawn a curve, whatever the yield form: the ratio of measured to
/// fitted row sums already cancels the row factor). None when the material does not
/// fluoresce.
fn excitation_reference(material: &Material, grid: &[f64]) -> Option<Vec<f64>> {
    if let [f] = material.fluorophores.as_slice() {
        if f.k() <= 0.0 {
            return None;
        }
        return normalise(
            grid.iter()
                .map(|&l| f.absorption.eval_zero_outside(l))
                .collect(),
        );
    }
    let means: Vec<f64> = material
        .fluorophores
        .iter()
        .map(|f| f.emission_mean_nm())
        .collect();
    normalised_sum(material, grid, |n, f, l| {
        f.reradiated_with_mean(l, means[n])
    })
}

/// The combined emission shape Σ (Σλ c·Q(λ)·a(λ))·e(λ), scaled to peak 1 on the emission
/// grid (e(λ)/max e for one fluorophore).
fn emission_reference(material: &Material, ex_grid: &[f64], em_grid: &[f64]) -> Option<Vec<f64>> {
    let weights: Vec<f64> = material
        .fluorophores
        .iter()
        .map(|f| {
            let mean = f.emission_mean_nm();
            ex_grid
                .iter()
                .map(|&l| f.reradiated_with_mean(l, mean))
                .sum::<f64>()
        })
        .collect();
    normalised_sum(material, em_grid, |n, f, l| {
        weights[n] * f.emission.eval_zero_outside(l)
    })
}

/// Σ over the fluorophores of `term(n, fluorophore, λ)` at every λ of `grid`, scaled to
/// peak 1 (None when it has no positive peak).
fn normalised_sum(
    material: &Material,
    grid: &[f64],
    term: impl Fn(usize, &Fluorophore, f64) -> f64,
) -> Option<Vec<f64>> {
    let fluorophores = &material.fluorophores;
    normalise(
        grid.iter()
            .map(|&l| {
                fluorophores
                    .iter()
                    .enumerate()
                    .map(|(n, f)| term(n, f, l))
                    .sum()
            })
            .collect(),
    )
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
        format,
    )
}

/// One curve of the spectra chart, as drawn.
#[derive(Debug, Clone, PartialEq)]
pub struct SpectraCurve {
    /// The legend text (e.g. "a₂(λ) absorption").
    pub label: String,
    /// The line colour (RGB).
    pub colour: [u8; 3],
    /// Whether the line is dashed (with gaps) rather than solid.
    pub dashed: bool,
    /// The points drawn: (wavelength nm, plotted value).
    pub points: Vec<(f64, f64)>,
}

/// Where the spectra chart was drawn and what it shows, so callers (tests) can probe
/// the pixels of each curve.
#[derive(Debug, Clone, PartialEq)]
pub struct SpectraPanel {
    /// Plotting area in pixels: left, top, right, bottom (right and bottom exclusive).
    pub plot_area_px: [i32; 4],
    /// The wavelength axis range (nm).
    pub x_range_nm: [f64; 2],
    /// The value axis range.
    pub y_range: [f64; 2],
    /// Every curve, in drawing order.
    pub curves: Vec<SpectraCurve>,
    /// The model name of the material's continuous forms when the curves are those forms
    /// evaluated every nanometre; None when they are the tabulated samples.
    pub forms_model: Option<String>,
}

impl SpectraPanel {
    /// The pixel (fractional) of the point (`nm`, `value`).
    pub fn pixel(&self, nm: f64, value: f64) -> (f64, f64) {
        let [left, top, right, bottom] = self.plot_area_px;
        let [x_lo, x_hi] = self.x_range_nm;
        let [y_lo, y_hi] = self.y_range;
        (
            left as f64 + (nm - x_lo) / (x_hi - x_lo) * (right - 1 - left) as f64,
            (bottom - 1) as f64 - (value - y_lo) / (y_hi - y_lo) * (bottom - 1 - top) as f64,
        )
    }

    /// The curve whose label starts with `prefix`.
    pub fn curve(&self, prefix: &str) -> Option<&SpectraCurve> {
        self.curves.iter().find(|c| c.label.starts_with(prefix))
    }
}

/// A curve to draw: its points, its look and its legend text.
type Line = (Vec<(f64, f64)>, Glyph, String);

/// What a legend entry's sample looks like.
#[derive(Clone, Copy)]
enum Glyph {
    Line(RGBColor),
    Thin(RGBColor),
    Dashed(RGBColor),
    LongDashed(RGBColor),
    Dot(RGBColor),
    Ring(RGBColor),
    Triangle(RGBColor),
}

/// `n` (from 1) in subscript digits: 1 → "₁", 12 → "₁₂".
fn subscript(n: usize) -> String {
    n.to_string()
        .chars()
        .map(|c| match c.to_digit(10) {
            Some(d) => char::from_u32(0x2080 + d).unwrap_or(c),
            None => c,
        })
        .collect()
}

/// Wavelengths every nanometre from `lo` to `hi`, both ends included.
fn every_nm(lo: f64, hi: f64) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite() && hi >= lo) {
        return Vec::new();
    }
    let mut grid = vec![lo];
    let mut l = lo.floor() + 1.0;
    // At most a few thousand points for any sensible spectrum.
    while l < hi && grid.len() < 100_000 {
        grid.push(l);
        l += 1.0;
    }
    if hi > lo {
        grid.push(hi);
    }
    grid
}

/// The range (nm) a spectrum is sampled over.
fn sample_range(s: &Spectrum) -> (f64, f64) {
    (
        s.wavelength_nm.first().copied().unwrap_or(f64::NAN),
        s.wavelength_nm.last().copied().unwrap_or(f64::NAN),
    )
}

/// The curve of a spectrum: its form every nanometre over its sample range, zero outside
/// (absorption, emission), or its samples when there is no form.
fn curve_points(s: &Spectrum, form: Option<&SpectralForm>) -> Vec<(f64, f64)> {
    match form {
        Some(form) => {
            let (lo, hi) = sample_range(s);
            every_nm(lo, hi)
                .into_iter()
                .map(|l| (l, form.eval(l)))
                .collect()
        }
        None => s
            .wavelength_nm
            .iter()
            .copied()
            .zip(s.value.iter().copied())
            .collect(),
    }
}

/// The material's spectra as continuous functions: the forms where present (absorption
/// zero outside its samples like the tabulated model), else the samples.
struct Curves<'a> {
    material: &'a Material,
    forms: Option<&'a MaterialForms>,
}

impl Curves<'_> {
    fn fluorophore_forms(&self, n: usize) -> Option<&FluorophoreForms> {
        self.forms.and_then(|f| f.fluorophores.get(n))
    }

    fn absorption(&self, n: usize, nm: f64) -> f64 {
        let f = &self.material.fluorophores[n];
        match self.fluorophore_forms(n) {
            Some(forms) => {
                let (lo, hi) = sample_range(&f.absorption);
                if (lo..=hi).contains(&nm) {
                    forms.absorption.eval(nm)
                } else {
                    0.0
                }
            }
            None => f.absorption.eval_zero_outside(nm),
        }
    }

    fn reflectance(&self, nm: f64) -> f64 {
        match self.forms.and_then(|f| f.reflectance.as_ref()) {
            Some(form) => form.eval(nm),
            None => self.material.reflectance.eval_clamped(nm),
        }
    }

    fn diagonal(&self, nm: f64) -> f64 {
        let absorbed: f64 = (0..self.material.fluorophores.len())
            .map(|n| self.material.fluorophores[n].concentration * self.absorption(n, nm))
            .sum();
        (1.0 - absorbed) * self.reflectance(nm)
    }
}

/// Colours of absorption and emission for a material with one fluorophore.
const SINGLE_COLOURS: (RGBColor, RGBColor) = (TAB10[0], TAB10[3]);

/// One colour per fluorophore when there are several (absorption solid, emission dashed):
/// blue, orange, purple, red, brown, cyan.
const COMPONENT_COLOURS: [RGBColor; 6] =
    [TAB10[0], TAB10[1], TAB10[4], TAB10[3], TAB10[5], TAB10[9]];

/// Colour of the data profiles and their combined references when there are several
/// fluorophores (the profiles then follow the sum over components, not one of them).
const COMBINED_COLOUR: RGBColor = RGBColor(0, 0, 0);

impl Draw for SpectraFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<Layout, DB> {
        let material = self.material;
        let (width, height) = SIZE;
        // Forms are used only when they match the fluorophores one to one.
        let forms = material
            .forms
            .as_ref()
            .filter(|f| f.fluorophores.len() == material.fluorophores.len());
        let model = forms.map(|f| format!(" ({})", f.model)).unwrap_or_default();
        let title = match self.comparison {
            Some(c) if c.measured.name != material.name => {
                format!(
                    "{}: fitted spectra vs data {}{model}",
                    material.name, c.measured.name
                )
            }
            Some(_) => format!("{}: fitted spectra vs measured data{model}", material.name),
            None => format!("{}: fitted spectra{model}", material.name),
        };
        draw_title(root, &title, (width as i32 / 2, TITLE_HEIGHT / 2 + 2))?;
        let curves = Curves { material, forms };

        // Curves, in plot coordinates.
        let mut legend: Vec<(Glyph, String)> = Vec::new();
        let mut lines: Vec<Line> = Vec::new();
        let several = material.fluorophores.len() > 1;
        for (n, f) in material.fluorophores.iter().enumerate() {
            let (abs_glyph, em_glyph, tag) = if several {
                let c = COMPONENT_COLOURS[n % COMPONENT_COLOURS.len()];
                (Glyph::Line(c), Glyph::LongDashed(c), subscript(n + 1))
            } else {
                (
                    Glyph::Line(SINGLE_COLOURS.0),
                    Glyph::Line(SINGLE_COLOURS.1),
                    String::new(),
                )
            };
            let ff = curves.fluorophore_forms(n);
            let a = curve_points(&f.absorption, ff.map(|ff| &ff.absorption));
            let e = curve_points(&f.emission, ff.map(|ff| &ff.emission));
            let e_max = e.iter().map(|p| p.1).fold(0.0, f64::max);
            let e_scale = if e_max > 0.0 { 1.0 / e_max } else { 0.0 };
            let e: Vec<(f64, f64)> = e.into_iter().map(|(l, v)| (l, v * e_scale)).collect();
            let a_label = format!("a{tag}(λ) absorption");
            let e_label = format!("e{tag}(λ) emission ÷ {} /nm", format_significant(e_max, 3));
            legend.push((abs_glyph, a_label.clone()));
            legend.push((em_glyph, e_label.clone()));
            lines.push((a, abs_glyph, a_label));
            lines.push((e, em_glyph, e_label));
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
        if reflectance_known {
            let r = curve_points(
                &material.reflectance,
                forms.and_then(|f| f.reflectance.as_ref()),
            );
            let label = "r(λ) reflectance".to_string();
            legend.push((Glyph::Line(REFLECTANCE_COLOUR), label.clone()));
            lines.push((r, Glyph::Line(REFLECTANCE_COLOUR), label));
        }
        if reflectance_known && !material.fluorophores.is_empty() {
            let samples = material.sample_wavelengths();
            let wavelengths = match (forms, samples.first(), samples.last()) {
                (Some(_), Some(&lo), Some(&hi)) => every_nm(lo, hi),
                _ => samples,
            };
            let d: Vec<(f64, f64)> = wavelengths
                .iter()
                .map(|&l| (l, curves.diagonal(l)))
                .collect();
            let label = if several {
                "d(λ) = (1 − Σc·a)·r, fitted diagonal"
            } else {
                "d(λ) = (1 − c·a)·r, fitted diagonal"
            }
            .to_string();
            legend.push((Glyph::Dashed(DIAGONAL_COLOUR), label.clone()));
            lines.push((d, Glyph::Dashed(DIAGONAL_COLOUR), label));
        }

        let mut diagonal_points = Vec::new();
        let mut profiles = Profiles::default();
        let (ring, triangle) = if several {
            (COMBINED_COLOUR, COMBINED_COLOUR)
        } else {
            SINGLE_COLOURS
        };
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
                legend.push((Glyph::Ring(ring), "data excitation profile".to_string()));
            }
            if !profiles.emission.is_empty() {
                legend.push((
                    Glyph::Triangle(triangle),
                    "data emission profile".to_string(),
                ));
            }
            // With several fluorophores the profiles follow the sums Σc·Q(λ)·a and
            // Σ(Σλ c·Q(λ)·a)·e, which no single curve shows: draw them thin.
            if several && !(profiles.excitation.is_empty() && profiles.emission.is_empty()) {
                let on = |grid: &[f64], v: Option<Vec<f64>>| -> Vec<(f64, f64)> {
                    v.map(|v| grid.iter().copied().zip(v).collect())
                        .unwrap_or_default()
                };
                let ex = on(
                    &m.excitation_nm,
                    excitation_reference(material, &m.excitation_nm),
                );
                let em = on(
                    &m.emission_nm,
                    emission_reference(material, &m.excitation_nm, &m.emission_nm),
                );
                let photon = material
                    .fluorophores
                    .iter()
                    .any(|f| f.yield_form == YieldForm::Photon);
                let label = if photon {
                    "Σc·Q(λ)·a, Σc·Q·A·e: what the profiles follow".to_string()
                } else {
                    "Σk·a, Σk·e: what the profiles follow".to_string()
                };
                legend.push((Glyph::Thin(COMBINED_COLOUR), label.clone()));
                lines.push((ex, Glyph::Thin(COMBINED_COLOUR), label.clone()));
                lines.push((em, Glyph::Thin(COMBINED_COLOUR), label));
            }
        }

        // Axis ranges covering every curve and point.
        let all_points = lines
            .iter()
            .flat_map(|(p, _, _)| p.iter())
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
        let mut drawn = Vec::new();
        for (points, glyph, label) in lines {
            let (colour, dashed) = match glyph {
                Glyph::Dashed(colour) => {
                    chart.draw_series(DashedLineSeries::new(
                        points.clone(),
                        8,
                        5,
                        colour.stroke_width(2),
                    ))?;
                    (colour, true)
                }
                Glyph::LongDashed(colour) => {
                    chart.draw_series(DashedLineSeries::new(
                        points.clone(),
                        14,
                        5,
                        colour.stroke_width(3),
                    ))?;
                    (colour, true)
                }
                Glyph::Line(colour) => {
                    chart.draw_series(LineSeries::new(points.clone(), colour.stroke_width(3)))?;
                    (colour, false)
                }
                Glyph::Thin(colour) => {
                    chart.draw_series(LineSeries::new(points.clone(), colour.stroke_width(1)))?;
                    (colour, false)
                }
                _ => continue,
            };
            drawn.push(SpectraCurve {
                label,
                colour: [colour.0, colour.1, colour.2],
                dashed,
                points,
            });
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
                .map(|&p| Circle::new(p, 4, ring.stroke_width(2))),
        )?;
        chart.draw_series(
            profiles
                .emission
                .iter()
                .map(|&p| TriangleMarker::new(p, 5, triangle.filled())),
        )?;
        let (xs, ys) = chart.plotting_area().get_pixel_range();
        let panel = SpectraPanel {
            plot_area_px: [xs.start, ys.start, xs.end, ys.end],
            x_range_nm: [x_lo, x_hi],
            y_range: [y_lo, y_hi],
            curves: drawn,
            forms_model: forms.map(|f| f.model.clone()),
        };

        // Legend and parameters to the right of the chart; lines close up when many
        // fluorophores would otherwise run off the figure.
        let parameters = super::parameters::parameter_lines(material, self.comparison);
        let x0 = CHART_WIDTH + 10;
        let top = TITLE_HEIGHT + 30;
        let needed = 26 * legend.len() as i32 + 18 + 23 * parameters.len() as i32;
        let available = height as i32 - top - 8;
        let squeeze = if needed > available {
            available as f64 / needed as f64
        } else {
            1.0
        };
        let step = |px: i32| ((px as f64 * squeeze).round() as i32).max(12);
        let mut y = top;
        let style = anchored(font(15.0), HPos::Left, VPos::Center);
        for (glyph, text) in &legend {
            draw_glyph(root, glyph, (x0, y))?;
            draw_text(root, text, (x0 + 40, y), &style)?;
            y += step(26);
        }
        y += step(18);
        for line in parameters {
            draw_text(root, &line, (x0, y), &style)?;
            y += step(23);
        }
        Ok(Layout {
            spectra: Some(panel),
            ..Layout::default()
        })
    }
}

fn draw_glyph<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    glyph: &Glyph,
    (x, y): (i32, i32),
) -> DrawResult<(), DB> {
    // Line glyphs as dashes: (start, end) pixels from x, and the stroke width.
    let dashes = |c: &RGBColor, dashes: &[(i32, i32)], width: u32| {
        dashes.iter().try_for_each(|&(from, to)| {
            root.draw(&PathElement::new(
                vec![(x + from, y), (x + to, y)],
                c.stroke_width(width),
            ))
        })
    };
    match glyph {
        Glyph::Line(c) => dashes(c, &[(0, 30)], 3),
        Glyph::Thin(c) => dashes(c, &[(0, 30)], 1),
        Glyph::Dashed(c) => dashes(c, &[(0, 10), (15, 25)], 2),
        Glyph::LongDashed(c) => dashes(c, &[(0, 13), (18, 31)], 3),
        Glyph::Dot(c) => root.draw(&Circle::new((x + 15, y), 3, c.filled())),
        Glyph::Ring(c) => root.draw(&Circle::new((x + 15, y), 4, c.stroke_width(2))),
        Glyph::Triangle(c) => root.draw(&TriangleMarker::new((x + 15, y), 5, c.filled())),
    }
}
