//! `fluorite fit` (in progress).

use std::process::ExitCode;

/// Arguments of `fluorite fit`.
#[derive(clap::Args)]
pub struct FitArgs {}

/// Runs `fluorite fit`.
pub fn run(_args: FitArgs) -> anyhow::Result<ExitCode> {
    anyhow::bail!("fit is not available yet")
}
