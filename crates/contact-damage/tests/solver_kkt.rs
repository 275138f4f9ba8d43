//! Property tests: the velocity step (5.1) and the damage step (5.2) satisfy their KKT
//! conditions to 1e-10 on random data, in every contact regime (no contact, all stick, all
//! slip, mixed) and with both damage bounds active.
//!
//! The KKT conditions are recomputed here from the problem data and the returned solution
//! alone, not with the solvers' residual functions or statistics: for (5.1) by
//! [`common::velocity_kkt`] (N(v) from this crate's tests' own quadrature loop, contact forces
//! from the weights and frames, Cartesian frame); for (5.2) from the matrix M/k + κK and the
//! vector b assembled here (dense, own quadrature loop) with the projected-gradient residual.
//! Observed over the proptest cases: velocity steps at most 1.6e-12, damage steps 3.9e-12. The
//! last two tests check that both recomputed checks fail for perturbed solutions.

use crate::common;

use common::{
    clamped_unknowns, regime_contact_data, velocity_kkt, Random, Regime, VelocityKkt,
    VelocityProblem, REGIMES,
};

use contact_damage::fem::mesh::Mesh;
use contact_damage::fem::quadrature::QuadratureRule;
use contact_damage::fem::space::LagrangeSpace;
use contact_damage::model::contact::{ContactNodes, ContactStatus};
use contact_damage::model::laws::{LinearViscosity, SaturatingViscosity, Viscosity};
use contact_damage::scheme::damage::DamageOperator;
use contact_damage::scheme::velocity::{
    VelocityData, VelocityOperator, VelocitySettings, VelocitySolution,
};
use contact_damage::solvers::box_qp::BoxQpSettings;
use nalgebra::{DMatrix, DVector, SVector};
use proptest::prelude::*;
use std::sync::Arc;

/// One random velocity step: its data and the solver's solution.
struct VelocityStep<const D: usize> {
    space: Arc<LagrangeSpace<D>>,
    law: Arc<dyn Viscosity<D>>,
    contact: Arc<ContactNodes<D>>,
    load: Vec<f64>,
    pressure: Vec<f64>,
    bound: Vec<f64>,
    constrained: Vec<bool>,
    solution: VelocitySolution,
}

impl<const D: usize> VelocityStep<D> {
    /// The KKT conditions of (5.1) at (v, λ), recomputed (the clamped unknowns of Γ1 carry
    /// p = 0).
    fn kkt(&self, velocity: &[f64], multipliers: &[f64]) -> VelocityKkt {
        let problem = VelocityProblem {
            space: &self.space,
            law: self.law.as_ref(),
            contact: &self.contact,
            load: &self.load,
            normal_pressure: &self.pressure,
            friction_bound: &self.bound,
            constrained: &self.constrained,
            prescribed: &vec![0.0; velocity.len()],
        };
        velocity_kkt(&problem, velocity, multipliers)
    }

    /// The KKT conditions at the solver's solution.
    fn solution_kkt(&self) -> VelocityKkt {
        self.kkt(&self.solution.velocity, &self.solution.multipliers)
    }
}

/// Solves one velocity step with random loads of size 0.05, the contact data of `regime` and a
/// random start.
fn velocity_step<const D: usize>(
    mesh: Mesh<D>,
    degree: usize,
    law: Arc<dyn Viscosity<D>>,
    regime: Regime,
    seed: u64,
) -> VelocityStep<D> {
    let mut rng = Random::new(seed);
    let space = Arc::new(LagrangeSpace::new(Arc::new(mesh), degree).unwrap());
    let contact = Arc::new(ContactNodes::new(&space).unwrap());
    let mut operator = VelocityOperator::new(space.clone(), law.clone(), contact.clone()).unwrap();
    let n = space.num_nodes() * D;
    let load: Vec<f64> = (0..n).map(|_| 0.05 * rng.symmetric()).collect();
    let (pressure, bound) = regime_contact_data(regime, contact.len(), &mut rng);
    let data = VelocityData {
        load: &load,
        normal_pressure: &pressure,
        friction_bound: &bound,
        implicit_contact: None,
        prescribed: None,
    };
    let start: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
    let solution = operator
        .solve(&data, &start, &VelocitySettings::default())
        .unwrap();
    VelocityStep {
        constrained: clamped_unknowns(&space),
        space,
        law,
        contact,
        load,
        pressure,
        bound,
        solution,
    }
}

