//! Optimisers: Adam and SGD with momentum, both with L2 weight decay.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::grads::Gradients;
use crate::mlp::Mlp;

/// Name written into saved Adam states.
pub const ADAM_FORMAT: &str = "red-nets/adam";
/// Version of the saved Adam format written by this crate.
pub const ADAM_FORMAT_VERSION: u32 = 1;

/// Updates a network's parameters from gradients of a loss.
pub trait Optimizer {
    /// One update of `net` with `grads` (gradients of the loss to MINIMISE,
    /// layout of `net`).
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] when `grads` or the optimiser's state has
    /// another layout than `net`; [`Error::NonFinite`] when a gradient is NaN
    /// or infinite (the network and state are left unchanged).
    fn step(&mut self, net: &mut Mlp, grads: &Gradients) -> Result<()>;
}

fn check_grads(net: &Mlp, grads: &Gradients, what: &str) -> Result<()> {
    if !grads.matches(net) {
        return Err(Error::shape(
            format!("{what}: gradients"),
            "the network's layout",
            "another layout",
        ));
    }
    if !grads.is_finite() {
        return Err(Error::NonFinite {
            what: format!("{what}: gradients"),
        });
    }
    Ok(())
}

fn check_nonneg(field: &str, v: f32) -> Result<()> {
    if !(v.is_finite() && v >= 0.0) {
        return Err(Error::config(
            field,
            format!("must be finite and >= 0, got {v}"),
        ));
    }
    Ok(())
}

/// Settings of [`Adam`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AdamConfig {
    /// Step size. Default 1e-3: the RED release's RND predictor and value
    /// function (and Kingma & Ba's suggestion).
    pub lr: f32,
    /// Decay of the first-moment average. Default 0.9 (Kingma & Ba; TF and PyTorch default).
    pub beta1: f32,
    /// Decay of the second-moment average. Default 0.999 (Kingma & Ba; TF and PyTorch default).
    pub beta2: f32,
    /// Added to the denominator. Default 1e-8: the default of TF1's
    /// `tf.train.AdamOptimizer` (which the release uses) and of PyTorch's
    /// `Adam` (Keras' newer `Adam` uses 1e-7). Note TF1 adds it to
    /// `sqrt(v_t)` before bias correction, this crate (like PyTorch and
    /// Kingma & Ba's Algorithm 1) after; the two agree unless `sqrt(v)` is
    /// near `eps`.
    pub eps: f32,
    /// L2 penalty: `weight_decay * w` is added to each WEIGHT's gradient
    /// before the moments (the gradient of `weight_decay / 2 * ||W||^2`, as
    /// TF's `l2_regularizer(scale)`); biases are not decayed. Default 0.
    pub weight_decay: f32,
}

impl Default for AdamConfig {
    fn default() -> Self {
        AdamConfig {
            lr: 1e-3,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
            weight_decay: 0.0,
        }
    }
}

impl AdamConfig {
    /// Default settings with step size `lr`.
    pub fn with_lr(lr: f32) -> Self {
        AdamConfig {
            lr,
            ..AdamConfig::default()
        }
    }

    /// Checks the settings.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the field: `lr` not finite and > 0,
    /// `beta1`/`beta2` outside `[0, 1)`, `eps` not finite and > 0,
    /// `weight_decay` negative or not finite.
    pub fn validate(&self) -> Result<()> {
        if !(self.lr.is_finite() && self.lr > 0.0) {
            return Err(Error::config(
                "lr",
                format!("must be finite and > 0, got {}", self.lr),
            ));
        }
        for (name, b) in [("beta1", self.beta1), ("beta2", self.beta2)] {
            if !(0.0..1.0).contains(&b) {
                return Err(Error::config(name, format!("must be in [0, 1), got {b}")));
            }
        }
        if !(self.eps.is_finite() && self.eps > 0.0) {
            return Err(Error::config(
                "eps",
                format!("must be finite and > 0, got {}", self.eps),
            ));
        }
        check_nonneg("weight_decay", self.weight_decay)
    }
}

/// Adam (Kingma & Ba 2015, Algorithm 1) with optional L2 weight decay.
///
/// Per parameter: `g += wd * w` (weights only), `m = b1 m + (1 - b1) g`,
/// `v = b2 v + (1 - b2) g^2`, `w -= lr / (1 - b1^t) * m / (sqrt(v) /
/// sqrt(1 - b2^t) + eps)`: PyTorch's arrangement of the same formula.
///
/// Serialisable: save it beside the network to resume training exactly.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Adam {
    config: AdamConfig,
    t: u64,
    m: Gradients,
    v: Gradients,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SavedAdam {
    format: String,
    version: u32,
    adam: Adam,
}

