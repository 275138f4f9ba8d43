//! Benchmark of one verification run split into its parts, written to
//! `reports/benchmark_harness.md`:
//!
//! ```text
//! cargo run --release -p verify --example bench_harness [-- OUT.md [REPEATS]]
//! ```
//!
//! Runs `zones2d` (l = 1) at 32, 64 and 128 cells per side with k = h (N = cells, T = 1), and
//! `zones3d` (l = 1) at 12 cells, each on one thread and on all threads, and reports the wall
//! time of: mesh/space setup (mesh, space, operators and their symbolic analyses, quadrature
//! data), manufactured data (time inside the data fields f0, f2, f3, q, κ∂β/∂ν, summed over
//! the threads that evaluated them), the rest of the load assembly, the velocity step (5.1),
//! the damage step (5.2) (the two run concurrently when a thread is free), the error
//! integrals, and the output (the run's JSON and CSV rows written atomically). Each run is
//! repeated REPEATS times (default 3; the shared machine's speed drifts by up to 30 % within
//! minutes): the table shows the run with the median total, and the ratio of data + errors to
//! the two solves as the median over the repeats with their range. A benchmark, not a test:
//! nothing is asserted.
//!
//! ```text
//! cargo run --release -p verify --example bench_harness -- --limit [OUT.md [REPEATS]]
//! ```
//!
//! writes `reports/benchmark_limit.md` instead: one thread, `zones2d` at 64, 128 and 256 cells
//! and `zones3d` at 12, 16 and 24, each run split as above beside the limit of this machine
//! for it, measured by micro-benchmarks in the same process right after the run: per step, two
//! triangular solves with the factor of (5.1), two with the factor of (5.2) (M/k + κK), and one
//! pass of the data over the quadrature points (f0 and q, the exact fields and the laws, at
//! every cell quadrature point of the loads, per step time, evaluated for a block of step
//! times per call as the run does — the one pass that loads and errors would share if fused).
//! Each kernel is timed as the fastest of several calls.

use contact_damage::algebra::linalg::CholeskySolver;
use contact_damage::model::fields::{
    BatchBoundaryScalarField, BatchBoundaryVectorField, BatchScalarField, BatchVectorField,
};
use contact_damage::scheme::damage::assemble_damage_matrix;
use contact_damage::scheme::loads::LoadQuadrature;
use contact_damage::scheme::{Data, Simulation};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use verify::case::{parse_case_file, Case};
use verify::cli::BUILT_IN_CASES;
use verify::error_norms::{ErrorTracker, Reference};
use verify::manufactured::data::ExactPrograms;
use verify::output::{write_atomic, write_csv_atomic, write_json_atomic};

// the machine description of the solver's bench examples
#[path = "../../contact-damage/examples/common/report.rs"]
#[allow(dead_code)] // its number format and writer serve the other benches
mod report;

/// A data field that adds the time spent in it to a shared counter.
struct Timed<F: ?Sized> {
    inner: Arc<F>,
    nanos: Arc<AtomicU64>,
}

impl<F: ?Sized> Timed<F> {
    fn time<R>(&self, f: impl FnOnce() -> R) -> R {
        let started = Instant::now();
        let result = f();
        self.nanos
            .fetch_add(started.elapsed().as_nanos() as u64, Ordering::Relaxed);
        result
    }
}

impl<const D: usize> BatchVectorField<D> for Timed<dyn BatchVectorField<D>> {
    fn evaluate(&self, points: &[[f64; D]], time: f64, out: &mut [[f64; D]]) {
        self.time(|| self.inner.evaluate(points, time, out))
    }

    fn evaluate_at_times(&self, points: &[[f64; D]], times: &[f64], out: &mut [[f64; D]]) {
        self.time(|| self.inner.evaluate_at_times(points, times, out))
    }

    fn times_per_evaluation(&self) -> usize {
        self.inner.times_per_evaluation()
    }
}

impl<const D: usize> BatchBoundaryVectorField<D> for Timed<dyn BatchBoundaryVectorField<D>> {
    fn evaluate(&self, points: &[[f64; D]], normals: &[[f64; D]], time: f64, out: &mut [[f64; D]]) {
        self.time(|| self.inner.evaluate(points, normals, time, out))
    }
}

impl<const D: usize> BatchScalarField<D> for Timed<dyn BatchScalarField<D>> {
    fn evaluate(&self, points: &[[f64; D]], time: f64, out: &mut [f64]) {
        self.time(|| self.inner.evaluate(points, time, out))
    }

    fn evaluate_at_times(&self, points: &[[f64; D]], times: &[f64], out: &mut [f64]) {
        self.time(|| self.inner.evaluate_at_times(points, times, out))
    }

    fn times_per_evaluation(&self) -> usize {
        self.inner.times_per_evaluation()
    }
}

