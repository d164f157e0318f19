//! The objective of problem (11): the weighted sum of the [`super::terms`].

use faer::{Mat, MatRef};
use serde::{Deserialize, Serialize};

use super::l1::Precision;
use super::terms::{self, TermValue};
use super::{Form, Problem, Scaling};

/// Which norm the low-norm term μ4/2 (‖Ψ A‖² + ‖Φ B‖²) uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum LowNorm {
    /// Euclidean Frobenius norms of the m × k and n × k matrices Ψ A, Φ B, as (11) is written:
    /// ‖Φ B‖²_F = tr(Bᵀ (Φᵀ Φ) B) with the Gram matrix Φᵀ Φ (≠ I for mass-orthonormal bases).
    Euclidean,
    /// Mass-weighted norms ‖Φ B‖²_{A_X} = tr(Bᵀ Φᵀ A_X Φ B) = ‖B‖²_F: independent of the meshing.
    Mass,
}

/// Parameters of problem (11). Defaults are the paper's: μ1 = μ2 = 1e-8, μ3 = 1e-5, μ4 = 1e-8,
/// ξ = 1e-3, with the optional commutativity term off.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CompletionParams {
    /// Weight of the Dirichlet energy on X, tr(A Bᵀ Λ_X B Aᵀ).
    pub mu1: f64,
    /// Weight of the Dirichlet energy on Y, tr(B Aᵀ Λ_Y A Bᵀ).
    pub mu2: f64,
    /// Weight of the L1 term Σ √(t² + ξ) over the m × n matrix T.
    pub mu3: f64,
    /// Weight of the low-norm term ½ (‖Ψ A‖² + ‖Φ B‖²).
    pub mu4: f64,
    /// Smoothing of the absolute value, |t| ≈ √(t² + ξ).
    pub xi: f64,
    /// Weight of the optional Laplacian-commutativity term ‖C_c Λ_X − Λ_Y C_c‖² (0 = off).
    pub mu_comm: f64,
    /// Size k_c of the leading block C_c of C = A Bᵀ the commutativity term acts on (0 = all k').
    pub k_comm: usize,
    /// Weight of the optional axiomatic prior ([`super::terms::prior`]: the functional-map energy
    /// of [`crate::fmap::energy`] without its descriptor term, on a leading block of C; 0 = off).
    /// The energy itself is part of the [`Problem`] ([`Problem::prior`]).
    #[serde(default)]
    pub mu_prior: f64,
    /// Norm of the low-norm term.
    pub low_norm: LowNorm,
    /// Rows of T per block of the L1 computation.
    pub block_rows: usize,
    /// Arithmetic of the L1 term's products ([`Precision`]; f64 by default).
    #[serde(default)]
    pub l1_precision: Precision,
}

impl Default for CompletionParams {
    fn default() -> Self {
        CompletionParams {
            mu1: 1e-8,
            mu2: 1e-8,
            mu3: 1e-5,
            mu4: 1e-8,
            xi: 1e-3,
            mu_comm: 0.0,
            k_comm: 0,
            mu_prior: 0.0,
            low_norm: LowNorm::Euclidean,
            block_rows: 256,
            l1_precision: Precision::F64,
        }
    }
}

/// Default Dirichlet weight μ1 = μ2 of the vertex forms (8)–(10) under [`Scaling::Unit`] (the
/// subspace form's is 1e-2); see [`CompletionParams::defaults_for_form`].
pub const VERTEX_DIRICHLET: f64 = 0.3;

impl CompletionParams {
    /// The default weights of a [`Scaling`] for the subspace form (11): the paper's for
    /// [`Scaling::Paper`]; for [`Scaling::Unit`], weights chosen on the faust_r development pairs
    /// (EXPERIMENTS.md). The vertex forms have their own: [`Self::defaults_for_form`].
    pub fn defaults_for(scaling: Scaling) -> Self {
        match scaling {
            Scaling::Paper => CompletionParams::default(),
            Scaling::Unit => CompletionParams {
                mu1: 1e-2,
                mu2: 1e-2,
                mu3: 1e-2,
                mu4: 1e-3,
                xi: 1e-2,
                low_norm: LowNorm::Mass,
                ..CompletionParams::default()
            },
        }
    }

