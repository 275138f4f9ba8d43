//! Per-step budget of the `simulate` time loop: the time of one step after the first
//! factorization, split into its parts, against two triangular solves with the velocity factor.
//!
//! ```text
//! cargo run --release -p simulate --example bench_step -- [--quick] [--output PATH] [CASE ...]
//! ```
//!
//! CASE is `2d:N` or `3d:N`; default 2D P1 at N = 128, 256, 512 and 3D P1 at N = 16, 32
//! (`--quick`: 2d:64 and 3d:8, written to `reports/benchmark_step-quick.md`). Every case runs on
//! one thread (`--threads 1` of `simulate`) in a fresh process (the example calls itself with
//! `--child CASE --threads 1`), so the sizes do not share allocator state; on a machine with
//! several cores it runs once more on all of them (`--threads` = the cores, `simulate`'s
//! default) for a second table of full steps.
//!
//! The problem is `examples/rectangle_2d.toml` (resp. `block_3d.toml`) on the unit square (cube)
//! with N cells per side, T = 1 and 128 steps, with β_0 = 1 − 0.4 exp(−|x − x_c|²/0.02) (x_c
//! under the loaded region) so that the damage step has both a free and an active set from the
//! start, and the load rising (steps 25–32 are measured, after 24 unmeasured steps, five times
//! from the same state; the fastest of the five is reported, since the machine is shared): contact
//! nodes change between separated, stick and slip, and the damage active set moves.
//!
//! Per measured step: the load and right-hand-side assembly ([`Simulation::step_loads`], inside
//! the step), the velocity step (5.1), the damage step (5.2), the rest of `Simulation::step`
//! (penetrations, gap, Dirichlet values), and the row of `history.csv` (contact and damage
//! statistics, contact zone, viscous power, reactions: `simulate::record::record_step`, the
//! function of the run loop, and the formatting of the line; writing its few hundred bytes is
//! not timed). The reference is one solve with the velocity factor (forward and backward
//! substitution), timed 5 times right after each of the five runs of the steps: the table gives
//! the fastest of these 25 solves and, as the ratio, the median over the runs of the run's full
//! step over its own fastest solve, so that a ratio never divides times measured minutes apart
//! on a shared machine (at 128², the same build measured 3.7 ms in one run and 7.4–7.8 ms in
//! two runs six hours later). The second table compares the simplicial and the supernodal
//! Cholesky factorizations of faer for the velocity matrix (its nested
//! dissection order) and the damage matrix M/k + κK (AMD).

// the machine description of the solver's bench examples
#[path = "../../contact-damage/examples/common/report.rs"]
#[allow(dead_code)] // the number format and writer of that file serve the other benches
mod report;

use contact_damage::algebra::linalg::{CholeskySolver, FactorKind};
use contact_damage::io::atomic::write_atomic;
use contact_damage::model::contact::ContactStatus;
use contact_damage::scheme::damage::assemble_damage_matrix;
use contact_damage::scheme::Simulation;
use contact_damage::solvers::box_qp::BoxQpMethod;
use simulate::contact_line::{ContactLine, LineCoordinate};
use simulate::history::{DomainQuadrature, RunningSums};
use simulate::problem::{parse_problem_file, ProblemSetup};
use simulate::record::record_step;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// Unmeasured steps before the measured ones (the load rises).
const WARM_STEPS: usize = 24;
/// Measured steps.
const MEASURED_STEPS: usize = 8;
/// Repetitions of the measured steps from the same state, each followed by its reference
/// solves; the fastest steps and the fastest reference are reported, and the median of the
/// ratios of the repetitions.
const REPEATS: usize = 5;
/// Solves with the velocity factor per repetition; the fastest is the repetition's reference.
const REFERENCE_SOLVES: usize = 5;

type Failure = Box<dyn std::error::Error>;

