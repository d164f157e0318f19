//! Dense linear-algebra helpers shared by the solvers (one copy each): the small product `mul`,
//! the Frobenius inner product `frob`, the minimum-norm solve `min_norm_solve`, and the
//! tall-skinny products of the completion method and of the block Lanczos eigensolver (`a_b`,
//! `a_b_into`, `at_b`, `at_b_as_bt_a`), column-by-column helpers on column-major matrices
//! (`round_to_f32`, `row_squared_norms`, `max_abs_finite`, `scale_rows`, `gather_rows`), and
//! [`at_vector_width!`](at_vector_width) for the loops that are not faer's.
//!
//! **Vector width.** The crate is compiled for the baseline x86-64 (SSE2: two f64 per vector) so
//! that one binary and one wheel run everywhere; faer's kernels choose AVX-512 or AVX2 at run
//! time, our own loops do not. `at_vector_width!` compiles an `#[inline(always)]` function three
//! times and picks the widest the CPU has. Since Rust neither reassociates nor contracts
//! floating-point operations, each width computes the same bits (tests pin the width per
//! thread and compare), so a map never depends on the machine's vector unit.
//!
//! **Tall-skinny products.** The long dimension n (vertices, n ≫ p, q) is split into row chunks
//! run as rayon tasks, each a *sequential* faer GEMM: faer's own parallel GEMM spreads such
//! products over threads that spin at barriers, which on a 2-core machine (or any busy one)
//! costs more than it gains (measured 4× slower than sequential on a 52k-vertex mesh under
//! load), while rayon's idle workers sleep. Chunk boundaries depend only on n and the
//! [`RowChunks`] of the caller, never on the thread count, and the partial sums of Aᵀ B are
//! added in chunk order, so results are deterministic.
//!
//! The chunking and the operand order are part of the arithmetic: they fix the order of the
//! floating-point sums. The two callers were tuned separately and keep their own, bit for bit:
//! the completion solvers use [`RowChunks::SOLVER`] and [`at_b`] (Aᵀ B packed as written), the
//! eigensolver [`RowChunks::KRYLOV`] and [`at_b_as_bt_a`] (the same product computed as
//! (Bᵀ A)ᵀ, which packs the thin block rather than the tall basis). Merging the two `Aᵀ B`
//! paths would change the eigenbases and every result downstream in the last bits.

use faer::linalg::matmul::matmul;
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::{Accum, Mat, MatMut, MatRef, Par};
use rayon::prelude::*;

/// `$vis fn $name(args) -> R` that runs the `#[inline(always)]` function `$generic` compiled for
/// the widest vectors the CPU has: AVX-512F, AVX2, or the baseline x86-64 the crate is built for
/// (SSE2: two f64 lanes), detected at run time (std caches the answer). For loops the compiler
/// vectorizes but that are not faer's kernels (which dispatch on their own). Every width
/// computes the same values bit for bit: Rust never contracts a product and a sum into a fused
/// multiply-add nor reassociates, so a wider vector only runs more of the same operations at
/// once. Written here rather than taken from the `multiversion` crate: one macro of a few
/// lines, no procedural-macro dependency to build.
macro_rules! at_vector_width {
    ($(#[$meta:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? = $generic:path) => {
        $(#[$meta])*
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx512f")]
                unsafe fn avx512($($arg: $ty),*) $(-> $ret)? {
                    $generic($($arg),*)
                }
                #[target_feature(enable = "avx2")]
                unsafe fn avx2($($arg: $ty),*) $(-> $ret)? {
                    $generic($($arg),*)
                }
                let widest = crate::linalg::widest_allowed();
                if widest >= 2 && std::arch::is_x86_feature_detected!("avx512f") {
                    // SAFETY: the CPU has AVX-512F (checked on the line above).
                    return unsafe { avx512($($arg),*) };
                }
                if widest >= 1 && std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU has AVX2 (checked on the line above).
                    return unsafe { avx2($($arg),*) };
                }
            }
            $generic($($arg),*)
        }
    };
}
pub(crate) use at_vector_width;

