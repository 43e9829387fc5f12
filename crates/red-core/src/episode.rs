//! Running one episode: the one loop that the evaluations, the demo
//! recorders and the scripted drive expert share ([`run_episode`],
//! [`record_episode`]). What is acted and what is kept per step are the
//! caller's closures; both see the environment, so an expert can read the
//! simulator's state and a recorder the poses.
//!
//! Returns are the environment's TRUE reward ([`true_reward`]): when the
//! environment is wrapped by [`crate::RewardWrapper`], the true reward is
//! read from its info ([`TRUE_REWARD`]), otherwise the step's own reward.

use crate::demo::{EpisodeEnd, Trajectory};
use crate::env::{Env, Step, TRUE_REWARD};

/// The environment's true reward of a step (see the module documentation).
pub fn true_reward(step: &Step) -> f64 {
    step.info.get(TRUE_REWARD).unwrap_or(step.reward)
}

/// How an episode run by [`run_episode`] went.
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodeRun {
    /// Steps taken.
    pub length: usize,
    /// Sum of the steps' true rewards, in step order.
    pub true_return: f64,
    /// The last step (its info tells how the episode ended).
    pub last: Step,
    /// [`EpisodeEnd::Terminated`] when the task ended it, else
    /// [`EpisodeEnd::Truncated`] (a time limit, or `max_steps`).
    pub end: EpisodeEnd,
}

/// Runs one episode from `obs`, the observation of a reset just done:
/// each step `act(env, obs)` gives the action handed to the environment,
/// then `on_step(env, obs, action, step)` sees the observation the action
/// was taken in, the action and the step. The episode ends when the
/// environment terminates or truncates it, or after `max_steps` steps.
///
/// # Errors
/// The environment's errors and the closures'.
pub fn run_episode<E, Er>(
    env: &mut E,
    mut obs: Vec<f64>,
    max_steps: Option<usize>,
    mut act: impl FnMut(&E, &[f64]) -> Result<Vec<f64>, Er>,
    mut on_step: impl FnMut(&E, Vec<f64>, Vec<f64>, &Step) -> Result<(), Er>,
) -> Result<EpisodeRun, Er>
where
    E: Env + ?Sized,
    Er: From<crate::Error>,
{
    let (mut true_return, mut length) = (0.0, 0);
    loop {
        let action = act(env, &obs)?;
        let step = env.step(&action)?;
        true_return += true_reward(&step);
        length += 1;
        on_step(env, obs, action, &step)?;
        if step.terminated || step.truncated || max_steps.is_some_and(|m| length >= m) {
            let end = if step.terminated {
                EpisodeEnd::Terminated
            } else {
                EpisodeEnd::Truncated
            };
            return Ok(EpisodeRun {
                length,
                true_return,
                last: step,
                end,
            });
        }
        obs = step.observation;
    }
}

