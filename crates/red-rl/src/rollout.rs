//! Running a [`GaussianPolicy`] in an environment: collecting on-policy
//! batches for learning ([`RolloutCollector`]) and evaluating a policy with
//! deterministic actions ([`evaluate`]).
//!
//! Returns are always the environment's TRUE reward: when the environment
//! is wrapped by [`red_core::RewardWrapper`], the true reward is read from
//! its info ([`red_core::TRUE_REWARD`]), otherwise the step's own reward.

use ndarray::Array2;
use rand::{Rng, RngExt};
use red_core::{Env, Space, run_episode};
use serde::{Deserialize, Serialize};

use crate::policy::{GaussianPolicy, PolicyWorkspace};
use crate::{Error, Result};

pub use red_core::episode::true_reward;

/// Bounds of a box action space, or an error naming what is wrong.
///
/// # Errors
/// [`Error::InvalidConfig`] for a discrete action space,
/// [`Error::ShapeMismatch`] if its dimension is not `act_dim`.
pub fn action_bounds<E: Env + ?Sized>(env: &E, act_dim: usize) -> Result<(Vec<f64>, Vec<f64>)> {
    match env.action_space() {
        Space::Box(b) if b.dim() == act_dim => Ok((b.low.clone(), b.high.clone())),
        Space::Box(b) => Err(Error::ShapeMismatch {
            what: "environment action space".into(),
            expected: format!("{act_dim} dimensions (the policy's)"),
            got: format!("{}", b.dim()),
        }),
        Space::Discrete(_) => Err(Error::InvalidConfig {
            field: "action_space".into(),
            reason: "a Gaussian policy needs a continuous (box) action space".into(),
        }),
    }
}

fn check_obs_space<E: Env + ?Sized>(env: &E, obs_dim: usize) -> Result<()> {
    let d = env.observation_space().dim();
    if d != obs_dim {
        return Err(Error::ShapeMismatch {
            what: "environment observation space".into(),
            expected: format!("{obs_dim} dimensions (the policy's)"),
            got: format!("{d}"),
        });
    }
    Ok(())
}

fn clip_into(a: &[f64], low: &[f64], high: &[f64], out: &mut [f64]) {
    for j in 0..a.len() {
        out[j] = a[j].clamp(low[j], high[j]);
    }
}

/// Per-episode true returns and lengths of an evaluation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalReport {
    /// True return of each episode.
    pub returns: Vec<f64>,
    /// Length of each episode in steps.
    pub lengths: Vec<usize>,
    /// Every entry of the steps' infos (reward terms, velocities, ...)
    /// summed over each episode, then averaged over the episodes, in the
    /// order the environment first reported them. Divide by
    /// [`EvalReport::mean_length`] for a per-step mean.
    #[serde(default)]
    pub info_totals: Vec<(String, f64)>,
}

impl EvalReport {
    /// Mean true return.
    pub fn mean_return(&self) -> f64 {
        mean(&self.returns)
    }

    /// Standard deviation (population) of the true returns.
    pub fn std_return(&self) -> f64 {
        let m = self.mean_return();
        (self.returns.iter().map(|r| (r - m) * (r - m)).sum::<f64>()
            / self.returns.len().max(1) as f64)
            .sqrt()
    }

