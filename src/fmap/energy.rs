//! The functional-map energy of the modern axiomatic pipeline, one function per term with its
//! gradient beside it, and its exact minimizer.
//!
//! Unknown: C (k_Y × k_X), mapping coefficients of functions on X (basis Φ, n × k_X) to
//! coefficients on Y (basis Ψ, m × k_Y); T = Ψ C Φᵀ A_X pushes functions from X to Y (the
//! pull-back by a point map Y → X). Data: q corresponding functions F (n × q) on X and G (m × q)
//! on Y, with coefficients Â = Φᵀ A_X F (k_X × q), B̂ = Ψᵀ A_Y G (k_Y × q).
//!
//! E(C) = w_d E_desc / s_d + w_l E_lap / s_l + w_c E_comm / s_c + w_o E_orient / s_o, with
//!
//! - **descriptor preservation** (Ovsjanikov et al. 2012, the paper's eq. (5)):
//!   `E_desc = ‖C Â − B̂‖²_F`;
//! - **Laplacian commutativity** with a mask M (k_Y × k_X): `E_lap = Σ_ij M_ij C_ij²`; the standard
//!   mask M_ij = (λ̃_Y,i − λ̃_X,j)² (Ovsjanikov et al. 2012 §6) or the resolvent mask of Ren, Melzi,
//!   Wonka, Ovsjanikov 2019 ("Structured regularization of functional map computations", eq. (8)):
//!   M_ij = |R(λ̃_Y,i) − R(λ̃_X,j)|², R(λ) = 1 / (λ^γ − i), γ = 0.5, the commutator with the resolvent
//!   of Δ^γ instead of with Δ itself, which penalizes high-frequency entries much less and is
//!   better conditioned; eigenvalues λ̃ = λ / max(λ_X,k, λ_Y,k) of both truncated spectra;
//! - **descriptor commutativity** (Nogneng & Ovsjanikov 2017, eq. (5)):
//!   `E_comm = Σ_p ‖C D^X_p − D^Y_p C‖²_F` with the multiplication operators of f_p and g_p
//!   ([`crate::operators::multiplication_operators`]);
//! - **orientation** (Ren, Poulenard, Wonka, Ovsjanikov 2018, BCICP, eq. (9)):
//!   `E_orient = Σ_p ‖C O^X_p − σ O^Y_p C‖²_F` with the orientation operators of f_p and g_p
//!   ([`crate::operators::orientation_operators`]), σ = +1 for orientation-preserving maps and −1
//!   for orientation-reversing ones.
//!
//! **Scales.** Every term is divided by its mean over Haar-random orthogonal k × k maps C (the
//! value of a map that carries no information; k = min(k_X, k_Y)), so the weights are
//! dimensionless and the same on shapes of any size and sampling, with descriptors of any
//! magnitude: E[‖C Â − B̂‖²] = ‖Â‖² + ‖B̂‖² (constant mode left out: it is fixed by the area
//! constraint), E[Σ M_ij C_ij²] = Σ M / k, E[‖C X − σ Y C‖²] = ‖X‖² + ‖Y‖² − 2σ tr X tr Y / k
//! (the trace term removes the part of a multiplication operator that commutes with every C;
//! orientation operators are skew, tr = 0). The three descriptor terms sum over q descriptors
//! that are strongly correlated (WKS at neighbouring energies), so their scales are further
//! divided by the effective number of independent descriptors p_eff = (tr G)² / ‖G‖²_F, G = Âᵀ Â
//! ([`effective_descriptors`]): with weights 1, each descriptor term counts as p_eff independent
//! constraints against the one Laplacian prior. The same normalization as pyFM 1.3's
//! `canonical_taus`, derived here from the random-map expectation.
//!
//! All four terms are quadratic in C, so E has a closed-form minimizer: vec(C) solves the
//! k_X k_Y × k_X k_Y symmetric positive (semi-)definite system H vec(C) = vec(B̂ Âᵀ) w_d / s_d
//! (column-major vec; [`Energy::solve`]). Cost O(q (k_X k_Y)² + (k_X k_Y)³ / 3): 0.01 s at
//! k = 30, ≈ 0.3 s at k = 50.

use crate::linalg::mul;
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatMut, MatRef, Par};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// Which maps the orientation term favours.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Orientation {
    /// Orientation-preserving maps (σ = +1): the true map between two scans of one object.
    Preserve,
    /// Orientation-reversing maps (σ = −1): a shape to its mirror image, or a left–right
    /// symmetry of one shape.
    Reverse,
    /// No orientation term.
    Ignore,
}

impl Orientation {
    /// σ of the orientation term (0 when ignored).
    pub fn sign(self) -> f64 {
        match self {
            Orientation::Preserve => 1.0,
            Orientation::Reverse => -1.0,
            Orientation::Ignore => 0.0,
        }
    }
}

/// The Laplacian-commutativity mask.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mask {
    /// M_ij = (λ̃_Y,i − λ̃_X,j)².
    Standard,
    /// M_ij = |R(λ̃_Y,i) − R(λ̃_X,j)|², R(λ) = 1 / (λ^γ − i).
    Resolvent {
        /// γ (Ren et al. 2019 use 0.5).
        gamma: f64,
    },
}

