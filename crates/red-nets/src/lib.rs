//! Dense neural networks for the `red` workspace: multilayer perceptrons on
//! [`ndarray`] with f32 parameters, a training tape with exact reverse-mode
//! ([`Mlp::backward`]) and forward-mode ([`Mlp::jvp`]) derivatives, Adam and
//! SGD with L2 weight decay, Glorot and orthogonal initialisers, and JSON
//! save/load that round-trips exactly. No knowledge of RL.
//!
//! Batches are rows: inputs have shape `(batch, input)`, outputs
//! `(batch, output)`; weights have shape `(in, out)`.
//!
//! Fit `y = 2x - 1` with a tiny net:
//!
//! ```
//! use ndarray::Array2;
//! use rand::SeedableRng;
//! use red_nets::{mse_loss, Activation, Adam, AdamConfig, Mlp, MlpConfig, Optimizer, Tape};
//!
//! # fn main() -> red_nets::Result<()> {
//! let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
//! let config = MlpConfig::new(1, &[16], 1).with_activation(Activation::Tanh);
//! let mut net = Mlp::new(&config, &mut rng)?;
//! let mut adam = Adam::new(AdamConfig::with_lr(1e-2), &net)?;
//! let x = Array2::from_shape_fn((32, 1), |(i, _)| i as f32 / 16.0 - 1.0);
//! let y = x.mapv(|v| 2.0 * v - 1.0);
//! let (mut tape, mut grads) = (Tape::new(), net.zero_grads());
//! let mut loss = f32::INFINITY;
//! for _ in 0..300 {
//!     let pred = net.forward_tape(x.view(), &mut tape);
//!     let (l, dpred) = mse_loss(pred, y.view());
//!     grads.zero();
//!     net.backward(&tape, dpred.view(), &mut grads);
//!     adam.step(&mut net, &grads)?;
//!     loss = l;
//! }
//! assert!(loss < 1e-2, "loss {loss}");
//! let restored = Mlp::from_json(&net.to_json()?)?;
//! assert_eq!(restored.predict(x.view()), net.predict(x.view()));
//! # Ok(())
//! # }
//! ```

mod activation;
mod config;
mod error;
mod frozen;
mod grads;
pub mod init;
mod loss;
mod mlp;
mod optim;

pub use activation::{Activation, LEAKY_RELU_SLOPE, tanh_f32};
pub use config::{Init, MlpConfig};
pub use error::{Error, Result};
pub use frozen::FrozenMlp;
pub use grads::{Gradients, LayerGrad, clip_grad_norm};
pub use loss::{mse_loss, mse_loss_into};
pub use mlp::{Layer, MLP_FORMAT, MLP_FORMAT_VERSION, Mlp, Tape, Workspace};
pub use optim::{ADAM_FORMAT, ADAM_FORMAT_VERSION, Adam, AdamConfig, Optimizer, Sgd, SgdConfig};

// The exact versions of the crates this crate's API takes and returns,
// so that a dependant names the same types (a second version of ndarray or
// rand in a build gives type errors that never mention versions).
pub use ndarray;
pub use rand;
pub use rand_chacha;
