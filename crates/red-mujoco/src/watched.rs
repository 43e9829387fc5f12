//! [`WatchedEnv`]: a task inside its time limit that counts MuJoCo's own
//! warnings, so a run can report them instead of letting them pass.

use red_core::{Env, Info, Space, Step, TimeLimit};

use crate::{BoxedEnv, EnvId, MujocoEnv, Result};

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
}

impl WatchedEnv {
    /// `id` with its default config and time limit.
    ///
    /// # Errors
    /// The model cannot be loaded (run `scripts/setup-mujoco.sh`).
    pub fn new(id: EnvId) -> Result<Self> {
        let env = id.make()?;
        let mut w = Self {
            env,
            last: [0; MJ_N_WARNING],
            fresh: [0; MJ_N_WARNING],
        };
        w.last = w.counts();
        Ok(w)
    }

    /// The watched environment.
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
        self.env.observation_space()
    }
    fn action_space(&self) -> &Space {
        self.env.action_space()
    }
    fn reset(&mut self, seed: Option<u64>) -> red_core::Result<(Vec<f64>, Info)> {
        let r = self.env.reset(seed)?;
        // mj_resetData clears the counters.
        self.last = self.counts();
        Ok(r)
    }
    fn step(&mut self, action: &[f64]) -> red_core::Result<Step> {
        let s = self.env.step(action)?;
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
}
