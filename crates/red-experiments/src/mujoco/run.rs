//! One TRPO run on a MuJoCo task, shared by experts, imitation runs and
//! the grid of Table 1: the run's settings ([`RunConfig`]), its folder,
//! checkpoints, metrics, the best checkpoint by true return, the final
//! policy and its evaluation.
//!
//! A run folder `<name>/` holds:
//! - `config.json`: every setting ([`RunConfig`]);
//! - `checkpoint.json`: the whole state (trainer, reward model, counters),
//!   written atomically every `checkpoint_every` iterations, when stopped
//!   and at the end; [`super::launch::run`] with `resume` continues from it;
//! - `metrics.csv`: one row per TRPO iteration (true return, imitation
//!   reward, losses, MuJoCo warnings);
//! - `best_policy.json`: the policy whenever the mean TRUE return of the
//!   last `best_window` training episodes reached a new best (the paper's
//!   model selection, which uses the true reward);
//! - `policy.json`: the final policy; `eval.json`: both evaluated with
//!   deterministic actions on the true reward;
//! - for `expert` runs, `expert_policy.json` and `demos.json` (the
//!   4-trajectory demonstration file).

use std::collections::VecDeque;
use std::io::BufRead;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use ndarray::Array2;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use red_core::checkpoint::{load_checkpoint_for, write_atomic};
use red_core::{
    BoxSpace, ClippedActions, Demos, Env, RewardModel, Seeder, Space, Stream, record_episode,
};
use red_mujoco::watched::MJ_N_WARNING;
use red_mujoco::{EnvId, MujocoEnv, WatchedEnv, describe_warnings};
use red_rl::bc::{BcConfig, behavior_clone};
use red_rl::gae::GaeConfig;
use red_rl::gail::GailConfig;
use red_rl::gmmil::GmmilConfig;
use red_rl::normalize::{DEFAULT_CLIP, DEFAULT_MIN_STD, ObsNormalizer};
use red_rl::policy::{GaussianPolicy, GaussianPolicyConfig};
use red_rl::rollout::{EvalReport, evaluate, evaluate_sampled};
use red_rl::sac::SacConfig;
use red_rl::trpo::{IterationMetrics, TrpoConfig, TrpoHooks, TrpoTrainer};
use red_support::{AutoencoderConfig, ExpertScores, RedRewardConfig, RndConfig, Sigma1};
use serde::{Deserialize, Serialize};

use super::Method;
use crate::imitation::{ImitationReward, RewardSettings, fit_reward};
use crate::{Error, Progress, Result, ResultExt, RunDir};

/// The kind written in this experiment's checkpoints.
pub const CHECKPOINT_KIND: &str = "mujoco-train";

/// The state dimensions RED's reward leaves out on Reacher by default
/// (`rnd.ignored_state_dims`, since session 51): the joint angles' cosines
/// and sines (0-3), the target (4, 5) and the joint velocities (6, 7). It
/// reads the fingertip's offset from the target (8, 9), the time feature
/// ([`RunConfig::time_feature`], on with it) and the action. Four
/// demonstrations show four targets and four arm poses; on a new target
/// only the offset says whether the arm does what the demonstrator did, and
/// the time says when (far early, on the target late). Measured (session
/// 51, docs/results/mujoco.md): on the SAC Reacher expert's mean-action and
/// sampled demos, 2M steps, seeds 0-2, -5.05, -5.23, -5.91 and -5.65,
/// -4.65, -4.32 against -7.79, -9.33, -8.99 and -10.56, -9.91, -11.06 with
/// every dimension and no time; the time feature alone -6.99, -6.39, -9.73
/// and -6.87, -10.96, -9.19; these dimensions without the time -8.40,
/// -8.93, -10.23 and -10.39, -10.20, -11.01 (session 50).
pub const REACHER_RED_IGNORED_DIMS: [usize; 8] = [0, 1, 2, 3, 4, 5, 6, 7];

/// Every setting of a run, written to `config.json`. Defaults per task and
/// method come from [`RunConfig::for_task`]; they follow the RED release
/// (`reference/original-red.md`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RunConfig {
    /// The task.
    pub env: EnvId,
    /// How the policy is trained.
    pub method: Method,
    /// Seed of every random stream of the run.
    pub seed: u64,
    /// Budget in environment steps (not used by `bc`). Default: 2,000,000
    /// (the release's README example); 5,000,000 for `expert` (the paper's
    /// budget, which its experts need to reach the release's returns).
    pub steps: u64,
    /// Demonstration file (every method but `expert`).
    pub demo: Option<PathBuf>,
    /// TRPO's settings. Default: the release's (gamma 0.99 for Reacher),
    /// except that a `red` run with a BC warm start starts its policy's
    /// log-std at -1 (sigma ~0.37) on Hopper, HalfCheetah and Walker2d and at -2
    /// (sigma ~0.14) on Ant, instead of 0. Measured reason: with a wide
    /// Gaussian the sampled actions of the warm-started policy are mostly
    /// noise and TRPO drifts away from the cloned gait before it has seen
    /// it (HalfCheetah, sigma 1: the first batch of the 20-epoch warm start
    /// returned -230, BC's mean actions 1718). On Ant (expert trained to
    /// 5M, 3.3 m/s) sigma 0.37 still was too wide: imitation reward 0.26 and
    /// true reward 0.45 per step over the first 50 iterations, after which
    /// the ant stood still (771.63 at 1.2M, seed 0); with sigma 0.14: 0.78
    /// and 3.05 per step, and it kept walking (see `bc_warm_start_epochs`).
    ///
    /// RED on Hopper (since session 47) also discounts with gamma 0.99 and
    /// lambda 0.98 and bootstraps the value at the 1000-step time limit (the
    /// release: 0.97, 0.97, a cut treated as terminal), as the Hopper
    /// expert does. Measured reason: with gamma 0.97 (a horizon of ~33
    /// steps) a fall costs the policy little, and final policies that had
    /// found the expert's gait fell in many episodes; on the seed-1
    /// expert's demo sets, 2M steps, final policy (docs/results/mujoco.md,
    /// "Session 47"): mean-action clipped seed 1 3219.63 -> 3675.64,
    /// sampled raw seeds 0 and 2 1751.22 -> 3670.47 and 1454.47 -> 3629.10
    /// (the demos: 1954.03), one trajectory seed 2 2485.54 -> 3582.07;
    /// mean of 12 runs (4 sets x seeds 0-2) 3107.8 -> 3655.1, worst share
    /// of its set's return 67.9% -> 97.8%. At 5M steps on the same
    /// expert's demos, seeds 0-2: 2159.0, 3489.7, 3662.7 (session 32) ->
    /// 3681.1, 3655.3, 3676.7.
    ///
    /// RED on HalfCheetah discounts the same way since session 48 (its
    /// episodes always end at the time limit, which the release treated as
    /// a fall). Measured on 2M-step runs, final policy, seeds 0-2
    /// (docs/results/mujoco.md, "Session 48"): on the SAC expert's demos
    /// (6935.2) 3242.13, 4609.59, 3322.88 -> 5630.50, 6034.61, 5975.07,
    /// with the imitation reward per step up from 0.84 to 0.94 (seed 0),
    /// so the learner, not the reward, held those runs back; on the TRPO
    /// expert's raw mean actions (1798.1) 1673.55, 1680.83, 1579.62 ->
    /// 1706.57, 1709.81, 1695.68.
    ///
    /// RED on Walker2d discounts this way too since session 48, together
    /// with the sharper `sigma1` (see there): the discount alone (session
    /// 47) rescued the seed-1 expert's raw single trajectory but let other
    /// runs fall; both together hold on every set measured.
    pub trpo: TrpoConfig,
    /// RED's support estimator. Default: the release's RND (4 x 128 target,
    /// 1 x 128 predictor, outputs 128, 200 epochs; all widths 20 and 300
    /// epochs for Reacher) with two measured changes:
    /// - its input `[s, a]` is standardised by the expert pairs' mean and
    ///   standard deviation (the release feeds raw values). The release's
    ///   networks have zero biases and leaky ReLUs, so on raw input the
    ///   target and a trained predictor both stay near 0 around the origin:
    ///   a still HalfCheetah (all zeros) scored reward 0.78 (width 20) with sigma1
    ///   calibrated on the expert, 0.20 with standardised input. RED on
    ///   Walker2d at 5M: 1156 (22.9% of the expert) raw, 3881 (76.8%)
    ///   standardised;
    /// - HalfCheetah uses width 128 like Hopper, Walker2d and Ant (the
    ///   release: 20). Measured at 1M steps, standardised input, seed 0:
    ///   width 20 -152, width 128 625 (both with the release's warm start);
    /// - HalfCheetah's target draws its hidden biases from U(-1, 1)
    ///   (`target_bias` 1; zero elsewhere, as in the release). Standardising
    ///   moves the origin to the expert pairs' mean, and a fast periodic
    ///   gait circles that mean: on the demos of a SAC expert (6935) a
    ///   still HalfCheetah held near the mean scored 0.882 per step against
    ///   0.870 for a 4100-return run (0.751 against 0.833 with biases of
    ///   1), and RED's final policy stood still on seed 0 (-11.6). RED's
    ///   final policy over seeds 0-2 at 2M, zero biases -> U(-1, 1): SAC
    ///   demos -11.6, 4177.0, 1508.8 -> 3242.1, 4609.6, 3322.9; the
    ///   project's TRPO demos (1750) 1522.1, 1549.0, 1532.0 -> 1574.5,
    ///   1568.4, 1607.4; one trajectory of them (1732.6) 1336.8, 1269.2,
    ///   1408.1 -> 1537.4, 1422.7, 1487.0. U(-3, 3) did more on the SAC
    ///   demos (mean 3927) but wrecked the single trajectory (-209 to 62;
    ///   its σ1, calibrated on held-out scores, fell from 324 to 57).
    ///   docs/results/mujoco.md, session 30;
    /// - RED on Reacher leaves out every state dimension but the fingertip's
    ///   offset from the target (`ignored_state_dims`,
    ///   [`REACHER_RED_IGNORED_DIMS`], since session 51, with the time
    ///   feature).
    pub rnd: RndConfig,
    /// The AE baseline's autoencoder. Default: the release's hidden width
    /// (30 Hopper, Walker2d, HalfCheetah; 100 Reacher; 128 Ant).
    pub autoencoder: AutoencoderConfig,
    /// How `sigma1` of `exp(-sigma1 L)` is set for `red` and `ae`. Default:
    /// calibrated on the expert pairs so that their 0.9 quantile score gets
    /// reward 0.9 (the paper: expert rewards "mostly close to 1"). Measured
    /// reason: the release's hand-set values ([`RunConfig::release_sigma1`],
    /// e.g. 250000 for RED on Hopper) were tuned to its own demos; on our
    /// Hopper expert's demos the fitted RND scores are ~5e-5, so 250000
    /// gives the expert pairs a mean reward of 0.018 and a RED run learned
    /// nothing in 200k steps (imitation reward ~0). `{"fixed": 250000}`
    /// restores the release's value. RED on Ant is calibrated sharper: the
    /// 0.9 quantile gets reward 0.5. Measured reason (demos of the expert
    /// trained to 5M, log-std -2, 5M steps): with reward 0.9 a still or
    /// slow ant scored nearly as well as the expert (imitation reward
    /// 0.81-0.91 per step while walking or standing) and two of three seeds
    /// left the cloned gait (seed 1 stood still: 454.68 at 1.47M; seed 2
    /// slowed after 2.3M and ended at 859.98); seed 0 ended at 3668.34.
    /// With reward 0.5: seed 0 3755.45, seed 1 3890.00 (expert 3630.28).
    /// RED on HalfCheetah is calibrated the same way since session 48
    /// (with its new discount, see `trpo`; docs/results/mujoco.md, "Session
    /// 48"): on the SAC expert's demos (6935.2), 2M steps, seeds 0-2,
    /// 5630.50, 6034.61, 5975.07 -> 6574.10, 6278.12, 6479.62; on four kinds
    /// of TRPO-expert demos (mean actions clipped and raw, sampled raw, one
    /// trajectory; 12 runs) -14 to +30 against reward 0.9, every run at
    /// 90.6% of its set's return or more. RED on Walker2d since session 48
    /// as well, with the discount above: the seed-1 expert's raw single
    /// trajectory (4216.3), seeds 0-1, 2599.70, 1209.55 -> 4237.57,
    /// 4150.09; at 5M from the table expert's demos, seeds 0-2, 4631.1,
    /// 5474.8, 5531.7 -> 5565.15, 5442.38, 5548.00.
    pub sigma1: Sigma1,
    /// Whether the imitation reward sees actions clipped to the task's
    /// action space: the demonstrations' actions are clipped before the
    /// reward is fitted (and `sigma1` calibrated), and the policy's sampled
    /// actions before they are scored, as the environment executes them.
    /// Default: true for RED on Hopper (since session 27), false otherwise
    /// (the reward sees the demonstrations' actions as stored and the
    /// policy's unclipped draws). Measured (RED on Hopper, 2M steps, seeds
    /// 0-2, final policy, docs/results/mujoco.md "Session 27"): on four
    /// demo sets (two experts, actions stored clipped or raw) 11 of 12 runs
    /// reach 90% of the demos' return with it against 9 of 12 without, mean
    /// 3427.6 against 3295.3; on raw demos (40.5% of the action entries
    /// outside [-1, 1]) 3547.58, 3466.41, 3499.48 against 3586.55, 2579.05,
    /// 3124.60. On Walker2d (a 4262 expert's clipped and raw demos, seeds
    /// 0-1) 4189.12, 3593.62, 4174.93, 3121.73 with it against 4215.13,
    /// 4248.34, 4298.06, 4100.76 without: not needed there, so not its
    /// default; HalfCheetah, Ant and Reacher were not measured. A `config.json` without the
    /// field (written before session 25) reads as false, as it ran.
    #[serde(default)]
    pub reward_clips_actions: bool,
    /// GAIL's discriminator (OpenAI baselines' settings).
    pub gail: GailConfig,
    /// GMMIL's kernels (the release's median rule).
    pub gmmil: GmmilConfig,
    /// Behaviour cloning, for the `bc` method and the warm start. Default:
    /// the release's Adam 3e-4, batch 128.
    pub bc: BcConfig,
    /// Epochs of the behaviour-cloning warm start before TRPO; 0 for none.
    /// Default: 100 for `red` on HalfCheetah, Ant (the paper warm-starts
    /// these two), Walker2d, Hopper and Reacher (our additions), as the `bc` method: cloning
    /// until its loss flattens; as the release, 20 and 10 on HalfCheetah and
    /// Ant for `ae`; none elsewhere (the paper: GAIL and GMMIL start from a
    /// random policy). Measured on HalfCheetah at 1M steps (RED, width 128,
    /// standardised input, seed 0): warm start 20 and log-std 0: 625; 100
    /// and 0: 1365; 20 and -1: 1472; 100 and -1: 1631. Walker2d at 5M: no
    /// warm start 3881 (76.8% of the expert), warm start 5099 (100.9%).
    /// Hopper (issue 21, 2M steps; 4 deterministic demos of a second
    /// expert, 3682 per episode): without a warm start the policy's std
    /// shrinks within 150k steps onto a hop that falls after ~100 steps
    /// (imitation reward ~0.7 per step) and the run leaves it late or not
    /// at all: seeds 0-2 ended at 532.92, 2860.39, 1514.29 with the demo
    /// actions clipped and 1602.77, 2077.62, 3059.81 stored raw; with the
    /// warm start 3603.68, 3319.41, 3170.38 and 3586.55, 2579.05, 3124.60
    /// (BC alone, seed 0: 2146.55 and 2415.84); the project's own demos
    /// 3202.38 without, 3355.82 with (seed 0). See docs/results/mujoco.md,
    /// "RED on demos with raw actions: diagnosis (session 25)". Reacher
    /// (session 31, 2M steps, mean of seeds 0-2): the TRPO expert's demos
    /// -9.78 without (log-std 0), -6.22 with (100 epochs, log-std -1); a
    /// SAC expert's mean-action demos -10.45 and -8.75; its sampled ones
    /// -11.37 and -10.56. SAC runs have none (they start from a random
    /// policy).
    pub bc_warm_start_epochs: usize,
    /// The number of demonstration pairs the epochs of the reward's fit
    /// (`rnd.epochs`, `autoencoder.epochs`) and of the warm start
    /// (`bc_warm_start_epochs`) are set for; 0 turns the scaling off. A
    /// demonstration of fewer pairs is gone through more often, so that
    /// the fit and the warm start take about as many Adam steps as on this
    /// many pairs: the epochs are multiplied by this number over the
    /// demonstration's pairs, rounded to the nearest whole number (so a
    /// set with at least two thirds of the pairs keeps its epochs).
    /// Default: 4 x the task's time limit for `red` (the paper's four
    /// trajectories: 4000 pairs, Reacher 200), so one trajectory of 1000
    /// steps gets 400 warm-start and 800 RND epochs; 0 for the other
    /// methods (not measured). Measured reason (session 49,
    /// docs/results/mujoco.md): RED on HalfCheetah from one trajectory of
    /// the SAC expert (6819.4), 2M steps, seeds 0-2: 4281.58, 5013.82,
    /// 3592.94 unscaled, 6030.92, 6112.01, 6052.18 scaled (88-90%); the
    /// reward fitted on that trajectory already ranked the other three
    /// expert episodes (0.654 per step) and a 6531-return policy (0.679)
    /// above the unscaled runs' policies (0.579 and 0.386): the warm start
    /// with a quarter of the steps, not the reward, held them back. A
    /// `config.json` without the field (written before session 49) reads
    /// as 0, as it ran; 0 is not written, so the settings saved in such a
    /// run's checkpoint still match when it is resumed.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub epochs_reference_pairs: usize,
    /// Whether RED's reward leaves out the demonstrations' context: the
    /// state dimensions constant within every trajectory but not the same
    /// in all ([`Demos::context_dims`], e.g. Reacher's target). They read
    /// as 0 in the RND's input (added to `rnd.ignored_state_dims`). A few
    /// trajectories show a few values of a context, so every new episode's
    /// context is off their support whatever the agent does. Default:
    /// false. Measured (session 50, docs/results/mujoco.md): on the SAC
    /// Reacher expert's mean-action and sampled demos, 2M steps, seeds 0-2,
    /// -7.97, -8.93, -9.95 and -9.04, -9.83, -12.17 against the default's
    /// -7.79, -9.33, -8.99 and -10.56, -9.91, -11.06: not a change. A
    /// `config.json` without the field reads as false; false is not
    /// written, so older checkpoints resume.
    #[serde(default, skip_serializing_if = "is_false")]
    pub reward_ignores_context: bool,
    /// Whether every observation ends with the time feature: the episode's
    /// steps over the task's time limit, 0 at the reset
    /// ([`WatchedEnv::with_time_feature`]; the demonstrations get the same
    /// column from their step in the trajectory, [`Demos::with_time_feature`]).
    /// The policy, the value function and RED's reward all see it. Our
    /// addition (the paper's states have no time): for a task whose
    /// episodes always run to the limit, such as Reacher, it lets the
    /// reward tell reaching the target early from late. Default: true for
    /// RED on Reacher (since session 51, with [`REACHER_RED_IGNORED_DIMS`];
    /// the measurements are there), false otherwise. A `config.json`
    /// without the field reads as false; false is not written, so older
    /// checkpoints resume.
    #[serde(default, skip_serializing_if = "is_false")]
    pub time_feature: bool,
    /// Epochs of the `bc` method. Default 100 (our choice: the release does
    /// not report BC alone on MuJoCo; 100 epochs over 4000 pairs is about
    /// 3,100 Adam steps, where the training loss has flattened).
    pub bc_epochs: usize,
    /// Whether the observation normaliser is frozen at the expert
    /// observations' statistics. Default: true for `red`, `ae` and `bc`
    /// (the release, for RED and AE), false (running statistics) otherwise.
    pub freeze_obs_norm_from_demo: bool,
    /// Iterations between checkpoints. Default 50 (about 51,000 steps).
    pub checkpoint_every: u64,
    /// Episodes of each final evaluation. Default 50 (the paper).
    pub eval_episodes: usize,
    /// Training episodes averaged for the best-checkpoint rule. Default 40
    /// (the release).
    pub best_window: usize,
    /// Trajectories written to the demo file of an `expert` run. Default 4
    /// (the paper).
    pub demo_trajectories: usize,
    /// Which learner trains the policy. Default `trpo` (the paper's); `sac`
    /// (Soft Actor-Critic, our addition) trains `expert` runs on the true
    /// reward and `red` and `ae` runs on their fitted rewards (the
    /// adaptive rewards of GAIL and GMMIL train with TRPO). A `config.json`
    /// without the field (written before session 29) reads as `trpo`.
    #[serde(default)]
    pub learner: MujocoLearner,
    /// SAC's settings, used when `learner` is `sac`.
    #[serde(default)]
    pub sac: SacRunConfig,
}

