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
//!    [`COARSEST_SIZE`] unknowns remain; the coarsest level is solved by a dense Cholesky
//!    factor. If the coarsening stalls on a larger level (no strong connections left: the
//!    matrix is dominated by its diagonal), that level is the coarsest one and is solved
//!    approximately by symmetric Gauss–Seidel sweeps instead: as many as reduce the error by
//!    [`COARSEST_REDUCTION`] by the diagonal dominance of the level (see [`coarsest_sweeps`]),
//!    at most [`COARSEST_SWEEPS`].
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

use faer::sparse::SparseColMat;
use rayon::prelude::*;

/// Rows per task of the row-parallel passes ([`for_each_row`]).
const PARALLEL_ROWS: usize = 8192;

/// `value(i, &mut y[i])` for every row `i`: in tasks of [`PARALLEL_ROWS`] rows when the
/// thread pool has more than one thread and `y` has at least two tasks' worth of rows, on
/// the calling thread otherwise. Every entry is computed by the same expression either way,
/// so the result is bitwise the same on any number of threads.
pub(crate) fn for_each_row<T: Send>(y: &mut [T], value: impl Fn(usize, &mut T) + Sync) {
    if y.len() >= 2 * PARALLEL_ROWS && rayon::current_num_threads() > 1 {
        y.par_chunks_mut(PARALLEL_ROWS)
            .enumerate()
            .for_each(|(chunk, entries)| {
                let first = chunk * PARALLEL_ROWS;
                for (k, entry) in entries.iter_mut().enumerate() {
                    value(first + k, entry);
                }
            });
    } else {
        for (i, entry) in y.iter_mut().enumerate() {
            value(i, entry);
        }
    }
}

/// Largest number of unknowns solved directly on the coarsest level.
pub(crate) const COARSEST_SIZE: usize = 64;
/// Most symmetric Gauss–Seidel sweeps on a coarsest level too large for the dense factor
/// (the count for a level that is not strictly diagonally dominant, [`coarsest_sweeps`]).
pub(crate) const COARSEST_SWEEPS: usize = 4;
/// Error reduction (maximum norm) asked of the sweeps on a coarsest level without a dense
/// factor: a V-cycle preconditioner needs an approximate coarse solve only.
const COARSEST_REDUCTION: f64 = 0.1;
/// Size below which a pivot of the dense coarsest factor counts as zero, relative to the
/// largest diagonal entry (the scale of the rounding errors of the factorization).
const PIVOT_DROP: f64 = 1e-12;
/// Size of a negative pivot of the dense coarsest factor, relative to the largest diagonal
/// entry, that proves the matrix indefinite (smaller negative pivots are rounding of a
/// semidefinite matrix, dropped).
const INDEFINITE_PIVOT: f64 = 1e-8;
/// Strength-of-connection threshold θ.
const STRENGTH: f64 = 0.08;
/// Coarsening stops when a level keeps more than this fraction of the unknowns.
const STALLED_COARSENING: f64 = 0.8;
/// Most levels built.
const MAX_LEVELS: usize = 25;
/// Marker of an unaggregated node.
pub(crate) const UNASSIGNED: usize = usize::MAX;

