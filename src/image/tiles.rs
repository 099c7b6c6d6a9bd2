//! The bytes of a tiled OpenEXR as fluorite writes it: the header, each tile's chunk, and
//! where each chunk lies in an uncompressed file, whose every chunk's size, and so its
//! place, is known before any pixel is produced ([`TiledFile`]: written by several
//! processes, each its own tiles). [`crate::image::sink`] writes whole images with them.

use std::collections::HashMap;
use std::fs::File;
use std::path::Path;

use exr::compression::Compression;
use exr::math::{RoundingMode, Vec2};
use exr::meta::BlockDescription;
use exr::meta::attribute::{
    AttributeValue, ChannelDescription, LevelMode, LineOrder, SampleType, Text, TileDescription,
};
use exr::meta::header::Header;

use crate::error::{Error, Result};
use crate::formats::exr::header_text as text;

/// Tile edge of every image fluorite writes: a 64 × 64 tile of a 49 × 41 bispectral
/// image is 19 MB as 32-bit floats, whatever the image's width.
pub const TILE: usize = 64;

/// The fields before a tiled chunk's data: tile x, tile y, level x, level y, data size
/// (an i32 each).
pub(super) const CHUNK_HEAD: usize = 5 * 4;

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

impl Rect {
    /// The pixels of an image block.
    pub(super) fn of_block(block: &exr::block::BlockIndex) -> Rect {
        Rect {
            x: block.pixel_position.x(),
            y: block.pixel_position.y(),
            width: block.pixel_size.x(),
            height: block.pixel_size.y(),
        }
    }
}

/// What an image written by [`write_image`](crate::image::sink::write_image) holds.
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

impl ImageSpec {
    /// The bytes of an uncompressed chunk's pixels (`block`'s pixels × channels × sample).
    pub(super) fn chunk_data_bytes(&self, block: &exr::block::BlockIndex) -> usize {
        let sample_bytes = if self.half { 2 } else { 4 };
        block.pixel_size.x() * block.pixel_size.y() * self.channels.len() * sample_bytes
    }
}

/// The header of an image of `spec`, and the order of its channels in the file:
/// `order[k]` is the producer's index of the file's k-th channel (sorted by name).
pub(super) fn header_of(path: &Path, spec: &ImageSpec) -> Result<(Header, Vec<usize>)> {
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
    Ok((header, order))
}

/// A tile's values (pixel by pixel, channels in the producer's order) as the bytes of an
/// uncompressed OpenEXR tile: row by row, each row channel by channel in the file's order.
pub(super) fn tile_bytes(
    values: &[f32],
    rect: Rect,
    spec: &ImageSpec,
    order: &[usize],
) -> Result<Vec<u8>> {
    let sample = if spec.half { 2 } else { 4 };
    let mut data = vec![0u8; values.len() * sample];
    fill_tile_bytes(values, rect, spec, order, &mut data)?;
    Ok(data)
}

/// A whole uncompressed tiled chunk of `rect` into `chunk` (exactly its size): the
/// chunk's fields (tile x, tile y, level 0, 0, data size), then [`fill_tile_bytes`].
pub(super) fn fill_tile_chunk(
    values: &[f32],
    rect: Rect,
    spec: &ImageSpec,
    order: &[usize],
    chunk: &mut [u8],
) -> Result<()> {
    let (head, data) = chunk.split_at_mut(CHUNK_HEAD);
    let size = i32::try_from(data.len())
        .map_err(|_| Error::invalid("image writer", "a tile larger than an OpenEXR chunk"))?;
    let tile = |v: usize| (v / TILE) as i32;
    for (field, value) in head
        .chunks_exact_mut(4)
        .zip([tile(rect.x), tile(rect.y), 0, 0, size])
    {
        field.copy_from_slice(&value.to_le_bytes());
    }
    fill_tile_bytes(values, rect, spec, order, data)
}

