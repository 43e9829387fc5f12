//! The importers on fixtures made by `tests/fixtures/make_fixtures.py`
//! (numpy 2), and on truncated and corrupted copies of them.

use std::path::PathBuf;

use red_core::import::{
    NpzLayout, baselines_npz_from_bytes, read_baselines_npz, read_baselines_npz_with_layout,
    read_red_pickle, red_pickle_from_bytes,
};
use red_core::{Demos, EpisodeEnd, Error};

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

fn expected() -> serde_json::Value {
    let text = std::fs::read_to_string(fixture("expected.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn rows(v: &serde_json::Value) -> Vec<Vec<f64>> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|r| {
            r.as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect()
        })
        .collect()
}

fn flat(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn all_obs(d: &Demos) -> Vec<Vec<f64>> {
    d.trajectories
        .iter()
        .flat_map(|t| t.observations.clone())
        .collect()
}

fn all_acts(d: &Demos) -> Vec<Vec<f64>> {
    d.trajectories
        .iter()
        .flat_map(|t| t.actions.clone())
        .collect()
}

#[test]
fn red_pickles_of_every_protocol_decode_exactly() {
    let want = &expected()["red"];
    for name in ["red_p2.pkl", "red_p4.pkl", "red_p5.pkl"] {
        let d = read_red_pickle(&fixture(name), "Toy-v0", 5).unwrap();
        assert_eq!(d.env_id, "Toy-v0");
        assert_eq!((d.obs_dim, d.act_dim), (3, 2), "{name}");
        assert_eq!(d.lengths(), vec![5, 5], "{name}");
        assert!(
            d.trajectories
                .iter()
                .all(|t| t.end == EpisodeEnd::Truncated && t.rewards.is_none())
        );
        // float64 observations and float32 actions are recovered bit for bit.
        assert_eq!(all_obs(&d), rows(&want["observations"]), "{name}");
        assert_eq!(all_acts(&d), rows(&want["actions"]), "{name}");
        d.validate().unwrap();
    }
}

#[test]
fn red_pickle_trajectory_length_must_divide_the_rows() {
    let e = read_red_pickle(&fixture("red_p4.pkl"), "Toy-v0", 3)
        .unwrap_err()
        .to_string();
    assert!(e.contains("red_p4.pkl"), "{e}");
    assert!(
        e.contains("10 rows are not a whole number of trajectories of 3 steps"),
        "{e}"
    );
    let d = read_red_pickle(&fixture("red_p4.pkl"), "Toy-v0", 10).unwrap();
    assert_eq!(d.lengths(), vec![10]);
    assert!(read_red_pickle(&fixture("red_p4.pkl"), "Toy-v0", 0).is_err());
}

#[test]
fn red_pickle_errors_name_the_problem() {
    let e = read_red_pickle(&fixture("baselines_flat.npz"), "x", 5)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("baselines_flat.npz") && e.contains("not a readable pickle"),
        "{e}"
    );
    let e = read_red_pickle(&fixture("nope.pkl"), "x", 5).unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e:?}");
    // A pickled dict without `actions`: PROTO 2, EMPTY_DICT, MARK,
    // BINUNICODE 'observations', NONE, SETITEMS, STOP.
    let mut p = vec![0x80, 2, b'}', b'('];
    p.push(b'X');
    p.extend(12u32.to_le_bytes());
    p.extend(b"observations");
    p.extend([b'N', b'u', b'.']);
    let e = red_pickle_from_bytes(&p, "x", 5).unwrap_err().to_string();
    assert!(
        e.contains("`observations`: expected a numpy array, found None"),
        "{e}"
    );
}

/// Every prefix of `bytes` must fail; every byte flipped must fail or
/// decode to a valid set; nothing may panic. Returns the number of flips
/// that were caught.
fn torture(bytes: &[u8], decode: impl Fn(&[u8]) -> red_core::Result<Demos>) -> usize {
    for cut in 0..bytes.len() {
        assert!(
            decode(&bytes[..cut]).is_err(),
            "prefix of {cut} bytes decoded"
        );
    }
    let mut errors = 0;
    for i in 0..bytes.len() {
        for flip in [0xff, 0x01, 0x80] {
            let mut v = bytes.to_vec();
            v[i] ^= flip;
            match decode(&v) {
                Err(_) => errors += 1,
                // A flip inside the numbers can still decode: it must then
                // be a valid set.
                Ok(d) => d.validate().unwrap(),
            }
        }
    }
    errors
}

