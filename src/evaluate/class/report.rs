//! What a class sweep writes: the CSV, the Markdown report and, per case, the files that
//! let anyone refit it (`fluorite class --dump`).

use std::fmt::Write as _;

use crate::error::Result;
use crate::fit::BandAxisChoice;
use crate::formats::{RowsAre, write_wide_csv};

use super::super::{SEARCH_BOUND, quantile};
use super::{
    Case, ClassSweep, DEFAULT_FIT, DeltaEStats, GRID_FIT, METHODS, SEARCH, SEARCH_NOISE,
    WORST_LISTED, measured_colour_floor, of_method, summarise,
};

/// The CSV header of [`to_csv`].
pub const CSV_HEADER: &str = "case,method,true_fluorophores,step_nm,noise_sigma,crosstalk,missing_fraction,measured_colour_delta_e2000_truth,dye_free_twin_fluorophores,dye_free_twin_delta_e2000_truth,error,model,fluorophores,bound_met,max_delta_e2000_measurement,max_delta_e2000_truth,ms";

/// One line per case and method.
pub fn to_csv(sweep: &ClassSweep) -> String {
    let mut out = String::from(CSV_HEADER);
    out.push('\n');
    for c in &sweep.cases {
        for r in &c.results {
            let _ = writeln!(
                out,
                "{},{},{},{},{:.4e},{:.4},{:.4},{:.4},{},{:.4},\"{}\",{},{},{},{:.4},{:.4},{:.3}",
                c.name,
                r.method,
                c.true_fluorophores,
                c.step_nm,
                c.noise_sigma,
                c.crosstalk,
                c.missing_fraction,
                c.measured_colour_truth,
                c.dye_free.fluorophores,
                c.dye_free.delta_e_truth,
                r.error.as_deref().unwrap_or("").replace('"', "'"),
                r.model,
                r.fluorophores,
                r.bound_met.map(|b| b.to_string()).unwrap_or_default(),
                r.delta_e_measurement,
                r.delta_e_truth,
                r.ms
            );
        }
    }
    out
}

fn stats_row(out: &mut String, method: &str, against: &str, group: &str, s: &DeltaEStats) {
    if s.n == 0 {
        // A group without cases (e.g. no two-dye truth among the `--case` picked).
        let _ = writeln!(
            out,
            "| {method} | {against} | {group} | 0 | – | – | – | – | – |"
        );
        return;
    }
    let _ = writeln!(
        out,
        "| {method} | {against} | {group} | {} | {:.2} | {:.2} | {:.2} | {:.0} % | {:.0} % |",
        s.n,
        s.median,
        s.p90,
        s.max,
        100.0 * s.within_1,
        100.0 * s.within_2
    );
}