fn main() -> Result<(), Failure> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let Some(position) = args.iter().position(|a| a == "--child") {
        let case = args.get(position + 1).ok_or("--child needs a case")?;
        let threads = match args.iter().position(|a| a == "--threads") {
            Some(p) => args.get(p + 1).ok_or("--threads needs a count")?.parse()?,
            None => 1,
        };
        contact_input::threads::set_threads(Some(threads))?;
        let (dim, cells) = parse_case(case)?;
        let line = match (dim, threads) {
            (2, 1) => measure::<2>(cells)?,
            (_, 1) => measure::<3>(cells)?,
            (2, _) => measure_threads::<2>(cells, threads)?,
            _ => measure_threads::<3>(cells, threads)?,
        };
        println!("ROW {line}");
        return Ok(());
    }
    let quick = args.iter().any(|a| a == "--quick");
    let output = match args.iter().position(|a| a == "--output") {
        Some(p) => PathBuf::from(args.get(p + 1).ok_or("--output needs a path")?),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join(if quick {
            "../../reports/benchmark_step-quick.md"
        } else {
            "../../reports/benchmark_step.md"
        }),
    };
    let mut cases: Vec<String> = args
        .iter()
        .filter(|a| a.starts_with("2d:") || a.starts_with("3d:"))
        .cloned()
        .collect();
    if cases.is_empty() {
        cases = if quick {
            vec!["2d:64".into(), "3d:8".into()]
        } else {
            ["2d:128", "2d:256", "2d:512", "3d:16", "3d:32"]
                .map(String::from)
                .to_vec()
        };
    }
    let started = report::utc_now();
    let load = report::load_average();
    let mut step_rows = Vec::new();
    let mut factor_rows = Vec::new();
    let mut thread_rows = Vec::new();
    // the second table: all cores of the machine (simulate's default), if more than one
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    for case in &cases {
        parse_case(case)?;
        eprintln!("bench_step: {case} …");
        match child_row(case, 1)? {
            Ok(row) => {
                let (steps, factors) = row.split_once(" ## ").ok_or("malformed child row")?;
                step_rows.push(steps.to_string());
                factor_rows.push(factors.to_string());
            }
            Err(failure) => step_rows.push(format!("| {case} | failed: {failure} |")),
        }
        if cores > 1 {
            eprintln!("bench_step: {case} on {cores} threads …");
            thread_rows.push(match child_row(case, cores)? {
                Ok(row) => row,
                Err(failure) => format!("| {case} | failed: {failure} |"),
            });
        }
    }
    let command = format!(
        "cargo run --release -p simulate --example bench_step --{}{}",
        if quick { " --quick" } else { "" },
        cases.iter().map(|c| format!(" {c}")).collect::<String>()
    );
    let table = render(
        &command,
        &started,
        &load,
        &step_rows,
        &factor_rows,
        (cores, &thread_rows),
    );
    print!("{table}");
    write_atomic(&output, |w| w.write_all(table.as_bytes()))?;
    eprintln!("written {}", output.display());
    Ok(())
}

/// Runs the child process of `case` on `threads` threads: its row, or the last line of its
/// error output.
fn child_row(case: &str, threads: usize) -> Result<Result<String, String>, Failure> {
    let out = Command::new(std::env::current_exe()?)
        .args(["--child", case, "--threads", &threads.to_string()])
        .output()?;
    let text = String::from_utf8_lossy(&out.stdout);
    Ok(match text.lines().find_map(|l| l.strip_prefix("ROW ")) {
        Some(row) => Ok(row.to_string()),
        None => Err(String::from_utf8_lossy(&out.stderr)
            .lines()
            .last()
            .unwrap_or("no output")
            .to_string()),
    })
}

fn parse_case(case: &str) -> Result<(usize, usize), Failure> {
    let (dim, cells) = case.split_once(':').ok_or("case must be 2d:N or 3d:N")?;
    let dim = match dim {
        "2d" => 2,
        "3d" => 3,
        _ => return Err(format!("unknown dimension in {case}").into()),
    };
    let cells: usize = cells.parse()?;
    if cells == 0 {
        return Err(format!("{case}: N must be positive").into());
    }
    Ok((dim, cells))
}

