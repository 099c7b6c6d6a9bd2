//! The built-in spectral renderer: previews a [`Material`](crate::Material), or a material
//! map that varies one over a texture, on a sphere or a rectangle, sampling the
//! fluorescent BBRRDF as the paper describes (model.md §6).
//!
//! - [`spectra`]: spectra tabulated at 1 nm over 300–780 nm and the sampling tables.
//! - [`geometry`]: rays, spheres, planes, quads, the camera, cosine sampling, texture
//!   coordinates.
//! - [`texture`]: a material map's textures, checked and looked up at (u, v).
//! - [`surface`]: a scene's surfaces, uniform or textured, and either at one hit point.
//! - [`scene`]: scenes, and the built-in preview, furnace and plane scenes.
//! - [`integrator`]: the path tracer (hero wavelengths, fluorescent events, next-event
//!   estimation with multiple importance sampling, Russian roulette).
//! - [`image`]: the exposure rule, sRGB PNG and linear EXR.
//! - [`compare`]: the `--compare` picture: automatic exposure and the label strip.
//! - [`picture`]: one picture of a material, rendered and developed.
//! - [`report`]: furnace noise and time, to compare sampling rules.
//!
//! [`render`] produces a film of CIE XYZ for pictures; [`spectral_radiance`] estimates
//! spectral radiance with standard errors over a pixel region, so that tests check
//! spectra rather than colours. Every pixel draws from its own seeded generator, so a
//! render is reproducible whatever the number of threads.

pub mod compare;
pub mod geometry;
pub mod image;
pub mod integrator;
pub mod picture;
pub mod report;
pub mod rng;
pub mod scene;
pub mod spectra;
pub mod surface;
pub mod texture;
pub mod wavelengths;

use glam::Vec4;
use rayon::prelude::*;

use crate::error::{Error, Result};

pub use geometry::{Camera, Quad, Ray, Shape};
pub use image::DEFAULT_EXPOSURE_EV;
pub use scene::{Object, Scene, SceneKind, SpectralSampling};
pub use spectra::{LAMBDA_MAX_NM, LAMBDA_MIN_NM, LightSpectrum, Observer, SurfaceTables};
pub use surface::{MaterialSource, Surface, SurfacePoint, TexturedSurface};
pub use texture::{MaterialTexture, is_material_map};
pub use wavelengths::WavelengthSampler;

use integrator::{CHANNELS, trace};
use rng::Rng;

/// Largest accepted image width, height and samples per pixel.
pub const MAX_SETTING: u32 = 16384;

/// Image size, samples per pixel and seed of a render.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RenderSettings {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Camera paths per pixel (each carries four wavelengths).
    pub samples_per_pixel: u32,
    /// Seed: the same seed gives the same image.
    pub seed: u64,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 640,
            height: 400,
            samples_per_pixel: 64,
            seed: 1,
        }
    }
}

impl RenderSettings {
    /// Checks that size and samples are between 1 and [`MAX_SETTING`].
    pub fn validate(&self) -> Result<()> {
        for (value, name, what) in [
            (self.width, "--size", "width"),
            (self.height, "--size", "height"),
            (self.samples_per_pixel, "--spp", "samples per pixel"),
        ] {
            if value == 0 || value > MAX_SETTING {
                return Err(Error::invalid(
                    name,
                    format!("{what} is {value}; give a value from 1 to {MAX_SETTING}"),
                ));
            }
        }
        if self.paths() > crate::limits::MAX_RENDER_PATHS {
            return Err(Error::invalid(
                "--spp",
                format!(
                    "{} spp × {}×{} pixels is {} camera paths; at most {} are rendered at once (hours on any machine): lower --spp or --size",
                    self.samples_per_pixel,
                    self.width,
                    self.height,
                    self.paths(),
                    crate::limits::MAX_RENDER_PATHS
                ),
            ));
        }
        Ok(())
    }

    /// width / height.
    pub fn aspect(&self) -> f32 {
        self.width as f32 / self.height as f32
    }

    /// Camera paths of the whole render.
    pub fn paths(&self) -> u64 {
        self.width as u64 * self.height as u64 * self.samples_per_pixel as u64
    }
}

