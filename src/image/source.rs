//! Reading a bispectral OpenEXR image as a stream of pixel blocks.
//!
//! The file is never held whole: a pass reads the file's chunks (scanline blocks or
//! tiles of the full-resolution level) in file order, a few at a time, decompresses and
//! converts them in parallel, and hands each block's result to a fold in file order. The
//! memory a pass holds is a few chunks, whatever the image's size, and its result does not
//! depend on the number of threads.

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use exr::block::UncompressedBlock;
use exr::block::chunk::Chunk;
use exr::meta::MetaData;
use exr::meta::attribute::SampleType;
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::formats::exr::{Channel, parse_channel};

use super::layout::{Cell, Layout};

/// Chunks read and decoded per thread between two folds of a pass: enough to keep every
/// thread busy, few enough that a pass holds only a handful of chunks' results.
const CHUNKS_PER_THREAD: usize = 4;

/// Reads `buffer.len()` bytes of `file` (opened from `path`) at `offset`, from any thread.
fn read_at(
    #[allow(unused_variables)] path: &Path,
    file: &File,
    buffer: &mut [u8],
    offset: u64,
) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileExt;
        file.read_exact_at(buffer, offset)
    }
    #[cfg(not(unix))]
    {
        // A handle of its own: a cloned handle would share the file position.
        use std::io::{Read, Seek, SeekFrom};
        let _ = file;
        let mut file = File::open(path)?;
        file.seek(SeekFrom::Start(offset))?;
        file.read_exact(buffer)
    }
}

/// A block of pixels: a scanline block or a tile of the image.
#[derive(Debug, Clone, PartialEq)]
pub struct PixelBlock {
    /// Column of the block's first pixel.
    pub x: usize,
    /// Row of the block's first pixel.
    pub y: usize,
    /// Pixels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Cells per pixel (the layout's length).
    pub cells: usize,
    /// Values, pixel-major (row by row, then column), each pixel's cells in the layout's
    /// canonical order. Non-finite values are kept as read.
    pub values: Vec<f32>,
}

impl PixelBlock {
    /// The cells of pixel `index` (row-major within the block).
    pub fn pixel(&self, index: usize) -> &[f32] {
        &self.values[index * self.cells..(index + 1) * self.cells]
    }

    /// Number of pixels.
    pub fn pixel_count(&self) -> usize {
        self.width * self.height
    }

    /// Image pixel index (row-major over the whole image of `image_width`) of block pixel
    /// `index`.
    pub fn image_index(&self, index: usize, image_width: usize) -> usize {
        (self.y + index / self.width) * image_width + self.x + index % self.width
    }
}

/// A block of pixels stored plane by plane: `planes[c·n + q]` is cell c of block pixel
/// q (row-major within the block, n pixels). The passes' matrix products read it as a
/// pixels × cells column-major matrix without a copy.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanarBlock {
    /// Column of the block's first pixel.
    pub x: usize,
    /// Row of the block's first pixel.
    pub y: usize,
    /// Pixels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Cells per pixel.
    pub cells: usize,
    /// The planes, one per cell in canonical order.
    pub planes: Vec<f32>,
}

impl PlanarBlock {
    /// Number of pixels.
    pub fn pixel_count(&self) -> usize {
        self.width * self.height
    }

    /// Cell `c` of every pixel.
    pub fn plane(&self, c: usize) -> &[f32] {
        let n = self.pixel_count();
        &self.planes[c * n..(c + 1) * n]
    }

    /// Image pixel index (row-major over an image of `image_width`) of block pixel `q`.
    pub fn image_index(&self, q: usize, image_width: usize) -> usize {
        (self.y + q / self.width) * image_width + self.x + q % self.width
    }
}

