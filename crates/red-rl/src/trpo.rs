//! Trust region policy optimisation (Schulman et al., 2015) with the RED
//! release's settings (paper Sec. 5.2), on a [`GaussianPolicy`].
//!
//! One iteration: collect `steps_per_batch` steps (episodes continue across
//! batches); if a reward model is given, replace the rewards by its
//! `r(s, a)` (the true return is still recorded); update the observation
//! statistics; estimate advantages with GAE; take the natural-gradient step
//! `theta += beta * F^-1 g` with `beta = sqrt(2 max_kl / g^T F^-1 g)`,
//! solving with conjugate gradient on Fisher-vector products over a
//! subsample of the batch, then backtrack until the surrogate improves and
//! the mean KL (on the whole batch) is within bounds; fit the value
//! network; let an adaptive reward model learn from the batch.
//!
//! The trainer's whole state (networks, optimiser, statistics, random
//! streams, counters, the episode in progress) is serde-serialisable:
//! a run saved and resumed gives the same numbers as an uninterrupted one.
//!
//! ```no_run
//! use red_rl::trpo::{TrpoConfig, TrpoTrainer};
//! # fn demo<E: red_core::Env>(mut env: E) -> red_rl::Result<()> {
//! let mut trainer = TrpoTrainer::new(TrpoConfig::default(), 11, 3, None, 0)?;
//! trainer.train(&mut env, None, 1_000_000, |_t, m| {
//!     println!("{} {:?}", m.env_steps, m.mean_true_return);
//!     Ok(std::ops::ControlFlow::Continue(()))
//! })?;
//! # Ok(()) }
//! ```

use std::ops::ControlFlow;

use ndarray::{Array2, ArrayView2, Axis, concatenate, s};
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use red_core::{Env, RewardModel, Seeder, Stream};
use red_nets::{
    Activation, Adam, AdamConfig, Gradients, Init, Mlp, MlpConfig, Optimizer, Tape, Workspace,
    mse_loss_into,
};
use serde::{Deserialize, Serialize};

use crate::gae::{GaeConfig, gae};
use crate::normalize::{DEFAULT_CLIP, DEFAULT_MIN_STD, ObsNormalizer};
use crate::policy::{GaussianPolicy, GaussianPolicyConfig};
use crate::rollout::{RolloutBatch, RolloutCollector};
use crate::{Error, Result};

/// Settings of [`TrpoTrainer`]. Defaults are the RED release's MuJoCo
/// settings (`reference/original-red.md`) unless a field says otherwise.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrpoConfig {
    /// The policy network. Default 2 x 100 tanh (release).
    pub policy: GaussianPolicyConfig,
    /// Hidden widths of the value network. Default `[100, 100]` (release).
    pub value_hidden: Vec<usize>,
    /// Hidden activation of the value network. Default tanh (release).
    pub value_activation: Activation,
    /// Adam step size of the value network. Default 1e-3 (release).
    pub value_lr: f32,
    /// Passes over each batch when fitting the value network. Default 5
    /// (release).
    pub value_epochs: usize,
    /// Minibatch size of the value fit. Default 128 (release).
    pub value_batch_size: usize,
    /// Whether the value network predicts returns normalised by their
    /// running mean and standard deviation. Default true (release).
    pub normalize_value_targets: bool,
    /// Discounting and GAE. Default gamma 0.97, lambda 0.97, a time-limit
    /// cut treated as terminal (release; use gamma 0.99 for Reacher).
    pub gae: GaeConfig,
    /// Environment steps per iteration. Default 1024 (release).
    pub steps_per_batch: usize,
    /// Trust region: bound on the mean `KL(pi_old || pi)`. Default 0.01
    /// (release).
    pub max_kl: f64,
    /// Conjugate-gradient iterations. Default 10 (release).
    pub cg_iters: usize,
    /// Damping added to the Fisher matrix, `F + damping I`. Default 0.1
    /// (release).
    pub cg_damping: f64,
    /// Fisher-vector products use every `fvp_subsample`-th step of the
    /// batch. Default 5 (release).
    pub fvp_subsample: usize,
    /// Backtracking line-search steps (each halves the step). Default 10
    /// (release).
    pub max_backtracks: usize,
    /// A line-search step is accepted when the mean KL on the batch is at
    /// most `kl_accept_factor * max_kl` (and the surrogate improved).
    /// Default 1.5: OpenAI baselines' TRPO, on which the release is built,
    /// accepts up to 1.5 times the bound (the step is sized on a quadratic
    /// model of the KL). 1.0 enforces the bound exactly.
    pub kl_accept_factor: f64,
    /// Whether advantages are standardised per batch. Default true
    /// (baselines' TRPO).
    pub normalize_advantages: bool,
    /// Whether observations are normalised by running statistics when no
    /// fixed normaliser is given to [`TrpoTrainer::new`]. Default true.
    pub normalize_observations: bool,
    /// Clip of normalised observations. Default 5 (release).
    pub obs_clip: f64,
    /// Floor of the observation standard deviation. Default 0.1 (see
    /// [`DEFAULT_MIN_STD`]).
    pub obs_min_std: f64,
    /// Whether sampled actions are clipped to the action space before they
    /// reach the environment (log-probabilities and reward models use the
    /// unclipped ones). Default true: environments of this workspace may
    /// reject actions outside their box.
    pub clip_actions: bool,
}

