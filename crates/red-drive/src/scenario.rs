//! The road a demonstration was driven on, carried inside the demo file.
//!
//! A drive demo file (format version 2) holds the whole [`DriveConfig`] it
//! was made under, track seed included, in its `scenario` field, so every
//! command that uses the file drives the same road. Files without the field
//! (version 1, or written by other tools) are read as made on the default
//! road; [`road_of`] says so, so a front end can print it.
//!
//! ```
//! use red_drive::scenario::{RoadSource, check_fits, road_of, set_road};
//! use red_drive::{DriveConfig, expert_demos};
//!
//! let road = DriveConfig { track_seed: 7, ..DriveConfig::default() };
//! let mut demos = expert_demos(&road, 1, 0)?;
//! set_road(&mut demos, &road)?;
//! let (found, source) = road_of(&demos)?;
//! assert_eq!((found.track_seed, source), (7, RoadSource::File));
//! check_fits(&found, &demos)?;
//! let other = DriveConfig { track_seed: 8, ..DriveConfig::default() };
//! assert!(check_fits(&other, &demos).is_err());
//! # Ok::<(), red_drive::Error>(())
//! ```

use red_core::{Demos, EpisodeEnd, Trajectory};

use crate::config::{CONTROL_HZ, DriveConfig};
use crate::render::replay;
use crate::{ENV_ID, Error, Result};

/// Where [`road_of`] found the road.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RoadSource {
    /// The demo file's `scenario` field.
    File,
    /// The file has no `scenario` field: the default road is assumed.
    Assumed,
}

/// Writes `road` into `demos`' `scenario` field.
///
/// # Errors
/// [`Error::InvalidConfig`] if `road` is invalid.
pub fn set_road(demos: &mut Demos, road: &DriveConfig) -> Result<()> {
    road.validate()?;
    let value = serde_json::to_value(road).map_err(|e| Error::InvalidConfig {
        field: "scenario",
        reason: e.to_string(),
    })?;
    demos.scenario = Some(value);
    Ok(())
}

/// The road `demos` were driven on: the file's `scenario` field, or the
/// default road when the file has none.
///
/// # Errors
/// [`Error::Replay`] if the demos are not of the drive scenario, or if the
/// `scenario` field is not a valid drive road (an unknown field, a value
/// out of range), naming what is wrong.
pub fn road_of(demos: &Demos) -> Result<(DriveConfig, RoadSource)> {
    if demos.env_id != ENV_ID {
        return Err(Error::Replay {
            reason: format!(
                "these are `{}` demonstrations, not `{ENV_ID}` ones",
                demos.env_id
            ),
        });
    }
    let Some(value) = &demos.scenario else {
        return Ok((DriveConfig::default(), RoadSource::Assumed));
    };
    let road: DriveConfig = serde_json::from_value(value.clone()).map_err(|e| Error::Replay {
        reason: format!("the file's `scenario` field is not a drive road: {e}"),
    })?;
    road.validate().map_err(|e| Error::Replay {
        reason: format!("the file's `scenario` field is not a valid drive road: {e}"),
    })?;
    Ok((road, RoadSource::File))
}

/// Checks that every trajectory of `demos` retraces on `road` (see
/// [`replay`]); the error names the trajectory, the step and the reason.
///
/// # Errors
/// [`Error::Replay`] for the first trajectory that does not fit.
pub fn check_fits(road: &DriveConfig, demos: &Demos) -> Result<()> {
    for (i, t) in demos.trajectories.iter().enumerate() {
        replay(road, t).map_err(|e| match e {
            Error::Replay { reason } => Error::Replay {
                reason: format!(
                    "trajectory {i} does not fit the road (track seed {}): {reason}",
                    road.track_seed
                ),
            },
            other => other,
        })?;
    }
    Ok(())
}

/// One line per trajectory of `demos` driven on `road`: steps, seconds,
/// how it ended (`finish`, `CRASH`, or `time limit or stopped`) and the
/// distance of the road covered (the sum of its rewards, the distance
/// gained).
pub fn episode_lines(demos: &Demos, road: &DriveConfig) -> Vec<String> {
    demos
        .trajectories
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let distance: f64 = t.rewards.as_ref().map_or(0.0, |r| r.iter().sum());
            format!(
                "episode {i}: {} steps ({:.1} s), {}, distance {distance:.1} m of {:.0} m ({:.1}%)",
                t.actions.len(),
                t.actions.len() as f64 / CONTROL_HZ,
                ending(t, distance, road),
                road.road_length,
                100.0 * distance / road.road_length
            )
        })
        .collect()
}

/// How an episode ended, from its end and distance.
pub fn ending(t: &Trajectory, distance: f64, road: &DriveConfig) -> &'static str {
    match t.end {
        // The reward is the distance gained, so a finished episode sums to
        // the road's length (up to the rounding of the file's numbers).
        EpisodeEnd::Terminated if distance >= road.road_length - 1e-3 => "finish",
        EpisodeEnd::Terminated => "CRASH",
        EpisodeEnd::Truncated => "time limit or stopped",
    }
}

/// The differences between two roads, as `field: a -> b` items (empty when
/// they are the same road).
pub fn differences(a: &DriveConfig, b: &DriveConfig) -> Vec<String> {
    let (Ok(serde_json::Value::Object(x)), Ok(serde_json::Value::Object(y))) =
        (serde_json::to_value(a), serde_json::to_value(b))
    else {
        return vec!["(not comparable)".into()];
    };
    // A field at its default may be left out of the JSON (for example
    // `collision_margin`): such a field reads "(default)".
    let shown = |v: Option<&serde_json::Value>| v.map_or("(default)".into(), |v| v.to_string());
    let mut keys: Vec<&String> = x.keys().collect();
    keys.extend(y.keys().filter(|k| !x.contains_key(*k)));
    keys.into_iter()
        .filter_map(|k| {
            let (v, w) = (x.get(k), y.get(k));
            (v != w).then(|| format!("{k}: {} -> {}", shown(v), shown(w)))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A field left out of the JSON at its default still counts: two roads
    /// that differ only in `collision_margin` name it, either way round.
    #[test]
    fn differences_name_a_field_written_on_one_side_only() {
        let a = DriveConfig::default();
        assert!(differences(&a, &a).is_empty());
        let b = DriveConfig {
            collision_margin: 0.2,
            track_seed: 4,
            ..a.clone()
        };
        assert_eq!(
            differences(&a, &b),
            ["track_seed: 0 -> 4", "collision_margin: (default) -> 0.2"]
        );
        assert_eq!(
            differences(&b, &a),
            ["collision_margin: 0.2 -> (default)", "track_seed: 4 -> 0"]
        );
    }
}
