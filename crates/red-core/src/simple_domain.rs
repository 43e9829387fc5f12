//! The stateless task of the paper's Sec. 5.1: `s ~ U(-1, 1)`, actions
//! `a in {-1, +1}`, true reward `a * s`, expert `sign(s)`.
//!
//! The action space is `Discrete(2)`: index 0 means `a = -1`, index 1 means
//! `a = +1` (see [`action_value`]). Demonstrations store the index, as for
//! every discrete environment of the project; [`ActionValues`] lets a reward
//! model see the paper's `a in {-1, +1}` instead.
//!
//! An episode lasts [`EPISODE_LENGTH`] steps and ends by the time limit
//! (truncated): the task has no terminal state. "Mean episodic reward" in
//! the experiments is the mean true reward PER STEP over an episode, so the
//! expert scores `E|s| = 0.5` and a random policy 0 whatever the length.
//!
//! It lives in red-core, below the learners, so that red-rl's DQN tests and
//! red-experiments' toy experiment use the same task without a dependency
//! between them.

use ndarray::{Array1, Array2, ArrayView2};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::{
    BoxSpace, Demos, Env, EpisodeEnd, Error, Info, Result, RewardModel, Space, Step, TimeLimit,
    Trajectory,
};

/// Steps per episode. The paper gives none; 100 makes an episode's mean
/// reward per step a 100-sample average (std about 0.03 for the expert).
pub const EPISODE_LENGTH: usize = 100;

/// The environment id written in demonstration files.
pub const ENV_ID: &str = "simple-domain";

/// The action value `a in {-1, +1}` of a discrete action index.
pub fn action_value(index: f64) -> f64 {
    if index >= 0.5 { 1.0 } else { -1.0 }
}

/// Action indices `(n, 1)` mapped to the paper's values `a in {-1, +1}`.
pub fn to_action_values(actions: ArrayView2<'_, f64>) -> Array2<f64> {
    actions.mapv(action_value)
}

/// A reward model fitted on `(s, a)` with `a in {-1, +1}`, used with the
/// environment's action indices: it maps each index to its value before
/// asking the inner model.
pub struct ActionValues<R>(pub R);

