//! The spectral path tracer.
//!
//! A camera path carries four wavelengths at once (hero-wavelength sampling: one drawn,
//! three rotated from it in primary sample space). Every surface is Lambertian in
//! direction, reflecting and reradiating alike (model.md §1), so one cosine-sampled
//! direction serves all four; only the wavelength bookkeeping differs per channel. At a
//! surface each channel, at its current wavelength λo, chooses between
//! - the elastic branch, probability d(λo) / (d(λo) + F(λo)), keeping λo, and
//! - the fluorescent branch, probability F(λo) / (d(λo) + F(λo)) with
//!   F(λo) = Σ k·A·e(λo): a fluorophore with probability ∝ its k·A·e(λo), then the
//!   excitation wavelength λi with density x(λi)·a(λi)/A, which becomes the channel's
//!   wavelength. x is the yield form's excitation factor: 1 for a constant energy yield
//!   Q (k = c·Q), λi/λ̄e for a constant photon yield Φ (k = c·Φ, energy yield Φ·λi/λ̄e),
//!   and A = ∫x·a dλ.
//!
//! In both branches the channel's weight is multiplied by d(λo) + F(λo), the camera-side
//! row albedo (model.md §6), which is exactly f/p for these choices: the fluorescent
//! term k·x(λi)·a(λi)·e(λo) over P(branch)·P(fluorophore)·p(λi) =
//! [F/(d + F)]·[k·A·e(λo)/F]·[x·a/A] is d + F in either form. Light arriving at the
//! surface is then gathered at the (possibly new) wavelength by next-event estimation
//! towards the area lights and by the continued path, combined with the power heuristic.
//! Russian roulette ends paths whose weight has fallen.

use std::f32::consts::PI;

use glam::{Vec3, Vec4};

use super::geometry::{RAY_EPSILON, Ray, Shape, cosine_sample};
use super::rng::Rng;
use super::scene::Scene;
use super::spectra::{Lookup, SurfaceTables};

/// Wavelengths a camera path carries.
pub const CHANNELS: usize = 4;
/// Hard cap on path length; Russian roulette ends paths long before in any scene whose
/// albedo stays below 1.
pub const MAX_BOUNCES: u32 = 256;

/// Power heuristic (β = 2) weight of the strategy with density `pdf` against `other`.
#[inline]
fn power_heuristic(pdf: f32, other: f32) -> f32 {
    let a = pdf * pdf;
    let b = other * other;
    if a + b > 0.0 { a / (a + b) } else { 0.0 }
}

/// Chooses each channel's branch at a surface; moves fluorescent channels to their
/// excitation wavelength. Returns the weight factor d + F per channel and whether any
/// wavelength changed.
#[inline]
fn scatter(surface: &SurfaceTables, lambda: &mut Vec4, at: &Lookup, rng: &mut Rng) -> (Vec4, bool) {
    let d = surface.diagonal.gather(at);
    if !surface.is_fluorescent() {
        return (d, false);
    }
    let f = surface.fluorescent_albedo.gather(at);
    let total = d + f;
    let mut wavelengths = lambda.to_array();
    let fluorescent = f.to_array();
    let totals = total.to_array();
    let mut changed = false;
    for j in 0..CHANNELS {
        if fluorescent[j] > 0.0 && rng.next_f32() * totals[j] < fluorescent[j] {
            wavelengths[j] = excite(surface, wavelengths[j], fluorescent[j], rng);
            changed = true;
        }
    }
    if changed {
        *lambda = Vec4::from_array(wavelengths);
    }
    (total, changed)
}

/// The excitation wavelength of a fluorescent event seen from emission wavelength
/// `lambda_o` (F = the surface's fluorescent albedo there).
#[inline]
fn excite(surface: &SurfaceTables, lambda_o: f32, albedo: f32, rng: &mut Rng) -> f32 {
    let fluorophores = &surface.fluorophores;
    let chosen = if fluorophores.len() == 1 {
        &fluorophores[0]
    } else {
        let mut u = rng.next_f32() * albedo;
        let mut chosen = &fluorophores[fluorophores.len() - 1];
        for f in fluorophores {
            let share = f.albedo.eval(lambda_o);
            if u < share {
                chosen = f;
                break;
            }
            u -= share;
        }
        chosen
    };
    let u = rng.next_f32();
    chosen.sample_excitation(u, || rng.next_f32())
}

