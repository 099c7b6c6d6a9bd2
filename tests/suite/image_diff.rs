//! `fluorite image-diff`: two bispectral images compared pixel by pixel, checked against
//! colours computed here from each pixel's matrix with the patch colorimeter `fluorite
//! fit` judges a bispectral EXR by (one grid, missing cells zero), never against the
//! command's own weights.

use std::path::Path;

use fluorite::colour::{Light, PatchColorimeter, delta_e2000};
use fluorite::image::layout::{Cell, Layout};
use fluorite::image::sink::{ImageSpec, write_image};
use fluorite::material::Material;
use fluorite::measurement::{Measurement, Units};

use crate::common::map::write_map;
use crate::common::{fluorite, refused, succeed, temp_dir};

const LIGHTS: [&str; 4] = ["d65", "a", "f11", "uv"];

/// The BFC-450 grid: excitation 300–780 nm, emission 380–780 nm, 10 nm (its one grid
/// holds cells the layout lacks: below 380 nm there is no diagonal).
fn bfc_layout() -> Layout {
    let ex: Vec<f64> = (0..49).map(|i| 300.0 + 10.0 * i as f64).collect();
    let em: Vec<f64> = (0..41).map(|i| 380.0 + 10.0 * i as f64).collect();
    Layout::from_grids(&ex, &em).unwrap()
}

/// The green-dye example's matrix at concentration scale `s` on the layout's cells.
fn dye_cells(layout: &Layout, s: f64) -> Vec<f64> {
    let mut m = Material::load(Path::new("data/green-dye.truth.json")).unwrap();
    m.fluorophores[0].concentration *= s;
    let grid = &layout.wavelengths;
    let matrix = fluorite::model::predict(&m, "dye", grid, grid, Units::PerBin, true);
    layout
        .cells
        .iter()
        .map(|c| match *c {
            Cell::Diagonal(i) => matrix.get(i, i),
            Cell::Reradiation(i, o) => matrix.get(i, o),
        })
        .collect()
}

/// Writes an image of `size` on `layout`, pixel (x, y) holding `pixel(x, y)`.
fn write(
    path: &Path,
    layout: &Layout,
    size: (usize, usize),
    pixel: &(dyn Fn(usize, usize) -> Vec<f64> + Sync),
) {
    let spec = ImageSpec {
        width: size.0,
        height: size.1,
        channels: layout.channel_names(),
        half: false,
        zip: false,
        attributes: Vec::new(),
    };
    write_image(
        path,
        &spec,
        |rect| {
            let mut v = Vec::new();
            for y in rect.y..rect.y + rect.height {
                for x in rect.x..rect.x + rect.width {
                    v.extend(pixel(x, y).into_iter().map(|c| c as f32));
                }
            }
            Ok(v)
        },
        |_, _| {},
    )
    .unwrap();
}

/// A pixel's cells as the matrix `fluorite fit` reads from the EXR: the layout's one
/// grid on both axes, the cells it lacks missing. Values rounded to f32 as stored.
fn matrix(layout: &Layout, cells: &[f64]) -> Measurement {
    let grid = &layout.wavelengths;
    let n = grid.len();
    let mut values = vec![f64::NAN; n * n];
    for (c, &v) in layout.cells.iter().zip(cells) {
        let (i, o) = match *c {
            Cell::Diagonal(i) => (i, i),
            Cell::Reradiation(i, o) => (i, o),
        };
        values[i * n + o] = f64::from(v as f32);
    }
    Measurement::new("pixel", grid.clone(), grid.clone(), values, Units::PerBin).unwrap()
}

/// ΔE2000 between two pixels under `light`, with the patch colorimeter.
fn delta_e(layout: &Layout, a: &[f64], b: &[f64], light: &str) -> f64 {
    let grid = &layout.wavelengths;
    let pc = PatchColorimeter::new(&Light::builtin(light).unwrap(), grid, grid);
    delta_e2000(pc.lab(&matrix(layout, a)), pc.lab(&matrix(layout, b)))
}