/// The Markdown report: what was drawn, per-method summary, ΔE2000 tables, time, and
/// the [`WORST_LISTED`] worst cases against the truth per method. `command` is the
/// command line that made it.
pub fn to_markdown(sweep: &ClassSweep, command: &str) -> String {
    let summaries = summarise(sweep);
    let two = sweep
        .cases
        .iter()
        .filter(|c| c.true_fluorophores == 2)
        .count();
    let truth_bands = sweep.config.truth_bands.name();
    let axis_words = match sweep.config.band_axis {
        BandAxisChoice::Both => "as every search here, its Gaussian bands on wavenumber and on wavelength, the result that meets the bound kept, of two the one of lower BIC: `--band-axis both`".to_string(),
        one => {
            let axis = one.axes()[0].name();
            format!("as every search here, its Gaussian bands on {axis} alone: `--band-axis {axis}`")
        }
    };
    let mut out = String::from("# Accuracy on a randomized class of materials\n\n");
    let _ = writeln!(
        out,
        "Made by `{command}`. {} synthetic cases (seed {:#X}; {two} with two fluorophores; draws the synthesiser refused and were redrawn: {}): Gaussian bands in {truth_bands}, sampled on each case's grids (the truth is linear between those samples), absorption peak 300–620 nm with an optional second band, Stokes shift 15–120 nm, sigmoid reflectance, c 0.1–1, yield 0.3–1 of its limit (energy form 80 %, photon form 20 %), noise σ log-uniform 1e-4–3e-3, crosstalk 0–0.05, missing cells 0–0.05, 10 nm grid (70 %), 5 nm (20 %) or 20 nm (10 %). Methods: `{GRID_FIT}` (the tabulated fit, `--model tabulated`), `{SEARCH}` (the model search, ΔE2000 ≤ {SEARCH_BOUND}; {axis_words}), `{SEARCH_NOISE}` (the same with `--noise-aware-bound`: each light held to max({SEARCH_BOUND}, 3 × its measured colour's noise RMS where the miss's χ² agrees, at most the grid fit's ΔE2000 + {SEARCH_BOUND}), its colour term weighed by that noise and, on a noisy colour, by the share of what the grid fit leaves beyond the noise, its reflectance tabulated where no polynomial fits the diagonal within the noise, a candidate the matrix tells from the grid model passed over for the grid fit (or, where the grid fit meets a light only within its noise, for the larger one-component model of lowest BIC below the grid model's, fitted to the matrix alone) or a later candidate) and `{DEFAULT_FIT}` (`fluorite fit` as it comes: the grid fit, kept where it is within ΔE2000 1 under every light or within its measured colour's noise (in ΔE2000 and χ²) or, where it removed crosstalk, within 1 of the cells it fitted, and that colour does not rest on missing cells it filled itself while leaving structure, else escalated to the noise-aware search (and, where it is kept only within the colour's noise, replaced by that search's first model where it has the lower BIC), `search-noise` under the default's bounds). ΔE2000 is the largest over D65, A, F11 and UV, against the measurement (the fit's report) and against the true material.\n",
        sweep.cases.len(),
        sweep.config.seed,
        sweep.refused
    );
    out.push_str("| method | cases | errors | bound met | fluorophores right | time median (ms) | p90 | max |\n|---|---|---|---|---|---|---|---|\n");
    for s in &summaries {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {:.1} | {:.1} | {:.1} |",
            s.method,
            s.cases,
            s.errors,
            s.bound_met.map(|n| n.to_string()).unwrap_or("–".into()),
            s.fluorophores_right,
            s.ms[0],
            s.ms[1],
            s.ms[2]
        );
    }
    out.push_str("\n| method | against | true dyes | n | median ΔE2000 | p90 | max | ≤ 1 | ≤ 2 |\n|---|---|---|---|---|---|---|---|---|\n");
    for s in &summaries {
        for (against, split) in [("truth", &s.truth), ("measurement", &s.measurement)] {
            for (group, st) in [("all", &split.all), ("1", &split.one), ("2", &split.two)] {
                stats_row(&mut out, &s.method, against, group, st);
            }
        }
    }
    let floor = measured_colour_floor(sweep);
    for (group, st) in [("all", &floor.all), ("1", &floor.one), ("2", &floor.two)] {
        stats_row(&mut out, "measured colour (no fit)", "truth", group, st);
    }
    let beyond: Vec<f64> = sweep
        .cases
        .iter()
        .map(|c| (c.measured_colour_truth - SEARCH_BOUND).max(0.0))
        .collect();
    let forced = beyond.iter().filter(|&&v| v > 1.0).count();
    let _ = writeln!(
        out,
        "\nThe `measured colour` rows need no fit: the colour of the cells as measured (noise and crosstalk included, missing cells filled from the truth) against the truth's, both on the measurement's grids. A fit within ΔE2000 {SEARCH_BOUND} of the measured colour, as `{SEARCH}` asks, is about that distance − {SEARCH_BOUND} or more from the truth (ΔE2000 is close to a distance at these sizes): at least median {:.2}, 90th percentile {:.2}, max {:.2}; more than 1 on {forced} of {} cases.",
        quantile(&beyond, 0.5),
        quantile(&beyond, 0.9),
        beyond.iter().copied().fold(0.0, f64::max),
        beyond.len()
    );
    let twins: Vec<f64> = sweep
        .cases
        .iter()
        .map(|c| c.dye_free.delta_e_truth)
        .collect();
    let fluorescent: Vec<&Case> = sweep
        .cases
        .iter()
        .filter(|c| c.dye_free.fluorophores > 0 || c.dye_free.error.is_some())
        .collect();
    let _ = writeln!(
        out,
        "\n**Dye-free twins.** Each case drawn again without its fluorophores (the same reflectance, grid, noise, crosstalk and missing cells) and fitted with `{GRID_FIT}`, which both searches start from and keep as it is when it finds no fluorescence: {} of {} stay plain reflectors, ΔE2000 to the truth median {:.2}, max {:.2}.",
        sweep.cases.len() - fluorescent.len(),
        sweep.cases.len(),
        quantile(&twins, 0.5),
        twins.iter().copied().fold(0.0, f64::max)
    );
    if !fluorescent.is_empty() {
        out.push_str("\n| dye-free twin of | grid (nm) | noise σ | crosstalk | missing | fluorophores fitted | ΔE2000 truth | error |\n|---|---|---|---|---|---|---|---|\n");
        for c in &fluorescent {
            let _ = writeln!(
                out,
                "| {} | {} | {:.1e} | {:.3} | {:.3} | {} | {:.2} | {} |",
                c.name,
                c.step_nm,
                c.noise_sigma,
                c.crosstalk,
                c.missing_fraction,
                c.dye_free.fluorophores,
                c.dye_free.delta_e_truth,
                c.dye_free.error.as_deref().unwrap_or("")
            );
        }
    }
    for method in METHODS {
        let mut pairs = of_method(sweep, method);
        pairs.sort_by(|a, b| b.1.delta_e_truth.total_cmp(&a.1.delta_e_truth));
        let _ = writeln!(
            out,
            "\n## The {WORST_LISTED} worst `{method}` fits against the truth\n\n| case | K true | K fit | model | grid (nm) | noise σ | crosstalk | missing | ΔE2000 truth | ΔE2000 measurement | error |\n|---|---|---|---|---|---|---|---|---|---|---|"
        );
        for (c, r) in pairs.iter().take(WORST_LISTED) {
            let _ = writeln!(
                out,
                "| {} | {} | {} | {} | {} | {:.1e} | {:.3} | {:.3} | {:.2} | {:.2} | {} |",
                c.name,
                c.true_fluorophores,
                r.fluorophores,
                r.model,
                c.step_nm,
                c.noise_sigma,
                c.crosstalk,
                c.missing_fraction,
                r.delta_e_truth,
                r.delta_e_measurement,
                r.error.as_deref().unwrap_or("")
            );
        }
    }
    out
}

