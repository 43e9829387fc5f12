//! Random network distillation as support estimation (paper Sec. 3.1-3.2,
//! Eq. 5-6).
//!
//! A fixed, randomly initialised target `f_θ: [s, a] -> R^K` (the input
//! row of [`InputMap`]) and a
//! predictor `f_θ̂` trained by regression on the expert pairs. The score is
//! the MEAN over the `K` outputs of `(f_θ̂(x) - f_θ(x))^2`, as in the
//! release (the paper writes the squared norm; the two differ by the factor
//! `K`, which `σ1` absorbs). Each output of the target is one of the `K`
//! random prediction problems of Eq. 5, so this is Eq. 6.
//!
//! `ensemble > 1` trains that many independent target/predictor pairs and
//! averages their scores, Eq. 6 with `K * ensemble` problems.

use ndarray::{Array1, Array2, ArrayView2};
use rand::{Rng, RngExt};
use red_nets::{Activation, AdamConfig, FrozenMlp, Init, Mlp, MlpConfig, Tape, Workspace};
use serde::{Deserialize, Serialize};

use crate::estimator::{FitProgress, SupportEstimatorConfig, SupportModel};
use crate::input::{CappedDim, InputMap, PeriodicDim, WeightedDim, cap_states};
use crate::train::{Regression, fit_regression, to_f32};
use crate::{Error, Result};

/// Hyperparameters of [`Rnd`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RndConfig {
    /// Hidden widths of the fixed target.
    pub target_hidden: Vec<usize>,
    /// Hidden widths of the trained predictor.
    pub predictor_hidden: Vec<usize>,
    /// Width `K` of both outputs (linear).
    pub output: usize,
    /// Hidden activation of both networks.
    pub activation: Activation,
    /// Weight initialisation of both networks (biases start at 0).
    pub init: Init,
    /// Number of independent target/predictor pairs whose scores are
    /// averaged.
    pub ensemble: usize,
    /// Passes over the expert pairs.
    pub epochs: usize,
    /// Minibatch size.
    pub batch_size: usize,
    /// The predictor's optimiser.
    pub adam: AdamConfig,
    /// Standardise `[s, a]` with the expert mean and standard deviation.
    pub standardize: bool,
    /// Floor of each standard deviation when standardising (our addition;
    /// 0 keeps the plain rule: only a constant dimension is left unscaled).
    /// A narrow demonstration (a car at one speed: standard deviation 0.04%
    /// of the top speed) otherwise makes any other value many deviations
    /// away.
    pub min_std: f64,
    /// Half-width of a uniform draw of the target's hidden-layer biases
    /// (our addition; 0, the release's, keeps every bias at zero and draws
    /// nothing). With zero biases a (leaky) ReLU target is positively
    /// homogeneous, `f(c x) = c f(x)`, so along every ray from the origin
    /// it is linear and a predictor that fits the expert pairs also fits
    /// the inside of their cloud: for a periodic gait (a ring of states
    /// around the standardised mean) the still state at the mean scores
    /// as expert-like. Random biases put the target's kinks inside the
    /// cloud.
    pub target_bias: f32,
    /// State dimensions the estimator does not see (our addition; empty,
    /// the release's, keeps every input): they read as 0 whatever their
    /// value, in the fit and in every score.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub ignored_state_dims: Vec<usize>,
    /// State dimensions the estimator reads by their phase alone (our
    /// addition; empty, the release's, reads none so): each becomes the
    /// two inputs of [`PeriodicDim`] after the action (in the state's
    /// units, never standardised), and reads as 0 in its own place, in the
    /// fit and in every score. A dimension may stand in only one of
    /// `ignored_state_dims`, `periodic_state_dims` and `capped_state_dims`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub periodic_state_dims: Vec<PeriodicDim>,
    /// State dimensions the estimator reads no higher than a cap (our
    /// addition; empty, the release's, caps none), see [`CappedDim`], in
    /// the fit and in every score.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub capped_state_dims: Vec<CappedDim>,
    /// State dimensions the estimator reads with a weight (our addition;
    /// empty, the release's, weighs every input alike), see
    /// [`WeightedDim`], in the fit and in every score. A weighted dimension
    /// may be capped, not ignored or periodic.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub weighted_state_dims: Vec<WeightedDim>,
}

