//! Runs and inputs that cannot lose or mix results (issue 20), through the
//! binary as a user meets them: plain run names, a folder holding a run
//! refused (`--resume` / `--force`), the run lock, failed writes that say
//! how to finish, checkpoints that were edited or hold nonsense, demo values
//! too large for the networks, a byte-order mark, SIGTERM and SIGHUP, and
//! zero-valued flags.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The binary under test; `RED_CLI_BIN` runs the same cases against
/// another build (for example main's, to see which fail there).
fn red() -> Command {
    Command::new(
        std::env::var_os("RED_CLI_BIN").unwrap_or_else(|| env!("CARGO_BIN_EXE_red-cli").into()),
    )
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn ok(o: &Output) {
    assert!(o.status.success(), "status {:?}\n{}", o.status, stderr(o));
}

fn refused(o: &Output, words: &[&str]) -> String {
    let err = stderr(o);
    assert!(!o.status.success(), "accepted:\n{err}");
    assert_ne!(o.status.code(), Some(101), "panicked:\n{err}");
    for w in words {
        assert!(err.contains(w), "`{w}` missing from:\n{err}");
    }
    err
}

/// A tiny toy grid (about a second).
fn toy(dir: &Path, name: &str, extra: &[&str]) -> Output {
    red()
        .args(["toy", "--runs-dir"])
        .arg(dir)
        .args([
            "--name",
            name,
            "--n",
            "5",
            "--methods",
            "red",
            "--seeds",
            "2",
        ])
        .args(["--steps", "300", "--eval-interval", "100", "--epochs", "5"])
        .args(["--quiet"])
        .args(extra)
        .output()
        .unwrap()
}

/// A toy grid of many short runs on one thread, to be stopped part-way.
fn slow_toy(dir: &Path, name: &str) -> Command {
    let mut cmd = red();
    cmd.args(["toy", "--runs-dir"])
        .arg(dir)
        .args(["--name", name, "--n", "5,10", "--seeds", "3"])
        .args([
            "--steps",
            "1500",
            "--eval-interval",
            "500",
            "--epochs",
            "20",
        ])
        .args(["--threads", "1", "--quiet"]);
    cmd
}

fn toy_resume(run: &Path) -> Output {
    red()
        .args(["toy", "--quiet", "--resume"])
        .arg(run)
        .output()
        .unwrap()
}

fn wait_for(path: &Path, child: &mut std::process::Child) {
    let t0 = std::time::Instant::now();
    while !path.exists() {
        assert!(
            t0.elapsed().as_secs() < 120,
            "no {} after 120 s",
            path.display()
        );
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the run ended ({status}) before {}", path.display());
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
}

fn demo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/drive-scripted-expert.json")
}

const TINY: &str = r#"{
  "policy": {"hidden": [16], "init_log_std": -2.0},
  "svg": {"hidden": [16], "learning_starts": 100, "policy_delay": 100, "batch_size": 16},
  "sigma1": {"folds": 2},
  "reward_update_pairs": 150,
  "select_every": 200,
  "select_episodes": 1
}"#;

/// `red-cli drive` with tiny settings, outputs in `dir`.
fn drive(dir: &Path, args: &[&str]) -> Output {
    let cfg = dir.join("tiny.json");
    std::fs::write(&cfg, TINY).unwrap();
    red()
        .args(["drive", "--train-config"])
        .arg(&cfg)
        .args(["--rnd-epochs", "2", "--bc-epochs", "3", "--eval-runs", "1"])
        .args(["--eval-roads", "0", "--out-dir"])
        .arg(dir)
        .args(args)
        .output()
        .unwrap()
}

/// A drive run of RED interrupted at step 250 of 400: its checkpoint.
fn interrupted_drive(dir: &Path, name: &str) -> PathBuf {
    let demo = demo();
    let o = drive(
        dir,
        &[
            "--demo",
            demo.to_str().unwrap(),
            "--methods",
            "red",
            "--steps",
            "400",
            "--name",
            name,
            "--checkpoint-every",
            "150",
            "--interrupt-after",
            "250",
        ],
    );
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    dir.join(name)
}

