//! Behaviour cloning on a linear expert: the policy mean approaches the
//! expert's actions.

use ndarray::{Array2, array};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use red_rl::bc::{BcConfig, bc_mse, behavior_clone};
use red_rl::normalize::ObsNormalizer;
use red_rl::policy::{GaussianPolicy, GaussianPolicyConfig};

#[test]
fn behavior_cloning_fits_a_linear_expert() {
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let n = 512;
    // Observations on a scale the normaliser must handle.
    let states = Array2::from_shape_fn((n, 3), |(_, j)| {
        rng.random_range(-1.0..1.0) * [1.0, 10.0, 0.1][j] + [0.0, 5.0, 0.0][j]
    });
    let w = array![[0.5, -0.3], [0.04, 0.02], [2.0, 3.0]];
    let actions = (&states - &array![[0.0, 5.0, 0.0]]).dot(&w);
    let norm = ObsNormalizer::from_data(states.view(), 5.0, 0.1).unwrap();
    let cfg = GaussianPolicyConfig {
        hidden: vec![32, 32],
        ..Default::default()
    };
    let mut policy = GaussianPolicy::new(&cfg, 3, 2, Some(norm), &mut rng).unwrap();
    let log_std_before = policy.net().params_flat();
    let before = bc_mse(&policy, states.view(), actions.view()).unwrap();
    let bc = BcConfig {
        epochs: 60,
        lr: 3e-3,
        ..Default::default()
    };
    let losses = behavior_clone(&mut policy, states.view(), actions.view(), &bc, &mut rng).unwrap();
    let after = bc_mse(&policy, states.view(), actions.view()).unwrap();
    assert_eq!(losses.len(), 60);
    assert!(losses[59] < losses[0]);
    assert!(after < 0.05 * before, "MSE {before} -> {after}");
    // The log-std head's bias received no gradient.
    let theta = policy.net().params_flat();
    let k = theta.len();
    assert_eq!(theta[k - 2..], log_std_before[k - 2..]);
    // Errors name the problem.
    assert!(
        behavior_clone(
            &mut policy,
            states.view(),
            actions.slice(ndarray::s![..10, ..]),
            &bc,
            &mut rng
        )
        .is_err()
    );
}
