//! The simple domain of the paper's Sec. 5.1 (Fig. 2 and 3) as library
//! code.
//!
//! For each expert-set size `n`, method and seed, a reward is fitted (RED,
//! AE) or set up to adapt (GAIL, GMMIL) on `n` expert pairs, and DQN learns
//! from it. Every `eval_interval` steps the greedy policy's TRUE mean reward
//! per step is measured on a fixed set of evaluation states (the task is
//! stateless, so this is the expected per-step reward of an episode). The
//! runs of the grid are independent; each is saved to the checkpoint when it
//! ends, so a stopped experiment resumes to the numbers of an uninterrupted
//! one.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use ndarray::{Array1, Array2};
use rand::RngExt;
use serde::{Deserialize, Serialize};

use red_core::simple_domain::{
    ActionValues, action_value, expert_demos, expert_demos_stratified, simple_domain,
    to_action_values,
};
use red_core::{Env, RewardModel, Seeder, Stream};
use red_rl::dqn::{Dqn, DqnConfig};
use red_rl::gail::GailConfig;
use red_rl::gmmil::GmmilConfig;
use red_support::{
    AutoencoderConfig, ExpertScores, RedReward, RedRewardConfig, RndConfig, SupportModel,
};

use crate::grid::OnFailure;
use crate::imitation::{ImitationReward, RewardSettings, fit_reward};
use crate::plot::{Panel, Series, draw_panels, mean_std};
use crate::{Error, Progress, Result, ResultExt, RunDir};

pub use crate::imitation::Method;

/// Which expert scores calibrate σ1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Calibration {
    /// Scores of each expert pair by a model fitted without it (k-fold).
    HeldOut,
    /// Scores of the pairs the model was fitted on.
    Train,
}

impl std::str::FromStr for Calibration {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "held-out" => Ok(Self::HeldOut),
            "train" => Ok(Self::Train),
            other => Err(format!("unknown calibration `{other}` (held-out or train)")),
        }
    }
}

/// How the expert states of the simple domain are drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Sampling {
    /// One uniform draw in each of `n` equal slices of [-1, 1].
    Stratified,
    /// Independent uniform draws on [-1, 1].
    Iid,
}

impl std::str::FromStr for Sampling {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "stratified" => Ok(Self::Stratified),
            "iid" => Ok(Self::Iid),
            other => Err(format!("unknown sampling `{other}` (stratified or iid)")),
        }
    }
}

/// Every setting of the simple-domain experiment, written to `config.json`
/// and kept in the checkpoint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ToyConfig {
    /// Expert-set sizes (the paper's 5, 10, 50, 100).
    pub n: Vec<usize>,
    /// Methods to compare.
    pub methods: Vec<Method>,
    /// Seeds per cell.
    pub seeds: u64,
    /// The first seed; cell seeds are `seed, seed + 1, ...`.
    pub seed: u64,
    /// DQN environment steps per run.
    pub steps: u64,
    /// Environment steps between evaluations.
    pub eval_interval: u64,
    /// DQN discount. The task is stateless (the next state does not depend
    /// on the action), so every discount gives the same greedy policy; 0
    /// removes the bootstrapping noise. The paper gives none.
    pub gamma: f64,
    /// DQN gradient steps: one every this many environment steps. CleanRL's
    /// default is 10; the toy's reward differences between the two actions
    /// near the decision boundary are small, and 1 lets the Q-network fit
    /// them within the short run.
    pub train_frequency: u64,
    /// Independent RND target/predictor pairs whose scores RED averages
    /// (the paper's Eq. 6 in its general form; the release trains 1).
    pub rnd_ensemble: usize,
    /// How the `n` expert states are drawn: stratified (one uniform draw in
    /// each of `n` equal slices of [-1, 1]) or iid (independent uniform
    /// draws, which at n = 5 miss one side of the task in one set out of
    /// 16).
    pub sampling: Sampling,
    /// Standardise the estimators' input `[s, a]` with the expert pairs'
    /// mean and standard deviation (RED and AE; the release does not).
    pub standardize: bool,
    /// Epochs of the RND predictor and the autoencoder (release: 200).
    pub epochs: usize,
    /// How σ1 of RED and AE is calibrated: on held-out expert pairs (k-fold,
    /// k = min(5, n)) or on the training pairs themselves. Either way the
    /// 90% quantile of the expert scores gets reward 0.9.
    pub calibration: Calibration,
    /// The expert-set size whose learned rewards Fig. 3 shows (default: 10
    /// if run, else the first size).
    pub fig3_n: Option<usize>,
}

