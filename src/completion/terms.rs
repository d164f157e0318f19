//! The terms of problem (11), each *unweighted* with its gradient with respect to A and B
//! (both k' × k). The weights μ are applied in `super::objective`.
//!
//! Several terms depend on (A, B) only through C = A Bᵀ (k' × k'); for those, with
//! G = ∂f/∂C, the chain rule gives ∇_A f = G B and ∇_B f = Gᵀ A.

use faer::{Mat, MatRef};

use super::l1::{soft_l1, Precision, Products, Weights};
use super::{gemm_nn, gemm_tn, mul};

/// The value of one term and its gradients with respect to A and B.
#[derive(Clone, Debug)]
pub struct TermValue {
    /// The term's value.
    pub value: f64,
    /// ∂/∂A (k' × k).
    pub grad_a: Mat<f64>,
    /// ∂/∂B (k' × k).
    pub grad_b: Mat<f64>,
}

/// Gradients of a function of C = A Bᵀ from G = ∂f/∂C: (G B, Gᵀ A).
fn chain_c(value: f64, g: MatRef<f64>, a: MatRef<f64>, b: MatRef<f64>) -> TermValue {
    TermValue { value, grad_a: mul(g, b), grad_b: mul(g.transpose(), a) }
}

/// Data term of (11) as a function of C (k' × k'): ‖C Â − B̂‖²_F with Â = Φ_k'ᵀ A_X F,
/// B̂ = Ψ_k'ᵀ A_Y G (k' × q), the mass-weighted coefficients of the data (see the module
/// documentation of [`crate::completion`] for this mass placement). Returns the value and
/// ∂/∂C = 2 R Âᵀ with R = C Â − B̂.
pub fn data_c(c: MatRef<f64>, f_hat: MatRef<f64>, g_hat: MatRef<f64>) -> (f64, Mat<f64>) {
    let mut r = mul(c, f_hat);
    r -= g_hat;
    (r.squared_norm_l2(), mul(r.as_ref(), f_hat.transpose()) * 2.0)
}

/// [`data_c`] at C = A Bᵀ with gradients ∇_A = 2 R Âᵀ B, ∇_B = 2 Â Rᵀ A.
pub fn data(a: MatRef<f64>, b: MatRef<f64>, f_hat: MatRef<f64>, g_hat: MatRef<f64>) -> TermValue {
    let (value, g) = data_c(mul(a, b.transpose()).as_ref(), f_hat, g_hat);
    chain_c(value, g.as_ref(), a, b)
}

/// Dirichlet energy on X of (11) as a function of C: tr(C Λ_X Cᵀ) = Σ_ij C_ij² λ^X_j
/// (= tr(A Bᵀ Λ_X B Aᵀ) for C = A Bᵀ); ∂/∂C = 2 C Λ_X.
pub fn dirichlet_x_c(c: MatRef<f64>, lambda_x: &[f64]) -> (f64, Mat<f64>) {
    let g = Mat::from_fn(c.nrows(), c.ncols(), |i, j| 2.0 * c[(i, j)] * lambda_x[j]);
    let value = 0.5 * (0..c.ncols()).map(|j| (0..c.nrows()).map(|i| g[(i, j)] * c[(i, j)]).sum::<f64>()).sum::<f64>();
    (value, g)
}

/// [`dirichlet_x_c`] at C = A Bᵀ: ∇_A = 2 C Λ_X B, ∇_B = 2 Λ_X Cᵀ A.
pub fn dirichlet_x(a: MatRef<f64>, b: MatRef<f64>, lambda_x: &[f64]) -> TermValue {
    let (value, g) = dirichlet_x_c(mul(a, b.transpose()).as_ref(), lambda_x);
    chain_c(value, g.as_ref(), a, b)
}

/// Dirichlet energy on Y of (11) as a function of C: tr(Cᵀ Λ_Y C) = Σ_ij λ^Y_i C_ij²
/// (= tr(B Aᵀ Λ_Y A Bᵀ) for C = A Bᵀ); ∂/∂C = 2 Λ_Y C.
pub fn dirichlet_y_c(c: MatRef<f64>, lambda_y: &[f64]) -> (f64, Mat<f64>) {
    let g = Mat::from_fn(c.nrows(), c.ncols(), |i, j| 2.0 * lambda_y[i] * c[(i, j)]);
    let value = 0.5 * (0..c.ncols()).map(|j| (0..c.nrows()).map(|i| g[(i, j)] * c[(i, j)]).sum::<f64>()).sum::<f64>();
    (value, g)
}

