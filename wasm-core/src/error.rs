//! The one error type of the crate: every failure says what went wrong and where.

use std::fmt;

/// An error with enough context to act on: the file and line for BVH input, the section and
/// field for `.mmdb` input, the key for a configuration.
#[derive(Debug, Clone, PartialEq)]
pub enum Error {
    /// Malformed BVH text. `line` is 1-based; `0` means "end of file".
    Bvh { file: String, line: usize, message: String },
    /// A `.mmdb` file that is corrupt, truncated or of another version.
    Format(String),
    /// A database configuration that cannot be built (bad key, missing file, topology mismatch).
    Config(String),
    /// A file that could not be read or written.
    Io(String),
}

impl Error {
    pub fn bvh(file: &str, line: usize, message: impl Into<String>) -> Self {
        Error::Bvh { file: file.to_string(), line, message: message.into() }
    }
    pub fn format(message: impl Into<String>) -> Self {
        Error::Format(message.into())
    }
    pub fn config(message: impl Into<String>) -> Self {
        Error::Config(message.into())
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Bvh { file, line: 0, message } => write!(f, "{file}: end of file: {message}"),
            Error::Bvh { file, line, message } => write!(f, "{file}:{line}: {message}"),
            Error::Format(m) => write!(f, "invalid .mmdb: {m}"),
            Error::Config(m) => write!(f, "config: {m}"),
            Error::Io(m) => write!(f, "{m}"),
        }
    }
}

impl std::error::Error for Error {}

pub type Result<T> = std::result::Result<T, Error>;
