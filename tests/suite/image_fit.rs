//! `fluorite fit-image`: bispectral images into material maps, judged against images
//! built here from known materials (the shipped examples' truths), never against the
//! fit's own output.

use std::path::{Path, PathBuf};

use fluorite::colour::{Light, PatchColorimeter, delta_e2000};
use fluorite::image::fit::{ImageFitOptions, fit_image};
use fluorite::image::layout::{Cell, Layout};
use fluorite::image::map::MaterialMap;
use fluorite::image::sink::{ImageSpec, write_image};
use fluorite::image::{ExrImage, PixelBlock};
use fluorite::material::Material;
use fluorite::measurement::Units;
use fluorite::numeric::SplitMix64;

use crate::common::temp_dir;

/// The BFC-450 grid: excitation 300–780 nm, emission 380–780 nm, 10 nm.
fn bfc_layout() -> Layout {
    let ex: Vec<f64> = (0..49).map(|i| 300.0 + 10.0 * i as f64).collect();
    let em: Vec<f64> = (0..41).map(|i| 380.0 + 10.0 * i as f64).collect();
    Layout::from_grids(&ex, &em).unwrap()
}

/// A test image's truth: two fluorophores (the green-dye and brightener examples') whose
/// concentrations vary over the image, a region without fluorescence, and a reflectance
/// mixed from two examples'.
struct Truth {
    width: usize,
    height: usize,
    layout: Layout,
    /// Per fluorophore: its matrix at c = 1 on the layout's cells (diagonal cells hold
    /// only its fluorescence there), and its absorption at the diagonal wavelengths.
    unit: Vec<(Vec<f64>, Vec<f64>)>,
    reflectances: [Vec<f64>; 2],
}

fn material(name: &str) -> Material {
    Material::load(Path::new(&format!("data/{name}.truth.json"))).unwrap()
}

impl Truth {
    fn new(width: usize, height: usize) -> Truth {
        let layout = bfc_layout();
        let grid = layout.wavelengths.clone();
        let unit = ["green-dye", "brightener"]
            .iter()
            .map(|name| {
                let mut m = material(name);
                m.fluorophores[0].concentration = 1.0;
                let f = m.fluorophores[0].clone();
                let matrix = fluorite::model::predict(&m, name, &grid, &grid, Units::PerBin, false);
                let cells = layout
                    .cells
                    .iter()
                    .map(|c| match *c {
                        Cell::Diagonal(i) => matrix.get(i, i),
                        Cell::Reradiation(i, o) => matrix.get(i, o),
                    })
                    .collect();
                let absorption = layout
                    .diagonal_wavelengths()
                    .iter()
                    .map(|&i| f.absorption.eval_zero_outside(grid[i]))
                    .collect();
                (cells, absorption)
            })
            .collect();
        let r = |name: &str| -> Vec<f64> {
            let m = material(name);
            layout
                .diagonal_wavelengths()
                .iter()
                .map(|&i| m.reflectance.eval_clamped(grid[i]))
                .collect()
        };
        let reflectances = [r("plain"), r("red-pigment")];
        Truth {
            width,
            height,
            layout,
            unit,
            reflectances,
        }
    }

    /// c of both fluorophores at (x, y): a soft disc of the first with a gradient inside,
    /// a band of the second, nothing in the right-hand quarter.
    fn concentrations(&self, x: usize, y: usize) -> [f64; 2] {
        let (u, v) = (
            (x as f64 + 0.5) / self.width as f64,
            (y as f64 + 0.5) / self.height as f64,
        );
        let soft = |t: f64| 1.0 / (1.0 + (-t / 0.03).exp());
        let disc = soft(0.3 - ((u - 0.35).powi(2) + (v - 0.45).powi(2)).sqrt());
        let band = soft(0.2 - (v - 0.6).abs()) * soft(0.75 - u);
        let no_fluorescence = soft(u - 0.8);
        [
            0.8 * disc * (0.4 + 0.6 * u) * (1.0 - no_fluorescence),
            0.6 * band * (0.3 + 0.7 * v) * (1.0 - no_fluorescence),
        ]
    }

