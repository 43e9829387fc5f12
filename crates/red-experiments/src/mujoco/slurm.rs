//! The grid of Table 1 on a SLURM cluster: one job-array task per cell.
//!
//! [`submit`] writes a batch script for the cells of a [`TableConfig`] that
//! have not finished ([`batch_script`]) into `<grid>/slurm/`, and hands it
//! to `sbatch` (or only writes it, for a dry run). Each array task runs the
//! ordinary single-run command, `red-cli mujoco train`, into the cell's run
//! folder of the grid ([`TableConfig::cell_dir`], the folder a local
//! `red-cli mujoco table` uses), with the settings the local grid gives the
//! cell; when the folder already holds a run, the task runs
//! `red-cli mujoco train --resume` instead, so a requeued, preempted or
//! timed-out task continues from its checkpoint. `red-cli` saves its
//! checkpoint and exits on SIGTERM (what SLURM sends at preemption, at the
//! time limit and on `scancel`), so such a task loses at most the
//! iteration it was in.
//!
//! [`grid_status`] says, cell by cell, what the shared runs folder holds
//! (finished, unfinished at some step, not started, no demonstrations) with
//! the last line of the cell's latest SLURM log, so the report can list the
//! missing or failed cells, and [`submit`] called again submits only those.
//! The numbers of a cell do not depend on where it ran: same settings, same
//! seed, same results as the local grid.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use serde::{Deserialize, Serialize};

use super::table::{GridCell, TableConfig, cell_finished};
use super::{default_demo, short_name};
use crate::{Error, Result};

/// What each array task asks of SLURM, and the programs to use.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SlurmConfig {
    /// `--partition` (default: the cluster's default partition).
    pub partition: Option<String>,
    /// `--time`, the time limit of each task (`MM`, `HH:MM:SS`,
    /// `D-HH:MM`, ...; default: the partition's). A task that reaches it
    /// saves its checkpoint on SIGTERM and is continued by a resubmission.
    pub time: Option<String>,
    /// `--cpus-per-task`. Default 1: a cell is one single-threaded TRPO or
    /// BC run (the local grid also runs one cell per core).
    pub cpus_per_task: usize,
    /// `--mem` (`4G`, ...; default: the partition's).
    pub mem: Option<String>,
    /// `--account` (default: the user's default account).
    pub account: Option<String>,
    /// At most this many tasks of the array at once (`--array=...%N`).
    pub max_running: Option<usize>,
    /// Further `#SBATCH` options, each a whole option (`--qos=long`).
    pub extra: Vec<String>,
    /// The `red-cli` the tasks run: a path the compute nodes can reach.
    /// Default `red-cli` (found on the nodes' `PATH`).
    pub red_cli: PathBuf,
    /// The `sbatch` program. Default `sbatch`.
    pub sbatch: PathBuf,
    /// The `squeue` program, asked before a submission whether a job of the
    /// grid is still queued. Default `squeue`.
    pub squeue: PathBuf,
}

impl Default for SlurmConfig {
    fn default() -> Self {
        Self {
            partition: None,
            time: None,
            cpus_per_task: 1,
            mem: None,
            account: None,
            max_running: None,
            extra: Vec::new(),
            red_cli: PathBuf::from("red-cli"),
            sbatch: PathBuf::from("sbatch"),
            squeue: PathBuf::from("squeue"),
        }
    }
}

