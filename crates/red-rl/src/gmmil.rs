//! GMMIL's reward (Kim & Park 2018): minimise the maximum mean discrepancy
//! between the policy's and the expert's state-action distributions.
//!
//! The kernel is a sum of two Gaussians, `k(x, y) = exp(-|x-y|^2 / h1) +
//! exp(-|x-y|^2 / h2)`. As in the RED release's GMMIL baseline, `h1` is the
//! median squared distance between expert pairs and `h2` the median squared
//! distance between the FIRST policy batch and the expert pairs, both then
//! frozen. (The release describes `h2` as a median distance; we use squared
//! distances for both so that both are in the unit of `|x-y|^2`.)
//!
//! The reward of a pair is the MMD witness function
//! `mean_j k(x, e_j) - mean_j k(x, p_j)` over the expert pairs `e` and the
//! latest policy batch `p`, shifted by a constant so that its minimum over
//! that policy batch is 0. The shift is fixed at each update, so a reward
//! does not depend on which batch it is computed in. Before the first
//! update the policy term and the shift are absent and only `h1` is used.
//! Each reward costs `O((n_expert + n_policy) * dim)`.

use ndarray::{Array1, Array2, ArrayView1, ArrayView2};
use serde::{Deserialize, Serialize};

use red_core::RewardModel;

use crate::gail::{concat_pairs, into_core};
use crate::{Error, Result};
use red_core::DifferentiableReward;

/// Settings of [`Gmmil`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GmmilConfig {
    /// Fixed bandwidths `(h1, h2)`; `None` uses the release's median rule.
    pub bandwidths: Option<(f64, f64)>,
    /// At most this many rows of each set enter a median (an evenly spaced
    /// subset beyond it), bounding the median rule's cost.
    pub median_sample: usize,
}

impl Default for GmmilConfig {
    fn default() -> Self {
        Self {
            bandwidths: None,
            median_sample: 500,
        }
    }
}

impl GmmilConfig {
    /// Checks every field.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the first bad field.
    pub fn validate(&self) -> Result<()> {
        if let Some((h1, h2)) = self.bandwidths
            && !(h1.is_finite() && h1 > 0.0 && h2.is_finite() && h2 > 0.0)
        {
            return Err(Error::InvalidConfig {
                field: "bandwidths".into(),
                reason: format!("both must be positive numbers, got ({h1}, {h2})"),
            });
        }
        if self.median_sample < 2 {
            return Err(Error::InvalidConfig {
                field: "median_sample".into(),
                reason: "must be at least 2".into(),
            });
        }
        Ok(())
    }
}

/// The GMMIL reward model.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Gmmil {
    config: GmmilConfig,
    expert: Array2<f64>,
    policy: Option<Array2<f64>>,
    h1: f64,
    h2: Option<f64>,
    offset: f64,
    obs_dim: usize,
    act_dim: usize,
}

