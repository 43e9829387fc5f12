//! `red-cli toy` end to end on a tiny configuration: outputs exist, the
//! same seed gives the same metrics, and bad arguments are refused.

use std::path::Path;
use std::process::Command;

fn run_toy(dir: &Path, name: &str, seed: &str) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_red-cli"))
        .args([
            "toy",
            "--runs-dir",
            dir.to_str().expect("utf-8 temp path"),
            "--name",
            name,
            "--n",
            "5,20",
            "--seeds",
            "2",
            "--seed",
            seed,
            "--steps",
            "1200",
            "--eval-interval",
            "400",
            "--epochs",
            "20",
            "--quiet",
        ])
        .output()
        .expect("red-cli runs")
}

#[test]
fn tiny_toy_run_is_complete_and_reproducible() {
    let dir = tempfile::tempdir().expect("temp dir");
    let a = run_toy(dir.path(), "a", "3");
    assert!(
        a.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&a.stderr)
    );
    let b = run_toy(dir.path(), "b", "3");
    assert!(
        b.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&b.stderr)
    );

    let out_a = dir.path().join("a");
    for f in [
        "config.json",
        "metrics.csv",
        "final.csv",
        "learned_reward.csv",
        "results.md",
        "fig2_true_reward.png",
        "fig3_learned_reward.png",
    ] {
        let p = out_a.join(f);
        assert!(p.is_file(), "missing {}", p.display());
        assert!(
            std::fs::metadata(&p).expect("metadata").len() > 0,
            "empty {}",
            p.display()
        );
    }
    let metrics_a = std::fs::read_to_string(out_a.join("metrics.csv")).expect("metrics a");
    let metrics_b = std::fs::read_to_string(dir.path().join("b/metrics.csv")).expect("metrics b");
    assert_eq!(metrics_a, metrics_b, "same seed, different metrics");
    // 4 methods x 2 sizes x 2 seeds x (1 initial + 3 evaluations) rows + header.
    assert_eq!(metrics_a.lines().count(), 1 + 4 * 2 * 2 * 4);
    let stdout = String::from_utf8_lossy(&a.stdout);
    for m in ["RED", "AE", "GAIL", "GMMIL"] {
        assert!(
            stdout.contains(&format!("| {m} |")),
            "table lacks {m}: {stdout}"
        );
    }

    let c = run_toy(dir.path(), "c", "4");
    assert!(c.status.success());
    let metrics_c = std::fs::read_to_string(dir.path().join("c/metrics.csv")).expect("metrics c");
    assert_ne!(metrics_a, metrics_c, "another seed gave identical metrics");
}

#[test]
fn bad_arguments_are_refused_with_the_flag_named() {
    let out = Command::new(env!("CARGO_BIN_EXE_red-cli"))
        .args(["toy", "--gamma", "1.5", "--quiet"])
        .output()
        .expect("red-cli runs");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--gamma"));
    let out = Command::new(env!("CARGO_BIN_EXE_red-cli"))
        .args(["toy", "--n", "0", "--quiet"])
        .output()
        .expect("red-cli runs");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--n"));
}

/// A toy run with many short runs on one thread, so that it can be stopped
/// part-way through.
fn slow_toy(dir: &Path, name: &str) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_red-cli"));
    cmd.args([
        "toy",
        "--runs-dir",
        dir.to_str().expect("utf-8 temp path"),
        "--name",
        name,
        "--n",
        "5,10",
        "--seeds",
        "3",
        "--seed",
        "7",
        "--steps",
        "1500",
        "--eval-interval",
        "500",
        "--epochs",
        "20",
        "--threads",
        "1",
        "--quiet",
    ]);
    cmd
}

