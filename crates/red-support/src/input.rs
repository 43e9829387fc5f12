//! The estimators' input: the concatenation `x = [s, a]`, checked, and
//! optionally standardised with the expert statistics; state dimensions
//! may be left out, capped, weighted, or read by their phase (two more
//! columns after the action).

use ndarray::{Array1, Array2, ArrayView2, Axis, s};
use serde::{Deserialize, Serialize};

use crate::{Error, Result};

/// A standard deviation below this is treated as a constant dimension and
/// left unscaled (dividing by it would blow any other value up).
const MIN_STD: f64 = 1e-8;

/// Maps state-action batches to the estimator's input rows `[s, a]`,
/// standardised per dimension when fitted with `standardize = true` (after
/// any caps), then weighted ([`WeightedDim`]), then the two phase columns
/// of each periodic dimension (never standardised).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputMap {
    /// Length of a state.
    pub obs_dim: usize,
    /// Length of an action.
    pub act_dim: usize,
    /// Per-dimension mean subtracted from `[s, a]` (zeros when not
    /// standardising).
    pub mean: Vec<f64>,
    /// Per-dimension scale `[s, a]` is divided by (ones when not
    /// standardising).
    pub scale: Vec<f64>,
    /// State dimensions the estimator does not see: they read as 0 in
    /// every row (our addition; empty, the release's, keeps every input).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ignored: Vec<usize>,
    /// State dimensions read by their phase (our addition; empty, the
    /// release's, reads none so): each reads as 0 in its own place and
    /// adds two inputs after the action, see [`PeriodicDim`].
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub periodic: Vec<PeriodicDim>,
    /// State dimensions read no higher than a cap (our addition; empty,
    /// the release's, caps none), see [`CappedDim`].
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub capped: Vec<CappedDim>,
    /// State dimensions read with a weight (our addition; empty, the
    /// release's, weighs every input alike), see [`WeightedDim`].
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub weighted: Vec<WeightedDim>,
}

/// A state dimension that the estimator reads multiplied by `weight`, after
/// any cap and standardisation: a weight below 1 makes the support wider
/// along it (a move along it costs less of the reward), above 1 narrower.
/// A weight of 0.5 on the driving road's lateral position halves how far
/// a change of lane reads from the demonstration (`ignored_state_dims`
/// would make it read as no change at all).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WeightedDim {
    /// The state dimension.
    pub dim: usize,
    /// Its weight (finite, above 0).
    pub weight: f64,
}

/// A state dimension that the estimator reads as `min(v, max)` of its raw
/// value `v`, before any standardisation (whose statistics are then those
/// of the capped values, see [`cap_states`]): every value above the cap
/// reads as the cap. The driving road's margin to the nearer wall capped at
/// half a lane reads alike in every lane but for the outer lanes' wall
/// side.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CappedDim {
    /// The state dimension.
    pub dim: usize,
    /// The highest value it reads (finite).
    pub max: f64,
}

/// A state dimension that the estimator reads by its phase alone: the raw
/// value `v` (before any standardisation) becomes the two inputs
/// `r cos(2 pi v / period)` and `r sin(2 pi v / period)` with
/// `r = period / (2 pi)`, so values a whole period apart read the same,
/// and near any value a small change moves the input by as much as it
/// moved `v` itself. The two inputs are never standardised (nor floored):
/// they stay in the state's own units. The driving road's lateral position
/// read with the lane width as its period is the place within a lane,
/// whichever lane.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PeriodicDim {
    /// The state dimension.
    pub dim: usize,
    /// Its period, in the state's own units (finite, above 0).
    pub period: f64,
}

impl PeriodicDim {
    /// The two inputs `[r cos, r sin]` of the raw value `v`, in the
    /// state's units.
    pub fn features(&self, v: f64) -> [f64; 2] {
        let r = self.period / std::f64::consts::TAU;
        let phase = v / r;
        [r * phase.cos(), r * phase.sin()]
    }
}

impl InputMap {
    /// Checks the expert batch and builds the map: the identity, or the
    /// standardisation by the expert mean and standard deviation
    /// (dimensions with a standard deviation below 1e-8 are only centred).
    ///
    /// # Errors
    /// As [`check_pairs`], and [`Error::TooFewSamples`] for an empty batch.
    pub fn fit(
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
        standardize: bool,
    ) -> Result<Self> {
        Self::fit_floored(states, actions, standardize, 0.0)
    }

