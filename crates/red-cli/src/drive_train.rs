//! `red-cli drive --demo FILE`: the driving experiment of
//! `red_experiments::drive` from the command line: arguments to a config,
//! a progress bar, the table.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use red_experiments::drive::{self, DriveFlags, DriveOutcome, DriveRunConfig};

use crate::interrupt;
use crate::progress::Bar;
use crate::road::TrackArgs;

/// Arguments of `red-cli drive --demo FILE` (training and evaluation).
#[derive(Debug, Args)]
pub struct TrainArgs {
    /// Demonstration file (`drive` scenario) to imitate. Its road comes
    /// from the file.
    #[arg(long)]
    pub demo: Option<PathBuf>,
    /// Methods, comma-separated, or `all`: `red` (RED's RND reward +
    /// SVG(1)-ER), `ae` (autoencoder reward + SVG(1)-ER), `gail`, `gmmil`
    /// (adaptive rewards + SVG(1)-ER), all warm-started by BC, and `bc`
    /// (behaviour cloning alone).
    #[arg(long, default_value = "red,bc", value_delimiter = ',')]
    pub methods: Vec<String>,
    /// Seed of everything random (fits, exploration, start noise).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Environment steps of SVG(1)-ER per method (default: the training
    /// config's `steps`).
    #[arg(long)]
    pub steps: Option<u64>,
    /// Run name: outputs go to `<out-dir>/<name>/`.
    #[arg(long, default_value = "drive")]
    pub name: String,
    /// Folder of the runs.
    #[arg(long, default_value = "runs")]
    pub out_dir: PathBuf,
    /// Training epochs of the RND predictor and of the autoencoder
    /// (default: the training config's; kernel PCA has none).
    #[arg(long)]
    pub rnd_epochs: Option<usize>,
    /// Behaviour-cloning epochs of the warm start (default: the training
    /// config's).
    #[arg(long)]
    pub bc_epochs: Option<usize>,
    /// Evaluation episodes per method and road.
    #[arg(long, default_value_t = 5)]
    pub eval_runs: usize,
    /// Roads the demonstration never saw (other track seeds, from 100 on)
    /// on which every policy is also evaluated; 0: none.
    #[arg(long, default_value_t = 10)]
    pub eval_roads: usize,
    /// Train and evaluate on the road of --track-seed/--config even though
    /// the demonstration was driven on another one.
    #[arg(long)]
    pub other_road: bool,
    /// Training settings (JSON of the `train` object of a run's
    /// `config.json`; missing fields take their defaults).
    #[arg(long)]
    pub train_config: Option<PathBuf>,
    /// Continue the run saved in this folder (its `checkpoint.json`); every
    /// setting comes from the checkpoint.
    #[arg(long)]
    pub resume: Option<PathBuf>,
    /// Start over in a folder that holds a run: the old folder is moved
    /// aside to `<name>.old-N` first.
    #[arg(long, conflicts_with = "resume")]
    pub force: bool,
    /// Environment steps between checkpoints (default: the training
    /// config's `checkpoint_every`).
    #[arg(long)]
    pub checkpoint_every: Option<u64>,
    /// Testing aid: behave as if Ctrl-C was pressed once this process has
    /// run this many SVG environment steps (over all methods).
    #[arg(long, hide = true)]
    pub interrupt_after: Option<u64>,
    /// The road, when it is not the demonstration's (see --other-road) or
    /// the file does not record one.
    #[command(flatten)]
    pub track: TrackArgs,
}

/// The run's settings from the command line, and the demonstration.
fn run_config(args: &TrainArgs) -> anyhow::Result<(DriveRunConfig, red_core::Demos)> {
    let demo = args.demo.clone().context("--demo is required")?;
    let requested = args.track.requested()?;
    let (demos, road, note) = drive::load_demo(&demo, requested, args.other_road)?;
    if let Some(n) = note {
        eprintln!("note: {n}");
    }
    let flags = DriveFlags {
        methods: args.methods.clone(),
        seed: args.seed,
        eval_runs: args.eval_runs,
        eval_roads: args.eval_roads,
        train_config: args.train_config.clone(),
        steps: args.steps,
        rnd_epochs: args.rnd_epochs,
        bc_epochs: args.bc_epochs,
        checkpoint_every: args.checkpoint_every,
    };
    Ok((flags.config(&demo, road)?, demos))
}

/// Runs `red-cli drive --demo FILE` (or `--resume DIR`).
pub fn run(args: TrainArgs) -> anyhow::Result<()> {
    interrupt::install();
    let mut bar = Bar::new(false, args.interrupt_after);
    let (outcome, out) = match &args.resume {
        Some(dir) => (
            drive::resume(dir, interrupt::flag(), &mut bar)?,
            dir.clone(),
        ),
        None => {
            let (config, demos) = run_config(&args)?;
            let force = args.force.into();
            let dir = red_experiments::RunDir::create_with(&args.out_dir, &args.name, force)?;
            let out = dir.path().to_path_buf();
            (
                drive::run_new(config, &demos, dir, interrupt::flag(), &mut bar)?,
                out,
            )
        }
    };
    if let Some(note) = outcome.stop_note(&out) {
        eprint!("{note}");
        std::process::exit(130);
    }
    if let DriveOutcome::Finished(report) = outcome {
        print!("{}", report.table());
    }
    Ok(())
}
