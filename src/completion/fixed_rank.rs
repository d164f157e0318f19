//! The fixed-rank form (8): Riemannian conjugate gradients on the manifold of r × c matrices
//! of rank k, as manopt's `fixedrankembeddedfactory` + `conjugategradient` (Vandereycken 2013,
//! "Low-rank matrix completion by Riemannian optimization"; Boumal et al. 2014), which the
//! paper used (§3.3).
//!
//! A point is X = U diag(σ) Vᵀ with orthonormal U (r × k), V (c × k) and σ > 0 (k). A tangent
//! vector at X is η = U M Vᵀ + U_p Vᵀ + U V_pᵀ with M (k × k), U_p ⊥ U (r × k), V_p ⊥ V (c × k);
//! the metric is the Euclidean one of R^{r×c}, ⟨η, ζ⟩ = ⟨M, M'⟩ + ⟨U_p, U_p'⟩ + ⟨V_p, V_p'⟩.
//! - Riemannian gradient: the projection of the Euclidean gradient Z = ∂f/∂X onto the tangent
//!   space, from the products Z V and Zᵀ U only: M = Uᵀ Z V, U_p = Z V − U M, V_p = Zᵀ U − V Mᵀ.
//! - Retraction: the best rank-k approximation of X + t η, computed from its rank-2k
//!   factorization [U(Σ + tM) + tU_p, tU] [V, V_p]ᵀ by two thin QRs and a 2k × 2k SVD (robust
//!   when r or c < 2k, where manopt's [U Q_u] would not be orthonormal).
//! - Vector transport: projection of the ambient matrix η onto the new tangent space.
//! - Line search: backtracking with sufficient decrease (Armijo) from Nocedal's initial step
//!   2 (f_k − f_{k−1}) / φ'(0); conjugate directions by Polak–Ribière+ with restarts.
//!
//! The algorithm is [`crate::optim::rcg`]; this module supplies the manifold (a private
//! implementation of [`crate::optim::Manifold`]) and the objective.
//!
//! The objective only has to provide f at X = L Rᵀ and the products Z·P_R, Zᵀ·P_L of its
//! Euclidean gradient ([`RankObjective`]), so X is never formed when r × c is large: the
//! vertex-space form (8) runs on m × n matrices through [`super::full::FullProblem`], the
//! subspace form on the k' × k' map C through [`super::Problem`].

use crate::linalg::frob;

use faer::{Mat, MatRef};

use super::full::{metric, scale_rows, unscale_rows, FullProblem};
use super::lbfgs::{CompletionReport, OptimizeOptions};
use super::objective::{gradient_c, value, CompletionParams, Terms};
use super::{gemm_nn, gemm_tn, mul, Problem};
use crate::error::{Error, Result};
use crate::optim::{self, rcg, Beta, Manifold, RcgLineSearch, RcgOptions, Stop, StopRule};

/// An objective on r × c matrices for the fixed-rank solver.
pub trait RankObjective {
    /// (r, c).
    fn dims(&self) -> (usize, usize);
    /// The terms of f at X = L Rᵀ (L: r × k, R: c × k); f = `total`.
    fn value(&self, l: MatRef<f64>, r: MatRef<f64>) -> Terms;
    /// The terms at X = L Rᵀ and the products Z·P_R (r × p) and Zᵀ·P_L (c × p') of the
    /// Euclidean gradient Z = ∂f/∂X.
    fn egrad(&self, l: MatRef<f64>, r: MatRef<f64>, pl: MatRef<f64>, pr: MatRef<f64>) -> (Terms, Mat<f64>, Mat<f64>);
}

/// The subspace problem on C = A Bᵀ (k' × k'): (11) with μ4 = 0, which the paper notes is the
/// subspace version of (8). The low-norm weight of `params` is ignored.
pub struct SubspaceRank<'a> {
    /// The problem.
    pub problem: &'a Problem,
    /// Its weights (μ4 is ignored).
    pub params: CompletionParams,
}

