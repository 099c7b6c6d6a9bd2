//! Speed of the parametric-form fits, which also seed the matrix fit (a 50 ms budget for
//! the whole model search): two Gaussian bands on 50 samples, a degree-6 sigmoid
//! polynomial on 41 samples, and the dye curves of ../shared/data/spectra when present.
//!
//! `cargo bench --bench parametric`.

#[path = "../tests/suite/common/mod.rs"]
mod common;

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use fluorite::import::read_spectrum;
use fluorite::parametric::fit::{
    fit_bands, fit_bands_to_tolerance, fit_sigmoid_polynomial, positive_range,
};
use fluorite::parametric::{BandDomain, GaussianBand, GaussianBands};

/// A deterministic ripple of about ±`amplitude` standing in for measurement noise.
fn ripple(i: usize, amplitude: f64) -> f64 {
    amplitude * ((i as f64 * 12.9898).sin() * 43758.5453).fract()
}

/// 50 samples (10 nm) of an emission-like curve: two overlapping bands and 0.5 % noise.
fn emission_samples() -> (Vec<f64>, Vec<f64>) {
    let nm: Vec<f64> = (0..50).map(|i| 300.0 + 10.0 * i as f64).collect();
    let bands = GaussianBands {
        domain: BandDomain::Wavenumber,
        support_nm: [300.0, 790.0],
        bands: vec![
            GaussianBand {
                centre_nm: 520.0,
                width: 900.0,
                height: 1.0,
            },
            GaussianBand {
                centre_nm: 560.0,
                width: 1400.0,
                height: 0.4,
            },
        ],
    };
    let values = nm
        .iter()
        .enumerate()
        .map(|(i, &l)| bands.eval(l) + ripple(i, 0.005))
        .collect();
    (nm, values)
}

/// 41 samples (10 nm, 380–780) of a yellow-pigment-like reflectance with 0.5 % noise.
fn reflectance_samples() -> (Vec<f64>, Vec<f64>) {
    let nm: Vec<f64> = (0..41).map(|i| 380.0 + 10.0 * i as f64).collect();
    let values = nm
        .iter()
        .enumerate()
        .map(|(i, &l)| 0.05 + 0.8 / (1.0 + (-(l - 500.0) / 15.0).exp()) + ripple(i, 0.005))
        .collect();
    (nm, values)
}

fn bench_parametric(c: &mut Criterion) {
    let (nm, values) = emission_samples();
    for domain in [BandDomain::Wavenumber, BandDomain::Wavelength] {
        c.bench_function(
            &format!("fit_bands_50_samples_2_bands_{}", domain.name()),
            |b| b.iter(|| fit_bands(black_box(&nm), black_box(&values), domain, 2).unwrap()),
        );
    }
    let (nm, values) = reflectance_samples();
    c.bench_function("fit_sigmoid_polynomial_41_samples_degree_6", |b| {
        b.iter(|| fit_sigmoid_polynomial(black_box(&nm), black_box(&values), None, 6).unwrap())
    });
    let Some(dye) = common::shared("spectra/fluorescein_0.1MNaOH_wave_excitation_emission.csv")
    else {
        return;
    };
    let s = read_spectrum(&dye, Some("emission"), &[]).unwrap();
    let range = positive_range(&s.value).unwrap();
    let (nm, values) = (&s.wavelength_nm[range.clone()], &s.value[range]);
    c.bench_function("fit_bands_to_tolerance_fluorescein_emission", |b| {
        b.iter(|| fit_bands_to_tolerance(nm, values, BandDomain::Wavenumber, 6, 0.01).unwrap())
    });
}

criterion_group! {
    name = benches;
    // No plots: criterion's plotters backend would need a system font.
    config = Criterion::default().without_plots();
    targets = bench_parametric
}
criterion_main!(benches);
