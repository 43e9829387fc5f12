//! The env checker on small environments: a correct one passes, each kind
//! of broken one fails naming the property and the step.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use red_core::check::{AfterEnd, CheckConfig, check_env_with};
use red_core::{BoxSpace, Env, Error, Info, Result, Space, Step, TimeLimit, check_env};

/// Ways to break [`Corridor`].
#[derive(Debug, Default, Clone, Copy)]
struct Faults {
    /// The reward depends on steps taken since construction, not since the
    /// seeded reset.
    nondeterministic: bool,
    /// Emits NaN in the observation at this step (counted from the seeded
    /// reset).
    nan_at: Option<usize>,
    /// Emits an observation outside the space at this step.
    out_of_bounds_at: Option<usize>,
    /// Emits a NaN reward at this step.
    nan_reward_at: Option<usize>,
    /// Sets both flags when the episode ends.
    both_flags: bool,
    /// Goes on after the end of an episode.
    continue_after_end: bool,
    /// Accepts actions of any length, NaN included.
    accept_bad_actions: bool,
    /// Starts outside the observation space.
    reset_outside: bool,
}

/// A noisy one-dimensional corridor: observation `[position, noise]`,
/// action a push in `[-1, 1]`, terminated at `|position| >= 5`.
struct Corridor {
    faults: Faults,
    obs_space: Space,
    act_space: Space,
    rng: ChaCha8Rng,
    pos: f64,
    done: bool,
    started: bool,
    since_seed: usize,
    since_new: u64,
}

impl Corridor {
    fn new(faults: Faults) -> Self {
        Self {
            faults,
            obs_space: Space::Box(BoxSpace::new(vec![-5.0, -1.0], vec![5.0, 1.0]).unwrap()),
            act_space: Space::Box(BoxSpace::uniform(1, -1.0, 1.0)),
            rng: ChaCha8Rng::seed_from_u64(0),
            pos: 0.0,
            done: false,
            started: false,
            since_seed: 0,
            since_new: 0,
        }
    }
}

impl Env for Corridor {
    fn observation_space(&self) -> &Space {
        &self.obs_space
    }

    fn action_space(&self) -> &Space {
        &self.act_space
    }

    fn reset(&mut self, seed: Option<u64>) -> Result<(Vec<f64>, Info)> {
        if let Some(s) = seed {
            self.rng = ChaCha8Rng::seed_from_u64(s);
            self.since_seed = 0;
        }
        self.pos = self.rng.random_range(-1.0..1.0);
        self.done = false;
        self.started = true;
        let x = if self.faults.reset_outside {
            7.5
        } else {
            self.pos
        };
        let mut info = Info::new();
        info.set("start", self.pos);
        Ok((vec![x, 0.0], info))
    }

    fn step(&mut self, action: &[f64]) -> Result<Step> {
        if !self.faults.accept_bad_actions {
            self.act_space.check("action", action)?;
        }
        if !self.started || (self.done && !self.faults.continue_after_end) {
            return Err(Error::NeedsReset {
                reason: "episode over".into(),
            });
        }
        let k = self.since_seed;
        self.since_seed += 1;
        self.since_new += 1;
        let noise: f64 = self.rng.random_range(-1.0..1.0);
        self.pos = (self.pos + 2.0 * action.first().copied().unwrap_or(0.0) + 0.1 * noise)
            .clamp(-5.0, 5.0);
        let terminated = self.pos.abs() >= 5.0;
        self.done |= terminated;
        let mut observation = vec![self.pos, noise];
        if self.faults.nan_at == Some(k) {
            observation[1] = f64::NAN;
        }
        if self.faults.out_of_bounds_at == Some(k) {
            observation[0] = 6.0;
        }
        let mut reward = -self.pos.abs();
        if self.faults.nondeterministic {
            reward += self.since_new as f64 * 1e-3;
        }
        if self.faults.nan_reward_at == Some(k) {
            reward = f64::NAN;
        }
        let mut info = Info::new();
        info.set("progress", self.pos / 5.0);
        Ok(Step {
            observation,
            reward,
            terminated,
            truncated: terminated && self.faults.both_flags,
            info,
        })
    }
}

fn check(faults: Faults) -> Result<red_core::CheckReport> {
    let mut env = TimeLimit::new(Corridor::new(faults), 15)?;
    check_env(&mut env, 3, 120)
}

fn failure(faults: Faults) -> String {
    match check(faults) {
        Err(Error::EnvCheck { reason }) => reason,
        other => panic!("expected an env check failure for {faults:?}, got {other:?}"),
    }
}

