//! Importers for demonstration formats users already have.
//!
//! - [`read_red_pickle`]: the original RED release's pickled dict,
//!   `observations` `(N, obs)` float64 and `actions` `(N, 1, act)` float32
//!   numpy arrays, with trajectories of a fixed length (1000 steps, 50 for
//!   Reacher) concatenated.
//! - [`read_baselines_npz`]: OpenAI baselines' expert `.npz` (`obs`, `acs`,
//!   optional `rews`, `ep_rets`, `lens`).
//!
//! Both return validated [`Demos`] for the `env_id` the caller gives, with
//! `control_hz` unset (set it on the result if it matters). Pickles are
//! read by a small reader of their opcodes that rebuilds numpy arrays and
//! calls nothing else; no Python code runs, and malformed bytes give an
//! error naming the byte offset, never a panic.
//!
//! ```no_run
//! use red_core::import::{read_red_pickle, DEFAULT_RED_TRAJ_LEN};
//! let demos = read_red_pickle("hopper.pkl".as_ref(), "Hopper-v5", DEFAULT_RED_TRAJ_LEN)?;
//! println!("{}", demos.summary());
//! # Ok::<(), red_core::Error>(())
//! ```

mod npy;
mod pickle;
mod zip;

use std::path::Path;

use crate::{Demos, EpisodeEnd, Error, Result, Trajectory};

use npy::Npy;
use pickle::NdArray;

/// Steps per trajectory in the RED release's MuJoCo data (Reacher: 50,
/// see [`REACHER_RED_TRAJ_LEN`]).
pub const DEFAULT_RED_TRAJ_LEN: usize = 1000;

/// Steps per trajectory in the RED release's Reacher data.
pub const REACHER_RED_TRAJ_LEN: usize = 50;

/// The time limit of baselines' MuJoCo episodes: a trajectory of this
/// length was cut by it.
pub const DEFAULT_MAX_EPISODE_STEPS: usize = 1000;

/// The formats [`import_file`] reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImportFormat {
    /// The RED release's pickle ([`read_red_pickle`]).
    RedPickle,
    /// OpenAI baselines' expert `.npz` ([`read_baselines_npz`]).
    BaselinesNpz,
}

impl ImportFormat {
    /// Every format, in the order the CLI lists them.
    pub const ALL: [ImportFormat; 2] = [ImportFormat::RedPickle, ImportFormat::BaselinesNpz];

    /// The format's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ImportFormat::RedPickle => "red-pickle",
            ImportFormat::BaselinesNpz => "baselines-npz",
        }
    }
}

impl std::str::FromStr for ImportFormat {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        Self::ALL
            .into_iter()
            .find(|f| f.name() == s)
            .ok_or_else(|| Error::InvalidConfig {
                field: "from".into(),
                reason: format!(
                    "unknown format `{s}`; known: {}",
                    Self::ALL.map(ImportFormat::name).join(", ")
                ),
            })
    }
}

/// Reads `path` in `format` as demonstrations of `env_id`, marked as
/// imported ([`crate::DemoSource::Imported`]). `steps` is the trajectory
/// length of a RED pickle (default [`DEFAULT_RED_TRAJ_LEN`], or
/// [`REACHER_RED_TRAJ_LEN`] when `env_id` names Reacher) or the time
/// limit of a baselines `.npz` (default [`DEFAULT_MAX_EPISODE_STEPS`]).
///
/// # Errors
/// As [`read_red_pickle`] and [`read_baselines_npz`], with the file named.
pub fn import_file(
    format: ImportFormat,
    path: &Path,
    env_id: &str,
    steps: Option<usize>,
) -> Result<Demos> {
    let mut demos = match format {
        ImportFormat::RedPickle => {
            let reacher = env_id.to_ascii_lowercase().starts_with("reacher");
            let default = if reacher {
                REACHER_RED_TRAJ_LEN
            } else {
                DEFAULT_RED_TRAJ_LEN
            };
            read_red_pickle(path, env_id, steps.unwrap_or(default))?
        }
        ImportFormat::BaselinesNpz => {
            read_baselines_npz(path, env_id, steps.unwrap_or(DEFAULT_MAX_EPISODE_STEPS))?
        }
    };
    demos.source = Some(crate::DemoSource::Imported);
    Ok(demos)
}

