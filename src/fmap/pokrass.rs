//! Pokrass et al. 2013 ("Sparse modeling of intrinsic correspondences"), paper eq. (6): the
//! order of the data columns is unknown,
//!
//! min over Π, C of ‖C Â Π − B̂‖²_F / s + μ ‖M ∘ C‖₁
//!
//! with Â = Φ_kᵀ A_X F, B̂ = Ψ_kᵀ A_Y G, s = (‖Â‖² + ‖B̂‖²)/2 (see [`super`]) and M the
//! off-diagonal weights of Pokrass et al.: M_ij = 0 for i = j, 1 otherwise (the diagonal is free,
//! everything else is pushed to zero: near-isometries have nearly diagonal C).
//!
//! The permutation is returned as `perm` with `perm[j]` = the column of F that corresponds to
//! column j of G, i.e. column j of Â Π is column `perm[j]` of Â.
//!
//! Alternation:
//! 0. Initial Π: optimal assignment between the columns of |Â| and |B̂| (entry-wise absolute
//!    values, cost = squared distance). This is exact when C is diagonal ±1 — the sign of each
//!    eigenfunction is arbitrary, so comparing Â with B̂ directly would not be — and a good guess
//!    for near-isometries. The first C is the diagonal least-squares fit (row i: the scalar
//!    cᵢᵢ minimizing ‖cᵢᵢ (ÂΠ)ᵢ − b̂ᵢ‖²): bounded, and what the prior M favours.
//! 1. C by FISTA (Beck & Teboulle 2009) on the weighted-L1 problem, warm-started from the
//!    previous C, step 1/L with L = 2 σ_max(Â Π (Â Π)ᵀ) / s = 2 σ_max(Â)² / s (the Lipschitz
//!    constant of the data term's gradient, independent of Π); prox = soft thresholding by
//!    μ M_ij / L. Stops when ‖C_{t+1} − C_t‖_F ≤ tol · ‖C_t‖_F or after `fista_iterations`.
//! 2. Π by optimal linear assignment (Kuhn–Munkres, costs scaled to integers) between the columns
//!    of C Â and those of B̂, cost = squared Euclidean distance.
//!
//! The alternation stops when Π no longer changes or after `outer_iterations`.

use faer::Mat;
use pathfinding::kuhn_munkres::kuhn_munkres_min;
use pathfinding::matrix::Matrix;

use super::{mul, Problem};
use crate::descriptors::Descriptors;
use crate::error::{Error, Result};
use crate::spectral::Basis;

/// Options of [`pokrass`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PokrassOptions {
    /// μ ≥ 0: weight of ‖M ∘ C‖₁ relative to the normalized data term.
    pub mu: f64,
    /// Maximum number of (assignment, sparse coding) alternations (≥ 1).
    pub outer_iterations: usize,
    /// Maximum number of FISTA iterations per sparse-coding step (≥ 1).
    pub fista_iterations: usize,
    /// FISTA stops when the relative change of C is below this.
    pub tol: f64,
}

impl Default for PokrassOptions {
    /// μ = 1e-3, 10 alternations, 2000 FISTA iterations, tol 1e-9.
    fn default() -> Self {
        PokrassOptions { mu: 1e-3, outer_iterations: 10, fista_iterations: 2000, tol: 1e-9 }
    }
}

/// The functional map C (k × k) and the column permutation of eq. (6) (see the module
/// documentation for the meaning of `perm`). Errors as [`super::ovsjanikov()`], and on invalid
/// options.
pub fn pokrass(
    bx: &Basis,
    by: &Basis,
    f: &Descriptors,
    g: &Descriptors,
    k: usize,
    opts: &PokrassOptions,
) -> Result<(Mat<f64>, Vec<usize>)> {
    if !(opts.mu.is_finite() && opts.mu >= 0.0) {
        return Err(Error::invalid("mu", format!("μ must be finite and ≥ 0, got {}", opts.mu)));
    }
    if opts.outer_iterations == 0 || opts.fista_iterations == 0 {
        return Err(Error::invalid("iterations", "need at least one outer and one FISTA iteration"));
    }
    if !(opts.tol.is_finite() && opts.tol >= 0.0) {
        return Err(Error::invalid("tol", format!("must be finite and ≥ 0, got {}", opts.tol)));
    }
    let p = Problem::new(bx, by, f, g, k)?;
    let abs = |m: &Mat<f64>| Mat::from_fn(m.nrows(), m.ncols(), |i, j| m[(i, j)].abs());
    let perm = assign(&abs(&p.a), &abs(&p.b));
    let (c, perm) = alternate(&p, perm, opts);
    if !(0..k).all(|j| (0..k).all(|i| c[(i, j)].is_finite())) {
        return Err(Error::numerical("pokrass", "the functional map is not finite"));
    }
    Ok((c, perm))
}

