//! The error type of `red-core`.

use std::path::PathBuf;

/// Errors of `red-core`.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An array or vector had the wrong length or shape.
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
    /// An action outside the environment's action space.
    #[error("invalid action: {reason}")]
    InvalidAction {
        /// Why the action was rejected.
        reason: String,
    },
    /// `step` was called before `reset`, or after the episode ended.
    #[error("environment must be reset: {reason}")]
    NeedsReset {
        /// Why a reset is needed.
        reason: String,
    },
    /// A configuration value was rejected.
    #[error("invalid config field `{field}`: {reason}")]
    InvalidConfig {
        /// The field's name.
        field: String,
        /// Why it was rejected.
        reason: String,
    },
    /// A demonstration file or dataset is malformed.
    #[error("{}{reason}", location_prefix(path.as_deref(), *trajectory, *step))]
    Demo {
        /// The file, if the demonstrations came from one.
        path: Option<PathBuf>,
        /// The trajectory (0-based) of the first problem, if it has one.
        trajectory: Option<usize>,
        /// The step (0-based) within that trajectory, if it has one.
        step: Option<usize>,
        /// What is wrong, in words.
        reason: String,
    },
    /// The env checker found a property an environment breaks.
    #[error("env check failed: {reason}")]
    EnvCheck {
        /// The property broken.
        reason: String,
    },
    /// An environment failed for a reason of its own (for example a physics
    /// engine's error).
    #[error("environment error: {reason}")]
    Env {
        /// What went wrong.
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

impl Error {
    /// The same error, naming `path` as its file if it is an
    /// [`Error::Demo`] without one; other errors are returned unchanged.
    pub fn with_path(self, path: &std::path::Path) -> Self {
        match self {
            Error::Demo {
                path: None,
                trajectory,
                step,
                reason,
            } => Error::Demo {
                path: Some(path.to_path_buf()),
                trajectory,
                step,
                reason,
            },
            other => other,
        }
    }
}

fn location_prefix(
    path: Option<&std::path::Path>,
    trajectory: Option<usize>,
    step: Option<usize>,
) -> String {
    let mut s = String::new();
    if let Some(p) = path {
        s.push_str(&format!("{}: ", p.display()));
    }
    match (trajectory, step) {
        (Some(t), Some(k)) => s.push_str(&format!("trajectory {t}, step {k}: ")),
        (Some(t), None) => s.push_str(&format!("trajectory {t}: ")),
        _ => {}
    }
    s
}

/// `Result` with `red-core`'s [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
