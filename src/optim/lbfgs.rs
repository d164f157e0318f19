//! Unconstrained minimization of f: Rⁿ → R by L-BFGS with a strong-Wolfe line search (Nocedal &
//! Wright, Algorithms 7.4, 3.5 and 3.6), over a flat vector of n variables.
//!
//! The objective is a closure `f(x, grad) -> V`: it returns f(x) (as any [`Value`], e.g. a plain
//! `f64`) and writes ∇f(x) into `grad` (length n, provided by the optimizer; its previous content
//! is unspecified).

use std::collections::VecDeque;
use std::time::Instant;

use serde::Serialize;

use super::{tolerances_met, Minimum, Report, Stop, Value};
use crate::error::{Error, Result};

/// Options of [`minimize`] and `line_search`.
#[derive(Clone, Debug, Serialize)]
pub struct LbfgsOptions {
    /// Iteration cap.
    pub max_iterations: usize,
    /// Stop when the relative decrease of the objective in one iteration, (f_old − f)/|f_old|,
    /// falls to this value or below.
    pub rel_tol: f64,
    /// Also stop when ‖∇f‖ ≤ `grad_tol`·‖∇f(x₀)‖.
    pub grad_tol: f64,
    /// Number of (s, y) pairs kept.
    pub memory: usize,
    /// Objective evaluations allowed per line search.
    pub max_line_search: usize,
    /// Sufficient-decrease constant c1 of the Wolfe conditions.
    pub c1: f64,
    /// Curvature constant c2 of the strong Wolfe conditions.
    pub c2: f64,
}

impl Default for LbfgsOptions {
    /// 300 iterations, `rel_tol` 1e-6, `grad_tol` 1e-10, memory 10, 25 evaluations per line
    /// search, c1 = 1e-4, c2 = 0.9.
    fn default() -> Self {
        LbfgsOptions {
            max_iterations: 300,
            rel_tol: 1e-6,
            grad_tol: 1e-10,
            memory: 10,
            max_line_search: 25,
            c1: 1e-4,
            c2: 0.9,
        }
    }
}

pub(crate) use crate::linalg::dot;

fn axpy(alpha: f64, x: &[f64], y: &[f64]) -> Vec<f64> {
    x.iter().zip(y).map(|(xi, yi)| yi + alpha * xi).collect()
}

/// y ← y + α x in place (the two-loop recursion: no 8·n-byte allocation per stored pair).
fn axpy_in_place(alpha: f64, x: &[f64], y: &mut [f64]) {
    y.iter_mut().zip(x).for_each(|(yi, xi)| *yi += alpha * xi);
}

/// A trial point of a line search along x + α p.
#[derive(Clone, Debug)]
pub(crate) struct LinePoint<V> {
    /// The step α.
    pub alpha: f64,
    /// φ(α) = f(x + α p).
    pub f: f64,
    /// φ'(α) = ⟨∇f(x + α p), p⟩.
    pub d: f64,
    /// ∇f(x + α p) (length n).
    pub grad: Vec<f64>,
    /// What the objective returned at x + α p.
    pub value: V,
}

/// Step, value and slope of a point on the line (the line search's bracket ends).
#[derive(Clone, Copy)]
struct Trial {
    alpha: f64,
    f: f64,
    d: f64,
}

impl<V> LinePoint<V> {
    fn trial(&self) -> Trial {
        Trial { alpha: self.alpha, f: self.f, d: self.d }
    }
}

/// Minimizer of the cubic through (a0, f0, d0), (a1, f1, d1), safeguarded to the inner 80 % of
/// the interval (bisection when the cubic has no minimizer).
fn cubic_step(lo: &Trial, hi: &Trial) -> f64 {
    let (a0, a1) = (lo.alpha, hi.alpha);
    let d1 = lo.d + hi.d - 3.0 * (lo.f - hi.f) / (a0 - a1);
    let disc = d1 * d1 - lo.d * hi.d;
    let mid = 0.5 * (a0 + a1);
    let mut a = if disc >= 0.0 {
        let d2 = (a1 - a0).signum() * disc.sqrt();
        a1 - (a1 - a0) * (hi.d + d2 - d1) / (hi.d - lo.d + 2.0 * d2)
    } else {
        mid
    };
    let (left, right) = (a0.min(a1), a0.max(a1));
    let w = right - left;
    if !a.is_finite() || a < left + 0.1 * w || a > right - 0.1 * w {
        a = if a.is_finite() { a.clamp(left + 0.1 * w, right - 0.1 * w) } else { mid };
    }
    a
}

