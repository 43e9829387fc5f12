//! SVG(1) with experience replay (Heess et al. 2015, "Learning Continuous
//! Control Policies by Stochastic Value Gradients", Algorithm 2, SVG(1)-ER).
//!
//! Three learned pieces, all updated from a replay buffer:
//!
//! - a one-step dynamics model `x' = x + f(x, a)` (an MLP predicting the
//!   change of the policy's prepared observation `x`), fitted by mean squared
//!   error on replayed transitions;
//! - a state-value function `V(x)` fitted by TD(0) with a Polyak-averaged
//!   target network, each transition weighted by its truncated importance
//!   weight;
//! - a reparameterised Gaussian policy `a = mu(x) + sigma(x) * eta`
//!   ([`GaussianPolicy`]), moved along the gradient of
//!   `w * [r(s, a) + gamma * V(x')]`.
//!
//! The policy step follows SVG(1)-ER's noise inference: for a replayed
//! transition `(s, a, s')` the policy noise is inferred as
//! `eta = (a - mu(x)) / sigma(x)` and the model noise as
//! `xi = x'_observed - x - f(x, a)`, both held fixed, so the objective
//! `r(s, mu + sigma eta) + gamma V(x + f(x, mu + sigma eta) + xi)` equals the
//! observed outcome at the current parameters and its gradient flows through
//! the reward's action-gradient, the model's action-Jacobian and the
//! reparameterisation. Each term is weighted by the importance weight
//! `w = min(pi(a|s) / mu_b(a|s), iw_clip)` of the current policy against the
//! behaviour policy that chose the action (the log-probability is stored at
//! acting time), treated as a constant, as in Heess et al.
//!
//! The reward and its action-gradient come from a [`DifferentiableReward`],
//! implemented for RED's `red_support::RedReward`, GAIL and GMMIL.

use ndarray::{Array2, ArrayView2, Axis, concatenate, s};
use rand::{Rng, RngExt};
use serde::{Deserialize, Serialize};

use red_core::{Env, Info};
use red_nets::{
    Activation, Adam, AdamConfig, Gradients, Init, Mlp, MlpConfig, Optimizer, Tape, Workspace,
    clip_grad_norm, mse_loss,
};

use crate::episodic::{EpisodeLog, EpisodicLearner, one_row};
pub use crate::episodic::{EpisodeOutcome, EpisodeReport};
use crate::policy::{GaussianPolicy, PolicyWorkspace};
use crate::replay::{Batch, NStepTail, ReplayBuffer};
use crate::{Error, Result};

// The trait lives beside `RewardModel` in red-core; re-exported here where
// SVG(1) users have always found it.
pub use red_core::DifferentiableReward;

/// The noise of the spatial smoothness term by default.
fn default_spatial_smooth_std() -> f64 {
    0.1
}

/// Whether `spatial_smooth_std` is the default (then not written, so that
/// files of runs without the term read in builds before it).
fn is_default_spatial_smooth_std(v: &f64) -> bool {
    *v == default_spatial_smooth_std()
}

/// Whether a weight is 0 (a setting that is off is not written).
fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// `eta_scale`'s default: SVG(1)-ER's policy step.
fn default_eta_scale() -> f64 {
    1.0
}

/// Whether `eta_scale` is the default (then not written, so that files of
/// runs without it read in builds before it).
fn is_default_eta_scale(v: &f64) -> bool {
    *v == default_eta_scale()
}

