//! `red-cli drive`: the driving scenario (paper Sec. 5.3). Subcommands make
//! scripted demonstrations, record a person driving in the terminal, and
//! draw demonstrations as top-down pictures.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};

use crate::road::{TrackArgs, load_config};
use clap::{Args, CommandFactory, Subcommand};
use red_core::Demos;
use red_drive::record::{KeyKind, RecordStatus};
use red_drive::render::demo_path;
use red_drive::{
    CONTROL_HZ, DriveConfig, DriveKey, HumanConfig, KeyEvent, Recorder, RenderOptions,
    expert_demos, render_png,
};

/// Arguments of `red-cli drive`.
#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct DriveArgs {
    /// What to do.
    #[command(subcommand)]
    pub command: Option<DriveCommand>,
    /// Without a subcommand: train and evaluate on a demonstration.
    #[command(flatten)]
    pub train: crate::drive_train::TrainArgs,
}

/// The subcommands of `red-cli drive`.
#[derive(Debug, Subcommand)]
pub enum DriveCommand {
    /// Scripted demonstrations: an expert that knows the layout drives at
    /// about 100 km/h around the obstacles (`--style script`), or a
    /// person-like driver presses keys through the recorder (`--style
    /// human`).
    Expert(ExpertArgs),
    /// Drive yourself in the terminal (arrows: steer, more/less
    /// accelerator; q, Esc or Ctrl-C: stop) and save the demonstration.
    Record(RecordArgs),
    /// Draw a demonstration file's paths (and lidar rays) on its road as a
    /// PNG.
    Render(RenderArgs),
}

/// Arguments of `red-cli drive expert`.
#[derive(Debug, Args)]
pub struct ExpertArgs {
    /// Demonstration file to write.
    #[arg(long)]
    pub out: PathBuf,
    /// Number of episodes (each from its own reset seed).
    #[arg(long, default_value_t = 1)]
    pub episodes: usize,
    /// Seed of the episodes' start noise.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Round every number to this many significant digits (smaller files).
    #[arg(long)]
    pub sig_digits: Option<usize>,
    /// Who drives: `script`, the smooth expert that knows the whole layout,
    /// or `human`, a script that drives like a person at the keyboard
    /// (key taps through the recorder's key model, reaction delays, lane
    /// wobble, only the 100 m ahead in view; `red_drive::human`).
    #[arg(long, value_enum, default_value_t = ExpertStyle::Script)]
    pub style: ExpertStyle,
    /// The road.
    #[command(flatten)]
    pub track: TrackArgs,
}

/// Who drives in `red-cli drive expert`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ExpertStyle {
    /// The scripted expert ([`red_drive::Expert`]).
    Script,
    /// The person-like driver ([`red_drive::HumanDriver`]).
    Human,
}

/// Arguments of `red-cli drive record`.
#[derive(Debug, Args)]
pub struct RecordArgs {
    /// Demonstration file to write (on finish, quit or Ctrl-C).
    #[arg(long)]
    pub out: PathBuf,
    /// Seed of the start noise.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// The road.
    #[command(flatten)]
    pub track: TrackArgs,
}

/// Arguments of `red-cli drive render`.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Demonstration file; drawn on the road it records (files without
    /// one: the default road, or the one given below).
    #[arg(long)]
    pub demo: PathBuf,
    /// PNG to write.
    #[arg(long)]
    pub out: PathBuf,
    /// Draw the lidar rays every K steps (0: none).
    #[arg(long, default_value_t = 20)]
    pub lidar_every: usize,
    /// Metres of road per picture strip.
    #[arg(long, default_value_t = 250.0)]
    pub strip_length: f64,
    /// The road.
    #[command(flatten)]
    pub track: TrackArgs,
}

