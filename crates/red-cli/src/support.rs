//! `red-cli support`: fit a support estimator on a demo file, and score a
//! demo file with a fitted model.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::{Args, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use red_core::{Demos, Seeder, Stream};
use red_support::stats::quantile_sorted;
use red_support::{
    AutoencoderConfig, EstimatorConfig, FitProgress, FittedEstimator, KernelPcaConfig,
    RedRewardConfig, RndConfig, Sigma1, SupportEstimatorConfig, SupportModel, calibrate_sigma1,
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

/// The estimator kinds.
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

fn read_config<T: serde::de::DeserializeOwned + Default>(
    path: &Option<PathBuf>,
) -> anyhow::Result<T> {
    match path {
        None => Ok(T::default()),
        Some(p) => {
            let text =
                std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
            serde_json::from_str(&text).with_context(|| format!("parsing {}", p.display()))
        }
    }
}

fn fit(args: FitArgs) -> anyhow::Result<()> {
    let demos =
        Demos::read(&args.demo).with_context(|| format!("reading {}", args.demo.display()))?;
    let (s, a) = demos.pairs();
    if s.nrows() == 0 {
        bail!("{}: no state-action pairs to fit on", args.demo.display());
    }
    let mut cfg = match args.estimator {
        Kind::Rnd => EstimatorConfig::Rnd(read_config::<RndConfig>(&args.config)?),
        Kind::Ae => EstimatorConfig::Autoencoder(read_config::<AutoencoderConfig>(&args.config)?),
        Kind::Kpca => EstimatorConfig::KernelPca(read_config::<KernelPcaConfig>(&args.config)?),
    };
    if let Some(e) = args.epochs {
        match &mut cfg {
            EstimatorConfig::Rnd(c) => c.epochs = e,
            EstimatorConfig::Autoencoder(c) => c.epochs = e,
            EstimatorConfig::KernelPca(_) => bail!("--epochs does not apply to kernel PCA"),
        }
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
    let bar = ProgressBar::new(0);
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} {msg} [{elapsed_precise} < {eta}]")
            .context("progress bar template")?,
    );
    let mut on_progress = |p: FitProgress| {
        bar.set_length(p.total as u64);
        bar.set_position(p.done as u64);
        if let Some(l) = p.loss {
            bar.set_message(format!("loss {l:.3e}"));
        }
    };
    let mut rng = Seeder::new(args.seed).rng(Stream::Estimator);
    let start = Instant::now();
    let model = cfg.fit(s.view(), a.view(), &mut rng, &mut on_progress)?;
    bar.finish_and_clear();
    let secs = start.elapsed().as_secs_f64();
    model
        .save(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    let detail = match &model {
        FittedEstimator::Rnd(m) => format!("final training loss {:?}", m.final_losses()),
        FittedEstimator::Autoencoder(m) => format!("final training loss {:.4e}", m.final_loss()),
        FittedEstimator::KernelPca(m) => format!(
            "bandwidth {:.4}, {} components ({:.4} of the trace)",
            m.bandwidth(),
            m.components(),
            m.explained_share()
        ),
    };
    println!("fitted in {secs:.1} s: {detail}");
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
    print_stats("score L", &scores);
    let (sigma1, how) = match args.sigma1 {
        Some(s) => (s, "given".to_string()),
        None => match RedRewardConfig::default().sigma1 {
            Sigma1::Calibrated { quantile, reward } => (
                calibrate_sigma1(&scores, quantile, reward)?,
                format!("calibrated: the {quantile} quantile of these scores gets reward {reward}"),
            ),
            Sigma1::Fixed(s) => (s, "default".to_string()),
        },
    };
    if !(sigma1.is_finite() && sigma1 > 0.0) {
        bail!("--sigma1 must be finite and > 0, got {sigma1}");
    }
    println!("sigma1 = {sigma1:.6e} ({how})");
    // exp(-sigma1 L) is decreasing in L, so the sorted rewards are the
    // reversed sorted scores.
    let rewards: Vec<f64> = scores.iter().rev().map(|l| (-sigma1 * l).exp()).collect();
    print_stats("reward r", &rewards);
    let share = rewards.iter().filter(|r| **r >= 0.9).count() as f64 / rewards.len() as f64;
    println!("share of pairs with reward >= 0.9: {share:.3}");
    Ok(())
}

fn print_stats(name: &str, sorted: &[f64]) {
    let mean = sorted.iter().sum::<f64>() / sorted.len() as f64;
    println!(
        "{name:<8} mean {:.4e}  min {:.4e}  q10 {:.4e}  q25 {:.4e}  median {:.4e}  q75 {:.4e}  q90 {:.4e}  q99 {:.4e}  max {:.4e}",
        mean,
        sorted[0],
        quantile_sorted(sorted, 0.1),
        quantile_sorted(sorted, 0.25),
        quantile_sorted(sorted, 0.5),
        quantile_sorted(sorted, 0.75),
        quantile_sorted(sorted, 0.9),
        quantile_sorted(sorted, 0.99),
        sorted[sorted.len() - 1]
    );
}
