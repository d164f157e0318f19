//! Baseline functional-map solvers of the paper's §2: Ovsjanikov et al. 2012 (eq. (5)), Pokrass
//! et al. 2013 (eq. (6)) and Kovnatsky et al. 2013 (eq. (7)).
//!
//! Notation: X has n vertices and basis Φ (n × k, Φᵀ A_X Φ = I), Y has m vertices and basis Ψ;
//! F (n × q) and G (m × q) are corresponding functions. Every solver returns C (k × k) mapping
//! coefficients on X to coefficients on Y: T = Ψ C Φᵀ A_X.
//!
//! Conventions shared by all solvers:
//! - **Coefficients** are mass-weighted, Â = Φ_kᵀ A_X F and B̂ = Ψ_kᵀ A_Y G (k × q): with
//!   A-orthonormal bases these are the true expansion coefficients (the paper's Φᵀ F is only right
//!   for A = I).
//! - **Data term scale**: the data term is divided by s = (‖Â‖²_F + ‖B̂‖²_F) / 2, so it is a relative
//!   residual, invariant under rescaling the shapes (Â grows linearly with the shape's size) or
//!   the data; the weights μ then mean the same on every shape.
//! - **Eigenvalue scale**: eigenvalues enter as λ̃ = λ / λ_max with λ_max the largest of the 2k
//!   eigenvalues λ_X,1..k, λ_Y,1..k used, so λ̃ ∈ [0, 1] and regularizers are scale-free.

pub mod axiomatic;
pub mod coupled;
pub mod energy;
pub mod ovsjanikov;
pub mod pokrass;

pub use coupled::{coupled, CoupledInfo, CoupledOptions};
pub use ovsjanikov::{ovsjanikov, OvsjanikovOptions};
pub use pokrass::{pokrass, PokrassOptions};

pub(crate) use crate::linalg::mul;
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};

/// A functional map in the pull-back direction of a point map π: X → Y: C_yx = Φᵀ A_X Π Ψ
/// (k_X × k_Y) takes the coefficients of a function g on Y (in Ψ) to those of g ∘ π on X (in
/// Φ) — the transpose direction of the C (k_Y × k_X) of this module's solvers. The axiomatic
/// pipeline ([`crate::matching::axiomatic`]) estimates π through it from the fit
/// ([`axiomatic::axiomatic_pullbacks`]) to the last refinement ([`crate::refine`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Pullback(pub Mat<f64>);

impl Pullback {
    /// C_yx (k_X × k_Y).
    pub fn as_ref(&self) -> MatRef<'_, f64> {
        self.0.as_ref()
    }
    /// k_X, the size of its basis of X (rows).
    pub fn k_x(&self) -> usize {
        self.0.nrows()
    }
    /// k_Y, the size of its basis of Y (columns).
    pub fn k_y(&self) -> usize {
        self.0.ncols()
    }
    /// C_yxᵀ (k_Y × k_X), read as the functional map X → Y of this module: equal to the C of
    /// the same point map when both are orthonormal (a bijective isometry), which ZoomOut's maps
    /// approach.
    pub fn transposed(&self) -> Mat<f64> {
        self.0.transpose().to_owned()
    }
}

use crate::descriptors::Descriptors;
use crate::error::{Error, Result};
use crate::spectral::Basis;

/// The validated inputs of a solver: coefficients and normalized eigenvalues.
pub(crate) struct Problem {
    /// Â = Φ_kᵀ A_X F (k × q).
    pub a: Mat<f64>,
    /// B̂ = Ψ_kᵀ A_Y G (k × q).
    pub b: Mat<f64>,
    /// λ̃_X (k), divided by the largest eigenvalue of both truncated spectra.
    pub lx: Vec<f64>,
    /// λ̃_Y (k), same scale as `lx`.
    pub ly: Vec<f64>,
    /// Data-term scale s = (‖Â‖²_F + ‖B̂‖²_F) / 2 (> 0).
    pub scale: f64,
}

fn all_finite(m: MatRef<f64>) -> bool {
    (0..m.ncols()).all(|j| (0..m.nrows()).all(|i| m[(i, j)].is_finite()))
}

