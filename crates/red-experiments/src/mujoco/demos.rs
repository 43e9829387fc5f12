//! Demonstration sets of other kinds than an `expert` run's (issue 21):
//! episodes of a saved policy with mean or sampled actions, stored clipped
//! to the action space or raw, and the first K trajectories of a demo file.
//! The episodes are recorded by [`super::run::record_demos_with`], the
//! loop `expert` runs use.
//!
//! ```no_run
//! use red_experiments::mujoco::demos::{DemoRequest, make_demos, write_new};
//! use red_mujoco::EnvId;
//!
//! let mut req = DemoRequest::new("runs/expert-hopper/policy.json".into(), EnvId::Hopper, 4);
//! req.sampled = true;
//! req.raw = true;
//! let demos = make_demos(&req)?;
//! write_new(&demos, std::path::Path::new("hopper-sampled-raw.json"))?;
//! # Ok::<(), red_experiments::Error>(())
//! ```

use std::path::{Path, PathBuf};

use red_core::{DemoSource, Demos, Env};
use red_mujoco::{EnvId, WatchedEnv};
use red_rl::policy::GaussianPolicy;
use serde::{Deserialize, Serialize};

use super::run::{RecordOptions, read_config, record_demos_with};
use crate::{Error, Result};

/// What to record: `episodes` episodes of the policy file `policy` on
/// `env`, with `seed`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DemoRequest {
    /// A policy file as `red-cli mujoco expert` / `mujoco train` write it
    /// (`policy.json`, `best_policy.json`, `expert_policy.json`).
    pub policy: PathBuf,
    /// The task.
    pub env: EnvId,
    /// Episodes (trajectories), at least 1.
    pub episodes: usize,
    /// Seed of the episodes' resets (and of the action noise when
    /// `sampled`). Default 0.
    pub seed: u64,
    /// Actions sampled from the policy's Gaussian instead of its mean.
    pub sampled: bool,
    /// Store the raw actions (unclipped network output or sample) instead
    /// of the actions clipped to the action space.
    pub raw: bool,
    /// Steps per episode at most (default: the task's time limit).
    pub max_steps: Option<usize>,
}

impl DemoRequest {
    /// Mean actions, stored clipped, seed 0, to the time limit: what an
    /// `expert` run writes.
    pub fn new(policy: PathBuf, env: EnvId, episodes: usize) -> Self {
        Self {
            policy,
            env,
            episodes,
            seed: 0,
            sampled: false,
            raw: false,
            max_steps: None,
        }
    }
}

/// How a demo file was made, written to its `made_with` field.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MadeWith {
    /// The command: `mujoco demos` or `demo take`.
    pub command: String,
    /// The policy file (`mujoco demos`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub policy: Option<String>,
    /// The method and seed of the run whose folder holds the policy file,
    /// when that folder has a `config.json` (for example `expert, seed 0`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub policy_run: Option<String>,
    /// Seed of the episodes (`mujoco demos`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// `mean` or `sampled` (`mujoco demos`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub actions: Option<String>,
    /// `clipped` or `raw` (`mujoco demos`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stored: Option<String>,
    /// Steps per episode at most, when set.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_steps: Option<usize>,
    /// The file the trajectories were taken from (`demo take`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub taken_from: Option<String>,
    /// The `made_with` of that file, if it had one (`demo take`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source_made_with: Option<serde_json::Value>,
}

/// Loads the request's policy, checks it fits the task, and records the
/// episodes: `source` is `policy` and `made_with` says how ([`MadeWith`]).
///
/// # Errors
/// [`Error::InvalidConfig`] for 0 episodes or `max_steps` 0;
/// [`Error::Input`] naming the policy file when it cannot be read or is
/// not a policy, or when its dimensions are not the task's; environment
/// errors.
pub fn make_demos(req: &DemoRequest) -> Result<Demos> {
    let positive = |field: &str, v: usize| {
        if v == 0 {
            Err(Error::InvalidConfig {
                field: field.into(),
                reason: "must be at least 1".into(),
            })
        } else {
            Ok(())
        }
    };
    positive("episodes", req.episodes)?;
    if let Some(m) = req.max_steps {
        positive("max_steps", m)?;
    }
    let bad = |reason: String| Error::Input {
        path: req.policy.clone(),
        reason,
    };
    let policy = GaussianPolicy::load(&req.policy).map_err(|e| {
        bad(format!(
            "cannot load a policy ({e}); give the policy.json (or best_policy.json) \
             that `red-cli mujoco expert` or `mujoco train` wrote"
        ))
    })?;
    let probe = WatchedEnv::new(req.env)?;
    let (od, ad) = (probe.observation_space().dim(), probe.action_space().dim());
    // a policy trained with the time feature reads one number more
    let fits = policy.obs_dim() == od || policy.obs_dim() == od + 1;
    if !fits || policy.act_dim() != ad {
        return Err(bad(format!(
            "is a policy for observations of {} and actions of {} numbers, but {} has {od} \
             (or {} with the time feature) and {ad}: give a policy trained on {} (or the --env \
             it was trained on)",
            policy.obs_dim(),
            policy.act_dim(),
            req.env.name(),
            od + 1,
            req.env.name()
        )));
    }
    let opts = RecordOptions {
        sampled: req.sampled,
        raw: req.raw,
        max_steps: req.max_steps,
    };
    let mut demos = record_demos_with(req.env, &policy, req.episodes, req.seed, &opts)?;
    let policy_run = req
        .policy
        .parent()
        .filter(|d| d.join("config.json").is_file())
        .and_then(|d| read_config(d).ok())
        .map(|c| format!("{}, seed {}", c.method.name(), c.seed));
    let made = MadeWith {
        command: "mujoco demos".into(),
        policy: Some(req.policy.display().to_string()),
        policy_run,
        seed: Some(req.seed),
        actions: Some(if req.sampled { "sampled" } else { "mean" }.into()),
        stored: Some(if req.raw { "raw" } else { "clipped" }.into()),
        max_steps: req.max_steps,
        taken_from: None,
        source_made_with: None,
    };
    demos.source = Some(DemoSource::Policy);
    demos.made_with = Some(serde_json::to_value(made).expect("plain fields serialise"));
    Ok(demos)
}