#[cfg(test)]
thread_local! {
    /// The widest vectors [`at_vector_width`] may use on this thread (tests): 0 the baseline,
    /// 1 up to AVX2, 2 up to AVX-512F.
    pub(crate) static WIDEST: std::cell::Cell<u8> = const { std::cell::Cell::new(2) };
}

/// The widest vectors [`at_vector_width`] may use (always every width outside tests).
#[inline]
pub(crate) fn widest_allowed() -> u8 {
    #[cfg(test)]
    {
        WIDEST.with(|w| w.get())
    }
    #[cfg(not(test))]
    {
        2
    }
}

/// Runs `f` with [`at_vector_width`] limited to `widest` on this thread (tests of the widths).
#[cfg(test)]
pub(crate) fn with_widest<R>(widest: u8, f: impl FnOnce() -> R) -> R {
    let old = WIDEST.with(|w| w.replace(widest));
    let r = f();
    WIDEST.with(|w| w.set(old));
    r
}

/// The rows `rows` of the columns `cols` of X, each column scaled by `scale` (r × #cols, r =
/// `rows.len()`; entry (s, a) = scale · x[rows[s], cols.start + a]), built column by column.
/// Exactly the entries of the element-by-element gather (a copy, or one product by `scale`).
pub fn gather_rows(x: MatRef<f64>, rows: &[usize], cols: std::ops::Range<usize>, scale: f64) -> Mat<f64> {
    let mut out = Mat::<f64>::zeros(rows.len(), cols.len());
    gather_rows_into(out.as_mut(), x, rows, cols, scale);
    out
}

/// [`gather_rows`] into `out` (r × #cols, column-major).
pub fn gather_rows_into(
    mut out: MatMut<f64>,
    x: MatRef<f64>,
    rows: &[usize],
    cols: std::ops::Range<usize>,
    scale: f64,
) {
    debug_assert_eq!((out.nrows(), out.ncols()), (rows.len(), cols.len()));
    for (a, c) in cols.enumerate() {
        let mut dst = out.rb_mut().col_mut(a);
        let dst = dst.rb_mut().try_as_col_major_mut().expect("output columns are contiguous").as_slice_mut();
        match x.col(c).try_as_col_major() {
            Some(col) => {
                let src = col.as_slice();
                if scale == 1.0 {
                    dst.iter_mut().zip(rows).for_each(|(d, &r)| *d = src[r]);
                } else {
                    dst.iter_mut().zip(rows).for_each(|(d, &r)| *d = scale * src[r]);
                }
            }
            None if scale == 1.0 => dst.iter_mut().zip(rows).for_each(|(d, &r)| *d = x[(r, c)]),
            None => dst.iter_mut().zip(rows).for_each(|(d, &r)| *d = scale * x[(r, c)]),
        }
    }
}

/// diag(w) X (m × d, `w` of length m): every row of X times its weight, column by column at the
/// CPU's vector width.
pub fn scale_rows(x: MatRef<f64>, w: &[f64]) -> Mat<f64> {
    debug_assert_eq!(x.nrows(), w.len());
    let mut out = Mat::<f64>::zeros(x.nrows(), x.ncols());
    for j in 0..x.ncols() {
        let dst = out.col_as_slice_mut(j);
        match x.col(j).try_as_col_major() {
            Some(col) => scale_slice(dst, w, col.as_slice()),
            None => dst.iter_mut().enumerate().for_each(|(i, v)| *v = w[i] * x[(i, j)]),
        }
    }
    out
}

#[inline(always)]
fn scale_slice_generic(dst: &mut [f64], w: &[f64], x: &[f64]) {
    for ((d, &a), &b) in dst.iter_mut().zip(w).zip(x) {
        *d = a * b;
    }
}

at_vector_width! {
    /// `dst` = `w` · `x`, entry by entry.
    fn scale_slice(dst: &mut [f64], w: &[f64], x: &[f64]) = scale_slice_generic
}

/// X (m × d) rounded to f32, column by column at the CPU's vector width.
pub fn round_to_f32(x: MatRef<f64>) -> Mat<f32> {
    round_to_f32_scaled(x, 1.0)
}

