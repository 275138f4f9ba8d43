//! Property tests: the velocity step (5.1) and the damage step (5.2) satisfy their KKT
//! conditions to 1e-10 on random data, in every contact regime (no contact, all stick, all
//! slip, mixed) and with both damage bounds active. The KKT conditions are recomputed here from
//! the assembled matrices, independently of the solvers' own residuals.

mod common;

use common::{regime_contact_data, Random, Regime, REGIMES};

use contact_damage::contact::{ContactNodes, ContactStatus};
use contact_damage::damage::{assemble_damage_matrix, DamageOperator};
use contact_damage::laws::LinearViscosity;
use contact_damage::linalg::multiply;
use contact_damage::mesh::Mesh;
use contact_damage::obstacle::{box_qp_kkt_residual, BoxQpSettings};
use contact_damage::space::LagrangeSpace;
use contact_damage::velocity::{VelocityData, VelocityOperator, VelocitySettings};
use proptest::prelude::*;
use std::sync::Arc;

/// Solves one random velocity step and returns the independently recomputed KKT residual and
/// the contact statuses.
fn velocity_kkt<const D: usize>(
    mesh: Mesh<D>,
    degree: usize,
    regime: Regime,
    seed: u64,
) -> (f64, Vec<ContactStatus>) {
    let mut rng = Random::new(seed);
    let space = Arc::new(LagrangeSpace::new(Arc::new(mesh), degree).unwrap());
    let contact = Arc::new(ContactNodes::new(&space).unwrap());
    let law = Arc::new(LinearViscosity {
        shear: 1.0,
        bulk: 0.3,
    });
    let mut operator = VelocityOperator::new(space.clone(), law, contact.clone()).unwrap();
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
    // independent KKT check in the system frame
    let matrix = operator.assemble(None).unwrap();
    let v = operator.to_system(&solution.velocity);
    let mut f = operator.to_system(&load);
    for (k, &node) in contact.nodes.iter().enumerate() {
        f[node * D] -= contact.weights[k] * pressure[k];
    }
    let mut residual: Vec<f64> = multiply(&matrix, &v)
        .iter()
        .zip(&f)
        .map(|(a, b)| a - b)
        .collect();
    let clamped = space.boundary_nodes(contact_damage::mesh::BoundaryPart::Dirichlet);
    for &node in &clamped {
        for i in 0..D {
            residual[node * D + i] = solution.velocity[node * D + i];
        }
    }
    let g = D - 1;
    let mut complementarity: f64 = 0.0;
    for (k, &node) in contact.nodes.iter().enumerate() {
        let weight = contact.weights[k] * bound[k];
        let lambda = &solution.multipliers[k * g..(k + 1) * g];
        for i in 0..g {
            residual[node * D + 1 + i] += weight * lambda[i];
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
    let scale = f.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let stationarity = residual.iter().fold(0.0f64, |m, r| m.max(r.abs())) / scale;
    (stationarity.max(complementarity), solution.status)
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

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn velocity_step_satisfies_kkt_2d(seed in any::<u64>(), regime in 0usize..4, degree in 1usize..=2) {
        let regime = REGIMES[regime];
        let (kkt, statuses) = velocity_kkt(common::square(4), degree, regime, seed);
        prop_assert!(kkt <= 1e-10, "KKT residual {kkt:e} in regime {regime:?}");
        if !matches!(regime, Regime::Mixed) {
            check_regime(&statuses, regime);
        }
    }

    #[test]
    fn velocity_step_satisfies_kkt_3d(seed in any::<u64>(), regime in 0usize..4) {
        let regime = REGIMES[regime];
        let (kkt, statuses) = velocity_kkt(common::cube(3), 1, regime, seed);
        prop_assert!(kkt <= 1e-10, "KKT residual {kkt:e} in regime {regime:?}");
        if !matches!(regime, Regime::Mixed) {
            check_regime(&statuses, regime);
        }
    }

    #[test]
    fn damage_step_satisfies_kkt(seed in any::<u64>(), degree in 1usize..=2, amplitude in 0.1f64..50.0) {
        let mut rng = Random::new(seed);
        let space = Arc::new(LagrangeSpace::new(Arc::new(common::square(5)), degree).unwrap());
        let time_step = 0.1;
        let mut operator = DamageOperator::new(space.clone(), 0.05, time_step, BoxQpSettings::default()).unwrap();
        let n = space.num_nodes();
        let previous: Vec<f64> = (0..n).map(|_| rng.next()).collect();
        // a source that pushes left nodes down and right nodes up, plus noise
        let source: Vec<f64> = (0..n)
            .map(|i| amplitude * ((space.node(i)[0] - 0.5) + 0.3 * rng.symmetric()) / (n as f64))
            .collect();
        // β_{n−2}: none (a first step) or random, so that the extrapolated start
        // clamp(2β_{n−1} − β_{n−2}) is anywhere in the box
        let before: Vec<f64> = if seed % 2 == 0 { Vec::new() } else { (0..n).map(|_| rng.next()).collect() };
        let solution = operator.solve(&source, &previous, &before).unwrap();
        let matrix = assemble_damage_matrix(&space, 1.0 / time_step, 0.05).unwrap();
        let mass = assemble_damage_matrix(&space, 1.0, 0.0).unwrap();
        let rhs: Vec<f64> = multiply(&mass, &previous).iter().zip(&source).map(|(m, s)| m / time_step + s).collect();
        let kkt = box_qp_kkt_residual(&matrix, &rhs, &vec![0.0; n], &vec![1.0; n], &solution.damage);
        prop_assert!(kkt <= 1e-10, "damage KKT residual {kkt:e}");
        prop_assert!(solution.damage.iter().all(|b| (0.0..=1.0).contains(b)));
    }
}

#[test]
fn mixed_regime_has_all_three_contact_states() {
    let (kkt, statuses) = velocity_kkt(common::square(6), 1, Regime::Mixed, 7);
    assert!(kkt <= 1e-10);
    check_regime(&statuses, Regime::Mixed);
}

#[test]
fn damage_step_activates_both_bounds() {
    let space = Arc::new(LagrangeSpace::new(Arc::new(common::square(6)), 1).unwrap());
    let mut operator =
        DamageOperator::new(space.clone(), 0.01, 0.1, BoxQpSettings::default()).unwrap();
    let n = space.num_nodes();
    let previous = vec![0.5; n];
    let source: Vec<f64> = (0..n)
        .map(|i| 50.0 * (space.node(i)[0] - 0.5) / n as f64)
        .collect();
    let solution = operator.solve(&source, &previous, &[]).unwrap();
    assert!(
        solution.stats.lower_active > 0 && solution.stats.upper_active > 0,
        "{:?}",
        solution.stats
    );
    assert!(solution.stats.kkt_residual <= 1e-10);
}

#[test]
fn velocity_step_with_nonlinear_viscosity_satisfies_kkt() {
    use contact_damage::laws::SaturatingViscosity;
    let space = Arc::new(LagrangeSpace::new(Arc::new(common::square(6)), 1).unwrap());
    let contact = Arc::new(ContactNodes::new(&space).unwrap());
    let law = Arc::new(SaturatingViscosity {
        linear: LinearViscosity {
            shear: 1.0,
            bulk: 0.3,
        },
        extra_shear: 5.0,
        rate_scale: 0.01,
    });
    let mut operator = VelocityOperator::new(space.clone(), law, contact.clone()).unwrap();
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
    assert!(solution.stats.kkt_residual <= 1e-10, "{:?}", solution.stats);
    let weights: Vec<f64> = contact
        .weights
        .iter()
        .zip(&bound)
        .map(|(w, s)| w * s)
        .collect();
    let mut system_load = operator.to_system(&load);
    for (k, &node) in contact.nodes.iter().enumerate() {
        system_load[node * 2] -= contact.weights[k] * pressure[k];
    }
    let kkt = operator.kkt_residual(
        &system_load,
        &weights,
        &operator.to_system(&solution.velocity),
        &solution.multipliers,
    );
    assert!(kkt <= 1e-10, "recomputed KKT residual {kkt:e}");
    check_regime(&solution.status, Regime::Mixed);
}