impl Default for TrpoConfig {
    fn default() -> Self {
        Self {
            policy: GaussianPolicyConfig::default(),
            value_hidden: vec![100, 100],
            value_activation: Activation::Tanh,
            value_lr: 1e-3,
            value_epochs: 5,
            value_batch_size: 128,
            normalize_value_targets: true,
            gae: GaeConfig::default(),
            steps_per_batch: 1024,
            max_kl: 0.01,
            cg_iters: 10,
            cg_damping: 0.1,
            fvp_subsample: 5,
            max_backtracks: 10,
            kl_accept_factor: 1.5,
            normalize_advantages: true,
            normalize_observations: true,
            obs_clip: DEFAULT_CLIP,
            obs_min_std: DEFAULT_MIN_STD,
            clip_actions: true,
        }
    }
}

impl TrpoConfig {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the first bad field.
    pub fn validate(&self) -> Result<()> {
        let bad = |field: &str, reason: String| {
            Err(Error::InvalidConfig {
                field: field.into(),
                reason,
            })
        };
        self.policy.validate()?;
        self.gae.validate()?;
        if self.value_hidden.contains(&0) {
            return bad("value_hidden", "widths must be at least 1".into());
        }
        if !(self.value_lr.is_finite() && self.value_lr > 0.0) {
            return bad(
                "value_lr",
                format!("must be finite and > 0, got {}", self.value_lr),
            );
        }
        for (field, v) in [
            ("value_batch_size", self.value_batch_size),
            ("steps_per_batch", self.steps_per_batch),
            ("cg_iters", self.cg_iters),
            ("fvp_subsample", self.fvp_subsample),
            ("max_backtracks", self.max_backtracks),
        ] {
            if v == 0 {
                return bad(field, "must be at least 1".into());
            }
        }
        for (field, v) in [
            ("max_kl", self.max_kl),
            ("kl_accept_factor", self.kl_accept_factor),
            ("obs_clip", self.obs_clip),
            ("obs_min_std", self.obs_min_std),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(field, format!("must be finite and > 0, got {v}"));
            }
        }
        if !(self.cg_damping.is_finite() && self.cg_damping >= 0.0) {
            return bad(
                "cg_damping",
                format!("must be finite and >= 0, got {}", self.cg_damping),
            );
        }
        Ok(())
    }
}

