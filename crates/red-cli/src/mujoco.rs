//! `red-cli mujoco`: the MuJoCo environments (Gymnasium's `-v5` Hopper,
//! HalfCheetah, Walker2d, Ant, Reacher): set-up check, experts and their
//! demonstrations, imitation runs (paper Sec. 5.2), evaluation, and the
//! grid of Table 1.
//!
//! A thin front end over `red_experiments::mujoco`: arguments to configs,
//! progress bars (a `Progress` per run, one per running cell of the grid),
//! Ctrl-C as the stop flag, and printing what the library returns.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use clap::{Args, Subcommand};
use indicatif::MultiProgress;
use red_experiments::Progress;
use red_experiments::mujoco::check::check_envs;
use red_experiments::mujoco::run::{self, MujocoLearner, Outcome, PolicyEval, RunFlags};
use red_experiments::mujoco::slurm::{self, SlurmConfig};
use red_experiments::mujoco::table::{self, GridProgress, TableConfig};
use red_experiments::mujoco::{Method, launch, short_name};
use red_mujoco::EnvId;

use crate::interrupt;
use crate::progress::Bar;

/// Arguments of `red-cli mujoco`.
#[derive(Debug, Args)]
pub struct MujocoArgs {
    #[command(subcommand)]
    command: MujocoCommand,
}

#[derive(Debug, Subcommand)]
enum MujocoCommand {
    /// Check the MuJoCo set-up: load each environment, play it through the
    /// env checker (seeded random actions, twice, compared bit for bit) and
    /// print its dimensions and speed.
    Check(CheckArgs),
    /// Train an expert with TRPO (or SAC, `--learner sac`) on the true
    /// reward, then write its policy and a demonstration file of 4
    /// deterministic episodes (the paper's protocol) into
    /// `runs/expert-<env>/`.
    Expert(ExpertArgs),
    /// Imitation with TRPO (RED, AE, GAIL, GMMIL; RED and AE also with
    /// SAC) or behaviour cloning alone, from a demonstration file; checkpoints, `--resume`, metrics,
    /// best checkpoint by true return, final evaluation.
    Train(TrainArgs),
    /// Evaluate a saved policy: deterministic actions (or sampled with
    /// `--stochastic`), true reward, mean and standard deviation of the return.
    Eval(EvalArgs),
    /// Write a demonstration file from a saved policy: mean or sampled
    /// actions, stored clipped to the action space or raw.
    Demos(DemosArgs),
    /// Run a grid of tasks x methods x seeds in parallel and write the
    /// paper's Table 1 (markdown and CSV) and a learning-curve PNG per task.
    Table(TableArgs),
}

/// Options shared by `expert` and `train`.
#[derive(Debug, Args)]
struct CommonRunArgs {
    /// Environment steps (default: 5,000,000 for `expert` with TRPO,
    /// 1,000,000 with SAC, 2,000,000 for `train`).
    #[arg(long)]
    pub steps: Option<u64>,
    /// Seed of every random stream of the run.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Run name: outputs go to `<out-dir>/<name>/`.
    #[arg(long)]
    pub name: Option<String>,
    /// Folder of the runs.
    #[arg(long, default_value = "runs")]
    pub out_dir: PathBuf,
    /// Continue the run in this folder from its last checkpoint (its
    /// `config.json` holds the settings; `--steps` changes the budget: at or
    /// below the steps done, the run ends there and is evaluated).
    #[arg(long, value_name = "RUN_DIR")]
    pub resume: Option<PathBuf>,
    /// Start over in a folder that holds a run: the old folder is moved
    /// aside to `<name>.old-N` first.
    #[arg(long, conflicts_with = "resume")]
    pub force: bool,
    /// A JSON file of settings (the fields of `config.json`; missing fields
    /// take the task's defaults, unknown fields are refused).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// TRPO iterations between checkpoints.
    #[arg(long)]
    pub checkpoint_every: Option<u64>,
    /// Evaluation episodes of the final policy and of the best checkpoint.
    #[arg(long)]
    pub eval_episodes: Option<usize>,
    /// A fixed sigma1 for `red` and `ae` (default: calibrated so that 90%
    /// of the expert pairs get a reward of at least 0.9; at least 0.5 for
    /// `red` on Ant, HalfCheetah, Walker2d).
    #[arg(long, conflicts_with = "release_sigma1")]
    pub sigma1: Option<f64>,
    /// Use the RED release's hand-set sigma1 of the task and method.
    #[arg(long)]
    pub release_sigma1: bool,
    /// Stop as Ctrl-C does once this many iterations are done (for tests).
    #[arg(long, hide = true)]
    pub stop_after_iterations: Option<u64>,
    /// The learner: trpo (the paper's) or sac (Soft Actor-Critic: experts,
    /// red and ae; 1,000,000 steps by default; checkpoints every 100,000
    /// steps hold its whole replay).
    #[arg(long, conflicts_with = "resume", value_parser = |s: &str| s.parse::<MujocoLearner>())]
    pub learner: Option<MujocoLearner>,
}

