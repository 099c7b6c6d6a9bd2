//! Reading matrices: the real files in ../shared, exact round trips of every layout
//! fluorite writes, one test per kind of bad input, and fuzzing for panics.

use std::path::Path;

use fluorite::Measurement;
use fluorite::formats::{
    Format, ReadOptions, RowsAre, read, read_bytes, write_bfc, write_long_csv, write_wide_csv,
};
use fluorite::measurement::Units;
use fluorite::spectrum::uniform_grid;
use proptest::prelude::*;

use crate::common;

// ---------------------------------------------------------------------------------------
// Helpers

fn defaults() -> ReadOptions {
    ReadOptions::default()
}

/// Value at (excitation nm, emission nm).
fn cell(m: &Measurement, ex: f64, em: f64) -> f64 {
    let i = m
        .excitation_nm
        .iter()
        .position(|&l| l == ex)
        .unwrap_or_else(|| panic!("no excitation {ex} nm"));
    let j = m
        .emission_nm
        .iter()
        .position(|&l| l == em)
        .unwrap_or_else(|| panic!("no emission {em} nm"));
    m.get(i, j)
}

/// Same grids and bit-identical values (NaN where NaN).
fn assert_same_matrix(got: &Measurement, want: &Measurement) {
    assert_eq!(got.excitation_nm, want.excitation_nm, "excitation grid");
    assert_eq!(got.emission_nm, want.emission_nm, "emission grid");
    assert_eq!(got.values.len(), want.values.len());
    for (k, (a, b)) in got.values.iter().zip(&want.values).enumerate() {
        assert!(
            a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()),
            "cell {k}: got {a}, want {b}"
        );
    }
}

/// A synthetic reradiation matrix with a fluorescent band on the Stokes side, a
/// reflectance diagonal, awkward (full-precision) values, negative noise and a few
/// missing cells. Grids as given.
fn synthetic(excitation_nm: Vec<f64>, emission_nm: Vec<f64>) -> Measurement {
    let mut values = Vec::new();
    for (i, &ex) in excitation_nm.iter().enumerate() {
        for (j, &em) in emission_nm.iter().enumerate() {
            let absorption = (-((ex - 420.0) / 40.0f64).powi(2)).exp();
            let emission = (-((em - 560.0) / 35.0f64).powi(2)).exp();
            let noise = 0.003 * ((i * 31 + j * 17) as f64).sin();
            let v = if em == ex {
                0.2 + 0.7 * (em / 900.0)
            } else if em > ex {
                0.3 * absorption * emission + noise
            } else {
                noise
            };
            values.push(v);
        }
    }
    let mut m = Measurement::new(
        "synthetic",
        excitation_nm,
        emission_nm,
        values,
        Units::PerBin,
    )
    .unwrap();
    let n = m.values.len();
    for k in [3, n / 2, n - 2] {
        m.values[k] = f64::NAN;
    }
    m
}

fn bfc_grid() -> Measurement {
    synthetic(
        uniform_grid(300.0, 780.0, 10.0),
        uniform_grid(380.0, 780.0, 10.0),
    )
}

/// Writes `content` into a fresh temp dir as `name` and reads it.
fn read_text(name: &str, content: &[u8], options: &ReadOptions) -> fluorite::Result<Measurement> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, content).unwrap();
    read(&path, options)
}

fn error_of(name: &str, content: &str) -> String {
    match read_text(name, content.as_bytes(), &defaults()) {
        Ok(m) => panic!("{name} read without error: {m:?}"),
        Err(e) => e.to_string(),
    }
}

fn assert_mentions(message: &str, parts: &[&str]) {
    for part in parts {
        assert!(message.contains(part), "message lacks {part:?}:\n{message}");
    }
}

/// A WebFluor file as the database writes it: emission header, rows from long to short
/// excitation wavelengths, blank lines between rows, `\r\r\n` line ends, 0 = missing.
fn webfluor_text(m: &Measurement) -> String {
    let mut out = String::new();
    let header: Vec<String> = m.emission_nm.iter().map(|l| l.to_string()).collect();
    out.push_str(&header.join(" "));
    out.push_str("\r\r\n");
    for i in (0..m.n_excitation()).rev() {
        out.push_str("\r\r\n");
        out.push_str(&m.excitation_nm[i].to_string());
        for j in 0..m.n_emission() {
            let v = m.get(i, j);
            out.push(' ');
            out.push_str(&if v.is_nan() {
                "0".to_string()
            } else {
                format!("{v:?}")
            });
        }
        out.push_str("\r\r\n");
    }
    out
}

