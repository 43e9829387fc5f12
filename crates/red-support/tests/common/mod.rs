//! Synthetic supports shared by the crate tests. None of the estimators'
//! defaults were tuned on them.

#![allow(dead_code)]

use ndarray::{Array2, s};
use rand::{Rng, RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// A support: in-support samples, off-support samples, and how `[s, a]`
/// splits (`obs_dim`).
pub struct Support {
    pub name: &'static str,
    pub obs_dim: usize,
    sample_in: fn(&mut ChaCha8Rng) -> Vec<f64>,
    sample_off: fn(&mut ChaCha8Rng) -> Vec<f64>,
    sample_near: fn(&mut ChaCha8Rng) -> Vec<f64>,
}

impl Support {
    /// `n` in-support rows, split into states and actions.
    pub fn inside(&self, n: usize, seed: u64) -> (Array2<f64>, Array2<f64>) {
        self.draw(n, seed, self.sample_in)
    }

    /// `n` off-support rows, split into states and actions.
    pub fn outside(&self, n: usize, seed: u64) -> (Array2<f64>, Array2<f64>) {
        self.draw(n, seed, self.sample_off)
    }

    /// `n` off-support rows close to the support (a harder test).
    pub fn near(&self, n: usize, seed: u64) -> (Array2<f64>, Array2<f64>) {
        self.draw(n, seed, self.sample_near)
    }

    fn draw(
        &self,
        n: usize,
        seed: u64,
        f: fn(&mut ChaCha8Rng) -> Vec<f64>,
    ) -> (Array2<f64>, Array2<f64>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let rows: Vec<Vec<f64>> = (0..n).map(|_| f(&mut rng)).collect();
        let d = rows[0].len();
        let x = Array2::from_shape_fn((n, d), |(i, j)| rows[i][j]);
        (
            x.slice(s![.., ..self.obs_dim]).to_owned(),
            x.slice(s![.., self.obs_dim..]).to_owned(),
        )
    }
}

fn normal<R: Rng>(rng: &mut R) -> f64 {
    StandardNormal.sample(rng)
}

/// The unit circle in 2-D: s = cos t, a = sin t. Off: uniform in
/// [-1.6, 1.6]^2 at least 0.25 from the circle.
fn circle_in(rng: &mut ChaCha8Rng) -> Vec<f64> {
    let t = rng.random_range(0.0..std::f64::consts::TAU);
    vec![t.cos(), t.sin()]
}

fn circle_off(rng: &mut ChaCha8Rng) -> Vec<f64> {
    loop {
        let p: [f64; 2] = [rng.random_range(-1.6..1.6), rng.random_range(-1.6..1.6)];
        let r = (p[0] * p[0] + p[1] * p[1]).sqrt();
        if (r - 1.0).abs() >= 0.25 {
            return p.to_vec();
        }
    }
}

/// Near the circle: radius in [0.85, 0.9] or [1.1, 1.15].
fn circle_near(rng: &mut ChaCha8Rng) -> Vec<f64> {
    let t = rng.random_range(0.0..std::f64::consts::TAU);
    let off = rng.random_range(0.1..0.15);
    let r = if rng.random_range(0.0..1.0) < 0.5 {
        1.0 - off
    } else {
        1.0 + off
    };
    vec![r * t.cos(), r * t.sin()]
}

const SEG_A: [f64; 10] = [-1.0, 0.5, 0.0, 0.3, -0.2, 0.8, -0.5, 0.1, 0.4, -0.7];
const SEG_B: [f64; 10] = [1.0, -0.3, 0.6, -0.4, 0.2, 0.1, 0.5, -0.6, -0.2, 0.9];

/// A segment in 10-D (8 state + 2 action dims). Off: a point of the
/// segment's line (parameter in [-0.3, 1.3]) moved 0.4 away in a random
/// direction orthogonal to it.
fn segment_in(rng: &mut ChaCha8Rng) -> Vec<f64> {
    let t = rng.random_range(0.0..1.0);
    (0..10)
        .map(|j| SEG_A[j] + t * (SEG_B[j] - SEG_A[j]))
        .collect()
}

fn segment_off(rng: &mut ChaCha8Rng) -> Vec<f64> {
    segment_moved(rng, 0.4)
}

/// Near the segment: moved 0.15 away (the segment is about 2.9 long).
fn segment_near(rng: &mut ChaCha8Rng) -> Vec<f64> {
    segment_moved(rng, 0.15)
}

fn segment_moved(rng: &mut ChaCha8Rng, dist: f64) -> Vec<f64> {
    let t = rng.random_range(-0.3..1.3);
    let dir: Vec<f64> = (0..10).map(|j| SEG_B[j] - SEG_A[j]).collect();
    let dn = dir.iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut v: Vec<f64> = (0..10).map(|_| normal(rng)).collect();
    let along: f64 = v.iter().zip(&dir).map(|(a, b)| a * b).sum::<f64>() / (dn * dn);
    for j in 0..10 {
        v[j] -= along * dir[j];
    }
    let vn = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    (0..10)
        .map(|j| SEG_A[j] + t * dir[j] + dist * v[j] / vn)
        .collect()
}

const CENTRES: [[f64; 4]; 5] = [
    [0.0, 0.0, 0.0, 0.0],
    [1.0, 1.0, 0.0, -1.0],
    [-1.0, 0.5, 1.0, 0.5],
    [0.5, -1.0, -1.0, 1.0],
    [-0.5, -0.5, 0.8, -0.8],
];

/// Five tight Gaussian clusters (std 0.05) in 4-D (3 state + 1 action).
/// Off: uniform in [-1.5, 1.5]^4 at least 0.3 from every centre.
fn clusters_in(rng: &mut ChaCha8Rng) -> Vec<f64> {
    let c = CENTRES[rng.random_range(0..CENTRES.len())];
    c.iter().map(|v| v + 0.05 * normal(rng)).collect()
}

fn clusters_off(rng: &mut ChaCha8Rng) -> Vec<f64> {
    loop {
        let p: Vec<f64> = (0..4).map(|_| rng.random_range(-1.5..1.5)).collect();
        let near = CENTRES.iter().any(|c| {
            c.iter()
                .zip(&p)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                .sqrt()
                < 0.3
        });
        if !near {
            return p;
        }
    }
}

/// Near the clusters: 0.2 to 0.3 from a centre (4 cluster standard
/// deviations and more).
fn clusters_near(rng: &mut ChaCha8Rng) -> Vec<f64> {
    let c = CENTRES[rng.random_range(0..CENTRES.len())];
    let v: Vec<f64> = (0..4).map(|_| normal(rng)).collect();
    let vn = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let r = rng.random_range(0.2..0.3);
    c.iter().zip(&v).map(|(ci, vi)| ci + r * vi / vn).collect()
}

/// The three supports.
pub fn supports() -> [Support; 3] {
    [
        Support {
            name: "circle-2d",
            obs_dim: 1,
            sample_in: circle_in,
            sample_off: circle_off,
            sample_near: circle_near,
        },
        Support {
            name: "segment-10d",
            obs_dim: 8,
            sample_in: segment_in,
            sample_off: segment_off,
            sample_near: segment_near,
        },
        Support {
            name: "clusters-4d",
            obs_dim: 3,
            sample_in: clusters_in,
            sample_off: clusters_off,
            sample_near: clusters_near,
        },
    ]
}
