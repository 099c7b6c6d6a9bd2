//! One pixel's material and colour from its scratch record, the shared spectra and the
//! gauge: scores by NNLS, concentrations, the reflectance from the diagonal, the fitted
//! matrix's colour beside the measured one under every light.

use crate::colour::Xyz;
use crate::image::layout::{Cell, Layout};

use super::colour::CellColours;
use super::gauge::Gauge;
use super::nnls::MAX_UNKNOWNS;
use super::scratch::RecordLayout;
use super::shared::{Cells, Projected, Shared};

/// A reflectance this far outside [0, 1] before clamping marks the pixel as clamped,
/// unless the noise of its estimate is larger (see [`PixelModel::fit`]).
const CLAMP_REPORT: f64 = 0.01;

/// Everything a pixel's evaluation needs, computed once.
pub struct PixelModel {
    k: usize,
    projected: Projected,
    record: RecordLayout,
    factors: Vec<f64>,
    /// a_k at each diagonal wavelength, K × diagonal.
    absorption: Vec<f64>,
    /// β_k·ε_k at each diagonal wavelength (the fluorescence a unit score puts into the
    /// diagonal cell), K × diagonal.
    diagonal_fluorescence: Vec<f64>,
    /// Per light: the XYZ of each component's reradiation cells per unit score.
    component_xyz: Vec<Vec<Xyz>>,
    colours: CellColours,
    diagonal: usize,
    /// Noise σ per cell of the measurement.
    sigma: f64,
}

/// A pixel's material: what the textures and the fitted image need.
#[derive(Debug, Clone, PartialEq)]
pub struct PixelFit {
    /// The measurement held a non-finite cell: nothing below is meaningful.
    pub masked: bool,
    /// Scores s_k = c_k·(yield factor).
    pub scores: [f64; MAX_UNKNOWNS],
    /// Concentrations c_k.
    pub concentration: [f64; MAX_UNKNOWNS],
    /// r at the diagonal wavelengths.
    pub reflectance: Vec<f64>,
    /// The fitted diagonal cells.
    pub fitted_diagonal: Vec<f64>,
    /// The pixel's material needed clamping (Σ c·a > 1, c > 1 or r outside [0, 1] by
    /// more than 0.01 and more than three times the noise of its estimate).
    pub clamped: bool,
}

/// A pixel's colours under every light, fitted beside measured: what the bound, the ΔE
/// maps and the light images need. Kept apart from [`PixelFit`] because the colour
/// difference is most of a pixel's evaluation and the textures do not need it.
#[derive(Debug, Clone, PartialEq)]
pub struct PixelColours {
    /// Measured and fitted XYZ per light.
    pub measured_xyz: Vec<Xyz>,
    /// See `measured_xyz`.
    pub fitted_xyz: Vec<Xyz>,
    /// ΔE2000 fitted against measured, per light.
    pub delta_e: Vec<f64>,
}

