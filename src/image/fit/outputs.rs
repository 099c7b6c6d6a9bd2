//! The files of an image fit, each written tile by tile (EXR) or row by row (PNG) from
//! the scratch file, atomically: the material map and its textures, the fitted image in
//! the input's layout, ΔE2000 maps and the image under each light, measured beside
//! fitted.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

use crate::colour::{D65_WHITE, adapt_bradford, xyz_to_srgb8};
use crate::error::{Error, Result};
use crate::files::write_atomic;
use crate::image::array::PixelSource;
use crate::image::map::{MaterialMap, SCHEMA, Textures, concentration_channel};
use crate::image::sink::{ImageSpec, Rect, write_image};

use super::gauge::Gauge;
use super::passes::Census;
use super::pixel::{PixelColours, PixelFit, PixelModel};
use super::scratch::Scratch;
use super::state::State;
use super::{ImageFitOptions, Step, Trial};

/// The top of the ΔE2000 false-colour scale, in multiples of the bound.
const DELTA_E_SCALE: f64 = 2.0;
/// Columns between the measured and the fitted image in the light PNGs.
const GAP: usize = 8;
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

/// A light's name as a file-name part (the channels of `delta-e.exr`, the PNGs' names).
pub fn file_part(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c.to_ascii_lowercase()
            } else {
                '_'
            }
        })
        .collect()
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