/// For `skip_serializing_if`: a setting whose 0 is what a file without it
/// means.
fn is_zero(v: &usize) -> bool {
    *v == 0
}

fn is_false(v: &bool) -> bool {
    !*v
}

/// The learner of a MuJoCo run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MujocoLearner {
    /// TRPO (Schulman et al. 2015), the paper's.
    #[default]
    Trpo,
    /// Soft Actor-Critic (Haarnoja et al. 2018), for experts.
    Sac,
}

impl std::str::FromStr for MujocoLearner {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "trpo" => Ok(Self::Trpo),
            "sac" => Ok(Self::Sac),
            _ => Err(format!("unknown learner `{s}` (trpo or sac)")),
        }
    }
}

/// SAC's settings for a MuJoCo expert: the library's (Haarnoja et al.
/// 2018b, Table 1: two hidden layers of 256, Adam 3e-4, batch 256, replay
/// 1e6, tau 0.005, gamma 0.99, automatic temperature with target entropy
/// `-dim(A)`), with 10,000 uniform-action steps before the first update
/// (`random_steps` and `learning_starts`: the authors' softlearning code and
/// stable-baselines3's MuJoCo settings start this way).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SacRunConfig {
    /// The learner's settings.
    pub learner: SacConfig,
    /// The actor: a tanh-squashed Gaussian with a state-dependent log-std
    /// (`squash` is forced on). Default two hidden layers of 256, ReLU.
    pub policy: GaussianPolicyConfig,
    /// Environment steps between checkpoints. Default 100,000. A checkpoint
    /// holds the whole replay (about 0.9 KB per HalfCheetah step as JSON).
    pub checkpoint_steps: u64,
}

impl Default for SacRunConfig {
    fn default() -> Self {
        Self {
            learner: SacConfig {
                random_steps: 10_000,
                learning_starts: 10_000,
                ..SacConfig::default()
            },
            policy: GaussianPolicyConfig {
                hidden: vec![256, 256],
                activation: red_nets::Activation::Relu,
                squash: true,
                ..GaussianPolicyConfig::default()
            },
            checkpoint_steps: 100_000,
        }
    }
}

/// Environment steps of a run trained with SAC (an expert, `red` or `ae`)
/// unless set (`RunFlags::learner`): 1,000,000, where SAC's published MuJoCo curves
/// are reported (Haarnoja et al. 2018b, Fig. 1).
pub const SAC_EXPERT_STEPS: u64 = 1_000_000;

impl Default for RunConfig {
    fn default() -> Self {
        Self::for_task(EnvId::Hopper, Method::Red)
    }
}

impl RunConfig {
    /// Environment steps of one iteration: a TRPO batch; SAC has no
    /// batches, so its iteration is 1,000 steps (for `stop_after`-style
    /// counts).
    pub fn iteration_steps(&self) -> u64 {
        match self.learner {
            MujocoLearner::Trpo => self.trpo.steps_per_batch as u64,
            MujocoLearner::Sac => 1_000,
        }
    }

    /// The defaults for `method` on `env` (see each field).
    pub fn for_task(env: EnvId, method: Method) -> Self {
        let mut trpo = TrpoConfig::default();
        if env == EnvId::Reacher {
            trpo.gae.gamma = 0.99;
        }
        let w = if env == EnvId::Reacher { 20 } else { 128 };
        let rnd = RndConfig {
            target_hidden: vec![w; 4],
            predictor_hidden: vec![w],
            output: w,
            epochs: if env == EnvId::Reacher { 300 } else { 200 },
            standardize: true,
            target_bias: if env == EnvId::HalfCheetah { 1.0 } else { 0.0 },
            ignored_state_dims: if (method, env) == (Method::Red, EnvId::Reacher) {
                REACHER_RED_IGNORED_DIMS.to_vec()
            } else {
                Vec::new()
            },
            ..RndConfig::default()
        };
        let autoencoder = AutoencoderConfig {
            hidden: match env {
                EnvId::Reacher => 100,
                EnvId::Ant => 128,
                _ => 30,
            },
            ..AutoencoderConfig::default()
        };
        let bc_warm_start_epochs = match (method, env) {
            (Method::Red, _) => 100,
            (Method::Ae, EnvId::HalfCheetah) => 20,
            (Method::Ae, EnvId::Ant) => 10,
            _ => 0,
        };
        if method == Method::Red && bc_warm_start_epochs > 0 {
            trpo.policy.init_log_std = if env == EnvId::Ant { -2.0 } else { -1.0 };
        }
        if method == Method::Red
            && matches!(env, EnvId::Hopper | EnvId::HalfCheetah | EnvId::Walker2d)
        {
            trpo.gae = GaeConfig {
                gamma: 0.99,
                lambda: 0.98,
                bootstrap_on_truncation: true,
            };
        }
        Self {
            env,
            method,
            seed: 0,
            steps: if method == Method::Expert {
                5_000_000
            } else {
                2_000_000
            },
            demo: None,
            trpo,
            rnd,
            autoencoder,
            sigma1: if method == Method::Red
                && matches!(env, EnvId::Ant | EnvId::HalfCheetah | EnvId::Walker2d)
            {
                Sigma1::Calibrated {
                    quantile: 0.9,
                    reward: 0.5,
                }
            } else {
                RedRewardConfig::default().sigma1
            },
            reward_clips_actions: (method, env) == (Method::Red, EnvId::Hopper),
            gail: GailConfig::default(),
            gmmil: GmmilConfig::default(),
            bc: BcConfig::default(),
            bc_warm_start_epochs,
            epochs_reference_pairs: if method == Method::Red {
                4 * env.max_episode_steps()
            } else {
                0
            },
            reward_ignores_context: false,
            time_feature: (method, env) == (Method::Red, EnvId::Reacher),
            bc_epochs: 100,
            freeze_obs_norm_from_demo: matches!(method, Method::Red | Method::Ae | Method::Bc),
            checkpoint_every: 50,
            eval_episodes: 50,
            best_window: 40,
            demo_trajectories: 4,
            learner: MujocoLearner::Trpo,
            sac: SacRunConfig::default(),
        }
    }

    /// The release's hand-set `sigma1` for `method` on `env` (RED: 250000
    /// Hopper, Walker2d, Ant; 25000 HalfCheetah; 2500 Reacher. AE: 1000
    /// Hopper, HalfCheetah, Reacher; 100 Walker2d, Ant).
    pub fn release_sigma1(env: EnvId, method: Method) -> f64 {
        match (method, env) {
            (Method::Ae, EnvId::Walker2d | EnvId::Ant) => 100.0,
            (Method::Ae, _) => 1000.0,
            (_, EnvId::HalfCheetah) => 25_000.0,
            (_, EnvId::Reacher) => 2_500.0,
            _ => 250_000.0,
        }
    }

