//! Exact solver for the sparse box-constrained quadratic program of the damage step (5.2).
//!
//! # Problem
//! With the consistent mass matrix `M` and the stiffness matrix `K` of `X^h`, the damage step
//! (5.2) of Han, Shillor & Sofonea (2001) is the variational inequality of
//!
//! ```text
//!     minimize  q(x) = ½ xᵀ A x − bᵀ x   subject to  lower ≤ x ≤ upper   (componentwise),
//!     A = M/k + κ K,   b = M β_{n−1}/k + (φ(ε(u_{n−1}), β_{n−1}), ψ_i)_i,
//! ```
//!
//! here for any sparse symmetric positive definite `A` and `lower_i ≤ upper_i` (infinite bounds
//! allowed, `lower_i = upper_i` fixes `x_i`). The consistent mass matrix has positive
//! off-diagonal entries, so `A` is in general **not** an M-matrix.
//!
//! With the gradient `g = A x − b`, the KKT conditions read, for every index `i`,
//! `lower_i < x_i < upper_i ⇒ g_i = 0`, `x_i = lower_i ⇒ g_i ≥ 0`, `x_i = upper_i ⇒ g_i ≤ 0`.
//! For any `c_i > 0` they are equivalent to the fixed-point equation
//!
//! ```text
//!     x_i = clamp(x_i − g_i / c_i, lower_i, upper_i)        for all i.                (★)
//! ```
//!
//! The reported **KKT residual** (see [`box_qp_kkt_residual`]) is the natural residual of (★)
//! with `c_i = 1`, scaled by the data: `‖x − clamp(x − g, lower, upper)‖_∞ / max(1, ‖b‖_∞)`.
//! It vanishes exactly at the solution; the returned `x` always lies within the bounds exactly
//! (zero primal violation).
//!
//! # Algorithm (default): truncated nonsmooth Newton multigrid
//! [`BoxQpMethod::MonotoneMultigrid`], after Gräser & Kornhuber (2009), on an algebraic
//! hierarchy of `A` built once per matrix (smoothed aggregation, Vaněk, Mandel & Brezina
//! 1996: greedy aggregates of strongly coupled unknowns, a Jacobi-smoothed piecewise constant
//! prolongation, Galerkin coarse matrices, a dense factor on the coarsest level of at most
//! 64 unknowns, factorized with diagonal pivoting; no factorization of `A`). One iteration:
//! 0. **Coarse obstacle correction** (only for large diffusion-dominated matrices;
//!    `solvers/box_qp_coarse.rs`): the correction constant on the aggregates of the coarsening
//!    that minimizes `q` within conservative bounds, by the same method on `P̂ᵀAP̂`,
//!    recursively. It frees in one step a layer of indices that the smoother would free a
//!    few cells per iteration. Computed while the KKT residual is above the coarse tolerance,
//!    and below it where a band of indices on a bound still has gradients pointing into the
//!    box (see that module).
//! 1. **Nonlinear smoothing**: a symmetric projected Gauss–Seidel sweep, every `x_i` in turn
//!    replaced by the exact minimizer of `q` in its interval, `clamp(x_i − g_i/a_ii)`. An
//!    index that its last update left on a bound, with no value of its row changed since, is
//!    skipped (its update would leave it there again), and the gradient is recomputed on the
//!    rows that saw a change only: on a damage plateau (β = 1 where the source pushes β up,
//!    about half of the nodes in `bench_step`'s problem) the sweeps cost next to nothing.
//! 2. **Truncation**: the indices lying on a bound after the smoothing keep their value; the
//!    hierarchy is truncated to the others, `F` (only the coarse rows the change touches are
//!    recomputed).
//! 3. **Linear correction**: `A_FF d_F = −g_F` by conjugate gradients preconditioned with one
//!    truncated V-cycle per iteration, to a tenth of the free gradient (at most ten
//!    iterations).
//! 4. **Projection and line search**: `d` is cut back so that `x + d` lies in the box, and
//!    `x ← x + α d` with the exact minimizer `α ∈ [0, 1]` of `q` on the segment.
//!
//! **Threads.** The sweeps are sequential. The row-wise passes (the gradient on the stale rows,
//! the products of the correction and of the line search, the residuals and grid transfers
//! of the V-cycle) run in tasks of 8192 rows when the thread pool has several threads
//! (`crate::algebra::multigrid::for_each_row`): in `simulate` the damage step runs beside the velocity
//! step, and once that is done the other core takes a share of these passes. Every entry is
//! computed by the same expression, so the iterates are bitwise those of one thread.
//!
//! Every step decreases `q` (the smoother by exact minimization, the correction by the line
//! search), and the projected Gauss–Seidel method alone converges to the unique minimizer
//! for any SPD `A` from any start, so the iteration converges globally (the convergence
//! argument of Gräser & Kornhuber 2009 for a globally convergent smoother followed by
//! corrections that do not increase `q`: every accumulation point is a fixed point of the
//! smoother, i.e. the minimizer). Once the
//! bound set is identified it is a linear multigrid on `A_FF`, with a contraction independent
//! of the mesh size; the KKT residual is checked after the smoothing and after the correction.
//! Why this method for (5.2): the work per iteration is a few sparse products (no
//! factorization at all, so nothing is refactorized when the active set changes), and the
//! consistent mass matrix (positive off-diagonal entries) is no obstacle for projected
//! Gauss–Seidel. Iteration counts on the moving-damage case are in `docs/explanation/performance.md`: once the
//! active set is found, about four iterations to 1e-12 at every N; at a fixed time step the
//! free boundary moves by more cells on finer meshes, and without the coarse obstacle
//! correction the counts grew by about one iteration per doubling of N (at most 6, 6, 7, 9
//! per step, 5.0, 5.1, 6.4 and 8.1 on average, at N = 64, 128, 256, 512; with it at most 6
//! at every N, 5.0, 5.1, 5.2 and 6.0 on average).
//! Measured per step against the active set method in `reports/benchmark_step.md`.
//!
//! # Alternative algorithm: primal–dual active set
//! [`BoxQpMethod::ActiveSet`]:
//! 1. **Primal–dual active set method** (PDAS; Hintermüller, Ito & Kunisch 2002), which is the
//!    semismooth Newton method for (★). Given an iterate `(x, g)` the active sets are
//!    `L = {i : x_i − g_i/c_i < lower_i}`, `U = {i : x_i − g_i/c_i > upper_i}`, and the free set
//!    `F` is the rest (indices with `lower_i = upper_i` always belong to `L`). The next iterate
//!    fixes `x_L = lower_L`, `x_U = upper_U` and solves the reduced system
//!    `A_FF x_F = b_F − A_FL lower_L − A_FU upper_U`; the multipliers are then `g = A x − b`
//!    (`g_F = 0`). We take `c_i = A_ii` (a Jacobi scaling); after the first iteration `c` plays
//!    no role any more, because `x` sits on its bounds on `L ∪ U` and `g = 0` on `F`. The
//!    iteration stops as soon as the projected iterate `clamp(x, lower, upper)` has a KKT
//!    residual below the tolerance. In exact arithmetic this happens when the active sets
//!    repeat; in floating point, **degenerate** indices (`x_i*` on a bound with `g_i* = 0`, e.g.
//!    a damage field that stays at 1 where there is no source) would let the sets flip forever
//!    on the sign of rounding noise although the solution is already exact. For the same reason
//!    an index lying exactly on a bound whose gradient has the wrong sign by at most
//!    `0.1 · tolerance · max(1, ‖b‖_∞)` is kept at that bound (this costs at most a tenth of the
//!    tolerance in the residual and keeps the active sets, hence the warm start, stable
//!    from one time step to the next).
//!    For M-matrices PDAS converges in finitely many steps (HIK 2002, Kunisch & Rendl 2003); for
//!    general SPD matrices it can cycle (Ben Gharbia & Gilbert 2012; the unit tests contain a
//!    3×3 example with a 3-cycle).
//! 2. **Safeguard.** After the first iteration a PDAS iterate is a function of the active sets
//!    alone, so PDAS either reaches a fixed point or revisits an earlier pair `(L, U)` and cycles
//!    forever. Every visited pair is recorded (by a 64-bit hash: a collision can only cause an
//!    unnecessary switch, never a wrong answer). On a revisit, on a fixed point of the sets
//!    whose residual stays above the tolerance, or after half of the iteration budget, the
//!    solver switches to step 3, starting from the best feasible point seen so far (least `q`
//!    among the projected PDAS iterates).
//! 3. **Projected Newton method** (Bertsekas 1982) on the feasible set, globally convergent for
//!    strictly convex bound-constrained problems: with `w = ‖x − clamp(x − g/diag A)‖_∞` and
//!    `ε = min(ε̄, w)`, the ε-active set is
//!    `I = {i : x_i ≤ lower_i + ε, g_i > 0} ∪ {i : x_i ≥ upper_i − ε, g_i < 0}` (plus fixed
//!    indices); the direction is the reduced Newton step `d_F = −A_FF⁻¹ g_F` on the rest and the
//!    scaled gradient step `d_i = −g_i / A_ii` on `I`; the step `x(α) = clamp(x + α d)` is
//!    accepted by the Armijo rule along the projection arc (Bertsekas 1982, eq. (33)),
//!    `q(x) − q(x(α)) ≥ σ (α Σ_{i∉I} −g_i d_i + Σ_{i∈I} g_i (x_i − x_i(α)))`, `σ = 10⁻⁴`,
//!    `α = 1, ½, ¼, …`. Every limit point is stationary, hence the iterates converge to the
//!    unique minimizer. Before each projected Newton step the solver tries an **exact reduced
//!    solve** (one PDAS step) on the active sets of the current point; near the minimizer this
//!    step lands on the exact solution (local convergence of the semismooth Newton method, also
//!    when some constraints are degenerate), so the fallback ends after finitely many steps with
//!    the same accuracy as a converged PDAS run.
//!
//! # Linear algebra of the active set method
//! `A` is fixed for the whole run (M/k + κK in the damage step), so it is factorized **once**
//! (sparse Cholesky, AMD ordering, on the first solve) and every reduced system
//! `A_FF y_F = r_F` of the iteration — one per active-set change — is solved by the
//! **preconditioned conjugate gradient method** on the free set `F` with that one factor,
//! instead of a new numeric factorization of `A_FF` per change. Why this method:
//! each iteration costs one solve with the fixed factor (two triangular solves) plus a few
//! sparse products, the free values of the previous iterate (and of the previous time step)
//! are the warm start, and the result depends only on the data and the start, never on which
//! factor happened to be cached, so `simulate --resume` stays bitwise identical. (A Schur
//! complement on the active set would need a dense system of the size of the active set —
//! most of the domain where β = 1 — and a monotone multigrid a mesh hierarchy the problem
//! files do not have.)
//!
//! The preconditioner is a symmetric two-level cycle on `A_FF`: a forward Gauss–Seidel sweep
//! on `F`, the correction `(A⁻¹ r̃)_F` of the residual extended by zero (one solve with the
//! factor; on its own, `(A⁻¹)_FF` is the inverse of the Schur complement `S_FF` of `A` onto
//! `F`, exact when no index is fixed, and `S_FF⁻¹A_FF − I` has rank at most the number of
//! fixed indices), and a backward sweep. The sweeps damp the error components that `S_FF⁻¹`
//! gets wrong next to the free boundary (where `A_FF` sees a zero extension and `S_FF` the
//! `A`-harmonic one); the CG coefficient `β` is the Polak–Ribière one, which tolerates a
//! preconditioner that is not exactly SPD. While the active sets still change, a reduced
//! solve stops when its free gradient is a hundredth of the current KKT residual
//! (`INEXACT_FRACTION`); once the sets repeat it is solved to a tenth of the tolerance, and
//! every result is certified by the same KKT residual as before, so the accuracy is that of
//! a direct solve. The cost depends on `κk/h²`: when the mass term dominates (k ≲ h²/κ)
//! a reduced solve takes a few CG iterations whatever N; when diffusion dominates, the
//! measured CG iterations per step grow about like N at fixed k (table in
//! `docs/explanation/performance.md`, case
//! of `examples/common/moving_damage.rs`). The projected Newton direction of step 3 is computed
//! by the same CG from zero (a descent direction at any iteration).
//!
//! The factor is simplicial by default ([`FactorKind::Simplicial`]); it is computed once per
//! run and solved with a few times per step. Measured on the P1 damage matrices of
//! `reports/benchmark_step.md` (factorization / one warm solve, ms, simplicial against
//! supernodal, the supernodal solve by the solver's own sweeps, `crate::algebra::triangular`): 2D 128²
//! 20.6 / 0.92 against 11.0 / 0.99, 256² 146 / 3.85 against 38.7 / 3.97, 512² 1279 / 19.2
//! against 253 / 20.4, 3D 16³ 78 / 0.96 against 10.0 / 0.53, 32³ 18 945 / 31.0 against 744 /
//! 34.2. In 2D the solves decide, and the damage steps with either factor were within the
//! noise of the shared machine (at 256², interleaved pairs: 94 / 115 ms per step simplicial
//! against 127 / 120 ms supernodal, and the reverse, 127 against 94 ms, in two runs of
//! `bench_step`), so the default stays simplicial. In 3D the supernodal factor saves
//! most of the factorization (18.9 → 0.7 s at 32³) and `simulate` chooses it for 3D problems
//! (`block_3d.toml` with 32 × 16 × 16 cells, `damage_method = "active-set"`, two interleaved
//! pairs: 11.2 / 12.6 → 10.3 / 10.9 s).
//!
//! # References
//! - C. Gräser, R. Kornhuber, *Multigrid methods for obstacle problems*, J. Comput. Math. 27
//!   (2009) 1–44.
//! - C. Gräser, U. Sack, O. Sander, *Truncated nonsmooth Newton multigrid methods for convex
//!   minimization problems*, in: Domain Decomposition Methods in Science and Engineering
//!   XVIII, LNCSE 70, Springer (2009) 129–136.
//! - M. Hintermüller, K. Ito, K. Kunisch, *The primal-dual active set strategy as a semismooth
//!   Newton method*, SIAM J. Optim. 13 (2002) 865–888.
//! - K. Kunisch, F. Rendl, *An infeasible active set method for quadratic problems with simple
//!   bounds*, SIAM J. Optim. 14 (2003) 35–52.
//! - D. P. Bertsekas, *Projected Newton methods for optimization problems with simple
//!   constraints*, SIAM J. Control Optim. 20 (1982) 221–246.
//! - L. Ben Gharbia, J. Ch. Gilbert, *Nonconvergence of the plain Newton-min algorithm for linear
//!   complementarity problems with a P-matrix*, Math. Program. 134 (2012) 349–364.

use std::hash::{DefaultHasher, Hash, Hasher};

use faer::sparse::{SparseColMat, Triplet};
use faer::MatMut;

pub use crate::algebra::linalg::FactorKind;
use crate::algebra::linalg::{dot, max_abs, max_abs_free, multiply_into, CholeskySolver};
use crate::algebra::multigrid::{for_each_row, inverse, Csr, Hierarchy};
use crate::error::{Error, History, Result};
use crate::solvers::box_qp_coarse::{bound_violations, CoarseObstacle, NestedBoxQp};

