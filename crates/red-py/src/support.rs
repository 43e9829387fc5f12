//! `red_support` on numpy arrays: fitting RND, the autoencoder and kernel
//! PCA, RED's reward with `σ1` calibration, the terminal heuristic, and the
//! model files of `red-cli support fit`.

use std::path::PathBuf;

use ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use red_core::{Seeder, Stream};
use red_support::{
    AutoencoderConfig, EstimatorConfig, FittedEstimator, KernelPcaConfig, RedReward,
    RedRewardConfig, RndConfig, Sigma1, SupportEstimatorConfig, SupportModel, TerminalHeuristic,
    TerminalHeuristicConfig, calibrate_sigma1, held_out_scores, no_progress,
};

use crate::arrays::{matrix, same_rows, support_err};

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySupportModel>()?;
    m.add_class::<PyRedReward>()?;
    m.add_class::<PyTerminalHeuristic>()?;
    m.add_function(wrap_pyfunction!(default_sigma1_rule, m)?)?;
    Ok(())
}

/// The estimator config of `kind` (`rnd`, `ae` or `kpca`, the names of
/// `red-cli support fit --estimator`), its fields from `config` (a dict;
/// missing fields take the Rust defaults) and `epochs` overriding them.
fn estimator_config(
    py: Python<'_>,
    kind: &str,
    config: Option<&Bound<'_, PyAny>>,
    epochs: Option<usize>,
) -> PyResult<EstimatorConfig> {
    let text = match config {
        None => "{}".to_string(),
        Some(c) => py
            .import("json")?
            .call_method1("dumps", (c,))?
            .extract::<String>()?,
    };
    let parse_err =
        |e: serde_json::Error| PyValueError::new_err(format!("config for estimator `{kind}`: {e}"));
    let mut cfg = match kind {
        "rnd" => EstimatorConfig::Rnd(serde_json::from_str::<RndConfig>(&text).map_err(parse_err)?),
        "ae" => EstimatorConfig::Autoencoder(
            serde_json::from_str::<AutoencoderConfig>(&text).map_err(parse_err)?,
        ),
        "kpca" => EstimatorConfig::KernelPca(
            serde_json::from_str::<KernelPcaConfig>(&text).map_err(parse_err)?,
        ),
        other => {
            return Err(PyValueError::new_err(format!(
                "unknown estimator `{other}`: use \"rnd\", \"ae\" or \"kpca\""
            )));
        }
    };
    if let Some(e) = epochs {
        match &mut cfg {
            EstimatorConfig::Rnd(c) => c.epochs = e,
            EstimatorConfig::Autoencoder(c) => c.epochs = e,
            EstimatorConfig::KernelPca(_) => {
                return Err(PyValueError::new_err("epochs does not apply to kernel PCA"));
            }
        }
    }
    cfg.validate().map_err(support_err)?;
    Ok(cfg)
}

fn pairs(
    model_dims: Option<(usize, usize)>,
    obs: &Bound<'_, PyAny>,
    act: &Bound<'_, PyAny>,
) -> PyResult<(Array2<f64>, Array2<f64>)> {
    let s = matrix(obs, "obs", model_dims.map(|d| d.0))?;
    let a = matrix(act, "act", model_dims.map(|d| d.1))?;
    same_rows(&s, &a)?;
    Ok((s, a))
}

/// The calibration rule the Rust crates use by default: `(quantile,
/// reward)` of `RedRewardConfig::default()`.
#[pyfunction]
fn default_sigma1_rule() -> (f64, f64) {
    match RedRewardConfig::default().sigma1 {
        Sigma1::Calibrated { quantile, reward } => (quantile, reward),
        // Not the case today; a fixed default has no quantile.
        Sigma1::Fixed(s) => (f64::NAN, s),
    }
}

/// A fitted support estimator (RND, autoencoder or kernel PCA): a score
/// `L(s, a) >= 0`, near 0 on the support of the expert pairs.
#[pyclass(name = "SupportModel", module = "red._red", frozen)]
pub(crate) struct PySupportModel {
    model: FittedEstimator,
}

