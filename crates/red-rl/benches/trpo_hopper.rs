//! TRPO training throughput on MuJoCo Hopper-v5 (`red-mujoco`), one thread:
//! environment steps per second with learning included, the figure to set
//! against the raw physics (`cargo bench -p red-mujoco`) and the project's
//! bar of 6,000 steps/s.
//!
//! `cargo bench -p red-rl --bench trpo_hopper` (needs
//! `scripts/setup-mujoco.sh` to have run).

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use red_mujoco::EnvId;
use red_rl::trpo::{TrpoConfig, TrpoTrainer};

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
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
