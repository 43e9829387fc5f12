//! Diagnosis: how a saved final RED policy starts. For each road (track
//! seed) and reset seed given, the start (lateral offset in m, heading in
//! rad, speed in km/h), the distance driven, and every 4th step of the
//! first STEPS (80 by default) as `y/steer/pedal` (`TRACE_EVERY=N`: every
//! Nth step instead; 0 reads as 1). `TRACE_RAYS=1` adds the
//! start's lidar rays 6-13 (the fan's middle; ray 10 points 0.25 degrees
//! left of the heading, ray 9 as far right), as fractions of the range.
//! `cargo run --release -p red-experiments --example drive_trace --
//! RUN_DIR 23,101 1000,1001 [STEPS]`.
use red_drive::DriveConfig;
use red_experiments::drive::{drive_deterministic, load_run_policy};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        return Err(
            "usage: drive_trace RUN_DIR ROADS SEEDS [STEPS], e.g. RUN 23,101 1000,1001".into(),
        );
    }
    let dir = std::path::PathBuf::from(&args[0]);
    let roads: Vec<u64> = args[1]
        .split(',')
        .map(|s| s.parse())
        .collect::<Result<_, _>>()?;
    let seeds: Vec<u64> = args[2]
        .split(',')
        .map(|s| s.parse())
        .collect::<Result<_, _>>()?;
    let steps: usize = match args.get(3) {
        Some(s) => s.parse()?,
        None => 80,
    };
    let every: usize = match std::env::var("TRACE_EVERY") {
        Ok(s) => s
            .parse::<usize>()
            .map_err(|e| format!("TRACE_EVERY={s}: {e} (give a whole number >= 1)"))?
            .max(1),
        Err(_) => 4,
    };
    let (run, policy) = load_run_policy(&dir, "red", false)?;
    for &road in &roads {
        let cfg = DriveConfig {
            track_seed: road,
            ..run.drive.clone()
        };
        let hw = cfg.half_width();
        for &seed in &seeds {
            let (t, r) = drive_deterministic(&cfg, &policy, seed)?;
            let o0 = &t.observations[0];
            println!(
                "road {road} seed {seed}: start y {:+.2} hd {:+.3} v {:.1} -> {:.1} m",
                o0[20] * hw,
                o0[21] * cfg.heading_scale,
                o0[23] * cfg.max_speed * 3.6,
                r.true_return
            );
            if std::env::var_os("TRACE_RAYS").is_some() {
                let rays: Vec<String> = o0[6..14].iter().map(|r| format!("{r:.2}")).collect();
                println!("   start rays 6-13: {}", rays.join(" "));
            }
            let mut line = String::new();
            for i in (0..t.observations.len().min(steps)).step_by(every) {
                let o = &t.observations[i];
                let a = &t.actions[i];
                line.push_str(&format!("{:+.1}/{:+.2}/{:+.2} ", o[20] * hw, a[0], a[1]));
            }
            println!("   {line}");
        }
    }
    Ok(())
}
