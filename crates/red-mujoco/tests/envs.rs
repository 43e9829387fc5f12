//! Properties of the five environments that do not need Gymnasium: the env
//! checker, spaces, seeding, reset noise, reward bookkeeping, errors and
//! configs.

use red_core::check::check_env;
use red_core::{Env, Error as CoreError};
use red_mujoco::{
    Ant, AntConfig, EnvId, HalfCheetah, HalfCheetahConfig, Hopper, HopperConfig, MujocoEnv,
    Reacher, ReacherConfig, Walker2d, Walker2dConfig, make,
};

/// (env, observation length, action length, info terms summing to the
/// reward).
fn cases() -> Vec<(EnvId, usize, usize, &'static [&'static str])> {
    vec![
        (
            EnvId::Hopper,
            11,
            3,
            &["reward_forward", "reward_ctrl", "reward_survive"],
        ),
        (
            EnvId::HalfCheetah,
            17,
            6,
            &["reward_forward", "reward_ctrl"],
        ),
        (
            EnvId::Walker2d,
            17,
            6,
            &["reward_forward", "reward_ctrl", "reward_survive"],
        ),
        (
            EnvId::Ant,
            27,
            8,
            &[
                "reward_forward",
                "reward_ctrl",
                "reward_contact",
                "reward_survive",
            ],
        ),
        (EnvId::Reacher, 10, 2, &["reward_dist", "reward_ctrl"]),
    ]
}

#[test]
fn every_env_passes_the_env_checker() {
    for id in EnvId::ALL {
        let mut env = id.make().unwrap();
        let report = check_env(&mut env, 3, 300).unwrap_or_else(|e| panic!("{id}: {e}"));
        assert_eq!(report.steps, 300);
        eprintln!("{id}: {report}");
    }
    let mut ant = red_core::TimeLimit::new(
        Ant::new(AntConfig {
            include_cfrc_ext_in_observation: true,
            ..AntConfig::default()
        })
        .unwrap(),
        1000,
    )
    .unwrap();
    check_env(&mut ant, 3, 100).unwrap();
}

#[test]
fn spaces_and_rewards_follow_gymnasium() {
    for (id, obs_dim, act_dim, terms) in cases() {
        let mut env = id.make().unwrap();
        assert_eq!(env.observation_space().dim(), obs_dim, "{id}");
        assert_eq!(env.action_space().dim(), act_dim, "{id}");
        let (obs, _) = env.reset(Some(1)).unwrap();
        assert_eq!(obs.len(), obs_dim, "{id}");
        let action: Vec<f64> = (0..act_dim).map(|i| 0.9 - 0.3 * i as f64).collect();
        let step = env.step(&action).unwrap();
        let sum: f64 = terms.iter().map(|k| step.info.get(k).unwrap()).sum();
        assert!((step.reward - sum).abs() < 1e-12, "{id}: {step:?}");
        // The control cost uses the raw action, bounds or not.
        let sq: f64 = action.iter().map(|a| a * a).sum();
        let weight = match id {
            EnvId::Hopper | EnvId::Walker2d => 1e-3,
            EnvId::HalfCheetah => 0.1,
            EnvId::Ant => 0.5,
            EnvId::Reacher => 1.0,
        };
        let ctrl = step.info.get("reward_ctrl").unwrap();
        assert!((ctrl + weight * sq).abs() < 1e-12, "{id}: {ctrl}");
    }
}

#[test]
fn seeds_reproduce_and_streams_continue() {
    for id in EnvId::ALL {
        let mut env = id.make().unwrap();
        let (a, _) = env.reset(Some(5)).unwrap();
        let (b, _) = env.reset(None).unwrap();
        let (c, _) = env.reset(Some(5)).unwrap();
        let (d, _) = env.reset(Some(6)).unwrap();
        assert_eq!(a, c, "{id}: same seed, same start");
        assert_ne!(a, b, "{id}: reset(None) continues the stream");
        assert_ne!(a, d, "{id}: another seed, another start");
        // A fresh environment, never seeded, is reproducible too.
        let (e, _) = id.make().unwrap().reset(None).unwrap();
        let (f, _) = id.make().unwrap().reset(None).unwrap();
        assert_eq!(e, f, "{id}");
    }
}

