//! Errors of the library. Each one names the file, the field and the reason, so a user can fix the
//! input without reading drape's source. `main` maps [`Error::exit_code`] to the process exit code:
//! 2 for bad input (the user's to fix), 1 for a failure while running.

use std::path::{Path, PathBuf};

/// Everything that can go wrong in drape's library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The scene file is not valid JSON, or does not match the schema (unknown field, wrong type).
    #[error("{file}:{line}:{column}: {path}: {reason}")]
    SceneSyntax {
        file: String,
        line: usize,
        column: usize,
        /// The JSON path of the offending field, e.g. `garments[0].resolution`.
        path: String,
        reason: String,
    },
    /// A field parsed but its value is impossible (zero resolution, negative mass, pin off the grid).
    #[error("{file}: {field}: {reason}")]
    InvalidField {
        file: String,
        field: String,
        reason: String,
    },
    /// A file or folder could not be read or written.
    #[error("{path}: {action}: {source}")]
    Io {
        path: PathBuf,
        action: &'static str,
        source: std::io::Error,
    },
    /// The GPU could not be used: no adapter, device lost, a buffer too large, a shader error.
    #[error("GPU: {reason}")]
    Gpu { reason: String },
    /// A command-line value is impossible (e.g. `--frames 0`).
    #[error("{flag}: {reason}")]
    InvalidArgument { flag: String, reason: String },
}

impl Error {
    /// Exit code for the command line: 2 for input the user must fix, 1 for run-time failures.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::SceneSyntax { .. }
            | Error::InvalidField { .. }
            | Error::InvalidArgument { .. } => 2,
            Error::Io { action, .. } if *action == "cannot read" => 2,
            Error::Io { .. } | Error::Gpu { .. } => 1,
        }
    }

    /// An I/O error on `path` while doing `action` ("cannot read", "cannot write", ...).
    pub fn io(path: &Path, action: &'static str, source: std::io::Error) -> Self {
        Error::Io {
            path: path.to_path_buf(),
            action,
            source,
        }
    }
}

/// Result with drape's [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
