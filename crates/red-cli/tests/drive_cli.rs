//! `red-cli drive expert` and `red-cli drive render` end to end: a
//! scripted and a person-like demo file carrying their road, a picture of
//! the size the options give, and a demo refused on another road.

use std::path::Path;
use std::process::{Command, Output};

use red_core::Demos;
use red_drive::{CONTROL_HZ, DriveConfig, RenderOptions};

fn cli(args: &[&str], files: &[&Path]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_red-cli"));
    c.arg("drive").args(args);
    for (flag, path) in ["--out", "--demo"].iter().zip(files) {
        c.arg(flag).arg(path);
    }
    c.output().unwrap()
}

fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

#[test]
fn expert_then_render_writes_a_demo_and_a_picture() {
    let dir = tempfile::tempdir().unwrap();
    let demo = dir.path().join("expert.json");
    let png = dir.path().join("expert.png");
    let expert = [
        "expert",
        "--episodes",
        "2",
        "--seed",
        "1",
        "--sig-digits",
        "6",
    ];
    ok(&cli(
        &[&expert[..], &["--track-seed", "5"]].concat(),
        &[&demo],
    ));
    let demos = Demos::read(&demo).unwrap();
    assert_eq!(demos.trajectories.len(), 2);
    assert_eq!(demos.control_hz, Some(CONTROL_HZ));
    let render = ["render", "--lidar-every", "50", "--strip-length", "500"];
    ok(&cli(&render, &[&png, &demo]));
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
    // A file without its road, drawn on another track, does not replay.
    let mut bare = demos.clone();
    bare.scenario = None;
    let bare_path = dir.path().join("bare.json");
    bare.write(&bare_path).unwrap();
    let o = cli(&["render", "--track-seed", "6"], &[&png, &bare_path]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("track"));
}

#[test]
fn human_style_writes_a_script_demo_that_carries_its_road() {
    let dir = tempfile::tempdir().unwrap();
    let demo = dir.path().join("human.json");
    let args = ["expert", "--style", "human", "--track-seed", "11"];
    let o = cli(&[&args[..], &["--sig-digits", "6"]].concat(), &[&demo]);
    ok(&o);
    assert!(String::from_utf8_lossy(&o.stdout).contains("finish"));
    let demos = Demos::read(&demo).unwrap();
    assert_eq!(demos.source, Some(red_core::DemoSource::Script));
    let (road, source) = red_drive::scenario::road_of(&demos).unwrap();
    assert_eq!(source, red_drive::scenario::RoadSource::File);
    assert_eq!(road.track_seed, 11);
    red_drive::scenario::check_fits(&road, &demos).unwrap();
    // Most steps steer 0: the wheel returns between taps.
    let t = &demos.trajectories[0];
    let zero = t.actions.iter().filter(|a| a[0] == 0.0).count();
    assert!(2 * zero > t.actions.len());
}
