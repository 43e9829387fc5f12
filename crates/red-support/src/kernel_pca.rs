//! Exact kernel PCA support estimation (paper Sec. 2.2, Eq. 3-4).
//!
//! With the kernel matrix `K` of the `n` expert inputs and its top `m`
//! eigenpairs `K ≈ U_m Λ_m U_m^T`, the score of a point `x` is the squared
//! distance in feature space from `φ(x)` to the span of the principal
//! directions:
//!
//! `L(x) = k(x, x) - K_x^T K_m^+ K_x = k(x, x) - ||W^T K_x||^2`,
//! `W = U_m Λ_m^{-1/2}`,
//!
//! where `(K_x)_i = k(x_i, x)`. `W` (`n x m`) is computed once at fit time,
//! so a score costs `O(n d + n m)`, never a solve. The eigenpairs come from
//! nalgebra's dense `SymmetricEigen` (exact, all of them) or, above 1500
//! pairs by default, from block Lanczos for the leading ones only (see
//! [`Eigensolver`]).
//!
//! The regularised variant (Tikhonov, `lambda > 0`) replaces `K_m^+` by
//! `(K + n λ I)^{-1}` on the same `m` directions, the empirical form of
//! `⟨φ(x), Ĉ (Ĉ + λ I)^{-1} φ(x)⟩` (Rudi et al. 2017), so that with all
//! components kept it is exactly the Tikhonov-filtered support estimator:
//!
//! `L_λ(x) = k(x, x) - (U_m^T K_x) · (Z^T K_x)`, `Z = (K + n λ I)^{-1} U_m`.
//!
//! `Z` is computed by `clarabel`: column `j` is the minimiser of the convex
//! quadratic program `1/2 z^T (K + n λ I) z - u_j^T z` (no constraints),
//! whose optimality condition is the linear system. A test checks it
//! against nalgebra's Cholesky solve. Each column is a fresh factorisation
//! of a dense `n x n` matrix, so this variant costs `O(m n^3)` at fit time
//! and suits a few hundred pairs; the unregularised default does not use it.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use ndarray::{Array1, Array2, ArrayView2, Axis, s};
use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::estimator::{FitProgress, SupportEstimatorConfig, SupportModel};
use crate::input::InputMap;
use crate::{Error, Result};

/// Eigenvalues below this fraction of the largest are numerically zero
/// (the rounding error of the eigensolver is about `1e-16 * n * λ_max`)
/// and never kept: dividing by them would turn rounding into score.
pub const EIGEN_RELATIVE_CUTOFF: f64 = 1e-12;

/// The kernel's form.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum KernelKind {
    /// The usual Gaussian kernel `exp(-||x - x'||^2 / (2 h^2))`.
    Gaussian,
    /// `exp(-||x - x'|| / h)`, the form the paper prints in Sec. 2.2 (it
    /// calls it Gaussian; with the unsquared norm it is the Laplacian/
    /// exponential kernel, which also has the separating property).
    Laplacian,
}

/// How the bandwidth `h` is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Bandwidth {
    /// The median Euclidean distance between distinct pairs of expert
    /// inputs (the median heuristic), after standardisation if enabled.
    Median,
    /// A given `h > 0`.
    Fixed(f64),
}

/// How the leading eigenpairs of the kernel matrix are computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Eigensolver {
    /// The exact, full eigendecomposition (nalgebra's `SymmetricEigen`,
    /// `O(n^3)` with a large constant).
    Dense,
    /// Block Krylov (Lanczos with full reorthogonalisation) for the
    /// leading eigenpairs only, iterated until every kept pair's residual
    /// `||K v - θ v||` is at most `1e-10 λ_max`; falls back to the dense
    /// solver when more than [`KRYLOV_MAX_DIM`] basis vectors would be
    /// needed. Its start block is drawn from a fixed seed, so the fit
    /// stays deterministic.
    Krylov,
    /// Dense up to [`AUTO_DENSE_MAX`] pairs (or when every component is
    /// kept), Krylov above.
    Auto,
}

/// Largest `n` for which [`Eigensolver::Auto`] uses the dense solver.
pub const AUTO_DENSE_MAX: usize = 1500;
/// Largest Krylov basis before [`Eigensolver::Krylov`] gives up and falls
/// back to the dense solver.
pub const KRYLOV_MAX_DIM: usize = 1536;
/// Residual tolerance of the Krylov solver, relative to `λ_max`.
pub const KRYLOV_TOL: f64 = 1e-10;
/// Columns added to the Krylov basis per step.
const KRYLOV_BLOCK: usize = 64;

