//! Any estimator behind one type: [`EstimatorConfig`] fits any of RND,
//! the autoencoder and kernel PCA and gives a [`FittedEstimator`], which a
//! program can save and load without knowing its kind.

use std::path::Path;

use ndarray::{Array1, Array2, ArrayView2};
use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::estimator::{FitProgress, SupportEstimatorConfig, SupportModel};
use crate::{
    Autoencoder, AutoencoderConfig, Error, KernelPca, KernelPcaConfig, Result, Rnd, RndConfig,
};

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
