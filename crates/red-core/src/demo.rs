//! Expert demonstrations: the dataset type and the project's JSON format.
//!
//! A demo file is one JSON object: a header (`format` = `"red-demos"`,
//! `version`, `env_id`, `obs_dim`, `act_dim`, optional `control_hz`) and
//! `trajectories`, each with `observations` and `actions` (one row per
//! step, `observations[t]` being the state `actions[t]` was taken in),
//! optional true `rewards`, and `end` (`"terminated"` or `"truncated"`):
//!
//! ```json
//! {"format": "red-demos", "version": 1, "env_id": "drive", "obs_dim": 2,
//!  "act_dim": 1, "control_hz": 20.0,
//!  "trajectories": [{"observations": [[0.0, 1.0], [0.5, 1.0]],
//!                    "actions": [[0.1], [-0.2]], "rewards": [1.0, 0.5],
//!                    "end": "truncated"}]}
//! ```
//!
//! Reading validates everything ([`Demos::validate`]) and reports the
//! file, trajectory and step of the first problem; JSON syntax errors, and
//! `NaN`, `Infinity` or out-of-range numbers such as `1e400` (which JSON
//! cannot hold, and demonstrations must not), are reported with their line
//! and column too. Importers for the formats of the original RED release
//! and of OpenAI baselines are in [`crate::import`].
//!
//! ```
//! use red_core::demo::{Demos, EpisodeEnd, Trajectory};
//! let mut demos = Demos::new("walk", 1, 1, Some(10.0));
//! demos.trajectories.push(Trajectory {
//!     observations: vec![vec![0.0], vec![0.5]],
//!     actions: vec![vec![0.5], vec![0.5]],
//!     rewards: None,
//!     end: EpisodeEnd::Truncated,
//! });
//! demos.validate()?;
//! let text = serde_json::to_string(&demos).unwrap();
//! assert_eq!(Demos::from_json_str(&text)?, demos);
//!
//! let broken = text.replace("[0.5],[0.5]", "[0.5],[0.5,1.0]");
//! let err = Demos::from_json_str(&broken).unwrap_err().to_string();
//! assert!(err.contains("trajectory 0, step 1"), "{err}");
//! # Ok::<(), red_core::Error>(())
//! ```

use std::fmt::Write as _;
use std::path::Path;

use ndarray::Array2;
use serde::{Deserialize, Serialize};

use crate::{Error, Result};

/// Name written in the `format` field of every demo file.
pub const FORMAT_NAME: &str = "red-demos";
/// The version of the format this build writes. Version 2 added the
/// optional `source` and `scenario` fields, version 3 the optional
/// `made_with`; files of versions 1 and 2 (without them) are read as
/// before.
pub const FORMAT_VERSION: u32 = 3;
/// The oldest version this build reads.
pub const OLDEST_READABLE_VERSION: u32 = 1;

/// The largest magnitude an observation, action or reward of a
/// demonstration may have: 1e9. The networks that learn from the pairs work
/// in `f32`, whose largest number is 3.4e38: a value of 1e308 (finite in
/// the file) becomes infinite there, and even 1e20 overflows when squared by
/// a loss. Below 1e9 the square (1e18) and sums of squares over any data
/// set stay far inside `f32`. No observation or action of the supported
/// tasks comes within several orders of magnitude of it (MuJoCo's are below
/// 1e3, the driving scenario's below 1e2); rescale larger data first.
pub const MAX_ABS_VALUE: f64 = 1e9;

/// Who or what made a set of demonstrations. Tables call a person's
/// demonstration a "demonstration", not an "expert".
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DemoSource {
    /// A person at the controls (for example `red-cli drive record`).
    Person,
    /// A scripted driver or controller.
    Script,
    /// A trained policy.
    Policy,
    /// Converted from another format; the maker is not known.
    Imported,
}

