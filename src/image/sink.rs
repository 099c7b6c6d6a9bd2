//! Writing OpenEXR images block by block: the pixels of each tile are asked for when the
//! tile is written, so an image of any size is written with a few tiles in memory. The
//! file is written beside its target and renamed into place when complete.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use exr::block::UncompressedBlock;
use exr::block::writer::ChunksWriter;
use exr::meta::header::Header;
use rayon::prelude::*;

use crate::error::{Error, Result};

use super::tiles::{CHUNK_HEAD, UncompressedLayout, fill_tile_chunk, header_of, tile_bytes};
pub use super::tiles::{ImageSpec, Rect, TILE, TiledFile};

/// Tiles produced and compressed together per thread.
const TILES_PER_THREAD: usize = 1;

/// Writes `path` tile by tile: `produce(rect)` returns the rectangle's pixels, row by row,
/// each pixel's values in `spec.channels`' order. Tiles are produced in parallel, a few at
/// a time, and written in order; `progress` gets the tiles written so far and the total.
pub fn write_image(
    path: &Path,
    spec: &ImageSpec,
    produce: impl Fn(Rect) -> Result<Vec<f32>> + Sync,
    mut progress: impl FnMut(usize, usize),
) -> Result<()> {
    let (header, order) = header_of(path, spec)?;
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

fn write_tiles(
    tmp: &Path,
    header: Header,
    spec: &ImageSpec,
    order: &[usize],
    produce: &(impl Fn(Rect) -> Result<Vec<f32>> + Sync),
    progress: &mut impl FnMut(usize, usize),
) -> Result<()> {
    #[cfg(unix)]
    if !spec.zip {
        return write_uncompressed_tiles(
            tmp,
            header,
            spec,
            order,
            produce,
            progress,
            Direct::Large,
        );
    }
    write_tiles_with_exr(tmp, header, spec, order, produce, progress)
}

/// Makes the results of `blocks` in parallel, a group of `group` at a time, one group
/// ahead of `consume`, which gets each group's results in order on this thread: copying a
/// group into a file is one thread's work that would otherwise leave the others idle.
fn produce_ahead<B: Sync, T: Send>(
    tmp: &Path,
    blocks: &[B],
    group: usize,
    make: impl Fn(&B) -> Result<T> + Sync,
    mut consume: impl FnMut(Vec<T>) -> Result<()>,
) -> Result<()> {
    let (sender, receiver) = std::sync::mpsc::sync_channel::<Result<Vec<T>>>(1);
    let make = &make;
    std::thread::scope(|scope| {
        // The producer owns the sender: the loop below ends when it does.
        scope.spawn(move || {
            for group_blocks in blocks.chunks(group.max(1)) {
                let results = crate::files::check_interrupted(tmp)
                    .and_then(|()| group_blocks.par_iter().map(make).collect());
                let failed = results.is_err();
                // The receiver is gone when consuming failed.
                if sender.send(results).is_err() || failed {
                    return;
                }
            }
        });
        // Owned here, the receiver goes when this closure returns, early on an error, so
        // that a producer waiting to send ends instead of waiting for ever.
        let receiver = receiver;
        for results in receiver.iter() {
            consume(results?)?;
        }
        Ok(())
    })
}

/// [`write_tiles`] through the exr crate's writer (compressed images).
fn write_tiles_with_exr(
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
            let mut written = 0;
            produce_ahead(
                tmp,
                &blocks,
                group,
                |&(index, block)| {
                    let rect = Rect::of_block(&block);
                    let data = tile_bytes(&produce(rect)?, rect, spec, order)?;
                    let chunk = UncompressedBlock { index: block, data }
                        .compress_to_chunk(&meta.headers)
                        .map_err(encode_failure)?;
                    Ok((index, chunk))
                },
                |chunks| {
                    written += chunks.len();
                    for (index, chunk) in chunks {
                        writer.write_chunk(index, chunk).map_err(encode_failure)?;
                    }
                    progress(written, total);
                    Ok(())
                },
            )
            .map_err(|e| {
                failure = Some(e);
                exr::error::Error::Aborted
            })
        },
    )
    .map_err(|e| failure.take().unwrap_or_else(|| encode_failure(e)))?;
    if let Some(e) = failure {
        return Err(e);
    }
    Ok(())
}

/// When an uncompressed image is written with O_DIRECT.
#[cfg(unix)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Direct {
    /// From 64 MB up (Linux; a smaller image goes through the exr crate's writer).
    Large,
    /// Whatever its size (Linux; tests).
    #[cfg_attr(not(test), allow(dead_code))]
    Always,
    /// Never: through a map.
    #[cfg_attr(not(test), allow(dead_code))]
    Never,
}