impl<const D: usize> BatchBoundaryScalarField<D> for Timed<dyn BatchBoundaryScalarField<D>> {
    fn evaluate(&self, points: &[[f64; D]], normals: &[[f64; D]], time: f64, out: &mut [f64]) {
        self.time(|| self.inner.evaluate(points, normals, time, out))
    }
}

/// The data of `data` with every field timed into `nanos`.
fn timed<const D: usize>(data: Data<D>, nanos: &Arc<AtomicU64>) -> Data<D> {
    macro_rules! wrap {
        ($field:expr) => {
            $field.map(|inner| {
                Arc::new(Timed {
                    inner,
                    nanos: nanos.clone(),
                }) as _
            })
        };
    }
    Data {
        body_force: wrap!(data.body_force),
        traction: wrap!(data.traction),
        contact_traction: wrap!(data.contact_traction),
        damage_supply: wrap!(data.damage_supply),
        damage_flux: wrap!(data.damage_flux),
        ..data
    }
}

/// The time split of one run.
struct Row {
    case: &'static str,
    cells: usize,
    steps: usize,
    threads: usize,
    unknowns: usize,
    setup: Duration,
    data: Duration,
    assembly: Duration,
    velocity: Duration,
    damage: Duration,
    errors: Duration,
    output: Duration,
    total: Duration,
    error_total: f64,
    /// (data + errors) / ((5.1) + (5.2)) of each repeat, ascending.
    ratios: Vec<f64>,
    /// The kernels of the limit, when measured.
    limit: Option<Limit>,
}

/// The kernels of the limit of one run, each the fastest of several calls.
#[derive(Clone, Copy)]
struct Limit {
    /// Two triangular solves with the factor of (5.1).
    velocity_solve: Duration,
    /// Two triangular solves with the factor of (5.2).
    damage_solve: Duration,
    /// f0 and q at every cell quadrature point of the loads, per step time.
    data_pass: Duration,
}

impl Limit {
    /// `steps` × (the three kernels).
    fn total(&self, steps: usize) -> Duration {
        (self.velocity_solve + self.damage_solve + self.data_pass) * steps as u32
    }
}

/// The fastest of `calls` calls of `kernel`.
fn fastest(calls: usize, mut kernel: impl FnMut()) -> Duration {
    (0..calls)
        .map(|_| {
            let started = Instant::now();
            kernel();
            started.elapsed()
        })
        .min()
        .expect("at least one call")
}

/// The limit of `simulation`'s run (after it): see the module documentation.
fn measure_limit<const D: usize>(
    simulation: &Simulation<D>,
    data: &Data<D>,
    diffusion: f64,
) -> Limit {
    let space = simulation.space();
    let size = simulation.velocity_operator().size();
    let rhs: Vec<f64> = (0..size).map(|i| ((i % 7) as f64) - 3.0).collect();
    let velocity = simulation.velocity_operator().solver();
    let velocity_solve = fastest(9, || {
        std::hint::black_box(velocity.solve(&rhs).expect("a velocity solve"));
    });
    let matrix = assemble_damage_matrix(space, 1.0 / simulation.time_step(), diffusion)
        .expect("the damage matrix");
    let mut damage = CholeskySolver::analyse(&matrix, "damage").expect("its analysis");
    damage.factorize(&matrix).expect("its factor");
    let rhs: Vec<f64> = (0..space.num_nodes())
        .map(|i| ((i % 5) as f64) - 2.0)
        .collect();
    let damage_solve = fastest(9, || {
        std::hint::black_box(damage.solve(&rhs).expect("a damage solve"));
    });
    // as the run evaluates them: a block of step times per call (the time-independent values
    // of a point are read once per block), per time
    let quadrature = LoadQuadrature::new(space);
    let times: Vec<f64> = (1..=quadrature.times_per_block(data))
        .map(|n| n as f64 * simulation.time_step())
        .collect();
    let data_pass = fastest(3, || {
        std::hint::black_box(quadrature.bulk_data(data, &times));
    }) / times.len() as u32;
    Limit {
        velocity_solve,
        damage_solve,
        data_pass,
    }
}

impl Row {
    /// (data + errors) / ((5.1) + (5.2)).
    fn ratio(&self) -> f64 {
        (self.data + self.errors).as_secs_f64() / (self.velocity + self.damage).as_secs_f64()
    }
}

/// The run with the median total of `repeats` runs, with the ratios of them all.
fn median_run<const D: usize>(
    case: &Case<D>,
    name: &'static str,
    cells: usize,
    threads: usize,
    repeats: usize,
    with_limit: bool,
) -> Row {
    let mut runs: Vec<Row> = (0..repeats)
        .map(|_| run(case, name, cells, threads, with_limit))
        .collect();
    let mut ratios: Vec<f64> = runs.iter().map(Row::ratio).collect();
    ratios.sort_by(f64::total_cmp);
    runs.sort_by_key(|row| row.total);
    let mut median = runs.swap_remove(runs.len() / 2);
    median.ratios = ratios;
    median
}

