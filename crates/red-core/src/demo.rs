//! Expert demonstrations: the dataset type and the project's JSON format.
//!
//! Status: the data types and plain reading/writing are here; full
//! validation with located errors and the importers are being completed.

use std::path::Path;

use ndarray::Array2;
use serde::{Deserialize, Serialize};

use crate::{Error, Result};

/// Name written in the `format` field of every demo file.
pub const FORMAT_NAME: &str = "red-demos";
/// The version of the format this build writes.
pub const FORMAT_VERSION: u32 = 1;

/// How a trajectory ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EpisodeEnd {
    /// The task ended it (a fall, a crash, the goal).
    Terminated,
    /// A time limit cut it.
    Truncated,
}

/// One demonstrated episode: `observations[t]` is the state in which
/// `actions[t]` was taken, so both have the same length.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Trajectory {
    /// States, one per step, each of `obs_dim` numbers.
    pub observations: Vec<Vec<f64>>,
    /// Actions, one per step, each of `act_dim` numbers.
    pub actions: Vec<Vec<f64>>,
    /// The environment's true rewards, one per step, if known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rewards: Option<Vec<f64>>,
    /// How the episode ended.
    pub end: EpisodeEnd,
}

/// A set of demonstrations for one environment.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Demos {
    /// Always [`FORMAT_NAME`].
    pub format: String,
    /// The format's version.
    pub version: u32,
    /// The environment's id (for example `"drive"`, `"Hopper-v5"`).
    pub env_id: String,
    /// Length of an observation.
    pub obs_dim: usize,
    /// Length of an action.
    pub act_dim: usize,
    /// Control frequency in Hz, if meaningful.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub control_hz: Option<f64>,
    /// The trajectories.
    pub trajectories: Vec<Trajectory>,
}

impl Demos {
    /// An empty set for `env_id` with the given dimensions.
    pub fn new(
        env_id: impl Into<String>,
        obs_dim: usize,
        act_dim: usize,
        control_hz: Option<f64>,
    ) -> Self {
        Self {
            format: FORMAT_NAME.into(),
            version: FORMAT_VERSION,
            env_id: env_id.into(),
            obs_dim,
            act_dim,
            control_hz,
            trajectories: Vec::new(),
        }
    }

    /// Total number of state-action pairs.
    pub fn num_pairs(&self) -> usize {
        self.trajectories.iter().map(|t| t.actions.len()).sum()
    }

    /// All state-action pairs stacked: `((N, obs_dim), (N, act_dim))`.
    pub fn pairs(&self) -> (Array2<f64>, Array2<f64>) {
        let n = self.num_pairs();
        let mut s = Array2::zeros((n, self.obs_dim));
        let mut a = Array2::zeros((n, self.act_dim));
        let mut row = 0;
        for t in &self.trajectories {
            for (o, u) in t.observations.iter().zip(&t.actions) {
                for (j, v) in o.iter().enumerate() {
                    s[[row, j]] = *v;
                }
                for (j, v) in u.iter().enumerate() {
                    a[[row, j]] = *v;
                }
                row += 1;
            }
        }
        (s, a)
    }

    /// Writes the set as JSON to `path`.
    ///
    /// # Errors
    /// [`Error::Io`] if the file cannot be written.
    pub fn write(&self, path: &Path) -> Result<()> {
        let text = serde_json::to_string(self).map_err(|e| Error::Demo {
            path: Some(path.to_path_buf()),
            trajectory: None,
            step: None,
            reason: e.to_string(),
        })?;
        std::fs::write(path, text).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })
    }

    /// Reads a demo file.
    ///
    /// # Errors
    /// [`Error::Io`] if it cannot be read, [`Error::Demo`] if it is malformed.
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
        serde_json::from_str(&text).map_err(|e| Error::Demo {
            path: Some(path.to_path_buf()),
            trajectory: None,
            step: None,
            reason: e.to_string(),
        })
    }
}
