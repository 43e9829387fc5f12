//! The scenario's settings: road, obstacles, car, lidar and episode length.

use serde::{Deserialize, Serialize};

use crate::{Error, Result};

/// Number of lanes of the road (the paper's track has three).
pub const NUM_LANES: usize = 3;
/// Number of lidar rays (the paper's observation has 20 lidar readings).
pub const NUM_RAYS: usize = 20;
/// Length of an observation: 20 lidar ranges, 3 road numbers, the speed.
pub const OBS_DIM: usize = NUM_RAYS + 4;
/// Length of an action: steering, accelerator/brake.
pub const ACT_DIM: usize = 2;
/// Control frequency in Hz (the paper sampled the human's actions at 20 Hz).
pub const CONTROL_HZ: f64 = 20.0;
/// Seconds per control step.
pub const DT: f64 = 1.0 / CONTROL_HZ;
/// 100 km/h in m/s, the cruising speed the paper asked its human driver for.
pub const KMH_100: f64 = 100.0 / 3.6;

/// Settings of the driving scenario. Lengths are in metres, speeds in m/s,
/// angles in radians unless a name says otherwise.
///
/// ```
/// let config = red_drive::DriveConfig { track_seed: 3, ..Default::default() };
/// config.validate()?;
/// # Ok::<(), red_drive::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DriveConfig {
    /// Length of the road; reaching its end ends the episode with success.
    pub road_length: f64,
    /// Width of one of the three lanes.
    pub lane_width: f64,
    /// Distance from the start to the first obstacle's centre.
    pub first_obstacle_distance: f64,
    /// Smallest distance between the centres of two successive obstacles.
    pub obstacle_spacing_min: f64,
    /// Extra random spacing: each gap is `obstacle_spacing_min + U(0, this)`.
    pub obstacle_spacing_jitter: f64,
    /// No obstacle is placed closer than this to the end of the road.
    pub end_clearance: f64,
    /// Length of the car and of every obstacle (a stopped car).
    pub car_length: f64,
    /// Width of the car and of every obstacle.
    pub car_width: f64,
    /// Distance between the car's axles (kinematic bicycle model).
    pub wheelbase: f64,
    /// Largest steering angle of the front wheels (reached at low speed).
    pub max_steer_angle: f64,
    /// Lateral acceleration at full steering: at speed the steering angle is
    /// limited so that `steering = 1` turns with this acceleration.
    pub max_lateral_accel: f64,
    /// Acceleration at full accelerator (`action[1] = 1`).
    pub max_accel: f64,
    /// Deceleration at full brake (`action[1] = -1`).
    pub max_brake: f64,
    /// Aerodynamic drag: deceleration `drag * v^2`.
    pub drag: f64,
    /// Rolling resistance: a constant deceleration while moving.
    pub rolling_resistance: f64,
    /// Top speed; the speed observation is `v / max_speed`.
    pub max_speed: f64,
    /// Speed at the start of an episode (before reset noise).
    pub initial_speed: f64,
    /// The speed the scripted expert keeps.
    pub expert_speed: f64,
    /// Reset noise: the start's lateral offset is `U(-this, this)`.
    pub start_lateral_noise: f64,
    /// Reset noise: the start's heading is `U(-this, this)`.
    pub start_heading_noise: f64,
    /// Reset noise: the start's speed is `initial_speed + U(-this, this)`.
    pub start_speed_noise: f64,
    /// Range of the lidar; readings are divided by it.
    pub lidar_range: f64,
    /// Angle covered by the fan of rays, centred on the car's heading, in
    /// degrees.
    pub lidar_fan_deg: f64,
    /// Spacing of the rays over the fan: ray `i` points at
    /// `fan/2 * sign(u) * |u|^power` for `u` evenly spaced in `[-1, 1]`;
    /// 1 spaces the rays evenly, larger values gather them ahead.
    pub lidar_spacing_power: f64,
    /// Heading error (radians) that maps to 1 in the observation; the
    /// observed value is clipped to `[-1, 1]`.
    pub heading_scale: f64,
    /// Episode length limit in control steps (applied by
    /// [`red_core::TimeLimit`] in [`crate::make_env`]).
    pub time_limit: usize,
    /// Seed of the road's layout (obstacle positions and lanes). The
    /// layout is fixed for a config; `Env::reset`'s seed only draws the
    /// start noise, so evaluations run on the same track, as in the paper.
    pub track_seed: u64,
    /// A margin around the driven car's body for collisions, metres (our
    /// addition, for training episodes): the car collides when its body
    /// grown by this on every side touches a stopped car or a wall. The
    /// lidar, the obstacles and everything else are unchanged. 0 (the
    /// default, and not written): the body itself.
    #[serde(skip_serializing_if = "is_zero")]
    pub collision_margin: f64,
}

