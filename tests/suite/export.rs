//! `export`: round trips through `fit`, independent readers of every format, and bad
//! input through the binary.

use std::path::{Path, PathBuf};
use std::process::Command;

use fluorite::Units;
use fluorite::export::{ExportFormat, ExportOptions, export};
use fluorite::fit::{FitOptions, FitOutcome, ModelChoice, fit};
use fluorite::formats::{ReadOptions, read};
use fluorite::material::{Fluorophore, Material, YieldForm};
use fluorite::parametric::SpectralForm;
use fluorite::synth::SynthSpec;

use crate::common;

const VERSION: &str = env!("CARGO_PKG_VERSION");

fn fitted(outcome: FitOutcome) -> Material {
    match outcome {
        FitOutcome::Material(m) => *m,
        FitOutcome::Shapes(_) => panic!("expected a material"),
    }
}

/// The one-fluorophore grid fit (`--model tabulated`): the round trips below export its
/// grid samples (HERPICER's default fit escalates to two parametric fluorophores).
fn grid_options() -> FitOptions {
    FitOptions {
        model: ModelChoice::Tabulated,
        ..FitOptions::default()
    }
}

/// A noise-free synthetic matrix (no crosstalk, nothing missing) and its fit.
fn synthetic_fit(preset: &str) -> Material {
    let mut spec = SynthSpec::preset(preset).unwrap();
    spec.noise_sigma = 0.0;
    spec.crosstalk = 0.0;
    let (m, _) = spec.generate().unwrap();
    fitted(fit(&m, &FitOptions::default()).unwrap())
}

/// Exports the matrix of `material` on the grids to a file, reads it back and fits it.
fn refit(material: &Material, ex: &[f64], em: &[f64], dir: &Path) -> Material {
    let options = ExportOptions {
        excitation_nm: Some(ex.to_vec()),
        emission_nm: Some(em.to_vec()),
        ..ExportOptions::new(ExportFormat::Matrix)
    };
    let files = export(material, &options).unwrap();
    assert_eq!(files.len(), 1);
    let path = dir.join(&files[0].name);
    std::fs::write(&path, &files[0].contents).unwrap();
    let m = read(&path, &ReadOptions::default()).unwrap();
    assert_eq!(m.excitation_nm, ex);
    assert_eq!(m.emission_nm, em);
    // Matrix only, in the material's own yield form: the round trip tests the export.
    let form = material.fluorophores.first().map(|f| f.yield_form);
    let options = FitOptions {
        colour_weight: 0.0,
        yield_choice: match form {
            Some(fluorite::YieldForm::Photon) => fluorite::fit::YieldChoice::Photon,
            _ => fluorite::fit::YieldChoice::Energy,
        },
        ..FitOptions::default()
    };
    fitted(fit(&m, &options).unwrap())
}

/// max |got − want| / max |want|.
fn rel(got: &[f64], want: &[f64]) -> f64 {
    assert_eq!(got.len(), want.len());
    let scale = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    got.iter()
        .zip(want)
        .map(|(g, w)| (g - w).abs())
        .fold(0.0, f64::max)
        / scale
}

fn uniform(start: f64, end: f64, step: f64) -> Vec<f64> {
    let n = ((end - start) / step).round() as usize;
    (0..=n).map(|i| start + step * i as f64).collect()
}

