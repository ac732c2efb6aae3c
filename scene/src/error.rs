//! The one error type of training, evaluation and reporting: every message is one
//! line that names the file, field or value at fault.

use std::path::Path;

/// What went wrong in a run, an evaluation or a report.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Bad data, config, option or file content.
    #[error("{0}")]
    Input(String),
    /// A file or folder could not be read or written.
    // The OS error is part of the message and deliberately not a `source`: error
    // chains print every source again, which showed it twice.
    #[error("{path}: {os}")]
    Io {
        /// File or folder.
        path: String,
        /// Underlying OS error.
        os: std::io::Error,
    },
}

impl Error {
    /// An I/O error on `path`.
    pub fn io(path: &Path, os: std::io::Error) -> Self {
        Error::Io {
            path: path.display().to_string(),
            os,
        }
    }
}

/// Writes `bytes` to `path` crash-safely ([`maaf_io::write_atomic`]: temp file,
/// fsync, rename, folder fsync), naming `path` on error.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), Error> {
    maaf_io::write_atomic(path, bytes).map_err(|e| Error::io(path, e))
}