    /// As [`InputMap::fit`], with the standard deviations floored at
    /// `min_std` when standardising: a dimension whose expert spread is
    /// below the floor (constant ones included) is divided by the floor,
    /// so that a small step off a narrow demonstration does not read as
    /// many deviations. A floor of at most 1e-8 is the plain rule of
    /// [`InputMap::fit`].
    ///
    /// # Errors
    /// As [`InputMap::fit`].
    pub fn fit_floored(
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
        standardize: bool,
        min_std: f64,
    ) -> Result<Self> {
        let (obs_dim, act_dim) = (states.ncols(), actions.ncols());
        check_pairs(states, actions, obs_dim, act_dim)?;
        let n = states.nrows();
        if n == 0 {
            return Err(Error::TooFewSamples {
                what: "a support estimator".into(),
                need: 1,
                got: 0,
            });
        }
        let d = obs_dim + act_dim;
        let (mut mean, mut scale) = (vec![0.0; d], vec![1.0; d]);
        if standardize {
            let x = concat(states, actions);
            for j in 0..d {
                let col = x.column(j);
                let m = col.sum() / n as f64;
                let var = col.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / n as f64;
                mean[j] = m;
                let sd = var.sqrt();
                scale[j] = if min_std > MIN_STD {
                    sd.max(min_std)
                } else if sd < MIN_STD {
                    1.0
                } else {
                    sd
                };
            }
        }
        Ok(Self {
            obs_dim,
            act_dim,
            mean,
            scale,
            ignored: Vec::new(),
            periodic: Vec::new(),
            capped: Vec::new(),
            weighted: Vec::new(),
        })
    }

