//! Oracle checks of TRPO's pieces: conjugate gradient against a direct
//! solve, GAE against hand-computed values, and the Gaussian policy's
//! derivatives (backward, reparameterised backward, Fisher-vector product)
//! against finite differences.

use nalgebra::{DMatrix, DVector};
use ndarray::{Array2, array};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use red_nets::{Gradients, Tape, Workspace};
use red_rl::gae::{GaeConfig, gae};
use red_rl::policy::{GaussianBatch, GaussianPolicy, GaussianPolicyConfig};
use red_rl::trpo::conjugate_gradient;

#[test]
fn conjugate_gradient_matches_direct_solve() {
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let n = 12;
    let m = DMatrix::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
    // Symmetric positive definite, like F + damping I.
    let a = &m * m.transpose() + DMatrix::identity(n, n) * 0.1;
    let b = DVector::from_fn(n, |_, _| rng.random_range(-1.0..1.0));
    let direct = a.clone().lu().solve(&b).expect("invertible");
    let avp = |v: &[f64], out: &mut [f64]| {
        let r = &a * DVector::from_column_slice(v);
        out.copy_from_slice(r.as_slice());
    };
    // In exact arithmetic CG solves an n x n system in n iterations.
    let x = conjugate_gradient(avp, b.as_slice(), 3 * n, 1e-20);
    for i in 0..n {
        assert!(
            (x[i] - direct[i]).abs() < 1e-6 * (1.0 + direct[i].abs()),
            "{i}: {} vs {}",
            x[i],
            direct[i]
        );
    }
    // Fewer iterations still reduce the residual (TRPO stops at 10).
    let x3 = conjugate_gradient(avp, b.as_slice(), 3, 0.0);
    let res = |x: &[f64]| (&a * DVector::from_column_slice(x) - &b).norm();
    assert!(res(&x3) < b.norm());
}

#[test]
fn gae_matches_hand_computed_values_with_termination_and_truncation() {
    // Five steps: an episode terminated at t=1, an episode truncated at t=3,
    // and a batch cut after t=4 (mid-episode, always bootstrapped).
    let r = [1.0, 2.0, 0.5, -1.0, 3.0];
    let v = [0.1, 0.2, 0.3, 0.4, 0.5];
    // Next-state values: within an episode the next step's value; at the
    // ends, the value of the observation the step returned.
    let nv = [0.2, 9.0, 0.4, 0.7, 0.6];
    let term = [false, true, false, false, false];
    let trunc = [false, false, false, true, false];
    let (g, l) = (0.9, 0.8);
    let cfg = GaeConfig {
        gamma: g,
        lambda: l,
        bootstrap_on_truncation: false,
    };
    let (adv, ret) = gae(&cfg, &r, &v, &nv, &term, &trunc).unwrap();
    // Hand computation.
    let d4 = 3.0 + g * 0.6 - 0.5; // cut: bootstrap
    let d3 = -1.0 + 0.0 - 0.4; // truncated, treated as terminal
    let d2 = 0.5 + g * 0.4 - 0.3;
    let d1 = 2.0 + 0.0 - 0.2; // terminated: the 9.0 is never read
    let d0 = 1.0 + g * 0.2 - 0.1;
    let want = [d0 + g * l * d1, d1, d2 + g * l * d3, d3, d4];
    for t in 0..5 {
        assert!(
            (adv[t] - want[t]).abs() < 1e-12,
            "t={t}: {} vs {}",
            adv[t],
            want[t]
        );
        assert!((ret[t] - (want[t] + v[t])).abs() < 1e-12);
    }
    // Bootstrapping on truncation changes only the truncated episode.
    let cfg_b = GaeConfig {
        bootstrap_on_truncation: true,
        ..cfg
    };
    let (adv_b, _) = gae(&cfg_b, &r, &v, &nv, &term, &trunc).unwrap();
    let d3b = -1.0 + g * 0.7 - 0.4;
    let want_b = [want[0], want[1], d2 + g * l * d3b, d3b, d4];
    for t in 0..5 {
        assert!((adv_b[t] - want_b[t]).abs() < 1e-12, "t={t}");
    }
    assert!(gae(&cfg, &r, &v[..4], &nv, &term, &trunc).is_err());
}

