//! Joint-fit speed: the classic Dorrit PARAFAC (23 EEMs, emission 250–681 nm,
//! excitation 230–315 nm, four components, one closed-form start), the fit alone and with
//! its diagnostics (core consistency, split-half).
//!
//! `cargo bench --bench eem_joint`. Needs ../shared/data/eem-instrument/dorrit; says so
//! and benchmarks nothing when it is absent.

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use fluorite::eem::joint::{JointOptions, fit_joint};
use fluorite::eem::parafac::ParafacOptions;
use fluorite::eem::{EemOptions, prepare};
use fluorite::formats::{ReadOptions, read};
use fluorite::measurement::Measurement;

/// The outliers the classic analysis leaves out (the data README).
const OUTLIERS: [&str; 4] = ["QAB", "QAC", "QAE", "QAA"];

fn dorrit() -> Option<Vec<Measurement>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/eem-instrument/dorrit");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .ok()?
        .map(|e| e.unwrap().path())
        .filter(|p| {
            let stem = p.file_stem().unwrap().to_string_lossy().to_string();
            stem != "concentrations" && !OUTLIERS.contains(&stem.as_str())
        })
        .collect();
    files.sort();
    Some(
        files
            .iter()
            .map(|p| {
                let m = read(p, &ReadOptions::default()).unwrap();
                prepare(m, &EemOptions::default()).unwrap().0
            })
            .collect(),
    )
}

fn bench_joint(c: &mut Criterion) {
    let Some(set) = dorrit() else {
        eprintln!("../shared/data/eem-instrument/dorrit absent: nothing to benchmark");
        return;
    };
    let options = JointOptions {
        parafac: ParafacOptions {
            components: 4,
            ..ParafacOptions::default()
        },
        em_range: Some((250.0, 681.0)),
        ex_range: Some((230.0, 315.0)),
        no_split_half: true,
    };
    let mut group = c.benchmark_group("eem_joint");
    group.sample_size(20);
    group.bench_function("dorrit/k4/fit", |b| {
        b.iter(|| fit_joint(black_box(&set), &options).unwrap())
    });
    let with_diagnostics = JointOptions {
        no_split_half: false,
        ..options.clone()
    };
    group.bench_function("dorrit/k4/fit+diagnostics", |b| {
        b.iter(|| fit_joint(black_box(&set), &with_diagnostics).unwrap())
    });
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().without_plots();
    targets = bench_joint
}
criterion_main!(benches);
