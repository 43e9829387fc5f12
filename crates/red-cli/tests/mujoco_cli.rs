//! `red-cli mujoco expert / train / eval / table` end to end on Reacher with
//! a tiny budget: an expert and its demo file, imitation runs that stop
//! (as on Ctrl-C) and resume to the same numbers as uninterrupted runs, the
//! evaluation of a saved policy, the table, and clear refusals.

use std::path::Path;
use std::process::{Command, Output};

fn cli(args: &[&str], out: &Path) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_red-cli"));
    c.arg("mujoco").args(args);
    if args[0] != "eval" {
        c.arg("--out-dir").arg(out);
    }
    c.output().unwrap()
}

fn ok(o: &Output) -> String {
    assert!(
        o.status.success(),
        "stdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Small batches keep the test quick; the rest are the task's defaults.
fn small_config(dir: &Path) -> String {
    let p = dir.join("small.json");
    std::fs::write(
        &p,
        r#"{"trpo": {"steps_per_batch": 256}, "rnd": {"epochs": 20}, "autoencoder": {"epochs": 20}}"#,
    )
    .unwrap();
    p.display().to_string()
}

/// metrics.csv without its wall-time column.
fn metrics_without_time(run: &Path) -> Vec<String> {
    std::fs::read_to_string(run.join("metrics.csv"))
        .unwrap()
        .lines()
        .map(|l| l.rsplit_once(',').unwrap().0.to_string())
        .collect()
}

fn eval_returns(run: &Path) -> (Vec<f64>, Option<Vec<f64>>) {
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("eval.json")).unwrap()).unwrap();
    let returns = |x: &serde_json::Value| -> Vec<f64> {
        x["returns"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r.as_f64().unwrap())
            .collect()
    };
    let best = (!v["best_checkpoint"].is_null()).then(|| returns(&v["best_checkpoint"]));
    (returns(&v["final_policy"]), best)
}

#[test]
fn expert_train_interrupt_resume_eval_and_table() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path();
    let small = small_config(out);

    // Expert: policy and a 4-trajectory demo file of Reacher's 50 steps.
    let s = ok(&cli(
        &[
            "expert",
            "--env",
            "reacher",
            "--steps",
            "1024",
            "--config",
            &small,
            "--eval-episodes",
            "2",
        ],
        out,
    ));
    assert!(s.contains("demonstrations written"), "{s}");
    let demo: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("expert-reacher/demos.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(demo["env_id"], "Reacher-v5");
    let trajs = demo["trajectories"].as_array().unwrap();
    assert_eq!(trajs.len(), 4);
    assert!(
        trajs
            .iter()
            .all(|t| t["actions"].as_array().unwrap().len() == 50)
    );
    assert!(out.join("expert-reacher/expert_policy.json").is_file());

    for method in ["red", "gail"] {
        let common = [
            "train",
            "--env",
            "reacher",
            "--method",
            method,
            "--steps",
            "1024",
            "--seed",
            "3",
            "--config",
            &small,
            "--checkpoint-every",
            "1",
            "--eval-episodes",
            "3",
        ];
        let full = format!("{method}-full");
        let split = format!("{method}-split");
        let mut a: Vec<&str> = common.to_vec();
        a.extend(["--name", &full]);
        ok(&cli(&a, out));

        // Stopped after 2 of 4 iterations as Ctrl-C would, then resumed.
        let mut b: Vec<&str> = common.to_vec();
        b.extend(["--name", &split, "--stop-after-iterations", "2"]);
        let s = ok(&cli(&b, out));
        assert!(s.contains("interrupted"), "{s}");
        assert!(out.join(&split).join("checkpoint.json").is_file());
        assert!(!out.join(&split).join("eval.json").exists());
        let split_dir = out.join(&split).display().to_string();
        let s = ok(&cli(&["train", "--resume", &split_dir], out));
        assert!(s.contains("final policy (1024 env steps)"), "{s}");

        assert_eq!(
            metrics_without_time(&out.join(&full)),
            metrics_without_time(&out.join(&split)),
            "{method}: resumed metrics differ"
        );
        assert_eq!(metrics_without_time(&out.join(&full)).len(), 5);
        assert_eq!(
            eval_returns(&out.join(&full)),
            eval_returns(&out.join(&split)),
            "{method}: resumed evaluation differs"
        );
        assert!(out.join(&split).join("best_policy.json").is_file());
    }

    // The evaluation command reproduces the run's own evaluation (same
    // seed, same episodes).
    let (final_returns, _) = eval_returns(&out.join("red-split"));
    let mean = final_returns.iter().sum::<f64>() / final_returns.len() as f64;
    let policy = out.join("red-split/policy.json").display().to_string();
    let eval = |extra: &[&str]| {
        let mut args = vec![
            "eval",
            "--policy",
            &policy,
            "--env",
            "reacher",
            "--episodes",
            "3",
            "--seed",
            "3",
        ];
        args.extend_from_slice(extra);
        ok(&cli(&args, out))
    };
    let s = eval(&[]);
    assert!(s.contains(&format!("{mean:.2} +-")), "{s} vs {mean}");
    // Sampled actions: reproducible, labelled, and not the mean's return.
    let sampled = |name: &str| {
        let json = out.join(name);
        let s = eval(&["--stochastic", "--out", json.to_str().unwrap()]);
        assert!(s.contains("sampled actions"), "{s}");
        let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        assert_eq!(v["actions"], "sampled");
        v["mean"].as_f64().unwrap()
    };
    let m1 = sampled("s1.json");
    assert_eq!(m1, sampled("s2.json"));
    assert_ne!(format!("{m1:.2}"), format!("{mean:.2}"));

    // A table over the finished grid: BC runs, the expert row, the curve.
    let s = ok(&cli(
        &[
            "table",
            "--envs",
            "reacher",
            "--methods",
            "bc",
            "--steps",
            "1024",
            "--eval-episodes",
            "2",
            "--name",
            "grid",
        ],
        out,
    ));
    assert!(s.contains("| BC |") && s.contains("Expert"), "{s}");
    assert!(out.join("grid/table.csv").is_file());
}

