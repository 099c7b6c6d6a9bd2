//! Long tables as labs write them are read without `--format`: unit-suffixed and synonym
//! headers (`Ex (nm)`, `Excitation`, `lambda_ex`, `Intensity`, `Signal`, `RF`, …), tab-
//! and semicolon-separated, decimal commas, quoted headers, a unit row under the header,
//! the columns in another order. Each file is written by the test from a shipped example
//! and must read back equal, cell for cell, to the example read from its wide CSV. Headers
//! that match no layout are refused with a message listing the layouts and `--format`.

use std::path::{Path, PathBuf};

use fluorite::formats::{Format, ReadOptions, detect_format, read, read_bytes};
use fluorite::measurement::Measurement;

fn example() -> (PathBuf, Measurement) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/green-dye.csv");
    let m = read(&path, &ReadOptions::default()).unwrap();
    (path, m)
}

/// How a lab file lays out its columns.
struct Layout {
    name: &'static str,
    separator: &'static str,
    decimal_comma: bool,
    header: &'static str,
    unit_row: Option<&'static str>,
    /// For each column: 'x' excitation, 'm' emission, 'v' value, 's' a sample-name column.
    columns: &'static str,
}

const LAYOUTS: [Layout; 8] = [
    Layout {
        name: "units-in-brackets.csv",
        separator: ",",
        decimal_comma: false,
        header: "Ex (nm),Em (nm),Intensity",
        unit_row: None,
        columns: "xmv",
    },
    Layout {
        name: "tab.txt",
        separator: "\t",
        decimal_comma: false,
        header: "Excitation\tEmission\tSignal",
        unit_row: None,
        columns: "xmv",
    },
    Layout {
        name: "semicolon-decimal-comma.csv",
        separator: ";",
        decimal_comma: true,
        header: "\"lambda_ex\";\"lambda_em\";\"RF\"",
        unit_row: None,
        columns: "xmv",
    },
    Layout {
        name: "unit-row.csv",
        separator: ",",
        decimal_comma: false,
        header: "EX,EM,Counts",
        unit_row: Some("nm,nm,a.u."),
        columns: "xmv",
    },
    Layout {
        name: "emission-first.csv",
        separator: ",",
        decimal_comma: false,
        header: "Em (nm),Ex (nm),value",
        unit_row: None,
        columns: "mxv",
    },
    Layout {
        name: "long-names.tsv",
        separator: "\t",
        decimal_comma: true,
        header: "excitation_wavelength\temission_wavelength\tFluorescence intensity [a.u.]",
        unit_row: Some("unit\tunit\ta.u."),
        columns: "xmv",
    },
    Layout {
        name: "sample-column.csv",
        separator: ";",
        decimal_comma: true,
        header: "Sample;\"Wavelength Ex [nm]\";λem / nm;Value",
        unit_row: None,
        columns: "sxmv",
    },
    Layout {
        name: "value-first.csv",
        separator: ",",
        decimal_comma: false,
        header: "Intensity (counts),Emission,Excitation",
        unit_row: None,
        columns: "vmx",
    },
];

fn number(v: f64, decimal_comma: bool) -> String {
    // Display gives the shortest text that reads back as the same f64.
    let text = format!("{v}");
    if decimal_comma {
        text.replace('.', ",")
    } else {
        text
    }
}

/// `m` written in `layout`, one line per measured cell.
fn write(m: &Measurement, layout: &Layout) -> String {
    let mut out = format!("{}\n", layout.header);
    if let Some(units) = layout.unit_row {
        out.push_str(units);
        out.push('\n');
    }
    for (i, &ex) in m.excitation_nm.iter().enumerate() {
        for (j, &em) in m.emission_nm.iter().enumerate() {
            let v = m.get(i, j);
            if v.is_nan() {
                continue;
            }
            let cells: Vec<String> = layout
                .columns
                .chars()
                .map(|c| match c {
                    'x' => number(ex, layout.decimal_comma),
                    'm' => number(em, layout.decimal_comma),
                    'v' => number(v, layout.decimal_comma),
                    _ => "green dye".to_string(),
                })
                .collect();
            out.push_str(&cells.join(layout.separator));
            out.push('\n');
        }
    }
    out
}

fn assert_same_cells(read: &Measurement, truth: &Measurement, what: &str) {
    assert_eq!(read.excitation_nm, truth.excitation_nm, "{what}");
    assert_eq!(read.emission_nm, truth.emission_nm, "{what}");
    for (k, (a, b)) in read.values.iter().zip(&truth.values).enumerate() {
        assert!(
            a == b || (a.is_nan() && b.is_nan()),
            "{what}: cell {k} reads {a}, the wide CSV {b}"
        );
    }
}

