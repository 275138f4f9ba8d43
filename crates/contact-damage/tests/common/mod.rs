//! Shared builders for the integration tests.
#![allow(dead_code)]

use contact_damage::laws::{
    DamageSourceFn, DamagedHooke, LinearViscosity, NormalComplianceCoulomb, Tensor,
};
use contact_damage::mesh::{BoundaryPart, Mesh};
use contact_damage::scheme::{Data, Model, Problem, SchemeSettings};
use std::sync::Arc;

/// The default model of the tests: linear viscosity, damaged Hooke, a smooth damage source.
pub fn model<const D: usize>() -> Model<D> {
    Model {
        viscosity: Arc::new(LinearViscosity {
            shear: 1.0,
            bulk: 0.5,
        }),
        elasticity: Arc::new(DamagedHooke {
            shear_modulus: 1.0,
            lame_lambda: 1.0,
        }),
        damage_source: Arc::new(DamageSourceFn(|strain: &Tensor<D>, beta: f64| {
            0.1 * (1.0 - beta) - 0.5 * strain.norm_squared()
        })),
        contact: Arc::new(NormalComplianceCoulomb {
            stiffness: 10.0,
            friction: 0.4,
            wear: 0.0,
        }),
        damage_diffusion: 0.1,
    }
}

/// Data with no loads, zero gap, u0 = 0, β0 = 1.
pub fn quiet_data<const D: usize>() -> Data<D> {
    Data {
        body_force: None,
        traction: None,
        contact_traction: None,
        damage_supply: None,
        damage_flux: None,
        gap: Arc::new(|_| 0.0),
        initial_displacement: Arc::new(|_| [0.0; D]),
        initial_damage: Arc::new(|_| 1.0),
    }
}

/// A problem on a box mesh.
pub fn problem<const D: usize>(
    mesh: Mesh<D>,
    degree: usize,
    data: Data<D>,
    final_time: f64,
    steps: usize,
) -> Problem<D> {
    Problem {
        mesh: Arc::new(mesh),
        degree,
        model: model(),
        data,
        final_time,
        steps,
        settings: SchemeSettings::default(),
    }
}

/// Unit square with Γ1 = {x = 0}, Γ3 = {y = 0}, Γ2 elsewhere.
pub fn square(cells: usize) -> Mesh<2> {
    use BoundaryPart::*;
    Mesh::box_mesh(
        [0.0, 0.0],
        [1.0, 1.0],
        [cells, cells],
        [[Dirichlet, Neumann], [Contact, Neumann]],
    )
    .unwrap()
}

/// Unit cube with Γ1 = {x = 0}, Γ3 = {z = 0}, Γ2 elsewhere.
pub fn cube(cells: usize) -> Mesh<3> {
    use BoundaryPart::*;
    Mesh::box_mesh(
        [0.0; 3],
        [1.0; 3],
        [cells; 3],
        [[Dirichlet, Neumann], [Neumann, Neumann], [Contact, Neumann]],
    )
    .unwrap()
}

/// A box mesh whose interior vertices are moved by a deterministic pseudo-random amount
/// (at most `amount` times the grid spacing), keeping the boundary flat.
pub fn distorted<const D: usize>(mesh: &Mesh<D>, spacing: f64, amount: f64) -> Mesh<D> {
    let mut seed: u64 = 0x9E3779B97F4A7C15;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let vertices: Vec<[f64; D]> = mesh
        .vertices()
        .iter()
        .map(|p| {
            let interior = p.iter().all(|&c| c > 1e-12 && c < 1.0 - 1e-12);
            std::array::from_fn(|i| {
                if interior {
                    p[i] + 2.0 * amount * spacing * next()
                } else {
                    p[i]
                }
            })
        })
        .collect();
    let cells: Vec<usize> = (0..mesh.num_cells())
        .flat_map(|c| mesh.cell(c).to_vec())
        .collect();
    let facets: Vec<usize> = (0..mesh.num_facets())
        .flat_map(|f| mesh.facet(f).to_vec())
        .collect();
    let parts: Vec<BoundaryPart> = (0..mesh.num_facets()).map(|f| mesh.facet_part(f)).collect();
    Mesh::new(vertices, cells, facets, parts).unwrap()
}
