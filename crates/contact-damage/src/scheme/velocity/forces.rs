//! Internal forces and energies of the velocity step (5.1): ⟨𝒜ε(v), ε(φ)⟩ and ∫ Φ(ε(v)) cell
//! by cell (with the implicit normal compliance), the friction term Σ_a w_a |v_τ(a)|, and the
//! reactions on the constrained unknowns.

use super::operator::VelocityOperator;
use crate::error::{Error, Result};
use nalgebra::SVector;
use rayon::prelude::*;

impl<const D: usize> VelocityOperator<D> {
    /// ⟨𝒜ε(v), ε(φ_a e_i)⟩ (Cartesian) summed over the cells that carry a constrained unknown
    /// only: exact on the constrained unknowns, and exact everywhere for a v that vanishes
    /// outside those cells (the lifting K p of the prescribed velocities, linear 𝒜).
    pub(super) fn constrained_cell_force(&self, velocity_cartesian: &[f64]) -> Vec<f64> {
        let n_local = self.space.nodes_per_cell() * D;
        let tab = &self.tabulation;
        let n = tab.nodes;
        let mut locals = vec![0.0; self.constrained_cells.len() * n_local];
        locals
            .par_chunks_mut(n_local)
            .zip(&self.constrained_cells)
            .for_each(|(out, &cell)| {
                let nodes = self.space.cell_nodes(cell);
                let mut grads = [SVector::<f64, D>::zeros(); crate::fem::element::MAX_CELL_NODES];
                for q in 0..tab.len() {
                    let geometry = self.space.geometry_at(cell, &tab.points[q]);
                    crate::scheme::assembly::physical_gradients(&geometry, tab, q, &mut grads);
                    let rate = crate::scheme::assembly::field_strain(
                        nodes,
                        &grads[..n],
                        velocity_cartesian,
                    );
                    let stress = self.law.stress(&rate) * (tab.weights[q] * geometry.det);
                    for a in 0..n {
                        let traction = stress * grads[a];
                        for i in 0..D {
                            out[a * D + i] += traction[i];
                        }
                    }
                }
            });
        let mut force = vec![0.0; self.size()];
        for (chunk, &cell) in locals.chunks(n_local).zip(&self.constrained_cells) {
            for (a, &node) in self.space.cell_nodes(cell).iter().enumerate() {
                for i in 0..D {
                    force[node * D + i] += chunk[a * D + i];
                }
            }
        }
        force
    }

    /// Reactions R_c = ⟨𝒜ε(v), ε(φ_c)⟩ − F_c on the constrained Cartesian unknowns (Cartesian
    /// load and velocity; zero on the free unknowns): the residual of the equilibrium there. At
    /// a contact node on a symmetry plane the contact and friction forces are normal to the
    /// fixed axis, so the residual along it is the reaction alone.
    pub fn reactions(&self, load_cartesian: &[f64], velocity_cartesian: &[f64]) -> Vec<f64> {
        let mut reaction = self.constrained_cell_force(velocity_cartesian);
        for ((r, f), &c) in reaction
            .iter_mut()
            .zip(load_cartesian)
            .zip(&self.constrained_cartesian)
        {
            *r = if c { *r - f } else { 0.0 };
        }
        reaction
    }

    /// The cell energies ∫_K Φ(ε(v)) dx and the internal force vector ⟨𝒜ε(v), ε(φ_a e_i)⟩ in
    /// the system frame (on every unknown, constrained ones included).
    pub(super) fn energy_and_force(&self, velocity_system: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let cartesian = self.to_cartesian(velocity_system);
        let n_local = self.space.nodes_per_cell() * D;
        let n_cells = self.space.mesh().num_cells();
        let tab = &self.tabulation;
        let n = tab.nodes;
        let mut locals = vec![0.0; n_cells * (n_local + 1)];
        locals
            .par_chunks_mut(n_local + 1)
            .enumerate()
            .for_each(|(cell, out)| {
                let nodes = self.space.cell_nodes(cell);
                let mut grads = [SVector::<f64, D>::zeros(); crate::fem::element::MAX_CELL_NODES];
                for q in 0..tab.len() {
                    let geometry = self.space.geometry_at(cell, &tab.points[q]);
                    crate::scheme::assembly::physical_gradients(&geometry, tab, q, &mut grads);
                    let rate =
                        crate::scheme::assembly::field_strain(nodes, &grads[..n], &cartesian);
                    let weight = tab.weights[q] * geometry.det;
                    out[n_local] += weight * self.law.potential(&rate);
                    let stress = self.law.stress(&rate) * weight;
                    for a in 0..n {
                        let traction = stress * grads[a];
                        for i in 0..D {
                            out[a * D + i] += traction[i];
                        }
                    }
                }
            });
        let mut force = vec![0.0; self.size()];
        let mut energy = vec![0.0; n_cells];
        for (cell, chunk) in locals.chunks(n_local + 1).enumerate() {
            energy[cell] = chunk[n_local];
            for (a, &node) in self.space.cell_nodes(cell).iter().enumerate() {
                for i in 0..D {
                    force[node * D + i] += chunk[a * D + i];
                }
            }
        }
        let mut force = self.rotate_to_system(&force);
        if let Some(implicit) = &self.implicit {
            // Σ_a ω_a P(r_a + k v_ν(a))/k and its gradient ω_a p_ν(r_a + k v_ν(a)) e_ν
            for (k, &node) in self.contact.nodes.iter().enumerate() {
                let penetration = implicit.penetration(k, velocity_system[node * D]);
                let weight = self.contact.weights[k];
                energy.push(weight * implicit.law.normal_energy(penetration) / implicit.time_step);
                force[node * D] += weight * implicit.law.normal_pressure(penetration);
            }
        }
        (energy, force)
    }

    /// The weights w_a = ω_a μ p_ν of the friction term at the contact nodes. A node whose
    /// tangential components are all fixed by Γ1 has weight 0: its friction acts on fixed
    /// unknowns only and enters the reaction there. Error: a node with one of two tangents fixed
    /// to a nonzero velocity and a positive friction bound (the friction term would couple the
    /// free tangent with a moving constraint; a symmetry plane, velocity 0, is exact).
    pub(super) fn friction_weights(&self, friction_bound: &[f64]) -> Result<Vec<f64>> {
        let mut weights: Vec<f64> = self
            .contact
            .weights
            .iter()
            .zip(friction_bound)
            .map(|(w, s)| w * s)
            .collect();
        for (k, &node) in self.contact.nodes.iter().enumerate() {
            let fixed = &self.constrained[node * D + 1..node * D + D];
            if !fixed.contains(&true) {
                continue;
            }
            if fixed.iter().all(|&f| f) {
                weights[k] = 0.0;
                continue;
            }
            let moving = (1..D)
                .any(|i| self.constrained[node * D + i] && self.prescribed[node * D + i] != 0.0);
            if moving && weights[k] > 0.0 {
                return Err(Error::InvalidInput(format!(
                    "contact node {node} at {:?}: Γ1 moves a tangential component of a node in \
                     frictional contact (a moving roller across Γ3); only a fixed roller or \
                     symmetry plane (zero prescribed displacement) may cut the contact zone",
                    self.space.node(node)
                )));
            }
        }
        Ok(weights)
    }

    pub(super) fn friction_term(&self, weights: &[f64], velocity_system: &[f64]) -> f64 {
        self.contact
            .nodes
            .iter()
            .zip(weights)
            .map(|(&node, w)| {
                w * velocity_system[node * D + 1..node * D + D]
                    .iter()
                    .map(|t| t * t)
                    .sum::<f64>()
                    .sqrt()
            })
            .sum()
    }
}
