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

use crate::contact_line::ContactLine;
use crate::folder;
use crate::history::{
    history_header, truncate_history, DomainQuadrature, ForceCycle, HistoryRow, RunningSums,
    CYCLE_WINDOW_STEPS, HISTORY_FILE,
};
use crate::pictures::{
    contact_history_svg, damage_picture_file, damage_svg, picture_steps, pressure_steps,
    read_contact_history, truncate_contact_history, CONTACT_HISTORY_FILE, CONTACT_HISTORY_HEADER,
    CONTACT_HISTORY_PICTURE,
};
use crate::problem::ProblemSetup;
use crate::record::{record_step, StepRecord};
use crate::resume::resume;
pub use crate::resume::{read_saved_state, SavedState};
pub use crate::snapshot::{cell_stress, contact_file, solution_file};
use crate::snapshot::{save_step, SavedStep};
use contact_damage::fem::space::LagrangeSpace;
use contact_damage::io::vtk::VtuGrid;
use contact_damage::model::contact::ContactNodes;
use contact_damage::scheme::stability::StepLimit;
use contact_damage::scheme::{DamageEvolution, Simulation, State, StepOutcome};
use contact_input::output::write_atomic;
use contact_input::{FileKind, InputError};
use std::fs::{File, OpenOptions};
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
    let dir = output_folder(setup, options)?;
    check_memory(
        &setup.origin,
        contact_damage::algebra::memory::estimate(
            D,
            setup.problem.degree,
            setup.problem.mesh.num_vertices() as f64,
        ),
        options,
    )?;
    let mut simulation = Simulation::new(setup.problem.clone())
        .map_err(|error| setup.load_watch.explain(&setup.origin, error.into()))?;
    check_symmetry_planes(setup, &simulation)?;
    let (mut time_loop, mut progress) = StepLoop::prepare(setup, options, &mut simulation, dir)?;
    time_loop.print_start(&simulation)?;
    while simulation.state().step < time_loop.last_step {
        let outcome = simulation
            .step()
            .map_err(|error| setup.load_watch.explain(&setup.origin, error.into()))?;
        time_loop.after_step(&simulation, &outcome, &mut progress)?;
        if progress.interrupted {
            break;
        }
    }
    time_loop.finish(&simulation, progress)
}

/// A `[[displacement]]` declared a symmetry plane (`symmetry = true`) may fix only components
/// tangential to Γ3 where it meets Γ3, so that those nodes stay in the contact rule: one that
/// fixes the normal component of a node of Γ3 (a roller across Γ3, whose nodes would leave the
/// contact rule) is an error at its key, naming the node and the normal.
fn check_symmetry_planes<const D: usize>(
    setup: &ProblemSetup<D>,
    simulation: &Simulation<D>,
) -> Result<(), InputError> {
    let (contact, space) = (simulation.contact(), simulation.space());
    let declared = setup.file.displacement.iter().enumerate();
    for (i, _) in declared.filter(|(_, part)| part.symmetry) {
        let Some(part) = setup.problem.data.dirichlet.get(i) else {
            continue;
        };
        let on_part = |node: usize| {
            part.facets
                .iter()
                .any(|&f| space.facet_nodes(f).contains(&node))
        };
        if let Some((node, normal)) = contact.normal_fixed.iter().find(|(n, _)| on_part(*n)) {
            let point = space.node(*node);
            return Err(contact_input::FileKind::Problem.error(
                &setup.origin,
                &format!("displacement[{i}].symmetry"),
                format!(
                    "part `{}` is declared a symmetry plane, but at node {node} of Γ3 \
                     (x = {point:?}) the components it fixes are along Γ3's normal ν = {:?}, \
                     not tangential to Γ3: the node would leave the contact rule. A symmetry \
                     plane must cut Γ3 at a right angle; drop `symmetry = true` if the part is \
                     meant to prescribe the normal displacement",
                    part.name,
                    normal.as_slice()
                ),
            ));
        }
    }
    Ok(())
}

/// The output folder of a run (`--out`, or `output.dir` of the problem): a fresh run checks
/// that it may start there, before anything is computed or written (see [`crate::folder`]).
fn output_folder<const D: usize>(
    setup: &ProblemSetup<D>,
    options: &RunOptions,
) -> Result<PathBuf, InputError> {
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
    Ok(dir)
}

