//! The fixed damage case of the iteration-count test (`tests/damage_iterations.rs`) and of the
//! `damage_iterations` example: (5.2) alone on the unit square, P1 on an N × N Kuhn mesh, with
//! κ = 0.01, T = 0.25 and 16 steps (k = 1/64, the same for every N), β_0 = 1 − ½ b(x − c(0)) and
//! a damage source H − S b(x − c(t)) (H = 1, S = 40) whose centre c(t) = (0.3 + 1.6 t, 0.5) moves along x, with
//! b(y) = exp(−|y|²/0.02). Both bounds become active (β = 0 under the source once it has
//! eroded the material, β = 1 away from it) and the active sets move with the source.

use contact_damage::algebra::linalg::multiply;
use contact_damage::fem::mesh::{BoundaryPart, Mesh};
use contact_damage::fem::space::LagrangeSpace;
use contact_damage::scheme::damage::{assemble_damage_matrix, DamageOperator};
use contact_damage::solvers::box_qp::{BoxQpMethod, BoxQpSettings, BoxQpStats};
use std::sync::Arc;

/// κ of the case.
pub const DIFFUSION: f64 = 0.01;
/// Final time T.
pub const FINAL_TIME: f64 = 0.25;
/// Number of time steps of the fixed case (k = T / STEPS for every N).
pub const STEPS: usize = 16;
/// Strength S of the source.
pub const STRENGTH: f64 = 40.0;
/// A constant positive part H of the source, which keeps β = 1 active away from the bump.
pub const HEALING: f64 = 1.0;

fn bump(x: [f64; 2], centre: [f64; 2]) -> f64 {
    let r2 = (x[0] - centre[0]).powi(2) + (x[1] - centre[1]).powi(2);
    (-r2 / 0.02).exp()
}

fn centre(t: f64) -> [f64; 2] {
    [0.3 + 1.6 * t, 0.5]
}

/// Runs the case on an N × N mesh with the box QP method `method` and `steps` time steps
/// (k = T / steps); returns the statistics of every step.
pub fn run(
    cells: usize,
    method: BoxQpMethod,
    steps: usize,
) -> contact_damage::Result<Vec<BoxQpStats>> {
    use BoundaryPart::{Dirichlet, Neumann};
    // the sides only matter for the velocity step, which is not solved here
    let sides = [[Dirichlet, Neumann], [Neumann, Neumann]];
    let mesh = Mesh::box_mesh([0.0; 2], [1.0; 2], [cells; 2], sides)?;
    let space = Arc::new(LagrangeSpace::new(Arc::new(mesh), 1)?);
    let mass = assemble_damage_matrix(&space, 1.0, 0.0)?;
    let k = FINAL_TIME / steps as f64;
    let settings = BoxQpSettings {
        method,
        ..BoxQpSettings::default()
    };
    let mut operator = DamageOperator::new(space.clone(), DIFFUSION, k, settings)?;
    let mut damage: Vec<f64> = space
        .nodes()
        .iter()
        .map(|&x| 1.0 - 0.5 * bump(x, centre(0.0)))
        .collect();
    // β_{n−2}: the start of each step is extrapolated as in the scheme (empty at n = 1)
    let mut before = Vec::new();
    let mut stats = Vec::with_capacity(steps);
    for n in 1..=steps {
        let c = centre(n as f64 * k);
        let nodal: Vec<f64> = space
            .nodes()
            .iter()
            .map(|&x| HEALING - STRENGTH * bump(x, c))
            .collect();
        let source = multiply(&mass, &nodal);
        let solution = operator.solve(&source, &damage, &before)?;
        before = std::mem::replace(&mut damage, solution.damage);
        stats.push(solution.stats);
    }
    Ok(stats)
}
