//! Synthetic bispectral images with known truth (`fluorite synth --image`): a
//! measured-like image (the model's matrix per pixel plus Gaussian noise per cell), the
//! same without noise, and the truth as a material map (`fluorite-material-map/1`).
//!
//! The content is built from fitted materials (`fits/measured/*.json` by default): their
//! fluorophores, shared by every pixel, in soft-edged regions with a concentration
//! gradient inside each ([`scene`]), a strip without fluorescence, and a reflectance that
//! blends the materials' reflectances over the image. Every pixel's material conserves
//! energy and photons: c_k ∈ [0, 1], Σ c_k·a_k ≤ 1 (overlapping regions are scaled down
//! together), r ∈ [0, 1], and each fluorophore keeps its source's yield and yield form.
//!
//! Images are streamed: a pixel's matrix is Σ_k c_k(p)·F_k plus the diagonal
//! (1 − Σ c_k·a_k)·r(p), with F_k each fluorophore's cells at c = 1 computed once with
//! [`crate::model::predict`]; tiles are computed when the writer asks for them, so memory
//! is bounded by a few tiles whatever the image's size.

pub mod colour;
pub mod scene;
mod write;

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::image::layout::{Cell, Layout};
use crate::image::map::{MaterialMap, SCHEMA as MAP_SCHEMA, Textures, concentration_channel};
use crate::material::{Fluorophore, Material, YieldForm};
use crate::measurement::Units;
use crate::model::predict;
use crate::numeric::SplitMix64;
use crate::spectrum::{Spectrum, check_grid, find_wavelength, uniform_grid};

use colour::DeltaEStats;
use scene::Scene;

/// Schema tag of the generating parameters (`NAME.synth.json`).
pub const SCHEMA: &str = "fluorite-image-synth/1";

/// The source materials when none are given: fluorite's grid fits (one fluorophore each,
/// `fit --model tabulated`) of three real surfaces whose fluorophores differ (an optical
/// brightener absorbing in the UV and emitting blue, a yellow-green textile dye, a pink
/// Post-It dye), relative to the repository's root. Grid fits, not the default fits: an
/// image takes every fluorophore of every source, and the default fit of postit_pink has
/// two since 2026-12-05 (the grid fits are what the default fits were before).
pub const DEFAULT_MATERIALS: [&str; 3] = [
    "fits/measured/grid/CIBA12.json",
    "fits/measured/grid/TEXTYELL.json",
    "fits/measured/grid/postit_pink.json",
];

/// Largest image side (pixels).
pub const MAX_SIDE: usize = 16_384;

/// Most fluorophores an image shares.
pub const MAX_FLUOROPHORES: usize = 8;

/// Image side when none is given (pixels).
pub const DEFAULT_SIDE: usize = 256;

/// Width of the regions' soft edges when none is given (pixels).
pub const DEFAULT_FALLOFF_PX: f64 = 4.0;

/// What to generate, apart from the source materials.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ImageSynthOptions {
    /// File stem of the outputs (`NAME.exr`, `NAME.truth.exr`, `NAME.truth/`,
    /// `NAME.synth.json`).
    pub name: String,
    /// Pixels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Excitation grid (nm).
    pub excitation_nm: Vec<f64>,
    /// Emission grid (nm).
    pub emission_nm: Vec<f64>,
    /// Gaussian noise σ added to every cell of the measured-like image.
    pub noise_sigma: f64,
    /// Random seed of the scene and the noise.
    pub seed: u64,
    /// 16-bit float images instead of 32-bit.
    pub half: bool,
    /// ZIP-compressed images instead of uncompressed ones.
    pub zip: bool,
    /// Width of the regions' soft edges (pixels).
    pub falloff_px: f64,
}

impl ImageSynthOptions {
    /// Defaults: a [`DEFAULT_SIDE`]² image on the BFC-450 grid (excitation 300–780 nm,
    /// emission 380–780 nm, 10 nm), the measured noise σ, seed 1, 32-bit, uncompressed.
    pub fn new(name: impl Into<String>) -> ImageSynthOptions {
        ImageSynthOptions {
            name: name.into(),
            width: DEFAULT_SIDE,
            height: DEFAULT_SIDE,
            excitation_nm: uniform_grid(300.0, 780.0, 10.0),
            emission_nm: uniform_grid(380.0, 780.0, 10.0),
            noise_sigma: crate::synth::MEASURED_NOISE_SIGMA,
            seed: 1,
            half: false,
            zip: false,
            falloff_px: DEFAULT_FALLOFF_PX,
        }
    }