#[test]
fn corrupt_pickles_never_panic() {
    for name in ["red_p2.pkl", "red_p4.pkl", "red_p5.pkl"] {
        let bytes = std::fs::read(fixture(name)).unwrap();
        let caught = torture(&bytes, |b| red_pickle_from_bytes(b, "x", 5));
        // Flips in the opcodes and lengths are caught; flips in the numbers
        // cannot be.
        assert!(caught > bytes.len() / 2, "{name}: {caught} flips caught");
    }
}

#[test]
fn truncated_pickle_reports_its_offset() {
    let bytes = std::fs::read(fixture("red_p4.pkl")).unwrap();
    let e = red_pickle_from_bytes(&bytes[..300], "x", 5)
        .unwrap_err()
        .to_string();
    assert!(e.contains("pickle byte") && e.contains("truncated"), "{e}");
}

#[test]
fn baselines_npz_per_episode_layout() {
    let want = &expected()["episodes"];
    let (d, layout) =
        read_baselines_npz_with_layout(&fixture("baselines_episodes.npz"), "Toy-v0", 4).unwrap();
    assert_eq!(layout, NpzLayout::PerEpisode);
    assert_eq!((d.obs_dim, d.act_dim), (3, 2));
    assert_eq!(d.lengths(), vec![4, 4]);
    assert_eq!(all_obs(&d), rows(&want["observations"]));
    assert_eq!(all_acts(&d), rows(&want["actions"]));
    let rewards: Vec<f64> = d
        .trajectories
        .iter()
        .flat_map(|t| t.rewards.clone().unwrap())
        .collect();
    assert_eq!(rewards, flat(&want["rewards"]));
    // Episodes as long as the time limit were truncated by it...
    assert!(
        d.trajectories
            .iter()
            .all(|t| t.end == EpisodeEnd::Truncated)
    );
    // ...shorter ones ended by the task, and longer ones are an error.
    let d = read_baselines_npz(&fixture("baselines_episodes.npz"), "Toy-v0", 1000).unwrap();
    assert!(
        d.trajectories
            .iter()
            .all(|t| t.end == EpisodeEnd::Terminated)
    );
    let e = read_baselines_npz(&fixture("baselines_episodes.npz"), "Toy-v0", 3).unwrap_err();
    assert!(
        e.to_string()
            .contains("trajectory 0: episode of 4 steps is longer than the time limit of 3"),
        "{e}"
    );
}

#[test]
fn baselines_npz_flat_layout_deflated_with_lens() {
    let want = &expected()["flat"];
    let (d, layout) =
        read_baselines_npz_with_layout(&fixture("baselines_flat.npz"), "Toy-v0", 5).unwrap();
    assert_eq!(layout, NpzLayout::FlatByLens);
    assert_eq!((d.obs_dim, d.act_dim), (3, 1));
    assert_eq!(d.lengths(), vec![5, 3]);
    assert_eq!(all_obs(&d), rows(&want["observations"]));
    assert_eq!(all_acts(&d), rows(&want["actions"]));
    assert_eq!(d.trajectories[0].end, EpisodeEnd::Truncated);
    assert_eq!(d.trajectories[1].end, EpisodeEnd::Terminated);
    let rewards: Vec<f64> = d
        .trajectories
        .iter()
        .flat_map(|t| t.rewards.clone().unwrap())
        .collect();
    assert_eq!(rewards, flat(&want["rewards"]));
}

#[test]
fn baselines_npz_ragged_object_arrays() {
    let want = &expected()["ragged"];
    let (d, layout) =
        read_baselines_npz_with_layout(&fixture("baselines_ragged.npz"), "Toy-v0", 4).unwrap();
    assert_eq!(layout, NpzLayout::Ragged);
    assert_eq!(d.lengths(), vec![4, 2]);
    assert_eq!(all_obs(&d), rows(&want["observations"]));
    assert_eq!(all_acts(&d), rows(&want["actions"]));
    assert!(d.trajectories.iter().all(|t| t.rewards.is_none()));
}

