//! The renderer shows a material map (`fluorite-material-map/1`): per hit point the
//! concentrations and the reflectance at the object's (u, v), the BBRRDF of that texel's
//! material sampled as for a single material.
//!
//! Truth is model.md §6's closed form: a convex object (the furnace sphere, the plane
//! scene's rectangle) in a uniform environment L sends Lo(λo) = d(λo)·L(λo) +
//! Σ c·Q·e(λo)·∫a·L dλ from every point, d = (1 − Σ c·a)·r, whatever the point's normal, so
//! each region of a textured object must show the exact radiance of its texels' material.
//! Error model as in `render.rs`: |mean − exact| ≤ 5 standard errors + 0.2 % (the
//! renderer's f32 tables on a 1 nm grid) + 0.1 % of the peak, and the standard errors
//! must be small against the effect tested.

use crate::common;
use crate::common::map::{CONCENTRATION_FILE, REFLECTANCE_FILE, write_exr, write_map};

use std::path::{Path, PathBuf};

use fluorite::colour::Light;
use fluorite::render::texture::MASKED_REFLECTANCE;
use fluorite::render::{
    MaterialTexture, PixelRegion, RenderSettings, Scene, SceneKind, SpectralEstimate,
    SpectralSampling, spectral_radiance,
};
use fluorite::spectrum::uniform_grid;
use fluorite::{Fluorophore, Material, Spectrum, YieldForm};
use glam::Vec3;

// ---------------------------------------------------------------------------------------
// Maps with known texels.

fn gaussian(grid: &[f64], peak: f64, sigma: f64) -> Vec<f64> {
    grid.iter()
        .map(|l| (-0.5 * ((l - peak) / sigma).powi(2)).exp())
        .collect()
}

/// A fluorophore absorbing blue (peak 450 nm) and emitting yellow-green (560 nm), energy
/// yield 0.5, on a 5 nm grid (its concentration is set per texel).
fn blue_to_green() -> Fluorophore {
    let grid = uniform_grid(300.0, 780.0, 5.0);
    let e = Spectrum::new(grid.clone(), gaussian(&grid, 560.0, 25.0), "e").unwrap();
    let area = e.integral();
    Fluorophore {
        concentration: 1.0,
        quantum_yield: 0.5,
        yield_form: YieldForm::Energy,
        concentration_range: None,
        absorption: Spectrum::new(grid.clone(), gaussian(&grid, 450.0, 30.0), "a").unwrap(),
        emission: Spectrum::new(grid, e.value.iter().map(|v| v / area).collect(), "e").unwrap(),
    }
}

/// A UV brightener in the photon form (absorbs at 360 nm, emits at 440 nm, Φ = 0.8).
fn brightener() -> Fluorophore {
    let grid = uniform_grid(300.0, 780.0, 5.0);
    let e = Spectrum::new(grid.clone(), gaussian(&grid, 440.0, 20.0), "e").unwrap();
    let area = e.integral();
    Fluorophore {
        concentration: 1.0,
        quantum_yield: 0.8,
        yield_form: YieldForm::Photon,
        concentration_range: None,
        absorption: Spectrum::new(grid.clone(), gaussian(&grid, 360.0, 20.0), "a").unwrap(),
        emission: Spectrum::new(grid, e.value.iter().map(|v| v / area).collect(), "e").unwrap(),
    }
}

/// The reflectance textures' wavelengths: 10 nm over the rendered range.
fn texture_grid() -> Vec<f64> {
    uniform_grid(300.0, 780.0, 10.0)
}

/// A reflectance rising linearly from `from` at 300 nm to `to` at 780 nm, at `grid`.
fn ramp(grid: &[f64], from: f64, to: f64) -> Vec<f64> {
    grid.iter()
        .map(|l| from + (to - from) * (l - 300.0) / 480.0)
        .collect()
}

fn as_f32(values: &[f64]) -> Vec<f32> {
    values.iter().map(|&v| v as f32).collect()
}

