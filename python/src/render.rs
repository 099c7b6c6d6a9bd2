//! `fluorite.render`: the built-in spectral path tracer, images as numpy arrays.

use fluorite::render::{RenderSettings, SceneKind, SpectralSampling};
use numpy::PyArray3;
use pyo3::prelude::*;

use crate::convert::{image, items};
use crate::material::PyMaterial;
use crate::{detached, invalid};
use fluorite::render::picture::{Picture, render_picture};

/// The linear (float32) and display (uint8) images of a render.
type Images<'py> = (Bound<'py, PyArray3<f32>>, Bound<'py, PyArray3<u8>>);

/// Renders ``material`` on a sphere in the built-in spectral path tracer (hero
/// wavelengths, the paper's fluorescent events).
///
/// ``scene``: ``"preview"`` (a sphere on a grey ground under an area light and a dim
/// environment of the light's spectrum) or ``"furnace"`` (the sphere alone in a uniform
/// environment of the light: a white diffuser reads Y = 1). ``light``: a name, CSV path,
/// ``(wavelengths, values)`` or an object with ``.wavelengths``/``.values``, normalised
/// to unit luminance. ``spp`` camera paths per pixel, ``size`` = (width, height),
/// ``seed`` (the same seed gives the same image whatever the threads), ``compare`` (a
/// twin sphere with the same reflectance and no fluorescence on the right),
/// ``exposure`` (stops; default −0.5, automatic with ``compare``), ``adapt`` (adapt the
/// light's white to D65 in the display image), ``sampling`` (``"light"`` or
/// ``"paper"``).
///
/// Returns ``(linear, srgb)``: ``linear`` float32 (height, width, 3), scene-referred
/// linear sRGB primaries of the film's XYZ (no adaptation, exposure or clipping; white
/// diffuser Y ≈ 1); ``srgb`` uint8 (height, width, 3), the display image as the PNG shows
/// it (adapted, exposed, gamut-mapped, sRGB-encoded; without compare's label strip).
/// The GIL is released while it renders.
#[pyfunction]
#[pyo3(signature = (material, *, light = None, scene = "preview", spp = 64, size = None, seed = 1, compare = false, exposure = None, adapt = true, sampling = "light"))]
#[allow(clippy::too_many_arguments)]
pub fn render<'py>(
    py: Python<'py>,
    material: &Bound<'py, PyMaterial>,
    light: Option<Bound<'py, PyAny>>,
    scene: &str,
    spp: u32,
    size: Option<Bound<'py, PyAny>>,
    seed: u64,
    compare: bool,
    exposure: Option<f64>,
    adapt: bool,
    sampling: &str,
) -> PyResult<Images<'py>> {
    let light = match light.filter(|l| !l.is_none()) {
        Some(l) => crate::lights::light(&l, "custom")?,
        None => crate::lights::light(pyo3::types::PyString::new(py, "d65").as_any(), "d65")?,
    };
    let (width, height) = match size.filter(|s| !s.is_none()) {
        None => (640, 400),
        Some(s) => {
            let parts = items(&s, "size")?;
            let [w, h] = parts.as_slice() else {
                return Err(invalid("size", "expected (width, height) in pixels"));
            };
            let w: u32 = w
                .extract()
                .map_err(|_| invalid("size", "width must be a positive int"))?;
            let h: u32 = h
                .extract()
                .map_err(|_| invalid("size", "height must be a positive int"))?;
            (w, h)
        }
    };
    let kind = match scene.to_ascii_lowercase().as_str() {
        "preview" => SceneKind::Preview,
        "furnace" => SceneKind::Furnace,
        other => {
            return Err(invalid(
                "scene",
                format!("\"{other}\" is not one of preview, furnace"),
            ));
        }
    };
    let sampling = match sampling.to_ascii_lowercase().as_str() {
        "light" => SpectralSampling::LightAware,
        "paper" => SpectralSampling::Paper,
        other => {
            return Err(invalid(
                "sampling",
                format!("\"{other}\" is not one of light, paper"),
            ));
        }
    };
    let picture = Picture {
        settings: RenderSettings {
            width,
            height,
            samples_per_pixel: spp,
            seed,
        },
        kind,
        compare,
        sampling,
        exposure_ev: exposure,
        adapt,
        exr: false,
        ..Picture::new(light)
    };
    let material = material.get().material.clone();
    let rendered = detached(py, "render", move || {
        render_picture(&material, &picture, &|| {})
    })?;
    let (w, h) = (rendered.film.width as usize, rendered.film.height as usize);
    let linear: Vec<f32> = rendered.scene_linear.iter().flatten().copied().collect();
    Ok((
        image(py, h, w, linear)?,
        image(py, h, w, rendered.display_srgb8)?,
    ))
}
