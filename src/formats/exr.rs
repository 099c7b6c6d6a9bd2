//! The bispectral spectral OpenEXR layout of Fichet, Mercier and Wilkie ("An OpenEXR
//! Layout for Spectral Images", JCGT 10(3), 2021; reference implementation
//! afichet/spectral-exr, `lib/EXRBiSpectralImage.cpp`), read as a measurement.
//!
//! A reflective (bispectral) image names its channels after wavelengths: `T.<λ>nm` holds
//! the diagonal (reflectance) at λ, `T.<λi>nm.<λo>nm` the reradiation from λi to λo > λi.
//! Numbers use a comma as decimal separator (`T.432,5nm`); the reference's grammar also
//! allows an exponent, SI prefixes and `Hz`, which are read here too. One wavelength grid
//! serves both axes, and only λo > λi has channels: the layout holds no anti-Stokes
//! cell, so those cells read as missing. Every pixel is one matrix; a uniform image (what
//! `fluorite export --to exr` writes) reads as that matrix, a non-uniform one as the
//! mean over its pixels, with a note giving the spread.

use std::path::Path;

use crate::error::{Error, Result};

use super::Parsed;

/// The header attribute naming the layout's version.
pub const VERSION_ATTRIBUTE: &str = "spectralLayoutVersion";

/// Header text: OpenEXR strings are Latin-1, so other characters become `?`.
pub fn header_text(s: &str) -> exr::meta::attribute::Text {
    use exr::meta::attribute::Text;
    let latin1: String = s
        .chars()
        .map(|c| if (c as u32) < 256 { c } else { '?' })
        .collect();
    Text::new_or_none(latin1).unwrap_or_else(|| Text::from("?"))
}
/// The version of the layout written and read.
pub const VERSION: &str = "1.0";
/// The first four bytes of every OpenEXR file.
const MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

/// Whether `bytes` start like an OpenEXR file.
pub fn is_exr(bytes: &[u8]) -> bool {
    bytes.starts_with(&MAGIC)
}

/// A wavelength as the layout writes it: at most six decimals (the reference writer's
/// `std::to_string` precision), trailing zeros dropped, with a comma as decimal
/// separator (`432,5`, `300`). Six decimals keep grid steps such as 0.1 nm short:
/// 300.20000000000005 is `300,2`.
fn wavelength_text(nm: f64) -> String {
    let fixed = format!("{nm:.6}");
    let trimmed = fixed.trim_end_matches('0').trim_end_matches('.');
    trimmed.replace('.', ",")
}

/// The channel holding the diagonal (reflectance) at `nm`: `T.<λ>nm`.
pub fn diagonal_channel(nm: f64) -> String {
    format!("T.{}nm", wavelength_text(nm))
}

/// The channel holding the reradiation from `excitation_nm` to `emission_nm` (which the
/// layout requires to be longer): `T.<λi>nm.<λo>nm`.
pub fn reradiation_channel(excitation_nm: f64, emission_nm: f64) -> String {
    format!(
        "T.{}nm.{}nm",
        wavelength_text(excitation_nm),
        wavelength_text(emission_nm)
    )
}

/// What a channel name means in the layout.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Channel {
    /// `T.<λ>`: the diagonal at λ (nm).
    Diagonal(f64),
    /// `T.<λi>.<λo>`: the reradiation from λi to λo (nm).
    Reradiation(f64, f64),
    /// `S<k>.<λ>`: an emissive Stokes component (polarisation component k) at λ (nm).
    Emissive(u8, f64),
}

/// Parses a channel name by the reference implementation's grammar
/// (`EXRBiSpectralImage::channelType`); `None` for channels outside the layout (`R`, `G`,
/// `B`, …).
pub fn parse_channel(name: &str) -> Option<Channel> {
    let (prefix, rest) = name.split_once('.')?;
    let parts: Vec<&str> = rest.split('.').collect();
    match (prefix, parts.as_slice()) {
        ("T", [l]) => Some(Channel::Diagonal(quantity_nm(l)?)),
        ("T", [i, o]) => Some(Channel::Reradiation(quantity_nm(i)?, quantity_nm(o)?)),
        (s, [l]) if s.len() == 2 && s.starts_with('S') => {
            let k = s[1..].parse::<u8>().ok().filter(|k| *k <= 3)?;
            Some(Channel::Emissive(k, quantity_nm(l)?))
        }
        _ => None,
    }
}

