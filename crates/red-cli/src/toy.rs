//! `red-cli toy`: the simple domain of the paper's Sec. 5.1 (Fig. 2 and 3).
//!
//! For each expert-set size `n`, method and seed, a reward is fitted (RED,
//! AE) or set up to adapt (GAIL, GMMIL) on `n` expert pairs, and DQN learns
//! from it. Every `--eval-interval` steps the greedy policy's TRUE mean
//! reward per step is measured on a fixed set of evaluation states (the task
//! is stateless, so this is the expected per-step reward of an episode).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use anyhow::{Context, bail};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use ndarray::{Array1, Array2};
use rand::RngExt;
use serde::{Deserialize, Serialize};

use red_core::{Env, RewardModel, Seeder, Stream};
use red_rl::dqn::{Dqn, DqnConfig};
use red_rl::gail::{Gail, GailConfig};
use red_rl::gmmil::{Gmmil, GmmilConfig};
use red_rl::simple_domain::{
    ActionValues, action_value, expert_demos, expert_demos_stratified, simple_domain,
    to_action_values,
};
use red_support::{
    Autoencoder, AutoencoderConfig, RedReward, RedRewardConfig, Rnd, RndConfig, Sigma1,
    SupportEstimatorConfig, SupportModel, calibrate_sigma1, held_out_scores, no_progress,
};

use red_experiments::plot::{Panel, Series, draw_panels, mean_std};

/// The imitation methods of the simple domain.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Random Expert Distillation (RND support estimate, `exp(-σ1 L)`).
    Red,
    /// The autoencoder support estimate, `exp(-σ1 L)`.
    Ae,
    /// Generative adversarial imitation learning.
    Gail,
    /// Generative moment matching imitation learning.
    Gmmil,
}

impl Method {
    fn name(self) -> &'static str {
        match self {
            Method::Red => "RED",
            Method::Ae => "AE",
            Method::Gail => "GAIL",
            Method::Gmmil => "GMMIL",
        }
    }
}

/// Which expert scores calibrate σ1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Calibration {
    /// Scores of each expert pair by a model fitted without it (k-fold).
    HeldOut,
    /// Scores of the pairs the model was fitted on.
    Train,
}

/// How the expert states of the simple domain are drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Sampling {
    /// One uniform draw in each of `n` equal slices of [-1, 1].
    Stratified,
    /// Independent uniform draws on [-1, 1].
    Iid,
}