/// Settings of [`Svg1`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SvgConfig {
    /// Hidden widths of the dynamics model and of the value function. Our
    /// choice: `[100, 100]`, the width of the release's policy.
    pub hidden: Vec<usize>,
    /// Discount. Our choice: 0.99 (the RED paper does not state SVG's).
    pub gamma: f64,
    /// Adam learning rate of the policy. Our choice: 1e-4, small because
    /// the policy is usually warm-started by behaviour cloning.
    pub policy_lr: f32,
    /// Adam learning rate of the value function. Our choice: 1e-3.
    pub value_lr: f32,
    /// Adam learning rate of the dynamics model. Our choice: 1e-3.
    pub model_lr: f32,
    /// Minibatch size of every update. Our choice: 64.
    pub batch_size: usize,
    /// Replay capacity in transitions. Our choice: 100,000.
    pub buffer_size: usize,
    /// Environment steps before any update. Our choice: 500.
    pub learning_starts: u64,
    /// Gradient updates (model, value and policy once each) per environment
    /// step after `learning_starts`. Our choice: 1.
    pub updates_per_step: usize,
    /// Policy updates are skipped for this many environment steps after
    /// `learning_starts`, while the model and value settle. Our choice: 500.
    pub policy_delay: u64,
    /// Truncation of the importance weights `pi / mu_b` (Heess et al.
    /// truncate them; the value is our choice: 5).
    pub iw_clip: f64,
    /// Polyak factor of the value target network per update. Our choice:
    /// 0.01.
    pub target_tau: f64,
    /// Gradient-norm clip of every network. Our choice: 10.
    pub max_grad_norm: f32,
    /// When set, the policy's standard deviation is this fixed value for
    /// acting, importance weights and the policy step (the policy's own
    /// log-std head is ignored and not trained). Default: none (the learned,
    /// state-dependent log-std).
    pub fixed_std: Option<f64>,
    /// With `fixed_std`: the standard deviation reached (linearly) at
    /// environment step `schedule_steps`. Default: none (constant).
    pub fixed_std_final: Option<f64>,
    /// The policy learning rate reached (linearly from `policy_lr`, starting
    /// when policy updates start) at environment step `schedule_steps`.
    /// Default: none (constant).
    pub policy_lr_final: Option<f32>,
    /// Environment step at which the schedules above end. 0: no schedule.
    pub schedule_steps: u64,
    /// Polyak factor of an averaged copy of the policy's parameters, moved
    /// after every policy update (0: no averaged copy, unless
    /// `policy_avg_uniform_from` asks for one). The averaged policy is what
    /// [`Svg1::reported_policy`] returns.
    pub policy_avg_tau: f64,
    /// From this environment step on, the averaged copy is the plain mean
    /// of the policies after each policy update since then (Polyak-Ruppert
    /// averaging; stochastic weight averaging, Izmailov et al. 2018) instead
    /// of the exponential average of `policy_avg_tau`, which it replaces
    /// from that step (before it, `policy_avg_tau` applies when > 0). Our
    /// addition. Measured on the driving task only (RED, four demos, seeds
    /// 0-4, docs/results/drive.md): from step 40,000 of 80,000, +2.3 points
    /// of the demo's road and -6.2 of unseen roads; from 60,000, -1.8 and
    /// +0.1, against the exponential average of `policy_avg_tau` 1e-4.
    /// `None`: off.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub policy_avg_uniform_from: Option<u64>,
    /// Whether value and policy updates weight replayed transitions by the
    /// truncated importance weight (SVG(1)-ER as in Heess et al.: true).
    pub importance_weights: bool,
    /// Weight of a behaviour-cloning term `bc_weight * mean ||mu(s_d) -
    /// a_d||^2` on demonstration pairs (set with [`Svg1::set_demos`]) added
    /// to the policy loss: our addition, not Heess et al.'s nor the RED
    /// paper's. 0: off.
    pub bc_weight: f64,
    /// With `fixed_std`: the exploration noise of the behaviour policy is
    /// an AR(1) process `eps_t = rho eps_(t-1) + sqrt(1 - rho^2) sigma z_t`
    /// (stationary std `sigma`, reset each episode), so steering
    /// excursions last several steps; the behaviour log-probability stored
    /// is the conditional one, so the importance weights correct for it.
    /// 0: white noise.
    pub noise_rho: f64,
    /// Weight of a temporal smoothness term (our addition, after Mysore et
    /// al. 2021, "Regularizing Action Policies for Smooth Control with
    /// Reinforcement Learning"): `smooth_weight * mean ||mu(s) - mu(s')||^2`
    /// over the policy batch's replayed transitions `(s, s')`, added to
    /// the policy loss. Transitions into a terminal state count in the mean
    /// as 0; those cut by a time limit count, `s'` being the last
    /// observation. It charges a policy whose mean action jumps between
    /// consecutive states, as one that chatters does. 0: off (and not
    /// written, so files of runs without it read in builds before it).
    #[serde(skip_serializing_if = "is_zero")]
    pub smooth_weight: f64,
    /// Weight of a spatial smoothness term (our addition, the other term
    /// of Mysore et al. 2021): `spatial_smooth_weight * mean ||mu(x) -
    /// mu(x + eps)||^2` over the policy batch's states `x` (as the policy
    /// reads them, after its input normaliser), `eps` drawn from a normal
    /// of standard deviation `spatial_smooth_std` per input. It charges a
    /// policy whose mean action moves much between nearby states. Applied
    /// by [`Svg1::update`], which draws the noise, not by the lower-level
    /// [`Svg1::update_policy`]. 0: off (no number is drawn, and not
    /// written).
    #[serde(skip_serializing_if = "is_zero")]
    pub spatial_smooth_weight: f64,
    /// The noise of `spatial_smooth_weight`, in the policy's normalised
    /// input units (standard deviations of the demonstration's states
    /// when the policy has a normaliser).
    #[serde(
        default = "default_spatial_smooth_std",
        skip_serializing_if = "is_default_spatial_smooth_std"
    )]
    pub spatial_smooth_std: f64,
    /// Weight of a self-imitation term (our addition, after Oh et al.
    /// 2018, "Self-Imitation Learning"): the learner keeps its
    /// `sil_episodes` training episodes of highest own return (the
    /// learning reward plus the terminal adjustment, never a true reward)
    /// and adds `sil_weight * mean m_i ||mu(s_i) - a_i||^2` on pairs drawn
    /// from them, where `m_i` is 1 when the pair's discounted own return
    /// from there on exceeds the value function's estimate `V(s_i)` and 0
    /// otherwise (so the steps into a crash are not imitated). 0: off (no
    /// random number is drawn for it).
    pub sil_weight: f64,
    /// Episodes kept for `sil_weight`.
    pub sil_episodes: usize,
    /// Steps of the value function's target (our addition; Heess et al.
    /// fit `V` by TD(0), which is 1): with `n > 1` the target is the
    /// stored rewards of up to `n` consecutive steps of the same episode
    /// and then `gamma^n V_target` (see
    /// [`ReplayBuffer::sample_with_tail`]), so a crash's penalty reaches
    /// the states `n` steps before it in one update. The later steps are
    /// not importance-corrected and their rewards are the stored ones (for
    /// an adaptive reward, as it was when stored). Measured on the driving
    /// task only (RED, four demos, docs/results/drive.md, session 41): 10
    /// steps at the discount 0.98 drove +0.1 points of the demo's road
    /// (s.e. 3.6) and +2.7 of unseen roads (3.5) against the discount 0.98
    /// with TD(0), over seeds 0-9, and more of its final policies stop on
    /// the road; 10 steps at 0.95 lost 16 points on one demo. With a
    /// training-time end for a stopped car, 10 steps at 0.98 became the
    /// driving default in session 42 (+9.1 points of unseen roads). Always
    /// written, so a saved config given back (for example the `train`
    /// object of a driving run's config.json through `--train-config`,
    /// which is laid over the driving defaults) keeps its value; a file
    /// without it reads as 1.
    pub value_nstep: usize,
    /// Scale of the inferred policy noise in the policy step (our
    /// addition). SVG(1)-ER (1) takes the objective's gradient at the
    /// replayed action `mu + sigma eta`, so the policy ascends the action
    /// value smoothed by the exploration noise. 0 takes it at the current
    /// policy's mean `mu` (the inferred model noise and the importance
    /// weights of the replayed action are kept, as they are for any `mu`
    /// that has moved since the step was stored); values between scale
    /// `eta`. With a learned std (no `fixed_std`) the objective's pull on
    /// `sigma` scales with it too, and at 0 there is none. Must lie in
    /// [0, 1]. Not written at 1.
    #[serde(skip_serializing_if = "is_default_eta_scale")]
    pub eta_scale: f64,
    /// A second value function (our addition, after the clipped double
    /// estimate of Fujimoto et al. 2018, TD3): two value networks, each
    /// with its target, learn from the same targets, and wherever the
    /// learner reads a value (the bootstrap of the targets, the policy
    /// step's `V(x')`, the self-imitation mask) it takes the smaller of
    /// the two, so a value that one network overrates where data is thin
    /// is not climbed. The policy step's gradient flows through the
    /// smaller network, row by row. Off by default (one network, as in
    /// Heess et al.; no random number is drawn for the second). Not
    /// written when off.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub twin_value: bool,
}

impl Default for SvgConfig {
    fn default() -> Self {
        Self {
            hidden: vec![100, 100],
            gamma: 0.99,
            policy_lr: 1e-4,
            value_lr: 1e-3,
            model_lr: 1e-3,
            batch_size: 64,
            buffer_size: 100_000,
            learning_starts: 500,
            updates_per_step: 1,
            policy_delay: 500,
            iw_clip: 5.0,
            target_tau: 0.01,
            max_grad_norm: 10.0,
            fixed_std: None,
            fixed_std_final: None,
            policy_lr_final: None,
            schedule_steps: 0,
            policy_avg_tau: 0.0,
            policy_avg_uniform_from: None,
            importance_weights: true,
            bc_weight: 0.0,
            noise_rho: 0.0,
            smooth_weight: 0.0,
            spatial_smooth_weight: 0.0,
            spatial_smooth_std: default_spatial_smooth_std(),
            sil_weight: 0.0,
            sil_episodes: 4,
            value_nstep: 1,
            eta_scale: default_eta_scale(),
            twin_value: false,
        }
    }
}