impl Default for RndConfig {
    /// The RED release's configuration (reference/original-red.md): target
    /// 4 x 128 leaky relu, predictor 1 x 128 leaky relu, linear outputs of
    /// 128, Glorot-uniform weights and zero biases, Adam lr 1e-3, batch 32,
    /// shuffled, 200 epochs, raw (unstandardised) input. `ensemble = 1`:
    /// the release trains one pair.
    fn default() -> Self {
        Self {
            target_hidden: vec![128; 4],
            predictor_hidden: vec![128],
            output: 128,
            activation: Activation::LeakyRelu,
            init: Init::GlorotUniform,
            ensemble: 1,
            epochs: 200,
            batch_size: 32,
            adam: AdamConfig::with_lr(1e-3),
            standardize: false,
            min_std: 0.0,
            target_bias: 0.0,
            ignored_state_dims: Vec::new(),
            periodic_state_dims: Vec::new(),
            capped_state_dims: Vec::new(),
            weighted_state_dims: Vec::new(),
        }
    }
}

impl RndConfig {
    /// Rejects nonsense values, naming the field.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`].
    pub fn validate(&self) -> Result<()> {
        if !(self.min_std.is_finite() && self.min_std >= 0.0) {
            return Err(Error::InvalidConfig {
                field: "min_std".into(),
                reason: format!("must be finite and at least 0, got {}", self.min_std),
            });
        }
        if !(self.target_bias.is_finite() && self.target_bias >= 0.0) {
            return Err(Error::InvalidConfig {
                field: "target_bias".into(),
                reason: format!("must be finite and at least 0, got {}", self.target_bias),
            });
        }
        for (field, v) in [
            ("output", self.output),
            ("ensemble", self.ensemble),
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
        for (field, h) in [
            ("target_hidden", &self.target_hidden),
            ("predictor_hidden", &self.predictor_hidden),
        ] {
            if let Some(i) = h.iter().position(|&w| w == 0) {
                return Err(Error::InvalidConfig {
                    field: format!("{field}[{i}]"),
                    reason: "a layer width must be at least 1".into(),
                });
            }
        }
        self.adam.validate().map_err(|e| prefix("adam", e))?;
        crate::input::check_periodic(&self.periodic_state_dims, usize::MAX)?;
        crate::input::check_caps(&self.capped_state_dims, usize::MAX)?;
        crate::input::check_weights(&self.weighted_state_dims, usize::MAX)?;
        let twice = |field: &str, d: usize| Error::InvalidConfig {
            field: field.into(),
            reason: format!(
                "state dimension {d} also stands in another of ignored_state_dims, \
                 periodic_state_dims and capped_state_dims: give each dimension one"
            ),
        };
        let ignored = &self.ignored_state_dims;
        if let Some(p) = self
            .periodic_state_dims
            .iter()
            .find(|p| ignored.contains(&p.dim))
        {
            return Err(twice("periodic_state_dims", p.dim));
        }
        if let Some(c) = self.capped_state_dims.iter().find(|c| {
            ignored.contains(&c.dim) || self.periodic_state_dims.iter().any(|p| p.dim == c.dim)
        }) {
            return Err(twice("capped_state_dims", c.dim));
        }
        if let Some(w) = self.weighted_state_dims.iter().find(|w| {
            ignored.contains(&w.dim) || self.periodic_state_dims.iter().any(|p| p.dim == w.dim)
        }) {
            return Err(Error::InvalidConfig {
                field: "weighted_state_dims".into(),
                reason: format!(
                    "state dimension {} is also ignored or periodic: it has no value to weigh",
                    w.dim
                ),
            });
        }
        Ok(())
    }

    fn net_config(&self, input: usize, hidden: &[usize]) -> MlpConfig {
        MlpConfig {
            input,
            hidden: hidden.to_vec(),
            output: self.output,
            activation: self.activation,
            output_activation: Activation::Identity,
            init: self.init,
        }
    }
}

/// Draws the biases of `net`'s hidden layers uniformly from `[-half, half]`
/// (the output layer's stay at zero), layer by layer.
fn draw_hidden_biases<R: Rng + ?Sized>(net: &mut Mlp, half: f32, rng: &mut R) -> Result<()> {
    let mut flat = net.params_flat();
    let mut at = 0;
    let n_layers = net.layers().len();
    for (i, l) in net.layers().iter().enumerate() {
        at += l.w.len();
        if i + 1 < n_layers {
            for b in &mut flat[at..at + l.b.len()] {
                *b = rng.random_range(-half..=half);
            }
        }
        at += l.b.len();
    }
    net.set_params_flat(&flat).map_err(|e| prefix("target", e))
}

/// Prefixes the field of a red-nets config error with `what.`.
pub(crate) fn prefix(what: &str, e: red_nets::Error) -> Error {
    match e {
        red_nets::Error::InvalidConfig { field, reason } => Error::InvalidConfig {
            field: format!("{what}.{field}"),
            reason,
        },
        other => Error::from(other),
    }
}

/// One fixed target and its trained predictor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RndPair {
    /// The fixed random target `f_θ`.
    pub target: FrozenMlp,
    /// The predictor `f_θ̂` trained on the expert pairs.
    pub predictor: Mlp,
}

