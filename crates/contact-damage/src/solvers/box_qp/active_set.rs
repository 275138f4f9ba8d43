//! The primal–dual active set method with its projected Newton safeguard
//! ([`BoxQpMethod::ActiveSet`]; the [module documentation](super), "Alternative algorithm"):
//! the active set phase (Hintermüller, Ito & Kunisch 2002), the projected Newton phase
//! (Bertsekas 1982) and the active set classification of (★).
//!
//! [`BoxQpMethod::ActiveSet`]: super::BoxQpMethod::ActiveSet

use std::hash::{DefaultHasher, Hash, Hasher};

use crate::algebra::linalg::multiply_into;
use crate::error::Result;
use crate::solvers::box_qp::kkt::{
    clamp, gradient, objective, project, scaled_kkt_residual, Problem,
};
use crate::solvers::box_qp::settings::BoxQpStats;
use crate::solvers::box_qp::solver::BoxQpSolver;
use crate::solvers::box_qp::workspace::{BoundStatus, Workspace};

/// Sufficient decrease constant of the Armijo rule.
const ARMIJO_SIGMA: f64 = 1e-4;
/// Smallest step length tried by the Armijo backtracking before giving up.
const MIN_STEP_LENGTH: f64 = 1e-14;
/// Free-gradient target of an inexact reduced solve, as a fraction of the current KKT residual.
const INEXACT_FRACTION: f64 = 1e-2;

impl BoxQpSolver {
    /// Primal–dual active set iteration. Returns `true` with the solution in `x` on convergence,
    /// `false` with the best projected iterate in `x` when it cycles, exhausts its budget or
    /// stalls at the rounding level.
    pub(super) fn active_set_phase(
        &mut self,
        problem: &Problem<'_>,
        x: &mut [f64],
        work: &mut Workspace,
        stats: &mut BoxQpStats,
        history: &mut Vec<f64>,
    ) -> Result<bool> {
        let tolerance = self.settings.tolerance;
        let budget = self.settings.max_iterations.div_ceil(2);
        let mut best_objective = objective(x, &work.gradient, problem.rhs);
        let mut best = x.to_vec();
        classify(x, &work.gradient, problem, &self.diagonal, &mut work.state);
        // Warm start of the reduced solves: the free values of the previous iterate.
        work.trial.copy_from_slice(x);
        let mut visited = Vec::new();
        // Inexact reduced solves while far from the solution (the free gradient reduced to a
        // fraction of the current KKT residual), exact ones (a tenth of the tolerance) once the
        // active sets have settled.
        let exact = 0.1 * tolerance * problem.scale;
        let inexact = |residual: f64| exact.max(INEXACT_FRACTION * residual * problem.scale);
        let mut target = inexact(history.last().copied().unwrap_or(0.0));

        while stats.iterations < budget {
            stats.iterations += 1;
            visited.push(state_hash(&work.state));
            let state = std::mem::take(&mut work.state);
            self.reduced_solve(&state, problem, target, work, stats)?;
            work.state = state;
            classify(
                &work.trial,
                &work.trial_gradient,
                problem,
                &self.diagonal,
                &mut work.next_state,
            );
            work.projected.copy_from_slice(&work.trial);
            project(&mut work.projected, problem.lower, problem.upper);
            gradient(
                &self.matrix,
                &work.projected,
                problem.rhs,
                &mut work.projected_gradient,
            );
            let residual = scaled_kkt_residual(&work.projected, &work.projected_gradient, problem);
            history.push(residual);
            let projected_objective =
                objective(&work.projected, &work.projected_gradient, problem.rhs);
            if projected_objective < best_objective {
                best_objective = projected_objective;
                best.copy_from_slice(&work.projected);
            }
            if residual <= tolerance {
                x.copy_from_slice(&work.projected);
                return Ok(true);
            }
            if work.next_state == work.state || visited.contains(&state_hash(&work.next_state)) {
                if target > exact {
                    // Settled (or revisited) with an inexact solve: solve exactly from here.
                    target = exact;
                    visited.clear();
                    continue;
                }
                // A fixed point of the active sets above the tolerance (rounding level) or a
                // cycle: hand over to the safeguard.
                break;
            }
            target = inexact(residual);
            std::mem::swap(&mut work.state, &mut work.next_state);
        }
        x.copy_from_slice(&best);
        Ok(false)
    }

