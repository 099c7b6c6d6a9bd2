//! `fluorite bands`: how many Gaussian bands each curve of a spectrum file needs, in
//! wavenumber and in wavelength.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use fluorite::Error;
use fluorite::fit::BandAxisChoice;
use fluorite::import::{read_spectrum, spectrum_columns};
use fluorite::parametric::fit::{
    BandFit, check_band_search, fit_bands_to_tolerance, positive_range,
};
use fluorite::parametric::{BandDomain, GaussianBands};
use serde::Serialize;

/// Arguments of `fluorite bands`.
#[derive(clap::Args, Debug)]
pub struct BandsArgs {
    /// Spectrum files: a header row, the wavelength (nm) in the first column, one curve
    /// per further column (e.g. wavelength_nm,excitation,emission); each curve is fitted
    /// over its measured range (first to last positive value).
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// The axis the bands are Gaussian in: wavenumber, wavelength, or both (each curve
    /// fitted on each, to compare them).
    #[arg(long, value_enum, default_value = "both", hide_possible_values = true)]
    pub domain: BandAxisChoice,
    /// Largest accepted RMS of fit − data, as a fraction of the curve's peak.
    #[arg(long, default_value_t = 0.01)]
    pub tolerance: f64,
    /// Most bands tried per curve.
    #[arg(long, default_value_t = 6)]
    pub max_bands: usize,
    /// Print JSON (one object per file, curve and domain, with the fitted bands) instead
    /// of tables.
    #[arg(long)]
    pub json: bool,
}

/// One fit attempt in the JSON output.
#[derive(Serialize)]
struct Attempt {
    bands: usize,
    rel_rms: f64,
    max_rel_error: f64,
}

/// The outcome for one file, curve and domain.
#[derive(Serialize)]
struct CurveResult {
    file: String,
    curve: String,
    range_nm: [f64; 2],
    samples: usize,
    domain: BandDomain,
    tolerance: f64,
    /// The fewest bands meeting the tolerance; `None` when `max_bands` do not.
    bands_needed: Option<usize>,
    rel_rms: f64,
    max_rel_error: f64,
    fit_ms: f64,
    tried: Vec<Attempt>,
    fit: GaussianBands,
}

/// Runs `fluorite bands`.
pub fn run(args: BandsArgs) -> anyhow::Result<ExitCode> {
    // The library decides which searches are possible; errors name its parameters.
    check_band_search(args.max_bands, args.tolerance).map_err(named_as_flags)?;
    let mut results = Vec::new();
    for path in &args.files {
        let file = path
            .file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_else(|| path.display().to_string());
        let mut file_results = Vec::new();
        for curve in spectrum_columns(path)? {
            let spectrum = read_spectrum(path, Some(&curve), &[])?;
            let Some(range) = positive_range(&spectrum.value) else {
                eprintln!("{file}: {curve} has no positive value; skipped");
                continue;
            };
            let nm = &spectrum.wavelength_nm[range.clone()];
            let values = &spectrum.value[range];
            for &domain in args.domain.axes() {
                let start = Instant::now();
                let fits =
                    fit_bands_to_tolerance(nm, values, domain, args.max_bands, args.tolerance)
                        .map_err(|e| anyhow::anyhow!("{file}: {curve}: {}", named_as_flags(e)))?;
                let fit_ms = start.elapsed().as_secs_f64() * 1e3;
                file_results.push(curve_result(
                    &file,
                    &curve,
                    nm,
                    domain,
                    args.tolerance,
                    fits,
                    fit_ms,
                )?);
            }
        }
        if !args.json {
            print_table(&file, &file_results, args.tolerance, args.max_bands);
        }
        results.extend(file_results);
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&results)?);
    } else if args.domain == BandAxisChoice::Both {
        print_totals(&results);
    }
    Ok(ExitCode::SUCCESS)
}

/// `e` with the library's parameter names replaced by the flags that set them.
fn named_as_flags(e: Error) -> Error {
    match e {
        Error::Invalid { parameter, message } => {
            let flag = match parameter.as_str() {
                "max_bands" => "--max-bands",
                "tolerance_rel_rms" => "--tolerance",
                _ => parameter.as_str(),
            };
            Error::invalid(flag, message)
        }
        other => other,
    }
}

fn curve_result(
    file: &str,
    curve: &str,
    nm: &[f64],
    domain: BandDomain,
    tolerance: f64,
    fits: Vec<BandFit>,
    fit_ms: f64,
) -> anyhow::Result<CurveResult> {
    let tried = fits
        .iter()
        .map(|f| Attempt {
            bands: f.bands.bands.len(),
            rel_rms: f.rel_rms,
            max_rel_error: f.max_rel_error,
        })
        .collect();
    // The last fit tried is the chosen one.
    let last = fits
        .into_iter()
        .last()
        .ok_or_else(|| anyhow::anyhow!("{file}: {curve}: no band fit was produced"))?;
    Ok(CurveResult {
        file: file.to_string(),
        curve: curve.to_string(),
        range_nm: [nm[0], nm[nm.len() - 1]],
        samples: nm.len(),
        domain,
        tolerance,
        bands_needed: (last.rel_rms <= tolerance).then_some(last.bands.bands.len()),
        rel_rms: last.rel_rms,
        max_rel_error: last.max_rel_error,
        fit_ms,
        tried,
        fit: last.bands,
    })
}

fn print_table(file: &str, results: &[CurveResult], tolerance: f64, max_bands: usize) {
    println!(
        "{file} (tolerance: rel RMS ≤ {} % of peak)",
        100.0 * tolerance
    );
    println!(
        "  {:<12} {:>9} {:>7}  {:<10} {:>5} {:>8} {:>9} {:>9}",
        "curve", "range nm", "samples", "domain", "bands", "rel RMS", "max error", "time"
    );
    for r in results {
        let bands = match r.bands_needed {
            Some(n) => n.to_string(),
            None => format!(">{max_bands}"),
        };
        println!(
            "  {:<12} {:>9} {:>7}  {:<10} {:>5} {:>7.2}% {:>8.2}% {:>6.1} ms",
            r.curve,
            format!("{:.0}–{:.0}", r.range_nm[0], r.range_nm[1]),
            r.samples,
            r.domain.name(),
            bands,
            100.0 * r.rel_rms,
            100.0 * r.max_rel_error,
            r.fit_ms
        );
    }
}

/// Bands needed summed over the curves, per domain: the comparison `--domain both` is for.
fn print_totals(results: &[CurveResult]) {
    println!("total over all curves");
    for domain in [BandDomain::Wavenumber, BandDomain::Wavelength] {
        let mine: Vec<&CurveResult> = results.iter().filter(|r| r.domain == domain).collect();
        let met: Vec<usize> = mine.iter().filter_map(|r| r.bands_needed).collect();
        println!(
            "  {:<10} {} bands for the {} of {} curves meeting the tolerance",
            domain.name(),
            met.iter().sum::<usize>(),
            met.len(),
            mine.len()
        );
    }
}
