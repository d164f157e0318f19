//! Laplacian eigenbases (paper §2, "Harmonic analysis on manifolds", eq. (3)).
//!
//! Computes the first k eigenpairs of the generalized problem W φ = λ A φ (W: n × n stiffness,
//! A: diagonal mass, see [`crate::laplacian`]): eigenvalues ascending, eigenvectors
//! A-orthonormal (Φᵀ A Φ = I), with a deterministic sign.
//!
//! Method. With A diagonal and positive we solve the equivalent standard problem for
//! L̃ = A^{-1/2} W A^{-1/2} (φ = A^{-1/2} u) in shift-invert mode: the operator
//! Op = A^{1/2} (W + sA)⁻¹ A^{1/2} = (L̃ + s)⁻¹ has eigenvalues θ = 1/(λ + s), so the smallest λ
//! are the largest θ. (W + sA) is factored once by faer's sparse supernodal Cholesky, and a
//! **block Lanczos method with full reorthogonalization and thick restart** finds the top-k θ.
//!
//! Why our own Lanczos and not faer's `partial_self_adjoint_eigen`: faer's is a single-vector
//! Krylov–Schur that reorthogonalizes one column at a time (memory-bound GEMV). With k' = 350
//! eigenpairs on 50k vertices that is hundreds of gigabytes of memory traffic; the block method
//! here applies the factorization to b right-hand sides at once and orthogonalizes with GEMM
//! (faer's, parallel), and handles eigenvalue multiplicities up to b naturally (symmetric shapes,
//! several components).
//!
//! Small problems (n ≤ [`SpectralOptions::dense_below`]) use faer's dense symmetric eigensolver.
//!
//! The Ritz pairs are checked when the basis is full and, in a cycle that starts with every
//! residual within 10⁴ × the tolerance, about four times on the way (the solve then stops as
//! soon as all pass instead of finishing the cycle).
//!
//! Setting the environment variable `FUNCORR_DEBUG_LANCZOS` prints, at every check, the basis
//! size, the number of converged pairs and the worst residual estimate to stderr.
//!
//! Every returned pair is verified: the residual ‖Wφ − λAφ‖_{A⁻¹} / λ_max (λ_max the largest
//! eigenvalue returned) must be ≤ [`SpectralOptions::max_residual`], else an error is returned.

use std::time::Instant;

use faer::{Mat, MatRef, Side};

use crate::error::{Error, Result};
use crate::laplacian::Laplacian;

mod cache;
mod lanczos;

pub use cache::{load_basis, save_basis, BasisCache};

/// Options of [`eigen_basis`].
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SpectralOptions {
    /// Number of eigenpairs k (1 ≤ k < n).
    pub k: usize,
    /// Lanczos stopping rule: a Ritz pair is converged when its relative residual
    /// ‖Wφ − λAφ‖_{A⁻¹} / λ_k (the measure of [`Basis::residuals`]) is ≤ tol.
    pub tol: f64,
    /// Acceptance threshold on the verified relative residual of every returned pair.
    pub max_residual: f64,
    /// Block size b of the Lanczos method (None: automatic, 4 for k ≤ 120, 8 for k ≤ 250 or
    /// fewer than 16,384 vertices, else 16).
    pub block_size: Option<usize>,
    /// Maximum number of restarts before giving up.
    pub max_restarts: usize,
    /// Seed of the random start block.
    pub seed: u64,
    /// Problems with n ≤ this use the dense eigensolver.
    pub dense_below: usize,
}

impl SpectralOptions {
    /// Defaults for k eigenpairs: tol 1e-8, max_residual 1e-6, automatic block size,
    /// 300 restarts, seed 0, dense below 1,000 vertices.
    pub fn new(k: usize) -> Self {
        SpectralOptions {
            k,
            tol: 1e-8,
            max_residual: 1e-6,
            block_size: None,
            max_restarts: 300,
            seed: 0,
            dense_below: 1000,
        }
    }

