//! A scripted driver that drives like a person at the keyboard: it presses
//! keys, and [`Recorder::tick`] turns them into actions, so its
//! demonstrations hold exactly what the terminal recorder would store for
//! a person (`red-cli drive expert --style human`).
//!
//! What makes it person-like, unlike [`crate::Expert`]:
//! - Steering by taps of Left/Right ([`HumanConfig::max_taps`] at most per
//!   burst, [`HumanConfig::tap_gap_ticks`] apart); the wheel returns to the
//!   centre between bursts, so most steps steer 0 and the rest take the
//!   few values the recorder's ramp reaches.
//! - The pedal by Up/Down taps on its grid ([`crate::record::PEDAL_STEP`]):
//!   it keeps a speed of its own, drawn per episode around 100 km/h, as
//!   it reads it off the screen (a few km/h off), touching the pedal when
//!   that reading is more than 5 km/h off; between the grid's levels
//!   (0.15 holds 100 km/h, 0.2 118 km/h) that means a tap up now and then
//!   and a tap down later.
//! - Glances and reactions: it looks every 0.2-0.5 s, and what it decides
//!   starts 150-300 ms later (both drawn per decision from its own seeded
//!   stream), from a slightly wrong reading of its lateral position.
//! - Imperfect lane keeping: it corrects only when its offset from the
//!   lane's centre, one second ahead, exceeds [`HumanConfig::lane_tolerance`].
//! - It sees only the stopped cars within [`HumanConfig::view_distance`]
//!   ahead (the recorder's view, [`crate::record::VIEW_AHEAD`]) and picks
//!   lanes from those alone, slowing down when a needed lane change is
//!   short of road.
//!
//! ```
//! use red_drive::DriveConfig;
//! use red_drive::human::{HumanConfig, human_demos};
//!
//! let road = DriveConfig { track_seed: 11, ..DriveConfig::default() };
//! let demos = human_demos(&road, &HumanConfig::default(), 1, 0)?;
//! assert_eq!(demos.source, Some(red_core::DemoSource::Script));
//! red_drive::scenario::check_fits(&road, &demos)?;
//! # Ok::<(), red_drive::Error>(())
//! ```

use std::collections::VecDeque;

use rand::{Rng, RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use red_core::{DemoSource, Demos, Seeder, Stream, Trajectory};
use serde::{Deserialize, Serialize};

use crate::config::{DT, DriveConfig, NUM_LANES};
use crate::env::EpisodeSummary;
use crate::record::{
    DriveKey, HOLD_TICKS, KeyEvent, KeyKind, PEDAL_STEP, RecordStatus, Recorder, VIEW_AHEAD,
    next_steer, pedal_on_grid,
};
use crate::{Error, Result};

/// Time constant (s) of the lateral correction when a stopped car is
/// near: a little above the second a glance-react-tap loop takes, so that
/// corrections do not overshoot.
const URGENT_TAU: f64 = 1.2;

/// The seed stream of the driver's own randomness (glances, reaction
/// times, perception, tap rhythm), apart from the start noise's.
pub const HUMAN_STREAM: Stream = Stream::Other(71);

/// How the person-like driver behaves. Times are in seconds, lengths in
/// metres, speeds in m/s unless a name says otherwise.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HumanConfig {
    /// Shortest delay from a decision to its first key.
    pub reaction_min: f64,
    /// Longest delay from a decision to its first key.
    pub reaction_max: f64,
    /// Shortest pause between glances (and after a burst of keys has
    /// played out).
    pub glance_min: f64,
    /// Longest pause between glances.
    pub glance_max: f64,
    /// How far ahead it sees stopped cars.
    pub view_distance: f64,
    /// Offset from the lane's centre (predicted one second ahead) it
    /// leaves alone.
    pub lane_tolerance: f64,
    /// Its reading of its lateral position is off by `U(-this, this)`.
    pub position_noise: f64,
    /// Its reading of its lateral speed is off by `U(-this, this)`.
    pub drift_noise: f64,
    /// A correction aims to remove the lateral offset in this time.
    pub settle_time: f64,
    /// Lateral speed of an unhurried lane change.
    pub lane_change_speed: f64,
    /// Fastest lateral speed it asks for when road is short.
    pub max_lateral_speed: f64,
    /// Most taps of one steering key in a burst.
    pub max_taps: usize,
    /// Most taps of Up/Down in a burst.
    pub max_pedal_taps: usize,
    /// Ticks between two taps of a burst: this, or one more (drawn per
    /// tap) where that stays below [`HOLD_TICKS`]; at most
    /// `HOLD_TICKS - 1` so a burst holds the wheel without a gap. At the
    /// default 2 the rhythm is a steady 100 ms.
    pub tap_gap_ticks: u32,
    /// Distance kept along the road from a stopped car before it may leave
    /// the lane beside it.
    pub pass_margin: f64,
    /// Slowest speed it chooses to keep, km/h (drawn per episode between
    /// this and `cruise_max_kmh`).
    pub cruise_min_kmh: f64,
    /// Fastest speed it chooses to keep, km/h.
    pub cruise_max_kmh: f64,
    /// Its reading of the speed is off by `U(-this, this)` km/h.
    pub speed_noise_kmh: f64,
    /// Speed error it tolerates before touching the pedal, km/h.
    pub speed_tolerance_kmh: f64,
    /// Slowest it slows down to for a lane change short of road, km/h.
    pub min_speed_kmh: f64,
    /// Whether the terminal reports key releases (holds last until
    /// released) or not (each press holds [`HOLD_TICKS`] ticks).
    pub key_releases: bool,
}

