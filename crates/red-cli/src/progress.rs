//! The CLI's [`Progress`] observer: an indicatif bar per run (one per
//! running cell of a grid, under one another), notes above it or on stderr,
//! and the hidden testing aids that raise the stop flag at a known point.

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use red_experiments::Progress;

use crate::interrupt;

/// A bar on stderr (hidden when `quiet` or not a terminal).
pub struct Bar {
    bar: Option<ProgressBar>,
    label: String,
    multi: Option<MultiProgress>,
    quiet: bool,
    last: u64,
    /// Raises the stop flag once this process has done this many more
    /// units of work (environment steps).
    interrupt_after: Option<u64>,
    /// Raises the stop flag once the run has reached this many units.
    pub stop_at: Option<u64>,
}

impl Bar {
    /// A bar; `interrupt_after` raises the stop flag once this many units
    /// of work (environment steps) have been done by this process.
    pub fn new(quiet: bool, interrupt_after: Option<u64>) -> Self {
        Self {
            bar: None,
            label: String::new(),
            multi: None,
            quiet,
            last: 0,
            interrupt_after,
            stop_at: None,
        }
    }

    /// A bar prefixed by `label` (notes too, when the bar is hidden),
    /// shown under the others of `multi`.
    pub fn labelled(label: String, multi: Option<&MultiProgress>) -> Self {
        let mut bar = Self::new(false, None);
        bar.label = label;
        bar.multi = multi.cloned();
        bar
    }
}

impl Progress for Bar {
    fn note(&mut self, text: &str) {
        match &self.bar {
            Some(b) if !b.is_hidden() => b.println(text),
            _ if self.label.is_empty() => eprintln!("{text}"),
            _ => eprintln!("{}: {text}", self.label),
        }
    }

    fn start(&mut self, label: &str, total: u64, done: u64) {
        let bar = match (&self.multi, self.quiet) {
            (_, true) => ProgressBar::hidden(),
            (Some(m), false) => m.add(ProgressBar::new(total)),
            (None, false) => ProgressBar::new(total),
        };
        let label = if self.label.is_empty() {
            label
        } else {
            &self.label
        };
        bar.set_style(
            ProgressStyle::with_template(&format!(
                "{label} {{bar:30}} {{pos}}/{{len}}, {{elapsed}} ({{eta}} left) {{msg}}"
            ))
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar.set_position(done);
        self.finish();
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
        if self.stop_at.is_some_and(|s| done >= s) {
            interrupt::request();
        }
        self.last = done;
    }

    fn finish(&mut self) {
        if let Some(b) = self.bar.take() {
            b.finish_and_clear();
            if let Some(m) = &self.multi {
                m.remove(&b);
            }
        }
    }
}

impl Drop for Bar {
    fn drop(&mut self) {
        self.finish();
    }
}
