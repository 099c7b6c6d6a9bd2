//! Writing OpenEXR images block by block: the pixels of each tile are asked for when the
//! tile is written, so an image of any size is written with a few tiles in memory. The
//! file is written beside its target and renamed into place when complete.

use std::collections::HashMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use exr::block::UncompressedBlock;
use exr::block::writer::ChunksWriter;
use exr::compression::Compression;
use exr::math::{RoundingMode, Vec2};
use exr::meta::BlockDescription;
use exr::meta::attribute::{
    AttributeValue, ChannelDescription, LevelMode, LineOrder, SampleType, Text, TileDescription,
};
use exr::meta::header::Header;
use rayon::prelude::*;

use crate::error::{Error, Result};

/// Tile edge of every image fluorite writes: a 64 × 64 tile of a 49 × 41 bispectral
/// image is 19 MB as 32-bit floats, whatever the image's width.
pub const TILE: usize = 64;

/// Tiles produced and compressed together per thread.
const TILES_PER_THREAD: usize = 1;

/// A pixel rectangle of an image being written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rect {
    /// First column.
    pub x: usize,
    /// First row.
    pub y: usize,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
}

/// What an image written by [`write_image`] holds.
#[derive(Debug, Clone)]
pub struct ImageSpec {
    /// Pixels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Channel names, in the order the producer gives each pixel's values.
    pub channels: Vec<String>,
    /// 16-bit floats instead of 32-bit.
    pub half: bool,
    /// Lossless ZIP compression (smaller files, slower) instead of none.
    pub zip: bool,
    /// Text attributes of the header (name, value). `spectralLayoutVersion` is written as
    /// its own attribute; the others are joined into the standard `comments` attribute.
    pub attributes: Vec<(String, String)>,
}

/// OpenEXR text: Latin-1, other characters become `?`.
fn text(s: &str) -> Text {
    let latin1: String = s
        .chars()
        .map(|c| if (c as u32) < 256 { c } else { '?' })
        .collect();
    Text::new_or_none(latin1).unwrap_or_else(|| Text::from("?"))
}

/// Writes `path` tile by tile: `produce(rect)` returns the rectangle's pixels, row by row,
/// each pixel's values in `spec.channels`' order. Tiles are produced in parallel, a few at
/// a time, and written in order; `progress` gets the tiles written so far and the total.
pub fn write_image(
    path: &Path,
    spec: &ImageSpec,
    produce: impl Fn(Rect) -> Result<Vec<f32>> + Sync,
    mut progress: impl FnMut(usize, usize),
) -> Result<()> {
    let fail = |message: String| Error::invalid(path.display().to_string(), message);
    if spec.width == 0 || spec.height == 0 || spec.channels.is_empty() {
        return Err(fail("an image needs pixels and channels".into()));
    }
    // The file lists its channels sorted by name; `order[k]` is the producer's index of
    // the file's k-th channel.
    let mut order: Vec<usize> = (0..spec.channels.len()).collect();
    order.sort_by(|&a, &b| spec.channels[a].cmp(&spec.channels[b]));
    if let Some(w) = order
        .windows(2)
        .find(|w| spec.channels[w[0]] == spec.channels[w[1]])
    {
        return Err(fail(format!(
            "channel {} is named twice",
            spec.channels[w[0]]
        )));
    }
    let sample_type = if spec.half {
        SampleType::F16
    } else {
        SampleType::F32
    };
    let channels = order
        .iter()
        .map(|&k| ChannelDescription::new(text(&spec.channels[k]), sample_type, true))
        .collect();
    let mut header = Header::new(text("bispectral"), (spec.width, spec.height), channels)
        .with_encoding(
            if spec.zip {
                Compression::ZIP16
            } else {
                Compression::Uncompressed
            },
            BlockDescription::Tiles(TileDescription {
                tile_size: Vec2(TILE, TILE),
                level_mode: LevelMode::Singular,
                rounding_mode: RoundingMode::Down,
            }),
            LineOrder::Increasing,
        );
    header.own_attributes.layer_name = None;
    // The exr crate keeps custom attributes in a hash map and writes them in random
    // order: one custom attribute (the layout's version) keeps files byte-reproducible;
    // every other attribute goes into the standard `comments` text.
    let mut other: HashMap<Text, AttributeValue> = HashMap::new();
    let mut comments = Vec::new();
    for (name, value) in &spec.attributes {
        if name == crate::formats::exr::VERSION_ATTRIBUTE {
            other.insert(text(name), AttributeValue::Text(text(value)));
        } else {
            comments.push(format!("{name}: {value}"));
        }
    }
    header.own_attributes.other = other;
    if !comments.is_empty() {
        header.own_attributes.comments = Some(text(&comments.join("; ")));
    }
    header.own_attributes.software_name =
        Some(text(&format!("fluorite {}", env!("CARGO_PKG_VERSION"))));
    let tmp = crate::files::stage_beside(path)?;
    let written = write_tiles(&tmp, header, spec, &order, &produce, &mut progress);
    match written {
        Ok(()) => crate::files::persist_staged(&tmp, path),
        Err(e) => {
            crate::files::discard_staged(&tmp);
            Err(e)
        }
    }
}