#[derive(Debug, Args)]
struct ExpertArgs {
    /// The task, e.g. `hopper` or `Hopper-v5` (not needed with `--resume`).
    #[arg(long, required_unless_present = "resume")]
    env: Option<EnvId>,
    #[command(flatten)]
    common: CommonRunArgs,
}

#[derive(Debug, Args)]
struct TrainArgs {
    /// The task, e.g. `hopper` or `Hopper-v5`.
    #[arg(long)]
    env: Option<EnvId>,
    /// The method: red, ae, gail, gmmil, bc (or expert).
    #[arg(long)]
    method: Option<Method>,
    /// Demonstration file (default: `<out-dir>/expert-<env>/demos.json`,
    /// written by `red-cli mujoco expert`).
    #[arg(long)]
    demo: Option<PathBuf>,
    #[command(flatten)]
    common: CommonRunArgs,
}

#[derive(Debug, Args)]
struct DemosArgs {
    /// A policy file of a run (`policy.json`, `best_policy.json`, ...).
    #[arg(long)]
    policy: PathBuf,
    /// The task the policy was trained on.
    #[arg(long)]
    env: EnvId,
    /// Episodes (trajectories) to record.
    #[arg(long, default_value_t = 4)]
    episodes: usize,
    /// Seed of the resets and of the action noise.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Sample the actions from the policy's Gaussian instead of its mean.
    #[arg(long)]
    sampled: bool,
    /// Store the raw actions instead of those clipped to the action space.
    #[arg(long)]
    raw_actions: bool,
    /// Steps per episode at most (default: the task's time limit).
    #[arg(long)]
    max_steps: Option<usize>,
    /// The demo file to write (never overwritten).
    #[arg(long)]
    out: PathBuf,
}

#[derive(Debug, Args)]
struct EvalArgs {
    /// A policy file (`policy.json`, `best_policy.json`,
    /// `expert_policy.json` of a run).
    #[arg(long)]
    policy: PathBuf,
    /// The task the policy was trained on.
    #[arg(long)]
    env: EnvId,
    /// Episodes (the paper: 50).
    #[arg(long, default_value_t = 50)]
    episodes: usize,
    /// Seed of the episodes' resets.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Also write the returns to this JSON file.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Sample the actions from the policy's Gaussian, as in training,
    /// instead of taking its mean (the default).
    #[arg(long)]
    stochastic: bool,
}