impl SlurmConfig {
    /// Checks every field.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the first bad field.
    pub fn validate(&self) -> Result<()> {
        let bad = |field: &str, reason: String| {
            Err(Error::InvalidConfig {
                field: field.into(),
                reason,
            })
        };
        // An `#SBATCH` line ends at the first blank: values cannot hold one.
        let word = |v: &str| !v.is_empty() && !v.chars().any(char::is_whitespace);
        for (field, value) in [
            ("partition", &self.partition),
            ("mem", &self.mem),
            ("account", &self.account),
        ] {
            if let Some(v) = value
                && !word(v)
            {
                return bad(field, format!("{v:?} must be one word without blanks"));
            }
        }
        if let Some(t) = &self.time
            && (t.is_empty()
                || !t.chars().next().is_some_and(|c| c.is_ascii_digit())
                || !t
                    .chars()
                    .all(|c| c.is_ascii_digit() || c == ':' || c == '-'))
        {
            return bad(
                "time",
                format!(
                    "{t:?} is not a SLURM time limit (minutes, MM:SS, HH:MM:SS, D-HH, D-HH:MM or D-HH:MM:SS)"
                ),
            );
        }
        if self.cpus_per_task == 0 {
            return bad("cpus_per_task", "must be at least 1".into());
        }
        if self.max_running == Some(0) {
            return bad(
                "max_running",
                "must be at least 1 (leave it out for no limit)".into(),
            );
        }
        if let Some(e) = self.extra.iter().find(|e| !e.starts_with('-') || !word(e)) {
            return bad(
                "extra",
                format!("{e:?} must be one sbatch option such as --qos=long, without blanks"),
            );
        }
        if self.red_cli.as_os_str().is_empty() {
            return bad("red_cli", "must name the red-cli program".into());
        }
        Ok(())
    }
}

/// Where a cell stands in the shared runs folder.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CellState {
    /// Trained and evaluated with the grid's budget.
    Finished,
    /// Started (a `config.json`) but not finished: resumed when submitted
    /// again. `env_steps`: the last step of its `metrics.csv`, if any.
    Unfinished {
        /// Environment steps in `metrics.csv` (the checkpoint may be at
        /// this step or earlier).
        env_steps: Option<u64>,
    },
    /// Nothing in its folder yet.
    NotStarted,
    /// Its task has no demonstrations at the experts' folder: it cannot
    /// run (make the expert first).
    NoDemo,
}

/// One cell of the grid with its state and its latest SLURM log.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CellStatus {
    /// The cell.
    pub cell: GridCell,
    /// What its folder holds.
    pub state: CellState,
    /// The latest SLURM log of the cell (in `<grid>/slurm/`) and its last
    /// non-empty line (an error, `interrupted; ...`, the evaluation).
    pub log: Option<(PathBuf, String)>,
}

impl CellStatus {
    /// `hopper red s0`.
    pub fn label(&self) -> String {
        format!(
            "{} {} s{}",
            short_name(self.cell.env),
            self.cell.method.name(),
            self.cell.seed
        )
    }

    /// One line for a report: the cell, its state and its last log line.
    pub fn line(&self) -> String {
        let state = match &self.state {
            CellState::Finished => "finished".to_string(),
            CellState::Unfinished { env_steps: Some(s) } => {
                format!("unfinished (metrics up to env step {s})")
            }
            CellState::Unfinished { env_steps: None } => "unfinished (no iteration yet)".into(),
            CellState::NotStarted => "not started".into(),
            CellState::NoDemo => "no demonstrations for its task".into(),
        };
        let mut s = format!("{}: {state} [{}]", self.label(), self.cell.dir.display());
        if let Some((path, last)) = &self.log {
            let _ = write!(s, "; last log line ({}): {last}", path.display());
        }
        s
    }
}

/// The folder of the grid's batch scripts and SLURM logs: `<grid>/slurm`.
pub fn slurm_dir(cfg: &TableConfig) -> PathBuf {
    cfg.root().join("slurm")
}

/// The state of every cell of the grid, in [`TableConfig::cells`] order.
pub fn grid_status(cfg: &TableConfig) -> Vec<CellStatus> {
    let logs = cell_logs(&slurm_dir(cfg));
    cfg.cells()
        .into_iter()
        .map(|cell| {
            let state = if cell_finished(cfg, &cell.dir) {
                CellState::Finished
            } else if cell.dir.join("config.json").is_file() {
                CellState::Unfinished {
                    env_steps: last_metrics_step(&cell.dir),
                }
            } else if !default_demo(cfg.experts_dir(), cell.env).is_file() {
                CellState::NoDemo
            } else {
                CellState::NotStarted
            };
            let log = absolute(&cell.dir)
                .ok()
                .and_then(|d| logs.iter().find(|(dir, _, _)| *dir == d))
                .map(|(_, path, last)| (path.clone(), last.clone()));
            CellStatus { cell, state, log }
        })
        .collect()
}

