//! Performance benchmark of the solver for P1 elements on the unit box, through the public API.
//!
//! ```text
//! cargo run --release -p contact-damage --example bench -- [--quick] [--timeout SECONDS] [--output PATH]
//! ```
//!
//! Geometry: the unit square (2D, N = 256, 512, 1024 cells per side) and the unit cube (3D,
//! N = 16, 32), Kuhn meshes, with Γ1 = {x = 0} (clamped), Γ3 = {y = 0} in 2D / {z = 0} in 3D
//! (contact) and Γ2 on the other sides. `--quick` runs 2D N = 256 and 3D N = 16 only.
//!
//! Every size runs in a fresh process (the example re-invokes itself with `--size 2d:512`), so
//! the peak resident memory (VmHWM of /proc/self/status) is per size, and a size that runs out
//! of memory or exceeds the timeout shows up as a failed row instead of ending the benchmark.
//!
//! Measured per size, in this order:
//! 1. mesh generation ([`Mesh::box_mesh`]);
//! 2. standalone linear algebra on the space: [`VelocityOperator::new`] (pattern, one assembly
//!    and symbolic analysis), the numeric assembly [`VelocityOperator::assemble`] (best of 3),
//!    the symbolic analysis [`CholeskySolver::analyse`] of the assembled matrix, one numeric
//!    factorization plus one solve with that [`CholeskySolver`], the first
//!    [`VelocityOperator::solve`] (numeric factorization + condensed Schur complement on the Γ3
//!    tangential unknowns + friction problem) and a second solve with the same data (the
//!    per-step cost of the velocity step (5.1) for the linear viscosity), and one damage step
//!    (5.2) with [`DamageOperator::solve`] (cold: it includes the numeric factorizations);
//! 3. a [`Simulation`] of Problem P_V^hk with active contact and evolving damage: construction,
//!    the first step (which factorizes), the load assembly [`Simulation::step_loads`] alone, and
//!    the second step, the number reported as "one full step".
//!
//! The loading presses the body onto the foundation: u0 = −a x e_D (zero on Γ1), so that
//! u0·ν = a x on Γ3 penetrates the gap g for x > g/a, and a traction on the top side with a
//! downward and a tangential component; the nodes near Γ1 are separated, the others are in
//! contact, partly stuck and partly slipping (the table reports the counts of the second step).
//!
//! The markdown table goes to stdout and, written atomically (temporary file + rename), to
//! `reports/benchmark.md` of the workspace (`reports/benchmark-quick.md` with `--quick`, so a
//! smoke test does not overwrite the full table), or to `--output PATH`.

#[path = "common/report.rs"]
mod report;
use contact_damage::algebra::linalg::{multiply, CholeskySolver};
use contact_damage::algebra::ordering::{fill_reducing_node_order, NodeGraph};
use contact_damage::fem::mesh::{BoundaryPart, Mesh};
use contact_damage::fem::space::LagrangeSpace;
use contact_damage::model::contact::{ContactNodes, ContactStatus};
use contact_damage::model::laws::{
    DamageSourceFn, DamagedHooke, LinearViscosity, NormalComplianceCoulomb, Tensor, Viscosity,
};
use contact_damage::scheme::assembly::add_facet_integrals;
use contact_damage::scheme::damage::{assemble_damage_matrix, DamageOperator};
use contact_damage::scheme::velocity::{VelocityData, VelocityOperator, VelocitySettings};
use contact_damage::scheme::{Data, Model, Problem, SchemeSettings, Simulation, StepOutcome};
use contact_damage::solvers::box_qp::BoxQpSettings;
use report::{cpu_model, fmt_s, load_average, utc_now, write_atomically};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Sizes of the full benchmark: (dimension, cells per side).
const FULL_CASES: [(usize, usize); 5] = [(2, 256), (2, 512), (2, 1024), (3, 16), (3, 32)];
/// Sizes of `--quick`.
const QUICK_CASES: [(usize, usize); 2] = [(2, 256), (3, 16)];
/// Default wall-time limit of one size, in seconds.
const DEFAULT_TIMEOUT: u64 = 3600;

