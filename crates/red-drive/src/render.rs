//! Top-down pictures of the road: obstacles, the paths cars drove, their
//! lidar rays at chosen steps and how each episode ended. The road is cut
//! into strips stacked from top to bottom, driving from left to right (the
//! car's left is up). Drawn with plotters' bitmap backend; text (the
//! legend) is optional and skipped if no system font is found.

use std::path::Path;

use plotters::prelude::*;
use red_core::{EpisodeEnd, Trajectory};

use crate::config::{DriveConfig, NUM_LANES, NUM_RAYS};
use crate::env::{CarState, DriveEnv, INFO_COLLISION, INFO_SUCCESS};
use crate::{Error, Result};

/// How a drawn path ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PathEnd {
    /// Reached the end of the road (drawn as a ring).
    Success,
    /// Hit an obstacle or a wall (drawn as a cross).
    Collision,
    /// Cut by the time limit or stopped by the driver (drawn as a square).
    Stopped,
}

/// One path to draw.
#[derive(Debug, Clone, PartialEq)]
pub struct PathSpec {
    /// Name in the legend.
    pub label: String,
    /// Colour, RGB.
    pub colour: [u8; 3],
    /// The car's states along the path, in order.
    pub poses: Vec<CarState>,
    /// How the episode ended.
    pub end: PathEnd,
    /// Lidar readings to draw: the car's state and its ranges in metres.
    pub lidar: Vec<(CarState, [f64; NUM_RAYS])>,
}

/// Size and layout of a picture.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderOptions {
    /// Metres of road per strip.
    pub strip_length: f64,
    /// Picture width in pixels.
    pub width_px: u32,
    /// Empty border in pixels.
    pub margin_px: u32,
    /// Vertical space between strips in pixels.
    pub strip_gap_px: u32,
    /// Whether to reserve a row on top for the legend (labels need a
    /// system font; without one the row stays empty).
    pub legend: bool,
}

impl Default for RenderOptions {
    /// 250 m strips on a 1600-pixel-wide picture (6.2 pixels per metre: a
    /// car is 28 x 11 pixels), a legend row.
    fn default() -> Self {
        Self {
            strip_length: 250.0,
            width_px: 1600,
            margin_px: 20,
            strip_gap_px: 24,
            legend: true,
        }
    }
}

const LEGEND_PX: u32 = 28;

impl RenderOptions {
    fn px_per_metre(&self) -> f64 {
        f64::from(self.width_px - 2 * self.margin_px) / self.strip_length
    }

    fn road_px(&self, config: &DriveConfig) -> u32 {
        (2.0 * config.half_width() * self.px_per_metre()).ceil() as u32
    }

    fn strips(&self, config: &DriveConfig) -> u32 {
        (config.road_length / self.strip_length).ceil().max(1.0) as u32
    }

    fn top_px(&self) -> u32 {
        self.margin_px + if self.legend { LEGEND_PX } else { 0 }
    }

    /// The picture's `(width, height)` in pixels for `config`'s road.
    pub fn image_size(&self, config: &DriveConfig) -> (u32, u32) {
        let n = self.strips(config);
        let h =
            self.top_px() + n * self.road_px(config) + (n - 1) * self.strip_gap_px + self.margin_px;
        (self.width_px, h)
    }

    fn validate(&self, path: &Path) -> Result<()> {
        if !(self.strip_length.is_finite() && self.strip_length > 0.0)
            || self.width_px <= 2 * self.margin_px + 10
        {
            return Err(Error::Render {
                path: path.to_path_buf(),
                reason: format!(
                    "need strip_length > 0 and width_px > 2 x margin_px + 10, got {self:?}"
                ),
            });
        }
        Ok(())
    }
}

