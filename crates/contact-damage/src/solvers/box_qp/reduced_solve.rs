//! The linear algebra of the active set method ([module documentation](super), "Linear algebra
//! of the active set method"): reduced systems `A_FF y_F = r_F` by conjugate gradients
//! preconditioned with the one Cholesky factor of `A` and Gauss–Seidel sweeps on the free set.

use faer::sparse::SparseColMat;
use faer::MatMut;

use crate::algebra::linalg::{max_abs_free, multiply_into};
use crate::algebra::pcg::{pcg, BetaRule, PcgSettings, PcgSystem};
use crate::error::{Error, Result};
use crate::solvers::box_qp::kkt::{gradient, Problem};
use crate::solvers::box_qp::settings::BoxQpStats;
use crate::solvers::box_qp::solver::BoxQpSolver;
use crate::solvers::box_qp::workspace::{BoundStatus, CgWork, Workspace};

/// Maximum number of iterative refinement steps after a reduced solve.
const MAX_REFINEMENT_STEPS: usize = 3;

impl BoxQpSolver {
    /// Solves the reduced system of the active sets `state`: `work.trial` holds a start on
    /// entry (its free values are the warm start) and receives `x` with `x_L = lower_L`,
    /// `x_U = upper_U` and `A_FF x_F = b_F − A_FL lower_L − A_FU upper_U`; `work.trial_gradient`
    /// receives `A x − b`. The correction `δ_F` with `A_FF δ_F = −g_F` is computed by
    /// [`BoxQpSolver::reduced_cg`] and repeated (restarted from the true gradient) at most
    /// [`MAX_REFINEMENT_STEPS`] times until the free gradient is below `target`.
    #[allow(clippy::needless_range_loop)] // componentwise kernels over several vectors
    pub(super) fn reduced_solve(
        &mut self,
        state: &[BoundStatus],
        problem: &Problem<'_>,
        target: f64,
        work: &mut Workspace,
        stats: &mut BoxQpStats,
    ) -> Result<()> {
        for (i, status) in state.iter().enumerate() {
            work.fixed[i] = *status != BoundStatus::Free;
            match status {
                BoundStatus::Free => {}
                BoundStatus::AtLower => work.trial[i] = problem.lower[i],
                BoundStatus::AtUpper => work.trial[i] = problem.upper[i],
            }
        }
        gradient(
            &self.matrix,
            &work.trial,
            problem.rhs,
            &mut work.trial_gradient,
        );
        let mut free_residual = max_abs_free(&work.trial_gradient, &work.fixed);
        for _ in 0..=MAX_REFINEMENT_STEPS {
            if free_residual <= target {
                break;
            }
            for i in 0..state.len() {
                work.product[i] = if work.fixed[i] {
                    0.0
                } else {
                    -work.trial_gradient[i]
                };
            }
            let rhs = std::mem::take(&mut work.product);
            let mut correction = std::mem::take(&mut work.direction);
            let result = self.reduced_cg(
                &work.fixed,
                &rhs,
                &mut correction,
                target,
                &mut work.cg,
                stats,
            );
            work.product = rhs;
            result?;
            for i in 0..state.len() {
                work.projected[i] = work.trial[i];
                work.trial[i] += correction[i];
            }
            work.direction = correction;
            gradient(&self.matrix, &work.trial, problem.rhs, &mut work.product);
            let refined = max_abs_free(&work.product, &work.fixed);
            if refined < free_residual {
                free_residual = refined;
                work.trial_gradient.copy_from_slice(&work.product);
            } else {
                // No progress (rounding level): undo the correction and stop.
                work.trial.copy_from_slice(&work.projected);
                break;
            }
        }
        if work.trial.iter().any(|value| !value.is_finite()) {
            return Err(Error::NonFinite(
                "box QP reduced solve produced a non-finite value".into(),
            ));
        }
        Ok(())
    }

    /// Conjugate gradients for the reduced system `A_FF y_F = r_F` (`F` = indices not `fixed`;
    /// `rhs` and the returned `solution` vanish on the fixed indices), preconditioned with the
    /// restriction of `A⁻¹` to `F`: `z = (A⁻¹ r̃)_F` where `r̃` is `r` extended by zero. This
    /// preconditioner is SPD on `F` (it is `S_FF⁻¹`, the inverse of the Schur complement of `A`
    /// onto `F`), and the preconditioned operator `S_FF⁻¹ A_FF = I + S_FF⁻¹ A_FI A_II⁻¹ A_IF`
    /// differs from the identity by a term of rank at most `|I|`: CG ends in at most
    /// `min(|F|, |I| + 1)` steps in exact arithmetic, and its spectrum lies in
    /// `[1, 1/(1 − γ²)]` with `γ` the strengthened Cauchy–Schwarz constant between the
    /// discrete functions carried by `F` and by `I`. Stops when `‖r − A_FF y‖_∞ ≤ target` (the
    /// recursively updated residual), after a breakdown, or after the iteration cap.
    pub(super) fn reduced_cg(
        &mut self,
        fixed: &[bool],
        rhs: &[f64],
        solution: &mut [f64],
        target: f64,
        cg: &mut CgWork,
        stats: &mut BoxQpStats,
    ) -> Result<()> {
        self.ensure_factor(stats)?;
        let n = rhs.len();
        solution.fill(0.0);
        let free = fixed.iter().filter(|f| !**f).count();
        if free == 0 {
            return Ok(());
        }
        cg.vectors.residual.copy_from_slice(rhs);
        let settings = PcgSettings {
            target,
            max_iterations: 2 * free.min(n - free + 1) + 20,
            // flexible β: robust if the preconditioner is not exactly symmetric
            beta: BetaRule::PolakRibiere,
        };
        let mut system = ReducedSystem {
            solver: self,
            fixed,
            scratch: &mut cg.scratch,
            stats,
        };
        // a breakdown (at the rounding level) or the cap leaves the last iterate, as a
        // converged solve does: the caller measures the gradient it reaches
        pcg(&mut system, solution, &mut cg.vectors, &settings)?;
        Ok(())
    }