#[test]
fn baselines_npz_flat_without_lens_assumes_equal_episodes() {
    let want = &expected()["flat_no_lens"];
    let (d, layout) =
        read_baselines_npz_with_layout(&fixture("baselines_flat_no_lens.npz"), "Toy-v0", 1000)
            .unwrap();
    assert_eq!(layout, NpzLayout::FlatByEpisodeCount);
    assert!(layout.to_string().contains("assumed"));
    assert_eq!(d.lengths(), vec![3, 3]);
    assert_eq!(all_obs(&d), rows(&want["observations"]));
    assert_eq!(all_acts(&d), rows(&want["actions"]));
}

#[test]
fn baselines_returns_must_match_rewards() {
    let e = read_baselines_npz(&fixture("baselines_bad_rets.npz"), "Toy-v0", 1000)
        .unwrap_err()
        .to_string();
    assert!(e.contains("baselines_bad_rets.npz: trajectory 1:"), "{e}");
    assert!(
        e.contains("`rews` sum to 5.5 but `ep_rets` says 6.5"),
        "{e}"
    );
}

#[test]
fn corrupt_npz_never_panics() {
    for name in [
        "baselines_episodes.npz",
        "baselines_flat.npz",
        "baselines_ragged.npz",
    ] {
        let bytes = std::fs::read(fixture(name)).unwrap();
        // The CRC catches flips in the data too; flips in fields the reader
        // has no use for (times, attributes, local copies of names) pass.
        let caught = torture(&bytes, |b| baselines_npz_from_bytes(b, "x", 1000));
        assert!(
            caught > bytes.len(),
            "{name}: {caught} of {} flips caught",
            3 * bytes.len()
        );
    }
}

#[test]
fn npz_errors_name_file_and_problem() {
    let path = fixture("baselines_flat.npz");
    let bytes = std::fs::read(&path).unwrap();
    let e = baselines_npz_from_bytes(&bytes[..bytes.len() - 30], "x", 1000).unwrap_err();
    assert!(e.to_string().contains("not a readable .npz"), "{e}");
    let e = read_baselines_npz(&fixture("red_p2.pkl"), "x", 1000)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("red_p2.pkl") && e.contains("not a zip archive"),
        "{e}"
    );
    // Corrupting a stored entry's data is caught by its CRC.
    let mut stored = std::fs::read(fixture("baselines_episodes.npz")).unwrap();
    let at = stored.windows(6).position(|w| w == b"\x93NUMPY").unwrap() + 200;
    stored[at] ^= 0x55;
    let e = baselines_npz_from_bytes(&stored, "x", 1000)
        .unwrap_err()
        .to_string();
    assert!(e.contains("CRC"), "{e}");
}

/// Pickle bytes as Python 2's numpy wrote them: text GLOBALs, `str` (not
/// `bytes`) for the type codes and the raw data, ints for the dtype flags.
fn python2_array(out: &mut Vec<u8>, typestr: &str, shape: &[u8], raw: &[u8]) {
    let short_str = |out: &mut Vec<u8>, s: &[u8]| {
        out.push(b'U');
        out.push(s.len() as u8);
        out.extend(s);
    };
    out.extend(b"cnumpy.core.multiarray\n_reconstruct\n");
    out.extend(b"cnumpy\nndarray\n");
    out.extend([b'K', 0, 0x85]);
    short_str(out, b"b");
    out.extend([0x87, b'R', b'(', b'K', 1]);
    out.push(b'(');
    for &d in shape {
        out.extend([b'K', d]);
    }
    out.push(b't');
    out.extend(b"cnumpy\ndtype\n");
    short_str(out, typestr.as_bytes());
    out.extend([b'K', 0, b'K', 1, 0x87, b'R']);
    out.extend([b'(', b'K', 3]);
    short_str(out, b"<");
    out.extend([
        b'N', b'N', b'N', b'J', 0xff, 0xff, 0xff, 0xff, b'J', 0xff, 0xff, 0xff, 0xff,
    ]);
    out.extend([b'K', 0, b't', b'b', 0x89]);
    out.push(b'T');
    out.extend((raw.len() as u32).to_le_bytes());
    out.extend(raw);
    out.extend([b't', b'b']);
}

