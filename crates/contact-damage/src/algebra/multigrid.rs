//! Algebraic multigrid hierarchy by smoothed aggregation, with **truncation**: the linear
//! corrections of the monotone multigrid of [`crate::solvers::box_qp`] (the damage step (5.2)).
//!
//! # Construction (once per matrix)
//! From a sparse SPD matrix `A₀ = A` the hierarchy is built by smoothed aggregation
//! (Vaněk, Mandel & Brezina 1996), with the constants as near-kernel:
//! 1. **Strength of connection**: `j` is a strong neighbour of `i` if
//!    `|a_ij| ≥ θ √(a_ii a_jj)`, `θ = 0.08`. The absolute value matters: the consistent mass
//!    matrix in `M/k + κK` has positive off-diagonal entries.
//! 2. **Aggregation** (greedy, three passes): a node whose strong neighbours are all
//!    unaggregated starts an aggregate with them; the remaining nodes join the aggregate of
//!    their strongest aggregated neighbour; what is still left forms aggregates with its
//!    unaggregated strong neighbours.
//! 3. **Prolongation**: the tentative `P̂_{iJ} = 1` if `i` lies in aggregate `J`, smoothed by
//!    one damped Jacobi step `P = (I − ω D⁻¹A) P̂`, `ω = 4/(3ρ)` with the Gershgorin bound
//!    `ρ ≥ ρ(D⁻¹A)`.
//! 4. **Galerkin** coarse matrices `A_{l+1} = P_lᵀ A_l P_l`, until at most
//!    [`COARSEST_SIZE`](hierarchy::COARSEST_SIZE) unknowns remain; the coarsest level is
//!    solved by a dense Cholesky factor. If the coarsening stalls on a larger level (no
//!    strong connections left: the matrix is dominated by its diagonal), that level is the
//!    coarsest one and is solved approximately by symmetric Gauss–Seidel sweeps instead: as
//!    many as reduce the error by
//!    [`COARSEST_REDUCTION`](hierarchy::COARSEST_REDUCTION) by the diagonal dominance of the
//!    level (see [`coarsest_sweeps`](hierarchy::coarsest_sweeps)), at most
//!    [`COARSEST_SWEEPS`](hierarchy::COARSEST_SWEEPS).
//!
//! A truncated coarse matrix is only positive *semi*definite (two coarse functions may
//! coincide on the free set); the dense factor then drops the pivots that vanish up to
//! rounding, and the dropped directions get no coarse correction.
//!
//! The symbolic structure of every coarse matrix (its pattern) is computed once.
//!
//! # Truncation (once per active set)
//! The linear correction of the monotone multigrid solves `A_FF d_F = r_F` on the free set
//! `F` (the indices not on a bound) with `d = 0` on the rest. Following Kornhuber (1994) and
//! Gräser & Kornhuber (2009), the hierarchy is **truncated**: the fine-level rows of `P₀`
//! belonging to fixed indices are dropped (`P₀ᶠ = D_F P₀`), and the coarse matrices are
//! recomputed with the same patterns, `A₁ = P₀ᶠᵀ A P₀ᶠ = P₀ᵀ Ã₀ P₀` with
//! `Ã₀ = D_F A D_F` (the fixed rows and columns zeroed), `A_{l+1} = P_lᵀ A_l P_l` — so every
//! coarse correction is a Galerkin correction of the reduced operator `A_FF` and the V-cycle
//! is an SPD preconditioner for `A_FF` whatever `F`. A coarse unknown whose support lies in
//! the fixed set has a zero row: it is skipped by the smoothers and the coarse solve.
//! The products `Ã_l P_l` are kept: a truncation that changes the status of a few indices
//! recomputes only the rows of `Ã_l P_l` and `A_{l+1}` that contain them.
//!
//! # Cycle
//! A symmetric V(1,1)-cycle: forward Gauss–Seidel before the coarse correction, backward
//! after it, exact solve on the coarsest level; with a zero start it is a symmetric positive
//! definite operator on the free indices, used as the preconditioner of conjugate gradients.
//! The residuals and transfers of a level are computed row by row, in parallel tasks on a
//! pool of several threads ([`for_each_row`], bitwise the same result); the sweeps are
//! sequential.
//!
//! # References
//! - P. Vaněk, J. Mandel, M. Brezina, *Algebraic multigrid by smoothed aggregation for second
//!   and fourth order elliptic problems*, Computing 56 (1996) 179–196.
//! - R. Kornhuber, *Monotone multigrid methods for elliptic variational inequalities I*,
//!   Numer. Math. 69 (1994) 167–184.
//! - C. Gräser, R. Kornhuber, *Multigrid methods for obstacle problems*, J. Comput. Math. 27
//!   (2009) 1–44.

mod aggregation;
mod csr;
mod cycle;
mod dense_factor;
mod hierarchy;
mod parallel;

pub(crate) use aggregation::{aggregate, UNASSIGNED};
pub(crate) use csr::Csr;
pub(crate) use hierarchy::{inverse, Hierarchy};
pub(crate) use parallel::for_each_row;

#[cfg(test)]
pub(crate) mod tests;