#[test]
fn a_correct_env_passes() {
    let report = check(Faults::default()).unwrap();
    assert_eq!(report.steps, 120);
    assert_eq!((report.obs_dim, report.act_dim), (2, 1));
    // Both kinds of ending happen with this seed, so both paths are covered.
    assert!(report.terminated > 0, "{report}");
    assert!(report.truncated > 0, "{report}");
    assert_eq!(report.episodes, report.terminated + report.truncated);
    assert_eq!(report.after_end, AfterEnd::NeedsReset);
    assert_eq!(report.info_keys, vec!["start", "progress"]);
    assert!(report.to_string().contains("env check passed"));
}

#[test]
fn checking_is_itself_deterministic() {
    assert_eq!(
        check(Faults::default()).unwrap(),
        check(Faults::default()).unwrap()
    );
}

#[test]
fn a_nondeterministic_env_fails() {
    let r = failure(Faults {
        nondeterministic: true,
        ..Faults::default()
    });
    assert!(r.starts_with("determinism"), "{r}");
    assert!(
        r.contains("(step 0) in the reward: -0.6530651231021373 vs -0.5330651231021373"),
        "{r}"
    );
}

#[test]
fn a_nan_observation_fails_at_its_step() {
    let r = failure(Faults {
        nan_at: Some(7),
        ..Faults::default()
    });
    assert!(r.starts_with("finite observation"), "{r}");
    assert!(r.contains("run 1, step 7"), "{r}");
    assert!(r.contains("observation[1] = NaN"), "{r}");
}

#[test]
fn an_out_of_bounds_observation_fails_with_its_value_and_bounds() {
    let r = failure(Faults {
        out_of_bounds_at: Some(4),
        ..Faults::default()
    });
    assert!(r.starts_with("observation in space"), "{r}");
    assert!(r.contains("step 4"), "{r}");
    assert!(r.contains("observation[0] = 6 outside [-5, 5]"), "{r}");
}

#[test]
fn a_nan_reward_fails() {
    let r = failure(Faults {
        nan_reward_at: Some(2),
        ..Faults::default()
    });
    assert!(
        r.starts_with("finite reward") && r.contains("step 2"),
        "{r}"
    );
}

#[test]
fn both_flags_at_once_fail() {
    let r = failure(Faults {
        both_flags: true,
        ..Faults::default()
    });
    assert!(r.starts_with("terminated xor truncated"), "{r}");
}

#[test]
fn a_reset_outside_the_space_fails() {
    let r = failure(Faults {
        reset_outside: true,
        ..Faults::default()
    });
    assert!(r.starts_with("observation in space: reset of run 1"), "{r}");
}

#[test]
fn accepting_malformed_actions_fails() {
    let r = failure(Faults {
        accept_bad_actions: true,
        ..Faults::default()
    });
    assert!(r.starts_with("malformed action rejected"), "{r}");
    assert!(r.contains("one number too long"), "{r}");
}

#[test]
fn stepping_after_the_end_must_need_a_reset_unless_allowed() {
    // Without TimeLimit (which itself refuses steps after an end), the
    // corridor that goes on is caught...
    let faults = Faults {
        continue_after_end: true,
        ..Faults::default()
    };
    let err = check_env(&mut Corridor::new(faults), 3, 200).unwrap_err();
    assert!(err.to_string().contains("step after end"), "{err}");
    // ...and passes when its going on is declared.
    let config = CheckConfig {
        seed: 3,
        steps: 200,
        allow_step_after_end: true,
    };
    let report = check_env_with(&mut Corridor::new(faults), &config).unwrap();
    assert_eq!(report.after_end, AfterEnd::Continues);
}

/// A two-armed bandit with a discrete action, to check discrete spaces.
struct Bandit {
    obs: Space,
    act: Space,
    left: usize,
}

impl Env for Bandit {
    fn observation_space(&self) -> &Space {
        &self.obs
    }
    fn action_space(&self) -> &Space {
        &self.act
    }
    fn reset(&mut self, _seed: Option<u64>) -> Result<(Vec<f64>, Info)> {
        self.left = 3;
        Ok((vec![0.0], Info::new()))
    }
    fn step(&mut self, action: &[f64]) -> Result<Step> {
        self.act.check("action", action)?;
        if self.left == 0 {
            return Err(Error::NeedsReset {
                reason: "over".into(),
            });
        }
        self.left -= 1;
        Ok(Step {
            observation: vec![action[0]],
            reward: action[0],
            terminated: self.left == 0,
            truncated: false,
            info: Info::new(),
        })
    }
}

#[test]
fn discrete_action_spaces_are_checked_too() {
    let mut env = Bandit {
        obs: Space::Discrete(2),
        act: Space::Discrete(2),
        left: 0,
    };
    let report = check_env(&mut env, 1, 30).unwrap();
    assert_eq!(report.terminated, 10);
    env.act = Space::Discrete(0);
    let err = check_env(&mut env, 1, 30).unwrap_err().to_string();
    assert!(
        err.contains("action space Discrete(0) is malformed"),
        "{err}"
    );
}
