//! Functional correspondence by matrix completion (Kovnatsky, Bronstein, Bresson,
//! Vandergheynst, CVPR 2015, §3): all four forms of the paper.
//!
//! The correspondence is a matrix T (m × n) between functions on X (n vertices) and on Y (m
//! vertices). The subspace form (11), the default, restricts it to the span of the first k'
//! eigenfunctions of each shape and to rank k:
//!
//! ```text
//! T = Ψ_k' A Bᵀ Φ_k'ᵀ,   A, B ∈ R^{k'×k},   C = A Bᵀ ∈ R^{k'×k'} (the functional map),
//!
//!   ‖A Bᵀ Â − B̂‖²_F                                  data            ([`terms::data`])
//! + μ1 tr(A Bᵀ Λ_X B Aᵀ) + μ2 tr(B Aᵀ Λ_Y A Bᵀ)      Dirichlet       ([`terms::dirichlet_x`], [`terms::dirichlet_y`])
//! + μ3 Σ_ij √(t_ij² + ξ)                               L1 of T         ([`terms::l1`], [`l1`])
//! + μ4/2 (‖Ψ_k' A‖²_F + ‖Φ_k' B‖²_F)                   low norm        ([`terms::low_norm`])
//! [+ μ_c ‖C_c Λ_X − Λ_Y C_c‖²_F                        commutativity, optional ([`terms::commutativity`])]
//! ```
//!
//! The vertex-space forms — fixed rank (8), convex low rank (9), low norm (10) — are in
//! `full`, `fixed_rank` (Riemannian CG on the manifold of rank-k matrices, as manopt) and
//! `convex` (ADMM); [`solve()`] runs any of them.
//!
//! ## Mass placement
//! The bases are mass-orthonormal (Φᵀ A_X Φ = I), so the coefficients of the data F (n × q) are
//! Â = Φ_k'ᵀ A_X F, not the paper's literal Φᵀ F (which assumes Euclidean-orthonormal bases; on
//! meshes whose vertex areas vary ~200× the two are not proportional). T is the matrix of the
//! correspondence kernel: f on X maps to g = T A_X f on Y, so T = Ψ C Φᵀ. With this placement
//! every term of the vertex forms equals the term of (11) when U = Ψ_k' A, V = Φ_k' B.
//!
//! ## Scaling: weights that mean the same on every shape ([`Scaling`])
//! Taken literally ([`Scaling::Paper`]), the weights depend on the meshes: the eigenvalues scale
//! as 1 / area, the entries of T as 1 / area and their number as n·m, and the data term with
//! the data's magnitude. [`Scaling::Unit`] (the default) removes every such dependence:
//! - both shapes are rescaled to unit area (Φ̃ = √area_X Φ, masses a / area_X), so T is a
//!   density on Y × X and C is dimensionless (orthonormal for an isometry);
//! - data: ‖C Â − B̂‖² / s with s = (‖F‖²_{A_X} + ‖G‖²_{A_Y}) / 2 — a relative residual;
//! - Dirichlet: eigenvalues λ_j / Σ_{l ≤ k'} λ_l, so an orthonormal C has Dirichlet energy 1
//!   (independent of area; λ·area is scale-free by Weyl's law);
//! - L1: Σ_ij ã^Y_i ã^X_j √(t_ij² + ξ) = ∫∫ √(t² + ξ) dy dx, the integral of the kernel over the
//!   unit-area shapes, independent of n and m (≈ 1 for a localized, mass-preserving map); ξ is
//!   in units of (density)², ξ = 1 meaning the density of a map spread uniformly over Y;
//! - low norm: mass norms divided by k, ½ (‖A‖² + ‖B‖²) / k (= 1 for orthonormal factors);
//! - commutativity: eigenvalues divided by the largest in the block, as in [`crate::fmap`].
//!
//! Default weights ([`CompletionParams::defaults_for_form`]): μ1 = μ2 = 0.01, μ3 = 0.01,
//! μ4 = 0.001, ξ = 0.01 for the subspace form; the vertex forms (8)–(10) take μ1 = μ2 = 0.3
//! (`objective::VERTEX_DIRICHLET`), because on the vertices the Dirichlet terms alone do what
//! the truncation to k' eigenfunctions does in (11).
//!
//! Modules: [`terms`] (each term of (11) with its gradient), `l1` (the blocked L1 kernel),
//! `objective` (their weighted sum), `lbfgs` and `optimize` (L-BFGS with a
//! strong-Wolfe line search, initializations), `full`, `fixed_rank`, `convex`, [`solve`].

pub(crate) mod convex;
pub(crate) mod fixed_rank;
pub(crate) mod full;
pub(crate) mod l1;
pub(crate) mod lbfgs;
pub(crate) mod objective;
pub(crate) mod optimize;
pub(crate) mod solve;
pub mod terms;

pub use l1::Precision;
pub use lbfgs::{CompletionReport, OptimizeOptions};
pub use objective::{curvature_c, evaluate, value, CompletionParams, Evaluation, LowNorm, Precondition, Terms};
pub use optimize::{init_from_c, init_from_svd, optimize, optimize_preconditioned, optimize_until_settled, SettledMap};
pub use solve::{
    solve, solve_with_prior, CompletionOptions, Form, Init, L1Sampling, Optimizer, Solution, SolverReport,
};

