//! A fixed-capacity replay buffer of transitions, stored as flat `f64` rows.
//!
//! The stored reward is the IMITATION reward, written by the learner from its
//! reward model, never the environment's. When an adaptive reward model
//! (GAIL, GMMIL) changes, the learner relabels every stored transition at
//! once with [`ReplayBuffer::relabel`], so no minibatch sees a stale reward,
//! and a fixed model is evaluated once per transition rather than once per
//! draw.

use ndarray::Array2;
use rand::{Rng, RngExt};
use serde::{Deserialize, Serialize};

use crate::{Error, Result};

/// A minibatch drawn from a [`ReplayBuffer`]: rows are transitions.
#[derive(Debug, Clone, PartialEq)]
pub struct Batch {
    /// States `(b, obs_dim)`.
    pub states: Array2<f64>,
    /// Actions `(b, act_dim)`.
    pub actions: Array2<f64>,
    /// Next states `(b, obs_dim)`.
    pub next_states: Array2<f64>,
    /// Imitation rewards, `b` entries.
    pub rewards: Vec<f64>,
    /// Whether the next state is terminal (no bootstrapping), `b` entries.
    pub terminated: Vec<bool>,
}

/// Ring buffer of `(s, a, r, s', terminated)` transitions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReplayBuffer {
    capacity: usize,
    obs_dim: usize,
    act_dim: usize,
    states: Vec<f64>,
    actions: Vec<f64>,
    next_states: Vec<f64>,
    rewards: Vec<f64>,
    terminated: Vec<bool>,
    len: usize,
    next: usize,
}

impl ReplayBuffer {
    /// An empty buffer holding up to `capacity` transitions.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] if `capacity` or a dimension is 0.
    pub fn new(capacity: usize, obs_dim: usize, act_dim: usize) -> Result<Self> {
        for (field, v) in [
            ("capacity", capacity),
            ("obs_dim", obs_dim),
            ("act_dim", act_dim),
        ] {
            if v == 0 {
                return Err(Error::InvalidConfig {
                    field: field.into(),
                    reason: "must be at least 1".into(),
                });
            }
        }
        Ok(Self {
            capacity,
            obs_dim,
            act_dim,
            states: vec![0.0; capacity * obs_dim],
            actions: vec![0.0; capacity * act_dim],
            next_states: vec![0.0; capacity * obs_dim],
            rewards: vec![0.0; capacity],
            terminated: vec![false; capacity],
            len: 0,
            next: 0,
        })
    }

    /// Number of transitions held.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the buffer is empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Adds a transition, overwriting the oldest when full.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] if a vector has the wrong length.
    pub fn push(
        &mut self,
        state: &[f64],
        action: &[f64],
        reward: f64,
        next_state: &[f64],
        terminated: bool,
    ) -> Result<()> {
        for (what, got, want) in [
            ("state", state.len(), self.obs_dim),
            ("action", action.len(), self.act_dim),
            ("next_state", next_state.len(), self.obs_dim),
        ] {
            if got != want {
                return Err(Error::ShapeMismatch {
                    what: what.into(),
                    expected: format!("{want} numbers"),
                    got: format!("{got}"),
                });
            }
        }
        let i = self.next;
        self.states[i * self.obs_dim..(i + 1) * self.obs_dim].copy_from_slice(state);
        self.actions[i * self.act_dim..(i + 1) * self.act_dim].copy_from_slice(action);
        self.next_states[i * self.obs_dim..(i + 1) * self.obs_dim].copy_from_slice(next_state);
        self.rewards[i] = reward;
        self.terminated[i] = terminated;
        self.next = (self.next + 1) % self.capacity;
        self.len = (self.len + 1).min(self.capacity);
        Ok(())
    }

    /// Draws `batch` transitions uniformly with replacement.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] if the buffer is empty or `batch` is 0.
    pub fn sample<R: Rng + ?Sized>(&self, batch: usize, rng: &mut R) -> Result<Batch> {
        if self.len == 0 || batch == 0 {
            return Err(Error::InvalidConfig {
                field: "batch".into(),
                reason: format!("cannot draw {batch} transitions from {} held", self.len),
            });
        }
        let (o, a) = (self.obs_dim, self.act_dim);
        let mut out = Batch {
            states: Array2::zeros((batch, o)),
            actions: Array2::zeros((batch, a)),
            next_states: Array2::zeros((batch, o)),
            rewards: vec![0.0; batch],
            terminated: vec![false; batch],
        };
        for r in 0..batch {
            let i = rng.random_range(0..self.len);
            for j in 0..o {
                out.states[[r, j]] = self.states[i * o + j];
                out.next_states[[r, j]] = self.next_states[i * o + j];
            }
            for j in 0..a {
                out.actions[[r, j]] = self.actions[i * a + j];
            }
            out.rewards[r] = self.rewards[i];
            out.terminated[r] = self.terminated[i];
        }
        Ok(out)
    }

