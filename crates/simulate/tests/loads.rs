//! Problem files with a prescribed approach of a part of Γ1, a roller, a moving gap and a load
//! curve; errors that name the file and the key.

use contact_damage::scheme::Simulation;
use simulate::problem::{LoadCurve, ProblemSetup};
use std::path::Path;

/// A block [0, 1] × [0, 0.5] on a rigid foundation (Γ3 = {y = 0}), its top pressed down by
/// 0.02 over t ∈ [0, 1] and held (u_x = 0 there too), its left side on a roller (u_x = 0); the
/// implicit normal compliance takes the stiff foundation (c_ν = 1000) at k = 0.2 (the elastic
/// forces stay explicit in (5.1): k is below the viscous time η/μ = 1).
const PRESSED_BLOCK: &str = r#"
dim = 2
degree = 1
final_time = 16.0
steps = 80

[mesh]
box = { lower = [0, 0], upper = [1, 0.5], cells = [12, 6], sides = { y_min = "contact" } }

[laws]
viscosity = { kind = "linear", shear = 1.0, bulk = 1.0 }
elasticity = { kind = "damaged_hooke", shear_modulus = 1.0, lame_lambda = 1.5 }
damage_source = { kind = "expression", expr = "0" }
contact = { stiffness = 1000.0, friction = 0.3 }
damage_diffusion = 1.0

[loads]
gap = "0.002*(1 - min(t, 1))"

[scheme]
contact = "implicit"

[[displacement]]
part = "y_max"
x = "0"
y = "-0.02*min(t, 1)"

[[displacement]]
part = "x_min"
x = "0"
"#;

fn setup(text: &str) -> Result<ProblemSetup<2>, String> {
    let file =
        simulate::problem::parse_problem_file(text, "block.toml").map_err(|e| e.to_string())?;
    ProblemSetup::<2>::new(file, Path::new("block.toml")).map_err(|e| e.to_string())
}

#[test]
fn a_pressed_block_balances_the_reaction_of_its_grip_with_the_contact_force() {
    let setup = setup(PRESSED_BLOCK).unwrap();
    let mut simulation = Simulation::new(setup.problem.clone()).unwrap();
    assert_eq!(simulation.dirichlet_parts(), ["y_max", "x_min"]);
    let mut last = None;
    simulation
        .run(|report| {
            // the resultant contact force on the body: ω_a p_ν(a) (−ν_a) plus friction
            let contact = report.contact;
            let mut force = [0.0; 2];
            for k in 0..contact.len() {
                let normal = contact.normal(k);
                let frame = &contact.frames[k];
                let friction = -report.friction_bound[k] * report.multipliers[k];
                for i in 0..2 {
                    force[i] += contact.weights[k]
                        * (-report.normal_pressure[k] * normal[i] + friction * frame[(i, 1)]);
                }
            }
            let reaction: Vec<f64> = (0..2)
                .map(|i| report.reactions.iter().map(|r| r[i]).sum())
                .collect();
            let speed = report
                .state
                .velocity
                .iter()
                .fold(0.0f64, |m, v| m.max(v.abs()));
            last = Some((force, reaction, speed, report.velocity_stats.kkt_residual));
            Ok(())
        })
        .unwrap();
    let (force, reaction, speed, kkt) = last.unwrap();
    assert!(kkt <= 1e-10, "KKT residual {kkt:e}");
    assert!(speed < 1e-6, "not at equilibrium: |v| = {speed:e}");
    let pressed = force[1];
    assert!(
        pressed > 1e-3,
        "the block presses on the foundation: P = {pressed:e}"
    );
    for i in 0..2 {
        // the residual of the equilibrium, summed: reactions + contact force = 0 up to the
        // KKT tolerance of the step (relative to the forces it balances)
        assert!(
            (reaction[i] + force[i]).abs() <= 1e-8 * pressed,
            "component {i}: reaction {} against contact force {}",
            reaction[i],
            force[i]
        );
    }
}

