//! Soft Actor-Critic (Haarnoja et al. 2018a, "Soft Actor-Critic: Off-Policy
//! Maximum Entropy Deep Reinforcement Learning with a Stochastic Actor";
//! 2018b, "Soft Actor-Critic Algorithms and Applications", Algorithm 1 with
//! the automatic entropy adjustment of Sec. 5).
//!
//! - Actor: a tanh-squashed Gaussian, `a = tanh(u)`, `u = mu(x) +
//!   sigma(x) eps` ([`GaussianPolicy`] with `squash` on), log-probability
//!   `log N(u; mu, sigma) - sum_j ln(1 - a_j^2 + 1e-6)` (2018a, Appendix C,
//!   Eq. 21). Its deterministic action is `tanh(mu(x))`.
//! - Twin soft Q critics `Q_1, Q_2(x, a)` with Polyak-averaged target copies;
//!   each is fitted to `y = c r + gamma (1 - d) [min_k Qbar_k(x', a') -
//!   alpha log pi(a'|x')]`, `a' ~ pi(.|x')` (2018b, Eq. 5 with the clipped
//!   double-Q of Sec. 6), `c` the reward scale.
//! - Actor loss `E[alpha log pi(a|x) - min_k Q_k(x, a)]` with the
//!   reparameterised sample (2018b, Eq. 7).
//! - Temperature: `log alpha` minimises `-log alpha (log pi(a|x) + H)` with
//!   the target entropy `H = -dim(A)` (2018b, Eq. 18 and Sec. 5).
//!
//! Critics and actor read the policy's prepared observation `x` (its own
//! normaliser, if any). The reward of a stored transition is the imitation
//! reward of a [`DifferentiableReward`] (only its value is used); an
//! adaptive reward (GAIL, GMMIL) is recomputed for every replayed batch, the
//! terminal heuristic's adjustment kept apart so it survives. The learner
//! serialises whole (networks, optimiser moments, temperature, replay, step
//! count), so a run can be checkpointed between episodes and resumed
//! exactly.

use ndarray::{Array2, ArrayView2, Axis, concatenate, s};
use rand::{Rng, RngExt};
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

use red_core::{Env, Info};
use red_nets::{
    Activation, Adam, AdamConfig, Init, Mlp, MlpConfig, Optimizer, Tape, clip_grad_norm, mse_loss,
};

use crate::episodic::{EpisodeLog, EpisodeOutcome, EpisodicLearner};
use crate::policy::{GaussianBatch, GaussianPolicy, PolicyWorkspace};
use crate::replay::{Batch, ReplayBuffer};
use crate::svg::DifferentiableReward;
use crate::{Error, Result};

/// `0.5 * ln(2 pi)`.
const HALF_LN_2PI: f64 = 0.918_938_533_204_672_7;
/// The `1e-6` inside `ln(1 - tanh(u)^2 + 1e-6)` (the authors' code).
const SQUASH_EPS: f64 = 1e-6;

/// Settings of [`Sac`]. The defaults are Table 1 of Haarnoja et al. 2018b
/// ("SAC Algorithms and Applications") unless marked as ours.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SacConfig {
    /// Hidden widths of each Q network. Table 1: 2 layers of 256.
    pub hidden: Vec<usize>,
    /// Hidden activation of the Q networks. Table 1: ReLU.
    pub activation: Activation,
    /// Discount. Table 1: 0.99.
    pub gamma: f64,
    /// Polyak factor of the target Q networks per gradient step (target
    /// update interval 1). Table 1: 0.005.
    pub tau: f64,
    /// Adam learning rate of the actor. Table 1: 3e-4.
    pub actor_lr: f32,
    /// Adam learning rate of the Q networks. Table 1: 3e-4.
    pub critic_lr: f32,
    /// Adam learning rate of `log alpha`. Table 1: 3e-4.
    pub alpha_lr: f32,
    /// Minibatch size. Table 1: 256.
    pub batch_size: usize,
    /// Replay capacity in transitions. Table 1: 1e6.
    pub buffer_size: usize,
    /// Environment steps before the first update. Ours: 1,000 (the paper
    /// does not list it).
    pub learning_starts: u64,
    /// Gradient steps per environment step. Table 1: 1.
    pub updates_per_step: usize,
    /// Initial temperature `alpha`. Ours: 1.0 (the authors' softlearning
    /// code's initial value).
    pub init_alpha: f64,
    /// Whether `alpha` is adjusted to hold the target entropy (2018b,
    /// Sec. 5). Default true; false keeps `init_alpha` (2018a).
    pub auto_alpha: bool,
    /// Target entropy `H`. `None`: `-dim(A)`, Table 1's heuristic.
    pub target_entropy: Option<f64>,
    /// Factor on the stored reward in the critic target. 1 with automatic
    /// temperature (2018b; the fixed-temperature 2018a tuned it per task).
    pub reward_scale: f64,
    /// Gradient-norm clip of each network. `None` (the paper clips none).
    pub max_grad_norm: Option<f32>,
    /// Environment steps at the start of training whose actions are drawn
    /// uniformly from `(-1, 1)^dim(A)` instead of from the actor (the
    /// authors' softlearning code and stable-baselines3 fill the replay this
    /// way before learning; 10,000 steps on MuJoCo in both). Ours: default 0,
    /// no such steps and no random numbers drawn for them.
    #[serde(default)]
    pub random_steps: u64,
    /// Whether a step cut by the time limit ends the return like a terminal
    /// one (no bootstrap from its next state). Right when the state holds
    /// the time (a time feature: nothing follows the limit; Pardo et al.
    /// 2018); without it the cut is outside the task and the value goes on.
    /// Default false; false is not written, so older checkpoints resume.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub end_at_truncation: bool,
}