impl Default for HumanConfig {
    /// Where the values come from:
    /// - reaction 0.15-0.30 s: simple visual reaction times of an alert
    ///   person; glances every 0.2-0.5 s.
    /// - `view_distance` 100 m: what the recorder's view shows
    ///   ([`VIEW_AHEAD`]).
    /// - `lane_tolerance` 0.4 m, readings off by up to 0.15 m and
    ///   0.1 m/s: a lane has 0.85 m of room on each side of a car; these
    ///   give a visible wobble without touching the walls (measured on
    ///   the shipped demos: see `data/README.md`).
    /// - `settle_time` 1.5 s, `lane_change_speed` 2 m/s (a 3.5 m lane
    ///   change in about 2 s), `max_lateral_speed` 3.5 m/s.
    /// - `max_taps` 3 (at 100 km/h one tap turns the car's lateral speed
    ///   by about 0.6 m/s, three by 2.5 m/s), `max_pedal_taps` 6,
    ///   `tap_gap_ticks` 2 (taps 100 ms apart; with 100-150 ms, 3 ticks
    ///   now and then, bursts hold longer and it finished 474 of 500
    ///   roads instead of 499).
    /// - `pass_margin` 2.5 m beyond the 4.5 m at which two cars touch.
    /// - a speed of its own in 92-108 km/h (the paper's driver was asked
    ///   for about 100 km/h), read 3 km/h off at most, corrected when more
    ///   than 5 km/h off; never slower than 40 km/h for a lane change.
    /// - `key_releases` false: most terminals do not report releases.
    fn default() -> Self {
        Self {
            reaction_min: 0.15,
            reaction_max: 0.30,
            glance_min: 0.2,
            glance_max: 0.5,
            view_distance: VIEW_AHEAD,
            lane_tolerance: 0.4,
            position_noise: 0.15,
            drift_noise: 0.1,
            settle_time: 1.5,
            lane_change_speed: 2.0,
            max_lateral_speed: 3.5,
            max_taps: 3,
            max_pedal_taps: 6,
            tap_gap_ticks: 2,
            pass_margin: 2.5,
            cruise_min_kmh: 92.0,
            cruise_max_kmh: 108.0,
            speed_noise_kmh: 3.0,
            speed_tolerance_kmh: 5.0,
            min_speed_kmh: 40.0,
            key_releases: false,
        }
    }
}

