//! Assembly of the velocity operator of (5.1) in the system frame: the viscous operator H, or
//! the Newton tangent at a velocity (with the tangent of the implicit normal compliance).

use super::operator::VelocityOperator;
use crate::error::Result;
use crate::scheme::assembly::viscous_element_matrix;
use faer::sparse::SparseColMat;
use nalgebra::SVector;
use rayon::prelude::*;

impl<const D: usize> VelocityOperator<D> {
    /// Assembles the (linearized) operator in the system frame, in parallel.
    pub fn assemble(&self, velocity_system: Option<&[f64]>) -> Result<SparseColMat<usize, f64>> {
        let cartesian = velocity_system.map(|v| self.to_cartesian(v));
        let n_local = self.space.nodes_per_cell() * D;
        let block = n_local * n_local;
        let n_cells = self.space.mesh().num_cells();
        let mut values = vec![0.0; self.pattern.value_count()];
        let (cell_values, constrained_values) = values.split_at_mut(n_cells * block);
        cell_values
            .par_chunks_mut(block)
            .enumerate()
            .for_each(|(cell, out)| {
                viscous_element_matrix(
                    self.law.as_ref(),
                    &self.space,
                    &self.tabulation,
                    cell,
                    cartesian.as_deref(),
                    out,
                );
                self.rotate_element_matrix(cell, out);
            });
        constrained_values.fill(1.0);
        let mut matrix = self.pattern.matrix(&values)?;
        if let (Some(implicit), Some(velocity)) = (&self.implicit, velocity_system) {
            // the tangent of the implicit normal compliance: ω_a k p_ν′(r_a + k v_ν(a))
            for (k, &node) in self.contact.nodes.iter().enumerate() {
                let dof = node * D;
                let stiffness = self.contact.weights[k]
                    * implicit.time_step
                    * implicit
                        .law
                        .normal_stiffness(implicit.penetration(k, velocity[dof]));
                add_to_diagonal(&mut matrix, dof, stiffness);
            }
        }
        Ok(matrix)
    }

    /// K ← Qᵀ K Q for the frames of the contact nodes of the cell.
    fn rotate_element_matrix(&self, cell: usize, out: &mut [f64]) {
        let nodes = self.space.cell_nodes(cell);
        let nd = nodes.len() * D;
        for (a, &node) in nodes.iter().enumerate() {
            let Some(k) = self.contact.index_of_node[node] else {
                continue;
            };
            let frame = &self.contact.frames[k];
            // rows: K[(a,·), :] ← R_aᵀ K[(a,·), :]
            for col in 0..nd {
                let old: SVector<f64, D> = SVector::from_fn(|i, _| out[(a * D + i) * nd + col]);
                let new = frame.transpose() * old;
                for i in 0..D {
                    out[(a * D + i) * nd + col] = new[i];
                }
            }
            // columns: K[:, (a,·)] ← K[:, (a,·)] R_a
            for row in 0..nd {
                let old: SVector<f64, D> = SVector::from_fn(|i, _| out[row * nd + a * D + i]);
                let new = frame.transpose() * old;
                for i in 0..D {
                    out[row * nd + a * D + i] = new[i];
                }
            }
        }
    }
}

/// matrix[(index, index)] += value (the entry is in the pattern: a node couples with itself).
fn add_to_diagonal(matrix: &mut SparseColMat<usize, f64>, index: usize, value: f64) {
    let symbolic = matrix.symbolic();
    let start = symbolic.col_ptr()[index];
    let end = symbolic.col_ptr()[index + 1];
    let position = symbolic.row_idx()[start..end]
        .iter()
        .position(|&row| row == index)
        .map(|p| start + p);
    if let Some(position) = position {
        matrix.val_mut()[position] += value;
    }
}