/// Viscosity 𝒜ε = 2η ε + ζ tr(ε) I.
const VISCOSITY: LinearViscosity = LinearViscosity {
    shear: 1.0,
    bulk: 0.5,
};
/// Elasticity G(ε, β) = β (2μ ε + λ tr(ε) I).
const ELASTICITY: DamagedHooke = DamagedHooke {
    shear_modulus: 1.0,
    lame_lambda: 1.0,
};
/// Normal compliance c_ν r₊ and Coulomb bound μ p_ν.
const CONTACT: NormalComplianceCoulomb = NormalComplianceCoulomb {
    stiffness: 100.0,
    friction: 0.4,
    wear: 0.0,
};
/// Damage diffusion κ.
const DAMAGE_DIFFUSION: f64 = 0.1;
/// Slope a of the initial displacement u0 = −a x e_D.
const DISPLACEMENT_SLOPE: f64 = 0.02;
/// Gap g on Γ3 (constant).
const GAP: f64 = 0.005;
/// Traction on the top side: tangential component (along e_1) and downward pressure.
const TOP_TRACTION: (f64, f64) = (0.05, 0.2);
/// Final time T and number of steps N of the simulation (k = T/N; two steps are run).
const FINAL_TIME: f64 = 0.1;
const STEPS: usize = 10;

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("bench: {message}");
            ExitCode::FAILURE
        }
    }
}

/// Command-line options.
struct Options {
    quick: bool,
    size: Option<(usize, usize)>,
    timeout: Duration,
    output: Option<PathBuf>,
}

fn parse_case(text: &str) -> Result<(usize, usize), String> {
    let bad = || format!("--size expects 2d:N or 3d:N with N ≥ 1, got {text:?}");
    let (dim, cells) = text.split_once(':').ok_or_else(bad)?;
    let dim = match dim.to_ascii_lowercase().as_str() {
        "2d" => 2,
        "3d" => 3,
        _ => return Err(bad()),
    };
    let cells: usize = cells.parse().map_err(|_| bad())?;
    if cells == 0 {
        return Err(bad());
    }
    Ok((dim, cells))
}

fn parse_options() -> Result<Options, String> {
    let mut options = Options {
        quick: false,
        size: None,
        timeout: Duration::from_secs(DEFAULT_TIMEOUT),
        output: None,
    };
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--quick" => options.quick = true,
            "--size" => {
                options.size = Some(parse_case(&args.next().ok_or("--size needs a value")?)?)
            }
            "--timeout" => {
                let value = args.next().ok_or("--timeout needs a value in seconds")?;
                let seconds: u64 = value
                    .parse()
                    .map_err(|_| format!("--timeout expects whole seconds, got {value:?}"))?;
                options.timeout = Duration::from_secs(seconds);
            }
            "--output" => {
                options.output = Some(PathBuf::from(args.next().ok_or("--output needs a path")?))
            }
            "-h" | "--help" => {
                println!(
                    "usage: bench [--quick] [--timeout SECONDS] [--output PATH] [--size 2d:N|3d:N]"
                );
                std::process::exit(0);
            }
            other => return Err(format!("unknown argument {other:?} (try --help)")),
        }
    }
    Ok(options)
}