/// Φ_kᵀ A F (k × q), checking sizes and finiteness.
fn coefficients(basis: &Basis, f: &Descriptors, k: usize, side: &str) -> Result<Mat<f64>> {
    let n = basis.n();
    if f.values.nrows() != n {
        return Err(Error::invalid(
            format!("data on {side}"),
            format!("it has {} rows but the shape has {n} vertices", f.values.nrows()),
        ));
    }
    if basis.mass.len() != n || basis.eigenvectors.ncols() != basis.k() {
        return Err(Error::invalid(format!("basis of {side}"), "inconsistent sizes"));
    }
    if k == 0 || k > basis.k() {
        return Err(Error::invalid("k", format!("need 1 ≤ k ≤ {} (the basis size of {side}), got {k}", basis.k())));
    }
    if !all_finite(f.values.as_ref()) {
        return Err(Error::invalid(format!("data on {side}"), "it contains a non-finite value"));
    }
    if !basis.eigenvalues[..k].iter().all(|l| l.is_finite()) || !basis.mass.iter().all(|a| a.is_finite()) {
        return Err(Error::invalid(format!("basis of {side}"), "it contains a non-finite value"));
    }
    let phi = basis.eigenvectors.subcols(0, k);
    if !all_finite(phi) {
        return Err(Error::invalid(format!("basis of {side}"), "it contains a non-finite value"));
    }
    let af = Mat::from_fn(n, f.values.ncols(), |i, j| basis.mass[i] * f.values[(i, j)]);
    let mut out = Mat::<f64>::zeros(k, f.values.ncols());
    matmul(out.as_mut(), Accum::Replace, phi.transpose(), af.as_ref(), 1.0, Par::Seq);
    Ok(out)
}

impl Problem {
    /// Validates the inputs and computes the coefficients. Errors: column counts of F and G
    /// differ or are zero, rows ≠ n / m, k = 0 or k larger than a basis, non-finite values, data
    /// with no component in the first k basis functions.
    pub(crate) fn new(bx: &Basis, by: &Basis, f: &Descriptors, g: &Descriptors, k: usize) -> Result<Problem> {
        if f.values.ncols() != g.values.ncols() {
            return Err(Error::invalid(
                "data",
                format!("F has {} columns but G has {}; they must correspond", f.values.ncols(), g.values.ncols()),
            ));
        }
        if f.values.ncols() == 0 {
            return Err(Error::invalid("data", "no corresponding functions given (q = 0)"));
        }
        let a = coefficients(bx, f, k, "X")?;
        let b = coefficients(by, g, k, "Y")?;
        let scale = 0.5 * (a.squared_norm_l2() + b.squared_norm_l2());
        if !(scale > 0.0 && scale.is_finite()) {
            return Err(Error::invalid("data", "the data has no component in the first k basis functions"));
        }
        let lmax = bx.eigenvalues[..k].iter().chain(&by.eigenvalues[..k]).fold(0.0f64, |m, l| m.max(l.abs()));
        let norm = if lmax > 0.0 { lmax } else { 1.0 };
        let lx = bx.eigenvalues[..k].iter().map(|l| l / norm).collect();
        let ly = by.eigenvalues[..k].iter().map(|l| l / norm).collect();
        Ok(Problem { a, b, lx, ly, scale })
    }

    pub(crate) fn k(&self) -> usize {
        self.a.nrows()
    }
}

/// Minimum-norm least-squares solution C of C Â ≈ B̂ (C = B̂ Â⁺), Â⁺ the pseudo-inverse from the
/// thin SVD with singular values below max(k, q) · ε · σ_max treated as zero.
pub(crate) fn min_norm_lstsq(a: MatRef<f64>, b: MatRef<f64>) -> Result<Mat<f64>> {
    let svd = a.thin_svd().map_err(|e| Error::numerical("least squares", format!("SVD failed: {e:?}")))?;
    let (u, v, s) = (svd.U(), svd.V(), svd.S());
    let r = s.column_vector().nrows();
    let smax = (0..r).fold(0.0f64, |m, i| m.max(s[i]));
    let cut = a.nrows().max(a.ncols()) as f64 * f64::EPSILON * smax;
    // B̂ V S⁺ Uᵀ
    let bv = mul(b, v);
    let scaled = Mat::from_fn(bv.nrows(), r, |i, j| if s[j] > cut { bv[(i, j)] / s[j] } else { 0.0 });
    Ok(mul(scaled.as_ref(), u.transpose()))
}

