//! Speed of `check` and of every export format on a BFC-450-sized synthetic material
//! (absorption 300–780 nm, emission 380–780 nm, 10 nm).

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use fluorite::check::check_material;
use fluorite::export::{ExportFormat, ExportOptions, export};
use fluorite::spectrum::uniform_grid;
use fluorite::synth::SynthSpec;

fn bench_export(c: &mut Criterion) {
    let (_, material) = SynthSpec::preset("green-dye").unwrap().generate().unwrap();
    c.bench_function("check_material", |b| {
        b.iter(|| check_material(black_box(&material)))
    });
    for (name, format) in [
        ("export_csv", ExportFormat::Csv),
        ("export_matrix_49x41", ExportFormat::Matrix),
        ("export_bfc_49x41", ExportFormat::Bfc),
        ("export_mitsuba", ExportFormat::Mitsuba),
        ("export_pbrt", ExportFormat::Pbrt),
    ] {
        let options = ExportOptions::new(format);
        c.bench_function(name, |b| {
            b.iter(|| export(black_box(&material), &options).unwrap())
        });
    }
    let grid = uniform_grid(300.0, 780.0, 1.0);
    let options = ExportOptions {
        excitation_nm: Some(grid.clone()),
        emission_nm: Some(grid),
        ..ExportOptions::new(ExportFormat::Matrix)
    };
    c.bench_function("export_matrix_481x481", |b| {
        b.iter(|| export(black_box(&material), &options).unwrap())
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().without_plots();
    targets = bench_export
}
criterion_main!(benches);
