//! What a synthetic image shows: one soft-edged elliptical region per fluorophore with a
//! concentration gradient inside it, a strip without fluorescence along the right edge,
//! and a reflectance that blends the source materials' reflectances smoothly over the
//! image, darkening towards the bottom. Everything is drawn from the seed once; a pixel's
//! values are then a closed-form function of its position, so tiles can be computed in
//! any order.

use serde::{Deserialize, Serialize};

use crate::numeric::SplitMix64;

/// The region of one fluorophore: an ellipse whose edge falls off smoothly, with the
/// concentration rising linearly across it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Region {
    /// The fluorophore (index into the image's fluorophores, from 0).
    pub fluorophore: usize,
    /// Centre (x, y) in pixels from the image's top-left corner.
    pub centre_px: [f64; 2],
    /// Semi-axes (pixels) before rotation.
    pub semi_axes_px: [f64; 2],
    /// Rotation of the ellipse (degrees, clockwise on screen).
    pub rotation_deg: f64,
    /// Direction in which the concentration rises (degrees).
    pub gradient_deg: f64,
    /// Fraction of the peak concentration on the gradient's low side (the high side
    /// reaches the peak).
    pub gradient_low: f64,
    /// The concentration on the gradient's high side, before the soft edge and before
    /// overlapping regions are scaled to Σ c·a ≤ 1: the source fit's concentration.
    pub peak_concentration: f64,
}

/// A point where one source material's reflectance dominates the blend.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Anchor {
    /// The source material (index into the image's sources, from 0).
    pub source: usize,
    /// Position (x, y) in pixels.
    pub centre_px: [f64; 2],
}

/// The content of a synthetic image, in pixels of an image of the given size.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scene {
    /// One region per fluorophore, in order.
    pub regions: Vec<Region>,
    /// Pixels whose centre lies at x ≥ this hold no fluorescence at all; the regions fade
    /// out over `falloff_px` before it.
    pub plain_from_x_px: f64,
    /// Width of every soft edge (pixels): regions reach full strength this far inside
    /// their boundary.
    pub falloff_px: f64,
    /// One anchor per source material: the reflectance at a pixel is the blend of the
    /// sources' reflectances with Gaussian weights of the distance to each anchor.
    pub anchors: Vec<Anchor>,
    /// Standard deviation of those Gaussian weights (pixels).
    pub blend_px: f64,
    /// The reflectance is scaled by 1 − shading·(y / height)²: darker towards the bottom.
    pub shading: f64,
}

/// t²(3 − 2t) on t clamped to [0, 1]: 0 below, 1 above, smooth in between.
fn smoothstep(t: f64) -> f64 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

impl Scene {
    /// The scene of a `width` × `height` image with one region per entry of
    /// `peak_concentrations` and one reflectance anchor per source, drawn from `seed`.
    pub fn new(
        width: usize,
        height: usize,
        peak_concentrations: &[f64],
        sources: usize,
        falloff_px: f64,
        seed: u64,
    ) -> Scene {
        let (w, h) = (width as f64, height as f64);
        let mut rng = SplitMix64::new(seed ^ 0x5343_454E_455F_5631);
        let k = peak_concentrations.len().max(1) as f64;
        let regions = peak_concentrations
            .iter()
            .enumerate()
            .map(|(n, &peak)| {
                // Centres spread from left to right over the fluorescent part, each with
                // some jitter; sizes a fifth to a third of the image.
                let cx = w * (0.1 + 0.55 * (n as f64 + 0.5) / k + 0.06 * (rng.uniform() - 0.5));
                let cy = h * (0.3 + 0.4 * rng.uniform());
                let ax = w * (0.14 + 0.1 * rng.uniform());
                let ay = h * (0.2 + 0.14 * rng.uniform());
                Region {
                    fluorophore: n,
                    centre_px: [cx, cy],
                    semi_axes_px: [ax, ay],
                    rotation_deg: 180.0 * rng.uniform(),
                    gradient_deg: 360.0 * rng.uniform(),
                    gradient_low: 0.15 + 0.2 * rng.uniform(),
                    peak_concentration: peak,
                }
            })
            .collect();
        let anchors = (0..sources)
            .map(|source| Anchor {
                source,
                centre_px: [w * rng.uniform(), h * rng.uniform()],
            })
            .collect();
        Scene {
            regions,
            plain_from_x_px: 0.8 * w,
            falloff_px,
            anchors,
            blend_px: 0.3 * w.hypot(h) / (sources.max(1) as f64).sqrt(),
            shading: 0.4,
        }
    }

