//! Prescribed displacement on parts of Γ1, rollers and a moving, negative gap:
//! - the velocity step (5.1) with prescribed velocities on constrained unknowns satisfies its
//!   KKT conditions on the free unknowns, recomputed here with this file's own quadrature loop
//!   for N(v) (linear and nonlinear 𝒜), takes v_c = p_c exactly, and its reactions equal the
//!   assembled residual N(v) − F on the constrained unknowns;
//! - in the scheme, every velocity step takes the prescribed displacement (u_{n−1} + k v_n =
//!   u_D(t_n) with the solver's v_n, its KKT conditions recomputed on the free unknowns, its part
//!   reactions equal to N(v) − F on the constrained ones), a roller leaves the tangential
//!   component free, the explicit scheme takes the gap at t_{n−1} (the implicit
//!   normal compliance at t_n), a negative gap presses the body;
//! - errors: a part on Γ3, a non-finite gap or u_D, each naming what is wrong.

use crate::common;

use common::{internal_force, regime_contact_data, velocity_kkt, Random, VelocityProblem, REGIMES};

use contact_damage::fem::mesh::{BoundaryPart, BoundaryPart::*, Mesh};
use contact_damage::fem::space::LagrangeSpace;
use contact_damage::model::contact::ContactNodes;
use contact_damage::model::laws::{LinearViscosity, SaturatingViscosity, Viscosity};
use contact_damage::scheme::velocity::{VelocityData, VelocityOperator, VelocitySettings};
use contact_damage::scheme::{
    ContactTreatment, Data, PointScalarField, PrescribedDisplacement, Simulation,
};
use nalgebra::SVector;
use proptest::prelude::*;
use std::sync::Arc;

/// Unit square: Γ1 = {x = 0} ∪ {x = 1}, Γ3 = {y = 0}, Γ2 = {y = 1}.
fn square_two_grips(cells: usize) -> Mesh<2> {
    Mesh::box_mesh(
        [0.0, 0.0],
        [1.0, 1.0],
        [cells, cells],
        [[Dirichlet, Dirichlet], [Contact, Neumann]],
    )
    .unwrap()
}

