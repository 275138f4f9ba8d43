//! The outer iteration of the velocity step (5.1): the exact linear step with iterative
//! refinement, and the globalized proximal Newton method for a nonlinear 𝒜 (see the module
//! documentation of [`crate::scheme::velocity`]).

use super::operator::VelocityOperator;
use super::types::{TangentUpdate, VelocitySettings, VelocityStats};
use crate::algebra::linalg::{dot, multiply_symmetric};
use crate::error::{Error, Result};
use crate::solvers::friction::FrictionSettings;

impl<const D: usize> VelocityOperator<D> {
    /// Linear 𝒜: the model is (5.1) itself, so one exact model solve with the factor of the run
    /// solves the step; at most [`MAX_REFINEMENTS`] passes of iterative refinement follow when
    /// round-off leaves the KKT residual above the tolerance.
    pub(super) fn solve_linear(
        &mut self,
        load: &[f64],
        weights: &[f64],
        start: &[f64],
        settings: &VelocitySettings,
    ) -> Result<(Vec<f64>, Vec<f64>, VelocityStats)> {
        let mut stats = VelocityStats::default();
        let mut multipliers = vec![0.0; self.contact.len() * (D - 1)];
        let mut velocity = self.start_vector(start);
        let mut history: Vec<f64> = Vec::new();
        self.restore_plain_trailing();
        if !self.matrix_is_plain {
            // a Newton tangent (implicit contact) replaced the operator of the run
            self.matrix = self.assemble(None)?;
            self.matrix_is_plain = true;
            self.factorize()?;
            stats.factorizations += 1;
        }
        loop {
            stats.newton_iterations += 1;
            if !self.solver.is_factorized() {
                self.factorize()?;
                stats.factorizations += 1;
            }
            self.prepare_condensation(weights)?;
            let refinement = stats.newton_iterations > 1;
            // A refinement pass also asks the condensed friction problem for more digits: its
            // residual is relative to its own right-hand side r_c, which can exceed the forces
            // of (5.1) by orders of magnitude (r_c is the force that would stop all sliding),
            // so its default tolerance can leave the full KKT residual above `tolerance`.
            let mut friction_settings = settings.friction;
            let (rhs, base) = if let (true, Some(&reached)) = (refinement, history.last()) {
                friction_settings.tolerance = (friction_settings.tolerance
                    * (0.1 * settings.tolerance / reached))
                    .clamp(MIN_FRICTION_TOLERANCE, friction_settings.tolerance);
                let hv = multiply_symmetric(&self.matrix, &velocity);
                let residual: Vec<f64> = load.iter().zip(&hv).map(|(b, h)| b - h).collect();
                (residual, Some(velocity.as_slice()))
            } else {
                (load.to_vec(), None)
            };
            let trial = self.solve_model(
                &rhs,
                weights,
                &velocity,
                base,
                &mut multipliers,
                &friction_settings,
                &mut stats,
            );
            velocity = match trial {
                Ok(trial) => trial,
                // a refinement pass whose friction problem stagnates at the rounding level
                // ends the step with the velocity residual reached so far
                Err(Error::NoConvergence { .. }) if refinement => {
                    return Err(Error::NoConvergence {
                        solver: "velocity step (5.1), linear viscosity (with iterative refinement; the condensed friction problem reached its rounding level)",
                        iterations: stats.newton_iterations,
                        residual: stats.kkt_residual,
                        tolerance: settings.tolerance,
                        history: crate::error::History(history),
                    })
                }
                Err(error) => return Err(error),
            };
            stats.kkt_residual = self.kkt_residual(load, weights, &velocity, &multipliers);
            history.push(stats.kkt_residual);
            if stats.kkt_residual <= settings.tolerance {
                break;
            }
            if stats.newton_iterations > MAX_REFINEMENTS {
                return Err(Error::NoConvergence {
                    solver: "velocity step (5.1), linear viscosity (with iterative refinement)",
                    iterations: stats.newton_iterations,
                    residual: stats.kkt_residual,
                    tolerance: settings.tolerance,
                    history: crate::error::History(history),
                });
            }
        }
        stats.residual_history = history;
        Ok((velocity, multipliers, stats))
    }

