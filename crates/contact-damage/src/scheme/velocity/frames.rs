//! The system frame of the velocity step (5.1): nodal frames (ν_a, t_1, …) at the contact
//! nodes, Cartesian components elsewhere, and the prescribed velocities on Γ1.

use super::operator::VelocityOperator;
use nalgebra::SVector;

impl<const D: usize> VelocityOperator<D> {
    /// Cartesian node-major vector → system frame (frames at contact nodes, zero on the
    /// constrained unknowns).
    pub fn to_system(&self, cartesian: &[f64]) -> Vec<f64> {
        let mut system = self.rotate_to_system(cartesian);
        for (value, _) in system.iter_mut().zip(&self.constrained).filter(|(_, &c)| c) {
            *value = 0.0;
        }
        system
    }

    /// Cartesian node-major vector → system frame, keeping the constrained entries.
    pub(super) fn rotate_to_system(&self, cartesian: &[f64]) -> Vec<f64> {
        let mut system = cartesian.to_vec();
        for (k, &node) in self.contact.nodes.iter().enumerate() {
            let local = self.contact.frames[k].transpose()
                * SVector::<f64, D>::from_column_slice(&cartesian[node * D..node * D + D]);
            system[node * D..node * D + D].copy_from_slice(local.as_slice());
        }
        system
    }

    /// A start vector in the system frame: `to_system(cartesian)` with the prescribed
    /// velocities of the step on the constrained unknowns.
    pub(super) fn start_vector(&self, cartesian: &[f64]) -> Vec<f64> {
        let mut system = self.to_system(cartesian);
        for (dof, _) in self.constrained.iter().enumerate().filter(|(_, &c)| c) {
            system[dof] = self.prescribed[dof];
        }
        system
    }

    /// System frame → Cartesian node-major.
    pub fn to_cartesian(&self, system: &[f64]) -> Vec<f64> {
        let mut cartesian = system.to_vec();
        for (k, &node) in self.contact.nodes.iter().enumerate() {
            let global = self.contact.frames[k]
                * SVector::<f64, D>::from_column_slice(&system[node * D..node * D + D]);
            cartesian[node * D..node * D + D].copy_from_slice(global.as_slice());
        }
        cartesian
    }
}