/// Settings of [`BoxQpSolver`].
#[derive(Debug, Clone, Copy)]
pub struct BoxQpSettings {
    /// Tolerance on the scaled KKT residual of [`box_qp_kkt_residual`] (default `1e-12`).
    pub tolerance: f64,
    /// Maximum number of iterations, primal–dual active set and projected Newton steps together
    /// (default 100). The active set phase may use at most half of them.
    pub max_iterations: usize,
    /// Simplicial or supernodal Cholesky factor of `A` for [`BoxQpMethod::ActiveSet`]
    /// (default [`FactorKind::Simplicial`]; see the module documentation).
    pub factorization: FactorKind,
    /// The algorithm (default [`BoxQpMethod::MonotoneMultigrid`]).
    pub method: BoxQpMethod,
}

/// Algorithm of [`BoxQpSolver`] (see the module documentation).
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

/// Statistics of one call of [`BoxQpSolver::solve`].
#[derive(Debug, Clone, Default)]
pub struct BoxQpStats {
    /// Outer iterations performed: with [`BoxQpMethod::MonotoneMultigrid`] one projected
    /// Gauss–Seidel sweep, truncated coarse correction and line search each; with
    /// [`BoxQpMethod::ActiveSet`] active set steps plus projected Newton steps. 0 if the start
    /// already satisfied the tolerance.
    pub iterations: usize,
    /// Numeric Cholesky factorizations of `A` computed in this call: 1 in the first call of
    /// a solver with [`BoxQpMethod::ActiveSet`] (the factor of `A`), 0 afterwards and always 0
    /// with [`BoxQpMethod::MonotoneMultigrid`].
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
    /// Scaled KKT residual of the returned `x` (see [`box_qp_kkt_residual`]).
    pub kkt_residual: f64,
    /// Number of indices with `x_i = lower_i` (including fixed indices with `lower_i = upper_i`).
    pub lower_active: usize,
    /// Number of indices with `x_i = upper_i` and `lower_i < upper_i`.
    pub upper_active: usize,
    /// Whether the projected Newton safeguard was needed (PDAS cycled or exhausted its budget;
    /// [`BoxQpMethod::ActiveSet`] only).
    pub used_fallback: bool,
}

/// Position of an index relative to its bounds in the active set classification.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum BoundStatus {
    Free,
    AtLower,
    AtUpper,
}

/// Sufficient decrease constant of the Armijo rule.
const ARMIJO_SIGMA: f64 = 1e-4;
/// Smallest step length tried by the Armijo backtracking before giving up.
const MIN_STEP_LENGTH: f64 = 1e-14;
/// Free-gradient target of an inexact reduced solve, as a fraction of the current KKT residual.
const INEXACT_FRACTION: f64 = 1e-2;
/// Maximum number of iterative refinement steps after a reduced solve.
const MAX_REFINEMENT_STEPS: usize = 3;

/// The rows of `A` as the monotone multigrid's smoother reads them, built once per matrix.
#[derive(Debug, Clone)]
struct FineRows {
    rows: Csr,
    /// Per row, the number of columns below the diagonal ([`Csr::sweep_product`]).
    lower_counts: Vec<usize>,
    /// `1/a_ii`: the smoother multiplies by it (a division would lengthen the sweep's
    /// dependency chain from row to row).
    inverse_diagonal: Vec<f64>,
}

/// Solver of the sparse box-constrained QP `min ½ xᵀAx − bᵀx, lower ≤ x ≤ upper` with SPD `A`.
///
/// Symbolic analysis done once per matrix pattern; numeric factorizations reused across solves.
pub struct BoxQpSolver {
    matrix: SparseColMat<usize, f64>,
    settings: BoxQpSettings,
    diagonal: Vec<f64>,
    /// The Cholesky factor of `A` itself (symbolic analysis at construction, numeric
    /// factorization once, on the first solve that needs it; [`BoxQpMethod::ActiveSet`]).
    factor: Option<CholeskySolver>,
    /// `A` by rows and its truncated multigrid hierarchy ([`BoxQpMethod::MonotoneMultigrid`],
    /// built at construction).
    multigrid: Option<(FineRows, Hierarchy)>,
    /// The coarse obstacle correction on aggregates ([`BoxQpMethod::MonotoneMultigrid`], at
    /// least `coarse_obstacle::MIN_NESTED_SIZE` unknowns, diffusion dominated).
    coarse: Option<CoarseObstacle<BoxQpSolver>>,
    /// Work vectors kept between calls (allocated by the first).
    workspace: Option<Workspace>,
}

impl std::fmt::Debug for BoxQpSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BoxQpSolver")
            .field("dimension", &self.diagonal.len())
            .field("nonzeros", &self.matrix.val().len())
            .field("settings", &self.settings)
            .field(
                "factorized",
                &self
                    .factor
                    .as_ref()
                    .is_some_and(CholeskySolver::is_factorized),
            )
            .finish()
    }
}

/// Work vectors of one solve.
struct Workspace {
    gradient: Vec<f64>,
    trial: Vec<f64>,
    trial_gradient: Vec<f64>,
    projected: Vec<f64>,
    projected_gradient: Vec<f64>,
    direction: Vec<f64>,
    product: Vec<f64>,
    fixed: Vec<bool>,
    /// Per index, the [`SETTLED`] and [`STALE`] marks of the monotone multigrid.
    marks: Vec<u8>,
    state: Vec<BoundStatus>,
    next_state: Vec<BoundStatus>,
    cg: CgWork,
}

/// Work vectors of the preconditioned conjugate gradient method.
struct CgWork {
    residual: Vec<f64>,
    preconditioned: Vec<f64>,
    search: Vec<f64>,
    image: Vec<f64>,
    scratch: Vec<f64>,
    previous: Vec<f64>,
}

impl Workspace {
    /// Zeroes every vector (as [`Workspace::new`] leaves them).
    fn reset(&mut self) {
        for vector in [
            &mut self.gradient,
            &mut self.trial,
            &mut self.trial_gradient,
            &mut self.projected,
            &mut self.projected_gradient,
            &mut self.direction,
            &mut self.product,
            &mut self.cg.residual,
            &mut self.cg.preconditioned,
            &mut self.cg.search,
            &mut self.cg.image,
            &mut self.cg.scratch,
            &mut self.cg.previous,
        ] {
            vector.fill(0.0);
        }
        self.fixed.fill(false);
        self.marks.fill(STALE);
        self.state.fill(BoundStatus::Free);
        self.next_state.fill(BoundStatus::Free);
    }

    fn new(dimension: usize) -> Self {
        Self {
            gradient: vec![0.0; dimension],
            trial: vec![0.0; dimension],
            trial_gradient: vec![0.0; dimension],
            projected: vec![0.0; dimension],
            projected_gradient: vec![0.0; dimension],
            direction: vec![0.0; dimension],
            product: vec![0.0; dimension],
            fixed: vec![false; dimension],
            marks: vec![STALE; dimension],
            state: vec![BoundStatus::Free; dimension],
            next_state: vec![BoundStatus::Free; dimension],
            cg: CgWork {
                residual: vec![0.0; dimension],
                preconditioned: vec![0.0; dimension],
                search: vec![0.0; dimension],
                image: vec![0.0; dimension],
                scratch: vec![0.0; dimension],
                previous: vec![0.0; dimension],
            },
        }
    }
}

/// Problem data of one solve.
#[derive(Clone, Copy)]
struct Problem<'a> {
    rhs: &'a [f64],
    lower: &'a [f64],
    upper: &'a [f64],
    /// `max(1, ‖b‖_∞)`, the scale of the KKT residual.
    scale: f64,
    /// Gradient size below which an index lying exactly on a bound stays classified at that
    /// bound (`0.1 · tolerance · scale`): such an index contributes at most a tenth of the
    /// tolerance to the KKT residual, and the rule stops rounding noise in degenerate
    /// gradients from flipping the active sets.
    tie: f64,
}

impl BoxQpSolver {
    /// Validates (square, symmetric pattern, finite, positive diagonal) and analyses the pattern.
    ///
    /// The matrix must be stored with both triangles; its values must be symmetric up to a
    /// relative `1e-10` (measured against `√(A_ii A_jj)`). Positive definiteness itself is only
    /// detected by the Cholesky factorizations in [`BoxQpSolver::solve`]
    /// ([`Error::LinearAlgebra`]). Columns with unsorted row indices are sorted once here.
    pub fn new(matrix: SparseColMat<usize, f64>, settings: BoxQpSettings) -> Result<Self> {
        if !(settings.tolerance > 0.0 && settings.tolerance.is_finite()) {
            return Err(Error::parameter(
                "tolerance",
                settings.tolerance,
                "the KKT tolerance must be positive and finite",
            ));
        }
        if settings.max_iterations == 0 {
            return Err(Error::parameter(
                "max_iterations",
                0.0,
                "at least one iteration is needed",
            ));
        }
        let (nrows, ncols) = (matrix.nrows(), matrix.ncols());
        if nrows != ncols {
            return Err(Error::InvalidInput(format!(
                "box QP matrix must be square, got {nrows}×{ncols}"
            )));
        }
        if nrows == 0 {
            return Err(Error::InvalidInput("box QP matrix is empty (0×0)".into()));
        }
        let matrix = canonical_storage(matrix)?;
        let diagonal = validate_symmetric_positive_diagonal(&matrix)?;

        let factor = match settings.method {
            BoxQpMethod::ActiveSet => Some(CholeskySolver::analyse_as(
                &matrix,
                settings.factorization,
                "box QP Cholesky factor of A",
            )?),
            BoxQpMethod::MonotoneMultigrid => None,
        };
        let multigrid = (settings.method == BoxQpMethod::MonotoneMultigrid).then(|| {
            let rows = Csr::from_symmetric(&matrix);
            let hierarchy = Hierarchy::new(&rows);
            let fine = FineRows {
                lower_counts: rows.lower_counts(),
                inverse_diagonal: diagonal.iter().map(|&d| inverse(d)).collect(),
                rows,
            };
            (fine, hierarchy)
        });
        let coarse = match &multigrid {
            Some((fine, _)) => coarse_obstacle(&fine.rows, &diagonal, settings)?,
            None => None,
        };
        Ok(Self {
            matrix,
            settings,
            diagonal,
            factor,
            multigrid,
            coarse,
            workspace: None,
        })
    }

    /// Unknowns per level of the multigrid hierarchy, finest first (empty for
    /// [`BoxQpMethod::ActiveSet`]).
    pub fn multigrid_levels(&self) -> Vec<usize> {
        self.multigrid
            .as_ref()
            .map_or_else(Vec::new, |(_, hierarchy)| hierarchy.sizes())
    }

    /// Whether the Cholesky factor of `A` is supernodal (see [`FactorKind`]); `false` without
    /// a factor ([`BoxQpMethod::MonotoneMultigrid`]).
    pub fn is_supernodal(&self) -> bool {
        self.factor
            .as_ref()
            .is_some_and(CholeskySolver::is_supernodal)
    }

    /// The matrix `A` (in canonical storage: sorted row indices in each column).
    pub fn matrix(&self) -> &SparseColMat<usize, f64> {
        &self.matrix
    }

    /// Sets the scaled KKT tolerance of the next solves (the coarse obstacle corrections
    /// solve their box QP to a tolerance relative to the fine residual).
    pub(crate) fn set_tolerance(&mut self, tolerance: f64) {
        debug_assert!(tolerance > 0.0 && tolerance.is_finite());
        self.settings.tolerance = tolerance;
    }

    /// The settings given to [`BoxQpSolver::new`].
    pub fn settings(&self) -> BoxQpSettings {
        self.settings
    }

    /// Solve for x; `x` holds the start on entry (projected onto the box first) and the solution on exit.
    ///
    /// On success `lower ≤ x ≤ upper` holds exactly and the scaled KKT residual
    /// ([`box_qp_kkt_residual`]) is at most the tolerance; a start that already satisfies the
    /// tolerance is returned (projected) without iterating.
    ///
    /// Errors: length mismatch or `lower_i > upper_i` ([`Error::InvalidInput`] naming `i`),
    /// non-finite data ([`Error::NonFinite`]), a failed factorization (`A` not positive definite,
    /// [`Error::LinearAlgebra`]), and [`Error::NoConvergence`] with the history of KKT residuals.
    /// After an error `x` holds a feasible point but not the solution.
    pub fn solve(
        &mut self,
        rhs: &[f64],
        lower: &[f64],
        upper: &[f64],
        x: &mut [f64],
    ) -> Result<BoxQpStats> {
        self.check_problem(rhs, lower, upper, x)?;
        let scale = max_abs(rhs).max(1.0);
        let problem = Problem {
            rhs,
            lower,
            upper,
            scale,
            tie: 0.1 * self.settings.tolerance * scale,
        };
        let mut stats = BoxQpStats::default();
        let mut history = Vec::new();
        // The work vectors of the previous call, reset (so that a solve never depends on the
        // calls before it, as `--resume` requires), without new allocations. The monotone
        // multigrid writes every vector before it reads it, except the marks; zeroing them
        // all took 27 MB of writes per solve at 263k unknowns.
        let mut work = match self.workspace.take() {
            Some(mut work) => {
                if self.settings.method == BoxQpMethod::MonotoneMultigrid {
                    work.marks.fill(STALE);
                } else {
                    work.reset();
                }
                work
            }
            None => Workspace::new(x.len()),
        };
        let result = self.solve_with(&problem, x, &mut stats, &mut history, &mut work);
        self.workspace = Some(work);
        result.map(|()| stats)
    }

    /// [`BoxQpSolver::solve`] after the checks, with the work vectors `work`.
    fn solve_with(
        &mut self,
        problem: &Problem<'_>,
        x: &mut [f64],
        stats: &mut BoxQpStats,
        history: &mut Vec<f64>,
        work: &mut Workspace,
    ) -> Result<()> {
        let (rhs, lower, upper) = (problem.rhs, problem.lower, problem.upper);

        project(x, lower, upper);
        gradient(&self.matrix, x, rhs, &mut work.gradient);
        let start_residual = scaled_kkt_residual(x, &work.gradient, problem);
        if start_residual <= self.settings.tolerance {
            self.finish(x, problem, stats);
            return Ok(());
        }
        history.push(start_residual);

        if self.settings.method == BoxQpMethod::MonotoneMultigrid {
            self.monotone_multigrid(problem, x, work, stats, history)?;
            self.finish(x, problem, stats);
            return Ok(());
        }
        if self.active_set_phase(problem, x, work, stats, history)? {
            self.finish(x, problem, stats);
            return Ok(());
        }
        stats.used_fallback = true;
        self.projected_newton_phase(problem, x, work, stats, history)?;
        self.finish(x, problem, stats);
        Ok(())
    }

