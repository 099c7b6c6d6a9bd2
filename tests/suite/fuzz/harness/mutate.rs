//! The mutator: one to three random edits of a seed file, each described in words so a
//! failure's recipe says what was done.

use fluorite::numeric::SplitMix64;

use super::corpus::Seed;

/// What replaces a number: the issue's list (overflow, NaN, infinities, signed zero,
/// subnormal, 40 nines, a 42-digit number) and a few more that stress parsers.
const NUMBERS: &[&str] = &[
    "1e308",
    "-1e308",
    "NaN",
    "nan",
    "inf",
    "-inf",
    "0",
    "-0",
    "1e-320",
    "9999999999999999999999999999999999999999",
    "123456789012345678901234567890123456789012",
    "-1",
    "",
    "1e400",
    "0x1F",
    "1,5",
    "4294967297",
    "18446744073709551617",
];

/// What replaces a wavelength: huge, tiny, negative, or duplicated-looking values.
const WAVELENGTHS: &[&str] = &[
    "1e12",
    "1e300",
    "1e308",
    "123456789012345678901234567890123456789012",
    "9999999999999999999999999999999999999999",
    "100000",
    "-450",
    "0",
    "1e-9",
    "450.0000000001",
    "NaN",
    "inf",
];

/// Bytes inserted as junk.
const JUNK: &[&[u8]] = &[
    b"\0",
    b"\xff\xfe",
    b"\xef\xbb\xbf",
    b"\xc3",
    b"\r",
    b"\r\n\r\n",
    b"\t",
    b",",
    b";",
    b"\"",
    b"-",
    b"e",
    b"NA",
    b"\\",
];

/// A mutant: the bytes and the edits that made them.
pub struct Mutant {
    /// The mutated file.
    pub bytes: Vec<u8>,
    /// One phrase per edit.
    pub edits: Vec<String>,
}

fn below(rng: &mut SplitMix64, n: usize) -> usize {
    if n == 0 {
        0
    } else {
        (rng.next_u64() % n as u64) as usize
    }
}

fn pick<'a, T>(rng: &mut SplitMix64, items: &'a [T]) -> &'a T {
    &items[below(rng, items.len())]
}

/// Mutates `seed` with one to three edits; `others` supplies lines to splice in.
pub fn mutate(seed: &Seed, others: &[Seed], rng: &mut SplitMix64) -> Mutant {
    let mut bytes = seed.bytes.clone();
    let edits_wanted = match below(rng, 20) {
        0..=11 => 1,
        12..=16 => 2,
        _ => 3,
    };
    let mut edits = Vec::new();
    for _ in 0..edits_wanted {
        let edit = if seed.binary {
            binary_edit(&mut bytes, rng)
        } else {
            text_edit(&mut bytes, others, rng)
        };
        edits.push(edit);
    }
    Mutant { bytes, edits }
}

/// Byte ranges of the numbers in `bytes`: runs of `[0-9.eE+-]` holding a digit, not
/// glued to a letter or digit before them.
fn numbers(bytes: &[u8]) -> Vec<(usize, usize)> {
    let is_part = |b: u8| b.is_ascii_digit() || matches!(b, b'.' | b'e' | b'E' | b'+' | b'-');
    let mut spans = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let starts = (bytes[i].is_ascii_digit() || matches!(bytes[i], b'-' | b'+' | b'.'))
            && (i == 0 || !bytes[i - 1].is_ascii_alphanumeric());
        if !starts {
            i += 1;
            continue;
        }
        let mut j = i;
        while j < bytes.len() && is_part(bytes[j]) {
            j += 1;
        }
        if bytes[i..j].iter().any(u8::is_ascii_digit) {
            spans.push((i, j));
        }
        i = j.max(i + 1);
    }
    spans
}

