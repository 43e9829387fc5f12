//! The MuJoCo experiments (paper Sec. 5.2) on Gymnasium's `-v5` Hopper,
//! HalfCheetah, Walker2d, Ant and Reacher: one TRPO or behaviour-cloning
//! run, or a SAC expert, with its folder, checkpoints, best checkpoint and
//! evaluation ([`launch`] starts it, [`run`] holds its settings), and the grid of Table 1 with its table and learning curves
//! ([`table`]).
//!
//! An expert, then RED imitating it, from Rust, with tiny budgets:
//!
//! ```no_run
//! use std::sync::atomic::AtomicBool;
//! use red_experiments::mujoco::{Method, launch, run::{self, Outcome, RunConfig}};
//! use red_mujoco::EnvId;
//!
//! let stop = AtomicBool::new(false);
//! let out = std::env::temp_dir().join("red-mujoco-example");
//! let mut expert = RunConfig::for_task(EnvId::Hopper, Method::Expert);
//! expert.steps = 8192;
//! let dir = out.join("expert-hopper");
//! launch::run(&dir, Some(expert), false, &stop, &mut red_experiments::Silent)?;
//! let mut red = RunConfig::for_task(EnvId::Hopper, Method::Red);
//! red.steps = 4096;
//! red.demo = Some(dir.join("demos.json"));
//! let dir = out.join("hopper-red");
//! if launch::run(&dir, Some(red), false, &stop, &mut red_experiments::Silent)? == Outcome::Finished {
//!     print!("{}", run::read_eval(&dir).expect("finished").summary(&dir));
//! }
//! # Ok::<(), red_experiments::Error>(())
//! ```

use std::path::{Path, PathBuf};

use red_mujoco::EnvId;

pub mod check;
pub mod demos;
pub mod launch;
pub mod run;
mod sac_run;
pub mod slurm;
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

/// Converts `file` from another `format` into demonstrations of `env`
/// (see [`red_core::import::import_file`]). A MuJoCo task (`hopper`,
/// `Hopper-v5`, ...) is written by its Gymnasium id and the file's
/// dimensions are checked against the task's; any other `env` is taken as
/// it is.
///
/// # Errors
/// The importer's errors, naming the file; [`crate::Error::Input`] when the
/// dimensions do not match the task's.
pub fn import_demos(
    format: red_core::import::ImportFormat,
    file: &Path,
    env: &str,
    steps: Option<usize>,
) -> crate::Result<red_core::Demos> {
    let task = env.parse::<EnvId>().ok();
    let env_id = task.map_or(env.to_string(), |t| t.name().to_string());
    let demos = red_core::import::import_file(format, file, &env_id, steps)?;
    if let Some(t) = task {
        let made = t.make_unlimited()?;
        let want = (made.observation_space().dim(), made.action_space().dim());
        if (demos.obs_dim, demos.act_dim) != want {
            return Err(crate::Error::Input {
                path: file.to_path_buf(),
                reason: format!(
                    "obs {} x act {} pairs, but {env_id} has obs {} x act {}",
                    demos.obs_dim, demos.act_dim, want.0, want.1
                ),
            });
        }
    }
    Ok(demos)
}