/// Compressed sparse rows (for a symmetric matrix: also its compressed columns).
#[derive(Debug, Clone)]
pub(crate) struct Csr {
    cols: usize,
    offsets: Vec<usize>,
    indices: Vec<usize>,
    values: Vec<f64>,
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
    fn transpose(&self) -> Self {
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
    fn diagonal_entry(&self, i: usize) -> f64 {
        let (columns, values) = self.row(i);
        columns
            .binary_search(&i)
            .map_or(0.0, |position| values[position])
    }
}

/// One level: its (truncated) matrix, the prolongation from the next coarser level and the
/// product of the two.
#[derive(Debug, Clone)]
struct Level {
    /// `Ã_l`: on the finest level `A` with the rows and columns of the fixed indices zeroed,
    /// on the coarser ones the Galerkin matrix `R_{l−1} Ã_{l−1} P_{l−1}`.
    matrix: Csr,
    diagonal: Vec<f64>,
    /// `1/a_ii` on the rows kept by the truncation (the smoother multiplies by it: a division
    /// would lengthen the sweep's dependency chain from row to row).
    inverse_diagonal: Vec<f64>,
    /// The counts of [`Csr::lower_counts`] (the pattern is fixed, truncation zeroes values).
    lower_counts: Vec<usize>,
    /// `P_l` (rows: this level, columns: the next coarser one), its transpose `R_l = P_lᵀ`
    /// and the product `Ã_l P_l`.
    transfer: Option<Transfer>,
    /// Marks of the rows changed by a truncation (all `false` between truncations).
    touched: Vec<bool>,
    /// Work vectors of the cycle.
    solution: Vec<f64>,
    rhs: Vec<f64>,
    residual: Vec<f64>,
}

impl Level {
    /// One Gauss–Seidel sweep on `solution` for this level's `rhs` (forward or backward).
    fn sweep(&mut self, backward: bool) {
        gauss_seidel(self, backward);
    }
}

/// Grid transfer of a level to the next coarser one.
#[derive(Debug, Clone)]
struct Transfer {
    prolongation: Csr,
    restriction: Csr,
    /// `Ã_l P_l`, kept so that a truncation recomputes only the rows it changes.
    product: Csr,
}

/// The truncated smoothed-aggregation hierarchy of a sparse SPD matrix.
#[derive(Debug, Clone)]
pub(crate) struct Hierarchy {
    levels: Vec<Level>,
    /// The untruncated fine matrix `A` and its diagonal.
    fine: Csr,
    fine_diagonal: Vec<f64>,
    /// Fixed fine indices of the current truncation.
    fixed: Vec<bool>,
    /// Largest size of the dense coarsest factor.
    coarsest_size: usize,
    /// Dense factor of the coarsest matrix, if it has at most `coarsest_size` unknowns.
    coarsest_factor: Option<DenseFactor>,
    /// Symmetric Gauss–Seidel sweeps on the coarsest level when it has no dense factor
    /// ([`coarsest_sweeps`] of its untruncated matrix).
    coarsest_sweeps: usize,
    /// The largest diagonal entry of the untruncated coarsest matrix: the scale of the
    /// rounding errors of its Galerkin sums, truncated or not.
    coarsest_scale: f64,
    /// Scratch of the sparse products: position of a column in the current row.
    marker: Vec<usize>,
}

impl Hierarchy {
    /// Builds the hierarchy of `matrix` (symmetric, both triangles stored, positive diagonal),
    /// untruncated.
    pub(crate) fn new(matrix: &Csr) -> Self {
        Self::with_coarsest_size(matrix, COARSEST_SIZE)
    }

    /// As [`Hierarchy::new`], coarsening down to at most `coarsest_size` unknowns (tests use
    /// small sizes to reach several levels on small matrices).
    pub(crate) fn with_coarsest_size(matrix: &Csr, coarsest_size: usize) -> Self {
        let mut levels = Vec::new();
        let mut current = matrix.clone();
        let mut marker = Vec::new();
        loop {
            let diagonal = current.diagonal();
            let n = current.rows();
            let done = n <= coarsest_size || levels.len() + 1 >= MAX_LEVELS;
            let aggregates =
                (!done)
                    .then(|| aggregate(&current, &diagonal))
                    .filter(|&(_, coarse)| {
                        coarse > 0 && coarse as f64 <= STALLED_COARSENING * n as f64
                    });
            let mut next = None;
            let transfer = aggregates.map(|(aggregates, coarse)| {
                let (prolongation, restriction) =
                    smoothed_prolongation(&current, &diagonal, &aggregates, coarse);
                marker.resize(marker.len().max(coarse), usize::MAX);
                let all: Vec<usize> = (0..n).collect();
                let mut product = product_pattern(&current, &prolongation);
                product_rows(&current, &prolongation, &mut product, &mut marker, &all);
                let mut galerkin = product_pattern(&restriction, &product);
                let all: Vec<usize> = (0..coarse).collect();
                product_rows(&restriction, &product, &mut galerkin, &mut marker, &all);
                next = Some(galerkin);
                Transfer {
                    prolongation,
                    restriction,
                    product,
                }
            });
            levels.push(Level {
                inverse_diagonal: diagonal.iter().map(|&d| inverse(d)).collect(),
                lower_counts: current.lower_counts(),
                touched: vec![false; n],
                solution: vec![0.0; n],
                rhs: vec![0.0; n],
                residual: vec![0.0; n],
                diagonal,
                matrix: current,
                transfer,
            });
            match next {
                Some(coarse) => current = coarse,
                None => break,
            }
        }
        let mut hierarchy = Self {
            coarsest_size,
            fine: matrix.clone(),
            fine_diagonal: matrix.diagonal(),
            fixed: vec![false; matrix.rows()],
            levels,
            coarsest_factor: None,
            coarsest_sweeps: COARSEST_SWEEPS,
            coarsest_scale: 0.0,
            marker,
        };
        hierarchy.coarsest_scale = hierarchy
            .levels
            .last()
            .expect("at least one level")
            .diagonal
            .iter()
            .fold(0.0_f64, |acc, d| acc.max(d.abs()));
        hierarchy.factor_coarsest();
        let coarsest = hierarchy.levels.last().expect("at least one level");
        hierarchy.coarsest_sweeps = coarsest_sweeps(&coarsest.matrix, &coarsest.diagonal);
        hierarchy
    }

