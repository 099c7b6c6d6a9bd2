//! `fluorite fit-image` when runs are killed and inputs are bad. A run killed with
//! SIGKILL and started again resumes and ends with the files an uninterrupted run writes,
//! byte for byte; a work folder of other options, of another image or with a damaged file
//! starts afresh; bad input is refused with exit code 2 and one line naming the file, and
//! writes nothing; non-finite cells mask their pixels, counted exactly; images of another
//! writer (scanline blocks, half floats, the reference's `T.300,000000nm` names) fit as
//! the tiled float one does. Images come from `fluorite synth --image` or are written
//! here with the `exr` crate's own API; results are judged against an uninterrupted run,
//! a fresh run, or the counts planted here.

use std::collections::BTreeMap;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Image, SmallVec, WritableImage, f16,
};

use crate::common;

use common::repository;

/// `fluorite synth --image --quiet --size SIZE --out DIR ARGS` from the repository's root
/// (where the default materials are); returns `DIR/image.exr`.
fn synth(dir: &Path, size: &str, args: &[&str]) -> PathBuf {
    let out = dir.display().to_string();
    let mut all = vec!["synth", "--image", "--quiet", "--size", size, "--out", &out];
    all.extend_from_slice(args);
    common::succeed(common::fluorite().args(&all).current_dir(repository()));
    dir.join("image.exr")
}

/// `fluorite fit-image IMAGE -o OUT ARGS`.
fn fit_image(image: &Path, out: &Path, args: &[&str]) -> Command {
    let mut command = common::fluorite();
    command
        .arg("fit-image")
        .arg(image)
        .arg("-o")
        .arg(out)
        .args(args);
    command
}

/// Runs a fit to its end; returns what it printed (stdout, then stderr).
fn fit(image: &Path, out: &Path, args: &[&str]) -> String {
    let o = common::succeed(&mut fit_image(image, out, args));
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Every entry of `dir`, hidden ones too: a file's bytes, None for a folder.
fn contents(dir: &Path) -> BTreeMap<String, Option<Vec<u8>>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            let bytes = e
                .file_type()
                .unwrap()
                .is_file()
                .then(|| std::fs::read(e.path()).unwrap());
            (e.file_name().to_string_lossy().into_owned(), bytes)
        })
        .collect()
}

/// The names of the entries of `dir`, hidden ones too, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// `got` holds the files `expected` holds, byte for byte, and nothing else.
#[track_caller]
fn assert_same_files(expected: &Path, got: &Path) {
    let (a, b) = (contents(expected), contents(got));
    assert_eq!(
        a.keys().collect::<Vec<_>>(),
        b.keys().collect::<Vec<_>>(),
        "{} and {} hold different files",
        expected.display(),
        got.display()
    );
    for name in [
        "material-map.json",
        "concentration.exr",
        "reflectance.exr",
        "fitted.exr",
        "delta-e.exr",
        "delta-e-d65.png",
        "under-uv.png",
    ] {
        assert!(a.contains_key(name), "{name} missing: {:?}", a.keys());
    }
    for (name, bytes) in &a {
        assert!(
            bytes == &b[name],
            "{name} differs between {} and {}",
            expected.display(),
            got.display()
        );
    }
}

/// The stages the work folder of `out` records as finished (none before it has a state).
fn done_stages(out: &Path) -> Vec<String> {
    std::fs::read_to_string(out.join(".fluorite-work/state.json"))
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .and_then(|v| {
            v["done"].as_array().map(|a| {
                a.iter()
                    .filter_map(|s| s.as_str().map(String::from))
                    .collect()
            })
        })
        .unwrap_or_default()
}

/// Starts `command` and kills it with SIGKILL as soon as `ready` holds (polled every few
/// milliseconds). Fails if the run ends first, or if `ready` does not hold within ten
/// minutes (a bound on a hung run, not a timing assertion).
#[track_caller]
fn kill_when(command: &mut Command, what: &str, ready: impl Fn() -> bool) {
    let mut child = command
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("the binary runs");
    let deadline = Instant::now() + Duration::from_secs(600);
    loop {
        if ready() {
            child.kill().unwrap();
            let status = child.wait().unwrap();
            assert_eq!(
                status.signal(),
                Some(9),
                "the run ended ({status}) before it could be killed once {what}"
            );
            return;
        }
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the run ended ({status}) before {what}");
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("no {what} within ten minutes");
        }
        std::thread::sleep(Duration::from_millis(3));
    }
}