/// σ X (m × d) rounded to f32 (entry by entry fl₃₂(σ x_ij); σ = 1 is [`round_to_f32`]).
pub fn round_to_f32_scaled(x: MatRef<f64>, sigma: f64) -> Mat<f32> {
    let mut out = Mat::<f32>::zeros(x.nrows(), x.ncols());
    for j in 0..x.ncols() {
        let dst = out.col_as_slice_mut(j);
        match x.col(j).try_as_col_major() {
            Some(col) => round_slice_to_f32(dst, col.as_slice(), sigma),
            None => dst.iter_mut().enumerate().for_each(|(i, v)| *v = (sigma * x[(i, j)]) as f32),
        }
    }
    out
}

#[inline(always)]
fn round_slice_to_f32_generic(dst: &mut [f32], src: &[f64], sigma: f64) {
    for (d, &s) in dst.iter_mut().zip(src) {
        *d = (sigma * s) as f32;
    }
}

at_vector_width! {
    /// `dst` = σ `src` rounded to f32, entry by entry.
    fn round_slice_to_f32(dst: &mut [f32], src: &[f64], sigma: f64) = round_slice_to_f32_generic
}

/// The squared norm Σ_c x_jc² of every row of X (m × d, length m), each summed over the
/// columns in order (the same bits as a row-by-row sum), accumulated column by column so that
/// the loads are contiguous and vectorize.
pub fn row_squared_norms(x: MatRef<f64>) -> Vec<f64> {
    let mut sq = vec![0.0; x.nrows()];
    for j in 0..x.ncols() {
        match x.col(j).try_as_col_major() {
            Some(col) => add_squares(&mut sq, col.as_slice()),
            None => sq.iter_mut().enumerate().for_each(|(i, v)| *v += x[(i, j)].powi(2)),
        }
    }
    sq
}

#[inline(always)]
fn add_squares_generic(acc: &mut [f64], x: &[f64]) {
    for (a, &v) in acc.iter_mut().zip(x) {
        *a += v.powi(2);
    }
}

at_vector_width! {
    /// `acc` += x², entry by entry.
    fn add_squares(acc: &mut [f64], x: &[f64]) = add_squares_generic
}

/// The largest |x_ij| of X, or `None` when an entry is not finite.
pub fn max_abs_finite(x: MatRef<f64>) -> Option<f64> {
    let mut max = 0.0f64;
    for j in 0..x.ncols() {
        let m = match x.col(j).try_as_col_major() {
            Some(col) => max_abs_slice(col.as_slice()),
            None => (0..x.nrows()).map(|i| x[(i, j)].abs()).fold(0.0, |m, v| if v > m || v.is_nan() { v } else { m }),
        };
        // NaN and ∞ both fail this test.
        if !m.is_finite() {
            return None;
        }
        max = max.max(m);
    }
    Some(max)
}

#[inline(always)]
fn max_abs_slice_generic(x: &[f64]) -> f64 {
    // Eight running maxima (compare-and-select); a NaN is carried as +∞ so that it is seen.
    let mut lanes = [0.0f64; 8];
    let chunks = x.chunks_exact(8);
    let mut tail = 0.0f64;
    for &v in chunks.remainder() {
        let a = if v.is_nan() { f64::INFINITY } else { v.abs() };
        tail = if a > tail { a } else { tail };
    }
    for c in chunks {
        for l in 0..8 {
            let a = if c[l].is_nan() { f64::INFINITY } else { c[l].abs() };
            lanes[l] = if a > lanes[l] { a } else { lanes[l] };
        }
    }
    lanes.iter().fold(tail, |m, &v| if v > m { v } else { m })
}

at_vector_width! {
    /// The largest |x_i| (+∞ when an entry is NaN or infinite).
    fn max_abs_slice(x: &[f64]) -> f64 = max_abs_slice_generic
}

