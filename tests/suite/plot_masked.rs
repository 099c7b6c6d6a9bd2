//! Residual maps of EEM fits show the cells scatter masking removed as masked (hatched,
//! with a legend entry), apart from cells the file never recorded (plain grey).

use crate::common;

use fluorite::eem::scatter::{ScatterOptions, WATER_RAMAN_SHIFT_CM};
use fluorite::eem::{EemOptions, prepare};
use fluorite::fit::{FitOptions, FitOutcome, fit};
use fluorite::formats::{ReadOptions, read};
use fluorite::measurement::{Measurement, Units};
use fluorite::plot::heatmap::{CellClass, cell_classes};
use fluorite::plot::{self, Comparison, FigureKind, PlotOptions, colormap};

/// Half-width of every scatter band (nm), set so the masked cells are known.
const BAND_NM: f64 = 8.0;

/// A small uncalibrated EEM: one fluorophore in counts, first- and second-order Rayleigh
/// lines far above it, and a few cells not recorded (NaN) away from every line.
fn eem() -> (Measurement, Vec<(usize, usize)>) {
    let ex: Vec<f64> = (0..16).map(|i| 240.0 + 10.0 * i as f64).collect();
    let em: Vec<f64> = (0..50).map(|j| 250.0 + 6.0 * j as f64).collect();
    let mut values = Vec::new();
    for &x in &ex {
        for &l in &em {
            let a = (-0.5 * ((x - 300.0) / 25.0f64).powi(2)).exp();
            let e = (-0.5 * ((l - 420.0) / 30.0f64).powi(2)).exp();
            let rayleigh = |c: f64| 5e5 * (-0.5 * ((l - c) / 3.0f64).powi(2)).exp();
            values.push(2e4 * a * e + rayleigh(x) + rayleigh(2.0 * x) + 10.0);
        }
    }
    let mut m = Measurement::new("eem", ex, em, values, Units::PerBin).unwrap();
    let not_recorded = vec![(3, 30), (10, 40), (12, 45)];
    for &(i, j) in &not_recorded {
        *m.get_mut(i, j) = f64::NAN;
    }
    (m, not_recorded)
}

/// Whether emission `l` under excitation `x` lies within `BAND_NM` of a scatter line:
/// Rayleigh λ and 2λ, water Raman 1/(1/λ − 3400 cm⁻¹) and twice that.
fn in_a_band(x: f64, l: f64) -> bool {
    let raman = 1.0 / (1.0 / x - WATER_RAMAN_SHIFT_CM * 1e-7);
    [x, 2.0 * x, raman, 2.0 * raman]
        .iter()
        .any(|c| (l - c).abs() <= BAND_NM + 1e-9)
}

fn prepared() -> (Measurement, Vec<(usize, usize)>, FitOutcome) {
    let (raw, not_recorded) = eem();
    let options = EemOptions {
        scatter: ScatterOptions {
            half_width_nm: [Some(BAND_NM); 4],
            ..ScatterOptions::default()
        },
        ..EemOptions::default()
    };
    let (m, preprocessing) = prepare(raw, &options).unwrap();
    let mut outcome = fit(&m, &FitOptions::default()).unwrap();
    let FitOutcome::Shapes(shapes) = &mut outcome else {
        panic!("an EEM in counts gives shapes");
    };
    shapes.fit.preprocessing = preprocessing;
    (m, not_recorded, outcome)
}

/// The classes the drawing uses: every cell within a band of a scatter line is masked,
/// the cells the file did not hold (outside the bands) are not recorded, the rest fitted.
#[test]
fn masked_scatter_and_unrecorded_cells_have_their_own_classes() {
    let (m, not_recorded, outcome) = prepared();
    let FitOutcome::Shapes(shapes) = &outcome else {
        unreachable!()
    };
    let material = plot::shapes_material(shapes);
    let comparison = Comparison::new(&material, &m, shapes.fit.guard_nm);
    let classes = cell_classes(&comparison);
    let n_em = m.n_emission();
    let (mut masked, mut missing) = (0, 0);
    for (i, &x) in m.excitation_nm.iter().enumerate() {
        for (j, &l) in m.emission_nm.iter().enumerate() {
            let expected = if in_a_band(x, l) {
                masked += 1;
                CellClass::Masked
            } else if not_recorded.contains(&(i, j)) {
                missing += 1;
                CellClass::Missing
            } else {
                CellClass::Fitted
            };
            assert_eq!(classes[i * n_em + j], expected, "cell {x} nm → {l} nm");
        }
    }
    assert!(
        masked > 50 && missing == not_recorded.len(),
        "{masked} {missing}"
    );
}

