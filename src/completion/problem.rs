//! The fixed data of problem (11) ([`Problem`]: truncated bases, eigenvalues, data coefficients,
//! Gram matrices and the optional L1 samples and prior) and how its terms are normalized
//! ([`Scaling`]); every solver of [`crate::completion`] reads it.

use faer::{Mat, MatRef};
use serde::{Deserialize, Serialize};

use super::gemm_tn;
use super::l1::Weights;
use crate::descriptors::Descriptors;
use crate::error::{Error, Result};
use crate::spatial::Samples;
use crate::spectral::Basis;

/// How the terms of (11) are normalized ([`crate::completion`] module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Scaling {
    /// The paper's (11) as written, with mass-weighted data coefficients: raw eigenvalues, L1
    /// over the m × n matrix Ψ C Φᵀ of the mass-orthonormal bases, Euclidean low norm.
    Paper,
    /// Scale-free: both shapes rescaled to unit area, the data term relative to the data's
    /// energy, Dirichlet energies relative to that of an orthonormal map, the L1 term the
    /// integral ∫∫|t(y, x)| dy dx of the correspondence kernel, the low norm per rank.
    #[default]
    Unit,
}

/// The fixed data of problem (11): truncated bases, eigenvalues, data coefficients and Gram
/// matrices, normalized according to a [`Scaling`].
#[derive(Clone, Debug)]
pub struct Problem {
    /// The normalization of the terms.
    pub scaling: Scaling,
    /// Φ_k' (n × k'); with [`Scaling::Unit`] multiplied by √area(X) (unit-area mass-orthonormal).
    pub phi: Mat<f64>,
    /// Ψ_k' (m × k'); with [`Scaling::Unit`] multiplied by √area(Y).
    pub psi: Mat<f64>,
    /// Weights of the Dirichlet term on X (k'): λ^X_j ([`Scaling::Paper`]) or λ^X_j / Σ_l λ^X_l.
    pub lambda_x: Vec<f64>,
    /// Weights of the Dirichlet term on Y (k'), as `lambda_x`.
    pub lambda_y: Vec<f64>,
    /// The eigenvalues of X (k', in the units of the input basis), for the commutativity term.
    pub eigenvalues_x: Vec<f64>,
    /// The eigenvalues of Y (k').
    pub eigenvalues_y: Vec<f64>,
    /// Â = Φ_k'ᵀ A_X F (k' × q); with [`Scaling::Unit`] in unit-area units and divided by √s,
    /// s = (‖F‖²_{A_X} + ‖G‖²_{A_Y}) / 2 (unit areas), so the data term is a relative residual.
    pub f_hat: Mat<f64>,
    /// B̂ = Ψ_k'ᵀ A_Y G (k' × q), normalized as `f_hat`.
    pub g_hat: Mat<f64>,
    /// Φ_k'ᵀ Φ_k' (k' × k'), for the Euclidean low-norm term ([`Scaling::Paper`]).
    pub gram_x: Mat<f64>,
    /// Ψ_k'ᵀ Ψ_k' (k' × k').
    pub gram_y: Mat<f64>,
    /// Weights w^X (n) of the entries of T in the L1 term: the unit-area vertex areas
    /// ([`Scaling::Unit`]); `None` for unweighted.
    pub l1_weights_x: Option<Vec<f64>>,
    /// Weights w^Y (m), as `l1_weights_x`.
    pub l1_weights_y: Option<Vec<f64>>,
    /// The factor from this problem's C = A Bᵀ to the functional map between the input bases:
    /// C_bases = `c_scale` · C, with `c_scale` = √(area(Y) / area(X)) ([`Scaling::Unit`]) or 1.
    pub c_scale: f64,
    /// The optional axiomatic prior's energy ([`super::terms::prior`], weight
    /// [`super::CompletionParams::mu_prior`]): E of [`crate::fmap::energy`] on the leading k_c × k_c block
    /// of the functional map between the input bases (k_c ≤ k'); set with [`Problem::with_prior`].
    pub prior: Option<crate::fmap::energy::Energy>,
    /// Σ A_X, the area of X in the input units (1 for [`Problem::from_coefficients`]).
    pub area_x: f64,
    /// Σ A_Y, the area of Y in the input units.
    pub area_y: f64,
    /// The vertex samples the L1 term is evaluated on instead of every pair of vertices
    /// ([`Problem::with_l1_samples`]); `None`: the full m × n sum.
    pub l1_sample: Option<L1Sample>,
}

