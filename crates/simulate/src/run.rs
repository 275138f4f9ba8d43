//! Running a problem: the time loop of the scheme (5.1)–(5.5) with output after each step.
//!
//! Files in the output folder:
//! - `solution_NNNNNN.vtu` per saved step: point fields `displacement` u_n, `velocity` v_n,
//!   `damage` β_n; cell field `stress` σ = 𝒜ε(v_n) + G(ε(u_n), β_n) (2.1) at the cell centroid;
//! - `contact_NNNNNN.vtu` per saved step, on Γ3: `status` (0 separated, 1 stick, 2 slip; nodes
//!   of Γ3 that are no contact node — clamped or of zero weight — get 0), `contact_node`
//!   (1 on contact nodes), `normal_pressure` p_ν(u_{n−1,ν} − g) and `tangential_traction`
//!   −p_τ λ (Cartesian) as used in step n;
//! - `solution.pvd`, `contact.pvd`: the time series (rewritten atomically at each saved step);
//! - `history.csv`: one row per step, appended and flushed after each step;
//! - `state.json`: the state of the last saved step (written atomically, last), for `--resume`;
//! - `damage_NNNNNN.svg` at the steps nearest the picture times, `contact_history.csv` (one
//!   row per contact node of the line drawn, every `output.every` steps and at the last step,
//!   appended like `history.csv`) and
//!   `contact_history.svg`, drawn from it at the end of every run: see [`crate::pictures`].
//!
//! A crash therefore leaves every completed saved step on disk; resuming truncates
//! `history.csv` to the resumed step and continues bitwise as the uninterrupted run would.
//! An interruption through [`RunOptions::interrupt`] (Ctrl-C in `simulate`) ends the run
//! after the step in progress and saves that step, so nothing computed is lost. `--resume`
//! refuses a state whose problem changed since ([`ProblemSetup::fingerprint`]). What a fresh
//! run, `--overwrite` and `--resume` may do with the files already in the folder (only the
//! names above are ours) is in [`crate::folder`].

use crate::folder;
use crate::history::{
    history_header, truncate_history, DomainQuadrature, ForceCycle, RunningSums,
    CYCLE_WINDOW_STEPS, HISTORY_FILE,
};
use crate::pictures::{
    contact_history_svg, damage_picture_file, damage_svg, picture_steps, pressure_steps,
    read_contact_history, truncate_contact_history, ContactLine, CONTACT_HISTORY_FILE,
    CONTACT_HISTORY_HEADER, CONTACT_HISTORY_PICTURE,
};
use crate::problem::ProblemSetup;
use crate::record::{record_step, StepRecord};
use crate::resume::resume;
pub use crate::resume::{read_saved_state, SavedState};
pub use crate::snapshot::{cell_stress, contact_file, solution_file};
use crate::snapshot::{save_step, SavedStep};
use contact_damage::io::vtk::VtuGrid;
use contact_damage::scheme::stability::StepLimit;
use contact_damage::scheme::{DamageEvolution, Simulation, StepOutcome};
use contact_input::output::write_atomic;
use contact_input::InputError;
use std::fs::OpenOptions;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

/// Command-line options of a run.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Output folder (overrides `output.dir`).
    pub out: Option<PathBuf>,
    /// Continue from `state.json` in the output folder.
    pub resume: bool,
    /// Start afresh even if the output folder holds a run.
    pub overwrite: bool,
    /// Stop after this step (it is saved), as if interrupted; `--resume` continues.
    pub until_step: Option<usize>,
    /// No progress lines.
    pub quiet: bool,
    /// Set from outside (the Ctrl-C handler of `simulate`) to stop the run after the step in
    /// progress: that step is saved like a saved step, so `--resume` continues from it.
    pub interrupt: Option<Arc<AtomicBool>>,
    /// Largest estimated memory a run may need, in bytes (`--memory-limit`; default: the
    /// physical memory, see [`contact_damage::algebra::memory`]).
    pub memory_limit: Option<f64>,
}

