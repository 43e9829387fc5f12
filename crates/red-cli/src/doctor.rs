//! `red-cli doctor`: a check of the whole install, with what to do about
//! each problem found.

use std::time::Instant;

use clap::Args;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use red_core::Env;
use red_mujoco::EnvId;

/// Arguments of `red-cli doctor`.
#[derive(Debug, Args)]
pub struct DoctorArgs {
    /// Steps of the tiny run of each environment.
    #[arg(long, default_value_t = 200)]
    pub steps: usize,
}

/// Plays `steps` random steps, resetting at episode ends; returns steps/s.
fn tiny_run<E: Env + ?Sized>(env: &mut E, steps: usize) -> anyhow::Result<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    env.reset(Some(0))?;
    let start = Instant::now();
    for _ in 0..steps {
        let action = env.action_space().sample(&mut rng);
        let step = env.step(&action)?;
        anyhow::ensure!(
            step.observation.iter().all(|v| v.is_finite()) && step.reward.is_finite(),
            "non-finite observation or reward"
        );
        if step.terminated || step.truncated {
            env.reset(Some(rng.random()))?;
        }
    }
    Ok(steps as f64 / start.elapsed().as_secs_f64().max(1e-9))
}

/// Prints the report; fails if any check failed.
///
/// # Errors
/// When a check fails (after printing every check).
pub fn run(args: DoctorArgs) -> anyhow::Result<()> {
    anyhow::ensure!(args.steps > 0, "--steps: must be at least 1");
    let mut problems = Vec::new();
    println!("red-cli {}", env!("CARGO_PKG_VERSION"));
    println!(
        "threads available: {}",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );

    let found = red_mujoco::library_version();
    let expected = red_mujoco::EXPECTED_LIBRARY_VERSION;
    let mark = if found == expected { "ok" } else { "MISMATCH" };
    println!("MuJoCo library: {found} (bindings expect {expected}) {mark}");
    if let Some(dir) = option_env!("MUJOCO_DYNAMIC_LINK_DIR") {
        println!("  linked from: {dir}");
    }
    if found != expected {
        problems.push(format!(
            "MuJoCo {found} was loaded but {expected} is needed: run scripts/setup-mujoco.sh --force"
        ));
    }

    match red_mujoco::assets::assets_dir() {
        Some((dir, source)) => println!("model files: {} ({source})", dir.display()),
        None => {
            println!("model files: no folder configured");
            problems.push("no model folder: run scripts/setup-mujoco.sh".into());
        }
    }

    println!(
        "tiny run of each environment ({} random steps):",
        args.steps
    );
    for id in EnvId::ALL {
        match id
            .make()
            .map_err(anyhow::Error::from)
            .and_then(|mut env| tiny_run(&mut env, args.steps))
        {
            Ok(rate) => println!("  {:<16} ok  {rate:>10.0} steps/s", id.name()),
            Err(e) => {
                println!("  {:<16} FAILED: {e:#}", id.name());
                problems.push(format!(
                    "{} does not run ({e:#}): run scripts/setup-mujoco.sh",
                    id.name()
                ));
            }
        }
    }
    let drive = red_drive::make_env(&red_drive::DriveConfig::default())
        .map_err(anyhow::Error::from)
        .and_then(|mut env| tiny_run(&mut env, args.steps));
    match drive {
        Ok(rate) => println!("  {:<16} ok  {rate:>10.0} steps/s", "drive"),
        Err(e) => {
            println!("  {:<16} FAILED: {e:#}", "drive");
            problems.push(format!("the driving scenario does not run: {e:#}"));
        }
    }

    if problems.is_empty() {
        println!("everything works");
        Ok(())
    } else {
        for p in &problems {
            eprintln!("problem: {p}");
        }
        anyhow::bail!("{} problem(s) found", problems.len())
    }
}