fn run() -> Result<(), String> {
    let options = parse_options()?;
    if let Some((dim, cells)) = options.size {
        // child mode: measure one size and print one machine-readable line on stdout
        let row = match dim {
            2 => measure::<2>(cells),
            _ => measure::<3>(cells),
        }
        .map_err(|e| format!("{dim}D N={cells}: {e}"))?;
        let line: Vec<String> = row.iter().map(|(k, v)| format!("{k}={v}")).collect();
        println!("ROW {}", line.join(" "));
        return Ok(());
    }
    let cases: &[(usize, usize)] = if options.quick {
        &QUICK_CASES
    } else {
        &FULL_CASES
    };
    let exe = std::env::current_exe()
        .map_err(|e| format!("cannot locate the benchmark executable: {e}"))?;
    let mut results = Vec::new();
    for &(dim, cells) in cases {
        eprintln!("== {dim}D P1, N = {cells} ==");
        results.push(((dim, cells), run_child(&exe, dim, cells, options.timeout)));
    }
    let mut command = String::from("cargo run --release -p contact-damage --example bench");
    if options.quick {
        command.push_str(" -- --quick");
    }
    let report = render(&command, &results, options.timeout);
    print!("{report}");
    let path = options.output.unwrap_or_else(|| {
        let name = if options.quick {
            "benchmark-quick.md"
        } else {
            "benchmark.md"
        };
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../reports")
            .join(name)
    });
    write_atomically(&path, &report)?;
    eprintln!("written to {}", path.display());
    Ok(())
}

/// Runs one size in a child process; Ok(fields) or Err(reason of failure).
fn run_child(
    exe: &Path,
    dim: usize,
    cells: usize,
    timeout: Duration,
) -> Result<BTreeMap<String, String>, String> {
    let mut child = Command::new(exe)
        .args(["--size", &format!("{dim}d:{cells}")])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .map_err(|e| format!("could not start: {e}"))?;
    let mut stdout = child.stdout.take().ok_or("no stdout pipe")?;
    let reader = std::thread::spawn(move || {
        let mut text = String::new();
        let _ = stdout.read_to_string(&mut text);
        text
    });
    let start = Instant::now();
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break status,
            Ok(None) if start.elapsed() > timeout => {
                let _ = child.kill();
                let _ = child.wait();
                let _ = reader.join();
                return Err(format!(
                    "too slow: stopped after the {} s time limit",
                    timeout.as_secs()
                ));
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(200)),
            Err(e) => return Err(format!("wait failed: {e}")),
        }
    };
    let text = reader.join().unwrap_or_default();
    if !status.success() {
        use std::os::unix::process::ExitStatusExt;
        return Err(match status.signal() {
            Some(9) => "killed by SIGKILL (out of memory?)".to_string(),
            Some(signal) => format!("killed by signal {signal}"),
            None => format!("failed with {status} (see stderr)"),
        });
    }
    let line = text
        .lines()
        .find_map(|l| l.strip_prefix("ROW "))
        .ok_or("no result line in the output")?;
    Ok(line
        .split_whitespace()
        .filter_map(|field| field.split_once('='))
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect())
}

/// Peak resident set size of this process in MiB (VmHWM), if readable.
fn peak_memory_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

/// Resets VmHWM to the current RSS (Linux ≥ 4.0); false if not permitted.
fn reset_peak_memory() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

fn seconds(since: Instant) -> f64 {
    since.elapsed().as_secs_f64()
}

/// Progress on stderr.
fn progress(dim: usize, cells: usize, what: &str, value: f64) {
    eprintln!("  [{dim}D N={cells}] {what}: {value:.3} s");
}

/// The unit box with Γ1 = {x = 0}, Γ3 = {x_D = 0}, Γ2 elsewhere.
fn unit_box<const D: usize>(cells: usize) -> contact_damage::Result<Mesh<D>> {
    use BoundaryPart::*;
    let mut sides = [[Neumann, Neumann]; D];
    sides[0][0] = Dirichlet;
    sides[D - 1][0] = Contact;
    Mesh::box_mesh([0.0; D], [1.0; D], [cells; D], sides)
}

/// Traction on the top side x_D = 1: (τ, 0, …, −p); zero on the other Γ2 sides.
fn top_traction<const D: usize>(x: &[f64; D]) -> [f64; D] {
    let mut f = [0.0; D];
    if x[D - 1] > 1.0 - 1e-9 {
        f[0] = TOP_TRACTION.0;
        f[D - 1] = -TOP_TRACTION.1;
    }
    f
}

/// u0 = −a x e_D.
fn initial_displacement<const D: usize>(x: &[f64; D]) -> [f64; D] {
    let mut u = [0.0; D];
    u[D - 1] = -DISPLACEMENT_SLOPE * x[0];
    u
}

