//! How far the noise alone moves each pixel's colour: CIEDE2000 between the noisy and the
//! noise-free matrix of every pixel, as a flat patch under D65, A and F11 (model.md §7),
//! with the library's patch colorimeter. The distribution is kept as a fine logarithmic
//! histogram, so memory stays bounded whatever the image's size.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::colour::{Light, PatchColorimeter, Xyz, delta_e2000, xyz_to_lab};
use crate::error::Result;
use crate::image::layout::{Cell, Layout};

/// The lights the noise's colour difference is reported under.
pub const NOISE_LIGHTS: [&str; 3] = ["d65", "a", "f11"];

/// Histogram bins per decade of ΔE2000 (relative resolution about 0.23 %).
const BINS_PER_DECADE: f64 = 1000.0;
/// Smallest ΔE2000 the histogram resolves (smaller values count in the first bin).
const LOWEST: f64 = 1e-6;
/// Decades above [`LOWEST`] (up to ΔE2000 = 100; larger values count in the last bin).
const DECADES: f64 = 8.0;

/// The distribution of ΔE2000 over an image's pixels under one light.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DeltaEStats {
    /// Median over the pixels.
    pub median: f64,
    /// 99th percentile over the pixels.
    pub p99: f64,
    /// Largest value.
    pub max: f64,
}

/// Per cell of a layout, the XYZ a unit value in that cell adds to a flat patch under one
/// light: a [`PatchColorimeter`]'s weights arranged in the layout's order, so a pixel's
/// colour is one dot product. Equal to [`PatchColorimeter::xyz_from`] with the diagonal
/// cells as the reflected part and every other cell as reradiation.
#[derive(Debug, Clone)]
pub struct CellColorimeter {
    /// The light's name.
    pub light: String,
    weights: Vec<Xyz>,
    /// The perfect white's XYZ under the light (Y = 100).
    pub white: Xyz,
}

impl CellColorimeter {
    /// The weights of `light` for the cells of `layout`, on the measurement grids the
    /// layout was made from; `grid_of(cell)` gives a cell's (excitation, emission) indices
    /// on those grids.
    pub fn new(
        light: &Light,
        layout: &Layout,
        excitation_nm: &[f64],
        emission_nm: &[f64],
        grid_of: &[(usize, usize)],
    ) -> CellColorimeter {
        let colorimeter = PatchColorimeter::new(light, excitation_nm, emission_nm);
        let (light_weights, reflected, emitted, widths, scale) = colorimeter.weights();
        let weights = layout
            .cells
            .iter()
            .zip(grid_of)
            .map(|(cell, &(i, j))| match cell {
                Cell::Diagonal(_) => reflected[j].map(|w| w * scale),
                Cell::Reradiation(..) => {
                    emitted[j].map(|w| w * scale * light_weights[i] / widths[j])
                }
            })
            .collect();
        CellColorimeter {
            light: light.name.clone(),
            weights,
            white: colorimeter.white,
        }
    }

    /// XYZ of the patch whose cells (in the layout's order) are `cells`.
    pub fn xyz(&self, cells: &[f32]) -> Xyz {
        let mut xyz = [0.0; 3];
        for (w, &v) in self.weights.iter().zip(cells) {
            let v = f64::from(v);
            xyz[0] += w[0] * v;
            xyz[1] += w[1] * v;
            xyz[2] += w[2] * v;
        }
        xyz
    }

    /// CIEDE2000 between two pixels' cells.
    pub fn delta_e(&self, a: &[f32], b: &[f32]) -> f64 {
        delta_e2000(
            xyz_to_lab(self.xyz(a), self.white),
            xyz_to_lab(self.xyz(b), self.white),
        )
    }
}

/// A logarithmic histogram of ΔE2000 values, one per light.
#[derive(Debug, Clone, PartialEq)]
pub struct Tally {
    counts: Vec<Vec<u64>>,
    max: Vec<f64>,
}

fn bins() -> usize {
    (BINS_PER_DECADE * DECADES) as usize
}

impl Tally {
    /// An empty tally for `lights` lights.
    pub fn new(lights: usize) -> Tally {
        Tally {
            counts: vec![vec![0; bins()]; lights],
            max: vec![0.0; lights],
        }
    }

    /// Counts `value` under light `light`.
    pub fn add(&mut self, light: usize, value: f64) {
        let bin = if value > LOWEST {
            (((value / LOWEST).log10() * BINS_PER_DECADE) as usize).min(bins() - 1)
        } else {
            0
        };
        self.counts[light][bin] += 1;
        if value > self.max[light] {
            self.max[light] = value;
        }
    }

    /// Adds another tally's counts.
    pub fn merge(&mut self, other: &Tally) {
        for (mine, theirs) in self.counts.iter_mut().zip(&other.counts) {
            for (a, b) in mine.iter_mut().zip(theirs) {
                *a += b;
            }
        }
        for (a, &b) in self.max.iter_mut().zip(&other.max) {
            *a = a.max(b);
        }
    }

    /// The `q`-quantile under light `light`: the geometric centre of the first bin whose
    /// cumulative count reaches q·n (NaN for an empty tally).
    pub fn quantile(&self, light: usize, q: f64) -> f64 {
        let counts = &self.counts[light];
        let n: u64 = counts.iter().sum();
        if n == 0 {
            return f64::NAN;
        }
        let wanted = (q * n as f64).ceil().max(1.0) as u64;
        let mut seen = 0;
        for (bin, &c) in counts.iter().enumerate() {
            seen += c;
            if seen >= wanted {
                return LOWEST * 10f64.powf((bin as f64 + 0.5) / BINS_PER_DECADE);
            }
        }
        self.max[light]
    }

    /// Median, 99th percentile and maximum per light, keyed by the lights' names.
    pub fn stats(&self, names: &[String]) -> BTreeMap<String, DeltaEStats> {
        names
            .iter()
            .enumerate()
            .map(|(light, name)| {
                let stats = DeltaEStats {
                    median: self.quantile(light, 0.5),
                    p99: self.quantile(light, 0.99),
                    max: self.max[light],
                };
                (name.clone(), stats)
            })
            .collect()
    }
}

/// The cell colorimeters of [`NOISE_LIGHTS`] for a layout.
pub fn noise_colorimeters(
    layout: &Layout,
    excitation_nm: &[f64],
    emission_nm: &[f64],
    grid_of: &[(usize, usize)],
) -> Result<Vec<CellColorimeter>> {
    NOISE_LIGHTS
        .iter()
        .map(|name| {
            let light = Light::parse(name)?;
            Ok(CellColorimeter::new(
                &light,
                layout,
                excitation_nm,
                emission_nm,
                grid_of,
            ))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_resolve_to_a_quarter_percent() {
        let mut t = Tally::new(1);
        for i in 1..=1000 {
            t.add(0, i as f64 / 1000.0);
        }
        let median = t.quantile(0, 0.5);
        assert!((median / 0.5 - 1.0).abs() < 0.0025, "{median}");
        let p99 = t.quantile(0, 0.99);
        assert!((p99 / 0.99 - 1.0).abs() < 0.0025, "{p99}");
        assert_eq!(t.stats(&["x".into()])["x"].max, 1.0);
    }
}
