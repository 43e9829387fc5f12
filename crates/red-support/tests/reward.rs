//! RED's reward over each estimator: range, calibration rule, determinism,
//! action gradients, save/load, the terminal heuristic and the
//! `RewardModel` interface.

mod common;

use common::supports;
use ndarray::Array2;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use red_core::RewardModel;
use red_support::{
    AutoencoderConfig, Bandwidth, Components, EstimatorConfig, FittedEstimator, KernelPcaConfig,
    RedReward, RedRewardConfig, RndConfig, Sigma1, SupportEstimatorConfig, SupportModel,
    TerminalHeuristic, TerminalHeuristicConfig, no_progress,
};

/// Small networks and few epochs: these tests check plumbing and
/// invariants, not estimation quality (tests/synthetic.rs does that).
fn estimators() -> Vec<EstimatorConfig> {
    vec![
        EstimatorConfig::Rnd(RndConfig {
            target_hidden: vec![32; 2],
            predictor_hidden: vec![32],
            output: 16,
            epochs: 20,
            ensemble: 2,
            ..Default::default()
        }),
        EstimatorConfig::Autoencoder(AutoencoderConfig {
            hidden: 32,
            epochs: 20,
            ..Default::default()
        }),
        EstimatorConfig::KernelPca(KernelPcaConfig::default()),
        EstimatorConfig::KernelPca(KernelPcaConfig {
            components: Components::Count(20),
            tikhonov: Some(1e-3),
            standardize: true,
            ..Default::default()
        }),
    ]
}

fn fit(cfg: &EstimatorConfig, s: &Array2<f64>, a: &Array2<f64>, seed: u64) -> FittedEstimator {
    cfg.fit(
        s.view(),
        a.view(),
        &mut ChaCha8Rng::seed_from_u64(seed),
        &mut no_progress,
    )
    .unwrap()
}

#[test]
fn rewards_are_in_range_and_calibration_meets_its_rule() {
    let support = &supports()[2];
    let (s, a) = support.inside(120, 1);
    let (os, oa) = support.outside(60, 2);
    for cfg in estimators() {
        let model = fit(&cfg, &s, &a, 3);
        let reward =
            RedReward::new(model, &RedRewardConfig::default(), s.view(), a.view()).unwrap();
        let r_exp = reward.reward(s.view(), a.view()).unwrap();
        let r_off = reward.reward(os.view(), oa.view()).unwrap();
        assert!(
            r_exp.iter().chain(&r_off).all(|r| *r > 0.0 && *r <= 1.0),
            "{}: reward outside (0, 1]",
            cfg.kind()
        );
        // The rule: the 0.9 quantile of expert scores gets reward 0.9, so at
        // least 90% of expert rewards are >= 0.9 (up to rounding).
        let share = r_exp.iter().filter(|r| **r >= 0.9 - 1e-12).count() as f64 / 120.0;
        assert!(
            share >= 0.9,
            "{}: share of expert rewards >= 0.9 is {share}",
            cfg.kind()
        );
        assert!(
            share < 0.95,
            "{}: calibration not tight: {share}",
            cfg.kind()
        );
        let q = red_support::stats::quantile(
            &reward.model().score(s.view(), a.view()).unwrap().to_vec(),
            0.9,
        );
        assert!(((-reward.sigma1() * q).exp() - 0.9).abs() < 1e-12);
        println!(
            "{}: sigma1 {:.4e}, mean expert reward {:.3}, mean off-support reward {:.3}",
            cfg.kind(),
            reward.sigma1(),
            r_exp.mean().unwrap(),
            r_off.mean().unwrap()
        );
        // The RewardModel interface gives the same numbers.
        assert_eq!(reward.rewards(os.view(), oa.view()).unwrap(), r_off);
        assert!(!reward.is_adaptive());
    }
}

#[test]
fn same_seed_same_scores_different_seed_different_scores() {
    let support = &supports()[0];
    let (s, a) = support.inside(100, 4);
    let (qs, qa) = support.outside(30, 5);
    for cfg in estimators() {
        let m1 = fit(&cfg, &s, &a, 9);
        let m2 = fit(&cfg, &s, &a, 9);
        let s1 = m1.score(qs.view(), qa.view()).unwrap();
        assert_eq!(
            s1,
            m2.score(qs.view(), qa.view()).unwrap(),
            "{}",
            cfg.kind()
        );
        assert_eq!(m1, m2);
        if cfg.kind() != "kpca" {
            let m3 = fit(&cfg, &s, &a, 10);
            assert_ne!(
                s1,
                m3.score(qs.view(), qa.view()).unwrap(),
                "{}",
                cfg.kind()
            );
        }
    }
}

