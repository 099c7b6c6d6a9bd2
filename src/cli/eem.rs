//! Options of `fluorite fit` for raw instrument EEMs: units, blank, inner filter, scatter.

use std::path::{Path, PathBuf};

use anyhow::Context;
use fluorite::eem::correct::Absorbance;
use fluorite::eem::scatter::{ScatterLine, ScatterOptions};
use fluorite::eem::{EemOptions, Preprocessing, UnitsChoice, prepare};
use fluorite::formats::{ReadOptions, read};
use fluorite::measurement::Measurement;

/// Arguments for uncalibrated EEMs (flattened into `fluorite fit`).
#[derive(clap::Args, Debug, Clone)]
pub struct EemArgs {
    /// Units of the values: `auto` (radiance factors if the values can be, radiance
    /// factors ×100 read ÷ 100 if they look like percent, else an uncalibrated EEM in
    /// arbitrary units, fitted for shapes and a scale only), `radiance-factor`, `percent`
    /// (radiance factors ×100) or `arbitrary`.
    #[arg(long, value_enum, default_value = "auto")]
    pub units: UnitsChoice,
    /// Blank (e.g. Milli-Q water, same settings) to subtract from each EEM: one file for
    /// all inputs, or one per input in order.
    #[arg(long)]
    pub blank: Vec<PathBuf>,
    /// Absorbance spectrum of the sample (two columns: wavelength nm, absorbance per cm)
    /// for the inner-filter correction F·10^((A_ex+A_em)/2) of a 1 cm cuvette: one per
    /// input, in order.
    #[arg(long)]
    pub absorbance: Vec<PathBuf>,
    /// Keep Rayleigh and Raman scatter in an EEM instead of masking it.
    #[arg(long)]
    pub keep_scatter: bool,
    /// Half-width (nm) of a scatter band, `LINE=NM` with LINE one of rayleigh1, raman1,
    /// rayleigh2, raman2 or all; comma-separated or repeated. Default: measured on the
    /// data (2.5 half widths at half maximum each side), else from --bandwidth, else 10.
    #[arg(long, value_delimiter = ',')]
    pub scatter_width: Vec<String>,
    /// Spectral bandwidth (slit bandpass, nm) of the instrument: scatter bands whose
    /// width cannot be measured are twice this each side (four times for second order).
    #[arg(long)]
    pub bandwidth: Option<f64>,
    /// Raman shift of the solvent (cm⁻¹).
    #[arg(long, default_value_t = fluorite::eem::scatter::WATER_RAMAN_SHIFT_CM)]
    pub raman_shift: f64,
}

impl EemArgs {
    /// The options for input number `index` of `count`; reads blank and absorbance files.
    pub fn options(
        &self,
        index: usize,
        count: usize,
        read_options: &ReadOptions,
    ) -> anyhow::Result<EemOptions> {
        let pick = |files: &[PathBuf],
                    what: &str,
                    shared: bool|
         -> anyhow::Result<Option<PathBuf>> {
            match files.len() {
                0 => Ok(None),
                1 if shared || count == 1 => Ok(Some(files[0].clone())),
                n if n == count => Ok(Some(files[index].clone())),
                n => anyhow::bail!(
                    "--{what}: {n} files for {count} inputs; give {}one per input, in the inputs' order",
                    if shared { "one for all inputs or " } else { "" }
                ),
            }
        };
        let blank = match pick(&self.blank, "blank", true)? {
            Some(path) => {
                let m = read(&path, read_options)
                    .with_context(|| format!("--blank {}", path.display()))?;
                Some((m, path))
            }
            None => None,
        };
        let absorbance = match pick(&self.absorbance, "absorbance", false)? {
            Some(path) => Some((
                Absorbance::read(&path)
                    .with_context(|| format!("--absorbance {}", path.display()))?,
                path,
            )),
            None => None,
        };
        let mut half_width_nm = [None; 4];
        for item in &self.scatter_width {
            let (line, nm) = item.split_once('=').with_context(|| {
                format!("--scatter-width {item:?}: expected LINE=NM, e.g. rayleigh2=12 or all=10")
            })?;
            // The library checks the width (EemOptions::validate); a word is not one.
            let nm: f64 = nm.trim().parse().ok().with_context(|| {
                format!("--scatter-width {item:?}: {nm:?} is not a width in nm (a number ≥ 0)")
            })?;
            let line = line.trim().to_ascii_lowercase();
            let mut matched = false;
            for (k, l) in ScatterLine::ALL.iter().enumerate() {
                if line == "all" || line == l.name() {
                    half_width_nm[k] = Some(nm);
                    matched = true;
                }
            }
            if !matched {
                anyhow::bail!(
                    "--scatter-width {item:?}: unknown line {line:?}; use rayleigh1, raman1, rayleigh2, raman2 or all"
                );
            }
        }
        Ok(EemOptions {
            units: self.units,
            zero_is_missing: read_options.zero_is_missing,
            blank,
            absorbance,
            keep_scatter: self.keep_scatter,
            scatter: ScatterOptions {
                half_width_nm,
                bandwidth_nm: self.bandwidth,
                raman_shift_cm: Some(self.raman_shift),
            },
        })
    }
}

/// Reads `input` and prepares it (units, blank, inner filter, scatter).
pub fn read_prepared(
    input: &Path,
    options: &EemOptions,
    read_options: &ReadOptions,
) -> anyhow::Result<(Measurement, Option<Preprocessing>)> {
    let m = read(input, read_options)?;
    Ok(prepare(m, options)?)
}