impl Gmmil {
    /// A GMMIL reward for the expert pairs `(n, obs_dim)` and `(n, act_dim)`.
    ///
    /// # Errors
    /// A bad config, mismatched or empty batches, or non-finite values.
    pub fn new(
        config: GmmilConfig,
        expert_states: ArrayView2<'_, f64>,
        expert_actions: ArrayView2<'_, f64>,
    ) -> Result<Self> {
        config.validate()?;
        let expert = concat_pairs(expert_states, expert_actions)?;
        if expert.nrows() == 0 || expert.ncols() == 0 {
            return Err(Error::InvalidConfig {
                field: "expert pairs".into(),
                reason: format!(
                    "need at least one expert pair of at least one number, got {} x {}",
                    expert.nrows(),
                    expert.ncols()
                ),
            });
        }
        if expert.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "expert pairs".into(),
                step: 0,
            });
        }
        let (h1, h2) = match config.bandwidths {
            Some((h1, h2)) => (h1, Some(h2)),
            None => (
                median_sq_dist(expert.view(), expert.view(), true, config.median_sample),
                None,
            ),
        };
        Ok(Self {
            config,
            expert,
            policy: None,
            h1,
            h2,
            offset: 0.0,
            obs_dim: expert_states.ncols(),
            act_dim: expert_actions.ncols(),
        })
    }

    /// The bandwidths in use: `h1`, and `h2` once set.
    pub fn bandwidths(&self) -> (f64, Option<f64>) {
        (self.h1, self.h2)
    }

    fn kernel(&self, d2: f64) -> f64 {
        let mut k = (-d2 / self.h1).exp();
        if let Some(h2) = self.h2 {
            k += (-d2 / h2).exp();
        }
        k
    }

    fn mean_kernel(&self, x: ArrayView1<'_, f64>, set: &Array2<f64>, d2: &mut Vec<f64>) -> f64 {
        let x = x.as_standard_layout();
        let set = set.as_standard_layout();
        sq_dists(
            x.as_slice().unwrap_or_default(),
            set.as_slice().unwrap_or_default(),
            d2,
        );
        let mut total = 0.0;
        for &d in d2.iter() {
            total += self.kernel(d);
        }
        total / set.nrows() as f64
    }

    fn raw_rewards(&self, x: &Array2<f64>) -> Array1<f64> {
        let mut d2 = Vec::new();
        x.rows()
            .into_iter()
            .map(|row| {
                let e = self.mean_kernel(row, &self.expert, &mut d2);
                let p = self
                    .policy
                    .as_ref()
                    .map_or(0.0, |p| self.mean_kernel(row, p, &mut d2));
                e - p
            })
            .collect()
    }

    fn pairs(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<Array2<f64>> {
        if states.ncols() != self.obs_dim || actions.ncols() != self.act_dim {
            return Err(Error::ShapeMismatch {
                what: "GMMIL input".into(),
                expected: format!("states of {} and actions of {}", self.obs_dim, self.act_dim),
                got: format!("{} and {}", states.ncols(), actions.ncols()),
            });
        }
        concat_pairs(states, actions)
    }
}

/// The squared distances from `x` to each row of `set` (rows of
/// `x.len()` numbers, one after another), into `out` in row order. Each is
/// summed over the dimensions in order, as a plain loop would, so the
/// numbers are the same to the bit; four rows go at a time so that their
/// sums overlap (a lone sum waits on its previous addition).
fn sq_dists(x: &[f64], set: &[f64], out: &mut Vec<f64>) {
    out.clear();
    let dim = x.len();
    debug_assert!(dim > 0, "GMMIL pairs have at least one number");
    let mut blocks = set.chunks_exact(4 * dim);
    for block in &mut blocks {
        let (a, rest) = block.split_at(dim);
        let (b, rest) = rest.split_at(dim);
        let (c, d) = rest.split_at(dim);
        let (mut s0, mut s1, mut s2, mut s3) = (0.0, 0.0, 0.0, 0.0);
        for k in 0..dim {
            let xk = x[k];
            let (t0, t1, t2, t3) = (a[k] - xk, b[k] - xk, c[k] - xk, d[k] - xk);
            s0 += t0 * t0;
            s1 += t1 * t1;
            s2 += t2 * t2;
            s3 += t3 * t3;
        }
        out.extend_from_slice(&[s0, s1, s2, s3]);
    }
    for y in blocks.remainder().chunks_exact(dim) {
        let mut s = 0.0;
        for k in 0..dim {
            let t = y[k] - x[k];
            s += t * t;
        }
        out.push(s);
    }
}

/// Median squared distance between rows of `a` and rows of `b` (distinct
/// pairs only when `same`), over at most `cap` evenly spaced rows of each.
fn median_sq_dist(a: ArrayView2<'_, f64>, b: ArrayView2<'_, f64>, same: bool, cap: usize) -> f64 {
    let pick = |n: usize| -> Vec<usize> {
        let k = n.min(cap).max(1);
        (0..k).map(|i| i * n / k).collect()
    };
    let (ia, ib) = (pick(a.nrows()), pick(b.nrows()));
    let mut d = Vec::with_capacity(ia.len() * ib.len());
    for &i in &ia {
        for &j in &ib {
            if same && j <= i {
                continue;
            }
            let d2: f64 = a
                .row(i)
                .iter()
                .zip(b.row(j).iter())
                .map(|(x, y)| (x - y) * (x - y))
                .sum();
            d.push(d2);
        }
    }
    if d.is_empty() {
        return 1.0;
    }
    d.sort_by(f64::total_cmp);
    let m = d[d.len() / 2];
    // Identical points would make the kernel a spike: fall back to unit width.
    if m > 1e-12 { m } else { 1.0 }
}