    /// Recomputes every stored reward with `f`, which maps a batch of states
    /// `(len, obs_dim)` and actions `(len, act_dim)` to `len` rewards.
    ///
    /// # Errors
    /// `f`'s errors, or [`Error::ShapeMismatch`] if it returns a wrong count.
    pub fn relabel(
        &mut self,
        f: impl FnOnce(Array2<f64>, Array2<f64>) -> Result<Vec<f64>>,
    ) -> Result<()> {
        let n = self.len;
        let s = Array2::from_shape_vec((n, self.obs_dim), self.states[..n * self.obs_dim].to_vec())
            .map_err(|e| Error::ShapeMismatch {
                what: "stored states".into(),
                expected: format!("({n}, {})", self.obs_dim),
                got: e.to_string(),
            })?;
        let a =
            Array2::from_shape_vec((n, self.act_dim), self.actions[..n * self.act_dim].to_vec())
                .map_err(|e| Error::ShapeMismatch {
                    what: "stored actions".into(),
                    expected: format!("({n}, {})", self.act_dim),
                    got: e.to_string(),
                })?;
        let r = f(s, a)?;
        if r.len() != n {
            return Err(Error::ShapeMismatch {
                what: "relabelled rewards".into(),
                expected: format!("{n}"),
                got: format!("{}", r.len()),
            });
        }
        self.rewards[..n].copy_from_slice(&r);
        Ok(())
    }

    /// The `k` most recent transitions' states and actions, oldest first:
    /// `((k, obs_dim), (k, act_dim))` with `k = min(k, len)`.
    pub fn recent(&self, k: usize) -> (Array2<f64>, Array2<f64>) {
        let k = k.min(self.len);
        let (o, a) = (self.obs_dim, self.act_dim);
        let mut s = Array2::zeros((k, o));
        let mut u = Array2::zeros((k, a));
        for r in 0..k {
            let i = (self.next + self.capacity - k + r) % self.capacity;
            for j in 0..o {
                s[[r, j]] = self.states[i * o + j];
            }
            for j in 0..a {
                u[[r, j]] = self.actions[i * a + j];
            }
        }
        (s, u)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn ring_overwrites_oldest_and_recent_is_ordered() {
        let mut b = ReplayBuffer::new(3, 1, 1).unwrap();
        for i in 0..5 {
            let x = i as f64;
            b.push(&[x], &[x], 10.0 * x, &[x + 1.0], i == 4).unwrap();
        }
        assert_eq!(b.len(), 3);
        let (s, a) = b.recent(3);
        assert_eq!(s.column(0).to_vec(), vec![2.0, 3.0, 4.0]);
        assert_eq!(a.column(0).to_vec(), vec![2.0, 3.0, 4.0]);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
        let batch = b.sample(100, &mut rng).unwrap();
        for r in 0..100 {
            let s = batch.states[[r, 0]];
            assert!((2.0..=4.0).contains(&s));
            assert_eq!(batch.next_states[[r, 0]], s + 1.0);
            assert_eq!(batch.terminated[r], s == 4.0);
            assert_eq!(batch.rewards[r], 10.0 * s);
        }
        b.relabel(|s, a| {
            Ok(s.column(0)
                .iter()
                .zip(a.column(0))
                .map(|(x, y)| x + y)
                .collect())
        })
        .unwrap();
        let batch = b.sample(50, &mut rng).unwrap();
        for r in 0..50 {
            assert_eq!(batch.rewards[r], 2.0 * batch.states[[r, 0]]);
        }
        assert!(b.relabel(|_, _| Ok(vec![0.0])).is_err());
    }

    #[test]
    fn rejects_wrong_shapes_and_empty_draws() {
        let mut b = ReplayBuffer::new(2, 2, 1).unwrap();
        assert!(b.push(&[0.0], &[0.0], 0.0, &[0.0, 0.0], false).is_err());
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
        assert!(b.sample(4, &mut rng).is_err());
        assert!(ReplayBuffer::new(0, 1, 1).is_err());
    }
}
