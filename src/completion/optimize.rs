//! Minimization of (11) over x = (A, B) by L-BFGS with a strong-Wolfe line search, and the
//! paper's initializations.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::svd::{svd, svd_scratch, ComputeSvdVectors};
use faer::{Mat, MatRef, Par};

use super::lbfgs::{self, CompletionReport, OptimizeOptions};
use super::objective::{curvature_c, evaluate, low_norm_curvature, CompletionParams, Precondition};
use super::{mul, Problem};
use crate::error::{Error, Result};
use crate::optim::Stop;

/// x = (vec A, vec B), column-major.
pub(crate) fn pack(a: MatRef<f64>, b: MatRef<f64>) -> Vec<f64> {
    let mut x = vec![0.0; 2 * a.nrows() * a.ncols()];
    pack_into(a, b, &mut x);
    x
}

/// Writes (vec A, vec B), column-major, into `x` (length 2 · rows · cols).
fn pack_into(a: MatRef<f64>, b: MatRef<f64>, x: &mut [f64]) {
    let mut at = 0;
    for m in [a, b] {
        for j in 0..m.ncols() {
            for i in 0..m.nrows() {
                x[at] = m[(i, j)];
                at += 1;
            }
        }
    }
}

pub(crate) fn unpack(x: &[f64], kp: usize, k: usize) -> (Mat<f64>, Mat<f64>) {
    let half = kp * k;
    let a = Mat::from_fn(kp, k, |i, j| x[j * kp + i]);
    let b = Mat::from_fn(kp, k, |i, j| x[half + j * kp + i]);
    (a, b)
}

/// Minimizes (11) over (A, B) from (`a0`, `b0`) (both k' × k) by L-BFGS with a strong-Wolfe
/// line search (`super::lbfgs::minimize`). Every accepted step satisfies sufficient decrease,
/// so the objective is non-increasing. Stops on relative objective change ≤ `rel_tol`, on
/// ‖∇f‖ ≤ `grad_tol`·‖∇f₀‖, at the iteration cap, or when a line search finds no decrease.
pub fn optimize(
    problem: &Problem,
    params: &CompletionParams,
    opts: &OptimizeOptions,
    a0: MatRef<f64>,
    b0: MatRef<f64>,
) -> Result<(Mat<f64>, Mat<f64>, CompletionReport)> {
    optimize_until_settled(problem, params, opts, None, a0, b0)
}

/// A stopping rule on the point map (stop when the map, not only the objective, has settled):
/// every `every` iterations, the map of the check vertices of X — the L1 samples
/// ([`Problem::with_l1_samples`]) or every vertex — is computed, and L-BFGS stops when at most
/// `tolerance` of them changed since the previous check. The map is the one the caller reads
/// off: with `k` = 0 the nearest rows of Ψ A for the rows of Φ B (the extraction of
/// [`super::solve`]); with `k` > 0 the map of the leading k × k block C_k of C = A Bᵀ (the
/// nearest rows of Ψ_k C_k for the rows of Φ_k), where a refinement starting from C_k begins.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SettledMap {
    /// Iterations between checks (≥ 1).
    pub every: usize,
    /// Fraction of the check vertices whose image may change between two checks.
    pub tolerance: f64,
    /// 0: the map of the factors; k > 0: the map of the leading k × k block of C.
    #[serde(default)]
    pub k: usize,
}

/// [`optimize`] that also stops when the point map has settled (`settled`, `None`: only the
/// objective's rules). Errors: those of [`optimize`]; `every` = 0 or a tolerance outside [0, 1].
pub fn optimize_until_settled(
    problem: &Problem,
    params: &CompletionParams,
    opts: &OptimizeOptions,
    settled: Option<SettledMap>,
    a0: MatRef<f64>,
    b0: MatRef<f64>,
) -> Result<(Mat<f64>, Mat<f64>, CompletionReport)> {
    optimize_preconditioned(problem, params, opts, settled, Precondition::Off, a0, b0)
}