impl SvgConfig {
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
        for (f, v) in [
            ("policy_lr", self.policy_lr),
            ("value_lr", self.value_lr),
            ("model_lr", self.model_lr),
            ("max_grad_norm", self.max_grad_norm),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(f, format!("must be finite and > 0, got {v}"));
            }
        }
        for (f, v) in [
            ("batch_size", self.batch_size),
            ("buffer_size", self.buffer_size),
            ("updates_per_step", self.updates_per_step),
            ("value_nstep", self.value_nstep),
        ] {
            if v == 0 {
                return bad(f, "must be at least 1".into());
            }
        }
        if !(0.0..=1.0).contains(&self.eta_scale) {
            return bad(
                "eta_scale",
                format!("must lie in [0, 1], got {}", self.eta_scale),
            );
        }
        if !(self.iw_clip.is_finite() && self.iw_clip >= 1.0) {
            return bad(
                "iw_clip",
                format!("must be finite and >= 1, got {}", self.iw_clip),
            );
        }
        for (f, v) in [
            ("fixed_std", self.fixed_std),
            ("fixed_std_final", self.fixed_std_final),
        ] {
            if let Some(v) = v
                && !(v.is_finite() && v > 0.0)
            {
                return bad(f, format!("must be finite and > 0, got {v}"));
            }
        }
        if let Some(v) = self.policy_lr_final
            && !(v.is_finite() && v > 0.0)
        {
            return bad(
                "policy_lr_final",
                format!("must be finite and > 0, got {v}"),
            );
        }
        if !(0.0..1.0).contains(&self.noise_rho) {
            return bad(
                "noise_rho",
                format!("must lie in [0, 1), got {}", self.noise_rho),
            );
        }
        if !(0.0..=1.0).contains(&self.policy_avg_tau) {
            return bad(
                "policy_avg_tau",
                format!("must lie in [0, 1], got {}", self.policy_avg_tau),
            );
        }
        if !(self.bc_weight.is_finite() && self.bc_weight >= 0.0) {
            return bad(
                "bc_weight",
                format!("must be finite and >= 0, got {}", self.bc_weight),
            );
        }
        for (field, v) in [
            ("spatial_smooth_weight", self.spatial_smooth_weight),
            ("spatial_smooth_std", self.spatial_smooth_std),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::InvalidConfig {
                    field: field.into(),
                    reason: format!("must be finite and >= 0, got {v}"),
                });
            }
        }
        if !(self.smooth_weight.is_finite() && self.smooth_weight >= 0.0) {
            return bad(
                "smooth_weight",
                format!("must be finite and >= 0, got {}", self.smooth_weight),
            );
        }
        if !(self.sil_weight.is_finite() && self.sil_weight >= 0.0) {
            return bad(
                "sil_weight",
                format!("must be finite and >= 0, got {}", self.sil_weight),
            );
        }
        if self.sil_weight > 0.0 && self.sil_episodes == 0 {
            return bad(
                "sil_episodes",
                "must be at least 1 when sil_weight > 0".into(),
            );
        }
        if !(self.target_tau > 0.0 && self.target_tau <= 1.0) {
            return bad(
                "target_tau",
                format!("must lie in (0, 1], got {}", self.target_tau),
            );
        }
        Ok(())
    }
}

/// A minibatch for the SVG(1) updates: the replay buffer's [`Batch`], with
/// the behaviour log-probabilities filled.
pub type SvgBatch = Batch;

/// The quantities held fixed in a policy step: the inferred policy noise
/// `eta`, model noise `xi` and the truncated importance weights, computed at
/// the current parameters by [`Svg1::policy_inputs`].
#[derive(Debug, Clone, PartialEq)]
pub struct PolicyInputs {
    /// Inferred policy noise `(b, act_dim)`, times `eta_scale`.
    pub eta: Array2<f64>,
    /// Inferred model noise `(b, obs_dim)`, in prepared-observation units.
    pub xi: Array2<f64>,
    /// Truncated importance weights.
    pub weights: Vec<f64>,
}

/// Losses of one update.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct UpdateStats {
    /// Model mean squared error.
    pub model_loss: f64,
    /// Value TD mean squared error.
    pub value_loss: f64,
    /// Policy objective (mean weighted one-step value), when updated.
    pub policy_objective: Option<f64>,
}

/// An SVG(1)-ER learner; see the module documentation. It serialises
/// whole (networks, optimiser moments, replay, step count), so a run can be
/// checkpointed between episodes and resumed exactly.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Svg1 {
    config: SvgConfig,
    policy: GaussianPolicy,
    model: Mlp,
    value: Mlp,
    value_target: Mlp,
    policy_opt: Adam,
    model_opt: Adam,
    value_opt: Adam,
    replay: ReplayBuffer,
    env_steps: u64,
    /// Averaged policy (when `policy_avg_tau > 0` or
    /// `policy_avg_uniform_from` is set).
    #[serde(default)]
    avg_policy: Option<GaussianPolicy>,
    /// Policy updates averaged uniformly so far (`policy_avg_uniform_from`).
    #[serde(default)]
    avg_count: u64,
    /// Demonstration pairs for `bc_weight`.
    #[serde(default)]
    demos: Option<(Array2<f64>, Array2<f64>)>,
    /// The kept episodes of `sil_weight`, highest own return first.
    #[serde(default)]
    sil: Vec<SilEpisode>,
    /// The second value function of `twin_value`: network, target and
    /// optimiser.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    twin: Option<TwinValue>,
}

/// The second value network of `SvgConfig::twin_value`.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct TwinValue {
    value: Mlp,
    target: Mlp,
    opt: Adam,
}

/// One importance-weighted squared-error step of a value network `value`
/// toward `targets` on prepared observations `x`, then the Polyak move of
/// its `target` by `tau`; returns the weighted loss.
#[allow(clippy::too_many_arguments)]
fn td_step(
    value: &mut Mlp,
    target: &mut Mlp,
    opt: &mut Adam,
    x: ArrayView2<'_, f32>,
    targets: &[f64],
    weights: &[f64],
    max_grad_norm: f32,
    tau: f32,
) -> Result<f64> {
    let n = targets.len();
    let mut tape = Tape::new();
    let v = value.forward_tape(x, &mut tape).to_owned();
    let mut g = Array2::<f32>::zeros((n, 1));
    let mut loss = 0.0;
    for i in 0..n {
        let d = v[[i, 0]] as f64 - targets[i];
        loss += weights[i] * d * d / n as f64;
        g[[i, 0]] = (2.0 * weights[i] * d / n as f64) as f32;
    }
    let mut grads = value.zero_grads();
    value.backward_params(&tape, g.view(), &mut grads);
    clip_grad_norm(&mut grads, max_grad_norm);
    opt.step(value, &grads)?;
    target.polyak_toward(value, tau)?;
    Ok(loss)
}

/// A fresh value network on `o` prepared inputs (`config.hidden`, tanh,
/// Glorot-uniform).
fn value_net<R: Rng + ?Sized>(o: usize, config: &SvgConfig, rng: &mut R) -> Result<Mlp> {
    Ok(Mlp::new(
        &MlpConfig::new(o, &config.hidden, 1)
            .with_activation(Activation::Tanh)
            .with_init(Init::GlorotUniform),
        rng,
    )?)
}

/// The row-wise smaller of two `(n, 1)` value predictions.
fn min_values(a: Array2<f32>, b: &Array2<f32>) -> Array2<f32> {
    let mut a = a;
    a.zip_mut_with(b, |x, &y| *x = x.min(y));
    a
}

/// Pairs of the self-imitation term: states, actions and a 0/1 mask per
/// row.
type SilBatch = (Array2<f64>, Array2<f64>, Vec<f64>);

/// A training episode kept for the self-imitation term.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct SilEpisode {
    /// Sum of the learning rewards plus the terminal adjustment.
    own_return: f64,
    /// `(length, obs_dim)`.
    states: Array2<f64>,
    /// `(length, act_dim)`.
    actions: Array2<f64>,
    /// Discounted own return from each step on.
    returns: Vec<f64>,
}

