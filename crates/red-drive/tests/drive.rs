//! Evidence for the driving scenario: env checks, collisions, lidar
//! accuracy, the expert's completion rate, the recorder round trip and the
//! rendered picture.

use red_core::{Demos, Env, EpisodeEnd};
use red_drive::env::{INFO_COLLISION, INFO_DISTANCE, INFO_PROGRESS, INFO_SUCCESS};
use red_drive::expert::expert_success;
use red_drive::record::{DriveKey, KeyEvent, KeyKind, RecordStatus};
use red_drive::render::{demo_path, png_size};
use red_drive::{
    CarState, DriveConfig, DriveEnv, NUM_RAYS, Recorder, RenderOptions, expert_demos, make_env,
    render_png,
};

fn quiet() -> DriveConfig {
    DriveConfig {
        start_lateral_noise: 0.0,
        start_heading_noise: 0.0,
        start_speed_noise: 0.0,
        ..Default::default()
    }
}

#[test]
fn env_passes_the_env_checker() {
    let mut env = make_env(&DriveConfig::default()).unwrap();
    let report = red_core::check::check_env(&mut env, 3, 400).unwrap();
    assert!(report.terminated >= 2, "{report}");
    assert_eq!(report.after_end, red_core::check::AfterEnd::NeedsReset);
    for key in [INFO_PROGRESS, INFO_DISTANCE, INFO_SUCCESS, INFO_COLLISION] {
        assert!(report.info_keys.contains(&key), "{report}");
    }
    // A short time limit: truncated episodes too.
    let mut env = make_env(&DriveConfig {
        time_limit: 4,
        ..Default::default()
    })
    .unwrap();
    let report = red_core::check::check_env(&mut env, 4, 100).unwrap();
    assert!(report.truncated >= 5, "{report}");
}

#[test]
fn env_is_deterministic_and_stays_in_its_spaces() {
    use rand::SeedableRng;
    let mut env = make_env(&DriveConfig::default()).unwrap();
    let obs_space = env.observation_space().clone();
    let act_space = env.action_space().clone();
    assert_eq!(obs_space.dim(), 24);
    assert_eq!(act_space.dim(), 2);
    let run = |env: &mut red_core::TimeLimit<DriveEnv>, seed: u64| {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let (obs, _) = env.reset(Some(seed)).unwrap();
        assert!(obs_space.contains(&obs), "{obs:?}");
        let mut trace = vec![obs];
        for _ in 0..300 {
            let mut a = act_space.sample(&mut rng);
            a[0] *= 0.2;
            let s = env.step(&a).unwrap();
            assert!(obs_space.contains(&s.observation), "{:?}", s.observation);
            assert!(s.reward.is_finite());
            assert!(!s.truncated || !s.terminated);
            trace.push(s.observation.clone());
            trace.push(vec![s.reward, f64::from(u8::from(s.terminated))]);
            if s.terminated || s.truncated {
                break;
            }
        }
        trace
    };
    let a = run(&mut env, 5);
    let b = run(&mut env, 5);
    assert_eq!(a, b, "same seed, same trajectory");
    let c = run(&mut env, 6);
    assert_ne!(a[0], c[0], "another seed, another start");
    // reset(None) continues the stream: a different start again.
    let (o1, _) = env.reset(None).unwrap();
    let (o2, _) = env.reset(None).unwrap();
    assert_ne!(o1, o2);
}

#[test]
fn malformed_actions_and_stepping_after_the_end_are_errors() {
    let mut env = DriveEnv::new(&quiet()).unwrap();
    assert!(matches!(
        env.step(&[0.0, 0.0]),
        Err(red_core::Error::NeedsReset { .. })
    ));
    env.reset(Some(0)).unwrap();
    assert!(matches!(
        env.step(&[0.0]),
        Err(red_core::Error::ShapeMismatch { .. })
    ));
    assert!(matches!(
        env.step(&[f64::NAN, 0.0]),
        Err(red_core::Error::NonFinite { .. })
    ));
    // Hard left into the wall.
    let mut ended = false;
    for _ in 0..200 {
        let s = env.step(&[1.0, 0.0]).unwrap();
        if s.terminated {
            assert_eq!(s.info.get(INFO_COLLISION), Some(1.0));
            ended = true;
            break;
        }
    }
    assert!(ended, "steering into the wall must end the episode");
    assert!(matches!(
        env.step(&[0.0, 0.0]),
        Err(red_core::Error::NeedsReset { .. })
    ));
}

