//! The support-estimator interface: a config fits on expert pairs and
//! returns a fitted model that scores pairs.

use std::path::Path;

use ndarray::{Array1, Array2, ArrayView2};
use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::{
    Autoencoder, AutoencoderConfig, Error, KernelPca, KernelPcaConfig, Result, Rnd, RndConfig,
};

/// Progress of a fit, reported to the caller's callback.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitProgress {
    /// Units of work done (epochs for networks, stages for kernel PCA).
    pub done: usize,
    /// Units of work in all.
    pub total: usize,
    /// The training loss of the last unit, where there is one.
    pub loss: Option<f64>,
}

/// A callback that ignores progress.
pub fn no_progress(_: FitProgress) {}

/// The hyperparameters of a support estimator. [`fit`] is the only way to
/// get a model, so a model is never half-trained.
///
/// [`fit`]: SupportEstimatorConfig::fit
pub trait SupportEstimatorConfig {
    /// The fitted model.
    type Model: SupportModel;

    /// Rejects nonsense values, naming the field.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`].
    fn validate(&self) -> Result<()>;

    /// Fits on expert pairs: `states` is `(n, obs_dim)`, `actions` is
    /// `(n, act_dim)`. Randomness (initialisation, shuffling) comes from
    /// `rng` only, so the same generator state gives the same model.
    /// `progress` is called as work completes.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`], shape and finiteness errors, too few pairs,
    /// or a numerical failure.
    fn fit<R: Rng + ?Sized>(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
        rng: &mut R,
        progress: &mut dyn FnMut(FitProgress),
    ) -> Result<Self::Model>;
}

/// A fitted support estimator: a score `L(s, a) >= 0` that is near 0 on the
/// support of the expert's state-action distribution and grows away from it.
pub trait SupportModel {
    /// Length of a state.
    fn obs_dim(&self) -> usize;

    /// Length of an action.
    fn act_dim(&self) -> usize;

    /// Scores of a batch: `(n, obs_dim)` and `(n, act_dim)` in, `n` scores
    /// out, each `>= 0`.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] or [`Error::NonFinite`] for a bad batch.
    fn score(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<Array1<f64>>;

    /// Scores and their gradients with respect to the actions: `n` scores
    /// and an `(n, act_dim)` matrix whose row `i` is `dL(s_i, a_i)/da_i`.
    ///
    /// # Errors
    /// As [`SupportModel::score`].
    fn score_grad_action(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<(Array1<f64>, Array2<f64>)>;
}

/// The name written in the `format` field of model files.
pub const MODEL_FORMAT: &str = "red-support-model";
/// The version of the model file format this build writes.
pub const MODEL_VERSION: u32 = 1;

/// Any fitted estimator, so that a program can load a model file without
/// knowing its kind.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FittedEstimator {
    /// Random network distillation.
    Rnd(Rnd),
    /// Over-parametrised autoencoder.
    Autoencoder(Autoencoder),
    /// Kernel PCA.
    KernelPca(KernelPca),
}

/// Any estimator config; fitting gives a [`FittedEstimator`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EstimatorConfig {
    /// Random network distillation.
    Rnd(RndConfig),
    /// Over-parametrised autoencoder.
    Autoencoder(AutoencoderConfig),
    /// Kernel PCA.
    KernelPca(KernelPcaConfig),
}

impl EstimatorConfig {
    /// A short name of the kind: `rnd`, `ae` or `kpca`.
    pub fn kind(&self) -> &'static str {
        match self {
            EstimatorConfig::Rnd(_) => "rnd",
            EstimatorConfig::Autoencoder(_) => "ae",
            EstimatorConfig::KernelPca(_) => "kpca",
        }
    }

    /// The config of kind `kind` (`rnd`, `ae` or `kpca`) from the JSON of
    /// its fields (missing fields take their defaults), or its defaults
    /// when `json` is `None`.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] for an unknown kind or JSON that is not a
    /// config of that kind (an unknown field, a wrong type).
    pub fn from_json(kind: &str, json: Option<&str>) -> Result<Self> {
        fn parse<T: serde::de::DeserializeOwned + Default>(json: Option<&str>) -> Result<T> {
            json.map_or_else(
                || Ok(T::default()),
                |text| {
                    serde_json::from_str(text).map_err(|e| Error::InvalidConfig {
                        field: "estimator config".into(),
                        reason: e.to_string(),
                    })
                },
            )
        }
        Ok(match kind {
            "rnd" => EstimatorConfig::Rnd(parse(json)?),
            "ae" => EstimatorConfig::Autoencoder(parse(json)?),
            "kpca" => EstimatorConfig::KernelPca(parse(json)?),
            other => {
                return Err(Error::InvalidConfig {
                    field: "estimator".into(),
                    reason: format!("unknown kind `{other}` (rnd, ae or kpca)"),
                });
            }
        })
    }

    /// Sets the training epochs (RND and AE).
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] for kernel PCA, which has no epochs.
    pub fn set_epochs(&mut self, epochs: usize) -> Result<()> {
        match self {
            EstimatorConfig::Rnd(c) => c.epochs = epochs,
            EstimatorConfig::Autoencoder(c) => c.epochs = epochs,
            EstimatorConfig::KernelPca(_) => {
                return Err(Error::InvalidConfig {
                    field: "epochs".into(),
                    reason: "does not apply to kernel PCA".into(),
                });
            }
        }
        Ok(())
    }
}