fn err(path: Option<&Path>, trajectory: Option<usize>, reason: String) -> Error {
    Error::Demo {
        path: path.map(Path::to_path_buf),
        trajectory,
        step: None,
        reason,
    }
}

fn read_bytes(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Reads the RED release's pickled dict from `path`; see
/// [`red_pickle_from_bytes`].
///
/// # Errors
/// [`Error::Io`] if the file cannot be read; otherwise as
/// [`red_pickle_from_bytes`], with the file named.
pub fn read_red_pickle(path: &Path, env_id: &str, traj_len: usize) -> Result<Demos> {
    let bytes = read_bytes(path)?;
    red_pickle_from_bytes(&bytes, env_id, traj_len).map_err(|e| e.with_path(path))
}

/// Decodes the RED release's pickled dict (pickle protocols 2 to 5, numpy
/// 1 or 2): `observations` of shape `(N, obs_dim)` and `actions` of shape
/// `(N, 1, act_dim)` (or `(N, act_dim)`), any float or integer dtype,
/// converted to `f64`. The `N` rows are consecutive trajectories of
/// `traj_len` steps ([`DEFAULT_RED_TRAJ_LEN`], or
/// [`REACHER_RED_TRAJ_LEN`] for Reacher); each becomes a
/// [`Trajectory`] ending [`EpisodeEnd::Truncated`] (the release cut every
/// episode at its time limit) without rewards. Other keys are ignored.
///
/// # Errors
/// [`Error::Demo`] for bytes that are not such a pickle (with the byte
/// offset), a missing key, arrays of the wrong rank or of different
/// lengths, `N` = 0 or not a multiple of `traj_len`, `traj_len` = 0, or
/// data [`Demos::validate`] rejects (NaN, with trajectory and step).
pub fn red_pickle_from_bytes(bytes: &[u8], env_id: &str, traj_len: usize) -> Result<Demos> {
    let e = |r: String| err(None, None, r);
    if traj_len == 0 {
        return Err(e("trajectory length must be at least 1".into()));
    }
    let p = pickle::load(bytes).map_err(|pe| e(format!("not a readable pickle: {pe}")))?;
    let entries = p
        .dict_entries(p.root)
        .map_err(|r| e(format!("the pickle holds no dict of arrays: {r}")))?;
    let get = |key: &str| -> Result<NdArray> {
        let v = entries
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| *v)
            .ok_or_else(|| {
                let keys: Vec<&str> = entries.iter().map(|(k, _)| k.as_str()).collect();
                e(format!("the dict has no `{key}` (its keys: {keys:?})"))
            })?;
        p.array(v).map_err(|r| e(format!("`{key}`: {r}")))
    };
    let obs = get("observations")?;
    let acs = get("actions")?;
    let (n, obs_dim) = match obs.shape.as_slice() {
        [n, d] => (*n, *d),
        s => {
            return Err(e(format!(
                "`observations` has shape {s:?}, expected (N, obs_dim)"
            )));
        }
    };
    let act_dim = match acs.shape.as_slice() {
        [m, 1, d] | [m, d] if *m == n => *d,
        s => {
            return Err(e(format!(
                "`actions` has shape {s:?}, expected ({n}, 1, act_dim) or ({n}, act_dim) to match \
                 `observations` {:?}",
                obs.shape
            )));
        }
    };
    if n == 0 {
        return Err(e("`observations` has no rows".into()));
    }
    // Rows of no numbers would let a tiny file claim billions of steps.
    if obs_dim == 0 || act_dim == 0 {
        return Err(e(format!(
            "rows of no numbers: observations {:?}, actions {:?}",
            obs.shape, acs.shape
        )));
    }
    if n % traj_len != 0 {
        return Err(e(format!(
            "{n} rows are not a whole number of trajectories of {traj_len} steps \
             ({} full and {} left over); pass the right trajectory length (1000, or 50 for \
             Reacher)",
            n / traj_len,
            n % traj_len
        )));
    }
    let mut demos = Demos::new(env_id, obs_dim, act_dim, None);
    for t in 0..n / traj_len {
        let rows = t * traj_len..(t + 1) * traj_len;
        demos.trajectories.push(Trajectory {
            observations: rows_of(&obs.data, obs_dim, rows.clone()),
            actions: rows_of(&acs.data, act_dim, rows),
            rewards: None,
            end: EpisodeEnd::Truncated,
        });
    }
    demos.validate()?;
    Ok(demos)
}