/// Whether a length is 0 (then not written, so that files without it read
/// in builds before it).
fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

impl Default for DriveConfig {
    /// The defaults and where they come from:
    /// - `road_length` 1000 m: the paper's track was 7485 "distance units"
    ///   long, in units it does not name; we keep the shape of the task
    ///   (a straight road, obstacles to pass, 100 km/h) but choose a road that
    ///   the expert completes in about 36 s (720 steps at 20 Hz) to keep the
    ///   main experiment quick. Reports give distance and the road fraction.
    /// - `lane_width` 3.5 m: a common motorway lane.
    /// - `first_obstacle_distance` 80 m and `obstacle_spacing_min` 70 m,
    ///   `obstacle_spacing_jitter` 50 m: at 100 km/h a lane change between
    ///   two obstacles (at most one lane is ever needed, see
    ///   [`crate::expert`]) has at least 55 m, 2 s, of free road; about 12
    ///   obstacles on the default road.
    /// - `end_clearance` 20 m: no obstacle right at the finish line.
    /// - car 4.5 m x 1.8 m, wheelbase 2.7 m: a mid-size saloon; obstacles are
    ///   stopped cars of the same size.
    /// - `max_steer_angle` 0.6 rad, `max_lateral_accel` 8 m/s^2 (about
    ///   0.8 g, near a road tyre's grip limit): full steering at 100 km/h is
    ///   a hard but drivable turn, so actions stay in a useful range at speed.
    /// - `max_accel` 4 m/s^2, `max_brake` 8 m/s^2, `drag` 6.5e-4 /m,
    ///   `rolling_resistance` 0.1 m/s^2: an ordinary car; holding 100 km/h
    ///   takes about 0.15 accelerator.
    /// - `max_speed` 40 m/s (144 km/h).
    /// - `initial_speed` and `expert_speed` 100 km/h: the paper's human
    ///   kept about 100 km/h; starting at speed keeps every step of a
    ///   demonstration in that regime.
    /// - start noise 0.3 m, 0.03 rad, 1 m/s: small, so resets differ.
    /// - `lidar_range` 100 m (3.6 s ahead at 100 km/h); `lidar_fan_deg` 180
    ///   (the front half, so the side rays see the walls);
    ///   `lidar_spacing_power` 2: with even spacing the two middle rays of a
    ///   20-ray fan are 9.5 degrees apart and miss a car in the own lane
    ///   until about 11 m; power 2 puts them 0.5 degrees apart.
    /// - `heading_scale` 0.5 rad (29 degrees): lane changes at speed use a
    ///   few degrees, so this keeps the number near the scale of the others.
    /// - `time_limit` 1200 steps (60 s): the default road at 60 km/h on
    ///   average.
    /// - `track_seed` 0.
    fn default() -> Self {
        Self {
            road_length: 1000.0,
            lane_width: 3.5,
            first_obstacle_distance: 80.0,
            obstacle_spacing_min: 70.0,
            obstacle_spacing_jitter: 50.0,
            end_clearance: 20.0,
            car_length: 4.5,
            car_width: 1.8,
            wheelbase: 2.7,
            max_steer_angle: 0.6,
            max_lateral_accel: 8.0,
            max_accel: 4.0,
            max_brake: 8.0,
            drag: 6.5e-4,
            rolling_resistance: 0.1,
            max_speed: 40.0,
            initial_speed: KMH_100,
            expert_speed: KMH_100,
            start_lateral_noise: 0.3,
            start_heading_noise: 0.03,
            start_speed_noise: 1.0,
            lidar_range: 100.0,
            lidar_fan_deg: 180.0,
            lidar_spacing_power: 2.0,
            heading_scale: 0.5,
            time_limit: 1200,
            track_seed: 0,
            collision_margin: 0.0,
        }
    }
}