/// The figure draws them so: a masked cell holds both the hatch and its light-grey
/// background on the measured and residual panels and the hatch over the model's colour
/// on the fitted panel; an unrecorded cell is plain grey.
#[test]
fn the_residual_map_hatches_masked_cells() {
    let (m, not_recorded, outcome) = prepared();
    let plots = plot::plot_outcome(&outcome, &m, &PlotOptions::default()).unwrap();
    let figure = plots
        .figures
        .iter()
        .find(|f| f.kind == FigureKind::Residuals)
        .expect("an EEM fit gets a residual map");
    let (width, _, image) = common::decode_png(&figure.bytes);
    let pixel = |(x, y): (i32, i32)| {
        let k = 3 * (y as usize * width as usize + x as usize);
        [image[k], image[k + 1], image[k + 2]]
    };
    let rgb = |c: plotters::style::RGBColor| [c.0, c.1, c.2];
    let n_em = m.n_emission();
    // A masked cell well inside the first-order Rayleigh band (excitation 300 nm).
    let i = 6;
    let j = m
        .emission_nm
        .iter()
        .position(|&l| (l - 298.0).abs() < 1e-9)
        .unwrap();
    assert!(in_a_band(m.excitation_nm[i], m.emission_nm[j]));
    for (p, panel) in figure.layout.heatmaps.iter().enumerate() {
        let [left, top, right, bottom] = panel.cell_rect_px(i, j);
        let colours: Vec<[u8; 3]> = (left..right)
            .flat_map(|x| (top..bottom).map(move |y| (x, y)))
            .map(pixel)
            .collect();
        assert!(
            colours.contains(&rgb(colormap::HATCH)),
            "panel {p}: no hatch in the masked cell"
        );
        if p != 1 {
            assert!(
                colours.contains(&rgb(colormap::MASKED)),
                "panel {p}: no masked background"
            );
        }
        let (i, j) = not_recorded[0];
        if p != 1 {
            let [left, top, right, bottom] = panel.cell_rect_px(i, j);
            for x in left..right {
                for y in top..bottom {
                    assert_eq!(pixel((x, y)), rgb(colormap::MISSING), "panel {p}");
                }
            }
        }
    }
    assert_eq!(figure.layout.heatmaps[0].excitation_edges_nm.len(), 17);
    assert_eq!(n_em, 50);
}

/// The staRdom sample (`eem-instrument/stardom_d433sf.csv`) as `fit` prepares it: every
/// cell the scatter step removed (finite and non-zero in the file, missing after) is
/// drawn as masked, and every cell the file holds as 0 outside the bands as not recorded.
#[test]
fn stardom_sample_draws_its_masked_scatter_as_masked() {
    let Some(path) = common::shared("eem-instrument/stardom_d433sf.csv") else {
        return;
    };
    let raw = read(&path, &ReadOptions::default()).unwrap();
    let (m, preprocessing) = prepare(raw.clone(), &EemOptions::default()).unwrap();
    let preprocessing = preprocessing.expect("the sample is an uncalibrated EEM");
    let mut outcome = fit(&m, &FitOptions::default()).unwrap();
    let FitOutcome::Shapes(shapes) = &mut outcome else {
        panic!("an EEM in counts gives shapes");
    };
    shapes.fit.preprocessing = Some(preprocessing.clone());
    let material = plot::shapes_material(shapes);
    let classes = cell_classes(&Comparison::new(&material, &m, shapes.fit.guard_nm));
    let (mut removed, mut zeros) = (0, 0);
    for (k, (before, after)) in raw.values.iter().zip(&m.values).enumerate() {
        if before.is_finite() && *before != 0.0 && after.is_nan() {
            removed += 1;
            assert_eq!(classes[k], CellClass::Masked, "cell {k}");
        }
        let (i, j) = (k / m.n_emission(), k % m.n_emission());
        let outside = !preprocessing.masks(m.excitation_nm[i], m.emission_nm[j]);
        if *before == 0.0 && outside {
            zeros += 1;
            assert_eq!(classes[k], CellClass::Missing, "cell {k}");
        }
    }
    let reported: usize = preprocessing.scatter.iter().map(|b| b.cells).sum();
    assert_eq!(removed, reported);
    println!("{removed} masked scatter cells, {zeros} cells not recorded outside the bands");
    let plots = plot::plot_outcome(&outcome, &m, &PlotOptions::default()).unwrap();
    if let Ok(dir) = std::env::var("FLUORITE_PLOT_DIR") {
        plot::write_plots(&plots, std::path::Path::new(&dir), "stardom_d433sf").unwrap();
    }
}
