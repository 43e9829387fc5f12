//! End to end: demonstrations imported from the formats users have, saved
//! in the project's JSON format, read back, and stacked for a learner.

use std::path::PathBuf;

use red_core::import::{read_baselines_npz, read_red_pickle};
use red_core::{Demos, Error};

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("crates/red-core/tests/fixtures")
        .join(name)
}

#[test]
fn imported_demos_survive_the_json_round_trip() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let imports = [
        read_red_pickle(&fixture("red_p2.pkl"), "Toy-v0", 5)?,
        read_red_pickle(&fixture("red_p5.pkl"), "Toy-v0", 5)?,
        read_baselines_npz(&fixture("baselines_episodes.npz"), "Toy-v0", 1000)?,
        read_baselines_npz(&fixture("baselines_flat.npz"), "Toy-v0", 1000)?,
        read_baselines_npz(&fixture("baselines_ragged.npz"), "Toy-v0", 1000)?,
    ];
    for (i, mut demos) in imports.into_iter().enumerate() {
        demos.control_hz = Some(125.0);
        let path = dir.path().join(format!("demos{i}.json"));
        demos.write(&path)?;
        let back = Demos::read(&path)?;
        assert_eq!(back, demos);
        let (s, a) = back.pairs();
        assert_eq!(s.dim(), (demos.num_pairs(), demos.obs_dim));
        assert_eq!(a.dim(), (demos.num_pairs(), demos.act_dim));
        assert!(s.iter().chain(a.iter()).all(|v| v.is_finite()));
        assert!(back.summary().contains("Toy-v0"));
    }
    // Both RED pickles hold the same numbers.
    assert_eq!(
        read_red_pickle(&fixture("red_p2.pkl"), "Toy-v0", 5)?,
        read_red_pickle(&fixture("red_p4.pkl"), "Toy-v0", 5)?
    );
    Ok(())
}

#[test]
fn a_damaged_demo_file_is_reported_with_its_location() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("demos.json");
    read_red_pickle(&fixture("red_p4.pkl"), "Toy-v0", 5)?.write(&path)?;
    // Someone edits the file by hand and leaves a NaN in trajectory 1.
    let text = std::fs::read_to_string(&path)?;
    let second = text.find("\"observations\"").and_then(|first| {
        text[first + 1..]
            .find("\"observations\"")
            .map(|k| k + first + 1)
    });
    let at = second.expect("two trajectories") + "\"observations\":[[".len();
    let end = at + text[at..].find(',').expect("a number");
    let broken = format!("{}NaN{}", &text[..at], &text[end..]);
    std::fs::write(&path, broken)?;
    match Demos::read(&path) {
        Err(e @ Error::Demo { .. }) => {
            let msg = e.to_string();
            assert!(msg.contains("demos.json"), "{msg}");
            assert!(msg.contains("trajectory 1, step 0"), "{msg}");
            assert!(msg.contains("line 1 column"), "{msg}");
        }
        other => panic!("expected a demo error, got {other:?}"),
    }
    Ok(())
}