/// The material of a texel with concentrations `c` over reflectance `r` (on
/// [`texture_grid`]).
fn texel_material(fluorophores: &[Fluorophore], c: &[f64], r: &[f64]) -> Material {
    let fluorophores = fluorophores
        .iter()
        .zip(c)
        .map(|(f, &c)| Fluorophore {
            concentration: c,
            ..f.clone()
        })
        .collect();
    let m = Material::new(
        "texel",
        Spectrum::new(texture_grid(), r.to_vec(), "r").unwrap(),
        fluorophores,
    );
    m.validate().unwrap();
    m
}

// ---------------------------------------------------------------------------------------
// The exact furnace radiance (model.md §6), from the material's own spectra.

fn fine_integral(f: impl Fn(f64) -> f64) -> f64 {
    let (from, to, n) = (300.0, 780.0, 9600);
    let step = (to - from) / n as f64;
    (0..=n)
        .map(|i| {
            let l = from + step * i as f64;
            let w = if i == 0 || i == n { 0.5 * step } else { step };
            f(l) * w
        })
        .sum()
}

/// Lo(λo) = d(λo)·L(λo) + Σ c·y·e(λo)·∫x·a·L dλ, x = 1 (energy form) or λ/λ̄e (photon
/// form), L the light's power times the scene's scale.
fn exact_furnace(material: &Material, light: &Light, scale: f64, lo: f64) -> f64 {
    let power = |l: f64| scale * light.power(l);
    let mut value = material.diagonal(lo) * power(lo);
    for f in &material.fluorophores {
        let e = |l: f64| f.emission.eval_zero_outside(l);
        let mean = fine_integral(|l| l * e(l)) / fine_integral(e);
        let x = |l: f64| match f.yield_form {
            YieldForm::Energy => 1.0,
            YieldForm::Photon => l / mean,
        };
        let absorbed = fine_integral(|l| f.absorption.eval_zero_outside(l) * x(l) * power(l));
        value += f.concentration * f.quantum_yield * e(lo) * absorbed;
    }
    value
}

fn assert_matches(estimate: &SpectralEstimate, exact: &[f64], what: &str) {
    let peak = exact.iter().cloned().fold(0.0, f64::max);
    for (i, &lo) in estimate.wavelength_nm.iter().enumerate() {
        let (mean, se) = (estimate.mean[i], estimate.std_error[i]);
        let tolerance = 5.0 * se + 2e-3 * exact[i].abs() + 1e-3 * peak;
        assert!(
            (mean - exact[i]).abs() <= tolerance,
            "{what} at {lo} nm: rendered {mean:.6} ± {se:.6}, exact {:.6} (|diff| = {:.2} se)",
            exact[i],
            (mean - exact[i]).abs() / se.max(1e-30)
        );
        assert!(
            se <= 0.03 * peak,
            "{what} at {lo} nm: standard error {se} too large to test anything (peak {peak})"
        );
    }
}

/// The square of `size` pixels centred on the image of world point `at`.
fn region_around(scene: &Scene, settings: &RenderSettings, at: Vec3, size: u32) -> PixelRegion {
    let (u, v) = scene.camera().project(at).unwrap();
    let cx = (u * settings.width as f32) as u32;
    let cy = (v * settings.height as f32) as u32;
    PixelRegion {
        x0: cx - size / 2,
        y0: cy - size / 2,
        x1: cx - size / 2 + size,
        y1: cy - size / 2 + size,
    }
}

/// The exact furnace radiance of `material` at `wavelengths` in `scene`'s light.
fn exact_at(material: &Material, light: &Light, scene: &Scene, wavelengths: &[f64]) -> Vec<f64> {
    wavelengths
        .iter()
        .map(|&lo| exact_furnace(material, light, scene.light().scale, lo))
        .collect()
}

// ---------------------------------------------------------------------------------------
// (1) A uniform map is its material.