#[test]
fn driving_into_an_obstacle_terminates_without_success() {
    let c = quiet();
    let mut env = DriveEnv::new(&c).unwrap();
    env.reset(Some(0)).unwrap();
    let o = env.track().obstacles[2];
    env.reset_to(CarState {
        x: o.x - 20.0,
        y: o.y,
        heading: 0.0,
        speed: 20.0,
    })
    .unwrap();
    let mut total = 0.0;
    for k in 0..40 {
        let s = env.step(&[0.0, 0.0]).unwrap();
        total += s.reward;
        if s.terminated {
            assert!(!s.truncated);
            assert_eq!(s.info.get(INFO_COLLISION), Some(1.0));
            assert_eq!(s.info.get(INFO_SUCCESS), Some(0.0));
            // Bumpers meet when the centres are one car length apart.
            let gap = o.x - env.car().x;
            assert!(gap <= c.car_length && gap > c.car_length - 0.6, "gap {gap}");
            assert!((total - (20.0 - gap)).abs() < 1e-9);
            assert!(k >= 10, "took {k} steps");
            return;
        }
    }
    panic!("no collision");
}

#[test]
fn lidar_ranges_match_the_true_distances() {
    let c = quiet();
    let mut env = DriveEnv::new(&c).unwrap();
    env.reset(Some(0)).unwrap();
    let o = env.track().obstacles[3];
    let gap = 37.25;
    let y = o.y + 0.2;
    let obs = env
        .reset_to(CarState {
            x: o.x - gap,
            y,
            heading: 0.0,
            speed: 10.0,
        })
        .unwrap();
    let angles = c.ray_angles();
    let ranges = *env.lidar_ranges();
    // The two middle rays hit the obstacle's rear face, x = o.x - 2.25.
    for i in [NUM_RAYS / 2 - 1, NUM_RAYS / 2] {
        let want = (gap - 0.5 * c.car_length) / angles[i].cos();
        assert!(
            (ranges[i] - want).abs() < 2e-3,
            "ray {i}: {} vs {want}",
            ranges[i]
        );
        assert!((obs[i] - want / c.lidar_range).abs() < 2e-5);
    }
    // The outermost rays point at the walls, straight sideways.
    let hw = c.half_width();
    assert!((ranges[0] - (y + hw)).abs() < 2e-3, "{}", ranges[0]);
    assert!((ranges[NUM_RAYS - 1] - (hw - y)).abs() < 2e-3);
    // Road numbers and speed.
    assert!((obs[NUM_RAYS] - y / hw).abs() < 1e-12);
    assert_eq!(obs[NUM_RAYS + 1], 0.0);
    assert!((obs[NUM_RAYS + 2] - (hw - y.abs()) / hw).abs() < 1e-12);
    assert!((obs[NUM_RAYS + 3] - 10.0 / c.max_speed).abs() < 1e-12);
    // Nothing in range: the reading is the maximum.
    let mut far = c.clone();
    far.lidar_fan_deg = 4.0;
    let mut env = DriveEnv::new(&far).unwrap();
    env.reset_to(CarState {
        x: -500.0,
        y: 0.0,
        heading: 0.0,
        speed: 0.0,
    })
    .unwrap();
    assert!(
        env.lidar_ranges()
            .iter()
            .all(|r| (*r - c.lidar_range).abs() < 1e-3)
    );
}

#[test]
fn reaching_the_end_is_a_success_with_the_full_distance() {
    let c = DriveConfig {
        road_length: 60.0,
        first_obstacle_distance: 1000.0,
        ..quiet()
    };
    let mut env = make_env(&c).unwrap();
    env.reset(Some(3)).unwrap();
    let mut total = 0.0;
    loop {
        let s = env.step(&[0.0, 0.5]).unwrap();
        total += s.reward;
        if s.terminated || s.truncated {
            assert!(s.terminated);
            assert_eq!(s.info.get(INFO_SUCCESS), Some(1.0));
            assert_eq!(s.info.get(INFO_PROGRESS), Some(1.0));
            assert_eq!(s.info.get(INFO_DISTANCE), Some(60.0));
            assert!((total - 60.0).abs() < 1e-9);
            break;
        }
    }
}

#[test]
fn time_limit_truncates() {
    let c = DriveConfig {
        time_limit: 7,
        ..quiet()
    };
    let mut env = make_env(&c).unwrap();
    env.reset(Some(0)).unwrap();
    for k in 1..=7 {
        let s = env.step(&[0.0, -1.0]).unwrap();
        assert!(!s.terminated);
        assert_eq!(s.truncated, k == 7);
    }
}

#[test]
fn expert_completes_at_least_99_of_100_layouts() {
    let results = expert_success(&DriveConfig::default(), 0..100).unwrap();
    let done = results.iter().filter(|(_, e)| e.success).count();
    let failed: Vec<_> = results.iter().filter(|(_, e)| !e.success).collect();
    let steps = results.iter().map(|(_, e)| e.steps);
    let (lo, hi) = (steps.clone().min().unwrap(), steps.max().unwrap());
    eprintln!("expert completed {done}/100 layouts in {lo}..={hi} steps; failures: {failed:?}");
    assert!(done >= 99, "expert completed {done}/100: {failed:?}");
    for (_, e) in &results {
        if e.success {
            assert!((e.distance - 1000.0).abs() < 1e-9);
            // About 100 km/h: 1000 m in 36 s = 720 steps.
            assert!((700..=760).contains(&e.steps), "{e:?}");
        }
    }
}