/// Vertex samples of X and Y with quadrature weights on which the L1 term of (11) is evaluated:
/// Σ_{s ∈ S_Y} Σ_{r ∈ S_X} w^Y_s w^X_r √(t_sr² + ξ) in place of the full Σ_ji w_ji √(t_ji² + ξ),
/// i.e. the m × n matrix T replaced by its s_Y × s_X submatrix Ψ_S C Φ_Sᵀ. The cost of the term
/// falls by (m n) / (s_Y s_X); everything else in (11) is unchanged.
#[derive(Clone, Debug)]
pub struct L1Sample {
    /// The rows of Φ_k' at the samples of X (s_X × k').
    pub phi: Mat<f64>,
    /// The rows of Ψ_k' at the samples of Y (s_Y × k').
    pub psi: Mat<f64>,
    /// Quadrature weights of the samples of X (s_X), in the units of the full term's weights.
    pub weights_x: Vec<f64>,
    /// Quadrature weights of the samples of Y (s_Y).
    pub weights_y: Vec<f64>,
}

fn area(mass: &[f64]) -> f64 {
    mass.iter().sum()
}

impl Problem {
    /// Problem (11) for shapes with bases `x`, `y` and data `f` (n × q on X), `g` (m × q on Y),
    /// using the first `k_prime` eigenpairs of each basis, normalized by `scaling`.
    ///
    /// Errors: F and G with different column counts, F or G whose row count is not the vertex
    /// count of its basis, non-finite data, `k_prime` = 0, more than either basis holds, or not
    /// below the number of vertices.
    pub fn new(
        x: &Basis,
        y: &Basis,
        f: &Descriptors,
        g: &Descriptors,
        k_prime: usize,
        scaling: Scaling,
    ) -> Result<Problem> {
        if f.q() != g.q() {
            return Err(Error::invalid(
                "data",
                format!("F has {} columns but G has {}; the data must correspond column by column", f.q(), g.q()),
            ));
        }
        if f.n() != x.n() || g.n() != y.n() {
            return Err(Error::invalid(
                "data",
                format!(
                    "F has {} rows for {} vertices of X, G has {} rows for {} vertices of Y",
                    f.n(),
                    x.n(),
                    g.n(),
                    y.n()
                ),
            ));
        }
        if k_prime == 0 || k_prime > x.k() || k_prime > y.k() {
            return Err(Error::invalid(
                "k'",
                format!("k' = {k_prime} but the bases hold {} (X) and {} (Y) eigenfunctions", x.k(), y.k()),
            ));
        }
        if k_prime >= x.n() || k_prime >= y.n() {
            return Err(Error::invalid(
                "k'",
                format!("k' = {k_prime} must be below the vertex counts ({} and {})", x.n(), y.n()),
            ));
        }
        let finite = |d: &Descriptors| (0..d.q()).all(|j| (0..d.n()).all(|i| d.values[(i, j)].is_finite()));
        if !finite(f) || !finite(g) {
            return Err(Error::invalid("data", "F or G contains a non-finite value"));
        }
        let (area_x, area_y) = (area(&x.mass), area(&y.mass));
        if !(area_x > 0.0 && area_y > 0.0 && area_x.is_finite() && area_y.is_finite()) {
            return Err(Error::invalid("bases", "the vertex weights must have a positive, finite sum"));
        }
        let (sx, sy) = match scaling {
            Scaling::Paper => (1.0, 1.0),
            Scaling::Unit => (area_x.sqrt(), area_y.sqrt()),
        };
        let phi = Mat::from_fn(x.n(), k_prime, |i, j| sx * x.eigenvectors[(i, j)]);
        let psi = Mat::from_fn(y.n(), k_prime, |i, j| sy * y.eigenvectors[(i, j)]);
        // Mass of the (rescaled) shapes: a / area for Unit.
        let (mx, my): (Vec<f64>, Vec<f64>) = match scaling {
            Scaling::Paper => (x.mass.clone(), y.mass.clone()),
            Scaling::Unit => (x.mass.iter().map(|a| a / area_x).collect(), y.mass.iter().map(|a| a / area_y).collect()),
        };
        let weighted = |d: &Descriptors, mass: &[f64]| Mat::from_fn(d.n(), d.q(), |i, j| mass[i] * d.values[(i, j)]);
        let mut f_hat = gemm_tn(phi.as_ref(), weighted(f, &mx).as_ref());
        let mut g_hat = gemm_tn(psi.as_ref(), weighted(g, &my).as_ref());
        let (lambda_x, lambda_y) = match scaling {
            Scaling::Paper => (x.eigenvalues[..k_prime].to_vec(), y.eigenvalues[..k_prime].to_vec()),
            Scaling::Unit => {
                let rel = |l: &[f64]| {
                    let s: f64 = l.iter().sum();
                    l.iter().map(|v| if s > 0.0 { v / s } else { 0.0 }).collect::<Vec<f64>>()
                };
                (rel(&x.eigenvalues[..k_prime]), rel(&y.eigenvalues[..k_prime]))
            }
        };
        let (mut l1_weights_x, mut l1_weights_y, mut c_scale) = (None, None, 1.0);
        if scaling == Scaling::Unit {
            let energy = |d: &Descriptors, mass: &[f64]| {
                (0..d.q()).map(|j| (0..d.n()).map(|i| mass[i] * d.values[(i, j)].powi(2)).sum::<f64>()).sum::<f64>()
            };
            let s = 0.5 * (energy(f, &mx) + energy(g, &my));
            if !(s > 0.0 && s.is_finite()) {
                return Err(Error::invalid("data", "F and G are zero; there is nothing to match"));
            }
            f_hat *= faer::Scale(1.0 / s.sqrt());
            g_hat *= faer::Scale(1.0 / s.sqrt());
            l1_weights_x = Some(mx);
            l1_weights_y = Some(my);
            c_scale = (area_y / area_x).sqrt();
        }
        let mut p = Problem::from_coefficients(phi, psi, lambda_x, lambda_y, f_hat, g_hat)?;
        p.scaling = scaling;
        p.eigenvalues_x = x.eigenvalues[..k_prime].to_vec();
        p.eigenvalues_y = y.eigenvalues[..k_prime].to_vec();
        p.l1_weights_x = l1_weights_x;
        p.l1_weights_y = l1_weights_y;
        p.c_scale = c_scale;
        (p.area_x, p.area_y) = (area_x, area_y);
        Ok(p)
    }

