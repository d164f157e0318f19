//! Unconstrained minimization by L-BFGS with a strong-Wolfe line search (Nocedal & Wright,
//! Algorithms 7.4, 3.5 and 3.6), over a flat vector of variables. Used by the subspace form (11)
//! (variables A, B) and the factored forms (8), (10) (variables U, V).

use std::collections::VecDeque;
use std::time::Instant;

use super::objective::Terms;
use serde::Serialize;

use crate::error::{Error, Result};

/// Options of the completion optimizers ([`super::optimize`], [`minimize`], the Riemannian CG of
/// the fixed-rank form).
#[derive(Clone, Debug, Serialize)]
pub struct OptimizeOptions {
    /// Iteration cap.
    pub max_iterations: usize,
    /// Stop when the relative decrease of the objective in one iteration, (f_old − f)/|f_old|,
    /// falls to this value or below.
    pub rel_tol: f64,
    /// Also stop when ‖∇f‖ ≤ `grad_tol`·‖∇f(x₀)‖.
    pub grad_tol: f64,
    /// Number of (s, y) pairs L-BFGS keeps.
    pub memory: usize,
    /// Objective evaluations allowed per line search.
    pub max_line_search: usize,
    /// Sufficient-decrease constant c1 of the Wolfe conditions.
    pub c1: f64,
    /// Curvature constant c2 of the strong Wolfe conditions.
    pub c2: f64,
}