fn policy(seed: u64) -> GaussianPolicy {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let cfg = GaussianPolicyConfig {
        hidden: vec![8, 6],
        init_log_std: -0.5,
        // A larger head than the default so the outputs depend visibly on
        // the parameters.
        output_scale: 1.0,
        ..Default::default()
    };
    GaussianPolicy::new(&cfg, 3, 2, None, &mut rng).unwrap()
}

fn obs() -> Array2<f32> {
    array![
        [0.2f32, -0.5, 0.9],
        [-1.0, 0.3, 0.1],
        [0.7, 0.7, -0.4],
        [0.0, -0.2, 0.5]
    ]
}

fn dist_at(p: &GaussianPolicy, x: &Array2<f32>) -> GaussianBatch {
    p.distribution(x.view(), &mut Workspace::new()).unwrap()
}

fn with_params(p: &GaussianPolicy, theta: &[f32]) -> GaussianPolicy {
    let mut q = p.clone();
    q.net_mut().set_params_flat(theta).unwrap();
    q
}

#[test]
fn log_prob_gradient_matches_finite_differences() {
    let p = policy(1);
    let x = obs();
    let acts = array![[0.3, -0.1], [1.0, 0.5], [-0.7, 0.2], [0.0, 0.0]];
    let mut tape = Tape::new();
    let d = p.distribution_tape(x.view(), &mut tape).unwrap();
    // L = sum_i log pi(a_i | s_i).
    let inv_var = d.log_std.mapv(|l| (-2.0 * l).exp());
    let diff = &acts - &d.mean;
    let d_mean = &diff * &inv_var;
    let d_ls = (&diff * &diff) * &inv_var - 1.0;
    let mut grads = p.net().zero_grads();
    p.backward(&tape, &d, d_mean.view(), d_ls.view(), &mut grads);
    let g = grads.flat();
    let theta = p.net().params_flat();
    let f = |th: &[f32]| {
        dist_at(&with_params(&p, th), &x)
            .log_prob(acts.view())
            .iter()
            .sum::<f64>()
    };
    let h = 1e-2f32;
    for idx in (0..theta.len()).step_by(7) {
        let mut tp = theta.clone();
        tp[idx] += h;
        let mut tm = theta.clone();
        tm[idx] -= h;
        let fd = (f(&tp) - f(&tm)) / (2.0 * h as f64);
        assert!(
            (fd - g[idx] as f64).abs() < 2e-2 * (1.0 + fd.abs()),
            "param {idx}: fd {fd} vs {}",
            g[idx]
        );
    }
}

