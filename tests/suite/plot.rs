//! Plotting a fit: every figure renders for a synthetic fit, decodes as a PNG of
//! the stated size, is not blank, and shows the colour map's colour at known heat-map
//! cells; bad input fails cleanly and writes nothing.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use fluorite::material::FitReport;
use fluorite::measurement::CellKind;
use fluorite::plot::colormap::{self, diverging, viridis};
use fluorite::plot::{self, FigureKind, ImageFormat, PlotOptions, Plots};
use fluorite::spectrum::{Spectrum, bin_widths, uniform_grid};
use fluorite::{Fluorophore, Material, Measurement, Units, model};

const GUARD_NM: f64 = 10.0;
const NOISE: f64 = 0.002;

fn gaussian(grid: &[f64], centre: f64, sigma: f64) -> Vec<f64> {
    grid.iter()
        .map(|l| (-0.5 * ((l - centre) / sigma).powi(2)).exp())
        .collect()
}

/// A one-fluorophore material on the BFC-450 grids (excitation 300–780 nm, emission
/// 380–780 nm, 10 nm), with a fit block written by hand.
fn synthetic_material() -> Material {
    let ex = uniform_grid(300.0, 780.0, 10.0);
    let em = uniform_grid(380.0, 780.0, 10.0);
    let a = gaussian(&ex, 460.0, 40.0);
    let peak = a.iter().cloned().fold(0.0, f64::max);
    let a: Vec<f64> = a.iter().map(|v| v / peak).collect();
    let e = gaussian(&em, 570.0, 30.0);
    let area: f64 = e.iter().zip(bin_widths(&em)).map(|(v, w)| v * w).sum();
    let e: Vec<f64> = e.iter().map(|v| v / area).collect();
    let r: Vec<f64> = em
        .iter()
        .map(|l| 0.15 + 0.7 / (1.0 + (-(l - 560.0) / 25.0).exp()))
        .collect();
    let mut material = Material::new(
        "SYNTH",
        Spectrum::new(em.clone(), r, "r").unwrap(),
        vec![Fluorophore {
            concentration: 0.6,
            quantum_yield: 0.5,
            yield_form: fluorite::YieldForm::Energy,
            concentration_range: Some([0.3, 0.9]),
            absorption: Spectrum::new(ex, a, "a").unwrap(),
            emission: Spectrum::new(em, e, "e").unwrap(),
        }],
    );
    material.validate().unwrap();
    material.fit = Some(FitReport {
        source: "synthetic.csv".to_string(),
        solver: "lbfgs".to_string(),
        converged: true,
        iterations: 40,
        guard_nm: GUARD_NM,
        gauge: "max-concentration".to_string(),
        delta_e2000: BTreeMap::new(),
        cost_history: (0..40).map(|n| 2.0 * 0.8f64.powi(n) + 1e-3).collect(),
        ..FitReport::default()
    });
    material
}

/// Deterministic noise in [−0.5, 0.5) per cell (xorshift of the cell index).
fn noise(i: usize, j: usize) -> f64 {
    let mut x = (i as u64 * 7919 + j as u64 * 104_729 + 12_345) | 1;
    for _ in 0..3 {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
    }
    (x % 10_000) as f64 / 10_000.0 - 0.5
}

/// The material's matrix with noise of ±`amplitude` and a few missing cells.
fn synthetic_measurement(material: &Material, amplitude: f64, missing: bool) -> Measurement {
    let ex = material.fluorophores[0].absorption.wavelength_nm.clone();
    let em = material.fluorophores[0].emission.wavelength_nm.clone();
    let mut m = model::predict(material, "SYNTH", &ex, &em, Units::PerBin, true);
    for i in 0..m.n_excitation() {
        for j in 0..m.n_emission() {
            *m.get_mut(i, j) += amplitude * noise(i, j);
        }
    }
    if missing {
        for (i, j) in missing_cells() {
            *m.get_mut(i, j) = f64::NAN;
        }
    }
    m.validate().unwrap();
    m
}

/// Missing cells: excitation 700 nm and 710 nm at emission 400 nm (anti-Stokes corner).
fn missing_cells() -> Vec<(usize, usize)> {
    vec![(40, 2), (41, 2)]
}

fn pixel(rgb: &[u8], width: u32, (x, y): (i32, i32)) -> [u8; 3] {
    let k = 3 * (y as usize * width as usize + x as usize);
    [rgb[k], rgb[k + 1], rgb[k + 2]]
}

fn as_array(c: plotters::style::RGBColor) -> [u8; 3] {
    [c.0, c.1, c.2]
}

fn render_synthetic() -> (Material, Measurement, Plots) {
    let material = synthetic_material();
    let measured = synthetic_measurement(&material, NOISE, true);
    let plots = plot::plot(&material, Some(&measured), &PlotOptions::default()).unwrap();
    (material, measured, plots)
}

#[test]
fn every_figure_decodes_at_its_stated_size_and_is_not_blank() {
    let (_, _, plots) = render_synthetic();
    let kinds: Vec<FigureKind> = plots.figures.iter().map(|f| f.kind).collect();
    assert_eq!(
        kinds,
        [
            FigureKind::Residuals,
            FigureKind::Spectra,
            FigureKind::Colour,
            FigureKind::Convergence
        ]
    );
    assert!(plots.skipped.is_empty(), "{:?}", plots.skipped);
    for figure in &plots.figures {
        let (w, h, rgb) = decode_png(&figure.bytes);
        assert_eq!((w, h), (figure.width, figure.height), "{:?}", figure.kind);
        assert_eq!((w, h), figure.kind.size());
        assert!(
            w >= 900,
            "{:?} is {w} px wide; README figures need ~900 px",
            figure.kind
        );
        let mut colours: Vec<[u8; 3]> = rgb.chunks(3).map(|c| [c[0], c[1], c[2]]).collect();
        let non_white = colours.iter().filter(|c| **c != [255, 255, 255]).count();
        colours.sort_unstable();
        colours.dedup();
        assert!(
            colours.len() > 40,
            "{:?} has only {} distinct colours",
            figure.kind,
            colours.len()
        );
        assert!(
            non_white as f64 > 0.02 * (w * h) as f64,
            "{:?} is nearly blank ({non_white} non-white pixels)",
            figure.kind
        );
    }
}

