//! Scenes: objects with surfaces and emission, one light spectrum shared by every emitter
//! and the environment, a camera; and the built-in scenes (preview, furnace, plane), which
//! show a material or a material map ([`MaterialSource`]).

use glam::Vec3;

use crate::colour::Light;
use crate::error::{Error, Result};

use super::geometry::{Camera, Quad, Ray, Shape};
use super::spectra::{LightSpectrum, SurfaceTables};
use super::surface::{MaterialSource, Surface};
use super::wavelengths::WavelengthSampler;

/// Reflectance of the neutral grey ground of the preview scene.
pub const GROUND_REFLECTANCE: f32 = 0.35;
/// Radiance of the preview's dim environment, relative to the light's unit luminance: a
/// white diffuser facing up would read Y = 0.15 from the environment alone.
pub const PREVIEW_ENVIRONMENT: f32 = 0.15;
/// Radiance of the furnace environment (the light at unit luminance).
pub const FURNACE_ENVIRONMENT: f32 = 1.0;
/// Radius of the material's sphere.
pub const SPHERE_RADIUS: f32 = 1.0;
/// Horizontal distance of each sphere's centre from the middle in `--compare` renders.
pub const COMPARE_OFFSET: f32 = 1.15;
/// Half the longer side of the plane scene's rectangle (scene units; the shorter side
/// follows the texture's aspect).
pub const PLANE_HALF_SIZE: f32 = 1.0;
/// Gap between the material's rectangle and its twin in `--compare` plane renders.
pub const PLANE_COMPARE_GAP: f32 = 0.3;

/// Which built-in scene to render.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SceneKind {
    /// The material on a sphere resting on a grey ground, lit by a large area light and a
    /// dim environment of the same spectrum.
    #[default]
    Preview,
    /// The material on a sphere alone in a uniform environment (for checks: its exact
    /// radiance is known, model.md §6).
    Furnace,
    /// The material on a rectangle facing the camera, alone in a uniform environment of
    /// the light: every point shows the flat-patch colour of its material (model.md §7),
    /// exactly known (model.md §6). Its texture coordinates span a material map once,
    /// upright; the rectangle has the map's aspect (a square for a uniform material).
    Plane,
}

/// An object of a scene.
#[derive(Debug, Clone, Copy)]
pub struct Object {
    /// Its shape.
    pub shape: Shape,
    /// Index of its surface in the scene's surfaces; None for a black (non-reflecting)
    /// object such as the area light's housing.
    pub surface: Option<usize>,
    /// Emitted radiance as a multiple of the scene's light spectrum (0 for none). Quads
    /// emit from their front only; spheres and planes from both sides.
    pub emission: f32,
}

/// The nearest hit of a ray.
#[derive(Debug, Clone, Copy)]
pub struct Hit {
    /// Index of the object hit.
    pub object: usize,
    /// Distance along the ray.
    pub t: f32,
}

/// A scene the path tracer renders.
#[derive(Debug, Clone)]
pub struct Scene {
    objects: Vec<Object>,
    surfaces: Vec<Surface>,
    /// Objects that are emitting quads: the targets of next-event estimation.
    lights: Vec<usize>,
    light: LightSpectrum,
    environment: f32,
    camera: Camera,
    sampling: SpectralSampling,
}

/// How camera paths draw their wavelengths and, at fluorescent events, the excitation
/// wavelength λi.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SpectralSampling {
    /// The paper's rules (model.md §6), as the renderer had them first: camera
    /// wavelengths from the observer's density; at a surface the event ∝ the row albedo
    /// and λi ∝ x·a; Russian roulette on the path weight. Noisy under lights with lines
    /// or UV peaks that the absorption rarely lands on.
    Paper,
    /// Light-aware: camera wavelengths from [`Scene::wavelength_sampler`]; at a
    /// fluorescent surface one-sample multiple importance sampling (balance heuristic)
    /// of the paper's rule and of the same rule weighted by the scene's light spectrum L
    /// at λi (the event ∝ d·L(λo) or k·e(λo)·∫x·a·L, λi ∝ x·a·L), which follows
    /// absorption × incident light wherever the incident light has the light's spectrum
    /// and stays unbiased where it does not; Russian roulette on the path weight times
    /// the light at the path's wavelength.
    #[default]
    LightAware,
}

