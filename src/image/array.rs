//! A bispectral image held in memory (a numpy array from Python, a test's image): the
//! same passes as a file, over blocks of rows.

use crate::error::{Error, Result};

use super::layout::Layout;
use super::source::{ExrImage, PixelBlock, PlanarBlock};

/// Rows per block of a pass over an in-memory image.
pub const ROWS_PER_BLOCK: usize = 16;

/// An image in memory: `values[(y·width + x)·cells + c]` in the layout's canonical order.
#[derive(Debug, Clone, PartialEq)]
pub struct ArrayImage {
    /// A name for reports and outputs (the file stem it stands for).
    pub name: String,
    /// Pixels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// The cells of every pixel.
    pub layout: Layout,
    /// The values, pixel-major.
    pub values: Vec<f32>,
}

impl ArrayImage {
    /// Checks the shape: `values` must hold width × height × cells numbers, and the image
    /// more than one pixel.
    pub fn new(
        name: &str,
        width: usize,
        height: usize,
        layout: Layout,
        values: Vec<f32>,
    ) -> Result<ArrayImage> {
        if width * height < 2 {
            return Err(Error::invalid(
                "image",
                format!(
                    "{} pixel(s): an image fit shares its fluorophores across pixels; fit a single matrix instead",
                    width * height
                ),
            ));
        }
        if values.len() != width * height * layout.len() {
            return Err(Error::invalid(
                "image",
                format!(
                    "{} values for {width} × {height} pixels of {} cells ({} expected)",
                    values.len(),
                    layout.len(),
                    width * height * layout.len()
                ),
            ));
        }
        Ok(ArrayImage {
            name: name.to_string(),
            width,
            height,
            layout,
            values,
        })
    }
}