impl Default for ToyConfig {
    /// The paper's grid (n = 5, 10, 50, 100; RED, AE, GAIL, GMMIL), 5 seeds,
    /// 10,000 DQN steps; the other values as their fields say.
    fn default() -> Self {
        Self {
            n: vec![5, 10, 50, 100],
            methods: vec![Method::Red, Method::Ae, Method::Gail, Method::Gmmil],
            seeds: 5,
            seed: 0,
            steps: 10_000,
            eval_interval: 500,
            gamma: 0.0,
            train_frequency: 1,
            rnd_ensemble: 1,
            sampling: Sampling::Stratified,
            standardize: false,
            epochs: 200,
            calibration: Calibration::HeldOut,
            fig3_n: None,
        }
    }
}

impl ToyConfig {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the field.
    pub fn validate(&self) -> Result<()> {
        let bad = |field: &str, reason: &str| {
            Err(Error::InvalidConfig {
                field: field.into(),
                reason: reason.into(),
            })
        };
        if self.n.is_empty() || self.n.contains(&0) {
            return bad("n", "give expert-set sizes of at least 1");
        }
        if self.methods.is_empty() {
            return bad("methods", "give at least one method");
        }
        if let Some(m) = self.methods.iter().find(|m| !m.imitates_by_reward()) {
            return bad(
                "methods",
                &format!("`{}`: the toy has red, ae, gail, gmmil", m.name()),
            );
        }
        if self.seeds == 0 {
            return bad("seeds", "must be at least 1");
        }
        if self.steps == 0 {
            return bad("steps", "must be at least 1");
        }
        if self.eval_interval == 0 {
            return bad("eval_interval", "must be at least 1");
        }
        if !(0.0..=1.0).contains(&self.gamma) {
            return bad("gamma", &format!("must be in [0, 1], got {}", self.gamma));
        }
        if self.rnd_ensemble == 0 {
            return bad("rnd_ensemble", "must be at least 1");
        }
        if self.train_frequency == 0 {
            return bad("train_frequency", "must be at least 1");
        }
        if self.epochs == 0 {
            return bad("epochs", "must be at least 1");
        }
        Ok(())
    }
}

/// Number of evaluation states (fixed per seed).
const EVAL_STATES: usize = 1_000;
/// Grid points of the learned-reward plot over `s in [-1, 1]`.
const GRID: usize = 201;