    /// The same map with the state dimensions `dims` read as 0 in every
    /// row, whatever their value (sorted, each once).
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] for a dimension at or beyond `obs_dim`.
    pub fn ignoring(mut self, dims: &[usize]) -> Result<Self> {
        check_state_dims(dims, self.obs_dim, "ignored_state_dims")?;
        let mut dims = dims.to_vec();
        dims.sort_unstable();
        dims.dedup();
        self.ignored = dims;
        Ok(self)
    }

    /// The same map with the state dimensions of `dims` read by their
    /// phase ([`PeriodicDim`]), in the order given.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] for a dimension at or beyond `obs_dim`, one
    /// given twice, or a period that is not finite and above 0.
    pub fn with_periodic(mut self, dims: &[PeriodicDim]) -> Result<Self> {
        check_periodic(dims, self.obs_dim)?;
        self.periodic = dims.to_vec();
        Ok(self)
    }

    /// The same map with the state dimensions of `dims` read no higher
    /// than their caps ([`CappedDim`]). A map that standardises should be
    /// fitted on [`cap_states`] of the batch.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] for a dimension at or beyond `obs_dim`, one
    /// given twice, or a cap that is not finite.
    pub fn with_caps(mut self, dims: &[CappedDim]) -> Result<Self> {
        check_caps(dims, self.obs_dim)?;
        self.capped = dims.to_vec();
        Ok(self)
    }

    /// The same map with the state dimensions of `dims` weighted
    /// ([`WeightedDim`]).
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] for a dimension at or beyond `obs_dim`, one
    /// given twice, one that is ignored or periodic (it reads as 0 in its
    /// place), or a weight that is not finite and above 0.
    pub fn with_weights(mut self, dims: &[WeightedDim]) -> Result<Self> {
        check_weights(dims, self.obs_dim)?;
        if let Some(w) = dims
            .iter()
            .find(|w| self.ignored.contains(&w.dim) || self.periodic.iter().any(|p| p.dim == w.dim))
        {
            return Err(Error::InvalidConfig {
                field: "weighted_state_dims".into(),
                reason: format!(
                    "state dimension {} is ignored or read by its phase: it has no value to weigh",
                    w.dim
                ),
            });
        }
        self.weighted = dims.to_vec();
        Ok(self)
    }

    /// Length of an input row: `obs_dim + act_dim`, and two more for each
    /// periodic dimension.
    pub fn dim(&self) -> usize {
        self.obs_dim + self.act_dim + 2 * self.periodic.len()
    }

    /// The input rows of a batch: `(n, obs_dim)` and `(n, act_dim)` in,
    /// `(n, self.dim())` out.
    ///
    /// # Errors
    /// As [`check_pairs`].
    pub fn apply(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<Array2<f64>> {
        check_pairs(states, actions, self.obs_dim, self.act_dim)?;
        check_state_dims(&self.ignored, self.obs_dim, "ignored")?;
        // The lists' values were checked when the map was built; here only
        // what indexing needs, without allocating on the per-step path.
        let dims = self.periodic.iter().map(|p| p.dim);
        if let Some(d) = dims
            .chain(self.capped.iter().map(|c| c.dim))
            .chain(self.weighted.iter().map(|w| w.dim))
            .find(|&d| d >= self.obs_dim)
        {
            return Err(Error::InvalidConfig {
                field: "periodic, capped or weighted".into(),
                reason: format!(
                    "state dimension {d} does not exist: states have {} dimensions",
                    self.obs_dim
                ),
            });
        }
        let (o, a) = (self.obs_dim, self.act_dim);
        let mut x = Array2::zeros((states.nrows(), self.dim()));
        x.slice_mut(s![.., ..o]).assign(&states);
        x.slice_mut(s![.., o..o + a]).assign(&actions);
        for (i, mut row) in x.rows_mut().into_iter().enumerate() {
            for c in &self.capped {
                row[c.dim] = row[c.dim].min(c.max);
            }
            for j in 0..o + a {
                row[j] = (row[j] - self.mean[j]) / self.scale[j];
            }
            for w in &self.weighted {
                row[w.dim] *= w.weight;
            }
            for &j in &self.ignored {
                row[j] = 0.0;
            }
            for (k, p) in self.periodic.iter().enumerate() {
                let [c, sn] = p.features(states[[i, p.dim]]);
                row[p.dim] = 0.0;
                row[o + a + 2 * k] = c;
                row[o + a + 2 * k + 1] = sn;
            }
        }
        Ok(x)
    }

    /// Turns a gradient with respect to the input rows, `(n, dim)`, into one
    /// with respect to the actions, `(n, act_dim)` (the chain rule through
    /// the standardisation).
    pub fn action_grad(&self, grad_x: ArrayView2<'_, f64>) -> Array2<f64> {
        let mut g = grad_x
            .slice(s![.., self.obs_dim..self.obs_dim + self.act_dim])
            .to_owned();
        let inv: Array1<f64> = self.scale[self.obs_dim..].iter().map(|v| 1.0 / v).collect();
        g *= &inv.view().insert_axis(Axis(0));
        g
    }
}

/// Checks that `states` is `(n, obs_dim)`, `actions` is `(n, act_dim)` and
/// all values are finite.
///
/// # Errors
/// [`Error::ShapeMismatch`] or [`Error::NonFinite`].
pub fn check_pairs(
    states: ArrayView2<'_, f64>,
    actions: ArrayView2<'_, f64>,
    obs_dim: usize,
    act_dim: usize,
) -> Result<()> {
    if states.ncols() != obs_dim {
        return Err(Error::ShapeMismatch {
            what: "states".into(),
            expected: format!("{obs_dim} columns"),
            got: format!("{} columns", states.ncols()),
        });
    }
    if actions.ncols() != act_dim {
        return Err(Error::ShapeMismatch {
            what: "actions".into(),
            expected: format!("{act_dim} columns"),
            got: format!("{} columns", actions.ncols()),
        });
    }
    if states.nrows() != actions.nrows() {
        return Err(Error::ShapeMismatch {
            what: "actions".into(),
            expected: format!("{} rows, as many as the states", states.nrows()),
            got: format!("{} rows", actions.nrows()),
        });
    }
    if states.iter().any(|v| !v.is_finite()) {
        return Err(Error::NonFinite {
            what: "states".into(),
        });
    }
    if actions.iter().any(|v| !v.is_finite()) {
        return Err(Error::NonFinite {
            what: "actions".into(),
        });
    }
    Ok(())
}

/// Refuses a state dimension at or beyond `obs_dim` in `dims`, naming
/// `field`.
fn check_state_dims(dims: &[usize], obs_dim: usize, field: &str) -> Result<()> {
    match dims.iter().find(|&&d| d >= obs_dim) {
        Some(&d) => Err(Error::InvalidConfig {
            field: field.into(),
            reason: format!(
                "state dimension {d} does not exist: states have {obs_dim} dimensions (0..{obs_dim})"
            ),
        }),
        None => Ok(()),
    }
}