/// Starts `cmd`, waits for its first checkpoint, sends `signal` and waits
/// for the process to end.
fn stop_after_first_checkpoint(
    mut cmd: Command,
    checkpoint: &Path,
    signal: &str,
) -> std::process::ExitStatus {
    let mut child = cmd.spawn().expect("red-cli starts");
    let t0 = std::time::Instant::now();
    while !checkpoint.exists() {
        assert!(t0.elapsed().as_secs() < 120, "no checkpoint after 120 s");
        if let Some(status) = child.try_wait().expect("wait") {
            panic!("the run ended ({status}) before its first checkpoint");
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let kill = Command::new("kill")
        .args([signal, &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(kill.success());
    child.wait().expect("wait")
}

fn resume(dir: &Path, name: &str) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_red-cli"))
        .args(["toy", "--quiet", "--resume"])
        .arg(dir.join(name))
        .output()
        .expect("red-cli runs")
}

#[test]
fn interrupted_and_killed_runs_resume_to_the_same_numbers() {
    let dir = tempfile::tempdir().expect("temp dir");
    let full = slow_toy(dir.path(), "full").output().expect("red-cli runs");
    assert!(
        full.status.success(),
        "{}",
        String::from_utf8_lossy(&full.stderr)
    );
    let expected = std::fs::read_to_string(dir.path().join("full/metrics.csv")).expect("metrics");

    for (name, signal) in [("ctrl-c", "-INT"), ("killed", "-KILL")] {
        let checkpoint = dir.path().join(name).join("checkpoint.json");
        let status = stop_after_first_checkpoint(slow_toy(dir.path(), name), &checkpoint, signal);
        assert!(!status.success(), "{name}: the run was not stopped");
        if signal == "-INT" {
            assert_eq!(status.code(), Some(130), "Ctrl-C exits with 130");
        }
        assert!(
            !dir.path().join(name).join("metrics.csv").exists(),
            "{name}: a stopped run wrote final outputs"
        );
        // The checkpoint left behind is whole and readable.
        let text = std::fs::read_to_string(&checkpoint).expect("checkpoint");
        let v: serde_json::Value = serde_json::from_str(&text).expect("a whole JSON file");
        let runs = v["state"]["results"].as_array().expect("results");
        let saved = runs.iter().filter(|r| !r.is_null()).count();
        assert!(
            saved >= 1 && saved < runs.len(),
            "{name}: {saved} of {} saved",
            runs.len()
        );

        let out = resume(dir.path(), name);
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(String::from_utf8_lossy(&out.stderr).contains("already done"));
        let got =
            std::fs::read_to_string(dir.path().join(name).join("metrics.csv")).expect("metrics");
        assert_eq!(
            got, expected,
            "{name}: resumed run differs from the uninterrupted one"
        );
    }
}

#[test]
fn resume_refuses_a_folder_without_a_toy_checkpoint() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = resume(dir.path(), "nothing-here");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("cannot resume") && err.contains("checkpoint.json"),
        "{err}"
    );
    std::fs::create_dir_all(dir.path().join("other")).expect("dir");
    std::fs::write(
        dir.path().join("other/checkpoint.json"),
        r#"{"format":"red-checkpoint","version":1,"kind":"drive","state":{}}"#,
    )
    .expect("write");
    let out = resume(dir.path(), "other");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("not a `toy` run"));
}

/// `red-cli toy --resume` on byte-mutated checkpoints of a finished tiny
/// run: the command must end without a panic (exit status 101) or a hang,
/// and its errors name the file or the setting at fault. Inputs:
/// `RED_FUZZ_CASES / 30` (default 50); each one starts a process.
#[test]
fn mutated_toy_checkpoints_never_panic() {
    let dir = tempfile::tempdir().expect("temp dir");
    let made = Command::new(env!("CARGO_BIN_EXE_red-cli"))
        .args([
            "toy",
            "--n",
            "3",
            "--methods",
            "red",
            "--seeds",
            "1",
            "--steps",
            "100",
        ])
        .args([
            "--eval-interval",
            "100",
            "--epochs",
            "2",
            "--quiet",
            "--runs-dir",
        ])
        .arg(dir.path())
        .args(["--name", "seed"])
        .output()
        .expect("red-cli runs");
    assert!(
        made.status.success(),
        "{}",
        String::from_utf8_lossy(&made.stderr)
    );
    let seed = std::fs::read(dir.path().join("seed/checkpoint.json")).expect("checkpoint");
    let n = std::env::var("RED_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
        .unwrap_or(1_500)
        / 30;
    let mut state = 0x9e37_79b9_7f4a_7c15_u64;
    let mut next = move || {
        // xorshift64*: enough to pick edits; the test needs no rand crate.
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        state.wrapping_mul(0x2545_f491_4f6c_dd1d)
    };
    let mut ok = 0;
    for k in 0..n {
        let mut bytes = seed.clone();
        for _ in 0..1 + next() % 4 {
            let at = (next() as usize) % bytes.len().max(1);
            match next() % 4 {
                0 if !bytes.is_empty() => bytes[at] ^= 1 << (next() % 8),
                1 if !bytes.is_empty() => {
                    bytes[at] = b"0123456789-.e,:{}[]\"n"[(next() % 20) as usize]
                }
                2 => bytes.insert(at.min(bytes.len()), (next() % 256) as u8),
                _ => bytes.truncate(at),
            }
        }
        let run = dir.path().join(format!("case{k}"));
        std::fs::create_dir_all(&run).expect("dir");
        std::fs::write(run.join("checkpoint.json"), &bytes).expect("write");
        let start = std::time::Instant::now();
        let out = Command::new(env!("CARGO_BIN_EXE_red-cli"))
            .args(["toy", "--quiet", "--resume"])
            .arg(&run)
            .output()
            .expect("red-cli runs");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_ne!(out.status.code(), Some(101), "case {k} panicked: {stderr}");
        assert!(
            start.elapsed().as_secs() < 60,
            "case {k} took {:?}",
            start.elapsed()
        );
        if out.status.success() {
            ok += 1;
        } else {
            assert!(
                stderr.contains("checkpoint.json") || stderr.contains("--"),
                "case {k}: the error names neither the file nor a setting: {stderr}"
            );
        }
        std::fs::remove_dir_all(&run).expect("clean");
    }
    println!(
        "fuzz toy checkpoint through the CLI: {n} inputs, {ok} resumed without error, none panicked"
    );
}
