//! Benchmark of three solver components in isolation, through the public API.
//!
//! ```text
//! cargo run --release -p contact-damage --example bench_components -- [--repeats N] [--output PATH]
//! ```
//!
//! Components and problems (every timed call is repeated N times, default 3, on identical data;
//! the table reports the best and the worst wall time):
//! 1. **Mesh generation** [`Mesh::box_mesh`] (Kuhn triangulation plus boundary detection): the
//!    unit square with 1024 × 1024 cells (2.1 M triangles) and the unit cube with 64³ cells
//!    (1.6 M tetrahedra).
//! 2. **Condensed Tresca friction solver** [`CondensedFriction::solve`] on dense symmetric
//!    positive definite Schur complements like the ones of the velocity step (5.1): the discrete
//!    Dirichlet-to-Neumann map of the 5-point Laplacian of a half-strip onto 513 boundary nodes
//!    (2D body, one tangential unknown per node, G = 1), and the map of the 7-point Laplacian of
//!    a half-space onto 33 × 33 boundary nodes coupled with a 2 × 2 SPD block (3D body, tangential
//!    plane, G = 2, 2178 unknowns). The right-hand side is manufactured from a known solution
//!    with stick and slip nodes (friction bound w = 0.2 per node), so the table also reports the
//!    error against it. Two starts: zero and 10³ sin(i) (a far-off start).
//! 3. **Box-constrained QP solver** [`BoxQpSolver`] of the damage step (5.2) on an m × m grid
//!    (m = 320, 512): A = M/k + κ L with the 5-point Laplacian L and a consistent-type mass M
//!    (h²/2 on the diagonal, h²/8 for the 4 neighbours: positive off-diagonal entries, so A is
//!    not an M-matrix), k = 10⁻³, κ = 10⁻⁴, bounds 0 ≤ β ≤ 1, and five damage-like time steps
//!    from β = ½: a source of ±1000 on two discs pushes β above 1 in one and below 0 in the
//!    other; steps 4 and 5 move the discs by 0.01 and 0.02, so the active sets change. Each
//!    repetition starts from a fresh solver ([`BoxQpSolver::new`]: its multigrid hierarchy, or
//!    with the active set method its symbolic analysis) so that every repetition starts from the
//!    same state.
//!
//! The KKT residuals are recomputed outside the timed calls with the public residual functions
//! ([`CondensedFriction::kkt_report`], [`box_qp_kkt_residual`]).
//!
//! The markdown table goes to stdout and, written atomically (temporary file + rename), to
//! `reports/benchmark_components.md` of the workspace, or to `--output PATH`.

#[path = "common/report.rs"]
mod report;
use contact_damage::algebra::linalg::multiply;
use contact_damage::fem::mesh::{BoundaryPart, Mesh};
use contact_damage::solvers::box_qp::{
    box_qp_kkt_residual, BoxQpSettings, BoxQpSolver, BoxQpStats,
};
use contact_damage::solvers::friction::{CondensedFriction, FrictionSettings};
use faer::sparse::{SparseColMat, Triplet};
use faer::Mat;
use report::{cpu_model, fmt_s, load_average, utc_now, write_atomically};
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// Sparse matrix of the box QP.
type SparseMatrix = SparseColMat<usize, f64>;

/// Default number of repetitions of every timed call.
const DEFAULT_REPEATS: usize = 3;
/// Friction bound w_a of every contact node in the friction problems.
const FRICTION_WEIGHT: f64 = 0.2;
/// Threshold of the manufactured friction solution: |profile| > threshold slips.
const SLIP_THRESHOLD: f64 = 0.5;
/// Time step k and diffusion κ of the damage-like box QP.
const QP_TIME_STEP: f64 = 1e-3;
const QP_DIFFUSION: f64 = 1e-4;
/// Strength of the damage-like source on the two discs.
const QP_SOURCE: f64 = 1000.0;

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("bench_components: {message}");
            ExitCode::FAILURE
        }
    }
}

/// Command-line options.
struct Options {
    repeats: usize,
    output: Option<PathBuf>,
}