/// How many principal components `m` are kept.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Components {
    /// Exactly this many (at most the number of numerically non-zero
    /// eigenvalues).
    Count(usize),
    /// The fewest leading components whose eigenvalues sum to at least this
    /// share (in `(0, 1]`) of the trace of `K`.
    Share(f64),
    /// Every numerically non-zero component.
    All,
}

/// Hyperparameters of [`KernelPca`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct KernelPcaConfig {
    /// The kernel's form.
    pub kernel: KernelKind,
    /// The bandwidth.
    pub bandwidth: Bandwidth,
    /// How the leading eigenpairs of `K` are computed.
    pub eigensolver: Eigensolver,
    /// The number of principal components `m`.
    pub components: Components,
    /// Tikhonov regularisation `λ` (see the module docs); `None` is the
    /// paper's truncated pseudo-inverse.
    pub tikhonov: Option<f64>,
    /// Standardise `[s, a]` with the expert mean and standard deviation.
    pub standardize: bool,
}

impl Default for KernelPcaConfig {
    /// - `kernel`: Gaussian, the kernel the paper names (Sec. 2.2).
    /// - `bandwidth`: the median heuristic; the paper gives no value.
    /// - `eigensolver`: [`Eigensolver::Auto`]: nalgebra's dense solver up
    ///   to 1500 pairs, block Krylov above (measured: the dense solver
    ///   takes about 100 s at 4000 pairs on our 2-core machine, Krylov a
    ///   few seconds; see BENCHMARKS.md).
    /// - `components`: 0.99 of the trace; the paper leaves `m` as a
    ///   hyperparameter. On our synthetic supports this keeps the held-out
    ///   residual of in-support points small while dropping the directions
    ///   that only fit noise.
    /// - `tikhonov`: none, as in the paper's Eq. 4.
    /// - `standardize`: false, as the release feeds raw `[s, a]`.
    fn default() -> Self {
        Self {
            kernel: KernelKind::Gaussian,
            bandwidth: Bandwidth::Median,
            eigensolver: Eigensolver::Auto,
            components: Components::Share(0.99),
            tikhonov: None,
            standardize: false,
        }
    }
}

impl KernelPcaConfig {
    /// Rejects nonsense values, naming the field.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`].
    pub fn validate(&self) -> Result<()> {
        if let Bandwidth::Fixed(h) = self.bandwidth
            && !(h.is_finite() && h > 0.0)
        {
            return Err(invalid(
                "bandwidth",
                format!("must be finite and > 0, got {h}"),
            ));
        }
        match self.components {
            Components::Count(0) => {
                return Err(invalid("components", "a count must be at least 1".into()));
            }
            Components::Share(s) if !(s > 0.0 && s <= 1.0) => {
                return Err(invalid(
                    "components",
                    format!("a share must be in (0, 1], got {s}"),
                ));
            }
            _ => {}
        }
        if let Some(l) = self.tikhonov
            && !(l.is_finite() && l > 0.0)
        {
            return Err(invalid(
                "tikhonov",
                format!("must be finite and > 0 (or absent), got {l}"),
            ));
        }
        Ok(())
    }
}

fn invalid(field: &str, reason: String) -> Error {
    Error::InvalidConfig {
        field: field.into(),
        reason,
    }
}

/// A fitted kernel PCA support estimator.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KernelPca {
    input: InputMap,
    kernel: KernelKind,
    bandwidth: f64,
    /// Expert inputs after the input map, `(n, d)`.
    train: Array2<f64>,
    /// `W = U_m Λ_m^{-1/2}` (unregularised) or `U_m` (regularised), `(n, m)`.
    left: Array2<f64>,
    /// `Z = (K + n λ I)^{-1} U_m` for the regularised variant, `(n, m)`.
    right: Option<Array2<f64>>,
    /// The kept eigenvalues of `K`, descending.
    eigenvalues: Vec<f64>,
    /// The trace of `K`.
    trace: f64,
}

impl KernelPca {
    /// The bandwidth `h` in use.
    pub fn bandwidth(&self) -> f64 {
        self.bandwidth
    }

    /// The number of kept components `m`.
    pub fn components(&self) -> usize {
        self.eigenvalues.len()
    }

    /// The kept eigenvalues of the kernel matrix, descending.
    pub fn eigenvalues(&self) -> &[f64] {
        &self.eigenvalues
    }