    /// Checks every field.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the first bad field.
    pub fn validate(&self) -> Result<()> {
        let field = |name: &str, r: std::result::Result<(), String>| -> Result<()> {
            r.map_err(|reason| Error::InvalidConfig {
                field: name.into(),
                reason,
            })
        };
        field("trpo", self.trpo.validate().map_err(|e| e.to_string()))?;
        field("rnd", self.rnd.validate().map_err(|e| e.to_string()))?;
        field(
            "autoencoder",
            self.autoencoder.validate().map_err(|e| e.to_string()),
        )?;
        field("gail", self.gail.validate().map_err(|e| e.to_string()))?;
        field("gmmil", self.gmmil.validate().map_err(|e| e.to_string()))?;
        field("bc", self.bc.validate().map_err(|e| e.to_string()))?;
        let positive = |name: &str, v: u64| {
            field(
                name,
                if v == 0 {
                    Err("must be at least 1".into())
                } else {
                    Ok(())
                },
            )
        };
        if self.reward_ignores_context && self.method != Method::Red {
            field(
                "reward_ignores_context",
                Err(format!(
                    "leaves the context out of RED's RND only; method `{}` does not use it \
                     (remove the field)",
                    self.method.name()
                )),
            )?;
        }
        if self.time_feature
            && self.learner == MujocoLearner::Trpo
            && self.trpo.gae.bootstrap_on_truncation
        {
            field(
                "time_feature",
                Err(
                    "with the time in the state nothing follows the time limit, but \
                     trpo.gae.bootstrap_on_truncation carries the value past it: set it to false"
                        .into(),
                ),
            )?;
        }
        if self.method != Method::Bc {
            positive("steps", self.steps)?;
        } else {
            positive("bc_epochs", self.bc_epochs as u64)?;
        }
        positive("checkpoint_every", self.checkpoint_every)?;
        positive("eval_episodes", self.eval_episodes as u64)?;
        positive("best_window", self.best_window as u64)?;
        if self.method == Method::Expert {
            positive("demo_trajectories", self.demo_trajectories as u64)?;
        }
        field(
            "sigma1",
            RedRewardConfig {
                sigma1: self.sigma1,
            }
            .validate()
            .map_err(|e| e.to_string()),
        )?;
        if self.learner == MujocoLearner::Sac {
            if !matches!(self.method, Method::Expert | Method::Red | Method::Ae) {
                return Err(Error::InvalidConfig {
                    field: "learner".into(),
                    reason: format!(
                        "SAC trains experts and the fixed rewards of `red` and `ae`; `{}` trains with TRPO: set learner to trpo",
                        self.method.name()
                    ),
                });
            }
            if self.bc_warm_start_epochs > 0 {
                return Err(Error::InvalidConfig {
                    field: "bc_warm_start_epochs".into(),
                    reason: "SAC starts from a random policy (its 10,000 uniform-action steps); the behaviour-cloning warm start is TRPO's: set it to 0".into(),
                });
            }
            field(
                "sac.learner",
                self.sac.learner.validate().map_err(|e| e.to_string()),
            )?;
            field(
                "sac.policy",
                self.sac.policy.validate().map_err(|e| e.to_string()),
            )?;
            positive("sac.checkpoint_steps", self.sac.checkpoint_steps)?;
        }
        if self.method.needs_demo() && self.demo.is_none() {
            return Err(Error::InvalidConfig {
                field: "demo".into(),
                reason: format!(
                    "method `{}` needs a demonstration file (--demo)",
                    self.method.name()
                ),
            });
        }
        Ok(())
    }

    /// The settings a run fits its imitation reward with
    /// ([`crate::imitation::fit_reward`]; `σ1` from in-sample expert scores).
    pub fn reward_settings(&self) -> RewardSettings<'_> {
        RewardSettings {
            rnd: &self.rnd,
            kernel_pca: None,
            autoencoder: &self.autoencoder,
            sigma1: self.sigma1,
            scores: ExpertScores::InSample,
            gail: &self.gail,
            gmmil: &self.gmmil,
        }
    }

    /// How many times the epochs of the reward's fit and of the warm start
    /// are multiplied for a demonstration of `pairs` pairs (see
    /// [`RunConfig::epochs_reference_pairs`]): 1 when the scaling is off or
    /// the demonstration holds at least two thirds of the reference.
    pub fn epochs_factor(&self, pairs: usize) -> usize {
        if self.epochs_reference_pairs == 0 || pairs == 0 {
            return 1;
        }
        ((self.epochs_reference_pairs as f64 / pairs as f64).round() as usize).max(1)
    }

    /// These settings with the epochs of the reward's fit and of the warm
    /// start multiplied by [`RunConfig::epochs_factor`] for `pairs`.
    pub fn scaled_for_pairs(&self, pairs: usize) -> RunConfig {
        let k = self.epochs_factor(pairs);
        let mut c = self.clone();
        c.rnd.epochs *= k;
        c.autoencoder.epochs *= k;
        c.bc_warm_start_epochs *= k;
        c
    }

    /// The settings the imitation reward is fitted with on `pairs` pairs
    /// whose context dimensions are `context` ([`Demos::context_dims`]):
    /// the epochs scaled ([`RunConfig::scaled_for_pairs`]) and, with
    /// [`RunConfig::reward_ignores_context`], `context` added to
    /// `rnd.ignored_state_dims`.
    pub fn reward_fit_config(&self, pairs: usize, context: &[usize]) -> RunConfig {
        let mut c = self.scaled_for_pairs(pairs);
        if self.reward_ignores_context {
            c.rnd.ignored_state_dims.extend_from_slice(context);
            c.rnd.ignored_state_dims.sort_unstable();
            c.rnd.ignored_state_dims.dedup();
        }
        c
    }

    /// These settings overwritten by the fields of the JSON object `json`
    /// (part of a `config.json`, read from `source`; nested objects are
    /// merged field by field, so missing fields keep their values; unknown
    /// fields are refused). A whole run's `config.json` (one that names
    /// `env` and `method`) is read as that run's settings, as a resume reads
    /// it: a field it does not write (false, 0 or empty) is that value, not
    /// these settings' (a Reacher RED run of before session 51 keeps its
    /// plain observations).
    ///
    /// # Errors
    /// [`Error::Input`] naming `source` for text that is not JSON, an unknown
    /// field, or another task or method than these settings'.
    pub fn with_overrides(self, json: &str, source: &Path) -> Result<Self> {
        let (env, method) = (self.env, self.method);
        let whole = serde_json::from_str::<serde_json::Value>(json.trim_start_matches('\u{feff}'))
            .ok()
            .is_some_and(|v| v.get("env").is_some() && v.get("method").is_some());
        let cfg = if whole {
            crate::run_dir::parse_json::<RunConfig>(json, source)?
        } else {
            crate::run_dir::overlay_json(&self, json, source)?
        };
        if cfg.env != env || cfg.method != method {
            return Err(Error::Input {
                path: source.to_path_buf(),
                reason: "sets another task or method than the command line".into(),
            });
        }
        Ok(cfg)
    }
}

/// The best mean true return of the last `best_window` training episodes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct BestRecord {
    pub(super) mean_true_return: f64,
    pub(super) env_steps: u64,
    /// TRPO's iteration; with SAC, the training episode's number.
    pub(super) iteration: u64,
}

/// Everything a run needs to continue exactly where it stopped.
#[derive(Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RunState {
    trainer: TrpoTrainer,
    reward: Option<ImitationReward>,
    /// True returns of the last `best_window` training episodes.
    recent: VecDeque<f64>,
    best: Option<BestRecord>,
    /// MuJoCo warnings counted so far, by MuJoCo's warning index.
    mujoco_warnings: [u64; MJ_N_WARNING],
    /// Wall time spent in earlier sessions of the run.
    wall_s: f64,
}

/// [`RunState`] written from its parts while the trainer trains.
#[derive(Serialize)]
struct RunStateRef<'a> {
    trainer: &'a TrpoTrainer,
    reward: Option<&'a ImitationReward>,
    recent: &'a VecDeque<f64>,
    best: &'a Option<BestRecord>,
    mujoco_warnings: &'a [u64; MJ_N_WARNING],
    wall_s: f64,
}

/// How a call to [`super::launch::run`] ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Trained, evaluated, outputs written.
    Finished,
    /// Stopped on request (the stop flag) after saving a checkpoint; [`super::launch::run`]
    /// with `resume` continues.
    Interrupted,
}

/// One evaluation in `eval.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct EvalSummary {
    /// Which policy: `final` or `best checkpoint (by training true return)`.
    pub protocol: String,
    /// Environment steps the policy was trained for.
    pub env_steps: u64,
    /// Mean true return over the episodes.
    pub mean: f64,
    /// Standard deviation (population) over the episodes.
    pub std: f64,
    /// Mean episode length.
    pub mean_length: f64,
    /// Every episode's true return.
    pub returns: Vec<f64>,
}

impl EvalSummary {
    fn new(protocol: &str, env_steps: u64, r: &EvalReport) -> Self {
        Self {
            protocol: protocol.into(),
            env_steps,
            mean: r.mean_return(),
            std: r.std_return(),
            mean_length: r.mean_length(),
            returns: r.returns.clone(),
        }
    }
}

/// `eval.json` of a finished run.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct EvalFile {
    /// The task (`Hopper-v5`, ...).
    pub env: String,
    /// The method's name.
    pub method: String,
    /// The run's seed.
    pub seed: u64,
    /// Episodes per evaluation (deterministic actions, true reward).
    pub episodes: usize,
    /// The final policy.
    pub final_policy: EvalSummary,
    /// The best checkpoint by the mean true return of the last
    /// `best_window` training episodes (the paper's protocol); `None` for
    /// `bc`.
    pub best_checkpoint: Option<EvalSummary>,
    /// Mean true return of the demonstrations the run learned from.
    pub demo_mean_return: Option<f64>,
    /// Mean imitation reward per step of the demonstrations (`red`, `ae`).
    pub demo_mean_imitation_reward: Option<f64>,
    /// MuJoCo warnings during training.
    pub mujoco_warnings: u64,
    /// Wall time of the whole run, all sessions, in seconds.
    pub wall_s: f64,
    /// For `expert` runs: which policy became the expert.
    pub expert_choice: Option<String>,
    /// For `expert` runs: true returns of the recorded demonstrations.
    pub demo_returns: Option<Vec<f64>>,
}

