//! The per-pixel baseline (`fluorite fit-image --per-pixel`): every pixel fitted on its
//! own with the library's default single-matrix fit, as `fluorite fit` would fit that
//! pixel's matrix read from a bispectral EXR (one grid for both axes, cells the layout
//! lacks missing). It is what sharing the fluorophores (model.md §8) is measured against:
//! one fit per pixel, each with the noise of a whole matrix and its own fluorophores, so
//! there is no material map, only the fitted image and its colour error.
//!
//! The image is read once, block by block; the pixels of a block are fitted in
//! parallel and each pixel's fitted cells and ΔE2000 go into an anonymous scratch file in
//! the output folder, from which `fitted.exr` and `delta-e.exr` are written tile by tile.

use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

use crate::colour::Light;
use crate::error::{Error, Result};
use crate::fit::{FitOptions, FitOutcome, fit};
use crate::image::array::PixelSource;
use crate::image::fit::Step;
use crate::image::fit::colour::CellColours;
use crate::image::fit::outputs::file_part;
use crate::image::layout::{Cell, Layout};
use crate::image::sink::{ImageSpec, Rect, write_image};
use crate::measurement::{Measurement, Units};
use crate::model::predict_like;

/// How to fit every pixel on its own.
#[derive(Debug, Clone)]
pub struct PerPixelOptions {
    /// The single-matrix fit of each pixel (default: the library's default fit).
    pub fit: FitOptions,
    /// Lights of `delta-e.exr` and the summary (fitted against measured).
    pub lights: Vec<Light>,
    /// ZIP-compress the EXR outputs.
    pub zip: bool,
}

impl Default for PerPixelOptions {
    fn default() -> Self {
        PerPixelOptions {
            fit: FitOptions::default(),
            lights: Light::standard(),
            zip: false,
        }
    }
}

/// The outcome of a per-pixel fit.
#[derive(Debug, Clone, PartialEq)]
pub struct PerPixelFit {
    /// Every file written (`fitted.exr`, `delta-e.exr`).
    pub files: Vec<PathBuf>,
    /// Pixels fitted.
    pub fitted: usize,
    /// Pixels holding a non-finite cell: not fitted, NaN in the outputs.
    pub masked: usize,
    /// Pixels whose fit failed: NaN in the outputs.
    pub failed: usize,
    /// The light names, in order.
    pub lights: Vec<String>,
    /// Median ΔE2000 per light over the fitted pixels (fitted against measured).
    pub median_delta_e: Vec<f64>,
    /// 99th percentile per light.
    pub p99_delta_e: Vec<f64>,
    /// Largest per light.
    pub max_delta_e: Vec<f64>,
    /// Lines for the report.
    pub notes: Vec<String>,
}

/// A pixel's cells as the matrix `fluorite fit` reads from a bispectral EXR: the layout's
/// one grid on both axes, cells the layout lacks missing (NaN).
pub fn pixel_measurement(layout: &Layout, cells: &[f32], name: String) -> Result<Measurement> {
    let grid = &layout.wavelengths;
    let n = grid.len();
    let mut values = vec![f64::NAN; n * n];
    for (c, &v) in layout.cells.iter().zip(cells) {
        let (i, o) = match *c {
            Cell::Diagonal(i) => (i, i),
            Cell::Reradiation(i, o) => (i, o),
        };
        values[i * n + o] = f64::from(v);
    }
    Measurement::new(name, grid.clone(), grid.clone(), values, Units::PerBin)
}

/// The cells of `m` (on the layout's grid) in the layout's order.
fn layout_cells(layout: &Layout, m: &Measurement) -> Vec<f32> {
    layout
        .cells
        .iter()
        .map(|c| match *c {
            Cell::Diagonal(i) => m.get(i, i) as f32,
            Cell::Reradiation(i, o) => m.get(i, o) as f32,
        })
        .collect()
}

/// What fitting one pixel gave: its record (fitted cells, then ΔE per light), or why not.
enum Pixel {
    Fitted(Vec<f32>),
    Masked,
    Failed(String),
}

