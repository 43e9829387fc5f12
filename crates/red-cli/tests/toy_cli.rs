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
