//! Observation and action spaces.

use rand::{Rng, RngExt};
use serde::{Deserialize, Serialize};

use crate::{Error, Result};

/// A box of real vectors `low[i] <= x[i] <= high[i]`; bounds may be infinite.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoxSpace {
    /// Lower bounds, one per dimension.
    pub low: Vec<f64>,
    /// Upper bounds, one per dimension.
    pub high: Vec<f64>,
}

impl BoxSpace {
    /// A box with the given bounds.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] if the bound vectors differ in length,
    /// [`Error::InvalidConfig`] if a bound is NaN or `low > high`.
    pub fn new(low: Vec<f64>, high: Vec<f64>) -> Result<Self> {
        if low.len() != high.len() {
            return Err(Error::ShapeMismatch {
                what: "box bounds".into(),
                expected: format!("{} upper bounds", low.len()),
                got: format!("{}", high.len()),
            });
        }
        for (i, (l, h)) in low.iter().zip(&high).enumerate() {
            if l.is_nan() || h.is_nan() || l > h {
                return Err(Error::InvalidConfig {
                    field: format!("box bounds[{i}]"),
                    reason: format!("need low <= high, got [{l}, {h}]"),
                });
            }
        }
        Ok(Self { low, high })
    }

    /// The box `[low, high]^dim`.
    pub fn uniform(dim: usize, low: f64, high: f64) -> Self {
        Self {
            low: vec![low; dim],
            high: vec![high; dim],
        }
    }

    /// Number of dimensions.
    pub fn dim(&self) -> usize {
        self.low.len()
    }

    /// The rows of `x`, `(n, dim)`, each entry clipped into its bounds (what
    /// an environment that clips executes); `(n, dim)` out.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] if `x` does not have `dim` columns.
    pub fn clip_rows(&self, x: ndarray::ArrayView2<'_, f64>) -> Result<ndarray::Array2<f64>> {
        if x.ncols() != self.dim() {
            return Err(Error::ShapeMismatch {
                what: "rows to clip into the box".into(),
                expected: format!("{} columns", self.dim()),
                got: format!("{} columns", x.ncols()),
            });
        }
        let mut y = x.to_owned();
        for mut row in y.rows_mut() {
            for ((v, l), h) in row.iter_mut().zip(&self.low).zip(&self.high) {
                *v = v.max(*l).min(*h);
            }
        }
        Ok(y)
    }
}

/// The space of an observation or an action.
///
/// A discrete action is passed to [`crate::Env::step`] as a slice of one
/// number, the index `0..n` as `f64`, so that every learner and reward model
/// sees actions as real vectors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Space {
    /// Real vectors inside a box.
    Box(BoxSpace),
    /// One of `n` choices, `0..n`.
    Discrete(usize),
}

impl Space {
    /// Length of the vector that represents an element (1 for discrete).
    pub fn dim(&self) -> usize {
        match self {
            Space::Box(b) => b.dim(),
            Space::Discrete(_) => 1,
        }
    }

    /// Checks that the space itself is well formed: a box has as many lower
    /// as upper bounds, none NaN, `low <= high`; a discrete space has at
    /// least one element. [`Space::sample`] needs a well-formed space.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] for bound vectors of different lengths,
    /// [`Error::InvalidConfig`] for a NaN bound, `low > high`, or
    /// `Discrete(0)`.
    pub fn validate(&self) -> Result<()> {
        match self {
            Space::Box(b) => BoxSpace::new(b.low.clone(), b.high.clone()).map(|_| ()),
            Space::Discrete(0) => Err(Error::InvalidConfig {
                field: "discrete space".into(),
                reason: "needs at least one element, got Discrete(0)".into(),
            }),
            Space::Discrete(_) => Ok(()),
        }
    }

    /// Whether `x` is an element of the space (finite, right length, in
    /// bounds; for discrete, an integer in `0..n`).
    pub fn contains(&self, x: &[f64]) -> bool {
        match self {
            Space::Box(b) => {
                x.len() == b.dim()
                    && x.iter()
                        .zip(b.low.iter().zip(&b.high))
                        .all(|(v, (l, h))| v.is_finite() && *v >= *l && *v <= *h)
            }
            Space::Discrete(n) => {
                x.len() == 1
                    && x[0].is_finite()
                    && x[0].fract() == 0.0
                    && x[0] >= 0.0
                    && x[0] < *n as f64
            }
        }
    }

    /// Checks `x` against the space.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] for a wrong length, [`Error::NonFinite`] for
    /// NaN or infinity, [`Error::InvalidAction`] for a value out of bounds.
    pub fn check(&self, what: &str, x: &[f64]) -> Result<()> {
        if x.len() != self.dim() {
            return Err(Error::ShapeMismatch {
                what: what.into(),
                expected: format!("{} numbers", self.dim()),
                got: format!("{}", x.len()),
            });
        }
        if x.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite { what: what.into() });
        }
        if !self.contains(x) {
            return Err(Error::InvalidAction {
                reason: format!("{what} {x:?} is outside {self:?}"),
            });
        }
        Ok(())
    }

    /// A uniformly random element. A box dimension unbounded on both sides
    /// is drawn uniformly from `[-1, 1]` instead, one bounded on one side
    /// only from the two units next to its finite bound.
    ///
    /// # Panics
    /// On a malformed space (`Discrete(0)`, `low > high`, a NaN bound);
    /// [`Space::validate`] tells those apart beforehand.
    pub fn sample<R: Rng + ?Sized>(&self, rng: &mut R) -> Vec<f64> {
        match self {
            Space::Box(b) => b
                .low
                .iter()
                .zip(&b.high)
                .map(|(&l, &h)| match (l.is_finite(), h.is_finite()) {
                    (true, true) if l == h => l,
                    (true, true) if (h - l).is_finite() => rng.random_range(l..=h),
                    // So wide that the width overflows: centre on zero.
                    (true, true) => rng.random_range(-1.0..=1.0),
                    (true, false) => l + rng.random_range(0.0..=2.0),
                    (false, true) => h - rng.random_range(0.0..=2.0),
                    (false, false) => rng.random_range(-1.0..=1.0),
                })
                .collect(),
            Space::Discrete(n) => vec![rng.random_range(0..*n) as f64],
        }
    }
}
