//! `red-cli doctor`: a check of the whole install
//! (`red_experiments::doctor`), with what to do about each problem found.

use clap::Args;

/// Arguments of `red-cli doctor`.
#[derive(Debug, Args)]
pub struct DoctorArgs {
    /// Steps of the tiny run of each environment.
    #[arg(long, default_value_t = 200)]
    pub steps: usize,
}

/// Prints the report; fails if any check failed.
///
/// # Errors
/// When a check fails (after printing every check).
pub fn run(args: DoctorArgs) -> anyhow::Result<()> {
    anyhow::ensure!(args.steps > 0, "--steps: must be at least 1");
    println!("red-cli {}", env!("CARGO_PKG_VERSION"));
    println!("threads available: {}", red_experiments::cores());
    let report = red_experiments::doctor::check_install(args.steps);
    for line in &report.lines {
        println!("{line}");
    }
    if report.problems.is_empty() {
        println!("everything works");
        return Ok(());
    }
    for p in &report.problems {
        eprintln!("problem: {p}");
    }
    anyhow::bail!("{} problem(s) found", report.problems.len())
}