    /// Checks lengths, finiteness and the ordering of the bounds.
    fn check_problem(&self, rhs: &[f64], lower: &[f64], upper: &[f64], x: &[f64]) -> Result<()> {
        let dimension = self.diagonal.len();
        for (name, len) in [
            ("rhs", rhs.len()),
            ("lower", lower.len()),
            ("upper", upper.len()),
            ("x", x.len()),
        ] {
            if len != dimension {
                return Err(Error::InvalidInput(format!(
                    "box QP: `{name}` has length {len} but the matrix has dimension {dimension}"
                )));
            }
        }
        for i in 0..dimension {
            if !rhs[i].is_finite() {
                return Err(Error::NonFinite(format!(
                    "box QP right-hand side rhs[{i}] = {}",
                    rhs[i]
                )));
            }
            if !x[i].is_finite() {
                return Err(Error::NonFinite(format!("box QP start x[{i}] = {}", x[i])));
            }
            if lower[i].is_nan() || upper[i].is_nan() {
                return Err(Error::NonFinite(format!(
                    "box QP bounds at index {i}: lower = {}, upper = {}",
                    lower[i], upper[i]
                )));
            }
            if lower[i] > upper[i] {
                return Err(Error::InvalidInput(format!(
                    "box QP bounds crossed at index {i}: lower[{i}] = {} > upper[{i}] = {}",
                    lower[i], upper[i]
                )));
            }
            if lower[i] == f64::INFINITY || upper[i] == f64::NEG_INFINITY {
                return Err(Error::InvalidInput(format!(
                    "box QP bounds at index {i} leave no finite value: lower = {}, upper = {}",
                    lower[i], upper[i]
                )));
            }
        }
        Ok(())
    }

    /// Truncated nonsmooth Newton multigrid (module documentation, "Algorithm"): `x` is
    /// feasible on entry with `work.gradient = A x − b`, and holds the solution on success.
    #[allow(clippy::needless_range_loop)] // componentwise kernels over several vectors
    fn monotone_multigrid(
        &mut self,
        problem: &Problem<'_>,
        x: &mut [f64],
        work: &mut Workspace,
        stats: &mut BoxQpStats,
        history: &mut Vec<f64>,
    ) -> Result<()> {
        let tolerance = self.settings.tolerance;
        let exact = 0.1 * tolerance * problem.scale;
        let n = x.len();
        let (fine, hierarchy) = self.multigrid.as_mut().expect("built for this method");
        let rows = &fine.rows;
        while stats.iterations < self.settings.max_iterations {
            stats.iterations += 1;
            // 0. The coarse obstacle correction (`crate::solvers::box_qp_coarse`).
            let residual = history.last().copied().unwrap_or(f64::INFINITY);
            if let Some(coarse) = self.coarse.as_mut() {
                let violations = || {
                    bound_violations(x, &work.gradient, problem.lower, problem.upper, problem.tie)
                };
                if let Some(tolerance) = coarse.tolerance_at(residual, n, violations) {
                    let iterations = coarse.correct(
                        x,
                        &work.gradient,
                        problem.lower,
                        problem.upper,
                        tolerance,
                    )?;
                    if iterations > 0 {
                        stats.coarse_iterations += iterations;
                        work.marks.fill(STALE);
                        residual_gradient(
                            rows,
                            x,
                            problem.rhs,
                            &mut work.gradient,
                            &mut work.marks,
                        );
                    }
                }
            }
            // 1. Nonlinear smoothing: a symmetric projected Gauss–Seidel sweep.
            projected_gauss_seidel(fine, problem, x, false, &mut work.marks);
            projected_gauss_seidel(fine, problem, x, true, &mut work.marks);
            residual_gradient(rows, x, problem.rhs, &mut work.gradient, &mut work.marks);
            let residual = scaled_kkt_residual(x, &work.gradient, problem);
            history.push(residual);
            if residual <= tolerance {
                return Ok(());
            }
            // 2. Truncation: the indices on a bound keep their value in the correction.
            for i in 0..n {
                work.fixed[i] = x[i] == problem.lower[i] || x[i] == problem.upper[i];
            }
            if hierarchy.truncate(&work.fixed) {
                stats.coarse_updates += 1;
            }
            if hierarchy.is_indefinite() {
                return Err(not_positive_definite(
                    "coarsest level of the multigrid hierarchy",
                ));
            }
            // 3. Linear correction: A_FF d_F = −g_F by multigrid-preconditioned CG.
            // −g_F (zero on the fixed indices) and its size.
            for i in 0..n {
                work.product[i] = if work.fixed[i] {
                    0.0
                } else {
                    -work.gradient[i]
                };
            }
            let free_gradient = max_abs(&work.product);
            let target = exact.max(CORRECTION_FRACTION * free_gradient);
            multigrid_cg(
                rows,
                hierarchy,
                &work.fixed,
                &work.product,
                &mut work.direction,
                target,
                &mut work.cg,
                stats,
            )?;
            // 4. Projection of the correction onto the box, then an exact line search on the
            // segment from x to the projected point (q never increases).
            // The rows that see a nonzero entry of d are marked stale (their gradient changes)
            // and unsettled; A d vanishes on the others.
            for i in 0..n {
                let corrected = clamp(x[i] + work.direction[i], problem.lower[i], problem.upper[i]);
                work.trial[i] = corrected;
                work.direction[i] = corrected - x[i];
                if work.direction[i] != 0.0 {
                    mark_stale(rows.row(i).0, &mut work.marks);
                }
            }
            rows.multiply_rows(&work.direction, &mut work.product, |i| {
                work.marks[i] & STALE != 0
            });
            let (mut slope, mut curvature) = (0.0, 0.0);
            for i in 0..n {
                slope += work.gradient[i] * work.direction[i];
                curvature += work.direction[i] * work.product[i];
            }
            if curvature < 0.0 {
                return Err(not_positive_definite(
                    "line search of the multigrid correction",
                ));
            }
            if slope < 0.0 && curvature > 0.0 {
                let step = (-slope / curvature).min(1.0);
                // x ← x + α d (for α = 1 the projected point itself: indices clamped by the
                // projection lie on their bounds exactly) and g ← g + α A d (up to rounding; a
                // converged iterate is confirmed below with the gradient recomputed from x).
                for i in 0..n {
                    x[i] = if step == 1.0 {
                        work.trial[i]
                    } else {
                        clamp(
                            x[i] + step * work.direction[i],
                            problem.lower[i],
                            problem.upper[i],
                        )
                    };
                    work.gradient[i] += step * work.product[i];
                }
            }
            let mut residual = scaled_kkt_residual(x, &work.gradient, problem);
            if residual <= tolerance {
                residual_gradient(rows, x, problem.rhs, &mut work.gradient, &mut work.marks);
                residual = scaled_kkt_residual(x, &work.gradient, problem);
            }
            history.push(residual);
            if residual <= tolerance {
                return Ok(());
            }
            if x.iter().any(|value| !value.is_finite()) {
                return Err(Error::NonFinite(
                    "box QP monotone multigrid produced a non-finite value".into(),
                ));
            }
        }
        Err(self.no_convergence(
            stats.iterations,
            history.last().copied().unwrap_or(f64::INFINITY),
            history,
        ))
    }

    /// Primal–dual active set iteration. Returns `true` with the solution in `x` on convergence,
    /// `false` with the best projected iterate in `x` when it cycles, exhausts its budget or
    /// stalls at the rounding level.
    fn active_set_phase(
        &mut self,
        problem: &Problem<'_>,
        x: &mut [f64],
        work: &mut Workspace,
        stats: &mut BoxQpStats,
        history: &mut Vec<f64>,
    ) -> Result<bool> {
        let tolerance = self.settings.tolerance;
        let budget = self.settings.max_iterations.div_ceil(2);
        let mut best_objective = objective(x, &work.gradient, problem.rhs);
        let mut best = x.to_vec();
        classify(x, &work.gradient, problem, &self.diagonal, &mut work.state);
        // Warm start of the reduced solves: the free values of the previous iterate.
        work.trial.copy_from_slice(x);
        let mut visited = Vec::new();
        // Inexact reduced solves while far from the solution (the free gradient reduced to a
        // fraction of the current KKT residual), exact ones (a tenth of the tolerance) once the
        // active sets have settled.
        let exact = 0.1 * tolerance * problem.scale;
        let inexact = |residual: f64| exact.max(INEXACT_FRACTION * residual * problem.scale);
        let mut target = inexact(history.last().copied().unwrap_or(0.0));

        while stats.iterations < budget {
            stats.iterations += 1;
            visited.push(state_hash(&work.state));
            let state = std::mem::take(&mut work.state);
            self.reduced_solve(&state, problem, target, work, stats)?;
            work.state = state;
            classify(
                &work.trial,
                &work.trial_gradient,
                problem,
                &self.diagonal,
                &mut work.next_state,
            );
            work.projected.copy_from_slice(&work.trial);
            project(&mut work.projected, problem.lower, problem.upper);
            gradient(
                &self.matrix,
                &work.projected,
                problem.rhs,
                &mut work.projected_gradient,
            );
            let residual = scaled_kkt_residual(&work.projected, &work.projected_gradient, problem);
            history.push(residual);
            let projected_objective =
                objective(&work.projected, &work.projected_gradient, problem.rhs);
            if projected_objective < best_objective {
                best_objective = projected_objective;
                best.copy_from_slice(&work.projected);
            }
            if residual <= tolerance {
                x.copy_from_slice(&work.projected);
                return Ok(true);
            }
            if work.next_state == work.state || visited.contains(&state_hash(&work.next_state)) {
                if target > exact {
                    // Settled (or revisited) with an inexact solve: solve exactly from here.
                    target = exact;
                    visited.clear();
                    continue;
                }
                // A fixed point of the active sets above the tolerance (rounding level) or a
                // cycle: hand over to the safeguard.
                break;
            }
            target = inexact(residual);
            std::mem::swap(&mut work.state, &mut work.next_state);
        }
        x.copy_from_slice(&best);
        Ok(false)
    }

    /// Projected Newton method of Bertsekas (1982) with an exact reduced solve tried before
    /// every step; `x` is feasible on entry and holds the solution on success.
    #[allow(clippy::needless_range_loop)] // componentwise kernels over several vectors
    fn projected_newton_phase(
        &mut self,
        problem: &Problem<'_>,
        x: &mut [f64],
        work: &mut Workspace,
        stats: &mut BoxQpStats,
        history: &mut Vec<f64>,
    ) -> Result<()> {
        let tolerance = self.settings.tolerance;
        let epsilon_bar = self.epsilon_bar(problem, x);
        loop {
            gradient(&self.matrix, x, problem.rhs, &mut work.gradient);
            let residual = scaled_kkt_residual(x, &work.gradient, problem);
            if residual <= tolerance {
                return Ok(());
            }
            if stats.iterations >= self.settings.max_iterations {
                return Err(self.no_convergence(stats.iterations, residual, history));
            }
            stats.iterations += 1;

            // Exact reduced solve on the active sets of the current point.
            let mut state = std::mem::take(&mut work.state);
            classify(x, &work.gradient, problem, &self.diagonal, &mut state);
            work.trial.copy_from_slice(x);
            let exact = 0.1 * tolerance * problem.scale;
            self.reduced_solve(&state, problem, exact, work, stats)?;
            work.state = state;
            work.projected.copy_from_slice(&work.trial);
            project(&mut work.projected, problem.lower, problem.upper);
            gradient(
                &self.matrix,
                &work.projected,
                problem.rhs,
                &mut work.projected_gradient,
            );
            let polished = scaled_kkt_residual(&work.projected, &work.projected_gradient, problem);
            if polished <= tolerance {
                history.push(polished);
                x.copy_from_slice(&work.projected);
                return Ok(());
            }

            // Projected Newton step: ε-active set, reduced Newton direction, Armijo arc search.
            let mut width = 0.0_f64;
            for i in 0..x.len() {
                let scaled_step = x[i] - work.gradient[i] / self.diagonal[i];
                width = width
                    .max((x[i] - clamp(scaled_step, problem.lower[i], problem.upper[i])).abs());
            }
            let epsilon = epsilon_bar.min(width);
            for i in 0..x.len() {
                let (g, lower, upper) = (work.gradient[i], problem.lower[i], problem.upper[i]);
                work.fixed[i] = lower == upper
                    || (x[i] <= lower + epsilon && g > 0.0)
                    || (x[i] >= upper - epsilon && g < 0.0);
            }
            let fixed = std::mem::take(&mut work.fixed);
            for i in 0..x.len() {
                work.product[i] = if fixed[i] { 0.0 } else { -work.gradient[i] };
            }
            // Reduced Newton direction d_F = −A_FF⁻¹ g_F by CG from 0 (a descent direction
            // even if stopped early).
            let rhs = std::mem::take(&mut work.product);
            let mut direction = std::mem::take(&mut work.direction);
            let target = 0.1 * tolerance * problem.scale;
            let result = self.reduced_cg(&fixed, &rhs, &mut direction, target, &mut work.cg, stats);
            work.product = rhs;
            work.direction = direction;
            result?;
            let mut newton_decrement = 0.0;
            for i in 0..x.len() {
                if fixed[i] {
                    work.direction[i] = -work.gradient[i] / self.diagonal[i];
                } else {
                    newton_decrement -= work.gradient[i] * work.direction[i];
                }
            }
            work.fixed = fixed;

            let mut step_length = 1.0;
            loop {
                // trial = clamp(x + α d), direction of travel stored in `projected`.
                let mut predicted = step_length * newton_decrement;
                for i in 0..x.len() {
                    work.trial[i] = clamp(
                        x[i] + step_length * work.direction[i],
                        problem.lower[i],
                        problem.upper[i],
                    );
                    work.projected[i] = work.trial[i] - x[i];
                    if work.fixed[i] {
                        predicted -= work.gradient[i] * work.projected[i];
                    }
                }
                multiply_into(&self.matrix, &work.projected, &mut work.product);
                let mut decrease = 0.0;
                for i in 0..x.len() {
                    decrease -= work.projected[i] * (work.gradient[i] + 0.5 * work.product[i]);
                }
                if decrease > 0.0 && decrease >= ARMIJO_SIGMA * predicted {
                    x.copy_from_slice(&work.trial);
                    break;
                }
                step_length *= 0.5;
                if step_length < MIN_STEP_LENGTH {
                    history.push(residual);
                    return Err(self.no_convergence(stats.iterations, residual, history));
                }
            }
            gradient(&self.matrix, x, problem.rhs, &mut work.gradient);
            history.push(scaled_kkt_residual(x, &work.gradient, problem));
        }
    }

    /// The fixed ε̄ of the ε-active set: a tenth of the narrowest finite box width, or, if no
    /// width is finite, a tenth of `max(1, ‖x‖_∞)`. Any fixed ε̄ > 0 gives global convergence.
    fn epsilon_bar(&self, problem: &Problem<'_>, x: &[f64]) -> f64 {
        let narrowest = problem
            .lower
            .iter()
            .zip(problem.upper)
            .map(|(lower, upper)| upper - lower)
            .filter(|width| *width > 0.0 && width.is_finite())
            .fold(f64::INFINITY, f64::min);
        if narrowest.is_finite() {
            0.1 * narrowest
        } else {
            0.1 * x.iter().fold(1.0_f64, |acc, value| acc.max(value.abs()))
        }
    }