    /// The default weights of `form` under `scaling`.
    ///
    /// - Subspace form (11): [`Self::defaults_for`].
    /// - Vertex forms (8)–(10) with [`Scaling::Unit`]: the same μ3, ξ (and μ4 for (9), (10); μ4 = 0
    ///   for the fixed-rank form (8), which has no low-norm term), but μ1 = μ2 =
    ///   `VERTEX_DIRICHLET` = 0.3 instead of 0.01. In (11) T = Ψ_k' A Bᵀ Φ_k'ᵀ cannot leave the
    ///   first k' eigenfunctions; on the vertices nothing but the Dirichlet terms keeps T smooth,
    ///   and the L1 term alone favours spiky, high-frequency kernels. With the scale-free
    ///   Dirichlet weights (λ_j / Σ_{l ≤ k'} λ_l, an orthonormal k'-map costs 1), a component of
    ///   T at eigenfunction j costs μ · λ_j / Σ_{l ≤ k'} λ_l ≈ 2μ j / k'² per unit energy (Weyl:
    ///   λ_j ∝ j); μ must be large enough for the content beyond j ≈ k' to cost more than the L1
    ///   term gains from it. Measured (module [`super::solve`] tests; bumpy sphere and a
    ///   renumbered, rescaled copy, 642 vertices, k = ¾ k', default stopping rule, nearest
    ///   neighbours of the rows of the factors): with μ = 0.01, 71 % (fixed rank, RCG), 85 %
    ///   (fixed rank, L-BFGS), 84 % (low norm) of the vertices recovered at k' = 40, and 66 %
    ///   (fixed rank) at k' = 120 with μ = 0.03; with μ = 0.3, 97–100 % for k' = 20, 40, 60 and
    ///   120. Every μ in [0.1, 1] gives ≥ 96 % for k' ≥ 40 except the low-norm form at k' = 120,
    ///   μ = 0.1 (70 %); larger μ over-smooths T (μ = 3: the map through C falls to 49–80 %).
    ///   0.3 is the middle of that range on a log scale. The largest entry of each column of T
    ///   (`--extract argmax`) is a poor reading of such smooth kernels (9–52 % at μ = 0.3): use
    ///   nearest neighbours (the default) or the functional map.
    /// - [`Scaling::Paper`]: the paper's literal weights for every form.
    pub fn defaults_for_form(scaling: Scaling, form: Form) -> Self {
        let mut p = CompletionParams::defaults_for(scaling);
        if scaling == Scaling::Unit && form != Form::Subspace {
            p.mu1 = VERTEX_DIRICHLET;
            p.mu2 = VERTEX_DIRICHLET;
        }
        if form == Form::FixedRank {
            p.mu4 = 0.0;
        }
        p
    }

    /// Errors when a weight is negative or not finite, ξ < 0, or the block size is 0.
    pub fn validate(&self) -> crate::Result<()> {
        let named = [
            ("mu1", self.mu1),
            ("mu2", self.mu2),
            ("mu3", self.mu3),
            ("mu4", self.mu4),
            ("xi", self.xi),
            ("commutativity", self.mu_comm),
            ("prior weight", self.mu_prior),
        ];
        for (name, v) in named {
            if !(v.is_finite() && v >= 0.0) {
                return Err(crate::Error::invalid(name, format!("must be finite and ≥ 0, got {v}")));
            }
        }
        if self.block_rows == 0 {
            return Err(crate::Error::invalid("block rows", "must be at least 1"));
        }
        Ok(())
    }
}

/// Weighted values of the terms of (11) at one point, and their sum.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Terms {
    /// ‖A Bᵀ Â − B̂‖².
    pub data: f64,
    /// μ1 tr(A Bᵀ Λ_X B Aᵀ).
    pub dirichlet_x: f64,
    /// μ2 tr(B Aᵀ Λ_Y A Bᵀ).
    pub dirichlet_y: f64,
    /// μ3 Σ √(t² + ξ).
    pub l1: f64,
    /// μ4/2 (‖Ψ A‖² + ‖Φ B‖²).
    pub low_norm: f64,
    /// μ_c ‖C_c Λ_X − Λ_Y C_c‖².
    pub commutativity: f64,
    /// μ_p E(s C_c), the axiomatic prior ([`super::terms::prior`]).
    #[serde(default)]
    pub prior: f64,
    /// The objective, the sum of the above.
    pub total: f64,
}

impl Terms {
    /// The sum of the weighted terms (what `total` holds).
    pub fn sum(&self) -> f64 {
        self.data + self.dirichlet_x + self.dirichlet_y + self.l1 + self.low_norm + self.commutativity + self.prior
    }
}

