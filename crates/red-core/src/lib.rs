//! Shared vocabulary of the `red` workspace: the [`Env`] trait and its
//! [`Space`]s, the [`TimeLimit`], [`RewardWrapper`] and [`LastAction`] wrappers, the
//! [`RewardModel`] trait, seeding, and expert demonstrations.
//!
//! - [`check`]: the checker every environment of the project passes
//!   (determinism from a seed, observations finite and in their space,
//!   `NeedsReset` after the end, malformed actions rejected).
//! - [`demo`]: the versioned JSON demonstration format, validated on read
//!   with the file, trajectory, step (and line and column) of the first
//!   problem, written atomically.
//! - [`import`]: the original RED release's pickles and OpenAI baselines'
//!   `.npz` experts, read without Python.
//!
//! ```
//! use red_core::{check_env, Env, TimeLimit};
//! # use red_core::{Info, Result, Space, Step, BoxSpace};
//! # struct Walk { pos: f64, obs: Space, act: Space }
//! # impl Env for Walk {
//! #     fn observation_space(&self) -> &Space { &self.obs }
//! #     fn action_space(&self) -> &Space { &self.act }
//! #     fn reset(&mut self, _seed: Option<u64>) -> Result<(Vec<f64>, Info)> {
//! #         self.pos = 0.0; Ok((vec![0.0], Info::new()))
//! #     }
//! #     fn step(&mut self, a: &[f64]) -> Result<Step> {
//! #         self.act.check("action", a)?;
//! #         self.pos += a[0];
//! #         Ok(Step { observation: vec![self.pos], reward: a[0], terminated: false,
//! #                   truncated: false, info: Info::new() })
//! #     }
//! # }
//! # let walk = Walk { pos: 0.0, obs: Space::Box(BoxSpace::uniform(1, f64::NEG_INFINITY, f64::INFINITY)),
//! #                   act: Space::Box(BoxSpace::uniform(1, -1.0, 1.0)) };
//! let mut env = TimeLimit::new(walk, 3)?;
//! env.reset(Some(0))?;
//! let mut steps = 0;
//! loop {
//!     let step = env.step(&[0.5])?;
//!     steps += 1;
//!     if step.terminated || step.truncated { break; }
//! }
//! assert_eq!(steps, 3);
//!
//! // Every environment of the project passes the checker.
//! let report = check_env(&mut env, 0, 50)?;
//! assert_eq!(report.truncated, 50 / 3);
//! # Ok::<(), red_core::Error>(())
//! ```

#![warn(missing_docs)]

pub mod check;
pub mod checkpoint;
pub mod demo;
pub mod env;
pub mod episode;
pub mod error;
pub mod import;
mod json_loc;
pub mod reward;
pub mod seeding;
pub mod simple_domain;
pub mod space;
pub mod wrappers;

pub use check::{CheckReport, check_env};
pub use demo::{DemoSource, Demos, EpisodeEnd, Trajectory};
pub use env::{Env, Info, Step, TRUE_REWARD};
pub use episode::{EpisodeRun, record_episode, run_episode, true_reward};
pub use error::{Error, Result};
pub use reward::{ClippedActions, DifferentiableReward, RewardModel};
pub use seeding::{Seeder, Stream};
pub use space::{BoxSpace, Space};
pub use wrappers::{LastAction, RewardWrapper, TimeLimit};

// The exact versions of the crates this crate's API takes and returns,
// so that a dependant names the same types (a second version of ndarray or
// rand in a build gives type errors that never mention versions).
pub use ndarray;
pub use rand;
pub use rand_chacha;
