//! Image fit speed: the shared fit (model.md §8; sketch, power step and projection
//! passes, the shared fluorophores, the outputs) on a 64 × 64 synthetic image held in
//! memory (`synth --image`'s default scene and materials, BFC-450 grid, measured noise),
//! reported as pixels per second. The fluorophore count is fixed at the scene's three, so
//! each run is one K; outputs go to a fresh temporary folder each run (a reused one would
//! resume).
//!
//! `cargo bench --bench image`. Speed is measured here only, never asserted in tests.

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use fluorite::Material;
use fluorite::image::fit::{ImageFitOptions, fit_image};
use fluorite::image::synth::{DEFAULT_MATERIALS, ImageSynth, ImageSynthOptions, Source};
use fluorite::image::{ArrayImage, PixelSource};

const SIDE: usize = 64;

/// The 64² image `fluorite synth --image --size 64` writes, in memory.
fn image() -> ArrayImage {
    let sources = DEFAULT_MATERIALS
        .iter()
        .map(|path| Source {
            label: path.to_string(),
            material: Material::load(Path::new(path)).expect("the default materials load"),
        })
        .collect();
    let mut options = ImageSynthOptions::new("bench");
    options.width = SIDE;
    options.height = SIDE;
    let synth = ImageSynth::new(options, sources).expect("the scene builds");
    let layout = synth.layout().clone();
    let mut values = Vec::with_capacity(SIDE * SIDE * layout.len());
    let mut cells = vec![0.0; layout.len()];
    for y in 0..SIDE {
        for x in 0..SIDE {
            let truth = synth.pixel(x, y).expect("a pixel's truth");
            synth.truth_cells(&truth, &mut cells);
            synth.add_noise(x, y, &mut cells);
            values.extend(cells.iter().map(|&v| v as f32));
        }
    }
    ArrayImage::new("bench", SIDE, SIDE, layout, values).expect("the image's shape")
}

fn bench_image(c: &mut Criterion) {
    let image = image();
    let options = ImageFitOptions {
        components: Some(3),
        ..ImageFitOptions::default()
    };
    let mut group = c.benchmark_group("image");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(8));
    group.throughput(Throughput::Elements((SIDE * SIDE) as u64));
    group.bench_function("shared-fit/64x64/K=3", |b| {
        b.iter_batched(
            || tempfile::tempdir().expect("a temporary folder"),
            |dir| {
                let fit = fit_image(
                    PixelSource::Array(black_box(&image)),
                    &dir.path().join("fit"),
                    &options,
                    &|_| {},
                )
                .expect("the fit runs");
                (fit, dir)
            },
            BatchSize::PerIteration,
        )
    });
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().without_plots();
    targets = bench_image
}
criterion_main!(benches);