/// Objective value (per term) and gradient at one point.
#[derive(Clone, Debug)]
pub struct Evaluation {
    /// The weighted terms.
    pub terms: Terms,
    /// ∂/∂A of the total (k' × k).
    pub grad_a: Mat<f64>,
    /// ∂/∂B of the total (k' × k).
    pub grad_b: Mat<f64>,
}

fn check_shapes(problem: &Problem, a: MatRef<f64>, b: MatRef<f64>) {
    let kp = problem.k_prime();
    assert!(
        a.nrows() == kp && b.nrows() == kp && a.ncols() == b.ncols(),
        "A is {}×{} and B {}×{}; both must be k'×k with k' = {kp}",
        a.nrows(),
        a.ncols(),
        b.nrows(),
        b.ncols()
    );
}

/// The Gram matrices Φᵀ Φ, Ψᵀ Ψ (k' × k' each).
type Grams<'p> = (MatRef<'p, f64>, MatRef<'p, f64>);

/// The Gram matrices (Euclidean norm, [`Scaling::Paper`] only) and the factor of the low-norm
/// term: 1 ([`Scaling::Paper`]) or 1/k ([`Scaling::Unit`], mass norms, so that an orthonormal
/// rank-k map has low norm 1).
fn low_norm_setup<'p>(problem: &'p Problem, params: &CompletionParams, k: usize) -> (Option<Grams<'p>>, f64) {
    match (problem.scaling, params.low_norm) {
        (Scaling::Unit, _) => (None, 1.0 / k as f64),
        (Scaling::Paper, LowNorm::Euclidean) => (Some((problem.gram_x.as_ref(), problem.gram_y.as_ref())), 1.0),
        (Scaling::Paper, LowNorm::Mass) => (None, 1.0),
    }
}

/// Eigenvalues of the commutativity term, divided by the largest of both in the block (so the
/// weight means the same as [`crate::fmap::OvsjanikovOptions::commutativity`]), and the block size.
fn comm_setup(problem: &Problem, params: &CompletionParams) -> (Vec<f64>, Vec<f64>, usize) {
    let kc = if params.k_comm == 0 { problem.k_prime() } else { params.k_comm.min(problem.k_prime()) };
    let (ex, ey) = (&problem.eigenvalues_x[..kc], &problem.eigenvalues_y[..kc]);
    let lmax = ex.iter().chain(ey).fold(0.0f64, |m, l| m.max(l.abs()));
    let norm = if lmax > 0.0 { lmax } else { 1.0 };
    (ex.iter().map(|l| l / norm).collect(), ey.iter().map(|l| l / norm).collect(), kc)
}

/// The objective of (11) (plus the optional commutativity term) and its gradient at (A, B).
/// Terms whose weight is 0 are skipped (value 0). Panics if A, B are not both k' × k.
///
/// The terms that are functions of C = A Bᵀ (data, Dirichlet, commutativity, prior, and the L1
/// term when k' < 2k) share one C and one chain rule: their gradient Z = ∂f/∂C (k' × k') is
/// summed first and ∇_A = Z B, ∇_B = Zᵀ A formed once (forming C and chaining per term cost
/// 1.7 s of a 13.1 s completion stage on a 5k pair at k' = 350, k = 250; BENCHMARKS.md).
/// With k' ≥ 2k the L1 term keeps its factored gradients ([`terms::l1`]), cheaper there.
pub fn evaluate(problem: &Problem, params: &CompletionParams, a: MatRef<f64>, b: MatRef<f64>) -> Evaluation {
    check_shapes(problem, a, b);
    let l1_in_c = a.nrows() < 2 * a.ncols();
    let (mut terms, z) = c_terms(problem, params, a, b, l1_in_c);
    let (mut grad_a, mut grad_b) = rayon::join(|| super::mul(z.as_ref(), b), || super::mul(z.transpose(), a));
    let mut add = |w: f64, t: TermValue| -> f64 {
        grad_a += &t.grad_a * w;
        grad_b += &t.grad_b * w;
        w * t.value
    };
    if params.mu3 != 0.0 && !l1_in_c {
        let (phi, psi, weights) = problem.l1_operands();
        let t = terms::l1(a, b, phi, psi, params.xi, weights, params.block_rows, params.l1_precision);
        terms.l1 = add(params.mu3, t);
    }
    if params.mu4 != 0.0 {
        let (grams, w) = low_norm_setup(problem, params, a.ncols());
        terms.low_norm = add(params.mu4 * w, terms::low_norm(a, b, grams));
    }
    terms.total = terms.sum();
    Evaluation { terms, grad_a, grad_b }
}

