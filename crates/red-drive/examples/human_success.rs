//! The person-like driver's success rate over track seeds, with its
//! failures: `cargo run --release -p red-drive --example human_success -- 0 50`
//! (track seeds 0..50); add `releases` for a terminal that reports key
//! releases.

use red_drive::DriveConfig;
use red_drive::human::{HumanConfig, human_success};

fn main() -> Result<(), red_drive::Error> {
    let args: Vec<u64> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let (lo, hi) = match args[..] {
        [lo, hi] => (lo, hi),
        _ => (0, 50),
    };
    let human = HumanConfig {
        key_releases: std::env::args().any(|a| a == "releases"),
        ..HumanConfig::default()
    };
    let results = human_success(&DriveConfig::default(), &human, lo..hi)?;
    let done = results.iter().filter(|(_, e)| e.success).count();
    for (s, e) in &results {
        if !e.success {
            println!(
                "track seed {s}: stopped at {:.1} m after {} steps",
                e.distance, e.steps
            );
        }
    }
    let steps: Vec<usize> = results
        .iter()
        .filter(|(_, e)| e.success)
        .map(|(_, e)| e.steps)
        .collect();
    println!(
        "finished {done}/{} roads (track seeds {lo}..{hi}, key releases {}); steps of finished runs {:?}..={:?}",
        results.len(),
        human.key_releases,
        steps.iter().min(),
        steps.iter().max()
    );
    Ok(())
}
