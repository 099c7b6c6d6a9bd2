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
//!
//! A surface is first evaluated at the hit ([`Surface::at`](super::surface::Surface::at)):
//! a material map's texel there has its own d, F and G, and each fluorophore's k is
//! scaled by the texel's concentration; every rule here then reads that point alike.
//!
//! That is the paper's rule ([`SpectralSampling::Paper`]); by default
//! ([`SpectralSampling::LightAware`]) a fluorescent surface draws its event by one-sample
//! multiple importance sampling of that rule (share α = [`DEFENSIVE_SHARE`]) and of the
//! same rule weighted by the scene's light spectrum L at the excitation wavelength (every
//! emitter and the environment share L): elastic ∝ d(λo)·L(λo), fluorophore ∝
//! k·e(λo)·∫x·a·L, λi ∝ x·a·L (Mojzík, Fichet and Wilkie 2018 follow absorption × incident
//! light likewise). The weight f/(α·p1 + (1 − α)·p2) is exact for both yield forms and
//! any number of fluorophores; under a UV LED or F11's lines it makes the weight times
//! the light at λi nearly constant.

use std::f32::consts::PI;

use glam::{Vec3, Vec4};

use super::geometry::{RAY_EPSILON, Ray, Shape, cosine_sample};
use super::rng::Rng;
use super::scene::{Scene, SpectralSampling};
use super::spectra::{FluorophoreTables, Lookup};
use super::surface::SurfacePoint;

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

/// Share of the events at a fluorescent surface that the light-aware mixture draws by
/// the paper's rule (α): it keeps every excitation wavelength the material can absorb
/// reachable when the incident light does not have the light's spectrum (light re-emitted
/// by other fluorescent surfaces, for one), and bounds the path weight by (d + F)/α.
pub const DEFENSIVE_SHARE: f32 = 0.2;

/// Chooses each channel's branch at a surface; moves fluorescent channels to their
/// excitation wavelength. `light` is the scene's light spectrum at the channels'
/// wavelengths. Returns the weight factor f/p per channel and whether any wavelength
/// changed.
#[inline]
fn scatter(
    surface: &SurfacePoint,
    lambda: &mut Vec4,
    light: Vec4,
    sampling: SpectralSampling,
    rng: &mut Rng,
) -> (Vec4, bool) {
    let d = surface.diagonal;
    if !surface.is_fluorescent() {
        return (d, false);
    }
    let f = surface.fluorescent_albedo;
    let total = d + f;
    let mut wavelengths = lambda.to_array();
    let fluorescent = f.to_array();
    let totals = total.to_array();
    let mut changed = false;
    if sampling == SpectralSampling::Paper {
        for j in 0..CHANNELS {
            if fluorescent[j] > 0.0 && rng.next_f32() * totals[j] < fluorescent[j] {
                wavelengths[j] = excite(surface, wavelengths[j], fluorescent[j], rng).1;
                changed = true;
            }
        }
        if changed {
            *lambda = Vec4::from_array(wavelengths);
        }
        return (total, changed);
    }
    // One-sample MIS of two strategies, balance heuristic: with probability α the
    // paper's (event ∝ d or k·x·a·e, mass d + F), else the light-weighted one (event ∝ d·L(λo)
    // or k·x·a·L·e, mass T = d·L(λo) + G). The weight f/(α·p1 + (1 − α)·p2) is
    // 1/(α/(d + F) + (1 − α)·L(λo)/T) for the elastic branch and
    // x·a/(α·x·a/(d + F) + (1 − α)·ĝ/T) at the excitation wavelength (ĝ ≈ x·a·L).
    let lit = surface.lit_albedo;
    let lit_totals = (d * light + lit).to_array();
    let lits = lit.to_array();
    let diagonal = d.to_array();
    let light = light.to_array();
    let mut weights = [0.0f32; CHANNELS];
    for j in 0..CHANNELS {
        let alpha = if lit_totals[j] > 0.0 {
            DEFENSIVE_SHARE
        } else {
            1.0
        };
        let by_light = alpha < 1.0 && rng.next_f32() >= alpha;
        let (event, mass) = if by_light {
            (lits[j], lit_totals[j])
        } else {
            (fluorescent[j], totals[j])
        };
        if event > 0.0 && rng.next_f32() * mass < event {
            let (chosen, nm) = excite_mixed(surface, wavelengths[j], event, by_light, rng);
            let xa = chosen.excitation_factor(nm) * chosen.absorption.eval(nm);
            let mut density = alpha * xa / totals[j];
            if alpha < 1.0
                && let Some(l) = &chosen.lit
            {
                density += (1.0 - alpha) * l.product.eval(nm) / lit_totals[j];
            }
            weights[j] = if density > 0.0 { xa / density } else { 0.0 };
            wavelengths[j] = nm;
            changed = true;
        } else if diagonal[j] > 0.0 {
            let mut density = alpha / totals[j];
            if alpha < 1.0 {
                density += (1.0 - alpha) * light[j] / lit_totals[j];
            }
            weights[j] = 1.0 / density;
        }
    }
    if changed {
        *lambda = Vec4::from_array(wavelengths);
    }
    (Vec4::from_array(weights), changed)
}