/// `states` with each dimension of `dims` capped ([`CappedDim`]): what a
/// standardising map with these caps is fitted on.
///
/// # Errors
/// As [`InputMap::with_caps`], and [`Error::NonFinite`] for a state that
/// is not finite (a cap would hide a NaN).
pub fn cap_states(states: ArrayView2<'_, f64>, dims: &[CappedDim]) -> Result<Array2<f64>> {
    check_caps(dims, states.ncols())?;
    if states.iter().any(|v| !v.is_finite()) {
        return Err(Error::NonFinite {
            what: "states".into(),
        });
    }
    let mut out = states.to_owned();
    for c in dims {
        out.column_mut(c.dim).mapv_inplace(|v| v.min(c.max));
    }
    Ok(out)
}

/// Refuses a capped dimension at or beyond `obs_dim`, one given twice, or
/// a cap that is not finite.
pub(crate) fn check_caps(dims: &[CappedDim], obs_dim: usize) -> Result<()> {
    let list: Vec<(usize, f64)> = dims.iter().map(|c| (c.dim, c.max)).collect();
    check_dim_list(&list, obs_dim, "capped_state_dims", "max", "finite", |v| {
        v.is_finite()
    })
}

/// Refuses a weighted dimension at or beyond `obs_dim`, one given twice,
/// or a weight that is not finite and above 0.
pub(crate) fn check_weights(dims: &[WeightedDim], obs_dim: usize) -> Result<()> {
    let list: Vec<(usize, f64)> = dims.iter().map(|w| (w.dim, w.weight)).collect();
    check_dim_list(
        &list,
        obs_dim,
        "weighted_state_dims",
        "weight",
        "finite and above 0",
        |v| v.is_finite() && v > 0.0,
    )
}

/// Refuses a periodic dimension at or beyond `obs_dim`, one given twice,
/// or a period that is not finite and above 0.
pub(crate) fn check_periodic(dims: &[PeriodicDim], obs_dim: usize) -> Result<()> {
    let list: Vec<(usize, f64)> = dims.iter().map(|p| (p.dim, p.period)).collect();
    check_dim_list(
        &list,
        obs_dim,
        "periodic_state_dims",
        "period",
        "finite and above 0",
        |v| v.is_finite() && v > 0.0,
    )
}

/// Refuses, in the list `field` of (state dimension, value) settings, a
/// dimension at or beyond `obs_dim`, one given twice, or a value (named
/// `value`) that `ok` refuses (`want` says what it must be).
fn check_dim_list(
    list: &[(usize, f64)],
    obs_dim: usize,
    field: &str,
    value: &str,
    want: &str,
    ok: fn(f64) -> bool,
) -> Result<()> {
    let idx: Vec<usize> = list.iter().map(|&(d, _)| d).collect();
    check_state_dims(&idx, obs_dim, field)?;
    for (k, &(d, v)) in list.iter().enumerate() {
        if !ok(v) {
            return Err(Error::InvalidConfig {
                field: format!("{field}[{k}].{value}"),
                reason: format!("must be {want}, got {v}"),
            });
        }
        if idx[..k].contains(&d) {
            return Err(Error::InvalidConfig {
                field: format!("{field}[{k}].dim"),
                reason: format!("state dimension {d} is given twice"),
            });
        }
    }
    Ok(())
}

