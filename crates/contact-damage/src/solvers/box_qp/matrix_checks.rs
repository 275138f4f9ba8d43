//! Checks and normalization of the matrix `A` of a box QP: canonical column storage, a
//! symmetric pattern and values, finite entries, a positive diagonal.

use faer::sparse::{SparseColMat, Triplet};

use crate::error::{Error, Result};

/// Returns the matrix with compact storage and strictly increasing row indices in every column
/// (rebuilding it, duplicates summed, only if necessary).
pub(super) fn canonical_storage(
    matrix: SparseColMat<usize, f64>,
) -> Result<SparseColMat<usize, f64>> {
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
pub(super) fn validate_symmetric_positive_diagonal(
    matrix: &SparseColMat<usize, f64>,
) -> Result<Vec<f64>> {
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