    /// Checks every option; errors name the `fluorite synth` flag that sets it.
    pub fn validate(&self) -> Result<()> {
        let name = &self.name;
        if name.is_empty()
            || name.contains(['/', '\\'])
            || name.starts_with('.')
            || name.chars().any(char::is_control)
        {
            return Err(Error::invalid(
                "--name",
                format!("is {name:?}; give a file stem without folders, e.g. `image`"),
            ));
        }
        for (side, what) in [(self.width, "width"), (self.height, "height")] {
            if side == 0 || side > MAX_SIDE {
                return Err(Error::invalid(
                    "--size",
                    format!("the {what} is {side}; give 1 to {MAX_SIDE} pixels per side"),
                ));
            }
        }
        if self.width * self.height < 2 {
            return Err(Error::invalid(
                "--size",
                "is 1×1; an image needs at least 2 pixels (e.g. --size 2)",
            ));
        }
        check_grid(&self.excitation_nm, "--excitation-grid")?;
        check_grid(&self.emission_nm, "--emission-grid")?;
        if !(self.noise_sigma.is_finite() && self.noise_sigma >= 0.0) {
            return Err(Error::invalid(
                "--noise",
                format!("is {}; give a non-negative σ", self.noise_sigma),
            ));
        }
        if !(self.falloff_px.is_finite() && (0.0..=1000.0).contains(&self.falloff_px)) {
            return Err(Error::invalid(
                "--falloff",
                format!("is {}; give 0 to 1000 pixels", self.falloff_px),
            ));
        }
        Ok(())
    }
}

/// Parses an image size: `512` (square) or `640x480` (width × height; `×` also accepted).
pub fn parse_size(text: &str) -> Result<(usize, usize)> {
    let bad = || {
        Error::invalid(
            "--size",
            format!(
                "is {text:?}; give one side for a square (512) or width x height (640x480), 1 to {MAX_SIDE} pixels each"
            ),
        )
    };
    let side = |s: &str| -> Result<usize> {
        let v: usize = s.trim().parse().map_err(|_| bad())?;
        if v == 0 || v > MAX_SIDE {
            return Err(bad());
        }
        Ok(v)
    };
    let t = text.trim().to_ascii_lowercase().replace('×', "x");
    match t.split_once('x') {
        Some((w, h)) => Ok((side(w)?, side(h)?)),
        None => {
            let s = side(&t)?;
            Ok((s, s))
        }
    }
}

/// A source material and how to name it (its file).
#[derive(Debug, Clone)]
pub struct Source {
    /// The file it was read from, as given.
    pub label: String,
    /// The material.
    pub material: Material,
}

/// Where a fluorophore of the image comes from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FluorophoreOrigin {
    /// The source material's file.
    pub source: String,
    /// The source material's name.
    pub material: String,
    /// Its index among that material's fluorophores (from 0).
    pub index: usize,
    /// Its yield form in the source (and the image).
    pub yield_form: YieldForm,
    /// Its yield (Q or Φ) in the source (and the image).
    #[serde(rename = "yield")]
    pub yield_value: f64,
    /// Its concentration in the source fit: the peak of its region.
    pub source_concentration: f64,
    /// The largest concentration it reaches in the image (the map's value).
    pub max_concentration: f64,
    /// The texture channel of its concentration.
    pub channel: String,
}

/// The truth of one pixel: the concentrations and the reflectance, as stored.
#[derive(Debug, Clone, PartialEq)]
pub struct PixelTruth {
    /// c_k per fluorophore.
    pub concentration: Vec<f32>,
    /// r at each diagonal wavelength of the layout.
    pub reflectance: Vec<f32>,
}

/// The generating parameters, written as `NAME.synth.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ImageSynthRecord {
    /// Always [`SCHEMA`].
    pub schema: String,
    /// The options.
    #[serde(flatten)]
    pub options: ImageSynthOptions,
    /// Cells per pixel (channels of the bispectral images).
    pub cells: usize,
    /// The source materials' files.
    pub sources: Vec<String>,
    /// The image's fluorophores, in the map's order.
    pub fluorophores: Vec<FluorophoreOrigin>,
    /// What the image shows, drawn from the seed.
    pub scene: Scene,
    /// ΔE2000 between each pixel of the noisy image and its truth, under D65, A and F11
    /// (as stored: 16-bit values with `half`); absent until the noisy image is written.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub noise_delta_e2000: BTreeMap<String, DeltaEStats>,
}