fn fit_pixel(
    layout: &Layout,
    colours: &CellColours,
    options: &FitOptions,
    cells: &[f32],
    name: String,
) -> Pixel {
    if cells.iter().any(|v| !v.is_finite()) {
        return Pixel::Masked;
    }
    let m = match pixel_measurement(layout, cells, name) {
        Ok(m) => m,
        Err(e) => return Pixel::Failed(e.to_string()),
    };
    let material = match fit(&m, options) {
        Ok(FitOutcome::Material(material)) => material,
        Ok(FitOutcome::Shapes(_)) => {
            return Pixel::Failed("the fit gave shapes only, not a material".into());
        }
        Err(e) => return Pixel::Failed(e.to_string()),
    };
    let mut record = layout_cells(layout, &predict_like(&material, &m));
    for l in 0..colours.lights.len() {
        let measured = colours.xyz(l, 0, cells);
        let fitted = colours.xyz(l, 0, &record[..layout.len()]);
        record.push(colours.delta_e(l, measured, fitted) as f32);
    }
    Pixel::Fitted(record)
}

/// The `q`-quantile of `values` (finite ones), as the image fit reports it.
fn quantile(values: &[f32], q: f64) -> f64 {
    let v: Vec<f64> = values.iter().map(|&x| f64::from(x)).collect();
    crate::numeric::quantile(&v, q)
}

