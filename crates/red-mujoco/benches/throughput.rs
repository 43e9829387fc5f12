//! Environment steps per second of each environment beside the raw physics
//! of the same model: `frame_skip` calls of `mj_step` per environment step,
//! nothing else.
//!
//! Both loops replay one recorded run of 1000 environment steps (seeded
//! random actions in the action bounds, Gymnasium's time limit, a reset after
//! every terminal step): the raw loop writes the same controls and restores
//! the same states at the same steps, so both integrate exactly the same
//! trajectory and the difference is the environment's own cost (observation,
//! reward, checks, info, reset noise, and for Ant the contact forces).
//!
//! `cargo bench -p red-mujoco`; throughput is in environment steps
//! ("elements") per second.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{Criterion, Throughput};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use red_core::Env;
use red_mujoco::{EnvId, MujocoEnv, Simulation};

const STEPS: usize = 1000;
const SEED: u64 = 7;

/// One recorded run: the start state, the actions, and after which steps
/// the environment was reset and to which state.
struct Recording {
    start: (Vec<f64>, Vec<f64>),
    actions: Vec<Vec<f64>>,
    resets: Vec<Option<(Vec<f64>, Vec<f64>)>>,
    end: (Vec<f64>, Vec<f64>),
}

fn state(env: &impl MujocoEnv) -> (Vec<f64>, Vec<f64>) {
    let sim = env.simulation();
    (sim.qpos().to_vec(), sim.qvel().to_vec())
}

fn record(id: EnvId) -> Recording {
    let mut env = id.make().expect("run scripts/setup-mujoco.sh");
    let mut rng = ChaCha8Rng::seed_from_u64(SEED);
    env.reset(Some(SEED)).unwrap();
    let start = state(env.inner());
    let mut actions = Vec::with_capacity(STEPS);
    let mut resets = Vec::with_capacity(STEPS);
    for _ in 0..STEPS {
        let a: Vec<f64> = (0..env.action_space().dim())
            .map(|_| rng.random_range(-1.0..1.0))
            .collect();
        let step = env.step(&a).unwrap();
        actions.push(a);
        if step.terminated || step.truncated {
            env.reset(None).unwrap();
            resets.push(Some(state(env.inner())));
        } else {
            resets.push(None);
        }
    }
    Recording {
        start,
        actions,
        resets,
        end: state(env.inner()),
    }
}

type TimedEnv = red_core::TimeLimit<red_mujoco::BoxedEnv>;

/// Replays the recording through the environment.
fn replay_env(env: &mut TimedEnv, rec: &Recording) {
    env.reset(Some(SEED)).unwrap();
    for a in &rec.actions {
        let step = env.step(black_box(a)).unwrap();
        if step.terminated || step.truncated {
            env.reset(None).unwrap();
        }
        black_box(&step);
    }
}

/// Replays the recording with nothing but the physics: controls, `mj_step`,
/// and the recorded resets.
fn replay_raw(sim: &mut Simulation, rec: &Recording) {
    let frame_skip = sim.frame_skip();
    sim.reset();
    sim.set_state(&rec.start.0, &rec.start.1).unwrap();
    for (a, reset) in rec.actions.iter().zip(&rec.resets) {
        let data = sim.data_mut();
        data.ctrl_mut().copy_from_slice(black_box(a));
        for _ in 0..frame_skip {
            data.step();
        }
        if let Some((qpos, qvel)) = reset {
            sim.reset();
            sim.set_state(qpos, qvel).unwrap();
        }
    }
    black_box(sim.qpos()[0]);
}

fn model_file(id: EnvId) -> &'static str {
    match id {
        EnvId::Hopper => "hopper.xml",
        EnvId::HalfCheetah => "half_cheetah.xml",
        EnvId::Walker2d => "walker2d_v5.xml",
        EnvId::Ant => "ant.xml",
        EnvId::Reacher => "reacher.xml",
    }
}

/// Environment and raw replays timed alternately, `PAIRS` times, so that
/// both see the same load of a shared machine; the ratio of each pair, then
/// the median over pairs.
const PAIRS: usize = 15;

/// Seconds this thread has run on a CPU (from `/proc/thread-self/schedstat`),
/// so that time spent waiting for a core on a busy machine is not counted;
/// wall time where that file is missing.
fn busy_seconds(wall_origin: Instant) -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<u64>().ok())
        .map(|ns| ns as f64 * 1e-9)
        .unwrap_or_else(|| wall_origin.elapsed().as_secs_f64())
}

