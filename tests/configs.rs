//! Every serde config of the workspace rejects unknown fields, and its
//! `validate()` rejects nonsense numbers with a message naming the field.
//! For each config: the default round-trips and validates; an extra field
//! is refused by name; each listed bad value parses but is refused by
//! `validate()` with the field's name in the message.

use serde::Serialize;
use serde::de::DeserializeOwned;
use serde_json::{Value, json};

/// Checks one config type. `bad` lists `(json pointer, bad value, field
/// name the error must contain)`.
fn check<T, E>(name: &str, validate: impl Fn(&T) -> Result<(), E>, bad: &[(&str, Value, &str)])
where
    T: Serialize + DeserializeOwned + Default,
    E: std::fmt::Display,
{
    check_from(name, &T::default(), validate, bad);
}

/// As [`check`], from `base` instead of the default (a config whose
/// default needs a file, or one per task).
fn check_from<T, E>(
    name: &str,
    base: &T,
    validate: impl Fn(&T) -> Result<(), E>,
    bad: &[(&str, Value, &str)],
) where
    T: Serialize + DeserializeOwned,
    E: std::fmt::Display,
{
    let default = serde_json::to_value(base).expect("serialise");
    let back: T = serde_json::from_value(default.clone()).expect("the default parses");
    if let Err(e) = validate(&back) {
        panic!("{name}: the default does not validate: {e}");
    }

    let mut extra = default.clone();
    extra
        .as_object_mut()
        .unwrap_or_else(|| panic!("{name}: not a JSON object"))
        .insert("no_such_setting".into(), json!(1));
    let err = serde_json::from_value::<T>(extra)
        .err()
        .unwrap_or_else(|| panic!("{name}: an unknown field was accepted"));
    assert!(
        err.to_string().contains("no_such_setting"),
        "{name}: the error does not name the unknown field: {err}"
    );

    assert!(!bad.is_empty(), "{name}: no bad values listed");
    for (pointer, value, field) in bad {
        let mut v = default.clone();
        *v.pointer_mut(pointer)
            .unwrap_or_else(|| panic!("{name}: no field at {pointer}")) = value.clone();
        let parsed: T = serde_json::from_value(v)
            .unwrap_or_else(|e| panic!("{name}: {pointer} = {value} does not parse: {e}"));
        let err = validate(&parsed)
            .err()
            .unwrap_or_else(|| panic!("{name}: {pointer} = {value} was accepted"));
        assert!(
            err.to_string().contains(field),
            "{name}: {pointer} = {value}: the error does not name `{field}`: {err}"
        );
    }
}

#[test]
fn network_and_optimiser_configs() {
    check::<red_nets::MlpConfig, _>(
        "MlpConfig",
        |c| c.validate(),
        &[
            ("/input", json!(0), "input"),
            ("/output", json!(0), "output"),
        ],
    );
    check::<red_nets::AdamConfig, _>(
        "AdamConfig",
        |c| c.validate(),
        &[
            ("/lr", json!(-1e-3), "lr"),
            ("/beta1", json!(1.5), "beta1"),
            ("/beta2", json!(-0.1), "beta2"),
            ("/eps", json!(0.0), "eps"),
            ("/weight_decay", json!(-1.0), "weight_decay"),
        ],
    );
    check::<red_nets::SgdConfig, _>(
        "SgdConfig",
        |c| c.validate(),
        &[
            ("/lr", json!(0.0), "lr"),
            ("/momentum", json!(1.5), "momentum"),
        ],
    );
}