/// The standard Laplacian-commutativity mask (k_Y × k_X): M_ij = (λ̃_Y,i − λ̃_X,j)².
pub fn standard_mask(lx: &[f64], ly: &[f64]) -> Mat<f64> {
    Mat::from_fn(ly.len(), lx.len(), |i, j| (ly[i] - lx[j]).powi(2))
}

/// The resolvent mask (k_Y × k_X) of Ren et al. 2019: with R(λ) = 1 / (λ^γ − i) =
/// (λ^γ + i) / (λ^{2γ} + 1), M_ij = |R(λ̃_Y,i) − R(λ̃_X,j)|². Eigenvalues must be ≥ 0 (they are
/// clamped at 0 against round-off).
pub fn resolvent_mask(lx: &[f64], ly: &[f64], gamma: f64) -> Mat<f64> {
    let r = |l: f64| {
        let g = l.max(0.0).powf(gamma);
        let d = g * g + 1.0;
        (g / d, 1.0 / d)
    };
    let (rx, ry): (Vec<_>, Vec<_>) = (lx.iter().map(|&l| r(l)).collect(), ly.iter().map(|&l| r(l)).collect());
    Mat::from_fn(ly.len(), lx.len(), |i, j| (ry[i].0 - rx[j].0).powi(2) + (ry[i].1 - rx[j].1).powi(2))
}

/// Descriptor preservation `‖C Â − B̂‖²_F` (C: k_Y × k_X, Â: k_X × q, B̂: k_Y × q).
pub fn descriptor_preservation(c: MatRef<f64>, a: MatRef<f64>, b: MatRef<f64>) -> f64 {
    (mul(c, a) - b).squared_norm_l2()
}

/// Gradient of [`descriptor_preservation`]: `2 (C Â − B̂) Âᵀ` (k_Y × k_X).
pub fn descriptor_preservation_gradient(c: MatRef<f64>, a: MatRef<f64>, b: MatRef<f64>) -> Mat<f64> {
    mul((mul(c, a) - b).as_ref(), a.transpose()) * 2.0
}

/// Laplacian commutativity `Σ_ij M_ij C_ij²` (C and M: k_Y × k_X).
pub fn laplacian_commutativity(c: MatRef<f64>, mask: MatRef<f64>) -> f64 {
    (0..c.ncols()).map(|j| (0..c.nrows()).map(|i| mask[(i, j)] * c[(i, j)].powi(2)).sum::<f64>()).sum()
}

/// Gradient of [`laplacian_commutativity`]: `2 M ∘ C`.
pub fn laplacian_commutativity_gradient(c: MatRef<f64>, mask: MatRef<f64>) -> Mat<f64> {
    Mat::from_fn(c.nrows(), c.ncols(), |i, j| 2.0 * mask[(i, j)] * c[(i, j)])
}

/// Operator commutativity `Σ_p ‖C X_p − σ Y_p C‖²_F` (X_p: k_X × k_X, Y_p: k_Y × k_Y): descriptor
/// commutativity with multiplication operators (σ = 1), orientation with orientation operators.
pub fn operator_commutativity(c: MatRef<f64>, ops_x: &[Mat<f64>], ops_y: &[Mat<f64>], sigma: f64) -> f64 {
    ops_x.iter().zip(ops_y).map(|(ox, oy)| (mul(c, ox.as_ref()) - mul(oy.as_ref(), c) * sigma).squared_norm_l2()).sum()
}

/// Gradient of [`operator_commutativity`]: `Σ_p 2 (R_p X_pᵀ − σ Y_pᵀ R_p)`, R_p = C X_p − σ Y_p C.
pub fn operator_commutativity_gradient(c: MatRef<f64>, ops_x: &[Mat<f64>], ops_y: &[Mat<f64>], sigma: f64) -> Mat<f64> {
    let mut g = Mat::<f64>::zeros(c.nrows(), c.ncols());
    for (ox, oy) in ops_x.iter().zip(ops_y) {
        let r = mul(c, ox.as_ref()) - mul(oy.as_ref(), c) * sigma;
        g += (mul(r.as_ref(), ox.transpose()) - mul(oy.transpose(), r.as_ref()) * sigma) * 2.0;
    }
    g
}

/// Weights of the energy's terms (dimensionless; see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct EnergyWeights {
    /// w_d, descriptor preservation.
    pub descriptors: f64,
    /// w_l, Laplacian commutativity.
    pub laplacian: f64,
    /// w_c, descriptor commutativity.
    pub commutativity: f64,
    /// w_o, orientation.
    pub orientation: f64,
}

/// One shape's side of the energy, in its reduced basis (k eigenpairs).
#[derive(Clone, Debug)]
pub struct SpectralSide {
    /// Descriptor coefficients Φᵀ A F (k × q).
    pub coefficients: Mat<f64>,
    /// λ₁..λ_k (unscaled).
    pub eigenvalues: Vec<f64>,
    /// Multiplication operators of the q descriptors (k × k each; empty when not used).
    pub multiplication: Vec<Mat<f64>>,
    /// Orientation operators of the q descriptors (k × k each; empty when not used).
    pub orientation: Vec<Mat<f64>>,
}

