//! The one error type of the data layer: every variant names the file and, where there
//! is one, the field (`frames[3].time`), so a bad data set is diagnosed in one line.

use std::path::Path;

/// Errors raised while reading, checking, downsampling or writing a data set.
///
/// `Display` is a single line of the form `<file>: <field>: <what is wrong>`.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// A file (json, PNG, flow) could not be read or created.
    #[error("{path}: {message}")]
    Io {
        /// File or folder that failed.
        path: String,
        /// What failed, with the OS error.
        message: String,
    },
    /// The file is not valid JSON.
    #[error("{path}: not valid JSON: {message}")]
    Json {
        /// File that failed.
        path: String,
        /// serde_json's description (line and column).
        message: String,
    },
    /// A field is missing, has the wrong type or an unusable value.
    #[error("{path}: field `{field}`: {message}")]
    Field {
        /// File that holds the field.
        path: String,
        /// Field path, e.g. `frames[3].transform_matrix`.
        field: String,
        /// What is wrong with it.
        message: String,
    },
    /// An image file exists but does not decode, or is not usable.
    #[error("{path}: {message}")]
    Image {
        /// Image file.
        path: String,
        /// Decoder message.
        message: String,
    },
    /// A requested scale is not an integer downsampling of the source images.
    #[error("{path}: scale {scale}: {message}")]
    Scale {
        /// Split json whose images were asked for.
        path: String,
        /// The requested scale (relative to the source image size).
        scale: f64,
        /// Why it is refused.
        message: String,
    },
    /// The output folder is being written by another process ([`maaf_io::RunLock`]).
    #[error(transparent)]
    Lock(#[from] maaf_io::LockError),
    /// A request that does not fit the data set (absent split, index out of range,
    /// bad generator option).
    #[error("{path}: {message}")]
    Request {
        /// Data set folder or split json concerned.
        path: String,
        /// What is wrong with the request.
        message: String,
    },
}

impl DataError {
    /// `Io` error for `path` from an OS error, with a short verb (`cannot read`).
    pub fn io(path: &Path, what: &str, err: std::io::Error) -> Self {
        DataError::Io {
            path: path.display().to_string(),
            message: format!("{what}: {err}"),
        }
    }

    /// `Field` error for `path` and `field`.
    pub fn field(path: &Path, field: impl Into<String>, message: impl Into<String>) -> Self {
        DataError::Field {
            path: path.display().to_string(),
            field: field.into(),
            message: message.into(),
        }
    }

    /// `Request` error for `path`.
    pub fn request(path: &Path, message: impl Into<String>) -> Self {
        DataError::Request {
            path: path.display().to_string(),
            message: message.into(),
        }
    }
}
