//! The globalized iteration of the friction solver of (5.1): semismooth Newton steps accepted
//! by the merit function J, bursts of proximal-gradient steps when Newton makes no progress,
//! and the stagnation test at the rounding level.

use super::blocks::block_norm;
use super::newton_system::NewtonCache;
use super::objective::Problem;
use super::proximal_gradient::Lipschitz;
use super::settings::{FrictionSettings, FrictionStats};
use crate::error::History;
use crate::error::{Error, Result};

/// Armijo constant η of the Newton line search.
const ARMIJO: f64 = 1e-4;
/// Smallest Newton step length tried before falling back to proximal-gradient steps.
const MIN_STEP: f64 = 1.0 / 1024.0;
/// Length of the first burst of proximal-gradient steps; it doubles while Newton makes no
/// progress, up to [`MAX_BURST`], and is reset after a successful Newton step.
const INITIAL_BURST: usize = 10;
/// Largest burst of proximal-gradient steps between two Newton attempts.
const MAX_BURST: usize = 640;
/// Consecutive Newton-plus-burst cycles without any improvement of J (beyond its rounding band)
/// or of the KKT residual after which the solver reports that it stagnated at the rounding level.
const STALL_LIMIT: usize = 5;

impl Problem<'_> {
    /// Solves in place from the start `x`, with the multipliers λ into `multipliers` (see
    /// [`CondensedFriction::solve`](super::CondensedFriction::solve)).
    pub(super) fn solve(
        &self,
        x: &mut [f64],
        multipliers: &mut [f64],
        settings: &FrictionSettings,
    ) -> Result<FrictionStats> {
        let m = self.dimension();
        let tolerance = settings.tolerance;
        let mut sx = vec![0.0; m];
        self.apply(x, &mut sx);
        let mut energy = self.energy(x, &sx);
        let mut report = self.kkt(x, &sx);
        let mut history = vec![report.max()];
        let mut stats = FrictionStats::default();
        let mut lipschitz: Option<Lipschitz> = None;
        let mut burst = INITIAL_BURST;
        let mut candidate = vec![0.0; m];
        let mut candidate_image = vec![0.0; m];
        let mut trial = vec![0.0; m];
        let mut trial_image = vec![0.0; m];
        let mut best_residual = report.max();
        let mut best_energy = energy.value;
        let mut stalled_cycles = 0;
        let mut newton_cache = NewtonCache::default();
        while report.max() > tolerance {
            let exhausted = stats.newton_iterations >= settings.max_newton
                && stats.gradient_iterations >= settings.max_gradient;
            if exhausted || stalled_cycles >= STALL_LIMIT {
                return Err(Error::NoConvergence {
                    solver: if exhausted {
                        "friction semismooth Newton / FISTA"
                    } else {
                        "friction semismooth Newton / FISTA (stagnated at the rounding level)"
                    },
                    iterations: stats.newton_iterations + stats.gradient_iterations,
                    residual: report.max(),
                    tolerance,
                    history: History(history),
                });
            }
            let mut progress = false;
            if stats.newton_iterations < settings.max_newton {
                stats.newton_iterations += 1;
                self.newton_point(x, &sx, &mut candidate, &mut newton_cache)?;
                self.apply(&candidate, &mut candidate_image);
                let slope = self.directional_derivative(x, &sx, &candidate);
                // The full step first: by Armijo, or by the rounding clause (J flat to
                // rounding, but the residual at least halves: near the solution the decrease
                // of J falls below its rounding error).
                let full_energy = self.energy(&candidate, &candidate_image);
                let band = self.rounding_band(energy.magnitude + full_energy.magnitude);
                let full_step = (slope < 0.0 && full_energy.value <= energy.value + ARMIJO * slope)
                    || (full_energy.value <= energy.value + band
                        && self.kkt(&candidate, &candidate_image).max() <= 0.5 * report.max());
                let mut accepted = None;
                if full_step {
                    trial.copy_from_slice(&candidate);
                    trial_image.copy_from_slice(&candidate_image);
                    accepted = Some((1.0, full_energy));
                } else if slope < 0.0 {
                    // Damped steps count only with a decrease of J beyond its rounding band:
                    // an Armijo test whose slope is at the rounding level accepts noise, and a
                    // damped step in place of a full one that would have converged stalls
                    // Newton (it was the cause of most proximal-gradient bursts in 3D).
                    let mut step = 0.5;
                    while step >= MIN_STEP {
                        for i in 0..m {
                            trial[i] = x[i] + step * (candidate[i] - x[i]);
                            trial_image[i] = sx[i] + step * (candidate_image[i] - sx[i]);
                        }
                        let trial_energy = self.energy(&trial, &trial_image);
                        let band = self.rounding_band(energy.magnitude + trial_energy.magnitude);
                        if trial_energy.value <= energy.value + ARMIJO * step * slope
                            && trial_energy.value < energy.value - band
                        {
                            accepted = Some((step, trial_energy));
                            break;
                        }
                        step *= 0.5;
                    }
                }
                if let Some((step, trial_energy)) = accepted {
                    x.copy_from_slice(&trial);
                    sx.copy_from_slice(&trial_image);
                    energy = trial_energy;
                    let previous = report.max();
                    report = self.kkt(x, &sx);
                    progress = step == 1.0 && report.max() <= 0.5 * previous;
                }
                history.push(report.max());
            }
            if progress {
                burst = INITIAL_BURST;
            } else if report.max() > tolerance && stats.gradient_iterations < settings.max_gradient
            {
                let lipschitz = lipschitz.get_or_insert_with(|| self.lipschitz());
                let steps = burst.min(settings.max_gradient - stats.gradient_iterations);
                stats.gradient_iterations += self.gradient_burst(
                    x,
                    &mut sx,
                    &mut energy,
                    &mut report,
                    lipschitz,
                    steps,
                    tolerance,
                );
                history.push(report.max());
                burst = (2 * burst).min(MAX_BURST);
            }
            // Stagnation: neither J (beyond its rounding band) nor the residual improved.
            let band = self.rounding_band(energy.magnitude);
            if report.max() < (1.0 - 1e-3) * best_residual || energy.value < best_energy - band {
                stalled_cycles = 0;
            } else {
                stalled_cycles += 1;
            }
            best_residual = best_residual.min(report.max());
            best_energy = best_energy.min(energy.value);
        }
        self.multipliers(x, &sx, multipliers);
        for (block, &w) in x.chunks_exact(self.group).zip(self.weights) {
            if w == 0.0 {
                stats.free += 1;
            } else if block_norm(block) > 0.0 {
                stats.slip += 1;
            } else {
                stats.stick += 1;
            }
        }
        stats.kkt_residual = report.natural;
        stats.stationarity = report.stationarity;
        stats.dual_infeasibility = report.dual_infeasibility;
        Ok(stats)
    }
}