/// A synthetic image and an uninterrupted run's outputs.
struct Reference {
    dir: common::TempDir,
    image: PathBuf,
    fitted: PathBuf,
}

fn reference(tag: &str, size: &str) -> Reference {
    let dir = common::temp_dir(tag);
    let image = synth(&dir.join("synth"), size, &[]);
    let fitted = dir.join("reference");
    fit(&image, &fitted, &["--quiet"]);
    Reference { dir, image, fitted }
}

/// 96 × 96 pixels (44 MB, three fluorophores): a debug build takes seconds over it.
fn big() -> &'static Reference {
    static BIG: OnceLock<Reference> = OnceLock::new();
    BIG.get_or_init(|| reference("big", "96"))
}

/// 48 × 48 pixels, for the tests that need a run but not a long one.
fn small() -> &'static Reference {
    static SMALL: OnceLock<Reference> = OnceLock::new();
    SMALL.get_or_init(|| reference("small", "48"))
}

/// The number of fluorophores a fit in `out` chose.
fn components(out: &Path) -> u64 {
    let text = std::fs::read_to_string(out.join("material-map.json")).unwrap();
    let map: serde_json::Value = serde_json::from_str(&text).unwrap();
    map["fit"]["components"].as_u64().unwrap()
}

#[test]
fn a_run_killed_after_its_first_passes_resumes_and_ends_with_the_same_files() {
    let r = big();
    let out = r.dir.join("killed-in-passes");
    kill_when(
        &mut fit_image(&r.image, &out, &["--quiet"]),
        "the power step (pass 2) was recorded as finished",
        || done_stages(&out).iter().any(|s| s == "basis-1"),
    );
    assert!(!out.join("material-map.json").exists());
    assert!(!out.join("concentration.exr").exists());
    let report = fit(&r.image, &out, &[]);
    assert!(
        report.contains("resumed") && report.contains("power step 1"),
        "{report}"
    );
    assert_same_files(&r.fitted, &out);
}

#[test]
fn a_run_killed_while_writing_its_outputs_resumes_and_ends_with_the_same_files() {
    let r = big();
    let out = r.dir.join("killed-in-outputs");
    // Killed while an output is half written (its `.fluorite-<process>-NAME` beside the
    // target), or failing that once the first output is in place.
    let writing = || {
        std::fs::read_dir(&out).is_ok_and(|entries| {
            entries.flatten().any(|e| {
                let name = e.file_name().to_string_lossy().into_owned();
                (name.starts_with(".fluorite-") && name.ends_with(".exr"))
                    || name == "concentration.exr"
            })
        })
    };
    kill_when(
        &mut fit_image(&r.image, &out, &["--quiet"]),
        "the outputs were being written",
        writing,
    );
    assert!(
        !out.join("material-map.json").exists(),
        "killed before the material map, the last output"
    );
    // Every K the search needed was kept: the kill came in the output stage.
    let chosen = format!("trial-{}", components(&r.fitted));
    let stages = done_stages(&out);
    assert!(stages.contains(&chosen), "{stages:?}");
    let report = fit(&r.image, &out, &[]);
    assert!(
        report.contains("resumed after: sketch, power step 1, projection, K = 1"),
        "{report}"
    );
    // Same files and nothing else: no half-written file of the killed run is left.
    assert_same_files(&r.fitted, &out);
}

