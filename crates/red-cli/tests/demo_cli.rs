//! `red-cli demo import` end to end on the importers' fixtures (made by
//! red-core's `tests/fixtures/make_fixtures.py`), and on bad files: each
//! refusal names the file and writes nothing.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use red_core::import::{read_baselines_npz, read_red_pickle};
use red_core::{DemoSource, Demos};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../red-core/tests/fixtures")
        .join(name)
}

fn import(from: &str, file: &Path, env: &str, out: &Path, extra: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_red-cli"))
        .args(["demo", "import", "--from", from])
        .arg(file)
        .args(["--env", env, "--out"])
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

#[test]
fn both_formats_import_to_the_same_pairs_as_the_library_reads() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "red-pickle",
            "red_p2.pkl",
            read_red_pickle(&fixture("red_p2.pkl"), "Toy-v0", 5),
        ),
        (
            "baselines-npz",
            "baselines_episodes.npz",
            read_baselines_npz(&fixture("baselines_episodes.npz"), "Toy-v0", 1000),
        ),
    ];
    for (from, name, want) in cases {
        let out = dir.path().join(format!("{name}.json"));
        let steps: &[&str] = if from == "red-pickle" {
            &["--steps", "5"]
        } else {
            &[]
        };
        let o = import(from, &fixture(name), "Toy-v0", &out, steps);
        assert!(o.status.success(), "{}", text(&o));
        assert!(text(&o).contains("trajectories"), "{}", text(&o));
        let got = Demos::read(&out).unwrap();
        let want = want.unwrap();
        assert_eq!(got.source, Some(DemoSource::Imported));
        assert_eq!(got.env_id, "Toy-v0");
        assert_eq!(got.trajectories.len(), want.trajectories.len());
        for (g, w) in got.trajectories.iter().zip(&want.trajectories) {
            assert_eq!(g.observations, w.observations);
            assert_eq!(g.actions, w.actions);
            assert_eq!(g.end, w.end);
        }
    }
}

#[test]
fn bad_files_and_bad_arguments_are_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.json");
    // A truncated pickle and a truncated npz.
    let pkl = std::fs::read(fixture("red_p2.pkl")).unwrap();
    let short = dir.path().join("short.pkl");
    std::fs::write(&short, &pkl[..pkl.len() / 2]).unwrap();
    let npz = std::fs::read(fixture("baselines_episodes.npz")).unwrap();
    let corrupt = dir.path().join("corrupt.npz");
    std::fs::write(&corrupt, &npz[..npz.len() * 2 / 3]).unwrap();
    let cases: [(&str, PathBuf, &str, &str); 6] = [
        ("red-pickle", short.clone(), "Toy-v0", "short.pkl"),
        ("baselines-npz", corrupt, "Toy-v0", "corrupt.npz"),
        // Returns that do not match the rewards.
        (
            "baselines-npz",
            fixture("baselines_bad_rets.npz"),
            "Toy-v0",
            "baselines_bad_rets.npz",
        ),
        // A pickle given as an npz.
        (
            "baselines-npz",
            fixture("red_p2.pkl"),
            "Toy-v0",
            "red_p2.pkl",
        ),
        (
            "hdf5",
            fixture("red_p2.pkl"),
            "Toy-v0",
            "red-pickle, baselines-npz",
        ),
        (
            "red-pickle",
            dir.path().join("missing.pkl"),
            "Toy-v0",
            "missing.pkl",
        ),
    ];
    for (from, file, env, named) in cases {
        let o = import(from, &file, env, &out, &["--steps", "5"]);
        assert!(
            !o.status.success(),
            "{from} {}: {}",
            file.display(),
            text(&o)
        );
        assert!(text(&o).contains(named), "{from}: {}", text(&o));
        assert!(!out.exists(), "{from}: wrote {}", out.display());
    }
    // An existing --out is never overwritten.
    std::fs::write(&out, "keep").unwrap();
    let o = import(
        "red-pickle",
        &fixture("red_p2.pkl"),
        "Toy-v0",
        &out,
        &["--steps", "5"],
    );
    assert!(!o.status.success());
    assert!(text(&o).contains("exists"), "{}", text(&o));
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "keep");
}

#[test]
fn a_mujoco_task_is_named_by_its_gymnasium_id_and_its_dimensions_checked() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("hopper.json");
    let o = import(
        "red-pickle",
        &fixture("red_p2.pkl"),
        "hopper",
        &out,
        &["--steps", "5"],
    );
    assert!(!o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("Hopper-v5 has obs 11 x act 3"),
        "{}",
        text(&o)
    );
    assert!(!out.exists());
}