fn rows_of(data: &[f64], dim: usize, rows: std::ops::Range<usize>) -> Vec<Vec<f64>> {
    rows.map(|r| data[r * dim..(r + 1) * dim].to_vec())
        .collect()
}

/// Reads OpenAI baselines' expert `.npz` from `path`; see
/// [`baselines_npz_from_bytes`].
///
/// # Errors
/// [`Error::Io`] if the file cannot be read; otherwise as
/// [`baselines_npz_from_bytes`], with the file named.
pub fn read_baselines_npz(path: &Path, env_id: &str, max_episode_steps: usize) -> Result<Demos> {
    let bytes = read_bytes(path)?;
    baselines_npz_from_bytes(&bytes, env_id, max_episode_steps).map_err(|e| e.with_path(path))
}

/// One array of the archive, as per-episode rows.
enum Arr {
    /// `(n_traj, T, ...)`: episodes of equal length.
    PerEpisode(NdArray),
    /// `(N, ...)`: all steps, episodes concatenated.
    Flat(NdArray),
    /// An object array of `n_traj` arrays `(T_i, ...)`.
    Ragged(Vec<NdArray>),
}

/// Decodes OpenAI baselines' expert `.npz` (stored or deflated zip of
/// `.npy` files): `obs` and `acs` (required), `rews`, `ep_rets` and `lens`
/// (optional). Three layouts are accepted, told apart by the rank of `obs`:
///
/// - per episode: `obs` `(n_traj, T, obs_dim)`, `acs` `(n_traj, T, act_dim)`
///   or `(n_traj, T)`, `rews` `(n_traj, T)` (baselines' released experts);
/// - flat: `obs` `(N, obs_dim)`, `acs` `(N, act_dim)` or `(N,)`, `rews`
///   `(N,)`, cut into episodes by `lens` if present, else into
///   `len(ep_rets)` episodes of equal length;
/// - ragged: object arrays of `n_traj` arrays `(T_i, obs_dim)` and so on.
///
/// A trajectory of `max_episode_steps` steps ends
/// [`EpisodeEnd::Truncated`], a shorter one [`EpisodeEnd::Terminated`].
/// When both `rews` and `ep_rets` are present, each episode's rewards must
/// sum to its `ep_rets` entry (to 1e-4 relative).
///
/// # Errors
/// [`Error::Demo`] for a file that is not a zip of `.npy` files (truncated,
/// corrupt, failing its CRC), a missing `obs` or `acs`, shapes that do not
/// agree (naming both), episodes that cannot be delimited, an episode
/// longer than `max_episode_steps`, returns that do not match the rewards,
/// or data [`Demos::validate`] rejects.
pub fn baselines_npz_from_bytes(
    bytes: &[u8],
    env_id: &str,
    max_episode_steps: usize,
) -> Result<Demos> {
    baselines_npz_with_layout(bytes, env_id, max_episode_steps).map(|(d, _)| d)
}

/// How the arrays of a baselines `.npz` were laid out (see
/// [`baselines_npz_from_bytes`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NpzLayout {
    /// `obs` `(n_traj, T, obs_dim)`: episodes of equal length.
    PerEpisode,
    /// `obs` `(N, obs_dim)`, cut into episodes by `lens`.
    FlatByLens,
    /// `obs` `(N, obs_dim)`, cut into `len(ep_rets)` episodes of equal
    /// length (an assumption: the file does not say where episodes end).
    FlatByEpisodeCount,
    /// Object arrays of one `(T_i, obs_dim)` array per episode.
    Ragged,
}

impl std::fmt::Display for NpzLayout {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            NpzLayout::PerEpisode => "per episode: obs (n_traj, T, obs_dim)",
            NpzLayout::FlatByLens => "flat: obs (N, obs_dim) cut by `lens`",
            NpzLayout::FlatByEpisodeCount => {
                "flat: obs (N, obs_dim) cut into len(ep_rets) equal episodes (assumed)"
            }
            NpzLayout::Ragged => "ragged: object arrays of (T_i, obs_dim) episodes",
        })
    }
}