/// The last environment step in a run's `metrics.csv`.
fn last_metrics_step(dir: &Path) -> Option<u64> {
    let text = std::fs::read_to_string(dir.join("metrics.csv")).ok()?;
    text.lines()
        .skip(1)
        .filter_map(|l| l.split(',').nth(1)?.parse::<u64>().ok())
        .last()
}

/// The first line a task writes to its log, naming the cell's folder.
const LOG_HEAD: &str = "cell: ";

/// `(cell folder, log, last non-empty line)` of every log in `dir`, the
/// newest first.
fn cell_logs(dir: &Path) -> Vec<(PathBuf, PathBuf, String)> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut logs: Vec<_> = entries
        .filter_map(std::result::Result::ok)
        .filter(|e| e.path().extension().is_some_and(|x| x == "out"))
        .filter_map(|e| {
            let path = e.path();
            let modified = e.metadata().ok()?.modified().ok()?;
            let text = std::fs::read_to_string(&path).ok()?;
            let first = text.lines().next()?.strip_prefix(LOG_HEAD)?;
            let cell = PathBuf::from(first.split(" (job ").next()?);
            let last = text.lines().rev().find(|l| !l.trim().is_empty())?.trim();
            Some((modified, cell, path, last.to_string()))
        })
        .collect();
    logs.sort_by(|a, b| b.0.cmp(&a.0).then_with(|| b.2.cmp(&a.2)));
    logs.into_iter().map(|(_, c, p, l)| (c, p, l)).collect()
}

fn absolute(path: &Path) -> Result<PathBuf> {
    std::path::absolute(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })
}

fn utf8<'a>(path: &'a Path, what: &str) -> Result<&'a str> {
    path.to_str().ok_or_else(|| Error::Input {
        path: path.to_path_buf(),
        reason: format!("{what}: a path that is not UTF-8 cannot go into a batch script"),
    })
}

/// `s` as one word of a POSIX shell.
fn sh_quote(s: &str) -> String {
    let plain = |c: char| c.is_ascii_alphanumeric() || "_./:=@%+,-".contains(c);
    if !s.is_empty() && s.chars().all(plain) {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', r"'\''"))
    }
}