impl Svg1 {
    /// A learner improving `policy`, with fresh model and value networks
    /// initialised from `rng`.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] for a bad config.
    pub fn new<R: Rng + ?Sized>(
        config: &SvgConfig,
        policy: GaussianPolicy,
        rng: &mut R,
    ) -> Result<Self> {
        config.validate()?;
        if policy.config().squash {
            return Err(Error::InvalidConfig {
                field: "policy.squash".into(),
                reason: "SVG(1)-ER needs an unsquashed Gaussian policy".into(),
            });
        }
        let (o, a) = (policy.obs_dim(), policy.act_dim());
        let model = Mlp::new(
            &MlpConfig::new(o + a, &config.hidden, o)
                .with_activation(Activation::Tanh)
                .with_init(Init::GlorotUniform),
            rng,
        )?;
        let value = value_net(o, config, rng)?;
        let policy_opt = Adam::new(AdamConfig::with_lr(config.policy_lr), policy.net())?;
        let model_opt = Adam::new(AdamConfig::with_lr(config.model_lr), &model)?;
        let value_opt = Adam::new(AdamConfig::with_lr(config.value_lr), &value)?;
        let avg_policy = (config.policy_avg_tau > 0.0 || config.policy_avg_uniform_from.is_some())
            .then(|| policy.clone());
        let twin = if config.twin_value {
            let value = value_net(o, config, rng)?;
            let opt = Adam::new(AdamConfig::with_lr(config.value_lr), &value)?;
            Some(TwinValue {
                target: value.clone(),
                value,
                opt,
            })
        } else {
            None
        };
        Ok(Self {
            twin,
            avg_count: 0,
            demos: None,
            sil: Vec::new(),
            avg_policy,
            config: config.clone(),
            policy,
            value_target: value.clone(),
            model,
            value,
            policy_opt,
            model_opt,
            value_opt,
            replay: ReplayBuffer::new(config.buffer_size, o, a)?.with_behaviour_logp(),
            env_steps: 0,
        })
    }

    /// Lookahead through the learned model and value: for each row
    /// `(s, a)`, `r(s, a) + gamma^horizon V(x_horizon)` where `x_1 = x +
    /// f(x, a)` and, for `horizon > 1`, `policy`'s mean action drives the
    /// model on (`x_{k+1} = x_k + f(x_k, mu(x_k))`; the rewards of those
    /// later steps are not counted, as the reward reads raw states and the
    /// model predicts prepared ones). Without `reward` the reward term is
    /// left out. Terminal states are not predicted (the value is read as if
    /// the episode went on). At horizon 1 with a reward this is the
    /// quantity the policy step ascends for a non-terminal transition, at
    /// zero model and policy noise and unit importance weight.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] for horizon 0; shape errors, the reward's
    /// errors.
    pub fn lookahead_scores(
        &self,
        policy: &GaussianPolicy,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
        reward: Option<&dyn DifferentiableReward>,
        horizon: usize,
    ) -> Result<Vec<f64>> {
        if horizon == 0 {
            return Err(Error::InvalidConfig {
                field: "horizon".into(),
                reason: "must be at least 1 model step".into(),
            });
        }
        let x = self.policy.prepare_obs(states)?;
        let input = Self::model_input(x.view(), actions);
        let mut xn = &x + &self.model.predict(input.view());
        let mut ws = Workspace::new();
        for _ in 1..horizon {
            let mu = policy.distribution(xn.view(), &mut ws)?.mean;
            let input = Self::model_input(xn.view(), mu.view());
            xn = &xn + &self.model.predict(input.view());
        }
        let v = self.value_estimate(xn.view());
        let discount = self.config.gamma.powi(horizon as i32);
        let r = match reward {
            Some(rw) => rw.reward_and_grad(states, actions)?.0.to_vec(),
            None => vec![0.0; states.nrows()],
        };
        Ok(r.iter()
            .zip(v.column(0))
            .map(|(r, v)| r + discount * *v as f64)
            .collect())
    }

    /// The learner without its replay buffer and kept episodes: its
    /// networks (policy, averaged policy, model, value and its target),
    /// optimiser moments, settings and demonstration pairs, for a small
    /// file to study the final model and value. Training on from it
    /// starts from an empty buffer of the configured size, but at the
    /// copied step count, so without a warm-up.
    ///
    /// # Errors
    /// None in practice (the buffer's shape comes from the policy).
    pub fn without_replay(&self) -> Result<Self> {
        let (o, a) = (self.policy.obs_dim(), self.policy.act_dim());
        Ok(Self {
            config: self.config.clone(),
            policy: self.policy.clone(),
            model: self.model.clone(),
            value: self.value.clone(),
            value_target: self.value_target.clone(),
            policy_opt: self.policy_opt.clone(),
            model_opt: self.model_opt.clone(),
            value_opt: self.value_opt.clone(),
            replay: ReplayBuffer::new(self.config.buffer_size, o, a)?.with_behaviour_logp(),
            env_steps: self.env_steps,
            avg_policy: self.avg_policy.clone(),
            avg_count: self.avg_count,
            demos: self.demos.clone(),
            sil: Vec::new(),
            twin: self.twin.clone(),
        })
    }

    /// The learner's value of prepared observations `x`: the value
    /// network's, or with `twin_value` the smaller of the two networks'.
    fn value_estimate(&self, x: ArrayView2<'_, f32>) -> Array2<f32> {
        let v = self.value.predict(x);
        match &self.twin {
            Some(t) => min_values(v, &t.value.predict(x)),
            None => v,
        }
    }

    /// The settings.
    pub fn config(&self) -> &SvgConfig {
        &self.config
    }

    /// The policy.
    pub fn policy(&self) -> &GaussianPolicy {
        &self.policy
    }

    /// The policy, mutably (to set parameters, e.g. in a gradient check).
    pub fn policy_mut(&mut self) -> &mut GaussianPolicy {
        &mut self.policy
    }

    /// The policy to report: the averaged one when `policy_avg_tau > 0` or
    /// once the uniform average of `policy_avg_uniform_from` has started,
    /// else the current one.
    pub fn reported_policy(&self) -> &GaussianPolicy {
        match &self.avg_policy {
            Some(avg) if self.config.policy_avg_tau > 0.0 || self.avg_count > 0 => avg,
            _ => &self.policy,
        }
    }

    /// The fixed standard deviation at the current step, if any.
    pub fn current_fixed_std(&self) -> Option<f64> {
        let s0 = self.config.fixed_std?;
        Some(match self.config.fixed_std_final {
            Some(s1) => s0 + (s1 - s0) * self.schedule_progress(0),
            None => s0,
        })
    }

    /// Fraction in [0, 1] of the schedule done, the schedule starting at
    /// env step `start`.
    fn schedule_progress(&self, start: u64) -> f64 {
        let end = self.config.schedule_steps;
        if end <= start {
            return if end == 0 { 0.0 } else { 1.0 };
        }
        (self.env_steps.saturating_sub(start) as f64 / (end - start) as f64).min(1.0)
    }

    /// The policy's distribution on prepared observations, with the fixed
    /// standard deviation applied (its log-std then passes no gradient).
    fn dist_fixed(&self, mut dist: crate::policy::GaussianBatch) -> crate::policy::GaussianBatch {
        if let Some(sd) = self.current_fixed_std() {
            dist.log_std.fill(sd.ln());
            dist.log_std_mask.fill(0.0);
        }
        dist
    }

