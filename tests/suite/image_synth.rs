//! `fluorite synth --image`: bispectral images with known truth. The images are read
//! back with the streaming reader and graded against truth computed apart from the
//! generator: each pixel's material from the material map, its matrix from
//! `model::predict`, its laws from `check`, its colour from the patch colorimeter.

use crate::common;

use std::path::Path;

use fluorite::colour::{Light, PatchColorimeter, delta_e2000, xyz_to_lab};
use fluorite::image::map::LoadedTextures;
use fluorite::image::{Cell, ExrImage, MaterialMap};
use fluorite::measurement::Units;
use fluorite::model::predict;
use fluorite::spectrum::{find_wavelength, uniform_grid};

use common::repository;

/// Runs `fluorite synth --image --out <fresh folder> ARGS` from the repository's root
/// (so the default materials are found) and returns the folder.
#[track_caller]
fn generate(tag: &str, args: &[&str]) -> common::TempDir {
    let out = common::temp_dir(tag);
    let out_text = out.display().to_string();
    let mut all = vec!["synth", "--image", "--quiet", "--out", &out_text];
    all.extend_from_slice(args);
    common::succeed(common::fluorite().args(&all).current_dir(repository()));
    out
}

/// Every pixel's cells, in image order (pixel-major, canonical cell order).
fn read_cells(path: &Path) -> (ExrImage, Vec<f32>) {
    let image = ExrImage::open(path).unwrap();
    let cells = image.layout.len();
    let mut all = vec![f32::NAN; image.pixels() * cells];
    image
        .pass(
            |block| Ok(block.clone()),
            |block| {
                for p in 0..block.pixel_count() {
                    let i = block.image_index(p, image.width);
                    all[i * cells..(i + 1) * cells].copy_from_slice(block.pixel(p));
                }
                Ok(())
            },
            |_| {},
        )
        .unwrap();
    assert!(all.iter().all(|v| v.is_finite()), "every cell was read");
    (image, all)
}

/// The truth material map of `out/NAME.truth/` and its textures.
fn truth_map(out: &Path, name: &str) -> (MaterialMap, LoadedTextures) {
    let json = out.join(format!("{name}.truth/material-map.json"));
    let map = MaterialMap::load(&json).unwrap();
    let textures = map.load_textures(&json).unwrap();
    (map, textures)
}

fn bfc_grids() -> (Vec<f64>, Vec<f64>) {
    (
        uniform_grid(300.0, 780.0, 10.0),
        uniform_grid(380.0, 780.0, 10.0),
    )
}

/// Per cell of `image`'s layout, its (excitation, emission) indices on the BFC grids.
fn grid_of(image: &ExrImage) -> Vec<(usize, usize)> {
    let (ex, em) = bfc_grids();
    let l = &image.layout;
    l.cells
        .iter()
        .map(|&c| {
            let (i, o) = match c {
                Cell::Diagonal(w) => (w, w),
                Cell::Reradiation(i, o) => (i, o),
            };
            (
                find_wavelength(&ex, l.wavelengths[i]).unwrap(),
                find_wavelength(&em, l.wavelengths[o]).unwrap(),
            )
        })
        .collect()
}

/// The material of pixel `p` as the map describes it.
fn material(map: &MaterialMap, t: &LoadedTextures, p: usize) -> fluorite::Material {
    let k = map.fluorophores.len();
    let n = t.wavelengths.len();
    map.material_at(
        &t.concentration[p * k..(p + 1) * k],
        &t.wavelengths,
        &t.reflectance[p * n..(p + 1) * n],
    )
    .unwrap()
}