impl RankObjective for SubspaceRank<'_> {
    fn dims(&self) -> (usize, usize) {
        (self.problem.k_prime(), self.problem.k_prime())
    }
    fn value(&self, l: MatRef<f64>, r: MatRef<f64>) -> Terms {
        value(self.problem, &CompletionParams { mu4: 0.0, ..self.params.clone() }, l, r)
    }
    fn egrad(&self, l: MatRef<f64>, r: MatRef<f64>, pl: MatRef<f64>, pr: MatRef<f64>) -> (Terms, Mat<f64>, Mat<f64>) {
        let (t, z) = gradient_c(self.problem, &self.params, l, r);
        (t, mul(z.as_ref(), pr), mul(z.transpose(), pl))
    }
}

/// The vertex-space problem (8) on T (m × n), in the scaled variable T_S = D_Y T D_X with
/// D = A^{1/2} ([`super::full::metric`]): the manifold's metric is then the mass-weighted one,
/// under which the problem is as well conditioned as the subspace form. The low-norm weight of
/// `params` is ignored.
pub struct FullRank<'a> {
    /// The problem.
    pub problem: &'a FullProblem,
    /// Its weights (μ4 is ignored).
    pub params: CompletionParams,
    /// D_Y (m).
    pub dy: Vec<f64>,
    /// D_X (n).
    pub dx: Vec<f64>,
}

impl<'a> FullRank<'a> {
    /// The objective of `problem` with `params` in the scaled variable.
    pub fn new(problem: &'a FullProblem, params: CompletionParams) -> Self {
        let (dy, dx) = metric(problem);
        FullRank { problem, params, dy, dx }
    }

    /// Factors of T = L Rᵀ from factors of T_S.
    pub fn unscale(&self, ls: MatRef<f64>, rs: MatRef<f64>) -> (Mat<f64>, Mat<f64>) {
        (unscale_rows(&self.dy, ls), unscale_rows(&self.dx, rs))
    }

    /// Factors of T_S from factors of T.
    pub fn scale(&self, l: MatRef<f64>, r: MatRef<f64>) -> (Mat<f64>, Mat<f64>) {
        (scale_rows(&self.dy, l), scale_rows(&self.dx, r))
    }
}

impl RankObjective for FullRank<'_> {
    fn dims(&self) -> (usize, usize) {
        (self.problem.m(), self.problem.n())
    }
    fn value(&self, l: MatRef<f64>, r: MatRef<f64>) -> Terms {
        let (l, r) = self.unscale(l, r);
        self.problem.t_terms(&self.params, l.as_ref(), r.as_ref(), None).0
    }
    fn egrad(&self, l: MatRef<f64>, r: MatRef<f64>, pl: MatRef<f64>, pr: MatRef<f64>) -> (Terms, Mat<f64>, Mat<f64>) {
        // Z_S = D_Y⁻¹ Z D_X⁻¹: Z_S P = D_Y⁻¹ Z (D_X⁻¹ P), Z_Sᵀ P' = D_X⁻¹ Zᵀ (D_Y⁻¹ P').
        let (l, r) = self.unscale(l, r);
        let (pl, pr) = self.unscale(pl, pr);
        let (t, z) = self.problem.t_terms(&self.params, l.as_ref(), r.as_ref(), Some((pl.as_ref(), pr.as_ref())));
        let (zr, ztl) = z.expect("requested");
        (t, unscale_rows(&self.dy, zr.as_ref()), unscale_rows(&self.dx, ztl.as_ref()))
    }
}

/// A point X = U diag(σ) Vᵀ of the manifold of rank-k matrices.
#[derive(Clone, Debug)]
pub struct RankPoint {
    /// U (r × k), orthonormal columns.
    pub u: Mat<f64>,
    /// σ (k), the singular values, decreasing.
    pub s: Vec<f64>,
    /// V (c × k), orthonormal columns.
    pub v: Mat<f64>,
}