impl Default for SacConfig {
    fn default() -> Self {
        Self {
            hidden: vec![256, 256],
            activation: Activation::Relu,
            gamma: 0.99,
            tau: 0.005,
            actor_lr: 3e-4,
            critic_lr: 3e-4,
            alpha_lr: 3e-4,
            batch_size: 256,
            buffer_size: 1_000_000,
            learning_starts: 1_000,
            updates_per_step: 1,
            init_alpha: 1.0,
            auto_alpha: true,
            target_entropy: None,
            reward_scale: 1.0,
            max_grad_norm: None,
            random_steps: 0,
            end_at_truncation: false,
        }
    }
}

impl SacConfig {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the field.
    pub fn validate(&self) -> Result<()> {
        let bad = |field: &str, reason: String| {
            Err(Error::InvalidConfig {
                field: field.into(),
                reason,
            })
        };
        if self.hidden.contains(&0) {
            return bad("hidden", "widths must be at least 1".into());
        }
        if !(0.0..1.0).contains(&self.gamma) {
            return bad("gamma", format!("must lie in [0, 1), got {}", self.gamma));
        }
        if !(self.tau > 0.0 && self.tau <= 1.0) {
            return bad("tau", format!("must lie in (0, 1], got {}", self.tau));
        }
        for (f, v) in [
            ("actor_lr", self.actor_lr),
            ("critic_lr", self.critic_lr),
            ("alpha_lr", self.alpha_lr),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(f, format!("must be finite and > 0, got {v}"));
            }
        }
        for (f, v) in [
            ("batch_size", self.batch_size),
            ("buffer_size", self.buffer_size),
            ("updates_per_step", self.updates_per_step),
        ] {
            if v == 0 {
                return bad(f, "must be at least 1".into());
            }
        }
        for (f, v) in [
            ("init_alpha", self.init_alpha),
            ("reward_scale", self.reward_scale),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(f, format!("must be finite and > 0, got {v}"));
            }
        }
        if let Some(h) = self.target_entropy
            && !h.is_finite()
        {
            return bad("target_entropy", format!("must be finite, got {h}"));
        }
        if let Some(c) = self.max_grad_norm
            && !(c.is_finite() && c > 0.0)
        {
            return bad("max_grad_norm", format!("must be finite and > 0, got {c}"));
        }
        Ok(())
    }
}

/// Adam on one scalar (`log alpha`), the same update as [`Adam`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct ScalarAdam {
    lr: f64,
    m: f64,
    v: f64,
    t: i32,
}

impl ScalarAdam {
    fn step(&mut self, x: &mut f64, g: f64) {
        let (b1, b2, eps) = (0.9_f64, 0.999_f64, 1e-8);
        self.t += 1;
        self.m = b1 * self.m + (1.0 - b1) * g;
        self.v = b2 * self.v + (1.0 - b2) * g * g;
        let mh = self.m / (1.0 - b1.powi(self.t));
        let vh = self.v / (1.0 - b2.powi(self.t));
        *x -= self.lr * mh / (vh.sqrt() + eps);
    }
}

