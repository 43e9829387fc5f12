//! The environment: a kinematic bicycle car on the road, a parry2d lidar
//! and collision queries, and the [`red_core::Env`] implementation.

use parry2d::math::{Pose, Vector};
use parry2d::query::{Ray, RayCast, intersection_test};
use parry2d::shape::Cuboid;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use red_core::{BoxSpace, Env, Info, Space, Step, TimeLimit};
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

use crate::config::{ACT_DIM, DT, DriveConfig, NUM_LANES, NUM_RAYS, OBS_DIM};
use crate::track::Track;
use crate::{Error, Result};

/// What one scripted episode achieved (the expert's or the person-like
/// driver's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EpisodeSummary {
    /// Whether the car reached the end of the road.
    pub success: bool,
    /// Distance along the road (the return).
    pub distance: f64,
    /// Control steps taken.
    pub steps: usize,
}

/// Integration sub-steps per 20 Hz control step; collisions and the end of
/// the road are checked after each (at 100 km/h a sub-step moves 0.35 m).
const SUBSTEPS: usize = 4;
/// Half the thickness of a wall.
const WALL_HALF_THICKNESS: f64 = 0.5;
/// Half the length of a wall shape; walls are centred on the car for
/// queries, so this only has to exceed the lidar range.
const WALL_HALF_LENGTH: f64 = 1.0e4;

/// Info key: fraction of the road completed, in `[0, 1]`.
pub const INFO_PROGRESS: &str = "progress";
/// Info key: distance travelled along the road since the start, metres.
pub const INFO_DISTANCE: &str = "distance";
/// Info key: 1 when the car reached the end of the road, else 0.
pub const INFO_SUCCESS: &str = "success";
/// Info key: 1 when the car hit an obstacle or a wall, else 0.
pub const INFO_COLLISION: &str = "collision";
/// Info key: the car's speed, m/s.
pub const INFO_SPEED: &str = "speed";

/// The car's pose and speed. `x` runs along the road from the start,
/// `y` to the left of the driving direction from the centre line,
/// `heading` is counter-clockwise from the road's direction.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CarState {
    /// Position of the car's centre along the road, metres.
    pub x: f64,
    /// Lateral position of the car's centre, metres (positive = left).
    pub y: f64,
    /// Heading relative to the road, radians (positive = turned left).
    pub heading: f64,
    /// Speed, m/s (never negative: the car has no reverse gear).
    pub speed: f64,
}

impl CarState {
    /// The state at the start of an episode whose first observation is
    /// `obs`: `x = 0`, and lateral offset, heading and speed read back from
    /// the observation. Used to replay a demonstration's actions.
    ///
    /// # Errors
    /// [`Error::Replay`] if `obs` is not an observation of this scenario.
    pub fn from_first_observation(config: &DriveConfig, obs: &[f64]) -> Result<Self> {
        if obs.len() != OBS_DIM {
            return Err(Error::Replay {
                reason: format!("an observation has {OBS_DIM} numbers, got {}", obs.len()),
            });
        }
        Ok(Self {
            x: 0.0,
            y: obs[NUM_RAYS] * config.half_width(),
            heading: obs[NUM_RAYS + 1] * config.heading_scale,
            speed: obs[NUM_RAYS + 3] * config.max_speed,
        })
    }
}

/// How one control step ended for the car.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Outcome {
    Driving,
    Collision,
    Success,
}

/// The static world: the road's obstacles and walls as parry2d shapes, and
/// the lidar's ray directions.
#[derive(Debug, Clone)]
pub struct World {
    config: DriveConfig,
    track: Track,
    car: Cuboid,
    obstacle: Cuboid,
    wall: Cuboid,
    ray_angles: [f64; NUM_RAYS],
}

impl World {
    /// The world for `config` (its layout from `config.track_seed`).
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] if the config is invalid.
    pub fn new(config: &DriveConfig) -> Result<Self> {
        config.validate()?;
        let half = Vector::new(
            0.5 * config.car_length as f32,
            0.5 * config.car_width as f32,
        );
        let grown = half + Vector::splat(config.collision_margin as f32);
        Ok(Self {
            config: config.clone(),
            track: Track::generate(config),
            car: Cuboid::new(grown),
            obstacle: Cuboid::new(half),
            wall: Cuboid::new(Vector::new(
                WALL_HALF_LENGTH as f32,
                WALL_HALF_THICKNESS as f32,
            )),
            ray_angles: config.ray_angles(),
        })
    }

    /// The same road seen in a mirror: every obstacle in the lane on the
    /// other side of the centre line. A car at `(x, -y)` with heading
    /// `-h` sees in it what a car at `(x, y)` with heading `h` sees here,
    /// left and right swapped ([`mirror_pair`]).
    pub fn mirrored(&self) -> Self {
        let mut w = self.clone();
        for o in &mut w.track.obstacles {
            o.lane = NUM_LANES - 1 - o.lane;
            o.y = -o.y;
        }
        w
    }

    /// The settings.
    pub fn config(&self) -> &DriveConfig {
        &self.config
    }

    /// The layout.
    pub fn track(&self) -> &Track {
        &self.track
    }

    /// Directions of the rays relative to the car's heading, radians.
    pub fn ray_angles(&self) -> &[f64; NUM_RAYS] {
        &self.ray_angles
    }

    /// Centre lines (lateral positions) of the two walls: right, left.
    fn wall_centres(&self) -> [f64; 2] {
        let c = self.config.half_width() + WALL_HALF_THICKNESS;
        [-c, c]
    }

    /// Lidar ranges in metres from the car's centre, each at most
    /// `lidar_range`, written into `out` (ray order of [`Self::ray_angles`]).
    /// Queries are made in coordinates centred on the car, in `f32`.
    pub fn lidar(&self, car: &CarState, out: &mut [f64; NUM_RAYS]) {
        let range = self.config.lidar_range;
        let reach = range + self.config.car_length;
        let near = self.track.between(car.x - reach, car.x + reach);
        let walls = self.wall_centres();
        for (r, angle) in out.iter_mut().zip(&self.ray_angles) {
            let (s, c) = (car.heading + angle).sin_cos();
            let dir = Vector::new(c as f32, s as f32);
            let mut best = range as f32;
            for o in near {
                // The obstacle's frame is a translation of the car's, so the
                // ray is cast in the obstacle's local coordinates directly.
                let origin = Vector::new((car.x - o.x) as f32, (car.y - o.y) as f32);
                if let Some(t) = self
                    .obstacle
                    .cast_local_ray(&Ray::new(origin, dir), best, true)
                {
                    best = best.min(t);
                }
            }
            for wy in walls {
                let origin = Vector::new(0.0, (car.y - wy) as f32);
                if let Some(t) = self.wall.cast_local_ray(&Ray::new(origin, dir), best, true) {
                    best = best.min(t);
                }
            }
            *r = f64::from(best);
        }
    }

    /// Whether the car's body (grown by `collision_margin`) overlaps an
    /// obstacle or a wall.
    pub fn collides(&self, car: &CarState) -> bool {
        let pose = Pose::new(Vector::ZERO, car.heading as f32);
        let reach = self.config.car_length + 2.0 * self.config.collision_margin + 1.0;
        for o in self.track.between(car.x - reach, car.x + reach) {
            let other =
                Pose::from_translation(Vector::new((o.x - car.x) as f32, (o.y - car.y) as f32));
            if hits(&pose, &self.car, &other, &self.obstacle) {
                return true;
            }
        }
        // Cheap exact pre-check: the car's lateral extent against the road.
        let (s, c) = car.heading.sin_cos();
        let m = self.config.collision_margin;
        let extent = (0.5 * self.config.car_length + m) * s.abs()
            + (0.5 * self.config.car_width + m) * c.abs();
        if car.y.abs() + extent < self.config.half_width() - 1e-3 {
            return false;
        }
        self.wall_centres().iter().any(|wy| {
            let other = Pose::from_translation(Vector::new(0.0, (wy - car.y) as f32));
            hits(&pose, &self.car, &other, &self.wall)
        })
    }

    /// The 24-number observation of `car` given its lidar ranges (metres):
    /// `[ranges / lidar_range (20), y / half_width, heading / heading_scale,
    /// (half_width - |y|) / half_width, speed / max_speed]`, each clipped to
    /// the observation space.
    pub fn observation(&self, car: &CarState, ranges: &[f64; NUM_RAYS], out: &mut Vec<f64>) {
        let c = &self.config;
        let hw = c.half_width();
        out.clear();
        out.extend(ranges.iter().map(|r| (r / c.lidar_range).clamp(0.0, 1.0)));
        out.push((car.y / hw).clamp(-1.0, 1.0));
        out.push((wrap_angle(car.heading) / c.heading_scale).clamp(-1.0, 1.0));
        out.push(((hw - car.y.abs()) / hw).clamp(0.0, 1.0));
        out.push((car.speed / c.max_speed).clamp(0.0, 1.0));
    }

    /// Advances the car by one control step under `action` (clipped to
    /// `[-1, 1]^2`), checking the end of the road and collisions after each
    /// sub-step.
    fn advance(&self, car: &mut CarState, action: &[f64]) -> Outcome {
        let c = &self.config;
        let steer = action[0].clamp(-1.0, 1.0);
        let pedal = action[1].clamp(-1.0, 1.0);
        let accel = if pedal >= 0.0 {
            pedal * c.max_accel
        } else {
            pedal * c.max_brake
        };
        let h = DT / SUBSTEPS as f64;
        let half_wb = 0.5 * c.wheelbase;
        for _ in 0..SUBSTEPS {
            let delta = steer * c.steer_limit(car.speed);
            // Kinematic bicycle about the centre, rear and front axles at
            // half the wheelbase: slip angle beta.
            let beta = (0.5 * delta.tan()).atan();
            let (s, co) = (car.heading + beta).sin_cos();
            car.x += car.speed * co * h;
            car.y += car.speed * s * h;
            car.heading += car.speed / half_wb * beta.sin() * h;
            let resist = if car.speed > 0.0 {
                c.drag * car.speed * car.speed + c.rolling_resistance
            } else {
                0.0
            };
            car.speed = (car.speed + (accel - resist) * h).clamp(0.0, c.max_speed);
            if car.x >= c.road_length {
                return Outcome::Success;
            }
            if self.collides(car) {
                return Outcome::Collision;
            }
        }
        Outcome::Driving
    }
}

