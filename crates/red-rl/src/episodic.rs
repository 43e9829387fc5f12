//! The one training loop of the learners that act and learn episode by
//! episode on a [`DifferentiableReward`] (SVG(1)-ER, SAC), with hooks for
//! what a caller does between episodes: record, check or select a policy,
//! update an adaptive reward, checkpoint, stop.
//!
//! ```no_run
//! use red_rl::episodic::EpisodicLearner;
//! # fn demo<E: red_core::Env>(
//! #     env: &mut E,
//! #     svg: &mut red_rl::svg::Svg1,
//! #     reward: &dyn red_rl::svg::DifferentiableReward,
//! # ) -> red_rl::Result<()> {
//! use rand::SeedableRng;
//! let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
//! svg.train(env, reward, 20_000, None, &|_, _| 0.0, &mut rng, &mut |ep| {
//!     println!("{} {}", ep.env_steps, ep.true_return);
//! })?;
//! # Ok(()) }
//! ```

use std::ops::ControlFlow;

use ndarray::{Array2, ArrayView2};
use rand::Rng;
use red_core::{DifferentiableReward, Env, Info, Space};

use crate::{Error, Result};

/// An episode finished during [`EpisodicLearner::train`].
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodeReport {
    /// Environment steps so far.
    pub env_steps: u64,
    /// Sum of the environment's (true) rewards.
    pub true_return: f64,
    /// Sum of the imitation rewards stored, terminal adjustment included.
    pub imitation_return: f64,
    /// Steps in the episode.
    pub length: usize,
    /// The last step's info.
    pub info: Info,
}

/// One episode of [`EpisodicLearner::run_episode`].
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodeOutcome {
    /// Returns, length and the last step's info.
    pub report: EpisodeReport,
    /// False when the step budget cut the episode short.
    pub finished: bool,
    /// The states visited, `(length, obs_dim)`.
    pub states: Array2<f64>,
    /// The actions taken, `(length, act_dim)`.
    pub actions: Array2<f64>,
}

/// What one episode of a learner gathers as it goes (its pairs, both
/// returns, how it ended), for [`EpisodicLearner::run_episode`].
pub(crate) struct EpisodeLog {
    obs_dim: usize,
    act_dim: usize,
    states: Vec<f64>,
    actions: Vec<f64>,
    true_return: f64,
    imitation_return: f64,
    length: usize,
    finished: bool,
    info: Info,
}

impl EpisodeLog {
    pub(crate) fn new(obs_dim: usize, act_dim: usize) -> Self {
        Self {
            obs_dim,
            act_dim,
            states: Vec::new(),
            actions: Vec::new(),
            true_return: 0.0,
            imitation_return: 0.0,
            length: 0,
            finished: false,
            info: Info::new(),
        }
    }

    /// Steps taken so far.
    pub(crate) fn length(&self) -> usize {
        self.length
    }

    /// `reward`'s value of the pair `(obs, a)`; [`Error::NonFinite`] at
    /// environment step `env_step` when it is not finite.
    pub(crate) fn reward_of(
        reward: &dyn DifferentiableReward,
        obs: &[f64],
        a: &[f64],
        env_step: u64,
    ) -> Result<f64> {
        let ov = ArrayView2::from_shape((1, obs.len()), obs).map_err(one_row)?;
        let av = ArrayView2::from_shape((1, a.len()), a).map_err(one_row)?;
        let r = reward.reward_and_grad(ov, av)?.0[0];
        if r.is_finite() {
            Ok(r)
        } else {
            Err(Error::NonFinite {
                what: "imitation reward".into(),
                step: env_step,
            })
        }
    }

    /// Records one step: the pair, the environment's reward and the
    /// imitation reward stored.
    pub(crate) fn record(&mut self, obs: &[f64], a: &[f64], true_reward: f64, imitation: f64) {
        self.states.extend_from_slice(obs);
        self.actions.extend_from_slice(a);
        self.true_return += true_reward;
        self.imitation_return += imitation;
        self.length += 1;
    }