impl DemoSource {
    /// How a table names the demonstrations' row: `"demonstration"` for a
    /// person's, `"expert"` otherwise.
    pub fn row_label(source: Option<Self>) -> &'static str {
        match source {
            Some(Self::Person) => "demonstration",
            _ => "expert",
        }
    }
}

/// How a trajectory ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EpisodeEnd {
    /// The task ended it (a fall, a crash, the goal).
    Terminated,
    /// A time limit cut it.
    Truncated,
}

/// One demonstrated episode: `observations[t]` is the state in which
/// `actions[t]` was taken, so both have the same length.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Trajectory {
    /// States, one per step, each of `obs_dim` numbers.
    pub observations: Vec<Vec<f64>>,
    /// Actions, one per step, each of `act_dim` numbers.
    pub actions: Vec<Vec<f64>>,
    /// The environment's true rewards, one per step, if known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rewards: Option<Vec<f64>>,
    /// How the episode ended.
    pub end: EpisodeEnd,
}

impl Trajectory {
    /// Number of steps (state-action pairs).
    pub fn len(&self) -> usize {
        self.actions.len()
    }

    /// Whether it has no steps (never the case in a valid set).
    pub fn is_empty(&self) -> bool {
        self.actions.is_empty()
    }

    /// The sum of the true rewards, if known.
    pub fn true_return(&self) -> Option<f64> {
        self.rewards.as_ref().map(|r| r.iter().sum())
    }
}

/// A set of demonstrations for one environment.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Demos {
    /// Always [`FORMAT_NAME`].
    pub format: String,
    /// The format's version.
    pub version: u32,
    /// The environment's id (for example `"drive"`, `"Hopper-v5"`).
    pub env_id: String,
    /// Length of an observation.
    pub obs_dim: usize,
    /// Length of an action.
    pub act_dim: usize,
    /// Control frequency in Hz, if meaningful.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub control_hz: Option<f64>,
    /// Who or what made the demonstrations, if known (version 2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<DemoSource>,
    /// The environment's own settings the demonstrations were made under
    /// (version 2): for `drive`, the road (`red_drive::DriveConfig`, track
    /// seed included), so that every command using the file uses that road.
    /// The environment's crate reads and checks it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scenario: Option<serde_json::Value>,
    /// How the demonstrations were made, if recorded (version 3): a JSON
    /// object of the generating command's settings, for example the policy
    /// file, seed, whether actions were sampled and whether they are stored
    /// clipped or raw (`red-cli mujoco demos`), or the file and count a
    /// subset was taken from (`red-cli demo take`). Informational: nothing
    /// reads it back to change behaviour.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub made_with: Option<serde_json::Value>,
    /// The trajectories.
    pub trajectories: Vec<Trajectory>,
}

impl Demos {
    /// An empty set for `env_id` with the given dimensions.
    pub fn new(
        env_id: impl Into<String>,
        obs_dim: usize,
        act_dim: usize,
        control_hz: Option<f64>,
    ) -> Self {
        Self {
            format: FORMAT_NAME.into(),
            version: FORMAT_VERSION,
            env_id: env_id.into(),
            obs_dim,
            act_dim,
            control_hz,
            source: None,
            scenario: None,
            made_with: None,
            trajectories: Vec::new(),
        }
    }

    /// Total number of state-action pairs.
    pub fn num_pairs(&self) -> usize {
        self.trajectories.iter().map(|t| t.actions.len()).sum()
    }

    /// All state-action pairs stacked, trajectory after trajectory:
    /// `((N, obs_dim), (N, act_dim))` with `N = num_pairs()`.
    ///
    /// Rows shorter than the dimensions are padded with zeros and longer
    /// ones cut; a set that passed [`Demos::validate`] has neither.
    pub fn pairs(&self) -> (Array2<f64>, Array2<f64>) {
        let n = self.num_pairs();
        let mut s = Array2::zeros((n, self.obs_dim));
        let mut a = Array2::zeros((n, self.act_dim));
        let mut row = 0;
        for t in &self.trajectories {
            for (o, u) in t.observations.iter().zip(&t.actions) {
                for (j, v) in o.iter().take(self.obs_dim).enumerate() {
                    s[[row, j]] = *v;
                }
                for (j, v) in u.iter().take(self.act_dim).enumerate() {
                    a[[row, j]] = *v;
                }
                row += 1;
            }
        }
        (s, a)
    }

