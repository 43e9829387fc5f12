//! A run trained with Soft Actor-Critic ([`red_rl::sac::Sac`], our
//! addition): an `expert` on the task's own reward, or `red` and `ae` on
//! their imitation reward (fitted once on the demonstrations, as for TRPO;
//! SAC's tanh-squashed actions always lie in the action box, so the reward
//! sees the actions the task receives). [`super::launch::run_with`] hands
//! such runs here. The same folder, `config.json`, best checkpoint,
//! evaluation, `eval.json` and (for an expert) demonstrations as a TRPO
//! run; no behaviour-cloning warm start (SAC starts from a random policy;
//! `bc_warm_start_epochs`, `freeze_obs_norm_from_demo` and `trpo` are
//! TRPO's). Its own checkpoint (the learner whole, replay included, its
//! random stream and the fitted reward) is written every
//! `sac.checkpoint_steps` environment steps, on a stop request and at the
//! end, so that a resumed run ends with the numbers of an uninterrupted
//! one.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use rand_chacha::ChaCha8Rng;
use red_core::checkpoint::load_checkpoint_for;
use red_core::{Env, Seeder, Stream};
use red_mujoco::describe_warnings;
use red_mujoco::watched::MJ_N_WARNING;
use red_rl::episodic::EpisodicLearner;
use red_rl::policy::GaussianPolicy;
use red_rl::sac::Sac;
use serde::{Deserialize, Serialize};

use super::run::{
    BestRecord, Outcome, RunConfig, Trained, action_box, checkpoint_settings, finish_run,
    fit_run_reward, fitted_reward_note, load_run_demos, num, reward_pairs, run_env, save_policy,
};
use crate::imitation::ImitationReward;
use crate::{Error, Progress, Result, ResultExt, RunDir};

/// The checkpoint kind of a SAC run (a TRPO checkpoint is refused).
pub const SAC_CHECKPOINT_KIND: &str = "mujoco-sac";

/// `metrics.csv` of a SAC run: a row per training episode (the second
/// column is the environment step and the fifth the window's mean return,
/// as in a TRPO run's, so the grid's curves read both).
const SAC_METRICS_HEADER: &str =
    "episode,env_steps,length,true_return,true_return_window,alpha,mujoco_warnings,wall_s";

/// `metrics.csv` of a `red` or `ae` run: the same with the episode's sum
/// of imitation rewards before the wall time.
const SAC_IMITATION_METRICS_HEADER: &str = "episode,env_steps,length,true_return,true_return_window,alpha,mujoco_warnings,imitation_return,wall_s";

/// Seconds between rewrites of `metrics.csv` between checkpoints (Hopper
/// starts with episodes of a few dozen steps: a rewrite per episode would
/// write the growing file thousands of times).
const METRICS_EVERY_S: u64 = 10;

/// Everything a SAC run needs to continue exactly where it stopped.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SacState {
    sac: Sac,
    rng: ChaCha8Rng,
    episodes: u64,
    recent: VecDeque<f64>,
    best: Option<BestRecord>,
    mujoco_warnings: [u64; MJ_N_WARNING],
    /// `metrics.csv` as of this state.
    metrics: String,
    /// Wall time spent in earlier sessions of the run.
    wall_s: f64,
    /// The imitation reward of a `red` or `ae` run (`None` for an expert;
    /// checkpoints of expert runs from before it existed have none).
    #[serde(default)]
    reward: Option<ImitationReward>,
}

impl SacState {
    fn fresh(
        cfg: &RunConfig,
        obs_dim: usize,
        act_dim: usize,
        reward: Option<ImitationReward>,
    ) -> Result<Self> {
        let seeder = Seeder::new(cfg.seed);
        let mut init = seeder.rng(Stream::Init);
        let pc = red_rl::policy::GaussianPolicyConfig {
            squash: true,
            ..cfg.sac.policy.clone()
        };
        let policy = GaussianPolicy::new(&pc, obs_dim, act_dim, None, &mut init)?;
        let sac = Sac::new(&sac_learner(cfg), policy, &mut init)?;
        Ok(Self {
            sac,
            rng: seeder.rng(Stream::Exploration),
            episodes: 0,
            recent: VecDeque::new(),
            best: None,
            mujoco_warnings: [0; MJ_N_WARNING],
            metrics: match reward {
                Some(_) => format!("{SAC_IMITATION_METRICS_HEADER}\n"),
                None => format!("{SAC_METRICS_HEADER}\n"),
            },
            wall_s: 0.0,
            reward,
        })
    }

