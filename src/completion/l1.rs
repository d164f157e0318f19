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
//!
//! # Products in single precision ([`Precision::F32`], opt-in)
//!
//! faer's f32 GEMM does twice the flops per vector instruction of its f64 one. With
//! [`Precision::F32`], U, V and P_U, P_V (or Ψ, Φ) are rounded to f32 once per call; each block
//! T̂_r = U_r Vᵀ is formed by the f32 GEMM; √(t̂² + ξ), the value and s = w t̂ / √(t̂² + ξ) are
//! computed in f64 from the f32 t̂, and s is rounded back to f32. The products of S sum in f32
//! over at most c = `F32_CHUNK` = 512 columns (S·P_V, S Φ: the chunks are added in f64) or over
//! the b rows of one block (Sᵀ·P_U and Ψ_rᵀ (S_r Φ), whose blocks are added in f64; S_r Φ is
//! rounded to f32 once more before that product). Every sum across blocks is in f64.
//!
//! Error bound (worst case). With u = 2⁻²⁴ and γ_j = j u / (1 − j u), an f32 sum of j products
//! of f32-rounded operands differs from the exact sum of the unrounded products by at most
//! γ_{j+2} times the sum of their absolute values (Higham, *Accuracy and Stability of Numerical
//! Algorithms*, §3.1). With τ_ji = Σ_l |u_jl| |v_il| ≤ ‖u_j‖ ‖v_i‖ (rows of U and V):
//!
//! ```text
//! |t̂ − t| ≤ γ_{k+2} τ                                  (k = 250: γ_252 ≈ 1.5e-5)
//! ```
//!
//! The smoothed |·|, f(t) = √(t² + ξ), has |f′| ≤ 1 and |f″| = ξ / (t² + ξ)^{3/2} ≤ 1/√ξ, so
//!
//! ```text
//! |L̂1 − L1| ≤ γ_{k+2} Σ w τ,     relative: ≤ γ_{k+2} Σ w τ / Σ w √(t² + ξ)
//! |ŝ − s|   ≤ w (γ_{k+2} τ / √ξ + u)     (u: s rounded to f32)
//! |Ẑ − Z|   ≤ |Ψ|ᵀ |Ŝ − S| |Φ| + γ_{c+b+3} |Ψ|ᵀ |S| |Φ|       (entrywise, Z = Ψᵀ S Φ)
//! ```
//!
//! (and S·P_V, Sᵀ·P_U likewise with γ_{c+1}, γ_{b+1}), up to f64 roundings; ∇_A = Z B and
//! ∇_B = Zᵀ A are formed in f64 from Ẑ. The gradient's bound grows as 1/√ξ where T has entries
//! near 0, its value's does not. The test `f32_l1_kernel_agrees_with_f64_within_the_bound` checks
//! these bounds entry by entry. They are pessimistic: rounding errors have random signs (~√j u
//! rather than j u), and in the value they also cancel over the m·n entries. Measured (BENCHMARKS.md,
//! `examples/completion_timing.rs precision` and `pair-precision`): relative differences of the
//! value ~1e-13 (random bases) and ~1e-10 (faust_r, k' = 350, k = 250, ξ = 1e-2, weighted), of
//! the gradient ~1e-7, against bounds of ~1e-5 and more. The optimizer's objective changes by
//! more than that per iteration (~1e-6 relative late in a run), and the f32 kernel's results are
//! as deterministic (independent of the thread count) as the f64 kernel's. L-BFGS runs with either
//! kernel follow the same path for ~20 iterations and then drift apart, as any perturbation does
//! (measured in BENCHMARKS.md, with final errors within ±0.03 ×100 on two faust_r pairs), which
//! is why f64 stays the default.

use faer::linalg::matmul::matmul;
use faer::reborrow::ReborrowMut;
use faer::{Accum, Mat, MatRef, Par};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::linalg::round_to_f32;

/// Maximum number of independent accumulators (groups of row blocks).
const GROUPS: usize = 4;

/// Longest sum formed in f32 by the products of S with [`Precision::F32`] (S·P_V and S Φ sum over
/// the n columns of T in chunks of this many, the chunks added in f64).
const F32_CHUNK: usize = 512;

/// The arithmetic of the products of `soft_l1` (the smoothed |·|, its derivative and every sum
/// across blocks are in f64 either way).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// f64 GEMM (the default).
    #[default]
    F64,
    /// f32 GEMM on f32 copies of the operands, partial products added in f64; see the module
    /// documentation for the error bound.
    F32,
}

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