#[test]
fn reward_action_gradient_matches_finite_differences() {
    let support = &supports()[1];
    let (s, a) = support.inside(100, 6);
    let (qs, qa) = support.inside(8, 7);
    let qa = qa + 0.05;
    for cfg in estimators() {
        // Networks are f32 and leaky relu has kinks; use a smooth activation
        // for the check (see the unit tests) and a step suited to f32.
        let cfg = match cfg {
            EstimatorConfig::Rnd(c) => EstimatorConfig::Rnd(RndConfig {
                activation: red_nets::Activation::Tanh,
                ..c
            }),
            EstimatorConfig::Autoencoder(c) => EstimatorConfig::Autoencoder(AutoencoderConfig {
                activation: red_nets::Activation::Tanh,
                ..c
            }),
            other => other,
        };
        let eps = if cfg.kind() == "kpca" { 1e-6 } else { 1e-3 };
        let tol = if cfg.kind() == "kpca" { 1e-5 } else { 3e-2 };
        let model = fit(&cfg, &s, &a, 8);
        let reward =
            RedReward::new(model, &RedRewardConfig::default(), s.view(), a.view()).unwrap();
        let (r, g) = reward.reward_grad_action(qs.view(), qa.view()).unwrap();
        assert_eq!(g.dim(), (8, 2));
        let plain = reward.reward(qs.view(), qa.view()).unwrap();
        for (x, y) in r.iter().zip(&plain) {
            assert!((x - y).abs() < 1e-6);
        }
        let scale = g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for i in 0..8 {
            for j in 0..2 {
                let mut ap = qa.clone();
                ap[[i, j]] += eps;
                let mut am = qa.clone();
                am[[i, j]] -= eps;
                let fd = (reward.reward(qs.view(), ap.view()).unwrap()[i]
                    - reward.reward(qs.view(), am.view()).unwrap()[i])
                    / (2.0 * eps);
                assert!(
                    (fd - g[[i, j]]).abs() <= tol * scale.max(1e-8),
                    "{}: row {i} dim {j}: fd {fd} vs analytic {} (scale {scale})",
                    cfg.kind(),
                    g[[i, j]]
                );
            }
        }
    }
}

#[test]
fn save_load_round_trip_gives_identical_scores() {
    let support = &supports()[2];
    let (s, a) = support.inside(80, 11);
    let (qs, qa) = support.outside(40, 12);
    let dir = tempfile::tempdir().unwrap();
    for cfg in estimators() {
        let model = fit(&cfg, &s, &a, 13);
        let path = dir.path().join(format!("{}.json", cfg.kind()));
        model.save(&path).unwrap();
        let back = FittedEstimator::load(&path).unwrap();
        assert_eq!(back.kind(), model.kind());
        assert_eq!(
            back.score(qs.view(), qa.view()).unwrap(),
            model.score(qs.view(), qa.view()).unwrap(),
            "{}",
            cfg.kind()
        );
        assert_eq!(
            back.score_grad_action(qs.view(), qa.view()).unwrap(),
            model.score_grad_action(qs.view(), qa.view()).unwrap()
        );
    }
    std::fs::write(
        dir.path().join("bad.json"),
        r#"{"format": "other", "version": 1}"#,
    )
    .unwrap();
    let e = FittedEstimator::load(&dir.path().join("bad.json")).unwrap_err();
    assert!(e.to_string().contains("bad.json"), "{e}");
}

#[test]
fn scoring_rejects_bad_batches() {
    let support = &supports()[0];
    let (s, a) = support.inside(50, 14);
    let model = fit(&estimators()[2], &s, &a, 0);
    assert_eq!((model.obs_dim(), model.act_dim()), (1, 1));
    let e = model
        .score(Array2::zeros((3, 2)).view(), Array2::zeros((3, 1)).view())
        .unwrap_err();
    assert!(e.to_string().contains("states"), "{e}");
    let mut bad = Array2::zeros((3, 1));
    bad[[0, 0]] = f64::INFINITY;
    assert!(
        model
            .score(Array2::zeros((3, 1)).view(), bad.view())
            .is_err()
    );
    // Through RewardModel the error keeps its kind.
    let reward = RedReward::with_sigma1(model, 10.0).unwrap();
    assert!(matches!(
        reward.rewards(Array2::zeros((3, 2)).view(), Array2::zeros((3, 1)).view()),
        Err(red_core::Error::ShapeMismatch { .. })
    ));
    assert!(RedReward::with_sigma1(reward.into_model(), -1.0).is_err());
}

#[test]
fn calibration_refuses_all_zero_expert_scores() {
    // Kernel PCA with every component scores its own training pairs at 0:
    // no quantile of them can set sigma1.
    let support = &supports()[0];
    let (s, a) = support.inside(40, 15);
    let cfg = KernelPcaConfig {
        bandwidth: Bandwidth::Fixed(0.05),
        components: Components::All,
        ..Default::default()
    };
    let model = cfg
        .fit(
            s.view(),
            a.view(),
            &mut ChaCha8Rng::seed_from_u64(0),
            &mut no_progress,
        )
        .unwrap();
    let sc = model.score(s.view(), a.view()).unwrap();
    assert!(sc.iter().all(|v| *v < 1e-6), "{sc:?}");
    // Rounding leaves some of those scores a hair above 0; exact zeros are
    // refused with a message that says what to do.
    let e = red_support::calibrate_sigma1(&[0.0; 10], 0.9, 0.9).unwrap_err();
    assert!(e.to_string().contains("give a fixed sigma1"), "{e}");
    let bad = RedRewardConfig {
        sigma1: Sigma1::Calibrated {
            quantile: 0.9,
            reward: 1.0,
        },
    };
    assert!(bad.validate().unwrap_err().to_string().contains("sigma1"));
}