// ---------------------------------------------------------------------------------------
// Real files

#[test]
fn bfc_files_read_with_their_grid() {
    let Some(data) = common::shared("") else {
        return;
    };
    let excitation = uniform_grid(300.0, 780.0, 10.0);
    let emission = uniform_grid(380.0, 780.0, 10.0);
    for name in ["CIBA12", "HERPICER", "TEXTYELL", "POLGREE"] {
        let path = data.join("measured").join(format!("{name}.BFC"));
        let m = read(&path, &defaults()).unwrap();
        assert_eq!(m.name, name);
        assert_eq!(m.excitation_nm, excitation, "{name}");
        assert_eq!(m.emission_nm, emission, "{name}");
        assert_eq!(m.values.len(), 49 * 41);
        assert!(
            m.values.iter().all(|v| v.is_finite()),
            "{name}: no missing cells"
        );
        assert!(m.has_diagonal && !m.arbitrary_scale);
        assert_eq!(m.diagonal().len(), 41);
        assert_eq!(m.units, Units::PerBin);
        assert_eq!(m.source.as_deref(), Some(path.as_path()));
        assert!(m.notes.is_empty(), "{name}: {:?}", m.notes);
    }
    let m = read(&data.join("measured/HERPICER.BFC"), &defaults()).unwrap();
    // Cells as printed in the file (rows are emission there).
    assert_eq!(cell(&m, 380.0, 380.0), 0.0902205);
    assert_eq!(cell(&m, 300.0, 380.0), -0.00447876);
    assert_eq!(cell(&m, 300.0, 390.0), -0.00405812);
    assert_eq!(cell(&m, 550.0, 610.0), 0.0716182);
    assert_eq!(cell(&m, 780.0, 780.0), 0.955144);
    // Provenance: the digest of the bytes, as `sha256sum` prints it.
    assert_eq!(
        m.source_sha256.as_deref(),
        Some("777b48818a8fdeb0ed0e0ba232047844cbed6215bf27007f879d1e92d9645f88")
    );
    // --per-nm only changes the units.
    let per_nm = ReadOptions {
        per_nm: true,
        ..defaults()
    };
    let d = read(&data.join("measured/HERPICER.BFC"), &per_nm).unwrap();
    assert_eq!(d.units, Units::PerNm);
    assert_same_matrix(&d, &m);
}

#[test]
fn every_shared_matrix_reads() {
    let Some(data) = common::shared("") else {
        return;
    };
    let mut count = 0;
    for dir in ["measured", "eem"] {
        for entry in std::fs::read_dir(data.join(dir)).unwrap() {
            let path = entry.unwrap().path();
            let stem = path.file_stem().unwrap().to_string_lossy().into_owned();
            // The post-it folders carry a description beside each matrix.
            if stem.ends_with("_meta") {
                continue;
            }
            let m = read(&path, &defaults()).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(m.name, stem);
            assert!(m.values.iter().any(|v| v.is_finite()));
            count += 1;
        }
    }
    assert_eq!(count, 10, "4 BFC + 2 CSV + 4 WebFluor files");
}

#[test]
fn postit_csvs_are_transposed_from_emission_rows() {
    let Some(data) = common::shared("") else {
        return;
    };
    let excitation = uniform_grid(300.0, 780.0, 10.0);
    let emission = uniform_grid(380.0, 780.0, 10.0);
    for name in ["postit_yellow", "postit_pink"] {
        let m = read(&data.join(format!("measured/{name}.csv")), &defaults()).unwrap();
        assert_eq!(m.excitation_nm, excitation, "{name}");
        assert_eq!(m.emission_nm, emission, "{name}");
        assert!(m.values.iter().all(|v| v.is_finite()));
        assert!(
            m.notes.is_empty(),
            "corner label em_nm\\ex_nm needs no inference"
        );
        assert_eq!(m.diagonal().len(), 41);
    }
    let yellow = read(&data.join("measured/postit_yellow.csv"), &defaults()).unwrap();
    // File row 390 (emission), first column 300 (excitation).
    assert_eq!(cell(&yellow, 300.0, 390.0), 0.000303509);
    assert_eq!(cell(&yellow, 310.0, 380.0), -8.31e-05);
    assert_eq!(cell(&yellow, 380.0, 380.0), 0.251802);
    assert_eq!(cell(&yellow, 450.0, 550.0), 0.0157527);
    let pink = read(&data.join("measured/postit_pink.csv"), &defaults()).unwrap();
    assert_eq!(cell(&pink, 520.0, 600.0), 0.0352371);
    assert_eq!(cell(&pink, 300.0, 520.0), -0.00113611);
}

