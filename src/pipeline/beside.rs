//! What a fit writes next to its material when asked: the figures against the data
//! (`fit --plot`, also `fluorite plot`) and a preview render (`fit --render`).

use std::path::{Path, PathBuf};

use crate::colour::Light;
use crate::error::{Error, Result};
use crate::fit::FitOutcome;
use crate::material::Material;
use crate::measurement::Measurement;
use crate::plot::{self, ImageFormat, PlotOptions};
use crate::render::picture::{Picture, Rendered, render_picture};

/// Figures written, and what was skipped and why.
#[derive(Debug, Clone, Default)]
pub struct Figures {
    /// The files written.
    pub written: Vec<PathBuf>,
    /// Figures not drawn, each with its reason.
    pub skipped: Vec<String>,
}

/// Draws every figure of `material` (against `data` when given) in memory, then writes
/// them all into `output_dir` (created if missing) or beside `material_path`, named after
/// its stem.
pub fn write_figures(
    material: &Material,
    data: Option<&Measurement>,
    material_path: &Path,
    output_dir: Option<&Path>,
    format: ImageFormat,
) -> Result<Figures> {
    let plots = plot::plot(
        material,
        data,
        &PlotOptions {
            format,
            guard_nm: None,
        },
    )?;
    let dir = match output_dir {
        Some(dir) => {
            std::fs::create_dir_all(dir).map_err(|e| Error::Io {
                path: dir.to_path_buf(),
                message: format!(
                    "cannot create the output folder ({e}); choose another with -o DIR"
                ),
            })?;
            dir.to_path_buf()
        }
        None => match material_path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        },
    };
    let stem = material_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| material.name.clone());
    let written = plot::write_plots(&plots, &dir, &stem)?;
    Ok(Figures {
        written,
        skipped: plots.skipped,
    })
}

/// The figures of a fit just made (the material, or an EEM's shapes) beside the JSON it
/// was written to, against the matrix it was fitted to (as prepared: masked scatter is
/// drawn as masked).
pub fn plot_fit(
    outcome: &FitOutcome,
    measurement: &Measurement,
    material_path: &Path,
) -> Result<Figures> {
    let shapes_material;
    let material = match outcome {
        FitOutcome::Material(material) => material.as_ref(),
        FitOutcome::Shapes(shapes) => {
            shapes_material = plot::shapes_material(shapes);
            &shapes_material
        }
    };
    write_figures(
        material,
        Some(measurement),
        material_path,
        None,
        ImageFormat::Png,
    )
}

/// The default preview of a material just fitted: `<stem>.png` beside its JSON, the
/// preview scene under D65 at the default size and samples. Returns the path written,
/// the picture and its render.
pub fn preview(
    material: &Material,
    material_path: &Path,
    on_row: &(dyn Fn() + Sync),
) -> Result<(PathBuf, Picture, Rendered)> {
    let picture = Picture::new(Light::parse("d65")?);
    let rendered = render_picture(material, &picture, on_row)?;
    let output = material_path.with_extension("png");
    crate::files::write_atomic(&output, &rendered.png)?;
    Ok((output, picture, rendered))
}