impl HumanConfig {
    /// Checks every field.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the first field out of range.
    pub fn validate(&self) -> Result<()> {
        let bad = |field: &'static str, reason: String| Err(Error::InvalidConfig { field, reason });
        for (field, v) in [
            ("reaction_min", self.reaction_min),
            ("glance_min", self.glance_min),
            ("position_noise", self.position_noise),
            ("drift_noise", self.drift_noise),
            ("lane_tolerance", self.lane_tolerance),
            ("pass_margin", self.pass_margin),
            ("speed_tolerance_kmh", self.speed_tolerance_kmh),
            ("speed_noise_kmh", self.speed_noise_kmh),
            ("min_speed_kmh", self.min_speed_kmh),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(field, format!("must be a finite number >= 0, got {v}"));
            }
        }
        for (field, v) in [
            ("view_distance", self.view_distance),
            ("settle_time", self.settle_time),
            ("lane_change_speed", self.lane_change_speed),
            ("max_lateral_speed", self.max_lateral_speed),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(field, format!("must be a finite number > 0, got {v}"));
            }
        }
        if !(self.reaction_max.is_finite() && self.reaction_max >= self.reaction_min) {
            return bad(
                "reaction_max",
                format!("must be at least reaction_min, got {}", self.reaction_max),
            );
        }
        if !(self.glance_max.is_finite() && self.glance_max >= self.glance_min) {
            return bad(
                "glance_max",
                format!("must be at least glance_min, got {}", self.glance_max),
            );
        }
        if !(self.cruise_min_kmh.is_finite() && self.cruise_min_kmh > 0.0) {
            return bad(
                "cruise_min_kmh",
                format!("must be a finite number > 0, got {}", self.cruise_min_kmh),
            );
        }
        if !(self.cruise_max_kmh.is_finite() && self.cruise_max_kmh >= self.cruise_min_kmh) {
            return bad(
                "cruise_max_kmh",
                format!(
                    "must be at least cruise_min_kmh, got {}",
                    self.cruise_max_kmh
                ),
            );
        }
        if self.max_taps == 0 {
            return bad("max_taps", "must be at least 1".into());
        }
        if self.tap_gap_ticks == 0 || self.tap_gap_ticks + 1 > HOLD_TICKS {
            return bad(
                "tap_gap_ticks",
                format!(
                    "must be in 1..={} so that a burst holds the wheel without a gap, got {}",
                    HOLD_TICKS - 1,
                    self.tap_gap_ticks
                ),
            );
        }
        Ok(())
    }
}

/// The person-like driver: call [`HumanDriver::keys`] once per tick for
/// the key events to give [`Recorder::tick`].
#[derive(Debug, Clone)]
pub struct HumanDriver {
    config: HumanConfig,
    rng: ChaCha8Rng,
    tick: u64,
    /// Key events waiting for their tick, in order.
    queue: VecDeque<(u64, KeyEvent)>,
    /// The tick of the next glance.
    next_glance: u64,
    /// The lane it is heading for.
    target_lane: Option<usize>,
    /// The speed it keeps, m/s.
    cruise: f64,
}

impl HumanDriver {
    /// A driver drawing its randomness from `rng`.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] for an invalid config.
    pub fn new(config: &HumanConfig, mut rng: ChaCha8Rng) -> Result<Self> {
        config.validate()?;
        let kmh = if config.cruise_max_kmh > config.cruise_min_kmh {
            rng.random_range(config.cruise_min_kmh..=config.cruise_max_kmh)
        } else {
            config.cruise_min_kmh
        };
        Ok(Self {
            config: config.clone(),
            cruise: kmh / 3.6,
            rng,
            tick: 0,
            queue: VecDeque::new(),
            next_glance: 0,
            target_lane: None,
        })
    }

