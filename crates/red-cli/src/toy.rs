//! `red-cli toy`: the simple domain of the paper's Sec. 5.1 (Fig. 2 and 3),
//! run by `red_experiments::toy`: arguments to a config, a progress bar,
//! the table.

use std::path::PathBuf;

use clap::Args;
use red_experiments::toy::{self, Calibration, Method, Sampling, ToyConfig, ToyOutcome};

use crate::interrupt;
use crate::progress::Bar;

/// Arguments of `red-cli toy` (see `ToyConfig` for what each setting
/// does and where its default comes from).
#[derive(Debug, Clone, Args)]
pub struct ToyArgs {
    /// Name of the run: outputs go to `<out-dir>/<name>/`.
    #[arg(long, default_value = "toy")]
    pub name: String,
    /// Folder of the runs (`--runs-dir` is its earlier name).
    #[arg(long, visible_alias = "runs-dir", default_value = "runs")]
    pub out_dir: PathBuf,
    /// Expert-set sizes (the paper's 5, 10, 50, 100).
    #[arg(long, value_delimiter = ',', default_value = "5,10,50,100")]
    pub n: Vec<usize>,
    /// Methods to compare: red, ae, gail, gmmil.
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
    /// DQN discount (the task is stateless; 0 removes bootstrapping noise).
    #[arg(long, default_value_t = 0.0)]
    pub gamma: f64,
    /// DQN gradient steps: one every this many environment steps.
    #[arg(long, default_value_t = 1)]
    pub train_frequency: u64,
    /// Independent RND target/predictor pairs whose scores RED averages.
    #[arg(long, default_value_t = 1)]
    pub rnd_ensemble: usize,
    /// How the expert states are drawn: stratified or iid.
    #[arg(long, default_value = "stratified")]
    pub sampling: Sampling,
    /// Standardise the estimators' input with the expert pairs' statistics.
    #[arg(long)]
    pub standardize: bool,
    /// Epochs of the RND predictor and the autoencoder (release: 200).
    #[arg(long, default_value_t = 200)]
    pub epochs: usize,
    /// How σ1 of RED and AE is calibrated: held-out or train.
    #[arg(long, default_value = "held-out")]
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
    pub quiet: bool,
    /// Continue the interrupted run saved in this folder (`runs/<name>`):
    /// its settings come from its checkpoint, finished runs are kept and
    /// the others are run. Other settings given with it are ignored.
    #[arg(long)]
    pub resume: Option<PathBuf>,
    /// Start over in a folder that holds a run: the old folder is moved
    /// aside to `<name>.old-N` first.
    #[arg(long, conflicts_with = "resume")]
    pub force: bool,
}

impl ToyArgs {
    fn config(&self) -> ToyConfig {
        ToyConfig {
            n: self.n.clone(),
            methods: self.methods.clone(),
            seeds: self.seeds,
            seed: self.seed,
            steps: self.steps,
            eval_interval: self.eval_interval,
            gamma: self.gamma,
            train_frequency: self.train_frequency,
            rnd_ensemble: self.rnd_ensemble,
            sampling: self.sampling,
            standardize: self.standardize,
            epochs: self.epochs,
            calibration: self.calibration,
            fig3_n: self.fig3_n,
        }
    }
}

/// Runs `red-cli toy`.
pub fn run(args: ToyArgs) -> anyhow::Result<()> {
    interrupt::install();
    let threads = args.threads.unwrap_or_else(red_experiments::cores);
    let mut bar = Bar::new(args.quiet, None);
    let outcome = match &args.resume {
        Some(dir) => toy::resume(dir, threads, interrupt::flag(), &mut bar)?,
        None => {
            let config = args.config();
            config.validate().map_err(crate::flag_error)?;
            let force = args.force.into();
            let dir = red_experiments::RunDir::create_with(&args.out_dir, &args.name, force)?;
            let outcome = toy::run_new(config, dir, threads, interrupt::flag(), &mut bar);
            outcome.map_err(crate::flag_error)?
        }
    };
    let message = outcome.message();
    if let ToyOutcome::Stopped { .. } = outcome {
        eprint!("{message}");
        std::process::exit(130);
    }
    print!("{message}");
    Ok(())
}