/// Solves `A x = b` for a symmetric positive-definite `A` given only as a
/// product `avp(v, out)` writing `A v` into `out`, with at most `iters`
/// conjugate-gradient iterations from `x = 0`, stopping early once the
/// squared residual is below `residual_tol`.
pub fn conjugate_gradient(
    mut avp: impl FnMut(&[f64], &mut [f64]),
    b: &[f64],
    iters: usize,
    residual_tol: f64,
) -> Vec<f64> {
    let n = b.len();
    let mut x = vec![0.0; n];
    let mut r = b.to_vec();
    let mut p = b.to_vec();
    let mut ap = vec![0.0; n];
    let mut rr = dot(&r, &r);
    for _ in 0..iters {
        if rr < residual_tol {
            break;
        }
        avp(&p, &mut ap);
        let pap = dot(&p, &ap);
        if pap <= 0.0 || !pap.is_finite() {
            break;
        }
        let alpha = rr / pap;
        for i in 0..n {
            x[i] += alpha * p[i];
            r[i] -= alpha * ap[i];
        }
        let rr_new = dot(&r, &r);
        let beta = rr_new / rr;
        for i in 0..n {
            p[i] = r[i] + beta * p[i];
        }
        rr = rr_new;
    }
    x
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// What one iteration did, for logging and checkpoint decisions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IterationMetrics {
    /// Iterations completed, this one included.
    pub iteration: u64,
    /// Environment steps taken so far.
    pub env_steps: u64,
    /// True returns of the episodes that ended in this iteration's batch.
    pub true_returns: Vec<f64>,
    /// Mean of `true_returns` (`charts/episodic_return`); `None` if no
    /// episode ended.
    pub mean_true_return: Option<f64>,
    /// Mean length of the episodes that ended; `None` if none did.
    pub mean_episode_length: Option<f64>,
    /// Mean per-step reward of the reward model over the batch; `None`
    /// when learning from the environment's reward.
    pub mean_imitation_reward: Option<f64>,
    /// Mean per-step true reward over the batch.
    pub mean_true_reward: f64,
    /// Surrogate loss `-mean(ratio * advantage)` after the update
    /// (`losses/policy_loss`).
    pub policy_loss: f64,
    /// Mean squared error of the value fit over its last epoch, in the
    /// units the network predicts (normalised returns by default)
    /// (`losses/value_loss`).
    pub value_loss: f64,
    /// Mean `KL(pi_old || pi_new)` of the step on the batch (0 if rejected).
    pub kl: f64,
    /// Mean entropy of the updated policy on the batch.
    pub entropy: f64,
    /// Line-search halvings before acceptance (or the maximum if none was
    /// accepted).
    pub backtracks: usize,
    /// Whether a step was accepted.
    pub step_accepted: bool,
}

/// Buffers reused across iterations (not part of the saved state).
#[derive(Debug, Default)]
struct Scratch {
    tape: Tape,
    fvp_tape: Tape,
    ws: Workspace,
    value_tape: Tape,
}

impl Clone for Scratch {
    fn clone(&self) -> Self {
        Self::default()
    }
}

/// TRPO with a Gaussian policy and a value network; see the module docs.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrpoTrainer {
    config: TrpoConfig,
    policy: GaussianPolicy,
    value: Mlp,
    value_opt: Adam,
    /// Running statistics of the value targets (when normalised).
    return_stats: Option<ObsNormalizer>,
    collector: RolloutCollector,
    explore_rng: ChaCha8Rng,
    env_rng: ChaCha8Rng,
    minibatch_rng: ChaCha8Rng,
    iteration: u64,
    env_steps: u64,
    #[serde(skip)]
    scratch: Scratch,
}

/// Name written in saved trainer states.
pub const TRPO_STATE_FORMAT: &str = "red-rl/trpo-state";
/// Version of the saved trainer format.
pub const TRPO_STATE_VERSION: u32 = 1;

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SavedTrainer {
    format: String,
    version: u32,
    trainer: TrpoTrainer,
}