/// [`tile_bytes`] written into `data` (exactly the tile's size).
fn fill_tile_bytes(
    values: &[f32],
    rect: Rect,
    spec: &ImageSpec,
    order: &[usize],
    data: &mut [u8],
) -> Result<()> {
    let channel_count = spec.channels.len();
    let sample = if spec.half { 2 } else { 4 };
    if values.len() != rect.width * rect.height * channel_count
        || data.len() != values.len() * sample
    {
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
    let width = rect.width;
    // Each row is transposed to channel-major in cache-sized blocks first: gathering a
    // channel straight from the pixel-major values reads one value per cache line.
    const BLOCK: usize = 16;
    let mut planar = vec![0f32; width * channel_count];
    let mut out = data.chunks_exact_mut(width * sample);
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
            let line = out.next().expect("the data holds every row's channels");
            if spec.half {
                for (o, &v) in line.chunks_exact_mut(2).zip(samples) {
                    o.copy_from_slice(&exr::prelude::f16::from_f32(v).to_le_bytes());
                }
            } else {
                for (o, &v) in line.chunks_exact_mut(4).zip(samples) {
                    o.copy_from_slice(&v.to_le_bytes());
                }
            }
        }
    }
    Ok(())
}

/// Where everything of an uncompressed tiled image lies: every chunk's size, and so its
/// place, is known before any pixel is produced.
pub(super) struct UncompressedLayout {
    /// The header (given back for the exr crate's writer).
    pub(super) headers: [Header; 1],
    /// The bytes before the first chunk: magic number, version, header, offset table.
    pub(super) head: Vec<u8>,
    /// The chunks in the order they follow the offset table (increasing y), each with its
    /// index in the table.
    pub(super) blocks: Vec<(usize, exr::block::BlockIndex)>,
    /// Each chunk's place in the file, by its index in the table.
    pub(super) offsets: Vec<u64>,
    /// The file's length.
    pub(super) length: u64,
}

impl UncompressedLayout {
    /// The layout of `header`'s image, written as the exr crate's writer writes it
    /// (headers, the offset table, the chunks in increasing-y order).
    pub(super) fn of(tmp: &Path, header: Header, spec: &ImageSpec) -> Result<UncompressedLayout> {
        let encode_failure = |e: exr::error::Error| {
            Error::io(
                tmp,
                std::io::Error::other(format!("OpenEXR writing failed: {e}")),
            )
        };
        let headers = [header];
        let requirements = exr::meta::MetaData::validate(&headers, true).map_err(encode_failure)?;
        let mut head = Vec::new();
        exr::meta::magic_number::write(&mut head).map_err(encode_failure)?;
        requirements.write(&mut head).map_err(encode_failure)?;
        exr::meta::header::Header::write_all(&headers, &mut head, requirements.has_multiple_layers)
            .map_err(encode_failure)?;
        let blocks: Vec<(usize, exr::block::BlockIndex)> =
            exr::block::enumerate_ordered_header_block_indices(&headers).collect();
        let total = blocks.len();
        let data_size = |b: &exr::block::BlockIndex| spec.chunk_data_bytes(b);
        if let Some(block) = blocks
            .iter()
            .find(|(_, b)| i32::try_from(data_size(b)).is_err())
        {
            return Err(Error::invalid(
                tmp.display().to_string(),
                format!(
                    "a tile of {} channels is {} bytes, more than an OpenEXR chunk holds; write fewer channels",
                    spec.channels.len(),
                    data_size(&block.1)
                ),
            ));
        }
        // The chunks follow the offset table in the order of `blocks`.
        let mut offsets = vec![0u64; total];
        let mut next = (head.len() + 8 * total) as u64;
        for (index, block) in &blocks {
            offsets[*index] = next;
            next += (CHUNK_HEAD + data_size(block)) as u64;
        }
        for offset in &offsets {
            head.extend_from_slice(&offset.to_le_bytes());
        }
        if usize::try_from(next).is_err() {
            return Err(Error::invalid(
                tmp.display().to_string(),
                "the image is larger than this machine's address space",
            ));
        }
        Ok(UncompressedLayout {
            headers,
            head,
            blocks,
            offsets,
            length: next,
        })
    }
}

/// An uncompressed tiled image written by several processes: [`TiledFile::plan`] lays
/// it out, [`TiledFile::create`] writes its header and offset table and sets its length,
/// and [`TiledFile::write_tiles`] writes tiles into their places from any process that
/// opens the file (the workers of a cluster, each its own tiles). The bytes are those
/// [`write_image`](crate::image::sink::write_image) writes for the same `spec`.
pub struct TiledFile {
    spec: ImageSpec,
    order: Vec<usize>,
    layout: UncompressedLayout,
}

impl TiledFile {
    /// The layout of an uncompressed image of `spec` (`path` names it in errors).
    pub fn plan(path: &Path, spec: &ImageSpec) -> Result<TiledFile> {
        if spec.zip {
            return Err(Error::invalid(
                path.display().to_string(),
                "a compressed image's tiles have no place before they are compressed: write it with write_image",
            ));
        }
        let (header, order) = header_of(path, spec)?;
        let layout = UncompressedLayout::of(path, header, spec)?;
        Ok(TiledFile {
            spec: spec.clone(),
            order,
            layout,
        })
    }