/// The output folder and the two files of a run appended at every step.
struct OutputFiles {
    /// The output folder.
    dir: PathBuf,
    /// Its `history.csv`.
    history: PathBuf,
    /// Its `contact_history.csv`.
    contact_history: PathBuf,
}

/// What a run gathers step by step, from its start (or the resumed step) to its outcome.
struct Progress {
    /// Steps saved so far (over all runs in the folder).
    saved_steps: Vec<usize>,
    /// The running sums of the history.
    sums: RunningSums,
    /// Largest KKT residuals of the steps done by this run.
    max_kkt: MaxKkt,
    /// The watch over a total normal force that cycles with period two.
    force_cycle: ForceCycle,
    /// The run is to stop after the step just done ([`RunOptions::interrupt`]).
    interrupted: bool,
}

/// Prepares the output folder before the first step. Resuming: the state of `state.json` is
/// set in `simulation`, the step limit checked, and both CSV files truncated to the resumed
/// step. Fresh: the step limit checked, the folder created (emptied of our files with
/// `--overwrite`), and both CSV files started with their headers.
fn prepare_folder<const D: usize>(
    setup: &ProblemSetup<D>,
    options: &RunOptions,
    simulation: &mut Simulation<D>,
    files: &OutputFiles,
    contact_line: &ContactLine,
) -> Result<(Progress, StepLimit), InputError> {
    let contact_nodes = simulation.contact().len();
    let steps = simulation.steps();
    let mut saved_steps = Vec::new();
    let mut sums = RunningSums::new(contact_nodes);
    let header = history_header(simulation.dirichlet_parts(), D);
    let step_limit;
    if options.resume {
        let resumed = resume(setup, simulation, &files.dir, contact_nodes)?;
        saved_steps = resumed.saved_steps;
        sums = resumed.sums;
        step_limit = check_step_limit(setup, simulation)?;
        truncate_history(&files.history, resumed.step, &header)?;
        let recorded: Vec<usize> = (1..=resumed.step)
            .filter(|&n| records_contact_history(n, setup.every, steps))
            .collect();
        truncate_contact_history(
            &files.contact_history,
            &recorded,
            contact_line.indices.len(),
        )?;
    } else {
        step_limit = check_step_limit(setup, simulation)?;
        let dir = &files.dir;
        std::fs::create_dir_all(dir).map_err(io_error("creating directory", dir))?;
        if options.overwrite {
            folder::remove_output(dir)?;
        }
        write_atomic(&files.history, format!("{header}\n").as_bytes())?;
        write_atomic(
            &files.contact_history,
            format!("{CONTACT_HISTORY_HEADER}\n").as_bytes(),
        )?;
    }
    let progress = Progress {
        saved_steps,
        sums,
        max_kkt: MaxKkt::default(),
        force_cycle: ForceCycle::default(),
        interrupted: false,
    };
    Ok((progress, step_limit))
}

/// Opens `path` for appending.
fn open_append(path: &Path) -> Result<File, InputError> {
    OpenOptions::new()
        .append(true)
        .open(path)
        .map_err(io_error("opening", path))
}

/// The time loop of a run: what its steps share, fixed before the first one.
struct StepLoop<'a, const D: usize> {
    setup: &'a ProblemSetup<D>,
    options: &'a RunOptions,
    files: OutputFiles,
    space: Arc<LagrangeSpace<D>>,
    contact: Arc<ContactNodes<D>>,
    /// N.
    steps: usize,
    /// The contact nodes of `contact_history.csv`.
    contact_line: ContactLine,
    /// The steps of the damage pictures.
    pictures: Vec<usize>,
    step_limit: StepLimit,
    /// The step the run starts after (0, or the resumed step).
    started_from: usize,
    /// `history.csv`, open for appending.
    history: File,
    /// `contact_history.csv`, open for appending.
    contact_history: File,
    /// The cell rule of the Ω integrals of the history.
    quadrature: DomainQuadrature<D>,
    grid: VtuGrid,
    /// The last step of this run (`--until-step`, or N).
    last_step: usize,
    damage_evolves: bool,
    /// Started before the first step.
    clock: Instant,
}

