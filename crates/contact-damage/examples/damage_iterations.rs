//! Iteration counts of the damage step (5.2) against the mesh size, on the fixed case of
//! `common/moving_damage.rs` (moving source, both bounds active, k the same for every N).
//!
//! ```text
//! cargo run --release -p contact-damage --example damage_iterations -- [--active-set] [--steps-per-cell R] [N ...]
//! ```
//!
//! With `--active-set` the primal–dual active set method (`BoxQpMethod::ActiveSet`) is measured
//! instead of the default monotone multigrid. With `--steps-per-cell R` the run takes R·N steps
//! instead of 16 (k ∝ h: the source, hence the free boundary, moves the same number of cells
//! per step at every N).
//!
//! Prints a markdown table: per N, the largest and the total number of outer (active-set /
//! projected Newton) iterations and of inner (preconditioned CG) iterations over the steps,
//! the factorizations, the truncations of the multigrid hierarchy, the iterations of the coarse
//! obstacle solves (all levels), the largest KKT residual and the active bounds of the last
//! step.
//! Default N = 64, 128, 256, 512.

#[path = "common/moving_damage.rs"]
mod moving_damage;

use contact_damage::solvers::box_qp::BoxQpMethod;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let arguments: Vec<String> = std::env::args().skip(1).collect();
    let method = if arguments.iter().any(|a| a == "--active-set") {
        BoxQpMethod::ActiveSet
    } else {
        BoxQpMethod::MonotoneMultigrid
    };
    let steps_per_cell: Option<f64> = match arguments.iter().position(|a| a == "--steps-per-cell") {
        Some(p) => Some(
            arguments
                .get(p + 1)
                .ok_or("--steps-per-cell needs a value")?
                .parse()?,
        ),
        None => None,
    };
    let mut sizes: Vec<usize> = arguments
        .iter()
        .enumerate()
        .filter(|(i, a)| {
            *a != "--active-set"
                && *a != "--steps-per-cell"
                && !(*i > 0 && arguments[i - 1] == "--steps-per-cell")
        })
        .map(|(_, a)| a.parse())
        .collect::<Result<_, _>>()?;
    if sizes.is_empty() {
        sizes = vec![64, 128, 256, 512];
    }
    println!(
        "method: {method:?}, steps: {}",
        steps_per_cell.map_or("16".to_string(), |r| format!("{r}·N"))
    );
    println!(
        "| N | unknowns | outer it. max / total | inner CG it. max / total | factorizations | coarse updates | coarse obstacle it. | fallback steps | max KKT | β = 0 / β = 1 nodes (last step) | time per step |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for cells in sizes {
        let started = Instant::now();
        let steps = steps_per_cell.map_or(moving_damage::STEPS, |r| {
            (r * cells as f64).round() as usize
        });
        let stats = moving_damage::run(cells, method, steps.max(1))?;
        let per_step = started.elapsed().as_secs_f64() / stats.len() as f64;
        let outer_max = stats.iter().map(|s| s.iterations).max().unwrap_or(0);
        let outer_total: usize = stats.iter().map(|s| s.iterations).sum();
        let inner_max = stats.iter().map(|s| s.inner_iterations).max().unwrap_or(0);
        let inner_total: usize = stats.iter().map(|s| s.inner_iterations).sum();
        let factorizations: usize = stats.iter().map(|s| s.factorizations).sum();
        let coarse: usize = stats.iter().map(|s| s.coarse_updates).sum();
        let coarse_solves: usize = stats.iter().map(|s| s.coarse_iterations).sum();
        let fallback = stats.iter().filter(|s| s.used_fallback).count();
        let kkt = stats.iter().map(|s| s.kkt_residual).fold(0.0, f64::max);
        let last = stats.last().expect("steps");
        println!(
            "| {cells} | {} | {outer_max} / {outer_total} | {inner_max} / {inner_total} | {factorizations} | {coarse} | {coarse_solves} | {fallback} | {kkt:.1e} | {} / {} | {:.3} s |",
            (cells + 1) * (cells + 1),
            last.lower_active,
            last.upper_active,
            per_step
        );
    }
    Ok(())
}