/// What [`ImageSynth::write`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct Written {
    /// The files, in the order written: the noisy image, the truth image, the two
    /// textures, the material map and the generating parameters.
    pub files: Vec<PathBuf>,
    /// The generating parameters as written.
    pub record: ImageSynthRecord,
}

/// A synthetic image ready to be written: the scene and every table a pixel needs.
#[derive(Debug, Clone)]
pub struct ImageSynth {
    options: ImageSynthOptions,
    layout: Layout,
    sources: Vec<Source>,
    fluorophores: Vec<Fluorophore>,
    origins: Vec<FluorophoreOrigin>,
    scene: Scene,
    /// The layout's diagonal wavelengths (nm): the reflectance texture's channels.
    diagonal_nm: Vec<f64>,
    /// Per cell: its (excitation, emission) indices on the measurement grids.
    grid_of: Vec<(usize, usize)>,
    /// Per fluorophore: its cells at c = 1 (layout order).
    unit_cells: Vec<Vec<f64>>,
    /// Per fluorophore: a at the diagonal wavelengths.
    diagonal_absorption: Vec<Vec<f64>>,
    /// Per fluorophore: a at every sample of every absorption (where Σ c·a peaks).
    absorption_samples: Vec<Vec<f64>>,
    /// Per source: r at the diagonal wavelengths.
    source_reflectance: Vec<Vec<f64>>,
    /// Whether some fluorophore has the photon form, whose energy yield exceeds 1 above
    /// its mean emission wavelength: the reflectance is then lowered where needed.
    photon_form: bool,
}

/// `v` rounded to an f32 not above it (values at a bound stay within it).
fn f32_down(v: f64) -> f32 {
    let f = v as f32;
    if f64::from(f) > v { f.next_down() } else { f }
}