/// Arguments of `red-cli toy`.
#[derive(Debug, Clone, Args, Serialize, Deserialize)]
pub struct ToyArgs {
    /// Name of the run: outputs go to `<runs-dir>/<name>/`.
    #[arg(long, default_value = "toy")]
    pub name: String,
    /// Folder holding runs.
    #[arg(long, default_value = "runs")]
    pub runs_dir: PathBuf,
    /// Expert-set sizes (the paper's 5, 10, 50, 100).
    #[arg(long, value_delimiter = ',', default_value = "5,10,50,100")]
    pub n: Vec<usize>,
    /// Methods to compare.
    #[arg(long, value_delimiter = ',', default_value = "red,ae,gail,gmmil")]
    pub methods: Vec<Method>,
    /// Seeds per cell.
    #[arg(long, default_value_t = 5)]
    pub seeds: u64,
    /// The first seed; cell seeds are `seed, seed + 1, ...`.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// DQN environment steps per run.
    #[arg(long, default_value_t = 10_000)]
    pub steps: u64,
    /// Environment steps between evaluations.
    #[arg(long, default_value_t = 500)]
    pub eval_interval: u64,
    /// DQN discount. The task is stateless (the next state does not depend
    /// on the action), so every discount gives the same greedy policy; 0
    /// removes the bootstrapping noise. The paper gives none.
    #[arg(long, default_value_t = 0.0)]
    pub gamma: f64,
    /// DQN gradient steps: one every this many environment steps. CleanRL's
    /// default is 10; the toy's reward differences between the two actions
    /// near the decision boundary are small, and 1 lets the Q-network fit
    /// them within the short run.
    #[arg(long, default_value_t = 1)]
    pub train_frequency: u64,
    /// Independent RND target/predictor pairs whose scores RED averages
    /// (the paper's Eq. 6 in its general form; the release trains 1).
    #[arg(long, default_value_t = 1)]
    pub rnd_ensemble: usize,
    /// How the `n` expert states are drawn: `stratified` (one uniform draw
    /// in each of `n` equal slices of [-1, 1]) or `iid` (independent uniform
    /// draws, which at n = 5 miss one side of the task in one set out of 16).
    #[arg(long, value_enum, default_value_t = Sampling::Stratified)]
    pub sampling: Sampling,
    /// Standardise the estimators' input `[s, a]` with the expert pairs'
    /// mean and standard deviation (RED and AE; the release does not).
    #[arg(long)]
    pub standardize: bool,
    /// Epochs of the RND predictor and the autoencoder (release: 200).
    #[arg(long, default_value_t = 200)]
    pub epochs: usize,
    /// How σ1 of RED and AE is calibrated: on held-out expert pairs (k-fold,
    /// k = min(5, n)) or on the training pairs themselves. Either way the
    /// 90% quantile of the expert scores gets reward 0.9.
    #[arg(long, value_enum, default_value_t = Calibration::HeldOut)]
    pub calibration: Calibration,
    /// Worker threads (default: the available cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// The expert-set size whose learned rewards Fig. 3 shows (default: 10
    /// if run, else the first size).
    #[arg(long)]
    pub fig3_n: Option<usize>,
    /// Hide the progress bar.
    #[arg(long)]
    #[serde(skip)]
    pub quiet: bool,
    /// Continue the interrupted run saved in this folder (`runs/<name>`):
    /// its settings come from its checkpoint, finished runs are kept and
    /// the others are run. Other settings given with it are ignored.
    #[arg(long)]
    #[serde(skip)]
    pub resume: Option<PathBuf>,
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

enum ToyReward {
    Red(ActionValues<RedReward<Rnd>>),
    Ae(ActionValues<RedReward<Autoencoder>>),
    Gail(Box<ActionValues<Gail>>),
    Gmmil(ActionValues<Gmmil>),
}

impl ToyReward {
    fn as_model(&mut self) -> &mut dyn RewardModel {
        match self {
            ToyReward::Red(r) => r,
            ToyReward::Ae(r) => r,
            ToyReward::Gail(r) => r.as_mut(),
            ToyReward::Gmmil(r) => r,
        }
    }

    /// The plotted reward of `(s, a)` for a batch.
    fn plotted(&mut self, s: &Array2<f64>, a: &Array2<f64>) -> anyhow::Result<Array1<f64>> {
        Ok(match self {
            ToyReward::Red(r) => {
                r.0.model()
                    .score(s.view(), to_action_values(a.view()).view())?
            }
            ToyReward::Ae(r) => {
                r.0.model()
                    .score(s.view(), to_action_values(a.view()).view())?
            }
            other => other.as_model().rewards(s.view(), a.view())?,
        })
    }