/// Replays `trajectory`'s actions on `config`'s track from the state read
/// back from its first observation, and returns the car's states (one more
/// than the actions) and how the replay ended. With a demonstration made on
/// this track the replay retraces it; numbers rounded in the file can make
/// it drift slightly, so the check against the recorded lidar allows a few
/// mismatching steps.
///
/// # Errors
/// [`Error::Replay`] for an empty trajectory, one of another scenario, or
/// one that does not retrace on this track: the replay ends before the
/// recording, or does not end where the recording terminated, or more than
/// 5% of the replayed lidar readings differ from the recorded ones.
pub fn replay(config: &DriveConfig, trajectory: &Trajectory) -> Result<(Vec<CarState>, PathEnd)> {
    let first = trajectory
        .observations
        .first()
        .ok_or_else(|| Error::Replay {
            reason: "the trajectory is empty".into(),
        })?;
    let other_track = "was it recorded with another --track-seed or config?";
    let mut env = DriveEnv::new(config)?;
    let mut obs = env.reset_to(CarState::from_first_observation(config, first)?)?;
    let mut poses = vec![*env.car()];
    let mut end = PathEnd::Stopped;
    let mut mismatched = 0usize;
    let mut first_mismatch = None;
    let n = trajectory.actions.len();
    for (t, a) in trajectory.actions.iter().enumerate() {
        if let Some(rec) = trajectory.observations.get(t)
            && rec
                .iter()
                .zip(&obs)
                .take(NUM_RAYS)
                .any(|(r, o)| (r - o).abs() > 0.01)
        {
            mismatched += 1;
            first_mismatch.get_or_insert(t);
        }
        let step = red_core::Env::step(&mut env, a)?;
        obs = step.observation;
        poses.push(*env.car());
        if step.terminated {
            end = if step.info.get(INFO_SUCCESS) == Some(1.0) {
                PathEnd::Success
            } else if step.info.get(INFO_COLLISION) == Some(1.0) {
                PathEnd::Collision
            } else {
                PathEnd::Stopped
            };
            if t + 1 < n {
                return Err(Error::Replay {
                    reason: format!(
                        "the replay ended ({end:?}) at step {t} but the demonstration goes on \
                         to step {}; {other_track}",
                        n - 1
                    ),
                });
            }
            break;
        }
    }
    if end == PathEnd::Stopped && trajectory.end == EpisodeEnd::Terminated {
        return Err(Error::Replay {
            reason: format!(
                "the demonstration terminated but its replay on this track did not; {other_track}"
            ),
        });
    }
    if mismatched * 20 > n {
        return Err(Error::Replay {
            reason: format!(
                "the lidar readings of {mismatched} of {n} steps differ from the recorded ones \
                 (first at step {}); {other_track}",
                first_mismatch.unwrap_or(0)
            ),
        });
    }
    Ok((poses, end))
}

/// A [`PathSpec`] for a demonstration: its replayed path, and lidar rays
/// (from its recorded observations) every `lidar_every` steps (0: none).
///
/// # Errors
/// As [`replay`].
pub fn demo_path(
    config: &DriveConfig,
    trajectory: &Trajectory,
    label: impl Into<String>,
    colour: [u8; 3],
    lidar_every: usize,
) -> Result<PathSpec> {
    let (poses, end) = replay(config, trajectory)?;
    let mut lidar = Vec::new();
    if lidar_every > 0 {
        for (t, obs) in trajectory
            .observations
            .iter()
            .enumerate()
            .step_by(lidar_every)
        {
            if let Some(p) = poses.get(t) {
                let mut r = [0.0; NUM_RAYS];
                for (ri, o) in r.iter_mut().zip(obs) {
                    *ri = o * config.lidar_range;
                }
                lidar.push((*p, r));
            }
        }
    }
    Ok(PathSpec {
        label: label.into(),
        colour,
        poses,
        end,
        lidar,
    })
}

/// Colours of the paths drawn by [`demo_paths`], in turn.
pub const PATH_COLOURS: [[u8; 3]; 6] = [
    [20, 90, 200],
    [230, 130, 0],
    [30, 150, 60],
    [150, 50, 170],
    [0, 160, 170],
    [120, 80, 40],
];

/// A [`PathSpec`] per trajectory of `demos` ([`demo_path`]), labelled
/// `label` (with ` #i` when there are several) and coloured in turn from
/// [`PATH_COLOURS`].
///
/// # Errors
/// As [`replay`], naming the trajectory.
pub fn demo_paths(
    config: &DriveConfig,
    demos: &red_core::Demos,
    label: &str,
    lidar_every: usize,
) -> Result<Vec<PathSpec>> {
    let n = demos.trajectories.len();
    demos
        .trajectories
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let name = if n == 1 {
                label.to_string()
            } else {
                format!("{label} #{i}")
            };
            let colour = PATH_COLOURS[i % PATH_COLOURS.len()];
            demo_path(config, t, name, colour, lidar_every).map_err(|e| match e {
                Error::Replay { reason } => Error::Replay {
                    reason: format!("trajectory {i}: {reason}"),
                },
                other => other,
            })
        })
        .collect()
}

