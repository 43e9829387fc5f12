//! A network that can only be evaluated (RND's fixed random target).

use ndarray::{Array2, ArrayView2};
use serde::{Deserialize, Serialize};

use crate::config::MlpConfig;
use crate::mlp::{Mlp, Workspace};

/// An [`Mlp`] whose parameters cannot change: it offers inference only, no
/// tape, no gradients, no optimiser access. RND's target network is one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct FrozenMlp(Mlp);

impl FrozenMlp {
    /// Freezes `net`.
    pub fn new(net: Mlp) -> Self {
        FrozenMlp(net)
    }

    /// See [`Mlp::forward`]: output view of shape `(batch, output)` for `x`
    /// of shape `(batch, input)`.
    ///
    /// # Panics
    /// When `x` does not have `input_dim()` columns.
    pub fn forward<'w>(
        &self,
        x: ArrayView2<'_, f32>,
        ws: &'w mut Workspace,
    ) -> ArrayView2<'w, f32> {
        self.0.forward(x, ws)
    }

    /// See [`Mlp::predict`].
    ///
    /// # Panics
    /// When `x` does not have `input_dim()` columns.
    pub fn predict(&self, x: ArrayView2<'_, f32>) -> Array2<f32> {
        self.0.predict(x)
    }

    /// Width of the input.
    pub fn input_dim(&self) -> usize {
        self.0.input_dim()
    }

    /// Width of the output.
    pub fn output_dim(&self) -> usize {
        self.0.output_dim()
    }

    /// The config of the wrapped network.
    pub fn config(&self) -> &MlpConfig {
        self.0.config()
    }

    /// Read-only access to the wrapped network (for saving or inspection).
    pub fn as_mlp(&self) -> &Mlp {
        &self.0
    }
}
