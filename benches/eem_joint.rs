//! Joint-fit speed: the classic Dorrit PARAFAC (23 EEMs, emission 250–681 nm,
//! excitation 230–315 nm, four components, one closed-form start), the fit alone and with
//! its diagnostics (core consistency, split-half).
//!
//! `cargo bench --bench eem_joint`. Needs ../shared/data/eem-instrument/dorrit; says so
//! and benchmarks nothing when it is absent.

#[path = "../tests/suite/common/mod.rs"]
mod common;

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use fluorite::fit::joint::fit_joint;
use fluorite::measurement::Measurement;

fn bench_joint(c: &mut Criterion) {
    let Some(set) = common::dorrit_classic() else {
        return;
    };
    let set: Vec<Measurement> = set.into_iter().map(|(_, m)| m).collect();
    let options = common::dorrit_classic_options(false);
    let mut group = c.benchmark_group("eem_joint");
    group.sample_size(20);
    group.bench_function("dorrit/k4/fit", |b| {
        b.iter(|| fit_joint(black_box(&set), &options).unwrap())
    });
    let with_diagnostics = common::dorrit_classic_options(true);
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
