//! The run folder: where an experiment writes `config.json`, `metrics.csv`,
//! `eval.json`, its pictures and its checkpoint.
//!
//! - A run's name is a plain folder name, so the run stays inside the
//!   folder of runs ([`check_name`]).
//! - A new run refuses a folder that already holds files (they belong to
//!   another run): the user continues that run (`--resume`) or starts over
//!   with [`Existing::MoveAside`] (`--force`), which renames the old folder
//!   to `<name>.old-<k>` first, so files of two runs never mix.
//! - A lock file (`run.lock`: the process id, the host's name and, under
//!   SLURM, the job's array task) is held for the life of the [`RunDir`]: a
//!   second run on the same folder is refused with the holder's pid and
//!   host; the lock of a process of this host that is no longer running is
//!   taken over, with a note ([`RunDir::notes`]), and so is the lock of the
//!   same SLURM task on another host (a requeued task starts again only
//!   after its earlier run ended). A lock of another host is otherwise
//!   refused: its process cannot be checked from here.
//! - Every file is written atomically (a temporary file beside it, then a
//!   rename), so a run killed at any moment leaves each file whole: the old
//!   one or the new one. A write that fails names the file and says what
//!   survives and how to finish ([`Error::Write`]).

use std::io::Write as _;
use std::path::{Path, PathBuf};

use crate::{Error, Result};

/// The lock file of a run folder.
pub const LOCK_FILE: &str = "run.lock";

/// What a new run does with a folder that already holds files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Existing {
    /// Refuse it, naming `--resume` and `--force` (the default).
    #[default]
    Refuse,
    /// Rename it to `<name>.old-<k>` (the first free `k`) and start an
    /// empty folder.
    MoveAside,
}

impl Existing {
    /// [`Existing::MoveAside`] when `force`, else [`Existing::Refuse`].
    pub fn from_force(force: bool) -> Self {
        if force { Self::MoveAside } else { Self::Refuse }
    }
}

impl From<bool> for Existing {
    /// The command line's `--force`: see [`Existing::from_force`].
    fn from(force: bool) -> Self {
        Self::from_force(force)
    }
}

/// A run's folder, locked for as long as this value lives.
#[derive(Debug)]
pub struct RunDir {
    path: PathBuf,
    notes: Vec<String>,
    lock: Option<RunLock>,
    /// Whether this value made the folder (then an empty folder is removed
    /// when it is dropped: a run refused before writing leaves nothing).
    created: bool,
}

impl Drop for RunDir {
    fn drop(&mut self) {
        drop(self.lock.take());
        if self.created {
            // Fails, harmlessly, unless the folder is empty.
            let _ = std::fs::remove_dir(&self.path);
        }
    }
}

impl RunDir {
    /// A new run's folder `name` inside `out_dir`; a folder that already
    /// holds files is refused (see [`RunDir::create_with`]).
    ///
    /// # Errors
    /// As [`RunDir::create_with`].
    pub fn create(out_dir: &Path, name: &str) -> Result<Self> {
        Self::create_with(out_dir, name, Existing::Refuse)
    }

    /// A new run's folder `name` inside `out_dir`, created if missing and
    /// locked. `name` must be a plain name ([`check_name`]). A folder that
    /// already holds files is refused or moved aside, as `existing` says;
    /// one locked by a running process is always refused.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] for a name that is not plain,
    /// [`Error::Input`] for a folder that holds a run or is in use,
    /// [`Error::Io`] if the folder cannot be created or moved.
    pub fn create_with(out_dir: &Path, name: &str, existing: Existing) -> Result<Self> {
        check_name(name)?;
        Self::new_at(&out_dir.join(name), existing)
    }

