//! The one replay buffer of the learners (DQN, SVG(1)-ER, SAC): a
//! fixed-capacity ring of transitions stored as flat `f64` rows, growing up
//! to its capacity and then overwriting the oldest.
//!
//! The stored reward is the IMITATION reward, written by the learner from its
//! reward model, never the environment's. Next to it the buffer keeps the
//! terminal heuristic's adjustment (`bonus`, added with
//! [`ReplayBuffer::adjust_last_reward`]) apart, so an adaptive reward can be
//! recomputed without losing it: either for every stored transition at once
//! with [`ReplayBuffer::relabel`] (DQN), or per minibatch with
//! [`Batch::set_rewards`] (SVG(1)-ER, SAC). A buffer made
//! [`ReplayBuffer::with_behaviour_logp`] also keeps each action's
//! log-probability under the policy that took it (SVG(1)-ER's importance
//! weights).
//!
//! Draws are uniform with replacement, one `random_range(0..len)` a row, so
//! the same generator state gives the same indices in every learner.
//!
//! Serialised form: the fields below with flat rows. Older checkpoints still
//! load: SVG(1)-ER's buffer stored one `Vec` a row and no dimensions, SAC's
//! flat rows without dimensions, and DQN's a preallocated ring with `len`.

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
    /// Stored (imitation) rewards, the terminal adjustment included.
    pub rewards: Vec<f64>,
    /// The terminal adjustment alone (0 except at an episode's last step).
    pub bonus: Vec<f64>,
    /// Whether the next state is terminal (no bootstrapping), `b` entries.
    pub terminated: Vec<bool>,
    /// Log-probability of each action under the behaviour policy; empty
    /// unless the buffer keeps them.
    pub behaviour_logp: Vec<f64>,
}

impl Batch {
    /// Replaces the rewards by freshly computed imitation rewards `r`, one a
    /// row, keeping the terminal adjustment: `rewards[i] = r[i] + bonus[i]`.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] if `r` has not one entry a row.
    pub fn set_rewards(&mut self, r: &[f64]) -> Result<()> {
        if r.len() != self.rewards.len() {
            return Err(Error::ShapeMismatch {
                what: "minibatch rewards".into(),
                expected: format!("{}", self.rewards.len()),
                got: format!("{}", r.len()),
            });
        }
        for (i, ri) in r.iter().enumerate() {
            self.rewards[i] = ri + self.bonus[i];
        }
        Ok(())
    }
}

/// What an `n`-step value target needs beyond a [`Batch`] row: see
/// [`ReplayBuffer::sample_with_tail`]. The target of row `i` is
/// `rewards[i] + later_rewards[i] + discount[i] * V(boot_states[i])`.
#[derive(Debug, Clone, PartialEq)]
pub struct NStepTail {
    /// `sum_(k=1..m-1) gamma^k r_(i+k)` over the `m - 1` later steps
    /// followed (0 when none).
    pub later_rewards: Vec<f64>,
    /// The next state of the chain's last row `(b, obs_dim)`.
    pub boot_states: Array2<f64>,
    /// `gamma^m`, or 0 when the chain ended in a terminated row.
    pub discount: Vec<f64>,
}

/// Ring buffer of `(s, a, r, s', terminated)` transitions; see the module
/// documentation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "StoredReplay")]
pub struct ReplayBuffer {
    capacity: usize,
    obs_dim: usize,
    act_dim: usize,
    states: Vec<f64>,
    actions: Vec<f64>,
    next_states: Vec<f64>,
    rewards: Vec<f64>,
    bonus: Vec<f64>,
    terminated: Vec<bool>,
    #[serde(skip_serializing_if = "Option::is_none")]
    behaviour_logp: Option<Vec<f64>>,
    next: usize,
}

/// Rows as stored: flat, or one `Vec` a row (SVG(1)-ER before the buffers
/// were one).
#[derive(Deserialize)]
#[serde(untagged)]
enum StoredRows {
    Flat(Vec<f64>),
    Nested(Vec<Vec<f64>>),
}