fn problem<const D: usize>(mesh: Arc<Mesh<D>>) -> Problem<D> {
    Problem {
        mesh,
        degree: 1,
        model: Model {
            viscosity: Arc::new(VISCOSITY),
            elasticity: Arc::new(ELASTICITY),
            damage_source: Arc::new(DamageSourceFn(|strain: &Tensor<D>, beta: f64| {
                0.1 * (1.0 - beta) - 0.5 * strain.norm_squared()
            })),
            contact: Arc::new(CONTACT),
            damage_diffusion: DAMAGE_DIFFUSION,
        },
        data: Data {
            body_force: None,
            body_stress: None,
            traction: Some(Arc::new(|x: &[f64; D], _t: f64, _n: &[f64; D]| {
                top_traction(x)
            })),
            contact_traction: None,
            damage_supply: None,
            damage_flux: None,
            gap: Arc::new(|_, _| GAP),
            dirichlet: Vec::new(),
            initial_displacement: Arc::new(initial_displacement::<D>),
            initial_damage: Arc::new(|_| 1.0),
            jump_planes: Vec::new(),
        },
        final_time: FINAL_TIME,
        steps: STEPS,
        settings: SchemeSettings::default(),
    }
}

/// Measures one size; returns the fields of its row.
fn measure<const D: usize>(cells: usize) -> contact_damage::Result<BTreeMap<String, String>> {
    let mut row = BTreeMap::new();
    let mut put = |key: &str, value: String| {
        row.insert(key.to_string(), value);
    };
    let time_step = FINAL_TIME / STEPS as f64;
    put(
        "load_start",
        load_average()
            .split_whitespace()
            .next()
            .unwrap_or("?")
            .to_string(),
    );

    // 1. mesh
    let start = Instant::now();
    let mesh = Arc::new(unit_box::<D>(cells)?);
    let mesh_time = seconds(start);
    progress(D, cells, "mesh", mesh_time);
    put("mesh_s", format!("{mesh_time:.4}"));
    put("cells", mesh.num_cells().to_string());

    // 2. standalone linear algebra
    {
        let start = Instant::now();
        let space = Arc::new(LagrangeSpace::new(mesh.clone(), 1)?);
        let contact = Arc::new(ContactNodes::new(&space)?);
        put("space_s", format!("{:.4}", seconds(start)));
        put("unknowns", (space.num_nodes() * D).to_string());
        put("contact_nodes", contact.len().to_string());

        let start = Instant::now();
        let viscosity: Arc<dyn Viscosity<D>> = Arc::new(VISCOSITY);
        let mut operator = VelocityOperator::new(space.clone(), viscosity, contact.clone())?;
        let build = seconds(start);
        progress(
            D,
            cells,
            "velocity operator (pattern + assembly + analysis)",
            build,
        );
        put("operator_new_s", format!("{build:.4}"));
        put("nnz", operator.nnz().to_string());

        let mut assembly = f64::INFINITY;
        let mut matrix = None;
        for _ in 0..3 {
            let start = Instant::now();
            let assembled = operator.assemble(None)?;
            assembly = assembly.min(seconds(start));
            matrix = Some(assembled);
        }
        let matrix = matrix.expect("three assemblies were done");
        progress(D, cells, "assembly (best of 3)", assembly);
        put("assembly_s", format!("{assembly:.4}"));

        let start = Instant::now();
        // the solver's own fill-reducing order (nested dissection in 3D, minimum degree in 2D)
        let graph = NodeGraph::from_cells(
            space.num_nodes(),
            (0..mesh.num_cells()).map(|c| space.cell_nodes(c)),
        );
        let ordering: Vec<usize> = fill_reducing_node_order(space.nodes(), &graph)?
            .into_iter()
            .flat_map(|node| (0..D).map(move |i| node * D + i))
            .collect();
        let mut solver = CholeskySolver::analyse_with_ordering(
            &matrix,
            &ordering,
            "benchmark: velocity operator",
        )?;
        let symbolic = seconds(start);
        progress(D, cells, "symbolic analysis", symbolic);
        put("symbolic_s", format!("{symbolic:.4}"));

        // load: the top traction, in the system frame of the operator
        let mut load = vec![0.0; space.num_nodes() * D];
        add_facet_integrals(
            &space,
            2,
            D,
            |f| mesh.facet_part(f) == BoundaryPart::Neumann,
            |x, _normal, out| out.copy_from_slice(&top_traction(x)),
            &mut load,
        );
        let rhs = operator.to_system(&load);
        let start = Instant::now();
        solver.factorize(&matrix)?;
        let factor = seconds(start);
        let start = Instant::now();
        let solution = solver.solve(&rhs)?;
        let solve = seconds(start);
        progress(D, cells, "numeric factorization", factor);
        progress(D, cells, "solve", solve);
        let residual: f64 = multiply(&matrix, &solution)
            .iter()
            .zip(&rhs)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            .sqrt()
            / rhs.iter().map(|b| b * b).sum::<f64>().sqrt();
        put("factor_s", format!("{factor:.4}"));
        put("solve_s", format!("{solve:.4}"));
        put("solve_residual", format!("{residual:.1e}"));
        drop(solver);
        drop(matrix);

        // velocity step with the contact data of u0: p_ν = c_ν (u0·ν − g)₊, s = μ p_ν
        let (pressure, bound): (Vec<f64>, Vec<f64>) = contact
            .nodes
            .iter()
            .enumerate()
            .map(|(k, &node)| {
                let u0 = initial_displacement(&space.node(node));
                let normal = contact.normal(k);
                let penetration: f64 = (0..D).map(|i| u0[i] * normal[i]).sum::<f64>() - GAP;
                use contact_damage::model::laws::ContactLaw;
                (
                    CONTACT.normal_pressure(penetration),
                    CONTACT.friction_bound(penetration),
                )
            })
            .unzip();
        let data = VelocityData {
            load: &load,
            normal_pressure: &pressure,
            friction_bound: &bound,
            implicit_contact: None,
            prescribed: None,
        };
        let settings = VelocitySettings::default();
        let zero = vec![0.0; load.len()];
        let start = Instant::now();
        let first = operator.solve(&data, &zero, &settings)?;
        let setup = seconds(start);
        progress(
            D,
            cells,
            "velocity step, first solve (factorization + Schur complement)",
            setup,
        );
        let start = Instant::now();
        let second = operator.solve(&data, &first.velocity, &settings)?;
        let velocity_solve = seconds(start);
        progress(D, cells, "velocity step, second solve", velocity_solve);
        put("velocity_setup_s", format!("{setup:.4}"));
        put("velocity_solve_s", format!("{velocity_solve:.4}"));
        put(
            "velocity_solve_factorizations",
            second.stats.factorizations.to_string(),
        );
        drop(operator);

        // damage step with the source φ(ε(u0), 1) = −½|ε(u0)|² (constant) times ∫φ_a
        let start = Instant::now();
        let mut damage = DamageOperator::new(
            space.clone(),
            DAMAGE_DIFFUSION,
            time_step,
            BoxQpSettings::default(),
        )?;
        put("damage_new_s", format!("{:.4}", seconds(start)));
        let mass = assemble_damage_matrix(&space, 1.0, 0.0)?;
        let lumped = multiply(&mass, &vec![1.0; space.num_nodes()]);
        let strain_energy = 0.5 * 0.5 * DISPLACEMENT_SLOPE * DISPLACEMENT_SLOPE; // ½|ε(u0)|²
        let source: Vec<f64> = lumped.iter().map(|m| -strain_energy * m).collect();
        let previous = vec![1.0; space.num_nodes()];
        let start = Instant::now();
        let solved = damage.solve(&source, &previous, &[])?;
        let damage_solve = seconds(start);
        progress(D, cells, "damage step (cold)", damage_solve);
        put("damage_solve_s", format!("{damage_solve:.4}"));
        put(
            "damage_solve_factorizations",
            solved.stats.factorizations.to_string(),
        );
    }
    if let Some(peak) = peak_memory_mib() {
        put("peak_standalone_mib", format!("{peak:.0}"));
    }
    let reset = reset_peak_memory();

    // 3. simulation
    let start = Instant::now();
    let mut simulation = Simulation::new(problem::<D>(mesh.clone()))?;
    let sim_new = seconds(start);
    progress(D, cells, "Simulation::new", sim_new);
    put("sim_new_s", format!("{sim_new:.4}"));
    let start = Instant::now();
    let first_velocity = simulation.step()?.velocity;
    let step1 = seconds(start);
    progress(D, cells, "step 1", step1);
    put("step1_s", format!("{step1:.4}"));
    put(
        "step1_factorizations",
        first_velocity.stats.factorizations.to_string(),
    );
    let start = Instant::now();
    let _ = simulation.step_loads(2.0 * time_step);
    let loads = seconds(start);
    put("loads_s", format!("{loads:.4}"));
    let start = Instant::now();
    let StepOutcome {
        velocity, damage, ..
    } = simulation.step()?;
    let step2 = seconds(start);
    progress(D, cells, "step 2", step2);
    put("step2_s", format!("{step2:.4}"));
    put("newton", velocity.stats.newton_iterations.to_string());
    put(
        "friction_iterations",
        velocity.stats.friction_iterations.to_string(),
    );
    put(
        "friction_gradient_iterations",
        velocity.stats.friction_gradient_iterations.to_string(),
    );
    put(
        "velocity_factorizations",
        velocity.stats.factorizations.to_string(),
    );
    put(
        "velocity_kkt",
        format!("{:.1e}", velocity.stats.kkt_residual),
    );
    put("damage_iterations", damage.stats.iterations.to_string());
    put(
        "damage_factorizations",
        damage.stats.factorizations.to_string(),
    );
    put("damage_kkt", format!("{:.1e}", damage.stats.kkt_residual));
    let count = |status: ContactStatus| velocity.status.iter().filter(|s| **s == status).count();
    put("separated", count(ContactStatus::Separated).to_string());
    put("stick", count(ContactStatus::Stick).to_string());
    put("slip", count(ContactStatus::Slip).to_string());
    let state = simulation.state();
    let beta_min = state.damage.iter().copied().fold(f64::INFINITY, f64::min);
    put("beta_min", format!("{beta_min:.6}"));
    put("beta_lower_active", damage.stats.lower_active.to_string());
    put("beta_upper_active", damage.stats.upper_active.to_string());
    if let Some(peak) = peak_memory_mib() {
        put(
            if reset {
                "peak_simulation_mib"
            } else {
                "peak_total_mib"
            },
            format!("{peak:.0}"),
        );
    }
    Ok(row)
}