    /// A new run's folder at `path` (a cell of a grid, a folder the caller
    /// named), as [`RunDir::create_with`] without the name check.
    ///
    /// # Errors
    /// As [`RunDir::create_with`].
    pub fn new_at(path: &Path, existing: Existing) -> Result<Self> {
        let mut notes = Vec::new();
        let mut created = !path.exists();
        if path.exists() {
            if !path.is_dir() {
                return Err(Error::Input {
                    path: path.to_path_buf(),
                    reason: "exists and is not a folder; choose another --name".into(),
                });
            }
            refuse_if_locked(path)?;
            if holds_files(path)? {
                match existing {
                    Existing::Refuse => {
                        return Err(Error::Input {
                            path: path.to_path_buf(),
                            reason: format!(
                                "already holds a run; continue it with --resume {0}, or start \
                                 over with --force (the old folder is moved aside to {0}.old-N, \
                                 never mixed with the new run), or choose another --name",
                                path.display()
                            ),
                        });
                    }
                    Existing::MoveAside => {
                        let aside = aside_path(path);
                        std::fs::rename(path, &aside).map_err(|source| Error::Io {
                            path: path.to_path_buf(),
                            source,
                        })?;
                        notes.push(format!(
                            "--force: the old {} was moved aside to {}",
                            path.display(),
                            aside.display()
                        ));
                        created = true;
                    }
                }
            }
        }
        std::fs::create_dir_all(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let (lock, note) = RunLock::acquire(path)?;
        notes.extend(note);
        Ok(Self {
            path: path.to_path_buf(),
            notes,
            lock: Some(lock),
            created,
        })
    }

    /// An existing run folder, to resume it; locked.
    ///
    /// # Errors
    /// [`Error::Input`] if `path` is not a folder or another running
    /// process holds its lock.
    pub fn open(path: &Path) -> Result<Self> {
        if !path.is_dir() {
            return Err(Error::Input {
                path: path.to_path_buf(),
                reason: format!(
                    "not a run folder (no such directory, so no {CHECKPOINT} to resume from)"
                ),
            });
        }
        let (lock, note) = RunLock::acquire(path)?;
        Ok(Self {
            path: path.to_path_buf(),
            notes: note.into_iter().collect(),
            lock: Some(lock),
            created: false,
        })
    }

    /// What happened while the folder was prepared (an old folder moved
    /// aside, a stale lock taken over), for the user to read.
    pub fn notes(&self) -> &[String] {
        &self.notes
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
    /// [`Error::Write`] naming the file, what survives and how to finish.
    pub fn write(&self, file: &str, bytes: &[u8]) -> Result<()> {
        red_core::checkpoint::write_atomic(&self.file(file), bytes)
            .map_err(|e| self.write_error(file, e))
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

    /// Saves the run's checkpoint (`checkpoint.json`) atomically with
    /// [`red_core::checkpoint::save_checkpoint_for`].
    ///
    /// # Errors
    /// As [`RunDir::write`].
    pub fn save_checkpoint<C: serde::Serialize, T: serde::Serialize>(
        &self,
        kind: &str,
        config: &C,
        state: &T,
    ) -> Result<()> {
        red_core::checkpoint::save_checkpoint_for(&self.file(CHECKPOINT), kind, config, state)
            .map_err(|e| self.write_error(CHECKPOINT, e))
    }

    /// A failed write of `file`, with what survives and how to finish.
    fn write_error(&self, file: &str, e: red_core::Error) -> Error {
        let survives = if file == CHECKPOINT {
            format!(
                "the previous {CHECKPOINT} (if any) is untouched; make room and continue \
                 from it with --resume {}",
                self.path.display()
            )
        } else {
            format!(
                "{file} was left as it was (no partial file); the files written before it \
                 are whole and {CHECKPOINT} keeps the run: make room and finish it with \
                 --resume {}",
                self.path.display()
            )
        };
        let reason = match e {
            red_core::Error::Io { source, .. } => source.to_string(),
            other => other.to_string(),
        };
        Error::Write {
            path: self.file(file),
            reason,
            survives,
        }
    }
}

/// The checkpoint's file name in a run folder.
pub const CHECKPOINT: &str = "checkpoint.json";

/// `out_dir/name` after checking that `name` is plain ([`check_name`]).
///
/// # Errors
/// As [`check_name`].
pub fn path_in(out_dir: &Path, name: &str) -> Result<PathBuf> {
    check_name(name)?;
    Ok(out_dir.join(name))
}

/// Whether `dir` holds anything but a lock file.
fn holds_files(dir: &Path) -> Result<bool> {
    let io = |source| Error::Io {
        path: dir.to_path_buf(),
        source,
    };
    for entry in std::fs::read_dir(dir).map_err(io)? {
        if entry.map_err(io)?.file_name() != LOCK_FILE {
            return Ok(true);
        }
    }
    Ok(false)
}

/// The first free `<path>.old-<k>`, k = 1, 2, ...
fn aside_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map_or_else(|| "run".into(), |n| n.to_string_lossy().into_owned());
    (1..)
        .map(|k| path.with_file_name(format!("{name}.old-{k}")))
        .find(|p| !p.exists())
        .unwrap_or_else(|| path.with_file_name(format!("{name}.old")))
}

/// Refuses `dir` if a running process holds its lock.
fn refuse_if_locked(dir: &Path) -> Result<()> {
    match read_lock(&dir.join(LOCK_FILE)) {
        Some(h) if h.may_run() => Err(in_use(dir, &h)),
        _ => Ok(()),
    }
}

fn in_use(dir: &Path, holder: &Holder) -> Error {
    let lock = dir.join(LOCK_FILE);
    let reason = match &holder.host {
        Some(host) if *host != this_host() => format!(
            "is in use by another run (process {} on host {host}, lock file {}); a process of \
             another host cannot be checked from here: if no run of this folder is going on \
             there, delete the lock file, or choose another --name",
            holder.pid,
            lock.display()
        ),
        _ => format!(
            "is in use by another run (process {}, lock file {}); wait for it to end or stop \
             it, or choose another --name",
            holder.pid,
            lock.display()
        ),
    };
    Error::Input {
        path: dir.to_path_buf(),
        reason,
    }
}

/// Who holds a lock: the first line of the file is the pid (the only line
/// in locks written before the host was recorded), then `host=` and, under
/// SLURM, `slurm=` lines.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Holder {
    pid: u32,
    host: Option<String>,
    slurm: Option<String>,
}

impl Holder {
    /// This process.
    fn me() -> Self {
        Self {
            pid: std::process::id(),
            host: Some(this_host()),
            slurm: slurm_task(),
        }
    }