fn hits(p1: &Pose, s1: &Cuboid, p2: &Pose, s2: &Cuboid) -> bool {
    // Cuboid against cuboid is always supported by parry's dispatcher.
    intersection_test(p1, s1, p2, s2)
        .map(|i| i.intersecting)
        .unwrap_or(true)
}

/// Turns an observation and action into those of the road seen in a
/// mirror ([`World::mirrored`]): the lidar's rays in reverse order (the
/// fan is symmetric about the heading), the lateral offset and the heading
/// negated, the distance to the wall and the speed kept; the steering
/// negated, the pedal kept. An observation extended by the last action
/// (steering, pedal: [`red_core::LastAction`]) has that steering negated
/// too. Used to double a demonstration's pairs (`train.mirror_demos` of
/// the driving experiment).
///
/// # Panics
/// If `obs` is shorter than [`OBS_DIM`] or `act` is empty.
pub fn mirror_pair(obs: &mut [f64], act: &mut [f64]) {
    obs[..NUM_RAYS].reverse();
    obs[NUM_RAYS] = -obs[NUM_RAYS];
    obs[NUM_RAYS + 1] = -obs[NUM_RAYS + 1];
    if let Some(steer) = obs.get_mut(OBS_DIM) {
        *steer = -*steer;
    }
    act[0] = -act[0];
}

/// The observations ([`OBS_DIM`] numbers each) of a recorded path moved
/// sideways by whole lanes: for each shift `k * lane_width` (`k` = -2,
/// -1, 1, 2 on three lanes) and each step `t` of `poses` but the last
/// (the last pose has no action), the observation of `poses[t]` moved by
/// the shift, kept only if, over steps `t` to `t + clear_steps`:
/// - the recorded path keeps its lane (the nearest lane centre): a lane
///   change has its reason in the recorded lane, which the moved one does
///   not share;
/// - the moved car is on the road and touches nothing (at control steps,
///   not sub-steps).
///
/// Steps past the path's last pose count as clear only when `finished`
/// (the path ended at the end of the road); otherwise the last
/// `clear_steps` steps are dropped. With `undriven_only`, a step is moved
/// only into a lane the recorded path never keeps for more than
/// `clear_steps` steps in a row: the moved pairs then stand in where the
/// demonstration shows no lane keeping of its own.
///
/// The car's motion does not depend on its lateral position, so a moved
/// path is the one the same actions drive from the moved start until it
/// meets something: the kept steps are the recorded lane keeping, done in
/// another lane by a driver still clear `clear_steps` steps later.
/// Returns `(k, t, observation)` in order of `k`, then `t`.
pub fn lane_shifted(
    world: &World,
    poses: &[CarState],
    finished: bool,
    clear_steps: usize,
    undriven_only: bool,
) -> Vec<(i64, usize, Vec<f64>)> {
    if poses.is_empty() {
        return Vec::new();
    }
    let n = poses.len() - 1;
    let road = world.config();
    let (lane, hw) = (road.lane_width, road.half_width());
    // For each step, the first one from it on at which the recorded path
    // has just changed lanes.
    let lanes: Vec<usize> = poses.iter().map(|p| road.nearest_lane(p.y)).collect();
    let next_change = first_at_or_after(n + 1, |t| t > 0 && lanes[t] != lanes[t - 1]);
    // The lanes the recorded path keeps for more than `clear_steps` steps
    // in a row somewhere.
    let mut driven = [false; NUM_LANES];
    let mut kept_for = 0;
    for t in 0..lanes.len() {
        kept_for = if t > 0 && lanes[t] == lanes[t - 1] {
            kept_for + 1
        } else {
            1
        };
        if kept_for > clear_steps {
            driven[lanes[t]] = true;
        }
    }
    let max_shift = NUM_LANES as i64 - 1;
    let mut out = Vec::new();
    let mut ranges = [0.0; NUM_RAYS];
    for k in (-max_shift..=max_shift).filter(|&k| k != 0) {
        let moved: Vec<CarState> = poses
            .iter()
            .map(|p| CarState {
                y: p.y + k as f64 * lane,
                ..*p
            })
            .collect();
        // A car moved past a wall's far side touches nothing: off the road
        // counts as a hit too.
        let next_hit = first_at_or_after(n + 1, |t| {
            moved[t].y.abs() >= hw || world.collides(&moved[t])
        });
        for t in 0..n {
            let last = t + clear_steps;
            let blocked = |at: Option<usize>| at.is_some_and(|at| at <= last);
            // A change at step t itself is the lane t is in, not a change.
            if blocked(next_hit[t]) || blocked(next_change[t + 1]) || (!finished && last > n) {
                continue;
            }
            let to = lanes[t] as i64 + k;
            if undriven_only && (0..NUM_LANES as i64).contains(&to) && driven[to as usize] {
                continue;
            }
            world.lidar(&moved[t], &mut ranges);
            let mut obs = Vec::with_capacity(OBS_DIM);
            world.observation(&moved[t], &ranges, &mut obs);
            out.push((k, t, obs));
        }
    }
    out
}