/// A minibatch for the SAC updates: the replay buffer's [`Batch`]; actions
/// lie in `(-1, 1)`.
pub type SacBatch = Batch;

/// Losses and statistics of one update.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SacStats {
    /// Mean squared TD error of the two critics (their mean).
    pub critic_loss: f64,
    /// Actor loss `mean(alpha log pi - min Q)`.
    pub actor_loss: f64,
    /// Mean `-log pi(a|x)` of the actor's fresh samples.
    pub entropy: f64,
    /// The temperature after the update.
    pub alpha: f64,
}

/// A Soft Actor-Critic learner; see the module documentation.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Sac {
    config: SacConfig,
    policy: GaussianPolicy,
    q1: Mlp,
    q2: Mlp,
    q1_target: Mlp,
    q2_target: Mlp,
    policy_opt: Adam,
    q1_opt: Adam,
    q2_opt: Adam,
    log_alpha: f64,
    alpha_opt: ScalarAdam,
    replay: ReplayBuffer,
    env_steps: u64,
}

/// A reparameterised squashed sample of a batch.
struct Squashed {
    dist: GaussianBatch,
    eps: Array2<f64>,
    actions: Array2<f64>,
    logp: Vec<f64>,
}

fn squashed_sample<R: Rng + ?Sized>(dist: GaussianBatch, rng: &mut R) -> Squashed {
    let (n, k) = dist.mean.dim();
    let eps = Array2::from_shape_simple_fn((n, k), || rng.sample::<f64, _>(StandardNormal));
    let mut actions = Array2::zeros((n, k));
    let mut logp = vec![0.0; n];
    for i in 0..n {
        for j in 0..k {
            let ls = dist.log_std[[i, j]];
            let e = eps[[i, j]];
            let a = (dist.mean[[i, j]] + ls.exp() * e).tanh();
            actions[[i, j]] = a;
            logp[i] += -0.5 * e * e - ls - HALF_LN_2PI - (1.0 - a * a + SQUASH_EPS).ln();
        }
    }
    Squashed {
        dist,
        eps,
        actions,
        logp,
    }
}

fn q_input(x: ArrayView2<'_, f32>, a: ArrayView2<'_, f64>) -> Array2<f32> {
    concatenate(Axis(1), &[x, a.mapv(|v| v as f32).view()]).expect("same number of rows")
}

impl Sac {
    /// A learner improving `policy` (which must have `squash` on), with
    /// fresh Q networks initialised from `rng`.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] for a bad config or an unsquashed policy.
    pub fn new<R: Rng + ?Sized>(
        config: &SacConfig,
        policy: GaussianPolicy,
        rng: &mut R,
    ) -> Result<Self> {
        config.validate()?;
        if !policy.config().squash {
            return Err(Error::InvalidConfig {
                field: "policy.squash".into(),
                reason: "SAC's actor is a tanh-squashed Gaussian: turn `squash` on".into(),
            });
        }
        let (o, a) = (policy.obs_dim(), policy.act_dim());
        let qcfg = MlpConfig::new(o + a, &config.hidden, 1)
            .with_activation(config.activation)
            .with_init(Init::GlorotUniform);
        let q1 = Mlp::new(&qcfg, rng)?;
        let q2 = Mlp::new(&qcfg, rng)?;
        Ok(Self {
            policy_opt: Adam::new(AdamConfig::with_lr(config.actor_lr), policy.net())?,
            q1_opt: Adam::new(AdamConfig::with_lr(config.critic_lr), &q1)?,
            q2_opt: Adam::new(AdamConfig::with_lr(config.critic_lr), &q2)?,
            q1_target: q1.clone(),
            q2_target: q2.clone(),
            q1,
            q2,
            log_alpha: config.init_alpha.ln(),
            alpha_opt: ScalarAdam {
                lr: config.alpha_lr as f64,
                m: 0.0,
                v: 0.0,
                t: 0,
            },
            replay: ReplayBuffer::new(config.buffer_size, o, a)?,
            env_steps: 0,
            config: config.clone(),
            policy,
        })
    }

    /// The settings.
    pub fn config(&self) -> &SacConfig {
        &self.config
    }

    /// The actor.
    pub fn policy(&self) -> &GaussianPolicy {
        &self.policy
    }

