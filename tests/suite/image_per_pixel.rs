//! `fluorite fit-image --per-pixel`: every pixel fitted on its own, judged against the
//! noise-free image it was drawn from (built here from a known material), with the
//! patch colorimeter, never against the fit's own ΔE.

use std::path::Path;

use fluorite::colour::{Light, PatchColorimeter, delta_e2000};
use fluorite::image::layout::{Cell, Layout};
use fluorite::image::map::read_whole;
use fluorite::image::sink::{ImageSpec, write_image};
use fluorite::material::Material;
use fluorite::measurement::{Measurement, Units};

use crate::common::{fluorite, succeed, temp_dir};

#[test]
fn every_pixel_is_fitted_on_its_own_and_matches_its_truth() {
    let dir = temp_dir("per-pixel");
    // A 20 nm grid keeps the fits quick: excitation 300–700 nm, emission 380–700 nm.
    let ex: Vec<f64> = (0..21).map(|i| 300.0 + 20.0 * i as f64).collect();
    let em: Vec<f64> = (0..17).map(|i| 380.0 + 20.0 * i as f64).collect();
    let layout = Layout::from_grids(&ex, &em).unwrap();
    let grid = layout.wavelengths.clone();
    let base = Material::load(Path::new("data/green-dye.truth.json")).unwrap();
    let (w, h) = (3, 2);
    let cells = |x: usize, y: usize| -> Vec<f64> {
        let mut m = base.clone();
        m.fluorophores[0].concentration *= 0.4 + 0.2 * x as f64 + 0.3 * y as f64;
        let matrix = fluorite::model::predict(&m, "p", &grid, &grid, Units::PerBin, true);
        layout
            .cells
            .iter()
            .map(|c| match *c {
                Cell::Diagonal(i) => matrix.get(i, i),
                Cell::Reradiation(i, o) => matrix.get(i, o),
            })
            .collect()
    };
    let image = dir.join("image.exr");
    write_image(
        &image,
        &ImageSpec {
            width: w,
            height: h,
            channels: layout.channel_names(),
            half: false,
            zip: false,
            attributes: Vec::new(),
        },
        |rect| {
            let mut v = Vec::new();
            for y in rect.y..rect.y + rect.height {
                for x in rect.x..rect.x + rect.width {
                    v.extend(cells(x, y).into_iter().map(|c| c as f32));
                }
            }
            Ok(v)
        },
        |_, _| {},
    )
    .unwrap();
    let out = dir.join("fit");
    let run = succeed(fluorite().args([
        "fit-image",
        image.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--per-pixel",
    ]));
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(stdout.contains("no material map"), "{stdout}");
    assert!(!out.join("material-map.json").exists());
    // fitted.exr: the input's channels; each pixel's colour that of its truth.
    let (fw, fh, names, values) = read_whole(&out.join("fitted.exr")).unwrap();
    assert_eq!((fw, fh), (w, h));
    let mut expected_names = layout.channel_names();
    expected_names.sort();
    assert_eq!(names, expected_names);
    let n = grid.len();
    let pc = PatchColorimeter::new(&Light::builtin("d65").unwrap(), &grid, &grid);
    let lab = |pixel: &dyn Fn(usize) -> f64| {
        let mut m = vec![f64::NAN; n * n];
        for (k, c) in layout.cells.iter().enumerate() {
            let (i, o) = match *c {
                Cell::Diagonal(i) => (i, i),
                Cell::Reradiation(i, o) => (i, o),
            };
            m[i * n + o] = pixel(k);
        }
        let m = Measurement::new("p", grid.clone(), grid.clone(), m, Units::PerBin).unwrap();
        pc.lab(&m)
    };
    for y in 0..h {
        for x in 0..w {
            let p = y * w + x;
            let truth = cells(x, y);
            let fitted = |k: usize| {
                let name = layout.channel_name(layout.cells[k]);
                let c = names.iter().position(|n| *n == name).unwrap();
                f64::from(values[c][p])
            };
            let de = delta_e2000(lab(&|k| truth[k]), lab(&fitted));
            assert!(
                de < 0.5,
                "pixel ({x}, {y}): ΔE2000 {de:.3} against the truth"
            );
        }
    }
    // delta-e.exr: one finite channel per light.
    let (_, _, lights, de) = read_whole(&out.join("delta-e.exr")).unwrap();
    assert_eq!(lights, vec!["a", "d65", "f11", "uv"]);
    assert!(de.iter().flatten().all(|v| v.is_finite() && *v >= 0.0));
}
