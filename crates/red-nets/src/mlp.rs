//! The multilayer perceptron: inference, training tape, backward, jvp, save/load.

use std::path::Path;

use ndarray::linalg::general_mat_mul;
use ndarray::{Array1, Array2, ArrayView2, Axis};
use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::activation::Activation;
use crate::config::MlpConfig;
use crate::error::{Error, Result};
use crate::grads::{Gradients, LayerGrad};
use crate::init::init_weights;

/// Name written into saved networks.
pub const MLP_FORMAT: &str = "red-nets/mlp";
/// Version of the saved-network format written by this crate.
pub const MLP_FORMAT_VERSION: u32 = 1;

/// One dense layer: `out = act(x W + b)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Layer {
    /// Weights, shape `(in, out)`.
    pub w: Array2<f32>,
    /// Biases, shape `(out,)`.
    pub b: Array1<f32>,
}

/// A dense feed-forward network with f32 parameters.
///
/// Inputs are batches of row vectors, shape `(batch, input)`; outputs have
/// shape `(batch, output)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "MlpRepr", into = "MlpRepr")]
pub struct Mlp {
    config: MlpConfig,
    layers: Vec<Layer>,
}

/// Reusable buffers for [`Mlp::forward`]: one output buffer per layer,
/// reallocated only when the batch size (or the network) changes.
#[derive(Debug, Clone, Default)]
pub struct Workspace {
    bufs: Vec<Array2<f32>>,
}

impl Workspace {
    /// An empty workspace; buffers are made on the first forward pass.
    pub fn new() -> Self {
        Workspace::default()
    }
}

/// What [`Mlp::forward_tape`] records for [`Mlp::backward`] and
/// [`Mlp::jvp`]: the input and every layer's activated output.
///
/// Each layer's input is kept, and its activated output; the derivatives of
/// all four [`Activation`]s are exact functions of the output (see
/// [`Activation::derivative_from_output`]), so no pre-activation copy is
/// needed. Buffers are reused across calls at the same batch size.
#[derive(Debug, Clone, Default)]
pub struct Tape {
    /// `acts[0]` is the input, `acts[i + 1]` the output of layer `i`.
    acts: Vec<Array2<f32>>,
}

impl Tape {
    /// An empty tape.
    pub fn new() -> Self {
        Tape::default()
    }

    /// Batch size of the last recorded forward pass (0 if none).
    pub fn batch(&self) -> usize {
        self.acts.first().map_or(0, |a| a.nrows())
    }

    /// The recorded input, shape `(batch, input)` (empty before any pass).
    pub fn input(&self) -> ArrayView2<'_, f32> {
        match self.acts.first() {
            Some(a) => a.view(),
            None => ArrayView2::from_shape((0, 0), &[]).expect("empty view"),
        }
    }

    /// The recorded output, shape `(batch, output)` (empty before any pass).
    pub fn output(&self) -> ArrayView2<'_, f32> {
        match self.acts.last() {
            Some(a) => a.view(),
            None => ArrayView2::from_shape((0, 0), &[]).expect("empty view"),
        }
    }
}

fn ensure_shape(buf: &mut Array2<f32>, rows: usize, cols: usize) {
    if buf.dim() != (rows, cols) {
        *buf = Array2::zeros((rows, cols));
    }
}

/// Batches up to this size skip the general matrix product: matrixmultiply
/// packs the whole weight matrix on every call, which for a single row
/// costs about as much as the product itself.
const SMALL_BATCH: usize = 3;

/// `out = x w` (`x`: `(batch, in)`, `w`: `(in, out)`, contiguous). Small
/// batches use row-times-matrix as a sum of scaled weight rows (a contiguous,
/// vectorisable loop); larger ones the packed general product.
fn affine_product(x: ArrayView2<'_, f32>, w: &Array2<f32>, out: &mut Array2<f32>) {
    if x.nrows() > SMALL_BATCH {
        general_mat_mul(1.0, &x, w, 0.0, out);
        return;
    }
    let width = w.ncols();
    let w = w.as_slice().expect("weights are contiguous");
    for (xr, mut orow) in x.rows().into_iter().zip(out.rows_mut()) {
        let o = orow.as_slice_mut().expect("layer buffers are contiguous");
        o.fill(0.0);
        for (&xi, wrow) in xr.iter().zip(w.chunks_exact(width)) {
            for (oj, &wj) in o.iter_mut().zip(wrow) {
                *oj += xi * wj;
            }
        }
    }
}

