//! Parsing speed of the input formats on a 49 × 41 BFC-450-sized matrix.

#[path = "../tests/suite/common/mod.rs"]
mod common;

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use fluorite::Measurement;
use fluorite::formats::{
    ReadOptions, RowsAre, read_bytes, write_bfc, write_long_csv, write_wide_csv,
};
use fluorite::measurement::Units;
use fluorite::spectrum::uniform_grid;

/// A 49 excitation × 41 emission matrix with full-precision values.
fn matrix() -> Measurement {
    let excitation = uniform_grid(300.0, 780.0, 10.0);
    let emission = uniform_grid(380.0, 780.0, 10.0);
    let values = (0..excitation.len() * emission.len())
        .map(|k| 0.003 * (k as f64 * 0.7).sin())
        .collect();
    Measurement::new("bench", excitation, emission, values, Units::PerBin).unwrap()
}

fn bench_formats(c: &mut Criterion) {
    let m = matrix();
    let options = ReadOptions::default();
    let files = [
        ("bfc_49x41", write_bfc(&m).unwrap(), "m.BFC"),
        (
            "wide_csv_49x41",
            write_wide_csv(&m, RowsAre::Emission),
            "m.csv",
        ),
        ("long_csv_49x41", write_long_csv(&m), "m.csv"),
    ];
    for (name, text, file) in &files {
        c.bench_function(&format!("read_{name}"), |b| {
            b.iter(|| read_bytes(black_box(text.as_bytes()), Path::new(file), &options).unwrap())
        });
    }
    if let Some(real) = common::measured("HERPICER.BFC") {
        let bytes = std::fs::read(&real).unwrap();
        c.bench_function("read_HERPICER_BFC", |b| {
            b.iter(|| read_bytes(black_box(&bytes), &real, &options).unwrap())
        });
    }
}

criterion_group! {
    name = benches;
    // Plots need system fonts, which the machines lack; the numbers are what matters.
    config = Criterion::default().without_plots();
    targets = bench_formats
}
criterion_main!(benches);
