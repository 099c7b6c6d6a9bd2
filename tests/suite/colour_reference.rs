//! What `fit` reports about its colour, recomputed apart from the code under test.
//!
//! Everything the reference needs is computed here from the raw data: a BFC-450 reader
//! of its own, the material evaluated from the written JSON (both yield forms), the CIE
//! tables read from `../shared/data/cie`, its own hat projection of lights and observer on
//! a 1 nm grid, its own CIELAB and CIEDE2000 (model.md §7). Only `fit` itself, the
//! synthetic generator and the material's JSON come from the library.

use std::path::Path;

use fluorite::fit::{FitOptions, FitOutcome, fit};
use fluorite::formats::{ReadOptions, read};
use fluorite::synth::SynthSpec;
use serde_json::Value;

use crate::common;

/// A matrix M[excitation][emission] on its grids.
struct Matrix {
    excitation: Vec<f64>,
    emission: Vec<f64>,
    values: Vec<Vec<f64>>,
}

/// BFC-450 matrix file: rows are emission, columns excitation (data README).
fn read_bfc(path: &Path) -> Matrix {
    let bytes = std::fs::read(path).unwrap();
    let text: String = bytes.iter().map(|&b| b as char).collect(); // latin-1
    let lines: Vec<&str> = text.lines().map(|l| l.trim_end_matches('\r')).collect();
    let start = lines.iter().position(|l| l.starts_with("r:c:")).unwrap();
    let excitation: Vec<f64> = lines[start]
        .split('\t')
        .skip(1)
        .filter(|s| !s.trim().is_empty())
        .map(|s| s.trim().parse().unwrap())
        .collect();
    let mut emission = Vec::new();
    let mut rows = Vec::new();
    for line in &lines[start + 1..] {
        if line.trim() == "EOD" || line.trim().is_empty() {
            break;
        }
        let fields: Vec<f64> = line
            .split('\t')
            .filter(|s| !s.trim().is_empty())
            .map(|s| s.trim().parse().unwrap())
            .collect();
        emission.push(fields[0]);
        rows.push(fields[1..=excitation.len()].to_vec());
    }
    let values = (0..excitation.len())
        .map(|i| rows.iter().map(|r| r[i]).collect())
        .collect();
    Matrix {
        excitation,
        emission,
        values,
    }
}

/// Linear interpolation of a table; `hold` keeps the end values outside, else zero.
fn interpolate(x: &[f64], y: &[f64], at: f64, hold: bool) -> f64 {
    if at < x[0] || at > x[x.len() - 1] {
        return if hold {
            if at < x[0] { y[0] } else { y[y.len() - 1] }
        } else {
            0.0
        };
    }
    let k = x.partition_point(|&v| v < at);
    if k == 0 || (x[k] - at).abs() < 1e-12 {
        return y[k];
    }
    let t = (at - x[k - 1]) / (x[k] - x[k - 1]);
    y[k - 1] + t * (y[k] - y[k - 1])
}

fn spectrum(value: &Value) -> (Vec<f64>, Vec<f64>) {
    let list = |key: &str| -> Vec<f64> {
        value[key]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect()
    };
    (list("wavelength_nm"), list("value"))
}

fn trapezoid(x: &[f64], y: &[f64]) -> f64 {
    x.windows(2)
        .zip(y.windows(2))
        .map(|(xs, ys)| 0.5 * (xs[1] - xs[0]) * (ys[0] + ys[1]))
        .sum()
}

/// Emission bin widths by the trapezoid rule (half bins at the ends, model.md §2).
fn bin_widths(grid: &[f64]) -> Vec<f64> {
    (0..grid.len())
        .map(|j| {
            let lo = if j > 0 { grid[j] - grid[j - 1] } else { 0.0 };
            let hi = if j + 1 < grid.len() {
                grid[j + 1] - grid[j]
            } else {
                0.0
            };
            0.5 * (lo + hi)
        })
        .collect()
}