fn concat(states: ArrayView2<'_, f64>, actions: ArrayView2<'_, f64>) -> Array2<f64> {
    let (n, o, a) = (states.nrows(), states.ncols(), actions.ncols());
    let mut x = Array2::zeros((n, o + a));
    x.slice_mut(s![.., ..o]).assign(&states);
    x.slice_mut(s![.., o..]).assign(&actions);
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::array;

    #[test]
    fn a_weighted_dimension_is_scaled_after_standardisation_and_bad_weights_are_refused() {
        let s = array![[1.0, 5.0, 2.0], [3.0, 7.0, 2.0], [5.0, 9.0, 4.0]];
        let a = array![[0.0], [1.0], [2.0]];
        for standardize in [false, true] {
            let plain = InputMap::fit(s.view(), a.view(), standardize).unwrap();
            let w = [WeightedDim {
                dim: 1,
                weight: 0.5,
            }];
            let weighted = plain.clone().with_weights(&w).unwrap();
            let (x0, x1) = (
                plain.apply(s.view(), a.view()).unwrap(),
                weighted.apply(s.view(), a.view()).unwrap(),
            );
            for j in 0..4 {
                let f = if j == 1 { 0.5 } else { 1.0 };
                for i in 0..3 {
                    assert_eq!(x1[[i, j]], f * x0[[i, j]], "row {i}, column {j}");
                }
            }
        }
        let map = InputMap::fit(s.view(), a.view(), false).unwrap();
        for (w, what) in [
            (
                vec![WeightedDim {
                    dim: 3,
                    weight: 1.0,
                }],
                "does not exist",
            ),
            (
                vec![WeightedDim {
                    dim: 0,
                    weight: 0.0,
                }],
                "above 0",
            ),
            (
                vec![WeightedDim {
                    dim: 0,
                    weight: f64::NAN,
                }],
                "above 0",
            ),
            (
                vec![
                    WeightedDim {
                        dim: 0,
                        weight: 1.0,
                    },
                    WeightedDim {
                        dim: 0,
                        weight: 2.0,
                    },
                ],
                "twice",
            ),
        ] {
            let e = map.clone().with_weights(&w).unwrap_err().to_string();
            assert!(e.contains(what), "{e}");
        }
        for bad in [-1.0, f64::INFINITY] {
            let e = map
                .clone()
                .with_weights(&[WeightedDim {
                    dim: 0,
                    weight: bad,
                }])
                .unwrap_err()
                .to_string();
            assert!(e.contains("above 0"), "{e}");
        }
        let periodic = map
            .clone()
            .with_periodic(&[PeriodicDim {
                dim: 2,
                period: 1.0,
            }])
            .unwrap();
        let ignoring = map.clone().ignoring(&[2]).unwrap();
        for no_value in [periodic, ignoring] {
            let e = no_value
                .with_weights(&[WeightedDim {
                    dim: 2,
                    weight: 2.0,
                }])
                .unwrap_err()
                .to_string();
            assert!(e.contains("no value to weigh"), "{e}");
        }
    }

    #[test]
    fn standardisation_gives_zero_mean_unit_std_and_keeps_constant_dims() {
        let s = array![[1.0, 5.0], [3.0, 5.0], [5.0, 5.0]];
        let a = array![[0.0], [1.0], [2.0]];
        let map = InputMap::fit(s.view(), a.view(), true).unwrap();
        let x = map.apply(s.view(), a.view()).unwrap();
        for j in [0, 2] {
            let c = x.column(j);
            assert!(c.sum().abs() < 1e-12);
            assert!((c.mapv(|v| v * v).sum() / 3.0 - 1.0).abs() < 1e-12);
        }
        // The constant dimension is centred, not scaled.
        assert_eq!(map.scale[1], 1.0);
        assert!(x.column(1).iter().all(|v| *v == 0.0));
        let g = map.action_grad(Array2::ones((3, 3)).view());
        assert!((g[[0, 0]] - 1.0 / map.scale[2]).abs() < 1e-12);
    }

    #[test]
    fn a_floor_divides_narrow_and_constant_dims_by_itself_only() {
        // spreads: 2 (wide), 0.01 (narrow), 0 (constant); floor 0.5.
        let s = array![[-2.0, 0.99, 7.0], [2.0, 1.01, 7.0]];
        let a = array![[0.0], [0.0]];
        let map = InputMap::fit_floored(s.view(), a.view(), true, 0.5).unwrap();
        assert_eq!(map.scale, vec![2.0, 0.5, 0.5, 0.5]);
        assert_eq!(map.mean, vec![0.0, 1.0, 7.0, 0.0]);
        // a step of 0.1 off the narrow dimension reads as 0.2, not 10.
        let x = map
            .apply(array![[0.0, 1.1, 7.0]].view(), array![[0.0]].view())
            .unwrap();
        assert!((x[[0, 1]] - 0.2).abs() < 1e-12);
        // no floor (0) is the plain rule.
        let plain = InputMap::fit_floored(s.view(), a.view(), true, 0.0).unwrap();
        assert_eq!(plain, InputMap::fit(s.view(), a.view(), true).unwrap());
        assert_eq!(plain.scale[2], 1.0);
        assert!((plain.scale[1] - 0.01).abs() < 1e-12);
    }

    #[test]
    fn periodic_dims_read_by_their_phase_after_the_action() {
        let p = PeriodicDim {
            dim: 1,
            period: 2.0,
        };
        let s = array![[0.5, 0.3], [0.5, 2.3], [0.5, -1.7]];
        let a = array![[0.25], [0.25], [0.25]];
        let map = InputMap::fit(s.view(), a.view(), false)
            .unwrap()
            .with_periodic(&[p])
            .unwrap();
        assert_eq!(map.dim(), 5);
        let x = map.apply(s.view(), a.view()).unwrap();
        let r = 2.0 / std::f64::consts::TAU;
        let phase = 0.3 / r;
        for i in 0..3 {
            // the state's other dimension and the action are unchanged, the
            // periodic one reads 0 in its place; values a period apart read
            // the same.
            assert_eq!(x[[i, 0]], 0.5);
            assert_eq!(x[[i, 1]], 0.0);
            assert_eq!(x[[i, 2]], 0.25);
            assert!((x[[i, 3]] - r * phase.cos()).abs() < 1e-12);
            assert!((x[[i, 4]] - r * phase.sin()).abs() < 1e-12);
        }
        // a small step moves the input by about as much as the value.
        let step = map
            .apply(array![[0.5, 0.301]].view(), array![[0.25]].view())
            .unwrap();
        let moved =
            ((step[[0, 3]] - x[[0, 3]]).powi(2) + (step[[0, 4]] - x[[0, 4]]).powi(2)).sqrt();
        assert!((moved - 0.001).abs() < 1e-6, "{moved}");
        // the action's gradient is read from the action's column only.
        let mut g = Array2::zeros((1, 5));
        g[[0, 2]] = 3.0;
        g[[0, 3]] = 7.0;
        assert_eq!(map.action_grad(g.view()), array![[3.0]]);
    }

    #[test]
    fn capped_dims_read_no_higher_than_the_cap_and_standardise_capped() {
        let caps = [CappedDim { dim: 0, max: 1.0 }];
        let s = array![[0.0, 4.0], [2.0, 5.0], [0.5, 6.0]];
        let a = array![[0.0], [1.0], [2.0]];
        let map = InputMap::fit(s.view(), a.view(), false)
            .unwrap()
            .with_caps(&caps)
            .unwrap();
        let x = map.apply(s.view(), a.view()).unwrap();
        assert_eq!(x.column(0).to_vec(), vec![0.0, 1.0, 0.5]);
        assert_eq!(x.column(1).to_vec(), vec![4.0, 5.0, 6.0]);
        // standardised on the capped batch: the capped column has mean 0.
        let capped = cap_states(s.view(), &caps).unwrap();
        let std_map = InputMap::fit(capped.view(), a.view(), true)
            .unwrap()
            .with_caps(&caps)
            .unwrap();
        let z = std_map.apply(s.view(), a.view()).unwrap();
        assert!(z.column(0).sum().abs() < 1e-12);
        assert_eq!(z, std_map.apply(capped.view(), a.view()).unwrap());
        for (dims, want) in [
            (
                vec![CappedDim { dim: 2, max: 1.0 }],
                "state dimension 2 does not exist",
            ),
            (
                vec![CappedDim {
                    dim: 0,
                    max: f64::INFINITY,
                }],
                "capped_state_dims[0].max",
            ),
            (
                vec![
                    CappedDim { dim: 1, max: 1.0 },
                    CappedDim { dim: 1, max: 2.0 },
                ],
                "capped_state_dims[1].dim",
            ),
        ] {
            let e = map.clone().with_caps(&dims).unwrap_err();
            assert!(e.to_string().contains(want), "{e}");
        }
    }

    #[test]
    fn periodic_columns_read_the_raw_value_when_standardising_and_round_trip() {
        let p = PeriodicDim {
            dim: 0,
            period: 0.5,
        };
        let caps = [CappedDim { dim: 1, max: 2.0 }];
        let s = array![[1.0, 1.0], [3.0, 2.0], [8.0, 6.0]];
        let a = array![[0.0], [1.0], [5.0]];
        let map = InputMap::fit(cap_states(s.view(), &caps).unwrap().view(), a.view(), true)
            .unwrap()
            .with_periodic(&[p])
            .unwrap()
            .with_caps(&caps)
            .unwrap();
        let x = map.apply(s.view(), a.view()).unwrap();
        for i in 0..3 {
            assert_eq!([x[[i, 3]], x[[i, 4]]], p.features(s[[i, 0]]));
        }
        let back: InputMap = serde_json::from_str(&serde_json::to_string(&map).unwrap()).unwrap();
        assert_eq!(back, map);
        assert_eq!(back.apply(s.view(), a.view()).unwrap(), x);
        let e = cap_states(array![[f64::NAN, 0.0]].view(), &caps).unwrap_err();
        assert!(e.to_string().contains("states"), "{e}");
    }

    #[test]
    fn bad_periodic_dims_are_refused_by_name() {
        let s = array![[0.0, 1.0]];
        let a = array![[0.0]];
        let map = InputMap::fit(s.view(), a.view(), false).unwrap();
        for (dims, want) in [
            (vec![(2, 1.0)], "state dimension 2 does not exist"),
            (vec![(0, 0.0)], "periodic_state_dims[0].period"),
            (vec![(0, f64::NAN)], "periodic_state_dims[0].period"),
            (vec![(1, 1.0), (1, 2.0)], "periodic_state_dims[1].dim"),
        ] {
            let dims: Vec<PeriodicDim> = dims
                .into_iter()
                .map(|(dim, period)| PeriodicDim { dim, period })
                .collect();
            let e = map.clone().with_periodic(&dims).unwrap_err();
            assert!(e.to_string().contains(want), "{e}");
        }
    }

    #[test]
    fn ignored_state_dims_read_as_zero_and_the_rest_is_unchanged() {
        let s = array![[1.0, 5.0, -3.0], [3.0, 6.0, 4.0]];
        let a = array![[0.5], [1.5]];
        let map = InputMap::fit(s.view(), a.view(), true).unwrap();
        let full = map.apply(s.view(), a.view()).unwrap();
        let some = map.clone().ignoring(&[2, 0, 2]).unwrap();
        assert_eq!(some.ignored, vec![0, 2]);
        let x = some.apply(s.view(), a.view()).unwrap();
        for r in 0..2 {
            assert_eq!(x[[r, 0]], 0.0);
            assert_eq!(x[[r, 2]], 0.0);
            assert_eq!(x[[r, 1]], full[[r, 1]]);
            assert_eq!(x[[r, 3]], full[[r, 3]]);
        }
        // any value of an ignored dimension gives the same row
        let far = some
            .apply(array![[100.0, 5.0, -70.0]].view(), array![[0.5]].view())
            .unwrap();
        assert_eq!(far.row(0), x.row(0));
        // a saved map naming an action column is refused when used
        let mut bad = some.clone();
        bad.ignored = vec![3];
        assert!(bad.apply(s.view(), a.view()).is_err());
        let e = map.ignoring(&[3]).unwrap_err();
        assert!(e.to_string().contains("ignored_state_dims"), "{e}");
        // a map saved without the field reads back with none ignored
        let json =
            serde_json::to_string(&InputMap::fit(s.view(), a.view(), true).unwrap()).unwrap();
        assert!(!json.contains("ignored"), "{json}");
        let back: InputMap = serde_json::from_str(&json).unwrap();
        assert!(back.ignored.is_empty());
    }

    #[test]
    fn bad_batches_are_rejected_with_the_field() {
        let map = InputMap::fit(
            Array2::zeros((2, 2)).view(),
            Array2::zeros((2, 1)).view(),
            false,
        )
        .unwrap();
        let e = map
            .apply(Array2::zeros((2, 3)).view(), Array2::zeros((2, 1)).view())
            .unwrap_err();
        assert!(e.to_string().contains("states"), "{e}");
        let e = map
            .apply(Array2::zeros((2, 2)).view(), Array2::zeros((3, 1)).view())
            .unwrap_err();
        assert!(e.to_string().contains("actions"), "{e}");
        let mut a = Array2::zeros((2, 1));
        a[[1, 0]] = f64::NAN;
        assert!(matches!(
            map.apply(Array2::zeros((2, 2)).view(), a.view()),
            Err(Error::NonFinite { .. })
        ));
    }
}