#[test]
fn learner_configs() {
    use red_rl::{bc, dqn, gae, gail, gmmil, policy, svg, trpo};
    check::<dqn::DqnConfig, _>(
        "DqnConfig",
        |c| c.validate(),
        &[
            ("/learning_rate", json!(-1e-4), "learning_rate"),
            ("/gamma", json!(1.5), "gamma"),
            ("/batch_size", json!(0), "batch_size"),
            ("/buffer_size", json!(0), "buffer_size"),
            ("/start_epsilon", json!(2.0), "start_epsilon"),
        ],
    );
    check::<trpo::TrpoConfig, _>(
        "TrpoConfig",
        |c| c.validate(),
        &[
            ("/max_kl", json!(-0.01), "max_kl"),
            ("/steps_per_batch", json!(0), "steps_per_batch"),
            ("/value_lr", json!(-1.0), "value_lr"),
            ("/value_batch_size", json!(0), "value_batch_size"),
            ("/cg_damping", json!(-0.1), "cg_damping"),
            ("/gae/gamma", json!(1.5), "gamma"),
        ],
    );
    check::<gae::GaeConfig, _>(
        "GaeConfig",
        |c| c.validate(),
        &[
            ("/gamma", json!(-0.5), "gamma"),
            ("/lambda", json!(2.0), "lambda"),
        ],
    );
    check::<bc::BcConfig, _>(
        "BcConfig",
        |c| c.validate(),
        &[
            ("/lr", json!(-3e-4), "lr"),
            ("/batch_size", json!(0), "batch_size"),
        ],
    );
    check::<gail::GailConfig, _>(
        "GailConfig",
        |c| c.validate(),
        &[
            ("/learning_rate", json!(0.0), "learning_rate"),
            ("/epochs", json!(0), "epochs"),
        ],
    );
    check::<gmmil::GmmilConfig, _>(
        "GmmilConfig",
        |c| c.validate(),
        &[("/median_sample", json!(0), "median_sample")],
    );
    check::<policy::GaussianPolicyConfig, _>(
        "GaussianPolicyConfig",
        |c| c.validate(),
        &[("/init_log_std", json!(100.0), "init_log_std")],
    );
    check::<red_rl::sac::SacConfig, _>(
        "SacConfig",
        |c| c.validate(),
        &[
            ("/gamma", json!(1.0), "gamma"),
            ("/tau", json!(0.0), "tau"),
            ("/actor_lr", json!(-3e-4), "actor_lr"),
            ("/buffer_size", json!(0), "buffer_size"),
            ("/init_alpha", json!(0.0), "init_alpha"),
            ("/hidden", json!([0]), "hidden"),
        ],
    );
    check::<svg::SvgConfig, _>(
        "SvgConfig",
        |c| c.validate(),
        &[
            ("/gamma", json!(1.0), "gamma"),
            ("/policy_lr", json!(-1e-4), "policy_lr"),
            ("/batch_size", json!(0), "batch_size"),
            ("/iw_clip", json!(0.5), "iw_clip"),
            ("/target_tau", json!(0.0), "target_tau"),
        ],
    );
}

#[test]
fn support_and_reward_configs() {
    use red_support::{
        AutoencoderConfig, KernelPcaConfig, RedRewardConfig, RndConfig, TerminalHeuristicConfig,
    };
    check::<RndConfig, _>(
        "RndConfig",
        |c| c.validate(),
        &[
            ("/epochs", json!(0), "epochs"),
            ("/batch_size", json!(0), "batch_size"),
            ("/output", json!(0), "output"),
            ("/ensemble", json!(0), "ensemble"),
            ("/adam/lr", json!(-1.0), "lr"),
        ],
    );
    check::<AutoencoderConfig, _>(
        "AutoencoderConfig",
        |c| c.validate(),
        &[
            ("/epochs", json!(0), "epochs"),
            ("/batch_size", json!(0), "batch_size"),
        ],
    );
    check::<KernelPcaConfig, _>(
        "KernelPcaConfig",
        |c| c.validate(),
        &[("/tikhonov", json!(-1.0), "tikhonov")],
    );
    check::<RedRewardConfig, _>(
        "RedRewardConfig",
        |c| c.validate(),
        &[("/sigma1", json!({"fixed": -1.0}), "sigma1")],
    );
    check::<TerminalHeuristicConfig, _>(
        "TerminalHeuristicConfig",
        |c| c.validate(),
        &[
            ("/sigma2", json!(-1.0), "sigma2"),
            ("/sigma3", json!(-1.0), "sigma3"),
        ],
    );
}