pub(crate) use crate::linalg::mul;
// The tall-skinny products (n × k' bases) with the solvers' chunking, under the names the
// submodules call them by: gemm_nn(A, B) = A B, gemm_tn(A, B) = Aᵀ B ([`crate::linalg`]).
pub(crate) use crate::linalg::{a_b as gemm_nn, at_b as gemm_tn};

mod problem;
pub use problem::{L1Sample, Problem, Scaling};

#[cfg(test)]
pub(crate) mod testutil {
    use faer::Mat;

    use crate::spectral::Normal;

    /// A matrix of independent standard normal entries, deterministic in `seed`.
    pub fn randn(rows: usize, cols: usize, seed: u64) -> Mat<f64> {
        let mut rng = Normal::new(seed);
        let mut m = Mat::<f64>::zeros(rows, cols);
        for j in 0..cols {
            for i in 0..rows {
                m[(i, j)] = rng.sample();
            }
        }
        m
    }

    /// ⟨x, y⟩_F.
    pub fn dot(x: &Mat<f64>, y: &Mat<f64>) -> f64 {
        let mut s = 0.0;
        for j in 0..x.ncols() {
            for i in 0..x.nrows() {
                s += x[(i, j)] * y[(i, j)];
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::descriptors::signatures::{hks, hks_times, wks};
    use crate::descriptors::Descriptors;
    use crate::laplacian::cotangent;
    use crate::primitives::bumpy_sphere;
    use crate::shape::TriMesh;
    use crate::spatial::Samples;
    use crate::spectral::Basis;
    use crate::spectral::{eigen_basis, SpectralOptions};
    use faer::{Mat, MatRef};

    /// For every row of `query` the index of the nearest row of `reference` (brute force).
    fn nearest(reference: MatRef<f64>, query: MatRef<f64>) -> Vec<usize> {
        (0..query.nrows())
            .map(|i| {
                let d2 =
                    |j: usize| (0..query.ncols()).map(|c| (query[(i, c)] - reference[(j, c)]).powi(2)).sum::<f64>();
                (0..reference.nrows()).min_by(|&x, &y| d2(x).total_cmp(&d2(y))).unwrap()
            })
            .collect()
    }

    /// The L1 term on random vertex samples ([`Samples::random`]) is an unbiased estimate of
    /// the full term: over 400 seeds, the mean value and gradient (∂/∂C) are within 4 standard
    /// errors of the full ones (642-vertex pair, k' = 20, 60 draws per shape ≈ 1 % of the pairs).
    /// Farthest-point samples, a deterministic quadrature, are closer than one random draw.
    #[test]
    fn sampled_l1_is_unbiased() {
        use crate::completion::full::tests::small_pair;
        let sp = small_pair(3, 20);
        let p = Problem::new(&sp.bx, &sp.by, &sp.f, &sp.g, 20, Scaling::Unit).unwrap();
        let (kp, k) = (20, 20);
        let a = Mat::<f64>::identity(kp, k) + testutil::randn(kp, k, 1) * 0.3;
        let b = Mat::<f64>::identity(kp, k);
        let l1 = |p: &Problem| {
            let (phi, psi, w) = p.l1_operands();
            terms::l1_c(a.as_ref(), b.as_ref(), phi, psi, 1e-2, w, 64, l1::Precision::F64)
        };
        let (full, full_grad) = l1(&p);
        let runs = 400;
        let (mut mean, mut sq) = (0.0, 0.0);
        let mut grad_mean = Mat::<f64>::zeros(kp, kp);
        let mut grad_sq = 0.0;
        let mut estimates = Vec::new();
        for seed in 0..runs {
            let sx = Samples::random(&sp.bx.mass, 60, 2 * seed).unwrap();
            let sy = Samples::random(&sp.by.mass, 60, 2 * seed + 1).unwrap();
            let (v, g) = l1(&p.clone().with_l1_samples(&sx, &sy).unwrap());
            mean += v / runs as f64;
            sq += v * v / runs as f64;
            grad_mean += &g * (1.0 / runs as f64);
            grad_sq += g.squared_norm_l2() / runs as f64;
            estimates.push(v);
        }
        let se = ((sq - mean * mean) / runs as f64).sqrt();
        let grad_se = ((grad_sq - grad_mean.squared_norm_l2()) / runs as f64).sqrt();
        let grad_err = (&grad_mean - &full_grad).norm_l2();
        eprintln!(
            "L1 full {full:.5}, mean of {runs} sampled {mean:.5} ± {se:.5}; ‖mean ∇ − ∇‖ {grad_err:.3e} (se {grad_se:.3e}, ‖∇‖ {:.3e})",
            full_grad.norm_l2()
        );
        assert!(se > 0.0 && (mean - full).abs() <= 4.0 * se, "{mean} vs {full} ± {se}");
        assert!(grad_err <= 4.0 * grad_se, "{grad_err} vs se {grad_se}");
        // The estimate is not trivially exact: single draws scatter.
        assert!(estimates.iter().any(|v| (v - full).abs() > se));
        // Farthest-point samples (60 per shape): closer than the typical random draw.
        let fx = crate::spatial::farthest_point_samples(&sp.px, &sp.bx.mass, 60).unwrap();
        let fy = crate::spatial::farthest_point_samples(&sp.py, &sp.by.mass, 60).unwrap();
        let (fps, _) = l1(&p.clone().with_l1_samples(&fx, &fy).unwrap());
        let spread = (se * (runs as f64).sqrt()).max(f64::MIN_POSITIVE);
        eprintln!("farthest points: {fps:.5} (error {:.2e}; one random draw: {spread:.2e})", (fps - full).abs());
        assert!((fps - full).abs() < spread);
    }

    /// On a mesh and its vertex-permuted copy, with q = 60 descriptors (30 WKS + 30 HKS) and a
    /// perturbed identity as the start, (11) recovers the permutation through nearest neighbours
    /// of the rows of Φ B among the rows of Ψ A.
    ///
    /// Scale: the data columns are normalized to unit mass-norm and the paper's weights μ1…μ4
    /// are multiplied by 1e-4. With the literal paper weights on this 642-vertex mesh the L1 term
    /// outweighs the data term and the optimizer leaves even the exact answer C = I (measured:
    /// 6–52 of 642 vertices correct); the weights do not mean the same on every shape.
    #[test]
    fn recovers_a_vertex_permutation() {
        let x_mesh = bumpy_sphere(3);
        let n = x_mesh.n_vertices();
        // Y = X with vertices renumbered: Y vertex `new` is X vertex `perm[new]`.
        let perm: Vec<usize> = (0..n).map(|i| (i * 7919) % n).collect();
        let y_mesh = x_mesh.permuted(&perm).unwrap();
        let mut inv = vec![0u32; n];
        for (new, &old) in perm.iter().enumerate() {
            inv[old] = new as u32;
        }
        let basis = |m: &TriMesh| eigen_basis(&cotangent(m).unwrap(), &SpectralOptions::new(60), None).unwrap().0;
        let (bx, by) = (basis(&x_mesh), basis(&y_mesh));
        // q = 60 data functions: 30 WKS + 30 HKS on each shape, columns of unit mass-norm.
        let data = |b: &Basis| {
            let w = wks(b, 30, true).unwrap();
            let h = hks(b, &hks_times(b, 30).unwrap(), true).unwrap();
            let d = w.concat(&h).unwrap();
            let norm = |j: usize| (0..d.n()).map(|i| b.mass[i] * d.values[(i, j)].powi(2)).sum::<f64>().sqrt();
            let norms: Vec<f64> = (0..d.q()).map(norm).collect();
            Descriptors::new(Mat::from_fn(d.n(), d.q(), |i, j| d.values[(i, j)] / norms[j]), d.names.clone()).unwrap()
        };
        let (f, g) = (data(&bx), data(&by));
        let (kp, k) = (40, 30);
        let problem = Problem::new(&bx, &by, &f, &g, kp, Scaling::Paper).unwrap();
        // Identity-ish start: C = I_{k'×k} plus a perturbation.
        let (a0, b0) = init_from_c(Mat::<f64>::identity(kp, k).as_ref(), kp, k).unwrap();
        let a0 = a0 + testutil::randn(kp, k, 42) * 0.05;
        let d = CompletionParams::default();
        let params =
            CompletionParams { mu1: d.mu1 * 1e-4, mu2: d.mu2 * 1e-4, mu3: d.mu3 * 1e-4, mu4: d.mu4 * 1e-4, ..d };
        let (a, b, report) =
            optimize(&problem, &params, &OptimizeOptions::default(), a0.as_ref(), b0.as_ref()).unwrap();
        assert!(report.objective_history.windows(2).all(|w| w[1] <= w[0]));
        assert!(report.terms.total < report.initial_terms.total);
        let emb_x = mul(problem.phi.as_ref(), b.as_ref());
        let emb_y = mul(problem.psi.as_ref(), a.as_ref());
        let map = nearest(emb_y.as_ref(), emb_x.as_ref());
        let correct = (0..n).filter(|&i| map[i] == inv[i] as usize).count();
        // The same with the k'-dimensional embedding Φ Cᵀ against Ψ, for the report.
        let c = mul(a.as_ref(), b.transpose());
        let map_c = nearest(problem.psi.as_ref(), mul(problem.phi.as_ref(), c.transpose()).as_ref());
        let correct_c = (0..n).filter(|&i| map_c[i] == inv[i] as usize).count();
        eprintln!(
            "permutation: Φ B → Ψ A {correct}/{n}, Φ Cᵀ → Ψ {correct_c}/{n}; {} iterations ({}), terms {:?} from {:?}",
            report.iterations, report.stop_reason, report.terms, report.initial_terms
        );
        assert!(correct as f64 >= 0.95 * n as f64, "{correct}/{n}");
    }
}