    /// Unknowns per level, finest first.
    pub(crate) fn sizes(&self) -> Vec<usize> {
        self.levels
            .iter()
            .map(|level| level.matrix.rows())
            .collect()
    }

    /// Truncates the hierarchy to the free set `{i : !fixed[i]}` (see the module
    /// documentation); a no-op if `fixed` is the current truncation. Only the rows that the
    /// change of truncation affects are recomputed, each from scratch, so the result does not
    /// depend on earlier truncations. Returns whether anything changed.
    pub(crate) fn truncate(&mut self, fixed: &[bool]) -> bool {
        // Fine level: the rows of Ã₀ that change are those of the indices whose status
        // changes and of their neighbours.
        let mut rows = Vec::new();
        {
            let level = &mut self.levels[0];
            for (c, (now, before)) in fixed.iter().zip(&self.fixed).enumerate() {
                if now == before {
                    continue;
                }
                for &i in std::iter::once(&c).chain(self.fine.row(c).0) {
                    if !level.touched[i] {
                        level.touched[i] = true;
                        rows.push(i);
                    }
                }
            }
            if rows.is_empty() {
                return false;
            }
            self.fixed.copy_from_slice(fixed);
            for &i in &rows {
                level.touched[i] = false;
                for position in level.matrix.offsets[i]..level.matrix.offsets[i + 1] {
                    let j = level.matrix.indices[position];
                    level.matrix.values[position] = if fixed[i] || fixed[j] {
                        0.0
                    } else {
                        self.fine.values[position]
                    };
                }
                level.diagonal[i] = if fixed[i] { 0.0 } else { self.fine_diagonal[i] };
                level.inverse_diagonal[i] = inverse(level.diagonal[i]);
            }
        }
        // Level by level: the changed rows of Ã_l change the same rows of Ã_l P_l, and these
        // the rows I of R_l Ã_l P_l with R_{Ii} ≠ 0.
        for l in 0..self.levels.len() - 1 {
            let (fine_levels, coarse_levels) = self.levels.split_at_mut(l + 1);
            let level = &mut fine_levels[l];
            let coarse = &mut coarse_levels[0];
            let transfer = level.transfer.as_mut().expect("a finer level has P");
            product_rows(
                &level.matrix,
                &transfer.prolongation,
                &mut transfer.product,
                &mut self.marker,
                &rows,
            );
            let mut coarse_rows = Vec::new();
            for &i in &rows {
                for &row in transfer.prolongation.row(i).0 {
                    if !coarse.touched[row] {
                        coarse.touched[row] = true;
                        coarse_rows.push(row);
                    }
                }
            }
            product_rows(
                &transfer.restriction,
                &transfer.product,
                &mut coarse.matrix,
                &mut self.marker,
                &coarse_rows,
            );
            for &row in &coarse_rows {
                coarse.touched[row] = false;
                coarse.diagonal[row] = coarse.matrix.diagonal_entry(row);
                coarse.inverse_diagonal[row] = inverse(coarse.diagonal[row]);
            }
            rows = coarse_rows;
        }
        if !rows.is_empty() {
            self.factor_coarsest();
        }
        true
    }

    /// Dense factor of the coarsest matrix (if it is small enough).
    fn factor_coarsest(&mut self) {
        let level = self.levels.last().expect("at least one level");
        self.coarsest_factor = (level.matrix.rows() <= self.coarsest_size)
            .then(|| DenseFactor::new(&level.matrix, &level.diagonal, self.coarsest_scale));
    }

    /// Whether the coarsest dense factor met a clearly negative pivot: the matrix is not
    /// positive semidefinite on the free set, so `A` is not positive definite.
    pub(crate) fn is_indefinite(&self) -> bool {
        self.coarsest_factor
            .as_ref()
            .is_some_and(|factor| factor.indefinite)
    }

    /// `z = B r`: one symmetric V-cycle for the truncated fine matrix from a zero start; `r`
    /// must vanish on the fixed indices, and so does `z`.
    pub(crate) fn cycle(&mut self, residual: &[f64], z: &mut [f64]) {
        self.levels[0].rhs.copy_from_slice(residual);
        self.cycle_level(0);
        z.copy_from_slice(&self.levels[0].solution);
    }