/// Reads a baselines `.npz` from `path` and says which layout it had.
///
/// # Errors
/// As [`read_baselines_npz`].
pub fn read_baselines_npz_with_layout(
    path: &Path,
    env_id: &str,
    max_episode_steps: usize,
) -> Result<(Demos, NpzLayout)> {
    let bytes = read_bytes(path)?;
    baselines_npz_with_layout(&bytes, env_id, max_episode_steps).map_err(|e| e.with_path(path))
}

/// [`baselines_npz_from_bytes`], also saying which layout the file had.
///
/// # Errors
/// As [`baselines_npz_from_bytes`].
pub fn baselines_npz_with_layout(
    bytes: &[u8],
    env_id: &str,
    max_episode_steps: usize,
) -> Result<(Demos, NpzLayout)> {
    let e = |r: String| err(None, None, r);
    let entries = zip::read_entries(bytes).map_err(|r| e(format!("not a readable .npz: {r}")))?;
    let mut arrays: Vec<(String, Npy)> = Vec::new();
    for ent in &entries {
        let key = ent
            .name
            .strip_suffix(".npy")
            .unwrap_or(&ent.name)
            .to_string();
        let a = npy::parse(&ent.data).map_err(|r| e(format!("`{}`: {r}", ent.name)))?;
        arrays.push((key, a));
    }
    let take =
        |key: &str| -> Option<&Npy> { arrays.iter().find(|(k, _)| k == key).map(|(_, v)| v) };
    let need = |key: &str| -> Result<&Npy> {
        take(key).ok_or_else(|| {
            let keys: Vec<&str> = arrays.iter().map(|(k, _)| k.as_str()).collect();
            e(format!("the archive has no `{key}` (its arrays: {keys:?})"))
        })
    };
    let obs = need("obs")?;
    let acs = need("acs")?;

    // Episode lengths and per-episode arrays.
    let lens_hint: Option<Vec<usize>> = match take("lens") {
        Some(Npy::Numeric(a)) => Some(
            a.data
                .iter()
                .map(|&v| {
                    if v >= 0.0 && v.fract() == 0.0 && v <= usize::MAX as f64 {
                        Ok(v as usize)
                    } else {
                        Err(e(format!("`lens` holds {v}, not an episode length")))
                    }
                })
                .collect::<Result<_>>()?,
        ),
        _ => None,
    };
    let ep_rets: Option<Vec<f64>> = match take("ep_rets") {
        Some(Npy::Numeric(a)) => Some(a.data.clone()),
        Some(Npy::Objects { .. }) => return Err(e("`ep_rets` is an object array".into())),
        None => None,
    };
    let classify = |name: &str, a: &Npy, per_step_rank: usize| -> Result<Arr> {
        match a {
            Npy::Numeric(x) if x.shape.len() == per_step_rank + 1 => Ok(Arr::PerEpisode(x.clone())),
            Npy::Numeric(x) if x.shape.len() == per_step_rank => Ok(Arr::Flat(x.clone())),
            Npy::Numeric(x) => Err(e(format!(
                "`{name}` has shape {:?}, expected rank {} (per episode) or {} (flat)",
                x.shape,
                per_step_rank + 1,
                per_step_rank
            ))),
            Npy::Objects { items, .. } => Ok(Arr::Ragged(items.clone())),
        }
    };
    let obs = classify("obs", obs, 2)?;
    // Rows of no numbers would let a tiny file claim billions of steps.
    let empty_rows = match &obs {
        Arr::PerEpisode(a) | Arr::Flat(a) => a.shape.last() == Some(&0),
        Arr::Ragged(items) => items.iter().any(|it| it.shape.get(1) == Some(&0)),
    };
    if empty_rows {
        return Err(e("`obs` has rows of 0 numbers".into()));
    }
    let layout = match obs {
        Arr::PerEpisode(_) => NpzLayout::PerEpisode,
        Arr::Ragged(_) => NpzLayout::Ragged,
        Arr::Flat(_) if lens_hint.is_some() => NpzLayout::FlatByLens,
        Arr::Flat(_) => NpzLayout::FlatByEpisodeCount,
    };
    let (obs_dim, lengths) = match &obs {
        Arr::PerEpisode(a) => (a.shape[2], vec![a.shape[1]; a.shape[0]]),
        Arr::Ragged(items) => {
            let mut dim = None;
            let mut lengths = Vec::new();
            for (i, it) in items.iter().enumerate() {
                match (it.shape.as_slice(), dim) {
                    ([t, d], None) => {
                        dim = Some(*d);
                        lengths.push(*t);
                    }
                    ([t, d], Some(d0)) if *d == d0 => lengths.push(*t),
                    (s, _) => {
                        return Err(err(
                            None,
                            Some(i),
                            format!(
                                "`obs` item {i} has shape {s:?}, expected (T, {})",
                                dim.map_or("obs_dim".to_string(), |d| d.to_string())
                            ),
                        ));
                    }
                }
            }
            (dim.unwrap_or(0), lengths)
        }
        Arr::Flat(a) => {
            let n = a.shape[0];
            let lengths = match (&lens_hint, &ep_rets) {
                (Some(l), _) => {
                    let total = l.iter().try_fold(0usize, |acc, &t| acc.checked_add(t));
                    if total != Some(n) {
                        return Err(e(format!(
                            "`lens` {l:?} does not add up to the {n} rows of flat `obs`"
                        )));
                    }
                    l.clone()
                }
                (None, Some(r)) if !r.is_empty() && n % r.len() == 0 => vec![n / r.len(); r.len()],
                (None, Some(r)) => {
                    return Err(e(format!(
                        "flat `obs` of {n} rows cannot be cut into {} episodes (`ep_rets`) of \
                         equal length, and there is no `lens`",
                        r.len()
                    )));
                }
                (None, None) => {
                    return Err(e(format!(
                        "flat `obs` of {n} rows and neither `lens` nor `ep_rets` to tell \
                         where episodes end"
                    )));
                }
            };
            (a.shape[1], lengths)
        }
    };
    if lengths.is_empty() {
        return Err(e("`obs` holds no episodes".into()));
    }

    let obs_rows = episode_rows("obs", &obs, &lengths, Some(obs_dim))?;
    let (acs_arr, act_dim) = like_obs("acs", acs, &obs)?;
    if act_dim == 0 {
        return Err(e("`acs` has rows of 0 numbers".into()));
    }
    let acs_rows = episode_rows("acs", &acs_arr, &lengths, Some(act_dim))?;
    let rews_rows = match take("rews") {
        None => None,
        Some(r) => {
            let (rews, _) = like_obs("rews", r, &obs)?;
            Some(episode_rows("rews", &rews, &lengths, Some(1))?)
        }
    };

    let mut demos = Demos::new(env_id, obs_dim, act_dim, None);
    for (i, (observations, actions)) in obs_rows.into_iter().zip(acs_rows).enumerate() {
        let t = actions.len();
        if t > max_episode_steps {
            return Err(err(
                None,
                Some(i),
                format!(
                    "episode of {t} steps is longer than the time limit of {max_episode_steps} \
                 given to the importer"
                ),
            ));
        }
        let rewards: Option<Vec<f64>> = rews_rows
            .as_ref()
            .map(|r| r[i].iter().map(|row| row[0]).collect());
        if let (Some(r), Some(rets)) = (&rewards, &ep_rets) {
            let want = *rets.get(i).ok_or_else(|| {
                e(format!(
                    "`ep_rets` has {} entries for {} episodes",
                    rets.len(),
                    lengths.len()
                ))
            })?;
            let sum: f64 = r.iter().sum();
            let scale: f64 = r.iter().map(|v| v.abs()).sum::<f64>().max(1.0);
            if (sum - want).abs() > 1e-4 * scale {
                return Err(err(
                    None,
                    Some(i),
                    format!("`rews` sum to {sum} but `ep_rets` says {want}"),
                ));
            }
        }
        demos.trajectories.push(Trajectory {
            observations,
            actions,
            rewards,
            end: if t == max_episode_steps {
                EpisodeEnd::Truncated
            } else {
                EpisodeEnd::Terminated
            },
        });
    }
    demos.validate()?;
    Ok((demos, layout))
}