impl ImageSynth {
    /// Prepares an image of `sources`' fluorophores (every fluorophore of every source, in
    /// order) and reflectances. Fails when an option is impossible, when the sources
    /// hold no fluorophore or more than [`MAX_FLUOROPHORES`], or when the grids share no
    /// wavelength (no diagonal) or hold no λo > λi pair.
    pub fn new(options: ImageSynthOptions, sources: Vec<Source>) -> Result<ImageSynth> {
        options.validate()?;
        if sources.is_empty() {
            return Err(Error::invalid(
                "--material",
                "no source material; give one or more fitted materials, e.g. fits/measured/CIBA12.json",
            ));
        }
        let (ex, em) = (&options.excitation_nm, &options.emission_nm);
        let layout = Layout::from_grids(ex, em)
            .map_err(|e| Error::invalid("--excitation-grid/--emission-grid", e.to_string()))?;
        let diagonal_nm: Vec<f64> = layout
            .diagonal_wavelengths()
            .iter()
            .map(|&i| layout.wavelengths[i])
            .collect();
        if diagonal_nm.is_empty() {
            return Err(Error::invalid(
                "--excitation-grid/--emission-grid",
                "the grids share no wavelength, so the image would hold no diagonal (reflectance) cell; give grids that overlap",
            ));
        }
        let mut fluorophores = Vec::new();
        let mut origins = Vec::new();
        for source in &sources {
            for (index, f) in source.material.fluorophores.iter().enumerate() {
                origins.push(FluorophoreOrigin {
                    source: source.label.clone(),
                    material: source.material.name.clone(),
                    index,
                    yield_form: f.yield_form,
                    yield_value: f.quantum_yield,
                    source_concentration: f.concentration,
                    max_concentration: 0.0,
                    channel: concentration_channel(fluorophores.len()),
                });
                fluorophores.push(f.clone());
            }
        }
        if fluorophores.is_empty() || fluorophores.len() > MAX_FLUOROPHORES {
            return Err(Error::invalid(
                "--material",
                format!(
                    "the materials hold {} fluorophores; an image shares 1 to {MAX_FLUOROPHORES}: choose fitted fluorescent materials such as fits/measured/CIBA12.json",
                    fluorophores.len()
                ),
            ));
        }
        let grid_of = layout
            .cells
            .iter()
            .map(|&cell| {
                let (wi, wo) = match cell {
                    Cell::Diagonal(w) => (w, w),
                    Cell::Reradiation(i, o) => (i, o),
                };
                let i = find_wavelength(ex, layout.wavelengths[wi]);
                let j = find_wavelength(em, layout.wavelengths[wo]);
                i.zip(j).ok_or_else(|| {
                    Error::invalid(
                        "--excitation-grid/--emission-grid",
                        format!("cell {cell:?} lies on neither grid (an internal inconsistency)"),
                    )
                })
            })
            .collect::<Result<Vec<_>>>()?;
        let zero = Spectrum::new(diagonal_nm.clone(), vec![0.0; diagonal_nm.len()], "r")?;
        let unit_cells = fluorophores
            .iter()
            .map(|f| {
                let unit = Fluorophore {
                    concentration: 1.0,
                    concentration_range: None,
                    ..f.clone()
                };
                let material = Material::new("unit", zero.clone(), vec![unit]);
                let m = predict(&material, "unit", ex, em, Units::PerBin, false);
                grid_of.iter().map(|&(i, j)| m.get(i, j)).collect()
            })
            .collect();
        let mut samples: Vec<f64> = fluorophores
            .iter()
            .flat_map(|f| f.absorption.wavelength_nm.iter().copied())
            .collect();
        samples.sort_by(f64::total_cmp);
        samples.dedup();
        let at =
            |s: &Spectrum, grid: &[f64]| grid.iter().map(|&l| s.eval_zero_outside(l)).collect();
        let diagonal_absorption = fluorophores
            .iter()
            .map(|f| at(&f.absorption, &diagonal_nm))
            .collect();
        let absorption_samples = fluorophores
            .iter()
            .map(|f| at(&f.absorption, &samples))
            .collect();
        let source_reflectance = sources
            .iter()
            .map(|s| {
                diagonal_nm
                    .iter()
                    .map(|&l| s.material.reflectance.eval_clamped(l).clamp(0.0, 1.0))
                    .collect()
            })
            .collect();
        let photon_form = fluorophores
            .iter()
            .any(|f| f.yield_form == YieldForm::Photon);
        let peaks: Vec<f64> = fluorophores.iter().map(|f| f.concentration).collect();
        let scene = Scene::new(
            options.width,
            options.height,
            &peaks,
            sources.len(),
            options.falloff_px,
            options.seed,
        );
        let mut synth = ImageSynth {
            options,
            layout,
            sources,
            fluorophores,
            origins,
            scene,
            diagonal_nm,
            grid_of,
            unit_cells,
            diagonal_absorption,
            absorption_samples,
            source_reflectance,
            photon_form,
        };
        synth.find_max_concentrations();
        Ok(synth)
    }

    /// The options.
    pub fn options(&self) -> &ImageSynthOptions {
        &self.options
    }

    /// The cells of every pixel.
    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The diagonal wavelengths (nm): where the reflectance is given.
    pub fn reflectance_nm(&self) -> &[f64] {
        &self.diagonal_nm
    }

    /// Each fluorophore's largest concentration over the image: one pass over the
    /// concentrations alone (a few numbers per pixel).
    fn find_max_concentrations(&mut self) {
        use rayon::prelude::*;
        let k = self.fluorophores.len();
        let max = (0..self.options.height)
            .into_par_iter()
            .map(|y| {
                let mut row = vec![0f32; k];
                for x in 0..self.options.width {
                    for (m, c) in row.iter_mut().zip(self.concentrations(x, y)) {
                        *m = m.max(c);
                    }
                }
                row
            })
            .reduce(
                || vec![0f32; k],
                |a, b| a.iter().zip(&b).map(|(x, y)| x.max(*y)).collect(),
            );
        for (origin, m) in self.origins.iter_mut().zip(max) {
            origin.max_concentration = f64::from(m);
        }
    }

