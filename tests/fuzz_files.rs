//! Byte-level fuzzing of every file format the project reads: demo JSON,
//! the RED release's pickles, baselines' `.npz`, saved networks, optimiser
//! states, fitted support estimators, policies, TRPO checkpoints and
//! configs. Each target starts from a valid file and applies random
//! mutations (bit flips, byte overwrites, insertions, deletions,
//! truncation, duplicated chunks). For every input the reader must return
//! (an error is fine) without panicking, within a time bound, and without
//! any single allocation far beyond the input's size.
//!
//! Inputs per target: `RED_FUZZ_CASES` (default 1,500); the counts run are
//! printed (`cargo test --test fuzz_files -- --nocapture`).

// A counting allocator needs `unsafe impl GlobalAlloc`; it only forwards to
// the system allocator and records sizes.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::Path;
use std::time::{Duration, Instant};

use ndarray::Array2;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

struct PeakAlloc;

thread_local! {
    static PEAK: Cell<usize> = const { Cell::new(0) };
}

fn note(size: usize) {
    let _ = PEAK.try_with(|p| {
        if size > p.get() {
            p.set(size);
        }
    });
}

// SAFETY: every call is forwarded unchanged to `System`; the only addition
// is recording the requested size in a thread-local that never allocates.
unsafe impl GlobalAlloc for PeakAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        // SAFETY: same layout contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from `System.alloc` with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        // SAFETY: as for `alloc`.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note(new_size);
        // SAFETY: `ptr` came from `System` with `layout`.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: PeakAlloc = PeakAlloc;

fn cases() -> usize {
    std::env::var("RED_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1_500)
}

fn mutate(seed: &[u8], rng: &mut ChaCha8Rng) -> Vec<u8> {
    let mut v = seed.to_vec();
    let edits = rng.random_range(1..=4);
    for _ in 0..edits {
        if v.is_empty() {
            v.push(rng.random());
            continue;
        }
        let i = rng.random_range(0..v.len());
        match rng.random_range(0..7) {
            0 => v[i] ^= 1 << rng.random_range(0..8),
            1 => v[i] = rng.random(),
            2 => v.insert(i, rng.random()),
            3 => {
                let end = (i + rng.random_range(1..=16)).min(v.len());
                v.drain(i..end);
            }
            4 => v.truncate(i),
            5 => {
                let end = (i + rng.random_range(1..=32)).min(v.len());
                let chunk = v[i..end].to_vec();
                let at = rng.random_range(0..=v.len());
                v.splice(at..at, chunk);
            }
            // Interesting bytes for text formats and length fields.
            _ => {
                v[i] = *[b'"', b'-', b'9', b'e', b'[', b'{', b',', 0xff, 0x7f, 0x00]
                    .get(rng.random_range(0..10))
                    .unwrap_or(&0)
            }
        }
    }
    v
}

/// Runs `parse` on `cases()` mutations of `seed`; returns how many ran and
/// how many parsed without error.
fn fuzz(name: &str, seed: &[u8], parse: impl Fn(&[u8]) -> bool) -> (usize, usize) {
    assert!(parse(seed), "{name}: the unmutated seed file must parse");
    let mut rng = ChaCha8Rng::seed_from_u64(name.len() as u64 * 7919 + seed.len() as u64);
    let n = cases();
    let mut ok = 0;
    for k in 0..n {
        let input = mutate(seed, &mut rng);
        PEAK.with(|p| p.set(0));
        let start = Instant::now();
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| parse(&input)));
        let took = start.elapsed();
        let peak = PEAK.with(|p| p.get());
        let accepted = outcome
            .unwrap_or_else(|_| panic!("{name}: case {k} panicked on {} bytes", input.len()));
        ok += usize::from(accepted);
        assert!(
            took < Duration::from_secs(2),
            "{name}: case {k} took {took:?}"
        );
        let bound = 64 * input.len() + (4 << 20);
        assert!(
            peak <= bound,
            "{name}: case {k} allocated {peak} bytes at once for {} input bytes",
            input.len()
        );
    }
    println!("fuzz {name:<22} {n} inputs, {ok} parsed without error, none panicked");
    (n, ok)
}

fn fixture(name: &str) -> Vec<u8> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("crates/red-core/tests/fixtures")
        .join(name);
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

fn text(b: &[u8]) -> Option<&str> {
    std::str::from_utf8(b).ok()
}

#[test]
fn demo_json() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut demos = red_core::Demos::new("Hopper-v5", 3, 2, Some(125.0));
    for _ in 0..2 {
        let len = 6;
        demos.trajectories.push(red_core::Trajectory {
            observations: (0..len)
                .map(|_| (0..3).map(|_| rng.random_range(-2.0..2.0)).collect())
                .collect(),
            actions: (0..len)
                .map(|_| (0..2).map(|_| rng.random_range(-1.0..1.0)).collect())
                .collect(),
            rewards: Some((0..len).map(|_| rng.random()).collect()),
            end: red_core::EpisodeEnd::Truncated,
        });
    }
    let seed = serde_json::to_vec(&demos).expect("serialise");
    fuzz("demo json", &seed, |b| {
        text(b).is_some_and(|s| red_core::Demos::from_json_str(s).is_ok())
    });
}

#[test]
fn red_release_pickles() {
    for f in ["red_p2.pkl", "red_p4.pkl", "red_p5.pkl"] {
        let seed = fixture(f);
        fuzz(&format!("RED pickle {f}"), &seed, |b| {
            red_core::import::red_pickle_from_bytes(b, "Hopper-v5", 5).is_ok()
        });
    }
}