    /// Checks the tolerances: `max_residual` finite and > 0, `tol` finite, > 0 and ≤
    /// `max_residual` (a looser stopping rule than the acceptance threshold would stop with
    /// pairs the check then rejects, or, from the cache, serve any basis). Errors:
    /// [`Error::Invalid`] naming `tol` or `max_residual`.
    pub fn validate(&self) -> Result<()> {
        if !(self.max_residual.is_finite() && self.max_residual > 0.0) {
            return Err(Error::invalid("max_residual", format!("must be finite and > 0, got {:e}", self.max_residual)));
        }
        if !(self.tol.is_finite() && self.tol > 0.0 && self.tol <= self.max_residual) {
            return Err(Error::invalid(
                "tol",
                format!(
                    "the eigensolver's tolerance must be in (0, {:e}] (the residual every pair is checked against), got {:e}",
                    self.max_residual, self.tol
                ),
            ));
        }
        Ok(())
    }
}

/// A truncated Laplacian eigenbasis.
#[derive(Debug, Clone)]
pub struct Basis {
    /// λ₁ ≤ … ≤ λ_k (length k), in units⁻² for meshes.
    pub eigenvalues: Vec<f64>,
    /// Φ (n × k), column i the eigenvector of λᵢ; Φᵀ A Φ = I.
    pub eigenvectors: Mat<f64>,
    /// A (length n): the vertex weights the basis is orthonormal for.
    pub mass: Vec<f64>,
    /// Verified relative residual ‖Wφᵢ − λᵢAφᵢ‖_{A⁻¹} / λ_k of every pair (length k); λ_k is
    /// floored at 10⁻⁶ · tr(W)/tr(A) when k ≤ the number of connected components.
    pub residuals: Vec<f64>,
}

impl Basis {
    /// Number of vertices n.
    pub fn n(&self) -> usize {
        self.eigenvectors.nrows()
    }
    /// Number of eigenpairs k.
    pub fn k(&self) -> usize {
        self.eigenvalues.len()
    }
    /// The first `k` eigenpairs as a new basis (Φ_k), `k ≤ self.k()`.
    pub fn truncate(&self, k: usize) -> Result<Basis> {
        if k == 0 || k > self.k() {
            return Err(Error::invalid("k", format!("cannot take {k} of {} eigenpairs", self.k())));
        }
        Ok(Basis {
            eigenvalues: self.eigenvalues[..k].to_vec(),
            eigenvectors: self.eigenvectors.subcols(0, k).to_owned(),
            mass: self.mass.clone(),
            residuals: self.residuals[..k].to_vec(),
        })
    }
}

/// What the solver did (for reports and benchmarks).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct SolveInfo {
    /// `"dense"` or `"block-lanczos"`.
    pub method: String,
    /// Shift s of the factored matrix W + sA.
    pub shift: f64,
    /// Lanczos block size b.
    pub block_size: usize,
    /// Maximum Krylov basis dimension.
    pub max_basis: usize,
    /// Number of thick restarts.
    pub restarts: usize,
    /// Number of vectors the operator was applied to.
    pub operator_applications: usize,
    /// Wall time of the sparse factorization, seconds.
    pub factor_seconds: f64,
    /// Wall time of the iteration (and dense solve), seconds.
    pub iterate_seconds: f64,
}

/// Progress callback: (converged eigenpairs, wanted eigenpairs).
pub type Progress<'a> = &'a (dyn Fn(usize, usize) + Sync);

pub(crate) use crate::rng::Normal;

