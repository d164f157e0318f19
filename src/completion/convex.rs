//! The convex low-rank form (9) on the whole m × n correspondence T, by the alternating
//! direction method of multipliers (ADMM; Boyd et al. 2011), one of the augmented Lagrangian
//! methods the paper suggests (§3, §5):
//!
//! ```text
//! min_T  f(T) + μ3 Σ w √(t² + ξ) + μ4' ‖D_Y T D_X‖_*
//! f(T) = ‖T A_X F − G‖²_{A_Y} + μ1 tr(T W_X Tᵀ A_Y)/ν_X + μ2 tr(Tᵀ W_Y T A_X)/ν_Y
//! ```
//!
//! with the terms, weights and scalings of [`super::full::FullProblem`] (D and μ4' from
//! [`super::full::FullProblem::nuclear_scaling`], so that (9) has the same minimum value as
//! the low-norm form (10) with a large enough rank). Splitting Z₁ = T, Z₂ = D_Y T D_X:
//! - T-step: the quadratic f + ρ/2 ‖T − Z₁ + Y₁‖² + ρ/2 ‖D_Y T D_X − Z₂ + Y₂‖², an SPD linear
//!   system in T solved by conjugate gradients (warm-started);
//! - Z₁-step: the proximal map of the smoothed absolute value, per entry, by safeguarded
//!   Newton (soft thresholding when ξ = 0);
//! - Z₂-step: singular value thresholding (a dense SVD of an m × n matrix);
//! - scaled dual updates, residual balancing of ρ, and the stopping rule of Boyd et al. §3.3.
//!
//! **Size limit**: T and the SVD are dense, O(m·n) memory and O(m·n·min(m, n)) flops per
//! iteration; [`solve`] refuses problems with m·n > [`MAX_ENTRIES`] (e.g. 2,000 × 2,000). It is
//! meant for small shapes and graphs; use the low-norm (10) or subspace (11) form beyond.

use crate::linalg::frob;
use std::time::Instant;

use faer::{Mat, MatRef};
use rayon::prelude::*;
use serde::Serialize;

use super::full::{sparse_mul, FullProblem};
use super::objective::{CompletionParams, Terms};
use super::{gemm_nn, mul};
use crate::error::{Error, Result};

/// Over-relaxation parameter α of the Z-steps.
const RELAX: f64 = 1.6;

/// The largest m·n that [`solve`] accepts.
pub const MAX_ENTRIES: usize = 4_000_000;

/// Options of [`solve`].
#[derive(Clone, Debug, Serialize)]
pub struct AdmmOptions {
    /// Iteration cap.
    pub max_iterations: usize,
    /// Absolute tolerance ε_abs of the primal and dual residuals (per √entry).
    pub eps_abs: f64,
    /// Relative tolerance ε_rel.
    pub eps_rel: f64,
    /// Initial penalty ρ.
    pub rho: f64,
    /// Relative tolerance of the conjugate-gradient T-step.
    pub cg_tol: f64,
}

impl Default for AdmmOptions {
    fn default() -> Self {
        AdmmOptions { max_iterations: 5000, eps_abs: 1e-9, eps_rel: 1e-7, rho: 1.0, cg_tol: 1e-10 }
    }
}

/// What [`solve`] did.
#[derive(Clone, Debug, Serialize)]
pub struct AdmmReport {
    /// ADMM iterations.
    pub iterations: usize,
    /// Conjugate-gradient iterations of all T-steps.
    pub cg_iterations: usize,
    /// True when the residual tolerances were met.
    pub converged: bool,
    /// Final primal residual ‖(T − Z₁, D T D − Z₂)‖.
    pub primal_residual: f64,
    /// Final dual residual.
    pub dual_residual: f64,
    /// The terms at the final T (the nuclear norm in `low_norm`).
    pub terms: Terms,
    /// The objective at the T of every 10th iteration.
    pub objective_history: Vec<f64>,
    /// Wall time.
    pub seconds_total: f64,
}