    /// The share of the trace of `K` the kept components explain.
    pub fn explained_share(&self) -> f64 {
        self.eigenvalues.iter().sum::<f64>() / self.trace
    }

    /// The number of training pairs `n`.
    pub fn num_train(&self) -> usize {
        self.train.nrows()
    }

    /// `K_q` between the query rows `x` (`(b, d)`) and the training rows,
    /// `(b, n)`, and, for the Laplacian kernel, the distances.
    fn cross_kernel(&self, x: ArrayView2<'_, f64>) -> (Array2<f64>, Option<Array2<f64>>) {
        let d2 = sq_dists(x, self.train.view());
        kernel_from_sq_dists(d2, self.kernel, self.bandwidth)
    }

    fn scores_from(&self, kq: &Array2<f64>) -> (Array1<f64>, Array2<f64>, Option<Array2<f64>>) {
        let a = kq.dot(&self.left);
        let b = self.right.as_ref().map(|z| kq.dot(z));
        let proj = match &b {
            Some(b) => (&a * b).sum_axis(Axis(1)),
            None => a.mapv(|v| v * v).sum_axis(Axis(1)),
        };
        // k(x, x) = 1 for both kernels; the exact score is >= 0 (a squared
        // norm), so anything below is rounding.
        let scores = proj.mapv(|p| (1.0 - p).max(0.0));
        (scores, a, b)
    }
}

impl SupportModel for KernelPca {
    fn obs_dim(&self) -> usize {
        self.input.obs_dim
    }

    fn act_dim(&self) -> usize {
        self.input.act_dim
    }

    fn score(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<Array1<f64>> {
        let x = self.input.apply(states, actions)?;
        let (kq, _) = self.cross_kernel(x.view());
        Ok(self.scores_from(&kq).0)
    }

    fn score_grad_action(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<(Array1<f64>, Array2<f64>)> {
        let x = self.input.apply(states, actions)?;
        let (kq, dist) = self.cross_kernel(x.view());
        let (scores, a, b) = self.scores_from(&kq);
        // d/dx of sum_j a_j b_j with a = U^T K_x, b = Z^T K_x is
        // (U b + Z a)^T dK_x/dx; in the symmetric case 2 W a.
        let coef = match (&b, &self.right) {
            (Some(b), Some(z)) => b.dot(&self.left.t()) + a.dot(&z.t()),
            _ => a.dot(&self.left.t()) * 2.0,
        };
        // dk_i/dx = k_i (x_i - x) / h^2 (Gaussian) or k_i (x_i - x) / (h d_i)
        // (Laplacian), so grad L = -sum_i m_i (x_i - x) with m_i = coef_i *
        // k_i * (that factor).
        let mut m = &coef * &kq;
        match (self.kernel, dist) {
            (KernelKind::Gaussian, _) => m /= self.bandwidth * self.bandwidth,
            (KernelKind::Laplacian, Some(d)) => {
                m.zip_mut_with(&d, |v, &di| {
                    *v = if di > 0.0 {
                        *v / (self.bandwidth * di)
                    } else {
                        0.0
                    }
                });
            }
            (KernelKind::Laplacian, None) => unreachable!("the Laplacian kernel keeps distances"),
        }
        let msum = m.sum_axis(Axis(1));
        let mut grad_x = m.dot(&self.train);
        for ((mut g, xi), (ms, sc)) in grad_x
            .rows_mut()
            .into_iter()
            .zip(x.rows())
            .zip(msum.iter().zip(&scores))
        {
            if *sc == 0.0 {
                // Clamped at zero: the score is flat there.
                g.fill(0.0);
                continue;
            }
            g.zip_mut_with(&xi, |gv, &xv| *gv = -(*gv - ms * xv));
        }
        Ok((scores, self.input.action_grad(grad_x.view())))
    }
}

impl SupportEstimatorConfig for KernelPcaConfig {
    type Model = KernelPca;

    fn validate(&self) -> Result<()> {
        KernelPcaConfig::validate(self)
    }

    /// Fits by the eigendecomposition of the `n x n` kernel matrix (see
    /// [`Eigensolver`]: dense and exact, or block Krylov for the leading
    /// pairs); `rng` is not used (the fit is deterministic). Progress counts
    /// three stages: kernel matrix, eigenpairs, projection (with the
    /// regularised solve).
    fn fit<R: Rng + ?Sized>(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
        _rng: &mut R,
        progress: &mut dyn FnMut(FitProgress),
    ) -> Result<KernelPca> {
        self.validate()?;
        let input = InputMap::fit(states, actions, self.standardize)?;
        let x = input.apply(states, actions)?;
        let n = x.nrows();
        if n < 2 {
            return Err(Error::TooFewSamples {
                what: "kernel PCA".into(),
                need: 2,
                got: n,
            });
        }
        let stage = |done| FitProgress {
            done,
            total: 3,
            loss: None,
        };
        let d2 = sq_dists(x.view(), x.view());
        let bandwidth = match self.bandwidth {
            Bandwidth::Fixed(h) => h,
            Bandwidth::Median => median_distance(&d2)?,
        };
        let (k, _) = kernel_from_sq_dists(d2, self.kernel, bandwidth);
        progress(stage(1));

        let trace: f64 = k.diag().sum();
        let components = self.components;
        let need = move |vals: &[f64]| needed_components(vals, trace, components);
        let use_krylov = match self.eigensolver {
            Eigensolver::Dense => false,
            Eigensolver::Krylov => true,
            Eigensolver::Auto => n > AUTO_DENSE_MAX && components != Components::All,
        };
        let krylov = if use_krylov {
            leading_eigen_krylov(&k, &need)?
        } else {
            None
        };
        let (values, vectors) = match krylov {
            Some(found) => found,
            None => sorted_eigen(&k)?,
        };
        let m = need(&values).unwrap_or_else(|| positive_count(&values));
        let u_m = vectors.slice(ndarray::s![.., ..m]).to_owned();
        progress(stage(2));

        let (left, right) = match self.tikhonov {
            None => {
                let mut w = u_m;
                for (mut col, lam) in w.columns_mut().into_iter().zip(&values) {
                    col /= lam.sqrt();
                }
                (w, None)
            }
            Some(lambda) => {
                let z = tikhonov_solve_clarabel(&k, n as f64 * lambda, u_m.view())?;
                (u_m, Some(z))
            }
        };
        progress(stage(3));
        Ok(KernelPca {
            input,
            kernel: self.kernel,
            bandwidth,
            train: x,
            left,
            right,
            eigenvalues: values[..m].to_vec(),
            trace,
        })
    }
}

/// Squared Euclidean distances between the rows of `a` (`(p, d)`) and `b`
/// (`(q, d)`), `(p, q)`, by `|a|^2 + |b|^2 - 2 a b^T` (clamped at 0).
pub(crate) fn sq_dists(a: ArrayView2<'_, f64>, b: ArrayView2<'_, f64>) -> Array2<f64> {
    let na: Array1<f64> = a.rows().into_iter().map(|r| r.dot(&r)).collect();
    let nb: Array1<f64> = b.rows().into_iter().map(|r| r.dot(&r)).collect();
    let mut d2 = a.dot(&b.t());
    for (i, mut row) in d2.rows_mut().into_iter().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (na[i] + nb[j] - 2.0 * *v).max(0.0);
        }
    }
    d2
}