    /// Solves the reduced system of the active sets `state`: `work.trial` holds a start on
    /// entry (its free values are the warm start) and receives `x` with `x_L = lower_L`,
    /// `x_U = upper_U` and `A_FF x_F = b_F − A_FL lower_L − A_FU upper_U`; `work.trial_gradient`
    /// receives `A x − b`. The correction `δ_F` with `A_FF δ_F = −g_F` is computed by
    /// [`BoxQpSolver::reduced_cg`] and repeated (restarted from the true gradient) at most
    /// [`MAX_REFINEMENT_STEPS`] times until the free gradient is below `target`.
    #[allow(clippy::needless_range_loop)] // componentwise kernels over several vectors
    fn reduced_solve(
        &mut self,
        state: &[BoundStatus],
        problem: &Problem<'_>,
        target: f64,
        work: &mut Workspace,
        stats: &mut BoxQpStats,
    ) -> Result<()> {
        for (i, status) in state.iter().enumerate() {
            work.fixed[i] = *status != BoundStatus::Free;
            match status {
                BoundStatus::Free => {}
                BoundStatus::AtLower => work.trial[i] = problem.lower[i],
                BoundStatus::AtUpper => work.trial[i] = problem.upper[i],
            }
        }
        gradient(
            &self.matrix,
            &work.trial,
            problem.rhs,
            &mut work.trial_gradient,
        );
        let mut free_residual = max_abs_free(&work.trial_gradient, &work.fixed);
        for _ in 0..=MAX_REFINEMENT_STEPS {
            if free_residual <= target {
                break;
            }
            for i in 0..state.len() {
                work.product[i] = if work.fixed[i] {
                    0.0
                } else {
                    -work.trial_gradient[i]
                };
            }
            let rhs = std::mem::take(&mut work.product);
            let mut correction = std::mem::take(&mut work.direction);
            let result = self.reduced_cg(
                &work.fixed,
                &rhs,
                &mut correction,
                target,
                &mut work.cg,
                stats,
            );
            work.product = rhs;
            result?;
            for i in 0..state.len() {
                work.projected[i] = work.trial[i];
                work.trial[i] += correction[i];
            }
            work.direction = correction;
            gradient(&self.matrix, &work.trial, problem.rhs, &mut work.product);
            let refined = max_abs_free(&work.product, &work.fixed);
            if refined < free_residual {
                free_residual = refined;
                work.trial_gradient.copy_from_slice(&work.product);
            } else {
                // No progress (rounding level): undo the correction and stop.
                work.trial.copy_from_slice(&work.projected);
                break;
            }
        }
        if work.trial.iter().any(|value| !value.is_finite()) {
            return Err(Error::NonFinite(
                "box QP reduced solve produced a non-finite value".into(),
            ));
        }
        Ok(())
    }

    /// Conjugate gradients for the reduced system `A_FF y_F = r_F` (`F` = indices not `fixed`;
    /// `rhs` and the returned `solution` vanish on the fixed indices), preconditioned with the
    /// restriction of `A⁻¹` to `F`: `z = (A⁻¹ r̃)_F` where `r̃` is `r` extended by zero. This
    /// preconditioner is SPD on `F` (it is `S_FF⁻¹`, the inverse of the Schur complement of `A`
    /// onto `F`), and the preconditioned operator `S_FF⁻¹ A_FF = I + S_FF⁻¹ A_FI A_II⁻¹ A_IF`
    /// differs from the identity by a term of rank at most `|I|`: CG ends in at most
    /// `min(|F|, |I| + 1)` steps in exact arithmetic, and its spectrum lies in
    /// `[1, 1/(1 − γ²)]` with `γ` the strengthened Cauchy–Schwarz constant between the
    /// discrete functions carried by `F` and by `I`. Stops when `‖r − A_FF y‖_∞ ≤ target` (the
    /// recursively updated residual), after a breakdown, or after the iteration cap.
    #[allow(clippy::needless_range_loop)] // componentwise kernels over several vectors
    fn reduced_cg(
        &mut self,
        fixed: &[bool],
        rhs: &[f64],
        solution: &mut [f64],
        target: f64,
        cg: &mut CgWork,
        stats: &mut BoxQpStats,
    ) -> Result<()> {
        self.ensure_factor(stats)?;
        let n = rhs.len();
        solution.fill(0.0);
        let free = fixed.iter().filter(|f| !**f).count();
        if free == 0 {
            return Ok(());
        }
        let cap = 2 * free.min(n - free + 1) + 20;
        cg.residual.copy_from_slice(rhs);
        if max_abs(&cg.residual) <= target {
            return Ok(());
        }
        self.precondition(
            fixed,
            &cg.residual,
            &mut cg.preconditioned,
            &mut cg.scratch,
            stats,
        )?;
        cg.search.copy_from_slice(&cg.preconditioned);
        let mut rho = dot(&cg.residual, &cg.preconditioned);
        for _ in 0..cap {
            multiply_into(&self.matrix, &cg.search, &mut cg.image);
            for i in 0..n {
                if fixed[i] {
                    cg.image[i] = 0.0;
                }
            }
            let curvature = dot(&cg.search, &cg.image);
            if !(curvature > 0.0 && rho > 0.0) {
                break; // breakdown at the rounding level
            }
            let alpha = rho / curvature;
            for i in 0..n {
                solution[i] += alpha * cg.search[i];
                cg.residual[i] -= alpha * cg.image[i];
            }
            if max_abs(&cg.residual) <= target {
                break;
            }
            cg.previous.copy_from_slice(&cg.preconditioned);
            self.precondition(
                fixed,
                &cg.residual,
                &mut cg.preconditioned,
                &mut cg.scratch,
                stats,
            )?;
            let next_rho = dot(&cg.residual, &cg.preconditioned);
            // Polak–Ribière (flexible) β: robust if the preconditioner is not exactly symmetric.
            let beta = (next_rho
                - cg.residual
                    .iter()
                    .zip(&cg.previous)
                    .map(|(r, z)| r * z)
                    .sum::<f64>())
                / rho;
            rho = next_rho;
            for i in 0..n {
                cg.search[i] = cg.preconditioned[i] + beta * cg.search[i];
            }
        }
        Ok(())
    }

    /// The preconditioner of [`BoxQpSolver::reduced_cg`], `z = B_F r` (zero on the fixed
    /// indices): a symmetric two-level cycle on `A_FF` whose global part is one solve with the
    /// factor of `A` and whose local part is a forward and a backward Gauss–Seidel sweep on the
    /// free indices (see the module documentation, "Linear algebra").
    #[allow(clippy::needless_range_loop)] // componentwise kernels over several vectors
    fn precondition(
        &mut self,
        fixed: &[bool],
        residual: &[f64],
        z: &mut [f64],
        scratch: &mut [f64],
        stats: &mut BoxQpStats,
    ) -> Result<()> {
        stats.inner_iterations += 1;
        z.fill(0.0);
        if SMOOTHING {
            gauss_seidel_sweep(&self.matrix, &self.diagonal, fixed, residual, z, false);
            multiply_into(&self.matrix, z, scratch);
            for i in 0..z.len() {
                scratch[i] = if fixed[i] {
                    0.0
                } else {
                    residual[i] - scratch[i]
                };
            }
        } else {
            scratch.copy_from_slice(residual);
        }
        self.solve_in_place(scratch)?;
        for i in 0..z.len() {
            if !fixed[i] {
                z[i] += scratch[i];
            }
        }
        if SMOOTHING {
            gauss_seidel_sweep(&self.matrix, &self.diagonal, fixed, residual, z, true);
        }
        Ok(())
    }

    /// Numerically factorizes `A` once (the first time a solve needs it).
    fn ensure_factor(&mut self, stats: &mut BoxQpStats) -> Result<()> {
        let factor = self
            .factor
            .as_mut()
            .expect("the active set method analyses A at construction");
        if factor.is_factorized() {
            return Ok(());
        }
        factor.factorize(&self.matrix)?;
        stats.factorizations += 1;
        Ok(())
    }

    /// Overwrites `rhs` with `A⁻¹ rhs` (the factor must exist).
    fn solve_in_place(&mut self, rhs: &mut [f64]) -> Result<()> {
        let dimension = rhs.len();
        self.factor
            .as_mut()
            .expect("the active set method analyses A at construction")
            .solve_block(MatMut::from_column_major_slice_mut(rhs, dimension, 1))
    }

    /// Fills the final statistics for the feasible point `x`.
    fn finish(&self, x: &[f64], problem: &Problem<'_>, stats: &mut BoxQpStats) {
        stats.kkt_residual =
            box_qp_kkt_residual(&self.matrix, problem.rhs, problem.lower, problem.upper, x);
        stats.lower_active = x
            .iter()
            .zip(problem.lower)
            .filter(|(value, lower)| value == lower)
            .count();
        stats.upper_active = x
            .iter()
            .zip(problem.lower.iter().zip(problem.upper))
            .filter(|(value, (lower, upper))| lower < upper && value == upper)
            .count();
    }

    fn no_convergence(&self, iterations: usize, residual: f64, history: &[f64]) -> Error {
        Error::NoConvergence {
            solver: match self.settings.method {
                BoxQpMethod::MonotoneMultigrid => "box QP (truncated nonsmooth Newton multigrid)",
                BoxQpMethod::ActiveSet => "box QP (primal-dual active set + projected Newton)",
            },
            iterations,
            residual,
            tolerance: self.settings.tolerance,
            history: History(history.to_vec()),
        }
    }
}

/// The coarse correction of the box QP with the rows `rows` of `A` and its diagonal
/// ([`CoarseObstacle::new`]), whose coarse problem is solved by a box QP solver with the fine
/// one's settings but the coarse tolerance and iteration limit.
pub(crate) fn coarse_obstacle(
    rows: &Csr,
    diagonal: &[f64],
    settings: BoxQpSettings,
) -> Result<Option<CoarseObstacle<BoxQpSolver>>> {
    CoarseObstacle::new(
        rows,
        diagonal,
        settings.tolerance,
        |matrix, tolerance, max_iterations| {
            BoxQpSolver::new(
                matrix,
                BoxQpSettings {
                    tolerance,
                    max_iterations,
                    ..settings
                },
            )
        },
    )
}

impl NestedBoxQp for BoxQpSolver {
    fn set_tolerance(&mut self, tolerance: f64) {
        BoxQpSolver::set_tolerance(self, tolerance);
    }

    fn solve_nested(
        &mut self,
        rhs: &[f64],
        lower: &[f64],
        upper: &[f64],
        x: &mut [f64],
    ) -> Result<usize> {
        self.solve(rhs, lower, upper, x)
            .map(|stats| stats.iterations + stats.coarse_iterations)
    }
}

/// KKT residual of x for the problem (A, b, lower, upper), as defined above.
///
/// Precisely: with `g = A x − b`, returns
/// `max_i |x_i − clamp(x_i − g_i, lower_i, upper_i)| / max(1, max_i |b_i|)`, the natural
/// residual of the KKT conditions (zero exactly at the solution, for feasible and infeasible `x`
/// alike). Returns `+∞` if the lengths do not match the matrix or a value is not finite, so that
/// a check `residual <= tolerance` fails for such input.
pub fn box_qp_kkt_residual(
    matrix: &SparseColMat<usize, f64>,
    rhs: &[f64],
    lower: &[f64],
    upper: &[f64],
    x: &[f64],
) -> f64 {
    let dimension = matrix.nrows();
    if matrix.ncols() != dimension
        || [rhs.len(), lower.len(), upper.len(), x.len()]
            .iter()
            .any(|len| *len != dimension)
    {
        return f64::INFINITY;
    }
    let mut gradient_values = vec![0.0; dimension];
    gradient(matrix, x, rhs, &mut gradient_values);
    let problem = Problem {
        rhs,
        lower,
        upper,
        scale: max_abs(rhs).max(1.0),
        tie: 0.0,
    };
    if !problem.scale.is_finite() {
        return f64::INFINITY;
    }
    scaled_kkt_residual(x, &gradient_values, &problem)
}

/// `max_i |x_i − clamp(x_i − g_i)| / scale`, or `+∞` if any term is not a number.
///
/// The maximum is kept in [`KKT_LANES`] independent partial maxima (as
/// [`crate::algebra::linalg::max_abs`]: no chain of dependent comparisons, bitwise the sequential
/// maximum).
fn scaled_kkt_residual(x: &[f64], gradient: &[f64], problem: &Problem<'_>) -> f64 {
    let n = x.len();
    let (gradient, lower, upper) = (&gradient[..n], &problem.lower[..n], &problem.upper[..n]);
    let mut lanes = [0.0_f64; KKT_LANES];
    let mut not_a_number = [false; KKT_LANES];
    let mut accumulate = |lane: usize, x: f64, gradient: f64, lower: f64, upper: f64| {
        let term = (x - clamp(x - gradient, lower, upper)).abs();
        not_a_number[lane] |= term.is_nan();
        lanes[lane] = lanes[lane].max(term);
    };
    let full = n / KKT_LANES * KKT_LANES;
    for start in (0..full).step_by(KKT_LANES) {
        let block = start..start + KKT_LANES;
        let (x, gradient) = (&x[block.clone()], &gradient[block.clone()]);
        let (lower, upper) = (&lower[block.clone()], &upper[block]);
        for k in 0..KKT_LANES {
            accumulate(k, x[k], gradient[k], lower[k], upper[k]);
        }
    }
    for i in full..n {
        accumulate(0, x[i], gradient[i], lower[i], upper[i]);
    }
    if not_a_number.contains(&true) {
        return f64::INFINITY;
    }
    lanes.into_iter().fold(0.0, f64::max) / problem.scale
}

/// Partial maxima of [`scaled_kkt_residual`].
const KKT_LANES: usize = 8;

/// `min(max(value, lower), upper)` for `lower ≤ upper`, infinite bounds allowed; a value
/// equal to a bound gives the bound, and a NaN stays NaN (the iterations and the residual
/// then report a non-finite value instead of hiding it on a bound).
///
/// Written with comparisons, which compile to the processor's plain min and max
/// instructions: `f64::max` and `f64::min` must return the other operand for a NaN, which
/// costs extra instructions on the dependency chain of a Gauss–Seidel sweep (the damage step
/// of the 128² benchmark case on an AMD Zen 5: 2.80–3.00 ms per step against 2.88–3.13 ms,
/// interleaved runs; no measurable change on an older machine).
#[inline]
fn clamp(value: f64, lower: f64, upper: f64) -> f64 {
    if value <= lower {
        lower
    } else if value >= upper {
        upper
    } else {
        value
    }
}

/// Projects `x` onto the box.
fn project(x: &mut [f64], lower: &[f64], upper: &[f64]) {
    for i in 0..x.len() {
        x[i] = clamp(x[i], lower[i], upper[i]);
    }
}

/// `gradient = A x − b`.
fn gradient(matrix: &SparseColMat<usize, f64>, x: &[f64], rhs: &[f64], gradient: &mut [f64]) {
    multiply_into(matrix, x, gradient);
    for (g, b) in gradient.iter_mut().zip(rhs) {
        *g -= b;
    }
}

