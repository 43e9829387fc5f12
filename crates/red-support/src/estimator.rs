//! The support-estimator interface: a config fits on expert pairs and
//! returns a fitted model that scores pairs.

use ndarray::{Array1, Array2, ArrayView2};
use rand::Rng;

use crate::Result;

/// Progress of a fit, reported to the caller's callback.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitProgress {
    /// Units of work done (epochs for networks, stages for kernel PCA).
    pub done: usize,
    /// Units of work in all.
    pub total: usize,
    /// The training loss of the last unit, where there is one.
    pub loss: Option<f64>,
}

/// A callback that ignores progress.
pub fn no_progress(_: FitProgress) {}

/// The hyperparameters of a support estimator. [`fit`] is the only way to
/// get a model, so a model is never half-trained.
///
/// [`fit`]: SupportEstimatorConfig::fit
pub trait SupportEstimatorConfig {
    /// The fitted model.
    type Model: SupportModel;

    /// Rejects nonsense values, naming the field.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`].
    fn validate(&self) -> Result<()>;

    /// Fits on expert pairs: `states` is `(n, obs_dim)`, `actions` is
    /// `(n, act_dim)`. Randomness (initialisation, shuffling) comes from
    /// `rng` only, so the same generator state gives the same model.
    /// `progress` is called as work completes.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`], shape and finiteness errors, too few pairs,
    /// or a numerical failure.
    fn fit<R: Rng + ?Sized>(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
        rng: &mut R,
        progress: &mut dyn FnMut(FitProgress),
    ) -> Result<Self::Model>;
}

/// A fitted support estimator: a score `L(s, a) >= 0` that is near 0 on the
/// support of the expert's state-action distribution and grows away from it.
pub trait SupportModel {
    /// Length of a state.
    fn obs_dim(&self) -> usize;

    /// Length of an action.
    fn act_dim(&self) -> usize;

    /// Scores of a batch: `(n, obs_dim)` and `(n, act_dim)` in, `n` scores
    /// out, each `>= 0`.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] or [`Error::NonFinite`] for a bad batch.
    fn score(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<Array1<f64>>;

    /// Scores and their gradients with respect to the actions: `n` scores
    /// and an `(n, act_dim)` matrix whose row `i` is `dL(s_i, a_i)/da_i`.
    ///
    /// # Errors
    /// As [`SupportModel::score`].
    fn score_grad_action(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<(Array1<f64>, Array2<f64>)>;
}

impl<M: SupportModel + ?Sized> SupportModel for Box<M> {
    fn obs_dim(&self) -> usize {
        (**self).obs_dim()
    }
    fn act_dim(&self) -> usize {
        (**self).act_dim()
    }
    fn score(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<Array1<f64>> {
        (**self).score(states, actions)
    }
    fn score_grad_action(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<(Array1<f64>, Array2<f64>)> {
        (**self).score_grad_action(states, actions)
    }
}
