//! The `fluorite` command-line tool. Errors end the run with a one-line message on stderr
//! and a non-zero exit code, never a backtrace.

mod cli;

use std::process::ExitCode;

/// The exit code of a run ended by Ctrl-C (128 + SIGINT, as shells report it).
const INTERRUPTED: u8 = 130;

fn main() -> ExitCode {
    // Ctrl-C: remove the files being written (every output is written to a temporary file
    // and renamed into place), say so, and end; what was already in place stays whole.
    let _ = ctrlc::set_handler(|| {
        fluorite::files::interrupt();
        eprintln!("fluorite: interrupted: files in progress removed; finished files are whole");
        std::process::exit(i32::from(INTERRUPTED));
    });
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