    /// The state dimensions that hold an episode's context rather than its
    /// behaviour: constant within every trajectory (to 1e-9 relative) but
    /// not the same in all of them, such as Reacher's target. Empty for
    /// fewer than two trajectories or a trajectory of fewer than two steps
    /// (nothing then tells a context from a single value).
    pub fn context_dims(&self) -> Vec<usize> {
        let steps = |t: &Trajectory| t.observations.len().min(t.actions.len());
        if self.trajectories.len() < 2 || self.trajectories.iter().any(|t| steps(t) < 2) {
            return Vec::new();
        }
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * (1.0 + a.abs().max(b.abs()));
        (0..self.obs_dim)
            .filter(|&j| {
                let value = |o: &Vec<f64>| o.get(j).copied().unwrap_or(0.0);
                let firsts: Vec<f64> = self
                    .trajectories
                    .iter()
                    .map(|t| value(&t.observations[0]))
                    .collect();
                let constant = self.trajectories.iter().zip(&firsts).all(|(t, &v0)| {
                    let mut rows = t.observations.iter().take(steps(t));
                    rows.all(|o| close(value(o), v0))
                });
                constant && firsts.iter().any(|&v| !close(v, firsts[0]))
            })
            .collect()
    }

    /// The set as an environment with a time feature sees it: every
    /// observation gets one more number, its step in the trajectory over
    /// `max_steps` (0 for the first, as at a reset). Assumes each trajectory
    /// starts at a reset.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] if `max_steps` is 0 or a trajectory has more
    /// than `max_steps` steps (it cannot come from that time limit).
    pub fn with_time_feature(mut self, max_steps: usize) -> Result<Self> {
        if max_steps == 0 {
            return Err(Error::InvalidConfig {
                field: "max_steps".into(),
                reason: "must be at least 1".into(),
            });
        }
        if let Some((i, t)) = self
            .trajectories
            .iter()
            .enumerate()
            .find(|(_, t)| t.len() > max_steps)
        {
            return Err(Error::InvalidConfig {
                field: "time_feature".into(),
                reason: format!(
                    "trajectory {i} has {} steps, more than the time limit of {max_steps}",
                    t.len()
                ),
            });
        }
        for t in &mut self.trajectories {
            for (k, o) in t.observations.iter_mut().enumerate() {
                o.truncate(self.obs_dim);
                o.resize(self.obs_dim, 0.0);
                o.push(k as f64 / max_steps as f64);
            }
        }
        self.obs_dim += 1;
        Ok(self)
    }

    /// The length of each trajectory.
    pub fn lengths(&self) -> Vec<usize> {
        self.trajectories.iter().map(Trajectory::len).collect()
    }

    /// The true return of each trajectory, if every trajectory has rewards.
    pub fn returns(&self) -> Option<Vec<f64>> {
        self.trajectories
            .iter()
            .map(Trajectory::true_return)
            .collect()
    }