    /// Demonstration pairs for the behaviour-cloning term (`bc_weight`).
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] for no pairs, row counts that differ or
    /// widths other than the policy's; [`Error::NonFinite`] for a value that
    /// is not finite.
    pub fn set_demos(&mut self, states: Array2<f64>, actions: Array2<f64>) -> Result<()> {
        let (o, a) = (self.policy.obs_dim(), self.policy.act_dim());
        if states.nrows() == 0
            || states.nrows() != actions.nrows()
            || states.ncols() != o
            || actions.ncols() != a
        {
            return Err(Error::ShapeMismatch {
                what: "SVG demonstration pairs".into(),
                expected: format!("n >= 1 rows of {o} state and {a} action numbers"),
                got: format!(
                    "{} x {} states, {} x {} actions",
                    states.nrows(),
                    states.ncols(),
                    actions.nrows(),
                    actions.ncols()
                ),
            });
        }
        if states.iter().chain(actions.iter()).any(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "SVG demonstration pairs".into(),
                step: self.env_steps,
            });
        }
        self.demos = Some((states, actions));
        Ok(())
    }

    /// Unwraps the policy.
    pub fn into_policy(self) -> GaussianPolicy {
        self.policy
    }

    /// Transitions held in replay.
    pub fn replay_len(&self) -> usize {
        self.replay.len()
    }

    /// Environment steps seen by [`EpisodicLearner::run_episode`].
    pub fn env_steps(&self) -> u64 {
        self.env_steps
    }

    /// Samples an action for one raw observation; returns it with its
    /// log-probability under the current policy.
    ///
    /// # Errors
    /// Shape or non-finite observation errors.
    pub fn act<R: Rng + ?Sized>(&self, obs: &[f64], rng: &mut R) -> Result<(Vec<f64>, f64)> {
        let mut a = vec![0.0; self.policy.act_dim()];
        if let Some(sd) = self.current_fixed_std() {
            self.policy
                .act_into(obs, None::<&mut R>, &mut PolicyWorkspace::default(), &mut a)?;
            for v in &mut a {
                *v += sd * rng.sample::<f64, _>(rand_distr::StandardNormal);
            }
        } else {
            self.policy
                .act_into(obs, Some(rng), &mut PolicyWorkspace::default(), &mut a)?;
        }
        let x = self
            .policy
            .prepare_obs(ArrayView2::from_shape((1, obs.len()), obs).map_err(one_row)?)?;
        let dist = self.dist_fixed(self.policy.distribution(x.view(), &mut Workspace::new())?);
        let av = ArrayView2::from_shape((1, a.len()), &a).map_err(one_row)?;
        let logp = dist.log_prob(av)[0];
        Ok((a, logp))
    }

    /// Stores a transition with the behaviour log-probability of its action.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] for wrong lengths.
    pub fn push(
        &mut self,
        state: &[f64],
        action: &[f64],
        behaviour_logp: f64,
        reward: f64,
        next_state: &[f64],
        terminated: bool,
    ) -> Result<()> {
        self.replay.push_with_logp(
            state,
            action,
            behaviour_logp,
            reward,
            next_state,
            terminated,
        )
    }

    /// Adds `delta` to the stored reward of the most recent transition (the
    /// terminal reward heuristic at an episode's end).
    pub fn adjust_last_reward(&mut self, delta: f64) {
        self.replay.adjust_last_reward(delta);
    }

    /// Draws `n` transitions uniformly with replacement.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] if the replay is empty.
    pub fn sample<R: Rng + ?Sized>(&self, n: usize, rng: &mut R) -> Result<SvgBatch> {
        self.replay.sample(n, rng)
    }

    /// Model input `[x, a]`.
    fn model_input(x: ArrayView2<'_, f32>, a: ArrayView2<'_, f64>) -> Array2<f32> {
        concatenate(Axis(1), &[x, a.mapv(|v| v as f32).view()]).expect("same number of rows")
    }

    /// One model step on `batch`; returns the loss.
    ///
    /// # Errors
    /// Shape errors.
    pub fn update_model(&mut self, batch: &SvgBatch) -> Result<f64> {
        let x = self.policy.prepare_obs(batch.states.view())?;
        let xn = self.policy.prepare_obs(batch.next_states.view())?;
        let input = Self::model_input(x.view(), batch.actions.view());
        let target = &xn - &x;
        let mut tape = Tape::new();
        let pred = self.model.forward_tape(input.view(), &mut tape);
        let (loss, g) = mse_loss(pred, target.view());
        let mut grads = self.model.zero_grads();
        self.model.backward_params(&tape, g.view(), &mut grads);
        clip_grad_norm(&mut grads, self.config.max_grad_norm);
        self.model_opt.step(&mut self.model, &grads)?;
        Ok(loss as f64)
    }

    /// Truncated importance weights of `batch` under the current policy.
    ///
    /// # Errors
    /// Shape errors.
    pub fn importance_weights(&self, batch: &SvgBatch) -> Result<Vec<f64>> {
        let x = self.policy.prepare_obs(batch.states.view())?;
        let dist = self.dist_fixed(self.policy.distribution(x.view(), &mut Workspace::new())?);
        let lp = dist.log_prob(batch.actions.view());
        if !self.config.importance_weights {
            return Ok(vec![1.0; lp.len()]);
        }
        Ok(lp
            .iter()
            .zip(&batch.behaviour_logp)
            .map(|(l, b)| (l - b).min(self.config.iw_clip.ln()).exp())
            .collect())
    }

    /// One importance-weighted TD(0) step of the value function; returns
    /// the loss. Also moves the target network.
    ///
    /// # Errors
    /// Shape errors.
    pub fn update_value(&mut self, batch: &SvgBatch, weights: &[f64]) -> Result<f64> {
        let discount: Vec<f64> = batch
            .terminated
            .iter()
            .map(|&t| if t { 0.0 } else { self.config.gamma })
            .collect();
        let later = vec![0.0; discount.len()];
        self.value_step(batch, &batch.next_states, &later, &discount, weights)
    }

    /// One importance-weighted `n`-step TD step of the value function
    /// (`svg.value_nstep`): the target of row `i` is `r_i +
    /// tail.later_rewards[i] + tail.discount[i] * V_target(tail.boot_states[i])`,
    /// weighted by row `i`'s importance weight only (the later steps'
    /// actions are not corrected). Returns the loss; moves the target
    /// network.
    ///
    /// # Errors
    /// Shape errors.
    pub fn update_value_nstep(
        &mut self,
        batch: &SvgBatch,
        tail: &NStepTail,
        weights: &[f64],
    ) -> Result<f64> {
        self.value_step(
            batch,
            &tail.boot_states,
            &tail.later_rewards,
            &tail.discount,
            weights,
        )
    }

    fn value_step(
        &mut self,
        batch: &SvgBatch,
        boot_states: &Array2<f64>,
        later: &[f64],
        discount: &[f64],
        weights: &[f64],
    ) -> Result<f64> {
        let x = self.policy.prepare_obs(batch.states.view())?;
        let xn = self.policy.prepare_obs(boot_states.view())?;
        let mut vn = self.value_target.predict(xn.view());
        if let Some(t) = &self.twin {
            vn = min_values(vn, &t.target.predict(xn.view()));
        }
        let n = batch.rewards.len();
        let targets: Vec<f64> = (0..n)
            .map(|i| {
                let boot = if discount[i] == 0.0 {
                    0.0
                } else {
                    discount[i] * vn[[i, 0]] as f64
                };
                batch.rewards[i] + later[i] + boot
            })
            .collect();
        let (max_norm, tau) = (self.config.max_grad_norm, self.config.target_tau as f32);
        let loss = td_step(
            &mut self.value,
            &mut self.value_target,
            &mut self.value_opt,
            x.view(),
            &targets,
            weights,
            max_norm,
            tau,
        )?;
        if let Some(t) = &mut self.twin {
            td_step(
                &mut t.value,
                &mut t.target,
                &mut t.opt,
                x.view(),
                &targets,
                weights,
                max_norm,
                tau,
            )?;
        }
        Ok(loss)
    }

    /// The noise and weights held fixed in a policy step on `batch`.
    ///
    /// # Errors
    /// Shape errors.
    pub fn policy_inputs(&self, batch: &SvgBatch) -> Result<PolicyInputs> {
        let x = self.policy.prepare_obs(batch.states.view())?;
        let xn = self.policy.prepare_obs(batch.next_states.view())?;
        let dist = self.dist_fixed(self.policy.distribution(x.view(), &mut Workspace::new())?);
        let mut eta = &batch.actions - &dist.mean;
        let scale = self.config.eta_scale;
        eta.zip_mut_with(&dist.log_std, |e, &ls| *e *= scale * (-ls).exp());
        let input = Self::model_input(x.view(), batch.actions.view());
        let pred = self.model.predict(input.view());
        let xi = (&xn - &x - &pred).mapv(|v| v as f64);
        let weights = self.importance_weights(batch)?;
        Ok(PolicyInputs { eta, xi, weights })
    }

    /// The policy objective `mean_i w_i [r(s_i, a_i) + gamma (1 - d_i)
    /// V(x_i + f(x_i, a_i) + xi_i)]` with `a_i = mu(x_i) + sigma(x_i) eta_i`,
    /// and its gradient with respect to the policy parameters (ascent
    /// direction).
    ///
    /// # Errors
    /// Shape errors, the reward's errors.
    pub fn policy_objective(
        &self,
        batch: &SvgBatch,
        inputs: &PolicyInputs,
        reward: &dyn DifferentiableReward,
    ) -> Result<(f64, Gradients)> {
        let n = batch.rewards.len();
        let o = self.policy.obs_dim();
        let x = self.policy.prepare_obs(batch.states.view())?;
        let mut ptape = Tape::new();
        let dist = self.dist_fixed(self.policy.distribution_tape(x.view(), &mut ptape)?);
        let mut a = inputs.eta.clone();
        a.zip_mut_with(&dist.log_std, |e, &ls| *e *= ls.exp());
        a += &dist.mean;
        let (r, dr) = reward.reward_and_grad(batch.states.view(), a.view())?;
        if r.len() != n || dr.dim() != a.dim() {
            return Err(Error::ShapeMismatch {
                what: "differentiable reward output".into(),
                expected: format!("{n} rewards and {:?} gradients", a.dim()),
                got: format!("{} and {:?}", r.len(), dr.dim()),
            });
        }
        // Next state through the model with the inferred model noise.
        let input = Self::model_input(x.view(), a.view());
        let mut mtape = Tape::new();
        let pred = self.model.forward_tape(input.view(), &mut mtape).to_owned();
        let xn = &x + &pred + &inputs.xi.mapv(|v| v as f32);
        let mut vtape = Tape::new();
        let v = self.value.forward_tape(xn.view(), &mut vtape).to_owned();
        // With `twin_value`, each row reads (and differentiates) the
        // smaller of the two values.
        let mut ttape = Tape::new();
        let v2 = self
            .twin
            .as_ref()
            .map(|t| t.value.forward_tape(xn.view(), &mut ttape).to_owned());
        let mut objective = 0.0;
        let mut gv = Array2::<f32>::zeros((n, 1));
        let mut gv2 = Array2::<f32>::zeros((n, 1));
        for i in 0..n {
            let cont = if batch.terminated[i] { 0.0 } else { 1.0 };
            let w = inputs.weights[i] / n as f64;
            let g = (w * self.config.gamma * cont) as f32;
            let vi = match &v2 {
                Some(v2) if v2[[i, 0]] < v[[i, 0]] => {
                    gv2[[i, 0]] = g;
                    v2[[i, 0]]
                }
                _ => {
                    gv[[i, 0]] = g;
                    v[[i, 0]]
                }
            };
            objective += w * (r[i] + self.config.gamma * cont * vi as f64);
        }
        // dJ/dx' -> dJ/d(model output) is the same (x' = x + f + xi).
        let mut scratch = self.value.zero_grads();
        let mut d_xn = self.value.backward(&vtape, gv.view(), &mut scratch);
        if let Some(t) = &self.twin {
            let mut scratch = t.value.zero_grads();
            d_xn += &t.value.backward(&ttape, gv2.view(), &mut scratch);
        }
        let mut scratch_m = self.model.zero_grads();
        let d_in = self.model.backward(&mtape, d_xn.view(), &mut scratch_m);
        let mut d_a = d_in.slice(s![.., o..]).mapv(|v| v as f64);
        for i in 0..n {
            let w = inputs.weights[i] / n as f64;
            for j in 0..a.ncols() {
                d_a[[i, j]] += w * dr[[i, j]];
            }
        }
        let mut grads = self.policy.net().zero_grads();
        self.policy
            .backward_reparam(&ptape, &dist, inputs.eta.view(), d_a.view(), &mut grads);
        Ok((objective, grads))
    }

    /// One policy ascent step on `batch`; returns the objective.
    ///
    /// # Errors
    /// Shape errors, the reward's errors, [`Error::NonFinite`].
    pub fn update_policy(
        &mut self,
        batch: &SvgBatch,
        inputs: &PolicyInputs,
        reward: &dyn DifferentiableReward,
    ) -> Result<f64> {
        self.update_policy_bc(batch, inputs, reward, None)
    }

    /// [`Svg1::update_policy`] with an optional behaviour-cloning batch
    /// `(states, actions)` weighted by `bc_weight`.
    ///
    /// # Errors
    /// As [`Svg1::update_policy`].
    pub fn update_policy_bc(
        &mut self,
        batch: &SvgBatch,
        inputs: &PolicyInputs,
        reward: &dyn DifferentiableReward,
        bc: Option<(&Array2<f64>, &Array2<f64>)>,
    ) -> Result<f64> {
        self.update_policy_imitating(batch, inputs, reward, bc, None, None)
    }

    /// [`Svg1::update_policy_bc`] with an optional self-imitation batch
    /// `(states, actions, mask)` weighted by `sil_weight`, and the noise
    /// of the spatial smoothness term (`spatial_smooth_weight`), one row
    /// per state of `batch` in the policy's normalised input.
    fn update_policy_imitating(
        &mut self,
        batch: &SvgBatch,
        inputs: &PolicyInputs,
        reward: &dyn DifferentiableReward,
        bc: Option<(&Array2<f64>, &Array2<f64>)>,
        sil: Option<&SilBatch>,
        spatial_noise: Option<&Array2<f32>>,
    ) -> Result<f64> {
        let (obj, mut grads) = self.policy_objective(batch, inputs, reward)?;
        if !grads.is_finite() || !obj.is_finite() {
            return Err(Error::NonFinite {
                what: "SVG policy gradient".into(),
                step: self.env_steps,
            });
        }
        grads.scale(-1.0);
        if let Some((ds, da)) = bc
            && self.config.bc_weight > 0.0
        {
            let x = self.policy.prepare_obs(ds.view())?;
            let mut tape = Tape::new();
            let dist = self.policy.distribution_tape(x.view(), &mut tape)?;
            let n = ds.nrows() as f64;
            let d_mean = (&dist.mean - da).mapv(|v| 2.0 * self.config.bc_weight * v / n);
            let d_ls = Array2::<f64>::zeros(d_mean.raw_dim());
            self.policy
                .backward_params(&tape, &dist, d_mean.view(), d_ls.view(), &mut grads);
        }
        if let Some((ss, sa, mask)) = sil
            && self.config.sil_weight > 0.0
        {
            let x = self.policy.prepare_obs(ss.view())?;
            let mut tape = Tape::new();
            let dist = self.policy.distribution_tape(x.view(), &mut tape)?;
            let n = ss.nrows() as f64;
            let w = 2.0 * self.config.sil_weight / n;
            let mut d_mean = &dist.mean - sa;
            for (mut row, m) in d_mean.rows_mut().into_iter().zip(mask) {
                row.mapv_inplace(|v| w * m * v);
            }
            let d_ls = Array2::<f64>::zeros(d_mean.raw_dim());
            self.policy
                .backward_params(&tape, &dist, d_mean.view(), d_ls.view(), &mut grads);
        }
        if self.config.smooth_weight > 0.0 {
            self.add_smoothness_grad(batch, &mut grads)?;
        }
        if let Some(eps) = spatial_noise
            && self.config.spatial_smooth_weight > 0.0
        {
            self.add_spatial_smoothness_grad(batch, eps, &mut grads)?;
        }
        clip_grad_norm(&mut grads, self.config.max_grad_norm);
        if let Some(lr1) = self.config.policy_lr_final {
            let start = self.config.learning_starts + self.config.policy_delay;
            let f = self.schedule_progress(start) as f32;
            let lr0 = self.config.policy_lr;
            self.policy_opt.set_lr(lr0 + (lr1 - lr0) * f)?;
        }
        self.policy_opt.step(self.policy.net_mut(), &grads)?;
        if let Some(avg) = self.avg_policy.as_mut() {
            let uniform = self
                .config
                .policy_avg_uniform_from
                .is_some_and(|from| self.env_steps >= from);
            // The n-th policy of the uniform mean enters with weight 1/n
            // (the first replaces whatever the copy held).
            let tau = if uniform {
                self.avg_count += 1;
                1.0 / self.avg_count as f64
            } else {
                self.config.policy_avg_tau
            };
            if tau > 0.0 {
                avg.net_mut().polyak_toward(self.policy.net(), tau as f32)?;
            }
        }
        Ok(obj)
    }

    /// Adds to `grads` the gradient of the temporal smoothness term
    /// (`smooth_weight`) on `batch`'s transitions not into a terminal
    /// state.
    fn add_smoothness_grad(&self, batch: &SvgBatch, grads: &mut Gradients) -> Result<()> {
        let live: Vec<usize> = (0..batch.terminated.len())
            .filter(|&i| !batch.terminated[i])
            .collect();
        if live.is_empty() {
            return Ok(());
        }
        let x = self
            .policy
            .prepare_obs(batch.states.select(Axis(0), &live).view())?;
        let x_next = self
            .policy
            .prepare_obs(batch.next_states.select(Axis(0), &live).view())?;
        let w = 2.0 * self.config.smooth_weight / batch.states.nrows() as f64;
        self.add_pull_together_grad(&x, &x_next, w, grads)
    }

    /// Adds to `grads` the gradient of `w / 2 * sum ||mu(x) - mu(y)||^2`
    /// over the rows of the policy inputs `x` and `y` (both sides move).
    fn add_pull_together_grad(
        &self,
        x: &Array2<f32>,
        y: &Array2<f32>,
        w: f64,
        grads: &mut Gradients,
    ) -> Result<()> {
        let (mut tape, mut tape_y) = (Tape::new(), Tape::new());
        let dist = self.policy.distribution_tape(x.view(), &mut tape)?;
        let dist_y = self.policy.distribution_tape(y.view(), &mut tape_y)?;
        let d_mean = (&dist.mean - &dist_y.mean).mapv(|v| w * v);
        let d_ls = Array2::<f64>::zeros(d_mean.raw_dim());
        self.policy
            .backward_params(&tape, &dist, d_mean.view(), d_ls.view(), grads);
        let d_y = d_mean.mapv(|v| -v);
        self.policy
            .backward_params(&tape_y, &dist_y, d_y.view(), d_ls.view(), grads);
        Ok(())
    }

    /// Adds to `grads` the gradient of the spatial smoothness term
    /// (`spatial_smooth_weight`) on `batch`'s states, moved by `eps` in
    /// the policy's normalised input.
    fn add_spatial_smoothness_grad(
        &self,
        batch: &SvgBatch,
        eps: &Array2<f32>,
        grads: &mut Gradients,
    ) -> Result<()> {
        let x = self.policy.prepare_obs(batch.states.view())?;
        let x_near = &x + eps;
        let w = 2.0 * self.config.spatial_smooth_weight / batch.states.nrows() as f64;
        self.add_pull_together_grad(&x, &x_near, w, grads)
    }

    /// One round of updates (model, value, and the policy when
    /// `with_policy`) on fresh minibatches.
    ///
    /// # Errors
    /// As the individual updates.
    pub fn update<R: Rng + ?Sized>(
        &mut self,
        reward: &dyn DifferentiableReward,
        with_policy: bool,
        rng: &mut R,
    ) -> Result<UpdateStats> {
        let bs = self.config.batch_size;
        let b = self.sample(bs, rng)?;
        let model_loss = self.update_model(&b)?;
        self.check_finite("SVG model loss", model_loss)?;
        let (mut b, tail) = if self.config.value_nstep > 1 {
            let (b, t) = self.replay.sample_with_tail(
                bs,
                self.config.value_nstep,
                self.config.gamma,
                rng,
            )?;
            (b, Some(t))
        } else {
            (self.sample(bs, rng)?, None)
        };
        if reward.is_adaptive() {
            let (r, _) = reward.reward_and_grad(b.states.view(), b.actions.view())?;
            b.set_rewards(&r.to_vec())?;
        }
        let w = self.importance_weights(&b)?;
        let value_loss = match &tail {
            Some(t) => self.update_value_nstep(&b, t, &w)?,
            None => self.update_value(&b, &w)?,
        };
        self.check_finite("SVG value loss", value_loss)?;
        let policy_objective = if with_policy {
            let b = self.sample(bs, rng)?;
            let inputs = self.policy_inputs(&b)?;
            let bc = match (&self.demos, self.config.bc_weight > 0.0) {
                (Some((ds, da)), true) => {
                    let m = ds.nrows();
                    let idx: Vec<usize> = (0..bs).map(|_| rng.random_range(0..m)).collect();
                    Some((ds.select(Axis(0), &idx), da.select(Axis(0), &idx)))
                }
                (None, true) => {
                    return Err(Error::InvalidConfig {
                        field: "bc_weight".into(),
                        reason: format!(
                            "is {} but the learner has no demonstration pairs \
                             (Svg1::set_demos); set them or set bc_weight to 0",
                            self.config.bc_weight
                        ),
                    });
                }
                (_, false) => None,
            };
            let sil = self.sil_batch(bs, rng)?;
            let sd = self.config.spatial_smooth_std;
            let spatial = (self.config.spatial_smooth_weight > 0.0).then(|| {
                Array2::from_shape_fn((b.states.nrows(), self.policy.obs_dim()), |_| {
                    (sd * rng.sample::<f64, _>(rand_distr::StandardNormal)) as f32
                })
            });
            let o = self.update_policy_imitating(
                &b,
                &inputs,
                reward,
                bc.as_ref().map(|(s, a)| (s, a)),
                sil.as_ref(),
                spatial.as_ref(),
            )?;
            Some(o)
        } else {
            None
        };
        Ok(UpdateStats {
            model_loss,
            value_loss,
            policy_objective,
        })
    }

    /// Pairs drawn uniformly from the kept self-imitation episodes, with
    /// their masks (1 where the discounted own return from the pair on
    /// exceeds `V(s)`); `None` when the term is off or nothing is kept.
    fn sil_batch<R: Rng + ?Sized>(&self, n: usize, rng: &mut R) -> Result<Option<SilBatch>> {
        let total: usize = self.sil.iter().map(|e| e.returns.len()).sum();
        if self.config.sil_weight <= 0.0 || total == 0 {
            return Ok(None);
        }
        let (o, a) = (self.policy.obs_dim(), self.policy.act_dim());
        let mut states = Array2::<f64>::zeros((n, o));
        let mut actions = Array2::<f64>::zeros((n, a));
        let mut returns = Vec::with_capacity(n);
        for i in 0..n {
            let mut k = rng.random_range(0..total);
            for e in &self.sil {
                if k < e.returns.len() {
                    states.row_mut(i).assign(&e.states.row(k));
                    actions.row_mut(i).assign(&e.actions.row(k));
                    returns.push(e.returns[k]);
                    break;
                }
                k -= e.returns.len();
            }
        }
        let x = self.policy.prepare_obs(states.view())?;
        let v = self.value_estimate(x.view());
        let mask = returns
            .iter()
            .zip(v.column(0))
            .map(|(g, v)| if *g > *v as f64 { 1.0 } else { 0.0 })
            .collect();
        Ok(Some((states, actions, mask)))
    }

    /// Offers a finished training episode to the self-imitation term:
    /// kept when its own return is among the `sil_episodes` highest.
    fn offer_sil(&mut self, outcome: &EpisodeOutcome, rewards: &[f64]) {
        if self.config.sil_weight <= 0.0 || rewards.is_empty() {
            return;
        }
        let own_return: f64 = rewards.iter().sum();
        let k = self.config.sil_episodes;
        if self.sil.len() >= k && self.sil.last().is_some_and(|e| e.own_return >= own_return) {
            return;
        }
        let mut returns = vec![0.0; rewards.len()];
        let mut g = 0.0;
        for t in (0..rewards.len()).rev() {
            g = rewards[t] + self.config.gamma * g;
            returns[t] = g;
        }
        let at = self
            .sil
            .iter()
            .position(|e| e.own_return < own_return)
            .unwrap_or(self.sil.len());
        self.sil.insert(
            at,
            SilEpisode {
                own_return,
                states: outcome.states.clone(),
                actions: outcome.actions.clone(),
                returns,
            },
        );
        self.sil.truncate(k);
    }

    /// Own returns of the episodes kept for the self-imitation term,
    /// highest first.
    pub fn sil_returns(&self) -> Vec<f64> {
        self.sil.iter().map(|e| e.own_return).collect()
    }

    fn check_finite(&self, what: &str, v: f64) -> Result<()> {
        if v.is_finite() {
            Ok(())
        } else {
            Err(Error::NonFinite {
                what: what.into(),
                step: self.env_steps,
            })
        }
    }

    fn check_observation(&self, obs: &[f64]) -> Result<()> {
        crate::episodic::check_observation(obs, self.env_steps)
    }

    fn check_spaces<E: Env + ?Sized>(&self, env: &E) -> Result<()> {
        let (o, a) = (self.policy.obs_dim(), self.policy.act_dim());
        crate::episodic::check_spaces("SVG", env, o, a)
    }
}