impl TrpoTrainer {
    /// A fresh trainer for observations of `obs_dim` and actions of
    /// `act_dim`. `normalizer` fixes the observation normalisation (for
    /// example statistics of the expert's observations, frozen, as the
    /// release does for RED and AE); without it, running statistics are
    /// used if `config.normalize_observations`. Every random stream derives
    /// from `seed` ([`Seeder`]).
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] for a bad config, dimension mismatches.
    pub fn new(
        config: TrpoConfig,
        obs_dim: usize,
        act_dim: usize,
        normalizer: Option<ObsNormalizer>,
        seed: u64,
    ) -> Result<Self> {
        config.validate()?;
        let seeder = Seeder::new(seed);
        let mut init_rng = seeder.rng(Stream::Init);
        let normalizer = match normalizer {
            Some(n) => Some(n),
            None if config.normalize_observations => Some(ObsNormalizer::new(
                obs_dim,
                config.obs_clip,
                config.obs_min_std,
            )?),
            None => None,
        };
        let policy =
            GaussianPolicy::new(&config.policy, obs_dim, act_dim, normalizer, &mut init_rng)?;
        let value_cfg = MlpConfig {
            input: obs_dim,
            hidden: config.value_hidden.clone(),
            output: 1,
            activation: config.value_activation,
            output_activation: Activation::Identity,
            init: Init::Orthogonal { gain: 1.0 },
        };
        let value = Mlp::new(&value_cfg, &mut init_rng)?;
        let value_opt = Adam::new(AdamConfig::with_lr(config.value_lr), &value)?;
        let return_stats = if config.normalize_value_targets {
            // A tiny floor: returns are not clipped and may have any scale.
            Some(ObsNormalizer::new(1, f64::MAX, 1e-6)?)
        } else {
            None
        };
        Ok(Self {
            collector: RolloutCollector::new(config.clip_actions),
            config,
            policy,
            value,
            value_opt,
            return_stats,
            explore_rng: seeder.rng(Stream::Exploration),
            env_rng: seeder.rng(Stream::Env),
            minibatch_rng: seeder.rng(Stream::Replay),
            iteration: 0,
            env_steps: 0,
            scratch: Scratch::default(),
        })
    }

    /// The settings.
    pub fn config(&self) -> &TrpoConfig {
        &self.config
    }

    /// The current policy (with its observation normaliser).
    pub fn policy(&self) -> &GaussianPolicy {
        &self.policy
    }

    /// The policy, mutably (for example to warm-start it with behaviour
    /// cloning before training).
    pub fn policy_mut(&mut self) -> &mut GaussianPolicy {
        &mut self.policy
    }

    /// The value network (input: normalised observations).
    pub fn value_net(&self) -> &Mlp {
        &self.value
    }

    /// Iterations completed.
    pub fn iteration(&self) -> u64 {
        self.iteration
    }

    /// Environment steps taken.
    pub fn env_steps(&self) -> u64 {
        self.env_steps
    }

    /// The state as JSON (with a format header), to checkpoint a run.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] if serialisation fails.
    pub fn to_json(&self) -> Result<String> {
        let doc = SavedTrainer {
            format: TRPO_STATE_FORMAT.into(),
            version: TRPO_STATE_VERSION,
            trainer: self.clone(),
        };
        serde_json::to_string(&doc).map_err(|e| Error::InvalidConfig {
            field: "trpo state".into(),
            reason: format!("cannot serialise: {e}"),
        })
    }

    /// A trainer from [`TrpoTrainer::to_json`]'s output. The next
    /// iteration first replays the interrupted episode into the environment
    /// it is given.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming what is wrong with the text.
    pub fn from_json(s: &str) -> Result<Self> {
        let doc: SavedTrainer = serde_json::from_str(s).map_err(|e| Error::InvalidConfig {
            field: "trpo state".into(),
            reason: format!("not a saved TRPO state: {e}"),
        })?;
        if doc.format != TRPO_STATE_FORMAT || doc.version != TRPO_STATE_VERSION {
            return Err(Error::InvalidConfig {
                field: "trpo state".into(),
                reason: format!(
                    "format `{}` version {} is not `{TRPO_STATE_FORMAT}` version {TRPO_STATE_VERSION}",
                    doc.format, doc.version
                ),
            });
        }
        doc.trainer.config.validate()?;
        Ok(doc.trainer)
    }

    /// Runs iterations until at least `total_env_steps` environment steps
    /// have been taken, calling `callback` after each with the trainer (to
    /// checkpoint or evaluate) and the iteration's metrics; the callback
    /// stops training early with `ControlFlow::Break`. The short form of
    /// [`TrpoTrainer::train_with`].
    ///
    /// # Errors
    /// Any error of [`TrpoTrainer::iterate`] or of the callback.
    pub fn train<E: Env + ?Sized>(
        &mut self,
        env: &mut E,
        reward: Option<&mut dyn RewardModel>,
        total_env_steps: u64,
        callback: impl FnMut(&Self, &IterationMetrics) -> Result<ControlFlow<()>>,
    ) -> Result<()> {
        // Only the callback can stop training, and it knows when it did.
        let _ = self.train_with(env, total_env_steps, &mut Callback { reward, callback })?;
        Ok(())
    }

    /// The training loop: runs iterations until at least `total_env_steps`
    /// environment steps have been taken (counting those of earlier calls
    /// and of a resumed state), with `hooks` before each iteration (to stop
    /// or checkpoint), supplying the reward model, and after each (to
    /// record, select or checkpoint). Returns `Break` when a hook stopped
    /// training early.
    ///
    /// # Errors
    /// Any error of [`TrpoTrainer::iterate`] or of the hooks.
    pub fn train_with<E: Env + ?Sized, H: TrpoHooks<E> + ?Sized>(
        &mut self,
        env: &mut E,
        total_env_steps: u64,
        hooks: &mut H,
    ) -> std::result::Result<ControlFlow<()>, H::Error> {
        while self.env_steps < total_env_steps {
            if hooks.before_iteration(self)?.is_break() {
                return Ok(ControlFlow::Break(()));
            }
            let m = self.iterate(env, hooks.reward())?;
            if hooks.after_iteration(self, env, &m)?.is_break() {
                return Ok(ControlFlow::Break(()));
            }
        }
        Ok(ControlFlow::Continue(()))
    }

    /// One iteration: collect a batch, update the policy and the value
    /// network, and let an adaptive reward model learn from the batch.
    ///
    /// With `reward`, the learner's rewards are `reward.rewards(s, a)` on
    /// the batch's (raw) observations and unclipped actions; the
    /// environment's reward (or its [`red_core::TRUE_REWARD`] info) is only
    /// recorded.
    ///
    /// # Errors
    /// Dimension mismatches between the trainer and the environment, an
    /// environment or reward-model error, or [`Error::NonFinite`] when an
    /// observation, action, reward, advantage or loss is NaN or infinite.
    pub fn iterate<E: Env + ?Sized>(
        &mut self,
        env: &mut E,
        reward: Option<&mut dyn RewardModel>,
    ) -> Result<IterationMetrics> {
        let batch = self.collect(env)?;
        self.update(&batch, reward)
    }

    /// The collection half of [`TrpoTrainer::iterate`]: `steps_per_batch`
    /// steps of the current policy, counted in [`TrpoTrainer::env_steps`].
    ///
    /// # Errors
    /// Dimension mismatches, an environment error, or a failed replay of
    /// the interrupted episode after a resume.
    pub fn collect<E: Env + ?Sized>(&mut self, env: &mut E) -> Result<RolloutBatch> {
        let batch = self.collector.collect(
            env,
            &self.policy,
            self.config.steps_per_batch,
            &mut self.explore_rng,
            &mut self.env_rng,
        )?;
        self.env_steps += batch.len() as u64;
        Ok(batch)
    }

    /// The learning half of [`TrpoTrainer::iterate`] on a batch from
    /// [`TrpoTrainer::collect`].
    ///
    /// # Errors
    /// As [`TrpoTrainer::iterate`].
    pub fn update(
        &mut self,
        batch: &RolloutBatch,
        reward: Option<&mut dyn RewardModel>,
    ) -> Result<IterationMetrics> {
        let step_id = self.env_steps;
        check_batch(batch, self.policy.obs_dim(), self.policy.act_dim(), step_id)?;
        let mean_true_reward = mean(&batch.true_rewards);
        let (rewards, mean_imitation_reward) = match &reward {
            Some(model) => {
                let r = model.rewards(batch.observations.view(), batch.actions.view())?;
                if r.len() != batch.len() {
                    return Err(Error::ShapeMismatch {
                        what: "reward model output".into(),
                        expected: format!("{} rewards", batch.len()),
                        got: format!("{}", r.len()),
                    });
                }
                let r = r.to_vec();
                let m = mean(&r);
                (r, Some(m))
            }
            None => (batch.true_rewards.clone(), None),
        };
        if rewards.iter().any(|r| !r.is_finite()) {
            return Err(Error::NonFinite {
                what: "reward".into(),
                step: step_id,
            });
        }

        // As the release: statistics first, then every quantity of the
        // update under the new statistics.
        if let Some(n) = self.policy.normalizer_mut() {
            n.update(batch.observations.view())?;
        }
        let obs = self.policy.prepare_obs(batch.observations.view())?;
        let boundary = self
            .policy
            .prepare_obs(batch.boundary_observations.view())?;
        let (advantages, returns) =
            self.advantages(batch, &rewards, obs.view(), boundary.view())?;
        if advantages.iter().any(|a| !a.is_finite()) {
            return Err(Error::NonFinite {
                what: "advantage".into(),
                step: step_id,
            });
        }

        let step = self.policy_step(obs.view(), batch.actions.view(), &advantages, step_id)?;
        let value_loss = self.fit_value(obs.view(), &returns, step_id)?;
        if let Some(model) = reward
            && model.is_adaptive()
        {
            model.update(batch.observations.view(), batch.actions.view())?;
        }
        self.iteration += 1;
        let n_eps = batch.episode_returns.len();
        Ok(IterationMetrics {
            iteration: self.iteration,
            env_steps: self.env_steps,
            mean_true_return: (n_eps > 0).then(|| mean(&batch.episode_returns)),
            mean_episode_length: (n_eps > 0)
                .then(|| batch.episode_lengths.iter().sum::<usize>() as f64 / n_eps as f64),
            true_returns: batch.episode_returns.clone(),
            mean_imitation_reward,
            mean_true_reward,
            policy_loss: step.policy_loss,
            value_loss,
            kl: step.kl,
            entropy: step.entropy,
            backtracks: step.backtracks,
            step_accepted: step.accepted,
        })
    }

    /// Value predictions (in return units) for prepared observations.
    fn predict_values(&mut self, obs: ArrayView2<'_, f32>) -> Vec<f64> {
        let out = self.value.forward(obs, &mut self.scratch.ws);
        let (m, sd) = match &self.return_stats {
            Some(st) => (st.mean()[0], st.stds()[0]),
            None => (0.0, 1.0),
        };
        out.column(0).iter().map(|&v| m + sd * v as f64).collect()
    }

    fn advantages(
        &mut self,
        batch: &RolloutBatch,
        rewards: &[f64],
        obs: ArrayView2<'_, f32>,
        boundary: ArrayView2<'_, f32>,
    ) -> Result<(Vec<f64>, Vec<f64>)> {
        let t_len = batch.len();
        let all = concatenate(Axis(0), &[obs, boundary]).map_err(|e| Error::ShapeMismatch {
            what: "observations and boundary observations".into(),
            expected: "the same number of columns".into(),
            got: e.to_string(),
        })?;
        let v_all = self.predict_values(all.view());
        let values = &v_all[..t_len];
        let mut next_values = vec![0.0; t_len];
        next_values[..t_len.saturating_sub(1)].copy_from_slice(&values[1..]);
        for (k, &t) in batch.boundary_steps.iter().enumerate() {
            next_values[t] = v_all[t_len + k];
        }
        let (mut adv, ret) = gae(
            &self.config.gae,
            rewards,
            values,
            &next_values,
            &batch.terminated,
            &batch.truncated,
        )?;
        if self.config.normalize_advantages && adv.len() > 1 {
            let m = mean(&adv);
            let sd = (adv.iter().map(|a| (a - m) * (a - m)).sum::<f64>() / adv.len() as f64).sqrt();
            for a in &mut adv {
                *a = (*a - m) / (sd + 1e-8);
            }
        }
        Ok((adv, ret))
    }

    fn policy_step(
        &mut self,
        obs: ArrayView2<'_, f32>,
        actions: ArrayView2<'_, f64>,
        adv: &[f64],
        step_id: u64,
    ) -> Result<PolicyStep> {
        let n = obs.nrows();
        let k = self.policy.act_dim();
        let old = self.policy.distribution_tape(obs, &mut self.scratch.tape)?;
        let logp_old = old.log_prob(actions);

        // Gradient of the surrogate mean(A * ratio) at the old policy: by
        // component, A / n * d log pi / d (mu, log_sigma).
        let mut d_mean = Array2::zeros((n, k));
        let mut d_ls = Array2::zeros((n, k));
        for i in 0..n {
            let w = adv[i] / n as f64;
            for j in 0..k {
                let inv_var = (-2.0 * old.log_std[[i, j]]).exp();
                let diff = actions[[i, j]] - old.mean[[i, j]];
                d_mean[[i, j]] = w * diff * inv_var;
                d_ls[[i, j]] = w * (diff * diff * inv_var - 1.0);
            }
        }
        let mut grads = self.policy.net().zero_grads();
        self.policy.backward_params(
            &self.scratch.tape,
            &old,
            d_mean.view(),
            d_ls.view(),
            &mut grads,
        );
        let g: Vec<f64> = grads.flat().iter().map(|&v| v as f64).collect();
        if g.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "policy gradient".into(),
                step: step_id,
            });
        }
        let surr_old = mean(adv);
        let entropy_old = mean(&old.entropy());
        let unchanged = PolicyStep {
            policy_loss: -surr_old,
            kl: 0.0,
            entropy: entropy_old,
            backtracks: self.config.max_backtracks,
            accepted: false,
        };
        if g.iter().all(|&v| v == 0.0) {
            return Ok(unchanged);
        }

        // Fisher-vector products on every fvp_subsample-th step.
        let sub = obs.slice(s![..;self.config.fvp_subsample, ..]);
        let old_sub = self
            .policy
            .distribution_tape(sub, &mut self.scratch.fvp_tape)?;
        let damping = self.config.cg_damping;
        let policy = &self.policy;
        let tape = &self.scratch.fvp_tape;
        let mut fv = policy.net().zero_grads();
        let mut fvp = |v: &[f64], out: &mut [f64]| {
            let v32: Vec<f32> = v.iter().map(|&x| x as f32).collect();
            let dir = Gradients::from_flat(policy.net(), &v32)
                .expect("direction has the network's layout");
            policy.fisher_vector_product(tape, &old_sub, &dir, &mut fv);
            for ((o, f), x) in out.iter_mut().zip(fv.flat()).zip(v) {
                *o = f as f64 + damping * x;
            }
        };
        let dir = conjugate_gradient(&mut fvp, &g, self.config.cg_iters, 1e-10);
        let mut fdir = vec![0.0; dir.len()];
        fvp(&dir, &mut fdir);
        let shs = 0.5 * dot(&dir, &fdir);
        if !(shs.is_finite() && shs > 0.0) {
            return Err(Error::NonFinite {
                what: "natural-gradient step size".into(),
                step: step_id,
            });
        }
        let scale = (shs / self.config.max_kl).sqrt();
        let theta_old = self.policy.net().params_flat();
        let mut theta = theta_old.clone();
        let mut frac = 1.0;
        for b in 0..self.config.max_backtracks {
            for i in 0..theta.len() {
                theta[i] = (theta_old[i] as f64 + frac * dir[i] / scale) as f32;
            }
            if self.policy.net_mut().set_params_flat(&theta).is_ok() {
                let new = self.policy.distribution(obs, &mut self.scratch.ws)?;
                let logp = new.log_prob(actions);
                let surr = (0..n)
                    .map(|i| (logp[i] - logp_old[i]).exp() * adv[i])
                    .sum::<f64>()
                    / n as f64;
                let kl = mean(&old.kl(&new));
                let ok = surr.is_finite()
                    && kl.is_finite()
                    && kl <= self.config.kl_accept_factor * self.config.max_kl
                    && surr > surr_old;
                if ok {
                    return Ok(PolicyStep {
                        policy_loss: -surr,
                        kl,
                        entropy: mean(&new.entropy()),
                        backtracks: b,
                        accepted: true,
                    });
                }
            }
            frac *= 0.5;
        }
        self.policy.net_mut().set_params_flat(&theta_old)?;
        Ok(unchanged)
    }

    fn fit_value(
        &mut self,
        obs: ArrayView2<'_, f32>,
        returns: &[f64],
        step_id: u64,
    ) -> Result<f64> {
        let (m, sd) = match &mut self.return_stats {
            Some(st) => {
                let col = ArrayView2::from_shape((returns.len(), 1), returns).map_err(|e| {
                    Error::ShapeMismatch {
                        what: "returns".into(),
                        expected: "a column".into(),
                        got: e.to_string(),
                    }
                })?;
                st.update(col)?;
                (st.mean()[0], st.stds()[0])
            }
            None => (0.0, 1.0),
        };
        let n = returns.len();
        let od = obs.ncols();
        let bs = self.config.value_batch_size.min(n);
        let targets: Vec<f32> = returns.iter().map(|r| ((r - m) / sd) as f32).collect();
        let mut idx: Vec<usize> = (0..n).collect();
        let mut x = Array2::<f32>::zeros((bs, od));
        let mut y = Array2::<f32>::zeros((bs, 1));
        let mut grad_out = Array2::<f32>::zeros((bs, 1));
        let mut grads = self.value.zero_grads();
        let mut last_epoch_loss = 0.0;
        for _ in 0..self.config.value_epochs {
            idx.shuffle(&mut self.minibatch_rng);
            let (mut sum, mut count) = (0.0, 0);
            for chunk in idx.chunks(bs) {
                if chunk.len() != x.nrows() {
                    x = Array2::zeros((chunk.len(), od));
                    y = Array2::zeros((chunk.len(), 1));
                }
                for (r, &i) in chunk.iter().enumerate() {
                    x.row_mut(r).assign(&obs.row(i));
                    y[[r, 0]] = targets[i];
                }
                let pred = self
                    .value
                    .forward_tape(x.view(), &mut self.scratch.value_tape);
                let loss = mse_loss_into(pred, y.view(), &mut grad_out);
                if !loss.is_finite() {
                    return Err(Error::NonFinite {
                        what: "value loss".into(),
                        step: step_id,
                    });
                }
                grads.zero();
                self.value
                    .backward_params(&self.scratch.value_tape, grad_out.view(), &mut grads);
                self.value_opt.step(&mut self.value, &grads)?;
                sum += loss as f64;
                count += 1;
                if x.nrows() != bs {
                    x = Array2::zeros((bs, od));
                    y = Array2::zeros((bs, 1));
                }
            }
            last_epoch_loss = sum / count.max(1) as f64;
        }
        Ok(last_epoch_loss)
    }
}