/// The files `fluorite class --dump` writes for `case`, named relative to the dump
/// folder: `NAME.csv` (the measurement as fitted, a wide CSV with rows = excitation, read
/// back exactly), `NAME.truth.json` (the true material), `NAME.synth.json` (the drawn
/// parameters, as `fluorite synth` writes them) and `NAME.METHOD.json` (each method's
/// fitted material with its report). `fluorite fit NAME.csv` is the `default` fit again.
pub fn case_files(case: &Case) -> Result<Vec<(String, Vec<u8>)>> {
    let (m, truth) = case.spec.generate()?;
    let name = &case.name;
    let mut files = vec![
        (
            format!("{name}.csv"),
            write_wide_csv(&m, RowsAre::Excitation).into_bytes(),
        ),
        (format!("{name}.truth.json"), truth.to_json().into_bytes()),
        (
            format!("{name}.synth.json"),
            // Plain numbers, strings and arrays: serialising cannot fail.
            (serde_json::to_string_pretty(&case.spec).expect("spec serialises") + "\n")
                .into_bytes(),
        ),
    ];
    for result in &case.results {
        if let Some(material) = &result.material {
            files.push((
                format!("{name}.{}.json", result.method),
                material.to_json().into_bytes(),
            ));
        }
    }
    Ok(files)
}