fn parse_options() -> Result<Options, String> {
    let mut options = Options {
        repeats: DEFAULT_REPEATS,
        output: None,
    };
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--repeats" => {
                let value = args.next().ok_or("--repeats needs a value")?;
                options.repeats =
                    value
                        .parse()
                        .ok()
                        .filter(|&n: &usize| n >= 1)
                        .ok_or_else(|| {
                            format!("--repeats expects a whole number ≥ 1, got {value:?}")
                        })?;
            }
            "--output" => {
                options.output = Some(PathBuf::from(args.next().ok_or("--output needs a path")?))
            }
            "-h" | "--help" => {
                println!("usage: bench_components [--repeats N] [--output PATH]");
                std::process::exit(0);
            }
            other => return Err(format!("unknown argument {other:?} (try --help)")),
        }
    }
    Ok(options)
}

/// One line of the table.
struct Row {
    component: &'static str,
    case: String,
    size: String,
    iterations: String,
    kkt: String,
    check: String,
    /// All measured wall times in seconds, or the reason of a failure.
    times: Result<Vec<f64>, String>,
}

impl Row {
    fn failed(component: &'static str, case: String, reason: String) -> Self {
        Row {
            component,
            case,
            size: String::new(),
            iterations: String::new(),
            kkt: String::new(),
            check: String::new(),
            times: Err(reason),
        }
    }
}

fn run() -> Result<(), String> {
    let options = parse_options()?;
    let load_start = load_average();
    let mut rows = Vec::new();

    eprintln!("== mesh generation ==");
    rows.extend(bench_mesh(options.repeats));
    eprintln!("== condensed friction solver ==");
    rows.extend(bench_friction(options.repeats));
    eprintln!("== box-constrained QP solver ==");
    for side in [320, 512] {
        rows.extend(
            bench_box_qp(side, options.repeats).unwrap_or_else(|reason| {
                vec![Row::failed("box QP", format!("{side}² grid"), reason)]
            }),
        );
    }

    let mut command =
        String::from("cargo run --release -p contact-damage --example bench_components");
    let arguments: Vec<String> = std::env::args().skip(1).collect();
    if !arguments.is_empty() {
        command.push_str(" -- ");
        command.push_str(&arguments.join(" "));
    }
    let report = render(&command, &rows, options.repeats, &load_start);
    print!("{report}");
    let path = options.output.unwrap_or_else(|| {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../reports/benchmark_components.md")
    });
    write_atomically(&path, &report)?;
    eprintln!("written to {}", path.display());
    if rows.iter().any(|row| row.times.is_err()) {
        return Err("some measurements failed (see the table)".into());
    }
    Ok(())
}

/// Runs `work` `repeats` times; returns the wall times and the result of the last run.
fn repeat<T, E>(
    repeats: usize,
    mut work: impl FnMut() -> Result<T, E>,
) -> Result<(Vec<f64>, T), E> {
    let mut times = Vec::with_capacity(repeats);
    let mut last = None;
    for _ in 0..repeats {
        let start = Instant::now();
        let value = work()?;
        times.push(start.elapsed().as_secs_f64());
        last = Some(value);
    }
    Ok((times, last.expect("repeats ≥ 1")))
}

fn best(times: &[f64]) -> f64 {
    times.iter().copied().fold(f64::INFINITY, f64::min)
}

fn worst(times: &[f64]) -> f64 {
    times.iter().copied().fold(0.0, f64::max)
}

// ---------------------------------------------------------------------------------------------
// 1. Mesh generation

fn bench_mesh(repeats: usize) -> Vec<Row> {
    use BoundaryPart::{Contact, Dirichlet, Neumann};
    let mut rows = Vec::new();
    let square = repeat(repeats, || {
        Mesh::<2>::box_mesh(
            [0.0; 2],
            [1.0; 2],
            [1024; 2],
            [[Dirichlet, Neumann], [Contact, Neumann]],
        )
    });
    rows.push(mesh_row(
        "2D unit square, 1024²",
        square.map(|(t, mesh)| (t, mesh.num_cells(), mesh.num_vertices())),
    ));
    let cube = repeat(repeats, || {
        Mesh::<3>::box_mesh([0.0; 3], [1.0; 3], [64; 3], [[Dirichlet, Neumann]; 3])
    });
    rows.push(mesh_row(
        "3D unit cube, 64³",
        cube.map(|(t, mesh)| (t, mesh.num_cells(), mesh.num_vertices())),
    ));
    rows
}

fn mesh_row(case: &str, outcome: contact_damage::Result<(Vec<f64>, usize, usize)>) -> Row {
    match outcome {
        Ok((times, cells, vertices)) => {
            eprintln!("  {case}: {:.3} s", best(&times));
            Row {
                component: "`Mesh::box_mesh`",
                case: case.to_string(),
                size: format!("{} cells, {} vertices", count(cells), count(vertices)),
                iterations: "—".into(),
                kkt: "—".into(),
                check: format!("{} cells/s", count_f(cells as f64 / best(&times))),
                times: Ok(times),
            }
        }
        Err(e) => Row::failed("`Mesh::box_mesh`", case.to_string(), e.to_string()),
    }
}