/// The matrix the material JSON predicts on the grids, per emission bin.
fn model_matrix(material: &Value, excitation: &[f64], emission: &[f64]) -> Vec<Vec<f64>> {
    let widths = bin_widths(emission);
    let (r_nm, r) = spectrum(&material["reflectance"]);
    let mut m = vec![vec![0.0; emission.len()]; excitation.len()];
    let mut absorbed = vec![0.0; excitation.len()];
    for f in material["fluorophores"].as_array().unwrap() {
        let c = f["concentration"].as_f64().unwrap();
        let (a_nm, a) = spectrum(&f["absorption"]);
        let (e_nm, e) = spectrum(&f["emission"]);
        let mean = trapezoid(
            &e_nm,
            &e_nm.iter().zip(&e).map(|(l, v)| l * v).collect::<Vec<_>>(),
        ) / trapezoid(&e_nm, &e);
        let energy_yield = |l: f64| match f.get("yield_form").and_then(Value::as_str) {
            Some("photon") => f["photon_yield"].as_f64().unwrap() * l / mean,
            _ => f["quantum_yield"].as_f64().unwrap(),
        };
        for (i, &li) in excitation.iter().enumerate() {
            let ai = interpolate(&a_nm, &a, li, false);
            absorbed[i] += c * ai;
            for (j, &lo) in emission.iter().enumerate() {
                m[i][j] +=
                    c * energy_yield(li) * ai * interpolate(&e_nm, &e, lo, false) * widths[j];
            }
        }
    }
    for (i, &li) in excitation.iter().enumerate() {
        if let Some(j) = emission.iter().position(|&lo| (lo - li).abs() < 1e-9) {
            m[i][j] += (1.0 - absorbed[i]) * interpolate(&r_nm, &r, li, true);
        }
    }
    m
}

fn read_table(path: &Path) -> Vec<Vec<f64>> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .map(|l| l.split(',').map(|v| v.trim().parse().unwrap()).collect())
        .collect()
}

/// The lights of model.md §7 on a 1 nm grid from 300 to 830 nm.
fn lights(cie: &Path, fine: &[f64]) -> Vec<(&'static str, Vec<f64>)> {
    let light = |file: &str| -> Vec<f64> {
        let t = read_table(&cie.join(file));
        let x: Vec<f64> = t.iter().map(|r| r[0]).collect();
        let y: Vec<f64> = t.iter().map(|r| r[1]).collect();
        fine.iter()
            .map(|&l| interpolate(&x, &y, l, false))
            .collect()
    };
    let d65 = light("illuminant_D65.csv");
    // D65 plus a 365 nm LED (Gaussian, 10 nm FWHM) of the same radiant power over 300–780.
    let sigma = 10.0 / (2.0 * (2.0 * 2f64.ln()).sqrt());
    let led: Vec<f64> = fine
        .iter()
        .map(|l| (-0.5 * ((l - 365.0) / sigma).powi(2)).exp())
        .collect();
    let in_range: Vec<usize> = (0..fine.len()).filter(|&k| fine[k] <= 780.0).collect();
    let power = |v: &[f64]| {
        let xs: Vec<f64> = in_range.iter().map(|&k| fine[k]).collect();
        let ys: Vec<f64> = in_range.iter().map(|&k| v[k]).collect();
        trapezoid(&xs, &ys)
    };
    let scale = power(&d65) / power(&led);
    let uv = d65.iter().zip(&led).map(|(d, l)| d + scale * l).collect();
    vec![
        ("d65", d65),
        ("a", light("illuminant_A.csv")),
        ("f11", light("illuminant_F11.csv")),
        ("uv", uv),
    ]
}

/// ∫f·hat_g over the fine grid for each sample g of `grid` (linear-interpolation basis).
fn hat_weights(grid: &[f64], fine: &[f64], f: &[f64]) -> Vec<f64> {
    (0..grid.len())
        .map(|k| {
            let lo = if k > 0 { grid[k - 1] } else { grid[k] };
            let hi = if k + 1 < grid.len() {
                grid[k + 1]
            } else {
                grid[k]
            };
            let hat: Vec<f64> = fine
                .iter()
                .map(|&l| {
                    if l < lo || l > hi {
                        0.0
                    } else if l <= grid[k] {
                        if grid[k] > lo {
                            (l - lo) / (grid[k] - lo)
                        } else {
                            1.0
                        }
                    } else if hi > grid[k] {
                        (hi - l) / (hi - grid[k])
                    } else {
                        0.0
                    }
                })
                .collect();
            let product: Vec<f64> = hat.iter().zip(f).map(|(h, v)| h * v).collect();
            trapezoid(fine, &product)
        })
        .collect()
}

