//! The error type of `red-drive`.

use std::path::PathBuf;

/// Errors of `red-drive`.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A [`crate::DriveConfig`] field was rejected.
    #[error("invalid drive config field `{field}`: {reason}")]
    InvalidConfig {
        /// The field's name.
        field: &'static str,
        /// Why it was rejected, and what would be accepted.
        reason: String,
    },
    /// An error of the shared vocabulary (a malformed action, a demo file).
    #[error(transparent)]
    Core(#[from] red_core::Error),
    /// Drawing a picture failed.
    #[error("rendering {}: {reason}", path.display())]
    Render {
        /// The picture being written.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
    /// The terminal of a recording failed (raw mode, reading keys, drawing).
    #[error("terminal: {0}")]
    Terminal(#[from] std::io::Error),
    /// A demonstration cannot be replayed on this track.
    #[error("replay: {reason}")]
    Replay {
        /// Why.
        reason: String,
    },
}

impl From<Error> for red_core::Error {
    fn from(e: Error) -> Self {
        match e {
            Error::Core(inner) => inner,
            Error::InvalidConfig { field, reason } => red_core::Error::InvalidConfig {
                field: field.to_string(),
                reason,
            },
            other => red_core::Error::Env {
                reason: other.to_string(),
            },
        }
    }
}

/// `Result` with `red-drive`'s [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
