//! Rays, the three shapes the scenes need (sphere, infinite plane, one-sided quad), the
//! pinhole camera and cosine-weighted hemisphere sampling.

use glam::Vec3;

/// Hits closer than this are self-intersections of a ray leaving a surface (scene units;
/// the scenes are a few units across).
pub const RAY_EPSILON: f32 = 1e-4;

/// A ray with a unit direction.
#[derive(Debug, Clone, Copy)]
pub struct Ray {
    /// Start point.
    pub origin: Vec3,
    /// Unit direction.
    pub direction: Vec3,
}

impl Ray {
    /// The point at distance `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + t * self.direction
    }
}

/// A parallelogram `corner + s·edge_u + t·edge_v`, s, t ∈ [0, 1]. Its front faces along
/// edge_u × edge_v; as an emitter it shines from the front only.
#[derive(Debug, Clone, Copy)]
pub struct Quad {
    /// One corner.
    pub corner: Vec3,
    /// First edge from the corner.
    pub edge_u: Vec3,
    /// Second edge from the corner.
    pub edge_v: Vec3,
    /// Unit normal of the front face.
    pub normal: Vec3,
    /// Area.
    pub area: f32,
    /// (edge_u × edge_v) / |edge_u × edge_v|², for the hit's local coordinates.
    w: Vec3,
}

impl Quad {
    /// A quad from a corner and two edges.
    pub fn new(corner: Vec3, edge_u: Vec3, edge_v: Vec3) -> Quad {
        let n = edge_u.cross(edge_v);
        let len2 = n.length_squared();
        Quad {
            corner,
            edge_u,
            edge_v,
            normal: n / len2.sqrt(),
            area: len2.sqrt(),
            w: n / len2,
        }
    }

    /// A square of side `size` centred at `centre`, its front facing `facing`.
    pub fn facing(centre: Vec3, facing: Vec3, size: f32) -> Quad {
        let n = facing.normalize();
        let helper = if n.y.abs() < 0.9 { Vec3::Y } else { Vec3::X };
        let u = helper.cross(n).normalize() * size;
        let v = n.cross(u).normalize() * size;
        Quad::new(centre - 0.5 * u - 0.5 * v, u, v)
    }

    /// The point at local coordinates (s, t) ∈ [0, 1]².
    #[inline]
    pub fn point(&self, s: f32, t: f32) -> Vec3 {
        self.corner + s * self.edge_u + t * self.edge_v
    }
}

/// A shape of the scene.
#[derive(Debug, Clone, Copy)]
pub enum Shape {
    /// A sphere (hit from outside or inside).
    Sphere {
        /// Centre.
        centre: Vec3,
        /// Radius.
        radius: f32,
    },
    /// An infinite plane through `point` with unit `normal`.
    Plane {
        /// A point on the plane.
        point: Vec3,
        /// Unit normal (its front side).
        normal: Vec3,
    },
    /// A parallelogram.
    Quad(Quad),
}

impl Shape {
    /// Distance to the nearest hit in (RAY_EPSILON, t_max), if any.
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<f32> {
        match self {
            Shape::Sphere { centre, radius } => {
                let oc = ray.origin - *centre;
                let b = oc.dot(ray.direction);
                let c = oc.length_squared() - radius * radius;
                let disc = b * b - c;
                if disc < 0.0 {
                    return None;
                }
                let root = disc.sqrt();
                let near = -b - root;
                let t = if near > RAY_EPSILON { near } else { -b + root };
                (t > RAY_EPSILON && t < t_max).then_some(t)
            }
            Shape::Plane { point, normal } => {
                let den = normal.dot(ray.direction);
                if den.abs() < 1e-12 {
                    return None;
                }
                let t = (*point - ray.origin).dot(*normal) / den;
                (t > RAY_EPSILON && t < t_max).then_some(t)
            }
            Shape::Quad(q) => {
                let den = q.normal.dot(ray.direction);
                if den.abs() < 1e-12 {
                    return None;
                }
                let t = (q.corner - ray.origin).dot(q.normal) / den;
                if !(t > RAY_EPSILON && t < t_max) {
                    return None;
                }
                let h = ray.at(t) - q.corner;
                let s = q.w.dot(h.cross(q.edge_v));
                let r = q.w.dot(q.edge_u.cross(h));
                ((0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&r)).then_some(t)
            }
        }
    }