fn linear_law<const D: usize>() -> Arc<dyn Viscosity<D>> {
    Arc::new(LinearViscosity {
        shear: 1.0,
        bulk: 0.3,
    })
}

fn check_regime(statuses: &[ContactStatus], regime: Regime) {
    let has = |s: ContactStatus| statuses.contains(&s);
    match regime {
        Regime::NoContact => assert!(statuses.iter().all(|s| *s == ContactStatus::Separated)),
        Regime::AllStick => assert!(
            statuses.iter().all(|s| *s == ContactStatus::Stick),
            "{statuses:?}"
        ),
        Regime::AllSlip => assert!(
            statuses.iter().all(|s| *s == ContactStatus::Slip),
            "{statuses:?}"
        ),
        Regime::Mixed => assert!(
            has(ContactStatus::Separated) && has(ContactStatus::Stick) && has(ContactStatus::Slip),
            "{statuses:?}"
        ),
    }
}

/// The recomputed KKT conditions hold and agree with the statuses the solver reports: every
/// node it calls sticking or slipping is one in the solution.
fn check_velocity_step<const D: usize>(step: &VelocityStep<D>, regime: Regime) {
    let kkt = step.solution_kkt();
    assert!(kkt.residual() <= 1e-10, "{kkt:?} in regime {regime:?}");
    let count = |s: ContactStatus| step.solution.status.iter().filter(|&&x| x == s).count();
    assert_eq!(
        (kkt.sticking, kkt.slipping),
        (count(ContactStatus::Stick), count(ContactStatus::Slip)),
        "{:?}",
        step.solution.status
    );
    if !matches!(regime, Regime::Mixed) {
        check_regime(&step.solution.status, regime);
    }
}

/// The damage step's box QP min ½βᵀAβ − bᵀβ over 0 ≤ β ≤ 1 as this file builds it.
struct DamageQp {
    /// A = M/k + κK.
    matrix: DMatrix<f64>,
    /// b = M β_{n−1}/k + source.
    rhs: DVector<f64>,
}

/// m·M + κ·K on `space` (consistent mass, Lagrange basis), dense, by this file's own loop with
/// the degree-2l rule (exact for both).
fn damage_matrix<const D: usize>(
    space: &LagrangeSpace<D>,
    mass_coefficient: f64,
    diffusion: f64,
) -> DMatrix<f64> {
    let element = space.element();
    let rule = QuadratureRule::<D>::simplex(2 * space.degree());
    let n = element.num_nodes();
    let mut matrix = DMatrix::zeros(space.num_nodes(), space.num_nodes());
    let mut values = vec![0.0; n];
    let mut reference = vec![[0.0; D]; n];
    for cell in 0..space.mesh().num_cells() {
        let geometry = space.geometry(cell);
        let nodes = space.cell_nodes(cell);
        for (point, weight) in rule.points.iter().zip(&rule.weights) {
            element.values(point, &mut values);
            element.gradients(point, &mut reference);
            let gradients: Vec<SVector<f64, D>> = reference
                .iter()
                .map(|g| geometry.inverse_transpose * SVector::<f64, D>::from(*g))
                .collect();
            let weight = weight * geometry.det.abs();
            for a in 0..n {
                for b in 0..n {
                    matrix[(nodes[a], nodes[b])] += weight
                        * (mass_coefficient * values[a] * values[b]
                            + diffusion * gradients[a].dot(&gradients[b]));
                }
            }
        }
    }
    matrix
}

