//! [`WatchedEnv`]: a task inside its time limit that counts MuJoCo's own
//! warnings, so a run can report them instead of letting them pass, and
//! can end each observation with the time ([`WatchedEnv::with_time_feature`]).

use red_core::{Env, Info, Space, Step, TimeLimit};

use crate::{BoxedEnv, EnvId, Error, MujocoEnv, Result};

/// MuJoCo's `mjNWARNING`.
pub const MJ_N_WARNING: usize = 8;

/// Names of MuJoCo's warnings (`mjtWarning`), by index.
pub const MJ_WARNING_NAMES: [&str; MJ_N_WARNING] = [
    "inertia (mjWARN_INERTIA)",
    "contact buffer full (mjWARN_CONTACTFULL)",
    "constraint buffer full (mjWARN_CNSTRFULL)",
    "visual geoms full (mjWARN_VGEOMFULL)",
    "bad qpos (mjWARN_BADQPOS)",
    "bad qvel (mjWARN_BADQVEL)",
    "bad qacc, simulation unstable (mjWARN_BADQACC)",
    "bad ctrl (mjWARN_BADCTRL)",
];

/// A MuJoCo environment inside its time limit that counts MuJoCo's own
/// warnings (the `warning` array of `mjData`) after every step, so a run can
/// report them instead of letting them pass.
pub struct WatchedEnv {
    env: TimeLimit<BoxedEnv>,
    last: [i64; MJ_N_WARNING],
    fresh: [u64; MJ_N_WARNING],
    /// With the time feature: the task's observation box with one more
    /// dimension in `[0, 1]`.
    timed_space: Option<Space>,
}

impl WatchedEnv {
    /// `id` with its default config and time limit.
    ///
    /// # Errors
    /// The model cannot be loaded (run `scripts/setup-mujoco.sh`).
    pub fn new(id: EnvId) -> Result<Self> {
        Self::with_time_feature(id, false)
    }

    /// `id` as [`WatchedEnv::new`], and with `time_feature` every
    /// observation ends with one more number: the steps taken in the episode
    /// over the time limit (0 at the reset, 1 at the limit), the "time
    /// feature" of Pardo et al. (2018, "Time Limits in Reinforcement
    /// Learning") for tasks whose episodes end at a fixed step.
    ///
    /// # Errors
    /// The model cannot be loaded (run `scripts/setup-mujoco.sh`).
    pub fn with_time_feature(id: EnvId, time_feature: bool) -> Result<Self> {
        let env = id.make()?;
        let timed_space = match (time_feature, env.observation_space()) {
            (false, _) => None,
            (true, Space::Box(b)) => {
                let (mut low, mut high) = (b.low.clone(), b.high.clone());
                low.push(0.0);
                high.push(1.0);
                let b = red_core::BoxSpace::new(low, high).map_err(|e| Error::InvalidConfig {
                    field: "time_feature",
                    reason: e.to_string(),
                })?;
                Some(Space::Box(b))
            }
            (true, Space::Discrete(_)) => {
                return Err(Error::InvalidConfig {
                    field: "time_feature",
                    reason: format!("{id} has a discrete observation space"),
                });
            }
        };
        let mut w = Self {
            env,
            last: [0; MJ_N_WARNING],
            fresh: [0; MJ_N_WARNING],
            timed_space,
        };
        w.last = w.counts();
        Ok(w)
    }

    /// Whether observations end with the time feature.
    pub fn has_time_feature(&self) -> bool {
        self.timed_space.is_some()
    }

    fn add_time(&self, obs: &mut Vec<f64>) {
        if self.timed_space.is_some() {
            obs.push(self.env.elapsed() as f64 / self.env.max_steps() as f64);
        }
    }

    /// The watched environment (its observations never hold the time).
    pub fn inner(&self) -> &TimeLimit<BoxedEnv> {
        &self.env
    }

    /// The watched environment, mutably (to set a state).
    pub fn inner_mut(&mut self) -> &mut TimeLimit<BoxedEnv> {
        &mut self.env
    }