#[test]
fn lab_long_tables_read_like_the_wide_csv() {
    let (_, truth) = example();
    for layout in &LAYOUTS {
        let text = write(&truth, layout);
        let path = Path::new(layout.name);
        assert_eq!(
            detect_format(path, text.as_bytes()),
            Some(Format::Long),
            "{}: {}",
            layout.name,
            layout.header
        );
        let m = read_bytes(text.as_bytes(), path, &ReadOptions::default())
            .unwrap_or_else(|e| panic!("{}: {e}", layout.name));
        assert_same_cells(&m, &truth, layout.name);
        let unit_note = m.notes.iter().find(|n| n.contains("unit row"));
        match layout.unit_row {
            Some(units) => {
                let note = unit_note.unwrap_or_else(|| panic!("{}: {:?}", layout.name, m.notes));
                assert!(
                    note.contains("line 2")
                        && note.contains(units.split(layout.separator).last().unwrap()),
                    "{note}"
                );
            }
            None => assert!(unit_note.is_none(), "{}: {:?}", layout.name, m.notes),
        }
    }
}

#[test]
fn written_files_read_from_disk_too() {
    let (_, truth) = example();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lab.csv");
    std::fs::write(&path, write(&truth, &LAYOUTS[3])).unwrap();
    let m = read(&path, &ReadOptions::default()).unwrap();
    assert_same_cells(&m, &truth, "lab.csv");
}

#[test]
fn a_lone_third_column_holds_the_values_with_a_note() {
    let text = "Ex (nm),Em (nm),Sample 12\n400,400,0.5\n400,450,0.1\n";
    let m = read_bytes(
        text.as_bytes(),
        Path::new("third.csv"),
        &ReadOptions::default(),
    )
    .unwrap();
    assert_eq!(m.values, vec![0.5, 0.1]);
    assert!(
        m.notes
            .iter()
            .any(|n| n.contains("column 3 \"Sample 12\" read as the values")),
        "{:?}",
        m.notes
    );
}

#[test]
fn a_unit_row_under_a_wide_header_is_skipped_with_a_note() {
    let text = "ex\\em,400,450\nunit,a.u.,a.u.\n400,0.5,0.1\n450,0,0.4\n";
    let m = read_bytes(text.as_bytes(), Path::new("w.csv"), &ReadOptions::default()).unwrap();
    assert_eq!(m.values, vec![0.5, 0.1, 0.0, 0.4]);
    assert!(
        m.notes
            .iter()
            .any(|n| n.contains("line 2 \"unit,a.u.,a.u.\" read as a unit row")),
        "{:?}",
        m.notes
    );
}

fn error_of(name: &str, text: &str, options: &ReadOptions) -> String {
    match read_bytes(text.as_bytes(), Path::new(name), options) {
        Ok(m) => panic!("{name} read: {m:?}"),
        Err(e) => e.to_string(),
    }
}

/// A header that matches no layout: the message names the cell, lists every layout and
/// the `--format` option.
#[test]
fn unmatched_headers_list_the_layouts_and_format() {
    let layouts = [
        "--format wide",
        "--format long",
        "--format bfc",
        "--format webfluor",
        "--format exr",
        "Ex (nm),Em (nm),Intensity",
    ];
    let wide = error_of(
        "odd.csv",
        "Wavelength 1,Wavelength 2,I\n400,450,0.1\n",
        &ReadOptions::default(),
    );
    assert!(
        wide.contains("odd.csv:1:2") && wide.contains("\"Wavelength 2\""),
        "{wide}"
    );
    for needle in layouts {
        assert!(wide.contains(needle), "missing {needle:?} in {wide}");
    }
    // Excitation and emission found, but two other columns and neither a value name.
    let long = error_of(
        "two-others.csv",
        "Ex (nm),Em (nm),Sample,Comment\n400,450,a,b\n",
        &ReadOptions::default(),
    );
    assert!(
        long.contains("two-others.csv:1") && long.contains("no value column"),
        "{long}"
    );
    for needle in layouts.iter().chain(&["intensity, signal, counts, RF"]) {
        assert!(long.contains(needle), "missing {needle:?} in {long}");
    }
    // Forced long on a header without an emission column.
    let forced = error_of(
        "forced.csv",
        "Ex (nm),Intensity\n400,0.1\n",
        &ReadOptions {
            format: Some(Format::Long),
            ..ReadOptions::default()
        },
    );
    assert!(
        forced.contains("no emission_nm column") && forced.contains("Em (nm)"),
        "{forced}"
    );
}