struct Job {
    method: Method,
    n: usize,
    seed: u64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct RunResult {
    curve: Vec<(u64, f64)>,
    /// True mean reward per step of the policy `argmax_a r(s, a)` under the
    /// final learned reward: what a perfect learner would reach on it, so
    /// the reward's quality can be told apart from DQN's.
    reward_argmax: f64,
    /// Learned reward over the grid for `a = -1` and `a = +1` (RED and AE:
    /// `1 - σ1 L`, the paper's Fig. 3 convention with `α1 = σ1`).
    reward_minus: Vec<f64>,
    reward_plus: Vec<f64>,
    sigma1: Option<f64>,
    /// α1 of the plotted `1 - α1 L` (RED and AE).
    alpha: Option<f64>,
}

/// The plotted reward of `(s, a)` for a batch: the support score `L` for
/// RED and AE (Fig. 3 plots `1 - α1 L`), the reward for the others.
fn plotted(
    reward: &ActionValues<ImitationReward>,
    s: &Array2<f64>,
    a: &Array2<f64>,
) -> Result<Array1<f64>> {
    Ok(match reward.0.support() {
        Some(r) => r
            .model()
            .score(s.view(), to_action_values(a.view()).view())?,
        None => reward.rewards(s.view(), a.view())?,
    })
}

impl Calibration {
    /// The expert scores this calibration uses with `n` expert pairs
    /// (held out: 5 folds, or one per pair below 5 pairs).
    fn scores(self, n: usize) -> ExpertScores {
        match self {
            Calibration::Train => ExpertScores::InSample,
            Calibration::HeldOut => ExpertScores::HeldOut { folds: n.min(5) },
        }
    }
}

fn ae_config(config: &ToyConfig) -> AutoencoderConfig {
    AutoencoderConfig {
        epochs: config.epochs,
        standardize: config.standardize,
        ..AutoencoderConfig::default()
    }
}

fn rnd_config(config: &ToyConfig) -> RndConfig {
    RndConfig {
        epochs: config.epochs,
        ensemble: config.rnd_ensemble,
        standardize: config.standardize,
        ..RndConfig::default()
    }
}

/// GAIL's discriminator in the toy: baselines' network and entropy bonus,
/// but 5 epochs per update at step size 1e-3, because a 10,000-step DQN
/// run gives it only 20 updates (baselines' TRPO runs give thousands).
fn gail_config() -> GailConfig {
    GailConfig {
        epochs: 5,
        learning_rate: 1e-3,
        ..GailConfig::default()
    }
}

fn one_minus_alpha_l(scores: Array1<f64>, alpha: f64) -> Array1<f64> {
    scores.mapv(|l| 1.0 - alpha * l)
}

fn dqn_config(config: &ToyConfig) -> DqnConfig {
    DqnConfig {
        gamma: config.gamma,
        // Adaptive rewards (GAIL, GMMIL) see each 500-step window of the
        // policy's pairs: 20 updates over the default 10,000 steps.
        reward_update_interval: 500,
        train_frequency: config.train_frequency,
        ..DqnConfig::default()
    }
}

fn run_one(config: &ToyConfig, job: &Job, on_eval: &dyn Fn()) -> Result<RunResult> {
    let seeder = Seeder::new(config.seed.wrapping_add(job.seed));
    let mut demo_rng = seeder.rng(Stream::Demo);
    let demos = match config.sampling {
        Sampling::Stratified => expert_demos_stratified(job.n, &mut demo_rng),
        Sampling::Iid => expert_demos(job.n, &mut demo_rng),
    };
    // The reward models see the paper's action values a in {-1, +1}.
    let (es, ea_index) = demos.pairs();
    let ea = to_action_values(ea_index.view());
    let mut est_rng = seeder.rng(Stream::Estimator);
    let (rnd, autoencoder) = (rnd_config(config), ae_config(config));
    let settings = RewardSettings {
        rnd: &rnd,
        kernel_pca: None,
        autoencoder: &autoencoder,
        sigma1: RedRewardConfig::default().sigma1,
        scores: config.calibration.scores(es.nrows()),
        gail: &gail_config(),
        gmmil: &GmmilConfig::default(),
    };
    let gail_seed = seeder.derive(Stream::Estimator);
    let fitted = fit_reward(
        job.method,
        &settings,
        es.view(),
        ea.view(),
        &mut est_rng,
        gail_seed,
    )?;
    let mut reward = ActionValues(fitted.ok_or_else(|| Error::InvalidConfig {
        field: "methods".into(),
        reason: format!("`{}` has no reward in the toy", job.method.label()),
    })?);

    let mut eval_rng = seeder.rng(Stream::Eval);
    let eval_states =
        Array2::from_shape_fn((EVAL_STATES, 1), |_| eval_rng.random_range(-1.0..=1.0));
    let mut env = simple_domain();
    let mut dqn = Dqn::new(
        dqn_config(config),
        1,
        env.action_space(),
        config.steps,
        &seeder,
    )?;
    let evaluate = |dqn: &Dqn| -> f64 {
        let acts = dqn.greedy_actions(eval_states.view());
        let total: f64 = eval_states
            .column(0)
            .iter()
            .zip(&acts)
            .map(|(s, &a)| action_value(a as f64) * s)
            .sum();
        total / EVAL_STATES as f64
    };
    let mut curve = vec![(0, evaluate(&dqn))];
    let mut env_seed = Some(seeder.derive(Stream::Env));
    while dqn.steps() < config.steps {
        let chunk = config.eval_interval.min(config.steps - dqn.steps());
        dqn.train(&mut env, &mut reward, chunk, env_seed.take(), &mut |_| {})?;
        curve.push((dqn.steps(), evaluate(&dqn)));
        on_eval();
    }

    let minus_eval = reward.rewards(eval_states.view(), Array2::zeros((EVAL_STATES, 1)).view())?;
    let plus_eval = reward.rewards(eval_states.view(), Array2::ones((EVAL_STATES, 1)).view())?;
    let reward_argmax = eval_states
        .column(0)
        .iter()
        .zip(minus_eval.iter().zip(&plus_eval))
        .map(|(s, (m, p))| if p > m { *s } else { -s })
        .sum::<f64>()
        / EVAL_STATES as f64;

    let grid = Array2::from_shape_fn((GRID, 1), |(i, _)| {
        -1.0 + 2.0 * i as f64 / (GRID - 1) as f64
    });
    let mut minus = plotted(&reward, &grid, &Array2::zeros((GRID, 1)))?;
    let mut plus = plotted(&reward, &grid, &Array2::ones((GRID, 1)))?;
    let mut alpha = None;
    if reward.0.support().is_some() {
        // The paper plots 1 - α1 L without giving α1; α1 = 1 / max L over
        // the plotted pairs puts both curves in [0, 1].
        let max_l = minus.iter().chain(plus.iter()).copied().fold(0.0, f64::max);
        let a = if max_l > 0.0 { 1.0 / max_l } else { 1.0 };
        minus = one_minus_alpha_l(minus, a);
        plus = one_minus_alpha_l(plus, a);
        alpha = Some(a);
    }
    Ok(RunResult {
        curve,
        reward_argmax,
        reward_minus: minus.to_vec(),
        reward_plus: plus.to_vec(),
        sigma1: reward.0.support().map(RedReward::sigma1),
        alpha,
    })
}

/// The checkpoint of a toy run: its settings and the result of every
/// finished (method, n, seed) run. Runs are independent and each is
/// determined by its seed, so a resumed experiment ends with exactly the
/// numbers of an uninterrupted one; a killed process loses only the runs
/// in flight (a few seconds each).
#[derive(Debug, Serialize, Deserialize)]
struct ToyCheckpoint {
    config: ToyConfig,
    results: Finished,
}

/// The result of each run of the grid, `None` while not finished.
type Finished = Vec<Option<RunResult>>;

const CHECKPOINT: &str = "checkpoint.json";
const CHECKPOINT_KIND: &str = "toy";

/// How a toy experiment ended.
#[derive(Debug)]
pub enum ToyOutcome {
    /// Every run finished; the outputs are written.
    Finished(ToyReport),
    /// The stop flag was raised: `saved` of `total` runs are in the
    /// checkpoint.
    Stopped {
        /// The run folder.
        dir: PathBuf,
        /// The checkpoint.
        checkpoint: PathBuf,
        /// Runs saved.
        saved: usize,
        /// Runs of the grid.
        total: usize,
    },
}

/// A finished toy experiment.
#[derive(Debug, Clone, PartialEq)]
pub struct ToyReport {
    /// The Markdown tables of `results.md`.
    pub table: String,
    /// The run folder.
    pub out: PathBuf,
    /// Wall time of this process's part, seconds.
    pub wall_time_s: f64,
}

impl ToyOutcome {
    /// What to tell the user: for a finished run the tables and where they
    /// were written; for a stopped one, what is saved and the command
    /// that continues it. Each ends with a newline.
    pub fn message(&self) -> String {
        match self {
            Self::Finished(r) => format!(
                "{}\nwrote {} ({:.1} s)\n",
                r.table,
                r.out.display(),
                r.wall_time_s
            ),
            Self::Stopped {
                dir,
                checkpoint,
                saved,
                total,
            } => format!(
                "interrupted: {saved} of {total} runs are saved in {}; continue with `red-cli toy --resume {}`\n",
                checkpoint.display(),
                dir.display()
            ),
        }
    }
}

/// Runs the experiment of `config` into the new run folder `dir` (see
/// [`RunDir::create_with`]) on `threads` worker threads.
///
/// # Errors
/// Invalid settings (`threads` 0 included), a failing run (what finished
/// is kept in the checkpoint), or files that cannot be written.
pub fn run_new(
    config: ToyConfig,
    dir: RunDir,
    threads: usize,
    stop: &AtomicBool,
    progress: &mut dyn Progress,
) -> Result<ToyOutcome> {
    config.validate()?;
    check_threads(threads)?;
    run_grid(config, dir, None, threads, stop, progress)
}

fn check_threads(threads: usize) -> Result<()> {
    if threads == 0 {
        return Err(Error::InvalidConfig {
            field: "threads".into(),
            reason: "must be at least 1 (leave it out to use every core)".into(),
        });
    }
    Ok(())
}

/// Continues the toy run saved in `dir`: its settings come from its
/// checkpoint, finished runs are kept and the others are run.
///
/// # Errors
/// A missing or damaged checkpoint (naming it), then as [`run_new`].
pub fn resume(
    dir: &Path,
    threads: usize,
    stop: &AtomicBool,
    progress: &mut dyn Progress,
) -> Result<ToyOutcome> {
    check_threads(threads)?;
    let run_dir =
        RunDir::open(dir).with_context(|| format!("cannot resume from {}", dir.display()))?;
    let path = dir.join(CHECKPOINT);
    let cp: ToyCheckpoint = red_core::checkpoint::load_checkpoint(&path, CHECKPOINT_KIND)
        .with_context(|| format!("cannot resume from {}", dir.display()))?;
    cp.config
        .validate()
        .with_context(|| format!("settings in {}", path.display()))?;
    run_grid(
        cp.config,
        run_dir,
        Some(cp.results),
        threads,
        stop,
        progress,
    )
}

fn run_grid(
    config: ToyConfig,
    dir: RunDir,
    resumed: Option<Finished>,
    threads: usize,
    stop: &AtomicBool,
    progress: &mut dyn Progress,
) -> Result<ToyOutcome> {
    let checkpoint_path = dir.file(CHECKPOINT);
    for n in dir.notes() {
        progress.note(n);
    }
    let start = std::time::Instant::now();
    let mut jobs = Vec::new();
    for &n in &config.n {
        for &method in &config.methods {
            for seed in 0..config.seeds {
                jobs.push(Job { method, n, seed });
            }
        }
    }
    let threads = threads.max(1).min(jobs.len());
    let evals_per_run = config.steps.div_ceil(config.eval_interval);
    let finished: Finished = match resumed {
        Some(saved) if saved.len() == jobs.len() => saved,
        Some(saved) => {
            return Err(Error::Input {
                path: checkpoint_path,
                reason: format!(
                    "holds {} runs but its settings make {}: the checkpoint is damaged",
                    saved.len(),
                    jobs.len()
                ),
            });
        }
        None => vec![None; jobs.len()],
    };
    let already = finished.iter().filter(|r| r.is_some()).count();
    if already > 0 {
        progress.note(&format!(
            "resuming {}: {already} of {} runs already done",
            dir.path().display(),
            jobs.len()
        ));
    }
    progress.start(
        &format!("{} runs on {threads} threads", jobs.len()),
        jobs.len() as u64 * evals_per_run,
        already as u64 * evals_per_run,
    );
    let evals_done = AtomicUsize::new(already * evals_per_run as usize);
    let progress = Mutex::new(progress);
    // Finished results, saved to the checkpoint after each run; the lock
    // also keeps two workers from writing the checkpoint at once.
    let state = Mutex::new(ToyCheckpoint {
        config: config.clone(),
        results: finished,
    });
    let poisoned = || Error::InvalidConfig {
        field: "threads".into(),
        reason: "a worker thread panicked".into(),
    };
    // The first failure stops the other workers; what finished is saved.
    let failures = crate::grid::run_pool(jobs.len(), threads, stop, OnFailure::StopAll, |i| {
        let job = &jobs[i];
        let done_before = state
            .lock()
            .map(|s| s.results[i].is_some())
            .unwrap_or(false);
        if done_before {
            return Ok(());
        }
        let on_eval = || {
            let d = evals_done.fetch_add(1, Ordering::SeqCst) + 1;
            if let Ok(mut p) = progress.lock() {
                p.advance(d as u64, "");
            }
        };
        run_one(&config, job, &on_eval)
            .with_context(|| format!("run {} n={} seed={}", job.method.label(), job.n, job.seed))
            .and_then(|r| {
                let mut s = state.lock().map_err(|_| poisoned())?;
                s.results[i] = Some(r);
                dir.save_checkpoint(CHECKPOINT_KIND, &config, &*s)?;
                Ok(())
            })
    });
    let failures: Vec<Error> = failures.into_iter().map(|(_, e)| e).collect();
    let progress = progress.into_inner().map_err(|_| poisoned())?;
    progress.finish();
    let state = state.into_inner().map_err(|_| poisoned())?;
    let saved = state.results.iter().filter(|r| r.is_some()).count();
    if let Some(e) = failures.into_iter().next() {
        return Err(e.context(format!(
            "{saved} of {} finished runs are kept in {}",
            jobs.len(),
            checkpoint_path.display()
        )));
    }
    if saved < jobs.len() {
        return Ok(ToyOutcome::Stopped {
            dir: dir.path().to_path_buf(),
            checkpoint: checkpoint_path,
            saved,
            total: jobs.len(),
        });
    }
    let done: Vec<RunResult> = state.results.into_iter().flatten().collect();
    write_config(&config, &dir)?;
    dir.write("metrics.csv", csv_metrics(&jobs, &done).as_bytes())?;
    dir.write(
        "learned_reward.csv",
        csv_reward_curves(&jobs, &done).as_bytes(),
    )?;
    dir.write("final.csv", csv_finals(&jobs, &done).as_bytes())?;
    plot_fig2(&config, &jobs, &done, dir.path())?;
    plot_fig3(&config, &jobs, &done, dir.path())?;
    let table = final_table(&config, &jobs, &done);
    dir.write("results.md", table.as_bytes())?;
    Ok(ToyOutcome::Finished(ToyReport {
        table,
        out: dir.path().to_path_buf(),
        wall_time_s: start.elapsed().as_secs_f64(),
    }))
}

fn write_config(config: &ToyConfig, dir: &RunDir) -> Result<()> {
    #[derive(Serialize)]
    struct Config<'a> {
        command: &'a str,
        version: &'a str,
        config: &'a ToyConfig,
        dqn: DqnConfig,
        rnd: RndConfig,
        autoencoder: AutoencoderConfig,
        red_reward: RedRewardConfig,
        gail: GailConfig,
        gmmil: GmmilConfig,
        episode_length: usize,
        eval_states: usize,
    }
    dir.write_json(
        "config.json",
        &Config {
            command: "toy",
            version: env!("CARGO_PKG_VERSION"),
            config,
            dqn: dqn_config(config),
            rnd: rnd_config(config),
            autoencoder: ae_config(config),
            red_reward: RedRewardConfig::default(),
            gail: gail_config(),
            gmmil: GmmilConfig::default(),
            episode_length: red_core::simple_domain::EPISODE_LENGTH,
            eval_states: EVAL_STATES,
        },
    )
}