#[test]
fn heat_map_pixels_show_the_colour_map_colour_of_their_cell() {
    let (material, measured, plots) = render_synthetic();
    let residuals = &plots.figures[0];
    let (w, _, rgb) = decode_png(&residuals.bytes);
    let panels = &residuals.layout.heatmaps;
    assert_eq!(panels.len(), 3);
    let fitted = model::predict(
        &material,
        "fit",
        &measured.excitation_nm,
        &measured.emission_nm,
        Units::PerBin,
        true,
    );

    // Independent scales: values from 0 to the largest cell outside the diagonal and guard
    // band (either matrix); residuals symmetric to the largest |measured − fitted| there.
    let (mut value_max, mut residual_max) = (0.0f64, 0.0f64);
    for i in 0..measured.n_excitation() {
        for j in 0..measured.n_emission() {
            let offset = (measured.emission_nm[j] - measured.excitation_nm[i]).abs();
            let (m, f) = (measured.get(i, j), fitted.get(i, j));
            if offset > GUARD_NM + 1e-6 {
                value_max = value_max.max(f);
                if !m.is_nan() {
                    value_max = value_max.max(m);
                    residual_max = residual_max.max((m - f).abs());
                }
            }
        }
    }
    assert!((panels[0].scale.max - value_max).abs() < 1e-15);
    assert_eq!(panels[0].scale.min, 0.0);
    assert!((panels[2].scale.max - residual_max).abs() < 1e-15);

    let idx = |nm: f64, grid: &[f64]| grid.iter().position(|&g| (g - nm).abs() < 1e-9).unwrap();
    let mut probed = 0;
    for (ex_nm, em_nm) in [
        (460.0, 570.0),
        (300.0, 780.0),
        (420.0, 520.0),
        (500.0, 650.0),
        (700.0, 450.0),
    ] {
        let (i, j) = (
            idx(ex_nm, &measured.excitation_nm),
            idx(em_nm, &measured.emission_nm),
        );
        let (m, f) = (measured.get(i, j), fitted.get(i, j));
        let expected = [
            viridis(m / value_max),
            viridis(f / value_max),
            diverging(((m - f) / residual_max + 1.0) / 2.0),
        ];
        for (panel, colour) in panels.iter().zip(expected) {
            let at = panel.cell_centre_px(i, j);
            assert_eq!(
                pixel(&rgb, w, at),
                as_array(colour),
                "{} panel, cell ({ex_nm}, {em_nm}) nm at pixel {at:?}",
                panel.title
            );
            probed += 1;
        }
    }
    assert_eq!(probed, 15);

    // The peak cell maps to the top of viridis: a bright yellow-green.
    let (i, j) = (
        idx(460.0, &measured.excitation_nm),
        idx(570.0, &measured.emission_nm),
    );
    let [r, g, b] = pixel(&rgb, w, panels[1].cell_centre_px(i, j));
    assert!(g > 180 && b < 120 && r > 100, "peak cell is {r},{g},{b}");

    // Diagonal black, missing grey, in the measured panel.
    let (i, j) = (
        idx(500.0, &measured.excitation_nm),
        idx(500.0, &measured.emission_nm),
    );
    assert_eq!(measured.cell_kind(i, j, GUARD_NM), CellKind::Diagonal);
    assert_eq!(
        pixel(&rgb, w, panels[0].cell_centre_px(i, j)),
        as_array(colormap::DIAGONAL)
    );
    for (i, j) in missing_cells() {
        assert_eq!(
            pixel(&rgb, w, panels[0].cell_centre_px(i, j)),
            as_array(colormap::MISSING)
        );
        assert_eq!(
            pixel(&rgb, w, panels[2].cell_centre_px(i, j)),
            as_array(colormap::MISSING)
        );
    }
    // Cells tile the plotting area: the first and last cells touch its corners.
    let p = &panels[0];
    let first = p.cell_rect_px(0, 0);
    let last = p.cell_rect_px(measured.n_excitation() - 1, measured.n_emission() - 1);
    assert_eq!((first[0], first[3]), (p.plot_area_px[0], p.plot_area_px[3]));
    assert_eq!((last[2], last[1]), (p.plot_area_px[2], p.plot_area_px[1]));
}

#[test]
fn swatches_match_for_a_perfect_fit_and_show_their_colours() {
    let material = synthetic_material();
    let measured = synthetic_measurement(&material, 0.0, false);
    let plots = plot::plot(&material, Some(&measured), &PlotOptions::default()).unwrap();
    let colour = plots
        .figures
        .iter()
        .find(|f| f.kind == FigureKind::Colour)
        .unwrap();
    let swatches = &colour.layout.swatches;
    let lights: Vec<&str> = swatches.iter().map(|s| s.pair.light.as_str()).collect();
    assert_eq!(lights, ["d65", "a", "f11", "uv"]);
    let (w, _, rgb) = decode_png(&colour.bytes);
    for s in swatches {
        // Noise-free data are the model's own matrix: identical colour, ΔE = 0.
        assert!(
            s.pair.delta_e2000 < 1e-9,
            "{}: {}",
            s.pair.light,
            s.pair.delta_e2000
        );
        assert_eq!(s.pair.measured_srgb, s.pair.fitted_srgb);
        for (rect, srgb) in [
            (s.measured_rect_px, s.pair.measured_srgb),
            (s.fitted_rect_px, s.pair.fitted_srgb),
        ] {
            let centre = ((rect[0] + rect[2]) / 2, (rect[1] + rect[3]) / 2);
            assert_eq!(pixel(&rgb, w, centre), srgb, "{} swatch", s.pair.light);
        }
    }
    // The synthetic material reflects red and absorbs blue: the D65 swatch is warm.
    let d65 = swatches[0].pair.measured_srgb;
    assert!(d65[0] > d65[2] + 40, "D65 swatch {d65:?}");
}

