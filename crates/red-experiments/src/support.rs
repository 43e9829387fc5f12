//! A support estimator on its own (`red-cli support`): fitting one on the
//! expert pairs of a demonstration file, and scoring a file's pairs with a
//! fitted model (the scores, the `σ1` a rule gives and RED's reward
//! `exp(-σ1 L)`).

use std::path::Path;
use std::time::Instant;

use ndarray::Array2;
use red_core::{Demos, Seeder, Stream};
use red_support::stats::summary_line;
use red_support::{
    EstimatorConfig, FitProgress, FittedEstimator, RedRewardConfig, Sigma1, SupportEstimatorConfig,
    SupportModel,
};

use crate::{Error, Progress, Result, ResultExt};

/// The estimator config of `kind` (`rnd`, `ae`, `kpca`) from the JSON of
/// its fields (`None`: the defaults), with `epochs` set when given,
/// validated.
///
/// # Errors
/// [`Error::Support`] for an unknown kind, bad JSON or a bad value, with
/// the setting named (`--epochs` for kernel PCA, which has none).
pub fn estimator_config(
    kind: &str,
    json: Option<&str>,
    epochs: Option<usize>,
) -> Result<EstimatorConfig> {
    let mut cfg = EstimatorConfig::from_json(kind, json)?;
    if let Some(e) = epochs {
        cfg.set_epochs(e).with_context(|| "--epochs")?;
    }
    cfg.validate().with_context(|| "estimator config")?;
    Ok(cfg)
}

/// The state-action pairs of `demos` (read from `path`), refusing a file
/// without any; `what` says what they are for (`fit`, `score`).
///
/// # Errors
/// [`Error::Input`] when there are no pairs.
pub fn demo_pairs(demos: &Demos, path: &Path, what: &str) -> Result<(Array2<f64>, Array2<f64>)> {
    let (s, a) = demos.pairs();
    if s.nrows() == 0 {
        return Err(Error::Input {
            path: path.to_path_buf(),
            reason: format!("no state-action pairs to {what}"),
        });
    }
    Ok((s, a))
}

/// The line that announces a fit of `cfg` on `pairs` pairs of `demos`
/// (read from `path`) with `seed`.
pub fn fit_line(
    cfg: &EstimatorConfig,
    pairs: usize,
    demos: &Demos,
    path: &Path,
    seed: u64,
) -> String {
    format!(
        "fitting {} on {pairs} pairs ({} state + {} action numbers) from {}, seed {seed}",
        cfg.kind(),
        demos.obs_dim,
        demos.act_dim,
        path.display()
    )
}

/// Fits `cfg` on the pairs `(s, a)` with the estimator stream of `seed`,
/// shown to `progress` as the phase `fit` (units: epochs, or kernel PCA's
/// stages, with the last loss as message); returns the model and the
/// seconds the fit took.
///
/// # Errors
/// The estimator's errors.
pub fn fit(
    cfg: &EstimatorConfig,
    (s, a): &(Array2<f64>, Array2<f64>),
    seed: u64,
    progress: &mut dyn Progress,
) -> Result<(FittedEstimator, f64)> {
    let mut rng = Seeder::new(seed).rng(Stream::Estimator);
    let start = Instant::now();
    progress.start("fit", 0, 0);
    let mut total = 0;
    let mut on_progress = |p: FitProgress| {
        if p.total as u64 != total {
            // The total is known once the fit has begun.
            total = p.total as u64;
            progress.start("fit", total, p.done as u64);
        }
        let loss = p.loss.map_or(String::new(), |l| format!("loss {l:.3e}"));
        progress.advance(p.done as u64, &loss);
    };
    let model = cfg.fit(s.view(), a.view(), &mut rng, &mut on_progress)?;
    progress.finish();
    Ok((model, start.elapsed().as_secs_f64()))
}

/// What scoring a demonstration file's pairs with a fitted model gives.
#[derive(Debug, Clone, PartialEq)]
pub struct ScoreReport {
    /// The scores `L`, sorted ascending.
    pub scores: Vec<f64>,
    /// The `σ1` used.
    pub sigma1: f64,
    /// How it was chosen ([`Sigma1::describe`]).
    pub rule: String,
    /// RED's rewards `exp(-σ1 L)`, sorted ascending.
    pub rewards: Vec<f64>,
    /// Share of the pairs with reward at least 0.9.
    pub share_high: f64,
}

impl ScoreReport {
    /// The report as `red-cli support score` prints it: what was scored
    /// (`model` read from `model_path`, the pairs of `demo_path`), the
    /// score statistics, `σ1` and its rule, the reward statistics and the
    /// share of high rewards; one line each, each ending with a newline.
    pub fn summary(&self, model: &FittedEstimator, model_path: &Path, demo_path: &Path) -> String {
        format!(
            "{} model {} on {} pairs of {}\n{}\nsigma1 = {:.6e} ({})\n{}\n\
             share of pairs with reward >= 0.9: {:.3}\n",
            model.kind(),
            model_path.display(),
            self.scores.len(),
            demo_path.display(),
            summary_line("score L", &self.scores),
            self.sigma1,
            self.rule,
            summary_line("reward r", &self.rewards),
            self.share_high
        )
    }
}

