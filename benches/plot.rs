//! Rendering cost of the four fit figures for a BFC-450-sized synthetic fit (49 × 41
//! cells), PNG and SVG.

use criterion::{Criterion, criterion_group, criterion_main};
use fluorite::material::FitReport;
use fluorite::plot::{self, ImageFormat, PlotOptions};
use fluorite::spectrum::{Spectrum, bin_widths, uniform_grid};
use fluorite::{Fluorophore, Material, Units, model};

fn synthetic() -> (Material, fluorite::Measurement) {
    let ex = uniform_grid(300.0, 780.0, 10.0);
    let em = uniform_grid(380.0, 780.0, 10.0);
    let gauss = |g: &[f64], c: f64, s: f64| -> Vec<f64> {
        g.iter()
            .map(|l| (-0.5 * ((l - c) / s).powi(2)).exp())
            .collect()
    };
    let a = gauss(&ex, 460.0, 40.0);
    let peak = a.iter().cloned().fold(0.0, f64::max);
    let a: Vec<f64> = a.iter().map(|v| v / peak).collect();
    let e = gauss(&em, 570.0, 30.0);
    let area: f64 = e.iter().zip(bin_widths(&em)).map(|(v, w)| v * w).sum();
    let e: Vec<f64> = e.iter().map(|v| v / area).collect();
    let r = vec![0.5; em.len()];
    let mut material = Material::new(
        "BENCH",
        Spectrum::new(em.clone(), r, "r").unwrap(),
        vec![Fluorophore {
            concentration: 0.6,
            quantum_yield: 0.5,
            yield_form: fluorite::YieldForm::Energy,
            concentration_range: None,
            absorption: Spectrum::new(ex.clone(), a, "a").unwrap(),
            emission: Spectrum::new(em.clone(), e, "e").unwrap(),
        }],
    );
    material.fit = Some(FitReport {
        solver: "lbfgs".to_string(),
        guard_nm: 10.0,
        cost_history: (0..50).map(|n| 0.9f64.powi(n)).collect(),
        ..FitReport::default()
    });
    let mut m = model::predict(&material, "BENCH", &ex, &em, Units::PerBin, true);
    for (k, v) in m.values.iter_mut().enumerate() {
        *v += 0.002 * ((k * 7919 % 1000) as f64 / 1000.0 - 0.5);
    }
    (material, m)
}

fn bench_plot(c: &mut Criterion) {
    let (material, measured) = synthetic();
    for (name, format) in [("png", ImageFormat::Png), ("svg", ImageFormat::Svg)] {
        let options = PlotOptions {
            format,
            guard_nm: None,
        };
        c.bench_function(&format!("plot/all_figures_{name}"), |b| {
            b.iter(|| plot::plot(&material, Some(&measured), &options).unwrap())
        });
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench_plot
}
criterion_main!(benches);
