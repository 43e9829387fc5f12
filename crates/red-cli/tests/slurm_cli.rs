//! `red-cli mujoco table --slurm` on a one-node SLURM cluster started on
//! this machine by `scripts/slurm-local.sh` (slurm-wlm and munge from
//! Debian's packages; root needed): a 2 tasks x 2 methods grid with a tiny
//! budget gives the same table, the same metrics and the same evaluation
//! returns through SLURM as run locally with the same seeds; a cell
//! cancelled with `scancel` mid-run saves its checkpoint on SIGTERM and,
//! resubmitted with `--report-only --resubmit-missing`, ends with the same
//! numbers as an uninterrupted run.
//!
//! If the cluster cannot be installed or started, the test fails (the suite
//! must exercise it). The cluster is stopped at the end unless it was
//! already running.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

fn script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scripts/slurm-local.sh")
}

fn slurm_local(action: &str) -> Output {
    Command::new("bash")
        .arg(script())
        .arg(action)
        .output()
        .unwrap()
}

/// Stops the cluster (if this test started it) and cancels the test's jobs
/// on the way out, also when an assertion failed.
struct Cluster {
    started_here: bool,
    jobs: Vec<String>,
}

impl Drop for Cluster {
    fn drop(&mut self) {
        for j in &self.jobs {
            let _ = Command::new("scancel").arg(j).output();
        }
        if self.started_here {
            let _ = slurm_local("stop");
        }
    }
}

fn cli(args: &[&str], out: &Path) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_red-cli"))
        .arg("mujoco")
        .args(args)
        .arg("--out-dir")
        .arg(out)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "red-cli mujoco {args:?}\nstdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The job id of `submitted job N: ...`.
fn job_id(stdout: &str) -> String {
    stdout
        .lines()
        .find_map(|l| l.strip_prefix("submitted job ")?.split(':').next())
        .unwrap_or_else(|| panic!("no job id in:\n{stdout}"))
        .to_string()
}

/// Waits until the job has left the queue.
fn wait_job(id: &str, grid: &Path) {
    let start = Instant::now();
    loop {
        let o = Command::new("squeue")
            .args(["-h", "-j", id])
            .output()
            .unwrap();
        // squeue fails for a job it no longer knows (MinJobAge passed).
        if !o.status.success() || o.stdout.iter().all(u8::is_ascii_whitespace) {
            return;
        }
        assert!(
            start.elapsed() < Duration::from_secs(600),
            "job {id} still queued after 600 s:\n{}\nlogs in {}",
            String::from_utf8_lossy(&o.stdout),
            grid.join("slurm").display()
        );
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// metrics.csv without its wall-time column (BC runs have none).
fn metrics(run: &Path) -> Option<Vec<String>> {
    let text = std::fs::read_to_string(run.join("metrics.csv")).ok()?;
    Some(
        text.lines()
            .map(|l| l.rsplit_once(',').unwrap().0.to_string())
            .collect(),
    )
}

/// The evaluation returns (final policy, best checkpoint) of a run.
fn returns(run: &Path) -> (serde_json::Value, serde_json::Value) {
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("eval.json")).unwrap()).unwrap();
    (
        v["final_policy"]["returns"].clone(),
        v["best_checkpoint"]["returns"].clone(),
    )
}

/// Same table, and cell by cell the same metrics and evaluation returns.
fn assert_same_grid(a: &Path, b: &Path, cells: &[&str]) {
    assert_eq!(
        std::fs::read_to_string(a.join("table.csv")).unwrap(),
        std::fs::read_to_string(b.join("table.csv")).unwrap(),
        "table.csv of {} and {} differ",
        a.display(),
        b.display()
    );
    for c in cells {
        let (ra, rb) = (a.join("runs").join(c), b.join("runs").join(c));
        assert_eq!(metrics(&ra), metrics(&rb), "{c}: metrics differ");
        assert_eq!(metrics(&ra).is_some(), !c.contains("-bc-"), "{c}");
        assert_eq!(returns(&ra), returns(&rb), "{c}: evaluation differs");
    }
}

