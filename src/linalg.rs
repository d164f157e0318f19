//! Small dense linear-algebra helpers shared by the solvers (one copy each): the product of two
//! matrices and the Frobenius inner product. Heavier kernels (blocked GEMMs of the completion
//! method and of the eigensolver) stay beside the code whose memory layout they are tuned for.

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};

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

#[cfg(test)]
mod tests {
    use super::*;

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
}