#[derive(Debug, Args)]
struct CheckArgs {
    /// Environment to check, e.g. `Hopper-v5` or `hopper`; repeat for
    /// several (default: all five).
    #[arg(long = "env", value_name = "ID")]
    envs: Vec<EnvId>,
    /// Steps per run of the checker.
    #[arg(long, default_value_t = 1000)]
    steps: usize,
    /// Seed of the resets and of the random actions.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

/// Arguments of `red-cli mujoco table`.
#[derive(Debug, Args)]
struct TableArgs {
    /// Tasks, comma-separated (default: all five).
    #[arg(long, value_delimiter = ',')]
    envs: Vec<EnvId>,
    /// Methods, comma-separated (default: red, ae, gail, gmmil, bc).
    #[arg(long, value_delimiter = ',')]
    methods: Vec<Method>,
    /// Seeds, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0")]
    seeds: Vec<u64>,
    /// Environment steps of each TRPO run (the release's README example:
    /// 2,000,000; the paper: 5,000,000).
    #[arg(long, default_value_t = 2_000_000)]
    steps: u64,
    /// Name of the grid: outputs go to `<out-dir>/<name>/`.
    #[arg(long, default_value = "mujoco-table")]
    name: String,
    /// Folder of the runs.
    #[arg(long, default_value = "runs")]
    out_dir: PathBuf,
    /// Folder holding `expert-<task>/` (demos and expert evaluation)
    /// (default: `--out-dir`).
    #[arg(long)]
    experts_dir: Option<PathBuf>,
    /// Runs at once (default: the number of cores).
    #[arg(long)]
    jobs: Option<usize>,
    /// Evaluation episodes per run and protocol.
    #[arg(long, default_value_t = 50)]
    eval_episodes: usize,
    /// TRPO iterations between checkpoints.
    #[arg(long, default_value_t = 50)]
    checkpoint_every: u64,
    /// Only build the table and plots from the runs already finished, and
    /// list the cells that are missing or failed.
    #[arg(long)]
    report_only: bool,
    #[command(flatten)]
    slurm: SlurmArgs,
}

/// `red-cli mujoco table` on a SLURM cluster (docs/slurm.md).
#[derive(Debug, Args)]
struct SlurmArgs {
    /// Submit the grid's unfinished cells as a SLURM job array (one task per
    /// cell, each `red-cli mujoco train` into the grid's folder, resumed from
    /// its checkpoint when requeued) instead of running them here.
    #[arg(long, conflicts_with = "report_only")]
    slurm: bool,
    /// With --report-only: submit the missing and failed cells again (after
    /// the earlier job has left the queue).
    #[arg(long, requires = "report_only")]
    resubmit_missing: bool,
    /// Only write the batch script (into `<grid>/slurm/`), do not submit it.
    #[arg(long)]
    dry_run: bool,
    /// SLURM partition.
    #[arg(long)]
    partition: Option<String>,
    /// Time limit of each task (`HH:MM:SS`, `D-HH:MM`, ...).
    #[arg(long)]
    time: Option<String>,
    /// CPUs of each task.
    #[arg(long, default_value_t = 1)]
    cpus_per_task: usize,
    /// Memory of each task (`4G`, ...).
    #[arg(long)]
    mem: Option<String>,
    /// SLURM account.
    #[arg(long)]
    account: Option<String>,
    /// At most this many tasks at once.
    #[arg(long)]
    max_running: Option<usize>,
    /// A further sbatch option for the script (`--sbatch-arg=--qos=long`);
    /// repeat for several.
    #[arg(long, value_name = "OPTION", allow_hyphen_values = true)]
    sbatch_arg: Vec<String>,
    /// The red-cli the tasks run, a path the compute nodes reach (default:
    /// this program).
    #[arg(long, value_name = "PATH")]
    red_cli: Option<PathBuf>,
}

impl SlurmArgs {
    fn config(&self) -> anyhow::Result<SlurmConfig> {
        let red_cli = match &self.red_cli {
            Some(p) => p.clone(),
            None => std::env::current_exe().context("finding this red-cli for the batch script")?,
        };
        let cfg = SlurmConfig {
            partition: self.partition.clone(),
            time: self.time.clone(),
            cpus_per_task: self.cpus_per_task,
            mem: self.mem.clone(),
            account: self.account.clone(),
            max_running: self.max_running,
            extra: self.sbatch_arg.clone(),
            red_cli,
            ..SlurmConfig::default()
        };
        cfg.validate().map_err(crate::flag_error)?;
        Ok(cfg)
    }

