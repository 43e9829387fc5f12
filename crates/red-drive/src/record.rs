//! Recording a person's driving: abstract key events in, a demonstration
//! out. The terminal itself (reading keys, drawing) lives in `red-cli`; this
//! module holds everything that can be tested without one.
//!
//! Controls: Left/Right steer (the wheel turns further each tick a key is
//! held and returns to the centre when none is), Up/Down raise/lower a
//! latched accelerator/brake level by 0.1 per key event (about 0.15 holds
//! 100 km/h; negative values brake), Quit ends the recording. Terminals that
//! report key releases hold a steering key until it is released; others
//! treat each press or auto-repeat as holding it for [`HOLD_TICKS`] ticks.

use red_core::{Demos, Env, EpisodeEnd, Info, TimeLimit, Trajectory};

use crate::config::{ACT_DIM, CONTROL_HZ, DriveConfig, OBS_DIM};
use crate::env::{CarState, DriveEnv, INFO_DISTANCE, make_env};
use crate::{ENV_ID, Result};

/// Ticks a steering key counts as held after a press or an auto-repeat,
/// for terminals that do not report releases (150 ms at 20 Hz, a bit more
/// than the usual auto-repeat interval).
pub const HOLD_TICKS: u32 = 3;
/// Change of the steering per tick while a steering key is held.
pub const STEER_RATE: f64 = 0.2;
/// Change of the steering per tick back towards the centre when no
/// steering key is held.
pub const STEER_RETURN: f64 = 0.3;
/// Change of the accelerator/brake level per Up/Down key event.
pub const PEDAL_STEP: f64 = 0.1;

/// A key the driver uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DriveKey {
    /// Steer left.
    Left,
    /// Steer right.
    Right,
    /// More accelerator (less brake).
    Up,
    /// Less accelerator (more brake).
    Down,
    /// Stop recording (q, Esc, Ctrl-C).
    Quit,
}

/// What happened to a key.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum KeyKind {
    /// Pressed.
    Press,
    /// Auto-repeated while held.
    Repeat,
    /// Released (only on terminals that report releases).
    Release,
}

/// One key event.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct KeyEvent {
    /// The key.
    pub key: DriveKey,
    /// Press, repeat or release.
    pub kind: KeyKind,
}

impl KeyEvent {
    /// A press of `key`.
    pub fn press(key: DriveKey) -> Self {
        Self {
            key,
            kind: KeyKind::Press,
        }
    }
}

/// Where the recording stands after a tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RecordStatus {
    /// The episode goes on.
    Driving,
    /// The episode ended (crash or finish: terminated; time limit: truncated).
    Ended(EpisodeEnd),
    /// The driver quit.
    Quit,
}

/// Records one episode driven with key events, one [`Recorder::tick`] per
/// 20 Hz control step.
#[derive(Debug)]
pub struct Recorder {
    env: TimeLimit<DriveEnv>,
    obs: Vec<f64>,
    info: Info,
    steer: f64,
    pedal: f64,
    key_releases: bool,
    hold_left: u32,
    hold_right: u32,
    observations: Vec<Vec<f64>>,
    actions: Vec<Vec<f64>>,
    rewards: Vec<f64>,
    status: RecordStatus,
}

impl Recorder {
    /// Starts an episode on `config`'s track (reset seed `seed`).
    /// `key_releases` says whether the terminal reports key releases. The
    /// accelerator starts at the level that holds the initial speed.
    ///
    /// # Errors
    /// [`crate::Error::InvalidConfig`] for an invalid config.
    pub fn new(config: &DriveConfig, seed: u64, key_releases: bool) -> Result<Self> {
        let mut env = make_env(config)?;
        let (obs, info) = env.reset(Some(seed))?;
        let v = env.inner().car().speed;
        let hold = (config.drag * v * v + config.rolling_resistance) / config.max_accel;
        Ok(Self {
            env,
            obs,
            info,
            steer: 0.0,
            pedal: (hold / PEDAL_STEP).round() * PEDAL_STEP,
            key_releases,
            hold_left: 0,
            hold_right: 0,
            observations: Vec::new(),
            actions: Vec::new(),
            rewards: Vec::new(),
            status: RecordStatus::Driving,
        })
    }