fn diff_json(args: &[&str]) -> serde_json::Value {
    let out = succeed(
        fluorite()
            .arg("image-diff")
            .args(args)
            .args(["--json", "-q"]),
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

fn stat(json: &serde_json::Value, light: usize, key: &str) -> f64 {
    json["lights"][light][key].as_f64().unwrap()
}

/// Pixel (x, y) of the varied test image: the dye at a concentration that changes
/// across the image.
fn varied(layout: &Layout) -> impl Fn(usize, usize) -> Vec<f64> + Sync + '_ {
    move |x, y| dye_cells(layout, 0.2 + 0.1 * x as f64 + 0.05 * y as f64)
}

#[test]
fn an_image_against_itself_differs_by_nothing() {
    let dir = temp_dir("itself");
    let layout = bfc_layout();
    let (a, b) = (dir.join("a.exr"), dir.join("b.exr"));
    write(&a, &layout, (7, 5), &varied(&layout));
    write(&b, &layout, (7, 5), &varied(&layout));
    let json = diff_json(&[a.to_str().unwrap(), b.to_str().unwrap()]);
    assert_eq!(json["compared"], 35);
    assert_eq!(json["skipped"], 0);
    for (l, name) in LIGHTS.iter().enumerate() {
        assert_eq!(json["lights"][l]["light"], *name);
        for key in ["median", "p90", "p99", "max"] {
            assert_eq!(stat(&json, l, key), 0.0, "{name} {key}");
        }
    }
}

#[test]
fn a_uniform_change_gives_the_colorimeters_delta_e() {
    let dir = temp_dir("uniform");
    let layout = bfc_layout();
    let nd = layout.diagonal_count;
    let base = dye_cells(&layout, 1.0);
    // Every pixel alike; the second image's diagonal 0.03 higher and its fluorescence
    // 10 % lower.
    let changed: Vec<f64> = base
        .iter()
        .enumerate()
        .map(|(k, v)| if k < nd { v + 0.03 } else { 0.9 * v })
        .collect();
    let (a, b) = (dir.join("a.exr"), dir.join("b.exr"));
    write(&a, &layout, (6, 4), &|_, _| base.clone());
    write(&b, &layout, (6, 4), &|_, _| changed.clone());
    let json = diff_json(&[a.to_str().unwrap(), b.to_str().unwrap()]);
    assert_eq!(json["compared"], 24);
    for (l, name) in LIGHTS.iter().enumerate() {
        let expected = delta_e(&layout, &base, &changed, name);
        assert!(expected > 0.5, "{name}: the change is visible ({expected})");
        for key in ["median", "p90", "p99", "max"] {
            let got = stat(&json, l, key);
            assert!(
                (got - expected).abs() < 1e-3,
                "{name} {key}: {got} against the colorimeter's {expected}"
            );
        }
    }
}

#[test]
fn a_varied_image_gives_each_pixels_delta_e_and_skips_non_finite_pixels() {
    let dir = temp_dir("varied");
    let layout = bfc_layout();
    let nd = layout.diagonal_count;
    let (w, h) = (9, 7);
    let pixel_a = varied(&layout);
    // The second image: a uniform change of the diagonal; one pixel holds a NaN cell.
    let pixel_b = |x: usize, y: usize| {
        let mut cells = pixel_a(x, y);
        for v in &mut cells[..nd] {
            *v += 0.02;
        }
        if (x, y) == (4, 3) {
            cells[nd + 5] = f64::NAN;
        }
        cells
    };
    let (a, b) = (dir.join("a.exr"), dir.join("b.exr"));
    write(&a, &layout, (w, h), &pixel_a);
    write(&b, &layout, (w, h), &pixel_b);
    let json = diff_json(&[
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--lights",
        "d65,f11",
    ]);
    assert_eq!(json["compared"], w * h - 1);
    assert_eq!(json["skipped"], 1);
    assert_eq!(json["non_finite_a"], 0);
    assert_eq!(json["non_finite_b"], 1);
    for (l, name) in ["d65", "f11"].iter().enumerate() {
        let values: Vec<f64> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .filter(|&p| p != (4, 3))
            .map(|(x, y)| delta_e(&layout, &pixel_a(x, y), &pixel_b(x, y), name))
            .collect();
        for (key, q) in [("median", 0.5), ("p90", 0.9), ("p99", 0.99), ("max", 1.0)] {
            let expected = fluorite::numeric::quantile(&values, q);
            let got = stat(&json, l, key);
            assert!(
                (got - expected).abs() < 1e-3,
                "{name} {key}: {got} against {expected}"
            );
        }
    }
}

#[test]
fn images_of_other_layouts_or_sizes_are_refused_naming_both() {
    let dir = temp_dir("refused");
    let layout = bfc_layout();
    let a = dir.join("a.exr");
    write(&a, &layout, (4, 4), &|_, _| dye_cells(&layout, 1.0));
    // One reradiation channel fewer.
    let mut cells = layout.cells.clone();
    cells.pop();
    let fewer = Layout::new(layout.wavelengths.clone(), cells).unwrap();
    let b = dir.join("fewer-channels.exr");
    write(&b, &fewer, (4, 4), &|_, _| {
        dye_cells(&layout, 1.0)[..fewer.len()].to_vec()
    });
    let (code, message) =
        refused(fluorite().args(["image-diff", a.to_str().unwrap(), b.to_str().unwrap()]));
    assert_ne!(code, Some(0));
    assert!(
        message.contains("a.exr") && message.contains("fewer-channels.exr"),
        "{message}"
    );
    assert!(message.contains("layout"), "{message}");
    // Another size.
    let c = dir.join("smaller.exr");
    write(&c, &layout, (4, 3), &|_, _| dye_cells(&layout, 1.0));
    let (_, message) =
        refused(fluorite().args(["image-diff", a.to_str().unwrap(), c.to_str().unwrap()]));
    assert!(
        message.contains("a.exr") && message.contains("smaller.exr"),
        "{message}"
    );
    assert!(
        message.contains("4×4") && message.contains("4×3"),
        "{message}"
    );
}

#[test]
fn concentration_maps_are_matched_one_to_one_by_correlation() {
    let dir = temp_dir("maps");
    let material = Material::load(Path::new("data/two-dyes.truth.json")).unwrap();
    let two = material.fluorophores.clone();
    let three = vec![two[0].clone(), two[1].clone(), two[0].clone()];
    let wavelengths = vec![400.0, 500.0, 600.0];
    let size = (8, 6);
    let reflectance = |_: usize, _: usize| vec![0.5f32; 3];
    std::fs::create_dir_all(dir.join("a")).unwrap();
    std::fs::create_dir_all(dir.join("b")).unwrap();
    let (ma, mb) = (
        dir.join("a/material-map.json"),
        dir.join("b/material-map.json"),
    );
    // A: c1 grows along x, c2 along y.
    write_map(
        &ma,
        "a",
        size,
        &two,
        &wavelengths,
        &|x, y| vec![0.1 * x as f32, 0.1 * y as f32],
        &reflectance,
    )
    .unwrap();
    // B: its first map follows A's second (scaled), its second A's first with a wobble,
    // its third is a checkerboard that matches neither.
    write_map(
        &mb,
        "b",
        size,
        &three,
        &wavelengths,
        &|x, y| {
            vec![
                0.05 * y as f32,
                0.1 * x as f32 + 0.01 * ((x + y) % 2) as f32,
                ((x + y) % 2) as f32 * 0.3,
            ]
        },
        &reflectance,
    )
    .unwrap();
    let image = dir.join("image.exr");
    let layout = bfc_layout();
    write(&image, &layout, size, &|_, _| dye_cells(&layout, 1.0));
    let json = diff_json(&[
        image.to_str().unwrap(),
        image.to_str().unwrap(),
        "--maps",
        ma.to_str().unwrap(),
        mb.to_str().unwrap(),
    ]);
    let maps = &json["maps"];
    assert_eq!(maps["fluorophores_a"], 2);
    assert_eq!(maps["fluorophores_b"], 3);
    let matches = maps["matches"].as_array().unwrap();
    assert_eq!(matches.len(), 2);
    // Correlations computed here.
    let a1: Vec<f64> = (0..6)
        .flat_map(|_| (0..8).map(|x| 0.1 * x as f64))
        .collect();
    let b2: Vec<f64> = (0..6)
        .flat_map(|y| (0..8).map(move |x| 0.1 * x as f64 + 0.01 * ((x + y) % 2) as f64))
        .collect();
    let expected = pearson(&a1, &b2);
    for m in matches {
        match (m["a"].as_u64().unwrap(), m["b"].as_u64().unwrap()) {
            (2, 1) => assert!((m["correlation"].as_f64().unwrap() - 1.0).abs() < 1e-6),
            (1, 2) => assert!(
                (m["correlation"].as_f64().unwrap() - expected).abs() < 1e-6,
                "{m} against {expected}"
            ),
            other => panic!("unexpected match {other:?}"),
        }
    }
    assert_eq!(maps["unmatched_b"], serde_json::json!([3]));
    assert_eq!(maps["unmatched_a"], serde_json::json!([]));
}

fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let cov: f64 = a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = a.iter().map(|x| (x - ma).powi(2)).sum();
    let vb: f64 = b.iter().map(|y| (y - mb).powi(2)).sum();
    cov / (va * vb).sqrt()
}
