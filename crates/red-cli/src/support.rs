//! `red-cli support`: fit a support estimator on a demo file, and score a
//! demo file with a fitted model.

use std::path::PathBuf;

use anyhow::Context;
use clap::{Args, Subcommand, ValueEnum};
use red_core::Demos;
use red_experiments::support;

use crate::progress::Bar;
use red_support::FittedEstimator;

/// Arguments of `red-cli support`.
#[derive(Debug, Args)]
pub struct SupportArgs {
    #[command(subcommand)]
    command: SupportCommand,
}

#[derive(Debug, Subcommand)]
enum SupportCommand {
    /// Fit a support estimator on the expert pairs of a demo file and save it.
    Fit(FitArgs),
    /// Score the pairs of a demo file with a fitted model: score statistics
    /// and RED's reward exp(-sigma1 * score).
    Score(ScoreArgs),
}

/// The estimator kinds (their value names are `EstimatorConfig::kind`'s).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Kind {
    /// Random network distillation (the release's networks).
    Rnd,
    /// Over-parametrised autoencoder with L2 weight decay.
    Ae,
    /// Exact kernel PCA (Gaussian kernel, median bandwidth).
    Kpca,
}

#[derive(Debug, Args)]
struct FitArgs {
    /// Demonstration file (the project's JSON format).
    #[arg(long)]
    demo: PathBuf,
    /// Which estimator.
    #[arg(long, value_enum)]
    estimator: Kind,
    /// Where to write the fitted model (JSON).
    #[arg(long)]
    out: PathBuf,
    /// Run seed (the estimator's stream of it initialises and shuffles).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Training epochs (RND and AE; default 200 as in the release).
    #[arg(long)]
    epochs: Option<usize>,
    /// Estimator config as JSON (fields of RndConfig, AutoencoderConfig or
    /// KernelPcaConfig; missing fields take their defaults). `--epochs`
    /// overrides its epochs.
    #[arg(long)]
    config: Option<PathBuf>,
}

#[derive(Debug, Args)]
struct ScoreArgs {
    /// A model written by `red-cli support fit`.
    #[arg(long)]
    model: PathBuf,
    /// Demonstration file whose pairs are scored.
    #[arg(long)]
    demo: PathBuf,
    /// A fixed sigma1; without it sigma1 is calibrated on the scored pairs
    /// (their 0.9 quantile gets reward 0.9, RedRewardConfig's default).
    #[arg(long)]
    sigma1: Option<f64>,
}

/// Runs `red-cli support`.
pub fn run(args: SupportArgs) -> anyhow::Result<()> {
    match args.command {
        SupportCommand::Fit(a) => fit(a),
        SupportCommand::Score(a) => score(a),
    }
}

fn fit(args: FitArgs) -> anyhow::Result<()> {
    let demos =
        Demos::read(&args.demo).with_context(|| format!("reading {}", args.demo.display()))?;
    let pairs = support::demo_pairs(&demos, &args.demo, "fit on")?;
    let json = crate::read_text(args.config.as_deref())?;
    let kind = args
        .estimator
        .to_possible_value()
        .map(|v| v.get_name().to_string());
    let cfg = support::estimator_config(
        kind.as_deref().unwrap_or("rnd"),
        json.as_deref(),
        args.epochs,
    )?;
    let n = pairs.0.nrows();
    println!(
        "{}",
        support::fit_line(&cfg, n, &demos, &args.demo, args.seed)
    );
    // The fit finishes the bar before the lines below.
    let (model, secs) = support::fit(&cfg, &pairs, args.seed, &mut Bar::new(false, None))?;
    model
        .save(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    println!("fitted in {secs:.1} s: {}", model.describe());
    println!("model written to {}", args.out.display());
    Ok(())
}

fn score(args: ScoreArgs) -> anyhow::Result<()> {
    let model = FittedEstimator::load(&args.model)?;
    let demos =
        Demos::read(&args.demo).with_context(|| format!("reading {}", args.demo.display()))?;
    let r = support::score(&model, &demos, &args.demo, args.sigma1)?;
    print!("{}", r.summary(&model, &args.model, &args.demo));
    Ok(())
}
