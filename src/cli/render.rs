//! `fluorite render` (in progress).

use std::path::Path;
use std::process::ExitCode;

/// Arguments of `fluorite render`.
#[derive(clap::Args)]
pub struct RenderArgs {
    /// Material JSON to render.
    pub material: std::path::PathBuf,
}

/// Runs `fluorite render`.
pub fn run(_args: RenderArgs) -> anyhow::Result<ExitCode> {
    anyhow::bail!("render is not available yet")
}

/// Renders the default preview of a freshly fitted material (used by `fit --render`).
pub fn preview(_material_path: &Path) -> anyhow::Result<()> {
    anyhow::bail!("render is not available yet")
}
