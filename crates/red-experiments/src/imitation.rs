//! The imitation layer shared by the experiments: one [`Method`]
//! vocabulary, one imitation reward ([`ImitationReward`]) and one function
//! that fits it from expert pairs ([`fit_reward`]). The support-estimation
//! part (fit, then `σ1` from in-sample or held-out expert scores) is
//! red-support's [`red_support::fit_red_reward`].

use ndarray::{Array1, Array2, ArrayView2};
use rand_chacha::ChaCha8Rng;
use red_core::{DifferentiableReward, RewardModel};
use red_rl::gail::{Gail, GailConfig};
use red_rl::gmmil::{Gmmil, GmmilConfig};
use red_support::{
    AutoencoderConfig, ExpertScores, FittedEstimator, KernelPcaConfig, RedReward, RndConfig,
    Sigma1, fit_red_reward,
};
use serde::{Deserialize, Serialize};

use crate::Result;

/// How a policy is trained: the one method vocabulary of every
/// experiment (the toy and the driving experiment use the imitation
/// methods; MuJoCo also trains experts and behaviour cloning alone).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// TRPO on the environment's true reward (an expert for demonstrations).
    Expert,
    /// RED: TRPO on `exp(-sigma1 L)` with `L` the RND score (paper Eq. 7;
    /// the driving experiment can ask for exact kernel PCA instead).
    Red,
    /// The autoencoder baseline: the same reward with an autoencoder's
    /// reconstruction error as `L`.
    Ae,
    /// GAIL's discriminator reward, adapted on every batch.
    Gail,
    /// GMMIL's MMD witness reward, adapted on every batch.
    Gmmil,
    /// Behaviour cloning alone (no reinforcement learning).
    Bc,
}

impl Method {
    /// The imitation methods of Table 1, in its order.
    pub const TABLE: [Method; 5] = [
        Method::Red,
        Method::Ae,
        Method::Gail,
        Method::Gmmil,
        Method::Bc,
    ];

    /// The lower-case name used in file names and tables.
    pub fn name(self) -> &'static str {
        match self {
            Method::Expert => "expert",
            Method::Red => "red",
            Method::Ae => "ae",
            Method::Gail => "gail",
            Method::Gmmil => "gmmil",
            Method::Bc => "bc",
        }
    }

    /// The name in tables (`RED`, `GAIL`, ...).
    pub fn label(self) -> &'static str {
        match self {
            Method::Expert => "Expert (TRPO, true reward)",
            Method::Red => "RED",
            Method::Ae => "AE",
            Method::Gail => "GAIL",
            Method::Gmmil => "GMMIL",
            Method::Bc => "BC",
        }
    }

    /// Whether the method learns from a reward fitted on demonstrations
    /// (RED, AE, GAIL, GMMIL).
    pub fn imitates_by_reward(self) -> bool {
        !matches!(self, Method::Expert | Method::Bc)
    }

    /// Whether the method learns from demonstrations.
    pub fn needs_demo(self) -> bool {
        self != Method::Expert
    }
}

impl std::str::FromStr for Method {
    type Err = String;
    /// A method by its [`Method::name`] (`red`, `ae`, `gail`, `gmmil`, `bc`,
    /// `expert`), case-insensitive.
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let s = s.trim().to_ascii_lowercase();
        [Method::Expert]
            .into_iter()
            .chain(Method::TABLE)
            .find(|m| m.name() == s)
            .ok_or_else(|| format!("unknown method `{s}` (red, ae, gail, gmmil, bc or expert)"))
    }
}

/// The reward an imitation method learns from, in place of the true one.
#[derive(Clone, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ImitationReward {
    /// RED or AE: `exp(-σ1 L)`, fixed after fitting.
    Support(Box<RedReward<FittedEstimator>>),
    /// GAIL's discriminator, adapted on the policy's pairs.
    Gail(Box<Gail>),
    /// GMMIL's witness function, adapted on the policy's pairs.
    Gmmil(Box<Gmmil>),
}

impl ImitationReward {
    /// RED's or AE's reward (`None` for the adaptive ones).
    pub fn support(&self) -> Option<&RedReward<FittedEstimator>> {
        match self {
            ImitationReward::Support(r) => Some(r),
            _ => None,
        }
    }