    /// Applies the key events received since the last tick, then steps the
    /// environment once with the resulting action and records the step.
    /// After the episode ended or the driver quit it does nothing.
    ///
    /// # Errors
    /// An environment error (none is expected).
    pub fn tick(&mut self, events: &[KeyEvent]) -> Result<RecordStatus> {
        if self.status != RecordStatus::Driving {
            return Ok(self.status);
        }
        let held = if self.key_releases {
            u32::MAX
        } else {
            HOLD_TICKS
        };
        for e in events {
            match (e.key, e.kind) {
                (DriveKey::Quit, KeyKind::Release) => {}
                (DriveKey::Quit, _) => {
                    self.status = RecordStatus::Quit;
                    return Ok(self.status);
                }
                (DriveKey::Left, KeyKind::Release) => self.hold_left = 0,
                (DriveKey::Right, KeyKind::Release) => self.hold_right = 0,
                (DriveKey::Left, _) => self.hold_left = held,
                (DriveKey::Right, _) => self.hold_right = held,
                (DriveKey::Up | DriveKey::Down, KeyKind::Release) => {}
                (DriveKey::Up, _) => self.pedal = (self.pedal + PEDAL_STEP).min(1.0),
                (DriveKey::Down, _) => self.pedal = (self.pedal - PEDAL_STEP).max(-1.0),
            }
        }
        let dir =
            f64::from(u8::from(self.hold_left > 0)) - f64::from(u8::from(self.hold_right > 0));
        if dir != 0.0 {
            self.steer = (self.steer + STEER_RATE * dir).clamp(-1.0, 1.0);
        } else if self.steer.abs() <= STEER_RETURN {
            self.steer = 0.0;
        } else {
            self.steer -= STEER_RETURN * self.steer.signum();
        }
        if self.hold_left != u32::MAX {
            self.hold_left = self.hold_left.saturating_sub(1);
        }
        if self.hold_right != u32::MAX {
            self.hold_right = self.hold_right.saturating_sub(1);
        }
        // Round to the key steps so stored actions are exact multiples.
        self.pedal = (self.pedal / PEDAL_STEP).round() * PEDAL_STEP;
        let action = [self.steer, self.pedal];
        let step = self.env.step(&action)?;
        self.observations
            .push(std::mem::replace(&mut self.obs, step.observation));
        self.actions.push(action.to_vec());
        self.rewards.push(step.reward);
        self.info = step.info;
        if step.terminated {
            self.status = RecordStatus::Ended(EpisodeEnd::Terminated);
        } else if step.truncated {
            self.status = RecordStatus::Ended(EpisodeEnd::Truncated);
        }
        Ok(self.status)
    }

    /// The status after the last tick.
    pub fn status(&self) -> RecordStatus {
        self.status
    }

    /// The car's state.
    pub fn car(&self) -> &CarState {
        self.env.inner().car()
    }

    /// Steps recorded so far.
    pub fn steps(&self) -> usize {
        self.actions.len()
    }

    /// The current steering and accelerator/brake.
    pub fn controls(&self) -> [f64; ACT_DIM] {
        [self.steer, self.pedal]
    }

    /// One line about speed, distance and controls.
    pub fn status_line(&self) -> String {
        let car = self.car();
        format!(
            "{:5.1} km/h  {:6.1} / {:.0} m  steer {:+.1}  pedal {:+.1}  {:5.1} s",
            car.speed * 3.6,
            self.info.get(INFO_DISTANCE).unwrap_or(0.0),
            self.env.inner().config().road_length,
            self.steer,
            self.pedal,
            self.steps() as f64 / CONTROL_HZ
        )
    }

    /// A top-down view of the road around the car, `rows` lines of `cols`
    /// characters (at least 5 x 5): the road's far end at the top, the car
    /// (`A`) near the bottom, walls `|`, lane lines `:`, stopped cars `#`,
    /// the finish line `=`. Each row is 2.5 m of road.
    pub fn view(&self, rows: usize, cols: usize) -> Vec<String> {
        ascii_view(self.env.inner(), rows.max(5), cols.max(5))
    }

    /// The demonstration recorded so far: one trajectory (none if no step
    /// was taken), marked as a person's and carrying its road
    /// ([`crate::scenario`]). An episode the driver quit counts as
    /// truncated.
    pub fn finish(self) -> Demos {
        let mut demos = Demos::new(ENV_ID, OBS_DIM, ACT_DIM, Some(CONTROL_HZ));
        demos.source = Some(red_core::DemoSource::Person);
        // The road was validated by `new`, so this cannot fail.
        let _ = crate::scenario::set_road(&mut demos, self.env.inner().config());
        if !self.actions.is_empty() {
            let end = match self.status {
                RecordStatus::Ended(end) => end,
                RecordStatus::Driving | RecordStatus::Quit => EpisodeEnd::Truncated,
            };
            demos.trajectories.push(Trajectory {
                observations: self.observations,
                actions: self.actions,
                rewards: Some(self.rewards),
                end,
            });
        }
        demos
    }
}

/// Metres of road per row of [`ascii_view`].
const METRES_PER_ROW: f64 = 2.5;

