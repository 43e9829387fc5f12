//! What the five environments share: the simulation, the random stream of
//! resets, the spaces, the episode state, and the checks of actions and
//! configs.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use red_core::{BoxSpace, Info, Space};

use crate::{Error, Result, Simulation};

/// A MuJoCo environment: a [`red_core::Env`] whose physical state can be
/// read and set, as Gymnasium's `MujocoEnv` allows.
pub trait MujocoEnv: red_core::Env {
    /// The simulation (model, data, frame skip).
    fn simulation(&self) -> &Simulation;

    /// Sets the joint positions (`nq` numbers) and velocities (`nv`), as
    /// Gymnasium's `set_state`, and returns the observation of that state.
    /// The episode may be stepped afterwards, as after a reset.
    ///
    /// # Errors
    /// [`red_core::Error::ShapeMismatch`] or [`red_core::Error::NonFinite`]
    /// for malformed vectors.
    fn set_state(&mut self, qpos: &[f64], qvel: &[f64]) -> red_core::Result<Vec<f64>>;

    /// The observation of the current state.
    fn observation(&self) -> Vec<f64>;
}

/// The seed of the reset stream until the first `reset(Some(seed))`: an
/// environment is reproducible even when never seeded.
pub(crate) const DEFAULT_SEED: u64 = 0;

/// The parts every environment has.
#[derive(Debug)]
pub(crate) struct EnvCore {
    pub(crate) sim: Simulation,
    pub(crate) rng: ChaCha8Rng,
    /// True before the first reset and after a terminal step.
    pub(crate) needs_reset: bool,
    pub(crate) observation_space: Space,
    pub(crate) action_space: Space,
}

impl EnvCore {
    /// Wraps `sim`; observations have `obs_dim` unbounded numbers and
    /// actions the actuators' control ranges (as Gymnasium's
    /// `_set_action_space`).
    pub(crate) fn new(sim: Simulation, obs_dim: usize) -> Result<Self> {
        let (low, high) = sim.ctrl_range().iter().map(|r| (r[0], r[1])).unzip();
        let action = BoxSpace::new(low, high).map_err(|e| Error::ModelMismatch {
            model: sim.name().to_string(),
            reason: format!("actuator control ranges: {e}"),
        })?;
        Ok(Self {
            sim,
            rng: ChaCha8Rng::seed_from_u64(DEFAULT_SEED),
            needs_reset: true,
            observation_space: Space::Box(BoxSpace::uniform(
                obs_dim,
                f64::NEG_INFINITY,
                f64::INFINITY,
            )),
            action_space: Space::Box(action),
        })
    }

    /// Restarts the reset stream from `seed`, or keeps it for `None`, then
    /// runs `mj_resetData` as Gymnasium's `reset` does before
    /// `reset_model`.
    pub(crate) fn begin_reset(&mut self, seed: Option<u64>) {
        if let Some(seed) = seed {
            self.rng = ChaCha8Rng::seed_from_u64(seed);
        }
        self.sim.reset();
    }

    /// Checks that the episode may step and that `action` has the right
    /// length and finite values. Values outside the action space are
    /// accepted, as in Gymnasium: MuJoCo clamps the control, and the control
    /// cost uses the raw action.
    pub(crate) fn check_step(&self, action: &[f64]) -> red_core::Result<()> {
        if self.needs_reset {
            return Err(red_core::Error::NeedsReset {
                reason: "step called before reset or after the episode terminated".into(),
            });
        }
        let dim = self.action_space.dim();
        if action.len() != dim {
            return Err(Error::ShapeMismatch {
                what: "action",
                expected: dim,
                got: action.len(),
            }
            .into());
        }
        if action.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite { what: "action" }.into());
        }
        Ok(())
    }

    /// `n` draws of `U[low, high)` added to `base`.
    pub(crate) fn add_uniform(&mut self, base: &[f64], low: f64, high: f64) -> Vec<f64> {
        base.iter()
            .map(|b| b + uniform(&mut self.rng, low, high))
            .collect()
    }

    /// `scale * N(0, 1)` added to each of `base`.
    pub(crate) fn add_normal(&mut self, base: &[f64], scale: f64) -> Vec<f64> {
        base.iter()
            .map(|b| b + scale * self.rng.sample::<f64, _>(StandardNormal))
            .collect()
    }
}