/// The observations ([`OBS_DIM`] numbers each) of a recorded path with the
/// car nudged off it: for each nudge `nudges[i]` = `(dy, dheading)` (metres
/// to the left, radians to the left) and each step `t` of `poses` but the
/// last (the last pose has no action), the observation of `poses[t]` moved
/// sideways by `dy` and turned by `dheading`, kept only if the nudged car
/// is on the road and touches nothing (walls included) at that step. Returns `(i, t,
/// observation)` in order of `i`, then `t`.
///
/// These are the states a driver who holds the recorded line would meet
/// after a small slip; what to do there is the caller's choice (e.g. the
/// recorded action plus a steer back).
pub fn nudged(
    world: &World,
    poses: &[CarState],
    nudges: &[(f64, f64)],
) -> Vec<(usize, usize, Vec<f64>)> {
    let n = poses.len().saturating_sub(1);
    let mut out = Vec::new();
    let mut ranges = [0.0; NUM_RAYS];
    for (i, &(dy, dheading)) in nudges.iter().enumerate() {
        for (t, pose) in poses[..n].iter().enumerate() {
            let car = CarState {
                y: pose.y + dy,
                heading: pose.heading + dheading,
                ..*pose
            };
            // Past a wall's far side the car touches nothing: off the road
            // counts as a hit too.
            if car.y.abs() >= world.config().half_width() || world.collides(&car) {
                continue;
            }
            world.lidar(&car, &mut ranges);
            let mut obs = Vec::with_capacity(OBS_DIM);
            world.observation(&car, &ranges, &mut obs);
            out.push((i, t, obs));
        }
    }
    out
}

/// The lane (0-2, 0 the right-hand one) nearest the car whose observation
/// on `road` is `obs` ([`World::observation`]: input `NUM_RAYS` is the
/// lateral position over the road's half width).
pub fn observed_lane(road: &DriveConfig, obs: &[f64]) -> usize {
    road.nearest_lane(obs[NUM_RAYS] * road.half_width())
}

/// For each `t < len`, the first `s >= t` with `marked(s)`, if any.
fn first_at_or_after(len: usize, marked: impl Fn(usize) -> bool) -> Vec<Option<usize>> {
    let mut out = vec![None; len];
    let mut next = None;
    for t in (0..len).rev() {
        if marked(t) {
            next = Some(t);
        }
        out[t] = next;
    }
    out
}

/// `a` wrapped into `(-pi, pi]`.
pub fn wrap_angle(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let w = (a + PI).rem_euclid(TAU) - PI;
    if w <= -PI { w + TAU } else { w }
}

/// The driving scenario as a [`red_core::Env`]. Observations: 24 numbers
/// (see [`World::observation`]); actions: `[steering, accelerator/brake]` in
/// `[-1, 1]^2` (steering +1 turns left at the steering limit; pedal +1 full
/// throttle, -1 full brake). Out-of-range actions are clipped. The reward
/// is the distance gained along the road this step. It terminates on a
/// collision (info `collision` = 1) and at the end of the road (info
/// `success` = 1); it never truncates itself: wrap it in
/// [`red_core::TimeLimit`] or build it with [`make_env`].
#[derive(Debug, Clone)]
pub struct DriveEnv {
    world: World,
    car: CarState,
    ranges: [f64; NUM_RAYS],
    rng: ChaCha8Rng,
    observation_space: Space,
    action_space: Space,
    in_episode: bool,
    scratch: Vec<f64>,
    /// The roads of [`DriveEnv::set_road_pool`].
    road_pool: Option<RoadPool>,
    /// The road the env was built on (track seed).
    home_track_seed: u64,
    /// Share of seeded resets on the home road while a pool is set
    /// ([`DriveEnv::set_home_share`]).
    home_share: f64,
    /// `(states, share)` of [`DriveEnv::set_start_states`].
    start_pool: Option<(Vec<CarState>, f64)>,
    /// [`DriveEnv::set_crash_restarts`].
    crash_restarts: Option<CrashRestarts>,
}

/// Restarts from states shortly before earlier crashes
/// ([`DriveEnv::set_crash_restarts`]).
#[derive(Debug, Clone)]
struct CrashRestarts {
    share: f64,
    back_steps: usize,
    capacity: usize,
    /// `(track seed, state)` from `back_steps` steps before each recorded
    /// crash; once full, the oldest is replaced first.
    pool: Vec<(u64, CarState)>,
    next: usize,
    /// The states before the episode's last `back_steps` steps, oldest
    /// first.
    recent: VecDeque<CarState>,
}

/// The roads a seeded reset draws from ([`DriveEnv::set_road_pool`]).
#[derive(Debug, Clone, Copy)]
struct RoadPool {
    first: u64,
    count: u64,
}

/// The default scenario wrapped in its time limit (`config.time_limit`).
///
/// ```
/// use red_core::Env;
/// let mut env = red_drive::make_env(&red_drive::DriveConfig::default())?;
/// let (obs, _) = env.reset(Some(0))?;
/// assert_eq!(obs.len(), 24);
/// let step = env.step(&[0.0, 0.15])?;
/// assert!(step.reward > 1.0); // about 1.4 m per step at 100 km/h
/// # Ok::<(), red_drive::Error>(())
/// ```
///
/// # Errors
/// [`Error::InvalidConfig`] for an invalid config.
pub fn make_env(config: &DriveConfig) -> Result<TimeLimit<DriveEnv>> {
    let env = DriveEnv::new(config)?;
    Ok(TimeLimit::new(env, config.time_limit)?)
}