/// Fits every pixel of `image` on its own and writes `fitted.exr` (each pixel's
/// predicted matrix in the input's layout) and `delta-e.exr` (fitted against measured,
/// one channel per light) into `out` (created if missing).
pub fn fit_per_pixel(
    image: PixelSource<'_>,
    out: &Path,
    options: &PerPixelOptions,
    report: &(dyn Fn(Step) + Sync),
) -> Result<PerPixelFit> {
    if options.lights.is_empty() {
        return Err(Error::invalid("--lights", "give at least one light"));
    }
    if out.is_file() {
        return Err(Error::invalid(
            "-o",
            format!("{} is a file; give a folder", out.display()),
        ));
    }
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let layout = image.layout();
    let (width, height) = (image.width(), image.height());
    let cells = layout.len();
    let nl = options.lights.len();
    let record = cells + nl;
    let colours = CellColours::new(layout, &options.lights);
    let stem = image.stem();

    // The scratch file: one record per pixel, removed when dropped.
    let scratch = tempfile::tempfile_in(out).map_err(|e| Error::io(out, e))?;
    let write_at = |file: &File, pixel: usize, values: &[f32]| -> Result<()> {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        file.write_all_at(&bytes, (pixel * record * 4) as u64)
            .map_err(|e| Error::io(out, e))
    };
    let nan_record = vec![f32::NAN; record];

    report(Step::Stage {
        what: "per-pixel fits".into(),
        total: image.pixels(),
    });
    let done = AtomicUsize::new(0);
    let first_failure: Mutex<Option<String>> = Mutex::new(None);
    let (mut fitted, mut masked, mut failed) = (0, 0, 0);
    let mut delta: Vec<Vec<f32>> = vec![Vec::new(); nl];
    image.pass(
        |block| {
            let results: Vec<(usize, Pixel)> = (0..block.pixel_count())
                .into_par_iter()
                .map(|q| {
                    let p = block.image_index(q, width);
                    let name = format!("{stem} pixel ({}, {})", p % width, p / width);
                    let fit = fit_pixel(layout, &colours, &options.fit, block.pixel(q), name);
                    let n = done.fetch_add(1, Ordering::Relaxed) + 1;
                    report(Step::Done(n));
                    (p, fit)
                })
                .collect();
            Ok(results)
        },
        |results| {
            for (p, pixel) in results {
                match pixel {
                    Pixel::Fitted(values) => {
                        fitted += 1;
                        for (l, d) in delta.iter_mut().enumerate() {
                            d.push(values[cells + l]);
                        }
                        write_at(&scratch, p, &values)?;
                    }
                    Pixel::Masked => {
                        masked += 1;
                        write_at(&scratch, p, &nan_record)?;
                    }
                    Pixel::Failed(why) => {
                        failed += 1;
                        let mut first = first_failure.lock().unwrap_or_else(|e| e.into_inner());
                        first.get_or_insert(why);
                        write_at(&scratch, p, &nan_record)?;
                    }
                }
            }
            Ok(())
        },
        |_| {},
    )?;

    // The outputs, tile by tile from the scratch file.
    let read_rect = |rect: Rect, take: std::ops::Range<usize>| -> Result<Vec<f32>> {
        let mut v = Vec::with_capacity(rect.width * rect.height * take.len());
        let mut bytes = vec![0u8; rect.width * record * 4];
        for y in rect.y..rect.y + rect.height {
            scratch
                .read_exact_at(&mut bytes, ((y * width + rect.x) * record * 4) as u64)
                .map_err(|e| Error::io(out, e))?;
            for r in bytes.chunks_exact(record * 4) {
                v.extend(
                    r[take.start * 4..take.end * 4]
                        .chunks_exact(4)
                        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                );
            }
        }
        Ok(v)
    };
    let attributes = vec![
        ("spectralLayoutVersion".to_string(), "1.0".to_string()),
        ("fluoriteSource".to_string(), image.describe()),
    ];
    let tiles =
        width.div_ceil(crate::image::sink::TILE) * height.div_ceil(crate::image::sink::TILE);
    let mut files = Vec::new();
    let fitted_path = out.join("fitted.exr");
    report(Step::Stage {
        what: "writing fitted.exr".into(),
        total: tiles,
    });
    write_image(
        &fitted_path,
        &ImageSpec {
            width,
            height,
            channels: layout.channel_names(),
            half: image.half(),
            zip: options.zip,
            attributes: attributes.clone(),
        },
        |rect| read_rect(rect, 0..cells),
        |d, _| report(Step::Done(d)),
    )?;
    files.push(fitted_path);
    let delta_path = out.join("delta-e.exr");
    report(Step::Stage {
        what: "writing delta-e.exr".into(),
        total: tiles,
    });
    write_image(
        &delta_path,
        &ImageSpec {
            width,
            height,
            channels: colours.lights.iter().map(|l| file_part(l)).collect(),
            half: false,
            zip: options.zip,
            attributes,
        },
        |rect| read_rect(rect, cells..record),
        |d, _| report(Step::Done(d)),
    )?;
    files.push(delta_path);

    let mut notes = vec![
        "no material map: every pixel has fluorophores of its own (the per-pixel baseline); fitted.exr and delta-e.exr only".to_string(),
    ];
    if masked > 0 {
        notes.push(format!(
            "{masked} pixel(s) hold non-finite cells: not fitted, NaN in every output"
        ));
    }
    if failed > 0 {
        let why = first_failure
            .into_inner()
            .unwrap_or_else(|e| e.into_inner())
            .unwrap_or_default();
        notes.push(format!(
            "{failed} pixel fit(s) failed (NaN in every output); the first: {why}"
        ));
    }
    Ok(PerPixelFit {
        files,
        fitted,
        masked,
        failed,
        lights: colours.lights.clone(),
        median_delta_e: delta.iter().map(|d| quantile(d, 0.5)).collect(),
        p99_delta_e: delta.iter().map(|d| quantile(d, 0.99)).collect(),
        max_delta_e: delta.iter().map(|d| quantile(d, 1.0)).collect(),
        notes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pixel_reads_as_the_exr_reader_reads_a_matrix() {
        let grid = vec![400.0, 410.0, 420.0];
        let layout = Layout::new(
            grid.clone(),
            vec![
                Cell::Diagonal(1),
                Cell::Diagonal(2),
                Cell::Reradiation(0, 2),
                Cell::Reradiation(1, 2),
            ],
        )
        .unwrap();
        let m = pixel_measurement(&layout, &[0.5, 0.6, 0.01, 0.02], "p".into()).unwrap();
        assert_eq!(m.excitation_nm, grid);
        assert_eq!(m.emission_nm, grid);
        assert!(m.get(0, 0).is_nan(), "a cell the layout lacks is missing");
        assert!(m.get(2, 1).is_nan(), "anti-Stokes cells are missing");
        assert_eq!(m.get(1, 1), 0.5);
        assert_eq!(m.get(2, 2), f64::from(0.6f32));
        assert_eq!(m.get(0, 2), f64::from(0.01f32));
        assert_eq!(layout_cells(&layout, &m), vec![0.5, 0.6, 0.01, 0.02]);
    }
}