/// The text of `metrics.csv`.
fn csv_metrics(jobs: &[Job], done: &[RunResult]) -> String {
    let mut f = String::new();
    let _ = writeln!(f, "method,n,seed,steps,true_mean_reward");
    for (job, r) in jobs.iter().zip(done) {
        for (steps, v) in &r.curve {
            let _ = writeln!(
                f,
                "{},{},{},{},{:.6}",
                job.method.label(),
                job.n,
                job.seed,
                steps,
                v
            );
        }
    }
    f
}

/// The text of `final.csv`.
fn csv_finals(jobs: &[Job], done: &[RunResult]) -> String {
    let mut f = String::new();
    let _ = writeln!(
        f,
        "method,n,seed,final_true_mean_reward,reward_argmax_true_mean_reward,sigma1"
    );
    for (job, r) in jobs.iter().zip(done) {
        let last = r.curve.last().map_or(f64::NAN, |c| c.1);
        let sigma = r.sigma1.map_or(String::new(), |v| format!("{v:.6e}"));
        let _ = writeln!(
            f,
            "{},{},{},{last:.6},{:.6},{sigma}",
            job.method.label(),
            job.n,
            job.seed,
            r.reward_argmax
        );
    }
    f
}

/// The text of `learned_reward.csv`.
fn csv_reward_curves(jobs: &[Job], done: &[RunResult]) -> String {
    let mut f = String::new();
    let _ = writeln!(f, "method,n,seed,sigma1,s,reward_a_minus1,reward_a_plus1");
    for (job, r) in jobs.iter().zip(done) {
        for i in 0..GRID {
            let s = -1.0 + 2.0 * i as f64 / (GRID - 1) as f64;
            let sigma = r.sigma1.map_or(String::new(), |v| format!("{v:.6e}"));
            let _ = writeln!(
                f,
                "{},{},{},{},{:.4},{:.6},{:.6}",
                job.method.label(),
                job.n,
                job.seed,
                sigma,
                s,
                r.reward_minus[i],
                r.reward_plus[i]
            );
        }
    }
    f
}

