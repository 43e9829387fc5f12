//! Best-of-5 throughput of the cases in `benches/nets.rs`, plus a breakdown
//! of one RND training step. On a machine shared with other work the best of
//! several repeats is closer to the uncontended speed than a median, and the
//! thread's on-CPU time (from `/proc/thread-self/schedstat`, Linux only)
//! leaves out the time spent waiting for a core; both are printed.
//!
//! `cargo run --release -p red-nets --example nets_throughput`

use std::hint::black_box;
use std::time::Instant;

use ndarray::{Array2, s};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use red_nets::{
    Activation, Adam, AdamConfig, FrozenMlp, Mlp, MlpConfig, Optimizer, Tape, Workspace,
    mse_loss_into,
};

/// Nanoseconds this thread has spent on a CPU, if the kernel tells.
fn thread_cpu_ns() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    s.split_whitespace().next()?.parse().ok()
}

/// Runs `f` `iters` times per repeat, 5 repeats after a warm-up; prints the
/// best wall time per call and its rows per second, then the best on-CPU
/// time per call and its rows per second.
fn time<F: FnMut()>(name: &str, rows: usize, iters: usize, mut f: F) {
    for _ in 0..iters / 5 + 1 {
        f();
    }
    let (mut best, mut best_cpu) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..5 {
        let c0 = thread_cpu_ns();
        let t = Instant::now();
        for _ in 0..iters {
            f();
        }
        best = best.min(t.elapsed().as_secs_f64() / iters as f64);
        if let (Some(c0), Some(c1)) = (c0, thread_cpu_ns()) {
            best_cpu = best_cpu.min((c1 - c0) as f64 * 1e-9 / iters as f64);
        }
    }
    println!(
        "{name:48} wall {:9.2} us {:11.0}/s | on-CPU {:9.2} us {:11.0}/s",
        best * 1e6,
        rows as f64 / best,
        best_cpu * 1e6,
        rows as f64 / best_cpu
    );
}

fn main() {
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let data = Array2::from_shape_simple_fn((4000, 14), || rng.random_range(-1.0f32..1.0));
    let mut predictor = Mlp::new(&MlpConfig::new(14, &[128], 128), &mut rng).unwrap();
    let target = FrozenMlp::new(Mlp::new(&MlpConfig::new(14, &[128; 4], 128), &mut rng).unwrap());
    let targets = target.predict(data.view());
    let mut adam = Adam::new(AdamConfig::default(), &predictor).unwrap();
    let mut tape = Tape::new();
    let mut grads = predictor.zero_grads();
    let mut dpred = Array2::zeros((32, 128));
    let mut ws = Workspace::new();
    let batches = data.nrows() / 32;

    let mut k = 0;
    time("(a) rnd predictor train step, batch 32", 32, 2000, || {
        let rows = s![32 * k..32 * (k + 1), ..];
        k = (k + 1) % batches;
        let pred = predictor.forward_tape(data.slice(rows), &mut tape);
        black_box(mse_loss_into(pred, targets.slice(rows), &mut dpred));
        grads.zero();
        predictor.backward_params(&tape, dpred.view(), &mut grads);
        adam.step(&mut predictor, &grads).unwrap();
    });
    time(
        "(a') + target forward (RND fit), batch 32",
        32,
        2000,
        || {
            let rows = s![32 * k..32 * (k + 1), ..];
            k = (k + 1) % batches;
            let x = data.slice(rows);
            let t = target.forward(x, &mut ws);
            let pred = predictor.forward_tape(x, &mut tape);
            black_box(mse_loss_into(pred, t, &mut dpred));
            grads.zero();
            predictor.backward_params(&tape, dpred.view(), &mut grads);
            adam.step(&mut predictor, &grads).unwrap();
        },
    );
    let x32 = data.slice(s![..32, ..]);
    time("    predictor forward_tape, batch 32", 32, 5000, || {
        black_box(predictor.forward_tape(x32, &mut tape)[[0, 0]]);
    });
    mse_loss_into(tape.output(), targets.slice(s![..32, ..]), &mut dpred);
    time("    predictor backward_params, batch 32", 32, 5000, || {
        grads.zero();
        predictor.backward_params(&tape, dpred.view(), &mut grads);
    });
    time("    Adam step (18,560 parameters)", 32, 5000, || {
        adam.step(&mut predictor, &grads).unwrap();
    });
    for batch in [1usize, 32, 1024] {
        let x = data.slice(s![..batch, ..]);
        time(
            &format!("(b) rnd target forward, batch {batch}"),
            batch,
            64_000 / batch,
            || {
                black_box(target.forward(x, &mut ws)[[0, 0]]);
            },
        );
    }
    for act in [Activation::Tanh, Activation::Identity] {
        let config = MlpConfig::new(11, &[100, 100], 3).with_activation(act);
        let policy = Mlp::new(&config, &mut rng).unwrap();
        let x = Array2::from_shape_simple_fn((1024, 11), || rng.random_range(-2.0f32..2.0));
        let x1 = x.slice(s![..1, ..]);
        time(
            &format!("    2 x 100 {act:?} policy forward, batch 1"),
            1,
            20_000,
            || {
                black_box(policy.forward(x1, &mut ws)[[0, 0]]);
            },
        );
        time(
            &format!("(c) 2 x 100 {act:?} policy forward, batch 1024"),
            1024,
            200,
            || {
                black_box(policy.forward(x.view(), &mut ws)[[0, 0]]);
            },
        );
    }
}
