//! The experiments of *Random Expert Distillation* (Wang et al., ICML 2019)
//! as library code. Each experiment takes a plain serde config, a stop flag
//! and a [`Progress`] observer, writes a run folder ([`run_dir::RunDir`])
//! and returns its outcome; `red-cli` is a thin front end over it.
//!
//! The driving experiment (paper Sec. 5.3) from Rust, on the shipped
//! demonstration, with a small budget:
//!
//! ```no_run
//! use std::sync::atomic::AtomicBool;
//! use red_experiments::drive::{self, DriveOutcome, DriveRunConfig};
//!
//! let (demos, road, _note) = drive::load_demo("data/drive-scripted-expert.json".as_ref(), None, false)?;
//! let mut config = DriveRunConfig::new("data/drive-scripted-expert.json", road);
//! config.train.steps = 3_000;
//! let stop = AtomicBool::new(false);
//! // A new folder (a folder holding a run is refused; Existing::MoveAside
//! // moves it aside), locked while the run lasts.
//! let out = red_experiments::RunDir::create(&std::env::temp_dir(), "red-drive-example")?;
//! match drive::run_new(config, &demos, out, &stop, &mut red_experiments::Silent)? {
//!     DriveOutcome::Finished(report) => print!("{}", report.table()),
//!     DriveOutcome::Stopped { .. } => unreachable!("nobody set the stop flag"),
//! }
//! # Ok::<(), red_experiments::Error>(())
//! ```

pub mod checks;
pub mod doctor;
pub mod drive;
pub mod error;
pub mod grid;
pub mod imitation;
pub mod mujoco;
pub mod plot;
pub mod run_dir;
pub mod stall;
pub mod support;
pub mod toy;

pub use error::{Error, Result, ResultExt};
pub use run_dir::RunDir;

// The exact versions of the crates this crate's API takes and returns,
// so that a dependant names the same types (a second version of ndarray or
// rand in a build gives type errors that never mention versions).
pub use ndarray;
pub use rand;
pub use rand_chacha;

/// What a long experiment tells its caller while it runs. Every method has
/// a default that does nothing; a front end draws bars or prints lines.
pub trait Progress: Send {
    /// A line of information (a fitted `σ1`, the road assumed, ...).
    fn note(&mut self, text: &str) {
        let _ = text;
    }
    /// A phase starts: `label`, `total` units of work, `done` of them
    /// already (a resumed run).
    fn start(&mut self, label: &str, total: u64, done: u64) {
        let _ = (label, total, done);
    }
    /// The current phase reached `done` units; `message` is a short
    /// summary (for example the recent return).
    fn advance(&mut self, done: u64, message: &str) {
        let _ = (done, message);
    }
    /// The current phase ended.
    fn finish(&mut self) {}
}

/// The cores this process may use (1 when unknown): the default number of
/// parallel runs or worker threads.
pub fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// A [`Progress`] that ignores everything.
#[derive(Debug, Default, Clone, Copy)]
pub struct Silent;

impl Progress for Silent {}