    /// The key events for this tick, given what the recorder shows (the
    /// car, the controls, the road within the view).
    pub fn keys(&mut self, rec: &Recorder) -> Vec<KeyEvent> {
        // Pending pedal taps do not keep it from looking (and re-deciding
        // them); a steering burst plays out first.
        let steering = self
            .queue
            .iter()
            .any(|(_, e)| matches!(e.key, DriveKey::Left | DriveKey::Right));
        if !steering && self.tick >= self.next_glance {
            self.queue.clear();
            self.decide(rec);
            self.queue.make_contiguous().sort_by_key(|(t, _)| *t);
        }
        let mut out = Vec::new();
        while let Some(&(t, e)) = self.queue.front() {
            if t > self.tick {
                break;
            }
            out.push(e);
            self.queue.pop_front();
        }
        self.tick += 1;
        out
    }

    fn ticks(&mut self, lo: f64, hi: f64) -> u64 {
        let s = if hi > lo {
            self.rng.random_range(lo..=hi)
        } else {
            lo
        };
        (s / DT).round() as u64
    }

    fn noise(&mut self, scale: f64) -> f64 {
        if scale > 0.0 {
            self.rng.random_range(-scale..=scale)
        } else {
            0.0
        }
    }

    /// One glance: what to do, scheduled after a reaction time.
    fn decide(&mut self, rec: &Recorder) {
        let h = self.config.clone();
        let road = rec.world().config().clone();
        let car = *rec.car();
        let v = car.speed.max(1.0);
        let react = self.ticks(h.reaction_min, h.reaction_max);
        let delay = react as f64 * DT;
        let y = car.y + self.noise(h.position_noise);
        let vy = car.speed * car.heading.sin() + self.noise(h.drift_noise);
        // Where it will be when its keys start to act.
        let y_then = y + vy * delay;
        let lane_now = road.nearest_lane(y);
        let (target, blocker) = self.choose_lane(rec, lane_now, y_then + vy);
        let e = y_then - road.lane_center(target);

        // Lateral speed wanted: proportional to the offset it will have
        // when its keys act (a whole glance-react-tap loop takes about a
        // second, so the time constant stays above it), faster when a
        // stopped car in its lane leaves little road.
        let mut vy_want = vy;
        let mut slow_to = None;
        if (e + vy).abs() > h.lane_tolerance {
            let (mut tau, mut cap) = (h.settle_time, h.lane_change_speed);
            if let Some(d) = blocker {
                // Road left before the car's nose reaches the stopped car,
                // and the sideways distance to clear it.
                let t_left = (d / v - delay - 0.3).max(0.1);
                let off = (y_then - road.lane_center(lane_now)).abs();
                let need = (road.car_width + 0.4 - off).max(0.0);
                if need / t_left > e.abs() / tau {
                    tau = URGENT_TAU;
                    cap = h.max_lateral_speed;
                    let fastest = (e.abs() / tau).min(cap);
                    if need / t_left > fastest {
                        let v_ok = d / (need / fastest + delay + 0.3);
                        slow_to = Some(v_ok.max(h.min_speed_kmh / 3.6));
                    }
                }
            }
            vy_want = -e.signum() * (e.abs() / tau).min(cap);
        }

        let mut at = self.tick + react;
        let mut last = None;
        // Steering burst: the number of taps whose turn best gives vy_want.
        let want = vy_want - vy;
        if want.abs() > 0.0 {
            let gaps: Vec<u32> = (1..h.max_taps)
                .map(|_| {
                    h.tap_gap_ticks
                        + u32::from(h.tap_gap_ticks < HOLD_TICKS - 1 && self.rng.random_bool(0.5))
                })
                .collect();
            // Lateral speed per unit of steering per tick at this speed.
            let gain = DT * car.speed * car.speed * road.steer_limit(car.speed) / road.wheelbase;
            let mut best = (want.abs(), 0);
            for n in 1..=h.max_taps {
                let got = gain * pulse_sum(self.burst_hold(&gaps[..n - 1]));
                let err = (want.abs() - got).abs();
                if err < best.0 {
                    best = (err, n);
                }
            }
            let n = best.1;
            if n > 0 {
                let key = if want > 0.0 {
                    DriveKey::Left
                } else {
                    DriveKey::Right
                };
                let mut t = at;
                for k in 0..n {
                    self.queue.push_back((t, KeyEvent::press(key)));
                    if k + 1 < n {
                        t += u64::from(gaps[k]);
                    }
                }
                let end = if h.key_releases {
                    let release = t + u64::from(HOLD_TICKS);
                    self.queue.push_back((
                        release,
                        KeyEvent {
                            key,
                            kind: KeyKind::Release,
                        },
                    ));
                    release
                } else {
                    t + u64::from(HOLD_TICKS)
                };
                // The wheel is back at the centre within 4 ticks of the
                // hold's end; the next key waits for that.
                last = Some(end + 4);
                // The other key's taps fall between these.
                at += 1;
            }
        }

        // Pedal: its own speed, slower when road is short.
        let v_want = slow_to.map_or(self.cruise, |s| s.min(self.cruise));
        let tol = h.speed_tolerance_kmh / 3.6;
        let speed = car.speed + self.noise(h.speed_noise_kmh) / 3.6;
        let hold =
            |s: f64| pedal_on_grid((road.drag * s * s + road.rolling_resistance) / road.max_accel);
        let pedal = rec.controls()[1];
        let pedal_want = if speed > v_want + 3.0 * tol {
            -0.3
        } else if speed > v_want + tol {
            hold(v_want) - 0.1
        } else if speed < v_want - tol {
            hold(v_want) + 0.1
        } else if (speed - v_want).abs() < 0.5 * tol {
            hold(v_want)
        } else {
            // Close enough and getting closer: leave the pedal.
            pedal
        };
        let steps = ((pedal_want - pedal) / PEDAL_STEP).round() as i64;
        let n = steps.unsigned_abs().min(h.max_pedal_taps as u64);
        if n > 0 {
            let key = if steps > 0 {
                DriveKey::Up
            } else {
                DriveKey::Down
            };
            for k in 0..n {
                self.queue
                    .push_back((at + k * u64::from(h.tap_gap_ticks), KeyEvent::press(key)));
            }
        }
        let pause = self.ticks(h.glance_min, h.glance_max);
        self.next_glance = last.unwrap_or(self.tick) + pause;
    }

