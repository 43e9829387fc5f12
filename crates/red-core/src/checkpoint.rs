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
pub const CHECKPOINT_VERSION: u32 = 1;

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
struct EnvelopeOut<'a, T> {
    format: &'a str,
    version: u32,
    kind: &'a str,
    state: &'a T,
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
    #[serde(borrow)]
    state: &'a serde_json::value::RawValue,
}

/// Saves `state` atomically as a checkpoint of a run of `kind` (e.g.
/// `"drive"`, `"mujoco-train"`).
///
/// # Errors
/// [`Error::Io`] when the file cannot be written; [`Error::InvalidConfig`]
/// when the state cannot be serialised (for instance a non-finite number in
/// a map key).
pub fn save_checkpoint<T: Serialize>(path: &Path, kind: &str, state: &T) -> Result<()> {
    let text = serde_json::to_string(&EnvelopeOut {
        format: CHECKPOINT_FORMAT,
        version: CHECKPOINT_VERSION,
        kind,
        state,
    })
    .map_err(|e| Error::InvalidConfig {
        field: "checkpoint".into(),
        reason: format!("{}: cannot serialise the run's state: {e}", path.display()),
    })?;
    write_atomic(path, text.as_bytes())
}

/// Loads a checkpoint written by [`save_checkpoint`] for a run of `kind`.
///
/// # Errors
/// [`Error::Io`] when the file cannot be read; [`Error::InvalidConfig`]
/// naming the file when it is not a checkpoint, has another version, holds
/// another kind of run, or its state does not parse.
pub fn load_checkpoint<T: DeserializeOwned>(path: &Path, kind: &str) -> Result<T> {
    let bytes = std::fs::read(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_checkpoint(&bytes, kind).map_err(|e| match e {
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
/// another version, hold another kind of run, or the state does not parse.
pub fn parse_checkpoint<T: DeserializeOwned>(bytes: &[u8], kind: &str) -> Result<T> {
    let bad = |reason: String| Error::InvalidConfig {
        field: "checkpoint".into(),
        reason,
    };
    let env: EnvelopeIn<'_> = serde_json::from_slice(bytes)
        .map_err(|e| bad(format!("not a readable checkpoint: {e}")))?;
    if env.format != CHECKPOINT_FORMAT {
        return Err(bad(format!(
            "format is `{}`, expected `{CHECKPOINT_FORMAT}`",
            env.format
        )));
    }
    if env.version != CHECKPOINT_VERSION {
        return Err(bad(format!(
            "checkpoint version {} is not supported (this build reads {CHECKPOINT_VERSION})",
            env.version
        )));
    }
    if env.kind != kind {
        return Err(bad(format!(
            "holds a `{}` run, not a `{kind}` run",
            env.kind
        )));
    }
    serde_json::from_str(env.state.get())
        .map_err(|e| bad(format!("the saved state does not parse: {e}")))
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
        let text = serde_json::json!({"format": "red-checkpoint", "version": 99, "kind": "toy", "state": [1.0, []]});
        std::fs::write(&p, text.to_string()).unwrap();
        let e = load_checkpoint::<(f64, Vec<bool>)>(&p, "toy").unwrap_err();
        assert!(e.to_string().contains("version 99"), "{e}");
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