    fn reflectance(&self, x: usize, y: usize) -> Vec<f64> {
        let t = (x as f64 + y as f64) / (self.width + self.height) as f64;
        self.reflectances[0]
            .iter()
            .zip(&self.reflectances[1])
            .map(|(a, b)| (1.0 - t) * a + t * b)
            .collect()
    }

    /// The pixel's cells without noise.
    fn pixel(&self, x: usize, y: usize) -> Vec<f64> {
        let c = self.concentrations(x, y);
        let r = self.reflectance(x, y);
        let mut cells = vec![0.0; self.layout.len()];
        for (k, (unit, _)) in self.unit.iter().enumerate() {
            for (v, u) in cells.iter_mut().zip(unit) {
                *v += c[k] * u;
            }
        }
        for d in 0..self.layout.diagonal_count {
            let absorbed: f64 = (0..2).map(|k| c[k] * self.unit[k].1[d]).sum();
            assert!(absorbed <= 1.0);
            cells[d] += (1.0 - absorbed) * r[d];
        }
        cells
    }

    /// Writes the image, with Gaussian noise σ per cell (none for σ = 0).
    fn write(&self, path: &Path, noise: f64, seed: u64) {
        let spec = ImageSpec {
            width: self.width,
            height: self.height,
            channels: self.layout.channel_names(),
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
                        let mut rng = SplitMix64::new(seed ^ ((y * self.width + x) as u64 * 7919));
                        for cell in self.pixel(x, y) {
                            let n = if noise > 0.0 {
                                noise * rng.normal()
                            } else {
                                0.0
                            };
                            v.push((cell + n) as f32);
                        }
                    }
                }
                Ok(v)
            },
            |_, _| {},
        )
        .unwrap();
    }
}

/// Every pixel of an image, row-major.
fn read_all(path: &Path) -> (ExrImage, Vec<Vec<f32>>) {
    let image = ExrImage::open(path).unwrap();
    let mut pixels = vec![Vec::new(); image.pixels()];
    let width = image.width;
    image
        .pass(
            |b: &PixelBlock| Ok(b.clone()),
            |b| {
                for q in 0..b.pixel_count() {
                    pixels[b.image_index(q, width)] = b.pixel(q).to_vec();
                }
                Ok(())
            },
            |_| {},
        )
        .unwrap();
    (image, pixels)
}

/// ΔE2000 per pixel between two images on `layout`, under `light` (the layout's cells as
/// a matrix on its one grid, missing cells zero).
fn delta_e(layout: &Layout, a: &[Vec<f32>], b: &[Vec<f32>], light: &Light) -> Vec<f64> {
    let grid = &layout.wavelengths;
    let n = grid.len();
    let pc = PatchColorimeter::new(light, grid, grid);
    let lab = |cells: &[f32]| {
        let mut diagonal = vec![0.0; n];
        let mut matrix = vec![0.0; n * n];
        for (c, &v) in layout.cells.iter().zip(cells) {
            match *c {
                Cell::Diagonal(i) => diagonal[i] = f64::from(v),
                Cell::Reradiation(i, o) => matrix[i * n + o] = f64::from(v),
            }
        }
        fluorite::colour::xyz_to_lab(pc.xyz_from(&diagonal, |i, o| matrix[i * n + o]), pc.white)
    };
    a.iter()
        .zip(b)
        .map(|(x, y)| delta_e2000(lab(x), lab(y)))
        .collect()
}

fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let cov: f64 = a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = a.iter().map(|x| (x - ma).powi(2)).sum();
    let vb: f64 = b.iter().map(|y| (y - mb).powi(2)).sum();
    cov / (va * vb).sqrt()
}

fn quantile(values: &[f64], q: f64) -> f64 {
    fluorite::numeric::quantile(values, q)
}

