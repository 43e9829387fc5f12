//! Drives finished runs' saved final RED policies again (the evaluation's
//! episodes: the demo's road and the unseen roads) and prints each road's
//! % and how every episode ended, through
//! [`red_experiments::drive::eval_saved`].
//! `cargo run --release -p red-experiments --example drive_eval_saved --
//! RUN_DIR...`
use red_experiments::drive::{EvalRequest, eval_saved};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let runs: Vec<String> = std::env::args().skip(1).collect();
    if runs.is_empty() {
        return Err("usage: drive_eval_saved RUN_DIR...".into());
    }
    let req = EvalRequest {
        method: "red".into(),
        ..EvalRequest::default()
    };
    for d in &runs {
        println!("== {d}");
        print!("{}", eval_saved(std::path::Path::new(d), &req)?);
    }
    Ok(())
}