#[test]
fn problem_file_loads_are_checked_naming_the_key() {
    for (from, to, expected) in [
        (
            "part = \"x_min\"",
            "part = \"y_min\"",
            "key `displacement[1].part`: side `y_min` is the contact boundary Γ3",
        ),
        (
            "part = \"x_min\"",
            "part = \"x_left\"",
            "key `displacement[1].part`: unknown side",
        ),
        (
            "part = \"x_min\"\nx = \"0\"",
            "part = \"x_min\"\nx = \"log(y - 0.25)\"",
            "key `displacement[1].x`",
        ),
        (
            "gap = \"0.002*(1 - min(t, 1))\"",
            "gap = \"1/(t - 8)\"",
            "key `loads.gap`",
        ),
        (
            "gap = \"0.002*(1 - min(t, 1))\"",
            "traction_curve = [[0, 0], [2, 1], [1, 1]]",
            "key `loads.traction_curve[2]`: times must increase strictly",
        ),
        (
            "gap = \"0.002*(1 - min(t, 1))\"",
            "traction_curve = [[0, 0, 1]]",
            "key `loads.traction_curve[0]`",
        ),
    ] {
        assert!(PRESSED_BLOCK.contains(from), "test setup: {from}");
        let text = PRESSED_BLOCK.replacen(from, to, 1);
        let Err(message) = setup(&text) else {
            panic!("`{to}` was accepted");
        };
        assert!(
            message.contains("block.toml") && message.contains(expected),
            "{message}"
        );
    }
}

#[test]
fn a_load_curve_is_piecewise_linear_and_constant_outside_its_times() {
    let curve = LoadCurve::new(
        "f.toml",
        "k",
        &[vec![1.0, 0.0], vec![2.0, 4.0], vec![4.0, 2.0]],
    )
    .unwrap();
    for (t, expected) in [
        (0.0, 0.0),
        (1.0, 0.0),
        (1.5, 2.0),
        (2.0, 4.0),
        (3.0, 3.0),
        (4.0, 2.0),
        (9.0, 2.0),
    ] {
        assert_eq!(curve.factor(t), expected, "t = {t}");
    }
}

/// The plate with a hole (Gmsh): its top group pressed down, its right group on a roller.
const GMSH_PLATE: &str = r#"
dim = 2
degree = 1
final_time = 0.2
steps = 4

[mesh]
gmsh = { file = "plate_with_hole_2d.msh", clamped = ["clamped"], traction = ["hole"], contact = ["bottom"] }

[laws]
viscosity = { kind = "linear", shear = 1.0, bulk = 1.0 }
elasticity = { kind = "damaged_hooke", shear_modulus = 1.0, lame_lambda = 1.0 }
damage_source = { kind = "expression", expr = "0" }
contact = { stiffness = 10.0, friction = 0.3 }
damage_diffusion = 1.0

[[displacement]]
part = "top"
y = "-0.05*t"

[[displacement]]
part = "right"
x = "0"
"#;

fn gmsh_setup(text: &str) -> Result<ProblemSetup<2>, String> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/plate.toml");
    let file =
        simulate::problem::parse_problem_file(text, "plate.toml").map_err(|e| e.to_string())?;
    ProblemSetup::<2>::new(file, &path).map_err(|e| e.to_string())
}

#[test]
fn gmsh_groups_take_a_prescribed_displacement_and_a_roller() {
    let setup = gmsh_setup(GMSH_PLATE).unwrap();
    let mut simulation = Simulation::new(setup.problem.clone()).unwrap();
    assert_eq!(simulation.dirichlet_parts(), ["top", "right", "clamped"]);
    let space = simulation.space().clone();
    let constrained = simulation.velocity_operator().constrained().to_vec();
    let (mut top, mut right) = (0, 0);
    simulation
        .run(|report| {
            let t = report.state.time;
            for node in 0..space.num_nodes() {
                let x = space.node(node);
                let u = &report.state.displacement[node * 2..node * 2 + 2];
                if x[1] == 1.0 && x[0] > 0.0 {
                    top += 1;
                    assert!(constrained[node * 2 + 1]);
                    assert_eq!(u[1], -0.05 * t, "top node {x:?}");
                    // u_x is free on the top except at the corners of other parts
                    if x[0] < 2.0 {
                        assert!(!constrained[node * 2]);
                    }
                } else if x[0] == 2.0 && x[1] > 0.0 {
                    right += 1;
                    assert!(constrained[node * 2] && !constrained[node * 2 + 1]);
                    assert_eq!(u[0], 0.0, "right node {x:?}");
                }
            }
            assert!(report.reactions[0][1] < 0.0, "the top is pushed down");
            Ok(())
        })
        .unwrap();
    assert!(top > 0 && right > 0);
}

