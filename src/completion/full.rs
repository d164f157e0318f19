//! The vertex-space forms of the method: fixed rank (8), low rank (9) and low norm (10), on the
//! m × n correspondence T itself (not on basis coefficients).
//!
//! T is the matrix of the correspondence *kernel*: a function f on X (n values) maps to
//! g = T A_X f on Y, so that T = Ψ C Φᵀ for a functional map C between mass-orthonormal bases.
//! With this mass placement every term below equals the corresponding term of the subspace
//! form (11) when U = Ψ_k' A and V = Φ_k' B (the data term up to the constant
//! ‖G − Ψ B̂‖²_{A_Y}, the part of G outside the basis); tested in `subspace_is_a_special_case`.
//!
//! ```text
//! data           ‖T A_X F − G‖²_{A_Y}            Z = 2 A_Y R (A_X F)ᵀ,  R = T A_X F − G
//! Dirichlet, X   tr(T W_X Tᵀ A_Y) / ν_X           Z = 2 A_Y T W_X / ν_X      (rows of T smooth on X)
//! Dirichlet, Y   tr(Tᵀ W_Y T A_X) / ν_Y           Z = 2 W_Y T A_X / ν_Y      (columns smooth on Y)
//! L1             Σ w_ji √(t_ji² + ξ)              see [`super::l1`]
//! low norm (10)  ½ (‖U‖² + ‖V‖²) for T = U Vᵀ    (Euclidean, or with the masses)
//! nuclear (9)    ‖D_Y T D_X‖_*                    (D = I, or A^{1/2}: the low norm's minimum)
//! ```
//!
//! W_X, W_Y are the stiffness matrices (Φᵀ W_X Φ = Λ_X). Normalization as in the subspace form
//! ([`Scaling`]): with [`Scaling::Unit`] both shapes are rescaled to unit area (masses / area,
//! T in density units), the data term is divided by s = (‖F‖²_{A_X} + ‖G‖²_{A_Y}) / 2, ν = the sum
//! of the first K unit-area eigenvalues (K = the k' of the matching subspace problem), the L1
//! weights are the unit-area masses, and the low norm uses the masses and is divided by k. With
//! [`Scaling::Paper`], ν = 1, no weights, and the data term is not rescaled.

use crate::linalg::frob;
use faer::linalg::matmul::matmul;
use faer::sparse::linalg::matmul::sparse_dense_matmul;
use faer::sparse::SparseColMat;
use faer::{Accum, Mat, MatRef, Par};

use super::l1::{soft_l1, Products, Weights};
use super::objective::{CompletionParams, LowNorm, Terms};
use super::{gemm_nn, gemm_tn, mul, Scaling};
use crate::descriptors::Descriptors;
use crate::error::{Error, Result};
use crate::laplacian::Laplacian;
use crate::spectral::Basis;

/// Products Z·P_R (m × p) and Zᵀ·P_L (n × p') of a gradient Z (m × n) with probe matrices.
pub type GradientProducts = (Mat<f64>, Mat<f64>);

/// The fixed data of the vertex-space forms (8)–(10), normalized by a [`Scaling`].
#[derive(Clone, Debug)]
pub struct FullProblem {
    /// The normalization.
    pub scaling: Scaling,
    /// W_X (n × n), symmetric positive semi-definite stiffness.
    pub w_x: SparseColMat<usize, f64>,
    /// W_Y (m × m).
    pub w_y: SparseColMat<usize, f64>,
    /// A_X (n): vertex weights (unit-area for [`Scaling::Unit`]).
    pub mass_x: Vec<f64>,
    /// A_Y (m).
    pub mass_y: Vec<f64>,
    /// P = A_X F (n × q), divided by √s for [`Scaling::Unit`].
    pub p: Mat<f64>,
    /// G (m × q), divided by √s for [`Scaling::Unit`].
    pub g: Mat<f64>,
    /// ν_X: the Dirichlet energy on X is divided by it.
    pub nu_x: f64,
    /// ν_Y.
    pub nu_y: f64,
    /// Factor from a C of this problem's units to the input bases (as [`super::Problem::c_scale`]).
    pub c_scale: f64,
    /// √area(X) for [`Scaling::Unit`] (1 otherwise): unit-area basis = `basis_scale_x` · Φ.
    pub basis_scale_x: f64,
    /// √area(Y) for [`Scaling::Unit`] (1 otherwise).
    pub basis_scale_y: f64,
}