    /// Mean episode length.
    pub fn mean_length(&self) -> f64 {
        self.lengths.iter().sum::<usize>() as f64 / self.lengths.len().max(1) as f64
    }
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

/// Runs `episodes` episodes with the policy's deterministic (mean) actions,
/// clipped to the action space, each reset with a seed drawn from `rng`,
/// and at most `max_steps` steps each (`None`: until the environment ends
/// the episode; wrap it in [`red_core::TimeLimit`] if it never does).
///
/// # Errors
/// Dimension mismatches between the policy and the environment, a discrete
/// action space, or an environment error.
pub fn evaluate<E: Env + ?Sized, R: Rng + ?Sized>(
    env: &mut E,
    policy: &GaussianPolicy,
    episodes: usize,
    max_steps: Option<usize>,
    rng: &mut R,
) -> Result<EvalReport> {
    run_episodes(env, policy, episodes, max_steps, rng, false)
}

/// As [`evaluate`], but with actions sampled from the policy's Gaussian (as
/// in training) instead of its mean. The resets use the same seeds as
/// [`evaluate`] with the same `rng`; the action noise comes from a stream
/// seeded by one more draw from `rng` after them.
///
/// # Errors
/// As [`evaluate`].
pub fn evaluate_sampled<E: Env + ?Sized, R: Rng + ?Sized>(
    env: &mut E,
    policy: &GaussianPolicy,
    episodes: usize,
    max_steps: Option<usize>,
    rng: &mut R,
) -> Result<EvalReport> {
    run_episodes(env, policy, episodes, max_steps, rng, true)
}

fn run_episodes<E: Env + ?Sized, R: Rng + ?Sized>(
    env: &mut E,
    policy: &GaussianPolicy,
    episodes: usize,
    max_steps: Option<usize>,
    rng: &mut R,
    sampled: bool,
) -> Result<EvalReport> {
    check_obs_space(env, policy.obs_dim())?;
    let (low, high) = action_bounds(env, policy.act_dim())?;
    let seeds: Vec<u64> = (0..episodes).map(|_| rng.random()).collect();
    let mut noise = sampled.then(|| {
        use rand::SeedableRng;
        rand_chacha::ChaCha8Rng::seed_from_u64(rng.random())
    });
    let mut ws = PolicyWorkspace::default();
    let mut a = vec![0.0; policy.act_dim()];
    let mut report = EvalReport {
        returns: Vec::with_capacity(episodes),
        lengths: Vec::with_capacity(episodes),
        info_totals: Vec::new(),
    };
    let mut totals: Vec<(&'static str, f64)> = Vec::new();
    for seed in seeds {
        let (obs, _) = env.reset(Some(seed))?;
        let run = run_episode(
            env,
            obs,
            max_steps,
            |_, obs| {
                policy.act_into(obs, noise.as_mut(), &mut ws, &mut a)?;
                let mut clipped = vec![0.0; a.len()];
                clip_into(&a, &low, &high, &mut clipped);
                Ok::<_, Error>(clipped)
            },
            |_, _, _, step| {
                for (k, v) in step.info.iter() {
                    match totals.iter_mut().find(|e| e.0 == k) {
                        Some(e) => e.1 += v,
                        None => totals.push((k, v)),
                    }
                }
                Ok(())
            },
        )?;
        report.returns.push(run.true_return);
        report.lengths.push(run.length);
    }
    let n = episodes.max(1) as f64;
    report.info_totals = totals
        .into_iter()
        .map(|(k, v)| (k.to_string(), v / n))
        .collect();
    Ok(report)
}

/// One on-policy batch of consecutive steps (possibly spanning episodes).
#[derive(Debug, Clone, PartialEq)]
pub struct RolloutBatch {
    /// Raw observations the actions were taken in, `(T, obs_dim)`.
    pub observations: Array2<f64>,
    /// The sampled actions, before clipping to the action space
    /// (the policy's log-probabilities and reward models use these),
    /// `(T, act_dim)`.
    pub actions: Array2<f64>,
    /// The environment's true rewards, `T`.
    pub true_rewards: Vec<f64>,
    /// Whether step `t` terminated its episode, `T`.
    pub terminated: Vec<bool>,
    /// Whether step `t` was cut by a time limit, `T`.
    pub truncated: Vec<bool>,
    /// Indices `t` whose next observation is not `observations[t + 1]`: the
    /// episode ended at `t`, or `t` is the batch's last step.
    pub boundary_steps: Vec<usize>,
    /// The next observation of each boundary step, `(boundary_steps.len(),
    /// obs_dim)`, in the same order.
    pub boundary_observations: Array2<f64>,
    /// True returns of the episodes that ended in this batch.
    pub episode_returns: Vec<f64>,
    /// Lengths of the episodes that ended in this batch.
    pub episode_lengths: Vec<usize>,
}

impl RolloutBatch {
    /// Number of steps `T`.
    pub fn len(&self) -> usize {
        self.true_rewards.len()
    }

    /// Whether the batch has no steps.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// The episode in progress between two batches.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Episode {
    /// The seed the episode was reset with.
    seed: u64,
    /// The (clipped) actions sent to the environment so far, flat.
    actions: Vec<f64>,
    /// The current observation.
    observation: Vec<f64>,
    true_return: f64,
    length: usize,
}

/// Collects batches of a fixed number of steps, continuing episodes across
/// batches (as the release does: a batch ends mid-episode and the next
/// batch goes on from there).
///
/// Every episode is reset with a seed drawn from the caller's environment
/// stream, and the actions of the episode in progress are kept, so a
/// collector restored from serde replays them into a fresh environment (the
/// [`Env`] contract: the same seed and the same actions give the same
/// trajectory) and resumes exactly where it stopped. The replay checks that
/// it reproduces the saved observation bit for bit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RolloutCollector {
    clip_actions: bool,
    episode: Option<Episode>,
    /// Whether the environment is known to be in `episode`'s state (false
    /// after deserialisation: the environment must be replayed).
    #[serde(skip)]
    synced: bool,
    #[serde(skip)]
    ws: PolicyWorkspaceSlot,
}

/// A [`PolicyWorkspace`] that compares equal and clones empty, so it does
/// not take part in the collector's identity.
#[derive(Debug, Default)]
struct PolicyWorkspaceSlot(PolicyWorkspace);

impl Clone for PolicyWorkspaceSlot {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl PartialEq for PolicyWorkspaceSlot {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl RolloutCollector {
    /// A collector with no episode in progress. With `clip_actions`, sampled
    /// actions are clipped to the action space before they reach the
    /// environment (the batch keeps the unclipped ones).
    pub fn new(clip_actions: bool) -> Self {
        Self {
            clip_actions,
            episode: None,
            synced: false,
            ws: PolicyWorkspaceSlot::default(),
        }
    }