fn methods_sorted(config: &ToyConfig) -> Vec<Method> {
    let mut m = config.methods.clone();
    m.sort();
    m.dedup();
    m
}

fn plot_fig2(config: &ToyConfig, jobs: &[Job], done: &[RunResult], out: &Path) -> Result<()> {
    let mut panels = Vec::new();
    for &n in &config.n {
        let mut series = Vec::new();
        for method in methods_sorted(config) {
            let runs: Vec<&RunResult> = jobs
                .iter()
                .zip(done)
                .filter(|(j, _)| j.n == n && j.method == method)
                .map(|(_, r)| r)
                .collect();
            let Some(first) = runs.first() else { continue };
            let mut points = Vec::new();
            let mut band = Vec::new();
            for (k, &(steps, _)) in first.curve.iter().enumerate() {
                let vals: Vec<f64> = runs.iter().map(|r| r.curve[k].1).collect();
                let (m, s) = mean_std(&vals);
                points.push((steps as f64, m));
                band.push((steps as f64, m - s, m + s));
            }
            series.push(Series {
                label: method.label().into(),
                points,
                band,
            });
        }
        panels.push(Panel {
            title: format!("n = {n} (mean ± std over {} seeds)", config.seeds),
            x_label: "DQN steps".into(),
            y_label: "true mean reward per step".into(),
            series,
            y_range: Some((-0.55, 0.6)),
        });
    }
    let cols = if panels.len() > 1 { 2 } else { 1 };
    let rows = panels.len().div_ceil(cols) as u32;
    draw_panels(
        &out.join("fig2_true_reward.png"),
        &panels,
        cols,
        (600 * cols as u32, 420 * rows),
    )?;
    Ok(())
}