// ---------------------------------------------------------------------------------------------
// 2. Condensed friction solver

/// Discrete Dirichlet-to-Neumann map of the 5-point (`dimension` = 1: boundary line of `side`
/// nodes) or 7-point (`dimension` = 2: boundary grid of `side` × `side` nodes) Laplacian of a
/// half-strip (half-space): the Schur complement of the interior unknowns, dense, symmetric
/// positive definite with condition number ~ side.
///
/// In the sine basis of the boundary Laplacian (eigenvalues λ_k) the map is diagonal with
/// entries λ/2 + sqrt(λ + λ²/4), the decaying solution of the three-term recurrence in the
/// normal direction.
fn dirichlet_to_neumann(side: usize, dimension: usize) -> Mat<f64> {
    let h = PI / (side + 1) as f64;
    let sine = Mat::from_fn(side, side, |i, j| {
        (2.0 / (side + 1) as f64).sqrt() * (((i + 1) * (j + 1)) as f64 * h).sin()
    });
    let eigenvalue = |k: usize| 4.0 * (0.5 * (k + 1) as f64 * h).sin().powi(2);
    let (basis, laplacian): (Mat<f64>, Vec<f64>) = if dimension == 1 {
        (sine, (0..side).map(eigenvalue).collect())
    } else {
        let n = side * side;
        (
            Mat::from_fn(n, n, |i, j| {
                sine[(i / side, j / side)] * sine[(i % side, j % side)]
            }),
            (0..n)
                .map(|k| eigenvalue(k / side) + eigenvalue(k % side))
                .collect(),
        )
    };
    let n = laplacian.len();
    let scaled = Mat::from_fn(n, n, |i, j| {
        let lambda = laplacian[j];
        basis[(i, j)] * (0.5 * lambda + (lambda + 0.25 * lambda * lambda).sqrt())
    });
    let product = scaled * basis.transpose();
    // Symmetrize away the rounding of the product.
    Mat::from_fn(n, n, |i, j| 0.5 * (product[(i, j)] + product[(j, i)]))
}

/// A friction problem with a known solution: S, the solution x*, and the multipliers λ* with
/// λ*_a = x*_a / |x*_a| on slip nodes and |λ*_a| ≤ 1 on stick nodes.
struct ManufacturedFriction {
    case: String,
    matrix: Mat<f64>,
    solution: Vec<f64>,
    multiplier: Vec<f64>,
    weights: Vec<f64>,
    group_size: usize,
}

/// 2D body: 513 contact nodes on a line, G = 1, profile 1.5 sin(3πs) + 0.5 s soft-thresholded.
fn friction_problem_2d() -> ManufacturedFriction {
    let side = 513;
    let matrix = dirichlet_to_neumann(side, 1);
    let mut solution = vec![0.0; side];
    let mut multiplier = vec![0.0; side];
    for i in 0..side {
        let s = (i + 1) as f64 / (side + 1) as f64;
        let profile = 1.5 * (3.0 * PI * s).sin() + 0.5 * s;
        if profile.abs() > SLIP_THRESHOLD {
            solution[i] = profile - SLIP_THRESHOLD * profile.signum();
            multiplier[i] = profile.signum();
        } else {
            multiplier[i] = profile / SLIP_THRESHOLD;
        }
    }
    ManufacturedFriction {
        case: format!("2D, {side} nodes, G = 1"),
        matrix,
        solution,
        multiplier,
        weights: vec![FRICTION_WEIGHT; side],
        group_size: 1,
    }
}

