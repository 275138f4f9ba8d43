//! The velocity step (5.1) with a nonlinear viscosity 𝒜 (3.4): from any start, the globalized
//! proximal Newton method reaches a relative KKT residual ≤ 1e-12 (1e-2 × the default 1e-10
//! certificate) in a bounded number of iterations, in 2D and 3D, for P1 and P2, in every contact
//! regime; and its Newton phase converges superlinearly.
//!
//! The KKT conditions are recomputed here: the internal force N(v) = ⟨𝒜ε(v), ε(φ_a e_i)⟩ is
//! assembled by this file's own quadrature loop from the law's stress, not by the solver.
//!
//! Observed iteration counts (proptest runs of this file, random starts of size up to 10):
//! 4 to 7 Newton iterations in 600 cases (4: 75%, 5: 17%, 6: 8%, 7: 2 cases), largest KKT
//! residual 9.7e-13; the bound asserted is [`MAX_ITERATIONS`] = 12.

use crate::common;

use common::{internal_force, regime_contact_data, Random, Regime, REGIMES};

use contact_damage::fem::mesh::{BoundaryPart, Mesh};
use contact_damage::fem::space::LagrangeSpace;
use contact_damage::model::contact::{ContactNodes, ContactStatus};
use contact_damage::model::laws::{LinearViscosity, SaturatingViscosity};
use contact_damage::scheme::velocity::{
    TangentUpdate, VelocityData, VelocityOperator, VelocitySettings,
};
use proptest::prelude::*;
use std::sync::Arc;

/// Bound on the Newton iterations of one step asserted by the property tests.
const MAX_ITERATIONS: usize = 12;
/// The KKT residual every nonlinear step must reach (head room under the 1e-10 certificate).
const KKT_TARGET: f64 = 1e-12;

/// A mild law (η₁ = η/2, ε₀ = 0.2) and a strongly nonlinear one (η₁ = 5η, ε₀ = 0.01, far below
/// the strain rates of the random data).
fn saturating(strong: bool) -> SaturatingViscosity {
    SaturatingViscosity {
        linear: LinearViscosity {
            shear: 1.0,
            bulk: 0.3,
        },
        extra_shear: if strong { 5.0 } else { 0.5 },
        rate_scale: if strong { 0.01 } else { 0.2 },
    }
}

struct Outcome {
    /// KKT residual recomputed here.
    kkt: f64,
    /// The solver's own reported residual.
    reported: f64,
    iterations: usize,
    history: Vec<f64>,
    statuses: Vec<ContactStatus>,
    velocity: Vec<f64>,
    factorizations: usize,
}

/// Solves one velocity step with random data and a random start of size `start_size`, by
/// exact Newton.
fn solve_random<const D: usize>(
    mesh: Mesh<D>,
    degree: usize,
    law: SaturatingViscosity,
    regime: Regime,
    seed: u64,
    start_size: f64,
) -> Outcome {
    solve_random_with(
        mesh,
        degree,
        law,
        regime,
        seed,
        start_size,
        TangentUpdate::Newton,
    )
}