impl DriveEnv {
    /// The scenario for `config`, without a time limit.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] for an invalid config.
    pub fn new(config: &DriveConfig) -> Result<Self> {
        let world = World::new(config)?;
        let mut low = vec![0.0; OBS_DIM];
        let mut high = vec![1.0; OBS_DIM];
        low[NUM_RAYS] = -1.0;
        low[NUM_RAYS + 1] = -1.0;
        high[NUM_RAYS] = 1.0;
        high[NUM_RAYS + 1] = 1.0;
        Ok(Self {
            world,
            car: CarState {
                x: 0.0,
                y: 0.0,
                heading: 0.0,
                speed: 0.0,
            },
            ranges: [0.0; NUM_RAYS],
            rng: ChaCha8Rng::seed_from_u64(0),
            observation_space: Space::Box(BoxSpace::new(low, high)?),
            action_space: Space::Box(BoxSpace::uniform(ACT_DIM, -1.0, 1.0)),
            in_episode: false,
            scratch: Vec::with_capacity(OBS_DIM),
            road_pool: None,
            home_track_seed: config.track_seed,
            home_share: 0.0,
            start_pool: None,
            crash_restarts: None,
        })
    }

    /// Makes every [`Env::reset`] with a seed drive on one of `count` roads
    /// (but for the share of [`DriveEnv::set_home_share`]): the road of
    /// track seed `first + seed % count` (other settings as this env's),
    /// so training can see many roads while evaluation keeps its own.
    /// `count = 0` turns it off: the next seeded reset drives the road the
    /// env was built on again.
    pub fn set_road_pool(&mut self, first: u64, count: u64) {
        self.road_pool = (count > 0).then_some(RoadPool { first, count });
    }

    /// With a road pool, makes a share of the seeded resets drive on the
    /// home road (the road the env was built on: for training, the run's,
    /// which is the demonstration's) instead of a pool road, drawn by the
    /// reset's random stream. `share = 0` (the default) draws no random
    /// number, so episodes are as without it. The share outlives a later
    /// [`DriveEnv::set_road_pool`].
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] for a share outside `[0, 1]`, or above 0
    /// with no road pool set.
    pub fn set_home_share(&mut self, share: f64) -> Result<()> {
        if !(0.0..=1.0).contains(&share) {
            return Err(Error::InvalidConfig {
                field: "home share",
                reason: format!(
                    "the share of episodes on the home road must be in [0, 1], got {share}"
                ),
            });
        }
        if share > 0.0 && self.road_pool.is_none() {
            return Err(Error::InvalidConfig {
                field: "home share",
                reason: "a share of episodes on the home road needs a road pool: set one first"
                    .into(),
            });
        }
        self.home_share = share;
        Ok(())
    }

    /// Makes a share of the episodes start at one of `states` (drawn by the
    /// reset's random stream) instead of at the road's start, with the same
    /// start noise on the lateral offset, heading and speed; the others
    /// start as usual. With the states a demonstration passed through, this
    /// is reference-state initialisation (Peng et al. 2018, DeepMimic):
    /// training episodes begin at every part of the demonstrated drive, so a
    /// manoeuvre far down the road is practised as often as the start.
    /// `share = 0` or no states turn it off (no random number is drawn
    /// then, so episodes are as without it). The states are for this env's
    /// road: a road pool ([`DriveEnv::set_road_pool`]) cannot be combined
    /// with it.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] for a share outside `[0, 1]`, a non-finite
    /// state, or a road pool already set.
    pub fn set_start_states(&mut self, states: Vec<CarState>, share: f64) -> Result<()> {
        if !(0.0..=1.0).contains(&share) {
            return Err(Error::InvalidConfig {
                field: "start share",
                reason: format!(
                    "the share of episodes starting at given states must be in [0, 1], got {share}"
                ),
            });
        }
        if let Some(bad) = states
            .iter()
            .find(|c| ![c.x, c.y, c.heading, c.speed].iter().all(|v| v.is_finite()))
        {
            return Err(Error::InvalidConfig {
                field: "start states",
                reason: format!("a start state is not finite: {bad:?}"),
            });
        }
        let on = share > 0.0 && !states.is_empty();
        if on && self.road_pool.is_some() {
            return Err(Error::InvalidConfig {
                field: "start states",
                reason: "start states are on this env's road and cannot be combined with a road \
                         pool"
                    .into(),
            });
        }
        self.start_pool = on.then_some((states, share));
        Ok(())
    }

    /// Makes a share of the seeded resets start where an earlier episode
    /// of this env was `back_steps` steps before it crashed (on that
    /// episode's road, with the usual start noise) instead of at the
    /// road's start: failure-state restarts (our addition), so the learner
    /// practises the moments that ended its drives as often as it likes.
    /// Each collision at least `back_steps` steps into its episode adds
    /// its state to a pool of `capacity`, the oldest replaced first; the
    /// pool starts empty and lives as long as the env. `share = 0` turns
    /// it off and empties the pool; with an empty pool no random number is
    /// drawn, so episodes are as without it until the first crash.
    /// Unseeded resets always start at the road's start.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] for a share outside `[0, 1]`, or
    /// `back_steps` or `capacity` of 0 with a share above 0.
    pub fn set_crash_restarts(
        &mut self,
        share: f64,
        back_steps: usize,
        capacity: usize,
    ) -> Result<()> {
        if !(0.0..=1.0).contains(&share) {
            return Err(Error::InvalidConfig {
                field: "crash restarts",
                reason: format!(
                    "the share of episodes restarting before a crash must be in [0, 1], got \
                     {share}"
                ),
            });
        }
        if share > 0.0 && (back_steps == 0 || capacity == 0) {
            return Err(Error::InvalidConfig {
                field: "crash restarts",
                reason: format!(
                    "restarts need at least 1 step back and room for 1 state, got {back_steps} \
                     step(s) back and room for {capacity}"
                ),
            });
        }
        self.crash_restarts = (share > 0.0).then(|| CrashRestarts {
            share,
            back_steps,
            capacity,
            pool: Vec::new(),
            next: 0,
            recent: VecDeque::new(),
        });
        Ok(())
    }

    /// The pool of [`DriveEnv::set_crash_restarts`]: `(track seed, state)`
    /// of each recorded crash still kept, in no particular order.
    pub fn crash_restart_states(&self) -> &[(u64, CarState)] {
        self.crash_restarts.as_ref().map_or(&[], |c| &c.pool)
    }

    /// The static world (settings, layout, shapes).
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The settings.
    pub fn config(&self) -> &DriveConfig {
        &self.world.config
    }

    /// The layout.
    pub fn track(&self) -> &Track {
        &self.world.track
    }

    /// The car's current state.
    pub fn car(&self) -> &CarState {
        &self.car
    }

    /// The current lidar ranges in metres.
    pub fn lidar_ranges(&self) -> &[f64; NUM_RAYS] {
        &self.ranges
    }

    /// Starts an episode from a given state instead of a random one (for
    /// replaying a demonstration) and returns its observation.
    ///
    /// # Errors
    /// [`Error::Replay`] if the state is not finite.
    pub fn reset_to(&mut self, car: CarState) -> Result<Vec<f64>> {
        if ![car.x, car.y, car.heading, car.speed]
            .iter()
            .all(|v| v.is_finite())
        {
            return Err(Error::Replay {
                reason: format!("non-finite start state {car:?}"),
            });
        }
        self.car = car;
        self.car.speed = self.car.speed.clamp(0.0, self.config().max_speed);
        self.in_episode = true;
        if let Some(c) = &mut self.crash_restarts {
            c.recent.clear();
        }
        Ok(self.observe())
    }

    fn observe(&mut self) -> Vec<f64> {
        self.world.lidar(&self.car, &mut self.ranges);
        self.world
            .observation(&self.car, &self.ranges, &mut self.scratch);
        self.scratch.clone()
    }

    fn info(&self, outcome: Outcome) -> Info {
        let c = self.config();
        let along = self.car.x.min(c.road_length);
        let mut info = Info::new();
        info.set(INFO_PROGRESS, (along / c.road_length).clamp(0.0, 1.0));
        info.set(INFO_DISTANCE, along);
        info.set(
            INFO_SUCCESS,
            f64::from(u8::from(outcome == Outcome::Success)),
        );
        info.set(
            INFO_COLLISION,
            f64::from(u8::from(outcome == Outcome::Collision)),
        );
        info.set(INFO_SPEED, self.car.speed);
        info
    }
}

