//! Diagnosis: RED's driving reward as run seed K fits it (the defaults'
//! RND, `σ1` and terminal heuristic, the run's estimator stream), read
//! along the episodes of saved final policies on the demo's road.
//! `cargo run --release -p red-experiments --example drive_reward_probe --
//! DEMO --seeds 1,3,4 RUN_DIR...`: for each reward seed, `σ1` and for each
//! run folder's final RED policy (reset seed 1000, the evaluation's first
//! episode) the distance, the mean reward of the episode, of its last 40
//! steps and of its last pair, and whether the paper's terminal test
//! penalises the ending. `PROBE_CHUNKS=1` adds, per 50 steps, the mean
//! reward, lateral offset (m) and speed (km/h) as `reward@y/kmh`. The
//! reward is fitted on the recorded pairs only: a run whose demonstration
//! got lane-moved pairs (`train.lane_shift_clear_steps`, a one-lane demo
//! such as s37 at the defaults since session 59) or turned pairs
//! (`train.heading_turns`) fitted on more.
use ndarray::Array2;
use red_experiments::drive::{
    DriveTrainConfig, EVAL_SEED, drive_deterministic, load_demo, load_run_policy, run_reward,
};
use red_experiments::imitation::Method;

type AnyResult<T> = Result<T, Box<dyn std::error::Error>>;

fn main() -> AnyResult<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 4 || args[1] != "--seeds" {
        return Err("usage: drive_reward_probe DEMO --seeds 1,3,4 RUN_DIR...".into());
    }
    let demo_path = std::path::PathBuf::from(&args[0]);
    let seeds: Vec<u64> = args[2]
        .split(',')
        .map(|s| s.parse())
        .collect::<Result<_, _>>()?;
    let runs = &args[3..];
    let mut episodes = Vec::new();
    let mut road = None;
    for d in runs {
        let (run, policy) = load_run_policy(std::path::Path::new(d), "red", false)?;
        if run.train.last_action_input {
            return Err(format!(
                "{d}: its policy read the last action (train.last_action_input); this probe \
                 fits rewards on the recorded 24-number observations"
            )
            .into());
        }
        if run.train.kernel_pca.is_some() {
            return Err(
                format!("{d}: RED fitted kernel PCA there; this probe fits RND rewards").into(),
            );
        }
        let (t, r) = drive_deterministic(&run.drive, &policy, EVAL_SEED)?;
        road.get_or_insert(run.drive.clone());
        episodes.push((d.clone(), t, r));
    }
    let road = road.ok_or("give at least one run folder")?;
    let (demos, _, _) = load_demo(&demo_path, Some(road.clone()), false)?;
    let (es, ea) = demos.pairs();
    let cfg = DriveTrainConfig::default();
    for &seed in &seeds {
        let (reward, term) = run_reward(&cfg, Method::Red, seed, es.view(), ea.view())?;
        let r = reward.support().ok_or("not RED")?;
        let term = term.ok_or("no terminal heuristic")?;
        println!(
            "reward seed {seed}: sigma1 {:.1}, mean demo reward {:.3}",
            r.sigma1(),
            term.expert_mean_reward()
        );
        for (d, t, run) in &episodes {
            let n = t.observations.len();
            let s = Array2::from_shape_fn((n, es.ncols()), |(i, j)| t.observations[i][j]);
            let a = Array2::from_shape_fn((n, ea.ncols()), |(i, j)| t.actions[i][j]);
            let v = r.reward(s.view(), a.view())?;
            let k = n.saturating_sub(40);
            let tail = v.slice(ndarray::s![k..]).mean().unwrap_or(f64::NAN);
            let last = v[n - 1];
            println!(
                "  {d}: {:.1} m, mean reward {:.3}, last 40 steps {tail:.3}, last pair {last:.3}, \
                 terminal penalty {:.1}",
                run.true_return,
                v.mean().unwrap_or(f64::NAN),
                term.penalty(last)
            );
            if std::env::var_os("PROBE_CHUNKS").is_some() {
                // Mean reward, lateral offset (m) and speed (km/h) per 50
                // steps.
                let half = road.half_width();
                let line: Vec<String> = (0..n)
                    .step_by(50)
                    .map(|c| {
                        let e = (c + 50).min(n);
                        let mean =
                            |j: usize| s.slice(ndarray::s![c..e, j]).mean().unwrap_or(f64::NAN);
                        let rm = v.slice(ndarray::s![c..e]).mean().unwrap_or(f64::NAN);
                        let (y, kmh) = (mean(20) * half, mean(23) * road.max_speed * 3.6);
                        format!("{rm:.2}@{y:+.1}/{kmh:.0}")
                    })
                    .collect();
                println!("    {}", line.join(" "));
            }
        }
    }
    Ok(())
}
