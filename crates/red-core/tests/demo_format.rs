//! The JSON demo format: round trips, atomic writes, and one test per kind
//! of malformed file, each checking that the message names the location
//! and the problem.

use red_core::Error;
use red_core::demo::{Demos, EpisodeEnd, FORMAT_NAME, FORMAT_VERSION, Trajectory};

/// A valid file of two trajectories; line 10 holds trajectory 1.
const BASE: &str = r#"{
 "format": "red-demos",
 "version": 1,
 "env_id": "toy",
 "obs_dim": 2,
 "act_dim": 1,
 "control_hz": 20.0,
 "trajectories": [
  {"observations": [[0.0, 1.0], [0.5, 1.0]], "actions": [[0.1], [-0.2]], "rewards": [1.0, 0.5], "end": "truncated"},
  {"observations": [[1.0, 0.0], [1.5, 0.25], [2.0, 0.5]], "actions": [[0.3], [0.4], [0.5]], "end": "terminated"}
 ]
}"#;

fn with(from: &str, to: &str) -> String {
    assert!(BASE.contains(from), "{from}");
    BASE.replacen(from, to, 1)
}

/// The error message for `text`, which must be rejected as a demo error.
fn rejected(text: &str) -> String {
    match Demos::from_json_str(text) {
        Err(e @ Error::Demo { .. }) => e.to_string(),
        other => panic!("expected a demo error, got {other:?}"),
    }
}

fn assert_has(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "`{p}` missing from: {msg}");
    }
}

/// 1-based column of the first `needle` on line 10 (trajectory 1's line).
fn col_on_line_10(text: &str, needle: &str) -> usize {
    let line = text.lines().nth(9).unwrap();
    line.find(needle).unwrap() + 1
}

#[test]
fn the_base_file_is_valid() {
    let d = Demos::from_json_str(BASE).unwrap();
    assert_eq!(d.trajectories.len(), 2);
    assert_eq!(d.lengths(), vec![2, 3]);
    assert_eq!(d.num_pairs(), 5);
    assert_eq!(d.trajectories[1].end, EpisodeEnd::Terminated);
    assert_eq!(d.trajectories[0].true_return(), Some(1.5));
    assert_eq!(d.returns(), None);
    let (s, a) = d.pairs();
    assert_eq!(s.shape(), &[5, 2]);
    assert_eq!(a.shape(), &[5, 1]);
    assert_eq!(s[[3, 1]], 0.25);
    assert_eq!(a[[4, 0]], 0.5);
}

#[test]
fn nan_token_is_located() {
    let text = with("[1.5, 0.25]", "[1.5, NaN]");
    let col = col_on_line_10(&text, "NaN");
    let msg = rejected(&text);
    assert_has(
        &msg,
        &[
            "trajectory 1, step 1",
            &format!("line 10 column {col}"),
            "trajectories[1].observations[1][1]",
            "`NaN` is not a finite number",
        ],
    );
}

#[test]
fn infinity_tokens_are_located() {
    for tok in ["Infinity", "-Infinity", "inf"] {
        let text = with("[[0.3], [0.4]", &format!("[[0.3], [{tok}]"));
        let msg = rejected(&text);
        assert_has(
            &msg,
            &[
                "trajectory 1, step 1",
                "line 10",
                "actions[1][0]",
                &format!("`{tok}`"),
            ],
        );
    }
}

#[test]
fn huge_number_is_out_of_range() {
    let text = with("\"rewards\": [1.0, 0.5]", "\"rewards\": [1.0, 1e400]");
    let msg = rejected(&text);
    assert_has(
        &msg,
        &[
            "trajectory 0, step 1",
            "line 9",
            "1e400",
            "out of range for f64",
        ],
    );
}

#[test]
fn huge_integers_and_negative_overflow_are_out_of_range_too() {
    let big = format!("1{}", "0".repeat(400));
    for tok in [big.as_str(), "-1e400", "1.5E+309"] {
        let text = with("[0.5, 1.0]]", &format!("[0.5, {tok}]]"));
        let msg = rejected(&text);
        assert_has(
            &msg,
            &["trajectory 0, step 1", "line 9", "out of range for f64"],
        );
    }
}

#[test]
fn truncated_json_reports_line_and_column() {
    let cut = &BASE[..BASE.find("[0.4]").unwrap()];
    let msg = rejected(cut);
    assert_has(&msg, &["ends early (truncated file?)", "line 10 column"]);
}

