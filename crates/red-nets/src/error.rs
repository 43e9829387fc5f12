//! The error type of `red-nets`.

use std::path::PathBuf;

/// Errors of `red-nets`.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An array, gradient or parameter vector had the wrong shape or length.
    #[error("shape mismatch in {what}: expected {expected}, got {got}")]
    ShapeMismatch {
        /// What was checked.
        what: String,
        /// The expected shape, in words.
        expected: String,
        /// The shape found, in words.
        got: String,
    },
    /// A gradient, parameter or loss was NaN or infinite.
    #[error("non-finite value in {what}")]
    NonFinite {
        /// Where the value was found.
        what: String,
    },
    /// A configuration value was rejected.
    #[error("invalid config field `{field}`: {reason}")]
    InvalidConfig {
        /// The field's name (for example `hidden[1]` or `adam.lr`).
        field: String,
        /// Why it was rejected, and what would be accepted.
        reason: String,
    },
    /// Reading or writing a file failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A saved network or optimiser state could not be parsed or is
    /// inconsistent (wrong format name or version, shapes that disagree with
    /// the config).
    #[error("{}{reason}", path.as_ref().map(|p| format!("{}: ", p.display())).unwrap_or_default())]
    Format {
        /// The file, when the text came from one.
        path: Option<PathBuf>,
        /// What is wrong, in words.
        reason: String,
    },
}

impl Error {
    pub(crate) fn shape(
        what: impl Into<String>,
        expected: impl ToString,
        got: impl ToString,
    ) -> Self {
        Error::ShapeMismatch {
            what: what.into(),
            expected: expected.to_string(),
            got: got.to_string(),
        }
    }

    pub(crate) fn config(field: impl Into<String>, reason: impl Into<String>) -> Self {
        Error::InvalidConfig {
            field: field.into(),
            reason: reason.into(),
        }
    }
}

/// `Result` with `red-nets`' [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
