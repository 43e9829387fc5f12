//! A training-time end for a car that has stopped driving: the learners'
//! episodes end (terminated) once the speed stays below a threshold for a
//! while, so the terminal heuristic can charge for it. Without it, RED's
//! reward of a slow car is about 0, never negative, and a car standing
//! still until the time limit risks no crash: with the crash penalty and
//! a long discount, standing still can look better to the learner than
//! driving on (docs/results/drive.md, session 41). The checks and the
//! evaluation drive the plain scenario.

use red_core::{Env, Info, Space, Step};
use red_drive::config::DT;
use red_drive::env::INFO_SPEED;
use serde::{Deserialize, Serialize};

/// `info` key set to 1 on the step where [`StallEnd`] ended an episode.
pub const INFO_STALLED: &str = "stalled";

/// When a training episode counts as stalled.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StallRule {
    /// Speeds below this, in km/h, count as stopped.
    pub below_kmh: f64,
    /// The episode ends after this many seconds in a row below it.
    pub seconds: f64,
}

impl StallRule {
    /// Steps in a row below the speed that end an episode (at least 1).
    pub fn steps(&self) -> usize {
        ((self.seconds / DT).round() as usize).max(1)
    }

    /// Checks both numbers are finite and > 0.
    ///
    /// # Errors
    /// A message naming the field.
    pub fn check(&self) -> Result<(), String> {
        for (f, v) in [("below_kmh", self.below_kmh), ("seconds", self.seconds)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{f} must be finite and > 0, got {v}"));
            }
        }
        Ok(())
    }
}

/// Wraps a driving environment: a step after `rule.steps()` steps in a
/// row below `rule.below_kmh` is terminated, with [`INFO_STALLED`] set.
/// Without a rule it passes every step through unchanged.
pub struct StallEnd<E> {
    inner: E,
    below: f64,
    steps: usize,
    slow: usize,
}

impl<E> StallEnd<E> {
    /// `inner` with `rule` (`None`: never ends an episode).
    pub fn new(inner: E, rule: Option<StallRule>) -> Self {
        let (below, steps) = rule.map_or((f64::NEG_INFINITY, usize::MAX), |r| {
            (r.below_kmh / 3.6, r.steps())
        });
        Self {
            inner,
            below,
            steps,
            slow: 0,
        }
    }
}

impl<E: Env> Env for StallEnd<E> {
    fn observation_space(&self) -> &Space {
        self.inner.observation_space()
    }
    fn action_space(&self) -> &Space {
        self.inner.action_space()
    }
    fn reset(&mut self, seed: Option<u64>) -> red_core::Result<(Vec<f64>, Info)> {
        self.slow = 0;
        self.inner.reset(seed)
    }
    fn step(&mut self, action: &[f64]) -> red_core::Result<Step> {
        let mut step = self.inner.step(action)?;
        match step.info.get(INFO_SPEED) {
            Some(v) if v < self.below => self.slow += 1,
            _ => self.slow = 0,
        }
        if self.slow >= self.steps && !step.terminated {
            step.terminated = true;
            step.truncated = false;
            step.info.set(INFO_STALLED, 1.0);
        }
        Ok(step)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use red_drive::{DriveConfig, make_env};

    /// Full brake from the start: the car slows below 30 km/h, and 1 s
    /// later the wrapped episode ends terminated and marked stalled; the
    /// plain one drives on.
    #[test]
    fn a_stopped_car_ends_the_episode_and_a_driving_one_does_not() {
        let rule = StallRule {
            below_kmh: 30.0,
            seconds: 1.0,
        };
        assert_eq!(rule.steps(), (1.0 / DT).round() as usize);
        let config = DriveConfig::default();
        let mut env = StallEnd::new(make_env(&config).unwrap(), Some(rule));
        let mut plain = make_env(&config).unwrap();
        env.reset(Some(3)).unwrap();
        plain.reset(Some(3)).unwrap();
        let brake = [0.0, -1.0];
        let (mut slow, mut ended) = (0, None);
        for t in 0..400 {
            let s = env.step(&brake).unwrap();
            let p = plain.step(&brake).unwrap();
            assert_eq!(p.info.get(INFO_STALLED), None);
            let v = s.info.get(INFO_SPEED).unwrap();
            slow = if v < 30.0 / 3.6 { slow + 1 } else { 0 };
            if s.terminated {
                assert_eq!(s.info.get(INFO_STALLED), Some(1.0), "step {t}");
                assert!(!p.terminated, "the plain scenario goes on at step {t}");
                ended = Some(slow);
                break;
            }
            assert_eq!(s.info.get(INFO_STALLED), None);
        }
        assert_eq!(ended, Some(rule.steps()), "ends after exactly 1 s below");
        // Driving on at speed never stalls.
        env.reset(Some(3)).unwrap();
        for _ in 0..200 {
            let s = env.step(&[0.0, 0.5]).unwrap();
            assert!(s.info.get(INFO_STALLED).is_none());
            if s.terminated || s.truncated {
                break;
            }
        }
        assert!(rule.check().is_ok());
        let bad = StallRule {
            seconds: 0.0,
            ..rule
        };
        assert!(bad.check().unwrap_err().contains("seconds"));
    }
}
