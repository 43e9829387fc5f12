//! Step-by-step parity with Gymnasium's `-v5` environments.
//!
//! For each environment: episodes start from the state of one of our resets,
//! set on both sides with `set_state`; the same random actions (some outside
//! the action bounds, which Gymnasium passes through unclipped) are applied
//! for 200 steps in all, a new episode starting whenever ours terminates.
//! Observations, rewards, terminations and every info entry must agree
//! within 1e-6 relative (1e-9 absolute near zero).
//!
//! The Gymnasium side is `scripts/gym_oracle.py` run by the virtualenv
//! `.venv-oracle` that `scripts/setup-mujoco.sh` creates (or the Python named
//! by `RED_ORACLE_PYTHON`). `RED_SKIP_PARITY=1` skips these tests.

use std::io::Write;
use std::path::PathBuf;
use std::process::{Command, Stdio};

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use red_core::Env;
use red_mujoco::{
    Ant, AntConfig, HalfCheetah, HalfCheetahConfig, Hopper, HopperConfig, MujocoEnv, Reacher,
    ReacherConfig, Walker2d, Walker2dConfig,
};
use serde_json::{Value, json};

const TOTAL_STEPS: usize = 200;
const REL_TOL: f64 = 1e-6;
const ABS_TOL: f64 = 1e-9;
/// Actions are drawn from `U[-ACTION_SPAN, ACTION_SPAN)`, a bit wider than
/// the bounds [-1, 1].
const ACTION_SPAN: f64 = 1.2;

fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The oracle's Python, or `None` when the parity tests are skipped.
fn oracle_python() -> Option<PathBuf> {
    if std::env::var("RED_SKIP_PARITY").is_ok_and(|v| v == "1") {
        // Written to the stream itself, past the test harness's capture of
        // `eprintln!`, so that the skip shows in every test log.
        let _ = writeln!(
            std::io::stderr(),
            "\n*** RED_SKIP_PARITY=1: SKIPPING a Gymnasium parity test of red-mujoco. ***\n\
             *** Nothing was compared against Gymnasium.                            ***\n"
        );
        return None;
    }
    let python = std::env::var_os("RED_ORACLE_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo_root().join(".venv-oracle/bin/python"));
    assert!(
        python.exists(),
        "the Gymnasium oracle {} is missing: run `scripts/setup-mujoco.sh` from the repository \
         root (it creates .venv-oracle), or set RED_SKIP_PARITY=1 to skip this test",
        python.display()
    );
    Some(python)
}

/// One episode as run on our side.
struct Episode {
    qpos: Vec<f64>,
    qvel: Vec<f64>,
    reset_obs: Vec<f64>,
    /// The info of our `reset` (positions only, so a perturbed velocity
    /// does not change it).
    reset_info: red_core::Info,
    actions: Vec<Vec<f64>>,
    steps: Vec<red_core::Step>,
}

/// Changes the velocities of a reset state before the episode starts (to
/// reach states that random actions rarely reach). Positions stay, so our
/// reset info still describes the state.
type Perturb = dyn Fn(&mut [f64]);

fn run_ours(env: &mut dyn MujocoEnv, seed: u64, perturb: &Perturb) -> Vec<Episode> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let act_dim = env.action_space().dim();
    let mut episodes = Vec::new();
    let mut total = 0;
    while total < TOTAL_STEPS {
        let (_, reset_info) = env.reset(Some(seed + episodes.len() as u64)).unwrap();
        let qpos = env.simulation().qpos().to_vec();
        let mut qvel = env.simulation().qvel().to_vec();
        perturb(&mut qvel);
        let reset_obs = env.set_state(&qpos, &qvel).unwrap();
        let mut episode = Episode {
            qpos,
            qvel,
            reset_obs,
            reset_info,
            actions: Vec::new(),
            steps: Vec::new(),
        };
        while total < TOTAL_STEPS {
            let action: Vec<f64> = (0..act_dim)
                .map(|_| rng.random_range(-ACTION_SPAN..ACTION_SPAN))
                .collect();
            let step = env.step(&action).unwrap();
            total += 1;
            let done = step.terminated;
            episode.actions.push(action);
            episode.steps.push(step);
            if done {
                break;
            }
        }
        episodes.push(episode);
    }
    episodes
}

