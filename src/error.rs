//! The library's error type: every failure names what went wrong, where, and how to fix it.

use std::path::PathBuf;

/// Result alias used across the library.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Every way a fluorite operation can fail. Messages are complete sentences meant for the
/// user: they name the file (and line/column where there is one), the parameter, and what
/// would fix the problem.
#[derive(Debug, Clone, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written.
    #[error("{}: {message}", path.display())]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// What failed, including the operating system's reason.
        message: String,
    },
    /// A file was read but its content is malformed.
    #[error("{}{}: {message}", path.display(), location(*line, *column))]
    Parse {
        /// The file concerned.
        path: PathBuf,
        /// 1-based line, 0 when the problem concerns the whole file.
        line: usize,
        /// 1-based column (field index), 0 when the problem concerns a whole line.
        column: usize,
        /// What is wrong and how to fix it.
        message: String,
    },
    /// A parameter (from the command line, a material file or an API call) is impossible.
    #[error("{parameter}: {message}")]
    Invalid {
        /// The parameter's name as the user knows it (`--spp`, `fluorophores[0].concentration`).
        parameter: String,
        /// Why the value is impossible and what would be accepted.
        message: String,
    },
    /// A fit could not produce a valid material.
    #[error("fit failed: {0}")]
    Fit(String),
    /// An error met while doing something the message names first (`--blank FILE`, `joint
    /// fit: sample FILE`): the context, then the error itself.
    #[error("{context}: {error}")]
    Context {
        /// What was being done, naming the file or option.
        context: String,
        /// The error met.
        error: Box<Error>,
    },
}

fn location(line: usize, column: usize) -> String {
    match (line, column) {
        (0, _) => String::new(),
        (l, 0) => format!(":{l}"),
        (l, c) => format!(":{l}:{c}"),
    }
}

impl Error {
    /// An I/O failure on `path`.
    pub fn io(path: impl Into<PathBuf>, err: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            message: err.to_string(),
        }
    }

    /// A malformed file at `line`/`column` (1-based; 0 for unknown).
    pub fn parse(
        path: impl Into<PathBuf>,
        line: usize,
        column: usize,
        message: impl Into<String>,
    ) -> Self {
        Error::Parse {
            path: path.into(),
            line,
            column,
            message: message.into(),
        }
    }

    /// This error, preceded by `context` (what was being done when it happened).
    pub fn context(self, context: impl Into<String>) -> Self {
        Error::Context {
            context: context.into(),
            error: Box::new(self),
        }
    }

    /// An impossible parameter value.
    pub fn invalid(parameter: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Invalid {
            parameter: parameter.into(),
            message: message.into(),
        }
    }
}