impl Scene {
    /// An empty, black scene lit by nothing yet; emitters use `light`'s spectrum.
    pub fn new(light: LightSpectrum, camera: Camera) -> Scene {
        Scene {
            objects: Vec::new(),
            surfaces: Vec::new(),
            lights: Vec::new(),
            light,
            environment: 0.0,
            camera,
            sampling: SpectralSampling::default(),
        }
    }

    /// Adds a surface (uniform [`SurfaceTables`] or a textured surface); returns its
    /// index for [`Object::surface`]. Its light-aware excitation samplers are built for
    /// the scene's light spectrum.
    pub fn add_surface(&mut self, surface: impl Into<Surface>) -> usize {
        let mut surface = surface.into();
        surface.light_with(&self.light.radiance);
        self.surfaces.push(surface);
        self.surfaces.len() - 1
    }

    /// Adds an object; returns its index.
    pub fn add_object(&mut self, object: Object) -> Result<usize> {
        if let Some(s) = object.surface
            && s >= self.surfaces.len()
        {
            return Err(Error::invalid(
                "object.surface",
                format!(
                    "is {s} but the scene has {} surfaces; add the surface first",
                    self.surfaces.len()
                ),
            ));
        }
        if !(object.emission >= 0.0 && object.emission.is_finite()) {
            return Err(Error::invalid(
                "object.emission",
                format!(
                    "is {}; emission must be a non-negative finite number",
                    object.emission
                ),
            ));
        }
        self.objects.push(object);
        let index = self.objects.len() - 1;
        if object.emission > 0.0 && matches!(object.shape, Shape::Quad(_)) {
            self.lights.push(index);
        }
        Ok(index)
    }

    /// Sets the uniform environment radiance (a multiple of the light spectrum).
    pub fn set_environment(&mut self, radiance: f32) -> Result<()> {
        if !(radiance >= 0.0 && radiance.is_finite()) {
            return Err(Error::invalid(
                "environment",
                format!("is {radiance}; it must be a non-negative finite number"),
            ));
        }
        self.environment = radiance;
        Ok(())
    }

    /// Chooses how paths draw wavelengths (default [`SpectralSampling::LightAware`]).
    pub fn set_spectral_sampling(&mut self, sampling: SpectralSampling) {
        self.sampling = sampling;
    }

    /// How paths draw wavelengths.
    pub fn spectral_sampling(&self) -> SpectralSampling {
        self.sampling
    }

    /// Replaces the camera.
    pub fn set_camera(&mut self, camera: Camera) {
        self.camera = camera;
    }

    /// The objects.
    pub fn objects(&self) -> &[Object] {
        &self.objects
    }

    /// The surfaces.
    pub fn surfaces(&self) -> &[Surface] {
        &self.surfaces
    }

    /// Indices of the emitting quads (sampled by next-event estimation).
    pub fn lights(&self) -> &[usize] {
        &self.lights
    }

    /// The light spectrum shared by all emitters and the environment.
    pub fn light(&self) -> &LightSpectrum {
        &self.light
    }

    /// The density of the camera paths' wavelengths: the observer's under
    /// [`SpectralSampling::Paper`], else guided by the light spectrum L (the emitters,
    /// the environment) and by each surface's radiance in a furnace of the light,
    /// d·L + G (G its light-aware fluorescent albedo; a map's mean over its texels), see
    /// [`WavelengthSampler`].
    pub fn wavelength_sampler(&self) -> WavelengthSampler {
        if self.sampling == SpectralSampling::Paper {
            return WavelengthSampler::observer();
        }
        let mut guides = vec![self.light.radiance.clone()];
        for surface in &self.surfaces {
            guides.push(surface.furnace_guide(&self.light.radiance));
        }
        WavelengthSampler::guided(&guides)
    }

    /// The environment radiance (multiple of the light spectrum).
    pub fn environment(&self) -> f32 {
        self.environment
    }