/// [`write_tiles`] for an uncompressed image, whose every chunk's size, and so its place
/// in the file, is known before any pixel is produced. By default an image under 64 MB
/// goes through the exr crate's writer (the page cache takes it cheaply). With `direct`
/// (Linux, on a file system that takes O_DIRECT) the bytes are streamed past the
/// page cache ([`write_direct`]); otherwise each thread writes the tiles it produces straight into
/// their places in the mapped file, which shares the copying between the threads without
/// the file lock that serialises `write` calls (measured: threads writing with `pwrite`
/// spend their time waiting for each other). Either way the bytes are those the exr
/// crate's writer writes (headers, the offset table, the chunks in increasing-y order);
/// a mapped file's blocks are reserved first, so a full disk is an error, not a fault
/// while writing through the map.
#[cfg(unix)]
#[allow(clippy::too_many_arguments)]
fn write_uncompressed_tiles(
    tmp: &Path,
    header: Header,
    spec: &ImageSpec,
    order: &[usize],
    produce: &(impl Fn(Rect) -> Result<Vec<f32>> + Sync),
    progress: &mut impl FnMut(usize, usize),
    direct: Direct,
) -> Result<()> {
    let io = |e: std::io::Error| Error::io(tmp, e);
    let UncompressedLayout {
        headers,
        head,
        blocks,
        offsets,
        length: next,
    } = UncompressedLayout::of(tmp, header, spec)?;
    let total = blocks.len();
    let data_size = |b: &exr::block::BlockIndex| spec.chunk_data_bytes(b);
    if direct == Direct::Large && next < DIRECT_MIN_BYTES {
        // Small: the page cache takes it cheaply (measured: the 64² criterion bench
        // 0.20 s through per-tile maps, 0.16 s through the exr crate's buffered writer).
        let [header] = headers;
        return write_tiles_with_exr(tmp, header, spec, order, produce, progress);
    }
    #[cfg(target_os = "linux")]
    if direct != Direct::Never {
        use std::os::unix::fs::OpenOptionsExt;
        // Not every file system takes O_DIRECT (tmpfs does not): then the map below.
        if let Ok(file) = std::fs::OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(true)
            .custom_flags(libc::O_DIRECT)
            .open(tmp)
        {
            return write_direct(
                tmp, file, &head, &blocks, next, spec, order, produce, progress,
            );
        }
    }
    let file = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(true)
        .open(tmp)
        .map_err(io)?;
    reserve(&file, next).map_err(io)?;
    use std::os::unix::fs::FileExt;
    file.write_all_at(&head, 0).map_err(io)?;
    // Each tile maps only its own chunk: the pages mapped are those of the tiles being
    // written, so the memory held does not grow with the image.
    let page = page_size();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let (sender, receiver) = std::sync::mpsc::channel::<usize>();
    std::thread::scope(|scope| -> Result<()> {
        // The tiles are written by rayon's threads; this thread reports progress. The
        // channel is unbounded: a rayon thread never waits on it.
        let work = scope.spawn(move || {
            blocks.par_iter().try_for_each(|(index, block)| {
                crate::files::check_interrupted(tmp)?;
                let rect = Rect::of_block(block);
                let values = produce(rect)?;
                let offset = offsets[*index];
                let start = offset - offset % page;
                let skip = (offset - start) as usize;
                // SAFETY: the staging file is this process's own (a name with its
                // pid, made above), its length reserved and fixed while mapped; no
                // other map of it is written at these bytes.
                let mut map = unsafe {
                    memmap2::MmapOptions::new()
                        .offset(start)
                        .len(skip + CHUNK_HEAD + data_size(block))
                        .map_mut(&file)
                }
                .map_err(io)?;
                fill_tile_chunk(&values, rect, spec, order, &mut map[skip..])?;
                let _ = sender.send(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
                Ok(())
            })
        });
        for written in receiver.iter() {
            progress(written.min(total), total);
        }
        work.join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
    })?;
    Ok(())
}

/// Alignment of the memory, file offsets and lengths of an O_DIRECT write: the largest
/// logical block size of common devices.
#[cfg(target_os = "linux")]
const DIRECT_ALIGN: usize = 4096;

/// The smallest image written past the page cache: a smaller one fits it cheaply, and
/// through it the writer does not wait for the disk.
#[cfg(unix)]
const DIRECT_MIN_BYTES: u64 = 64 << 20;

/// Bytes gathered before each O_DIRECT write.
#[cfg(target_os = "linux")]
const DIRECT_BUFFER: usize = 8 << 20;

/// Writes an uncompressed image through `file`, opened with O_DIRECT: the tiles are
/// produced in parallel, a group at a time, and this thread streams their bytes to the
/// disk past the page cache. Writing an image as large as its input through the page
/// cache costs the CPU time of filling a fresh page per 4 KB (here about 1 s per GB on
/// one thread and twice that per thread when two threads write, measured with `perf`),
/// time the threads producing tiles lose; written directly, the disk's controller copies
/// it while the threads go on, and the file does not push the input out of the cache.
#[cfg(target_os = "linux")]
#[allow(clippy::too_many_arguments)]
fn write_direct(
    tmp: &Path,
    file: File,
    head: &[u8],
    blocks: &[(usize, exr::block::BlockIndex)],
    length: u64,
    spec: &ImageSpec,
    order: &[usize],
    produce: &(impl Fn(Rect) -> Result<Vec<f32>> + Sync),
    progress: &mut impl FnMut(usize, usize),
) -> Result<()> {
    use std::os::unix::fs::FileExt;
    let io = |e: std::io::Error| Error::io(tmp, e);
    let total = blocks.len();
    let data_size = |b: &exr::block::BlockIndex| spec.chunk_data_bytes(b);
    let group = TILES_PER_THREAD * rayon::current_num_threads().max(1);
    // An aligned buffer: O_DIRECT reads the memory it writes in whole blocks.
    let mut memory = vec![0u8; DIRECT_BUFFER + DIRECT_ALIGN];
    let skip = memory.as_ptr().align_offset(DIRECT_ALIGN);
    let buffer = &mut memory[skip..skip + DIRECT_BUFFER];
    let mut filled = 0;
    let mut position = 0u64;
    // Appends bytes to the stream, writing every full buffer.
    let mut push = |mut bytes: &[u8], filled: &mut usize, position: &mut u64| -> Result<()> {
        while !bytes.is_empty() {
            let n = bytes.len().min(DIRECT_BUFFER - *filled);
            buffer[*filled..*filled + n].copy_from_slice(&bytes[..n]);
            *filled += n;
            bytes = &bytes[n..];
            if *filled == DIRECT_BUFFER {
                file.write_all_at(buffer, *position).map_err(io)?;
                *position += DIRECT_BUFFER as u64;
                *filled = 0;
            }
        }
        Ok(())
    };
    push(head, &mut filled, &mut position)?;
    let mut written = 0;
    produce_ahead(
        tmp,
        blocks,
        group,
        |(_, block)| {
            let rect = Rect::of_block(block);
            let values = produce(rect)?;
            let mut bytes = vec![0u8; CHUNK_HEAD + data_size(block)];
            fill_tile_chunk(&values, rect, spec, order, &mut bytes)?;
            Ok(bytes)
        },
        |chunks| {
            for bytes in chunks {
                push(&bytes, &mut filled, &mut position)?;
                written += 1;
            }
            progress(written, total);
            Ok(())
        },
    )?;
    if written_all(position + filled as u64, length, tmp)? && filled > 0 {
        // The last, partial block is written whole and the file cut to its length.
        let whole = filled.div_ceil(DIRECT_ALIGN) * DIRECT_ALIGN;
        buffer[filled..whole].fill(0);
        file.write_all_at(&buffer[..whole], position).map_err(io)?;
    }
    file.set_len(length).map_err(io)?;
    Ok(())
}

/// Whether a stream that ends at `end` wrote the `length` bytes planned.
#[cfg(target_os = "linux")]
fn written_all(end: u64, length: u64, tmp: &Path) -> Result<bool> {
    if end == length {
        Ok(true)
    } else {
        Err(Error::invalid(
            tmp.display().to_string(),
            format!("{end} bytes written where {length} were planned: the writer is broken"),
        ))
    }
}

/// The size of a memory page: where a map may start in a file.
#[cfg(unix)]
fn page_size() -> u64 {
    // SAFETY: a plain query of the system's configuration.
    let size = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
    u64::try_from(size).ok().filter(|&s| s > 0).unwrap_or(4096)
}

/// Gives `file` its `length`, with its blocks allocated (Linux): a write through a map
/// into a block the disk has no room for is a fault, not an error.
#[cfg(unix)]
fn reserve(file: &File, length: u64) -> std::io::Result<()> {
    file.set_len(length)?;
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::io::AsRawFd;
        let length = libc::off_t::try_from(length).map_err(std::io::Error::other)?;
        // SAFETY: a plain system call on a descriptor this function borrows.
        let status = unsafe { libc::posix_fallocate(file.as_raw_fd(), 0, length) };
        if status != 0 {
            return Err(std::io::Error::from_raw_os_error(status));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A spec and its producer: values that name their pixel and channel.
    fn example(half: bool, zip: bool) -> (ImageSpec, impl Fn(Rect) -> Result<Vec<f32>> + Sync) {
        let channels: Vec<String> = (0..300).map(|c| format!("T.{:03}nm", 400 + c)).collect();
        let count = channels.len();
        let spec = ImageSpec {
            width: 150,
            height: 70,
            channels,
            half,
            zip,
            attributes: vec![("note".into(), "test".into())],
        };
        let produce = move |r: Rect| -> Result<Vec<f32>> {
            let mut v = Vec::new();
            for y in r.y..r.y + r.height {
                for x in r.x..r.x + r.width {
                    v.extend((0..count).map(|c| (x * 7 + y * 13 + c) as f32 / 64.0));
                }
            }
            Ok(v)
        };
        (spec, produce)
    }

    fn written(dir: &Path, name: &str, spec: &ImageSpec, how: &str) -> Vec<u8> {
        let (_, produce) = example(spec.half, spec.zip);
        let path = dir.join(name);
        let mut order: Vec<usize> = (0..spec.channels.len()).collect();
        order.sort_by(|&a, &b| spec.channels[a].cmp(&spec.channels[b]));
        // The header write_image would build.
        write_image(&path, spec, &produce, |_, _| {}).unwrap();
        let built = std::fs::read(&path).unwrap();
        if how == "write_image" {
            return built;
        }
        let meta =
            exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(&built), false).unwrap();
        let header = meta.headers[0].clone();
        let mut progress = |_, _| {};
        match how {
            "exr" => write_tiles_with_exr(&path, header, spec, &order, &produce, &mut progress),
            "shared" => {
                // Two writers, each its own tiles, the second first.
                let file = TiledFile::plan(&path, spec).unwrap();
                file.create(&path).unwrap();
                let half = file.tiles() / 2;
                file.write_tiles(&path, half..file.tiles(), &produce)
                    .and_then(|()| file.write_tiles(&path, 0..half, &produce))
            }
            "map" => write_uncompressed_tiles(
                &path,
                header,
                spec,
                &order,
                &produce,
                &mut progress,
                Direct::Never,
            ),
            "direct" => write_uncompressed_tiles(
                &path,
                header,
                spec,
                &order,
                &produce,
                &mut progress,
                Direct::Always,
            ),
            _ => unreachable!(),
        }
        .unwrap();
        std::fs::read(&path).unwrap()
    }

    #[test]
    fn uncompressed_images_hold_the_exr_crates_bytes_and_values() {
        let dir = tempfile::tempdir().unwrap();
        for half in [false, true] {
            let (spec, produce) = example(half, false);
            // 150 × 70 pixels in 64 × 64 tiles: edge tiles of 22 columns and 6 rows; 300
            // channels: over 8 MB, more than one buffer of the direct writer.
            let ours = written(dir.path(), "a.exr", &spec, "write_image");
            let map = written(dir.path(), "b.exr", &spec, "map");
            let direct = written(dir.path(), "d.exr", &spec, "direct");
            let crate_bytes = written(dir.path(), "c.exr", &spec, "exr");
            let shared = written(dir.path(), "s.exr", &spec, "shared");
            assert!(half || ours.len() > 8 << 20, "{}", ours.len());
            assert!(
                ours == crate_bytes,
                "write_image (half {half}) differs from the exr crate's writer"
            );
            assert!(
                direct == crate_bytes,
                "the O_DIRECT writer (half {half}) differs from the exr crate's writer"
            );
            assert!(
                map == crate_bytes,
                "the mapped writer (half {half}) differs from the exr crate's writer"
            );
            assert!(
                shared == crate_bytes,
                "the shared file's writers (half {half}) differ from the exr crate's writer"
            );
            // And the exr crate reads back every value.
            let image =
                exr::prelude::read_all_flat_layers_from_file(dir.path().join("a.exr")).unwrap();
            let layer = &image.layer_data[0];
            let all = produce(Rect {
                x: 0,
                y: 0,
                width: spec.width,
                height: spec.height,
            })
            .unwrap();
            for (k, channel) in layer.channel_data.list.iter().enumerate() {
                let c: usize = channel.name.to_string()[2..5].parse::<usize>().unwrap() - 400;
                let values: Vec<f32> = channel.sample_data.values_as_f32().collect();
                for p in [0, 63, 64, 149, 150 * 64, 150 * 70 - 1] {
                    let expected = all[p * spec.channels.len() + c];
                    let expected = if half {
                        exr::prelude::f16::from_f32(expected).to_f32()
                    } else {
                        expected
                    };
                    assert_eq!(values[p], expected, "channel {k}, pixel {p}");
                }
            }
        }
    }
}