#[test]
fn grid_through_slurm_equals_local_and_survives_scancel() {
    let started_here = !slurm_local("status").status.success();
    let mut cluster = Cluster {
        started_here,
        jobs: Vec::new(),
    };
    let o = slurm_local("start");
    assert!(
        o.status.success(),
        "scripts/slurm-local.sh start failed: the one-node SLURM cluster is needed\n{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );

    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path();
    for env in ["reacher", "hopper"] {
        cli(
            &[
                "expert",
                "--env",
                env,
                "--steps",
                "1024",
                "--eval-episodes",
                "2",
            ],
            out,
        );
    }

    // 2 tasks x 2 methods, 3 TRPO iterations of 1024 steps.
    let grid = [
        "table",
        "--envs",
        "reacher,hopper",
        "--methods",
        "red,bc",
        "--steps",
        "3072",
        "--eval-episodes",
        "2",
        "--checkpoint-every",
        "1",
    ];
    let with = |extra: &[&'static str]| {
        let mut a = grid.to_vec();
        a.extend_from_slice(extra);
        a
    };
    let t = Instant::now();
    cli(&with(&["--name", "local", "--jobs", "2"]), out);
    let local_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let s = cli(
        &with(&["--name", "viaslurm", "--slurm", "--time", "10"]),
        out,
    );
    assert!(s.contains("4 cell(s)"), "{s}");
    let id = job_id(&s);
    cluster.jobs.push(id.clone());
    wait_job(&id, &out.join("viaslurm"));
    let slurm_s = t.elapsed().as_secs_f64();
    let s = cli(&with(&["--name", "viaslurm", "--report-only"]), out);
    assert!(s.contains("0 of 4 cells missing"), "{s}");
    eprintln!(
        "2x2 grid (3072 steps per TRPO run): locally (--jobs 2) {local_s:.1} s, through SLURM (submit until the job left the queue) {slurm_s:.1} s"
    );
    assert_same_grid(
        &out.join("local"),
        &out.join("viaslurm"),
        &[
            "reacher-red-s0",
            "reacher-bc-s0",
            "hopper-red-s0",
            "hopper-bc-s0",
        ],
    );

    // One longer cell, checkpoints only at the end (every 1000
    // iterations): the checkpoint after scancel can only come from the
    // SIGTERM handler.
    let long = [
        "table",
        "--envs",
        "hopper",
        "--methods",
        "red",
        "--steps",
        "20480",
        "--eval-episodes",
        "2",
        "--checkpoint-every",
        "1000",
    ];
    let with = |extra: &[&'static str]| {
        let mut a = long.to_vec();
        a.extend_from_slice(extra);
        a
    };
    cli(&with(&["--name", "long-local", "--jobs", "1"]), out);
    let s = cli(&with(&["--name", "long", "--slurm"]), out);
    let id = job_id(&s);
    cluster.jobs.push(id.clone());
    // A second submission while the job is queued is refused.
    let o = Command::new(env!("CARGO_BIN_EXE_red-cli"))
        .arg("mujoco")
        .args(with(&[
            "--name",
            "long",
            "--report-only",
            "--resubmit-missing",
        ]))
        .arg("--out-dir")
        .arg(out)
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("still in the queue"),
        "{e}"
    );
    let cell = out.join("long/runs/hopper-red-s0");
    let t = Instant::now();
    // Two iterations done (header + 2 rows), then cancel.
    while std::fs::read_to_string(cell.join("metrics.csv")).map_or(0, |m| m.lines().count()) < 3 {
        assert!(
            t.elapsed() < Duration::from_secs(300),
            "the cell did not start"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let o = Command::new("scancel").arg(&id).output().unwrap();
    assert!(o.status.success(), "{o:?}");
    wait_job(&id, &out.join("long"));
    let log = std::fs::read_to_string(out.join(format!("long/slurm/{id}_0.out"))).unwrap();
    assert!(log.contains("stopped at env step"), "{log}");
    assert!(!cell.join("eval.json").exists(), "{log}");
    let done = metrics(&cell).unwrap().len() - 1;
    assert!((2..20).contains(&done), "cancelled after {done} iterations");
    assert!(cell.join("checkpoint.json").is_file());
    let s = cli(&with(&["--name", "long", "--report-only"]), out);
    assert!(s.contains("1 of 1 cells missing"), "{s}");
    assert!(s.contains("unfinished"), "{s}");
    let s = cli(
        &with(&["--name", "long", "--report-only", "--resubmit-missing"]),
        out,
    );
    let id = job_id(&s);
    cluster.jobs.push(id.clone());
    wait_job(&id, &out.join("long"));
    let s = cli(&with(&["--name", "long", "--report-only"]), out);
    assert!(s.contains("0 of 1 cells missing"), "{s}");
    eprintln!("scancel after {done} of 20 iterations; resumed to the end");
    assert_same_grid(
        &out.join("long-local"),
        &out.join("long"),
        &["hopper-red-s0"],
    );
}

/// `--dry-run` writes the script with the flags' `#SBATCH` lines and
/// submits nothing (no SLURM needed); bad flags are refused by name.
#[test]
fn dry_run_writes_the_script_and_bad_flags_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path();
    cli(
        &[
            "expert",
            "--env",
            "reacher",
            "--steps",
            "1024",
            "--eval-episodes",
            "2",
        ],
        out,
    );
    let s = cli(
        &[
            "table",
            "--envs",
            "reacher",
            "--methods",
            "red,gail,bc",
            "--seeds",
            "0,1",
            "--slurm",
            "--dry-run",
            "--partition",
            "cpu",
            "--time",
            "1-00:00:00",
            "--mem",
            "2G",
            "--max-running",
            "3",
            "--sbatch-arg=--qos=long",
        ],
        out,
    );
    assert!(
        s.contains("batch script for 6 cell(s) written (not submitted)"),
        "{s}"
    );
    let script = std::fs::read_to_string(out.join("mujoco-table/slurm/submit-1.sbatch")).unwrap();
    for line in [
        "#SBATCH --array=0-5%3\n",
        "#SBATCH --partition=cpu\n",
        "#SBATCH --time=1-00:00:00\n",
        "#SBATCH --mem=2G\n",
        "#SBATCH --qos=long\n",
        "--method gail --seed 1 ",
    ] {
        assert!(script.contains(line), "{line} not in\n{script}");
    }
    assert!(
        !out.join("mujoco-table/runs")
            .join("reacher-red-s0")
            .exists()
    );
    for (flags, named) in [
        (&["--slurm", "--time", "2 hours"][..], "--time"),
        (&["--slurm", "--cpus-per-task", "0"][..], "--cpus-per-task"),
        (&["--dry-run"][..], "--dry-run"),
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_red-cli"))
            .args(["mujoco", "table", "--envs", "reacher"])
            .args(flags)
            .arg("--out-dir")
            .arg(out)
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && e.contains(named), "{flags:?}: {e}");
    }
}

