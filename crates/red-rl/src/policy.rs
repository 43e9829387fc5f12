//! A diagonal Gaussian policy with a state-dependent standard deviation.
//!
//! One network maps a (normalised) observation to `2 * act_dim` outputs: the
//! first `act_dim` are the mean `mu(s)`, the last `act_dim` are the raw
//! log-standard deviation, clamped to `[log_std_min, log_std_max]`:
//! `log_sigma(s) = clamp(raw(s))`. One trunk for both heads halves the cost of
//! a forward pass against two networks; the clamp keeps a state's standard
//! deviation from collapsing or exploding (its gradient is 0 outside the
//! range, which the Fisher products and backward passes below respect).
//! The release's policy has a state-dependent log-std too.
//!
//! The deterministic action is the mean. Observations are normalised by the
//! policy's own [`ObsNormalizer`] if it has one, so a saved policy is
//! self-contained.
//!
//! ```
//! use rand::SeedableRng;
//! use red_rl::policy::{GaussianPolicy, GaussianPolicyConfig};
//! let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
//! let policy = GaussianPolicy::new(&GaussianPolicyConfig::default(), 11, 3, None, &mut rng)?;
//! let a = policy.act_deterministic(&[0.0; 11])?;
//! assert_eq!(a.len(), 3);
//! # Ok::<(), red_rl::Error>(())
//! ```

use std::path::Path;

use ndarray::{Array2, ArrayView2, Axis, s};
use rand::{Rng, RngExt};
use rand_distr::StandardNormal;
use red_nets::{Activation, Gradients, Init, Mlp, MlpConfig, Tape, Workspace};
use serde::{Deserialize, Serialize};

use crate::normalize::ObsNormalizer;
use crate::{Error, Result};

/// `0.5 * ln(2 pi)`.
const HALF_LN_2PI: f64 = 0.918_938_533_204_672_7;

/// Settings of a [`GaussianPolicy`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GaussianPolicyConfig {
    /// Hidden layer widths. Default `[100, 100]`, the release's.
    pub hidden: Vec<usize>,
    /// Hidden activation. Default tanh, the release's.
    pub activation: Activation,
    /// Initial log-standard deviation (the bias of the log-std outputs).
    /// Default 0 (standard deviation 1), OpenAI baselines' initial value.
    pub init_log_std: f32,
    /// Lower clamp of the log-std. Default -5 (sigma ~ 0.0067): below any
    /// useful exploration for actions of order 1.
    pub log_std_min: f32,
    /// Upper clamp of the log-std. Default 2 (sigma ~ 7.4).
    pub log_std_max: f32,
    /// Factor applied to the output layer's initial weights. Default 0.01,
    /// as OpenAI baselines' policy head (`normc_initializer(0.01)`), so the
    /// first policy has mean ~0 and log-std ~`init_log_std` everywhere.
    pub output_scale: f32,
    /// Whether the actions this policy emits ([`GaussianPolicy::act_into`],
    /// [`GaussianPolicy::act_deterministic`]) are squashed by `tanh` into
    /// `(-1, 1)`: the tanh-squashed Gaussian of SAC (Haarnoja et al. 2018,
    /// Appendix C). The distribution methods (`distribution`, `log_prob`)
    /// still describe the Gaussian before the squash; SVG(1)-ER and TRPO
    /// refuse a squashed policy. Default false.
    pub squash: bool,
    /// Extra inputs that read an observation's place within a period
    /// (our addition, empty by default): for each, the network also sees
    /// `2 (u - round(u))` with `u = x[dim] / period` of the raw
    /// observation (read back from the normalised input, so a normaliser
    /// must have soft tails or no clip), in `[-1, 1]`, 0 at the multiples
    /// of `period` and +-1 halfway between. On the driving road with `dim` the lateral
    /// position and `period` one lane, it is the offset from the nearest
    /// lane's centre, and it jumps at each lane line. The learners see the
    /// input as constant: its slope is not chained to the observation in
    /// the input gradients of [`GaussianPolicy::backward`].
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub wrapped_inputs: Vec<WrappedInput>,
}

/// One of [`GaussianPolicyConfig::wrapped_inputs`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WrappedInput {
    /// The observation's dimension read.
    pub dim: usize,
    /// Its period, in the observation's raw units (> 0).
    pub period: f64,
}

impl WrappedInput {
    /// The input for a raw value `x`: `2 (u - round(u))`, `u = x / period`.
    pub fn value(&self, x: f64) -> f64 {
        let u = x / self.period;
        2.0 * (u - u.round())
    }
}

impl Default for GaussianPolicyConfig {
    fn default() -> Self {
        Self {
            hidden: vec![100, 100],
            activation: Activation::Tanh,
            init_log_std: 0.0,
            log_std_min: -5.0,
            log_std_max: 2.0,
            output_scale: 0.01,
            squash: false,
            wrapped_inputs: Vec::new(),
        }
    }
}

