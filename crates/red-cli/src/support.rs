//! `red-cli support`: fit a support estimator on a demo file, and score a
//! demo file with a fitted model.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::{Args, Subcommand, ValueEnum};
use red_core::{Demos, Seeder, Stream};
use red_experiments::Progress;

use crate::progress::Bar;
use red_support::stats::summary_line;
use red_support::{
    EstimatorConfig, FitProgress, FittedEstimator, RedRewardConfig, Sigma1, SupportEstimatorConfig,
    SupportModel,
};

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
    let (s, a) = demos.pairs();
    if s.nrows() == 0 {
        bail!("{}: no state-action pairs to fit on", args.demo.display());
    }
    let json = crate::read_text(args.config.as_deref())?;
    let kind = args
        .estimator
        .to_possible_value()
        .map(|v| v.get_name().to_string());
    let mut cfg = EstimatorConfig::from_json(kind.as_deref().unwrap_or("rnd"), json.as_deref())?;
    if let Some(e) = args.epochs {
        cfg.set_epochs(e).context("--epochs")?;
    }
    cfg.validate().context("estimator config")?;
    println!(
        "fitting {} on {} pairs ({} state + {} action numbers) from {}, seed {}",
        cfg.kind(),
        s.nrows(),
        demos.obs_dim,
        demos.act_dim,
        args.demo.display(),
        args.seed
    );
    let mut bar = Bar::new(false, None);
    bar.start("fit", 0, 0);
    let mut on_progress = |p: FitProgress| {
        let loss = p.loss.map_or(String::new(), |l| format!("loss {l:.3e}"));
        bar.start_total(p.total as u64);
        bar.advance(p.done as u64, &loss);
    };
    let mut rng = Seeder::new(args.seed).rng(Stream::Estimator);
    let start = Instant::now();
    let model = cfg.fit(s.view(), a.view(), &mut rng, &mut on_progress)?;
    bar.finish();
    let secs = start.elapsed().as_secs_f64();
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
    if (demos.obs_dim, demos.act_dim) != (model.obs_dim(), model.act_dim()) {
        bail!(
            "{} has {} state + {} action numbers, the model was fitted on {} + {}",
            args.demo.display(),
            demos.obs_dim,
            demos.act_dim,
            model.obs_dim(),
            model.act_dim()
        );
    }
    let (s, a) = demos.pairs();
    if s.nrows() == 0 {
        bail!("{}: no state-action pairs to score", args.demo.display());
    }
    let mut scores = model.score(s.view(), a.view())?.to_vec();
    scores.sort_by(f64::total_cmp);
    println!(
        "{} model {} on {} pairs of {}",
        model.kind(),
        args.model.display(),
        scores.len(),
        args.demo.display()
    );
    println!("{}", summary_line("score L", &scores));
    let rule = args
        .sigma1
        .map_or(RedRewardConfig::default().sigma1, Sigma1::Fixed);
    let sigma1 = rule.resolve(&scores)?;
    if !(sigma1.is_finite() && sigma1 > 0.0) {
        bail!("--sigma1 must be finite and > 0, got {sigma1}");
    }
    println!("sigma1 = {sigma1:.6e} ({})", rule.describe());
    // exp(-sigma1 L) is decreasing in L, so the sorted rewards are the
    // reversed sorted scores.
    let rewards: Vec<f64> = scores.iter().rev().map(|l| (-sigma1 * l).exp()).collect();
    println!("{}", summary_line("reward r", &rewards));
    let share = rewards.iter().filter(|r| **r >= 0.9).count() as f64 / rewards.len() as f64;
    println!("share of pairs with reward >= 0.9: {share:.3}");
    Ok(())
}