    fn contents(&self) -> String {
        let mut s = format!("{}\n", self.pid);
        if let Some(h) = &self.host {
            s.push_str(&format!("host={h}\n"));
        }
        if let Some(t) = &self.slurm {
            s.push_str(&format!("slurm={t}\n"));
        }
        s
    }

    fn parse(text: &str) -> Option<Self> {
        let mut lines = text.lines();
        let pid = lines.next()?.trim().parse().ok()?;
        let (mut host, mut slurm) = (None, None);
        for line in lines {
            if let Some(h) = line.strip_prefix("host=") {
                host = Some(h.trim().to_string());
            } else if let Some(t) = line.strip_prefix("slurm=") {
                slurm = Some(t.trim().to_string());
            }
        }
        Some(Self { pid, host, slurm })
    }

    /// Whether the holder may still be running: on this host (or in a lock
    /// that names no host) its pid is checked; on another host it is taken
    /// as running unless it is this same SLURM task (requeued) or a SLURM
    /// task that `squeue` no longer lists.
    fn may_run(&self) -> bool {
        match &self.host {
            Some(h) if *h != this_host() => match &self.slurm {
                Some(task) if Some(task) == slurm_task().as_ref() => false,
                Some(task) => slurm_task_queued(task),
                None => true,
            },
            _ => pid_alive(self.pid),
        }
    }
}

/// The host's name (Linux: the kernel's; else `HOSTNAME`, else `unknown`).
fn this_host() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .or_else(|| std::env::var("HOSTNAME").ok())
        .map(|h| h.trim().to_string())
        .filter(|h| !h.is_empty())
        .unwrap_or_else(|| "unknown".into())
}