    /// The preconditioner of [`BoxQpSolver::reduced_cg`], `z = B_F r` (zero on the fixed
    /// indices): a symmetric two-level cycle on `A_FF` whose global part is one solve with the
    /// factor of `A` and whose local part is a forward and a backward Gauss–Seidel sweep on the
    /// free indices (see the [module documentation](super), "Linear algebra").
    #[allow(clippy::needless_range_loop)] // componentwise kernels over several vectors
    fn precondition(
        &mut self,
        fixed: &[bool],
        residual: &[f64],
        z: &mut [f64],
        scratch: &mut [f64],
        stats: &mut BoxQpStats,
    ) -> Result<()> {
        stats.inner_iterations += 1;
        z.fill(0.0);
        if SMOOTHING {
            gauss_seidel_sweep(&self.matrix, &self.diagonal, fixed, residual, z, false);
            multiply_into(&self.matrix, z, scratch);
            for i in 0..z.len() {
                scratch[i] = if fixed[i] {
                    0.0
                } else {
                    residual[i] - scratch[i]
                };
            }
        } else {
            scratch.copy_from_slice(residual);
        }
        self.solve_in_place(scratch)?;
        for i in 0..z.len() {
            if !fixed[i] {
                z[i] += scratch[i];
            }
        }
        if SMOOTHING {
            gauss_seidel_sweep(&self.matrix, &self.diagonal, fixed, residual, z, true);
        }
        Ok(())
    }

    /// Numerically factorizes `A` once (the first time a solve needs it).
    fn ensure_factor(&mut self, stats: &mut BoxQpStats) -> Result<()> {
        let factor = self
            .factor
            .as_mut()
            .expect("the active set method analyses A at construction");
        if factor.is_factorized() {
            return Ok(());
        }
        factor.factorize(&self.matrix)?;
        stats.factorizations += 1;
        Ok(())
    }

    /// Overwrites `rhs` with `A⁻¹ rhs` (the factor must exist).
    fn solve_in_place(&mut self, rhs: &mut [f64]) -> Result<()> {
        let dimension = rhs.len();
        self.factor
            .as_mut()
            .expect("the active set method analyses A at construction")
            .solve_block(MatMut::from_column_major_slice_mut(rhs, dimension, 1))
    }
}

/// Whether the preconditioner adds the Gauss–Seidel sweeps.
const SMOOTHING: bool = true;

/// One Gauss–Seidel sweep for `A_FF z = r` on the free indices (forward or backward), in place;
/// the matrix is stored with both triangles, so column `i` is row `i`.
fn gauss_seidel_sweep(
    matrix: &SparseColMat<usize, f64>,
    diagonal: &[f64],
    fixed: &[bool],
    rhs: &[f64],
    z: &mut [f64],
    backward: bool,
) {
    let symbolic = matrix.symbolic();
    let rows = symbolic.row_idx();
    let values = matrix.val();
    let n = z.len();
    for step in 0..n {
        let i = if backward { n - 1 - step } else { step };
        if fixed[i] {
            continue;
        }
        let mut sum = rhs[i];
        for position in symbolic.col_range(i) {
            let j = rows[position];
            if !fixed[j] {
                sum -= values[position] * z[j];
            }
        }
        z[i] += sum / diagonal[i];
    }
}

/// The reduced operator `A_FF` (rows and columns of the fixed indices zero) and the two-level
/// preconditioner of [`BoxQpSolver::reduced_cg`].
struct ReducedSystem<'a> {
    solver: &'a mut BoxQpSolver,
    fixed: &'a [bool],
    scratch: &'a mut [f64],
    stats: &'a mut BoxQpStats,
}

impl PcgSystem for ReducedSystem<'_> {
    type Error = Error;

    fn apply(&mut self, x: &[f64], image: &mut [f64]) -> Result<()> {
        multiply_into(&self.solver.matrix, x, image);
        for (value, fixed) in image.iter_mut().zip(self.fixed) {
            if *fixed {
                *value = 0.0;
            }
        }
        Ok(())
    }

    fn precondition(&mut self, residual: &[f64], z: &mut [f64]) -> Result<()> {
        self.solver
            .precondition(self.fixed, residual, z, self.scratch, self.stats)
    }
}
