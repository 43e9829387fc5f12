//! Running mean / standard-deviation normalisation of observations, clipped,
//! with the option to freeze statistics taken from expert data.
//!
//! `normalize(x) = clip((x - mean) / max(std, min_std, floor_j), -clip, clip)`
//! (`floor_j` a per-dimension floor, [`ObsNormalizer::with_dim_floors`], 0
//! unless set), or,
//! with soft tails ([`ObsNormalizer::with_soft_tails`]), the same inside
//! `+-clip` and `sign(z) (clip + ln(1 + |z| - clip))` beyond it, so that an
//! input far from the data still moves the output (slowly) instead of
//! saturating.
//!
//! ```
//! use ndarray::array;
//! use red_rl::normalize::ObsNormalizer;
//! let expert = array![[0.0, 10.0], [2.0, 10.0]];
//! let norm = ObsNormalizer::from_data(expert.view(), 5.0, 0.1)?;
//! assert!(norm.is_frozen());
//! let mut out = [0.0f32; 2];
//! norm.normalize_into(&[2.0, 100.0], &mut out)?;
//! assert_eq!(out, [1.0, 5.0]); // std 1 on the first dim; the second is clipped
//! # Ok::<(), red_rl::Error>(())
//! ```

use ndarray::{Array2, ArrayView2};
use serde::{Deserialize, Serialize};

use crate::{Error, Result};

/// Observation statistics (count, mean, variance), updated from batches with
/// the parallel form of Welford's algorithm, or frozen.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObsNormalizer {
    count: f64,
    mean: Vec<f64>,
    /// Population variance (divided by `count`).
    var: Vec<f64>,
    clip: f64,
    min_std: f64,
    frozen: bool,
    /// Logarithmic tails beyond `clip` instead of a hard clip. Absent in
    /// files written before it existed: a hard clip.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    soft_tails: bool,
    /// Per-dimension floors on the standard deviation that replace
    /// `min_std` where they are larger (0 where none was set); empty when
    /// none was set, as in files written before they existed.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    dim_floors: Vec<f64>,
}

/// The release's clip of normalised observations, `+-5`.
pub const DEFAULT_CLIP: f64 = 5.0;

/// Floor on the standard deviation, `0.1`: OpenAI baselines' running
/// mean/std (which the release uses) floors the variance at `1e-2`. It keeps
/// a dimension that is constant in the data from being blown up.
pub const DEFAULT_MIN_STD: f64 = 0.1;

