//! The environment interface, after Gymnasium's: `reset(seed)` and
//! `step(action) -> (observation, reward, terminated, truncated, info)`.

use crate::{Result, Space};

/// Named numbers an environment reports beside its reward: reward terms,
/// the true reward under a reward wrapper, progress, and so on.
///
/// Keys are `&'static str` so that filling it costs no string allocation.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Info {
    entries: Vec<(&'static str, f64)>,
}

impl Info {
    /// An empty info.
    pub fn new() -> Self {
        Self::default()
    }

    /// Sets `key` to `value`, replacing an earlier value.
    pub fn set(&mut self, key: &'static str, value: f64) {
        match self.entries.iter_mut().find(|(k, _)| *k == key) {
            Some(e) => e.1 = value,
            None => self.entries.push((key, value)),
        }
    }

    /// The value of `key`, if set.
    pub fn get(&self, key: &str) -> Option<f64> {
        self.entries.iter().find(|(k, _)| *k == key).map(|e| e.1)
    }

    /// All entries in the order they were first set.
    pub fn iter(&self) -> impl Iterator<Item = (&'static str, f64)> + '_ {
        self.entries.iter().copied()
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether there are no entries.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}

/// The key under which [`crate::RewardWrapper`] keeps the environment's own
/// reward.
pub const TRUE_REWARD: &str = "true_reward";

/// The outcome of one [`Env::step`].
#[derive(Debug, Clone, PartialEq)]
pub struct Step {
    /// The observation after the step.
    pub observation: Vec<f64>,
    /// The reward for the step.
    pub reward: f64,
    /// The episode reached a terminal state of the task (a fall, a crash,
    /// the goal). No bootstrapping past it.
    pub terminated: bool,
    /// The episode was cut for a reason outside the task, a time limit.
    /// Only [`crate::TimeLimit`] sets it.
    pub truncated: bool,
    /// Extra numbers (reward terms, true reward, progress).
    pub info: Info,
}

/// A reinforcement-learning environment.
///
/// Observations and actions are real vectors (`f64`); a discrete action is
/// one number, its index (see [`Space`]).
pub trait Env {
    /// The space observations belong to.
    fn observation_space(&self) -> &Space;

    /// The space actions belong to.
    fn action_space(&self) -> &Space;

    /// Starts a new episode and returns its first observation and info.
    /// With `Some(seed)` the environment's random stream restarts from that
    /// seed, so the same seed and the same actions give the same trajectory;
    /// with `None` it continues its current stream.
    ///
    /// # Errors
    /// An environment-specific failure (for example of the physics engine).
    fn reset(&mut self, seed: Option<u64>) -> Result<(Vec<f64>, Info)>;

    /// Applies `action` (of length `action_space().dim()`) for one control
    /// step.
    ///
    /// # Errors
    /// [`crate::Error::ShapeMismatch`] or [`crate::Error::NonFinite`] for a
    /// malformed action, [`crate::Error::NeedsReset`] when called before
    /// `reset` or after the episode ended, or an environment failure.
    fn step(&mut self, action: &[f64]) -> Result<Step>;
}

impl<E: Env + ?Sized> Env for Box<E> {
    fn observation_space(&self) -> &Space {
        (**self).observation_space()
    }
    fn action_space(&self) -> &Space {
        (**self).action_space()
    }
    fn reset(&mut self, seed: Option<u64>) -> Result<(Vec<f64>, Info)> {
        (**self).reset(seed)
    }
    fn step(&mut self, action: &[f64]) -> Result<Step> {
        (**self).step(action)
    }
}
