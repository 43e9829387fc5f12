//! Checks of a loaded checkpoint's values that make no sense even when the
//! file is whole (its checksum holds): a policy whose hidden sizes disagree
//! with the run's settings, a normaliser with a negative or non-finite
//! variance, more steps than the budget. Each returns what is wrong in
//! words; the caller names the file.

use red_rl::normalize::ObsNormalizer;
use red_rl::policy::{GaussianPolicy, GaussianPolicyConfig};

/// A policy of the run: its own settings' hidden sizes, its network's and
/// the run's (`run`) must agree, as must its wrapped inputs and the run's,
/// and its normaliser must be sound.
///
/// # Errors
/// What disagrees, naming `what`.
pub fn check_policy(
    what: &str,
    policy: &GaussianPolicy,
    run: &GaussianPolicyConfig,
) -> std::result::Result<(), String> {
    let hidden = &run.hidden;
    let own = &policy.config().hidden;
    let net = &policy.net().config().hidden;
    if own != hidden || net != hidden {
        return Err(format!(
            "{what}: the run's settings give hidden sizes {hidden:?}, but the saved policy has \
             {own:?} and its network {net:?}"
        ));
    }
    let (saved, wanted) = (&policy.config().wrapped_inputs, &run.wrapped_inputs);
    if saved != wanted {
        return Err(format!(
            "{what}: the run's settings give wrapped inputs {wanted:?}, but the saved policy has \
             {saved:?}"
        ));
    }
    if let Some(n) = policy.normalizer() {
        check_normalizer(what, n)?;
    }
    Ok(())
}

/// An observation normaliser: a finite non-negative count, finite means,
/// finite non-negative variances, and per-input floors that are either
/// absent or one finite non-negative value per input.
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
    let floors = n.dim_floors();
    if !floors.is_empty() && floors.len() != n.dim() {
        return Err(format!(
            "{what}: the observation normaliser has {} per-input floors for {} inputs",
            floors.len(),
            n.dim()
        ));
    }
    if let Some((j, v)) = floors
        .iter()
        .enumerate()
        .find(|(_, v)| !(v.is_finite() && **v >= 0.0))
    {
        return Err(format!(
            "{what}: the observation normaliser's floor[{j}] is {v}; a floor is finite and              never negative"
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_saved_normaliser_with_wrong_floors_is_refused() {
        let data = ndarray::array![[0.0, 1.0], [1.0, 1.0]];
        let good = ObsNormalizer::from_data(data.view(), 5.0, 0.01)
            .unwrap()
            .with_dim_floors(&[(1, 0.3)])
            .unwrap();
        check_normalizer("p", &good).unwrap();
        let text = serde_json::to_string(&good).unwrap();
        assert!(text.contains(r#""dim_floors":[0.0,0.3]"#), "{text}");
        for (bad, want) in [
            ("[0.3]", "1 per-input floors for 2 inputs"),
            ("[0.0,-0.3]", "floor[1] is -0.3"),
        ] {
            let edited = text.replace("[0.0,0.3]", bad);
            let n: ObsNormalizer = serde_json::from_str(&edited).unwrap();
            let e = check_normalizer("p", &n).unwrap_err();
            assert!(e.contains(want), "{e}");
        }
    }
}