/// Reads `a` in the layout of `obs`, with the length of its rows (1 when
/// the array has no dimension for them, as `acs` `(n_traj, T)` or `rews`).
fn like_obs(name: &str, a: &Npy, obs: &Arr) -> Result<(Arr, usize)> {
    let last_or_1 = |shape: &[usize], rank_with_dim: usize| {
        if shape.len() == rank_with_dim {
            shape[rank_with_dim - 1]
        } else {
            1
        }
    };
    let bad = |x: &NdArray, want: &str| {
        err(
            None,
            None,
            format!(
                "`{name}` has shape {:?}, expected {want} like `obs`",
                x.shape
            ),
        )
    };
    match (a, obs) {
        (Npy::Objects { items, .. }, _) => {
            let d = items.first().map_or(1, |it| last_or_1(&it.shape, 2));
            Ok((Arr::Ragged(items.clone()), d))
        }
        (Npy::Numeric(x), Arr::PerEpisode(_)) => match x.shape.len() {
            2 | 3 => Ok((Arr::PerEpisode(x.clone()), last_or_1(&x.shape, 3))),
            _ => Err(bad(x, "(n_traj, T, dim) or (n_traj, T)")),
        },
        (Npy::Numeric(x), Arr::Flat(_) | Arr::Ragged(_)) => match x.shape.len() {
            1 | 2 => Ok((Arr::Flat(x.clone()), last_or_1(&x.shape, 2))),
            _ => Err(bad(x, "(N, dim) or (N,)")),
        },
    }
}