/// The batch script of a job array over `cells` of the grid `cfg`: task
/// `i` runs `cells[i]`. Paths in the script are absolute (the tasks may
/// start in another folder than the caller).
///
/// The task of a cell whose folder holds no run yet runs
/// `red-cli mujoco train --env E --method M --seed S --steps N
/// --eval-episodes K --checkpoint-every C --demo <experts>/expert-<task>/demos.json
/// --out-dir <grid>/runs --name <task>-<method>-s<seed>`, the settings the
/// local grid gives the cell; otherwise `red-cli mujoco train --resume
/// <folder> --steps N'`, N' the larger of the grid's budget and the one the
/// run has. The task's log, `<grid>/slurm/<job>_<task>.out` (appended to
/// when the task is requeued), starts with `cell: <folder>`.
///
/// # Errors
/// [`Error::InvalidConfig`] for bad settings or no cells,
/// [`Error::Input`] for a path that is not UTF-8 or whose grid folder holds
/// a blank (an `#SBATCH` line cannot), [`Error::Io`] if the current folder
/// is unknown.
pub fn batch_script(cfg: &TableConfig, slurm: &SlurmConfig, cells: &[GridCell]) -> Result<String> {
    cfg.validate()?;
    slurm.validate()?;
    if cells.is_empty() {
        return Err(Error::InvalidConfig {
            field: "cells".into(),
            reason: "a job array needs at least one cell".into(),
        });
    }
    let logs = absolute(&slurm_dir(cfg))?;
    let logs_s = utf8(&logs, "the grid folder")?;
    if logs_s.chars().any(char::is_whitespace) {
        return Err(Error::Input {
            path: logs.clone(),
            reason: "an #SBATCH --output path cannot hold blanks; choose an --out-dir without them"
                .into(),
        });
    }
    let runs = absolute(&cfg.root().join("runs"))?;
    let red_cli = if slurm.red_cli.components().count() > 1 {
        absolute(&slurm.red_cli)?
    } else {
        slurm.red_cli.clone()
    };
    let mut s = String::new();
    let _ = writeln!(s, "#!/bin/bash");
    let _ = writeln!(
        s,
        "# Written by `red-cli mujoco table --slurm`: grid `{}`, {} cell(s), one array task each.",
        cfg.name,
        cells.len()
    );
    let _ = writeln!(
        s,
        "# A task runs `red-cli mujoco train` into its cell's folder, or resumes the run there\n\
         # (a requeued, preempted or timed-out task continues from its checkpoint)."
    );
    let _ = writeln!(s, "#SBATCH --job-name=red-{}", cfg.name);
    let _ = writeln!(
        s,
        "#SBATCH --array=0-{}{}",
        cells.len() - 1,
        slurm.max_running.map_or(String::new(), |m| format!("%{m}"))
    );
    let _ = writeln!(s, "#SBATCH --output={logs_s}/%A_%a.out");
    let _ = writeln!(s, "#SBATCH --open-mode=append");
    let _ = writeln!(s, "#SBATCH --requeue");
    let _ = writeln!(s, "#SBATCH --ntasks=1");
    let _ = writeln!(s, "#SBATCH --cpus-per-task={}", slurm.cpus_per_task);
    for (flag, value) in [
        ("partition", &slurm.partition),
        ("time", &slurm.time),
        ("mem", &slurm.mem),
        ("account", &slurm.account),
    ] {
        if let Some(v) = value {
            let _ = writeln!(s, "#SBATCH --{flag}={v}");
        }
    }
    for e in &slurm.extra {
        let _ = writeln!(s, "#SBATCH {e}");
    }
    let _ = writeln!(s, "set -euo pipefail");
    let _ = writeln!(
        s,
        "RED_CLI={}",
        sh_quote(utf8(&red_cli, "the red-cli program")?)
    );
    let _ = writeln!(
        s,
        "case \"${{SLURM_ARRAY_TASK_ID:?submit this script with sbatch}}\" in"
    );
    for (i, cell) in cells.iter().enumerate() {
        let dir = absolute(&cell.dir)?;
        let steps =
            super::run::read_config(&cell.dir).map_or(cfg.steps, |c| c.steps.max(cfg.steps));
        let demo = absolute(&default_demo(cfg.experts_dir(), cell.env))?;
        let name = super::default_run_name(cell.env, cell.method, cell.seed);
        let new = [
            "mujoco".to_string(),
            "train".into(),
            "--env".into(),
            short_name(cell.env),
            "--method".into(),
            cell.method.name().into(),
            "--seed".into(),
            cell.seed.to_string(),
            "--steps".into(),
            cfg.steps.to_string(),
            "--eval-episodes".into(),
            cfg.eval_episodes.to_string(),
            "--checkpoint-every".into(),
            cfg.checkpoint_every.to_string(),
            "--demo".into(),
            utf8(&demo, "the demonstrations")?.to_string(),
            "--out-dir".into(),
            utf8(&runs, "the grid folder")?.to_string(),
            "--name".into(),
            name,
        ];
        let new: Vec<String> = new.iter().map(|a| sh_quote(a)).collect();
        let _ = writeln!(
            s,
            "  {i}) DIR={}; STEPS={steps}; NEW=({}) ;;",
            sh_quote(utf8(&dir, "the cell's folder")?),
            new.join(" ")
        );
    }
    let _ = writeln!(
        s,
        "  *) echo \"no cell for array task $SLURM_ARRAY_TASK_ID\" >&2; exit 2 ;;\nesac"
    );
    let _ = writeln!(
        s,
        "echo \"{LOG_HEAD}$DIR (job ${{SLURM_JOB_ID:-?}}, array task $SLURM_ARRAY_TASK_ID, host $(hostname), $(date -u +%FT%TZ))\""
    );
    // `exec`: red-cli itself gets SLURM's SIGTERM, saves and exits.
    let _ = writeln!(
        s,
        "if [ -f \"$DIR/config.json\" ]; then\n  exec \"$RED_CLI\" mujoco train --resume \"$DIR\" --steps \"$STEPS\"\nelse\n  exec \"$RED_CLI\" \"${{NEW[@]}}\"\nfi"
    );
    Ok(s)
}

