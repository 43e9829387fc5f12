//! The environment checker every environment of the project must pass.
//!
//! [`check_env`] plays the environment twice from one seed with the same
//! seeded random actions and checks, step by step:
//!
//! - the spaces are well formed and sampling the action space gives actions
//!   inside it;
//! - `reset` returns a finite observation inside the observation space;
//! - every observation is finite and inside the observation space, every
//!   reward and info value is finite, and `terminated` and `truncated` are
//!   never both set (only [`crate::TimeLimit`] sets `truncated`, and
//!   `terminated` wins);
//! - the two runs are identical, bit for bit: observations, rewards, flags,
//!   info keys and values (episodes after the first start with
//!   `reset(None)`, so continuing the random stream is checked too);
//! - `step` after the end of an episode fails with
//!   [`Error::NeedsReset`] (or, with [`CheckConfig::allow_step_after_end`],
//!   an environment documented to go on may return a step);
//! - a malformed action (wrong length, NaN) is rejected with an error.
//!
//! ```
//! use red_core::check::check_env;
//! # use red_core::{BoxSpace, Env, Error, Info, Result, Space, Step, TimeLimit};
//! # struct Walk { pos: Option<f64>, obs: Space, act: Space }
//! # impl Env for Walk {
//! #     fn observation_space(&self) -> &Space { &self.obs }
//! #     fn action_space(&self) -> &Space { &self.act }
//! #     fn reset(&mut self, _seed: Option<u64>) -> Result<(Vec<f64>, Info)> {
//! #         self.pos = Some(0.0); Ok((vec![0.0], Info::new()))
//! #     }
//! #     fn step(&mut self, a: &[f64]) -> Result<Step> {
//! #         self.act.check("action", a)?;
//! #         let pos = self.pos.as_mut().ok_or(Error::NeedsReset { reason: "ended".into() })?;
//! #         *pos = (*pos + a[0]).clamp(-10.0, 10.0);
//! #         let p = *pos;
//! #         let terminated = p.abs() >= 10.0;
//! #         if terminated { self.pos = None; }
//! #         Ok(Step { observation: vec![p], reward: -p.abs(), terminated,
//! #                   truncated: false, info: Info::new() })
//! #     }
//! # }
//! # let walk = Walk { pos: None, obs: Space::Box(BoxSpace::uniform(1, -10.0, 10.0)),
//! #                   act: Space::Box(BoxSpace::uniform(1, -1.0, 1.0)) };
//! // `walk` is a one-dimensional random walk that ends at |x| = 10.
//! let mut env = TimeLimit::new(walk, 20)?;
//! let report = check_env(&mut env, 0, 100)?;
//! assert_eq!(report.steps, 100);
//! assert!(report.episodes >= 5);
//! # Ok::<(), red_core::Error>(())
//! ```

use std::fmt;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::{Env, Error, Info, Result, Space, Step};

/// Settings of [`check_env_with`].
#[derive(Debug, Clone, PartialEq)]
pub struct CheckConfig {
    /// Seed of the first `reset` and of the random actions.
    pub seed: u64,
    /// Number of steps played in each of the two runs (episodes are reset
    /// as they end).
    pub steps: usize,
    /// Accept an environment that returns a step when stepped after its
    /// episode ended, instead of failing with [`Error::NeedsReset`]. Set it
    /// only for an environment whose documentation says it goes on.
    pub allow_step_after_end: bool,
}

impl Default for CheckConfig {
    /// Seed 0, 200 steps (enough for several episodes of the small test
    /// environments and quick in debug builds), and stepping after the end
    /// must fail.
    fn default() -> Self {
        Self {
            seed: 0,
            steps: 200,
            allow_step_after_end: false,
        }
    }
}

/// What stepping after the end of an episode did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AfterEnd {
    /// It failed with [`Error::NeedsReset`], as it should.
    NeedsReset,
    /// It returned a step (accepted only with
    /// [`CheckConfig::allow_step_after_end`]).
    Continues,
    /// No episode ended within the steps played, so it was not tried.
    NotReached,
}

