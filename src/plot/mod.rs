//! Figures that show how well a fitted material matches its measurement:
//!
//! 1. residual map — measured matrix, fitted matrix and their difference as heat maps
//!    ([`heatmap`]);
//! 2. spectra — fitted a(λ), e(λ) of every fluorophore and r(λ) (the continuous forms
//!    when the material has them) with the measured diagonal and the data's own
//!    excitation and emission profiles ([`spectra`]);
//! 3. colour — measured and fitted patch colour under each standard light, with ΔE2000
//!    ([`swatches`]);
//! 4. convergence — solver cost per iteration ([`convergence`]).
//!
//! Beside them: the joint fit's components and scores ([`joint`]) and the charts of the
//! bench and stability commands ([`evaluation`]), and the image fits' time against
//! accuracy ([`image_chart`]).
//!
//! Every figure is rendered into memory first ([`plot`]); only when all of them succeeded
//! are they written ([`write_plots`]), each through a temporary file renamed into place,
//! so a failed run leaves no partial output.

pub mod colormap;
mod common;
pub(crate) use common::{Caption, draw_captions};
pub mod convergence;
pub mod evaluation;
pub mod font;
pub mod heatmap;
pub mod image_chart;
pub mod joint;
mod parameters;
pub mod spectra;
pub mod swatches;
mod text;

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::material::{Fluorophore, FluorophoreShapes, Material, YieldForm};
use crate::measurement::{CellKind, Measurement};
use crate::model;
use crate::spectrum::Spectrum;

/// Image file format of the figures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ImageFormat {
    /// 8-bit RGB PNG.
    #[default]
    Png,
    /// SVG (text references the "sans-serif" family).
    Svg,
}

impl ImageFormat {
    /// File extension without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            ImageFormat::Png => "png",
            ImageFormat::Svg => "svg",
        }
    }
}

/// The four figures.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FigureKind {
    /// Measured, fitted and residual heat maps (needs data).
    Residuals,
    /// Fitted spectra, with data profiles when data are given.
    Spectra,
    /// Patch colours under the standard lights (needs data).
    Colour,
    /// Cost per solver iteration (needs a cost history in the fit block).
    Convergence,
}

impl FigureKind {
    /// The suffix in output file names: `<stem>-<suffix>.png`.
    pub fn suffix(self) -> &'static str {
        match self {
            FigureKind::Residuals => "residuals",
            FigureKind::Spectra => "spectra",
            FigureKind::Colour => "colour",
            FigureKind::Convergence => "convergence",
        }
    }

    /// Size of the figure in pixels (width, height).
    pub fn size(self) -> (u32, u32) {
        match self {
            FigureKind::Residuals => heatmap::SIZE,
            FigureKind::Spectra => spectra::SIZE,
            FigureKind::Colour => swatches::SIZE,
            FigureKind::Convergence => convergence::SIZE,
        }
    }
}

/// Where a figure drew the elements whose colour is known, so callers (tests) can probe
/// pixels.
#[derive(Debug, Clone, Default)]
pub struct Layout {
    /// Heat-map panels, in drawing order (measured, fitted, residual).
    pub heatmaps: Vec<heatmap::HeatmapPanel>,
    /// Swatch pairs, one per light.
    pub swatches: Vec<swatches::SwatchPanel>,
    /// The spectra chart: plotting area, axis ranges and curves.
    pub spectra: Option<spectra::SpectraPanel>,
}

/// One rendered figure, held in memory until written.
#[derive(Debug, Clone)]
pub struct Figure {
    /// Which figure.
    pub kind: FigureKind,
    /// PNG or SVG.
    pub format: ImageFormat,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The encoded file.
    pub bytes: Vec<u8>,
    /// Positions of the colour-known elements.
    pub layout: Layout,
}

impl Figure {
    /// The figure's file name for material file stem `stem`: `<stem>-<kind>.<ext>`.
    pub fn file_name(&self, stem: &str) -> String {
        format!("{stem}-{}.{}", self.kind.suffix(), self.format.extension())
    }
}

