//! Generalised advantage estimation (Schulman et al., 2016), with the end of
//! a task (`terminated`) kept apart from a time-limit cut (`truncated`).
//!
//! For step `t` with reward `r_t`, value `V(s_t)` and the value `V(s_{t+1})`
//! of the observation the step produced,
//!
//! ```text
//! delta_t = r_t + gamma * b_t * V(s_{t+1}) - V(s_t)
//! A_t     = delta_t + gamma * lambda * c_t * A_{t+1}
//! ```
//!
//! where `b_t` is 0 after a termination (and after a truncation unless
//! [`GaeConfig::bootstrap_on_truncation`]) and 1 otherwise, and `c_t` is 0
//! when an episode ended at `t` or `t` is the batch's last step (nothing of
//! the episode follows in the batch). A batch that stops mid-episode is
//! bootstrapped with the value of its last next-observation, as the release
//! does.
//!
//! ```
//! use red_rl::gae::{gae, GaeConfig};
//! let cfg = GaeConfig { gamma: 0.5, lambda: 1.0, bootstrap_on_truncation: false };
//! let (adv, ret) = gae(&cfg, &[1.0, 1.0], &[0.0, 0.0], &[0.0, 0.0], &[false, true], &[false, false])?;
//! assert_eq!(adv, vec![1.5, 1.0]);
//! assert_eq!(ret, adv);
//! # Ok::<(), red_rl::Error>(())
//! ```

use serde::{Deserialize, Serialize};

use crate::{Error, Result};

/// Settings of [`gae`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GaeConfig {
    /// Discount factor, in `[0, 1]`.
    pub gamma: f64,
    /// GAE's `lambda`, in `[0, 1]`.
    pub lambda: f64,
    /// Whether a time-limit cut (`truncated`) is bootstrapped with the value
    /// of the last observation (the textbook treatment: the state is not
    /// terminal, only the episode was cut). `false` treats it as terminal.
    pub bootstrap_on_truncation: bool,
}

impl Default for GaeConfig {
    /// The RED release's MuJoCo settings: `gamma = 0.97` (the release uses
    /// 0.99 for Reacher), `lambda = 0.97`, and a time-limit cut treated as
    /// terminal (`bootstrap_on_truncation = false`), as the release (built on
    /// OpenAI baselines) does.
    fn default() -> Self {
        Self {
            gamma: 0.97,
            lambda: 0.97,
            bootstrap_on_truncation: false,
        }
    }
}

impl GaeConfig {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming `gamma` or `lambda` if outside `[0, 1]`.
    pub fn validate(&self) -> Result<()> {
        for (field, v) in [("gamma", self.gamma), ("lambda", self.lambda)] {
            if !(0.0..=1.0).contains(&v) {
                return Err(Error::InvalidConfig {
                    field: field.into(),
                    reason: format!("must be in [0, 1], got {v}"),
                });
            }
        }
        Ok(())
    }
}

/// Advantages and lambda-returns (`advantage + value`, the value targets) of
/// a batch of consecutive steps, possibly spanning several episodes.
///
/// All slices have the batch's length `T`: `rewards[t]`, `values[t] =
/// V(s_t)`, `next_values[t] = V(s_{t+1})` (the value of the observation
/// returned by step `t`, before any reset; only read where it is used, so
/// its entry may be anything after a termination), and the step's
/// `terminated` / `truncated` flags.
///
/// # Errors
/// [`Error::ShapeMismatch`] if the slices differ in length,
/// [`Error::InvalidConfig`] for a bad config.
pub fn gae(
    cfg: &GaeConfig,
    rewards: &[f64],
    values: &[f64],
    next_values: &[f64],
    terminated: &[bool],
    truncated: &[bool],
) -> Result<(Vec<f64>, Vec<f64>)> {
    let n = rewards.len();
    let mut adv = vec![0.0; n];
    let mut ret = vec![0.0; n];
    gae_into(
        cfg,
        rewards,
        values,
        next_values,
        terminated,
        truncated,
        &mut adv,
        &mut ret,
    )?;
    Ok((adv, ret))
}

/// [`gae`] writing into preallocated `advantages` and `returns` (length `T`).
///
/// # Errors
/// As [`gae`], and [`Error::ShapeMismatch`] if an output has the wrong length.
pub fn gae_into(
    cfg: &GaeConfig,
    rewards: &[f64],
    values: &[f64],
    next_values: &[f64],
    terminated: &[bool],
    truncated: &[bool],
    advantages: &mut [f64],
    returns: &mut [f64],
) -> Result<()> {
    cfg.validate()?;
    let n = rewards.len();
    let lens = [
        ("values", values.len()),
        ("next_values", next_values.len()),
        ("terminated", terminated.len()),
        ("truncated", truncated.len()),
        ("advantages", advantages.len()),
        ("returns", returns.len()),
    ];
    for (what, len) in lens {
        if len != n {
            return Err(Error::ShapeMismatch {
                what: format!("gae {what}"),
                expected: format!("{n} entries (one per reward)"),
                got: format!("{len}"),
            });
        }
    }
    let mut next_adv = 0.0;
    for t in (0..n).rev() {
        let ended = terminated[t] || truncated[t];
        let bootstrap = !terminated[t] && (!truncated[t] || cfg.bootstrap_on_truncation);
        let next_v = if bootstrap { next_values[t] } else { 0.0 };
        let delta = rewards[t] + cfg.gamma * next_v - values[t];
        // `next_adv` is 0 at the batch's last step and after an episode end.
        let carry = if ended { 0.0 } else { next_adv };
        let a = delta + cfg.gamma * cfg.lambda * carry;
        advantages[t] = a;
        returns[t] = a + values[t];
        next_adv = a;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg(gamma: f64, lambda: f64, boot: bool) -> GaeConfig {
        GaeConfig {
            gamma,
            lambda,
            bootstrap_on_truncation: boot,
        }
    }

    #[test]
    fn lambda_one_zero_values_gives_discounted_returns() {
        let (adv, _) = gae(
            &cfg(0.9, 1.0, false),
            &[1.0, 2.0, 3.0],
            &[0.0; 3],
            &[0.0; 3],
            &[false, false, true],
            &[false; 3],
        )
        .unwrap();
        let want = [1.0 + 0.9 * 2.0 + 0.81 * 3.0, 2.0 + 0.9 * 3.0, 3.0];
        for (a, w) in adv.iter().zip(want) {
            assert!((a - w).abs() < 1e-12, "{adv:?}");
        }
    }

    #[test]
    fn lambda_zero_is_one_step_td_error() {
        let r = [1.0, -1.0, 0.5];
        let v = [0.3, 0.2, 0.1];
        let nv = [0.2, 0.1, 0.7];
        let (adv, ret) = gae(&cfg(0.9, 0.0, false), &r, &v, &nv, &[false; 3], &[false; 3]).unwrap();
        for t in 0..3 {
            let want = r[t] + 0.9 * nv[t] - v[t];
            assert!((adv[t] - want).abs() < 1e-12);
            assert!((ret[t] - (want + v[t])).abs() < 1e-12);
        }
    }

    #[test]
    fn validate_names_field() {
        let err = cfg(1.5, 0.9, false).validate().unwrap_err().to_string();
        assert!(err.contains("gamma"), "{err}");
    }
}