/// [`optimize_until_settled`] with L-BFGS preconditioned by `precondition`
/// ([`Precondition::Off`]: exactly [`optimize_until_settled`]); see [`Precondition`] and
/// [`crate::optim::lbfgs::minimize_preconditioned`].
pub fn optimize_preconditioned(
    problem: &Problem,
    params: &CompletionParams,
    opts: &OptimizeOptions,
    settled: Option<SettledMap>,
    precondition: Precondition,
    a0: MatRef<f64>,
    b0: MatRef<f64>,
) -> Result<(Mat<f64>, Mat<f64>, CompletionReport)> {
    if let Some(s) = settled {
        if s.every == 0 || !(0.0..=1.0).contains(&s.tolerance) {
            return Err(Error::invalid(
                "settled map",
                format!("need a check interval ≥ 1 and a tolerance in [0, 1], got {} and {}", s.every, s.tolerance),
            ));
        }
    }
    let kp = problem.k_prime();
    if a0.nrows() != kp || b0.nrows() != kp || a0.ncols() != b0.ncols() || a0.ncols() == 0 {
        return Err(Error::invalid(
            "initialization",
            format!(
                "A is {}×{} and B {}×{}; both must be k'×k with k' = {kp} and k ≥ 1",
                a0.nrows(),
                a0.ncols(),
                b0.nrows(),
                b0.ncols()
            ),
        ));
    }
    if a0.ncols() > kp {
        return Err(Error::invalid("k", format!("k = {} exceeds k' = {kp}", a0.ncols())));
    }
    let k = a0.ncols();
    let mut eval = |x: &[f64], grad: &mut [f64]| {
        let (a, b) = unpack(x, kp, k);
        let e = evaluate(problem, params, a.as_ref(), b.as_ref());
        pack_into(e.grad_a.as_ref(), e.grad_b.as_ref(), grad);
        e.terms
    };
    // The check vertices of X (rows of Φ) and the map at the last check.
    let check = problem.l1_sample.as_ref().map_or(problem.phi.as_ref(), |s| s.phi.as_ref());
    let mut last: Option<Vec<usize>> = None;
    let mut monitor = |iterations: usize, x: &[f64]| -> Option<Stop> {
        let s = settled?;
        if !iterations.is_multiple_of(s.every) {
            return None;
        }
        let (a, b) = unpack(x, kp, k);
        let (query, reference) = if s.k == 0 {
            (mul(check, b.as_ref()), mul(problem.psi.as_ref(), a.as_ref()))
        } else {
            let kc = s.k.min(kp);
            let c = mul(a.subrows(0, kc), b.subrows(0, kc).transpose());
            (check.subcols(0, kc).to_owned(), mul(problem.psi.subcols(0, kc), c.as_ref()))
        };
        // A failed search (non-finite factors) leaves the decision to the objective's rules.
        let map = crate::spatial::nearest_rows(reference.as_ref(), query.as_ref()).ok()?;
        let changed = last.as_ref().map(|l| l.iter().zip(&map).filter(|(p, q)| p != q).count());
        last = Some(map);
        match changed {
            Some(c) if c as f64 <= s.tolerance * check.nrows() as f64 => Some(Stop::Settled(s.tolerance)),
            _ => None,
        }
    };
    let mut pc = DiagonalPreconditioner::new(problem, params, precondition, k);
    let (x, report) = match pc.as_mut() {
        None => lbfgs::minimize_monitored(pack(a0, b0), opts, &mut eval, &mut monitor)?,
        Some(pc) => {
            let mut apply = |x: &[f64], v: &mut [f64]| pc.apply(x, v);
            lbfgs::minimize_preconditioned(pack(a0, b0), opts, &mut eval, &mut monitor, Some(&mut apply))?
        }
    };
    let (a, b) = unpack(&x, kp, k);
    Ok((a, b, report))
}

/// Iterations between refreshes of the L1 part of [`Precondition::Full`].
const L1_REFRESH: usize = 10;

/// The diagonal preconditioner of [`Precondition`] for x = (vec A, vec B) (A, B: k' × k): with
/// H = [`curvature_c`] (k' × k'), the Gauss–Newton diagonal of the terms of C = A Bᵀ in (A, B),
/// D_A = H (B ∘ B) and D_B = Hᵀ (A ∘ A) (k' × k' times k' × k), plus the low-norm curvature
/// ([`low_norm_curvature`]), floored at 10⁻³ of its mean; P = D⁻¹. D is recomputed at every new
/// x (4·k'²·k flops); the L1 part of H ([`Precondition::Full`]) every [`L1_REFRESH`] new points.
struct DiagonalPreconditioner<'p> {
    problem: &'p Problem,
    params: &'p CompletionParams,
    k: usize,
    /// H without the L1 part (constant).
    quadratic: Mat<f64>,
    /// H with the L1 part at the last refresh ([`Precondition::Full`] only).
    full: Option<Mat<f64>>,
    with_l1: bool,
    low_a: Vec<f64>,
    low_b: Vec<f64>,
    /// The point D was computed at, and D (length 2 k' k).
    last: Option<(Vec<f64>, Vec<f64>)>,
    points: usize,
}

