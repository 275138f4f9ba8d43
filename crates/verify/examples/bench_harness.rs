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

use contact_damage::model::fields::{
    BatchBoundaryScalarField, BatchBoundaryVectorField, BatchScalarField, BatchVectorField,
};
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
) -> Row {
    let mut runs: Vec<Row> = (0..repeats)
        .map(|_| run(case, name, cells, threads))
        .collect();
    let mut ratios: Vec<f64> = runs.iter().map(Row::ratio).collect();
    ratios.sort_by(f64::total_cmp);
    runs.sort_by_key(|row| row.total);
    let mut median = runs.swap_remove(runs.len() / 2);
    median.ratios = ratios;
    median
}

fn run<const D: usize>(case: &Case<D>, name: &'static str, cells: usize, threads: usize) -> Row {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool");
    pool.install(|| {
        let started = Instant::now();
        let nanos = Arc::new(AtomicU64::new(0));
        let mut problem = case.problem(cells, 1, cells).expect("the problem");
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
            total: started.elapsed(),
            error_total: result.total,
            ratios: Vec::new(),
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
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "reports/benchmark_harness.md".to_string());
    let repeats: usize = match std::env::args().nth(2).map(|a| a.parse()) {
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
    for threads in [1, all] {
        for cells in [32, 64, 128] {
            rows.push(median_run(&zones2d, "zones2d", cells, threads, repeats));
            eprintln!("zones2d {cells} cells, {threads} threads done");
        }
        rows.push(median_run(&zones3d, "zones3d", 12, threads, repeats));
        eprintln!("zones3d 12 cells, {threads} threads done");
    }
    let seconds = |d: Duration| format!("{:.3}", d.as_secs_f64());
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
    for row in &rows {
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