#[test]
fn environment_configs() {
    check::<red_drive::DriveConfig, _>(
        "DriveConfig",
        |c| c.validate(),
        &[
            ("/road_length", json!(-5.0), "road_length"),
            ("/lane_width", json!(0.0), "lane_width"),
            ("/lidar_range", json!(-1.0), "lidar_range"),
            ("/time_limit", json!(0), "time_limit"),
        ],
    );
    check::<red_drive::HumanConfig, _>(
        "HumanConfig",
        |c| c.validate(),
        &[
            ("/reaction_min", json!(-0.1), "reaction_min"),
            ("/reaction_max", json!(-1.0), "reaction_max"),
            ("/view_distance", json!(0.0), "view_distance"),
            ("/cruise_min_kmh", json!(0.0), "cruise_min_kmh"),
        ],
    );
    use red_mujoco::{AntConfig, HalfCheetahConfig, HopperConfig, ReacherConfig, Walker2dConfig};
    check::<HopperConfig, _>(
        "HopperConfig",
        |c| c.validate(),
        &[
            ("/frame_skip", json!(0), "frame_skip"),
            ("/reset_noise_scale", json!(-1.0), "reset_noise_scale"),
        ],
    );
    check::<Walker2dConfig, _>(
        "Walker2dConfig",
        |c| c.validate(),
        &[("/frame_skip", json!(0), "frame_skip")],
    );
    check::<HalfCheetahConfig, _>(
        "HalfCheetahConfig",
        |c| c.validate(),
        &[("/frame_skip", json!(0), "frame_skip")],
    );
    check::<AntConfig, _>(
        "AntConfig",
        |c| c.validate(),
        &[("/frame_skip", json!(0), "frame_skip")],
    );
    check::<ReacherConfig, _>(
        "ReacherConfig",
        |c| c.validate(),
        &[("/frame_skip", json!(0), "frame_skip")],
    );
}

#[test]
fn experiment_configs() {
    check::<red_experiments::drive::DriveTrainConfig, _>(
        "DriveTrainConfig",
        |c| c.validate(),
        &[
            ("/sigma1/quantile", json!(0.0), "sigma1.quantile"),
            ("/sigma1/reward", json!(1.0), "sigma1.reward"),
            ("/sigma1/folds", json!(1), "sigma1.folds"),
            ("/reward_update_pairs", json!(0), "reward_update_pairs"),
            ("/svg/gamma", json!(1.5), "gamma"),
            ("/policy/hidden", json!([0]), "train.policy"),
            ("/select_episodes", json!(0), "select_episodes"),
            ("/demo_starts", json!(-0.1), "demo_starts"),
        ],
    );
    // On the demonstration's road alone (the paper's setting), a share of
    // other-road episodes has no roads to go to.
    let one_road = red_experiments::drive::DriveTrainConfig {
        train_roads: 0,
        ..Default::default()
    };
    check_from(
        "DriveTrainConfig on one road",
        &one_road,
        |c: &red_experiments::drive::DriveTrainConfig| c.validate(),
        &[("/demo_road_share", json!(0.5), "needs train_roads > 0")],
    );
    // With other roads, a share in [0, 1] is accepted and one outside it
    // is refused by the range check.
    let roads = red_experiments::drive::DriveTrainConfig {
        train_roads: 50,
        demo_road_share: 0.5,
        ..Default::default()
    };
    check_from(
        "DriveTrainConfig with train_roads",
        &roads,
        |c: &red_experiments::drive::DriveTrainConfig| c.validate(),
        &[
            ("/demo_road_share", json!(1.5), "must lie in [0, 1]"),
            ("/demo_road_share", json!(-0.5), "must lie in [0, 1]"),
            (
                "/demo_starts",
                json!(0.5),
                "cannot be combined with train_roads",
            ),
        ],
    );
    check::<red_experiments::toy::ToyConfig, _>(
        "ToyConfig",
        |c| c.validate(),
        &[
            ("/n", json!([0]), "n"),
            ("/methods", json!([]), "methods"),
            ("/seeds", json!(0), "seeds"),
            ("/steps", json!(0), "steps"),
            ("/eval_interval", json!(0), "eval_interval"),
            ("/gamma", json!(1.5), "gamma"),
            ("/rnd_ensemble", json!(0), "rnd_ensemble"),
            ("/train_frequency", json!(0), "train_frequency"),
            ("/epochs", json!(0), "epochs"),
        ],
    );
    // The run config has no Default (it needs a demo and a road): its
    // fields are checked through a made one.
    let mut run =
        red_experiments::drive::DriveRunConfig::new("demo.json", red_drive::DriveConfig::default());
    run.validate().expect("the defaults validate");
    run.eval_runs = 0;
    assert!(
        run.validate()
            .unwrap_err()
            .to_string()
            .contains("eval_runs")
    );
    run.eval_runs = 5;
    run.methods = vec!["dagger".into()];
    assert!(run.validate().unwrap_err().to_string().contains("dagger"));
    let mut v = serde_json::to_value(&run).expect("serialise");
    v.as_object_mut()
        .expect("object")
        .insert("no_such_setting".into(), json!(1));
    let err = serde_json::from_value::<red_experiments::drive::DriveRunConfig>(v).unwrap_err();
    assert!(err.to_string().contains("no_such_setting"), "{err}");
}

