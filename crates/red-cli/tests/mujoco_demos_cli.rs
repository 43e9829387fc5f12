//! `red-cli mujoco demos` and `red-cli demo take` end to end on Reacher,
//! with freshly initialised policies saved in the `policy.json` format (no
//! training): each kind of demo set, and the refusals.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use red_core::{DemoSource, Demos};
use red_rl::policy::{GaussianPolicy, GaussianPolicyConfig};

fn cli(args: &[&str], paths: &[(&str, &Path)]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_red-cli"));
    c.args(args);
    for (flag, p) in paths {
        if !flag.is_empty() {
            c.arg(flag);
        }
        c.arg(p);
    }
    c.output().unwrap()
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// A fresh policy of `obs` observations and `act` actions whose output
/// layer is scaled by `scale` (10: means far outside [-1, 1]).
fn policy(dir: &Path, obs: usize, act: usize, scale: f32) -> PathBuf {
    let cfg = GaussianPolicyConfig {
        output_scale: scale,
        ..GaussianPolicyConfig::default()
    };
    let p = GaussianPolicy::new(&cfg, obs, act, None, &mut ChaCha8Rng::seed_from_u64(1)).unwrap();
    let path = dir.join(format!("policy-{obs}x{act}.json"));
    p.save(&path).unwrap();
    path
}

fn demos(policy: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["mujoco", "demos", "--env", "reacher"];
    if !extra.contains(&"--episodes") {
        args.extend(["--episodes", "2"]);
    }
    args.extend_from_slice(extra);
    cli(&args, &[("--policy", policy), ("--out", out)])
}

fn actions(d: &Demos) -> Vec<f64> {
    d.trajectories
        .iter()
        .flat_map(|t| t.actions.iter().flatten().copied())
        .collect()
}

#[test]
fn each_kind_of_demo_set_is_written_as_asked() {
    let dir = tempfile::tempdir().unwrap();
    let p = policy(dir.path(), 10, 2, 10.0);
    let kinds: [(&str, &[&str]); 5] = [
        ("mean-clipped", &[]),
        ("mean-raw", &["--raw-actions"]),
        ("sampled-clipped", &["--sampled"]),
        ("sampled-raw", &["--sampled", "--raw-actions"]),
        ("sampled-clipped-again", &["--sampled"]),
    ];
    let mut got = Vec::new();
    for (name, extra) in kinds {
        let out = dir.path().join(format!("{name}.json"));
        let o = demos(&p, &out, extra);
        assert!(o.status.success(), "{name}: {}", text(&o));
        assert!(text(&o).contains("2 trajectories"), "{}", text(&o));
        let d = Demos::read(&out).unwrap();
        assert_eq!(d.lengths(), [50, 50], "{name}");
        assert_eq!(d.source, Some(DemoSource::Policy));
        let made = d.made_with.clone().unwrap();
        let sampled = extra.contains(&"--sampled");
        let raw = extra.contains(&"--raw-actions");
        assert_eq!(made["actions"], if sampled { "sampled" } else { "mean" });
        assert_eq!(made["stored"], if raw { "raw" } else { "clipped" });
        assert_eq!(made["seed"], 0);
        let beyond = actions(&d).iter().any(|a| a.abs() > 1.0);
        assert_eq!(
            beyond, raw,
            "{name}: raw actions exceed [-1, 1], clipped never"
        );
        got.push((out, d));
    }
    assert_ne!(actions(&got[0].1), actions(&got[2].1), "sampled == mean");
    assert_ne!(actions(&got[1].1), actions(&got[3].1), "sampled == mean");
    // The same seed gives the same file, byte for byte; another seed not.
    assert_eq!(
        std::fs::read(&got[2].0).unwrap(),
        std::fs::read(&got[4].0).unwrap()
    );
    let other = dir.path().join("seed1.json");
    assert!(
        demos(&p, &other, &["--sampled", "--seed", "1"])
            .status
            .success()
    );
    assert_ne!(Demos::read(&other).unwrap(), got[2].1);
    // --max-steps cuts every episode.
    let short = dir.path().join("short.json");
    assert!(demos(&p, &short, &["--max-steps", "9"]).status.success());
    assert_eq!(Demos::read(&short).unwrap().lengths(), [9, 9]);

    // Fewer trajectories: the first one of a file.
    let one = dir.path().join("one.json");
    let o = cli(
        &["demo", "take", "--trajectories", "1"],
        &[("", &got[3].0), ("--out", &one)],
    );
    assert!(o.status.success(), "{}", text(&o));
    let d = Demos::read(&one).unwrap();
    assert_eq!(d.trajectories, got[3].1.trajectories[..1]);
    assert_eq!(d.made_with.unwrap()["source_made_with"]["stored"], "raw");
    let o = cli(
        &["demo", "take", "--trajectories", "3"],
        &[("", &got[3].0), ("--out", &dir.path().join("three.json"))],
    );
    assert!(!o.status.success());
    assert!(
        text(&o).contains("sampled-raw.json") && text(&o).contains("at most 2"),
        "{}",
        text(&o)
    );
}

#[test]
fn bad_inputs_are_refused_naming_the_file_and_the_fix() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.json");
    let missing = dir.path().join("missing-policy.json");
    let hopper = policy(dir.path(), 11, 3, 0.01);
    let reacher = policy(dir.path(), 10, 2, 0.01);
    let cases: [(&Path, &[&str], &[&str]); 3] = [
        (&missing, &[], &["missing-policy.json", "mujoco expert"]),
        (
            &hopper,
            &[],
            &["policy-11x3.json", "Reacher-v5", "trained on"],
        ),
        (&reacher, &["--episodes", "0"], &["episodes", "at least 1"]),
    ];
    for (p, extra, named) in cases {
        let o = demos(p, &out, extra);
        assert!(!o.status.success(), "{}", text(&o));
        for n in named {
            assert!(text(&o).contains(n), "`{n}` missing: {}", text(&o));
        }
        assert!(!out.exists());
    }
    std::fs::write(&out, "keep").unwrap();
    let o = demos(&reacher, &out, &[]);
    assert!(!o.status.success());
    assert!(
        text(&o).contains("out.json") && text(&o).contains("another --out"),
        "{}",
        text(&o)
    );
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "keep");
}