    /// The camera.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// The nearest hit closer than `t_max`.
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut limit = t_max;
        for (object, o) in self.objects.iter().enumerate() {
            if let Some(t) = o.shape.intersect(ray, limit) {
                limit = t;
                best = Some(Hit { object, t });
            }
        }
        best
    }

    /// True when something other than object `skip` blocks the ray before `t_max`.
    #[inline]
    pub fn occluded(&self, ray: &Ray, t_max: f32, skip: usize) -> bool {
        self.objects
            .iter()
            .enumerate()
            .any(|(i, o)| i != skip && o.shape.intersect(ray, t_max).is_some())
    }

    /// A built-in scene showing `material` (a [`Material`](crate::Material) or a
    /// material map's [`MaterialTexture`](super::texture::MaterialTexture)) under
    /// `light`. With `compare`, a twin with the same reflectance r and no fluorescence
    /// stands to the right of the material's sphere (or rectangle). `aspect` is the
    /// image's width / height.
    pub fn build<'m>(
        kind: SceneKind,
        material: impl Into<MaterialSource<'m>>,
        light: &Light,
        compare: bool,
        aspect: f32,
    ) -> Result<Scene> {
        if !(aspect > 0.0 && aspect.is_finite()) {
            return Err(Error::invalid(
                "aspect",
                format!("is {aspect}; the image needs a positive width and height"),
            ));
        }
        let source = material.into();
        let light = LightSpectrum::new(light)?;
        let surface = source.surface()?;
        let twin = if compare { Some(source.twin()?) } else { None };
        let centre_y = match kind {
            SceneKind::Preview => SPHERE_RADIUS,
            SceneKind::Furnace => 0.0,
            SceneKind::Plane => return plane_scene(light, surface, twin, source.aspect(), aspect),
        };
        let x = if compare { -COMPARE_OFFSET } else { 0.0 };
        let (eye, target) = match kind {
            SceneKind::Preview => (Vec3::new(0.0, 2.4, 8.0), Vec3::new(0.0, 0.85, 0.0)),
            _ => (Vec3::new(0.0, 0.0, 6.0), Vec3::ZERO),
        };
        // Half the width and height of what must be in frame, at the target.
        let half_width = x.abs() + SPHERE_RADIUS + if compare { 0.9 } else { 1.4 };
        let half_height: f32 = match kind {
            SceneKind::Preview => 1.55,
            _ => 1.3,
        };
        let camera = framing(eye, target, half_width, half_height, aspect);

        let mut scene = Scene::new(light, camera);
        let material_surface = scene.add_surface(surface);
        let sphere = |x: f32| Shape::Sphere {
            centre: Vec3::new(x, centre_y, 0.0),
            radius: SPHERE_RADIUS,
        };
        scene.add_object(Object {
            shape: sphere(x),
            surface: Some(material_surface),
            emission: 0.0,
        })?;
        if let Some(twin) = twin {
            let twin_surface = scene.add_surface(twin);
            scene.add_object(Object {
                shape: sphere(-x),
                surface: Some(twin_surface),
                emission: 0.0,
            })?;
        }
        match kind {
            SceneKind::Furnace | SceneKind::Plane => scene.set_environment(FURNACE_ENVIRONMENT)?,
            SceneKind::Preview => {
                let ground = scene.add_surface(SurfaceTables::grey("ground", GROUND_REFLECTANCE));
                scene.add_object(Object {
                    shape: Shape::Plane {
                        point: Vec3::ZERO,
                        normal: Vec3::Y,
                    },
                    surface: Some(ground),
                    emission: 0.0,
                })?;
                let quad = Quad::facing(
                    Vec3::new(-2.5, 5.5, 4.0),
                    Vec3::new(0.0, SPHERE_RADIUS, 0.0) - Vec3::new(-2.5, 5.5, 4.0),
                    4.0,
                );
                // Exposure rule: the light alone gives a white diffuser facing up at the
                // top of the sphere Y = 1 − PREVIEW_ENVIRONMENT; the environment adds
                // the rest (less the sliver of sky the light hides), so white reads ≈ 1.
                let top = Vec3::new(0.0, 2.0 * SPHERE_RADIUS, 0.0);
                let radiance = (1.0 - PREVIEW_ENVIRONMENT) * std::f32::consts::PI
                    / projected_solid_angle(&quad, top, Vec3::Y);
                scene.add_object(Object {
                    shape: Shape::Quad(quad),
                    surface: None,
                    emission: radiance,
                })?;
                scene.set_environment(PREVIEW_ENVIRONMENT)?;
            }
        }
        Ok(scene)
    }
}