impl<'a, const D: usize> StepLoop<'a, D> {
    /// Sets up the run of `simulation` in the folder `dir`: the output folder prepared
    /// ([`prepare_folder`]), the CSV files opened for appending, and what the steps share.
    fn prepare(
        setup: &'a ProblemSetup<D>,
        options: &'a RunOptions,
        simulation: &mut Simulation<D>,
        dir: PathBuf,
    ) -> Result<(Self, Progress), InputError> {
        let space = simulation.space().clone();
        let contact = simulation.contact().clone();
        let steps = simulation.steps();
        let files = OutputFiles {
            history: dir.join(HISTORY_FILE),
            contact_history: dir.join(CONTACT_HISTORY_FILE),
            dir,
        };
        let contact_line = match &setup.profile {
            None => ContactLine::new(&space, &contact),
            Some(segment) => ContactLine::along(&space, &contact, segment).map_err(|message| {
                FileKind::Problem.error(&setup.origin, "output.profile", message)
            })?,
        };
        let pictures = picture_steps(&setup.pictures, simulation.time_step(), steps);
        let (progress, step_limit) =
            prepare_folder(setup, options, simulation, &files, &contact_line)?;
        let started_from = simulation.state().step;
        let history = open_append(&files.history)?;
        let contact_history = open_append(&files.contact_history)?;
        let quadrature = DomainQuadrature::new(&space, 2 * space.degree());
        let grid = VtuGrid::new(&space, setup.vtu)?;
        let last_step = options.until_step.unwrap_or(steps).min(steps);
        let clock = Instant::now();
        let damage_evolves = setup.problem.settings.damage_evolution == DamageEvolution::Parabolic;
        let time_loop = Self {
            setup,
            options,
            files,
            space,
            contact,
            steps,
            contact_line,
            pictures,
            step_limit,
            started_from,
            history,
            contact_history,
            quadrature,
            grid,
            last_step,
            damage_evolves,
            clock,
        };
        Ok((time_loop, progress))
    }

    /// The first progress line: the problem, its size, N, k and the stability limit.
    fn print_start(&self, simulation: &Simulation<D>) -> Result<(), InputError> {
        if self.options.quiet {
            return Ok(());
        }
        let (space, steps, started_from) = (&self.space, self.steps, self.started_from);
        contact_input::outln!(
            "{}: d = {D}, l = {}, {} cells, {} nodes, {} contact nodes, N = {steps}, k = {:e} (stability limit {:.3e}){}",
            self.setup.name,
            space.degree(),
            space.mesh().num_cells(),
            space.num_nodes(),
            self.contact.len(),
            simulation.time_step(),
            self.step_limit.time_step,
            if started_from > 0 {
                format!(", resuming after step {started_from}")
            } else {
                String::new()
            }
        )?;
        if let Some((node, _)) = self.contact.normal_fixed.first() {
            contact_input::outln!(
                "note: {} node(s) of Γ3 have a prescribed displacement along Γ3's normal and take no part in the contact rule (the first at x = {:?}); a part meant as a symmetry plane takes `symmetry = true`",
                self.contact.normal_fixed.len(),
                space.node(*node)
            )?;
        }
        Ok(())
    }