    /// Makes the environment's state that of the episode in progress: a
    /// no-op when it already is; after deserialisation, replays the episode.
    fn sync<E: Env + ?Sized>(&mut self, env: &mut E) -> Result<()> {
        if self.synced {
            return Ok(());
        }
        if let Some(ep) = &self.episode {
            let (mut obs, _) = env.reset(Some(ep.seed))?;
            let k = env.action_space().dim();
            for (i, a) in ep.actions.chunks(k.max(1)).enumerate() {
                let step = env.step(a)?;
                if step.terminated || step.truncated {
                    return Err(replay_error(format!(
                        "the episode ended at step {i} of the replay"
                    )));
                }
                obs = step.observation;
            }
            if obs != ep.observation {
                return Err(replay_error(
                    "the replay reached another observation".into(),
                ));
            }
        }
        self.synced = true;
        Ok(())
    }

    /// Runs `policy` (sampling with `explore_rng`) for `steps` steps and
    /// returns the batch. New episodes are reset with seeds drawn from
    /// `env_rng`.
    ///
    /// # Errors
    /// Dimension mismatches, a discrete action space, an environment error,
    /// or a failed replay after deserialisation (a non-deterministic
    /// environment, or another environment than the one of the run).
    pub fn collect<E: Env + ?Sized, R1: Rng + ?Sized, R2: Rng + ?Sized>(
        &mut self,
        env: &mut E,
        policy: &GaussianPolicy,
        steps: usize,
        explore_rng: &mut R1,
        env_rng: &mut R2,
    ) -> Result<RolloutBatch> {
        let (od, ad) = (policy.obs_dim(), policy.act_dim());
        check_obs_space(env, od)?;
        let (low, high) = action_bounds(env, ad)?;
        self.sync(env)?;
        let mut batch = RolloutBatch {
            observations: Array2::zeros((steps, od)),
            actions: Array2::zeros((steps, ad)),
            true_rewards: Vec::with_capacity(steps),
            terminated: Vec::with_capacity(steps),
            truncated: Vec::with_capacity(steps),
            boundary_steps: Vec::new(),
            boundary_observations: Array2::zeros((0, od)),
            episode_returns: Vec::new(),
            episode_lengths: Vec::new(),
        };
        let mut boundary_obs: Vec<f64> = Vec::new();
        let mut sent = vec![0.0; ad];
        for t in 0..steps {
            if self.episode.is_none() {
                let seed: u64 = env_rng.random();
                let (obs, _) = env.reset(Some(seed))?;
                check_len(&obs, od)?;
                self.episode = Some(Episode {
                    seed,
                    actions: Vec::new(),
                    observation: obs,
                    true_return: 0.0,
                    length: 0,
                });
            }
            let ep = self.episode.as_mut().expect("an episode is in progress");
            let obs_row = batch.observations.row_mut(t);
            let obs_slice = obs_row.into_slice().expect("contiguous row");
            obs_slice.copy_from_slice(&ep.observation);
            let act_slice = batch
                .actions
                .row_mut(t)
                .into_slice()
                .expect("contiguous row");
            policy.act_into(
                &ep.observation,
                Some(explore_rng),
                &mut self.ws.0,
                act_slice,
            )?;
            if self.clip_actions {
                clip_into(act_slice, &low, &high, &mut sent);
            } else {
                sent.copy_from_slice(act_slice);
            }
            let step = env.step(&sent)?;
            check_len(&step.observation, od)?;
            let r = true_reward(&step);
            ep.actions.extend_from_slice(&sent);
            ep.true_return += r;
            ep.length += 1;
            batch.true_rewards.push(r);
            batch.terminated.push(step.terminated);
            batch.truncated.push(step.truncated);
            let ended = step.terminated || step.truncated;
            if ended || t + 1 == steps {
                batch.boundary_steps.push(t);
                boundary_obs.extend_from_slice(&step.observation);
            }
            if ended {
                batch.episode_returns.push(ep.true_return);
                batch.episode_lengths.push(ep.length);
                self.episode = None;
            } else {
                ep.observation = step.observation;
            }
        }
        batch.boundary_observations =
            Array2::from_shape_vec((batch.boundary_steps.len(), od), boundary_obs).map_err(
                |e| Error::ShapeMismatch {
                    what: "boundary observations".into(),
                    expected: format!("{} columns", od),
                    got: e.to_string(),
                },
            )?;
        Ok(batch)
    }
}

fn check_len(obs: &[f64], dim: usize) -> Result<()> {
    if obs.len() != dim {
        return Err(Error::ShapeMismatch {
            what: "observation returned by the environment".into(),
            expected: format!("{dim} entries"),
            got: format!("{}", obs.len()),
        });
    }
    Ok(())
}

fn replay_error(detail: String) -> Error {
    Error::InvalidConfig {
        field: "environment".into(),
        reason: format!(
            "cannot resume the interrupted episode: {detail}. The environment must be the run's and \
             deterministic given its reset seed and actions"
        ),
    }
}