impl Env for DriveEnv {
    fn observation_space(&self) -> &Space {
        &self.observation_space
    }

    fn action_space(&self) -> &Space {
        &self.action_space
    }

    fn reset(&mut self, seed: Option<u64>) -> red_core::Result<(Vec<f64>, Info)> {
        let mut restart = None;
        if let Some(s) = seed {
            self.rng = ChaCha8Rng::seed_from_u64(s);
            // A state before an earlier crash (no number is drawn while the
            // pool is empty).
            if let Some(c) = &self.crash_restarts
                && !c.pool.is_empty()
                && self.rng.random::<f64>() < c.share
            {
                restart = Some(c.pool[self.rng.random_range(0..c.pool.len())]);
            }
            // Its road, a pool road, or the road the env was built on (no
            // pool, or the home share's draw; no number is drawn at share 0).
            let track_seed = match (restart, self.road_pool) {
                (Some((track_seed, _)), _) => track_seed,
                (None, Some(pool))
                    if !(self.home_share > 0.0 && self.rng.random::<f64>() < self.home_share) =>
                {
                    pool.first.wrapping_add(s % pool.count)
                }
                _ => self.home_track_seed,
            };
            if track_seed != self.world.config.track_seed {
                let config = DriveConfig {
                    track_seed,
                    ..self.world.config.clone()
                };
                self.world = World::new(&config)?;
            }
        }
        let c = self.world.config.clone();
        let mut start = CarState {
            x: 0.0,
            y: c.lane_center(1),
            heading: 0.0,
            speed: c.initial_speed,
        };
        if let Some((_, state)) = restart {
            start = state;
        } else if let Some((states, share)) = &self.start_pool
            && self.rng.random::<f64>() < *share
        {
            start = states[self.rng.random_range(0..states.len())];
        }
        let mut noise = |scale: f64| {
            if scale > 0.0 {
                self.rng.random_range(-scale..=scale)
            } else {
                0.0
            }
        };
        start.y += noise(c.start_lateral_noise);
        start.heading += noise(c.start_heading_noise);
        start.speed = (start.speed + noise(c.start_speed_noise)).clamp(0.0, c.max_speed);
        let obs = self.reset_to(start)?;
        Ok((obs, self.info(Outcome::Driving)))
    }

