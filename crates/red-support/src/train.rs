//! The regression loop shared by RND's predictor and the autoencoder:
//! shuffled minibatches, mean squared error, one Adam step per batch.

use ndarray::{Array2, ArrayView2};
use rand::Rng;
use rand::seq::SliceRandom;
use red_nets::{Adam, AdamConfig, Gradients, Mlp, Optimizer, Tape, mse_loss_into};

use crate::estimator::FitProgress;
use crate::{Error, Result};

/// Settings of one regression run.
pub(crate) struct Regression<'a> {
    pub epochs: usize,
    pub batch_size: usize,
    pub adam: &'a AdamConfig,
    /// Progress units already done before this run, and in all (for
    /// ensembles trained one after another).
    pub progress_offset: usize,
    pub progress_total: usize,
}

/// Trains `net` to map the rows of `x` (`(n, in)`) to the rows of `y`
/// (`(n, out)`) by minimising the mean squared error over shuffled
/// minibatches (the last one of an epoch may be smaller). Returns the mean
/// batch loss of the last epoch.
pub(crate) fn fit_regression<R: Rng + ?Sized>(
    net: &mut Mlp,
    x: ArrayView2<'_, f32>,
    y: ArrayView2<'_, f32>,
    settings: &Regression<'_>,
    rng: &mut R,
    progress: &mut dyn FnMut(FitProgress),
) -> Result<f64> {
    let n = x.nrows();
    let (din, dout) = (x.ncols(), y.ncols());
    let mut adam = Adam::new(settings.adam.clone(), net)?;
    let mut grads: Gradients = net.zero_grads();
    let mut tape = Tape::new();
    let mut order: Vec<usize> = (0..n).collect();
    let bs = settings.batch_size.min(n);
    let mut xb = Array2::<f32>::zeros((bs, din));
    let mut yb = Array2::<f32>::zeros((bs, dout));
    let mut gout = Array2::<f32>::zeros((bs, dout));
    let mut last = f64::NAN;
    for epoch in 0..settings.epochs {
        order.shuffle(rng);
        let mut total = 0.0f64;
        let mut batches = 0usize;
        for chunk in order.chunks(bs) {
            let m = chunk.len();
            if xb.nrows() != m {
                xb = Array2::zeros((m, din));
                yb = Array2::zeros((m, dout));
            }
            for (r, &i) in chunk.iter().enumerate() {
                xb.row_mut(r).assign(&x.row(i));
                yb.row_mut(r).assign(&y.row(i));
            }
            let pred = net.forward_tape(xb.view(), &mut tape);
            let loss = mse_loss_into(pred, yb.view(), &mut gout);
            if !loss.is_finite() {
                // Name the first pair whose input, target or prediction is
                // not finite (its index among the fitted rows).
                let bad = (0..m).find(|&r| {
                    let row_bad =
                        |a: ndarray::ArrayView1<'_, f32>| a.iter().any(|v| !v.is_finite());
                    row_bad(xb.row(r)) || row_bad(yb.row(r)) || row_bad(pred.row(r))
                });
                let pair = bad.map_or_else(String::new, |r| {
                    format!(
                        " (first non-finite value at pair {} of the {n} fitted pairs, counted \
                         through the trajectories in order)",
                        chunk[r]
                    )
                });
                return Err(Error::NonFinite {
                    what: format!("training loss at epoch {epoch}{pair}"),
                });
            }
            grads.zero();
            net.backward(&tape, gout.view(), &mut grads);
            adam.step(net, &grads)?;
            total += f64::from(loss);
            batches += 1;
        }
        last = total / batches as f64;
        progress(FitProgress {
            done: settings.progress_offset + epoch + 1,
            total: settings.progress_total,
            loss: Some(last),
        });
    }
    Ok(last)
}

/// The rows of `x` as f32.
pub(crate) fn to_f32(x: ArrayView2<'_, f64>) -> Array2<f32> {
    x.mapv(|v| v as f32)
}