/// What [`TrpoTrainer::train_with`] calls around its iterations. The
/// hooks hold what a caller keeps beside the trainer (the reward model,
/// records, a stop flag), so that they can checkpoint both together.
pub trait TrpoHooks<E: ?Sized> {
    /// The hooks' error; the trainer's errors convert into it.
    type Error: From<Error>;

    /// Before each iteration; `Break` ends training before it (for
    /// example on a stop request, after saving a checkpoint).
    ///
    /// # Errors
    /// The hooks' own; an error ends training.
    fn before_iteration(
        &mut self,
        _trainer: &TrpoTrainer,
    ) -> std::result::Result<ControlFlow<()>, Self::Error> {
        Ok(ControlFlow::Continue(()))
    }

    /// The reward model of the next iteration; `None`, the default, learns
    /// from the environment's reward.
    fn reward(&mut self) -> Option<&mut dyn RewardModel> {
        None
    }

    /// After each iteration, with the environment (to read what it
    /// counts) and the iteration's metrics; `Break` ends training.
    ///
    /// # Errors
    /// The hooks' own; an error ends training.
    fn after_iteration(
        &mut self,
        trainer: &TrpoTrainer,
        env: &mut E,
        metrics: &IterationMetrics,
    ) -> std::result::Result<ControlFlow<()>, Self::Error>;
}

