//! Held-out scores of the expert pairs by k-fold cross-fitting, for
//! calibrating `σ1` on pairs a model has not seen.
//!
//! A support estimator fitted on few pairs scores its own training pairs far
//! below other pairs of the same support (RND's predictor can nearly
//! memorise five points). Calibrating `σ1` on those training scores then
//! gives a `σ1` so large that unseen on-support pairs already get rewards
//! near 0, indistinguishable from off-support ones. Scores of held-out
//! expert pairs measure what "on the support" looks like to the model.

use ndarray::{Array1, Array2, ArrayView2};
use rand::Rng;
use rand::seq::SliceRandom;

use crate::estimator::{SupportEstimatorConfig, SupportModel, no_progress};
use crate::{Error, Result};

/// Scores every expert pair with a model fitted on the OTHER folds: the
/// pairs are shuffled into `folds` near-equal folds, and `folds` models are
/// fitted, each on all folds but one. Returns `n` held-out scores in the
/// order of the input rows.
///
/// # Errors
/// [`Error::InvalidConfig`] if `folds < 2` or `folds > n`; the estimator's
/// own fitting and scoring errors.
pub fn held_out_scores<C: SupportEstimatorConfig, R: Rng + ?Sized>(
    config: &C,
    states: ArrayView2<'_, f64>,
    actions: ArrayView2<'_, f64>,
    folds: usize,
    rng: &mut R,
) -> Result<Array1<f64>> {
    let n = states.nrows();
    if folds < 2 || folds > n {
        return Err(Error::InvalidConfig {
            field: "folds".into(),
            reason: format!("need 2 <= folds <= {n} (the number of expert pairs), got {folds}"),
        });
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.shuffle(rng);
    let mut scores = Array1::zeros(n);
    for k in 0..folds {
        let held: Vec<usize> = order.iter().copied().skip(k).step_by(folds).collect();
        let kept: Vec<usize> = order
            .iter()
            .copied()
            .filter(|i| !held.contains(i))
            .collect();
        let pick = |m: ArrayView2<'_, f64>, rows: &[usize]| -> Array2<f64> {
            Array2::from_shape_fn((rows.len(), m.ncols()), |(r, c)| m[[rows[r], c]])
        };
        let model = config.fit(
            pick(states, &kept).view(),
            pick(actions, &kept).view(),
            rng,
            &mut no_progress,
        )?;
        let s = model.score(pick(states, &held).view(), pick(actions, &held).view())?;
        for (r, &i) in held.iter().enumerate() {
            scores[i] = s[r];
        }
    }
    Ok(scores)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{RndConfig, calibrate_sigma1};
    use rand::SeedableRng;

    #[test]
    fn held_out_scores_exceed_training_scores() {
        let s = Array2::from_shape_fn((10, 1), |(i, _)| -1.0 + 0.2 * i as f64);
        let a = s.mapv(|v| if v >= 0.0 { 1.0 } else { 0.0 });
        let config = RndConfig {
            epochs: 100,
            ..RndConfig::default()
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
        let full = config
            .fit(s.view(), a.view(), &mut rng, &mut no_progress)
            .unwrap();
        let train = full.score(s.view(), a.view()).unwrap();
        let held = held_out_scores(&config, s.view(), a.view(), 5, &mut rng).unwrap();
        let q_train = calibrate_sigma1(train.as_slice().unwrap(), 0.9, 0.9).unwrap();
        let q_held = calibrate_sigma1(held.as_slice().unwrap(), 0.9, 0.9).unwrap();
        assert!(
            q_held < q_train,
            "held-out sigma1 {q_held} vs training {q_train}"
        );
        assert!(held.iter().all(|v| v.is_finite() && *v >= 0.0));
    }

    #[test]
    fn rejects_bad_fold_counts() {
        let s = Array2::zeros((3, 1));
        let a = Array2::zeros((3, 1));
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
        let err =
            held_out_scores(&RndConfig::default(), s.view(), a.view(), 4, &mut rng).unwrap_err();
        assert!(err.to_string().contains("folds"), "{err}");
    }
}