impl EpisodicLearner for Svg1 {
    fn env_steps(&self) -> u64 {
        self.env_steps
    }

    /// Runs one episode with the stochastic policy, at most `max_steps`
    /// environment steps, storing transitions with the imitation reward of
    /// `reward` (never the environment's) and updating as configured. The
    /// episode starts with `env.reset(Some(reset_seed))` or, without one,
    /// a seed drawn from `rng`. At the episode's end `terminal(final_reward,
    /// final_info)` (the last step's imitation reward and the environment's
    /// info of that step) is added to the last stored reward (RED's terminal
    /// heuristic; pass `|_, _| 0.0` for none).
    ///
    /// Returns the episode's report and its state-action pairs; `finished`
    /// is false when the step budget cut it short.
    ///
    /// # Errors
    /// Environment, shape and update errors; [`Error::NonFinite`] naming a
    /// non-finite observation, imitation reward, loss or gradient and the
    /// environment step where it appeared.
    fn run_episode<E: Env + ?Sized, R: Rng + ?Sized>(
        &mut self,
        env: &mut E,
        reward: &dyn DifferentiableReward,
        reset_seed: Option<u64>,
        terminal: &dyn Fn(f64, &Info) -> f64,
        max_steps: u64,
        rng: &mut R,
    ) -> Result<EpisodeOutcome> {
        self.check_spaces(env)?;
        let seed = reset_seed.unwrap_or_else(|| rng.random());
        let (mut obs, _) = env.reset(Some(seed))?;
        let mut eps_prev: Option<Vec<f64>> = None;
        self.check_observation(&obs)?;
        let mut log = EpisodeLog::new(self.policy.obs_dim(), self.policy.act_dim());
        let mut own_rewards = Vec::new();
        while (log.length() as u64) < max_steps {
            let (a, logp) = match (self.current_fixed_std(), self.config.noise_rho > 0.0) {
                (Some(sd), true) => {
                    let rho = self.config.noise_rho;
                    let mu = self.policy.act_deterministic(&obs)?;
                    let k = mu.len();
                    let (cs, prev) = match &eps_prev {
                        Some(p) => (
                            (1.0 - rho * rho).sqrt() * sd,
                            p.iter().map(|e| rho * e).collect(),
                        ),
                        None => (sd, vec![0.0; k]),
                    };
                    let mut eps = vec![0.0; k];
                    let mut a = vec![0.0; k];
                    let mut logp = 0.0;
                    for j in 0..k {
                        let z: f64 = rng.sample(rand_distr::StandardNormal);
                        eps[j] = prev[j] + cs * z;
                        a[j] = mu[j] + eps[j];
                        logp -= 0.5 * z * z + cs.ln() + 0.918_938_533_204_672_7;
                    }
                    eps_prev = Some(eps);
                    (a, logp)
                }
                _ => self.act(&obs, rng)?,
            };
            let step = env.step(&a)?;
            self.check_observation(&step.observation)?;
            let r = EpisodeLog::reward_of(reward, &obs, &a, self.env_steps)?;
            self.push(&obs, &a, logp, r, &step.observation, step.terminated)?;
            log.record(&obs, &a, step.reward, r);
            own_rewards.push(r);
            self.env_steps += 1;
            let start = self.config.learning_starts;
            if self.env_steps > start {
                let with_policy = self.env_steps > start + self.config.policy_delay;
                for _ in 0..self.config.updates_per_step {
                    self.update(reward, with_policy, rng)?;
                }
            }
            if step.terminated || step.truncated {
                let adj = terminal(r, &step.info);
                self.adjust_last_reward(adj);
                log.end(adj, step.info);
                if let Some(last) = own_rewards.last_mut() {
                    *last += adj;
                }
                let outcome = log.into_outcome(self.env_steps)?;
                if outcome.finished {
                    self.offer_sil(&outcome, &own_rewards);
                }
                return Ok(outcome);
            }
            obs = step.observation;
        }
        log.into_outcome(self.env_steps)
    }
}
