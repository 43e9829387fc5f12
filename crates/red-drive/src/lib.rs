//! The driving scenario of the paper's Sec. 5.3: a straight three-lane road
//! with walls at both edges and stopped cars in random lanes, a car with
//! steering and accelerator/brake controlled at 20 Hz, and a 20-ray lidar.
//! Geometry queries (ray casts, overlap tests) use parry2d, rapier's
//! geometry library; the car is a kinematic bicycle integrated here.
//!
//! ```
//! use red_core::Env;
//! use red_drive::{DriveConfig, Expert, make_env};
//!
//! let config = DriveConfig::default();
//! let mut env = make_env(&config)?;
//! let expert = Expert::new(env.inner().world());
//! env.reset(Some(0))?;
//! let mut total = 0.0;
//! for _ in 0..100 {
//!     let action = expert.act(env.inner().car());
//!     let step = env.step(&action)?;
//!     total += step.reward;
//!     if step.terminated || step.truncated { break; }
//! }
//! assert!(total > 100.0);
//! # Ok::<(), red_drive::Error>(())
//! ```

pub mod config;
pub mod env;
pub mod error;
pub mod expert;
pub mod human;
pub mod record;
pub mod render;
pub mod scenario;
#[cfg(feature = "terminal")]
pub mod terminal;
pub mod track;

pub use config::{ACT_DIM, CONTROL_HZ, DriveConfig, NUM_LANES, NUM_RAYS, OBS_DIM};
pub use env::{CarState, DriveEnv, World, make_env};
pub use error::{Error, Result};
pub use expert::{Expert, ExpertStyle, expert_demos};
pub use human::{HumanConfig, HumanDriver, human_demos};
pub use record::{DriveKey, KeyEvent, Recorder};
pub use render::{PathEnd, PathSpec, RenderOptions, render_png};
pub use track::{Obstacle, Track};

// The exact versions of the crates this crate's API takes and returns,
// so that a dependant names the same types (a second version of ndarray or
// rand in a build gives type errors that never mention versions).
pub use rand;
pub use rand_chacha;

/// The environment id written in demonstration files of this scenario.
pub const ENV_ID: &str = "drive";
