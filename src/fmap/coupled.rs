//! Kovnatsky et al. 2013 ("Coupled quasi-harmonic bases"), paper eq. (7): orthonormal P, Q
//! (k × k) rotate the bases Φ, Ψ into coupled bases Φ P, Ψ Q in which the map is diagonal,
//!
//! E(P, Q) = ‖Âᵀ P − B̂ᵀ Q‖²_F / s + μ1 off(Pᵀ Λ̃_X P) + μ2 off(Qᵀ Λ̃_Y Q),  PᵀP = QᵀQ = I,
//!
//! with Â = Φ_kᵀ A_X F, B̂ = Ψ_kᵀ A_Y G (mass-weighted coefficients), s = (‖Â‖² + ‖B̂‖²)/2,
//! λ̃ = λ / λ_max (see [`super`]) and off(S) = Σ_{i≠j} s_ij². (Pᵀ Λ P is the Laplacian of X in the
//! rotated basis Φ P; the paper prints Q Λ Qᵀ for Y, we use the same form Qᵀ Λ Q on both sides.)
//!
//! Euclidean gradients (R = Âᵀ P − B̂ᵀ Q, q × k; off(S) also denotes S with its diagonal zeroed):
//! - data term D = ‖R‖²/s: dD = 2⟨R, Âᵀ dP − B̂ᵀ dQ⟩/s, so ∇_P D = 2 Â R / s, ∇_Q D = −2 B̂ R / s;
//! - off term O(P) = off(S), S = Pᵀ Λ P symmetric: O = ‖S‖² − Σᵢ sᵢᵢ², dO = 2⟨off(S), dS⟩ and
//!   dS = dPᵀ Λ P + Pᵀ Λ dP, so dO = 4⟨Λ P off(S), dP⟩ and ∇ O = 4 Λ P off(S).
//!
//! Optimizer: Riemannian conjugate gradient (Polak–Ribière⁺) on O(k) × O(k) ([`crate::optim::rcg`],
//! this module supplies the manifold and the objective). The Riemannian
//! gradient is the projection of the Euclidean one onto the tangent space, G − P sym(PᵀG); the
//! previous direction is transported by the same projection; the retraction is the QR
//! decomposition of P + ξ with a positive diagonal of R; the step satisfies the Armijo condition
//! by backtracking (halving) from twice the previous accepted step. A non-descent direction is
//! replaced by the negative gradient. Stops when the decrease of E is below `tol` · max(E, 1e-12)
//! twice in a row (E is dimensionless, 1e-12 is its resolution), when the Riemannian gradient
//! vanishes or no Armijo step is found, or after `max_iterations`.
//!
//! Start: P = I and Q = diag(σ) with σᵢ = sign(⟨âᵢ, b̂ᵢ⟩) (rows of Â, B̂; +1 on ties). Starting
//! from Q = I, as the method is usually described, fails as soon as eigenfunction signs differ
//! between the two shapes (they are arbitrary): a sign flip is not reachable by a continuous
//! rotation that keeps off(·) small, and an odd number of them lies in the other connected
//! component of O(k). The data-fitted signs are the best diagonal ±1 start.
//!
//! Finally the diagonal map in the coupled bases: c_i minimizes ‖c_i (PᵀÂ)_i − (QᵀB̂)_i‖² (rows),
//! c_i = ⟨(PᵀÂ)_i, (QᵀB̂)_i⟩ / ‖(PᵀÂ)_i‖² (0 if that row is 0), and the functional map in the
//! original bases is C = Q diag(c) Pᵀ (T = Ψ Q diag(c) Pᵀ Φᵀ A_X).

use faer::Mat;

use super::{mul, Problem};
use crate::descriptors::Descriptors;
use crate::error::{Error, Result};
use crate::optim::{self, rcg, Beta, Manifold, RcgLineSearch, RcgOptions, Stop, StopRule};
use crate::spectral::Basis;

/// Options of [`coupled`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CoupledOptions {
    /// μ1 ≥ 0: weight of off(Pᵀ Λ̃_X P).
    pub mu1: f64,
    /// μ2 ≥ 0: weight of off(Qᵀ Λ̃_Y Q).
    pub mu2: f64,
    /// Maximum number of conjugate-gradient iterations.
    pub max_iterations: usize,
    /// Stop when the relative decrease of the objective is below this.
    pub tol: f64,
}