#[pymethods]
impl PySupportModel {
    /// Fits `kind` ("rnd", "ae" or "kpca") on expert pairs `obs` (n, obs_dim)
    /// and `act` (n, act_dim). The randomness comes from `seed` exactly as in
    /// `red-cli support fit --seed`, so the same seed gives the same model.
    /// `config` is a dict of the Rust config's fields (missing ones take
    /// their defaults); `epochs` overrides the networks' epochs.
    #[staticmethod]
    #[pyo3(signature = (kind, obs, act, *, seed = 0, config = None, epochs = None))]
    fn fit(
        py: Python<'_>,
        kind: &str,
        obs: &Bound<'_, PyAny>,
        act: &Bound<'_, PyAny>,
        seed: u64,
        config: Option<&Bound<'_, PyAny>>,
        epochs: Option<usize>,
    ) -> PyResult<Self> {
        let cfg = estimator_config(py, kind, config, epochs)?;
        let (s, a) = pairs(None, obs, act)?;
        let model = py
            .detach(|| {
                let mut rng = Seeder::new(seed).rng(Stream::Estimator);
                cfg.fit(s.view(), a.view(), &mut rng, &mut no_progress)
            })
            .map_err(support_err)?;
        Ok(Self { model })
    }

    /// Reads a model file written by `red-cli support fit` or `save`.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let model = py
            .detach(|| FittedEstimator::load(&path))
            .map_err(support_err)?;
        Ok(Self { model })
    }

    /// Writes the model in the Rust crates' model file format (JSON).
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| self.model.save(&path)).map_err(support_err)
    }

    /// Scores of a batch: `obs` (n, obs_dim), `act` (n, act_dim) -> (n,)
    /// float64, each >= 0.
    fn score<'py>(
        &self,
        py: Python<'py>,
        obs: &Bound<'py, PyAny>,
        act: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (s, a) = pairs(Some(dims(&self.model)), obs, act)?;
        let out = py
            .detach(|| self.model.score(s.view(), a.view()))
            .map_err(support_err)?;
        Ok(out.into_pyarray(py))
    }

    /// "rnd", "ae" or "kpca".
    #[getter]
    fn kind(&self) -> &'static str {
        self.model.kind()
    }

    /// Length of a state.
    #[getter]
    fn obs_dim(&self) -> usize {
        self.model.obs_dim()
    }

    /// Length of an action.
    #[getter]
    fn act_dim(&self) -> usize {
        self.model.act_dim()
    }

    fn __repr__(&self) -> String {
        format!(
            "SupportModel(kind={:?}, obs_dim={}, act_dim={})",
            self.model.kind(),
            self.model.obs_dim(),
            self.model.act_dim()
        )
    }
}

fn dims(m: &FittedEstimator) -> (usize, usize) {
    (m.obs_dim(), m.act_dim())
}

/// Rewards (n,) and their action gradients (n, act_dim).
type RewardGrad<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray2<f64>>);

/// RED's reward `r(s, a) = exp(-sigma1 * L(s, a))` over a support model.
#[pyclass(name = "RedReward", module = "red._red", frozen)]
pub(crate) struct PyRedReward {
    reward: RedReward<FittedEstimator>,
}

#[pymethods]
impl PyRedReward {
    /// The reward over `model`. With `sigma1` given it is used as is;
    /// otherwise it is calibrated on the expert pairs `obs`, `act` so that
    /// their `quantile` gets reward `reward` (`RedReward::new`; defaults from
    /// `RedRewardConfig::default()`, 0.9 and 0.9). Calibrating on the pairs
    /// the model was fitted on gives a larger sigma1 than held-out pairs:
    /// `RedReward.fit` calibrates on held-out scores.
    #[new]
    #[pyo3(signature = (model, obs = None, act = None, *, sigma1 = None, quantile = None, reward = None))]
    fn new(
        py: Python<'_>,
        model: &PySupportModel,
        obs: Option<&Bound<'_, PyAny>>,
        act: Option<&Bound<'_, PyAny>>,
        sigma1: Option<f64>,
        quantile: Option<f64>,
        reward: Option<f64>,
    ) -> PyResult<Self> {
        let m = model.model.clone();
        if let Some(s1) = sigma1 {
            if quantile.is_some() || reward.is_some() {
                return Err(PyValueError::new_err(
                    "give either sigma1 or the calibration (quantile, reward), not both",
                ));
            }
            let reward = RedReward::with_sigma1(m, s1).map_err(support_err)?;
            return Ok(Self { reward });
        }
        let (Some(obs), Some(act)) = (obs, act) else {
            return Err(PyValueError::new_err(
                "without sigma1, give the expert pairs obs and act to calibrate it on",
            ));
        };
        let (s, a) = pairs(Some(dims(&m)), obs, act)?;
        let (dq, dr) = default_sigma1_rule();
        let config = RedRewardConfig {
            sigma1: Sigma1::Calibrated {
                quantile: quantile.unwrap_or(dq),
                reward: reward.unwrap_or(dr),
            },
        };
        let reward = py
            .detach(|| RedReward::new(m, &config, s.view(), a.view()))
            .map_err(support_err)?;
        Ok(Self { reward })
    }