impl GaussianPolicyConfig {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the field.
    pub fn validate(&self) -> Result<()> {
        let bad = |field: &str, reason: String| {
            Err(Error::InvalidConfig {
                field: field.into(),
                reason,
            })
        };
        if self.hidden.contains(&0) {
            return bad("hidden", "widths must be at least 1".into());
        }
        if !(self.log_std_min.is_finite()
            && self.log_std_max.is_finite()
            && self.log_std_min < self.log_std_max)
        {
            return bad(
                "log_std_min",
                format!(
                    "need finite log_std_min < log_std_max, got {} and {}",
                    self.log_std_min, self.log_std_max
                ),
            );
        }
        if !(self.log_std_min..=self.log_std_max).contains(&self.init_log_std) {
            return bad(
                "init_log_std",
                format!(
                    "must lie in [log_std_min, log_std_max], got {}",
                    self.init_log_std
                ),
            );
        }
        if !(self.output_scale.is_finite() && self.output_scale > 0.0) {
            return bad(
                "output_scale",
                format!("must be finite and > 0, got {}", self.output_scale),
            );
        }
        for (i, w) in self.wrapped_inputs.iter().enumerate() {
            if !(w.period.is_finite() && w.period > 0.0) {
                return bad(
                    &format!("wrapped_inputs[{i}].period"),
                    format!("must be finite and > 0, got {}", w.period),
                );
            }
        }
        Ok(())
    }
}

/// The distribution parameters of a batch: `mean` and clamped `log_std`,
/// each `(n, act_dim)`, in `f64` for the statistics computed from them.
#[derive(Debug, Clone, PartialEq)]
pub struct GaussianBatch {
    /// Means, `(n, act_dim)`.
    pub mean: Array2<f64>,
    /// Log-standard deviations after the clamp, `(n, act_dim)`.
    pub log_std: Array2<f64>,
    /// 1 where the raw log-std was inside the clamp range (the clamp passes
    /// gradients), 0 where it was clamped; `(n, act_dim)`.
    pub log_std_mask: Array2<f64>,
}

impl GaussianBatch {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.mean.nrows()
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Log-density of each row's action, `actions` `(n, act_dim)`; returns
    /// `n` values.
    pub fn log_prob(&self, actions: ArrayView2<'_, f64>) -> Vec<f64> {
        assert_eq!(actions.dim(), self.mean.dim(), "log_prob: actions shape");
        let k = self.mean.ncols() as f64;
        (0..self.len())
            .map(|i| {
                let mut lp = -k * HALF_LN_2PI;
                for j in 0..self.mean.ncols() {
                    let ls = self.log_std[[i, j]];
                    let z = (actions[[i, j]] - self.mean[[i, j]]) * (-ls).exp();
                    lp -= 0.5 * z * z + ls;
                }
                lp
            })
            .collect()
    }

    /// Entropy of each row's distribution.
    pub fn entropy(&self) -> Vec<f64> {
        let k = self.mean.ncols() as f64;
        self.log_std
            .rows()
            .into_iter()
            .map(|r| r.sum() + k * (0.5 + HALF_LN_2PI))
            .collect()
    }

    /// `KL(self || other)` of each row.
    ///
    /// # Panics
    /// When the batches differ in shape.
    pub fn kl(&self, other: &GaussianBatch) -> Vec<f64> {
        assert_eq!(self.mean.dim(), other.mean.dim(), "kl: batch shapes differ");
        (0..self.len())
            .map(|i| {
                let mut kl = 0.0;
                for j in 0..self.mean.ncols() {
                    let (lp, lq) = (self.log_std[[i, j]], other.log_std[[i, j]]);
                    let dm = self.mean[[i, j]] - other.mean[[i, j]];
                    kl += lq - lp + ((2.0 * lp).exp() + dm * dm) / (2.0 * (2.0 * lq).exp()) - 0.5;
                }
                kl
            })
            .collect()
    }

    /// The `(n, 2 * act_dim)` gradient with respect to the network's raw
    /// outputs of a loss whose gradients with respect to the means and the
    /// (clamped) log-stds are `d_mean` and `d_log_std`: the log-std part is
    /// masked by the clamp.
    pub fn output_grad(
        &self,
        d_mean: ArrayView2<'_, f64>,
        d_log_std: ArrayView2<'_, f64>,
    ) -> Array2<f32> {
        let (n, k) = self.mean.dim();
        let mut g = Array2::zeros((n, 2 * k));
        for i in 0..n {
            for j in 0..k {
                g[[i, j]] = d_mean[[i, j]] as f32;
                g[[i, k + j]] = (d_log_std[[i, j]] * self.log_std_mask[[i, j]]) as f32;
            }
        }
        g
    }
}

/// A diagonal Gaussian policy; see the module documentation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GaussianPolicy {
    config: GaussianPolicyConfig,
    net: Mlp,
    obs_dim: usize,
    act_dim: usize,
    normalizer: Option<ObsNormalizer>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SavedPolicy {
    format: String,
    version: u32,
    policy: GaussianPolicy,
}

/// The observation normaliser's dimension and the wrapped inputs against
/// `obs_dim`; wrapped inputs need the normaliser's inverse to be exact, so
/// a normaliser with a hard clip is refused with them.
fn check_inputs(
    config: &GaussianPolicyConfig,
    obs_dim: usize,
    normalizer: Option<&ObsNormalizer>,
) -> Result<()> {
    if let Some(n) = normalizer
        && n.dim() != obs_dim
    {
        return Err(Error::ShapeMismatch {
            what: "policy observation normaliser".into(),
            expected: format!("{obs_dim} dimensions"),
            got: format!("{}", n.dim()),
        });
    }
    for (i, w) in config.wrapped_inputs.iter().enumerate() {
        if w.dim >= obs_dim {
            return Err(Error::InvalidConfig {
                field: format!("wrapped_inputs[{i}].dim"),
                reason: format!(
                    "must be below {obs_dim} (the observation's length), got {}",
                    w.dim
                ),
            });
        }
    }
    if let Some(n) = normalizer
        && !config.wrapped_inputs.is_empty()
        && !n.soft_tails()
        && n.clip() < f64::MAX
    {
        return Err(Error::InvalidConfig {
            field: "wrapped_inputs".into(),
            reason: "read through the normaliser's inverse, which a hard clip makes wrong beyond \
                     it: give the normaliser soft tails (ObsNormalizer::with_soft_tails; on the \
                     driving task train.policy_obs_soft_tails) or no clip"
                .into(),
        });
    }
    Ok(())
}