/// This process's SLURM task: `<array job>_<array task>` in a job array,
/// else `<job>`; `None` outside SLURM.
fn slurm_task() -> Option<String> {
    let var = |k: &str| std::env::var(k).ok().filter(|v| !v.is_empty());
    match (var("SLURM_ARRAY_JOB_ID"), var("SLURM_ARRAY_TASK_ID")) {
        (Some(j), Some(t)) => Some(format!("{j}_{t}")),
        _ => var("SLURM_JOB_ID"),
    }
}

/// Whether SLURM still lists `task` (`squeue -h -j <task>` prints a line);
/// `true` when `squeue` cannot say (not installed, an error).
fn slurm_task_queued(task: &str) -> bool {
    match std::process::Command::new("squeue")
        .args(["-h", "-j", task])
        .stderr(std::process::Stdio::null())
        .output()
    {
        Ok(out) if out.status.success() => out.stdout.iter().any(|b| !b.is_ascii_whitespace()),
        _ => true,
    }
}

/// The holder of a lock file, if it names one.
fn read_lock(path: &Path) -> Option<Holder> {
    Holder::parse(&std::fs::read_to_string(path).ok()?)
}

/// Whether process `pid` is running (on Linux: `/proc/<pid>` exists and is
/// not a zombie; elsewhere every pid is taken as running, so a lock is
/// never taken over there).
fn pid_alive(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    if cfg!(target_os = "linux") {
        match std::fs::read_to_string(format!("/proc/{pid}/stat")) {
            // The state follows the command name in parentheses.
            Ok(stat) => stat
                .rsplit_once(')')
                .and_then(|(_, rest)| rest.trim_start().chars().next())
                .is_none_or(|state| state != 'Z' && state != 'X'),
            Err(_) => false,
        }
    } else {
        true
    }
}

/// The held lock of a run folder; dropping it removes the lock file.
#[derive(Debug)]
struct RunLock {
    path: PathBuf,
}

impl RunLock {
    /// Takes `dir`'s lock: the file is made whole beside it and hard-linked
    /// into place, which fails if a lock exists, so a reader never sees an
    /// empty lock. A lock whose process is gone is taken over (the note
    /// says so).
    fn acquire(dir: &Path) -> Result<(Self, Option<String>)> {
        let path = dir.join(LOCK_FILE);
        let me = Holder::me();
        let tmp = dir.join(format!(".{LOCK_FILE}.{}", me.pid));
        let io = |p: &Path| {
            let p = p.to_path_buf();
            move |source| Error::Io { path: p, source }
        };
        std::fs::File::create(&tmp)
            .and_then(|mut f| f.write_all(me.contents().as_bytes()))
            .map_err(io(&tmp))?;
        let mut note = None;
        let result = loop {
            match std::fs::hard_link(&tmp, &path) {
                Ok(()) => break Ok(Self { path: path.clone() }),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && note.is_none() => {
                    let holder = read_lock(&path);
                    match holder {
                        Some(h) if h.may_run() => break Err(in_use(dir, &h)),
                        Some(h) => {
                            let why = match (&h.host, &h.slurm) {
                                (Some(host), Some(task)) if *host != this_host() => format!(
                                    "on host {host}, SLURM task {task}, which is this task \
                                     requeued or no longer in SLURM's queue"
                                ),
                                _ => "which is no longer running".into(),
                            };
                            note = Some(format!(
                                "took over the lock {} of process {}, {why}",
                                path.display(),
                                h.pid
                            ));
                        }
                        None => {
                            note = Some(format!(
                                "took over the lock {}, which names no process",
                                path.display()
                            ));
                        }
                    }
                    let _ = std::fs::remove_file(&path);
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    // Another process took it between our removal and
                    // our link.
                    let holder = read_lock(&path).unwrap_or(Holder {
                        pid: 0,
                        host: None,
                        slurm: None,
                    });
                    break Err(in_use(dir, &holder));
                }
                Err(source) => {
                    break Err(Error::Io {
                        path: path.clone(),
                        source,
                    });
                }
            }
        };
        let _ = std::fs::remove_file(&tmp);
        result.map(|lock| (lock, note))
    }
}