    /// The episode ended (terminated or truncated) with `info`; the terminal
    /// adjustment `adjustment` was added to the last stored reward.
    pub(crate) fn end(&mut self, adjustment: f64, info: Info) {
        self.imitation_return += adjustment;
        self.finished = true;
        self.info = info;
    }

    /// The outcome, at the learner's step count `env_steps`.
    pub(crate) fn into_outcome(self, env_steps: u64) -> Result<EpisodeOutcome> {
        let len = self.length;
        let shape = |w: usize, v: Vec<f64>| {
            Array2::from_shape_vec((len, w), v).map_err(|e| Error::ShapeMismatch {
                what: "episode pairs".into(),
                expected: format!("{len} rows of {w}"),
                got: e.to_string(),
            })
        };
        Ok(EpisodeOutcome {
            report: EpisodeReport {
                env_steps,
                true_return: self.true_return,
                imitation_return: self.imitation_return,
                length: len,
                info: self.info,
            },
            finished: self.finished,
            states: shape(self.obs_dim, self.states)?,
            actions: shape(self.act_dim, self.actions)?,
        })
    }
}

/// A slice seen as one row.
pub(crate) fn one_row(e: ndarray::ShapeError) -> Error {
    Error::ShapeMismatch {
        what: "one-row view".into(),
        expected: "a row".into(),
        got: e.to_string(),
    }
}

/// What [`EpisodicLearner::train_with`] calls around its episodes. The
/// hooks hold what a caller keeps beside the learner (the reward, records,
/// a stop flag), so that they can checkpoint both together: they see the
/// learner `L` and the random stream `R` it acts with.
pub trait EpisodeHooks<L: ?Sized, R: ?Sized> {
    /// The hooks' error; the learner's errors convert into it.
    type Error: From<Error>;

    /// The reward the next episode learns from (an adaptive one may be
    /// updated by [`EpisodeHooks::after_episode`]).
    fn reward(&self) -> &dyn DifferentiableReward;

    /// Before each episode; `Break` ends training before it. The default
    /// does nothing.
    ///
    /// # Errors
    /// The hooks' own; an error ends training.
    fn before_episode(
        &mut self,
        _learner: &L,
        _rng: &R,
    ) -> std::result::Result<ControlFlow<()>, Self::Error> {
        Ok(ControlFlow::Continue(()))
    }

    /// After each episode, also one the step budget cut short
    /// (`episode.finished` false); `Break` ends training.
    ///
    /// # Errors
    /// The hooks' own; an error ends training.
    fn after_episode(
        &mut self,
        learner: &L,
        rng: &R,
        episode: &EpisodeOutcome,
    ) -> std::result::Result<ControlFlow<()>, Self::Error>;
}

/// A learner trained one episode at a time; its training loop is
/// [`EpisodicLearner::train_with`] (and the short form
/// [`EpisodicLearner::train`]).
pub trait EpisodicLearner {
    /// Environment steps taken so far.
    fn env_steps(&self) -> u64;

    /// Runs one episode of at most `max_steps` steps, learning as it goes;
    /// the reset seed is `reset_seed` or drawn from `rng`, and
    /// `terminal(final_reward, final_info)` (the last step's imitation
    /// reward and the environment's info of that step, which may say how
    /// the episode ended) is added to the episode's last stored reward.
    ///
    /// # Errors
    /// The learner's own (shapes, non-finite values, the environment's).
    fn run_episode<E: Env + ?Sized, R: Rng + ?Sized>(
        &mut self,
        env: &mut E,
        reward: &dyn DifferentiableReward,
        reset_seed: Option<u64>,
        terminal: &dyn Fn(f64, &Info) -> f64,
        max_steps: u64,
        rng: &mut R,
    ) -> Result<EpisodeOutcome>;