#[test]
fn syntax_errors_report_line_and_column() {
    let text = with("[0.5, 1.0]]", "[0.5 1.0]]");
    let msg = rejected(&text);
    assert_has(
        &msg,
        &["invalid JSON", "line 9 column", "trajectory 0, step 1"],
    );
}

#[test]
fn wrong_observation_dimension() {
    let msg = rejected(&with("[1.5, 0.25]", "[1.5, 0.25, 3.0]"));
    assert_has(
        &msg,
        &[
            "trajectory 1, step 1",
            "observation has 3 numbers, obs_dim is 2",
        ],
    );
}

#[test]
fn wrong_action_dimension() {
    let msg = rejected(&with("[[0.1], [-0.2]]", "[[0.1], []]"));
    assert_has(
        &msg,
        &["trajectory 0, step 1", "action has 0 numbers, act_dim is 1"],
    );
}

#[test]
fn empty_trajectory() {
    let msg = rejected(&with(
        r#"[[1.0, 0.0], [1.5, 0.25], [2.0, 0.5]], "actions": [[0.3], [0.4], [0.5]]"#,
        r#"[], "actions": []"#,
    ));
    assert_has(&msg, &["trajectory 1: empty trajectory"]);
}

#[test]
fn no_trajectories() {
    let start = BASE.find("\"trajectories\"").unwrap();
    let text = format!("{}\"trajectories\": []}}", &BASE[..start]);
    assert_has(&rejected(&text), &["no trajectories"]);
}

#[test]
fn observations_and_actions_of_different_lengths() {
    let msg = rejected(&with("[[0.3], [0.4], [0.5]]", "[[0.3], [0.4]]"));
    assert_has(&msg, &["trajectory 1:", "3 observations but 2 actions"]);
}

#[test]
fn rewards_of_the_wrong_length() {
    let msg = rejected(&with("[1.0, 0.5]", "[1.0]"));
    assert_has(&msg, &["trajectory 0:", "1 rewards but 2 actions"]);
}

#[test]
fn unknown_version() {
    let msg = rejected(&with("\"version\": 1", "\"version\": 4"));
    assert_has(&msg, &["unknown version 4", "reads versions 1 to 3"]);
    // Checked before the fields, so a newer file's new fields do not hide it.
    let newer = with(
        "\"version\": 1",
        "\"version\": 4, \"compression\": \"none\"",
    );
    assert_has(&rejected(&newer), &["unknown version 4"]);
    assert_has(
        &rejected(&with("\"version\": 1", "\"version\": \"1\"")),
        &["unknown version \"1\""],
    );
}

#[test]
fn wrong_format_name() {
    let msg = rejected(&with("\"red-demos\"", "\"gym-demos\""));
    assert_has(&msg, &["format is \"gym-demos\"", "expected \"red-demos\""]);
    let start = BASE.find("\"version\"").unwrap();
    let missing = format!("{{{}", &BASE[start..]);
    assert_has(&rejected(&missing), &["no `format` field"]);
}

#[test]
fn missing_and_ill_typed_fields() {
    let msg = rejected(&with(", \"end\": \"terminated\"", ""));
    assert_has(&msg, &["missing field `end`", "trajectory 1"]);
    let msg = rejected(&with("[2.0, 0.5]", "[2.0, \"0.5\"]"));
    assert_has(&msg, &["invalid type", "trajectory 1, step 2", "line 10"]);
    let msg = rejected(&with("\"terminated\"", "\"crashed\""));
    assert_has(&msg, &["unknown variant `crashed`", "trajectory 1"]);
    let msg = rejected(&with(
        "\"env_id\": \"toy\"",
        "\"env_id\": \"toy\", \"speed\": 3",
    ));
    assert_has(&msg, &["unknown field `speed`"]);
    assert_has(&rejected(&with("\"toy\"", "\" \"")), &["env_id is empty"]);
    assert_has(
        &rejected(&with("\"obs_dim\": 2", "\"obs_dim\": 0")),
        &["obs_dim and act_dim must be positive"],
    );
    assert_has(
        &rejected(&with("20.0", "-20.0")),
        &["control_hz is -20, it must be a positive finite number"],
    );
}

#[test]
fn not_a_demo_object() {
    assert_has(&rejected("[1, 2, 3]"), &["expected a JSON object"]);
    assert_has(&rejected("  \n"), &["empty"]);
    assert_has(&rejected("{}"), &["no `format` field"]);
}