fn positive(field: &'static str, v: f64) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(Error::InvalidConfig {
            field,
            reason: format!("must be a finite number > 0, got {v}"),
        })
    }
}

fn non_negative(field: &'static str, v: f64) -> Result<()> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(Error::InvalidConfig {
            field,
            reason: format!("must be a finite number >= 0, got {v}"),
        })
    }
}

impl DriveConfig {
    /// Half the road's width (three lanes), from the centre line to a wall.
    pub fn half_width(&self) -> f64 {
        0.5 * NUM_LANES as f64 * self.lane_width
    }

    /// The lateral position of the centre of `lane` (0 = rightmost,
    /// 2 = leftmost; `y` points to the left of the driving direction).
    pub fn lane_center(&self, lane: usize) -> f64 {
        (lane as f64 - 0.5 * (NUM_LANES as f64 - 1.0)) * self.lane_width
    }

    /// The lane whose centre is nearest the lateral position `y`.
    pub fn nearest_lane(&self, y: f64) -> usize {
        (0..NUM_LANES)
            .min_by(|&a, &b| {
                (self.lane_center(a) - y)
                    .abs()
                    .total_cmp(&(self.lane_center(b) - y).abs())
            })
            .unwrap_or(1)
    }

    /// Checks every field.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the first field that is out of range.
    pub fn validate(&self) -> Result<()> {
        positive("road_length", self.road_length)?;
        positive("lane_width", self.lane_width)?;
        positive("car_length", self.car_length)?;
        positive("car_width", self.car_width)?;
        if self.car_width >= self.lane_width {
            return Err(Error::InvalidConfig {
                field: "car_width",
                reason: format!(
                    "must be below lane_width ({}) so that cars fit in a lane, got {}",
                    self.lane_width, self.car_width
                ),
            });
        }
        non_negative("first_obstacle_distance", self.first_obstacle_distance)?;
        non_negative("obstacle_spacing_jitter", self.obstacle_spacing_jitter)?;
        non_negative("end_clearance", self.end_clearance)?;
        positive("obstacle_spacing_min", self.obstacle_spacing_min)?;
        if self.obstacle_spacing_min < 2.0 * self.car_length {
            return Err(Error::InvalidConfig {
                field: "obstacle_spacing_min",
                reason: format!(
                    "must leave room to pass between obstacles: at least 2 x car_length ({}), got {}",
                    2.0 * self.car_length,
                    self.obstacle_spacing_min
                ),
            });
        }
        positive("wheelbase", self.wheelbase)?;
        if self.wheelbase > self.car_length {
            return Err(Error::InvalidConfig {
                field: "wheelbase",
                reason: format!(
                    "must not exceed car_length ({}), got {}",
                    self.car_length, self.wheelbase
                ),
            });
        }
        positive("max_steer_angle", self.max_steer_angle)?;
        if self.max_steer_angle >= std::f64::consts::FRAC_PI_2 {
            return Err(Error::InvalidConfig {
                field: "max_steer_angle",
                reason: format!("must be below pi/2, got {}", self.max_steer_angle),
            });
        }
        positive("max_lateral_accel", self.max_lateral_accel)?;
        positive("max_accel", self.max_accel)?;
        positive("max_brake", self.max_brake)?;
        non_negative("drag", self.drag)?;
        non_negative("rolling_resistance", self.rolling_resistance)?;
        positive("max_speed", self.max_speed)?;
        for (field, v) in [
            ("initial_speed", self.initial_speed),
            ("expert_speed", self.expert_speed),
        ] {
            non_negative(field, v)?;
            if v > self.max_speed {
                return Err(Error::InvalidConfig {
                    field,
                    reason: format!("must not exceed max_speed ({}), got {v}", self.max_speed),
                });
            }
        }
        non_negative("start_lateral_noise", self.start_lateral_noise)?;
        non_negative("start_speed_noise", self.start_speed_noise)?;
        non_negative("start_heading_noise", self.start_heading_noise)?;
        let free = 0.5 * (self.lane_width - self.car_width);
        non_negative("collision_margin", self.collision_margin)?;
        if self.collision_margin >= free {
            return Err(Error::InvalidConfig {
                field: "collision_margin",
                reason: format!(
                    "must leave the car room in its lane: below {free}, got {}",
                    self.collision_margin
                ),
            });
        }
        let room = free - self.collision_margin;
        if self.start_lateral_noise >= room {
            return Err(Error::InvalidConfig {
                field: "start_lateral_noise",
                reason: format!(
                    "must keep the car inside its lane: below {room} (half the lane's free \
                     width less collision_margin {}), got {}",
                    self.collision_margin, self.start_lateral_noise
                ),
            });
        }
        positive("lidar_range", self.lidar_range)?;
        positive("lidar_fan_deg", self.lidar_fan_deg)?;
        if self.lidar_fan_deg > 360.0 {
            return Err(Error::InvalidConfig {
                field: "lidar_fan_deg",
                reason: format!("must be at most 360, got {}", self.lidar_fan_deg),
            });
        }
        positive("lidar_spacing_power", self.lidar_spacing_power)?;
        positive("heading_scale", self.heading_scale)?;
        if self.time_limit == 0 {
            return Err(Error::InvalidConfig {
                field: "time_limit",
                reason: "must be at least 1 step".into(),
            });
        }
        Ok(())
    }