    /// The concentrations at pixel (x, y): the scene's, scaled together so that
    /// Σ c_k·a_k ≤ 1 at every absorption sample (hence everywhere between), rounded down
    /// to f32.
    pub fn concentrations(&self, x: usize, y: usize) -> Vec<f32> {
        let mut c = vec![0.0; self.fluorophores.len()];
        self.scene.concentrations(x, y, &mut c);
        let n = self.absorption_samples.first().map_or(0, Vec::len);
        let total = (0..n)
            .map(|s| {
                c.iter()
                    .zip(&self.absorption_samples)
                    .map(|(c, a)| c * a[s])
                    .sum::<f64>()
            })
            .fold(0.0, f64::max);
        let scale = if total > 1.0 { 1.0 / total } else { 1.0 };
        c.iter()
            .map(|&v| f32_down((v * scale).clamp(0.0, 1.0)))
            .collect()
    }

    /// The truth of pixel (x, y): its concentrations and its reflectance (the blend of
    /// the sources', lowered where a photon-form fluorophore would otherwise reradiate
    /// more energy than arrives), both rounded down to f32.
    pub fn pixel(&self, x: usize, y: usize) -> Result<PixelTruth> {
        let concentration = self.concentrations(x, y);
        let mut blend = vec![0.0; self.sources.len()];
        self.scene.blend(x, y, self.options.height, &mut blend);
        let mut r: Vec<f64> = (0..self.diagonal_nm.len())
            .map(|j| {
                blend
                    .iter()
                    .zip(&self.source_reflectance)
                    .map(|(m, s)| m * s[j])
                    .sum::<f64>()
                    .clamp(0.0, 1.0)
            })
            .collect();
        if self.photon_form {
            let mut material = self.material(&concentration, &r)?;
            material.lower_reflectance_to_energy_bound();
            r = material.reflectance.value;
        }
        Ok(PixelTruth {
            concentration,
            reflectance: r.into_iter().map(f32_down).collect(),
        })
    }

    /// The material of a pixel with concentrations `c` and reflectance `r` (on the
    /// diagonal wavelengths).
    fn material(&self, c: &[f32], r: &[f64]) -> Result<Material> {
        let reflectance = Spectrum::new(self.diagonal_nm.clone(), r.to_vec(), "reflectance")?;
        let fluorophores = self
            .fluorophores
            .iter()
            .zip(c)
            .map(|(f, &c)| Fluorophore {
                concentration: f64::from(c),
                concentration_range: None,
                ..f.clone()
            })
            .collect();
        // Without the conservation block: only the energy law's reflectance bound is asked.
        Ok(Material {
            schema: crate::material::SCHEMA.into(),
            name: self.options.name.clone(),
            reflectance,
            fluorophores,
            fit: None,
            conservation: None,
            forms: None,
        })
    }

    /// The noise-free cells of a pixel (layout order) into `out`:
    /// Σ_k c_k·F_k, plus (1 − Σ_k c_k·a_k)·r on the diagonal.
    pub fn truth_cells(&self, pixel: &PixelTruth, out: &mut [f64]) {
        out.fill(0.0);
        for (&c, unit) in pixel.concentration.iter().zip(&self.unit_cells) {
            if c > 0.0 {
                let c = f64::from(c);
                for (o, u) in out.iter_mut().zip(unit) {
                    *o += c * u;
                }
            }
        }
        for (j, &r) in pixel.reflectance.iter().enumerate() {
            let absorbed: f64 = pixel
                .concentration
                .iter()
                .zip(&self.diagonal_absorption)
                .map(|(&c, a)| f64::from(c) * a[j])
                .sum();
            out[j] += (1.0 - absorbed) * f64::from(r);
        }
    }

    /// Adds the noise of pixel (x, y) to its cells: independent N(0, σ²) per cell, drawn
    /// from a generator seeded by the seed and the pixel's index, so any tile order gives
    /// the same image.
    pub fn add_noise(&self, x: usize, y: usize, cells: &mut [f64]) {
        let sigma = self.options.noise_sigma;
        if sigma == 0.0 {
            return;
        }
        let index = (y * self.options.width + x) as u64;
        let key = self.options.seed ^ 0x4E4F_4953_455F_5631;
        let mut rng = SplitMix64::new(
            SplitMix64::new(key.wrapping_add(index.wrapping_mul(0xD1B5_4A32_D192_ED03))).next_u64(),
        );
        for pair in cells.chunks_mut(2) {
            // Box–Muller: two independent normals per pair of uniforms.
            let u1 = 1.0 - rng.uniform();
            let u2 = rng.uniform();
            let radius = sigma * (-2.0 * u1.ln()).sqrt();
            let (s, c) = (std::f64::consts::TAU * u2).sin_cos();
            pair[0] += radius * c;
            if let Some(second) = pair.get_mut(1) {
                *second += radius * s;
            }
        }
    }