impl EvalFile {
    /// A few lines for people: both evaluations, the expert's choice and
    /// demonstrations, MuJoCo warnings, wall time, and where the run's
    /// folder `dir` is.
    pub fn summary(&self, dir: &Path) -> String {
        let mut s = format!(
            "{} {} seed {} ({} episodes, deterministic actions, true reward):\n",
            self.env, self.method, self.seed, self.episodes
        );
        let f = &self.final_policy;
        s.push_str(&format!(
            "  final policy ({} env steps): {:.2} +- {:.2} (mean length {:.0})\n",
            f.env_steps, f.mean, f.std, f.mean_length
        ));
        if let Some(b) = &self.best_checkpoint {
            s.push_str(&format!(
                "  best checkpoint by training true return ({} env steps): {:.2} +- {:.2}\n",
                b.env_steps, b.mean, b.std
            ));
        }
        if let Some(r) = &self.demo_returns {
            s.push_str(&format!(
                "  expert: {}; demonstrations written ({} trajectories, returns {})\n",
                self.expert_choice.as_deref().unwrap_or("-"),
                r.len(),
                r.iter()
                    .map(|x| format!("{x:.1}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
        if self.mujoco_warnings > 0 {
            s.push_str(&format!(
                "  MuJoCo warnings during training: {}\n",
                self.mujoco_warnings
            ));
        }
        s.push_str(&format!(
            "  wall time {:.0} s; outputs in {}\n",
            self.wall_s,
            dir.display()
        ));
        s
    }
}

/// Reads the demonstration file and checks it fits `env`.
///
/// # Errors
/// An unreadable or invalid file, or one of another task.
pub fn load_demos(path: &Path, env: EnvId) -> Result<Demos> {
    let demos = Demos::read(path).with_context(|| format!("reading {}", path.display()))?;
    let probe = WatchedEnv::new(env).with_context(|| format!("cannot build {env}"))?;
    let (od, ad) = (probe.observation_space().dim(), probe.action_space().dim());
    let bad = |reason: String| Error::Input {
        path: path.to_path_buf(),
        reason,
    };
    if demos.env_id != env.name() {
        return Err(bad(format!(
            "holds demonstrations of `{}`, not `{}`",
            demos.env_id,
            env.name()
        )));
    }
    if demos.obs_dim != od || demos.act_dim != ad {
        return Err(bad(format!(
            "has observations of {} and actions of {} numbers; {} has {od} and {ad}",
            demos.obs_dim,
            demos.act_dim,
            env.name()
        )));
    }
    if demos.num_pairs() < 2 {
        return Err(bad("has fewer than 2 state-action pairs".into()));
    }
    Ok(demos)
}

/// The run's task as its policy sees it: with the time feature when
/// [`RunConfig::time_feature`] is set.
///
/// # Errors
/// The model cannot be loaded.
pub fn run_env(cfg: &RunConfig) -> Result<WatchedEnv> {
    WatchedEnv::with_time_feature(cfg.env, cfg.time_feature)
        .with_context(|| format!("cannot build {}", cfg.env))
}

/// Reads the demonstration file as [`load_demos`] and gives its states the
/// time feature when [`RunConfig::time_feature`] is set.
///
/// # Errors
/// As [`load_demos`], or a trajectory longer than the task's time limit.
pub fn load_run_demos(path: &Path, cfg: &RunConfig) -> Result<Demos> {
    let demos = load_demos(path, cfg.env)?;
    if !cfg.time_feature {
        return Ok(demos);
    }
    demos
        .with_time_feature(cfg.env.max_episode_steps())
        .map_err(|e| Error::Input {
            path: path.to_path_buf(),
            reason: format!(
                "does not fit the time feature ({e}): give demonstrations recorded under {}'s \
                 time limit of {} steps, or set `time_feature` to false",
                cfg.env,
                cfg.env.max_episode_steps()
            ),
        })
}

/// The task as `policy` was trained on it: with the time feature
/// ([`RunConfig::time_feature`]) when the policy reads one number more than
/// the task's observations.
///
/// # Errors
/// The model cannot be loaded, or the policy's input fits neither.
pub fn policy_env(id: EnvId, policy: &GaussianPolicy) -> Result<WatchedEnv> {
    let plain = WatchedEnv::new(id).with_context(|| format!("cannot build {id}"))?;
    let od = plain.observation_space().dim();
    match policy.obs_dim() {
        d if d == od => Ok(plain),
        d if d == od + 1 => Ok(WatchedEnv::with_time_feature(id, true)?),
        d => Err(Error::InvalidConfig {
            field: "policy".into(),
            reason: format!(
                "the policy reads {d} numbers; {id} has {od} (or {} with the time feature)",
                od + 1
            ),
        }),
    }
}

/// Reads a run folder's `config.json`.
///
/// # Errors
/// Missing, unreadable or invalid file.
pub fn read_config(dir: &Path) -> Result<RunConfig> {
    let p = dir.join("config.json");
    let text = std::fs::read_to_string(&p).map_err(|e| Error::Input {
        path: p.clone(),
        reason: format!("cannot read it ({e}); is {} a run folder?", dir.display()),
    })?;
    let cfg: RunConfig = crate::run_dir::parse_json(&text, &p)?;
    cfg.validate()
        .with_context(|| format!("checking {}", p.display()))?;
    Ok(cfg)
}

/// Reads a run folder's `eval.json`, if the run finished.
pub fn read_eval(dir: &Path) -> Option<EvalFile> {
    let text = std::fs::read_to_string(dir.join("eval.json")).ok()?;
    serde_json::from_str(&text).ok()
}

const METRICS_HEADER: &str = "iteration,env_steps,episodes,mean_true_return,true_return_window,mean_imitation_reward,mean_true_reward,policy_loss,value_loss,kl,entropy,backtracks,step_accepted,mujoco_warnings,wall_s";

fn fmt_opt(v: Option<f64>) -> String {
    v.map_or(String::new(), num)
}

/// `x` as the shortest text that reads back to it: plain decimals as
/// before, but with an exponent below 1e-5 and from 1e16 in size (a mean
/// reward of 1e-300 would otherwise take 300 digits).
pub(super) fn num(x: f64) -> String {
    if x != 0.0 && x.is_finite() && !(1e-5..1e16).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

fn metrics_row(m: &IterationMetrics, window: Option<f64>, warnings: u64, wall_s: f64) -> String {
    format!(
        "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{:.3}\n",
        m.iteration,
        m.env_steps,
        m.true_returns.len(),
        fmt_opt(m.mean_true_return),
        fmt_opt(window),
        fmt_opt(m.mean_imitation_reward),
        num(m.mean_true_reward),
        num(m.policy_loss),
        num(m.value_loss),
        num(m.kl),
        num(m.entropy),
        m.backtracks,
        m.step_accepted,
        warnings,
        wall_s
    )
}

/// Keeps the header and the rows of iterations up to `iteration` (the rows
/// written after the checkpoint a run resumes from are dropped).
fn truncate_metrics(path: &Path, iteration: u64) -> Result<String> {
    let mut kept = format!("{METRICS_HEADER}\n");
    if let Ok(f) = std::fs::File::open(path) {
        for line in std::io::BufReader::new(f).lines().skip(1) {
            let line = line.map_err(|source| Error::Io {
                path: path.to_path_buf(),
                source,
            })?;
            let it: Option<u64> = line.split(',').next().and_then(|s| s.parse().ok());
            if it.is_some_and(|i| i <= iteration) {
                kept.push_str(&line);
                kept.push('\n');
            }
        }
    }
    write_atomic(path, kept.as_bytes())?;
    Ok(kept)
}

pub(super) fn save_policy(path: &Path, policy: &GaussianPolicy) -> Result<()> {
    write_atomic(path, policy.to_json()?.as_bytes())?;
    Ok(())
}

/// Builds the fresh state of a run: the reward model (fitted once), the
/// policy's normaliser and warm start.
fn fresh_state(
    cfg: &RunConfig,
    demos: Option<&Demos>,
    obs_dim: usize,
    action_box: &BoxSpace,
) -> Result<RunState> {
    let act_dim = action_box.dim();
    let seeder = Seeder::new(cfg.seed);
    let pairs = demos.map(|d| d.pairs());
    let reward_pairs = demos
        .map(|d| reward_pairs(cfg, d, action_box))
        .transpose()?;
    let normalizer = match (&pairs, cfg.freeze_obs_norm_from_demo) {
        (Some((es, _)), true) => Some(ObsNormalizer::from_data(
            es.view(),
            cfg.trpo.obs_clip,
            cfg.trpo.obs_min_std,
        )?),
        _ => None,
    };
    let mut trainer = TrpoTrainer::new(cfg.trpo.clone(), obs_dim, act_dim, normalizer, cfg.seed)?;
    let reward = match &reward_pairs {
        None if cfg.method.needs_demo() && cfg.method != Method::Bc => {
            return Err(Error::InvalidConfig {
                field: "demo".into(),
                reason: format!("method `{}` needs demonstrations", cfg.method.name()),
            });
        }
        None => None,
        Some((es, ea)) => {
            let context = demos.map(Demos::context_dims).unwrap_or_default();
            fit_run_reward(cfg, es, ea, &context)?
        }
    };
    if cfg.bc_warm_start_epochs > 0
        && let Some((es, ea)) = &pairs
    {
        let bc = BcConfig {
            epochs: cfg.bc_warm_start_epochs * cfg.epochs_factor(es.nrows()),
            ..cfg.bc.clone()
        };
        let mut rng = seeder.rng(Stream::Other(1));
        behavior_clone(trainer.policy_mut(), es.view(), ea.view(), &bc, &mut rng)?;
    }
    Ok(RunState {
        trainer,
        reward,
        recent: VecDeque::new(),
        best: None,
        mujoco_warnings: [0; MJ_N_WARNING],
        wall_s: 0.0,
    })
}

/// The run's imitation reward fitted on the expert pairs `es`, `ea` (from
/// [`reward_pairs`]) with the seed's estimator stream, its epochs scaled
/// for their number ([`RunConfig::scaled_for_pairs`]); `None` for `expert`
/// and `bc`.
pub(super) fn fit_run_reward(
    cfg: &RunConfig,
    es: &Array2<f64>,
    ea: &Array2<f64>,
    context: &[usize],
) -> Result<Option<ImitationReward>> {
    let seeder = Seeder::new(cfg.seed);
    let scaled = cfg.reward_fit_config(es.nrows(), context);
    let settings = scaled.reward_settings();
    let mut rng = seeder.rng(Stream::Estimator);
    let gail_seed = seeder.derive(Stream::Estimator);
    fit_reward(
        cfg.method,
        &settings,
        es.view(),
        ea.view(),
        &mut rng,
        gail_seed,
    )
}

/// The line a run prints once its RED or AE reward is fitted: σ1 and the
/// expert pairs' rewards (`None` for the other rewards).
pub(super) fn fitted_reward_note(
    cfg: &RunConfig,
    reward: &ImitationReward,
    demos: &Demos,
    action_box: &BoxSpace,
) -> Result<Option<String>> {
    let ImitationReward::Support(r) = reward else {
        return Ok(None);
    };
    let (es, ea) = reward_pairs(cfg, demos, action_box)?;
    let on = r.rewards(es.view(), ea.view())?;
    let k = cfg.epochs_factor(es.nrows());
    let mut scaled = if k > 1 {
        format!(
            " (fewer than the {} pairs of the defaults: fit and warm-start epochs x{k})",
            cfg.epochs_reference_pairs
        )
    } else {
        String::new()
    };
    // (`validate` refuses the flag for methods other than RED)
    let context = if cfg.reward_ignores_context {
        demos.context_dims()
    } else {
        Vec::new()
    };
    if !context.is_empty() {
        scaled += &format!(
            " (state dimensions {context:?} are each trajectory's constant context: left out)"
        );
    }
    Ok(Some(format!(
        "{} fitted on {} expert pairs{scaled}: sigma1 {}, expert pairs' reward mean {:.3}, min {:.3}",
        cfg.method.label(),
        es.nrows(),
        r.sigma1(),
        on.mean().unwrap_or(f64::NAN),
        on.iter().copied().fold(f64::INFINITY, f64::min)
    )))
}

/// The expert pairs the imitation reward is fitted and checked on: the
/// demonstrations' pairs, with the actions clipped into `action_box` when
/// [`RunConfig::reward_clips_actions`] is set.
pub(super) fn reward_pairs(
    cfg: &RunConfig,
    demos: &Demos,
    action_box: &BoxSpace,
) -> Result<(Array2<f64>, Array2<f64>)> {
    let (s, a) = demos.pairs();
    if cfg.reward_clips_actions {
        let a = action_box.clip_rows(a.view())?;
        Ok((s, a))
    } else {
        Ok((s, a))
    }
}

/// The task's action box (every MuJoCo task has one).
pub(super) fn action_box(env: &impl Env) -> Result<BoxSpace> {
    match env.action_space() {
        Space::Box(b) => Ok(b.clone()),
        Space::Discrete(n) => Err(Error::InvalidConfig {
            field: "env".into(),
            reason: format!("needs a box action space, got {n} discrete actions"),
        }),
    }
}

/// The run's side of TRPO's training loop ([`TrpoTrainer::train_with`]):
/// the stop flag, a row of `metrics.csv` per iteration, the best window,
/// MuJoCo's warnings and the checkpoints, which hold the trainer with
/// these.
struct RunHooks<'a> {
    cfg: &'a RunConfig,
    rd: &'a RunDir,
    stop: &'a AtomicBool,
    progress: &'a mut dyn Progress,
    session: Instant,
    /// Wall time of earlier sessions.
    wall_before: f64,
    /// `metrics.csv`, rewritten whole (atomically) after every iteration,
    /// never appended to: a failed write leaves the previous file intact.
    metrics: String,
    reward: Option<RunReward>,
    recent: VecDeque<f64>,
    best: Option<BestRecord>,
    mujoco_warnings: [u64; MJ_N_WARNING],
}

impl RunHooks<'_> {
    fn save(&mut self, trainer: &TrpoTrainer) -> Result<()> {
        self.rd.write("metrics.csv", self.metrics.as_bytes())?;
        let state = RunStateRef {
            trainer,
            reward: self.reward.as_ref().map(RunReward::model),
            recent: &self.recent,
            best: &self.best,
            mujoco_warnings: &self.mujoco_warnings,
            wall_s: self.wall_before + self.session.elapsed().as_secs_f64(),
        };
        let settings = checkpoint_settings(self.cfg);
        self.rd.save_checkpoint(CHECKPOINT_KIND, &settings, &state)
    }
}

/// The imitation reward as TRPO scores its batches: as fitted, or with
/// [`RunConfig::reward_clips_actions`] seeing the actions clipped into the
/// task's box ([`ClippedActions`]), as for the fit.
enum RunReward {
    AsFitted(ImitationReward),
    Clipped(ClippedActions<ImitationReward>),
}

impl RunReward {
    fn model(&self) -> &ImitationReward {
        match self {
            Self::AsFitted(m) => m,
            Self::Clipped(c) => c.inner(),
        }
    }

    fn as_dyn(&mut self) -> &mut dyn RewardModel {
        match self {
            Self::AsFitted(m) => m,
            Self::Clipped(c) => c,
        }
    }
}

impl TrpoHooks<WatchedEnv> for RunHooks<'_> {
    type Error = Error;

    fn before_iteration(&mut self, trainer: &TrpoTrainer) -> Result<ControlFlow<()>> {
        if !self.stop.load(Ordering::SeqCst) {
            return Ok(ControlFlow::Continue(()));
        }
        self.save(trainer)?;
        self.progress.note(&format!(
            "stopped at env step {} (iteration {}); checkpoint saved in {}",
            trainer.env_steps(),
            trainer.iteration(),
            self.rd.path().display()
        ));
        self.progress.finish();
        Ok(ControlFlow::Break(()))
    }

    fn reward(&mut self) -> Option<&mut dyn RewardModel> {
        self.reward.as_mut().map(RunReward::as_dyn)
    }

    fn after_iteration(
        &mut self,
        trainer: &TrpoTrainer,
        env: &mut WatchedEnv,
        m: &IterationMetrics,
    ) -> Result<ControlFlow<()>> {
        let (cfg, step) = (self.cfg, trainer.env_steps());
        let fresh = env.take_warnings();
        if fresh.iter().any(|&n| n > 0) {
            self.progress.note(&format!(
                "MuJoCo warnings in the batch ending at env step {step}: {} (the simulation was reset by MuJoCo; check the actions and the model)",
                describe_warnings(&fresh)
            ));
            for i in 0..MJ_N_WARNING {
                self.mujoco_warnings[i] += fresh[i];
            }
        }
        for &r in &m.true_returns {
            self.recent.push_back(r);
            if self.recent.len() > cfg.best_window {
                self.recent.pop_front();
            }
        }
        let window = (!self.recent.is_empty())
            .then(|| self.recent.iter().sum::<f64>() / self.recent.len() as f64);
        if let Some(w) = window
            && !m.true_returns.is_empty()
            && self.best.as_ref().is_none_or(|b| w > b.mean_true_return)
        {
            save_policy(&self.rd.file("best_policy.json"), trainer.policy())?;
            self.best = Some(BestRecord {
                mean_true_return: w,
                env_steps: step,
                iteration: m.iteration,
            });
        }
        let total_warnings: u64 = self.mujoco_warnings.iter().sum();
        let wall = self.wall_before + self.session.elapsed().as_secs_f64();
        self.metrics
            .push_str(&metrics_row(m, window, total_warnings, wall));
        self.rd.write("metrics.csv", self.metrics.as_bytes())?;
        let msg = format!(
            "return(last {}) {}{}",
            cfg.best_window,
            window.map_or("-".into(), |w| format!("{w:.1}")),
            m.mean_imitation_reward
                .map_or(String::new(), |r| format!(", imitation reward/step {r:.3}"))
        );
        if m.iteration.is_multiple_of(cfg.checkpoint_every) {
            self.save(trainer)?;
            self.progress.note(&format!("env step {step}: {msg}"));
        }
        self.progress.advance(step.min(cfg.steps), &msg);
        Ok(ControlFlow::Continue(()))
    }
}

/// How [`super::launch::run_with`] treats the run folder.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Start {
    /// A new run; a folder that holds files is refused.
    New,
    /// A new run; a folder that holds files is moved aside first
    /// ([`crate::run_dir::Existing::MoveAside`]).
    Force,
    /// Continue the run in the folder.
    Resume,
}

impl Start {
    /// From the command line's `--resume` and `--force`.
    pub fn from_flags(resume: bool, force: bool) -> Self {
        match (resume, force) {
            (true, _) => Self::Resume,
            (false, true) => Self::Force,
            (false, false) => Self::New,
        }
    }
}

/// The command line's settings of an `expert` or `train` run: each `None`
/// keeps the value of the `config` file or the task's default.
#[derive(Debug, Clone, Default)]
pub struct RunFlags {
    /// Environment steps of TRPO.
    pub steps: Option<u64>,
    /// Seed of every random stream of the run.
    pub seed: u64,
    /// Run name (default: [`super::default_run_name`]).
    pub name: Option<String>,
    /// Folder of the runs.
    pub out_dir: PathBuf,
    /// Continue the run in this folder (its `config.json` holds the
    /// settings; only `steps` changes them).
    pub resume: Option<PathBuf>,
    /// Move a folder that holds a run aside first.
    pub force: bool,
    /// A settings file and its text (the fields of `config.json`).
    pub config: Option<(PathBuf, String)>,
    /// TRPO iterations between checkpoints.
    pub checkpoint_every: Option<u64>,
    /// Evaluation episodes.
    pub eval_episodes: Option<usize>,
    /// A fixed sigma1.
    pub sigma1: Option<f64>,
    /// The RED release's hand-set sigma1 of the task and method.
    pub release_sigma1: bool,
    /// Demonstration file (default: [`super::default_demo`] in `out_dir`).
    pub demo: Option<PathBuf>,
    /// The learner (default: the config file's, else TRPO). SAC also sets
    /// the default budget to [`SAC_EXPERT_STEPS`].
    pub learner: Option<MujocoLearner>,
}

impl RunFlags {
    /// The settings of a new run of `method` on `env`: the task's defaults,
    /// then the `config` file, then the other flags; validated.
    ///
    /// # Errors
    /// A `config` file that cannot be used, or invalid settings.
    pub fn config(&self, env: EnvId, method: Method) -> Result<RunConfig> {
        let mut cfg = RunConfig::for_task(env, method);
        if self.learner == Some(MujocoLearner::Sac) {
            cfg.learner = MujocoLearner::Sac;
            cfg.steps = SAC_EXPERT_STEPS;
        }
        if let Some((path, text)) = &self.config {
            // Fields missing from the file keep the task's defaults.
            cfg = cfg.with_overrides(text, path)?;
        }
        if let Some(l) = self.learner {
            cfg.learner = l;
        }
        // SAC starts from a random policy: the task's TRPO warm start is
        // dropped unless the config file asks for one (which is refused).
        let file_sets_warm_start = self.config.as_ref().is_some_and(|(_, text)| {
            serde_json::from_str::<serde_json::Value>(text)
                .ok()
                .is_some_and(|v| v.get("bc_warm_start_epochs").is_some())
        });
        if cfg.learner == MujocoLearner::Sac && !file_sets_warm_start {
            cfg.bc_warm_start_epochs = 0;
        }
        cfg.seed = self.seed;
        cfg.steps = self.steps.unwrap_or(cfg.steps);
        cfg.checkpoint_every = self.checkpoint_every.unwrap_or(cfg.checkpoint_every);
        cfg.eval_episodes = self.eval_episodes.unwrap_or(cfg.eval_episodes);
        if let Some(s) = self.sigma1 {
            cfg.sigma1 = Sigma1::Fixed(s);
        }
        if self.release_sigma1 {
            cfg.sigma1 = Sigma1::Fixed(RunConfig::release_sigma1(env, method));
        }
        if method.needs_demo() {
            let demo = self.demo.clone();
            cfg.demo = Some(demo.unwrap_or_else(|| super::default_demo(&self.out_dir, env)));
        }
        cfg.validate()?;
        Ok(cfg)
    }

    /// The run's folder, settings and start: with `resume`, the folder's
    /// `config.json` (with `steps` when given); otherwise a new run of
    /// `method` on `env` ([`RunFlags::config`]) in `out_dir/name`.
    ///
    /// # Errors
    /// As [`read_config`] and [`RunFlags::config`]; an invalid name.
    pub fn prepare(&self, env: EnvId, method: Method) -> Result<(PathBuf, RunConfig, Start)> {
        if let Some(dir) = &self.resume {
            let mut cfg = read_config(dir)?;
            cfg.steps = self.steps.unwrap_or(cfg.steps);
            return Ok((dir.clone(), cfg, Start::Resume));
        }
        let cfg = self.config(env, method)?;
        let name = self.name.clone();
        let name = name.unwrap_or_else(|| super::default_run_name(env, method, cfg.seed));
        let dir = crate::run_dir::path_in(&self.out_dir, &name)?;
        Ok((dir, cfg, Start::from_flags(false, self.force)))
    }
}

/// The settings a checkpoint must have been made with: all but the step
/// budget, which a resume may change.
pub(super) fn checkpoint_settings(cfg: &RunConfig) -> RunConfig {
    RunConfig {
        steps: 0,
        ..cfg.clone()
    }
}

impl RunState {
    /// Values that make no sense even in a whole file.
    fn check(&self, cfg: &RunConfig) -> std::result::Result<(), String> {
        let t = &self.trainer;
        if t.config() != &cfg.trpo {
            return Err(
                "the TRPO learner was made with other settings than config.json's trpo".into(),
            );
        }
        crate::checks::check_policy("the policy", t.policy(), &cfg.trpo.policy)?;
        let expected = t.iteration() * cfg.trpo.steps_per_batch as u64;
        if t.env_steps() != expected {
            return Err(format!(
                "has {} environment steps after {} iterations of {} steps: they must be {expected}",
                t.env_steps(),
                t.iteration(),
                cfg.trpo.steps_per_batch
            ));
        }
        Ok(())
    }
}

/// Opens the run folder of [`super::launch::run_with`]: a new run's folder
/// with its `config.json`, or the one to resume (whose `config.json` is
/// used, with `cfg`'s step budget). Returns the folder, the settings and
/// whether the run resumes.
///
/// # Errors
/// Bad settings or demonstrations, a folder that holds a run ([`Start::New`])
/// or none to resume.
pub(super) fn open_run(
    dir: &Path,
    cfg: Option<RunConfig>,
    start: Start,
) -> Result<(RunDir, RunConfig, bool)> {
    if start == Start::Resume {
        let rd = RunDir::open(dir)?;
        let mut saved = read_config(dir)?;
        if let Some(c) = &cfg
            && c.steps != saved.steps
        {
            saved.steps = c.steps;
            rd.write_json("config.json", &saved)?;
        }
        return Ok((rd, saved, true));
    }
    let cfg = cfg.ok_or_else(|| Error::InvalidConfig {
        field: "config".into(),
        reason: "no settings given for a new run".into(),
    })?;
    cfg.validate()?;
    if let (true, Some(p)) = (cfg.method.needs_demo(), &cfg.demo) {
        load_run_demos(p, &cfg)?;
    }
    let existing = crate::run_dir::Existing::from_force(start == Start::Force);
    let rd = RunDir::new_at(dir, existing)?;
    rd.write_json("config.json", &cfg)?;
    Ok((rd, cfg, false))
}

/// Trains (or, with `resume`, continues from its checkpoint) the TRPO run
/// (or behaviour cloning) of `rd`, whose `config.json` holds `cfg`, then
/// evaluates it ([`super::launch::run_with`] tells the whole story).
///
/// # Errors
/// As [`super::launch::run_with`].
pub(super) fn train(
    rd: RunDir,
    cfg: RunConfig,
    resume: bool,
    stop: &AtomicBool,
    progress: &mut dyn Progress,
) -> Result<Outcome> {
    let state = if resume && rd.file("checkpoint.json").is_file() {
        let path = rd.file("checkpoint.json");
        let s: RunState = load_checkpoint_for(&path, CHECKPOINT_KIND, &checkpoint_settings(&cfg))
            .with_context(|| format!("resuming {}", rd.path().display()))?;
        s.trainer.config().validate()?;
        s.check(&cfg).map_err(|reason| Error::Input {
            path: path.clone(),
            reason: format!("{reason}; the checkpoint cannot be resumed"),
        })?;
        Some(s)
    } else {
        None
    };
    for n in rd.notes() {
        progress.note(n);
    }
    let session = Instant::now();
    let mut env = run_env(&cfg)?;
    let (od, ad) = (env.observation_space().dim(), env.action_space().dim());
    let act_box = action_box(&env)?;
    let demos = match &cfg.demo {
        Some(p) if cfg.method.needs_demo() => Some(load_run_demos(p, &cfg)?),
        _ => None,
    };
    if cfg.method == Method::Bc {
        return run_bc(&rd, &cfg, demos.as_ref(), od, ad, session);
    }
    if resume
        && rd.file("eval.json").is_file()
        && state
            .as_ref()
            .is_some_and(|s| s.trainer.env_steps() >= cfg.steps)
    {
        // Finished earlier with this budget: nothing to redo.
        return Ok(Outcome::Finished);
    }
    let state = match state {
        Some(s) => s,
        None => {
            let s = fresh_state(&cfg, demos.as_ref(), od, &act_box)?;
            rd.save_checkpoint(CHECKPOINT_KIND, &checkpoint_settings(&cfg), &s)?;
            if let (Some(r), Some(d)) = (&s.reward, &demos)
                && let Some(msg) = fitted_reward_note(&cfg, r, d, &act_box)?
            {
                progress.note(&msg);
            }
            s
        }
    };
    let RunState {
        mut trainer,
        reward,
        recent,
        best,
        mujoco_warnings,
        wall_s: wall_before,
    } = state;
    progress.start(
        &format!("{} {}", super::short_name(cfg.env), cfg.method.name()),
        cfg.steps,
        trainer.env_steps().min(cfg.steps),
    );
    let mut hooks = RunHooks {
        cfg: &cfg,
        rd: &rd,
        stop,
        progress: &mut *progress,
        session,
        wall_before,
        metrics: truncate_metrics(&rd.file("metrics.csv"), trainer.iteration())?,
        reward: reward.map(|m| match cfg.reward_clips_actions {
            true => RunReward::Clipped(ClippedActions::new(m, act_box.clone())),
            false => RunReward::AsFitted(m),
        }),
        recent,
        best,
        mujoco_warnings,
    };
    let flow = trainer
        .train_with(&mut env, cfg.steps, &mut hooks)
        .with_context(|| {
            format!(
                "TRPO iteration {}, the batch ending at env step {} (last good checkpoint kept: {})",
                trainer.iteration() + 1,
                (trainer.iteration() + 1) * cfg.trpo.steps_per_batch as u64,
                rd.file("checkpoint.json").display()
            )
        })?;
    if flow.is_break() {
        return Ok(Outcome::Interrupted);
    }
    hooks.save(&trainer)?;
    let RunHooks {
        reward,
        best,
        mujoco_warnings,
        ..
    } = hooks;
    let reward = reward.map(|r| match r {
        RunReward::AsFitted(m) => m,
        RunReward::Clipped(c) => c.into_inner(),
    });

    let done = Trained {
        policy: trainer.policy().clone(),
        env_steps: trainer.env_steps(),
        best,
        reward,
        mujoco_warnings,
        wall_before,
    };
    finish_run(&rd, &cfg, demos.as_ref(), &act_box, done, session, progress)
}

/// What training hands to [`finish_run`].
pub(super) struct Trained {
    pub(super) policy: GaussianPolicy,
    pub(super) env_steps: u64,
    pub(super) best: Option<BestRecord>,
    pub(super) reward: Option<ImitationReward>,
    pub(super) mujoco_warnings: [u64; MJ_N_WARNING],
    /// Wall time of earlier sessions.
    pub(super) wall_before: f64,
}

/// The end of a trained run: saves the final policy, evaluates it and the
/// best checkpoint, records an expert's demonstrations, writes `eval.json`.
pub(super) fn finish_run(
    rd: &RunDir,
    cfg: &RunConfig,
    demos: Option<&Demos>,
    act_box: &BoxSpace,
    done: Trained,
    session: Instant,
    progress: &mut dyn Progress,
) -> Result<Outcome> {
    let Trained {
        policy,
        env_steps: steps_done,
        best,
        reward,
        mujoco_warnings,
        wall_before,
    } = done;
    let dir = rd.path();
    // Final policy and evaluations.
    save_policy(&rd.file("policy.json"), &policy)?;
    let eval_seed = Seeder::new(cfg.seed).derive(Stream::Eval);
    let mut eval_env = run_env(cfg)?;
    progress.advance(steps_done.min(cfg.steps), "evaluating");
    let final_report = evaluate(
        &mut eval_env,
        &policy,
        cfg.eval_episodes,
        None,
        &mut ChaCha8Rng::seed_from_u64(eval_seed),
    )?;
    let final_eval = EvalSummary::new("final", steps_done, &final_report);
    let (best_eval, best_policy) = match &best {
        Some(b) if rd.file("best_policy.json").is_file() => {
            let bp = GaussianPolicy::load(&rd.file("best_policy.json"))?;
            let r = evaluate(
                &mut eval_env,
                &bp,
                cfg.eval_episodes,
                None,
                &mut ChaCha8Rng::seed_from_u64(eval_seed),
            )?;
            (
                Some(EvalSummary::new(
                    "best checkpoint (by training true return)",
                    b.env_steps,
                    &r,
                )),
                Some(bp),
            )
        }
        _ => (None, None),
    };
    let demo_mean_imitation_reward = match (&reward, demos) {
        (Some(ImitationReward::Support(r)), Some(d)) => {
            let (es, ea) = reward_pairs(cfg, d, act_box)?;
            Some(r.rewards(es.view(), ea.view())?.mean().unwrap_or(f64::NAN))
        }
        _ => None,
    };
    let mut eval_file = EvalFile {
        env: cfg.env.name().into(),
        method: cfg.method.name().into(),
        seed: cfg.seed,
        episodes: cfg.eval_episodes,
        final_policy: final_eval,
        best_checkpoint: best_eval,
        demo_mean_return: demos
            .and_then(|d| d.returns())
            .map(|r| r.iter().sum::<f64>() / r.len().max(1) as f64),
        demo_mean_imitation_reward,
        mujoco_warnings: mujoco_warnings.iter().sum(),
        wall_s: wall_before + session.elapsed().as_secs_f64(),
        expert_choice: None,
        demo_returns: None,
    };
    if cfg.method == Method::Expert {
        let use_best = eval_file
            .best_checkpoint
            .as_ref()
            .is_some_and(|b| b.mean > eval_file.final_policy.mean);
        let expert = if use_best {
            best_policy.clone().unwrap_or(policy.clone())
        } else {
            policy.clone()
        };
        eval_file.expert_choice = Some(if use_best {
            "best checkpoint".into()
        } else {
            "final policy".into()
        });
        save_policy(&dir.join("expert_policy.json"), &expert)?;
        let demos = record_demos(
            cfg.env,
            &expert,
            cfg.demo_trajectories,
            Seeder::new(cfg.seed).derive(Stream::Demo),
        )?;
        demos
            .write(&dir.join("demos.json"))
            .with_context(|| format!("writing {}", dir.join("demos.json").display()))?;
        eval_file.demo_returns = demos.returns();
    }
    eval_file.wall_s = wall_before + session.elapsed().as_secs_f64();
    rd.write_json("eval.json", &eval_file)?;
    progress.finish();
    Ok(Outcome::Finished)
}

/// Behaviour cloning alone: fit, save, evaluate.
fn run_bc(
    rd: &RunDir,
    cfg: &RunConfig,
    demos: Option<&Demos>,
    od: usize,
    ad: usize,
    session: Instant,
) -> Result<Outcome> {
    let demos = demos.ok_or_else(|| Error::InvalidConfig {
        field: "demo".into(),
        reason: "bc needs demonstrations".into(),
    })?;
    let (es, ea) = demos.pairs();
    let seeder = Seeder::new(cfg.seed);
    let normalizer = if cfg.freeze_obs_norm_from_demo {
        Some(ObsNormalizer::from_data(
            es.view(),
            DEFAULT_CLIP.min(cfg.trpo.obs_clip),
            DEFAULT_MIN_STD.min(cfg.trpo.obs_min_std),
        )?)
    } else {
        None
    };
    let mut policy = GaussianPolicy::new(
        &cfg.trpo.policy,
        od,
        ad,
        normalizer,
        &mut seeder.rng(Stream::Init),
    )?;
    let bc = BcConfig {
        epochs: cfg.bc_epochs,
        ..cfg.bc.clone()
    };
    let losses = behavior_clone(
        &mut policy,
        es.view(),
        ea.view(),
        &bc,
        &mut seeder.rng(Stream::Other(1)),
    )?;
    let mut csv = String::from("epoch,bc_loss\n");
    for (i, l) in losses.iter().enumerate() {
        csv.push_str(&format!("{},{l}\n", i + 1));
    }
    rd.write("bc_losses.csv", csv.as_bytes())?;
    save_policy(&rd.file("policy.json"), &policy)?;
    let mut env = run_env(cfg)?;
    let report = evaluate(
        &mut env,
        &policy,
        cfg.eval_episodes,
        None,
        &mut ChaCha8Rng::seed_from_u64(seeder.derive(Stream::Eval)),
    )?;
    let eval_file = EvalFile {
        env: cfg.env.name().into(),
        method: cfg.method.name().into(),
        seed: cfg.seed,
        episodes: cfg.eval_episodes,
        final_policy: EvalSummary::new("final", 0, &report),
        best_checkpoint: None,
        demo_mean_return: demos
            .returns()
            .map(|r| r.iter().sum::<f64>() / r.len().max(1) as f64),
        demo_mean_imitation_reward: None,
        mujoco_warnings: env.take_warnings().iter().sum(),
        wall_s: session.elapsed().as_secs_f64(),
        expert_choice: None,
        demo_returns: None,
    };
    rd.write_json("eval.json", &eval_file)?;
    Ok(Outcome::Finished)
}

/// Records `n` episodes of `policy` with deterministic actions (clipped to
/// the action space, as evaluation does; the file holds the actions the
/// environment received), with their true rewards.
///
/// # Errors
/// An environment or policy error.
pub fn record_demos(id: EnvId, policy: &GaussianPolicy, n: usize, seed: u64) -> Result<Demos> {
    record_demos_with(id, policy, n, seed, &RecordOptions::default())
}

/// How [`record_demos_with`] acts and what it stores. The default is what
/// an `expert` run writes: mean actions, stored clipped, episodes to the
/// task's time limit.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RecordOptions {
    /// Actions sampled from the policy's Gaussian (noise from the stream
    /// `Exploration` of `seed`) instead of its mean.
    pub sampled: bool,
    /// Store the raw action (the network's output, or the sample) instead
    /// of the action clipped to the action space. The environment always
    /// receives the clipped one.
    pub raw: bool,
    /// Cut each episode after this many steps (ended `truncated`).
    pub max_steps: Option<usize>,
}

/// As [`record_demos`], with the choices of `opts`.
///
/// # Errors
/// An environment or policy error.
pub fn record_demos_with(
    id: EnvId,
    policy: &GaussianPolicy,
    n: usize,
    seed: u64,
    opts: &RecordOptions,
) -> Result<Demos> {
    let mut env = policy_env(id, policy)?;
    let mut noise = opts
        .sampled
        .then(|| ChaCha8Rng::seed_from_u64(Seeder::new(seed).derive(Stream::Exploration)));
    let mut ws = red_rl::policy::PolicyWorkspace::default();
    let (low, high) = match env.action_space() {
        Space::Box(b) => (b.low.clone(), b.high.clone()),
        Space::Discrete(_) => {
            return Err(Error::InvalidConfig {
                field: "env".into(),
                reason: format!("{id} has a discrete action space"),
            });
        }
    };
    let sim = env.inner().inner().simulation();
    let hz = 1.0 / sim.dt();
    // A file holds the task's own observations: a policy trained with the
    // time feature reads it, the file does not keep it.
    let od = env.observation_space().dim() - usize::from(env.has_time_feature());
    let mut demos = Demos::new(id.name(), od, env.action_space().dim(), Some(hz));
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for _ in 0..n {
        let s: u64 = rand::RngExt::random(&mut rng);
        let (obs, _) = env.reset(Some(s))?;
        let mut raws = Vec::new();
        let act = |_: &WatchedEnv, obs: &[f64]| {
            let mut raw = vec![0.0; low.len()];
            policy.act_into(obs, noise.as_mut(), &mut ws, &mut raw)?;
            let mut a = raw.clone();
            for j in 0..a.len() {
                a[j] = a[j].clamp(low[j], high[j]);
            }
            raws.push(raw);
            Ok::<_, Error>(a)
        };
        let (mut trajectory, _) =
            record_episode(&mut env, obs, opts.max_steps, act, |_, _| Ok(()))?;
        if opts.raw {
            trajectory.actions = raws;
        }
        for o in &mut trajectory.observations {
            o.truncate(od);
        }
        demos.trajectories.push(trajectory);
    }
    demos.validate()?;
    Ok(demos)
}

/// The evaluation of a policy file, as `red-cli mujoco eval --out` writes
/// it.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PolicyEval {
    /// The policy file.
    pub policy: String,
    /// The task (`Hopper-v5`, ...).
    pub env: String,
    /// Episodes.
    pub episodes: usize,
    /// Seed of the episodes' resets.
    pub seed: u64,
    /// `deterministic` (the policy's mean) or `sampled` actions.
    pub actions: String,
    /// Mean true return.
    pub mean: f64,
    /// Standard deviation (population) of the true return.
    pub std: f64,
    /// Every episode's true return.
    pub returns: Vec<f64>,
    /// Every episode's length.
    pub lengths: Vec<usize>,
    /// The environment's info entries summed over an episode, averaged over
    /// the episodes (reward terms, velocities, positions).
    pub info_totals: Vec<(String, f64)>,
}