    /// Ticks the wheel counts as held for a burst whose taps are `gaps`
    /// ticks apart (one tap: an empty slice).
    fn burst_hold(&self, gaps: &[u32]) -> u32 {
        gaps.iter().sum::<u32>() + HOLD_TICKS
    }

    /// The lane to be in, from the stopped cars within view only (`y_ahead`:
    /// where it expects to be in a second), and the
    /// distance to the stopped car in the car's own lane that makes a
    /// change urgent (from the car's nose to its tail), if any.
    fn choose_lane(
        &mut self,
        rec: &Recorder,
        lane_now: usize,
        y_ahead: f64,
    ) -> (usize, Option<f64>) {
        let road = rec.world().config();
        let car = rec.car();
        let clear = road.car_length + self.config.pass_margin;
        let visible: Vec<_> = rec
            .world()
            .track()
            .between(car.x - clear, car.x + self.config.view_distance)
            .iter()
            .filter(|o| o.x + clear > car.x)
            .copied()
            .collect();
        let current = self.target_lane.unwrap_or(lane_now);
        if visible.is_empty() {
            self.target_lane = Some(current);
            return (current, None);
        }
        let lanes: Vec<usize> = visible.iter().map(|o| o.lane).collect();
        // Beside the first stopped car (or about to be), it may only move
        // away from it.
        let first = lanes[0];
        let beside = car.x > visible[0].x - clear;
        let allowed: [bool; NUM_LANES] =
            std::array::from_fn(|c| !beside || (c != first && (c < first) == (lane_now < first)));
        let costs = first_lane_costs(&lanes, lane_now, allowed);
        let best = costs.iter().copied().min().unwrap_or(u64::MAX);
        let ties: Vec<usize> = (0..NUM_LANES).filter(|&c| costs[c] == best).collect();
        // Of equally good lanes: the one it is heading for, else the one
        // it drifts towards, else either.
        let target = if ties.contains(&current) {
            current
        } else {
            let dist = |c: usize| (road.lane_center(c) - y_ahead).abs();
            let nearest = ties.iter().map(|&c| dist(c)).fold(f64::INFINITY, f64::min);
            let near: Vec<usize> = ties
                .iter()
                .copied()
                .filter(|&c| dist(c) < nearest + 0.5)
                .collect();
            near[self.rng.random_range(0..near.len())]
        };
        self.target_lane = Some(target);
        let blocker = visible
            .iter()
            .find(|o| o.lane == lane_now && o.x > car.x)
            .filter(|_| target != lane_now)
            .map(|o| o.x - car.x - road.car_length);
        (target, blocker)
    }
}