/// What [`check_env`] saw in a passing environment.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckReport {
    /// Steps played in each run.
    pub steps: usize,
    /// Episodes that ended within those steps.
    pub episodes: usize,
    /// Of those, how many were terminated.
    pub terminated: usize,
    /// Of those, how many were truncated.
    pub truncated: usize,
    /// Length of an observation.
    pub obs_dim: usize,
    /// Length of an action.
    pub act_dim: usize,
    /// Info keys seen, in the order first seen.
    pub info_keys: Vec<&'static str>,
    /// What stepping after an episode's end did.
    pub after_end: AfterEnd,
}

impl fmt::Display for CheckReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "env check passed: {} steps twice, {} episodes ended ({} terminated, {} truncated), \
             obs dim {}, act dim {}, info keys {:?}, step after end: {:?}",
            self.steps,
            self.episodes,
            self.terminated,
            self.truncated,
            self.obs_dim,
            self.act_dim,
            self.info_keys,
            self.after_end
        )
    }
}

/// Checks `env` with the default settings, `seed` and `steps` steps per run:
/// see the [module documentation](self) for the properties.
///
/// # Errors
/// [`Error::EnvCheck`] naming the first property broken, the run, step and
/// values involved; any error the environment returns where it should not
/// is wrapped in an [`Error::EnvCheck`] too.
pub fn check_env<E: Env + ?Sized>(env: &mut E, seed: u64, steps: usize) -> Result<CheckReport> {
    check_env_with(
        env,
        &CheckConfig {
            seed,
            steps,
            ..CheckConfig::default()
        },
    )
}

/// Checks `env` with explicit settings.
///
/// # Errors
/// As [`check_env`].
pub fn check_env_with<E: Env + ?Sized>(env: &mut E, config: &CheckConfig) -> Result<CheckReport> {
    let obs_space = env.observation_space().clone();
    let act_space = env.action_space().clone();
    obs_space
        .validate()
        .map_err(|e| fail(format!("observation space {obs_space:?} is malformed: {e}")))?;
    act_space
        .validate()
        .map_err(|e| fail(format!("action space {act_space:?} is malformed: {e}")))?;
    if act_space.dim() == 0 {
        return Err(fail("action space has dimension 0".into()));
    }
    check_sampling(&act_space, config.seed)?;

    let first = play(env, &obs_space, &act_space, config, 1)?;
    let second = play(env, &obs_space, &act_space, config, 2)?;
    compare(&first.events, &second.events)?;
    check_malformed_actions(env, &act_space, config.seed)?;

    let mut info_keys = Vec::new();
    for ev in &first.events {
        for (k, _) in ev.info().iter() {
            if !info_keys.contains(&k) {
                info_keys.push(k);
            }
        }
    }
    Ok(CheckReport {
        steps: config.steps,
        episodes: first.terminated + first.truncated,
        terminated: first.terminated,
        truncated: first.truncated,
        obs_dim: obs_space.dim(),
        act_dim: act_space.dim(),
        info_keys,
        after_end: first.after_end,
    })
}

fn fail(reason: String) -> Error {
    Error::EnvCheck { reason }
}

/// Sampled actions must lie inside the action space.
fn check_sampling(space: &Space, seed: u64) -> Result<()> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5a5a_5a5a);
    for i in 0..100 {
        let a = space.sample(&mut rng);
        if !space.contains(&a) {
            return Err(fail(format!(
                "action sampling: sample {i} = {a:?} is outside the action space {space:?}"
            )));
        }
    }
    Ok(())
}

/// One thing that happened in a run, kept to compare the two runs.
#[derive(Debug, Clone, PartialEq)]
enum Event {
    Reset {
        observation: Vec<f64>,
        info: Info,
    },
    Step {
        action: Vec<f64>,
        step: Step,
    },
    /// Stepping after the end returned a step (allowed by the config).
    AfterEnd(Step),
}

impl Event {
    fn info(&self) -> &Info {
        match self {
            Event::Reset { info, .. } => info,
            Event::Step { step, .. } | Event::AfterEnd(step) => &step.info,
        }
    }
}

struct Run {
    events: Vec<Event>,
    terminated: usize,
    truncated: usize,
    after_end: AfterEnd,
}