impl<'p> DiagonalPreconditioner<'p> {
    fn new(problem: &'p Problem, params: &'p CompletionParams, kind: Precondition, k: usize) -> Option<Self> {
        let with_l1 = match kind {
            Precondition::Off => return None,
            Precondition::Quadratic => false,
            Precondition::Full => true,
        };
        let kp = problem.k_prime();
        let zero = Mat::<f64>::zeros(kp, k);
        let quadratic = curvature_c(problem, params, zero.as_ref(), zero.as_ref(), false);
        let (low_a, low_b) = low_norm_curvature(problem, params, k);
        Some(DiagonalPreconditioner {
            problem,
            params,
            k,
            quadratic,
            full: None,
            with_l1,
            low_a,
            low_b,
            last: None,
            points: 0,
        })
    }

    /// D at x (length 2 k' k).
    fn diagonal(&mut self, x: &[f64]) -> Vec<f64> {
        let (kp, k) = (self.problem.k_prime(), self.k);
        let (a, b) = unpack(x, kp, k);
        if self.with_l1 && (self.full.is_none() || self.points.is_multiple_of(L1_REFRESH)) {
            self.full = Some(curvature_c(self.problem, self.params, a.as_ref(), b.as_ref(), true));
        }
        self.points += 1;
        let h = self.full.as_ref().unwrap_or(&self.quadratic);
        let a2 = Mat::from_fn(kp, k, |i, l| a[(i, l)] * a[(i, l)]);
        let b2 = Mat::from_fn(kp, k, |j, l| b[(j, l)] * b[(j, l)]);
        let da = mul(h.as_ref(), b2.as_ref());
        let db = mul(h.transpose(), a2.as_ref());
        let mut d = vec![0.0; 2 * kp * k];
        for l in 0..k {
            for i in 0..kp {
                d[l * kp + i] = da[(i, l)] + self.low_a[i];
                d[kp * k + l * kp + i] = db[(i, l)] + self.low_b[i];
            }
        }
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        let floor = if mean > 0.0 { 1e-3 * mean } else { 1.0 };
        d.iter_mut().for_each(|v| *v = v.max(floor));
        d
    }

    /// v ← D(x)⁻¹ v.
    fn apply(&mut self, x: &[f64], v: &mut [f64]) {
        if self.last.as_ref().is_none_or(|(lx, _)| lx.as_slice() != x) {
            let d = self.diagonal(x);
            self.last = Some((x.to_vec(), d));
        }
        let (_, d) = self.last.as_ref().expect("set above");
        v.iter_mut().zip(d).for_each(|(vi, di)| *vi /= di);
    }
}

/// The paper's initialization from a functional map C (r × c, r ≤ k', c ≤ k), e.g. Ovsjanikov's:
/// A = C zero-padded to k' × k, B = I_{k'×k}, so that A Bᵀ = C zero-padded to k' × k'.
pub fn init_from_c(c: MatRef<f64>, k_prime: usize, k: usize) -> Result<(Mat<f64>, Mat<f64>)> {
    check_k(k_prime, k)?;
    if c.nrows() > k_prime || c.ncols() > k {
        return Err(Error::invalid(
            "C",
            format!("C is {}×{} but must fit in k'×k = {k_prime}×{k}", c.nrows(), c.ncols()),
        ));
    }
    let a = Mat::from_fn(k_prime, k, |i, j| if i < c.nrows() && j < c.ncols() { c[(i, j)] } else { 0.0 });
    let b = Mat::from_fn(k_prime, k, |i, j| if i == j { 1.0 } else { 0.0 });
    Ok((a, b))
}