    fn sigma1(&self) -> Option<f64> {
        match self {
            ToyReward::Red(r) => Some(r.0.sigma1()),
            ToyReward::Ae(r) => Some(r.0.sigma1()),
            _ => None,
        }
    }
}

/// Fits the support estimator and sets σ1 by the 0.9-quantile rule of
/// [`RedRewardConfig::default`] on the chosen expert scores.
fn fit_red_reward<C: SupportEstimatorConfig>(
    config: &C,
    calibration: Calibration,
    es: &Array2<f64>,
    ea: &Array2<f64>,
    rng: &mut rand_chacha::ChaCha8Rng,
) -> anyhow::Result<RedReward<C::Model>> {
    let model = config.fit(es.view(), ea.view(), rng, &mut no_progress)?;
    let scores = match calibration {
        Calibration::Train => model.score(es.view(), ea.view())?,
        Calibration::HeldOut => {
            held_out_scores(config, es.view(), ea.view(), es.nrows().min(5), rng)?
        }
    };
    let (quantile, reward) = match RedRewardConfig::default().sigma1 {
        Sigma1::Calibrated { quantile, reward } => (quantile, reward),
        Sigma1::Fixed(_) => (0.9, 0.9),
    };
    let sigma1 = calibrate_sigma1(&scores.to_vec(), quantile, reward)?;
    Ok(RedReward::with_sigma1(model, sigma1)?)
}

fn rnd_config(args: &ToyArgs) -> RndConfig {
    RndConfig {
        epochs: args.epochs,
        ensemble: args.rnd_ensemble,
        standardize: args.standardize,
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

fn dqn_config(args: &ToyArgs) -> DqnConfig {
    DqnConfig {
        gamma: args.gamma,
        // Adaptive rewards (GAIL, GMMIL) see each 500-step window of the
        // policy's pairs: 20 updates over the default 10,000 steps.
        reward_update_interval: 500,
        train_frequency: args.train_frequency,
        ..DqnConfig::default()
    }
}

fn run_one(args: &ToyArgs, job: &Job, on_eval: &dyn Fn()) -> anyhow::Result<RunResult> {
    let seeder = Seeder::new(args.seed.wrapping_add(job.seed));
    let mut demo_rng = seeder.rng(Stream::Demo);
    let demos = match args.sampling {
        Sampling::Stratified => expert_demos_stratified(job.n, &mut demo_rng),
        Sampling::Iid => expert_demos(job.n, &mut demo_rng),
    };
    // The reward models see the paper's action values a in {-1, +1}.
    let (es, ea_index) = demos.pairs();
    let ea = to_action_values(ea_index.view());
    let mut est_rng = seeder.rng(Stream::Estimator);
    let mut reward = match job.method {
        Method::Red => {
            let cfg = rnd_config(args);
            let r = fit_red_reward(&cfg, args.calibration, &es, &ea, &mut est_rng)?;
            ToyReward::Red(ActionValues(r))
        }
        Method::Ae => {
            let cfg = AutoencoderConfig {
                epochs: args.epochs,
                standardize: args.standardize,
                ..AutoencoderConfig::default()
            };
            let r = fit_red_reward(&cfg, args.calibration, &es, &ea, &mut est_rng)?;
            ToyReward::Ae(ActionValues(r))
        }
        Method::Gail => {
            let seed = seeder.derive(Stream::Estimator);
            let g = Gail::new(gail_config(), es.view(), ea.view(), seed)?;
            ToyReward::Gail(Box::new(ActionValues(g)))
        }
        Method::Gmmil => {
            let g = Gmmil::new(GmmilConfig::default(), es.view(), ea.view())?;
            ToyReward::Gmmil(ActionValues(g))
        }
    };

    let mut eval_rng = seeder.rng(Stream::Eval);
    let eval_states =
        Array2::from_shape_fn((EVAL_STATES, 1), |_| eval_rng.random_range(-1.0..=1.0));
    let mut env = simple_domain();
    let mut dqn = Dqn::new(dqn_config(args), 1, env.action_space(), args.steps, &seeder)?;
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
    while dqn.steps() < args.steps {
        let chunk = args.eval_interval.min(args.steps - dqn.steps());
        dqn.train(
            &mut env,
            reward.as_model(),
            chunk,
            env_seed.take(),
            &mut |_| {},
        )?;
        curve.push((dqn.steps(), evaluate(&dqn)));
        on_eval();
    }

    let minus_eval = reward
        .as_model()
        .rewards(eval_states.view(), Array2::zeros((EVAL_STATES, 1)).view())?;
    let plus_eval = reward
        .as_model()
        .rewards(eval_states.view(), Array2::ones((EVAL_STATES, 1)).view())?;
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
    let mut minus = reward.plotted(&grid, &Array2::zeros((GRID, 1)))?;
    let mut plus = reward.plotted(&grid, &Array2::ones((GRID, 1)))?;
    let mut alpha = None;
    if matches!(reward, ToyReward::Red(_) | ToyReward::Ae(_)) {
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
        sigma1: reward.sigma1(),
        alpha,
    })
}

fn validate(args: &ToyArgs) -> anyhow::Result<()> {
    if args.n.is_empty() || args.n.contains(&0) {
        bail!("--n: give expert-set sizes of at least 1");
    }
    if args.methods.is_empty() {
        bail!("--methods: give at least one method");
    }
    if args.seeds == 0 {
        bail!("--seeds: must be at least 1");
    }
    if args.steps == 0 || args.eval_interval == 0 {
        bail!("--steps and --eval-interval must be at least 1");
    }
    if !(0.0..=1.0).contains(&args.gamma) {
        bail!("--gamma: must be in [0, 1], got {}", args.gamma);
    }
    if args.rnd_ensemble == 0 {
        bail!("--rnd-ensemble: must be at least 1");
    }
    if args.train_frequency == 0 {
        bail!("--train-frequency: must be at least 1");
    }
    if args.epochs == 0 {
        bail!("--epochs: must be at least 1");
    }
    Ok(())
}

/// The checkpoint of a `toy` run: its settings and the result of every
/// finished (method, n, seed) run. Runs are independent and each is
/// determined by its seed, so a resumed experiment ends with exactly the
/// numbers of an uninterrupted one; a killed process loses only the runs
/// in flight (a few seconds each).
#[derive(Debug, Serialize, Deserialize)]
struct ToyCheckpoint {
    args: ToyArgs,
    results: Finished,
}

/// The result of each run of the grid, `None` while not finished.
type Finished = Vec<Option<RunResult>>;

const CHECKPOINT: &str = "checkpoint.json";
const CHECKPOINT_KIND: &str = "toy";

/// The settings and finished runs to start from: fresh ones, or those of
/// the checkpoint named by `--resume`.
fn starting_point(args: ToyArgs) -> anyhow::Result<(ToyArgs, PathBuf, Option<Finished>)> {
    let Some(dir) = args.resume.clone() else {
        validate(&args)?;
        let out = args.runs_dir.join(&args.name);
        return Ok((args, out, None));
    };
    let path = dir.join(CHECKPOINT);
    let cp: ToyCheckpoint = red_core::checkpoint::load_checkpoint(&path, CHECKPOINT_KIND)
        .with_context(|| format!("cannot resume from {}", dir.display()))?;
    let mut saved = cp.args;
    validate(&saved).with_context(|| format!("settings in {}", path.display()))?;
    saved.quiet = args.quiet;
    saved.threads = args.threads;
    saved.resume = Some(dir.clone());
    Ok((saved, dir, Some(cp.results)))
}

/// Runs the experiment and writes its outputs.
///
/// # Errors
/// Bad arguments, a failing run, or files that cannot be written.
pub fn run(args: ToyArgs) -> anyhow::Result<()> {
    let (args, out, resumed) = starting_point(args)?;
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let checkpoint_path = out.join(CHECKPOINT);
    crate::interrupt::install();
    let start = std::time::Instant::now();

    let mut jobs = Vec::new();
    for &n in &args.n {
        for &method in &args.methods {
            for seed in 0..args.seeds {
                jobs.push(Job { method, n, seed });
            }
        }
    }
    let threads = args
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
        .max(1)
        .min(jobs.len());
    let evals_per_run = args.steps.div_ceil(args.eval_interval);
    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(jobs.len() as u64 * evals_per_run)
    };
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {percent}% ({eta} left) {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_message(format!("{} runs on {threads} threads", jobs.len()));

    let finished: Finished = match resumed {
        Some(saved) if saved.len() == jobs.len() => saved,
        Some(saved) => bail!(
            "{} holds {} runs but its settings make {}: the checkpoint is damaged",
            checkpoint_path.display(),
            saved.len(),
            jobs.len()
        ),
        None => vec![None; jobs.len()],
    };
    let already = finished.iter().filter(|r| r.is_some()).count();
    if already > 0 {
        eprintln!(
            "resuming {}: {already} of {} runs already done",
            out.display(),
            jobs.len()
        );
        bar.inc(already as u64 * evals_per_run);
    }
    // Finished results, saved to the checkpoint after each run; the lock
    // also keeps two workers from writing the checkpoint at once.
    let state = Mutex::new(ToyCheckpoint {
        args: args.clone(),
        results: finished,
    });
    let failures: Mutex<Vec<anyhow::Error>> = Mutex::new(Vec::new());
    let next = AtomicUsize::new(0);
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| {
                loop {
                    if crate::interrupt::requested() {
                        break;
                    }
                    let i = next.fetch_add(1, Ordering::SeqCst);
                    let Some(job) = jobs.get(i) else { break };
                    let done_before = state
                        .lock()
                        .map(|s| s.results[i].is_some())
                        .unwrap_or(false);
                    if done_before {
                        continue;
                    }
                    let outcome = run_one(&args, job, &|| bar.inc(1))
                        .with_context(|| {
                            format!("run {} n={} seed={}", job.method.name(), job.n, job.seed)
                        })
                        .and_then(|r| {
                            let mut s = state
                                .lock()
                                .map_err(|_| anyhow::anyhow!("a worker thread panicked"))?;
                            s.results[i] = Some(r);
                            red_core::checkpoint::save_checkpoint(
                                &checkpoint_path,
                                CHECKPOINT_KIND,
                                &*s,
                            )?;
                            Ok(())
                        });
                    if let Err(e) = outcome {
                        if let Ok(mut f) = failures.lock() {
                            f.push(e);
                        }
                        // Stop the other workers too; what finished is saved.
                        crate::interrupt::request();
                        break;
                    }
                }
            });
        }
    });
    bar.finish_and_clear();
    let failures = failures
        .into_inner()
        .map_err(|_| anyhow::anyhow!("a worker thread panicked"))?;
    let state = state
        .into_inner()
        .map_err(|_| anyhow::anyhow!("a worker thread panicked"))?;
    let saved = state.results.iter().filter(|r| r.is_some()).count();
    if let Some(e) = failures.into_iter().next() {
        return Err(e.context(format!(
            "{saved} of {} finished runs are kept in {}",
            jobs.len(),
            checkpoint_path.display()
        )));
    }
    if saved < jobs.len() {
        eprintln!(
            "interrupted: {saved} of {} runs are saved in {}; continue with `red-cli toy --resume {}`",
            jobs.len(),
            checkpoint_path.display(),
            out.display()
        );
        std::process::exit(130);
    }
    let done: Vec<RunResult> = state.results.into_iter().flatten().collect();

    write_config(&args, &out)?;
    write_metrics(&jobs, &done, &out)?;
    write_reward_curves(&jobs, &done, &out)?;
    write_finals(&jobs, &done, &out)?;
    plot_fig2(&args, &jobs, &done, &out)?;
    plot_fig3(&args, &jobs, &done, &out)?;
    let table = final_table(&args, &jobs, &done);
    std::fs::write(out.join("results.md"), &table)
        .with_context(|| format!("writing {}", out.join("results.md").display()))?;
    println!("{table}");
    println!(
        "wrote {} ({:.1} s)",
        out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

fn write_config(args: &ToyArgs, out: &Path) -> anyhow::Result<()> {
    #[derive(Serialize)]
    struct Config<'a> {
        command: &'a str,
        version: &'a str,
        args: &'a ToyArgs,
        dqn: DqnConfig,
        rnd: RndConfig,
        autoencoder: AutoencoderConfig,
        red_reward: RedRewardConfig,
        gail: GailConfig,
        gmmil: GmmilConfig,
        episode_length: usize,
        eval_states: usize,
    }
    let c = Config {
        command: "toy",
        version: env!("CARGO_PKG_VERSION"),
        args,
        dqn: dqn_config(args),
        rnd: rnd_config(args),
        autoencoder: AutoencoderConfig {
            epochs: args.epochs,
            standardize: args.standardize,
            ..AutoencoderConfig::default()
        },
        red_reward: RedRewardConfig::default(),
        gail: gail_config(),
        gmmil: GmmilConfig::default(),
        episode_length: red_rl::simple_domain::EPISODE_LENGTH,
        eval_states: EVAL_STATES,
    };
    let path = out.join("config.json");
    std::fs::write(&path, serde_json::to_string_pretty(&c)?)
        .with_context(|| format!("writing {}", path.display()))
}