impl PolicyEval {
    /// The evaluation `report` of the policy file `policy` on `id`.
    pub fn new(policy: &Path, id: EnvId, seed: u64, sampled: bool, report: &EvalReport) -> Self {
        Self {
            policy: policy.display().to_string(),
            env: id.name().into(),
            episodes: report.returns.len(),
            seed,
            actions: if sampled { "sampled" } else { "deterministic" }.into(),
            mean: report.mean_return(),
            std: report.std_return(),
            returns: report.returns.clone(),
            lengths: report.lengths.clone(),
            info_totals: report.info_totals.clone(),
        }
    }

    /// A few lines for people: the mean return, then where it comes from:
    /// each reward term of the task summed over an episode, and the other
    /// info entries (velocities, positions) as means per step.
    pub fn summary(&self) -> String {
        let mean_length =
            self.lengths.iter().sum::<usize>() as f64 / self.lengths.len().max(1) as f64;
        let mut s = format!(
            "{} on {}: {:.2} +- {:.2} over {} episodes ({} actions, true reward; mean length {:.0})\n",
            self.policy,
            self.env,
            self.mean,
            self.std,
            self.returns.len(),
            self.actions,
            mean_length
        );
        let steps = mean_length.max(1.0);
        let (terms, other): (Vec<_>, Vec<_>) = self
            .info_totals
            .iter()
            .partition(|(k, _)| k.starts_with("reward_"));
        let show = |v: &[&(String, f64)], scale: f64| {
            v.iter()
                .map(|(k, x)| format!("{k} {:.2}", x / scale))
                .collect::<Vec<_>>()
                .join(", ")
        };
        if !terms.is_empty() {
            s.push_str(&format!("  per episode: {}\n", show(&terms, 1.0)));
        }
        if !other.is_empty() {
            s.push_str(&format!("  per step: {}\n", show(&other, steps)));
        }
        s
    }
}