fn kernel_from_sq_dists(
    mut d2: Array2<f64>,
    kind: KernelKind,
    h: f64,
) -> (Array2<f64>, Option<Array2<f64>>) {
    match kind {
        KernelKind::Gaussian => {
            let c = -1.0 / (2.0 * h * h);
            d2.mapv_inplace(|v| (c * v).exp());
            (d2, None)
        }
        KernelKind::Laplacian => {
            d2.mapv_inplace(f64::sqrt);
            let k = d2.mapv(|d| (-d / h).exp());
            (k, Some(d2))
        }
    }
}

/// The median distance over distinct pairs `i < j` of a squared-distance
/// matrix.
fn median_distance(d2: &Array2<f64>) -> Result<f64> {
    let n = d2.nrows();
    let mut v = Vec::with_capacity(n * (n - 1) / 2);
    for i in 0..n {
        for j in i + 1..n {
            v.push(d2[[i, j]]);
        }
    }
    let mid = v.len() / 2;
    let (_, med, _) = v.select_nth_unstable_by(mid, f64::total_cmp);
    let h = med.sqrt();
    if h > 0.0 && h.is_finite() {
        Ok(h)
    } else {
        Err(Error::Numerical {
            what: "median bandwidth".into(),
            reason: "more than half of the expert pairs coincide; give a fixed bandwidth".into(),
        })
    }
}

/// The number of leading eigenvalues above the numerical cutoff.
fn positive_count(vals: &[f64]) -> usize {
    let lmax = vals.first().copied().unwrap_or(0.0);
    vals.iter()
        .take_while(|&&v| v > EIGEN_RELATIVE_CUTOFF * lmax)
        .count()
}

