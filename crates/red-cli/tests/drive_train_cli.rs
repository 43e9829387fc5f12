//! `red-cli drive --demo FILE` end to end with a tiny budget: outputs exist,
//! the same seed gives the same metrics, bad demos are refused clearly.

use std::path::{Path, PathBuf};
use std::process::Command;

fn demo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/drive-scripted-expert.json")
}

fn train(out: &Path, name: &str, seed: u64) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_red-cli"))
        .args(["drive", "--demo"])
        .arg(demo())
        .args(["--steps", "1200", "--rnd-epochs", "2", "--bc-epochs", "3"])
        .args([
            "--eval-runs",
            "2",
            "--seed",
            &seed.to_string(),
            "--name",
            name,
        ])
        .arg("--out-dir")
        .arg(out)
        .output()
        .unwrap()
}

#[test]
fn tiny_run_writes_outputs_and_is_reproducible() {
    let dir = tempfile::tempdir().unwrap();
    let a = train(dir.path(), "a", 3);
    assert!(a.status.success(), "{}", String::from_utf8_lossy(&a.stderr));
    let table = String::from_utf8_lossy(&a.stdout);
    for row in ["expert", "red", "bc", "% road"] {
        assert!(table.contains(row), "{table}");
    }
    for f in [
        "config.json",
        "metrics.csv",
        "eval.json",
        "learning_curve.png",
        "eval_paths.png",
    ] {
        let p = dir.path().join("a").join(f);
        assert!(std::fs::metadata(&p).unwrap().len() > 0, "{}", p.display());
    }
    let metrics = std::fs::read_to_string(dir.path().join("a/metrics.csv")).unwrap();
    assert!(metrics.lines().count() > 1, "{metrics}");
    let eval: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("a/eval.json")).unwrap())
            .unwrap();
    assert_eq!(eval["methods"].as_array().unwrap().len(), 2);
    let b = train(dir.path(), "b", 3);
    assert!(b.status.success());
    let metrics_b = std::fs::read_to_string(dir.path().join("b/metrics.csv")).unwrap();
    assert_eq!(metrics, metrics_b);
}

#[test]
fn bad_demo_is_refused_with_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(demo()).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["env_id"] = serde_json::Value::String("hopper".into());
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, serde_json::to_string(&v).unwrap()).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_red-cli"))
        .args(["drive", "--demo"])
        .arg(&bad)
        .arg("--out-dir")
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("hopper") && err.contains("drive"), "{err}");
}