/// 3D body: 33 × 33 contact nodes, G = 2, S = DtN ⊗ C with the 2 × 2 SPD coupling C.
fn friction_problem_3d() -> ManufacturedFriction {
    let side = 33;
    let scalar = dirichlet_to_neumann(side, 2);
    let coupling = [[1.0, 0.3], [0.3, 0.7]];
    let groups = side * side;
    let matrix = Mat::from_fn(2 * groups, 2 * groups, |i, j| {
        scalar[(i / 2, j / 2)] * coupling[i % 2][j % 2]
    });
    let mut solution = vec![0.0; 2 * groups];
    let mut multiplier = vec![0.0; 2 * groups];
    for a in 0..groups {
        let s = (a / side + 1) as f64 / (side + 1) as f64;
        let t = (a % side + 1) as f64 / (side + 1) as f64;
        let profile = [
            1.5 * (2.0 * PI * s).sin() * (PI * t).cos(),
            1.2 * (3.0 * PI * s).cos() * (2.0 * PI * t).sin(),
        ];
        let norm = profile[0].hypot(profile[1]);
        for k in 0..2 {
            if norm > SLIP_THRESHOLD {
                solution[2 * a + k] = profile[k] * (1.0 - SLIP_THRESHOLD / norm);
                multiplier[2 * a + k] = profile[k] / norm;
            } else {
                multiplier[2 * a + k] = profile[k] / SLIP_THRESHOLD;
            }
        }
    }
    ManufacturedFriction {
        case: format!("3D, {side}×{side} nodes, G = 2"),
        matrix,
        solution,
        multiplier,
        weights: vec![FRICTION_WEIGHT; groups],
        group_size: 2,
    }
}

fn bench_friction(repeats: usize) -> Vec<Row> {
    let mut rows = Vec::new();
    for manufactured in [friction_problem_2d(), friction_problem_3d()] {
        let m = manufactured.solution.len();
        let group = manufactured.group_size;
        // r = S x* + W λ*
        let rhs: Vec<f64> = (0..m)
            .map(|i| {
                (0..m)
                    .map(|j| manufactured.matrix[(i, j)] * manufactured.solution[j])
                    .sum::<f64>()
                    + manufactured.weights[i / group] * manufactured.multiplier[i]
            })
            .collect();
        let problem = CondensedFriction {
            matrix: manufactured.matrix.as_ref(),
            rhs: &rhs,
            weights: &manufactured.weights,
            group_size: group,
        };
        for (start_label, start) in [
            ("zero start", vec![0.0; m]),
            (
                "start 10³ sin(i)",
                (0..m).map(|i| 1e3 * (i as f64).sin()).collect(),
            ),
        ] {
            let case = format!("{}, {start_label}", manufactured.case);
            let outcome = repeat(repeats, || {
                let mut x = start.clone();
                let mut multipliers = vec![0.0; m];
                problem
                    .solve(&mut x, &mut multipliers, &FrictionSettings::default())
                    .map(|stats| (x, stats))
            });
            let row = match outcome {
                Ok((times, (x, stats))) => {
                    eprintln!("  {case}: {:.3} s", best(&times));
                    let error = x
                        .iter()
                        .zip(&manufactured.solution)
                        .fold(0.0_f64, |acc, (a, b)| acc.max((a - b).abs()));
                    Row {
                        component: "`CondensedFriction::solve`",
                        case,
                        size: format!("m = {m} (dense S)"),
                        iterations: format!(
                            "Newton {}, gradient {}",
                            stats.newton_iterations, stats.gradient_iterations
                        ),
                        kkt: format!("{:.1e}", problem.kkt_report(&x).max()),
                        check: format!(
                            "‖x − x*‖∞ = {error:.1e}; stick/slip {}/{}",
                            stats.stick, stats.slip
                        ),
                        times: Ok(times),
                    }
                }
                Err(e) => Row::failed("`CondensedFriction::solve`", case, e.to_string()),
            };
            rows.push(row);
        }
    }
    rows
}

// ---------------------------------------------------------------------------------------------
// 3. Box-constrained QP solver

/// The damage-like steps: label and shift of the source discs.
const QP_STEPS: [(&str, f64); 5] = [
    ("step 1 (cold)", 0.0),
    ("step 2, same source", 0.0),
    ("step 3, same source", 0.0),
    ("step 4, source moved by 0.01", 0.01),
    ("step 5, source moved by 0.02", 0.02),
];