    /// Unwraps the actor.
    pub fn into_policy(self) -> GaussianPolicy {
        self.policy
    }

    /// The current temperature `alpha`.
    pub fn alpha(&self) -> f64 {
        self.log_alpha.exp()
    }

    /// The target entropy in use.
    pub fn target_entropy(&self) -> f64 {
        self.config
            .target_entropy
            .unwrap_or(-(self.policy.act_dim() as f64))
    }

    /// Transitions held in replay.
    pub fn replay_len(&self) -> usize {
        self.replay.len()
    }

    /// Environment steps seen by [`EpisodicLearner::run_episode`].
    pub fn env_steps(&self) -> u64 {
        self.env_steps
    }

    /// Fits the actor's squashed mean `tanh(mu(s))` to demonstration
    /// actions (clipped to `[-0.995, 0.995]`) by `steps` Adam steps (rate
    /// 1e-3) on minibatches of `batch` pairs; the log-std is left alone.
    /// Our addition: it carries a behaviour-cloning warm start fitted
    /// without the squash over to the squashed actor. Returns the last
    /// minibatch's mean squared error.
    ///
    /// # Errors
    /// Shape errors; [`Error::InvalidConfig`] for no pairs or `batch` 0.
    pub fn fit_squashed_mean<R: Rng + ?Sized>(
        &mut self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
        steps: usize,
        batch: usize,
        rng: &mut R,
    ) -> Result<f64> {
        let m = states.nrows();
        if m == 0 || batch == 0 || actions.nrows() != m {
            return Err(Error::InvalidConfig {
                field: "demonstration pairs".into(),
                reason: format!(
                    "need pairs and a batch, got {m} states, {} actions and batch {batch}",
                    actions.nrows()
                ),
            });
        }
        let mut opt = Adam::new(AdamConfig::with_lr(1e-3), self.policy.net())?;
        let mut loss = 0.0;
        for _ in 0..steps {
            let idx: Vec<usize> = (0..batch).map(|_| rng.random_range(0..m)).collect();
            let s = states.select(Axis(0), &idx);
            let a = actions.select(Axis(0), &idx);
            let x = self.policy.prepare_obs(s.view())?;
            let mut tape = Tape::new();
            let dist = self.policy.distribution_tape(x.view(), &mut tape)?;
            let k = a.ncols();
            let mut d_mean = Array2::zeros(dist.mean.raw_dim());
            loss = 0.0;
            for i in 0..batch {
                for j in 0..k {
                    let t = dist.mean[[i, j]].tanh();
                    let d = t - a[[i, j]].clamp(-0.995, 0.995);
                    loss += d * d / (batch * k) as f64;
                    d_mean[[i, j]] = 2.0 * d * (1.0 - t * t) / (batch * k) as f64;
                }
            }
            let d_ls = Array2::<f64>::zeros(d_mean.raw_dim());
            let mut grads = self.policy.net().zero_grads();
            self.policy
                .backward_params(&tape, &dist, d_mean.view(), d_ls.view(), &mut grads);
            opt.step(self.policy.net_mut(), &grads)?;
        }
        Ok(loss)
    }

    /// Samples an action in `(-1, 1)` for one raw observation.
    ///
    /// # Errors
    /// Shape or non-finite observation errors.
    pub fn act<R: Rng + ?Sized>(&self, obs: &[f64], rng: &mut R) -> Result<Vec<f64>> {
        let mut a = vec![0.0; self.policy.act_dim()];
        self.policy
            .act_into(obs, Some(rng), &mut PolicyWorkspace::default(), &mut a)?;
        Ok(a)
    }

    /// Stores a transition.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] for wrong lengths.
    pub fn push(
        &mut self,
        state: &[f64],
        action: &[f64],
        reward: f64,
        next_state: &[f64],
        terminated: bool,
    ) -> Result<()> {
        self.replay
            .push(state, action, reward, next_state, terminated)
    }

    /// Adds `delta` to the stored reward of the most recent transition (the
    /// terminal reward heuristic at an episode's end).
    pub fn adjust_last_reward(&mut self, delta: f64) {
        self.replay.adjust_last_reward(delta);
    }

    /// Draws `n` transitions uniformly with replacement.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] if the replay is empty or `n` is 0.
    pub fn sample<R: Rng + ?Sized>(&self, n: usize, rng: &mut R) -> Result<SacBatch> {
        self.replay.sample(n, rng)
    }

