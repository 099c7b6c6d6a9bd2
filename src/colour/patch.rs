//! The colorimeter of a flat patch described by a reradiation matrix (model.md §7).

use std::sync::OnceLock;

use super::{Lab, Light, Xyz, cie1931, xyz_to_lab};
use crate::measurement::Measurement;
use crate::spectrum::hat_integrals_with;

/// Colorimeter for a flat patch described by a reradiation matrix on fixed grids under one
/// light (model.md §7). The light and the observer are projected onto the grids' hat
/// functions once, so the colour of any matrix on these grids is two small sums. It is
/// exact for spectra linear between the grid's samples, which is how fluorite reads a
/// matrix.
#[derive(Debug, Clone)]
pub struct PatchColorimeter {
    /// The light's name.
    pub light: String,
    /// ∫L·h_i over the excitation grid.
    light_weights: Vec<f64>,
    /// (∫L·h_i)·(∫x̄·h_j)/Δλ_j for the diagonal cell of emission sample j (i its
    /// excitation sample; the emission grid's own ∫L·h_j where there is none).
    reflected_weights: Vec<Xyz>,
    /// ∫x̄·h_j over the emission grid (emitted light, density per nm).
    emitted_weights: Vec<Xyz>,
    emission_bin_widths: Vec<f64>,
    excitation_nm: Vec<f64>,
    emission_nm: Vec<f64>,
    /// XYZ of the perfect white (no fluorescence) on the emission grid, scaled to Y = 100.
    pub white: Xyz,
    scale: f64,
}

impl PatchColorimeter {
    /// Prepares the weights for `light` on the given grids.
    pub fn new(light: &Light, excitation_nm: &[f64], emission_nm: &[f64]) -> Self {
        let observer = cie1931();
        // Substeps small enough that a 10 nm FWHM LED is resolved on a 10 nm grid: about
        // 0.25 nm over the grid's mean spacing, and no more than an interval's own length
        // needs at 0.25 nm (the same count on a uniform grid; far fewer on the short
        // intervals of a grid with one very wide one).
        let sub = |grid: &[f64]| {
            let span = grid.last().unwrap_or(&0.0) - grid.first().unwrap_or(&0.0);
            let mean = ((span / grid.len().max(2) as f64) / 0.25).ceil().max(4.0) as usize;
            move |interval_nm: f64| mean.min((interval_nm / 0.25).ceil().max(4.0) as usize)
        };
        let light_weights =
            hat_integrals_with(excitation_nm, |l| light.power(l), sub(excitation_nm));
        let channel =
            |c: usize| hat_integrals_with(emission_nm, |l| observer.at(l)[c], sub(emission_nm));
        let zip3 = |x: Vec<f64>, y: Vec<f64>, z: Vec<f64>| -> Vec<Xyz> {
            x.into_iter()
                .zip(y)
                .zip(z)
                .map(|((x, y), z)| [x, y, z])
                .collect()
        };
        let emitted_weights = zip3(channel(0), channel(1), channel(2));
        let emission_bin_widths = crate::spectrum::bin_widths(emission_nm);
        // Every cell, the diagonal included, sees the light through the excitation
        // bandpass and is seen through the emission bandpass (model.md §7: per emission
        // bin Σi L(λi)·Δλi·M[λi, λo] / Δλo, with L and x̄ each projected on the grid's
        // hats). Projecting the product L·x̄ for the diagonal instead differs under a line
        // spectrum: 0.10 ΔE2000 on CIBA12 under F11, against an evaluator written from
        // model.md.
        let emission_light = hat_integrals_with(emission_nm, |l| light.power(l), sub(emission_nm));
        let per_nm =
            |j: usize, lw: f64| emitted_weights[j].map(|w| w * lw / emission_bin_widths[j]);
        let reflected_weights: Vec<Xyz> = emission_nm
            .iter()
            .enumerate()
            .map(|(j, &nm)| {
                let lw = crate::spectrum::find_wavelength(excitation_nm, nm)
                    .map_or(emission_light[j], |i| light_weights[i]);
                per_nm(j, lw)
            })
            .collect();
        // The perfect white: a matrix whose diagonal is 1 (L* = 100 exactly; where the
        // emission grid starts inside the excitation grid this takes the excitation hat
        // of the first bin, as the diagonal cell does).
        let mut white = [0.0; 3];
        for w in &reflected_weights {
            for c in 0..3 {
                white[c] += w[c];
            }
        }
        let scale = if white[1] > 0.0 {
            100.0 / white[1]
        } else {
            1.0
        };
        PatchColorimeter {
            light: light.name.clone(),
            light_weights,
            reflected_weights,
            emitted_weights,
            emission_bin_widths,
            excitation_nm: excitation_nm.to_vec(),
            emission_nm: emission_nm.to_vec(),
            white: white.map(|v| v * scale),
            scale,
        }
    }

