//! Ovsjanikov et al. 2012, paper eq. (5), with the optional Laplacian-commutativity regularizer
//! of Ovsjanikov et al. 2012 §6 (as in pyFM):
//!
//! C = argmin ‖C Â − B̂‖²_F / s + μ_c ‖C Λ̃_X − Λ̃_Y C‖²_F
//!
//! with Â = Φ_kᵀ A_X F, B̂ = Ψ_kᵀ A_Y G, s = (‖Â‖² + ‖B̂‖²)/2 and λ̃ = λ / λ_max (see [`super`]).
//!
//! - μ_c = 0: plain least squares. When k > q (or the data is rank deficient) Â Âᵀ is singular
//!   and the problem has many minimizers; we return the **minimum-norm** one, C = B̂ Â⁺, with the
//!   pseudo-inverse from the thin SVD of Â (singular values below max(k, q) · ε · σ_max dropped).
//! - μ_c > 0: the objective separates over the rows cᵢ of C; setting the gradient to zero gives
//!   (Â Âᵀ + μ_c s Dᵢ) cᵢ = Â b̂ᵢ, Dᵢ = diag((λ̃_X,j − λ̃_Y,i)²)_j, solved by Cholesky, row by
//!   row in parallel (a pseudo-inverse from the symmetric eigendecomposition if Cholesky fails,
//!   i.e. when the system is singular).

use faer::{Mat, Side};
use rayon::prelude::*;

use super::{min_norm_lstsq, mul, Problem};
use crate::descriptors::Descriptors;
use crate::error::{Error, Result};
use crate::spectral::Basis;

/// Options of [`ovsjanikov`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct OvsjanikovOptions {
    /// μ_c ≥ 0, weight of the Laplacian-commutativity term ‖C Λ̃_X − Λ̃_Y C‖² relative to the
    /// normalized data term (0: the paper's plain eq. (5)).
    pub commutativity: f64,
}

impl Default for OvsjanikovOptions {
    /// μ_c = 0 (the paper's eq. (5)).
    fn default() -> Self {
        OvsjanikovOptions { commutativity: 0.0 }
    }
}

/// The functional map C (k × k) of eq. (5) from bases `bx` (X, n vertices), `by` (Y, m
/// vertices) and corresponding data F (n × q) on X, G (m × q) on Y, using the first k basis
/// functions of each. Errors when F and G have different column counts, their rows are not n
/// and m, k = 0 or k exceeds a basis, an input is not finite, or μ_c is negative or not finite.
pub fn ovsjanikov(
    bx: &Basis,
    by: &Basis,
    f: &Descriptors,
    g: &Descriptors,
    k: usize,
    opts: &OvsjanikovOptions,
) -> Result<Mat<f64>> {
    let mu = opts.commutativity;
    if !(mu.is_finite() && mu >= 0.0) {
        return Err(Error::invalid("commutativity", format!("μ_c must be finite and ≥ 0, got {mu}")));
    }
    let p = Problem::new(bx, by, f, g, k)?;
    let c = if mu == 0.0 { min_norm_lstsq(p.a.as_ref(), p.b.as_ref())? } else { regularized(&p, mu)? };
    if !(0..k).all(|j| (0..k).all(|i| c[(i, j)].is_finite())) {
        return Err(Error::numerical("ovsjanikov", "the functional map is not finite"));
    }
    Ok(c)
}

/// The row-by-row solve of the commutativity-regularized problem.
fn regularized(p: &Problem, mu: f64) -> Result<Mat<f64>> {
    let k = p.k();
    let aat = mul(p.a.as_ref(), p.a.transpose());
    let ab = mul(p.a.as_ref(), p.b.transpose()); // column i: Â b̂ᵢ
    let weight = mu * p.scale;
    let rows: Vec<Result<Vec<f64>>> = (0..k)
        .into_par_iter()
        .map(|i| {
            let sys = Mat::from_fn(k, k, |r, c| {
                let d = if r == c { weight * (p.lx[r] - p.ly[i]).powi(2) } else { 0.0 };
                aat[(r, c)] + d
            });
            let rhs = Mat::from_fn(k, 1, |r, _| ab[(r, i)]);
            solve_spd(&sys, rhs)
        })
        .collect();
    let mut c = Mat::<f64>::zeros(k, k);
    for (i, row) in rows.into_iter().enumerate() {
        for (j, v) in row?.into_iter().enumerate() {
            c[(i, j)] = v;
        }
    }
    Ok(c)
}