/// The minimum-norm solution X = H⁺ B of a symmetric positive semi-definite system (H k × k,
/// B k × r) from the eigendecomposition of H: eigenvalues at or below k ε max|λ| count as zero.
/// The fallback of the Cholesky solves when H is singular. `what` names the caller in errors.
pub fn min_norm_solve(h: MatRef<f64>, b: MatRef<f64>, what: &str) -> crate::error::Result<Mat<f64>> {
    let k = h.nrows();
    let evd = h
        .self_adjoint_eigen(faer::Side::Lower)
        .map_err(|e| crate::error::Error::numerical(what, format!("eigendecomposition failed: {e:?}")))?;
    let (u, s) = (evd.U(), evd.S());
    let smax = (0..k).fold(0.0f64, |m, i| m.max(s[i].abs()));
    let cut = k as f64 * f64::EPSILON * smax;
    let utb = mul(u.transpose(), b);
    let y = Mat::from_fn(k, b.ncols(), |i, j| if s[i] > cut { utb[(i, j)] / s[i] } else { 0.0 });
    Ok(mul(u, y.as_ref()))
}

/// A B (a.nrows() × b.ncols()), sequential: callers parallelize at a coarser level.
pub fn mul(a: MatRef<f64>, b: MatRef<f64>) -> Mat<f64> {
    let mut out = Mat::<f64>::zeros(a.nrows(), b.ncols());
    matmul(out.as_mut(), Accum::Replace, a, b, 1.0, Par::Seq);
    out
}

/// Frobenius inner product ⟨X, Y⟩ = Σ_ij X_ij Y_ij of two matrices of the same size.
pub fn frob(x: MatRef<f64>, y: MatRef<f64>) -> f64 {
    debug_assert_eq!((x.nrows(), x.ncols()), (y.nrows(), y.ncols()));
    (0..x.ncols()).map(|j| (0..x.nrows()).map(|i| x[(i, j)] * y[(i, j)]).sum::<f64>()).sum()
}

/// x · y = Σ x_i y_i of two vectors of the same length (summed in order).
pub fn dot(x: &[f64], y: &[f64]) -> f64 {
    debug_assert_eq!(x.len(), y.len());
    // Eight running sums in a fixed order: one running sum is a chain of dependent adds (4
    // cycles each, not vectorized under strict f64 semantics) and made L-BFGS's two-loop
    // recursion over 175k-entry vectors a fifth of a completion iteration. Deterministic.
    let (xs, ys) = (x.chunks_exact(8), y.chunks_exact(8));
    let tail: f64 = xs.remainder().iter().zip(ys.remainder()).map(|(a, b)| a * b).sum();
    let mut acc = [0.0f64; 8];
    for (xc, yc) in xs.zip(ys) {
        for ((s, a), b) in acc.iter_mut().zip(xc).zip(yc) {
            *s += a * b;
        }
    }
    let pairs = [acc[0] + acc[4], acc[1] + acc[5], acc[2] + acc[6], acc[3] + acc[7]];
    (pairs[0] + pairs[2]) + (pairs[1] + pairs[3]) + tail
}

/// How a tall-skinny product splits its n rows into rayon tasks (module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RowChunks {
    /// Rows per task (the last task takes the remainder).
    pub rows: usize,
    /// Below this many rows the product is one sequential GEMM (task overhead dominates).
    pub parallel_from: usize,
}

impl RowChunks {
    /// The completion solvers' products (n × k' with k' ≲ 100): 2048 rows per task, in parallel
    /// from 4096 rows.
    pub const SOLVER: RowChunks = RowChunks { rows: 2048, parallel_from: 4096 };
    /// The block Lanczos products (the Krylov basis, n × p with p up to a few hundred): 4096 rows
    /// per task, in parallel from 16384 rows.
    pub const KRYLOV: RowChunks = RowChunks { rows: 4096, parallel_from: 16384 };
}