#[test]
fn webfluor_eems_sort_rows_and_mask_zeros() {
    let Some(data) = common::shared("") else {
        return;
    };
    let excitation = uniform_grid(250.0, 520.0, 10.0);
    let emission = uniform_grid(260.0, 750.0, 5.0);
    for name in ["FAD", "NADH", "collagen1", "tryptophan"] {
        let m = read(&data.join(format!("eem/{name}.txt")), &defaults()).unwrap();
        assert_eq!(m.excitation_nm, excitation, "{name}: ascending excitation");
        assert_eq!(m.emission_nm, emission, "{name}");
        assert!(!m.has_diagonal && m.arbitrary_scale, "{name}");
        assert!(m.diagonal().is_empty());
        assert!(
            m.values.iter().all(|&v| v.is_nan() || v != 0.0),
            "{name}: zeros masked"
        );
        assert!(m.values.iter().any(|v| v.is_nan()) && m.values.iter().any(|v| v > &0.0));
        assert!(
            m.notes.iter().any(|n| n.contains("read as missing")),
            "{name}: {:?}",
            m.notes
        );
    }
    let fad = read(&data.join("eem/FAD.txt"), &defaults()).unwrap();
    assert_eq!(cell(&fad, 520.0, 530.0), 25250.0);
    assert_eq!(cell(&fad, 450.0, 460.0), 33064.0);
    assert_eq!(cell(&fad, 250.0, 260.0), 10.0);
    assert!(cell(&fad, 520.0, 260.0).is_nan(), "0 = not measured");
    let collagen = read(&data.join("eem/collagen1.txt"), &defaults()).unwrap();
    assert_eq!(cell(&collagen, 450.0, 460.0), 2.19e5);
    // Zeros kept on request.
    let keep = ReadOptions {
        zero_is_missing: Some(false),
        ..defaults()
    };
    let fad_zeros = read(&data.join("eem/FAD.txt"), &keep).unwrap();
    assert_eq!(cell(&fad_zeros, 520.0, 260.0), 0.0);
    assert!(fad_zeros.values.iter().all(|v| v.is_finite()));
    assert!(fad_zeros.notes.is_empty());
}

// ---------------------------------------------------------------------------------------
// Round trips

#[test]
fn wide_csv_round_trips_in_both_orientations() {
    let m = bfc_grid();
    for rows in [RowsAre::Excitation, RowsAre::Emission] {
        let text = write_wide_csv(&m, rows);
        let back = read_text("w.csv", text.as_bytes(), &defaults()).unwrap();
        assert_same_matrix(&back, &m);
        assert!(back.notes.is_empty(), "{:?}", back.notes);
        assert_eq!(back.name, "w");
    }
}

#[test]
fn wide_csv_without_corner_label_infers_orientation_and_says_so() {
    let m = bfc_grid();
    for (rows, word) in [
        (RowsAre::Excitation, "excitation"),
        (RowsAre::Emission, "emission"),
    ] {
        for corner in ["", "wavelength_nm"] {
            let text = write_wide_csv(&m, rows);
            let (_, rest) = text.split_once(',').unwrap();
            let text = format!("{corner},{rest}");
            let back = read_text("nolabel.csv", text.as_bytes(), &defaults()).unwrap();
            assert_same_matrix(&back, &m);
            assert_eq!(back.notes.len(), 1, "{:?}", back.notes);
            let note = &back.notes[0];
            assert_mentions(note, &[&format!("rows read as {word}"), "--rows"]);
            // The explicit option silences the inference.
            let forced = ReadOptions {
                rows: Some(rows),
                ..defaults()
            };
            let back = read_text("nolabel.csv", text.as_bytes(), &forced).unwrap();
            assert_same_matrix(&back, &m);
            assert!(back.notes.is_empty());
        }
    }
}

#[test]
fn wide_csv_without_corner_cell_at_all() {
    // Header of bare wavelengths: rows one cell longer than the header.
    let m = synthetic(
        uniform_grid(400.0, 500.0, 20.0),
        uniform_grid(400.0, 600.0, 20.0),
    );
    let text = write_wide_csv(&m, RowsAre::Excitation);
    let (_, rest) = text.split_once(',').unwrap();
    let back = read_text("bare.csv", rest.as_bytes(), &defaults()).unwrap();
    assert_same_matrix(&back, &m);
    assert_mentions(&back.notes[0], &["no corner label", "--rows emission"]);
}