#[test]
fn refusals_name_the_problem() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path();
    // No demonstrations at the default place.
    let o = cli(
        &[
            "train", "--env", "hopper", "--method", "red", "--steps", "10",
        ],
        out,
    );
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("demos.json"), "{e}");
    // An unknown config field is refused, naming it.
    let bad = out.join("bad.json");
    std::fs::write(&bad, r#"{"trpo": {"max_kll": 0.1}}"#).unwrap();
    let o = cli(
        &[
            "expert",
            "--env",
            "reacher",
            "--config",
            bad.to_str().unwrap(),
        ],
        out,
    );
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("max_kll"), "{e}");
    // A bad value is refused, naming the field.
    std::fs::write(&bad, r#"{"eval_episodes": 0}"#).unwrap();
    let o = cli(
        &[
            "expert",
            "--env",
            "reacher",
            "--config",
            bad.to_str().unwrap(),
        ],
        out,
    );
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("eval_episodes"), "{e}");
    // Resuming something that is not a run.
    let o = cli(&["train", "--resume", out.to_str().unwrap()], out);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("config.json"), "{e}");
    // An unknown task is refused, naming the known ones.
    let mut c = Command::new(env!("CARGO_BIN_EXE_red-cli"));
    let o = c
        .args(["mujoco", "check", "--env", "Humanoid-v5", "--steps", "10"])
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("Hopper-v5"), "{e}");
}

