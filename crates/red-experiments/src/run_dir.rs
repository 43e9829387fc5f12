//! The run folder: where an experiment writes `config.json`, `metrics.csv`,
//! `eval.json`, its pictures and its checkpoint. Every file is written
//! atomically (a temporary file beside it, then a rename), so a run killed at
//! any moment leaves each file whole: the old one or the new one.

use std::path::{Path, PathBuf};

use crate::{Error, Result};

/// A run's folder.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RunDir {
    path: PathBuf,
}

impl RunDir {
    /// The folder `name` inside `out_dir`, created if missing. `name` must
    /// be a plain name: not empty, no path separator, not `.` or `..`, so
    /// the run always stays inside `out_dir`.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] for a name that is not plain, [`Error::Io`]
    /// if the folder cannot be created.
    pub fn create(out_dir: &Path, name: &str) -> Result<Self> {
        check_name(name)?;
        let path = out_dir.join(name);
        std::fs::create_dir_all(&path).map_err(|source| Error::Io {
            path: path.clone(),
            source,
        })?;
        Ok(Self { path })
    }

    /// An existing run folder (to resume it).
    ///
    /// # Errors
    /// [`Error::Input`] if `path` is not a folder.
    pub fn open(path: &Path) -> Result<Self> {
        if !path.is_dir() {
            return Err(Error::Input {
                path: path.to_path_buf(),
                reason: "not a run folder (no such directory)".into(),
            });
        }
        Ok(Self {
            path: path.to_path_buf(),
        })
    }

    /// The folder.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The path of `file` in the folder.
    pub fn file(&self, file: &str) -> PathBuf {
        self.path.join(file)
    }

    /// Writes `bytes` to `file` in the folder atomically.
    ///
    /// # Errors
    /// [`Error::Core`] with an I/O error naming the file.
    pub fn write(&self, file: &str, bytes: &[u8]) -> Result<()> {
        red_core::checkpoint::write_atomic(&self.file(file), bytes)?;
        Ok(())
    }

    /// Writes `value` as pretty JSON to `file` atomically.
    ///
    /// # Errors
    /// As [`RunDir::write`].
    pub fn write_json<T: serde::Serialize>(&self, file: &str, value: &T) -> Result<()> {
        let text = serde_json::to_string_pretty(value).map_err(|e| Error::Input {
            path: self.file(file),
            reason: format!("cannot serialise: {e}"),
        })?;
        self.write(file, text.as_bytes())
    }
}

/// Checks that a run name is a plain folder name.
///
/// # Errors
/// [`Error::InvalidConfig`] naming `name` and why.
pub fn check_name(name: &str) -> Result<()> {
    let bad = |reason: &str| {
        Err(Error::InvalidConfig {
            field: "name".into(),
            reason: format!("`{name}` {reason}; use a plain folder name such as `drive-1`"),
        })
    };
    if name.trim().is_empty() {
        return bad("is empty");
    }
    if name == "." || name == ".." {
        return bad("is not a folder name");
    }
    if name.contains('/') || name.contains('\\') || Path::new(name).is_absolute() {
        return bad("contains a path separator");
    }
    Ok(())
}

/// Where a picture being drawn goes before [`commit_partial`] renames it
/// over `path` (same folder, same extension, so the drawing library picks
/// the same format).
pub fn partial_path(path: &Path) -> PathBuf {
    let stem = path
        .file_stem()
        .map_or_else(|| "out".into(), |s| s.to_string_lossy().into_owned());
    let ext = path
        .extension()
        .map_or_else(String::new, |e| format!(".{}", e.to_string_lossy()));
    path.with_file_name(format!(".{stem}.partial-{}{ext}", std::process::id()))
}

/// Renames the finished `tmp` over `path`.
///
/// # Errors
/// [`Error::Io`] naming `path`; `tmp` is removed then.
pub fn commit_partial(tmp: &Path, path: &Path) -> Result<()> {
    std::fs::rename(tmp, path).map_err(|source| {
        let _ = std::fs::remove_file(tmp);
        Error::Io {
            path: path.to_path_buf(),
            source,
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_must_be_plain() {
        for bad in ["", " ", ".", "..", "../x", "a/b", "/abs"] {
            assert!(check_name(bad).is_err(), "{bad:?}");
        }
        for good in ["drive", "drive-1", "a.b"] {
            check_name(good).unwrap();
        }
    }

    #[test]
    fn writes_are_whole_and_named() {
        let dir = tempfile::tempdir().unwrap();
        let run = RunDir::create(dir.path(), "r").unwrap();
        run.write("a.txt", b"hello").unwrap();
        assert_eq!(std::fs::read(run.file("a.txt")).unwrap(), b"hello");
        run.write_json("b.json", &vec![1, 2]).unwrap();
        let left: Vec<_> = std::fs::read_dir(run.path()).unwrap().collect();
        assert_eq!(left.len(), 2, "no temporary file is left behind");
    }
}