#[test]
fn noisy_data_give_small_but_nonzero_colour_differences() {
    let (_, _, plots) = render_synthetic();
    let colour = &plots.figures[2];
    for s in &colour.layout.swatches {
        let de = s.pair.delta_e2000;
        assert!(de > 0.0 && de < 2.0, "{}: ΔE {de}", s.pair.light);
    }
}

#[test]
fn without_data_only_spectra_and_convergence_are_drawn() {
    let material = synthetic_material();
    let plots = plot::plot(&material, None, &PlotOptions::default()).unwrap();
    let kinds: Vec<FigureKind> = plots.figures.iter().map(|f| f.kind).collect();
    assert_eq!(kinds, [FigureKind::Spectra, FigureKind::Convergence]);
    assert_eq!(plots.skipped.len(), 2);
    assert!(plots.skipped[0].starts_with("residual map"));
    assert!(plots.skipped[1].starts_with("colour swatches"));
    for f in &plots.figures {
        assert_eq!(decode_png(&f.bytes).0, f.width);
    }

    let mut bare = material.clone();
    bare.fit = None;
    let plots = plot::plot(&bare, None, &PlotOptions::default()).unwrap();
    assert_eq!(plots.figures.len(), 1);
    assert!(
        plots.skipped[2].contains("no fit block"),
        "{:?}",
        plots.skipped
    );
}

#[test]
fn data_profiles_lie_on_the_fitted_curves_for_noise_free_data() {
    let material = synthetic_material();
    let measured = synthetic_measurement(&material, 0.0, false);
    let comparison = plot::Comparison::new(&material, &measured, GUARD_NM);
    let profiles = plot::spectra::data_profiles(&material, &comparison);
    let f = &material.fluorophores[0];
    let e_max = f.emission.max();
    assert!(profiles.excitation.len() > 10 && profiles.emission.len() > 10);
    for &(l, v) in &profiles.excitation {
        assert!(
            (v - f.absorption.eval_zero_outside(l)).abs() < 1e-9,
            "a at {l}: {v}"
        );
    }
    for &(l, v) in &profiles.emission {
        assert!(
            (v - f.emission.eval_zero_outside(l) / e_max).abs() < 1e-9,
            "e at {l}: {v}"
        );
    }
}

#[test]
fn svg_output_is_an_svg_of_the_stated_size() {
    let material = synthetic_material();
    let measured = synthetic_measurement(&material, NOISE, true);
    let options = PlotOptions {
        format: ImageFormat::Svg,
        guard_nm: None,
    };
    let plots = plot::plot(&material, Some(&measured), &options).unwrap();
    assert_eq!(plots.figures.len(), 4);
    for f in &plots.figures {
        let text = std::str::from_utf8(&f.bytes).unwrap();
        assert!(text.starts_with("<svg"), "{:?}", f.kind);
        assert!(text.contains(&format!("width=\"{}\"", f.width)));
        assert!(text.contains(&format!("height=\"{}\"", f.height)));
        assert!(text.contains("SYNTH"));
        assert!(f.file_name("SYNTH").ends_with(".svg"));
    }
}

#[test]
fn data_on_another_grid_is_refused_with_a_clear_error() {
    let material = synthetic_material();
    let ex = uniform_grid(300.0, 780.0, 5.0);
    let em = uniform_grid(380.0, 780.0, 10.0);
    let other = model::predict(&material, "OTHER", &ex, &em, Units::PerBin, true);
    let err = plot::plot(&material, Some(&other), &PlotOptions::default()).unwrap_err();
    let message = err.to_string();
    assert!(message.starts_with("--data"), "{message}");
    assert!(
        message.contains("excitation grid (300–780 nm, 97 samples)"),
        "{message}"
    );
    assert!(message.contains("49 samples"), "{message}");
    assert!(message.contains("synthetic.csv"), "{message}");
}

fn files_in(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    files
}

#[test]
fn writing_puts_every_figure_in_place_or_nothing() {
    let (_, _, plots) = render_synthetic();
    let dir = tempfile::tempdir().unwrap();

    // A path under a regular file is no folder.
    let blocker = dir.path().join("not-a-folder");
    std::fs::write(&blocker, b"x").unwrap();
    let err = plot::write_plots(&plots, &blocker.join("out"), "SYNTH").unwrap_err();
    assert!(err.to_string().contains("output folder"), "{err}");
    assert_eq!(files_in(dir.path()), vec![blocker.clone()]);

    // A folder where the third figure should go: nothing may be written, not even the
    // first two.
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    std::fs::create_dir(out.join("SYNTH-colour.png")).unwrap();
    let err = plot::write_plots(&plots, &out, "SYNTH").unwrap_err();
    assert!(err.to_string().contains("SYNTH-colour.png"), "{err}");
    assert_eq!(files_in(&out), vec![out.join("SYNTH-colour.png")]);
    std::fs::remove_dir(out.join("SYNTH-colour.png")).unwrap();

    let written = plot::write_plots(&plots, &out, "SYNTH").unwrap();
    let names: Vec<String> = written
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            "SYNTH-residuals.png",
            "SYNTH-spectra.png",
            "SYNTH-colour.png",
            "SYNTH-convergence.png"
        ]
    );
    assert_eq!(files_in(&out), {
        let mut w = written.clone();
        w.sort();
        w
    });
    for (path, figure) in written.iter().zip(&plots.figures) {
        assert_eq!(std::fs::read(path).unwrap(), figure.bytes);
    }
}