    /// Projected Newton method of Bertsekas (1982) with an exact reduced solve tried before
    /// every step; `x` is feasible on entry and holds the solution on success.
    #[allow(clippy::needless_range_loop)] // componentwise kernels over several vectors
    pub(super) fn projected_newton_phase(
        &mut self,
        problem: &Problem<'_>,
        x: &mut [f64],
        work: &mut Workspace,
        stats: &mut BoxQpStats,
        history: &mut Vec<f64>,
    ) -> Result<()> {
        let tolerance = self.settings.tolerance;
        let epsilon_bar = self.epsilon_bar(problem, x);
        loop {
            gradient(&self.matrix, x, problem.rhs, &mut work.gradient);
            let residual = scaled_kkt_residual(x, &work.gradient, problem);
            if residual <= tolerance {
                return Ok(());
            }
            if stats.iterations >= self.settings.max_iterations {
                return Err(self.no_convergence(stats.iterations, residual, history));
            }
            stats.iterations += 1;

            // Exact reduced solve on the active sets of the current point.
            let mut state = std::mem::take(&mut work.state);
            classify(x, &work.gradient, problem, &self.diagonal, &mut state);
            work.trial.copy_from_slice(x);
            let exact = 0.1 * tolerance * problem.scale;
            self.reduced_solve(&state, problem, exact, work, stats)?;
            work.state = state;
            work.projected.copy_from_slice(&work.trial);
            project(&mut work.projected, problem.lower, problem.upper);
            gradient(
                &self.matrix,
                &work.projected,
                problem.rhs,
                &mut work.projected_gradient,
            );
            let polished = scaled_kkt_residual(&work.projected, &work.projected_gradient, problem);
            if polished <= tolerance {
                history.push(polished);
                x.copy_from_slice(&work.projected);
                return Ok(());
            }

            // Projected Newton step: ε-active set, reduced Newton direction, Armijo arc search.
            let mut width = 0.0_f64;
            for i in 0..x.len() {
                let scaled_step = x[i] - work.gradient[i] / self.diagonal[i];
                width = width
                    .max((x[i] - clamp(scaled_step, problem.lower[i], problem.upper[i])).abs());
            }
            let epsilon = epsilon_bar.min(width);
            for i in 0..x.len() {
                let (g, lower, upper) = (work.gradient[i], problem.lower[i], problem.upper[i]);
                work.fixed[i] = lower == upper
                    || (x[i] <= lower + epsilon && g > 0.0)
                    || (x[i] >= upper - epsilon && g < 0.0);
            }
            let fixed = std::mem::take(&mut work.fixed);
            for i in 0..x.len() {
                work.product[i] = if fixed[i] { 0.0 } else { -work.gradient[i] };
            }
            // Reduced Newton direction d_F = −A_FF⁻¹ g_F by CG from 0 (a descent direction
            // even if stopped early).
            let rhs = std::mem::take(&mut work.product);
            let mut direction = std::mem::take(&mut work.direction);
            let target = 0.1 * tolerance * problem.scale;
            let result = self.reduced_cg(&fixed, &rhs, &mut direction, target, &mut work.cg, stats);
            work.product = rhs;
            work.direction = direction;
            result?;
            let mut newton_decrement = 0.0;
            for i in 0..x.len() {
                if fixed[i] {
                    work.direction[i] = -work.gradient[i] / self.diagonal[i];
                } else {
                    newton_decrement -= work.gradient[i] * work.direction[i];
                }
            }
            work.fixed = fixed;

            let mut step_length = 1.0;
            loop {
                // trial = clamp(x + α d), direction of travel stored in `projected`.
                let mut predicted = step_length * newton_decrement;
                for i in 0..x.len() {
                    work.trial[i] = clamp(
                        x[i] + step_length * work.direction[i],
                        problem.lower[i],
                        problem.upper[i],
                    );
                    work.projected[i] = work.trial[i] - x[i];
                    if work.fixed[i] {
                        predicted -= work.gradient[i] * work.projected[i];
                    }
                }
                multiply_into(&self.matrix, &work.projected, &mut work.product);
                let mut decrease = 0.0;
                for i in 0..x.len() {
                    decrease -= work.projected[i] * (work.gradient[i] + 0.5 * work.product[i]);
                }
                if decrease > 0.0 && decrease >= ARMIJO_SIGMA * predicted {
                    x.copy_from_slice(&work.trial);
                    break;
                }
                step_length *= 0.5;
                if step_length < MIN_STEP_LENGTH {
                    history.push(residual);
                    return Err(self.no_convergence(stats.iterations, residual, history));
                }
            }
            gradient(&self.matrix, x, problem.rhs, &mut work.gradient);
            history.push(scaled_kkt_residual(x, &work.gradient, problem));
        }
    }

    /// The fixed ε̄ of the ε-active set: a tenth of the narrowest finite box width, or, if no
    /// width is finite, a tenth of `max(1, ‖x‖_∞)`. Any fixed ε̄ > 0 gives global convergence.
    fn epsilon_bar(&self, problem: &Problem<'_>, x: &[f64]) -> f64 {
        let narrowest = problem
            .lower
            .iter()
            .zip(problem.upper)
            .map(|(lower, upper)| upper - lower)
            .filter(|width| *width > 0.0 && width.is_finite())
            .fold(f64::INFINITY, f64::min);
        if narrowest.is_finite() {
            0.1 * narrowest
        } else {
            0.1 * x.iter().fold(1.0_f64, |acc, value| acc.max(value.abs()))
        }
    }
}

/// Active set classification of (★) with `c_i = A_ii`; indices with `lower_i = upper_i` are
/// always at their (lower) bound, and an index exactly on a bound whose gradient has the wrong
/// sign by at most `problem.tie` stays at that bound (degenerate ties).
pub(super) fn classify(
    x: &[f64],
    gradient: &[f64],
    problem: &Problem<'_>,
    diagonal: &[f64],
    state: &mut [BoundStatus],
) {
    for i in 0..x.len() {
        let (lower, upper) = (problem.lower[i], problem.upper[i]);
        let trial = x[i] - gradient[i] / diagonal[i];
        state[i] =
            if lower == upper || trial < lower || (x[i] == lower && gradient[i] >= -problem.tie) {
                BoundStatus::AtLower
            } else if trial > upper || (x[i] == upper && gradient[i] <= problem.tie) {
                BoundStatus::AtUpper
            } else {
                BoundStatus::Free
            };
    }
}

pub(super) fn state_hash(state: &[BoundStatus]) -> u64 {
    let mut hasher = DefaultHasher::new();
    state.hash(&mut hasher);
    hasher.finish()
}
