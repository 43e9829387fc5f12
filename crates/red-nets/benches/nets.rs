//! Throughput of the networks the RED reproduction runs most.
//!
//! `cargo bench -p red-nets`. Each benchmark reports samples (rows) per
//! second; compare with `/work/shared/reference/peer-figures.md` (PyTorch,
//! one thread) as ratios.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use ndarray::{Array2, s};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use red_nets::{
    Activation, Adam, AdamConfig, FrozenMlp, Mlp, MlpConfig, Optimizer, Tape, Workspace,
    mse_loss_into,
};

/// 4000 random (state, action) pairs of Hopper's size (11 + 3), as in the
/// peer figures' set-up.
fn pairs(rng: &mut ChaCha8Rng) -> Array2<f32> {
    Array2::from_shape_simple_fn((4000, 14), || rng.random_range(-1.0f32..1.0))
}

fn rnd_nets(rng: &mut ChaCha8Rng) -> (Mlp, FrozenMlp) {
    let predictor = Mlp::new(&MlpConfig::new(14, &[128], 128), rng).unwrap();
    let target = FrozenMlp::new(Mlp::new(&MlpConfig::new(14, &[128; 4], 128), rng).unwrap());
    (predictor, target)
}

fn group<'a>(
    c: &'a mut Criterion,
    name: &str,
    rows: usize,
) -> criterion::BenchmarkGroup<'a, criterion::measurement::WallTime> {
    let mut g = c.benchmark_group(name);
    g.warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3))
        .sample_size(30)
        .throughput(Throughput::Elements(rows as u64));
    g
}

/// (a) The release's RND predictor, one Adam step on a batch of 32 against
/// precomputed target outputs; (a') the same plus the target's forward pass
/// (the peer figure's "RND fit").
fn rnd_fit(c: &mut Criterion) {
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let data = pairs(&mut rng);
    let (mut predictor, target) = rnd_nets(&mut rng);
    let targets = target.predict(data.view());
    let mut adam = Adam::new(AdamConfig::default(), &predictor).unwrap();
    let mut tape = Tape::new();
    let mut grads = predictor.zero_grads();
    let mut dpred = Array2::zeros((32, 128));
    let mut ws = Workspace::new();
    let batches = data.nrows() / 32;

    let mut g = group(c, "rnd_predictor_train", 32);
    let mut k = 0;
    g.bench_function("batch32", |b| {
        b.iter(|| {
            let rows = s![32 * k..32 * (k + 1), ..];
            k = (k + 1) % batches;
            let pred = predictor.forward_tape(data.slice(rows), &mut tape);
            let loss = mse_loss_into(pred, targets.slice(rows), &mut dpred);
            grads.zero();
            predictor.backward_params(&tape, dpred.view(), &mut grads);
            adam.step(&mut predictor, &grads).unwrap();
            black_box(loss)
        })
    });
    g.finish();

    let mut g = group(c, "rnd_fit_with_target_forward", 32);
    let mut k = 0;
    g.bench_function("batch32", |b| {
        b.iter(|| {
            let rows = s![32 * k..32 * (k + 1), ..];
            k = (k + 1) % batches;
            let x = data.slice(rows);
            let t = target.forward(x, &mut ws);
            let pred = predictor.forward_tape(x, &mut tape);
            let loss = mse_loss_into(pred, t, &mut dpred);
            grads.zero();
            predictor.backward_params(&tape, dpred.view(), &mut grads);
            adam.step(&mut predictor, &grads).unwrap();
            black_box(loss)
        })
    });
    g.finish();
}

/// (b) The release's RND target, forward only (batch 1 takes the row-by-row path).
fn rnd_target_forward(c: &mut Criterion) {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let data = pairs(&mut rng);
    let (_, target) = rnd_nets(&mut rng);
    let mut ws = Workspace::new();
    for batch in [1usize, 32, 1024] {
        let mut g = group(c, "rnd_target_forward", batch);
        let x = data.slice(s![..batch, ..]);
        g.bench_function(format!("batch{batch}"), |b| {
            b.iter(|| black_box(target.forward(black_box(x), &mut ws)[[0, 0]]))
        });
        g.finish();
    }
}

/// (c) A 2 x 100 tanh policy, 11 -> 3, forward on a batch of 1024.
fn policy_forward(c: &mut Criterion) {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let config = MlpConfig::new(11, &[100, 100], 3).with_activation(Activation::Tanh);
    let policy = Mlp::new(&config, &mut rng).unwrap();
    let x = Array2::from_shape_simple_fn((1024, 11), || rng.random_range(-2.0f32..2.0));
    let mut ws = Workspace::new();
    let mut g = group(c, "policy_tanh_2x100_forward", 1024);
    g.bench_function("batch1024", |b| {
        b.iter(|| black_box(policy.forward(black_box(x.view()), &mut ws)[[0, 0]]))
    });
    g.finish();
}

/// (d) A Polyak step of a network of driving's SVG(1)-ER value size (24
/// inputs, 100 x 100, 1 output) toward another: in place
/// (`Mlp::polyak_toward`, what the learners run since session 34) against
/// copying the parameters out, averaging, and writing them back (what they
/// ran before; the same numbers).
fn polyak(c: &mut Criterion) {
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let cfg = MlpConfig::new(24, &[100, 100], 1);
    let source = Mlp::new(&cfg, &mut rng).unwrap();
    let mut target = Mlp::new(&cfg, &mut rng).unwrap();
    let mut g = group(c, "polyak_value_net", 1);
    g.bench_function("in_place", |b| {
        b.iter(|| target.polyak_toward(black_box(&source), 0.01).unwrap())
    });
    g.bench_function("flat_copies", |b| {
        b.iter(|| {
            let p = black_box(&source).params_flat();
            let mut t = target.params_flat();
            for (ti, pi) in t.iter_mut().zip(&p) {
                *ti += 0.01 * (pi - *ti);
            }
            target.set_params_flat(&t).unwrap();
        })
    });
    g.finish();
}

criterion_group!(benches, rnd_fit, rnd_target_forward, policy_forward, polyak);
criterion_main!(benches);