fn plot_fig3(config: &ToyConfig, jobs: &[Job], done: &[RunResult], out: &Path) -> Result<()> {
    let n = config.fig3_n.unwrap_or(if config.n.contains(&10) {
        10
    } else {
        config.n[0]
    });
    let mut panels = Vec::new();
    for method in methods_sorted(config) {
        let Some((_, r)) = jobs
            .iter()
            .zip(done)
            .find(|(j, _)| j.n == n && j.method == method && j.seed == 0)
        else {
            continue;
        };
        let grid: Vec<f64> = (0..GRID)
            .map(|i| -1.0 + 2.0 * i as f64 / (GRID - 1) as f64)
            .collect();
        let line = |vals: &[f64]| {
            grid.iter()
                .copied()
                .zip(vals.iter().copied())
                .collect::<Vec<_>>()
        };
        let y_label = match (method, r.alpha) {
            (Method::Red | Method::Ae, Some(a)) => format!("1 - α1 L, α1 = 1/max L = {a:.3e}"),
            _ => "learned reward (end of training)".into(),
        };
        panels.push(Panel {
            title: format!("{} (n = {n}, seed 0)", method.label()),
            x_label: "state s".into(),
            y_label,
            series: vec![
                Series {
                    label: "a = -1".into(),
                    points: line(&r.reward_minus),
                    band: Vec::new(),
                },
                Series {
                    label: "a = +1".into(),
                    points: line(&r.reward_plus),
                    band: Vec::new(),
                },
            ],
            y_range: None,
        });
    }
    if panels.is_empty() {
        return Ok(());
    }
    let cols = if panels.len() > 1 { 2 } else { 1 };
    let rows = panels.len().div_ceil(cols) as u32;
    draw_panels(
        &out.join("fig3_learned_reward.png"),
        &panels,
        cols,
        (600 * cols as u32, 420 * rows),
    )?;
    Ok(())
}

