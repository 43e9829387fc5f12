//! `red-cli`: the command-line tool of the red workspace. It composes the
//! library crates and holds no algorithm of its own: each subcommand lives
//! in a module of its own (`drive.rs`, `support.rs`, ...).

use clap::{Parser, Subcommand};

/// Imitation learning from a handful of demonstrations with Random Expert
/// Distillation (RED).
#[derive(Debug, Parser)]
#[command(name = "red-cli", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Inspect a demonstration file: environment, dimensions, trajectories.
    Demo(demo::DemoArgs),
    /// Support estimation: fit RND, AE or kernel PCA on a demo file; score
    /// pairs and RED's reward with a fitted model.
    Support(support::SupportArgs),
    /// The driving scenario (paper Sec. 5.3): scripted demonstrations,
    /// recording a person in the terminal, pictures of driven paths.
    Drive(drive::DriveArgs),
    /// The simple domain of the paper's Sec. 5.1: DQN with RED, AE, GAIL and
    /// GMMIL rewards (Fig. 2 and 3).
    Toy(toy::ToyArgs),
    /// Check the whole install: MuJoCo library version, model files,
    /// threads, and a tiny run of every environment.
    Doctor(doctor::DoctorArgs),
    /// The MuJoCo tasks (Gymnasium -v5, paper Sec. 5.2): check the set-up,
    /// train experts, imitate, evaluate, run Table 1.
    Mujoco(mujoco::MujocoArgs),
}

mod demo;
mod doctor;
mod drive;
mod drive_train;
mod interrupt;
mod mujoco;
mod progress;
mod road;
mod support;
mod toy;

/// A config error named by its command-line flag (`gamma` -> `--gamma`),
/// other errors as they are.
pub(crate) fn flag_error(e: red_experiments::Error) -> anyhow::Error {
    match e {
        red_experiments::Error::InvalidConfig { field, reason } => {
            anyhow::anyhow!("--{}: {reason}", field.replace('_', "-"))
        }
        other => other.into(),
    }
}

/// The text of the file a flag names, if it names one.
pub(crate) fn read_text(path: Option<&std::path::Path>) -> anyhow::Result<Option<String>> {
    let read = |p: &std::path::Path| {
        std::fs::read_to_string(p).map_err(|e| anyhow::anyhow!("reading {}: {e}", p.display()))
    };
    path.map(read).transpose()
}

/// The config in the JSON file a flag names (missing fields take their
/// defaults), or the defaults.
pub(crate) fn read_json<T: serde::de::DeserializeOwned + Default>(
    path: Option<&std::path::Path>,
    what: &str,
) -> anyhow::Result<T> {
    let read =
        |p| red_experiments::run_dir::read_json(p).map_err(|e| anyhow::anyhow!("{what}: {e}"));
    Ok(path.map(read).transpose()?.unwrap_or_default())
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Demo(args) => demo::run(args),
        Command::Doctor(args) => doctor::run(args),
        Command::Support(args) => support::run(args),
        Command::Drive(args) => drive::run(args),
        Command::Toy(args) => toy::run(args),
        Command::Mujoco(args) => mujoco::run(args),
    }
}
