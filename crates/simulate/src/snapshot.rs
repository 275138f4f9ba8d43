//! A saved step: the VTU files of Ω and Γ3, the PVD time series and `state.json` (see
//! [`crate::run`] for the files), and the fields they hold.

use crate::folder::STATE_FILE;
use crate::history::RunningSums;
use crate::problem::ProblemSetup;
use crate::resume::{ContactOutput, SavedState};
use contact_damage::fem::mesh::BoundaryPart;
use contact_damage::fem::space::{strain, LagrangeSpace, Tabulation};
use contact_damage::io::vtk::{
    write_boundary_vtu, write_pvd, write_vtu_on_grid, CellData, PointData, VtuGrid,
};
use contact_damage::model::contact::{ContactNodes, ContactStatus};
use contact_damage::model::laws::Tensor;
use contact_damage::scheme::velocity::VelocitySolution;
use contact_damage::scheme::State;
use contact_input::output::write_json_compact_atomic;
use contact_input::InputError;
use std::path::Path;

/// File name of the domain VTU of step n.
pub fn solution_file(step: usize) -> String {
    format!("solution_{step:06}.vtu")
}

/// File name of the Γ3 VTU of step n.
pub fn contact_file(step: usize) -> String {
    format!("contact_{step:06}.vtu")
}

/// Cell stress σ = 𝒜ε(v) + G(ε(u), β) (2.1) at the centroid of every cell, row-major D×D.
pub fn cell_stress<const D: usize>(
    setup: &ProblemSetup<D>,
    space: &LagrangeSpace<D>,
    state: &State,
) -> Vec<f64> {
    let model = &setup.problem.model;
    // the basis at the centroid, tabulated once for all cells
    let centroid = Tabulation::new(
        space.element(),
        vec![[1.0 / (D as f64 + 1.0); D]],
        vec![1.0],
    );
    let cells = space.mesh().num_cells();
    let mut stress = Vec::with_capacity(cells * D * D);
    for c in 0..cells {
        let (_, velocity_gradient) = space.eval_vector_tabulated(c, &centroid, 0, &state.velocity);
        let (_, displacement_gradient) =
            space.eval_vector_tabulated(c, &centroid, 0, &state.displacement);
        let (damage, _) = space.eval_scalar_tabulated(c, &centroid, 0, &state.damage);
        let sigma: Tensor<D> = model.viscosity.stress(&strain(&velocity_gradient))
            + model
                .elasticity
                .stress(&strain(&displacement_gradient), damage);
        for i in 0..D {
            for j in 0..D {
                stress.push(sigma[(i, j)]);
            }
        }
    }
    stress
}

/// What a saved step writes: the state after step n and the contact quantities of the step.
#[derive(Clone, Copy)]
pub(crate) struct SavedStep<'a, const D: usize> {
    /// The problem.
    pub setup: &'a ProblemSetup<D>,
    /// The space of the fields.
    pub space: &'a LagrangeSpace<D>,
    /// The points and cells of the space's `.vtu` files, encoded once per run.
    pub grid: &'a VtuGrid,
    /// The contact nodes of Γ3 with their frames.
    pub contact: &'a ContactNodes<D>,
    /// The state after step n.
    pub state: &'a State,
    /// The velocity step (5.1): contact status and friction multipliers.
    pub velocity: &'a VelocitySolution,
    /// p_ν per contact node as used in the step.
    pub normal_pressure: &'a [f64],
    /// The friction bound p_τ per contact node.
    pub friction_bound: &'a [f64],
    /// The running sums of the history after step n.
    pub sums: &'a RunningSums,
    /// N.
    pub steps: usize,
    /// k.
    pub time_step: f64,
}