/// The terms of the objective at C = A Bᵀ that depend on C alone (all but the low norm,
/// which is left at 0) and their gradient Z = ∂f/∂C (k' × k'), for solvers that work on C
/// directly (the fixed-rank form, [`super::fixed_rank`]).
pub fn gradient_c(problem: &Problem, params: &CompletionParams, a: MatRef<f64>, b: MatRef<f64>) -> (Terms, Mat<f64>) {
    check_shapes(problem, a, b);
    let (mut t, z) = c_terms(problem, params, a, b, true);
    t.total = t.sum();
    (t, z)
}

/// The weighted terms that are functions of C = A Bᵀ — data, Dirichlet, commutativity, prior,
/// and the L1 term if `with_l1` — at one C, and the sum Z of their gradients in C (k' × k').
/// `total` is left at 0.
fn c_terms(
    problem: &Problem,
    params: &CompletionParams,
    a: MatRef<f64>,
    b: MatRef<f64>,
    with_l1: bool,
) -> (Terms, Mat<f64>) {
    // The L1 term (both cores inside) side by side with the terms of C, which run on one core;
    // its gradient is added last, as before.
    let l1 = || {
        (with_l1 && params.mu3 != 0.0).then(|| {
            let (phi, psi, weights) = problem.l1_operands();
            terms::l1_c(a, b, phi, psi, params.xi, weights, params.block_rows, params.l1_precision)
        })
    };
    let ((mut t, mut z), l1) = rayon::join(
        || {
            let c = super::mul(a, b.transpose());
            let (data, mut z) = terms::data_c(c.as_ref(), problem.f_hat.as_ref(), problem.g_hat.as_ref());
            let mut t = Terms { data, ..Terms::default() };
            let mut add = |w: f64, (value, g): (f64, Mat<f64>)| -> f64 {
                z += &g * w;
                w * value
            };
            if params.mu1 != 0.0 {
                t.dirichlet_x = add(params.mu1, terms::dirichlet_x_c(c.as_ref(), &problem.lambda_x));
            }
            if params.mu2 != 0.0 {
                t.dirichlet_y = add(params.mu2, terms::dirichlet_y_c(c.as_ref(), &problem.lambda_y));
            }
            if params.mu_comm != 0.0 {
                let (lx, ly, kc) = comm_setup(problem, params);
                t.commutativity = add(params.mu_comm, terms::commutativity_c(c.as_ref(), &lx, &ly, kc));
            }
            if let (true, Some(e)) = (params.mu_prior != 0.0, &problem.prior) {
                t.prior = add(params.mu_prior, terms::prior_c(c.as_ref(), e, problem.c_scale));
            }
            (t, z)
        },
        l1,
    );
    if let Some((value, g)) = l1 {
        z += &g * params.mu3;
        t.l1 = params.mu3 * value;
    }
    (t, z)
}

/// The weighted terms of the objective at (A, B) without gradients (the L1 term costs 2·m·n·k
/// flops instead of 6·m·n·k).
pub fn value(problem: &Problem, params: &CompletionParams, a: MatRef<f64>, b: MatRef<f64>) -> Terms {
    check_shapes(problem, a, b);
    // The C terms' gradients in C are elementwise or k'² q: negligible beside the L1 value.
    let (mut terms, _) = c_terms(problem, params, a, b, false);
    if params.mu3 != 0.0 {
        let (phi, psi, weights) = problem.l1_operands();
        terms.l1 =
            params.mu3 * terms::l1_value(a, b, phi, psi, params.xi, weights, params.block_rows, params.l1_precision);
    }
    if params.mu4 != 0.0 {
        let (grams, w) = low_norm_setup(problem, params, a.ncols());
        terms.low_norm = params.mu4 * w * terms::low_norm(a, b, grams).value;
    }
    terms.total = terms.sum();
    terms
}