impl RankPoint {
    /// The rank-k truncation of L Rᵀ (L: r × p, R: c × p, p ≥ k) by thin QR of both factors and
    /// an SVD of the p × p core. Errors when p < k or the factors are not finite.
    pub fn from_factors(l: MatRef<f64>, r: MatRef<f64>, k: usize) -> Result<RankPoint> {
        let p = l.ncols();
        if r.ncols() != p || k == 0 || k > p || k > l.nrows() || k > r.nrows() {
            return Err(Error::invalid(
                "rank",
                format!("cannot take rank {k} from factors {}×{} and {}×{}", l.nrows(), p, r.nrows(), r.ncols()),
            ));
        }
        let finite = |x: MatRef<f64>| (0..x.ncols()).all(|j| (0..x.nrows()).all(|i| x[(i, j)].is_finite()));
        if !finite(l) || !finite(r) {
            return Err(Error::numerical("fixed rank", "a factor is not finite"));
        }
        let ql = l.qr();
        let qr = r.qr();
        let (q1, r1) = (ql.compute_thin_Q(), ql.thin_R().to_owned());
        let (q2, r2) = (qr.compute_thin_Q(), qr.thin_R().to_owned());
        let core = mul(r1.as_ref(), r2.transpose());
        let svd = core.thin_svd().map_err(|e| Error::numerical("fixed rank", format!("SVD failed: {e:?}")))?;
        let (uc, vc, sc) = (svd.U(), svd.V(), svd.S());
        let u = gemm_nn(q1.as_ref(), uc.subcols(0, k));
        let v = gemm_nn(q2.as_ref(), vc.subcols(0, k));
        let s = (0..k).map(|i| sc[i]).collect();
        Ok(RankPoint { u, s, v })
    }

    /// L = U diag(σ) (r × k): X = L Vᵀ.
    pub fn left(&self) -> Mat<f64> {
        Mat::from_fn(self.u.nrows(), self.s.len(), |i, j| self.u[(i, j)] * self.s[j])
    }

    /// Balanced factors (U diag(√σ), V diag(√σ)) with X = L Rᵀ.
    pub fn balanced(&self) -> (Mat<f64>, Mat<f64>) {
        let k = self.s.len();
        let l = Mat::from_fn(self.u.nrows(), k, |i, j| self.u[(i, j)] * self.s[j].sqrt());
        let r = Mat::from_fn(self.v.nrows(), k, |i, j| self.v[(i, j)] * self.s[j].sqrt());
        (l, r)
    }
}

/// A tangent vector η = U M Vᵀ + U_p Vᵀ + U V_pᵀ.
#[derive(Clone, Debug)]
struct Tangent {
    m: Mat<f64>,
    up: Mat<f64>,
    vp: Mat<f64>,
}

impl Tangent {
    fn inner(&self, o: &Tangent) -> f64 {
        frob(self.m.as_ref(), o.m.as_ref())
            + frob(self.up.as_ref(), o.up.as_ref())
            + frob(self.vp.as_ref(), o.vp.as_ref())
    }
    fn scaled(&self, a: f64) -> Tangent {
        Tangent { m: &self.m * a, up: &self.up * a, vp: &self.vp * a }
    }
    fn add_scaled(&self, a: f64, o: &Tangent) -> Tangent {
        Tangent { m: &self.m + &o.m * a, up: &self.up + &o.up * a, vp: &self.vp + &o.vp * a }
    }
}

/// Projection onto the tangent space at `x` of an ambient matrix H given by H V (r × k) and
/// Hᵀ U (c × k).
fn project(x: &RankPoint, hv: Mat<f64>, htu: Mat<f64>) -> Tangent {
    let m = gemm_tn(x.u.as_ref(), hv.as_ref());
    let up = hv - gemm_nn(x.u.as_ref(), m.as_ref());
    let vp = htu - gemm_nn(x.v.as_ref(), m.transpose());
    Tangent { m, up, vp }
}

/// The tangent vector `eta` at `from`, transported to `to` by projection.
fn transport(from: &RankPoint, eta: &Tangent, to: &RankPoint) -> Tangent {
    let vv = gemm_tn(from.v.as_ref(), to.v.as_ref()); // V0ᵀ V1 (k × k)
    let uu = gemm_tn(from.u.as_ref(), to.u.as_ref()); // U0ᵀ U1
                                                      // η V1 = U0 (M V0ᵀV1 + Vpᵀ V1) + Up (V0ᵀ V1).
    let inner_v = mul(eta.m.as_ref(), vv.as_ref()) + gemm_tn(eta.vp.as_ref(), to.v.as_ref());
    let hv = gemm_nn(from.u.as_ref(), inner_v.as_ref()) + gemm_nn(eta.up.as_ref(), vv.as_ref());
    // ηᵀ U1 = V0 (Mᵀ U0ᵀU1 + Upᵀ U1) + Vp (U0ᵀ U1).
    let inner_u = mul(eta.m.transpose(), uu.as_ref()) + gemm_tn(eta.up.as_ref(), to.u.as_ref());
    let htu = gemm_nn(from.v.as_ref(), inner_u.as_ref()) + gemm_nn(eta.vp.as_ref(), uu.as_ref());
    project(to, hv, htu)
}

