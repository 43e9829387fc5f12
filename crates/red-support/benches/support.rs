//! Benchmarks of red-support: RND fit with the release's configuration,
//! RED reward inference, kernel PCA fit. Run with
//! `cargo bench -p red-support --bench support` (filter by name after `--`).
//! Throughputs are reported in elements: samples for the fit
//! (4000 pairs x 200 epochs) and for inference (pairs scored).

use std::hint::black_box;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use ndarray::Array2;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use red_support::{KernelPcaConfig, RedReward, RndConfig, SupportEstimatorConfig, no_progress};

/// `n` random pairs of a Hopper-sized problem (11 state + 3 action numbers).
fn pairs(n: usize, seed: u64) -> (Array2<f64>, Array2<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (
        Array2::from_shape_fn((n, 11), |_| rng.random_range(-1.0..1.0)),
        Array2::from_shape_fn((n, 3), |_| rng.random_range(-1.0..1.0)),
    )
}

fn rnd_fit(c: &mut Criterion) {
    let (s, a) = pairs(4000, 1);
    let cfg = RndConfig::default();
    let mut g = c.benchmark_group("rnd_fit");
    g.sample_size(10);
    g.measurement_time(Duration::from_secs(60));
    g.throughput(Throughput::Elements((4000 * cfg.epochs) as u64));
    g.bench_function("release_4000x14_200ep", |b| {
        b.iter(|| {
            let mut rng = ChaCha8Rng::seed_from_u64(2);
            black_box(
                cfg.fit(s.view(), a.view(), &mut rng, &mut no_progress)
                    .unwrap(),
            )
        })
    });
    g.finish();
}

fn reward_inference(c: &mut Criterion) {
    let (s, a) = pairs(4000, 1);
    // Inference cost does not depend on training; a few epochs suffice.
    let cfg = RndConfig {
        epochs: 2,
        ..Default::default()
    };
    let model = cfg
        .fit(
            s.view(),
            a.view(),
            &mut ChaCha8Rng::seed_from_u64(2),
            &mut no_progress,
        )
        .unwrap();
    let reward = RedReward::with_sigma1(model, 1000.0).unwrap();
    let mut g = c.benchmark_group("red_reward_rnd");
    for batch in [1usize, 1024] {
        let (qs, qa) = pairs(batch, 3);
        g.throughput(Throughput::Elements(batch as u64));
        g.bench_with_input(BenchmarkId::new("batch", batch), &batch, |b, _| {
            b.iter(|| black_box(reward.reward(qs.view(), qa.view()).unwrap()))
        });
    }
    g.finish();
}

fn kpca_fit(c: &mut Criterion) {
    let mut g = c.benchmark_group("kpca_fit");
    g.sample_size(10);
    for n in [1000usize, 4000] {
        let (s, a) = pairs(n, 4);
        g.bench_with_input(BenchmarkId::new("n", n), &n, |b, _| {
            b.iter(|| {
                let mut rng = ChaCha8Rng::seed_from_u64(0);
                black_box(
                    KernelPcaConfig::default()
                        .fit(s.view(), a.view(), &mut rng, &mut no_progress)
                        .unwrap(),
                )
            })
        });
    }
    g.finish();
}

criterion_group!(benches, rnd_fit, reward_inference, kpca_fit);
criterion_main!(benches);