fn drive_resume(dir: &Path, run: &Path) -> Output {
    drive(dir, &["--resume", run.to_str().unwrap()])
}

// ---- 1. run names -------------------------------------------------------

#[test]
fn run_names_that_are_not_plain_are_refused_everywhere() {
    let dir = tempfile::tempdir().unwrap();
    let runs = dir.path().join("runs");
    std::fs::create_dir(&runs).unwrap();
    let abs = dir.path().join("abs");
    let abs = abs.to_str().unwrap();
    let demo = demo();
    for name in ["../escape", "", ".", "..", "a/b", abs] {
        let o = toy(&runs, name, &[]);
        refused(&o, &["name"]);
        let o = drive(
            &runs,
            &[
                "--demo",
                demo.to_str().unwrap(),
                "--name",
                name,
                "--steps",
                "10",
            ],
        );
        refused(&o, &["name"]);
        let o = red()
            .args(["mujoco", "expert", "--env", "reacher", "--steps", "10"])
            .arg("--out-dir")
            .arg(&runs)
            .args(["--name", name])
            .output()
            .unwrap();
        refused(&o, &["name"]);
    }
    // Nothing was written outside the runs folder, nor into it as a run.
    assert!(!dir.path().join("escape").exists());
    assert!(!dir.path().join("abs").exists());
    let inside: Vec<_> = std::fs::read_dir(&runs)
        .map(|d| d.map(|e| e.unwrap().file_name()).collect())
        .unwrap_or_default();
    assert!(
        inside.iter().all(|n| n == "tiny.json"),
        "left in runs/: {inside:?}"
    );
}

// ---- 2. a folder holding a run ------------------------------------------

#[test]
fn a_new_run_refuses_an_existing_run_and_force_moves_it_aside() {
    let dir = tempfile::tempdir().unwrap();
    let first = toy(dir.path(), "A", &["--seed", "1"]);
    ok(&first);
    let run = dir.path().join("A");
    let metrics = std::fs::read(run.join("metrics.csv")).unwrap();
    // Same name again: refused, nothing touched.
    let again = toy(dir.path(), "A", &["--seed", "2"]);
    refused(&again, &["already holds a run", "--resume", "--force"]);
    assert_eq!(std::fs::read(run.join("metrics.csv")).unwrap(), metrics);
    // --force: the old folder is moved aside whole; the new run is alone.
    let forced = toy(dir.path(), "A", &["--seed", "2", "--force"]);
    ok(&forced);
    assert!(stderr(&forced).contains("A.old-1"), "{}", stderr(&forced));
    let old = dir.path().join("A.old-1");
    assert_eq!(std::fs::read(old.join("metrics.csv")).unwrap(), metrics);
    let new = std::fs::read(run.join("metrics.csv")).unwrap();
    assert_ne!(new, metrics, "the new run (seed 2) wrote its own numbers");
    let config = std::fs::read_to_string(run.join("config.json")).unwrap();
    assert!(config.contains("\"seed\": 2"), "{config}");
}

#[test]
fn a_new_drive_run_never_deletes_an_interrupted_ones_checkpoint() {
    let dir = tempfile::tempdir().unwrap();
    let run = interrupted_drive(dir.path(), "same");
    let checkpoint = std::fs::read(run.join("checkpoint.json")).unwrap();
    let demo = demo();
    let o = drive(
        dir.path(),
        &[
            "--demo",
            demo.to_str().unwrap(),
            "--methods",
            "bc",
            "--name",
            "same",
        ],
    );
    refused(&o, &["already holds a run", "--resume", "--force"]);
    assert_eq!(
        std::fs::read(run.join("checkpoint.json")).unwrap(),
        checkpoint
    );
    assert!(!run.join("eval.json").exists(), "no output of another run");
    // It can still be finished.
    ok(&drive_resume(dir.path(), &run));
    assert!(run.join("eval.json").exists());
}

