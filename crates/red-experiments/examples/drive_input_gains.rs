//! Diagnosis: how strongly a saved final RED policy's steering responds to
//! each of its 24 observation inputs (a policy that also reads the last
//! action, `train.last_action_input`, has two more, left out here). For
//! each input: the demonstration's standard
//! deviation (the policy normaliser's, before any floor; over every pair
//! the run learnt from: the demo's states and any lane-moved, turned or
//! mirrored ones), the divisor the
//! normaliser uses (after the floors), and the median over states of
//! |d steer / d input| (the mean action's steering, per unit of the raw
//! observation, by a central difference of 1e-3), over the states the
//! policy itself visits driving the demo's road and the run's unseen roads
//! from the evaluation's starts (reset seeds 1000..). A ray the
//! demonstrator held nearly constant is divided by a tiny spread: a policy
//! that leans on it steers hard on small changes of it, and reads a lane
//! away from the demonstrator's as far outside its data.
//! `cargo run --release -p red-experiments --example drive_input_gains --
//! RUN_DIR [RUN_DIR ...]`.
use red_drive::{DriveConfig, OBS_DIM};
use red_experiments::drive::{EVAL_SEED, drive_deterministic, load_run_policy};

const STEP: f64 = 1e-3;

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dirs: Vec<String> = std::env::args().skip(1).collect();
    if dirs.is_empty() {
        return Err("usage: drive_input_gains RUN_DIR [RUN_DIR ...]".into());
    }
    for d in &dirs {
        let dir = std::path::PathBuf::from(d);
        let (run, policy) = load_run_policy(&dir, "red", false)?;
        let norm = policy.normalizer().ok_or("the policy has no normaliser")?;
        let data_std: Vec<f64> = norm.var().iter().map(|v| v.sqrt()).collect();
        let divisor = norm.stds();
        let mut roads = vec![(true, run.drive.track_seed)];
        roads.extend(run.unseen_track_seeds().into_iter().map(|r| (false, r)));
        // Per road kind (demo, unseen), per input, the |gains| over states.
        let mut gains = [vec![Vec::new(); OBS_DIM], vec![Vec::new(); OBS_DIM]];
        for &(demo, road) in &roads {
            let cfg = DriveConfig {
                track_seed: road,
                ..run.drive.clone()
            };
            for i in 0..run.eval_runs as u64 {
                let (t, _) = drive_deterministic(&cfg, &policy, EVAL_SEED + i)?;
                for o in &t.observations {
                    let mut x = o.clone();
                    for j in 0..OBS_DIM {
                        x[j] = o[j] + STEP;
                        let up = policy.act_deterministic(&x)?[0];
                        x[j] = o[j] - STEP;
                        let down = policy.act_deterministic(&x)?[0];
                        x[j] = o[j];
                        gains[usize::from(!demo)][j].push(((up - down) / (2.0 * STEP)).abs());
                    }
                }
            }
        }
        let [on_demo, on_unseen] = gains;
        println!("{d}");
        println!("input,demo_std,divisor,median_gain_demo_road,median_gain_unseen_roads");
        for (j, (a, b)) in on_demo.into_iter().zip(on_unseen).enumerate() {
            let name = match j {
                0..=19 => format!("ray{j}"),
                20 => "y".into(),
                21 => "heading".into(),
                22 => "wall_gap".into(),
                _ => "speed".into(),
            };
            println!(
                "{name},{:.4},{:.4},{:.2},{:.2}",
                data_std[j],
                divisor[j],
                median(a),
                median(b)
            );
        }
    }
    Ok(())
}