/// The truth image equals, cell by cell within f32 rounding, the matrix `model::predict`
/// gives for the material the map holds at each pixel.
fn assert_truth_is_the_maps_prediction(out: &Path, width: usize, height: usize) {
    let (image, cells) = read_cells(&out.join("image.truth.exr"));
    assert_eq!((image.width, image.height), (width, height));
    assert!(!image.half);
    let (map, textures) = truth_map(out, "image");
    assert_eq!((textures.width, textures.height), (width, height));
    let n = image.layout.len();
    assert_eq!(
        n, 1189,
        "the BFC-450 layout: 41 diagonal and 1148 reradiation cells"
    );
    let (ex, em) = bfc_grids();
    let at = grid_of(&image);
    let mut worst: f64 = 0.0;
    for p in 0..width * height {
        let m = predict(
            &material(&map, &textures, p),
            "p",
            &ex,
            &em,
            Units::PerBin,
            true,
        );
        for (c, &(i, j)) in at.iter().enumerate() {
            let expected = m.get(i, j);
            let got = f64::from(cells[p * n + c]);
            let error = (got - expected).abs() / expected.abs().max(1e-30);
            assert!(
                (got - expected).abs() <= 1.2e-7 * expected.abs() + 1e-15,
                "pixel {p} cell {c} ({}): file {got}, map's prediction {expected}",
                image.layout.channel_name(image.layout.cells[c])
            );
            worst = worst.max(error);
        }
    }
    assert!(worst > 0.0 || cells.iter().all(|&v| v == 0.0));
}

#[test]
fn the_truth_image_is_the_material_maps_matrix_at_every_pixel() {
    let out = generate("truth", &["--size", "32x24"]);
    assert_truth_is_the_maps_prediction(&out, 32, 24);
    // The map's fluorophores are the default sources', each at its largest concentration.
    let (map, t) = truth_map(&out, "image");
    let k = map.fluorophores.len();
    assert_eq!(k, 3);
    for (f, source) in map
        .fluorophores
        .iter()
        .zip(["CIBA12", "TEXTYELL", "postit_pink"])
    {
        let fit = fluorite::Material::load(
            &repository().join(format!("fits/measured/grid/{source}.json")),
        )
        .unwrap();
        let s = &fit.fluorophores[0];
        assert_eq!(
            (f.quantum_yield, f.yield_form),
            (s.quantum_yield, s.yield_form)
        );
        assert_eq!(f.absorption, s.absorption);
        assert_eq!(f.emission, s.emission);
        assert!(f.concentration > 0.0 && f.concentration <= s.concentration);
    }
    for j in 0..k {
        let max = (0..t.width * t.height)
            .map(|p| t.concentration[p * k + j])
            .fold(0f32, f32::max);
        assert_eq!(f64::from(max), map.fluorophores[j].concentration);
    }
}

#[test]
fn tiles_meet_without_seams_in_a_non_square_image() {
    // 72 columns: two tiles across, the second 8 pixels wide.
    let out = generate("tiles", &["--size", "72x20", "--seed", "3"]);
    assert_truth_is_the_maps_prediction(&out, 72, 20);
}

