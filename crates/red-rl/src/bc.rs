//! Behaviour cloning: regress a [`GaussianPolicy`]'s mean on the expert's
//! actions (mean squared error), as a baseline and as a warm start for TRPO
//! (the release warm-starts HalfCheetah and Ant).
//!
//! One **epoch** is one shuffled pass over all demonstration pairs in
//! minibatches of `batch_size`, each an Adam step. The release's "20
//! iterations" (HalfCheetah) and "10" (Ant) are taken here as 20 and 10
//! epochs. (OpenAI baselines' behaviour cloning calls a single minibatch
//! step an iteration; 20 minibatch steps would barely move a fresh network,
//! so the epoch reading is the one a warm start can mean. This is a
//! judgement, not a fact read from the release.) `red-cli mujoco train`
//! keeps these for `ae` but clones for 100 epochs before a `red` run, a
//! measured change documented on its `RunConfig`.
//!
//! Only the mean head is trained; the log-std outputs get no gradient.
//! Observations go through the policy's own normaliser, so set it (for
//! example from the expert's observations) before cloning.

use ndarray::{Array2, ArrayView2};
use rand::Rng;
use rand::seq::SliceRandom;
use red_nets::{Adam, AdamConfig, Optimizer, Tape, Workspace};
use serde::{Deserialize, Serialize};

use crate::policy::GaussianPolicy;
use crate::{Error, Result};

/// Settings of [`behavior_clone`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BcConfig {
    /// Adam step size. Default 3e-4 (release).
    pub lr: f32,
    /// Minibatch size. Default 128 (release).
    pub batch_size: usize,
    /// Passes over the demonstrations. Default 20 (the release's
    /// HalfCheetah warm start; 10 for Ant); see the module documentation.
    pub epochs: usize,
}

impl Default for BcConfig {
    fn default() -> Self {
        Self {
            lr: 3e-4,
            batch_size: 128,
            epochs: 20,
        }
    }
}

impl BcConfig {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the field.
    pub fn validate(&self) -> Result<()> {
        if !(self.lr.is_finite() && self.lr > 0.0) {
            return Err(Error::InvalidConfig {
                field: "lr".into(),
                reason: format!("must be finite and > 0, got {}", self.lr),
            });
        }
        if self.batch_size == 0 {
            return Err(Error::InvalidConfig {
                field: "batch_size".into(),
                reason: "must be at least 1".into(),
            });
        }
        Ok(())
    }
}

fn check_pairs(
    policy: &GaussianPolicy,
    states: ArrayView2<'_, f64>,
    actions: ArrayView2<'_, f64>,
) -> Result<()> {
    if states.nrows() != actions.nrows() || states.nrows() == 0 {
        return Err(Error::ShapeMismatch {
            what: "demonstration pairs".into(),
            expected: "as many action rows as state rows, at least one".into(),
            got: format!("{} states and {} actions", states.nrows(), actions.nrows()),
        });
    }
    if actions.ncols() != policy.act_dim() {
        return Err(Error::ShapeMismatch {
            what: "demonstration actions".into(),
            expected: format!("{} columns", policy.act_dim()),
            got: format!("{}", actions.ncols()),
        });
    }
    if actions.iter().any(|v| !v.is_finite()) {
        return Err(Error::NonFinite {
            what: "demonstration action".into(),
            step: 0,
        });
    }
    Ok(())
}

/// Mean over pairs and action dimensions of `(mu(s) - a)^2`.
///
/// # Errors
/// Shape mismatches or non-finite actions.
pub fn bc_mse(
    policy: &GaussianPolicy,
    states: ArrayView2<'_, f64>,
    actions: ArrayView2<'_, f64>,
) -> Result<f64> {
    check_pairs(policy, states, actions)?;
    let obs = policy.prepare_obs(states)?;
    let dist = policy.distribution(obs.view(), &mut Workspace::new())?;
    let diff = &dist.mean - &actions;
    Ok(diff.mapv(|d| d * d).mean().unwrap_or(0.0))
}

/// Trains `policy`'s mean on the pairs (`states` `(n, obs_dim)` raw,
/// `actions` `(n, act_dim)`) and returns the mean training loss of each
/// epoch. Minibatches are shuffled with `rng`.
///
/// # Errors
/// [`Error::InvalidConfig`] for a bad config, shape mismatches, non-finite
/// data or a non-finite loss.
pub fn behavior_clone<R: Rng + ?Sized>(
    policy: &mut GaussianPolicy,
    states: ArrayView2<'_, f64>,
    actions: ArrayView2<'_, f64>,
    config: &BcConfig,
    rng: &mut R,
) -> Result<Vec<f64>> {
    config.validate()?;
    check_pairs(policy, states, actions)?;
    let obs = policy.prepare_obs(states)?;
    let n = obs.nrows();
    let (od, k) = (policy.obs_dim(), policy.act_dim());
    let mut adam = Adam::new(AdamConfig::with_lr(config.lr), policy.net())?;
    let mut idx: Vec<usize> = (0..n).collect();
    let mut tape = Tape::new();
    let mut grads = policy.net().zero_grads();
    let mut losses = Vec::with_capacity(config.epochs);
    for epoch in 0..config.epochs {
        idx.shuffle(rng);
        let (mut sum, mut count) = (0.0, 0usize);
        for chunk in idx.chunks(config.batch_size) {
            let m = chunk.len();
            let mut x = Array2::<f32>::zeros((m, od));
            for (r, &i) in chunk.iter().enumerate() {
                x.row_mut(r).assign(&obs.row(i));
            }
            // The distribution's path, so the network sees its wrapped
            // inputs too; its means are the outputs before the log-stds.
            let mean = policy.distribution_tape(x.view(), &mut tape)?.mean;
            let mut g = Array2::<f32>::zeros((m, 2 * k));
            let mut loss = 0.0f64;
            let mut first_bad = None;
            let scale = 2.0 / (m * k) as f64;
            for (r, &i) in chunk.iter().enumerate() {
                for j in 0..k {
                    let d = mean[[r, j]] - actions[[i, j]];
                    if !(d * d).is_finite() && first_bad.is_none() {
                        first_bad = Some(i);
                    }
                    loss += d * d;
                    g[[r, j]] = (scale * d) as f32;
                }
            }
            loss /= (m * k) as f64;
            if !loss.is_finite() {
                let pair = first_bad.map_or_else(String::new, |i| {
                    format!(
                        " (first non-finite at demonstration pair {i} of {n}, counted through \
                         the trajectories in order)"
                    )
                });
                return Err(Error::NonFinite {
                    what: format!("behaviour-cloning loss{pair}"),
                    step: epoch as u64,
                });
            }
            grads.zero();
            policy.net().backward_params(&tape, g.view(), &mut grads);
            adam.step(policy.net_mut(), &grads)?;
            sum += loss * m as f64;
            count += m;
        }
        losses.push(sum / count as f64);
    }
    Ok(losses)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validate_names_field() {
        let c = BcConfig {
            batch_size: 0,
            ..Default::default()
        };
        assert!(c.validate().unwrap_err().to_string().contains("batch_size"));
    }
}
