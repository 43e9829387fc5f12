//! Files that must survive a crash: atomic writes and versioned
//! checkpoints.
//!
//! A long run saves its state with [`save_checkpoint`] at a set interval.
//! The state goes to a temporary file in the same folder, is flushed to disk
//! and then renamed over the previous checkpoint, so a process killed at any
//! moment leaves either the old checkpoint or the new one, never half of
//! one. [`load_checkpoint`] checks the envelope (format name, version and
//! the kind of run) before it hands back the state.
//!
//! Since version 2 the envelope also holds the settings the run was made
//! with (`config`), their hash (`config_hash`) and a checksum of the exact
//! text of `config` and `state` (`checksum`, 64-bit FNV-1a): an edited or
//! damaged file that is still valid JSON is refused, and
//! [`load_checkpoint_for`] refuses a checkpoint made with other settings
//! than the caller's, naming the settings that differ. The checksum guards
//! against accidents (a stray edit, a bad copy), not against someone who
//! recomputes it. Version 1 files (no checksum) are still read.
//!
//! ```
//! use red_core::checkpoint::{load_checkpoint, save_checkpoint};
//! # let dir = tempfile::tempdir().unwrap();
//! let path = dir.path().join("checkpoint.json");
//! save_checkpoint(&path, "counter", &vec![1u32, 2, 3])?;
//! let back: Vec<u32> = load_checkpoint(&path, "counter")?;
//! assert_eq!(back, vec![1, 2, 3]);
//! // A checkpoint of another kind of run is refused with a clear message.
//! assert!(load_checkpoint::<Vec<u32>>(&path, "drive").is_err());
//! # Ok::<(), red_core::Error>(())
//! ```

use std::io::Write;
use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use crate::{Error, Result};

/// The format name written in every checkpoint.
pub const CHECKPOINT_FORMAT: &str = "red-checkpoint";
/// The checkpoint envelope's version.
pub const CHECKPOINT_VERSION: u32 = 2;
/// The oldest envelope version still read (version 1 has no checksum).
pub const OLDEST_CHECKPOINT_VERSION: u32 = 1;

/// The 64-bit FNV-1a hash of `parts`, a zero byte after each, as
/// `fnv1a64:<16 hex digits>` (the checkpoint's `checksum` and
/// `config_hash`).
pub fn checksum(parts: &[&[u8]]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for part in parts {
        for &b in part.iter().chain(std::iter::once(&0u8)) {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    }
    format!("fnv1a64:{h:016x}")
}

/// Skips a UTF-8 byte-order mark at the start of `bytes` (some editors on
/// Windows write one; JSON parsers refuse it).
pub fn strip_bom(bytes: &[u8]) -> &[u8] {
    bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes)
}

/// Writes `bytes` to a temporary file in `path`'s folder, syncs it and
/// renames it over `path`: readers see the old file or the new one, whole.
///
/// # Errors
/// [`Error::Io`] naming the file when it cannot be written or renamed.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let io = |p: &Path| {
        let p = p.to_path_buf();
        move |source| Error::Io { path: p, source }
    };
    let name = path
        .file_name()
        .ok_or_else(|| Error::Io {
            path: path.to_path_buf(),
            source: std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a file path"),
        })?
        .to_string_lossy();
    // Unique per process and per call, so concurrent writers never share
    // a temporary file.
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp: PathBuf = path.with_file_name(format!(".{name}.tmp-{}-{call}", std::process::id()));
    let result = std::fs::File::create(&tmp)
        .and_then(|mut f| {
            f.write_all(bytes)?;
            f.sync_all()
        })
        .map_err(io(&tmp))
        .and_then(|()| std::fs::rename(&tmp, path).map_err(io(path)));
    if result.is_err() {
        // Best effort: the temporary file is useless after a failure.
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

#[derive(Serialize)]
struct EnvelopeOut<'a> {
    format: &'a str,
    version: u32,
    kind: &'a str,
    checksum: String,
    config_hash: String,
    config: &'a serde_json::value::RawValue,
    state: &'a serde_json::value::RawValue,
}

