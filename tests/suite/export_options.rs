//! The library refuses export options the format does not use, naming the
//! `fluorite export` flag, whoever calls it (not only the command line).

use fluorite::Units;
use fluorite::colour::Light;
use fluorite::export::{ExportFormat, ExportOptions, RgbSpace, export_with_notes};
use fluorite::material::Material;
use fluorite::synth::SynthSpec;

fn one_dye() -> Material {
    SynthSpec::preset("green-dye").unwrap().truth().unwrap()
}

fn two_dyes() -> Material {
    SynthSpec::preset("two-dyes").unwrap().truth().unwrap()
}

fn light(name: &str) -> Light {
    Light::builtin(name).unwrap()
}

/// The error of exporting `material` with `options`; panics if the export succeeds.
fn refusal(material: &Material, options: &ExportOptions) -> String {
    match export_with_notes(material, options) {
        Ok(_) => panic!("{:?} was exported with {options:?}", options.format),
        Err(e) => e.to_string(),
    }
}

/// Asserts that the one-dye material's export with `options` is refused by a message
/// starting with `start` and ending with the format's name.
fn assert_refused_for_the_format(options: &ExportOptions, start: &str) {
    let e = refusal(&one_dye(), options);
    assert!(
        e.starts_with(start) && e.ends_with(&format!("not to {}", options.format.name())),
        "{e}"
    );
}

const ALL: [ExportFormat; 9] = [
    ExportFormat::Csv,
    ExportFormat::Matrix,
    ExportFormat::Bfc,
    ExportFormat::Mitsuba,
    ExportFormat::Pbrt,
    ExportFormat::Pearray,
    ExportFormat::Art,
    ExportFormat::Exr,
    ExportFormat::Rgb,
];

#[test]
fn defaults_export_in_every_format() {
    for material in [one_dye(), two_dyes()] {
        for format in ALL {
            let exported = export_with_notes(&material, &ExportOptions::new(format));
            assert!(exported.is_ok(), "{format:?}: {:?}", exported.err());
        }
    }
}

#[test]
fn grids_and_per_nm_are_refused_without_a_matrix() {
    let grid: Vec<f64> = (0..=24).map(|i| 300.0 + 20.0 * i as f64).collect();
    let with_grids = |format| ExportOptions {
        excitation_nm: Some(grid.clone()),
        ..ExportOptions::new(format)
    };
    let emission_only = |format| ExportOptions {
        emission_nm: Some(grid.clone()),
        ..ExportOptions::new(format)
    };
    let per_nm = |format| ExportOptions {
        units: Units::PerNm,
        ..ExportOptions::new(format)
    };
    for format in [ExportFormat::Csv, ExportFormat::Pearray, ExportFormat::Rgb] {
        for options in [with_grids(format), emission_only(format), per_nm(format)] {
            assert_refused_for_the_format(&options, "--grid/--per-nm: apply to the matrix formats");
        }
    }
    // Mitsuba writes the matrix only beside the fork's one-fluorophore scene.
    for options in [
        with_grids(ExportFormat::Mitsuba),
        per_nm(ExportFormat::Mitsuba),
    ] {
        let e = refusal(&one_dye(), &options);
        assert!(
            e.starts_with("--grid/--per-nm:") && e.contains("fewer than two fluorophores"),
            "{e}"
        );
        assert!(export_with_notes(&two_dyes(), &options).is_ok());
    }
    for format in [ExportFormat::Matrix, ExportFormat::Bfc, ExportFormat::Pbrt] {
        assert!(export_with_notes(&one_dye(), &with_grids(format)).is_ok());
        assert!(export_with_notes(&one_dye(), &per_nm(format)).is_ok());
    }
}

#[test]
fn per_nm_is_refused_by_the_per_bin_layouts() {
    let per_nm = |format| ExportOptions {
        units: Units::PerNm,
        ..ExportOptions::new(format)
    };
    let e = refusal(&one_dye(), &per_nm(ExportFormat::Exr));
    assert!(e.starts_with("--per-nm: does not apply to exr"), "{e}");
    let e = refusal(&one_dye(), &per_nm(ExportFormat::Art));
    assert!(
        e.starts_with("--per-nm: ART archives hold radiance factors per emission bin"),
        "{e}"
    );
}

#[test]
fn lights_are_refused_where_nothing_is_lit() {
    for format in ALL.into_iter().filter(|f| !f.uses_lights()) {
        let options = ExportOptions {
            lights: vec![light("a")],
            ..ExportOptions::new(format)
        };
        assert_refused_for_the_format(
            &options,
            "--light: applies to mitsuba, pbrt, pearray and rgb",
        );
    }
    // Explicit D65, the default, is still an option the format would ignore.
    let options = ExportOptions {
        lights: vec![light("d65")],
        ..ExportOptions::new(ExportFormat::Csv)
    };
    assert!(refusal(&one_dye(), &options).starts_with("--light:"));
}

#[test]
fn a_light_given_twice_is_refused() {
    for format in ALL.into_iter().filter(|f| f.uses_lights()) {
        let options = ExportOptions {
            lights: vec![light("d65"), light("a"), light("D65")],
            ..ExportOptions::new(format)
        };
        let e = refusal(&one_dye(), &options);
        assert!(e.starts_with("--light: names d65 twice"), "{e}");
    }
}

#[test]
fn a_colour_space_is_refused_without_the_rgb_reduction() {
    for format in ALL.into_iter().filter(|&f| f != ExportFormat::Rgb) {
        let options = ExportOptions {
            space: Some(RgbSpace::Xyz),
            ..ExportOptions::new(format)
        };
        assert_refused_for_the_format(&options, "--space: applies to the rgb reduction");
    }
}

#[test]
fn unusable_grids_are_refused_naming_the_grid() {
    type Grid = Option<Vec<f64>>;
    let cases: [(Grid, Grid, &str); 4] = [
        (Some(vec![]), None, "--excitation-grid: is empty"),
        (None, Some(vec![]), "--emission-grid: is empty"),
        (Some(vec![400.0, 300.0]), None, "--excitation-grid[1]"),
        (None, Some(vec![400.0, f64::NAN]), "--emission-grid[1]"),
    ];
    // Exr merges both grids into one: an empty or unsorted one must not slip through.
    for format in [ExportFormat::Matrix, ExportFormat::Exr] {
        for (excitation_nm, emission_nm, expected) in cases.clone() {
            let options = ExportOptions {
                excitation_nm,
                emission_nm,
                ..ExportOptions::new(format)
            };
            let e = refusal(&one_dye(), &options);
            assert!(e.starts_with(expected), "{format:?}: {e}");
        }
    }
}