crate::linalg::at_vector_width! {
    /// [`soft_abs_generic`] at the CPU's vector width (the crate is built for the baseline
    /// x86-64, whose SSE2 vectors hold two f64).
    fn soft_abs(t: &mut Mat<f64>, xi: f64, r0: usize, w: Option<Weights>, grad: bool) -> f64 = soft_abs_generic
}

/// [`soft_abs_generic`] on a block of T held in f32: each t is widened to f64, √(t² + ξ) and the
/// sums are formed in f64, and s = w t / √(t² + ξ) is rounded back to f32 in place.
#[inline(always)]
fn soft_abs32_generic(t: &mut Mat<f32>, xi: f64, r0: usize, w: Option<Weights>, grad: bool) -> f64 {
    let mut total = 0.0;
    let len = t.nrows();
    for j in 0..t.ncols() {
        let col = t.col_as_slice_mut(j);
        let mut acc = [0.0f64; LANES];
        let (wx, wy) = match w {
            Some(w) => (w.x[j], Some(&w.y[r0..r0 + len])),
            None => (1.0, None),
        };
        match wy {
            None => {
                let mut chunks = col.chunks_exact_mut(LANES);
                for c in &mut chunks {
                    for l in 0..LANES {
                        let x = c[l] as f64;
                        let r = (x * x + xi).sqrt();
                        acc[l] += r;
                        if grad {
                            c[l] = (x / r) as f32;
                        }
                    }
                }
                for (l, c) in chunks.into_remainder().iter_mut().enumerate() {
                    let x = *c as f64;
                    let r = (x * x + xi).sqrt();
                    acc[l] += r;
                    if grad {
                        *c = (x / r) as f32;
                    }
                }
            }
            Some(wy) => {
                let mut chunks = col.chunks_exact_mut(LANES);
                let mut wchunks = wy.chunks_exact(LANES);
                for (c, ww) in (&mut chunks).zip(&mut wchunks) {
                    for l in 0..LANES {
                        let x = c[l] as f64;
                        let r = (x * x + xi).sqrt();
                        acc[l] += ww[l] * r;
                        if grad {
                            c[l] = (x * (wx * ww[l] / r)) as f32;
                        }
                    }
                }
                for (l, (c, ww)) in chunks.into_remainder().iter_mut().zip(wchunks.remainder()).enumerate() {
                    let x = *c as f64;
                    let r = (x * x + xi).sqrt();
                    acc[l] += ww * r;
                    if grad {
                        *c = (x * (wx * ww / r)) as f32;
                    }
                }
            }
        }
        total += wx * acc.iter().sum::<f64>();
    }
    total
}

crate::linalg::at_vector_width! {
    /// [`soft_abs32_generic`] at the CPU's vector width.
    fn soft_abs32(t: &mut Mat<f32>, xi: f64, r0: usize, w: Option<Weights>, grad: bool) -> f64 = soft_abs32_generic
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
    precision: Precision,
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
    let partials = match precision {
        Precision::F64 => partials_f64(u, v, xi, weights, block, products),
        Precision::F32 => partials_f32(u, v, xi, weights, block, products),
    };
    combine(partials)
}

/// The per-group partial results of [`soft_l1`] in f64.
fn partials_f64(
    u: MatRef<f64>,
    v: MatRef<f64>,
    xi: f64,
    weights: Option<Weights>,
    block: usize,
    products: Products,
) -> Vec<Partial> {
    let (m, n) = (u.nrows(), v.nrows());
    let ranges = block_groups(m, block);
    let grad = !matches!(products, Products::Value);
    ranges
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
        .collect()
}

/// `acc` += `part`, widened to f64 (column by column, at the CPU's vector width).
fn add_widened(mut acc: faer::MatMut<f64>, part: MatRef<f32>) {
    for j in 0..acc.ncols() {
        match (acc.rb_mut().col_mut(j).try_as_col_major_mut(), part.col(j).try_as_col_major()) {
            (Some(a), Some(p)) => add_widened_slice(a.as_slice_mut(), p.as_slice()),
            _ => {
                for i in 0..acc.nrows() {
                    acc[(i, j)] += part[(i, j)] as f64;
                }
            }
        }
    }
}