/// For each lane `c`, the cost of the best plan that is in `c` beside the
/// first of the stopped cars in `lanes` and avoids all of them, starting
/// from `start` (`u64::MAX` where impossible or not `allowed`). A plan
/// costs 10 per squared lane change, plus `k` for a change made only
/// after the `k`-th stopped car: of two plans with the same changes, the
/// one that changes lanes earlier (with more road) wins.
fn first_lane_costs(lanes: &[usize], start: usize, allowed: [bool; NUM_LANES]) -> [u64; NUM_LANES] {
    let inf = u64::MAX / 4;
    let step = |a: usize, b: usize, k: usize| {
        let d = a.abs_diff(b) as u64;
        10 * d * d + if d > 0 { k as u64 } else { 0 }
    };
    // Backwards: to_go[c] = least cost from lane c beside car i on.
    let mut to_go = [0u64; NUM_LANES];
    for i in (0..lanes.len()).rev() {
        let mut here = [inf; NUM_LANES];
        for (c, h) in here.iter_mut().enumerate() {
            if c == lanes[i] {
                continue;
            }
            *h = if i + 1 == lanes.len() {
                0
            } else {
                (0..NUM_LANES)
                    .map(|n| step(c, n, i + 1).saturating_add(to_go[n]))
                    .min()
                    .unwrap_or(inf)
            };
        }
        to_go = here;
    }
    let mut out = [u64::MAX; NUM_LANES];
    for (c, o) in out.iter_mut().enumerate() {
        if to_go[c] < inf && allowed[c] {
            *o = step(start, c, 0) + to_go[c];
        }
    }
    out
}

/// Sum of the steering values, tick by tick, of a pulse that holds a
/// steering key for `hold` ticks from the centre until the wheel is back
/// (the recorder's ramp and return, [`next_steer`]).
pub fn pulse_sum(hold: u32) -> f64 {
    let mut steer = 0.0;
    let mut sum = 0.0;
    for _ in 0..hold {
        steer = next_steer(steer, 1.0);
        sum += steer;
    }
    while steer != 0.0 {
        steer = next_steer(steer, 0.0);
        sum += steer;
    }
    sum
}

/// Drives one episode on `road` from reset seed `seed` through a
/// [`Recorder`], with a driver drawing from `rng`. Returns the trajectory
/// (as the recorder stores it) and a summary.
///
/// # Errors
/// [`Error::InvalidConfig`] for an invalid road or driver config.
pub fn human_episode(
    road: &DriveConfig,
    human: &HumanConfig,
    seed: u64,
    rng: ChaCha8Rng,
) -> Result<(Trajectory, EpisodeSummary)> {
    let mut driver = HumanDriver::new(human, rng)?;
    let mut rec = Recorder::new(road, seed, human.key_releases)?;
    while rec.status() == RecordStatus::Driving {
        let keys = driver.keys(&rec);
        rec.tick(&keys)?;
    }
    let summary = EpisodeSummary {
        success: rec.finished(),
        distance: rec.distance(),
        steps: rec.steps(),
    };
    let mut demos = rec.finish();
    let t = demos
        .trajectories
        .pop()
        .ok_or_else(|| Error::InvalidConfig {
            field: "time_limit",
            reason: "the episode ended before its first step".into(),
        })?;
    Ok((t, summary))
}

