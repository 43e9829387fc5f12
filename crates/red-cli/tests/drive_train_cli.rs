//! `red-cli drive --demo FILE` end to end with a tiny budget: outputs exist
//! for every method, the same seed gives the same numbers, an interrupted
//! run resumes to the numbers of an uninterrupted one, bad demos and bad
//! resumes are refused clearly.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn demo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/drive-scripted-expert.json")
}

/// Small networks and short warm-ups so every method trains in about a
/// second.
const TINY: &str = r#"{
  "policy": {"hidden": [16], "init_log_std": -2.0},
  "svg": {"hidden": [16], "learning_starts": 100, "policy_delay": 100, "batch_size": 16},
  "gail": {"hidden": [16]},
  "autoencoder": {"hidden": 32},
  "sigma1": {"folds": 2},
  "reward_update_pairs": 150,
  "select_every": 200,
  "select_episodes": 1
}"#;

fn cli(args: &[&str], dir: &Path) -> Output {
    cli_with(TINY, args, dir)
}

/// [`cli`] with another training config.
fn cli_with(train_config: &str, args: &[&str], dir: &Path) -> Output {
    let cfg = dir.join("tiny.json");
    std::fs::write(&cfg, train_config).unwrap();
    Command::new(env!("CARGO_BIN_EXE_red-cli"))
        .args(["drive", "--train-config"])
        .arg(&cfg)
        .args([
            "--rnd-epochs",
            "2",
            "--bc-epochs",
            "3",
            "--eval-runs",
            "2",
            "--eval-roads",
            "2",
        ])
        .arg("--out-dir")
        .arg(dir)
        .args(args)
        .output()
        .unwrap()
}

fn train(dir: &Path, name: &str, methods: &str, extra: &[&str]) -> Output {
    let demo = demo();
    let mut args = vec![
        "--demo",
        demo.to_str().unwrap(),
        "--methods",
        methods,
        "--steps",
        "400",
        "--seed",
        "3",
        "--name",
        name,
    ];
    args.extend_from_slice(extra);
    cli(&args, dir)
}

/// eval.json without its wall time, and metrics.csv.
fn numbers(dir: &Path) -> (serde_json::Value, String) {
    let mut eval: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("eval.json")).unwrap()).unwrap();
    eval.as_object_mut().unwrap().remove("wall_time_s");
    let metrics = std::fs::read_to_string(dir.join("metrics.csv")).unwrap();
    (eval, metrics)
}

fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "status {:?}\n{}",
        o.status,
        String::from_utf8_lossy(&o.stderr)
    );
}

#[test]
fn all_methods_tiny_run_writes_outputs_and_is_reproducible() {
    let dir = tempfile::tempdir().unwrap();
    let a = train(dir.path(), "a", "all", &[]);
    ok(&a);
    let table = String::from_utf8_lossy(&a.stdout);
    for row in [
        "expert", "red", "ae", "gail", "gmmil", "bc", "% road", "TRUE",
    ] {
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
    // A finished run leaves no checkpoint behind.
    assert!(!dir.path().join("a/checkpoint.json").exists());
    let (eval, metrics) = numbers(&dir.path().join("a"));
    let methods = eval["methods"].as_array().unwrap();
    assert_eq!(methods.len(), 5);
    for m in methods {
        let f = &m["final_policy"];
        assert_eq!(f["distances"].as_array().unwrap().len(), 2, "{m}");
        assert_eq!(
            f["unseen_roads"]["track_seeds"].as_array().unwrap().len(),
            2,
            "{m}"
        );
        if m["method"] != "bc" {
            assert!(m["selected_by_own_reward"].is_object(), "{m}");
            assert!(m["best_true_distance_policy"].is_object(), "{m}");
        }
    }
    for m in ["red", "ae", "gail", "gmmil"] {
        assert!(metrics.contains(&format!("{m},train,")), "{metrics}");
        assert!(metrics.contains(&format!("{m},check,")), "{metrics}");
    }
    let config: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("a/config.json")).unwrap())
            .unwrap();
    assert_eq!(config["train"]["steps"], 400);
    assert_eq!(config["seed"], 3);

    let b = train(dir.path(), "b", "all", &[]);
    ok(&b);
    assert_eq!(numbers(&dir.path().join("b")), (eval, metrics));
}