/// `<value><SI prefix><m|Hz>` in nm: the value's digits with at most one comma and an
/// optional exponent, as the reference's `(\d*,?\d*([Ee][+-]?\d+)?)` reads it.
fn quantity_nm(text: &str) -> Option<f64> {
    let bytes = text.as_bytes();
    let mut end = 0;
    let mut commas = 0;
    while end < bytes.len() && (bytes[end].is_ascii_digit() || bytes[end] == b',') {
        commas += usize::from(bytes[end] == b',');
        end += 1;
    }
    if commas > 1 || !bytes[..end].iter().any(u8::is_ascii_digit) {
        return None;
    }
    // An exponent only when digits follow: `5Em` is 5 exametres, `5E1m` is 50 m.
    if end < bytes.len() && matches!(bytes[end], b'e' | b'E') {
        let mut k = end + 1;
        if k < bytes.len() && matches!(bytes[k], b'+' | b'-') {
            k += 1;
        }
        let digits = bytes[k..].iter().take_while(|b| b.is_ascii_digit()).count();
        if digits > 0 {
            end = k + digits;
        }
    }
    let value: f64 = text[..end].replace(',', ".").parse().ok()?;
    let units = &text[end..];
    let (prefix, hertz) = if let Some(p) = units.strip_suffix("Hz") {
        (p, true)
    } else {
        (units.strip_suffix('m')?, false)
    };
    let scale = match prefix {
        "" => 1.0,
        "Y" => 1e24,
        "Z" => 1e21,
        "E" => 1e18,
        "P" => 1e15,
        "T" => 1e12,
        "G" => 1e9,
        "M" => 1e6,
        "k" => 1e3,
        "h" => 1e2,
        "da" => 1e1,
        "d" => 1e-1,
        "c" => 1e-2,
        "m" => 1e-3,
        "u" => 1e-6,
        "n" => 1e-9,
        "p" => 1e-12,
        _ => return None,
    };
    let nm = if hertz {
        299_792_458.0 / (value * scale) * 1e9
    } else if prefix == "n" {
        value
    } else {
        value * scale * 1e9
    };
    (nm.is_finite() && nm > 0.0).then_some(nm)
}

/// OpenEXR's compression codes, by the names the OpenEXR library gives them.
const COMPRESSIONS: [&str; 14] = [
    "none", "RLE", "ZIPS", "ZIP", "PIZ", "PXR24", "B44", "B44A", "DWAA", "DWAB", "HTJ2K256",
    "HTJ2K32", "LJ2K", "ZSTD",
];
/// The codes up to this one are those the `exr` crate decodes (0–9: none … DWAB). It
/// reads the headers of HTJ2K files (10, 11) but cannot decompress their pixels, and
/// refuses the headers of the codes after them.
const LAST_DECODED_COMPRESSION: u8 = 9;

/// Why a file compressed with `code` cannot be read, and what to do, when the `exr`
/// crate cannot decode that compression; `None` when it can.
pub fn compression_not_decoded(code: u8) -> Option<String> {
    if code <= LAST_DECODED_COMPRESSION {
        return None;
    }
    let name = COMPRESSIONS.get(usize::from(code)).map_or_else(
        || format!("compression {code}"),
        |n| format!("{n} (code {code})"),
    );
    Some(format!(
        "it is compressed with {name}, which fluorite's OpenEXR reader (the exr crate) cannot decode; rewrite it with one of {} (e.g. `oiiotool IN.exr --compression zip -o OUT.exr`, or the OpenEXR Python bindings)",
        COMPRESSIONS[..=usize::from(LAST_DECODED_COMPRESSION)].join(", ")
    ))
}

/// [`compression_not_decoded`] for a header the `exr` crate has read.
pub fn compression_not_decoded_in(header: &exr::meta::header::Header) -> Option<String> {
    use exr::compression::Compression;
    match header.compression {
        Compression::HTJ2K256 => compression_not_decoded(10),
        Compression::HTJ2K32 => compression_not_decoded(11),
        _ => None,
    }
}

/// Why an OpenEXR file the `exr` crate refused cannot be read, when the reason is a
/// compression it does not decode (HTJ2K, LJ2K, ZSTD: codes 10–13, or a later code):
/// read from the headers' attribute lists alone, without decoding. The crate itself
/// says only "missing or invalid compression attribute" or "yet unimplemented
/// compression method". `None` when every part's compression is one the crate decodes,
/// or the headers cannot be walked.
pub fn unsupported_compression(reader: impl std::io::Read) -> Option<String> {
    header_compressions(reader)?
        .into_iter()
        .find_map(compression_not_decoded)
}