fn field(row: &BTreeMap<String, String>, key: &str) -> f64 {
    row.get(key)
        .and_then(|v| v.parse().ok())
        .unwrap_or(f64::NAN)
}

fn text<'a>(row: &'a BTreeMap<String, String>, key: &str) -> &'a str {
    row.get(key).map(String::as_str).unwrap_or("?")
}

fn fmt_count(value: f64) -> String {
    if value >= 1e6 {
        format!("{:.2} M", value / 1e6)
    } else if value >= 1e3 {
        format!("{:.1} k", value / 1e3)
    } else {
        format!("{value:.0}")
    }
}

type Outcome = ((usize, usize), Result<BTreeMap<String, String>, String>);

/// The markdown report.
fn render(command: &str, results: &[Outcome], timeout: Duration) -> String {
    let mut out = String::new();
    let threads = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    let _ = writeln!(out, "# Benchmark of the P1 solver\n");
    let _ = writeln!(out, "```text\n{command}\n```\n");
    let _ = writeln!(
        out,
        "Machine: {} × {threads} (nproc = {threads}), load average {} at the end; date {}.\n",
        cpu_model(),
        load_average(),
        utc_now()
    );
    let _ = writeln!(
        out,
        "Unit box, Kuhn mesh with N cells per side, P1; Γ1 = {{x = 0}}, Γ3 = {{y = 0}} (2D) / {{z = 0}} (3D). \
         Linear viscosity (η = {}, ζ = {}), damaged Hooke (μ = {}, λ = {}), normal compliance c_ν = {} with \
         Coulomb μ = {}, damage diffusion κ = {DAMAGE_DIFFUSION}, φ = 0.1(1 − β) − ½|ε|², gap g = {GAP}, \
         u0 = −{DISPLACEMENT_SLOPE} x e_D, top traction ({}, 0, −{}), β0 = 1, k = {}. Each size runs in its own \
         process (time limit {} s). Times in seconds, wall clock.\n",
        VISCOSITY.shear,
        VISCOSITY.bulk,
        ELASTICITY.shear_modulus,
        ELASTICITY.lame_lambda,
        CONTACT.stiffness,
        CONTACT.friction,
        TOP_TRACTION.0,
        TOP_TRACTION.1,
        FINAL_TIME / STEPS as f64,
        timeout.as_secs()
    );
    let _ = writeln!(
        out,
        "| case | cells | unknowns | nnz(H) | mesh | assembly | assembly cells/s | symbolic | factor + solve | velocity setup | full step (2nd) | peak RSS MiB |"
    );
    let _ = writeln!(
        out,
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    for ((dim, cells), result) in results {
        match result {
            Ok(row) => {
                let cells_count = field(row, "cells");
                let assembly = field(row, "assembly_s");
                let peak = field(row, "peak_standalone_mib")
                    .max(field(row, "peak_simulation_mib"))
                    .max(field(row, "peak_total_mib"));
                let _ = writeln!(
                    out,
                    "| {dim}D P1 N={cells} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.0} |",
                    fmt_count(cells_count),
                    fmt_count(field(row, "unknowns")),
                    fmt_count(field(row, "nnz")),
                    fmt_s(field(row, "mesh_s")),
                    fmt_s(assembly),
                    fmt_count(cells_count / assembly),
                    fmt_s(field(row, "symbolic_s")),
                    fmt_s(field(row, "factor_s") + field(row, "solve_s")),
                    fmt_s(field(row, "velocity_setup_s")),
                    fmt_s(field(row, "step2_s")),
                    peak
                );
            }
            Err(reason) => {
                let _ = writeln!(
                    out,
                    "| {dim}D P1 N={cells} | {reason} | | | | | | | | | | |"
                );
            }
        }
    }
    let _ = writeln!(out);
    let _ = writeln!(
        out,
        "Columns: *assembly* = `VelocityOperator::assemble` (element matrices, frame rotation at Γ3 nodes, \
         sum into the pattern; best of 3); *symbolic* = `CholeskySolver::analyse_with_ordering` of the assembled matrix with the solver's fill-reducing order; \
         *factor + solve* = `CholeskySolver::factorize` + one `solve`; *velocity setup* = first \
         `VelocityOperator::solve` (numeric factorization + Schur complement on the Γ3 tangential unknowns + \
         two solves + friction problem); *full step (2nd)* = the second `Simulation::step()` (load assembly, \
         velocity step (5.1) and damage step (5.2)) with contact active; *peak RSS* = VmHWM of the size's \
         process.\n"
    );
    let _ = writeln!(
        out,
        "| case | contact nodes sep/stick/slip | Newton | friction it. | damage it. (fact.) | min β | KKT (5.1) / (5.2) | loads | velocity solve | damage step (cold) | step 1 | `Simulation::new` | peak RSS MiB standalone / simulation | load avg at start |"
    );
    let _ = writeln!(
        out,
        "|---|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---|---:|"
    );
    for ((dim, cells), result) in results {
        let Ok(row) = result else {
            let _ = writeln!(
                out,
                "| {dim}D P1 N={cells} | failed | | | | | | | | | | | | |"
            );
            continue;
        };
        let _ = writeln!(
            out,
            "| {dim}D P1 N={cells} | {}/{}/{} | {} | {} | {} ({}) | {} | {} / {} | {} | {} | {} | {} | {} | {} / {} | {} |",
            text(row, "separated"),
            text(row, "stick"),
            text(row, "slip"),
            text(row, "newton"),
            text(row, "friction_iterations"),
            text(row, "damage_iterations"),
            text(row, "damage_factorizations"),
            text(row, "beta_min"),
            text(row, "velocity_kkt"),
            text(row, "damage_kkt"),
            fmt_s(field(row, "loads_s")),
            fmt_s(field(row, "velocity_solve_s")),
            fmt_s(field(row, "damage_solve_s")),
            fmt_s(field(row, "step1_s")),
            fmt_s(field(row, "sim_new_s")),
            text(row, "peak_standalone_mib"),
            row.get("peak_simulation_mib").map(String::as_str).unwrap_or("n/a"),
            text(row, "load_start"),
        );
    }
    let _ = writeln!(out);
    let _ = writeln!(
        out,
        "Second table: the step-2 counts and iterations (Newton of (5.1), semismooth Newton of the condensed \
         friction problem, active-set iterations and numeric factorizations of the damage box QP); *loads* = \
         `Simulation::step_loads` alone; *velocity solve* = a second `VelocityOperator::solve` with a cached \
         factorization (top-traction load, contact data of u0); *damage step (cold)* = `DamageOperator::solve` \
         from β = 1 including its numeric factorization; *standalone* peak covers the measurements of the first \
         table, *simulation* the peak during `Simulation::new` and two steps (VmHWM reset in between); \
         *load avg* = 1-minute load average of the machine when the size started (the machine has {threads} \
         cores and is shared: a load above {threads} means the timings include contention).\n"
    );
    let _ = writeln!(out, "## Targets\n");
    let lookup = |dim: usize, cells: usize| {
        results
            .iter()
            .find(|(case, _)| *case == (dim, cells))
            .map(|(_, r)| r)
    };
    let verdict = |dim: usize,
                   cells: usize,
                   key: &dyn Fn(&BTreeMap<String, String>) -> f64,
                   met: &dyn Fn(f64) -> bool,
                   unit: &str| {
        match lookup(dim, cells) {
            None => "not measured (size not run)".to_string(),
            Some(Err(reason)) => format!("not met: {reason}"),
            Some(Ok(row)) => {
                let value = key(row);
                format!(
                    "{} ({} {unit})",
                    if met(value) { "**met**" } else { "**not met**" },
                    fmt_s_or_count(value, unit)
                )
            }
        }
    };
    let assembly_rate =
        |row: &BTreeMap<String, String>| field(row, "cells") / field(row, "assembly_s");
    let factor_solve =
        |row: &BTreeMap<String, String>| field(row, "factor_s") + field(row, "solve_s");
    let step = |row: &BTreeMap<String, String>| field(row, "step2_s");
    for cells in [256, 512, 1024] {
        let _ = writeln!(
            out,
            "- Assembly of 2D P1 ≥ 2 M cells/s, N = {cells}: {}",
            verdict(2, cells, &assembly_rate, &|v| v >= 2e6, "cells/s")
        );
    }
    let _ = writeln!(
        out,
        "- Factorization + solve, 2D P1 at 0.5 M unknowns (N = 512) < 3 s: {}",
        verdict(2, 512, &factor_solve, &|v| v < 3.0, "s")
    );
    let _ = writeln!(
        out,
        "- Factorization + solve, 3D P1 at 0.1 M unknowns (N = 32) < 10 s: {}",
        verdict(3, 32, &factor_solve, &|v| v < 10.0, "s")
    );
    let _ = writeln!(
        out,
        "- Full 2D P1 step at 0.5 M unknowns (N = 512) after the first factorization < 1 s: {}",
        verdict(2, 512, &step, &|v| v < 1.0, "s")
    );
    out
}

fn fmt_s_or_count(value: f64, unit: &str) -> String {
    if unit == "s" {
        fmt_s(value)
    } else {
        fmt_count(value)
    }
}