    /// A problem from its parts directly (any bases, e.g. random ones in tests), with
    /// [`Scaling::Paper`] and `lambda_*` used both as Dirichlet weights and eigenvalues; computes
    /// the Gram matrices. `f_hat`, `g_hat` are the k' × q coefficient matrices.
    pub fn from_coefficients(
        phi: Mat<f64>,
        psi: Mat<f64>,
        lambda_x: Vec<f64>,
        lambda_y: Vec<f64>,
        f_hat: Mat<f64>,
        g_hat: Mat<f64>,
    ) -> Result<Problem> {
        let kp = phi.ncols();
        if psi.ncols() != kp || lambda_x.len() != kp || lambda_y.len() != kp {
            return Err(Error::invalid(
                "bases",
                format!(
                    "Φ has {kp} columns, Ψ {}, Λ_X {} and Λ_Y {} entries; all must be k'",
                    psi.ncols(),
                    lambda_x.len(),
                    lambda_y.len()
                ),
            ));
        }
        if f_hat.nrows() != kp || g_hat.nrows() != kp || f_hat.ncols() != g_hat.ncols() {
            return Err(Error::invalid(
                "data",
                format!(
                    "coefficients are {}×{} and {}×{}; both must be k'×q with k' = {kp}",
                    f_hat.nrows(),
                    f_hat.ncols(),
                    g_hat.nrows(),
                    g_hat.ncols()
                ),
            ));
        }
        let gram_x = gemm_tn(phi.as_ref(), phi.as_ref());
        let gram_y = gemm_tn(psi.as_ref(), psi.as_ref());
        Ok(Problem {
            scaling: Scaling::Paper,
            phi,
            psi,
            eigenvalues_x: lambda_x.clone(),
            eigenvalues_y: lambda_y.clone(),
            lambda_x,
            lambda_y,
            f_hat,
            g_hat,
            gram_x,
            gram_y,
            l1_weights_x: None,
            l1_weights_y: None,
            c_scale: 1.0,
            prior: None,
            area_x: 1.0,
            area_y: 1.0,
            l1_sample: None,
        })
    }