/// [`solve_random`] with the tangent updated as `tangent` says.
fn solve_random_with<const D: usize>(
    mesh: Mesh<D>,
    degree: usize,
    law: SaturatingViscosity,
    regime: Regime,
    seed: u64,
    start_size: f64,
    tangent: TangentUpdate,
) -> Outcome {
    let mut rng = Random::new(seed);
    let space = Arc::new(LagrangeSpace::new(Arc::new(mesh), degree).unwrap());
    let contact = Arc::new(ContactNodes::new(&space).unwrap());
    let mut operator =
        VelocityOperator::new(space.clone(), Arc::new(law), contact.clone()).unwrap();
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
    let start: Vec<f64> = (0..n).map(|_| start_size * rng.symmetric()).collect();
    let settings = VelocitySettings {
        tangent,
        ..VelocitySettings::default()
    };
    let solution = operator.solve(&data, &start, &settings).unwrap();
    // stationarity N(v) − F + E_c W λ in the system frame, recomputed
    let force = operator.to_system(&internal_force(&space, &law, &solution.velocity));
    let v = operator.to_system(&solution.velocity);
    let mut f = operator.to_system(&load);
    for (k, &node) in contact.nodes.iter().enumerate() {
        f[node * D] -= contact.weights[k] * pressure[k];
    }
    let mut residual: Vec<f64> = force.iter().zip(&f).map(|(a, b)| a - b).collect();
    for &node in &space.boundary_nodes(BoundaryPart::Dirichlet) {
        for i in 0..D {
            residual[node * D + i] = solution.velocity[node * D + i];
        }
    }
    let g = D - 1;
    let mut complementarity: f64 = 0.0;
    let mut friction_force: f64 = 0.0;
    for (k, &node) in contact.nodes.iter().enumerate() {
        let weight = contact.weights[k] * bound[k];
        let lambda = &solution.multipliers[k * g..(k + 1) * g];
        for i in 0..g {
            residual[node * D + 1 + i] += weight * lambda[i];
            friction_force = friction_force.max((weight * lambda[i]).abs());
        }
        let norm: f64 = lambda.iter().map(|l| l * l).sum::<f64>().sqrt();
        complementarity = complementarity.max(norm - 1.0);
        let tangential: Vec<f64> = (1..D).map(|i| v[node * D + i]).collect();
        let speed: f64 = tangential.iter().map(|t| t * t).sum::<f64>().sqrt();
        if weight > 0.0 && speed > 0.0 {
            for i in 0..g {
                complementarity = complementarity.max((lambda[i] - tangential[i] / speed).abs());
            }
        }
    }
    let largest = |values: &[f64]| values.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    // relative to the largest force balanced, as the solver's certificate
    let scale = largest(&f).max(largest(&force)).max(friction_force);
    let stationarity = largest(&residual) / scale;
    Outcome {
        kkt: stationarity.max(complementarity),
        reported: solution.stats.kkt_residual,
        iterations: solution.stats.newton_iterations,
        history: solution.stats.residual_history,
        statuses: solution.status,
        velocity: solution.velocity,
        factorizations: solution.stats.factorizations,
    }
}

