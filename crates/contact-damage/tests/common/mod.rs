//! Shared builders for the integration tests.
#![allow(dead_code)]

use contact_damage::assembly::{field_strain, physical_gradients};
use contact_damage::laws::{
    DamageSourceFn, DamagedHooke, LinearViscosity, NormalComplianceCoulomb, Tensor, Viscosity,
};
use contact_damage::mesh::{BoundaryPart, Mesh};
use contact_damage::quadrature::QuadratureRule;
use contact_damage::scheme::{Data, Model, Problem, SchemeSettings};
use contact_damage::space::{LagrangeSpace, Tabulation};
use nalgebra::SVector;
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
        gap: Arc::new(|_, _| 0.0),
        dirichlet: Vec::new(),
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

/// Deterministic random data for the solver tests: proptest's ChaCha generator, seeded.
pub struct Random(proptest::test_runner::TestRng);

impl Random {
    /// The generator of `seed`.
    pub fn new(seed: u64) -> Self {
        let mut bytes = [0u8; 32];
        bytes[..8].copy_from_slice(&seed.to_le_bytes());
        Self(proptest::test_runner::TestRng::from_seed(
            proptest::test_runner::RngAlgorithm::ChaCha,
            &bytes,
        ))
    }
    /// Uniform in [0, 1).
    pub fn next(&mut self) -> f64 {
        use proptest::prelude::RngExt;
        self.0.random::<f64>()
    }
    /// Uniform in [−1, 1).
    pub fn symmetric(&mut self) -> f64 {
        2.0 * self.next() - 1.0
    }
}

/// The contact regimes of the random velocity-step data.
#[derive(Debug, Clone, Copy)]
pub enum Regime {
    /// Every contact node separated (p_ν = 0).
    NoContact,
    /// Every node in contact with a friction bound far above the tangential forces.
    AllStick,
    /// Every node in contact with a tiny friction bound.
    AllSlip,
    /// Separated, sticking and slipping nodes in turn.
    Mixed,
}

/// All regimes, indexable by a proptest strategy.
pub const REGIMES: [Regime; 4] = [
    Regime::NoContact,
    Regime::AllStick,
    Regime::AllSlip,
    Regime::Mixed,
];

/// Normal pressure and friction bound per contact node that realize `regime` for the random
/// loads of size 0.05 of the solver tests.
pub fn regime_contact_data(regime: Regime, count: usize, rng: &mut Random) -> (Vec<f64>, Vec<f64>) {
    (0..count)
        .map(|k| match regime {
            Regime::NoContact => (0.0, 0.0),
            Regime::AllStick => (1.0, 10.0 + rng.next()),
            Regime::AllSlip => (1.0, 1e-4 * (1.0 + rng.next())),
            Regime::Mixed => match k % 3 {
                0 => (0.0, 0.0),
                1 => (1.0, 10.0 * (1.0 + rng.next())),
                _ => (1.0, 1e-4 * (1.0 + rng.next())),
            },
        })
        .unzip()
}

/// N(v) (Cartesian, node-major) by this test's own quadrature loop, with the degree-2l rule
/// the solver uses for a nonlinear law.
pub fn internal_force<const D: usize>(
    space: &LagrangeSpace<D>,
    law: &dyn Viscosity<D>,
    velocity: &[f64],
) -> Vec<f64> {
    let tab = Tabulation::cell_rule(
        space.element(),
        &QuadratureRule::<D>::simplex(2 * space.degree()),
    );
    let n = tab.nodes;
    let mut force = vec![0.0; velocity.len()];
    let mut grads = vec![SVector::<f64, D>::zeros(); n];
    for cell in 0..space.mesh().num_cells() {
        let geometry = space.geometry(cell);
        let nodes = space.cell_nodes(cell);
        for q in 0..tab.weights.len() {
            physical_gradients(geometry, &tab, q, &mut grads);
            let rate = field_strain(nodes, &grads, velocity);
            let stress = law.stress(&rate) * (tab.weights[q] * geometry.det);
            for (a, &node) in nodes.iter().enumerate() {
                let traction = stress * grads[a];
                for i in 0..D {
                    force[node * D + i] += traction[i];
                }
            }
        }
    }
    force
}