    /// Nonlinear 𝒜: globalized proximal Newton, see the module documentation. Stops when the
    /// KKT residual of the iterate (multipliers from [`Self::best_multipliers`]) is at most
    /// `NEWTON_HEADROOM × tolerance`; the reported residual is that same number.
    pub(super) fn solve_nonlinear(
        &mut self,
        load: &[f64],
        weights: &[f64],
        start: &[f64],
        settings: &VelocitySettings,
    ) -> Result<(Vec<f64>, Vec<f64>, VelocityStats)> {
        let mut stats = VelocityStats::default();
        if self.law.is_linear()
            && self.implicit.is_some()
            && self.normals_last
            && !(self.matrix_is_plain && self.solver.is_factorized())
        {
            // the factor of H, kept for the whole run: the Newton tangents change the contact
            // block only
            self.factorize_viscous()?;
            stats.factorizations += 1;
        }
        let target = settings.tolerance * NEWTON_HEADROOM;
        let mut velocity = self.start_vector(start);
        let mut point = self.evaluate(load, weights, &velocity);
        if self.law.is_linear() && self.implicit.is_some() && start.iter().any(|&v| v != 0.0) {
            // A load that stops — the step at rest of a static contact problem solved with
            // k = τ — is met by v = 0 (u_n = u_{n−1}) far better than by the previous velocity,
            // which would move the body on and let Newton walk it back: start from whichever
            // of the two has the lower J (one more evaluation).
            let rest = self.start_vector(&vec![0.0; start.len()]);
            let at_rest = self.evaluate(load, weights, &rest);
            let change = at_rest
                .cell_energy
                .iter()
                .zip(&point.cell_energy)
                .map(|(r, s)| r - s)
                .sum::<f64>()
                - (dot(load, &rest) - dot(load, &velocity))
                + self.friction_term(weights, &rest)
                - self.friction_term(weights, &velocity);
            if change < 0.0 {
                velocity = rest;
                point = at_rest;
            }
        }
        let mut model_multipliers = point.multipliers.clone();
        let mut history: Vec<f64> = Vec::new();
        let mut best = point.residual;
        let failure =
            |stats: &VelocityStats, history: &[f64], solver: &'static str| Error::NoConvergence {
                solver,
                iterations: stats.newton_iterations,
                residual: history.last().copied().unwrap_or(f64::INFINITY),
                tolerance: target,
                history: crate::error::History(history.to_vec()),
            };
        while point.residual > target {
            if stats.newton_iterations >= settings.max_newton {
                if point.residual <= settings.tolerance {
                    break; // the certificate holds; the head room was not reached in time
                }
                return Err(failure(
                    &stats,
                    &history,
                    "velocity step (5.1), proximal Newton (iteration limit)",
                ));
            }
            stats.newton_iterations += 1;
            let stale = self.linearized_at.as_deref() != Some(velocity.as_slice());
            let refresh = stale
                && match settings.tangent {
                    TangentUpdate::Newton => true,
                    // keep a tangent of this law (not H, not after a reset) while it contracts,
                    // and go over to exact Newton in a step that has used half its iterations
                    TangentUpdate::Frozen => {
                        self.law.is_linear()
                            || self.matrix_is_plain
                            || self.linearized_at.is_none()
                            || self.frozen_contraction > FAST_REDUCTION
                            || 2 * stats.newton_iterations > settings.max_newton
                    }
                };
            if refresh {
                if self.linearize_contact_in_trailing(&velocity)? {
                    // linear 𝒜, implicit contact: only the contact block changes
                    stats.contact_block_factorizations += 1;
                } else {
                    self.matrix = self.assemble(Some(&velocity))?;
                    self.matrix_is_plain = false;
                    self.factorize()?;
                    stats.factorizations += 1;
                }
                self.linearized_at = Some(velocity.clone());
            }
            self.prepare_condensation(weights)?;
            // the Newton model around v in increment form: b − Hv = F − N(v)
            // (zero on the constrained unknowns: the iterates keep v_c = p_c)
            let minus_gradient: Vec<f64> = load
                .iter()
                .zip(&point.force)
                .zip(&self.constrained)
                .map(|((f, n), &c)| if c { 0.0 } else { f - n })
                .collect();
            let mut friction_settings = settings.friction;
            friction_settings.tolerance = (friction_settings.tolerance * NEWTON_HEADROOM)
                .max(MIN_FRICTION_TOLERANCE)
                .min(settings.friction.tolerance);
            let mut solve = |friction_settings: &FrictionSettings, stats: &mut VelocityStats| {
                self.solve_model(
                    &minus_gradient,
                    weights,
                    &velocity,
                    Some(&velocity),
                    &mut model_multipliers,
                    friction_settings,
                    stats,
                )
            };
            let trial = match solve(&friction_settings, &mut stats) {
                Ok(trial) => trial,
                // the tighter friction tolerance can lie below the rounding level of a
                // badly conditioned S: retry with the configured one
                Err(Error::NoConvergence { .. }) => solve(&settings.friction, &mut stats)?,
                Err(error) => return Err(error),
            };
            let direction: Vec<f64> = trial.iter().zip(&velocity).map(|(t, v)| t - v).collect();
            let friction_now = self.friction_term(weights, &velocity);
            let predicted = -dot(&minus_gradient, &direction) + self.friction_term(weights, &trial)
                - friction_now;
            let load_along = dot(load, &direction);
            let mut step = 1.0;
            let mut accepted = None;
            for _ in 0..MAX_BACKTRACKS {
                let candidate: Vec<f64> = if step == 1.0 {
                    trial.clone()
                } else {
                    velocity
                        .iter()
                        .zip(&direction)
                        .map(|(v, d)| v + step * d)
                        .collect()
                };
                let evaluated = self.evaluate(load, weights, &candidate);
                // J(candidate) − J(v), summed cell by cell against cancellation
                let decrease = evaluated
                    .cell_energy
                    .iter()
                    .zip(&point.cell_energy)
                    .map(|(new, old)| new - old)
                    .sum::<f64>()
                    - step * load_along
                    + self.friction_term(weights, &candidate)
                    - friction_now;
                if evaluated.residual <= FAST_REDUCTION * best
                    || decrease <= ARMIJO * step * predicted.min(0.0) && predicted < 0.0
                {
                    accepted = Some((candidate, evaluated));
                    break;
                }
                step *= 0.5;
            }
            let Some((next, evaluated)) = accepted else {
                if point.residual <= settings.tolerance {
                    break; // rounding level reached below the certificate
                }
                return Err(failure(
                    &stats,
                    &history,
                    "velocity step (5.1), proximal Newton (no step decreases the KKT residual or J: rounding level)",
                ));
            };
            self.frozen_contraction = evaluated.residual / point.residual;
            velocity = next;
            point = evaluated;
            history.push(point.residual);
            best = best.min(point.residual);
        }
        stats.kkt_residual = point.residual;
        stats.residual_history = history;
        Ok((velocity, point.multipliers, stats))
    }

    /// Cell energies, internal force, the best multipliers and the KKT residual at v.
    fn evaluate(&self, load: &[f64], weights: &[f64], velocity: &[f64]) -> Iterate {
        let (cell_energy, force) = self.energy_and_force(velocity);
        let multipliers = self.best_multipliers(load, weights, velocity, &force);
        let residual = self.kkt_residual_with_force(load, weights, velocity, &multipliers, &force);
        Iterate {
            cell_energy,
            force,
            multipliers,
            residual,
        }
    }
}