/// `out = act(out + b)` row by row, in one pass; the match sits outside the
/// loops so each inner loop is a plain, vectorisable slice loop.
fn bias_act(out: &mut Array2<f32>, b: &Array1<f32>, act: Activation) {
    let n = b.len();
    let b = b.as_slice().expect("biases are contiguous");
    let data = out.as_slice_mut().expect("layer buffers are contiguous");
    if n == 0 {
        return;
    }
    match act {
        Activation::Identity => {
            for row in data.chunks_exact_mut(n) {
                for (y, &bb) in row.iter_mut().zip(b) {
                    *y += bb;
                }
            }
        }
        Activation::Relu => {
            for row in data.chunks_exact_mut(n) {
                for (y, &bb) in row.iter_mut().zip(b) {
                    *y = (*y + bb).max(0.0);
                }
            }
        }
        Activation::LeakyRelu => {
            for row in data.chunks_exact_mut(n) {
                for (y, &bb) in row.iter_mut().zip(b) {
                    let z = *y + bb;
                    *y = if z > 0.0 {
                        z
                    } else {
                        crate::activation::LEAKY_RELU_SLOPE * z
                    };
                }
            }
        }
        Activation::Tanh => tanh_bias_rows(data, b),
    }
}

/// `y = tanh(y + b)` over rows of `b.len()` values. Compiled once per
/// instruction set listed and picked at run time: the default x86-64
/// target only has 4-lane SSE2, while AVX-512 evaluates the polynomial on
/// 16 lanes. Each copy performs the same operations (no fused multiply-add
/// is introduced), so every machine gets the same bits.
#[multiversion::multiversion(targets("x86_64+avx512f+avx512vl", "x86_64+avx2+fma"))]
fn tanh_bias_rows(data: &mut [f32], b: &[f32]) {
    for row in data.chunks_exact_mut(b.len()) {
        for (y, &bb) in row.iter_mut().zip(b) {
            *y = crate::activation::tanh_f32(*y + bb);
        }
    }
}

/// `g *= act'(a)` element-wise, with the derivative taken from the output `a`.
fn mul_act_derivative(g: &mut Array2<f32>, a: &Array2<f32>, act: Activation) {
    let slope = crate::activation::LEAKY_RELU_SLOPE;
    match act {
        Activation::Identity => {}
        Activation::Relu => g.zip_mut_with(a, |g, &a| {
            if a <= 0.0 {
                *g = 0.0
            }
        }),
        Activation::LeakyRelu => g.zip_mut_with(a, |g, &a| {
            if a <= 0.0 {
                *g *= slope
            }
        }),
        Activation::Tanh => g.zip_mut_with(a, |g, &a| *g *= 1.0 - a * a),
    }
}

impl Mlp {
    /// A network with weights drawn by `config.init` from `rng` and zero biases.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] when `config.validate()` fails.
    pub fn new<R: Rng + ?Sized>(config: &MlpConfig, rng: &mut R) -> Result<Mlp> {
        config.validate()?;
        let widths = config.widths();
        let layers = widths
            .windows(2)
            .map(|w| Layer {
                w: init_weights(config.init, w[0], w[1], rng),
                b: Array1::zeros(w[1]),
            })
            .collect();
        Ok(Mlp {
            config: config.clone(),
            layers,
        })
    }

    /// The config the network was built from.
    pub fn config(&self) -> &MlpConfig {
        &self.config
    }

    /// Width of the input.
    pub fn input_dim(&self) -> usize {
        self.config.input
    }

    /// Width of the output.
    pub fn output_dim(&self) -> usize {
        self.config.output
    }

    /// Number of trainable numbers (weights and biases).
    pub fn num_params(&self) -> usize {
        self.layers.iter().map(|l| l.w.len() + l.b.len()).sum()
    }

    /// The layers, input side first.
    pub fn layers(&self) -> &[Layer] {
        &self.layers
    }

