//! Support estimation of the expert policy and RED's reward (paper Sec. 2.2
//! and 3).
//!
//! A [`SupportEstimatorConfig`] fits on expert state-action pairs and
//! returns a [`SupportModel`] whose score `L(s, a) >= 0` is near 0 on the
//! support of the expert's pairs and grows away from it. Three estimators:
//! [`RndConfig`] (random network distillation, the paper's method),
//! [`AutoencoderConfig`] (the over-parametrised autoencoder baseline) and
//! [`KernelPcaConfig`] (exact kernel PCA, the estimator RND approximates).
//! [`RedReward`] turns a score into the reward `exp(-σ1 L)`, and
//! [`TerminalHeuristic`] is the optional end-of-episode penalty.
//!
//! ```
//! use ndarray::Array2;
//! use rand::SeedableRng;
//! use red_support::{
//!     KernelPcaConfig, RedReward, RedRewardConfig, SupportEstimatorConfig, SupportModel,
//!     no_progress,
//! };
//!
//! # fn main() -> red_support::Result<()> {
//! // Expert pairs on the line a = s.
//! let s = Array2::from_shape_fn((50, 1), |(i, _)| i as f64 / 25.0 - 1.0);
//! let a = s.clone();
//! let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
//! let model = KernelPcaConfig::default().fit(s.view(), a.view(), &mut rng, &mut no_progress)?;
//! let reward = RedReward::new(model, &RedRewardConfig::default(), s.view(), a.view())?;
//! let on = reward.reward(Array2::from_elem((1, 1), 0.3).view(), Array2::from_elem((1, 1), 0.3).view())?;
//! let off = reward.reward(Array2::from_elem((1, 1), 0.3).view(), Array2::from_elem((1, 1), -0.9).view())?;
//! assert!(on[0] > 0.8 && off[0] < on[0]);
//! # Ok(())
//! # }
//! ```

pub mod autoencoder;
pub mod cross_val;
pub mod error;
pub mod estimator;
pub mod fitted;
pub mod input;
pub mod kernel_pca;
pub mod reward;
pub mod rnd;
pub mod stats;
pub mod terminal;
mod train;

pub use autoencoder::{Autoencoder, AutoencoderConfig};
pub use cross_val::held_out_scores;
pub use error::{Error, Result};
pub use estimator::{FitProgress, SupportEstimatorConfig, SupportModel, no_progress};
pub use fitted::{EstimatorConfig, FittedEstimator, MODEL_FORMAT, MODEL_VERSION};
pub use input::{CappedDim, InputMap, PeriodicDim, WeightedDim, cap_states};
pub use kernel_pca::{Bandwidth, Components, KernelKind, KernelPca, KernelPcaConfig};
pub use reward::{
    ExpertScores, RedReward, RedRewardConfig, Sigma1, calibrate_sigma1, fit_red_reward,
};
pub use rnd::{Rnd, RndConfig, RndPair};
pub use terminal::{TerminalHeuristic, TerminalHeuristicConfig};

// The exact versions of the crates this crate's API takes and returns,
// so that a dependant names the same types (a second version of ndarray or
// rand in a build gives type errors that never mention versions).
pub use ndarray;
pub use rand;
pub use rand_chacha;
