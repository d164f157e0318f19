//! The completion method's interface to the general optimizers of [`crate::optim`]: its options
//! ([`OptimizeOptions`], shared by L-BFGS and the Riemannian CG of the fixed-rank form), its
//! report with the weighted terms of the objective ([`CompletionReport`]), and [`minimize`],
//! L-BFGS with a strong-Wolfe line search ([`crate::optim::lbfgs`]) over a flat vector of
//! variables. Used by the subspace form (11) (variables A, B) and the factored forms (8), (10)
//! (variables U, V).

use super::objective::Terms;
use serde::Serialize;

use crate::error::Result;
use crate::optim::{self, LbfgsOptions, Minimum, Stop};

/// Options of the completion optimizers ([`super::optimize`], `minimize`, the Riemannian CG of
/// the fixed-rank form): the shared L-BFGS options (the CG reads the iteration cap and the two
/// tolerances).
pub type OptimizeOptions = LbfgsOptions;

/// What an optimizer of the completion method did.
#[derive(Clone, Debug, Serialize)]
pub struct CompletionReport {
    /// Accepted steps (of L-BFGS or the Riemannian CG).
    pub iterations: usize,
    /// Objective evaluations (with or without the gradient), line searches included.
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
    /// Wall time of the whole optimization, seconds.
    pub seconds_total: f64,
    /// Wall time per iteration (total / max(iterations, 1)).
    pub seconds_per_iteration: f64,
}

impl optim::Value for Terms {
    /// The objective, `total`.
    fn value(&self) -> f64 {
        self.total
    }
}

impl CompletionReport {
    /// The report of a minimization whose objective returned [`Terms`]; `stop_reason` is the
    /// reason in words (the optimizers word a zero gradient and a failed line search their own
    /// way).
    pub(crate) fn new(min: &Minimum<impl Sized, Terms>, stop_reason: String) -> Self {
        let r = &min.report;
        CompletionReport {
            iterations: r.iterations,
            evaluations: r.evaluations,
            converged: r.converged(),
            stop_reason,
            initial_terms: min.initial.clone(),
            terms: min.value.clone(),
            objective_history: r.objective_history.clone(),
            gradient_norm_initial: r.gradient_norm_initial,
            gradient_norm_final: r.gradient_norm_final,
            seconds_total: r.seconds_total,
            seconds_per_iteration: r.seconds_per_iteration(),
        }
    }
}

/// An objective for [`minimize`]: returns the terms at x (f = `terms.total`) and writes ∇f(x)
/// into the buffer (same length as x).
pub type Objective<'a> = dyn FnMut(&[f64], &mut [f64]) -> Terms + 'a;

/// Minimizes f from `x0` by L-BFGS ([`crate::optim::lbfgs::minimize`]); `eval(x, grad)` returns
/// the terms of f at x (f = `terms.total`) and writes ∇f(x) into `grad`. Every accepted step
/// satisfies sufficient decrease, so the objective is non-increasing. Stops on relative
/// objective change ≤ `rel_tol`, on ‖∇f‖ ≤ `grad_tol`·‖∇f₀‖, at the iteration cap, or when a
/// line search along steepest descent finds no decrease. Errors when f is not finite at `x0`.
pub fn minimize(x0: Vec<f64>, opts: &OptimizeOptions, eval: &mut Objective) -> Result<(Vec<f64>, CompletionReport)> {
    minimize_monitored(x0, opts, eval, &mut |_, _| None)
}

/// [`minimize`] with the caller's stopping rule `monitor(iterations, x)`
/// ([`crate::optim::lbfgs::minimize_monitored`]).
pub fn minimize_monitored(
    x0: Vec<f64>,
    opts: &OptimizeOptions,
    eval: &mut Objective,
    monitor: &mut dyn FnMut(usize, &[f64]) -> Option<Stop>,
) -> Result<(Vec<f64>, CompletionReport)> {
    minimize_preconditioned(x0, opts, eval, monitor, None)
}

/// [`minimize_monitored`] with an optional preconditioner
/// ([`crate::optim::lbfgs::minimize_preconditioned`]; `None`: exactly [`minimize_monitored`]).
pub fn minimize_preconditioned(
    x0: Vec<f64>,
    opts: &OptimizeOptions,
    eval: &mut Objective,
    monitor: &mut dyn FnMut(usize, &[f64]) -> Option<Stop>,
    precondition: Option<&mut optim::lbfgs::Preconditioner>,
) -> Result<(Vec<f64>, CompletionReport)> {
    let min = optim::lbfgs::minimize_preconditioned(
        x0,
        opts,
        |x: &[f64], grad: &mut [f64]| eval(x, grad),
        monitor,
        precondition,
    )?;
    let reason = match min.report.stop {
        Stop::ZeroGradient => "zero gradient at the start".to_string(),
        stop => stop.to_string(),
    };
    let report = CompletionReport::new(&min, reason);
    Ok((min.x, report))
}