impl Drop for RunLock {
    fn drop(&mut self) {
        // Only our own lock: never one another process took over.
        if read_lock(&self.path)
            .is_some_and(|h| h.pid == std::process::id() && h.host == Some(this_host()))
        {
            let _ = std::fs::remove_file(&self.path);
        }
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

/// The JSON text `text`, read from `path`, as a `T`; a UTF-8 byte-order
/// mark (as some Windows editors write) is skipped.
///
/// # Errors
/// [`Error::Input`] naming `path` when the text is not a `T`.
pub fn parse_json<T: serde::de::DeserializeOwned>(text: &str, path: &Path) -> Result<T> {
    serde_json::from_str(text.trim_start_matches('\u{feff}')).map_err(|e| Error::Input {
        path: path.to_path_buf(),
        reason: format!("parsing: {e}"),
    })
}

/// The JSON file at `path` as a `T` (a config file, a settings file).
///
/// # Errors
/// [`Error::Input`] naming `path` when it cannot be read or is not a `T`.
pub fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::Input {
        path: path.to_path_buf(),
        reason: format!("cannot read it: {e}"),
    })?;
    parse_json(&text, path)
}

/// `base` with the fields of the JSON object `text` (read from `source`)
/// written over it: nested objects are merged field by field, so a field
/// the text leaves out keeps `base`'s value at every depth (a partial
/// `{"svg": {"gamma": 0.9}}` keeps every other SVG setting of `base`, not
/// the library type's own defaults). Unknown fields are refused as `T`
/// refuses them.
///
/// # Errors
/// [`Error::Input`] naming `source` for text that is not JSON or not a `T`
/// once merged.
pub fn overlay_json<T>(base: &T, text: &str, source: &Path) -> Result<T>
where
    T: serde::Serialize + serde::de::DeserializeOwned,
{
    let bad = |reason: String| Error::Input {
        path: source.to_path_buf(),
        reason,
    };
    let mut merged = serde_json::to_value(base)
        .map_err(|e| bad(format!("cannot serialise the defaults: {e}")))?;
    let over: serde_json::Value = serde_json::from_str(text.trim_start_matches('\u{feff}'))
        .map_err(|e| bad(format!("parsing: {e}")))?;
    if !over.is_object() {
        return Err(bad("must hold a JSON object ({...})".into()));
    }
    merge(&mut merged, over);
    serde_json::from_value(merged).map_err(|e| bad(e.to_string()))
}

/// The JSON object in the file at `path` written over `base` (see
/// [`overlay_json`]).
///
/// # Errors
/// [`Error::Input`] naming `path` when it cannot be read or does not make a
/// `T`.
pub fn read_json_over<T>(path: &Path, base: &T) -> Result<T>
where
    T: serde::Serialize + serde::de::DeserializeOwned,
{
    let text = std::fs::read_to_string(path).map_err(|e| Error::Input {
        path: path.to_path_buf(),
        reason: format!("cannot read it: {e}"),
    })?;
    overlay_json(base, &text, path)
}

