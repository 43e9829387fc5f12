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

use std::sync::OnceLock;

use ndarray::{Array1, Array2, ArrayView2};
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
    /// `expert` laid out by columns (see [`columns`]), built on first use.
    #[serde(skip)]
    expert_cols: OnceLock<Vec<f64>>,
    /// The same for `policy`, reset at each update.
    #[serde(skip)]
    policy_cols: OnceLock<Vec<f64>>,
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
            expert_cols: OnceLock::new(),
            policy_cols: OnceLock::new(),
        })
    }

    /// The bandwidths in use: `h1`, and `h2` once set.
    pub fn bandwidths(&self) -> (f64, Option<f64>) {
        (self.h1, self.h2)
    }

    /// The expert pairs and the latest policy batch (if any), each as
    /// columns with the weight of its mean in the witness.
    fn sets(&self) -> Vec<(&[f64], f64)> {
        let expert = self.expert_cols.get_or_init(|| columns(&self.expert));
        let mut sets = vec![(expert.as_slice(), 1.0 / self.expert.nrows() as f64)];
        if let Some(p) = &self.policy {
            let cols = self.policy_cols.get_or_init(|| columns(p));
            sets.push((cols.as_slice(), -1.0 / p.nrows() as f64));
        }
        sets
    }

    /// The witness of each row of `x` (offset not subtracted), and when
    /// `grad` is given its gradient with respect to the action numbers.
    fn witness(&self, x: &Array2<f64>, mut grad: Option<&mut Array2<f64>>) -> Array1<f64> {
        let x = x.as_standard_layout();
        let width = x.ncols();
        let widths = Widths {
            inv_h1: 1.0 / self.h1,
            inv_h2: self.h2.map(|h| 1.0 / h),
        };
        let sets = self.sets();
        let mut scratch = Scratch::default();
        let mut g = vec![0.0; self.act_dim];
        let rows = x.as_slice().unwrap_or_default().chunks_exact(width);
        let mut r = Array1::zeros(x.nrows());
        for (i, row) in rows.enumerate() {
            for &(cols, scale) in &sets {
                let want = grad.is_some().then_some(self.obs_dim);
                let total = score_against(row, cols, widths, &mut scratch, want, &mut g);
                r[i] += scale * total;
                if let Some(grad) = grad.as_deref_mut() {
                    for (a, v) in g.iter().enumerate() {
                        grad[[i, a]] += scale * v;
                    }
                }
            }
        }
        r
    }

    fn raw_rewards(&self, x: &Array2<f64>) -> Array1<f64> {
        self.witness(x, None)
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

/// The rows of `set` laid out by columns: column `k` (the `k`-th number of
/// every row) is `out[k * n..(k + 1) * n]` for `n` rows, so that the loops
/// over rows below read memory in order and vectorise.
fn columns(set: &Array2<f64>) -> Vec<f64> {
    set.t().iter().copied().collect()
}

/// The kernel's inverse widths: `1 / h1`, and `1 / h2` once set.
#[derive(Clone, Copy)]
struct Widths {
    inv_h1: f64,
    inv_h2: Option<f64>,
}

/// Scratch vectors of one scoring loop: squared distances, kernel values
/// and gradient weights, one per set row.
#[derive(Default)]
struct Scratch {
    d2: Vec<f64>,
    k: Vec<f64>,
    w: Vec<f64>,
}

/// Set rows per block of the distance loop (its sums stay in the L1 cache).
const BLOCK: usize = 512;

/// The squared distances from `x` to each of the `n` rows of a set given by
/// columns (`cols.len() == x.len() * n`), into `out` in row order. Each
/// row's sum adds its dimensions in order from 0, as the plain loop
/// `sum_k (y_k - x_k)^2` does, so the numbers are the same to the bit
/// whichever instructions the loop is compiled to.
#[inline(always)]
fn sq_dists_cols(x: &[f64], cols: &[f64], out: &mut Vec<f64>) {
    let n = if x.is_empty() {
        0
    } else {
        cols.len() / x.len()
    };
    out.clear();
    out.resize(n, 0.0);
    for (b, block) in out.chunks_mut(BLOCK).enumerate() {
        let start = b * BLOCK;
        for (k, &xk) in x.iter().enumerate() {
            let col = &cols[k * n + start..k * n + start + block.len()];
            for (o, &y) in block.iter_mut().zip(col) {
                let t = y - xk;
                *o += t * t;
            }
        }
    }
}

/// The sum over a set's rows of the kernel of `x` with each row (given by
/// columns); when `act_from` is `Some(o)`, also `grad[a] = sum_j
/// d/dx_{o+a} k(x, y_j)` for the numbers of `x` from `o` on (the action).
/// Compiled for AVX-512 and AVX2 as well, picked at run time; the results
/// are the same numbers on every path (no fused multiply-adds).
#[multiversion::multiversion(targets("x86_64+avx512f+avx512vl", "x86_64+avx2+fma"))]
fn score_against(
    x: &[f64],
    cols: &[f64],
    widths: Widths,
    scratch: &mut Scratch,
    act_from: Option<usize>,
    grad: &mut [f64],
) -> f64 {
    let Scratch { d2, k, w } = scratch;
    sq_dists_cols(x, cols, d2);
    let n = d2.len();
    let i1 = widths.inv_h1;
    k.clear();
    k.resize(n, 0.0);
    w.clear();
    match (act_from.is_some(), widths.inv_h2) {
        (true, Some(i2)) => {
            w.resize(n, 0.0);
            for ((k, w), &d) in k.iter_mut().zip(w.iter_mut()).zip(d2.iter()) {
                let (e1, e2) = (exp_nonpositive(-d * i1), exp_nonpositive(-d * i2));
                *k = e1 + e2;
                *w = -2.0 * (e1 * i1 + e2 * i2);
            }
        }
        (true, None) => {
            w.resize(n, 0.0);
            for ((k, w), &d) in k.iter_mut().zip(w.iter_mut()).zip(d2.iter()) {
                let e1 = exp_nonpositive(-d * i1);
                *k = e1;
                *w = -2.0 * (e1 * i1);
            }
        }
        (false, Some(i2)) => {
            for (k, &d) in k.iter_mut().zip(d2.iter()) {
                *k = exp_nonpositive(-d * i1) + exp_nonpositive(-d * i2);
            }
        }
        (false, None) => {
            for (k, &d) in k.iter_mut().zip(d2.iter()) {
                *k = exp_nonpositive(-d * i1);
            }
        }
    }
    if let Some(o) = act_from {
        // d/dx exp(-|x-y|^2 / h) = -2 (x - y) / h exp(-|x-y|^2 / h)
        for (a, g) in grad.iter_mut().enumerate() {
            let col = &cols[(o + a) * n..(o + a + 1) * n];
            *g = weighted_offsets(w, x[o + a], col);
        }
    }
    sum4(k)
}

/// `exp(x)` for `x <= 0` (and not NaN), within 2 ulp of `f64::exp`, written
/// so that a loop of it vectorises (no call, no branch): `x = n ln2 + r`
/// with `|r| <= ln2 / 2` (`n` rounded by the 1.5 * 2^52 trick, `ln2` split
/// in two so that `n ln2` is exact), `exp(r)` by its Taylor series to
/// `r^13` (the rest is below 1e-17 relative), times `2^n` built in the
/// exponent bits. Below -708 the argument is clamped: `exp(-708)` is 3e-308,
/// nothing next to the kernel's other terms.
#[inline(always)]
fn exp_nonpositive(x: f64) -> f64 {
    const ROUND: f64 = 6_755_399_441_055_744.0; // 1.5 * 2^52
    // ln 2 in two parts: its leading 32 bits (so that n * LN2_HI is exact
    // for |n| < 2^21), and the rest.
    const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
    const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);
    let x = x.max(-708.0);
    let t = x * std::f64::consts::LOG2_E + ROUND;
    let n = t - ROUND;
    let r = (x - n * LN2_HI) - n * LN2_LO;
    let mut p = 1.0 / 6_227_020_800.0; // 1/13!
    for c in [
        1.0 / 479_001_600.0,
        1.0 / 39_916_800.0,
        1.0 / 3_628_800.0,
        1.0 / 362_880.0,
        1.0 / 40_320.0,
        1.0 / 5_040.0,
        1.0 / 720.0,
        1.0 / 120.0,
        1.0 / 24.0,
        1.0 / 6.0,
        0.5,
        1.0,
        1.0,
    ] {
        p = p * r + c;
    }
    // The low bits of `t` hold `n` (two's complement), which is in -1022..=0.
    let n = t.to_bits().wrapping_sub(ROUND.to_bits()) as i64;
    p * f64::from_bits(((n + 1023) as u64) << 52)
}

