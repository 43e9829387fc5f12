//! Weight initialisers.

use ndarray::Array2;
use rand::{Rng, RngExt};

use crate::config::Init;

/// Draws a weight matrix of shape `(fan_in, fan_out)` with `init`.
pub fn init_weights<R: Rng + ?Sized>(
    init: Init,
    fan_in: usize,
    fan_out: usize,
    rng: &mut R,
) -> Array2<f32> {
    match init {
        Init::GlorotUniform => glorot_uniform(fan_in, fan_out, rng),
        Init::Orthogonal { gain } => orthogonal(fan_in, fan_out, gain, rng),
    }
}

/// The bound `sqrt(6 / (fan_in + fan_out))` of Glorot-uniform.
pub fn glorot_limit(fan_in: usize, fan_out: usize) -> f32 {
    (6.0 / (fan_in + fan_out) as f64).sqrt() as f32
}

/// Uniform on `[-l, l]`, `l = sqrt(6 / (fan_in + fan_out))`, shape `(fan_in, fan_out)`.
pub fn glorot_uniform<R: Rng + ?Sized>(fan_in: usize, fan_out: usize, rng: &mut R) -> Array2<f32> {
    let limit = glorot_limit(fan_in, fan_out);
    Array2::from_shape_simple_fn((fan_in, fan_out), || rng.random_range(-limit..=limit))
}

/// A standard normal draw (Box-Muller, in f64), kept here so the stream of
/// numbers depends only on `rand`'s uniform sampling.
fn standard_normal<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    loop {
        let u: f64 = rng.random();
        if u > 0.0 {
            let v: f64 = rng.random();
            return (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos();
        }
    }
}

/// A random (semi-)orthogonal matrix of shape `(rows, cols)` times `gain`.
///
/// Draws a Gaussian matrix with `max(rows, cols)` rows and `min(rows, cols)`
/// columns, orthonormalises its columns (Gram-Schmidt, done twice in f64 for
/// accuracy; it leaves the triangular factor with a positive diagonal, so the
/// result is Haar-distributed), and transposes when
/// `rows < cols`.
pub fn orthogonal<R: Rng + ?Sized>(
    rows: usize,
    cols: usize,
    gain: f32,
    rng: &mut R,
) -> Array2<f32> {
    let (n, k) = if rows >= cols {
        (rows, cols)
    } else {
        (cols, rows)
    };
    // Columns stored contiguously: q[j] is column j, length n.
    let mut q: Vec<Vec<f64>> = (0..k)
        .map(|_| (0..n).map(|_| standard_normal(rng)).collect())
        .collect();
    for j in 0..k {
        // Two passes of Gram-Schmidt against the finished columns: the second
        // removes what rounding left of the first.
        for _pass in 0..2 {
            let (done, rest) = q.split_at_mut(j);
            let col = &mut rest[0];
            for prev in done.iter() {
                let dot: f64 = prev.iter().zip(col.iter()).map(|(a, b)| a * b).sum();
                for (x, &b) in col.iter_mut().zip(prev) {
                    *x -= dot * b;
                }
            }
            // A zero column has probability zero with Gaussian draws; guard anyway.
            let norm = col.iter().map(|x| x * x).sum::<f64>().sqrt();
            let norm = if norm > 0.0 { norm } else { 1.0 };
            for x in col.iter_mut() {
                *x /= norm;
            }
        }
    }
    let g = gain as f64;
    if rows >= cols {
        Array2::from_shape_fn((rows, cols), |(i, j)| (g * q[j][i]) as f32)
    } else {
        Array2::from_shape_fn((rows, cols), |(i, j)| (g * q[i][j]) as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    fn max_dev_from_scaled_identity(m: &Array2<f64>, s: f64) -> f64 {
        let mut worst = 0.0f64;
        for ((i, j), &v) in m.indexed_iter() {
            let target = if i == j { s } else { 0.0 };
            worst = worst.max((v - target).abs());
        }
        worst
    }

    #[test]
    fn orthogonal_gives_scaled_identity_gram_matrix() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for &(r, c, gain) in &[
            (14usize, 128usize, 1.0f32),
            (128, 128, 2f32.sqrt()),
            (100, 3, 0.01),
            (5, 5, 1.0),
            (1, 7, 1.0),
        ] {
            let w = orthogonal(r, c, gain, &mut rng).mapv(|x| x as f64);
            let g2 = (gain as f64).powi(2);
            let gram = if r >= c { w.t().dot(&w) } else { w.dot(&w.t()) };
            let dev = max_dev_from_scaled_identity(&gram, g2);
            assert!(
                dev < 1e-5 * g2.max(1.0),
                "({r}, {c}) gain {gain}: max deviation {dev}"
            );
        }
    }

    #[test]
    fn glorot_respects_bounds_and_spreads() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let w = glorot_uniform(14, 128, &mut rng);
        let l = glorot_limit(14, 128);
        assert!((l - (6.0f32 / 142.0).sqrt()).abs() < 1e-7);
        assert!(w.iter().all(|&x| x.abs() <= l));
        let max = w.iter().fold(0.0f32, |m, &x| m.max(x.abs()));
        assert!(
            max > 0.95 * l,
            "samples should approach the bound, max {max} vs {l}"
        );
        let mean = w.mean().unwrap();
        assert!(mean.abs() < 0.02, "mean {mean}");
        // Variance of U(-l, l) is l^2 / 3.
        let var = w.mapv(|x| x * x).mean().unwrap();
        assert!((var / (l * l / 3.0) - 1.0).abs() < 0.1, "variance {var}");
    }
}
