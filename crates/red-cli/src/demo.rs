//! `red-cli demo`: summary of a demonstration file; `red-cli demo import`;
//! `red-cli demo take`.

use std::path::PathBuf;

use anyhow::Context;
use clap::{Args, Subcommand};
use red_core::Demos;
use red_core::import::ImportFormat;

/// Arguments of `red-cli demo`.
#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct DemoArgs {
    #[command(subcommand)]
    command: Option<DemoCommand>,
    /// The demonstration file (the project's JSON format).
    pub file: Option<PathBuf>,
}

#[derive(Debug, Subcommand)]
enum DemoCommand {
    /// Convert demonstrations from another format into the project's.
    Import(ImportArgs),
    /// Keep the first K trajectories of a demo file.
    Take {
        /// Trajectories to keep.
        #[arg(long)]
        trajectories: usize,
        /// The demo file.
        file: PathBuf,
        /// Where to write them (never overwritten).
        #[arg(long)]
        out: PathBuf,
    },
}

/// Arguments of `red-cli demo import`.
#[derive(Debug, Args)]
struct ImportArgs {
    /// The file's format: `red-pickle` (the RED release's pickle) or
    /// `baselines-npz` (OpenAI baselines' expert `.npz`).
    #[arg(long, value_parser = |s: &str| s.parse::<ImportFormat>().map_err(|e| e.to_string()))]
    from: ImportFormat,
    /// The file to convert.
    file: PathBuf,
    /// The environment the demonstrations were made in (a MuJoCo task is
    /// written by its Gymnasium id, `hopper` -> `Hopper-v5`, and the file's
    /// dimensions are checked against it).
    #[arg(long)]
    env: String,
    /// Where to write the project's JSON file (never overwritten).
    #[arg(long)]
    out: PathBuf,
    /// Steps per trajectory of a RED pickle (default 1000, Reacher 50) or
    /// the time limit of a baselines `.npz` (default 1000).
    #[arg(long)]
    steps: Option<usize>,
}

/// Runs `red-cli demo`.
pub fn run(args: DemoArgs) -> anyhow::Result<()> {
    match (args.command, args.file) {
        (Some(DemoCommand::Import(a)), _) => import(a),
        (
            Some(DemoCommand::Take {
                trajectories,
                file,
                out,
            }),
            _,
        ) => {
            let demos = red_experiments::mujoco::demos::take_trajectories(&file, trajectories)?;
            red_experiments::mujoco::demos::write_new(&demos, &out)?;
            summary(&out)
        }
        (None, Some(file)) => summary(&file),
        (None, None) => anyhow::bail!("give a demo file (`red-cli demo FILE`) or `import`"),
    }
}

fn import(a: ImportArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        !a.out.exists(),
        "{} exists; choose another --out (nothing was written)",
        a.out.display()
    );
    let demos = red_experiments::mujoco::import_demos(a.from, &a.file, &a.env, a.steps)?;
    demos.write(&a.out)?;
    println!(
        "{}: {} -> {}",
        a.from.name(),
        a.file.display(),
        a.out.display()
    );
    summary(&a.out)
}

/// Prints the file's summary (header, lengths, returns).
fn summary(file: &std::path::Path) -> anyhow::Result<()> {
    let demos = Demos::read(file).with_context(|| format!("reading {}", file.display()))?;
    println!("{}: {}", file.display(), demos.summary());
    Ok(())
}