fn run<const D: usize>(
    case: &Case<D>,
    name: &'static str,
    cells: usize,
    threads: usize,
    with_limit: bool,
) -> Row {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool");
    pool.install(|| {
        let started = Instant::now();
        let nanos = Arc::new(AtomicU64::new(0));
        let mut problem = case.problem(cells, 1, cells).expect("the problem");
        let (plain_data, diffusion) = (problem.data.clone(), problem.model.damage_diffusion);
        problem.data = timed(problem.data, &nanos);
        let mut simulation = Simulation::new(problem).expect("the simulation");
        let setup = started.elapsed();
        let mut errors = Duration::ZERO;
        let clock = Instant::now();
        let space = simulation.space().clone();
        let mut tracker = ErrorTracker::new(
            &space,
            Reference::Exact(Arc::new(ExactPrograms::clone(&case.programs))),
            simulation.time_step(),
            cells,
        );
        errors += clock.elapsed();
        simulation
            .run(|report| {
                let clock = Instant::now();
                tracker.observe(report.space, report.state);
                errors += clock.elapsed();
                Ok(())
            })
            .expect("the run");
        let clock = Instant::now();
        let result = tracker.finish();
        let folder = std::env::temp_dir().join(format!("bench_harness_{}", std::process::id()));
        std::fs::create_dir_all(&folder).expect("a temporary folder");
        write_json_atomic(&folder.join("errors.json"), &result).expect("JSON written");
        write_csv_atomic(&folder.join("errors.csv"), &[result]).expect("CSV written");
        std::fs::remove_dir_all(&folder).expect("the temporary folder removed");
        let output = clock.elapsed();
        let total = started.elapsed();
        let limit = with_limit.then(|| measure_limit(&simulation, &plain_data, diffusion));
        let timings = *simulation.timings();
        let data = Duration::from_nanos(nanos.load(Ordering::Relaxed));
        Row {
            case: name,
            cells,
            steps: cells,
            threads,
            unknowns: simulation.velocity_operator().size(),
            setup,
            data,
            assembly: timings.loads.saturating_sub(data),
            velocity: timings.velocity,
            damage: timings.damage,
            errors,
            output,
            total,
            error_total: result.total,
            ratios: Vec::new(),
            limit,
        }
    })
}

fn case<const D: usize>(name: &str) -> Case<D> {
    let text = BUILT_IN_CASES
        .iter()
        .find(|(case, _)| *case == name)
        .expect("a built-in case")
        .1;
    let file = parse_case_file(text, name).expect("the built-in case parses");
    Case::<D>::new(file, name).expect("the built-in case is valid")
}

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let limit = args.first().is_some_and(|a| a == "--limit");
    if limit {
        args.remove(0);
    }
    let out = args.first().cloned().unwrap_or_else(|| {
        if limit {
            "reports/benchmark_limit.md"
        } else {
            "reports/benchmark_harness.md"
        }
        .to_string()
    });
    let repeats: usize = match args.get(1).map(|a| a.parse()) {
        None => 3,
        Some(Ok(n)) if n > 0 => n,
        Some(_) => {
            eprintln!("REPEATS must be a positive integer");
            std::process::exit(2);
        }
    };
    let all = std::thread::available_parallelism().map_or(1, |n| n.get());
    let (started, load) = (report::utc_now(), report::load_average());
    let zones2d = case::<2>("zones2d");
    let zones3d = case::<3>("zones3d");
    let mut rows = Vec::new();
    let (threads_list, cells_2d, cells_3d): (Vec<usize>, &[usize], &[usize]) = if limit {
        (vec![1], &[64, 128, 256], &[12, 16, 24])
    } else {
        (vec![1, all], &[32, 64, 128], &[12])
    };
    for &threads in &threads_list {
        for &cells in cells_2d {
            rows.push(median_run(
                &zones2d, "zones2d", cells, threads, repeats, limit,
            ));
            eprintln!("zones2d {cells} cells, {threads} threads done");
        }
        for &cells in cells_3d {
            rows.push(median_run(
                &zones3d, "zones3d", cells, threads, repeats, limit,
            ));
            eprintln!("zones3d {cells} cells, {threads} threads done");
        }
    }
    let mut text = if limit {
        limit_table(&rows, repeats)
    } else {
        split_table(&rows, repeats)
    };
    text.push_str(&format!(
        "\nMachine: {}, {all} threads available; other processes may share them (wall times; \
         load average at start {load}).  \nDate: {started}.\n",
        report::cpu_model()
    ));
    write_atomic(std::path::Path::new(&out), text.as_bytes())
        .unwrap_or_else(|e| panic!("cannot write {out}: {e}"));
    print!("{text}");
    eprintln!("wrote {out}");
}