/// Passes of iterative refinement allowed after the exact solve of a linear velocity step.
const MAX_REFINEMENTS: usize = 3;
/// A nonlinear step iterates to `NEWTON_HEADROOM × tolerance` (1e-12 for the default 1e-10
/// certificate), so that the certificate holds with two digits to spare.
pub const NEWTON_HEADROOM: f64 = 1e-2;
/// A Newton step (full or damped) is accepted when it lowers the best KKT residual so far by
/// this factor (the region of fast convergence), whatever it does to J.
const FAST_REDUCTION: f64 = 0.5;
/// Armijo constant σ of the sufficient decrease J(v + αd) ≤ J(v) + σ α Δ.
const ARMIJO: f64 = 1e-4;
/// Halvings of the step before the line search gives up (2^-40 ≈ 1e-12).
const MAX_BACKTRACKS: usize = 41;

/// J's cell energies, the internal force, the best multipliers and the KKT residual at an
/// iterate of the nonlinear velocity step.
struct Iterate {
    cell_energy: Vec<f64>,
    force: Vec<f64>,
    multipliers: Vec<f64>,
    residual: f64,
}
/// Smallest tolerance a refinement pass asks of the condensed friction problem (relative to
/// its right-hand side; its rounding level is about ε κ(S)).
const MIN_FRICTION_TOLERANCE: f64 = 1e-15;