struct Fitted {
    /// Holds the scratch folder (removed when the test ends).
    _scratch: crate::common::TempDir,
    dir: PathBuf,
    truth: Truth,
    truth_path: PathBuf,
}

/// Fits a 96 × 80 noisy image of [`Truth`] (σ = 0.0006 per cell, what the BFC-450 files
/// show) with the library.
fn fitted(tag: &str) -> Fitted {
    let dir = temp_dir(tag);
    let truth = Truth::new(96, 80);
    let measured = dir.join("image.exr");
    let truth_path = dir.join("truth.exr");
    truth.write(&measured, 0.0006, 3);
    truth.write(&truth_path, 0.0, 0);
    let image = ExrImage::open(&measured).unwrap();
    let out = dir.join("fit");
    fit_image(
        fluorite::image::PixelSource::Exr(&image),
        &out,
        &ImageFitOptions::default(),
        &|_| {},
    )
    .unwrap();
    Fitted {
        _scratch: dir,
        dir: out,
        truth,
        truth_path,
    }
}

#[test]
fn shared_fluorophores_recover_the_truth() {
    let f = fitted("image-fit-truth");
    let map = MaterialMap::load(&f.dir.join("material-map.json")).unwrap();
    assert_eq!(
        map.fluorophores.len(),
        2,
        "two fluorophores drawn, {} found",
        map.fluorophores.len()
    );
    // fitted.exr against the noise-free truth, as any tool would compare them.
    let (_, fitted) = read_all(&f.dir.join("fitted.exr"));
    let (_, truth) = read_all(&f.truth_path);
    for name in ["d65", "a", "f11"] {
        let light = Light::builtin(name).unwrap();
        let de = delta_e(&f.truth.layout, &fitted, &truth, &light);
        let (median, p99) = (quantile(&de, 0.5), quantile(&de, 0.99));
        assert!(
            median <= 0.3 && p99 <= 1.0,
            "{name}: median {median:.3}, 99th {p99:.3}"
        );
    }
    // Concentration maps correlate with the truth (up to the gauge's scale).
    let textures = map.load_textures(&f.dir.join("material-map.json")).unwrap();
    let truth_c: Vec<[f64; 2]> = (0..f.truth.height)
        .flat_map(|y| (0..f.truth.width).map(move |x| (x, y)))
        .map(|(x, y)| f.truth.concentrations(x, y))
        .collect();
    for k in 0..2 {
        let t: Vec<f64> = truth_c.iter().map(|c| c[k]).collect();
        let best = (0..2)
            .map(|j| {
                let fitted: Vec<f64> = (0..truth_c.len())
                    .map(|p| f64::from(textures.concentration[p * 2 + j]))
                    .collect();
                correlation(&t, &fitted)
            })
            .fold(f64::MIN, f64::max);
        assert!(best >= 0.99, "fluorophore {k}: correlation {best:.4}");
    }
    // Reflectance where there is no fluorescence: the truth within the noise.
    let nd = f.truth.layout.diagonal_count;
    let (x, y) = (f.truth.width - 3, 5);
    let r_truth = f.truth.reflectance(x, y);
    let p = y * f.truth.width + x;
    for (d, truth) in r_truth.iter().enumerate() {
        let r = f64::from(textures.reflectance[p * nd + d]);
        assert!((r - truth).abs() < 0.005, "r[{d}] {r} vs {truth}");
    }
    // Every fluorophore and a sample of pixel materials conserve energy and photons.
    for (p, _) in truth_c.iter().enumerate().step_by(97) {
        let m = map
            .material_at(
                &textures.concentration[p * 2..p * 2 + 2],
                &textures.wavelengths,
                &textures.reflectance[p * nd..(p + 1) * nd],
            )
            .unwrap();
        let report = fluorite::check::check_material(&m);
        assert!(report.valid, "pixel {p}: {}", report.failed_names());
    }
}
