//! Losses.

use ndarray::{Array2, ArrayView2};

/// Mean squared error over all elements and its gradient.
///
/// `pred` and `target` have the same shape `(batch, k)`. Returns
/// `mean((pred - target)^2)` (accumulated in f64) and `d loss / d pred =
/// 2 (pred - target) / (batch * k)`, shape `(batch, k)`.
///
/// # Panics
/// When the shapes differ.
pub fn mse_loss(pred: ArrayView2<'_, f32>, target: ArrayView2<'_, f32>) -> (f32, Array2<f32>) {
    let mut grad = Array2::zeros(pred.raw_dim());
    let loss = mse_loss_into(pred, target, &mut grad);
    (loss, grad)
}

/// [`mse_loss`] writing the gradient into `grad` (reshaped if needed), so a
/// training loop allocates nothing.
///
/// # Panics
/// When `pred` and `target` shapes differ.
pub fn mse_loss_into(
    pred: ArrayView2<'_, f32>,
    target: ArrayView2<'_, f32>,
    grad: &mut Array2<f32>,
) -> f32 {
    assert_eq!(
        pred.dim(),
        target.dim(),
        "mse_loss: prediction and target shapes differ"
    );
    if grad.dim() != pred.dim() {
        *grad = Array2::zeros(pred.raw_dim());
    }
    let n = pred.len();
    if n == 0 {
        return 0.0;
    }
    let scale = 2.0 / n as f32;
    let mut sum = 0.0f64;
    ndarray::Zip::from(grad)
        .and(&pred)
        .and(&target)
        .for_each(|g, &p, &t| {
            let d = p - t;
            *g = scale * d;
            sum += (d * d) as f64;
        });
    (sum / n as f64) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::array;

    #[test]
    fn mse_value_and_gradient() {
        let p = array![[1.0f32, 2.0], [3.0, -1.0]];
        let t = array![[0.0f32, 2.0], [1.0, 1.0]];
        let (l, g) = mse_loss(p.view(), t.view());
        assert!((l - (1.0 + 0.0 + 4.0 + 4.0) / 4.0).abs() < 1e-7);
        assert_eq!(g, array![[0.5f32, 0.0], [1.0, -1.0]]);
        // Central differences on one entry.
        let h = 1e-3f32;
        let mut pp = p.clone();
        pp[[1, 0]] += h;
        let lp = mse_loss(pp.view(), t.view()).0;
        pp[[1, 0]] -= 2.0 * h;
        let lm = mse_loss(pp.view(), t.view()).0;
        assert!(((lp - lm) / (2.0 * h) - g[[1, 0]]).abs() < 1e-3);
    }
}