impl ObsNormalizer {
    /// Statistics of no data yet (mean 0, variance 0, so the floor `min_std`
    /// applies), updated by [`ObsNormalizer::update`].
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] if `dim` is 0, `clip` is not positive and
    /// finite (JSON cannot hold infinity; `f64::MAX` means no clip), or
    /// `min_std` is not positive and finite.
    pub fn new(dim: usize, clip: f64, min_std: f64) -> Result<Self> {
        if dim == 0 {
            return Err(Error::InvalidConfig {
                field: "obs_dim".into(),
                reason: "must be at least 1".into(),
            });
        }
        if !clip.is_finite() || clip <= 0.0 {
            return Err(Error::InvalidConfig {
                field: "clip".into(),
                reason: format!("must be positive and finite (use f64::MAX for none), got {clip}"),
            });
        }
        if !min_std.is_finite() || min_std <= 0.0 {
            return Err(Error::InvalidConfig {
                field: "min_std".into(),
                reason: format!("must be positive and finite, got {min_std}"),
            });
        }
        Ok(Self {
            count: 0.0,
            mean: vec![0.0; dim],
            var: vec![0.0; dim],
            clip,
            min_std,
            frozen: false,
            soft_tails: false,
            dim_floors: Vec::new(),
        })
    }

    /// The same statistics with logarithmic tails beyond `clip` (`on`) or
    /// the hard clip (`!on`): a normalised value `z` with `|z| > clip`
    /// becomes `sign(z) (clip + ln(1 + |z| - clip))`, continuous with a
    /// continuous slope at `clip`, so values inside `+-clip` are unchanged
    /// and values outside keep their order (`z = 20` gives about 7.8 at
    /// clip 5, `z = 100` about 9.6).
    #[must_use]
    pub fn with_soft_tails(mut self, on: bool) -> Self {
        self.soft_tails = on;
        self
    }

    /// The same statistics with the standard deviation of dimension `dim`
    /// floored at `min_std` instead of the common floor, for each
    /// `(dim, min_std)` of `floors` whose floor is the larger: an input the
    /// data held nearly constant can be given a physical scale (the
    /// driving road's lateral position, half a lane) without coarsening the
    /// others. A later pair for the same dimension replaces an earlier one.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] for a dimension out of range or a floor
    /// that is not positive and finite.
    pub fn with_dim_floors(mut self, floors: &[(usize, f64)]) -> Result<Self> {
        for &(dim, floor) in floors {
            if dim >= self.dim() {
                return Err(Error::InvalidConfig {
                    field: "dim_floors".into(),
                    reason: format!(
                        "dimension {dim} is out of range: inputs have {}",
                        self.dim()
                    ),
                });
            }
            if !floor.is_finite() || floor <= 0.0 {
                return Err(Error::InvalidConfig {
                    field: "dim_floors".into(),
                    reason: format!(
                        "the floor of dimension {dim} must be positive and finite, got {floor}"
                    ),
                });
            }
            if self.dim_floors.is_empty() {
                self.dim_floors = vec![0.0; self.dim()];
            }
            self.dim_floors[dim] = floor;
        }
        Ok(self)
    }

    /// The clip of normalised values (`f64::MAX`: none).
    pub fn clip(&self) -> f64 {
        self.clip
    }

    /// Whether the tails beyond `clip` are logarithmic rather than clipped.
    pub fn soft_tails(&self) -> bool {
        self.soft_tails
    }

    /// Statistics of `data` (`(n, dim)`, for example the expert's
    /// observations), frozen: later [`ObsNormalizer::update`] calls do
    /// nothing. This is what the release does for RED and AE.
    ///
    /// # Errors
    /// As [`ObsNormalizer::new`], and [`Error::ShapeMismatch`] for no rows,
    /// [`Error::NonFinite`] for a non-finite entry.
    pub fn from_data(data: ArrayView2<'_, f64>, clip: f64, min_std: f64) -> Result<Self> {
        if data.nrows() == 0 {
            return Err(Error::ShapeMismatch {
                what: "normaliser data".into(),
                expected: "at least one row".into(),
                got: "0 rows".into(),
            });
        }
        let mut n = Self::new(data.ncols(), clip, min_std)?;
        n.update(data)?;
        n.frozen = true;
        Ok(n)
    }

    /// Adds a batch `(n, dim)` to the statistics, unless frozen.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] for the wrong number of columns,
    /// [`Error::NonFinite`] for a non-finite entry (the statistics are then
    /// left unchanged).
    pub fn update(&mut self, batch: ArrayView2<'_, f64>) -> Result<()> {
        if self.frozen || batch.nrows() == 0 {
            return Ok(());
        }
        if batch.ncols() != self.dim() {
            return Err(Error::ShapeMismatch {
                what: "normaliser batch".into(),
                expected: format!("{} columns", self.dim()),
                got: format!("{}", batch.ncols()),
            });
        }
        if let Some(i) = batch.iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: format!("observation entry {i} of a normaliser batch"),
                step: 0,
            });
        }
        let nb = batch.nrows() as f64;
        let total = self.count + nb;
        for (j, col) in batch.columns().into_iter().enumerate() {
            let bmean = col.sum() / nb;
            let bvar = col.iter().map(|v| (v - bmean) * (v - bmean)).sum::<f64>() / nb;
            let delta = bmean - self.mean[j];
            // Chan et al.'s combination of two sets' means and sums of squares.
            let m2 = self.var[j] * self.count + bvar * nb + delta * delta * self.count * nb / total;
            self.mean[j] += delta * nb / total;
            self.var[j] = m2 / total;
        }
        self.count = total;
        Ok(())
    }

    /// Normalises one observation into `out` (`f32`, the networks' type).
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] if `x` or `out` is not of length `dim`.
    pub fn normalize_into(&self, x: &[f64], out: &mut [f32]) -> Result<()> {
        if x.len() != self.dim() || out.len() != self.dim() {
            return Err(Error::ShapeMismatch {
                what: "observation to normalise".into(),
                expected: format!("{} entries", self.dim()),
                got: format!("{} in, {} out", x.len(), out.len()),
            });
        }
        for j in 0..x.len() {
            out[j] = self.normalize_value(j, x[j]) as f32;
        }
        Ok(())
    }

    /// Normalises a batch `(n, dim)` into a new `(n, dim)` `f32` array.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] for the wrong number of columns.
    pub fn normalize_batch(&self, x: ArrayView2<'_, f64>) -> Result<Array2<f32>> {
        if x.ncols() != self.dim() {
            return Err(Error::ShapeMismatch {
                what: "observations to normalise".into(),
                expected: format!("{} columns", self.dim()),
                got: format!("{}", x.ncols()),
            });
        }
        let mut out = Array2::zeros(x.raw_dim());
        for (mut o, row) in out.rows_mut().into_iter().zip(x.rows()) {
            for j in 0..row.len() {
                o[j] = self.normalize_value(j, row[j]) as f32;
            }
        }
        Ok(out)
    }

    /// Chains a gradient with respect to normalised observations
    /// (`d_norm`, `(n, dim)`, for example what a network's backward pass
    /// returns) back to the raw observations `raw` (`(n, dim)`): divided by
    /// the standard deviation, and 0 where the clip was active (with soft
    /// tails, times the tail's slope `1 / (1 + |z| - clip)` there).
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] if the shapes differ or have the wrong
    /// number of columns.
    pub fn backward(
        &self,
        raw: ArrayView2<'_, f64>,
        d_norm: ArrayView2<'_, f32>,
    ) -> Result<Array2<f64>> {
        if raw.dim() != d_norm.dim() || raw.ncols() != self.dim() {
            return Err(Error::ShapeMismatch {
                what: "normaliser backward".into(),
                expected: format!("two arrays of (n, {})", self.dim()),
                got: format!("{:?} and {:?}", raw.dim(), d_norm.dim()),
            });
        }
        let mut out = Array2::zeros(raw.raw_dim());
        for ((i, j), o) in out.indexed_iter_mut() {
            let z = (raw[[i, j]] - self.mean[j]) / self.std(j);
            if z.abs() < self.clip {
                *o = d_norm[[i, j]] as f64 / self.std(j);
            } else if self.soft_tails {
                *o = d_norm[[i, j]] as f64 / (self.std(j) * (1.0 + z.abs() - self.clip));
            }
        }
        Ok(out)
    }

    /// The raw value of dimension `j` that normalises to `z`: the inverse
    /// of the normalisation, exact inside `+-clip` and, with soft tails,
    /// beyond it too; with the hard clip a value at `+-clip` reads as the
    /// raw value at the clip.
    pub fn denormalize_value(&self, j: usize, z: f64) -> f64 {
        let z = if self.soft_tails && z.abs() > self.clip {
            z.signum() * (self.clip + (z.abs() - self.clip).exp_m1())
        } else {
            z
        };
        self.mean[j] + z * self.std(j)
    }

    #[inline]
    fn normalize_value(&self, j: usize, v: f64) -> f64 {
        let z = (v - self.mean[j]) / self.std(j);
        if self.soft_tails && z.abs() > self.clip {
            z.signum() * (self.clip + (z.abs() - self.clip).ln_1p())
        } else {
            z.clamp(-self.clip, self.clip)
        }
    }

    #[inline]
    fn std(&self, j: usize) -> f64 {
        let floor = match self.dim_floors.get(j) {
            Some(&f) => f.max(self.min_std),
            None => self.min_std,
        };
        self.var[j].sqrt().max(floor)
    }

    /// Stops later updates.
    pub fn freeze(&mut self) {
        self.frozen = true;
    }

    /// Whether updates are ignored.
    pub fn is_frozen(&self) -> bool {
        self.frozen
    }

    /// Length of an observation.
    pub fn dim(&self) -> usize {
        self.mean.len()
    }

    /// Number of observations the statistics were computed from.
    pub fn count(&self) -> f64 {
        self.count
    }

    /// Per-dimension means.
    pub fn mean(&self) -> &[f64] {
        &self.mean
    }

    /// Per-dimension population variances (before the floor).
    pub fn var(&self) -> &[f64] {
        &self.var
    }

    /// The per-dimension floors of [`ObsNormalizer::with_dim_floors`]: one
    /// per dimension (0 where none was set), or empty when none was set.
    pub fn dim_floors(&self) -> &[f64] {
        &self.dim_floors
    }

    /// Per-dimension standard deviations used to divide (after the floor).
    pub fn stds(&self) -> Vec<f64> {
        (0..self.dim()).map(|j| self.std(j)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::{Axis, array, s};

    #[test]
    fn batched_updates_match_direct_statistics() {
        let data = array![
            [1.0, -3.0],
            [2.0, 0.5],
            [4.0, 2.0],
            [-1.0, 7.0],
            [0.5, 0.0],
            [3.0, 1.0],
            [10.0, -2.0]
        ];
        let mut n = ObsNormalizer::new(2, 5.0, 1e-6).unwrap();
        n.update(data.slice(s![0..3, ..])).unwrap();
        n.update(data.slice(s![3..4, ..])).unwrap();
        n.update(data.slice(s![4.., ..])).unwrap();
        let mean = data.mean_axis(Axis(0)).unwrap();
        let var = data.var_axis(Axis(0), 0.0);
        assert_eq!(n.count(), 7.0);
        for j in 0..2 {
            assert!((n.mean()[j] - mean[j]).abs() < 1e-12);
            assert!((n.var()[j] - var[j]).abs() < 1e-12);
        }
        let mut out = [0.0f32; 2];
        n.normalize_into(&[4.0, 1.0], &mut out).unwrap();
        for j in 0..2 {
            let x = [4.0, 1.0][j];
            let want = ((x - mean[j]) / var[j].sqrt()).clamp(-5.0, 5.0) as f32;
            assert!((out[j] - want).abs() < 1e-6);
        }
        let b = n.normalize_batch(data.view()).unwrap();
        assert!(b.iter().all(|v| v.abs() <= 5.0));
    }

    #[test]
    fn a_dimension_floor_replaces_the_common_floor_where_larger() {
        // Stds 1, 0.05 and 0 (constant); common floor 0.01.
        let data = array![[0.0, 0.45, 2.0], [2.0, 0.55, 2.0]];
        let n = ObsNormalizer::from_data(data.view(), 5.0, 0.01).unwrap();
        let plain = n.stds();
        let n = n
            .with_dim_floors(&[(1, 0.25), (2, 0.001), (0, 0.5)])
            .unwrap();
        assert_eq!(n.stds(), vec![1.0, 0.25, 0.01], "was {plain:?}");
        let mut out = [0f32; 3];
        n.normalize_into(&[1.0, 1.0, 2.0], &mut out).unwrap();
        assert!((out[1] - 2.0).abs() < 1e-6, "{out:?}");
        // Backward divides by the floored std too.
        let g = n
            .backward(
                array![[1.0, 0.6, 2.0]].view(),
                array![[1.0f32, 1.0, 0.0]].view(),
            )
            .unwrap();
        assert!((g[[0, 1]] - 4.0).abs() < 1e-9, "{g:?}");
        // Kept through a file; files without floors read as before.
        let back: ObsNormalizer =
            serde_json::from_str(&serde_json::to_string(&n).unwrap()).unwrap();
        assert_eq!(back, n);
        let none = ObsNormalizer::from_data(data.view(), 5.0, 0.01).unwrap();
        let text = serde_json::to_string(&none).unwrap();
        assert!(!text.contains("dim_floors"), "{text}");
        let old: ObsNormalizer = serde_json::from_str(&text).unwrap();
        assert!(old.dim_floors().is_empty());
        assert_eq!(old.stds(), plain);
        for (bad, what) in [
            ((3, 0.1), "out of range"),
            ((0, 0.0), "positive"),
            ((0, f64::NAN), "positive"),
        ] {
            let e = none
                .clone()
                .with_dim_floors(&[bad])
                .unwrap_err()
                .to_string();
            assert!(e.contains(what), "{e}");
        }
    }

    #[test]
    fn frozen_ignores_updates_and_floor_applies() {
        let expert = array![[1.0, 3.0], [1.0, 5.0]];
        let mut n = ObsNormalizer::from_data(expert.view(), 5.0, 0.1).unwrap();
        let before = n.clone();
        n.update(array![[100.0, 100.0]].view()).unwrap();
        assert_eq!(n, before);
        // The first dimension is constant: std floored at 0.1.
        assert_eq!(n.stds(), vec![0.1, 1.0]);
        let mut out = [0.0f32; 2];
        n.normalize_into(&[1.2, 4.0], &mut out).unwrap();
        assert!((out[0] - 2.0).abs() < 1e-5 && out[1].abs() < 1e-6);
    }

    #[test]
    fn backward_matches_finite_differences() {
        let n = ObsNormalizer::from_data(array![[0.0, 1.0], [2.0, 5.0]].view(), 1.2, 0.1).unwrap();
        // Second entry of the second row is clipped (z = 2.5 > 1.2).
        let raw = array![[0.5, 2.0], [1.5, 8.0]];
        let w = array![[1.0f32, -2.0], [0.5, 3.0]];
        let f = |x: &Array2<f64>| -> f64 {
            let z = n.normalize_batch(x.view()).unwrap();
            z.iter()
                .zip(w.iter())
                .map(|(a, b)| (*a as f64) * (*b as f64))
                .sum()
        };
        let g = n.backward(raw.view(), w.view()).unwrap();
        for i in 0..2 {
            for j in 0..2 {
                let mut p = raw.clone();
                p[[i, j]] += 1e-3;
                let mut m = raw.clone();
                m[[i, j]] -= 1e-3;
                let fd = (f(&p) - f(&m)) / 2e-3;
                assert!(
                    (fd - g[[i, j]]).abs() < 1e-3,
                    "({i},{j}): {fd} vs {}",
                    g[[i, j]]
                );
            }
        }
        assert_eq!(g[[1, 1]], 0.0);
    }

    #[test]
    fn soft_tails_keep_the_inside_and_order_the_outside() {
        let data = array![[0.0], [2.0]]; // mean 1, std 1
        let hard = ObsNormalizer::from_data(data.view(), 5.0, 0.1).unwrap();
        let soft = hard.clone().with_soft_tails(true);
        assert!(soft.soft_tails() && !hard.soft_tails());
        let at = |n: &ObsNormalizer, x: f64| {
            let mut o = [0.0f32];
            n.normalize_into(&[x], &mut o).unwrap();
            o[0] as f64
        };
        for x in [-3.5, 0.0, 1.0, 4.0, 5.9] {
            assert_eq!(at(&soft, x), at(&hard, x), "inside the clip at {x}");
        }
        // z = 20 and z = -100: the hard clip gives 5 and -5 for both.
        assert_eq!(at(&hard, 21.0), 5.0);
        assert!((at(&soft, 21.0) - (5.0 + 16f64.ln())).abs() < 1e-5);
        assert!((at(&soft, -99.0) + (5.0 + 96f64.ln())).abs() < 1e-5);
        let ys: Vec<f64> = [6.5, 8.0, 30.0, 1e4]
            .iter()
            .map(|&x| at(&soft, x))
            .collect();
        assert!(ys.windows(2).all(|w| w[0] < w[1]), "{ys:?}");
        // Continuous at the knee.
        assert!((at(&soft, 6.0 + 1e-9) - 5.0).abs() < 1e-6);
        // The gradient through the tail matches finite differences.
        let raw = array![[12.0], [-40.0], [3.0]];
        let g = soft
            .backward(raw.view(), array![[1.0f32], [1.0], [1.0]].view())
            .unwrap();
        for i in 0..3 {
            let x = raw[[i, 0]];
            let fd = (at(&soft, x + 1e-3) - at(&soft, x - 1e-3)) / 2e-3;
            assert!((fd - g[[i, 0]]).abs() < 1e-3, "{i}: {fd} vs {}", g[[i, 0]]);
        }
        // Written only when on; a file without the key reads as the hard clip.
        let text = serde_json::to_string(&hard).unwrap();
        assert!(!text.contains("soft_tails"), "{text}");
        let back: ObsNormalizer =
            serde_json::from_str(&serde_json::to_string(&soft).unwrap()).unwrap();
        assert_eq!(back, soft);
    }

    #[test]
    fn serde_round_trip_and_errors() {
        let mut n = ObsNormalizer::new(3, DEFAULT_CLIP, DEFAULT_MIN_STD).unwrap();
        n.update(array![[1.0, 2.0, 3.0], [0.0, 1.0, 5.0]].view())
            .unwrap();
        let back: ObsNormalizer =
            serde_json::from_str(&serde_json::to_string(&n).unwrap()).unwrap();
        assert_eq!(back, n);
        assert!(n.update(array![[1.0, 2.0]].view()).is_err());
        assert!(n.update(array![[1.0, f64::NAN, 2.0]].view()).is_err());
        assert_eq!(back, n, "a rejected batch leaves the statistics unchanged");
        assert!(
            ObsNormalizer::new(3, 0.0, 0.1)
                .unwrap_err()
                .to_string()
                .contains("clip")
        );
    }

    #[test]
    fn denormalize_inverts_inside_and_in_the_soft_tails() {
        let data = array![[0.0, 1.0], [2.0, 1.2]];
        let soft = ObsNormalizer::from_data(data.view(), 5.0, 0.01)
            .unwrap()
            .with_soft_tails(true);
        for v in [-50.0, -3.0, 0.3, 1.1, 1.9, 40.0] {
            for j in 0..2 {
                let mut z = [0.0f32; 2];
                let mut x = [1.0, 1.1];
                x[j] = v;
                soft.normalize_into(&x, &mut z).unwrap();
                let back = soft.denormalize_value(j, z[j] as f64);
                assert!(
                    (back - v).abs() < 1e-4 * v.abs().max(1.0),
                    "{j} {v}: {back}"
                );
            }
        }
        // The hard clip reads a clipped value as the one at the clip.
        let hard = ObsNormalizer::from_data(data.view(), 5.0, 0.01).unwrap();
        let mut z = [0.0f32; 2];
        hard.normalize_into(&[1.0, 40.0], &mut z).unwrap();
        assert!((hard.denormalize_value(1, z[1] as f64) - 1.6).abs() < 1e-6);
    }
}
