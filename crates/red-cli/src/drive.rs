//! `red-cli drive`: the driving scenario (paper Sec. 5.3). Subcommands make
//! scripted demonstrations, record a person driving in the terminal, and
//! draw demonstrations as top-down pictures.

use std::path::PathBuf;

use anyhow::{Context, bail};

use crate::road::{TrackArgs, load_config};
use clap::{Args, CommandFactory, Subcommand};
use red_core::Demos;
use red_drive::record::RecordStatus;
use red_drive::render::demo_paths;
use red_drive::scenario::episode_lines;
use red_drive::{DriveConfig, ExpertStyle, Recorder, RenderOptions, render_png, terminal};

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
    #[arg(long, default_value = "script")]
    pub style: ExpertStyle,
    /// The road.
    #[command(flatten)]
    pub track: TrackArgs,
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

fn expert(args: ExpertArgs) -> anyhow::Result<()> {
    let config = load_config(&args.track)?;
    if args.episodes == 0 {
        bail!("--episodes must be at least 1");
    }
    let mut demos = args.style.demos(&config, args.episodes, args.seed)?;
    if let Some(d) = args.sig_digits {
        demos
            .round_to_significant(d)
            .map_err(|_| anyhow::anyhow!("--sig-digits must be at least 1"))?;
    }
    demos
        .write(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    println!(
        "{}: {} {} episode(s) on track seed {}",
        args.out.display(),
        demos.trajectories.len(),
        args.style.who(),
        config.track_seed
    );
    summarise(&demos, &config);
    Ok(())
}

fn summarise(demos: &Demos, config: &DriveConfig) {
    for line in episode_lines(demos, config) {
        println!("  {line}");
    }
}

fn render(args: RenderArgs) -> anyhow::Result<()> {
    let requested = args.track.requested()?;
    let (demos, config, note) = red_experiments::drive::load_demo(&args.demo, requested, false)?;
    if let Some(n) = note {
        eprintln!("note: {n}");
    }
    let stem = args
        .demo
        .file_stem()
        .map_or_else(|| "demo".to_string(), |s| s.to_string_lossy().into_owned());
    let paths = demo_paths(&config, &demos, &stem, args.lidar_every)
        .with_context(|| format!("replaying {}", args.demo.display()))?;
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

fn record(args: RecordArgs) -> anyhow::Result<()> {
    let config = load_config(&args.track)?;
    let mut rec = Recorder::new(&config, args.seed, terminal::reports_key_releases())?;
    // Ctrl-C arrives as a key in raw mode; this catches SIGTERM and SIGHUP
    // (the terminal closing), and SIGINT before raw mode, so that they save
    // the drive too.
    crate::interrupt::install();
    let outcome = terminal::drive(&mut rec, crate::interrupt::flag());
    let end = match rec.status() {
        RecordStatus::Driving => format!("interrupted after {:.1} m", rec.distance()),
        _ => rec.end_line(),
    };
    let demos = rec.finish();
    let saved = if demos.trajectories.is_empty() {
        Err(anyhow::anyhow!(
            "nothing was driven; {} not written",
            args.out.display()
        ))
    } else {
        demos
            .write(&args.out)
            .with_context(|| format!("writing {}", args.out.display()))
    };
    outcome?;
    saved?;
    println!("{}: {end}", args.out.display());
    summarise(&demos, &config);
    Ok(())
}