/// The number of components `m` the rule asks for, given the leading
/// eigenvalues `vals` (descending; possibly only some of them), or `None`
/// if more eigenvalues are needed to tell.
fn needed_components(vals: &[f64], trace: f64, components: Components) -> Option<usize> {
    let pos = positive_count(vals);
    // A value below the cutoff is in the list: every positive one is known.
    let all_known = pos < vals.len();
    match components {
        Components::Count(c) if c <= pos => Some(c),
        Components::Share(share) => {
            let mut acc = 0.0;
            for (j, v) in vals[..pos].iter().enumerate() {
                acc += v;
                if acc >= share * trace {
                    return Some(j + 1);
                }
            }
            all_known.then_some(pos)
        }
        _ => all_known.then_some(pos),
    }
}

/// The leading eigenpairs of the symmetric positive semi-definite `k` by
/// block Lanczos with full reorthogonalisation and Rayleigh-Ritz: returns
/// the `m` pairs `need` asks for once each has a residual of at most
/// [`KRYLOV_TOL`] `λ_max`, or `None` if the basis would exceed
/// [`KRYLOV_MAX_DIM`].
fn leading_eigen_krylov(
    k: &Array2<f64>,
    need: &dyn Fn(&[f64]) -> Option<usize>,
) -> Result<Option<(Vec<f64>, Array2<f64>)>> {
    use rand::{RngExt, SeedableRng};
    let n = k.nrows();
    let max_dim = KRYLOV_MAX_DIM.min(n);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x6b70_6361);
    let mut q = Array2::<f64>::zeros((n, max_dim));
    let mut kq = Array2::<f64>::zeros((n, max_dim));
    let mut w = Array2::from_shape_fn((n, KRYLOV_BLOCK.min(max_dim)), |_| {
        rng.random_range(-1.0..1.0)
    });
    let mut dim = 0;
    while dim < max_dim {
        let b = w.ncols().min(max_dim - dim);
        let mut block = w.slice(s![.., ..b]).to_owned();
        orthonormalise_against(q.slice(s![.., ..dim]), &mut block, &mut rng);
        q.slice_mut(s![.., dim..dim + b]).assign(&block);
        let kb = k.dot(&block);
        kq.slice_mut(s![.., dim..dim + b]).assign(&kb);
        dim += b;
        if dim >= 2 * KRYLOV_BLOCK || dim == max_dim {
            let qd = q.slice(s![.., ..dim]);
            let kqd = kq.slice(s![.., ..dim]);
            let t = qd.t().dot(&kqd);
            let tm = nalgebra::DMatrix::from_fn(dim, dim, |i, j| 0.5 * (t[[i, j]] + t[[j, i]]));
            let eig = nalgebra::SymmetricEigen::new(tm);
            let mut order: Vec<usize> = (0..dim).collect();
            order.sort_by(|&a, &c| eig.eigenvalues[c].total_cmp(&eig.eigenvalues[a]));
            let theta: Vec<f64> = order.iter().map(|&j| eig.eigenvalues[j]).collect();
            if let Some(m) = need(&theta)
                && (m < dim || dim == n)
            {
                let sm = Array2::from_shape_fn((dim, m), |(i, c)| eig.eigenvectors[(i, order[c])]);
                let v = qd.dot(&sm);
                let kv = kqd.dot(&sm);
                let lmax = theta[0];
                let converged = (0..m).all(|j| {
                    let r: f64 = kv
                        .column(j)
                        .iter()
                        .zip(v.column(j))
                        .map(|(a, b)| (a - theta[j] * b).powi(2))
                        .sum();
                    r.sqrt() <= KRYLOV_TOL * lmax
                });
                if converged {
                    return Ok(Some((theta[..m].to_vec(), v)));
                }
            }
        }
        w = kb;
    }
    Ok(None)
}