/// A rendered image: mean CIE XYZ per pixel (film units: a white diffuser under the
/// preview's lighting reads Y ≈ 1), rows top to bottom.
#[derive(Debug, Clone)]
pub struct Film {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// XYZ per pixel, row-major.
    pub xyz: Vec<[f32; 3]>,
}

/// Wavelength-sampling density and colour matching for the film, with the hero rotation.
#[inline]
fn camera_wavelengths(sampler: &WavelengthSampler, hero: f32) -> (Vec4, [f32; CHANNELS]) {
    let mut lambda = [0.0; CHANNELS];
    let mut inverse_pdf = [0.0; CHANNELS];
    for j in 0..CHANNELS {
        // hero + j/4 < 2: wrap without `fract`, which is a libm call on baseline x86-64.
        let shifted = hero + j as f32 / CHANNELS as f32;
        let u = if shifted >= 1.0 {
            shifted - 1.0
        } else {
            shifted
        };
        let (nm, pdf) = sampler.sample(u);
        lambda[j] = nm;
        inverse_pdf[j] = 1.0 / (pdf * CHANNELS as f32);
    }
    (Vec4::from_array(lambda), inverse_pdf)
}

/// Renders `scene` into a film of XYZ. `on_row` is called once per finished row (from
/// worker threads), for progress reporting.
pub fn render(
    scene: &Scene,
    settings: &RenderSettings,
    on_row: &(dyn Fn() + Sync),
) -> Result<Film> {
    settings.validate()?;
    let (width, height) = (settings.width, settings.height);
    let observer = Observer::get();
    let sampler = scene.wavelength_sampler();
    let camera = *scene.camera();
    let mut xyz = vec![[0.0f32; 3]; width as usize * height as usize];
    xyz.par_chunks_mut(width as usize)
        .enumerate()
        .for_each(|(y, row)| {
            let y = y as u32;
            for (x, pixel) in row.iter_mut().enumerate() {
                let x = x as u32;
                let mut rng = Rng::for_pixel(settings.seed, x, y, 0);
                let mut sum = Vec4::ZERO;
                for _ in 0..settings.samples_per_pixel {
                    let u = (x as f32 + rng.next_f32()) / width as f32;
                    let v = (y as f32 + rng.next_f32()) / height as f32;
                    let ray = camera.ray(u, v);
                    let (lambda, inverse_pdf) = camera_wavelengths(&sampler, rng.next_f32());
                    let radiance = trace(scene, ray, lambda, &mut rng).to_array();
                    let wavelengths = lambda.to_array();
                    for j in 0..CHANNELS {
                        sum += (radiance[j] * inverse_pdf[j]) * observer.cmf4(wavelengths[j]);
                    }
                }
                let mean = sum / settings.samples_per_pixel as f32;
                *pixel = [mean.x, mean.y, mean.z];
            }
            on_row();
        });
    Ok(Film { width, height, xyz })
}

/// A rectangle of pixels, `x0..x1` × `y0..y1` (half open).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PixelRegion {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
}

impl PixelRegion {
    /// A square of `size` pixels centred on the image.
    pub fn centre(settings: &RenderSettings, size: u32) -> PixelRegion {
        let size = size.min(settings.width).min(settings.height).max(1);
        let x0 = (settings.width - size) / 2;
        let y0 = (settings.height - size) / 2;
        PixelRegion {
            x0,
            y0,
            x1: x0 + size,
            y1: y0 + size,
        }
    }

    fn pixels(&self) -> Vec<(u32, u32)> {
        (self.y0..self.y1)
            .flat_map(|y| (self.x0..self.x1).map(move |x| (x, y)))
            .collect()
    }
}

/// Spectral radiance over a pixel region, with its Monte Carlo standard error.
#[derive(Debug, Clone, PartialEq)]
pub struct SpectralEstimate {
    /// The wavelengths asked for (nm).
    pub wavelength_nm: Vec<f64>,
    /// Mean radiance per wavelength, in units of the scene's light spectrum (at unit
    /// luminance).
    pub mean: Vec<f64>,
    /// Standard error of each mean: the sample standard deviation of the single-path
    /// estimates over √(paths). Paths of different pixels are pooled, so a region whose
    /// radiance varies gets a larger, conservative error.
    pub std_error: Vec<f64>,
    /// Paths traced per wavelength.
    pub paths: u64,
}