    fn counts(&self) -> [i64; MJ_N_WARNING] {
        let mut c = [0; MJ_N_WARNING];
        for (i, w) in self
            .env
            .inner()
            .simulation()
            .data()
            .warning()
            .iter()
            .take(MJ_N_WARNING)
            .enumerate()
        {
            c[i] = i64::from(w.number);
        }
        c
    }

    /// Warnings counted since the last call, by index.
    pub fn take_warnings(&mut self) -> [u64; MJ_N_WARNING] {
        std::mem::take(&mut self.fresh)
    }
}

impl Env for WatchedEnv {
    fn observation_space(&self) -> &Space {
        self.timed_space
            .as_ref()
            .unwrap_or_else(|| self.env.observation_space())
    }
    fn action_space(&self) -> &Space {
        self.env.action_space()
    }
    fn reset(&mut self, seed: Option<u64>) -> red_core::Result<(Vec<f64>, Info)> {
        let (mut obs, info) = self.env.reset(seed)?;
        // mj_resetData clears the counters.
        self.last = self.counts();
        self.add_time(&mut obs);
        Ok((obs, info))
    }
    fn step(&mut self, action: &[f64]) -> red_core::Result<Step> {
        let mut s = self.env.step(action)?;
        self.add_time(&mut s.observation);
        let now = self.counts();
        for i in 0..MJ_N_WARNING {
            if now[i] > self.last[i] {
                self.fresh[i] += (now[i] - self.last[i]) as u64;
            }
        }
        self.last = now;
        Ok(s)
    }
}

/// `3 x bad qvel (mjWARN_BADQVEL), ...`: the warnings that occurred, with
/// their counts.
pub fn describe_warnings(w: &[u64; MJ_N_WARNING]) -> String {
    w.iter()
        .enumerate()
        .filter(|(_, n)| **n > 0)
        .map(|(i, n)| format!("{n} x {}", MJ_WARNING_NAMES[i]))
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mujoco_warnings_are_counted_and_named() {
        let mut env = WatchedEnv::new(EnvId::Hopper).unwrap();
        env.reset(Some(0)).unwrap();
        env.step(&[0.0; 3]).unwrap();
        assert_eq!(env.take_warnings(), [0; MJ_N_WARNING]);
        // A velocity far beyond anything physical: MuJoCo warns and resets.
        env.inner_mut()
            .inner_mut()
            .set_state(&[0.0, 1.25, 0.0, 0.0, 0.0, 0.0], &[1e11; 6])
            .unwrap();
        env.step(&[0.0; 3]).unwrap();
        let w = env.take_warnings();
        assert!(w.iter().sum::<u64>() > 0, "{w:?}");
        let text = describe_warnings(&w);
        assert!(text.contains("mjWARN_BAD"), "{text}");
        // Counted once: the next call starts from zero.
        assert_eq!(env.take_warnings(), [0; MJ_N_WARNING]);
    }

    #[test]
    fn the_time_feature_ends_each_observation_with_the_step_over_the_limit() {
        let mut plain = WatchedEnv::new(EnvId::Reacher).unwrap();
        let mut timed = WatchedEnv::with_time_feature(EnvId::Reacher, true).unwrap();
        assert!(timed.has_time_feature() && !plain.has_time_feature());
        let d = plain.observation_space().dim();
        assert_eq!(timed.observation_space().dim(), d + 1);
        let (o0, _) = plain.reset(Some(3)).unwrap();
        let (t0, _) = timed.reset(Some(3)).unwrap();
        assert_eq!(&t0[..d], &o0[..]);
        assert_eq!(t0[d], 0.0);
        assert!(timed.observation_space().contains(&t0));
        let limit = EnvId::Reacher.max_episode_steps();
        for k in 1..=limit {
            let a = [0.1, -0.2];
            let (p, t) = (plain.step(&a).unwrap(), timed.step(&a).unwrap());
            assert_eq!(&t.observation[..d], &p.observation[..]);
            assert_eq!(t.observation[d], k as f64 / limit as f64);
            assert_eq!(t.truncated, k == limit);
        }
        // a new episode starts the count again
        assert_eq!(timed.reset(Some(4)).unwrap().0[d], 0.0);
    }
}
