//! The error type of `red-experiments`.

use std::path::PathBuf;

/// Errors of an experiment: bad input (named with its file and place), a
/// failure of a lower crate, or a file that cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A setting was rejected.
    #[error("invalid setting `{field}`: {reason}")]
    InvalidConfig {
        /// The setting's name as the config file spells it.
        field: String,
        /// Why, and what would be accepted.
        reason: String,
    },
    /// An input file (demonstration, config, checkpoint) cannot be used.
    #[error("{}: {reason}", path.display())]
    Input {
        /// The file.
        path: PathBuf,
        /// What is wrong and how to fix it.
        reason: String,
    },
    /// A file of the run cannot be written or read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A file of the run cannot be written: which, why, what survives and
    /// how to finish the run.
    #[error("cannot write {}: {reason}; {survives}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        reason: String,
        /// What is left whole and how to finish.
        survives: String,
    },
    /// A picture cannot be drawn.
    #[error("drawing {}: {reason}", path.display())]
    Plot {
        /// The picture's file.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
    /// An error of the shared vocabulary (demo files, checkpoints).
    #[error(transparent)]
    Core(#[from] red_core::Error),
    /// An error of a learner.
    #[error(transparent)]
    Rl(#[from] red_rl::Error),
    /// An error of a support estimator or RED's reward.
    #[error(transparent)]
    Support(#[from] red_support::Error),
    /// An error of the driving scenario.
    #[error(transparent)]
    Drive(#[from] red_drive::Error),
    /// An error of a MuJoCo environment (a model that cannot be loaded).
    #[error(transparent)]
    Mujoco(#[from] red_mujoco::Error),
    /// A quantity that must be finite was not.
    #[error("non-finite {what}")]
    NonFinite {
        /// What, and where it was met.
        what: String,
    },
    /// An error with what was being done when it happened.
    #[error("{context}: {source}")]
    Context {
        /// What was being done.
        context: String,
        /// The error.
        source: Box<Error>,
    },
}

impl Error {
    /// Wraps the error with what was being done.
    pub fn context(self, context: impl Into<String>) -> Self {
        Self::Context {
            context: context.into(),
            source: Box::new(self),
        }
    }
}

/// Adds context to a fallible result.
pub trait ResultExt<T> {
    /// On error, wraps it with `f()`'s description of what was being done.
    ///
    /// # Errors
    /// The wrapped error.
    fn with_context<S: Into<String>>(self, f: impl FnOnce() -> S) -> Result<T>;
}

impl<T, E: Into<Error>> ResultExt<T> for std::result::Result<T, E> {
    fn with_context<S: Into<String>>(self, f: impl FnOnce() -> S) -> Result<T> {
        self.map_err(|e| e.into().context(f()))
    }
}

/// `Result` with `red-experiments`' [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