#[test]
fn interrupted_run_resumes_to_the_same_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let whole = train(
        dir.path(),
        "whole",
        "red,gail",
        &["--checkpoint-every", "150"],
    );
    ok(&whole);

    // Interrupted inside RED, then again inside GAIL (an adaptive reward).
    let first = train(
        dir.path(),
        "cut",
        "red,gail",
        &["--checkpoint-every", "150", "--interrupt-after", "250"],
    );
    assert_eq!(
        first.status.code(),
        Some(130),
        "{}",
        String::from_utf8_lossy(&first.stderr)
    );
    let err = String::from_utf8_lossy(&first.stderr);
    assert!(err.contains("--resume"), "{err}");
    let cut = dir.path().join("cut");
    assert!(cut.join("checkpoint.json").exists());
    let resume = |extra: &[&str]| {
        let mut args = vec!["--resume", cut.to_str().unwrap()];
        args.extend_from_slice(extra);
        cli(&args, dir.path())
    };
    // The same step limit now interrupts GAIL once it passes it.
    let second = resume(&["--interrupt-after", "300"]);
    assert_eq!(
        second.status.code(),
        Some(130),
        "{}",
        String::from_utf8_lossy(&second.stderr)
    );
    let last = resume(&[]);
    ok(&last);
    assert_eq!(numbers(&cut), numbers(&dir.path().join("whole")));
}

#[test]
fn sac_learner_runs_and_resumes_to_the_same_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let mut cfg: serde_json::Value = serde_json::from_str(TINY).unwrap();
    cfg["learner"] = "sac".into();
    cfg["sac"] = serde_json::json!({"hidden": [16], "learning_starts": 100, "batch_size": 16});
    let cfg = cfg.to_string();
    let demo = demo();
    let run = |name: &str, extra: &[&str]| {
        let mut args = vec![
            "--demo",
            demo.to_str().unwrap(),
            "--methods",
            "red",
            "--steps",
            "400",
            "--seed",
            "3",
            "--name",
            name,
            "--checkpoint-every",
            "150",
        ];
        args.extend_from_slice(extra);
        cli_with(&cfg, &args, dir.path())
    };
    let whole = run("whole", &[]);
    ok(&whole);
    let config: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("whole/config.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(config["train"]["learner"], "sac");
    let (_, metrics) = numbers(&dir.path().join("whole"));
    assert!(metrics.contains("red,train,"), "{metrics}");
    let first = run("cut", &["--interrupt-after", "250"]);
    assert_eq!(
        first.status.code(),
        Some(130),
        "{}",
        String::from_utf8_lossy(&first.stderr)
    );
    let cut = dir.path().join("cut");
    ok(&cli_with(
        &cfg,
        &["--resume", cut.to_str().unwrap()],
        dir.path(),
    ));
    assert_eq!(numbers(&cut), numbers(&dir.path().join("whole")));
}

#[test]
fn bad_demo_and_bad_resume_are_refused_with_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(demo()).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["env_id"] = serde_json::Value::String("hopper".into());
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, serde_json::to_string(&v).unwrap()).unwrap();
    let out = cli(&["--demo", bad.to_str().unwrap()], dir.path());
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("hopper") && err.contains("drive"), "{err}");

    let none = dir.path().join("nothing-here");
    let out = cli(&["--resume", none.to_str().unwrap()], dir.path());
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("checkpoint.json"), "{err}");

    let out = cli(
        &[
            "--demo",
            demo().to_str().unwrap(),
            "--methods",
            "red,dagger",
        ],
        dir.path(),
    );
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("dagger"));
}

/// A person-like demonstration (key taps through the recorder's key model)
/// on another road (track seed 9), written by `red-cli drive expert --style
/// human`.
fn demo_on_road_9(dir: &Path) -> PathBuf {
    let path = dir.join("road9.json");
    let o = Command::new(env!("CARGO_BIN_EXE_red-cli"))
        .args([
            "drive",
            "expert",
            "--style",
            "human",
            "--track-seed",
            "9",
            "--sig-digits",
            "7",
            "--out",
        ])
        .arg(&path)
        .output()
        .unwrap();
    ok(&o);
    path
}

