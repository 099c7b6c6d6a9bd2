//! `fluorite import-spectra`: build a material from published absorption and emission
//! spectra.

use std::path::PathBuf;
use std::process::ExitCode;

use fluorite::YieldForm;
use fluorite::files::write_atomic;
use fluorite::import::{ImportOptions, ReflectanceSource, SpectrumSource, import_spectra};

/// Arguments of `fluorite import-spectra`.
#[derive(clap::Args, Debug)]
pub struct ImportSpectraArgs {
    /// Absorption (or excitation) spectrum file: a header row, the wavelength (nm) in the
    /// first column; any scale (normalised to max a = 1).
    #[arg(long)]
    pub absorption: PathBuf,
    /// Column of the absorption file (default: absorption, absorbance or excitation).
    #[arg(long)]
    pub absorption_column: Option<String>,
    /// Emission spectrum file (default: the absorption file); any scale (normalised to
    /// ∫e dλ = 1).
    #[arg(long)]
    pub emission: Option<PathBuf>,
    /// Column of the emission file (default: emission or fluorescence).
    #[arg(long)]
    pub emission_column: Option<String>,
    /// Reflectance r of the non-fluorescent part: a constant in [0, 1] or a spectrum file
    /// (column reflectance, or the only value column).
    #[arg(long)]
    pub reflectance: String,
    /// Concentration c: fraction of light absorbed at the absorption peak, in [0, 1].
    #[arg(short = 'c', long)]
    pub concentration: f64,
    /// Energy quantum yield Q (emitted / absorbed energy), in [0, 1], constant over the
    /// excitation wavelength; photon conservation requires Q·λ̄e/λ ≤ 1 at every absorbed
    /// λ. Give this or --photon-yield.
    #[arg(
        short = 'q',
        long,
        required_unless_present = "photon_yield",
        conflicts_with = "photon_yield"
    )]
    pub quantum_yield: Option<f64>,
    /// Photon quantum yield Φ (emitted / absorbed photons), in [0, 1], constant over the
    /// excitation wavelength (Kasha–Vavilov): the yield chemists tabulate. The material
    /// then has the photon form, with energy yield Φ·λi/λ̄e. Give this or
    /// --quantum-yield.
    #[arg(long)]
    pub photon_yield: Option<f64>,
    /// Material name (default: the absorption file's stem).
    #[arg(long)]
    pub name: Option<String>,
    /// Output material JSON.
    #[arg(short, long)]
    pub out: PathBuf,
}

/// Runs `fluorite import-spectra`.
pub fn run(args: ImportSpectraArgs) -> anyhow::Result<ExitCode> {
    let reflectance = match args.reflectance.trim().parse::<f64>() {
        Ok(r) => ReflectanceSource::Constant(r),
        Err(_) => ReflectanceSource::File(SpectrumSource {
            path: PathBuf::from(&args.reflectance),
            column: None,
        }),
    };
    let name = args.name.clone().unwrap_or_else(|| {
        args.absorption
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "material".into())
    });
    let options = ImportOptions {
        name,
        absorption: SpectrumSource {
            path: args.absorption.clone(),
            column: args.absorption_column.clone(),
        },
        emission: SpectrumSource {
            path: args
                .emission
                .clone()
                .unwrap_or_else(|| args.absorption.clone()),
            column: args.emission_column.clone(),
        },
        reflectance,
        concentration: args.concentration,
        quantum_yield: args.quantum_yield.or(args.photon_yield).unwrap_or(f64::NAN),
        yield_form: if args.photon_yield.is_some() {
            YieldForm::Photon
        } else {
            YieldForm::Energy
        },
    };
    let (material, report) = import_spectra(&options)?;
    write_atomic(&args.out, material.to_json().as_bytes())?;
    println!("{}", args.out.display());
    print!("{}", super::printer::check_report(&report));
    Ok(ExitCode::SUCCESS)
}