impl Default for CoupledOptions {
    /// μ1 = μ2 = 1, 1000 iterations, tol 1e-10.
    fn default() -> Self {
        CoupledOptions { mu1: 1.0, mu2: 1.0, max_iterations: 1000, tol: 1e-10 }
    }
}

/// What [`coupled`] found besides C.
#[derive(Debug, Clone)]
pub struct CoupledInfo {
    /// P (k × k, orthonormal): the coupled basis of X is Φ P.
    pub p: Mat<f64>,
    /// Q (k × k, orthonormal): the coupled basis of Y is Ψ Q.
    pub q: Mat<f64>,
    /// The diagonal map c (k) between the coupled bases.
    pub diagonal: Vec<f64>,
    /// Conjugate-gradient iterations done.
    pub iterations: usize,
    /// Final ‖Âᵀ P − B̂ᵀ Q‖² / s.
    pub data: f64,
    /// Final off(Pᵀ Λ̃_X P) (not multiplied by μ1).
    pub off_x: f64,
    /// Final off(Qᵀ Λ̃_Y Q) (not multiplied by μ2).
    pub off_y: f64,
}

/// The functional map C = Q diag(c) Pᵀ (k × k) of eq. (7) and the coupled bases. Errors as
/// [`super::ovsjanikov()`], and on invalid options.
pub fn coupled(
    bx: &Basis,
    by: &Basis,
    f: &Descriptors,
    g: &Descriptors,
    k: usize,
    opts: &CoupledOptions,
) -> Result<(Mat<f64>, CoupledInfo)> {
    for (name, v) in [("mu1", opts.mu1), ("mu2", opts.mu2), ("tol", opts.tol)] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(Error::invalid(name, format!("must be finite and ≥ 0, got {v}")));
        }
    }
    let pr = Problem::new(bx, by, f, g, k)?;
    let obj = Objective { pr: &pr, mu1: opts.mu1, mu2: opts.mu2 };
    let p0 = Mat::<f64>::identity(k, k);
    let q0 = Mat::from_fn(k, k, |i, j| {
        if i != j {
            return 0.0;
        }
        let dot: f64 = (0..pr.a.ncols()).map(|c| pr.a[(i, c)] * pr.b[(i, c)]).sum();
        if dot < 0.0 {
            -1.0
        } else {
            1.0
        }
    });
    let (p, q, iterations) = minimize(&obj, p0, q0, opts.max_iterations, opts.tol)?;
    let pa = mul(p.transpose(), pr.a.as_ref());
    let qb = mul(q.transpose(), pr.b.as_ref());
    let diagonal: Vec<f64> = (0..k)
        .map(|i| {
            let den: f64 = pa.row(i).iter().map(|v| v * v).sum();
            let num: f64 = pa.row(i).iter().zip(qb.row(i).iter()).map(|(x, y)| x * y).sum();
            if den > 0.0 {
                num / den
            } else {
                0.0
            }
        })
        .collect();
    let qd = Mat::from_fn(k, k, |i, j| q[(i, j)] * diagonal[j]);
    let c = mul(qd.as_ref(), p.transpose());
    if !(0..k).all(|j| (0..k).all(|i| c[(i, j)].is_finite())) {
        return Err(Error::numerical("coupled", "the functional map is not finite"));
    }
    let (data, _, _) = data_term(&pr, &p, &q);
    let (off_x, _) = off_term(&pr.lx, &p);
    let (off_y, _) = off_term(&pr.ly, &q);
    Ok((c, CoupledInfo { p, q, diagonal, iterations, data, off_x, off_y }))
}

/// D = ‖Âᵀ P − B̂ᵀ Q‖² / s with ∇_P D = 2 Â R / s and ∇_Q D = −2 B̂ R / s.
fn data_term(pr: &Problem, p: &Mat<f64>, q: &Mat<f64>) -> (f64, Mat<f64>, Mat<f64>) {
    let r = &mul(pr.a.transpose(), p.as_ref()) - &mul(pr.b.transpose(), q.as_ref());
    let value = r.squared_norm_l2() / pr.scale;
    let gp = mul(pr.a.as_ref(), r.as_ref()) * (2.0 / pr.scale);
    let gq = mul(pr.b.as_ref(), r.as_ref()) * (-2.0 / pr.scale);
    (value, gp, gq)
}