/// A fitted RND support estimator.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rnd {
    input: InputMap,
    pairs: Vec<RndPair>,
    /// The mean batch loss of each pair's last epoch.
    final_losses: Vec<f64>,
}

impl Rnd {
    /// The target/predictor pairs.
    pub fn pairs(&self) -> &[RndPair] {
        &self.pairs
    }

    /// The mean training loss of each pair's last epoch.
    pub fn final_losses(&self) -> &[f64] {
        &self.final_losses
    }

    /// Scores of input rows already mapped, `(b, d)` f32.
    fn score_rows(&self, x: ArrayView2<'_, f32>) -> Array1<f64> {
        let mut out = Array1::<f64>::zeros(x.nrows());
        if x.nrows() <= ROWWISE_MAX_BATCH {
            let mut bufs = RowBuffers::default();
            for (o, row) in out.iter_mut().zip(x.rows()) {
                let row = row.to_vec();
                for pair in &self.pairs {
                    let t = forward_row(pair.target.as_mlp(), &row, &mut bufs).to_vec();
                    let p = forward_row(&pair.predictor, &row, &mut bufs);
                    let s: f32 = t.iter().zip(p).map(|(a, b)| (b - a) * (b - a)).sum();
                    *o += f64::from(s) / t.len() as f64;
                }
            }
        } else {
            let (mut wt, mut wp) = (Workspace::new(), Workspace::new());
            for pair in &self.pairs {
                let t = pair.target.forward(x, &mut wt);
                let p = pair.predictor.forward(x, &mut wp);
                let k = t.ncols() as f64;
                for ((o, tr), pr) in out.iter_mut().zip(t.rows()).zip(p.rows()) {
                    let s: f32 = tr.iter().zip(pr).map(|(a, b)| (b - a) * (b - a)).sum();
                    *o += f64::from(s) / k;
                }
            }
        }
        out /= self.pairs.len() as f64;
        out
    }
}

/// Batches up to this size are scored one row at a time by
/// [`forward_row`]: for a single pair (a reward per environment step) a
/// matrix-vector loop beats a general matrix product, whose packing of each
/// weight matrix costs more than the arithmetic (measured in
/// `cargo bench -p red-support -- red_reward`). The two paths sum in a
/// different order, so a pair's score may differ between them by f32
/// rounding (a test bounds it at 1e-5 relative).
pub(crate) const ROWWISE_MAX_BATCH: usize = 4;

/// Scratch buffers for [`forward_row`].
#[derive(Default)]
pub(crate) struct RowBuffers {
    a: Vec<f32>,
    b: Vec<f32>,
}

/// The output of `net` for one input row, computed layer by layer as
/// `act(x W + b)` with `W` of shape `(in, out)` walked row by row (each row
/// of `W` is contiguous, so the inner loop vectorises). Returns a slice
/// into `bufs`.
pub(crate) fn forward_row<'b>(net: &Mlp, x: &[f32], bufs: &'b mut RowBuffers) -> &'b [f32] {
    let layers = net.layers();
    let cfg = net.config();
    bufs.a.clear();
    bufs.a.extend_from_slice(x);
    for (i, layer) in layers.iter().enumerate() {
        let act = if i + 1 == layers.len() {
            cfg.output_activation
        } else {
            cfg.activation
        };
        bufs.b.clear();
        bufs.b.extend(layer.b.iter());
        for (xi, wrow) in bufs.a.iter().zip(layer.w.rows()) {
            match wrow.as_slice() {
                Some(w) => {
                    for (o, wv) in bufs.b.iter_mut().zip(w) {
                        *o += xi * wv;
                    }
                }
                None => {
                    for (o, wv) in bufs.b.iter_mut().zip(wrow.iter()) {
                        *o += xi * wv;
                    }
                }
            }
        }
        if act != Activation::Identity {
            for v in bufs.b.iter_mut() {
                *v = act.apply(*v);
            }
        }
        std::mem::swap(&mut bufs.a, &mut bufs.b);
    }
    &bufs.a
}