/// [`run_episode`] keeping the trajectory: the observations, the actions
/// handed to the environment and the true rewards. `on_step` sees each
/// step after it is recorded, for whatever else the caller keeps.
///
/// # Errors
/// As [`run_episode`].
pub fn record_episode<E, Er>(
    env: &mut E,
    obs: Vec<f64>,
    max_steps: Option<usize>,
    act: impl FnMut(&E, &[f64]) -> Result<Vec<f64>, Er>,
    mut on_step: impl FnMut(&E, &Step) -> Result<(), Er>,
) -> Result<(Trajectory, EpisodeRun), Er>
where
    E: Env + ?Sized,
    Er: From<crate::Error>,
{
    let (mut observations, mut actions, mut rewards) = (Vec::new(), Vec::new(), Vec::new());
    let run = run_episode(env, obs, max_steps, act, |env, o, a, step| {
        observations.push(o);
        actions.push(a);
        rewards.push(true_reward(step));
        on_step(env, step)
    })?;
    let trajectory = Trajectory {
        observations,
        actions,
        rewards: Some(rewards),
        end: run.end,
    };
    Ok((trajectory, run))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{BoxSpace, Info, Result, Space, TimeLimit};

    /// A walk on a line: the observation is the position, the reward the
    /// action; the task ends past position 2.5.
    struct Walk {
        pos: f64,
        obs: Space,
        act: Space,
    }

    impl Env for Walk {
        fn observation_space(&self) -> &Space {
            &self.obs
        }
        fn action_space(&self) -> &Space {
            &self.act
        }
        fn reset(&mut self, _seed: Option<u64>) -> Result<(Vec<f64>, Info)> {
            self.pos = 0.0;
            Ok((vec![0.0], Info::new()))
        }
        fn step(&mut self, a: &[f64]) -> Result<Step> {
            self.pos += a[0];
            let mut info = Info::new();
            info.set("pos", self.pos);
            Ok(Step {
                observation: vec![self.pos],
                reward: a[0],
                terminated: self.pos > 2.5,
                truncated: false,
                info,
            })
        }
    }

    fn walk() -> Walk {
        Walk {
            pos: 0.0,
            obs: Space::Box(BoxSpace::uniform(1, f64::NEG_INFINITY, f64::INFINITY)),
            act: Space::Box(BoxSpace::uniform(1, -1.0, 1.0)),
        }
    }

    #[test]
    fn records_what_was_seen_and_done_until_the_task_ends() {
        let mut env = walk();
        let (obs, _) = env.reset(None).unwrap();
        let mut seen = Vec::new();
        let (t, run) = record_episode(
            &mut env,
            obs,
            None,
            |e: &Walk, o: &[f64]| Ok::<_, crate::Error>(vec![0.5 + 0.0 * o[0] + 0.0 * e.pos]),
            |e, step| {
                seen.push((e.pos, step.info.get("pos")));
                Ok(())
            },
        )
        .unwrap();
        assert_eq!(run.length, 6);
        assert_eq!(run.end, EpisodeEnd::Terminated);
        assert_eq!(run.true_return, 3.0);
        assert_eq!(run.last.observation, vec![3.0]);
        assert_eq!(t.end, EpisodeEnd::Terminated);
        assert_eq!(t.observations[0], vec![0.0]);
        assert_eq!(t.observations[5], vec![2.5]);
        assert_eq!(t.actions.len(), 6);
        assert_eq!(t.rewards, Some(vec![0.5; 6]));
        assert_eq!(seen.len(), 6);
        assert_eq!(seen[5], (3.0, Some(3.0)));
    }

    #[test]
    fn max_steps_and_time_limits_truncate() {
        let mut env = walk();
        let (obs, _) = env.reset(None).unwrap();
        let run = run_episode(
            &mut env,
            obs,
            Some(2),
            |_, _| Ok::<_, crate::Error>(vec![0.1]),
            |_, _, _, _| Ok(()),
        )
        .unwrap();
        assert_eq!((run.length, run.end), (2, EpisodeEnd::Truncated));
        let mut env = TimeLimit::new(walk(), 3).unwrap();
        let (obs, _) = env.reset(None).unwrap();
        let run = run_episode(
            &mut env,
            obs,
            None,
            |_, _| Ok::<_, crate::Error>(vec![0.1]),
            |_, _, _, _| Ok(()),
        )
        .unwrap();
        assert_eq!((run.length, run.end), (3, EpisodeEnd::Truncated));
        assert!(run.last.truncated);
        // A closure's error stops the episode.
        let (obs, _) = env.reset(None).unwrap();
        let err = run_episode(
            &mut env,
            obs,
            None,
            |_, _| Ok::<_, crate::Error>(vec![0.1]),
            |_, _, _, _| {
                Err(crate::Error::InvalidConfig {
                    field: "x".into(),
                    reason: "stop".into(),
                })
            },
        );
        assert!(err.is_err());
    }
}