#[test]
fn a_work_folder_of_other_options_starts_afresh() {
    let s = small();
    let dir = common::temp_dir("other-options");
    let out = dir.join("out");
    kill_when(
        &mut fit_image(&s.image, &out, &["--quiet"]),
        "the projection (pass 3) was recorded as finished",
        || done_stages(&out).iter().any(|s| s == "projection"),
    );
    let report = fit(&s.image, &out, &["--rank", "16"]);
    assert!(!report.contains("resumed"), "{report}");
    let fresh = dir.join("fresh");
    fit(&s.image, &fresh, &["--rank", "16", "--quiet"]);
    assert_same_files(&fresh, &out);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_work_folder_of_another_image_at_the_same_path_starts_afresh() {
    let s = small();
    let dir = common::temp_dir("other-image");
    let image = dir.join("image.exr");
    std::fs::copy(&s.image, &image).unwrap();
    let other = synth(&dir.join("other"), "48", &["--seed", "2"]);
    let (first, second) = (
        std::fs::read(&image).unwrap(),
        std::fs::read(&other).unwrap(),
    );
    assert_eq!(first.len(), second.len(), "the same size");
    assert_ne!(first, second, "other pixels");
    let out = dir.join("out");
    kill_when(
        &mut fit_image(&image, &out, &["--quiet"]),
        "the projection (pass 3) was recorded as finished",
        || done_stages(&out).iter().any(|s| s == "projection"),
    );
    std::fs::write(&image, &second).unwrap();
    let report = fit(&image, &out, &[]);
    assert!(!report.contains("resumed"), "{report}");
    // What a run of the second image that never met the first one's work folder writes
    // (a resumed run would have fitted the first image's projection).
    let fresh = dir.join("fresh");
    fit(&image, &fresh, &["--quiet"]);
    assert_same_files(&fresh, &out);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_work_folder_with_a_damaged_scratch_file_starts_afresh() {
    let s = small();
    let out = s.dir.join("damaged");
    kill_when(
        &mut fit_image(&s.image, &out, &["--quiet"]),
        "the projection (pass 3) was recorded as finished",
        || done_stages(&out).iter().any(|s| s == "projection"),
    );
    let scratch = out.join(".fluorite-work/scratch.f32");
    let file = std::fs::OpenOptions::new()
        .write(true)
        .open(&scratch)
        .unwrap();
    let len = file.metadata().unwrap().len();
    file.set_len(len / 2).unwrap();
    drop(file);
    let report = fit(&s.image, &out, &[]);
    assert!(!report.contains("resumed"), "{report}");
    assert_same_files(&s.fitted, &out);
}

/// Named channels, each's samples row-major.
type Channels = Vec<(String, Vec<f32>)>;

/// The channels of an EXR's first part, read with the `exr` crate: its size and each
/// channel's name and samples (row-major), in the file's order.
fn read_channels(path: &Path) -> ((usize, usize), Channels) {
    let image = exr::prelude::read_first_flat_layer_from_file(path).unwrap();
    let size = image.layer_data.size;
    let channels = image
        .layer_data
        .channel_data
        .list
        .iter()
        .map(|c| {
            (
                c.name.to_string(),
                c.sample_data.values_as_f32().collect::<Vec<f32>>(),
            )
        })
        .collect();
    ((size.x(), size.y()), channels)
}

/// Writes channels with the `exr` crate's own API, as 32- or 16-bit floats.
fn write_channels(
    path: &Path,
    size: (usize, usize),
    channels: &[(String, Vec<f32>)],
    half: bool,
    encoding: Encoding,
) {
    let list: SmallVec<[AnyChannel<FlatSamples>; 4]> = channels
        .iter()
        .map(|(name, values)| {
            let samples = if half {
                FlatSamples::F16(values.iter().map(|&v| f16::from_f32(v)).collect())
            } else {
                FlatSamples::F32(values.clone())
            };
            AnyChannel::new(name.as_str(), samples)
        })
        .collect();
    Image::from_encoded_channels(size, encoding, AnyChannels::sort(list))
        .write()
        .to_file(path)
        .unwrap();
}

/// A small image of `(name, value)` channels, every pixel alike.
fn write_uniform(path: &Path, size: (usize, usize), channels: &[(&str, f32)]) {
    let channels: Channels = channels
        .iter()
        .map(|&(n, v)| (n.to_string(), vec![v; size.0 * size.1]))
        .collect();
    write_channels(path, size, &channels, false, Encoding::UNCOMPRESSED);
}

/// A channel name in the reference writer's form: `T.300nm.380nm` →
/// `T.300,000000nm.380,000000nm`.
fn reference_name(name: &str) -> String {
    let rest = name.strip_prefix("T.").unwrap();
    let parts: Vec<String> = rest
        .split('.')
        .map(|part| {
            let nm: f64 = part.strip_suffix("nm").unwrap().parse().unwrap();
            format!("{nm:.6}nm").replace('.', ",")
        })
        .collect();
    format!("T.{}", parts.join("."))
}

/// Runs fit-image on `image` into a folder that does not exist: it must be refused with
/// exit code 2 and one line naming the file, and leave nothing behind (no output or work
/// folder, nothing beside the image). Returns the message.
#[track_caller]
fn refused_writing_nothing(image: &Path) -> String {
    let parent = image.parent().unwrap();
    let before = names(parent);
    let out = parent.join(format!(
        "{}.fit",
        image.file_name().unwrap().to_string_lossy()
    ));
    let (code, message) = common::refused(&mut fit_image(image, &out, &[]));
    assert_eq!(code, Some(2), "{message}");
    assert!(
        message.contains(&image.display().to_string()),
        "the message names {}: {message}",
        image.display()
    );
    assert!(!out.exists(), "{} was left behind", out.display());
    assert_eq!(before, names(parent), "nothing is written beside the image");
    message
}

#[test]
fn a_truncated_image_is_refused_naming_the_file_and_writes_nothing() {
    let dir = common::temp_dir("truncated");
    // 2 × 2 tiles of the synthetic image, and a scanline copy (one chunk per row).
    let whole = synth(&dir.join("synth"), "100x70", &[]);
    let (size, channels) = read_channels(&whole);
    let scanline = dir.join("synth/scanline.exr");
    write_channels(&scanline, size, &channels, false, Encoding::UNCOMPRESSED);
    let cases = dir.join("cases");
    std::fs::create_dir_all(&cases).unwrap();
    for source in [&whole, &scanline] {
        let bytes = std::fs::read(source).unwrap();
        let stem = source.file_stem().unwrap().to_string_lossy();
        for (cut, keep) in [("half", bytes.len() / 2), ("end", bytes.len() - 4096)] {
            let path = cases.join(format!("{stem}-{cut}.exr"));
            std::fs::write(&path, &bytes[..keep]).unwrap();
            let message = refused_writing_nothing(&path);
            assert!(message.contains("truncated"), "{message}");
        }
    }
    // An output folder that exists keeps what it held and gains nothing, not even an
    // earlier run's work folder is touched.
    let out = dir.join("existing");
    std::fs::create_dir_all(out.join(".fluorite-work")).unwrap();
    std::fs::write(out.join("keep.txt"), "kept").unwrap();
    std::fs::write(out.join(".fluorite-work/state.json"), "{}").unwrap();
    let (code, message) = common::refused(&mut fit_image(&cases.join("image-half.exr"), &out, &[]));
    assert_eq!(code, Some(2), "{message}");
    assert_eq!(names(&out), [".fluorite-work", "keep.txt"]);
    assert_eq!(
        std::fs::read_to_string(out.join(".fluorite-work/state.json")).unwrap(),
        "{}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn an_rgb_image_without_spectral_channels_is_refused() {
    let dir = common::temp_dir("rgb");
    let path = dir.join("rgb.exr");
    exr::prelude::write_rgb_file(&path, 8, 8, |x, y| (x as f32 / 8.0, y as f32 / 8.0, 0.5f32))
        .unwrap();
    let message = refused_writing_nothing(&path);
    assert!(
        message.contains("no reflective spectral channel"),
        "{message}"
    );
}

#[test]
fn a_one_pixel_image_is_refused_as_a_fit_shares_fluorophores_across_pixels() {
    let dir = common::temp_dir("one-pixel");
    let path = dir.join("one.exr");
    write_uniform(
        &path,
        (1, 1),
        &[("T.400nm", 0.5), ("T.500nm", 0.6), ("T.400nm.500nm", 0.01)],
    );
    let message = refused_writing_nothing(&path);
    assert!(message.contains("1 pixel(s)"), "{message}");
}

/// λo < λi is outside the layout (reradiation goes to longer wavelengths): a writer
/// that swapped the axes would be read wrongly if it were ignored or turned round, so it
/// is refused, naming the channel.
#[test]
fn a_reradiation_channel_to_a_shorter_wavelength_is_refused_as_outside_the_layout() {
    let dir = common::temp_dir("anti-stokes");
    let path = dir.join("anti.exr");
    write_uniform(
        &path,
        (4, 4),
        &[
            ("T.400nm", 0.5),
            ("T.500nm", 0.6),
            ("T.400nm.500nm", 0.01),
            ("T.500nm.400nm", 0.01),
        ],
    );
    let message = refused_writing_nothing(&path);
    assert!(
        message.contains("T.500nm.400nm") && message.contains("λo > λi"),
        "{message}"
    );
}

/// `500nm` and `500,0nm` name one cell: which value is the measurement is unknowable.
#[test]
fn two_channels_naming_one_cell_are_refused_as_ambiguous() {
    let dir = common::temp_dir("duplicate");
    let path = dir.join("duplicate.exr");
    write_uniform(
        &path,
        (4, 4),
        &[
            ("T.400nm", 0.5),
            ("T.500nm", 0.6),
            ("T.500,0nm", 0.6),
            ("T.400nm.500nm", 0.01),
        ],
    );
    let message = refused_writing_nothing(&path);
    assert!(message.contains("two channels name the cell"), "{message}");
}

/// Reradiation without the diagonal gives the fluorescence but no reflectance, which a
/// material map holds for every pixel: refused, rather than fitted with an invented one.
#[test]
fn reradiation_channels_without_a_diagonal_are_refused_as_they_give_no_reflectance() {
    let dir = common::temp_dir("no-diagonal");
    let path = dir.join("reradiation.exr");
    write_uniform(
        &path,
        (4, 4),
        &[
            ("T.400nm.500nm", 0.01),
            ("T.400nm.600nm", 0.005),
            ("T.500nm.600nm", 0.01),
        ],
    );
    let message = refused_writing_nothing(&path);
    assert!(message.contains("no diagonal"), "{message}");
}

#[test]
fn an_image_whose_every_pixel_holds_a_non_finite_cell_is_refused_and_writes_nothing() {
    let dir = common::temp_dir("all-nan");
    let path = dir.join("nan.exr");
    write_uniform(
        &path,
        (4, 4),
        &[
            ("T.400nm", 0.5),
            ("T.500nm", f32::NAN),
            ("T.400nm.500nm", 0.01),
        ],
    );
    let message = refused_writing_nothing(&path);
    assert!(message.contains("non-finite"), "{message}");
}

#[test]
fn a_folder_given_as_the_image_is_refused() {
    let dir = common::temp_dir("folder");
    let path = dir.join("images.exr");
    std::fs::create_dir_all(&path).unwrap();
    let message = refused_writing_nothing(&path);
    assert!(message.contains("folder"), "{message}");
}

#[test]
fn a_missing_image_is_refused() {
    let dir = common::temp_dir("missing");
    let message = refused_writing_nothing(&dir.join("missing.exr"));
    assert!(message.contains("No such file"), "{message}");
}

#[test]
fn scanline_and_half_float_images_of_another_writer_fit_with_the_same_components() {
    let s = small();
    let k = components(&s.fitted);
    let dir = common::temp_dir("other-writer");
    let (size, channels) = read_channels(&s.image);
    let renamed: Channels = channels
        .iter()
        .map(|(name, values)| (reference_name(name), values.clone()))
        .collect();
    assert!(
        renamed
            .iter()
            .any(|(n, _)| n == "T.300,000000nm.380,000000nm")
    );
    for (name, half, encoding) in [
        ("scanline.exr", false, Encoding::UNCOMPRESSED),
        ("half.exr", true, Encoding::SMALL_LOSSLESS),
    ] {
        let path = dir.join(name);
        write_channels(&path, size, &renamed, half, encoding);
        let meta = exr::meta::MetaData::read_from_file(&path, false).unwrap();
        let header = &meta.headers[0];
        assert_eq!(header.blocks, exr::meta::BlockDescription::ScanLines);
        let sample = header.channels.list[0].sample_type;
        assert_eq!(
            sample,
            if half {
                exr::meta::attribute::SampleType::F16
            } else {
                exr::meta::attribute::SampleType::F32
            }
        );
        let out = dir.join(format!("{name}.fit"));
        fit(&path, &out, &["--quiet"]);
        assert_eq!(components(&out), k, "{name}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn non_finite_cells_mask_their_pixels_are_counted_exactly_and_are_nan_in_the_maps() {
    let s = small();
    let dir = common::temp_dir("non-finite");
    let ((width, height), mut channels) = read_channels(&s.image);
    let pixels = width * height;
    // (pixel, [(channel, value)]): five pixels, eight cells.
    let planted: [(usize, &[(usize, f32)]); 5] = [
        (0, &[(0, f32::NAN)]),
        (100, &[(5, f32::INFINITY), (600, f32::NEG_INFINITY)]),
        (1000, &[(10, f32::NAN), (20, f32::NAN), (30, f32::NAN)]),
        (1500, &[(41, f32::NAN)]),
        (pixels - 1, &[(channels.len() - 1, f32::INFINITY)]),
    ];
    for (pixel, cells) in planted {
        for &(channel, value) in cells {
            channels[channel].1[pixel] = value;
        }
    }
    let path = dir.join("non-finite.exr");
    // The exr crate's default encoding: RLE-compressed 64 × 64 tiles.
    write_channels(
        &path,
        (width, height),
        &channels,
        false,
        Encoding::FAST_LOSSLESS,
    );
    let out = dir.join("fit");
    let report = fit(&path, &out, &[]);
    assert!(
        report.contains("5 pixel(s) hold non-finite cells (8 cells)"),
        "{report}"
    );
    let text = std::fs::read_to_string(out.join("material-map.json")).unwrap();
    let map: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(map["fit"]["masked_pixels"], 5);
    assert_eq!(map["fit"]["non_finite_cells"], 8);
    let masked: Vec<usize> = planted.iter().map(|p| p.0).collect();
    for name in [
        "concentration.exr",
        "reflectance.exr",
        "fitted.exr",
        "delta-e.exr",
    ] {
        let (size, maps) = read_channels(&out.join(name));
        assert_eq!(size, (width, height), "{name}");
        for p in 0..pixels {
            let values: Vec<f32> = maps.iter().map(|(_, v)| v[p]).collect();
            if masked.contains(&p) {
                assert!(values.iter().all(|v| v.is_nan()), "{name}: pixel {p}");
            } else {
                assert!(values.iter().all(|v| v.is_finite()), "{name}: pixel {p}");
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Newer OpenEXR libraries write compressions the `exr` crate does not decode: HTJ2K
/// (codes 10, 11), whose header it reads and whose pixels it calls "yet unimplemented"
/// (fit-image called that a truncated file), and LJ2K and ZSTD (12, 13), which it
/// refuses as "missing or invalid compression attribute". fit-image, image-diff and fit
/// say which compression it is and what to do, and write nothing. (scripts/other_tool_image.py --compression zstd writes such a file
/// with the OpenEXR library itself; python/tests/test_other_tool_image.py runs it.)
#[test]
fn an_image_compressed_with_a_codec_the_reader_lacks_is_refused_naming_it() {
    let dir = common::temp_dir("zstd");
    let path = dir.join("zstd.exr");
    write_uniform(
        &path,
        (4, 4),
        &[("T.400nm", 0.5), ("T.500nm", 0.6), ("T.400nm.500nm", 0.01)],
    );
    let mut bytes = std::fs::read(&path).unwrap();
    let key = b"compression\0compression\0\x01\0\0\0";
    let at = (0..bytes.len() - key.len())
        .find(|&i| bytes[i..].starts_with(key))
        .expect("a compression attribute")
        + key.len();
    for (code, name) in [
        (13u8, "ZSTD (code 13)"),
        (12, "LJ2K (code 12)"),
        (11, "HTJ2K32 (code 11)"),
        (10, "HTJ2K256 (code 10)"),
    ] {
        bytes[at] = code;
        std::fs::write(&path, &bytes).unwrap();
        let message = refused_writing_nothing(&path);
        assert!(
            message.contains(name) && message.contains("ZIP, PIZ"),
            "{message}"
        );
        for args in [vec!["fit"], vec!["image-diff", path.to_str().unwrap()]] {
            let (code, message) = common::refused(common::fluorite().args(&args).arg(&path));
            assert_eq!(code, Some(2), "{message}");
            assert!(message.contains(name), "{args:?}: {message}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
