//! The step limit of the explicit terms of (5.1) (`contact_damage::scheme::stability`): exact where it is
//! known in closed form, and it separates the steps at which the explicit scheme settles from
//! those at which it does not.

use crate::common;

use contact_damage::fem::mesh::Mesh;
use contact_damage::model::laws::{
    DamageSourceFn, DamagedHooke, LinearViscosity, NormalComplianceCoulomb, Tensor,
};
use contact_damage::scheme::{ContactTreatment, Problem, Simulation};
use std::sync::Arc;

/// Viscosity τ times the elasticity: 𝒜 = τ G(·, 1), so H = τ K_G.
fn proportional<const D: usize>(mesh: Mesh<D>, degree: usize, relaxation_time: f64) -> Problem<D> {
    let mut problem = common::problem(mesh, degree, common::quiet_data::<D>(), 1.0, 10);
    let (shear_modulus, lame_lambda) = (1.3, 0.7);
    problem.model.elasticity = Arc::new(DamagedHooke {
        shear_modulus,
        lame_lambda,
    });
    problem.model.viscosity = Arc::new(LinearViscosity {
        shear: relaxation_time * shear_modulus,
        bulk: relaxation_time * lame_lambda,
    });
    problem
}

#[test]
fn elastic_step_limit_of_proportional_viscosity_is_twice_the_relaxation_time() {
    // H^{-1} K_G = I/τ on the free unknowns: every eigenvalue is 1/τ, k_max = 2τ
    let cases: Vec<(Problem<2>, f64)> = vec![
        (proportional(common::square(6), 1, 0.3), 0.3),
        (proportional(common::square(4), 2, 2.5), 2.5),
    ];
    for (mut problem, tau) in cases {
        problem.settings.contact = ContactTreatment::Implicit;
        let limit = Simulation::new(problem).unwrap().step_limit().unwrap();
        assert!(!limit.includes_contact);
        assert!(
            (limit.time_step - 2.0 * tau).abs() <= 1e-10 * tau,
            "{limit:?} vs 2τ = {}",
            2.0 * tau
        );
    }
    let mut problem = proportional(common::cube(3), 1, 0.8);
    problem.settings.contact = ContactTreatment::Implicit;
    let limit = Simulation::new(problem).unwrap().step_limit().unwrap();
    assert!((limit.time_step - 1.6).abs() <= 1e-10, "{limit:?}");
}

#[test]
fn contact_stiffness_lowers_the_step_limit() {
    // with the explicit normal compliance the limit shrinks as c_ν grows, like 1/c_ν
    let limits: Vec<f64> = [1.0, 1e2, 1e4]
        .iter()
        .map(|&stiffness| {
            let mut problem = proportional(common::square(6), 1, 1.0);
            problem.model.contact = Arc::new(NormalComplianceCoulomb {
                stiffness,
                friction: 0.3,
                wear: 0.0,
            });
            let limit = Simulation::new(problem).unwrap().step_limit().unwrap();
            assert!(limit.includes_contact);
            limit.time_step
        })
        .collect();
    assert!(
        limits[0] < 2.0 && limits[1] < limits[0] && limits[2] < limits[1],
        "{limits:?}"
    );
    let ratio = limits[1] / limits[2];
    assert!(
        (ratio - 100.0).abs() <= 5.0,
        "k_max(1e2)/k_max(1e4) = {ratio}"
    );
}

/// The unit square clamped at x = 0, resting on a foundation of stiffness c_ν at y = 0 and
/// pressed by (0, −0.1) on y = 1; no damage evolution. Returns the largest nodal velocity
/// over the last tenth of the run relative to the displacement.
fn settles(stiffness: f64, relative_step: f64) -> (f64, f64) {
    let mut data = common::quiet_data::<2>();
    data.traction = Some(Arc::new(|_x: &[f64; 2], _t: f64, normal: &[f64; 2]| {
        if normal[1] > 0.5 {
            [0.0, -0.1]
        } else {
            [0.0, 0.0]
        }
    }));
    let build = |steps: usize, final_time: f64| {
        let mut problem = common::problem(common::square(6), 1, data.clone(), final_time, steps);
        problem.model.contact = Arc::new(NormalComplianceCoulomb {
            stiffness,
            friction: 0.0,
            wear: 0.0,
        });
        problem.model.damage_source = Arc::new(DamageSourceFn(|_: &Tensor<2>, _: f64| 0.0));
        Simulation::new(problem).unwrap()
    };
    let limit = build(1, 1.0).step_limit().unwrap().time_step;
    let step = relative_step * limit;
    let final_time = 30.0;
    let steps = (final_time / step).round() as usize;
    let mut simulation = build(steps, steps as f64 * step);
    let mut late_velocity: f64 = 0.0;
    simulation
        .run(|report| {
            if report.state.step * 10 >= steps * 9 {
                let v = report
                    .state
                    .velocity
                    .iter()
                    .fold(0.0f64, |m, v| m.max(v.abs()));
                late_velocity = late_velocity.max(v);
            }
            Ok(())
        })
        .unwrap();
    let displacement = simulation
        .state()
        .displacement
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    (late_velocity / displacement, limit)
}

#[test]
fn explicit_scheme_settles_below_the_step_limit_and_not_above() {
    for stiffness in [10.0, 100.0] {
        let (below, limit) = settles(stiffness, 0.9);
        let (above, _) = settles(stiffness, 1.15);
        eprintln!("c_ν = {stiffness}: k_max = {limit:e}, late |v|/|u| at 0.9 k_max {below:e}, at 1.15 k_max {above:e}");
        assert!(
            below <= 1e-6,
            "c_ν = {stiffness}: no rest at 0.9 k_max ({below:e})"
        );
        assert!(
            above >= 1e-3,
            "c_ν = {stiffness}: rest at 1.15 k_max ({above:e})"
        );
    }
}