impl SupportModel for Rnd {
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
        Ok(self.score_rows(x.view()))
    }

    fn score_grad_action(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<(Array1<f64>, Array2<f64>)> {
        let x = to_f32(self.input.apply(states, actions)?.view());
        let n = x.nrows();
        let kpairs = self.pairs.len() as f32;
        let mut scores = Array1::<f64>::zeros(n);
        let mut grad_x = Array2::<f32>::zeros(x.raw_dim());
        let (mut tt, mut tp) = (Tape::new(), Tape::new());
        for pair in &self.pairs {
            let target = pair.target.as_mlp();
            let t = target.forward_tape(x.view(), &mut tt).to_owned();
            let p = pair.predictor.forward_tape(x.view(), &mut tp);
            let k = t.ncols() as f32;
            // L = mean_j (p_j - t_j)^2, so dL/dp = 2 (p - t) / K = -dL/dt.
            let diff = &p - &t;
            for (o, row) in scores.iter_mut().zip(diff.rows()) {
                *o += f64::from(row.iter().map(|d| d * d).sum::<f32>() / k);
            }
            let gout = diff.mapv(|d| 2.0 * d / (k * kpairs));
            let mut gp = pair.predictor.zero_grads();
            let mut gt = target.zero_grads();
            grad_x += &pair.predictor.backward(&tp, gout.view(), &mut gp);
            grad_x -= &target.backward(&tt, gout.view(), &mut gt);
        }
        scores /= self.pairs.len() as f64;
        let grad_x = grad_x.mapv(f64::from);
        Ok((scores, self.input.action_grad(grad_x.view())))
    }
}

impl SupportEstimatorConfig for RndConfig {
    type Model = Rnd;

    fn validate(&self) -> Result<()> {
        RndConfig::validate(self)
    }