/// [`dirichlet_y_c`] at C = A Bᵀ: ∇_A = 2 Λ_Y C B, ∇_B = 2 Cᵀ Λ_Y A.
pub fn dirichlet_y(a: MatRef<f64>, b: MatRef<f64>, lambda_y: &[f64]) -> TermValue {
    let (value, g) = dirichlet_y_c(mul(a, b.transpose()).as_ref(), lambda_y);
    chain_c(value, g.as_ref(), a, b)
}

/// Optional Laplacian-commutativity term (Ovsjanikov et al. 2012), not part of the paper's (11):
/// ‖C_c Λ_X − Λ_Y C_c‖²_F = Σ_{i,j<k_c} (λ^X_j − λ^Y_i)² C_ij², on the leading k_c × k_c block
/// C_c of C. Pure (11) does not reward near-isometric maps; this term does.
/// ∂/∂C_ij = 2 (λ^X_j − λ^Y_i)² C_ij inside the block, 0 outside.
pub fn commutativity_c(c: MatRef<f64>, lambda_x: &[f64], lambda_y: &[f64], k_c: usize) -> (f64, Mat<f64>) {
    let kc = k_c.min(c.nrows()).min(c.ncols());
    let mut value = 0.0;
    let g = Mat::from_fn(c.nrows(), c.ncols(), |i, j| {
        if i < kc && j < kc {
            let w = (lambda_x[j] - lambda_y[i]).powi(2);
            value += w * c[(i, j)] * c[(i, j)];
            2.0 * w * c[(i, j)]
        } else {
            0.0
        }
    });
    (value, g)
}

/// [`commutativity_c`] at C = A Bᵀ, with gradients by the chain rule.
pub fn commutativity(a: MatRef<f64>, b: MatRef<f64>, lambda_x: &[f64], lambda_y: &[f64], k_c: usize) -> TermValue {
    let (value, g) = commutativity_c(mul(a, b.transpose()).as_ref(), lambda_x, lambda_y, k_c);
    chain_c(value, g.as_ref(), a, b)
}

/// Optional axiomatic prior (EXPERIMENTS.md, "The completion method with the same terms (scarce
/// data)"), not part of the paper's (11): the functional-map energy
/// E of [`crate::fmap::energy`] without its descriptor term — Laplacian commutativity (standard or
/// resolvent mask), descriptor commutativity and orientation — at the leading k_c × k_c block of
/// the functional map between the input bases, s C_c (s = [`super::Problem::c_scale`]).
/// ∂/∂C = s ∇E(s C_c) inside the block, 0 outside.
pub fn prior_c(c: MatRef<f64>, energy: &crate::fmap::energy::Energy, s: f64) -> (f64, Mat<f64>) {
    let kc = energy.k_x().min(c.nrows()).min(c.ncols());
    let block = c.submatrix(0, 0, kc, kc).to_owned() * faer::Scale(s);
    let g_block = energy.gradient(block.as_ref());
    let g = Mat::from_fn(c.nrows(), c.ncols(), |i, j| if i < kc && j < kc { s * g_block[(i, j)] } else { 0.0 });
    (energy.value(block.as_ref()), g)
}

/// [`prior_c`] at C = A Bᵀ, with gradients by the chain rule.
pub fn prior(a: MatRef<f64>, b: MatRef<f64>, energy: &crate::fmap::energy::Energy, s: f64) -> TermValue {
    let (value, g) = prior_c(mul(a, b.transpose()).as_ref(), energy, s);
    chain_c(value, g.as_ref(), a, b)
}

/// Low-norm term of (11) without its weight: ½ (‖Ψ_k' A‖²_F + ‖Φ_k' B‖²_F).
///
/// The bases are mass-orthonormal, not Euclidean-orthonormal, so with `grams = Some((Φᵀ Φ, Ψᵀ Ψ))`
/// the Euclidean norms are computed exactly as ½ (tr(Aᵀ G_Y A) + tr(Bᵀ G_X B)), with gradients
/// ∇_A = G_Y A and ∇_B = G_X B. With `None` the mass-weighted norms are used instead,
/// ‖Ψ A‖²_{A_Y} = ‖A‖²_F, giving ½ (‖A‖² + ‖B‖²) with gradients A and B.
pub fn low_norm(a: MatRef<f64>, b: MatRef<f64>, grams: Option<(MatRef<f64>, MatRef<f64>)>) -> TermValue {
    let (grad_a, grad_b) = match grams {
        Some((gram_x, gram_y)) => (mul(gram_y, a), mul(gram_x, b)),
        None => (a.to_owned(), b.to_owned()),
    };
    let dot = |x: MatRef<f64>, y: &Mat<f64>| {
        (0..x.ncols()).map(|j| (0..x.nrows()).map(|i| x[(i, j)] * y[(i, j)]).sum::<f64>()).sum::<f64>()
    };
    let value = 0.5 * (dot(a, &grad_a) + dot(b, &grad_b));
    TermValue { value, grad_a, grad_b }
}

