//! The truncated nonsmooth Newton multigrid ([`BoxQpMethod::MonotoneMultigrid`], Gräser &
//! Kornhuber 2009; the [module documentation](super), "Algorithm"): the iteration, and the
//! conjugate gradients preconditioned with one truncated V-cycle of its linear correction.
//!
//! [`BoxQpMethod::MonotoneMultigrid`]: super::BoxQpMethod::MonotoneMultigrid

use crate::algebra::linalg::max_abs;
use crate::algebra::multigrid::{Csr, Hierarchy};
use crate::algebra::pcg::{pcg, BetaRule, PcgSettings, PcgStop, PcgSystem};
use crate::error::{Error, Result};
use crate::solvers::box_qp::kkt::{clamp, scaled_kkt_residual, Problem};
use crate::solvers::box_qp::projected_gauss_seidel::{
    mark_stale, projected_gauss_seidel, residual_gradient, STALE,
};
use crate::solvers::box_qp::settings::BoxQpStats;
use crate::solvers::box_qp::solver::BoxQpSolver;
use crate::solvers::box_qp::workspace::{CgWork, Workspace};
use crate::solvers::box_qp_coarse::bound_violations;

impl BoxQpSolver {
    /// Truncated nonsmooth Newton multigrid ([module documentation](super), "Algorithm"): `x` is
    /// feasible on entry with `work.gradient = A x − b`, and holds the solution on success.
    #[allow(clippy::needless_range_loop)] // componentwise kernels over several vectors
    pub(super) fn monotone_multigrid(
        &mut self,
        problem: &Problem<'_>,
        x: &mut [f64],
        work: &mut Workspace,
        stats: &mut BoxQpStats,
        history: &mut Vec<f64>,
    ) -> Result<()> {
        let tolerance = self.settings.tolerance;
        let exact = 0.1 * tolerance * problem.scale;
        let n = x.len();
        let (fine, hierarchy) = self.multigrid.as_mut().expect("built for this method");
        let rows = &fine.rows;
        while stats.iterations < self.settings.max_iterations {
            stats.iterations += 1;
            // 0. The coarse obstacle correction (`crate::solvers::box_qp_coarse`).
            let residual = history.last().copied().unwrap_or(f64::INFINITY);
            if let Some(coarse) = self.coarse.as_mut() {
                let violations = || {
                    bound_violations(x, &work.gradient, problem.lower, problem.upper, problem.tie)
                };
                if let Some(tolerance) = coarse.tolerance_at(residual, n, violations) {
                    let iterations = coarse.correct(
                        x,
                        &work.gradient,
                        problem.lower,
                        problem.upper,
                        tolerance,
                    )?;
                    if iterations > 0 {
                        stats.coarse_iterations += iterations;
                        work.marks.fill(STALE);
                        residual_gradient(
                            rows,
                            x,
                            problem.rhs,
                            &mut work.gradient,
                            &mut work.marks,
                        );
                    }
                }
            }
            // 1. Nonlinear smoothing: a symmetric projected Gauss–Seidel sweep.
            projected_gauss_seidel(fine, problem, x, false, &mut work.marks);
            projected_gauss_seidel(fine, problem, x, true, &mut work.marks);
            residual_gradient(rows, x, problem.rhs, &mut work.gradient, &mut work.marks);
            let residual = scaled_kkt_residual(x, &work.gradient, problem);
            history.push(residual);
            if residual <= tolerance {
                return Ok(());
            }
            // 2. Truncation: the indices on a bound keep their value in the correction.
            for i in 0..n {
                work.fixed[i] = x[i] == problem.lower[i] || x[i] == problem.upper[i];
            }
            if hierarchy.truncate(&work.fixed) {
                stats.coarse_updates += 1;
            }
            if hierarchy.is_indefinite() {
                return Err(not_positive_definite(
                    "coarsest level of the multigrid hierarchy",
                ));
            }
            // 3. Linear correction: A_FF d_F = −g_F by multigrid-preconditioned CG.
            // −g_F (zero on the fixed indices) and its size.
            for i in 0..n {
                work.product[i] = if work.fixed[i] {
                    0.0
                } else {
                    -work.gradient[i]
                };
            }
            let free_gradient = max_abs(&work.product);
            let target = exact.max(CORRECTION_FRACTION * free_gradient);
            multigrid_cg(
                rows,
                hierarchy,
                &work.fixed,
                &work.product,
                &mut work.direction,
                target,
                &mut work.cg,
                stats,
            )?;
            // 4. Projection of the correction onto the box, then an exact line search on the
            // segment from x to the projected point (q never increases).
            // The rows that see a nonzero entry of d are marked stale (their gradient changes)
            // and unsettled; A d vanishes on the others.
            for i in 0..n {
                let corrected = clamp(x[i] + work.direction[i], problem.lower[i], problem.upper[i]);
                work.trial[i] = corrected;
                work.direction[i] = corrected - x[i];
                if work.direction[i] != 0.0 {
                    mark_stale(rows.row(i).0, &mut work.marks);
                }
            }
            rows.multiply_rows(&work.direction, &mut work.product, |i| {
                work.marks[i] & STALE != 0
            });
            let (mut slope, mut curvature) = (0.0, 0.0);
            for i in 0..n {
                slope += work.gradient[i] * work.direction[i];
                curvature += work.direction[i] * work.product[i];
            }
            if curvature < 0.0 {
                return Err(not_positive_definite(
                    "line search of the multigrid correction",
                ));
            }
            if slope < 0.0 && curvature > 0.0 {
                let step = (-slope / curvature).min(1.0);
                // x ← x + α d (for α = 1 the projected point itself: indices clamped by the
                // projection lie on their bounds exactly) and g ← g + α A d (up to rounding; a
                // converged iterate is confirmed below with the gradient recomputed from x).
                for i in 0..n {
                    x[i] = if step == 1.0 {
                        work.trial[i]
                    } else {
                        clamp(
                            x[i] + step * work.direction[i],
                            problem.lower[i],
                            problem.upper[i],
                        )
                    };
                    work.gradient[i] += step * work.product[i];
                }
            }
            let mut residual = scaled_kkt_residual(x, &work.gradient, problem);
            if residual <= tolerance {
                residual_gradient(rows, x, problem.rhs, &mut work.gradient, &mut work.marks);
                residual = scaled_kkt_residual(x, &work.gradient, problem);
            }
            history.push(residual);
            if residual <= tolerance {
                return Ok(());
            }
            if x.iter().any(|value| !value.is_finite()) {
                return Err(Error::NonFinite(
                    "box QP monotone multigrid produced a non-finite value".into(),
                ));
            }
        }
        Err(self.no_convergence(
            stats.iterations,
            history.last().copied().unwrap_or(f64::INFINITY),
            history,
        ))
    }
}