/// Makes the columns of `block` orthonormal and orthogonal to the
/// orthonormal columns of `basis` (block Gram-Schmidt, twice, then
/// Gram-Schmidt within the block). A column that vanishes (the Krylov space
/// is exhausted in that direction) is replaced by a random one.
fn orthonormalise_against<R: Rng + ?Sized>(
    basis: ArrayView2<'_, f64>,
    block: &mut Array2<f64>,
    rng: &mut R,
) {
    use rand::RngExt;
    for _ in 0..2 {
        if basis.ncols() > 0 {
            let c = basis.t().dot(&*block);
            *block -= &basis.dot(&c);
        }
    }
    for j in 0..block.ncols() {
        for _ in 0..3 {
            let before = block.column(j).dot(&block.column(j)).sqrt();
            for _ in 0..2 {
                for i in 0..j {
                    let d = block.column(i).dot(&block.column(j));
                    let ci = block.column(i).to_owned();
                    block.column_mut(j).scaled_add(-d, &ci);
                }
            }
            let norm = block.column(j).dot(&block.column(j)).sqrt();
            if norm > 1e-8 * before.max(f64::MIN_POSITIVE) && norm > 0.0 {
                block.column_mut(j).mapv_inplace(|v| v / norm);
                break;
            }
            // Degenerate: restart the column from noise, orthogonal to the
            // basis, and try again.
            let mut fresh: Array1<f64> = (0..block.nrows())
                .map(|_| rng.random_range(-1.0..1.0))
                .collect();
            for _ in 0..2 {
                if basis.ncols() > 0 {
                    let c = basis.t().dot(&fresh);
                    fresh -= &basis.dot(&c);
                }
            }
            block.column_mut(j).assign(&fresh);
        }
    }
}

/// Eigenvalues (descending) and eigenvectors (columns, same order) of a
/// symmetric matrix.
fn sorted_eigen(k: &Array2<f64>) -> Result<(Vec<f64>, Array2<f64>)> {
    let n = k.nrows();
    let m = nalgebra::DMatrix::from_fn(n, n, |i, j| k[[i, j]]);
    let eig = nalgebra::SymmetricEigen::try_new(m, 1e-15, 0).ok_or_else(|| Error::Numerical {
        what: "kernel matrix eigendecomposition".into(),
        reason: "the eigensolver did not converge".into(),
    })?;
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let values: Vec<f64> = order.iter().map(|&j| eig.eigenvalues[j]).collect();
    let vectors = Array2::from_shape_fn((n, n), |(i, c)| eig.eigenvectors[(i, order[c])]);
    if values[0].is_nan() || values[0] <= 0.0 {
        return Err(Error::Numerical {
            what: "kernel matrix eigendecomposition".into(),
            reason: "the kernel matrix has no positive eigenvalue".into(),
        });
    }
    Ok((values, vectors))
}

