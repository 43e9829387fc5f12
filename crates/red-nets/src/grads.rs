//! Parameter gradients (and parameter-shaped vectors in general).

use ndarray::{Array1, Array2};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// One layer's part of a [`Gradients`]: `dw` has the layer's weight shape
/// `(in, out)`, `db` its bias shape `(out,)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LayerGrad {
    /// Gradient (or direction) for the weights, shape `(in, out)`.
    pub dw: Array2<f32>,
    /// Gradient (or direction) for the biases, shape `(out,)`.
    pub db: Array1<f32>,
}

/// A vector in parameter space with the layout of an [`crate::Mlp`]: gradients
/// accumulated by [`crate::Mlp::backward`], directions for [`crate::Mlp::jvp`], optimiser
/// moments.
///
/// The flat layout ([`Gradients::flat`]) is the same as
/// [`crate::Mlp::params_flat`]: layer by layer, the weights in row-major `(in, out)`
/// order, then the biases.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Gradients {
    layers: Vec<LayerGrad>,
}

impl Gradients {
    /// A vector made of these per-layer parts (the layout of a net is
    /// given by the constructors in `mlp.rs`: [`Gradients::zeros`],
    /// [`Gradients::from_flat`]).
    pub(crate) fn from_layers(layers: Vec<LayerGrad>) -> Gradients {
        Gradients { layers }
    }

    /// The per-layer parts, input layer first.
    pub fn layers(&self) -> &[LayerGrad] {
        &self.layers
    }

    /// Mutable per-layer parts. Changing an array's shape breaks the layout
    /// and makes later calls panic or fail.
    pub fn layers_mut(&mut self) -> &mut [LayerGrad] {
        &mut self.layers
    }

    /// Total number of entries (equals [`crate::Mlp::num_params`] of the net it came from).
    pub fn len(&self) -> usize {
        self.layers.iter().map(|l| l.dw.len() + l.db.len()).sum()
    }

    /// Whether there are no entries at all.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn same_layout(&self, other: &Gradients) -> bool {
        self.layers.len() == other.layers.len()
            && self
                .layers
                .iter()
                .zip(&other.layers)
                .all(|(a, b)| a.dw.dim() == b.dw.dim() && a.db.dim() == b.db.dim())
    }

    /// All entries in the flat order of [`crate::Mlp::params_flat`].
    pub fn flat(&self) -> Vec<f32> {
        let mut v = Vec::with_capacity(self.len());
        for l in &self.layers {
            v.extend(l.dw.iter());
            v.extend(l.db.iter());
        }
        v
    }

    /// Euclidean norm of all entries (accumulated in f64).
    pub fn norm(&self) -> f32 {
        self.dot(self).unwrap_or(f64::NAN).sqrt() as f32
    }

    /// Inner product with `other` (accumulated in f64).
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] when the layouts differ.
    pub fn dot(&self, other: &Gradients) -> Result<f64> {
        if !self.same_layout(other) {
            return Err(Error::shape(
                "Gradients::dot",
                "the same layout",
                "a different layout",
            ));
        }
        let mut s = 0.0f64;
        for (a, b) in self.layers.iter().zip(&other.layers) {
            s +=
                a.dw.iter()
                    .zip(b.dw.iter())
                    .map(|(&x, &y)| x as f64 * y as f64)
                    .sum::<f64>();
            s +=
                a.db.iter()
                    .zip(b.db.iter())
                    .map(|(&x, &y)| x as f64 * y as f64)
                    .sum::<f64>();
        }
        Ok(s)
    }

    /// Multiplies every entry by `a`.
    pub fn scale(&mut self, a: f32) {
        for l in &mut self.layers {
            l.dw.mapv_inplace(|x| x * a);
            l.db.mapv_inplace(|x| x * a);
        }
    }

    /// Sets every entry to zero (keeps the allocation).
    pub fn zero(&mut self) {
        for l in &mut self.layers {
            l.dw.fill(0.0);
            l.db.fill(0.0);
        }
    }

    /// `self += a * other`.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] when the layouts differ.
    pub fn add_scaled(&mut self, other: &Gradients, a: f32) -> Result<()> {
        if !self.same_layout(other) {
            return Err(Error::shape(
                "Gradients::add_scaled",
                "the same layout",
                "a different layout",
            ));
        }
        for (s, o) in self.layers.iter_mut().zip(&other.layers) {
            s.dw.scaled_add(a, &o.dw);
            s.db.scaled_add(a, &o.db);
        }
        Ok(())
    }

    /// Whether every entry is finite. One pass, no early exit: a non-finite
    /// entry makes `x * 0` NaN, which poisons the sum.
    pub fn is_finite(&self) -> bool {
        let mut acc = 0.0f32;
        for l in &self.layers {
            acc += l.dw.iter().fold(0.0f32, |s, &x| s + x * 0.0);
            acc += l.db.iter().fold(0.0f32, |s, &x| s + x * 0.0);
        }
        acc == 0.0
    }
}