    /// A shared colorimeter for `light` on these grids, built once per process and reused:
    /// fits of many files on the same instrument grid share the light's projection.
    ///
    /// A fit asks for it several times per light, so the lookup is cheap: a hash of the
    /// light's name and of a few samples of each array (SipHash over all ~1,200 values was
    /// a third of the time the fit report's colour-noise figure took, perf), then an exact
    /// comparison of every value with the entry's, so that lights or grids that share the
    /// hash never share a colorimeter.
    pub fn cached(
        light: &Light,
        excitation_nm: &[f64],
        emission_nm: &[f64],
    ) -> std::sync::Arc<PatchColorimeter> {
        use std::collections::HashMap;
        use std::sync::{Arc, Mutex};
        struct Entry {
            light: Light,
            excitation_nm: Vec<f64>,
            emission_nm: Vec<f64>,
            colorimeter: Arc<PatchColorimeter>,
        }
        let same = |a: &[f64], b: &[f64]| {
            a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
        };
        let matches = |e: &Entry| {
            e.light.name == light.name
                && same(
                    &e.light.spectrum.wavelength_nm,
                    &light.spectrum.wavelength_nm,
                )
                && same(&e.light.spectrum.value, &light.spectrum.value)
                && same(&e.excitation_nm, excitation_nm)
                && same(&e.emission_nm, emission_nm)
        };
        static CACHE: OnceLock<Mutex<HashMap<u64, Vec<Entry>>>> = OnceLock::new();
        let mut key = 0u64;
        let mut mix =
            |bits: u64| key = (key.rotate_left(5) ^ bits).wrapping_mul(0x517c_c1b7_2722_0a95);
        light.name.bytes().for_each(|b| mix(u64::from(b)));
        for part in [
            &light.spectrum.wavelength_nm[..],
            &light.spectrum.value,
            excitation_nm,
            emission_nm,
        ] {
            mix(part.len() as u64);
            let step = (part.len() / 8).max(1);
            part.iter().step_by(step).for_each(|v| mix(v.to_bits()));
        }
        let cache = CACHE.get_or_init(|| Mutex::new(HashMap::new()));
        let found = cache.lock().ok().and_then(|c| {
            let entries = c.get(&key)?;
            Some(entries.iter().find(|e| matches(e))?.colorimeter.clone())
        });
        if let Some(pc) = found {
            return pc;
        }
        let pc = Arc::new(PatchColorimeter::new(light, excitation_nm, emission_nm));
        if let Ok(mut c) = cache.lock() {
            // Bounded: a process sees few grids; drop all if something churns through many.
            if c.len() > 256 {
                c.clear();
            }
            let entries = c.entry(key).or_default();
            match entries.iter().find(|e| matches(e)) {
                // Another thread built it meanwhile: share that one.
                Some(e) => return e.colorimeter.clone(),
                None => entries.push(Entry {
                    light: light.clone(),
                    excitation_nm: excitation_nm.to_vec(),
                    emission_nm: emission_nm.to_vec(),
                    colorimeter: pc.clone(),
                }),
            }
        }
        pc
    }

    /// XYZ (white Y = 100) of a patch whose diagonal reflectance is `diagonal[j]` at
    /// emission sample j and whose reradiation (per emission bin, off the diagonal) is
    /// `fluorescence(i, j)`. NaN cells count as zero.
    pub fn xyz_from(&self, diagonal: &[f64], fluorescence: impl Fn(usize, usize) -> f64) -> Xyz {
        let mut xyz = [0.0; 3];
        for (j, w) in self.reflected_weights.iter().enumerate() {
            let d = diagonal.get(j).copied().unwrap_or(0.0);
            if d.is_finite() {
                for c in 0..3 {
                    xyz[c] += d * w[c];
                }
            }
        }
        for (j, w) in self.emitted_weights.iter().enumerate() {
            let mut emitted = 0.0;
            for (i, lw) in self.light_weights.iter().enumerate() {
                let v = fluorescence(i, j);
                if v.is_finite() {
                    emitted += lw * v;
                }
            }
            let density = emitted / self.emission_bin_widths[j];
            for c in 0..3 {
                xyz[c] += density * w[c];
            }
        }
        xyz.map(|v| v * self.scale)
    }

    /// XYZ of the patch a measured (or predicted) matrix describes. The matrix must be
    /// on this colorimeter's grids and expressed per bin; its diagonal cells give the
    /// reflected part, every other cell the reradiated part (missing cells count as zero).
    pub fn xyz(&self, m: &Measurement) -> Xyz {
        debug_assert_eq!(m.excitation_nm, self.excitation_nm);
        debug_assert_eq!(m.emission_nm, self.emission_nm);
        let diag = m.diagonal();
        let mut diagonal = vec![0.0; self.emission_nm.len()];
        let mut is_diag = vec![usize::MAX; self.emission_nm.len()];
        for &(i, j) in &diag {
            diagonal[j] = m.get(i, j);
            is_diag[j] = i;
        }
        self.xyz_from(
            &diagonal,
            |i, j| if is_diag[j] == i { 0.0 } else { m.get(i, j) },
        )
    }

    /// The projections behind [`PatchColorimeter::xyz_from`]: ∫L·h_i per excitation
    /// sample, the diagonal's weights and ∫x̄·h_j per emission sample, the emission bin widths and the
    /// factor scaling the white to Y = 100. XYZ is linear in the matrix with these
    /// weights, which is what a fit needs to differentiate colour.
    pub fn weights(&self) -> (&[f64], &[Xyz], &[Xyz], &[f64], f64) {
        (
            &self.light_weights,
            &self.reflected_weights,
            &self.emitted_weights,
            &self.emission_bin_widths,
            self.scale,
        )
    }

    /// CIELAB of the patch a matrix describes, against the perfect white under this light.
    pub fn lab(&self, m: &Measurement) -> Lab {
        xyz_to_lab(self.xyz(m), self.white)
    }
}