/// The fluorophore and excitation wavelength of a fluorescent event by the paper's rule,
/// seen from emission wavelength `lambda_o` (F = the surface's fluorescent albedo there).
#[inline]
fn excite<'s>(
    surface: &SurfacePoint<'s>,
    lambda_o: f32,
    albedo: f32,
    rng: &mut Rng,
) -> (&'s FluorophoreTables, f32) {
    let fluorophores = surface.fluorophores;
    let chosen = if fluorophores.len() == 1 {
        &fluorophores[0]
    } else {
        let mut u = rng.next_f32() * albedo;
        let mut chosen = surface.fallback(false);
        for (j, f) in fluorophores.iter().enumerate() {
            let share = surface.scale(j) * f.albedo.eval(lambda_o);
            if u < share {
                chosen = f;
                break;
            }
            u -= share;
        }
        chosen
    };
    let u = rng.next_f32();
    (chosen, chosen.sample_excitation(u, || rng.next_f32()))
}

/// The fluorophore and excitation wavelength of a fluorescent event seen from emission
/// wavelength `lambda_o`: by the paper's rule (fluorophore ∝ k·A·e(λo), λi ∝ x·a; `mass`
/// = F there) or, `by_light`, by the light-weighted rule (fluorophore ∝ k·B·e(λo),
/// λi ∝ ĝ; `mass` = G there).
#[inline]
fn excite_mixed<'s>(
    surface: &SurfacePoint<'s>,
    lambda_o: f32,
    mass: f32,
    by_light: bool,
    rng: &mut Rng,
) -> (&'s FluorophoreTables, f32) {
    if !by_light {
        return excite(surface, lambda_o, mass, rng);
    }
    let fluorophores = surface.fluorophores;
    // Some fluorophore absorbs the light: the caller draws this rule only when G > 0.
    let chosen = if fluorophores.len() == 1 {
        &fluorophores[0]
    } else {
        let mut u = rng.next_f32() * mass;
        let mut chosen = surface.fallback(true);
        for (j, f) in fluorophores.iter().enumerate() {
            let share = surface.scale(j)
                * f.lit
                    .as_ref()
                    .map_or(0.0, |l| f.k * l.absorbed * f.emission.eval(lambda_o));
            if u < share {
                chosen = f;
                break;
            }
            u -= share;
        }
        chosen
    };
    let nm = match &chosen.lit {
        Some(l) => l.sample(rng.next_f32()),
        None => chosen.sample_excitation(rng.next_f32(), || rng.next_f32()),
    };
    (chosen, nm)
}

/// Spectral radiance arriving along `ray` at the four wavelengths `lambda` (nm, each in
/// 300–780), estimated by one path. Radiance is in units of the scene's light spectrum.
pub fn trace(scene: &Scene, mut ray: Ray, mut lambda: Vec4, rng: &mut Rng) -> Vec4 {
    let light = &scene.light().radiance;
    let mut at = Lookup::new(lambda);
    // The light spectrum at the path's current wavelengths (every emitter shares it).
    let mut emitted = light.gather(&at);
    let sampling = scene.spectral_sampling();
    // Russian roulette weighs each channel by (L(λ) + L̄)/(L(λo) + L̄): the light at its
    // current wavelength against the light at the wavelength it started from (L̄ the
    // light's mean, so that the ratio is positive and 1 until a fluorescent event). A
    // light-aware event to a strong line (a UV LED) gives a small weight that the light
    // there makes up for; the plain weight would end most such paths.
    let mean_light = scene.light().mean_radiance;
    let start_light = emitted + Vec4::splat(mean_light);
    let objects = scene.objects();
    let surfaces = scene.surfaces();
    let environment = scene.environment();
    let mut radiance = Vec4::ZERO;
    let mut weight = Vec4::ONE;
    // Solid-angle density of the direction that led here; 0 for the camera ray, whose
    // emitter hits need no multiple-importance weight.
    let mut direction_pdf = 0.0f32;
    for bounce in 0..MAX_BOUNCES {
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
        let local = surfaces[surface].at(&object.shape, point, &at, lambda);
        let (albedo, changed) = scatter(&local, &mut lambda, emitted, sampling, rng);
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
        // Russian roulette after the direct light: survival in proportion to the path
        // weight (light-aware: times the light ratio above, and never at a fluorescent
        // first surface, where a channel's weight says little about what the pixel
        // gains: ending such paths there made the furnace under F11 twice as noisy),
        // so that surviving paths carry weight ≈ 1.
        let importance = match sampling {
            SpectralSampling::Paper => weight,
            SpectralSampling::LightAware => {
                weight * (emitted + Vec4::splat(mean_light)) / start_light
            }
        };
        let survival =
            if bounce == 0 && sampling == SpectralSampling::LightAware && local.is_fluorescent() {
                1.0
            } else {
                importance.max_element().min(1.0)
            };
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