#[test]
fn rows_option_overrides_corner_label() {
    let m = bfc_grid();
    // Written with excitation rows but labelled as emission rows: the option wins.
    let text = write_wide_csv(&m, RowsAre::Excitation).replacen("ex_nm\\em_nm", "em\\ex", 1);
    let forced = ReadOptions {
        rows: Some(RowsAre::Excitation),
        ..defaults()
    };
    let back = read_text("x.csv", text.as_bytes(), &forced).unwrap();
    assert_same_matrix(&back, &m);
    assert_mentions(&back.notes[0], &["corner label", "--rows excitation"]);
    // Without the option the label is believed, so the matrix comes out transposed.
    let believed = read_text("x.csv", text.as_bytes(), &defaults()).unwrap();
    assert_eq!(believed.excitation_nm, m.emission_nm);
    assert_eq!(
        cell(&believed, 380.0, 300.0).to_bits(),
        cell(&m, 300.0, 380.0).to_bits()
    );
}

#[test]
fn corner_label_spellings() {
    let m = synthetic(vec![400.0, 450.0], vec![400.0, 450.0, 500.0]);
    for (label, rows) in [
        ("ex\\em", RowsAre::Excitation),
        ("excitation\\emission", RowsAre::Excitation),
        ("ex_nm/em_nm", RowsAre::Excitation),
        ("em\\ex", RowsAre::Emission),
        ("em_nm\\ex_nm", RowsAre::Emission),
        ("emission/excitation", RowsAre::Emission),
    ] {
        let text = write_wide_csv(&m, rows);
        let (_, rest) = text.split_once(',').unwrap();
        let back = read_text("c.csv", format!("{label},{rest}").as_bytes(), &defaults()).unwrap();
        assert_same_matrix(&back, &m);
        assert!(back.notes.is_empty(), "{label}: {:?}", back.notes);
    }
}

#[test]
fn semicolons_tabs_quotes_decimal_commas_and_missing_markers() {
    let want = Measurement::new(
        "t",
        vec![400.0, 450.0],
        vec![400.0, 500.0, 550.5],
        vec![0.5, f64::NAN, 0.25, f64::NAN, f64::NAN, -0.125],
        Units::PerBin,
    )
    .unwrap();
    let files = [
        "ex\\em;400;500;550,5\n400;0,5;;0,25\n450;NA;nan;-0,125\n",
        "ex\\em\t400\t500\t550.5\t\r\n400\t0.5\tNaN\t0.25\t\r\n450\t\tna\t-1.25e-1\t\r\n",
        "\"ex\\em\",\"400\",\"500\",\"550.5\"\n\"400\",\"0.5\",\"\",\"0.25\"\n\"450\",\"NA\",\"NaN\",\"-0.125\"\n",
        "# comment line\n\nex\\em,400,500,550.5\n400,0.5,,0.25,\n\n450,,,-0.125,\n",
        "ex\\em 400 500 550.5\n400 0.5 NaN 0.25\n450 NA NaN -0.125\n",
    ];
    for text in files {
        let m = read_text("t.csv", text.as_bytes(), &defaults())
            .unwrap_or_else(|e| panic!("{text:?}: {e}"));
        assert_same_matrix(&m, &want);
    }
    // Latin-1 bytes in a corner label do not stop the reader.
    let latin1 = b"ex\\em \xb5\xe9,400,500\n400,0.5,0.1\n";
    let m = read_text("l.csv", latin1, &defaults()).unwrap();
    assert_eq!(m.values, vec![0.5, 0.1]);
}

#[test]
fn long_csv_round_trips_in_any_order() {
    let m = synthetic(
        uniform_grid(300.0, 500.0, 25.0),
        vec![380.0, 400.0, 455.5, 600.0],
    );
    let text = write_long_csv(&m);
    let back = read_text("long.csv", text.as_bytes(), &defaults()).unwrap();
    assert_same_matrix(&back, &m);
    // Columns permuted, an extra column, lines reversed, missing cells left out.
    let mut lines: Vec<String> = Vec::new();
    for (i, &ex) in m.excitation_nm.iter().enumerate() {
        for (j, &em) in m.emission_nm.iter().enumerate() {
            let v = m.get(i, j);
            if !v.is_nan() {
                lines.push(format!("{v:?};note;{em};{ex}"));
            }
        }
    }
    lines.reverse();
    let text = format!(
        "value;comment;emission_nm;excitation_nm\n{}\n",
        lines.join("\n")
    );
    let back = read_text("long2.txt", text.as_bytes(), &defaults()).unwrap();
    assert_same_matrix(&back, &m);
}

