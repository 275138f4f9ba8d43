//! The KKT residual of the velocity step (5.1) and the multipliers that satisfy its KKT
//! conditions best at a given velocity (the merit function of the nonlinear iteration).

use super::operator::VelocityOperator;
use crate::algebra::linalg::{max_abs, max_abs_free, multiply_symmetric};

impl<const D: usize> VelocityOperator<D> {
    /// Relative KKT residual of (5.1) for (v, λ) on the free unknowns:
    /// max of ‖N(v) − F + E_c W λ‖_∞ / max(‖F‖_∞, ‖N(v)‖_∞, ‖E_c W λ‖_∞) (stationarity,
    /// relative to the largest of the forces it balances; on a constrained unknown the entry
    /// is |v_c − p_c| instead), max_a (|λ_a| − 1)₊ (dual
    /// feasibility) and max over slipping nodes of |λ_a − v_τ(a)/|v_τ(a)||
    /// (complementarity); stick nodes have v_τ(a) = 0 exactly.
    ///
    /// The stationarity is scaled by all three forces, not by F alone: F (the loads minus the
    /// elastic forces of u_{n−1}) can be a small difference of large terms while the viscous
    /// and friction forces that balance it are large, and the rounding error of N(v) is
    /// relative to those (seen on an unstructured 3D mesh: ‖F‖_∞ = 2e-3 against forces ≈ 1.5).
    pub fn kkt_residual(
        &self,
        load_system: &[f64],
        weights: &[f64],
        velocity_system: &[f64],
        multipliers: &[f64],
    ) -> f64 {
        let force = if self.law.is_linear() && self.implicit.is_none() && self.matrix_is_plain {
            // H_ff v_f on the free rows (the load is lifted)
            multiply_symmetric(&self.matrix, velocity_system)
        } else {
            self.energy_and_force(velocity_system).1
        };
        self.kkt_residual_with_force(load_system, weights, velocity_system, multipliers, &force)
    }

    /// [`Self::kkt_residual`] with the internal force N(v) (system frame) already known. The
    /// scale takes the load and the internal force on the free unknowns, the friction forces
    /// and the force K_fc p_c of the prescribed velocities on the free unknowns (zero for the
    /// paper's u = 0 on Γ1; without it a body moved by its support alone would have no scale).
    pub(super) fn kkt_residual_with_force(
        &self,
        load_system: &[f64],
        weights: &[f64],
        velocity_system: &[f64],
        multipliers: &[f64],
        force: &[f64],
    ) -> f64 {
        let mut residual: Vec<f64> = force.iter().zip(load_system).map(|(n, f)| n - f).collect();
        let load_scale = max_abs_free(load_system, &self.constrained);
        let force_scale = max_abs_free(force, &self.constrained).max(self.lifting_scale);
        for (dof, _) in self.constrained.iter().enumerate().filter(|(_, &c)| c) {
            residual[dof] = velocity_system[dof] - self.prescribed[dof];
        }
        let g = D - 1;
        let mut worst: f64 = 0.0;
        for (k, &node) in self.contact.nodes.iter().enumerate() {
            let lambda = &multipliers[k * g..(k + 1) * g];
            for i in 0..g {
                if !self.constrained[node * D + 1 + i] {
                    residual[node * D + 1 + i] += weights[k] * lambda[i];
                }
            }
            let norm = lambda.iter().map(|l| l * l).sum::<f64>().sqrt();
            worst = worst.max(norm - 1.0);
            let tangential: Vec<f64> = (0..g).map(|i| velocity_system[node * D + 1 + i]).collect();
            let speed = tangential.iter().map(|t| t * t).sum::<f64>().sqrt();
            if speed > 0.0 && weights[k] > 0.0 {
                for i in 0..g {
                    worst = worst.max((lambda[i] - tangential[i] / speed).abs());
                }
            }
        }
        let friction_force = (0..self.contact.len())
            .map(|k| weights[k] * max_abs(&multipliers[k * g..(k + 1) * g]))
            .fold(0.0f64, f64::max);
        let scale = load_scale
            .max(force_scale)
            .max(friction_force)
            .max(f64::MIN_POSITIVE);
        let stationarity = max_abs(&residual) / scale;
        stationarity.max(worst)
    }

    /// The multipliers that satisfy the KKT conditions of (5.1) best at a given v: at a node that
    /// slips, λ_a = v_τ(a)/|v_τ(a)| (complementarity fixes it); at a node with v_τ(a) = 0, the
    /// projection of −(N(v) − F)_τ(a)/w_a onto the unit ball (the λ of the subdifferential closest
    /// to balancing the forces). With them, dual feasibility and complementarity hold exactly,
    /// and the KKT residual is the stationarity alone: a function of v, used as merit function.
    pub fn best_multipliers(
        &self,
        load_system: &[f64],
        weights: &[f64],
        velocity_system: &[f64],
        force_system: &[f64],
    ) -> Vec<f64> {
        let g = D - 1;
        let mut multipliers = vec![0.0; self.contact.len() * g];
        for (k, &node) in self.contact.nodes.iter().enumerate() {
            if weights[k] <= 0.0 {
                continue;
            }
            let lambda = &mut multipliers[k * g..(k + 1) * g];
            let tangential = &velocity_system[node * D + 1..node * D + D];
            let speed = tangential.iter().map(|t| t * t).sum::<f64>().sqrt();
            if speed > 0.0 {
                for (l, t) in lambda.iter_mut().zip(tangential) {
                    *l = t / speed;
                }
            } else {
                for (i, l) in lambda.iter_mut().enumerate() {
                    let dof = node * D + 1 + i;
                    // a tangent fixed by Γ1 takes its force as a reaction, not as friction
                    if !self.constrained[dof] {
                        *l = -(force_system[dof] - load_system[dof]) / weights[k];
                    }
                }
                let norm = lambda.iter().map(|l| l * l).sum::<f64>().sqrt();
                if norm > 1.0 {
                    lambda.iter_mut().for_each(|l| *l /= norm);
                }
            }
        }
        multipliers
    }
}