    /// Rounds every observation, action and reward to `digits` significant
    /// digits (smaller files; 0 and non-finite numbers stay as they are).
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] if `digits` is 0.
    pub fn round_to_significant(&mut self, digits: usize) -> Result<()> {
        if digits == 0 {
            return Err(Error::InvalidConfig {
                field: "sig_digits".to_string(),
                reason: "must be at least 1".to_string(),
            });
        }
        for t in &mut self.trajectories {
            let rows = t.observations.iter_mut().chain(t.actions.iter_mut());
            let values = rows.flatten().chain(t.rewards.iter_mut().flatten());
            for v in values {
                *v = round_significant(*v, digits);
            }
        }
        Ok(())
    }

    /// A few lines describing the set: environment, counts, dimensions,
    /// lengths, how episodes ended and the true returns when known.
    pub fn summary(&self) -> String {
        let mut s = String::new();
        let lengths = self.lengths();
        let _ = write!(
            s,
            "{} v{} demos for `{}`: {} trajectories, {} state-action pairs, obs dim {}, act dim {}",
            self.format,
            self.version,
            self.env_id,
            self.trajectories.len(),
            self.num_pairs(),
            self.obs_dim,
            self.act_dim
        );
        if let Some(hz) = self.control_hz {
            let _ = write!(s, ", {hz} Hz");
        }
        if let (Some(min), Some(max)) = (lengths.iter().min(), lengths.iter().max()) {
            let mean = lengths.iter().sum::<usize>() as f64 / lengths.len() as f64;
            let terminated = self
                .trajectories
                .iter()
                .filter(|t| t.end == EpisodeEnd::Terminated)
                .count();
            let _ = write!(
                s,
                "\nlengths: min {min}, mean {mean:.1}, max {max}; {terminated} terminated, {} truncated",
                self.trajectories.len() - terminated
            );
        }
        match self.returns() {
            Some(r) if !r.is_empty() => {
                let n = r.len() as f64;
                let mean = r.iter().sum::<f64>() / n;
                let std = (r.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt();
                let min = r.iter().copied().fold(f64::INFINITY, f64::min);
                let max = r.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                let _ = write!(
                    s,
                    "\ntrue return: mean {mean:.3} +- {std:.3} (min {min:.3}, max {max:.3})"
                );
            }
            _ => s.push_str("\ntrue return: unknown (no rewards recorded)"),
        }
        s
    }

    /// Checks everything a learner relies on: the header (format name,
    /// version, a non-empty `env_id`, positive dimensions, a positive finite
    /// `control_hz`), at least one trajectory, and in each trajectory at
    /// least one step, as many observations (and rewards, if any) as
    /// actions, rows of `obs_dim` and `act_dim` numbers, all finite and at
    /// most [`MAX_ABS_VALUE`] in magnitude.
    ///
    /// # Errors
    /// [`Error::Demo`] for the first problem, with its trajectory and step
    /// (`path` is `None`; [`Demos::read`] fills it in).
    pub fn validate(&self) -> Result<()> {
        let err = |trajectory, step, reason: String| Error::Demo {
            path: None,
            trajectory,
            step,
            reason,
        };
        check_header(&self.format, self.version).map_err(|r| err(None, None, r))?;
        if self.env_id.trim().is_empty() {
            return Err(err(None, None, "env_id is empty".into()));
        }
        if self.obs_dim == 0 || self.act_dim == 0 {
            return Err(err(
                None,
                None,
                format!(
                    "obs_dim and act_dim must be positive, got {} and {}",
                    self.obs_dim, self.act_dim
                ),
            ));
        }
        if let Some(hz) = self.control_hz
            && !(hz.is_finite() && hz > 0.0)
        {
            return Err(err(
                None,
                None,
                format!("control_hz is {hz}, it must be a positive finite number"),
            ));
        }
        if self.trajectories.is_empty() {
            return Err(err(None, None, "no trajectories".into()));
        }
        for (i, t) in self.trajectories.iter().enumerate() {
            let n = t.actions.len();
            if n == 0 && t.observations.is_empty() {
                return Err(err(Some(i), None, "empty trajectory (no steps)".into()));
            }
            if t.observations.len() != n {
                return Err(err(
                    Some(i),
                    None,
                    format!(
                        "{} observations but {n} actions: they must have the same length \
                         (observations[t] is the state actions[t] was taken in)",
                        t.observations.len()
                    ),
                ));
            }
            if let Some(r) = &t.rewards
                && r.len() != n
            {
                return Err(err(
                    Some(i),
                    None,
                    format!(
                        "{} rewards but {n} actions: need one reward per step",
                        r.len()
                    ),
                ));
            }
            for k in 0..n {
                check_row("observation", &t.observations[k], self.obs_dim, "obs_dim")
                    .map_err(|r| err(Some(i), Some(k), r))?;
                check_row("action", &t.actions[k], self.act_dim, "act_dim")
                    .map_err(|r| err(Some(i), Some(k), r))?;
                if let Some(r) = &t.rewards {
                    if !r[k].is_finite() {
                        return Err(err(
                            Some(i),
                            Some(k),
                            format!("reward is {}, not a finite number", r[k]),
                        ));
                    }
                    if r[k].abs() > MAX_ABS_VALUE {
                        return Err(err(Some(i), Some(k), too_large("reward", r[k])));
                    }
                }
            }
        }
        Ok(())
    }

    /// Parses and validates a demo file's text.
    ///
    /// # Errors
    /// [`Error::Demo`] (without `path`) for invalid JSON (with line and
    /// column: a truncated file, `NaN`, `Infinity`, a number too large for
    /// `f64`), a wrong format name or unknown version, a missing or
    /// ill-typed field, or anything [`Demos::validate`] rejects; the
    /// trajectory and step are given when the problem has them. A UTF-8
    /// byte-order mark at the start is skipped.
    pub fn from_json_str(text: &str) -> Result<Self> {
        // A UTF-8 byte-order mark (some Windows editors write one) is
        // skipped: it is not part of the JSON.
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        if text.trim().is_empty() {
            return Err(demo_err(
                None,
                None,
                "the file is empty, expected a JSON demo object".into(),
            ));
        }
        if !text.trim_start().starts_with('{') {
            let found: String = text.trim_start().chars().take(20).collect();
            return Err(demo_err(
                None,
                None,
                format!("expected a JSON object with the {FORMAT_NAME} header, found `{found}`"),
            ));
        }
        // The header first, so that a file of another format or version is
        // named as such rather than failing on its first unfamiliar field.
        let probe: Probe = serde_json::from_str(text).map_err(|e| json_error(text, &e))?;
        probe.check()?;
        let demos: Demos = serde_json::from_str(text).map_err(|e| json_error(text, &e))?;
        demos.validate()?;
        Ok(demos)
    }

    /// Reads and validates a demo file.
    ///
    /// # Errors
    /// [`Error::Io`] if it cannot be read, [`Error::Demo`] naming the file
    /// (and trajectory, step, line and column where they apply) if it is not
    /// valid UTF-8 or [`Demos::from_json_str`] rejects it.
    pub fn read(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let text = std::str::from_utf8(&bytes).map_err(|e| Error::Demo {
            path: Some(path.to_path_buf()),
            trajectory: None,
            step: None,
            reason: format!(
                "not UTF-8 text (byte {}): not a JSON demo file",
                e.valid_up_to()
            ),
        })?;
        Self::from_json_str(text).map_err(|e| e.with_path(path))
    }

    /// Validates the set, then writes it as JSON to `path` atomically: the
    /// text goes to a temporary file beside `path`, which is then renamed
    /// over it, so a reader never sees half a file.
    ///
    /// # Errors
    /// [`Error::Demo`] if [`Demos::validate`] rejects the set (nothing is
    /// written), [`Error::Io`] if the file cannot be written.
    pub fn write(&self, path: &Path) -> Result<()> {
        self.validate().map_err(|e| e.with_path(path))?;
        let text = serde_json::to_string(self).map_err(|e| Error::Demo {
            path: Some(path.to_path_buf()),
            trajectory: None,
            step: None,
            reason: e.to_string(),
        })?;
        crate::checkpoint::write_atomic(path, text.as_bytes())
    }
}

