//! TRPO training throughput on MuJoCo Hopper-v5 (`red-mujoco`), one thread:
//! environment steps per second with learning included, the figure to set
//! against the raw physics (`cargo bench -p red-mujoco`) and the project's
//! bar of 6,000 steps/s.
//!
//! `cargo bench -p red-rl --bench trpo_hopper` (needs
//! `scripts/setup-mujoco.sh` to have run).

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use red_mujoco::EnvId;
use red_rl::trpo::{TrpoConfig, TrpoTrainer};

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
    let mut env = EnvId::Hopper
        .make()
        .expect("Hopper-v5: run scripts/setup-mujoco.sh first");
    let mut trainer = TrpoTrainer::new(config.clone(), 11, 3, None, 0).expect("valid config");
    let mut group = c.benchmark_group("trpo_hopper");
    group.sample_size(20);
    group.throughput(Throughput::Elements(config.steps_per_batch as u64));
    group.bench_function("iteration_1024_steps", |b| {
        b.iter(|| black_box(trainer.iterate(&mut env, None).expect("iteration runs")))
    });
    group.bench_function("iteration_1024_steps_on_cpu", |b| {
        b.iter_custom(|iters| {
            time_on_cpu(iters, || {
                black_box(trainer.iterate(&mut env, None).expect("iteration runs"));
            })
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