impl DamageQp {
    fn new<const D: usize>(
        space: &LagrangeSpace<D>,
        diffusion: f64,
        time_step: f64,
        previous: &[f64],
        source: &[f64],
    ) -> Self {
        let mass = damage_matrix(space, 1.0, 0.0);
        let rhs = &mass * DVector::from_column_slice(previous) / time_step
            + DVector::from_column_slice(source);
        Self {
            matrix: damage_matrix(space, 1.0 / time_step, diffusion),
            rhs,
        }
    }

    /// The KKT residual of the box QP at β: max_i |min(β_i − 0, max(β_i − 1, g_i/s))|, g = Aβ − b
    /// the gradient and s = max(‖b‖∞, ‖Aβ‖∞) the size of the forces it balances. Zero exactly
    /// at the minimizer: β feasible, g ≥ 0 where β = 0, g ≤ 0 where β = 1, g = 0 between.
    fn kkt(&self, damage: &[f64]) -> f64 {
        let beta = DVector::from_column_slice(damage);
        let product = &self.matrix * &beta;
        let gradient = &product - &self.rhs;
        let scale = self.rhs.amax().max(product.amax()).max(f64::MIN_POSITIVE);
        beta.iter()
            .zip(gradient.iter())
            .map(|(&b, &g)| (b - 0.0).min((b - 1.0).max(g / scale)).abs())
            .fold(0.0, f64::max)
    }
}

/// One damage step on P_degree of a 5 × 5 square with random β_{n−1} (and β_{n−2} for odd
/// seeds), a source pushing the left nodes down and the right nodes up plus noise: the QP
/// assembled here and the solver's β.
fn damage_step(seed: u64, degree: usize, amplitude: f64) -> (DamageQp, Vec<f64>) {
    let mut rng = Random::new(seed);
    let space = Arc::new(LagrangeSpace::new(Arc::new(common::square(5)), degree).unwrap());
    let (time_step, diffusion) = (0.1, 0.05);
    let mut operator = DamageOperator::new(
        space.clone(),
        diffusion,
        time_step,
        BoxQpSettings::default(),
    )
    .unwrap();
    let n = space.num_nodes();
    let previous: Vec<f64> = (0..n).map(|_| rng.next()).collect();
    let source: Vec<f64> = (0..n)
        .map(|i| amplitude * ((space.node(i)[0] - 0.5) + 0.3 * rng.symmetric()) / (n as f64))
        .collect();
    // β_{n−2}: none (a first step) or random, so that the extrapolated start
    // clamp(2β_{n−1} − β_{n−2}) is anywhere in the box
    let before: Vec<f64> = if seed % 2 == 0 {
        Vec::new()
    } else {
        (0..n).map(|_| rng.next()).collect()
    };
    let solution = operator.solve(&source, &previous, &before).unwrap();
    let qp = DamageQp::new(&space, diffusion, time_step, &previous, &source);
    (qp, solution.damage)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn velocity_step_satisfies_kkt_2d(seed in any::<u64>(), regime in 0usize..4, degree in 1usize..=2) {
        let regime = REGIMES[regime];
        let step = velocity_step(common::square(4), degree, linear_law(), regime, seed);
        check_velocity_step(&step, regime);
    }

    #[test]
    fn velocity_step_satisfies_kkt_3d(seed in any::<u64>(), regime in 0usize..4) {
        let regime = REGIMES[regime];
        let step = velocity_step(common::cube(3), 1, linear_law(), regime, seed);
        check_velocity_step(&step, regime);
    }

    #[test]
    fn damage_step_satisfies_kkt(seed in any::<u64>(), degree in 1usize..=2, amplitude in 0.1f64..50.0) {
        let (qp, damage) = damage_step(seed, degree, amplitude);
        let kkt = qp.kkt(&damage);
        prop_assert!(kkt <= 1e-10, "damage KKT residual {kkt:e}");
        prop_assert!(damage.iter().all(|b| (0.0..=1.0).contains(b)));
    }
}