#[test]
fn reparameterised_backward_matches_finite_differences() {
    let p = policy(2);
    let x = obs();
    let mut tape = Tape::new();
    let d = p.distribution_tape(x.view(), &mut tape).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let (a, eps) = p.sample_reparam(&d, &mut rng);
    // The sample is mu + sigma * eps.
    let recon = &d.mean + &(d.log_std.mapv(f64::exp) * &eps);
    assert!((&a - &recon).iter().all(|v| v.abs() < 1e-12));
    // L = sum_ij c_ij a_ij with fixed eps.
    let c = array![[1.0, -2.0], [0.5, 0.3], [-1.0, 1.5], [2.0, 0.1]];
    let mut grads = p.net().zero_grads();
    let d_obs = p.backward_reparam(&tape, &d, eps.view(), c.view(), &mut grads);
    let loss = |q: &GaussianPolicy, xx: &Array2<f32>| {
        let dd = dist_at(q, xx);
        let aa = &dd.mean + &(dd.log_std.mapv(f64::exp) * &eps);
        (&aa * &c).sum()
    };
    let theta = p.net().params_flat();
    let g = grads.flat();
    let h = 1e-2f32;
    for idx in (0..theta.len()).step_by(5) {
        let mut tp = theta.clone();
        tp[idx] += h;
        let mut tm = theta.clone();
        tm[idx] -= h;
        let fd =
            (loss(&with_params(&p, &tp), &x) - loss(&with_params(&p, &tm), &x)) / (2.0 * h as f64);
        assert!(
            (fd - g[idx] as f64).abs() < 2e-2 * (1.0 + fd.abs()),
            "param {idx}: fd {fd} vs {}",
            g[idx]
        );
    }
    // d loss / d observation.
    for (i, j) in [(0, 0), (1, 2), (3, 1)] {
        let mut xp = x.clone();
        xp[[i, j]] += h;
        let mut xm = x.clone();
        xm[[i, j]] -= h;
        let fd = (loss(&p, &xp) - loss(&p, &xm)) / (2.0 * h as f64);
        assert!(
            (fd - d_obs[[i, j]] as f64).abs() < 2e-2 * (1.0 + fd.abs()),
            "obs ({i},{j}): fd {fd} vs {}",
            d_obs[[i, j]]
        );
    }
}

#[test]
fn fisher_vector_product_is_the_kl_hessian() {
    let p = policy(3);
    let x = obs();
    let mut tape = Tape::new();
    let d = p.distribution_tape(x.view(), &mut tape).unwrap();
    let theta = p.net().params_flat();
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let v: Vec<f32> = (0..theta.len())
        .map(|_| rng.random_range(-1.0..1.0))
        .collect();
    let dir = Gradients::from_flat(p.net(), &v).unwrap();
    let mut fv = p.net().zero_grads();
    p.fisher_vector_product(&tape, &d, &dir, &mut fv);
    let vfv: f64 = fv
        .flat()
        .iter()
        .zip(&v)
        .map(|(a, b)| *a as f64 * *b as f64)
        .sum();
    // KL(pi || pi_{theta + h v}) = h^2 / 2 * v^T F v + O(h^3).
    let h = 1e-2f32;
    let kl_at = |s: f32| {
        let th: Vec<f32> = theta.iter().zip(&v).map(|(t, vv)| t + s * vv).collect();
        let q = dist_at(&with_params(&p, &th), &x);
        d.kl(&q).iter().sum::<f64>() / x.nrows() as f64
    };
    // Average +h and -h to cancel the cubic term.
    let quad = (kl_at(h) + kl_at(-h)) / (h as f64 * h as f64);
    assert!(vfv > 0.0);
    assert!(
        (quad - vfv).abs() < 0.03 * vfv,
        "finite differences {quad} vs F product {vfv}"
    );
}

#[test]
fn clamped_log_std_passes_no_gradient() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let cfg = GaussianPolicyConfig {
        hidden: vec![4],
        init_log_std: -5.0,
        log_std_min: -5.0,
        ..Default::default()
    };
    let mut p = GaussianPolicy::new(&cfg, 2, 1, None, &mut rng).unwrap();
    // Push the log-std bias below the clamp.
    let mut theta = p.net().params_flat();
    let last = theta.len() - 1;
    theta[last] = -8.0;
    p.net_mut().set_params_flat(&theta).unwrap();
    let x = array![[0.1f32, 0.2]];
    let mut tape = Tape::new();
    let d = p.distribution_tape(x.view(), &mut tape).unwrap();
    assert_eq!(d.log_std[[0, 0]], -5.0);
    assert_eq!(d.log_std_mask[[0, 0]], 0.0);
    let mut grads = p.net().zero_grads();
    p.backward(
        &tape,
        &d,
        array![[0.0]].view(),
        array![[1.0]].view(),
        &mut grads,
    );
    assert_eq!(grads.flat()[last], 0.0);
}
