//! Settings, algorithm choice and statistics of the box QP solver of the damage step (5.2)
//! ([`super`]).

use crate::algebra::linalg::FactorKind;

/// Settings of [`BoxQpSolver`](super::BoxQpSolver).
#[derive(Debug, Clone, Copy)]
pub struct BoxQpSettings {
    /// Tolerance on the scaled KKT residual of
    /// [`box_qp_kkt_residual`](super::box_qp_kkt_residual) (default `1e-12`).
    pub tolerance: f64,
    /// Maximum number of iterations, primal–dual active set and projected Newton steps together
    /// (default 100). The active set phase may use at most half of them.
    pub max_iterations: usize,
    /// Simplicial or supernodal Cholesky factor of `A` for [`BoxQpMethod::ActiveSet`]
    /// (default [`FactorKind::Simplicial`]; see the [module documentation](super)).
    pub factorization: FactorKind,
    /// The algorithm (default [`BoxQpMethod::MonotoneMultigrid`]).
    pub method: BoxQpMethod,
}

/// Algorithm of [`BoxQpSolver`](super::BoxQpSolver) (see the [module documentation](super)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BoxQpMethod {
    /// Truncated nonsmooth Newton multigrid (Gräser & Kornhuber 2009) on an algebraic
    /// smoothed-aggregation hierarchy of `A`: no factorization of `A`, iteration counts
    /// independent of the mesh size.
    #[default]
    MonotoneMultigrid,
    /// Primal–dual active set method with a projected Newton safeguard; reduced systems by
    /// conjugate gradients preconditioned with one Cholesky factor of `A`.
    ActiveSet,
}

impl Default for BoxQpSettings {
    fn default() -> Self {
        Self {
            tolerance: 1e-12,
            max_iterations: 100,
            factorization: FactorKind::Simplicial,
            method: BoxQpMethod::MonotoneMultigrid,
        }
    }
}

/// Statistics of one call of [`BoxQpSolver::solve`](super::BoxQpSolver::solve).
#[derive(Debug, Clone, Default)]
pub struct BoxQpStats {
    /// Outer iterations performed: with [`BoxQpMethod::MonotoneMultigrid`] one projected
    /// Gauss–Seidel sweep, truncated coarse correction and line search each; with
    /// [`BoxQpMethod::ActiveSet`] active set steps plus projected Newton steps. 0 if the start
    /// already satisfied the tolerance.
    pub iterations: usize,
    /// Numeric Cholesky factorizations computed in this call: 1 in the first call of a solver
    /// with [`BoxQpMethod::ActiveSet`] (the factor of `A`), 0 afterwards and in the iterations
    /// of [`BoxQpMethod::MonotoneMultigrid`]; plus 1 when
    /// [`BoxQpSolver::solve_predicted`](super::BoxQpSolver::solve_predicted) factorized for a
    /// new bound set.
    pub factorizations: usize,
    /// Preconditioned conjugate gradient iterations of all reduced solves (linear
    /// corrections) in this call; each costs one product with `A` and one preconditioner
    /// application: a solve with the factor of `A` (two triangular solves) for
    /// [`BoxQpMethod::ActiveSet`], one truncated V-cycle for [`BoxQpMethod::MonotoneMultigrid`].
    pub inner_iterations: usize,
    /// Truncations of the multigrid hierarchy (recomputed coarse matrices) in this call: one
    /// per change of the set of indices on a bound ([`BoxQpMethod::MonotoneMultigrid`]).
    pub coarse_updates: usize,
    /// Iterations of the coarse obstacle solves in this call, all levels together
    /// ([`BoxQpMethod::MonotoneMultigrid`] on at least 2000 unknowns; each costs about a
    /// ninth of a fine iteration in 2D per level down).
    pub coarse_iterations: usize,
    /// Scaled KKT residual of the returned `x` (see
    /// [`box_qp_kkt_residual`](super::box_qp_kkt_residual)).
    pub kkt_residual: f64,
    /// Number of indices with `x_i = lower_i` (including fixed indices with `lower_i = upper_i`).
    pub lower_active: usize,
    /// Number of indices with `x_i = upper_i` and `lower_i < upper_i`.
    pub upper_active: usize,
    /// Whether the projected Newton safeguard was needed (PDAS cycled or exhausted its budget;
    /// [`BoxQpMethod::ActiveSet`] only).
    pub used_fallback: bool,
    /// Whether the solution is the solve on the predicted bound set of
    /// [`BoxQpSolver::solve_predicted`](super::BoxQpSolver::solve_predicted) (counted as one
    /// iteration; its factorization, when the set was new, among the `factorizations`).
    pub bound_set_solve: bool,
}