/// R_x(t η): the best rank-k approximation of X + t η.
fn retract(x: &RankPoint, eta: &Tangent, t: f64) -> Result<RankPoint> {
    let (r, c, k) = (x.u.nrows(), x.v.nrows(), x.s.len());
    // X + tη = [U (Σ + tM) + t U_p, t U] [V, V_p]ᵀ.
    let sm = Mat::from_fn(k, k, |i, j| if i == j { x.s[i] } else { 0.0 } + t * eta.m[(i, j)]);
    let first = gemm_nn(x.u.as_ref(), sm.as_ref()) + &eta.up * t;
    let l = Mat::from_fn(r, 2 * k, |i, j| if j < k { first[(i, j)] } else { t * x.u[(i, j - k)] });
    let rr = Mat::from_fn(c, 2 * k, |i, j| if j < k { x.v[(i, j)] } else { eta.vp[(i, j - k)] });
    // With r or c below 2k the thin QR keeps min(r, 2k) columns.
    let p = (2 * k).min(r).min(c);
    if p < 2 * k {
        let lq = l.qr();
        let rq = rr.qr();
        let core = mul(lq.thin_R(), rq.thin_R().transpose());
        let svd = core.thin_svd().map_err(|e| Error::numerical("fixed rank", format!("SVD failed: {e:?}")))?;
        let u = gemm_nn(lq.compute_thin_Q().as_ref(), svd.U().subcols(0, k));
        let v = gemm_nn(rq.compute_thin_Q().as_ref(), svd.V().subcols(0, k));
        let s = (0..k).map(|i| svd.S()[i]).collect();
        return Ok(RankPoint { u, s, v });
    }
    RankPoint::from_factors(l.as_ref(), rr.as_ref(), k)
}

/// The manifold of r × c matrices of rank k (points [`RankPoint`], tangent vectors
/// [`Tangent`], Euclidean gradients given by their products Z V (r × k) and Zᵀ U (c × k)).
struct FixedRank;

impl Manifold for FixedRank {
    type Point = RankPoint;
    type Tangent = Tangent;
    type Ambient = (Mat<f64>, Mat<f64>);
    fn inner(&self, _: &RankPoint, u: &Tangent, v: &Tangent) -> f64 {
        u.inner(v)
    }
    fn scale(&self, v: &Tangent, a: f64) -> Tangent {
        v.scaled(a)
    }
    fn add_scaled(&self, v: &Tangent, a: f64, w: &Tangent) -> Tangent {
        v.add_scaled(a, w)
    }
    fn project(&self, x: &RankPoint, (hv, htu): (Mat<f64>, Mat<f64>)) -> Tangent {
        project(x, hv, htu)
    }
    fn retract(&self, x: &RankPoint, v: &Tangent, t: f64) -> Result<RankPoint> {
        retract(x, v, t)
    }
    fn transport(&self, from: &RankPoint, v: &Tangent, to: &RankPoint) -> Tangent {
        transport(from, v, to)
    }
    fn point_norm(&self, x: &RankPoint) -> f64 {
        x.s.iter().map(|s| s * s).sum::<f64>().sqrt()
    }
}

/// A [`RankObjective`] as an objective of the Riemannian CG.
struct OnManifold<'a>(&'a dyn RankObjective);

impl optim::Objective<FixedRank> for OnManifold<'_> {
    type Value = Terms;
    fn value(&mut self, x: &RankPoint) -> Terms {
        self.0.value(x.left().as_ref(), x.v.as_ref())
    }
    fn gradient(&mut self, x: &RankPoint) -> (Terms, (Mat<f64>, Mat<f64>)) {
        let (t, zv, ztu) = self.0.egrad(x.left().as_ref(), x.v.as_ref(), x.u.as_ref(), x.v.as_ref());
        (t, (zv, ztu))
    }
}