#[cfg(test)]
pub(crate) mod testdata {
    //! A bumpy sphere and a vertex-permuted copy with rich matched data, shared by the tests.
    use std::sync::OnceLock;

    use faer::Mat;

    use crate::descriptors::signatures::{hkm, hks, hks_times, wks};
    use crate::descriptors::Descriptors;
    use crate::laplacian::cotangent;
    use crate::primitives::bumpy_sphere;
    use crate::spectral::{eigen_basis, Basis, SpectralOptions};

    pub struct Pair {
        pub bx: Basis,
        pub by: Basis,
        pub f: Descriptors,
        pub g: Descriptors,
        /// Vertex i of Y is vertex `perm[i]` of X.
        pub perm: Vec<usize>,
        /// Ground-truth C: diag(±1) (the signs flipped on Ψ).
        pub signs: Vec<f64>,
    }

    fn build() -> Pair {
        let k = 30;
        let x = bumpy_sphere(3);
        let n = x.n_vertices();
        let perm: Vec<usize> = (0..n).map(|i| (i * 7919 + 13) % n).collect();
        // Y: the permuted copy (same size: an area change would scale C).
        let y = x.permuted(&perm).unwrap();
        let mut inv = vec![0u32; n];
        for (new, &old) in perm.iter().enumerate() {
            inv[old] = new as u32;
        }
        let opts = SpectralOptions::new(k);
        let bx = eigen_basis(&cotangent(&x).unwrap(), &opts, None).unwrap().0;
        let mut by = eigen_basis(&cotangent(&y).unwrap(), &opts, None).unwrap().0;
        // Flip some eigenvector signs on Y so the ground truth is not the identity.
        let signs: Vec<f64> = (0..k).map(|i| if i % 3 == 1 || i % 7 == 2 { -1.0 } else { 1.0 }).collect();
        for j in 0..k {
            for i in 0..n {
                by.eigenvectors[(i, j)] *= signs[j];
            }
        }
        // q = 60: 21 WKS, 21 HKS (squares of eigenfunctions: blind to signs, nearly rank deficient)
        // and heat kernel maps from 6 corresponding seeds at 3 short times (linear in Φ, they
        // excite every frequency and fix the signs).
        let lk = bx.eigenvalues[k - 1];
        let times = [0.5 / lk, 2.0 / lk, 8.0 / lk];
        let seeds_x = [5usize, 100, 222, 333, 480, 600];
        let seeds_y: Vec<usize> = seeds_x.iter().map(|&v| inv[v] as usize).collect();
        let data = |b: &Basis, seeds: &[usize]| {
            let h = hks(b, &hks_times(b, 21).unwrap(), true).unwrap();
            let m = hkm(b, seeds, &times, true).unwrap();
            wks(b, 21, true).unwrap().concat(&h).unwrap().concat(&m).unwrap()
        };
        let (f, g) = (data(&bx, &seeds_x), data(&by, &seeds_y));
        Pair { bx, by, f, g, perm, signs }
    }

    pub fn pair() -> &'static Pair {
        static PAIR: OnceLock<Pair> = OnceLock::new();
        PAIR.get_or_init(build)
    }

    /// Fraction of vertices of X mapped to their true image on Y by nearest neighbours of the
    /// rows of Φ Cᵀ among the rows of Ψ.
    pub fn recovered(p: &Pair, c: &Mat<f64>) -> f64 {
        let k = c.nrows();
        let map = crate::pointwise::map_from_fmap(
            p.bx.eigenvectors.subcols(0, k),
            p.by.eigenvectors.subcols(0, k),
            c.as_ref(),
        )
        .unwrap();
        let n = p.bx.n();
        let mut truth = vec![0usize; n];
        for (new, &old) in p.perm.iter().enumerate() {
            truth[old] = new;
        }
        (0..n).filter(|&i| map[i] == truth[i]).count() as f64 / n as f64
    }

    /// Largest |C_ij − signs_i δ_ij|.
    pub fn diag_error(p: &Pair, c: &Mat<f64>) -> f64 {
        let k = c.nrows();
        let mut worst = 0.0f64;
        for i in 0..k {
            for j in 0..k {
                let want = if i == j { p.signs[i] } else { 0.0 };
                worst = worst.max((c[(i, j)] - want).abs());
            }
        }
        worst
    }
}
