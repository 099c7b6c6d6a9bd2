//! Furnace noise and time: how clean a material's preview is for the time it takes.
//!
//! In the furnace (a sphere of the material alone in a uniform environment of the light)
//! every pixel wholly covered by the sphere has the same exact radiance (model.md §6), so
//! the spread of luminance Y over those pixels is pure Monte Carlo noise. The report
//! gives its relative standard deviation and the render's time, for each excitation
//! sampling rule, so that the rules can be compared at equal sample count and at equal
//! time.

use std::time::Instant;

use crate::Material;
use crate::colour::Light;
use crate::error::{Error, Result};

use super::{Film, RenderSettings, Scene, SceneKind, SpectralSampling, render};

/// Furnace noise and render time of one material under one light with one sampling rule.
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseReport {
    /// The excitation sampling rule.
    pub sampling: SpectralSampling,
    /// Relative standard deviation of Y over the pixels wholly covered by the sphere.
    pub noise: f64,
    /// Mean Y over those pixels (film units: the furnace's white reads 1).
    pub mean_y: f64,
    /// Pixels wholly covered by the sphere.
    pub pixels: usize,
    /// Median wall-clock time of one render (seconds).
    pub seconds: f64,
}

/// Indices (row-major) of the pixels whose four corners all see object `object` first:
/// pixels wholly inside its silhouette.
pub fn covered_pixels(scene: &Scene, settings: &RenderSettings, object: usize) -> Vec<usize> {
    let (w, h) = (settings.width, settings.height);
    let camera = scene.camera();
    let sees = |x: u32, y: u32| {
        let ray = camera.ray(x as f32 / w as f32, y as f32 / h as f32);
        scene
            .intersect(&ray, f32::INFINITY)
            .is_some_and(|hit| hit.object == object)
    };
    let mut pixels = Vec::new();
    for y in 0..h {
        for x in 0..w {
            if sees(x, y) && sees(x + 1, y) && sees(x, y + 1) && sees(x + 1, y + 1) {
                pixels.push((y * w + x) as usize);
            }
        }
    }
    pixels
}

/// Mean and relative standard deviation (sample standard deviation over the mean) of
/// the luminance Y of `pixels`; None with fewer than two pixels or a mean of zero.
pub fn luminance_spread(film: &Film, pixels: &[usize]) -> Option<(f64, f64)> {
    if pixels.len() < 2 {
        return None;
    }
    let values: Vec<f64> = pixels
        .iter()
        .filter_map(|&i| film.xyz.get(i).map(|p| p[1] as f64))
        .collect();
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    if mean.abs() <= 0.0 || !mean.is_finite() {
        return None;
    }
    let variance = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    Some((mean, variance.sqrt() / mean.abs()))
}

impl NoiseReport {
    /// This rule's noise had it run as long as `other`: noise falls as 1/√samples, hence
    /// as 1/√time.
    pub fn noise_at_time_of(&self, other: &NoiseReport) -> f64 {
        self.noise * (self.seconds / other.seconds).sqrt()
    }
}

/// Renders `material`'s furnace under `light` with `settings` `runs` times (at least
/// once) per sampling rule in `rules`, and reports the noise of the first render and the
/// median time.
pub fn furnace_noise(
    material: &Material,
    light: &Light,
    settings: &RenderSettings,
    rules: &[SpectralSampling],
    runs: usize,
) -> Result<Vec<NoiseReport>> {
    settings.validate()?;
    let mut scene = Scene::build(
        SceneKind::Furnace,
        material,
        light,
        false,
        settings.aspect(),
    )?;
    // The material's sphere is the scene's first object.
    let pixels = covered_pixels(&scene, settings, 0);
    if pixels.len() < 2 {
        return Err(Error::invalid(
            "--size",
            format!(
                "{}×{} leaves fewer than two pixels inside the sphere; give a larger image",
                settings.width, settings.height
            ),
        ));
    }
    let mut reports = Vec::new();
    for &sampling in rules {
        scene.set_spectral_sampling(sampling);
        let mut times = Vec::new();
        let mut film = None;
        for _ in 0..runs.max(1) {
            let started = Instant::now();
            let rendered = render(&scene, settings, &|| {})?;
            times.push(started.elapsed().as_secs_f64());
            film.get_or_insert(rendered);
        }
        times.sort_by(f64::total_cmp);
        let film = film.ok_or_else(|| Error::invalid("runs", "no render was made"))?;
        let (mean_y, noise) = luminance_spread(&film, &pixels).ok_or_else(|| {
            Error::invalid(
                "material",
                format!(
                    "{} reads no light in the furnace under {}; its noise is undefined",
                    material.name, light.name
                ),
            )
        })?;
        reports.push(NoiseReport {
            sampling,
            noise,
            mean_y,
            pixels: pixels.len(),
            seconds: times[times.len() / 2],
        });
    }
    Ok(reports)
}
