//! Recording a person in the terminal (feature `terminal`): raw mode, the
//! keyboard through crossterm, the top-down view redrawn at 20 Hz, and the
//! [`Recorder`] stepped every tick.
//!
//! ```no_run
//! use std::sync::atomic::AtomicBool;
//! use red_drive::{DriveConfig, Recorder, terminal};
//!
//! let stop = AtomicBool::new(false);
//! let releases = terminal::reports_key_releases();
//! let mut rec = Recorder::new(&DriveConfig::default(), 0, releases)?;
//! terminal::drive(&mut rec, &stop)?;
//! rec.finish().write(std::path::Path::new("me.json"))?;
//! # Ok::<(), red_drive::Error>(())
//! ```

use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crossterm::event::{self, Event, KeyCode, KeyEventKind, KeyModifiers};
use crossterm::{cursor, execute, queue, style::Print, terminal};

use crate::Result;
use crate::config::CONTROL_HZ;
use crate::record::{
    DriveKey, KeyEvent, KeyKind, MIN_VIEW_ROWS, RecordStatus, Recorder, VIEW_AHEAD, view_scale,
};

/// Whether this terminal reports key releases (then [`Recorder::new`]
/// takes `key_releases = true` and a held arrow acts until released).
pub fn reports_key_releases() -> bool {
    terminal::supports_keyboard_enhancement().unwrap_or(false)
}

/// Raw mode, alternate screen and hidden cursor for the recording; undone
/// on drop, also when the recording fails.
struct Screen {
    enhanced: bool,
}

impl Screen {
    fn enter(enhanced: bool) -> Result<Self> {
        terminal::enable_raw_mode()?;
        let s = Self { enhanced };
        let mut out = std::io::stdout();
        execute!(out, terminal::EnterAlternateScreen, cursor::Hide)?;
        if enhanced {
            execute!(
                out,
                event::PushKeyboardEnhancementFlags(
                    event::KeyboardEnhancementFlags::REPORT_EVENT_TYPES
                )
            )?;
        }
        Ok(s)
    }
}

impl Drop for Screen {
    fn drop(&mut self) {
        let mut out = std::io::stdout();
        if self.enhanced {
            let _ = execute!(out, event::PopKeyboardEnhancementFlags);
        }
        let _ = execute!(out, cursor::Show, terminal::LeaveAlternateScreen);
        let _ = terminal::disable_raw_mode();
    }
}

fn to_drive_key(k: &event::KeyEvent) -> Option<KeyEvent> {
    let key = match k.code {
        KeyCode::Left => DriveKey::Left,
        KeyCode::Right => DriveKey::Right,
        KeyCode::Up => DriveKey::Up,
        KeyCode::Down => DriveKey::Down,
        KeyCode::Esc | KeyCode::Char('q') => DriveKey::Quit,
        KeyCode::Char('c') if k.modifiers.contains(KeyModifiers::CONTROL) => DriveKey::Quit,
        _ => return None,
    };
    let kind = match k.kind {
        KeyEventKind::Press => KeyKind::Press,
        KeyEventKind::Repeat => KeyKind::Repeat,
        KeyEventKind::Release => KeyKind::Release,
    };
    Some(KeyEvent { key, kind })
}