/// Runs `red-cli drive`.
pub fn run(args: DriveArgs) -> anyhow::Result<()> {
    match args.command {
        Some(DriveCommand::Expert(a)) => expert(a),
        Some(DriveCommand::Record(a)) => record(a),
        Some(DriveCommand::Render(a)) => render(a),
        None if args.train.demo.is_some() || args.train.resume.is_some() => {
            crate::drive_train::run(args.train)
        }
        None => {
            let mut cmd = crate::Cli::command();
            cmd.build();
            let drive = cmd
                .find_subcommand_mut("drive")
                .context("the drive subcommand is missing")?;
            drive.print_help()?;
            println!();
            Ok(())
        }
    }
}

fn round_sig(v: f64, digits: usize) -> f64 {
    if v == 0.0 || !v.is_finite() {
        return v;
    }
    format!("{v:.*e}", digits.saturating_sub(1))
        .parse()
        .unwrap_or(v)
}

fn expert(args: ExpertArgs) -> anyhow::Result<()> {
    let config = load_config(&args.track)?;
    if args.episodes == 0 {
        bail!("--episodes must be at least 1");
    }
    let mut demos = match args.style {
        ExpertStyle::Script => expert_demos(&config, args.episodes, args.seed)?,
        ExpertStyle::Human => {
            red_drive::human_demos(&config, &HumanConfig::default(), args.episodes, args.seed)?
        }
    };
    if let Some(d) = args.sig_digits {
        if d == 0 {
            bail!("--sig-digits must be at least 1");
        }
        for t in &mut demos.trajectories {
            for row in t.observations.iter_mut().chain(t.actions.iter_mut()) {
                for v in row.iter_mut() {
                    *v = round_sig(*v, d);
                }
            }
            if let Some(r) = &mut t.rewards {
                for v in r.iter_mut() {
                    *v = round_sig(*v, d);
                }
            }
        }
    }
    demos
        .write(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    let who = match args.style {
        ExpertStyle::Script => "scripted expert",
        ExpertStyle::Human => "person-like (human-style script)",
    };
    println!(
        "{}: {} {who} episode(s) on track seed {}",
        args.out.display(),
        demos.trajectories.len(),
        config.track_seed
    );
    summarise(&demos, &config);
    Ok(())
}

/// How an episode ended, from its end and distance: "finish", "crash" or
/// "time limit" / "stopped".
fn ending(t: &red_core::Trajectory, distance: f64, config: &DriveConfig) -> &'static str {
    match t.end {
        // The reward is the distance gained, so a finished episode sums to
        // the road's length (up to the rounding of --sig-digits).
        red_core::EpisodeEnd::Terminated if distance >= config.road_length - 1e-3 => "finish",
        red_core::EpisodeEnd::Terminated => "CRASH",
        red_core::EpisodeEnd::Truncated => "time limit or stopped",
    }
}

fn summarise(demos: &Demos, config: &DriveConfig) {
    for (i, t) in demos.trajectories.iter().enumerate() {
        let distance: f64 = t.rewards.as_ref().map_or(0.0, |r| r.iter().sum());
        println!(
            "  episode {i}: {} steps ({:.1} s), {}, distance {distance:.1} m of {:.0} m ({:.1}%)",
            t.actions.len(),
            t.actions.len() as f64 / CONTROL_HZ,
            ending(t, distance, config),
            config.road_length,
            100.0 * distance / config.road_length
        );
    }
}

