//! MuJoCo environments with the observations, rewards, terminations and
//! reset noise of Gymnasium's `-v5` versions: [`Hopper`], [`HalfCheetah`],
//! [`Walker2d`], [`Ant`] and [`Reacher`], on MuJoCo 3.17.0 through
//! `mujoco-rs`.
//!
//! Set-up: `scripts/setup-mujoco.sh` (from the repository root) puts the
//! MuJoCo library and Gymnasium's model files under `.mujoco/`; the model
//! folder can be moved with the environment variable `RED_MUJOCO_ASSETS`
//! (see [`assets`]).
//!
//! ```
//! use red_core::Env;
//! use red_mujoco::EnvId;
//!
//! // Hopper-v5 inside its 1000-step time limit.
//! let mut env = EnvId::Hopper.make()?;
//! let (obs, _info) = env.reset(Some(42))?;
//! assert_eq!(obs.len(), 11);
//! let step = env.step(&[0.1, -0.2, 0.3])?;
//! let survive = step.info.get("reward_survive").unwrap();
//! let forward = step.info.get("reward_forward").unwrap();
//! let ctrl = step.info.get("reward_ctrl").unwrap();
//! assert!((step.reward - (forward + survive + ctrl)).abs() < 1e-12);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! One default differs from Gymnasium's: [`Ant`] leaves the contact forces
//! out of its observation (27 numbers, as `Ant-v4`);
//! [`AntConfig::include_cfrc_ext_in_observation`] gives Gymnasium's `Ant-v5`
//! default of 105. Actions outside the bounds are accepted, as in Gymnasium
//! (MuJoCo clamps the control; the control cost uses the raw action).
//!
//! Every environment is checked step by step against Gymnasium itself by
//! `tests/gymnasium_parity.rs` (it needs the oracle virtualenv that
//! `scripts/setup-mujoco.sh` creates; `RED_SKIP_PARITY=1` skips it).

pub mod assets;
mod common;
pub mod error;
pub mod simulation;

pub mod ant;
pub mod half_cheetah;
pub mod hopper;
pub mod reacher;
pub mod registry;
pub mod walker2d;
pub mod watched;

pub use ant::{Ant, AntConfig};
pub use common::MujocoEnv;
pub use error::{Error, Result};
pub use half_cheetah::{HalfCheetah, HalfCheetahConfig};
pub use hopper::{Hopper, HopperConfig};
pub use reacher::{Reacher, ReacherConfig};
pub use registry::{BoxedEnv, EnvId, make};
pub use simulation::Simulation;
pub use walker2d::{Walker2d, Walker2dConfig};
pub use watched::{WatchedEnv, describe_warnings};

// The exact versions of the crates this crate's API takes and returns,
// so that a dependant names the same types (a second version of ndarray or
// rand in a build gives type errors that never mention versions).
pub use rand;
pub use rand_chacha;

/// The version string of the MuJoCo library loaded at run time (this crate
/// binds 3.17.0).
pub fn library_version() -> &'static str {
    mujoco_rs::mujoco_version()
}

/// The MuJoCo version the bindings were generated for.
pub const EXPECTED_LIBRARY_VERSION: &str = "3.17.0";

impl<E: MujocoEnv + ?Sized> MujocoEnv for Box<E> {
    fn simulation(&self) -> &Simulation {
        (**self).simulation()
    }
    fn set_state(&mut self, qpos: &[f64], qvel: &[f64]) -> red_core::Result<Vec<f64>> {
        (**self).set_state(qpos, qvel)
    }
    fn observation(&self) -> Vec<f64> {
        (**self).observation()
    }
}