/// One velocity step with random loads, contact data and prescribed velocities: x = 0 fully
/// constrained, x = 1 with a random component mask. Returns (KKT residual recomputed here,
/// largest |v_c − p_c|, largest relative difference reaction − (N(v) − F) on the constrained
/// unknowns).
fn prescribed_step(
    law: Arc<dyn Viscosity<2>>,
    degree: usize,
    regime: usize,
    seed: u64,
) -> (f64, f64, f64) {
    let mut rng = Random::new(seed);
    let space = Arc::new(LagrangeSpace::new(Arc::new(square_two_grips(4)), degree).unwrap());
    let contact = Arc::new(ContactNodes::new(&space).unwrap());
    let n = space.num_nodes() * 2;
    let mut constrained = vec![false; n];
    for node in space.boundary_nodes(BoundaryPart::Dirichlet) {
        let gripped = space.node(node)[0] == 0.0;
        for i in 0..2 {
            constrained[node * 2 + i] = gripped || rng.next() < 0.5;
        }
    }
    let mut operator = VelocityOperator::with_constraints(
        space.clone(),
        law.clone(),
        contact.clone(),
        constrained.clone(),
    )
    .unwrap();
    let load: Vec<f64> = (0..n).map(|_| 0.05 * rng.symmetric()).collect();
    let prescribed: Vec<f64> = (0..n)
        .map(|dof| {
            if constrained[dof] {
                0.2 * rng.symmetric()
            } else {
                f64::NAN // ignored on free unknowns
            }
        })
        .collect();
    let (pressure, bound) = regime_contact_data(REGIMES[regime], contact.len(), &mut rng);
    let data = VelocityData {
        load: &load,
        normal_pressure: &pressure,
        friction_bound: &bound,
        implicit_contact: None,
        prescribed: Some(&prescribed),
    };
    let start: Vec<f64> = (0..n).map(|_| rng.symmetric()).collect();
    let solution = operator
        .solve(&data, &start, &VelocitySettings::default())
        .unwrap();
    let cartesian_force = internal_force(&space, law.as_ref(), &solution.velocity);
    // reactions: N(v) − F on the constrained unknowns (Cartesian; no contact node is constrained)
    let mut reaction_error: f64 = 0.0;
    let mut prescribed_error: f64 = 0.0;
    let scale = cartesian_force
        .iter()
        .chain(&load)
        .fold(0.0f64, |m, v| m.max(v.abs()));
    for dof in (0..n).filter(|&dof| constrained[dof]) {
        let expected = cartesian_force[dof] - load[dof];
        reaction_error = reaction_error.max((solution.reaction[dof] - expected).abs() / scale);
        prescribed_error = prescribed_error.max((solution.velocity[dof] - prescribed[dof]).abs());
    }
    for dof in (0..n).filter(|&dof| !constrained[dof]) {
        assert_eq!(solution.reaction[dof], 0.0, "reaction on a free unknown");
    }
    // stationarity on the free unknowns in the system frame
    let force = operator.to_system(&cartesian_force);
    let v = operator.to_system(&solution.velocity);
    let mut f = operator.to_system(&load);
    for (k, &node) in contact.nodes.iter().enumerate() {
        f[node * 2] -= contact.weights[k] * pressure[k];
    }
    let mut residual: Vec<f64> = force.iter().zip(&f).map(|(a, b)| a - b).collect();
    let mut complementarity: f64 = 0.0;
    for (k, &node) in contact.nodes.iter().enumerate() {
        let weight = contact.weights[k] * bound[k];
        let lambda = solution.multipliers[k];
        residual[node * 2 + 1] += weight * lambda;
        complementarity = complementarity.max(lambda.abs() - 1.0);
        let tangential = v[node * 2 + 1];
        if weight > 0.0 && tangential != 0.0 {
            complementarity = complementarity.max((lambda - tangential.signum()).abs());
        }
    }
    let free_scale = (0..n)
        .filter(|&dof| !constrained[dof])
        .fold(0.0f64, |m, dof| m.max(f[dof].abs()).max(force[dof].abs()));
    let stationarity = (0..n)
        .filter(|&dof| !constrained[dof])
        .fold(0.0f64, |m, dof| m.max(residual[dof].abs()))
        / free_scale;
    (
        stationarity.max(complementarity),
        prescribed_error,
        reaction_error,
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]

    #[test]
    fn velocity_step_with_prescribed_velocities_satisfies_kkt_linear(
        seed in any::<u64>(), regime in 0usize..4, degree in 1usize..=2,
    ) {
        let law = Arc::new(LinearViscosity { shear: 1.0, bulk: 0.3 });
        let (kkt, prescribed, reaction) = prescribed_step(law, degree, regime, seed);
        prop_assert!(kkt <= 1e-10, "KKT residual {kkt:e}");
        prop_assert_eq!(prescribed, 0.0);
        prop_assert!(reaction <= 1e-12, "reaction differs by {reaction:e}");
    }

    #[test]
    fn velocity_step_with_prescribed_velocities_satisfies_kkt_nonlinear(
        seed in any::<u64>(), regime in 0usize..4, degree in 1usize..=2,
    ) {
        let law = Arc::new(SaturatingViscosity {
            linear: LinearViscosity { shear: 1.0, bulk: 0.3 },
            extra_shear: 5.0,
            rate_scale: 0.01,
        });
        let (kkt, prescribed, reaction) = prescribed_step(law, degree, regime, seed);
        prop_assert!(kkt <= 1e-10, "KKT residual {kkt:e}");
        prop_assert_eq!(prescribed, 0.0);
        prop_assert!(reaction <= 1e-12, "reaction differs by {reaction:e}");
    }
}

/// The approach u_y = −0.05 t (1 + x) of the top y = 1 (both components: u_x = 0.02 t x) and a
/// roller on x = 0 (u_x = 0); Γ3 = {y = 0} against an obstacle with the gap g(x, t).
fn pressed_square(gap: PointScalarField<2>, contact: ContactTreatment) -> Simulation<2> {
    let mesh = Mesh::box_mesh(
        [0.0, 0.0],
        [1.0, 1.0],
        [6, 6],
        [[Dirichlet, Neumann], [Contact, Dirichlet]],
    )
    .unwrap();
    let top = mesh.boundary_facets_where(|x| x[1] == 1.0);
    let left = mesh.boundary_facets_where(|x| x[0] == 0.0);
    let mut data: Data<2> = common::quiet_data();
    data.gap = gap;
    data.dirichlet = vec![
        PrescribedDisplacement {
            name: "top".into(),
            facets: top,
            components: [
                Some(Arc::new(|x: &[f64; 2], t: f64| 0.02 * t * x[0])),
                Some(Arc::new(|x: &[f64; 2], t: f64| -0.05 * t * (1.0 + x[0]))),
            ],
            traction: None,
        },
        PrescribedDisplacement {
            name: "roller".into(),
            facets: left,
            components: [Some(Arc::new(|_: &[f64; 2], _: f64| 0.0)), None],
            traction: None,
        },
    ];
    let mut problem = common::problem(mesh, 1, data, 1.0, 8);
    problem.settings.contact = contact;
    Simulation::new(problem).unwrap()
}

