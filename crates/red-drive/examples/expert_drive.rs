//! The scripted expert on a road of your choice, saved as a demonstration
//! (which records its road) and drawn as a picture:
//! `cargo run --release -p red-drive --example expert_drive [TRACK_SEED]`.
use red_drive::render::demo_path;
use red_drive::{DriveConfig, RenderOptions, expert_demos, render_png};

fn main() -> red_drive::Result<()> {
    let track_seed = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let road = DriveConfig {
        track_seed,
        ..DriveConfig::default()
    };
    let demos = expert_demos(&road, 1, 0)?;
    let t = &demos.trajectories[0];
    println!(
        "track seed {track_seed}: {} steps, {:.1} m of {:.0} m",
        t.len(),
        t.true_return().unwrap_or(0.0),
        road.road_length
    );
    let dir = std::env::temp_dir();
    demos.write(&dir.join("expert.json"))?;
    let path = demo_path(&road, t, "expert", [20, 90, 200], 40)?;
    render_png(
        &dir.join("expert.png"),
        &road,
        &[path],
        &RenderOptions::default(),
    )?;
    println!("wrote {0}/expert.json and {0}/expert.png", dir.display());
    Ok(())
}
