//! Sparse Cholesky factorizations of symmetric positive definite matrices that share one
//! sparsity pattern — for a Laplacian, W + c A (c ≥ 0) and A + t W (A is diagonal and W stores
//! its diagonal): the fill-reducing ordering and symbolic analysis are computed once per
//! Laplacian ([`crate::laplacian::Laplacian::symbolic_cholesky`], cached on it) and reused by
//! every numeric factorization —
//! the eigensolver's shift-invert operator ([`crate::spectral`]) and the roughness probe and
//! smoothing steps of [`crate::denoise`]. At 840k vertices the ordering alone takes ≈ 2.3 s.
//!
//! Always *supernodal*: faer's automatic choice picks the simplicial variant for mesh
//! Laplacians, whose triangular solves run one column at a time; the supernodal solves work on
//! dense blocks with all right-hand sides at once (what block Lanczos needs), and its numeric
//! factorization runs on both cores.

use std::sync::Arc;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::SparseColMatRef;
use faer::{Conj, MatMut, Par, Side};

use crate::error::{Error, Result};

/// The AMD ordering and supernodal symbolic factorization of a symmetric pattern (the lower
/// triangle of `pattern`, n × n, diagonal stored). Errors: faer's (a pattern too large to index).
pub(crate) fn symbolic_of(pattern: SparseColMatRef<usize, f64>) -> Result<Arc<SymbolicCholesky<usize>>> {
    let params = CholeskySymbolicParams {
        supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
        ..Default::default()
    };
    factorize_symbolic_cholesky(pattern.symbolic(), Side::Lower, SymmetricOrdering::Amd, params)
        .map(Arc::new)
        .map_err(|e| Error::numerical("cholesky", format!("symbolic factorization failed: {e:?}")))
}

/// A numeric factorization L Lᵀ = P M Pᵀ of a symmetric positive definite M with the pattern
/// of a Laplacian's W.
pub(crate) struct SparseLlt {
    symbolic: Arc<SymbolicCholesky<usize>>,
    values: Vec<f64>,
}

impl SparseLlt {
    /// Factors `mat` (n × n, the pattern `symbolic` was computed from). The error string is
    /// faer's (a non-positive pivot: M is not positive definite).
    pub(crate) fn new(
        mat: SparseColMatRef<usize, f64>,
        symbolic: Arc<SymbolicCholesky<usize>>,
    ) -> std::result::Result<Self, String> {
        let par = Par::rayon(0);
        let mut values = vec![0.0; symbolic.len_val()];
        let mut buf = MemBuffer::new(symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()));
        symbolic
            .factorize_numeric_llt(
                &mut values,
                mat,
                Side::Lower,
                Default::default(),
                par,
                MemStack::new(&mut buf),
                Default::default(),
            )
            .map_err(|e| format!("{e:?}"))?;
        Ok(SparseLlt { symbolic, values })
    }

    /// x ← M⁻¹ x for an n × b block, sequentially: splitting the columns over two tasks was
    /// 10–20 % faster in isolation but not in the eigensolver (840k vertices, k = 100: solves
    /// 39.0 → 37.8 s, within run-to-run noise), and faer's parallel solve spins at barriers.
    pub(crate) fn solve_in_place(&self, x: MatMut<f64>) {
        self.solve_sequential(x);
    }

    fn solve_sequential(&self, x: MatMut<f64>) {
        let mut buf = MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(x.ncols(), Par::Seq));
        LltRef::new(&self.symbolic, &self.values).solve_in_place_with_conj(
            Conj::No,
            x,
            Par::Seq,
            MemStack::new(&mut buf),
        );
    }
}