fn final_table(config: &ToyConfig, jobs: &[Job], done: &[RunResult]) -> String {
    let mut s = String::new();
    s.push_str(&format!(
        "Final true mean reward per step of the greedy policy after {} DQN steps (expert 0.5, random 0); mean ± std over {} seeds\n\n",
        config.steps, config.seeds
    ));
    let mut header = String::from("| method |");
    for n in &config.n {
        header.push_str(&format!(" n = {n} |"));
    }
    header.push_str("\n|---|");
    for _ in &config.n {
        header.push_str("---|");
    }
    header.push('\n');
    s.push_str(&header);
    for method in methods_sorted(config) {
        s.push_str(&format!("| {} |", method.label()));
        for &n in &config.n {
            let finals: Vec<f64> = jobs
                .iter()
                .zip(done)
                .filter(|(j, _)| j.n == n && j.method == method)
                .filter_map(|(_, r)| r.curve.last().map(|c| c.1))
                .collect();
            let (m, sd) = mean_std(&finals);
            s.push_str(&format!(" {m:.3} ± {sd:.3} |"));
        }
        s.push('\n');
    }
    s.push_str("\nTrue mean reward per step of argmax_a r(s, a) under each final learned reward (what a perfect learner would reach on it); mean ± std over seeds\n\n");
    s.push_str(&header);
    for method in methods_sorted(config) {
        s.push_str(&format!("| {} |", method.label()));
        for &n in &config.n {
            let vals: Vec<f64> = jobs
                .iter()
                .zip(done)
                .filter(|(j, _)| j.n == n && j.method == method)
                .map(|(_, r)| r.reward_argmax)
                .collect();
            let (m, sd) = mean_std(&vals);
            s.push_str(&format!(" {m:.3} ± {sd:.3} |"));
        }
        s.push('\n');
    }
    s
}
