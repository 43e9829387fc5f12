//! `red-cli mujoco`: the MuJoCo environments (Gymnasium's `-v5` Hopper,
//! HalfCheetah, Walker2d, Ant, Reacher).

use std::time::Instant;

use anyhow::Context;
use clap::{Args, Subcommand};
use red_core::Env;
use red_core::check::{CheckConfig, check_env_with};
use red_mujoco::{EnvId, MujocoEnv};

/// Arguments of `red-cli mujoco`.
#[derive(Debug, Args)]
pub struct MujocoArgs {
    #[command(subcommand)]
    command: MujocoCommand,
}

#[derive(Debug, Subcommand)]
enum MujocoCommand {
    /// Check the MuJoCo set-up: load each environment, play it through the
    /// env checker (seeded random actions, twice, compared bit for bit) and
    /// print its dimensions and speed.
    Check(CheckArgs),
}

#[derive(Debug, Args)]
struct CheckArgs {
    /// Environment to check, e.g. `Hopper-v5` or `hopper`; repeat for
    /// several (default: all five).
    #[arg(long = "env", value_name = "ID")]
    envs: Vec<String>,
    /// Steps per run of the checker.
    #[arg(long, default_value_t = 1000)]
    steps: usize,
    /// Seed of the resets and of the random actions.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

/// Runs `red-cli mujoco ...`.
pub fn run(args: MujocoArgs) -> anyhow::Result<()> {
    match args.command {
        MujocoCommand::Check(a) => check(a),
    }
}

/// One line of the check's table.
struct Row {
    id: EnvId,
    obs_dim: usize,
    act_dim: usize,
    frame_skip: usize,
    dt: f64,
    episodes: usize,
    terminated: usize,
    steps_per_s: f64,
}

fn check_one(id: EnvId, steps: usize, seed: u64) -> anyhow::Result<Row> {
    let mut env = id
        .make()
        .with_context(|| format!("cannot build {id} (did you run scripts/setup-mujoco.sh?)"))?;
    let config = CheckConfig {
        seed,
        steps,
        ..CheckConfig::default()
    };
    let start = Instant::now();
    let report = check_env_with(&mut env, &config).with_context(|| format!("{id}"))?;
    // The checker plays `steps` steps twice.
    let steps_per_s = (2 * steps) as f64 / start.elapsed().as_secs_f64();
    let sim = env.inner().simulation();
    Ok(Row {
        id,
        obs_dim: env.observation_space().dim(),
        act_dim: env.action_space().dim(),
        frame_skip: sim.frame_skip(),
        dt: sim.dt(),
        episodes: report.episodes,
        terminated: report.terminated,
        steps_per_s,
    })
}

fn check(args: CheckArgs) -> anyhow::Result<()> {
    let ids = if args.envs.is_empty() {
        EnvId::ALL.to_vec()
    } else {
        args.envs
            .iter()
            .map(|s| s.parse::<EnvId>())
            .collect::<Result<Vec<_>, _>>()?
    };
    anyhow::ensure!(args.steps > 0, "--steps must be at least 1");
    match red_mujoco::assets::assets_dir() {
        Some((dir, source)) => println!("model files: {} ({source})", dir.display()),
        None => println!("model files: no folder configured"),
    }
    println!(
        "| env | obs | act | frame skip | dt (s) | time limit | episodes ended (terminated) | steps/s |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for id in ids {
        let r = check_one(id, args.steps, args.seed)?;
        println!(
            "| {} | {} | {} | {} | {} | {} | {} ({}) | {:.0} |",
            r.id,
            r.obs_dim,
            r.act_dim,
            r.frame_skip,
            r.dt,
            r.id.max_episode_steps(),
            r.episodes,
            r.terminated,
            r.steps_per_s
        );
    }
    println!("all environments passed the env checker");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checks_an_environment() {
        let row = check_one(EnvId::Reacher, 120, 1).unwrap();
        assert_eq!((row.obs_dim, row.act_dim, row.frame_skip), (10, 2, 2));
        assert_eq!(row.episodes, 2);
        assert!(row.steps_per_s > 0.0);
    }

    #[test]
    fn rejects_unknown_environments() {
        let err = check(CheckArgs {
            envs: vec!["Humanoid-v5".into()],
            steps: 10,
            seed: 0,
        })
        .unwrap_err();
        assert!(err.to_string().contains("Hopper-v5"), "{err}");
    }
}