/// Estimates the spectral radiance reaching the camera through `region` at each of
/// `wavelengths_nm` (300–780 nm), with `settings.samples_per_pixel` paths per pixel.
/// Wavelengths are traced four at a time, as in [`render`]; all four share the
/// path's directions.
pub fn spectral_radiance(
    scene: &Scene,
    settings: &RenderSettings,
    region: PixelRegion,
    wavelengths_nm: &[f64],
) -> Result<SpectralEstimate> {
    settings.validate()?;
    if region.x0 >= region.x1
        || region.y0 >= region.y1
        || region.x1 > settings.width
        || region.y1 > settings.height
    {
        return Err(Error::invalid(
            "region",
            format!(
                "{region:?} is empty or outside the {}×{} image",
                settings.width, settings.height
            ),
        ));
    }
    if wavelengths_nm.is_empty() {
        return Err(Error::invalid(
            "wavelengths",
            "are empty; ask for at least one",
        ));
    }
    if let Some(bad) = wavelengths_nm
        .iter()
        .find(|l| !(LAMBDA_MIN_NM as f64..=LAMBDA_MAX_NM as f64).contains(*l))
    {
        return Err(Error::invalid(
            "wavelengths",
            format!("include {bad} nm; the renderer carries {LAMBDA_MIN_NM}–{LAMBDA_MAX_NM} nm"),
        ));
    }
    let camera = *scene.camera();
    let pixels = region.pixels();
    let groups: Vec<&[f64]> = wavelengths_nm.chunks(CHANNELS).collect();
    let mut sum = vec![0.0f64; wavelengths_nm.len()];
    let mut sum_sq = vec![0.0f64; wavelengths_nm.len()];
    for (g, group) in groups.iter().enumerate() {
        let mut lambda = [group[0] as f32; CHANNELS];
        for (j, l) in group.iter().enumerate() {
            lambda[j] = *l as f32;
        }
        let lambda = Vec4::from_array(lambda);
        // Per-pixel sums, collected in order and added sequentially so that the result
        // does not depend on how rayon splits the work.
        let per_pixel: Vec<([f64; CHANNELS], [f64; CHANNELS])> = pixels
            .par_iter()
            .map(|&(x, y)| {
                let mut rng = Rng::for_pixel(settings.seed, x, y, 1 + g as u32);
                let mut s = [0.0; CHANNELS];
                let mut s2 = [0.0; CHANNELS];
                for _ in 0..settings.samples_per_pixel {
                    let u = (x as f32 + rng.next_f32()) / settings.width as f32;
                    let v = (y as f32 + rng.next_f32()) / settings.height as f32;
                    let radiance = trace(scene, camera.ray(u, v), lambda, &mut rng).to_array();
                    for j in 0..CHANNELS {
                        let r = radiance[j] as f64;
                        s[j] += r;
                        s2[j] += r * r;
                    }
                }
                (s, s2)
            })
            .collect();
        for (s, s2) in per_pixel {
            for j in 0..group.len() {
                sum[g * CHANNELS + j] += s[j];
                sum_sq[g * CHANNELS + j] += s2[j];
            }
        }
    }
    let n = pixels.len() as u64 * settings.samples_per_pixel as u64;
    let nf = n as f64;
    let mean: Vec<f64> = sum.iter().map(|s| s / nf).collect();
    let std_error = sum_sq
        .iter()
        .zip(&mean)
        .map(|(s2, m)| {
            let variance = ((s2 / nf - m * m) * nf / (nf - 1.0).max(1.0)).max(0.0);
            (variance / nf).sqrt()
        })
        .collect();
    Ok(SpectralEstimate {
        wavelength_nm: wavelengths_nm.to_vec(),
        mean,
        std_error,
        paths: n,
    })
}