/// What [`submit`] did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Submission {
    /// The batch script written (none when every cell had finished or
    /// could not run).
    pub script: Option<PathBuf>,
    /// The cells of the job array, task `i` being `cells[i]`.
    pub cells: Vec<GridCell>,
    /// Cells left out because their task has no demonstrations.
    pub no_demo: Vec<GridCell>,
    /// The job id `sbatch` gave (none for a dry run or nothing to submit).
    pub job_id: Option<String>,
}

impl Submission {
    /// What was done, for the user: cells left out, the job id or the
    /// script not submitted, where the logs go and how to go on.
    pub fn summary(&self, cfg: &TableConfig) -> String {
        let mut s = String::new();
        for c in &self.no_demo {
            let _ = writeln!(
                s,
                "{}: no demonstrations at {}; left out (run `red-cli mujoco expert` first)",
                c.dir.display(),
                default_demo(cfg.experts_dir(), c.env).display()
            );
        }
        let Some(script) = &self.script else {
            s.push_str("nothing to submit: no cell is missing\n");
            return s;
        };
        let _ = match &self.job_id {
            Some(id) => writeln!(
                s,
                "submitted job {id}: {} cell(s), batch script {}",
                self.cells.len(),
                script.display()
            ),
            None => writeln!(
                s,
                "batch script for {} cell(s) written (not submitted): {}",
                self.cells.len(),
                script.display()
            ),
        };
        let _ = writeln!(
            s,
            "logs in {}; when the job has left the queue, run the same command with --report-only \
             instead of --slurm (add --resubmit-missing to submit what is missing again)",
            slurm_dir(cfg).display()
        );
        s
    }
}

/// The cells of the grid that have not finished, one line each
/// ([`CellStatus::line`]), under a count: `2 of 4 cells missing`.
pub fn missing_report(cfg: &TableConfig) -> String {
    let missing: Vec<_> = grid_status(cfg)
        .into_iter()
        .filter(|c| c.state != CellState::Finished)
        .collect();
    let mut s = format!("{} of {} cells missing\n", missing.len(), cfg.cells().len());
    for c in &missing {
        let _ = writeln!(s, "  {}", c.line());
    }
    s
}