fn render(args: RenderArgs) -> anyhow::Result<()> {
    let requested = args.track.requested()?;
    let (demos, config, note) = red_experiments::drive::load_demo(&args.demo, requested, false)?;
    if let Some(n) = note {
        eprintln!("note: {n}");
    }
    const COLOURS: [[u8; 3]; 6] = [
        [20, 90, 200],
        [230, 130, 0],
        [30, 150, 60],
        [150, 50, 170],
        [0, 160, 170],
        [120, 80, 40],
    ];
    let stem = args
        .demo
        .file_stem()
        .map_or_else(|| "demo".to_string(), |s| s.to_string_lossy().into_owned());
    let mut paths = Vec::new();
    for (i, t) in demos.trajectories.iter().enumerate() {
        let label = if demos.trajectories.len() == 1 {
            stem.clone()
        } else {
            format!("{stem} #{i}")
        };
        let spec = demo_path(
            &config,
            t,
            label,
            COLOURS[i % COLOURS.len()],
            args.lidar_every,
        )
        .with_context(|| format!("replaying trajectory {i} of {}", args.demo.display()))?;
        paths.push(spec);
    }
    let options = RenderOptions {
        strip_length: args.strip_length,
        ..RenderOptions::default()
    };
    render_png(&args.out, &config, &paths, &options)?;
    let (w, h) = options.image_size(&config);
    println!(
        "{}: {w} x {h} pixels, {} path(s) on track seed {}",
        args.out.display(),
        paths.len(),
        config.track_seed
    );
    Ok(())
}

/// Raw mode, alternate screen and hidden cursor for the recording; undone
/// on drop, also when the recording fails.
struct Terminal {
    enhanced: bool,
}

impl Terminal {
    fn enter(enhanced: bool) -> anyhow::Result<Self> {
        use crossterm::{cursor, event, execute, terminal};
        terminal::enable_raw_mode().context("the terminal cannot enter raw mode")?;
        let t = Self { enhanced };
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
        Ok(t)
    }
}

impl Drop for Terminal {
    fn drop(&mut self) {
        use crossterm::{cursor, event, execute, terminal};
        let mut out = std::io::stdout();
        if self.enhanced {
            let _ = execute!(out, event::PopKeyboardEnhancementFlags);
        }
        let _ = execute!(out, cursor::Show, terminal::LeaveAlternateScreen);
        let _ = terminal::disable_raw_mode();
    }
}