/// See [`Recorder::view`].
pub fn ascii_view(env: &DriveEnv, rows: usize, cols: usize) -> Vec<String> {
    let c = env.config();
    let car = env.car();
    let hw = c.half_width();
    let inner = cols - 2;
    let col_w = 2.0 * hw / inner as f64;
    let car_row = rows - 3;
    let near = env.track().between(
        car.x - 10.0 * c.car_length,
        car.x + rows as f64 * METRES_PER_ROW + c.car_length,
    );
    let (s, co) = car.heading.sin_cos();
    // The column nearest to each line between two lanes.
    let line_cols: Vec<usize> = (1..crate::config::NUM_LANES)
        .map(|k| {
            let y = c.lane_center(k) - 0.5 * c.lane_width;
            ((hw - y) / col_w - 0.5)
                .round()
                .clamp(0.0, (inner - 1) as f64) as usize
        })
        .collect();
    let mut out = Vec::with_capacity(rows);
    for r in 0..rows {
        let x = car.x + (car_row as f64 - r as f64) * METRES_PER_ROW;
        let mut line = String::with_capacity(cols);
        line.push('|');
        for k in 0..inner {
            let y = hw - (k as f64 + 0.5) * col_w;
            let in_box = |cx: f64, cy: f64| {
                (x - cx).abs() <= 0.5 * (c.car_length + METRES_PER_ROW)
                    && (y - cy).abs() <= 0.5 * (c.car_width + col_w)
            };
            // The car's body in its own frame.
            let (dx, dy) = (x - car.x, y - car.y);
            let (lx, ly) = (co * dx + s * dy, -s * dx + co * dy);
            let ch = if lx.abs() <= 0.5 * (c.car_length + METRES_PER_ROW)
                && ly.abs() <= 0.5 * (c.car_width + col_w)
            {
                'A'
            } else if near.iter().any(|o| in_box(o.x, o.y)) {
                '#'
            } else if x >= c.road_length && x < c.road_length + METRES_PER_ROW {
                '='
            } else if line_cols.contains(&k) && (x / METRES_PER_ROW).floor() as i64 % 2 == 0 {
                ':'
            } else {
                ' '
            };
            line.push(ch);
        }
        line.push('|');
        out.push(line);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quiet() -> DriveConfig {
        DriveConfig {
            start_lateral_noise: 0.0,
            start_heading_noise: 0.0,
            start_speed_noise: 0.0,
            ..Default::default()
        }
    }

    #[test]
    fn steering_ramps_and_returns_to_centre() {
        let mut r = Recorder::new(&quiet(), 0, false).unwrap();
        r.tick(&[KeyEvent::press(DriveKey::Left)]).unwrap();
        assert!((r.controls()[0] - STEER_RATE).abs() < 1e-12);
        // Held for HOLD_TICKS ticks without repeats, then it returns.
        for _ in 1..HOLD_TICKS {
            r.tick(&[]).unwrap();
        }
        assert!((r.controls()[0] - STEER_RATE * HOLD_TICKS as f64).abs() < 1e-12);
        r.tick(&[]).unwrap();
        r.tick(&[]).unwrap();
        r.tick(&[]).unwrap();
        assert_eq!(r.controls()[0], 0.0);
        let pedal = r.controls()[1];
        r.tick(&[
            KeyEvent::press(DriveKey::Down),
            KeyEvent::press(DriveKey::Down),
        ])
        .unwrap();
        assert!((r.controls()[1] - (pedal - 2.0 * PEDAL_STEP)).abs() < 1e-9);
    }

    #[test]
    fn releases_hold_a_key_until_released() {
        let mut r = Recorder::new(&quiet(), 0, true).unwrap();
        r.tick(&[KeyEvent::press(DriveKey::Right)]).unwrap();
        for _ in 0..3 {
            r.tick(&[]).unwrap();
        }
        assert!((r.controls()[0] + 4.0 * STEER_RATE).abs() < 1e-12);
        r.tick(&[KeyEvent {
            key: DriveKey::Right,
            kind: KeyKind::Release,
        }])
        .unwrap();
        assert!((r.controls()[0] + 4.0 * STEER_RATE - STEER_RETURN).abs() < 1e-12);
    }

    #[test]
    fn view_shows_car_walls_and_obstacles() {
        let c = quiet();
        let mut env = DriveEnv::new(&c).unwrap();
        env.reset(Some(0)).unwrap();
        let first = env.track().obstacles[0];
        env.reset_to(CarState {
            x: first.x - 30.0,
            y: 0.0,
            heading: 0.0,
            speed: 20.0,
        })
        .unwrap();
        let v = ascii_view(&env, 30, 44);
        assert_eq!(v.len(), 30);
        assert!(v.iter().all(|l| l.chars().count() == 44));
        assert!(v.iter().all(|l| l.starts_with('|') && l.ends_with('|')));
        assert!(v[27].contains('A'));
        assert!(v.iter().any(|l| l.contains('#')));
        assert!(v.iter().any(|l| l.contains(':')));
    }
}