/// Computes the first k eigenpairs of W φ = λ A φ. See the module documentation.
///
/// Errors: k = 0 or k ≥ n, non-positive or non-finite mass, a failed factorization, no
/// convergence within the restart budget, or a verified residual above the threshold.
pub fn eigen_basis(lap: &Laplacian, opts: &SpectralOptions, progress: Option<Progress>) -> Result<(Basis, SolveInfo)> {
    let n = lap.n();
    let k = opts.k;
    if k == 0 || k >= n {
        return Err(Error::invalid("k", format!("need 1 ≤ k < n = {n} eigenpairs, got k = {k}")));
    }
    if let Some(i) = lap.mass.iter().position(|a| !(a.is_finite() && *a > 0.0)) {
        return Err(Error::invalid("mass", format!("vertex {i} has weight {}; all must be positive", lap.mass[i])));
    }
    if let Some(p) = lap.w.val().iter().position(|v| !v.is_finite()) {
        return Err(Error::invalid("W", format!("entry {p} of the stiffness matrix is not finite")));
    }
    opts.validate()?;
    // The solver works on the problem of the shape scaled to unit area (A / area_total): W is
    // dimensionless (cotangent weights) or unchanged, so every number the solvers see is the same
    // whatever the shape's units (faer's dense and tridiagonal eigensolvers have absolute
    // thresholds: at 10⁻³ of a body's size the Ritz values fell below them and Lanczos stalled
    // at residuals of 10⁻⁶). Then λ = λ' / area_total and φ = φ' / √area_total.
    let total: f64 = lap.mass.iter().sum();
    if !(total.is_finite() && total > 0.0) {
        return Err(Error::invalid("mass", format!("the total vertex weight {total} must be finite and positive")));
    }
    let unit = lap.with_mass(lap.mass.iter().map(|a| a / total).collect());
    let sqrt_m: Vec<f64> = unit.mass.iter().map(|a| a.sqrt()).collect();
    let (mut theta_lambda, u, mut info) = if n <= opts.dense_below {
        dense_eigen(&unit, &sqrt_m, k)?
    } else {
        lanczos::lanczos(&unit, &sqrt_m, opts, progress)?
    };
    drop(unit);
    let t_post = Instant::now();
    theta_lambda.iter_mut().for_each(|l| *l /= total);
    info.shift /= total;
    let sqrt_m: Vec<f64> = lap.mass.iter().map(|a| a.sqrt()).collect();
    // φ = A^{-1/2} u into a matrix of its own size (the solver's U may live in the larger
    // allocation of its Krylov basis, which is freed here), then a deterministic sign.
    let solver_u = u;
    let mut u = Mat::<f64>::from_fn(n, k, |i, j| solver_u[(i, j)] / sqrt_m[i]);
    drop(solver_u);
    for j in 0..k {
        fix_sign(u.col_as_slice_mut(j), &lap.mass);
    }
    // Verify every pair.
    let residuals = relative_residuals(lap, &u, &theta_lambda);
    if let Some(j) = residuals.iter().position(|r| !(r.is_finite() && *r <= opts.max_residual)) {
        return Err(Error::numerical(
            "eigensolver",
            format!(
                "eigenpair {j} (λ = {:.6e}) has relative residual {:.3e} > {:.1e}: not converged",
                theta_lambda[j], residuals[j], opts.max_residual
            ),
        ));
    }
    if std::env::var_os("FUNCORR_DEBUG_LANCZOS").is_some() {
        eprintln!("scaling, signs and residuals {:.2} s", t_post.elapsed().as_secs_f64());
    }
    let lam_k = theta_lambda[k - 1].abs();
    for l in &mut theta_lambda {
        // Round-off can make the zero eigenvalue(s) slightly negative; W is PSD.
        if *l < 0.0 && *l > -1e-10 * lam_k {
            *l = 0.0;
        }
    }
    Ok((Basis { eigenvalues: theta_lambda, eigenvectors: u, mass: lap.mass.clone(), residuals }, info))
}