    fn clip(&self, grads: &mut red_nets::Gradients) {
        if let Some(c) = self.config.max_grad_norm {
            clip_grad_norm(grads, c);
        }
    }

    /// One step of both critics towards the soft Bellman target, then the
    /// target networks' Polyak step; returns the critics' mean loss.
    ///
    /// # Errors
    /// Shape errors.
    pub fn update_critics<R: Rng + ?Sized>(
        &mut self,
        batch: &SacBatch,
        rng: &mut R,
    ) -> Result<f64> {
        let n = batch.rewards.len();
        let x = self.policy.prepare_obs(batch.states.view())?;
        let xn = self.policy.prepare_obs(batch.next_states.view())?;
        let next = squashed_sample(
            self.policy
                .distribution(xn.view(), &mut red_nets::Workspace::new())?,
            rng,
        );
        let qin_n = q_input(xn.view(), next.actions.view());
        let (t1, t2) = (
            self.q1_target.predict(qin_n.view()),
            self.q2_target.predict(qin_n.view()),
        );
        let alpha = self.alpha();
        let mut y = Array2::<f32>::zeros((n, 1));
        for i in 0..n {
            let soft = (t1[[i, 0]].min(t2[[i, 0]]) as f64) - alpha * next.logp[i];
            let cont = if batch.terminated[i] { 0.0 } else { 1.0 };
            y[[i, 0]] = (self.config.reward_scale * batch.rewards[i]
                + self.config.gamma * cont * soft) as f32;
        }
        let qin = q_input(x.view(), batch.actions.view());
        let mut total = 0.0;
        for k in 0..2 {
            let (net, opt) = if k == 0 {
                (&mut self.q1, &mut self.q1_opt)
            } else {
                (&mut self.q2, &mut self.q2_opt)
            };
            let mut tape = Tape::new();
            let pred = net.forward_tape(qin.view(), &mut tape);
            let (loss, g) = mse_loss(pred, y.view());
            let mut grads = net.zero_grads();
            net.backward_params(&tape, g.view(), &mut grads);
            if let Some(c) = self.config.max_grad_norm {
                clip_grad_norm(&mut grads, c);
            }
            opt.step(net, &grads)?;
            total += loss as f64 / 2.0;
        }
        let tau = self.config.tau as f32;
        self.q1_target.polyak_toward(&self.q1, tau)?;
        self.q2_target.polyak_toward(&self.q2, tau)?;
        Ok(total)
    }

    /// One actor step on the states of `batch` with fresh reparameterised
    /// samples, then (with `auto_alpha`) one temperature step. Returns
    /// `(actor loss, mean entropy estimate)`.
    ///
    /// # Errors
    /// Shape errors, [`Error::NonFinite`].
    pub fn update_actor<R: Rng + ?Sized>(
        &mut self,
        batch: &SacBatch,
        rng: &mut R,
    ) -> Result<(f64, f64)> {
        let n = batch.rewards.len();
        let o = self.policy.obs_dim();
        let x = self.policy.prepare_obs(batch.states.view())?;
        let mut ptape = Tape::new();
        let smp = squashed_sample(self.policy.distribution_tape(x.view(), &mut ptape)?, rng);
        let qin = q_input(x.view(), smp.actions.view());
        let mut tapes = [Tape::new(), Tape::new()];
        let [tape1, tape2] = &mut tapes;
        let v1 = self.q1.forward_tape(qin.view(), tape1).to_owned();
        let v2 = self.q2.forward_tape(qin.view(), tape2).to_owned();
        let mut g1 = Array2::<f32>::zeros((n, 1));
        let mut g2 = Array2::<f32>::zeros((n, 1));
        let alpha = self.alpha();
        let mut loss = 0.0;
        for i in 0..n {
            let (q, g) = if v1[[i, 0]] <= v2[[i, 0]] {
                (v1[[i, 0]], &mut g1)
            } else {
                (v2[[i, 0]], &mut g2)
            };
            g[[i, 0]] = 1.0;
            loss += (alpha * smp.logp[i] - q as f64) / n as f64;
        }
        let mut scratch1 = self.q1.zero_grads();
        let mut scratch2 = self.q2.zero_grads();
        let d1 = self.q1.backward(&tapes[0], g1.view(), &mut scratch1);
        let d2 = self.q2.backward(&tapes[1], g2.view(), &mut scratch2);
        let dq = (&d1.slice(s![.., o..]) + &d2.slice(s![.., o..])).mapv(|v| v as f64);
        let k = smp.actions.ncols();
        let mut d_mean = Array2::zeros((n, k));
        let mut d_ls = Array2::zeros((n, k));
        for i in 0..n {
            for j in 0..k {
                let a = smp.actions[[i, j]];
                let da_du = 1.0 - a * a;
                let dlogp_du = 2.0 * a * da_du / (da_du + SQUASH_EPS);
                let du = (alpha * dlogp_du - dq[[i, j]] * da_du) / n as f64;
                d_mean[[i, j]] = du;
                d_ls[[i, j]] =
                    -alpha / n as f64 + du * smp.dist.log_std[[i, j]].exp() * smp.eps[[i, j]];
            }
        }
        let mut grads = self.policy.net().zero_grads();
        self.policy
            .backward_params(&ptape, &smp.dist, d_mean.view(), d_ls.view(), &mut grads);
        if !grads.is_finite() || !loss.is_finite() {
            return Err(Error::NonFinite {
                what: "SAC actor gradient".into(),
                step: self.env_steps,
            });
        }
        self.clip(&mut grads);
        self.policy_opt.step(self.policy.net_mut(), &grads)?;
        let mean_logp = smp.logp.iter().sum::<f64>() / n as f64;
        if self.config.auto_alpha {
            let g = -(mean_logp + self.target_entropy());
            self.alpha_opt.step(&mut self.log_alpha, g);
        }
        Ok((loss, -mean_logp))
    }