/// Scores the pairs of `demos` (read from `path`) with `model`; `σ1` is
/// `sigma1` when given, else calibrated on the scored pairs by
/// [`RedRewardConfig`]'s default rule.
///
/// # Errors
/// [`Error::Input`] for a file of other dimensions than the model's or
/// without pairs; [`Error::InvalidConfig`] for a `σ1` that is not finite
/// and positive; the model's errors.
pub fn score(
    model: &FittedEstimator,
    demos: &Demos,
    path: &Path,
    sigma1: Option<f64>,
) -> Result<ScoreReport> {
    if (demos.obs_dim, demos.act_dim) != (model.obs_dim(), model.act_dim()) {
        return Err(Error::Input {
            path: path.to_path_buf(),
            reason: format!(
                "has {} state + {} action numbers, the model was fitted on {} + {}",
                demos.obs_dim,
                demos.act_dim,
                model.obs_dim(),
                model.act_dim()
            ),
        });
    }
    let (s, a) = demo_pairs(demos, path, "score")?;
    let mut scores = model.score(s.view(), a.view())?.to_vec();
    scores.sort_by(f64::total_cmp);
    let rule = sigma1.map_or(RedRewardConfig::default().sigma1, Sigma1::Fixed);
    let sigma1 = rule.resolve(&scores)?;
    if !(sigma1.is_finite() && sigma1 > 0.0) {
        return Err(Error::InvalidConfig {
            field: "--sigma1".into(),
            reason: format!("must be finite and > 0, got {sigma1}"),
        });
    }
    // exp(-sigma1 L) is decreasing in L, so the sorted rewards are the
    // reversed sorted scores.
    let rewards: Vec<f64> = scores.iter().rev().map(|l| (-sigma1 * l).exp()).collect();
    let share_high = rewards.iter().filter(|r| **r >= 0.9).count() as f64 / rewards.len() as f64;
    Ok(ScoreReport {
        scores,
        sigma1,
        rule: rule.describe(),
        rewards,
        share_high,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use red_core::{EpisodeEnd, Trajectory};

    fn demos(n: usize) -> Demos {
        let mut d = Demos::new("Toy-v0", 2, 1, None);
        if n > 0 {
            d.trajectories.push(Trajectory {
                observations: (0..n).map(|i| vec![i as f64 / n as f64, 0.5]).collect(),
                actions: (0..n).map(|i| vec![(i % 3) as f64 / 3.0]).collect(),
                rewards: None,
                end: EpisodeEnd::Truncated,
            });
        }
        d
    }

    /// What a fit tells its observer.
    #[derive(Default)]
    struct Seen {
        starts: Vec<u64>,
        done: Vec<u64>,
        finished: bool,
    }

    impl Progress for Seen {
        fn start(&mut self, _label: &str, total: u64, _done: u64) {
            self.starts.push(total);
        }
        fn advance(&mut self, done: u64, _message: &str) {
            self.done.push(done);
        }
        fn finish(&mut self) {
            self.finished = true;
        }
    }

    #[test]
    fn fits_and_scores_a_file_and_refuses_what_does_not_fit() {
        let path = Path::new("demo.json");
        let cfg = estimator_config("kpca", None, None).unwrap();
        assert!(estimator_config("kpca", None, Some(3)).is_err());
        assert!(estimator_config("nope", None, None).is_err());
        let d = demos(40);
        let pairs = demo_pairs(&d, path, "fit").unwrap();
        let mut seen = Seen::default();
        let (model, secs) = fit(&cfg, &pairs, 0, &mut seen).unwrap();
        assert!(secs >= 0.0);
        // The bar starts, learns the fit's total, reaches it and ends.
        let total = seen.starts.last().copied().unwrap();
        assert!(seen.starts.len() >= 2 && total > 0, "{:?}", seen.starts);
        assert_eq!(seen.done.last(), Some(&total));
        assert!(seen.finished);
        let line = fit_line(&cfg, pairs.0.nrows(), &d, path, 7);
        assert_eq!(
            line,
            "fitting kpca on 40 pairs (2 state + 1 action numbers) from demo.json, seed 7"
        );
        let r = score(&model, &d, path, None).unwrap();
        assert_eq!(r.scores.len(), 40);
        assert!(r.scores.windows(2).all(|w| w[0] <= w[1]));
        assert!(r.rewards.windows(2).all(|w| w[0] <= w[1]));
        assert!((0.0..=1.0).contains(&r.share_high));
        let fixed = score(&model, &d, path, Some(2.0)).unwrap();
        assert_eq!(fixed.sigma1, 2.0);
        assert_eq!(fixed.rewards[0], (-2.0 * fixed.scores[39]).exp());
        assert!(score(&model, &d, path, Some(-1.0)).is_err());
        assert!(demo_pairs(&demos(0), path, "fit").is_err());
        let other = Demos::new("Toy-v0", 3, 1, None);
        let err = score(&model, &other, path, None).unwrap_err().to_string();
        assert!(err.contains("the model was fitted on 2 + 1"), "{err}");
    }
}