/// CIELAB of a flat patch (matrix per emission bin) against the perfect white.
fn patch_lab(
    m: &Matrix,
    values: &[Vec<f64>],
    light: &[f64],
    observer: &[[f64; 3]],
    fine: &[f64],
) -> [f64; 3] {
    let widths = bin_widths(&m.emission);
    let l_ex = hat_weights(&m.excitation, fine, light);
    let l_em = hat_weights(&m.emission, fine, light);
    let cmf: Vec<Vec<f64>> = (0..3)
        .map(|c| {
            let channel: Vec<f64> = observer.iter().map(|o| o[c]).collect();
            hat_weights(&m.emission, fine, &channel)
                .iter()
                .zip(&widths)
                .map(|(h, w)| h / w)
                .collect()
        })
        .collect();
    let mut xyz = [0.0; 3];
    let mut white = [0.0; 3];
    for (j, _) in m.emission.iter().enumerate() {
        let out: f64 = values
            .iter()
            .zip(&l_ex)
            .map(|(row, l)| if row[j].is_finite() { l * row[j] } else { 0.0 })
            .sum();
        for c in 0..3 {
            xyz[c] += out * cmf[c][j];
            white[c] += l_em[j] * cmf[c][j];
        }
    }
    let f = |t: f64| {
        if t > (6.0f64 / 29.0).powi(3) {
            t.cbrt()
        } else {
            t / (3.0 * (6.0f64 / 29.0).powi(2)) + 4.0 / 29.0
        }
    };
    let (fx, fy, fz) = (
        f(xyz[0] / white[0]),
        f(xyz[1] / white[1]),
        f(xyz[2] / white[2]),
    );
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// CIEDE2000 (Sharma, Wu, Dalal 2005).
fn ciede2000(p: [f64; 3], q: [f64; 3]) -> f64 {
    use std::f64::consts::PI;
    let deg = |r: f64| r * 180.0 / PI;
    let rad = |d: f64| d * PI / 180.0;
    let c1 = p[1].hypot(p[2]);
    let c2 = q[1].hypot(q[2]);
    let c_bar = 0.5 * (c1 + c2);
    let g = 0.5 * (1.0 - (c_bar.powi(7) / (c_bar.powi(7) + 25f64.powi(7))).sqrt());
    let (a1, a2) = ((1.0 + g) * p[1], (1.0 + g) * q[1]);
    let (c1p, c2p) = (a1.hypot(p[2]), a2.hypot(q[2]));
    let hue = |b: f64, a: f64| {
        if a == 0.0 && b == 0.0 {
            0.0
        } else {
            let h = deg(b.atan2(a));
            if h < 0.0 { h + 360.0 } else { h }
        }
    };
    let (h1, h2) = (hue(p[2], a1), hue(q[2], a2));
    let dl = q[0] - p[0];
    let dc = c2p - c1p;
    let dh = if c1p * c2p == 0.0 {
        0.0
    } else if (h2 - h1).abs() <= 180.0 {
        h2 - h1
    } else if h2 - h1 > 180.0 {
        h2 - h1 - 360.0
    } else {
        h2 - h1 + 360.0
    };
    let dhh = 2.0 * (c1p * c2p).sqrt() * rad(dh / 2.0).sin();
    let l_bar = 0.5 * (p[0] + q[0]);
    let cp_bar = 0.5 * (c1p + c2p);
    let h_bar = if c1p * c2p == 0.0 {
        h1 + h2
    } else if (h1 - h2).abs() <= 180.0 {
        0.5 * (h1 + h2)
    } else if h1 + h2 < 360.0 {
        0.5 * (h1 + h2 + 360.0)
    } else {
        0.5 * (h1 + h2 - 360.0)
    };
    let t = 1.0 - 0.17 * rad(h_bar - 30.0).cos()
        + 0.24 * rad(2.0 * h_bar).cos()
        + 0.32 * rad(3.0 * h_bar + 6.0).cos()
        - 0.20 * rad(4.0 * h_bar - 63.0).cos();
    let d_theta = 30.0 * (-((h_bar - 275.0) / 25.0).powi(2)).exp();
    let rc = 2.0 * (cp_bar.powi(7) / (cp_bar.powi(7) + 25f64.powi(7))).sqrt();
    let sl = 1.0 + 0.015 * (l_bar - 50.0).powi(2) / (20.0 + (l_bar - 50.0).powi(2)).sqrt();
    let sc = 1.0 + 0.045 * cp_bar;
    let sh = 1.0 + 0.015 * cp_bar * t;
    let rt = -rad(2.0 * d_theta).sin() * rc;
    ((dl / sl).powi(2) + (dc / sc).powi(2) + (dhh / sh).powi(2) + rt * (dc / sc) * (dhh / sh))
        .sqrt()
}

/// The independent ΔE2000 per light between a measured matrix and a material JSON.
struct Colorimeter {
    fine: Vec<f64>,
    observer: Vec<[f64; 3]>,
    lights: Vec<(&'static str, Vec<f64>)>,
}

impl Colorimeter {
    fn new(cie: &Path) -> Self {
        let fine: Vec<f64> = (300..=830).map(f64::from).collect();
        let t = read_table(&cie.join("cie1931_2deg_xyz.csv"));
        let x: Vec<f64> = t.iter().map(|r| r[0]).collect();
        let observer = fine
            .iter()
            .map(|&l| {
                [1, 2, 3]
                    .map(|c| interpolate(&x, &t.iter().map(|r| r[c]).collect::<Vec<_>>(), l, false))
            })
            .collect();
        let lights = lights(cie, &fine);
        Colorimeter {
            fine,
            observer,
            lights,
        }
    }

    /// ΔE2000 per light, measured (missing cells from `model`) against `model`.
    fn delta_e(&self, m: &Matrix, model: &[Vec<f64>]) -> Vec<(&'static str, f64)> {
        let reference: Vec<Vec<f64>> = m
            .values
            .iter()
            .zip(model)
            .map(|(row, fit)| {
                row.iter()
                    .zip(fit)
                    .map(|(v, f)| if v.is_finite() { *v } else { *f })
                    .collect()
            })
            .collect();
        self.lights
            .iter()
            .map(|(name, light)| {
                let measured = patch_lab(m, &reference, light, &self.observer, &self.fine);
                let fitted = patch_lab(m, model, light, &self.observer, &self.fine);
                (*name, ciede2000(measured, fitted))
            })
            .collect()
    }
}

fn material_json(outcome: FitOutcome) -> (Value, std::collections::BTreeMap<String, f64>) {
    let FitOutcome::Material(material) = outcome else {
        panic!("expected a material");
    };
    let reported = material.fit.as_ref().unwrap().delta_e2000.clone();
    (serde_json::from_str(&material.to_json()).unwrap(), reported)
}

/// The ΔE2000 `fit` reports equals this file's own computation from the raw BFC-450 file
/// and the written material, for the default grid fit and the model search; and the
/// search meets ΔE2000 ≤ 1 under all four lights by this independent measure.
#[test]
fn reported_colour_equals_an_independent_recomputation() {
    let (Some(measured), Some(cie)) = (common::shared("measured"), common::shared("cie")) else {
        return;
    };
    let colorimeter = Colorimeter::new(&cie);
    for name in ["CIBA12", "HERPICER", "POLGREE", "TEXTYELL"] {
        let path = measured.join(format!("{name}.BFC"));
        let raw = read_bfc(&path);
        let m = read(&path, &ReadOptions::default()).unwrap();
        // Both sides project the light and the observer on the grid's hats (model.md §7),
        // this one at 1 nm, fluorite at 0.25 nm: 0.02 is the bar for agreement (the
        // reports differed by up to 0.10 under F11 while fluorite projected L·x̄ together
        // for the diagonal).
        for (label, options, tolerance) in [
            ("default", FitOptions::default(), 0.02),
            (
                "search",
                FitOptions {
                    max_delta_e: Some(1.0),
                    model: fluorite::fit::ModelChoice::Auto,
                    ..FitOptions::default()
                },
                0.02,
            ),
        ] {
            let (material, reported) = material_json(fit(&m, &options).unwrap());
            let model = model_matrix(&material, &raw.excitation, &raw.emission);
            for (light, own) in colorimeter.delta_e(&raw, &model) {
                let said = reported[light];
                println!("{name} {label} {light}: reported {said:.3}, recomputed {own:.3}");
                assert!(
                    (said - own).abs() <= tolerance,
                    "{name} {label} under {light}: reported {said}, recomputed {own}"
                );
                if label == "search" {
                    assert!(own <= 1.0, "{name} search under {light}: {own}");
                }
            }
        }
    }
}

/// A matrix whose cells next to the diagonal carry fluorescence the fit sets aside
/// (`--guard 10`, matrix-only objective): the reported colour error sees it, as the independent computation with
/// every measured cell does; the old reference, which took those cells from the fit,
/// would not.
#[test]
fn reported_colour_sees_fluorescence_next_to_the_diagonal() {
    let Some(cie) = common::shared("cie") else {
        return;
    };
    let colorimeter = Colorimeter::new(&cie);
    let mut spec = SynthSpec::preset("green-dye").unwrap();
    spec.crosstalk = 0.0;
    let (mut m, _) = spec.generate().unwrap();
    // A blue emitter with a Stokes shift of one grid step: excited at 400–480 nm, it emits
    // only in the cell 10 nm above the diagonal.
    for i in 0..m.n_excitation() {
        let li = m.excitation_nm[i];
        if let Some(j) = m
            .emission_nm
            .iter()
            .position(|&lo| (lo - li - 10.0).abs() < 1e-9)
        {
            let bump = 0.12 * (-0.5 * ((li - 440.0) / 20.0).powi(2)).exp();
            let v = m.get_mut(i, j);
            if v.is_finite() {
                *v += bump;
            }
        }
    }
    let raw = Matrix {
        excitation: m.excitation_nm.clone(),
        emission: m.emission_nm.clone(),
        values: (0..m.n_excitation())
            .map(|i| (0..m.n_emission()).map(|j| m.get(i, j)).collect())
            .collect(),
    };
    // Matrix only: nothing in the fit sees the guard band, so only the colour reference
    // can (with the colour term the fit would also answer for those cells' colour).
    // The grid fit's reference is under test: the default fit would escalate on the
    // bump's colour the guard band hides from it.
    let options = FitOptions {
        guard_nm: Some(10.0),
        colour_weight: 0.0,
        model: fluorite::fit::ModelChoice::Tabulated,
        ..FitOptions::default()
    };
    let outcome = fit(&m, &options).unwrap();
    let guard_fraction = outcome.report().guard_signal_fraction;
    let (material, reported) = material_json(outcome);
    let model = model_matrix(&material, &raw.excitation, &raw.emission);
    let own = colorimeter.delta_e(&raw, &model);
    // The old reference: cells within the guard band taken from the fit.
    let mut borrowed = raw.values.clone();
    for (i, row) in borrowed.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            let offset = (raw.emission[j] - raw.excitation[i]).abs();
            if offset > 1e-9 && offset <= 10.0 + 1e-9 {
                *v = model[i][j];
            }
        }
    }
    let old = colorimeter.delta_e(
        &Matrix {
            values: borrowed,
            excitation: raw.excitation.clone(),
            emission: raw.emission.clone(),
        },
        &model,
    );
    println!("guard signal fraction {guard_fraction:.3}; own {own:?}; old reference {old:?}");
    assert!(guard_fraction > 0.05, "the guard band held the bump");
    let worst_own = own.iter().map(|x| x.1).fold(0.0, f64::max);
    let worst_old = old.iter().map(|x| x.1).fold(0.0, f64::max);
    assert!(worst_own > 1.0, "the bump is visible: {own:?}");
    assert!(worst_old < 0.5 * worst_own, "{old:?} vs {own:?}");
    for (light, value) in own {
        assert!(
            (reported[light] - value).abs() <= 0.05,
            "under {light}: reported {}, recomputed {value}",
            reported[light]
        );
    }
}
