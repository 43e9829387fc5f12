//! The CLI's [`Progress`] observer: an indicatif bar per phase, notes on
//! stderr, and the hidden `--interrupt-after` testing aid.

use indicatif::{ProgressBar, ProgressStyle};
use red_experiments::Progress;

use crate::interrupt;

/// Bars on stderr (none when `quiet`).
pub struct Bar {
    bar: Option<ProgressBar>,
    last: u64,
    quiet: bool,
    interrupt_after: Option<u64>,
}

impl Bar {
    /// A bar; `interrupt_after` raises the stop flag once this many units
    /// of work (environment steps) have been done by this process.
    pub fn new(quiet: bool, interrupt_after: Option<u64>) -> Self {
        Self {
            bar: None,
            last: 0,
            quiet,
            interrupt_after,
        }
    }
}

impl Progress for Bar {
    fn note(&mut self, text: &str) {
        eprintln!("{text}");
    }

    fn start(&mut self, label: &str, total: u64, done: u64) {
        let bar = if self.quiet {
            ProgressBar::hidden()
        } else {
            ProgressBar::new(total)
        };
        bar.set_style(
            ProgressStyle::with_template(&format!(
                "{label} {{bar:30}} {{pos}}/{{len}}, {{elapsed}} ({{eta}} left) {{msg}}"
            ))
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar.set_position(done);
        self.bar = Some(bar);
        self.last = done;
    }

    fn advance(&mut self, done: u64, message: &str) {
        if let Some(b) = &self.bar {
            b.set_position(done);
            b.set_message(message.to_string());
        }
        if let Some(n) = self.interrupt_after.as_mut() {
            *n = n.saturating_sub(done.saturating_sub(self.last));
            if *n == 0 {
                interrupt::request();
            }
        }
        self.last = done;
    }

    fn finish(&mut self) {
        if let Some(b) = self.bar.take() {
            b.finish_and_clear();
        }
    }
}