/// Steps 1–2 of the alternation from the permutation `perm`.
fn alternate(p: &Problem, mut perm: Vec<usize>, opts: &PokrassOptions) -> (Mat<f64>, Vec<usize>) {
    // Diagonal least squares: the minimizer among the matrices the prior M favours (a full
    // least-squares start is unbounded when Â is ill-conditioned and Π wrong). A small ridge,
    // 1e-3 of the mean row energy of ÂΠ, keeps rows the data barely excite (k > q) near 0
    // instead of a ratio of two tiny numbers, which the data term would never correct.
    let ap = permuted(&p.a, &perm);
    let k = p.k();
    let energy: Vec<f64> = (0..k).map(|i| ap.row(i).iter().map(|v| v * v).sum()).collect();
    let ridge = 1e-3 * energy.iter().sum::<f64>() / k.max(1) as f64;
    let mut c = Mat::from_fn(k, k, |i, j| {
        let den = energy[i] + ridge;
        if i != j || den == 0.0 {
            return 0.0;
        }
        ap.row(i).iter().zip(p.b.row(i).iter()).map(|(x, y)| x * y).sum::<f64>() / den
    });
    for _ in 0..opts.outer_iterations {
        c = fista(p, &perm, c, opts);
        let next = assign(&mul(c.as_ref(), p.a.as_ref()), &p.b);
        if next == perm {
            break;
        }
        perm = next;
    }
    (c, perm)
}

/// Â Π: column j is column `perm[j]` of Â.
fn permuted(a: &Mat<f64>, perm: &[usize]) -> Mat<f64> {
    Mat::from_fn(a.nrows(), perm.len(), |i, j| a[(i, perm[j])])
}

/// `perm[j]` = the column of `x` assigned to column j of `y`, minimizing Σ_j ‖x_(perm j) − y_j‖².
fn assign(x: &Mat<f64>, y: &Mat<f64>) -> Vec<usize> {
    let q = x.ncols();
    let cost = Mat::from_fn(q, q, |j, i| (0..x.nrows()).map(|r| (y[(r, j)] - x[(r, i)]).powi(2)).sum::<f64>());
    let max = (0..q).flat_map(|j| (0..q).map(move |i| (j, i))).fold(0.0f64, |m, (j, i)| m.max(cost[(j, i)]));
    let unit = if max > 0.0 { 1e9 / max } else { 0.0 };
    let weights = Matrix::from_fn(q, q, |(j, i)| (cost[(j, i)] * unit).round() as i64);
    kuhn_munkres_min(&weights).1
}

/// Off-diagonal weight of Pokrass et al.
fn weight(i: usize, j: usize) -> f64 {
    if i == j {
        0.0
    } else {
        1.0
    }
}