    fn step(&mut self, action: &[f64]) -> red_core::Result<Step> {
        if !self.in_episode {
            return Err(red_core::Error::NeedsReset {
                reason: "step called before reset or after the episode terminated".into(),
            });
        }
        if action.len() != ACT_DIM {
            return Err(red_core::Error::ShapeMismatch {
                what: "drive action".into(),
                expected: format!("{ACT_DIM} numbers [steering, accelerator/brake]"),
                got: format!("{} numbers", action.len()),
            });
        }
        if action.iter().any(|a| !a.is_finite()) {
            return Err(red_core::Error::NonFinite {
                what: "drive action".into(),
            });
        }
        let road = self.config().road_length;
        let before = self.car.x.min(road);
        let mut car = self.car;
        let outcome = self.world.advance(&mut car, action);
        if let Some(c) = &mut self.crash_restarts {
            if c.recent.len() == c.back_steps {
                c.recent.pop_front();
            }
            c.recent.push_back(self.car);
            // Only a crash at least `back_steps` into its episode is kept,
            // so restarts that crash again at once do not pile up copies of
            // their own start.
            if outcome == Outcome::Collision
                && c.recent.len() == c.back_steps
                && let Some(&before) = c.recent.front()
            {
                let entry = (self.world.config.track_seed, before);
                if c.pool.len() < c.capacity {
                    c.pool.push(entry);
                } else {
                    c.pool[c.next] = entry;
                    c.next = (c.next + 1) % c.capacity;
                }
            }
        }
        self.car = car;
        let reward = self.car.x.min(road) - before;
        let terminated = outcome != Outcome::Driving;
        if terminated {
            self.in_episode = false;
        }
        let observation = self.observe();
        Ok(Step {
            observation,
            reward,
            terminated,
            truncated: false,
            info: self.info(outcome),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The margin grows the driven car's body only: a car beside or behind
    /// a stopped car, or by the wall, with 0.25 m to spare collides with a
    /// margin of 0.3 and not with 0.2 (also turned, through the wall's
    /// pre-check); the lidar reads the same; the margin is checked against
    /// the lane's room.
    #[test]
    fn a_collision_margin_grows_the_car_and_nothing_else() {
        let plain = World::new(&DriveConfig::default()).unwrap();
        let c = plain.config().clone();
        let first = plain.track().obstacles[0];
        // Beside the first stopped car, on the road's side of it, with 0.25
        // m of air between the bodies.
        let beside = CarState {
            x: first.x,
            y: first.y - first.y.signum() * (c.car_width + 0.25),
            heading: 0.0,
            speed: 20.0,
        };
        // Before the first car, 0.25 m from the left wall.
        let by_wall = CarState {
            x: 10.0,
            y: c.half_width() - 0.5 * c.car_width - 0.25,
            ..beside
        };
        // Right behind the first stopped car, 0.25 m short of its tail.
        let behind = CarState {
            x: first.x - c.car_length - 0.25,
            y: first.y,
            ..beside
        };
        let with = |m: f64| {
            World::new(&DriveConfig {
                collision_margin: m,
                ..c.clone()
            })
            .unwrap()
        };
        for car in [beside, by_wall, behind] {
            assert!(!plain.collides(&car), "{car:?}");
            assert!(!with(0.2).collides(&car), "{car:?}");
            assert!(with(0.3).collides(&car), "{car:?}");
        }
        // Turned 0.3 rad toward the left wall, its corner 0.25 m from it:
        // the grown corner reaches m (sin 0.3 + cos 0.3) = 1.25 m further
        // out, so 0.15 (0.19 m) misses the wall and 0.3 (0.38 m) hits it.
        let h: f64 = 0.3;
        let reach = 0.5 * c.car_length * h.sin() + 0.5 * c.car_width * h.cos();
        let turned = CarState {
            x: 10.0,
            y: c.half_width() - reach - 0.25,
            heading: h,
            speed: 20.0,
        };
        assert!(!plain.collides(&turned));
        assert!(!with(0.15).collides(&turned));
        assert!(with(0.3).collides(&turned));
        let (mut a, mut b) = ([0.0; NUM_RAYS], [0.0; NUM_RAYS]);
        plain.lidar(&beside, &mut a);
        with(0.3).lidar(&beside, &mut b);
        assert_eq!(a, b);
        // Written only when set, read back when set.
        assert!(!serde_json::to_string(&c).unwrap().contains("margin"));
        let json = serde_json::to_string(&with(0.3).config).unwrap();
        let back: DriveConfig = serde_json::from_str(&json).unwrap();
        assert_eq!(back.collision_margin, 0.3);
        // The lane's free half-width is 0.85 m; the start noise is 0.3 m.
        for (m, field) in [
            (-0.1, "field `collision_margin`"),
            (0.85, "field `collision_margin`"),
            (0.6, "field `start_lateral_noise`"),
        ] {
            let e = DriveConfig {
                collision_margin: m,
                ..c.clone()
            }
            .validate()
            .unwrap_err()
            .to_string();
            assert!(e.contains(field), "{m}: {e}");
        }
    }
    #[test]
    fn no_poses_move_to_nothing() {
        let world = World::new(&DriveConfig::default()).unwrap();
        assert!(lane_shifted(&world, &[], true, 60, false).is_empty());
        let start = CarState {
            x: 0.0,
            y: 0.0,
            heading: 0.0,
            speed: 20.0,
        };
        // One pose has no action, so no step to move.
        assert!(lane_shifted(&world, &[start], true, 0, false).is_empty());
    }

    #[test]
    fn nudged_poses_read_the_nudge_and_skip_a_wall() {
        let road = DriveConfig::default();
        let world = World::new(&road).unwrap();
        assert!(nudged(&world, &[], &[(0.0, 0.1)]).is_empty());
        let at = |y: f64| CarState {
            x: 10.0,
            y,
            heading: 0.02,
            speed: 25.0,
        };
        // The second step's car touches the top wall once turned by 0.5
        // rad: its corner reaches past the road's half width.
        let edge = road.half_width() - 0.5 * road.car_width - 0.05;
        let poses = [at(0.0), at(edge), at(0.0)];
        // Moved 3 m to the left the second car is past the wall, where it
        // touches nothing: off the road, so left out too.
        let past = road.half_width() + 2.0 * road.car_length;
        assert!(!world.collides(&CarState {
            y: past,
            ..poses[1]
        }));
        let nudges = [(0.0, -0.04), (0.0, 0.5), (0.3, 0.0), (past - edge, 0.0)];
        let out = nudged(&world, &poses, &nudges);
        let keys: Vec<(usize, usize)> = out.iter().map(|(i, t, _)| (*i, *t)).collect();
        // Moved 0.3 m to the left the second car is in the wall too.
        assert_eq!(keys, [(0, 0), (0, 1), (1, 0), (2, 0)]);
        let mut ranges = [0.0; NUM_RAYS];
        let mut want = Vec::new();
        let turned = CarState {
            heading: 0.02 - 0.04,
            ..poses[1]
        };
        world.lidar(&turned, &mut ranges);
        world.observation(&turned, &ranges, &mut want);
        assert_eq!(out[1].2, want);
        assert!((want[NUM_RAYS + 1] - (-0.02 / road.heading_scale)).abs() < 1e-12);
        let moved = CarState { y: 0.3, ..poses[0] };
        world.lidar(&moved, &mut ranges);
        world.observation(&moved, &ranges, &mut want);
        assert_eq!(out[3].2, want);
    }

    #[test]
    fn the_observed_lane_is_the_lane_the_car_is_in() {
        let road = DriveConfig::default();
        let world = World::new(&road).unwrap();
        let mut ranges = [0.0; NUM_RAYS];
        let mut obs = Vec::new();
        for lane in 0..NUM_LANES {
            for off in [-1.5, 0.0, 1.5] {
                let car = CarState {
                    x: 10.0,
                    y: road.lane_center(lane) + off,
                    heading: 0.0,
                    speed: 20.0,
                };
                world.lidar(&car, &mut ranges);
                world.observation(&car, &ranges, &mut obs);
                assert_eq!(observed_lane(&road, &obs), lane, "{off}");
            }
        }
        // Lane 0 is the right-hand one: y < 0.
        assert!(road.lane_center(0) < 0.0);
    }

    #[test]
    fn a_road_pool_draws_the_road_from_the_reset_seed() {
        let mut env = DriveEnv::new(&DriveConfig::default()).unwrap();
        env.set_road_pool(500, 3);
        env.reset(Some(4)).unwrap();
        assert_eq!(env.config().track_seed, 501);
        let layout = env.track().obstacles.clone();
        env.reset(Some(2)).unwrap();
        assert_eq!(env.config().track_seed, 502);
        assert_ne!(env.track().obstacles, layout);
        env.reset(Some(7)).unwrap();
        assert_eq!(env.config().track_seed, 501);
        assert_eq!(env.track().obstacles, layout);
        // Without a seed the road stays; with the pool off, a seeded reset
        // drives the road the env was built on again.
        env.reset(None).unwrap();
        assert_eq!(env.config().track_seed, 501);
        env.set_road_pool(0, 0);
        env.reset(Some(2)).unwrap();
        assert_eq!(env.config().track_seed, DriveConfig::default().track_seed);
        assert_eq!(
            env.track().obstacles,
            DriveEnv::new(&DriveConfig::default())
                .unwrap()
                .track()
                .obstacles
        );
    }

    #[test]
    fn a_home_share_sends_some_seeded_resets_back_to_the_home_road() {
        let config = DriveConfig {
            track_seed: 7,
            ..DriveConfig::default()
        };
        let mut env = DriveEnv::new(&config).unwrap();
        // No pool: a share is refused, share 0 is accepted.
        assert!(env.set_home_share(0.5).is_err());
        env.set_home_share(0.0).unwrap();
        env.set_road_pool(500, 3);
        assert!(env.set_home_share(1.5).is_err());
        assert!(env.set_home_share(f64::NAN).is_err());
        let roads = |env: &mut DriveEnv| -> Vec<(u64, Vec<f64>)> {
            (0..200)
                .map(|s| {
                    let (obs, _) = env.reset(Some(s)).unwrap();
                    (env.config().track_seed, obs)
                })
                .collect()
        };
        // Share 0: every seeded reset starts exactly as on the pool's road
        // without any share (no random number drawn for it).
        let pool_only = roads(&mut env);
        for (s, (track, obs)) in pool_only.iter().enumerate() {
            let mut plain = DriveEnv::new(&DriveConfig {
                track_seed: 500 + s as u64 % 3,
                ..config.clone()
            })
            .unwrap();
            assert_eq!(*track, 500 + s as u64 % 3);
            assert_eq!(*obs, plain.reset(Some(s as u64)).unwrap().0, "seed {s}");
        }
        // Share 1: always home.
        env.set_home_share(1.0).unwrap();
        assert!(roads(&mut env).iter().all(|(t, _)| *t == 7));
        // Share 0.5: about half home, the others on the road of seed % 3,
        // the same draw for the same seed.
        env.set_home_share(0.5).unwrap();
        let mixed = roads(&mut env);
        let home = mixed.iter().filter(|(t, _)| *t == 7).count();
        assert!((70..=130).contains(&home), "{home} of 200 resets home");
        for (s, ((m, _), (p, _))) in mixed.iter().zip(&pool_only).enumerate() {
            assert!(*m == 7 || m == p, "seed {s}: road {m}, pool road {p}");
        }
        assert_eq!(roads(&mut env), mixed);
        // Setting the pool again, while on a pool road, keeps the home road
        // (the one built) and the share.
        env.reset(Some(1)).unwrap();
        env.set_road_pool(500, 3);
        assert_eq!(roads(&mut env), mixed);
        env.set_home_share(1.0).unwrap();
        env.reset(Some(3)).unwrap();
        assert_eq!(env.config().track_seed, 7);
        let fresh = DriveEnv::new(&config).unwrap();
        assert_eq!(env.track().obstacles, fresh.track().obstacles);
    }

    #[test]
    fn start_states_take_their_share_and_leave_other_resets_alone() {
        let config = DriveConfig::default();
        let mut plain = DriveEnv::new(&config).unwrap();
        let mut pooled = DriveEnv::new(&config).unwrap();
        let far = CarState {
            x: 500.0,
            y: config.lane_center(2),
            heading: 0.0,
            speed: 25.0,
        };
        // Share 0: the same episodes as without a pool.
        pooled.set_start_states(vec![far], 0.0).unwrap();
        for s in 0..5 {
            assert_eq!(
                plain.reset(Some(s)).unwrap().0,
                pooled.reset(Some(s)).unwrap().0
            );
        }
        pooled.set_start_states(vec![far], 0.5).unwrap();
        let mut at_far = 0;
        for s in 0..200 {
            pooled.reset(Some(s)).unwrap();
            let car = *pooled.car();
            if car.x == 500.0 {
                at_far += 1;
                assert!((car.y - far.y).abs() <= config.start_lateral_noise + 1e-12);
            } else {
                assert_eq!(car.x, 0.0);
            }
        }
        assert!(
            (70..=130).contains(&at_far),
            "{at_far} of 200 at the given state"
        );
        // The same seed, the same start.
        pooled.reset(Some(3)).unwrap();
        let a = *pooled.car();
        pooled.reset(Some(3)).unwrap();
        assert_eq!(a, *pooled.car());
        assert!(pooled.set_start_states(vec![far], 1.5).is_err());
        let nan = CarState { x: f64::NAN, ..far };
        assert!(pooled.set_start_states(vec![nan], 0.5).is_err());
        pooled.set_start_states(vec![], 0.0).unwrap();
        pooled.set_road_pool(500, 3);
        assert!(pooled.set_start_states(vec![far], 0.5).is_err());
    }

    /// Steers hard left from a seeded reset until the car hits the wall;
    /// returns the states before each step.
    fn crash_into_the_wall(env: &mut DriveEnv, seed: u64) -> Vec<CarState> {
        env.reset(Some(seed)).unwrap();
        let mut before = Vec::new();
        loop {
            before.push(*env.car());
            let step = env.step(&[1.0, 0.5]).unwrap();
            if step.terminated {
                assert_eq!(step.info.get(INFO_COLLISION), Some(1.0));
                return before;
            }
            assert!(before.len() < 500, "no crash");
        }
    }

    #[test]
    fn crash_restarts_start_before_earlier_crashes_on_their_road() {
        let config = DriveConfig::default();
        let mut plain = DriveEnv::new(&config).unwrap();
        let mut env = DriveEnv::new(&config).unwrap();
        assert!(env.set_crash_restarts(1.5, 5, 2).is_err());
        assert!(env.set_crash_restarts(0.5, 0, 2).is_err());
        assert!(env.set_crash_restarts(0.5, 5, 0).is_err());
        env.set_crash_restarts(0.5, 5, 2).unwrap();
        env.set_road_pool(500, 3);
        plain.set_road_pool(500, 3);
        // An empty pool: the same episodes as without restarts.
        for s in 0..5 {
            assert_eq!(
                plain.reset(Some(s)).unwrap().0,
                env.reset(Some(s)).unwrap().0
            );
        }
        assert!(env.crash_restart_states().is_empty());
        let before = crash_into_the_wall(&mut env, 4);
        assert!(before.len() > 5);
        assert_eq!(
            env.crash_restart_states(),
            &[(501, before[before.len() - 5])]
        );
        let crash = before[before.len() - 5];
        let mut restarts = 0;
        for s in 0..200 {
            env.reset(Some(s)).unwrap();
            let car = *env.car();
            if car.x == crash.x {
                restarts += 1;
                assert_eq!(env.config().track_seed, 501);
                assert!((car.y - crash.y).abs() <= config.start_lateral_noise + 1e-12);
            } else {
                assert_eq!(car.x, 0.0);
            }
        }
        assert!(
            (70..=130).contains(&restarts),
            "{restarts} of 200 restarted"
        );
        // Share 0 empties the pool; the pool keeps the newest `capacity`
        // crashes (a share that never restarts in practice).
        env.set_crash_restarts(0.0, 5, 2).unwrap();
        assert!(env.crash_restart_states().is_empty());
        env.set_crash_restarts(1e-12, 5, 2).unwrap();
        let crashes: Vec<(u64, CarState)> = [0, 1, 2]
            .into_iter()
            .map(|s| {
                let before = crash_into_the_wall(&mut env, s);
                (env.config().track_seed, before[before.len() - 5])
            })
            .collect();
        assert_eq!(env.crash_restart_states(), &[crashes[2], crashes[1]]);
        // A crash fewer than `back_steps` steps after its start, from a
        // reset or from `reset_to` after a long episode, adds nothing.
        env.set_crash_restarts(1e-12, 5, 2).unwrap();
        let before = crash_into_the_wall(&mut env, 4);
        assert_eq!(env.crash_restart_states().len(), 1);
        env.reset(Some(4)).unwrap();
        for _ in 0..10 {
            env.step(&[0.0, 0.5]).unwrap();
        }
        env.reset_to(before[before.len() - 3]).unwrap();
        let mut steps = 0;
        while !env.step(&[1.0, 0.5]).unwrap().terminated {
            steps += 1;
            assert!(steps < 5, "no crash");
        }
        assert_eq!(env.crash_restart_states().len(), 1);
        env.set_crash_restarts(1e-12, 1000, 2).unwrap();
        crash_into_the_wall(&mut env, 4);
        assert!(env.crash_restart_states().is_empty());
    }

    #[test]
    fn wrap_angle_stays_in_range() {
        use std::f64::consts::PI;
        for a in [-7.0, -PI, -1.0, 0.0, 1.0, PI, 7.0, 100.0] {
            let w = wrap_angle(a);
            assert!(w > -PI - 1e-12 && w <= PI + 1e-12, "{a} -> {w}");
            assert!(((a - w) / std::f64::consts::TAU).fract().abs() < 1e-9 || (a - w).abs() < 1e-9);
        }
    }

    #[test]
    fn straight_driving_keeps_the_lane_and_earns_distance() {
        let c = DriveConfig {
            start_lateral_noise: 0.0,
            start_heading_noise: 0.0,
            start_speed_noise: 0.0,
            ..Default::default()
        };
        let mut env = DriveEnv::new(&c).unwrap();
        env.reset(Some(1)).unwrap();
        // Hold speed: the accelerator that cancels drag and rolling resistance.
        let hold = (c.drag * KMH * KMH + c.rolling_resistance) / c.max_accel;
        let s = env.step(&[0.0, hold]).unwrap();
        assert!((s.reward - KMH * DT).abs() < 1e-3, "{}", s.reward);
        assert!(env.car().y.abs() < 1e-12);
        assert!((env.car().speed - KMH).abs() < 1e-3);
    }

    const KMH: f64 = crate::config::KMH_100;

    #[test]
    fn steering_turns_left_for_positive_action() {
        let mut env = DriveEnv::new(&DriveConfig::default()).unwrap();
        env.reset(Some(2)).unwrap();
        let h0 = env.car().heading;
        env.step(&[1.0, 0.0]).unwrap();
        assert!(env.car().heading > h0);
        // At 100 km/h full steering turns with about max_lateral_accel.
        let rate = (env.car().heading - h0) / DT;
        let lat = rate * env.car().speed;
        assert!((lat - 8.0).abs() < 1.0, "lateral acceleration {lat}");
    }
    #[test]
    fn a_path_moved_by_lanes_keeps_exactly_the_lane_keeping_steps_clear_ahead() {
        let config = DriveConfig::default();
        let demos = crate::expert_demos(&config, 1, 0).unwrap();
        let (poses, _) = crate::render::replay(&config, &demos.trajectories[0]).unwrap();
        let world = World::new(&config).unwrap();
        let (hw, lane) = (config.half_width(), config.lane_width);
        let n = poses.len() - 1;
        let lane_at = |s: usize| config.nearest_lane(poses[s].y);
        let mut env = DriveEnv::new(&config).unwrap();
        let cases = [
            (40, true, false),
            (40, false, false),
            (160, true, false),
            (40, true, true),
            (160, true, true),
        ];
        for (clear, finished, undriven_only) in cases {
            let moved = lane_shifted(&world, &poses, finished, clear, undriven_only);
            // The lanes the path keeps for clear + 1 steps in a row.
            let driven = |l: i64| {
                (0..=n.saturating_sub(clear))
                    .any(|t| (t..=t + clear).all(|s| lane_at(s) as i64 == l))
            };
            let mut want = Vec::new();
            for k in [-2i64, -1, 1, 2] {
                let at = |s: usize| CarState {
                    y: poses[s].y + k as f64 * lane,
                    ..poses[s]
                };
                // Every step checked one by one over its whole window.
                for t in 0..n {
                    let clear_ahead = (t..=t + clear).all(|s| {
                        if s > n {
                            return finished;
                        }
                        at(s).y.abs() < hw && !world.collides(&at(s)) && lane_at(s) == lane_at(t)
                    });
                    if clear_ahead && !(undriven_only && driven(lane_at(t) as i64 + k)) {
                        want.push((k, t));
                    }
                }
            }
            let got: Vec<(i64, usize)> = moved.iter().map(|(k, t, _)| (*k, *t)).collect();
            assert_eq!(got, want, "clear {clear} {finished} {undriven_only}");
            // Some steps of every shift are dropped (walls, stopped cars,
            // lane changes); with 2 s of look ahead, each shift by one lane
            // keeps some.
            for k in [-2i64, -1, 1, 2] {
                let kept = got.iter().filter(|(j, _)| *j == k).count();
                assert!(kept < n, "k {k}: {kept} of {n}");
                assert!(
                    k.abs() == 2 || clear > 40 || undriven_only || kept > 0,
                    "k {k}"
                );
            }
            // Each is the moved car's own view, as the env reports it.
            for (k, t, obs) in moved.iter().step_by(37) {
                let car = CarState {
                    y: poses[*t].y + *k as f64 * lane,
                    ..poses[*t]
                };
                assert_eq!(*obs, env.reset_to(car).unwrap(), "k {k} t {t}");
            }
        }
        // The expert changes lanes and meets stopped cars, so the filter
        // bites: a longer look ahead keeps fewer; an unfinished path drops
        // its last steps.
        let count =
            |clear, finished, only| lane_shifted(&world, &poses, finished, clear, only).len();
        assert!(count(160, true, false) < count(40, true, false));
        assert!(count(40, false, false) < count(40, true, false));
        // The expert keeps two of the three lanes: moves into those go, the
        // ones into the third stay.
        let only = count(40, true, true);
        assert!(0 < only && only < count(40, true, false), "{only}");
    }

    #[test]
    fn the_mirrored_road_drives_as_the_mirror_image() {
        let config = DriveConfig {
            track_seed: 11,
            ..DriveConfig::default()
        };
        let world = World::new(&config).unwrap();
        let mirror = world.mirrored();
        assert_ne!(world.track(), mirror.track());
        assert_eq!(mirror.mirrored().track(), world.track());
        let mut car = CarState {
            x: 0.0,
            y: 1.2,
            heading: 0.05,
            speed: 25.0,
        };
        let mut twin = CarState {
            y: -car.y,
            heading: -car.heading,
            ..car
        };
        let (mut ranges, mut twin_ranges) = ([0.0; NUM_RAYS], [0.0; NUM_RAYS]);
        let (mut obs, mut twin_obs) = (Vec::new(), Vec::new());
        let (mut seen_near, mut steps) = (false, 400);
        for t in 0..400 {
            // Change lanes (left, right, centre) so that obstacles on both
            // sides come into view.
            let target = [0.0, 3.5, -3.5, 0.0][t / 100];
            let steer = 0.1 * (target - car.y) - 2.0 * car.heading;
            let mut act = [steer.clamp(-1.0, 1.0), 0.1];
            world.lidar(&car, &mut ranges);
            world.observation(&car, &ranges, &mut obs);
            mirror.lidar(&twin, &mut twin_ranges);
            mirror.observation(&twin, &twin_ranges, &mut twin_obs);
            seen_near |= ranges.iter().any(|&r| r < 0.5 * config.lidar_range);
            let mut mirrored = obs.clone();
            mirror_pair(&mut mirrored, &mut act);
            for (i, (a, b)) in mirrored.iter().zip(&twin_obs).enumerate() {
                assert!((a - b).abs() < 1e-4, "step {t}, number {i}: {a} vs {b}");
            }
            let end = mirror.advance(&mut twin, &act);
            act[0] = -act[0];
            assert_eq!(world.advance(&mut car, &act), end, "step {t}");
            if end != Outcome::Driving {
                steps = t;
                break;
            }
        }
        assert!(seen_near, "the drive never came near an obstacle");
        assert!(steps > 100, "the drive ended at step {steps}");
    }
}
