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
use std::time::Duration;

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

fn bench_env(c: &mut Criterion, id: EnvId) {
    let rec = record(id);
    let n_resets = rec.resets.iter().filter(|r| r.is_some()).count();
    let mut group = c.benchmark_group(id.name());
    group
        .throughput(Throughput::Elements(STEPS as u64))
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(4));

    let mut env = id.make().unwrap();
    group.bench_function("env_step", |b| {
        b.iter(|| {
            env.reset(Some(SEED)).unwrap();
            for a in &rec.actions {
                let step = env.step(black_box(a)).unwrap();
                if step.terminated || step.truncated {
                    env.reset(None).unwrap();
                }
                black_box(&step);
            }
        })
    });
    assert_eq!(state(env.inner()), rec.end, "the env replay diverged");

    let file = match id {
        EnvId::Hopper => "hopper.xml",
        EnvId::HalfCheetah => "half_cheetah.xml",
        EnvId::Walker2d => "walker2d_v5.xml",
        EnvId::Ant => "ant.xml",
        EnvId::Reacher => "reacher.xml",
    };
    let frame_skip = env.inner().simulation().frame_skip();
    let mut sim = Simulation::load(file, frame_skip).unwrap();
    group.bench_function("raw_mj_step", |b| {
        b.iter(|| {
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
        })
    });
    // Same physics on both sides: the raw loop ends where the env ended.
    assert_eq!(state_of(&sim), rec.end, "the raw replay diverged");
    group.finish();
    eprintln!(
        "{}: frame_skip {frame_skip}, {n_resets} resets in {STEPS} steps",
        id.name()
    );
}

fn state_of(sim: &Simulation) -> (Vec<f64>, Vec<f64>) {
    (sim.qpos().to_vec(), sim.qvel().to_vec())
}

fn main() {
    let mut c = Criterion::default().configure_from_args();
    for id in EnvId::ALL {
        bench_env(&mut c, id);
    }
    c.final_summary();
}
