//! Sparse linear algebra under the two steps of the scheme: assembly patterns and the sparse
//! Cholesky solver (symbolic analysis once, numeric factorizations many times), triangular
//! solves on its supernodal factor, fill-reducing orderings, the one preconditioned conjugate gradient solver, the algebraic multigrid hierarchy of
//! the damage step, and the memory estimate of a run.

pub mod linalg;
pub mod memory;
pub(crate) mod multigrid;
pub mod ordering;
pub mod pcg;
pub(crate) mod triangular;