/// Writes the files of the saved step `saved` into `dir` and appends its step to
/// `saved_steps`; `state.json` is written last, so that it names only steps whose files exist.
pub(crate) fn save_step<const D: usize>(
    dir: &Path,
    saved: &SavedStep<'_, D>,
    saved_steps: &mut Vec<usize>,
) -> Result<(), InputError> {
    let &SavedStep {
        setup,
        space,
        grid,
        contact,
        state,
        velocity,
        normal_pressure,
        friction_bound,
        sums,
        steps,
        time_step,
    } = saved;
    let n = state.step;
    let state_path = dir.join(STATE_FILE);
    // Γ3 fields on all space nodes (zero off the contact nodes)
    let nodes = space.num_nodes();
    let mut status = vec![0.0; nodes];
    let mut contact_node = vec![0.0; nodes];
    let mut pressure = vec![0.0; nodes];
    let mut tangential = vec![0.0; nodes * D];
    for (k, &node) in contact.nodes.iter().enumerate() {
        status[node] = match velocity.status[k] {
            ContactStatus::Separated => 0.0,
            ContactStatus::Stick => 1.0,
            ContactStatus::Slip => 2.0,
        };
        contact_node[node] = 1.0;
        pressure[node] = normal_pressure[k];
        for i in 0..D - 1 {
            let traction = -friction_bound[k] * velocity.multipliers[k * (D - 1) + i];
            for j in 0..D {
                tangential[node * D + j] += traction * contact.frames[k][(j, 1 + i)];
            }
        }
    }
    let stress = cell_stress(setup, space, state);
    write_vtu_on_grid(
        &dir.join(solution_file(n)),
        space,
        grid,
        &[
            PointData::Vector {
                name: "displacement",
                values: &state.displacement,
            },
            PointData::Vector {
                name: "velocity",
                values: &state.velocity,
            },
            PointData::Scalar {
                name: "damage",
                values: &state.damage,
            },
        ],
        &[CellData::Tensor {
            name: "stress",
            values: &stress,
        }],
    )?;
    write_boundary_vtu(
        &dir.join(contact_file(n)),
        space,
        BoundaryPart::Contact,
        &[
            PointData::Scalar {
                name: "status",
                values: &status,
            },
            PointData::Scalar {
                name: "contact_node",
                values: &contact_node,
            },
            PointData::Scalar {
                name: "normal_pressure",
                values: &pressure,
            },
            PointData::Vector {
                name: "tangential_traction",
                values: &tangential,
            },
            PointData::Vector {
                name: "displacement",
                values: &state.displacement,
            },
        ],
        setup.vtu,
    )?;
    saved_steps.push(n);
    let entries = |name: fn(usize) -> String| -> Vec<(f64, String)> {
        saved_steps
            .iter()
            .map(|&s| (s as f64 * time_step, name(s)))
            .collect()
    };
    write_pvd(&dir.join("solution.pvd"), &entries(solution_file))?;
    write_pvd(&dir.join("contact.pvd"), &entries(contact_file))?;
    write_json_compact_atomic(
        &state_path,
        &SavedState {
            name: setup.name.clone(),
            dim: D,
            degree: space.degree(),
            steps,
            final_time: setup.problem.final_time,
            nodes,
            saved_steps: saved_steps.clone(),
            step: n,
            time: state.time,
            displacement: state.displacement.clone(),
            velocity: state.velocity.clone(),
            damage: state.damage.clone(),
            previous_damage: state.previous_damage.clone(),
            accumulated_slip: sums.accumulated_slip.clone(),
            friction_dissipation: sums.friction_dissipation,
            viscous_dissipation: sums.viscous_dissipation,
            fingerprint: setup.fingerprint.clone(),
            output_every: Some(setup.every),
            contact_output: Some(ContactOutput::of(setup)),
        },
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::history::tests::{setup, unit_square_space};

    #[test]
    fn cell_stress_is_viscous_plus_damaged_elastic_stress() {
        let setup = setup();
        let space = unit_square_space(2);
        // affine fields: ε(u) = [[0.1, 0.05], [0.05, -0.2]], ε(v) = [[0, 0.5], [0.5, 0.3]]
        let state = State {
            step: 0,
            time: 0.0,
            displacement: space.interpolate_vector(|x| [0.1 * x[0] + 0.1 * x[1], -0.2 * x[1]]),
            velocity: space.interpolate_vector(|x| [x[1], 0.3 * x[1]]),
            damage: vec![0.6; space.num_nodes()],
            previous_damage: Vec::new(),
        };
        let stress = cell_stress(&setup, &space, &state);
        let strain = Tensor::<2>::new(0.1, 0.05, 0.05, -0.2);
        let rate = Tensor::<2>::new(0.0, 0.5, 0.5, 0.3);
        let identity = Tensor::<2>::identity();
        let expected = (rate * 2.0 * 0.5 + identity * 0.25 * rate.trace())
            + (strain * 2.0 * 2.0 + identity * 3.0 * strain.trace()) * 0.6;
        assert_eq!(stress.len(), space.mesh().num_cells() * 4);
        for sigma in stress.chunks(4) {
            for i in 0..2 {
                for j in 0..2 {
                    assert!((sigma[i * 2 + j] - expected[(i, j)]).abs() < 1e-13);
                }
            }
        }
    }
}