/// [`TrpoTrainer::train`]'s hooks: a reward model and a callback.
struct Callback<'r, F> {
    reward: Option<&'r mut dyn RewardModel>,
    callback: F,
}

impl<E: ?Sized, F> TrpoHooks<E> for Callback<'_, F>
where
    F: FnMut(&TrpoTrainer, &IterationMetrics) -> Result<ControlFlow<()>>,
{
    type Error = Error;

    fn reward(&mut self) -> Option<&mut dyn RewardModel> {
        match self.reward {
            Some(ref mut m) => Some(&mut **m),
            None => None,
        }
    }

    fn after_iteration(
        &mut self,
        trainer: &TrpoTrainer,
        _env: &mut E,
        metrics: &IterationMetrics,
    ) -> Result<ControlFlow<()>> {
        (self.callback)(trainer, metrics)
    }
}

/// Rejects a batch whose parts disagree (its fields are public, so one can
/// be built by hand) or hold a NaN or infinite value; `step` is the
/// environment step the batch ends at.
fn check_batch(batch: &RolloutBatch, obs_dim: usize, act_dim: usize, step: u64) -> Result<()> {
    let t = batch.len();
    let b = batch.boundary_steps.len();
    let ok = t > 0
        && batch.observations.dim() == (t, obs_dim)
        && batch.actions.dim() == (t, act_dim)
        && batch.terminated.len() == t
        && batch.truncated.len() == t
        && batch.boundary_observations.dim() == (b, obs_dim)
        && batch.boundary_steps.iter().all(|&s| s < t)
        && batch.boundary_steps.last() == Some(&(t - 1));
    if !ok {
        return Err(Error::ShapeMismatch {
            what: "rollout batch".into(),
            expected: format!(
                "at least one step, (T, {obs_dim}) observations, (T, {act_dim}) actions, T flags, \
                 and boundary steps below T ending with the last step"
            ),
            got: format!(
                "T = {t}, observations {:?}, actions {:?}, {} boundary steps",
                batch.observations.dim(),
                batch.actions.dim(),
                b
            ),
        });
    }
    let non_finite = |what: String| Err(Error::NonFinite { what, step });
    if let Some(i) = batch.observations.iter().position(|v| !v.is_finite()) {
        return non_finite(format!("observation (entry {i} of the batch)"));
    }
    if batch.boundary_observations.iter().any(|v| !v.is_finite()) {
        return non_finite("observation at an episode end".into());
    }
    if batch.true_rewards.iter().any(|v| !v.is_finite()) {
        return non_finite("true reward".into());
    }
    if batch.actions.iter().any(|v| !v.is_finite()) {
        return non_finite("action".into());
    }
    Ok(())
}

struct PolicyStep {
    policy_loss: f64,
    kl: f64,
    entropy: f64,
    backtracks: usize,
    accepted: bool,
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}