/// Where a pass finds one of an image's blocks: the chunk's file offset and the pixels
/// it holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChunkPlace {
    /// Byte offset of the chunk in the file.
    pub offset: u64,
    /// Column of the block's first pixel.
    pub x: usize,
    /// Row of the block's first pixel.
    pub y: usize,
    /// Pixels per row of the block.
    pub width: usize,
    /// Rows of the block.
    pub height: usize,
}

/// The blocks of an image's passes, in pass order, with the file's metadata to decode
/// them ([`ExrImage::chunk_index`]).
#[derive(Debug, Clone)]
pub struct ChunkIndex {
    meta: MetaData,
    /// Each block's place, in pass order.
    pub places: Vec<ChunkPlace>,
}

/// A bispectral EXR image opened for streaming.
#[derive(Debug, Clone)]
pub struct ExrImage {
    /// The file.
    pub path: PathBuf,
    /// Pixels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// The cells its channels hold.
    pub layout: Layout,
    /// The part (layer) read.
    layer: usize,
    /// Per channel of that part (in the file's order): its cell's canonical index, or
    /// None for channels outside the layout (R, G, B, emissive).
    channel_cells: Vec<Option<usize>>,
    /// Per channel: bytes per sample.
    channel_bytes: Vec<usize>,
    /// Per channel: sample type.
    channel_types: Vec<SampleType>,
    /// Full-resolution chunks of the part.
    chunks: usize,
    /// Whether the part holds any 16-bit float channel.
    pub half: bool,
    /// Notes for the report (ignored channels).
    pub notes: Vec<String>,
}