fn seconds(duration: Duration) -> String {
    format!("{:.3}", duration.as_secs_f64())
}

/// The table of `reports/benchmark_limit.md`.
fn limit_table(rows: &[Row], repeats: usize) -> String {
    let mut text = format!(
        "# A verification run against the limit of the machine\n\n\
         Generated by `cargo run --release -p verify --example bench_harness -- --limit` (l = 1, \
         k = h: N = cells, T = 1, one thread). Wall seconds of the run with the median total of \
         {repeats}, split as in `benchmark_harness.md` (*setup* the mesh, space, operators and \
         their analyses, *data* the time inside the manufactured data fields, *assembly* the \
         rest of the load vectors, *errors* the error integrals; *total* includes the setup). \
         The limit is measured in the same process after the run, each kernel the fastest of \
         several calls: *tri (5.1)* and *tri (5.2)* two triangular solves with the factor of \
         each step, *pass* the data f0 and q at every cell quadrature point per step time, \
         evaluated for a block of step times per call as the run does (the one pass over the \
         points that loads and errors would share); *limit* = N × (tri (5.1) + tri (5.2) + \
         pass), in seconds like the run; *× limit* = total / limit, and per part: (5.1) / (N tri \
         (5.1)), (5.2) / (N tri (5.2)), (data + assembly + errors) / (N pass); *step / tri* = \
         total / (N tri (5.1)), a whole step against two triangular solves with the velocity \
         factor.\n\n\
         | case | N | unknowns | setup | data | assembly | (5.1) | (5.2) | errors | output | total | tri (5.1) ms | tri (5.2) ms | pass ms | limit | × limit | (5.1) × | (5.2) × | data + assembly + errors × | step / tri |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let ms = |d: Duration| format!("{:.3}", d.as_secs_f64() * 1e3);
    let ratio = |a: Duration, b: Duration| format!("{:.1}", a.as_secs_f64() / b.as_secs_f64());
    for row in rows {
        let limit = row.limit.expect("measured with the run");
        let steps = row.steps as u32;
        text.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
            row.case,
            row.steps,
            row.unknowns,
            seconds(row.setup),
            seconds(row.data),
            seconds(row.assembly),
            seconds(row.velocity),
            seconds(row.damage),
            seconds(row.errors),
            seconds(row.output),
            seconds(row.total),
            ms(limit.velocity_solve),
            ms(limit.damage_solve),
            ms(limit.data_pass),
            seconds(limit.total(row.steps)),
            ratio(row.total, limit.total(row.steps)),
            ratio(row.velocity, limit.velocity_solve * steps),
            ratio(row.damage, limit.damage_solve * steps),
            ratio(row.data + row.assembly + row.errors, limit.data_pass * steps),
            ratio(row.total, limit.velocity_solve * steps),
        ));
    }
    text
}

/// The table of `reports/benchmark_harness.md`.
fn split_table(rows: &[Row], repeats: usize) -> String {
    let mut text = format!(
        "# Benchmark of a verification run\n\n\
         Generated by `cargo run --release -p verify --example bench_harness` (l = 1, k = h: \
         N = cells, T = 1). Wall seconds per part of one run, the run with the median total of \
         {repeats}; *data* is the time inside the \
         manufactured data fields (f0, f2, f3, q, κ∂β/∂ν; summed over threads, so with several \
         threads it is CPU time and may exceed the wall time of the loads), *assembly* the rest \
         of the load vectors (one thread only), (5.1) and (5.2) the two solves of all steps (concurrent when \
         a thread is free), *errors* the error integrals of E(h, k), *output* the run's rows \
         written atomically; *ratio* is (data + errors) / ((5.1) + (5.2)), the median over the \
         {repeats} runs with their range.\n\n\
         | case | cells | N | threads | unknowns | setup | data | assembly | (5.1) | (5.2) | errors | output | total | data + errors | (5.1) + (5.2) | ratio | E(h, k) |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for row in rows {
        text.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.2} ({:.2}–{:.2}) | {:.4e} |\n",
            row.case,
            row.cells,
            row.steps,
            row.threads,
            row.unknowns,
            seconds(row.setup),
            seconds(row.data),
            if row.threads == 1 {
                seconds(row.assembly)
            } else {
                "—".to_string()
            },
            seconds(row.velocity),
            seconds(row.damage),
            seconds(row.errors),
            seconds(row.output),
            seconds(row.total),
            seconds(row.data + row.errors),
            seconds(row.velocity + row.damage),
            row.ratios[row.ratios.len() / 2],
            row.ratios[0],
            row.ratios[row.ratios.len() - 1],
            row.error_total,
        ));
    }
    text
}