    /// One gradient step (critics, actor, temperature) on a fresh
    /// minibatch; an adaptive reward is recomputed for it first.
    ///
    /// # Errors
    /// As the individual updates; the reward's errors.
    pub fn update<R: Rng + ?Sized>(
        &mut self,
        reward: &dyn DifferentiableReward,
        rng: &mut R,
    ) -> Result<SacStats> {
        self.update_with(Some(reward), rng)
    }

    /// [`Sac::update`] on the stored rewards as they are (`None`: the
    /// environment's, nothing recomputed).
    fn update_with<R: Rng + ?Sized>(
        &mut self,
        reward: Option<&dyn DifferentiableReward>,
        rng: &mut R,
    ) -> Result<SacStats> {
        let mut b = self.sample(self.config.batch_size, rng)?;
        if let Some(reward) = reward
            && reward.is_adaptive()
        {
            let (r, _) = reward.reward_and_grad(b.states.view(), b.actions.view())?;
            b.set_rewards(&r.to_vec())?;
        }
        let critic_loss = self.update_critics(&b, rng)?;
        if !critic_loss.is_finite() {
            return Err(Error::NonFinite {
                what: "SAC critic loss".into(),
                step: self.env_steps,
            });
        }
        let (actor_loss, entropy) = self.update_actor(&b, rng)?;
        Ok(SacStats {
            critic_loss,
            actor_loss,
            entropy,
            alpha: self.alpha(),
        })
    }

    /// Runs one episode on the environment's own reward (training an
    /// expert): the transitions store `step.reward`, no terminal
    /// adjustment; otherwise as [`EpisodicLearner::run_episode`] (actions of
    /// the stochastic actor, or uniform ones during the first
    /// `random_steps`; updates after `learning_starts`).
    ///
    /// # Errors
    /// As [`EpisodicLearner::run_episode`].
    pub fn run_env_episode<E: Env + ?Sized, R: Rng + ?Sized>(
        &mut self,
        env: &mut E,
        reset_seed: Option<u64>,
        max_steps: u64,
        rng: &mut R,
    ) -> Result<EpisodeOutcome> {
        self.episode(env, None, reset_seed, &|_, _| 0.0, max_steps, rng)
    }