impl ExrImage {
    /// Opens `path` and reads its header: the channels must follow the bispectral layout.
    pub fn open(path: &Path) -> Result<ExrImage> {
        let fail = |message: String| Error::parse(path, 0, 0, message);
        if path.is_dir() {
            return Err(Error::invalid(
                path.display().to_string(),
                "is a folder; give a bispectral OpenEXR file",
            ));
        }
        let file = File::open(path).map_err(|e| Error::io(path, e))?;
        let meta = MetaData::read_from_buffered(BufReader::new(file), false).map_err(|e| {
            // Name the compression when the exr crate refused a newer one.
            match File::open(path) {
                Ok(file) => fail(crate::formats::exr::unreadable(e, file)),
                Err(_) => fail(format!("not a readable OpenEXR file: {e}")),
            }
        })?;
        let mut chosen = None;
        for (index, header) in meta.headers.iter().enumerate() {
            if header.deep {
                continue;
            }
            let reflective = header.channels.list.iter().any(|c| {
                matches!(
                    parse_channel(&c.name.to_string()),
                    Some(Channel::Diagonal(_) | Channel::Reradiation(..))
                )
            });
            if reflective {
                chosen = Some(index);
                break;
            }
        }
        let Some(layer) = chosen else {
            return Err(fail(
                "no reflective spectral channel (T.<λ>nm or T.<λi>nm.<λo>nm): this is not a bispectral image (channels must follow the spectral OpenEXR layout of Fichet, Mercier and Wilkie); write one with `fluorite synth --image` or the spectral-exr tools".into(),
            ));
        };
        let header = &meta.headers[layer];
        if let Some(why) = crate::formats::exr::compression_not_decoded_in(header) {
            return Err(fail(format!("not a readable OpenEXR file: {why}")));
        }
        let mut grid = Vec::new();
        let mut named = Vec::new();
        let mut notes = Vec::new();
        let mut ignored = Vec::new();
        for c in &header.channels.list {
            let name = c.name.to_string();
            if c.sampling.x() != 1 || c.sampling.y() != 1 {
                return Err(fail(format!(
                    "channel {name} is subsampled ({}×{}); bispectral images hold every channel at every pixel",
                    c.sampling.x(),
                    c.sampling.y()
                )));
            }
            match parse_channel(&name) {
                Some(Channel::Diagonal(l)) => {
                    grid.push(l);
                    named.push(Some((l, l)));
                }
                Some(Channel::Reradiation(i, o)) => {
                    if o <= i {
                        return Err(fail(format!(
                            "channel {name}: the layout's reradiation channels go from a shorter to a longer wavelength (λo > λi), here {i} nm → {o} nm"
                        )));
                    }
                    grid.extend([i, o]);
                    named.push(Some((i, o)));
                }
                _ => {
                    ignored.push(name);
                    named.push(None);
                }
            }
        }
        if !ignored.is_empty() {
            notes.push(format!(
                "{} channel(s) outside the bispectral layout ignored: {}",
                ignored.len(),
                ignored
                    .iter()
                    .take(6)
                    .cloned()
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
        grid.sort_by(f64::total_cmp);
        grid.dedup_by(|a, b| (*a - *b).abs() <= 1e-6);
        for &nm in [grid.first(), grid.last()].into_iter().flatten() {
            crate::limits::check_wavelength(nm)
                .map_err(|message| fail(format!("a channel names the wavelength {message}")))?;
        }
        let index = |nm: f64| crate::spectrum::find_wavelength(&grid, nm).unwrap_or(0);
        let cells: Vec<Option<Cell>> = named
            .iter()
            .map(|n| {
                n.map(|(i, o)| {
                    if i == o {
                        Cell::Diagonal(index(i))
                    } else {
                        Cell::Reradiation(index(i), index(o))
                    }
                })
            })
            .collect();
        let mut listed: Vec<Cell> = cells.iter().flatten().copied().collect();
        listed.sort();
        if let Some(w) = listed.windows(2).find(|w| w[0] == w[1]) {
            let (i, o) = match w[0] {
                Cell::Diagonal(i) => (i, i),
                Cell::Reradiation(i, o) => (i, o),
            };
            return Err(fail(format!(
                "two channels name the cell {} nm → {} nm (e.g. `500nm` and `500,0nm`); keep one",
                grid[i], grid[o]
            )));
        }
        if !listed.iter().any(|c| matches!(c, Cell::Diagonal(_))) {
            return Err(fail(
                "reradiation channels (T.<λi>nm.<λo>nm) only, no diagonal (T.<λ>nm): a material map needs each pixel's reflectance, which only the diagonal measures; include the diagonal channels".into(),
            ));
        }
        let layout = Layout::new(grid, listed).map_err(|e| fail(e.to_string()))?;
        let channel_cells = cells
            .iter()
            .map(|c| c.and_then(|c| layout.position(c)))
            .collect();
        let channel_types: Vec<SampleType> =
            header.channels.list.iter().map(|c| c.sample_type).collect();
        let channel_bytes = channel_types
            .iter()
            .map(|t| match t {
                SampleType::F16 => 2,
                SampleType::F32 | SampleType::U32 => 4,
            })
            .collect();
        let half = channel_types.contains(&SampleType::F16);
        let width = header.layer_size.x();
        let height = header.layer_size.y();
        if width * height < 2 {
            return Err(fail(format!(
                "the image has {} pixel(s): an image fit shares its fluorophores across pixels; fit a single matrix with `fluorite fit {}`",
                width * height,
                path.display()
            )));
        }
        let chunks = header
            .enumerate_ordered_blocks()
            .filter(|(_, tile)| tile.location.level_index == exr::math::Vec2(0, 0))
            .count();
        Ok(ExrImage {
            path: path.to_path_buf(),
            width,
            height,
            layout,
            layer,
            channel_cells,
            channel_bytes,
            channel_types,
            chunks,
            half,
            notes,
        })
    }

    /// Number of pixels.
    pub fn pixels(&self) -> usize {
        self.width * self.height
    }

    /// Number of full-resolution chunks (blocks) a pass reads.
    pub fn blocks(&self) -> usize {
        self.chunks
    }

    /// One pass over the image: `map` runs on every block (in parallel, a few chunks at
    /// a time), and `fold` receives the results in the file's chunk order. `progress` is
    /// called with the number of blocks done after each group.
    pub fn pass<T: Send>(
        &self,
        map: impl Fn(&PixelBlock) -> Result<T> + Sync,
        fold: impl FnMut(T) -> Result<()>,
        progress: impl FnMut(usize),
    ) -> Result<()> {
        self.run_pass(
            |block| {
                let pixels = self.convert(block)?;
                map(&pixels)
            },
            fold,
            progress,
        )
    }

    /// [`ExrImage::pass`] over blocks stored plane by plane (the passes' layout).
    pub fn pass_planar<T: Send>(
        &self,
        map: impl Fn(PlanarBlock) -> Result<T> + Sync,
        fold: impl FnMut(T) -> Result<()>,
        progress: impl FnMut(usize),
    ) -> Result<()> {
        self.run_pass(|block| map(self.convert_planar(block)?), fold, progress)
    }

    /// Where the part's full-resolution chunks lie, in the order a pass reads them
    /// (increasing file offset): the chunk at position `i` is block `i` of every pass.
    pub fn chunk_index(&self) -> Result<ChunkIndex> {
        use std::io::Read;
        let fail = |message: String| Error::parse(&self.path, 0, 0, message);
        let file = File::open(&self.path).map_err(|e| Error::io(&self.path, e))?;
        // The metadata reader consumes the headers exactly (it peeks no byte past them):
        // the offset tables follow, one per header, a u64 per chunk.
        let mut reader = BufReader::new(file);
        let meta = MetaData::read_from_buffered(&mut reader, false)
            .map_err(|e| fail(format!("not a readable OpenEXR file: {e}")))?;
        let mut offsets = Vec::with_capacity(self.chunks);
        for (index, header) in meta.headers.iter().enumerate() {
            let mut table = vec![0u8; 8 * header.chunk_count];
            reader.read_exact(&mut table).map_err(|e| {
                fail(format!(
                    "cannot read the chunk offsets ({e}): the file is truncated or damaged"
                ))
            })?;
            if index != self.layer {
                continue;
            }
            for (tile, bytes) in header
                .blocks_increasing_y_order()
                .zip(table.chunks_exact(8))
            {
                if tile.location.level_index != exr::math::Vec2(0, 0) {
                    continue;
                }
                let bounds = header
                    .get_absolute_block_pixel_coordinates(tile.location)
                    .map_err(|e| fail(format!("a chunk lies outside the image ({e})")))?;
                let (x, y) = (bounds.position.x(), bounds.position.y());
                offsets.push(ChunkPlace {
                    offset: u64::from_le_bytes(bytes.try_into().expect("8 bytes")),
                    x: usize::try_from(x).unwrap_or(0),
                    y: usize::try_from(y).unwrap_or(0),
                    width: bounds.size.x(),
                    height: bounds.size.y(),
                });
            }
        }
        offsets.sort_unstable_by_key(|p| p.offset);
        if offsets.len() != self.chunks {
            return Err(fail(format!(
                "{} chunk offsets for {} chunks: the file is damaged",
                offsets.len(),
                self.chunks
            )));
        }
        Ok(ChunkIndex {
            meta,
            places: offsets,
        })
    }

    /// Blocks `range` of a pass (positions in [`ExrImage::chunk_index`]'s order), one
    /// after the other on this thread: `map` runs on each, `fold` receives the results
    /// in order. The blocks are the ones a whole pass hands its `map` at those
    /// positions, so a pass split into ranges (processes of a cluster) and summed in
    /// block order gives the whole pass's result.
    pub fn pass_planar_range<T>(
        &self,
        range: std::ops::Range<usize>,
        index: &ChunkIndex,
        mut map: impl FnMut(PlanarBlock) -> Result<T>,
        mut fold: impl FnMut(T) -> Result<()>,
    ) -> Result<()> {
        use std::io::{Seek, SeekFrom};
        let (meta, offsets) = (&index.meta, &index.places);
        if range.start > range.end || range.end > offsets.len() {
            return Err(Error::invalid(
                "blocks",
                format!(
                    "{}..{} is outside the image's {} blocks",
                    range.start,
                    range.end,
                    offsets.len()
                ),
            ));
        }
        let fail = |message: String| Error::parse(&self.path, 0, 0, message);
        let file = File::open(&self.path).map_err(|e| Error::io(&self.path, e))?;
        let mut reader = BufReader::with_capacity(1 << 20, file);
        for position in range {
            crate::files::check_interrupted(&self.path)?;
            let damaged = |e: exr::error::Error| {
                fail(format!(
                    "chunk {} of {} cannot be read ({e}): the file is truncated or damaged",
                    position + 1,
                    self.chunks
                ))
            };
            reader
                .seek(SeekFrom::Start(offsets[position].offset))
                .map_err(|e| Error::io(&self.path, e))?;
            let chunk = Chunk::read(&mut reader, meta).map_err(damaged)?;
            let block = UncompressedBlock::decompress_chunk(chunk, meta, false).map_err(damaged)?;
            fold(map(self.convert_planar(&block)?)?)?;
        }
        Ok(())
    }

    fn run_pass<T: Send>(
        &self,
        map: impl Fn(&UncompressedBlock) -> Result<T> + Sync,
        mut fold: impl FnMut(T) -> Result<()>,
        mut progress: impl FnMut(usize),
    ) -> Result<()> {
        let index = self.chunk_index()?;
        let file = File::open(&self.path).map_err(|e| Error::io(&self.path, e))?;
        let length = file.metadata().map_err(|e| Error::io(&self.path, e))?.len();
        let total = index.places.len();
        let raw = self.raw_chunks(&index.meta);
        // Every thread reads its own chunks (copying from the page cache in parallel),
        // decompresses and maps them; the results are folded in file order, a group at a
        // time, so a pass holds a few chunks and its result does not depend on the number
        // of threads.
        let group = CHUNKS_PER_THREAD * rayon::current_num_threads().max(1);
        let mut done = 0;
        while done < total {
            crate::files::check_interrupted(&self.path)?;
            let end = (done + group).min(total);
            let results: Vec<Result<T>> = (done..end)
                .into_par_iter()
                .map_init(Vec::new, |buffer: &mut Vec<u8>, position| {
                    let block = self.read_block(&file, length, &index, position, raw, buffer)?;
                    let result = map(&block);
                    // The block's bytes are the next block's buffer.
                    *buffer = block.data;
                    result
                })
                .collect();
            for r in results {
                fold(r?)?;
            }
            done = end;
            progress(done);
        }
        Ok(())
    }

    /// The length of an uncompressed chunk's own fields before its pixels, when the
    /// image's chunks are uncompressed and the machine little-endian (the file's order):
    /// then a block's pixels are read straight into its buffer, not through the exr
    /// crate's chunk reader and decompressor (each a copy of the block).
    fn raw_chunks(&self, meta: &MetaData) -> Option<usize> {
        let header = &meta.headers[self.layer];
        let uncompressed = header.compression == exr::compression::Compression::Uncompressed;
        if !uncompressed || header.deep || cfg!(target_endian = "big") {
            return None;
        }
        let part = if meta.requirements.is_multilayer() {
            4
        } else {
            0
        };
        let fields = match header.blocks {
            exr::meta::BlockDescription::Tiles(_) => 5 * 4,
            exr::meta::BlockDescription::ScanLines => 2 * 4,
        };
        Some(part + fields)
    }

    /// Block `position` of a pass (in [`ExrImage::chunk_index`]'s order), decompressed;
    /// `buffer` is spare memory it may use.
    fn read_block(
        &self,
        file: &File,
        length: u64,
        index: &ChunkIndex,
        position: usize,
        raw: Option<usize>,
        buffer: &mut Vec<u8>,
    ) -> Result<UncompressedBlock> {
        let fail = |message: String| Error::parse(&self.path, 0, 0, message);
        let (meta, places) = (&index.meta, &index.places);
        let total = places.len();
        let place = places[position];
        let begin = place.offset;
        let truncated = || {
            fail(format!(
                "chunk {} of {total} at byte {begin} is cut short by the end of the file's {length} bytes: the file is truncated or damaged",
                position + 1
            ))
        };
        if let Some(fields) = raw {
            // The chunk's fields must name the block the offset table places there (its
            // part, its tile or first row, its size); a chunk that does not goes through
            // the exr crate's reader below, which judges it.
            let mut head = vec![0u8; fields];
            if begin + fields as u64 > length {
                return Err(truncated());
            }
            read_at(&self.path, file, &mut head, begin).map_err(|e| Error::io(&self.path, e))?;
            let values: Vec<i32> = head
                .chunks_exact(4)
                .map(|b| i32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .collect();
            let bytes_per_line: usize = self.channel_bytes.iter().map(|b| b * place.width).sum();
            let size = bytes_per_line * place.height;
            let header = &meta.headers[self.layer];
            let part = meta.requirements.is_multilayer();
            let at = |i: usize| values[i + usize::from(part)] as i64;
            let matches = (!part || values[0] as i64 == self.layer as i64)
                && match header.blocks {
                    exr::meta::BlockDescription::Tiles(t) => {
                        at(0) * t.tile_size.x() as i64 == place.x as i64
                            && at(1) * t.tile_size.y() as i64 == place.y as i64
                            && at(2) == 0
                            && at(3) == 0
                            && at(4) == size as i64
                    }
                    exr::meta::BlockDescription::ScanLines => {
                        at(0) == place.y as i64 + header.own_attributes.layer_position.y() as i64
                            && at(1) == size as i64
                    }
                };
            if matches {
                if begin + (fields + size) as u64 > length {
                    return Err(truncated());
                }
                buffer.resize(size, 0);
                read_at(&self.path, file, buffer, begin + fields as u64)
                    .map_err(|e| Error::io(&self.path, e))?;
                return Ok(UncompressedBlock {
                    index: exr::block::BlockIndex {
                        layer: self.layer,
                        level: exr::math::Vec2(0, 0),
                        pixel_position: exr::math::Vec2(place.x, place.y),
                        pixel_size: exr::math::Vec2(place.width, place.height),
                    },
                    data: std::mem::take(buffer),
                });
            }
        }
        // A chunk is at most its block's bytes and the chunk's own fields (part number,
        // tile coordinates and levels, sizes); anything past that before the next chunk
        // (another part's chunks) is not read.
        let largest = meta.headers[self.layer].max_block_byte_size() as u64 + 64;
        let stop = places
            .get(position + 1)
            .map_or(length, |next| next.offset)
            .min(begin.saturating_add(largest))
            .min(length);
        if begin >= stop {
            return Err(truncated());
        }
        buffer.resize((stop - begin) as usize, 0);
        read_at(&self.path, file, buffer, begin).map_err(|e| Error::io(&self.path, e))?;
        let chunk = Chunk::read(&mut buffer.as_slice(), meta).map_err(|e| {
            fail(format!(
                "chunk {} of {total} cannot be read ({e}): the file is truncated or damaged",
                position + 1
            ))
        })?;
        UncompressedBlock::decompress_chunk(chunk, meta, false).map_err(|e| {
            let why = if matches!(e, exr::error::Error::NotSupported(_)) {
                "the exr crate does not decode this case of its compression"
            } else {
                "the file is truncated or damaged"
            };
            fail(format!(
                "chunk {} of {total} cannot be decompressed ({e}): {why}",
                position + 1,
            ))
        })
    }

    /// A decompressed block's samples, converted to f32 planes in canonical cell order.
    fn convert_planar(&self, block: &UncompressedBlock) -> Result<PlanarBlock> {
        let width = block.index.pixel_size.x();
        let height = block.index.pixel_size.y();
        let cells = self.layout.len();
        let n = width * height;
        let mut planes = vec![0f32; n * cells];
        self.check_block_size(block, width, height)?;
        let data = &block.data;
        let mut offset = 0;
        for row in 0..height {
            for (c, &bytes) in self.channel_bytes.iter().enumerate() {
                let line = &data[offset..offset + bytes * width];
                offset += bytes * width;
                let Some(cell) = self.channel_cells[c] else {
                    continue;
                };
                let out = &mut planes[cell * n + row * width..cell * n + (row + 1) * width];
                match self.channel_types[c] {
                    SampleType::F32 => {
                        for (o, b) in out.iter_mut().zip(line.chunks_exact(4)) {
                            *o = f32::from_ne_bytes([b[0], b[1], b[2], b[3]]);
                        }
                    }
                    SampleType::F16 => {
                        for (o, b) in out.iter_mut().zip(line.chunks_exact(2)) {
                            *o = exr::prelude::f16::from_ne_bytes([b[0], b[1]]).to_f32();
                        }
                    }
                    SampleType::U32 => {
                        for (o, b) in out.iter_mut().zip(line.chunks_exact(4)) {
                            *o = u32::from_ne_bytes([b[0], b[1], b[2], b[3]]) as f32;
                        }
                    }
                }
            }
        }
        Ok(PlanarBlock {
            x: block.index.pixel_position.x(),
            y: block.index.pixel_position.y(),
            width,
            height,
            cells,
            planes,
        })
    }

    /// An error unless the block holds the bytes its pixels need.
    fn check_block_size(
        &self,
        block: &UncompressedBlock,
        width: usize,
        height: usize,
    ) -> Result<()> {
        let bytes_per_line: usize = self.channel_bytes.iter().map(|b| b * width).sum();
        if block.data.len() != bytes_per_line * height {
            return Err(Error::parse(
                &self.path,
                0,
                0,
                format!(
                    "a block at row {} holds {} bytes where its {width}×{height} pixels need {}: the file is damaged",
                    block.index.pixel_position.y(),
                    block.data.len(),
                    bytes_per_line * height
                ),
            ));
        }
        Ok(())
    }

    /// A decompressed block's samples, converted to f32 in canonical cell order.
    fn convert(&self, block: &UncompressedBlock) -> Result<PixelBlock> {
        let width = block.index.pixel_size.x();
        let height = block.index.pixel_size.y();
        let cells = self.layout.len();
        let mut values = vec![0f32; width * height * cells];
        self.check_block_size(block, width, height)?;
        let data = &block.data;
        let mut offset = 0;
        for row in 0..height {
            for (c, &bytes) in self.channel_bytes.iter().enumerate() {
                let line = &data[offset..offset + bytes * width];
                offset += bytes * width;
                let Some(cell) = self.channel_cells[c] else {
                    continue;
                };
                let out = |x: usize| (row * width + x) * cells + cell;
                match self.channel_types[c] {
                    SampleType::F32 => {
                        for (x, b) in line.chunks_exact(4).enumerate() {
                            values[out(x)] = f32::from_ne_bytes([b[0], b[1], b[2], b[3]]);
                        }
                    }
                    SampleType::F16 => {
                        for (x, b) in line.chunks_exact(2).enumerate() {
                            values[out(x)] =
                                exr::prelude::f16::from_ne_bytes([b[0], b[1]]).to_f32();
                        }
                    }
                    SampleType::U32 => {
                        for (x, b) in line.chunks_exact(4).enumerate() {
                            values[out(x)] = u32::from_ne_bytes([b[0], b[1], b[2], b[3]]) as f32;
                        }
                    }
                }
            }
        }
        Ok(PixelBlock {
            x: block.index.pixel_position.x(),
            y: block.index.pixel_position.y(),
            width,
            height,
            cells,
            values,
        })
    }
}
