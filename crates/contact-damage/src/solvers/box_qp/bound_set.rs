//! The solve on a predicted bound set ([`BoxQpSolver::solve_predicted`]; the
//! [module documentation](super), "Predicted bound sets"): when the indices on each bound are
//! known in advance, the box QP is one linear system, `A_FF x_F = b_F − A_FL lower_L −
//! A_FU upper_U`, solved with a Cholesky factor of that bound set and certified by the KKT
//! residual.

use faer::sparse::SparseColMat;

use crate::algebra::linalg::{multiply_into, CholeskySolver, FactorKind};
use crate::error::{Error, Result};
use crate::solvers::box_qp::bound_set_border::Border;
use crate::solvers::box_qp::kkt::{gradient, project, scaled_kkt_residual, Problem};
use crate::solvers::box_qp::settings::BoxQpStats;
use crate::solvers::box_qp::solver::BoxQpSolver;
use crate::solvers::box_qp::workspace::BoundStatus;

/// The Cholesky factor of `A` with the rows and columns of the fixed indices of one bound set
/// replaced by those of the identity. The matrix keeps the pattern of `A` (the removed entries
/// are stored zeros), so one symbolic analysis serves every bound set, and the factor depends
/// on the bound set alone: which set was cached before changes the cost of a solve, never its
/// result.
pub(super) struct BoundSetFactor {
    /// The bound set of the factor (indices with `lower_i = upper_i` as [`BoundStatus::AtLower`]).
    pub(super) set: Vec<BoundStatus>,
    /// `A` with the fixed rows and columns of `set` replaced by the identity's.
    matrix: SparseColMat<usize, f64>,
    pub(super) factor: CholeskySolver,
    /// `A x_fixed` (the fixed values extended by zero), then the gradient of the candidate.
    pub(super) product: Vec<f64>,
    /// The right-hand side of the reduced system, the fixed values at the fixed indices.
    pub(super) reduced_rhs: Vec<f64>,
    /// The border of the factor for the sets followed from it
    /// ([`BoxQpSolver::solve_following`]), cleared at each factorization.
    pub(super) border: Border,
}

impl BoundSetFactor {
    /// The symbolic analysis of the pattern of `matrix` (supernodal: the factor is recomputed
    /// at each new bound set, and the supernodal factorization is the faster one on the
    /// damage matrices, `reports/benchmark_step.md`).
    fn new(matrix: &SparseColMat<usize, f64>) -> Result<Self> {
        let n = matrix.nrows();
        Ok(Self {
            set: Vec::new(),
            matrix: matrix.clone(),
            factor: CholeskySolver::analyse_as(
                matrix,
                FactorKind::Supernodal,
                "box QP Cholesky factor on a predicted bound set",
            )?,
            product: vec![0.0; n],
            reduced_rhs: vec![0.0; n],
            border: Border::default(),
        })
    }

    /// Factorizes for the bound set `set` unless it is the set of the current factor; returns
    /// whether it factorized.
    pub(super) fn prepare(
        &mut self,
        original: &SparseColMat<usize, f64>,
        set: &[BoundStatus],
    ) -> Result<bool> {
        if self.factor.is_factorized() && self.set == set {
            return Ok(false);
        }
        self.set.clear();
        self.set.extend_from_slice(set);
        self.border.clear();
        let column_pointers = original.col_ptr();
        let row_indices = original.row_idx();
        let values = original.val();
        let reduced = self.matrix.val_mut();
        for column in 0..original.ncols() {
            let column_free = set[column] == BoundStatus::Free;
            for entry in column_pointers[column]..column_pointers[column + 1] {
                let row = row_indices[entry];
                reduced[entry] = if column_free && set[row] == BoundStatus::Free {
                    values[entry]
                } else if row == column {
                    1.0
                } else {
                    0.0
                };
            }
        }
        self.factor.factorize(&self.matrix)?;
        Ok(true)
    }
}

/// The bound set `predicted` made consistent with the bounds (an index with `lower_i = upper_i`
/// is fixed at its lower bound), or `None` when it puts an index on an infinite bound.
pub(super) fn normalized_set(
    predicted: &[BoundStatus],
    lower: &[f64],
    upper: &[f64],
) -> Option<Vec<BoundStatus>> {
    predicted
        .iter()
        .zip(lower.iter().zip(upper))
        .map(|(&status, (&lower, &upper))| {
            if lower == upper {
                return Some(BoundStatus::AtLower);
            }
            let bound = match status {
                BoundStatus::Free => return Some(BoundStatus::Free),
                BoundStatus::AtLower => lower,
                BoundStatus::AtUpper => upper,
            };
            bound.is_finite().then_some(status)
        })
        .collect()
}

