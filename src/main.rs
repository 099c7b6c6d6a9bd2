//! The `fluorite` command-line tool. Errors end the run with a one-line message on stderr
//! and a non-zero exit code, never a backtrace.

mod cli;

use std::process::ExitCode;

fn main() -> ExitCode {
    match cli::run() {
        Ok(code) => code,
        Err(err) => {
            // `{:#}` prints the whole cause chain on one line.
            let message = format!("{err:#}").replace('\n', " ");
            eprintln!("fluorite: error: {message}");
            ExitCode::from(2)
        }
    }
}
