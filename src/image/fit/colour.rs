//! Colour of a pixel's matrix under the judging lights, as linear weights on its cells
//! (model.md §7): XYZ = Σ_cells weight·value, with the light and the observer projected
//! onto the layout's grid as `fluorite fit` does for a bispectral EXR (one grid for both
//! axes, cells the layout lacks count as zero). The measured and the fitted image are
//! judged with the same weights, so a difference is the fit's alone.

use crate::colour::{Lab, Light, PatchColorimeter, Xyz, delta_e2000, xyz_to_lab};

use crate::image::layout::{Cell, Layout};

/// Per light: the XYZ weight of every cell of the layout, and the light's white.
#[derive(Debug, Clone)]
pub struct CellColours {
    /// Light names, in order.
    pub lights: Vec<String>,
    /// `weights[light][cell]`: XYZ per unit value of the cell.
    pub weights: Vec<Vec<Xyz>>,
    /// The perfect white under each light (Y = 100).
    pub whites: Vec<Xyz>,
    /// Per light: Σ over cells of w·wᵀ, so that cell noise of σ moves XYZ with
    /// covariance σ²·this.
    pub covariance: Vec<[[f64; 3]; 3]>,
}

impl CellColours {
    /// The weights of `layout`'s cells under `lights`.
    pub fn new(layout: &Layout, lights: &[Light]) -> CellColours {
        let grid = &layout.wavelengths;
        let mut weights = Vec::with_capacity(lights.len());
        let mut whites = Vec::with_capacity(lights.len());
        let mut covariance = Vec::with_capacity(lights.len());
        for light in lights {
            let pc = PatchColorimeter::new(light, grid, grid);
            let (lw, rw, ew, bw, scale) = pc.weights();
            let w: Vec<Xyz> = layout
                .cells
                .iter()
                .map(|&c| match c {
                    Cell::Diagonal(i) => rw[i].map(|v| v * scale),
                    Cell::Reradiation(i, o) => ew[o].map(|v| v * lw[i] / bw[o] * scale),
                })
                .collect();
            let mut cov = [[0.0; 3]; 3];
            for x in &w {
                for a in 0..3 {
                    for b in 0..3 {
                        cov[a][b] += x[a] * x[b];
                    }
                }
            }
            covariance.push(cov);
            weights.push(w);
            whites.push(pc.white);
        }
        CellColours {
            lights: lights.iter().map(|l| l.name.clone()).collect(),
            weights,
            whites,
            covariance,
        }
    }

    /// The RMS ΔE2000 that independent cell noise of `sigma` gives the colour `xyz` under
    /// light `l`, to first order: the noise's Lab covariance (through the CIELAB
    /// Jacobian) weighed by ΔE2000's local metric there, as the single-matrix fit's
    /// [`crate::fit::assess::colour_noise_delta_e2000`] takes it. Held against a ΔE2000,
    /// it must be one: the RMS ΔE76 it was until 2026-12-05 runs up to 1.7× larger under
    /// uv, where noise moves chroma most.
    pub fn noise_delta_e2000(&self, l: usize, xyz: Xyz, sigma: f64) -> f64 {
        let j = crate::colour::lab_jacobian(xyz, self.whites[l]);
        let c = &self.covariance[l];
        let lab_covariance: [[f64; 3]; 3] = std::array::from_fn(|a| {
            std::array::from_fn(|b| {
                (0..3)
                    .flat_map(|x| (0..3).map(move |y| (x, y)))
                    .map(|(x, y)| j[a][x] * c[x][y] * j[b][y])
                    .sum()
            })
        });
        let metric = crate::fit::assess::delta_e2000_metric(self.lab(l, xyz));
        let trace: f64 = (0..3)
            .flat_map(|a| (0..3).map(move |b| (a, b)))
            .map(|(a, b)| metric[a][b] * lab_covariance[b][a])
            .sum();
        sigma * trace.max(0.0).sqrt()
    }

    /// XYZ under light `l` of the cells `values` (in the layout's order, or any range of
    /// it starting at cell `first`); non-finite values count as zero.
    pub fn xyz(&self, l: usize, first: usize, values: &[f32]) -> Xyz {
        let mut xyz = [0.0; 3];
        for (w, &v) in self.weights[l][first..].iter().zip(values) {
            if v.is_finite() {
                let v = f64::from(v);
                xyz[0] += w[0] * v;
                xyz[1] += w[1] * v;
                xyz[2] += w[2] * v;
            }
        }
        xyz
    }

    /// CIELAB of `xyz` under light `l`.
    pub fn lab(&self, l: usize, xyz: Xyz) -> Lab {
        xyz_to_lab(xyz, self.whites[l])
    }

    /// ΔE2000 between two XYZ under light `l`.
    pub fn delta_e(&self, l: usize, a: Xyz, b: Xyz) -> f64 {
        delta_e2000(self.lab(l, a), self.lab(l, b))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numeric::SplitMix64;

    /// The propagated RMS ΔE2000 of a pixel's colour against noise draws: cell noise of
    /// σ = 2·10⁻³ added to every cell of an orange-ish pixel (reflectance rising at
    /// 580 nm, a UV-excited emission at 450 nm), the colour recomputed per draw. 300 draws
    /// estimate an RMS to about 4 %; the linearisation adds little at these sizes.
    #[test]
    fn noise_delta_e2000_matches_noise_draws() {
        let grid: Vec<f64> = (0..=48).map(|i| 300.0 + 10.0 * f64::from(i)).collect();
        let layout = Layout::from_grids(&grid, &grid[8..]).unwrap();
        let lights = Light::standard();
        let colours = CellColours::new(&layout, &lights);
        let values: Vec<f32> = layout
            .cells
            .iter()
            .map(|&c| match c {
                Cell::Diagonal(i) => {
                    let nm = layout.wavelengths[i];
                    (0.1 + 0.7 / (1.0 + (-(nm - 580.0) / 15.0).exp())) as f32
                }
                Cell::Reradiation(i, o) => {
                    let (ex, em) = (layout.wavelengths[i], layout.wavelengths[o]);
                    (0.02
                        * (-((ex - 360.0) / 30.0).powi(2)).exp()
                        * (-((em - 450.0) / 25.0).powi(2)).exp()) as f32
                }
            })
            .collect();
        let sigma = 2e-3;
        let draws = 300;
        let mut rng = SplitMix64::new(41);
        for (l, light) in lights.iter().enumerate() {
            let clean = colours.xyz(l, 0, &values);
            let mut sum = 0.0;
            for _ in 0..draws {
                let noisy: Vec<f32> = values
                    .iter()
                    .map(|&v| v + (sigma * rng.normal()) as f32)
                    .collect();
                sum += colours.delta_e(l, colours.xyz(l, 0, &noisy), clean).powi(2);
            }
            let drawn = (sum / f64::from(draws)).sqrt();
            let propagated = colours.noise_delta_e2000(l, clean, sigma);
            assert!(
                (propagated / drawn - 1.0).abs() < 0.15,
                "{}: propagated {propagated}, drawn {drawn}",
                light.name
            );
        }
    }
}