// ---- 3. the lock ---------------------------------------------------------

#[test]
fn a_second_run_on_a_running_folder_is_refused_and_a_stale_lock_taken_over() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("L");
    let mut first = slow_toy(dir.path(), "L").spawn().unwrap();
    wait_for(&run.join("run.lock"), &mut first);
    let pid = first.id().to_string();
    let second = toy(dir.path(), "L", &[]);
    refused(&second, &["in use", &pid]);
    let forced = toy(dir.path(), "L", &["--force"]);
    refused(&forced, &["in use", &pid]);
    let resumed = toy_resume(&run);
    refused(&resumed, &["in use", &pid]);
    // Killed without a chance to clean up: the lock names a dead process.
    wait_for(&run.join("checkpoint.json"), &mut first);
    first.kill().unwrap();
    first.wait().unwrap();
    assert!(run.join("run.lock").exists());
    let resumed = toy_resume(&run);
    ok(&resumed);
    let err = stderr(&resumed);
    assert!(
        err.contains("took over the lock") && err.contains(&pid),
        "{err}"
    );
    assert!(!run.join("run.lock").exists(), "released at the end");
}

// ---- 4. failed writes ----------------------------------------------------

#[test]
fn a_failed_output_write_names_the_file_and_resume_finishes_the_run() {
    let dir = tempfile::tempdir().unwrap();
    ok(&toy(dir.path(), "W", &[]));
    let run = dir.path().join("W");
    let metrics = std::fs::read(run.join("metrics.csv")).unwrap();
    // metrics.csv cannot be replaced (a folder stands in its place, as a
    // full disk would refuse it).
    std::fs::remove_file(run.join("metrics.csv")).unwrap();
    std::fs::create_dir(run.join("metrics.csv")).unwrap();
    let o = toy_resume(&run);
    refused(&o, &["metrics.csv", "--resume", "checkpoint.json"]);
    std::fs::remove_dir(run.join("metrics.csv")).unwrap();
    ok(&toy_resume(&run));
    assert_eq!(std::fs::read(run.join("metrics.csv")).unwrap(), metrics);

    // drive: eval.json cannot be written at the end of a resumed run.
    let run = interrupted_drive(dir.path(), "D");
    std::fs::create_dir(run.join("eval.json")).unwrap();
    let o = drive_resume(dir.path(), &run);
    refused(&o, &["eval.json", "--resume"]);
    assert!(
        run.join("checkpoint.json").exists(),
        "the checkpoint survives"
    );
    std::fs::remove_dir(run.join("eval.json")).unwrap();
    ok(&drive_resume(dir.path(), &run));
    assert!(std::fs::metadata(run.join("eval.json")).unwrap().len() > 0);
    let left: Vec<String> = std::fs::read_dir(&run)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(left.is_empty(), "temporary files left: {left:?}");
}

// ---- 5. checkpoints ------------------------------------------------------

/// Edits the checkpoint's state with `f` and writes it back with a valid
/// checksum (as a careful forger or a bug would), so only the sanity checks
/// stand in the way.
fn reseal(path: &Path, f: impl FnOnce(&mut serde_json::Value)) {
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    f(&mut v["state"]);
    let config = serde_json::to_string(&v["config"]).unwrap();
    let state = serde_json::to_string(&v["state"]).unwrap();
    v["checksum"] = red_core::checkpoint::checksum(&[config.as_bytes(), state.as_bytes()]).into();
    v["config_hash"] = red_core::checkpoint::checksum(&[config.as_bytes()]).into();
    std::fs::write(path, serde_json::to_string(&v).unwrap()).unwrap();
}

/// An edit of a checkpoint's state.
type Edit = dyn Fn(&mut serde_json::Value);