#[inline(always)]
fn add_widened_slice_generic(acc: &mut [f64], part: &[f32]) {
    for (a, &p) in acc.iter_mut().zip(part) {
        *a += p as f64;
    }
}

crate::linalg::at_vector_width! {
    /// `acc` += `part` widened to f64, entry by entry.
    fn add_widened_slice(acc: &mut [f64], part: &[f32]) = add_widened_slice_generic
}

/// `dst` (f64) = `s` · `p`, with the sum over the columns of `s` (rows of `p`) formed in f32 over
/// chunks of at most [`F32_CHUNK`] terms and added in f64; `tmp` is scratch of dst's shape.
fn mul_chunked(mut dst: faer::MatMut<f64>, s: MatRef<f32>, p: MatRef<f32>, tmp: &mut Mat<f32>) {
    dst.fill(0.0);
    let n = s.ncols();
    let mut c0 = 0;
    while c0 < n {
        let len = F32_CHUNK.min(n - c0);
        matmul(tmp.as_mut(), Accum::Replace, s.subcols(c0, len), p.subrows(c0, len), 1.0f32, Par::Seq);
        add_widened(dst.as_mut(), tmp.as_ref());
        c0 += len;
    }
}

/// The per-group partial results of [`soft_l1`] with the products in f32 ([`Precision::F32`]).
fn partials_f32(
    u: MatRef<f64>,
    v: MatRef<f64>,
    xi: f64,
    weights: Option<Weights>,
    block: usize,
    products: Products,
) -> Vec<Partial> {
    let (m, n) = (u.nrows(), v.nrows());
    let ranges = block_groups(m, block);
    let grad = !matches!(products, Products::Value);
    let (u32_, v32) = (round_to_f32(u), round_to_f32(v));
    let (a32, b32) = match products {
        Products::Value => (None, None),
        Products::Factored { pu, pv } => (Some(round_to_f32(pu)), Some(round_to_f32(pv))),
        Products::Projected { psi, phi } => (Some(round_to_f32(psi)), Some(round_to_f32(phi))),
    };
    ranges
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
            let mut t = Mat::<f32>::zeros(0, 0);
            // Scratch: rows of S·P_V or S Φ in f64, the same in f32, and an f32 product.
            let (mut rows64, mut tmp, mut small) =
                (Mat::<f64>::zeros(0, 0), Mat::<f32>::zeros(0, 0), Mat::<f32>::zeros(0, 0));
            for bi in range.clone() {
                let r0 = bi * block;
                let len = block.min(m - r0);
                if t.nrows() != len {
                    t = Mat::zeros(len, n);
                }
                matmul(t.as_mut(), Accum::Replace, u32_.as_ref().subrows(r0, len), v32.transpose(), 1.0f32, Par::Seq);
                p.value += soft_abs32(&mut t, xi, r0, weights, grad);
                let (Some(a32), Some(b32)) = (a32.as_ref(), b32.as_ref()) else { continue };
                if tmp.nrows() != len {
                    tmp = Mat::zeros(len, b32.ncols());
                }
                match products {
                    Products::Value => {}
                    Products::Factored { .. } => {
                        // S_r · P_V (len × p), then Sᵀ_r · P_U,r (n × p').
                        let out = p.s_pv.as_mut().expect("allocated");
                        mul_chunked(out.as_mut().subrows_mut(r0 - rows0, len), t.as_ref(), b32.as_ref(), &mut tmp);
                        if small.nrows() != n {
                            small = Mat::zeros(n, a32.ncols());
                        }
                        matmul(
                            small.as_mut(),
                            Accum::Replace,
                            t.transpose(),
                            a32.as_ref().subrows(r0, len),
                            1.0f32,
                            Par::Seq,
                        );
                        add_widened(p.st_pu.as_mut().expect("allocated").as_mut(), small.as_ref());
                    }
                    Products::Projected { .. } => {
                        // S_r Φ (len × k'_X) summed in f64 over column chunks, rounded to f32,
                        // then Ψ_rᵀ (S_r Φ) (k'_Y × k'_X) added in f64.
                        if rows64.nrows() != len {
                            rows64 = Mat::zeros(len, b32.ncols());
                        }
                        mul_chunked(rows64.as_mut(), t.as_ref(), b32.as_ref(), &mut tmp);
                        let rows32 = round_to_f32(rows64.as_ref());
                        if small.nrows() != a32.ncols() {
                            small = Mat::zeros(a32.ncols(), b32.ncols());
                        }
                        matmul(
                            small.as_mut(),
                            Accum::Replace,
                            a32.as_ref().subrows(r0, len).transpose(),
                            rows32.as_ref(),
                            1.0f32,
                            Par::Seq,
                        );
                        add_widened(p.projected.as_mut().expect("allocated").as_mut(), small.as_ref());
                    }
                }
            }
            p
        })
        .collect()
}