/// The scheme's velocity step takes the prescribed displacement: on the constrained unknowns
/// u_{n−1} + k v_n = u_D(t_n) with the solver's v_n (to rounding; the scheme then sets u_n =
/// u_D(t_n) exactly), and with those v_c the KKT conditions of (5.1) hold on the free unknowns,
/// recomputed here from the step's loads ([`Simulation::step_loads`] at the state n − 1), p_ν,
/// p_τ and this file's N(v); the part reactions sum the residual N(v) − F of the constrained
/// unknowns. An overwrite of u_n on Γ1 alone, with the velocity step solved for other v_c,
/// fails the first check or the second (the free unknowns next to Γ1 see the v_c through N(v)).
/// The roller leaves u_y free and carries no tangential reaction.
#[test]
fn scheme_velocity_steps_take_the_prescribed_displacement_and_the_roller_slides() {
    let mut simulation = pressed_square(Arc::new(|_, _| 0.0), ContactTreatment::Explicit);
    let constrained = simulation.velocity_operator().constrained().to_vec();
    let space = simulation.space().clone();
    let contact = simulation.contact().clone();
    let law = common::model::<2>().viscosity;
    let k = simulation.time_step();
    assert_eq!(simulation.dirichlet_parts(), ["top", "roller"]);
    let u_d = |x: &[f64; 2], t: f64| {
        if x[1] == 1.0 {
            [0.02 * t * x[0], -0.05 * t * (1.0 + x[0])]
        } else {
            [0.0, f64::NAN] // the roller: u_x only
        }
    };
    let mut roller_moved: f64 = 0.0;
    let mut pressed = false;
    let mut worst_kkt: f64 = 0.0;
    let mut worst_reached: f64 = 0.0;
    while simulation.state().step < simulation.steps() {
        let t = (simulation.state().step + 1) as f64 * k;
        let previous = simulation.state().displacement.clone();
        let (load, _) = simulation.step_loads(t);
        let outcome = simulation.step().unwrap();
        let velocity = &outcome.velocity.velocity;
        let u = &simulation.state().displacement;
        // the prescribed velocities p_c = (u_D(t_n) − u_{n−1,c})/k of the constrained unknowns
        let mut prescribed = vec![0.0; velocity.len()];
        let mut displacement_scale: f64 = 0.0;
        for node in 0..space.num_nodes() {
            let x = space.node(node);
            for i in 0..2 {
                let dof = node * 2 + i;
                if constrained[dof] {
                    let target = u_d(&x, t)[i];
                    prescribed[dof] = (target - previous[dof]) / k;
                    assert_eq!(u[dof], target, "u_n = u_D(t_n) at {x:?}");
                    displacement_scale = displacement_scale.max(target.abs());
                }
            }
            if x[1] == 1.0 {
                assert!(constrained[node * 2] && constrained[node * 2 + 1]);
            } else if x[0] == 0.0 {
                assert!(constrained[node * 2] && !constrained[node * 2 + 1]);
                roller_moved = roller_moved.max(u[node * 2 + 1].abs());
            } else {
                assert!(!constrained[node * 2] && !constrained[node * 2 + 1]);
            }
        }
        // u_{n−1} + k v_n of the solver's v_n on Γ1
        for dof in (0..velocity.len()).filter(|&dof| constrained[dof]) {
            let reached = previous[dof] + k * velocity[dof];
            worst_reached = worst_reached.max((reached - u[dof]).abs() / displacement_scale);
        }
        let problem = VelocityProblem {
            space: &space,
            law: law.as_ref(),
            contact: &contact,
            load: &load,
            normal_pressure: &outcome.normal_pressure,
            friction_bound: &outcome.friction_bound,
            constrained: &constrained,
            prescribed: &prescribed,
        };
        let kkt = velocity_kkt(&problem, velocity, &outcome.velocity.multipliers);
        worst_kkt = worst_kkt.max(kkt.residual());
        // the part reactions: the residual N(v) − F summed over the constrained unknowns
        let force = internal_force(&space, law.as_ref(), velocity);
        let reactions = simulation.part_reactions(&outcome.velocity.reaction);
        assert_eq!(reactions.len(), 2);
        let force_scale = force
            .iter()
            .chain(&load)
            .fold(0.0f64, |m, f| m.max(f.abs()));
        for i in 0..2 {
            let expected: f64 = (0..space.num_nodes())
                .map(|node| node * 2 + i)
                .filter(|&dof| constrained[dof])
                .map(|dof| force[dof] - load[dof])
                .sum();
            let reported: f64 = reactions.iter().map(|part| part[i]).sum();
            assert!(
                (reported - expected).abs() <= 1e-12 * force_scale,
                "step at t = {t}, component {i}: reactions {reported} vs N(v) − F {expected}"
            );
        }
        // the roller carries no tangential reaction by construction; the top pushes down
        assert_eq!(reactions[1][1], 0.0);
        pressed |= reactions[0][1] < 0.0 && outcome.normal_pressure.iter().any(|&p| p > 0.0);
    }
    // observed: u_{n−1} + k v_n = u_D(t_n) bit for bit, KKT residuals up to 1.4e-15, reactions
    // equal to N(v) − F to 3.9e-16 of the largest force
    assert!(
        worst_reached <= 1e-14,
        "u_(n−1) + k v_n differs from u_D(t_n) by {worst_reached:e}"
    );
    assert!(worst_kkt <= 1e-10, "recomputed KKT residual {worst_kkt:e}");
    assert!(
        roller_moved > 1e-3,
        "the roller's free u_y moved by {roller_moved:e}"
    );
    assert!(pressed, "the top pressed the body onto the foundation");
}