/// [`eigen_basis`] through a [`BasisCache`]: returns the cached basis when an intact one with at
/// least k eigenpairs, computed with a tolerance ≤ `opts.tol`, exists for this Laplacian (then
/// `SolveInfo` is `None`), otherwise computes and stores it. A failure to write the cache is a
/// warning on stderr, not an error.
pub fn eigen_basis_cached(
    lap: &Laplacian,
    opts: &SpectralOptions,
    cache: Option<&BasisCache>,
    progress: Option<Progress>,
) -> Result<(Basis, Option<SolveInfo>)> {
    opts.validate()?;
    let key = cache.map(|_| BasisCache::key(lap));
    if let (Some(c), Some(key)) = (cache, &key) {
        if let Some(b) = c.get(key, lap.n(), opts.k, opts.tol) {
            return Ok((b, None));
        }
    }
    let (b, info) = eigen_basis(lap, opts, progress)?;
    if let (Some(c), Some(key)) = (cache, &key) {
        // The basis is computed: a cache that cannot be written costs the next run time, not
        // this run its result.
        if let Err(e) = c.put(key, &b, opts.tol) {
            eprintln!("warning: could not write the eigenbasis cache: {e}");
        }
    }
    Ok((b, Some(info)))
}

/// 10⁻⁶ · tr(W)/tr(A): the mean of the spectrum (tr(W)/tr(A)), scaled far below the eigenvalues
/// anyone asks for on a shape of more than a few hundred vertices. The block Lanczos solver's
/// first shift, and the floor of [`residual_scale`].
pub(crate) fn low_end_scale(lap: &Laplacian) -> f64 {
    let trace_w: f64 = (0..lap.n()).map(|i| lap.w.as_ref().get(i, i).copied().unwrap_or(0.0)).sum();
    let trace_a: f64 = lap.mass.iter().sum();
    1e-6 * trace_w / trace_a
}

/// The scale residuals are measured against: |λ_k|, but at least `floor` =
/// [`low_end_scale`]. Without the floor a request for no more eigenpairs than the shape has
/// connected components (every λ ≈ 0, e.g. `-k 1`) divides by ≈ 0 and never converges; with it
/// those pairs are measured against the spectrum's own scale.
pub(crate) fn residual_scale(lambda_k: f64, floor: f64) -> f64 {
    lambda_k.abs().max(floor).max(f64::MIN_POSITIVE)
}

/// Relative residuals ‖Wφⱼ − λⱼAφⱼ‖_{A⁻¹} / [`residual_scale`] (|λ_k| for every shape with more
/// connected components than k) of the columns of Φ (n × k), λ_k the last (largest) eigenvalue:
/// the measure of [`Basis::residuals`].
pub(crate) fn relative_residuals(lap: &Laplacian, phi: &Mat<f64>, lambda: &[f64]) -> Vec<f64> {
    relative_residuals_scaled(lap, phi.as_ref(), None, lambda)
}

/// [`relative_residuals`] of φ = A^{-1/2} u column by column (`sqrt_m` = A^{1/2}, length n), or
/// of φ = u when `sqrt_m` is `None`, without an n × k copy. Columns in parallel; each column's
/// sums are sequential, so the values do not depend on the number of threads.
pub(crate) fn relative_residuals_scaled(
    lap: &Laplacian,
    u: MatRef<f64>,
    sqrt_m: Option<&[f64]>,
    lambda: &[f64],
) -> Vec<f64> {
    use rayon::prelude::*;
    let lam_max = residual_scale(lambda.last().copied().unwrap_or(0.0), low_end_scale(lap));
    (0..u.ncols())
        .into_par_iter()
        .map(|j| {
            let scaled: Vec<f64>;
            let col = match sqrt_m {
                Some(s) => {
                    scaled = column(u, j).iter().zip(s).map(|(x, s)| x / s).collect();
                    &scaled[..]
                }
                None => column(u, j),
            };
            let wphi = lap.apply_w(col);
            let r2: f64 = wphi
                .iter()
                .zip(col)
                .zip(&lap.mass)
                .map(|((w, p), a)| {
                    let r = w - lambda[j] * a * p;
                    r * r / a
                })
                .sum();
            r2.sqrt() / lam_max
        })
        .collect()
}