/// Where an image fit reads its pixels from.
#[derive(Debug, Clone, Copy)]
pub enum PixelSource<'a> {
    /// A bispectral OpenEXR file, streamed.
    Exr(&'a ExrImage),
    /// An image in memory.
    Array(&'a ArrayImage),
}

impl PixelSource<'_> {
    /// Pixels per row.
    pub fn width(&self) -> usize {
        match self {
            PixelSource::Exr(i) => i.width,
            PixelSource::Array(i) => i.width,
        }
    }

    /// Rows.
    pub fn height(&self) -> usize {
        match self {
            PixelSource::Exr(i) => i.height,
            PixelSource::Array(i) => i.height,
        }
    }

    /// Pixels.
    pub fn pixels(&self) -> usize {
        self.width() * self.height()
    }

    /// The cells of a pixel.
    pub fn layout(&self) -> &Layout {
        match self {
            PixelSource::Exr(i) => &i.layout,
            PixelSource::Array(i) => &i.layout,
        }
    }

    /// What to call the image in reports (its path or name).
    pub fn describe(&self) -> String {
        match self {
            PixelSource::Exr(i) => i.path.display().to_string(),
            PixelSource::Array(i) => i.name.clone(),
        }
    }

    /// The name outputs take (file stem).
    pub fn stem(&self) -> String {
        match self {
            PixelSource::Exr(i) => i
                .path
                .file_stem()
                .map_or_else(|| "image".to_string(), |s| s.to_string_lossy().into_owned()),
            PixelSource::Array(i) => i.name.clone(),
        }
    }

    /// Whether the fitted image is written with 16-bit floats (as the input).
    pub fn half(&self) -> bool {
        match self {
            PixelSource::Exr(i) => i.half,
            PixelSource::Array(_) => false,
        }
    }

    /// Blocks a pass reads.
    pub fn blocks(&self) -> usize {
        match self {
            PixelSource::Exr(i) => i.blocks(),
            PixelSource::Array(i) => i.height.div_ceil(ROWS_PER_BLOCK),
        }
    }

    /// The input's identity for resuming: a file's path, size, modification and status
    /// change times (a copy that keeps the modification time still changes the latter)
    /// and a hash of the bytes at its two ends (header, chunk offsets and the last
    /// chunk); a hash of the values of an array.
    pub fn identity(&self) -> Result<String> {
        match self {
            PixelSource::Exr(i) => {
                use sha2::{Digest, Sha256};
                use std::io::{Read, Seek, SeekFrom};
                use std::os::unix::fs::MetadataExt;
                const END: u64 = 1 << 16;
                let io = |e| Error::io(&i.path, e);
                let mut file = std::fs::File::open(&i.path).map_err(io)?;
                let meta = file.metadata().map_err(io)?;
                let modified = meta
                    .modified()
                    .ok()
                    .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
                    .map_or(0, |d| d.as_nanos());
                let mut hasher = Sha256::new();
                let mut bytes = Vec::new();
                (&mut file).take(END).read_to_end(&mut bytes).map_err(io)?;
                file.seek(SeekFrom::Start(meta.len().saturating_sub(END).max(END)))
                    .map_err(io)?;
                file.take(END).read_to_end(&mut bytes).map_err(io)?;
                hasher.update(&bytes);
                let hex: String = hasher
                    .finalize()
                    .iter()
                    .map(|b| format!("{b:02x}"))
                    .collect();
                let path = std::fs::canonicalize(&i.path).unwrap_or_else(|_| i.path.clone());
                Ok(format!(
                    "{} {} bytes, modified {modified}, changed {}.{:09}, ends {hex}",
                    path.display(),
                    meta.len(),
                    meta.ctime(),
                    meta.ctime_nsec()
                ))
            }
            PixelSource::Array(i) => {
                use sha2::{Digest, Sha256};
                let mut hasher = Sha256::new();
                for v in &i.values {
                    hasher.update(v.to_le_bytes());
                }
                let digest = hasher.finalize();
                let hex: String = digest.iter().map(|b| format!("{b:02x}")).collect();
                Ok(format!("array {} {}×{} {hex}", i.name, i.width, i.height))
            }
        }
    }

    /// One pass over blocks stored plane by plane (see [`ExrImage::pass_planar`]).
    pub fn pass_planar<T: Send>(
        &self,
        map: impl Fn(PlanarBlock) -> Result<T> + Sync,
        fold: impl FnMut(T) -> Result<()>,
        progress: impl FnMut(usize),
    ) -> Result<()> {
        match self {
            PixelSource::Exr(i) => i.pass_planar(map, fold, progress),
            PixelSource::Array(_) => self.pass(
                |b| {
                    let n = b.pixel_count();
                    let mut planes = vec![0f32; n * b.cells];
                    for q in 0..n {
                        for (c, &v) in b.pixel(q).iter().enumerate() {
                            planes[c * n + q] = v;
                        }
                    }
                    map(PlanarBlock {
                        x: b.x,
                        y: b.y,
                        width: b.width,
                        height: b.height,
                        cells: b.cells,
                        planes,
                    })
                },
                fold,
                progress,
            ),
        }
    }

    /// One pass over the pixels (see [`ExrImage::pass`]).
    pub fn pass<T: Send>(
        &self,
        map: impl Fn(&PixelBlock) -> Result<T> + Sync,
        mut fold: impl FnMut(T) -> Result<()>,
        mut progress: impl FnMut(usize),
    ) -> Result<()> {
        match self {
            PixelSource::Exr(i) => i.pass(map, fold, progress),
            PixelSource::Array(i) => {
                use rayon::prelude::*;
                let cells = i.layout.len();
                let blocks: Vec<usize> = (0..i.height.div_ceil(ROWS_PER_BLOCK)).collect();
                let group = 2 * rayon::current_num_threads().max(1);
                for (g, chunk) in blocks.chunks(group).enumerate() {
                    let results: Vec<Result<T>> = chunk
                        .par_iter()
                        .map(|&b| {
                            let y = b * ROWS_PER_BLOCK;
                            let height = ROWS_PER_BLOCK.min(i.height - y);
                            let start = y * i.width * cells;
                            let block = PixelBlock {
                                x: 0,
                                y,
                                width: i.width,
                                height,
                                cells,
                                values: i.values[start..start + height * i.width * cells].to_vec(),
                            };
                            map(&block)
                        })
                        .collect();
                    for r in results {
                        fold(r?)?;
                    }
                    progress(((g + 1) * group).min(blocks.len()));
                }
                Ok(())
            }
        }
    }
}
