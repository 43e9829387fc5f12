//! The error type of `red-support`.

use std::path::PathBuf;

/// Errors of `red-support`.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An array had the wrong shape.
    #[error("shape mismatch in {what}: expected {expected}, got {got}")]
    ShapeMismatch {
        /// What was checked.
        what: String,
        /// The expected shape, in words.
        expected: String,
        /// The shape found, in words.
        got: String,
    },
    /// A number that must be finite was NaN or infinite.
    #[error("non-finite value in {what}")]
    NonFinite {
        /// Where the value was found.
        what: String,
    },
    /// A configuration value was rejected.
    #[error("invalid config field `{field}`: {reason}")]
    InvalidConfig {
        /// The field's name.
        field: String,
        /// Why it was rejected, and what would be accepted.
        reason: String,
    },
    /// Fitting needs at least this many expert pairs.
    #[error("not enough expert pairs to fit {what}: need at least {need}, got {got}")]
    TooFewSamples {
        /// The estimator.
        what: String,
        /// The minimum.
        need: usize,
        /// What was given.
        got: usize,
    },
    /// A numerical routine failed (a solver that did not converge, a
    /// degenerate kernel matrix).
    #[error("numerical failure in {what}: {reason}")]
    Numerical {
        /// The routine.
        what: String,
        /// What went wrong.
        reason: String,
    },
    /// An error of the network library.
    #[error("network error: {0}")]
    Nets(#[from] red_nets::Error),
    /// A model file is malformed or of another kind or version.
    #[error("{}: {reason}", path.display())]
    ModelFile {
        /// The file.
        path: PathBuf,
        /// What is wrong.
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
}

/// `Result` with `red-support`'s [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

impl From<Error> for red_core::Error {
    /// Errors cross into `red_core` through [`red_core::RewardModel`]; shape
    /// and finiteness problems keep their kind, the rest become an
    /// environment-level failure with the message.
    fn from(e: Error) -> Self {
        match e {
            Error::ShapeMismatch {
                what,
                expected,
                got,
            } => red_core::Error::ShapeMismatch {
                what,
                expected,
                got,
            },
            Error::NonFinite { what } => red_core::Error::NonFinite { what },
            Error::InvalidConfig { field, reason } => {
                red_core::Error::InvalidConfig { field, reason }
            }
            other => red_core::Error::Env {
                reason: other.to_string(),
            },
        }
    }
}