#[test]
fn bfc_layout_round_trips() {
    let m = bfc_grid();
    let text = write_bfc(&m).unwrap();
    assert!(text.contains("380\t780\t10\t49\t300\t10\r\n"), "grid line");
    let back = read_text("round.BFC", text.as_bytes(), &defaults()).unwrap();
    assert_same_matrix(&back, &m);
    // Detected by content whatever the extension.
    let back = read_text("round.txt", text.as_bytes(), &defaults()).unwrap();
    assert_same_matrix(&back, &m);
    // Non-uniform grids cannot be written as BFC-450.
    let uneven = synthetic(vec![300.0, 310.0, 330.0], vec![380.0, 390.0]);
    let err = write_bfc(&uneven).unwrap_err().to_string();
    assert_mentions(&err, &["excitation_nm", "not uniform", "wide CSV"]);
}

#[test]
fn webfluor_layout_round_trips() {
    let m = synthetic(
        uniform_grid(250.0, 400.0, 10.0),
        uniform_grid(260.0, 500.0, 5.0),
    );
    assert!(m.values.iter().all(|&v| v != 0.0));
    let back = read_text("eem.txt", webfluor_text(&m).as_bytes(), &defaults()).unwrap();
    assert_eq!(back.excitation_nm, m.excitation_nm, "rows sorted ascending");
    assert_same_matrix(&back, &m);
    assert!(!back.has_diagonal && back.arbitrary_scale);
}

#[test]
fn non_uniform_and_different_grids() {
    let m = synthetic(
        vec![300.0, 305.0, 330.0, 400.0],
        vec![310.0, 320.0, 400.0, 401.5],
    );
    for rows in [RowsAre::Excitation, RowsAre::Emission] {
        let back = read_text("n.csv", write_wide_csv(&m, rows).as_bytes(), &defaults()).unwrap();
        assert_same_matrix(&back, &m);
    }
}

#[test]
fn format_can_be_forced() {
    let m = synthetic(vec![400.0, 450.0], vec![400.0, 500.0]);
    let text = write_wide_csv(&m, RowsAre::Excitation);
    let as_long = ReadOptions {
        format: Some(Format::Long),
        ..defaults()
    };
    let err = read_text("w.csv", text.as_bytes(), &as_long)
        .unwrap_err()
        .to_string();
    assert_mentions(&err, &["w.csv:1", "no excitation_nm column"]);
    let as_wide = ReadOptions {
        format: Some(Format::Wide),
        ..defaults()
    };
    assert_same_matrix(&read_text("w.dat", text.as_bytes(), &as_wide).unwrap(), &m);
    // Zeros can be masked in any format.
    let zeros = "ex\\em,400,500\n400,0,0.5\n";
    let masked = ReadOptions {
        zero_is_missing: Some(true),
        ..defaults()
    };
    let m = read_text("z.csv", zeros.as_bytes(), &masked).unwrap();
    assert!(m.values[0].is_nan() && m.values[1] == 0.5);
}

// ---------------------------------------------------------------------------------------
// Bad input: one test per case, each checking file, position and problem.

#[test]
fn empty_file() {
    let err = error_of("empty.csv", "");
    assert_mentions(
        &err,
        &["empty.csv", "empty", "expected a reradiation matrix"],
    );
    let err = error_of("blank.BFC", "\r\n  \r\n\t\n");
    assert_mentions(&err, &["blank.BFC", "only blank lines"]);
}

#[test]
fn missing_file() {
    let err = read(Path::new("/nonexistent/dir/m.csv"), &defaults())
        .unwrap_err()
        .to_string();
    assert_mentions(&err, &["/nonexistent/dir/m.csv", "No such file"]);
}

#[test]
fn truncated_bfc_without_eod() {
    let text = write_bfc(&bfc_grid()).unwrap();
    // Cut in the middle of a row.
    let cut = &text[..text.len() / 2];
    let err = error_of("cut.BFC", cut);
    assert_mentions(&err, &["cut.BFC:", "middle of a row", "truncated", "EOD"]);
    // Cut after a whole row.
    let rows: Vec<&str> = text.split("\r\n").take(30).collect();
    let err = error_of("cut.BFC", &rows.join("\r\n"));
    assert_mentions(
        &err,
        &[
            "cut.BFC:30",
            "without the EOD line",
            "after 18 of the 41 emission rows",
            "truncated",
        ],
    );
    // Cut in the middle of the header.
    let err = error_of(
        "head.BFC",
        "VEC_01\t5167\r\nBFC-450 Matrix File\r\n;name\r\n",
    );
    assert_mentions(&err, &["head.BFC:3", "truncated", "grid line"]);
}