/// Strong-Wolfe line search (Nocedal & Wright, Algorithms 3.5 and 3.6, cubic interpolation) on
/// φ(α) = f(x + α p), from φ(0) = `f0`, φ'(0) = `d0` < 0 and the first trial step `alpha0`;
/// `phi(α)` evaluates the objective there. Uses `max_line_search`, `c1` and `c2` of `opts`.
///
/// Returns the accepted point, which always satisfies sufficient decrease (Armijo,
/// φ(α) ≤ φ(0) + c1 α φ'(0)); if the curvature condition |φ'(α)| ≤ −c2 φ'(0) is not met within
/// the budget, the best sufficient-decrease point found is returned; `None` if there is none.
pub(crate) fn line_search<V: Clone>(
    phi: &mut dyn FnMut(f64) -> LinePoint<V>,
    f0: f64,
    d0: f64,
    alpha0: f64,
    opts: &LbfgsOptions,
) -> Option<LinePoint<V>> {
    let armijo = |p: &Trial| p.f <= f0 + opts.c1 * p.alpha * d0;
    let curvature = |p: &Trial| p.d.abs() <= -opts.c2 * d0;
    let mut best: Option<LinePoint<V>> = None;
    let keep = |p: &LinePoint<V>, best: &mut Option<LinePoint<V>>| {
        if armijo(&p.trial()) && best.as_ref().is_none_or(|b| p.f < b.f) {
            *best = Some(p.clone());
        }
    };
    let mut prev = Trial { alpha: 0.0, f: f0, d: d0 };
    let mut alpha = alpha0;
    let mut evals = 0;
    // Bracketing phase.
    let (mut lo, mut hi) = loop {
        if evals >= opts.max_line_search {
            return best;
        }
        let p = phi(alpha);
        evals += 1;
        keep(&p, &mut best);
        let t = p.trial();
        if !t.f.is_finite() || !armijo(&t) || (evals > 1 && t.f >= prev.f) {
            break (prev, t);
        }
        if curvature(&t) {
            return Some(p);
        }
        if t.d >= 0.0 {
            break (t, prev);
        }
        alpha = 2.0 * t.alpha;
        prev = t;
    };
    // Zoom phase: lo satisfies sufficient decrease with the lowest f so far.
    loop {
        if evals >= opts.max_line_search || (hi.alpha - lo.alpha).abs() < 1e-16 * lo.alpha.abs().max(1e-300) {
            return best;
        }
        let a = if hi.f.is_finite() { cubic_step(&lo, &hi) } else { 0.5 * (lo.alpha + hi.alpha) };
        let p = phi(a);
        evals += 1;
        keep(&p, &mut best);
        let t = p.trial();
        if !t.f.is_finite() || !armijo(&t) || t.f >= lo.f {
            hi = t;
        } else {
            if curvature(&t) {
                return Some(p);
            }
            if t.d * (hi.alpha - lo.alpha) >= 0.0 {
                hi = lo;
            }
            lo = t;
        }
    }
}

/// Minimizes f from `x0` (length n) by L-BFGS; `f(x, grad)` returns f at x (as a [`Value`])
/// and writes ∇f(x) into `grad` (length n). Every accepted step satisfies sufficient decrease,
/// so the objective is non-increasing. Stops on relative objective change ≤ `rel_tol`
/// ([`Stop::RelativeChange`]), on ‖∇f‖ ≤ `grad_tol`·‖∇f₀‖ ([`Stop::GradientTolerance`]), on a
/// zero gradient at the start, at the iteration cap, or when a line search along steepest
/// descent finds no decrease ([`Stop::LineSearchFailed`]). Errors when f or ∇f is not finite at
/// `x0`.
pub fn minimize<V, F>(x0: Vec<f64>, opts: &LbfgsOptions, f: F) -> Result<Minimum<Vec<f64>, V>>
where
    V: Value,
    F: FnMut(&[f64], &mut [f64]) -> V,
{
    minimize_monitored(x0, opts, f, |_, _| None)
}

