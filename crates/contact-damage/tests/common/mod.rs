//! Shared builders for the integration tests.
#![allow(dead_code)]

use contact_damage::fem::mesh::{BoundaryPart, Mesh};
use contact_damage::fem::quadrature::QuadratureRule;
use contact_damage::fem::space::{LagrangeSpace, Tabulation};
use contact_damage::model::contact::ContactNodes;
use contact_damage::model::laws::{
    DamageSourceFn, DamagedHooke, LinearViscosity, NormalComplianceCoulomb, Tensor, Viscosity,
};
use contact_damage::scheme::assembly::{field_strain, physical_gradients};
use contact_damage::scheme::{Data, Model, Problem, SchemeSettings};
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
        body_stress: None,
        traction: None,
        contact_traction: None,
        damage_supply: None,
        damage_flux: None,
        gap: Arc::new(|_, _| 0.0),
        dirichlet: Vec::new(),
        initial_displacement: Arc::new(|_| [0.0; D]),
        initial_damage: Arc::new(|_| 1.0),
        jump_planes: Vec::new(),
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

/// The data of one velocity step (5.1) as a test knows them (Cartesian, node-major): what the
/// KKT conditions are recomputed from in [`velocity_kkt`].
pub struct VelocityProblem<'a, const D: usize> {
    pub space: &'a LagrangeSpace<D>,
    pub law: &'a dyn Viscosity<D>,
    pub contact: &'a ContactNodes<D>,
    /// The load F without the normal compliance.
    pub load: &'a [f64],
    /// p_ν per contact node.
    pub normal_pressure: &'a [f64],
    /// The friction bound s per contact node.
    pub friction_bound: &'a [f64],
    /// The constrained unknowns (Γ1).
    pub constrained: &'a [bool],
    /// The prescribed velocity p_c of each constrained unknown (ignored on free ones).
    pub prescribed: &'a [f64],
}

/// The KKT conditions of the velocity step (5.1) at (v, λ), each as a relative residual.
#[derive(Debug, Clone, Copy)]
pub struct VelocityKkt {
    /// max over the free unknowns of |N(v) − F + Σ_a ω_a p_a ν_a + Σ_a ω_a s_a Σ_i λ_a,i t_a,i|,
    /// relative to the largest force it balances: F, N(v) and the force N(v_Γ1) of the
    /// constrained velocities alone on the free unknowns, the contact forces.
    pub stationarity: f64,
    /// max over the constrained unknowns of |v_c − p_c|, relative to the largest |v|.
    pub prescribed: f64,
    /// max_a (|λ_a| − 1)₊.
    pub dual_feasibility: f64,
    /// max over the slipping nodes (s_a > 0, v_τ(a) ≠ 0) of |λ_a − v_τ(a)/|v_τ(a)||.
    pub complementarity: f64,
    /// Contact nodes with s_a > 0 and v_τ(a) = 0.
    pub sticking: usize,
    /// Contact nodes with s_a > 0 and v_τ(a) ≠ 0.
    pub slipping: usize,
}

impl VelocityKkt {
    /// The largest of the four residuals.
    pub fn residual(&self) -> f64 {
        self.stationarity
            .max(self.prescribed)
            .max(self.dual_feasibility)
            .max(self.complementarity)
    }
}