impl RunOptions {
    /// The memory limit in bytes.
    pub fn memory_limit(&self) -> f64 {
        self.memory_limit
            .unwrap_or_else(contact_damage::algebra::memory::default_limit)
    }
}

/// Refuses a problem whose estimated memory exceeds the limit, before the solver allocates.
pub fn check_memory(
    origin: &str,
    estimate: contact_damage::algebra::memory::MemoryEstimate,
    options: &RunOptions,
) -> Result<(), InputError> {
    contact_damage::algebra::memory::check(
        estimate,
        options.memory_limit(),
        &format!("the problem of {origin}"),
        "--memory-limit",
    )
    .map_err(InputError::from)
}

/// Largest KKT residuals of the velocity steps (5.1) and damage steps (5.2) of a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct MaxKkt {
    /// Of the velocity steps (5.1).
    pub velocity: f64,
    /// Of the damage steps (5.2).
    pub damage: f64,
}

/// What a run did.
#[derive(Debug, Clone)]
pub struct RunOutcome {
    /// The output folder.
    pub output_dir: PathBuf,
    /// First step computed by this run minus one (0, or the resumed step).
    pub started_from: usize,
    /// Last step done.
    pub last_step: usize,
    /// Steps saved so far (over all runs in this folder).
    pub saved_steps: Vec<usize>,
    /// Largest KKT residuals of the steps done by this run.
    pub max_kkt: MaxKkt,
    /// Wall time of the time loop in seconds.
    pub seconds: f64,
    /// The run stopped early because [`RunOptions::interrupt`] was set.
    pub interrupted: bool,
}

fn io_error(action: &'static str, path: &Path) -> impl FnOnce(std::io::Error) -> InputError {
    let path = path.to_path_buf();
    move |e| InputError::io(action, path, e)
}

/// Whether step n has rows in `contact_history.csv`: every `output.every` steps and the last
/// step N — not the extra steps saved by an interruption or `--until-step`, so that a resumed
/// run writes the file of an uninterrupted one.
fn records_contact_history(n: usize, every: usize, steps: usize) -> bool {
    n % every == 0 || n == steps
}

/// Refuses a time step above the stability limit of the explicit terms of (5.1)
/// ([`contact_damage::scheme::stability`]): such a run would not fail, it would produce a displacement
/// that grows without bound or a contact force that cycles, with every step exact.
fn check_step_limit<const D: usize>(
    setup: &ProblemSetup<D>,
    simulation: &mut Simulation<D>,
) -> Result<StepLimit, InputError> {
    let limit = simulation.step_limit()?;
    let step = simulation.time_step();
    if step <= limit.time_step {
        return Ok(limit);
    }
    let final_time = setup.problem.final_time;
    let needed = contact_input::number::short((final_time / limit.time_step).ceil());
    let (terms, remedy) = if limit.includes_contact {
        (
            "the elastic stress and the normal compliance p_ν",
            format!(
                "raise `steps` to at least {needed}, or take the normal compliance implicitly with `[scheme] contact = \"implicit\"` (then only the elastic limit applies)"
            ),
        )
    } else {
        (
            "the elastic stress",
            format!("raise `steps` to at least {needed} (or the viscosity against the elasticity)"),
        )
    };
    Err(InputError::InvalidInput(format!(
        "{}: the time step k = final_time/steps = {}/{} = {step:e} exceeds the stability limit k_max = {:.3e} of the explicit terms of (5.1) ({terms} at u_(n−1); λ_max(H⁻¹B) = {:.3e} by {} Lanczos iterations): the run would oscillate or blow up; {remedy}",
        setup.origin,
        contact_input::number::short(final_time),
        simulation.steps(),
        limit.time_step,
        limit.largest_rate,
        limit.iterations,
    )))
}

