//! `fluorite plot` (in progress).

use std::path::Path;
use std::process::ExitCode;

/// Arguments of `fluorite plot`.
#[derive(clap::Args)]
pub struct PlotArgs {
    /// Material JSON to plot.
    pub material: std::path::PathBuf,
}

/// Runs `fluorite plot`.
pub fn run(_args: PlotArgs) -> anyhow::Result<ExitCode> {
    anyhow::bail!("plot is not available yet")
}

/// Plots a freshly fitted material against its data (used by `fit --plot`).
pub fn plot_fit(_material_path: &Path, _data_path: &Path) -> anyhow::Result<()> {
    anyhow::bail!("plot is not available yet")
}