/// The paper's initialization from the SVD of a given correspondence T = Ψ C Φᵀ, for T in the
/// bases, i.e. from the SVD of its functional map C (r × c, r, c ≤ k', zero-padded to k' × k'):
/// C = U Σ Vᵀ, A = U_k Σ_k^{1/2}, B = V_k Σ_k^{1/2}, truncated to the k largest singular values,
/// so A Bᵀ is the best rank-k approximation of C.
pub fn init_from_svd(c: MatRef<f64>, k_prime: usize, k: usize) -> Result<(Mat<f64>, Mat<f64>)> {
    check_k(k_prime, k)?;
    if c.nrows() > k_prime || c.ncols() > k_prime {
        return Err(Error::invalid(
            "C",
            format!("C is {}×{} but must fit in k'×k' = {k_prime}×{k_prime}", c.nrows(), c.ncols()),
        ));
    }
    let full = Mat::from_fn(k_prime, k_prime, |i, j| if i < c.nrows() && j < c.ncols() { c[(i, j)] } else { 0.0 });
    let mut s = faer::diag::Diag::<f64>::zeros(k_prime);
    let mut u = Mat::<f64>::zeros(k_prime, k_prime);
    let mut v = Mat::<f64>::zeros(k_prime, k_prime);
    let mut buf = MemBuffer::new(svd_scratch::<f64>(
        k_prime,
        k_prime,
        ComputeSvdVectors::Thin,
        ComputeSvdVectors::Thin,
        Par::Seq,
        Default::default(),
    ));
    svd(
        full.as_ref(),
        s.as_mut(),
        Some(u.as_mut()),
        Some(v.as_mut()),
        Par::Seq,
        MemStack::new(&mut buf),
        Default::default(),
    )
    .map_err(|e| Error::numerical("completion", format!("SVD of the initial map failed: {e:?}")))?;
    // Singular values come sorted in decreasing order.
    let a = Mat::from_fn(k_prime, k, |i, j| u[(i, j)] * s[j].max(0.0).sqrt());
    let b = Mat::from_fn(k_prime, k, |i, j| v[(i, j)] * s[j].max(0.0).sqrt());
    Ok((a, b))
}