/// The envelope as read: the state stays raw text until the header has
/// been checked, so a checkpoint of another kind or version is reported as
/// such rather than as a parse error of its state.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct EnvelopeIn<'a> {
    format: String,
    version: u32,
    kind: String,
    #[serde(default)]
    checksum: Option<String>,
    #[serde(default)]
    config_hash: Option<String>,
    #[serde(borrow, default)]
    config: Option<&'a serde_json::value::RawValue>,
    #[serde(borrow)]
    state: &'a serde_json::value::RawValue,
}

/// Saves `state` atomically as a checkpoint of a run of `kind` (e.g.
/// `"drive"`, `"mujoco-train"`) with no settings of its own (see
/// [`save_checkpoint_for`]).
///
/// # Errors
/// As [`save_checkpoint_for`].
pub fn save_checkpoint<T: Serialize>(path: &Path, kind: &str, state: &T) -> Result<()> {
    save_checkpoint_for(path, kind, &(), state)
}

/// Saves `state` atomically as a checkpoint of a run of `kind` made with
/// the settings `config`, with the checksum and the settings' hash.
///
/// # Errors
/// [`Error::Io`] when the file cannot be written; [`Error::InvalidConfig`]
/// when the state cannot be serialised (for instance a non-finite number in
/// a map key).
pub fn save_checkpoint_for<C: Serialize, T: Serialize>(
    path: &Path,
    kind: &str,
    config: &C,
    state: &T,
) -> Result<()> {
    let bad = |e: serde_json::Error| Error::InvalidConfig {
        field: "checkpoint".into(),
        reason: format!("{}: cannot serialise the run's state: {e}", path.display()),
    };
    let config = serde_json::value::to_raw_value(config).map_err(bad)?;
    let state = serde_json::value::to_raw_value(state).map_err(bad)?;
    let text = serde_json::to_string(&EnvelopeOut {
        format: CHECKPOINT_FORMAT,
        version: CHECKPOINT_VERSION,
        kind,
        checksum: checksum(&[config.get().as_bytes(), state.get().as_bytes()]),
        config_hash: checksum(&[config.get().as_bytes()]),
        config: &config,
        state: &state,
    })
    .map_err(bad)?;
    write_atomic(path, text.as_bytes())
}

/// Loads a checkpoint written by [`save_checkpoint`] or
/// [`save_checkpoint_for`] for a run of `kind`, without comparing its
/// settings with anything.
///
/// # Errors
/// As [`load_checkpoint_for`].
pub fn load_checkpoint<T: DeserializeOwned>(path: &Path, kind: &str) -> Result<T> {
    load_checkpoint_impl(path, kind, None)
}

/// Loads a checkpoint of a run of `kind` that must have been made with the
/// settings `config`.
///
/// # Errors
/// [`Error::Io`] when the file cannot be read; [`Error::InvalidConfig`]
/// naming the file when it is not a checkpoint, has another version, holds
/// another kind of run, fails its checksum, was made with other settings
/// (naming those that differ), or its state does not parse.
pub fn load_checkpoint_for<C: Serialize, T: DeserializeOwned>(
    path: &Path,
    kind: &str,
    config: &C,
) -> Result<T> {
    // Through text, as the saved settings were: `to_value` would widen an
    // f32 0.9 to 0.8999999761581421, its text reads back as 0.9.
    let expected: serde_json::Value = serde_json::to_string(config)
        .and_then(|t| serde_json::from_str(&t))
        .map_err(|e| Error::InvalidConfig {
            field: "checkpoint".into(),
            reason: format!("cannot serialise the settings to compare: {e}"),
        })?;
    load_checkpoint_impl(path, kind, Some(&expected))
}