fn play<E: Env + ?Sized>(
    env: &mut E,
    obs_space: &Space,
    act_space: &Space,
    config: &CheckConfig,
    run: usize,
) -> Result<Run> {
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
    let mut events = Vec::with_capacity(config.steps + 8);
    let mut out = Run {
        events: Vec::new(),
        terminated: 0,
        truncated: 0,
        after_end: AfterEnd::NotReached,
    };
    let mut episode = 0;
    let mut t = 0;
    reset(env, obs_space, Some(config.seed), run, episode, &mut events)?;
    for k in 0..config.steps {
        let action = act_space.sample(&mut rng);
        let step = env.step(&action).map_err(|e| {
            fail(format!(
                "step failed: run {run}, step {k} (episode {episode}, t = {t}), action {action:?}: {e}"
            ))
        })?;
        let at = format!("run {run}, step {k} (episode {episode}, t = {t})");
        check_step(&step, obs_space, &at)?;
        let ended = step.terminated || step.truncated;
        if step.terminated {
            out.terminated += 1;
        } else if step.truncated {
            out.truncated += 1;
        }
        events.push(Event::Step { action, step });
        t += 1;
        if ended {
            if episode == 0 {
                out.after_end = step_after_end(env, act_space, config, &at, &mut rng, &mut events)?;
            }
            episode += 1;
            t = 0;
            reset(env, obs_space, None, run, episode, &mut events)?;
        }
    }
    out.events = events;
    Ok(out)
}

fn reset<E: Env + ?Sized>(
    env: &mut E,
    obs_space: &Space,
    seed: Option<u64>,
    run: usize,
    episode: usize,
    events: &mut Vec<Event>,
) -> Result<()> {
    let (observation, info) = env.reset(seed).map_err(|e| {
        fail(format!(
            "reset failed: run {run}, episode {episode}, seed {seed:?}: {e}"
        ))
    })?;
    let at = format!("reset of run {run}, episode {episode}");
    check_observation(&observation, obs_space, &at)?;
    check_info(&info, &at)?;
    events.push(Event::Reset { observation, info });
    Ok(())
}

fn step_after_end<E: Env + ?Sized>(
    env: &mut E,
    act_space: &Space,
    config: &CheckConfig,
    at: &str,
    rng: &mut ChaCha8Rng,
    events: &mut Vec<Event>,
) -> Result<AfterEnd> {
    let action = act_space.sample(rng);
    match env.step(&action) {
        Err(Error::NeedsReset { .. }) => Ok(AfterEnd::NeedsReset),
        Err(e) => Err(fail(format!(
            "step after end: after the episode ended at {at}, step({action:?}) failed with \
             `{e}` instead of Error::NeedsReset"
        ))),
        Ok(step) if config.allow_step_after_end => {
            events.push(Event::AfterEnd(step));
            Ok(AfterEnd::Continues)
        }
        Ok(step) => Err(fail(format!(
            "step after end: after the episode ended at {at}, step({action:?}) returned a step \
             (observation {:?}, reward {}) instead of Error::NeedsReset; if the environment is \
             documented to go on, check it with CheckConfig::allow_step_after_end",
            step.observation, step.reward
        ))),
    }
}

fn check_observation(obs: &[f64], space: &Space, at: &str) -> Result<()> {
    if obs.len() != space.dim() {
        return Err(fail(format!(
            "observation length: {at}: observation has {} numbers, the observation space {}",
            obs.len(),
            space.dim()
        )));
    }
    if let Some((i, v)) = obs.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(fail(format!(
            "finite observation: {at}: observation[{i}] = {v} in {obs:?}"
        )));
    }
    if !space.contains(obs) {
        let detail = match space {
            Space::Box(b) => obs
                .iter()
                .enumerate()
                .find(|(i, v)| **v < b.low[*i] || **v > b.high[*i])
                .map(|(i, v)| {
                    format!(
                        "observation[{i}] = {v} outside [{}, {}]",
                        b.low[i], b.high[i]
                    )
                })
                .unwrap_or_default(),
            Space::Discrete(n) => format!("{} is not an integer in 0..{n}", obs[0]),
        };
        return Err(fail(format!(
            "observation in space: {at}: {detail}; observation {obs:?}"
        )));
    }
    Ok(())
}

fn check_info(info: &Info, at: &str) -> Result<()> {
    if let Some((k, v)) = info.iter().find(|(_, v)| !v.is_finite()) {
        return Err(fail(format!("finite info: {at}: info `{k}` = {v}")));
    }
    Ok(())
}