/// A SAC expert on Reacher with tiny networks: its demo file, a run stopped
/// (as on Ctrl-C) that resumes to the numbers of an uninterrupted one; then
/// RED trained by SAC on those demos, stopped and resumed the same way, and
/// SAC refused for GAIL.
#[test]
fn sac_expert_interrupts_resumes_and_writes_demos() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path();
    let cfg = out.join("sac.json");
    std::fs::write(
        &cfg,
        r#"{"sac": {"learner": {"hidden": [16, 16], "batch_size": 32, "random_steps": 300,
            "learning_starts": 300}, "policy": {"hidden": [16, 16]}, "checkpoint_steps": 500}}"#,
    )
    .unwrap();
    let cfg = cfg.display().to_string();
    let common = [
        "expert",
        "--env",
        "reacher",
        "--learner",
        "sac",
        "--steps",
        "1500",
        "--seed",
        "2",
        "--config",
        &cfg,
        "--eval-episodes",
        "2",
    ];
    let mut a = common.to_vec();
    a.extend(["--name", "full"]);
    let s = ok(&cli(&a, out));
    assert!(s.contains("demonstrations written"), "{s}");
    let conf: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("full/config.json")).unwrap())
            .unwrap();
    assert_eq!(conf["learner"], "sac");
    let demo: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("full/demos.json")).unwrap())
            .unwrap();
    assert_eq!(demo["trajectories"].as_array().unwrap().len(), 4);
    // 1500 steps of 50-step episodes: a metrics row per episode.
    assert_eq!(metrics_without_time(&out.join("full")).len(), 1 + 30);

    let mut b = common.to_vec();
    b.extend(["--name", "split", "--stop-after-iterations", "1"]);
    let s = ok(&cli(&b, out));
    assert!(s.contains("interrupted"), "{s}");
    assert!(!out.join("split/eval.json").exists());
    let split = out.join("split").display().to_string();
    ok(&cli(&["expert", "--resume", &split], out));
    assert_eq!(
        eval_returns(&out.join("full")),
        eval_returns(&out.join("split"))
    );
    assert_eq!(
        metrics_without_time(&out.join("full")),
        metrics_without_time(&out.join("split"))
    );
    assert_eq!(
        std::fs::read_to_string(out.join("full/demos.json")).unwrap(),
        std::fs::read_to_string(out.join("split/demos.json")).unwrap()
    );

    // RED trained by SAC on the expert's demos: its reward fitted once, a
    // stop that resumes to the numbers of an uninterrupted run, the
    // imitation return in metrics.csv; GAIL's adaptive reward is refused.
    let demo_path = out.join("full/demos.json").display().to_string();
    let red = |name: &str, extra: &[&str]| {
        let mut v = vec![
            "train",
            "--env",
            "reacher",
            "--method",
            "red",
            "--learner",
            "sac",
            "--demo",
            &demo_path,
            "--steps",
            "1500",
            "--seed",
            "1",
            "--config",
            &cfg,
            "--eval-episodes",
            "2",
            "--name",
            name,
        ];
        v.extend_from_slice(extra);
        cli(&v, out)
    };
    let o = red("red-full", &[]);
    ok(&o);
    let notes = String::from_utf8_lossy(&o.stderr);
    assert!(notes.contains("fitted on 200 expert pairs"), "{notes}");
    let s = ok(&red("red-split", &["--stop-after-iterations", "1"]));
    assert!(s.contains("interrupted"), "{s}");
    let split = out.join("red-split").display().to_string();
    ok(&cli(&["train", "--resume", &split], out));
    assert_eq!(
        eval_returns(&out.join("red-full")),
        eval_returns(&out.join("red-split"))
    );
    let rows = metrics_without_time(&out.join("red-full"));
    assert_eq!(rows, metrics_without_time(&out.join("red-split")));
    assert!(rows[0].ends_with("imitation_return"), "{}", rows[0]);
    // RED's reward lies in (0, 1]: a 50-step episode earns at most 50.
    for r in &rows[1..] {
        let imitation: f64 = r.rsplit_once(',').unwrap().1.parse().unwrap();
        assert!(imitation > 0.0 && imitation <= 50.0, "{r}");
    }
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("red-full/eval.json")).unwrap())
            .unwrap();
    assert!(
        v["demo_mean_imitation_reward"].as_f64().unwrap() > 0.5,
        "{v}"
    );
    assert!(!out.join("red-full/demos.json").exists());
    // SAC starts from a random policy: RED's TRPO warm start is dropped
    // from the task's defaults, and refused when a config file asks for it.
    let conf: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("red-full/config.json")).unwrap())
            .unwrap();
    assert_eq!(conf["bc_warm_start_epochs"], 0);
    let warm = out.join("sac-warm.json");
    std::fs::write(&warm, r#"{"learner": "sac", "bc_warm_start_epochs": 100}"#).unwrap();
    let o = cli(
        &[
            "train",
            "--env",
            "reacher",
            "--method",
            "red",
            "--demo",
            &demo_path,
            "--config",
            &warm.display().to_string(),
        ],
        out,
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("bc_warm_start_epochs"),
        "{err}"
    );
    let o = cli(
        &[
            "train",
            "--env",
            "reacher",
            "--method",
            "gail",
            "--learner",
            "sac",
            "--demo",
            &demo_path,
        ],
        out,
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("`gail` trains with TRPO"),
        "{err}"
    );
}