    /// Fits `kind` ("rnd", "ae" or "kpca") on the expert pairs with `seed`
    /// (the model is the one `SupportModel.fit` and `red-cli support fit`
    /// give for that seed) and calibrates sigma1 as the driving experiment
    /// does: `folds`-fold held-out expert scores (`held_out_scores`, the
    /// same generator continuing after the fit), whose `quantile` gets
    /// reward `reward` (`calibrate_sigma1`). `folds=None` calibrates on the
    /// training pairs instead; `sigma1` skips calibration.
    #[staticmethod]
    #[pyo3(signature = (kind, obs, act, *, seed = 0, folds = Some(5), quantile = None, reward = None, sigma1 = None, config = None, epochs = None))]
    fn fit(
        py: Python<'_>,
        kind: &str,
        obs: &Bound<'_, PyAny>,
        act: &Bound<'_, PyAny>,
        seed: u64,
        folds: Option<usize>,
        quantile: Option<f64>,
        reward: Option<f64>,
        sigma1: Option<f64>,
        config: Option<&Bound<'_, PyAny>>,
        epochs: Option<usize>,
    ) -> PyResult<Self> {
        let cfg = estimator_config(py, kind, config, epochs)?;
        let (s, a) = pairs(None, obs, act)?;
        let (dq, dr) = default_sigma1_rule();
        let (q, r) = (quantile.unwrap_or(dq), reward.unwrap_or(dr));
        let reward = py
            .detach(|| {
                let mut rng = Seeder::new(seed).rng(Stream::Estimator);
                let model = cfg.fit(s.view(), a.view(), &mut rng, &mut no_progress)?;
                match (sigma1, folds) {
                    (Some(s1), _) => RedReward::with_sigma1(model, s1),
                    (None, Some(k)) => {
                        let held = held_out_scores(&cfg, s.view(), a.view(), k, &mut rng)?;
                        let s1 = calibrate_sigma1(&held.to_vec(), q, r)?;
                        RedReward::with_sigma1(model, s1)
                    }
                    (None, None) => RedReward::new(
                        model,
                        &RedRewardConfig {
                            sigma1: Sigma1::Calibrated {
                                quantile: q,
                                reward: r,
                            },
                        },
                        s.view(),
                        a.view(),
                    ),
                }
            })
            .map_err(support_err)?;
        Ok(Self { reward })
    }