struct Paired {
    env_steps_per_s: f64,
    raw_steps_per_s: f64,
    ratio: f64,
    ratio_min: f64,
    ratio_max: f64,
}

fn median(mut x: Vec<f64>) -> f64 {
    x.sort_by(f64::total_cmp);
    let n = x.len();
    if n % 2 == 1 {
        x[n / 2]
    } else {
        0.5 * (x[n / 2 - 1] + x[n / 2])
    }
}

/// Each timed sample lasts at least this long, so that the coarse
/// accounting of on-CPU time (updated at scheduler ticks) stays small.
const MIN_SAMPLE_SECONDS: f64 = 0.2;

fn paired(env: &mut TimedEnv, sim: &mut Simulation, rec: &Recording) -> Paired {
    let t = Instant::now();
    replay_raw(sim, rec);
    let reps = (MIN_SAMPLE_SECONDS / t.elapsed().as_secs_f64())
        .ceil()
        .max(1.0) as usize;
    let (mut env_t, mut raw_t, mut ratios) = (Vec::new(), Vec::new(), Vec::new());
    let origin = Instant::now();
    for _ in 0..PAIRS {
        let t = busy_seconds(origin);
        for _ in 0..reps {
            replay_env(env, rec);
        }
        let e = (busy_seconds(origin) - t) / reps as f64;
        let t = busy_seconds(origin);
        for _ in 0..reps {
            replay_raw(sim, rec);
        }
        let r = (busy_seconds(origin) - t) / reps as f64;
        env_t.push(e);
        raw_t.push(r);
        ratios.push(r / e);
    }
    let lo = ratios.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = ratios.iter().copied().fold(0.0, f64::max);
    Paired {
        env_steps_per_s: STEPS as f64 / median(env_t),
        raw_steps_per_s: STEPS as f64 / median(raw_t),
        ratio: median(ratios),
        ratio_min: lo,
        ratio_max: hi,
    }
}

fn bench_env(c: &mut Criterion, id: EnvId, measure_pairs: bool) -> Option<Paired> {
    let rec = record(id);
    let n_resets = rec.resets.iter().filter(|r| r.is_some()).count();
    let mut env = id.make().unwrap();
    let frame_skip = env.inner().simulation().frame_skip();
    let mut sim = Simulation::load(model_file(id), frame_skip).unwrap();

    // Both replays must integrate the recorded trajectory exactly.
    replay_env(&mut env, &rec);
    assert_eq!(state(env.inner()), rec.end, "the env replay diverged");
    replay_raw(&mut sim, &rec);
    assert_eq!(state_of(&sim), rec.end, "the raw replay diverged");

    let mut group = c.benchmark_group(id.name());
    group
        .throughput(Throughput::Elements(STEPS as u64))
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    group.bench_function("env_step", |b| b.iter(|| replay_env(&mut env, &rec)));
    group.bench_function("raw_mj_step", |b| b.iter(|| replay_raw(&mut sim, &rec)));
    group.finish();

    eprintln!(
        "{}: frame_skip {frame_skip}, {n_resets} resets in {STEPS} steps",
        id.name()
    );
    measure_pairs.then(|| paired(&mut env, &mut sim, &rec))
}

fn state_of(sim: &Simulation) -> (Vec<f64>, Vec<f64>) {
    (sim.qpos().to_vec(), sim.qvel().to_vec())
}

fn main() {
    let mut c = Criterion::default().configure_from_args();
    // `cargo bench` passes `--bench`; `cargo test --all-targets` does not,
    // and then criterion only runs each benchmark once: skip the pairs too.
    let measure_pairs = std::env::args().any(|a| a == "--bench");
    let mut table = Vec::new();
    for id in EnvId::ALL {
        if let Some(p) = bench_env(&mut c, id, measure_pairs) {
            table.push((id, p));
        }
    }
    c.final_summary();
    if table.is_empty() {
        return;
    }
    println!(
        "\nPaired replays ({PAIRS} alternations, each at least {MIN_SAMPLE_SECONDS} s of \
         {STEPS}-step replays; on-CPU time of the thread; medians):\n\
         | env | env.step steps/s | raw mj_step env-steps/s | env / raw (min - max) |\n\
         |---|---|---|---|"
    );
    for (id, p) in table {
        println!(
            "| {} | {:.0} | {:.0} | {:.1}% ({:.1} - {:.1}%) |",
            id.name(),
            p.env_steps_per_s,
            p.raw_steps_per_s,
            100.0 * p.ratio,
            100.0 * p.ratio_min,
            100.0 * p.ratio_max
        );
    }
}
