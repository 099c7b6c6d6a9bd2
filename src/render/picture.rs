//! One picture of a material or a material map: build the scene, render it, develop it
//! into the display image (PNG), the scene-referred linear image and, if asked, an EXR.
//! `fluorite render`, `fit --render` and the Python package's `render` all go through
//! [`render_picture`].

use std::time::Instant;

use crate::colour::Light;
use crate::error::Result;

use super::compare::develop_compare;
use super::image::{
    DEFAULT_EXPOSURE_EV, Develop, check_exposure, develop, film_to_linear_srgb, to_srgb8,
    xyz_to_srgb_matrix,
};
use super::surface::MaterialSource;
use super::{Film, RenderSettings, Scene, SceneKind, SpectralSampling, render};

/// Everything a picture needs but the material.
#[derive(Debug, Clone)]
pub struct Picture {
    /// The scene's light.
    pub light: Light,
    /// Size, samples per pixel and seed.
    pub settings: RenderSettings,
    /// The built-in scene.
    pub kind: SceneKind,
    /// A twin sphere (or rectangle) with the same reflectance and no fluorescence to the
    /// right.
    pub compare: bool,
    /// How paths draw wavelengths.
    pub sampling: SpectralSampling,
    /// Exposure of the display image in stops; `None`: [`DEFAULT_EXPOSURE_EV`], or
    /// automatic with `compare`.
    pub exposure_ev: Option<f64>,
    /// Adapt the light's white to D65 in the display image.
    pub adapt: bool,
    /// Also encode the scene-referred image as OpenEXR.
    pub exr: bool,
}

impl Picture {
    /// The default picture under `light`: the preview scene, default settings and
    /// sampling, adapted, no EXR.
    pub fn new(light: Light) -> Picture {
        Picture {
            light,
            settings: RenderSettings::default(),
            kind: SceneKind::Preview,
            compare: false,
            sampling: SpectralSampling::default(),
            exposure_ev: None,
            adapt: true,
            exr: false,
        }
    }
}

/// A rendered and developed picture.
#[derive(Debug, Clone)]
pub struct Rendered {
    /// The film: mean CIE XYZ per pixel.
    pub film: Film,
    /// Scene-referred linear sRGB primaries per pixel (row-major, rows top to bottom): the
    /// film's XYZ without chromatic adaptation, exposure or clipping.
    pub scene_linear: Vec<[f32; 3]>,
    /// The display image as 8-bit sRGB, `width × height × 3` bytes (adapted as asked,
    /// exposed, gamut-mapped; without the compare picture's label strip).
    pub display_srgb8: Vec<u8>,
    /// The display PNG (with the compare picture's label strip).
    pub png: Vec<u8>,
    /// The scene-referred EXR, when [`Picture::exr`] asks for it.
    pub exr: Option<Vec<u8>>,
    /// The exposure used, in stops.
    pub exposure_ev: f64,
    /// Whether the exposure was chosen automatically (compare pictures).
    pub exposure_auto: bool,
    /// Seconds spent rendering (not developing).
    pub seconds: f64,
}

/// Renders `material` (a [`Material`](crate::Material) or a material map's
/// [`MaterialTexture`](super::texture::MaterialTexture)) as `picture` says. `on_row` is
/// called once per finished row, from worker threads.
pub fn render_picture<'m>(
    material: impl Into<MaterialSource<'m>>,
    picture: &Picture,
    on_row: &(dyn Fn() + Sync),
) -> Result<Rendered> {
    let material = material.into();
    let Picture {
        light,
        settings,
        kind,
        compare,
        exposure_ev,
        ..
    } = picture;
    settings.validate()?;
    if let Some(ev) = exposure_ev {
        check_exposure(*ev)?;
    }
    let mut scene = Scene::build(*kind, material, light, *compare, settings.aspect())?;
    scene.set_spectral_sampling(picture.sampling);
    let started = Instant::now();
    let film = render(&scene, settings, on_row)?;
    let seconds = started.elapsed().as_secs_f64();

    let exposure = exposure_ev.unwrap_or(DEFAULT_EXPOSURE_EV);
    let description = format!(
        "{} under {}{}, scene {:?}, {} spp, seed {}{}{}",
        material.name(),
        light.name,
        if *compare {
            " (right: same reflectance without fluorescence)"
        } else {
            ""
        },
        kind,
        settings.samples_per_pixel,
        settings.seed,
        // The compare picture states its exposure itself (it may be automatic).
        if *compare {
            String::new()
        } else {
            format!(", exposure {exposure:+} EV")
        },
        if picture.adapt {
            ", adapted to D65"
        } else {
            ", not adapted"
        }
    );
    let develop_as = Develop {
        adapt: picture.adapt,
        exposure_ev: exposure,
        description,
        exr: picture.exr,
    };
    let (png, exr, exposure_ev, exposure_auto) = if *compare {
        let developed = develop_compare(
            &film,
            &scene,
            settings,
            &develop_as,
            exposure_ev.is_none(),
            (material.name(), &light.name),
        )?;
        (
            developed.png,
            developed.exr,
            developed.exposure.ev,
            developed.exposure.auto,
        )
    } else {
        let (png, exr) = develop(&film, scene.light(), &develop_as)?;
        (png, exr, exposure, false)
    };
    let display = film_to_linear_srgb(&film, &xyz_to_srgb_matrix(scene.light(), picture.adapt));
    let display_srgb8 = to_srgb8(&display, exposure_ev);
    let scene_linear = film_to_linear_srgb(&film, &xyz_to_srgb_matrix(scene.light(), false));
    Ok(Rendered {
        film,
        scene_linear,
        display_srgb8,
        png,
        exr,
        exposure_ev,
        exposure_auto,
        seconds,
    })
}