impl Default for OptimizeOptions {
    fn default() -> Self {
        OptimizeOptions {
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

/// What an optimizer of the completion method did.
#[derive(Clone, Debug, Serialize)]
pub struct CompletionReport {
    /// Accepted L-BFGS steps.
    pub iterations: usize,
    /// Objective + gradient evaluations, line searches included.
    pub evaluations: usize,
    /// True when a tolerance was met (not the iteration cap or a failed line search).
    pub converged: bool,
    /// Why the optimization stopped.
    pub stop_reason: String,
    /// The weighted terms at the start.
    pub initial_terms: Terms,
    /// The weighted terms at the end.
    pub terms: Terms,
    /// The objective after each iteration, starting with the initial value.
    pub objective_history: Vec<f64>,
    /// ‖∇f‖ at the start.
    pub gradient_norm_initial: f64,
    /// ‖∇f‖ at the end.
    pub gradient_norm_final: f64,
    /// Wall time of the whole optimization.
    pub seconds_total: f64,
    /// Wall time per iteration (total / max(iterations, 1)).
    pub seconds_per_iteration: f64,
}

impl OptimizeOptions {
    /// The stopping rule shared by the optimizers, after an accepted step from objective
    /// `f_old` to `f` with gradient norm `g_norm` (`g0_norm` at the start): why to stop, if so.
    pub(crate) fn converged(&self, f_old: f64, f: f64, g_norm: f64, g0_norm: f64) -> Option<String> {
        if f_old - f <= self.rel_tol * f_old.abs() {
            Some(format!("relative objective change ≤ {:e}", self.rel_tol))
        } else if g_norm <= self.grad_tol * g0_norm {
            Some(format!("gradient norm ≤ {:e} of its initial value", self.grad_tol))
        } else {
            None
        }
    }
}

pub(crate) fn dot(x: &[f64], y: &[f64]) -> f64 {
    x.iter().zip(y).map(|(a, b)| a * b).sum()
}

fn axpy(alpha: f64, x: &[f64], y: &[f64]) -> Vec<f64> {
    x.iter().zip(y).map(|(xi, yi)| yi + alpha * xi).collect()
}

/// A point of the line search: step, objective, directional derivative, gradient and terms.
struct Point {
    alpha: f64,
    f: f64,
    d: f64,
    grad: Vec<f64>,
    terms: Terms,
}

/// Minimizer of the cubic through (a0, f0, d0), (a1, f1, d1), safeguarded to the inner 80 % of
/// the interval (bisection when the cubic has no minimizer).
fn cubic_step(lo: &Point, hi: &Point) -> f64 {
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

/// Strong-Wolfe line search (Nocedal & Wright, Algorithms 3.5 and 3.6, cubic interpolation).
/// Returns the accepted point, which always satisfies sufficient decrease; if the curvature
/// condition is not met within the budget, the best sufficient-decrease point found is
/// returned; `None` if there is none.
fn line_search(
    eval: &mut dyn FnMut(f64) -> Point,
    f0: f64,
    d0: f64,
    alpha0: f64,
    opts: &OptimizeOptions,
) -> Option<Point> {
    let armijo = |p: &Point| p.f <= f0 + opts.c1 * p.alpha * d0;
    let curvature = |p: &Point| p.d.abs() <= -opts.c2 * d0;
    let mut best: Option<Point> = None;
    let keep = |p: &Point, best: &mut Option<Point>| {
        if armijo(p) && best.as_ref().is_none_or(|b| p.f < b.f) {
            *best = Some(Point { alpha: p.alpha, f: p.f, d: p.d, grad: p.grad.clone(), terms: p.terms.clone() });
        }
    };
    let mut prev = Point { alpha: 0.0, f: f0, d: d0, grad: Vec::new(), terms: Terms::default() };
    let mut alpha = alpha0;
    let mut evals = 0;
    // Bracketing phase.
    let (mut lo, mut hi) = loop {
        if evals >= opts.max_line_search {
            return best;
        }
        let p = eval(alpha);
        evals += 1;
        keep(&p, &mut best);
        if !p.f.is_finite() || !armijo(&p) || (evals > 1 && p.f >= prev.f) {
            break (prev, p);
        }
        if curvature(&p) {
            return Some(p);
        }
        if p.d >= 0.0 {
            break (p, prev);
        }
        alpha = 2.0 * p.alpha;
        prev = p;
    };
    // Zoom phase: lo satisfies sufficient decrease with the lowest f so far.
    loop {
        if evals >= opts.max_line_search || (hi.alpha - lo.alpha).abs() < 1e-16 * lo.alpha.abs().max(1e-300) {
            return best;
        }
        let a = if hi.f.is_finite() { cubic_step(&lo, &hi) } else { 0.5 * (lo.alpha + hi.alpha) };
        let p = eval(a);
        evals += 1;
        keep(&p, &mut best);
        if !p.f.is_finite() || !armijo(&p) || p.f >= lo.f {
            hi = p;
        } else {
            if curvature(&p) {
                return Some(p);
            }
            if p.d * (hi.alpha - lo.alpha) >= 0.0 {
                hi = lo;
            }
            lo = p;
        }
    }
}

/// An objective for [`minimize`]: the terms at x (f = `terms.total`) and ∇f(x).
pub type Objective<'a> = dyn FnMut(&[f64]) -> (Terms, Vec<f64>) + 'a;

/// Minimizes f from `x0` by L-BFGS; `eval(x)` returns the terms of f at x (f = `terms.total`)
/// and ∇f(x). Every accepted step satisfies sufficient decrease, so the objective is
/// non-increasing. Stops on relative objective change ≤ `rel_tol`, on ‖∇f‖ ≤ `grad_tol`·‖∇f₀‖,
/// at the iteration cap, or when a line search along steepest descent finds no decrease.
/// Errors when f is not finite at `x0`.
pub fn minimize(x0: Vec<f64>, opts: &OptimizeOptions, eval: &mut Objective) -> Result<(Vec<f64>, CompletionReport)> {
    let start = Instant::now();
    let mut evaluations = 0usize;
    let mut eval_at = |x: &[f64]| {
        evaluations += 1;
        eval(x)
    };
    let mut x = x0;
    let (t0, mut g) = eval_at(&x);
    if !t0.total.is_finite() || g.iter().any(|v| !v.is_finite()) {
        return Err(Error::numerical("optimizer", "the objective or its gradient is not finite at the start"));
    }
    let initial_terms = t0.clone();
    let mut f = t0.total;
    let mut terms = t0;
    let g0_norm = dot(&g, &g).sqrt();
    let mut history = vec![f];
    let mut pairs: VecDeque<(Vec<f64>, Vec<f64>, f64)> = VecDeque::new(); // (s, y, 1/yᵀs)
    let mut iterations = 0;
    let (mut converged, mut stop_reason) = (false, String::from("iteration cap reached"));
    if g0_norm == 0.0 {
        converged = true;
        stop_reason = "zero gradient at the start".into();
    }
    while !converged && iterations < opts.max_iterations {
        // Two-loop recursion: p = −H g.
        let mut q = g.clone();
        let mut alphas = Vec::with_capacity(pairs.len());
        for (s, y, rho) in pairs.iter().rev() {
            let a = rho * dot(s, &q);
            q = axpy(-a, y, &q);
            alphas.push(a);
        }
        if let Some((s, y, _)) = pairs.back() {
            let gamma = dot(s, y) / dot(y, y);
            q.iter_mut().for_each(|v| *v *= gamma);
        }
        for ((s, y, rho), a) in pairs.iter().zip(alphas.iter().rev()) {
            let b = rho * dot(y, &q);
            q = axpy(a - b, s, &q);
        }
        let mut p: Vec<f64> = q.iter().map(|v| -v).collect();
        let mut d0 = dot(&p, &g);
        if d0.is_nan() || d0 >= 0.0 {
            // Not a descent direction: restart from steepest descent.
            pairs.clear();
            p = g.iter().map(|v| -v).collect();
            d0 = dot(&p, &g);
        }
        let alpha0 = if pairs.is_empty() { (1.0 / dot(&p, &p).sqrt()).min(1.0) } else { 1.0 };
        let xc = x.clone();
        let pc = p.clone();
        let mut phi = |alpha: f64| -> Point {
            let xa = axpy(alpha, &pc, &xc);
            let (t, grad) = eval_at(&xa);
            Point { alpha, f: t.total, d: dot(&grad, &pc), grad, terms: t }
        };
        let Some(pt) = line_search(&mut phi, f, d0, alpha0, opts) else {
            if !pairs.is_empty() {
                // Retry from steepest descent before giving up.
                pairs.clear();
                continue;
            }
            stop_reason = "line search found no decrease along the steepest descent direction".into();
            break;
        };
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
        let f_old = f;
        x = x_new;
        f = pt.f;
        g = pt.grad;
        terms = pt.terms;
        iterations += 1;
        history.push(f);
        if let Some(reason) = opts.converged(f_old, f, dot(&g, &g).sqrt(), g0_norm) {
            converged = true;
            stop_reason = reason;
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    let report = CompletionReport {
        iterations,
        evaluations,
        converged,
        stop_reason,
        initial_terms,
        terms,
        objective_history: history,
        gradient_norm_initial: g0_norm,
        gradient_norm_final: dot(&g, &g).sqrt(),
        seconds_total: seconds,
        seconds_per_iteration: seconds / iterations.max(1) as f64,
    };
    Ok((x, report))
}