fn to_drive_key(k: &crossterm::event::KeyEvent) -> Option<KeyEvent> {
    use crossterm::event::{KeyCode, KeyEventKind, KeyModifiers};
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

fn draw(rec: &Recorder, banner: &str) -> anyhow::Result<()> {
    use crossterm::{cursor::MoveTo, queue, style::Print, terminal};
    use red_drive::record::{MIN_VIEW_ROWS, VIEW_AHEAD, view_scale};
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

/// Waits for a key (or an interrupt: Ctrl-C as a signal, SIGTERM, SIGHUP)
/// and returns it, `None` after an interrupt.
fn wait_for_key() -> anyhow::Result<Option<crossterm::event::KeyEvent>> {
    use crossterm::event::{self, Event};
    loop {
        if crate::interrupt::requested() {
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
/// the first tick. Returns when the episode ends, the driver quits or an
/// interrupt (SIGINT, SIGTERM, SIGHUP) arrives.
fn drive_loop(rec: &mut Recorder) -> anyhow::Result<()> {
    use crossterm::event::{self, Event};
    draw(rec, "arrows: steer/pedal; q, Esc: stop; an arrow starts")?;
    let mut events = Vec::new();
    loop {
        let Some(k) = wait_for_key()? else {
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
        if crate::interrupt::requested() {
            return Ok(());
        }
        let status = rec.tick(&events)?;
        events.clear();
        match status {
            RecordStatus::Driving => draw(rec, "driving")?,
            RecordStatus::Quit => return Ok(()),
            RecordStatus::Ended(_) => {
                draw(rec, &format!("{}. Press any key.", rec.end_line()))?;
                let _ = wait_for_key();
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

fn record(args: RecordArgs) -> anyhow::Result<()> {
    let config = load_config(&args.track)?;
    let enhanced = crossterm::terminal::supports_keyboard_enhancement().unwrap_or(false);
    let mut rec = Recorder::new(&config, args.seed, enhanced)?;
    // Ctrl-C arrives as a key in raw mode; this catches SIGTERM and SIGHUP
    // (the terminal closing), and SIGINT before raw mode, so that they save
    // the drive too.
    crate::interrupt::install();
    let outcome = {
        let _terminal = Terminal::enter(enhanced)?;
        drive_loop(&mut rec)
    };
    let end = match rec.status() {
        RecordStatus::Driving => format!("interrupted after {:.1} m", rec.distance()),
        _ => rec.end_line(),
    };
    let demos = rec.finish();
    let saved = save(&demos, &args.out);
    outcome?;
    saved?;
    println!("{}: {end}", args.out.display());
    summarise(&demos, &config);
    Ok(())
}

fn save(demos: &Demos, path: &Path) -> anyhow::Result<()> {
    if demos.trajectories.is_empty() {
        bail!("nothing was driven; {} not written", path.display());
    }
    demos
        .write(path)
        .with_context(|| format!("writing {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_keeps_significant_digits() {
        assert_eq!(round_sig(123.456789, 6), 123.457);
        assert_eq!(round_sig(-0.000123456789, 3), -0.000123);
        assert_eq!(round_sig(0.0, 6), 0.0);
    }

    #[test]
    fn expert_then_render_writes_a_demo_and_a_picture() {
        let dir = std::env::temp_dir().join(format!("red-cli-drive-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let demo = dir.join("expert.json");
        let png = dir.join("expert.png");
        let track = || TrackArgs {
            config: None,
            track_seed: Some(5),
        };
        expert(ExpertArgs {
            out: demo.clone(),
            episodes: 2,
            seed: 1,
            sig_digits: Some(6),
            style: ExpertStyle::Script,
            track: track(),
        })
        .unwrap();
        let demos = Demos::read(&demo).unwrap();
        assert_eq!(demos.trajectories.len(), 2);
        assert_eq!(demos.control_hz, Some(CONTROL_HZ));
        render(RenderArgs {
            demo: demo.clone(),
            out: png.clone(),
            lidar_every: 50,
            strip_length: 500.0,
            track: track(),
        })
        .unwrap();
        let options = RenderOptions {
            strip_length: 500.0,
            ..RenderOptions::default()
        };
        let config = DriveConfig {
            track_seed: 5,
            ..DriveConfig::default()
        };
        assert_eq!(
            red_drive::render::png_size(&png).unwrap(),
            options.image_size(&config)
        );
        // The same file on another track does not replay.
        let err = render(RenderArgs {
            demo,
            out: png,
            lidar_every: 0,
            strip_length: 500.0,
            track: TrackArgs {
                config: None,
                track_seed: Some(6),
            },
        });
        let _ = std::fs::remove_dir_all(&dir);
        assert!(format!("{:#}", err.unwrap_err()).contains("track"));
    }

    #[test]
    fn human_style_writes_a_script_demo_that_carries_its_road() {
        let dir = tempfile::tempdir().unwrap();
        let demo = dir.path().join("human.json");
        expert(ExpertArgs {
            out: demo.clone(),
            episodes: 1,
            seed: 0,
            sig_digits: Some(6),
            style: ExpertStyle::Human,
            track: TrackArgs {
                config: None,
                track_seed: Some(11),
            },
        })
        .unwrap();
        let demos = Demos::read(&demo).unwrap();
        assert_eq!(demos.source, Some(red_core::DemoSource::Script));
        let (road, source) = red_drive::scenario::road_of(&demos).unwrap();
        assert_eq!(source, red_drive::scenario::RoadSource::File);
        assert_eq!(road.track_seed, 11);
        red_drive::scenario::check_fits(&road, &demos).unwrap();
        let t = &demos.trajectories[0];
        let distance: f64 = t.rewards.as_ref().unwrap().iter().sum();
        assert_eq!(ending(t, distance, &road), "finish");
        // Most steps steer 0: the wheel returns between taps.
        let zero = t.actions.iter().filter(|a| a[0] == 0.0).count();
        assert!(2 * zero > t.actions.len());
    }
}