impl StoredRows {
    /// The flat rows and, when they say it, the row width.
    fn flatten(self) -> (Vec<f64>, Option<usize>) {
        match self {
            StoredRows::Flat(v) => (v, None),
            StoredRows::Nested(rows) => {
                let width = rows.first().map(Vec::len);
                (rows.concat(), width)
            }
        }
    }
}

/// Every serialised form of [`ReplayBuffer`], this one and older ones.
#[derive(Deserialize)]
struct StoredReplay {
    capacity: usize,
    #[serde(default)]
    obs_dim: Option<usize>,
    #[serde(default)]
    act_dim: Option<usize>,
    states: StoredRows,
    actions: StoredRows,
    next_states: StoredRows,
    rewards: Vec<f64>,
    #[serde(default)]
    bonus: Option<Vec<f64>>,
    terminated: Vec<bool>,
    #[serde(default)]
    behaviour_logp: Option<Vec<f64>>,
    /// DQN's older preallocated ring: how many rows are filled.
    #[serde(default)]
    len: Option<usize>,
    next: usize,
}

impl TryFrom<StoredReplay> for ReplayBuffer {
    type Error = String;

    fn try_from(s: StoredReplay) -> std::result::Result<Self, String> {
        let (mut states, sw) = s.states.flatten();
        let (mut actions, aw) = s.actions.flatten();
        let (mut next_states, _) = s.next_states.flatten();
        let mut rewards = s.rewards;
        let mut terminated = s.terminated;
        let n = s.len.unwrap_or(rewards.len());
        let width = |given: Option<usize>, nested: Option<usize>, flat: usize| {
            given.or(nested).unwrap_or(if rewards.is_empty() {
                0
            } else {
                flat / rewards.len()
            })
        };
        let obs_dim = width(s.obs_dim, sw, states.len());
        let act_dim = width(s.act_dim, aw, actions.len());
        states.truncate(n * obs_dim);
        next_states.truncate(n * obs_dim);
        actions.truncate(n * act_dim);
        rewards.truncate(n);
        terminated.truncate(n);
        let bonus = s.bonus.unwrap_or_else(|| vec![0.0; n]);
        let ok = s.capacity > 0
            && n <= s.capacity
            && s.next < s.capacity
            && states.len() == n * obs_dim
            && next_states.len() == n * obs_dim
            && actions.len() == n * act_dim
            && rewards.len() == n
            && terminated.len() == n
            && bonus.len() == n
            && s.behaviour_logp.as_ref().is_none_or(|l| l.len() == n);
        if !ok {
            return Err(format!(
                "replay buffer: inconsistent stored rows ({n} rewards, capacity {})",
                s.capacity
            ));
        }
        Ok(Self {
            capacity: s.capacity,
            obs_dim,
            act_dim,
            states,
            actions,
            next_states,
            rewards,
            bonus,
            terminated,
            behaviour_logp: s.behaviour_logp,
            next: s.next,
        })
    }
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
            states: Vec::new(),
            actions: Vec::new(),
            next_states: Vec::new(),
            rewards: Vec::new(),
            bonus: Vec::new(),
            terminated: Vec::new(),
            behaviour_logp: None,
            next: 0,
        })
    }

    /// The same buffer keeping each action's behaviour log-probability,
    /// given to [`ReplayBuffer::push_with_logp`].
    pub fn with_behaviour_logp(mut self) -> Self {
        self.behaviour_logp = Some(Vec::new());
        self
    }

    /// Number of transitions held.
    pub fn len(&self) -> usize {
        self.rewards.len()
    }

    /// Whether the buffer is empty.
    pub fn is_empty(&self) -> bool {
        self.rewards.is_empty()
    }

    /// Adds a transition, overwriting the oldest when full.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] if a vector has the wrong length;
    /// [`Error::InvalidConfig`] if the buffer keeps behaviour
    /// log-probabilities (use [`ReplayBuffer::push_with_logp`]).
    pub fn push(
        &mut self,
        state: &[f64],
        action: &[f64],
        reward: f64,
        next_state: &[f64],
        terminated: bool,
    ) -> Result<()> {
        self.push_row(state, action, reward, next_state, terminated, None)
    }

    /// Adds a transition with the log-probability of its action under the
    /// policy that took it.
    ///
    /// # Errors
    /// As [`ReplayBuffer::push`]; [`Error::InvalidConfig`] if the buffer was
    /// not made [`ReplayBuffer::with_behaviour_logp`].
    pub fn push_with_logp(
        &mut self,
        state: &[f64],
        action: &[f64],
        behaviour_logp: f64,
        reward: f64,
        next_state: &[f64],
        terminated: bool,
    ) -> Result<()> {
        self.push_row(
            state,
            action,
            reward,
            next_state,
            terminated,
            Some(behaviour_logp),
        )
    }

    fn push_row(
        &mut self,
        state: &[f64],
        action: &[f64],
        reward: f64,
        next_state: &[f64],
        terminated: bool,
        logp: Option<f64>,
    ) -> Result<()> {
        if self.is_empty() && self.obs_dim == 0 && self.act_dim == 0 {
            // An empty buffer loaded from a form without dimensions.
            self.obs_dim = state.len();
            self.act_dim = action.len();
        }
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
        if self.behaviour_logp.is_some() != logp.is_some() {
            return Err(Error::InvalidConfig {
                field: "behaviour_logp".into(),
                reason: "give it exactly when the buffer keeps it".into(),
            });
        }
        let (o, a) = (self.obs_dim, self.act_dim);
        if self.len() < self.capacity {
            self.states.extend_from_slice(state);
            self.actions.extend_from_slice(action);
            self.next_states.extend_from_slice(next_state);
            self.rewards.push(reward);
            self.bonus.push(0.0);
            self.terminated.push(terminated);
            if let (Some(l), Some(v)) = (self.behaviour_logp.as_mut(), logp) {
                l.push(v);
            }
        } else {
            let i = self.next;
            self.states[i * o..(i + 1) * o].copy_from_slice(state);
            self.actions[i * a..(i + 1) * a].copy_from_slice(action);
            self.next_states[i * o..(i + 1) * o].copy_from_slice(next_state);
            self.rewards[i] = reward;
            self.bonus[i] = 0.0;
            self.terminated[i] = terminated;
            if let (Some(l), Some(v)) = (self.behaviour_logp.as_mut(), logp) {
                l[i] = v;
            }
        }
        self.next = (self.next + 1) % self.capacity;
        Ok(())
    }

    /// Adds `delta` to the stored reward of the most recent transition and
    /// to its terminal adjustment (the terminal reward heuristic at an
    /// episode's end). Does nothing on an empty buffer.
    pub fn adjust_last_reward(&mut self, delta: f64) {
        if self.is_empty() {
            return;
        }
        let i = (self.next + self.capacity - 1) % self.capacity;
        self.rewards[i] += delta;
        self.bonus[i] += delta;
    }

    /// Draws `batch` transitions uniformly with replacement.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] if the buffer is empty or `batch` is 0.
    pub fn sample<R: Rng + ?Sized>(&self, batch: usize, rng: &mut R) -> Result<Batch> {
        Ok(self.rows(&self.draw_rows(batch, rng)?))
    }

    /// `batch` row indices drawn uniformly with replacement, one
    /// `random_range(0..len)` each.
    fn draw_rows<R: Rng + ?Sized>(&self, batch: usize, rng: &mut R) -> Result<Vec<usize>> {
        let len = self.len();
        if len == 0 || batch == 0 {
            return Err(Error::InvalidConfig {
                field: "batch_size".into(),
                reason: format!("cannot draw {batch} transitions from {len} held"),
            });
        }
        Ok((0..batch).map(|_| rng.random_range(0..len)).collect())
    }

    /// The stored rows `rows` as a [`Batch`], in that order.
    fn rows(&self, rows: &[usize]) -> Batch {
        let batch = rows.len();
        let (o, a) = (self.obs_dim, self.act_dim);
        let mut out = Batch {
            states: Array2::zeros((batch, o)),
            actions: Array2::zeros((batch, a)),
            next_states: Array2::zeros((batch, o)),
            rewards: Vec::with_capacity(batch),
            bonus: Vec::with_capacity(batch),
            terminated: Vec::with_capacity(batch),
            behaviour_logp: Vec::new(),
        };
        for (r, &i) in rows.iter().enumerate() {
            for j in 0..o {
                out.states[[r, j]] = self.states[i * o + j];
                out.next_states[[r, j]] = self.next_states[i * o + j];
            }
            for j in 0..a {
                out.actions[[r, j]] = self.actions[i * a + j];
            }
            out.rewards.push(self.rewards[i]);
            out.bonus.push(self.bonus[i]);
            out.terminated.push(self.terminated[i]);
            if let Some(l) = &self.behaviour_logp {
                out.behaviour_logp.push(l[i]);
            }
        }
        out
    }

    /// Draws `batch` transitions exactly as [`ReplayBuffer::sample`] does
    /// (the same generator calls, so the same rows) and, for each, follows
    /// its episode for up to `n` steps in storage order: the
    /// [`NStepTail`] of an `n`-step value target `r_i + sum_(k=1..m-1)
    /// gamma^k r_(i+k) + gamma^m V(s'_(i+m-1))`. A row continues into the
    /// next stored row when it did not terminate, the next row is not the
    /// oldest one (the ring's seam) nor beyond the newest, and the next
    /// row's state equals this row's next state number for number (a reset
    /// starts elsewhere, so a truncated episode stops the chain there and
    /// bootstraps). A chain that reaches a terminated row has discount 0.
    /// The later rewards are the stored ones (imitation reward plus the
    /// terminal adjustment). `n = 1` gives zero later rewards, the row's
    /// own next state and discount `gamma` (0 if terminated).
    ///
    /// # Errors
    /// As [`ReplayBuffer::sample`]; [`Error::InvalidConfig`] if `n` is 0.
    pub fn sample_with_tail<R: Rng + ?Sized>(
        &self,
        batch: usize,
        n: usize,
        gamma: f64,
        rng: &mut R,
    ) -> Result<(Batch, NStepTail)> {
        if n == 0 {
            return Err(Error::InvalidConfig {
                field: "n".into(),
                reason: "an n-step target needs n >= 1".into(),
            });
        }
        let rows = self.draw_rows(batch, rng)?;
        let (len, o) = (self.len(), self.obs_dim);
        let full = len == self.capacity;
        let mut tail = NStepTail {
            later_rewards: Vec::with_capacity(batch),
            boot_states: Array2::zeros((batch, o)),
            discount: Vec::with_capacity(batch),
        };
        let newest = (self.next + self.capacity - 1) % self.capacity;
        for (r, &i) in rows.iter().enumerate() {
            let (mut last, mut later, mut disc) = (i, 0.0, gamma);
            for _ in 1..n {
                if self.terminated[last] || last == newest {
                    break;
                }
                let j = if full {
                    (last + 1) % self.capacity
                } else {
                    last + 1
                };
                if j >= len
                    || self.next_states[last * o..(last + 1) * o] != self.states[j * o..(j + 1) * o]
                {
                    break;
                }
                later += disc * self.rewards[j];
                disc *= gamma;
                last = j;
            }
            if self.terminated[last] {
                disc = 0.0;
            }
            for k in 0..o {
                tail.boot_states[[r, k]] = self.next_states[last * o + k];
            }
            tail.later_rewards.push(later);
            tail.discount.push(disc);
        }
        Ok((self.rows(&rows), tail))
    }

    /// Recomputes every stored reward with `f`, which maps a batch of states
    /// `(len, obs_dim)` and actions `(len, act_dim)` to `len` rewards; the
    /// terminal adjustment is kept (added to `f`'s reward).
    ///
    /// # Errors
    /// `f`'s errors, or [`Error::ShapeMismatch`] if it returns a wrong count.
    pub fn relabel(
        &mut self,
        f: impl FnOnce(Array2<f64>, Array2<f64>) -> Result<Vec<f64>>,
    ) -> Result<()> {
        let n = self.len();
        let s = Array2::from_shape_vec((n, self.obs_dim), self.states.clone()).map_err(|e| {
            Error::ShapeMismatch {
                what: "stored states".into(),
                expected: format!("({n}, {})", self.obs_dim),
                got: e.to_string(),
            }
        })?;
        let a = Array2::from_shape_vec((n, self.act_dim), self.actions.clone()).map_err(|e| {
            Error::ShapeMismatch {
                what: "stored actions".into(),
                expected: format!("({n}, {})", self.act_dim),
                got: e.to_string(),
            }
        })?;
        let r = f(s, a)?;
        if r.len() != n {
            return Err(Error::ShapeMismatch {
                what: "relabelled rewards".into(),
                expected: format!("{n}"),
                got: format!("{}", r.len()),
            });
        }
        for (i, ri) in r.iter().enumerate() {
            self.rewards[i] = ri + self.bonus[i];
        }
        Ok(())
    }

    /// The `k` most recent transitions' states and actions, oldest first:
    /// `((k, obs_dim), (k, act_dim))` with `k = min(k, len)`.
    pub fn recent(&self, k: usize) -> (Array2<f64>, Array2<f64>) {
        let len = self.len();
        let k = k.min(len);
        let (o, a) = (self.obs_dim, self.act_dim);
        let mut s = Array2::zeros((k, o));
        let mut u = Array2::zeros((k, a));
        for r in 0..k {
            let i = (self.next + len - k + r) % len;
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

    /// Pushes an episode of states `x0, x0 + 1, ...` (one number each),
    /// rewards `r`, the last step terminated or not.
    fn push_episode(b: &mut ReplayBuffer, x0: f64, r: &[f64], terminated: bool) {
        for (k, &rk) in r.iter().enumerate() {
            let x = x0 + k as f64;
            let last = k + 1 == r.len();
            b.push(&[x], &[0.0], rk, &[x + 1.0], last && terminated)
                .unwrap();
        }
    }

    /// Every drawn row's tail against `expect(state) -> (later, discount,
    /// boot state)`.
    fn check_tails(b: &ReplayBuffer, n: usize, expect: impl Fn(f64) -> (f64, f64, f64)) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let (batch, tail) = b.sample_with_tail(300, n, 0.5, &mut rng).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        assert_eq!(
            batch,
            b.sample(300, &mut rng).unwrap(),
            "the same rows as sample"
        );
        let mut seen = std::collections::BTreeSet::new();
        for r in 0..300 {
            let x = batch.states[[r, 0]];
            seen.insert(x as i64);
            let (later, disc, boot) = expect(x);
            assert!(
                (tail.later_rewards[r] - later).abs() < 1e-12,
                "later at {x}"
            );
            assert!((tail.discount[r] - disc).abs() < 1e-12, "discount at {x}");
            assert_eq!(tail.boot_states[[r, 0]], boot, "boot state at {x}");
        }
        assert_eq!(seen.len(), b.len(), "every row drawn");
    }

    #[test]
    fn n_step_tails_follow_the_episode_and_stop_at_its_end() {
        let mut b = ReplayBuffer::new(100, 1, 1).unwrap();
        // Episode A: states 0..4, rewards 1..5, terminated at state 4.
        push_episode(&mut b, 0.0, &[1.0, 2.0, 3.0, 4.0, 5.0], true);
        // Episode B: states 10, 11, truncated (not terminated).
        push_episode(&mut b, 10.0, &[7.0, 8.0], false);
        // Episode C: states 20, 21, still running (the newest row is 21).
        push_episode(&mut b, 20.0, &[9.0, 6.0], false);
        check_tails(&b, 1, |x| {
            let disc = if x == 4.0 { 0.0 } else { 0.5 };
            (0.0, disc, x + 1.0)
        });
        check_tails(&b, 3, |x| match x as i64 {
            0 => (0.5 * 2.0 + 0.25 * 3.0, 0.125, 3.0),
            1 => (0.5 * 3.0 + 0.25 * 4.0, 0.125, 4.0),
            2 => (0.5 * 4.0 + 0.25 * 5.0, 0.0, 5.0),
            3 => (0.5 * 5.0, 0.0, 5.0),
            4 => (0.0, 0.0, 5.0),
            10 => (0.5 * 8.0, 0.25, 12.0),
            // B was cut by time: its chain stops and bootstraps.
            11 => (0.0, 0.5, 12.0),
            20 => (0.5 * 6.0, 0.25, 22.0),
            21 => (0.0, 0.5, 22.0),
            _ => unreachable!(),
        });
    }

    #[test]
    fn n_step_tails_do_not_cross_the_rings_seam() {
        // Capacity 4: an episode of 6 steps leaves states 2, 3, 4, 5 with
        // 4 and 5 stored in slots 0 and 1, 2 and 3 in slots 2 and 3.
        let mut b = ReplayBuffer::new(4, 1, 1).unwrap();
        push_episode(&mut b, 0.0, &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0], false);
        check_tails(&b, 4, |x| match x as i64 {
            2 => (0.5 * 4.0 + 0.25 * 5.0 + 0.125 * 6.0, 0.0625, 6.0),
            3 => (0.5 * 5.0 + 0.25 * 6.0, 0.125, 6.0),
            4 => (0.5 * 6.0, 0.25, 6.0),
            5 => (0.0, 0.5, 6.0),
            _ => unreachable!(),
        });
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
        assert!(b.sample_with_tail(4, 0, 0.5, &mut rng).is_err());
    }

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

    /// A buffer of capacity 3 after pushing 4 transitions of one state
    /// number and one action number, with a bonus on the last one.
    fn filled(logp: bool) -> ReplayBuffer {
        let mut b = ReplayBuffer::new(3, 1, 1).unwrap();
        if logp {
            b = b.with_behaviour_logp();
        }
        for i in 0..4 {
            let x = i as f64;
            if logp {
                b.push_with_logp(&[x], &[-x], -0.5 * x, x, &[x + 1.0], false)
                    .unwrap();
            } else {
                b.push(&[x], &[-x], x, &[x + 1.0], false).unwrap();
            }
        }
        b.adjust_last_reward(0.25);
        b
    }

    #[test]
    fn bonus_survives_relabelling_and_logp_is_kept() {
        let mut b = filled(true);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let batch = b.sample(40, &mut rng).unwrap();
        for r in 0..40 {
            let x = batch.states[[r, 0]];
            assert_eq!(batch.behaviour_logp[r], -0.5 * x);
            assert_eq!(batch.bonus[r], if x == 3.0 { 0.25 } else { 0.0 });
            assert_eq!(batch.rewards[r], x + batch.bonus[r]);
        }
        let mut batch2 = batch.clone();
        batch2.set_rewards(&vec![1.0; 40]).unwrap();
        for r in 0..40 {
            assert_eq!(batch2.rewards[r], 1.0 + batch.bonus[r]);
        }
        assert!(batch2.set_rewards(&[1.0]).is_err());
        b.relabel(|s, _| Ok(vec![0.0; s.nrows()])).unwrap();
        let batch = b.sample(40, &mut rng).unwrap();
        for r in 0..40 {
            assert_eq!(batch.rewards[r], batch.bonus[r]);
        }
        // A buffer that keeps log-probabilities wants them, and only it.
        assert!(b.push(&[0.0], &[0.0], 0.0, &[0.0], false).is_err());
        let mut plain = filled(false);
        assert!(
            plain
                .push_with_logp(&[0.0], &[0.0], 0.0, 0.0, &[0.0], false)
                .is_err()
        );
        assert!(plain.sample(5, &mut rng).unwrap().behaviour_logp.is_empty());
    }

    #[test]
    fn serialised_form_round_trips_and_draws_the_same_rows() {
        for logp in [false, true] {
            let b = filled(logp);
            let text = serde_json::to_string(&b).unwrap();
            let back: ReplayBuffer = serde_json::from_str(&text).unwrap();
            assert_eq!(back, b);
        }
    }

    /// The forms the three buffers had before they were one still load,
    /// and equal the buffer that the same pushes make today.
    #[test]
    fn older_serialised_forms_load() {
        // SVG(1)-ER: one Vec a row, no dimensions, log-probabilities.
        let svg = r#"{"capacity":3,"states":[[3.0],[1.0],[2.0]],"actions":[[-3.0],[-1.0],[-2.0]],
            "next_states":[[4.0],[2.0],[3.0]],"rewards":[3.25,1.0,2.0],"bonus":[0.25,0.0,0.0],
            "terminated":[false,false,false],"behaviour_logp":[-1.5,-0.5,-1.0],"next":1}"#;
        let b: ReplayBuffer = serde_json::from_str(svg).unwrap();
        assert_eq!(b, filled(true));
        // SAC: flat rows, no dimensions, no log-probabilities.
        let sac = r#"{"capacity":3,"states":[3.0,1.0,2.0],"actions":[-3.0,-1.0,-2.0],
            "next_states":[4.0,2.0,3.0],"rewards":[3.25,1.0,2.0],"bonus":[0.25,0.0,0.0],
            "terminated":[false,false,false],"next":1}"#;
        let b: ReplayBuffer = serde_json::from_str(sac).unwrap();
        assert_eq!(b, filled(false));
        // DQN: a preallocated ring with `len`, no bonus.
        let dqn = r#"{"capacity":3,"obs_dim":1,"act_dim":1,"states":[0.0,1.0,0.0],
            "actions":[0.0,-1.0,0.0],"next_states":[1.0,2.0,0.0],"rewards":[0.0,1.0,0.0],
            "terminated":[false,false,false],"len":2,"next":2}"#;
        let b: ReplayBuffer = serde_json::from_str(dqn).unwrap();
        let mut want = ReplayBuffer::new(3, 1, 1).unwrap();
        want.push(&[0.0], &[0.0], 0.0, &[1.0], false).unwrap();
        want.push(&[1.0], &[-1.0], 1.0, &[2.0], false).unwrap();
        assert_eq!(b, want);
        // An empty old SVG(1)-ER buffer takes its dimensions from the first
        // push.
        let empty = r#"{"capacity":3,"states":[],"actions":[],"next_states":[],"rewards":[],
            "bonus":[],"terminated":[],"behaviour_logp":[],"next":0}"#;
        let mut b: ReplayBuffer = serde_json::from_str(empty).unwrap();
        b.push_with_logp(&[1.0, 2.0], &[0.5], -1.0, 0.0, &[2.0, 3.0], true)
            .unwrap();
        assert!(
            b.push_with_logp(&[1.0], &[0.5], -1.0, 0.0, &[2.0], true)
                .is_err()
        );
        // Inconsistent rows are refused.
        let bad = r#"{"capacity":3,"states":[1.0],"actions":[1.0],"next_states":[],"rewards":[1.0],
            "terminated":[false],"next":1}"#;
        assert!(serde_json::from_str::<ReplayBuffer>(bad).is_err());
    }
}
