//! The error type of `red-rl`.

/// Errors of `red-rl`.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An array had the wrong shape.
    #[error("shape mismatch in {what}: expected {expected}, got {got}")]
    ShapeMismatch {
        /// What was checked.
        what: String,
        /// The expected shape, in words.
        expected: String,
        /// The shape found.
        got: String,
    },
    /// A loss, gradient, reward or observation became NaN or infinite.
    #[error("non-finite {what} at step {step}")]
    NonFinite {
        /// What became non-finite.
        what: String,
        /// The environment step (or update) at which it was found.
        step: u64,
    },
    /// A configuration value was rejected.
    #[error("invalid config field `{field}`: {reason}")]
    InvalidConfig {
        /// The field's name.
        field: String,
        /// Why it was rejected.
        reason: String,
    },
    /// An error of the environment or of the shared vocabulary.
    #[error(transparent)]
    Core(#[from] red_core::Error),
    /// An error of the networks.
    #[error(transparent)]
    Nets(#[from] red_nets::Error),
}

/// `Result` with `red-rl`'s [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