    fn inner(&self) -> &dyn RewardModel {
        match self {
            ImitationReward::Support(r) => r.as_ref(),
            ImitationReward::Gail(g) => g.as_ref(),
            ImitationReward::Gmmil(g) => g.as_ref(),
        }
    }

    fn inner_differentiable(&self) -> &dyn DifferentiableReward {
        match self {
            ImitationReward::Support(r) => r.as_ref(),
            ImitationReward::Gail(g) => g.as_ref(),
            ImitationReward::Gmmil(g) => g.as_ref(),
        }
    }
}

impl RewardModel for ImitationReward {
    fn rewards(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> red_core::Result<Array1<f64>> {
        self.inner().rewards(states, actions)
    }

    fn update(
        &mut self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> red_core::Result<()> {
        match self {
            ImitationReward::Support(r) => r.update(states, actions),
            ImitationReward::Gail(g) => g.update(states, actions),
            ImitationReward::Gmmil(g) => g.update(states, actions),
        }
    }

    fn is_adaptive(&self) -> bool {
        self.inner().is_adaptive()
    }
}

impl DifferentiableReward for ImitationReward {
    fn reward_and_grad(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> red_core::Result<(Array1<f64>, Array2<f64>)> {
        self.inner_differentiable().reward_and_grad(states, actions)
    }

    fn is_adaptive(&self) -> bool {
        self.inner_differentiable().is_adaptive()
    }
}

/// The settings [`fit_reward`] takes from an experiment's config.
#[derive(Debug, Clone, Copy)]
pub struct RewardSettings<'a> {
    /// RED's estimator.
    pub rnd: &'a RndConfig,
    /// When set, RED fits exact kernel PCA with these settings instead of
    /// `rnd`.
    pub kernel_pca: Option<&'a KernelPcaConfig>,
    /// AE's estimator.
    pub autoencoder: &'a AutoencoderConfig,
    /// How RED's and AE's `σ1` is set.
    pub sigma1: Sigma1,
    /// Which expert scores calibrate a calibrated `σ1`.
    pub scores: ExpertScores,
    /// GAIL's discriminator.
    pub gail: &'a GailConfig,
    /// GMMIL's kernels.
    pub gmmil: &'a GmmilConfig,
}

/// Fits `method`'s reward on the expert pairs (`(n, obs_dim)`,
/// `(n, act_dim)`): RED and AE fit their estimator with `rng` and set `σ1`
/// ([`fit_red_reward`]); GAIL's discriminator is initialised from
/// `gail_seed`; GMMIL needs no randomness. `None` for the methods without
/// a learned reward (expert, BC).
///
/// # Errors
/// The estimators' and the baselines' errors (bad configs, too few pairs, a
/// calibration quantile of 0).
pub fn fit_reward(
    method: Method,
    settings: &RewardSettings<'_>,
    states: ArrayView2<'_, f64>,
    actions: ArrayView2<'_, f64>,
    rng: &mut ChaCha8Rng,
    gail_seed: u64,
) -> Result<Option<ImitationReward>> {
    let support =
        |model: RedReward<FittedEstimator>| Some(ImitationReward::Support(Box::new(model)));
    let (sigma1, scores) = (settings.sigma1, settings.scores);
    Ok(match method {
        Method::Expert | Method::Bc => None,
        Method::Red => match settings.kernel_pca {
            Some(k) => {
                let r = fit_red_reward(k, sigma1, scores, states, actions, rng)?;
                support(r.map_model(FittedEstimator::KernelPca))
            }
            None => {
                let r = fit_red_reward(settings.rnd, sigma1, scores, states, actions, rng)?;
                support(r.map_model(FittedEstimator::Rnd))
            }
        },
        Method::Ae => {
            let r = fit_red_reward(settings.autoencoder, sigma1, scores, states, actions, rng)?;
            support(r.map_model(FittedEstimator::Autoencoder))
        }
        Method::Gail => Some(ImitationReward::Gail(Box::new(Gail::new(
            settings.gail.clone(),
            states,
            actions,
            gail_seed,
        )?))),
        Method::Gmmil => Some(ImitationReward::Gmmil(Box::new(Gmmil::new(
            settings.gmmil.clone(),
            states,
            actions,
        )?))),
    })
}
