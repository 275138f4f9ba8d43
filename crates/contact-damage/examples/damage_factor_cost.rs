//! What the factor of a predicted bound set of the damage step costs, against its fill.
//!
//! ```text
//! cargo run --release -p contact-damage --example damage_factor_cost
//! ```
//!
//! For the damage matrix M/k + κK (κ = 0.01, k = h) on the unit square and cube (P1 at 64²,
//! 128², 256² and 12³, 16³, 24³; P2 at 64² and 12³), on one thread: the stored values of the
//! matrix and of its supernodal Cholesky factor, their ratio (the fill,
//! `BoxQpSolver::bound_set_fill`), the time of one numeric factorization (mean of 5) and of
//! one solve with it (two triangular solves, mean of 20), and whether the damage step tries
//! predicted bound sets on that mesh (fill ≤ `MAX_PREDICTION_FILL`). Prints a markdown table;
//! a benchmark, nothing is asserted.

#[path = "common/report.rs"]
#[allow(dead_code)] // the writer and number formats serve the other benches
mod report;

use contact_damage::algebra::linalg::{CholeskySolver, FactorKind};
use contact_damage::fem::mesh::{BoundaryPart, Mesh};
use contact_damage::fem::space::LagrangeSpace;
use contact_damage::scheme::damage::{assemble_damage_matrix, DamageOperator, MAX_PREDICTION_FILL};
use contact_damage::solvers::box_qp::{BoxQpSettings, BoxQpSolver};
use std::sync::Arc;
use std::time::Instant;

const DIFFUSION: f64 = 0.01;

type Failure = Box<dyn std::error::Error + Send + Sync>;

fn row<const D: usize>(
    space: Arc<LagrangeSpace<D>>,
    label: &str,
    cells: usize,
) -> Result<String, Failure> {
    let time_step = 1.0 / cells as f64;
    let matrix = assemble_damage_matrix(&space, 1.0 / time_step, DIFFUSION)?;
    let fill = BoxQpSolver::new(matrix.clone(), BoxQpSettings::default())?.bound_set_fill()?;
    let predicts = DamageOperator::new(
        space.clone(),
        DIFFUSION,
        time_step,
        BoxQpSettings::default(),
    )?
    .predicts_bound_sets();
    let mut factor = CholeskySolver::analyse_as(&matrix, FactorKind::Supernodal, "damage matrix")?;
    let started = Instant::now();
    for _ in 0..5 {
        factor.factorize(&matrix)?;
    }
    let factorization = started.elapsed().as_secs_f64() / 5.0;
    let rhs = vec![1.0; matrix.nrows()];
    let started = Instant::now();
    for _ in 0..20 {
        std::hint::black_box(factor.solve(&rhs)?);
    }
    let solve = started.elapsed().as_secs_f64() / 20.0;
    Ok(format!(
        "| {label} | {} | {} | {} | {fill:.1} | {:.2} | {:.3} | {:.1} | {} |\n",
        matrix.nrows(),
        matrix.val().len(),
        factor.factor_len(),
        factorization * 1e3,
        solve * 1e3,
        factorization / solve,
        if predicts { "yes" } else { "no" },
    ))
}

fn main() -> Result<(), Failure> {
    use BoundaryPart::{Dirichlet, Neumann};
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    faer::set_global_parallelism(faer::Par::Seq);
    let mut table = String::from(
        "| mesh | unknowns | values of A | values of L | fill | factorization ms | solve ms | factorization / solve | predicted |\n|---|---:|---:|---:|---:|---:|---:|---:|---|\n",
    );
    pool.install(|| -> Result<(), Failure> {
        for (cells, degree) in [(64, 1), (128, 1), (256, 1), (64, 2)] {
            let sides = [[Dirichlet, Neumann], [Neumann, Neumann]];
            let mesh = Mesh::box_mesh([0.0; 2], [1.0; 2], [cells; 2], sides)?;
            let space = Arc::new(LagrangeSpace::new(Arc::new(mesh), degree)?);
            table.push_str(&row(space, &format!("2D P{degree} {cells}²"), cells)?);
        }
        for (cells, degree) in [(12, 1), (16, 1), (24, 1), (12, 2)] {
            let sides = [[Dirichlet, Neumann], [Neumann, Neumann], [Neumann, Neumann]];
            let mesh = Mesh::box_mesh([0.0; 3], [1.0; 3], [cells; 3], sides)?;
            let space = Arc::new(LagrangeSpace::new(Arc::new(mesh), degree)?);
            table.push_str(&row(space, &format!("3D P{degree} {cells}³"), cells)?);
        }
        Ok(())
    })?;
    print!("{table}");
    println!(
        "\nPredicted bound sets are tried where the fill is at most {MAX_PREDICTION_FILL}. Machine: {}; one thread; {}.",
        report::cpu_model(),
        report::utc_now()
    );
    Ok(())
}