/// Splits an array into per-episode rows of `dim` numbers, checking its
/// shape against the episode `lengths`.
fn episode_rows(
    name: &str,
    a: &Arr,
    lengths: &[usize],
    dim: Option<usize>,
) -> Result<Vec<Vec<Vec<f64>>>> {
    let e = |trajectory: Option<usize>, r: String| err(None, trajectory, r);
    let n_traj = lengths.len();
    let row_dim = |shape: &[usize], rank_with_dim: usize| -> usize {
        if shape.len() == rank_with_dim {
            shape[shape.len() - 1]
        } else {
            1
        }
    };
    let dim_ok = |d: usize| dim.is_none_or(|want| want == d);
    match a {
        Arr::PerEpisode(x) => {
            let d = row_dim(&x.shape, 3);
            if x.shape[0] != n_traj || lengths.iter().any(|&t| t != x.shape[1]) || !dim_ok(d) {
                return Err(e(
                    None,
                    format!(
                        "`{name}` has shape {:?}, which does not match {n_traj} episodes of {} steps",
                        x.shape, lengths[0]
                    ),
                ));
            }
            let t = x.shape[1];
            Ok((0..n_traj)
                .map(|i| rows_of(&x.data, d, i * t..(i + 1) * t))
                .collect())
        }
        Arr::Flat(x) => {
            let d = row_dim(&x.shape, 2);
            let total: usize = lengths.iter().sum();
            if x.shape[0] != total || !dim_ok(d) {
                return Err(e(
                    None,
                    format!(
                        "`{name}` has shape {:?}, which does not match {total} steps in {n_traj} episodes",
                        x.shape
                    ),
                ));
            }
            let mut start = 0;
            Ok(lengths
                .iter()
                .map(|&t| {
                    let r = rows_of(&x.data, d, start..start + t);
                    start += t;
                    r
                })
                .collect())
        }
        Arr::Ragged(items) => {
            if items.len() != n_traj {
                return Err(e(
                    None,
                    format!("`{name}` holds {} episodes, `obs` {n_traj}", items.len()),
                ));
            }
            items
                .iter()
                .zip(lengths)
                .enumerate()
                .map(|(i, (it, &t))| {
                    let d = row_dim(&it.shape, 2);
                    if it.shape.first() != Some(&t) || it.shape.len() > 2 || !dim_ok(d) {
                        return Err(e(
                            Some(i),
                            format!(
                                "`{name}` item {i} has shape {:?}, expected {t} steps",
                                it.shape
                            ),
                        ));
                    }
                    Ok(rows_of(&it.data, d, 0..t))
                })
                .collect()
        }
    }
}