#[test]
fn truncated_bfc_with_fewer_rows_than_its_grid_line() {
    let text = write_bfc(&bfc_grid()).unwrap();
    let lines: Vec<&str> = text.split("\r\n").collect();
    // Drop the last five emission rows, keep EOD.
    let eod = lines.iter().position(|&l| l == "EOD").unwrap();
    let kept = [&lines[..eod - 5], &lines[eod..]].concat().join("\r\n");
    let err = error_of("short.BFC", &kept);
    assert_mentions(
        &err,
        &[
            &format!("short.BFC:{}", eod - 4),
            "after 36 emission rows",
            "announces 41",
            "truncated",
        ],
    );
}

#[test]
fn bfc_grid_line_problems() {
    let text = write_bfc(&bfc_grid()).unwrap();
    let err = error_of(
        "g.BFC",
        &text.replace("380\t780\t10\t49\t300\t10", "380\t780\tten\t49\t300\t10"),
    );
    assert_mentions(&err, &["g.BFC:11:3", "em_step", "\"ten\""]);
    let err = error_of(
        "g.BFC",
        &text.replace("380\t780\t10\t49\t300\t10", "380\t780\t10\t48\t300\t10"),
    );
    assert_mentions(
        &err,
        &["g.BFC:12", "49 excitation wavelengths", "n_ex = 48"],
    );
    let err = error_of(
        "g.BFC",
        &text.replace("380\t780\t10\t49\t300\t10", "380 780"),
    );
    assert_mentions(&err, &["g.BFC:11", "2 fields, expected 6"]);
    let err = error_of("g.BFC", &text.replace("r:c:", "x:y:"));
    assert_mentions(&err, &["g.BFC:12:1", "r:c:"]);
    let err = error_of(
        "g.txt",
        &text
            .replace("BFC-450 Matrix File", "Some Other File")
            .replace("VEC", "\"VEC"),
    );
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn wide_csv_header_without_rows() {
    let err = error_of("head.csv", "ex\\em,400,410,420\n\n");
    assert_mentions(&err, &["head.csv:1", "no data rows", "truncated"]);
}

#[test]
fn ragged_rows() {
    let err = error_of(
        "ragged.csv",
        "ex\\em,400,410,420\n400,0.1,0.2,0.3\n410,0.1,0.2\n",
    );
    assert_mentions(
        &err,
        &["ragged.csv:3:4", "ragged row", "3 cells", "needs 4 cells"],
    );
    let err = error_of("long_row.csv", "ex\\em,400,410\n400,0.1,0.2,0.3\n");
    assert_mentions(&err, &["long_row.csv:2:4", "4 cells", "needs 3"]);
    let err = error_of("r.txt", "400 410 420\n300 1 2 3\n310 1 2\n");
    assert_mentions(&err, &["r.txt:3:4", "ragged"]);
    let err = error_of(
        "l.csv",
        "excitation_nm,emission_nm,value\n400,500,0.1\n400,510\n",
    );
    assert_mentions(&err, &["l.csv:3:3", "ragged", "3 columns"]);
    let text = write_bfc(&bfc_grid()).unwrap();
    let lines: Vec<&str> = text.split("\r\n").collect();
    let row: Vec<&str> = lines[13].split('\t').collect();
    let short = row[..row.len() - 1].join("\t");
    let err = error_of("r.BFC", &text.replacen(lines[13], &short, 1));
    assert_mentions(&err, &["r.BFC:14:50", "49 cells", "needs 50"]);
}

#[test]
fn non_numeric_cells_are_quoted() {
    let err = error_of("text.csv", "ex\\em,400,410\n400,0.1,abc\n");
    assert_mentions(&err, &["text.csv:2:3", "\"abc\"", "not a number"]);
    let err = error_of("wl.csv", "ex\\em,400,4l0\n400,0.1,0.2\n");
    assert_mentions(&err, &["wl.csv:1:3", "\"4l0\"", "column wavelength"]);
    let err = error_of("row.csv", "ex\\em,400,410\nfour,0.1,0.2\n");
    assert_mentions(&err, &["row.csv:2:1", "\"four\"", "row wavelength"]);
    let err = error_of("l.csv", "emission_nm,excitation_nm,value\n500,400,1..2\n");
    assert_mentions(&err, &["l.csv:2:3", "\"1..2\""]);
    let err = error_of("w.txt", "400 410\n300 1 x\n");
    assert_mentions(&err, &["w.txt:2:3", "\"x\""]);
}

#[test]
fn duplicate_wavelengths_are_named() {
    let err = error_of("dup.csv", "ex\\em,400,410,400\n400,0.1,0.2,0.3\n");
    assert_mentions(
        &err,
        &[
            "dup.csv:1:4",
            "duplicate column wavelength 400 nm",
            "column 2",
        ],
    );
    let err = error_of("duprow.csv", "ex\\em,400,410\n400,0.1,0.2\n400,0.1,0.2\n");
    assert_mentions(
        &err,
        &[
            "duprow.csv:3:1",
            "duplicate row wavelength 400 nm",
            "line 2",
        ],
    );
    let err = error_of("dup.txt", "400 410\n300 1 2\n\n300 1 2\n");
    assert_mentions(
        &err,
        &[
            "dup.txt:4:1",
            "duplicate excitation wavelength 300 nm",
            "line 2",
        ],
    );
    let err = error_of(
        "dup_long.csv",
        "excitation_nm,emission_nm,value\n400,500,1\n410,500,1\n400,500,2\n",
    );
    assert_mentions(
        &err,
        &[
            "dup_long.csv:4",
            "excitation 400 nm, emission 500 nm",
            "line 2",
        ],
    );
}

#[test]
fn unsorted_wavelengths_are_named() {
    let err = error_of("unsorted.csv", "ex\\em,400,420,410\n400,0.1,0.2,0.3\n");
    assert_mentions(
        &err,
        &[
            "unsorted.csv:1:4",
            "410 nm comes after 420 nm",
            "column 3",
            "increasing",
        ],
    );
    let err = error_of("rows.csv", "ex\\em,400,410\n410,0.1,0.2\n400,0.1,0.2\n");
    assert_mentions(
        &err,
        &["rows.csv:3:1", "400 nm comes after 410 nm", "line 2"],
    );
    let err = error_of("eem.txt", "260 255\n300 1 2\n");
    assert_mentions(&err, &["eem.txt:1:2", "unsorted emission wavelengths"]);
}

#[test]
fn non_positive_wavelengths() {
    let err = error_of("neg.csv", "ex\\em,-400,410\n400,0.1,0.2\n");
    assert_mentions(&err, &["neg.csv:1:2", "-400 nm is not positive"]);
    let err = error_of("zero.csv", "excitation_nm,emission_nm,value\n0,500,1\n");
    assert_mentions(&err, &["zero.csv:2:1", "0 nm is not positive"]);
    let err = error_of("empty_wl.csv", "ex\\em,400,410\n,0.1,0.2\n");
    assert_mentions(&err, &["empty_wl.csv:2:1", "row wavelength is missing"]);
}

#[test]
fn grid_without_usable_cell() {
    let err = error_of("nan.csv", "ex\\em,400,410\n400,NaN,\n410,NA,nan\n");
    assert_mentions(&err, &["nan.csv", "no usable cell", "all 4 cells"]);
    let err = error_of("zeros.txt", "400 410\n300 0 0\n");
    assert_mentions(
        &err,
        &["zeros.txt", "no usable cell", "zeros count as missing"],
    );
}

#[test]
fn infinities_are_rejected() {
    for (cell, col) in [("inf", 3), ("-Infinity", 3), ("1e999", 3)] {
        let err = error_of("inf.csv", &format!("ex\\em,400,410\n400,0.1,{cell}\n"));
        assert_mentions(&err, &[&format!("inf.csv:2:{col}"), "infinite", "NaN"]);
    }
    let err = error_of("infwl.csv", "ex\\em,400,inf\n400,0.1,0.2\n");
    assert_mentions(&err, &["infwl.csv:1:3", "infinite"]);
    let err = error_of("inf.txt", "400 410\n300 1 inf\n");
    assert_mentions(&err, &["inf.txt:2:3", "infinite"]);
}

#[test]
fn unknown_format() {
    let err = error_of("notes.dat", "hello\nworld\n");
    assert_mentions(&err, &["notes.dat", "unknown format", "--format"]);
    let err = match read_text("blob.bin", &[0u8, 159, 146, 150, 0, 1, 2], &defaults()) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("binary read"),
    };
    assert_mentions(&err, &["blob.bin", "unknown format"]);
}