#[test]
fn mixed_regime_has_all_three_contact_states() {
    let step = velocity_step(common::square(6), 1, linear_law(), Regime::Mixed, 7);
    check_velocity_step(&step, Regime::Mixed);
    check_regime(&step.solution.status, Regime::Mixed);
}

#[test]
fn damage_step_activates_both_bounds() {
    let space = Arc::new(LagrangeSpace::new(Arc::new(common::square(6)), 1).unwrap());
    let (time_step, diffusion) = (0.1, 0.01);
    let mut operator = DamageOperator::new(
        space.clone(),
        diffusion,
        time_step,
        BoxQpSettings::default(),
    )
    .unwrap();
    let n = space.num_nodes();
    let previous = vec![0.5; n];
    let source: Vec<f64> = (0..n)
        .map(|i| 50.0 * (space.node(i)[0] - 0.5) / n as f64)
        .collect();
    let solution = operator.solve(&source, &previous, &[]).unwrap();
    let lower = solution.damage.iter().filter(|&&b| b == 0.0).count();
    let upper = solution.damage.iter().filter(|&&b| b == 1.0).count();
    assert!(lower > 0 && upper > 0, "{:?}", solution.damage);
    let qp = DamageQp::new(&space, diffusion, time_step, &previous, &source);
    let kkt = qp.kkt(&solution.damage);
    assert!(kkt <= 1e-10, "damage KKT residual {kkt:e}");
}

#[test]
fn velocity_step_with_nonlinear_viscosity_satisfies_kkt() {
    let law: Arc<dyn Viscosity<2>> = Arc::new(SaturatingViscosity {
        linear: LinearViscosity {
            shear: 1.0,
            bulk: 0.3,
        },
        extra_shear: 5.0,
        rate_scale: 0.01,
    });
    let space = Arc::new(LagrangeSpace::new(Arc::new(common::square(6)), 1).unwrap());
    let contact = Arc::new(ContactNodes::new(&space).unwrap());
    let mut operator = VelocityOperator::new(space.clone(), law.clone(), contact.clone()).unwrap();
    let mut rng = Random::new(11);
    let n = space.num_nodes() * 2;
    let load: Vec<f64> = (0..n).map(|_| 0.05 * rng.symmetric()).collect();
    let (pressure, bound): (Vec<f64>, Vec<f64>) = (0..contact.len())
        .map(|k| match k % 3 {
            0 => (0.0, 0.0),
            1 => (1.0, 10.0),
            _ => (1.0, 1e-4),
        })
        .unzip();
    let data = VelocityData {
        load: &load,
        normal_pressure: &pressure,
        friction_bound: &bound,
        implicit_contact: None,
        prescribed: None,
    };
    let solution = operator
        .solve(&data, &vec![0.0; n], &VelocitySettings::default())
        .unwrap();
    // the saturating law is genuinely nonlinear at these rates: Newton needs several iterations
    assert!(
        solution.stats.newton_iterations >= 3,
        "{:?}",
        solution.stats
    );
    let step = VelocityStep {
        constrained: clamped_unknowns(&space),
        space,
        law,
        contact,
        load,
        pressure,
        bound,
        solution,
    };
    check_velocity_step(&step, Regime::Mixed);
    check_regime(&step.solution.status, Regime::Mixed);
}

/// The recomputed KKT check of (5.1) rejects wrong answers: the solution of the mixed regime
/// with one free velocity moved by 1e-6 of the largest velocity, a clamped velocity made
/// nonzero, the multiplier of a sticking node halved (still |λ| ≤ 1), the multiplier of a
/// slipping node reversed, or a multiplier pushed out of the unit ball. Observed: the solutions
/// at 1.6e-14 (2D P2) and 4.1e-15 (3D P1), the perturbed ones from 1.0e-6 (clamped velocity, 3D)
/// to 2; asserted: above 1e-8.
#[test]
fn recomputed_velocity_kkt_rejects_perturbed_solutions() {
    rejects_perturbed(&velocity_step(
        common::square(6),
        2,
        linear_law(),
        Regime::Mixed,
        7,
    ));
    rejects_perturbed(&velocity_step(
        common::cube(3),
        1,
        linear_law(),
        Regime::Mixed,
        7,
    ));
}