    /// Values that make no sense even in a whole file.
    fn check(&self, cfg: &RunConfig) -> std::result::Result<(), String> {
        if self.sac.config() != &sac_learner(cfg) {
            return Err(
                "the SAC learner was made with other settings than config.json's sac".into(),
            );
        }
        crate::checks::check_policy("the policy", self.sac.policy(), &cfg.sac.policy)?;
        let wants_reward = cfg.method.needs_demo();
        if wants_reward != self.reward.is_some() {
            return Err(format!(
                "a `{}` run {} a fitted imitation reward, and the checkpoint {} one",
                cfg.method.name(),
                if wants_reward {
                    "needs"
                } else {
                    "has no use for"
                },
                if self.reward.is_some() {
                    "holds"
                } else {
                    "does not hold"
                }
            ));
        }
        if self.sac.replay_len() as u64 > self.sac.env_steps() {
            return Err(format!(
                "holds {} replayed transitions after {} environment steps",
                self.sac.replay_len(),
                self.sac.env_steps()
            ));
        }
        Ok(())
    }

    fn save(&mut self, rd: &RunDir, cfg: &RunConfig, wall_s: f64) -> Result<()> {
        self.wall_s = wall_s;
        rd.write("metrics.csv", self.metrics.as_bytes())?;
        rd.save_checkpoint(SAC_CHECKPOINT_KIND, &checkpoint_settings(cfg), &*self)
    }
}