#[test]
fn baselines_npz() {
    for f in [
        "baselines_episodes.npz",
        "baselines_flat.npz",
        "baselines_ragged.npz",
    ] {
        let seed = fixture(f);
        fuzz(&format!("npz {f}"), &seed, |b| {
            red_core::import::baselines_npz_from_bytes(b, "x", 1000).is_ok()
        });
    }
}

#[test]
fn saved_networks_and_optimisers() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let net = red_nets::Mlp::new(&red_nets::MlpConfig::new(3, &[4], 2), &mut rng).expect("net");
    let seed = net.to_json().expect("json").into_bytes();
    fuzz("network json", &seed, |b| {
        text(b).is_some_and(|s| red_nets::Mlp::from_json(s).is_ok())
    });
    let adam = red_nets::Adam::new(red_nets::AdamConfig::default(), &net).expect("adam");
    let seed = adam.to_json().expect("json").into_bytes();
    fuzz("adam json", &seed, |b| {
        text(b).is_some_and(|s| red_nets::Adam::from_json(s).is_ok())
    });
}

#[test]
fn fitted_estimator_files() {
    use red_support::SupportEstimatorConfig;
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let s = Array2::from_shape_fn((12, 2), |_| rng.random_range(-1.0..1.0));
    let a = Array2::from_shape_fn((12, 1), |_| rng.random_range(-1.0..1.0));
    let cfg = red_support::RndConfig {
        target_hidden: vec![4],
        predictor_hidden: vec![4],
        output: 3,
        epochs: 2,
        ..red_support::RndConfig::default()
    };
    let model = cfg
        .fit(s.view(), a.view(), &mut rng, &mut red_support::no_progress)
        .expect("fit");
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("model.json");
    red_support::FittedEstimator::Rnd(model)
        .save(&path)
        .expect("save");
    let seed = std::fs::read(&path).expect("read");
    let probe = dir.path().join("probe.json");
    fuzz("support model file", &seed, |b| {
        std::fs::write(&probe, b).is_ok() && red_support::FittedEstimator::load(&probe).is_ok()
    });
}

#[test]
fn policies_checkpoints_and_configs() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let cfg = red_rl::policy::GaussianPolicyConfig {
        hidden: vec![4],
        ..red_rl::policy::GaussianPolicyConfig::default()
    };
    let policy = red_rl::policy::GaussianPolicy::new(&cfg, 3, 2, None, &mut rng).expect("policy");
    let seed = policy.to_json().expect("json").into_bytes();
    fuzz("policy json", &seed, |b| {
        text(b).is_some_and(|s| red_rl::policy::GaussianPolicy::from_json(s).is_ok())
    });

    let seed = serde_json::to_vec(&red_rl::dqn::DqnConfig::default()).expect("json");
    fuzz("dqn config", &seed, |b| {
        serde_json::from_slice::<red_rl::dqn::DqnConfig>(b).is_ok_and(|c| c.validate().is_ok())
    });
    let seed = serde_json::to_vec(&red_rl::trpo::TrpoConfig::default()).expect("json");
    fuzz("trpo config", &seed, |b| {
        serde_json::from_slice::<red_rl::trpo::TrpoConfig>(b).is_ok_and(|c| c.validate().is_ok())
    });
    let seed = serde_json::to_vec(&red_support::RndConfig::default()).expect("json");
    fuzz("rnd config", &seed, |b| {
        serde_json::from_slice::<red_support::RndConfig>(b).is_ok_and(|c| c.validate().is_ok())
    });
}

#[test]
fn training_states_and_checkpoint_envelopes() {
    // A TRPO trainer's whole state (networks, optimiser, normaliser, RNGs),
    // what `mujoco train` checkpoints hold.
    let cfg = red_rl::trpo::TrpoConfig {
        policy: red_rl::policy::GaussianPolicyConfig {
            hidden: vec![4],
            ..red_rl::policy::GaussianPolicyConfig::default()
        },
        value_hidden: vec![4],
        ..red_rl::trpo::TrpoConfig::default()
    };
    let trainer = red_rl::trpo::TrpoTrainer::new(cfg, 3, 2, None, 5).expect("trainer");
    let seed = trainer.to_json().expect("json").into_bytes();
    fuzz("trpo trainer state", &seed, |b| {
        text(b).is_some_and(|s| red_rl::trpo::TrpoTrainer::from_json(s).is_ok())
    });

    // The checkpoint envelope of every long command, here around a state
    // of nested numbers, strings and options like a run's.
    #[derive(serde::Serialize, serde::Deserialize)]
    struct State {
        args: Vec<String>,
        results: Vec<Option<Vec<(u64, f64)>>>,
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("checkpoint.json");
    let state = State {
        args: vec!["--n".into(), "5".into()],
        results: vec![Some(vec![(0, -0.25), (500, 0.5)]), None],
    };
    red_core::checkpoint::save_checkpoint(&path, "toy", &state).expect("save");
    let seed = std::fs::read(&path).expect("read");
    fuzz("checkpoint envelope", &seed, |b| {
        red_core::checkpoint::parse_checkpoint::<State>(b, "toy").is_ok()
    });
}

#[test]
fn the_guards_catch_panics_and_oversized_allocations() {
    let seed = b"{}".to_vec();
    let panicking = std::panic::catch_unwind(|| {
        fuzz("always panics", &seed, |b| {
            assert!(b == b"{}", "a mutated input");
            true
        })
    });
    assert!(panicking.is_err(), "a panicking reader was not caught");
    let greedy = std::panic::catch_unwind(|| {
        fuzz("allocates 64 MiB", &seed, |b| {
            let v = vec![0u8; 64 << 20];
            std::hint::black_box(&v);
            b == b"{}" || v.len() > 1
        })
    });
    assert!(greedy.is_err(), "an oversized allocation was not caught");
}