/// GMMIL's witness reward with its action gradient, for SVG(1)-ER:
/// `d/dx exp(-|x-y|^2 / h) = -2 (x - y) / h exp(-|x-y|^2 / h)`, averaged
/// over the expert pairs minus the same over the latest policy batch.
impl Gmmil {
    /// [`DifferentiableReward::reward_and_grad`] with this crate's errors.
    fn reward_grad(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<(Array1<f64>, Array2<f64>)> {
        let x = self.pairs(states, actions)?;
        let (n, o) = (x.nrows(), self.obs_dim);
        let width = x.ncols();
        let mut r = Array1::zeros(n);
        let mut g = Array2::zeros((n, self.act_dim));
        let mut grad = vec![0.0; self.act_dim];
        let mut d2 = Vec::new();
        let expert = self.expert.as_standard_layout();
        let policy = self.policy.as_ref().map(|p| p.as_standard_layout());
        let sets = [Some((&expert, 1.0)), policy.as_ref().map(|p| (p, -1.0))];
        for (i, row) in x.rows().into_iter().enumerate() {
            let row = row.as_standard_layout();
            let row = row.as_slice().unwrap_or_default();
            for (set, sign) in sets.iter().flatten() {
                let ys = set.as_slice().unwrap_or_default();
                sq_dists(row, ys, &mut d2);
                let scale = sign / set.nrows() as f64;
                grad.iter_mut().for_each(|v| *v = 0.0);
                let mut total = 0.0;
                for (y, &d) in ys.chunks_exact(width).zip(d2.iter()) {
                    let mut dk = 0.0;
                    for h in std::iter::once(self.h1).chain(self.h2) {
                        let k = (-d / h).exp();
                        total += k;
                        dk -= 2.0 * k / h;
                    }
                    for (j, gj) in grad.iter_mut().enumerate() {
                        *gj += dk * (row[o + j] - y[o + j]);
                    }
                }
                r[i] += scale * total;
                for (j, gj) in grad.iter().enumerate() {
                    g[[i, j]] += scale * gj;
                }
            }
            r[i] -= self.offset;
        }
        Ok((r, g))
    }
}

impl DifferentiableReward for Gmmil {
    fn reward_and_grad(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> red_core::Result<(Array1<f64>, Array2<f64>)> {
        self.reward_grad(states, actions).map_err(into_core)
    }

    fn is_adaptive(&self) -> bool {
        true
    }
}

impl RewardModel for Gmmil {
    fn rewards(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> red_core::Result<Array1<f64>> {
        let x = self.pairs(states, actions).map_err(into_core)?;
        Ok(self.raw_rewards(&x) - self.offset)
    }

    fn update(
        &mut self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> red_core::Result<()> {
        let x = self.pairs(states, actions).map_err(into_core)?;
        if x.nrows() == 0 {
            return Ok(());
        }
        if x.iter().any(|v| !v.is_finite()) {
            return Err(red_core::Error::NonFinite {
                what: "GMMIL policy batch".into(),
            });
        }
        if self.h2.is_none() {
            self.h2 = Some(median_sq_dist(
                x.view(),
                self.expert.view(),
                false,
                self.config.median_sample,
            ));
        }
        self.policy = Some(x.clone());
        let raw = self.raw_rewards(&x);
        self.offset = raw.iter().copied().fold(f64::INFINITY, f64::min);
        Ok(())
    }

    fn is_adaptive(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn witness_prefers_expert_region_and_shift_zeroes_batch_minimum() {
        let es = Array2::from_shape_fn((50, 1), |(i, _)| 0.5 + i as f64 * 0.01);
        let ea = Array2::zeros((50, 1));
        let mut g = Gmmil::new(GmmilConfig::default(), es.view(), ea.view()).unwrap();
        let ps = Array2::from_shape_fn((40, 1), |(i, _)| -1.0 + i as f64 * 0.01);
        let pa = Array2::zeros((40, 1));
        g.update(ps.view(), pa.view()).unwrap();
        assert!(g.bandwidths().1.is_some());
        let rp = g.rewards(ps.view(), pa.view()).unwrap();
        let min = rp.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(min.abs() < 1e-12, "policy-batch minimum {min}");
        let re = g.rewards(es.view(), ea.view()).unwrap();
        assert!(re.mean().unwrap() > rp.mean().unwrap() + 0.1);
        // A reward does not depend on the batch it is computed in.
        let one = g
            .rewards(
                es.slice(ndarray::s![3..4, ..]),
                ea.slice(ndarray::s![3..4, ..]),
            )
            .unwrap();
        assert_eq!(one[0], re[3]);
    }

    #[test]
    fn action_gradient_matches_finite_differences() {
        let es = Array2::from_shape_fn((30, 2), |(i, j)| (i as f64 * 0.37 + j as f64).sin());
        let ea = Array2::from_shape_fn((30, 2), |(i, j)| (i as f64 * 0.11 - j as f64).cos());
        let mut g = Gmmil::new(GmmilConfig::default(), es.view(), ea.view()).unwrap();
        let ps = Array2::from_shape_fn((20, 2), |(i, j)| (i as f64 * 0.53 + 2.0 * j as f64).cos());
        let pa = Array2::from_shape_fn((20, 2), |(i, j)| (i as f64 * 0.29 + j as f64).sin());
        g.update(ps.view(), pa.view()).unwrap();
        let (r, grad) = g.reward_and_grad(ps.view(), pa.view()).unwrap();
        let direct = g.rewards(ps.view(), pa.view()).unwrap();
        for (x, y) in r.iter().zip(&direct) {
            assert!((x - y).abs() < 1e-12, "{x} vs {y}");
        }
        let h = 1e-5;
        for i in 0..20 {
            for j in 0..2 {
                let at = |d: f64| {
                    let mut a2 = pa.clone();
                    a2[[i, j]] += d;
                    g.rewards(ps.view(), a2.view()).unwrap()[i]
                };
                let numeric = (at(h) - at(-h)) / (2.0 * h);
                assert!(
                    (numeric - grad[[i, j]]).abs() <= 1e-6 * (1.0 + numeric.abs()),
                    "pair {i} action {j}: analytic {} numeric {numeric}",
                    grad[[i, j]]
                );
            }
        }
        assert!(grad.iter().any(|v| v.abs() > 1e-3));
    }

    #[test]
    fn median_rule_matches_hand_computation() {
        // Points 0, 1, 3: squared distances 1, 9, 4 -> median 4.
        let e = Array2::from_shape_vec((3, 1), vec![0.0, 1.0, 3.0]).unwrap();
        let a = Array2::zeros((3, 0));
        let g = Gmmil::new(GmmilConfig::default(), e.view(), a.view()).unwrap();
        assert_eq!(g.bandwidths().0, 4.0);
    }

    #[test]
    fn blocked_distances_are_the_plain_loop_to_the_bit() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut out = Vec::new();
        for dim in [1, 2, 3, 7, 24] {
            for rows in 0..10 {
                let x: Vec<f64> = (0..dim).map(|_| rng.random_range(-3.0..3.0)).collect();
                let set: Vec<f64> = (0..rows * dim)
                    .map(|_| rng.random_range(-3.0..3.0) * 1e3_f64.powi(rng.random_range(-2..3)))
                    .collect();
                sq_dists(&x, &set, &mut out);
                let plain: Vec<f64> = set
                    .chunks_exact(dim)
                    .map(|y| y.iter().zip(&x).map(|(a, b)| (a - b) * (a - b)).sum())
                    .collect();
                assert_eq!(out.len(), rows);
                for (a, b) in out.iter().zip(&plain) {
                    assert_eq!(a.to_bits(), b.to_bits(), "dim {dim} rows {rows}");
                }
            }
        }
    }

    #[test]
    fn rejects_bad_bandwidths() {
        let c = GmmilConfig {
            bandwidths: Some((0.0, 1.0)),
            ..GmmilConfig::default()
        };
        assert!(c.validate().unwrap_err().to_string().contains("bandwidths"));
    }
}