    /// What follows the step just done by `simulation` with `outcome`: its row of
    /// `history.csv`, the cycle check of the normal force, the damage picture, the rows of
    /// `contact_history.csv`, and the saved step (every `output.every` steps, at the last step,
    /// and when interrupted).
    fn after_step(
        &mut self,
        simulation: &Simulation<D>,
        outcome: &StepOutcome,
        progress: &mut Progress,
    ) -> Result<(), InputError> {
        let StepRecord { row, speed } = record_step(
            self.setup,
            simulation,
            outcome,
            &self.quadrature,
            &self.contact_line.coordinate,
            &mut progress.sums,
        );
        let StepOutcome {
            velocity,
            damage,
            normal_pressure,
            friction_bound,
        } = outcome;
        let state = simulation.state();
        let n = state.step;
        progress.max_kkt.velocity = progress.max_kkt.velocity.max(velocity.stats.kkt_residual);
        progress.max_kkt.damage = progress.max_kkt.damage.max(damage.stats.kkt_residual);
        if let Some((low, high)) = progress.force_cycle.push(row.normal_force) {
            return Err(self.force_cycle_error(low, high, n, simulation.time_step()));
        }
        let history_path = &self.files.history;
        self.history
            .write_all(row.csv_line().as_bytes())
            .and_then(|()| self.history.flush())
            .map_err(io_error("appending to", history_path))?;
        if self.damage_evolves && self.pictures.contains(&n) {
            damage_svg(
                &self.files.dir.join(damage_picture_file(n)),
                &self.space,
                &state.damage,
                n,
                state.time,
            )?;
        }

        if records_contact_history(n, self.setup.every, self.steps) {
            let rows = self.contact_line.csv_rows(
                n,
                state.time,
                &velocity.status,
                normal_pressure,
                &speed,
                &progress.sums.accumulated_slip,
            );
            let contact_history_path = &self.files.contact_history;
            self.contact_history
                .write_all(rows.as_bytes())
                .and_then(|()| self.contact_history.flush())
                .map_err(io_error("appending to", contact_history_path))?;
        }
        progress.interrupted = self
            .options
            .interrupt
            .as_ref()
            .is_some_and(|flag| flag.load(Ordering::SeqCst));
        if n % self.setup.every == 0
            || n == self.steps
            || n == self.last_step
            || progress.interrupted
        {
            save_step(
                &self.files.dir,
                &SavedStep {
                    setup: self.setup,
                    space: &self.space,
                    grid: &self.grid,
                    contact: &self.contact,
                    state,
                    velocity,
                    normal_pressure,
                    friction_bound,
                    sums: &progress.sums,
                    steps: self.steps,
                    time_step: simulation.time_step(),
                },
                &mut progress.saved_steps,
            )?;
            self.print_saved_step(state, &row)?;
        }
        if progress.interrupted && !self.options.quiet {
            contact_input::outln!("interrupted: step {n} is saved; continue with --resume")?;
        }
        Ok(())
    }

    /// The error of a total normal contact force that cycles between `low` and `high` up to
    /// step n: the step k is above the stability limit for the contact state reached.
    fn force_cycle_error(&self, low: f64, high: f64, n: usize, time_step: f64) -> InputError {
        InputError::InvalidInput(format!(
            "{}: the total normal contact force cycles with period two between {low:.6e} and {high:.6e} over steps {}..={n}, although every step is solved exactly: the step k = {:e} is above the stability limit of the explicit normal compliance for the contact state reached (the estimate at the start was {:.3e}); raise `steps` or use `[scheme] contact = \"implicit\"`",
            self.setup.origin,
            n + 1 - CYCLE_WINDOW_STEPS,
            time_step,
            self.step_limit.time_step,
        ))
    }

    /// The progress line of a saved step: its iterations, KKT residuals, contact status and
    /// mean damage, and the time taken and left.
    fn print_saved_step(&self, state: &State, row: &HistoryRow) -> Result<(), InputError> {
        if self.options.quiet {
            return Ok(());
        }
        let (n, steps) = (state.step, self.steps);
        let elapsed = self.clock.elapsed().as_secs_f64();
        let done = n - self.started_from;
        let left = elapsed / done as f64 * (self.last_step - n) as f64;
        contact_input::outln!(
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
        )?;
        Ok(())
    }

    /// Ends the run: both CSV files synced, `contact_history.svg` drawn from the whole contact
    /// history, and the outcome.
    fn finish(
        self,
        simulation: &Simulation<D>,
        progress: Progress,
    ) -> Result<RunOutcome, InputError> {
        let files = &self.files;
        self.history
            .sync_all()
            .map_err(io_error("syncing", &files.history))?;
        self.contact_history
            .sync_all()
            .map_err(io_error("syncing", &files.contact_history))?;
        let records = read_contact_history(&files.contact_history)?;
        if !records.is_empty() {
            contact_history_svg(
                &files.dir.join(CONTACT_HISTORY_PICTURE),
                &records,
                &self.contact_line.description,
                &pressure_steps(&records, &self.pictures),
            )?;
        }
        Ok(RunOutcome {
            output_dir: self.files.dir,
            started_from: self.started_from,
            last_step: simulation.state().step,
            saved_steps: progress.saved_steps,
            max_kkt: progress.max_kkt,
            seconds: self.clock.elapsed().as_secs_f64(),
            interrupted: progress.interrupted,
        })
    }
}