    /// The truth as a material map (the textures are `concentration.exr` and
    /// `reflectance.exr` beside its JSON).
    pub fn material_map(&self) -> MaterialMap {
        let fluorophores = self
            .fluorophores
            .iter()
            .zip(&self.origins)
            .map(|(f, o)| Fluorophore {
                concentration: o.max_concentration,
                concentration_range: None,
                ..f.clone()
            })
            .collect();
        MaterialMap {
            schema: MAP_SCHEMA.into(),
            name: self.options.name.clone(),
            width: self.options.width,
            height: self.options.height,
            fluorophores,
            gauge: "synthetic truth: each fluorophore keeps the yield and yield form of the fitted material it comes from; the concentrations are the generated ones".into(),
            textures: Textures {
                concentration: "concentration.exr".into(),
                concentration_channels: (0..self.fluorophores.len())
                    .map(concentration_channel)
                    .collect(),
                reflectance: "reflectance.exr".into(),
            },
            fit: None,
        }
    }

    /// The generating parameters (without the noise's colour difference, which writing
    /// the noisy image measures).
    pub fn record(&self) -> ImageSynthRecord {
        ImageSynthRecord {
            schema: SCHEMA.into(),
            options: self.options.clone(),
            cells: self.layout.len(),
            sources: self.sources.iter().map(|s| s.label.clone()).collect(),
            fluorophores: self.origins.clone(),
            scene: self.scene.clone(),
            noise_delta_e2000: BTreeMap::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn sizes_parse_as_squares_or_width_by_height() {
        assert_eq!(parse_size("512").unwrap(), (512, 512));
        assert_eq!(parse_size("640x480").unwrap(), (640, 480));
        assert_eq!(parse_size(" 32×24 ").unwrap(), (32, 24));
        for bad in ["", "0", "x5", "5x", "-3", "17000", "3x4x5", "1.5"] {
            let e = parse_size(bad).unwrap_err().to_string();
            assert!(e.starts_with("--size"), "{bad}: {e}");
        }
    }

    #[test]
    fn a_photon_form_fluorophore_lowers_a_white_reflectance_where_it_would_add_energy() {
        // HERPICER's fluorophores (the default fit's two, both photon form): the pigment
        // absorbs far to the red of its mean emission, so its energy yield there exceeds
        // 1. Over a perfect white (r = 1, no shading) every pixel a fluorophore reaches
        // would reflect and reradiate more than arrives unless r gives way.
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("fits/measured/HERPICER.json");
        let mut white = Material::load(&path).unwrap();
        white.reflectance = Spectrum::new(vec![380.0, 780.0], vec![1.0, 1.0], "r").unwrap();
        let options = ImageSynthOptions {
            width: 24,
            height: 16,
            ..ImageSynthOptions::new("white")
        };
        let source = Source {
            label: "white".into(),
            material: white,
        };
        let mut synth = ImageSynth::new(options, vec![source]).unwrap();
        synth.scene.shading = 0.0;
        let mut lowered = 0;
        for y in 0..16 {
            for x in 0..24 {
                let pixel = synth.pixel(x, y).unwrap();
                let r: Vec<f64> = pixel.reflectance.iter().map(|&v| f64::from(v)).collect();
                let material = synth.material(&pixel.concentration, &r).unwrap();
                let report = crate::check::check_material(&material);
                assert!(report.valid, "({x}, {y}): {}", report.failed_names());
                if pixel.reflectance.iter().any(|&v| v < 0.9999) {
                    lowered += 1;
                    assert!(pixel.concentration.iter().any(|&c| c > 0.0));
                }
            }
        }
        assert!(lowered >= 20, "{lowered} pixels lowered");
    }

    #[test]
    fn rounding_down_never_exceeds_the_value() {
        for v in [0.0, 1.0, 0.1, 0.3333333333333333, 0.9999999999, 1e-30] {
            let f = f32_down(v);
            assert!(f64::from(f) <= v && v - f64::from(f) <= 1.2e-7 * v.max(1e-38));
        }
    }
}