/// Clips the segment `p-q` to `a <= x <= b`.
fn clip_x(p: (f64, f64), q: (f64, f64), a: f64, b: f64) -> Option<((f64, f64), (f64, f64))> {
    let (mut p, mut q) = (p, q);
    if p.0 > q.0 {
        std::mem::swap(&mut p, &mut q);
    }
    if q.0 < a || p.0 > b {
        return None;
    }
    let at = |x: f64| {
        if (q.0 - p.0).abs() < 1e-12 {
            (x, p.1)
        } else {
            (x, p.1 + (q.1 - p.1) * (x - p.0) / (q.0 - p.0))
        }
    };
    let p2 = if p.0 < a { at(a) } else { p };
    let q2 = if q.0 > b { at(b) } else { q };
    Some((p2, q2))
}

/// Draws `config`'s road with `paths` into a PNG at `path`, of size
/// [`RenderOptions::image_size`].
///
/// # Errors
/// [`Error::InvalidConfig`] for an invalid config, [`Error::Render`] if the
/// picture cannot be drawn or written.
pub fn render_png(
    path: &Path,
    config: &DriveConfig,
    paths: &[PathSpec],
    options: &RenderOptions,
) -> Result<()> {
    config.validate()?;
    options.validate(path)?;
    let err = |e: String| Error::Render {
        path: path.to_path_buf(),
        reason: e,
    };
    let world = crate::env::World::new(config)?;
    let (w, h) = options.image_size(config);
    let root = BitMapBackend::new(path, (w, h)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
    let ppm = options.px_per_metre();
    let hw = config.half_width();
    let road_px = options.road_px(config) as i32;
    let gap = options.strip_gap_px as i32;
    let left = options.margin_px as i32;
    let top = options.top_px() as i32;
    let s_len = options.strip_length;
    let road = RGBColor(205, 205, 205);
    let wall = RGBColor(60, 60, 60);
    let obstacle = RGBColor(200, 40, 40);

    for k in 0..options.strips(config) as i32 {
        let a = f64::from(k) * s_len;
        let b = (a + s_len).min(config.road_length);
        let y0 = top + k * (road_px + gap);
        let px = move |x: f64, y: f64| -> (i32, i32) {
            (
                left + ((x - a) * ppm).round() as i32,
                y0 + ((hw - y) * ppm).round() as i32,
            )
        };
        let x_end = px(b, 0.0).0;
        let r = &root;
        let drawn = (|| -> std::result::Result<(), String> {
            r.draw(&Rectangle::new(
                [(left, y0), (x_end, y0 + road_px)],
                road.filled(),
            ))
            .map_err(|e| e.to_string())?;
            for yy in [hw, -hw] {
                let p = px(a, yy);
                r.draw(&PathElement::new(
                    vec![p, (x_end, p.1)],
                    wall.stroke_width(3),
                ))
                .map_err(|e| e.to_string())?;
            }
            for lane in 1..NUM_LANES {
                let yl = config.lane_center(lane) - 0.5 * config.lane_width;
                let mut x = a;
                while x < b {
                    let p = px(x, yl);
                    let q = px((x + 3.0).min(b), yl);
                    r.draw(&PathElement::new(vec![p, q], WHITE.stroke_width(1)))
                        .map_err(|e| e.to_string())?;
                    x += 9.0;
                }
            }
            if b >= config.road_length {
                let p = px(config.road_length, hw);
                let q = px(config.road_length, -hw);
                r.draw(&PathElement::new(vec![p, q], BLACK.stroke_width(3)))
                    .map_err(|e| e.to_string())?;
            }
            let half_l = 0.5 * config.car_length;
            let half_w = 0.5 * config.car_width;
            for o in world.track().between(a - half_l, b + half_l) {
                let x0 = (o.x - half_l).max(a);
                let x1 = (o.x + half_l).min(b);
                if x1 > x0 {
                    r.draw(&Rectangle::new(
                        [px(x0, o.y + half_w), px(x1, o.y - half_w)],
                        obstacle.filled(),
                    ))
                    .map_err(|e| e.to_string())?;
                }
            }
            for spec in paths {
                let [cr, cg, cb] = spec.colour;
                let colour = RGBColor(cr, cg, cb);
                let faint = RGBAColor(cr, cg, cb, 0.45);
                for (p, ranges) in &spec.lidar {
                    if p.x < a - config.lidar_range || p.x > b + config.lidar_range {
                        continue;
                    }
                    for (ang, len) in world.ray_angles().iter().zip(ranges) {
                        let (s, c) = (p.heading + ang).sin_cos();
                        let q = (p.x + c * len, p.y + s * len);
                        if let Some((u, v)) = clip_x((p.x, p.y), q, a, b) {
                            r.draw(&PathElement::new(
                                vec![px(u.0, u.1), px(v.0, v.1)],
                                faint.stroke_width(1),
                            ))
                            .map_err(|e| e.to_string())?;
                        }
                    }
                }
                for pair in spec.poses.windows(2) {
                    if let Some((u, v)) =
                        clip_x((pair[0].x, pair[0].y), (pair[1].x, pair[1].y), a, b)
                    {
                        r.draw(&PathElement::new(
                            vec![px(u.0, u.1), px(v.0, v.1)],
                            colour.stroke_width(2),
                        ))
                        .map_err(|e| e.to_string())?;
                    }
                }
                if let Some(last) = spec.poses.last()
                    && last.x >= a
                    && (last.x < b || (b >= config.road_length && last.x <= b + s_len))
                {
                    let (cx, cy) = px(last.x.min(b), last.y);
                    let m = 6;
                    match spec.end {
                        PathEnd::Success => r
                            .draw(&Circle::new((cx, cy), m, colour.stroke_width(2)))
                            .map_err(|e| e.to_string())?,
                        PathEnd::Collision => {
                            for (d0, d1) in [((-m, -m), (m, m)), ((-m, m), (m, -m))] {
                                r.draw(&PathElement::new(
                                    vec![(cx + d0.0, cy + d0.1), (cx + d1.0, cy + d1.1)],
                                    colour.stroke_width(3),
                                ))
                                .map_err(|e| e.to_string())?;
                            }
                        }
                        PathEnd::Stopped => r
                            .draw(&Rectangle::new(
                                [(cx - m, cy - m), (cx + m, cy + m)],
                                colour.stroke_width(2),
                            ))
                            .map_err(|e| e.to_string())?,
                    }
                }
            }
            Ok(())
        })();
        drawn.map_err(err)?;
    }
    if options.legend {
        let mut x = left;
        for spec in paths {
            let [cr, cg, cb] = spec.colour;
            let colour = RGBColor(cr, cg, cb);
            let y = options.margin_px as i32 + 8;
            root.draw(&Rectangle::new([(x, y), (x + 24, y + 4)], colour.filled()))
                .map_err(|e| err(e.to_string()))?;
            // Text needs a system font; a picture without labels is still
            // useful, so a font failure is not an error.
            let _ = root.draw(&Text::new(
                spec.label.clone(),
                (x + 30, y - 6),
                ("sans-serif", 16).into_font().color(&BLACK),
            ));
            x += 40 + 9 * spec.label.chars().count() as i32;
        }
    }
    root.present().map_err(|e| err(e.to_string()))?;
    Ok(())
}

/// The `(width, height)` in a PNG file's header.
///
/// # Errors
/// [`Error::Render`] if the file cannot be read or is not a PNG.
pub fn png_size(path: &Path) -> Result<(u32, u32)> {
    let bytes = std::fs::read(path).map_err(|e| Error::Render {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    const SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a];
    if bytes.len() < 24 || bytes[..8] != SIGNATURE || &bytes[12..16] != b"IHDR" {
        return Err(Error::Render {
            path: path.to_path_buf(),
            reason: "not a PNG file".into(),
        });
    }
    let be = |i: usize| u32::from_be_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
    Ok((be(16), be(20)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clip_keeps_the_part_inside() {
        assert_eq!(clip_x((0.0, 0.0), (10.0, 10.0), 20.0, 30.0), None);
        let (p, q) = clip_x((0.0, 0.0), (10.0, 10.0), 5.0, 8.0).unwrap();
        assert_eq!(p, (5.0, 5.0));
        assert_eq!(q, (8.0, 8.0));
        let (p, q) = clip_x((10.0, 0.0), (0.0, 10.0), 0.0, 20.0).unwrap();
        assert_eq!((p, q), ((0.0, 10.0), (10.0, 0.0)));
    }
}