/// The grid problem of the module docs: (A, M) on a `side` × `side` grid of the unit square.
fn grid_matrices(side: usize) -> Result<(SparseMatrix, SparseMatrix), String> {
    let n = side * side;
    let h = 1.0 / (side - 1) as f64;
    let (mass_diagonal, mass_neighbour) = (0.5 * h * h, 0.125 * h * h);
    let mut triplets = Vec::with_capacity(5 * n);
    let mut mass_triplets = Vec::with_capacity(5 * n);
    for iy in 0..side {
        for ix in 0..side {
            let i = iy * side + ix;
            triplets.push(Triplet::new(
                i,
                i,
                mass_diagonal / QP_TIME_STEP + 4.0 * QP_DIFFUSION,
            ));
            mass_triplets.push(Triplet::new(i, i, mass_diagonal));
            let neighbours = [
                (ix > 0).then(|| i - 1),
                (ix + 1 < side).then(|| i + 1),
                (iy > 0).then(|| i - side),
                (iy + 1 < side).then(|| i + side),
            ];
            for j in neighbours.into_iter().flatten() {
                triplets.push(Triplet::new(
                    i,
                    j,
                    mass_neighbour / QP_TIME_STEP - QP_DIFFUSION,
                ));
                mass_triplets.push(Triplet::new(i, j, mass_neighbour));
            }
        }
    }
    let matrix = SparseColMat::try_new_from_triplets(n, n, &triplets)
        .map_err(|e| format!("cannot build A: {e:?}"))?;
    let mass = SparseColMat::try_new_from_triplets(n, n, &mass_triplets)
        .map_err(|e| format!("cannot build M: {e:?}"))?;
    Ok((matrix, mass))
}

/// Right-hand side b = M (β_prev / k + source) of one damage-like step.
fn qp_rhs(mass: &SparseMatrix, side: usize, previous: &[f64], shift: f64) -> Vec<f64> {
    let h = 1.0 / (side - 1) as f64;
    let source = |x: f64, y: f64| {
        let inside_up = (x - 0.3 - shift).powi(2) + (y - 0.3).powi(2) < 0.04;
        let inside_down = (x - 0.7).powi(2) + (y - 0.7 + shift).powi(2) < 0.04;
        QP_SOURCE * (f64::from(u8::from(inside_up)) - f64::from(u8::from(inside_down)))
    };
    let load: Vec<f64> = previous
        .iter()
        .enumerate()
        .map(|(i, beta)| beta / QP_TIME_STEP + source((i % side) as f64 * h, (i / side) as f64 * h))
        .collect();
    multiply(mass, &load)
}

fn bench_box_qp(side: usize, repeats: usize) -> Result<Vec<Row>, String> {
    let (matrix, mass) = grid_matrices(side)?;
    let n = side * side;
    let nnz = matrix.val().len();
    let (lower, upper) = (vec![0.0; n], vec![1.0; n]);
    let mut new_times = Vec::with_capacity(repeats);
    let mut step_times = vec![Vec::with_capacity(repeats); QP_STEPS.len()];
    // statistics and independent KKT residual of every step, from the first repetition
    let mut step_results: Vec<(BoxQpStats, f64)> = Vec::new();
    let mut varied = vec![false; QP_STEPS.len()];
    for repetition in 0..repeats {
        let start = Instant::now();
        let mut solver = BoxQpSolver::new(matrix.clone(), BoxQpSettings::default())
            .map_err(|e| format!("BoxQpSolver::new: {e}"))?;
        new_times.push(start.elapsed().as_secs_f64());
        let mut x = vec![0.5; n];
        for (step, &(label, shift)) in QP_STEPS.iter().enumerate() {
            let rhs = qp_rhs(&mass, side, &x, shift);
            let start = Instant::now();
            let stats = solver
                .solve(&rhs, &lower, &upper, &mut x)
                .map_err(|e| format!("{label}: {e}"))?;
            step_times[step].push(start.elapsed().as_secs_f64());
            if repetition == 0 {
                let residual = box_qp_kkt_residual(&matrix, &rhs, &lower, &upper, &x);
                step_results.push((stats, residual));
            } else {
                let first = &step_results[step].0;
                varied[step] |= first.iterations != stats.iterations
                    || first.factorizations != stats.factorizations;
            }
        }
    }
    let case = |what: &str| format!("{side}² grid, {what}");
    let size = format!("n = {}, nnz(A) = {}", count(n), count(nnz));
    eprintln!("  {}: {:.3} s", case("new"), best(&new_times));
    let mut rows = vec![Row {
        component: "`BoxQpSolver::new`",
        case: case("set-up (multigrid hierarchy)"),
        size: size.clone(),
        iterations: "—".into(),
        kkt: "—".into(),
        check: String::new(),
        times: Ok(new_times),
    }];
    for (step, ((label, _), times)) in QP_STEPS.iter().zip(step_times).enumerate() {
        let (stats, residual) = &step_results[step];
        eprintln!("  {}: {:.3} s", case(label), best(&times));
        rows.push(Row {
            component: "`BoxQpSolver::solve`",
            case: case(label),
            size: size.clone(),
            iterations: format!(
                "{} ({} fact.){}{}",
                stats.iterations,
                stats.factorizations,
                if stats.used_fallback {
                    ", projected Newton"
                } else {
                    ""
                },
                if varied[step] {
                    "; varied between runs"
                } else {
                    ""
                }
            ),
            kkt: format!("{residual:.1e}"),
            check: format!(
                "at 0 / at 1: {} / {}",
                count(stats.lower_active),
                count(stats.upper_active)
            ),
            times: Ok(times),
        });
    }
    Ok(rows)
}