impl<R: RewardModel> RewardModel for ActionValues<R> {
    fn rewards(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<Array1<f64>> {
        self.0.rewards(states, to_action_values(actions).view())
    }
    fn update(&mut self, states: ArrayView2<'_, f64>, actions: ArrayView2<'_, f64>) -> Result<()> {
        self.0.update(states, to_action_values(actions).view())
    }
    fn is_adaptive(&self) -> bool {
        self.0.is_adaptive()
    }
}

/// The expert's action index for state `s`: `sign(s)` (`+1` at `s = 0`).
pub fn expert_action(s: f64) -> f64 {
    if s >= 0.0 { 1.0 } else { 0.0 }
}

/// The stateless environment, without its time limit (see [`simple_domain`]).
#[derive(Debug, Clone)]
pub struct SimpleDomain {
    obs_space: Space,
    act_space: Space,
    rng: ChaCha8Rng,
    state: Option<f64>,
}

impl SimpleDomain {
    /// A new environment; its stream is set by the first `reset(Some(seed))`.
    pub fn new() -> Self {
        Self {
            obs_space: Space::Box(BoxSpace::uniform(1, -1.0, 1.0)),
            act_space: Space::Discrete(2),
            rng: ChaCha8Rng::seed_from_u64(0),
            state: None,
        }
    }
}

impl Default for SimpleDomain {
    fn default() -> Self {
        Self::new()
    }
}

impl Env for SimpleDomain {
    fn observation_space(&self) -> &Space {
        &self.obs_space
    }
    fn action_space(&self) -> &Space {
        &self.act_space
    }
    fn reset(&mut self, seed: Option<u64>) -> Result<(Vec<f64>, Info)> {
        if let Some(seed) = seed {
            self.rng = ChaCha8Rng::seed_from_u64(seed);
        }
        let s = self.rng.random_range(-1.0..=1.0);
        self.state = Some(s);
        Ok((vec![s], Info::new()))
    }
    fn step(&mut self, action: &[f64]) -> Result<Step> {
        let s = self.state.ok_or_else(|| Error::NeedsReset {
            reason: "step called before reset".into(),
        })?;
        self.act_space.check("action", action)?;
        let reward = action_value(action[0]) * s;
        let next = self.rng.random_range(-1.0..=1.0);
        self.state = Some(next);
        Ok(Step {
            observation: vec![next],
            reward,
            terminated: false,
            truncated: false,
            info: Info::new(),
        })
    }
}

/// The task as the experiments use it: [`SimpleDomain`] cut at
/// [`EPISODE_LENGTH`] steps.
pub fn simple_domain() -> TimeLimit<SimpleDomain> {
    // EPISODE_LENGTH is non-zero, so the constructor cannot fail.
    TimeLimit::new(SimpleDomain::new(), EPISODE_LENGTH).expect("EPISODE_LENGTH > 0")
}

/// An expert dataset of `n` pairs `(s, sign(s))` with `s ~ U(-1, 1)`, as one
/// trajectory (the task is stateless, so the grouping carries nothing).
pub fn expert_demos<R: rand::Rng + ?Sized>(n: usize, rng: &mut R) -> Demos {
    let states = (0..n).map(|_| rng.random_range(-1.0..=1.0)).collect();
    demos_of_states(states)
}

/// An expert dataset of `n` pairs `(s, sign(s))` whose states are drawn by
/// stratified sampling: `s_i ~ U(-1 + 2i/n, -1 + 2(i+1)/n)` for
/// `i = 0..n`. Each state is still uniform on its stratum, so the set as a
/// whole covers `[-1, 1]` as a uniform draw does on average, but it cannot
/// miss a whole side: with `n = 5` independent draws, one set in 16 holds
/// states of a single sign, from which no estimator can tell what the
/// expert does on the other side.
pub fn expert_demos_stratified<R: rand::Rng + ?Sized>(n: usize, rng: &mut R) -> Demos {
    let width = 2.0 / n as f64;
    let states = (0..n)
        .map(|i| -1.0 + width * (i as f64 + rng.random_range(0.0..1.0)))
        .collect();
    demos_of_states(states)
}

fn demos_of_states(states: Vec<f64>) -> Demos {
    let mut demos = Demos::new(ENV_ID, 1, 1, None);
    let observations: Vec<Vec<f64>> = states.into_iter().map(|s| vec![s]).collect();
    let actions = observations
        .iter()
        .map(|o| vec![expert_action(o[0])])
        .collect();
    let rewards = observations.iter().map(|o| o[0].abs()).collect();
    demos.trajectories.push(Trajectory {
        observations,
        actions,
        rewards: Some(rewards),
        end: EpisodeEnd::Truncated,
    });
    demos
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn expert_scores_half_per_step() {
        let mut env = simple_domain();
        let (mut obs, _) = env.reset(Some(3)).unwrap();
        let mut total = 0.0;
        let mut steps = 0;
        for _ in 0..20 * EPISODE_LENGTH {
            let step = env.step(&[expert_action(obs[0])]).unwrap();
            total += step.reward;
            steps += 1;
            obs = if step.truncated {
                env.reset(None).unwrap().0
            } else {
                step.observation
            };
        }
        let mean = total / steps as f64;
        assert!(
            (mean - 0.5).abs() < 0.03,
            "expert mean reward per step {mean}"
        );
    }

    #[test]
    fn truncates_at_episode_length() {
        let mut env = simple_domain();
        env.reset(Some(0)).unwrap();
        for t in 1..=EPISODE_LENGTH {
            let step = env.step(&[1.0]).unwrap();
            assert!(!step.terminated);
            assert_eq!(step.truncated, t == EPISODE_LENGTH);
        }
    }

    #[test]
    fn rejects_bad_actions() {
        let mut env = SimpleDomain::new();
        assert!(env.step(&[1.0]).is_err(), "step before reset");
        env.reset(Some(0)).unwrap();
        assert!(env.step(&[2.0]).is_err());
        assert!(env.step(&[0.5]).is_err());
        assert!(env.step(&[f64::NAN]).is_err());
    }

    #[test]
    fn stratified_demos_cover_each_stratum() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let demos = expert_demos_stratified(5, &mut rng);
        let (s, a) = demos.pairs();
        for i in 0..5 {
            let lo = -1.0 + 0.4 * i as f64;
            assert!(
                (lo..lo + 0.4).contains(&s[[i, 0]]),
                "state {i}: {}",
                s[[i, 0]]
            );
            assert_eq!(a[[i, 0]], expert_action(s[[i, 0]]));
        }
    }

    #[test]
    fn expert_demos_follow_sign() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let demos = expert_demos(50, &mut rng);
        assert_eq!(demos.num_pairs(), 50);
        let (s, a) = demos.pairs();
        for i in 0..50 {
            assert_eq!(
                action_value(a[[i, 0]]),
                if s[[i, 0]] >= 0.0 { 1.0 } else { -1.0 }
            );
        }
    }
}