/// The first `k` trajectories of the demo file `file` (its header, source
/// and scenario kept; `made_with` records the file and its own
/// `made_with`).
///
/// # Errors
/// [`Error::InvalidConfig`] for `k` 0; the file's read errors;
/// [`Error::Input`] naming the file when it holds fewer than `k`
/// trajectories.
pub fn take_trajectories(file: &Path, k: usize) -> Result<Demos> {
    if k == 0 {
        return Err(Error::InvalidConfig {
            field: "trajectories".into(),
            reason: "must be at least 1".into(),
        });
    }
    let mut demos = Demos::read(file)?;
    let n = demos.trajectories.len();
    if n < k {
        return Err(Error::Input {
            path: file.to_path_buf(),
            reason: format!(
                "holds {n} trajectories, fewer than the {k} asked: ask for at most {n}"
            ),
        });
    }
    demos.trajectories.truncate(k);
    let made = MadeWith {
        command: format!("demo take --trajectories {k}"),
        policy: None,
        policy_run: None,
        seed: None,
        actions: None,
        stored: None,
        max_steps: None,
        taken_from: Some(file.display().to_string()),
        source_made_with: demos.made_with.take(),
    };
    demos.version = red_core::demo::FORMAT_VERSION;
    demos.made_with = Some(serde_json::to_value(made).expect("plain fields serialise"));
    Ok(demos)
}

/// [`make_demos`] written to `out` (refused before any episode when `out`
/// exists, see [`write_new`]).
///
/// # Errors
/// As [`make_demos`] and [`write_new`].
pub fn make_demos_file(req: &DemoRequest, out: &Path) -> Result<Demos> {
    refuse_existing(out)?;
    let demos = make_demos(req)?;
    write_new(&demos, out)?;
    Ok(demos)
}

fn refuse_existing(out: &Path) -> Result<()> {
    if out.exists() {
        return Err(Error::Input {
            path: out.to_path_buf(),
            reason: "exists; choose another --out (nothing was written)".into(),
        });
    }
    Ok(())
}