/// The example problem of dimension D on the unit box with N cells per side.
fn problem_text(dim: usize, cells: usize) -> String {
    let (text, old_box, new_box, initial) = if dim == 2 {
        (
            include_str!("rectangle_2d.toml"),
            "upper = [2.0, 1.0], cells = [40, 20]",
            format!("upper = [1.0, 1.0], cells = [{cells}, {cells}]"),
            "initial_damage = \"1 - 0.4*exp(-((x - 0.6)^2 + (y - 0.8)^2)/0.02)\"",
        )
    } else {
        (
            include_str!("block_3d.toml"),
            "upper = [2.0, 1.0, 1.0], cells = [16, 8, 8]",
            format!("upper = [1.0, 1.0, 1.0], cells = [{cells}, {cells}, {cells}]"),
            "initial_damage = \"1 - 0.4*exp(-((x - 0.6)^2 + (y - 0.5)^2 + (z - 0.8)^2)/0.02)\"",
        )
    };
    let mut out = String::new();
    for line in text.lines() {
        let line = if line.starts_with("final_time") {
            "final_time = 1.0".to_string()
        } else if line.starts_with("steps") {
            "steps = 128".to_string()
        } else if line.starts_with("center") {
            "center = 0.6".to_string()
        } else if line.starts_with("gap") {
            // an obstacle pushed into the body for x < 0.5: contact from the start, the
            // zone moving with the load
            "gap = \"0.03*(x - 0.5)\"".to_string()
        } else {
            line.replace(old_box, &new_box)
        };
        out.push_str(&line);
        out.push('\n');
        if line == "[loads]" {
            out.push_str(initial);
            out.push('\n');
        }
    }
    out
}