/// W x for a sparse symmetric W and dense x.
pub(crate) fn sparse_mul(w: &SparseColMat<usize, f64>, x: MatRef<f64>) -> Mat<f64> {
    let mut out = Mat::<f64>::zeros(w.nrows(), x.ncols());
    sparse_dense_matmul(out.as_mut(), Accum::Replace, w.as_ref(), x, 1.0, Par::Seq);
    out
}

/// diag(d) x.
pub(crate) fn scale_rows(d: &[f64], x: MatRef<f64>) -> Mat<f64> {
    Mat::from_fn(x.nrows(), x.ncols(), |i, j| d[i] * x[(i, j)])
}

impl FullProblem {
    /// The vertex-space problem for shapes with Laplacians `lx` (n vertices), `ly` (m) and data
    /// F (n × q), G (m × q). `bx`, `by` (bases of the same shapes) give the Dirichlet
    /// normalization ν over their first `k_norm` eigenvalues ([`Scaling::Unit`] only).
    ///
    /// Errors: sizes that do not match, non-finite data, `k_norm` = 0 or beyond a basis.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        lx: &Laplacian,
        ly: &Laplacian,
        bx: &Basis,
        by: &Basis,
        f: &Descriptors,
        g: &Descriptors,
        k_norm: usize,
        scaling: Scaling,
    ) -> Result<FullProblem> {
        let (n, m) = (lx.n(), ly.n());
        if f.q() != g.q() {
            return Err(Error::invalid(
                "data",
                format!("F has {} columns but G has {}; the data must correspond column by column", f.q(), g.q()),
            ));
        }
        if f.n() != n || g.n() != m || bx.n() != n || by.n() != m {
            return Err(Error::invalid(
                "data",
                format!(
                    "F has {} rows, G {}, the bases {} and {}, for {n} vertices of X and {m} of Y",
                    f.n(),
                    g.n(),
                    bx.n(),
                    by.n()
                ),
            ));
        }
        if k_norm == 0 || k_norm > bx.k() || k_norm > by.k() {
            return Err(Error::invalid("k'", format!("k' = {k_norm} but the bases hold {} and {}", bx.k(), by.k())));
        }
        let finite = |d: &Descriptors| (0..d.q()).all(|j| (0..d.n()).all(|i| d.values[(i, j)].is_finite()));
        if !finite(f) || !finite(g) {
            return Err(Error::invalid("data", "F or G contains a non-finite value"));
        }
        let (area_x, area_y): (f64, f64) = (lx.mass.iter().sum(), ly.mass.iter().sum());
        if !(area_x > 0.0 && area_y > 0.0 && area_x.is_finite() && area_y.is_finite()) {
            return Err(Error::invalid("Laplacian", "the vertex weights must have a positive, finite sum"));
        }
        let (mass_x, mass_y, nu_x, nu_y, c_scale, sx, sy) = match scaling {
            Scaling::Paper => (lx.mass.clone(), ly.mass.clone(), 1.0, 1.0, 1.0, 1.0, 1.0),
            Scaling::Unit => {
                let nu = |b: &Basis, area: f64| area * b.eigenvalues[..k_norm].iter().sum::<f64>();
                let (nx, ny) = (nu(bx, area_x), nu(by, area_y));
                if !(nx > 0.0 && ny > 0.0) {
                    return Err(Error::invalid("bases", "the eigenvalues must not all be zero"));
                }
                (
                    lx.mass.iter().map(|a| a / area_x).collect(),
                    ly.mass.iter().map(|a| a / area_y).collect(),
                    nx,
                    ny,
                    (area_y / area_x).sqrt(),
                    area_x.sqrt(),
                    area_y.sqrt(),
                )
            }
        };
        let mut p = scale_rows(&mass_x, f.values.as_ref());
        let mut gm = g.values.clone();
        if scaling == Scaling::Unit {
            let energy = |d: &Mat<f64>, mass: &[f64]| {
                (0..d.ncols()).map(|j| (0..d.nrows()).map(|i| mass[i] * d[(i, j)].powi(2)).sum::<f64>()).sum::<f64>()
            };
            let s = 0.5 * (energy(&f.values, &mass_x) + energy(&gm, &mass_y));
            if !(s > 0.0 && s.is_finite()) {
                return Err(Error::invalid("data", "F and G are zero; there is nothing to match"));
            }
            p *= faer::Scale(1.0 / s.sqrt());
            gm *= faer::Scale(1.0 / s.sqrt());
        }
        Ok(FullProblem {
            scaling,
            w_x: lx.w.clone(),
            w_y: ly.w.clone(),
            mass_x,
            mass_y,
            p,
            g: gm,
            nu_x,
            nu_y,
            c_scale,
            basis_scale_x: sx,
            basis_scale_y: sy,
        })
    }

    /// n, the vertex count of X.
    pub fn n(&self) -> usize {
        self.mass_x.len()
    }

    /// m, the vertex count of Y.
    pub fn m(&self) -> usize {
        self.mass_y.len()
    }

    /// The L1 weights ([`Scaling::Unit`]: the unit-area masses).
    pub fn l1_weights(&self) -> Option<Weights<'_>> {
        match self.scaling {
            Scaling::Unit => Some(Weights { y: &self.mass_y, x: &self.mass_x }),
            Scaling::Paper => None,
        }
    }

    /// The terms of T = L Rᵀ (L: m × k, R: n × k) that depend on T alone (data, Dirichlet, L1;
    /// weighted by `params`, without the low norm) and, with `probes = Some((P_L, P_R))`
    /// (P_L: m × p', P_R: n × p), the products Z·P_R (m × p) and Zᵀ·P_L (n × p') of their
    /// gradient Z = ∂f/∂T (m × n), which is never formed. With P_L = L, P_R = R these are the
    /// gradients with respect to the factors: ∇_L = Z R, ∇_R = Zᵀ L.
    pub fn t_terms(
        &self,
        params: &CompletionParams,
        l: MatRef<f64>,
        r: MatRef<f64>,
        probes: Option<(MatRef<f64>, MatRef<f64>)>,
    ) -> (Terms, Option<GradientProducts>) {
        let (m, n) = (self.m(), self.n());
        assert!(l.nrows() == m && r.nrows() == n && l.ncols() == r.ncols(), "factor sizes");
        let mut terms = Terms::default();
        let mut zr: Option<GradientProducts> =
            probes.map(|(pl, pr)| (Mat::zeros(m, pr.ncols()), Mat::zeros(n, pl.ncols())));
        // Data: R_d = L (Rᵀ P) − G.
        let rtp = gemm_tn(r, self.p.as_ref()); // k × q
        let mut res = gemm_nn(l, rtp.as_ref()); // m × q
        res -= &self.g;
        let ares = scale_rows(&self.mass_y, res.as_ref());
        terms.data = frob(res.as_ref(), ares.as_ref());
        if let (Some((pl, pr)), Some((z_pr, zt_pl))) = (probes, zr.as_mut()) {
            // Z = 2 A_Y R_d Pᵀ.
            let ptpr = gemm_tn(self.p.as_ref(), pr); // q × p
            matmul(z_pr.as_mut(), Accum::Add, ares.as_ref(), ptpr.as_ref(), 2.0, Par::Seq);
            let rtapl = gemm_tn(ares.as_ref(), pl); // q × p'
            matmul(zt_pl.as_mut(), Accum::Add, self.p.as_ref(), rtapl.as_ref(), 2.0, Par::Seq);
        }
        let need_a_l = params.mu1 != 0.0 || params.mu2 != 0.0;
        if need_a_l {
            let al = scale_rows(&self.mass_y, l); // A_Y L
            let ar = scale_rows(&self.mass_x, r); // A_X R
            if params.mu1 != 0.0 {
                // tr(T W_X Tᵀ A_Y) = ⟨Rᵀ W_X R, Lᵀ A_Y L⟩; Z = 2 A_Y L (W_X R)ᵀ / ν_X.
                let wr = sparse_mul(&self.w_x, r);
                let w = params.mu1 / self.nu_x;
                terms.dirichlet_x = w * frob(gemm_tn(r, wr.as_ref()).as_ref(), gemm_tn(l, al.as_ref()).as_ref());
                if let (Some((pl, pr)), Some((z_pr, zt_pl))) = (probes, zr.as_mut()) {
                    let wrt_pr = gemm_tn(wr.as_ref(), pr);
                    matmul(z_pr.as_mut(), Accum::Add, al.as_ref(), wrt_pr.as_ref(), 2.0 * w, Par::Seq);
                    let alt_pl = gemm_tn(al.as_ref(), pl);
                    matmul(zt_pl.as_mut(), Accum::Add, wr.as_ref(), alt_pl.as_ref(), 2.0 * w, Par::Seq);
                }
            }
            if params.mu2 != 0.0 {
                // tr(Tᵀ W_Y T A_X) = ⟨Lᵀ W_Y L, Rᵀ A_X R⟩; Z = 2 (W_Y L)(A_X R)ᵀ / ν_Y.
                let wl = sparse_mul(&self.w_y, l);
                let w = params.mu2 / self.nu_y;
                terms.dirichlet_y = w * frob(gemm_tn(l, wl.as_ref()).as_ref(), gemm_tn(r, ar.as_ref()).as_ref());
                if let (Some((pl, pr)), Some((z_pr, zt_pl))) = (probes, zr.as_mut()) {
                    let art_pr = gemm_tn(ar.as_ref(), pr);
                    matmul(z_pr.as_mut(), Accum::Add, wl.as_ref(), art_pr.as_ref(), 2.0 * w, Par::Seq);
                    let wlt_pl = gemm_tn(wl.as_ref(), pl);
                    matmul(zt_pl.as_mut(), Accum::Add, ar.as_ref(), wlt_pl.as_ref(), 2.0 * w, Par::Seq);
                }
            }
        }
        if params.mu3 != 0.0 {
            let products = match probes {
                Some((pl, pr)) => Products::Factored { pu: pl, pv: pr },
                None => Products::Value,
            };
            let out = soft_l1(l, r, params.xi, self.l1_weights(), params.block_rows, products, params.l1_precision);
            terms.l1 = params.mu3 * out.value;
            if let Some((z_pr, zt_pl)) = zr.as_mut() {
                *z_pr += out.s_pv.expect("requested") * faer::Scale(params.mu3);
                *zt_pl += out.st_pu.expect("requested") * faer::Scale(params.mu3);
            }
        }
        terms.total = terms.data + terms.dirichlet_x + terms.dirichlet_y + terms.l1;
        (terms, zr)
    }

    /// The low-norm term μ4/2 (‖U‖² + ‖V‖²) of (10) (weighted norms per [`Scaling`] and
    /// `params.low_norm`) and its gradients (m × k, n × k).
    pub fn low_norm(&self, params: &CompletionParams, u: MatRef<f64>, v: MatRef<f64>) -> (f64, Mat<f64>, Mat<f64>) {
        let (mass, factor) = match (self.scaling, params.low_norm) {
            (Scaling::Unit, _) => (true, 1.0 / u.ncols() as f64),
            (Scaling::Paper, LowNorm::Euclidean) => (false, 1.0),
            (Scaling::Paper, LowNorm::Mass) => (true, 1.0),
        };
        let w = params.mu4 * factor;
        let (gu, gv) = if mass {
            (scale_rows(&self.mass_y, u) * faer::Scale(w), scale_rows(&self.mass_x, v) * faer::Scale(w))
        } else {
            (u.to_owned() * faer::Scale(w), v.to_owned() * faer::Scale(w))
        };
        let value = 0.5 * (frob(u, gu.as_ref()) + frob(v, gv.as_ref()));
        (value, gu, gv)
    }

    /// The diagonal scalings D_Y (m), D_X (n) of the nuclear norm ‖D_Y T D_X‖_* equal to the
    /// minimum of the low norm over factorizations T = U Vᵀ, and its factor (1 or 1/k).
    pub fn nuclear_scaling(&self, params: &CompletionParams, k: usize) -> (Vec<f64>, Vec<f64>, f64) {
        match (self.scaling, params.low_norm) {
            (Scaling::Unit, _) => (
                self.mass_y.iter().map(|a| a.sqrt()).collect(),
                self.mass_x.iter().map(|a| a.sqrt()).collect(),
                1.0 / k as f64,
            ),
            (Scaling::Paper, LowNorm::Mass) => {
                (self.mass_y.iter().map(|a| a.sqrt()).collect(), self.mass_x.iter().map(|a| a.sqrt()).collect(), 1.0)
            }
            (Scaling::Paper, LowNorm::Euclidean) => (vec![1.0; self.m()], vec![1.0; self.n()], 1.0),
        }
    }

    /// The factors U = Ψ_k' A (m × k), V = Φ_k' B (n × k) in this problem's units of a subspace
    /// solution (A, B: k' × k of a [`super::Problem`] with the same scaling).
    pub fn factors_from_subspace(
        &self,
        bx: &Basis,
        by: &Basis,
        a: MatRef<f64>,
        b: MatRef<f64>,
    ) -> (Mat<f64>, Mat<f64>) {
        let kp = a.nrows();
        let psi = by.eigenvectors.subcols(0, kp);
        let phi = bx.eigenvectors.subcols(0, kp);
        let u = mul(psi, a) * faer::Scale(self.basis_scale_y);
        let v = mul(phi, b) * faer::Scale(self.basis_scale_x);
        (u, v)
    }
}