/// Column j of a column-major view as a slice.
pub(super) fn column(m: MatRef<'_, f64>, j: usize) -> &[f64] {
    m.col(j).try_as_col_major().expect("faer matrices are column-major").as_slice()
}

/// Sign convention: the A-weighted third moment Σ aᵢφᵢ³ is positive (invariant under vertex
/// permutation and rigid motion); when it vanishes (|moment| below 1e-10 of its scale), the
/// entry of largest magnitude (first on ties) is positive.
fn fix_sign(phi: &mut [f64], mass: &[f64]) {
    let m3: f64 = phi.iter().zip(mass).map(|(p, a)| a * p * p * p).sum();
    let scale: f64 = phi.iter().zip(mass).map(|(p, a)| a * p.abs().powi(3)).sum();
    let flip = if m3.abs() > 1e-10 * scale {
        m3 < 0.0
    } else {
        let mut best = 0usize;
        for (i, p) in phi.iter().enumerate() {
            if p.abs() > phi[best].abs() * (1.0 + 1e-12) {
                best = i;
            }
        }
        phi[best] < 0.0
    };
    if flip {
        phi.iter_mut().for_each(|p| *p = -*p);
    }
}

/// Dense path: eigen-decomposition of L̃ = A^{-1/2} W A^{-1/2}. Returns (λ, U) with U n × k.
fn dense_eigen(lap: &Laplacian, sqrt_m: &[f64], k: usize) -> Result<(Vec<f64>, Mat<f64>, SolveInfo)> {
    let t0 = Instant::now();
    let n = lap.n();
    let w = lap.w.as_ref();
    let mut l = Mat::<f64>::zeros(n, n);
    for c in 0..n {
        for p in w.symbolic().col_ptr()[c]..w.symbolic().col_ptr()[c + 1] {
            let r = w.symbolic().row_idx()[p];
            l[(r, c)] += w.val()[p] / (sqrt_m[r] * sqrt_m[c]);
        }
    }
    let evd = l
        .self_adjoint_eigen(Side::Lower)
        .map_err(|e| Error::numerical("eigensolver", format!("dense eigensolver failed: {e:?}")))?;
    let lambda: Vec<f64> = (0..k).map(|i| evd.S()[i]).collect();
    let u = evd.U().subcols(0, k).to_owned();
    let info = SolveInfo { method: "dense".into(), iterate_seconds: t0.elapsed().as_secs_f64(), ..Default::default() };
    Ok((lambda, u, info))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::laplacian::{cotangent, graph, VertexWeights};
    use crate::primitives::{bumpy_sphere, cycle_edges, icosphere, rectangle};
    use crate::shape::TriMesh;

    fn solve(lap: &Laplacian, k: usize) -> Basis {
        eigen_basis(lap, &SpectralOptions::new(k), None).unwrap().0
    }

    #[test]
    fn a_tolerance_looser_than_the_acceptance_check_names_tol() {
        let lap = cotangent(&icosphere(1)).unwrap();
        let cache = BasisCache::new(std::env::temp_dir().join(format!("funcorr-tol-{}", std::process::id())));
        for tol in [1e300, 1e-3, f64::NAN, f64::INFINITY, 0.0, -1.0] {
            let o = SpectralOptions { tol, ..SpectralOptions::new(5) };
            for r in
                [eigen_basis(&lap, &o, None).map(|_| ()), eigen_basis_cached(&lap, &o, Some(&cache), None).map(|_| ())]
            {
                match r {
                    Err(Error::Invalid { what, .. }) => assert_eq!(what, "tol"),
                    other => panic!("tol {tol}: {other:?}"),
                }
            }
        }
        assert!(SpectralOptions { tol: 1e-6, ..SpectralOptions::new(5) }.validate().is_ok());
        let _ = std::fs::remove_dir_all(cache.dir());
    }

    /// Φᵀ A Φ = I to `tol`.
    fn assert_mass_orthonormal(b: &Basis, tol: f64) {
        for i in 0..b.k() {
            for j in 0..=i {
                let d: f64 = (0..b.n()).map(|r| b.eigenvectors[(r, i)] * b.mass[r] * b.eigenvectors[(r, j)]).sum();
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((d - want).abs() < tol, "(ΦᵀAΦ)[{i},{j}] = {d}");
            }
        }
    }

    #[test]
    fn icosphere_spectrum_is_l_l_plus_1() {
        let mesh = icosphere(4);
        assert!(mesh.n_vertices() >= 2500);
        let lap = cotangent(&mesh).unwrap();
        let (b, info) = eigen_basis(&lap, &SpectralOptions::new(25), None).unwrap();
        assert_eq!(info.method, "block-lanczos");
        assert!(b.eigenvalues[0].abs() < 1e-8);
        for l in 1..5usize {
            let exact = (l * (l + 1)) as f64;
            for i in l * l..(l + 1) * (l + 1) {
                let rel = (b.eigenvalues[i] - exact).abs() / exact;
                assert!(rel < 0.02, "λ[{i}] = {} vs l(l+1) = {exact}", b.eigenvalues[i]);
            }
        }
        assert_mass_orthonormal(&b, 1e-8);
        assert!(b.residuals.iter().all(|r| *r < 1e-8));
    }

    #[test]
    fn rectangle_spectrum_is_neumann() {
        let (a, bb) = (2.0, 1.0);
        let lap = cotangent(&rectangle(a, bb, 100, 50)).unwrap();
        let k = 15;
        let b = solve(&lap, k);
        let pi2 = std::f64::consts::PI.powi(2);
        let mut exact: Vec<f64> = (0..20)
            .flat_map(|i| (0..20).map(move |j| pi2 * ((i * i) as f64 / (a * a) + (j * j) as f64 / (bb * bb))))
            .collect();
        exact.sort_by(f64::total_cmp);
        assert!(b.eigenvalues[0].abs() < 1e-8);
        for i in 1..k {
            let rel = (b.eigenvalues[i] - exact[i]).abs() / exact[i];
            assert!(rel < 0.01, "λ[{i}] = {} vs {}", b.eigenvalues[i], exact[i]);
        }
        assert_mass_orthonormal(&b, 1e-8);
    }

    #[test]
    fn cotangent_w_is_symmetric_psd_with_zero_row_sums() {
        let mesh = icosphere(3);
        let lap = cotangent(&mesh).unwrap();
        let n = lap.n();
        let mut dense = Mat::<f64>::zeros(n, n);
        let w = lap.w.as_ref();
        for c in 0..n {
            for p in w.symbolic().col_ptr()[c]..w.symbolic().col_ptr()[c + 1] {
                dense[(w.symbolic().row_idx()[p], c)] += w.val()[p];
            }
        }
        let scale = (0..n).map(|i| dense[(i, i)]).fold(0.0, f64::max);
        for i in 0..n {
            let row: f64 = (0..n).map(|j| dense[(i, j)]).sum();
            assert!(row.abs() < 1e-12 * scale);
            for j in 0..n {
                assert_eq!(dense[(i, j)], dense[(j, i)]);
            }
        }
        let ev = dense.self_adjoint_eigenvalues(Side::Lower).unwrap();
        assert!(ev[0] > -1e-12 * scale, "min eigenvalue {}", ev[0]);
        let area: f64 = lap.mass.iter().sum();
        assert!((area - mesh.total_area()).abs() < 1e-12 * area);
    }

    #[test]
    fn cycle_graph_eigenvalues() {
        for n in [60usize, 1500] {
            let lap = graph(n, &cycle_edges(n), VertexWeights::Identity).unwrap();
            let k = 21;
            let (b, info) = eigen_basis(&lap, &SpectralOptions::new(k), None).unwrap();
            assert_eq!(info.method, if n <= 1000 { "dense" } else { "block-lanczos" });
            let mut exact: Vec<f64> =
                (0..n).map(|j| 2.0 - 2.0 * (2.0 * std::f64::consts::PI * j as f64 / n as f64).cos()).collect();
            exact.sort_by(f64::total_cmp);
            for i in 0..k {
                assert!(
                    (b.eigenvalues[i] - exact[i]).abs() < 1e-9 * exact[k - 1],
                    "n={n} λ[{i}] = {} vs {}",
                    b.eigenvalues[i],
                    exact[i]
                );
            }
            assert_mass_orthonormal(&b, 1e-8);
        }
    }

    #[test]
    fn permuted_and_moved_copy_has_same_spectrum() {
        let a = bumpy_sphere(3);
        let n = a.n_vertices();
        // A deterministic permutation and a rigid motion (rotation about z by 0.7 rad + shift).
        let perm: Vec<usize> = (0..n).map(|i| (i * 7919) % n).collect();
        let (c, s) = (0.7f64.cos(), 0.7f64.sin());
        let b = a
            .permuted(&perm)
            .unwrap()
            .map_vertices(|p| [c * p[0] - s * p[1] + 5.0, s * p[0] + c * p[1] - 2.0, p[2] + 1.0])
            .unwrap();
        let (ba, bb) = (solve(&cotangent(&a).unwrap(), 30), solve(&cotangent(&b).unwrap(), 30));
        for i in 1..30 {
            let rel = (ba.eigenvalues[i] - bb.eigenvalues[i]).abs() / ba.eigenvalues[i];
            assert!(rel < 1e-9, "λ[{i}]: {} vs {}", ba.eigenvalues[i], bb.eigenvalues[i]);
        }
        // Simple eigenvalues: the permuted eigenvector equals the original, sign included.
        for i in 1..30 {
            let gap = (ba.eigenvalues[i] - ba.eigenvalues[i - 1])
                .min(ba.eigenvalues.get(i + 1).map_or(f64::MAX, |l| l - ba.eigenvalues[i]));
            if gap < 1e-3 * ba.eigenvalues[i] {
                continue;
            }
            let err = (0..n)
                .map(|new| (bb.eigenvectors[(new, i)] - ba.eigenvectors[(perm[new], i)]).abs())
                .fold(0.0, f64::max);
            assert!(err < 1e-6, "eigenvector {i} differs by {err}");
        }
    }

    #[test]
    fn lanczos_agrees_with_dense() {
        let lap = cotangent(&icosphere(3)).unwrap(); // 642 vertices
        let mut opts = SpectralOptions::new(40);
        let dense = eigen_basis(&lap, &opts, None).unwrap().0;
        opts.dense_below = 0;
        opts.block_size = Some(4); // smaller than the multiplicities 5, 7, 9, 11: must still find them
        let (lz, info) = eigen_basis(&lap, &opts, None).unwrap();
        assert_eq!(info.method, "block-lanczos");
        for i in 0..40 {
            assert!(
                (dense.eigenvalues[i] - lz.eigenvalues[i]).abs() < 1e-9 * dense.eigenvalues[39],
                "λ[{i}] {} vs {}",
                dense.eigenvalues[i],
                lz.eigenvalues[i]
            );
        }
    }

    #[test]
    fn disconnected_shape_has_repeated_zero() {
        let s = icosphere(3);
        let n = s.n_vertices() as u32;
        let mut v = s.vertices().to_vec();
        v.extend(s.vertices().iter().map(|p| [p[0] + 3.0, p[1], p[2]]));
        let mut f = s.faces().to_vec();
        f.extend(s.faces().iter().map(|t| [t[0] + n, t[1] + n, t[2] + n]));
        let lap = cotangent(&TriMesh::new(v, f).unwrap()).unwrap();
        let b = solve(&lap, 10);
        assert!(b.eigenvalues[0].abs() < 1e-8 && b.eigenvalues[1].abs() < 1e-8);
        for i in 2..8 {
            assert!((b.eigenvalues[i] - 2.0).abs() < 0.05, "λ[{i}] = {}", b.eigenvalues[i]);
        }
        assert!(b.eigenvalues[8] > 5.0);
        // As many eigenpairs as components (every λ ≈ 0), and fewer: the null space, converged.
        for k in [1, 2] {
            let b = solve(&lap, k);
            assert!(b.eigenvalues.iter().all(|l| l.abs() < 1e-8), "k = {k}: {:?}", b.eigenvalues);
            assert!(b.residuals.iter().all(|r| *r <= 1e-6), "k = {k}: {:?}", b.residuals);
        }
        let one = solve(&cotangent(&s).unwrap(), 1);
        assert!(one.eigenvalues[0].abs() < 1e-8);
    }

    #[test]
    fn multiplicities_larger_than_the_block_are_found() {
        // Six identical spheres: every eigenvalue has multiplicity 6 × (its multiplicity on one
        // sphere), e.g. 6 zeros and 18 copies of λ ≈ 2, far above the default block size 4.
        let s = icosphere(2);
        let n1 = s.n_vertices() as u32;
        let mut v = Vec::new();
        let mut f = Vec::new();
        for c in 0..6u32 {
            v.extend(s.vertices().iter().map(|p| [p[0] + 3.0 * c as f64, p[1], p[2]]));
            f.extend(s.faces().iter().map(|t| [t[0] + c * n1, t[1] + c * n1, t[2] + c * n1]));
        }
        let lap = cotangent(&TriMesh::new(v, f).unwrap()).unwrap();
        let k = 40;
        let mut opts = SpectralOptions::new(k);
        let dense = eigen_basis(&lap, &opts, None).unwrap().0;
        opts.dense_below = 0;
        let (lz, info) = eigen_basis(&lap, &opts, None).unwrap();
        assert!(info.block_size > 18, "block size {} cannot hold 18 copies", info.block_size);
        for i in 0..k {
            let scale = dense.eigenvalues[k - 1];
            assert!(
                (dense.eigenvalues[i] - lz.eigenvalues[i]).abs() < 1e-9 * scale,
                "λ[{i}]: {} vs {}",
                dense.eigenvalues[i],
                lz.eigenvalues[i]
            );
        }
        assert_mass_orthonormal(&lz, 1e-8);
    }

    #[test]
    fn knn_laplacian_of_sphere_points_has_sphere_spectrum_up_to_scale() {
        // The paper's point-cloud Laplacian (eq. (1)) approximates c·Δ on uniform samples, so the
        // eigenvalue ratios are those of the sphere, l(l+1)/2, with multiplicities 1, 3, 5.
        use crate::laplacian::{knn_graph, KnnOptions};
        let pts = icosphere(4).to_point_set();
        let lap = knn_graph(&pts, &KnnOptions::default()).unwrap();
        let b = solve(&lap, 16);
        assert!(b.eigenvalues[0].abs() < 1e-10);
        let unit = b.eigenvalues[1..4].iter().sum::<f64>() / 6.0; // l = 1: l(l+1) = 2
        for (range, ll) in [(1..4, 2.0), (4..9, 6.0), (9..16, 12.0)] {
            for i in range {
                let ratio = b.eigenvalues[i] / unit;
                assert!((ratio - ll).abs() < 0.05 * ll, "λ[{i}]/c = {ratio}, want {ll}");
            }
        }
    }

    #[test]
    fn bad_k_is_an_error() {
        let lap = cotangent(&icosphere(1)).unwrap();
        let n = lap.n();
        assert!(eigen_basis(&lap, &SpectralOptions::new(0), None).is_err());
        assert!(eigen_basis(&lap, &SpectralOptions::new(n), None).is_err());
        assert!(eigen_basis(&lap, &SpectralOptions::new(n + 5), None).is_err());
        let mut o = SpectralOptions::new(5);
        o.dense_below = 0;
        // n = 42 is too small for the iterative solver with k = 30.
        o.k = 30;
        assert!(eigen_basis(&lap, &o, None).is_err());
    }
}