fn demo_err(trajectory: Option<usize>, step: Option<usize>, reason: String) -> Error {
    Error::Demo {
        path: None,
        trajectory,
        step,
        reason,
    }
}

fn check_header(format: &str, version: u32) -> std::result::Result<(), String> {
    if format != FORMAT_NAME {
        return Err(format!(
            "format is \"{format}\", expected \"{FORMAT_NAME}\" (not a red demo file)"
        ));
    }
    if !(OLDEST_READABLE_VERSION..=FORMAT_VERSION).contains(&version) {
        return Err(format!(
            "unknown version {version}: this build reads versions \
             {OLDEST_READABLE_VERSION} to {FORMAT_VERSION}"
        ));
    }
    Ok(())
}

fn check_row(
    what: &str,
    row: &[f64],
    dim: usize,
    dim_name: &str,
) -> std::result::Result<(), String> {
    if row.len() != dim {
        return Err(format!(
            "{what} has {} numbers, {dim_name} is {dim}",
            row.len()
        ));
    }
    if let Some((j, v)) = row.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(format!("{what}[{j}] is {v}, not a finite number"));
    }
    if let Some((j, v)) = row
        .iter()
        .enumerate()
        .find(|(_, v)| v.abs() > MAX_ABS_VALUE)
    {
        return Err(too_large(&format!("{what}[{j}] (column {j})"), *v));
    }
    Ok(())
}