/// The optimization variables of the vertex forms: the factors scaled by the square roots of
/// the masses, U_S = A_Y^{1/2} U, V_S = A_X^{1/2} V (so that T_S = A_Y^{1/2} T A_X^{1/2} is the
/// kernel in mass-orthonormal coordinates, where the subspace problem lives). Only the
/// optimizers' metric changes; the minimizers are the same. Returns (√A_Y (m), √A_X (n)).
pub(crate) fn metric(problem: &FullProblem) -> (Vec<f64>, Vec<f64>) {
    (problem.mass_y.iter().map(|a| a.sqrt()).collect(), problem.mass_x.iter().map(|a| a.sqrt()).collect())
}

/// diag(1/d) x.
pub(crate) fn unscale_rows(d: &[f64], x: MatRef<f64>) -> Mat<f64> {
    Mat::from_fn(x.nrows(), x.ncols(), |i, j| x[(i, j)] / d[i])
}

/// The objective of (10) at x = (vec U_S, vec V_S) (scaled factors, [`metric`]) and its
/// gradient with respect to them, for L-BFGS.
pub(crate) fn low_norm_objective(
    problem: &FullProblem,
    params: &CompletionParams,
    (dy, dx): (&[f64], &[f64]),
    x: &[f64],
    k: usize,
    grad: &mut [f64],
) -> Terms {
    let (m, n) = (problem.m(), problem.n());
    let u = unscale_rows(dy, MatRef::from_column_major_slice(&x[..m * k], m, k));
    let v = unscale_rows(dx, MatRef::from_column_major_slice(&x[m * k..], n, k));
    let (mut terms, grads) = problem.t_terms(params, u.as_ref(), v.as_ref(), Some((u.as_ref(), v.as_ref())));
    let (mut gu, mut gv) = grads.expect("requested");
    if params.mu4 != 0.0 {
        let (value, lu, lv) = problem.low_norm(params, u.as_ref(), v.as_ref());
        terms.low_norm = value;
        terms.total += value;
        gu += &lu;
        gv += &lv;
    }
    let mut at = 0;
    for (mat, d) in [(&gu, dy), (&gv, dx)] {
        for j in 0..k {
            let col = mat.col_as_slice(j);
            for (o, (v, d)) in grad[at..at + col.len()].iter_mut().zip(col.iter().zip(d)) {
                *o = v / d;
            }
            at += col.len();
        }
    }
    terms
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::completion::objective::value;
    use crate::completion::testutil::{dot, randn};
    use crate::completion::Problem;
    use crate::descriptors::signatures::{hkm, hks, hks_times, wks};
    use crate::laplacian::cotangent;
    use crate::primitives::bumpy_sphere;
    use crate::spectral::{eigen_basis, SpectralOptions};

    /// A small pair: a bumpy sphere X (`level` subdivisions) and Y = X with vertices renumbered
    /// (Y vertex j is X vertex perm[j]) and uniformly scaled by 1.3, with Laplacians, bases of
    /// `k` eigenpairs and q = 36 data functions (WKS, HKS, heat kernel maps from 10 seeds).
    pub(crate) struct SmallPair {
        pub lx: Laplacian,
        pub ly: Laplacian,
        pub bx: Basis,
        pub by: Basis,
        pub f: Descriptors,
        pub g: Descriptors,
        /// map_xy of the truth: vertex i of X is vertex truth[i] of Y.
        pub truth: Vec<usize>,
        /// Vertex positions of X (n) and Y (m).
        pub px: Vec<[f64; 3]>,
        pub py: Vec<[f64; 3]>,
    }

    pub(crate) fn small_pair(level: u32, k: usize) -> SmallPair {
        let x = bumpy_sphere(level);
        let n = x.n_vertices();
        let perm: Vec<usize> = (0..n).map(|i| (i * 7919 + 3) % n).collect();
        let y = x.permuted(&perm).unwrap().map_vertices(|p| [1.3 * p[0], 1.3 * p[1], 1.3 * p[2]]).unwrap();
        let mut truth = vec![0usize; n];
        for (new, &old) in perm.iter().enumerate() {
            truth[old] = new;
        }
        let (lx, ly) = (cotangent(&x).unwrap(), cotangent(&y).unwrap());
        let basis = |l: &Laplacian| eigen_basis(l, &SpectralOptions::new(k), None).unwrap().0;
        let (bx, by) = (basis(&lx), basis(&ly));
        // 8 WKS + 8 HKS (blind to eigenfunction signs) and heat kernel maps from 10 seeds at
        // 2 times (linear in the eigenfunctions: they fix the signs).
        let seeds_x: Vec<usize> = (0..10).map(|s| s * n / 10).collect();
        let seeds_y: Vec<usize> = seeds_x.iter().map(|&i| truth[i]).collect();
        let data = |b: &Basis, seeds: &[usize]| {
            let times = hks_times(b, 8).unwrap();
            wks(b, 8, true)
                .unwrap()
                .concat(&hks(b, &times, true).unwrap())
                .unwrap()
                .concat(&hkm(b, seeds, &[times[1], times[3]], true).unwrap())
                .unwrap()
        };
        let (f, g) = (data(&bx, &seeds_x), data(&by, &seeds_y));
        let (px, py) = (x.vertices().to_vec(), y.vertices().to_vec());
        SmallPair { lx, ly, bx, by, f, g, truth, px, py }
    }

    fn fd_check(p: &FullProblem, params: &CompletionParams, k: usize, seed: u64, what: &str) {
        let (m, n) = (p.m(), p.n());
        let u = randn(m, k, seed) * 0.3;
        let v = randn(n, k, seed + 1) * 0.3;
        let x: Vec<f64> = (0..k)
            .flat_map(|j| (0..m).map(move |i| (j, i)))
            .map(|(j, i)| u[(i, j)])
            .chain((0..k).flat_map(|j| (0..n).map(move |i| (j, i))).map(|(j, i)| v[(i, j)]))
            .collect();
        let ones = (vec![1.0; m], vec![1.0; n]);
        let met = (ones.0.as_slice(), ones.1.as_slice());
        let mut g = vec![0.0; x.len()];
        let t = low_norm_objective(p, params, met, &x, k, &mut g);
        let d: Vec<f64> = randn(x.len(), 1, seed + 2).col_as_slice(0).to_vec();
        let h = 1e-6;
        let at = |s: f64| {
            let y: Vec<f64> = x.iter().zip(&d).map(|(a, b)| a + s * b).collect();
            low_norm_objective(p, params, met, &y, k, &mut vec![0.0; y.len()]).total
        };
        let fd = (at(h) - at(-h)) / (2.0 * h);
        let an: f64 = g.iter().zip(&d).map(|(a, b)| a * b).sum();
        let rel = (fd - an).abs() / an.abs().max(1e-300);
        assert!(rel < 1e-5, "{what}: fd {fd} vs analytic {an} (rel {rel:.1e}), value {}", t.total);
    }

    /// Finite-difference checks of every term of (8) and (10) with respect to U and V, one
    /// term at a time, in both scalings.
    #[test]
    fn vertex_form_gradients_match_finite_differences() {
        let sp = small_pair(2, 20);
        for scaling in [Scaling::Unit, Scaling::Paper] {
            let p = FullProblem::new(&sp.lx, &sp.ly, &sp.bx, &sp.by, &sp.f, &sp.g, 20, scaling).unwrap();
            let zero =
                CompletionParams { mu1: 0.0, mu2: 0.0, mu3: 0.0, mu4: 0.0, block_rows: 37, ..Default::default() };
            let (a, b) = match scaling {
                Scaling::Unit => (1.0, 1.0),
                Scaling::Paper => (1e-2, 1e3),
            };
            for (what, params) in [
                ("data", zero.clone()),
                ("dirichlet x", CompletionParams { mu1: a, ..zero.clone() }),
                ("dirichlet y", CompletionParams { mu2: a, ..zero.clone() }),
                ("l1", CompletionParams { mu3: b, xi: 1e-2, ..zero.clone() }),
                ("low norm", CompletionParams { mu4: 1.0, ..zero.clone() }),
                ("low norm (mass)", CompletionParams { mu4: 1.0, low_norm: LowNorm::Mass, ..zero.clone() }),
            ] {
                fd_check(&p, &params, 4, 10, &format!("{scaling:?} {what}"));
            }
        }
    }

    /// With U = Ψ_k' A and V = Φ_k' B every term of the vertex forms equals the term of (11),
    /// the data term up to a constant (the part of G outside the basis).
    #[test]
    fn subspace_is_a_special_case() {
        let sp = small_pair(2, 20);
        let (kp, k) = (20, 6);
        for scaling in [Scaling::Unit, Scaling::Paper] {
            let full = FullProblem::new(&sp.lx, &sp.ly, &sp.bx, &sp.by, &sp.f, &sp.g, kp, scaling).unwrap();
            let sub = Problem::new(&sp.bx, &sp.by, &sp.f, &sp.g, kp, scaling).unwrap();
            let params = CompletionParams {
                mu1: 0.3,
                mu2: 0.2,
                mu3: 0.1,
                mu4: 0.05,
                xi: 1e-2,
                block_rows: 50,
                ..CompletionParams::defaults_for(scaling)
            };
            let mut offsets = Vec::new();
            for seed in [1u64, 2] {
                let (a, b) = (randn(kp, k, seed), randn(kp, k, seed + 10));
                let (u, v) = full.factors_from_subspace(&sp.bx, &sp.by, a.as_ref(), b.as_ref());
                let (mut tf, _) = full.t_terms(&params, u.as_ref(), v.as_ref(), None);
                tf.low_norm = full.low_norm(&params, u.as_ref(), v.as_ref()).0;
                let ts = value(&sub, &params, a.as_ref(), b.as_ref());
                let close = |x: f64, y: f64| (x - y).abs() <= 1e-8 * x.abs().max(y.abs());
                assert!(close(tf.dirichlet_x, ts.dirichlet_x), "{scaling:?} {} vs {}", tf.dirichlet_x, ts.dirichlet_x);
                assert!(close(tf.dirichlet_y, ts.dirichlet_y), "{scaling:?} {} vs {}", tf.dirichlet_y, ts.dirichlet_y);
                assert!(close(tf.l1, ts.l1), "{scaling:?} {} vs {}", tf.l1, ts.l1);
                assert!(close(tf.low_norm, ts.low_norm), "{scaling:?} {} vs {}", tf.low_norm, ts.low_norm);
                offsets.push(tf.data - ts.data);
                assert!(offsets[offsets.len() - 1] >= -1e-10);
            }
            assert!((offsets[0] - offsets[1]).abs() < 1e-8 * offsets[0].abs().max(1e-3), "{offsets:?}");
        }
        let _ = dot;
    }
}
