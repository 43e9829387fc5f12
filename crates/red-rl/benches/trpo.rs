//! TRPO training throughput (environment steps per second, learning
//! included) on a synthetic environment with Hopper's dimensions
//! (observation 11, action 3) whose dynamics cost next to nothing, so the
//! figure is the learner's own cost: collection through the policy network,
//! GAE, the natural-gradient step with its line search, and the value fit.
//!
//! `cargo bench -p red-rl --bench trpo`

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use red_core::{BoxSpace, Env, Info, Space, Step, TimeLimit};
use red_rl::trpo::{TrpoConfig, TrpoTrainer};

const OBS: usize = 11;
const ACT: usize = 3;

/// A stable linear system `x' = 0.95 x + 0.1 B u` with a quadratic cost,
/// falling (terminating) when `|x_0|` exceeds 3, like Hopper's health check.
struct Synthetic {
    x: [f64; OBS],
    rng: ChaCha8Rng,
    obs_space: Space,
    act_space: Space,
}

impl Env for Synthetic {
    fn observation_space(&self) -> &Space {
        &self.obs_space
    }
    fn action_space(&self) -> &Space {
        &self.act_space
    }
    fn reset(&mut self, seed: Option<u64>) -> red_core::Result<(Vec<f64>, Info)> {
        if let Some(s) = seed {
            self.rng = ChaCha8Rng::seed_from_u64(s);
        }
        for v in &mut self.x {
            *v = self.rng.random_range(-0.1..0.1);
        }
        Ok((self.x.to_vec(), Info::new()))
    }
    fn step(&mut self, u: &[f64]) -> red_core::Result<Step> {
        let mut cost = 0.0;
        for (i, v) in self.x.iter_mut().enumerate() {
            *v = 0.95 * *v + 0.1 * u[i % ACT];
            cost += *v * *v;
        }
        Ok(Step {
            observation: self.x.to_vec(),
            reward: 1.0 - 0.1 * cost,
            terminated: self.x[0].abs() > 3.0,
            truncated: false,
            info: Info::new(),
        })
    }
}

fn env() -> TimeLimit<Synthetic> {
    TimeLimit::new(
        Synthetic {
            x: [0.0; OBS],
            rng: ChaCha8Rng::seed_from_u64(0),
            obs_space: Space::Box(BoxSpace::uniform(OBS, f64::NEG_INFINITY, f64::INFINITY)),
            act_space: Space::Box(BoxSpace::uniform(ACT, -1.0, 1.0)),
        },
        1000,
    )
    .expect("valid limit")
}

/// Time this thread spent running on a CPU, read from
/// `/proc/thread-self/schedstat` (nanoseconds, first field): on a shared,
/// busy machine it leaves out the time spent waiting for a core. `None`
/// where the file is missing.
fn on_cpu() -> Option<Duration> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let ns: u64 = s.split_whitespace().next()?.parse().ok()?;
    Some(Duration::from_nanos(ns))
}

/// Runs `f` `iters` times and returns its on-CPU time (wall time if the
/// scheduler statistics are unavailable).
fn time_on_cpu(iters: u64, mut f: impl FnMut()) -> Duration {
    let (cpu0, wall0) = (on_cpu(), Instant::now());
    for _ in 0..iters {
        f();
    }
    match (cpu0, on_cpu()) {
        (Some(a), Some(b)) => b - a,
        _ => wall0.elapsed(),
    }
}

fn bench(c: &mut Criterion) {
    let config = TrpoConfig::default();
    let steps = config.steps_per_batch as u64;
    let mut group = c.benchmark_group("trpo");
    group.sample_size(20);
    group.throughput(Throughput::Elements(steps));
    let mut trainer = TrpoTrainer::new(config.clone(), OBS, ACT, None, 0).expect("valid config");
    let mut e = env();
    group.bench_function("iteration_1024_steps_obs11_act3", |b| {
        b.iter(|| black_box(trainer.iterate(&mut e, None).expect("iteration runs")))
    });
    group.bench_function("iteration_1024_steps_obs11_act3_on_cpu", |b| {
        b.iter_custom(|iters| {
            time_on_cpu(iters, || {
                black_box(trainer.iterate(&mut e, None).expect("iteration runs"));
            })
        })
    });
    // The collection half alone, to see where the time goes.
    let mut trainer = TrpoTrainer::new(config, OBS, ACT, None, 0).expect("valid config");
    let mut e = env();
    group.bench_function("collect_only_1024_steps_obs11_act3", |b| {
        b.iter(|| black_box(trainer.collect(&mut e).expect("collection runs")))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
