//! `fluorite check`: check materials against the model's laws.

use std::path::PathBuf;
use std::process::ExitCode;

use fluorite::check::check_file;

/// Arguments of `fluorite check`.
#[derive(clap::Args, Debug)]
pub struct CheckArgs {
    /// Material JSON files (fitted, hand-written or from elsewhere).
    #[arg(required = true)]
    pub materials: Vec<PathBuf>,
    /// Print the report as JSON (one object per file; an array for several files).
    #[arg(long)]
    pub json: bool,
}

/// Runs `fluorite check`. Exit code 0 when every material is valid, 1 when one breaks a
/// law (the report says which), 2 when a file cannot be read as a material.
pub fn run(args: CheckArgs) -> anyhow::Result<ExitCode> {
    let mut worst = 0u8;
    let mut reports = Vec::new();
    for path in &args.materials {
        match check_file(path) {
            Ok(report) => {
                if !report.valid {
                    worst = worst.max(1);
                }
                if !args.json {
                    print!("{}", super::printer::check_report(&report));
                }
                reports.push(report);
            }
            Err(e) => {
                let message = e.to_string().replace('\n', " ");
                eprintln!("fluorite: error: {message}");
                worst = 2;
            }
        }
    }
    if args.json {
        let text = if args.materials.len() == 1 {
            reports.first().map(|r| r.to_json()).unwrap_or_default()
        } else {
            serde_json::to_string_pretty(&reports)? + "\n"
        };
        print!("{text}");
    }
    Ok(ExitCode::from(worst))
}
