//! The dense pivoted Cholesky factor of the coarsest level, which reveals the rank of a
//! truncated (positive semidefinite) coarsest matrix and detects an indefinite one.

use crate::algebra::multigrid::csr::Csr;

/// Size below which a pivot of the dense coarsest factor counts as zero, relative to the
/// largest diagonal entry (the scale of the rounding errors of the factorization).
const PIVOT_DROP: f64 = 1e-12;
/// Size of a negative pivot of the dense coarsest factor, relative to the largest diagonal
/// entry, that proves the matrix indefinite (smaller negative pivots are rounding of a
/// semidefinite matrix, dropped).
const INDEFINITE_PIVOT: f64 = 1e-8;

/// Dense Cholesky factor `Πᵀ A Π = L Lᵀ` of a symmetric positive semidefinite matrix with
/// diagonal pivoting (at each step the largest remaining diagonal entry of the Schur
/// complement is the pivot), which reveals the rank: the factorization stops when every
/// remaining pivot vanishes up to rounding (at most [`PIVOT_DROP`] times the scale; in
/// particular the rows of unknowns truncated away), and the solve sets those unknowns to zero.
/// Without pivoting, a pivot that vanishes in exact arithmetic but not in floating point
/// (a coarse unknown almost all of whose fine support is truncated) was kept and its
/// rounding amplified into large negative pivots later on, i.e. a positive semidefinite
/// matrix reported indefinite.
#[derive(Debug, Clone)]
pub(super) struct DenseFactor {
    size: usize,
    /// The pivots in order: `order[k]` is the unknown eliminated at step k.
    order: Vec<usize>,
    /// Number of pivots kept (the numerical rank).
    pub(super) rank: usize,
    /// Row-major `L` in the pivoted order, its first `rank` columns.
    lower: Vec<f64>,
    /// A remaining pivot below `−INDEFINITE_PIVOT · scale` was met.
    pub(super) indefinite: bool,
}

impl DenseFactor {
    /// The factor of the matrix with rows `matrix` and diagonal `diagonal`; `scale` is the
    /// size of its entries before any truncation, against which rounding is measured.
    #[allow(clippy::needless_range_loop)] // dense triangular kernels
    pub(super) fn new(matrix: &Csr, diagonal: &[f64], scale: f64) -> Self {
        let n = matrix.rows();
        // The full symmetric matrix, permuted in place as the pivots are chosen.
        let mut work = vec![0.0; n * n];
        for i in 0..n {
            let (columns, values) = matrix.row(i);
            for (&j, &value) in columns.iter().zip(values) {
                work[i * n + j] = value;
            }
        }
        // Rounding in the Galerkin sums (which cancel: mass and stiffness couplings have
        // opposite signs) is relative to the largest entries of the untruncated matrix
        // (`scale`), not to a row's own diagonal nor to the truncated matrix, whose entries
        // may all be of the size of that rounding when most indices are fixed.
        let scale = diagonal.iter().fold(scale, |acc, d| acc.max(d.abs()));
        let mut order: Vec<usize> = (0..n).collect();
        let mut rank = n;
        for k in 0..n {
            let (pivot_row, pivot) = (k..n).map(|i| (i, work[i * n + i])).fold(
                (k, f64::NEG_INFINITY),
                |best, candidate| {
                    if candidate.1 > best.1 {
                        candidate
                    } else {
                        best
                    }
                },
            );
            if pivot.is_nan() || pivot <= PIVOT_DROP * scale {
                rank = k;
                break;
            }
            if pivot_row != k {
                order.swap(k, pivot_row);
                for column in 0..n {
                    work.swap(k * n + column, pivot_row * n + column);
                }
                for row in 0..n {
                    work.swap(row * n + k, row * n + pivot_row);
                }
            }
            let root = pivot.sqrt();
            work[k * n + k] = root;
            for i in k + 1..n {
                work[i * n + k] /= root;
            }
            // The Schur complement of the remaining rows (lower triangle and diagonal; the
            // upper triangle mirrors it for the pivot search and swaps).
            for i in k + 1..n {
                let factor = work[i * n + k];
                for j in k + 1..=i {
                    work[i * n + j] -= factor * work[j * n + k];
                }
                for j in k + 1..i {
                    work[j * n + i] = work[i * n + j];
                }
            }
        }
        let indefinite = (rank..n).any(|i| work[i * n + i] < -INDEFINITE_PIVOT * scale);
        Self {
            size: n,
            order,
            rank,
            lower: work,
            indefinite,
        }
    }

    /// `x = Π L⁻ᵀ L⁻¹ Πᵀ b` on the kept unknowns, zero on the dropped ones; `scratch` holds
    /// at least as many values as there are unknowns.
    #[allow(clippy::needless_range_loop)] // dense triangular kernels
    pub(super) fn solve(&self, rhs: &[f64], x: &mut [f64], scratch: &mut [f64]) {
        let (n, rank) = (self.size, self.rank);
        let y = &mut scratch[..rank];
        for k in 0..rank {
            let mut value = rhs[self.order[k]];
            for m in 0..k {
                value -= self.lower[k * n + m] * y[m];
            }
            y[k] = value / self.lower[k * n + k];
        }
        for k in (0..rank).rev() {
            let mut value = y[k];
            for m in k + 1..rank {
                value -= self.lower[m * n + k] * y[m];
            }
            y[k] = value / self.lower[k * n + k];
        }
        x.fill(0.0);
        for k in 0..rank {
            x[self.order[k]] = y[k];
        }
    }
}
