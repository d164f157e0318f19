//! The smoothed L1 norm of a correspondence T = U Vᵀ (m × n) and its gradient, computed in
//! row blocks of T without ever storing T — the hot loop of every form of the method.
//!
//! With |t| ≈ √(t² + ξ) (paper §3.3) and optional positive weights w_ji = w^Y_j w^X_i,
//!
//! ```text
//! L1(T) = Σ_ji w_ji √(t_ji² + ξ),    S = ∂L1/∂T,  s_ji = w_ji t_ji / √(t_ji² + ξ).
//! ```
//!
//! T is formed one block of rows at a time, T_r = U_r Vᵀ (block × n), turned into S_r in place,
//! and consumed by the products the caller needs ([`Products`]):
//! - `Factored`: S·P_V (m × p) and Sᵀ·P_U (n × p'), for gradients with respect to factors
//!   (∇_U = S V, ∇_V = Sᵀ U when T = U Vᵀ): 2·m·n·(k + p + p') flops;
//! - `Projected`: Ψᵀ S Φ (k'_Y × k'_X), the gradient with respect to C of T = Ψ C Φᵀ:
//!   2·m·n·(k + k'_X) + 2·m·k'_X·k'_Y flops.
//!
//! Memory: O((m + n)·k + block·n) per group. The row blocks are split into a fixed number of
//! contiguous groups (independent of the thread count) whose partial sums are added in order,
//! so results do not depend on the number of threads. faer's GEMM runs sequentially inside a
//! group: its own parallel GEMM spins at barriers on small machines (see `spectral::lanczos`).

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use rayon::prelude::*;

/// Maximum number of independent accumulators (groups of row blocks).
const GROUPS: usize = 4;

/// Lanes of the elementwise loops: independent accumulators, so that the sums vectorize without
/// reassociation (the result is the same whichever instruction set runs it).
const LANES: usize = 8;

/// Weights w_ji = `y[j]` · `x[i]` of the entries of T (m × n): `y` has m entries, `x` has n.
#[derive(Clone, Copy, Debug)]
pub struct Weights<'a> {
    /// w^Y (m), one per row of T (vertex of Y).
    pub y: &'a [f64],
    /// w^X (n), one per column of T (vertex of X).
    pub x: &'a [f64],
}

/// Which products of S the caller needs.
#[derive(Clone, Copy, Debug)]
pub enum Products<'a> {
    /// The value only (2·m·n·k flops).
    Value,
    /// S·`pv` (pv: n × p) and Sᵀ·`pu` (pu: m × p').
    Factored {
        /// m × p'.
        pu: MatRef<'a, f64>,
        /// n × p.
        pv: MatRef<'a, f64>,
    },
    /// Ψᵀ S Φ, with `psi` m × k'_Y and `phi` n × k'_X.
    Projected {
        /// Ψ (m × k'_Y).
        psi: MatRef<'a, f64>,
        /// Φ (n × k'_X).
        phi: MatRef<'a, f64>,
    },
}

/// The value of the smoothed L1 norm and the requested products of S.
#[derive(Clone, Debug)]
pub struct L1 {
    /// Σ w √(t² + ξ).
    pub value: f64,
    /// S·P_V (m × p), for [`Products::Factored`].
    pub s_pv: Option<Mat<f64>>,
    /// Sᵀ·P_U (n × p'), for [`Products::Factored`].
    pub st_pu: Option<Mat<f64>>,
    /// Ψᵀ S Φ (k'_Y × k'_X), for [`Products::Projected`].
    pub projected: Option<Mat<f64>>,
}

/// In place t ← w t / √(t² + ξ) over the columns of a block of rows r0.. of T; returns
/// Σ w √(t² + ξ). Unweighted when `w` is `None`.
#[inline(always)]
fn soft_abs_generic(t: &mut Mat<f64>, xi: f64, r0: usize, w: Option<Weights>, grad: bool) -> f64 {
    let mut total = 0.0;
    let len = t.nrows();
    for j in 0..t.ncols() {
        let col = t.col_as_slice_mut(j);
        let mut acc = [0.0f64; LANES];
        match w {
            None => {
                let mut chunks = col.chunks_exact_mut(LANES);
                for c in &mut chunks {
                    for l in 0..LANES {
                        let r = (c[l] * c[l] + xi).sqrt();
                        acc[l] += r;
                        if grad {
                            c[l] /= r;
                        }
                    }
                }
                for (l, x) in chunks.into_remainder().iter_mut().enumerate() {
                    let r = (*x * *x + xi).sqrt();
                    acc[l] += r;
                    if grad {
                        *x /= r;
                    }
                }
                total += acc.iter().sum::<f64>();
            }
            Some(w) => {
                let wx = w.x[j];
                let wy = &w.y[r0..r0 + len];
                let mut chunks = col.chunks_exact_mut(LANES);
                let mut wchunks = wy.chunks_exact(LANES);
                for (c, ww) in (&mut chunks).zip(&mut wchunks) {
                    for l in 0..LANES {
                        let r = (c[l] * c[l] + xi).sqrt();
                        acc[l] += ww[l] * r;
                        if grad {
                            c[l] *= wx * ww[l] / r;
                        }
                    }
                }
                for (l, (x, ww)) in chunks.into_remainder().iter_mut().zip(wchunks.remainder()).enumerate() {
                    let r = (*x * *x + xi).sqrt();
                    acc[l] += ww * r;
                    if grad {
                        *x *= wx * ww / r;
                    }
                }
                total += wx * acc.iter().sum::<f64>();
            }
        }
    }
    total
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn soft_abs_avx2(t: &mut Mat<f64>, xi: f64, r0: usize, w: Option<Weights>, grad: bool) -> f64 {
    soft_abs_generic(t, xi, r0, w, grad)
}

/// [`soft_abs_generic`], compiled for AVX2 when the CPU has it (the crate is built for the
/// baseline x86-64, whose SSE2 vectors are half as wide).
fn soft_abs(t: &mut Mat<f64>, xi: f64, r0: usize, w: Option<Weights>, grad: bool) -> f64 {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports AVX2 and FMA, checked just above.
        return unsafe { soft_abs_avx2(t, xi, r0, w, grad) };
    }
    soft_abs_generic(t, xi, r0, w, grad)
}