/// diag(dy) X diag(dx).
fn scale2(dy: &[f64], x: MatRef<f64>, dx: &[f64]) -> Mat<f64> {
    Mat::from_fn(x.nrows(), x.ncols(), |i, j| dy[i] * x[(i, j)] * dx[j])
}

/// argmin_z a √(z² + ξ) + ρ/2 (z − v)²: the root of ρ (z − v) + a z / √(z² + ξ), which lies
/// between 0 and v; safeguarded Newton (bisection when a step leaves the bracket).
fn prox_soft_abs(v: f64, a: f64, xi: f64, rho: f64) -> f64 {
    if a == 0.0 || v == 0.0 {
        return v;
    }
    if xi == 0.0 {
        return v.signum() * (v.abs() - a / rho).max(0.0);
    }
    let (mut lo, mut hi) = if v > 0.0 { (0.0, v) } else { (v, 0.0) };
    let mut z = v;
    for _ in 0..100 {
        let r = (z * z + xi).sqrt();
        let phi = rho * (z - v) + a * z / r;
        if phi > 0.0 {
            hi = z;
        } else {
            lo = z;
        }
        let dphi = rho + a * xi / (r * r * r);
        let mut next = z - phi / dphi;
        if !(next > lo && next < hi) {
            next = 0.5 * (lo + hi);
        }
        if (next - z).abs() <= 1e-16 * v.abs().max(1e-300) {
            return next;
        }
        z = next;
    }
    z
}

/// Singular value thresholding: U max(Σ − τ, 0) Vᵀ, and Σ max(σ − τ, 0).
fn svt(x: MatRef<f64>, tau: f64) -> Result<(Mat<f64>, f64)> {
    let svd = x.thin_svd().map_err(|e| Error::numerical("low rank", format!("SVD failed: {e:?}")))?;
    let (u, v, s) = (svd.U(), svd.V(), svd.S());
    let r = (0..s.column_vector().nrows()).take_while(|&i| s[i] > tau).count();
    if r == 0 {
        return Ok((Mat::zeros(x.nrows(), x.ncols()), 0.0));
    }
    let us = Mat::from_fn(x.nrows(), r, |i, j| u[(i, j)] * (s[j] - tau));
    let nuclear = (0..r).map(|j| s[j] - tau).sum();
    Ok((mul(us.as_ref(), v.subcols(0, r).transpose()), nuclear))
}

/// The objective terms of (9) at T (the nuclear norm in `low_norm`).
pub fn objective(problem: &FullProblem, params: &CompletionParams, t: MatRef<f64>, k_norm: usize) -> Result<Terms> {
    let (m, n) = (problem.m(), problem.n());
    if t.nrows() != m || t.ncols() != n {
        return Err(Error::invalid("T", format!("T is {}×{} but must be {m}×{n}", t.nrows(), t.ncols())));
    }
    // T = L Rᵀ with L = T, R = I: the smooth and L1 terms from the factored code would form
    // n × n identities; evaluate directly instead.
    let mut terms = smooth_terms(problem, params, t).0;
    if params.mu3 != 0.0 {
        let w = problem.l1_weights();
        let l1: f64 = (0..n)
            .into_par_iter()
            .map(|j| {
                (0..m)
                    .map(|i| {
                        let wt = w.map_or(1.0, |w| w.y[i] * w.x[j]);
                        wt * (t[(i, j)].powi(2) + params.xi).sqrt()
                    })
                    .sum::<f64>()
            })
            .collect::<Vec<f64>>()
            .iter()
            .sum();
        terms.l1 = params.mu3 * l1;
    }
    if params.mu4 != 0.0 {
        let (dy, dx, factor) = problem.nuclear_scaling(params, k_norm);
        let s = scale2(&dy, t, &dx)
            .as_ref()
            .singular_values()
            .map_err(|e| Error::numerical("low rank", format!("SVD failed: {e:?}")))?;
        terms.low_norm = params.mu4 * factor * s.iter().sum::<f64>();
    }
    terms.total = terms.data + terms.dirichlet_x + terms.dirichlet_y + terms.l1 + terms.low_norm;
    Ok(terms)
}

