//! General smooth optimizers; the modules that use them only supply objectives.
//!
//! - [`lbfgs`]: unconstrained minimization of f: Rⁿ → R by L-BFGS with a strong-Wolfe line
//!   search ([`lbfgs::minimize`], `lbfgs::line_search`). The objective is a closure that
//!   returns f(x) and writes ∇f(x) into a buffer the optimizer provides.
//! - [`rcg`]: Riemannian conjugate gradients ([`rcg::minimize`]) on any manifold described by
//!   the small [`rcg::Manifold`] trait (metric, projection of a Euclidean gradient onto the
//!   tangent space, retraction, vector transport); the objective ([`rcg::Objective`]) gives f
//!   and its Euclidean gradient.
//!
//! Layer 0 (beside `crate::linalg`): this module imports nothing from the rest of the crate
//! but [`crate::error`]. Users: `completion` (the subspace, low-norm and fixed-rank forms) and
//! `fmap::coupled` (eq. (7) on O(k) × O(k)).
//!
//! An objective may return more than the number f, e.g. the separate terms of a sum: anything
//! that implements [`Value`]. The optimizers hand back the value at the start and at the
//! solution ([`Minimum`]) together with a [`Report`] of what they did.

use std::fmt;

use serde::Serialize;

pub mod lbfgs;
pub mod rcg;

pub use lbfgs::LbfgsOptions;
pub use rcg::{Beta, Manifold, Objective, RcgLineSearch, RcgOptions, StopRule};

/// What an objective returns at a point: f itself (`f64`) or a richer record whose
/// [`Value::value`] is f (e.g. the weighted terms of a sum and their total).
pub trait Value: Clone {
    /// f, the number the optimizer minimizes.
    fn value(&self) -> f64;
}

impl Value for f64 {
    fn value(&self) -> f64 {
        *self
    }
}

/// Why an optimizer stopped.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum Stop {
    /// The iteration cap was reached.
    IterationCap,
    /// The relative decrease (f_old − f)/|f_old| of one iteration fell to this tolerance.
    RelativeChange(f64),
    /// ‖∇f‖ fell to this fraction of its initial value.
    GradientTolerance(f64),
    /// The gradient is exactly zero.
    ZeroGradient,
    /// The line search found no acceptable step along the steepest-descent direction.
    LineSearchFailed,
    /// The decrease of f stayed below its tolerance on consecutive iterations
    /// ([`StopRule::SmallDecrease`]).
    SmallDecrease,
    /// f or its gradient is not finite (at the start, or the gradient after a step).
    NotFinite,
    /// The caller's monitor ([`lbfgs::minimize_monitored`]) found the result settled: the
    /// fraction of a point map that changed since its last check fell to this tolerance.
    Settled(f64),
}

impl Stop {
    /// True when a tolerance was met or the gradient vanished (not the iteration cap, a failed
    /// line search or a non-finite value).
    pub fn converged(&self) -> bool {
        matches!(
            self,
            Stop::RelativeChange(_)
                | Stop::GradientTolerance(_)
                | Stop::ZeroGradient
                | Stop::SmallDecrease
                | Stop::Settled(_)
        )
    }
}

impl fmt::Display for Stop {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Stop::IterationCap => write!(f, "iteration cap reached"),
            Stop::RelativeChange(t) => write!(f, "relative objective change ≤ {t:e}"),
            Stop::GradientTolerance(t) => write!(f, "gradient norm ≤ {t:e} of its initial value"),
            Stop::ZeroGradient => write!(f, "zero gradient"),
            Stop::LineSearchFailed => write!(f, "line search found no decrease along the steepest descent direction"),
            Stop::SmallDecrease => write!(f, "objective decrease below tolerance on consecutive iterations"),
            Stop::NotFinite => write!(f, "the objective or its gradient is not finite"),
            Stop::Settled(t) => write!(f, "point map settled (≤ {t:e} of it changed since the last check)"),
        }
    }
}

/// What an optimizer did (independent of the objective).
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Accepted steps.
    pub iterations: usize,
    /// Objective evaluations (value only, or value and gradient), line searches included.
    pub evaluations: usize,
    /// Why the optimizer stopped.
    pub stop: Stop,
    /// f after each accepted step, starting with f(x₀) (length `iterations` + 1).
    pub objective_history: Vec<f64>,
    /// ‖∇f(x₀)‖ (the Riemannian gradient's norm in the metric of the manifold for [`rcg`]).
    pub gradient_norm_initial: f64,
    /// ‖∇f‖ at the solution.
    pub gradient_norm_final: f64,
    /// Wall time of the whole optimization, seconds.
    pub seconds_total: f64,
}

impl Report {
    /// True when a tolerance was met ([`Stop::converged`]).
    pub fn converged(&self) -> bool {
        self.stop.converged()
    }

    /// Wall time per accepted step, seconds (total / max(iterations, 1)).
    pub fn seconds_per_iteration(&self) -> f64 {
        self.seconds_total / self.iterations.max(1) as f64
    }
}

/// The result of a minimization.
#[derive(Clone, Debug)]
pub struct Minimum<P, V> {
    /// The solution (the last accepted point).
    pub x: P,
    /// What the objective returned at `x`.
    pub value: V,
    /// What the objective returned at the start.
    pub initial: V,
    /// What the optimizer did.
    pub report: Report,
}

/// The stopping test after an accepted step from f_old to f with gradient norm `g_norm`
/// (`g0_norm` at the start): relative decrease ≤ `rel_tol`, else ‖∇f‖ ≤ `grad_tol`·‖∇f₀‖.
pub(crate) fn tolerances_met(
    rel_tol: f64,
    grad_tol: f64,
    f_old: f64,
    f: f64,
    g_norm: f64,
    g0_norm: f64,
) -> Option<Stop> {
    if f_old - f <= rel_tol * f_old.abs() {
        Some(Stop::RelativeChange(rel_tol))
    } else if g_norm <= grad_tol * g0_norm {
        Some(Stop::GradientTolerance(grad_tol))
    } else {
        None
    }
}