/// Contiguous ranges of row blocks, one per group.
fn block_groups(m: usize, block: usize) -> Vec<std::ops::Range<usize>> {
    let nblocks = m.div_ceil(block);
    let groups = GROUPS.min(nblocks).max(1);
    (0..groups).map(|g| g * nblocks / groups..(g + 1) * nblocks / groups).collect()
}

/// Per-group partial results.
struct Partial {
    value: f64,
    /// Rows of S·P_V of this group's row range.
    s_pv: Option<Mat<f64>>,
    /// Partial Sᵀ·P_U.
    st_pu: Option<Mat<f64>>,
    /// Partial Ψᵀ S Φ.
    projected: Option<Mat<f64>>,
}

/// The smoothed L1 norm Σ w √(t² + ξ) of T = U Vᵀ (U: m × k, V: n × k) and the products of its
/// gradient S requested by `products`, in row blocks of `block_rows` rows (see the module
/// documentation). Panics on inconsistent sizes (callers validate their inputs).
pub fn soft_l1(
    u: MatRef<f64>,
    v: MatRef<f64>,
    xi: f64,
    weights: Option<Weights>,
    block_rows: usize,
    products: Products,
) -> L1 {
    let (m, n, k) = (u.nrows(), v.nrows(), u.ncols());
    assert_eq!(v.ncols(), k, "U and V must have the same number of columns");
    if let Some(w) = weights {
        assert!(w.y.len() == m && w.x.len() == n, "weights must have m and n entries");
    }
    match products {
        Products::Factored { pu, pv } => assert!(pu.nrows() == m && pv.nrows() == n, "probe sizes"),
        Products::Projected { psi, phi } => assert!(psi.nrows() == m && phi.nrows() == n, "basis sizes"),
        Products::Value => {}
    }
    let block = block_rows.max(1);
    let ranges = block_groups(m, block);
    let grad = !matches!(products, Products::Value);
    let partials: Vec<Partial> = ranges
        .par_iter()
        .map(|range| {
            let rows0 = range.start * block;
            let rows1 = (range.end * block).min(m);
            let mut p = Partial { value: 0.0, s_pv: None, st_pu: None, projected: None };
            match products {
                Products::Factored { pu, pv } => {
                    p.s_pv = Some(Mat::zeros(rows1 - rows0, pv.ncols()));
                    p.st_pu = Some(Mat::zeros(n, pu.ncols()));
                }
                Products::Projected { psi, phi } => p.projected = Some(Mat::zeros(psi.ncols(), phi.ncols())),
                Products::Value => {}
            }
            let mut t = Mat::<f64>::zeros(0, 0);
            let mut s_phi = Mat::<f64>::zeros(0, 0);
            for bi in range.clone() {
                let r0 = bi * block;
                let len = block.min(m - r0);
                if t.nrows() != len {
                    t = Mat::zeros(len, n);
                }
                let ur = u.subrows(r0, len);
                matmul(t.as_mut(), Accum::Replace, ur, v.transpose(), 1.0, Par::Seq);
                p.value += soft_abs(&mut t, xi, r0, weights, grad);
                match products {
                    Products::Value => {}
                    Products::Factored { pu, pv } => {
                        let out = p.s_pv.as_mut().expect("allocated");
                        matmul(
                            out.as_mut().subrows_mut(r0 - rows0, len),
                            Accum::Replace,
                            t.as_ref(),
                            pv,
                            1.0,
                            Par::Seq,
                        );
                        let acc = p.st_pu.as_mut().expect("allocated");
                        matmul(acc.as_mut(), Accum::Add, t.transpose(), pu.subrows(r0, len), 1.0, Par::Seq);
                    }
                    Products::Projected { psi, phi } => {
                        if s_phi.nrows() != len {
                            s_phi = Mat::zeros(len, phi.ncols());
                        }
                        matmul(s_phi.as_mut(), Accum::Replace, t.as_ref(), phi, 1.0, Par::Seq);
                        let acc = p.projected.as_mut().expect("allocated");
                        matmul(
                            acc.as_mut(),
                            Accum::Add,
                            psi.subrows(r0, len).transpose(),
                            s_phi.as_ref(),
                            1.0,
                            Par::Seq,
                        );
                    }
                }
            }
            p
        })
        .collect();
    let mut out = L1 { value: 0.0, s_pv: None, st_pu: None, projected: None };
    for p in partials {
        out.value += p.value;
        if let Some(rows) = p.s_pv {
            out.s_pv = Some(match out.s_pv.take() {
                None => rows,
                Some(prev) => {
                    let (a, b) = (prev.nrows(), rows.nrows());
                    Mat::from_fn(a + b, rows.ncols(), |i, j| if i < a { prev[(i, j)] } else { rows[(i - a, j)] })
                }
            });
        }
        for (acc, part) in [(&mut out.st_pu, p.st_pu), (&mut out.projected, p.projected)] {
            if let Some(part) = part {
                match acc {
                    Some(a) => *a += &part,
                    None => *acc = Some(part),
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::completion::testutil::randn;
    use crate::completion::{gemm_tn, mul};

    fn dense_s(u: &Mat<f64>, v: &Mat<f64>, xi: f64, w: Option<Weights>) -> (f64, Mat<f64>) {
        let t = mul(u.as_ref(), v.transpose());
        let wt = |i: usize, j: usize| w.map_or(1.0, |w| w.y[i] * w.x[j]);
        let value = (0..t.ncols())
            .map(|j| (0..t.nrows()).map(|i| wt(i, j) * (t[(i, j)].powi(2) + xi).sqrt()).sum::<f64>())
            .sum();
        let s = Mat::from_fn(t.nrows(), t.ncols(), |i, j| wt(i, j) * t[(i, j)] / (t[(i, j)].powi(2) + xi).sqrt());
        (value, s)
    }

    #[test]
    fn blocked_products_match_the_dense_formulas() {
        let (m, n, k) = (45, 50, 5);
        let u = randn(m, k, 1) * 0.1;
        let v = randn(n, k, 2) * 0.1;
        let (pu, pv) = (randn(m, 3, 3), randn(n, 4, 4));
        let (psi, phi) = (randn(m, 7, 5), randn(n, 6, 6));
        let wy: Vec<f64> = (0..m).map(|i| 0.5 + (i % 7) as f64 * 0.1).collect();
        let wx: Vec<f64> = (0..n).map(|i| 0.3 + (i % 5) as f64 * 0.2).collect();
        for w in [None, Some(Weights { y: &wy, x: &wx })] {
            let (value, s) = dense_s(&u, &v, 1e-3, w);
            for block in [1, 7, 16, 1000] {
                let f = soft_l1(
                    u.as_ref(),
                    v.as_ref(),
                    1e-3,
                    w,
                    block,
                    Products::Factored { pu: pu.as_ref(), pv: pv.as_ref() },
                );
                assert!((f.value - value).abs() < 1e-12 * value);
                let spv = mul(s.as_ref(), pv.as_ref());
                let stpu = mul(s.transpose(), pu.as_ref());
                assert!((f.s_pv.as_ref().unwrap() - &spv).norm_l2() < 1e-12 * spv.norm_l2());
                assert!((f.st_pu.as_ref().unwrap() - &stpu).norm_l2() < 1e-12 * stpu.norm_l2());
                let p = soft_l1(
                    u.as_ref(),
                    v.as_ref(),
                    1e-3,
                    w,
                    block,
                    Products::Projected { psi: psi.as_ref(), phi: phi.as_ref() },
                );
                let z = mul(gemm_tn(psi.as_ref(), s.as_ref()).as_ref(), phi.as_ref());
                assert!((p.projected.as_ref().unwrap() - &z).norm_l2() < 1e-12 * z.norm_l2());
                let val = soft_l1(u.as_ref(), v.as_ref(), 1e-3, w, block, Products::Value).value;
                assert!((val - value).abs() < 1e-12 * value);
            }
        }
    }

    #[test]
    fn elementwise_kernel_agrees_with_the_generic_code() {
        let t0 = randn(13, 7, 600) * 0.05;
        let wy: Vec<f64> = (0..20).map(|i| 1.0 + i as f64).collect();
        let wx: Vec<f64> = (0..7).map(|i| 0.5 + i as f64).collect();
        for w in [None, Some(Weights { y: &wy, x: &wx })] {
            let (mut t1, mut t2) = (t0.clone(), t0.clone());
            let v1 = soft_abs(&mut t1, 1e-3, 2, w, true);
            let v2 = soft_abs_generic(&mut t2, 1e-3, 2, w, true);
            assert_eq!(v1, v2);
            assert_eq!(t1, t2);
            let mut t3 = t0.clone();
            assert_eq!(soft_abs(&mut t3, 1e-3, 2, w, false), v1);
            assert_eq!(t3, t0);
        }
    }
}