    /// Steering angle at full steering for speed `v`: the smaller of
    /// `max_steer_angle` and the angle that gives `max_lateral_accel`.
    pub fn steer_limit(&self, v: f64) -> f64 {
        let v2 = v * v;
        if v2 <= 1e-9 {
            return self.max_steer_angle;
        }
        (self.max_lateral_accel * self.wheelbase / v2)
            .atan()
            .min(self.max_steer_angle)
    }

    /// The directions of the lidar rays relative to the car's heading, in
    /// radians, from right (negative) to left.
    pub fn ray_angles(&self) -> [f64; NUM_RAYS] {
        let half = 0.5 * self.lidar_fan_deg.to_radians();
        let mut out = [0.0; NUM_RAYS];
        for (i, a) in out.iter_mut().enumerate() {
            let u = -1.0 + 2.0 * i as f64 / (NUM_RAYS as f64 - 1.0);
            *a = half * u.signum() * u.abs().powf(self.lidar_spacing_power);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_valid_and_round_trips_through_json() {
        let c = DriveConfig::default();
        c.validate().unwrap();
        let text = serde_json::to_string(&c).unwrap();
        let back: DriveConfig = serde_json::from_str(&text).unwrap();
        assert_eq!(c, back);
    }

    #[test]
    fn unknown_fields_are_rejected_and_missing_ones_default() {
        assert!(serde_json::from_str::<DriveConfig>(r#"{"road_lenght": 5}"#).is_err());
        let c: DriveConfig = serde_json::from_str(r#"{"track_seed": 9}"#).unwrap();
        assert_eq!(c.track_seed, 9);
        assert_eq!(c.road_length, DriveConfig::default().road_length);
    }

    #[test]
    fn validate_names_the_field() {
        let c = DriveConfig {
            lane_width: -1.0,
            ..Default::default()
        };
        match c.validate() {
            Err(Error::InvalidConfig { field, .. }) => assert_eq!(field, "lane_width"),
            other => panic!("expected InvalidConfig, got {other:?}"),
        }
        let c = DriveConfig {
            obstacle_spacing_min: 5.0,
            ..Default::default()
        };
        assert!(
            c.validate()
                .unwrap_err()
                .to_string()
                .contains("obstacle_spacing_min")
        );
    }

    #[test]
    fn rays_are_symmetric_and_span_the_fan() {
        let c = DriveConfig::default();
        let a = c.ray_angles();
        assert!((a[0] + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!((a[NUM_RAYS - 1] - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        for i in 0..NUM_RAYS {
            assert!((a[i] + a[NUM_RAYS - 1 - i]).abs() < 1e-12);
        }
        assert!(a[NUM_RAYS / 2] < 0.01, "power 2 puts the middle rays close");
    }

    #[test]
    fn steering_limit_gives_the_lateral_acceleration() {
        let c = DriveConfig::default();
        let v = KMH_100;
        let d = c.steer_limit(v);
        let lat = v * v * d.tan() / c.wheelbase;
        assert!((lat - c.max_lateral_accel).abs() < 1e-9);
        assert_eq!(c.steer_limit(0.0), c.max_steer_angle);
    }
}
