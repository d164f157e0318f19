//! Riemannian conjugate gradients (Absil, Mahony & Sepulchre 2008, §8.3; Boumal 2023, §4.8):
//! minimizes f over a manifold M given by the [`Manifold`] trait, from the Euclidean gradient
//! the [`Objective`] supplies.
//!
//! One iteration at x with Riemannian gradient g = P_x(∇f(x)) and direction η:
//! 1. if ⟨g, η⟩ ≥ 0 (or NaN), η = −g;
//! 2. a backtracking line search along t ↦ R_x(t η) finds t with the Armijo condition
//!    f(R_x(t η)) ≤ f(x) + c1 t ⟨g, η⟩ ([`RcgLineSearch`]); if none is found along a conjugate
//!    direction, the iteration is retried along −g (when `retry_steepest_descent`), else the
//!    optimizer stops;
//! 3. at y = R_x(t η), with the new gradient g⁺ and the transports T(g), T(η) to y:
//!    η⁺ = −g⁺ + β T(η), β per [`Beta`];
//! 4. the stopping rule ([`StopRule`]) is tested.
//!
//! The sum in 3. is formed as (−g⁺) + (T(η)·β) and PR's difference as g⁺ + (T(g)·(−1)), so a
//! manifold whose [`Manifold::add_scaled`] computes v + w·a element by element reproduces a
//! hand-written "β T(η) − g⁺" and "g⁺ − T(g)" bit for bit.

use std::time::Instant;

use super::{tolerances_met, Minimum, Report, Stop, Value};
use crate::error::Result;

/// A Riemannian manifold embedded in a Euclidean space, with what conjugate gradients need.
pub trait Manifold {
    /// A point x of M.
    type Point: Clone;
    /// A tangent vector at some point.
    type Tangent: Clone;
    /// A vector of the ambient space (a Euclidean gradient), in whatever form
    /// [`Manifold::project`] needs (e.g. only its products with the point's factors).
    type Ambient;
    /// The metric ⟨u, v⟩_x of two tangent vectors at `x`.
    fn inner(&self, x: &Self::Point, u: &Self::Tangent, v: &Self::Tangent) -> f64;
    /// a·v.
    fn scale(&self, v: &Self::Tangent, a: f64) -> Self::Tangent;
    /// v + a·w (v and w tangent at the same point).
    fn add_scaled(&self, v: &Self::Tangent, a: f64, w: &Self::Tangent) -> Self::Tangent;
    /// The orthogonal projection of an ambient vector onto the tangent space at `x`: applied to
    /// the Euclidean gradient it is the Riemannian gradient (embedded submanifolds with the
    /// induced metric).
    fn project(&self, x: &Self::Point, v: Self::Ambient) -> Self::Tangent;
    /// The retraction R_x(t v).
    fn retract(&self, x: &Self::Point, v: &Self::Tangent, t: f64) -> Result<Self::Point>;
    /// The transport of `v` (tangent at `from`) to the tangent space at `to`.
    fn transport(&self, from: &Self::Point, v: &Self::Tangent, to: &Self::Point) -> Self::Tangent;
    /// A length scale of `x` (its ambient norm for embedded manifolds): the first trial step of
    /// [`RcgLineSearch::Interpolating`] moves by 0.1·‖x‖.
    fn point_norm(&self, x: &Self::Point) -> f64;
}

/// An objective on the manifold `M`: f and its Euclidean gradient.
pub trait Objective<M: Manifold> {
    /// What the objective returns: f itself or a record of terms ([`Value`]).
    type Value: Value;
    /// f(x).
    fn value(&mut self, x: &M::Point) -> Self::Value;
    /// f(x) and the Euclidean gradient ∇f(x) (an ambient vector; the optimizer projects it).
    fn gradient(&mut self, x: &M::Point) -> (Self::Value, M::Ambient);
}

/// The conjugate-direction coefficient β of η⁺ = −g⁺ + β T(η) (T: transport to the new point,
/// g: the previous Riemannian gradient).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Beta {
    /// Polak–Ribière⁺: β = max(0, ⟨g⁺, g⁺ − T(g)⟩ / ‖g‖²), the difference formed first.
    PolakRibiere,
    /// The same Polak–Ribière⁺ β evaluated as max(0, (‖g⁺‖² − ⟨g⁺, T(g)⟩) / ‖g‖²): two inner
    /// products, which round differently.
    PolakRibiereExpanded,
    /// Fletcher–Reeves: β = ‖g⁺‖² / ‖g‖².
    FletcherReeves,
}