#[test]
fn the_noise_has_the_requested_standard_deviation() {
    let out = generate(
        "noise",
        &["--size", "32x24", "--noise", "0.002", "--seed", "5"],
    );
    let (_, truth) = read_cells(&out.join("image.truth.exr"));
    let (_, noisy) = read_cells(&out.join("image.exr"));
    let n = truth.len() as f64;
    let d: Vec<f64> = noisy
        .iter()
        .zip(&truth)
        .map(|(a, b)| f64::from(*a) - f64::from(*b))
        .collect();
    let mean = d.iter().sum::<f64>() / n;
    let sd = (d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    // 913,000 cells: the standard error of the σ estimate is 0.07 %, of the mean 2e-6.
    assert!((sd / 0.002 - 1.0).abs() < 0.01, "σ = {sd}");
    assert!(mean.abs() < 5.0 * 0.002 / n.sqrt(), "mean {mean}");
    // Gaussian: 4.55 % of the cells lie beyond 2σ.
    let beyond = d.iter().filter(|v| v.abs() > 0.004).count() as f64 / n;
    assert!((beyond - 0.0455).abs() < 0.002, "{beyond}");
}

#[test]
fn every_pixel_conserves_energy_and_photons() {
    let out = generate("laws", &["--size", "32x24"]);
    // HERPICER's fluorophore has the photon form with Φ = 1: above its mean emission
    // wavelength it reradiates more energy than it absorbs, so the reflectance must give.
    let fits = repository().join("fits/measured");
    let sources = format!(
        "{},{}",
        fits.join("HERPICER.json").display(),
        fits.join("CIBA12.json").display()
    );
    let photon = generate("laws-photon", &["--size", "24x16", "--material", &sources]);
    for (out, pixels) in [(&out, 32 * 24), (&photon, 24 * 16)] {
        let (map, t) = truth_map(out, "image");
        for p in 0..pixels {
            let m = material(&map, &t, p);
            let report = fluorite::check::check_material(&m);
            assert!(
                report.valid,
                "{}: pixel {p} breaks {}",
                out.display(),
                report.failed_names()
            );
            m.validate().unwrap();
        }
    }
}

#[test]
fn a_region_without_fluorescence_has_no_reradiation() {
    let out = generate("plain", &["--size", "40x24"]);
    let (image, cells) = read_cells(&out.join("image.truth.exr"));
    let (map, t) = truth_map(&out, "image");
    let k = map.fluorophores.len();
    let n = image.layout.len();
    let diagonal = image.layout.diagonal_count;
    let mut plain = 0;
    let mut fluorescent = 0;
    for p in 0..t.width * t.height {
        let pixel = &cells[p * n..(p + 1) * n];
        if t.concentration[p * k..(p + 1) * k]
            .iter()
            .all(|&c| c == 0.0)
        {
            plain += 1;
            assert!(pixel[diagonal..].iter().all(|&v| v == 0.0), "pixel {p}");
            // The diagonal is the reflectance itself.
            assert_eq!(
                &pixel[..diagonal],
                &t.reflectance[p * diagonal..(p + 1) * diagonal]
            );
        } else if pixel[diagonal..].iter().any(|&v| v > 1e-4) {
            fluorescent += 1;
        }
    }
    // The strip right of 0.8 × 40 = 32 px holds none: 8 columns of 24 pixels at least.
    assert!(plain >= 8 * 24, "{plain} plain pixels");
    assert!(fluorescent >= 100, "{fluorescent} fluorescent pixels");
    for x in 32..40 {
        let p = 10 * 40 + x;
        assert!(
            t.concentration[p * k..(p + 1) * k]
                .iter()
                .all(|&c| c == 0.0)
        );
    }
}

#[test]
fn half_floats_round_trip_within_their_precision() {
    let full = generate("full", &["--size", "24x16", "--seed", "9"]);
    let half = generate("half", &["--size", "24x16", "--seed", "9", "--half"]);
    for file in ["image.truth.exr", "image.exr"] {
        let (f_image, f) = read_cells(&full.join(file));
        let (h_image, h) = read_cells(&half.join(file));
        assert!(h_image.half && !f_image.half);
        assert_eq!(h_image.layout, f_image.layout);
        for (a, b) in f.iter().zip(&h) {
            // Half floats: 11 significant bits, subnormal below 2^-14 with step 2^-24.
            let bound = a.abs() * 2f32.powi(-11) + 2f32.powi(-25);
            assert!((a - b).abs() <= bound, "{file}: {a} stored as {b}");
        }
    }
    let size = |dir: &Path| std::fs::metadata(dir.join("image.exr")).unwrap().len();
    assert!(
        size(&half) * 10 < size(&full) * 6,
        "half the bytes, plus the header"
    );
}

#[test]
fn zip_compression_is_lossless() {
    let plain = generate("unzipped", &["--size", "24x16", "--seed", "4"]);
    let zipped = generate("zipped", &["--size", "24x16", "--seed", "4", "--zip"]);
    for file in ["image.truth.exr", "image.exr"] {
        assert_eq!(
            read_cells(&plain.join(file)).1,
            read_cells(&zipped.join(file)).1
        );
    }
    let size = |dir: &Path| {
        std::fs::metadata(dir.join("image.truth.exr"))
            .unwrap()
            .len()
    };
    assert!(size(&zipped) < size(&plain));
}

#[test]
fn the_same_seed_writes_byte_identical_files() {
    let args = ["--size", "20x12", "--seed", "7"];
    let a = generate("seed-a", &args);
    let b = generate("seed-b", &args);
    let c = generate("seed-c", &["--size", "20x12", "--seed", "8"]);
    let files = [
        "image.exr",
        "image.truth.exr",
        "image.synth.json",
        "image.truth/material-map.json",
        "image.truth/concentration.exr",
        "image.truth/reflectance.exr",
    ];
    for file in files {
        let read = |dir: &Path| std::fs::read(dir.join(file)).unwrap();
        assert!(read(&a) == read(&b), "{file} differs between two runs");
    }
    let noisy = |dir: &Path| std::fs::read(dir.join("image.exr")).unwrap();
    assert!(noisy(&a) != noisy(&c), "another seed, another image");
}

#[test]
fn the_noises_colour_difference_is_reported_as_measured() {
    let out = generate("colour", &["--size", "32x24"]);
    let record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("image.synth.json")).unwrap())
            .unwrap();
    assert_eq!(record["schema"], "fluorite-image-synth/1");
    assert_eq!(record["noise_sigma"], 0.0006);
    let (image, truth) = read_cells(&out.join("image.truth.exr"));
    let (_, noisy) = read_cells(&out.join("image.exr"));
    let (ex, em) = bfc_grids();
    let at = grid_of(&image);
    let n = image.layout.len();
    let diagonal = image.layout.diagonal_count;
    for light in ["d65", "a", "f11"] {
        let colorimeter = PatchColorimeter::new(&Light::builtin(light).unwrap(), &ex, &em);
        // The pixel as a matrix: diagonal by emission index, reradiation by (i, j).
        let lab = |cells: &[f32]| {
            let mut d = vec![0.0; em.len()];
            let mut m = vec![0.0; ex.len() * em.len()];
            for (c, &(i, j)) in at.iter().enumerate() {
                if c < diagonal {
                    d[j] = f64::from(cells[c]);
                } else {
                    m[i * em.len() + j] = f64::from(cells[c]);
                }
            }
            xyz_to_lab(
                colorimeter.xyz_from(&d, |i, j| m[i * em.len() + j]),
                colorimeter.white,
            )
        };
        let mut de: Vec<f64> = (0..image.pixels())
            .map(|p| {
                delta_e2000(
                    lab(&truth[p * n..(p + 1) * n]),
                    lab(&noisy[p * n..(p + 1) * n]),
                )
            })
            .collect();
        de.sort_by(f64::total_cmp);
        for (q, key) in [(0.5, "median"), (0.99, "p99")] {
            let expected = de[((q * de.len() as f64).ceil() as usize).max(1) - 1];
            let reported = record["noise_delta_e2000"][light][key].as_f64().unwrap();
            assert!(
                (reported / expected - 1.0).abs() < 0.0025,
                "{light} {key}: reported {reported}, computed {expected}"
            );
        }
        let max = record["noise_delta_e2000"][light]["max"].as_f64().unwrap();
        assert!((max - de[de.len() - 1]).abs() < 1e-9 * max);
    }
}

#[test]
fn impossible_options_are_refused_naming_the_flag() {
    let out = common::temp_dir("refused");
    let out_text = out.display().to_string();
    for (args, flag) in [
        (vec!["--size", "0x4"], "--size"),
        (vec!["--size", "big"], "--size"),
        (vec!["--noise=-1"], "--noise"),
        (vec!["--material", "no/such.json"], "no/such.json"),
        (vec!["--name", "a/b"], "--name"),
    ] {
        let mut command = common::fluorite();
        command
            .args(["synth", "--image", "--out", &out_text])
            .args(&args)
            .current_dir(repository());
        let (code, message) = common::refused(&mut command);
        assert_eq!(code, Some(2), "{args:?}");
        assert!(message.contains(flag), "{args:?}: {message}");
    }
    // Image flags without --image, and matrix flags with it, are usage errors.
    for args in [
        vec!["synth", "--out", &out_text, "--size", "8"],
        vec!["synth", "--image", "--out", &out_text, "--preset", "plain"],
    ] {
        let o = common::run_in(&args, &repository());
        assert_eq!(o.status.code(), Some(2), "{args:?}");
    }
    assert_eq!(
        std::fs::read_dir(&out).unwrap().count(),
        0,
        "nothing written"
    );
}
