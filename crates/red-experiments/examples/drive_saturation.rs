//! Diagnosis: how often a saved final RED policy's inputs lie beyond its
//! normaliser's clip (±5 standard deviations of the demonstration's
//! states), on the demo's road and the run's unseen roads, reset seeds
//! 1000.. as the evaluation drives them. Per input group (the 20 rays, y,
//! heading, the wall gap, the speed): the share of steps beyond the clip
//! in finishing episodes, in the other episodes, and in the last 40 steps
//! (2 s) before each crash or stop.
//! `cargo run --release -p red-experiments --example drive_saturation --
//! RUN_DIR [RUN_DIR ...]`.
use red_drive::DriveConfig;
use red_experiments::drive::{EVAL_SEED, drive_deterministic, load_run_policy};

const GROUPS: [&str; 5] = ["rays", "y", "heading", "wallgap", "speed"];

fn group(j: usize) -> usize {
    if j < 20 { 0 } else { j - 19 }
}

#[derive(Default)]
struct Count {
    steps: usize,
    beyond: [usize; 5],
}

impl Count {
    fn add(&mut self, z: &[f64], clip: f64) {
        self.steps += 1;
        let mut hit = [false; 5];
        for (j, v) in z.iter().enumerate() {
            if v.abs() >= clip {
                hit[group(j)] = true;
            }
        }
        for (b, h) in self.beyond.iter_mut().zip(hit) {
            *b += usize::from(h);
        }
    }

    fn line(&self) -> String {
        let n = self.steps.max(1) as f64;
        let parts: Vec<String> = GROUPS
            .iter()
            .zip(self.beyond)
            .map(|(g, b)| format!("{g} {:.1}%", 100.0 * b as f64 / n))
            .collect();
        format!("{} steps: {}", self.steps, parts.join(", "))
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dirs: Vec<String> = std::env::args().skip(1).collect();
    if dirs.is_empty() {
        return Err("usage: drive_saturation RUN_DIR [RUN_DIR ...]".into());
    }
    for d in &dirs {
        let dir = std::path::PathBuf::from(d);
        let (run, policy) = load_run_policy(&dir, "red", false)?;
        let norm = policy.normalizer().ok_or("the policy has no normaliser")?;
        let (mean, std) = (norm.mean().to_vec(), norm.stds());
        let clip = red_rl::normalize::DEFAULT_CLIP;
        let mut roads = vec![run.drive.track_seed];
        roads.extend(run.unseen_track_seeds());
        let (mut fin, mut other, mut last) = (Count::default(), Count::default(), Count::default());
        let mut ends = 0;
        for (k, &road) in roads.iter().enumerate() {
            let cfg = DriveConfig {
                track_seed: road,
                ..run.drive.clone()
            };
            for i in 0..run.eval_runs as u64 {
                let (t, r) = drive_deterministic(&cfg, &policy, EVAL_SEED + i)?;
                let finished = r.true_return >= 0.999 * cfg.road_length;
                let zs: Vec<Vec<f64>> = t
                    .observations
                    .iter()
                    .map(|o| {
                        o.iter()
                            .enumerate()
                            .map(|(j, v)| (v - mean[j]) / std[j])
                            .collect()
                    })
                    .collect();
                let n = zs.len();
                for (s, z) in zs.iter().enumerate() {
                    if finished {
                        fin.add(z, clip);
                    } else {
                        other.add(z, clip);
                        if s + 40 >= n {
                            last.add(z, clip);
                        }
                    }
                }
                if !finished {
                    ends += 1;
                    if k == 0 {
                        let zl = &zs[n - 1];
                        println!(
                            "{d}: demo road, reset {}: ends at {:.1} m; last z: y {:+.1} heading {:+.1} speed {:+.1}",
                            EVAL_SEED + i,
                            r.true_return,
                            zl[20],
                            zl[21],
                            zl[23]
                        );
                    }
                }
            }
        }
        println!("{d}: finishing episodes: {}", fin.line());
        println!("{d}: other episodes ({ends}): {}", other.line());
        println!("{d}: their last 40 steps: {}", last.line());
    }
    Ok(())
}