/// dst ← (dst if `accumulate`) + α A B for tall A (n × p), B (p × q), dst (n × q): the rows of
/// dst in tasks of `chunks.rows`, each a sequential GEMM (every entry computed by one task).
pub fn a_b_into(dst: MatMut<f64>, accumulate: bool, a: MatRef<f64>, b: MatRef<f64>, alpha: f64, chunks: RowChunks) {
    debug_assert_eq!((a.nrows(), a.ncols(), b.ncols()), (dst.nrows(), b.nrows(), dst.ncols()));
    let accum = if accumulate { Accum::Add } else { Accum::Replace };
    if dst.nrows() < chunks.parallel_from {
        matmul(dst, accum, a, b, alpha, Par::Seq);
        return;
    }
    dst.par_row_chunks_mut(chunks.rows).enumerate().for_each(|(i, chunk)| {
        let rows = chunk.nrows();
        matmul(chunk, accum, a.subrows(i * chunks.rows, rows), b, alpha, Par::Seq);
    });
}

/// V[:, ..q] ← V[:, ..p] Y in place, for V n × c (c ≥ p ≥ q) and Y p × q: the thick restart
/// of the eigensolver. Each row chunk of `chunks` (those of [`a_b_into`], whose results these
/// are bit for bit) goes through a chunk-sized scratch, instead of an n × q product and a copy
/// (0.9 GB at 840k vertices and q = 133).
pub fn a_b_in_place(v: MatMut<f64>, p: usize, y: MatRef<f64>, chunks: RowChunks) {
    debug_assert!(y.nrows() == p && y.ncols() <= p && p <= v.ncols());
    let q = y.ncols();
    let run = |rows: MatMut<f64>| {
        let mut tmp = Mat::<f64>::zeros(rows.nrows(), q);
        matmul(tmp.as_mut(), Accum::Replace, rows.rb().subcols(0, p), y, 1.0, Par::Seq);
        rows.subcols_mut(0, q).copy_from(&tmp);
    };
    if v.nrows() < chunks.parallel_from {
        run(v);
    } else {
        v.par_row_chunks_mut(chunks.rows).for_each(run);
    }
}

/// A B (n × q) for tall A (n × p) and B (p × q), with the completion solvers' chunking
/// ([`RowChunks::SOLVER`]).
pub fn a_b(a: MatRef<f64>, b: MatRef<f64>) -> Mat<f64> {
    let mut c = Mat::<f64>::zeros(a.nrows(), b.ncols());
    a_b_into(c.as_mut(), false, a, b, 1.0, RowChunks::SOLVER);
    c
}

/// Aᵀ B (p × q) for tall A (n × p) and B (n × q): partial products over row chunks of
/// [`RowChunks::SOLVER`], added in chunk order. The general form; the eigensolver's variant is
/// [`at_b_as_bt_a`].
pub fn at_b(a: MatRef<f64>, b: MatRef<f64>) -> Mat<f64> {
    debug_assert_eq!(a.nrows(), b.nrows());
    let chunks = RowChunks::SOLVER;
    let n = a.nrows();
    let mut sum = Mat::<f64>::zeros(a.ncols(), b.ncols());
    if n < chunks.parallel_from {
        matmul(sum.as_mut(), Accum::Replace, a.transpose(), b, 1.0, Par::Seq);
        return sum;
    }
    let starts: Vec<usize> = (0..n).step_by(chunks.rows).collect();
    let partials: Vec<Mat<f64>> = starts
        .par_iter()
        .map(|&r0| {
            let len = chunks.rows.min(n - r0);
            let mut c = Mat::<f64>::zeros(a.ncols(), b.ncols());
            matmul(c.as_mut(), Accum::Replace, a.subrows(r0, len).transpose(), b.subrows(r0, len), 1.0, Par::Seq);
            c
        })
        .collect();
    for c in &partials {
        sum += c;
    }
    sum
}