fn rejects_perturbed<const D: usize>(step: &VelocityStep<D>) {
    let velocity = &step.solution.velocity;
    let multipliers = &step.solution.multipliers;
    let exact = step.solution_kkt();
    assert!(exact.residual() <= 1e-10, "{exact:?}");
    let size = velocity.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let g = D - 1;
    let statuses = &step.solution.status;
    let node_with = |status: ContactStatus| {
        statuses
            .iter()
            .position(|&s| s == status)
            .unwrap_or_else(|| panic!("no {status:?} node: {statuses:?}"))
    };
    let free_dof = (0..velocity.len())
        .find(|&dof| !step.constrained[dof] && step.contact.index_of_node[dof / D].is_none())
        .unwrap();
    let clamped_dof = step.constrained.iter().position(|&c| c).unwrap();
    let mut cases: Vec<(&str, Vec<f64>, Vec<f64>)> = Vec::new();
    let mut moved = velocity.clone();
    moved[free_dof] += 1e-6 * size;
    cases.push(("free velocity moved", moved, multipliers.clone()));
    let mut clamped = velocity.clone();
    clamped[clamped_dof] = 1e-6 * size;
    cases.push(("clamped velocity nonzero", clamped, multipliers.clone()));
    let stick = node_with(ContactStatus::Stick);
    let mut halved = multipliers.clone();
    halved[stick * g..(stick + 1) * g]
        .iter_mut()
        .for_each(|l| *l *= 0.5);
    cases.push(("sticking multiplier halved", velocity.clone(), halved));
    let slip = node_with(ContactStatus::Slip);
    let mut reversed = multipliers.clone();
    reversed[slip * g..(slip + 1) * g]
        .iter_mut()
        .for_each(|l| *l = -*l);
    cases.push(("slipping multiplier reversed", velocity.clone(), reversed));
    let mut outside = multipliers.clone();
    outside[stick * g] = 1.5;
    cases.push((
        "multiplier outside the unit ball",
        velocity.clone(),
        outside,
    ));
    for (what, velocity, multipliers) in cases {
        let kkt = step.kkt(&velocity, &multipliers);
        assert!(
            kkt.residual() > 1e-8,
            "{D}D, {what}: recomputed KKT {kkt:?} (solution: {:e})",
            exact.residual()
        );
    }
}

/// The recomputed KKT check of the damage step rejects wrong answers: the solution with one
/// node between the bounds moved by 1e-6, a node at the lower bound lifted to 1e-6, or a node at
/// the upper bound pushed to 1 + 1e-6. Observed: the solution at 2.0e-12, the perturbed ones at
/// 4.2e-7, 1e-6 and 1e-6; asserted: above 1e-8.
#[test]
fn recomputed_damage_kkt_rejects_perturbed_solutions() {
    let (qp, damage) = damage_step(3, 2, 40.0);
    let exact = qp.kkt(&damage);
    assert!(exact <= 1e-10, "{exact:e}");
    let find = |wanted: &dyn Fn(f64) -> bool| damage.iter().position(|&b| wanted(b)).unwrap();
    let between = find(&|b| b > 0.0 && b < 1.0);
    let lower = find(&|b| b == 0.0);
    let upper = find(&|b| b == 1.0);
    for (what, node, value) in [
        ("between the bounds, moved", between, damage[between] + 1e-6),
        ("at the lower bound, lifted", lower, 1e-6),
        ("at the upper bound, pushed out", upper, 1.0 + 1e-6),
    ] {
        let mut perturbed = damage.clone();
        perturbed[node] = value;
        let kkt = qp.kkt(&perturbed);
        assert!(
            kkt > 1e-8,
            "{what}: recomputed KKT {kkt:e} (solution: {exact:e})"
        );
    }
}
