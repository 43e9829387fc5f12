//! Environment steps per second: the default scenario (20 lidar rays,
//! collision checks at 4 sub-steps), one thread. Actions replay a scripted
//! expert episode so the car passes obstacles as in real use; the episode
//! is restarted (reset included in the timing) when it ends.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use red_core::Env;
use red_drive::{DriveConfig, expert_demos, make_env};
use std::hint::black_box;

fn bench_step(c: &mut Criterion) {
    let config = DriveConfig::default();
    let demos = expert_demos(&config, 1, 0).expect("expert episode");
    let actions = demos.trajectories[0].actions.clone();
    let mut env = make_env(&config).expect("env");
    env.reset(Some(0)).expect("reset");
    let mut t = 0;
    let mut group = c.benchmark_group("red_drive");
    group.throughput(Throughput::Elements(1));
    group.bench_function("env_step_20_rays", |b| {
        b.iter(|| {
            let step = env.step(black_box(&actions[t])).expect("step");
            t += 1;
            if step.terminated || step.truncated || t == actions.len() {
                env.reset(Some(0)).expect("reset");
                t = 0;
            }
            black_box(step.reward)
        })
    });
    group.finish();
}

criterion_group!(benches, bench_step);
criterion_main!(benches);
