//! The one error type of the crate: every failure says what went wrong and where.
//!
//! Messages stay short: the constructors cut the message to
//! [`MAX_MESSAGE_CHARS`](crate::limits::MAX_MESSAGE_CHARS) characters and a BVH file name to
//! [`MAX_FILE_NAME_CHARS`] (keeping its end, the part that tells files apart), so no input can
//! turn an error into a megabyte of text. Quote user input with [`crate::limits::quote`].

use crate::limits::cap_message;
use std::fmt;

/// An error with enough context to act on: the file and line for BVH input, the section and
/// field for `.mmdb` input, the key for a configuration.
#[derive(Debug, Clone, PartialEq)]
pub enum Error {
    /// Malformed BVH text. `line` is 1-based; `0` means "end of file".
    Bvh { file: String, line: usize, message: String },
    /// A glTF/GLB/VRMA file that cannot be read as motion (`crate::gltf`): what and where in it.
    Gltf { file: String, message: String },
    /// A `.mmdb` file that is corrupt, truncated or of another version.
    Format(String),
    /// A database configuration that cannot be built (bad key, missing file, topology mismatch).
    Config(String),
    /// A file that could not be read or written.
    Io(String),
}

/// Characters of a file name kept in a BVH error (the last ones).
pub const MAX_FILE_NAME_CHARS: usize = 120;

impl Error {
    /// A BVH error at `line` (1-based, `0` = end of file) of `file`.
    pub fn bvh(file: &str, line: usize, message: impl Into<String>) -> Self {
        Error::Bvh { file: cap_file(file), line, message: cap_message(message.into()) }
    }
    /// A glTF error in `file`.
    pub fn gltf(file: &str, message: impl Into<String>) -> Self {
        Error::Gltf { file: cap_file(file), message: cap_message(message.into()) }
    }
    pub fn format(message: impl Into<String>) -> Self {
        Error::Format(cap_message(message.into()))
    }
    pub fn config(message: impl Into<String>) -> Self {
        Error::Config(cap_message(message.into()))
    }
}

/// A file name cut to its last [`MAX_FILE_NAME_CHARS`] characters.
fn cap_file(file: &str) -> String {
    let chars = file.chars().count();
    if chars > MAX_FILE_NAME_CHARS {
        format!("…{}", file.chars().skip(chars - MAX_FILE_NAME_CHARS).collect::<String>())
    } else {
        file.to_string()
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Bvh { file, line: 0, message } => write!(f, "{file}: end of file: {message}"),
            Error::Bvh { file, line, message } => write!(f, "{file}:{line}: {message}"),
            Error::Gltf { file, message } => write!(f, "{file}: {message}"),
            Error::Format(m) => write!(f, "invalid .mmdb: {m}"),
            Error::Config(m) => write!(f, "config: {m}"),
            Error::Io(m) => write!(f, "{m}"),
        }
    }
}

impl std::error::Error for Error {}

pub type Result<T> = std::result::Result<T, Error>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constructors_cap_long_messages_and_file_names() {
        let e = Error::config("x".repeat(1 << 20)).to_string();
        assert!(e.len() < 400, "{}", e.len());
        let e = Error::bvh(&format!("{}/take.bvh", "d".repeat(10_000)), 3, "bad").to_string();
        assert!(e.len() < 200 && e.ends_with("take.bvh:3: bad"), "{e}");
    }
}