impl Adam {
    /// A fresh optimiser (zero moments, step 0) for `net`'s layout.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] when `config.validate()` fails.
    pub fn new(config: AdamConfig, net: &Mlp) -> Result<Adam> {
        config.validate()?;
        Ok(Adam {
            config,
            t: 0,
            m: net.zero_grads(),
            v: net.zero_grads(),
        })
    }

    /// The settings.
    pub fn config(&self) -> &AdamConfig {
        &self.config
    }

    /// Changes the step size (for schedules).
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] when `lr` is not finite and positive.
    pub fn set_lr(&mut self, lr: f32) -> Result<()> {
        let c = AdamConfig {
            lr,
            ..self.config.clone()
        };
        c.validate()?;
        self.config = c;
        Ok(())
    }

    /// Number of steps taken.
    pub fn steps(&self) -> u64 {
        self.t
    }

    /// The state as JSON (`{"format": "red-nets/adam", "version": 1, "adam": ..}`).
    ///
    /// # Errors
    /// [`Error::Format`] if serialisation fails.
    pub fn to_json(&self) -> Result<String> {
        let doc = SavedAdam {
            format: ADAM_FORMAT.into(),
            version: ADAM_FORMAT_VERSION,
            adam: self.clone(),
        };
        serde_json::to_string(&doc).map_err(|e| Error::Format {
            path: None,
            reason: e.to_string(),
        })
    }

    /// Reads a state written by [`Adam::to_json`].
    ///
    /// # Errors
    /// [`Error::Format`] when the text is not such a document or has another
    /// format, version, or an invalid config.
    pub fn from_json(s: &str) -> Result<Adam> {
        Self::parse(s).map_err(|reason| Error::Format { path: None, reason })
    }

    fn parse(s: &str) -> std::result::Result<Adam, String> {
        let doc: SavedAdam =
            serde_json::from_str(s).map_err(|e| format!("not a saved red-nets Adam state: {e}"))?;
        if doc.format != ADAM_FORMAT {
            return Err(format!(
                "format is `{}`, expected `{ADAM_FORMAT}`",
                doc.format
            ));
        }
        if doc.version != ADAM_FORMAT_VERSION {
            return Err(format!(
                "format version {} is not supported (this build reads {ADAM_FORMAT_VERSION})",
                doc.version
            ));
        }
        doc.adam.config.validate().map_err(|e| e.to_string())?;
        Ok(doc.adam)
    }

    /// Writes [`Adam::to_json`] to `path`.
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

    /// Reads a state saved by [`Adam::save`].
    ///
    /// # Errors
    /// [`Error::Io`] when the file cannot be read, [`Error::Format`] when its
    /// content is not a valid state.
    pub fn load(path: &Path) -> Result<Adam> {
        let s = std::fs::read_to_string(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&s).map_err(|reason| Error::Format {
            path: Some(path.to_path_buf()),
            reason,
        })
    }
}

/// One Adam update of a contiguous block. `decay` is the L2 factor for this
/// block (0 for biases).
#[inline]
fn adam_block(p: &mut [f32], g: &[f32], m: &mut [f32], v: &mut [f32], c: &AdamConsts, decay: f32) {
    for (((p, &g), m), v) in p.iter_mut().zip(g).zip(m.iter_mut()).zip(v.iter_mut()) {
        let g = g + decay * *p;
        *m = c.b1 * *m + c.one_minus_b1 * g;
        *v = c.b2 * *v + c.one_minus_b2 * g * g;
        let denom = v.sqrt() * c.inv_sqrt_bc2 + c.eps;
        *p -= c.step * *m / denom;
    }
}

struct AdamConsts {
    b1: f32,
    b2: f32,
    one_minus_b1: f32,
    one_minus_b2: f32,
    inv_sqrt_bc2: f32,
    eps: f32,
    step: f32,
}

