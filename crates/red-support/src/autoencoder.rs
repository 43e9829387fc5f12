//! The over-parametrised autoencoder as support estimation (paper Sec. 3.5):
//! one wide hidden layer reconstructs `x = [s, a]`, with L2 weight decay
//! keeping it from the identity; the score is the MEAN squared
//! reconstruction error over the `d` input dimensions.

use ndarray::{Array1, Array2, ArrayView2};
use rand::Rng;
use red_nets::{Activation, AdamConfig, Init, Mlp, MlpConfig, Tape, Workspace};
use serde::{Deserialize, Serialize};

use crate::estimator::{FitProgress, SupportEstimatorConfig, SupportModel};
use crate::input::InputMap;
use crate::rnd::prefix;
use crate::train::{Regression, fit_regression, to_f32};
use crate::{Error, Result};

/// Hyperparameters of [`Autoencoder`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AutoencoderConfig {
    /// Width of the single hidden layer.
    pub hidden: usize,
    /// Its activation (the output is linear).
    pub activation: Activation,
    /// Weight initialisation (biases start at 0).
    pub init: Init,
    /// Passes over the expert pairs.
    pub epochs: usize,
    /// Minibatch size.
    pub batch_size: usize,
    /// The optimiser, with the L2 weight decay in `adam.weight_decay`.
    pub adam: AdamConfig,
    /// Standardise `[s, a]` with the expert mean and standard deviation.
    pub standardize: bool,
}

impl Default for AutoencoderConfig {
    /// From the RED release (reference/original-red.md): one hidden layer,
    /// leaky relu, Glorot-uniform, L2 weight decay 1e-4, raw input. The
    /// release's width is per task (30 Hopper/Walker2d/HalfCheetah, 100
    /// Reacher, 128 Ant); the general default is 128, the widest, which is
    /// wider than every MuJoCo `[s, a]` up to Ant's 119 numbers
    /// (over-parametrised, as Sec. 3.5 asks). The release's training
    /// schedule for the AE is not recorded in the reference; we use the
    /// RND predictor's (Adam 1e-3, batch 32, 200 epochs).
    fn default() -> Self {
        Self {
            hidden: 128,
            activation: Activation::LeakyRelu,
            init: Init::GlorotUniform,
            epochs: 200,
            batch_size: 32,
            adam: AdamConfig {
                weight_decay: 1e-4,
                ..AdamConfig::with_lr(1e-3)
            },
            standardize: false,
        }
    }
}

impl AutoencoderConfig {
    /// Rejects nonsense values, naming the field.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`].
    pub fn validate(&self) -> Result<()> {
        for (field, v) in [
            ("hidden", self.hidden),
            ("epochs", self.epochs),
            ("batch_size", self.batch_size),
        ] {
            if v == 0 {
                return Err(Error::InvalidConfig {
                    field: field.into(),
                    reason: "must be at least 1".into(),
                });
            }
        }
        self.adam.validate().map_err(|e| prefix("adam", e))
    }
}

/// A fitted autoencoder support estimator.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Autoencoder {
    input: InputMap,
    net: Mlp,
    final_loss: f64,
}

impl Autoencoder {
    /// The network `[s, a] -> hidden -> [s, a]`.
    pub fn net(&self) -> &Mlp {
        &self.net
    }

    /// The mean training loss of the last epoch.
    pub fn final_loss(&self) -> f64 {
        self.final_loss
    }
}

impl SupportModel for Autoencoder {
    fn obs_dim(&self) -> usize {
        self.input.obs_dim
    }

    fn act_dim(&self) -> usize {
        self.input.act_dim
    }