/// L1 term of (11) without its weight: Σ_ij w_ij √(t_ij² + ξ) over T = Ψ_k' A Bᵀ Φ_k'ᵀ (m × n),
/// the smooth approximation |t| ≈ √(t² + ξ) of the paper, with optional entry weights
/// w_ij = w^Y_i w^X_j (`super::scaling`).
///
/// With U = Ψ A (m × k), V = Φ B (n × k), T = U Vᵀ and S = ∂/∂T:
/// ∇_A = Ψᵀ S V = Z B and ∇_B = Φᵀ Sᵀ U = Zᵀ A with Z = Ψᵀ S Φ (k' × k').
///
/// T is never stored (see `super::l1`). When k' < 2k, Z is accumulated directly
/// (2·m·n·(k + k') flops), otherwise S V and Sᵀ U are (6·m·n·k flops); memory
/// O((m + n)·k' + block·n).
#[allow(clippy::too_many_arguments)]
pub fn l1(
    a: MatRef<f64>,
    b: MatRef<f64>,
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    xi: f64,
    weights: Option<Weights>,
    block_rows: usize,
    precision: Precision,
) -> TermValue {
    let (kp, k) = (a.nrows(), a.ncols());
    if kp < 2 * k {
        let (value, z) = l1_c(a, b, phi, psi, xi, weights, block_rows, precision);
        chain_c(value, z.as_ref(), a, b)
    } else {
        let (u, v) = rayon::join(|| gemm_nn(psi, a), || gemm_nn(phi, b)); // m × k, n × k
        let r = soft_l1(
            u.as_ref(),
            v.as_ref(),
            xi,
            weights,
            block_rows,
            Products::Factored { pu: u.as_ref(), pv: v.as_ref() },
            precision,
        );
        let (s_pv, st_pu) = (r.s_pv.expect("requested"), r.st_pu.expect("requested"));
        let (grad_a, grad_b) = rayon::join(|| gemm_tn(psi, s_pv.as_ref()), || gemm_tn(phi, st_pu.as_ref()));
        TermValue { value: r.value, grad_a, grad_b }
    }
}

/// Z = ∂/∂C (k' × k') of the L1 term at C = A Bᵀ, with its value: Ψᵀ S Φ.
#[allow(clippy::too_many_arguments)]
pub fn l1_c(
    a: MatRef<f64>,
    b: MatRef<f64>,
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    xi: f64,
    weights: Option<Weights>,
    block_rows: usize,
    precision: Precision,
) -> (f64, Mat<f64>) {
    // U = Ψ A and V = Φ B side by side (each a sequential GEMM below 4096 sample rows).
    let (u, v) = rayon::join(|| gemm_nn(psi, a), || gemm_nn(phi, b));
    let r = soft_l1(u.as_ref(), v.as_ref(), xi, weights, block_rows, Products::Projected { psi, phi }, precision);
    (r.value, r.projected.expect("requested"))
}