fn run_oracle(python: &PathBuf, gym_id: &str, kwargs: &Value, episodes: &[Episode]) -> Value {
    let request = json!({
        "env": gym_id,
        "kwargs": kwargs,
        "episodes": episodes
            .iter()
            .map(|e| json!({"qpos": e.qpos, "qvel": e.qvel, "actions": e.actions}))
            .collect::<Vec<_>>(),
    });
    let script = repo_root().join("scripts/gym_oracle.py");
    // MuJoCo appends its warnings to MUJOCO_LOG.TXT in the working folder.
    let mut child = Command::new(python)
        .arg(&script)
        .current_dir(std::env::temp_dir())
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start {}: {e}", python.display()));
    child
        .stdin
        .take()
        .unwrap()
        .write_all(request.to_string().as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "the Gymnasium oracle failed ({}); stderr:\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let response: Value = serde_json::from_slice(&out.stdout).expect("oracle printed bad JSON");
    let versions = &response["versions"];
    assert_eq!(versions["mujoco"], "3.17.0", "oracle versions: {versions}");
    assert!(
        versions["gymnasium"]
            .as_str()
            .is_some_and(|v| v.starts_with("1.")),
        "oracle versions: {versions}"
    );
    response
}

thread_local! {
    /// The largest |ours - theirs| seen by this test's thread.
    static WORST: std::cell::Cell<f64> = const { std::cell::Cell::new(0.0) };
}

fn close(ours: f64, theirs: &Value) -> bool {
    if let Some(t) = theirs.as_f64() {
        WORST.with(|w| w.set(w.get().max((ours - t).abs())));
    }
    match theirs.as_f64() {
        Some(t) => (ours - t).abs() <= ABS_TOL.max(REL_TOL * ours.abs().max(t.abs())),
        None => theirs.is_null() && !ours.is_finite(),
    }
}

fn compare_vec(what: &str, ours: &[f64], theirs: &Value, problems: &mut Vec<String>) {
    let theirs = theirs.as_array().expect("oracle vector");
    if ours.len() != theirs.len() {
        problems.push(format!(
            "{what}: length {} vs Gymnasium's {}",
            ours.len(),
            theirs.len()
        ));
        return;
    }
    for (i, (o, t)) in ours.iter().zip(theirs).enumerate() {
        if !close(*o, t) {
            problems.push(format!("{what}[{i}]: ours {o:e}, Gymnasium {t}"));
        }
    }
}

fn compare_info(what: &str, ours: &red_core::Info, theirs: &Value, problems: &mut Vec<String>) {
    let theirs = theirs.as_object().expect("oracle info");
    let mut our_keys: Vec<&str> = ours.iter().map(|(k, _)| k).collect();
    let mut their_keys: Vec<&str> = theirs.keys().map(String::as_str).collect();
    our_keys.sort_unstable();
    their_keys.sort_unstable();
    if our_keys != their_keys {
        problems.push(format!(
            "{what} keys: ours {our_keys:?}, Gymnasium {their_keys:?}"
        ));
    }
    for (key, value) in ours.iter() {
        if let Some(tv) = theirs.get(key)
            && !close(value, tv)
        {
            problems.push(format!("{what} {key}: ours {value:e}, Gymnasium {tv}"));
        }
    }
}

/// Runs one environment on both sides and compares; returns (episodes,
/// terminations, steps) compared.
fn check_parity(
    gym_id: &str,
    kwargs: Value,
    env: &mut dyn MujocoEnv,
    seed: u64,
    perturb: &Perturb,
) -> Option<(usize, usize, usize)> {
    let python = oracle_python()?;
    WORST.with(|w| w.set(0.0));
    let ours = run_ours(env, seed, perturb);
    let theirs = run_oracle(&python, gym_id, &kwargs, &ours);
    let theirs = theirs["episodes"].as_array().expect("episodes");
    assert_eq!(ours.len(), theirs.len());

    let mut problems = Vec::new();
    let (mut steps, mut terminations) = (0, 0);
    for (e, (o, t)) in ours.iter().zip(theirs).enumerate() {
        compare_vec(
            &format!("episode {e} reset observation"),
            &o.reset_obs,
            &t["obs"],
            &mut problems,
        );
        compare_info(
            &format!("episode {e} reset info"),
            &o.reset_info,
            &t["reset_info"],
            &mut problems,
        );
        let t_steps = t["steps"].as_array().expect("steps");
        assert_eq!(o.steps.len(), t_steps.len());
        for (k, (os, ts)) in o.steps.iter().zip(t_steps).enumerate() {
            let at = format!("episode {e} step {k}");
            compare_vec(
                &format!("{at} observation"),
                &os.observation,
                &ts["obs"],
                &mut problems,
            );
            if !close(os.reward, &ts["reward"]) {
                problems.push(format!(
                    "{at} reward: ours {:e}, Gymnasium {}",
                    os.reward, ts["reward"]
                ));
            }
            if Some(os.terminated) != ts["terminated"].as_bool() {
                problems.push(format!(
                    "{at} terminated: ours {}, Gymnasium {}",
                    os.terminated, ts["terminated"]
                ));
            }
            compare_info(&format!("{at} info"), &os.info, &ts["info"], &mut problems);
            steps += 1;
            terminations += usize::from(os.terminated);
        }
    }
    assert!(
        problems.is_empty(),
        "{gym_id} {kwargs}: {} differences from Gymnasium, the first ones:\n{}",
        problems.len(),
        problems[..problems.len().min(20)].join("\n")
    );
    assert_eq!(steps, TOTAL_STEPS);
    eprintln!(
        "{gym_id} {kwargs}: {} episodes, {terminations} terminations, {steps} steps agree \
         (largest absolute difference {:e})",
        ours.len(),
        WORST.with(|w| w.get())
    );
    Some((ours.len(), terminations, steps))
}

#[test]
fn hopper_matches_gymnasium() {
    let mut env = Hopper::new(HopperConfig::default()).unwrap();
    if let Some((_, terminations, _)) = check_parity("Hopper-v5", json!({}), &mut env, 11, &|_| {})
    {
        assert!(terminations > 0, "no termination was compared");
    }
}

#[test]
fn half_cheetah_matches_gymnasium() {
    let mut env = HalfCheetah::new(HalfCheetahConfig::default()).unwrap();
    check_parity("HalfCheetah-v5", json!({}), &mut env, 12, &|_| {});
}

#[test]
fn walker2d_matches_gymnasium() {
    let mut env = Walker2d::new(Walker2dConfig::default()).unwrap();
    if let Some((_, terminations, _)) =
        check_parity("Walker2d-v5", json!({}), &mut env, 13, &|_| {})
    {
        assert!(terminations > 0, "no termination was compared");
    }
}

#[test]
fn ant_without_contact_forces_matches_gymnasium() {
    let mut env = Ant::new(AntConfig::default()).unwrap();
    assert_eq!(env.observation_space().dim(), 27);
    check_parity(
        "Ant-v5",
        json!({"include_cfrc_ext_in_observation": false}),
        &mut env,
        14,
        &|_| {},
    );
}

#[test]
fn ant_with_contact_forces_matches_gymnasium() {
    let mut env = Ant::new(AntConfig {
        include_cfrc_ext_in_observation: true,
        ..AntConfig::default()
    })
    .unwrap();
    assert_eq!(env.observation_space().dim(), 105);
    check_parity("Ant-v5", json!({}), &mut env, 15, &|_| {});
}

#[test]
fn ant_terminations_match_gymnasium() {
    // Thrown upwards, the torso leaves the healthy range [0.2, 1] in a few
    // steps: every episode here terminates.
    let mut env = Ant::new(AntConfig::default()).unwrap();
    let throw = |qvel: &mut [f64]| qvel[2] += 4.0;
    if let Some((episodes, terminations, _)) = check_parity(
        "Ant-v5",
        json!({"include_cfrc_ext_in_observation": false}),
        &mut env,
        18,
        &throw,
    ) {
        assert!(terminations + 1 >= episodes, "{terminations} of {episodes}");
    }
}

#[test]
fn reacher_matches_gymnasium() {
    let mut env = Reacher::new(ReacherConfig::default()).unwrap();
    check_parity("Reacher-v5", json!({}), &mut env, 16, &|_| {});
}

#[test]
fn non_default_options_match_gymnasium() {
    // Positions kept in the observation, termination off, other weights.
    let mut env = Hopper::new(HopperConfig {
        exclude_current_positions_from_observation: false,
        terminate_when_unhealthy: false,
        ctrl_cost_weight: 0.01,
        healthy_reward: 0.5,
        ..HopperConfig::default()
    })
    .unwrap();
    check_parity(
        "Hopper-v5",
        json!({
            "exclude_current_positions_from_observation": false,
            "terminate_when_unhealthy": false,
            "ctrl_cost_weight": 0.01,
            "healthy_reward": 0.5,
        }),
        &mut env,
        17,
        &|_| {},
    );
}

#[test]
fn non_default_options_of_the_other_envs_match_gymnasium() {
    let mut cheetah = HalfCheetah::new(HalfCheetahConfig {
        forward_reward_weight: 2.0,
        ctrl_cost_weight: 0.3,
        exclude_current_positions_from_observation: false,
        ..HalfCheetahConfig::default()
    })
    .unwrap();
    check_parity(
        "HalfCheetah-v5",
        json!({
            "forward_reward_weight": 2.0,
            "ctrl_cost_weight": 0.3,
            "exclude_current_positions_from_observation": false,
        }),
        &mut cheetah,
        19,
        &|_| {},
    );

    let mut walker = Walker2d::new(Walker2dConfig {
        healthy_z_range: [0.9, 1.5],
        healthy_angle_range: [-0.5, 0.5],
        healthy_reward: 2.0,
        ..Walker2dConfig::default()
    })
    .unwrap();
    check_parity(
        "Walker2d-v5",
        json!({
            "healthy_z_range": [0.9, 1.5],
            "healthy_angle_range": [-0.5, 0.5],
            "healthy_reward": 2.0,
        }),
        &mut walker,
        20,
        &|_| {},
    );

    let mut ant = Ant::new(AntConfig {
        exclude_current_positions_from_observation: false,
        include_cfrc_ext_in_observation: true,
        contact_force_range: [-0.5, 2.0],
        contact_cost_weight: 1e-2,
        healthy_z_range: [0.3, 0.9],
        ..AntConfig::default()
    })
    .unwrap();
    check_parity(
        "Ant-v5",
        json!({
            "exclude_current_positions_from_observation": false,
            "include_cfrc_ext_in_observation": true,
            "contact_force_range": [-0.5, 2.0],
            "contact_cost_weight": 1e-2,
            "healthy_z_range": [0.3, 0.9],
        }),
        &mut ant,
        21,
        &|_| {},
    );

    let mut reacher = Reacher::new(ReacherConfig {
        reward_dist_weight: 0.5,
        reward_control_weight: 3.0,
        ..ReacherConfig::default()
    })
    .unwrap();
    check_parity(
        "Reacher-v5",
        json!({"reward_dist_weight": 0.5, "reward_control_weight": 3.0}),
        &mut reacher,
        22,
        &|_| {},
    );
}