/// Name written in saved policies.
pub const POLICY_FORMAT: &str = "red-rl/gaussian-policy";
/// Version of the saved policy format.
pub const POLICY_FORMAT_VERSION: u32 = 1;

/// Buffers for [`GaussianPolicy::act_into`], reused across steps.
#[derive(Debug, Clone, Default)]
pub struct PolicyWorkspace {
    input: Vec<f32>,
    hidden: Vec<f32>,
    out: Vec<f32>,
}

/// One row through the network: `x` (the input) is overwritten layer by
/// layer, the result is left in `out`. A dedicated vector-matrix loop:
/// for a single row, a general matrix product spends more time packing the
/// weights than multiplying, and acting is once per environment step.
fn forward_row(net: &Mlp, x: &mut Vec<f32>, tmp: &mut Vec<f32>, out: &mut Vec<f32>) {
    let layers = net.layers();
    let last = layers.len() - 1;
    for (l, layer) in layers.iter().enumerate() {
        let act = if l == last {
            net.config().output_activation
        } else {
            net.config().activation
        };
        let dst = if l == last { &mut *out } else { &mut *tmp };
        dst.clear();
        dst.extend(layer.b.iter());
        let width = dst.len();
        match layer.w.as_slice() {
            Some(w) => {
                for (xi, row) in x.iter().zip(w.chunks_exact(width)) {
                    for (d, wij) in dst.iter_mut().zip(row) {
                        *d += xi * wij;
                    }
                }
            }
            None => {
                for (i, xi) in x.iter().enumerate() {
                    for (d, wij) in dst.iter_mut().zip(layer.w.row(i)) {
                        *d += xi * wij;
                    }
                }
            }
        }
        for d in dst.iter_mut() {
            *d = act.apply(*d);
        }
        if l != last {
            std::mem::swap(x, tmp);
        }
    }
}

impl GaussianPolicy {
    /// A fresh policy for observations of `obs_dim` and actions of `act_dim`,
    /// with an optional observation normaliser, initialised from `rng`.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] for a bad config or a zero dimension,
    /// [`Error::ShapeMismatch`] if the normaliser's dimension is not `obs_dim`.
    pub fn new<R: Rng + ?Sized>(
        config: &GaussianPolicyConfig,
        obs_dim: usize,
        act_dim: usize,
        normalizer: Option<ObsNormalizer>,
        rng: &mut R,
    ) -> Result<Self> {
        config.validate()?;
        if obs_dim == 0 || act_dim == 0 {
            return Err(Error::InvalidConfig {
                field: if obs_dim == 0 { "obs_dim" } else { "act_dim" }.into(),
                reason: "must be at least 1".into(),
            });
        }
        check_inputs(config, obs_dim, normalizer.as_ref())?;
        let net_cfg = MlpConfig {
            input: obs_dim + config.wrapped_inputs.len(),
            hidden: config.hidden.clone(),
            output: 2 * act_dim,
            activation: config.activation,
            output_activation: Activation::Identity,
            init: Init::Orthogonal { gain: 1.0 },
        };
        let mut net = Mlp::new(&net_cfg, rng)?;
        // Scale the output layer and set the log-std biases; in the flat
        // layout the last layer's weights then biases come last.
        let mut p = net.params_flat();
        let n = p.len();
        let last_in = *config.hidden.last().unwrap_or(&net_cfg.input);
        let w0 = n - last_in * 2 * act_dim - 2 * act_dim;
        for w in &mut p[w0..n - 2 * act_dim] {
            *w *= config.output_scale;
        }
        for b in &mut p[n - act_dim..] {
            *b = config.init_log_std;
        }
        net.set_params_flat(&p)?;
        Ok(Self {
            config: config.clone(),
            net,
            obs_dim,
            act_dim,
            normalizer,
        })
    }

    /// Checks a loaded policy's shapes: its normaliser's and its wrapped
    /// inputs' dimensions (as [`GaussianPolicy::new`]) and its network's
    /// input and output widths.
    fn check_shapes(&self) -> Result<()> {
        check_inputs(&self.config, self.obs_dim, self.normalizer.as_ref())?;
        let net = self.net.config();
        let (input, output) = (
            self.obs_dim + self.config.wrapped_inputs.len(),
            2 * self.act_dim,
        );
        if net.input != input || net.output != output {
            return Err(Error::ShapeMismatch {
                what: "saved policy network".into(),
                expected: format!("{input} inputs and {output} outputs"),
                got: format!("{} and {}", net.input, net.output),
            });
        }
        Ok(())
    }

    /// Turns the `tanh` squash of emitted actions on or off (a policy
    /// cloned without it can become SAC's actor).
    pub fn set_squash(&mut self, on: bool) {
        self.config.squash = on;
    }

    /// The settings.
    pub fn config(&self) -> &GaussianPolicyConfig {
        &self.config
    }

    /// Observation length.
    pub fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    /// Action length.
    pub fn act_dim(&self) -> usize {
        self.act_dim
    }

    /// The network (`obs_dim` plus the wrapped inputs `-> 2 * act_dim`).
    pub fn net(&self) -> &Mlp {
        &self.net
    }

    /// The network, mutably (for optimisers).
    pub fn net_mut(&mut self) -> &mut Mlp {
        &mut self.net
    }