#[test]
fn a_demo_on_another_road_trains_on_its_road_and_other_roads_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let demo = demo_on_road_9(dir.path());
    let d = demo.to_str().unwrap();
    let o = cli(
        &[
            "--demo",
            d,
            "--methods",
            "bc",
            "--steps",
            "10",
            "--name",
            "r9",
        ],
        dir.path(),
    );
    ok(&o);
    let table = String::from_utf8_lossy(&o.stdout);
    assert!(table.contains("track seed 9"), "{table}");
    let config: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("r9/config.json")).unwrap())
            .unwrap();
    assert_eq!(config["drive"]["track_seed"], 9);
    let eval: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("r9/eval.json")).unwrap())
            .unwrap();
    assert_eq!(eval["track_seed"], 9);
    // Unseen roads never include the demo's own.
    let seeds = eval["unseen_track_seeds"].as_array().unwrap();
    assert!(!seeds.iter().any(|s| s == 9), "{eval}");

    // Another road is refused before any training, naming both.
    let start = std::time::Instant::now();
    let o = cli(
        &[
            "--demo",
            d,
            "--methods",
            "red",
            "--track-seed",
            "4",
            "--name",
            "x",
        ],
        dir.path(),
    );
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("road9.json")
            && err.contains("track_seed: 9 -> 4")
            && err.contains("--other-road"),
        "{err}"
    );
    assert!(!dir.path().join("x").exists(), "nothing was written");
    assert!(start.elapsed().as_secs() < 20);

    // A file without its road, used on the wrong (default) road, is refused
    // with the step where it stops fitting.
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&demo).unwrap()).unwrap();
    v.as_object_mut().unwrap().remove("scenario");
    v["version"] = 1.into();
    let old = dir.path().join("old.json");
    std::fs::write(&old, serde_json::to_string(&v).unwrap()).unwrap();
    let o = cli(
        &["--demo", old.to_str().unwrap(), "--name", "y"],
        dir.path(),
    );
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("records no road") || err.contains("does not fit"),
        "{err}"
    );
    assert!(err.contains("step"), "{err}");
}

#[test]
fn the_table_and_numbers_are_written_when_a_picture_cannot_be() {
    let dir = tempfile::tempdir().unwrap();
    // A new run refuses a folder that holds files, so the run is stopped
    // part-way, a folder is put where the picture should go (the picture
    // cannot be written), and the run is resumed.
    let o = train(dir.path(), "p", "red,bc", &["--interrupt-after", "200"]);
    assert_eq!(o.status.code(), Some(130));
    std::fs::create_dir_all(dir.path().join("p/eval_paths.png/blocked")).unwrap();
    let o = cli(
        &["--resume", dir.path().join("p").to_str().unwrap()],
        dir.path(),
    );
    ok(&o);
    let table = String::from_utf8_lossy(&o.stdout);
    assert!(table.contains("warning: eval_paths.png"), "{table}");
    assert!(table.contains("red") && table.contains("% road"), "{table}");
    let eval: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("p/eval.json")).unwrap())
            .unwrap();
    assert_eq!(eval["methods"].as_array().unwrap().len(), 2);
    assert!(!eval["warnings"].as_array().unwrap().is_empty());
    assert!(
        std::fs::metadata(dir.path().join("p/metrics.csv"))
            .unwrap()
            .len()
            > 0
    );
    assert!(!dir.path().join("p/checkpoint.json").exists());
}

/// `eval_saved` output: `road S...: P% | ...` lines, as (seed, P).
fn road_percents(stdout: &str) -> Vec<(u64, f64)> {
    stdout
        .lines()
        .filter_map(|l| {
            let rest = l.strip_prefix("road ")?;
            let seed = rest.split([' ', ':']).next()?.parse().ok()?;
            let p = rest.split(": ").nth(1)?.split('%').next()?.parse().ok()?;
            Some((seed, p))
        })
        .collect()
}