/// A camera at `eye` looking at `target` whose view holds `half_width` and `half_height`
/// (scene units, at the target) in an image of `aspect` = width / height.
fn framing(eye: Vec3, target: Vec3, half_width: f32, half_height: f32, aspect: f32) -> Camera {
    let distance = (target - eye).length();
    let half_tan = (half_height.max(half_width / aspect)) / distance;
    let vfov = 2.0 * half_tan.atan().to_degrees();
    Camera::look_at(eye, target, vfov, aspect)
}

/// [`SceneKind::Plane`]: `surface` on a rectangle facing the camera (the longer side
/// 2·[`PLANE_HALF_SIZE`], width / height = `texture_aspect`), with `twin` on another to
/// its right, in a uniform environment of the light; `aspect` is the image's.
fn plane_scene(
    light: LightSpectrum,
    surface: Surface,
    twin: Option<Surface>,
    texture_aspect: f32,
    aspect: f32,
) -> Result<Scene> {
    let texture_aspect = if texture_aspect > 0.0 && texture_aspect.is_finite() {
        texture_aspect
    } else {
        1.0
    };
    let (half_w, half_h) = if texture_aspect >= 1.0 {
        (PLANE_HALF_SIZE, PLANE_HALF_SIZE / texture_aspect)
    } else {
        (PLANE_HALF_SIZE * texture_aspect, PLANE_HALF_SIZE)
    };
    let x = if twin.is_some() {
        -(half_w + 0.5 * PLANE_COMPARE_GAP)
    } else {
        0.0
    };
    let margin = 0.15 * PLANE_HALF_SIZE;
    let camera = framing(
        Vec3::new(0.0, 0.0, 6.0),
        Vec3::ZERO,
        x.abs() + half_w + margin,
        half_h + margin,
        aspect,
    );
    let mut scene = Scene::new(light, camera);
    // From the bottom-left corner, edge_u to the right and edge_v up: the front faces
    // the camera and the texture stands upright ([`Shape::uv_at`]).
    let rectangle = |centre_x: f32| {
        Shape::Quad(Quad::new(
            Vec3::new(centre_x - half_w, -half_h, 0.0),
            Vec3::X * (2.0 * half_w),
            Vec3::Y * (2.0 * half_h),
        ))
    };
    let material_surface = scene.add_surface(surface);
    scene.add_object(Object {
        shape: rectangle(x),
        surface: Some(material_surface),
        emission: 0.0,
    })?;
    if let Some(twin) = twin {
        let twin_surface = scene.add_surface(twin);
        scene.add_object(Object {
            shape: rectangle(-x),
            surface: Some(twin_surface),
            emission: 0.0,
        })?;
    }
    scene.set_environment(FURNACE_ENVIRONMENT)?;
    Ok(scene)
}

/// ∫ cos θ dω over the quad as seen from `point` with unit `normal` (the quad above the
/// point's horizon): irradiance per unit radiance, by Lambert's formula for polygons.
pub fn projected_solid_angle(quad: &Quad, point: Vec3, normal: Vec3) -> f32 {
    let corners = [
        quad.point(0.0, 0.0),
        quad.point(1.0, 0.0),
        quad.point(1.0, 1.0),
        quad.point(0.0, 1.0),
    ];
    let dirs = corners.map(|c| (c - point).normalize());
    let mut sum = 0.0;
    for i in 0..4 {
        let a = dirs[i];
        let b = dirs[(i + 1) % 4];
        let theta = a.dot(b).clamp(-1.0, 1.0).acos();
        sum += theta * a.cross(b).normalize().dot(normal);
    }
    0.5 * sum.abs()
}
