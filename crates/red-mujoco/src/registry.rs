//! The environments by name, with Gymnasium's time limits.

use std::fmt;
use std::str::FromStr;

use red_core::TimeLimit;
use serde::{Deserialize, Serialize};

use crate::{
    Ant, AntConfig, Error, HalfCheetah, HalfCheetahConfig, Hopper, HopperConfig, MujocoEnv,
    Reacher, ReacherConfig, Result, Walker2d, Walker2dConfig,
};

/// A boxed environment of this crate.
pub type BoxedEnv = Box<dyn MujocoEnv + Send>;

/// One of the five environments.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum EnvId {
    /// [`Hopper`], `Hopper-v5`.
    #[serde(rename = "Hopper-v5")]
    Hopper,
    /// [`HalfCheetah`], `HalfCheetah-v5`.
    #[serde(rename = "HalfCheetah-v5")]
    HalfCheetah,
    /// [`Walker2d`], `Walker2d-v5`.
    #[serde(rename = "Walker2d-v5")]
    Walker2d,
    /// [`Ant`], `Ant-v5`.
    #[serde(rename = "Ant-v5")]
    Ant,
    /// [`Reacher`], `Reacher-v5`.
    #[serde(rename = "Reacher-v5")]
    Reacher,
}

impl EnvId {
    /// Every environment.
    pub const ALL: [EnvId; 5] = [
        EnvId::Hopper,
        EnvId::HalfCheetah,
        EnvId::Walker2d,
        EnvId::Ant,
        EnvId::Reacher,
    ];

    /// Gymnasium's id, for example `"Hopper-v5"`.
    pub fn name(self) -> &'static str {
        match self {
            EnvId::Hopper => "Hopper-v5",
            EnvId::HalfCheetah => "HalfCheetah-v5",
            EnvId::Walker2d => "Walker2d-v5",
            EnvId::Ant => "Ant-v5",
            EnvId::Reacher => "Reacher-v5",
        }
    }

    /// Gymnasium's `max_episode_steps`: 1000, or 50 for Reacher.
    pub fn max_episode_steps(self) -> usize {
        match self {
            EnvId::Reacher => 50,
            _ => 1000,
        }
    }

    /// The environment with its default config and no time limit.
    ///
    /// # Errors
    /// The model cannot be loaded (run `scripts/setup-mujoco.sh`).
    pub fn make_unlimited(self) -> Result<BoxedEnv> {
        Ok(match self {
            EnvId::Hopper => Box::new(Hopper::new(HopperConfig::default())?),
            EnvId::HalfCheetah => Box::new(HalfCheetah::new(HalfCheetahConfig::default())?),
            EnvId::Walker2d => Box::new(Walker2d::new(Walker2dConfig::default())?),
            EnvId::Ant => Box::new(Ant::new(AntConfig::default())?),
            EnvId::Reacher => Box::new(Reacher::new(ReacherConfig::default())?),
        })
    }

    /// The environment with its default config inside Gymnasium's time
    /// limit ([`EnvId::max_episode_steps`]).
    ///
    /// # Errors
    /// As [`EnvId::make_unlimited`].
    pub fn make(self) -> Result<TimeLimit<BoxedEnv>> {
        let env = self.make_unlimited()?;
        TimeLimit::new(env, self.max_episode_steps()).map_err(|e| Error::InvalidConfig {
            field: "max_episode_steps",
            reason: e.to_string(),
        })
    }
}

impl fmt::Display for EnvId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for EnvId {
    type Err = Error;

    /// Accepts Gymnasium's id (`"Hopper-v5"`) or the bare name (`"hopper"`),
    /// in any case.
    fn from_str(s: &str) -> Result<Self> {
        let wanted = s.to_ascii_lowercase();
        EnvId::ALL
            .into_iter()
            .find(|id| {
                let name = id.name().to_ascii_lowercase();
                wanted == name || Some(wanted.as_str()) == name.strip_suffix("-v5")
            })
            .ok_or_else(|| Error::UnknownEnv {
                id: s.to_string(),
                known: EnvId::ALL.map(EnvId::name).join(", "),
            })
    }
}

/// The environment called `id` (see [`EnvId::from_str`]) with its default
/// config inside Gymnasium's time limit.
///
/// # Errors
/// [`Error::UnknownEnv`] for an unknown id, or the model cannot be loaded.
pub fn make(id: &str) -> Result<TimeLimit<BoxedEnv>> {
    id.parse::<EnvId>()?.make()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_parse_and_print() {
        for id in EnvId::ALL {
            assert_eq!(id.name().parse::<EnvId>().unwrap(), id);
            assert_eq!(id.to_string(), id.name());
            let json = serde_json::to_string(&id).unwrap();
            assert_eq!(json, format!("\"{}\"", id.name()));
        }
        assert_eq!("hopper".parse::<EnvId>().unwrap(), EnvId::Hopper);
        assert_eq!("WALKER2D-V5".parse::<EnvId>().unwrap(), EnvId::Walker2d);
        let err = "Humanoid-v5".parse::<EnvId>().unwrap_err();
        assert!(err.to_string().contains("Hopper-v5"), "{err}");
        assert_eq!(EnvId::Reacher.max_episode_steps(), 50);
        assert_eq!(EnvId::Ant.max_episode_steps(), 1000);
    }
}