/// How to plot.
#[derive(Debug, Clone, Default)]
pub struct PlotOptions {
    /// PNG (default) or SVG.
    pub format: ImageFormat,
    /// Guard band half-width in nm; default: the fit block's `guard_nm`, else one grid step.
    pub guard_nm: Option<f64>,
}

/// The rendered figures and what could not be drawn (and why).
#[derive(Debug, Clone)]
pub struct Plots {
    /// Rendered figures, in the order residuals, spectra, colour, convergence.
    pub figures: Vec<Figure>,
    /// One sentence per figure left out, saying what it needs.
    pub skipped: Vec<String>,
}

/// A measurement next to what the material predicts on the same grids.
#[derive(Debug, Clone)]
pub struct Comparison {
    /// The measured matrix.
    pub measured: Measurement,
    /// `model::predict` on the measured grids, units and diagonal.
    pub fitted: Measurement,
    /// Guard band half-width (nm) used to classify cells.
    pub guard_nm: f64,
    /// Factor applied to the prediction: 1, except for data on an arbitrary scale (counts),
    /// where the least-squares factor over the Stokes cells brings the model to the data's
    /// units.
    pub fitted_scale: f64,
    /// Row-major, one per cell: true where the measurement is missing because a scatter
    /// band of the fit's preprocessing masked it (drawn as masked, not as unrecorded).
    pub masked: Vec<bool>,
}

impl Comparison {
    /// Predicts `material` on `measured`'s grids. The grids must match the material's
    /// (see [`check_grids`]).
    pub fn new(material: &Material, measured: &Measurement, guard_nm: f64) -> Self {
        let mut fitted = model::predict(
            material,
            &measured.name,
            &measured.excitation_nm,
            &measured.emission_nm,
            measured.units,
            measured.has_diagonal,
        );
        let mut fitted_scale = 1.0;
        if measured.arbitrary_scale {
            let (mut cross, mut square) = (0.0, 0.0);
            for i in 0..measured.n_excitation() {
                for j in 0..measured.n_emission() {
                    if measured.cell_kind(i, j, guard_nm) == CellKind::Stokes {
                        cross += measured.get(i, j) * fitted.get(i, j);
                        square += fitted.get(i, j).powi(2);
                    }
                }
            }
            if square > 0.0 && (cross / square).is_finite() {
                fitted_scale = cross / square;
                fitted.values.iter_mut().for_each(|v| *v *= fitted_scale);
            }
        }
        let preprocessing = material.fit.as_ref().and_then(|f| f.preprocessing.as_ref());
        let masked = measured
            .excitation_nm
            .iter()
            .flat_map(|&ex| measured.emission_nm.iter().map(move |&em| (ex, em)))
            .zip(&measured.values)
            .map(|((ex, em), v)| v.is_nan() && preprocessing.is_some_and(|p| p.masks(ex, em)))
            .collect();
        Comparison {
            measured: measured.clone(),
            fitted,
            guard_nm,
            fitted_scale,
            masked,
        }
    }

    /// Whether cell (`i`, `j`) is missing because scatter masking removed it.
    pub fn is_masked(&self, i: usize, j: usize) -> bool {
        self.masked[i * self.measured.n_emission() + j]
    }

    /// Kind of cell (`i`, `j`) in the measurement.
    pub fn kind(&self, i: usize, j: usize) -> CellKind {
        self.measured.cell_kind(i, j, self.guard_nm)
    }

    /// Measured minus fitted at (`i`, `j`); NaN where the measurement is missing.
    pub fn residual(&self, i: usize, j: usize) -> f64 {
        self.measured.get(i, j) - self.fitted.get(i, j)
    }

    /// ‖measured − fitted‖ / ‖measured‖ over the Stokes cells (where fluorescence is
    /// fitted); NaN when there are none.
    pub fn relative_residual_stokes(&self) -> f64 {
        let (mut num, mut den) = (0.0, 0.0);
        for i in 0..self.measured.n_excitation() {
            for j in 0..self.measured.n_emission() {
                if self.kind(i, j) == CellKind::Stokes {
                    num += self.residual(i, j).powi(2);
                    den += self.measured.get(i, j).powi(2);
                }
            }
        }
        (num / den).sqrt()
    }
}