    /// The training loop: episodes until the learner has taken
    /// `total_env_steps` environment steps (counting those of earlier calls
    /// and of a resumed state; the last episode is cut at the budget), on
    /// the reward of `hooks`, with `hooks` before and after each episode.
    /// Returns `Break` when a hook stopped training early.
    ///
    /// # Errors
    /// Any error of [`EpisodicLearner::run_episode`] or of the hooks.
    fn train_with<E, R, H>(
        &mut self,
        env: &mut E,
        total_env_steps: u64,
        reset_seed: Option<u64>,
        terminal: &dyn Fn(f64, &Info) -> f64,
        rng: &mut R,
        hooks: &mut H,
    ) -> std::result::Result<ControlFlow<()>, H::Error>
    where
        Self: Sized,
        E: Env + ?Sized,
        R: Rng + ?Sized,
        H: EpisodeHooks<Self, R> + ?Sized,
    {
        while self.env_steps() < total_env_steps {
            if hooks.before_episode(self, rng)?.is_break() {
                return Ok(ControlFlow::Break(()));
            }
            let left = total_env_steps - self.env_steps();
            let ep = self.run_episode(env, hooks.reward(), reset_seed, terminal, left, rng)?;
            if hooks.after_episode(self, rng, &ep)?.is_break() {
                return Ok(ControlFlow::Break(()));
            }
        }
        Ok(ControlFlow::Continue(()))
    }

    /// Runs `steps` more environment steps on a fixed `reward`;
    /// `on_episode` gets the report of every episode that finished (the
    /// last one may be cut by the budget). Episodes are reset with seeds
    /// drawn from `rng`, or every one with `reset_seed` when given (one
    /// fixed track). The short form of [`EpisodicLearner::train_with`].
    ///
    /// # Errors
    /// As [`EpisodicLearner::run_episode`].
    #[allow(clippy::too_many_arguments)]
    fn train<E: Env + ?Sized, R: Rng + ?Sized>(
        &mut self,
        env: &mut E,
        reward: &dyn DifferentiableReward,
        steps: u64,
        reset_seed: Option<u64>,
        terminal: &dyn Fn(f64, &Info) -> f64,
        rng: &mut R,
        on_episode: &mut dyn FnMut(&EpisodeReport),
    ) -> Result<()>
    where
        Self: Sized,
    {
        let end = self.env_steps() + steps;
        let mut hooks = OnEpisode { reward, on_episode };
        // `on_episode` cannot stop training: it always runs to the budget.
        let _ = self.train_with(env, end, reset_seed, terminal, rng, &mut hooks)?;
        Ok(())
    }
}

/// [`EpisodicLearner::train`]'s hooks: a fixed reward and a callback.
struct OnEpisode<'a> {
    reward: &'a dyn DifferentiableReward,
    on_episode: &'a mut dyn FnMut(&EpisodeReport),
}

impl<L: ?Sized, R: ?Sized> EpisodeHooks<L, R> for OnEpisode<'_> {
    type Error = Error;

    fn reward(&self) -> &dyn DifferentiableReward {
        self.reward
    }

    fn after_episode(&mut self, _: &L, _: &R, ep: &EpisodeOutcome) -> Result<ControlFlow<()>> {
        if ep.finished {
            (self.on_episode)(&ep.report);
        }
        Ok(ControlFlow::Continue(()))
    }
}

/// Refuses an environment whose spaces are not boxes of the learner's
/// dimensions (`learner` names it in the error).
pub(crate) fn check_spaces<E: Env + ?Sized>(
    learner: &str,
    env: &E,
    obs_dim: usize,
    act_dim: usize,
) -> Result<()> {
    match (env.observation_space(), env.action_space()) {
        (Space::Box(o), Space::Box(a)) if o.dim() == obs_dim && a.dim() == act_dim => Ok(()),
        _ => Err(Error::ShapeMismatch {
            what: format!("{learner} environment spaces"),
            expected: format!("boxes of {obs_dim} and {act_dim}"),
            got: "other spaces".into(),
        }),
    }
}

/// Refuses an observation with a NaN or infinite entry, seen at `step`.
pub(crate) fn check_observation(obs: &[f64], step: u64) -> Result<()> {
    if obs.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(Error::NonFinite {
            what: "observation".into(),
            step,
        })
    }
}