/// The sum of `xs` in four interleaved partial sums (so that the loop
/// vectorises), added together at the end.
#[inline(always)]
fn sum4(xs: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let mut chunks = xs.chunks_exact(4);
    for c in &mut chunks {
        for (a, v) in acc.iter_mut().zip(c) {
            *a += v;
        }
    }
    let tail: f64 = chunks.remainder().iter().sum();
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// `sum_j w_j (x - ys_j)`, in four interleaved partial sums.
#[inline(always)]
fn weighted_offsets(w: &[f64], x: f64, ys: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let mut wc = w.chunks_exact(4);
    let mut yc = ys.chunks_exact(4);
    for (a, b) in (&mut wc).zip(&mut yc) {
        for i in 0..4 {
            acc[i] += a[i] * (x - b[i]);
        }
    }
    let tail: f64 = wc
        .remainder()
        .iter()
        .zip(yc.remainder())
        .map(|(a, b)| a * (x - b))
        .sum();
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
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
        let mut g = Array2::zeros((x.nrows(), self.act_dim));
        let r = self.witness(&x, Some(&mut g)) - self.offset;
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
        self.policy_cols = OnceLock::new();
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
    fn witness_matches_the_formula_written_plainly() {
        let es = Array2::from_shape_fn((700, 3), |(i, j)| (i as f64 * 0.37 + j as f64).sin());
        let ea = Array2::from_shape_fn((700, 2), |(i, j)| (i as f64 * 0.11 - j as f64).cos());
        let ps = Array2::from_shape_fn((530, 3), |(i, j)| (i as f64 * 0.53 + 2.0 * j as f64).cos());
        let pa = Array2::from_shape_fn((530, 2), |(i, j)| (i as f64 * 0.29 + j as f64).sin());
        let mut g = Gmmil::new(GmmilConfig::default(), es.view(), ea.view()).unwrap();
        let plain = |g: &Gmmil, s: &Array2<f64>, a: &Array2<f64>| -> Vec<f64> {
            let (h1, h2) = g.bandwidths();
            let k = |x: &[f64], y: &[f64]| {
                let d: f64 = x.iter().zip(y).map(|(p, q)| (p - q) * (p - q)).sum();
                (-d / h1).exp() + h2.map_or(0.0, |h2| (-d / h2).exp())
            };
            let x = concat_pairs(s.view(), a.view()).unwrap();
            let e = concat_pairs(es.view(), ea.view()).unwrap();
            let p = g.policy.clone();
            x.rows()
                .into_iter()
                .map(|r| {
                    let r = r.to_vec();
                    let mean = |set: &Array2<f64>| {
                        set.rows()
                            .into_iter()
                            .map(|y| k(&r, &y.to_vec()))
                            .sum::<f64>()
                            / set.nrows() as f64
                    };
                    mean(&e) - p.as_ref().map_or(0.0, mean) - g.offset
                })
                .collect()
        };
        for updated in [false, true] {
            if updated {
                g.update(ps.view(), pa.view()).unwrap();
            }
            let got = g.rewards(ps.view(), pa.view()).unwrap();
            let (with_grad, _) = g.reward_and_grad(ps.view(), pa.view()).unwrap();
            for ((x, y), z) in got.iter().zip(plain(&g, &ps, &pa)).zip(&with_grad) {
                assert!((x - y).abs() < 1e-12, "{x} vs {y} (updated: {updated})");
                assert_eq!(x.to_bits(), z.to_bits());
            }
        }
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
    fn column_distances_are_the_plain_loop_to_the_bit() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut out = Vec::new();
        for dim in [1, 2, 3, 7, 24] {
            for rows in [0, 1, 2, 3, 5, 9, 511, 512, 513, 1100] {
                let x: Vec<f64> = (0..dim).map(|_| rng.random_range(-3.0..3.0)).collect();
                let set: Vec<f64> = (0..rows * dim)
                    .map(|_| rng.random_range(-3.0..3.0) * 1e3_f64.powi(rng.random_range(-2..3)))
                    .collect();
                let m = Array2::from_shape_vec((rows, dim), set.clone()).unwrap();
                sq_dists_cols(&x, &columns(&m), &mut out);
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
    fn vectorisable_exp_is_within_two_ulp_of_std() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let ulp = |v: f64| f64::from_bits(v.to_bits() + 1) - v;
        let mut xs: Vec<f64> = (0..200_000)
            .map(|_| -rng.random_range(0.0..708.0))
            .collect();
        xs.extend((0..100_000).map(|_| -rng.random_range(0.0..1.0_f64).powi(8)));
        xs.extend([
            0.0,
            -0.0,
            -1e-300,
            -f64::MIN_POSITIVE,
            -0.5 * std::f64::consts::LN_2,
            -708.0,
        ]);
        for x in xs {
            let (got, want) = (exp_nonpositive(x), x.exp());
            assert!(
                (got - want).abs() <= 2.0 * ulp(want),
                "exp({x}): {got} vs {want}"
            );
        }
        assert_eq!(exp_nonpositive(0.0), 1.0);
        // Clamped below -708: tiny, never negative, never NaN.
        for x in [-709.0, -1e6, f64::NEG_INFINITY] {
            let v = exp_nonpositive(x);
            assert!((0.0..1e-300).contains(&v), "exp({x}) gave {v}");
        }
    }

    #[test]
    fn four_lane_sums_match_plain_sums() {
        let xs: Vec<f64> = (0..37).map(|i| (i as f64 * 0.7).sin()).collect();
        let ys: Vec<f64> = (0..37).map(|i| (i as f64 * 0.3).cos()).collect();
        for n in 0..xs.len() {
            let plain: f64 = xs[..n].iter().sum();
            assert!((sum4(&xs[..n]) - plain).abs() < 1e-12);
            let plain: f64 = (0..n).map(|j| xs[j] * (0.25 - ys[j])).sum();
            assert!((weighted_offsets(&xs[..n], 0.25, &ys[..n]) - plain).abs() < 1e-12);
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