/// The value of [`l1`] alone (2·m·n·k flops), for line searches and reports.
#[allow(clippy::too_many_arguments)]
pub fn l1_value(
    a: MatRef<f64>,
    b: MatRef<f64>,
    phi: MatRef<f64>,
    psi: MatRef<f64>,
    xi: f64,
    weights: Option<Weights>,
    block_rows: usize,
    precision: Precision,
) -> f64 {
    // U = Ψ A and V = Φ B side by side (each a sequential GEMM below 4096 sample rows).
    let (u, v) = rayon::join(|| gemm_nn(psi, a), || gemm_nn(phi, b));
    soft_l1(u.as_ref(), v.as_ref(), xi, weights, block_rows, Products::Value, precision).value
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::completion::testutil::{dot, randn};

    const N: usize = 50;
    const M: usize = 45;
    const KP: usize = 8;
    const K: usize = 5;
    const Q: usize = 6;

    /// Central-difference check of a term along random directions: relative error of the
    /// directional derivative ⟨∇_A, D_A⟩ + ⟨∇_B, D_B⟩.
    fn fd_check(f: &dyn Fn(MatRef<f64>, MatRef<f64>) -> TermValue, seed: u64) {
        let a = randn(KP, K, seed);
        let b = randn(KP, K, seed + 1);
        let t = f(a.as_ref(), b.as_ref());
        assert_eq!((t.grad_a.nrows(), t.grad_a.ncols()), (KP, K));
        assert_eq!((t.grad_b.nrows(), t.grad_b.ncols()), (KP, K));
        let mut worst = 0.0f64;
        for trial in 0..3 {
            let da = randn(KP, K, seed + 10 + trial);
            let db = randn(KP, K, seed + 20 + trial);
            // Per-block checks too: A only, B only, both.
            for (wa, wb) in [(1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
                let h = 1e-5;
                let plus = f((&a + &da * (h * wa)).as_ref(), (&b + &db * (h * wb)).as_ref()).value;
                let minus = f((&a - &da * (h * wa)).as_ref(), (&b - &db * (h * wb)).as_ref()).value;
                let fd = (plus - minus) / (2.0 * h);
                let an = wa * dot(&t.grad_a, &da) + wb * dot(&t.grad_b, &db);
                let rel = (fd - an).abs() / an.abs().max(1e-12);
                assert!(rel < 1e-5, "trial {trial} ({wa},{wb}): fd {fd} vs analytic {an}, rel {rel:e}");
                worst = worst.max(rel);
            }
        }
        eprintln!("finite differences (seed {seed}): worst relative error {worst:.1e}");
    }

    fn eigen(k: usize, seed: u64) -> Vec<f64> {
        let r = randn(k, 1, seed);
        let mut l: Vec<f64> = (0..k).map(|i| i as f64 * 1.5 + 0.3 * r[(i, 0)].abs()).collect();
        l[0] = 0.0;
        l
    }

    #[test]
    fn data_term_gradient() {
        let f_hat = randn(KP, Q, 100);
        let g_hat = randn(KP, Q, 101);
        fd_check(&|a, b| data(a, b, f_hat.as_ref(), g_hat.as_ref()), 1);
        // Value: ‖A Bᵀ Â − B̂‖² by a direct formula.
        let (a, b) = (randn(KP, K, 7), randn(KP, K, 8));
        let c = mul(a.as_ref(), b.transpose());
        let r = mul(c.as_ref(), f_hat.as_ref()) - &g_hat;
        let v = data(a.as_ref(), b.as_ref(), f_hat.as_ref(), g_hat.as_ref()).value;
        assert!((v - r.squared_norm_l2()).abs() < 1e-10 * v);
    }

    #[test]
    fn dirichlet_gradients_and_values() {
        let lx = eigen(KP, 200);
        let ly = eigen(KP, 201);
        fd_check(&|a, b| dirichlet_x(a, b, &lx), 2);
        fd_check(&|a, b| dirichlet_y(a, b, &ly), 3);
        // Values against the trace formulas of (11).
        let (a, b) = (randn(KP, K, 9), randn(KP, K, 10));
        let lam_x = Mat::from_fn(KP, KP, |i, j| if i == j { lx[i] } else { 0.0 });
        let lam_y = Mat::from_fn(KP, KP, |i, j| if i == j { ly[i] } else { 0.0 });
        let c = mul(a.as_ref(), b.transpose());
        let tx = mul(mul(c.as_ref(), lam_x.as_ref()).as_ref(), c.transpose());
        let ty = mul(mul(c.transpose(), lam_y.as_ref()).as_ref(), c.as_ref());
        let trace = |m: &Mat<f64>| (0..KP).map(|i| m[(i, i)]).sum::<f64>();
        let vx = dirichlet_x(a.as_ref(), b.as_ref(), &lx).value;
        let vy = dirichlet_y(a.as_ref(), b.as_ref(), &ly).value;
        assert!((vx - trace(&tx)).abs() < 1e-10 * vx.abs());
        assert!((vy - trace(&ty)).abs() < 1e-10 * vy.abs());
    }

    #[test]
    fn commutativity_gradient_and_value() {
        let lx = eigen(KP, 300);
        let ly = eigen(KP, 301);
        fd_check(&|a, b| commutativity(a, b, &lx, &ly, 6), 4);
        fd_check(&|a, b| commutativity(a, b, &lx, &ly, KP), 5);
        let (a, b) = (randn(KP, K, 11), randn(KP, K, 12));
        let c = mul(a.as_ref(), b.transpose());
        let kc = 6;
        let direct: f64 = (0..kc)
            .flat_map(|i| (0..kc).map(move |j| (i, j)))
            .map(|(i, j)| (c[(i, j)] * lx[j] - ly[i] * c[(i, j)]).powi(2))
            .sum();
        let v = commutativity(a.as_ref(), b.as_ref(), &lx, &ly, kc).value;
        assert!((v - direct).abs() < 1e-10 * direct);
    }

    #[test]
    fn low_norm_gradient_and_value() {
        let phi = randn(N, KP, 400);
        let psi = randn(M, KP, 401);
        let gx = gemm_tn(phi.as_ref(), phi.as_ref());
        let gy = gemm_tn(psi.as_ref(), psi.as_ref());
        fd_check(&|a, b| low_norm(a, b, Some((gx.as_ref(), gy.as_ref()))), 6);
        fd_check(&|a, b| low_norm(a, b, None), 7);
        let (a, b) = (randn(KP, K, 13), randn(KP, K, 14));
        let direct =
            0.5 * (mul(psi.as_ref(), a.as_ref()).squared_norm_l2() + mul(phi.as_ref(), b.as_ref()).squared_norm_l2());
        let v = low_norm(a.as_ref(), b.as_ref(), Some((gx.as_ref(), gy.as_ref()))).value;
        assert!((v - direct).abs() < 1e-10 * direct);
        let v = low_norm(a.as_ref(), b.as_ref(), None).value;
        assert!((v - 0.5 * (a.squared_norm_l2() + b.squared_norm_l2())).abs() < 1e-12 * v);
    }

    /// Dense reference: T formed whole.
    fn l1_dense(a: MatRef<f64>, b: MatRef<f64>, phi: MatRef<f64>, psi: MatRef<f64>, xi: f64) -> f64 {
        let t = mul(mul(psi, a).as_ref(), mul(phi, b).transpose());
        (0..t.ncols()).map(|j| (0..t.nrows()).map(|i| (t[(i, j)].powi(2) + xi).sqrt()).sum::<f64>()).sum()
    }

    #[test]
    fn l1_gradient_value_and_blocking() {
        // Scaled so that entries of T are of order √ξ and larger: both regimes of √(t² + ξ).
        let phi = randn(N, KP, 500) * 0.1;
        let psi = randn(M, KP, 501) * 0.1;
        for block in [7, 16, 512] {
            fd_check(&|a, b| l1(a, b, phi.as_ref(), psi.as_ref(), 1e-3, None, block, Precision::F64), 8);
        }
        let (a, b) = (randn(KP, K, 15), randn(KP, K, 16));
        let reference = l1_dense(a.as_ref(), b.as_ref(), phi.as_ref(), psi.as_ref(), 1e-3);
        let full = l1(a.as_ref(), b.as_ref(), phi.as_ref(), psi.as_ref(), 1e-3, None, 7, Precision::F64);
        let single = l1(a.as_ref(), b.as_ref(), phi.as_ref(), psi.as_ref(), 1e-3, None, 1000, Precision::F64);
        for v in [
            full.value,
            single.value,
            l1_value(a.as_ref(), b.as_ref(), phi.as_ref(), psi.as_ref(), 1e-3, None, 7, Precision::F64),
        ] {
            assert!((v - reference).abs() < 1e-12 * reference, "{v} vs {reference}");
        }
        // Block size changes only the summation order.
        let d = (&full.grad_a - &single.grad_a).norm_l2() + (&full.grad_b - &single.grad_b).norm_l2();
        assert!(d < 1e-12 * (full.grad_a.norm_l2() + full.grad_b.norm_l2()));
        // Explicit gradient formulas ∇_A = Ψᵀ S Φ B, ∇_B = Φᵀ Sᵀ Ψ A on the dense T, for both
        // code paths: k' < 2k (Z = Ψᵀ S Φ accumulated) and k' ≥ 2k (S V and Sᵀ U accumulated).
        for k in [K, 3] {
            let (a, b) = (randn(KP, k, 15), randn(KP, k, 16));
            let got = l1(a.as_ref(), b.as_ref(), phi.as_ref(), psi.as_ref(), 1e-3, None, 7, Precision::F64);
            let t = mul(mul(psi.as_ref(), a.as_ref()).as_ref(), mul(phi.as_ref(), b.as_ref()).transpose());
            let s = Mat::from_fn(M, N, |i, j| t[(i, j)] / (t[(i, j)].powi(2) + 1e-3).sqrt());
            let ga = mul(mul(psi.transpose(), s.as_ref()).as_ref(), mul(phi.as_ref(), b.as_ref()).as_ref());
            let gb = mul(mul(phi.transpose(), s.transpose()).as_ref(), mul(psi.as_ref(), a.as_ref()).as_ref());
            assert!((&ga - &got.grad_a).norm_l2() < 1e-10 * ga.norm_l2(), "k = {k}");
            assert!((&gb - &got.grad_b).norm_l2() < 1e-10 * gb.norm_l2(), "k = {k}");
        }
    }
}