#[test]
fn long_csv_without_value_column() {
    // `signal` names the values; `sample` and `comment` name nothing fluorite reads.
    let err = error_of(
        "l.csv",
        "excitation_nm,emission_nm,sample,comment\n400,500,a,b\n",
    );
    assert_mentions(&err, &["l.csv:1", "no value column"]);
}

#[test]
fn read_bytes_names_the_given_path() {
    let err = read_bytes(
        b"ex\\em,400\n400,x\n",
        Path::new("mem/virtual.csv"),
        &defaults(),
    )
    .unwrap_err()
    .to_string();
    assert_mentions(&err, &["mem/virtual.csv:2:2", "\"x\""]);
}

// ---------------------------------------------------------------------------------------
// Fuzzing: any input gives Ok or Err, never a panic, and Ok is always a valid matrix.

fn check_no_panic(bytes: &[u8], name: &str) {
    let path = Path::new(name);
    let mut options = vec![defaults()];
    for format in [Format::Wide, Format::Long, Format::Bfc, Format::Webfluor] {
        options.push(ReadOptions {
            format: Some(format),
            rows: Some(RowsAre::Emission),
            zero_is_missing: Some(true),
            per_nm: true,
        });
    }
    for o in &options {
        if let Ok(m) = read_bytes(bytes, path, o) {
            m.validate().expect("a matrix read without error is valid");
            assert_eq!(m.values.len(), m.n_excitation() * m.n_emission());
        }
    }
}