#[test]
fn a_finished_run_keeps_its_policies_and_eval_saved_drives_them_again() {
    let dir = tempfile::tempdir().unwrap();
    ok(&train(dir.path(), "e", "red,bc", &[]));
    let run = dir.path().join("e");
    for f in [
        "red_policy.json",
        "red_selected_policy.json",
        "bc_policy.json",
    ] {
        assert!(run.join(f).is_file(), "{f} missing");
    }
    let eval: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("eval.json")).unwrap()).unwrap();
    for (method, selected, key) in [
        ("red", false, "final_policy"),
        ("bc", false, "final_policy"),
        ("red", true, "selected_by_own_reward"),
    ] {
        let req = red_experiments::drive::EvalRequest {
            method: method.into(),
            selected,
            ..Default::default()
        };
        let out = red_experiments::drive::eval_saved(&run, &req).unwrap();
        let got = road_percents(&out);
        let m = eval["methods"]
            .as_array()
            .unwrap()
            .iter()
            .find(|m| m["method"] == method)
            .unwrap();
        let want = &m[key];
        // The demo's road first, then the unseen roads, each the number
        // eval.json holds for the same episodes.
        assert_eq!(got.len(), 3, "{out}");
        assert_eq!(got[0].0, eval["track_seed"].as_u64().unwrap(), "{out}");
        let close = |a: f64, b: &serde_json::Value| (a - b.as_f64().unwrap()).abs() < 0.051;
        assert!(close(got[0].1, &want["percent_of_road"]), "{out}\n{want}");
        for (i, (seed, p)) in got[1..].iter().enumerate() {
            assert_eq!(*seed, want["unseen_roads"]["track_seeds"][i], "{out}");
            assert!(
                close(*p, &want["unseen_roads"]["percent_per_road"][i]),
                "{out}\n{want}"
            );
        }
    }
    // One named road, a picture of it, and a method the run did not train.
    let png = dir.path().join("road7.png");
    let req = red_experiments::drive::EvalRequest {
        method: "red".into(),
        roads: vec![7],
        runs: Some(1),
        png: Some(png.clone()),
        ..Default::default()
    };
    let out = red_experiments::drive::eval_saved(&run, &req).unwrap();
    assert_eq!(road_percents(&out).len(), 1, "{out}");
    assert!(out.contains("road 7:"), "{out}");
    assert!(std::fs::metadata(&png).unwrap().len() > 0);
    let req = red_experiments::drive::EvalRequest {
        method: "gail".into(),
        ..Default::default()
    };
    let err = red_experiments::drive::eval_saved(&run, &req)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("gail_policy.json") && err.contains("red, bc"),
        "{err}"
    );
    let err = red_experiments::drive::eval_saved(dir.path(), &req)
        .unwrap_err()
        .to_string();
    assert!(err.contains("config.json"), "{err}");
}

#[test]
fn a_kept_learner_drives_by_lookahead_and_without_candidates_as_its_policy() {
    let dir = tempfile::tempdir().unwrap();
    let kept = TINY.replacen('{', r#"{"keep_learner": true,"#, 1);
    let demo = demo();
    let args = [
        "--demo",
        demo.to_str().unwrap(),
        "--methods",
        "red",
        "--steps",
        "400",
        "--seed",
        "3",
        "--name",
        "k",
    ];
    ok(&cli_with(&kept, &args, dir.path()));
    let run = dir.path().join("k");
    assert!(run.join("red_learner.json").is_file());
    let plain = red_experiments::drive::EvalRequest {
        method: "red".into(),
        ..Default::default()
    };
    let want = road_percents(&red_experiments::drive::eval_saved(&run, &plain).unwrap());
    let ask = |steer: Vec<f64>| red_experiments::drive::EvalRequest {
        lookahead: Some(red_experiments::drive::Lookahead {
            steer,
            horizon: 1,
            ..Default::default()
        }),
        ..plain.clone()
    };
    // No candidates but the policy's own action: the policy's numbers.
    let out = red_experiments::drive::eval_saved(&run, &ask(Vec::new())).unwrap();
    assert!(out.contains("acting by lookahead"), "{out}");
    assert_eq!(road_percents(&out), want, "{out}");
    // With candidates: the same roads, each a percentage.
    let out = red_experiments::drive::eval_saved(&run, &ask(vec![-0.3, 0.3])).unwrap();
    let got = road_percents(&out);
    assert_eq!(got.len(), want.len(), "{out}");
    assert!(got.iter().all(|(_, p)| (0.0..=100.0).contains(p)), "{out}");
    // A zero horizon and a selected policy are refused.
    let mut zero = ask(vec![0.3]);
    zero.lookahead.as_mut().unwrap().horizon = 0;
    let err = red_experiments::drive::eval_saved(&run, &zero)
        .unwrap_err()
        .to_string();
    assert!(err.contains("lookahead.horizon"), "{err}");
    let mut sel = ask(vec![0.3]);
    sel.selected = true;
    let err = red_experiments::drive::eval_saved(&run, &sel)
        .unwrap_err()
        .to_string();
    assert!(err.contains("selected"), "{err}");
    let mut bc = ask(vec![0.3]);
    bc.method = "bc".into();
    assert!(red_experiments::drive::eval_saved(&run, &bc).is_err());
    // A run that kept no learner says how to keep one.
    std::fs::remove_file(run.join("red_learner.json")).unwrap();
    let err = red_experiments::drive::eval_saved(&run, &ask(vec![0.3]))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("red_learner.json") && err.contains("keep_learner"),
        "{err}"
    );
    // SAC keeps no model or value: refused before training.
    let sac = TINY.replacen('{', r#"{"keep_learner": true, "learner": "sac","#, 1);
    let o = cli_with(&sac, &args, dir.path());
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("keep_learner"), "{err}");
}
