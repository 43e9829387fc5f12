//! The MuJoCo experiments (paper Sec. 5.2) on Gymnasium's `-v5` Hopper,
//! HalfCheetah, Walker2d, Ant and Reacher: one TRPO or behaviour-cloning
//! run with its folder, checkpoints, best checkpoint and evaluation
//! ([`run`]), and the grid of Table 1 with its table and learning curves
//! ([`table`]).
//!
//! An expert, then RED imitating it, from Rust, with tiny budgets:
//!
//! ```no_run
//! use std::sync::atomic::AtomicBool;
//! use red_experiments::mujoco::{Method, run::{self, Outcome, RunConfig}};
//! use red_mujoco::EnvId;
//!
//! let stop = AtomicBool::new(false);
//! let out = std::env::temp_dir().join("red-mujoco-example");
//! let mut expert = RunConfig::for_task(EnvId::Hopper, Method::Expert);
//! expert.steps = 8192;
//! let dir = out.join("expert-hopper");
//! run::run(&dir, Some(expert), false, &stop, &mut red_experiments::Silent)?;
//! let mut red = RunConfig::for_task(EnvId::Hopper, Method::Red);
//! red.steps = 4096;
//! red.demo = Some(dir.join("demos.json"));
//! let dir = out.join("hopper-red");
//! if run::run(&dir, Some(red), false, &stop, &mut red_experiments::Silent)? == Outcome::Finished {
//!     print!("{}", run::read_eval(&dir).expect("finished").summary(&dir));
//! }
//! # Ok::<(), red_experiments::Error>(())
//! ```

use std::path::{Path, PathBuf};

use red_mujoco::EnvId;

pub mod check;
pub mod run;
pub mod table;

pub use crate::imitation::Method;

/// `hopper`, `halfcheetah`, ...: the task's name in run folders.
pub fn short_name(env: EnvId) -> String {
    env.name().trim_end_matches("-v5").to_ascii_lowercase()
}

/// The run folder of the expert of `env` in `out_dir`: `expert-<task>`.
pub fn expert_dir(out_dir: &Path, env: EnvId) -> PathBuf {
    out_dir.join(format!("expert-{}", short_name(env)))
}

/// Where the expert run of `env` in `out_dir` writes its demonstrations.
pub fn default_demo(out_dir: &Path, env: EnvId) -> PathBuf {
    expert_dir(out_dir, env).join("demos.json")
}

/// The default run name of `method` on `env` with `seed`:
/// `expert-<task>` for experts, `<task>-<method>-s<seed>` otherwise.
pub fn default_run_name(env: EnvId, method: Method, seed: u64) -> String {
    match method {
        Method::Expert => format!("expert-{}", short_name(env)),
        m => format!("{}-{}-s{seed}", short_name(env), m.name()),
    }
}