fn mean_std(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    let v = x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (n - 1.0);
    (m, v.sqrt())
}

#[test]
fn reset_noise_has_gymnasium_distributions() {
    let resets = 300;
    // Hopper: uniform on [-0.005, 0.005) for positions and velocities.
    let mut hopper = Hopper::new(HopperConfig::default()).unwrap();
    let init = hopper.simulation().init_qpos().to_vec();
    let mut noise = Vec::new();
    for k in 0..resets {
        hopper.reset(Some(k)).unwrap();
        let sim = hopper.simulation();
        noise.extend(sim.qpos().iter().zip(&init).map(|(q, i)| q - i));
        noise.extend_from_slice(sim.qvel());
    }
    assert!(noise.iter().all(|n| (-0.005..0.005).contains(n)));
    let (m, s) = mean_std(&noise);
    let uniform_std = 0.005 / 3f64.sqrt();
    assert!(m.abs() < 2e-4 && (s - uniform_std).abs() < 1e-4, "{m} {s}");

    // HalfCheetah: uniform positions, normal velocities with std 0.1.
    let mut cheetah = HalfCheetah::new(HalfCheetahConfig::default()).unwrap();
    let mut vel = Vec::new();
    for k in 0..resets {
        cheetah.reset(Some(k)).unwrap();
        vel.extend_from_slice(cheetah.simulation().qvel());
    }
    let (m, s) = mean_std(&vel);
    assert!(m.abs() < 0.01 && (s - 0.1).abs() < 0.005, "{m} {s}");
    assert!(
        vel.iter().any(|v| v.abs() > 0.2),
        "normal tails beyond 2 sigma"
    );

    // Reacher: target inside the disc of radius 0.2, target at rest.
    let mut reacher = Reacher::new(ReacherConfig::default()).unwrap();
    for k in 0..resets {
        reacher.reset(Some(k)).unwrap();
        let sim = reacher.simulation();
        let (q, v) = (sim.qpos(), sim.qvel());
        assert!(q[2].hypot(q[3]) < 0.2);
        assert_eq!(&v[2..], &[0.0, 0.0]);
        assert!(q[..2].iter().all(|a| a.abs() < 0.1));
        assert!(v[..2].iter().all(|a| a.abs() < 0.005));
    }
}

#[test]
fn stepping_rules() {
    let mut env = Hopper::new(HopperConfig::default()).unwrap();
    assert!(matches!(
        env.step(&[0.0; 3]),
        Err(CoreError::NeedsReset { .. })
    ));
    env.reset(Some(0)).unwrap();
    assert!(matches!(
        env.step(&[0.0; 2]),
        Err(CoreError::ShapeMismatch { .. })
    ));
    assert!(matches!(
        env.step(&[0.0, f64::INFINITY, 0.0]),
        Err(CoreError::NonFinite { .. })
    ));
    // Out-of-bounds actions are applied (MuJoCo clamps the control).
    env.step(&[3.0, -3.0, 3.0]).unwrap();

    // Falling over terminates; stepping afterwards needs a reset.
    let mut qpos = env.simulation().qpos().to_vec();
    qpos[2] = 0.5; // torso angle outside (-0.2, 0.2)
    let qvel = vec![0.0; 6];
    env.set_state(&qpos, &qvel).unwrap();
    assert!(!env.is_healthy());
    let step = env.step(&[0.0; 3]).unwrap();
    assert!(step.terminated && !step.truncated);
    assert_eq!(step.info.get("reward_survive"), Some(0.0));
    assert!(matches!(
        env.step(&[0.0; 3]),
        Err(CoreError::NeedsReset { .. })
    ));

    // Without termination the same state goes on, unrewarded.
    let mut env = Walker2d::new(Walker2dConfig {
        terminate_when_unhealthy: false,
        ..Walker2dConfig::default()
    })
    .unwrap();
    env.reset(Some(0)).unwrap();
    let mut qpos = env.simulation().qpos().to_vec();
    qpos[1] = 0.5; // torso below 0.8
    env.set_state(&qpos, &[0.0; 9]).unwrap();
    let step = env.step(&[0.0; 6]).unwrap();
    assert!(!step.terminated);
    assert_eq!(step.info.get("reward_survive"), Some(0.0));
    env.step(&[0.0; 6]).unwrap();
}