/// The diagonal of the Hessian of the terms of (11) that depend on C = A Bᵀ alone, with
/// respect to C (k' × k'), at C = A Bᵀ (A, B: k' × k); the building block of the diagonal
/// preconditioner of [`super::optimize`] ([`Precondition`]).
///
/// Entry (i, j) is ∂²f/∂C_ij²:
/// - data ‖C Â − B̂‖² (Â: k' × q): 2 (Â Âᵀ)_jj (its Hessian is 2 (Â Âᵀ ⊗ I), whose diagonal
///   this keeps);
/// - Dirichlet terms: 2 μ1 λ^X_j + 2 μ2 λ^Y_i (exact, the terms are diagonal in C);
/// - commutativity: 2 μ_c (λ^X_j − λ^Y_i)² inside the k_c × k_c block (exact, normalized
///   eigenvalues as in the term);
/// - the L1 term, only with `l1` = true: μ3 Σ_st w_st φ''(t_st) ψ_si² φ_tj² with
///   φ''(t) = ξ / (t² + ξ)^{3/2}, over the L1 operands (the samples or every vertex: 2·m·n·(k +
///   k') + 2·m·k'² flops, as one gradient evaluation); exact.
///
/// The axiomatic prior ([`CompletionParams::mu_prior`]) and the low-norm term (which is not a
/// function of C) are left out. Panics if A, B are not both k' × k.
pub fn curvature_c(problem: &Problem, params: &CompletionParams, a: MatRef<f64>, b: MatRef<f64>, l1: bool) -> Mat<f64> {
    check_shapes(problem, a, b);
    let kp = problem.k_prime();
    let f = problem.f_hat.as_ref();
    let data: Vec<f64> = (0..kp).map(|j| 2.0 * (0..f.ncols()).map(|p| f[(j, p)] * f[(j, p)]).sum::<f64>()).collect();
    let (lx, ly) = (&problem.lambda_x, &problem.lambda_y);
    let mut h = Mat::from_fn(kp, kp, |i, j| data[j] + 2.0 * params.mu1 * lx[j] + 2.0 * params.mu2 * ly[i]);
    if params.mu_comm != 0.0 {
        let (cx, cy, kc) = comm_setup(problem, params);
        for j in 0..kc {
            for i in 0..kc {
                h[(i, j)] += 2.0 * params.mu_comm * (cx[j] - cy[i]).powi(2);
            }
        }
    }
    if l1 && params.mu3 != 0.0 {
        let (phi, psi, weights) = problem.l1_operands();
        let u = super::gemm_nn(psi, a); // m × k
        let v = super::gemm_nn(phi, b); // n × k
        let phi2 = Mat::from_fn(phi.nrows(), kp, |t, j| phi[(t, j)] * phi[(t, j)]); // n × k'
        let rows = params.block_rows.max(1);
        let xi = params.xi;
        let mut r0 = 0;
        while r0 < u.nrows() {
            let r = rows.min(u.nrows() - r0);
            // K_r = w ∘ φ''(U_r Vᵀ) (r × n), then (Ψ_r ∘ Ψ_r)ᵀ K_r (Φ ∘ Φ) (k' × k').
            let mut kr = super::mul(u.subrows(r0, r), v.transpose());
            for t in 0..kr.ncols() {
                for s in 0..r {
                    let x = kr[(s, t)];
                    let q = x * x + xi;
                    let w = weights.map_or(1.0, |w| w.y[r0 + s] * w.x[t]);
                    kr[(s, t)] = w * xi / (q * q.sqrt());
                }
            }
            let m = super::mul(kr.as_ref(), phi2.as_ref()); // r × k'
            let psi2 = Mat::from_fn(r, kp, |s, i| psi[(r0 + s, i)] * psi[(r0 + s, i)]);
            let block = super::gemm_tn(psi2.as_ref(), m.as_ref()) * faer::Scale(params.mu3);
            h += &block;
            r0 += r;
        }
    }
    h
}

/// The curvature of the weighted low-norm term with respect to the entries of A and B: per row
/// of A (k' values) and per row of B (k'): μ4 w times the diagonal of the Gram matrices Ψᵀ Ψ,
/// Φᵀ Φ (Euclidean norm, [`Scaling::Paper`]) or μ4 w (mass norms), w the term's factor (1/k
/// for [`Scaling::Unit`]); zeros when μ4 = 0.
pub fn low_norm_curvature(problem: &Problem, params: &CompletionParams, k: usize) -> (Vec<f64>, Vec<f64>) {
    let kp = problem.k_prime();
    if params.mu4 == 0.0 {
        return (vec![0.0; kp], vec![0.0; kp]);
    }
    let (grams, w) = low_norm_setup(problem, params, k);
    let c = params.mu4 * w;
    match grams {
        Some((gx, gy)) => ((0..kp).map(|i| c * gy[(i, i)]).collect(), (0..kp).map(|j| c * gx[(j, j)]).collect()),
        None => (vec![c; kp], vec![c; kp]),
    }
}