// ---------------------------------------------------------------------------------------------
// Report

fn count(value: usize) -> String {
    count_f(value as f64)
}

fn count_f(value: f64) -> String {
    if value >= 1e6 {
        format!("{:.2} M", value / 1e6)
    } else if value >= 1e3 {
        format!("{:.1} k", value / 1e3)
    } else {
        format!("{value:.0}")
    }
}

/// The markdown report.
fn render(command: &str, rows: &[Row], repeats: usize, load_start: &str) -> String {
    let mut out = String::new();
    let threads = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    let _ = writeln!(out, "# Component benchmarks\n");
    let _ = writeln!(out, "```text\n{command}\n```\n");
    let _ = writeln!(
        out,
        "Machine: {} × {threads} (nproc = {threads}), load average {load_start} at the start and {} at the end; \
         date {}. The machine is shared: a load above {threads} means the timings include contention.\n",
        cpu_model(),
        load_average(),
        utc_now()
    );
    let _ = writeln!(
        out,
        "| component | case | size | iterations | KKT residual | check | best of {repeats} (s) | worst (s) |"
    );
    let _ = writeln!(out, "|---|---|---|---|---:|---|---:|---:|");
    for row in rows {
        match &row.times {
            Ok(times) => {
                let _ = writeln!(
                    out,
                    "| {} | {} | {} | {} | {} | {} | {} | {} |",
                    row.component,
                    row.case,
                    row.size,
                    row.iterations,
                    row.kkt,
                    row.check,
                    fmt_s(best(times)),
                    fmt_s(worst(times))
                );
            }
            Err(reason) => {
                let _ = writeln!(
                    out,
                    "| {} | {} | failed: {} | | | | | |",
                    row.component,
                    row.case,
                    reason.replace('|', "\\|").replace('\n', " ")
                );
            }
        }
    }
    let _ = writeln!(out);
    let _ = writeln!(
        out,
        "Rows: *`Mesh::box_mesh`* = Kuhn mesh of the unit box with boundary detection (sides tagged \
         Dirichlet/Contact/Neumann), *check* = cells per second. *`CondensedFriction::solve`* = the \
         condensed Tresca friction problem min ½ xᵀSx − rᵀx + Σ w_a|x_a| with S the dense discrete \
         Dirichlet-to-Neumann map of the Laplacian (half-strip onto 513 boundary nodes; half-space onto \
         33 × 33 nodes, Kronecker with a 2 × 2 SPD block), w_a = {FRICTION_WEIGHT}, r manufactured from a \
         known solution x* with stick and slip nodes; *iterations* = Newton systems (dense Cholesky) and \
         proximal-gradient steps; *KKT residual* = `kkt_report(x).max()` (tolerance 1e-12); *check* = \
         max error against x* and the stick/slip node counts. *`BoxQpSolver::new`* = the set-up for \
         A = M/k + κL on the grid (5-point L, consistent-type M with positive off-diagonals, k = \
         {QP_TIME_STEP:e}, κ = {QP_DIFFUSION:e}); *`BoxQpSolver::solve`* = one damage-like step with bounds \
         0 ≤ β ≤ 1 from the previous step's β (β = ½ before step 1), source ±{QP_SOURCE} on two discs of \
         radius 0.2, moved by 0.01 and 0.02 in steps 4 and 5; a fresh solver per repetition; \
         *iterations* = outer iterations of the default method (`BoxQpSettings::default()`, the \
         truncated nonsmooth Newton multigrid) with the numeric Cholesky factorizations of the call \
         (none with the multigrid); *KKT residual* = `box_qp_kkt_residual` (tolerance 1e-12); *check* = indices at the \
         lower / upper bound. Times: wall clock of the call alone (data construction and residual \
         checks excluded), best and worst of {repeats} runs on identical data.\n"
    );
    out
}