/// `episodes` demonstrations of the person-like driver on `road`, marked
/// as made by a script and carrying their road ([`crate::scenario`]).
/// Episode `k`'s reset seed is the `k`-th number of the [`Stream::Demo`]
/// stream of `seed` (the starts of [`crate::expert_demos`] with the same
/// seed); the driver draws from the [`HUMAN_STREAM`] stream of `seed`.
/// Crashed episodes are kept, as they happened.
///
/// # Errors
/// [`Error::InvalidConfig`] for an invalid road or driver config.
pub fn human_demos(
    road: &DriveConfig,
    human: &HumanConfig,
    episodes: usize,
    seed: u64,
) -> Result<Demos> {
    Ok(human_demos_with_summaries(road, human, episodes, seed)?.0)
}

/// [`human_demos`] with each episode's summary.
///
/// # Errors
/// [`Error::InvalidConfig`] for an invalid road or driver config.
pub fn human_demos_with_summaries(
    road: &DriveConfig,
    human: &HumanConfig,
    episodes: usize,
    seed: u64,
) -> Result<(Demos, Vec<EpisodeSummary>)> {
    let seeder = Seeder::new(seed);
    let mut starts = seeder.rng(Stream::Demo);
    let mut rng = seeder.rng(HUMAN_STREAM);
    let mut demos = Recorder::new(road, 0, human.key_releases)?.finish();
    let mut summaries = Vec::with_capacity(episodes);
    for _ in 0..episodes {
        let episode_rng = ChaCha8Rng::seed_from_u64(rng.next_u64());
        let (t, s) = human_episode(road, human, starts.next_u64(), episode_rng)?;
        demos.trajectories.push(t);
        summaries.push(s);
    }
    // A script imitating a person, not a person.
    demos.source = Some(DemoSource::Script);
    Ok((demos, summaries))
}

/// Runs the driver once on each track seed in `track_seeds` (reset seed =
/// track seed, driver seed from the [`HUMAN_STREAM`] of the track seed)
/// and returns the summaries.
///
/// # Errors
/// [`Error::InvalidConfig`] for an invalid road or driver config.
pub fn human_success(
    road: &DriveConfig,
    human: &HumanConfig,
    track_seeds: impl IntoIterator<Item = u64>,
) -> Result<Vec<(u64, EpisodeSummary)>> {
    track_seeds
        .into_iter()
        .map(|s| {
            let c = DriveConfig {
                track_seed: s,
                ..road.clone()
            };
            human_demos_with_summaries(&c, human, 1, s).map(|(_, e)| (s, e[0]))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pulse_sums_follow_the_ramp() {
        // 0.2, 0.4, 0.6, then back 0.3, 0.
        assert!((pulse_sum(3) - 1.5).abs() < 1e-12);
        // 0.2 .. 1.0, then 0.7, 0.4, 0.1.
        assert!((pulse_sum(5) - 4.2).abs() < 1e-12);
    }

    #[test]
    fn lane_costs_avoid_the_stopped_cars() {
        let all = [true; NUM_LANES];
        // One car ahead in the own (middle) lane: either side, one change.
        assert_eq!(first_lane_costs(&[1], 1, all), [10, u64::MAX, 10]);
        // Then one on the right: the left lane passes both.
        let c = first_lane_costs(&[1, 0], 1, all);
        assert!(c[2] < c[0], "{c:?}");
        // On the right of a car on the left, the next in the middle: move
        // right now rather than after passing it.
        let c = first_lane_costs(&[2, 1], 1, all);
        assert!(c[0] < c[1], "{c:?}");
        // Not allowed: impossible.
        assert_eq!(
            first_lane_costs(&[1, 2], 0, [true, false, false])[2],
            u64::MAX
        );
    }

    #[test]
    fn invalid_config_names_the_field() {
        let h = HumanConfig {
            tap_gap_ticks: 9,
            ..HumanConfig::default()
        };
        assert!(
            h.validate()
                .unwrap_err()
                .to_string()
                .contains("tap_gap_ticks")
        );
        HumanConfig::default().validate().unwrap();
    }
}
