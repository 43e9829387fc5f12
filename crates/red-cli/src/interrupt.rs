//! Ctrl-C for long commands: the first press asks the running command to
//! save a checkpoint and stop at its next safe point; a second press exits
//! at once (status 130), losing at most one checkpoint interval. SIGTERM
//! and SIGHUP (the terminal closing) count as Ctrl-C (`ctrlc`'s
//! `termination` feature).

use std::sync::Once;
use std::sync::atomic::{AtomicBool, Ordering};

static REQUESTED: AtomicBool = AtomicBool::new(false);
static INSTALL: Once = Once::new();

/// Installs the handler (once per process; later calls do nothing).
pub fn install() {
    INSTALL.call_once(|| {
        let result = ctrlc::set_handler(|| {
            if REQUESTED.swap(true, Ordering::SeqCst) {
                eprintln!("\nsecond interrupt: exiting without saving");
                std::process::exit(130);
            }
            eprintln!("\ninterrupt: saving and stopping (press Ctrl-C again to quit now)");
        });
        if let Err(e) = result {
            eprintln!("warning: cannot catch Ctrl-C ({e}); an interrupt will lose the work since the last checkpoint");
        }
    });
}

/// The flag a library run polls: raised by Ctrl-C.
pub fn flag() -> &'static AtomicBool {
    &REQUESTED
}

/// Asks the run to stop, as Ctrl-C does (tests use it to interrupt a run at
/// a known point).
#[allow(dead_code)] // only tests call it
pub fn request() {
    REQUESTED.store(true, Ordering::SeqCst);
}