#[test]
fn validate_catches_what_code_builds() {
    let mut d = Demos::from_json_str(BASE).unwrap();
    d.trajectories[1].actions[2][0] = f64::NAN;
    let e = d.validate().unwrap_err().to_string();
    assert_has(&e, &["trajectory 1, step 2", "action[0] is NaN"]);
    let mut d = Demos::from_json_str(BASE).unwrap();
    d.trajectories[0].rewards.as_mut().unwrap()[0] = f64::NEG_INFINITY;
    assert_has(
        &d.validate().unwrap_err().to_string(),
        &["trajectory 0, step 0", "reward is -inf"],
    );
    let mut d = Demos::from_json_str(BASE).unwrap();
    d.trajectories[0].observations[1][0] = f64::INFINITY;
    assert_has(
        &d.validate().unwrap_err().to_string(),
        &["observation[0] is inf"],
    );
}

fn awkward() -> Demos {
    let mut d = Demos::new("round-trip", 3, 2, Some(50.0));
    d.trajectories.push(Trajectory {
        observations: vec![
            vec![0.1, 1.0 / 3.0, 1e-300],
            vec![-0.0, -9.999_999_99e8, 123_456_789.123_456_78],
        ],
        actions: vec![
            vec![f64::MIN_POSITIVE, -1.0],
            vec![0.7, std::f64::consts::PI],
        ],
        rewards: Some(vec![0.3, -7e-9]),
        end: EpisodeEnd::Terminated,
    });
    d
}

#[test]
fn write_then_read_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("demos.json");
    let d = awkward();
    d.write(&path).unwrap();
    let back = Demos::read(&path).unwrap();
    assert_eq!(back, d);
    for (a, b) in back.trajectories[0]
        .observations
        .iter()
        .flatten()
        .zip(d.trajectories[0].observations.iter().flatten())
    {
        assert_eq!(a.to_bits(), b.to_bits());
    }
    assert_eq!(
        (back.format.as_str(), back.version),
        (FORMAT_NAME, FORMAT_VERSION)
    );
    // Overwriting works and leaves no temporary file behind.
    let mut d2 = d.clone();
    d2.env_id = "second".into();
    d2.write(&path).unwrap();
    assert_eq!(Demos::read(&path).unwrap().env_id, "second");
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, vec![std::ffi::OsString::from("demos.json")]);
}

#[test]
fn invalid_demos_are_not_written() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.json");
    let mut d = awkward();
    d.trajectories[0].observations[0][2] = f64::NAN;
    let e = d.write(&path).unwrap_err().to_string();
    assert_has(
        &e,
        &["bad.json", "trajectory 0, step 0", "observation[2] is NaN"],
    );
    assert!(!path.exists());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    // A directory that does not exist is an I/O error naming the file.
    let e = awkward()
        .write(&dir.path().join("no/such/dir/x.json"))
        .unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e:?}");
}

#[test]
fn read_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.json");
    std::fs::write(&path, with("[1.5, 0.25]", "[1.5, NaN]")).unwrap();
    let msg = Demos::read(&path).unwrap_err().to_string();
    assert!(
        msg.starts_with(&format!(
            "{}: trajectory 1, step 1: line 10",
            path.display()
        )),
        "{msg}"
    );
    std::fs::write(&path, [0xff, 0xfe, b'{']).unwrap();
    assert_has(
        &Demos::read(&path).unwrap_err().to_string(),
        &["broken.json", "not UTF-8"],
    );
    let e = Demos::read(&dir.path().join("missing.json")).unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e:?}");
}

#[test]
fn summary_describes_the_set() {
    let mut d = Demos::from_json_str(BASE).unwrap();
    let s = d.summary();
    assert_has(
        &s,
        &[
            "`toy`",
            "2 trajectories, 5 state-action pairs, obs dim 2, act dim 1, 20 Hz",
            "lengths: min 2, mean 2.5, max 3; 1 terminated, 1 truncated",
            "true return: unknown",
        ],
    );
    d.trajectories[1].rewards = Some(vec![1.0, 1.0, 1.5]);
    assert_has(
        &d.summary(),
        &["true return: mean 2.500 +- 1.000 (min 1.500, max 3.500)"],
    );
}

