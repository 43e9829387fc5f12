//! Reward models: a learned reward over state-action pairs.

use ndarray::{Array1, Array2, ArrayView2};

use crate::{BoxSpace, Result};

/// A reward over state-action pairs, used in place of the environment's own.
///
/// Some models are fitted once before learning (RED, AE); others adapt to
/// the policy's data during training (GAIL, GMMIL). A learner calls
/// [`RewardModel::update`] with each fresh batch of its own pairs and need
/// not know which kind it holds: a fixed model ignores the call.
pub trait RewardModel {
    /// Rewards of a batch: `states` is `(n, obs_dim)`, `actions` is
    /// `(n, act_dim)`; returns `n` rewards.
    ///
    /// # Errors
    /// A shape mismatch with the dimensions the model was fitted on, or
    /// non-finite inputs.
    fn rewards(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<Array1<f64>>;

    /// Lets an adaptive model learn from a batch of the policy's own pairs
    /// (`(n, obs_dim)` and `(n, act_dim)`). Models fitted once do nothing.
    ///
    /// # Errors
    /// Shape mismatches, non-finite inputs, or a training failure.
    fn update(&mut self, states: ArrayView2<'_, f64>, actions: ArrayView2<'_, f64>) -> Result<()> {
        let _ = (states, actions);
        Ok(())
    }

    /// Whether [`RewardModel::update`] changes the model.
    fn is_adaptive(&self) -> bool {
        false
    }
}

/// A reward model that sees actions clipped into a box: `rewards(s, a)` and
/// `update(s, a)` are the inner model's on `(s, clip(a))`. For a learner
/// whose environment clips its sampled actions, this scores what the
/// environment executes rather than the raw draw.
pub struct ClippedActions<M> {
    inner: M,
    bounds: BoxSpace,
}

impl<M: RewardModel> ClippedActions<M> {
    /// `inner` seen through the clip into `bounds`.
    pub fn new(inner: M, bounds: BoxSpace) -> Self {
        Self { inner, bounds }
    }

    /// The inner model.
    pub fn inner(&self) -> &M {
        &self.inner
    }

    /// The inner model, unwrapped.
    pub fn into_inner(self) -> M {
        self.inner
    }
}

impl<M: RewardModel> RewardModel for ClippedActions<M> {
    fn rewards(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<Array1<f64>> {
        let a = self.bounds.clip_rows(actions)?;
        self.inner.rewards(states, a.view())
    }

    fn update(&mut self, states: ArrayView2<'_, f64>, actions: ArrayView2<'_, f64>) -> Result<()> {
        let a = self.bounds.clip_rows(actions)?;
        self.inner.update(states, a.view())
    }

    fn is_adaptive(&self) -> bool {
        self.inner.is_adaptive()
    }
}

/// A reward `r(s, a)` with its gradient with respect to the action, for
/// learners that differentiate through the reward (SVG(1)).
pub trait DifferentiableReward {
    /// Rewards `(n,)` of states `(n, obs_dim)` and actions `(n, act_dim)`,
    /// and `dr/da`, `(n, act_dim)`.
    ///
    /// # Errors
    /// Shape errors of the implementation.
    fn reward_and_grad(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<(Array1<f64>, Array2<f64>)>;

    /// Whether the reward changes during training (GAIL's discriminator,
    /// GMMIL's witness). A learner then recomputes the rewards of replayed
    /// transitions at each value update instead of using the stored ones.
    fn is_adaptive(&self) -> bool {
        false
    }
}