/// Writes `m` as a wide CSV with excitation rows.
fn write_wide_csv(m: &Measurement, path: &Path) {
    let mut text = String::from("ex\\em");
    for l in &m.emission_nm {
        text += &format!(",{l}");
    }
    text.push('\n');
    for (i, l) in m.excitation_nm.iter().enumerate() {
        text += &format!("{l}");
        for j in 0..m.n_emission() {
            let v = m.get(i, j);
            if v.is_nan() {
                text.push(',');
            } else {
                text += &format!(",{v}");
            }
        }
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}

fn fluorite(args: &[&std::ffi::OsStr]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_fluorite"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn cli_plots_next_to_the_material_and_refuses_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let material = synthetic_material();
    let material_path = dir.path().join("SYNTH.json");
    material.save(&material_path).unwrap();

    // Without data: spectra and convergence next to the material, the rest reported.
    let out = fluorite(&["plot".as_ref(), material_path.as_os_str()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("skipped residual map"), "{stderr}");
    assert_eq!(
        files_in(dir.path()),
        vec![
            dir.path().join("SYNTH-convergence.png"),
            dir.path().join("SYNTH-spectra.png"),
            material_path.clone(),
        ]
    );

    // Data on another grid: one-line error, exit 2, nothing written into -o DIR.
    let other = model::predict(
        &material,
        "OTHER",
        &uniform_grid(300.0, 780.0, 20.0),
        &uniform_grid(380.0, 780.0, 10.0),
        Units::PerBin,
        true,
    );
    let other_path = dir.path().join("other.csv");
    write_wide_csv(&other, &other_path);
    let report = dir.path().join("report");
    let out = fluorite(&[
        "plot".as_ref(),
        material_path.as_os_str(),
        "--data".as_ref(),
        other_path.as_os_str(),
        "-o".as_ref(),
        report.as_os_str(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("excitation grid"), "{stderr}");
    assert!(!report.exists() || files_in(&report).is_empty());

    // Unwritable output folder (under a regular file): error, no files.
    let blocked = other_path.join("figures");
    let out = fluorite(&[
        "plot".as_ref(),
        material_path.as_os_str(),
        "-o".as_ref(),
        blocked.as_os_str(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("output folder"));

    // Matching data, SVG into a new folder: all four figures.
    let data_path = dir.path().join("synth.csv");
    write_wide_csv(&synthetic_measurement(&material, NOISE, true), &data_path);
    let out = fluorite(&[
        "plot".as_ref(),
        material_path.as_os_str(),
        "--data".as_ref(),
        data_path.as_os_str(),
        "--svg".as_ref(),
        "-o".as_ref(),
        report.as_os_str(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let names: Vec<String> = files_in(&report)
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            "SYNTH-colour.svg",
            "SYNTH-convergence.svg",
            "SYNTH-residuals.svg",
            "SYNTH-spectra.svg"
        ]
    );
}

/// A rough rank-1 material for a real matrix (stand-in for `fluorite fit`, which these
/// tests must not depend on): e from the Stokes column sums, a by least squares given e,
/// c in the middle of its feasible interval, r = d / (1 − c·a).
pub fn crude_rank1_material(m: &Measurement, guard_nm: f64) -> Material {
    let (n_ex, n_em) = (m.n_excitation(), m.n_emission());
    let widths = bin_widths(&m.emission_nm);
    let stokes = |i: usize, j: usize| m.cell_kind(i, j, guard_nm) == CellKind::Stokes;
    let mut e = vec![0.0; n_em];
    for i in 0..n_ex {
        for j in 0..n_em {
            if stokes(i, j) {
                e[j] += m.get(i, j).max(0.0) / widths[j];
            }
        }
    }
    let area: f64 = e.iter().zip(&widths).map(|(v, w)| v * w).sum();
    let e: Vec<f64> = e.iter().map(|v| v / area).collect();
    let mut amplitude = vec![0.0; n_ex];
    for (i, amp) in amplitude.iter_mut().enumerate() {
        let (mut num, mut den) = (0.0, 0.0);
        for j in 0..n_em {
            if stokes(i, j) {
                let basis = e[j] * widths[j];
                num += m.get(i, j) * basis;
                den += basis * basis;
            }
        }
        *amp = if den > 0.0 { (num / den).max(0.0) } else { 0.0 };
    }
    let k = amplitude.iter().cloned().fold(0.0, f64::max);
    let a: Vec<f64> = amplitude.iter().map(|v| v / k).collect();
    let absorption = Spectrum::new(m.excitation_nm.clone(), a, "a").unwrap();
    let emission = Spectrum::new(m.emission_nm.clone(), e, "e").unwrap();
    let diagonal: Vec<(f64, f64)> = m
        .diagonal()
        .into_iter()
        .map(|(i, j)| (m.emission_nm[j], m.get(i, j).clamp(0.0, 1.0)))
        .collect();
    let mean_emission = emission.mean_wavelength_nm();
    let shortest = m.excitation_nm[0];
    let low = k.max(k * mean_emission / shortest);
    let high = diagonal
        .iter()
        .map(|&(l, d)| {
            let a = absorption.eval_zero_outside(l);
            if a > 0.0 { (1.0 - d) / a } else { 1.0 }
        })
        .fold(1.0, f64::min);
    let c = (0.5 * (low + high)).clamp(low.min(1.0), 1.0);
    let r: Vec<f64> = diagonal
        .iter()
        .map(|&(l, d)| (d / (1.0 - c * absorption.eval_zero_outside(l))).clamp(0.0, 1.0))
        .collect();
    let mut r_grid: Vec<f64> = diagonal.iter().map(|p| p.0).collect();
    let mut r = r;
    if r_grid.is_empty() {
        // Solution EEMs carry no diagonal: reflectance is undetermined.
        r_grid = m.emission_nm.clone();
        r = vec![0.0; r_grid.len()];
    }
    let mut material = Material::new(
        m.name.clone(),
        Spectrum::new(r_grid, r, "r").unwrap(),
        vec![Fluorophore {
            concentration: c,
            // Photon conservation may cap Q below k/c where the data's crude k is too big.
            quantum_yield: (k / c).min(1.0).min(shortest / mean_emission),
            yield_form: fluorite::YieldForm::Energy,
            concentration_range: None,
            absorption,
            emission,
        }],
    );
    material.fit = Some(FitReport {
        source: m.name.clone(),
        solver: "rank1-test".to_string(),
        guard_nm,
        cost_history: vec![1.0, 0.2, 0.05, 0.04],
        ..FitReport::default()
    });
    material
}

#[test]
fn real_matrix_renders_with_noise_negatives_and_crosstalk() {
    let Some(path) = common::measured("HERPICER.BFC") else {
        return;
    };
    let measured = fluorite::formats::read(&path, &Default::default()).unwrap();
    assert_eq!((measured.n_excitation(), measured.n_emission()), (49, 41));
    let material = crude_rank1_material(&measured, GUARD_NM);
    let plots = plot::plot(&material, Some(&measured), &PlotOptions::default()).unwrap();
    assert_eq!(plots.figures.len(), 4);
    let residuals = &plots.figures[0];
    let (w, h, rgb) = decode_png(&residuals.bytes);
    assert_eq!((w, h), FigureKind::Residuals.size());
    let panel = &residuals.layout.heatmaps[0];

    // Independent scale: the largest measured or fitted value more than one step off the
    // diagonal.
    let fitted = model::predict(
        &material,
        "fit",
        &measured.excitation_nm,
        &measured.emission_nm,
        Units::PerBin,
        true,
    );
    let mut value_max = 0.0f64;
    let mut negative = None;
    for i in 0..measured.n_excitation() {
        for j in 0..measured.n_emission() {
            if (measured.emission_nm[j] - measured.excitation_nm[i]).abs() > GUARD_NM + 1e-6 {
                value_max = value_max.max(measured.get(i, j)).max(fitted.get(i, j));
                if measured.get(i, j) < 0.0 {
                    negative = Some((i, j));
                }
            }
        }
    }
    assert!((panel.scale.max - value_max).abs() < 1e-15);
    // HERPICER fluoresces near 600 nm for excitation around 540 nm.
    let i = measured
        .excitation_nm
        .iter()
        .position(|&l| l == 540.0)
        .unwrap();
    let j = measured
        .emission_nm
        .iter()
        .position(|&l| l == 600.0)
        .unwrap();
    let v = measured.get(i, j);
    assert!(v > 0.2 * value_max, "{v} vs {value_max}");
    assert_eq!(
        pixel(&rgb, w, panel.cell_centre_px(i, j)),
        as_array(viridis(v / value_max))
    );
    // Negative noise clamps to the bottom of the map.
    let (i, j) = negative.expect("real data hold negative cells");
    assert_eq!(
        pixel(&rgb, w, panel.cell_centre_px(i, j)),
        as_array(viridis(0.0))
    );
}

// ---------------------------------------------------------------------------------------
// Several fluorophores, and materials with continuous forms.

use fluorite::parametric::{
    BandDomain, FluorophoreForms, GaussianBand, GaussianBands, MaterialForms, SpectralForm,
};
use fluorite::synth::{Band, SynthSpec};

use crate::common;
use crate::common::decode_png;

/// The `two-dyes` preset's truth: a UV brightener (a at 365 nm, e at 440 nm) and an
/// orange-red dye (a at 545 nm, e at 610 nm), on the BFC-450 grids.
fn two_dyes() -> (SynthSpec, Material) {
    let spec = SynthSpec::preset("two-dyes").unwrap();
    let truth = spec.truth().unwrap();
    assert_eq!(truth.fluorophores.len(), 2);
    (spec, truth)
}

/// `bands` (wavelength Gaussians) scaled so they equal `samples` at the sample points.
fn form_of(bands: &[Band], samples: &Spectrum) -> SpectralForm {
    let raw = |l: f64| -> f64 {
        bands
            .iter()
            .map(|b| b.weight * (-0.5 * ((l - b.centre_nm) / b.width_nm).powi(2)).exp())
            .sum()
    };
    // The samples are the bands divided by one constant (peak or area on the grid).
    let (l, v) = samples
        .wavelength_nm
        .iter()
        .zip(&samples.value)
        .max_by(|a, b| a.1.total_cmp(b.1))
        .unwrap();
    let scale = v / raw(*l);
    let grid = &samples.wavelength_nm;
    SpectralForm::GaussianBands(GaussianBands {
        domain: BandDomain::Wavelength,
        support_nm: [grid[0], grid[grid.len() - 1]],
        bands: bands
            .iter()
            .map(|b| GaussianBand {
                centre_nm: b.centre_nm,
                width: b.width_nm,
                height: b.weight * scale,
            })
            .collect(),
    })
}

/// The two-dyes truth with a `forms` block: the Gaussian bands that generated it.
fn two_dyes_with_forms() -> (SynthSpec, Material) {
    let (spec, mut material) = two_dyes();
    let bands = [
        (&spec.absorption, &spec.emission),
        (&spec.components[0].absorption, &spec.components[0].emission),
    ];
    material.forms = Some(MaterialForms {
        model: "gaussian:2x2".to_string(),
        reflectance: None,
        fluorophores: material
            .fluorophores
            .iter()
            .zip(bands)
            .map(|(f, (a, e))| FluorophoreForms {
                absorption: form_of(a, &f.absorption),
                emission: form_of(e, &f.emission),
            })
            .collect(),
    });
    material.validate().unwrap();
    (spec, material)
}

/// Whether a pixel of colour `colour` lies within `radius` px of `at`.
fn colour_near(rgb: &[u8], width: u32, at: (f64, f64), radius: i32, colour: [u8; 3]) -> bool {
    let (x, y) = (at.0.round() as i32, at.1.round() as i32);
    (-radius..=radius).any(|dy| {
        (-radius..=radius).any(|dx| {
            let (px, py) = (x + dx, y + dy);
            px >= 0 && py >= 0 && pixel(rgb, width, (px, py)) == colour
        })
    })
}

fn spectra_figure(plots: &Plots) -> &plot::Figure {
    plots
        .figures
        .iter()
        .find(|f| f.kind == FigureKind::Spectra)
        .unwrap()
}

#[test]
fn two_fluorophore_spectra_show_each_component_in_its_own_colour() {
    let (_, material) = two_dyes();
    let plots = plot::plot(&material, None, &PlotOptions::default()).unwrap();
    let figure = spectra_figure(&plots);
    let panel = figure.layout.spectra.as_ref().unwrap();
    assert_eq!(panel.forms_model, None);
    let labels: Vec<&str> = panel.curves.iter().map(|c| c.label.as_str()).collect();
    assert_eq!(labels.len(), 6, "{labels:?}");
    for (k, prefix) in [
        "a₁(λ)",
        "e₁(λ)",
        "a₂(λ)",
        "e₂(λ)",
        "r(λ)",
        "d(λ) = (1 − Σc·a)",
    ]
    .iter()
    .enumerate()
    {
        assert!(labels[k].starts_with(prefix), "{labels:?}");
    }
    let (a1, e1) = (panel.curve("a₁").unwrap(), panel.curve("e₁").unwrap());
    let (a2, e2) = (panel.curve("a₂").unwrap(), panel.curve("e₂").unwrap());
    // One colour per component: a and e share it (a solid, e dashed), components differ.
    assert_eq!(a1.colour, e1.colour);
    assert_eq!(a2.colour, e2.colour);
    assert_ne!(a1.colour, a2.colour);
    assert!(!a1.dashed && e1.dashed && !a2.dashed && e2.dashed);
    // The e legend gives the divisor that scales e to peak 1.
    for (n, label) in [(0, &e1.label), (1, &e2.label)] {
        let e_max = material.fluorophores[n].emission.max();
        let shown: f64 = label
            .split("÷ ")
            .nth(1)
            .and_then(|t| t.split(' ').next())
            .and_then(|t| t.parse().ok())
            .unwrap_or_else(|| panic!("{label}"));
        assert!((shown / e_max - 1.0).abs() < 5e-3, "{label} vs {e_max}");
    }

    // Pixel probes at values taken from the truth material, not from the drawn curves.
    let (w, _, rgb) = decode_png(&figure.bytes);
    let [b, d] = [&material.fluorophores[0], &material.fluorophores[1]];
    let scaled_e = |f: &Fluorophore, nm: f64| f.emission.eval_zero_outside(nm) / f.emission.max();
    for (nm, value, colour, other, what) in [
        (
            360.0,
            b.absorption.eval_zero_outside(360.0),
            a1.colour,
            a2.colour,
            "a₁ peak",
        ),
        (
            350.0,
            b.absorption.eval_zero_outside(350.0),
            a1.colour,
            a2.colour,
            "a₁ flank",
        ),
        (
            550.0,
            d.absorption.eval_zero_outside(550.0),
            a2.colour,
            a1.colour,
            "a₂ peak",
        ),
        (
            530.0,
            d.absorption.eval_zero_outside(530.0),
            a2.colour,
            a1.colour,
            "a₂ flank",
        ),
        (440.0, scaled_e(b, 440.0), e1.colour, e2.colour, "e₁ peak"),
        (610.0, scaled_e(d, 610.0), e2.colour, e1.colour, "e₂ peak"),
    ] {
        assert!(value > 0.3, "{what}: {value}");
        let at = panel.pixel(nm, value);
        // Dashed emission: a dash is within half a gap of any point on the line.
        assert!(
            colour_near(&rgb, w, at, 5, colour),
            "{what} ({nm} nm, {value:.3}) at pixel {at:?} lacks {colour:?}"
        );
        assert!(
            !colour_near(&rgb, w, at, 5, other),
            "{what} at pixel {at:?} shows the other component's colour {other:?}"
        );
    }
    // The diagonal dips where each component absorbs: (1 − c·a)·r from the truth.
    let diagonal = panel.curve("d(λ)").unwrap();
    let at = panel.pixel(550.0, material.diagonal(550.0));
    assert!(material.diagonal(550.0) < 0.4);
    assert!(colour_near(&rgb, w, at, 4, diagonal.colour));
}

#[test]
fn continuous_forms_are_drawn_every_nanometre_and_named() {
    let (spec, material) = two_dyes_with_forms();
    let options = PlotOptions::default();
    let plots = plot::plot(&material, None, &options).unwrap();
    let figure = spectra_figure(&plots);
    let panel = figure.layout.spectra.as_ref().unwrap();
    assert_eq!(panel.forms_model.as_deref(), Some("gaussian:2x2"));
    let a2 = panel.curve("a₂").unwrap();
    // Every nanometre over the sampled range 300–780 nm.
    assert_eq!(a2.points.len(), 481);
    assert!(
        a2.points
            .windows(2)
            .all(|p| (p[1].0 - p[0].0 - 1.0).abs() < 1e-9)
    );
    // Between the 10 nm samples the form rises above their straight line: at 545 nm
    // (the band centre, halfway between the samples at 540 and 550 nm, both 1) the form
    // is 1 / exp(−½(5/18)²).
    let band = spec.components[0].absorption[0];
    assert_eq!(band.centre_nm, 545.0);
    let form_545 = 1.0 / (-0.5 * (5.0 / band.width_nm).powi(2)).exp();
    let drawn = a2.points.iter().find(|p| p.0 == 545.0).unwrap().1;
    assert!((drawn - form_545).abs() < 1e-9, "{drawn} vs {form_545}");
    let linear = material.fluorophores[1].absorption.eval_zero_outside(545.0);
    assert!((linear - 1.0).abs() < 1e-9);
    let (w, _, rgb) = decode_png(&figure.bytes);
    let (form_px, linear_px) = (panel.pixel(545.0, form_545), panel.pixel(545.0, linear));
    assert!(form_px.1 < linear_px.1 - 8.0, "{form_px:?} {linear_px:?}");
    assert!(colour_near(&rgb, w, form_px, 2, a2.colour));
    assert!(!colour_near(&rgb, w, linear_px, 2, a2.colour));

    // The title and the legend name the model (SVG keeps the text).
    let svg = plot::plot(
        &material,
        None,
        &PlotOptions {
            format: ImageFormat::Svg,
            guard_nm: None,
        },
    )
    .unwrap();
    let text = std::str::from_utf8(&spectra_figure(&svg).bytes).unwrap();
    assert!(text.contains("two-dyes: fitted spectra (gaussian:2x2)"));
    assert!(text.contains("model gaussian:2x2"));
    assert!(text.contains("(forms drawn every 1 nm)"));

    // Without forms the same material draws its samples.
    let mut samples_only = material.clone();
    samples_only.forms = None;
    let plots = plot::plot(&samples_only, None, &options).unwrap();
    let panel = spectra_figure(&plots).layout.spectra.clone().unwrap();
    assert_eq!(panel.curve("a₂").unwrap().points.len(), 49);
}

#[test]
fn two_fluorophore_heat_map_and_swatches_sum_the_components() {
    let (spec, material) = two_dyes();
    let ex = &spec.excitation_nm;
    let em = &spec.emission_nm;
    let measured = model::predict(&material, "two-dyes", ex, em, Units::PerBin, true);
    let plots = plot::plot(&material, Some(&measured), &PlotOptions::default()).unwrap();
    let residuals = &plots.figures[0];
    assert_eq!(residuals.kind, FigureKind::Residuals);
    let (w, _, rgb) = decode_png(&residuals.bytes);
    let panels = &residuals.layout.heatmaps;
    let widths = bin_widths(em);
    // Independent of `predict`: Σ c·Q·a(λi)·e(λo)·Δλo from the spectra's samples.
    let cell = |i: usize, j: usize| -> f64 {
        material
            .fluorophores
            .iter()
            .map(|f| f.k() * f.absorption.value[i] * f.emission.value[j] * widths[j])
            .sum()
    };
    let mut value_max = 0.0f64;
    for (i, li) in ex.iter().enumerate() {
        for (j, lo) in em.iter().enumerate() {
            if (lo - li).abs() > 10.0 + 1e-6 {
                value_max = value_max.max(cell(i, j));
            }
        }
    }
    assert!((panels[1].scale.max - value_max).abs() < 1e-12);
    let idx = |nm: f64, grid: &[f64]| grid.iter().position(|&g| g == nm).unwrap();
    for (ex_nm, em_nm) in [
        (360.0, 440.0),
        (550.0, 610.0),
        (370.0, 620.0),
        (540.0, 450.0),
    ] {
        let (i, j) = (idx(ex_nm, ex), idx(em_nm, em));
        let v = cell(i, j);
        for panel in &panels[..2] {
            assert_eq!(
                pixel(&rgb, w, panel.cell_centre_px(i, j)),
                as_array(viridis(v / value_max)),
                "{} ({ex_nm}, {em_nm})",
                panel.title
            );
        }
    }
    // Both components fluoresce visibly: each peak cell is in the top half of the map.
    assert!(cell(idx(360.0, ex), idx(440.0, em)) > 0.5 * value_max);
    assert!(cell(idx(550.0, ex), idx(610.0, em)) > 0.5 * value_max);

    // Swatches: the model's own matrix matches exactly; data without the brightener do
    // not, least of all under UV light, which only the brightener turns into blue.
    let colour = plots
        .figures
        .iter()
        .find(|f| f.kind == FigureKind::Colour)
        .unwrap();
    let (w, _, rgb) = decode_png(&colour.bytes);
    for s in &colour.layout.swatches {
        assert!(s.pair.delta_e2000 < 1e-9, "{}", s.pair.light);
        let rect = s.fitted_rect_px;
        let centre = ((rect[0] + rect[2]) / 2, (rect[1] + rect[3]) / 2);
        assert_eq!(pixel(&rgb, w, centre), s.pair.fitted_srgb);
    }
    let mut dye_only = material.clone();
    dye_only.fluorophores.remove(0);
    let without = model::predict(&dye_only, "dye only", ex, em, Units::PerBin, true);
    let plots = plot::plot(&material, Some(&without), &PlotOptions::default()).unwrap();
    let colour = plots
        .figures
        .iter()
        .find(|f| f.kind == FigureKind::Colour)
        .unwrap();
    let uv = colour
        .layout
        .swatches
        .iter()
        .find(|s| s.pair.light == "uv")
        .unwrap();
    let d65 = &colour.layout.swatches[0];
    assert!(uv.pair.delta_e2000 > 5.0, "UV ΔE {}", uv.pair.delta_e2000);
    assert!(uv.pair.delta_e2000 > d65.pair.delta_e2000);
    // Under UV the fitted (both components) swatch is bluer than the dye-only data.
    let (fitted, data) = (uv.pair.fitted_srgb, uv.pair.measured_srgb);
    assert!(fitted[2] as i32 - fitted[0] as i32 > data[2] as i32 - data[0] as i32);
}

// ---- the photon-yield form --------------------------------------------------------------

/// λ̄e = ∫λ·e dλ / ∫e dλ by the trapezoid rule on the emission's samples, written out here.
fn mean_emission(f: &Fluorophore) -> f64 {
    let w = bin_widths(&f.emission.wavelength_nm);
    let e = &f.emission;
    let num: f64 = (0..e.len())
        .map(|i| w[i] * e.value[i] * e.wavelength_nm[i])
        .sum();
    let den: f64 = (0..e.len()).map(|i| w[i] * e.value[i]).sum();
    num / den
}

#[test]
fn photon_form_profiles_follow_the_absorption_and_the_figure_states_phi() {
    // A single photon-form fluorophore: the profile is the data's absorption, on the drawn
    // a curve (the measured/fitted row ratio cancels the factor λ/λ̄e).
    let mut material = synthetic_material();
    material.fluorophores[0].yield_form = fluorite::YieldForm::Photon;
    material.fluorophores[0].quantum_yield = 0.8;
    material.validate().unwrap();
    let measured = synthetic_measurement(&material, 0.0, false);
    let comparison = plot::Comparison::new(&material, &measured, GUARD_NM);
    let profiles = plot::spectra::data_profiles(&material, &comparison);
    let f = &material.fluorophores[0];
    let e_max = f.emission.max();
    assert!(profiles.excitation.len() > 10 && profiles.emission.len() > 10);
    for &(l, v) in &profiles.excitation {
        assert!(
            (v - f.absorption.eval_zero_outside(l)).abs() < 1e-9,
            "a at {l}: {v}"
        );
    }
    for &(l, v) in &profiles.emission {
        assert!(
            (v - f.emission.eval_zero_outside(l) / e_max).abs() < 1e-9,
            "e at {l}: {v}"
        );
    }
    // The parameters: Φ and the energy yield over the absorbed wavelengths (300–780 nm,
    // the Gaussian absorption is positive on the whole grid).
    let options = PlotOptions {
        format: ImageFormat::Svg,
        guard_nm: None,
    };
    let plots = plot::plot(&material, Some(&measured), &options).unwrap();
    let spectra = plots
        .figures
        .iter()
        .find(|f| f.kind == FigureKind::Spectra)
        .unwrap();
    let svg = std::str::from_utf8(&spectra.bytes).unwrap();
    let mean = mean_emission(f);
    let q = |l: f64| 0.8 * l / mean;
    assert!(svg.contains("k = c·Φ = 0.48"), "k line missing");
    let prefix = "Φ = 0.8 (photon yield), Q(λ) ";
    let at = svg.find(prefix).expect("yield line missing") + prefix.len();
    let range: String = svg[at..]
        .chars()
        .take_while(|c| c.is_ascii_digit() || *c == '.' || *c == '–')
        .collect();
    let (lo, hi) = range.split_once('–').unwrap();
    // Two significant digits.
    let (lo, hi): (f64, f64) = (lo.parse().unwrap(), hi.parse().unwrap());
    assert!((lo - q(300.0)).abs() <= 0.005, "{lo} vs {}", q(300.0));
    assert!((hi - q(780.0)).abs() <= 0.05, "{hi} vs {}", q(780.0));
}

#[test]
fn mixed_form_profiles_follow_the_combined_row_factor() {
    // Two dyes, the second in the photon form: the excitation profile follows
    // Σ c·Q(λ)·a(λ) with Q(λ) = Φ·λ/λ̄e for the second, scaled to peak 1 (computed here).
    let (_, mut material) = two_dyes();
    material.fluorophores[1].yield_form = fluorite::YieldForm::Photon;
    material.fluorophores[1].quantum_yield = 0.9;
    material.validate().unwrap();
    let ex = uniform_grid(300.0, 780.0, 10.0);
    let em = uniform_grid(380.0, 780.0, 10.0);
    let measured = model::predict(&material, "MIXED", &ex, &em, Units::PerBin, true);
    let comparison = plot::Comparison::new(&material, &measured, GUARD_NM);
    let profiles = plot::spectra::data_profiles(&material, &comparison);
    let means: Vec<f64> = material.fluorophores.iter().map(mean_emission).collect();
    let row = |l: f64| -> f64 {
        material
            .fluorophores
            .iter()
            .zip(&means)
            .map(|(f, mean)| {
                let x = match f.yield_form {
                    fluorite::YieldForm::Energy => 1.0,
                    fluorite::YieldForm::Photon => l / mean,
                };
                f.concentration * f.quantum_yield * x * f.absorption.eval_zero_outside(l)
            })
            .sum()
    };
    let peak = ex.iter().map(|&l| row(l)).fold(0.0, f64::max);
    assert!(profiles.excitation.len() > 5);
    for &(l, v) in &profiles.excitation {
        assert!(
            (v - row(l) / peak).abs() < 1e-9,
            "{l}: {v} vs {}",
            row(l) / peak
        );
    }
}