    /// Tiles, in the order of the file (increasing y, then x).
    pub fn tiles(&self) -> usize {
        self.layout.blocks.len()
    }

    /// Tiles per row of tiles.
    pub fn tiles_per_row(&self) -> usize {
        self.spec.width.div_ceil(TILE)
    }

    /// The pixels of tile `tile`.
    pub fn rect(&self, tile: usize) -> Option<Rect> {
        self.layout.blocks.get(tile).map(|(_, b)| Rect::of_block(b))
    }

    /// Writes the header and the offset table into `path` (created or emptied) and gives
    /// it its whole length, the tiles' places reserved.
    pub fn create(&self, path: &Path) -> Result<()> {
        let io = |e: std::io::Error| Error::io(path, e);
        let file = File::create(path).map_err(io)?;
        // Not reserved (posix_fallocate writes every block on a file system without
        // fallocate, NFS among them): the tiles are written with pwrite, so a full disk
        // is an error of the worker that meets it.
        file.set_len(self.layout.length).map_err(io)?;
        write_at(&file, &self.layout.head, 0).map_err(io)
    }

    /// Writes tiles `tiles` into `path` (made by [`TiledFile::create`]): `produce(rect)`
    /// gives each tile's pixels as for [`write_image`](crate::image::sink::write_image).
    pub fn write_tiles(
        &self,
        path: &Path,
        tiles: std::ops::Range<usize>,
        mut produce: impl FnMut(Rect) -> Result<Vec<f32>>,
    ) -> Result<()> {
        let mut writer = self.writer(path)?;
        for tile in tiles {
            let rect = self.rect(tile).ok_or_else(|| {
                Error::invalid(
                    path.display().to_string(),
                    format!("tile {tile} of an image of {} tiles", self.tiles()),
                )
            })?;
            writer.write(tile, &produce(rect)?)?;
        }
        Ok(())
    }

    /// Opens `path` (made by [`TiledFile::create`]) to write tiles into, one after the
    /// other ([`TileWriter::write`]).
    pub fn writer<'a>(&'a self, path: &'a Path) -> Result<TileWriter<'a>> {
        let file = std::fs::OpenOptions::new()
            .write(true)
            .open(path)
            .map_err(|e| Error::io(path, e))?;
        Ok(TileWriter {
            plan: self,
            path,
            file,
            chunk: Vec::new(),
        })
    }
}

/// Writes tiles into a file laid out by a [`TiledFile`], each into its place, through
/// one buffer (a tile of a bispectral image is 19.5 MB: allocating it afresh for every
/// tile costs the kernel's first touch of its pages each time).
pub struct TileWriter<'a> {
    plan: &'a TiledFile,
    path: &'a Path,
    file: File,
    chunk: Vec<u8>,
}

impl TileWriter<'_> {
    /// Writes tile `tile` (in the file's order): `values` are its pixels, row by row,
    /// each pixel's values in the spec's channel order.
    pub fn write(&mut self, tile: usize, values: &[f32]) -> Result<()> {
        let plan = self.plan;
        let Some((index, block)) = plan.layout.blocks.get(tile) else {
            return Err(Error::invalid(
                self.path.display().to_string(),
                format!("tile {tile} of an image of {} tiles", plan.tiles()),
            ));
        };
        let rect = Rect::of_block(block);
        let sample = if plan.spec.half { 2 } else { 4 };
        let size = CHUNK_HEAD + rect.width * rect.height * plan.spec.channels.len() * sample;
        self.chunk.resize(size, 0);
        fill_tile_chunk(values, rect, &plan.spec, &plan.order, &mut self.chunk)?;
        write_at(&self.file, &self.chunk, plan.layout.offsets[*index])
            .map_err(|e| Error::io(self.path, e))
    }
}

/// Writes all of `bytes` at `offset` of `file`.
fn write_at(file: &File, bytes: &[u8], offset: u64) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileExt;
        file.write_all_at(bytes, offset)
    }
    #[cfg(windows)]
    {
        use std::os::windows::fs::FileExt;
        let mut done = 0;
        while done < bytes.len() {
            done += file.seek_write(&bytes[done..], offset + done as u64)?;
        }
        Ok(())
    }
}