/// Writes the batch script of every cell of the grid that has not finished
/// (not started, or unfinished: those resume) into
/// `<grid>/slurm/submit-<k>.sbatch` (the first free `k`) and, unless
/// `dry_run`, submits it with `sbatch --parsable`. A grid with a job still
/// in the queue (`squeue`, by the job name `red-<name>`) is refused: its
/// unfinished cells may be running, and two tasks must not share a cell. Cells whose task has no
/// demonstrations are left out (in [`Submission::no_demo`]). Run it again
/// after the job has left the queue to resubmit what is still missing.
///
/// # Errors
/// As [`batch_script`]; [`Error::Io`] if the script cannot be written;
/// [`Error::Input`] (naming the script) if `sbatch` cannot be started,
/// fails, or prints no job id, or (naming the grid) if a job of the grid
/// is still queued.
pub fn submit(cfg: &TableConfig, slurm: &SlurmConfig, dry_run: bool) -> Result<Submission> {
    cfg.validate()?;
    slurm.validate()?;
    if !dry_run {
        let queued = queued_jobs(slurm, cfg);
        if !queued.is_empty() {
            return Err(Error::Input {
                path: cfg.root(),
                reason: format!(
                    "job(s) {} of this grid (red-{}) are still in the queue; wait until they \
                     leave it (squeue) or scancel them, then submit again",
                    queued.join(", "),
                    cfg.name
                ),
            });
        }
    }
    let mut cells = Vec::new();
    let mut no_demo = Vec::new();
    for st in grid_status(cfg) {
        match st.state {
            CellState::Finished => {}
            CellState::NoDemo => no_demo.push(st.cell),
            CellState::Unfinished { .. } | CellState::NotStarted => cells.push(st.cell),
        }
    }
    if cells.is_empty() {
        return Ok(Submission {
            script: None,
            cells,
            no_demo,
            job_id: None,
        });
    }
    let text = batch_script(cfg, slurm, &cells)?;
    let dir = absolute(&slurm_dir(cfg))?;
    std::fs::create_dir_all(&dir).map_err(|source| Error::Io {
        path: dir.clone(),
        source,
    })?;
    let script = (1..)
        .map(|k| dir.join(format!("submit-{k}.sbatch")))
        .find(|p| !p.exists())
        .unwrap_or_else(|| dir.join("submit.sbatch"));
    red_core::checkpoint::write_atomic(&script, text.as_bytes())?;
    let job_id = if dry_run {
        None
    } else {
        Some(run_sbatch(&slurm.sbatch, &script)?)
    };
    Ok(Submission {
        script: Some(script),
        cells,
        no_demo,
        job_id,
    })
}

/// The ids of the queued jobs named `red-<name>` (none if `squeue` cannot
/// be asked).
fn queued_jobs(slurm: &SlurmConfig, cfg: &TableConfig) -> Vec<String> {
    let Ok(out) = Command::new(&slurm.squeue)
        .args(["-h", "-o", "%F", "-n"])
        .arg(format!("red-{}", cfg.name))
        .output()
    else {
        return Vec::new();
    };
    let mut ids: Vec<String> = String::from_utf8_lossy(&out.stdout)
        .split_whitespace()
        .map(str::to_string)
        .collect();
    ids.sort();
    ids.dedup();
    ids
}

fn run_sbatch(sbatch: &Path, script: &Path) -> Result<String> {
    let fail = |reason: String| Error::Input {
        path: script.to_path_buf(),
        reason,
    };
    let out = Command::new(sbatch)
        .arg("--parsable")
        .arg(script)
        .output()
        .map_err(|e| {
            fail(format!(
                "cannot run {} ({e}); is SLURM installed here? (--dry-run only writes the script)",
                sbatch.display()
            ))
        })?;
    let stdout = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() {
        return Err(fail(format!(
            "{} failed ({}): {}",
            sbatch.display(),
            out.status,
            String::from_utf8_lossy(&out.stderr).trim()
        )));
    }
    parse_job_id(&stdout).ok_or_else(|| {
        fail(format!(
            "{} printed no job id: {:?}",
            sbatch.display(),
            stdout.trim()
        ))
    })
}