impl SpectralSide {
    /// The same quantities in the first `k` eigenfunctions: the first k rows of the coefficients
    /// and eigenvalues, the leading k × k block of every operator (each is Φᵀ M Φ for a matrix M
    /// that does not depend on the basis size, so its leading block is the operator of Φ's first
    /// k columns). Lets one pass over the shape serve every candidate size. Requires k ≤ the
    /// current size.
    pub fn leading(&self, k: usize) -> SpectralSide {
        let k = k.min(self.eigenvalues.len());
        let block = |m: &Mat<f64>| m.submatrix(0, 0, k, k).to_owned();
        SpectralSide {
            coefficients: self.coefficients.subrows(0, k).to_owned(),
            eigenvalues: self.eigenvalues[..k].to_vec(),
            multiplication: self.multiplication.iter().map(block).collect(),
            orientation: self.orientation.iter().map(block).collect(),
        }
    }
}

/// The assembled energy E(C) of the module docs for one pair of shapes.
#[derive(Clone, Debug)]
pub struct Energy {
    a: Mat<f64>,
    b: Mat<f64>,
    mask: Mat<f64>,
    dx: Vec<Mat<f64>>,
    dy: Vec<Mat<f64>>,
    ox: Vec<Mat<f64>>,
    oy: Vec<Mat<f64>>,
    sigma: f64,
    /// 1 / s of the four terms (data, Laplacian, commutativity, orientation; 0 when off).
    inv_scale: [f64; 4],
    /// Effective weights w / s of the four terms.
    eff: [f64; 4],
}

/// The four terms of E at some C, unweighted and divided by their scales.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct EnergyTerms {
    /// E_desc / s_d.
    pub descriptors: f64,
    /// E_lap.
    pub laplacian: f64,
    /// E_comm / s_c.
    pub commutativity: f64,
    /// E_orient / s_o.
    pub orientation: f64,
}

fn trace(m: &Mat<f64>) -> f64 {
    (0..m.nrows().min(m.ncols())).map(|i| m[(i, i)]).sum()
}

/// The effective number of independent descriptors of coefficients Â (k × q), without the
/// constant mode (row 0): p_eff = (tr G)² / ‖G‖²_F with G = Â₁ᵀ Â₁ (q for q orthogonal
/// descriptors of equal norm, 1 for q copies of one); 1 when Â₁ = 0.
pub fn effective_descriptors(a: MatRef<f64>) -> f64 {
    if a.nrows() < 2 {
        return 1.0;
    }
    let a1 = a.subrows(1, a.nrows() - 1);
    let g = mul(a1.transpose(), a1);
    let tr: f64 = (0..g.nrows()).map(|i| g[(i, i)]).sum();
    let f = g.squared_norm_l2();
    if f > 0.0 && tr.is_finite() {
        tr * tr / f
    } else {
        1.0
    }
}

fn finite(m: MatRef<f64>) -> bool {
    (0..m.ncols()).all(|j| (0..m.nrows()).all(|i| m[(i, j)].is_finite()))
}