fn write_metrics(jobs: &[Job], done: &[RunResult], out: &Path) -> anyhow::Result<()> {
    let path = out.join("metrics.csv");
    let mut f = std::io::BufWriter::new(
        std::fs::File::create(&path).with_context(|| format!("creating {}", path.display()))?,
    );
    writeln!(f, "method,n,seed,steps,true_mean_reward")?;
    for (job, r) in jobs.iter().zip(done) {
        for (steps, v) in &r.curve {
            writeln!(
                f,
                "{},{},{},{},{:.6}",
                job.method.name(),
                job.n,
                job.seed,
                steps,
                v
            )?;
        }
    }
    f.flush()?;
    Ok(())
}

fn write_finals(jobs: &[Job], done: &[RunResult], out: &Path) -> anyhow::Result<()> {
    let path = out.join("final.csv");
    let mut f = std::io::BufWriter::new(
        std::fs::File::create(&path).with_context(|| format!("creating {}", path.display()))?,
    );
    writeln!(
        f,
        "method,n,seed,final_true_mean_reward,reward_argmax_true_mean_reward,sigma1"
    )?;
    for (job, r) in jobs.iter().zip(done) {
        let last = r.curve.last().map_or(f64::NAN, |c| c.1);
        let sigma = r.sigma1.map_or(String::new(), |v| format!("{v:.6e}"));
        writeln!(
            f,
            "{},{},{},{last:.6},{:.6},{sigma}",
            job.method.name(),
            job.n,
            job.seed,
            r.reward_argmax
        )?;
    }
    f.flush()?;
    Ok(())
}