/// Aᵀ B (p × q) for tall A (n × p) and thin B (n × q, q ≤ p), computed as (Bᵀ A)ᵀ so that the
/// packed left operand of every GEMM is the thin Bᵀ, not the tall A; partial products over row
/// chunks of `chunks`, added in chunk order. The same product as [`at_b`], but not the same
/// bits: the block Lanczos eigensolver's form ([`RowChunks::KRYLOV`]), kept for its results.
pub fn at_b_as_bt_a(a: MatRef<f64>, b: MatRef<f64>, chunks: RowChunks) -> Mat<f64> {
    debug_assert_eq!(a.nrows(), b.nrows());
    let n = a.nrows();
    if n < chunks.parallel_from {
        let mut c = Mat::<f64>::zeros(b.ncols(), a.ncols());
        matmul(c.as_mut(), Accum::Replace, b.transpose(), a, 1.0, Par::Seq);
        return c.transpose().to_owned();
    }
    let starts: Vec<usize> = (0..n).step_by(chunks.rows).collect();
    let partials: Vec<Mat<f64>> = starts
        .par_iter()
        .map(|&r0| {
            let len = chunks.rows.min(n - r0);
            let mut c = Mat::<f64>::zeros(b.ncols(), a.ncols());
            matmul(c.as_mut(), Accum::Replace, b.subrows(r0, len).transpose(), a.subrows(r0, len), 1.0, Par::Seq);
            c
        })
        .collect();
    let mut sum = Mat::<f64>::zeros(b.ncols(), a.ncols());
    for c in &partials {
        sum += c;
    }
    sum.transpose().to_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The in-place restart product equals the out-of-place one bit for bit, above and below
    /// the parallel threshold, and leaves the columns after q alone.
    #[test]
    fn in_place_product_is_the_chunked_product() {
        let mut rng = crate::rng::Normal::new(3);
        for n in [1000, 20_000] {
            let (c, p, q) = (12, 10, 7);
            let v = Mat::<f64>::from_fn(n, c, |_, _| rng.sample());
            let y = Mat::<f64>::from_fn(p, q, |_, _| rng.sample());
            let mut expect = Mat::<f64>::zeros(n, q);
            a_b_into(expect.as_mut(), false, v.subcols(0, p), y.as_ref(), 1.0, RowChunks::KRYLOV);
            let mut got = v.clone();
            a_b_in_place(got.as_mut(), p, y.as_ref(), RowChunks::KRYLOV);
            assert_eq!(got.subcols(0, q), expect.as_ref(), "n = {n}");
            assert_eq!(got.subcols(q, c - q), v.subcols(q, c - q), "n = {n}");
        }
    }

    #[test]
    fn product_and_inner_product() {
        let a = Mat::from_fn(2, 3, |i, j| (i * 3 + j) as f64);
        let b = Mat::from_fn(3, 2, |i, j| (i + 2 * j) as f64 - 1.0);
        let c = mul(a.as_ref(), b.as_ref());
        for i in 0..2 {
            for j in 0..2 {
                let want: f64 = (0..3).map(|t| a[(i, t)] * b[(t, j)]).sum();
                assert_eq!(c[(i, j)], want);
            }
        }
        assert_eq!(frob(a.as_ref(), a.as_ref()), (0..6).map(|v| (v * v) as f64).sum::<f64>());
    }

    #[test]
    fn tall_products_agree_with_the_plain_product() {
        // Above both parallel thresholds, with a partial last chunk.
        let n = 16384 + 1000;
        let a = Mat::from_fn(n, 5, |i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0);
        let b = Mat::from_fn(n, 3, |i, j| ((i * 5 + j) % 13) as f64 * 0.5);
        let c = Mat::from_fn(5, 3, |i, j| (i + j) as f64 - 2.0);
        // Integer-valued entries: every order of summation is exact.
        let atb = mul(a.transpose(), b.as_ref());
        assert_eq!(at_b(a.as_ref(), b.as_ref()), atb);
        assert_eq!(at_b_as_bt_a(a.as_ref(), b.as_ref(), RowChunks::KRYLOV), atb);
        let ac = mul(a.as_ref(), c.as_ref());
        assert_eq!(a_b(a.as_ref(), c.as_ref()), ac);
        let mut dst = b.clone();
        a_b_into(dst.as_mut(), true, a.as_ref(), c.as_ref(), -2.0, RowChunks::KRYLOV);
        assert_eq!(dst, &b - &ac * faer::Scale(2.0));
        // Below the thresholds.
        let (a, b) = (a.subrows(0, 100), b.subrows(0, 100));
        assert_eq!(at_b(a, b), mul(a.transpose(), b));
        assert_eq!(at_b_as_bt_a(a, b, RowChunks::KRYLOV), mul(a.transpose(), b));
    }
}
