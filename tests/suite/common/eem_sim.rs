//! Simulated solution EEMs for the joint-fit tests: the instrument's grids, Gaussian bands,
//! a small deterministic random stream, and one set of samples built from a signal the
//! test defines (fluorescence, scatter) plus 1 % uniform noise. Written apart from the
//! library: nothing here calls fluorite but `Measurement::new`.

use fluorite::measurement::{Measurement, Units};

/// Excitation 230–320 nm by 5, emission 250–700 nm by 2 (the Dorrit set's span).
pub fn grids() -> (Vec<f64>, Vec<f64>) {
    let ex = (0..19).map(|i| 230.0 + 5.0 * i as f64).collect();
    let em = (0..226).map(|i| 250.0 + 2.0 * i as f64).collect();
    (ex, em)
}

/// A Gaussian band of peak 1 at `mu`, full width at half maximum `fwhm`.
pub fn gauss(x: f64, mu: f64, fwhm: f64) -> f64 {
    let s = fwhm / 2.3548;
    (-(x - mu).powi(2) / (2.0 * s * s)).exp()
}

/// A 64-bit linear congruential stream (Knuth's MMIX constants), uniform in [0, 1).
pub struct Lcg(u64);

impl Lcg {
    /// A stream for `seed` (any value, 0 included).
    pub fn new(seed: u64) -> Self {
        Lcg(seed.wrapping_mul(0x9E3779B97F4A7C15) | 1)
    }

    /// The next value in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Squared Pearson correlation (written out here, apart from the library's).
pub fn pearson_squared(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx).powi(2)).sum();
    let syy: f64 = y.iter().map(|b| (b - my).powi(2)).sum();
    sxy * sxy / (sxx * syy)
}

/// One matrix per sample of `truth` (its concentrations) on [`grids`], named
/// `{prefix}{index}`: each sample draws its Rayleigh strength (300 × U(0.3, 2.3)), then each
/// cell is `signal(concentrations, rayleigh, λi, λo)` plus uniform noise of σ 0.1.
pub fn simulate(
    prefix: &str,
    truth: &[Vec<f64>],
    rng: &mut Lcg,
    signal: impl Fn(&[f64], f64, f64, f64) -> f64,
) -> Vec<Measurement> {
    let (ex, em) = grids();
    truth
        .iter()
        .enumerate()
        .map(|(s, conc)| {
            let rayleigh = 300.0 * (0.3 + 2.0 * rng.uniform());
            let mut values = Vec::with_capacity(ex.len() * em.len());
            for &x in &ex {
                for &l in &em {
                    let noise = (rng.uniform() - 0.5) * 12f64.sqrt() * 0.01 * 10.0;
                    values.push(signal(conc, rayleigh, x, l) + noise);
                }
            }
            Measurement::new(
                format!("{prefix}{s}"),
                ex.clone(),
                em.clone(),
                values,
                Units::PerBin,
            )
            .unwrap()
        })
        .collect()
}