    /// The observation normaliser, if any.
    pub fn normalizer(&self) -> Option<&ObsNormalizer> {
        self.normalizer.as_ref()
    }

    /// The observation normaliser, mutably.
    pub fn normalizer_mut(&mut self) -> Option<&mut ObsNormalizer> {
        self.normalizer.as_mut()
    }

    /// Raw observations `(n, obs_dim)` to the network's input: normalised
    /// (and clipped) by the policy's normaliser, or just cast to `f32`.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] for the wrong number of columns.
    pub fn prepare_obs(&self, obs: ArrayView2<'_, f64>) -> Result<Array2<f32>> {
        match &self.normalizer {
            Some(n) => n.normalize_batch(obs),
            None => {
                self.check_obs_cols(obs.ncols())?;
                Ok(obs.mapv(|v| v as f32))
            }
        }
    }

    fn check_obs_cols(&self, cols: usize) -> Result<()> {
        if cols != self.obs_dim {
            return Err(Error::ShapeMismatch {
                what: "policy observations".into(),
                expected: format!("{} columns", self.obs_dim),
                got: format!("{cols}"),
            });
        }
        Ok(())
    }

    /// The distribution parameters from the network's raw outputs
    /// `(n, 2 * act_dim)`.
    pub fn split_outputs(&self, out: ArrayView2<'_, f32>) -> GaussianBatch {
        let k = self.act_dim;
        let (lo, hi) = (
            self.config.log_std_min as f64,
            self.config.log_std_max as f64,
        );
        let mean = out.slice(s![.., ..k]).mapv(|v| v as f64);
        let raw = out.slice(s![.., k..]).mapv(|v| v as f64);
        let log_std_mask = raw.mapv(|v| if (lo..=hi).contains(&v) { 1.0 } else { 0.0 });
        let log_std = raw.mapv(|v| v.clamp(lo, hi));
        GaussianBatch {
            mean,
            log_std,
            log_std_mask,
        }
    }

    /// The distributions of a batch of prepared (normalised) observations
    /// `(n, obs_dim)`.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] for the wrong number of columns.
    pub fn distribution(
        &self,
        obs: ArrayView2<'_, f32>,
        ws: &mut Workspace,
    ) -> Result<GaussianBatch> {
        self.check_obs_cols(obs.ncols())?;
        let out = match self.with_wrapped(obs) {
            Some(x) => self.net.forward(x.view(), ws),
            None => self.net.forward(obs, ws),
        };
        Ok(self.split_outputs(out))
    }