#[test]
fn a_uniform_map_renders_as_its_single_material_in_the_furnace() {
    let dir = tempfile::tempdir().unwrap();
    let fluorophores = [blue_to_green(), brightener()];
    let (c, r) = ([0.7, 0.4], ramp(&texture_grid(), 0.2, 0.8));
    let json = dir.path().join("uniform.json");
    write_map(
        &json,
        "uniform",
        (5, 3),
        &fluorophores,
        &texture_grid(),
        &|_, _| vec![c[0] as f32, c[1] as f32],
        &|_, _| as_f32(&r),
    )
    .unwrap();
    let texture = MaterialTexture::load(&json).unwrap();
    let material = texel_material(&fluorophores, &c, &r);
    let settings = RenderSettings {
        width: 64,
        height: 64,
        samples_per_pixel: 512,
        seed: 11,
    };
    let region = PixelRegion::centre(&settings, 8);
    let wavelengths = uniform_grid(300.0, 780.0, 20.0);
    for light in ["d65", "uv"] {
        let light = Light::builtin(light).unwrap();
        for sampling in [SpectralSampling::LightAware, SpectralSampling::Paper] {
            let estimate = |scene: &mut Scene| {
                scene.set_spectral_sampling(sampling);
                spectral_radiance(scene, &settings, region, &wavelengths).unwrap()
            };
            let mut map_scene =
                Scene::build(SceneKind::Furnace, &texture, &light, false, 1.0).unwrap();
            let mut material_scene =
                Scene::build(SceneKind::Furnace, &material, &light, false, 1.0).unwrap();
            let (map, single) = (estimate(&mut map_scene), estimate(&mut material_scene));
            let what = format!("uniform map under {} ({sampling:?})", light.name);
            assert_matches(
                &map,
                &exact_at(&material, &light, &map_scene, &wavelengths),
                &what,
            );
            // And the same as the material rendered alone, within both renders' noise.
            for (i, lo) in wavelengths.iter().enumerate() {
                let se = map.std_error[i].hypot(single.std_error[i]);
                let diff = (map.mean[i] - single.mean[i]).abs();
                assert!(
                    diff <= 5.0 * se + 2e-3 * single.mean[i].abs(),
                    "{what} at {lo} nm: map {} vs material {} (se {se})",
                    map.mean[i],
                    single.mean[i]
                );
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// (2) Two halves: fluorescent on the left, a plain reflector on the right.

/// A 16 × 8 map: texels x < 8 hold [`blue_to_green`] at c = 0.7, the others none, over
/// one reflectance everywhere. Returns the texture and the two texel materials.
fn two_halves(dir: &Path) -> (MaterialTexture, Material, Material) {
    let r = ramp(&texture_grid(), 0.3, 0.7);
    let json = dir.join("halves.json");
    write_map(
        &json,
        "halves",
        (16, 8),
        &[blue_to_green()],
        &texture_grid(),
        &|x, _| vec![if x < 8 { 0.7 } else { 0.0 }],
        &|_, _| as_f32(&r),
    )
    .unwrap();
    (
        MaterialTexture::load(&json).unwrap(),
        texel_material(&[blue_to_green()], &[0.7], &r),
        texel_material(&[], &[], &r),
    )
}

/// In `scene`, the regions around `left` and `right` (world points on the map's object)
/// show the exact furnace radiance of `fluorescent` and of `plain`, and the fluorescence
/// is resolved: the left region's emission peak lies many standard errors above the plain
/// reflector's value.
fn check_halves(
    scene: &Scene,
    settings: &RenderSettings,
    (left, right): (Vec3, Vec3),
    (fluorescent, plain): (&Material, &Material),
    light: &Light,
    what: &str,
) {
    let wavelengths = uniform_grid(380.0, 740.0, 20.0);
    for (at, material, side) in [(left, fluorescent, "left"), (right, plain, "right")] {
        let region = region_around(scene, settings, at, 6);
        let estimate = spectral_radiance(scene, settings, region, &wavelengths).unwrap();
        let exact = exact_at(material, light, scene, &wavelengths);
        assert_matches(&estimate, &exact, &format!("{what}, {side} half"));
        let i = wavelengths.iter().position(|&l| l == 560.0).unwrap();
        let without = exact_at(plain, light, scene, &[560.0])[0];
        if side == "left" {
            assert!(
                estimate.mean[i] > without + 10.0 * estimate.std_error[i],
                "{what}: the left half's emission at 560 nm {} ± {} does not stand out of the plain {without}",
                estimate.mean[i],
                estimate.std_error[i]
            );
        }
    }
}

#[test]
fn a_two_halves_map_shows_each_half_s_exact_furnace_colour_on_the_sphere() {
    let dir = tempfile::tempdir().unwrap();
    let (texture, fluorescent, plain) = two_halves(dir.path());
    let light = Light::builtin("d65").unwrap();
    let settings = RenderSettings {
        width: 64,
        height: 64,
        samples_per_pixel: 256,
        seed: 7,
    };
    let scene = Scene::build(SceneKind::Furnace, &texture, &light, false, 1.0).unwrap();
    // 30° either side of the point facing the camera: u = 0.5 ∓ 1/12, texels 6.2 and 8.8
    // (the halves meet at texel 7.5; bilinear blending reaches from 7 to 8).
    let (s, c) = 30f32.to_radians().sin_cos();
    check_halves(
        &scene,
        &settings,
        (Vec3::new(-s, 0.0, c), Vec3::new(s, 0.0, c)),
        (&fluorescent, &plain),
        &light,
        "sphere",
    );
}

#[test]
fn a_two_halves_map_shows_each_half_s_exact_furnace_colour_on_the_plane() {
    let dir = tempfile::tempdir().unwrap();
    let (texture, fluorescent, plain) = two_halves(dir.path());
    let light = Light::builtin("d65").unwrap();
    let settings = RenderSettings {
        width: 64,
        height: 32,
        samples_per_pixel: 256,
        seed: 8,
    };
    let scene = Scene::build(SceneKind::Plane, &texture, &light, false, settings.aspect()).unwrap();
    // The 16 × 8 map spans a 2 × 1 rectangle: x = ∓0.5 is u = 0.25 and 0.75.
    check_halves(
        &scene,
        &settings,
        (Vec3::new(-0.5, 0.0, 0.0), Vec3::new(0.5, 0.0, 0.0)),
        (&fluorescent, &plain),
        &light,
        "plane",
    );
}

#[test]
fn the_compare_twin_of_a_map_has_its_reflectance_and_no_fluorescence() {
    let dir = tempfile::tempdir().unwrap();
    let (texture, fluorescent, plain) = two_halves(dir.path());
    let light = Light::builtin("d65").unwrap();
    let settings = RenderSettings {
        width: 96,
        height: 32,
        samples_per_pixel: 256,
        seed: 9,
    };
    let scene = Scene::build(SceneKind::Plane, &texture, &light, true, settings.aspect()).unwrap();
    // Two 2 × 1 rectangles 0.3 apart: the map's centred at x = −1.15, its twin at 1.15.
    let centre = 1.0 + 0.5 * fluorite::render::scene::PLANE_COMPARE_GAP;
    check_halves(
        &scene,
        &settings,
        (
            Vec3::new(-centre - 0.5, 0.0, 0.0),
            Vec3::new(centre - 0.5, 0.0, 0.0),
        ),
        (&fluorescent, &plain),
        &light,
        "compare plane",
    );
}

#[test]
fn masked_texels_render_as_a_neutral_middle_grey() {
    // A 2 × 1 map: the left texel masked (NaN concentration), the right a plain 0.6.
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("masked.json");
    let grid = texture_grid();
    write_map(
        &json,
        "masked",
        (2, 1),
        &[blue_to_green()],
        &grid,
        &|x, _| vec![if x == 0 { f32::NAN } else { 0.0 }],
        &|_, _| vec![0.6; grid.len()],
    )
    .unwrap();
    let texture = MaterialTexture::load(&json).unwrap();
    assert_eq!(texture.masked(), 1);
    let light = Light::builtin("a").unwrap();
    let settings = RenderSettings {
        width: 64,
        height: 32,
        samples_per_pixel: 512,
        seed: 3,
    };
    let scene = Scene::build(SceneKind::Plane, &texture, &light, false, settings.aspect()).unwrap();
    let wavelengths = uniform_grid(400.0, 700.0, 50.0);
    let flat = |r: f64| texel_material(&[], &[], &vec![r; grid.len()]);
    // Past the texel centres (u = 0.25, 0.75) each side is its texel alone.
    for (x, r) in [(-0.8, MASKED_REFLECTANCE as f64), (0.8, 0.6)] {
        let region = region_around(&scene, &settings, Vec3::new(x, 0.0, 0.0), 6);
        let estimate = spectral_radiance(&scene, &settings, region, &wavelengths).unwrap();
        let exact = exact_at(&flat(r), &light, &scene, &wavelengths);
        assert_matches(&estimate, &exact, &format!("reflectance {r} at x = {x}"));
    }
}

// ---------------------------------------------------------------------------------------
// (3) Broken maps: each error names the file at fault.

/// A valid 4 × 4 map of one fluorophore in `dir`; returns its JSON's path.
fn small_map(dir: &Path) -> PathBuf {
    let json = dir.join("map.json");
    let grid = texture_grid();
    write_map(
        &json,
        "small",
        (4, 4),
        &[blue_to_green()],
        &grid,
        &|x, _| vec![0.1 * x as f32],
        &|_, _| vec![0.5; grid.len()],
    )
    .unwrap();
    json
}

fn load_error(json: &Path) -> String {
    MaterialTexture::load(json).unwrap_err().to_string()
}

#[test]
fn a_missing_texture_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let json = small_map(dir.path());
    assert!(MaterialTexture::load(&json).is_ok());
    for file in [CONCENTRATION_FILE, REFLECTANCE_FILE] {
        let dir = tempfile::tempdir().unwrap();
        let json = small_map(dir.path());
        std::fs::remove_file(dir.path().join(file)).unwrap();
        let message = load_error(&json);
        assert!(
            message.contains(file) && message.contains("map.json"),
            "{file}: {message}"
        );
    }
}

#[test]
fn textures_of_the_wrong_size_are_an_error_naming_the_file() {
    let grid = texture_grid();
    let spectral: Vec<String> = grid
        .iter()
        .map(|&l| fluorite::formats::exr::diagonal_channel(l))
        .collect();
    // The reflectance texture 8 × 8 against a 4 × 4 concentration texture.
    let dir = tempfile::tempdir().unwrap();
    let json = small_map(dir.path());
    write_exr(
        &dir.path().join(REFLECTANCE_FILE),
        (8, 8),
        &spectral,
        &|_, _| vec![0.5; grid.len()],
    )
    .unwrap();
    let message = load_error(&json);
    assert!(
        message.contains(REFLECTANCE_FILE) && message.contains("8×8"),
        "{message}"
    );
    // Both textures 4 × 4, but the JSON says 5 × 4.
    let dir = tempfile::tempdir().unwrap();
    let json = small_map(dir.path());
    let text = std::fs::read_to_string(&json).unwrap();
    let mut value: serde_json::Value = serde_json::from_str(&text).unwrap();
    value["width"] = serde_json::json!(5);
    std::fs::write(&json, value.to_string()).unwrap();
    let message = load_error(&json);
    assert!(
        message.contains(CONCENTRATION_FILE) && message.contains("width 5"),
        "{message}"
    );
}

#[test]
fn textures_with_the_wrong_channels_are_an_error_naming_the_file() {
    // The concentration texture names its channel `conc1` where the map says `c1`.
    let dir = tempfile::tempdir().unwrap();
    let json = small_map(dir.path());
    write_exr(
        &dir.path().join(CONCENTRATION_FILE),
        (4, 4),
        &["conc1".to_string()],
        &|_, _| vec![0.2],
    )
    .unwrap();
    let message = load_error(&json);
    assert!(
        message.contains(CONCENTRATION_FILE) && message.contains("c1"),
        "{message}"
    );
    // The reflectance texture holds RGB, not the spectral channels T.<λ>nm.
    let dir = tempfile::tempdir().unwrap();
    let json = small_map(dir.path());
    write_exr(
        &dir.path().join(REFLECTANCE_FILE),
        (4, 4),
        &["R".to_string(), "G".to_string(), "B".to_string()],
        &|_, _| vec![0.5; 3],
    )
    .unwrap();
    let message = load_error(&json);
    assert!(
        message.contains(REFLECTANCE_FILE) && message.contains("T.<λ>nm"),
        "{message}"
    );
}

#[test]
fn a_concentration_above_one_is_an_error_naming_the_texel_and_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let json = small_map(dir.path());
    write_exr(
        &dir.path().join(CONCENTRATION_FILE),
        (4, 4),
        &["c1".to_string()],
        &|x, y| vec![if (x, y) == (2, 3) { 1.5 } else { 0.5 }],
    )
    .unwrap();
    let message = load_error(&json);
    assert!(
        message.contains(CONCENTRATION_FILE)
            && message.contains("(2, 3)")
            && message.contains("1.5"),
        "{message}"
    );
}

// ---------------------------------------------------------------------------------------
// The command line.

use crate::common::fluorite;

/// The mean of each sRGB channel over the pixels x0..x1 × y0..y1 of a decoded PNG.
fn mean_rgb(bytes: &[u8], width: u32, (x0, x1): (u32, u32), (y0, y1): (u32, u32)) -> [f64; 3] {
    let mut sum = [0.0; 3];
    for y in y0..y1 {
        for x in x0..x1 {
            for (c, s) in sum.iter_mut().enumerate() {
                *s += bytes[((y * width + x) * 3) as usize + c] as f64;
            }
        }
    }
    let n = ((x1 - x0) * (y1 - y0)) as f64;
    sum.map(|s| s / n)
}

#[test]
fn cli_renders_a_map_on_the_plane_and_the_sphere() {
    let dir = tempfile::tempdir().unwrap();
    let (_, _, _) = two_halves(dir.path());
    let json = dir.path().join("halves.json");
    let png = dir.path().join("x.png");
    common::succeed(
        fluorite()
            .arg("render")
            .arg(&json)
            .args(["--scene", "plane", "--light", "d65", "-o"])
            .arg(&png)
            .args(["--size", "48x24", "--spp", "16", "-q"]),
    );
    let (width, height, bytes) = common::decode_png(&std::fs::read(&png).unwrap());
    assert_eq!((width, height), (48, 24));
    // The rectangle spans about x = 7..41: the fluorescent left half (blue light turned
    // green) is greener against its blue than the plain right half.
    let left = mean_rgb(&bytes, width, (10, 18), (9, 15));
    let right = mean_rgb(&bytes, width, (30, 38), (9, 15));
    assert!(
        left[1] - left[2] > right[1] - right[2] + 10.0,
        "left {left:?}, right {right:?}"
    );
    // A file named material-map.json is a map whatever its schema says; the default
    // output is beside it; the sphere scenes and --compare take maps too.
    let named = dir.path().join("material-map.json");
    std::fs::copy(&json, &named).unwrap();
    common::succeed(fluorite().arg("render").arg(&named).args([
        "--compare",
        "--size",
        "40x20",
        "--spp",
        "2",
        "-q",
    ]));
    let (width, _, _) =
        common::decode_png(&std::fs::read(dir.path().join("material-map.png")).unwrap());
    assert_eq!(width, 40);
    // A uniform material on the plane scene.
    let material = dir.path().join("plain.json");
    texel_material(&[], &[], &ramp(&texture_grid(), 0.3, 0.7))
        .save(&material)
        .unwrap();
    common::succeed(
        fluorite()
            .arg("render")
            .arg(&material)
            .args(["--scene", "plane", "--size", "16x16", "--spp", "2", "-q"]),
    );
    assert!(dir.path().join("plain.png").is_file());
}

#[test]
fn cli_refuses_a_broken_map_naming_the_file_and_a_map_in_report() {
    let dir = tempfile::tempdir().unwrap();
    let json = small_map(dir.path());
    std::fs::remove_file(dir.path().join(REFLECTANCE_FILE)).unwrap();
    let (code, message) = common::refused(
        fluorite()
            .arg("render")
            .arg(&json)
            .args(["--size", "8x8", "--spp", "1"]),
    );
    assert_ne!(code, Some(0));
    assert!(message.contains(REFLECTANCE_FILE), "{message}");
    let json = small_map(dir.path());
    let (_, message) = common::refused(fluorite().arg("render").arg(&json).arg("--report"));
    assert!(
        message.contains("map.json") && message.contains("material map"),
        "{message}"
    );
}