#[test]
fn time_limits_truncate() {
    let mut env = make("Reacher-v5").unwrap();
    env.reset(Some(0)).unwrap();
    for t in 1..=50 {
        let step = env.step(&[0.1, -0.1]).unwrap();
        assert_eq!(step.truncated, t == 50);
        assert!(!step.terminated);
    }
    let mut env = make("HalfCheetah").unwrap();
    assert_eq!(env.max_steps(), 1000);
    env.reset(Some(0)).unwrap();
    let last = (0..1000).map(|_| env.step(&[0.0; 6]).unwrap()).last();
    assert!(last.unwrap().truncated);
}

#[test]
fn ant_contact_forces_in_observation_and_cost() {
    let mut env = Ant::new(AntConfig {
        include_cfrc_ext_in_observation: true,
        ..AntConfig::default()
    })
    .unwrap();
    let (obs, _) = env.reset(Some(0)).unwrap();
    assert_eq!(obs.len(), 105);
    // Right after a reset the contact forces are zeros, as in Gymnasium.
    assert!(obs[27..].iter().all(|f| *f == 0.0));
    let mut touched = false;
    for _ in 0..20 {
        let step = env.step(&[0.5; 8]).unwrap();
        let forces = &step.observation[27..];
        assert!(forces.iter().all(|f| (-1.0..=1.0).contains(f)));
        touched |= forces.iter().any(|f| *f != 0.0);
        let cost = -step.info.get("reward_contact").unwrap();
        assert!((cost - env.contact_cost()).abs() < 1e-15);
    }
    assert!(touched, "the legs touch the floor");
}

#[test]
fn configs_round_trip_and_validate() {
    let hopper = HopperConfig::default();
    let json = serde_json::to_string(&hopper).unwrap();
    assert!(json.contains(r#""healthy_z_range":[0.7,"inf"]"#), "{json}");
    let back: HopperConfig = serde_json::from_str(&json).unwrap();
    assert_eq!(back, hopper);
    let partial: AntConfig =
        serde_json::from_str(r#"{"include_cfrc_ext_in_observation": true}"#).unwrap();
    assert!(partial.include_cfrc_ext_in_observation);
    assert_eq!(partial.ctrl_cost_weight, 0.5);
    assert!(serde_json::from_str::<ReacherConfig>(r#"{"reward_weight": 1}"#).is_err());
    assert!(serde_json::from_str::<HopperConfig>(r#"{"healthy_z_range": [0, "big"]}"#).is_err());

    let bad = HopperConfig {
        healthy_angle_range: [0.2, -0.2],
        ..HopperConfig::default()
    };
    let err = Hopper::new(bad).unwrap_err();
    assert!(err.to_string().contains("healthy_angle_range"), "{err}");
    let err = HalfCheetah::new(HalfCheetahConfig {
        reset_noise_scale: -1.0,
        ..HalfCheetahConfig::default()
    })
    .unwrap_err();
    assert!(err.to_string().contains("reset_noise_scale"), "{err}");
    let err = Ant::new(AntConfig {
        main_body: 99,
        ..AntConfig::default()
    })
    .unwrap_err();
    assert!(err.to_string().contains("main_body"), "{err}");
    let err = Reacher::new(ReacherConfig {
        xml_file: "no_such_model.xml".into(),
        ..ReacherConfig::default()
    })
    .unwrap_err();
    assert!(err.to_string().contains("scripts/setup-mujoco.sh"), "{err}");
}