impl PolicyEval {
    /// [`evaluate_file`] as a [`PolicyEval`], with the MuJoCo warnings seen.
    ///
    /// # Errors
    /// As [`evaluate_file`].
    pub fn of_file(
        path: &Path,
        id: EnvId,
        episodes: usize,
        seed: u64,
        sampled: bool,
    ) -> Result<(Self, u64)> {
        let (report, warnings) = evaluate_file(path, id, episodes, seed, sampled)?;
        Ok((Self::new(path, id, seed, sampled, &report), warnings))
    }

    /// Writes the evaluation as JSON to `out` (atomically).
    ///
    /// # Errors
    /// A file that cannot be written.
    pub fn write(&self, out: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self).map_err(|e| Error::Input {
            path: out.to_path_buf(),
            reason: e.to_string(),
        })?;
        Ok(write_atomic(out, text.as_bytes())?)
    }
}

/// Runs the policy file `path` on `id` for `episodes` episodes with the
/// true reward: deterministic (mean) actions, or actions sampled from the
/// policy's Gaussian when `sampled`.
///
/// # Errors
/// An unreadable policy, or one whose dimensions do not fit the task.
pub fn evaluate_file(
    path: &Path,
    id: EnvId,
    episodes: usize,
    seed: u64,
    sampled: bool,
) -> Result<(EvalReport, u64)> {
    if episodes == 0 {
        return Err(Error::InvalidConfig {
            field: "episodes".into(),
            reason: "must be at least 1".into(),
        });
    }
    let policy =
        GaussianPolicy::load(path).with_context(|| format!("loading {}", path.display()))?;
    let mut env =
        policy_env(id, &policy).with_context(|| format!("evaluating {}", path.display()))?;
    let run = if sampled { evaluate_sampled } else { evaluate };
    let report = run(
        &mut env,
        &policy,
        episodes,
        None,
        &mut ChaCha8Rng::seed_from_u64(Seeder::new(seed).derive(Stream::Eval)),
    )
    .with_context(|| format!("evaluating {} on {id}", path.display()))?;
    let warnings = env.take_warnings().iter().sum();
    Ok((report, warnings))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mujoco::launch::run;

    #[test]
    fn reward_pairs_clip_the_actions_only_when_asked() {
        let mut d = Demos::new("Hopper-v5", 2, 2, None);
        d.trajectories.push(red_core::Trajectory {
            observations: vec![vec![5.0, -5.0], vec![0.0, 0.0]],
            actions: vec![vec![2.5, -0.5], vec![-3.0, 1.0]],
            rewards: None,
            end: red_core::EpisodeEnd::Terminated,
        });
        let b = BoxSpace::uniform(2, -1.0, 1.0);
        let mut cfg = RunConfig::for_task(EnvId::Walker2d, Method::Red);
        assert!(!cfg.reward_clips_actions);
        let (s, a) = reward_pairs(&cfg, &d, &b).unwrap();
        assert_eq!(s, ndarray::array![[5.0, -5.0], [0.0, 0.0]]);
        assert_eq!(a, ndarray::array![[2.5, -0.5], [-3.0, 1.0]]);
        cfg.reward_clips_actions = true;
        let (s2, a) = reward_pairs(&cfg, &d, &b).unwrap();
        assert_eq!(s2, s);
        assert_eq!(a, ndarray::array![[1.0, -0.5], [-1.0, 1.0]]);
    }

    #[test]
    fn the_shipped_red_settings_files_reproduce_runs_made_without_clipping() {
        // Every data/mujoco-red-* file restores settings of runs made before
        // Hopper's RED clipped by default, so each must keep it off.
        let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data");
        let mut files = Vec::new();
        for dir in [data.clone(), data.join("mujoco-red-first-settings")] {
            for e in std::fs::read_dir(&dir).unwrap() {
                let path = e.unwrap().path();
                let name = path.file_name().unwrap().to_string_lossy().into_owned();
                let in_first = dir.ends_with("mujoco-red-first-settings");
                if name.ends_with(".json") && (in_first || name.starts_with("mujoco-red-")) {
                    files.push(path);
                }
            }
        }
        assert!(files.len() >= 8, "{files:?}");
        let all = [
            EnvId::Hopper,
            EnvId::HalfCheetah,
            EnvId::Walker2d,
            EnvId::Ant,
            EnvId::Reacher,
        ];
        for path in files {
            let name = path.file_stem().unwrap().to_string_lossy().into_owned();
            // a file without a task in its name applies to every task
            let envs: Vec<EnvId> = match name.split('-').find_map(|w| w.parse::<EnvId>().ok()) {
                Some(env) => vec![env],
                None => all.to_vec(),
            };
            for env in envs {
                check_restoring_file(&path, &name, env);
            }
        }
    }

    fn check_restoring_file(path: &Path, name: &str, env: EnvId) {
        let text = std::fs::read_to_string(path).unwrap();
        let cfg = RunConfig::for_task(env, Method::Red)
            .with_overrides(&text, path)
            .unwrap();
        // Every file restores runs made before session 51, whose RED on
        // Reacher saw every state dimension and no time.
        if env == EnvId::Reacher {
            assert!(!cfg.time_feature, "{}", path.display());
            assert!(cfg.rnd.ignored_state_dims.is_empty(), "{}", path.display());
        }
        if name == "mujoco-red-reacher-no-time-feature" {
            return;
        }
        // The others restore runs made before session 49, which fitted and
        // warm-started with unscaled epochs.
        assert_eq!(cfg.epochs_reference_pairs, 0, "{}", path.display());
        if name == "mujoco-red-epochs-unscaled" {
            return;
        }
        // and every Hopper and HalfCheetah file restores the release's
        // discount, which RED on them used until sessions 47 and 48;
        // every HalfCheetah file also the reward rule of 0.9 it used
        // until session 48.
        if matches!(env, EnvId::HalfCheetah | EnvId::Walker2d) {
            assert_eq!(
                cfg.sigma1,
                Sigma1::Calibrated {
                    quantile: 0.9,
                    reward: 0.9
                },
                "{}",
                path.display()
            );
        }
        if matches!(env, EnvId::Hopper | EnvId::HalfCheetah | EnvId::Walker2d) {
            let g = &cfg.trpo.gae;
            assert_eq!(
                (g.gamma, g.lambda, g.bootstrap_on_truncation),
                (0.97, 0.97, false),
                "{}",
                path.display()
            );
        }
        if name == "mujoco-red-hopper-gamma-0.97" {
            // the defaults of sessions 27-46: clipping on.
            assert!(cfg.reward_clips_actions);
            return;
        }
        assert!(!cfg.reward_clips_actions, "{}", path.display());
    }

    #[test]
    fn red_goes_through_a_short_demonstration_as_often_as_through_four_trajectories() {
        let h = RunConfig::for_task(EnvId::HalfCheetah, Method::Red);
        assert_eq!(h.epochs_reference_pairs, 4000);
        // one trajectory: four times the epochs; two: twice; three or a
        // set whose episodes end a little early: as many as four.
        let factors: Vec<usize> = [1000, 2000, 3000, 3900, 4000, 8000]
            .iter()
            .map(|&n| h.epochs_factor(n))
            .collect();
        assert_eq!(factors, [4, 2, 1, 1, 1, 1]);
        let one = h.scaled_for_pairs(1000);
        assert_eq!((one.rnd.epochs, one.bc_warm_start_epochs), (800, 400));
        assert_eq!(h.scaled_for_pairs(4000), h);
        let r = RunConfig::for_task(EnvId::Reacher, Method::Red);
        assert_eq!((r.epochs_reference_pairs, r.epochs_factor(50)), (200, 4));
        // other methods are not scaled, and an old config.json reads as it ran
        for m in [Method::Ae, Method::Gail, Method::Gmmil, Method::Bc] {
            assert_eq!(RunConfig::for_task(EnvId::Hopper, m).epochs_factor(100), 1);
        }
        let mut v = serde_json::to_value(&h).unwrap();
        v.as_object_mut().unwrap().remove("epochs_reference_pairs");
        let back: RunConfig =
            crate::run_dir::parse_json(&v.to_string(), Path::new("config.json")).unwrap();
        assert_eq!(back.epochs_factor(1000), 1);
        // and writes no field, so that it matches the settings saved in
        // the checkpoints of runs made before the field existed
        let again = serde_json::to_value(checkpoint_settings(&back)).unwrap();
        assert!(again.get("epochs_reference_pairs").is_none());
        assert_eq!(
            serde_json::to_value(&h).unwrap()["epochs_reference_pairs"],
            4000
        );
    }

    #[test]
    fn the_warm_start_of_a_short_demonstration_takes_the_scaled_epochs() {
        use rand::RngExt;
        // one Reacher episode of 50 pairs, a quarter of the reference
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut d = Demos::new("Reacher-v5", 10, 2, None);
        d.trajectories.push(red_core::Trajectory {
            observations: (0..50)
                .map(|_| (0..10).map(|_| rng.random_range(-1.0..1.0)).collect())
                .collect(),
            actions: (0..50)
                .map(|_| (0..2).map(|_| rng.random_range(-1.0..1.0)).collect())
                .collect(),
            rewards: None,
            end: red_core::EpisodeEnd::Truncated,
        });
        let b = BoxSpace::uniform(2, -1.0, 1.0);
        let mut cfg = RunConfig::for_task(EnvId::Reacher, Method::Red);
        cfg.demo = Some("unused.json".into());
        (cfg.bc_warm_start_epochs, cfg.rnd.epochs) = (3, 2);
        let policy = |c: &RunConfig| {
            let s = fresh_state(c, Some(&d), 10, &b).unwrap();
            serde_json::to_string(s.trainer.policy()).unwrap()
        };
        let mut by_hand = cfg.clone();
        (by_hand.bc_warm_start_epochs, by_hand.rnd.epochs) = (12, 8);
        by_hand.epochs_reference_pairs = 0;
        let mut plain = cfg.clone();
        plain.epochs_reference_pairs = 0;
        let scaled = policy(&cfg);
        assert_eq!(scaled, policy(&by_hand));
        assert_ne!(scaled, policy(&plain));
    }

    #[test]
    fn the_reward_of_a_short_demonstration_is_fitted_with_the_scaled_epochs() {
        // 50 pairs of Reacher, a quarter of its reference: the run's fit is
        // the fit with four times the epochs and the scaling off.
        use rand::RngExt;
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let es = Array2::from_shape_fn((50, 10), |_| rng.random_range(-1.0..1.0));
        let ea = Array2::from_shape_fn((50, 2), |_| rng.random_range(-1.0..1.0));
        let mut cfg = RunConfig::for_task(EnvId::Reacher, Method::Red);
        cfg.rnd.epochs = 5;
        let scaled = fit_run_reward(&cfg, &es, &ea, &[]).unwrap().unwrap();
        let mut manual = cfg.clone();
        manual.rnd.epochs = 20;
        manual.epochs_reference_pairs = 0;
        let by_hand = fit_run_reward(&manual, &es, &ea, &[]).unwrap().unwrap();
        let plain = {
            let mut c = cfg.clone();
            c.epochs_reference_pairs = 0;
            fit_run_reward(&c, &es, &ea, &[]).unwrap().unwrap()
        };
        let (ImitationReward::Support(a), ImitationReward::Support(b), ImitationReward::Support(c)) =
            (&scaled, &by_hand, &plain)
        else {
            panic!("RED's reward is a support reward");
        };
        let (ra, rb, rc) = (
            a.rewards(es.view(), ea.view()).unwrap(),
            b.rewards(es.view(), ea.view()).unwrap(),
            c.rewards(es.view(), ea.view()).unwrap(),
        );
        assert_eq!(ra, rb);
        assert_ne!(ra, rc);
    }

    #[test]
    fn the_time_feature_reaches_the_env_the_demos_and_saved_policies() {
        // RED on Reacher has it by default, the other methods and tasks not
        let mut cfg = RunConfig::for_task(EnvId::Reacher, Method::Red);
        assert!(cfg.time_feature);
        assert_eq!(cfg.rnd.ignored_state_dims, REACHER_RED_IGNORED_DIMS);
        for (env, m) in [(EnvId::Reacher, Method::Gail), (EnvId::Hopper, Method::Red)] {
            let other = RunConfig::for_task(env, m);
            assert!(!other.time_feature && other.rnd.ignored_state_dims.is_empty());
        }
        cfg.time_feature = false;
        let od = run_env(&cfg).unwrap().observation_space().dim();
        cfg.time_feature = true;
        let env = run_env(&cfg).unwrap();
        assert_eq!(env.observation_space().dim(), od + 1);
        // demos recorded by a plain policy read with the step's time
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let plain = GaussianPolicy::new(&cfg.trpo.policy, od, 2, None, &mut rng).unwrap();
        let tmp = tempfile::tempdir().unwrap();
        let file = tmp.path().join("d.json");
        record_demos(EnvId::Reacher, &plain, 2, 3)
            .unwrap()
            .write(&file)
            .unwrap();
        let d = load_run_demos(&file, &cfg).unwrap();
        assert_eq!(d.obs_dim, od + 1);
        let t = &d.trajectories[1].observations;
        assert_eq!((t[0][od], t[10][od]), (0.0, 10.0 / 50.0));
        cfg.time_feature = false;
        assert_eq!(load_run_demos(&file, &cfg).unwrap().obs_dim, od);
        // a saved policy's input tells which task it was trained on
        assert!(
            !policy_env(EnvId::Reacher, &plain)
                .unwrap()
                .has_time_feature()
        );
        let timed = GaussianPolicy::new(&cfg.trpo.policy, od + 1, 2, None, &mut rng).unwrap();
        assert!(
            policy_env(EnvId::Reacher, &timed)
                .unwrap()
                .has_time_feature()
        );
        // and files it records hold the task's own observations
        let demos = record_demos(EnvId::Reacher, &timed, 1, 3).unwrap();
        assert_eq!(demos.obs_dim, od);
        assert!(
            demos.trajectories[0]
                .observations
                .iter()
                .all(|o| o.len() == od)
        );
        let odd = GaussianPolicy::new(&cfg.trpo.policy, od + 2, 2, None, &mut rng).unwrap();
        let e = policy_env(EnvId::Reacher, &odd).err().unwrap().to_string();
        assert!(e.contains("with the time feature"), "{e}");
        // a whole config.json of a run without the feature keeps it off
        let old = serde_json::to_string(&cfg).unwrap();
        let reread = RunConfig::for_task(EnvId::Reacher, Method::Red)
            .with_overrides(&old, Path::new("config.json"))
            .unwrap();
        assert!(!reread.time_feature);
        assert_eq!(reread, cfg);
        // TRPO may not carry the value past a limit the state shows
        let mut hop = RunConfig::for_task(EnvId::Hopper, Method::Red);
        hop.time_feature = true;
        let e = hop.validate().unwrap_err().to_string();
        assert!(e.contains("bootstrap_on_truncation"), "{e}");
        hop.trpo.gae.bootstrap_on_truncation = false;
        assert!(
            !hop.validate()
                .is_err_and(|e| e.to_string().contains("time_feature"))
        );
        // false is not written, and a config without the field reads false
        let v = serde_json::to_value(&cfg).unwrap();
        assert!(v.get("time_feature").is_none());
        let back: RunConfig = serde_json::from_value(v).unwrap();
        assert!(!back.time_feature);
    }

    #[test]
    fn the_context_is_left_out_of_the_reward_only_when_asked() {
        // 40 pairs of Reacher whose dims 4 and 5 are a context: the reward
        // fitted with the flag ignores them (any value scores the same)
        // and equals the fit with those dims ignored by hand.
        use rand::RngExt;
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let es = Array2::from_shape_fn((40, 10), |(i, j)| match j {
            4 | 5 => (i / 20) as f64 * 0.1 - 0.05,
            _ => rng.random_range(-1.0..1.0),
        });
        let ea = Array2::from_shape_fn((40, 2), |_| rng.random_range(-1.0..1.0));
        let mut cfg = RunConfig::for_task(EnvId::Reacher, Method::Red);
        // every dimension in, as before session 51
        cfg.rnd.ignored_state_dims.clear();
        cfg.rnd.epochs = 2;
        assert!(!cfg.reward_ignores_context);
        assert!(
            cfg.reward_fit_config(40, &[4, 5])
                .rnd
                .ignored_state_dims
                .is_empty()
        );
        let mut on = cfg.clone();
        on.reward_ignores_context = true;
        on.rnd.ignored_state_dims = vec![5, 9];
        assert_eq!(
            on.reward_fit_config(40, &[4, 5]).rnd.ignored_state_dims,
            vec![4, 5, 9]
        );
        on.rnd.ignored_state_dims.clear();
        let fitted = fit_run_reward(&on, &es, &ea, &[4, 5]).unwrap().unwrap();
        let mut by_hand = cfg.clone();
        by_hand.rnd.ignored_state_dims = vec![4, 5];
        let manual = fit_run_reward(&by_hand, &es, &ea, &[]).unwrap().unwrap();
        let plain = fit_run_reward(&cfg, &es, &ea, &[4, 5]).unwrap().unwrap();
        let mut moved = es.clone();
        moved.column_mut(4).fill(0.7);
        moved.column_mut(5).fill(-0.3);
        let r = |f: &ImitationReward, s: &Array2<f64>| f.rewards(s.view(), ea.view()).unwrap();
        assert_eq!(r(&fitted, &es), r(&manual, &es));
        assert_eq!(r(&fitted, &es), r(&fitted, &moved));
        assert_ne!(r(&plain, &es), r(&plain, &moved));
        // only RED's reward has it
        let mut ae = RunConfig::for_task(EnvId::Reacher, Method::Ae);
        ae.reward_ignores_context = true;
        let e = ae.validate().unwrap_err().to_string();
        assert!(e.contains("reward_ignores_context"), "{e}");
        let fine = on.validate().map_err(|e| e.to_string());
        assert!(
            !format!("{fine:?}").contains("reward_ignores_context"),
            "{fine:?}"
        );
        // false is not written, and a config without the field reads false
        let v = serde_json::to_value(&cfg).unwrap();
        assert!(v.get("reward_ignores_context").is_none());
        let back: RunConfig = serde_json::from_value(v).unwrap();
        assert!(!back.reward_ignores_context);
        assert_eq!(
            serde_json::to_value(&on).unwrap()["reward_ignores_context"],
            serde_json::json!(true)
        );
    }

    #[test]
    fn an_old_config_without_the_clipping_field_reads_as_it_ran() {
        // Hopper's RED clips by default now; a config.json written before
        // the field existed ran without clipping, for any task.
        for env in [EnvId::Hopper, EnvId::Walker2d] {
            let cfg = RunConfig::for_task(env, Method::Red);
            let mut v = serde_json::to_value(&cfg).unwrap();
            v.as_object_mut().unwrap().remove("reward_clips_actions");
            let back: RunConfig =
                crate::run_dir::parse_json(&v.to_string(), Path::new("config.json")).unwrap();
            assert!(!back.reward_clips_actions, "{env:?}");
            assert_eq!(
                RunConfig {
                    reward_clips_actions: cfg.reward_clips_actions,
                    ..back
                },
                cfg
            );
        }
    }

    #[test]
    fn flags_override_the_task_defaults_and_name_the_folder() {
        let out = PathBuf::from("runs");
        let flags = RunFlags {
            out_dir: out.clone(),
            seed: 3,
            ..RunFlags::default()
        };
        let cfg = flags.config(EnvId::Hopper, Method::Red).unwrap();
        let mut want = RunConfig::for_task(EnvId::Hopper, Method::Red);
        want.seed = 3;
        want.demo = Some(super::super::default_demo(&out, EnvId::Hopper));
        assert_eq!(cfg, want);
        let (dir, _, start) = flags.prepare(EnvId::Hopper, Method::Red).unwrap();
        assert_eq!(dir, out.join("hopper-red-s3"));
        assert_eq!(start, Start::New);
        let flags = RunFlags {
            steps: Some(1234),
            checkpoint_every: Some(2),
            eval_episodes: Some(4),
            sigma1: Some(0.5),
            force: true,
            config: Some(("c.json".into(), r#"{"best_window": 7}"#.into())),
            ..flags
        };
        let (dir, cfg, start) = flags.prepare(EnvId::Hopper, Method::Expert).unwrap();
        assert_eq!(dir, out.join("expert-hopper"));
        assert_eq!(start, Start::Force);
        assert_eq!(
            (cfg.steps, cfg.checkpoint_every, cfg.eval_episodes),
            (1234, 2, 4)
        );
        assert_eq!(
            (cfg.sigma1, cfg.best_window, cfg.demo),
            (Sigma1::Fixed(0.5), 7, None)
        );
        let release = RunFlags {
            release_sigma1: true,
            ..flags.clone()
        };
        let cfg = release.config(EnvId::Ant, Method::Red).unwrap();
        let want = Sigma1::Fixed(RunConfig::release_sigma1(EnvId::Ant, Method::Red));
        assert_eq!(cfg.sigma1, want);
        let bad = RunFlags {
            config: Some(("c.json".into(), r#"{"nope": 1}"#.into())),
            ..flags.clone()
        };
        assert!(bad.config(EnvId::Hopper, Method::Red).is_err());
        let missing = RunFlags {
            resume: Some("no/such/run".into()),
            ..flags
        };
        let err = missing.prepare(EnvId::Hopper, Method::Red).unwrap_err();
        assert!(
            err.to_string().contains("is no/such/run a run folder"),
            "{err}"
        );
    }

    #[test]
    fn metrics_numbers_are_short_and_read_back() {
        for (x, text) in [
            (0.63, "0.63"),
            (3.0, "3"),
            (0.0, "0"),
            (1e-300, "1e-300"),
            (-2.5e-7, "-2.5e-7"),
            (1e20, "1e20"),
        ] {
            assert_eq!(num(x), text);
            assert_eq!(num(x).parse::<f64>().unwrap(), x);
        }
    }

    /// Counts what a run tells its observer.
    #[derive(Default)]
    struct Recorder {
        starts: usize,
        advances: Vec<u64>,
        notes: Vec<String>,
        finishes: usize,
    }

    impl Progress for Recorder {
        fn note(&mut self, text: &str) {
            self.notes.push(text.into());
        }
        fn start(&mut self, _label: &str, _total: u64, _done: u64) {
            self.starts += 1;
        }
        fn advance(&mut self, done: u64, _message: &str) {
            self.advances.push(done);
        }
        fn finish(&mut self) {
            self.finishes += 1;
        }
    }

    #[test]
    fn a_stopped_run_resumes_to_the_numbers_of_an_uninterrupted_one() {
        let tmp = tempfile::tempdir().unwrap();
        let mut cfg = RunConfig::for_task(EnvId::Reacher, Method::Expert);
        cfg.trpo.steps_per_batch = 128;
        cfg.steps = 256;
        cfg.eval_episodes = 1;
        cfg.demo_trajectories = 1;
        let never = AtomicBool::new(false);
        let full = tmp.path().join("full");
        let mut p = Recorder::default();
        let out = run(&full, Some(cfg.clone()), false, &never, &mut p).unwrap();
        assert_eq!(out, Outcome::Finished);
        assert_eq!((p.starts, p.finishes), (1, 1));
        assert_eq!(p.advances, [128, 256, 256]);
        assert!(full.join("demos.json").is_file());

        let split = tmp.path().join("split");
        let now = AtomicBool::new(true);
        let out = run(&split, Some(cfg), false, &now, &mut Recorder::default()).unwrap();
        assert_eq!(out, Outcome::Interrupted);
        assert!(!split.join("eval.json").exists());
        let out = run(&split, None, true, &never, &mut Recorder::default()).unwrap();
        assert_eq!(out, Outcome::Finished);
        let rows = |d: &Path| -> Vec<String> {
            std::fs::read_to_string(d.join("metrics.csv"))
                .unwrap()
                .lines()
                .map(|l| l.rsplit_once(',').unwrap().0.to_string())
                .collect()
        };
        assert_eq!(rows(&full), rows(&split));
        assert_eq!(
            read_eval(&full).unwrap().final_policy.returns,
            read_eval(&split).unwrap().final_policy.returns
        );
        assert!(
            read_eval(&full)
                .unwrap()
                .summary(&full)
                .contains("final policy (256 env steps)")
        );
    }

    #[test]
    fn a_new_run_refuses_a_folder_that_holds_one_and_overrides_are_merged() {
        let tmp = tempfile::tempdir().unwrap();
        let base = RunConfig::for_task(EnvId::Hopper, Method::Red);
        let src = tmp.path().join("over.json");
        let c = base
            .clone()
            .with_overrides(r#"{"trpo": {"steps_per_batch": 256}}"#, &src)
            .unwrap();
        assert_eq!(c.trpo.steps_per_batch, 256);
        assert_eq!(c.trpo.max_kl, base.trpo.max_kl);
        let e = base
            .clone()
            .with_overrides(r#"{"method": "gail"}"#, &src)
            .unwrap_err()
            .to_string();
        assert!(e.contains("another task or method"), "{e}");
        let e = base
            .with_overrides(r#"{"trpoo": {}}"#, &src)
            .unwrap_err()
            .to_string();
        assert!(e.contains("trpoo"), "{e}");

        let dir = tmp.path().join("r");
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("config.json"), "{}").unwrap();
        let mut cfg = RunConfig::for_task(EnvId::Reacher, Method::Expert);
        cfg.steps = 128;
        let e = run(
            &dir,
            Some(cfg),
            false,
            &AtomicBool::new(false),
            &mut crate::Silent,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("already holds a run"), "{e}");
    }

    #[test]
    fn evaluation_breaks_the_return_into_the_tasks_reward_terms() {
        let mut env = WatchedEnv::new(EnvId::Ant).unwrap();
        let cfg = RunConfig::for_task(EnvId::Ant, Method::Expert);
        let trainer = TrpoTrainer::new(cfg.trpo, 27, 8, None, 0).unwrap();
        let report = evaluate(
            &mut env,
            trainer.policy(),
            3,
            Some(40),
            &mut ChaCha8Rng::seed_from_u64(1),
        )
        .unwrap();
        let terms: f64 = report
            .info_totals
            .iter()
            .filter(|(k, _)| k.starts_with("reward_"))
            .map(|e| e.1)
            .sum();
        assert!(
            (terms - report.mean_return()).abs() < 1e-9,
            "{terms} vs {}",
            report.mean_return()
        );
        let keys: Vec<&str> = report.info_totals.iter().map(|e| e.0.as_str()).collect();
        for k in [
            "reward_forward",
            "reward_ctrl",
            "reward_contact",
            "reward_survive",
            "x_velocity",
        ] {
            assert!(keys.contains(&k), "{k} missing from {keys:?}");
        }
    }

    #[test]
    fn config_validation_names_the_field() {
        let mut c = RunConfig::for_task(EnvId::Ant, Method::Red);
        assert!(c.validate().unwrap_err().to_string().contains("demo"));
        c.demo = Some("x.json".into());
        c.validate().unwrap();
        c.sigma1 = Sigma1::Fixed(-1.0);
        assert!(c.validate().unwrap_err().to_string().contains("sigma1"));
        c.sigma1 = Sigma1::Fixed(1.0);
        c.trpo.max_kl = 0.0;
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains("trpo") && e.contains("max_kl"), "{e}");
        let json = r#"{"env": "Ant-v5", "method": "red", "sigmaa1": 3}"#;
        let e = serde_json::from_str::<RunConfig>(json)
            .unwrap_err()
            .to_string();
        assert!(e.contains("sigmaa1"), "{e}");
        // The release's per-task settings, and RED's measured changes to
        // them: standardised RND input, width 128 on HalfCheetah, a longer
        // warm start and a smaller first log-std where it is warm-started.
        let h = RunConfig::for_task(EnvId::HalfCheetah, Method::Red);
        assert_eq!((h.rnd.output, h.bc_warm_start_epochs), (128, 100));
        assert!(h.rnd.standardize);
        assert_eq!(h.trpo.policy.init_log_std, -1.0);
        // Since session 48 RED on HalfCheetah discounts as on Hopper; its
        // other methods and RED on Ant keep the release's discount.
        let g = &h.trpo.gae;
        assert_eq!(
            (g.gamma, g.lambda, g.bootstrap_on_truncation),
            (0.99, 0.98, true)
        );
        assert_eq!(
            h.sigma1,
            Sigma1::Calibrated {
                quantile: 0.9,
                reward: 0.5
            }
        );
        let hg = RunConfig::for_task(EnvId::HalfCheetah, Method::Gail)
            .trpo
            .gae;
        assert_eq!((hg.gamma, hg.bootstrap_on_truncation), (0.97, false));
        let a = RunConfig::for_task(EnvId::Ant, Method::Red);
        assert_eq!(
            (a.trpo.gae.gamma, a.trpo.gae.bootstrap_on_truncation),
            (0.97, false)
        );
        assert_eq!(
            (a.bc_warm_start_epochs, a.trpo.policy.init_log_std),
            (100, -2.0)
        );
        assert_eq!(
            a.sigma1,
            Sigma1::Calibrated {
                quantile: 0.9,
                reward: 0.5
            }
        );
        assert_eq!(
            RunConfig::for_task(EnvId::Hopper, Method::Red).sigma1,
            RedRewardConfig::default().sigma1
        );
        // Since session 48 RED on Walker2d is calibrated and discounts as
        // on HalfCheetah.
        let w = RunConfig::for_task(EnvId::Walker2d, Method::Red);
        assert_eq!(w.sigma1, h.sigma1);
        assert_eq!(w.trpo.gae, h.trpo.gae);
        let a = RunConfig::for_task(EnvId::Ant, Method::Ae);
        assert_eq!(
            (a.bc_warm_start_epochs, a.trpo.policy.init_log_std),
            (10, 0.0)
        );
        let w = RunConfig::for_task(EnvId::Walker2d, Method::Red);
        assert_eq!(
            (w.bc_warm_start_epochs, w.trpo.policy.init_log_std),
            (100, -1.0)
        );
        // Hopper since session 25 (issue 21): warm-started like Walker2d.
        let p = RunConfig::for_task(EnvId::Hopper, Method::Red);
        assert_eq!(
            (p.bc_warm_start_epochs, p.trpo.policy.init_log_std),
            (100, -1.0)
        );
        // and, since session 27, its reward sees clipped actions (RED only);
        // since session 47 it discounts as the Hopper expert (RED only).
        assert!(p.reward_clips_actions);
        let g = &p.trpo.gae;
        assert_eq!(
            (g.gamma, g.lambda, g.bootstrap_on_truncation),
            (0.99, 0.98, true)
        );
        let gail = RunConfig::for_task(EnvId::Hopper, Method::Gail).trpo.gae;
        assert_eq!((gail.gamma, gail.bootstrap_on_truncation), (0.97, false));
        let wg = RunConfig::for_task(EnvId::Walker2d, Method::Gail).trpo.gae;
        assert_eq!(wg.gamma, 0.97);
        assert!(!RunConfig::for_task(EnvId::Hopper, Method::Gail).reward_clips_actions);
        assert!(!w.reward_clips_actions);
        let r = RunConfig::for_task(EnvId::Reacher, Method::Red);
        assert!(r.rnd.standardize && r.rnd.output == 20);
        // Reacher since session 31: warm-started like the others.
        assert_eq!(
            (r.bc_warm_start_epochs, r.trpo.policy.init_log_std),
            (100, -1.0)
        );
        assert_eq!(
            RunConfig::release_sigma1(EnvId::HalfCheetah, Method::Red),
            25_000.0
        );
        let r = RunConfig::for_task(EnvId::Reacher, Method::Ae);
        assert_eq!((r.autoencoder.hidden, r.trpo.gae.gamma), (100, 0.99));
        assert_eq!(
            RunConfig::release_sigma1(EnvId::Walker2d, Method::Ae),
            100.0
        );
        let g = RunConfig::for_task(EnvId::Ant, Method::Gail);
        assert!(!g.freeze_obs_norm_from_demo && g.bc_warm_start_epochs == 0);
    }

    #[test]
    fn every_mujoco_settings_file_in_data_applies() {
        // The `--config` files shipped in data/ (experts' TRPO settings,
        // RED's earlier defaults) must keep reading as the config grows.
        let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data");
        let mut files: Vec<PathBuf> = Vec::new();
        for dir in [data.clone(), data.join("mujoco-red-first-settings")] {
            for e in std::fs::read_dir(&dir).unwrap() {
                let p = e.unwrap().path();
                let name = p.file_name().unwrap().to_string_lossy().into_owned();
                let ours = dir != data || name.starts_with("mujoco-");
                if ours && name.ends_with(".json") {
                    files.push(p);
                }
            }
        }
        assert!(files.len() >= 10, "found only {files:?}");
        let mut big = None;
        for f in &files {
            let method = if f.to_string_lossy().contains("expert") {
                Method::Expert
            } else {
                Method::Red
            };
            let text = std::fs::read_to_string(f).unwrap();
            let c = RunConfig::for_task(EnvId::Walker2d, method).with_overrides(&text, f);
            let c = c.unwrap_or_else(|e| panic!("{}: {e}", f.display()));
            if f.ends_with("mujoco-expert-config-big-batch.json") {
                big = Some(c);
            }
        }
        let big = big.expect("data/mujoco-expert-config-big-batch.json");
        assert_eq!(big.trpo.steps_per_batch, 4096);
        assert!(big.trpo.gae.bootstrap_on_truncation);
    }
}