/// The backtracking line search along t ↦ R_x(t η) (φ(t) = f(R_x(t η)), φ'(0) = ⟨g, η⟩ < 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RcgLineSearch {
    /// First step Nocedal's 2 (f_k − f_{k−1}) / φ'(0) capped at a move of 10‖x‖ (a move of
    /// 0.1‖x‖ on the first iteration or when f did not decrease; ‖x‖ per
    /// [`Manifold::point_norm`]); then quadratic interpolation of φ safeguarded to
    /// [0.1 t, 0.5 t]. Trials evaluate f only; the gradient is evaluated at the accepted point.
    Interpolating {
        /// Trial steps allowed per line search.
        max_evaluations: usize,
        /// Sufficient-decrease constant c1.
        c1: f64,
    },
    /// First step twice the previously accepted one (2 on the first iteration), halved until
    /// accepted. Every trial evaluates f and its gradient (the accepted one's is kept).
    Halving {
        /// Trial steps allowed per line search.
        max_trials: usize,
        /// Sufficient-decrease constant c1.
        c1: f64,
    },
}

/// When to stop, tested after each accepted step from f_old to f.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StopRule {
    /// (f_old − f) ≤ `rel_tol`·|f_old| ([`Stop::RelativeChange`]), or ‖g‖ ≤ `grad_tol`·‖g₀‖
    /// ([`Stop::GradientTolerance`]).
    Tolerances {
        /// Relative decrease tolerance.
        rel_tol: f64,
        /// Gradient-norm tolerance relative to the start.
        grad_tol: f64,
    },
    /// (f_old − f) ≤ `tol`·max(|f|, `floor`) on `repeats` consecutive iterations
    /// ([`Stop::SmallDecrease`]).
    SmallDecrease {
        /// Relative decrease tolerance.
        tol: f64,
        /// Resolution of f: decreases below `tol`·`floor` count as small whatever f.
        floor: f64,
        /// Consecutive small decreases that stop the optimizer.
        repeats: usize,
    },
}

/// Options of [`minimize`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RcgOptions {
    /// Cap on accepted steps.
    pub max_iterations: usize,
    /// The conjugate-direction rule.
    pub beta: Beta,
    /// The line search.
    pub line_search: RcgLineSearch,
    /// The stopping rule.
    pub stop: StopRule,
    /// When the line search fails along a conjugate direction, retry along −g (else stop).
    pub retry_steepest_descent: bool,
}

impl Default for RcgOptions {
    /// 300 iterations, Polak–Ribière⁺, the interpolating line search (25 trials, c1 = 1e-4),
    /// relative tolerance 1e-6 and gradient tolerance 1e-10, retry along −g.
    fn default() -> Self {
        RcgOptions {
            max_iterations: 300,
            beta: Beta::PolakRibiere,
            line_search: RcgLineSearch::Interpolating { max_evaluations: 25, c1: 1e-4 },
            stop: StopRule::Tolerances { rel_tol: 1e-6, grad_tol: 1e-10 },
            retry_steepest_descent: true,
        }
    }
}

/// An accepted step: the new point, its value and Riemannian gradient, the step t.
type Step<M, V> = (<M as Manifold>::Point, V, <M as Manifold>::Tangent, f64);

