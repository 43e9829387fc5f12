//! GAIL's reward (Ho & Ermon 2016): a discriminator trained alternately with
//! the policy to tell expert pairs from the policy's.
//!
//! The discriminator outputs a logit `l(s, a)`; `D = sigmoid(l)` is its
//! probability that the pair is the EXPERT's. It minimises
//! `BCE(expert, 1) + BCE(policy, 0) - entropy_coef * H(D)` over policy pairs
//! and as many expert pairs drawn at random. The policy's reward is
//! `-ln(1 - D(s, a) + 1e-8)`, the form of OpenAI baselines' GAIL (which the
//! RED release compared against): positive, larger where the pair looks
//! like the expert's. With episodes that end on failure, a positive reward
//! also rewards survival; learners keep termination and truncation apart.

use ndarray::{Array1, Array2, ArrayView2, s};
use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use red_core::RewardModel;
use red_nets::{Activation, Adam, AdamConfig, Gradients, Init, Mlp, MlpConfig, Optimizer, Tape};

use crate::{Error, Result};
use red_core::DifferentiableReward;

/// Settings of [`Gail`]. Defaults are OpenAI baselines' GAIL
/// (`run_mujoco.py`: adversary hidden size 100, entropy coefficient 1e-3,
/// discriminator step size 3e-4, one discriminator epoch per policy batch).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GailConfig {
    /// Hidden widths of the discriminator (baselines: 100, 100, tanh).
    pub hidden: Vec<usize>,
    /// Adam step size (baselines: 3e-4).
    pub learning_rate: f32,
    /// Weight of the entropy bonus on `D` (baselines: 1e-3).
    pub entropy_coef: f32,
    /// Passes over the policy batch per [`RewardModel::update`] (baselines'
    /// `d_step`: 1).
    pub epochs: usize,
    /// Policy pairs per discriminator minibatch, matched by as many expert
    /// pairs (baselines splits a 1024-step batch into minibatches of 128).
    pub minibatch: usize,
    /// Standardise inputs with the expert pairs' mean and std (baselines
    /// normalises observations with running statistics; frozen expert
    /// statistics keep the reward from drifting for that reason alone).
    pub standardize: bool,
}

impl Default for GailConfig {
    fn default() -> Self {
        Self {
            hidden: vec![100, 100],
            learning_rate: 3e-4,
            entropy_coef: 1e-3,
            epochs: 1,
            minibatch: 128,
            standardize: true,
        }
    }
}

impl GailConfig {
    /// Checks every field.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the first bad field.
    pub fn validate(&self) -> Result<()> {
        let bad = |field: &str, reason: &str| {
            Err(Error::InvalidConfig {
                field: field.into(),
                reason: reason.into(),
            })
        };
        if self.hidden.contains(&0) {
            return bad("hidden", "widths must be at least 1");
        }
        if !(self.learning_rate.is_finite() && self.learning_rate > 0.0) {
            return bad("learning_rate", "must be a positive number");
        }
        if !(self.entropy_coef.is_finite() && self.entropy_coef >= 0.0) {
            return bad("entropy_coef", "must be a non-negative number");
        }
        if self.epochs == 0 {
            return bad("epochs", "must be at least 1");
        }
        if self.minibatch == 0 {
            return bad("minibatch", "must be at least 1");
        }
        Ok(())
    }
}

/// Concatenates states and actions row by row into `f32` pairs.
pub(crate) fn concat_pairs(
    states: ArrayView2<'_, f64>,
    actions: ArrayView2<'_, f64>,
) -> Result<Array2<f64>> {
    if states.nrows() != actions.nrows() {
        return Err(Error::ShapeMismatch {
            what: "state and action batches".into(),
            expected: format!("{} actions", states.nrows()),
            got: format!("{}", actions.nrows()),
        });
    }
    let mut x = Array2::zeros((states.nrows(), states.ncols() + actions.ncols()));
    x.slice_mut(s![.., ..states.ncols()]).assign(&states);
    x.slice_mut(s![.., states.ncols()..]).assign(&actions);
    Ok(x)
}