fn load_checkpoint_impl<T: DeserializeOwned>(
    path: &Path,
    kind: &str,
    config: Option<&serde_json::Value>,
) -> Result<T> {
    let bytes = std::fs::read(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_checkpoint_impl(&bytes, kind, config).map_err(|e| match e {
        Error::InvalidConfig { field, reason } => Error::InvalidConfig {
            field,
            reason: format!("{}: {reason}", path.display()),
        },
        other => other,
    })
}

/// Parses the bytes of a checkpoint of a run of `kind` (what
/// [`load_checkpoint`] does after reading the file).
///
/// # Errors
/// [`Error::InvalidConfig`] when the bytes are not a checkpoint, have
/// another version, hold another kind of run, fail the checksum, or the
/// state does not parse.
pub fn parse_checkpoint<T: DeserializeOwned>(bytes: &[u8], kind: &str) -> Result<T> {
    parse_checkpoint_impl(bytes, kind, None)
}

fn parse_checkpoint_impl<T: DeserializeOwned>(
    bytes: &[u8],
    kind: &str,
    config: Option<&serde_json::Value>,
) -> Result<T> {
    let bad = |reason: String| Error::InvalidConfig {
        field: "checkpoint".into(),
        reason,
    };
    let env: EnvelopeIn<'_> = serde_json::from_slice(strip_bom(bytes))
        .map_err(|e| bad(format!("not a readable checkpoint: {e}")))?;
    if env.format != CHECKPOINT_FORMAT {
        return Err(bad(format!(
            "format is `{}`, expected `{CHECKPOINT_FORMAT}`",
            env.format
        )));
    }
    if !(OLDEST_CHECKPOINT_VERSION..=CHECKPOINT_VERSION).contains(&env.version) {
        return Err(bad(format!(
            "checkpoint version {} is not supported (this build reads \
             {OLDEST_CHECKPOINT_VERSION} to {CHECKPOINT_VERSION})",
            env.version
        )));
    }
    if env.kind != kind {
        return Err(bad(format!(
            "holds a `{}` run, not a `{kind}` run",
            env.kind
        )));
    }
    if env.version >= 2 {
        let (Some(sum), Some(config_hash)) = (&env.checksum, &env.config_hash) else {
            return Err(bad(
                "has no `checksum` or `config_hash`: the file was edited or damaged".into(),
            ));
        };
        // `null` settings come back as `None`.
        let saved = env.config.map_or("null", |c| c.get());
        let found = checksum(&[saved.as_bytes(), env.state.get().as_bytes()]);
        if *sum != found {
            return Err(bad(format!(
                "fails its checksum (saved {sum}, the contents give {found}): the file was \
                 edited or damaged after it was written; resume from an intact copy or start \
                 the run again"
            )));
        }
        if *config_hash != checksum(&[saved.as_bytes()]) {
            return Err(bad(
                "its `config_hash` does not match its `config`: the file was edited".into(),
            ));
        }
        if let Some(expected) = config {
            let saved: serde_json::Value = serde_json::from_str(saved)
                .map_err(|e| bad(format!("its `config` does not parse: {e}")))?;
            let mut diffs = Vec::new();
            diff_values("", &saved, expected, &mut diffs);
            if !diffs.is_empty() {
                return Err(bad(format!(
                    "was made with other settings than the run's: {}",
                    diffs.join("; ")
                )));
            }
        }
    } else if config.is_some() {
        return Err(bad(
            "is a version 1 checkpoint, which does not record its settings; finish it with \
             the build that wrote it or start the run again"
                .into(),
        ));
    }
    serde_json::from_str(env.state.get())
        .map_err(|e| bad(format!("the saved state does not parse: {e}")))
}

/// Collects up to 8 settings that differ, as `path: checkpoint X, now Y`.
fn diff_values(
    at: &str,
    saved: &serde_json::Value,
    now: &serde_json::Value,
    out: &mut Vec<String>,
) {
    use serde_json::Value;
    const MAX: usize = 8;
    if out.len() >= MAX || saved == now {
        return;
    }
    let join = |k: &str| {
        if at.is_empty() {
            k.to_string()
        } else {
            format!("{at}.{k}")
        }
    };
    match (saved, now) {
        (Value::Object(a), Value::Object(b)) => {
            let mut keys: Vec<&String> = a.keys().chain(b.keys()).collect();
            keys.sort();
            keys.dedup();
            for k in keys {
                let (x, y) = (
                    a.get(k).unwrap_or(&Value::Null),
                    b.get(k).unwrap_or(&Value::Null),
                );
                diff_values(&join(k), x, y, out);
            }
        }
        _ => {
            let short = |v: &Value| {
                let s = v.to_string();
                if s.chars().count() > 60 {
                    format!("{}...", s.chars().take(60).collect::<String>())
                } else {
                    s
                }
            };
            let name = if at.is_empty() { "settings" } else { at };
            out.push(format!(
                "{name}: checkpoint {}, now {}",
                short(saved),
                short(now)
            ));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_refusals() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.json");
        save_checkpoint(&p, "toy", &(1.5f64, vec![true, false])).unwrap();
        let back: (f64, Vec<bool>) = load_checkpoint(&p, "toy").unwrap();
        assert_eq!(back, (1.5, vec![true, false]));
        let e = load_checkpoint::<(f64, Vec<bool>)>(&p, "drive").unwrap_err();
        assert!(e.to_string().contains("not a `drive` run"), "{e}");
        std::fs::write(&p, b"{\"format\":\"red-checkpoint\",\"ver").unwrap();
        let e = load_checkpoint::<(f64, Vec<bool>)>(&p, "toy").unwrap_err();
        assert!(e.to_string().contains("c.json"), "{e}");
        let text = serde_json::json!({"format": "red-checkpoint", "version": 99, "checksum": "x", "config_hash": "x", "config": null, "kind": "toy", "state": [1.0, []]});
        std::fs::write(&p, text.to_string()).unwrap();
        let e = load_checkpoint::<(f64, Vec<bool>)>(&p, "toy").unwrap_err();
        assert!(e.to_string().contains("version 99"), "{e}");
    }

    #[test]
    fn edits_and_other_settings_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.json");
        #[derive(Serialize)]
        struct Settings {
            hidden: Vec<usize>,
            lr: f32,
        }
        let config = Settings {
            hidden: vec![100, 100],
            lr: 0.9,
        };
        save_checkpoint_for(&p, "toy", &config, &vec![1.25f64, 2.5]).unwrap();
        let back: Vec<f64> = load_checkpoint_for(&p, "toy", &config).unwrap();
        assert_eq!(back, vec![1.25, 2.5]);
        // One digit of the state changed: still valid JSON, refused.
        let text = std::fs::read_to_string(&p).unwrap();
        std::fs::write(&p, text.replace("2.5]", "2.6]")).unwrap();
        let e = load_checkpoint::<Vec<f64>>(&p, "toy").unwrap_err();
        assert!(e.to_string().contains("checksum"), "{e}");
        // Other settings: the differences are named.
        std::fs::write(&p, &text).unwrap();
        let other = Settings {
            hidden: vec![64, 100],
            lr: 0.9,
        };
        let e = load_checkpoint_for::<_, Vec<f64>>(&p, "toy", &other).unwrap_err();
        assert!(
            e.to_string()
                .contains("hidden: checkpoint [100,100], now [64,100]"),
            "{e}"
        );
        // A byte-order mark is skipped.
        std::fs::write(&p, format!("\u{feff}{text}")).unwrap();
        load_checkpoint_for::<_, Vec<f64>>(&p, "toy", &config).unwrap();
        // Version 1 (no checksum) is still read.
        let v1 = serde_json::json!({"format": "red-checkpoint", "version": 1, "kind": "toy", "state": [1.0]});
        std::fs::write(&p, v1.to_string()).unwrap();
        assert_eq!(load_checkpoint::<Vec<f64>>(&p, "toy").unwrap(), vec![1.0]);
    }

    #[test]
    fn atomic_write_leaves_no_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.json");
        write_atomic(&p, b"one").unwrap();
        write_atomic(&p, b"two").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 1, "{names:?}");
    }
}