impl SupportEstimatorConfig for EstimatorConfig {
    type Model = FittedEstimator;

    fn validate(&self) -> Result<()> {
        match self {
            EstimatorConfig::Rnd(c) => c.validate(),
            EstimatorConfig::Autoencoder(c) => c.validate(),
            EstimatorConfig::KernelPca(c) => c.validate(),
        }
    }

    fn fit<R: Rng + ?Sized>(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
        rng: &mut R,
        progress: &mut dyn FnMut(FitProgress),
    ) -> Result<FittedEstimator> {
        Ok(match self {
            EstimatorConfig::Rnd(c) => FittedEstimator::Rnd(c.fit(states, actions, rng, progress)?),
            EstimatorConfig::Autoencoder(c) => {
                FittedEstimator::Autoencoder(c.fit(states, actions, rng, progress)?)
            }
            EstimatorConfig::KernelPca(c) => {
                FittedEstimator::KernelPca(c.fit(states, actions, rng, progress)?)
            }
        })
    }
}

impl FittedEstimator {
    fn inner(&self) -> &dyn SupportModel {
        match self {
            FittedEstimator::Rnd(m) => m,
            FittedEstimator::Autoencoder(m) => m,
            FittedEstimator::KernelPca(m) => m,
        }
    }

    /// A short name of the kind: `rnd`, `ae` or `kpca`.
    pub fn kind(&self) -> &'static str {
        match self {
            FittedEstimator::Rnd(_) => "rnd",
            FittedEstimator::Autoencoder(_) => "ae",
            FittedEstimator::KernelPca(_) => "kpca",
        }
    }

    /// What the fit ended with: RND's and AE's final training losses,
    /// kernel PCA's bandwidth and components.
    pub fn describe(&self) -> String {
        match self {
            FittedEstimator::Rnd(m) => format!("final training loss {:?}", m.final_losses()),
            FittedEstimator::Autoencoder(m) => {
                format!("final training loss {:.4e}", m.final_loss())
            }
            FittedEstimator::KernelPca(m) => format!(
                "bandwidth {:.4}, {} components ({:.4} of the trace)",
                m.bandwidth(),
                m.components(),
                m.explained_share()
            ),
        }
    }

    /// Writes the model as JSON to `path` (with a format name and version).
    ///
    /// # Errors
    /// [`Error::Io`] if the file cannot be written.
    pub fn save(&self, path: &Path) -> Result<()> {
        let file = ModelFile {
            format: MODEL_FORMAT.into(),
            version: MODEL_VERSION,
            model: self.clone(),
        };
        let text = serde_json::to_string(&file).map_err(|e| Error::ModelFile {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        std::fs::write(path, text).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })
    }

    /// Reads a model written by [`FittedEstimator::save`].
    ///
    /// # Errors
    /// [`Error::Io`] if it cannot be read, [`Error::ModelFile`] if it is not
    /// a model file of this version.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let bad = |reason: String| Error::ModelFile {
            path: path.to_path_buf(),
            reason,
        };
        let file: ModelFile = serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
        if file.format != MODEL_FORMAT {
            return Err(bad(format!(
                "format is `{}`, expected `{MODEL_FORMAT}`",
                file.format
            )));
        }
        if file.version != MODEL_VERSION {
            return Err(bad(format!(
                "format version {} is not supported (this build reads {MODEL_VERSION})",
                file.version
            )));
        }
        Ok(file.model)
    }
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ModelFile {
    format: String,
    version: u32,
    model: FittedEstimator,
}

impl SupportModel for FittedEstimator {
    fn obs_dim(&self) -> usize {
        self.inner().obs_dim()
    }
    fn act_dim(&self) -> usize {
        self.inner().act_dim()
    }
    fn score(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<Array1<f64>> {
        self.inner().score(states, actions)
    }
    fn score_grad_action(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<(Array1<f64>, Array2<f64>)> {
        self.inner().score_grad_action(states, actions)
    }
}

impl<M: SupportModel + ?Sized> SupportModel for Box<M> {
    fn obs_dim(&self) -> usize {
        (**self).obs_dim()
    }
    fn act_dim(&self) -> usize {
        (**self).act_dim()
    }
    fn score(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<Array1<f64>> {
        (**self).score(states, actions)
    }
    fn score_grad_action(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<(Array1<f64>, Array2<f64>)> {
        (**self).score_grad_action(states, actions)
    }
}