    /// One episode; `reward` `None` stores the environment's reward.
    fn episode<E: Env + ?Sized, R: Rng + ?Sized>(
        &mut self,
        env: &mut E,
        reward: Option<&dyn DifferentiableReward>,
        reset_seed: Option<u64>,
        terminal: &dyn Fn(f64, &Info) -> f64,
        max_steps: u64,
        rng: &mut R,
    ) -> Result<EpisodeOutcome> {
        self.check_spaces(env)?;
        let seed = reset_seed.unwrap_or_else(|| rng.random());
        let (mut obs, _) = env.reset(Some(seed))?;
        self.check_observation(&obs)?;
        let mut log = EpisodeLog::new(self.policy.obs_dim(), self.policy.act_dim());
        let mut ws = PolicyWorkspace::default();
        let mut a = vec![0.0; self.policy.act_dim()];
        while (log.length() as u64) < max_steps {
            if self.env_steps < self.config.random_steps {
                for v in a.iter_mut() {
                    *v = rng.random_range(-1.0..1.0);
                }
            } else {
                self.policy
                    .act_into(&obs, Some(&mut *rng), &mut ws, &mut a)?;
            }
            let step = env.step(&a)?;
            self.check_observation(&step.observation)?;
            let r = match reward {
                Some(m) => EpisodeLog::reward_of(m, &obs, &a, self.env_steps)?,
                None if step.reward.is_finite() => step.reward,
                None => {
                    return Err(Error::NonFinite {
                        what: "environment reward".into(),
                        step: self.env_steps,
                    });
                }
            };
            let ends = step.terminated || (self.config.end_at_truncation && step.truncated);
            self.push(&obs, &a, r, &step.observation, ends)?;
            log.record(&obs, &a, step.reward, r);
            self.env_steps += 1;
            if self.env_steps > self.config.learning_starts {
                for _ in 0..self.config.updates_per_step {
                    self.update_with(reward, rng)?;
                }
            }
            if step.terminated || step.truncated {
                let adj = terminal(r, &step.info);
                self.adjust_last_reward(adj);
                log.end(adj, step.info);
                break;
            }
            obs = step.observation;
        }
        log.into_outcome(self.env_steps)
    }

    fn check_observation(&self, obs: &[f64]) -> Result<()> {
        crate::episodic::check_observation(obs, self.env_steps)
    }

    fn check_spaces<E: Env + ?Sized>(&self, env: &E) -> Result<()> {
        let (o, a) = (self.policy.obs_dim(), self.policy.act_dim());
        crate::episodic::check_spaces("SAC", env, o, a)
    }
}

impl EpisodicLearner for Sac {
    fn env_steps(&self) -> u64 {
        self.env_steps
    }