/// The KKT conditions of (5.1), J(v) = Σ_K ∫_K Φ(ε(v)) − ⟨F, v⟩ + Σ_a ω_a s_a |v_τ(a)| minimized
/// with v_c = p_c on Γ1, recomputed from the problem data alone: N(v) by [`internal_force`] (this
/// file's quadrature loop over the law's stress), the contact forces from the weights ω_a and
/// the frames (ν_a, t_a,1, …) of the contact nodes, in the Cartesian frame. A tangential speed
/// below 1e-13 of the largest |v| is a stick (v_τ(a) = 0 up to the rounding of the frame).
pub fn velocity_kkt<const D: usize>(
    problem: &VelocityProblem<'_, D>,
    velocity: &[f64],
    multipliers: &[f64],
) -> VelocityKkt {
    let largest =
        |values: &mut dyn Iterator<Item = f64>| values.fold(0.0f64, |m, x| m.max(x.abs()));
    let force = internal_force(problem.space, problem.law, velocity);
    let mut residual: Vec<f64> = force.iter().zip(problem.load).map(|(n, f)| n - f).collect();
    let speed_scale = largest(&mut velocity.iter().copied());
    let g = D - 1;
    let mut contact_force: f64 = 0.0;
    let mut kkt = VelocityKkt {
        stationarity: 0.0,
        prescribed: 0.0,
        dual_feasibility: 0.0,
        complementarity: 0.0,
        sticking: 0,
        slipping: 0,
    };
    for (k, &node) in problem.contact.nodes.iter().enumerate() {
        let frame = &problem.contact.frames[k];
        let weight = problem.contact.weights[k];
        let lambda = &multipliers[k * g..(k + 1) * g];
        let v = SVector::<f64, D>::from_column_slice(&velocity[node * D..node * D + D]);
        let mut traction = frame.column(0) * (weight * problem.normal_pressure[k]);
        for (i, l) in lambda.iter().enumerate() {
            traction += frame.column(1 + i) * (weight * problem.friction_bound[k] * l);
        }
        for i in 0..D {
            residual[node * D + i] += traction[i];
        }
        contact_force = contact_force
            .max(weight * problem.normal_pressure[k])
            .max(weight * problem.friction_bound[k] * largest(&mut lambda.iter().copied()));
        let norm = lambda.iter().map(|l| l * l).sum::<f64>().sqrt();
        kkt.dual_feasibility = kkt.dual_feasibility.max(norm - 1.0);
        let tangential: Vec<f64> = (0..g).map(|i| frame.column(1 + i).dot(&v)).collect();
        let speed = tangential.iter().map(|t| t * t).sum::<f64>().sqrt();
        if problem.friction_bound[k] > 0.0 {
            if speed > 1e-13 * speed_scale {
                kkt.slipping += 1;
                for (l, t) in lambda.iter().zip(&tangential) {
                    kkt.complementarity = kkt.complementarity.max((l - t / speed).abs());
                }
            } else {
                kkt.sticking += 1;
            }
        }
    }
    let free = |dof: &usize| !problem.constrained[*dof];
    let n = velocity.len();
    // the force of the constrained velocities alone on the free unknowns (a body moved by its
    // support only has no other force to compare with)
    let lifted: Vec<f64> = (0..n)
        .map(|dof| if free(&dof) { 0.0 } else { velocity[dof] })
        .collect();
    let lifting = internal_force(problem.space, problem.law, &lifted);
    let scale = largest(&mut (0..n).filter(free).map(|dof| problem.load[dof]))
        .max(largest(&mut (0..n).filter(free).map(|dof| force[dof])))
        .max(largest(&mut (0..n).filter(free).map(|dof| lifting[dof])))
        .max(contact_force)
        .max(f64::MIN_POSITIVE);
    kkt.stationarity = largest(&mut (0..n).filter(free).map(|dof| residual[dof])) / scale;
    kkt.prescribed = largest(
        &mut (0..n)
            .filter(|dof| problem.constrained[*dof])
            .map(|dof| velocity[dof] - problem.prescribed[dof]),
    ) / speed_scale.max(f64::MIN_POSITIVE);
    kkt
}

/// The constrained unknowns of [`contact_damage::scheme::velocity::VelocityOperator::new`]: every
/// component of every node of Γ1.
pub fn clamped_unknowns<const D: usize>(space: &LagrangeSpace<D>) -> Vec<bool> {
    let mut constrained = vec![false; space.num_nodes() * D];
    for node in space.boundary_nodes(BoundaryPart::Dirichlet) {
        for i in 0..D {
            constrained[node * D + i] = true;
        }
    }
    constrained
}