/// `q(x) = ½ xᵀAx − bᵀx = ½ xᵀ(g − b)` with `g = A x − b`.
fn objective(x: &[f64], gradient: &[f64], rhs: &[f64]) -> f64 {
    0.5 * x
        .iter()
        .zip(gradient.iter().zip(rhs))
        .map(|(x, (g, b))| x * (g - b))
        .sum::<f64>()
}

/// Free-gradient target of a multigrid linear correction, as a fraction of the free gradient.
const CORRECTION_FRACTION: f64 = 1e-1;
/// Most conjugate gradient iterations of one multigrid linear correction.
const CORRECTION_ITERATIONS: usize = 10;

/// The error for a negative curvature `dᵀAd < 0` met in `context`: `A` is not positive definite.
fn not_positive_definite(context: &str) -> Error {
    Error::LinearAlgebra {
        context: format!("box QP monotone multigrid, {context}"),
        message: "negative curvature: the matrix A is not positive definite".into(),
    }
}

/// Mark of an index whose last projected Gauss–Seidel update left `x_i` on a bound, with no
/// `x_j` of its row changed since: its next update would leave it there again (up to the
/// order of the sum of its row), so the sweeps skip it. On a damage plateau (β = 1 where the
/// source pushes β up) that is most of the plateau, about half of the nodes in
/// `bench_step`'s problem.
const SETTLED: u8 = 1;
/// Mark of an index whose row saw a change of `x` since its gradient entry was last computed
/// from the row: [`residual_gradient`] recomputes only these entries (the others would come
/// out with the same bits).
const STALE: u8 = 2;

/// Marks the indices `row` (the columns of the row of a changed `x_i`, `i` among them) stale
/// and not settled.
#[inline]
fn mark_stale(row: &[usize], marks: &mut [u8]) {
    for &j in row {
        marks[j] = STALE;
    }
}

/// One projected Gauss–Seidel sweep (forward or backward): every `x_i` in turn is replaced by
/// the exact minimizer of `q` over `[lower_i, upper_i]` with the other values fixed,
/// `clamp(x_i − g_i / a_ii)`. Never increases `q`. Indices marked [`SETTLED`] are skipped;
/// an index left on a bound is marked settled, and a change of `x_i` marks its row
/// [`STALE`] and not settled.
fn projected_gauss_seidel(
    fine: &FineRows,
    problem: &Problem<'_>,
    x: &mut [f64],
    backward: bool,
    marks: &mut [u8],
) {
    let n = x.len();
    for step in 0..n {
        let i = if backward { n - 1 - step } else { step };
        if marks[i] & SETTLED != 0 {
            continue;
        }
        let (lower, upper) = (problem.lower[i], problem.upper[i]);
        let updated = if lower == upper {
            lower
        } else {
            let gradient = fine
                .rows
                .sweep_product(i, x, fine.lower_counts[i], backward)
                - problem.rhs[i];
            clamp(x[i] - gradient * fine.inverse_diagonal[i], lower, upper)
        };
        if updated != x[i] {
            x[i] = updated;
            mark_stale(fine.rows.row(i).0, marks);
        } else if updated == lower || updated == upper {
            marks[i] |= SETTLED;
        }
    }
}

/// Conjugate gradients for the truncated system `A_FF d_F = r_F` (`r` and `d` vanish on the
/// fixed indices) from `d = 0`, preconditioned with one V-cycle of the truncated hierarchy;
/// stops when `‖r − A_FF d‖_∞ ≤ target` or after [`CORRECTION_ITERATIONS`] iterations.
#[allow(clippy::too_many_arguments)]
#[allow(clippy::needless_range_loop)] // componentwise kernels over several vectors
fn multigrid_cg(
    rows: &Csr,
    hierarchy: &mut Hierarchy,
    fixed: &[bool],
    rhs: &[f64],
    solution: &mut [f64],
    target: f64,
    cg: &mut CgWork,
    stats: &mut BoxQpStats,
) -> Result<()> {
    let n = rhs.len();
    solution.fill(0.0);
    cg.residual.copy_from_slice(rhs);
    if max_abs(&cg.residual) <= target {
        return Ok(());
    }
    let mut precondition = |residual: &[f64], z: &mut [f64], stats: &mut BoxQpStats| {
        stats.inner_iterations += 1;
        hierarchy.cycle(residual, z);
    };
    precondition(&cg.residual, &mut cg.preconditioned, stats);
    cg.search.copy_from_slice(&cg.preconditioned);
    let mut rho = dot(&cg.residual, &cg.preconditioned);
    for _ in 0..CORRECTION_ITERATIONS {
        // A_FF s: the products of the free rows only.
        rows.multiply_rows(&cg.search, &mut cg.image, |i| !fixed[i]);
        let curvature = dot(&cg.search, &cg.image);
        if curvature < 0.0 {
            return Err(not_positive_definite(
                "conjugate gradients of the multigrid correction",
            ));
        }
        if !(curvature > 0.0 && rho > 0.0) {
            break; // breakdown at the rounding level
        }
        let alpha = rho / curvature;
        for i in 0..n {
            solution[i] += alpha * cg.search[i];
            cg.residual[i] -= alpha * cg.image[i];
        }
        if max_abs(&cg.residual) <= target {
            break;
        }
        precondition(&cg.residual, &mut cg.preconditioned, stats);
        let next_rho = dot(&cg.residual, &cg.preconditioned);
        let beta = next_rho / rho;
        rho = next_rho;
        for i in 0..n {
            cg.search[i] = cg.preconditioned[i] + beta * cg.search[i];
        }
    }
    Ok(())
}

/// Whether the preconditioner adds the Gauss–Seidel sweeps.
const SMOOTHING: bool = true;

/// One Gauss–Seidel sweep for `A_FF z = r` on the free indices (forward or backward), in place;
/// the matrix is stored with both triangles, so column `i` is row `i`.
fn gauss_seidel_sweep(
    matrix: &SparseColMat<usize, f64>,
    diagonal: &[f64],
    fixed: &[bool],
    rhs: &[f64],
    z: &mut [f64],
    backward: bool,
) {
    let symbolic = matrix.symbolic();
    let rows = symbolic.row_idx();
    let values = matrix.val();
    let n = z.len();
    for step in 0..n {
        let i = if backward { n - 1 - step } else { step };
        if fixed[i] {
            continue;
        }
        let mut sum = rhs[i];
        for position in symbolic.col_range(i) {
            let j = rows[position];
            if !fixed[j] {
                sum -= values[position] * z[j];
            }
        }
        z[i] += sum / diagonal[i];
    }
}

/// `g = A x − b` from the rows of `A`, on the rows marked [`STALE`] (the marks are cleared);
/// the other entries of `g` are up to date.
fn residual_gradient(rows: &Csr, x: &[f64], rhs: &[f64], gradient: &mut [f64], marks: &mut [u8]) {
    {
        let marks = &*marks;
        for_each_row(gradient, |i, g| {
            if marks[i] & STALE != 0 {
                *g = rows.row_product(i, x) - rhs[i];
            }
        });
    }
    for mark in marks.iter_mut() {
        *mark &= !STALE;
    }
}

/// Active set classification of (★) with `c_i = A_ii`; indices with `lower_i = upper_i` are
/// always at their (lower) bound, and an index exactly on a bound whose gradient has the wrong
/// sign by at most `problem.tie` stays at that bound (degenerate ties).
fn classify(
    x: &[f64],
    gradient: &[f64],
    problem: &Problem<'_>,
    diagonal: &[f64],
    state: &mut [BoundStatus],
) {
    for i in 0..x.len() {
        let (lower, upper) = (problem.lower[i], problem.upper[i]);
        let trial = x[i] - gradient[i] / diagonal[i];
        state[i] =
            if lower == upper || trial < lower || (x[i] == lower && gradient[i] >= -problem.tie) {
                BoundStatus::AtLower
            } else if trial > upper || (x[i] == upper && gradient[i] <= problem.tie) {
                BoundStatus::AtUpper
            } else {
                BoundStatus::Free
            };
    }
}

fn state_hash(state: &[BoundStatus]) -> u64 {
    let mut hasher = DefaultHasher::new();
    state.hash(&mut hasher);
    hasher.finish()
}

/// Returns the matrix with compact storage and strictly increasing row indices in every column
/// (rebuilding it, duplicates summed, only if necessary).
fn canonical_storage(matrix: SparseColMat<usize, f64>) -> Result<SparseColMat<usize, f64>> {
    let symbolic = matrix.symbolic();
    let is_canonical = symbolic.col_nnz().is_none()
        && (0..matrix.ncols()).all(|column| {
            symbolic
                .row_idx_of_col_raw(column)
                .windows(2)
                .all(|pair| pair[0] < pair[1])
        });
    if is_canonical {
        return Ok(matrix);
    }
    let mut triplets = Vec::with_capacity(symbolic.compute_nnz());
    for column in 0..matrix.ncols() {
        let rows = symbolic.row_idx_of_col_raw(column);
        let values = matrix.val_of_col(column);
        for (&row, &value) in rows.iter().zip(values) {
            triplets.push(Triplet::new(row, column, value));
        }
    }
    SparseColMat::try_new_from_triplets(matrix.nrows(), matrix.ncols(), &triplets).map_err(|err| {
        Error::InvalidInput(format!(
            "box QP matrix storage could not be normalized: {err:?}"
        ))
    })
}