fn check(outcome: &Outcome, regime: Regime) -> Result<(), TestCaseError> {
    prop_assert!(
        outcome.kkt <= KKT_TARGET && outcome.reported <= KKT_TARGET,
        "KKT residual {:e} (reported {:e}) in regime {regime:?}, history {:?}",
        outcome.kkt,
        outcome.reported,
        outcome.history
    );
    prop_assert!(
        outcome.iterations <= MAX_ITERATIONS,
        "{} Newton iterations, history {:?}",
        outcome.iterations,
        outcome.history
    );
    // the stop test and the reported residual are the same number
    prop_assert_eq!(outcome.history.last().copied(), Some(outcome.reported));
    let has = |s: ContactStatus| outcome.statuses.contains(&s);
    match regime {
        Regime::NoContact => prop_assert!(outcome
            .statuses
            .iter()
            .all(|s| *s == ContactStatus::Separated)),
        Regime::AllStick => {
            prop_assert!(outcome.statuses.iter().all(|s| *s == ContactStatus::Stick))
        }
        Regime::AllSlip => prop_assert!(outcome.statuses.iter().all(|s| *s == ContactStatus::Slip)),
        Regime::Mixed => prop_assert!(
            has(ContactStatus::Separated) && has(ContactStatus::Stick) && has(ContactStatus::Slip),
            "statuses {:?}",
            outcome.statuses
        ),
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn nonlinear_velocity_step_reaches_kkt_1e_12_in_2d(
        seed in any::<u64>(),
        regime in 0usize..4,
        degree in 1usize..=2,
        strong in any::<bool>(),
        start_size in 0.0f64..10.0,
    ) {
        let regime = REGIMES[regime];
        // 6 cells: P1 has 6 contact nodes, two of them with the small friction bound of the
        // mixed regime. With 4 cells the only one was held by its stuck neighbour in a rare
        // case (statuses [Separated, Stick, Stick, Separated], seed 2590237106501329265, P1,
        // strong law): a solution without a slip node, which the mixed check rejects.
        let outcome = solve_random(common::square(6), degree, saturating(strong), regime, seed, start_size);
        check(&outcome, regime)?;
    }

    #[test]
    fn nonlinear_velocity_step_reaches_kkt_1e_12_in_3d(
        seed in any::<u64>(),
        regime in 0usize..4,
        degree in 1usize..=2,
        strong in any::<bool>(),
        start_size in 0.0f64..10.0,
    ) {
        let regime = REGIMES[regime];
        let cells = if degree == 1 { 3 } else { 2 };
        let outcome = solve_random(common::cube(cells), degree, saturating(strong), regime, seed, start_size);
        check(&outcome, regime)?;
    }
}

/// On a smooth case (no contact, so (5.1) is a smooth strongly convex minimization) the
/// residual ratios r_{k+1}/r_k of the Newton phase tend to 0: each of the last three is below
/// the one before and the last is below 1e-2 (a linearly convergent method keeps a fixed ratio),
/// among the residuals above the round-off floor.
#[test]
fn nonlinear_velocity_step_converges_superlinearly() {
    let outcome = solve_random(
        common::square(8),
        2,
        saturating(true),
        Regime::NoContact,
        3,
        1.0,
    );
    // residuals at the round-off floor (≤ 1e-12, a hundred times the unit round-off times the
    // condition of the step) carry no information on the rate: their ratios are noise
    let history: Vec<f64> = outcome
        .history
        .iter()
        .copied()
        .filter(|&residual| residual > 1e-12)
        .collect();
    assert!(
        history.len() >= 4,
        "too few iterations to judge: {history:?}"
    );
    let ratios: Vec<f64> = history.windows(2).map(|w| w[1] / w[0]).collect();
    let last = &ratios[ratios.len() - 3..];
    assert!(
        last[0] > last[1] && last[1] > last[2] && last[2] < 1e-2,
        "ratios {ratios:?} of history {history:?}"
    );
    assert!(outcome.kkt <= KKT_TARGET);
}

/// The frozen tangent (the default) reaches the solution of exact Newton, certified to the same
/// KKT target, with fewer factorizations: on the smooth case of the test above and on a step
/// with stick and slip, in 2D and 3D (observed: velocities equal to 6e-14 of their size or
/// closer, one or two factorizations against four to six).
#[test]
fn frozen_tangent_reaches_the_newton_solution_with_fewer_factorizations() {
    let cases: [(Regime, u64); 2] = [(Regime::NoContact, 3), (Regime::Mixed, 5)];
    for (regime, seed) in cases {
        for dim in [2, 3] {
            let solve = |tangent| {
                if dim == 2 {
                    solve_random_with(
                        common::square(8),
                        2,
                        saturating(true),
                        regime,
                        seed,
                        1.0,
                        tangent,
                    )
                } else {
                    solve_random_with(
                        common::cube(3),
                        2,
                        saturating(true),
                        regime,
                        seed,
                        1.0,
                        tangent,
                    )
                }
            };
            let (newton, frozen) = (solve(TangentUpdate::Newton), solve(TangentUpdate::Frozen));
            assert!(frozen.kkt <= KKT_TARGET && frozen.reported <= KKT_TARGET);
            let size = newton.velocity.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let difference = newton
                .velocity
                .iter()
                .zip(&frozen.velocity)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(
                difference <= 1e-9 * size,
                "{regime:?}, {dim}D: velocities differ by {difference:e} of {size:e}"
            );
            assert!(
                frozen.factorizations < newton.factorizations,
                "{regime:?}, {dim}D: {} factorizations frozen, {} Newton",
                frozen.factorizations,
                newton.factorizations
            );
        }
    }
}