impl Optimizer for Adam {
    fn step(&mut self, net: &mut Mlp, grads: &Gradients) -> Result<()> {
        check_grads(net, grads, "Adam::step")?;
        if !self.m.matches(net) || !self.v.matches(net) {
            return Err(Error::shape(
                "Adam::step: optimiser state",
                "the network's layout",
                "another layout",
            ));
        }
        self.t += 1;
        let c = &self.config;
        let t = self.t as i32;
        let bc1 = 1.0 - (c.beta1 as f64).powi(t);
        let bc2 = 1.0 - (c.beta2 as f64).powi(t);
        let k = AdamConsts {
            b1: c.beta1,
            b2: c.beta2,
            one_minus_b1: 1.0 - c.beta1,
            one_minus_b2: 1.0 - c.beta2,
            inv_sqrt_bc2: (1.0 / bc2.sqrt()) as f32,
            eps: c.eps,
            step: (c.lr as f64 / bc1) as f32,
        };
        let wd = c.weight_decay;
        for (((layer, g), m), v) in net
            .layers_mut()
            .iter_mut()
            .zip(grads.layers())
            .zip(self.m.layers_mut())
            .zip(self.v.layers_mut())
        {
            adam_block(
                layer.w.as_slice_mut().expect("contiguous"),
                g.dw.as_slice().expect("contiguous"),
                m.dw.as_slice_mut().expect("contiguous"),
                v.dw.as_slice_mut().expect("contiguous"),
                &k,
                wd,
            );
            adam_block(
                layer.b.as_slice_mut().expect("contiguous"),
                g.db.as_slice().expect("contiguous"),
                m.db.as_slice_mut().expect("contiguous"),
                v.db.as_slice_mut().expect("contiguous"),
                &k,
                0.0,
            );
        }
        Ok(())
    }
}

/// Settings of [`Sgd`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SgdConfig {
    /// Step size. Default 1e-2 (PyTorch's examples; SGD has no universal default).
    pub lr: f32,
    /// Momentum factor in `[0, 1)`. Default 0 (plain SGD).
    pub momentum: f32,
    /// L2 penalty on weights (not biases), as in [`AdamConfig::weight_decay`]. Default 0.
    pub weight_decay: f32,
}

impl Default for SgdConfig {
    fn default() -> Self {
        SgdConfig {
            lr: 1e-2,
            momentum: 0.0,
            weight_decay: 0.0,
        }
    }
}

impl SgdConfig {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the field: `lr` not finite and > 0,
    /// `momentum` outside `[0, 1)`, `weight_decay` negative or not finite.
    pub fn validate(&self) -> Result<()> {
        if !(self.lr.is_finite() && self.lr > 0.0) {
            return Err(Error::config(
                "lr",
                format!("must be finite and > 0, got {}", self.lr),
            ));
        }
        if !(0.0..1.0).contains(&self.momentum) {
            return Err(Error::config(
                "momentum",
                format!("must be in [0, 1), got {}", self.momentum),
            ));
        }
        check_nonneg("weight_decay", self.weight_decay)
    }
}

/// Stochastic gradient descent with heavy-ball momentum (PyTorch's form,
/// no dampening): `g += wd * w` (weights only), `buf = momentum * buf + g`,
/// `w -= lr * buf`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sgd {
    config: SgdConfig,
    buf: Gradients,
}

impl Sgd {
    /// A fresh optimiser for `net`'s layout.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] when `config.validate()` fails.
    pub fn new(config: SgdConfig, net: &Mlp) -> Result<Sgd> {
        config.validate()?;
        Ok(Sgd {
            config,
            buf: net.zero_grads(),
        })
    }

    /// The settings.
    pub fn config(&self) -> &SgdConfig {
        &self.config
    }
}

fn sgd_block(p: &mut [f32], g: &[f32], buf: &mut [f32], lr: f32, momentum: f32, decay: f32) {
    for ((p, &g), b) in p.iter_mut().zip(g).zip(buf.iter_mut()) {
        let g = g + decay * *p;
        *b = momentum * *b + g;
        *p -= lr * *b;
    }
}

impl Optimizer for Sgd {
    fn step(&mut self, net: &mut Mlp, grads: &Gradients) -> Result<()> {
        check_grads(net, grads, "Sgd::step")?;
        if !self.buf.matches(net) {
            return Err(Error::shape(
                "Sgd::step: optimiser state",
                "the network's layout",
                "another layout",
            ));
        }
        let SgdConfig {
            lr,
            momentum,
            weight_decay,
        } = self.config;
        for ((layer, g), b) in net
            .layers_mut()
            .iter_mut()
            .zip(grads.layers())
            .zip(self.buf.layers_mut())
        {
            sgd_block(
                layer.w.as_slice_mut().expect("contiguous"),
                g.dw.as_slice().expect("contiguous"),
                b.dw.as_slice_mut().expect("contiguous"),
                lr,
                momentum,
                weight_decay,
            );
            sgd_block(
                layer.b.as_slice_mut().expect("contiguous"),
                g.db.as_slice().expect("contiguous"),
                b.db.as_slice_mut().expect("contiguous"),
                lr,
                momentum,
                0.0,
            );
        }
        Ok(())
    }
}