impl Energy {
    /// Assembles E for X (`x`, k_X eigenpairs) and Y (`y`, k_Y): checks sizes (same q on both
    /// sides, operators k × k and present whenever their weight is > 0) and finiteness, and
    /// computes the scales and the mask.
    pub fn new(
        x: &SpectralSide,
        y: &SpectralSide,
        w: &EnergyWeights,
        mask: Mask,
        orientation: Orientation,
    ) -> Result<Energy> {
        let (kx, ky, q) = (x.coefficients.nrows(), y.coefficients.nrows(), x.coefficients.ncols());
        for (name, v) in [
            ("descriptor weight", w.descriptors),
            ("Laplacian weight", w.laplacian),
            ("commutativity weight", w.commutativity),
            ("orientation weight", w.orientation),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::invalid(name, format!("must be finite and ≥ 0, got {v}")));
            }
        }
        if kx == 0 || ky == 0 {
            return Err(Error::invalid("energy", "empty basis"));
        }
        if y.coefficients.ncols() != q || q == 0 {
            return Err(Error::invalid(
                "data",
                format!("{q} functions on X and {} on Y; they must correspond (q ≥ 1)", y.coefficients.ncols()),
            ));
        }
        if x.eigenvalues.len() != kx || y.eigenvalues.len() != ky {
            return Err(Error::invalid("energy", "eigenvalue counts differ from the coefficient rows"));
        }
        if !finite(x.coefficients.as_ref()) || !finite(y.coefficients.as_ref()) {
            return Err(Error::invalid("data", "a coefficient is not finite"));
        }
        let ops_ok = |ox: &[Mat<f64>], oy: &[Mat<f64>], what: &str| -> Result<()> {
            if ox.len() != q || oy.len() != q {
                return Err(Error::invalid(
                    what,
                    format!("need {q} operators per shape, got {} and {}", ox.len(), oy.len()),
                ));
            }
            if ox.iter().any(|o| o.nrows() != kx || o.ncols() != kx || !finite(o.as_ref()))
                || oy.iter().any(|o| o.nrows() != ky || o.ncols() != ky || !finite(o.as_ref()))
            {
                return Err(Error::invalid(
                    what,
                    format!("operators must be finite, {kx} × {kx} on X and {ky} × {ky} on Y"),
                ));
            }
            Ok(())
        };
        let sigma = orientation.sign();
        let use_comm = w.commutativity > 0.0;
        let use_orient = w.orientation > 0.0 && sigma != 0.0;
        if use_comm {
            ops_ok(&x.multiplication, &y.multiplication, "multiplication operators")?;
        }
        if use_orient {
            ops_ok(&x.orientation, &y.orientation, "orientation operators")?;
        }
        // The scales: each term's mean over Haar-random orthogonal maps C (k = min(k_X, k_Y)),
        // the descriptor terms per effective descriptor (see the module docs).
        let k = kx.min(ky) as f64;
        let p_eff = effective_descriptors(x.coefficients.as_ref()).max(effective_descriptors(y.coefficients.as_ref()));
        let ops_scale = |ox: &[Mat<f64>], oy: &[Mat<f64>]| {
            let s: f64 = ox
                .iter()
                .zip(oy)
                .map(|(a, b)| a.squared_norm_l2() + b.squared_norm_l2() - 2.0 * trace(a) * trace(b) / k)
                .sum();
            s.max(0.0) / p_eff
        };
        let nonconstant =
            |m: &Mat<f64>| if m.nrows() > 1 { m.subrows(1, m.nrows() - 1).squared_norm_l2() } else { 0.0 };
        let s_d = (nonconstant(&x.coefficients) + nonconstant(&y.coefficients)) / p_eff;
        if !(s_d > 0.0 && s_d.is_finite()) {
            return Err(Error::invalid("data", "the descriptors have no non-constant component in the basis"));
        }
        let inv = |s: f64| if s > 0.0 && s.is_finite() { 1.0 / s } else { 0.0 };
        let s_c = if use_comm { ops_scale(&x.multiplication, &y.multiplication) } else { 0.0 };
        let s_o = if use_orient { ops_scale(&x.orientation, &y.orientation) } else { 0.0 };
        let lmax = x.eigenvalues.iter().chain(&y.eigenvalues).fold(0.0f64, |m, l| m.max(l.abs()));
        let norm = if lmax > 0.0 { lmax } else { 1.0 };
        let lx: Vec<f64> = x.eigenvalues.iter().map(|l| l / norm).collect();
        let ly: Vec<f64> = y.eigenvalues.iter().map(|l| l / norm).collect();
        if !lx.iter().chain(&ly).all(|l| l.is_finite()) {
            return Err(Error::invalid("eigenvalues", "not finite"));
        }
        let mask = match mask {
            Mask::Standard => standard_mask(&lx, &ly),
            Mask::Resolvent { gamma } => {
                if !(gamma.is_finite() && gamma > 0.0) {
                    return Err(Error::invalid("resolvent γ", format!("must be finite and > 0, got {gamma}")));
                }
                resolvent_mask(&lx, &ly, gamma)
            }
        };
        let s_l = mask.sum() / k;
        let s_l = if s_l > 0.0 { s_l } else { 1.0 };
        Ok(Energy {
            a: x.coefficients.clone(),
            b: y.coefficients.clone(),
            mask,
            dx: if use_comm { x.multiplication.clone() } else { vec![] },
            dy: if use_comm { y.multiplication.clone() } else { vec![] },
            ox: if use_orient { x.orientation.clone() } else { vec![] },
            oy: if use_orient { y.orientation.clone() } else { vec![] },
            sigma,
            inv_scale: [1.0 / s_d, 1.0 / s_l, inv(s_c), inv(s_o)],
            eff: [w.descriptors / s_d, w.laplacian / s_l, w.commutativity * inv(s_c), w.orientation * inv(s_o)],
        })
    }

    /// k_Y (rows of C).
    pub fn k_y(&self) -> usize {
        self.b.nrows()
    }

    /// k_X (columns of C).
    pub fn k_x(&self) -> usize {
        self.a.nrows()
    }

    /// The four terms at C (k_Y × k_X), each divided by its scale (not weighted; 0 for a term
    /// that is off).
    pub fn terms(&self, c: MatRef<f64>) -> EnergyTerms {
        let [sd, sl, sc, so] = self.inv_scale;
        EnergyTerms {
            descriptors: descriptor_preservation(c, self.a.as_ref(), self.b.as_ref()) * sd,
            laplacian: laplacian_commutativity(c, self.mask.as_ref()) * sl,
            commutativity: operator_commutativity(c, &self.dx, &self.dy, 1.0) * sc,
            orientation: operator_commutativity(c, &self.ox, &self.oy, self.sigma) * so,
        }
    }

    /// E(C).
    pub fn value(&self, c: MatRef<f64>) -> f64 {
        let [wd, wl, wc, wo] = self.eff;
        let mut e = wd * descriptor_preservation(c, self.a.as_ref(), self.b.as_ref());
        e += wl * laplacian_commutativity(c, self.mask.as_ref());
        if wc > 0.0 {
            e += wc * operator_commutativity(c, &self.dx, &self.dy, 1.0);
        }
        if wo > 0.0 {
            e += wo * operator_commutativity(c, &self.ox, &self.oy, self.sigma);
        }
        e
    }

    /// ∇E(C) (k_Y × k_X).
    pub fn gradient(&self, c: MatRef<f64>) -> Mat<f64> {
        let [wd, wl, wc, wo] = self.eff;
        let mut g = descriptor_preservation_gradient(c, self.a.as_ref(), self.b.as_ref()) * wd;
        g += laplacian_commutativity_gradient(c, self.mask.as_ref()) * wl;
        if wc > 0.0 {
            g += operator_commutativity_gradient(c, &self.dx, &self.dy, 1.0) * wc;
        }
        if wo > 0.0 {
            g += operator_commutativity_gradient(c, &self.ox, &self.oy, self.sigma) * wo;
        }
        g
    }

    /// The Hessian H / 2 (K × K, K = k_X k_Y, column-major vec of C: entry C_ij at i + j k_Y) and
    /// the right-hand side, so that E(C) = cᵀ H c / 2 ... = vec(C)ᵀ H vec(C) − 2 rhsᵀ vec(C) + const.
    fn normal_equations(&self) -> (Mat<f64>, Vec<f64>) {
        use rayon::prelude::*;
        let (kx, ky) = (self.k_x(), self.k_y());
        let kk = kx * ky;
        let [wd, wl, wc, wo] = self.eff;
        let aat = mul(self.a.as_ref(), self.a.transpose());
        // Operator terms: Σ_p (X Xᵀ ⊗ I + I ⊗ YᵀY − σ (X ⊗ Y + (X ⊗ Y)ᵀ)), with
        // (X ⊗ Y)[(i + j ky), (i' + j' ky)] = X[j, j'] Y[i, i'] and its transpose X[j', j] Y[i', i].
        // The Kronecker sums of every term come from one product per column block j' of H:
        // S_j' = R Lᵀ_j' (k_Y² × k_X), S_j'[(i + i' ky), j] = Σ_(term, p) wσ (X_p[j, j'] Y_p[i, i']
        // + X_p[j', j] Y_p[i', i]), with L's rows (j + j' kx) holding wσ X_p[j, j'] and wσ X_p[j', j]
        // and R's rows (i + i' ky) holding Y_p[i, i'] and Y_p[i', i], over all p of all terms.
        // No k_X² × k_Y² matrix beside H is held (at k = 50 it would be another 50 MB per fit).
        let terms: Vec<_> = [(wc, &self.dx[..], &self.dy[..], 1.0), (wo, &self.ox[..], &self.oy[..], self.sigma)]
            .into_iter()
            .filter(|(w, ox, _, _)| *w != 0.0 && !ox.is_empty())
            .collect();
        let mut xx = Mat::<f64>::zeros(kx, kx);
        let mut yy = Mat::<f64>::zeros(ky, ky);
        for &(w, ox, oy, _) in &terms {
            for (x, y) in ox.iter().zip(oy.iter()) {
                matmul(xx.as_mut(), Accum::Add, x.as_ref(), x.transpose(), w, Par::Seq);
                matmul(yy.as_mut(), Accum::Add, y.transpose(), y.as_ref(), w, Par::Seq);
            }
        }
        let inner: usize = terms.iter().map(|t| 2 * t.1.len()).sum();
        let mut l = Mat::<f64>::zeros(kx * kx, inner);
        let mut r = Mat::<f64>::zeros(ky * ky, inner);
        let mut at = 0;
        for &(w, ox, oy, sigma) in &terms {
            for (x, y) in ox.iter().zip(oy.iter()) {
                for jp in 0..kx {
                    for j in 0..kx {
                        l[(j + jp * kx, at)] = w * sigma * x[(j, jp)];
                        l[(j + jp * kx, at + 1)] = w * sigma * x[(jp, j)];
                    }
                }
                for ip in 0..ky {
                    for i in 0..ky {
                        r[(i + ip * ky, at)] = y[(i, ip)];
                        r[(i + ip * ky, at + 1)] = y[(ip, i)];
                    }
                }
                at += 2;
            }
        }
        let mut h = Mat::<f64>::zeros(kk, kk);
        h.as_mut().par_col_chunks_mut(ky).enumerate().for_each_init(
            || Mat::<f64>::zeros(ky * ky, kx),
            |sum, (jp, mut block)| {
                if inner > 0 {
                    let lj = l.as_ref().subrows(jp * kx, kx);
                    matmul(sum.as_mut(), Accum::Replace, r.as_ref(), lj.transpose(), 1.0, Par::Seq);
                }
                for ip in 0..ky {
                    let col =
                        block.as_mut().col_mut(ip).try_as_col_major_mut().expect("contiguous column").as_slice_mut();
                    for j in 0..kx {
                        let run = &mut col[j * ky..(j + 1) * ky];
                        if inner > 0 {
                            let s = &sum.col_as_slice(j)[ip * ky..(ip + 1) * ky];
                            run.iter_mut().zip(s).for_each(|(h, &v)| *h = -v);
                        }
                        // Data wd (Â Âᵀ ⊗ I) and the terms' X Xᵀ ⊗ I: on the diagonal of each
                        // ky × ky block.
                        run[ip] += wd * aat[(j, jp)] + xx[(j, jp)];
                    }
                    // The terms' I ⊗ YᵀY: the diagonal block j = j'.
                    for i in 0..ky {
                        col[i + jp * ky] += yy[(i, ip)];
                    }
                    // Laplacian: wl diag(vec M).
                    col[ip + jp * ky] += wl * self.mask[(ip, jp)];
                }
            },
        );
        let bat = mul(self.b.as_ref(), self.a.transpose());
        let rhs = (0..kk).map(|t| wd * bat[(t % ky, t / ky)]).collect();
        (h, rhs)
    }

    /// The exact minimizer of E: vec(C) = H⁻¹ rhs by Cholesky, H the Hessian / 2 (see the module
    /// docs); when H is singular (no Laplacian term and rank-deficient data), the minimum-norm
    /// solution from the symmetric eigendecomposition. The relative residual of the normal
    /// equations is checked (≤ 1e-8).
    pub fn solve(&self) -> Result<Mat<f64>> {
        let (kx, ky) = (self.k_x(), self.k_y());
        let (mut h, rhs) = self.normal_equations();
        // H x − rhs = ∇E(C) / 2 (E = xᵀ H x − 2 rhsᵀ x + const): the residual from the terms'
        // gradients, so H need not outlive its factorization.
        let residual = |x: &[f64]| -> Vec<f64> {
            let g = self.gradient(Mat::from_fn(ky, kx, |i, j| x[i + j * ky]).as_ref());
            (0..kx * ky).map(|t| 0.5 * g[(t % ky, t / ky)]).collect()
        };
        let x = solve_symmetric(h.as_mut(), &rhs, residual, || self.normal_equations().0)?;
        Ok(Mat::from_fn(ky, kx, |i, j| x[i + j * ky]))
    }

    /// The minimizer of E over the C whose first column is `first` (length k_Y), e.g. the column
    /// mapping the constant function on X to the constant on Y: the free entries solve
    /// H_ff c_f = rhs_f − H_f1 `first`.
    pub fn solve_with_first_column(&self, first: &[f64]) -> Result<Mat<f64>> {
        let (kx, ky) = (self.k_x(), self.k_y());
        if first.len() != ky || !first.iter().all(|v| v.is_finite()) {
            return Err(Error::invalid("first column", format!("need {ky} finite values, got {}", first.len())));
        }
        if kx == 1 {
            return Ok(Mat::from_fn(ky, 1, |i, _| first[i]));
        }
        let (mut h, rhs) = self.normal_equations();
        let kk = kx * ky;
        let nf = kk - ky;
        let b: Vec<f64> =
            (0..nf).map(|t| rhs[ky + t] - (0..ky).map(|i| h[(ky + t, i)] * first[i]).sum::<f64>()).collect();
        // H_ff x_f − b_f = (H x − rhs)_f = (∇E(C) / 2)_f with C = [first, x_f].
        let full = |x: &[f64]| Mat::from_fn(ky, kx, |i, j| if j == 0 { first[i] } else { x[i + (j - 1) * ky] });
        let residual = |x: &[f64]| -> Vec<f64> {
            let g = self.gradient(full(x).as_ref());
            (0..nf).map(|t| 0.5 * g[(t % ky, 1 + t / ky)]).collect()
        };
        let rebuild = || self.normal_equations().0.submatrix(ky, ky, nf, nf).to_owned();
        let x = solve_symmetric(h.as_mut().submatrix_mut(ky, ky, nf, nf), &b, residual, rebuild)?;
        Ok(full(&x))
    }
}