fn draw(rec: &Recorder, banner: &str) -> Result<()> {
    use crossterm::cursor::MoveTo;
    let (w, h) = terminal::size().unwrap_or((80, 24));
    let rows = usize::from(h).saturating_sub(3);
    let cols = usize::from(w).clamp(5, 45);
    let clip = |text: &str| -> String {
        let line = format!("{text:<w$}", w = usize::from(w));
        line.chars().take(usize::from(w)).collect()
    };
    let mut out = std::io::stdout();
    let banner = match (rec.view(rows, cols), view_scale(rows)) {
        (Some(view), Some(scale)) => {
            for (r, line) in view.iter().enumerate() {
                queue!(out, MoveTo(0, r as u16), Print(line))?;
            }
            format!("{banner}  [view: {VIEW_AHEAD:.0} m ahead, {scale:.1} m/row]")
        }
        _ => {
            queue!(out, terminal::Clear(terminal::ClearType::All))?;
            let lines = [
                format!(
                    "terminal too small: {h} lines; the view needs {} to show {VIEW_AHEAD:.0} m ahead.",
                    MIN_VIEW_ROWS + 3
                ),
                "Make the window taller (the drive goes on meanwhile; q stops).".to_string(),
            ];
            for (r, line) in lines.iter().enumerate() {
                queue!(out, MoveTo(0, r as u16), Print(clip(line)))?;
            }
            banner.to_string()
        }
    };
    let status = rec.status_line();
    let at = rows.max(2) as u16;
    queue!(
        out,
        MoveTo(0, at),
        Print(clip(&status)),
        MoveTo(0, at + 1),
        Print(clip(&banner))
    )?;
    out.flush()?;
    Ok(())
}

/// Waits for a key (or for `stop`) and returns it, `None` once `stop` is
/// raised.
fn wait_for_key(stop: &AtomicBool) -> Result<Option<event::KeyEvent>> {
    loop {
        if stop.load(Ordering::SeqCst) {
            return Ok(None);
        }
        if event::poll(Duration::from_millis(100))?
            && let Event::Key(k) = event::read()?
        {
            return Ok(Some(k));
        }
    }
}

/// The 20 Hz loop: gathers key events until each tick's deadline, then
/// steps the recorder. The first arrow key starts the clock and acts in
/// the first tick.
fn drive_loop(rec: &mut Recorder, stop: &AtomicBool) -> Result<()> {
    draw(rec, "arrows: steer/pedal; q, Esc: stop; an arrow starts")?;
    let mut events = Vec::new();
    loop {
        let Some(k) = wait_for_key(stop)? else {
            return Ok(());
        };
        match to_drive_key(&k) {
            Some(KeyEvent {
                key: DriveKey::Quit,
                ..
            }) => return Ok(()),
            Some(e) => {
                events.push(e);
                break;
            }
            None => {}
        }
    }
    let tick = Duration::from_secs_f64(1.0 / CONTROL_HZ);
    let mut next = Instant::now();
    loop {
        loop {
            let left = next.saturating_duration_since(Instant::now());
            if left.is_zero() || !event::poll(left)? {
                break;
            }
            if let Event::Key(k) = event::read()?
                && let Some(e) = to_drive_key(&k)
            {
                events.push(e);
            }
        }
        if stop.load(Ordering::SeqCst) {
            return Ok(());
        }
        let status = rec.tick(&events)?;
        events.clear();
        match status {
            RecordStatus::Driving => draw(rec, "driving")?,
            RecordStatus::Quit => return Ok(()),
            RecordStatus::Ended(_) => {
                draw(rec, &format!("{}. Press any key.", rec.end_line()))?;
                let _ = wait_for_key(stop);
                return Ok(());
            }
        }
        next += tick;
        // Fell behind (a slow terminal): do not try to catch up in a burst.
        let now = Instant::now();
        if next < now {
            next = now + tick;
        }
    }
}

/// Lets a person drive `rec` in this terminal (arrows: steer, more/less
/// accelerator; q, Esc or Ctrl-C: stop) until the episode ends, the driver
/// quits or `stop` is raised (a signal handler's flag: in raw mode Ctrl-C
/// arrives as a key, but SIGTERM and SIGHUP do not). The terminal is
/// restored on return, also on an error; `rec` keeps what was driven.
///
/// # Errors
/// [`crate::Error::Terminal`] if the terminal cannot enter raw mode, be
/// read or drawn; errors of [`Recorder::tick`].
pub fn drive(rec: &mut Recorder, stop: &AtomicBool) -> Result<()> {
    let _screen = Screen::enter(rec.key_releases())?;
    drive_loop(rec, stop)
}