#[test]
fn garbage_never_panics() {
    // Every prefix of a valid file, and every single-byte corruption of it,
    // is an error or a valid set: never a panic.
    for cut in 0..BASE.len() {
        if BASE.is_char_boundary(cut) {
            let _ = Demos::from_json_str(&BASE[..cut]);
        }
    }
    let bytes = BASE.as_bytes();
    for i in 0..bytes.len() {
        for b in [b'"', b'N', b'[', b'}', b'9', b'e', b'-', b',', b' '] {
            let mut v = bytes.to_vec();
            v[i] = b;
            if let Ok(t) = std::str::from_utf8(&v)
                && let Ok(d) = Demos::from_json_str(t)
            {
                d.validate().unwrap();
            }
        }
    }
}

#[test]
fn concurrent_writers_leave_one_whole_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("shared.json");
    std::thread::scope(|s| {
        for k in 0..8 {
            let path = &path;
            s.spawn(move || {
                let mut d = awkward();
                d.env_id = format!("writer-{k}");
                for _ in 0..5 {
                    d.write(path).unwrap();
                }
            });
        }
    });
    let back = Demos::read(&path).unwrap();
    assert!(back.env_id.starts_with("writer-"));
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
#[ignore = "timing, run with --release -- --ignored --nocapture"]
fn large_file_timing() {
    // 50 episodes of 2000 steps of the driving task's size (24 + 2 numbers).
    let mut d = Demos::new("drive", 24, 2, Some(20.0));
    for e in 0..50 {
        d.trajectories.push(Trajectory {
            observations: (0..2000)
                .map(|t| {
                    (0..24)
                        .map(|j| ((e * 2000 + t) * 24 + j) as f64 * 1e-3)
                        .collect()
                })
                .collect(),
            actions: (0..2000).map(|t| vec![(t as f64).sin(), 0.5]).collect(),
            rewards: Some(vec![1.0; 2000]),
            end: EpisodeEnd::Truncated,
        });
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("big.json");
    let t = std::time::Instant::now();
    d.write(&path).unwrap();
    let w = t.elapsed();
    let t = std::time::Instant::now();
    let back = Demos::read(&path).unwrap();
    let r = t.elapsed();
    assert_eq!(back, d);
    let mb = std::fs::metadata(&path).unwrap().len() as f64 / 1e6;
    println!(
        "{mb:.1} MB, {} pairs: write {w:?}, read+validate {r:?}",
        d.num_pairs()
    );
}

#[test]
fn version_2_carries_source_and_scenario_and_version_1_still_reads() {
    let v1 = Demos::from_json_str(BASE).expect("a version 1 file reads");
    assert_eq!((v1.source, v1.scenario.clone()), (None, None));
    let v2 = with(
        "\"version\": 1",
        "\"version\": 2, \"source\": \"person\", \"scenario\": {\"track_seed\": 7}",
    );
    let d = Demos::from_json_str(&v2).expect("a version 2 file reads");
    assert_eq!(d.source, Some(red_core::DemoSource::Person));
    assert_eq!(d.scenario, Some(serde_json::json!({"track_seed": 7})));
    assert_eq!(red_core::DemoSource::row_label(d.source), "demonstration");
    assert_eq!(red_core::DemoSource::row_label(None), "expert");
    // Written back, the fields survive.
    let text = serde_json::to_string(&d).expect("serialise");
    assert_eq!(Demos::from_json_str(&text).expect("reads"), d);
    assert_has(&rejected(&v2.replace("person", "robot")), &["robot"]);
}

#[test]
fn version_3_carries_how_the_demos_were_made_and_older_files_have_none() {
    let v1 = Demos::from_json_str(BASE).expect("a version 1 file reads");
    assert_eq!(v1.made_with, None);
    let v3 = with(
        "\"version\": 1",
        "\"version\": 3, \"source\": \"policy\", \"made_with\": {\"seed\": 4, \"stored\": \"raw\"}",
    );
    let d = Demos::from_json_str(&v3).expect("a version 3 file reads");
    assert_eq!(d.source, Some(red_core::DemoSource::Policy));
    assert_eq!(
        d.made_with,
        Some(serde_json::json!({"seed": 4, "stored": "raw"}))
    );
    let text = serde_json::to_string(&d).expect("serialise");
    assert_eq!(Demos::from_json_str(&text).expect("reads"), d);
    // A version 2 file read by this build gets no `made_with`, and a
    // version beyond this build's is named as unknown.
    let v2 = with("\"version\": 1", "\"version\": 2");
    assert_eq!(Demos::from_json_str(&v2).expect("reads").made_with, None);
    assert_has(
        &rejected(&with("\"version\": 1", "\"version\": 4")),
        &["version 4"],
    );
}