fn valid_files() -> Vec<(String, &'static str)> {
    let m = synthetic(
        uniform_grid(300.0, 360.0, 10.0),
        uniform_grid(320.0, 380.0, 10.0),
    );
    vec![
        (write_bfc(&m).unwrap(), "f.BFC"),
        (write_wide_csv(&m, RowsAre::Emission), "f.csv"),
        (write_long_csv(&m), "f.csv"),
        (webfluor_text(&m), "f.txt"),
    ]
}

#[derive(Debug, Clone)]
enum Mutation {
    Delete(usize, usize),
    Insert(usize, Vec<u8>),
    Replace(usize, u8),
    Truncate(usize),
    DuplicateSpan(usize, usize),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let special = prop::sample::select(vec![
        b',', b';', b'\t', b'\n', b'\r', b' ', b'"', b'-', b'.', b'e', b'0', b'9', b'\\', 0xff,
    ]);
    prop_oneof![
        (any::<usize>(), 1usize..40).prop_map(|(at, n)| Mutation::Delete(at, n)),
        (any::<usize>(), prop::collection::vec(any::<u8>(), 1..8))
            .prop_map(|(at, b)| Mutation::Insert(at, b)),
        (any::<usize>(), special).prop_map(|(at, b)| Mutation::Replace(at, b)),
        any::<usize>().prop_map(Mutation::Truncate),
        (any::<usize>(), 1usize..200).prop_map(|(at, n)| Mutation::DuplicateSpan(at, n)),
    ]
}

fn apply(bytes: &mut Vec<u8>, m: &Mutation) {
    let len = bytes.len().max(1);
    match m {
        Mutation::Delete(at, n) => {
            let at = at % len;
            let end = (at + n).min(bytes.len());
            if at < end {
                bytes.drain(at..end);
            }
        }
        Mutation::Insert(at, b) => {
            let at = at % (bytes.len() + 1);
            bytes.splice(at..at, b.iter().copied());
        }
        Mutation::Replace(at, b) => {
            if !bytes.is_empty() {
                let at = at % bytes.len();
                bytes[at] = *b;
            }
        }
        Mutation::Truncate(at) => bytes.truncate(at % len),
        Mutation::DuplicateSpan(at, n) => {
            let at = at % len;
            let end = (at + n).min(bytes.len());
            if at < end {
                let span = bytes[at..end].to_vec();
                bytes.splice(end..end, span);
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        check_no_panic(&bytes, "fuzz.csv");
        check_no_panic(&bytes, "fuzz.BFC");
    }

    #[test]
    fn random_text_never_panics(text in "[0-9a-zA-Z,;\\t \\r\\n.\\-+\"\\\\:]{0,400}") {
        check_no_panic(text.as_bytes(), "fuzz.txt");
    }

    #[test]
    fn mutated_valid_files_never_panic(
        which in 0usize..4,
        mutations in prop::collection::vec(mutation(), 1..6),
    ) {
        let (text, name) = &valid_files()[which];
        let mut bytes = text.as_bytes().to_vec();
        for m in &mutations {
            apply(&mut bytes, m);
        }
        check_no_panic(&bytes, name);
    }
}
