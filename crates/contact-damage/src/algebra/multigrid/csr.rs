//! Compressed sparse rows: products with vectors (row by row, in the order of a Gauss–Seidel
//! sweep, on selected rows), the transpose, the diagonal, and the sparse products `X Y` of the
//! Galerkin coarse matrices (pattern once, values of selected rows).

use faer::sparse::SparseColMat;

use crate::algebra::multigrid::parallel::for_each_row;

/// Compressed sparse rows (for a symmetric matrix: also its compressed columns).
#[derive(Debug, Clone)]
pub(crate) struct Csr {
    pub(super) cols: usize,
    pub(super) offsets: Vec<usize>,
    pub(super) indices: Vec<usize>,
    pub(super) values: Vec<f64>,
}

impl Csr {
    /// The rows of a symmetric matrix stored by columns with both triangles.
    pub(crate) fn from_symmetric(matrix: &SparseColMat<usize, f64>) -> Self {
        let symbolic = matrix.symbolic();
        let n = matrix.ncols();
        let mut offsets = Vec::with_capacity(n + 1);
        let mut indices = Vec::with_capacity(symbolic.compute_nnz());
        let mut values = Vec::with_capacity(symbolic.compute_nnz());
        offsets.push(0);
        for column in 0..n {
            indices.extend_from_slice(symbolic.row_idx_of_col_raw(column));
            values.extend_from_slice(matrix.val_of_col(column));
            offsets.push(indices.len());
        }
        Self {
            cols: matrix.nrows(),
            offsets,
            indices,
            values,
        }
    }

    pub(crate) fn rows(&self) -> usize {
        self.offsets.len() - 1
    }

    pub(crate) fn row(&self, i: usize) -> (&[usize], &[f64]) {
        let range = self.offsets[i]..self.offsets[i + 1];
        (&self.indices[range.clone()], &self.values[range])
    }

    /// `(A x)_i`.
    pub(crate) fn row_product(&self, i: usize, x: &[f64]) -> f64 {
        let (columns, values) = self.row(i);
        columns.iter().zip(values).map(|(&j, a)| a * x[j]).sum()
    }

    /// For every row, the number of its columns below the diagonal (the split of
    /// [`Csr::sweep_product`]).
    pub(crate) fn lower_counts(&self) -> Vec<usize> {
        (0..self.rows())
            .map(|i| self.row(i).0.partition_point(|&j| j < i))
            .collect()
    }

    /// `(A x)_i` summed in the order of a Gauss–Seidel sweep's dependencies: first the terms
    /// whose `x_j` the sweep has not changed yet (in a forward sweep the diagonal and the
    /// columns after `i`), then the changed ones, the most recent (the column nearest to `i`)
    /// last. The dependency chain from one row's update to the next row's then runs through
    /// one product and one sum instead of the whole row. `lower` is the row's count of
    /// [`Csr::lower_counts`].
    pub(crate) fn sweep_product(&self, i: usize, x: &[f64], lower: usize, backward: bool) -> f64 {
        let (columns, values) = self.row(i);
        let mut sum = 0.0;
        if backward {
            let split = if columns.get(lower) == Some(&i) {
                lower + 1
            } else {
                lower
            };
            for (&j, a) in columns[..split].iter().zip(&values[..split]) {
                sum += a * x[j];
            }
            for (&j, a) in columns[split..].iter().zip(&values[split..]).rev() {
                sum += a * x[j];
            }
        } else {
            for (&j, a) in columns[lower..].iter().zip(&values[lower..]) {
                sum += a * x[j];
            }
            for (&j, a) in columns[..lower].iter().zip(&values[..lower]) {
                sum += a * x[j];
            }
        }
        sum
    }

    /// `y = A x`.
    pub(crate) fn multiply(&self, x: &[f64], y: &mut [f64]) {
        for_each_row(y, |i, target| {
            let (columns, values) = self.row(i);
            *target = columns.iter().zip(values).map(|(&j, a)| a * x[j]).sum();
        });
    }

    /// `y_i = (A x)_i` on the rows with `keep(i)`, `y_i = 0` on the others (whose rows are
    /// not read).
    pub(crate) fn multiply_rows(
        &self,
        x: &[f64],
        y: &mut [f64],
        keep: impl Fn(usize) -> bool + Sync,
    ) {
        for_each_row(y, |i, target| {
            *target = if keep(i) { self.row_product(i, x) } else { 0.0 };
        });
    }

    /// The transpose.
    pub(super) fn transpose(&self) -> Self {
        let mut counts = vec![0usize; self.cols + 1];
        for &j in &self.indices {
            counts[j + 1] += 1;
        }
        for j in 0..self.cols {
            counts[j + 1] += counts[j];
        }
        let offsets = counts.clone();
        let mut next = counts;
        let mut indices = vec![0; self.indices.len()];
        let mut values = vec![0.0; self.values.len()];
        for i in 0..self.rows() {
            let (columns, entries) = self.row(i);
            for (&j, &value) in columns.iter().zip(entries) {
                indices[next[j]] = i;
                values[next[j]] = value;
                next[j] += 1;
            }
        }
        Self {
            cols: self.rows(),
            offsets,
            indices,
            values,
        }
    }

    /// Diagonal entries (zero where the pattern has none).
    pub(crate) fn diagonal(&self) -> Vec<f64> {
        (0..self.rows()).map(|i| self.diagonal_entry(i)).collect()
    }

    /// `a_ii` (zero if the pattern has no diagonal entry in row `i`; columns sorted).
    pub(super) fn diagonal_entry(&self, i: usize) -> f64 {
        let (columns, values) = self.row(i);
        columns
            .binary_search(&i)
            .map_or(0.0, |position| values[position])
    }
}

/// The pattern of the sparse product `X Y` (values zero; column indices sorted in every row).
pub(super) fn product_pattern(left: &Csr, right: &Csr) -> Csr {
    let mut seen = vec![usize::MAX; right.cols];
    let mut offsets = vec![0];
    let mut indices = Vec::new();
    for row in 0..left.rows() {
        let start = indices.len();
        for &k in left.row(row).0 {
            for &column in right.row(k).0 {
                if seen[column] != row {
                    seen[column] = row;
                    indices.push(column);
                }
            }
        }
        indices[start..].sort_unstable();
        offsets.push(indices.len());
    }
    let values = vec![0.0; indices.len()];
    Csr {
        cols: right.cols,
        offsets,
        indices,
        values,
    }
}

/// Values of the rows `rows` of the product `X Y` into the pattern of `product` (computed by
/// [`product_pattern`]). `marker` has at least as many entries as `Y` has columns and holds
/// `usize::MAX` on entry and on exit.
pub(super) fn product_rows(
    left: &Csr,
    right: &Csr,
    product: &mut Csr,
    marker: &mut [usize],
    rows: &[usize],
) {
    for &row in rows {
        let range = product.offsets[row]..product.offsets[row + 1];
        for position in range.clone() {
            marker[product.indices[position]] = position;
            product.values[position] = 0.0;
        }
        let (middle, weights) = left.row(row);
        for (&k, &weight) in middle.iter().zip(weights) {
            if weight == 0.0 {
                continue;
            }
            let (columns, values) = right.row(k);
            for (&column, &value) in columns.iter().zip(values) {
                product.values[marker[column]] += weight * value;
            }
        }
        for position in range {
            marker[product.indices[position]] = usize::MAX;
        }
    }
}