fn too_large(what: &str, v: f64) -> String {
    format!(
        "{what} is {v:e}, beyond the magnitude bound {MAX_ABS_VALUE:e} (the networks work in \
         f32, where its square would overflow); rescale the data"
    )
}

/// The header fields alone; every other field is skipped.
#[derive(Deserialize)]
struct Probe {
    format: Option<serde_json::Value>,
    version: Option<serde_json::Value>,
}

/// `v` rounded to `digits` (at least 1) significant digits.
fn round_significant(v: f64, digits: usize) -> f64 {
    if v == 0.0 || !v.is_finite() {
        return v;
    }
    format!("{v:.*e}", digits.saturating_sub(1))
        .parse()
        .unwrap_or(v)
}

impl Probe {
    fn check(&self) -> Result<()> {
        let format = match &self.format {
            None => {
                return Err(demo_err(
                    None,
                    None,
                    format!("no `format` field: not a {FORMAT_NAME} file"),
                ));
            }
            Some(serde_json::Value::String(s)) => s.as_str(),
            Some(other) => {
                return Err(demo_err(
                    None,
                    None,
                    format!("`format` is {other}, expected \"{FORMAT_NAME}\""),
                ));
            }
        };
        let version = match &self.version {
            None => return Err(demo_err(None, None, "no `version` field".into())),
            Some(v) => match v.as_u64().and_then(|v| u32::try_from(v).ok()) {
                Some(v) => v,
                None => {
                    return Err(demo_err(
                        None,
                        None,
                        format!(
                            "unknown version {v}: this build reads versions \
                             {OLDEST_READABLE_VERSION} to {FORMAT_VERSION}"
                        ),
                    ));
                }
            },
        };
        check_header(format, version).map_err(|r| demo_err(None, None, r))
    }
}