    /// Draws each target and predictor from `rng` (target first), then
    /// trains each predictor in turn. The target's outputs on the expert
    /// inputs are computed once, not per epoch (the target is fixed).
    /// Progress counts epochs over all pairs.
    fn fit<R: Rng + ?Sized>(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
        rng: &mut R,
        progress: &mut dyn FnMut(FitProgress),
    ) -> Result<Rnd> {
        self.validate()?;
        let capped = cap_states(states, &self.capped_state_dims)?;
        let input = InputMap::fit_floored(capped.view(), actions, self.standardize, self.min_std)?
            .ignoring(&self.ignored_state_dims)?
            .with_periodic(&self.periodic_state_dims)?
            .with_caps(&self.capped_state_dims)?
            .with_weights(&self.weighted_state_dims)?;
        let x = to_f32(input.apply(states, actions)?.view());
        let d = input.dim();
        let mut pairs = Vec::with_capacity(self.ensemble);
        let mut final_losses = Vec::with_capacity(self.ensemble);
        for e in 0..self.ensemble {
            let mut target = Mlp::new(&self.net_config(d, &self.target_hidden), rng)
                .map_err(|e| prefix("target", e))?;
            if self.target_bias > 0.0 {
                draw_hidden_biases(&mut target, self.target_bias, rng)?;
            }
            let mut predictor = Mlp::new(&self.net_config(d, &self.predictor_hidden), rng)
                .map_err(|e| prefix("predictor", e))?;
            let y = target.predict(x.view());
            let loss = fit_regression(
                &mut predictor,
                x.view(),
                y.view(),
                &Regression {
                    epochs: self.epochs,
                    batch_size: self.batch_size,
                    adam: &self.adam,
                    progress_offset: e * self.epochs,
                    progress_total: self.ensemble * self.epochs,
                },
                rng,
                progress,
            )?;
            pairs.push(RndPair {
                target: FrozenMlp::new(target),
                predictor,
            });
            final_losses.push(loss);
        }
        Ok(Rnd {
            input,
            pairs,
            final_losses,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimator::no_progress;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn small() -> RndConfig {
        RndConfig {
            target_hidden: vec![32, 32],
            predictor_hidden: vec![32],
            output: 16,
            epochs: 5,
            ensemble: 2,
            ..Default::default()
        }
    }

    /// `cfg` fitted on `s`, `a` from the stream of seed 2.
    fn fit_seed2(cfg: &RndConfig, s: &Array2<f64>, a: &Array2<f64>) -> Rnd {
        cfg.fit(
            s.view(),
            a.view(),
            &mut ChaCha8Rng::seed_from_u64(2),
            &mut no_progress,
        )
        .unwrap()
    }

    fn data(n: usize, seed: u64) -> (Array2<f64>, Array2<f64>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (
            Array2::from_shape_fn((n, 3), |_| rng.random_range(-1.0..1.0)),
            Array2::from_shape_fn((n, 2), |_| rng.random_range(-1.0..1.0)),
        )
    }

    #[test]
    fn periodic_dims_score_a_period_apart_alike_and_keep_the_gradient() {
        let (s, a) = data(64, 1);
        let cfg = RndConfig {
            periodic_state_dims: vec![PeriodicDim {
                dim: 0,
                period: 2.0,
            }],
            activation: Activation::Tanh,
            ..small()
        };
        let model = fit_seed2(&cfg, &s, &a);
        let mut shifted = s.clone();
        shifted.column_mut(0).mapv_inplace(|v| v + 2.0);
        let (x, y) = (
            model.score(s.view(), a.view()).unwrap(),
            model.score(shifted.view(), a.view()).unwrap(),
        );
        for (u, v) in x.iter().zip(&y) {
            assert!((u - v).abs() < 1e-6 * (1.0 + u.abs()), "{u} {v}");
        }
        // a shift by half the period is a different input.
        shifted.column_mut(0).mapv_inplace(|v| v - 1.0);
        let z = model.score(shifted.view(), a.view()).unwrap();
        assert!(x.iter().zip(&z).any(|(u, v)| (u - v).abs() > 1e-3));
        // the action gradient still matches finite differences.
        let (_, g) = model.score_grad_action(s.view(), a.view()).unwrap();
        let h = 1e-3;
        for j in 0..2 {
            let (mut up, mut down) = (a.clone(), a.clone());
            up.column_mut(j).mapv_inplace(|v| v + h);
            down.column_mut(j).mapv_inplace(|v| v - h);
            let fd = (model.score(s.view(), up.view()).unwrap()
                - model.score(s.view(), down.view()).unwrap())
                / (2.0 * h);
            for i in 0..4 {
                assert!(
                    (fd[i] - g[[i, j]]).abs() < 1e-2 * (1.0 + fd[i].abs()),
                    "{} {}",
                    fd[i],
                    g[[i, j]]
                );
            }
        }
        let bad = RndConfig {
            periodic_state_dims: vec![PeriodicDim {
                dim: 0,
                period: -1.0,
            }],
            ..small()
        };
        let e = bad.validate().unwrap_err();
        assert!(
            e.to_string().contains("periodic_state_dims[0].period"),
            "{e}"
        );
    }

    #[test]
    fn capped_dims_score_values_above_the_cap_alike() {
        let (s, a) = data(64, 1);
        for standardize in [false, true] {
            let cfg = RndConfig {
                capped_state_dims: vec![CappedDim { dim: 1, max: 0.0 }],
                standardize,
                ..small()
            };
            let model = fit_seed2(&cfg, &s, &a);
            let (mut up, mut down) = (s.clone(), s.clone());
            up.column_mut(1).fill(0.5);
            down.column_mut(1).fill(3.0);
            let (x, y) = (
                model.score(up.view(), a.view()).unwrap(),
                model.score(down.view(), a.view()).unwrap(),
            );
            assert_eq!(x, y);
            down.column_mut(1).fill(-0.5);
            let z = model.score(down.view(), a.view()).unwrap();
            assert!(x.iter().zip(&z).any(|(u, v)| (u - v).abs() > 1e-6));
        }
    }

    #[test]
    fn a_capped_fit_is_the_fit_on_the_capped_states() {
        let (s, a) = data(64, 1);
        let caps = vec![CappedDim { dim: 1, max: 0.0 }];
        let cfg = RndConfig {
            capped_state_dims: caps.clone(),
            standardize: true,
            ..small()
        };
        let capped = cap_states(s.view(), &caps).unwrap();
        let (m1, m2) = (fit_seed2(&cfg, &s, &a), fit_seed2(&cfg, &capped, &a));
        assert_eq!(
            m1.score(s.view(), a.view()).unwrap(),
            m2.score(s.view(), a.view()).unwrap()
        );
        // without the cap the statistics differ, and so do the scores.
        let plain = RndConfig {
            standardize: true,
            ..small()
        };
        assert_ne!(
            fit_seed2(&plain, &s, &a).score(s.view(), a.view()).unwrap(),
            fit_seed2(&plain, &capped, &a)
                .score(s.view(), a.view())
                .unwrap()
        );
    }

    #[test]
    fn a_dimension_may_take_one_input_setting() {
        let periodic = vec![PeriodicDim {
            dim: 2,
            period: 1.0,
        }];
        for cfg in [
            RndConfig {
                ignored_state_dims: vec![2],
                periodic_state_dims: periodic.clone(),
                ..small()
            },
            RndConfig {
                capped_state_dims: vec![CappedDim { dim: 2, max: 0.0 }],
                periodic_state_dims: periodic.clone(),
                ..small()
            },
            RndConfig {
                ignored_state_dims: vec![2],
                capped_state_dims: vec![CappedDim { dim: 2, max: 0.0 }],
                ..small()
            },
        ] {
            let e = cfg.validate().unwrap_err();
            assert!(
                e.to_string().contains("state dimension 2 also stands"),
                "{e}"
            );
        }
    }

    #[test]
    fn a_weighted_dim_reads_as_the_state_scaled_by_its_weight() {
        let (s, a) = data(64, 1);
        let weighted = RndConfig {
            weighted_state_dims: vec![WeightedDim {
                dim: 1,
                weight: 0.5,
            }],
            ..small()
        };
        // Without standardisation a weight is the same fit as the states
        // scaled by it beforehand.
        let mut halved = s.clone();
        halved.column_mut(1).mapv_inplace(|v| 0.5 * v);
        let (m1, m2) = (
            fit_seed2(&weighted, &s, &a),
            fit_seed2(&small(), &halved, &a),
        );
        let mut probe = s.clone();
        probe.column_mut(1).mapv_inplace(|v| v + 1.0);
        let mut probe_halved = probe.clone();
        probe_halved.column_mut(1).mapv_inplace(|v| 0.5 * v);
        assert_eq!(
            m1.score(probe.view(), a.view()).unwrap(),
            m2.score(probe_halved.view(), a.view()).unwrap()
        );
        assert_ne!(
            m1.score(probe.view(), a.view()).unwrap(),
            fit_seed2(&small(), &s, &a)
                .score(probe.view(), a.view())
                .unwrap()
        );
        for cfg in [
            RndConfig {
                ignored_state_dims: vec![1],
                ..weighted.clone()
            },
            RndConfig {
                periodic_state_dims: vec![PeriodicDim {
                    dim: 1,
                    period: 1.0,
                }],
                ..weighted.clone()
            },
        ] {
            let e = cfg.validate().unwrap_err();
            assert!(e.to_string().contains("no value to weigh"), "{e}");
        }
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let (s, a) = data(64, 1);
        for standardize in [false, true] {
            // A smooth activation, so finite differences do not straddle
            // the kinks of leaky relu (the backward pass is the same code
            // for every activation).
            let cfg = RndConfig {
                standardize,
                activation: Activation::Tanh,
                ..small()
            };
            let model = fit_seed2(&cfg, &s, &a);
            let (qs, qa) = data(5, 3);
            let (sc, g) = model.score_grad_action(qs.view(), qa.view()).unwrap();
            let plain = model.score(qs.view(), qa.view()).unwrap();
            for (x, y) in sc.iter().zip(&plain) {
                assert!((x - y).abs() <= 1e-6 * y.abs().max(1e-6));
            }
            // f32 networks: a step of 1e-2 keeps the rounding of the
            // difference quotient well below the tolerance.
            let eps = 1e-2;
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
                        "std {standardize} row {r} dim {j}: fd {fd} vs analytic {an}"
                    );
                }
            }
        }
    }