    /// This problem with the axiomatic prior `energy` (k_c × k_c, built on the same input bases).
    /// Errors: a non-square energy or one larger than k'.
    pub fn with_prior(mut self, energy: crate::fmap::energy::Energy) -> Result<Problem> {
        let kc = energy.k_x();
        if energy.k_y() != kc || kc == 0 || kc > self.k_prime() {
            return Err(Error::invalid(
                "prior",
                format!(
                    "the prior's map must be square and at most k' = {} (got {} × {})",
                    self.k_prime(),
                    energy.k_y(),
                    kc
                ),
            ));
        }
        self.prior = Some(energy);
        Ok(self)
    }

    /// This problem with its L1 term evaluated on the vertex samples `x` of X and `y` of Y
    /// ([`L1Sample`]) instead of on all n · m pairs. The samples' weights stand for vertex areas
    /// (as [`Samples`] from [`crate::spatial::farthest_point_samples`], Voronoi cells, or
    /// [`Samples::random`], unbiased draws) and are normalized here as the full term's weights:
    /// divided by the shape's area ([`Scaling::Unit`], where the full weights are the unit-area
    /// vertex areas). With farthest-point samples the sampled term is a quadrature of the integral
    /// ∫∫ √(t² + ξ) dy dx; with random samples its expectation is the full term
    /// (test `sampled_l1_is_unbiased`).
    ///
    /// Errors: [`Scaling::Paper`] (its L1 term is an unweighted count of entries, not an
    /// integral), empty samples, a vertex id out of range, a negative or non-finite weight.
    pub fn with_l1_samples(mut self, x: &Samples, y: &Samples) -> Result<Problem> {
        let (Some(wx), Some(wy)) = (&self.l1_weights_x, &self.l1_weights_y) else {
            return Err(Error::invalid(
                "L1 samples",
                "sampling the L1 term needs the scale-free weights (scaling unit), not the paper's literal sum",
            ));
        };
        let check = |s: &Samples, n: usize, shape: &str| -> Result<()> {
            if s.is_empty() || s.weights.len() != s.len() {
                return Err(Error::invalid(
                    "L1 samples",
                    format!("{shape}: {} samples with {} weights", s.len(), s.weights.len()),
                ));
            }
            if let Some(v) = s.vertices.iter().find(|&&v| v >= n) {
                return Err(Error::invalid("L1 samples", format!("{shape}: vertex {v} out of range (n = {n})")));
            }
            if s.weights.iter().any(|w| !(w.is_finite() && *w >= 0.0)) {
                return Err(Error::invalid("L1 samples", format!("{shape}: weights must be finite and ≥ 0")));
            }
            Ok(())
        };
        check(x, self.n(), "X")?;
        check(y, self.m(), "Y")?;
        // The full weights are a / area (Σ = 1); the samples' weights are areas.
        let unit = |s: &Samples, full: &[f64], mass_total: f64| -> Vec<f64> {
            let total_full: f64 = full.iter().sum();
            s.weights.iter().map(|w| w * total_full / mass_total).collect()
        };
        let (ax, ay) = (self.area_x, self.area_y);
        let sample = L1Sample {
            phi: Mat::from_fn(x.len(), self.k_prime(), |i, j| self.phi[(x.vertices[i], j)]),
            psi: Mat::from_fn(y.len(), self.k_prime(), |i, j| self.psi[(y.vertices[i], j)]),
            weights_x: unit(x, wx, ax),
            weights_y: unit(y, wy, ay),
        };
        self.l1_sample = Some(sample);
        Ok(self)
    }