    /// Texture coordinates (u, v) ∈ [0, 1]² of a point on the shape, row 0 of a texture
    /// at v = 0:
    /// - sphere: longitude and latitude, u = φ/2π, v = θ/π, with θ the angle from +y and
    ///   φ running from −z through −x, +z (u = ½) and +x, so that the whole texture wraps
    ///   once, its seam faces −z and a camera on +z sees its middle half upright;
    /// - quad: u = s along `edge_u`, v = 1 − t along `edge_v` (edge_u pointing right and
    ///   edge_v up, the texture appears upright from the front);
    /// - infinite plane: the point's coordinates along two axes in the plane, modulo 1 (the
    ///   texture repeats every scene unit).
    #[inline]
    pub fn uv_at(&self, p: Vec3) -> (f32, f32) {
        match self {
            Shape::Sphere { centre, radius } => {
                let d = (p - *centre) / *radius;
                let u = 0.5 + d.x.atan2(d.z) / std::f32::consts::TAU;
                let v = d.y.clamp(-1.0, 1.0).acos() / std::f32::consts::PI;
                (u.clamp(0.0, 1.0), v)
            }
            Shape::Plane { point, normal } => {
                let (a, b) = normal.any_orthonormal_pair();
                let h = p - *point;
                (h.dot(a).rem_euclid(1.0), h.dot(b).rem_euclid(1.0))
            }
            Shape::Quad(q) => {
                let h = p - q.corner;
                let s = q.w.dot(h.cross(q.edge_v));
                let t = q.w.dot(q.edge_u.cross(h));
                (s.clamp(0.0, 1.0), (1.0 - t).clamp(0.0, 1.0))
            }
        }
    }

    /// Whether u and v of [`Shape::uv_at`] are periodic (the texture continues across
    /// u = 1 to u = 0): a sphere's longitude, both on an infinite plane, neither on a
    /// quad.
    #[inline]
    pub fn uv_wraps(&self) -> [bool; 2] {
        match self {
            Shape::Sphere { .. } => [true, false],
            Shape::Plane { .. } => [true, true],
            Shape::Quad(_) => [false, false],
        }
    }

    /// The outward (front) unit normal at a point on the shape.
    #[inline]
    pub fn normal_at(&self, p: Vec3) -> Vec3 {
        match self {
            Shape::Sphere { centre, radius } => (p - *centre) / *radius,
            Shape::Plane { normal, .. } => *normal,
            Shape::Quad(q) => q.normal,
        }
    }
}

/// A pinhole camera.
#[derive(Debug, Clone, Copy)]
pub struct Camera {
    /// Eye position.
    pub eye: Vec3,
    /// Direction to the image's top-left corner at unit distance along the view.
    top_left: Vec3,
    /// Full image width and height vectors at unit distance (right, down).
    right: Vec3,
    down: Vec3,
}

impl Camera {
    /// A camera at `eye` looking at `target` with +y up (−z up when looking straight
    /// up or down), a vertical field of view of `vfov_deg` degrees and image aspect
    /// `aspect` = width / height.
    pub fn look_at(eye: Vec3, target: Vec3, vfov_deg: f32, aspect: f32) -> Camera {
        let forward = (target - eye).normalize();
        let up = if forward.cross(Vec3::Y).length_squared() > 1e-8 {
            Vec3::Y
        } else {
            -Vec3::Z
        };
        let right_dir = forward.cross(up).normalize();
        let up_dir = right_dir.cross(forward);
        let half_h = (0.5 * vfov_deg.to_radians()).tan();
        let half_w = half_h * aspect;
        Camera {
            eye,
            top_left: forward - half_w * right_dir + half_h * up_dir,
            right: 2.0 * half_w * right_dir,
            down: -2.0 * half_h * up_dir,
        }
    }

    /// Image coordinates (u, v) of a point in front of the camera (inverse of
    /// [`Camera::ray`]); None for points behind it.
    pub fn project(&self, point: Vec3) -> Option<(f32, f32)> {
        let d = point - self.eye;
        let right = self.right / self.right.length_squared();
        let down = self.down / self.down.length_squared();
        let forward = self.top_left + 0.5 * self.right + 0.5 * self.down;
        let depth = d.dot(forward) / forward.length_squared();
        if depth <= 0.0 {
            return None;
        }
        let on_plane = d / depth - self.top_left;
        Some((on_plane.dot(right), on_plane.dot(down)))
    }

    /// The ray through image coordinates (u, v) ∈ [0, 1]², u to the right, v downwards.
    #[inline]
    pub fn ray(&self, u: f32, v: f32) -> Ray {
        Ray {
            origin: self.eye,
            direction: (self.top_left + u * self.right + v * self.down).normalize(),
        }
    }
}