/// Adds the groups' partial results in order.
fn combine(partials: Vec<Partial>) -> L1 {
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
                    Precision::F64,
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
                    Precision::F64,
                );
                let z = mul(gemm_tn(psi.as_ref(), s.as_ref()).as_ref(), phi.as_ref());
                assert!((p.projected.as_ref().unwrap() - &z).norm_l2() < 1e-12 * z.norm_l2());
                let val = soft_l1(u.as_ref(), v.as_ref(), 1e-3, w, block, Products::Value, Precision::F64).value;
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

    fn abs(a: &Mat<f64>) -> Mat<f64> {
        Mat::from_fn(a.nrows(), a.ncols(), |i, j| a[(i, j)].abs())
    }

    /// The f32 products agree with the f64 ones within the bounds of the module documentation,
    /// entry by entry, for every kind of product, with and without weights; n > [`F32_CHUNK`] so
    /// that the chunked sums are exercised. The bounds are worst cases: the measured differences
    /// are printed (about 1e-7 relative for the gradients).
    #[test]
    fn f32_l1_kernel_agrees_with_f64_within_the_bound() {
        let (m, n, k, xi) = (300, 1100, 60, 1e-2);
        // Entries of T of the order of √ξ.
        let u = randn(m, k, 11) * 0.04;
        let v = randn(n, k, 12) * 0.04;
        let (pu, pv) = (randn(m, 9, 13), randn(n, 8, 14));
        let (psi, phi) = (randn(m, 30, 15), randn(n, 25, 16));
        let wy: Vec<f64> = (0..m).map(|i| 0.5 + (i % 7) as f64 * 0.1).collect();
        let wx: Vec<f64> = (0..n).map(|i| 0.3 + (i % 5) as f64 * 0.2).collect();
        let uu = 2f64.powi(-24);
        let gamma = |j: usize| j as f64 * uu / (1.0 - j as f64 * uu);
        // τ = |U| |V|ᵀ bounds |t̂ − t| / γ_{k+2}.
        let tau = mul(abs(&u).as_ref(), abs(&v).transpose());
        for w in [None, Some(Weights { y: &wy, x: &wx })] {
            let wt = |i: usize, j: usize| w.map_or(1.0, |w| w.y[i] * w.x[j]);
            let (value, s) = dense_s(&u, &v, xi, w);
            // Bound on |Ŝ − S| entrywise (u doubled for the f64 arithmetic), then on the products.
            let ds = Mat::from_fn(m, n, |i, j| wt(i, j) * (gamma(k + 2) * tau[(i, j)] / xi.sqrt() + 2.0 * uu));
            let value_bound = gamma(k + 2)
                * (0..n).map(|j| (0..m).map(|i| wt(i, j) * tau[(i, j)]).sum::<f64>()).sum::<f64>()
                + 1e-12 * value;
            for block in [64, 256] {
                let chunk = F32_CHUNK.min(n);
                let f = |products| soft_l1(u.as_ref(), v.as_ref(), xi, w, block, products, Precision::F32);
                let g = |products| soft_l1(u.as_ref(), v.as_ref(), xi, w, block, products, Precision::F64);
                // Factored: S·P_V sums over chunks of columns, Sᵀ·P_U over a block of rows.
                let products = Products::Factored { pu: pu.as_ref(), pv: pv.as_ref() };
                let (a, b) = (f(products), g(products));
                assert!((a.value - b.value).abs() <= value_bound, "{} {}", a.value - b.value, value_bound);
                assert!((a.value - value).abs() <= value_bound);
                let (abs_s, apu, apv) = (abs(&s), abs(&pu), abs(&pv));
                let bound_spv = mul(ds.as_ref(), apv.as_ref()) + mul(abs_s.as_ref(), apv.as_ref()) * gamma(chunk + 1);
                let bound_stpu =
                    mul(ds.transpose(), apu.as_ref()) + mul(abs_s.transpose(), apu.as_ref()) * gamma(block + 1);
                let spv = mul(s.as_ref(), pv.as_ref());
                let stpu = mul(s.transpose(), pu.as_ref());
                for (got, want, bound) in
                    [(a.s_pv.as_ref().unwrap(), &spv, &bound_spv), (a.st_pu.as_ref().unwrap(), &stpu, &bound_stpu)]
                {
                    let mut worst = 0.0f64;
                    for j in 0..want.ncols() {
                        for i in 0..want.nrows() {
                            let d = (got[(i, j)] - want[(i, j)]).abs();
                            assert!(d <= bound[(i, j)] + 1e-12 * want.norm_l2(), "{d} > {}", bound[(i, j)]);
                            worst = worst.max(d / bound[(i, j)]);
                        }
                    }
                    eprintln!(
                        "block {block}, weights {}: relative difference {:.2e}, at most {:.2e} of the bound",
                        w.is_some(),
                        (got - want).norm_l2() / want.norm_l2(),
                        worst
                    );
                }
                // Projected: S Φ over chunks of columns (then rounded to f32), Ψ_rᵀ (S Φ)_r over a
                // block of rows.
                let products = Products::Projected { psi: psi.as_ref(), phi: phi.as_ref() };
                let a = f(products);
                assert!((a.value - value).abs() <= value_bound);
                let (apsi, aphi) = (abs(&psi), abs(&phi));
                let bound = mul(gemm_tn(apsi.as_ref(), ds.as_ref()).as_ref(), aphi.as_ref())
                    + mul(gemm_tn(apsi.as_ref(), abs_s.as_ref()).as_ref(), aphi.as_ref()) * gamma(chunk + block + 3);
                let z = mul(gemm_tn(psi.as_ref(), s.as_ref()).as_ref(), phi.as_ref());
                let got = a.projected.as_ref().unwrap();
                for j in 0..z.ncols() {
                    for i in 0..z.nrows() {
                        let d = (got[(i, j)] - z[(i, j)]).abs();
                        assert!(d <= bound[(i, j)] + 1e-12 * z.norm_l2(), "{d} > {}", bound[(i, j)]);
                    }
                }
                let rel = (got - &z).norm_l2() / z.norm_l2();
                eprintln!("projected, block {block}, weights {}: relative difference {rel:.2e}", w.is_some());
                assert!(rel < 1e-5, "{rel}");
                let val = f(Products::Value).value;
                assert!((val - value).abs() <= value_bound);
                // Deterministic: the same bits again.
                assert_eq!(f(products).projected.unwrap(), *got);
            }
        }
    }

    /// The smoothed |·| of a block (f64 and f32 blocks, with and without weights and gradient)
    /// is the same bits at every vector width.
    #[test]
    fn soft_abs_is_the_same_at_every_vector_width() {
        let (len, n) = (29, 13);
        let t = Mat::from_fn(len, n, |i, j| ((i * 7 + j * 3) as f64 * 0.61).sin() * 0.2);
        let (wy, wx): (Vec<f64>, Vec<f64>) =
            ((0..len + 5).map(|i| 1.0 + 0.1 * i as f64).collect(), (0..n).map(|j| 0.5 + 0.05 * j as f64).collect());
        for w in [None, Some(Weights { y: &wy, x: &wx })] {
            for grad in [false, true] {
                let run64 = |widest: u8| {
                    let mut b = t.clone();
                    let v = crate::linalg::with_widest(widest, || soft_abs(&mut b, 1e-2, 5, w, grad));
                    (
                        v.to_bits(),
                        (0..n)
                            .flat_map(|j| (0..len).map(move |i| (i, j)))
                            .map(|(i, j)| b[(i, j)].to_bits())
                            .collect::<Vec<_>>(),
                    )
                };
                let run32 = |widest: u8| {
                    let mut b = Mat::<f32>::from_fn(len, n, |i, j| t[(i, j)] as f32);
                    let v = crate::linalg::with_widest(widest, || soft_abs32(&mut b, 1e-2, 5, w, grad));
                    (
                        v.to_bits(),
                        (0..n)
                            .flat_map(|j| (0..len).map(move |i| (i, j)))
                            .map(|(i, j)| b[(i, j)].to_bits())
                            .collect::<Vec<_>>(),
                    )
                };
                for widest in 1..=2 {
                    assert_eq!(run64(widest), run64(0), "f64, widest {widest}");
                    assert_eq!(run32(widest), run32(0), "f32, widest {widest}");
                }
            }
        }
    }
}
