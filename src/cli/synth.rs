//! `fluorite synth` (in progress).

use std::process::ExitCode;

/// Arguments of `fluorite synth`.
#[derive(clap::Args)]
pub struct SynthArgs {}

/// Runs `fluorite synth`.
pub fn run(_args: SynthArgs) -> anyhow::Result<ExitCode> {
    anyhow::bail!("synth is not available yet")
}
