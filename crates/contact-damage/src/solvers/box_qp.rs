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
//! # Predicted bound sets
//! [`BoxQpSolver::solve_predicted`] is given a bound set `(L, U)`, e.g. the one of the previous
//! time step. With `x_L = lower_L`, `x_U = upper_U`, the free values solve
//! `A_FF x_F = b_F − A_FL lower_L − A_FU upper_U`, with a Cholesky factor of `A` whose fixed
//! rows and columns are replaced by the identity's (the pattern of `A`, so one symbolic
//! analysis serves every set; the numeric factor is recomputed when the set changes). The
//! candidate, projected onto the box, is the solution when its KKT residual is within the
//! tolerance, which holds exactly when the set is the solution's (up to degenerate indices).
//! Otherwise the solve proceeds by the chosen method from the given start, as
//! [`BoxQpSolver::solve`]. The result is a function of the data, the start and the set alone.
//!
//! # Followed bound sets
//! [`BoxQpSolver::solve_following`] serves a sequence of problems with the same `A` whose bound
//! sets move by a few indices from one to the next, as the plateau of a damage front does. It
//! runs the primal–dual active set iteration below (at most four sets) from the bound set of
//! the start, and solves each set with the factor of a *reference* set kept from earlier calls,
//! bordered by the indices whose free/fixed status differs from it: the Schur complement
//! update of the active set QP methods (Gill, Murray, Saunders & Wright 1990). An index freed
//! since borders the reference matrix with its column of `A`, an index fixed since with a unit
//! vector and a multiplier; the border's columns of `L⁻¹G` are sparse (the elimination tree
//! paths from their nonzeros) and computed once per index and reference factor, so a set
//! costs a backward solve, products with the border's columns and a dense system of the
//! border (at most 64 indices; a set further away is factorized and becomes the reference).
//! A candidate is accepted as `solve_predicted`'s is, by its KKT residual; when the iteration
//! stalls, cycles or moves far from the set it factorized, the solve proceeds by the chosen
//! method from the start. The values depend on the reference factor, at the level of rounding:
//! a caller that needs each result to be a function of its data alone (a run resumed from a
//! snapshot) uses `solve_predicted`.
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

mod active_set;
mod bound_set;
mod bound_set_border;
mod kkt;
mod matrix_checks;
mod monotone_multigrid;
mod projected_gauss_seidel;
mod reduced_solve;
mod settings;
mod solver;
mod workspace;

pub use crate::algebra::linalg::FactorKind;
pub use bound_set_border::{MAX_BORDER, MAX_FOLLOWED_ITERATIONS};
pub use kkt::box_qp_kkt_residual;
pub use settings::{BoxQpMethod, BoxQpSettings, BoxQpStats};
pub use solver::BoxQpSolver;
pub use workspace::BoundStatus;

#[cfg(test)]
mod tests;