/// p_ν(u_ν − g) per contact node for a state and a time.
fn pressures(simulation: &Simulation<2>, displacement: &[f64], time: f64) -> Vec<f64> {
    let contact = simulation.contact();
    let gap = simulation.gap_at(time).unwrap();
    let law = contact_damage::model::laws::NormalComplianceCoulomb {
        stiffness: 10.0,
        friction: 0.4,
        wear: 0.0,
    };
    use contact_damage::model::laws::ContactLaw;
    (0..contact.len())
        .map(|k| {
            let node = contact.nodes[k];
            let u = SVector::<f64, 2>::from_column_slice(&displacement[node * 2..node * 2 + 2]);
            law.normal_pressure(u.dot(&contact.normal(k)) - gap[k])
        })
        .collect()
}

#[test]
fn moving_negative_gap_is_taken_at_the_start_of_the_step_explicit_and_at_its_end_implicit() {
    // the obstacle rises through y = 0: g = 0.02 − 0.2 t, negative for t > 0.1
    let gap: PointScalarField<2> = Arc::new(|x: &[f64; 2], t: f64| 0.02 - 0.2 * t + 0.01 * x[0]);
    for treatment in [ContactTreatment::Explicit, ContactTreatment::Implicit] {
        let mut simulation = pressed_square(gap.clone(), treatment);
        let k = simulation.time_step();
        let mut previous = simulation.state().displacement.clone();
        let mut negative_gap_contact = false;
        while simulation.state().step < simulation.steps() {
            let n = simulation.state().step + 1;
            let used = simulation.step().unwrap().normal_pressure;
            let expected = match treatment {
                ContactTreatment::Explicit => pressures(&simulation, &previous, (n - 1) as f64 * k),
                ContactTreatment::Implicit => {
                    pressures(&simulation, &simulation.state().displacement, n as f64 * k)
                }
            };
            assert_eq!(used, expected, "{treatment:?}: p_ν of step {n}");
            let gap_now = simulation.gap_at(n as f64 * k).unwrap();
            negative_gap_contact |= gap_now.iter().zip(&used).any(|(g, p)| *g < 0.0 && *p > 0.0);
            previous = simulation.state().displacement.clone();
        }
        assert!(
            negative_gap_contact,
            "{treatment:?}: no contact where g < 0"
        );
    }
}

/// The error of setting up a simulation on the unit square (`cells` per side, Γ1 = {x = 0},
/// Γ3 = {y = 0}) with the one part `name` on the side where `on_side` holds.
fn setup_error(
    cells: usize,
    name: &str,
    on_side: fn(&[f64; 2]) -> bool,
    components: [Option<PointScalarField<2>>; 2],
) -> String {
    let mesh = common::square(cells);
    let facets = mesh.boundary_facets_where(on_side);
    let mut data: Data<2> = common::quiet_data();
    data.dirichlet = vec![PrescribedDisplacement {
        name: name.into(),
        facets,
        components,
        traction: None,
    }];
    let Err(error) = Simulation::new(common::problem(mesh, 1, data, 1.0, 2)) else {
        panic!("part `{name}` was accepted");
    };
    error.to_string()
}