/// Runs the problem of `setup` with `options`; see the module documentation for the files.
pub fn run<const D: usize>(
    setup: &ProblemSetup<D>,
    options: &RunOptions,
) -> Result<RunOutcome, InputError> {
    let dir = options
        .out
        .clone()
        .unwrap_or_else(|| setup.output_dir.clone());
    let what = if options.out.is_some() {
        "--out".to_string()
    } else {
        format!("output.dir of {}, or its default", setup.origin)
    };
    if !options.resume {
        // before anything is computed or written (see crate::folder)
        folder::check_fresh(&dir, &what, options.overwrite)?;
    }
    check_memory(
        &setup.origin,
        contact_damage::algebra::memory::estimate(
            D,
            setup.problem.degree,
            setup.problem.mesh.num_vertices() as f64,
        ),
        options,
    )?;
    let mut simulation = Simulation::new(setup.problem.clone())?;
    let space = simulation.space().clone();
    let contact = simulation.contact().clone();
    let steps = simulation.steps();
    let history_path = dir.join(HISTORY_FILE);
    let contact_history_path = dir.join(CONTACT_HISTORY_FILE);
    let contact_line = ContactLine::new(&space, &contact);
    let pictures = picture_steps(&setup.pictures, simulation.time_step(), steps);

    let mut saved_steps = Vec::new();
    let mut sums = RunningSums::new(contact.len());
    let header = history_header(simulation.dirichlet_parts(), D);
    let step_limit;
    if options.resume {
        let resumed = resume(setup, &mut simulation, &dir, contact.len())?;
        saved_steps = resumed.saved_steps;
        sums = resumed.sums;
        step_limit = check_step_limit(setup, &mut simulation)?;
        truncate_history(&history_path, resumed.step, &header)?;
        let recorded: Vec<usize> = (1..=resumed.step)
            .filter(|&n| records_contact_history(n, setup.every, steps))
            .collect();
        truncate_contact_history(&contact_history_path, &recorded, contact_line.indices.len())?;
    } else {
        step_limit = check_step_limit(setup, &mut simulation)?;
        std::fs::create_dir_all(&dir).map_err(io_error("creating directory", &dir))?;
        if options.overwrite {
            folder::remove_output(&dir)?;
        }
        write_atomic(&history_path, format!("{header}\n").as_bytes())?;
        write_atomic(
            &contact_history_path,
            format!("{CONTACT_HISTORY_HEADER}\n").as_bytes(),
        )?;
    }
    let started_from = simulation.state().step;
    let mut history = OpenOptions::new()
        .append(true)
        .open(&history_path)
        .map_err(io_error("opening", &history_path))?;
    let mut contact_history = OpenOptions::new()
        .append(true)
        .open(&contact_history_path)
        .map_err(io_error("opening", &contact_history_path))?;

    let quadrature = DomainQuadrature::new(&space, 2 * space.degree());
    let grid = VtuGrid::new(&space, setup.vtu)?;
    let last_step = options.until_step.unwrap_or(steps).min(steps);
    let clock = Instant::now();
    let mut max_kkt = MaxKkt::default();
    let mut force_cycle = ForceCycle::default();
    let damage_evolves = setup.problem.settings.damage_evolution == DamageEvolution::Parabolic;
    let mut interrupted = false;
    if !options.quiet {
        println!(
            "{}: d = {D}, l = {}, {} cells, {} nodes, {} contact nodes, N = {steps}, k = {:e} (stability limit {:.3e}){}",
            setup.name,
            space.degree(),
            space.mesh().num_cells(),
            space.num_nodes(),
            contact.len(),
            simulation.time_step(),
            step_limit.time_step,
            if started_from > 0 {
                format!(", resuming after step {started_from}")
            } else {
                String::new()
            }
        );
    }
    while simulation.state().step < last_step {
        let outcome = simulation
            .step()
            .map_err(|error| setup.load_watch.explain(&setup.origin, error.into()))?;
        let StepRecord { row, speed } = record_step(
            setup,
            &simulation,
            &outcome,
            &quadrature,
            contact_line.axis,
            &mut sums,
        );
        let StepOutcome {
            velocity,
            damage,
            normal_pressure,
            friction_bound,
        } = &outcome;
        let state = simulation.state();
        let n = state.step;
        max_kkt.velocity = max_kkt.velocity.max(velocity.stats.kkt_residual);
        max_kkt.damage = max_kkt.damage.max(damage.stats.kkt_residual);
        if let Some((low, high)) = force_cycle.push(row.normal_force) {
            return Err(InputError::InvalidInput(format!(
                "{}: the total normal contact force cycles with period two between {low:.6e} and {high:.6e} over steps {}..={n}, although every step is solved exactly: the step k = {:e} is above the stability limit of the explicit normal compliance for the contact state reached (the estimate at the start was {:.3e}); raise `steps` or use `[scheme] contact = \"implicit\"`",
                setup.origin,
                n + 1 - CYCLE_WINDOW_STEPS,
                simulation.time_step(),
                step_limit.time_step,
            )));
        }
        history
            .write_all(row.csv_line().as_bytes())
            .and_then(|()| history.flush())
            .map_err(io_error("appending to", &history_path))?;
        if damage_evolves && pictures.contains(&n) {
            damage_svg(
                &dir.join(damage_picture_file(n)),
                &space,
                &state.damage,
                n,
                state.time,
            )?;
        }

        if records_contact_history(n, setup.every, steps) {
            contact_history
                .write_all(
                    contact_line
                        .csv_rows(
                            n,
                            state.time,
                            &velocity.status,
                            normal_pressure,
                            &speed,
                            &sums.accumulated_slip,
                        )
                        .as_bytes(),
                )
                .and_then(|()| contact_history.flush())
                .map_err(io_error("appending to", &contact_history_path))?;
        }
        interrupted = options
            .interrupt
            .as_ref()
            .is_some_and(|flag| flag.load(Ordering::SeqCst));
        if n % setup.every == 0 || n == steps || n == last_step || interrupted {
            save_step(
                &dir,
                &SavedStep {
                    setup,
                    space: &space,
                    grid: &grid,
                    contact: &contact,
                    state,
                    velocity,
                    normal_pressure,
                    friction_bound,
                    sums: &sums,
                    steps,
                    time_step: simulation.time_step(),
                },
                &mut saved_steps,
            )?;
            if !options.quiet {
                let elapsed = clock.elapsed().as_secs_f64();
                let done = n - started_from;
                let left = elapsed / done as f64 * (last_step - n) as f64;
                println!(
                    "step {n:>6}/{steps}  t = {:<10.4e} Newton {:>2}  friction {:>3}  damage {:>3}  KKT {:.1e}/{:.1e}  contact {}/{}/{} (sep/stick/slip)  β̄ = {:.4}  {elapsed:.1} s, ≈ {left:.1} s left",
                    state.time,
                    row.newton_iterations,
                    row.friction_iterations,
                    row.damage_iterations,
                    row.velocity_kkt,
                    row.damage_kkt,
                    row.separated,
                    row.stick,
                    row.slip,
                    row.mean_damage,
                );
            }
        }
        if interrupted {
            if !options.quiet {
                println!("interrupted: step {n} is saved; continue with --resume",);
            }
            break;
        }
    }
    history
        .sync_all()
        .map_err(io_error("syncing", &history_path))?;
    contact_history
        .sync_all()
        .map_err(io_error("syncing", &contact_history_path))?;
    let records = read_contact_history(&contact_history_path)?;
    if !records.is_empty() {
        contact_history_svg(
            &dir.join(CONTACT_HISTORY_PICTURE),
            &records,
            &contact_line.description,
            &pressure_steps(&records, &pictures),
        )?;
    }
    Ok(RunOutcome {
        output_dir: dir,
        started_from,
        last_step: simulation.state().step,
        saved_steps,
        max_kkt,
        seconds: clock.elapsed().as_secs_f64(),
        interrupted,
    })
}