    /// Runs one episode with the stochastic actor, at most `max_steps`
    /// environment steps, storing transitions with the imitation reward of
    /// `reward` (never the environment's) and updating after
    /// `learning_starts`. The episode starts with `env.reset(Some(seed))`,
    /// the seed `reset_seed` or one drawn from `rng`. At its end
    /// `terminal(final_reward, final_info)` is added to the last stored
    /// reward (RED's terminal heuristic; `|_, _| 0.0` for none). The same contract as
    /// [`Svg1`](crate::svg::Svg1)'s [`EpisodicLearner::run_episode`].
    ///
    /// # Errors
    /// Environment, shape and update errors; [`Error::NonFinite`] for a
    /// non-finite observation, reward, loss or gradient.
    fn run_episode<E: Env + ?Sized, R: Rng + ?Sized>(
        &mut self,
        env: &mut E,
        reward: &dyn DifferentiableReward,
        reset_seed: Option<u64>,
        terminal: &dyn Fn(f64, &Info) -> f64,
        max_steps: u64,
        rng: &mut R,
    ) -> Result<EpisodeOutcome> {
        self.episode(env, Some(reward), reset_seed, terminal, max_steps, rng)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::policy::GaussianPolicyConfig;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn config_rejects_nonsense() {
        assert!(SacConfig::default().validate().is_ok());
        let bad = SacConfig {
            tau: 0.0,
            ..SacConfig::default()
        };
        assert!(bad.validate().is_err());
        let bad = SacConfig {
            gamma: 1.0,
            ..SacConfig::default()
        };
        assert!(bad.validate().is_err());
        let s = r#"{"nope": 1}"#;
        assert!(serde_json::from_str::<SacConfig>(s).is_err());
    }

    #[test]
    fn unsquashed_policy_is_refused() {
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let p =
            GaussianPolicy::new(&GaussianPolicyConfig::default(), 3, 2, None, &mut rng).unwrap();
        assert!(Sac::new(&SacConfig::default(), p, &mut rng).is_err());
    }

    /// The actor gradient against central finite differences of the actor
    /// loss with the same noise (critics fixed, alpha fixed).
    #[test]
    fn actor_gradient_matches_finite_differences() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let pc = GaussianPolicyConfig {
            hidden: vec![8],
            init_log_std: -0.5,
            output_scale: 1.0,
            squash: true,
            ..GaussianPolicyConfig::default()
        };
        let p = GaussianPolicy::new(&pc, 3, 2, None, &mut rng).unwrap();
        let cfg = SacConfig {
            hidden: vec![8],
            activation: Activation::Tanh,
            init_alpha: 0.3,
            ..SacConfig::default()
        };
        let sac = Sac::new(&cfg, p, &mut rng).unwrap();
        let states =
            Array2::from_shape_fn((5, 3), |(i, j)| (i as f64 * 0.3 - j as f64 * 0.2).sin());
        let loss_of = |s: &Sac| {
            let x = s.policy.prepare_obs(states.view()).unwrap();
            let smp = squashed_sample(
                s.policy
                    .distribution(x.view(), &mut red_nets::Workspace::new())
                    .unwrap(),
                &mut ChaCha8Rng::seed_from_u64(9),
            );
            let qin = q_input(x.view(), smp.actions.view());
            let (v1, v2) = (s.q1.predict(qin.view()), s.q2.predict(qin.view()));
            (0..5)
                .map(|i| s.alpha() * smp.logp[i] - v1[[i, 0]].min(v2[[i, 0]]) as f64)
                .sum::<f64>()
                / 5.0
        };
        // Analytic gradient, with the same noise.
        let x = sac.policy.prepare_obs(states.view()).unwrap();
        let mut ptape = Tape::new();
        let dist = sac.policy.distribution_tape(x.view(), &mut ptape).unwrap();
        let smp = squashed_sample(dist, &mut ChaCha8Rng::seed_from_u64(9));
        let qin = q_input(x.view(), smp.actions.view());
        let (mut t1, mut t2) = (Tape::new(), Tape::new());
        let v1 = sac.q1.forward_tape(qin.view(), &mut t1).to_owned();
        let v2 = sac.q2.forward_tape(qin.view(), &mut t2).to_owned();
        let (mut g1, mut g2) = (Array2::<f32>::zeros((5, 1)), Array2::<f32>::zeros((5, 1)));
        for i in 0..5 {
            if v1[[i, 0]] <= v2[[i, 0]] {
                g1[[i, 0]] = 1.0;
            } else {
                g2[[i, 0]] = 1.0;
            }
        }
        let d1 = sac.q1.backward(&t1, g1.view(), &mut sac.q1.zero_grads());
        let d2 = sac.q2.backward(&t2, g2.view(), &mut sac.q2.zero_grads());
        let dq = (&d1.slice(s![.., 3..]) + &d2.slice(s![.., 3..])).mapv(|v| v as f64);
        let alpha = sac.alpha();
        let (mut dm, mut dl) = (Array2::zeros((5, 2)), Array2::zeros((5, 2)));
        for i in 0..5 {
            for j in 0..2 {
                let a = smp.actions[[i, j]];
                let da = 1.0 - a * a;
                let du = (alpha * 2.0 * a * da / (da + SQUASH_EPS) - dq[[i, j]] * da) / 5.0;
                dm[[i, j]] = du;
                dl[[i, j]] = -alpha / 5.0 + du * smp.dist.log_std[[i, j]].exp() * smp.eps[[i, j]];
            }
        }
        let mut grads = sac.policy.net().zero_grads();
        sac.policy
            .backward_params(&ptape, &smp.dist, dm.view(), dl.view(), &mut grads);
        let analytic = grads.flat();
        let p0 = sac.policy.net().params_flat();
        let mut probe = sac.clone();
        let h = 1e-2_f32;
        let mut checked = 0;
        for k in (0..p0.len()).step_by(7) {
            let mut p = p0.clone();
            p[k] += h;
            probe.policy.net_mut().set_params_flat(&p).unwrap();
            let up = loss_of(&probe);
            p[k] -= 2.0 * h;
            probe.policy.net_mut().set_params_flat(&p).unwrap();
            let down = loss_of(&probe);
            let fd = (up - down) / (2.0 * h as f64);
            let an = analytic[k] as f64;
            assert!(
                (fd - an).abs() <= 2e-3 + 2e-2 * an.abs().max(fd.abs()),
                "param {k}: finite differences {fd}, analytic {an}"
            );
            checked += 1;
        }
        assert!(checked > 5);
    }
}