fn check_step(step: &Step, obs_space: &Space, at: &str) -> Result<()> {
    check_observation(&step.observation, obs_space, at)?;
    if !step.reward.is_finite() {
        return Err(fail(format!(
            "finite reward: {at}: reward = {}",
            step.reward
        )));
    }
    check_info(&step.info, at)?;
    if step.terminated && step.truncated {
        return Err(fail(format!(
            "terminated xor truncated: {at}: both flags set; terminated must win \
             (only TimeLimit sets truncated, and not on a terminal step)"
        )));
    }
    Ok(())
}

fn same_numbers(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

fn same_info(a: &Info, b: &Info) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b.iter())
            .all(|((ka, va), (kb, vb))| ka == kb && va.to_bits() == vb.to_bits())
}

fn describe(ev: &Event) -> String {
    match ev {
        Event::Reset { observation, info } => {
            format!("reset -> observation {observation:?}, info {info:?}")
        }
        Event::Step { action, step } => format!(
            "step({action:?}) -> observation {:?}, reward {}, terminated {}, truncated {}, info {:?}",
            step.observation, step.reward, step.terminated, step.truncated, step.info
        ),
        Event::AfterEnd(step) => format!(
            "step after end -> observation {:?}, reward {}",
            step.observation, step.reward
        ),
    }
}

/// Where two vectors first differ, in words (`[3]: 0.5 vs 0.25`).
fn first_difference(a: &[f64], b: &[f64]) -> String {
    if a.len() != b.len() {
        return format!(": lengths {} vs {}", a.len(), b.len());
    }
    a.iter()
        .zip(b)
        .position(|(x, y)| x.to_bits() != y.to_bits())
        .map(|j| format!("[{j}]: {} vs {}", a[j], b[j]))
        .unwrap_or_default()
}

fn compare(first: &[Event], second: &[Event]) -> Result<()> {
    let mut step = 0usize;
    for (i, (a, b)) in first.iter().zip(second).enumerate() {
        let what = match (a, b) {
            (
                Event::Reset {
                    observation: oa,
                    info: ia,
                },
                Event::Reset {
                    observation: ob,
                    info: ib,
                },
            ) => {
                if !same_numbers(oa, ob) {
                    Some(format!("reset observation{}", first_difference(oa, ob)))
                } else if !same_info(ia, ib) {
                    Some("reset info".to_string())
                } else {
                    None
                }
            }
            (Event::Step { step: sa, .. }, Event::Step { step: sb, .. })
            | (Event::AfterEnd(sa), Event::AfterEnd(sb)) => {
                if !same_numbers(&sa.observation, &sb.observation) {
                    Some(format!(
                        "observation{}",
                        first_difference(&sa.observation, &sb.observation)
                    ))
                } else if sa.reward.to_bits() != sb.reward.to_bits() {
                    Some(format!("reward: {} vs {}", sa.reward, sb.reward))
                } else if sa.terminated != sb.terminated || sa.truncated != sb.truncated {
                    Some("terminated/truncated flags".to_string())
                } else if !same_info(&sa.info, &sb.info) {
                    Some("info".to_string())
                } else {
                    None
                }
            }
            _ => Some("sequence of resets and steps".to_string()),
        };
        if let Some(what) = what {
            return Err(fail(format!(
                "determinism: two runs from the same seed differ at event {i} (step {step}) in \
                 the {what}; run 1 {}; run 2 {}",
                describe(a),
                describe(b)
            )));
        }
        if matches!(a, Event::Step { .. }) {
            step += 1;
        }
    }
    if first.len() != second.len() {
        return Err(fail(format!(
            "determinism: two runs from the same seed have {} and {} events",
            first.len(),
            second.len()
        )));
    }
    Ok(())
}

fn check_malformed_actions<E: Env + ?Sized>(env: &mut E, space: &Space, seed: u64) -> Result<()> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let good = space.sample(&mut rng);
    let mut long = good.clone();
    long.push(0.0);
    let mut nan = good;
    nan[0] = f64::NAN;
    for (what, action) in [
        ("an action one number too long", long),
        ("a NaN action", nan),
    ] {
        env.reset(Some(seed)).map_err(|e| {
            fail(format!(
                "reset failed before the malformed-action check: {e}"
            ))
        })?;
        if let Ok(step) = env.step(&action) {
            return Err(fail(format!(
                "malformed action rejected: step with {what} {action:?} returned a step \
                 (observation {:?}) instead of an error",
                step.observation
            )));
        }
    }
    Ok(())
}