    /// Writes (and unless --dry-run submits) the batch script; prints what
    /// was done.
    fn submit(&self, cfg: &TableConfig) -> anyhow::Result<()> {
        let sub = slurm::submit(cfg, &self.config()?, self.dry_run)?;
        print!("{}", sub.summary(cfg));
        Ok(())
    }
}

/// Runs `red-cli mujoco ...`.
pub fn run(args: MujocoArgs) -> anyhow::Result<()> {
    match args.command {
        MujocoCommand::Check(a) => check(a),
        MujocoCommand::Expert(a) => {
            // Without --env (--resume), the run's config.json decides.
            let env = a.env.unwrap_or(EnvId::Hopper);
            start_run(env, Method::Expert, None, a.common)
        }
        MujocoCommand::Train(a) => {
            if a.common.resume.is_some() {
                return start_run(EnvId::Hopper, Method::Red, None, a.common);
            }
            let env = a.env.context("--env is required (or --resume RUN_DIR)")?;
            let method: Method = a
                .method
                .context("--method is required (red, ae, gail, gmmil or bc)")?;
            anyhow::ensure!(
                method != Method::Expert,
                "use `red-cli mujoco expert` to train an expert"
            );
            start_run(env, method, a.demo, a.common)
        }
        MujocoCommand::Eval(a) => eval(a),
        MujocoCommand::Demos(a) => {
            use red_experiments::mujoco::demos::{DemoRequest, make_demos_file};
            let mut req = DemoRequest::new(a.policy, a.env, a.episodes);
            (req.seed, req.sampled, req.raw) = (a.seed, a.sampled, a.raw_actions);
            req.max_steps = a.max_steps;
            let d = make_demos_file(&req, &a.out)?;
            println!("{}: {}", a.out.display(), d.summary());
            Ok(())
        }
        MujocoCommand::Table(a) => table(a),
    }
}

impl CommonRunArgs {
    /// The library's flags of the run (reads the `--config` file).
    fn flags(self, demo: Option<PathBuf>) -> anyhow::Result<RunFlags> {
        let text = crate::read_text(self.config.as_deref())?;
        Ok(RunFlags {
            steps: self.steps,
            seed: self.seed,
            name: self.name,
            out_dir: self.out_dir,
            resume: self.resume,
            force: self.force,
            config: self.config.zip(text),
            checkpoint_every: self.checkpoint_every,
            eval_episodes: self.eval_episodes,
            sigma1: self.sigma1,
            release_sigma1: self.release_sigma1,
            demo,
            learner: self.learner,
        })
    }
}

fn start_run(
    env: EnvId,
    method: Method,
    demo: Option<PathBuf>,
    common: CommonRunArgs,
) -> anyhow::Result<()> {
    interrupt::install();
    let stop_after = common.stop_after_iterations;
    let (dir, cfg, start) = common.flags(demo)?.prepare(env, method)?;
    let label = format!("{} {}", short_name(cfg.env), cfg.method.name());
    let mut bar = Bar::labelled(label, None);
    bar.stop_at = stop_after.map(|k| k * cfg.iteration_steps());
    let outcome = launch::run_with(&dir, Some(cfg), start, interrupt::flag(), &mut bar)?;
    drop(bar);
    if outcome == Outcome::Interrupted {
        println!("interrupted; continue with --resume {}", dir.display());
        return Ok(());
    }
    let e = run::read_eval(&dir)
        .with_context(|| format!("reading {}", dir.join("eval.json").display()))?;
    print!("{}", e.summary(&dir));
    Ok(())
}

/// Bars of the grid's running cells under one another.
struct GridBars(MultiProgress);

impl GridProgress for GridBars {
    fn note(&self, text: &str) {
        if self.0.is_hidden() {
            eprintln!("{text}");
        } else {
            let _ = self.0.println(text);
        }
    }

    fn cell(&self, label: &str) -> Box<dyn Progress + '_> {
        Box::new(Bar::labelled(label.to_string(), Some(&self.0)))
    }
}

/// Runs `red-cli mujoco table`.
fn table(args: TableArgs) -> anyhow::Result<()> {
    let cfg = TableConfig {
        seeds: args.seeds,
        steps: args.steps,
        name: args.name,
        out_dir: args.out_dir,
        experts_dir: args.experts_dir,
        jobs: args.jobs,
        eval_episodes: args.eval_episodes,
        checkpoint_every: args.checkpoint_every,
        ..TableConfig::default()
    }
    .with_grid(args.envs, args.methods)?;
    if args.slurm.slurm {
        return args.slurm.submit(&cfg);
    }
    anyhow::ensure!(
        !args.slurm.dry_run || args.slurm.resubmit_missing,
        "--dry-run goes with --slurm or --resubmit-missing"
    );
    let started = Instant::now();
    if !args.report_only {
        interrupt::install();
        let bars = GridBars(MultiProgress::new());
        let outcome = table::run_grid(&cfg, interrupt::flag(), &bars)?;
        eprint!("{}", outcome.notes());
    }
    let report = table::write_report(&cfg)?;
    print!("{}", report.summary(&cfg, started.elapsed().as_secs_f64()));
    if args.report_only {
        print!("{}", slurm::missing_report(&cfg));
        if args.slurm.resubmit_missing {
            args.slurm.submit(&cfg)?;
        }
    }
    Ok(())
}

fn eval(args: EvalArgs) -> anyhow::Result<()> {
    let (e, warnings) = PolicyEval::of_file(
        &args.policy,
        args.env,
        args.episodes,
        args.seed,
        args.stochastic,
    )?;
    print!("{}", e.summary());
    if warnings > 0 {
        println!("MuJoCo warnings during the evaluation: {warnings}");
    }
    if let Some(out) = &args.out {
        e.write(out)?;
    }
    Ok(())
}

fn check(args: CheckArgs) -> anyhow::Result<()> {
    Ok(check_envs(&args.envs, args.steps, args.seed, &mut |l| {
        println!("{l}")
    })?)
}
