//! RED's reward `r(s, a) = exp(-σ1 L(s, a))` (paper Eq. 7) over a fitted
//! support estimator's score `L`.

use ndarray::{Array1, Array2, ArrayView2, Axis};
use serde::{Deserialize, Serialize};

use crate::cross_val::held_out_scores;
use crate::estimator::{SupportEstimatorConfig, SupportModel, no_progress};
use crate::{Error, Result, stats};

/// How `σ1` is set.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Sigma1 {
    /// A given `σ1 > 0` (the release sets it by hand per task, e.g.
    /// 250000 for Hopper with RND).
    Fixed(f64),
    /// Calibrated on expert scores so that expert rewards are "mostly close
    /// to 1" (paper Sec. 3.2): the `quantile` of the expert scores gets
    /// reward `reward`, i.e. `σ1 = -ln(reward) / q`. So a share `quantile`
    /// of the expert pairs get a reward of at least `reward`.
    Calibrated {
        /// Which quantile of the expert scores, in `(0, 1]`.
        quantile: f64,
        /// The reward it gets, in `(0, 1)`.
        reward: f64,
    },
}

impl Sigma1 {
    /// `σ1` for a model whose expert pairs score `scores`: the fixed value,
    /// or the calibrated one ([`calibrate_sigma1`]).
    ///
    /// # Errors
    /// As [`calibrate_sigma1`].
    pub fn resolve(&self, scores: &[f64]) -> Result<f64> {
        match *self {
            Sigma1::Fixed(s) => Ok(s),
            Sigma1::Calibrated { quantile, reward } => calibrate_sigma1(scores, quantile, reward),
        }
    }

    /// How `σ1` was set, for a report: `given`, or the calibration rule.
    pub fn describe(&self) -> String {
        match *self {
            Sigma1::Fixed(_) => "given".to_string(),
            Sigma1::Calibrated { quantile, reward } => {
                format!("calibrated: the {quantile} quantile of the scores gets reward {reward}")
            }
        }
    }
}

/// Hyperparameters of [`RedReward`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RedRewardConfig {
    /// How `σ1` is set.
    pub sigma1: Sigma1,
}

impl Default for RedRewardConfig {
    /// `σ1` calibrated so that the 90% quantile of the expert scores gets
    /// reward 0.9: our reading of "mostly close to 1" (the paper gives no
    /// rule; the release's hand-set values are per task and per estimator).
    fn default() -> Self {
        Self {
            sigma1: Sigma1::Calibrated {
                quantile: 0.9,
                reward: 0.9,
            },
        }
    }
}

impl RedRewardConfig {
    /// Rejects nonsense values, naming the field.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`].
    pub fn validate(&self) -> Result<()> {
        let bad = |reason: String| {
            Err(Error::InvalidConfig {
                field: "sigma1".into(),
                reason,
            })
        };
        match self.sigma1 {
            Sigma1::Fixed(s) if !(s.is_finite() && s > 0.0) => {
                bad(format!("a fixed sigma1 must be finite and > 0, got {s}"))
            }
            Sigma1::Calibrated { quantile, .. } if !(quantile > 0.0 && quantile <= 1.0) => {
                bad(format!("the quantile must be in (0, 1], got {quantile}"))
            }
            Sigma1::Calibrated { reward, .. } if !(reward > 0.0 && reward < 1.0) => {
                bad(format!("the reward must be in (0, 1), got {reward}"))
            }
            _ => Ok(()),
        }
    }
}

/// RED's reward over a fitted support model `M`.
///
/// Rewards are in `(0, 1]` up to floating point: a score so large that
/// `exp` underflows gives 0.
///
/// A reward read from a file is checked as [`RedReward::with_sigma1`]
/// checks a new one: `σ1` finite and above 0.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, try_from = "RedRewardFile<M>")]
pub struct RedReward<M> {
    model: M,
    sigma1: f64,
    /// Whether every pair is scored with its action set to 0 (see
    /// [`RedReward::on_states_only`]).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    states_only: bool,
}

