//! The scripted expert: it knows the layout, plans which lane to be in
//! beside each obstacle, and follows a smooth reference path at about
//! 100 km/h with a pure-pursuit steering law.
//!
//! Lane plan: beside obstacle `i` the car must be in a lane `c_i != lane_i`.
//! Between two obstacles the road is free, so only `|c_i - c_{i+1}|` matters;
//! a lane is always reachable with at most one lane change per gap (stay if
//! `c_i != lane_{i+1}`, else move to a neighbour, which differs from
//! `lane_{i+1} = c_i`). A dynamic programme picks the plan with the least
//! sum of squared lane changes, so it never needs a two-lane change.

use rand::Rng;
use red_core::{DemoSource, Demos, Env, Seeder, Stream, Trajectory, record_episode};

use crate::config::{ACT_DIM, CONTROL_HZ, DriveConfig, NUM_LANES, OBS_DIM};
pub use crate::env::EpisodeSummary;
use crate::env::{CarState, INFO_SUCCESS, World, make_env};
use crate::{ENV_ID, Result};

/// Extra distance kept, along the road, between the car and an obstacle
/// before a lane change may start or after it must be done.
const CLEAR_MARGIN: f64 = 4.0;
/// Gain of the speed controller, accelerator per m/s of speed error.
const SPEED_GAIN: f64 = 0.5;

/// The scripted driver.
#[derive(Debug, Clone)]
pub struct Expert {
    config: DriveConfig,
    /// Knots `(x, y)` of the reference path; between two knots `y` blends
    /// with a quintic smoothstep (zero slope and curvature at the knots).
    knots: Vec<(f64, f64)>,
    /// The planned lane beside each obstacle.
    plan: Vec<usize>,
}

impl Expert {
    /// Plans the lanes for `world`'s layout. The car is assumed to start in
    /// the middle lane (as [`crate::DriveEnv`] resets it).
    pub fn new(world: &World) -> Self {
        let config = world.config().clone();
        let obstacles = &world.track().obstacles;
        let plan = plan_lanes(&obstacles.iter().map(|o| o.lane).collect::<Vec<_>>(), 1);
        let clear = config.car_length + CLEAR_MARGIN;
        let mut knots = vec![(0.0, config.lane_center(1))];
        for (o, &lane) in obstacles.iter().zip(&plan) {
            let y = config.lane_center(lane);
            knots.push((o.x - clear, y));
            knots.push((o.x + clear, y));
        }
        Self {
            config,
            knots,
            plan,
        }
    }

    /// The planned lane beside each obstacle, in the order of the track.
    pub fn plan(&self) -> &[usize] {
        &self.plan
    }

    /// The reference lateral position at `x` along the road.
    pub fn reference(&self, x: f64) -> f64 {
        let k = &self.knots;
        let i = k.partition_point(|p| p.0 <= x);
        if i == 0 {
            return k[0].1;
        }
        if i == k.len() {
            return k[k.len() - 1].1;
        }
        let (x0, y0) = k[i - 1];
        let (x1, y1) = k[i];
        if y0 == y1 || x1 <= x0 {
            return y1;
        }
        let t = ((x - x0) / (x1 - x0)).clamp(0.0, 1.0);
        let s = t * t * t * (10.0 + t * (-15.0 + 6.0 * t));
        y0 + (y1 - y0) * s
    }

    /// The action `[steering, accelerator/brake]` for the car's true state.
    pub fn act(&self, car: &CarState) -> [f64; ACT_DIM] {
        let c = &self.config;
        // Pure pursuit of the reference point one lookahead ahead: damping
        // ratio 1/sqrt(2) for the linearised lateral error at any speed.
        let lookahead = (0.7 * car.speed).clamp(8.0, 25.0);
        let target_y = self.reference(car.x + lookahead);
        let alpha = (target_y - car.y).atan2(lookahead) - car.heading;
        let dist = (lookahead * lookahead + (target_y - car.y).powi(2)).sqrt();
        let curvature = 2.0 * alpha.sin() / dist;
        let delta = (curvature * c.wheelbase).atan();
        let steer = (delta / c.steer_limit(car.speed)).clamp(-1.0, 1.0);
        let hold = (c.drag * car.speed * car.speed + c.rolling_resistance) / c.max_accel;
        let pedal = (hold + SPEED_GAIN * (c.expert_speed - car.speed)).clamp(-1.0, 1.0);
        [steer, pedal]
    }
}