/// Free-gradient target of a multigrid linear correction, as a fraction of the free gradient.
const CORRECTION_FRACTION: f64 = 1e-1;
/// Most conjugate gradient iterations of one multigrid linear correction.
const CORRECTION_ITERATIONS: usize = 10;

/// The error for a negative curvature `dᵀAd < 0` met in `context`: `A` is not positive definite.
fn not_positive_definite(context: &str) -> Error {
    Error::LinearAlgebra {
        context: format!("box QP monotone multigrid, {context}"),
        message: "negative curvature: the matrix A is not positive definite".into(),
    }
}

/// Conjugate gradients for the truncated system `A_FF d_F = r_F` (`r` and `d` vanish on the
/// fixed indices) from `d = 0`, preconditioned with one V-cycle of the truncated hierarchy;
/// stops when `‖r − A_FF d‖_∞ ≤ target` or after [`CORRECTION_ITERATIONS`] iterations.
#[allow(clippy::too_many_arguments)]
fn multigrid_cg(
    rows: &Csr,
    hierarchy: &mut Hierarchy,
    fixed: &[bool],
    rhs: &[f64],
    solution: &mut [f64],
    target: f64,
    cg: &mut CgWork,
    stats: &mut BoxQpStats,
) -> Result<()> {
    solution.fill(0.0);
    cg.vectors.residual.copy_from_slice(rhs);
    let settings = PcgSettings {
        target,
        max_iterations: CORRECTION_ITERATIONS,
        beta: BetaRule::FletcherReeves,
    };
    let mut system = TruncatedSystem {
        rows,
        hierarchy,
        fixed,
        stats,
    };
    let outcome = pcg(&mut system, solution, &mut cg.vectors, &settings)?;
    match outcome.stop {
        PcgStop::Breakdown { curvature } if curvature < 0.0 => Err(not_positive_definite(
            "conjugate gradients of the multigrid correction",
        )),
        // a breakdown at the rounding level or the cap leaves the last iterate
        _ => Ok(()),
    }
}

/// The truncated operator `A_FF` (products of the free rows only) and its V-cycle.
struct TruncatedSystem<'a> {
    rows: &'a Csr,
    hierarchy: &'a mut Hierarchy,
    fixed: &'a [bool],
    stats: &'a mut BoxQpStats,
}

impl PcgSystem for TruncatedSystem<'_> {
    type Error = Error;

    fn apply(&mut self, x: &[f64], image: &mut [f64]) -> Result<()> {
        let fixed = self.fixed;
        self.rows.multiply_rows(x, image, |i| !fixed[i]);
        Ok(())
    }

    fn precondition(&mut self, residual: &[f64], z: &mut [f64]) -> Result<()> {
        self.stats.inner_iterations += 1;
        self.hierarchy.cycle(residual, z);
        Ok(())
    }
}