/// The `compression` attribute of every header of an OpenEXR file (one per part), from
/// the attribute lists: name and type (NUL-terminated), size (i32, little-endian),
/// value. `None` when the bytes do not walk as headers.
fn header_compressions(reader: impl std::io::Read) -> Option<Vec<u8>> {
    use std::io::{BufRead, Read};
    /// A NUL-terminated name of at most 255 bytes, without its NUL.
    fn name(r: &mut impl BufRead) -> Option<Vec<u8>> {
        let mut out = Vec::new();
        r.take(256).read_until(0, &mut out).ok()?;
        (out.pop() == Some(0)).then_some(out)
    }
    let mut r = std::io::BufReader::new(reader);
    let mut start = [0u8; 8];
    r.read_exact(&mut start).ok()?;
    if start[..4] != MAGIC {
        return None;
    }
    let multipart = u32::from_le_bytes([start[4], start[5], start[6], start[7]]) & 0x1000 != 0;
    let mut codes = Vec::new();
    for _ in 0..10_000 {
        let mut attributes = 0;
        loop {
            let attribute = name(&mut r)?;
            if attribute.is_empty() {
                break;
            }
            attributes += 1;
            let kind = name(&mut r)?;
            let mut size = [0u8; 4];
            r.read_exact(&mut size).ok()?;
            let size = u64::try_from(i32::from_le_bytes(size)).ok()?;
            if attribute == b"compression" && kind == b"compression" && size == 1 {
                let mut code = [0u8; 1];
                r.read_exact(&mut code).ok()?;
                codes.push(code[0]);
            } else if std::io::copy(&mut (&mut r).take(size), &mut std::io::sink()).ok()? != size {
                return None;
            }
        }
        // A single-part file has one header; a multi-part file's list of headers ends
        // with an empty one.
        if !multipart || attributes == 0 {
            return Some(codes);
        }
    }
    None
}

/// The message for a file the `exr` crate refused: its error, and the compression the
/// crate lacks when that is why.
pub fn unreadable(error: impl std::fmt::Display, file: impl std::io::Read) -> String {
    match unsupported_compression(file) {
        Some(why) => format!("not a readable OpenEXR file: {why}"),
        None => format!("not a readable OpenEXR file: {error}"),
    }
}