    /// Rewards of a batch: `obs` (n, obs_dim), `act` (n, act_dim) -> (n,)
    /// float64 in (0, 1].
    fn reward<'py>(
        &self,
        py: Python<'py>,
        obs: &Bound<'py, PyAny>,
        act: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (s, a) = pairs(Some(dims(self.reward.model())), obs, act)?;
        let out = py
            .detach(|| self.reward.reward(s.view(), a.view()))
            .map_err(support_err)?;
        Ok(out.into_pyarray(py))
    }

    /// The support model's scores `L` of a batch, (n,) float64.
    fn score<'py>(
        &self,
        py: Python<'py>,
        obs: &Bound<'py, PyAny>,
        act: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (s, a) = pairs(Some(dims(self.reward.model())), obs, act)?;
        let out = py
            .detach(|| self.reward.model().score(s.view(), a.view()))
            .map_err(support_err)?;
        Ok(out.into_pyarray(py))
    }

    /// Rewards (n,) and their gradients with respect to the actions
    /// (n, act_dim).
    fn reward_grad_action<'py>(
        &self,
        py: Python<'py>,
        obs: &Bound<'py, PyAny>,
        act: &Bound<'py, PyAny>,
    ) -> PyResult<RewardGrad<'py>> {
        let (s, a) = pairs(Some(dims(self.reward.model())), obs, act)?;
        let (r, g) = py
            .detach(|| self.reward.reward_grad_action(s.view(), a.view()))
            .map_err(support_err)?;
        Ok((r.into_pyarray(py), g.into_pyarray(py)))
    }

    /// The terminal reward heuristic (paper Eq. 8) with the mean reward of
    /// the expert pairs `obs`, `act`; `sigma2`, `sigma3` default to
    /// `TerminalHeuristicConfig::default()` (10 and 0.5).
    #[pyo3(signature = (obs, act, *, sigma2 = None, sigma3 = None))]
    fn terminal_heuristic(
        &self,
        py: Python<'_>,
        obs: &Bound<'_, PyAny>,
        act: &Bound<'_, PyAny>,
        sigma2: Option<f64>,
        sigma3: Option<f64>,
    ) -> PyResult<PyTerminalHeuristic> {
        let (s, a) = pairs(Some(dims(self.reward.model())), obs, act)?;
        let config = heuristic_config(sigma2, sigma3);
        let h = py
            .detach(|| TerminalHeuristic::new(&config, &self.reward, s.view(), a.view()))
            .map_err(support_err)?;
        Ok(PyTerminalHeuristic { h })
    }

    /// sigma1.
    #[getter]
    fn sigma1(&self) -> f64 {
        self.reward.sigma1()
    }

    /// The support model (a copy).
    #[getter]
    fn model(&self) -> PySupportModel {
        PySupportModel {
            model: self.reward.model().clone(),
        }
    }

    /// Length of a state.
    #[getter]
    fn obs_dim(&self) -> usize {
        self.reward.model().obs_dim()
    }

    /// Length of an action.
    #[getter]
    fn act_dim(&self) -> usize {
        self.reward.model().act_dim()
    }

    fn __repr__(&self) -> String {
        format!(
            "RedReward(kind={:?}, obs_dim={}, act_dim={}, sigma1={})",
            self.reward.model().kind(),
            self.reward.model().obs_dim(),
            self.reward.model().act_dim(),
            self.reward.sigma1()
        )
    }
}

fn heuristic_config(sigma2: Option<f64>, sigma3: Option<f64>) -> TerminalHeuristicConfig {
    let d = TerminalHeuristicConfig::default();
    TerminalHeuristicConfig {
        sigma2: sigma2.unwrap_or(d.sigma2),
        sigma3: sigma3.unwrap_or(d.sigma3),
    }
}

/// The terminal reward heuristic: at the end of an episode whose last pair
/// has reward `r_T`, add `-sigma2 * r_mean` if `r_T < sigma3 * r_mean`.
#[pyclass(name = "TerminalHeuristic", module = "red._red", frozen)]
pub(crate) struct PyTerminalHeuristic {
    h: TerminalHeuristic,
}

#[pymethods]
impl PyTerminalHeuristic {
    /// The heuristic with a known mean expert reward.
    #[new]
    #[pyo3(signature = (expert_mean_reward, *, sigma2 = None, sigma3 = None))]
    fn new(expert_mean_reward: f64, sigma2: Option<f64>, sigma3: Option<f64>) -> PyResult<Self> {
        let config = heuristic_config(sigma2, sigma3);
        config.validate().map_err(support_err)?;
        Ok(Self {
            h: TerminalHeuristic::with_expert_mean(&config, expert_mean_reward),
        })
    }

    /// The reward to add at the end of an episode whose last pair has reward
    /// `final_reward` (0 or `-sigma2 * r_mean`).
    fn penalty(&self, final_reward: f64) -> f64 {
        self.h.penalty(final_reward)
    }

    /// The mean reward of the expert pairs.
    #[getter]
    fn expert_mean_reward(&self) -> f64 {
        self.h.expert_mean_reward()
    }

    fn __repr__(&self) -> String {
        format!(
            "TerminalHeuristic(expert_mean_reward={})",
            self.h.expert_mean_reward()
        )
    }
}