    /// As [`GaussianPolicy::distribution`], recording `tape` for
    /// [`GaussianPolicy::backward`] and [`GaussianPolicy::fisher_vector_product`].
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] for the wrong number of columns.
    pub fn distribution_tape(
        &self,
        obs: ArrayView2<'_, f32>,
        tape: &mut Tape,
    ) -> Result<GaussianBatch> {
        self.check_obs_cols(obs.ncols())?;
        let out = match self.with_wrapped(obs) {
            Some(x) => self.net.forward_tape(x.view(), tape),
            None => self.net.forward_tape(obs, tape),
        };
        Ok(self.split_outputs(out))
    }

    /// The prepared observations `(n, obs_dim)` followed by the wrapped
    /// inputs, read from the raw values the normaliser's inverse gives;
    /// `None` without wrapped inputs.
    fn with_wrapped(&self, obs: ArrayView2<'_, f32>) -> Option<Array2<f32>> {
        let wrapped = &self.config.wrapped_inputs;
        if wrapped.is_empty() {
            return None;
        }
        let o = self.obs_dim;
        let mut x = Array2::zeros((obs.nrows(), o + wrapped.len()));
        x.slice_mut(s![.., ..o]).assign(&obs);
        for (mut row, prepared) in x.rows_mut().into_iter().zip(obs.rows()) {
            for (k, w) in wrapped.iter().enumerate() {
                row[o + k] = self.wrapped_value(w, prepared[w.dim] as f64) as f32;
            }
        }
        Some(x)
    }

    /// A wrapped input from the prepared (normalised) value `z` of its
    /// dimension.
    fn wrapped_value(&self, w: &WrappedInput, z: f64) -> f64 {
        let raw = match &self.normalizer {
            Some(n) => n.denormalize_value(w.dim, z),
            None => z,
        };
        w.value(raw)
    }

    /// Back-propagates a loss's gradients with respect to the means and
    /// clamped log-stds of the batch recorded on `tape` (`(n, act_dim)`
    /// each), accumulating parameter gradients into `grads`; returns the
    /// gradient with respect to the network's input `(n, obs_dim)` (the
    /// normalised observation).
    pub fn backward(
        &self,
        tape: &Tape,
        dist: &GaussianBatch,
        d_mean: ArrayView2<'_, f64>,
        d_log_std: ArrayView2<'_, f64>,
        grads: &mut Gradients,
    ) -> Array2<f32> {
        let g = dist.output_grad(d_mean, d_log_std);
        let d_input = self.net.backward(tape, g.view(), grads);
        if self.config.wrapped_inputs.is_empty() {
            d_input
        } else {
            // The wrapped inputs are read as constants (see
            // `GaussianPolicyConfig::wrapped_inputs`).
            d_input.slice(s![.., ..self.obs_dim]).to_owned()
        }
    }

    /// Chains `d_input` (`(n, obs_dim)`, a gradient with respect to the
    /// network's input as [`GaussianPolicy::backward`] returns) back to the
    /// raw observations `raw_obs` through the policy's normaliser (identity
    /// without one).
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] if the shapes differ.
    pub fn input_grad_to_raw(
        &self,
        raw_obs: ArrayView2<'_, f64>,
        d_input: ArrayView2<'_, f32>,
    ) -> Result<Array2<f64>> {
        match &self.normalizer {
            Some(n) => n.backward(raw_obs, d_input),
            None => {
                if raw_obs.dim() != d_input.dim() {
                    return Err(Error::ShapeMismatch {
                        what: "input gradient".into(),
                        expected: format!("{:?}", raw_obs.dim()),
                        got: format!("{:?}", d_input.dim()),
                    });
                }
                Ok(d_input.mapv(|v| v as f64))
            }
        }
    }

    /// [`GaussianPolicy::backward`] without the input gradient (cheaper:
    /// what a policy-gradient step needs).
    pub fn backward_params(
        &self,
        tape: &Tape,
        dist: &GaussianBatch,
        d_mean: ArrayView2<'_, f64>,
        d_log_std: ArrayView2<'_, f64>,
        grads: &mut Gradients,
    ) {
        let g = dist.output_grad(d_mean, d_log_std);
        self.net.backward_params(tape, g.view(), grads);
    }

    /// Reparameterised sampling of a batch: `a = mu + sigma * eps` with
    /// `eps ~ N(0, I)` drawn from `rng`. Returns `(actions, eps)`, each
    /// `(n, act_dim)`; keep `eps` for [`GaussianPolicy::backward_reparam`].
    pub fn sample_reparam<R: Rng + ?Sized>(
        &self,
        dist: &GaussianBatch,
        rng: &mut R,
    ) -> (Array2<f64>, Array2<f64>) {
        let eps = Array2::from_shape_simple_fn(dist.mean.raw_dim(), || {
            rng.sample::<f64, _>(StandardNormal)
        });
        let mut a = eps.clone();
        a.zip_mut_with(&dist.log_std, |e, &ls| *e *= ls.exp());
        a += &dist.mean;
        (a, eps)
    }

    /// Back-propagates `d_action = d loss / d a` (`(n, act_dim)`) through
    /// the reparameterised sample `a = mu + sigma * eps` of the batch on
    /// `tape`: `d mu = d_action`, `d log_sigma = d_action * sigma * eps`.
    /// Accumulates parameter gradients into `grads` and returns `d loss / d
    /// input` `(n, obs_dim)` (the normalised input: chain it to raw observations
    /// with [`GaussianPolicy::input_grad_to_raw`]), the path through the
    /// action (SVG(1) needs both).
    pub fn backward_reparam(
        &self,
        tape: &Tape,
        dist: &GaussianBatch,
        eps: ArrayView2<'_, f64>,
        d_action: ArrayView2<'_, f64>,
        grads: &mut Gradients,
    ) -> Array2<f32> {
        let mut d_ls = d_action.to_owned();
        d_ls.zip_mut_with(&eps, |d, &e| *d *= e);
        d_ls.zip_mut_with(&dist.log_std, |d, &ls| *d *= ls.exp());
        self.backward(tape, dist, d_action, d_ls.view(), grads)
    }

    /// The product of the Fisher information of the batch on `tape` (the
    /// Hessian of the mean `KL(pi_old || pi)` at `pi = pi_old`) with the
    /// parameter direction `dir`, written into `out` (zeroed first):
    /// `F v = J^T M J v / n` with `M = 1 / sigma^2` on the mean outputs and
    /// `2` on the (unclamped) log-std outputs.
    pub fn fisher_vector_product(
        &self,
        tape: &Tape,
        dist: &GaussianBatch,
        dir: &Gradients,
        out: &mut Gradients,
    ) {
        let mut jv = self.net.jvp(tape, dir);
        let n = jv.nrows().max(1) as f64;
        let k = self.act_dim;
        for (i, mut row) in jv.axis_iter_mut(Axis(0)).enumerate() {
            for j in 0..k {
                let inv_var = (-2.0 * dist.log_std[[i, j]]).exp();
                row[j] = (row[j] as f64 * inv_var / n) as f32;
                let m = dist.log_std_mask[[i, j]];
                row[k + j] = (row[k + j] as f64 * 2.0 * m / n) as f32;
            }
        }
        out.zero();
        self.net.backward_params(tape, jv.view(), out);
    }

    /// Deterministic action (the mean) for one raw observation.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] if `obs` is not of length `obs_dim`.
    pub fn act_deterministic(&self, obs: &[f64]) -> Result<Vec<f64>> {
        let mut out = vec![0.0; self.act_dim];
        self.act_into(
            obs,
            None::<&mut rand_chacha::ChaCha8Rng>,
            &mut PolicyWorkspace::default(),
            &mut out,
        )?;
        Ok(out)
    }

    /// The action for one raw observation into `action` (length `act_dim`):
    /// sampled with `rng` when given, else the mean. Allocation-free after
    /// the first call with a given workspace.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] for wrong lengths, [`Error::NonFinite`] for a
    /// non-finite observation.
    pub fn act_into<R: Rng + ?Sized>(
        &self,
        obs: &[f64],
        rng: Option<&mut R>,
        ws: &mut PolicyWorkspace,
        action: &mut [f64],
    ) -> Result<()> {
        if obs.len() != self.obs_dim || action.len() != self.act_dim {
            return Err(Error::ShapeMismatch {
                what: "policy act".into(),
                expected: format!(
                    "observation of {} and action of {}",
                    self.obs_dim, self.act_dim
                ),
                got: format!("{} and {}", obs.len(), action.len()),
            });
        }
        if obs.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "observation given to the policy".into(),
                step: 0,
            });
        }
        let o = self.obs_dim;
        ws.input.resize(o + self.config.wrapped_inputs.len(), 0.0);
        match &self.normalizer {
            Some(n) => n.normalize_into(obs, &mut ws.input[..o])?,
            None => {
                for (r, v) in ws.input.iter_mut().zip(obs) {
                    *r = *v as f32;
                }
            }
        }
        for (k, w) in self.config.wrapped_inputs.iter().enumerate() {
            // As the batch path: read from the prepared value, so that
            // acting and learning see the same input.
            ws.input[o + k] = self.wrapped_value(w, ws.input[w.dim] as f64) as f32;
        }
        forward_row(&self.net, &mut ws.input, &mut ws.hidden, &mut ws.out);
        let out = &ws.out;
        let (lo, hi) = (self.config.log_std_min, self.config.log_std_max);
        let k = self.act_dim;
        match rng {
            Some(rng) => {
                for j in 0..k {
                    let sigma = (out[k + j].clamp(lo, hi) as f64).exp();
                    let e: f64 = rng.sample(StandardNormal);
                    action[j] = out[j] as f64 + sigma * e;
                }
            }
            None => {
                for j in 0..k {
                    action[j] = out[j] as f64;
                }
            }
        }
        if self.config.squash {
            for a in action.iter_mut() {
                *a = a.tanh();
            }
        }
        Ok(())
    }

    /// The policy as JSON (with a format header).
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] if serialisation fails (it does not for a
    /// valid policy).
    pub fn to_json(&self) -> Result<String> {
        let doc = SavedPolicy {
            format: POLICY_FORMAT.into(),
            version: POLICY_FORMAT_VERSION,
            policy: self.clone(),
        };
        serde_json::to_string(&doc).map_err(|e| Error::InvalidConfig {
            field: "policy".into(),
            reason: format!("cannot serialise: {e}"),
        })
    }

    /// A policy from [`GaussianPolicy::to_json`]'s output.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming what is wrong with the text.
    pub fn from_json(s: &str) -> Result<Self> {
        let doc: SavedPolicy = serde_json::from_str(s).map_err(|e| Error::InvalidConfig {
            field: "policy".into(),
            reason: format!("not a saved policy: {e}"),
        })?;
        if doc.format != POLICY_FORMAT || doc.version != POLICY_FORMAT_VERSION {
            return Err(Error::InvalidConfig {
                field: "policy".into(),
                reason: format!(
                    "format `{}` version {} is not `{POLICY_FORMAT}` version {POLICY_FORMAT_VERSION}",
                    doc.format, doc.version
                ),
            });
        }
        doc.policy.config.validate()?;
        doc.policy.check_shapes()?;
        Ok(doc.policy)
    }

    /// Writes the policy to `path` as JSON.
    ///
    /// # Errors
    /// [`Error::Core`] with an I/O error if the file cannot be written.
    pub fn save(&self, path: &Path) -> Result<()> {
        std::fs::write(path, self.to_json()?).map_err(|source| {
            red_core::Error::Io {
                path: path.to_path_buf(),
                source,
            }
            .into()
        })
    }

    /// Reads a policy written by [`GaussianPolicy::save`].
    ///
    /// # Errors
    /// I/O errors or a malformed file.
    pub fn load(path: &Path) -> Result<Self> {
        let s = std::fs::read_to_string(path).map_err(|source| red_core::Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_json(&s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::array;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    fn batch(mean: Array2<f64>, log_std: Array2<f64>) -> GaussianBatch {
        let mask = log_std.mapv(|_| 1.0);
        GaussianBatch {
            mean,
            log_std,
            log_std_mask: mask,
        }
    }

    #[test]
    fn log_prob_entropy_kl_match_closed_forms() {
        let p = batch(array![[0.5, -1.0]], array![[0.2f64.ln(), 0.0]]);
        let q = batch(array![[0.0, 1.0]], array![[0.5f64.ln(), 1.5f64.ln()]]);
        // 1-D normal densities multiplied.
        let a = array![[0.3, 0.1]];
        let pdf = |x: f64, m: f64, s: f64| {
            (-(x - m).powi(2) / (2.0 * s * s)).exp() / (s * (2.0 * std::f64::consts::PI).sqrt())
        };
        let want = (pdf(0.3, 0.5, 0.2) * pdf(0.1, -1.0, 1.0)).ln();
        assert!((p.log_prob(a.view())[0] - want).abs() < 1e-12);
        let h = |s: f64| 0.5 * (2.0 * std::f64::consts::PI * std::f64::consts::E * s * s).ln();
        assert!((p.entropy()[0] - (h(0.2) + h(1.0))).abs() < 1e-12);
        let kl1 = |m1: f64, s1: f64, m2: f64, s2: f64| {
            (s2 / s1).ln() + (s1 * s1 + (m1 - m2).powi(2)) / (2.0 * s2 * s2) - 0.5
        };
        let want_kl = kl1(0.5, 0.2, 0.0, 0.5) + kl1(-1.0, 1.0, 1.0, 1.5);
        assert!((p.kl(&q)[0] - want_kl).abs() < 1e-12);
        assert!(p.kl(&p)[0].abs() < 1e-15);
    }

    #[test]
    fn sampled_actions_have_policy_moments() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let cfg = GaussianPolicyConfig {
            init_log_std: -1.0,
            ..Default::default()
        };
        let pol = GaussianPolicy::new(&cfg, 2, 1, None, &mut rng).unwrap();
        let obs = [0.3, -0.2];
        let mean = pol.act_deterministic(&obs).unwrap()[0];
        let mut ws = PolicyWorkspace::default();
        let mut a = [0.0];
        let n = 20_000;
        let (mut s1, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            pol.act_into(&obs, Some(&mut rng), &mut ws, &mut a).unwrap();
            s1 += a[0];
            s2 += a[0] * a[0];
        }
        let m = s1 / n as f64;
        let sd = (s2 / n as f64 - m * m).sqrt();
        let x = array![[0.3f32, -0.2]];
        let d = pol.distribution(x.view(), &mut Workspace::new()).unwrap();
        let want_sd = d.log_std[[0, 0]].exp();
        assert!((m - mean).abs() < 0.01, "{m} vs {mean}");
        assert!((sd - want_sd).abs() < 0.01, "{sd} vs {want_sd}");
        assert!((want_sd - (-1.0f64).exp()).abs() < 0.05);
    }

    #[test]
    fn single_row_path_matches_batch_forward() {
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        let norm =
            ObsNormalizer::from_data(array![[0.0, 1.0, 2.0], [2.0, 3.0, -1.0]].view(), 5.0, 0.1)
                .unwrap();
        let cfg = GaussianPolicyConfig {
            output_scale: 1.0,
            ..Default::default()
        };
        let pol = GaussianPolicy::new(&cfg, 3, 2, Some(norm), &mut rng).unwrap();
        assert_row_matches_batch(&pol, &[0.5, -2.0, 7.0]);
    }

    /// The single-row path's action equals the batch path's mean.
    fn assert_row_matches_batch(pol: &GaussianPolicy, raw: &[f64]) {
        let rows = Array2::from_shape_vec((1, raw.len()), raw.to_vec()).unwrap();
        let x = pol.prepare_obs(rows.view()).unwrap();
        let d = pol.distribution(x.view(), &mut Workspace::new()).unwrap();
        let a = pol.act_deterministic(raw).unwrap();
        for j in 0..a.len() {
            assert!((a[j] - d.mean[[0, j]]).abs() < 1e-5, "{a:?} vs {}", d.mean);
        }
    }

    #[test]
    fn wrapped_inputs_read_the_place_in_the_period_on_both_paths() {
        let w = WrappedInput {
            dim: 1,
            period: 0.5,
        };
        // Centres at multiples of 0.5 read 0, a quarter period reads +-0.5,
        // and the input jumps from +1 to -1 halfway between two centres.
        assert!(w.value(1.0).abs() < 1e-12);
        assert!((w.value(0.125) - 0.5).abs() < 1e-12);
        assert!((w.value(-0.625) + 0.5).abs() < 1e-12);
        assert!((w.value(0.2499) - 0.9996).abs() < 1e-9);
        assert!((w.value(0.2501) + 0.9996).abs() < 1e-9);

        let mut rng = ChaCha8Rng::seed_from_u64(8);
        // Dimension 1 spreads little in the data, so the raw values below
        // lie far beyond the clip: the soft tails' inverse must give them back.
        let data = array![[0.0, 0.0, 2.0], [2.0, 0.02, -1.0]];
        let norm = ObsNormalizer::from_data(data.view(), 5.0, 0.01)
            .unwrap()
            .with_soft_tails(true);
        let cfg = GaussianPolicyConfig {
            output_scale: 1.0,
            wrapped_inputs: vec![w],
            ..Default::default()
        };
        let pol = GaussianPolicy::new(&cfg, 3, 2, Some(norm), &mut rng).unwrap();
        assert_eq!(pol.net().config().input, 4);
        for y in [0.0, 0.2499, 0.2501, -0.3, 0.9] {
            let raw = array![[0.5, y, 1.0]];
            let x = pol.prepare_obs(raw.view()).unwrap();
            let wide = pol.with_wrapped(x.view()).unwrap();
            assert!(
                (wide[[0, 3]] as f64 - w.value(y)).abs() < 1e-4,
                "y {y}: {} vs {}",
                wide[[0, 3]],
                w.value(y)
            );
            assert_row_matches_batch(&pol, &[0.5, y, 1.0]);
        }
        // The jump reaches the actions: the two sides of a line differ by
        // more than a continuous policy's change over 0.0002.
        let side = |y: f64| pol.act_deterministic(&[0.5, y, 1.0]).unwrap();
        let (lo, hi) = (side(0.2499), side(0.2501));
        assert!(
            (lo[0] - hi[0]).abs() + (lo[1] - hi[1]).abs() > 1e-3,
            "{lo:?} {hi:?}"
        );
        // The input gradient has the observation's columns.
        let x = pol.prepare_obs(array![[0.5, 0.1, 1.0]].view()).unwrap();
        let mut tape = Tape::new();
        let dist = pol.distribution_tape(x.view(), &mut tape).unwrap();
        let mut grads = pol.net().zero_grads();
        let ones = Array2::ones((1, 2));
        let d_in = pol.backward(&tape, &dist, ones.view(), ones.view(), &mut grads);
        assert_eq!(d_in.dim(), (1, 3));
        // Saved and loaded with its wrapped input.
        let back = GaussianPolicy::from_json(&pol.to_json().unwrap()).unwrap();
        assert_eq!(back, pol);
    }

    #[test]
    fn wrapped_inputs_are_checked_and_absent_from_plain_files() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let bad_dim = GaussianPolicyConfig {
            wrapped_inputs: vec![WrappedInput {
                dim: 2,
                period: 1.0,
            }],
            ..Default::default()
        };
        let e = GaussianPolicy::new(&bad_dim, 2, 1, None, &mut rng).unwrap_err();
        assert!(e.to_string().contains("wrapped_inputs[0].dim"), "{e}");
        let bad_period = GaussianPolicyConfig {
            wrapped_inputs: vec![WrappedInput {
                dim: 0,
                period: 0.0,
            }],
            ..Default::default()
        };
        let e = bad_period.validate().unwrap_err();
        assert!(e.to_string().contains("wrapped_inputs[0].period"), "{e}");
        let text = serde_json::to_string(&GaussianPolicyConfig::default()).unwrap();
        assert!(!text.contains("wrapped"), "{text}");
        let back: GaussianPolicyConfig = serde_json::from_str(&text).unwrap();
        assert!(back.wrapped_inputs.is_empty());
    }

    #[test]
    fn wrapped_inputs_reach_the_taped_path_and_behaviour_cloning() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        // Targets that jump at the lane lines y = +-1/3 (period 2/3): the
        // sign of the wrapped input, which a plain network cannot follow
        // within a small step of y.
        let n = 400;
        let mut states = Array2::zeros((n, 2));
        let mut actions = Array2::zeros((n, 1));
        let w = WrappedInput {
            dim: 0,
            period: 2.0 / 3.0,
        };
        for i in 0..n {
            let y = -1.0 + 2.0 * i as f64 / (n - 1) as f64;
            states[[i, 0]] = y;
            states[[i, 1]] = 0.5;
            actions[[i, 0]] = w.value(y).signum() * 0.5;
        }
        let norm = ObsNormalizer::from_data(states.view(), 5.0, 0.1)
            .unwrap()
            .with_soft_tails(true);
        let cfg = GaussianPolicyConfig {
            wrapped_inputs: vec![w],
            ..Default::default()
        };
        let mut pol = GaussianPolicy::new(&cfg, 2, 1, Some(norm), &mut rng).unwrap();
        let x = pol.prepare_obs(states.view()).unwrap();
        let mut tape = Tape::new();
        let taped = pol.distribution_tape(x.view(), &mut tape).unwrap();
        let plain = pol.distribution(x.view(), &mut Workspace::new()).unwrap();
        assert_eq!(taped, plain);
        let bc = crate::bc::BcConfig {
            epochs: 300,
            ..Default::default()
        };
        let losses =
            crate::bc::behavior_clone(&mut pol, states.view(), actions.view(), &bc, &mut rng)
                .unwrap();
        let last = *losses.last().unwrap();
        assert!(last < 0.25 * losses[0], "{losses:?}");
        // Either side of the line y = 1/3 the clone follows the jump.
        let (lo, hi) = (
            pol.act_deterministic(&[0.33, 0.5]).unwrap()[0],
            pol.act_deterministic(&[0.34, 0.5]).unwrap()[0],
        );
        assert!(lo > 0.2 && hi < -0.2, "{lo} {hi}");
    }

    #[test]
    fn loading_and_building_refuse_inputs_that_do_not_fit() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let data = array![[0.0, 1.0], [2.0, 3.0]];
        let cfg = GaussianPolicyConfig {
            wrapped_inputs: vec![WrappedInput {
                dim: 1,
                period: 1.0,
            }],
            ..Default::default()
        };
        // A hard clip makes the normaliser's inverse wrong beyond it.
        let hard = ObsNormalizer::from_data(data.view(), 5.0, 0.1).unwrap();
        let e = GaussianPolicy::new(&cfg, 2, 1, Some(hard), &mut rng).unwrap_err();
        assert!(e.to_string().contains("soft tails"), "{e}");
        let soft = ObsNormalizer::from_data(data.view(), 5.0, 0.1)
            .unwrap()
            .with_soft_tails(true);
        let pol = GaussianPolicy::new(&cfg, 2, 1, Some(soft), &mut rng).unwrap();
        let text = pol.to_json().unwrap();
        assert!(GaussianPolicy::from_json(&text).is_ok());
        // A saved wrapped input out of range, or a network of another width.
        let bad_dim = text.replace(r#""dim":1,"period""#, r#""dim":2,"period""#);
        assert_ne!(bad_dim, text);
        let e = GaussianPolicy::from_json(&bad_dim).unwrap_err();
        assert!(e.to_string().contains("must be below 2"), "{e}");
        let plain = GaussianPolicy::new(&GaussianPolicyConfig::default(), 2, 1, None, &mut rng)
            .unwrap()
            .to_json()
            .unwrap();
        let no_wrap = text.replace(r#","wrapped_inputs":[{"dim":1,"period":1.0}]"#, "");
        assert_ne!(no_wrap, text);
        let e = GaussianPolicy::from_json(&no_wrap).unwrap_err();
        assert!(
            e.to_string().contains("3 and 2") || e.to_string().contains("2 inputs"),
            "{e}"
        );
        assert!(GaussianPolicy::from_json(&plain).is_ok());
    }

    #[test]
    fn save_load_round_trip() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let norm =
            ObsNormalizer::from_data(array![[0.0, 1.0], [2.0, 3.0]].view(), 5.0, 0.1).unwrap();
        let pol = GaussianPolicy::new(&GaussianPolicyConfig::default(), 2, 2, Some(norm), &mut rng)
            .unwrap();
        let back = GaussianPolicy::from_json(&pol.to_json().unwrap()).unwrap();
        assert_eq!(back, pol);
        assert_eq!(
            back.act_deterministic(&[0.1, 0.2]).unwrap(),
            pol.act_deterministic(&[0.1, 0.2]).unwrap()
        );
        assert!(GaussianPolicy::from_json("{}").is_err());
    }
}