/// The lane beside each obstacle (lanes of the obstacles in `lanes`),
/// avoiding each obstacle's lane, starting from `start`, with the least
/// sum of squared lane changes (ties go to the lower lane).
fn plan_lanes(lanes: &[usize], start: usize) -> Vec<usize> {
    let n = lanes.len();
    if n == 0 {
        return Vec::new();
    }
    let inf = u64::MAX / 4;
    let step = |a: usize, b: usize| (a.abs_diff(b) * a.abs_diff(b)) as u64;
    let mut cost = vec![[inf; NUM_LANES]; n];
    let mut from = vec![[0usize; NUM_LANES]; n];
    for c in 0..NUM_LANES {
        if c != lanes[0] {
            cost[0][c] = step(start, c);
        }
    }
    for i in 1..n {
        for c in 0..NUM_LANES {
            if c == lanes[i] {
                continue;
            }
            for p in 0..NUM_LANES {
                let v = cost[i - 1][p].saturating_add(step(p, c));
                if v < cost[i][c] {
                    cost[i][c] = v;
                    from[i][c] = p;
                }
            }
        }
    }
    let mut best = 0;
    for c in 1..NUM_LANES {
        if cost[n - 1][c] < cost[n - 1][best] {
            best = c;
        }
    }
    let mut plan = vec![0; n];
    plan[n - 1] = best;
    for i in (1..n).rev() {
        plan[i - 1] = from[i][plan[i]];
    }
    plan
}

/// Drives one expert episode on `config`'s track from reset seed `seed`.
///
/// # Errors
/// [`crate::Error::InvalidConfig`] for an invalid config.
pub fn expert_episode(config: &DriveConfig, seed: u64) -> Result<(Trajectory, EpisodeSummary)> {
    let mut env = make_env(config)?;
    let expert = Expert::new(env.inner().world());
    let (obs, _) = env.reset(Some(seed))?;
    let (trajectory, run) = record_episode(
        &mut env,
        obs,
        None,
        |env, _| Ok::<_, crate::Error>(expert.act(env.inner().car()).to_vec()),
        |_, _| Ok(()),
    )?;
    let summary = EpisodeSummary {
        success: run.last.info.get(INFO_SUCCESS) == Some(1.0),
        distance: trajectory.rewards.iter().flatten().sum(),
        steps: trajectory.actions.len(),
    };
    Ok((trajectory, summary))
}

/// `episodes` scripted demonstrations on `config`'s track, with true
/// rewards; episode `k`'s reset seed is the `k`-th number of the
/// [`Stream::Demo`] stream of `seed`. The set records its road
/// ([`crate::scenario`]) and that a script made it.
///
/// # Errors
/// [`crate::Error::InvalidConfig`] for an invalid config.
pub fn expert_demos(config: &DriveConfig, episodes: usize, seed: u64) -> Result<Demos> {
    let mut demos = Demos::new(ENV_ID, OBS_DIM, ACT_DIM, Some(CONTROL_HZ));
    demos.source = Some(DemoSource::Script);
    crate::scenario::set_road(&mut demos, config)?;
    let mut rng = Seeder::new(seed).rng(Stream::Demo);
    for _ in 0..episodes {
        let (t, _) = expert_episode(config, rng.next_u64())?;
        demos.trajectories.push(t);
    }
    Ok(demos)
}

