//! Checks of a loaded checkpoint's values that make no sense even when the
//! file is whole (its checksum holds): a policy whose hidden sizes disagree
//! with the run's settings, a normaliser with a negative or non-finite
//! variance, more steps than the budget. Each returns what is wrong in
//! words; the caller names the file.

use red_rl::normalize::ObsNormalizer;
use red_rl::policy::GaussianPolicy;

/// A policy of the run: its own settings' hidden sizes, its network's and
/// the run's `hidden` must agree, and its normaliser must be sound.
///
/// # Errors
/// What disagrees, naming `what`.
pub fn check_policy(
    what: &str,
    policy: &GaussianPolicy,
    hidden: &[usize],
) -> std::result::Result<(), String> {
    let own = &policy.config().hidden;
    let net = &policy.net().config().hidden;
    if own != hidden || net != hidden {
        return Err(format!(
            "{what}: the run's settings give hidden sizes {hidden:?}, but the saved policy has \
             {own:?} and its network {net:?}"
        ));
    }
    if let Some(n) = policy.normalizer() {
        check_normalizer(what, n)?;
    }
    Ok(())
}

/// An observation normaliser: a finite non-negative count, finite means,
/// finite non-negative variances.
///
/// # Errors
/// The first bad value, naming `what` and its column.
pub fn check_normalizer(what: &str, n: &ObsNormalizer) -> std::result::Result<(), String> {
    if !(n.count().is_finite() && n.count() >= 0.0) {
        return Err(format!(
            "{what}: the observation normaliser's count is {}",
            n.count()
        ));
    }
    if let Some((j, v)) = n.mean().iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(format!(
            "{what}: the observation normaliser's mean[{j}] is {v}"
        ));
    }
    if let Some((j, v)) = n
        .var()
        .iter()
        .enumerate()
        .find(|(_, v)| !(v.is_finite() && **v >= 0.0))
    {
        return Err(format!(
            "{what}: the observation normaliser's variance[{j}] is {v}; a variance is never \
             negative"
        ));
    }
    Ok(())
}

/// Environment steps done against the budget.
///
/// # Errors
/// When `done` exceeds `budget`, naming `what`.
pub fn check_steps(what: &str, done: u64, budget: u64) -> std::result::Result<(), String> {
    if done > budget {
        return Err(format!(
            "{what} has {done} environment steps, beyond the run's budget of {budget}"
        ));
    }
    Ok(())
}