/// Writes `demos` to `out`, which must not exist yet.
///
/// # Errors
/// [`Error::Input`] naming `out` when it exists (nothing is written); write
/// errors.
pub fn write_new(demos: &Demos, out: &Path) -> Result<()> {
    refuse_existing(out)?;
    demos.write(out)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use red_rl::policy::GaussianPolicyConfig;

    use super::*;

    /// A fresh Reacher policy (10 observations, 2 actions in [-1, 1])
    /// whose output layer is scaled by `scale`: with 10 its means fall far
    /// outside the action bounds.
    fn policy_file(dir: &Path, obs: usize, act: usize, scale: f32) -> PathBuf {
        let cfg = GaussianPolicyConfig {
            output_scale: scale,
            ..GaussianPolicyConfig::default()
        };
        let p =
            GaussianPolicy::new(&cfg, obs, act, None, &mut ChaCha8Rng::seed_from_u64(3)).unwrap();
        let path = dir.join(format!("policy-{obs}-{act}-{scale}.json"));
        p.save(&path).unwrap();
        path
    }

    fn actions(d: &Demos) -> Vec<f64> {
        d.trajectories
            .iter()
            .flat_map(|t| t.actions.iter().flatten().copied())
            .collect()
    }

    #[test]
    fn each_kind_stores_what_it_says_and_the_same_seed_gives_the_same_set() {
        let tmp = tempfile::tempdir().unwrap();
        let wide = policy_file(tmp.path(), 10, 2, 10.0);
        let mut req = DemoRequest::new(wide.clone(), EnvId::Reacher, 3);
        req.seed = 5;
        let mean_clipped = make_demos(&req).unwrap();
        assert_eq!(mean_clipped.trajectories.len(), 3);
        assert_eq!(mean_clipped.lengths(), [50, 50, 50]);
        assert!(actions(&mean_clipped).iter().all(|a| a.abs() <= 1.0));
        assert_eq!(mean_clipped.source, Some(DemoSource::Policy));
        let made: MadeWith =
            serde_json::from_value(mean_clipped.made_with.clone().unwrap()).unwrap();
        assert_eq!(
            (made.actions.as_deref(), made.stored.as_deref(), made.seed),
            (Some("mean"), Some("clipped"), Some(5))
        );
        assert_eq!(made.policy, Some(wide.display().to_string()));

        req.raw = true;
        let mean_raw = make_demos(&req).unwrap();
        assert!(actions(&mean_raw).iter().any(|a| a.abs() > 1.0));
        // The environment received the clipped actions either way, so the
        // states and rewards are those of the clipped set.
        assert_eq!(
            mean_raw.trajectories[0].observations,
            mean_clipped.trajectories[0].observations
        );
        assert_eq!(mean_raw.returns(), mean_clipped.returns());

        req.sampled = true;
        let sampled_raw = make_demos(&req).unwrap();
        assert_ne!(actions(&sampled_raw), actions(&mean_raw));
        req.raw = false;
        let sampled_clipped = make_demos(&req).unwrap();
        assert_ne!(actions(&sampled_clipped), actions(&mean_clipped));
        assert!(actions(&sampled_clipped).iter().all(|a| a.abs() <= 1.0));
        assert_eq!(make_demos(&req).unwrap(), sampled_clipped);

        // Sampled differs from mean also where the mean stays in bounds.
        let narrow = policy_file(tmp.path(), 10, 2, 0.01);
        let mut req = DemoRequest::new(narrow, EnvId::Reacher, 1);
        let mean = make_demos(&req).unwrap();
        req.sampled = true;
        assert_ne!(actions(&make_demos(&req).unwrap()), actions(&mean));

        req.max_steps = Some(7);
        let short = make_demos(&req).unwrap();
        assert_eq!(short.lengths(), [7]);
        assert_eq!(short.trajectories[0].end, red_core::EpisodeEnd::Truncated);
    }

    #[test]
    fn bad_requests_are_refused_naming_the_file_and_the_fix() {
        let tmp = tempfile::tempdir().unwrap();
        let missing = tmp.path().join("nope.json");
        let e = make_demos(&DemoRequest::new(missing.clone(), EnvId::Reacher, 1))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("nope.json") && e.contains("mujoco expert"),
            "{e}"
        );
        let hopper = policy_file(tmp.path(), 11, 3, 0.01);
        let e = make_demos(&DemoRequest::new(hopper.clone(), EnvId::Reacher, 1))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("policy-11-3") && e.contains("Reacher-v5") && e.contains("trained on"),
            "{e}"
        );
        let e = make_demos(&DemoRequest::new(hopper.clone(), EnvId::Hopper, 0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("episodes") && e.contains("at least 1"), "{e}");

        let demos = make_demos(&DemoRequest::new(hopper, EnvId::Hopper, 1)).unwrap();
        let out = tmp.path().join("d.json");
        write_new(&demos, &out).unwrap();
        let before = std::fs::read(&out).unwrap();
        let e = write_new(&demos, &out).unwrap_err().to_string();
        assert!(e.contains("d.json") && e.contains("another --out"), "{e}");
        assert_eq!(std::fs::read(&out).unwrap(), before);
    }

    #[test]
    fn take_keeps_the_first_trajectories_and_says_where_from() {
        let tmp = tempfile::tempdir().unwrap();
        let p = policy_file(tmp.path(), 10, 2, 0.01);
        let mut req = DemoRequest::new(p, EnvId::Reacher, 3);
        req.max_steps = Some(5);
        let all = make_demos(&req).unwrap();
        let file = tmp.path().join("all.json");
        write_new(&all, &file).unwrap();
        let one = take_trajectories(&file, 1).unwrap();
        assert_eq!(one.trajectories, all.trajectories[..1]);
        let made: MadeWith = serde_json::from_value(one.made_with.unwrap()).unwrap();
        assert_eq!(made.taken_from, Some(file.display().to_string()));
        assert_eq!(made.source_made_with, all.made_with);
        let e = take_trajectories(&file, 4).unwrap_err().to_string();
        assert!(e.contains("all.json") && e.contains("at most 3"), "{e}");
        let e = take_trajectories(&file, 0).unwrap_err().to_string();
        assert!(e.contains("trajectories"), "{e}");
    }
}