/// The Riemannian CG of the module documentation with the tolerances and line-search budget of
/// `opts`: Polak–Ribière⁺ (expanded form), the interpolating backtracking line search, retry
/// along the negative gradient.
fn rcg_options(opts: &OptimizeOptions) -> RcgOptions {
    RcgOptions {
        max_iterations: opts.max_iterations,
        beta: Beta::PolakRibiereExpanded,
        line_search: RcgLineSearch::Interpolating { max_evaluations: opts.max_line_search, c1: opts.c1 },
        stop: StopRule::Tolerances { rel_tol: opts.rel_tol, grad_tol: opts.grad_tol },
        retry_steepest_descent: true,
    }
}

/// Minimizes `obj` over rank-k matrices from `x0` by Riemannian conjugate gradients (module
/// documentation; [`crate::optim::rcg::minimize`]). The objective is non-increasing (every step
/// satisfies sufficient decrease). Stops on relative objective change ≤ `rel_tol`, on
/// ‖grad f‖ ≤ `grad_tol`·‖grad f(x₀)‖, at the iteration cap, or when the line search finds no
/// decrease along the gradient. `memory` and `c2` of `opts` are not used.
pub fn minimize(
    obj: &dyn RankObjective,
    x0: RankPoint,
    opts: &OptimizeOptions,
) -> Result<(RankPoint, CompletionReport)> {
    let (r, c) = obj.dims();
    let k = x0.s.len();
    if x0.u.nrows() != r || x0.v.nrows() != c || x0.u.ncols() != k || x0.v.ncols() != k || k == 0 {
        return Err(Error::invalid(
            "initialization",
            format!("the start is {}×{} of rank {k} but the problem is {r}×{c}", x0.u.nrows(), x0.v.nrows()),
        ));
    }
    let min = rcg::minimize(&FixedRank, &mut OnManifold(obj), x0, &rcg_options(opts))?;
    if !min.initial.total.is_finite() {
        return Err(Error::numerical("fixed rank", "the objective is not finite at the initialization"));
    }
    let reason = match min.report.stop {
        Stop::ZeroGradient => "zero gradient at the initialization".to_string(),
        Stop::LineSearchFailed => "line search found no decrease along the negative gradient".to_string(),
        stop => stop.to_string(),
    };
    let report = CompletionReport::new(&min, reason);
    Ok((min.x, report))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::completion::objective::tests::random_problem;
    use crate::completion::testutil::randn;

    fn ambient(x: &RankPoint) -> Mat<f64> {
        mul(x.left().as_ref(), x.v.transpose())
    }

    #[test]
    fn retraction_and_projection_are_consistent() {
        let (r, c, k) = (12, 9, 3);
        let x = RankPoint::from_factors(randn(r, k, 1).as_ref(), randn(c, k, 2).as_ref(), k).unwrap();
        assert!((gemm_tn(x.u.as_ref(), x.u.as_ref()) - Mat::<f64>::identity(k, k)).norm_max() < 1e-12);
        // Project a random ambient H, check tangency (Uᵀ U_p = 0, Vᵀ V_p = 0) and that the
        // projection is the orthogonal one: ⟨H − P(H), ζ⟩ = 0 for a tangent ζ.
        let h = randn(r, c, 3);
        let p = project(&x, mul(h.as_ref(), x.v.as_ref()), mul(h.transpose(), x.u.as_ref()));
        assert!(gemm_tn(x.u.as_ref(), p.up.as_ref()).norm_max() < 1e-12);
        assert!(gemm_tn(x.v.as_ref(), p.vp.as_ref()).norm_max() < 1e-12);
        let amb = |e: &Tangent| {
            mul(mul(x.u.as_ref(), e.m.as_ref()).as_ref(), x.v.transpose())
                + mul(e.up.as_ref(), x.v.transpose())
                + mul(x.u.as_ref(), e.vp.transpose())
        };
        let ph = amb(&p);
        let h2 = randn(r, c, 4);
        let z = project(&x, mul(h2.as_ref(), x.v.as_ref()), mul(h2.transpose(), x.u.as_ref()));
        assert!(frob((&h - &ph).as_ref(), amb(&z).as_ref()).abs() < 1e-10);
        assert!((p.inner(&z) - frob(ph.as_ref(), amb(&z).as_ref())).abs() < 1e-10);
        // Retraction: first order, X + tη ≈ R(tη) for small t, and exact rank k.
        let t = 1e-4;
        let y = retract(&x, &p, t).unwrap();
        let lin = ambient(&x) + &ph * t;
        assert!((ambient(&y) - &lin).norm_l2() < 1e-2 * t * ph.norm_l2());
        assert!((gemm_tn(y.u.as_ref(), y.u.as_ref()) - Mat::<f64>::identity(k, k)).norm_max() < 1e-12);
        // Transport of a tangent vector to the same point is the identity.
        let same = transport(&x, &p, &x);
        assert!((&same.m - &p.m).norm_max() < 1e-12 && (&same.up - &p.up).norm_max() < 1e-12);
        // Retraction with r < 2k: the robust path.
        let x2 = RankPoint::from_factors(randn(5, 3, 5).as_ref(), randn(6, 3, 6).as_ref(), 3).unwrap();
        let h = randn(5, 6, 7);
        let p2 = project(&x2, mul(h.as_ref(), x2.v.as_ref()), mul(h.transpose(), x2.u.as_ref()));
        let y2 = retract(&x2, &p2, 1e-5).unwrap();
        assert!((gemm_tn(y2.u.as_ref(), y2.u.as_ref()) - Mat::<f64>::identity(3, 3)).norm_max() < 1e-12);
    }

    #[test]
    fn riemannian_gradient_matches_finite_differences_along_curves() {
        let p = random_problem(40, 35, 8, 6, 21);
        let params = CompletionParams {
            mu1: 0.1,
            mu2: 0.2,
            mu3: 0.05,
            mu4: 0.0,
            xi: 1e-2,
            mu_comm: 0.01,
            k_comm: 6,
            block_rows: 16,
            ..CompletionParams::default()
        };
        let obj = SubspaceRank { problem: &p, params };
        let x = RankPoint::from_factors(randn(8, 4, 1).as_ref(), randn(8, 4, 2).as_ref(), 4).unwrap();
        let (_, zv, ztu) = obj.egrad(x.left().as_ref(), x.v.as_ref(), x.u.as_ref(), x.v.as_ref());
        let g = project(&x, zv, ztu);
        let h = randn(8, 8, 3);
        let eta = project(&x, mul(h.as_ref(), x.v.as_ref()), mul(h.transpose(), x.u.as_ref()));
        let eps = 1e-5;
        let f = |t: f64| {
            let y = retract(&x, &eta, t).unwrap();
            obj.value(y.left().as_ref(), y.v.as_ref()).total
        };
        let fd = (f(eps) - f(-eps)) / (2.0 * eps);
        let an = g.inner(&eta);
        assert!((fd - an).abs() < 1e-5 * an.abs(), "fd {fd} vs {an}");
    }

    #[test]
    fn rcg_decreases_monotonically_and_reaches_a_stationary_point() {
        let p = random_problem(50, 45, 8, 6, 31);
        let params =
            CompletionParams { mu1: 1e-2, mu2: 1e-2, mu3: 1e-2, xi: 1e-3, block_rows: 16, ..Default::default() };
        let obj = SubspaceRank { problem: &p, params };
        let x0 = RankPoint::from_factors(randn(8, 4, 4).as_ref(), randn(8, 4, 5).as_ref(), 4).unwrap();
        let opts = OptimizeOptions { rel_tol: 1e-14, grad_tol: 1e-7, max_iterations: 3000, ..Default::default() };
        let (x, rep) = minimize(&obj, x0, &opts).unwrap();
        assert!(rep.objective_history.windows(2).all(|w| w[1] <= w[0]));
        assert!(rep.gradient_norm_final < 1e-4 * rep.gradient_norm_initial, "{rep:?}");
        assert_eq!(x.s.len(), 4);
        eprintln!(
            "RCG: {} iterations, f {:.4e} → {:.4e}, ({})",
            rep.iterations, rep.initial_terms.total, rep.terms.total, rep.stop_reason
        );
    }
}