/// Minimizes `obj` over `manifold` from `x0` by Riemannian conjugate gradients (module
/// documentation). The objective is non-increasing (every step satisfies sufficient decrease).
/// Stops per `opts.stop`, at `opts.max_iterations` accepted steps, when the gradient is zero
/// ([`Stop::ZeroGradient`]) or not finite ([`Stop::NotFinite`]; at the start too, with no step,
/// the caller decides whether that is an error), or when no step is found
/// ([`Stop::LineSearchFailed`]). Errors only when the retraction does.
pub fn minimize<M, O>(manifold: &M, obj: &mut O, x0: M::Point, opts: &RcgOptions) -> Result<Minimum<M::Point, O::Value>>
where
    M: Manifold,
    O: Objective<M>,
{
    let start = Instant::now();
    let mut evaluations = 0usize;
    let mut x = x0;
    let (v0, e0) = obj.gradient(&x);
    evaluations += 1;
    let mut g = manifold.project(&x, e0);
    let initial = v0.clone();
    let mut value = v0;
    let mut f = value.value();
    let g0_norm = manifold.inner(&x, &g, &g).sqrt();
    let mut eta = manifold.scale(&g, -1.0);
    let mut history = vec![f];
    let mut iterations = 0;
    let mut f_prev: Option<f64> = None;
    let mut last_step = 1.0;
    let mut small = 0;
    let mut stop = if f.is_finite() { None } else { Some(Stop::NotFinite) };
    while stop.is_none() {
        let gg = manifold.inner(&x, &g, &g);
        if gg == 0.0 {
            stop = Some(Stop::ZeroGradient);
            break;
        }
        if !gg.is_finite() {
            stop = Some(Stop::NotFinite);
            break;
        }
        if iterations >= opts.max_iterations {
            break;
        }
        let mut d0 = manifold.inner(&x, &g, &eta);
        if d0.is_nan() || d0 >= 0.0 {
            eta = manifold.scale(&g, -1.0);
            d0 = -gg;
        }
        let step: Option<Step<M, O::Value>> = match opts.line_search {
            RcgLineSearch::Interpolating { max_evaluations, c1 } => {
                let eta_norm = manifold.inner(&x, &eta, &eta).sqrt();
                let xnorm = manifold.point_norm(&x).max(1e-300);
                let mut t = match f_prev {
                    Some(fp) if fp > f => (2.0 * (fp - f) / -d0).min(10.0 * xnorm / eta_norm),
                    _ => 0.1 * xnorm / eta_norm,
                };
                let mut accepted = None;
                for _ in 0..max_evaluations {
                    let y = manifold.retract(&x, &eta, t)?;
                    evaluations += 1;
                    let fy = obj.value(&y).value();
                    if fy.is_finite() && fy <= f + c1 * t * d0 {
                        accepted = Some(y);
                        break;
                    }
                    // Quadratic interpolation of φ(t), safeguarded to [0.1 t, 0.5 t].
                    let denom = 2.0 * (fy - f - d0 * t);
                    let tq = if fy.is_finite() && denom > 0.0 { -d0 * t * t / denom } else { 0.5 * t };
                    t = tq.clamp(0.1 * t, 0.5 * t);
                }
                match accepted {
                    Some(y) => {
                        let (vy, ey) = obj.gradient(&y);
                        evaluations += 1;
                        let gy = manifold.project(&y, ey);
                        Some((y, vy, gy, t))
                    }
                    None => None,
                }
            }
            RcgLineSearch::Halving { max_trials, c1 } => {
                let mut t = 2.0 * last_step;
                let mut accepted = None;
                for _ in 0..max_trials {
                    let y = manifold.retract(&x, &eta, t)?;
                    let (vy, ey) = obj.gradient(&y);
                    evaluations += 1;
                    let fy = vy.value();
                    if fy.is_finite() && fy <= f + c1 * t * d0 {
                        accepted = Some((y, vy, ey));
                        break;
                    }
                    t *= 0.5;
                }
                accepted.map(|(y, vy, ey)| {
                    let gy = manifold.project(&y, ey);
                    (y, vy, gy, t)
                })
            }
        };
        let Some((y, vy, gy, t)) = step else {
            if opts.retry_steepest_descent && d0 != -gg {
                // Retry along the negative gradient before giving up.
                eta = manifold.scale(&g, -1.0);
                continue;
            }
            stop = Some(Stop::LineSearchFailed);
            break;
        };
        let eta_old = manifold.transport(&x, &eta, &y);
        let beta = match opts.beta {
            Beta::PolakRibiere => {
                let g_old = manifold.transport(&x, &g, &y);
                let diff = manifold.add_scaled(&gy, -1.0, &g_old);
                (manifold.inner(&y, &gy, &diff) / gg).max(0.0)
            }
            Beta::PolakRibiereExpanded => {
                let g_old = manifold.transport(&x, &g, &y);
                ((manifold.inner(&y, &gy, &gy) - manifold.inner(&y, &gy, &g_old)) / gg).max(0.0)
            }
            Beta::FletcherReeves => manifold.inner(&y, &gy, &gy) / gg,
        };
        eta = manifold.add_scaled(&manifold.scale(&gy, -1.0), beta, &eta_old);
        f_prev = Some(f);
        last_step = t;
        let f_old = f;
        x = y;
        g = gy;
        value = vy;
        f = value.value();
        iterations += 1;
        history.push(f);
        stop = match opts.stop {
            StopRule::Tolerances { rel_tol, grad_tol } => {
                tolerances_met(rel_tol, grad_tol, f_old, f, manifold.inner(&x, &g, &g).sqrt(), g0_norm)
            }
            StopRule::SmallDecrease { tol, floor, repeats } => {
                if f_old - f <= tol * f.abs().max(floor) {
                    small += 1;
                    (small >= repeats).then_some(Stop::SmallDecrease)
                } else {
                    small = 0;
                    None
                }
            }
        };
    }
    let report = Report {
        iterations,
        evaluations,
        stop: stop.unwrap_or(Stop::IterationCap),
        objective_history: history,
        gradient_norm_initial: g0_norm,
        gradient_norm_final: manifold.inner(&x, &g, &g).sqrt(),
        seconds_total: start.elapsed().as_secs_f64(),
    };
    Ok(Minimum { x, value, initial, report })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The unit sphere Sⁿ⁻¹ ⊂ Rⁿ: projection v − ⟨x, v⟩ x, retraction (x + t v)/‖x + t v‖,
    /// transport by projection.
    struct Sphere;

    use crate::linalg::dot;

    impl Manifold for Sphere {
        type Point = Vec<f64>;
        type Tangent = Vec<f64>;
        type Ambient = Vec<f64>;
        fn inner(&self, _: &Vec<f64>, u: &Vec<f64>, v: &Vec<f64>) -> f64 {
            dot(u, v)
        }
        fn scale(&self, v: &Vec<f64>, a: f64) -> Vec<f64> {
            v.iter().map(|x| x * a).collect()
        }
        fn add_scaled(&self, v: &Vec<f64>, a: f64, w: &Vec<f64>) -> Vec<f64> {
            v.iter().zip(w).map(|(x, y)| x + y * a).collect()
        }
        fn project(&self, x: &Vec<f64>, v: Vec<f64>) -> Vec<f64> {
            let c = dot(x, &v);
            v.iter().zip(x).map(|(vi, xi)| vi - c * xi).collect()
        }
        fn retract(&self, x: &Vec<f64>, v: &Vec<f64>, t: f64) -> Result<Vec<f64>> {
            let y = self.add_scaled(x, t, v);
            let n = dot(&y, &y).sqrt();
            Ok(y.iter().map(|a| a / n).collect())
        }
        fn transport(&self, _: &Vec<f64>, v: &Vec<f64>, to: &Vec<f64>) -> Vec<f64> {
            self.project(to, v.clone())
        }
        fn point_norm(&self, _: &Vec<f64>) -> f64 {
            1.0
        }
    }

    /// The Rayleigh quotient xᵀ A x on the sphere (A symmetric, n × n, row-major); Euclidean
    /// gradient 2 A x.
    struct Rayleigh {
        a: Vec<f64>,
        n: usize,
    }

    impl Rayleigh {
        fn ax(&self, x: &[f64]) -> Vec<f64> {
            (0..self.n).map(|i| dot(&self.a[i * self.n..(i + 1) * self.n], x)).collect()
        }
    }

    impl Objective<Sphere> for Rayleigh {
        type Value = f64;
        fn value(&mut self, x: &Vec<f64>) -> f64 {
            dot(x, &self.ax(x))
        }
        fn gradient(&mut self, x: &Vec<f64>) -> (f64, Vec<f64>) {
            let ax = self.ax(x);
            (dot(x, &ax), ax.iter().map(|v| 2.0 * v).collect())
        }
    }

    /// A = H diag(λ) H with the Householder reflection H = I − 2 w wᵀ/‖w‖² (symmetric,
    /// orthogonal), λ = (3, −1, 2, 5, 0.5): the smallest eigenvalue is −1 with eigenvector H e₂.
    fn problem() -> (Rayleigh, Vec<f64>, f64) {
        let n = 5;
        let w = [1.0, 2.0, -1.0, 0.5, 1.5];
        let ww = dot(&w, &w);
        let h = |i: usize, j: usize| if i == j { 1.0 } else { 0.0 } - 2.0 * w[i] * w[j] / ww;
        let lambda = [3.0, -1.0, 2.0, 5.0, 0.5];
        let a = (0..n * n).map(|k| (0..n).map(|t| h(k / n, t) * lambda[t] * h(t, k % n)).sum()).collect();
        let v = (0..n).map(|i| h(i, 1)).collect();
        (Rayleigh { a, n }, v, -1.0)
    }

    #[test]
    fn rayleigh_quotient_on_the_sphere_gives_the_smallest_eigenvector() {
        let (mut obj, v_min, l_min) = problem();
        let x0: Vec<f64> = {
            let x = [1.0, 1.0, 1.0, 1.0, 1.0];
            x.iter().map(|a| a / 5f64.sqrt()).collect()
        };
        let interpolating = RcgLineSearch::Interpolating { max_evaluations: 25, c1: 1e-4 };
        let halving = RcgLineSearch::Halving { max_trials: 60, c1: 1e-4 };
        let tolerances = StopRule::Tolerances { rel_tol: 0.0, grad_tol: 1e-10 };
        for beta in [Beta::PolakRibiere, Beta::PolakRibiereExpanded, Beta::FletcherReeves] {
            for line_search in [interpolating, halving] {
                let opts =
                    RcgOptions { max_iterations: 2000, beta, line_search, stop: tolerances, ..Default::default() };
                let m = minimize(&Sphere, &mut obj, x0.clone(), &opts).unwrap();
                let r = &m.report;
                eprintln!(
                    "{beta:?}, {line_search:?}: {} iterations, {} evaluations, {}",
                    r.iterations, r.evaluations, r.stop
                );
                assert!(r.converged(), "{beta:?} {line_search:?}: {}", r.stop);
                assert!(r.objective_history.windows(2).all(|w| w[1] <= w[0]));
                assert!((m.value - l_min).abs() < 1e-12, "{beta:?} {line_search:?}: f = {}", m.value);
                assert!((dot(&m.x, &m.x) - 1.0).abs() < 1e-14);
                let cos = dot(&m.x, &v_min).abs();
                assert!(1.0 - cos < 1e-10, "{beta:?} {line_search:?}: |⟨x, v⟩| = {cos}");
            }
        }
        // The small-decrease rule stops too, near the same point.
        let opts = RcgOptions {
            line_search: halving,
            stop: StopRule::SmallDecrease { tol: 1e-14, floor: 1e-12, repeats: 2 },
            retry_steepest_descent: false,
            max_iterations: 2000,
            ..Default::default()
        };
        let m = minimize(&Sphere, &mut obj, x0, &opts).unwrap();
        assert!(
            matches!(m.report.stop, Stop::SmallDecrease | Stop::ZeroGradient | Stop::LineSearchFailed),
            "{}",
            m.report.stop
        );
        assert!(1.0 - dot(&m.x, &v_min).abs() < 1e-8);
    }

    #[test]
    fn stops_at_once_at_a_critical_point_or_a_non_finite_start() {
        // A = diag(λ): at x = e₂ the Riemannian gradient 2 A x − 2 (xᵀ A x) x is exactly zero.
        let lambda = [3.0, -1.0, 2.0];
        let mut obj = Rayleigh { a: (0..9).map(|k| if k / 3 == k % 3 { lambda[k / 3] } else { 0.0 }).collect(), n: 3 };
        let m = minimize(&Sphere, &mut obj, vec![0.0, 1.0, 0.0], &RcgOptions::default()).unwrap();
        assert_eq!((m.report.stop, m.report.iterations, m.value), (Stop::ZeroGradient, 0, -1.0));
        assert!(m.report.converged());
        let m = minimize(&Sphere, &mut obj, vec![f64::NAN; 3], &RcgOptions::default()).unwrap();
        assert_eq!((m.report.stop, m.report.iterations), (Stop::NotFinite, 0));
    }
}