/// [`RedReward`] as a file holds it, before its check.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RedRewardFile<M> {
    model: M,
    sigma1: f64,
    #[serde(default)]
    states_only: bool,
}

impl<M> TryFrom<RedRewardFile<M>> for RedReward<M> {
    type Error = Error;

    fn try_from(f: RedRewardFile<M>) -> Result<Self> {
        RedRewardConfig {
            sigma1: Sigma1::Fixed(f.sigma1),
        }
        .validate()?;
        Ok(Self {
            model: f.model,
            sigma1: f.sigma1,
            states_only: f.states_only,
        })
    }
}

impl<M: SupportModel> RedReward<M> {
    /// The reward with a given `σ1`.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] if `σ1` is not finite and positive.
    pub fn with_sigma1(model: M, sigma1: f64) -> Result<Self> {
        RedRewardConfig {
            sigma1: Sigma1::Fixed(sigma1),
        }
        .validate()?;
        Ok(Self {
            model,
            sigma1,
            states_only: false,
        })
    }

    /// The same reward read on the state only (our addition): every pair
    /// is scored with its action replaced by zeros, so `r(s, a) = r(s, 0)`
    /// and `dr/da = 0`. For a model fitted on the expert's states with
    /// zero actions, this is RED on states: it rewards being where the
    /// expert was, whatever action led there.
    pub fn on_states_only(mut self, states_only: bool) -> Self {
        self.states_only = states_only;
        self
    }

    /// Whether the reward reads the state only ([`RedReward::on_states_only`]).
    pub fn states_only(&self) -> bool {
        self.states_only
    }

    /// The reward with `σ1` set by `config`; a calibrated `σ1` is computed
    /// from the model's scores of the expert pairs given (`(n, obs_dim)`,
    /// `(n, act_dim)`). Scoring the very pairs the model was fitted on
    /// gives a larger `σ1` than held-out expert pairs would (they score a
    /// little higher); pass held-out pairs when there are some.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`]; shape errors; [`Error::Numerical`] if the
    /// calibration quantile of the expert scores is 0 (every expert pair
    /// scores exactly 0, e.g. kernel PCA with all components on its own
    /// training set): then give `σ1`.
    pub fn new(
        model: M,
        config: &RedRewardConfig,
        expert_states: ArrayView2<'_, f64>,
        expert_actions: ArrayView2<'_, f64>,
    ) -> Result<Self> {
        config.validate()?;
        let sigma1 = match config.sigma1 {
            Sigma1::Fixed(s) => s,
            Sigma1::Calibrated { quantile, reward } => {
                let scores = model.score(expert_states, expert_actions)?;
                calibrate_sigma1(
                    scores.as_slice().unwrap_or(&scores.to_vec()),
                    quantile,
                    reward,
                )?
            }
        };
        Ok(Self {
            model,
            sigma1,
            states_only: false,
        })
    }

    /// `σ1`.
    pub fn sigma1(&self) -> f64 {
        self.sigma1
    }

    /// The support model.
    pub fn model(&self) -> &M {
        &self.model
    }

    /// Unwraps the support model.
    pub fn into_model(self) -> M {
        self.model
    }

    /// The same reward (`σ1`, [`RedReward::states_only`]) over the model
    /// `f` makes of this one's, e.g. a concrete estimator wrapped into
    /// [`crate::FittedEstimator`].
    pub fn map_model<N: SupportModel>(self, f: impl FnOnce(M) -> N) -> RedReward<N> {
        RedReward {
            model: f(self.model),
            sigma1: self.sigma1,
            states_only: self.states_only,
        }
    }

    /// This reward's `σ1` and [`RedReward::states_only`] around another
    /// model.
    pub fn with_model<N: SupportModel>(&self, model: N) -> RedReward<N> {
        RedReward {
            model,
            sigma1: self.sigma1,
            states_only: self.states_only,
        }
    }