/// A draw of `U[low, high)`; `low` itself when the interval is empty
/// (a noise scale of 0).
pub(crate) fn uniform(rng: &mut ChaCha8Rng, low: f64, high: f64) -> f64 {
    if low < high {
        rng.random_range(low..high)
    } else {
        low
    }
}

/// `sum(a_i^2)`.
pub(crate) fn sum_of_squares(a: &[f64]) -> f64 {
    a.iter().map(|v| v * v).sum()
}

/// An [`Info`] that already holds `keys` (set to 0), so that cloning it and
/// overwriting the values costs one allocation per step.
pub(crate) fn info_template(keys: &[&'static str]) -> Info {
    let mut info = Info::new();
    for k in keys {
        info.set(k, 0.0);
    }
    info
}

/// Config checks shared by the environments.
pub(crate) mod validate {
    use crate::{Error, Result};

    pub(crate) fn finite(field: &'static str, v: f64) -> Result<()> {
        if v.is_finite() {
            Ok(())
        } else {
            Err(Error::InvalidConfig {
                field,
                reason: format!("must be finite, got {v}"),
            })
        }
    }

    pub(crate) fn non_negative(field: &'static str, v: f64) -> Result<()> {
        finite(field, v)?;
        if v >= 0.0 {
            Ok(())
        } else {
            Err(Error::InvalidConfig {
                field,
                reason: format!("must be >= 0, got {v}"),
            })
        }
    }

    pub(crate) fn range(field: &'static str, r: [f64; 2]) -> Result<()> {
        if r[0].is_nan() || r[1].is_nan() || r[0] > r[1] {
            Err(Error::InvalidConfig {
                field,
                reason: format!("need low <= high, got [{}, {}]", r[0], r[1]),
            })
        } else {
            Ok(())
        }
    }

    pub(crate) fn frame_skip(v: usize) -> Result<()> {
        if v == 0 {
            Err(Error::InvalidConfig {
                field: "frame_skip",
                reason: "must be at least 1".into(),
            })
        } else {
            Ok(())
        }
    }

    pub(crate) fn xml_file(v: &str) -> Result<()> {
        if v.is_empty() {
            Err(Error::InvalidConfig {
                field: "xml_file",
                reason: "must name a model file".into(),
            })
        } else {
            Ok(())
        }
    }
}

/// Serde for a `[low, high]` range whose bounds may be infinite: JSON has
/// no infinity, so an infinite bound is written as the string `"inf"` or
/// `"-inf"`.
pub(crate) mod range_serde {
    use serde::de::Error as _;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    #[derive(Serialize, Deserialize)]
    #[serde(untagged)]
    enum Bound {
        Number(f64),
        Text(String),
    }

    fn to_bound(v: f64) -> Bound {
        if v == f64::INFINITY {
            Bound::Text("inf".into())
        } else if v == f64::NEG_INFINITY {
            Bound::Text("-inf".into())
        } else {
            Bound::Number(v)
        }
    }

    fn from_bound<E: serde::de::Error>(b: Bound) -> Result<f64, E> {
        match b {
            Bound::Number(v) => Ok(v),
            Bound::Text(s) => match s.as_str() {
                "inf" | "+inf" | "infinity" => Ok(f64::INFINITY),
                "-inf" | "-infinity" => Ok(f64::NEG_INFINITY),
                _ => Err(E::custom(format!(
                    "a range bound must be a number, \"inf\" or \"-inf\", got {s:?}"
                ))),
            },
        }
    }

    pub(crate) fn serialize<S: Serializer>(r: &[f64; 2], s: S) -> Result<S::Ok, S::Error> {
        [to_bound(r[0]), to_bound(r[1])].serialize(s)
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 2], D::Error> {
        let [lo, hi] = <[Bound; 2]>::deserialize(d)?;
        let r = [from_bound(lo)?, from_bound(hi)?];
        if r[0].is_nan() || r[1].is_nan() {
            return Err(D::Error::custom("a range bound is NaN"));
        }
        Ok(r)
    }
}
