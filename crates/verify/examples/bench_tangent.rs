//! The tangent of a nonlinear viscosity in the velocity step (5.1): exact Newton against a
//! frozen tangent ([`TangentUpdate`]), on manufactured cases with a nonlinear 𝒜.
//!
//! ```text
//! cargo run --release -p verify --example bench_tangent -- [CASE.toml …] [--cells N] [--steps M] [--order l] [--repeats R]
//! ```
//!
//! For each case (default: `verification/mild2d.toml`, `strong2d.toml`, `carreau2d.toml`) it
//! runs the scheme on one mesh of N cells per side with M steps (defaults 64 and 64, order 1),
//! once with each update, R times (default 3, the best time kept), on the calling thread, and
//! prints a table: the wall time of the run, the Newton iterations and the numeric
//! factorizations of the velocity steps, the largest KKT residual, and the largest difference
//! of the final displacements of the two runs relative to the largest displacement.

use contact_damage::scheme::velocity::TangentUpdate;
use contact_damage::scheme::Simulation;
use std::process::ExitCode;
use std::time::Instant;
use verify::case::{read_case_file, Case};
use verify::InputError;

/// What one run measured.
struct Measured {
    seconds: f64,
    newton: usize,
    factorizations: usize,
    kkt: f64,
    displacement: Vec<f64>,
}

fn measure<const D: usize>(
    case: &Case<D>,
    cells: usize,
    degree: usize,
    steps: usize,
    tangent: TangentUpdate,
    repeats: usize,
) -> Result<Measured, InputError> {
    let mut best: Option<Measured> = None;
    for _ in 0..repeats {
        let mut problem = case.problem(cells, degree, steps)?;
        problem.settings.velocity.tangent = tangent;
        let clock = Instant::now();
        let mut simulation = Simulation::new(problem)?;
        let (mut newton, mut factorizations, mut kkt) = (0, 0, 0.0f64);
        simulation.run(|report| {
            newton += report.velocity_stats.newton_iterations;
            factorizations += report.velocity_stats.factorizations;
            kkt = kkt.max(report.velocity_stats.kkt_residual);
            Ok(())
        })?;
        let seconds = clock.elapsed().as_secs_f64();
        if best.as_ref().is_none_or(|b| seconds < b.seconds) {
            best = Some(Measured {
                seconds,
                newton,
                factorizations,
                kkt,
                displacement: simulation.state().displacement.clone(),
            });
        }
    }
    Ok(best.expect("at least one repeat"))
}

fn row<const D: usize>(
    path: &str,
    case: &Case<D>,
    cells: usize,
    degree: usize,
    steps: usize,
    repeats: usize,
) -> Result<(), InputError> {
    let newton = measure(case, cells, degree, steps, TangentUpdate::Newton, repeats)?;
    let frozen = measure(case, cells, degree, steps, TangentUpdate::Frozen, repeats)?;
    let scale = newton
        .displacement
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let difference = newton
        .displacement
        .iter()
        .zip(&frozen.displacement)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    for (name, m) in [("Newton", &newton), ("frozen", &frozen)] {
        println!(
            "| {path} | {name} | {:.3} s | {} | {} | {:.1e} | {:.1e} |",
            m.seconds,
            m.newton,
            m.factorizations,
            m.kkt,
            difference / scale
        );
    }
    Ok(())
}

fn run(args: &[String]) -> Result<(), InputError> {
    let value = |flag: &str, default: usize| -> Result<usize, InputError> {
        match args.iter().position(|a| a == flag) {
            None => Ok(default),
            Some(i) => args
                .get(i + 1)
                .and_then(|v| v.parse().ok())
                .ok_or_else(|| InputError::InvalidInput(format!("{flag} needs a whole number"))),
        }
    };
    let (cells, steps) = (value("--cells", 64)?, value("--steps", 64)?);
    let (degree, repeats) = (value("--order", 1)?, value("--repeats", 3)?.max(1));
    let flags = ["--cells", "--steps", "--order", "--repeats"];
    let mut cases: Vec<String> = Vec::new();
    let mut skip = false;
    for arg in args {
        if skip {
            skip = false;
        } else if flags.contains(&arg.as_str()) {
            skip = true;
        } else {
            cases.push(arg.clone());
        }
    }
    if cases.is_empty() {
        cases = ["mild2d", "strong2d", "carreau2d"]
            .iter()
            .map(|name| {
                concat!(env!("CARGO_MANIFEST_DIR"), "/../../verification/").to_string()
                    + name
                    + ".toml"
            })
            .collect();
    }
    println!(
        "{cells} cells per side, {steps} steps, l = {degree}, best of {repeats}, one thread\n"
    );
    println!("| case | tangent | time | Newton iterations | factorizations | max KKT | final displacements differ by |");
    println!("|---|---|---:|---:|---:|---:|---:|");
    for path in &cases {
        let file = read_case_file(std::path::Path::new(path))?;
        let name = std::path::Path::new(path)
            .file_stem()
            .map_or(path.clone(), |s| s.to_string_lossy().into_owned());
        match file.dim {
            2 => row(
                &name,
                &Case::<2>::new(file, path)?,
                cells,
                degree,
                steps,
                repeats,
            )?,
            3 => row(
                &name,
                &Case::<3>::new(file, path)?,
                cells,
                degree,
                steps,
                repeats,
            )?,
            dim => {
                return Err(InputError::InvalidInput(format!(
                    "{path}: dim = {dim}, expected 2 or 3"
                )))
            }
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a thread pool");
    match pool.install(|| run(&args)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("bench_tangent: {error}");
            ExitCode::from(2)
        }
    }
}