/// off(Pᵀ Λ P) with its gradient 4 Λ P off(Pᵀ Λ P), Λ = diag(`lambda`).
fn off_term(lambda: &[f64], p: &Mat<f64>) -> (f64, Mat<f64>) {
    let k = p.nrows();
    let lp = Mat::from_fn(k, k, |i, j| lambda[i] * p[(i, j)]);
    let mut s = mul(p.transpose(), lp.as_ref());
    for i in 0..k {
        s[(i, i)] = 0.0;
    }
    let value = s.squared_norm_l2();
    let grad = mul(lp.as_ref(), s.as_ref()) * 4.0;
    (value, grad)
}

#[derive(Clone)]
struct Objective<'a> {
    pr: &'a Problem,
    mu1: f64,
    mu2: f64,
}

impl Objective<'_> {
    /// E and its Euclidean gradients.
    fn eval(&self, p: &Mat<f64>, q: &Mat<f64>) -> (f64, Mat<f64>, Mat<f64>) {
        let (d, mut gp, mut gq) = data_term(self.pr, p, q);
        let (ox, gx) = off_term(&self.pr.lx, p);
        let (oy, gy) = off_term(&self.pr.ly, q);
        gp += gx * self.mu1;
        gq += gy * self.mu2;
        (d + self.mu1 * ox + self.mu2 * oy, gp, gq)
    }
}

/// Projection onto the tangent space of O(k) at P: G − P sym(PᵀG).
fn project(p: &Mat<f64>, g: &Mat<f64>) -> Mat<f64> {
    let ptg = mul(p.transpose(), g.as_ref());
    let sym = Mat::from_fn(ptg.nrows(), ptg.ncols(), |i, j| 0.5 * (ptg[(i, j)] + ptg[(j, i)]));
    g - &mul(p.as_ref(), sym.as_ref())
}

/// QR retraction: the Q factor of P + ξ with a positive diagonal of R.
fn retract(p: &Mat<f64>, xi: &Mat<f64>, t: f64) -> Mat<f64> {
    let y = p + xi * t;
    let qr = y.qr();
    let (mut q, r) = (qr.compute_thin_Q(), qr.thin_R().to_owned());
    for j in 0..q.ncols() {
        if r[(j, j)] < 0.0 {
            for i in 0..q.nrows() {
                q[(i, j)] = -q[(i, j)];
            }
        }
    }
    q
}

fn inner(a: &Mat<f64>, b: &Mat<f64>) -> f64 {
    crate::linalg::frob(a.as_ref(), b.as_ref())
}

/// O(k) × O(k) with the Euclidean metric ⟨(U, V), (U', V')⟩ = ⟨U, U'⟩ + ⟨V, V'⟩: projection
/// [`project`] and QR retraction [`retract`] on each factor, transport by projection.
struct Orthogonal2;

type Pair = (Mat<f64>, Mat<f64>);

impl Manifold for Orthogonal2 {
    type Point = Pair;
    type Tangent = Pair;
    type Ambient = Pair;
    fn inner(&self, _: &Pair, u: &Pair, v: &Pair) -> f64 {
        inner(&u.0, &v.0) + inner(&u.1, &v.1)
    }
    fn scale(&self, v: &Pair, a: f64) -> Pair {
        (&v.0 * a, &v.1 * a)
    }
    fn add_scaled(&self, v: &Pair, a: f64, w: &Pair) -> Pair {
        (&v.0 + &(&w.0 * a), &v.1 + &(&w.1 * a))
    }
    fn project(&self, x: &Pair, g: Pair) -> Pair {
        (project(&x.0, &g.0), project(&x.1, &g.1))
    }
    fn retract(&self, x: &Pair, v: &Pair, t: f64) -> Result<Pair> {
        Ok((retract(&x.0, &v.0, t), retract(&x.1, &v.1, t)))
    }
    fn transport(&self, _: &Pair, v: &Pair, to: &Pair) -> Pair {
        self.project(to, v.clone())
    }
    fn point_norm(&self, x: &Pair) -> f64 {
        (inner(&x.0, &x.0) + inner(&x.1, &x.1)).sqrt()
    }
}

impl optim::Objective<Orthogonal2> for Objective<'_> {
    type Value = f64;
    fn value(&mut self, x: &Pair) -> f64 {
        self.eval(&x.0, &x.1).0
    }
    fn gradient(&mut self, x: &Pair) -> (f64, Pair) {
        let (e, gp, gq) = self.eval(&x.0, &x.1);
        (e, (gp, gq))
    }
}