    /// Rewards of a batch, `n` values in `(0, 1]`.
    ///
    /// # Errors
    /// As [`SupportModel::score`].
    pub fn reward(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<Array1<f64>> {
        let zeros;
        let actions = if self.states_only {
            zeros = Array2::zeros(actions.raw_dim());
            zeros.view()
        } else {
            actions
        };
        let mut r = self.model.score(states, actions)?;
        r.mapv_inplace(|l| (-self.sigma1 * l).exp());
        Ok(r)
    }

    /// Rewards and their gradients with respect to the actions:
    /// `dr/da = -σ1 r dL/da`, `(n, act_dim)` (for SVG(1)).
    ///
    /// # Errors
    /// As [`SupportModel::score_grad_action`].
    pub fn reward_grad_action(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<(Array1<f64>, Array2<f64>)> {
        if self.states_only {
            let r = self.reward(states, actions)?;
            return Ok((r, Array2::zeros(actions.raw_dim())));
        }
        let (scores, mut g) = self.model.score_grad_action(states, actions)?;
        let r = scores.mapv(|l| (-self.sigma1 * l).exp());
        let factor = r.mapv(|v| -self.sigma1 * v);
        g *= &factor.view().insert_axis(Axis(1));
        Ok((r, g))
    }
}

/// `σ1 = -ln(reward) / q` with `q` the `quantile` of `scores`.
///
/// # Errors
/// [`Error::Numerical`] if `scores` is empty or the quantile is not
/// positive.
pub fn calibrate_sigma1(scores: &[f64], quantile: f64, reward: f64) -> Result<f64> {
    let q = stats::quantile(scores, quantile);
    if !(q > 0.0 && q.is_finite()) {
        return Err(Error::Numerical {
            what: "sigma1 calibration".into(),
            reason: format!(
                "the {quantile} quantile of {} expert scores is {q}; give a fixed sigma1",
                scores.len()
            ),
        });
    }
    Ok(-reward.ln() / q)
}

impl<M: SupportModel> red_core::RewardModel for RedReward<M> {
    fn rewards(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> red_core::Result<Array1<f64>> {
        Ok(self.reward(states, actions)?)
    }
}

impl<M: SupportModel> red_core::DifferentiableReward for RedReward<M> {
    fn reward_and_grad(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> red_core::Result<(Array1<f64>, Array2<f64>)> {
        Ok(self.reward_grad_action(states, actions)?)
    }
}

/// Which expert scores calibrate a calibrated `σ1` (see [`fit_red_reward`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExpertScores {
    /// The fitted model's scores of the pairs it was fitted on (the
    /// smallest scores: the largest `σ1`).
    InSample,
    /// Each pair's score by a model fitted without it
    /// ([`crate::held_out_scores`] over `folds` folds): what "on the support"
    /// looks like to the model on pairs it has not seen.
    HeldOut {
        /// Folds of the cross-fitting (2 to the number of pairs).
        folds: usize,
    },
}

/// Fits `config` on the expert pairs (`(n, obs_dim)`, `(n, act_dim)`) and
/// returns RED's reward over it, with `σ1` set by `sigma1` from the expert
/// scores that `scores` chooses. `rng` first fits the model, then (for
/// held-out scores) shuffles and fits the folds.
///
/// # Errors
/// The estimator's fitting and scoring errors; [`Error::InvalidConfig`] for
/// a bad `σ1` or fold count; [`Error::Numerical`] if the calibration
/// quantile of the scores is 0.
pub fn fit_red_reward<C: SupportEstimatorConfig, R: rand::Rng + ?Sized>(
    config: &C,
    sigma1: Sigma1,
    scores: ExpertScores,
    states: ArrayView2<'_, f64>,
    actions: ArrayView2<'_, f64>,
    rng: &mut R,
) -> Result<RedReward<C::Model>> {
    let model = config.fit(states, actions, rng, &mut no_progress)?;
    let sigma1 = match (sigma1, scores) {
        (Sigma1::Fixed(s), _) => s,
        (rule, ExpertScores::InSample) => rule.resolve(&model.score(states, actions)?.to_vec())?,
        (rule, ExpertScores::HeldOut { folds }) => {
            rule.resolve(&held_out_scores(config, states, actions, folds, rng)?.to_vec())?
        }
    };
    RedReward::with_sigma1(model, sigma1)
}