/// SIGTERM (SLURM's preemption and time-limit signal) stops a local grid
/// as Ctrl-C does: the running cell saves its checkpoint mid-run (with
/// `--checkpoint-every 1000` only the handler can write one), the command
/// exits with success and says how to continue.
#[test]
fn local_table_saves_on_sigterm() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path();
    cli(
        &[
            "expert",
            "--env",
            "hopper",
            "--steps",
            "1024",
            "--eval-episodes",
            "2",
        ],
        out,
    );
    let child = Command::new(env!("CARGO_BIN_EXE_red-cli"))
        .args([
            "mujoco",
            "table",
            "--envs",
            "hopper",
            "--methods",
            "red",
            "--steps",
            "102400",
            "--checkpoint-every",
            "1000",
            "--eval-episodes",
            "2",
            "--out-dir",
        ])
        .arg(out)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let cell = out.join("mujoco-table/runs/hopper-red-s0");
    let t = Instant::now();
    while std::fs::read_to_string(cell.join("metrics.csv")).map_or(0, |m| m.lines().count()) < 3 {
        assert!(
            t.elapsed() < Duration::from_secs(300),
            "the cell did not start"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let k = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(k.success());
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("stopped at env step"), "{err}");
    assert!(err.contains("interrupted"), "{err}");
    assert!(!cell.join("eval.json").exists());
    let done = metrics(&cell).unwrap().len() - 1;
    assert!((2..100).contains(&done), "stopped after {done} iterations");
    // The checkpoint is at the last iteration of metrics.csv: a resume
    // keeps those rows as they are, wall times included (a resume from an
    // earlier checkpoint would drop and redo them).
    let before = std::fs::read_to_string(cell.join("metrics.csv")).unwrap();
    let s = cli(
        &[
            "train",
            "--resume",
            cell.to_str().unwrap(),
            "--steps",
            &((done as u64 + 1) * 1024).to_string(),
        ],
        out,
    );
    assert!(s.contains("final policy"), "{s}");
    let after = std::fs::read_to_string(cell.join("metrics.csv")).unwrap();
    assert!(after.starts_with(&before), "{before}\n---\n{after}");
    assert_eq!(after.lines().count(), before.lines().count() + 1);
}