/// Who drives scripted demonstrations: the smooth [`Expert`] that knows the
/// whole layout, or the person-like [`crate::HumanDriver`] (key taps
/// through the recorder's key model, reaction delays, lane wobble, only the
/// road ahead in view) with its default [`crate::HumanConfig`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ExpertStyle {
    /// The scripted expert ([`expert_demos`]).
    #[default]
    Script,
    /// The person-like driver ([`crate::human_demos`]).
    Human,
}

impl ExpertStyle {
    /// `episodes` demonstrations on `config`'s road by this driver, from the
    /// demo stream of `seed`.
    ///
    /// # Errors
    /// [`crate::Error::InvalidConfig`] for an invalid config.
    pub fn demos(self, config: &DriveConfig, episodes: usize, seed: u64) -> Result<Demos> {
        match self {
            ExpertStyle::Script => expert_demos(config, episodes, seed),
            ExpertStyle::Human => {
                crate::human_demos(config, &crate::HumanConfig::default(), episodes, seed)
            }
        }
    }

    /// Who drove, for a summary line.
    pub fn who(self) -> &'static str {
        match self {
            ExpertStyle::Script => "scripted expert",
            ExpertStyle::Human => "person-like (human-style script)",
        }
    }
}

impl std::str::FromStr for ExpertStyle {
    type Err = String;
    /// `script` or `human`.
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "script" => Ok(ExpertStyle::Script),
            "human" => Ok(ExpertStyle::Human),
            other => Err(format!("unknown style `{other}` (script or human)")),
        }
    }
}

/// Runs the expert once on each track seed in `track_seeds` (reset seed
/// 0) and returns the summaries.
///
/// # Errors
/// [`crate::Error::InvalidConfig`] for an invalid config.
pub fn expert_success(
    config: &DriveConfig,
    track_seeds: impl IntoIterator<Item = u64>,
) -> Result<Vec<(u64, EpisodeSummary)>> {
    track_seeds
        .into_iter()
        .map(|s| {
            let c = DriveConfig {
                track_seed: s,
                ..config.clone()
            };
            expert_episode(&c, s).map(|(_, e)| (s, e))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plan_avoids_every_obstacle_and_moves_one_lane_at_most() {
        let lanes = [1, 0, 1, 2, 2, 1, 0, 0, 2, 1];
        let plan = plan_lanes(&lanes, 1);
        for (c, l) in plan.iter().zip(&lanes) {
            assert_ne!(c, l);
        }
        assert!(plan[0].abs_diff(1) <= 1);
        for w in plan.windows(2) {
            assert!(w[0].abs_diff(w[1]) <= 1, "{plan:?}");
        }
        // Obstacles in lane 1 and 0: lane 2 passes both, no change needed.
        assert_eq!(plan_lanes(&[1, 0], 1), vec![2, 2]);
    }

    #[test]
    fn reference_is_smooth_between_knots() {
        let world = World::new(&DriveConfig::default()).unwrap();
        let e = Expert::new(&world);
        let c = world.config();
        let clear = c.car_length + CLEAR_MARGIN;
        for (o, lane) in world.track().obstacles.iter().zip(e.plan()) {
            for dx in [-clear, 0.0, clear] {
                assert_eq!(e.reference(o.x + dx), c.lane_center(*lane));
            }
        }
        let mut prev = e.reference(0.0);
        let mut x = 0.0;
        while x < c.road_length {
            x += 0.5;
            let y = e.reference(x);
            assert!((y - prev).abs() < 0.1, "jump at {x}");
            prev = y;
        }
    }

    #[test]
    fn styles_parse_by_name_and_drive_their_own_way() {
        assert_eq!("script".parse(), Ok(ExpertStyle::Script));
        assert_eq!("human".parse(), Ok(ExpertStyle::Human));
        assert!("robot".parse::<ExpertStyle>().is_err());
        let c = DriveConfig::default();
        let script = ExpertStyle::Script.demos(&c, 1, 3).unwrap();
        assert_eq!(script, expert_demos(&c, 1, 3).unwrap());
        let human = ExpertStyle::Human.demos(&c, 1, 3).unwrap();
        assert_ne!(human.trajectories, script.trajectories);
    }
}