/// Reads a bispectral EXR into an excitation-major matrix on its wavelength grid.
pub(super) fn read(path: &Path, bytes: &[u8]) -> Result<Parsed> {
    use exr::prelude::{ReadChannels, ReadLayers, read};
    let fail = |message: String| Error::parse(path, 0, 0, message);
    check_image_size(bytes).map_err(fail)?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(|e| fail(unreadable(e, bytes)))?;
    // The layout is one part; take the first layer holding reflective channels.
    let mut layers = image.layer_data.iter().map(named_channels);
    let channels = loop {
        match layers.next() {
            Some(channels)
                if channels
                    .iter()
                    .any(|(c, _)| !matches!(c, Channel::Emissive(..))) =>
            {
                break channels;
            }
            Some(_) => continue,
            None => {
                return Err(fail(
                    "no reflective spectral channel (T.<λ>nm or T.<λi>nm.<λo>nm): this is an RGB or emissive-only EXR, not a bispectral measurement; export one with `fluorite export MAT --to exr` or the spectral-exr tools".into(),
                ));
            }
        }
    };
    let mut grid: Vec<f64> = Vec::new();
    for (c, _) in &channels {
        match *c {
            Channel::Diagonal(l) => grid.push(l),
            Channel::Reradiation(i, o) => grid.extend([i, o]),
            Channel::Emissive(..) => {}
        }
    }
    grid.sort_by(f64::total_cmp);
    grid.dedup_by(|a, b| (*a - *b).abs() <= 1e-6);
    for &nm in [grid.first(), grid.last()].into_iter().flatten() {
        crate::limits::check_wavelength(nm)
            .map_err(|message| fail(format!("a channel names the wavelength {message}")))?;
    }
    let n = grid.len();
    if n * n > crate::limits::MAX_CELLS {
        return Err(fail(format!(
            "the channels name {n} wavelengths, a {n} × {n} matrix; at most {} cells are read",
            crate::limits::MAX_CELLS
        )));
    }
    let index = |nm: f64| crate::spectrum::find_wavelength(&grid, nm).unwrap_or(0);
    let mut values = vec![f64::NAN; n * n];
    let mut seen = vec![false; n * n];
    let mut notes = Vec::new();
    let mut spread: f64 = 0.0;
    let mut pixels = 0;
    for (channel, samples) in &channels {
        let (i, j) = match *channel {
            Channel::Diagonal(l) => (index(l), index(l)),
            Channel::Reradiation(ex, em) if em > ex => (index(ex), index(em)),
            Channel::Reradiation(ex, em) => {
                return Err(fail(format!(
                    "channel {}: the layout's reradiation channels go from a shorter to a longer wavelength (λo > λi), here {ex} nm → {em} nm; name it T.<λi>nm.<λo>nm with λi < λo",
                    reradiation_channel(ex, em)
                )));
            }
            Channel::Emissive(..) => continue,
        };
        if std::mem::replace(&mut seen[i * n + j], true) {
            return Err(fail(format!(
                "two channels name the cell {} nm → {} nm (e.g. `500nm` and `500,0nm`); keep one",
                grid[i], grid[j]
            )));
        }
        let (mut sum, mut count, mut lo, mut hi) = (0.0, 0usize, f64::INFINITY, f64::NEG_INFINITY);
        for v in samples
            .values_as_f32()
            .map(f64::from)
            .filter(|v| v.is_finite())
        {
            sum += v;
            count += 1;
            lo = lo.min(v);
            hi = hi.max(v);
        }
        pixels = pixels.max(samples.len());
        if count > 0 {
            values[i * n + j] = sum / count as f64;
            spread = spread.max(hi - lo);
        }
    }
    if channels
        .iter()
        .any(|(c, _)| matches!(c, Channel::Emissive(..)))
    {
        notes.push(
            "emissive channels (S0…S3) ignored: the measurement is the reflective (bispectral) part"
                .into(),
        );
    }
    if spread > 0.0 && pixels > 1 {
        notes.push(format!(
            "the image is not uniform (a cell varies by up to {spread:.3e} across its {pixels} pixels): the matrix read is the mean over the pixels"
        ));
    }
    if n > 1 {
        notes.push(format!(
            "the spectral EXR layout has no channel for anti-Stokes cells (λo < λi): those {} cells read as missing",
            n * (n - 1) / 2
        ));
    }
    Ok(Parsed::surface(grid.clone(), grid, values, notes))
}

/// Refuses, from the header alone, a compression the `exr` crate cannot decode and an
/// image whose samples (pixels × channels, summed over its parts) exceed
/// [`crate::limits::MAX_IMAGE_SAMPLES`], before any pixel is decoded.
fn check_image_size(bytes: &[u8]) -> std::result::Result<(), String> {
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
        .map_err(|e| unreadable(e, bytes))?;
    if let Some(why) = meta.headers.iter().find_map(compression_not_decoded_in) {
        return Err(format!("not a readable OpenEXR file: {why}"));
    }
    let mut samples: u64 = 0;
    for header in &meta.headers {
        let size = header.layer_size;
        let pixels = size.width() as u64 * size.height() as u64;
        samples = samples.saturating_add(pixels.saturating_mul(header.channels.list.len() as u64));
    }
    if samples > crate::limits::MAX_IMAGE_SAMPLES {
        return Err(format!(
            "the image holds {samples} samples (pixels × channels); at most {} are read at once: crop or bin the image",
            crate::limits::MAX_IMAGE_SAMPLES
        ));
    }
    Ok(())
}

type Layer = exr::image::Layer<exr::image::AnyChannels<exr::image::FlatSamples>>;