impl BoxQpSolver {
    /// The fill of the Cholesky factor of [`BoxQpSolver::solve_predicted`]: its stored values
    /// per stored value of `A`, from its symbolic analysis (done here on the first call, and
    /// kept for the predicted solves). A solve with the factor costs about four flops per
    /// stored value and a new factorization about ten such solves; this ratio says how that
    /// compares with the sparse products of an iteration without it.
    pub fn bound_set_fill(&mut self) -> Result<f64> {
        let factor = self.bound_set_factor()?;
        Ok(factor.factor.factor_len() as f64 / self.matrix.val().len() as f64)
    }

    /// Drops the factor of the predicted bound sets and its analysis (a caller that will not
    /// predict frees their memory; the next predicted solve analyses again).
    pub fn release_bound_set_factor(&mut self) {
        self.bound_set_factor = None;
    }

    /// The factor of the predicted bound sets, analysed on first use.
    pub(super) fn bound_set_factor(&mut self) -> Result<&mut BoundSetFactor> {
        if self.bound_set_factor.is_none() {
            self.bound_set_factor = Some(BoundSetFactor::new(&self.matrix)?);
        }
        Ok(self.bound_set_factor.as_mut().expect("created above"))
    }

    /// Solves the box QP like [`BoxQpSolver::solve`], trying first the bound set `predicted`:
    /// with `x_L = lower_L` and `x_U = upper_U` on its indices at a bound, the free values solve
    /// `A_FF x_F = b_F − A_FL lower_L − A_FU upper_U` (one solve with a Cholesky factor of that
    /// bound set, computed when the set differs from the one of the last factor). The result is
    /// that solution, projected onto the box, when its scaled KKT residual is within the
    /// tolerance (then [`BoxQpStats::bound_set_solve`] is set and one iteration is counted);
    /// otherwise the prediction is discarded and `x` is solved for by
    /// [`BoxQpSolver::solve`] from the start `x`, as without a prediction.
    ///
    /// The result depends on the data, the start and `predicted` only: the factor kept from an
    /// earlier call changes the cost, never the values. Errors: those of
    /// [`BoxQpSolver::solve`], and [`Error::InvalidInput`] when `predicted` does not have one
    /// status per unknown.
    pub fn solve_predicted(
        &mut self,
        rhs: &[f64],
        lower: &[f64],
        upper: &[f64],
        predicted: &[BoundStatus],
        x: &mut [f64],
    ) -> Result<BoxQpStats> {
        self.check_problem(rhs, lower, upper, x)?;
        if predicted.len() != x.len() {
            return Err(Error::InvalidInput(format!(
                "box QP: the predicted bound set has {} entries but the matrix has dimension {}",
                predicted.len(),
                x.len()
            )));
        }
        let mut factorizations = 0;
        if let Some(set) = normalized_set(predicted, lower, upper) {
            let tolerance = self.settings.tolerance;
            let problem = Problem::new(rhs, lower, upper, tolerance);
            self.bound_set_factor()?;
            let solver = self.bound_set_factor.as_mut().expect("analysed above");
            if solver.prepare(&self.matrix, &set)? {
                factorizations += 1;
            }
            let candidate = candidate(&self.matrix, solver, &set, &problem)?;
            gradient(&self.matrix, &candidate, rhs, &mut solver.product);
            if scaled_kkt_residual(&candidate, &solver.product, &problem) <= tolerance {
                x.copy_from_slice(&candidate);
                let mut stats = BoxQpStats {
                    iterations: 1,
                    factorizations,
                    bound_set_solve: true,
                    ..BoxQpStats::default()
                };
                self.finish(x, &problem, &mut stats);
                return Ok(stats);
            }
        }
        let mut stats = self.solve(rhs, lower, upper, x)?;
        stats.factorizations += factorizations;
        Ok(stats)
    }
}

/// The solution of the reduced system of the bound set `set` (whose factor `solver` holds),
/// with the fixed values exactly on their bounds, projected onto the box.
fn candidate(
    matrix: &SparseColMat<usize, f64>,
    solver: &mut BoundSetFactor,
    set: &[BoundStatus],
    problem: &Problem<'_>,
) -> Result<Vec<f64>> {
    let fixed_value = |i: usize| match set[i] {
        BoundStatus::Free => 0.0,
        BoundStatus::AtLower => problem.lower[i],
        BoundStatus::AtUpper => problem.upper[i],
    };
    let fixed: Vec<f64> = (0..set.len()).map(fixed_value).collect();
    multiply_into(matrix, &fixed, &mut solver.product);
    for (i, status) in set.iter().enumerate() {
        solver.reduced_rhs[i] = match status {
            BoundStatus::Free => problem.rhs[i] - solver.product[i],
            _ => fixed[i],
        };
    }
    let mut candidate = solver.factor.solve(&solver.reduced_rhs)?;
    for (i, status) in set.iter().enumerate() {
        if *status != BoundStatus::Free {
            candidate[i] = fixed[i];
        }
    }
    project(&mut candidate, problem.lower, problem.upper);
    Ok(candidate)
}
