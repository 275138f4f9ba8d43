//! Cost of the compiled manufactured-data programs per point and time against the number of
//! step times evaluated at once (`QuantityProgram::for_batches_at_times`), the measurement
//! behind `TIMES_PER_EVALUATION` (f0 and q) and `STATES_PER_BLOCK` (errors):
//!
//! ```text
//! cargo run --release -p verify --example bench_programs [-- CASE]
//! ```
//!
//! For the bulk program (f0 and q), the error program and the fields f0 and q themselves
//! (the program and the laws point by point) of a 2D built-in case (default
//! `zones2d`), over 16 384 points (their time-independent values stay in the cache) and
//! 196 608 points (the load points of the 128-cell level, 44 MB of time-independent values
//! for the bulk program), 128 steps' worth of evaluations on one thread, after a first
//! evaluation that fills the cache of time-independent values. A benchmark: nothing is
//! asserted; prints a markdown table.

use contact_damage::model::fields::{BatchScalarField, BatchVectorField};
use std::sync::Arc;
use std::time::Instant;
use verify::case::{parse_case_file, Case};
use verify::cli::BUILT_IN_CASES;
use verify::manufactured::data::{BodyForce, DamageSupply, ExactPrograms, ManufacturedData};
use verify::manufactured::programs::{Quantity, QuantityProgram};

fn main() {
    let name = std::env::args().nth(1).unwrap_or_else(|| "zones2d".into());
    let Some((_, text)) = BUILT_IN_CASES.iter().find(|(case, _)| *case == name) else {
        eprintln!("no built-in case `{name}`");
        std::process::exit(2);
    };
    let file = parse_case_file(text, &name).expect("the built-in case parses");
    if file.dim != 2 {
        eprintln!("`{name}` is not a 2D case");
        std::process::exit(2);
    }
    let case = Case::<2>::new(file, &name).expect("the built-in case is valid");
    let programs = &case.programs;
    println!("case {name}, ns per point and time, one thread");
    println!();
    println!("| program | points | 1 time | 2 times | 4 times | 8 times | 16 times |");
    println!("|---|---|---|---|---|---|---|");
    let steps = 128;
    for points in [16_384usize, 196_608] {
        // A fixed low-discrepancy sequence over the unit square.
        let coordinates: Vec<[f64; 2]> = (0..points)
            .map(|i| {
                [
                    (i as f64 * 0.618_034).fract(),
                    (i as f64 * 0.377_33).fract(),
                ]
            })
            .collect();
        for (label, program) in [
            ("bulk (f0, q)", &programs.bulk),
            ("errors", &programs.errors),
        ] {
            let mut row = format!("| {label} | {points} |");
            for times in [1usize, 2, 4, 8, 16] {
                row += &format!(" {:.1} |", per_point(program, &coordinates, steps, times));
            }
            println!("{row}");
        }
        // The fields the scheme calls: f0 with q handed over (the laws per point included).
        let mut row = format!("| f0 and q (fields) | {points} |");
        for times in [1usize, 2, 4, 8, 16] {
            row += &format!(
                " {:.1} |",
                fields_per_point(&case, &coordinates, steps, times)
            );
        }
        println!("{row}");
    }
}

/// As [`per_point`] for the fields f0 and q of `case` (f0, then q at the same points and
/// times, as the load assembly calls them).
fn fields_per_point(case: &Case<2>, points: &[[f64; 2]], steps: usize, times: usize) -> f64 {
    let data = ManufacturedData::new(
        Arc::new(ExactPrograms::clone(&case.programs)),
        case.laws.clone(),
    );
    let (force, supply) = (BodyForce(data.clone()), DamageSupply(data));
    let mut forces = vec![[0.0; 2]; points.len() * times];
    let mut sources = vec![0.0; points.len() * times];
    force.evaluate_at_times(points, &[0.0], &mut forces[..points.len()]);
    let nanos = nanos_per_point(points.len(), steps, times, |block| {
        force.evaluate_at_times(points, block, &mut forces);
        supply.evaluate_at_times(points, block, &mut sources);
    });
    std::hint::black_box((&forces, &sources));
    nanos
}

/// Nanoseconds per point and time of `steps · 196 608 / points` evaluations in calls of
/// `times` times each (a fresh copy of the program: its cache is filled first, untimed).
fn per_point(program: &QuantityProgram<2>, points: &[[f64; 2]], steps: usize, times: usize) -> f64 {
    let program = program.clone();
    let mut checksum = 0.0;
    program.for_batches(points, 0.0, |_, columns| {
        checksum += columns.get(Quantity::Damage)[0]
    });
    let nanos = nanos_per_point(points.len(), steps, times, |block| {
        program.for_batches_at_times(points, block, |_, _, columns| {
            checksum += columns.get(Quantity::Damage)[0]
        })
    });
    std::hint::black_box(checksum);
    nanos
}

/// Times `evaluate(times)` over `steps · 196 608 / points` point evaluations in calls of
/// `times` step times each (cycling through t = 1/steps, …, 1): nanoseconds per point and
/// time.
fn nanos_per_point(
    points: usize,
    steps: usize,
    times: usize,
    mut evaluate: impl FnMut(&[f64]),
) -> f64 {
    let evaluations = (steps * 196_608 / points).max(times);
    let calls = evaluations / times;
    let started = Instant::now();
    for call in 0..calls {
        let block: Vec<f64> = (0..times)
            .map(|i| ((call * times + i) % steps + 1) as f64 / steps as f64)
            .collect();
        evaluate(&block);
    }
    started.elapsed().as_nanos() as f64 / (calls * times * points) as f64
}