    /// The concentration of each fluorophore at pixel (x, y) before overlapping regions
    /// are scaled to Σ c·a ≤ 1, into `out` (one value per region).
    pub fn concentrations(&self, x: usize, y: usize, out: &mut [f64]) {
        let (u, v) = (x as f64 + 0.5, y as f64 + 0.5);
        let fade = |distance: f64| {
            if self.falloff_px > 0.0 {
                smoothstep(distance / self.falloff_px)
            } else if distance > 0.0 {
                1.0
            } else {
                0.0
            }
        };
        let plain = fade(self.plain_from_x_px - u);
        for (c, region) in out.iter_mut().zip(&self.regions) {
            *c = if plain > 0.0 {
                plain * region.weight(u, v, &fade)
            } else {
                0.0
            };
        }
    }

    /// The blend weights of the source reflectances at pixel (x, y), into `out` (one per
    /// source); they sum to the shading factor (≤ 1), so a blend of reflectances in
    /// [0, 1] stays in [0, 1].
    pub fn blend(&self, x: usize, y: usize, height: usize, out: &mut [f64]) {
        let (u, v) = (x as f64 + 0.5, y as f64 + 0.5);
        let mut total = 0.0;
        for (m, anchor) in out.iter_mut().zip(&self.anchors) {
            let d2 = (u - anchor.centre_px[0]).powi(2) + (v - anchor.centre_px[1]).powi(2);
            *m = (-0.5 * d2 / self.blend_px.powi(2)).exp();
            total += *m;
        }
        let shade = 1.0 - self.shading * (v / height.max(1) as f64).powi(2);
        let n = out.len().max(1) as f64;
        for m in out.iter_mut() {
            // Far from every anchor the weights all underflow: an even blend.
            *m = if total > 0.0 { *m / total } else { 1.0 / n } * shade;
        }
    }
}

impl Region {
    /// The concentration at (u, v) (pixel units): the peak times the gradient times the
    /// soft edge `fade(distance inside the edge)`.
    fn weight(&self, u: f64, v: f64, fade: &impl Fn(f64) -> f64) -> f64 {
        let (dx, dy) = (u - self.centre_px[0], v - self.centre_px[1]);
        let (s, c) = self.rotation_deg.to_radians().sin_cos();
        let (xr, yr) = (dx * c + dy * s, -dx * s + dy * c);
        let [ax, ay] = self.semi_axes_px;
        let rho = ((xr / ax).powi(2) + (yr / ay).powi(2)).sqrt();
        if rho.is_nan() || rho >= 1.0 {
            return 0.0;
        }
        // Distance to the edge along the ray from the centre (exact on that ray).
        let radial = xr.hypot(yr);
        let inside = if rho > 0.0 {
            radial * (1.0 / rho - 1.0)
        } else {
            ax.min(ay)
        };
        let (gs, gc) = self.gradient_deg.to_radians().sin_cos();
        let t = (0.5 + 0.5 * (dx * gc + dy * gs) / ax.max(ay)).clamp(0.0, 1.0);
        let gradient = self.gradient_low + (1.0 - self.gradient_low) * t;
        self.peak_concentration * gradient * fade(inside)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_right_strip_is_plain_and_regions_reach_their_peak_only_inside() {
        let scene = Scene::new(200, 100, &[0.9, 0.5], 2, 4.0, 7);
        let mut c = [0.0; 2];
        for y in 0..100 {
            for x in 160..200 {
                scene.concentrations(x, y, &mut c);
                assert_eq!(c, [0.0, 0.0], "({x}, {y})");
            }
        }
        let mut peak = [0.0f64; 2];
        for y in 0..100 {
            for x in 0..200 {
                scene.concentrations(x, y, &mut c);
                for k in 0..2 {
                    assert!(c[k] >= 0.0 && c[k] <= scene.regions[k].peak_concentration);
                    peak[k] = peak[k].max(c[k]);
                }
            }
        }
        assert!(peak[0] > 0.5 && peak[1] > 0.25, "{peak:?}");
    }

    #[test]
    fn blend_weights_are_a_shaded_partition_of_unity() {
        let scene = Scene::new(64, 48, &[0.5], 3, 4.0, 1);
        let mut m = [0.0; 3];
        for (x, y) in [(0, 0), (63, 47), (30, 20)] {
            scene.blend(x, y, 48, &mut m);
            let shade = 1.0 - 0.4 * ((y as f64 + 0.5) / 48.0).powi(2);
            assert!((m.iter().sum::<f64>() - shade).abs() < 1e-12);
            assert!(m.iter().all(|&w| w >= 0.0));
        }
    }
}