/// Writes every output of the fit into `out`.
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

    // concentration.exr: counts the clamped pixels on the way.
    let concentration_path = out.join("concentration.exr");
    step("writing concentration.exr", tiles);
    write_image(
        &concentration_path,
        &ImageSpec {
            width,
            height,
            channels: (0..k).map(concentration_channel).collect(),
            half: false,
            zip: options.zip,
            attributes: attributes.clone(),
        },
        |rect| {
            let mut v = Vec::with_capacity(rect.width * rect.height * k);
            for f in fits(scratch, model, width, rect)? {
                if f.clamped {
                    clamped.fetch_add(1, Ordering::Relaxed);
                }
                v.extend(f.concentration[..k].iter().map(|&c| c as f32));
            }
            Ok(v)
        },
        |d, _| report(Step::Done(d)),
    )?;
    files.push(concentration_path);

    // reflectance.exr: the reflective spectral layout.
    let reflectance_path = out.join("reflectance.exr");
    let diagonal_names: Vec<String> = layout.channel_names()[..nd].to_vec();
    step("writing reflectance.exr", tiles);
    write_image(
        &reflectance_path,
        &ImageSpec {
            width,
            height,
            channels: diagonal_names,
            half: false,
            zip: options.zip,
            attributes: attributes.clone(),
        },
        |rect| {
            let mut v = Vec::with_capacity(rect.width * rect.height * nd);
            for f in fits(scratch, model, width, rect)? {
                v.extend(f.reflectance.iter().map(|&r| r as f32));
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
    let fitted_path = out.join("fitted.exr");
    let delta_path = out.join("delta-e.exr");
    let lights = model.lights().to_vec();
    let vectors: Vec<Vec<f64>> = (0..k)
        .map(|c| trial.shared.cell_vector(&super::cells_of(layout), c))
        .collect();
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
            &ImageSpec {
                width,
                height,
                channels: layout.channel_names(),
                half: image.half(),
                zip: options.zip,
                attributes: attributes.clone(),
            },
            |rect| {
                let mut v = Vec::with_capacity(rect.width * rect.height * layout.len());
                for f in fits(scratch, model, width, rect)? {
                    v.extend(f.fitted_diagonal.iter().map(|&d| d as f32));
                    for j in 0..layout.len() - nd {
                        let value: f64 = if f.masked {
                            f64::NAN
                        } else {
                            (0..k).map(|c| f.scores[c] * vectors[c][j]).sum()
                        };
                        v.push(value as f32);
                    }
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
            &ImageSpec {
                width,
                height,
                channels: lights.iter().map(|l| file_part(l)).collect(),
                half: false,
                zip: options.zip,
                attributes: attributes.clone(),
            },
            |rect| {
                let mut v = Vec::with_capacity(rect.width * rect.height * lights.len());
                for (_, colours) in fits_with_colours(scratch, model, width, rect)? {
                    v.extend(colours.delta_e.iter().map(|&d| d as f32));
                }
                Ok(v)
            },
            |d, _| {
                advance(d - last);
                last = d;
            },
        )?;
        // ΔE false colour and measured | fitted under each light, row by row.
        write_pngs(
            out,
            scratch,
            model,
            width,
            height,
            options.max_delta_e,
            &advance,
        )
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

/// The ΔE2000 maps and the images under each light, row by row; `advance` gets the rows
/// written since its last call.
fn write_pngs(
    out: &Path,
    scratch: &Scratch,
    model: &PixelModel,
    width: usize,
    height: usize,
    bound: f64,
    advance: &(dyn Fn(usize) + Sync),
) -> Result<Vec<PathBuf>> {
    let lights = model.lights().to_vec();
    let mut targets = Vec::new();
    let mut writers = Vec::new();
    for light in &lights {
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
    let png_error =
        |path: &Path, e: png::EncodingError| Error::io(path, std::io::Error::other(e.to_string()));
    let whites: Vec<[f64; 3]> = (0..lights.len()).map(|l| model.white(l)).collect();
    // One row's pixels of every PNG: per light, the ΔE map's row and the light image's.
    let row_pixels = |y: usize| -> Result<Vec<(Vec<u8>, Vec<u8>)>> {
        let row = fits_with_colours(
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
        Ok((0..lights.len())
            .map(|l| {
                let mut delta = Vec::with_capacity(width * 3);
                let mut under = vec![255u8; (2 * width + GAP) * 3];
                for (x, (f, colours)) in row.iter().enumerate() {
                    let o = (width + GAP + x) * 3;
                    if f.masked {
                        delta.extend([128, 128, 128]);
                        under[x * 3..x * 3 + 3].copy_from_slice(&[128, 128, 128]);
                        under[o..o + 3].copy_from_slice(&[128, 128, 128]);
                        continue;
                    }
                    let c = crate::plot::colormap::viridis(
                        colours.delta_e[l] / (DELTA_E_SCALE * bound),
                    );
                    delta.extend([c.0, c.1, c.2]);
                    let show = |xyz: [f64; 3]| {
                        let adapted = adapt_bradford(xyz, whites[l], D65_WHITE.map(|v| v * 100.0));
                        xyz_to_srgb8(adapted.map(|v| v / 100.0))
                    };
                    under[x * 3..x * 3 + 3].copy_from_slice(&show(colours.measured_xyz[l]));
                    under[o..o + 3].copy_from_slice(&show(colours.fitted_xyz[l]));
                }
                (delta, under)
            })
            .collect())
    };
    // Rows are computed in parallel a band at a time and written in order.
    let band = ROWS_PER_THREAD * rayon::current_num_threads().max(1);
    for first in (0..height).step_by(band) {
        crate::files::check_interrupted(out)?;
        let rows = (first..(first + band).min(height))
            .into_par_iter()
            .map(row_pixels)
            .collect::<Result<Vec<_>>>()?;
        // Each PNG is encoded by its own thread (deflate is most of the writing).
        writers
            .par_iter_mut()
            .enumerate()
            .try_for_each(|(i, writer)| {
                let (l, under) = (i / 2, i % 2 == 1);
                rows.iter().try_for_each(|row| {
                    let (delta_row, under_row) = &row[l];
                    writer
                        .write_all(if under { under_row } else { delta_row })
                        .map_err(|e| Error::io(&targets[i].1, e))
                })
            })?;
        advance((first + band).min(height) - first);
    }
    let mut files = Vec::new();
    for (writer, (path, tmp)) in writers.into_iter().zip(targets) {
        writer.finish().map_err(|e| png_error(&tmp, e))?;
        crate::files::persist_staged(&tmp, &path)?;
        files.push(path);
    }
    Ok(files)
}
