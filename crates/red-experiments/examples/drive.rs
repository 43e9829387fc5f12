//! The driving experiment from Rust: RED and BC on the shipped
//! demonstration, on the road the file records, with the table printed.
//! `cargo run --release -p red-experiments --example drive [DEMO] [STEPS]`
use std::sync::atomic::AtomicBool;

use red_experiments::drive::{self, DriveOutcome, DriveRunConfig};

fn main() -> Result<(), red_experiments::Error> {
    let mut args = std::env::args().skip(1);
    let demo = args
        .next()
        .unwrap_or_else(|| "data/drive-scripted-expert.json".into());
    let (demos, road, note) = drive::load_demo(demo.as_ref(), None, false)?;
    if let Some(n) = note {
        eprintln!("note: {n}");
    }
    let mut config = DriveRunConfig::new(demo, road);
    if let Some(steps) = args.next().and_then(|s| s.parse().ok()) {
        config.train.steps = steps;
    }
    let stop = AtomicBool::new(false);
    let out = red_experiments::RunDir::create("runs".as_ref(), "example-drive")?;
    match drive::run_new(config, &demos, out, &stop, &mut red_experiments::Silent)? {
        DriveOutcome::Finished(report) => print!("{}", report.table()),
        DriveOutcome::Stopped { checkpoint, .. } => eprintln!("stopped: {}", checkpoint.display()),
    }
    Ok(())
}