#[test]
fn a_part_on_the_contact_boundary_is_refused_naming_it() {
    let message = setup_error(
        4,
        "floor",
        |x| x[1] == 0.0,
        [None, Some(Arc::new(|_: &[f64; 2], _: f64| 0.0))],
    );
    assert!(
        message.contains("`floor`") && message.contains("Γ3"),
        "{message}"
    );
}

#[test]
fn a_gap_or_prescribed_displacement_that_turns_non_finite_stops_the_step_naming_it() {
    let gap: PointScalarField<2> = Arc::new(|_, t| if t > 0.3 { f64::NAN } else { 0.0 });
    let mut simulation = pressed_square(gap, ContactTreatment::Explicit);
    let error = simulation.run(|_| Ok(())).unwrap_err().to_string();
    assert!(
        error.contains("gap") && error.contains("contact node") && error.contains("t = 0.375"),
        "{error}"
    );

    let mesh = common::square(2);
    let left = mesh.boundary_facets_where(|x| x[0] == 0.0);
    let mut data: Data<2> = common::quiet_data();
    data.dirichlet = vec![PrescribedDisplacement {
        name: "grip".into(),
        facets: left,
        components: [
            Some(Arc::new(|_: &[f64; 2], t: f64| {
                (0.5 - t).sqrt() - 0.5f64.sqrt()
            })),
            // u_y too: a grip of u_x alone would leave the body free to slide along y
            Some(Arc::new(|_: &[f64; 2], _: f64| 0.0)),
        ],
        traction: None,
    }];
    let mut simulation = Simulation::new(common::problem(mesh, 1, data, 1.0, 4)).unwrap();
    let error = simulation.run(|_| Ok(())).unwrap_err().to_string();
    assert!(
        error.contains("`grip`") && error.contains("component 0") && error.contains("NaN"),
        "{error}"
    );
}

/// Two parts that meet and prescribe one component: values that agree (to rounding) are
/// accepted, values that differ at some time stop the run at that time naming both parts, the
/// node and the component.
#[test]
fn parts_that_meet_with_different_values_are_refused_naming_both() {
    let grips = |roller: fn(&[f64; 2], f64) -> f64| {
        let mesh = Mesh::box_mesh(
            [0.0, 0.0],
            [1.0, 1.0],
            [2, 2],
            [[Dirichlet, Neumann], [Contact, Dirichlet]],
        )
        .unwrap();
        let top = mesh.boundary_facets_where(|x| x[1] == 1.0);
        let left = mesh.boundary_facets_where(|x| x[0] == 0.0);
        let mut data: Data<2> = common::quiet_data();
        data.dirichlet = vec![
            PrescribedDisplacement {
                name: "top".into(),
                facets: top,
                components: [
                    Some(Arc::new(|_: &[f64; 2], t: f64| 0.03 * t)),
                    Some(Arc::new(|_: &[f64; 2], _: f64| 0.0)),
                ],
                traction: None,
            },
            PrescribedDisplacement {
                name: "left".into(),
                facets: left,
                components: [Some(Arc::new(roller)), None],
                traction: None,
            },
        ];
        Simulation::new(common::problem(mesh, 1, data, 1.0, 4))
    };
    // the same function written another way: agrees to rounding at the corner (0, 1)
    let mut agreeing = grips(|_, t| t * 0.1 * 0.3).unwrap();
    agreeing.run(|_| Ok(())).unwrap();
    // equal at t = 0, different from the first step on
    let mut conflicting = grips(|_, t| 0.05 * t).unwrap();
    let error = conflicting.run(|_| Ok(())).unwrap_err().to_string();
    assert!(
        error.contains("`top`")
            && error.contains("`left`")
            && error.contains("component 0")
            && error.contains("[0.0, 1.0]")
            && error.contains("t = 0.25"),
        "{error}"
    );
}

/// A body whose only Γ1 side prescribes u_x is free to slide along y: refused before anything
/// is factorized, naming the motion and the part (the scheme used to run on the singular
/// matrix of (5.1) until something else failed).
#[test]
fn a_body_free_to_move_rigidly_is_refused_naming_the_motion_and_the_part() {
    let message = setup_error(
        2,
        "grip",
        |x| x[0] == 0.0,
        [Some(Arc::new(|_: &[f64; 2], t: f64| 0.01 * t)), None],
    );
    assert!(
        message.contains("can move rigidly")
            && message.contains("translation along y")
            && message.contains("`grip`"),
        "{message}"
    );
}
