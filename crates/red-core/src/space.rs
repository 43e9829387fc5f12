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

    /// A uniformly random element. A box dimension with an infinite bound is
    /// drawn uniformly from `[-1, 1]` instead.
    pub fn sample<R: Rng + ?Sized>(&self, rng: &mut R) -> Vec<f64> {
        match self {
            Space::Box(b) => b
                .low
                .iter()
                .zip(&b.high)
                .map(|(&l, &h)| {
                    if l.is_finite() && h.is_finite() {
                        if l == h { l } else { rng.random_range(l..=h) }
                    } else {
                        rng.random_range(-1.0..=1.0)
                    }
                })
                .collect(),
            Space::Discrete(n) => vec![rng.random_range(0..*n) as f64],
        }
    }
}
