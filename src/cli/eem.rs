//! Options of `fluorite fit` for raw instrument EEMs: units, blank, inner filter, scatter
//! (prepared by [`fluorite::pipeline::input`]).

use std::path::PathBuf;

use fluorite::eem::UnitsChoice;
use fluorite::pipeline::EemSettings;

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
    /// The library's settings for these flags (scatter widths parsed; files still paths).
    pub fn settings(&self) -> fluorite::Result<EemSettings> {
        let mut settings = EemSettings {
            units: self.units,
            blank: self.blank.clone(),
            absorbance: self.absorbance.clone(),
            keep_scatter: self.keep_scatter,
            bandwidth_nm: self.bandwidth,
            raman_shift_cm: self.raman_shift,
            ..EemSettings::default()
        };
        for item in &self.scatter_width {
            settings.parse_scatter_width(item)?;
        }
        Ok(settings)
    }
}