/// A direction around the unit normal `n` with density cos θ / π, from two uniform
/// numbers (Malley's method on a branchless orthonormal basis, Duff et al. 2017).
#[inline]
pub fn cosine_sample(n: Vec3, u1: f32, u2: f32) -> Vec3 {
    let r = u1.sqrt();
    let phi = std::f32::consts::TAU * u2;
    let (sin_phi, cos_phi) = phi.sin_cos();
    let x = r * cos_phi;
    let y = r * sin_phi;
    let z = (1.0 - u1).max(0.0).sqrt();
    let (t, b) = n.any_orthonormal_pair();
    // Unit length by construction (x² + y² + z² = 1 on an orthonormal basis).
    x * t + y * b + z * n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_are_hit_where_expected() {
        let ray = Ray {
            origin: Vec3::new(0.0, 0.0, 5.0),
            direction: -Vec3::Z,
        };
        let sphere = Shape::Sphere {
            centre: Vec3::ZERO,
            radius: 1.0,
        };
        assert!((sphere.intersect(&ray, f32::INFINITY).unwrap() - 4.0).abs() < 1e-5);
        let inside = Ray {
            origin: Vec3::ZERO,
            direction: Vec3::X,
        };
        assert!((sphere.intersect(&inside, f32::INFINITY).unwrap() - 1.0).abs() < 1e-5);
        let quad = Shape::Quad(Quad::facing(Vec3::ZERO, Vec3::Z, 2.0));
        assert!((quad.intersect(&ray, f32::INFINITY).unwrap() - 5.0).abs() < 1e-5);
        let miss = Ray {
            origin: Vec3::new(1.5, 0.0, 5.0),
            direction: -Vec3::Z,
        };
        assert!(quad.intersect(&miss, f32::INFINITY).is_none());
        let plane = Shape::Plane {
            point: Vec3::ZERO,
            normal: Vec3::Y,
        };
        let down = Ray {
            origin: Vec3::new(3.0, 2.0, 1.0),
            direction: -Vec3::Y,
        };
        assert!((plane.intersect(&down, f32::INFINITY).unwrap() - 2.0).abs() < 1e-5);
        assert!(plane.intersect(&down, 1.0).is_none());
    }

    #[test]
    fn texture_coordinates_follow_the_stated_conventions() {
        let sphere = Shape::Sphere {
            centre: Vec3::new(1.0, 2.0, 3.0),
            radius: 2.0,
        };
        let at = |d: Vec3| sphere.uv_at(Vec3::new(1.0, 2.0, 3.0) + 2.0 * d.normalize());
        let close = |(u, v): (f32, f32), (eu, ev): (f32, f32)| {
            assert!((u - eu).abs() < 1e-5 && (v - ev).abs() < 1e-5, "{u} {v}");
        };
        close(at(Vec3::Z), (0.5, 0.5));
        close(at(Vec3::X), (0.75, 0.5));
        close(at(-Vec3::X), (0.25, 0.5));
        close(at(Vec3::Y), (at(Vec3::Y).0, 0.0));
        close(at(-Vec3::Y), (at(-Vec3::Y).0, 1.0));
        close(at(Vec3::new(0.0, 1.0, 1.0)), (0.5, 0.25));
        assert_eq!(sphere.uv_wraps(), [true, false]);
        // A quad with edge_u right and edge_v up: its top-left corner is (0, 0).
        let quad = Shape::Quad(Quad::new(Vec3::ZERO, Vec3::X * 4.0, Vec3::Y * 2.0));
        close(quad.uv_at(Vec3::new(0.0, 2.0, 0.0)), (0.0, 0.0));
        close(quad.uv_at(Vec3::new(1.0, 0.5, 0.0)), (0.25, 0.75));
        assert_eq!(quad.uv_wraps(), [false, false]);
    }

    #[test]
    fn camera_projection_inverts_rays() {
        let camera = Camera::look_at(Vec3::new(1.0, 2.0, 5.0), Vec3::ZERO, 40.0, 1.5);
        for (u, v) in [(0.5, 0.5), (0.1, 0.9), (0.8, 0.25)] {
            let ray = camera.ray(u, v);
            let (pu, pv) = camera.project(ray.at(3.0)).unwrap();
            assert!((pu - u).abs() < 1e-5 && (pv - v).abs() < 1e-5, "{pu} {pv}");
        }
        let (u, v) = camera.project(Vec3::ZERO).unwrap();
        assert!((u - 0.5).abs() < 1e-5 && (v - 0.5).abs() < 1e-5);
        assert!(camera.project(Vec3::new(2.0, 4.0, 10.0)).is_none());
    }

    #[test]
    fn cosine_sampling_has_mean_cosine_two_thirds() {
        // E[cos θ] under the density cos θ/π is 2/3.
        let n = Vec3::new(0.3, 0.9, -0.2).normalize();
        let steps = 200;
        let mut sum = 0.0;
        for i in 0..steps {
            for j in 0..steps {
                let d = cosine_sample(
                    n,
                    (i as f32 + 0.5) / steps as f32,
                    (j as f32 + 0.5) / steps as f32,
                );
                assert!(d.dot(n) >= -1e-6);
                sum += d.dot(n) as f64;
            }
        }
        let mean = sum / (steps * steps) as f64;
        assert!((mean - 2.0 / 3.0).abs() < 1e-3, "{mean}");
    }
}