    fn cycle_level(&mut self, l: usize) {
        let last = self.levels.len() - 1;
        if l == last {
            let level = &mut self.levels[l];
            match &self.coarsest_factor {
                Some(factor) => factor.solve(&level.rhs, &mut level.solution, &mut level.residual),
                None => {
                    level.solution.fill(0.0);
                    for _ in 0..self.coarsest_sweeps {
                        level.sweep(false);
                        level.sweep(true);
                    }
                }
            }
            return;
        }
        {
            let level = &mut self.levels[l];
            level.solution.fill(0.0);
            level.sweep(false);
            // r = b − Ã_l z on the rows kept by the truncation (the others are zero rows).
            let (diagonal, rhs, matrix, solution) =
                (&level.diagonal, &level.rhs, &level.matrix, &level.solution);
            for_each_row(&mut level.residual, |i, residual| {
                *residual = if diagonal[i] > 0.0 {
                    rhs[i] - matrix.row_product(i, solution)
                } else {
                    0.0
                };
            });
        }
        {
            let (fine_levels, coarse_levels) = self.levels.split_at_mut(l + 1);
            let level = &fine_levels[l];
            let transfer = level.transfer.as_ref().expect("not the coarsest");
            transfer
                .restriction
                .multiply(&level.residual, &mut coarse_levels[0].rhs);
        }
        self.cycle_level(l + 1);
        {
            let (fine_levels, coarse_levels) = self.levels.split_at_mut(l + 1);
            let level = &mut fine_levels[l];
            let coarse = &coarse_levels[0];
            let prolongation = &level
                .transfer
                .as_ref()
                .expect("not the coarsest")
                .prolongation;
            let diagonal = &level.diagonal;
            for_each_row(&mut level.solution, |i, solution| {
                if diagonal[i] > 0.0 {
                    let (columns, values) = prolongation.row(i);
                    *solution += columns
                        .iter()
                        .zip(values)
                        .map(|(&j, p)| p * coarse.solution[j])
                        .sum::<f64>();
                }
            });
            level.sweep(true);
        }
    }
}

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
struct DenseFactor {
    size: usize,
    /// The pivots in order: `order[k]` is the unknown eliminated at step k.
    order: Vec<usize>,
    /// Number of pivots kept (the numerical rank).
    rank: usize,
    /// Row-major `L` in the pivoted order, its first `rank` columns.
    lower: Vec<f64>,
    /// A remaining pivot below `−INDEFINITE_PIVOT · scale` was met.
    indefinite: bool,
}

impl DenseFactor {
    /// The factor of the matrix with rows `matrix` and diagonal `diagonal`; `scale` is the
    /// size of its entries before any truncation, against which rounding is measured.
    #[allow(clippy::needless_range_loop)] // dense triangular kernels
    fn new(matrix: &Csr, diagonal: &[f64], scale: f64) -> Self {
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
    fn solve(&self, rhs: &[f64], x: &mut [f64], scratch: &mut [f64]) {
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

/// One Gauss–Seidel sweep of `level` for `Ã z = r` (forward or backward) on the rows with a
/// positive diagonal (the others are truncated away and stay zero).
fn gauss_seidel(level: &mut Level, backward: bool) {
    let n = level.solution.len();
    for step in 0..n {
        let i = if backward { n - 1 - step } else { step };
        if level.diagonal[i] <= 0.0 {
            continue;
        }
        let product =
            level
                .matrix
                .sweep_product(i, &level.solution, level.lower_counts[i], backward);
        level.solution[i] += (level.rhs[i] - product) * level.inverse_diagonal[i];
    }
}

/// The number of symmetric Gauss–Seidel sweeps (from a zero start) that reduce the error of
/// a system with the rows `matrix` by [`COARSEST_REDUCTION`] in the maximum norm, at most
/// [`COARSEST_SWEEPS`]; only the rows with a positive diagonal take part.
///
/// With the diagonal dominance `ρ = max_i (l_i + u_i)`, `l_i = Σ_{j<i} |a_ij| / a_ii` and
/// `u_i = Σ_{j>i} |a_ij| / a_ii`, a forward sweep maps an error `e` to `y` with
/// `|y_i| ≤ l_i ‖y‖_∞ + u_i ‖e‖_∞`, so at the row of the largest `|y_i|`,
/// `‖y‖_∞ ≤ u_i / (1 − l_i) ‖e‖_∞ ≤ ρ ‖e‖_∞` when `ρ < 1` (strict diagonal dominance); the
/// same holds backward, so `s` symmetric sweeps reduce the error by `ρ^{2s}`. Without strict
/// dominance the bound says nothing and the level gets [`COARSEST_SWEEPS`].
///
/// The hierarchy takes the count of the *untruncated* coarsest level, on which the coarsening
/// stalled because it has no strong connections: at 128² in `bench_step`'s damage problem
/// (κ = 0.01, k = 1/128) its 2827 rows have `ρ = 0.23`, so one sweep (`ρ² = 0.05`). The
/// truncation leaves a few rows with most of their support fixed and a small diagonal, whose
/// ratio exceeds 1 (up to 69 there): for the truncated matrix the count is a heuristic, not a
/// bound. It only decides how good the preconditioner of the linear corrections is, not what
/// the iteration converges to (the KKT residual is checked as always). Measured on the steps
/// 25–32 of that problem, solved 30 times in one process alternating the counts: 26 / 25
/// multigrid / CG iterations with four sweeps, 27 / 24 with one, (5.2) about 7 % faster.
fn coarsest_sweeps(matrix: &Csr, diagonal: &[f64]) -> usize {
    let mut dominance = 0.0_f64;
    for (i, &a) in diagonal.iter().enumerate() {
        if a > 0.0 {
            let (columns, values) = matrix.row(i);
            let off_diagonal: f64 = columns
                .iter()
                .zip(values)
                .filter(|(&j, _)| j != i)
                .map(|(_, v)| v.abs())
                .sum();
            dominance = dominance.max(off_diagonal / a);
        }
    }
    if dominance >= 1.0 {
        return COARSEST_SWEEPS;
    }
    // ρ = 0 (a diagonal level) gives 0 here, and one sweep solves it exactly
    let sweeps = (COARSEST_REDUCTION.ln() / (2.0 * dominance.ln())).ceil();
    (sweeps as usize).clamp(1, COARSEST_SWEEPS)
}

/// `1/d` for `d > 0`, else 0 (a truncated row).
pub(crate) fn inverse(d: f64) -> f64 {
    if d > 0.0 {
        1.0 / d
    } else {
        0.0
    }
}

/// Greedy aggregation on the strong connections; returns the aggregate of every node
/// ([`UNASSIGNED`] for the nodes without strong neighbours) and the number of aggregates.
pub(crate) fn aggregate(matrix: &Csr, diagonal: &[f64]) -> (Vec<usize>, usize) {
    let n = matrix.rows();
    let strong = |i: usize, j: usize, a: f64| {
        i != j && a.abs() >= STRENGTH * (diagonal[i] * diagonal[j]).abs().sqrt()
    };
    let mut aggregates = vec![UNASSIGNED; n];
    let mut count = 0;
    // Pass 1: roots whose strong neighbourhood is untouched.
    for i in 0..n {
        if aggregates[i] != UNASSIGNED {
            continue;
        }
        let (columns, values) = matrix.row(i);
        let mut has_strong = false;
        let mut untouched = true;
        for (&j, &a) in columns.iter().zip(values) {
            if strong(i, j, a) {
                has_strong = true;
                untouched &= aggregates[j] == UNASSIGNED;
            }
        }
        if has_strong && untouched {
            aggregates[i] = count;
            for (&j, &a) in columns.iter().zip(values) {
                if strong(i, j, a) {
                    aggregates[j] = count;
                }
            }
            count += 1;
        }
    }
    // Pass 2: join the aggregate of the strongest aggregated neighbour (of pass 1).
    let first_pass = aggregates.clone();
    for i in 0..n {
        if first_pass[i] != UNASSIGNED {
            continue;
        }
        let (columns, values) = matrix.row(i);
        let mut best: Option<(f64, usize)> = None;
        for (&j, &a) in columns.iter().zip(values) {
            if strong(i, j, a) && first_pass[j] != UNASSIGNED {
                let weight = a.abs() / (diagonal[i] * diagonal[j]).abs().sqrt();
                if best.is_none_or(|(strongest, _)| weight > strongest) {
                    best = Some((weight, first_pass[j]));
                }
            }
        }
        if let Some((_, aggregate)) = best {
            aggregates[i] = aggregate;
        }
    }
    // Pass 3: what is left forms aggregates with its unaggregated strong neighbours; a node
    // without strong neighbours stays unaggregated (its row is dominated by the diagonal, and
    // the smoother alone reduces its error).
    for i in 0..n {
        if aggregates[i] != UNASSIGNED {
            continue;
        }
        let (columns, values) = matrix.row(i);
        if !columns.iter().zip(values).any(|(&j, &a)| strong(i, j, a)) {
            continue;
        }
        aggregates[i] = count;
        for (&j, &a) in columns.iter().zip(values) {
            if strong(i, j, a) && aggregates[j] == UNASSIGNED {
                aggregates[j] = count;
            }
        }
        count += 1;
    }
    (aggregates, count)
}

/// `P = (I − ω D⁻¹A) P̂` with the tentative (piecewise constant) `P̂`; returns `(P, Pᵀ)`.
fn smoothed_prolongation(
    matrix: &Csr,
    diagonal: &[f64],
    aggregates: &[usize],
    coarse: usize,
) -> (Csr, Csr) {
    let n = matrix.rows();
    let spectral_bound = (0..n)
        .map(|i| {
            let (_, values) = matrix.row(i);
            values.iter().map(|a| a.abs()).sum::<f64>() / diagonal[i]
        })
        .fold(0.0_f64, f64::max);
    let omega = 4.0 / (3.0 * spectral_bound);
    let mut offsets = vec![0];
    let mut indices = Vec::new();
    let mut values = Vec::new();
    let mut row: Vec<(usize, f64)> = Vec::new();
    for i in 0..n {
        row.clear();
        if aggregates[i] != UNASSIGNED {
            row.push((aggregates[i], 1.0));
        }
        let (columns, entries) = matrix.row(i);
        for (&j, &a) in columns.iter().zip(entries) {
            if aggregates[j] != UNASSIGNED {
                row.push((aggregates[j], -omega * a / diagonal[i]));
            }
        }
        row.sort_unstable_by_key(|&(column, _)| column);
        let start = indices.len();
        for &(column, value) in &row {
            if indices.len() > start && indices[indices.len() - 1] == column {
                *values.last_mut().expect("same length") += value;
            } else {
                indices.push(column);
                values.push(value);
            }
        }
        offsets.push(indices.len());
    }
    let prolongation = Csr {
        cols: coarse,
        offsets,
        indices,
        values,
    };
    let restriction = prolongation.transpose();
    (prolongation, restriction)
}

/// The pattern of the sparse product `X Y` (values zero; column indices sorted in every row).
fn product_pattern(left: &Csr, right: &Csr) -> Csr {
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
fn product_rows(left: &Csr, right: &Csr, product: &mut Csr, marker: &mut [usize], rows: &[usize]) {
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

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::algebra::linalg::max_abs;
    use faer::sparse::Triplet;

    /// 5-point Laplacian plus a small mass shift on an m×m grid.
    pub(crate) fn laplacian(m: usize, shift: f64) -> SparseColMat<usize, f64> {
        let index = |i: usize, j: usize| i * m + j;
        let mut triplets = Vec::new();
        for i in 0..m {
            for j in 0..m {
                triplets.push(Triplet::new(index(i, j), index(i, j), 4.0 + shift));
                if i + 1 < m {
                    triplets.push(Triplet::new(index(i, j), index(i + 1, j), -1.0));
                    triplets.push(Triplet::new(index(i + 1, j), index(i, j), -1.0));
                }
                if j + 1 < m {
                    triplets.push(Triplet::new(index(i, j), index(i, j + 1), -1.0));
                    triplets.push(Triplet::new(index(i, j + 1), index(i, j), -1.0));
                }
            }
        }
        SparseColMat::try_new_from_triplets(m * m, m * m, &triplets).unwrap()
    }

    /// Energy-norm contraction of the V-cycle iteration `x ← x + B(b − A x)` on `A_FF`.
    fn contraction(hierarchy: &mut Hierarchy, matrix: &Csr, fixed: &[bool]) -> f64 {
        let n = fixed.len();
        let _ = hierarchy.truncate(fixed);
        // Error iteration on a rough start, b = 0: e ← e − B A_FF e.
        let mut error: Vec<f64> = (0..n)
            .map(|i| {
                if fixed[i] {
                    0.0
                } else {
                    ((i * 7919) % 13) as f64 - 6.0
                }
            })
            .collect();
        let energy = |e: &[f64]| {
            let mut image = vec![0.0; n];
            matrix.multiply(e, &mut image);
            e.iter().zip(&image).map(|(a, b)| a * b).sum::<f64>().sqrt()
        };
        let mut image = vec![0.0; n];
        let mut correction = vec![0.0; n];
        let mut rate = 0.0;
        for _ in 0..8 {
            let before = energy(&error);
            matrix.multiply(&error, &mut image);
            for i in 0..n {
                if fixed[i] {
                    image[i] = 0.0;
                }
            }
            hierarchy.cycle(&image, &mut correction);
            for i in 0..n {
                error[i] -= correction[i];
                assert!(!fixed[i] || correction[i] == 0.0);
            }
            rate = energy(&error) / before;
        }
        rate
    }

    /// Measured energy contraction of the V(1,1)-cycle on these grids: 0.34–0.37 for m = 32
    /// to 512, untruncated and truncated alike; the bound leaves room for rounding and
    /// ordering effects but fails if the rate grows with the grid.
    const CONTRACTION_BOUND: f64 = 0.45;

    #[test]
    fn v_cycle_contracts_independently_of_the_grid() {
        for m in [32, 64, 128, 256] {
            let matrix = laplacian(m, 1e-3);
            let csr = Csr::from_symmetric(&matrix);
            let mut hierarchy = Hierarchy::new(&csr);
            assert!(
                hierarchy.sizes().len() >= 2,
                "sizes {:?}",
                hierarchy.sizes()
            );
            let rate = contraction(&mut hierarchy, &csr, &vec![false; m * m]);
            assert!(
                rate < CONTRACTION_BOUND,
                "m = {m}: V-cycle contraction {rate}"
            );
        }
    }

    /// A banded matrix with unit diagonal and `-coupling` on the `band` neighbours on each
    /// side: every coupling below the strength threshold, so the coarsening stalls at once.
    fn weakly_coupled(n: usize, band: usize, coupling: f64) -> Csr {
        let dense: Vec<Vec<f64>> = (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| match i.abs_diff(j) {
                        0 => 1.0,
                        d if d <= band => -coupling,
                        _ => 0.0,
                    })
                    .collect()
            })
            .collect();
        dense_rows(&dense)
    }

    #[test]
    fn a_stalled_coarsest_level_gets_the_sweeps_its_dominance_needs() {
        let n = 200;
        // (band, coupling, ρ = 2·band·coupling, sweeps = ⌈ln 0.1 / (2 ln ρ)⌉ capped at 4)
        for (band, coupling, sweeps) in [
            (3, 0.04, 1),  // ρ = 0.24: ρ² = 0.058
            (3, 0.075, 2), // ρ = 0.45: ρ² = 0.20, ρ⁴ = 0.041
            (6, 0.075, 4), // ρ = 0.90: ρ⁸ = 0.43, capped
            (7, 0.075, 4), // ρ = 1.05: no bound
        ] {
            let matrix = weakly_coupled(n, band, coupling);
            let mut hierarchy = Hierarchy::with_coarsest_size(&matrix, 1);
            assert_eq!(
                hierarchy.sizes(),
                vec![n],
                "band {band}: the coarsening stalls"
            );
            assert!(hierarchy.coarsest_factor.is_none());
            assert_eq!(
                hierarchy.coarsest_sweeps, sweeps,
                "band {band}, coupling {coupling}"
            );
            let dominance = 2.0 * band as f64 * coupling;
            if dominance < 1.0 {
                // the cycle is the sweeps from zero: the error of A z = A x* shrinks by ρ^{2s}
                let exact: Vec<f64> = (0..n).map(|i| ((i * 37) % 11) as f64 - 5.0).collect();
                let mut rhs = vec![0.0; n];
                matrix.multiply(&exact, &mut rhs);
                let mut z = vec![0.0; n];
                hierarchy.cycle(&rhs, &mut z);
                let difference: Vec<f64> = exact.iter().zip(&z).map(|(x, z)| x - z).collect();
                let error = max_abs(&difference);
                let bound = dominance.powi(2 * sweeps as i32) * max_abs(&exact);
                assert!(error <= bound, "band {band}: error {error} > {bound}");
                if sweeps < COARSEST_SWEEPS {
                    assert!(bound <= COARSEST_REDUCTION * max_abs(&exact));
                }
            }
        }
    }

    #[test]
    fn truncated_v_cycle_contracts_on_the_free_set() {
        let m = 64;
        let matrix = laplacian(m, 1e-3);
        let csr = Csr::from_symmetric(&matrix);
        let mut hierarchy = Hierarchy::new(&csr);
        // Fixed: a disc in the middle and a strip along one side.
        let fixed: Vec<bool> = (0..m * m)
            .map(|k| {
                let (i, j) = ((k / m) as f64, (k % m) as f64);
                (i - 32.0).powi(2) + (j - 30.0).powi(2) < 150.0 || j < 5.0
            })
            .collect();
        let rate = contraction(&mut hierarchy, &csr, &fixed);
        assert!(
            rate < CONTRACTION_BOUND,
            "truncated V-cycle contraction {rate}"
        );
        // Untruncating again restores the original contraction.
        let rate = contraction(&mut hierarchy, &csr, &vec![false; m * m]);
        assert!(
            rate < CONTRACTION_BOUND,
            "restored V-cycle contraction {rate}"
        );
    }
    /// The products in sweep order are the row products up to rounding, in both directions,
    /// on rows with and without a stored diagonal entry (a row without one also has no lower
    /// or no upper part here), and the Gauss–Seidel sweep built on them solves the system.
    #[test]
    fn sweep_products_are_the_row_products_in_both_directions() {
        let m = 12;
        let matrix = Csr::from_symmetric(&laplacian(m, 0.5));
        // a row without its diagonal entry: drop it from the pattern of row 0 and the last
        let n = m * m;
        let mut offsets = vec![0];
        let (mut indices, mut values) = (Vec::new(), Vec::new());
        for i in 0..n {
            let (columns, entries) = matrix.row(i);
            for (&j, &a) in columns.iter().zip(entries) {
                if !(j == i && (i == 0 || i == n - 1)) {
                    indices.push(j);
                    // distinct values, so that a dropped or repeated term shows
                    values.push(a * (1.0 + 0.01 * ((i * 7 + j * 3) % 11) as f64));
                }
            }
            offsets.push(indices.len());
        }
        let without_diagonal = Csr {
            cols: n,
            offsets,
            indices,
            values,
        };
        let x: Vec<f64> = (0..n).map(|i| ((i * 13) % 17) as f64 - 8.3).collect();
        for csr in [&matrix, &without_diagonal] {
            for (i, &lower) in csr.lower_counts().iter().enumerate() {
                let exact = csr.row_product(i, &x);
                let size: f64 = csr
                    .row(i)
                    .0
                    .iter()
                    .zip(csr.row(i).1)
                    .map(|(&j, a)| (a * x[j]).abs())
                    .sum();
                for backward in [false, true] {
                    let swept = csr.sweep_product(i, &x, lower, backward);
                    assert!(
                        (swept - exact).abs() <= 1e-14 * size,
                        "row {i}, backward {backward}: {swept} vs {exact}"
                    );
                }
            }
        }
        // Symmetric Gauss–Seidel on the finest level of an untruncated hierarchy converges to
        // the solution of A z = r.
        let hierarchy = Hierarchy::new(&matrix);
        let mut level = hierarchy.levels[0].clone();
        level.rhs = (0..n).map(|i| (i % 5) as f64 - 2.0).collect();
        level.solution.fill(0.0);
        for _ in 0..400 {
            level.sweep(false);
            level.sweep(true);
        }
        let mut residual = vec![0.0; n];
        matrix.multiply(&level.solution, &mut residual);
        let worst = residual
            .iter()
            .zip(&level.rhs)
            .fold(0.0_f64, |w, (a, b)| w.max((a - b).abs()));
        assert!(worst < 1e-10, "Gauss–Seidel residual {worst}");
    }

    /// A dense symmetric matrix as rows.
    fn dense_rows(dense: &[Vec<f64>]) -> Csr {
        let n = dense.len();
        let mut triplets = Vec::new();
        for (i, row) in dense.iter().enumerate() {
            for (j, &value) in row.iter().enumerate() {
                if value != 0.0 {
                    triplets.push(Triplet::new(i, j, value));
                }
            }
        }
        Csr::from_symmetric(&SparseColMat::try_new_from_triplets(n, n, &triplets).unwrap())
    }

    /// `max_i |(A x − b)_i|` over the rows `kept`.
    fn residual_on(dense: &[Vec<f64>], x: &[f64], rhs: &[f64]) -> f64 {
        dense
            .iter()
            .zip(rhs)
            .map(|(row, b)| (row.iter().zip(x).map(|(a, x)| a * x).sum::<f64>() - b).abs())
            .fold(0.0, f64::max)
    }

    /// The truncated coarsest matrix (38 unknowns, 6 of them truncated away) that the
    /// Cholesky factor without pivoting reported indefinite (a pivot of −1.3e-5 times the
    /// largest diagonal entry) although its eigenvalues are ≥ −2e-20 (positive semidefinite
    /// up to rounding): met in a coarse obstacle problem whose aggregates touch both bounds.
    /// With diagonal pivoting it is factorized, and a consistent system is solved to
    /// rounding; a genuinely indefinite matrix is still reported.
    #[test]
    fn pivoted_dense_factor_solves_a_semidefinite_coarsest_matrix_and_detects_indefinite_ones() {
        let dense: Vec<Vec<f64>> = include_str!("../../tests/data/truncated_coarsest_38.txt")
            .lines()
            .filter(|line| !line.trim().is_empty())
            .map(|line| {
                line.split_whitespace()
                    .map(|v| v.parse().unwrap())
                    .collect()
            })
            .collect();
        let n = dense.len();
        assert_eq!(n, 38);
        let rows = dense_rows(&dense);
        let diagonal = rows.diagonal();
        let scale = diagonal.iter().fold(0.0_f64, |acc, d| acc.max(*d));
        let factor = DenseFactor::new(&rows, &diagonal, scale);
        assert!(!factor.indefinite);
        assert!(factor.rank < n, "rank {}", factor.rank);
        // A right-hand side in the range: b = A y.
        let y: Vec<f64> = (0..n).map(|i| ((i * 7 % 11) as f64 - 5.0) / 5.0).collect();
        let rhs: Vec<f64> = dense
            .iter()
            .map(|row| row.iter().zip(&y).map(|(a, y)| a * y).sum())
            .collect();
        let mut x = vec![0.0; n];
        factor.solve(&rhs, &mut x, &mut vec![0.0; n]);
        let size = rhs.iter().fold(0.0_f64, |acc, b| acc.max(b.abs()));
        assert!(
            residual_on(&dense, &x, &rhs) <= 1e-8 * size,
            "residual {} against {size}",
            residual_on(&dense, &x, &rhs)
        );
        // The truncated unknowns (zero rows) are dropped and set to zero.
        for i in 0..n {
            if diagonal[i] == 0.0 {
                assert_eq!(x[i], 0.0);
            }
        }
        let indefinite = vec![
            vec![2.0, 0.0, 1.0],
            vec![0.0, -1.0, 0.0],
            vec![1.0, 0.0, 3.0],
        ];
        let rows = dense_rows(&indefinite);
        let diagonal = rows.diagonal();
        assert!(DenseFactor::new(&rows, &diagonal, 3.0).indefinite);
    }
}