    #[test]
    fn row_by_row_scores_match_batched_scores() {
        let (s, a) = data(64, 4);
        let model = small()
            .fit(
                s.view(),
                a.view(),
                &mut ChaCha8Rng::seed_from_u64(5),
                &mut no_progress,
            )
            .unwrap();
        let (qs, qa) = data(20, 6);
        let batched = model.score(qs.view(), qa.view()).unwrap();
        for i in 0..20 {
            let one = model
                .score(
                    qs.slice(ndarray::s![i..i + 1, ..]),
                    qa.slice(ndarray::s![i..i + 1, ..]),
                )
                .unwrap();
            assert!(
                (one[0] - batched[i]).abs() <= 1e-5 * batched[i].abs().max(1e-9),
                "row {i}: {} vs {}",
                one[0],
                batched[i]
            );
        }
    }

    #[test]
    fn validation_names_the_field() {
        let e = RndConfig {
            batch_size: 0,
            ..Default::default()
        }
        .validate()
        .unwrap_err();
        assert!(e.to_string().contains("batch_size"), "{e}");
        let e = RndConfig {
            target_hidden: vec![8, 0],
            ..Default::default()
        }
        .validate()
        .unwrap_err();
        assert!(e.to_string().contains("target_hidden[1]"), "{e}");
        let mut c = RndConfig::default();
        c.adam.lr = -1.0;
        assert!(c.validate().unwrap_err().to_string().contains("adam.lr"));
    }