/// Acceptance: fit → export matrix on the measurement grid → fit reproduces a, e, r and
/// k to 1e-6 (relative to each spectrum's peak), for a noise-free synthetic matrix and a
/// real one.
#[test]
fn matrix_round_trip_on_the_measurement_grid() {
    let dir = common::temp_dir("roundtrip");
    let mut materials = vec![synthetic_fit("green-dye"), synthetic_fit("red-pigment")];
    for name in ["HERPICER.BFC", "postit_yellow.csv"] {
        if let Some(p) = common::measured(name) {
            let m = read(&p, &ReadOptions::default()).unwrap();
            materials.push(fitted(fit(&m, &grid_options()).unwrap()));
        }
    }
    for first in materials {
        let f1 = &first.fluorophores[0];
        let second = refit(
            &first,
            &f1.absorption.wavelength_nm,
            &f1.emission.wavelength_nm,
            &dir,
        );
        let f2 = &second.fluorophores[0];
        let errors = [
            rel(&f2.absorption.value, &f1.absorption.value),
            rel(&f2.emission.value, &f1.emission.value),
            rel(&second.reflectance.value, &first.reflectance.value),
            (f2.k() - f1.k()).abs() / f1.k(),
            (f2.concentration - f1.concentration).abs() / f1.concentration,
        ];
        println!("{}: a, e, r, k, c relative errors {errors:?}", first.name);
        assert_eq!(
            second.reflectance.wavelength_nm,
            first.reflectance.wavelength_nm
        );
        assert!(
            errors.iter().all(|&e| e < 1e-6),
            "{}: {errors:?}",
            first.name
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Export on a grid of half the step (excitation 300:780:5, emission 380:780:5) and fit.
///
/// The interpolation error, derived: the fitted a and e are linear between the 10 nm
/// samples, and every 10 nm sample is also a 5 nm sample, so the finer matrix samples the
/// same interpolants: k·a(λi)·e(λo)·Δλo with the 5 nm trapezoid widths, whose ∫e is
/// exactly the 10 nm one (the trapezoid rule is exact for a linear interpolant). So a, e
/// and k are reproduced exactly (to the solver's 1e-6) at every 5 nm sample. What is
/// not linear is λ·e(λ) in λ̄e = ∫λ·e dλ: the trapezoid rule overestimates ∫ of the
/// quadratic λ·e on an interval of width h by h³·s/6 (s the slope of e there), so
/// halving the step lowers λ̄e by Σ (H³ − H³/4)·s/6 = H²/8·(e(λlast) − e(λfirst)) with
/// H = 10 nm: a telescoping sum. The fit's gauge c = k·max(1, λ̄e/λmin) moves with λ̄e
/// when the photon bound is active, and with it Q = k/c and r = d/(1 − c·a), d being
/// gauge-invariant. The test predicts c, Q and r from that shift and checks them to 1e-6,
/// and checks d = (1 − c·a)·r to 1e-6.
#[test]
fn matrix_on_a_finer_grid_reproduces_within_the_interpolation_error() {
    let dir = common::temp_dir("fine");
    let mut materials = vec![synthetic_fit("green-dye"), synthetic_fit("brightener")];
    if let Some(p) = common::measured("HERPICER.BFC") {
        let m = read(&p, &ReadOptions::default()).unwrap();
        materials.push(fitted(fit(&m, &grid_options()).unwrap()));
    }
    for first in materials {
        let f1 = &first.fluorophores[0];
        let (ea, ee) = (&f1.absorption.wavelength_nm, &f1.emission.wavelength_nm);
        let h = 10.0;
        let ex = uniform(ea[0], ea[ea.len() - 1], h / 2.0);
        let em = uniform(ee[0], ee[ee.len() - 1], h / 2.0);
        let second = refit(&first, &ex, &em, &dir);
        let f2 = &second.fluorophores[0];
        let a_want: Vec<f64> = ex
            .iter()
            .map(|&l| f1.absorption.eval_zero_outside(l))
            .collect();
        let e_want: Vec<f64> = em
            .iter()
            .map(|&l| f1.emission.eval_zero_outside(l))
            .collect();
        let err_a = rel(&f2.absorption.value, &a_want);
        let err_e = rel(&f2.emission.value, &e_want);
        // In the photon form the matrix fixes k·λi/λ̄e (the row factor), so k moves with
        // the finer grid's λ̄e; compare what the matrix determines.
        let scale_of = |f: &fluorite::Fluorophore| match f.yield_form {
            fluorite::YieldForm::Energy => f.k(),
            fluorite::YieldForm::Photon => f.k() / f.emission_mean_nm(),
        };
        let err_k = (scale_of(f2) - scale_of(f1)).abs() / scale_of(f1);
        // λ̄e shift, derived above.
        let e = &f1.emission.value;
        let shift = h * h / 8.0 * (e[e.len() - 1] - e[0]);
        let mean1 = f1.emission_mean_nm();
        let mean2 = f2.emission_mean_nm();
        let err_mean = (mean1 - shift - mean2).abs() / mean1;
        let shortest = f1.shortest_absorbed_nm().unwrap();
        // The default gauge is the smallest feasible c: c = k·max(1, λ̄e/λmin) in the energy
        // form; c = c·Φ (Φ = 1) in the photon form, where the matrix fixes k/λ̄e.
        let c_pred = match f1.yield_form {
            fluorite::YieldForm::Energy => f1.k() * (mean2 / shortest).max(1.0),
            fluorite::YieldForm::Photon => f1.k() * mean2 / mean1,
        };
        let err_c = (f2.concentration - c_pred).abs() / c_pred;
        // r predicted from the gauge-invariant diagonal of the first material.
        let diag = second.reflectance.wavelength_nm.clone();
        let r_pred: Vec<f64> = diag
            .iter()
            .map(|&l| first.diagonal(l) / (1.0 - c_pred * f1.absorption.eval_zero_outside(l)))
            .collect();
        let err_r = rel(&second.reflectance.value, &r_pred);
        let d1: Vec<f64> = diag.iter().map(|&l| first.diagonal(l)).collect();
        let d2: Vec<f64> = diag.iter().map(|&l| second.diagonal(l)).collect();
        let err_d = rel(&d2, &d1);
        let c_shift = (f2.concentration - f1.concentration) / f1.concentration;
        println!(
            "{}: λ̄e shift predicted {shift:.3e} nm; relative errors a {err_a:.2e} e {err_e:.2e} k {err_k:.2e} λ̄e {err_mean:.2e} c {err_c:.2e} r {err_r:.2e} d {err_d:.2e}; c moved by {c_shift:.2e}",
            first.name
        );
        for (what, err) in [
            ("a", err_a),
            ("e", err_e),
            ("k", err_k),
            ("λ̄e", err_mean),
            ("c", err_c),
            ("r", err_r),
            ("d", err_d),
        ] {
            assert!(err < 1e-6, "{}: {what} {err:e}", first.name);
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

// ---- independent readers ----------------------------------------------------------

/// Header lines (`#` stripped) and data lines of a text file.
fn split_header(text: &str, marker: &str) -> (Vec<String>, Vec<String>) {
    let mut header = Vec::new();
    let mut data = Vec::new();
    for line in text.lines() {
        let line = line.trim_end_matches('\r');
        if let Some(h) = line.strip_prefix(marker) {
            header.push(h.trim().to_string());
        } else if !line.trim().is_empty() {
            data.push(line.to_string());
        }
    }
    (header, data)
}

fn numbers(line: &str, sep: &str) -> Vec<f64> {
    let cells: Vec<&str> = if sep == " " {
        line.split_whitespace().collect()
    } else {
        line.trim().split(sep).collect()
    };
    cells
        .iter()
        .map(|c| c.trim().parse::<f64>().unwrap())
        .collect()
}

/// Trapezoid bin widths, written out again here rather than taken from the library.
fn widths(grid: &[f64]) -> Vec<f64> {
    (0..grid.len())
        .map(|i| {
            let lo = grid[i.saturating_sub(1)];
            let hi = grid[(i + 1).min(grid.len() - 1)];
            (hi - lo) / 2.0
        })
        .collect()
}

/// The model's matrix cell from the material's spectra, independently of `model`: the
/// fluorescence of every fluorophore summed, plus (1 − Σc·a)·r on the diagonal.
/// A photon-form fluorophore's energy yield is Φ·λi/λ̄e (`excitation_factor`).
fn cell(m: &Material, li: f64, lo: f64, width: f64) -> f64 {
    let mut v = 0.0;
    let mut absorbed = 0.0;
    for f in &m.fluorophores {
        let a = f.absorption.eval_zero_outside(li);
        v += f.concentration
            * f.quantum_yield
            * excitation_factor(f, li)
            * a
            * f.emission.eval_zero_outside(lo)
            * width;
        absorbed += f.concentration * a;
    }
    if (li - lo).abs() < 1e-9 {
        v += (1.0 - absorbed) * m.reflectance.eval_clamped(li);
    }
    v
}

/// λ̄e = ∫λ·e dλ / ∫e dλ by the trapezoid rule on the emission's samples (the
/// material's documented definition), written out here.
fn mean_emission(f: &Fluorophore) -> f64 {
    let w = widths(&f.emission.wavelength_nm);
    let e = &f.emission;
    let num: f64 = (0..e.len())
        .map(|i| w[i] * e.value[i] * e.wavelength_nm[i])
        .sum();
    let den: f64 = (0..e.len()).map(|i| w[i] * e.value[i]).sum();
    num / den
}

/// The factor of the fluorescent term beside c·y·a(λi)·e(λo) (y the yield parameter): 1
/// for a constant energy yield, λi/λ̄e for a constant photon yield.
fn excitation_factor(f: &Fluorophore, li: f64) -> f64 {
    match f.yield_form {
        YieldForm::Energy => 1.0,
        YieldForm::Photon => li / mean_emission(f),
    }
}

fn close(got: f64, want: f64) -> bool {
    (got - want).abs() <= 1e-12 * want.abs().max(1e-3)
}

fn check_wide_matrix(text: &str, m: &Material, per_nm: bool) {
    let (header, data) = split_header(text, "#");
    let all = header.join("\n");
    assert!(
        all.contains(&format!("fluorite {VERSION}")) && all.contains(&format!("\"{}\"", m.name)),
        "{all}"
    );
    if per_nm {
        assert!(all.contains("per nm of emission (1/nm"), "{all}");
    } else {
        assert!(all.contains("per emission bin (dimensionless"), "{all}");
    }
    assert!(
        all.contains("rows: excitation wavelength λi (nm); columns: emission wavelength λo (nm)")
    );
    let first: Vec<&str> = data[0].split(',').collect();
    assert_eq!(first[0], "ex_nm\\em_nm");
    let em: Vec<f64> = first[1..].iter().map(|c| c.parse().unwrap()).collect();
    let w = widths(&em);
    let mut rows = 0;
    for line in &data[1..] {
        let v = numbers(line, ",");
        let li = v[0];
        for (j, &lo) in em.iter().enumerate() {
            let want = cell(m, li, lo, if per_nm { 1.0 } else { w[j] });
            assert!(close(v[j + 1], want), "{li} {lo}: {} vs {want}", v[j + 1]);
        }
        rows += 1;
    }
    assert!(rows > 1);
}

fn check_spd(
    text: &str,
    m: &Material,
    quantity: &str,
    unit: &str,
    want: impl Fn(f64) -> f64,
) -> usize {
    let (header, data) = split_header(text, "#");
    let all = header.join("\n");
    assert!(all.contains(&format!("fluorite {VERSION}")), "{all}");
    assert!(all.contains(&format!("\"{}\"", m.name)), "{all}");
    assert!(
        all.contains(quantity) && all.contains(unit),
        "{quantity} {unit}: {all}"
    );
    assert!(all.contains("wavelength (nm)"));
    for line in &data {
        let v = numbers(line, " ");
        assert_eq!(v.len(), 2, "{line}");
        // Renderers read f32: the files hold f32 values in shortest form (within one f32
        // ulp, 2^-23 relative, of the exact value).
        assert!(
            (v[1] - want(v[0])).abs() <= 2.4e-7 * want(v[0]).abs().max(1e-3),
            "{quantity} at {}: {} vs {}",
            v[0],
            v[1],
            want(v[0])
        );
    }
    data.len()
}

fn truth() -> Material {
    let (_, truth) = SynthSpec::preset("green-dye").unwrap().generate().unwrap();
    truth
}

fn render(m: &Material, format: ExportFormat) -> Vec<(String, String)> {
    common::exported(m, &ExportOptions::new(format))
}

fn file<'a>(files: &'a [(String, String)], name: &str) -> &'a str {
    common::named(files, name)
}

#[test]
fn csv_export_reads_back() {
    let m = truth();
    let f = &m.fluorophores[0];
    let files = render(&m, ExportFormat::Csv);
    assert_eq!(files.len(), 1);
    let (header, data) = split_header(file(&files, "green-dye.csv"), "#");
    let all = header.join("\n");
    assert!(all.contains(&format!("fluorite {VERSION}")) && all.contains("\"green-dye\""));
    assert!(all.contains("emission density in 1/nm"));
    let scalar = |key: &str| -> f64 {
        header
            .iter()
            .find_map(|h| h.strip_prefix(key))
            .unwrap()
            .split_whitespace()
            .next()
            .unwrap()
            .parse()
            .unwrap()
    };
    assert_eq!(scalar("concentration: c = "), f.concentration);
    assert_eq!(scalar("quantum_yield: Q = "), f.quantum_yield);
    assert_eq!(data[0], "wavelength_nm,absorption,emission,reflectance");
    let mut area = 0.0;
    let mut previous: Option<(f64, f64)> = None;
    for line in &data[1..] {
        let v = numbers(line, ",");
        assert_eq!(v[1], f.absorption.eval_zero_outside(v[0]));
        assert_eq!(v[2], f.emission.eval_zero_outside(v[0]));
        assert_eq!(v[3], m.reflectance.eval_clamped(v[0]));
        if let Some((l, e)) = previous {
            area += 0.5 * (e + v[2]) * (v[0] - l);
        }
        previous = Some((v[0], v[2]));
    }
    // The unit: e is a density in 1/nm, so its column integrates to 1 over nm.
    assert!((area - 1.0).abs() < 1e-9, "{area}");
}

#[test]
fn matrix_and_bfc_exports_read_back() {
    let m = truth();
    for per_nm in [false, true] {
        let options = ExportOptions {
            units: if per_nm { Units::PerNm } else { Units::PerBin },
            ..ExportOptions::new(ExportFormat::Matrix)
        };
        let files = export(&m, &options).unwrap();
        check_wide_matrix(std::str::from_utf8(&files[0].contents).unwrap(), &m, per_nm);
    }
    let files = render(&m, ExportFormat::Bfc);
    let text = file(&files, "green-dye.BFC");
    assert!(
        !text.replace("\r\n", "").contains('\n') && text.ends_with("EOD\r\n"),
        "CRLF line ends"
    );
    let lines: Vec<&str> = text.split("\r\n").collect();
    assert_eq!(lines[1], "BFC-450 Matrix File");
    let meta = lines[2..10].join("\n");
    assert!(meta.contains(";green-dye") && meta.contains(&format!("fluorite {VERSION}")));
    assert!(
        meta.contains("radiance factor per emission bin (dimensionless)"),
        "{meta}"
    );
    let grid = numbers(lines[10], "\t");
    let em = uniform(grid[0], grid[1], grid[2]);
    let ex: Vec<f64> = (0..grid[3] as usize)
        .map(|i| grid[4] + grid[5] * i as f64)
        .collect();
    assert_eq!((em[0], ex[0]), (380.0, 300.0));
    assert_eq!(numbers(&lines[11]["r:c:".len()..], "\t"), ex);
    let w = widths(&em);
    for (j, line) in lines[12..12 + em.len()].iter().enumerate() {
        let v = numbers(line, "\t");
        assert_eq!(v[0], em[j]);
        for (i, &li) in ex.iter().enumerate() {
            assert!(close(v[i + 1], cell(&m, li, em[j], w[j])));
        }
    }
    assert_eq!(lines[12 + em.len()], "EOD");
}

#[test]
fn renderer_exports_read_back() {
    let m = truth();
    let f = &m.fluorophores[0];
    let albedo = |l: f64| {
        (1.0 - f.concentration * f.absorption.eval_zero_outside(l)) * m.reflectance.eval_clamped(l)
    };
    {
        let files = render(&m, ExportFormat::Pbrt);
        let n = check_spd(
            file(&files, "green-dye_albedo.spd"),
            &m,
            "non-fluorescent albedo (1 - c*a(λ))*r(λ)",
            "dimensionless",
            albedo,
        );
        assert_eq!(n, m.sample_wavelengths().len());
        check_spd(
            file(&files, "green-dye_reflectance.spd"),
            &m,
            "reflectance r(λ)",
            "dimensionless",
            |l| m.reflectance.eval_clamped(l),
        );
        let n = check_spd(
            file(&files, "green-dye_excitation.spd"),
            &m,
            "excitation c*Q*a(λ)",
            "dimensionless",
            |l| f.concentration * f.quantum_yield * f.absorption.eval_zero_outside(l),
        );
        assert_eq!(n, f.absorption.len());
        check_spd(
            file(&files, "green-dye_emission.spd"),
            &m,
            "emission spectrum e(λ)",
            "1/nm",
            |l| f.emission.eval_zero_outside(l),
        );
        let scene = file(&files, "green-dye.pbrt");
        assert!(scene.contains(&format!("fluorite {VERSION}")));
        // The named materials carry their spectra inline (tests/export_renderers.rs reads
        // them as pbrt-v4 does).
        for name in ["green-dye_albedo", "green-dye_d65"] {
            assert!(scene.contains(&format!(
                "MakeNamedMaterial \"{name}\"\n    \"string type\" \"diffuse\"\n    \"spectrum reflectance\" [\n"
            )));
        }
        check_wide_matrix(file(&files, "green-dye_reradiation.csv"), &m, false);
    }
}

// ---- bad input through the binary -----------------------------------------------

fn run(args: &[&str], cwd: &Path) -> (Option<i32>, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_fluorite"))
        .args(args)
        .current_dir(cwd)
        .output()
        .unwrap();
    (out.status.code(), String::from_utf8(out.stderr).unwrap())
}

fn listing(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = walk(dir);
    v.sort();
    v
}

fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(walk(&p));
        }
        out.push(p);
    }
    out
}

#[test]
fn bad_input_is_a_one_line_error_and_writes_nothing() {
    let dir = common::temp_dir("bad");
    truth().save(&dir.join("m.json")).unwrap();
    std::fs::write(dir.join("blocker"), "a file, not a folder").unwrap();
    std::fs::write(
        dir.join("broken.json"),
        "{\"schema\": \"fluorite-material/1\"}",
    )
    .unwrap();
    let before = listing(&dir);
    let cases: [(&[&str], &str); 15] = [
        (
            &["--to", "obj", "-o", "out.csv"],
            "--to: \"obj\" is not a known format",
        ),
        (
            &["--to", "matrix", "--grid", "300:780", "-o", "out.csv"],
            "--grid: segment \"300:780\"",
        ),
        (
            &["--to", "matrix", "--grid", "300:x:5", "-o", "out.csv"],
            "is not a number",
        ),
        (
            &[
                "--to",
                "matrix",
                "--grid",
                "300:400:10,400:500:10",
                "-o",
                "out.csv",
            ],
            "overlapping",
        ),
        (
            &["--to", "matrix", "--grid", "780:300:5", "-o", "out.csv"],
            "is empty",
        ),
        (
            &["--to", "matrix", "--emission-grid", "", "-o", "out.csv"],
            "--emission-grid: is empty",
        ),
        (
            &["--to", "matrix", "-o", "missing/out.csv"],
            "does not exist",
        ),
        (
            &["--to", "mitsuba", "-o", "blocker/sub"],
            "cannot create the output folder",
        ),
        (
            &[
                "--to",
                "bfc",
                "--grid",
                "300:400:10,405:780:5",
                "-o",
                "out.BFC",
            ],
            "uniform",
        ),
        (
            &["--to", "csv", "--grid", "300:780:5", "-o", "out.csv"],
            "apply to the matrix formats",
        ),
        (
            &["--to", "mitsuba", "--light", "nowhere", "-o", "out/"],
            "--light",
        ),
        (
            &["--to", "mitsuba", "--light", "d65,a,D65", "-o", "out/"],
            "names d65 twice",
        ),
        (
            &["--to", "art", "--per-nm", "-o", "out.ark"],
            "--per-nm: ART archives hold radiance factors per emission bin",
        ),
        (
            &[
                "--to",
                "art",
                "--grid",
                "300:400:10,405:780:5",
                "-o",
                "out.ark",
            ],
            "ART archives hold regular grids",
        ),
        (
            &["--to", "pearray", "--grid", "300:780:5", "-o", "out/"],
            "apply to the matrix formats",
        ),
    ];
    for (args, expected) in cases {
        let mut all = vec!["export", "m.json"];
        all.extend_from_slice(args);
        let (code, stderr) = run(&all, &dir);
        assert!(code.is_some() && code != Some(0), "{args:?}: {code:?}");
        assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
        assert!(stderr.starts_with("fluorite: error: "), "{stderr}");
        assert!(stderr.contains(expected), "{args:?}: {stderr}");
        assert_eq!(listing(&dir), before, "{args:?} left output behind");
    }
    let (code, stderr) = run(
        &["export", "broken.json", "--to", "csv", "-o", "out.csv"],
        &dir,
    );
    assert_ne!(code, Some(0));
    assert_eq!(stderr.lines().count(), 1);
    assert!(stderr.contains("broken.json"), "{stderr}");
    assert_eq!(listing(&dir), before);

    // And the good case writes exactly the announced files.
    let (code, stderr) = run(&["export", "m.json", "--to", "pbrt", "-o", "pbrt/"], &dir);
    assert_eq!(code, Some(0), "{stderr}");
    let mut names: Vec<String> = std::fs::read_dir(dir.join("pbrt"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            "green-dye.pbrt",
            "green-dye_albedo.spd",
            "green-dye_baked_d65.spd",
            "green-dye_emission.spd",
            "green-dye_excitation.spd",
            "green-dye_reflectance.spd",
            "green-dye_reradiation.csv"
        ]
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

// ---- several fluorophores and continuous forms -----------------------------------------

fn two_dyes() -> Material {
    SynthSpec::preset("two-dyes").unwrap().truth().unwrap()
}

/// A BFC-450 file parsed by hand: (excitation, emission, rows of values per emission).
fn parse_bfc(text: &str) -> (Vec<f64>, Vec<f64>, Vec<Vec<f64>>) {
    let lines: Vec<&str> = text.split("\r\n").collect();
    assert_eq!(lines[1], "BFC-450 Matrix File");
    let grid = numbers(lines[10], "\t");
    let em = uniform(grid[0], grid[1], grid[2]);
    let ex = numbers(&lines[11]["r:c:".len()..], "\t");
    assert_eq!(ex.len(), grid[3] as usize);
    let rows = lines[12..12 + em.len()]
        .iter()
        .enumerate()
        .map(|(j, line)| {
            let v = numbers(line, "\t");
            assert_eq!(v[0], em[j]);
            v[1..].to_vec()
        })
        .collect();
    assert_eq!(lines[12 + em.len()], "EOD");
    (ex, em, rows)
}

#[test]
fn every_format_keeps_both_fluorophores() {
    let m = two_dyes();
    assert_eq!(m.fluorophores.len(), 2);
    // Independent truth: both components fluoresce in the matrix.
    assert!(cell(&m, 360.0, 440.0, 10.0) > 0.05 && cell(&m, 550.0, 610.0, 10.0) > 0.05);

    // csv: a and e columns per fluorophore, c and Q per fluorophore in the header.
    let files = render(&m, ExportFormat::Csv);
    let (header, data) = split_header(file(&files, "two-dyes.csv"), "#");
    assert_eq!(
        data[0],
        "wavelength_nm,absorption_0,emission_0,absorption_1,emission_1,reflectance"
    );
    for (k, f) in m.fluorophores.iter().enumerate() {
        let scalar = |key: String| -> f64 {
            header
                .iter()
                .find_map(|h| h.strip_prefix(key.as_str()))
                .unwrap_or_else(|| panic!("{key} missing"))
                .split_whitespace()
                .next()
                .unwrap()
                .parse()
                .unwrap()
        };
        assert_eq!(scalar(format!("concentration_{k}: c = ")), f.concentration);
        assert_eq!(scalar(format!("quantum_yield_{k}: Q = ")), f.quantum_yield);
        let mut area = 0.0;
        let mut previous: Option<(f64, f64)> = None;
        for line in &data[1..] {
            let v = numbers(line, ",");
            assert_eq!(v[1 + 2 * k], f.absorption.eval_zero_outside(v[0]));
            assert_eq!(v[2 + 2 * k], f.emission.eval_zero_outside(v[0]));
            // ∫e over e's own samples (outside them e is zero, and the linear ramp
            // from the last zero of the union grid is not part of the density).
            let sampled = v[0] >= f.emission.wavelength_nm[0];
            if let Some((l, e)) = previous
                && sampled
            {
                area += 0.5 * (e + v[2 + 2 * k]) * (v[0] - l);
            }
            previous = sampled.then_some((v[0], v[2 + 2 * k])).or(previous);
        }
        assert!((area - 1.0).abs() < 1e-9, "e_{k}: {area}");
    }

    // matrix and bfc: every cell is the sum over both fluorophores.
    for per_nm in [false, true] {
        let options = ExportOptions {
            units: if per_nm { Units::PerNm } else { Units::PerBin },
            ..ExportOptions::new(ExportFormat::Matrix)
        };
        let files = export(&m, &options).unwrap();
        let text = std::str::from_utf8(&files[0].contents).unwrap();
        check_wide_matrix(text, &m, per_nm);
        assert!(text.contains("summed over the 2 fluorophores"), "{text}");
        assert!(text.contains("d = (1 − Σc·a)·r"));
    }
    let files = render(&m, ExportFormat::Bfc);
    let text = file(&files, "two-dyes.BFC");
    assert!(text.contains(";fluorescence summed over 2 fluorophores\r\n"));
    assert!(text.contains(";diagonal: reflectance factor d = (1 - Σc*a)*r\r\n"));
    let (ex, em, rows) = parse_bfc(text);
    let w = widths(&em);
    for (j, row) in rows.iter().enumerate() {
        for (i, &li) in ex.iter().enumerate() {
            assert!(close(row[i], cell(&m, li, em[j], w[j])), "{li} {}", em[j]);
        }
    }

    // pbrt: one excitation and emission file per fluorophore, the albedo (1 − Σc·a)·r,
    // the full matrix, and a snippet naming every lobe (mitsuba: tests/export_renderers.rs).
    let albedo = |l: f64| {
        let absorbed: f64 = m
            .fluorophores
            .iter()
            .map(|f| f.concentration * f.absorption.eval_zero_outside(l))
            .sum();
        (1.0 - absorbed) * m.reflectance.eval_clamped(l)
    };
    {
        let files = render(&m, ExportFormat::Pbrt);
        let mut names: Vec<&str> = files.iter().map(|f| f.0.as_str()).collect();
        names.sort();
        let snippet = "two-dyes.pbrt";
        let mut expected = vec![
            snippet,
            "two-dyes_albedo.spd",
            "two-dyes_baked_d65.spd",
            "two-dyes_emission_0.spd",
            "two-dyes_emission_1.spd",
            "two-dyes_excitation_0.spd",
            "two-dyes_excitation_1.spd",
            "two-dyes_reflectance.spd",
            "two-dyes_reradiation.csv",
        ];
        expected.sort();
        assert_eq!(names, expected);
        check_spd(
            file(&files, "two-dyes_albedo.spd"),
            &m,
            "non-fluorescent albedo (1 - Σ c_k*a_k(λ))*r(λ)",
            "dimensionless",
            albedo,
        );
        for (k, f) in m.fluorophores.iter().enumerate() {
            let n = check_spd(
                file(&files, &format!("two-dyes_excitation_{k}.spd")),
                &m,
                "excitation c*Q*a(λ)",
                "dimensionless",
                |l| f.concentration * f.quantum_yield * f.absorption.eval_zero_outside(l),
            );
            assert_eq!(n, f.absorption.len());
            check_spd(
                file(&files, &format!("two-dyes_emission_{k}.spd")),
                &m,
                "emission spectrum e(λ)",
                "1/nm",
                |l| f.emission.eval_zero_outside(l),
            );
        }
        check_wide_matrix(file(&files, "two-dyes_reradiation.csv"), &m, false);
        let text = file(&files, snippet);
        assert!(text.contains("all 2 fluorophores summed"), "{text}");
        for k in 0..2 {
            assert!(text.contains(&format!("two-dyes_excitation_{k}.spd")));
            assert!(text.contains(&format!("two-dyes_emission_{k}.spd")));
        }
    }
}

#[test]
fn forms_are_sampled_and_their_parameters_kept() {
    let m = SynthSpec::preset("two-dyes")
        .unwrap()
        .truth_with_forms()
        .unwrap();
    let forms = m.forms.clone().unwrap();
    // csv: the samples, and one header line per form whose JSON reads back as the form.
    let files = render(&m, ExportFormat::Csv);
    let (header, data) = split_header(file(&files, "two-dyes.csv"), "#");
    assert!(
        header.iter().any(|h| h.starts_with("forms: model synth;")),
        "{header:?}"
    );
    for (k, f) in forms.fluorophores.iter().enumerate() {
        for (what, form) in [("absorption", &f.absorption), ("emission", &f.emission)] {
            let key = format!("form {what}_{k}: ");
            let json = header
                .iter()
                .find_map(|h| h.strip_prefix(key.as_str()))
                .unwrap_or_else(|| panic!("{key} missing from {header:?}"));
            // Exactly the form's JSON, which reads back as the form.
            assert_eq!(json, serde_json::to_string(form).unwrap());
            let back: SpectralForm = serde_json::from_str(json).unwrap();
            for nm in [300.0, 365.0, 440.0, 545.0, 612.5, 780.0] {
                assert!((back.eval(nm) - form.eval(nm)).abs() <= 1e-14 * form.eval(nm).max(1e-300));
            }
        }
    }
    // The sampled columns are the forms evaluated (within the forms tolerance).
    for line in &data[1..] {
        let v = numbers(line, ",");
        for (k, f) in forms.fluorophores.iter().enumerate() {
            if (300.0..=780.0).contains(&v[0]) {
                assert!((v[1 + 2 * k] - f.absorption.eval(v[0])).abs() < 1e-9);
            }
            if (380.0..=780.0).contains(&v[0]) {
                assert!((v[2 + 2 * k] - f.emission.eval(v[0])).abs() < 1e-9);
            }
        }
    }
    let files = render(&m, ExportFormat::Matrix);
    let text = file(&files, "two-dyes.matrix.csv");
    assert!(text.contains("# forms: model synth;") && text.contains("# form emission_1: {"));
    check_wide_matrix(text, &m, false);
    let files = render(&m, ExportFormat::Bfc);
    assert!(
        file(&files, "two-dyes.BFC")
            .contains(";spectra from the continuous forms of model synth\r\n")
    );
    {
        let files = render(&m, ExportFormat::Pbrt);
        for (name, text) in &files {
            if name.ends_with(".spd") && !name.contains("_baked_") {
                assert!(
                    text.contains("# spectra: samples of the continuous forms of model synth"),
                    "{name}"
                );
            }
        }
    }

    // Forms that do not reproduce their samples are refused, naming the law.
    let mut bad = m.clone();
    if let Some(forms) = &mut bad.forms
        && let SpectralForm::GaussianBands(bands) = &mut forms.fluorophores[0].absorption
    {
        bands.bands[0].centre_nm += 3.0;
    }
    let err = export(&bad, &ExportOptions::new(ExportFormat::Csv))
        .unwrap_err()
        .to_string();
    assert!(err.contains("violates forms"), "{err}");
}

#[test]
fn mitsuba_takes_a_grid_only_when_it_writes_the_matrix() {
    let dir = common::temp_dir("mitsuba-grid");
    truth().save(&dir.join("one.json")).unwrap();
    two_dyes().save(&dir.join("two.json")).unwrap();
    let (code, stderr) = run(
        &[
            "export",
            "one.json",
            "--to",
            "mitsuba",
            "--grid",
            "300:780:20",
            "-o",
            "one/",
        ],
        &dir,
    );
    assert_ne!(code, Some(0), "{stderr}");
    assert!(stderr.contains("fewer than two fluorophores"), "{stderr}");
    assert!(!dir.join("one").exists());
    let (code, stderr) = run(
        &[
            "export",
            "two.json",
            "--to",
            "mitsuba",
            "--grid",
            "300:780:20",
            "-o",
            "two/",
        ],
        &dir,
    );
    assert_eq!(code, Some(0), "{stderr}");
    let text = std::fs::read_to_string(dir.join("two/two-dyes_reradiation.csv")).unwrap();
    let m = two_dyes();
    check_wide_matrix(&text, &m, false);
    let header = text.lines().find(|l| l.starts_with("ex_nm")).unwrap();
    assert_eq!(header.split(',').count(), 1 + 25);
    std::fs::remove_dir_all(&dir).unwrap();
}

// ---- the photon-yield form ----------------------------------------------------------------

/// The green-dye truth with its yield read as a constant photon yield Φ = 0.8.
fn photon_truth() -> Material {
    let mut m = truth();
    m.name = "green-photon".into();
    m.fluorophores[0].yield_form = YieldForm::Photon;
    m.fluorophores[0].quantum_yield = 0.8;
    m.validate().unwrap();
    m
}

#[test]
fn photon_form_exports_write_the_form_and_the_photon_yield() {
    let m = photon_truth();
    let f = &m.fluorophores[0];
    let mean = mean_emission(f);
    // The factor λi/λ̄e matters across the absorption (the test is not vacuous).
    let [lo, hi] = [
        f.absorption.wavelength_nm[0],
        *f.absorption.wavelength_nm.last().unwrap(),
    ];
    assert!(hi / mean - lo / mean > 0.3, "{lo} {hi} {mean}");

    // csv: the form, Φ and λ̄e in the header, no constant energy yield.
    let files = render(&m, ExportFormat::Csv);
    let (header, _) = split_header(file(&files, "green-photon.csv"), "#");
    let scalar = |key: &str| -> f64 {
        header
            .iter()
            .find_map(|h| h.strip_prefix(key))
            .unwrap_or_else(|| panic!("{key} missing: {header:?}"))
            .split_whitespace()
            .next()
            .unwrap()
            .parse()
            .unwrap()
    };
    assert!(
        header.iter().any(|h| h.starts_with("yield_form: photon")),
        "{header:?}"
    );
    assert_eq!(scalar("photon_yield: Φ = "), 0.8);
    assert!((scalar("mean_emission: λ̄e = ") - mean).abs() < 1e-9 * mean);
    assert!(
        !header.iter().any(|h| h.starts_with("quantum_yield")),
        "{header:?}"
    );

    // matrix (both units) and BFC: every cell c·Φ·(λi/λ̄e)·a(λi)·e(λo)·Δλo off the diagonal.
    for per_nm in [false, true] {
        let options = ExportOptions {
            units: if per_nm { Units::PerNm } else { Units::PerBin },
            ..ExportOptions::new(ExportFormat::Matrix)
        };
        let files = export(&m, &options).unwrap();
        let text = std::str::from_utf8(&files[0].contents).unwrap();
        check_wide_matrix(text, &m, per_nm);
        assert!(
            text.contains("c·Q(λi)·a(λi)") && text.contains("Φ = 0.8"),
            "{text}"
        );
    }
    let files = render(&m, ExportFormat::Bfc);
    let text = file(&files, "green-photon.BFC");
    assert!(
        text.contains(";photon-form yield: energy yield Q(li) = Phi*li"),
        "{text}"
    );
    let (ex, em, rows) = parse_bfc(text);
    let w = widths(&em);
    for (j, row) in rows.iter().enumerate() {
        for (i, &li) in ex.iter().enumerate() {
            assert!(close(row[i], cell(&m, li, em[j], w[j])), "{li} {}", em[j]);
        }
    }

    // pbrt: the excitation file holds c·Φ·(λ/λ̄e)·a(λ), at least every 1 nm (λ·a is
    // quadratic between the absorption samples), through every absorption sample.
    {
        let files = render(&m, ExportFormat::Pbrt);
        let text = file(&files, "green-photon_excitation.spd");
        check_spd(
            text,
            &m,
            "excitation c*Q(λ)*a(λ) with the energy yield Q(λ) = Φ*λ/λ̄e",
            "Φ = 0.8",
            |l| f.concentration * 0.8 * l / mean * f.absorption.eval_zero_outside(l),
        );
        let (_, data) = split_header(text, "#");
        let grid: Vec<f64> = data.iter().map(|l| numbers(l, " ")[0]).collect();
        assert!(
            grid.windows(2)
                .all(|w| w[1] > w[0] && w[1] - w[0] <= 1.0 + 1e-9)
        );
        for l in &f.absorption.wavelength_nm {
            assert!(grid.iter().any(|g| (g - l).abs() < 1e-9), "{l} missing");
        }
        let snippet = file(&files, "green-photon.pbrt");
        assert!(
            snippet.contains("constant PHOTON yield Φ = 0.8") && snippet.contains("cannot express"),
            "{snippet}"
        );
        assert!(snippet.contains("photon form, Φ = 0.8"), "{snippet}");
    }
}

#[test]
fn mixed_forms_keep_each_fluorophores_own_yield() {
    // two-dyes with the orange dye in the photon form (Φ = 0.9), the brightener energy.
    let mut m = two_dyes();
    m.fluorophores[1].yield_form = YieldForm::Photon;
    m.fluorophores[1].quantum_yield = 0.9;
    m.validate().unwrap();
    let files = render(&m, ExportFormat::Bfc);
    let (ex, em, rows) = parse_bfc(file(&files, "two-dyes.BFC"));
    let w = widths(&em);
    for (j, row) in rows.iter().enumerate() {
        for (i, &li) in ex.iter().enumerate() {
            assert!(close(row[i], cell(&m, li, em[j], w[j])), "{li} {}", em[j]);
        }
    }
    let files = render(&m, ExportFormat::Pbrt);
    let scene = file(&files, "two-dyes.pbrt");
    let q0 = m.fluorophores[0].quantum_yield;
    assert!(
        scene.contains(&format!(
            "# fluorescent lobe_0: c = {}, Q = {}",
            m.fluorophores[0].concentration as f32, q0 as f32
        )),
        "{scene}"
    );
    assert!(
        scene.contains("lobe_1: c = ") && scene.contains("photon form, Φ = 0.9"),
        "{scene}"
    );
    assert!(scene.contains("Lobe_1 has a constant PHOTON yield") && !scene.contains("Lobe_0 has"));
    let f = &m.fluorophores[0];
    check_spd(
        file(&files, "two-dyes_excitation_0.spd"),
        &m,
        "excitation c*Q*a(λ)",
        "dimensionless",
        |l| f.concentration * q0 * f.absorption.eval_zero_outside(l),
    );
    let files = render(&m, ExportFormat::Csv);
    let (header, _) = split_header(file(&files, "two-dyes.csv"), "#");
    assert!(
        header
            .iter()
            .any(|h| h.starts_with("quantum_yield_0: Q = "))
    );
    assert!(
        header
            .iter()
            .any(|h| h.starts_with("photon_yield_1: Φ = 0.9"))
    );
}