/// A tile's values (pixel by pixel, channels in the producer's order) as the bytes of an
/// uncompressed OpenEXR tile: row by row, each row channel by channel in the file's order.
fn tile_bytes(values: &[f32], rect: Rect, spec: &ImageSpec, order: &[usize]) -> Result<Vec<u8>> {
    let channel_count = spec.channels.len();
    if values.len() != rect.width * rect.height * channel_count {
        return Err(Error::invalid(
            "image writer",
            format!(
                "a tile of {}×{} pixels got {} values for {channel_count} channels",
                rect.width,
                rect.height,
                values.len()
            ),
        ));
    }
    let bytes = if spec.half { 2 } else { 4 };
    let width = rect.width;
    let mut data = Vec::with_capacity(values.len() * bytes);
    // Each row is transposed to channel-major in cache-sized blocks first: gathering a
    // channel straight from the pixel-major values reads one value per cache line.
    const BLOCK: usize = 16;
    let mut planar = vec![0f32; width * channel_count];
    for row in values.chunks_exact(width * channel_count) {
        for x0 in (0..width).step_by(BLOCK) {
            for c0 in (0..channel_count).step_by(BLOCK) {
                let c1 = (c0 + BLOCK).min(channel_count);
                for x in x0..(x0 + BLOCK).min(width) {
                    for (c, &v) in
                        (c0..c1).zip(&row[x * channel_count + c0..x * channel_count + c1])
                    {
                        planar[c * width + x] = v;
                    }
                }
            }
        }
        for &c in order {
            let samples = &planar[c * width..(c + 1) * width];
            if spec.half {
                data.extend(
                    samples
                        .iter()
                        .flat_map(|&v| exr::prelude::f16::from_f32(v).to_ne_bytes()),
                );
            } else {
                data.extend(samples.iter().flat_map(|&v| v.to_ne_bytes()));
            }
        }
    }
    Ok(data)
}

fn write_tiles(
    tmp: &Path,
    header: Header,
    spec: &ImageSpec,
    order: &[usize],
    produce: &(impl Fn(Rect) -> Result<Vec<f32>> + Sync),
    progress: &mut impl FnMut(usize, usize),
) -> Result<()> {
    let io = |e: std::io::Error| Error::io(tmp, e);
    let file = File::create(tmp).map_err(io)?;
    let blocks: Vec<(usize, exr::block::BlockIndex)> =
        exr::block::enumerate_ordered_header_block_indices(std::slice::from_ref(&header)).collect();
    let total = blocks.len();
    let mut failure: Option<Error> = None;
    let group = TILES_PER_THREAD * rayon::current_num_threads().max(1);
    let headers: exr::meta::Headers = exr::prelude::SmallVec::from_vec(vec![header]);
    let encode_failure = |e: exr::error::Error| {
        Error::io(
            tmp,
            std::io::Error::other(format!("OpenEXR writing failed: {e}")),
        )
    };
    exr::block::write(
        BufWriter::with_capacity(1 << 20, file),
        headers,
        true,
        |meta, writer| {
            // Tiles are produced (in parallel) a group ahead of the writing: copying a
            // group into the file is one thread's work that would otherwise leave the
            // others idle.
            type Group = Result<Vec<(usize, exr::block::chunk::Chunk)>>;
            let (sender, receiver) = std::sync::mpsc::sync_channel::<Group>(1);
            std::thread::scope(|scope| {
                // The producer owns the sender: the receiver's loop ends when it does.
                scope.spawn(move || {
                    for group_blocks in blocks.chunks(group) {
                        let chunks: Group = crate::files::check_interrupted(tmp).and_then(|()| {
                            group_blocks
                                .par_iter()
                                .map(|&(index, block)| {
                                    let rect = Rect {
                                        x: block.pixel_position.x(),
                                        y: block.pixel_position.y(),
                                        width: block.pixel_size.x(),
                                        height: block.pixel_size.y(),
                                    };
                                    let data = tile_bytes(&produce(rect)?, rect, spec, order)?;
                                    let chunk = UncompressedBlock { index: block, data }
                                        .compress_to_chunk(&meta.headers)
                                        .map_err(encode_failure)?;
                                    Ok((index, chunk))
                                })
                                .collect()
                        });
                        let failed = chunks.is_err();
                        // The receiver is gone when writing failed.
                        if sender.send(chunks).is_err() || failed {
                            return;
                        }
                    }
                });
                let mut written = 0;
                for chunks in receiver.iter() {
                    match chunks {
                        Ok(chunks) => {
                            written += chunks.len();
                            for (index, chunk) in chunks {
                                writer.write_chunk(index, chunk)?;
                            }
                        }
                        Err(e) => {
                            failure = Some(e);
                            return Err(exr::error::Error::Aborted);
                        }
                    }
                    progress(written, total);
                }
                Ok(())
            })
        },
    )
    .map_err(|e| failure.take().unwrap_or_else(|| encode_failure(e)))?;
    if let Some(e) = failure {
        return Err(e);
    }
    Ok(())
}