/// Checks finiteness, a positive diagonal and symmetry (pattern exactly, values to a relative
/// `1e-10`); returns the diagonal. Requires canonical storage.
fn validate_symmetric_positive_diagonal(matrix: &SparseColMat<usize, f64>) -> Result<Vec<f64>> {
    let dimension = matrix.nrows();
    let symbolic = matrix.symbolic();
    let mut diagonal = vec![0.0; dimension];
    for (column, diagonal_entry) in diagonal.iter_mut().enumerate() {
        let rows = symbolic.row_idx_of_col_raw(column);
        let values = matrix.val_of_col(column);
        for (&row, &value) in rows.iter().zip(values) {
            if !value.is_finite() {
                return Err(Error::NonFinite(format!(
                    "box QP matrix entry A[{row},{column}] = {value}"
                )));
            }
        }
        match rows.binary_search(&column) {
            Ok(position) if values[position] > 0.0 => *diagonal_entry = values[position],
            Ok(position) => {
                return Err(Error::InvalidInput(format!(
                    "box QP matrix diagonal entry A[{column},{column}] = {} is not positive",
                    values[position]
                )))
            }
            Err(_) => {
                return Err(Error::InvalidInput(format!(
                    "box QP matrix diagonal entry A[{column},{column}] is missing from the pattern"
                )))
            }
        }
    }
    for column in 0..dimension {
        let rows = symbolic.row_idx_of_col_raw(column);
        let values = matrix.val_of_col(column);
        for (&row, &value) in rows.iter().zip(values) {
            if row == column {
                continue;
            }
            let transposed_rows = symbolic.row_idx_of_col_raw(row);
            let Ok(position) = transposed_rows.binary_search(&column) else {
                return Err(Error::InvalidInput(format!(
                    "box QP matrix pattern is not symmetric: A[{row},{column}] is stored but A[{column},{row}] is not (store both triangles)"
                )));
            };
            let transposed = matrix.val_of_col(row)[position];
            let allowed = 1e-10 * (diagonal[row] * diagonal[column]).sqrt();
            if (value - transposed).abs() > allowed {
                return Err(Error::InvalidInput(format!(
                    "box QP matrix is not symmetric: A[{row},{column}] = {value} but A[{column},{row}] = {transposed}"
                )));
            }
        }
    }
    Ok(diagonal)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algebra::multigrid::tests::laplacian;
    use crate::solvers::box_qp_coarse::tests::{energy, gradient, layer_problem, sparse};
    use crate::solvers::box_qp_coarse::{diffusion_dominance, COARSE_TOLERANCE};
    use proptest::prelude::*;

    type DenseMatrix = Vec<Vec<f64>>;

    use crate::test_random::SeededRandom as TestRng;

    fn sparse_from_dense(dense: &[Vec<f64>]) -> SparseColMat<usize, f64> {
        let n = dense.len();
        let mut triplets = Vec::new();
        for (i, row) in dense.iter().enumerate() {
            for (j, &value) in row.iter().enumerate() {
                if value != 0.0 || i == j {
                    triplets.push(Triplet::new(i, j, value));
                }
            }
        }
        SparseColMat::try_new_from_triplets(n, n, &triplets).unwrap()
    }

    fn dense_times(dense: &[Vec<f64>], x: &[f64]) -> Vec<f64> {
        dense
            .iter()
            .map(|row| row.iter().zip(x).map(|(a, x)| a * x).sum())
            .collect()
    }

    /// Gaussian elimination without pivoting (fine for SPD matrices).
    #[allow(clippy::needless_range_loop)]
    fn dense_solve(dense: &[Vec<f64>], rhs: &[f64]) -> Vec<f64> {
        let n = rhs.len();
        let mut a: Vec<Vec<f64>> = dense.to_vec();
        let mut b = rhs.to_vec();
        for k in 0..n {
            for r in k + 1..n {
                let factor = a[r][k] / a[k][k];
                for c in k..n {
                    a[r][c] -= factor * a[k][c];
                }
                b[r] -= factor * b[k];
            }
        }
        let mut x = vec![0.0; n];
        for k in (0..n).rev() {
            let tail: f64 = (k + 1..n).map(|c| a[k][c] * x[c]).sum();
            x[k] = (b[k] - tail) / a[k][k];
        }
        x
    }

    /// Natural KKT residual computed densely, independently of the solver module.
    fn dense_kkt_residual(
        dense: &[Vec<f64>],
        b: &[f64],
        lower: &[f64],
        upper: &[f64],
        x: &[f64],
    ) -> f64 {
        let ax = dense_times(dense, x);
        let scale = b.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
        let mut residual = 0.0_f64;
        for i in 0..x.len() {
            let g = ax[i] - b[i];
            let projected = (x[i] - g).max(lower[i]).min(upper[i]);
            residual = residual.max((x[i] - projected).abs());
        }
        residual / scale
    }

    fn assert_within_bounds(x: &[f64], lower: &[f64], upper: &[f64]) {
        for i in 0..x.len() {
            assert!(
                lower[i] <= x[i] && x[i] <= upper[i],
                "x[{i}] = {} outside [{}, {}]",
                x[i],
                lower[i],
                upper[i]
            );
        }
    }

    /// A = BᵀB + shift·I with a random sparse B (about three entries per row, both signs), so
    /// that A is SPD with off-diagonal entries of both signs (not an M-matrix).
    fn random_spd(n: usize, rng: &mut TestRng, shift: f64) -> Vec<Vec<f64>> {
        let mut b_matrix = vec![vec![0.0; n]; n];
        for row in b_matrix.iter_mut() {
            for _ in 0..3 {
                row[rng.index(n)] = rng.range(-1.0, 1.0);
            }
        }
        let mut a = vec![vec![0.0; n]; n];
        for i in 0..n {
            for j in 0..n {
                a[i][j] = (0..n).map(|k| b_matrix[k][i] * b_matrix[k][j]).sum();
            }
            a[i][i] += shift;
        }
        a
    }

    /// Consistent P1 mass and stiffness matrices of a uniform 1D grid on [0, 1].
    fn fe_1d(nodes: usize) -> (DenseMatrix, DenseMatrix) {
        let h = 1.0 / (nodes - 1) as f64;
        let mut mass = vec![vec![0.0; nodes]; nodes];
        let mut stiffness = vec![vec![0.0; nodes]; nodes];
        for e in 0..nodes - 1 {
            for (a, i) in [e, e + 1].into_iter().enumerate() {
                for (b, j) in [e, e + 1].into_iter().enumerate() {
                    mass[i][j] += h / 6.0 * if a == b { 2.0 } else { 1.0 };
                    stiffness[i][j] += if a == b { 1.0 } else { -1.0 } / h;
                }
            }
        }
        (mass, stiffness)
    }

    /// Consistent P1 mass and stiffness matrices on the unit square, m×m vertices, each cell cut
    /// into two triangles.
    fn fe_2d(m: usize) -> (DenseMatrix, DenseMatrix, Vec<[f64; 2]>) {
        let h = 1.0 / (m - 1) as f64;
        let n = m * m;
        let vertex = |ix: usize, iy: usize| iy * m + ix;
        let coords: Vec<[f64; 2]> = (0..n)
            .map(|v| [(v % m) as f64 * h, (v / m) as f64 * h])
            .collect();
        let mut mass = vec![vec![0.0; n]; n];
        let mut stiffness = vec![vec![0.0; n]; n];
        for iy in 0..m - 1 {
            for ix in 0..m - 1 {
                let triangles = [
                    [vertex(ix, iy), vertex(ix + 1, iy), vertex(ix + 1, iy + 1)],
                    [vertex(ix, iy), vertex(ix + 1, iy + 1), vertex(ix, iy + 1)],
                ];
                for tri in triangles {
                    let p: Vec<[f64; 2]> = tri.iter().map(|&v| coords[v]).collect();
                    let det = (p[1][0] - p[0][0]) * (p[2][1] - p[0][1])
                        - (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]);
                    let area = 0.5 * det.abs();
                    // gradients of the barycentric coordinates
                    let grads: Vec<[f64; 2]> = (0..3)
                        .map(|a| {
                            let (b, c) = ((a + 1) % 3, (a + 2) % 3);
                            [(p[b][1] - p[c][1]) / det, (p[c][0] - p[b][0]) / det]
                        })
                        .collect();
                    for a in 0..3 {
                        for b in 0..3 {
                            mass[tri[a]][tri[b]] += area / 12.0 * if a == b { 2.0 } else { 1.0 };
                            stiffness[tri[a]][tri[b]] +=
                                area * (grads[a][0] * grads[b][0] + grads[a][1] * grads[b][1]);
                        }
                    }
                }
            }
        }
        (mass, stiffness, coords)
    }

    /// A = M/k + κK.
    fn damage_matrix(
        mass: &[Vec<f64>],
        stiffness: &[Vec<f64>],
        time_step: f64,
        kappa: f64,
    ) -> Vec<Vec<f64>> {
        mass.iter()
            .zip(stiffness)
            .map(|(m, s)| {
                m.iter()
                    .zip(s)
                    .map(|(m, s)| m / time_step + kappa * s)
                    .collect()
            })
            .collect()
    }

    /// b = M (β_prev/k + φ).
    fn damage_rhs(mass: &[Vec<f64>], previous: &[f64], source: &[f64], time_step: f64) -> Vec<f64> {
        let load: Vec<f64> = previous
            .iter()
            .zip(source)
            .map(|(b, f)| b / time_step + f)
            .collect();
        dense_times(mass, &load)
    }

    fn has_positive_off_diagonal(dense: &[Vec<f64>]) -> bool {
        (0..dense.len()).any(|i| (0..dense.len()).any(|j| i != j && dense[i][j] > 0.0))
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn box_qp_satisfies_kkt_on_random_spd(
            n in 1usize..60,
            seed in any::<u64>(),
            shift in 0.01f64..1.0,
            bound_kind in 0usize..4,
        ) {
            let mut rng = TestRng::new(seed);
            let dense = random_spd(n, &mut rng, shift);
            let b: Vec<f64> = (0..n).map(|_| rng.range(-5.0, 5.0)).collect();
            let (lower, upper): (Vec<f64>, Vec<f64>) = match bound_kind {
                // nothing active: no bounds at all
                0 => (vec![f64::NEG_INFINITY; n], vec![f64::INFINITY; n]),
                // a tight box: both bounds active for most data
                1 => (vec![-0.2; n], vec![0.2; n]),
                // random bounds: one-sided, two-sided, equal, infinite
                2 => (0..n)
                    .map(|_| {
                        let a = rng.range(-1.0, 1.0);
                        match rng.index(5) {
                            0 => (a, f64::INFINITY),
                            1 => (f64::NEG_INFINITY, a),
                            2 => (a, a),
                            _ => (a, a + rng.range(0.0, 1.0)),
                        }
                    })
                    .unzip(),
                // wide finite box that no solution reaches
                _ => (vec![-1e6; n], vec![1e6; n]),
            };
            let start: Vec<f64> = (0..n).map(|_| rng.range(-2.0, 2.0)).collect();
            let matrix = sparse_from_dense(&dense);
            for (name, mut solver) in solver_variants(&matrix) {
                let mut x = start.clone();
                let stats = solver.solve(&b, &lower, &upper, &mut x).unwrap();

                assert_within_bounds(&x, &lower, &upper);
                let residual = box_qp_kkt_residual(&matrix, &b, &lower, &upper, &x);
                prop_assert!(residual <= 1e-10, "{name}: KKT residual {residual:e}, stats {stats:?}");
                let independent = dense_kkt_residual(&dense, &b, &lower, &upper, &x);
                prop_assert!(independent <= 1e-10, "{name}: dense KKT residual {independent:e}");
                prop_assert!(stats.kkt_residual <= 1e-12, "{name}: {stats:?}");
                if bound_kind == 0 || bound_kind == 3 {
                    prop_assert_eq!(stats.lower_active + stats.upper_active, 0);
                }
            }
        }

        /// The sweeps skip the indices marked settled and the gradient is recomputed on the
        /// stale rows only: the iterates and gradients are those of sweeps that visit every
        /// index and of a gradient computed on every row.
        #[test]
        fn skipped_rows_are_rows_a_sweep_leaves_unchanged(
            n in 2usize..60,
            seed in any::<u64>(),
            shift in 0.01f64..1.0,
        ) {
            let mut rng = TestRng::new(seed);
            let dense = random_spd(n, &mut rng, shift);
            let b: Vec<f64> = (0..n).map(|_| rng.range(-5.0, 5.0)).collect();
            // index 0 and about a quarter of the others fixed (lower = upper), the rest in a
            // tight box
            let (lower, upper): (Vec<f64>, Vec<f64>) = (0..n)
                .map(|i| match (i, rng.index(4)) {
                    (0, _) | (_, 0) => (-0.1, -0.1),
                    _ => (-0.2, 0.2),
                })
                .unzip();
            let rows = Csr::from_symmetric(&sparse_from_dense(&dense));
            let fine = FineRows {
                lower_counts: rows.lower_counts(),
                inverse_diagonal: (0..n).map(|i| 1.0 / dense[i][i]).collect(),
                rows,
            };
            let problem = Problem { rhs: &b, lower: &lower, upper: &upper, scale: 1.0, tie: 0.0 };
            let start: Vec<f64> = (0..n)
                .map(|i| clamp(rng.range(-0.3, 0.3), lower[i], upper[i]))
                .collect();
            let (mut skipping, mut visiting) = (start.clone(), start);
            let mut marks = vec![STALE; n];
            let (mut gradient, mut full_gradient) = (vec![0.0; n], vec![0.0; n]);
            let mut skipped = 0;
            for sweep in 0..8 {
                let backward = sweep % 2 == 1;
                skipped += marks.iter().filter(|&&m| m & SETTLED != 0).count();
                projected_gauss_seidel(&fine, &problem, &mut skipping, backward, &mut marks);
                projected_gauss_seidel(&fine, &problem, &mut visiting, backward, &mut vec![STALE; n]);
                prop_assert_eq!(&skipping, &visiting, "sweep {}", sweep);
                residual_gradient(&fine.rows, &skipping, &b, &mut gradient, &mut marks);
                residual_gradient(&fine.rows, &visiting, &b, &mut full_gradient, &mut vec![STALE; n]);
                prop_assert_eq!(&gradient, &full_gradient, "sweep {}", sweep);
            }
            // the fixed indices (index 0 at least) are settled after their first visit, so
            // the later sweeps skip them
            prop_assert!(skipped > 0);
        }
    }

    /// A solve does not depend on the solves before it (the work vectors kept between calls
    /// are reset as far as they are read): the second of two problems solved by one solver
    /// gives bitwise the iterate, residual and iteration counts of a fresh solver.
    #[test]
    fn a_solve_does_not_depend_on_earlier_solves() {
        let (mass, stiffness, _) = fe_2d(12);
        let dense = damage_matrix(&mass, &stiffness, 0.01, 0.05);
        let matrix = sparse_from_dense(&dense);
        let n = dense.len();
        // The first problem has its solution on the lower bound everywhere; the next "time
        // step" pushes up a patch in the middle and starts from that solution, so a sweep
        // that skipped the indices settled in the first solve would not move at all.
        let first_b = vec![-1.0 / n as f64; n];
        let first_start = vec![0.5; n];
        let b: Vec<f64> = (0..n)
            .map(|i| if (60..70).contains(&i) { 3.0 } else { -1.0 } / n as f64)
            .collect();
        let (lower, upper) = (vec![0.0; n], vec![1.0; n]);
        for ((name, mut used), (_, mut fresh)) in solver_variants(&matrix)
            .into_iter()
            .zip(solver_variants(&matrix))
        {
            let mut first = first_start.clone();
            used.solve(&first_b, &lower, &upper, &mut first).unwrap();
            let start = first;
            let (mut again, mut once) = (start.clone(), start.clone());
            let again_stats = used.solve(&b, &lower, &upper, &mut again).unwrap();
            let once_stats = fresh.solve(&b, &lower, &upper, &mut once).unwrap();
            assert!(
                once_stats.lower_active + once_stats.upper_active > 0,
                "{name}"
            );
            assert_eq!(again, once, "{name}");
            // (not the factorizations: the factor of `A` is computed once per solver; nor the
            // truncations: a hierarchy keeps its last one, and a truncation recomputes its rows
            // from scratch)
            let counts = |stats: &BoxQpStats| {
                (
                    stats.iterations,
                    stats.inner_iterations,
                    stats.coarse_iterations,
                    stats.kkt_residual.to_bits(),
                    stats.lower_active,
                    stats.upper_active,
                    stats.used_fallback,
                )
            };
            assert_eq!(counts(&again_stats), counts(&once_stats), "{name}");
        }
    }

    /// The row-parallel passes of the monotone multigrid (gradients, products, V-cycle
    /// residuals and transfers) give bitwise the iterates of the sequential ones: a problem
    /// large enough to be split into tasks, solved in a pool of one thread and of two.
    #[test]
    fn multigrid_solve_is_the_same_on_one_and_two_threads() {
        let m = 130; // 16 900 unknowns: at least two tasks of rows
        let matrix = crate::algebra::multigrid::tests::laplacian(m, 0.01);
        let n = m * m;
        // a source pushing a disc up to the upper bound, pulling the rest down to the lower
        let b: Vec<f64> = (0..n)
            .map(|i| {
                let (row, column) = ((i / m) as f64, (i % m) as f64);
                let r2 = (row - 60.0).powi(2) + (column - 70.0).powi(2);
                if r2 < 900.0 {
                    0.5
                } else {
                    -0.02
                }
            })
            .collect();
        let (lower, upper) = (vec![0.0; n], vec![1.0; n]);
        let solve = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let mut solver =
                    BoxQpSolver::new(matrix.clone(), BoxQpSettings::default()).unwrap();
                let mut x = vec![0.5; n];
                let stats = solver.solve(&b, &lower, &upper, &mut x).unwrap();
                (x, stats)
            })
        };
        let (one, one_stats) = solve(1);
        let (two, two_stats) = solve(2);
        assert!(one_stats.lower_active > 0 && one_stats.upper_active > 0);
        assert!(one_stats.inner_iterations > 0);
        assert!(one
            .iter()
            .zip(&two)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
        assert_eq!(
            (
                one_stats.iterations,
                one_stats.inner_iterations,
                one_stats.coarse_iterations
            ),
            (
                two_stats.iterations,
                two_stats.inner_iterations,
                two_stats.coarse_iterations
            )
        );
        assert_eq!(
            one_stats.kkt_residual.to_bits(),
            two_stats.kkt_residual.to_bits()
        );
    }

    /// The solver configurations every property test runs: the active set method, the
    /// monotone multigrid as configured by default (one dense level for these sizes) and the
    /// monotone multigrid on a hierarchy coarsened down to 4 unknowns (several levels).
    fn solver_variants(matrix: &SparseColMat<usize, f64>) -> Vec<(&'static str, BoxQpSolver)> {
        let active_set = BoxQpSettings {
            method: BoxQpMethod::ActiveSet,
            ..BoxQpSettings::default()
        };
        let mut deep = BoxQpSolver::new(matrix.clone(), BoxQpSettings::default()).unwrap();
        if let Some((fine, hierarchy)) = deep.multigrid.as_mut() {
            *hierarchy = Hierarchy::with_coarsest_size(&fine.rows, 4);
        }
        vec![
            (
                "active set",
                BoxQpSolver::new(matrix.clone(), active_set).unwrap(),
            ),
            (
                "multigrid",
                BoxQpSolver::new(matrix.clone(), BoxQpSettings::default()).unwrap(),
            ),
            ("multigrid, deep", deep),
        ]
    }

    /// Settings of the active set method.
    fn active_set() -> BoxQpSettings {
        BoxQpSettings {
            method: BoxQpMethod::ActiveSet,
            ..BoxQpSettings::default()
        }
    }

    #[test]
    fn random_spd_generator_produces_non_m_matrices() {
        let mut rng = TestRng::new(7);
        let dense = random_spd(30, &mut rng, 0.1);
        assert!(has_positive_off_diagonal(&dense));
    }

    #[test]
    fn damage_step_1d_activates_both_bounds_and_satisfies_kkt() {
        let nodes = 50;
        let (mass, stiffness) = fe_1d(nodes);
        let (time_step, kappa) = (0.01, 1e-3);
        let dense = damage_matrix(&mass, &stiffness, time_step, kappa);
        assert!(
            has_positive_off_diagonal(&dense),
            "test matrix should not be an M-matrix"
        );
        let previous = vec![0.5; nodes];
        let source: Vec<f64> = (0..nodes)
            .map(|i| match i * 3 / nodes {
                0 => 80.0,
                1 => 0.0,
                _ => -80.0,
            })
            .collect();
        let b = damage_rhs(&mass, &previous, &source, time_step);
        let (lower, upper) = (vec![0.0; nodes], vec![1.0; nodes]);
        let matrix = sparse_from_dense(&dense);
        let mut solver = BoxQpSolver::new(matrix.clone(), BoxQpSettings::default()).unwrap();
        let mut x = previous.clone();
        let stats = solver.solve(&b, &lower, &upper, &mut x).unwrap();
        assert!(
            stats.lower_active > 0 && stats.upper_active > 0,
            "{stats:?}"
        );
        assert!(stats.lower_active + stats.upper_active < nodes, "{stats:?}");
        assert_within_bounds(&x, &lower, &upper);
        assert!(box_qp_kkt_residual(&matrix, &b, &lower, &upper, &x) <= 1e-12);
        assert!(dense_kkt_residual(&dense, &b, &lower, &upper, &x) <= 1e-12);
    }

    #[test]
    fn damage_step_2d_activates_both_bounds_and_satisfies_kkt() {
        let m = 7;
        let (mass, stiffness, coords) = fe_2d(m);
        let (time_step, kappa) = (0.01, 1e-3);
        let dense = damage_matrix(&mass, &stiffness, time_step, kappa);
        assert!(has_positive_off_diagonal(&dense));
        let n = m * m;
        let previous = vec![0.5; n];
        let source: Vec<f64> = coords
            .iter()
            .map(|p| {
                if p[0] < 0.34 {
                    100.0
                } else if p[0] > 0.66 {
                    -100.0
                } else {
                    0.0
                }
            })
            .collect();
        let b = damage_rhs(&mass, &previous, &source, time_step);
        let (lower, upper) = (vec![0.0; n], vec![1.0; n]);
        let matrix = sparse_from_dense(&dense);
        let mut solver = BoxQpSolver::new(matrix.clone(), BoxQpSettings::default()).unwrap();
        let mut x = previous.clone();
        let stats = solver.solve(&b, &lower, &upper, &mut x).unwrap();
        assert!(
            stats.lower_active > 0 && stats.upper_active > 0,
            "{stats:?}"
        );
        assert_within_bounds(&x, &lower, &upper);
        assert!(dense_kkt_residual(&dense, &b, &lower, &upper, &x) <= 1e-12);
    }

    #[test]
    fn unconstrained_box_qp_equals_linear_solve() {
        let m = 7;
        let (mass, stiffness, _) = fe_2d(m);
        let dense = damage_matrix(&mass, &stiffness, 0.01, 1e-3);
        let n = m * m;
        let mut rng = TestRng::new(3);
        let b: Vec<f64> = (0..n).map(|_| rng.range(-1.0, 1.0)).collect();
        let expected = dense_solve(&dense, &b);
        for (lower, upper) in [
            (vec![f64::NEG_INFINITY; n], vec![f64::INFINITY; n]),
            (vec![-1e3; n], vec![1e3; n]),
        ] {
            for (name, mut solver) in solver_variants(&sparse_from_dense(&dense)) {
                let mut x = vec![0.0; n];
                let stats = solver.solve(&b, &lower, &upper, &mut x).unwrap();
                assert_eq!((stats.lower_active, stats.upper_active), (0, 0));
                if name == "active set" {
                    assert_eq!((stats.iterations, stats.factorizations), (1, 1));
                } else {
                    // Nothing on a bound: one smoothing sweep and one linear multigrid correction
                    // per iteration, which converges linearly.
                    assert_eq!(stats.factorizations, 0);
                    assert!(stats.iterations <= 10, "{name}: {stats:?}");
                }
                assert!(!stats.used_fallback);
                let norm = expected.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
                for i in 0..n {
                    assert!(
                        (x[i] - expected[i]).abs() <= 1e-12 * norm,
                        "{name}: x[{i}] = {} vs {}",
                        x[i],
                        expected[i]
                    );
                }
            }
        }
    }

    #[test]
    fn all_active_box_qp_returns_the_bounds_exactly() {
        let nodes = 40;
        let (mass, stiffness) = fe_1d(nodes);
        let (time_step, kappa) = (0.01, 1e-3);
        let dense = damage_matrix(&mass, &stiffness, time_step, kappa);
        // K·1 = 0, so the unconstrained solution of A x = 10⁴ M 1 is x = 10⁴ k = 100 > 1.
        let b = dense_times(&mass, &vec![1e4; nodes]);
        let (lower, upper) = (vec![0.0; nodes], vec![1.0; nodes]);
        let mut solver =
            BoxQpSolver::new(sparse_from_dense(&dense), BoxQpSettings::default()).unwrap();
        let mut x = vec![0.3; nodes];
        let stats = solver.solve(&b, &lower, &upper, &mut x).unwrap();
        assert_eq!(stats.upper_active, nodes);
        assert_eq!(stats.lower_active, 0);
        assert!(x.iter().all(|&v| v == 1.0));
        assert!(stats.kkt_residual <= 1e-12);

        // Equal bounds fix every variable, whatever the data.
        let fixed: Vec<f64> = (0..nodes).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut x = vec![0.0; nodes];
        let stats = solver.solve(&b, &fixed, &fixed, &mut x).unwrap();
        assert_eq!(x, fixed);
        assert_eq!((stats.lower_active, stats.upper_active), (nodes, 0));
        assert_eq!(stats.kkt_residual, 0.0);
    }

    #[test]
    fn the_matrix_is_factorized_once_per_solver() {
        let nodes = 50;
        let (mass, stiffness) = fe_1d(nodes);
        let (time_step, kappa) = (0.01, 1e-3);
        let dense = damage_matrix(&mass, &stiffness, time_step, kappa);
        let previous = vec![0.5; nodes];
        let source: Vec<f64> = (0..nodes)
            .map(|i| match i * 3 / nodes {
                0 => 80.0,
                1 => 0.0,
                _ => -80.0,
            })
            .collect();
        let b = damage_rhs(&mass, &previous, &source, time_step);
        let (lower, upper) = (vec![0.0; nodes], vec![1.0; nodes]);
        let mut solver = BoxQpSolver::new(sparse_from_dense(&dense), active_set()).unwrap();
        let mut x = previous.clone();
        let first = solver.solve(&b, &lower, &upper, &mut x).unwrap();
        assert_eq!(first.factorizations, 1, "{first:?}");

        // Same data from the solution: nothing to do.
        let second = solver.solve(&b, &lower, &upper, &mut x).unwrap();
        assert_eq!(second.factorizations, 0, "{second:?}");

        // Slightly different data with the same active set: still no factorization.
        let perturbed: Vec<f64> = b.iter().map(|v| v * (1.0 + 1e-6)).collect();
        let third = solver.solve(&perturbed, &lower, &upper, &mut x).unwrap();
        assert_eq!(third.factorizations, 0, "{third:?}");
        assert!(third.iterations >= 1);
        assert_eq!(
            (third.lower_active, third.upper_active),
            (first.lower_active, first.upper_active)
        );
        assert!(third.kkt_residual <= 1e-12);
    }

    /// β_prev = 1 without a source on the left half: there x* = 1 with g* = 0 (degenerate), so
    /// the sign of g is rounding noise; the iteration must still stop quickly, without fallback.
    #[test]
    fn degenerate_plateau_at_the_upper_bound_converges_quickly() {
        let nodes = 60;
        let (mass, stiffness) = fe_1d(nodes);
        let (time_step, kappa) = (0.01, 1e-3);
        let dense = damage_matrix(&mass, &stiffness, time_step, kappa);
        let previous: Vec<f64> = (0..nodes)
            .map(|i| if i < nodes / 2 { 1.0 } else { 0.5 })
            .collect();
        let source: Vec<f64> = (0..nodes)
            .map(|i| if i < 2 * nodes / 3 { 0.0 } else { -80.0 })
            .collect();
        let b = damage_rhs(&mass, &previous, &source, time_step);
        let (lower, upper) = (vec![0.0; nodes], vec![1.0; nodes]);
        let mut solver =
            BoxQpSolver::new(sparse_from_dense(&dense), BoxQpSettings::default()).unwrap();
        let mut x = previous.clone();
        let stats = solver.solve(&b, &lower, &upper, &mut x).unwrap();
        assert!(!stats.used_fallback && stats.iterations <= 4, "{stats:?}");
        assert!(stats.lower_active > 0, "{stats:?}");
        assert!(dense_kkt_residual(&dense, &b, &lower, &upper, &x) <= 1e-12);
        // The plateau stays at 1 up to rounding.
        assert!(
            x[..nodes / 4].iter().all(|&v| (v - 1.0).abs() <= 1e-13),
            "{x:?}"
        );
    }

    /// A 3×3 SPD (not M-) matrix for which plain PDAS for `x ≥ 0` has the 3-cycle
    /// {1} → {0,1,2} → {2} → {1} of active sets (found by a search; checked in exact rational
    /// arithmetic: every decision has a margin of at least 1/60). The solution is (11/30, 0, 0).
    fn cycling_example() -> (Vec<Vec<f64>>, Vec<f64>) {
        let dense = vec![
            vec![30.0, 21.0, -19.0],
            vec![21.0, 19.0, -9.0],
            vec![-19.0, -9.0, 22.0],
        ];
        (dense, vec![11.0, 1.0, -13.0])
    }

    /// One plain PDAS step for `x ≥ 0` (c = 1), dense and independent of the solver.
    fn plain_pdas_step(dense: &[Vec<f64>], b: &[f64], active: &[bool]) -> Vec<bool> {
        let n = b.len();
        let free: Vec<usize> = (0..n).filter(|&i| !active[i]).collect();
        let reduced: Vec<Vec<f64>> = free
            .iter()
            .map(|&i| free.iter().map(|&j| dense[i][j]).collect())
            .collect();
        let reduced_rhs: Vec<f64> = free.iter().map(|&i| b[i]).collect();
        let solution = dense_solve(&reduced, &reduced_rhs);
        let mut x = vec![0.0; n];
        for (k, &i) in free.iter().enumerate() {
            x[i] = solution[k];
        }
        let ax = dense_times(dense, &x);
        (0..n).map(|i| x[i] - (ax[i] - b[i]) < 0.0).collect()
    }

    #[test]
    fn plain_pdas_cycles_on_the_example() {
        let (dense, b) = cycling_example();
        let cycle = [
            vec![false, true, false],
            vec![true, true, true],
            vec![false, false, true],
        ];
        for k in 0..3 {
            assert_eq!(plain_pdas_step(&dense, &b, &cycle[k]), cycle[(k + 1) % 3]);
        }
    }

    #[test]
    fn box_qp_converges_with_fallback_where_plain_pdas_cycles() {
        let (dense, b) = cycling_example();
        let (lower, upper) = (vec![0.0; 3], vec![f64::INFINITY; 3]);
        let mut solver = BoxQpSolver::new(sparse_from_dense(&dense), active_set()).unwrap();
        let mut x = vec![0.0; 3];
        let stats = solver.solve(&b, &lower, &upper, &mut x).unwrap();
        assert!(stats.used_fallback, "{stats:?}");
        assert!(stats.kkt_residual <= 1e-12);
        assert_eq!((stats.lower_active, stats.upper_active), (2, 0));
        assert!((x[0] - 11.0 / 30.0).abs() <= 1e-15, "{x:?}");
        assert_eq!(&x[1..], &[0.0, 0.0]);
    }

    #[test]
    fn monotone_multigrid_solves_the_pdas_cycling_example() {
        let (dense, b) = cycling_example();
        let (lower, upper) = (vec![0.0; 3], vec![f64::INFINITY; 3]);
        for (name, mut solver) in solver_variants(&sparse_from_dense(&dense))
            .into_iter()
            .skip(1)
        {
            let mut x = vec![0.0; 3];
            let stats = solver.solve(&b, &lower, &upper, &mut x).unwrap();
            assert!(stats.kkt_residual <= 1e-12, "{name}: {stats:?}");
            assert_eq!((stats.lower_active, stats.upper_active), (2, 0), "{name}");
            assert!((x[0] - 11.0 / 30.0).abs() <= 1e-15, "{name}: {x:?}");
            assert_eq!(&x[1..], &[0.0, 0.0], "{name}");
        }
    }

    /// The monotone multigrid never increases q = ½xᵀAx − bᵀx (projected Gauss–Seidel and a
    /// line search on a projected correction), checked iteration by iteration through the
    /// iteration cap, on a 2D damage matrix with a four-level hierarchy.
    #[test]
    fn monotone_multigrid_decreases_the_energy_at_every_iteration() {
        let m = 24;
        let (mass, stiffness, coords) = fe_2d(m);
        let (time_step, kappa) = (0.01, 1e-2);
        let dense = damage_matrix(&mass, &stiffness, time_step, kappa);
        let previous: Vec<f64> = coords
            .iter()
            .map(|p| 0.5 + 0.5 * (6.0 * p[0]).sin())
            .collect();
        let source: Vec<f64> = coords
            .iter()
            .map(|p| if p[1] < 0.5 { 150.0 } else { -150.0 })
            .collect();
        let b = damage_rhs(&mass, &previous, &source, time_step);
        let n = m * m;
        let (lower, upper) = (vec![0.0; n], vec![1.0; n]);
        let matrix = sparse_from_dense(&dense);
        let energy = |x: &[f64]| {
            let ax = dense_times(&dense, x);
            (0..n)
                .map(|i| 0.5 * x[i] * ax[i] - b[i] * x[i])
                .sum::<f64>()
        };
        let mut x = previous.clone();
        project(&mut x, &lower, &upper);
        let mut last = energy(&x);
        let mut converged = false;
        for _ in 0..40 {
            let settings = BoxQpSettings {
                max_iterations: 1,
                ..BoxQpSettings::default()
            };
            let mut solver = BoxQpSolver::new(matrix.clone(), settings).unwrap();
            if let Some((fine, hierarchy)) = solver.multigrid.as_mut() {
                *hierarchy = Hierarchy::with_coarsest_size(&fine.rows, 8);
                assert!(hierarchy.sizes().len() >= 3, "{:?}", hierarchy.sizes());
            }
            let result = solver.solve(&b, &lower, &upper, &mut x);
            assert_within_bounds(&x, &lower, &upper);
            let now = energy(&x);
            assert!(
                now <= last + 1e-14 * last.abs(),
                "energy rose from {last} to {now}"
            );
            last = now;
            if let Ok(stats) = result {
                assert!(stats.kkt_residual <= 1e-12);
                converged = true;
                break;
            }
        }
        assert!(converged, "no convergence in 40 single iterations");
        assert!(dense_kkt_residual(&dense, &b, &lower, &upper, &x) <= 1e-12);
    }

    #[test]
    fn box_qp_reports_no_convergence_with_history() {
        let (dense, b) = cycling_example();
        let settings = BoxQpSettings {
            tolerance: 1e-12,
            max_iterations: 2,
            ..active_set()
        };
        let mut solver = BoxQpSolver::new(sparse_from_dense(&dense), settings).unwrap();
        let mut x = vec![0.0; 3];
        match solver.solve(&b, &[0.0; 3], &[f64::INFINITY; 3], &mut x) {
            Err(Error::NoConvergence {
                iterations,
                history,
                ..
            }) => {
                assert_eq!(iterations, 2);
                assert!(history.0.len() >= 2);
            }
            other => panic!("expected NoConvergence, got {other:?}"),
        }
        assert_within_bounds(&x, &[0.0; 3], &[f64::INFINITY; 3]);
    }

    #[test]
    fn box_qp_rejects_crossed_bounds() {
        let (dense, b) = cycling_example();
        let mut solver =
            BoxQpSolver::new(sparse_from_dense(&dense), BoxQpSettings::default()).unwrap();
        let mut x = vec![0.0; 3];
        let err = solver
            .solve(&b, &[0.0, 1.0, 0.0], &[1.0, 0.5, 1.0], &mut x)
            .unwrap_err();
        assert!(
            matches!(&err, Error::InvalidInput(message) if message.contains("index 1")),
            "{err}"
        );
    }

    #[test]
    fn box_qp_rejects_length_mismatch_and_non_finite_data() {
        let (dense, b) = cycling_example();
        let mut solver =
            BoxQpSolver::new(sparse_from_dense(&dense), BoxQpSettings::default()).unwrap();
        let mut x = vec![0.0; 3];
        let err = solver
            .solve(&b[..2], &[0.0; 3], &[1.0; 3], &mut x)
            .unwrap_err();
        assert!(
            matches!(&err, Error::InvalidInput(message) if message.contains("`rhs`")),
            "{err}"
        );
        let mut short = vec![0.0; 2];
        let err = solver
            .solve(&b, &[0.0; 3], &[1.0; 3], &mut short)
            .unwrap_err();
        assert!(
            matches!(&err, Error::InvalidInput(message) if message.contains("`x`")),
            "{err}"
        );
        let err = solver
            .solve(&[1.0, f64::NAN, 0.0], &[0.0; 3], &[1.0; 3], &mut x)
            .unwrap_err();
        assert!(
            matches!(&err, Error::NonFinite(message) if message.contains("rhs[1]")),
            "{err}"
        );
        let err = solver
            .solve(&b, &[0.0, 0.0, f64::INFINITY], &[f64::INFINITY; 3], &mut x)
            .unwrap_err();
        assert!(
            matches!(&err, Error::InvalidInput(message) if message.contains("index 2")),
            "{err}"
        );
        assert_eq!(
            box_qp_kkt_residual(solver.matrix(), &b[..2], &[0.0; 3], &[1.0; 3], &x),
            f64::INFINITY
        );
    }

    #[test]
    fn box_qp_rejects_non_symmetric_pattern() {
        let triplets = [
            Triplet::new(0, 0, 2.0),
            Triplet::new(1, 1, 2.0),
            Triplet::new(0, 1, 0.5),
        ];
        let matrix = SparseColMat::try_new_from_triplets(2, 2, &triplets).unwrap();
        let err = BoxQpSolver::new(matrix, BoxQpSettings::default()).unwrap_err();
        assert!(
            matches!(&err, Error::InvalidInput(message) if message.contains("pattern is not symmetric")),
            "{err}"
        );

        let matrix = sparse_from_dense(&[vec![2.0, 0.5], vec![0.7, 2.0]]);
        let err = BoxQpSolver::new(matrix, BoxQpSettings::default()).unwrap_err();
        assert!(
            matches!(&err, Error::InvalidInput(message) if message.contains("not symmetric")),
            "{err}"
        );
    }

    #[test]
    fn box_qp_rejects_non_positive_diagonal_and_bad_shapes() {
        let matrix = sparse_from_dense(&[vec![2.0, 0.5], vec![0.5, 0.0]]);
        let err = BoxQpSolver::new(matrix, BoxQpSettings::default()).unwrap_err();
        assert!(
            matches!(&err, Error::InvalidInput(message) if message.contains("A[1,1]")),
            "{err}"
        );

        let rectangular =
            SparseColMat::<usize, f64>::try_new_from_triplets(2, 3, &[Triplet::new(0, 0, 1.0)])
                .unwrap();
        let err = BoxQpSolver::new(rectangular, BoxQpSettings::default()).unwrap_err();
        assert!(matches!(err, Error::InvalidInput(_)), "{err}");

        let matrix = sparse_from_dense(&[vec![2.0]]);
        let settings = BoxQpSettings {
            tolerance: 0.0,
            max_iterations: 10,
            ..Default::default()
        };
        assert!(matches!(
            BoxQpSolver::new(matrix, settings),
            Err(Error::InvalidParameter { .. })
        ));
    }

    #[test]
    fn indefinite_matrix_is_reported_by_the_factorization() {
        let matrix = sparse_from_dense(&[vec![1.0, 2.0], vec![2.0, 1.0]]);
        for (name, mut solver) in solver_variants(&matrix) {
            let err = unbounded_solve(&mut solver, &[1.0, 1.0]).unwrap_err();
            assert!(matches!(err, Error::LinearAlgebra { .. }), "{name}: {err}");
        }
    }

    /// Solves without bounds (a linear solve) from zero.
    fn unbounded_solve(solver: &mut BoxQpSolver, b: &[f64]) -> Result<BoxQpStats> {
        let n = b.len();
        let mut x = vec![0.0; n];
        solver.solve(
            b,
            &vec![f64::NEG_INFINITY; n],
            &vec![f64::INFINITY; n],
            &mut x,
        )
    }

    /// An indefinite matrix on a multilevel hierarchy: a 2D Laplacian shifted by −0.5 has
    /// negative eigenvalues; the multigrid reports negative curvature instead of diverging.
    #[test]
    fn indefinite_matrix_is_reported_by_the_multigrid() {
        let m = 20;
        let (_, stiffness, _) = fe_2d(m);
        let n = m * m;
        let mut dense = stiffness.clone();
        for (i, row) in dense.iter_mut().enumerate() {
            row[i] -= 0.5;
        }
        let matrix = sparse_from_dense(&dense);
        let mut solver = BoxQpSolver::new(matrix, BoxQpSettings::default()).unwrap();
        if let Some((fine, hierarchy)) = solver.multigrid.as_mut() {
            *hierarchy = Hierarchy::with_coarsest_size(&fine.rows, 16);
        }
        let b: Vec<f64> = (0..n).map(|i| ((i * 37) % 11) as f64 - 5.0).collect();
        let err = unbounded_solve(&mut solver, &b).unwrap_err();
        assert!(matches!(err, Error::LinearAlgebra { .. }), "{err}");
    }

    #[test]
    fn monotone_multigrid_reports_no_convergence_with_history() {
        let m = 20;
        let (mass, stiffness, coords) = fe_2d(m);
        let dense = damage_matrix(&mass, &stiffness, 0.01, 1e-2);
        let n = m * m;
        let source: Vec<f64> = coords.iter().map(|p| 200.0 * (p[0] - 0.5)).collect();
        let b = damage_rhs(&mass, &vec![0.5; n], &source, 0.01);
        let settings = BoxQpSettings {
            max_iterations: 1,
            ..BoxQpSettings::default()
        };
        let mut solver = BoxQpSolver::new(sparse_from_dense(&dense), settings).unwrap();
        let mut x = vec![0.5; n];
        match solver.solve(&b, &vec![0.0; n], &vec![1.0; n], &mut x) {
            Err(Error::NoConvergence {
                iterations,
                history,
                solver,
                ..
            }) => {
                assert_eq!(iterations, 1);
                assert!(history.0.len() >= 2, "{history:?}");
                assert!(solver.contains("multigrid"), "{solver}");
            }
            other => panic!("expected NoConvergence, got {other:?}"),
        }
        assert_within_bounds(&x, &vec![0.0; n], &vec![1.0; n]);
    }

    #[test]
    fn unsorted_column_storage_is_normalized() {
        use faer::sparse::SymbolicSparseColMat;
        // [[2, 1], [1, 3]] with the rows of column 0 stored in reverse order.
        let symbolic =
            SymbolicSparseColMat::new_unsorted_checked(2, 2, vec![0, 2, 4], None, vec![1, 0, 0, 1]);
        let matrix = SparseColMat::new(symbolic, vec![1.0, 2.0, 1.0, 3.0]);
        let mut solver = BoxQpSolver::new(matrix, BoxQpSettings::default()).unwrap();
        let mut x = vec![0.0; 2];
        solver
            .solve(
                &[3.0, 4.0],
                &[f64::NEG_INFINITY; 2],
                &[f64::INFINITY; 2],
                &mut x,
            )
            .unwrap();
        assert!(
            (x[0] - 1.0).abs() < 1e-14 && (x[1] - 1.0).abs() < 1e-14,
            "{x:?}"
        );
    }

    // The coarse obstacle corrections with the box QP solver as their nested solver.

    #[test]
    fn only_large_diffusion_dominated_problems_get_a_coarse_correction() {
        let settings = BoxQpSettings::default();
        let dominated = Csr::from_symmetric(&laplacian(60, 0.01));
        assert!(diffusion_dominance(&dominated, &dominated.diagonal()) > 400.0);
        let coarse = coarse_obstacle(&dominated, &dominated.diagonal(), settings).unwrap();
        assert!(coarse.is_some_and(|c| c.coarse_size() < 3600 / 2));
        // Mass-dominated (a_ii / Σ_j a_ij ≈ 1): the layers are a cell wide.
        let mass = Csr::from_symmetric(&laplacian(60, 10.0));
        assert!(diffusion_dominance(&mass, &mass.diagonal()) < 2.0);
        assert!(coarse_obstacle(&mass, &mass.diagonal(), settings)
            .unwrap()
            .is_none());
        // Too small to pay.
        let small = Csr::from_symmetric(&laplacian(40, 0.01));
        assert!(coarse_obstacle(&small, &small.diagonal(), settings)
            .unwrap()
            .is_none());
    }

    /// From the upper bound everywhere (the layer and the right half must leave it), the
    /// coarse correction alone removes most of the energy gap to the solution, which the fine
    /// iteration's smoother frees a layer of cells at a time.
    #[test]
    fn coarse_correction_frees_a_layer_far_from_the_start() {
        let m = 60;
        let (rows, rhs) = layer_problem(m);
        let n = m * m;
        let (lower, upper) = (vec![0.0; n], vec![1.0; n]);
        let settings = BoxQpSettings::default();
        let mut coarse = coarse_obstacle(&rows, &rows.diagonal(), settings)
            .unwrap()
            .unwrap();
        let mut x = vec![1.0; n];
        let start = energy(&rows, &x, &rhs);
        let slope = gradient(&rows, &x, &rhs);
        let tolerance = coarse.coarse_tolerance();
        coarse
            .correct(&mut x, &slope, &lower, &upper, tolerance)
            .unwrap();
        let corrected = energy(&rows, &x, &rhs);
        let mut solution = vec![1.0; n];
        BoxQpSolver::new(sparse(&rows), settings)
            .unwrap()
            .solve(&rhs, &lower, &upper, &mut solution)
            .unwrap();
        let optimum = energy(&rows, &solution, &rhs);
        let removed = (start - corrected) / (start - optimum);
        assert!(removed > 0.9, "removed {removed} of the energy gap");
        assert!(x.iter().all(|v| (0.0..=1.0).contains(v)));
    }

    /// On random data (bounds with fixed indices, infinite ones, a random feasible start) the
    /// corrected point stays in the box and its energy does not increase.
    #[test]
    fn coarse_correction_stays_in_the_box_and_never_raises_the_energy() {
        let m = 50;
        let (rows, _) = layer_problem(m);
        let n = m * m;
        let mut coarse = coarse_obstacle(&rows, &rows.diagonal(), BoxQpSettings::default())
            .unwrap()
            .unwrap();
        let mut rng = TestRng::new(7);
        for _ in 0..8 {
            let rhs: Vec<f64> = (0..n).map(|_| rng.range(-0.05, 0.05)).collect();
            let mut lower = Vec::with_capacity(n);
            let mut upper = Vec::with_capacity(n);
            for _ in 0..n {
                let (a, b) = (rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
                match rng.index(10) {
                    0 => (lower.push(a), upper.push(a)),
                    1 => (lower.push(f64::NEG_INFINITY), upper.push(a.max(b))),
                    2 => (lower.push(a.min(b)), upper.push(f64::INFINITY)),
                    _ => (lower.push(a.min(b)), upper.push(a.max(b))),
                };
            }
            let mut x: Vec<f64> = (0..n)
                .map(|i| {
                    let (l, u) = (lower[i].max(-2.0), upper[i].min(2.0));
                    l + rng.range(0.0, 1.0) * (u - l)
                })
                .collect();
            let before = energy(&rows, &x, &rhs);
            let slope = gradient(&rows, &x, &rhs);
            let tolerance = coarse.coarse_tolerance();
            coarse
                .correct(&mut x, &slope, &lower, &upper, tolerance)
                .unwrap();
            assert!((0..n).all(|i| lower[i] <= x[i] && x[i] <= upper[i]));
            let after = energy(&rows, &x, &rhs);
            assert!(
                after <= before + 1e-12 * before.abs().max(1.0),
                "{before} -> {after}"
            );
        }
    }

    #[test]
    fn below_the_coarse_tolerance_only_a_band_gets_a_correction() {
        let (rows, _) = layer_problem(60);
        let settings = BoxQpSettings::default();
        let coarse = coarse_obstacle(&rows, &rows.diagonal(), settings)
            .unwrap()
            .unwrap();
        let n = 3600;
        // √n = 60: a band is more than 12 indices
        let never = || -> usize { panic!("counted above the coarse tolerance") };
        assert_eq!(coarse.tolerance_at(1e-3, n, never), Some(COARSE_TOLERANCE));
        assert_eq!(coarse.tolerance_at(1e-8, n, || 12), None);
        assert_eq!(coarse.tolerance_at(1e-8, n, || 13), Some(1e-9));
        assert_eq!(
            coarse.tolerance_at(5e-12, n, || 1000),
            Some(settings.tolerance)
        );
        assert_eq!(coarse.tolerance_at(settings.tolerance, n, || 1000), None);
    }

    /// The layer problem scaled by s = 5e-8 (right-hand side and bounds: the solution scales
    /// with them): from the upper bound everywhere the start residual, at most s, is below
    /// the coarse tolerance, yet the right half and the layer must leave the bound. The band rule
    /// lets the coarse corrections act; without it (no coarse correction below the coarse
    /// tolerance) the fine iteration frees the band a few cells per iteration.
    #[test]
    fn a_band_left_below_the_coarse_tolerance_is_freed_by_coarse_corrections() {
        let m = 80;
        let (rows, rhs) = layer_problem(m);
        let n = m * m;
        let scale = 5e-8;
        let rhs: Vec<f64> = rhs.iter().map(|b| b * scale).collect();
        let (lower, upper) = (vec![0.0; n], vec![scale; n]);
        let mut solver = BoxQpSolver::new(sparse(&rows), BoxQpSettings::default()).unwrap();
        let mut x = upper.clone();
        let start = gradient(&rows, &x, &rhs);
        let start_residual = (0..n)
            .map(|i| (x[i] - (x[i] - start[i]).clamp(lower[i], upper[i])).abs())
            .fold(0.0_f64, f64::max);
        assert!(start_residual < COARSE_TOLERANCE, "{start_residual}");
        let stats = solver.solve(&rhs, &lower, &upper, &mut x).unwrap();
        // 4 fine iterations (8 coarse ones) with the rule, 9 without it
        assert!(stats.coarse_iterations > 0, "{stats:?}");
        assert!(stats.iterations <= 5, "{stats:?}");
    }
}