/// Turns a serde_json error into an [`Error::Demo`] with line, column, the
/// JSON path and, inside a trajectory, its index and step.
fn json_error(text: &str, e: &serde_json::Error) -> Error {
    use serde_json::error::Category;
    // serde_json reports `NaN` as "expected value" and `1e400` as "number
    // out of range"; a scan names the token instead, if it is what failed.
    if matches!(e.classify(), Category::Syntax | Category::Eof)
        && let Some(bad) = crate::json_loc::first_non_finite(text)
        && bad.offset <= crate::json_loc::offset_of(text, e.line(), e.column())
    {
        let (trajectory, step) = bad.path.trajectory_step();
        return demo_err(
            trajectory,
            step,
            format!(
                "line {} column {} ({}): {}",
                bad.line,
                bad.column,
                bad.path,
                bad.problem()
            ),
        );
    }
    let offset = crate::json_loc::offset_of(text, e.line(), e.column());
    let path = crate::json_loc::path_at(text, offset);
    let (trajectory, step) = path.trajectory_step();
    let message = e.to_string();
    let reason = match e.classify() {
        Category::Eof => format!(
            "the JSON ends early (truncated file?): {message}{}",
            path.describe_in()
        ),
        Category::Syntax => format!("invalid JSON: {message}{}", path.describe_in()),
        Category::Data if path.is_root() && message.contains("expected struct") => {
            format!("expected a JSON object with the {FORMAT_NAME} header: {message}")
        }
        Category::Data | Category::Io => format!("{message}{}", path.describe_in()),
    };
    demo_err(trajectory, step, reason)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_keeps_significant_digits() {
        assert_eq!(round_significant(123.456789, 6), 123.457);
        assert_eq!(round_significant(-0.000123456789, 3), -0.000123);
        assert_eq!(round_significant(0.0, 6), 0.0);
        assert!(round_significant(f64::NAN, 2).is_nan());
    }

    fn traj(rows: &[[f64; 3]]) -> Trajectory {
        Trajectory {
            observations: rows.iter().map(|r| r.to_vec()).collect(),
            actions: rows.iter().map(|_| vec![0.0]).collect(),
            rewards: None,
            end: EpisodeEnd::Truncated,
        }
    }

    #[test]
    fn context_dims_are_constant_within_each_trajectory_and_differ_between() {
        let mut d = Demos::new("x", 3, 1, None);
        // dim 0 moves, dim 1 is each episode's own constant, dim 2 is one
        // constant everywhere (not a context: nothing varies).
        d.trajectories
            .push(traj(&[[0.0, 0.3, 7.0], [1.0, 0.3, 7.0]]));
        assert!(d.context_dims().is_empty(), "one trajectory");
        d.trajectories
            .push(traj(&[[2.0, -0.1, 7.0], [0.5, -0.1, 7.0]]));
        assert_eq!(d.context_dims(), vec![1]);
        // a value that moves within one trajectory is behaviour
        d.trajectories
            .push(traj(&[[1.0, 0.2, 7.0], [1.5, 0.2 + 1e-6, 7.0]]));
        assert!(d.context_dims().is_empty());
        // rounding noise far below the tolerance does not
        d.trajectories.pop();
        d.trajectories
            .push(traj(&[[1.0, 0.2, 7.0], [1.5, 0.2 + 1e-12, 7.0]]));
        assert_eq!(d.context_dims(), vec![1]);
        // a one-step trajectory tells nothing, nor one without states
        d.trajectories.push(traj(&[[1.0, 0.5, 7.0]]));
        assert!(d.context_dims().is_empty());
        d.trajectories.pop();
        let mut bare = traj(&[[1.0, 0.5, 7.0], [1.0, 0.5, 7.0]]);
        bare.observations.clear();
        d.trajectories.push(bare);
        assert!(d.context_dims().is_empty());
    }

    #[test]
    fn the_time_feature_counts_steps_from_each_trajectory_start() {
        let mut d = Demos::new("x", 3, 1, None);
        d.trajectories
            .push(traj(&[[0.5, 1.0, 0.0], [0.6, 1.0, 0.0], [0.7, 1.0, 0.0]]));
        d.trajectories
            .push(traj(&[[-0.5, 2.0, 0.0], [-0.4, 2.0, 0.0]]));
        let t = d.clone().with_time_feature(4).unwrap();
        assert_eq!(t.obs_dim, 4);
        assert_eq!(t.trajectories[0].observations[2], vec![0.7, 1.0, 0.0, 0.5]);
        assert_eq!(t.trajectories[1].observations[0], vec![-0.5, 2.0, 0.0, 0.0]);
        assert_eq!(
            t.trajectories[1].observations[1],
            vec![-0.4, 2.0, 0.0, 0.25]
        );
        assert_eq!(t.pairs().0.ncols(), 4);
        // a trajectory longer than the limit cannot be from it
        let e = d.clone().with_time_feature(2).unwrap_err().to_string();
        assert!(e.contains("trajectory 0 has 3 steps"), "{e}");
        assert!(d.with_time_feature(0).is_err());
    }
}