/// The GAIL reward model: a discriminator that adapts to each policy batch.
#[derive(Clone, Serialize, Deserialize)]
pub struct Gail {
    config: GailConfig,
    disc: Mlp,
    optimizer: Adam,
    expert: Array2<f32>,
    mean: Vec<f64>,
    std: Vec<f64>,
    obs_dim: usize,
    act_dim: usize,
    rng: ChaCha8Rng,
    last_loss: f64,
}

impl Gail {
    /// A discriminator for the expert pairs `(n, obs_dim)` and `(n, act_dim)`,
    /// initialised and sampled from `seed`.
    ///
    /// # Errors
    /// A bad config, mismatched or empty expert batches, non-finite values.
    pub fn new(
        config: GailConfig,
        expert_states: ArrayView2<'_, f64>,
        expert_actions: ArrayView2<'_, f64>,
        seed: u64,
    ) -> Result<Self> {
        config.validate()?;
        let x = concat_pairs(expert_states, expert_actions)?;
        if x.nrows() == 0 {
            return Err(Error::InvalidConfig {
                field: "expert pairs".into(),
                reason: "need at least one expert pair".into(),
            });
        }
        if x.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "expert pairs".into(),
                step: 0,
            });
        }
        let dim = x.ncols();
        let (mean, std) = if config.standardize {
            column_stats(&x)
        } else {
            (vec![0.0; dim], vec![1.0; dim])
        };
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let net = MlpConfig::new(dim, &config.hidden, 1)
            .with_activation(Activation::Tanh)
            .with_init(Init::GlorotUniform);
        let disc = Mlp::new(&net, &mut rng)?;
        let optimizer = Adam::new(
            AdamConfig {
                lr: config.learning_rate,
                ..AdamConfig::default()
            },
            &disc,
        )?;
        let expert = standardize(&x, &mean, &std);
        Ok(Self {
            config,
            disc,
            optimizer,
            expert,
            mean,
            std,
            obs_dim: expert_states.ncols(),
            act_dim: expert_actions.ncols(),
            rng,
            last_loss: f64::NAN,
        })
    }

    /// The discriminator loss of the last update (NaN before any).
    pub fn last_loss(&self) -> f64 {
        self.last_loss
    }

    /// Probability `D(s, a)` that each pair is the expert's, `(n,)`.
    ///
    /// # Errors
    /// Shape mismatches with the expert dimensions.
    pub fn expert_probability(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<Array1<f64>> {
        let x = self.inputs(states, actions)?;
        let logits = self.disc.predict(x.view());
        Ok(logits.column(0).mapv(|l| sigmoid(l as f64)))
    }

    fn inputs(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<Array2<f32>> {
        if states.ncols() != self.obs_dim || actions.ncols() != self.act_dim {
            return Err(Error::ShapeMismatch {
                what: "GAIL input".into(),
                expected: format!("states of {} and actions of {}", self.obs_dim, self.act_dim),
                got: format!("{} and {}", states.ncols(), actions.ncols()),
            });
        }
        let x = concat_pairs(states, actions)?;
        Ok(standardize(&x, &self.mean, &self.std))
    }
}

fn column_stats(x: &Array2<f64>) -> (Vec<f64>, Vec<f64>) {
    let n = x.nrows() as f64;
    let mean: Vec<f64> = x.columns().into_iter().map(|c| c.sum() / n).collect();
    let std = x
        .columns()
        .into_iter()
        .zip(&mean)
        .map(|(c, m)| {
            let var = c.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / n;
            // A constant column (e.g. one expert action everywhere) keeps its scale.
            if var > 1e-12 { var.sqrt() } else { 1.0 }
        })
        .collect();
    (mean, std)
}

fn standardize(x: &Array2<f64>, mean: &[f64], std: &[f64]) -> Array2<f32> {
    Array2::from_shape_fn(x.raw_dim(), |(i, j)| {
        ((x[[i, j]] - mean[j]) / std[j]) as f32
    })
}

fn sigmoid(l: f64) -> f64 {
    1.0 / (1.0 + (-l).exp())
}

impl RewardModel for Gail {
    fn rewards(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> red_core::Result<Array1<f64>> {
        let d = self
            .expert_probability(states, actions)
            .map_err(into_core)?;
        Ok(d.mapv(|p| -(1.0 - p + 1e-8).ln()))
    }

    fn update(
        &mut self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> red_core::Result<()> {
        self.train_discriminator(states, actions).map_err(into_core)
    }

    fn is_adaptive(&self) -> bool {
        true
    }
}

impl Gail {
    fn train_discriminator(
        &mut self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<()> {
        let policy = self.inputs(states, actions)?;
        let n = policy.nrows();
        if n == 0 {
            return Ok(());
        }
        let mut tape = Tape::new();
        let mut grads = Gradients::zeros(&self.disc);
        let mut order: Vec<usize> = (0..n).collect();
        let dim = policy.ncols();
        let mut total = 0.0;
        let mut batches = 0;
        for _ in 0..self.config.epochs {
            order.shuffle(&mut self.rng);
            for chunk in order.chunks(self.config.minibatch) {
                let m = chunk.len();
                // Rows 0..m are the policy's (label 0), m..2m the expert's (label 1).
                let mut x = Array2::<f32>::zeros((2 * m, dim));
                for (r, &i) in chunk.iter().enumerate() {
                    x.row_mut(r).assign(&policy.row(i));
                    let e = self.rng.random_range(0..self.expert.nrows());
                    x.row_mut(m + r).assign(&self.expert.row(e));
                }
                let logits = self.disc.forward_tape(x.view(), &mut tape).to_owned();
                let mut g = Array2::<f32>::zeros((2 * m, 1));
                let mut loss = 0.0f64;
                for r in 0..2 * m {
                    let l = logits[[r, 0]] as f64;
                    let y = if r < m { 0.0 } else { 1.0 };
                    let p = sigmoid(l);
                    // Mean BCE of each half, as baselines sums two means.
                    loss += (softplus(l) - y * l) / m as f64;
                    let mut dl = (p - y) / m as f64;
                    // -entropy_coef * mean entropy over all 2m logits.
                    let h = softplus(l) - l * p;
                    loss -= self.config.entropy_coef as f64 * h / (2 * m) as f64;
                    dl += self.config.entropy_coef as f64 * l * p * (1.0 - p) / (2 * m) as f64;
                    g[[r, 0]] = dl as f32;
                }
                if !loss.is_finite() {
                    return Err(Error::NonFinite {
                        what: "GAIL discriminator loss".into(),
                        step: batches,
                    });
                }
                grads.zero();
                self.disc.backward(&tape, g.view(), &mut grads);
                self.optimizer.step(&mut self.disc, &grads)?;
                total += loss;
                batches += 1;
            }
        }
        self.last_loss = total / batches as f64;
        Ok(())
    }
}

/// GAIL's reward with its action gradient, for SVG(1)-ER: the
/// discriminator is differentiated with respect to its input (through the
/// input standardisation), `d/dl [-ln(1 - sigmoid(l) + 1e-8)] = D (1 - D) /
/// (1 - D + 1e-8)`.
impl Gail {
    /// [`DifferentiableReward::reward_and_grad`] with this crate's errors.
    fn reward_grad(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<(Array1<f64>, Array2<f64>)> {
        let x = self.inputs(states, actions)?;
        let n = x.nrows();
        let mut tape = Tape::new();
        let logits = self.disc.forward_tape(x.view(), &mut tape).to_owned();
        let mut r = Array1::zeros(n);
        let mut g = Array2::<f32>::zeros((n, 1));
        for i in 0..n {
            let p = sigmoid(logits[[i, 0]] as f64);
            r[i] = -(1.0 - p + 1e-8).ln();
            g[[i, 0]] = (p * (1.0 - p) / (1.0 - p + 1e-8)) as f32;
        }
        let mut scratch = Gradients::zeros(&self.disc);
        let dx = self.disc.backward(&tape, g.view(), &mut scratch);
        let o = self.obs_dim;
        let da = Array2::from_shape_fn((n, self.act_dim), |(i, j)| {
            dx[[i, o + j]] as f64 / self.std[o + j]
        });
        Ok((r, da))
    }
}

impl DifferentiableReward for Gail {
    fn reward_and_grad(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> red_core::Result<(Array1<f64>, Array2<f64>)> {
        self.reward_grad(states, actions).map_err(into_core)
    }

    fn is_adaptive(&self) -> bool {
        true
    }
}

/// `ln(1 + e^l)`, stable for large `|l|`.
fn softplus(l: f64) -> f64 {
    if l > 30.0 { l } else { l.exp().ln_1p() }
}

pub(crate) fn into_core(e: Error) -> red_core::Error {
    match e {
        Error::Core(c) => c,
        other => red_core::Error::Env {
            reason: other.to_string(),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;

    #[test]
    fn discriminator_learns_to_separate() {
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let es = Array2::from_shape_fn((200, 1), |_| rng.random_range(-1.0..1.0));
        let ea = es.mapv(|s: f64| if s >= 0.0 { 1.0 } else { 0.0 });
        let mut gail = Gail::new(GailConfig::default(), es.view(), ea.view(), 1).unwrap();
        // The "policy" always takes the wrong action.
        let ps = Array2::from_shape_fn((256, 1), |_| rng.random_range(-1.0..1.0));
        let pa = ps.mapv(|s: f64| if s >= 0.0 { 0.0 } else { 1.0 });
        let before = gail.rewards(ps.view(), pa.view()).unwrap().mean().unwrap();
        for _ in 0..150 {
            gail.update(ps.view(), pa.view()).unwrap();
        }
        let wrong = gail.rewards(ps.view(), pa.view()).unwrap().mean().unwrap();
        let right = gail.rewards(es.view(), ea.view()).unwrap().mean().unwrap();
        assert!(
            right > wrong + 0.5,
            "expert reward {right} vs policy {wrong} (before {before})"
        );
        assert!(gail.last_loss().is_finite());
    }

    #[test]
    fn action_gradient_matches_finite_differences() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let es = Array2::from_shape_fn((64, 3), |_| rng.random_range(-1.0..1.0));
        let ea = Array2::from_shape_fn((64, 2), |_| rng.random_range(-0.5..0.5));
        let mut gail = Gail::new(GailConfig::default(), es.view(), ea.view(), 2).unwrap();
        let ps = Array2::from_shape_fn((64, 3), |_| rng.random_range(-1.0..1.0));
        let pa = Array2::from_shape_fn((64, 2), |_| rng.random_range(-1.0..1.0));
        for _ in 0..30 {
            gail.update(ps.view(), pa.view()).unwrap();
        }
        let (s, a) = (ps.slice(s![..8, ..]), pa.slice(s![..8, ..]));
        let (r, g) = gail.reward_and_grad(s, a).unwrap();
        assert_eq!(r, gail.rewards(s, a).unwrap());
        let h = 1e-2;
        for i in 0..8 {
            for j in 0..2 {
                let at = |d: f64| {
                    let mut a2 = a.to_owned();
                    a2[[i, j]] += d;
                    gail.rewards(s, a2.view()).unwrap()[i]
                };
                let numeric = (at(h) - at(-h)) / (2.0 * h);
                assert!(
                    (numeric - g[[i, j]]).abs() <= 0.02 * numeric.abs() + 2e-3,
                    "pair {i} action {j}: analytic {} numeric {numeric}",
                    g[[i, j]]
                );
            }
        }
        assert!(g.iter().any(|v| v.abs() > 1e-2), "{g}");
        assert!(DifferentiableReward::is_adaptive(&gail));
    }

    #[test]
    fn rejects_mismatched_inputs() {
        let es = Array2::zeros((4, 2));
        let ea = Array2::zeros((3, 1));
        assert!(Gail::new(GailConfig::default(), es.view(), ea.view(), 0).is_err());
        let ea = Array2::zeros((4, 1));
        let gail = Gail::new(GailConfig::default(), es.view(), ea.view(), 0).unwrap();
        assert!(
            gail.rewards(Array2::zeros((2, 3)).view(), Array2::zeros((2, 1)).view())
                .is_err()
        );
        let c = GailConfig {
            minibatch: 0,
            ..GailConfig::default()
        };
        assert!(c.validate().unwrap_err().to_string().contains("minibatch"));
    }
}