#[test]
fn edited_or_senseless_checkpoints_are_refused_with_what_differs() {
    let dir = tempfile::tempdir().unwrap();
    let run = interrupted_drive(dir.path(), "C");
    let path = run.join("checkpoint.json");
    let good = std::fs::read_to_string(&path).unwrap();

    // One digit of the warm start's first weight changed: still valid JSON.
    let w = good.find("\"warm_start\"").unwrap();
    let w = w + good[w..].find("\"w\":[").unwrap() + 5;
    let digit = w + good[w..].find(|c: char| ('1'..='9').contains(&c)).unwrap();
    let new = if &good[digit..=digit] == "7" {
        "3"
    } else {
        "7"
    };
    let edited = format!("{}{new}{}", &good[..digit], &good[digit + 1..]);
    assert!(serde_json::from_str::<serde_json::Value>(&edited).is_ok());
    std::fs::write(&path, &edited).unwrap();
    refused(
        &drive_resume(dir.path(), &run),
        &["checksum", "checkpoint.json"],
    );

    let cases: [(&str, &Edit); 3] = [
        ("variance[0] is -1", &|s| {
            s["warm_start"]["normalizer"]["var"][0] = (-1.0).into();
        }),
        ("beyond the run's budget", &|s| {
            s["current"]["svg"]["env_steps"] = 1_000_000_000_000u64.into();
        }),
        ("hidden sizes [32]", &|s| {
            s["config"]["train"]["policy"]["hidden"] = serde_json::json!([32]);
        }),
    ];
    let config = std::fs::read(run.join("config.json")).unwrap();
    for (words, edit) in cases {
        std::fs::write(&path, &good).unwrap();
        reseal(&path, edit);
        let o = drive_resume(dir.path(), &run);
        refused(&o, &[words, "checkpoint.json"]);
        let now = std::fs::read(run.join("config.json")).unwrap();
        assert_eq!(now, config, "config.json rewritten");
    }
    // The intact checkpoint still resumes.
    std::fs::write(&path, &good).unwrap();
    ok(&drive_resume(dir.path(), &run));

    // toy: a finished grid's checkpoint with one number changed.
    ok(&toy(dir.path(), "T", &[]));
    let path = dir.path().join("T/checkpoint.json");
    let text = std::fs::read_to_string(&path).unwrap();
    let at = text.find("\"curve\":[[").unwrap() + 10;
    let mut bytes = text.into_bytes();
    bytes[at] = if bytes[at] == b'1' { b'2' } else { b'1' };
    std::fs::write(&path, bytes).unwrap();
    refused(&toy_resume(&dir.path().join("T")), &["checksum"]);
}

// ---- 6, 7. demo values and the byte-order mark --------------------------

fn edited_demo(dir: &Path, name: &str, f: impl FnOnce(&mut serde_json::Value)) -> PathBuf {
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(demo()).unwrap()).unwrap();
    f(&mut v);
    let p = dir.join(name);
    std::fs::write(&p, serde_json::to_string(&v).unwrap()).unwrap();
    p
}

#[test]
fn huge_demo_values_are_refused_with_file_trajectory_step_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let obs = edited_demo(dir.path(), "obs.json", |v| {
        v["trajectories"][0]["observations"][17][3] = 1e308.into();
    });
    let act = edited_demo(dir.path(), "act.json", |v| {
        v["trajectories"][0]["actions"][5][1] = (-1e20).into();
    });
    for (file, words) in [
        (
            &obs,
            ["obs.json", "trajectory 0, step 17", "observation[3]"],
        ),
        (&act, ["act.json", "trajectory 0, step 5", "action[1]"]),
    ] {
        let o = drive(
            dir.path(),
            &[
                "--demo",
                file.to_str().unwrap(),
                "--name",
                "huge",
                "--steps",
                "10",
            ],
        );
        let err = refused(&o, &words);
        assert!(err.contains("magnitude"), "{err}");
        let o = red().arg("demo").arg(file).output().unwrap();
        refused(&o, &words);
    }
    assert!(!dir.path().join("huge").exists());
}