/// Spectral radiance arriving along `ray` at the four wavelengths `lambda` (nm, each in
/// 300–780), estimated by one path. Radiance is in units of the scene's light spectrum.
pub fn trace(scene: &Scene, mut ray: Ray, mut lambda: Vec4, rng: &mut Rng) -> Vec4 {
    let light = &scene.light().radiance;
    let mut at = Lookup::new(lambda);
    // The light spectrum at the path's current wavelengths (every emitter shares it).
    let mut emitted = light.gather(&at);
    let objects = scene.objects();
    let surfaces = scene.surfaces();
    let environment = scene.environment();
    let mut radiance = Vec4::ZERO;
    let mut weight = Vec4::ONE;
    // Solid-angle density of the direction that led here; 0 for the camera ray, whose
    // emitter hits need no multiple-importance weight.
    let mut direction_pdf = 0.0f32;
    for _ in 0..MAX_BOUNCES {
        let Some(hit) = scene.intersect(&ray, f32::INFINITY) else {
            if environment > 0.0 {
                radiance += weight * environment * emitted;
            }
            break;
        };
        let object = &objects[hit.object];
        let point = ray.at(hit.t);
        let outward = object.shape.normal_at(point);
        let cos_hit = outward.dot(ray.direction);
        if object.emission > 0.0 {
            match object.shape {
                Shape::Quad(quad) => {
                    if cos_hit < 0.0 {
                        let mis = if direction_pdf > 0.0 {
                            let light_pdf = hit.t * hit.t / (-cos_hit * quad.area);
                            power_heuristic(direction_pdf, light_pdf)
                        } else {
                            1.0
                        };
                        radiance += weight * (object.emission * mis) * emitted;
                    }
                }
                _ => radiance += weight * object.emission * emitted,
            }
        }
        let Some(surface) = object.surface else {
            break;
        };
        let normal = if cos_hit < 0.0 { outward } else { -outward };
        let (albedo, changed) = scatter(&surfaces[surface], &mut lambda, &at, rng);
        weight *= albedo;
        if changed {
            at = Lookup::new(lambda);
            emitted = light.gather(&at);
        }
        if weight.max_element() <= 0.0 {
            break;
        }
        let origin = point + normal * RAY_EPSILON;
        radiance += weight * emitted * direct_light(scene, origin, normal, rng);
        // Russian roulette from the first surface on, after the direct light: survival
        // in proportion to the path weight, so that surviving paths carry weight ≈ 1.
        let survival = weight.max_element().min(1.0);
        if rng.next_f32() >= survival {
            break;
        }
        weight /= survival;
        let direction = cosine_sample(normal, rng.next_f32(), rng.next_f32());
        direction_pdf = normal.dot(direction).max(1e-7) / PI;
        ray = Ray { origin, direction };
    }
    radiance
}

/// Next-event estimate of the light from the emitting quads reflected by a unit-albedo
/// Lambertian surface at `origin`, per unit of the light spectrum (the caller applies
/// the spectrum and the branch weight).
#[inline]
fn direct_light(scene: &Scene, origin: Vec3, normal: Vec3, rng: &mut Rng) -> f32 {
    let mut sum = 0.0;
    for &index in scene.lights() {
        let object = &scene.objects()[index];
        let Shape::Quad(quad) = object.shape else {
            continue;
        };
        let target = quad.point(rng.next_f32(), rng.next_f32());
        let to_light = target - origin;
        let distance2 = to_light.length_squared();
        let distance = distance2.sqrt();
        let direction = to_light / distance;
        let cos_surface = normal.dot(direction);
        let cos_light = -quad.normal.dot(direction);
        if cos_surface <= 0.0 || cos_light <= 0.0 {
            continue;
        }
        let shadow = Ray { origin, direction };
        if scene.occluded(&shadow, distance * (1.0 - 1e-4), index) {
            continue;
        }
        let light_pdf = distance2 / (cos_light * quad.area);
        let brdf_cos = cos_surface / PI;
        let mis = power_heuristic(light_pdf, brdf_cos);
        sum += object.emission * brdf_cos * mis / light_pdf;
    }
    sum
}
