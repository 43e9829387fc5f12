//! GMMIL's reward with its action gradient on a batch, the call SVG(1)-ER
//! makes for every policy update: 64 pairs of the driving task's widths
//! (22 observation and 2 action numbers) against 721 expert pairs (the
//! shipped demo's count) and a policy batch of 1,000 pairs.
//!
//! `cargo bench -p red-rl --bench gmmil`

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use ndarray::Array2;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use red_core::{DifferentiableReward, RewardModel};
use red_rl::gmmil::{Gmmil, GmmilConfig};

fn random(rows: usize, cols: usize, rng: &mut ChaCha8Rng) -> Array2<f64> {
    Array2::from_shape_fn((rows, cols), |_| rng.random_range(-1.0..1.0))
}

fn bench(c: &mut Criterion) {
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let (obs, act) = (22, 2);
    let mut gmmil = Gmmil::new(
        GmmilConfig::default(),
        random(721, obs, &mut rng).view(),
        random(721, act, &mut rng).view(),
    )
    .unwrap();
    let (ps, pa) = (random(1_000, obs, &mut rng), random(1_000, act, &mut rng));
    gmmil.update(ps.view(), pa.view()).unwrap();
    let (s, a) = (random(64, obs, &mut rng), random(64, act, &mut rng));
    c.bench_function("gmmil reward_and_grad, 64 pairs vs 721 + 1000", |b| {
        b.iter(|| black_box(gmmil.reward_and_grad(s.view(), a.view()).unwrap()))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
