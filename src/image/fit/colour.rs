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

    /// The RMS ΔE76 that independent cell noise of `sigma` gives the colour `xyz` under
    /// light `l` (to first order, through the CIELAB Jacobian).
    pub fn noise_delta_e(&self, l: usize, xyz: Xyz, sigma: f64) -> f64 {
        let j = crate::colour::lab_jacobian(xyz, self.whites[l]);
        let c = &self.covariance[l];
        let mut trace = 0.0;
        for row in &j {
            for a in 0..3 {
                for b in 0..3 {
                    trace += row[a] * c[a][b] * row[b];
                }
            }
        }
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
