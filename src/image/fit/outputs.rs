//! The files of an image fit, each written tile by tile (EXR) or row by row (PNG) from
//! the scratch file, atomically: the material map and its textures, the fitted image in
//! the input's layout, ΔE2000 maps and the image under each light, measured beside
//! fitted.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::files::write_atomic;
use crate::image::array::PixelSource;
use crate::image::map::{MaterialMap, SCHEMA, Textures, concentration_channel};
use crate::image::sink::{Rect, TiledFile, write_image};

pub use super::band::file_part;
use super::band::{
    BandOutputs, EXR_OUTPUTS, GAP, OutputJob, PngStyle, concentration_values, delta_e_values,
    exr_specs, fitted_values, reflectance_values,
};
use super::gauge::Gauge;
use super::passes::Census;
use super::pixel::{PixelColours, PixelFit, PixelModel};
use super::scratch::Scratch;
use super::state::State;
use super::{ImageFitOptions, Step, Trial};

/// PNG rows computed together per thread.
const ROWS_PER_THREAD: usize = 16;

/// What [`write_all`] wrote.
pub struct Written {
    /// The material map.
    pub map_path: PathBuf,
    /// Every file.
    pub files: Vec<PathBuf>,
    /// Pixels whose material needed clamping.
    pub clamped_pixels: usize,
}

/// The materials of the pixels of `rect`.
fn fits(scratch: &Scratch, model: &PixelModel, width: usize, rect: Rect) -> Result<Vec<PixelFit>> {
    let len = scratch.layout.len();
    let mut out = Vec::with_capacity(rect.width * rect.height);
    for y in rect.y..rect.y + rect.height {
        let records = scratch.read(y * width + rect.x, rect.width)?;
        out.extend(records.chunks_exact(len).map(|r| model.fit(r)));
    }
    Ok(out)
}

/// The materials and colours of the pixels of `rect`.
fn fits_with_colours(
    scratch: &Scratch,
    model: &PixelModel,
    width: usize,
    rect: Rect,
) -> Result<Vec<(PixelFit, PixelColours)>> {
    let len = scratch.layout.len();
    let mut out = Vec::with_capacity(rect.width * rect.height);
    for y in rect.y..rect.y + rect.height {
        let records = scratch.read(y * width + rect.x, rect.width)?;
        out.extend(records.chunks_exact(len).map(|r| {
            let fit = model.fit(r);
            let colours = model.colours(r, &fit);
            (fit, colours)
        }));
    }
    Ok(out)
}

/// Writes the bands of a fit's uncompressed EXR outputs elsewhere: the workers of a
/// cluster, each running [`super::band::write_band`] on its rows' records.
pub trait BandMapper: Sync {
    /// Runs `write_band` of `job` on bands of whole rows of tiles covering the image
    /// and hands each band's first row and result to `each`, in row order. Returns false
    /// when it writes nothing (the outputs are then written here).
    fn write_bands(
        &self,
        job: &OutputJob,
        each: &mut dyn FnMut(usize, BandOutputs) -> Result<()>,
    ) -> Result<bool>;
}