fn write_reward_curves(jobs: &[Job], done: &[RunResult], out: &Path) -> anyhow::Result<()> {
    let path = out.join("learned_reward.csv");
    let mut f = std::io::BufWriter::new(
        std::fs::File::create(&path).with_context(|| format!("creating {}", path.display()))?,
    );
    writeln!(f, "method,n,seed,sigma1,s,reward_a_minus1,reward_a_plus1")?;
    for (job, r) in jobs.iter().zip(done) {
        for i in 0..GRID {
            let s = -1.0 + 2.0 * i as f64 / (GRID - 1) as f64;
            let sigma = r.sigma1.map_or(String::new(), |v| format!("{v:.6e}"));
            writeln!(
                f,
                "{},{},{},{},{:.4},{:.6},{:.6}",
                job.method.name(),
                job.n,
                job.seed,
                sigma,
                s,
                r.reward_minus[i],
                r.reward_plus[i]
            )?;
        }
    }
    f.flush()?;
    Ok(())
}

fn methods_sorted(args: &ToyArgs) -> Vec<Method> {
    let mut m = args.methods.clone();
    m.sort();
    m.dedup();
    m
}

fn plot_fig2(args: &ToyArgs, jobs: &[Job], done: &[RunResult], out: &Path) -> anyhow::Result<()> {
    let mut panels = Vec::new();
    for &n in &args.n {
        let mut series = Vec::new();
        for method in methods_sorted(args) {
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
                label: method.name().into(),
                points,
                band,
            });
        }
        panels.push(Panel {
            title: format!("n = {n} (mean ± std over {} seeds)", args.seeds),
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

fn plot_fig3(args: &ToyArgs, jobs: &[Job], done: &[RunResult], out: &Path) -> anyhow::Result<()> {
    let n = args
        .fig3_n
        .unwrap_or(if args.n.contains(&10) { 10 } else { args.n[0] });
    let mut panels = Vec::new();
    for method in methods_sorted(args) {
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
            title: format!("{} (n = {n}, seed 0)", method.name()),
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

fn final_table(args: &ToyArgs, jobs: &[Job], done: &[RunResult]) -> String {
    let mut s = String::new();
    s.push_str(&format!(
        "Final true mean reward per step of the greedy policy after {} DQN steps (expert 0.5, random 0); mean ± std over {} seeds\n\n",
        args.steps, args.seeds
    ));
    let mut header = String::from("| method |");
    for n in &args.n {
        header.push_str(&format!(" n = {n} |"));
    }
    header.push_str("\n|---|");
    for _ in &args.n {
        header.push_str("---|");
    }
    header.push('\n');
    s.push_str(&header);
    for method in methods_sorted(args) {
        s.push_str(&format!("| {} |", method.name()));
        for &n in &args.n {
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
    for method in methods_sorted(args) {
        s.push_str(&format!("| {} |", method.name()));
        for &n in &args.n {
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