/// Solves `(K + shift I) Z = B` column by column with `clarabel`, each
/// column as the unconstrained convex QP `min 1/2 z^T (K + shift I) z -
/// b^T z`. `k` is `(n, n)` symmetric positive semi-definite, `shift > 0`,
/// `rhs` is `(n, c)`; returns `(n, c)`.
///
/// # Errors
/// [`Error::Numerical`] if clarabel rejects the problem or does not report
/// it solved.
pub fn tikhonov_solve_clarabel(
    k: &Array2<f64>,
    shift: f64,
    rhs: ArrayView2<'_, f64>,
) -> Result<Array2<f64>> {
    let n = k.nrows();
    // Upper triangle in compressed-column form, as clarabel expects for P.
    let mut colptr = Vec::with_capacity(n + 1);
    let mut rowval = Vec::with_capacity(n * (n + 1) / 2);
    let mut nzval = Vec::with_capacity(n * (n + 1) / 2);
    colptr.push(0);
    for j in 0..n {
        for i in 0..=j {
            rowval.push(i);
            nzval.push(if i == j { k[[i, j]] + shift } else { k[[i, j]] });
        }
        colptr.push(rowval.len());
    }
    let p = CscMatrix::new(n, n, colptr, rowval, nzval);
    let a = CscMatrix::<f64>::zeros((0, n));
    let cones: [SupportedConeT<f64>; 0] = [];
    let fail = |reason: String| Error::Numerical {
        what: "Tikhonov solve (clarabel)".into(),
        reason,
    };
    let mut z = Array2::zeros((n, rhs.ncols()));
    for (c, b) in rhs.columns().into_iter().enumerate() {
        let q: Vec<f64> = b.iter().map(|v| -v).collect();
        let settings = DefaultSettingsBuilder::default()
            .verbose(false)
            .tol_gap_abs(1e-12)
            .tol_gap_rel(1e-12)
            .tol_feas(1e-12)
            .build()
            .map_err(|e| fail(format!("settings: {e:?}")))?;
        let mut solver = DefaultSolver::new(&p, &q, &a, &[], &cones, settings)
            .map_err(|e| fail(e.to_string()))?;
        solver.solve();
        match solver.solution.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => {}
            s => return Err(fail(format!("column {c}: status {s:?}"))),
        }
        for (i, v) in solver.solution.x.iter().enumerate() {
            z[[i, c]] = *v;
        }
    }
    Ok(z)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimator::no_progress;
    use rand::RngExt;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    fn cloud(n: usize, d: usize, seed: u64) -> Array2<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        Array2::from_shape_fn((n, d), |_| rng.random_range(-1.0..1.0))
    }

    fn split(x: &Array2<f64>, obs: usize) -> (Array2<f64>, Array2<f64>) {
        (
            x.slice(ndarray::s![.., ..obs]).to_owned(),
            x.slice(ndarray::s![.., obs..]).to_owned(),
        )
    }

    #[test]
    fn all_components_score_training_points_at_zero() {
        let x = cloud(60, 3, 1);
        let (s, a) = split(&x, 2);
        for kernel in [KernelKind::Gaussian, KernelKind::Laplacian] {
            let cfg = KernelPcaConfig {
                kernel,
                bandwidth: Bandwidth::Fixed(0.3),
                components: Components::All,
                ..Default::default()
            };
            let model = cfg
                .fit(
                    s.view(),
                    a.view(),
                    &mut ChaCha8Rng::seed_from_u64(0),
                    &mut no_progress,
                )
                .unwrap();
            assert_eq!(
                model.components(),
                60,
                "{kernel:?}: K should be full rank here"
            );
            let sc = model.score(s.view(), a.view()).unwrap();
            let worst = sc.iter().cloned().fold(0.0, f64::max);
            // k(x, x) = 1, so this is relative to k(x, x).
            assert!(worst < 1e-6, "{kernel:?}: worst training score {worst}");
        }
    }

    #[test]
    fn clarabel_tikhonov_solve_matches_cholesky() {
        let x = cloud(40, 4, 2);
        let d2 = sq_dists(x.view(), x.view());
        let (k, _) = kernel_from_sq_dists(d2, KernelKind::Gaussian, 0.8);
        let shift = 40.0 * 1e-3;
        let b = cloud(40, 3, 3);
        let z = tikhonov_solve_clarabel(&k, shift, b.view()).unwrap();
        let mut m = nalgebra::DMatrix::from_fn(40, 40, |i, j| k[[i, j]]);
        for i in 0..40 {
            m[(i, i)] += shift;
        }
        let chol = nalgebra::Cholesky::new(m).unwrap();
        let bm = nalgebra::DMatrix::from_fn(40, 3, |i, j| b[[i, j]]);
        let closed = chol.solve(&bm);
        for c in 0..3 {
            let num: f64 = (0..40).map(|i| (z[[i, c]] - closed[(i, c)]).powi(2)).sum();
            let den: f64 = (0..40).map(|i| closed[(i, c)].powi(2)).sum();
            let rel = (num / den).sqrt();
            assert!(rel < 1e-6, "column {c}: relative error {rel}");
        }
    }

    #[test]
    fn regularised_scores_match_the_closed_form() {
        let x = cloud(30, 3, 4);
        let (s, a) = split(&x, 2);
        let lambda = 1e-3;
        let cfg = KernelPcaConfig {
            bandwidth: Bandwidth::Fixed(0.7),
            components: Components::All,
            tikhonov: Some(lambda),
            ..Default::default()
        };
        let model = cfg
            .fit(
                s.view(),
                a.view(),
                &mut ChaCha8Rng::seed_from_u64(0),
                &mut no_progress,
            )
            .unwrap();
        let q = cloud(10, 3, 5) * 1.5;
        let (qs, qa) = split(&q, 2);
        let got = model.score(qs.view(), qa.view()).unwrap();
        // Closed form: k(x, x) - K_x^T (K + n λ I)^{-1} K_x, by Cholesky.
        let d2 = sq_dists(x.view(), x.view());
        let (k, _) = kernel_from_sq_dists(d2, KernelKind::Gaussian, 0.7);
        let mut m = nalgebra::DMatrix::from_fn(30, 30, |i, j| k[[i, j]]);
        for i in 0..30 {
            m[(i, i)] += 30.0 * lambda;
        }
        let chol = nalgebra::Cholesky::new(m).unwrap();
        let (kq, _) = kernel_from_sq_dists(sq_dists(q.view(), x.view()), KernelKind::Gaussian, 0.7);
        for r in 0..10 {
            let kx = nalgebra::DVector::from_fn(30, |i, _| kq[[r, i]]);
            let want = 1.0 - kx.dot(&chol.solve(&kx));
            assert!(
                (got[r] - want).abs() <= 1e-6 * want.abs().max(1e-3),
                "row {r}: {} vs {want}",
                got[r]
            );
        }
    }

    #[test]
    fn action_gradient_matches_finite_differences() {
        let x = cloud(50, 4, 6);
        let (s, a) = split(&x, 2);
        for (kernel, tik, std) in [
            (KernelKind::Gaussian, None, false),
            (KernelKind::Gaussian, Some(1e-3), true),
            (KernelKind::Laplacian, None, true),
        ] {
            let cfg = KernelPcaConfig {
                kernel,
                components: Components::Count(10),
                tikhonov: tik,
                standardize: std,
                ..Default::default()
            };
            let model = cfg
                .fit(
                    s.view(),
                    a.view(),
                    &mut ChaCha8Rng::seed_from_u64(0),
                    &mut no_progress,
                )
                .unwrap();
            let q = cloud(6, 4, 7) * 0.8;
            let (qs, qa) = split(&q, 2);
            let (sc, g) = model.score_grad_action(qs.view(), qa.view()).unwrap();
            assert_eq!(sc, model.score(qs.view(), qa.view()).unwrap());
            let eps = 1e-6;
            for r in 0..6 {
                for j in 0..2 {
                    let mut ap = qa.clone();
                    ap[[r, j]] += eps;
                    let mut am = qa.clone();
                    am[[r, j]] -= eps;
                    let fp = model.score(qs.view(), ap.view()).unwrap()[r];
                    let fm = model.score(qs.view(), am.view()).unwrap()[r];
                    let fd = (fp - fm) / (2.0 * eps);
                    assert!(
                        (fd - g[[r, j]]).abs() <= 1e-5 * (1.0 + fd.abs()),
                        "{kernel:?} row {r} dim {j}: fd {fd} vs analytic {}",
                        g[[r, j]]
                    );
                }
            }
        }
    }

    #[test]
    fn krylov_agrees_with_the_dense_solver() {
        // Clustered data: a fast-decaying spectrum, as on real supports.
        let mut x = cloud(600, 5, 8);
        x.mapv_inplace(|v| v.round() * 0.7 + 0.05 * v);
        let (s, a) = split(&x, 3);
        let q = cloud(40, 5, 9);
        let (qs, qa) = split(&q, 3);
        for components in [Components::Share(0.99), Components::Count(40)] {
            let fit = |eigensolver| {
                KernelPcaConfig {
                    components,
                    eigensolver,
                    ..Default::default()
                }
                .fit(
                    s.view(),
                    a.view(),
                    &mut ChaCha8Rng::seed_from_u64(0),
                    &mut no_progress,
                )
                .unwrap()
            };
            let (dense, krylov) = (fit(Eigensolver::Dense), fit(Eigensolver::Krylov));
            assert_eq!(dense.components(), krylov.components(), "{components:?}");
            for (a, b) in dense.eigenvalues().iter().zip(krylov.eigenvalues()) {
                assert!((a - b).abs() <= 1e-9 * dense.eigenvalues()[0], "{a} vs {b}");
            }
            let (sd, sk) = (
                dense.score(qs.view(), qa.view()).unwrap(),
                krylov.score(qs.view(), qa.view()).unwrap(),
            );
            for (a, b) in sd.iter().zip(&sk) {
                assert!((a - b).abs() <= 1e-7, "{components:?}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn config_validation_names_the_field() {
        let bad = KernelPcaConfig {
            components: Components::Share(1.5),
            ..Default::default()
        };
        assert!(
            bad.validate()
                .unwrap_err()
                .to_string()
                .contains("components")
        );
        let bad = KernelPcaConfig {
            tikhonov: Some(-1.0),
            ..Default::default()
        };
        assert!(bad.validate().unwrap_err().to_string().contains("tikhonov"));
        let bad = KernelPcaConfig {
            bandwidth: Bandwidth::Fixed(0.0),
            ..Default::default()
        };
        assert!(
            bad.validate()
                .unwrap_err()
                .to_string()
                .contains("bandwidth")
        );
        let json = r#"{"components": {"count": 5}, "bandwidth": "median"}"#;
        let cfg: KernelPcaConfig = serde_json::from_str(json).unwrap();
        assert_eq!(cfg.components, Components::Count(5));
        assert!(serde_json::from_str::<KernelPcaConfig>(r#"{"sigma": 1}"#).is_err());
    }
}
