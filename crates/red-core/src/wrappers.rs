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

/// Appends the last action taken, clipped into the action box, to every
/// observation (zeros after a reset), when switched on: a policy that reads
/// it can tell the same state met in the middle of a move from the same
/// state met while holding still. Switched off it passes everything
/// through unchanged, so one type serves both.
#[derive(Debug, Clone)]
pub struct LastAction<E> {
    inner: E,
    /// `Some` when on: the last action, and the extended observation space.
    on: Option<(Vec<f64>, Space)>,
}

impl<E: Env> LastAction<E> {
    /// Wraps `inner`; `on` switches the extension on.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] when `on` and either space is not a box.
    pub fn new(inner: E, on: bool) -> Result<Self> {
        if !on {
            return Ok(Self { inner, on: None });
        }
        let (Space::Box(obs), Space::Box(act)) = (inner.observation_space(), inner.action_space())
        else {
            return Err(Error::InvalidConfig {
                field: "last action input".into(),
                reason: "needs box observation and action spaces".into(),
            });
        };
        let mut low = obs.low.clone();
        let mut high = obs.high.clone();
        low.extend(&act.low);
        high.extend(&act.high);
        let space = Space::Box(crate::BoxSpace::new(low, high)?);
        let last = vec![0.0; act.dim()];
        Ok(Self {
            inner,
            on: Some((last, space)),
        })
    }

    /// Whether the last action is appended.
    pub fn is_on(&self) -> bool {
        self.on.is_some()
    }

    /// The wrapped environment.
    pub fn inner(&self) -> &E {
        &self.inner
    }

    /// The wrapped environment, mutably.
    pub fn inner_mut(&mut self) -> &mut E {
        &mut self.inner
    }

    fn extended(&self, mut obs: Vec<f64>) -> Vec<f64> {
        if let Some((last, _)) = &self.on {
            obs.extend(last);
        }
        obs
    }
}

impl<E: Env> Env for LastAction<E> {
    fn observation_space(&self) -> &Space {
        match &self.on {
            Some((_, space)) => space,
            None => self.inner.observation_space(),
        }
    }
    fn action_space(&self) -> &Space {
        self.inner.action_space()
    }
    fn reset(&mut self, seed: Option<u64>) -> Result<(Vec<f64>, Info)> {
        let (obs, info) = self.inner.reset(seed)?;
        if let Some((last, _)) = &mut self.on {
            last.fill(0.0);
        }
        Ok((self.extended(obs), info))
    }
    fn step(&mut self, action: &[f64]) -> Result<Step> {
        let mut step = self.inner.step(action)?;
        if let (Some((last, _)), Space::Box(b)) = (&mut self.on, self.inner.action_space()) {
            for (((l, a), lo), hi) in last.iter_mut().zip(action).zip(&b.low).zip(&b.high) {
                *l = a.max(*lo).min(*hi);
            }
        }
        step.observation = self.extended(std::mem::take(&mut step.observation));
        Ok(step)
    }
}
