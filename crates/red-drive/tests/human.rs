//! The person-like driver: determinism, actions that only the recorder's
//! key model could have stored, finishing a road, replaying on the road
//! its file names, and deciding only from the road in view.

use red_core::{DemoSource, EpisodeEnd};
use red_drive::DriveConfig;
use red_drive::human::{HumanConfig, human_demos, human_demos_with_summaries, human_success};
use red_drive::record::{PEDAL_STEP, next_steer, pedal_on_grid};
use red_drive::scenario::{RoadSource, check_fits, road_of};

fn road(track_seed: u64) -> DriveConfig {
    DriveConfig {
        track_seed,
        ..DriveConfig::default()
    }
}

#[test]
fn human_driver_is_deterministic_per_seed() {
    let h = HumanConfig::default();
    let a = human_demos(&road(11), &h, 2, 3).unwrap();
    let b = human_demos(&road(11), &h, 2, 3).unwrap();
    assert_eq!(a, b);
    let c = human_demos(&road(11), &h, 2, 4).unwrap();
    assert_ne!(a.trajectories[0].actions, c.trajectories[0].actions);
}

/// Every stored action is one the recorder's key model reaches from the
/// one before: the steering by one tick of its ramp or return, the pedal
/// on its grid.
fn check_key_model(actions: &[Vec<f64>], start_pedal: f64) {
    let mut steer = 0.0;
    let mut pedal = start_pedal;
    for (t, a) in actions.iter().enumerate() {
        assert!(
            [-1.0, 0.0, 1.0]
                .iter()
                .any(|&d| next_steer(steer, d) == a[0]),
            "step {t}: steering {} does not follow {steer}",
            a[0]
        );
        assert_eq!(
            a[1],
            pedal_on_grid(a[1]),
            "step {t}: pedal {} off its grid",
            a[1]
        );
        let steps = (a[1] - pedal) / PEDAL_STEP;
        assert!((steps - steps.round()).abs() < 1e-9, "step {t}");
        steer = a[0];
        pedal = a[1];
    }
}

#[test]
fn human_actions_are_what_the_recorder_key_model_gives() {
    for key_releases in [false, true] {
        let h = HumanConfig {
            key_releases,
            ..HumanConfig::default()
        };
        let demos = human_demos(&road(23), &h, 1, 0).unwrap();
        let acts = &demos.trajectories[0].actions;
        // The level that holds 100 km/h.
        check_key_model(acts, 0.15);
        let zero = acts.iter().filter(|a| a[0] == 0.0).count() as f64 / acts.len() as f64;
        assert!(zero > 0.5, "{zero} of the steps steer 0");
        // It steered both ways.
        assert!(acts.iter().any(|a| a[0] > 0.0) && acts.iter().any(|a| a[0] < 0.0));
    }
}

#[test]
fn human_driver_finishes_a_road_and_its_demo_replays_there() {
    let r = road(11);
    let (demos, summaries) = human_demos_with_summaries(&r, &HumanConfig::default(), 1, 0).unwrap();
    let s = summaries[0];
    assert!(s.success, "{s:?}");
    assert!((s.distance - r.road_length).abs() < 1e-9);
    let t = &demos.trajectories[0];
    assert_eq!(t.end, EpisodeEnd::Terminated);
    assert_eq!(t.actions.len(), s.steps);
    assert_eq!(demos.source, Some(DemoSource::Script));
    let (found, source) = road_of(&demos).unwrap();
    assert_eq!((found.clone(), source), (r.clone(), RoadSource::File));
    check_fits(&found, &demos).unwrap();
    assert!(check_fits(&road(12), &demos).is_err());
}

#[test]
fn human_decides_only_from_the_road_in_view() {
    // The same layout up to 980 m; the longer road has more stopped cars
    // beyond. Until they come within 100 m, the drives are identical.
    let short = road(37);
    let long = DriveConfig {
        road_length: 2000.0,
        ..road(37)
    };
    let far = red_drive::Track::generate(&long)
        .obstacles
        .iter()
        .map(|o| o.x)
        .find(|&x| x > short.road_length - short.end_clearance)
        .unwrap();
    let h = HumanConfig::default();
    let a = human_demos(&short, &h, 1, 5).unwrap();
    let b = human_demos(&long, &h, 1, 5).unwrap();
    let (ta, tb) = (&a.trajectories[0], &b.trajectories[0]);
    let mut x = 0.0;
    let mut compared = 0;
    for (t, r) in ta.rewards.as_ref().unwrap().iter().enumerate() {
        if x >= far - h.view_distance - 10.0 {
            break;
        }
        assert_eq!(ta.actions[t], tb.actions[t], "step {t} at {x:.1} m");
        x += r;
        compared += 1;
    }
    assert!(compared > 400, "{compared} steps compared");
}

#[test]
fn a_crash_is_kept_as_it_happened() {
    // A driver that sees 5 m ahead cannot get out of the way in time.
    let h = HumanConfig {
        view_distance: 5.0,
        ..HumanConfig::default()
    };
    let r = road(11);
    let (demos, summaries) = human_demos_with_summaries(&r, &h, 1, 0).unwrap();
    let s = summaries[0];
    assert!(!s.success && s.distance < r.road_length, "{s:?}");
    let t = &demos.trajectories[0];
    assert_eq!(t.end, EpisodeEnd::Terminated);
    assert_eq!(t.actions.len(), s.steps);
    check_fits(&r, &demos).unwrap();
}

#[test]
fn human_finishes_at_least_48_of_50_held_out_roads() {
    // Track seeds 50-99 were not used while its settings were chosen
    // (measured: 50/50; 499/500 on seeds 150-649).
    let results = human_success(&DriveConfig::default(), &HumanConfig::default(), 50..100).unwrap();
    let failed: Vec<_> = results.iter().filter(|(_, e)| !e.success).collect();
    assert!(failed.len() <= 2, "{failed:?}");
}