/// Trains (or, with `resume`, continues) the SAC run of `rd`, whose
/// `config.json` already holds `cfg`, then evaluates it as
/// [`super::launch::run_with`] does.
pub(super) fn run(
    rd: RunDir,
    cfg: RunConfig,
    resume: bool,
    stop: &AtomicBool,
    progress: &mut dyn Progress,
) -> Result<Outcome> {
    cfg.validate()?;
    for n in rd.notes() {
        progress.note(n);
    }
    let session = Instant::now();
    let mut env = run_env(&cfg)?;
    let act_box = action_box(&env)?;
    if act_box.low.iter().any(|&l| l != -1.0) || act_box.high.iter().any(|&h| h != 1.0) {
        return Err(Error::InvalidConfig {
            field: "learner".into(),
            reason: format!(
                "SAC's tanh-squashed actions lie in (-1, 1), but {}'s action box is not [-1, 1]",
                cfg.env
            ),
        });
    }
    let demos = match &cfg.demo {
        Some(p) if cfg.method.needs_demo() => Some(load_run_demos(p, &cfg)?),
        _ => None,
    };
    let ckpt = rd.file("checkpoint.json");
    let mut state = if resume && ckpt.is_file() {
        let s: SacState =
            load_checkpoint_for(&ckpt, SAC_CHECKPOINT_KIND, &checkpoint_settings(&cfg))
                .with_context(|| format!("resuming {}", rd.path().display()))?;
        s.check(&cfg).map_err(|reason| Error::Input {
            path: ckpt.clone(),
            reason: format!("{reason}; the checkpoint cannot be resumed"),
        })?;
        s
    } else {
        let (od, ad) = (env.observation_space().dim(), act_box.dim());
        let reward = match &demos {
            Some(d) => {
                let (es, ea) = reward_pairs(&cfg, d, &act_box)?;
                let r = fit_run_reward(&cfg, &es, &ea, &d.context_dims())?;
                if let Some(msg) = r
                    .as_ref()
                    .map(|r| fitted_reward_note(&cfg, r, d, &act_box))
                    .transpose()?
                    .flatten()
                {
                    progress.note(&msg);
                }
                r
            }
            None => None,
        };
        let mut s = SacState::fresh(&cfg, od, ad, reward)?;
        s.save(&rd, &cfg, 0.0)?;
        s
    };
    if resume && rd.file("eval.json").is_file() && state.sac.env_steps() >= cfg.steps {
        return Ok(Outcome::Finished);
    }
    let wall_before = state.wall_s;
    let wall = |session: &Instant| wall_before + session.elapsed().as_secs_f64();
    progress.start(
        &format!("{} {} (SAC)", super::short_name(cfg.env), cfg.method.name()),
        cfg.steps,
        state.sac.env_steps().min(cfg.steps),
    );
    let every = cfg.sac.checkpoint_steps;
    let mut last_write = Instant::now();
    while state.sac.env_steps() < cfg.steps {
        if stop.load(Ordering::SeqCst) {
            state.save(&rd, &cfg, wall(&session))?;
            progress.note(&format!(
                "stopped at env step {} (episode {}); checkpoint saved in {}",
                state.sac.env_steps(),
                state.episodes,
                rd.path().display()
            ));
            progress.finish();
            return Ok(Outcome::Interrupted);
        }
        let before = state.sac.env_steps();
        let left = cfg.steps - before;
        let ep = match &state.reward {
            Some(r) => state
                .sac
                .run_episode(&mut env, r, None, &|_, _| 0.0, left, &mut state.rng),
            None => state
                .sac
                .run_env_episode(&mut env, None, left, &mut state.rng),
        }
        .with_context(|| {
            format!(
                "SAC episode {} from env step {before} (last good checkpoint kept: {})",
                state.episodes + 1,
                ckpt.display()
            )
        })?;
        state.episodes += 1;
        let step = state.sac.env_steps();
        let fresh = env.take_warnings();
        if fresh.iter().any(|&n| n > 0) {
            progress.note(&format!(
                "MuJoCo warnings in the episode ending at env step {step}: {} (the simulation was reset by MuJoCo; check the actions and the model)",
                describe_warnings(&fresh)
            ));
            for (total, n) in state.mujoco_warnings.iter_mut().zip(fresh) {
                *total += n;
            }
        }
        let ret = ep.report.true_return;
        state.recent.push_back(ret);
        if state.recent.len() > cfg.best_window {
            state.recent.pop_front();
        }
        let window = state.recent.iter().sum::<f64>() / state.recent.len() as f64;
        // The window counts once it is full: the first episodes' returns are
        // the uniform actions'.
        if state.recent.len() == cfg.best_window
            && state
                .best
                .as_ref()
                .is_none_or(|b| window > b.mean_true_return)
        {
            save_policy(&rd.file("best_policy.json"), state.sac.policy())?;
            state.best = Some(BestRecord {
                mean_true_return: window,
                env_steps: step,
                iteration: state.episodes,
            });
        }
        let imitation = match state.reward {
            Some(_) => format!("{},", num(ep.report.imitation_return)),
            None => String::new(),
        };
        let row = format!(
            "{},{step},{},{},{},{},{},{imitation}{:.3}\n",
            state.episodes,
            ep.report.length,
            num(ret),
            num(window),
            num(state.sac.alpha()),
            state.mujoco_warnings.iter().sum::<u64>(),
            wall(&session)
        );
        state.metrics.push_str(&row);
        let msg = format!("return(last {}) {window:.1}", state.recent.len());
        if before / every != step / every {
            state.save(&rd, &cfg, wall(&session))?;
            progress.note(&format!("env step {step}: {msg}"));
            last_write = Instant::now();
        } else if last_write.elapsed().as_secs() >= METRICS_EVERY_S {
            rd.write("metrics.csv", state.metrics.as_bytes())?;
            last_write = Instant::now();
        }
        progress.advance(step.min(cfg.steps), &msg);
    }
    state.save(&rd, &cfg, wall(&session))?;
    let done = Trained {
        policy: state.sac.policy().clone(),
        env_steps: state.sac.env_steps(),
        best: state.best,
        reward: state.reward,
        mujoco_warnings: state.mujoco_warnings,
        wall_before,
    };
    finish_run(&rd, &cfg, demos.as_ref(), &act_box, done, session, progress)
}

/// SAC's settings for the run: `sac.learner`, with a time-limit cut ending
/// the return when the observations hold the time
/// ([`RunConfig::time_feature`]).
fn sac_learner(cfg: &RunConfig) -> red_rl::sac::SacConfig {
    red_rl::sac::SacConfig {
        end_at_truncation: cfg.time_feature,
        ..cfg.sac.learner.clone()
    }
}