/// The job id in the output of `sbatch --parsable` (`1234` or
/// `1234;cluster`).
pub fn parse_job_id(stdout: &str) -> Option<String> {
    let line = stdout.lines().map(str::trim).rfind(|l| !l.is_empty())?;
    let id = line.split(';').next()?.trim();
    (!id.is_empty() && id.chars().all(|c| c.is_ascii_digit())).then(|| id.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mujoco::Method;
    use red_mujoco::EnvId;

    fn grid(out: &Path) -> TableConfig {
        TableConfig {
            envs: vec![EnvId::Reacher, EnvId::Hopper],
            methods: vec![Method::Red, Method::Bc],
            steps: 3072,
            eval_episodes: 2,
            checkpoint_every: 1,
            name: "g".into(),
            out_dir: out.to_path_buf(),
            ..TableConfig::default()
        }
    }

    #[test]
    fn job_ids_from_sbatch() {
        assert_eq!(parse_job_id("1234\n").as_deref(), Some("1234"));
        assert_eq!(parse_job_id("77;cluster\n").as_deref(), Some("77"));
        assert_eq!(parse_job_id("Submitted batch job 5\n"), None);
        assert_eq!(parse_job_id(""), None);
    }

    #[test]
    fn quoting_survives_the_shell() {
        assert_eq!(sh_quote("/a/b-c_1.json"), "/a/b-c_1.json");
        assert_eq!(sh_quote("it's"), r"'it'\''s'");
        assert_eq!(sh_quote(""), "''");
    }

    #[test]
    fn bad_settings_are_named() {
        let field = |s: SlurmConfig| match s.validate() {
            Err(Error::InvalidConfig { field, .. }) => field,
            other => panic!("{other:?}"),
        };
        let base = SlurmConfig::default();
        assert!(base.validate().is_ok());
        let t = |t: &str| SlurmConfig {
            time: Some(t.into()),
            ..SlurmConfig::default()
        };
        for ok in ["30", "02:00:00", "1-12:00"] {
            assert!(t(ok).validate().is_ok(), "{ok}");
        }
        assert_eq!(field(t("2 hours")), "time");
        assert_eq!(
            field(SlurmConfig {
                partition: Some("a b".into()),
                ..SlurmConfig::default()
            }),
            "partition"
        );
        assert_eq!(
            field(SlurmConfig {
                cpus_per_task: 0,
                ..SlurmConfig::default()
            }),
            "cpus_per_task"
        );
        assert_eq!(
            field(SlurmConfig {
                extra: vec!["qos=x".into()],
                ..SlurmConfig::default()
            }),
            "extra"
        );
    }

    /// The script is valid bash, asks for one task per cell, and task `i`
    /// runs the train command of cell `i`, or resumes it once its folder
    /// holds a run (checked with a stand-in red-cli that prints its
    /// arguments).
    #[test]
    fn script_runs_the_cell_of_its_task() {
        let tmp = tempfile::tempdir().unwrap();
        let cfg = grid(tmp.path());
        let fake = tmp.path().join("fake red-cli");
        std::fs::write(
            &fake,
            "#!/bin/sh\nfor a in \"$@\"; do echo \"[$a]\"; done\n",
        )
        .unwrap();
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();
        let slurm = SlurmConfig {
            time: Some("00:10:00".into()),
            partition: Some("debug".into()),
            max_running: Some(2),
            red_cli: fake.clone(),
            ..SlurmConfig::default()
        };
        let cells = cfg.cells();
        assert_eq!(cells.len(), 4);
        let text = batch_script(&cfg, &slurm, &cells).unwrap();
        assert!(text.contains("#SBATCH --array=0-3%2\n"), "{text}");
        assert!(text.contains("#SBATCH --time=00:10:00\n"));
        assert!(text.contains("#SBATCH --partition=debug\n"));
        let script = tmp.path().join("s.sbatch");
        std::fs::write(&script, &text).unwrap();
        let run = |task: &str| {
            let o = Command::new("bash")
                .arg(&script)
                .env("SLURM_ARRAY_TASK_ID", task)
                .output()
                .unwrap();
            (
                o.status.success(),
                String::from_utf8_lossy(&o.stdout).into_owned(),
            )
        };
        let (ok, out) = run("2");
        assert!(ok, "{out}");
        let dir = std::path::absolute(cfg.cell_dir(EnvId::Hopper, Method::Red, 0)).unwrap();
        assert!(
            out.starts_with(&format!("cell: {} (job", dir.display())),
            "{out}"
        );
        let args: Vec<&str> = out.lines().skip(1).collect();
        let runs = std::path::absolute(cfg.root().join("runs")).unwrap();
        let demo = std::path::absolute(tmp.path().join("expert-hopper/demos.json")).unwrap();
        let want = [
            "mujoco".to_string(),
            "train".into(),
            "--env".into(),
            "hopper".into(),
            "--method".into(),
            "red".into(),
            "--seed".into(),
            "0".into(),
            "--steps".into(),
            "3072".into(),
            "--eval-episodes".into(),
            "2".into(),
            "--checkpoint-every".into(),
            "1".into(),
            "--demo".into(),
            demo.display().to_string(),
            "--out-dir".into(),
            runs.display().to_string(),
            "--name".into(),
            "hopper-red-s0".into(),
        ]
        .map(|a| format!("[{a}]"));
        assert_eq!(args, want);
        // Once the folder holds a run, the task resumes it.
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("config.json"), "{}").unwrap();
        let (ok, out) = run("2");
        assert!(ok);
        let resume = format!(
            "[mujoco]\n[train]\n[--resume]\n[{}]\n[--steps]\n[3072]\n",
            dir.display()
        );
        assert!(out.ends_with(&resume), "{out}");
        // No task beyond the cells.
        assert!(!run("4").0);
    }

    /// States from the folders: no demos, not started, unfinished (with the
    /// step of its metrics), and the last line of the newest log.
    #[test]
    fn status_of_the_cells() {
        let tmp = tempfile::tempdir().unwrap();
        let cfg = grid(tmp.path());
        let st = grid_status(&cfg);
        assert!(st.iter().all(|s| s.state == CellState::NoDemo));
        let demo = default_demo(tmp.path(), EnvId::Reacher);
        std::fs::create_dir_all(demo.parent().unwrap()).unwrap();
        std::fs::write(&demo, "{}").unwrap();
        let dir = cfg.cell_dir(EnvId::Reacher, Method::Red, 0);
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("config.json"), "{}").unwrap();
        std::fs::write(
            dir.join("metrics.csv"),
            "iteration,env_steps,x\n1,1024,0\n2,2048,0\n",
        )
        .unwrap();
        let logs = slurm_dir(&cfg);
        std::fs::create_dir_all(&logs).unwrap();
        let abs = std::path::absolute(&dir).unwrap();
        std::fs::write(
            logs.join("7_0.out"),
            format!(
                "{LOG_HEAD}{} (job 7, array task 0, host h, t)\nError: boom\n\n",
                abs.display()
            ),
        )
        .unwrap();
        let st = grid_status(&cfg);
        let states: Vec<_> = st.iter().map(|s| s.state.clone()).collect();
        assert_eq!(
            states,
            [
                CellState::Unfinished {
                    env_steps: Some(2048)
                },
                CellState::NotStarted,
                CellState::NoDemo,
                CellState::NoDemo
            ]
        );
        assert_eq!(st[0].log.as_ref().unwrap().1, "Error: boom");
        assert!(
            st[0]
                .line()
                .contains("unfinished (metrics up to env step 2048)")
        );
        assert!(st[1].log.is_none());
        let report = missing_report(&cfg);
        assert!(report.starts_with("4 of 4 cells missing\n"), "{report}");
        assert!(report.contains("reacher red s0: unfinished"), "{report}");
        // A dry run writes the script for the two cells that can run.
        let sub = submit(&cfg, &SlurmConfig::default(), true).unwrap();
        assert_eq!(sub.cells.len(), 2);
        assert_eq!(sub.no_demo.len(), 2);
        assert!(sub.job_id.is_none());
        let text = std::fs::read_to_string(sub.script.as_ref().unwrap()).unwrap();
        assert!(text.contains("#SBATCH --array=0-1\n"), "{text}");
        let summary = sub.summary(&cfg);
        assert!(summary.contains("batch script for 2 cell(s) written (not submitted)"));
        assert!(summary.contains("expert-hopper"), "{summary}");
    }
}