    fn score(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<Array1<f64>> {
        let x = to_f32(self.input.apply(states, actions)?.view());
        let mut ws = Workspace::new();
        let y = self.net.forward(x.view(), &mut ws);
        let d = x.ncols() as f64;
        Ok(x.rows()
            .into_iter()
            .zip(y.rows())
            .map(|(xr, yr)| {
                let s: f32 = xr.iter().zip(yr).map(|(a, b)| (b - a) * (b - a)).sum();
                f64::from(s) / d
            })
            .collect())
    }

    fn score_grad_action(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<(Array1<f64>, Array2<f64>)> {
        let x = to_f32(self.input.apply(states, actions)?.view());
        let mut tape = Tape::new();
        let y = self.net.forward_tape(x.view(), &mut tape);
        let d = x.ncols() as f32;
        // L = mean_j (f_j(x) - x_j)^2: dL/dx = J^T g - g with g = 2 (f - x) / d.
        let g = (&y - &x).mapv(|v| 2.0 * v / d);
        let scores: Array1<f64> = g
            .rows()
            .into_iter()
            .map(|r| f64::from(r.iter().map(|v| v * v).sum::<f32>() * d / 4.0))
            .collect();
        let mut grads = self.net.zero_grads();
        let grad_x = (self.net.backward(&tape, g.view(), &mut grads) - &g).mapv(f64::from);
        Ok((scores, self.input.action_grad(grad_x.view())))
    }
}

impl SupportEstimatorConfig for AutoencoderConfig {
    type Model = Autoencoder;

    fn validate(&self) -> Result<()> {
        AutoencoderConfig::validate(self)
    }

    /// Draws the network from `rng`, then trains it to reconstruct the
    /// expert inputs. Progress counts epochs.
    fn fit<R: Rng + ?Sized>(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
        rng: &mut R,
        progress: &mut dyn FnMut(FitProgress),
    ) -> Result<Autoencoder> {
        self.validate()?;
        let input = InputMap::fit(states, actions, self.standardize)?;
        let x = to_f32(input.apply(states, actions)?.view());
        let d = input.dim();
        let cfg = MlpConfig {
            input: d,
            hidden: vec![self.hidden],
            output: d,
            activation: self.activation,
            output_activation: Activation::Identity,
            init: self.init,
        };
        let mut net = Mlp::new(&cfg, rng).map_err(|e| prefix("network", e))?;
        let final_loss = fit_regression(
            &mut net,
            x.view(),
            x.view(),
            &Regression {
                epochs: self.epochs,
                batch_size: self.batch_size,
                adam: &self.adam,
                progress_offset: 0,
                progress_total: self.epochs,
            },
            rng,
            progress,
        )?;
        Ok(Autoencoder {
            input,
            net,
            final_loss,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimator::no_progress;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn gradient_matches_finite_differences() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let s = Array2::from_shape_fn((64, 3), |_| rng.random_range(-1.0..1.0));
        let a = Array2::from_shape_fn((64, 2), |_| rng.random_range(-1.0..1.0));
        let cfg = AutoencoderConfig {
            hidden: 24,
            epochs: 5,
            standardize: true,
            // Smooth, so finite differences do not straddle leaky relu's kinks.
            activation: Activation::Tanh,
            ..Default::default()
        };
        let model = cfg
            .fit(
                s.view(),
                a.view(),
                &mut ChaCha8Rng::seed_from_u64(2),
                &mut no_progress,
            )
            .unwrap();
        let qs = Array2::from_shape_fn((5, 3), |_| rng.random_range(-2.0..2.0));
        let qa = Array2::from_shape_fn((5, 2), |_| rng.random_range(-2.0..2.0));
        let (sc, g) = model.score_grad_action(qs.view(), qa.view()).unwrap();
        let plain = model.score(qs.view(), qa.view()).unwrap();
        for (x, y) in sc.iter().zip(&plain) {
            assert!((x - y).abs() <= 1e-5 * y.abs().max(1e-6), "{x} vs {y}");
        }
        let eps = 1e-3;
        for r in 0..5 {
            for j in 0..2 {
                let mut ap = qa.clone();
                ap[[r, j]] += eps;
                let mut am = qa.clone();
                am[[r, j]] -= eps;
                let fd = (model.score(qs.view(), ap.view()).unwrap()[r]
                    - model.score(qs.view(), am.view()).unwrap()[r])
                    / (2.0 * eps);
                let an = g[[r, j]];
                assert!(
                    (fd - an).abs() <= 2e-2 * fd.abs().max(an.abs()) + 1e-4,
                    "row {r} dim {j}: fd {fd} vs analytic {an}"
                );
            }
        }
    }

    #[test]
    fn validation_names_the_field() {
        let e = AutoencoderConfig {
            hidden: 0,
            ..Default::default()
        }
        .validate()
        .unwrap_err();
        assert!(e.to_string().contains("hidden"), "{e}");
        let mut c = AutoencoderConfig::default();
        c.adam.weight_decay = -1.0;
        assert!(
            c.validate()
                .unwrap_err()
                .to_string()
                .contains("adam.weight_decay")
        );
    }
}