    #[test]
    fn target_biases_are_drawn_only_when_asked_and_mark_the_inside_of_a_ring() {
        // A periodic gait in miniature: states on a circle of radius 1,
        // the action the cosine of the angle. The centre (a still state)
        // lies inside the cloud, not on it.
        let n = 400;
        let th = |i: usize| i as f64 * std::f64::consts::TAU / n as f64;
        let s = Array2::from_shape_fn(
            (n, 2),
            |(i, j)| {
                if j == 0 { th(i).cos() } else { th(i).sin() }
            },
        );
        let a = Array2::from_shape_fn((n, 1), |(i, _)| th(i).cos());
        let centre = (Array2::zeros((1, 2)), Array2::zeros((1, 1)));
        let fit = |bias: f32| {
            let cfg = RndConfig {
                target_hidden: vec![64; 3],
                predictor_hidden: vec![64],
                output: 32,
                epochs: 60,
                standardize: true,
                target_bias: bias,
                ..Default::default()
            };
            let mut rng = ChaCha8Rng::seed_from_u64(3);
            let m = cfg
                .fit(s.view(), a.view(), &mut rng, &mut no_progress)
                .unwrap();
            let on = m.score(s.view(), a.view()).unwrap();
            let mut on = on.to_vec();
            on.sort_by(f64::total_cmp);
            let inside = m.score(centre.0.view(), centre.1.view()).unwrap()[0];
            (m, inside / on[on.len() * 9 / 10])
        };
        let (plain, plain_ratio) = fit(0.0);
        let (biased, biased_ratio) = fit(2.0);
        // Zero biases: every target bias is zero; drawn: the hidden ones lie
        // in [-2, 2] and are not all zero, the output's stay zero.
        let layers = plain.pairs()[0].target.as_mlp().layers();
        assert!(layers.iter().all(|l| l.b.iter().all(|&b| b == 0.0)));
        let layers = biased.pairs()[0].target.as_mlp().layers();
        let (last, hidden) = layers.split_last().unwrap();
        assert!(last.b.iter().all(|&b| b == 0.0));
        assert!(hidden.iter().all(|l| l.b.iter().all(|&b| b.abs() <= 2.0)));
        assert!(hidden.iter().all(|l| l.b.iter().any(|&b| b != 0.0)));
        // Drawn biases raise the centre's score against the ring's own
        // pairs (measured: 37 times the ring's 90% quantile with zero
        // biases, 285-325 times with biases of 1, 2 or 3).
        assert!(
            biased_ratio > 5.0 * plain_ratio,
            "centre over the ring's 90% quantile: {plain_ratio:.2} with zero biases, \
             {biased_ratio:.2} with drawn ones"
        );
        let bad = RndConfig {
            target_bias: -1.0,
            ..Default::default()
        };
        assert!(
            bad.validate()
                .unwrap_err()
                .to_string()
                .contains("target_bias")
        );
    }
}