/// x = H⁻¹ b for a symmetric positive semi-definite H (overwritten: factored in place by
/// Cholesky, so no copy of H is made), or, when H is singular, the minimum-norm solution from the
/// eigendecomposition of H built again by `rebuild`. `residual(x)` = H x − b, from which the
/// relative residual is checked (≤ 1e-8).
fn solve_symmetric(
    mut h: MatMut<f64>,
    rhs: &[f64],
    residual: impl Fn(&[f64]) -> Vec<f64>,
    rebuild: impl FnOnce() -> Mat<f64>,
) -> Result<Vec<f64>> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::cholesky::llt;
    let kk = h.nrows();
    let mut x = Mat::from_fn(kk, 1, |i, _| rhs[i]);
    let par = faer::get_global_parallelism();
    let mut buf = MemBuffer::new(llt::factor::cholesky_in_place_scratch::<f64>(kk, par, Default::default()));
    let factored = llt::factor::cholesky_in_place(
        h.as_mut(),
        Default::default(),
        par,
        MemStack::new(&mut buf),
        Default::default(),
    );
    if factored.is_ok() {
        llt::solve::solve_in_place(h.as_ref(), x.as_mut(), par, MemStack::new(&mut buf));
    } else {
        x = crate::linalg::min_norm_solve(rebuild().as_ref(), x.as_ref(), "functional map")?;
    }
    let out: Vec<f64> = x.col(0).iter().copied().collect();
    if !out.iter().all(|v| v.is_finite()) {
        return Err(Error::numerical("functional map", "the solution is not finite"));
    }
    let r = residual(&out);
    let res = r.iter().map(|v| v * v).sum::<f64>().sqrt();
    let b = rhs.iter().map(|v| v * v).sum::<f64>().sqrt();
    let hx = r.iter().zip(rhs).map(|(a, c)| (a + c) * (a + c)).sum::<f64>().sqrt();
    let scale = b.max(hx).max(f64::MIN_POSITIVE);
    if res.is_nan() || res > 1e-8 * scale {
        return Err(Error::numerical(
            "functional map",
            format!("normal equations solved to relative residual {:.1e}", res / scale),
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spectral::Normal;

    fn random(r: usize, c: usize, rng: &mut Normal) -> Mat<f64> {
        Mat::from_fn(r, c, |_, _| rng.sample())
    }

    fn side(k: usize, q: usize, rng: &mut Normal) -> SpectralSide {
        let mut ev: Vec<f64> = (0..k).map(|i| i as f64 * (1.0 + 0.1 * rng.sample().abs())).collect();
        ev.sort_by(f64::total_cmp);
        SpectralSide {
            coefficients: random(k, q, rng),
            eigenvalues: ev,
            multiplication: (0..q)
                .map(|_| {
                    let m = random(k, k, rng);
                    &m + m.transpose()
                })
                .collect(),
            orientation: (0..q)
                .map(|_| {
                    let m = random(k, k, rng);
                    &m - m.transpose()
                })
                .collect(),
        }
    }

    /// Central differences of f along a random direction against ⟨∇f, direction⟩.
    fn check_gradient(
        f: &dyn Fn(MatRef<f64>) -> f64,
        g: &dyn Fn(MatRef<f64>) -> Mat<f64>,
        c: &Mat<f64>,
        rng: &mut Normal,
    ) {
        for _ in 0..3 {
            let d = random(c.nrows(), c.ncols(), rng);
            let h = 1e-6;
            let fd = (f((c + &d * h).as_ref()) - f((c - &d * h).as_ref())) / (2.0 * h);
            let gr = g(c.as_ref());
            let an: f64 = (0..c.ncols()).map(|j| (0..c.nrows()).map(|i| gr[(i, j)] * d[(i, j)]).sum::<f64>()).sum();
            assert!((fd - an).abs() <= 1e-6 * (1.0 + an.abs()), "finite difference {fd} vs gradient {an}");
        }
    }

    #[test]
    fn term_gradients_match_finite_differences() {
        let mut rng = Normal::new(5);
        let (kx, ky, q) = (6, 5, 4);
        let (x, y) = (side(kx, q, &mut rng), side(ky, q, &mut rng));
        let c = random(ky, kx, &mut rng);
        let (a, b) = (x.coefficients.as_ref(), y.coefficients.as_ref());
        check_gradient(
            &|c| descriptor_preservation(c, a, b),
            &|c| descriptor_preservation_gradient(c, a, b),
            &c,
            &mut rng,
        );
        for mask in [standard_mask(&x.eigenvalues, &y.eigenvalues), resolvent_mask(&x.eigenvalues, &y.eigenvalues, 0.5)]
        {
            let m = mask.as_ref();
            check_gradient(
                &|c| laplacian_commutativity(c, m),
                &|c| laplacian_commutativity_gradient(c, m),
                &c,
                &mut rng,
            );
        }
        for sigma in [1.0, -1.0] {
            let (ox, oy) = (&x.orientation, &y.orientation);
            check_gradient(
                &|c| operator_commutativity(c, ox, oy, sigma),
                &|c| operator_commutativity_gradient(c, ox, oy, sigma),
                &c,
                &mut rng,
            );
        }
        let (dx, dy) = (&x.multiplication, &y.multiplication);
        check_gradient(
            &|c| operator_commutativity(c, dx, dy, 1.0),
            &|c| operator_commutativity_gradient(c, dx, dy, 1.0),
            &c,
            &mut rng,
        );
        // The whole energy.
        let w = EnergyWeights { descriptors: 1.0, laplacian: 0.3, commutativity: 0.5, orientation: 0.7 };
        for o in [Orientation::Preserve, Orientation::Reverse] {
            let e = Energy::new(&x, &y, &w, Mask::Resolvent { gamma: 0.5 }, o).unwrap();
            check_gradient(&|c| e.value(c), &|c| e.gradient(c), &c, &mut rng);
        }
    }

    #[test]
    fn closed_form_is_the_minimizer() {
        let mut rng = Normal::new(9);
        let (kx, ky, q) = (7, 6, 5);
        let (x, y) = (side(kx, q, &mut rng), side(ky, q, &mut rng));
        let w = EnergyWeights { descriptors: 1.0, laplacian: 0.1, commutativity: 0.2, orientation: 0.4 };
        for (mask, o) in [
            (Mask::Standard, Orientation::Ignore),
            (Mask::Resolvent { gamma: 0.5 }, Orientation::Preserve),
            (Mask::Resolvent { gamma: 0.5 }, Orientation::Reverse),
        ] {
            let e = Energy::new(&x, &y, &w, mask, o).unwrap();
            let c = e.solve().unwrap();
            let g = e.gradient(c.as_ref());
            let g0 = e.gradient(Mat::<f64>::zeros(ky, kx).as_ref());
            assert!(
                g.norm_l2() < 1e-9 * g0.norm_l2(),
                "gradient at the solution {} (at 0: {})",
                g.norm_l2(),
                g0.norm_l2()
            );
            // Any perturbation increases E.
            for _ in 0..5 {
                let d = random(ky, kx, &mut rng) * 1e-3;
                assert!(e.value((&c + &d).as_ref()) >= e.value(c.as_ref()));
            }
        }
    }

    #[test]
    fn constrained_solution_is_stationary_in_the_free_entries() {
        let mut rng = Normal::new(4);
        let (kx, ky, q) = (5, 5, 4);
        let (x, y) = (side(kx, q, &mut rng), side(ky, q, &mut rng));
        let w = EnergyWeights { descriptors: 1.0, laplacian: 0.1, commutativity: 0.2, orientation: 0.4 };
        let e = Energy::new(&x, &y, &w, Mask::Resolvent { gamma: 0.5 }, Orientation::Preserve).unwrap();
        let first = [0.9, 0.0, 0.1, 0.0, -0.2];
        let c = e.solve_with_first_column(&first).unwrap();
        let g = e.gradient(c.as_ref());
        for i in 0..ky {
            assert_eq!(c[(i, 0)], first[i]);
        }
        let free = g.subcols(1, kx - 1).norm_l2();
        assert!(free < 1e-9 * g.norm_l2().max(1.0), "free gradient {free}");
    }

    /// Descriptors alone, with a basis function of X that no descriptor has (a zero row of Â):
    /// H = Â Âᵀ ⊗ I has an exactly zero pivot, the in-place Cholesky factorization fails, and the
    /// solution is the minimum-norm one, C = B̂ (ÂᵀÂ)⁻¹ Âᵀ, from the eigendecomposition of H
    /// built again (the failed factorization has overwritten the first one).
    #[test]
    fn singular_system_gives_the_minimum_norm_solution() {
        let mut rng = Normal::new(11);
        let (kx, ky, q) = (5, 4, 4);
        let (mut x, y) = (side(kx, q, &mut rng), side(ky, q, &mut rng));
        for p in 0..q {
            x.coefficients[(kx - 1, p)] = 0.0;
        }
        let w = EnergyWeights { descriptors: 1.0, laplacian: 0.0, commutativity: 0.0, orientation: 0.0 };
        let e = Energy::new(&x, &y, &w, Mask::Standard, Orientation::Ignore).unwrap();
        let c = e.solve().unwrap();
        let (a, b) = (x.coefficients.as_ref(), y.coefficients.as_ref());
        let ata = mul(a.transpose(), a);
        let inv = {
            use faer::linalg::solvers::DenseSolveCore;
            ata.as_ref().llt(faer::Side::Lower).unwrap().inverse()
        };
        let expected = mul(mul(b, inv.as_ref()).as_ref(), a.transpose());
        let diff = (&c - &expected).norm_l2();
        assert!(diff < 1e-8 * expected.norm_l2(), "‖C − B̂ Â⁺‖ = {diff}");
    }

    #[test]
    fn masks() {
        let lx = [0.0, 0.2, 0.5, 1.0];
        let ly = [0.0, 0.25, 0.5, 0.9];
        let s = standard_mask(&lx, &ly);
        let r = resolvent_mask(&lx, &ly, 0.5);
        for i in 0..4 {
            assert_eq!(s[(i, i)], (ly[i] - lx[i]).powi(2));
        }
        assert_eq!(r[(2, 2)], 0.0);
        assert!(r[(0, 3)] > 0.0 && s[(0, 3)] == 1.0);
        // |R(0) − R(1)|² with R(λ) = (λ^γ + i)/(λ^{2γ} + 1): R(0) = i, R(1) = (1 + i)/2.
        assert!((r[(0, 3)] - 0.5).abs() < 1e-15);
    }

    #[test]
    fn bad_inputs_are_errors() {
        let mut rng = Normal::new(2);
        let (x, y) = (side(4, 3, &mut rng), side(4, 2, &mut rng));
        let w = EnergyWeights { descriptors: 1.0, laplacian: 0.1, commutativity: 1.0, orientation: 1.0 };
        assert!(Energy::new(&x, &y, &w, Mask::Standard, Orientation::Preserve).is_err());
        let y = side(4, 3, &mut rng);
        let bad = EnergyWeights { laplacian: -1.0, ..w };
        assert!(Energy::new(&x, &y, &bad, Mask::Standard, Orientation::Preserve).is_err());
        let mut y2 = y.clone();
        y2.orientation.pop();
        assert!(Energy::new(&x, &y2, &w, Mask::Standard, Orientation::Preserve).is_err());
        // Not needed when ignored.
        assert!(Energy::new(&x, &y2, &w, Mask::Standard, Orientation::Ignore).is_ok());
        assert!(Energy::new(&x, &y, &w, Mask::Resolvent { gamma: f64::NAN }, Orientation::Preserve).is_err());
    }
}
