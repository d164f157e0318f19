//! From functional maps to point-to-point maps (paper §2, last paragraphs).
//!
//! A functional map C (k × k) sends the coefficients of a function on X (in Φ, n × k) to
//! coefficients on Y (in Ψ, m × k). Thinking of the rows of Φ Cᵀ and of Ψ as points in R^k, the
//! point-wise map X → Y sends vertex i of X to the vertex of Y whose row of Ψ is nearest to row i
//! of Φ Cᵀ (Ovsjanikov et al. 2012). A point-to-point map `map_xy` is a vector of length n whose
//! entry i is the vertex of Y matched to vertex i of X.

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use rayon::prelude::*;

use crate::error::{Error, Result};

/// Query rows per task of the nearest-neighbour search.
const QUERY_BLOCK: usize = 256;

/// Exact Euclidean nearest neighbours: for every row of `query` (n × d) the index of the nearest
/// row of `reference` (m × d); ties go to the smallest index.
///
/// Blocked brute force: for a block of query rows, ‖q − r‖² = ‖q‖² − 2 q·r + ‖r‖² with the q·r
/// products from one GEMM (block × m), blocks in parallel. O(n·m·d) flops and O(block·m) memory,
/// exact in any dimension (the embeddings here have d = k up to hundreds, where k-d trees
/// degenerate to scanning anyway).
pub fn nearest_neighbors(reference: MatRef<f64>, query: MatRef<f64>) -> Result<Vec<usize>> {
    let (m, d) = (reference.nrows(), reference.ncols());
    if query.ncols() != d {
        return Err(Error::invalid(
            "embedding",
            format!("query has dimension {} but reference has {d}", query.ncols()),
        ));
    }
    if m == 0 {
        return Err(Error::invalid("embedding", "the reference set is empty"));
    }
    let finite = |x: MatRef<f64>| (0..x.ncols()).all(|j| (0..x.nrows()).all(|i| x[(i, j)].is_finite()));
    if !finite(reference) || !finite(query) {
        return Err(Error::invalid("embedding", "it contains a non-finite value"));
    }
    let ref_norm: Vec<f64> = (0..m).map(|j| (0..d).map(|c| reference[(j, c)].powi(2)).sum()).collect();
    let n = query.nrows();
    let starts: Vec<usize> = (0..n).step_by(QUERY_BLOCK).collect();
    let blocks: Vec<Vec<usize>> = starts
        .par_iter()
        .map(|&r0| {
            let len = QUERY_BLOCK.min(n - r0);
            let q = query.subrows(r0, len);
            let mut dots = Mat::<f64>::zeros(len, m);
            matmul(dots.as_mut(), Accum::Replace, q, reference.transpose(), 1.0, Par::Seq);
            (0..len)
                .map(|i| {
                    let mut best = (f64::INFINITY, 0usize);
                    for j in 0..m {
                        // ‖q‖² is the same for every j and left out.
                        let dist = ref_norm[j] - 2.0 * dots[(i, j)];
                        if dist < best.0 {
                            best = (dist, j);
                        }
                    }
                    best.1
                })
                .collect()
        })
        .collect();
    Ok(blocks.into_iter().flatten().collect())
}

/// Point-to-point map X → Y of a functional map C (k × k, coefficients on X → coefficients on
/// Y) between the bases Φ (n × k') and Ψ (m × k'), k ≤ k': nearest neighbours of the rows of
/// Φ_k Cᵀ among the rows of Ψ_k. Returns `map_xy` (length n, vertices of Y).
pub fn map_from_fmap(phi: MatRef<f64>, psi: MatRef<f64>, c: MatRef<f64>) -> Result<Vec<usize>> {
    let k = c.nrows();
    if c.ncols() != k || k == 0 || k > phi.ncols() || k > psi.ncols() {
        return Err(Error::invalid(
            "C",
            format!(
                "a {}×{} map does not fit bases with {} and {} columns",
                c.nrows(),
                c.ncols(),
                phi.ncols(),
                psi.ncols()
            ),
        ));
    }
    let mut emb = Mat::<f64>::zeros(phi.nrows(), k);
    matmul(emb.as_mut(), Accum::Replace, phi.subcols(0, k), c.transpose(), 1.0, Par::Seq);
    nearest_neighbors(psi.subcols(0, k), emb.as_ref())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spectral::Normal;

    #[test]
    fn nearest_neighbors_match_brute_force() {
        let mut rng = Normal::new(7);
        let (m, n, d) = (700, 600, 13);
        let r = Mat::from_fn(m, d, |_, _| rng.sample());
        let q = Mat::from_fn(n, d, |_, _| rng.sample());
        let got = nearest_neighbors(r.as_ref(), q.as_ref()).unwrap();
        for i in 0..n {
            let dist = |j: usize| (0..d).map(|c| (q[(i, c)] - r[(j, c)]).powi(2)).sum::<f64>();
            let want = (0..m).min_by(|&a, &b| dist(a).total_cmp(&dist(b))).unwrap();
            assert_eq!(got[i], want, "query {i}");
        }
        // A point of the reference set finds itself.
        let self_map = nearest_neighbors(r.as_ref(), r.as_ref()).unwrap();
        assert!(self_map.iter().enumerate().all(|(i, &j)| i == j));
    }

    #[test]
    fn identity_map_of_a_permuted_embedding() {
        let mut rng = Normal::new(3);
        let (n, k) = (500, 10);
        let phi = Mat::from_fn(n, k, |_, _| rng.sample());
        let perm: Vec<usize> = (0..n).map(|i| (i * 211 + 5) % n).collect(); // row i of Ψ is row perm[i] of Φ
        let psi = Mat::from_fn(n, k, |i, j| phi[(perm[i], j)]);
        let c = Mat::<f64>::identity(k, k);
        let map = map_from_fmap(phi.as_ref(), psi.as_ref(), c.as_ref()).unwrap();
        for (i, &p) in perm.iter().enumerate() {
            assert_eq!(map[p], i);
        }
    }

    #[test]
    fn bad_inputs_are_errors() {
        let a = Mat::<f64>::zeros(5, 3);
        let b = Mat::<f64>::zeros(5, 4);
        assert!(nearest_neighbors(a.as_ref(), b.as_ref()).is_err());
        assert!(nearest_neighbors(Mat::<f64>::zeros(0, 3).as_ref(), a.as_ref()).is_err());
        let nan = Mat::from_fn(5, 3, |_, _| f64::NAN);
        assert!(nearest_neighbors(a.as_ref(), nan.as_ref()).is_err());
        assert!(map_from_fmap(a.as_ref(), a.as_ref(), Mat::<f64>::identity(4, 4).as_ref()).is_err());
    }
}