/// [`minimize`] with a stopping rule of the caller's: after every accepted step,
/// `monitor(iterations, x)` may return a [`Stop`] to end the minimization there (e.g.
/// [`Stop::Settled`] when a quantity derived from x has stopped changing).
pub fn minimize_monitored<V, F, M>(x0: Vec<f64>, opts: &LbfgsOptions, f: F, monitor: M) -> Result<Minimum<Vec<f64>, V>>
where
    V: Value,
    F: FnMut(&[f64], &mut [f64]) -> V,
    M: FnMut(usize, &[f64]) -> Option<Stop>,
{
    minimize_preconditioned(x0, opts, f, monitor, None)
}

/// A preconditioner of [`minimize_preconditioned`]: `precondition(x, v)` replaces v (length n)
/// by P(x) v, where P(x) is a symmetric positive definite approximation of the inverse Hessian
/// of f at the current iterate x (length n), up to a scalar factor: L-BFGS's initial inverse
/// Hessian becomes H₀ = γ P(x) with γ = sᵀy / (yᵀ P(x) y) from the newest pair (the usual
/// scaling sᵀy / yᵀy in the metric of P). A diagonal P is the common choice.
pub type Preconditioner<'a> = dyn FnMut(&[f64], &mut [f64]) + 'a;

/// [`minimize_monitored`] with an optional preconditioner ([`Preconditioner`]): the two-loop
/// recursion starts from H₀ = γ P(x) instead of γ I, and a step with no stored pair (the first,
/// or after a restart) is p = −P(x) ∇f tried first at α = 1 (a Newton-like step when P is a good
/// inverse Hessian). `None` is exactly [`minimize_monitored`]. P is free to change between
/// iterations (e.g. refreshed from x); it must stay positive definite, or a step may not be a
/// descent direction (then L-BFGS restarts from steepest descent, as without P).
pub fn minimize_preconditioned<V, F, M>(
    x0: Vec<f64>,
    opts: &LbfgsOptions,
    mut f: F,
    mut monitor: M,
    mut precondition: Option<&mut Preconditioner>,
) -> Result<Minimum<Vec<f64>, V>>
where
    V: Value,
    F: FnMut(&[f64], &mut [f64]) -> V,
    M: FnMut(usize, &[f64]) -> Option<Stop>,
{
    let start = Instant::now();
    let mut evaluations = 0usize;
    let mut eval_at = |x: &[f64]| {
        evaluations += 1;
        let mut grad = vec![0.0; x.len()];
        let v = f(x, &mut grad);
        (v, grad)
    };
    let mut x = x0;
    let (v0, mut g) = eval_at(&x);
    if !v0.value().is_finite() || g.iter().any(|v| !v.is_finite()) {
        return Err(Error::numerical("optimizer", "the objective or its gradient is not finite at the start"));
    }
    let initial = v0.clone();
    let mut fx = v0.value();
    let mut value = v0;
    let g0_norm = dot(&g, &g).sqrt();
    let mut history = vec![fx];
    let mut pairs: VecDeque<(Vec<f64>, Vec<f64>, f64)> = VecDeque::new(); // (s, y, 1/yᵀs)
    let mut iterations = 0;
    let mut stop = if g0_norm == 0.0 { Some(Stop::ZeroGradient) } else { None };
    // Set after a failed line search: the retry is plain steepest descent (without P).
    let mut steepest = false;
    while stop.is_none() && iterations < opts.max_iterations {
        // Two-loop recursion: p = −H g.
        let mut q = g.clone();
        let mut alphas = Vec::with_capacity(pairs.len());
        for (s, y, rho) in pairs.iter().rev() {
            let a = rho * dot(s, &q);
            axpy_in_place(-a, y, &mut q);
            alphas.push(a);
        }
        let preconditioned = match precondition.as_deref_mut() {
            Some(pc) if !steepest => {
                pc(&x[..], &mut q[..]);
                if let Some((s, y, _)) = pairs.back() {
                    let mut py = y.clone();
                    pc(&x[..], &mut py[..]);
                    let gamma = dot(s, y) / dot(y, &py);
                    q.iter_mut().for_each(|v| *v *= gamma);
                }
                true
            }
            _ => {
                if let Some((s, y, _)) = pairs.back() {
                    let gamma = dot(s, y) / dot(y, y);
                    q.iter_mut().for_each(|v| *v *= gamma);
                }
                false
            }
        };
        for ((s, y, rho), a) in pairs.iter().zip(alphas.iter().rev()) {
            let b = rho * dot(y, &q);
            axpy_in_place(a - b, s, &mut q);
        }
        let mut p: Vec<f64> = q.iter().map(|v| -v).collect();
        let mut d0 = dot(&p, &g);
        let mut descent = preconditioned;
        if d0.is_nan() || d0 >= 0.0 {
            // Not a descent direction: restart from steepest descent.
            pairs.clear();
            p = g.iter().map(|v| -v).collect();
            d0 = dot(&p, &g);
            descent = false;
        }
        let alpha0 = if pairs.is_empty() && !descent { (1.0 / dot(&p, &p).sqrt()).min(1.0) } else { 1.0 };
        let xc = x.clone();
        let pc = p.clone();
        let mut phi = |alpha: f64| -> LinePoint<V> {
            let xa = axpy(alpha, &pc, &xc);
            let (v, grad) = eval_at(&xa);
            LinePoint { alpha, f: v.value(), d: dot(&grad, &pc), grad, value: v }
        };
        let Some(pt) = line_search(&mut phi, fx, d0, alpha0, opts) else {
            if !pairs.is_empty() || descent {
                // Retry from steepest descent before giving up.
                pairs.clear();
                steepest = true;
                continue;
            }
            stop = Some(Stop::LineSearchFailed);
            break;
        };
        steepest = false;
        let x_new = axpy(pt.alpha, &p, &x);
        let s: Vec<f64> = x_new.iter().zip(&x).map(|(a, b)| a - b).collect();
        let y: Vec<f64> = pt.grad.iter().zip(&g).map(|(a, b)| a - b).collect();
        let sy = dot(&s, &y);
        if sy > 1e-12 * dot(&s, &s).sqrt() * dot(&y, &y).sqrt() {
            if pairs.len() == opts.memory.max(1) {
                pairs.pop_front();
            }
            pairs.push_back((s, y, 1.0 / sy));
        }
        let f_old = fx;
        x = x_new;
        fx = pt.f;
        g = pt.grad;
        value = pt.value;
        iterations += 1;
        history.push(fx);
        stop = tolerances_met(opts.rel_tol, opts.grad_tol, f_old, fx, dot(&g, &g).sqrt(), g0_norm);
        if stop.is_none() {
            stop = monitor(iterations, &x);
        }
    }
    let report = Report {
        iterations,
        evaluations,
        stop: stop.unwrap_or(Stop::IterationCap),
        objective_history: history,
        gradient_norm_initial: g0_norm,
        gradient_norm_final: dot(&g, &g).sqrt(),
        seconds_total: start.elapsed().as_secs_f64(),
    };
    Ok(Minimum { x, value, initial, report })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// f = ½ xᵀ A x − bᵀ x with a symmetric positive definite A (n × n, row-major).
    fn quadratic(a: &[f64], b: &[f64], x: &[f64], grad: &mut [f64]) -> f64 {
        let n = b.len();
        let mut f = 0.0;
        for i in 0..n {
            let ax: f64 = (0..n).map(|j| a[i * n + j] * x[j]).sum();
            grad[i] = ax - b[i];
            f += 0.5 * x[i] * ax - b[i] * x[i];
        }
        f
    }

    fn rosenbrock(x: &[f64], grad: &mut [f64]) -> f64 {
        let (a, b) = (1.0 - x[0], x[1] - x[0] * x[0]);
        grad[0] = -2.0 * a - 400.0 * x[0] * b;
        grad[1] = 200.0 * b;
        a * a + 100.0 * b * b
    }

    #[test]
    fn minimizes_a_convex_quadratic() {
        // A = tridiag(−1, 4, −1) (5 × 5, eigenvalues in [2, 6]); solution of A x = b checked by
        // its residual.
        let n: usize = 5;
        let a: Vec<f64> = (0..n * n)
            .map(|k| match (k / n).abs_diff(k % n) {
                0 => 4.0,
                1 => -1.0,
                _ => 0.0,
            })
            .collect();
        let b = [1.0, -2.0, 0.5, 3.0, -1.0];
        let opts = LbfgsOptions { rel_tol: 0.0, grad_tol: 1e-10, ..Default::default() };
        let m = minimize(vec![0.0; n], &opts, |x: &[f64], g: &mut [f64]| quadratic(&a, &b, x, g)).unwrap();
        let r = &m.report;
        assert_eq!(r.stop, Stop::GradientTolerance(1e-10), "{r:?}");
        assert!(r.converged());
        assert!(r.gradient_norm_final <= 1e-10 * r.gradient_norm_initial);
        assert!(r.objective_history.windows(2).all(|w| w[1] <= w[0]));
        assert_eq!(r.objective_history.len(), r.iterations + 1);
        assert!(r.iterations <= 6 * n, "{} iterations on a 5-D quadratic", r.iterations);
        let mut g = vec![0.0; n];
        assert_eq!(quadratic(&a, &b, &m.x, &mut g), m.value);
        assert!(dot(&g, &g).sqrt() < 1e-9);
    }

    #[test]
    fn a_diagonal_preconditioner_speeds_up_an_ill_conditioned_quadratic() {
        // A = S M S (n × n) with M = tridiag(−1, 4, −1) (well conditioned) and S = diag(s_i), s_i
        // from 10⁻¹·⁵ to 10¹·⁵: cond(A) ≈ 10⁶. P = diag(A)⁻¹ removes the scaling.
        let n: usize = 60;
        let sc: Vec<f64> = (0..n).map(|i| 10f64.powf(-1.5 + 3.0 * i as f64 / (n - 1) as f64)).collect();
        let a: Vec<f64> = (0..n * n)
            .map(|k| {
                let (i, j) = (k / n, k % n);
                let m = match i.abs_diff(j) {
                    0 => 4.0,
                    1 => -1.0,
                    _ => 0.0,
                };
                sc[i] * m * sc[j]
            })
            .collect();
        let b: Vec<f64> = (0..n).map(|i| ((i * 7) % 5) as f64 - 2.0).collect();
        let opts = LbfgsOptions { rel_tol: 0.0, grad_tol: 1e-7, max_iterations: 20000, ..Default::default() };
        let f = |x: &[f64], g: &mut [f64]| quadratic(&a, &b, x, g);
        let plain = minimize(vec![0.0; n], &opts, f).unwrap();
        let diag: Vec<f64> = (0..n).map(|i| a[i * n + i]).collect();
        let mut calls = 0usize;
        let mut pc = |_: &[f64], v: &mut [f64]| {
            calls += 1;
            v.iter_mut().zip(&diag).for_each(|(vi, d)| *vi /= d);
        };
        let pc: &mut Preconditioner = &mut pc;
        let pre = minimize_preconditioned(vec![0.0; n], &opts, f, |_, _| None, Some(pc)).unwrap();
        let (rp, rq) = (&plain.report, &pre.report);
        eprintln!("ill-conditioned quadratic: {} iterations plain, {} preconditioned", rp.iterations, rq.iterations);
        assert!(calls > 0);
        assert_eq!(rq.stop, Stop::GradientTolerance(1e-7), "{rq:?}");
        assert!(rq.objective_history.windows(2).all(|w| w[1] <= w[0]));
        assert!(5 * rq.iterations < rp.iterations, "{} vs {}", rq.iterations, rp.iterations);
        // Both reach the unique minimizer A⁻¹ b (checked on the preconditioned one by its
        // residual, and on the difference of the two relative to its norm).
        let mut g = vec![0.0; n];
        quadratic(&a, &b, &pre.x, &mut g);
        assert!(dot(&g, &g).sqrt() < 1e-6, "{}", dot(&g, &g).sqrt());
        // The plain run ends on a flat objective (relative change 0) after thousands of steps, at
        // the same minimum value and nearly the same point.
        assert!((plain.value - pre.value).abs() < 1e-10 * pre.value.abs(), "{} vs {}", plain.value, pre.value);
        let diff: f64 = pre.x.iter().zip(&plain.x).map(|(p, q)| (p - q) * (p - q)).sum::<f64>().sqrt();
        assert!(diff < 1e-3 * dot(&pre.x, &pre.x).sqrt(), "{diff}");
        // Without a preconditioner, minimize_preconditioned is minimize.
        let same = minimize_preconditioned(vec![0.0; n], &opts, f, |_, _| None, None).unwrap();
        assert_eq!((same.x, same.report.iterations), (plain.x.clone(), rp.iterations));
    }

    #[test]
    fn minimizes_rosenbrock() {
        let opts = LbfgsOptions { rel_tol: 0.0, grad_tol: 1e-9, max_iterations: 1000, ..Default::default() };
        let m = minimize(vec![-1.2, 1.0], &opts, rosenbrock).unwrap();
        let r = &m.report;
        eprintln!("Rosenbrock: {} iterations, {} evaluations, f = {:.2e}", r.iterations, r.evaluations, m.value);
        assert_eq!(r.stop, Stop::GradientTolerance(1e-9), "{r:?}");
        assert!(r.gradient_norm_final <= 1e-9 * r.gradient_norm_initial);
        assert!((m.x[0] - 1.0).abs() < 1e-6 && (m.x[1] - 1.0).abs() < 1e-6, "{:?}", m.x);
        assert!(m.value < 1e-12);
        assert!(r.objective_history.windows(2).all(|w| w[1] <= w[0]));
    }

    #[test]
    fn line_search_satisfies_the_wolfe_conditions() {
        // Along p = −∇f from x = (−1.2, 1) on Rosenbrock, from several first steps (too short,
        // about right, far too long): the accepted point meets sufficient decrease (Armijo) and,
        // within the budget, the strong curvature condition.
        let opts = LbfgsOptions::default();
        let x = [-1.2, 1.0];
        let mut g = [0.0; 2];
        let f0 = rosenbrock(&x, &mut g);
        let p = [-g[0], -g[1]];
        let d0 = dot(&p, &g);
        for alpha0 in [1e-6, 1e-3, 1.0, 100.0] {
            let mut phi = |alpha: f64| {
                let xa = [x[0] + alpha * p[0], x[1] + alpha * p[1]];
                let mut grad = vec![0.0; 2];
                let f = rosenbrock(&xa, &mut grad);
                LinePoint { alpha, f, d: dot(&grad, &p), grad, value: f }
            };
            let pt = line_search(&mut phi, f0, d0, alpha0, &opts).expect("a step");
            assert!(pt.alpha > 0.0);
            assert!(pt.f <= f0 + opts.c1 * pt.alpha * d0, "Armijo fails at α = {} (from {alpha0})", pt.alpha);
            assert!(pt.d.abs() <= -opts.c2 * d0, "curvature fails at α = {} (from {alpha0})", pt.alpha);
            assert_eq!(pt.value, pt.f);
        }
        // An ascent direction has no sufficient-decrease point (within a budget of 5 trials,
        // which keeps the steps far above those where f(α) rounds to f(0)).
        let mut up = |alpha: f64| {
            let xa = [x[0] - alpha * p[0], x[1] - alpha * p[1]];
            let mut grad = vec![0.0; 2];
            let f = rosenbrock(&xa, &mut grad);
            LinePoint { alpha, f, d: -dot(&grad, &p), grad, value: () }
        };
        let few = LbfgsOptions { max_line_search: 5, ..opts };
        assert!(line_search(&mut up, f0, d0, 1e-3, &few).is_none());
    }

    #[test]
    fn a_non_finite_start_is_an_error_and_a_zero_gradient_stops_at_once() {
        let opts = LbfgsOptions::default();
        assert!(minimize(vec![1.0], &opts, |_: &[f64], g: &mut [f64]| {
            g[0] = 0.0;
            f64::NAN
        })
        .is_err());
        let m = minimize(vec![2.0], &opts, |x: &[f64], g: &mut [f64]| {
            g[0] = 0.0;
            x[0]
        })
        .unwrap();
        assert_eq!((m.report.stop, m.report.iterations, m.x[0]), (Stop::ZeroGradient, 0, 2.0));
    }
}