/// The channels of `layer` the layout names, with their samples.
fn named_channels(layer: &Layer) -> Vec<(Channel, &exr::image::FlatSamples)> {
    layer
        .channel_data
        .list
        .iter()
        .filter_map(|c| Some((parse_channel(&c.name.to_string())?, &c.sample_data)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A two-part OpenEXR file in memory (ZIP, then PIZ), as the `exr` crate writes it.
    fn two_parts() -> Vec<u8> {
        use exr::prelude::*;
        let layer = |name: &str, compression| {
            Layer::new(
                (4, 3),
                LayerAttributes::named(name),
                Encoding {
                    compression,
                    ..Encoding::default()
                },
                AnyChannels::sort(SmallVec::from_vec(vec![AnyChannel::new(
                    "T.500nm",
                    FlatSamples::F32(vec![0.5; 12]),
                )])),
            )
        };
        let image = Image::from_layers(
            ImageAttributes::new(IntegerBounds::from_dimensions((4, 3))),
            SmallVec::from_vec(vec![
                layer("one", Compression::ZIP16),
                layer("two", Compression::PIZ),
            ]),
        );
        let mut bytes = std::io::Cursor::new(Vec::new());
        image.write().to_buffered(&mut bytes).unwrap();
        bytes.into_inner()
    }

    #[test]
    fn a_compression_newer_than_the_reader_is_named() {
        let mut bytes = two_parts();
        // OpenEXR's codes: ZIP 3, PIZ 4; the crate reads both.
        assert_eq!(header_compressions(bytes.as_slice()), Some(vec![3, 4]));
        assert_eq!(unsupported_compression(bytes.as_slice()), None);
        // The second part's compression as OpenEXR 3.4's ZSTD (13): the crate refuses the
        // file without naming why; the message names it.
        let key = b"compression\0compression\0\x01\0\0\0";
        let at: Vec<usize> = (0..bytes.len() - key.len())
            .filter(|&i| bytes[i..].starts_with(key))
            .collect();
        assert_eq!(at.len(), 2);
        bytes[at[1] + key.len()] = 13;
        assert_eq!(header_compressions(bytes.as_slice()), Some(vec![3, 13]));
        let refused = exr::meta::MetaData::read_from_buffered(bytes.as_slice(), false).unwrap_err();
        let message = unreadable(refused, bytes.as_slice());
        assert!(message.contains("ZSTD (code 13)"), "{message}");
        bytes[at[1] + key.len()] = 40;
        let message = unsupported_compression(bytes.as_slice()).unwrap();
        assert!(message.contains("compression 40"), "{message}");
        // HTJ2K: the crate reads the header, not the pixels.
        bytes[at[1] + key.len()] = 11;
        let meta = exr::meta::MetaData::read_from_buffered(bytes.as_slice(), false).unwrap();
        let message = compression_not_decoded_in(&meta.headers[1]).unwrap();
        assert!(message.contains("HTJ2K32 (code 11)"), "{message}");
        assert_eq!(compression_not_decoded_in(&meta.headers[0]), None);
        // Not an OpenEXR file, or one cut inside its header: nothing to name.
        assert_eq!(header_compressions(&b"P6 4 3 255"[..]), None);
        assert_eq!(header_compressions(&bytes[..at[0] + 5]), None);
    }

    #[test]
    fn channel_names_follow_the_reference_grammar() {
        assert_eq!(diagonal_channel(432.5), "T.432,5nm");
        assert_eq!(reradiation_channel(300.0, 310.0), "T.300nm.310nm");
        assert_eq!(diagonal_channel(300.0 + 0.1 + 0.1), "T.300,2nm");
        assert_eq!(diagonal_channel(1000.0), "T.1000nm");
        assert_eq!(parse_channel("T.432,5nm"), Some(Channel::Diagonal(432.5)));
        // The reference writer's std::to_string form.
        assert_eq!(
            parse_channel("T.300,000000nm.310,000000nm"),
            Some(Channel::Reradiation(300.0, 310.0))
        );
        assert_eq!(parse_channel("S0.550nm"), Some(Channel::Emissive(0, 550.0)));
        let Some(Channel::Diagonal(um)) = parse_channel("T.0,5um") else {
            panic!("micrometres")
        };
        assert!((um - 500.0).abs() < 1e-9);
        let Some(Channel::Diagonal(hz)) = parse_channel("T.599,584916THz") else {
            panic!("terahertz")
        };
        assert!((hz - 500.0).abs() < 1e-6, "{hz}");
        let Some(Channel::Diagonal(e)) = parse_channel("T.5E2nm") else {
            panic!("exponent")
        };
        assert!((e - 500.0).abs() < 1e-9);
        for other in [
            "R",
            "G",
            "B",
            "T.nm",
            "T.5,0,0nm",
            "T.500",
            "S4.500nm",
            "X.500nm",
        ] {
            assert_eq!(parse_channel(other), None, "{other}");
        }
    }
}