/// Checks that `data` lies on the grids the material was fitted on: every fluorophore's
/// absorption samples equal the excitation grid and its emission samples the emission
/// grid. A parametric material (with forms) tabulates them on a finer grid that keeps
/// the measurement's wavelengths: there the samples must span the grid and include each
/// of its wavelengths.
pub fn check_grids(material: &Material, data: &Measurement) -> Result<()> {
    let same = |grid: &[f64], samples: &[f64]| {
        let close = |x: Option<&f64>, y: Option<&f64>| match (x, y) {
            (Some(x), Some(y)) => (x - y).abs() <= 1e-6,
            _ => false,
        };
        let finer = material.forms.is_some();
        close(grid.first(), samples.first())
            && close(grid.last(), samples.last())
            && (finer || grid.len() == samples.len())
            && grid.iter().all(|g| {
                let i = samples.partition_point(|s| *s < g - 1e-6);
                samples.get(i).is_some_and(|s| (s - g).abs() <= 1e-6)
            })
    };
    let describe = |g: &[f64]| match (g.first(), g.last()) {
        (Some(first), Some(last)) => format!("{first}–{last} nm, {} samples", g.len()),
        _ => "no samples".to_string(),
    };
    let file = data
        .source
        .as_ref()
        .map(|p| p.display().to_string())
        .unwrap_or_else(|| data.name.clone());
    let hint = match material.fit.as_ref().map(|f| f.source.as_str()) {
        Some(source) if !source.is_empty() => format!(
            "; plot the material against the file it was fitted to ({source}), or refit it to this file"
        ),
        _ => "; plot the material against the file it was fitted to, or refit it to this file"
            .to_string(),
    };
    for (n, f) in material.fluorophores.iter().enumerate() {
        for (grid, what, spectrum, role) in [
            (
                &data.excitation_nm,
                "excitation",
                &f.absorption.wavelength_nm,
                "absorption",
            ),
            (
                &data.emission_nm,
                "emission",
                &f.emission.wavelength_nm,
                "emission",
            ),
        ] {
            if !same(grid, spectrum) {
                return Err(Error::invalid(
                    "--data",
                    format!(
                        "{file}: its {what} grid ({}) does not match material \"{}\" (fluorophores[{n}].{role} sampled at {}){hint}",
                        describe(grid),
                        material.name,
                        describe(spectrum),
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Renders every figure that the inputs allow, all in memory. Without `data` only the
/// spectra and convergence figures are drawn; `skipped` says what was left out and why.
pub fn plot(
    material: &Material,
    data: Option<&Measurement>,
    options: &PlotOptions,
) -> Result<Plots> {
    if let Some(g) = options.guard_nm
        && !(g.is_finite() && g >= 0.0)
    {
        return Err(Error::invalid(
            "--guard-nm",
            format!("is {g}; give a non-negative width in nm"),
        ));
    }
    let comparison = match data {
        Some(m) => {
            m.validate()?;
            check_grids(material, m)?;
            let guard = options
                .guard_nm
                .or(material.fit.as_ref().map(|f| f.guard_nm))
                .filter(|g| g.is_finite() && *g >= 0.0)
                .unwrap_or_else(|| m.default_guard_nm());
            Some(Comparison::new(material, m, guard))
        }
        None => None,
    };
    let format = options.format;
    let mut figures = Vec::new();
    let mut skipped = Vec::new();
    let mut push = |kind: FigureKind, (bytes, layout): (Vec<u8>, Layout)| {
        let (width, height) = kind.size();
        figures.push(Figure {
            kind,
            format,
            width,
            height,
            bytes,
            layout,
        });
    };

    match &comparison {
        Some(comparison) => {
            let figure = heatmap::ResidualFigure {
                material,
                comparison,
            };
            push(
                FigureKind::Residuals,
                common::render(&figure, FigureKind::Residuals, format)?,
            )
        }
        None => skipped.push("residual map: needs the measured matrix (--data FILE)".to_string()),
    }
    push(
        FigureKind::Spectra,
        spectra::render(material, comparison.as_ref(), format)?,
    );
    match &comparison {
        Some(c) if c.measured.arbitrary_scale => skipped.push(
            "colour swatches: the data are on an arbitrary scale, so they have no colour to compare"
                .to_string(),
        ),
        Some(comparison) => {
            let figure = swatches::ColourFigure {
                material,
                comparison,
            };
            push(FigureKind::Colour, common::render(&figure, FigureKind::Colour, format)?)
        }
        None => skipped.push(
            "colour swatches: need the measured matrix (--data FILE)".to_string(),
        ),
    }
    match material.fit.as_ref() {
        Some(fit) if !fit.cost_history.is_empty() => push(
            FigureKind::Convergence,
            convergence::render(material, fit, format)?,
        ),
        Some(_) => {
            skipped.push("convergence: the material's fit block holds no cost history".to_string())
        }
        None => skipped.push(
            "convergence: the material has no fit block (it was not produced by fluorite fit)"
                .to_string(),
        ),
    }
    Ok(Plots { figures, skipped })
}

/// The material a shapes-only fit (an EEM without a diagonal) stands for in figures: its
/// absorption and emission with c = 1 and Q = k (1 on an arbitrary scale, where the
/// residual map scales the model to the data), no reflectance, and its fit report (which
/// holds the scatter bands masked before the fit).
pub fn shapes_material(shapes: &FluorophoreShapes) -> Material {
    let grid = shapes.emission.wavelength_nm.clone();
    let none = Spectrum {
        value: vec![0.0; grid.len()],
        wavelength_nm: grid,
    };
    let fluorophore = Fluorophore {
        concentration: 1.0,
        quantum_yield: shapes.k.unwrap_or(1.0),
        yield_form: YieldForm::Energy,
        concentration_range: None,
        absorption: shapes.absorption.clone(),
        emission: shapes.emission.clone(),
    };
    let mut material = Material::new(shapes.name.clone(), none, vec![fluorophore]);
    material.fit = Some(shapes.fit.clone());
    material
}

/// Renders the figures of a shapes-only fit against the (prepared) matrix it was fitted
/// to: the residual map with masked scatter hatched, the shapes and the convergence.
pub fn plot_shapes(
    shapes: &FluorophoreShapes,
    data: &Measurement,
    options: &PlotOptions,
) -> Result<Plots> {
    plot(&shapes_material(shapes), Some(data), options)
}

/// Renders the figures of either fit outcome against the matrix it was fitted to (as
/// prepared: an EEM's masked scatter is drawn as masked): what `fit --plot` draws.
pub fn plot_outcome(
    outcome: &crate::fit::FitOutcome,
    data: &Measurement,
    options: &PlotOptions,
) -> Result<Plots> {
    match outcome {
        crate::fit::FitOutcome::Material(material) => plot(material, Some(data), options),
        crate::fit::FitOutcome::Shapes(shapes) => plot_shapes(shapes, data, options),
    }
}

/// Writes the figures into `dir` as `<stem>-<kind>.<ext>` and returns the paths. All files
/// are first written to temporary files in `dir`; only when every one of them is complete
/// are they renamed into place, so an unwritable folder or a full disk leaves no output.
pub fn write_plots(plots: &Plots, dir: &Path, stem: &str) -> Result<Vec<PathBuf>> {
    if !dir.is_dir() {
        return Err(Error::io(
            dir,
            std::io::Error::new(
                std::io::ErrorKind::NotFound,
                "output folder does not exist or is not a folder; create it or choose another with -o DIR",
            ),
        ));
    }
    let files: Vec<(PathBuf, Vec<u8>)> = plots
        .figures
        .iter()
        .map(|figure| (dir.join(figure.file_name(stem)), figure.bytes.clone()))
        .collect();
    crate::files::write_files(&files)?;
    Ok(files.into_iter().map(|(path, _)| path).collect())
}