/// Data and Dirichlet terms at T and the gradient's constant-free part: returns the terms and
/// the residual R = T P − G (m × q).
fn smooth_terms(problem: &FullProblem, params: &CompletionParams, t: MatRef<f64>) -> (Terms, Mat<f64>) {
    let mut res = gemm_nn(t, problem.p.as_ref());
    res -= &problem.g;
    let mut terms = Terms {
        data: (0..res.ncols())
            .map(|j| (0..res.nrows()).map(|i| problem.mass_y[i] * res[(i, j)].powi(2)).sum::<f64>())
            .sum(),
        ..Terms::default()
    };
    if params.mu1 != 0.0 {
        // tr(T W_X Tᵀ A_Y) = ⟨A_Y T, T W_X⟩, with T W_X = (W_X Tᵀ)ᵀ.
        let twx = sparse_mul(&problem.w_x, t.transpose());
        let at = Mat::from_fn(t.nrows(), t.ncols(), |i, j| problem.mass_y[i] * t[(i, j)]);
        terms.dirichlet_x = params.mu1 / problem.nu_x * frob(at.as_ref(), twx.transpose());
    }
    if params.mu2 != 0.0 {
        let wyt = sparse_mul(&problem.w_y, t);
        let ta = Mat::from_fn(t.nrows(), t.ncols(), |i, j| t[(i, j)] * problem.mass_x[j]);
        terms.dirichlet_y = params.mu2 / problem.nu_y * frob(ta.as_ref(), wyt.as_ref());
    }
    (terms, res)
}

/// The SPD operator of the S-step in the variable S = D_Y T D_X:
/// H(S) = D_Y⁻¹ H_T(D_Y⁻¹ S D_X⁻¹) D_X⁻¹ + 2ρ S, with the Hessian of the smooth part in T,
/// H_T(T) = 2 A_Y T P Pᵀ + 2 w₁ A_Y T W_X + 2 w₂ W_Y T A_X.
struct SStep<'a> {
    problem: &'a FullProblem,
    w1: f64,
    w2: f64,
    rho: f64,
    /// 1 / D_Y (m), 1 / D_X (n).
    inv_dy: Vec<f64>,
    inv_dx: Vec<f64>,
}

impl SStep<'_> {
    fn apply(&self, s: MatRef<f64>) -> Mat<f64> {
        let p = self.problem;
        let t = scale2(&self.inv_dy, s, &self.inv_dx);
        let tp = gemm_nn(t.as_ref(), p.p.as_ref());
        let mut out = mul(tp.as_ref(), p.p.transpose()); // T P Pᵀ
        if self.w1 != 0.0 {
            let twx = sparse_mul(&p.w_x, t.transpose()); // (T W_X)ᵀ
            out += &(twx.transpose().to_owned() * faer::Scale(self.w1));
        }
        for j in 0..out.ncols() {
            for i in 0..out.nrows() {
                out[(i, j)] *= 2.0 * p.mass_y[i];
            }
        }
        if self.w2 != 0.0 {
            let wyt = sparse_mul(&p.w_y, t.as_ref());
            for j in 0..out.ncols() {
                for i in 0..out.nrows() {
                    out[(i, j)] += 2.0 * self.w2 * wyt[(i, j)] * p.mass_x[j];
                }
            }
        }
        for j in 0..out.ncols() {
            for i in 0..out.nrows() {
                out[(i, j)] = out[(i, j)] * self.inv_dy[i] * self.inv_dx[j] + 2.0 * self.rho * s[(i, j)];
            }
        }
        out
    }

    /// Conjugate gradients for H(S) = rhs from `s`, to relative residual `tol`; returns the
    /// iteration count.
    fn solve(&self, s: &mut Mat<f64>, rhs: &Mat<f64>, tol: f64, max_iter: usize) -> usize {
        let mut r = rhs - self.apply(s.as_ref());
        let bnorm = rhs.norm_l2().max(1e-300);
        let mut p = r.clone();
        let mut rr = frob(r.as_ref(), r.as_ref());
        for it in 0..max_iter {
            if rr.sqrt() <= tol * bnorm {
                return it;
            }
            let hp = self.apply(p.as_ref());
            let alpha = rr / frob(p.as_ref(), hp.as_ref());
            *s += &p * alpha;
            r -= &hp * alpha;
            let rr_new = frob(r.as_ref(), r.as_ref());
            p = &r + &p * (rr_new / rr);
            rr = rr_new;
        }
        max_iter
    }
}