    /// The operands of the L1 term: (Φ, Ψ, weights) of the full term or of its samples.
    pub fn l1_operands(&self) -> (MatRef<'_, f64>, MatRef<'_, f64>, Option<Weights<'_>>) {
        match &self.l1_sample {
            Some(s) => (s.phi.as_ref(), s.psi.as_ref(), Some(Weights { y: &s.weights_y, x: &s.weights_x })),
            None => (self.phi.as_ref(), self.psi.as_ref(), self.l1_weights()),
        }
    }

    /// k', the number of basis functions of each shape.
    pub fn k_prime(&self) -> usize {
        self.phi.ncols()
    }

    /// n, the vertex count of X.
    pub fn n(&self) -> usize {
        self.phi.nrows()
    }

    /// m, the vertex count of Y.
    pub fn m(&self) -> usize {
        self.psi.nrows()
    }

    /// The L1 entry weights, if any.
    pub fn l1_weights(&self) -> Option<Weights<'_>> {
        match (&self.l1_weights_y, &self.l1_weights_x) {
            (Some(y), Some(x)) => Some(Weights { y, x }),
            _ => None,
        }
    }

    /// The same objective restricted to maps C supported on the leading `k` × `k` block (k ≤ k'):
    /// the problem on the first k basis functions of each shape, with every weight, sample and
    /// normalization of this one (the Dirichlet weights keep their normalization by the sum over
    /// k', so the restricted objective at C equals this one at C zero-padded to k' × k'). For
    /// the multiscale schedule of [`super::solve()`]. Errors when k is 0, above k', or below the size of
    /// the axiomatic prior.
    pub fn leading(&self, k: usize) -> Result<Problem> {
        if k == 0 || k > self.k_prime() {
            return Err(Error::invalid(
                "k",
                format!("a leading block of size {k} of a k' = {} problem", self.k_prime()),
            ));
        }
        if let Some(e) = &self.prior {
            if e.k_x() > k {
                return Err(Error::invalid("k", format!("the prior needs at least {} basis functions", e.k_x())));
            }
        }
        let sub = |m: &Mat<f64>| m.subcols(0, k).to_owned();
        Ok(Problem {
            scaling: self.scaling,
            phi: sub(&self.phi),
            psi: sub(&self.psi),
            lambda_x: self.lambda_x[..k].to_vec(),
            lambda_y: self.lambda_y[..k].to_vec(),
            eigenvalues_x: self.eigenvalues_x[..k].to_vec(),
            eigenvalues_y: self.eigenvalues_y[..k].to_vec(),
            f_hat: self.f_hat.subrows(0, k).to_owned(),
            g_hat: self.g_hat.subrows(0, k).to_owned(),
            gram_x: self.gram_x.submatrix(0, 0, k, k).to_owned(),
            gram_y: self.gram_y.submatrix(0, 0, k, k).to_owned(),
            l1_weights_x: self.l1_weights_x.clone(),
            l1_weights_y: self.l1_weights_y.clone(),
            c_scale: self.c_scale,
            prior: self.prior.clone(),
            area_x: self.area_x,
            area_y: self.area_y,
            l1_sample: self.l1_sample.as_ref().map(|s| L1Sample {
                phi: sub(&s.phi),
                psi: sub(&s.psi),
                weights_x: s.weights_x.clone(),
                weights_y: s.weights_y.clone(),
            }),
        })
    }

    /// This problem's C (r × c) from a functional map between the input bases (e.g.
    /// Ovsjanikov's): C / `c_scale`.
    pub fn c_from_bases(&self, c_bases: MatRef<f64>) -> Mat<f64> {
        c_bases.to_owned() * faer::Scale(1.0 / self.c_scale)
    }

    /// The functional map between the input bases of this problem's C: `c_scale` · C.
    pub fn c_to_bases(&self, c: MatRef<f64>) -> Mat<f64> {
        c.to_owned() * faer::Scale(self.c_scale)
    }
}
