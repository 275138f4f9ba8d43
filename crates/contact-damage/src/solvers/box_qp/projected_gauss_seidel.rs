//! The nonlinear smoother of the monotone multigrid (step 1 of the [module
//! documentation](super), "Algorithm"): symmetric projected Gauss–Seidel sweeps that skip the
//! indices settled on a bound, and the gradient recomputed on the rows that saw a change.

use crate::algebra::multigrid::{for_each_row, Csr};
use crate::solvers::box_qp::kkt::{clamp, Problem};

/// The rows of `A` as the monotone multigrid's smoother reads them, built once per matrix.
#[derive(Debug, Clone)]
pub(super) struct FineRows {
    pub(super) rows: Csr,
    /// Per row, the number of columns below the diagonal ([`Csr::sweep_product`]).
    pub(super) lower_counts: Vec<usize>,
    /// `1/a_ii`: the smoother multiplies by it (a division would lengthen the sweep's
    /// dependency chain from row to row).
    pub(super) inverse_diagonal: Vec<f64>,
}

/// Mark of an index whose last projected Gauss–Seidel update left `x_i` on a bound, with no
/// `x_j` of its row changed since: its next update would leave it there again (up to the
/// order of the sum of its row), so the sweeps skip it. On a damage plateau (β = 1 where the
/// source pushes β up) that is most of the plateau, about half of the nodes in
/// `bench_step`'s problem.
pub(super) const SETTLED: u8 = 1;
/// Mark of an index whose row saw a change of `x` since its gradient entry was last computed
/// from the row: [`residual_gradient`] recomputes only these entries (the others would come
/// out with the same bits).
pub(super) const STALE: u8 = 2;

/// Marks the indices `row` (the columns of the row of a changed `x_i`, `i` among them) stale
/// and not settled.
#[inline]
pub(super) fn mark_stale(row: &[usize], marks: &mut [u8]) {
    for &j in row {
        marks[j] = STALE;
    }
}

/// One projected Gauss–Seidel sweep (forward or backward): every `x_i` in turn is replaced by
/// the exact minimizer of `q` over `[lower_i, upper_i]` with the other values fixed,
/// `clamp(x_i − g_i / a_ii)`. Never increases `q`. Indices marked [`SETTLED`] are skipped;
/// an index left on a bound is marked settled, and a change of `x_i` marks its row
/// [`STALE`] and not settled.
pub(super) fn projected_gauss_seidel(
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

/// `g = A x − b` from the rows of `A`, on the rows marked [`STALE`] (the marks are cleared);
/// the other entries of `g` are up to date.
pub(super) fn residual_gradient(
    rows: &Csr,
    x: &[f64],
    rhs: &[f64],
    gradient: &mut [f64],
    marks: &mut [u8],
) {
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