/// Removes what an earlier run killed while writing this folder's outputs left of them:
/// its half-written files beside their targets (`.fluorite-<process>-<output>`, and
/// `.fluorite-XXXXXX` of the material map), which only a Ctrl-C, not a kill, removes.
fn remove_leftovers(out: &Path) {
    let own = format!(".fluorite-{}-", std::process::id());
    let Ok(entries) = std::fs::read_dir(out) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(rest) = name.strip_prefix(".fluorite-") else {
            continue;
        };
        let staged_output = rest.split_once('-').is_some_and(|(process, output)| {
            !process.is_empty()
                && process.bytes().all(|b| b.is_ascii_digit())
                && !name.starts_with(&own)
                && (matches!(
                    output,
                    "concentration.exr" | "reflectance.exr" | "fitted.exr" | "delta-e.exr"
                ) || ((output.starts_with("delta-e-") || output.starts_with("under-"))
                    && output.ends_with(".png")))
        });
        let temporary = rest.len() == 6 && rest.bytes().all(|b| b.is_ascii_alphanumeric());
        if (staged_output || temporary) && entry.file_type().is_ok_and(|t| t.is_file()) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// Writes every output of the fit into `out`; with `bands` (and uncompressed outputs),
/// the EXR outputs' tiles are written by its workers.
#[allow(clippy::too_many_arguments)]
pub fn write_all(
    out: &Path,
    image: PixelSource<'_>,
    scratch: &Scratch,
    model: &PixelModel,
    gauge: &Gauge,
    trial: &Trial,
    trials: &[Trial],
    census: &Census,
    options: &ImageFitOptions,
    state: &mut State,
    report: &(dyn Fn(Step) + Sync),
    notes: &[String],
    bands: Option<&dyn BandMapper>,
) -> Result<Written> {
    remove_leftovers(out);
    let (width, height) = (image.width(), image.height());
    let layout = &image.layout();
    let k = model.components();
    let nd = layout.diagonal_count;
    let mut files = Vec::new();
    let tiles =
        width.div_ceil(crate::image::sink::TILE) * height.div_ceil(crate::image::sink::TILE);
    let stem = image.stem();
    let attributes = vec![
        ("spectralLayoutVersion".to_string(), "1.0".to_string()),
        ("fluoriteSource".to_string(), image.describe()),
    ];
    let clamped = AtomicUsize::new(0);
    let step = |what: &str, total: usize| {
        report(Step::Stage {
            what: what.to_string(),
            total,
        })
    };
    let lights = model.lights().to_vec();
    let specs = exr_specs(
        (width, height),
        layout,
        k,
        &lights,
        image.half(),
        options.zip,
        &attributes,
    );
    let [
        concentration_path,
        reflectance_path,
        fitted_path,
        delta_path,
    ] = EXR_OUTPUTS.map(|name| out.join(name));
    let vectors: Vec<Vec<f64>> = (0..k)
        .map(|c| trial.shared.cell_vector(&super::cells_of(layout), c))
        .collect();
    let style = PngStyle::new(model, options.max_delta_e);

    // Uncompressed outputs with a mapper: written by the workers, band by band.
    let mut elsewhere = false;
    if let (Some(mapper), false) = (bands, options.zip) {
        let job_paths = [
            &concentration_path,
            &reflectance_path,
            &fitted_path,
            &delta_path,
        ];
        if let Some((pngs, band_clamped)) = write_elsewhere(
            out,
            mapper,
            &specs,
            job_paths,
            model,
            trial,
            image.half(),
            &attributes,
            &style,
            (width, height),
            report,
        )? {
            clamped.store(band_clamped, Ordering::Relaxed);
            files.extend(job_paths.iter().map(|p| p.to_path_buf()));
            files.extend(pngs);
            elsewhere = true;
        }
    }

    if !elsewhere {
        // concentration.exr: counts the clamped pixels on the way.
        step("writing concentration.exr", tiles);
        write_image(
            &concentration_path,
            &specs[0],
            |rect| {
                let mut v = Vec::with_capacity(rect.width * rect.height * k);
                for f in fits(scratch, model, width, rect)? {
                    if f.clamped {
                        clamped.fetch_add(1, Ordering::Relaxed);
                    }
                    concentration_values(&f, k, &mut v);
                }
                Ok(v)
            },
            |d, _| report(Step::Done(d)),
        )?;
        files.push(concentration_path);

        // reflectance.exr: the reflective spectral layout.
        step("writing reflectance.exr", tiles);
        write_image(
            &reflectance_path,
            &specs[1],
            |rect| {
                let mut v = Vec::with_capacity(rect.width * rect.height * nd);
                for f in fits(scratch, model, width, rect)? {
                    reflectance_values(&f, &mut v);
                }
                Ok(v)
            },
            |d, _| report(Step::Done(d)),
        )?;
        files.push(reflectance_path);

        // fitted.exr, delta-e.exr and the PNGs are written at the same time: fitted.exr is
        // as large as the input, and copying it into the file is one thread's work (about
        // 1 GB/s here) that would otherwise leave the other threads idle. One progress bar
        // counts the tiles and rows of all three.
        step(
            "writing fitted.exr, delta-e.exr and the PNG images",
            2 * tiles + height,
        );
        let done = AtomicUsize::new(0);
        let advance =
            |units: usize| report(Step::Done(done.fetch_add(units, Ordering::Relaxed) + units));
        let write_fitted = || {
            let mut last = 0;
            write_image(
                &fitted_path,
                &specs[2],
                |rect| {
                    let mut v = Vec::with_capacity(rect.width * rect.height * layout.len());
                    for f in fits(scratch, model, width, rect)? {
                        fitted_values(&f, &vectors, &mut v);
                    }
                    Ok(v)
                },
                |d, _| {
                    advance(d - last);
                    last = d;
                },
            )
        };
        let write_rest = || -> Result<Vec<PathBuf>> {
            let mut last = 0;
            write_image(
                &delta_path,
                &specs[3],
                |rect| {
                    let mut v = Vec::with_capacity(rect.width * rect.height * lights.len());
                    for (_, colours) in fits_with_colours(scratch, model, width, rect)? {
                        delta_e_values(&colours, &mut v);
                    }
                    Ok(v)
                },
                |d, _| {
                    advance(d - last);
                    last = d;
                },
            )?;
            // ΔE false colour and measured | fitted under each light, row by row.
            write_pngs(out, scratch, model, &style, width, height, &advance)
        };
        let (fitted, rest) = std::thread::scope(|scope| {
            let fitted = scope.spawn(write_fitted);
            let rest = write_rest();
            (fitted.join(), rest)
        });
        let fitted = fitted.unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        match (fitted, rest) {
            (Ok(()), Ok(pngs)) => {
                files.push(fitted_path);
                files.push(delta_path);
                files.extend(pngs);
            }
            (Err(e), _) | (_, Err(e)) => return Err(e),
        }
    }

    // The material map, last: its presence means the textures are complete. Nothing in
    // it or in the images' headers depends on the run (no times, no output or work
    // folder; the image as the command named it): a resumed run writes the bytes an
    // uninterrupted one does.
    let map_path = out.join("material-map.json");
    let fit = serde_json::json!({
        "image": image.describe(),
        "width": width,
        "height": height,
        "cells_per_pixel": layout.len(),
        "components": k,
        "bound": {
            "max_delta_e": options.max_delta_e,
            "share": options.share,
            "lights": lights,
            "rule": "the smallest K whose fit is within the bound under every light on at least the share of unmasked pixels (fitted against measured, the layout's cells)",
        },
        "trials": trials.iter().map(|t| serde_json::json!({
            "components": t.components,
            "share_within": t.share_within,
            "median_delta_e": t.median_delta_e,
            "p99_delta_e": t.p99_delta_e,
            "max_delta_e": t.max_delta_e,
            "residual_share": t.residual_share,
            "iterations": t.iterations,
            "converged": t.converged,
        })).collect::<Vec<_>>(),
        "masked_pixels": census.masked_pixels,
        "non_finite_cells": census.non_finite_cells,
        "clamped_pixels": clamped.load(Ordering::Relaxed),
        "notes": notes,
    });
    let map = MaterialMap {
        schema: SCHEMA.to_string(),
        name: stem,
        width,
        height,
        fluorophores: gauge.fluorophores.clone(),
        gauge: format!(
            "each fluorophore's yield is the largest its form's conservation laws allow, chosen once for the image, so every pixel has the smallest concentration its measurement allows: {}",
            gauge.description.join("; ")
        ),
        textures: Textures {
            concentration: "concentration.exr".into(),
            concentration_channels: (0..k).map(concentration_channel).collect(),
            reflectance: "reflectance.exr".into(),
        },
        fit: Some(fit),
    };
    write_atomic(&map_path, map.to_json().as_bytes())?;
    files.push(map_path.clone());
    state.mark("outputs")?;
    Ok(Written {
        map_path,
        files,
        clamped_pixels: clamped.load(Ordering::Relaxed),
    })
}

/// The PNGs of a fit (per light, the ΔE2000 map and the image measured | fitted), being
/// written row by row in order: each staged beside its target until [`PngFiles::finish`].
struct PngFiles {
    targets: Vec<(PathBuf, PathBuf)>,
    writers: Vec<png::StreamWriter<'static, BufWriter<File>>>,
    width: usize,
}

impl PngFiles {
    fn create(out: &Path, lights: &[String], width: usize, height: usize) -> Result<PngFiles> {
        let mut targets = Vec::new();
        let mut writers = Vec::new();
        for light in lights {
            for (name, w) in [
                (format!("delta-e-{}.png", file_part(light)), width),
                (format!("under-{}.png", file_part(light)), 2 * width + GAP),
            ] {
                let path = out.join(name);
                let tmp = crate::files::stage_beside(&path)?;
                let file = File::create(&tmp).map_err(|e| Error::io(&tmp, e))?;
                let mut encoder = png::Encoder::new(BufWriter::new(file), w as u32, height as u32);
                encoder.set_color(png::ColorType::Rgb);
                encoder.set_depth(png::BitDepth::Eight);
                let writer = encoder
                    .write_header()
                    .and_then(|w| w.into_stream_writer())
                    .map_err(|e| Error::io(&tmp, std::io::Error::other(e.to_string())))?;
                targets.push((path, tmp));
                writers.push(writer);
            }
        }
        Ok(PngFiles {
            targets,
            writers,
            width,
        })
    }

    /// The next `rows` (each [`PngStyle::row_bytes`] long, laid out as it says) into
    /// every PNG; each PNG is encoded by its own thread (deflate is most of the writing).
    fn write_rows(&mut self, style: &PngStyle, rows: &[u8]) -> Result<()> {
        let width = self.width;
        let row_bytes = style.row_bytes(width);
        let targets = &self.targets;
        self.writers
            .par_iter_mut()
            .enumerate()
            .try_for_each(|(i, writer)| {
                let (l, under) = (i / 2, i % 2 == 1);
                rows.chunks_exact(row_bytes).try_for_each(|row| {
                    let (delta_row, under_row) = style.split(row, width, l);
                    writer
                        .write_all(if under { under_row } else { delta_row })
                        .map_err(|e| Error::io(&targets[i].1, e))
                })
            })
    }

    /// Ends every PNG and moves it into place.
    fn finish(self) -> Result<Vec<PathBuf>> {
        let mut files = Vec::new();
        for (writer, (path, tmp)) in self.writers.into_iter().zip(self.targets) {
            writer
                .finish()
                .map_err(|e| Error::io(&tmp, std::io::Error::other(e.to_string())))?;
            crate::files::persist_staged(&tmp, &path)?;
            files.push(path);
        }
        Ok(files)
    }

    /// Removes the staged files (after a failure).
    fn discard(self) {
        for (_, tmp) in &self.targets {
            crate::files::discard_staged(tmp);
        }
    }
}

/// The ΔE2000 maps and the images under each light, row by row; `advance` gets the rows
/// written since its last call.
fn write_pngs(
    out: &Path,
    scratch: &Scratch,
    model: &PixelModel,
    style: &PngStyle,
    width: usize,
    height: usize,
    advance: &(dyn Fn(usize) + Sync),
) -> Result<Vec<PathBuf>> {
    let mut pngs = PngFiles::create(out, model.lights(), width, height)?;
    // One row of every PNG.
    let row_pixels = |y: usize| -> Result<Vec<u8>> {
        let fits = fits_with_colours(
            scratch,
            model,
            width,
            Rect {
                x: 0,
                y,
                width,
                height: 1,
            },
        )?;
        let mut row = style.blank_row(width);
        for (x, (f, colours)) in fits.iter().enumerate() {
            style.fill(&mut row, width, x, f, colours);
        }
        Ok(row)
    };
    // Rows are computed in parallel a band at a time and written in order.
    let band = ROWS_PER_THREAD * rayon::current_num_threads().max(1);
    let written = (|| -> Result<()> {
        for first in (0..height).step_by(band) {
            crate::files::check_interrupted(out)?;
            let rows = (first..(first + band).min(height))
                .into_par_iter()
                .map(row_pixels)
                .collect::<Result<Vec<_>>>()?;
            pngs.write_rows(style, &rows.concat())?;
            advance((first + band).min(height) - first);
        }
        Ok(())
    })();
    match written {
        Ok(()) => pngs.finish(),
        Err(e) => {
            pngs.discard();
            Err(e)
        }
    }
}

/// The EXR outputs written by `mapper`'s workers into files laid out here (each staged
/// beside its target, moved into place when every band is written), and the PNGs encoded
/// here from the bands' rows, in order. None when the mapper writes nothing.
#[allow(clippy::too_many_arguments)]
fn write_elsewhere(
    out: &Path,
    mapper: &dyn BandMapper,
    specs: &[crate::image::sink::ImageSpec; 4],
    paths: [&PathBuf; 4],
    model: &PixelModel,
    trial: &Trial,
    half: bool,
    attributes: &[(String, String)],
    style: &PngStyle,
    (width, height): (usize, usize),
    report: &(dyn Fn(Step) + Sync),
) -> Result<Option<(Vec<PathBuf>, usize)>> {
    let mut staged = Vec::new();
    let result = (|| -> Result<Option<(Vec<PathBuf>, usize)>> {
        for (spec, path) in specs.iter().zip(paths) {
            let tmp = crate::files::stage_beside(path)?;
            staged.push(tmp.clone());
            TiledFile::plan(&tmp, spec)?.create(&tmp)?;
        }
        let job = OutputJob {
            shared: trial.shared.clone(),
            sigma: model.sigma(),
            staged: staged.clone(),
            attributes: attributes.to_vec(),
            half,
        };
        report(Step::Stage {
            what: "writing the outputs (workers: the EXR tiles; here: the PNG images)".into(),
            total: height,
        });
        let mut pngs = PngFiles::create(out, model.lights(), width, height)?;
        let (mut next, mut clamped) = (0usize, 0usize);
        let row_bytes = style.row_bytes(width);
        let mut each = |y: usize, band: BandOutputs| -> Result<()> {
            let rows = band.png.len() / row_bytes;
            if y != next || rows == 0 || rows * row_bytes != band.png.len() || y + rows > height {
                return Err(Error::invalid(
                    "outputs",
                    format!(
                        "a band of rows {y}..{} came where row {next} was due",
                        y + rows
                    ),
                ));
            }
            pngs.write_rows(style, &band.png)?;
            clamped += band.clamped;
            next += rows;
            report(Step::Done(next));
            Ok(())
        };
        let ran = mapper.write_bands(&job, &mut each);
        let complete = match ran {
            Ok(true) if next == height => Ok(true),
            Ok(true) => Err(Error::invalid(
                "outputs",
                format!("the bands ended at row {next} of {height}"),
            )),
            Ok(false) => Ok(false),
            Err(e) => Err(e),
        };
        match complete {
            Ok(true) => {
                let files = pngs.finish()?;
                for (tmp, path) in staged.iter().zip(paths) {
                    crate::files::persist_staged(tmp, path)?;
                }
                Ok(Some((files, clamped)))
            }
            Ok(false) => {
                pngs.discard();
                Ok(None)
            }
            Err(e) => {
                pngs.discard();
                Err(e)
            }
        }
    })();
    if !matches!(result, Ok(Some(_))) {
        for tmp in &staged {
            crate::files::discard_staged(tmp);
        }
    }
    result
}