#[test]
fn gmsh_parts_on_the_contact_group_or_missing_are_refused_naming_the_key() {
    for (from, to, expected) in [
        (
            "part = \"top\"",
            "part = \"bottom\"",
            "key `displacement[0].part`: group \"bottom\" is the contact boundary Γ3",
        ),
        (
            "part = \"right\"",
            "part = \"hole\"",
            "key `displacement[1].part`: group \"hole\" is a traction group",
        ),
        (
            "part = \"top\"",
            "part = \"lid\"",
            "key `displacement[0].part`",
        ),
    ] {
        let text = GMSH_PLATE.replacen(from, to, 1);
        let Err(message) = gmsh_setup(&text) else {
            panic!("`{to}` was accepted");
        };
        assert!(
            message.contains("plate.toml") && message.contains(expected),
            "{message}"
        );
    }
}

/// Runs `text` (the pressed block's file, modified) with `simulate`'s driver into a scratch
/// folder: the error message, if any.
fn run_block(text: &str, name: &str) -> Result<(), String> {
    let setup = setup(text)?;
    let options = simulate::run::RunOptions {
        out: Some(crate::common::scratch(name)),
        overwrite: true,
        quiet: true,
        ..simulate::run::RunOptions::default()
    };
    simulate::run::run(&setup, &options)
        .map(|_| ())
        .map_err(|e| e.to_string())
}

/// A part declared a symmetry plane must fix only components tangential to Γ3 where it meets
/// Γ3: the roller u_x = 0 on x = 0 (Γ3 = {y = 0}) declared so runs, and keeps its corner node in
/// the contact rule; u_y prescribed on x = 0 fixes the corner's normal component and is refused at
/// `displacement[1].symmetry`, naming the node and the normal. Undeclared, the same part runs
/// (its corner node leaves the contact rule, as a prescribed normal displacement should).
#[test]
fn a_symmetry_plane_that_fixes_the_normal_of_the_contact_boundary_is_refused() {
    let roller = "part = \"x_min\"\nx = \"0\"\n";
    assert!(PRESSED_BLOCK.contains(roller));
    let declared = PRESSED_BLOCK.replace(roller, &format!("{roller}symmetry = true\n"));
    run_block(&declared, "symmetry-roller").unwrap();
    let setup = setup(&declared).unwrap();
    let simulation = Simulation::new(setup.problem.clone()).unwrap();
    let corner = (0..simulation.space().num_nodes())
        .find(|&n| simulation.space().node(n) == [0.0, 0.0])
        .unwrap();
    assert!(simulation.contact().index_of_node[corner].is_some());

    // u_y on x = 0 agreeing with the top's at the corner (0, 0.5), zero at the contact corner
    let normal = "part = \"x_min\"\ny = \"-0.04*y*min(t, 1)\"\n";
    let across = PRESSED_BLOCK.replace(roller, &format!("{normal}symmetry = true\n"));
    let error = run_block(&across, "symmetry-across").unwrap_err();
    assert!(
        error.contains("block.toml")
            && error.contains("displacement[1].symmetry")
            && error.contains("[0.0, 0.0]")
            && error.contains("ν = [0.0, -1.0]"),
        "{error}"
    );
    let undeclared = PRESSED_BLOCK.replace(roller, normal);
    run_block(&undeclared, "symmetry-undeclared").unwrap();
}