#[test]
fn python2_style_red_pickles_decode() {
    let obs: Vec<f64> = (0..6).map(|i| i as f64 * 0.5).collect();
    let acs: Vec<f32> = vec![0.25, -0.75, 1.0];
    let mut p = vec![0x80, 2, b'}', b'q', 0, b'('];
    p.extend([b'U', 12]);
    p.extend(b"observations");
    python2_array(
        &mut p,
        "f8",
        &[3, 2],
        &obs.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<_>>(),
    );
    p.extend([b'U', 7]);
    p.extend(b"actions");
    python2_array(
        &mut p,
        "f4",
        &[3, 1, 1],
        &acs.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<_>>(),
    );
    p.extend([b'u', b'.']);
    let d = red_pickle_from_bytes(&p, "Old-v2", 3).unwrap();
    assert_eq!((d.obs_dim, d.act_dim), (2, 1));
    assert_eq!(d.trajectories[0].observations[2], vec![2.0, 2.5]);
    assert_eq!(
        d.trajectories[0].actions,
        vec![vec![0.25], vec![-0.75], vec![1.0]]
    );
}

#[test]
fn arrays_of_empty_rows_are_refused_without_allocating() {
    // observations of shape (10**12, 0): no data, a trillion rows claimed.
    let mut p = vec![0x80, 2, b'}', b'(', b'U', 12];
    p.extend(b"observations");
    // _reconstruct() (no arguments needed here), then BUILD with
    // (1, shape, dtype(typestr), False, b"").
    let arr = |p: &mut Vec<u8>, shape: &[u64], typestr: &str| {
        p.extend(b"cnumpy.core.multiarray\n_reconstruct\n)R(K\x01(");
        for &d in shape {
            p.push(0x8a);
            p.push(8);
            p.extend(d.to_le_bytes());
        }
        p.extend(b"tcnumpy\ndtype\nU");
        p.push(typestr.len() as u8);
        p.extend(typestr.as_bytes());
        p.extend(b"\x85R\x89C\x00tb");
    };
    arr(&mut p, &[1_000_000_000_000, 0], "f8");
    p.extend([b'U', 7]);
    p.extend(b"actions");
    arr(&mut p, &[1_000_000_000_000, 1, 0], "f4");
    p.extend([b'u', b'.']);
    let e = red_pickle_from_bytes(&p, "x", 1000)
        .unwrap_err()
        .to_string();
    assert!(e.contains("rows of no numbers"), "{e}");
}

#[test]
#[ignore = "random mutation fuzzing, run with --release -- --ignored"]
fn fuzz_importers_with_random_mutations() {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let files = [
        "red_p2.pkl",
        "red_p4.pkl",
        "red_p5.pkl",
        "baselines_episodes.npz",
        "baselines_flat.npz",
        "baselines_ragged.npz",
    ];
    let mut decoded = 0;
    for name in files {
        let base = std::fs::read(fixture(name)).unwrap();
        for _ in 0..20_000 {
            let mut v = base.clone();
            for _ in 0..rng.random_range(1..6) {
                let i = rng.random_range(0..v.len());
                match rng.random_range(0..4) {
                    0 => v[i] = rng.random(),
                    1 => v.insert(i, rng.random()),
                    2 => {
                        v.remove(i);
                    }
                    _ => v[i] = [0x00, 0xff, 0x7f, 0x80][rng.random_range(0..4)],
                }
            }
            let r = if name.ends_with(".pkl") {
                red_pickle_from_bytes(&v, "x", 5)
            } else {
                baselines_npz_from_bytes(&v, "x", 1000)
            };
            if let Ok(d) = r {
                d.validate().unwrap();
                decoded += 1;
            }
        }
    }
    println!(
        "{decoded} of {} mutants decoded to valid sets",
        files.len() * 20_000
    );
}
