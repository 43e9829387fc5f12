//! Where a MuJoCo run starts: [`run_with`] opens the run folder and hands
//! the run to its learner, TRPO ([`super::run`]) or SAC (`sac_run`).

use std::path::Path;
use std::sync::atomic::AtomicBool;

use super::run::{self, MujocoLearner, Outcome, RunConfig, Start};
use super::sac_run;
use crate::{Progress, Result};

/// [`run_with`] with [`Start::Resume`] when `resume`, else [`Start::New`].
///
/// # Errors
/// As [`run_with`].
pub fn run(
    dir: &Path,
    cfg: Option<RunConfig>,
    resume: bool,
    stop: &AtomicBool,
    progress: &mut dyn Progress,
) -> Result<Outcome> {
    let start = if resume { Start::Resume } else { Start::New };
    run_with(dir, cfg, start, stop, progress)
}

/// Starts a new run in `dir` (which must not hold one, unless
/// [`Start::Force`] moves it aside) with `cfg`, or continues the one there
/// ([`Start::Resume`]: its `config.json` is used; `cfg` only supplies the
/// step budget: a larger one trains on, one at or below the steps done ends
/// the run there, with its evaluation). The folder is locked for the run's
/// life ([`crate::RunDir`]).
///
/// `stop` is checked before every TRPO iteration (every SAC episode): once set, the run saves
/// its checkpoint and returns [`Outcome::Interrupted`]. `progress` hears of
/// the fitted reward, each iteration (env steps and the recent return),
/// MuJoCo warnings, and the evaluation.
///
/// # Errors
/// Bad settings or files, a failed fit, a non-finite quantity during
/// training (the last good checkpoint is kept), an environment error; a
/// checkpoint that fails its checksum, was made with other settings than
/// `config.json` or holds values that make no sense.
pub fn run_with(
    dir: &Path,
    cfg: Option<RunConfig>,
    start: Start,
    stop: &AtomicBool,
    progress: &mut dyn Progress,
) -> Result<Outcome> {
    let (rd, cfg, resume) = run::open_run(dir, cfg, start)?;
    match cfg.learner {
        MujocoLearner::Trpo => run::train(rd, cfg, resume, stop, progress),
        MujocoLearner::Sac => sac_run::run(rd, cfg, resume, stop, progress),
    }
}