    fn act_of(&self, i: usize) -> Activation {
        if i + 1 == self.layers.len() {
            self.config.output_activation
        } else {
            self.config.activation
        }
    }

    /// Checks that `x` has shape `(batch, input)` and finite entries.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] or [`Error::NonFinite`].
    pub fn check_input(&self, x: ArrayView2<'_, f32>) -> Result<()> {
        if x.ncols() != self.input_dim() {
            return Err(Error::shape(
                "network input columns",
                self.input_dim(),
                x.ncols(),
            ));
        }
        if !x.iter().all(|v| v.is_finite()) {
            return Err(Error::NonFinite {
                what: "network input".into(),
            });
        }
        Ok(())
    }

    fn assert_input(&self, x: &ArrayView2<'_, f32>, what: &str) {
        assert_eq!(
            x.ncols(),
            self.input_dim(),
            "{what}: input has {} columns, the network takes {}",
            x.ncols(),
            self.input_dim()
        );
    }

    /// Inference: the output for a batch `x` of shape `(batch, input)`,
    /// returned as a view of shape `(batch, output)` into `ws`.
    ///
    /// Allocates nothing once `ws` has seen this batch size with this network.
    /// Batches of up to 3 rows take a row-by-row path (several times faster
    /// for one row than the packed matrix product); a row's output can then
    /// differ in the last bits from the same row inside a larger batch,
    /// because the products are summed in another order. The same batch
    /// size always gives the same numbers.
    ///
    /// # Panics
    /// When `x` does not have `input_dim()` columns ([`Mlp::check_input`]
    /// reports that as an error instead).
    pub fn forward<'w>(
        &self,
        x: ArrayView2<'_, f32>,
        ws: &'w mut Workspace,
    ) -> ArrayView2<'w, f32> {
        self.assert_input(&x, "Mlp::forward");
        let batch = x.nrows();
        let n = self.layers.len();
        ws.bufs.resize_with(n, || Array2::zeros((0, 0)));
        for (i, layer) in self.layers.iter().enumerate() {
            let (prev, rest) = ws.bufs.split_at_mut(i);
            let out = &mut rest[0];
            ensure_shape(out, batch, layer.w.ncols());
            if i == 0 {
                affine_product(x, &layer.w, out);
            } else {
                affine_product(prev[i - 1].view(), &layer.w, out);
            }
            bias_act(out, &layer.b, self.act_of(i));
        }
        ws.bufs[n - 1].view()
    }

    /// Inference into a new array of shape `(batch, output)`.
    ///
    /// # Panics
    /// When `x` does not have `input_dim()` columns.
    pub fn predict(&self, x: ArrayView2<'_, f32>) -> Array2<f32> {
        let mut ws = Workspace::new();
        self.forward(x, &mut ws);
        ws.bufs.pop().expect("a network has at least one layer")
    }

    /// Forward pass for training: records what [`Mlp::backward`] and
    /// [`Mlp::jvp`] need in `tape` and returns the output, shape
    /// `(batch, output)`.
    ///
    /// # Panics
    /// When `x` does not have `input_dim()` columns.
    pub fn forward_tape<'t>(
        &self,
        x: ArrayView2<'_, f32>,
        tape: &'t mut Tape,
    ) -> ArrayView2<'t, f32> {
        self.assert_input(&x, "Mlp::forward_tape");
        let batch = x.nrows();
        let n = self.layers.len();
        tape.acts.resize_with(n + 1, || Array2::zeros((0, 0)));
        ensure_shape(&mut tape.acts[0], batch, x.ncols());
        tape.acts[0].assign(&x);
        for (i, layer) in self.layers.iter().enumerate() {
            let (prev, rest) = tape.acts.split_at_mut(i + 1);
            let out = &mut rest[0];
            ensure_shape(out, batch, layer.w.ncols());
            affine_product(prev[i].view(), &layer.w, out);
            bias_act(out, &layer.b, self.act_of(i));
        }
        tape.acts[n].view()
    }

    fn assert_tape(&self, tape: &Tape, what: &str) {
        let ok = tape.acts.len() == self.layers.len() + 1
            && tape.acts[0].ncols() == self.input_dim()
            && self
                .layers
                .iter()
                .zip(&tape.acts[1..])
                .all(|(l, a)| a.ncols() == l.w.ncols());
        assert!(
            ok,
            "{what}: the tape was not recorded by forward_tape of a network of this shape"
        );
    }

    /// Reverse mode: adds (`+=`) to `grads` the parameter gradient of
    /// `sum(grad_out * output)` at the tape's inputs, and returns its
    /// gradient with respect to the input, shape `(batch, input)`.
    ///
    /// `grad_out` has shape `(batch, output)`; for a loss `L(output)` pass
    /// `dL/d output` (for example the second value of [`crate::mse_loss`]).
    ///
    /// # Panics
    /// When the tape was not recorded by this network's shape, `grad_out`'s
    /// shape differs from the tape's output, or `grads` has another layout.
    pub fn backward(
        &self,
        tape: &Tape,
        grad_out: ArrayView2<'_, f32>,
        grads: &mut Gradients,
    ) -> Array2<f32> {
        self.backward_impl(tape, grad_out, grads, true)
    }

    /// [`Mlp::backward`] without the input gradient: accumulates the
    /// parameter gradients only and skips the first layer's input product
    /// (what training a network on a loss needs).
    ///
    /// # Panics
    /// As [`Mlp::backward`].
    pub fn backward_params(
        &self,
        tape: &Tape,
        grad_out: ArrayView2<'_, f32>,
        grads: &mut Gradients,
    ) {
        self.backward_impl(tape, grad_out, grads, false);
    }

    fn backward_impl(
        &self,
        tape: &Tape,
        grad_out: ArrayView2<'_, f32>,
        grads: &mut Gradients,
        want_input_grad: bool,
    ) -> Array2<f32> {
        self.assert_tape(tape, "Mlp::backward");
        let out = &tape.acts[self.layers.len()];
        assert_eq!(
            grad_out.dim(),
            out.dim(),
            "Mlp::backward: grad_out shape differs from the output's"
        );
        assert!(
            grads.matches(self),
            "Mlp::backward: gradients have another network's layout"
        );
        let mut g = grad_out.to_owned();
        for i in (0..self.layers.len()).rev() {
            let layer = &self.layers[i];
            mul_act_derivative(&mut g, &tape.acts[i + 1], self.act_of(i));
            let lg = &mut grads.layers_mut()[i];
            general_mat_mul(1.0, &tape.acts[i].t(), &g, 1.0, &mut lg.dw);
            let db = lg.db.as_slice_mut().expect("contiguous biases");
            let width = db.len();
            for row in g.as_slice().expect("contiguous").chunks_exact(width) {
                for (d, &v) in db.iter_mut().zip(row) {
                    *d += v;
                }
            }
            if i == 0 && !want_input_grad {
                return Array2::zeros((0, 0));
            }
            let mut g_in = Array2::zeros((g.nrows(), layer.w.nrows()));
            general_mat_mul(1.0, &g, &layer.w.t(), 0.0, &mut g_in);
            g = g_in;
        }
        g
    }

    /// Forward mode: the derivative of the output at the tape's inputs along
    /// the parameter direction `dir` (`J v`), shape `(batch, output)`.
    ///
    /// Together with [`Mlp::backward`] (`J^T u`) this gives Fisher-vector
    /// products without materialising `J`.
    ///
    /// # Panics
    /// When the tape was not recorded by this network's shape or `dir` has
    /// another layout.
    pub fn jvp(&self, tape: &Tape, dir: &Gradients) -> Array2<f32> {
        self.assert_tape(tape, "Mlp::jvp");
        assert!(
            dir.matches(self),
            "Mlp::jvp: direction has another network's layout"
        );
        let batch = tape.batch();
        let mut t: Option<Array2<f32>> = None;
        for (i, layer) in self.layers.iter().enumerate() {
            let d = &dir.layers()[i];
            let mut dz = Array2::zeros((batch, layer.w.ncols()));
            general_mat_mul(1.0, &tape.acts[i], &d.dw, 0.0, &mut dz);
            if let Some(t) = &t {
                general_mat_mul(1.0, t, &layer.w, 1.0, &mut dz);
            }
            dz += &d.db.view().insert_axis(Axis(0));
            mul_act_derivative(&mut dz, &tape.acts[i + 1], self.act_of(i));
            t = Some(dz);
        }
        t.expect("a network has at least one layer")
    }

    /// Zero gradients with this network's layout.
    pub fn zero_grads(&self) -> Gradients {
        Gradients::zeros(self)
    }

    /// All parameters: layer by layer, weights in row-major `(in, out)`
    /// order, then biases. Length `num_params()`.
    pub fn params_flat(&self) -> Vec<f32> {
        let mut v = Vec::with_capacity(self.num_params());
        for l in &self.layers {
            v.extend(l.w.iter());
            v.extend(l.b.iter());
        }
        v
    }

    /// Sets all parameters from the layout of [`Mlp::params_flat`].
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] when `p.len() != num_params()`,
    /// [`Error::NonFinite`] when an entry is NaN or infinite (nothing is
    /// changed in either case).
    pub fn set_params_flat(&mut self, p: &[f32]) -> Result<()> {
        if p.len() != self.num_params() {
            return Err(Error::shape(
                "Mlp::set_params_flat",
                self.num_params(),
                p.len(),
            ));
        }
        if !p.iter().all(|x| x.is_finite()) {
            return Err(Error::NonFinite {
                what: "Mlp::set_params_flat parameters".into(),
            });
        }
        let mut k = 0;
        for l in &mut self.layers {
            for (d, s) in l.w.iter_mut().zip(&p[k..]) {
                *d = *s;
            }
            k += l.w.len();
            for (d, s) in l.b.iter_mut().zip(&p[k..]) {
                *d = *s;
            }
            k += l.b.len();
        }
        Ok(())
    }

    /// Moves every parameter a share `tau` of the way toward `source`'s,
    /// in place: `θ ← θ + τ (θ_source − θ)` (the Polyak average of target
    /// networks and averaged policies). The same arithmetic as doing it on
    /// [`Mlp::params_flat`] and writing back, without the copies.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] when `source`'s layers differ in number or
    /// shape (nothing is changed), [`Error::NonFinite`] when a parameter
    /// becomes NaN or infinite.
    pub fn polyak_toward(&mut self, source: &Mlp, tau: f32) -> Result<()> {
        let shapes = |m: &Mlp| {
            m.layers
                .iter()
                .map(|l| (l.w.dim(), l.b.len()))
                .collect::<Vec<_>>()
        };
        if shapes(self) != shapes(source) {
            return Err(Error::shape(
                "Mlp::polyak_toward source layers",
                format!("{:?}", shapes(self)),
                format!("{:?}", shapes(source)),
            ));
        }
        // Plain slices where the arrays are in standard layout (they are,
        // as built and as loaded), so that the loop vectorises; the element
        // iterators otherwise. A value is non-finite when its exponent bits
        // are all set: OR-ing that test into an integer keeps the loop free
        // of branches.
        fn step<D: ndarray::Dimension>(
            t: &mut ndarray::Array<f32, D>,
            s: &ndarray::Array<f32, D>,
            tau: f32,
        ) -> u32 {
            const EXP: u32 = 0x7f80_0000;
            let mut bad = 0u32;
            let mut one = |ti: &mut f32, si: f32| {
                *ti += tau * (si - *ti);
                bad |= u32::from(ti.to_bits() & EXP == EXP);
            };
            match (t.as_slice_mut(), s.as_slice()) {
                (Some(ta), Some(sa)) => ta.iter_mut().zip(sa).for_each(|(ti, si)| one(ti, *si)),
                _ => t.zip_mut_with(s, |ti, si| one(ti, *si)),
            }
            bad
        }
        let mut bad = 0u32;
        for (t, s) in self.layers.iter_mut().zip(&source.layers) {
            bad |= step(&mut t.w, &s.w, tau) | step(&mut t.b, &s.b, tau);
        }
        let finite = bad == 0;
        if !finite {
            return Err(Error::NonFinite {
                what: "Mlp::polyak_toward parameters".into(),
            });
        }
        Ok(())
    }

    /// Mutable access to the layers, for optimisers in this crate. Shapes
    /// must not change.
    pub(crate) fn layers_mut(&mut self) -> &mut [Layer] {
        &mut self.layers
    }

    /// The network as a JSON document `{"format": "red-nets/mlp", "version":
    /// 1, "mlp": {"config": .., "layers": [{"w": [..], "b": [..]}, ..]}}`,
    /// weights row-major `(in, out)`. f32 values round-trip exactly.
    ///
    /// # Errors
    /// [`Error::Format`] if serialisation fails (it does not for valid networks).
    pub fn to_json(&self) -> Result<String> {
        let doc = SavedMlp {
            format: MLP_FORMAT.into(),
            version: MLP_FORMAT_VERSION,
            mlp: self.clone(),
        };
        serde_json::to_string(&doc).map_err(|e| Error::Format {
            path: None,
            reason: e.to_string(),
        })
    }

    /// Reads a network written by [`Mlp::to_json`].
    ///
    /// # Errors
    /// [`Error::Format`] when the text is not such a document, names another
    /// format or version, or its arrays disagree with its config.
    pub fn from_json(s: &str) -> Result<Mlp> {
        parse_saved(s).map_err(|reason| Error::Format { path: None, reason })
    }

    /// Writes [`Mlp::to_json`] to `path`.
    ///
    /// # Errors
    /// [`Error::Io`] when the file cannot be written.
    pub fn save(&self, path: &Path) -> Result<()> {
        let s = self.to_json()?;
        std::fs::write(path, s).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })
    }

    /// Reads a network saved by [`Mlp::save`].
    ///
    /// # Errors
    /// [`Error::Io`] when the file cannot be read, [`Error::Format`] (with
    /// the path) when its content is not a valid saved network.
    pub fn load(path: &Path) -> Result<Mlp> {
        let s = std::fs::read_to_string(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
        parse_saved(&s).map_err(|reason| Error::Format {
            path: Some(path.to_path_buf()),
            reason,
        })
    }
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SavedMlp {
    format: String,
    version: u32,
    mlp: Mlp,
}

#[derive(Deserialize)]
struct SavedHeader {
    format: String,
    version: u32,
}

fn parse_saved(s: &str) -> std::result::Result<Mlp, String> {
    let header: SavedHeader = serde_json::from_str::<serde_json::Value>(s)
        .and_then(serde_json::from_value)
        .map_err(|e| format!("not a saved red-nets network: {e}"))?;
    if header.format != MLP_FORMAT {
        return Err(format!(
            "format is `{}`, expected `{MLP_FORMAT}`",
            header.format
        ));
    }
    if header.version != MLP_FORMAT_VERSION {
        return Err(format!(
            "format version {} is not supported (this build reads version {MLP_FORMAT_VERSION})",
            header.version
        ));
    }
    let doc: SavedMlp = serde_json::from_str(s).map_err(|e| e.to_string())?;
    Ok(doc.mlp)
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct LayerRepr {
    w: Vec<f32>,
    b: Vec<f32>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct MlpRepr {
    config: MlpConfig,
    layers: Vec<LayerRepr>,
}

impl From<Mlp> for MlpRepr {
    fn from(m: Mlp) -> Self {
        MlpRepr {
            layers: m
                .layers
                .iter()
                .map(|l| LayerRepr {
                    w: l.w.iter().copied().collect(),
                    b: l.b.to_vec(),
                })
                .collect(),
            config: m.config,
        }
    }
}

impl TryFrom<MlpRepr> for Mlp {
    type Error = String;

    fn try_from(r: MlpRepr) -> std::result::Result<Self, String> {
        r.config.validate().map_err(|e| e.to_string())?;
        let widths = r.config.widths();
        if r.layers.len() != widths.len() - 1 {
            return Err(format!(
                "{} layers stored, the config has {}",
                r.layers.len(),
                widths.len() - 1
            ));
        }
        let mut layers = Vec::with_capacity(r.layers.len());
        for (i, (l, w)) in r.layers.into_iter().zip(widths.windows(2)).enumerate() {
            if l.w.len() != w[0] * w[1] || l.b.len() != w[1] {
                return Err(format!(
                    "layer {i}: {} weights and {} biases stored, the config needs {} x {} and {}",
                    l.w.len(),
                    l.b.len(),
                    w[0],
                    w[1],
                    w[1]
                ));
            }
            if !l.w.iter().chain(&l.b).all(|x| x.is_finite()) {
                return Err(format!("layer {i}: non-finite parameter"));
            }
            let wm = Array2::from_shape_vec((w[0], w[1]), l.w).map_err(|e| e.to_string())?;
            layers.push(Layer {
                w: wm,
                b: Array1::from(l.b),
            });
        }
        Ok(Mlp {
            config: r.config,
            layers,
        })
    }
}

/// The constructors of [`Gradients`] that take their layout from a net
/// (here, so that `grads.rs` does not depend on `mlp.rs`).
impl Gradients {
    /// Zeros with the layout of `net`.
    pub fn zeros(net: &Mlp) -> Gradients {
        Gradients::from_layers(
            net.layers()
                .iter()
                .map(|l| LayerGrad {
                    dw: Array2::zeros(l.w.raw_dim()),
                    db: Array1::zeros(l.b.raw_dim()),
                })
                .collect(),
        )
    }

    /// A vector with the layout of `net` from a flat slice in the order of
    /// [`Mlp::params_flat`].
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] when `flat.len() != net.num_params()`.
    pub fn from_flat(net: &Mlp, flat: &[f32]) -> Result<Gradients> {
        if flat.len() != net.num_params() {
            return Err(Error::shape(
                "Gradients::from_flat",
                net.num_params(),
                flat.len(),
            ));
        }
        let mut g = Gradients::zeros(net);
        let mut k = 0;
        for l in g.layers_mut() {
            for (d, s) in l.dw.iter_mut().zip(&flat[k..]) {
                *d = *s;
            }
            k += l.dw.len();
            for (d, s) in l.db.iter_mut().zip(&flat[k..]) {
                *d = *s;
            }
            k += l.db.len();
        }
        Ok(g)
    }

    /// Whether `self` has the layout of `net`.
    pub fn matches(&self, net: &Mlp) -> bool {
        self.layers().len() == net.layers().len()
            && self
                .layers()
                .iter()
                .zip(net.layers())
                .all(|(g, l)| g.dw.dim() == l.w.dim() && g.db.dim() == l.b.dim())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polyak_toward_matches_the_flat_update_and_checks_shapes() {
        use rand::SeedableRng;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let cfg = MlpConfig::new(3, &[5, 4], 2);
        let src = Mlp::new(&cfg, &mut rng).unwrap();
        let mut a = Mlp::new(&cfg, &mut rng).unwrap();
        let mut b = a.clone();
        a.polyak_toward(&src, 0.01).unwrap();
        let (p, mut t) = (src.params_flat(), b.params_flat());
        for (ti, pi) in t.iter_mut().zip(&p) {
            *ti += 0.01 * (pi - *ti);
        }
        b.set_params_flat(&t).unwrap();
        assert_eq!(a, b);
        let mut c = src.clone();
        c.polyak_toward(&src, 0.5).unwrap();
        assert_eq!(c, src);
        let other = MlpConfig::new(3, &[5], 2);
        let mut d = Mlp::new(&other, &mut rng).unwrap();
        let before = d.clone();
        assert!(d.polyak_toward(&src, 0.1).is_err());
        assert_eq!(d, before);
    }

    /// The copy of the tanh loop picked at run time (AVX-512 or AVX2 where
    /// the CPU has them) gives the same bits as the scalar formula.
    #[test]
    fn dispatched_tanh_loop_matches_the_scalar_formula_bit_for_bit() {
        let b: Vec<f32> = (0..37).map(|j| (j as f32 - 18.0) * 0.05).collect();
        let mut data: Vec<f32> = (0..37 * 53)
            .map(|i| ((i as f32) * 0.618_034).sin() * 9.0)
            .collect();
        let want: Vec<f32> = data
            .iter()
            .enumerate()
            .map(|(i, &y)| crate::activation::tanh_f32(y + b[i % 37]))
            .collect();
        tanh_bias_rows(&mut data, &b);
        for (i, (g, w)) in data.iter().zip(&want).enumerate() {
            assert_eq!(g.to_bits(), w.to_bits(), "element {i}: {g} vs {w}");
        }
    }
}