impl PixelModel {
    /// The model of `shared` under `gauge` on `layout`, for records of `record`'s layout,
    /// judged with `colours` at cell noise `sigma`.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        shared: &Shared,
        gauge: &Gauge,
        cells: &Cells,
        layout: &Layout,
        basis: &[f64],
        record: RecordLayout,
        colours: CellColours,
        sigma: f64,
    ) -> PixelModel {
        let k = shared.k;
        let diagonal = layout.diagonal_count;
        let (ni, no) = (cells.excitation_nm.len(), cells.emission_nm.len());
        let mut absorption = vec![0.0; k * diagonal];
        let mut diagonal_fluorescence = vec![0.0; k * diagonal];
        for (d, cell) in layout.cells[..diagonal].iter().enumerate() {
            let Cell::Diagonal(w) = *cell else { continue };
            let nm = layout.wavelengths[w];
            let ex = crate::spectrum::find_wavelength(&cells.excitation_nm, nm);
            let em = crate::spectrum::find_wavelength(&cells.emission_nm, nm);
            for c in 0..k {
                absorption[c * diagonal + d] =
                    gauge.fluorophores[c].absorption.eval_zero_outside(nm);
                if let (Some(i), Some(o)) = (ex, em) {
                    diagonal_fluorescence[c * diagonal + d] =
                        shared.excitation[c * ni + i] * shared.emission[c * no + o];
                }
            }
        }
        let component_xyz = (0..colours.lights.len())
            .map(|l| {
                (0..k)
                    .map(|c| {
                        let v = shared.cell_vector(cells, c);
                        let mut xyz = [0.0; 3];
                        for (w, x) in colours.weights[l][diagonal..].iter().zip(&v) {
                            for t in 0..3 {
                                xyz[t] += w[t] * x;
                            }
                        }
                        xyz
                    })
                    .collect()
            })
            .collect();
        PixelModel {
            k,
            projected: Projected::new(shared, cells, basis, record.rank),
            record,
            factors: gauge.factors.clone(),
            absorption,
            diagonal_fluorescence,
            component_xyz,
            colours,
            diagonal,
            sigma,
        }
    }

    /// Lights judged, in order.
    pub fn lights(&self) -> &[String] {
        &self.colours.lights
    }

    /// The perfect white under light `l` (Y = 100).
    pub fn white(&self, l: usize) -> [f64; 3] {
        self.colours.whites[l]
    }

    /// Components.
    pub fn components(&self) -> usize {
        self.k
    }

    /// The cell noise σ the colours are judged at.
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// The material of the pixel whose scratch record is `r`.
    pub fn fit(&self, r: &[f32]) -> PixelFit {
        let (k, nd) = (self.k, self.diagonal);
        if r[0] != 0.0 {
            return PixelFit {
                masked: true,
                scores: [f64::NAN; MAX_UNKNOWNS],
                concentration: [f64::NAN; MAX_UNKNOWNS],
                reflectance: vec![f64::NAN; nd],
                fitted_diagonal: vec![f64::NAN; nd],
                clamped: false,
            };
        }
        let mut scores = self.projected.scores(&r[self.record.y()]);
        let mut concentration = [0.0; MAX_UNKNOWNS];
        let mut clamped = false;
        for c in 0..k {
            concentration[c] = self.factors[c] * scores[c];
            if concentration[c] > 1.0 {
                scores[c] /= concentration[c];
                concentration[c] = 1.0;
                clamped = true;
            }
        }
        // Σ c·a ≤ 1 at every diagonal wavelength.
        let absorbed = |d: usize, conc: &[f64]| -> f64 {
            (0..k).map(|c| conc[c] * self.absorption[c * nd + d]).sum()
        };
        let most = (0..nd)
            .map(|d| absorbed(d, &concentration))
            .fold(0.0, f64::max);
        if most > 1.0 {
            for c in 0..k {
                concentration[c] /= most;
                scores[c] /= most;
            }
            clamped = true;
        }
        let measured_diagonal = &r[self.record.diagonal()];
        let mut reflectance = Vec::with_capacity(nd);
        let mut fitted_diagonal = Vec::with_capacity(nd);
        for d in 0..nd {
            let fluorescence: f64 = (0..k)
                .map(|c| scores[c] * self.diagonal_fluorescence[c * nd + d])
                .sum();
            let remaining = 1.0 - absorbed(d, &concentration);
            let raw = if remaining > 0.0 {
                (f64::from(measured_diagonal[d]) - fluorescence) / remaining
            } else {
                0.0
            };
            let value = raw.clamp(0.0, 1.0);
            // r = (D − fluorescence) / (1 − Σ c·a): the diagonal cell's noise σ is divided
            // by what the fluorophores leave, so where they absorb nearly everything a
            // reflectance outside [0, 1] by a few σ / (1 − Σ c·a) is noise, not a
            // material the model cannot hold.
            let noise = crate::fit::assess::NOISE_COVERAGE * self.sigma / remaining.max(1e-6);
            if (value - raw).abs() > CLAMP_REPORT.max(noise) {
                clamped = true;
            }
            reflectance.push(value);
            fitted_diagonal.push(remaining * value + fluorescence);
        }
        PixelFit {
            masked: false,
            scores,
            concentration,
            reflectance,
            fitted_diagonal,
            clamped,
        }
    }

    /// The colours of the pixel whose scratch record is `r` and whose material is `fit`.
    pub fn colours(&self, r: &[f32], fit: &PixelFit) -> PixelColours {
        let lights = self.colours.lights.len();
        if fit.masked {
            return PixelColours {
                measured_xyz: vec![[f64::NAN; 3]; lights],
                fitted_xyz: vec![[f64::NAN; 3]; lights],
                delta_e: vec![f64::NAN; lights],
            };
        }
        let measured_diagonal = &r[self.record.diagonal()];
        let mut measured_xyz = Vec::with_capacity(lights);
        let mut fitted_xyz = Vec::with_capacity(lights);
        let mut delta_e = Vec::with_capacity(lights);
        let fitted_f32: Vec<f32> = fit.fitted_diagonal.iter().map(|&v| v as f32).collect();
        for l in 0..lights {
            let off = &r[self.record.xyz(l)];
            let diag = self.colours.xyz(l, 0, measured_diagonal);
            let measured = [0, 1, 2].map(|t| f64::from(off[t]) + diag[t]);
            let mut fitted = self.colours.xyz(l, 0, &fitted_f32);
            for c in 0..self.k {
                for t in 0..3 {
                    fitted[t] += fit.scores[c] * self.component_xyz[l][c][t];
                }
            }
            delta_e.push(self.colours.delta_e(l, measured, fitted));
            measured_xyz.push(measured);
            fitted_xyz.push(fitted);
        }
        PixelColours {
            measured_xyz,
            fitted_xyz,
            delta_e,
        }
    }

    /// The RMS ΔE2000 that the cell noise gives the measured colour `xyz` under light
    /// `l` ([`CellColours::noise_delta_e2000`]). Computed only where asked: a pixel
    /// within the bound needs no allowance.
    pub fn noise_delta_e2000(&self, l: usize, xyz: Xyz) -> f64 {
        self.colours.noise_delta_e2000(l, xyz, self.sigma)
    }
}
