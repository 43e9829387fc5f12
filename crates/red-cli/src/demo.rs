//! `red-cli demo`: summary of a demonstration file.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use red_core::Demos;

/// Arguments of `red-cli demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// The demonstration file (the project's JSON format).
    pub file: PathBuf,
}

/// Prints the header and per-trajectory lengths of a demo file.
pub fn run(args: DemoArgs) -> anyhow::Result<()> {
    let demos =
        Demos::read(&args.file).with_context(|| format!("reading {}", args.file.display()))?;
    println!(
        "{}: env {}, obs {} x act {}, {} trajectories, {} pairs",
        args.file.display(),
        demos.env_id,
        demos.obs_dim,
        demos.act_dim,
        demos.trajectories.len(),
        demos.num_pairs()
    );
    for (i, t) in demos.trajectories.iter().enumerate() {
        let ret = t.rewards.as_ref().map(|r| r.iter().sum::<f64>());
        match ret {
            Some(r) => println!(
                "  trajectory {i}: {} steps, {:?}, return {r:.3}",
                t.actions.len(),
                t.end
            ),
            None => println!("  trajectory {i}: {} steps, {:?}", t.actions.len(), t.end),
        }
    }
    Ok(())
}
