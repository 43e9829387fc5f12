//! The set-up check of the MuJoCo tasks: load each one, play it through the
//! env checker (seeded random actions, twice, compared bit for bit) and
//! measure its dimensions and speed.

use std::time::Instant;

use red_core::Env;
use red_core::check::{CheckConfig, check_env_with};
use red_mujoco::{EnvId, MujocoEnv};

use crate::{Error, Result, ResultExt};

/// One task's check: its dimensions, timing, and what the checker saw.
#[derive(Debug, Clone, PartialEq)]
pub struct EnvCheck {
    /// The task.
    pub id: EnvId,
    /// Observation size.
    pub obs_dim: usize,
    /// Action size.
    pub act_dim: usize,
    /// Physics steps per environment step.
    pub frame_skip: usize,
    /// Seconds per physics step.
    pub dt: f64,
    /// Episodes ended during the checker's runs.
    pub episodes: usize,
    /// Of those, the ones ended by termination (not the time limit).
    pub terminated: usize,
    /// Environment steps per second over both runs.
    pub steps_per_s: f64,
}

/// Where the model files come from, as `red-cli mujoco check` prints it.
pub fn assets_line() -> String {
    match red_mujoco::assets::assets_dir() {
        Some((dir, source)) => format!("model files: {} ({source})", dir.display()),
        None => "model files: no folder configured".into(),
    }
}

impl EnvCheck {
    /// The header of [`EnvCheck::row`]'s markdown table (two lines).
    pub const HEADER: &'static str = "| env | obs | act | frame skip | dt (s) | time limit | episodes ended (terminated) | steps/s |\n|---|---|---|---|---|---|---|---|";

    /// The check as a markdown table row.
    pub fn row(&self) -> String {
        format!(
            "| {} | {} | {} | {} | {} | {} | {} ({}) | {:.0} |",
            self.id,
            self.obs_dim,
            self.act_dim,
            self.frame_skip,
            self.dt,
            self.id.max_episode_steps(),
            self.episodes,
            self.terminated,
            self.steps_per_s
        )
    }
}

/// Plays `id` through the env checker for `steps` steps (twice) from
/// `seed`.
///
/// # Errors
/// The model cannot be loaded (run `scripts/setup-mujoco.sh`), or the
/// checker found a fault (named with the task).
pub fn check_env(id: EnvId, steps: usize, seed: u64) -> Result<EnvCheck> {
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
    Ok(EnvCheck {
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

/// `red-cli mujoco check`: the model files' folder, then each of `ids`
/// (all five when empty) through [`check_env`] as a table row, each line
/// handed to `line` as soon as it is known.
///
/// # Errors
/// `steps` of 0, and [`check_env`]'s errors.
pub fn check_envs(
    ids: &[EnvId],
    steps: usize,
    seed: u64,
    line: &mut dyn FnMut(&str),
) -> Result<()> {
    if steps == 0 {
        return Err(Error::InvalidConfig {
            field: "--steps".into(),
            reason: "must be at least 1".into(),
        });
    }
    let ids = if ids.is_empty() { &EnvId::ALL[..] } else { ids };
    line(&assets_line());
    line(EnvCheck::HEADER);
    for &id in ids {
        line(&check_env(id, steps, seed)?.row());
    }
    line("all environments passed the env checker");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checks_an_environment() {
        let c = check_env(EnvId::Reacher, 120, 1).unwrap();
        assert_eq!((c.obs_dim, c.act_dim, c.frame_skip), (10, 2, 2));
        assert_eq!(c.episodes, 2);
        assert!(c.steps_per_s > 0.0);
        assert!(c.row().starts_with("| Reacher-v5 | 10 | 2 | 2 |"));
    }
}