/// FISTA on ‖C Â Π − B̂‖² / s + μ ‖M ∘ C‖₁ from `c0`.
fn fista(p: &Problem, perm: &[usize], c0: Mat<f64>, opts: &PokrassOptions) -> Mat<f64> {
    let k = p.k();
    let ap = permuted(&p.a, perm);
    let aat = mul(ap.as_ref(), ap.transpose());
    let bat = mul(p.b.as_ref(), ap.transpose());
    let smax = p.a.singular_values().ok().and_then(|s| s.first().copied()).unwrap_or(0.0);
    let lip = 2.0 * smax * smax / p.scale;
    if lip <= 0.0 {
        return c0;
    }
    let mut c = c0;
    let mut y = c.clone();
    let mut t = 1.0f64;
    for _ in 0..opts.fista_iterations {
        // ∇ = 2 (Y Â Π Πᵀ Âᵀ − B̂ Πᵀ Âᵀ) / s
        let yaat = mul(y.as_ref(), aat.as_ref());
        let next = Mat::from_fn(k, k, |i, j| {
            let grad = 2.0 * (yaat[(i, j)] - bat[(i, j)]) / p.scale;
            let v = y[(i, j)] - grad / lip;
            let thr = opts.mu * weight(i, j) / lip;
            v.signum() * (v.abs() - thr).max(0.0)
        });
        let tn = 0.5 * (1.0 + (1.0 + 4.0 * t * t).sqrt());
        let beta = (t - 1.0) / tn;
        let diff = &next - &c;
        let change = diff.norm_l2();
        y = &next + &diff * beta;
        let done = change <= opts.tol * c.norm_l2();
        c = next;
        t = tn;
        if done {
            break;
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmap::testdata::{diag_error, pair, recovered};
    use crate::spectral::Normal;

    #[test]
    fn recovers_shuffled_columns_and_the_map() {
        let p = pair();
        let q = p.g.q();
        let shuffle: Vec<usize> = (0..q).map(|j| (j * 37 + 11) % q).collect(); // G column j ← column shuffle[j]
        let vals = Mat::from_fn(p.g.n(), q, |i, j| p.g.values[(i, shuffle[j])]);
        let g = Descriptors::new(vals, shuffle.iter().map(|&j| p.g.names[j].clone()).collect()).unwrap();
        let (c, perm) = pokrass(&p.bx, &p.by, &p.f, &g, 30, &PokrassOptions::default()).unwrap();
        let wrong = (0..q).filter(|&j| perm[j] != shuffle[j]).count();
        let (err, rate) = (diag_error(p, &c), recovered(p, &c));
        eprintln!("pokrass: {wrong} of {q} columns misassigned, max |C − C_true| = {err:.2e}, recovered {rate:.3}");
        assert_eq!(wrong, 0);
        assert!(err < 0.05, "C off the ground truth by {err}");
        assert!(rate >= 0.95, "only {rate} of the vertices recovered");
    }

    #[test]
    fn alternation_repairs_a_wrong_initial_ordering() {
        // Start from the true ordering with 8 disjoint pairs of columns swapped (16 of 60 wrong).
        let p = pair();
        let pr = Problem::new(&p.bx, &p.by, &p.f, &p.g, 30).unwrap();
        let q = pr.a.ncols();
        let mut start: Vec<usize> = (0..q).collect();
        for s in 0..8 {
            start.swap(7 * s, 7 * s + 3);
        }
        let opts = PokrassOptions { mu: 1e-2, ..PokrassOptions::default() };
        let (c, perm) = alternate(&pr, start, &opts);
        let wrong = (0..q).filter(|&j| perm[j] != j).count();
        let (err, rate) = (diag_error(p, &c), recovered(p, &c));
        eprintln!(
            "pokrass from 16 wrong columns: {wrong} wrong after, max |C − C_true| = {err:.2e}, recovered {rate:.3}"
        );
        assert_eq!(wrong, 0);
        assert!(err < 0.05, "C off the ground truth by {err}");
        assert!(rate >= 0.95, "only {rate} of the vertices recovered");
    }

    #[test]
    fn sparse_coding_meets_the_optimality_conditions() {
        // Random problem: at the FISTA solution, ∇f_ij = −μ M_ij sign(C_ij) where C_ij ≠ 0 and
        // |∇f_ij| ≤ μ M_ij where C_ij = 0.
        let mut rng = Normal::new(11);
        let (k, q) = (6, 15);
        let a = Mat::from_fn(k, q, |_, _| rng.sample());
        let b = Mat::from_fn(k, q, |_, _| rng.sample());
        let scale = 0.5 * (a.squared_norm_l2() + b.squared_norm_l2());
        let p = Problem { a, b, lx: vec![0.0; k], ly: vec![0.0; k], scale };
        let perm: Vec<usize> = (0..q).collect();
        let opts = PokrassOptions { mu: 0.05, outer_iterations: 1, fista_iterations: 20000, tol: 1e-14 };
        let c = fista(&p, &perm, Mat::zeros(k, k), &opts);
        let r = &mul(c.as_ref(), p.a.as_ref()) - &p.b;
        let grad = mul(r.as_ref(), p.a.transpose()) * (2.0 / scale);
        let mut zeros = 0;
        for i in 0..k {
            for j in 0..k {
                let bound = opts.mu * weight(i, j);
                if c[(i, j)] == 0.0 {
                    zeros += 1;
                    assert!(grad[(i, j)].abs() <= bound + 1e-8, "({i},{j}): |∇| = {} > {bound}", grad[(i, j)]);
                } else {
                    let want = -bound * c[(i, j)].signum();
                    assert!((grad[(i, j)] - want).abs() < 1e-8, "({i},{j}): ∇ = {} vs {want}", grad[(i, j)]);
                }
            }
        }
        assert!(zeros > 0, "μ too small for this test: no zero entry");
    }

    #[test]
    fn bad_input_is_an_error() {
        let p = pair();
        let o = PokrassOptions::default();
        let few = Descriptors::new(p.g.values.subcols(0, 7).to_owned(), p.g.names[..7].to_vec()).unwrap();
        let e = pokrass(&p.bx, &p.by, &p.f, &few, 10, &o).unwrap_err().to_string();
        assert!(e.contains("columns"), "{e}");
        assert!(pokrass(&p.bx, &p.by, &p.f, &p.g, 40, &o).is_err());
        assert!(pokrass(&p.bx, &p.by, &p.f, &p.g, 10, &PokrassOptions { mu: -1.0, ..o }).is_err());
        assert!(pokrass(&p.bx, &p.by, &p.f, &p.g, 10, &PokrassOptions { outer_iterations: 0, ..o }).is_err());
    }
}