#[test]
fn terminal_heuristic_penalises_endings_off_the_support() {
    let support = &supports()[2];
    let (s, a) = support.inside(120, 16);
    let (os, oa) = support.outside(20, 17);
    let model = fit(&estimators()[2], &s, &a, 0);
    let reward = RedReward::new(model, &RedRewardConfig::default(), s.view(), a.view()).unwrap();
    let h = TerminalHeuristic::new(
        &TerminalHeuristicConfig::default(),
        &reward,
        s.view(),
        a.view(),
    )
    .unwrap();
    let rbar = h.expert_mean_reward();
    assert!(rbar > 0.85 && rbar <= 1.0, "mean expert reward {rbar}");
    // Expert pairs end on the support: no penalty. Off-support pairs far
    // away get the penalty -sigma2 * rbar.
    for r in reward.reward(s.view(), a.view()).unwrap() {
        assert_eq!(h.penalty(r), 0.0);
    }
    let r_off = reward.reward(os.view(), oa.view()).unwrap();
    let penalised = r_off
        .iter()
        .filter(|r| h.penalty(**r) == -10.0 * rbar)
        .count();
    assert!(
        penalised >= 15,
        "only {penalised} of 20 off-support endings penalised"
    );
}

#[test]
fn a_reward_on_states_only_ignores_the_action_and_survives_save_and_load() {
    use red_core::DifferentiableReward;
    let support = &supports()[2];
    let (s, a) = support.inside(80, 3);
    let zeros = Array2::zeros(a.raw_dim());
    let model = fit(&estimators()[0], &s, &zeros, 4);
    let full = RedReward::with_sigma1(model, 5.0).unwrap();
    assert!(!full.states_only());
    let on_states = full.clone().on_states_only(true);
    let at_zero = full.rewards(s.view(), zeros.view()).unwrap();
    // Any action gives the reward of the zero action, with no gradient.
    let (r, g) = on_states.reward_and_grad(s.view(), a.view()).unwrap();
    assert_eq!(r, at_zero);
    assert!(g.iter().all(|v| *v == 0.0));
    assert_eq!(on_states.rewards(s.view(), a.view()).unwrap(), at_zero);
    // The full reward does see the action.
    assert_ne!(full.rewards(s.view(), a.view()).unwrap(), at_zero);
    // The flag is saved; a file written before it existed reads as off.
    let text = serde_json::to_string(&on_states).unwrap();
    let back: RedReward<FittedEstimator> = serde_json::from_str(&text).unwrap();
    assert_eq!(back, on_states);
    let old: RedReward<FittedEstimator> =
        serde_json::from_str(&serde_json::to_string(&full).unwrap()).unwrap();
    assert!(!old.states_only());
    assert!(
        !serde_json::to_string(&full)
            .unwrap()
            .contains("states_only")
    );
}

#[test]
fn a_reward_moved_onto_another_model_keeps_sigma1_and_the_state_only_flag() {
    let support = &supports()[2];
    let (s, a) = support.inside(60, 5);
    let model = fit(&estimators()[0], &s, &a, 6);
    let FittedEstimator::Rnd(rnd) = model else {
        panic!("estimators()[0] is an RND");
    };
    for states_only in [false, true] {
        let plain = RedReward::with_sigma1(rnd.clone(), 3.5)
            .unwrap()
            .on_states_only(states_only);
        let wrapped = plain.clone().map_model(FittedEstimator::Rnd);
        assert_eq!(wrapped.sigma1(), 3.5);
        assert_eq!(wrapped.states_only(), states_only);
        assert_eq!(
            wrapped.reward(s.view(), a.view()).unwrap(),
            plain.reward(s.view(), a.view()).unwrap()
        );
        let back = wrapped.with_model(rnd.clone());
        assert_eq!(back, plain);
    }
    // A file whose sigma1 was edited to a bad value is refused on reading.
    let plain = RedReward::with_sigma1(rnd, 3.5).unwrap();
    let mut json = serde_json::to_value(&plain).unwrap();
    for bad in [0.0, -1.0] {
        json["sigma1"] = serde_json::json!(bad);
        let e = serde_json::from_value::<RedReward<red_support::Rnd>>(json.clone())
            .err()
            .unwrap();
        assert!(e.to_string().contains("sigma1"), "{e}");
    }
}
