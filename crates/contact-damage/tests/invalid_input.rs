//! Invalid input gets an error that names the problem: one test per class.

use crate::common;

use contact_damage::error::StepDatum;
use contact_damage::fem::space::LagrangeSpace;
use contact_damage::model::contact::ContactNodes;
use contact_damage::model::laws::LinearViscosity;
use contact_damage::scheme::velocity::{VelocityData, VelocityOperator, VelocitySettings};
use contact_damage::scheme::Simulation;
use contact_damage::Error;
use std::sync::Arc;

fn message_of<const D: usize>(problem: contact_damage::scheme::Problem<D>) -> String {
    match Simulation::new(problem) {
        Ok(_) => panic!("the problem should be rejected"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn simulation_rejects_initial_damage_outside_unit_interval() {
    let mut data = common::quiet_data::<2>();
    data.initial_damage = Arc::new(|x| 1.0 + x[0]);
    let message = message_of(common::problem(common::square(2), 1, data, 1.0, 4));
    assert!(
        message.contains("initial_damage") && message.contains("[0, 1]"),
        "{message}"
    );
}

#[test]
fn simulation_rejects_initial_displacement_on_clamped_side() {
    let mut data = common::quiet_data::<2>();
    data.initial_displacement = Arc::new(|_| [0.1, 0.0]);
    let message = message_of(common::problem(common::square(2), 1, data, 1.0, 4));
    assert!(
        message.contains("initial_displacement") && message.contains("Γ1"),
        "{message}"
    );
}

#[test]
fn simulation_rejects_non_finite_gap() {
    let mut data = common::quiet_data::<2>();
    // finite except at x = 0.5 of Γ3
    data.gap = Arc::new(|x, _| if x[0] == 0.5 { f64::NAN } else { 0.0 });
    let message = message_of(common::problem(common::square(2), 1, data, 1.0, 4));
    assert!(
        message.contains("gap") && message.contains("contact node") && message.contains("0.5"),
        "{message}"
    );
}

#[test]
fn simulation_rejects_nonpositive_final_time_and_zero_steps() {
    let message = message_of(common::problem(
        common::square(2),
        1,
        common::quiet_data::<2>(),
        0.0,
        4,
    ));
    assert!(message.contains("final_time"), "{message}");
    let message = message_of(common::problem(
        common::square(2),
        1,
        common::quiet_data::<2>(),
        1.0,
        0,
    ));
    assert!(message.contains("steps"), "{message}");
}

#[test]
fn simulation_rejects_nonpositive_damage_diffusion() {
    let mut problem = common::problem(common::square(2), 1, common::quiet_data::<2>(), 1.0, 4);
    problem.model.damage_diffusion = 0.0;
    let message = message_of(problem);
    assert!(message.contains("damage_diffusion"), "{message}");
}

#[test]
fn simulation_rejects_unsupported_degree() {
    let message = message_of(common::problem(
        common::square(2),
        3,
        common::quiet_data::<2>(),
        1.0,
        4,
    ));
    assert!(message.contains('3'), "{message}");
}

#[test]
fn simulation_rejects_invalid_law_parameters() {
    let mut problem = common::problem(common::square(2), 1, common::quiet_data::<2>(), 1.0, 4);
    problem.model.viscosity = Arc::new(LinearViscosity {
        shear: -1.0,
        bulk: 0.0,
    });
    let message = message_of(problem);
    assert!(message.contains("viscosity.shear"), "{message}");
    // finite, but beyond the scale of double precision
    let mut problem = common::problem(common::square(2), 1, common::quiet_data::<2>(), 1.0, 4);
    problem.model.viscosity = Arc::new(LinearViscosity {
        shear: 1e200,
        bulk: 0.0,
    });
    let message = message_of(problem);
    assert!(
        message.contains("`viscosity.shear` = 1e200") && message.contains("beyond 1e150"),
        "{message}"
    );
}

#[test]
fn velocity_step_rejects_bad_data() {
    let space = Arc::new(LagrangeSpace::new(Arc::new(common::square(2)), 1).unwrap());
    let contact = Arc::new(ContactNodes::new(&space).unwrap());
    let mut operator = VelocityOperator::new(
        space.clone(),
        Arc::new(LinearViscosity {
            shear: 1.0,
            bulk: 0.0,
        }),
        contact.clone(),
    )
    .unwrap();
    let n = space.num_nodes() * 2;
    let pressure = vec![0.0; contact.len()];
    let settings = VelocitySettings::default();
    // wrong length
    let short = vec![0.0; n - 1];
    let data = VelocityData {
        load: &short,
        normal_pressure: &pressure,
        friction_bound: &pressure,
        implicit_contact: None,
        prescribed: None,
    };
    let message = operator
        .solve(&data, &vec![0.0; n], &settings)
        .unwrap_err()
        .to_string();
    assert!(message.contains("sizes"), "{message}");
    // NaN load
    let mut load = vec![0.0; n];
    load[3] = f64::NAN;
    let data = VelocityData {
        load: &load,
        normal_pressure: &pressure,
        friction_bound: &pressure,
        implicit_contact: None,
        prescribed: None,
    };
    let message = operator
        .solve(&data, &vec![0.0; n], &settings)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("non-finite") && message.contains("dof 3"),
        "{message}"
    );
    // negative friction bound
    let load = vec![0.0; n];
    let mut bound = pressure.clone();
    bound[0] = -1.0;
    let data = VelocityData {
        load: &load,
        normal_pressure: &pressure,
        friction_bound: &bound,
        implicit_contact: None,
        prescribed: None,
    };
    let message = operator
        .solve(&data, &vec![0.0; n], &settings)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("friction bound") && message.contains("contact node"),
        "{message}"
    );
    // finite data beyond the scale of double precision: a load, a pressure, a friction bound
    // (at the limit itself all three are accepted)
    let limit = contact_damage::algebra::linalg::MAGNITUDE_LIMIT;
    for (size, expected) in [(limit, None), (1e200, Some("out of scale"))] {
        for which in [StepDatum::Load, StepDatum::Contact] {
            let mut load = vec![0.0; n];
            let mut pressure = vec![0.0; contact.len()];
            match which {
                StepDatum::Load => load[3] = -size,
                _ => pressure[1] = size,
            }
            let data = VelocityData {
                load: &load,
                normal_pressure: &pressure,
                friction_bound: &pressure,
                implicit_contact: None,
                prescribed: None,
            };
            match (operator.solve(&data, &vec![0.0; n], &settings), expected) {
                (Ok(_), None) => {}
                (
                    Err(Error::StepData {
                        quantity,
                        out_of_scale: true,
                        message,
                    }),
                    Some(expected),
                ) => {
                    assert_eq!(quantity, which);
                    assert!(
                        message.contains(expected) && message.contains("1e200"),
                        "{message}"
                    );
                }
                (outcome, _) => panic!(
                    "{which:?} of size {size:e}: {outcome:?}",
                    outcome = outcome.err()
                ),
            }
        }
    }
}