fn check_k(k_prime: usize, k: usize) -> Result<()> {
    if k == 0 || k > k_prime {
        return Err(Error::invalid("k", format!("k = {k} must be between 1 and k' = {k_prime}")));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::completion::objective::LowNorm;
    use crate::completion::testutil::randn;
    use crate::completion::{mul, Problem};

    fn random_problem(n: usize, m: usize, kp: usize, q: usize, seed: u64) -> Problem {
        let phi = randn(n, kp, seed) * 0.2;
        let psi = randn(m, kp, seed + 1) * 0.2;
        let lx: Vec<f64> = (0..kp).map(|i| i as f64 * 0.7).collect();
        let ly: Vec<f64> = (0..kp).map(|i| i as f64 * 0.75 + 0.01).collect();
        Problem::from_coefficients(phi, psi, lx, ly, randn(kp, q, seed + 2), randn(kp, q, seed + 3)).unwrap()
    }

    fn strong_params() -> CompletionParams {
        CompletionParams {
            mu1: 1e-2,
            mu2: 1e-2,
            mu3: 1e-2,
            mu4: 1e-2,
            xi: 1e-3,
            mu_comm: 1e-3,
            k_comm: 6,
            mu_prior: 0.0,
            low_norm: LowNorm::Euclidean,
            block_rows: 16,
            ..Default::default()
        }
    }

    #[test]
    fn objective_is_non_increasing_and_gradient_shrinks() {
        let p = random_problem(50, 50, 8, 6, 77);
        let (a0, b0) = (randn(8, 5, 1), randn(8, 5, 2));
        let opts = OptimizeOptions { rel_tol: 1e-15, grad_tol: 1e-8, max_iterations: 3000, ..Default::default() };
        let (a, b, r) = optimize(&p, &strong_params(), &opts, a0.as_ref(), b0.as_ref()).unwrap();
        assert!(r.objective_history.windows(2).all(|w| w[1] <= w[0]), "{:?}", r.objective_history);
        assert!(r.terms.total < 0.5 * r.initial_terms.total);
        // Stationary point: the gradient has shrunk by orders of magnitude.
        assert!(
            r.gradient_norm_final < 1e-5 * r.gradient_norm_initial,
            "‖g‖ {} from {} after {} iterations ({})",
            r.gradient_norm_final,
            r.gradient_norm_initial,
            r.iterations,
            r.stop_reason
        );
        eprintln!(
            "stationary: {} iterations, {} evaluations, ‖g‖ {:.2e} → {:.2e}, f {:.4} → {:.4} ({})",
            r.iterations,
            r.evaluations,
            r.gradient_norm_initial,
            r.gradient_norm_final,
            r.initial_terms.total,
            r.terms.total,
            r.stop_reason
        );
        let e = evaluate(&p, &strong_params(), a.as_ref(), b.as_ref());
        assert_eq!(e.terms.total, r.terms.total);
        assert!(serde_json::to_string(&r).unwrap().contains("seconds_per_iteration"));
    }

    #[test]
    fn default_options_stop_on_relative_change() {
        let p = random_problem(40, 45, 8, 6, 5);
        let (a0, b0) = init_from_c(Mat::<f64>::identity(8, 5).as_ref(), 8, 5).unwrap();
        let (_, _, r) =
            optimize(&p, &CompletionParams::default(), &OptimizeOptions::default(), a0.as_ref(), b0.as_ref()).unwrap();
        eprintln!("paper defaults: {} iterations, {}", r.iterations, r.stop_reason);
        assert!(r.converged, "{}", r.stop_reason);
        assert!(r.iterations < 300);
        assert!(r.objective_history.windows(2).all(|w| w[1] <= w[0]));
        let h = &r.objective_history;
        let n = h.len();
        assert!(h[n - 2] - h[n - 1] <= 1e-6 * h[n - 2]);
    }

    #[test]
    fn with_zero_weights_solves_the_data_term() {
        // k = q: some rank-k C satisfies C Â = B̂ exactly.
        let p = random_problem(30, 30, 8, 6, 11);
        let zero = CompletionParams { mu1: 0.0, mu2: 0.0, mu3: 0.0, mu4: 0.0, ..Default::default() };
        let (a0, b0) = init_from_c(Mat::<f64>::identity(8, 6).as_ref(), 8, 6).unwrap();
        let opts = OptimizeOptions { rel_tol: 1e-14, max_iterations: 2000, ..Default::default() };
        let (a, b, r) = optimize(&p, &zero, &opts, a0.as_ref(), b0.as_ref()).unwrap();
        let c = mul(a.as_ref(), b.transpose());
        let res = (mul(c.as_ref(), p.f_hat.as_ref()) - &p.g_hat).norm_l2() / p.g_hat.norm_l2();
        eprintln!("data term alone: relative residual {res:.1e} after {} iterations ({})", r.iterations, r.stop_reason);
        assert!(res < 1e-5, "relative residual {res}, {} iterations, {}", r.iterations, r.stop_reason);
    }

    #[test]
    fn initializations() {
        let c = randn(6, 4, 3);
        let (a, b) = init_from_c(c.as_ref(), 8, 5).unwrap();
        let ab = mul(a.as_ref(), b.transpose());
        for i in 0..8 {
            for j in 0..8 {
                let want = if i < 6 && j < 4 { c[(i, j)] } else { 0.0 };
                assert_eq!(ab[(i, j)], want);
            }
        }
        // SVD: exact when k = k', the best rank-k approximation otherwise.
        let c = randn(8, 8, 4);
        let (a, b) = init_from_svd(c.as_ref(), 8, 8).unwrap();
        assert!((mul(a.as_ref(), b.transpose()) - &c).norm_l2() < 1e-12 * c.norm_l2());
        let (a, b) = init_from_svd(c.as_ref(), 8, 3).unwrap();
        let err = (mul(a.as_ref(), b.transpose()) - &c).norm_l2();
        let sv = c.as_ref().singular_values().unwrap(); // decreasing
        let tail = sv[3..].iter().map(|s| s * s).sum::<f64>().sqrt();
        assert!((err - tail).abs() < 1e-10 * tail);
        // Balanced factors: ‖A‖ = ‖B‖.
        assert!((a.norm_l2() - b.norm_l2()).abs() < 1e-10 * a.norm_l2());
        // Bad sizes.
        assert!(init_from_c(c.as_ref(), 8, 9).is_err());
        assert!(init_from_c(c.as_ref(), 8, 5).is_err());
        assert!(init_from_svd(c.as_ref(), 6, 3).is_err());
        let p = random_problem(20, 20, 8, 3, 1);
        let bad = optimize(
            &p,
            &CompletionParams::default(),
            &OptimizeOptions::default(),
            randn(7, 3, 1).as_ref(),
            randn(8, 3, 2).as_ref(),
        );
        assert!(bad.is_err());
    }
}