/// Solves (9) by ADMM from `t0` (m × n; e.g. zero or a subspace solution). `k_norm` is the
/// rank that normalizes the nuclear norm under [`super::Scaling::Unit`] (as the k of (10)).
///
/// The iteration runs in S = D_Y T D_X, where the nuclear norm is the plain ‖S‖_* and both
/// splittings Z₁ = S (smoothed L1: per entry a √(s² + ξ δ²) with δ = d^Y_j d^X_i and
/// a = μ3 w_ji / δ) and Z₂ = S (nuclear norm) have the same scale, so one penalty ρ suits both.
/// Errors when m·n exceeds [`MAX_ENTRIES`], on bad sizes or parameters.
pub fn solve(
    problem: &FullProblem,
    params: &CompletionParams,
    opts: &AdmmOptions,
    t0: MatRef<f64>,
    k_norm: usize,
) -> Result<(Mat<f64>, AdmmReport)> {
    let (m, n) = (problem.m(), problem.n());
    if m.saturating_mul(n) > MAX_ENTRIES {
        return Err(Error::invalid(
            "form",
            format!(
                "the convex low-rank form (9) works on the dense {m}×{n} matrix T; it is limited to \
                 {MAX_ENTRIES} entries (e.g. 2000×2000): use the low-norm (10) or subspace (11) form"
            ),
        ));
    }
    if t0.nrows() != m || t0.ncols() != n {
        return Err(Error::invalid("T", format!("the start is {}×{} but must be {m}×{n}", t0.nrows(), t0.ncols())));
    }
    params.validate()?;
    if !(opts.rho > 0.0 && opts.rho.is_finite()) {
        return Err(Error::invalid("rho", format!("must be positive, got {}", opts.rho)));
    }
    let start = Instant::now();
    let (dy, dx, factor) = problem.nuclear_scaling(params, k_norm);
    let tau_nuc = params.mu4 * factor;
    let w = problem.l1_weights();
    let mut step = SStep {
        problem,
        w1: params.mu1 / problem.nu_x,
        w2: params.mu2 / problem.nu_y,
        rho: opts.rho,
        inv_dy: dy.iter().map(|d| 1.0 / d).collect(),
        inv_dx: dx.iter().map(|d| 1.0 / d).collect(),
    };
    // The constant part of the S-step's right-hand side: D_Y⁻¹ (2 A_Y G Pᵀ) D_X⁻¹.
    let rhs0 = {
        let mut x = mul(problem.g.as_ref(), problem.p.transpose());
        for j in 0..n {
            for i in 0..m {
                x[(i, j)] *= 2.0 * problem.mass_y[i] * step.inv_dy[i] * step.inv_dx[j];
            }
        }
        x
    };
    // Per-entry weight a and smoothing ξ' of the L1 term in S.
    let l1_a = |i: usize, j: usize| params.mu3 * w.map_or(1.0, |w| w.y[i] * w.x[j]) / (dy[i] * dx[j]);
    let l1_xi = |i: usize, j: usize| params.xi * (dy[i] * dx[j]).powi(2);
    let mut s = scale2(&dy, t0, &dx);
    let mut z1 = s.clone();
    let mut z2 = s.clone();
    let mut y1 = Mat::<f64>::zeros(m, n);
    let mut y2 = Mat::<f64>::zeros(m, n);
    let sqrt_mn = ((2 * m * n) as f64).sqrt();
    let (mut iterations, mut cg_iterations, mut converged) = (0, 0, false);
    let (mut primal, mut dual) = (f64::INFINITY, f64::INFINITY);
    let mut history = Vec::new();
    while iterations < opts.max_iterations {
        let rho = step.rho;
        // S-step: ∇f(S) + ρ (S − Z₁ + Y₁) + ρ (S − Z₂ + Y₂) = 0.
        let rhs = &rhs0 + (&z1 - &y1 + &z2 - &y2) * faer::Scale(rho);
        cg_iterations += step.solve(&mut s, &rhs, opts.cg_tol, 10 * (m + n));
        // Z-steps with over-relaxation (α = 1.6, Boyd et al. §3.4.3): Ŝ = α S + (1 − α) Z.
        let (z1_old, z2_old) = (z1.clone(), z2.clone());
        let h1 = &s * RELAX + &z1_old * (1.0 - RELAX);
        let h2 = &s * RELAX + &z2_old * (1.0 - RELAX);
        let v1 = &h1 + &y1;
        z1 = Mat::from_fn(m, n, |i, j| prox_soft_abs(v1[(i, j)], l1_a(i, j), l1_xi(i, j), rho));
        z2 = if tau_nuc > 0.0 { svt((&h2 + &y2).as_ref(), tau_nuc / rho)?.0 } else { &h2 + &y2 };
        y1 += &(&h1 - &z1);
        y2 += &(&h2 - &z2);
        let r1 = &s - &z1;
        let r2 = &s - &z2;
        primal = (r1.squared_norm_l2() + r2.squared_norm_l2()).sqrt();
        dual = rho * ((&z1 - &z1_old) + (&z2 - &z2_old)).norm_l2();
        iterations += 1;
        if iterations % 10 == 1 {
            history.push(
                objective(problem, params, scale2(&step.inv_dy, s.as_ref(), &step.inv_dx).as_ref(), k_norm)?.total,
            );
        }
        let eps_pri = opts.eps_abs * sqrt_mn
            + opts.eps_rel
                * (2.0 * s.squared_norm_l2()).sqrt().max((z1.squared_norm_l2() + z2.squared_norm_l2()).sqrt());
        let eps_dual =
            opts.eps_abs * sqrt_mn + opts.eps_rel * rho * (y1.squared_norm_l2() + y2.squared_norm_l2()).sqrt();
        if primal <= eps_pri && dual <= eps_dual {
            converged = true;
            break;
        }
        // Residual balancing (Boyd et al. §3.4.1): the scaled duals change with ρ.
        let new_rho = if primal > 10.0 * dual {
            2.0 * rho
        } else if dual > 10.0 * primal {
            rho / 2.0
        } else {
            rho
        };
        if new_rho != rho {
            y1 *= faer::Scale(rho / new_rho);
            y2 *= faer::Scale(rho / new_rho);
            step.rho = new_rho;
        }
    }
    let t = scale2(&step.inv_dy, s.as_ref(), &step.inv_dx);
    if t.as_ref().col_iter().any(|c| c.iter().any(|v| !v.is_finite())) {
        return Err(Error::numerical("low rank", "ADMM diverged (non-finite T)"));
    }
    let terms = objective(problem, params, t.as_ref(), k_norm)?;
    history.push(terms.total);
    let report = AdmmReport {
        iterations,
        cg_iterations,
        converged,
        primal_residual: primal,
        dual_residual: dual,
        terms,
        objective_history: history,
        seconds_total: start.elapsed().as_secs_f64(),
    };
    Ok((t, report))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prox_of_the_smoothed_absolute_value() {
        for &(v, a, xi, rho) in
            &[(1.0, 0.3, 1e-2, 1.0), (-2.0, 1.0, 1e-3, 0.5), (0.01, 5.0, 1e-4, 2.0), (3.0, 0.1, 0.0, 1.0)]
        {
            let z = prox_soft_abs(v, a, xi, rho);
            // Optimality by brute force on a fine grid around z.
            let obj = |z: f64| a * (z * z + xi).sqrt() + 0.5 * rho * (z - v) * (z - v);
            for d in [1e-6, -1e-6, 1e-3, -1e-3] {
                assert!(obj(z) <= obj(z + d) + 1e-15, "v {v} a {a}: z {z}");
            }
        }
        assert_eq!(prox_soft_abs(0.5, 1.0, 0.0, 1.0), 0.0);
    }
}