#[test]
fn mujoco_experiment_configs() {
    use red_experiments::imitation::Method;
    use red_experiments::mujoco::run::RunConfig;
    use red_mujoco::EnvId;
    // A run's defaults depend on its task and method, and every method but
    // `expert` needs a demonstration file: each pair is checked.
    for env in EnvId::ALL {
        for method in [Method::Expert].into_iter().chain(Method::TABLE) {
            let mut base = RunConfig::for_task(env, method);
            if method.needs_demo() {
                base.demo = Some("demos.json".into());
            }
            let name = format!("RunConfig {} {}", env.name(), method.name());
            let mut bad = vec![
                ("/trpo/max_kl", json!(-0.01), "trpo"),
                ("/rnd/epochs", json!(0), "rnd"),
                ("/autoencoder/epochs", json!(0), "autoencoder"),
                ("/gail/epochs", json!(0), "gail"),
                ("/gmmil/median_sample", json!(0), "gmmil"),
                ("/bc/batch_size", json!(0), "bc"),
                ("/sigma1", json!({"fixed": -1.0}), "sigma1"),
                ("/checkpoint_every", json!(0), "checkpoint_every"),
                ("/eval_episodes", json!(0), "eval_episodes"),
                ("/best_window", json!(0), "best_window"),
                (
                    if method == Method::Bc {
                        "/bc_epochs"
                    } else {
                        "/steps"
                    },
                    json!(0),
                    if method == Method::Bc {
                        "bc_epochs"
                    } else {
                        "steps"
                    },
                ),
            ];
            if method.needs_demo() {
                bad.push(("/demo", Value::Null, "demo"));
            } else {
                bad.push(("/demo_trajectories", json!(0), "demo_trajectories"));
            }
            check_from(&name, &base, |c: &RunConfig| c.validate(), &bad);
        }
    }
    check::<red_experiments::mujoco::table::TableConfig, _>(
        "TableConfig",
        |c| c.validate(),
        &[
            ("/methods", json!(["red", "expert"]), "methods"),
            ("/seeds", json!([]), "seeds"),
            ("/envs", json!([]), "envs"),
            ("/steps", json!(0), "steps"),
            ("/checkpoint_every", json!(0), "checkpoint_every"),
            ("/eval_episodes", json!(0), "eval_episodes"),
            ("/jobs", json!(0), "jobs"),
        ],
    );
}

/// The one method vocabulary of the experiments
/// (`red_experiments::imitation`): each method is written by its name in
/// configs, read back by it (and from the command line, case-insensitive),
/// and an unknown name is refused naming it.
#[test]
fn imitation_methods() {
    use red_experiments::imitation::Method;
    let all: Vec<Method> = [Method::Expert].into_iter().chain(Method::TABLE).collect();
    assert_eq!(all.len(), 6);
    for m in all {
        let v = serde_json::to_value(m).expect("serialise");
        assert_eq!(v, json!(m.name()), "{m:?}");
        let back: Method = serde_json::from_value(v).expect("parses");
        assert_eq!(back, m);
        assert_eq!(m.name().to_uppercase().parse::<Method>(), Ok(m));
        assert_eq!(m.needs_demo(), m != Method::Expert);
        assert_eq!(
            m.imitates_by_reward(),
            !matches!(m, Method::Expert | Method::Bc)
        );
    }
    let err = serde_json::from_value::<Method>(json!("dagger")).unwrap_err();
    assert!(err.to_string().contains("dagger"), "{err}");
    let err = "dagger".parse::<Method>().unwrap_err();
    assert!(err.contains("dagger"), "{err}");
    // A config holding a method refuses an unknown one.
    let mut table = serde_json::to_value(red_experiments::mujoco::table::TableConfig::default())
        .expect("serialise");
    table["methods"] = json!(["red", "dagger"]);
    let err =
        serde_json::from_value::<red_experiments::mujoco::table::TableConfig>(table).unwrap_err();
    assert!(err.to_string().contains("dagger"), "{err}");
}