fn best_of<T>(repeats: usize, mut run: impl FnMut() -> T) -> f64 {
    (0..repeats)
        .map(|_| {
            let started = Instant::now();
            std::hint::black_box(run());
            started.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn counts(status: &[ContactStatus]) -> [usize; 3] {
    let mut c = [0; 3];
    for s in status {
        match s {
            ContactStatus::Separated => c[0] += 1,
            ContactStatus::Stick => c[1] += 1,
            ContactStatus::Slip => c[2] += 1,
        }
    }
    c
}

/// The measured steps of one repetition: seconds per step and what the steps did.
struct Window {
    loads: f64,
    velocity: f64,
    damage: f64,
    total: f64,
    statistics: f64,
    outer: usize,
    inner: usize,
    damage_factorizations: usize,
    status_first: [usize; 3],
    status_last: [usize; 3],
    active_first: (usize, usize),
    active_last: (usize, usize),
    kkt: [f64; 2],
}

/// Runs the [`MEASURED_STEPS`] steps from the current state, each followed by its row of
/// `history.csv` as the run loop computes it.
fn measure_window<const D: usize>(
    setup: &ProblemSetup<D>,
    simulation: &mut Simulation<D>,
    quadrature: &DomainQuadrature<D>,
    coordinate: &LineCoordinate,
    sums: &mut RunningSums,
) -> Result<Window, Failure> {
    let before = *simulation.timings();
    let (mut total, mut statistics) = (0.0, 0.0);
    let (mut outer, mut inner, mut damage_factorizations) = (0, 0, 0);
    let mut status_first = [0; 3];
    let mut status_last = [0; 3];
    let mut active_first = (0, 0);
    let mut active_last = (0, 0);
    let mut kkt = [0.0f64; 2];
    for m in 0..MEASURED_STEPS {
        let started = Instant::now();
        let outcome = simulation.step()?;
        total += started.elapsed().as_secs_f64();
        let started = Instant::now();
        let record = record_step(setup, simulation, &outcome, quadrature, coordinate, sums);
        std::hint::black_box(record.row.csv_line());
        statistics += started.elapsed().as_secs_f64();
        let contact_damage::StepOutcome {
            velocity, damage, ..
        } = &outcome;
        outer += damage.stats.iterations;
        inner += damage.stats.inner_iterations;
        damage_factorizations += damage.stats.factorizations;
        kkt[0] = kkt[0].max(velocity.stats.kkt_residual);
        kkt[1] = kkt[1].max(damage.stats.kkt_residual);
        let active = (damage.stats.lower_active, damage.stats.upper_active);
        if m == 0 {
            status_first = counts(&velocity.status);
            active_first = active;
        }
        status_last = counts(&velocity.status);
        active_last = active;
    }
    let after = *simulation.timings();
    let per = |d: std::time::Duration| d.as_secs_f64() / MEASURED_STEPS as f64;
    Ok(Window {
        loads: per(after.loads - before.loads),
        velocity: per(after.velocity - before.velocity),
        damage: per(after.damage - before.damage),
        total: total / MEASURED_STEPS as f64,
        statistics: statistics / MEASURED_STEPS as f64,
        outer,
        inner,
        damage_factorizations,
        status_first,
        status_last,
        active_first,
        active_last,
        kkt,
    })
}

/// The measured steps of a case, [`REPEATS`] times, with their reference solves.
struct Windows {
    /// The repetition with the fastest full step.
    fastest: Window,
    /// The fastest of all reference solves.
    reference: f64,
    /// Full step over the repetition's fastest solve, one per repetition, sorted.
    ratios: Vec<f64>,
}

/// Runs [`WARM_STEPS`] steps, then the measured window [`REPEATS`] times from the same state.
fn measure_windows<const D: usize>(
    setup: &ProblemSetup<D>,
    simulation: &mut Simulation<D>,
) -> Result<Windows, Failure> {
    let space = simulation.space().clone();
    let contact = simulation.contact().clone();
    let line = ContactLine::new(&space, &contact);
    let quadrature = DomainQuadrature::new(&space, 2 * space.degree());
    let mut sums = RunningSums::new(contact.len());
    for _ in 0..WARM_STEPS {
        simulation.step()?;
    }
    // The measured window is run REPEATS times from the same state (`set_state`, as `--resume`
    // does; the steps are the same to the bit), each followed by the reference solves, so that
    // a ratio compares steps and solves measured in the same minute of a shared machine.
    let start_state = simulation.state().clone();
    let start_sums = sums.clone();
    let size = simulation.velocity_operator().size();
    let rhs: Vec<f64> = (0..size).map(|i| ((i % 7) as f64) - 3.0).collect();
    let mut fastest: Option<Window> = None;
    let mut references = Vec::with_capacity(REPEATS);
    let mut ratios = Vec::with_capacity(REPEATS);
    for _ in 0..REPEATS {
        simulation.set_state(start_state.clone())?;
        sums = start_sums.clone();
        let window = measure_window(setup, simulation, &quadrature, &line.coordinate, &mut sums)?;
        let solver = simulation.velocity_operator().solver();
        let reference = best_of(REFERENCE_SOLVES, || solver.solve(&rhs));
        references.push(reference);
        ratios.push((window.total + window.statistics) / reference);
        if let Some(first) = &fastest {
            if (first.outer, first.inner, first.kkt) != (window.outer, window.inner, window.kkt) {
                return Err("a repetition of the measured steps solved differently".into());
            }
        }
        if fastest
            .as_ref()
            .is_none_or(|f| window.total + window.statistics < f.total + f.statistics)
        {
            fastest = Some(window);
        }
    }
    let reference = references.iter().copied().fold(f64::INFINITY, f64::min);
    ratios.sort_by(f64::total_cmp);
    Ok(Windows {
        fastest: fastest.expect("REPEATS > 0"),
        reference,
        ratios,
    })
}

/// Runs one case on `threads` threads; returns its row of the table of several threads.
fn measure_threads<const D: usize>(cells: usize, threads: usize) -> Result<String, Failure> {
    let name = format!("{D}d:{cells}");
    let file = parse_problem_file(&problem_text(D, cells), &name)?;
    let setup = ProblemSetup::<D>::new(file, Path::new(&name))?;
    let mut simulation = Simulation::new(setup.problem.clone())?;
    let Windows {
        fastest,
        reference,
        ratios,
    } = measure_windows(&setup, &mut simulation)?;
    Ok(format!(
        "| {name} | {threads} | {} | {} | {} | **{}** | {} | **{:.1}×** ({:.1}–{:.1}) |",
        ms(fastest.loads),
        ms(fastest.total),
        ms(fastest.statistics),
        ms(fastest.total + fastest.statistics),
        ms(reference),
        ratios[REPEATS / 2],
        ratios[0],
        ratios[REPEATS - 1],
    ))
}

/// Runs one case; returns its row of the step table and its row of the factor table,
/// separated by ` ## `.
fn measure<const D: usize>(cells: usize) -> Result<String, Failure> {
    let name = format!("{D}d:{cells}");
    let text = problem_text(D, cells);
    let file = parse_problem_file(&text, &name)?;
    let setup = ProblemSetup::<D>::new(file, Path::new(&name))?;
    let mut simulation = Simulation::new(setup.problem.clone())?;
    let space = simulation.space().clone();
    let k = simulation.time_step();
    let size = simulation.velocity_operator().size();

    let Windows {
        fastest,
        reference,
        ratios,
    } = measure_windows(&setup, &mut simulation)?;

    let Window {
        loads,
        velocity,
        damage,
        total,
        statistics,
        outer,
        inner,
        damage_factorizations,
        status_first,
        status_last,
        active_first,
        active_last,
        kkt,
    } = fastest;
    let rest = total - loads - velocity - damage;
    let per = |d: std::time::Duration| d.as_secs_f64() / MEASURED_STEPS as f64;

    // The same steps with the active set method for (5.2), for comparison.
    let (active_set_damage, active_set_outer, active_set_inner) = {
        let mut problem = setup.problem.clone();
        problem.settings.damage.method = BoxQpMethod::ActiveSet;
        let mut comparison = Simulation::new(problem)?;
        for _ in 0..WARM_STEPS {
            comparison.step()?;
        }
        let before = *comparison.timings();
        let (mut outer, mut inner) = (0, 0);
        for _ in 0..MEASURED_STEPS {
            let outcome = comparison.step()?;
            outer += outcome.damage.stats.iterations;
            inner += outcome.damage.stats.inner_iterations;
        }
        (
            per(comparison.timings().damage - before.damage),
            outer,
            inner,
        )
    };

    let velocity_solver = simulation.velocity_operator().solver();
    let full = total + statistics;
    let step_row = format!(
        "| {name} | {size} / {} | {} | {} | {} | {} | {} | {} | **{}** | {} | **{:.1}×** ({:.1}–{:.1}) | {outer} / {inner} / {damage_factorizations} | {} ({active_set_outer} / {active_set_inner}) | {:?} → {:?} | {:?} → {:?} | {:.0e} / {:.0e} |",
        space.num_nodes(),
        ms(loads),
        ms(velocity),
        ms(damage),
        ms(rest),
        ms(statistics),
        ms(total),
        ms(full),
        ms(reference),
        ratios[REPEATS / 2],
        ratios[0],
        ratios[REPEATS - 1],
        ms(active_set_damage),
        status_first,
        status_last,
        active_first,
        active_last,
        kkt[0],
        kkt[1],
    );

    // simplicial against supernodal, velocity (nested dissection order) and damage (AMD)
    let velocity_matrix = simulation.velocity_operator().assemble(None)?;
    let ordering = velocity_solver.ordering();
    let damage_matrix =
        assemble_damage_matrix(&space, 1.0 / k, setup.problem.model.damage_diffusion)?;
    let mut factor_row = format!("| {name} |");
    for (what, matrix, order) in [
        ("velocity", &velocity_matrix, Some(&ordering)),
        ("damage", &damage_matrix, None),
    ] {
        let rhs: Vec<f64> = (0..matrix.nrows())
            .map(|i| ((i % 5) as f64) - 2.0)
            .collect();
        let mut cells = Vec::new();
        for kind in [FactorKind::Simplicial, FactorKind::Supernodal] {
            let mut solver = match order {
                Some(order) => CholeskySolver::analyse_with_ordering_as(matrix, order, kind, what)?,
                None => CholeskySolver::analyse_as(matrix, kind, what)?,
            };
            let factorize = best_of(1, || solver.factorize(matrix));
            let solve = best_of(5, || solver.solve(&rhs));
            cells.push((factorize, solve));
        }
        let auto = match order {
            Some(order) => CholeskySolver::analyse_with_ordering(matrix, order, what)?,
            None => CholeskySolver::analyse(matrix, what)?,
        };
        let _ = write!(
            factor_row,
            " {} / {} | {} / {} | {} |",
            ms(cells[0].0),
            ms(cells[0].1),
            ms(cells[1].0),
            ms(cells[1].1),
            if auto.is_supernodal() {
                "supernodal"
            } else {
                "simplicial"
            },
        );
    }
    Ok(format!("{step_row} ## {factor_row}"))
}

fn ms(seconds: f64) -> String {
    let value = seconds * 1e3;
    if value < 1.0 {
        format!("{value:.3}")
    } else if value < 100.0 {
        format!("{value:.2}")
    } else {
        format!("{value:.0}")
    }
}

fn render(
    command: &str,
    started: &str,
    load: &str,
    steps: &[String],
    factors: &[String],
    (threads, thread_rows): (usize, &[String]),
) -> String {
    let cpu = report::cpu_model();
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    let mut out = String::new();
    let _ = writeln!(out, "# Per-step budget of `simulate`\n");
    let _ = writeln!(
        out,
        "Command: `{command}`  \nMachine: {cpu}, {cores} cores shared with other jobs (load average at start {load}); one thread per case.  \nDate: {started}.\n"
    );
    let _ = writeln!(
        out,
        "Times in ms per step, mean of steps {}–{} of 128 (T = 1) of the rectangle/block example on the unit box \
         (after the first factorization), the fastest of {REPEATS} runs of these steps from the same state (`set_state`, as `--resume` does; \
         the iteration counts and KKT residuals of every run are checked equal), each run followed by {REFERENCE_SOLVES} solves with the velocity factor. *loads* = load and right-hand-side assembly of (5.1) and (5.2); *rest* = \
         the remainder of `Simulation::step` (penetrations, gap, Dirichlet values); *stats* = the row of `history.csv` \
         (`simulate::record::record_step` and its CSV line, as the run loop does); *step* = `Simulation::step`; *full* = step + stats (everything `simulate` does in \
         a step except writing VTU); *2 tri-solves* = one solve with the velocity factor (forward + backward \
         substitution), the reference limit, the fastest of all {} solves; *ratio* = the median over the {REPEATS} runs of full / 2 tri-solves \
         of the same run (target ≤ 3), in brackets the least and the largest. *damage it.* = outer \
         (monotone multigrid) / inner (preconditioned CG, one truncated V-cycle each) iterations over the measured \
         steps / numeric factorizations; *(5.2) active set* = the damage step of the same steps solved by the \
         primal–dual active set method instead (`damage_method = \"active-set\"`, one Cholesky factor per run), ms \
         per step (outer / inner iterations). Contact nodes as [separated, stick, slip] at the first → last measured step; \
         damage active nodes as (β = 0, β = 1).\n",
        WARM_STEPS + 1,
        WARM_STEPS + MEASURED_STEPS,
        REPEATS * REFERENCE_SOLVES
    );
    let _ = writeln!(
        out,
        "| case | unknowns velocity / damage | loads | (5.1) | (5.2) | rest | stats | step | full | 2 tri-solves | ratio | damage it. outer / inner / fact. | (5.2) active set | contact nodes | damage active | KKT (5.1) / (5.2) |"
    );
    let _ = writeln!(
        out,
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    for row in steps {
        let _ = writeln!(out, "{row}");
    }
    let _ = writeln!(
        out,
        "\n## Simplicial against supernodal Cholesky (faer)\n\nms, numeric factorization (once) / one solve (best of 5; \
         with the supernodal factor the solver's own sweeps, column by column over the supernodes narrower than 32 \
         columns and faer's dense kernels over the wider ones); \
         *auto* = faer's own choice (flop-ratio rule). The velocity operator uses it (supernodal; the trailing block \
         of the supernodal factor is the condensed operator of (5.1)); the damage box QP needs no factor with the \
         default monotone multigrid, and with the active set method one factor per run: simplicial in 2D, \
         supernodal in 3D (`simulate`'s choice of `BoxQpSettings::factorization`).\n"
    );
    let _ = writeln!(
        out,
        "| case | velocity simplicial | velocity supernodal | velocity auto | damage simplicial | damage supernodal | damage auto |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|");
    for row in factors {
        let _ = writeln!(out, "{row}");
    }
    if !thread_rows.is_empty() {
        let _ = writeln!(
            out,
            "\n## On {threads} threads\n\nThe same steps on all {threads} cores of the machine (`simulate`'s default): \
             the loads in parallel chunks of cells, (5.1) and (5.2) at the same time (`rayon::join`: the damage step \
             uses u_(n−1) and β_(n−1), not v_n), the row of `history.csv` in parallel chunks. ms per step, measured \
             as above (fastest of {REPEATS} runs of the steps); *2 tri-solves* = one solve with the velocity factor, \
             which is sequential (the same reference as above, measured again in this process); *ratio* as above. \
             The first table is the work of a step (one thread); this one is what a step of a run takes on this \
             machine as `simulate` runs by default. docs/explanation/performance.md states which cases are within the target in each.\n"
        );
        let _ = writeln!(
            out,
            "| case | threads | loads | step | stats | full | 2 tri-solves | ratio |"
        );
        let _ = writeln!(out, "|---|---|---|---|---|---|---|---|");
        for row in thread_rows {
            let _ = writeln!(out, "{row}");
        }
    }
    out
}