/// Byte ranges of the lines (without their `\n`).
fn lines(bytes: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut start = 0;
    for (i, &b) in bytes.iter().enumerate() {
        if b == b'\n' {
            spans.push((start, i));
            start = i + 1;
        }
    }
    if start < bytes.len() {
        spans.push((start, bytes.len()));
    }
    spans
}

fn line_number(bytes: &[u8], at: usize) -> usize {
    bytes[..at.min(bytes.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

fn replace(bytes: &mut Vec<u8>, (start, end): (usize, usize), with: &[u8]) {
    bytes.splice(start..end, with.iter().copied());
}

fn bit_flips(bytes: &mut [u8], rng: &mut SplitMix64) -> String {
    if bytes.is_empty() {
        return "bit flip: file empty, nothing flipped".into();
    }
    let flips = 1 + below(rng, 8);
    let mut at = Vec::new();
    for _ in 0..flips {
        let i = below(rng, bytes.len());
        let bit = below(rng, 8);
        bytes[i] ^= 1 << bit;
        at.push(format!("{i}.{bit}"));
    }
    format!("flipped bits (byte.bit) {}", at.join(" "))
}

fn truncate(bytes: &mut Vec<u8>, rng: &mut SplitMix64) -> String {
    let at = below(rng, bytes.len() + 1);
    bytes.truncate(at);
    format!("truncated to {at} bytes")
}

fn junk(bytes: &mut Vec<u8>, rng: &mut SplitMix64) -> String {
    let at = below(rng, bytes.len() + 1);
    let mut inserted = Vec::new();
    for _ in 0..1 + below(rng, 4) {
        if below(rng, 2) == 0 {
            let piece: &&[u8] = pick(rng, JUNK);
            inserted.extend_from_slice(piece);
        } else {
            inserted.push(rng.next_u64() as u8);
        }
    }
    let description = format!("inserted junk bytes {inserted:02x?} at byte {at}");
    bytes.splice(at..at, inserted);
    description
}

fn binary_edit(bytes: &mut Vec<u8>, rng: &mut SplitMix64) -> String {
    match below(rng, 6) {
        0 => bit_flips(bytes, rng),
        1 => truncate(bytes, rng),
        2 => junk(bytes, rng),
        3 => {
            // A 4-byte word: float specials, a huge or negative count.
            const WORDS: [u32; 7] = [
                0x7fc0_0000,
                0x7f80_0000,
                0xff80_0000,
                0x7f7f_ffff,
                0xffff_ffff,
                0x7fff_ffff,
                0,
            ];
            if bytes.len() < 4 {
                return truncate(bytes, rng);
            }
            let at = below(rng, bytes.len() - 3);
            let word = *pick(rng, &WORDS);
            bytes[at..at + 4].copy_from_slice(&word.to_le_bytes());
            format!("wrote word {word:#010x} at byte {at}")
        }
        4 => {
            let start = below(rng, bytes.len());
            let len = 1 + below(rng, 64.min(bytes.len() - start.min(bytes.len())).max(1));
            let end = (start + len).min(bytes.len());
            let chunk = bytes[start..end].to_vec();
            bytes.splice(end..end, chunk);
            format!("duplicated bytes {start}..{end}")
        }
        _ => {
            // The header's text (channel names `T.450nm`, attribute values) holds numbers.
            let header = 4096.min(bytes.len());
            let spans = numbers(&bytes[..header]);
            if spans.is_empty() {
                return bit_flips(bytes, rng);
            }
            let span = *pick(rng, &spans);
            let with = *pick(rng, WAVELENGTHS);
            let old = String::from_utf8_lossy(&bytes[span.0..span.1]).into_owned();
            replace(bytes, span, with.as_bytes());
            format!(
                "replaced header number {old:?} at byte {} by {with:?}",
                span.0
            )
        }
    }
}

fn text_edit(bytes: &mut Vec<u8>, others: &[Seed], rng: &mut SplitMix64) -> String {
    match below(rng, 14) {
        0 => bit_flips(bytes, rng),
        1 => truncate(bytes, rng),
        2 => junk(bytes, rng),
        3 => splice(bytes, others, rng),
        4 => duplicate_lines(bytes, rng),
        5 => delete_lines(bytes, rng),
        6 | 7 => replace_number(bytes, rng),
        8 | 9 => replace_wavelength(bytes, rng),
        10 => replace_row(bytes, rng),
        11 => delete_or_duplicate_cell(bytes, rng),
        12 => swap_delimiters(bytes, rng),
        _ => {
            // Two edits of the commonest kind.
            let a = replace_number(bytes, rng);
            let b = replace_number(bytes, rng);
            format!("{a}; {b}")
        }
    }
}

fn splice(bytes: &mut Vec<u8>, others: &[Seed], rng: &mut SplitMix64) -> String {
    let texts: Vec<&Seed> = others.iter().filter(|s| !s.binary).collect();
    if texts.is_empty() {
        return duplicate_lines(bytes, rng);
    }
    let donor = *pick(rng, &texts);
    let donor_lines = lines(&donor.bytes);
    if donor_lines.is_empty() {
        return junk(bytes, rng);
    }
    let first = below(rng, donor_lines.len());
    let last = (first + below(rng, 5)).min(donor_lines.len() - 1);
    let chunk = donor.bytes[donor_lines[first].0..donor_lines[last].1].to_vec();
    let own = lines(bytes);
    let at = if own.is_empty() {
        0
    } else {
        own[below(rng, own.len())].0
    };
    let line = line_number(bytes, at);
    let mut inserted = chunk;
    inserted.push(b'\n');
    bytes.splice(at..at, inserted);
    format!(
        "spliced lines {}-{} of {} before line {line}",
        first + 1,
        last + 1,
        donor.origin
    )
}

fn duplicate_lines(bytes: &mut Vec<u8>, rng: &mut SplitMix64) -> String {
    let own = lines(bytes);
    if own.is_empty() {
        return junk(bytes, rng);
    }
    let first = below(rng, own.len());
    let last = (first + below(rng, 3)).min(own.len() - 1);
    let times = *pick(rng, &[1usize, 1, 2, 50]);
    let mut chunk = bytes[own[first].0..own[last].1].to_vec();
    chunk.push(b'\n');
    let at = own[last].1.min(bytes.len());
    let at = if at < bytes.len() { at + 1 } else { at };
    let mut inserted = Vec::new();
    if at == bytes.len() && bytes.last() != Some(&b'\n') {
        inserted.push(b'\n');
    }
    for _ in 0..times {
        inserted.extend_from_slice(&chunk);
    }
    bytes.splice(at..at, inserted);
    format!("duplicated lines {}-{} {times}×", first + 1, last + 1)
}

fn delete_lines(bytes: &mut Vec<u8>, rng: &mut SplitMix64) -> String {
    let own = lines(bytes);
    if own.is_empty() {
        return junk(bytes, rng);
    }
    let first = below(rng, own.len());
    let last = (first + below(rng, 3)).min(own.len() - 1);
    let end = (own[last].1 + 1).min(bytes.len());
    bytes.drain(own[first].0..end);
    format!("deleted lines {}-{}", first + 1, last + 1)
}

fn replace_number(bytes: &mut Vec<u8>, rng: &mut SplitMix64) -> String {
    let spans = numbers(bytes);
    if spans.is_empty() {
        return junk(bytes, rng);
    }
    let span = *pick(rng, &spans);
    let with = *pick(rng, NUMBERS);
    let old = String::from_utf8_lossy(&bytes[span.0..span.1]).into_owned();
    let line = line_number(bytes, span.0);
    replace(bytes, span, with.as_bytes());
    format!("replaced number {old:?} on line {line} by {with:?}")
}

/// A wavelength: the first number of a row (row wavelengths) or any number of the first
/// lines (column wavelengths, the BFC grid line).
fn replace_wavelength(bytes: &mut Vec<u8>, rng: &mut SplitMix64) -> String {
    let spans = numbers(bytes);
    let own = lines(bytes);
    let candidates: Vec<(usize, usize)> = if below(rng, 2) == 0 {
        own.iter()
            .filter_map(|&(s, e)| spans.iter().find(|n| n.0 >= s && n.1 <= e).copied())
            .collect()
    } else {
        let header_end = own.get(12).map_or(bytes.len(), |l| l.1);
        spans
            .iter()
            .copied()
            .filter(|n| n.1 <= header_end)
            .collect()
    };
    if candidates.is_empty() {
        return replace_number(bytes, rng);
    }
    let span = *pick(rng, &candidates);
    let with = *pick(rng, WAVELENGTHS);
    let old = String::from_utf8_lossy(&bytes[span.0..span.1]).into_owned();
    let line = line_number(bytes, span.0);
    replace(bytes, span, with.as_bytes());
    format!("replaced wavelength-position number {old:?} on line {line} by {with:?}")
}

/// Every number of one line replaced by the same value (a row of NaN, of zeros, ...).
fn replace_row(bytes: &mut Vec<u8>, rng: &mut SplitMix64) -> String {
    let own = lines(bytes);
    if own.is_empty() {
        return junk(bytes, rng);
    }
    let index = below(rng, own.len());
    let (s, e) = own[index];
    let with = *pick(rng, NUMBERS);
    let spans: Vec<_> = numbers(&bytes[s..e])
        .into_iter()
        .map(|(a, b)| (a + s, b + s))
        .collect();
    for &span in spans.iter().rev() {
        replace(bytes, span, with.as_bytes());
    }
    format!(
        "replaced all {} numbers on line {} by {with:?}",
        spans.len(),
        index + 1
    )
}

fn delimiter_positions(line: &[u8]) -> Vec<usize> {
    line.iter()
        .enumerate()
        .filter(|(_, b)| matches!(b, b',' | b';' | b'\t' | b' '))
        .map(|(i, _)| i)
        .collect()
}

fn delete_or_duplicate_cell(bytes: &mut Vec<u8>, rng: &mut SplitMix64) -> String {
    let own = lines(bytes);
    if own.is_empty() {
        return junk(bytes, rng);
    }
    let index = below(rng, own.len());
    let (s, e) = own[index];
    let delimiters = delimiter_positions(&bytes[s..e]);
    if delimiters.is_empty() {
        return replace_number(bytes, rng);
    }
    // A cell with its following delimiter: from after the previous delimiter up to and
    // including a chosen one.
    let k = below(rng, delimiters.len());
    let start = if k == 0 { s } else { s + delimiters[k - 1] + 1 };
    let end = s + delimiters[k] + 1;
    if below(rng, 2) == 0 {
        bytes.drain(start..end);
        format!("deleted cell {} of line {}", k + 1, index + 1)
    } else {
        let cell = bytes[start..end].to_vec();
        bytes.splice(start..start, cell);
        format!("duplicated cell {} of line {}", k + 1, index + 1)
    }
}

fn swap_delimiters(bytes: &mut [u8], rng: &mut SplitMix64) -> String {
    const DELIMITERS: [u8; 4] = [b',', b';', b'\t', b' '];
    let from = *pick(rng, &DELIMITERS);
    let to = *pick(rng, &DELIMITERS);
    let own = lines(bytes);
    let (range, where_) = if below(rng, 2) == 0 || own.is_empty() {
        ((0, bytes.len()), "the whole file".to_string())
    } else {
        let index = below(rng, own.len());
        (own[index], format!("line {}", index + 1))
    };
    let mut swapped = 0;
    for b in &mut bytes[range.0..range.1] {
        if *b == from {
            *b = to;
            swapped += 1;
        }
    }
    format!(
        "swapped {swapped} delimiters {from:?}→{to:?} in {where_}",
        from = from as char,
        to = to as char
    )
}