#[test]
fn a_byte_order_mark_is_skipped() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(demo()).unwrap();
    let p = dir.path().join("bom.json");
    std::fs::write(&p, format!("\u{feff}{text}")).unwrap();
    let o = red().arg("demo").arg(&p).output().unwrap();
    ok(&o);
    assert!(String::from_utf8_lossy(&o.stdout).contains("drive"));
    // A training config with a BOM too.
    let cfg = dir.path().join("train.json");
    std::fs::write(&cfg, format!("\u{feff}{TINY}")).unwrap();
    let o = red()
        .args(["drive", "--demo"])
        .arg(&p)
        .arg("--train-config")
        .arg(&cfg)
        .args(["--methods", "bc", "--bc-epochs", "1", "--eval-runs", "1"])
        .args(["--eval-roads", "0", "--out-dir"])
        .arg(dir.path())
        .output()
        .unwrap();
    ok(&o);
}

// ---- 8. SIGTERM and SIGHUP ----------------------------------------------

#[test]
fn sigterm_and_sighup_save_and_stop_like_ctrl_c() {
    let dir = tempfile::tempdir().unwrap();
    for (signal, name) in [("-TERM", "term"), ("-HUP", "hup")] {
        let run = dir.path().join(name);
        let mut child = slow_toy(dir.path(), name)
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        wait_for(&run.join("checkpoint.json"), &mut child);
        let kill = Command::new("kill")
            .args([signal, &child.id().to_string()])
            .status()
            .unwrap();
        assert!(kill.success());
        let out = child.wait_with_output().unwrap();
        assert_eq!(out.status.code(), Some(130), "{signal}: {}", stderr(&out));
        assert!(stderr(&out).contains("--resume"), "{}", stderr(&out));
        assert!(!run.join("run.lock").exists(), "the lock is released");
        ok(&toy_resume(&run));
        assert!(run.join("metrics.csv").exists());
    }
}

// ---- 9. zero-valued flags ------------------------------------------------

#[test]
fn zero_valued_flags_are_refused_naming_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let demo = demo();
    let d = demo.to_str().unwrap();
    for (args, flag) in [
        (vec!["--steps", "0"], "steps"),
        (vec!["--checkpoint-every", "0"], "checkpoint_every"),
    ] {
        let mut all = vec!["--demo", d, "--name", "zero"];
        all.extend(args);
        refused(&drive(dir.path(), &all), &[flag, "at least 1"]);
    }
    for (args, flag) in [
        (vec!["--threads", "0"], "--threads"),
        (vec!["--steps", "0"], "--steps"),
        (vec!["--seeds", "0"], "--seeds"),
        (vec!["--eval-interval", "0"], "--eval-interval"),
    ] {
        let o = red()
            .args(["toy", "--quiet", "--name", "zero", "--out-dir"])
            .arg(dir.path())
            .args(&args)
            .output()
            .unwrap();
        refused(&o, &[flag, "at least 1"]);
    }
    let runs = dir.path().to_str().unwrap();
    for args in [
        vec!["expert", "--env", "reacher", "--steps", "0"],
        vec!["expert", "--env", "reacher", "--checkpoint-every", "0"],
        vec!["table", "--envs", "reacher", "--steps", "0"],
        vec!["table", "--envs", "reacher", "--checkpoint-every", "0"],
        vec!["table", "--envs", "reacher", "--jobs", "0"],
    ] {
        let o = red()
            .arg("mujoco")
            .args(&args)
            .args(["--out-dir", runs, "--name", "zero"])
            .output()
            .unwrap();
        refused(&o, &["at least 1"]);
    }
    assert!(!dir.path().join("zero").exists(), "no run folder was made");
}