#[test]
fn expert_demos_hold_true_rewards() {
    let demos = expert_demos(&DriveConfig::default(), 2, 11).unwrap();
    assert_eq!(demos.env_id, "drive");
    assert_eq!(demos.control_hz, Some(20.0));
    assert_eq!((demos.obs_dim, demos.act_dim), (24, 2));
    assert_eq!(demos.trajectories.len(), 2);
    for t in &demos.trajectories {
        assert_eq!(t.end, EpisodeEnd::Terminated);
        let ret: f64 = t.rewards.as_ref().unwrap().iter().sum();
        assert!((ret - 1000.0).abs() < 1e-9);
        assert!(t.actions.iter().flatten().all(|a| (-1.0..=1.0).contains(a)));
    }
    assert_ne!(
        demos.trajectories[0].observations[0],
        demos.trajectories[1].observations[0]
    );
}

#[test]
fn recorder_round_trip_through_a_demo_file() {
    let c = DriveConfig::default();
    let mut rec = Recorder::new(&c, 4, false).unwrap();
    let script: Vec<Vec<KeyEvent>> = (0..60)
        .map(|t| match t {
            3 | 4 => vec![KeyEvent::press(DriveKey::Left)],
            10 => vec![KeyEvent::press(DriveKey::Right)],
            20 => vec![
                KeyEvent::press(DriveKey::Up),
                KeyEvent {
                    key: DriveKey::Up,
                    kind: KeyKind::Repeat,
                },
            ],
            30 => vec![KeyEvent::press(DriveKey::Down)],
            _ => vec![],
        })
        .collect();
    for events in &script {
        assert_eq!(rec.tick(events).unwrap(), RecordStatus::Driving);
    }
    assert_eq!(
        rec.tick(&[KeyEvent::press(DriveKey::Quit)]).unwrap(),
        RecordStatus::Quit
    );
    assert_eq!(rec.steps(), 60);
    assert!(rec.view(20, 30).is_some_and(|v| v.len() == 20));
    let demos = rec.finish();
    let t = &demos.trajectories[0];
    assert_eq!(t.end, EpisodeEnd::Truncated);
    assert!(t.actions[3][0] > 0.0 && t.actions[10][0] < t.actions[9][0]);
    assert!(t.actions[21][1] > t.actions[19][1]);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("human.json");
    demos.write(&path).unwrap();
    let back = Demos::read(&path).unwrap();
    assert_eq!(back, demos);
    // The recorded actions replay to the recorded rewards.
    let mut env = DriveEnv::new(&c).unwrap();
    env.reset(Some(4)).unwrap();
    for (a, r) in t.actions.iter().zip(t.rewards.as_ref().unwrap()) {
        assert_eq!(env.step(a).unwrap().reward, *r);
    }
}

#[test]
fn rendered_png_has_the_expected_size() {
    let c = DriveConfig::default();
    let demos = expert_demos(&c, 1, 0).unwrap();
    let spec = demo_path(&c, &demos.trajectories[0], "expert", [20, 90, 200], 40).unwrap();
    assert_eq!(spec.end, red_drive::PathEnd::Success);
    assert!(spec.poses.last().unwrap().x >= c.road_length);
    let options = RenderOptions::default();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("drive.png");
    render_png(&path, &c, &[spec], &options).unwrap();
    let size = png_size(&path).unwrap();
    assert_eq!(size, options.image_size(&c));
    assert_eq!(size.0, 1600);
    assert!(size.1 > 200 && size.1 < 800, "{size:?}");
}

#[test]
fn shipped_demo_reads_and_replays_to_the_end_of_the_default_road() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../data/drive-scripted-expert.json");
    let demos = Demos::read(&path).unwrap();
    assert_eq!(demos.env_id, "drive");
    assert_eq!(demos.trajectories.len(), 1);
    assert!(std::fs::metadata(&path).unwrap().len() < 1_000_000);
    let t = &demos.trajectories[0];
    let ret: f64 = t.rewards.as_ref().unwrap().iter().sum();
    assert!((ret - 1000.0).abs() < 1e-2, "{ret}");
    // Numbers rounded to 6 digits still retrace the expert's drive.
    let (poses, end) = red_drive::render::replay(&DriveConfig::default(), t).unwrap();
    assert_eq!(end, red_drive::PathEnd::Success);
    assert_eq!(poses.len(), t.actions.len() + 1);
}
