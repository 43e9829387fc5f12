//! The error type of `red-mujoco`.

use std::path::PathBuf;

/// The environment variable naming the folder of the model files (kept
/// here, where [`Error::AssetNotFound`] names it, and re-exported by
/// [`crate::assets`]).
pub const ASSETS_ENV_VAR: &str = "RED_MUJOCO_ASSETS";

/// Errors of `red-mujoco`.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The folder of Gymnasium's model files, or a model file in it, is
    /// missing.
    #[error(
        "MuJoCo model file {} not found ({source_of_dir}); run `scripts/setup-mujoco.sh` \
         from the repository root to fetch Gymnasium's model files, or set {} to a folder \
         that holds them",
        path.display(),
        ASSETS_ENV_VAR
    )]
    AssetNotFound {
        /// The model file looked for.
        path: PathBuf,
        /// Where the folder came from (the run-time variable, the build-time
        /// default).
        source_of_dir: String,
    },
    /// MuJoCo could not load or compile a model.
    #[error("MuJoCo could not load {}: {reason}", path.display())]
    ModelLoad {
        /// The model file.
        path: PathBuf,
        /// MuJoCo's message.
        reason: String,
    },
    /// A model does not have the structure an environment needs (a body
    /// name, the number of joints).
    #[error("model {model} does not fit: {reason}")]
    ModelMismatch {
        /// The model file's name.
        model: String,
        /// What is wrong.
        reason: String,
    },
    /// A vector had the wrong length.
    #[error("shape mismatch in {what}: expected {expected} numbers, got {got}")]
    ShapeMismatch {
        /// What was checked.
        what: &'static str,
        /// The expected length.
        expected: usize,
        /// The length found.
        got: usize,
    },
    /// A number that must be finite was NaN or infinite.
    #[error("non-finite value in {what}")]
    NonFinite {
        /// Where the value was found.
        what: &'static str,
    },
    /// A configuration value was rejected.
    #[error("invalid config field `{field}`: {reason}")]
    InvalidConfig {
        /// The field's name.
        field: &'static str,
        /// Why it was rejected.
        reason: String,
    },
    /// An environment id that this crate does not provide.
    #[error("unknown MuJoCo environment `{id}`; known: {known}")]
    UnknownEnv {
        /// The id asked for.
        id: String,
        /// The ids this crate knows, comma-separated.
        known: String,
    },
}

/// `Result` with `red-mujoco`'s [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

impl From<Error> for red_core::Error {
    fn from(e: Error) -> Self {
        match e {
            Error::ShapeMismatch {
                what,
                expected,
                got,
            } => red_core::Error::ShapeMismatch {
                what: what.into(),
                expected: format!("{expected} numbers"),
                got: got.to_string(),
            },
            Error::NonFinite { what } => red_core::Error::NonFinite { what: what.into() },
            Error::InvalidConfig { field, reason } => red_core::Error::InvalidConfig {
                field: field.into(),
                reason,
            },
            other => red_core::Error::Env {
                reason: other.to_string(),
            },
        }
    }
}
