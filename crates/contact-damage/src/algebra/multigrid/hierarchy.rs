//! The hierarchy: its levels, their construction (step 4 of the [module
//! documentation](super), "Construction": Galerkin coarse matrices, the coarsest level's
//! factor or sweeps) and its truncation to a free set.

use crate::algebra::multigrid::aggregation::{aggregate, smoothed_prolongation};
use crate::algebra::multigrid::csr::{product_pattern, product_rows, Csr};
use crate::algebra::multigrid::dense_factor::DenseFactor;

/// Largest number of unknowns solved directly on the coarsest level.
pub(crate) const COARSEST_SIZE: usize = 64;
/// Most symmetric Gauss–Seidel sweeps on a coarsest level too large for the dense factor
/// (the count for a level that is not strictly diagonally dominant, [`coarsest_sweeps`]).
pub(crate) const COARSEST_SWEEPS: usize = 4;
/// Error reduction (maximum norm) asked of the sweeps on a coarsest level without a dense
/// factor: a V-cycle preconditioner needs an approximate coarse solve only.
pub(super) const COARSEST_REDUCTION: f64 = 0.1;
/// Coarsening stops when a level keeps more than this fraction of the unknowns.
const STALLED_COARSENING: f64 = 0.8;
/// Most levels built.
const MAX_LEVELS: usize = 25;

/// One level: its (truncated) matrix, the prolongation from the next coarser level and the
/// product of the two.
#[derive(Debug, Clone)]
pub(super) struct Level {
    /// `Ã_l`: on the finest level `A` with the rows and columns of the fixed indices zeroed,
    /// on the coarser ones the Galerkin matrix `R_{l−1} Ã_{l−1} P_{l−1}`.
    pub(super) matrix: Csr,
    pub(super) diagonal: Vec<f64>,
    /// `1/a_ii` on the rows kept by the truncation (the smoother multiplies by it: a division
    /// would lengthen the sweep's dependency chain from row to row).
    pub(super) inverse_diagonal: Vec<f64>,
    /// The counts of [`Csr::lower_counts`] (the pattern is fixed, truncation zeroes values).
    pub(super) lower_counts: Vec<usize>,
    /// `P_l` (rows: this level, columns: the next coarser one), its transpose `R_l = P_lᵀ`
    /// and the product `Ã_l P_l`.
    pub(super) transfer: Option<Transfer>,
    /// Marks of the rows changed by a truncation (all `false` between truncations).
    pub(super) touched: Vec<bool>,
    /// Work vectors of the cycle.
    pub(super) solution: Vec<f64>,
    pub(super) rhs: Vec<f64>,
    pub(super) residual: Vec<f64>,
}

/// Grid transfer of a level to the next coarser one.
#[derive(Debug, Clone)]
pub(super) struct Transfer {
    pub(super) prolongation: Csr,
    pub(super) restriction: Csr,
    /// `Ã_l P_l`, kept so that a truncation recomputes only the rows it changes.
    pub(super) product: Csr,
}

/// The truncated smoothed-aggregation hierarchy of a sparse SPD matrix.
#[derive(Debug, Clone)]
pub(crate) struct Hierarchy {
    pub(super) levels: Vec<Level>,
    /// The untruncated fine matrix `A` and its diagonal.
    fine: Csr,
    fine_diagonal: Vec<f64>,
    /// Fixed fine indices of the current truncation.
    fixed: Vec<bool>,
    /// Largest size of the dense coarsest factor.
    coarsest_size: usize,
    /// Dense factor of the coarsest matrix, if it has at most `coarsest_size` unknowns.
    pub(super) coarsest_factor: Option<DenseFactor>,
    /// Symmetric Gauss–Seidel sweeps on the coarsest level when it has no dense factor
    /// ([`coarsest_sweeps`] of its untruncated matrix).
    pub(super) coarsest_sweeps: usize,
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

    /// Truncates the hierarchy to the free set `{i : !fixed[i]}` (see the [module
    /// documentation](super)); a no-op if `fixed` is the current truncation. Only the rows that the
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
pub(super) fn coarsest_sweeps(matrix: &Csr, diagonal: &[f64]) -> usize {
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