/// Riemannian CG on O(k) × O(k) (module documentation; [`crate::optim::rcg`] with
/// Polak–Ribière⁺, halving from twice the previous step, no retry); returns (P, Q, iterations),
/// the iterations counting a last one whose line search failed.
fn minimize(
    obj: &Objective,
    p: Mat<f64>,
    q: Mat<f64>,
    max_iter: usize,
    tol: f64,
) -> Result<(Mat<f64>, Mat<f64>, usize)> {
    let opts = RcgOptions {
        max_iterations: max_iter,
        beta: Beta::PolakRibiere,
        line_search: RcgLineSearch::Halving { max_trials: 60, c1: 1e-4 },
        // E is dimensionless (relative residual): below 1e-12 its changes carry no information.
        stop: StopRule::SmallDecrease { tol, floor: 1e-12, repeats: 2 },
        retry_steepest_descent: false,
    };
    let min = rcg::minimize(&Orthogonal2, &mut obj.clone(), (p, q), &opts)?;
    let iterations = min.report.iterations + usize::from(min.report.stop == Stop::LineSearchFailed);
    Ok((min.x.0, min.x.1, iterations))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmap::testdata::{diag_error, pair, recovered};
    use crate::spectral::Normal;

    fn random_orthogonal(rng: &mut Normal, k: usize) -> Mat<f64> {
        let m = Mat::from_fn(k, k, |_, _| rng.sample());
        retract(&Mat::zeros(k, k), &m, 1.0)
    }

    fn random_problem(seed: u64, k: usize, q: usize) -> Problem {
        let mut rng = Normal::new(seed);
        let a = Mat::from_fn(k, q, |_, _| rng.sample());
        let b = Mat::from_fn(k, q, |_, _| rng.sample());
        let scale = 0.5 * (a.squared_norm_l2() + b.squared_norm_l2());
        let lx: Vec<f64> = (0..k).map(|i| i as f64 / k as f64).collect();
        let ly: Vec<f64> = (0..k).map(|i| (i as f64 + 0.3) / k as f64).collect();
        Problem { a, b, lx, ly, scale }
    }

    /// Central difference along a random direction V vs ⟨∇, V⟩.
    fn check(name: &str, f: impl Fn(&Mat<f64>) -> f64, x: &Mat<f64>, grad: &Mat<f64>, rng: &mut Normal) {
        let v = Mat::from_fn(x.nrows(), x.ncols(), |_, _| rng.sample());
        let h = 1e-5;
        let fd = (f(&(x + &v * h)) - f(&(x - &v * h))) / (2.0 * h);
        let an = inner(grad, &v);
        let rel = (fd - an).abs() / an.abs().max(1e-300);
        assert!(rel < 1e-5, "{name}: finite difference {fd} vs gradient {an} (relative error {rel:.1e})");
    }

    #[test]
    fn gradients_match_finite_differences() {
        let pr = random_problem(5, 7, 11);
        let mut rng = Normal::new(9);
        let (p, q) = (random_orthogonal(&mut rng, 7), random_orthogonal(&mut rng, 7));
        let (_, gp, gq) = data_term(&pr, &p, &q);
        check("data/P", |x| data_term(&pr, x, &q).0, &p, &gp, &mut rng);
        check("data/Q", |x| data_term(&pr, &p, x).0, &q, &gq, &mut rng);
        // Off-diagonality at a general (not orthogonal) point too: the formula does not assume it.
        for x in [p.clone(), Mat::from_fn(7, 7, |_, _| rng.sample())] {
            let (_, g) = off_term(&pr.lx, &x);
            check("off", |y| off_term(&pr.lx, y).0, &x, &g, &mut rng);
        }
        let obj = Objective { pr: &pr, mu1: 0.7, mu2: 1.3 };
        let (_, gp, gq) = obj.eval(&p, &q);
        check("E/P", |x| obj.eval(x, &q).0, &p, &gp, &mut rng);
        check("E/Q", |x| obj.eval(&p, x).0, &q, &gq, &mut rng);
    }

    #[test]
    fn optimizer_reaches_a_stationary_point_on_the_manifold() {
        let pr = random_problem(17, 8, 12);
        let obj = Objective { pr: &pr, mu1: 0.5, mu2: 0.5 };
        let k = 8;
        let (p0, q0) = (Mat::<f64>::identity(k, k), Mat::<f64>::identity(k, k));
        let e0 = obj.eval(&p0, &q0).0;
        let (p, q, iters) = minimize(&obj, p0, q0, 5000, 1e-14).unwrap();
        let (e, gp, gq) = obj.eval(&p, &q);
        let (rp, rq) = (project(&p, &gp), project(&q, &gq));
        let gnorm = (inner(&rp, &rp) + inner(&rq, &rq)).sqrt();
        let orth = (&mul(p.transpose(), p.as_ref()) - &Mat::<f64>::identity(k, k)).norm_l2()
            + (&mul(q.transpose(), q.as_ref()) - &Mat::<f64>::identity(k, k)).norm_l2();
        eprintln!("coupled optimizer: E {e0:.4} → {e:.6} in {iters} iterations, ‖grad‖ {gnorm:.1e}");
        assert!(e < 0.8 * e0, "{e} vs {e0}");
        assert!(gnorm < 1e-5, "Riemannian gradient {gnorm}");
        assert!(orth < 1e-12, "lost orthonormality: {orth}");
    }

    #[test]
    fn recovers_a_permuted_copy() {
        let p = pair();
        let (c, info) = coupled(&p.bx, &p.by, &p.f, &p.g, 30, &CoupledOptions::default()).unwrap();
        let (err, rate) = (diag_error(p, &c), recovered(p, &c));
        eprintln!(
            "coupled: max |C − C_true| = {err:.2e}, recovered {rate:.3}, {} iterations, data {:.2e}, off {:.2e} {:.2e}",
            info.iterations, info.data, info.off_x, info.off_y
        );
        assert!(err < 0.05, "C off the ground truth by {err}");
        for i in 0..30 {
            assert!((c[(i, i)].abs() - 1.0).abs() < 0.05, "|C_{i}{i}| = {}", c[(i, i)].abs());
        }
        assert!(rate >= 0.95, "only {rate} of the vertices recovered");
    }

    #[test]
    fn rotates_within_near_degenerate_eigenspaces() {
        // Ψ' = Ψ R with R rotating the nearly equal eigenpairs (2, 3) and (7, 8) by 0.6 rad:
        // B̂' = Rᵀ B̂, the true map is Rᵀ diag(σ), and the start (P = I, Q = diag(±1)) is wrong by R.
        let p = pair();
        let k = 30;
        let (cs, sn) = (0.6f64.cos(), 0.6f64.sin());
        let mut r = Mat::<f64>::identity(k, k);
        for (i, j) in [(2, 3), (7, 8)] {
            r[(i, i)] = cs;
            r[(j, j)] = cs;
            r[(i, j)] = -sn;
            r[(j, i)] = sn;
        }
        let mut by = p.by.clone();
        by.eigenvectors = mul(p.by.eigenvectors.as_ref(), r.as_ref());
        let truth = Mat::from_fn(k, k, |i, j| r[(j, i)] * p.signs[j]);
        let (c, info) = coupled(&p.bx, &by, &p.f, &p.g, k, &CoupledOptions::default()).unwrap();
        let err = (&c - &truth).norm_max();
        let start_err = (&Mat::from_fn(k, k, |i, j| if i == j { p.signs[i] } else { 0.0 }) - &truth).norm_max();
        let map =
            crate::pointwise::map_from_fmap(p.bx.eigenvectors.as_ref(), by.eigenvectors.as_ref(), c.as_ref()).unwrap();
        let n = p.bx.n();
        let mut want = vec![0usize; n];
        for (new, &old) in p.perm.iter().enumerate() {
            want[old] = new;
        }
        let rate = (0..n).filter(|&i| map[i] == want[i]).count() as f64 / n as f64;
        eprintln!(
            "coupled, rotated eigenspaces: max |C − C_true| = {err:.2e} (start {start_err:.2}), recovered {rate:.3}, \
             {} iterations, data {:.2e}, off {:.2e} {:.2e}",
            info.iterations, info.data, info.off_x, info.off_y
        );
        assert!(err < 0.05, "C off the ground truth by {err}");
        assert!(rate >= 0.95, "only {rate} of the vertices recovered");
    }

    #[test]
    fn bad_input_is_an_error() {
        let p = pair();
        let o = CoupledOptions::default();
        let few = Descriptors::new(p.g.values.subcols(0, 7).to_owned(), p.g.names[..7].to_vec()).unwrap();
        let e = coupled(&p.bx, &p.by, &p.f, &few, 10, &o).unwrap_err().to_string();
        assert!(e.contains("columns"), "{e}");
        assert!(coupled(&p.bx, &p.by, &p.f, &p.g, 31, &o).is_err());
        assert!(coupled(&p.bx, &p.by, &p.f, &p.g, 10, &CoupledOptions { mu1: f64::NAN, ..o }).is_err());
    }
}