/// Overwrites `base` with the fields of `over`, recursively for objects.
fn merge(base: &mut serde_json::Value, over: serde_json::Value) {
    match (base, over) {
        (serde_json::Value::Object(b), serde_json::Value::Object(o)) => {
            for (k, v) in o {
                match b.get_mut(&k) {
                    Some(slot) => merge(slot, v),
                    None => {
                        b.insert(k, v);
                    }
                }
            }
        }
        (b, o) => *b = o,
    }
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
        let mut left: Vec<_> = std::fs::read_dir(run.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(left, ["a.txt", "b.json", LOCK_FILE], "no temporary file");
        drop(run);
        assert!(
            !dir.path().join("r").join(LOCK_FILE).exists(),
            "lock released"
        );
    }

    #[test]
    fn a_folder_with_a_run_is_refused_or_moved_aside() {
        let dir = tempfile::tempdir().unwrap();
        let run = RunDir::create(dir.path(), "r").unwrap();
        run.write("eval.json", b"old").unwrap();
        drop(run);
        let e = RunDir::create(dir.path(), "r").unwrap_err().to_string();
        assert!(e.contains("--resume") && e.contains("--force"), "{e}");
        let run = RunDir::create_with(dir.path(), "r", Existing::MoveAside).unwrap();
        assert!(run.notes()[0].contains("r.old-1"), "{:?}", run.notes());
        assert!(
            !run.file("eval.json").exists(),
            "the new folder starts empty"
        );
        let old = dir.path().join("r.old-1/eval.json");
        assert_eq!(std::fs::read(old).unwrap(), b"old");
    }

    #[test]
    fn a_held_lock_refuses_and_a_stale_one_is_taken_over() {
        let dir = tempfile::tempdir().unwrap();
        let run = RunDir::create(dir.path(), "r").unwrap();
        let e = RunDir::open(run.path()).unwrap_err().to_string();
        assert!(e.contains(&std::process::id().to_string()), "{e}");
        let e = RunDir::create_with(dir.path(), "r", Existing::MoveAside)
            .unwrap_err()
            .to_string();
        assert!(e.contains("in use"), "{e}");
        let path = run.path().to_path_buf();
        run.write("config.json", b"{}").unwrap();
        drop(run);
        // A pid above Linux's maximum (2^22) is never running.
        std::fs::write(path.join(LOCK_FILE), "4194305\n").unwrap();
        let run = RunDir::open(&path).unwrap();
        assert!(run.notes()[0].contains("4194305"), "{:?}", run.notes());
        let lock = std::fs::read_to_string(path.join(LOCK_FILE)).unwrap();
        assert_eq!(Holder::parse(&lock), Some(Holder::me()), "{lock}");
    }

    #[test]
    fn a_lock_of_another_host_is_refused_unless_it_is_this_slurm_task() {
        let dir = tempfile::tempdir().unwrap();
        let run = RunDir::create(dir.path(), "r").unwrap();
        run.write("config.json", b"{}").unwrap();
        let path = run.path().to_path_buf();
        drop(run);
        // Another host's lock (a pid that would be dead here): refused.
        std::fs::write(path.join(LOCK_FILE), "4194305\nhost=elsewhere-node\n").unwrap();
        let e = RunDir::open(&path).unwrap_err().to_string();
        assert!(
            e.contains("host elsewhere-node") && e.contains("delete"),
            "{e}"
        );
        // Another SLURM task there: refused too.
        std::fs::write(
            path.join(LOCK_FILE),
            "4194305\nhost=elsewhere-node\nslurm=not-this-task\n",
        )
        .unwrap();
        assert!(RunDir::open(&path).is_err());
        // The same task (this process's, if under SLURM) requeued: taken over.
        if let Some(task) = slurm_task() {
            std::fs::write(
                path.join(LOCK_FILE),
                format!("4194305\nhost=elsewhere-node\nslurm={task}\n"),
            )
            .unwrap();
            let run = RunDir::open(&path).unwrap();
            assert!(run.notes()[0].contains("requeued"), "{:?}", run.notes());
        }
        let h = Holder::parse("12\nhost=a\nslurm=7_3\n").unwrap();
        assert_eq!(
            (h.pid, h.host.as_deref(), h.slurm.as_deref()),
            (12, Some("a"), Some("7_3"))
        );
        assert_eq!(Holder::parse(&h.contents()), Some(h));
        assert_eq!(Holder::parse("garbage"), None);
    }

    #[test]
    fn json_files_skip_a_bom_and_name_the_file_when_bad() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.json");
        std::fs::write(&p, "\u{feff}{\"a\": 2}").unwrap();
        let v: serde_json::Value = read_json(&p).unwrap();
        assert_eq!(v["a"], 2);
        std::fs::write(&p, "{\"a\": ").unwrap();
        let err = read_json::<serde_json::Value>(&p).unwrap_err().to_string();
        assert!(err.contains("c.json") && err.contains("parsing"), "{err}");
        let err = read_json::<serde_json::Value>(&dir.path().join("none.json"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("none.json") && err.contains("cannot read"),
            "{err}"
        );
    }
}
