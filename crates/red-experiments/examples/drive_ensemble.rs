//! Diagnosis: drives the mean action of several saved final policies (one
//! per run folder) on the first run's demo road and unseen roads, with the
//! evaluation's episodes, and each policy alone for comparison.
//! `cargo run --release -p red-experiments --example drive_ensemble -- DIR...`
use red_core::{Env, LastAction, record_episode};
use red_drive::{DriveConfig, make_env};
use red_experiments::drive::{DriveActor, EVAL_SEED, UNSEEN_FIRST_TRACK_SEED, load_run_policy};
use red_rl::policy::GaussianPolicy;

type AnyResult<T> = Result<T, Box<dyn std::error::Error>>;

fn distance(road: &DriveConfig, policies: &[&GaussianPolicy], seed: u64) -> AnyResult<f64> {
    // Every policy reads the same observation (main refuses a mix).
    let mut env = LastAction::new(make_env(road)?, policies[0].last_action_input())?;
    let (obs, _) = env.reset(Some(seed))?;
    let (_, run) = record_episode(
        &mut env,
        obs,
        None,
        |_, o| -> Result<Vec<f64>, Box<dyn std::error::Error>> {
            let mut mean = vec![0.0; red_drive::ACT_DIM];
            for p in policies {
                let a = p.act_deterministic(o)?;
                for (m, v) in mean.iter_mut().zip(a) {
                    *m += v / policies.len() as f64;
                }
            }
            Ok(mean)
        },
        |_, _| Ok(()),
    )?;
    Ok(run.true_return)
}

fn percent(road: &DriveConfig, policies: &[&GaussianPolicy]) -> AnyResult<f64> {
    let mut sum = 0.0;
    for i in 0..5 {
        sum += distance(road, policies, EVAL_SEED + i)?;
    }
    Ok(100.0 * sum / 5.0 / road.road_length)
}

fn report(road: &DriveConfig, policies: &[&GaussianPolicy]) -> AnyResult<(f64, f64)> {
    let demo = percent(road, policies)?;
    let mut unseen = 0.0;
    for k in 0..10 {
        let r = DriveConfig {
            track_seed: UNSEEN_FIRST_TRACK_SEED + k,
            ..road.clone()
        };
        unseen += percent(&r, policies)? / 10.0;
    }
    Ok((demo, unseen))
}

fn main() -> AnyResult<()> {
    let dirs: Vec<String> = std::env::args().skip(1).collect();
    let mut loaded = Vec::new();
    for d in &dirs {
        loaded.push(load_run_policy(std::path::Path::new(d), "red", false)?);
    }
    let road = loaded[0].0.drive.clone();
    let policies: Vec<&GaussianPolicy> = loaded.iter().map(|(_, p)| p).collect();
    if policies
        .iter()
        .any(|p| p.last_action_input() != policies[0].last_action_input())
    {
        return Err(
            "the runs differ in train.last_action_input: their policies read \
                    different observations"
                .into(),
        );
    }
    for (d, p) in dirs.iter().zip(&policies) {
        let (a, b) = report(&road, &[p])?;
        println!("{d}: {a:.1} | {b:.1}");
    }
    let (a, b) = report(&road, &policies)?;
    println!("mean action of {}: {a:.1} | {b:.1}", policies.len());
    Ok(())
}