/// The diagonal preconditioner of L-BFGS on the subspace form (11)
/// ([`super::optimize::optimize_preconditioned`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Precondition {
    /// None: L-BFGS's usual initial inverse Hessian (sᵀy / yᵀy) I.
    #[default]
    Off,
    /// The Gauss–Newton diagonal in (A, B) of the quadratic terms (data, Dirichlet,
    /// commutativity, low norm) ([`curvature_c`] without the L1 term); the L1 term's curvature is
    /// left to L-BFGS's scalar γ (in the preconditioned metric).
    Quadratic,
    /// [`Precondition::Quadratic`] plus the exact diagonal of the L1 term's Hessian in C,
    /// refreshed every 10 iterations.
    Full,
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::completion::testutil::{dot, randn};

    /// A small random problem (random bases: the formulas do not need orthonormality).
    pub(crate) fn random_problem(n: usize, m: usize, kp: usize, q: usize, seed: u64) -> Problem {
        let phi = randn(n, kp, seed) * 0.2;
        let psi = randn(m, kp, seed + 1) * 0.2;
        let lx: Vec<f64> = (0..kp).map(|i| i as f64 * 0.7).collect();
        let ly: Vec<f64> = (0..kp).map(|i| i as f64 * 0.75 + 0.01).collect();
        Problem::from_coefficients(phi, psi, lx, ly, randn(kp, q, seed + 2), randn(kp, q, seed + 3)).unwrap()
    }

    /// A random axiomatic prior (k_c × k_c, q descriptors): every term of the energy but the
    /// descriptor term on, with random coefficients and operators.
    pub(crate) fn random_prior(kc: usize, q: usize, seed: u64) -> crate::fmap::energy::Energy {
        use crate::fmap::energy::{Energy, EnergyWeights, Mask, Orientation, SpectralSide};
        let side = |s: u64, shift: f64| SpectralSide {
            coefficients: randn(kc, q, s),
            eigenvalues: (0..kc).map(|i| i as f64 * 0.7 + shift).collect(),
            multiplication: (0..q).map(|p| randn(kc, kc, s + 10 + p as u64)).collect(),
            orientation: (0..q).map(|p| randn(kc, kc, s + 50 + p as u64)).collect(),
        };
        let w = EnergyWeights { descriptors: 0.0, laplacian: 0.3, commutativity: 0.5, orientation: 0.7 };
        Energy::new(&side(seed, 0.0), &side(seed + 1, 0.05), &w, Mask::Resolvent { gamma: 0.5 }, Orientation::Preserve)
            .unwrap()
    }

    #[test]
    fn total_gradient_matches_finite_differences() {
        let mut p = random_problem(50, 40, 8, 6, 1000).with_prior(random_prior(6, 3, 77)).unwrap();
        p.c_scale = 1.3;
        // Weights large enough that every term matters.
        for low_norm in [LowNorm::Euclidean, LowNorm::Mass] {
            let params = CompletionParams {
                mu1: 0.1,
                mu2: 0.2,
                mu3: 0.05,
                mu4: 0.3,
                xi: 1e-2,
                mu_comm: 0.01,
                k_comm: 6,
                mu_prior: 0.05,
                low_norm,
                block_rows: 16,
                ..Default::default()
            };
            for k in [5, 3] {
                // k' = 8 < 2k: the L1 term joins the shared chain rule; 8 ≥ 2·3: factored gradients.
                let (a, b) = (randn(8, k, 1), randn(8, k, 2));
                let e = evaluate(&p, &params, a.as_ref(), b.as_ref());
                let t = &e.terms;
                let sum = t.data + t.dirichlet_x + t.dirichlet_y + t.l1 + t.low_norm + t.commutativity + t.prior;
                assert!((t.total - sum).abs() < 1e-12 * t.total.abs());
                assert!([t.dirichlet_x, t.dirichlet_y, t.l1, t.low_norm, t.commutativity, t.prior]
                    .iter()
                    .all(|&v| v > 0.0));
                let (tc, _) = gradient_c(&p, &params, a.as_ref(), b.as_ref());
                assert!((tc.prior - t.prior).abs() < 1e-12 * t.prior);
                let v = value(&p, &params, a.as_ref(), b.as_ref());
                assert!((v.total - t.total).abs() < 1e-12 * t.total);
                let (da, db) = (randn(8, k, 3), randn(8, k, 4));
                let h = 1e-5;
                let fp = value(&p, &params, (&a + &da * h).as_ref(), (&b + &db * h).as_ref()).total;
                let fm = value(&p, &params, (&a - &da * h).as_ref(), (&b - &db * h).as_ref()).total;
                let fd = (fp - fm) / (2.0 * h);
                let an = dot(&e.grad_a, &da) + dot(&e.grad_b, &db);
                assert!((fd - an).abs() < 1e-5 * an.abs(), "{fd} vs {an}");
            }
        }
    }

    /// The prior's gradient with respect to C (used by the fixed-rank solvers), by central
    /// differences, with the block smaller than C and a scale s ≠ 1.
    #[test]
    fn prior_gradient_in_c_matches_finite_differences() {
        let e = random_prior(5, 4, 3);
        let (c, dc) = (randn(8, 8, 11), randn(8, 8, 12));
        let (v, g) = terms::prior_c(c.as_ref(), &e, 0.8);
        assert!(v > 0.0);
        assert!((5..8).all(|i| (0..8).all(|j| g[(i, j)] == 0.0 && g[(j, i)] == 0.0)));
        let h = 1e-6;
        let fd = (terms::prior_c((&c + &dc * h).as_ref(), &e, 0.8).0
            - terms::prior_c((&c - &dc * h).as_ref(), &e, 0.8).0)
            / (2.0 * h);
        let an = dot(&g, &dc);
        assert!((fd - an).abs() < 1e-6 * an.abs(), "{fd} vs {an}");
    }

    /// The diagonal curvature in C equals the second differences of the objective along single
    /// entries of C (with A = C, B = I, so that C_ij is one variable), L1 term included.
    #[test]
    fn curvature_in_c_matches_second_differences() {
        let p = random_problem(50, 40, 8, 6, 31);
        let params = CompletionParams {
            mu1: 0.1,
            mu2: 0.2,
            mu3: 0.05,
            mu4: 0.0,
            xi: 1e-2,
            mu_comm: 0.01,
            k_comm: 6,
            block_rows: 16,
            ..CompletionParams::default()
        };
        let c = randn(8, 8, 5) * 0.3;
        let eye = Mat::<f64>::identity(8, 8);
        let h = curvature_c(&p, &params, c.as_ref(), eye.as_ref(), true);
        let h_quad = curvature_c(&p, &params, c.as_ref(), eye.as_ref(), false);
        let step = 1e-4;
        for (i, j) in [(0, 0), (1, 5), (7, 2), (4, 4), (6, 7)] {
            let at = |d: f64| {
                let mut cc = c.clone();
                cc[(i, j)] += d;
                value(&p, &params, cc.as_ref(), eye.as_ref()).total
            };
            let fd = (at(step) - 2.0 * at(0.0) + at(-step)) / (step * step);
            assert!((fd - h[(i, j)]).abs() < 1e-4 * h[(i, j)].abs(), "({i}, {j}): {fd} vs {}", h[(i, j)]);
            assert!(h_quad[(i, j)] > 0.0 && h_quad[(i, j)] < h[(i, j)]);
        }
    }

    #[test]
    fn paper_defaults_and_zero_weights() {
        let d = CompletionParams::default();
        assert_eq!((d.mu1, d.mu2, d.mu3, d.mu4, d.xi, d.mu_comm), (1e-8, 1e-8, 1e-5, 1e-8, 1e-3, 0.0));
        let p = random_problem(30, 30, 6, 4, 7);
        let zero = CompletionParams { mu1: 0.0, mu2: 0.0, mu3: 0.0, mu4: 0.0, ..d };
        let (a, b) = (randn(6, 4, 5), randn(6, 4, 6));
        let e = evaluate(&p, &zero, a.as_ref(), b.as_ref());
        let data = terms::data(a.as_ref(), b.as_ref(), p.f_hat.as_ref(), p.g_hat.as_ref());
        assert_eq!(e.terms.total, data.value);
        assert_eq!(e.grad_a, data.grad_a);
    }
}
