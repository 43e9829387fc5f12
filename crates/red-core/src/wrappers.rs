//! Environment wrappers: the time limit and the learned-reward swap.

use ndarray::ArrayView2;

use crate::env::TRUE_REWARD;
use crate::{Env, Error, Info, Result, RewardModel, Space, Step};

/// Cuts episodes after `max_steps` steps by setting `truncated`. It is the
/// only place in the project that sets `truncated`; when the inner
/// environment terminates on the same step, `terminated` wins and
/// `truncated` stays false.
///
/// After an episode ended (either flag), `step` fails with
/// [`Error::NeedsReset`] until the next `reset`, whatever the inner
/// environment would do; so does a `step` before the first `reset`.
#[derive(Debug, Clone)]
pub struct TimeLimit<E> {
    inner: E,
    max_steps: usize,
    elapsed: usize,
    /// No episode is running: before the first reset or after an end.
    needs_reset: bool,
}

impl<E: Env> TimeLimit<E> {
    /// Wraps `inner` with a limit of `max_steps` steps per episode.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] if `max_steps` is 0.
    pub fn new(inner: E, max_steps: usize) -> Result<Self> {
        if max_steps == 0 {
            return Err(Error::InvalidConfig {
                field: "max_steps".into(),
                reason: "must be at least 1".into(),
            });
        }
        Ok(Self {
            inner,
            max_steps,
            elapsed: 0,
            needs_reset: true,
        })
    }

    /// Steps taken in the current episode.
    pub fn elapsed(&self) -> usize {
        self.elapsed
    }

    /// The limit.
    pub fn max_steps(&self) -> usize {
        self.max_steps
    }

    /// The wrapped environment.
    pub fn inner(&self) -> &E {
        &self.inner
    }

    /// The wrapped environment, mutably.
    pub fn inner_mut(&mut self) -> &mut E {
        &mut self.inner
    }
}

impl<E: Env> Env for TimeLimit<E> {
    fn observation_space(&self) -> &Space {
        self.inner.observation_space()
    }
    fn action_space(&self) -> &Space {
        self.inner.action_space()
    }
    fn reset(&mut self, seed: Option<u64>) -> Result<(Vec<f64>, Info)> {
        self.elapsed = 0;
        let out = self.inner.reset(seed)?;
        self.needs_reset = false;
        Ok(out)
    }
    fn step(&mut self, action: &[f64]) -> Result<Step> {
        if self.needs_reset {
            return Err(Error::NeedsReset {
                reason: if self.elapsed == 0 {
                    "step called before reset".into()
                } else {
                    format!("the episode ended after {} steps", self.elapsed)
                },
            });
        }
        let mut step = self.inner.step(action)?;
        self.elapsed += 1;
        if !step.terminated && self.elapsed >= self.max_steps {
            step.truncated = true;
        }
        if step.terminated || step.truncated {
            self.needs_reset = true;
        }
        Ok(step)
    }
}

/// Replaces the environment's reward with a [`RewardModel`]'s `r(s, a)`,
/// where `s` is the observation the action was taken in. The environment's
/// own reward is kept in `info` under [`TRUE_REWARD`].
pub struct RewardWrapper<E, R> {
    inner: E,
    model: R,
    last_obs: Option<Vec<f64>>,
}

impl<E: Env, R: RewardModel> RewardWrapper<E, R> {
    /// Wraps `inner`, rewarding with `model`.
    pub fn new(inner: E, model: R) -> Self {
        Self {
            inner,
            model,
            last_obs: None,
        }
    }

    /// The reward model.
    pub fn model(&self) -> &R {
        &self.model
    }

    /// The reward model, mutably (an adaptive model is updated through it).
    pub fn model_mut(&mut self) -> &mut R {
        &mut self.model
    }

    /// The wrapped environment.
    pub fn inner(&self) -> &E {
        &self.inner
    }

    /// Unwraps into the environment and the model.
    pub fn into_parts(self) -> (E, R) {
        (self.inner, self.model)
    }
}

impl<E: Env, R: RewardModel> Env for RewardWrapper<E, R> {
    fn observation_space(&self) -> &Space {
        self.inner.observation_space()
    }
    fn action_space(&self) -> &Space {
        self.inner.action_space()
    }
    fn reset(&mut self, seed: Option<u64>) -> Result<(Vec<f64>, Info)> {
        let (obs, info) = self.inner.reset(seed)?;
        self.last_obs = Some(obs.clone());
        Ok((obs, info))
    }
    fn step(&mut self, action: &[f64]) -> Result<Step> {
        if self.last_obs.is_none() {
            return Err(Error::NeedsReset {
                reason: "step called before reset".into(),
            });
        }
        let mut step = self.inner.step(action)?;
        // The environment moved on: the next action is taken in the new
        // observation even if the model fails below.
        let state = self
            .last_obs
            .replace(step.observation.clone())
            .unwrap_or_default();
        let s = ArrayView2::from_shape((1, state.len()), state.as_slice()).map_err(|e| {
            Error::ShapeMismatch {
                what: "state".into(),
                expected: "a row".into(),
                got: e.to_string(),
            }
        })?;
        let a = ArrayView2::from_shape((1, action.len()), action).map_err(|e| {
            Error::ShapeMismatch {
                what: "action".into(),
                expected: "a row".into(),
                got: e.to_string(),
            }
        })?;
        let r = self.model.rewards(s, a)?;
        let reward = r.first().copied().ok_or_else(|| Error::ShapeMismatch {
            what: "reward model output".into(),
            expected: "1 reward".into(),
            got: "0".into(),
        })?;
        step.info.set(TRUE_REWARD, step.reward);
        step.reward = reward;
        Ok(step)
    }
}