/// x = S⁻¹ r for symmetric positive semi-definite S: Cholesky, or the minimum-norm
/// pseudo-inverse solution when S is (numerically) singular.
fn solve_spd(sys: &Mat<f64>, rhs: Mat<f64>) -> Result<Vec<f64>> {
    if let Ok(llt) = sys.llt(Side::Lower) {
        use faer::linalg::solvers::Solve;
        let x = llt.solve(&rhs);
        if x.col(0).iter().all(|v| v.is_finite()) {
            return Ok(x.col(0).iter().copied().collect());
        }
    }
    Ok(crate::linalg::min_norm_solve(sys.as_ref(), rhs.as_ref(), "ovsjanikov")?.col(0).iter().copied().collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmap::testdata::{diag_error, pair, recovered};

    /// Columns `cols` of the data of both shapes.
    fn subset(d: &Descriptors, cols: &[usize]) -> Descriptors {
        let v = Mat::from_fn(d.n(), cols.len(), |i, j| d.values[(i, cols[j])]);
        Descriptors::new(v, cols.iter().map(|&c| d.names[c].clone()).collect()).unwrap()
    }

    #[test]
    fn recovers_a_permuted_copy() {
        let p = pair();
        for mu in [0.0, 1e-3] {
            let c = ovsjanikov(&p.bx, &p.by, &p.f, &p.g, 30, &OvsjanikovOptions { commutativity: mu }).unwrap();
            let (err, rate) = (diag_error(p, &c), recovered(p, &c));
            eprintln!("ovsjanikov μ_c={mu}: max |C − C_true| = {err:.2e}, recovered {:.1}%", 100.0 * rate);
            assert!(err < 0.05, "μ_c={mu}: C off the ground truth by {err}");
            for i in 0..30 {
                assert!((c[(i, i)].abs() - 1.0).abs() < 0.05, "|C_{i}{i}| = {}", c[(i, i)].abs());
            }
            assert!(rate >= 0.95, "μ_c={mu}: only {rate} of the vertices recovered");
        }
    }

    #[test]
    fn commutativity_helps_with_scarce_data() {
        let p = pair();
        let cols = [3, 12, 21, 40, 50];
        let (f, mut g) = (subset(&p.f, &cols), subset(&p.g, &cols));
        // 2% noise (of each column's mean absolute value) on Y's data.
        let mut rng = crate::spectral::Normal::new(1);
        for j in 0..cols.len() {
            let level = 0.02 * g.values.col(j).iter().map(|v| v.abs()).sum::<f64>() / g.n() as f64;
            for i in 0..g.n() {
                g.values[(i, j)] += level * rng.sample();
            }
        }
        let k = 20;
        let truth = Mat::from_fn(k, k, |i, j| if i == j { p.signs[i] } else { 0.0 });
        let err = |c: &Mat<f64>| (c - &truth).norm_l2() / truth.norm_l2();
        let plain = ovsjanikov(&p.bx, &p.by, &f, &g, k, &OvsjanikovOptions::default()).unwrap();
        let reg = ovsjanikov(&p.bx, &p.by, &f, &g, k, &OvsjanikovOptions { commutativity: 1e-2 }).unwrap();
        let (e0, e1) = (err(&plain), err(&reg));
        let (r0, r1) = (recovered(p, &plain), recovered(p, &reg));
        eprintln!(
            "q=5 (2% noise), k=20: relative error plain {e0:.3}, commutativity {e1:.3}; recovered {r0:.3} vs {r1:.3}"
        );
        assert!(e0 > 0.5, "plain least squares unexpectedly good: {e0}");
        assert!(e1 < 0.25 * e0, "commutativity did not help enough: {e1} vs {e0}");
        assert!(r1 >= 0.95 && r0 < 0.7, "point-wise recovery {r1} (plain {r0})");
    }

    #[test]
    fn regularized_solution_is_stationary() {
        // The gradient 2(CÂ − B̂)Âᵀ/s + 2μ_c (C∘W) of the objective vanishes at the solution,
        // W_ij = (λ̃_X,j − λ̃_Y,i)².
        let p = pair();
        let cols: Vec<usize> = (0..60).step_by(4).collect();
        let (f, g) = (subset(&p.f, &cols), subset(&p.g, &cols));
        let k = 25;
        let mu = 0.3;
        let c = ovsjanikov(&p.bx, &p.by, &f, &g, k, &OvsjanikovOptions { commutativity: mu }).unwrap();
        let pr = Problem::new(&p.bx, &p.by, &f, &g, k).unwrap();
        let r = &mul(c.as_ref(), pr.a.as_ref()) - &pr.b;
        let data = mul(r.as_ref(), pr.a.transpose()) * (2.0 / pr.scale);
        let grad = Mat::from_fn(k, k, |i, j| data[(i, j)] + 2.0 * mu * (pr.lx[j] - pr.ly[i]).powi(2) * c[(i, j)]);
        let scale = data.norm_l2().max((mul(pr.b.as_ref(), pr.a.transpose()) * (2.0 / pr.scale)).norm_l2());
        assert!(grad.norm_l2() < 1e-8 * scale, "gradient {} (scale {scale})", grad.norm_l2());
    }

    #[test]
    fn minimum_norm_when_underdetermined() {
        // k > q: C Â = B̂ is solved exactly and C has no component outside the row space of Âᵀ.
        let p = pair();
        let cols = [0, 20, 45];
        let (f, g) = (subset(&p.f, &cols), subset(&p.g, &cols));
        let c = ovsjanikov(&p.bx, &p.by, &f, &g, 10, &OvsjanikovOptions::default()).unwrap();
        let pr = Problem::new(&p.bx, &p.by, &f, &g, 10).unwrap();
        let r = &mul(c.as_ref(), pr.a.as_ref()) - &pr.b;
        assert!(r.norm_l2() < 1e-10 * pr.b.norm_l2());
        // C = C U Uᵀ with U the left singular vectors of Â: no component outside span(Â).
        let svd = pr.a.thin_svd().unwrap();
        let uut = mul(svd.U(), svd.U().transpose());
        let off = &c - &mul(c.as_ref(), uut.as_ref());
        assert!(off.norm_l2() < 1e-10 * c.norm_l2(), "{}", off.norm_l2());
    }

    #[test]
    fn bad_input_is_an_error() {
        let p = pair();
        let o = OvsjanikovOptions::default();
        let g5 = subset(&p.g, &[0, 1, 2, 3, 4]);
        let e = ovsjanikov(&p.bx, &p.by, &p.f, &g5, 10, &o).unwrap_err().to_string();
        assert!(e.contains("columns"), "{e}");
        let e = ovsjanikov(&p.bx, &p.by, &p.f, &p.g, 31, &o).unwrap_err().to_string();
        assert!(e.contains("k"), "{e}");
        assert!(ovsjanikov(&p.bx, &p.by, &p.f, &p.g, 0, &o).is_err());
        let short = Descriptors::new(p.g.values.subrows(0, 10).to_owned(), p.g.names.clone()).unwrap();
        assert!(ovsjanikov(&p.bx, &p.by, &p.f, &short, 10, &o).is_err());
        let mut nan = p.f.clone();
        nan.values[(3, 2)] = f64::NAN;
        assert!(ovsjanikov(&p.bx, &p.by, &nan, &p.g, 10, &o).is_err());
        assert!(ovsjanikov(&p.bx, &p.by, &p.f, &p.g, 10, &OvsjanikovOptions { commutativity: -1.0 }).is_err());
    }
}