/// Scales `grads` so that their norm is at most `max_norm` and returns the
/// norm BEFORE clipping (as PyTorch's `clip_grad_norm_`).
///
/// Gradients whose norm is NaN or infinite are left unchanged (the returned
/// norm tells the caller); a negative `max_norm` is treated as 0.
pub fn clip_grad_norm(grads: &mut Gradients, max_norm: f32) -> f32 {
    let norm = grads.norm();
    let max_norm = max_norm.max(0.0);
    if norm.is_finite() && norm > max_norm {
        grads.scale(max_norm / norm);
    }
    norm
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::MlpConfig;
    use crate::mlp::Mlp;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    fn net() -> Mlp {
        Mlp::new(
            &MlpConfig::new(3, &[4], 2),
            &mut ChaCha8Rng::seed_from_u64(0),
        )
        .unwrap()
    }

    #[test]
    fn flat_round_trip_and_algebra() {
        let n = net();
        let v: Vec<f32> = (0..n.num_params()).map(|i| i as f32 * 0.5 - 3.0).collect();
        let g = Gradients::from_flat(&n, &v).unwrap();
        assert_eq!(g.flat(), v);
        assert_eq!(g.len(), n.num_params());
        let want: f64 = v.iter().map(|&x| (x as f64).powi(2)).sum::<f64>().sqrt();
        assert!((g.norm() as f64 - want).abs() < 1e-4 * want);
        let mut h = g.clone();
        h.add_scaled(&g, -2.0).unwrap();
        assert_eq!(h.flat(), v.iter().map(|&x| -x).collect::<Vec<_>>());
        h.scale(0.0);
        assert_eq!(h.norm(), 0.0);
        assert!(Gradients::from_flat(&n, &v[1..]).is_err());
        let other = Gradients::zeros(
            &Mlp::new(
                &MlpConfig::new(3, &[5], 2),
                &mut ChaCha8Rng::seed_from_u64(0),
            )
            .unwrap(),
        );
        assert!(h.add_scaled(&other, 1.0).is_err());
        assert!(!other.matches(&n) && h.matches(&n));
    }

    #[test]
    fn clip_grad_norm_scales_only_above_the_limit() {
        let n = net();
        let v: Vec<f32> = (0..n.num_params()).map(|i| (i % 5) as f32 - 2.0).collect();
        let mut g = Gradients::from_flat(&n, &v).unwrap();
        let before = g.norm();
        let returned = clip_grad_norm(&mut g, before * 2.0);
        assert_eq!(returned, before);
        assert_eq!(g.flat(), v, "below the limit nothing changes");
        let returned = clip_grad_norm(&mut g, 1.5);
        assert_eq!(returned, before);
        assert!((g.norm() - 1.5).abs() < 1e-5, "clipped norm {}", g.norm());
        // Direction is kept.
        let ratio = 1.5 / before;
        for (a, b) in g.flat().iter().zip(&v) {
            assert!((a - b * ratio).abs() < 1e-6);
        }
        let mut bad = g.clone();
        bad.layers_mut()[0].db[0] = f32::NAN;
        assert!(!bad.is_finite() && g.is_finite());
        assert!(clip_grad_norm(&mut bad, 1.0).is_nan());
    }
}
