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
    contact_integrals, damage_integrals, history_header, tangential_speed, truncate_history,
    viscous_power, ContactStep, ForceCycle, HistoryRow, RunningSums, CYCLE_WINDOW_STEPS,
    HISTORY_FILE,
};
use crate::pictures::{
    contact_history_svg, damage_picture_file, damage_svg, picture_steps, pressure_steps,
    read_contact_history, truncate_contact_history, ContactLine, CONTACT_HISTORY_FILE,
    CONTACT_HISTORY_HEADER, CONTACT_HISTORY_PICTURE,
};
use crate::problem::ProblemSetup;
use crate::zone::{boundary_penetration, contact_force, contact_zone};
use contact_damage::contact::ContactStatus;
use contact_damage::laws::Tensor;
use contact_damage::mesh::BoundaryPart;
use contact_damage::quadrature::QuadratureRule;
use contact_damage::scheme::{ContactTreatment, DamageEvolution, Simulation, State};
use contact_damage::space::{strain, LagrangeSpace, Tabulation};
use contact_damage::stability::StepLimit;
use contact_damage::vtk::{write_boundary_vtu, write_pvd, write_vtu, CellData, PointData};
use contact_input::output::{write_atomic, write_json_atomic};
use contact_input::InputError;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fs::OpenOptions;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

/// Name of the restart file.
pub const STATE_FILE: &str = "state.json";

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
    /// physical memory, see [`contact_damage::memory`]).
    pub memory_limit: Option<f64>,
}

impl RunOptions {
    /// The memory limit in bytes.
    pub fn memory_limit(&self) -> f64 {
        self.memory_limit
            .unwrap_or_else(contact_damage::memory::default_limit)
    }
}

/// Refuses a problem whose estimated memory exceeds the limit, before the solver allocates.
pub fn check_memory(
    origin: &str,
    estimate: contact_damage::memory::MemoryEstimate,
    options: &RunOptions,
) -> Result<(), InputError> {
    contact_damage::memory::check(
        estimate,
        options.memory_limit(),
        &format!("the problem of {origin}"),
        "--memory-limit",
    )
    .map_err(InputError::from)
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
    /// Largest velocity and damage KKT residuals of the steps done by this run.
    pub max_kkt: [f64; 2],
    /// Wall time of the time loop in seconds.
    pub seconds: f64,
    /// The run stopped early because [`RunOptions::interrupt`] was set.
    pub interrupted: bool,
}

/// The restart file: the state after a saved step and what it belongs to.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SavedState {
    /// Problem name.
    pub name: String,
    /// d.
    pub dim: usize,
    /// l.
    pub degree: usize,
    /// N.
    pub steps: usize,
    /// T.
    pub final_time: f64,
    /// Number of space nodes.
    pub nodes: usize,
    /// Steps saved so far (the PVD entries).
    pub saved_steps: Vec<usize>,
    /// n.
    pub step: usize,
    /// t_n.
    pub time: f64,
    /// u_n, node-major.
    pub displacement: Vec<f64>,
    /// v_n, node-major.
    pub velocity: Vec<f64>,
    /// β_n.
    pub damage: Vec<f64>,
    /// Σ_{m ≤ n} k |v_{m,τ}(a)| per contact node (see [`crate::history`]).
    pub accumulated_slip: Vec<f64>,
    /// Σ_{m ≤ n} k j(u_{m−1}, v_m).
    pub friction_dissipation: f64,
    /// Σ_{m ≤ n} k ∫_Ω 𝒜ε(v_m)·ε(v_m).
    pub viscous_dissipation: f64,
    /// [`ProblemSetup::fingerprint`] of the problem that was run.
    pub fingerprint: BTreeMap<String, String>,
}

/// File name of the domain VTU of step n.
pub fn solution_file(step: usize) -> String {
    format!("solution_{step:06}.vtu")
}

/// File name of the Γ3 VTU of step n.
pub fn contact_file(step: usize) -> String {
    format!("contact_{step:06}.vtu")
}

/// Cell stress σ = 𝒜ε(v) + G(ε(u), β) (2.1) at the centroid of every cell, row-major D×D.
pub fn cell_stress<const D: usize>(
    setup: &ProblemSetup<D>,
    space: &LagrangeSpace<D>,
    state: &State,
) -> Vec<f64> {
    let model = &setup.problem.model;
    let centroid = [1.0 / (D as f64 + 1.0); D];
    let cells = space.mesh().num_cells();
    let mut stress = Vec::with_capacity(cells * D * D);
    for c in 0..cells {
        let (_, velocity_gradient) = space.eval_vector(c, &centroid, &state.velocity);
        let (_, displacement_gradient) = space.eval_vector(c, &centroid, &state.displacement);
        let (damage, _) = space.eval_scalar(c, &centroid, &state.damage);
        let sigma: Tensor<D> = model.viscosity.stress(&strain(&velocity_gradient))
            + model
                .elasticity
                .stress(&strain(&displacement_gradient), damage);
        for i in 0..D {
            for j in 0..D {
                stress.push(sigma[(i, j)]);
            }
        }
    }
    stress
}

fn io_error(action: &'static str, path: &Path) -> impl FnOnce(std::io::Error) -> InputError {
    let path = path.to_path_buf();
    move |e| InputError::io(action, path, e)
}

/// Checks the values of a saved state as strictly as an input file: fields of the right
/// lengths, finite, β_n ∈ [0, 1] (the scheme's 𝒦^h), nonnegative running sums and slips, and
/// saved steps strictly increasing. The error names the file, the field and the first bad entry.
fn check_saved_values<const D: usize>(saved: &SavedState, path: &Path) -> Result<(), InputError> {
    let bad = |field: &str, detail: String| {
        InputError::InvalidInput(format!("{}: `{field}` {detail}", path.display()))
    };
    for (field, values, length) in [
        ("displacement", &saved.displacement, saved.nodes * D),
        ("velocity", &saved.velocity, saved.nodes * D),
        ("damage", &saved.damage, saved.nodes),
    ] {
        if values.len() != length {
            return Err(bad(
                field,
                format!("has {} values, expected {length}", values.len()),
            ));
        }
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(bad(field, format!("[{i}] = {} is not finite", values[i])));
        }
    }
    if let Some(i) = saved.damage.iter().position(|b| !(0.0..=1.0).contains(b)) {
        return Err(bad(
            "damage",
            format!("[{i}] = {} lies outside [0, 1]", saved.damage[i]),
        ));
    }
    if let Some(i) = saved
        .accumulated_slip
        .iter()
        .position(|s| !(s.is_finite() && *s >= 0.0))
    {
        return Err(bad(
            "accumulated_slip",
            format!(
                "[{i}] = {} must be finite and ≥ 0",
                saved.accumulated_slip[i]
            ),
        ));
    }
    for (field, value) in [
        ("friction_dissipation", saved.friction_dissipation),
        ("viscous_dissipation", saved.viscous_dissipation),
    ] {
        if !(value.is_finite() && value >= 0.0) {
            return Err(bad(field, format!("= {value} must be finite and ≥ 0")));
        }
    }
    if let Some(i) = saved.saved_steps.windows(2).position(|w| w[0] >= w[1]) {
        return Err(bad(
            "saved_steps",
            format!(
                "must increase strictly: {} then {}",
                saved.saved_steps[i],
                saved.saved_steps[i + 1]
            ),
        ));
    }
    Ok(())
}

/// Reads `state.json` of a folder.
pub fn read_saved_state(dir: &Path) -> Result<SavedState, InputError> {
    let path = dir.join(STATE_FILE);
    let text = std::fs::read_to_string(&path).map_err(io_error("reading saved state", &path))?;
    serde_json::from_str(&text)
        .map_err(|e| InputError::InvalidInput(format!("{}: {e}", path.display())))
}

/// Whether step n has rows in `contact_history.csv`: every `output.every` steps and the last
/// step N — not the extra steps saved by an interruption or `--until-step`, so that a resumed
/// run writes the file of an uninterrupted one.
fn records_contact_history(n: usize, every: usize, steps: usize) -> bool {
    n % every == 0 || n == steps
}

/// Refuses a time step above the stability limit of the explicit terms of (5.1)
/// ([`contact_damage::stability`]): such a run would not fail, it would produce a displacement
/// that grows without bound or a contact force that cycles, with every step exact.
fn check_step_limit<const D: usize>(
    setup: &ProblemSetup<D>,
    simulation: &Simulation<D>,
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
        "{}: the time step k = final_time/steps = {}/{} = {step:e} exceeds the stability limit k_max = {:.3e} of the explicit terms of (5.1) ({terms} at u_(n−1); λ_max(H⁻¹B) = {:.3e} by {} power iterations): the run would oscillate or blow up; {remedy}",
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
        contact_damage::memory::estimate(
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
    let state_path = dir.join(STATE_FILE);
    let history_path = dir.join(HISTORY_FILE);
    let contact_history_path = dir.join(CONTACT_HISTORY_FILE);
    let contact_line = ContactLine::new(&space, &contact);
    let pictures = picture_steps(&setup.pictures, simulation.time_step(), steps);
    let invalid = |message: String| InputError::InvalidInput(message);

    let mut saved_steps = Vec::new();
    let mut sums = RunningSums::new(contact.len());
    let header = history_header(simulation.dirichlet_parts(), D);
    let step_limit;
    if options.resume {
        let saved = read_saved_state(&dir)?;
        let mismatch = |what: &str, saved_value: String, problem_value: String| {
            invalid(format!(
                "{} does not belong to {}: {what} is {saved_value} there but {problem_value} in the problem",
                state_path.display(),
                setup.origin
            ))
        };
        if saved.dim != D {
            return Err(mismatch("dim", saved.dim.to_string(), D.to_string()));
        }
        if saved.degree != setup.problem.degree {
            return Err(mismatch(
                "degree",
                saved.degree.to_string(),
                setup.problem.degree.to_string(),
            ));
        }
        if saved.steps != steps {
            return Err(mismatch(
                "steps",
                saved.steps.to_string(),
                steps.to_string(),
            ));
        }
        if saved.final_time.to_bits() != setup.problem.final_time.to_bits() {
            return Err(mismatch(
                "final_time",
                saved.final_time.to_string(),
                setup.problem.final_time.to_string(),
            ));
        }
        if saved.nodes != space.num_nodes() {
            return Err(mismatch(
                "the number of nodes",
                saved.nodes.to_string(),
                space.num_nodes().to_string(),
            ));
        }
        if saved.step > steps || saved.saved_steps.last() != Some(&saved.step) {
            return Err(invalid(format!(
                "{}: step {} is not the last saved step of a run of {steps} steps",
                state_path.display(),
                saved.step
            )));
        }
        let keys = setup.fingerprint.keys().chain(saved.fingerprint.keys());
        for key in keys {
            if saved.fingerprint.get(key) != setup.fingerprint.get(key) {
                return Err(invalid(format!(
                    "{} does not belong to {}: `{key}` changed since the saved run (resume needs the same constants, laws, loads, mesh and scheme; start afresh with --overwrite)",
                    state_path.display(),
                    setup.origin
                )));
            }
        }
        if saved.accumulated_slip.len() != contact.len() {
            return Err(mismatch(
                "the number of contact nodes",
                saved.accumulated_slip.len().to_string(),
                contact.len().to_string(),
            ));
        }
        let expected_time = saved.step as f64 * simulation.time_step();
        if saved.time.to_bits() != expected_time.to_bits() {
            return Err(mismatch(
                "the time of the step",
                saved.time.to_string(),
                expected_time.to_string(),
            ));
        }
        check_saved_values::<D>(&saved, &state_path)?;
        folder::remove_stale_temporaries(&dir)?;
        saved_steps = saved.saved_steps.clone();
        sums = RunningSums {
            accumulated_slip: saved.accumulated_slip,
            friction_dissipation: saved.friction_dissipation,
            viscous_dissipation: saved.viscous_dissipation,
        };
        simulation.set_state(State {
            step: saved.step,
            time: saved.time,
            displacement: saved.displacement,
            velocity: saved.velocity,
            damage: saved.damage,
        })?;
        step_limit = check_step_limit(setup, &simulation)?;
        truncate_history(&history_path, saved.step, &header)?;
        let recorded: Vec<usize> = (1..=saved.step)
            .filter(|&n| records_contact_history(n, setup.every, steps))
            .collect();
        truncate_contact_history(&contact_history_path, &recorded, contact_line.indices.len())?;
    } else {
        step_limit = check_step_limit(setup, &simulation)?;
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

    let tabulation = Tabulation::cell_rule(
        space.element(),
        &QuadratureRule::<D>::simplex(2 * space.degree()),
    );
    let last_step = options.until_step.unwrap_or(steps).min(steps);
    let clock = Instant::now();
    let mut max_kkt = [0.0f64; 2];
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
        let (velocity, damage, normal_pressure, friction_bound) = simulation
            .step()
            .map_err(|error| setup.load_watch.explain(&setup.origin, error.into()))?;
        let state = simulation.state();
        let n = state.step;
        max_kkt[0] = max_kkt[0].max(velocity.stats.kkt_residual);
        max_kkt[1] = max_kkt[1].max(damage.stats.kkt_residual);
        let (mean_damage, area_damage_below_half) =
            damage_integrals(&space, &tabulation, &state.damage);
        let speed = tangential_speed(&contact, &state.velocity);
        let on_contact = contact_integrals(
            &contact,
            &ContactStep {
                status: &velocity.status,
                normal_pressure: &normal_pressure,
                friction_bound: &friction_bound,
            },
            &speed,
            simulation.time_step(),
            &mut sums,
        );
        let (force, tangential_force) = contact_force(
            &contact,
            &normal_pressure,
            &friction_bound,
            &velocity.multipliers,
        );
        // the penetration whose p_ν the step used: u_{n−1} − g(t_{n−1}) (5.1), or
        // u_n − g(t_n) (implicit)
        let (pressed, gap_time) = if setup.problem.settings.contact == ContactTreatment::Implicit {
            (state.displacement.clone(), state.time)
        } else {
            let k = simulation.time_step();
            let previous: Vec<f64> = state
                .displacement
                .iter()
                .zip(&state.velocity)
                .map(|(u, v)| u - k * v)
                .collect();
            (previous, state.time - k)
        };
        let gap = &setup.problem.data.gap;
        let zone = contact_zone(
            &space,
            &boundary_penetration(&space, &contact, &pressed, |x| gap(x, gap_time)),
            contact_line.axis,
        );
        if let Some((low, high)) = force_cycle.push(on_contact.normal_force) {
            return Err(InputError::InvalidInput(format!(
                "{}: the total normal contact force cycles with period two between {low:.6e} and {high:.6e} over steps {}..={n}, although every step is solved exactly: the step k = {:e} is above the stability limit of the explicit normal compliance for the contact state reached (the estimate at the start was {:.3e}); raise `steps` or use `[scheme] contact = \"implicit\"`",
                setup.origin,
                n + 1 - CYCLE_WINDOW_STEPS,
                simulation.time_step(),
                step_limit.time_step,
            )));
        }
        let viscous_power = viscous_power(setup, &space, &tabulation, &state.velocity);
        sums.viscous_dissipation += simulation.time_step() * viscous_power;
        let row = HistoryRow {
            step: n,
            time: state.time,
            normal_force: on_contact.normal_force,
            tangential_force,
            force: std::array::from_fn(|i| if i < D { force[i] } else { 0.0 }),
            contact_zone: zone.measure,
            zone_bounds: [zone.lower, zone.upper],
            slip_zone: on_contact.slip_zone,
            separated: on_contact.counts[0],
            stick: on_contact.counts[1],
            slip: on_contact.counts[2],
            slip_rate: on_contact.slip_rate,
            max_accumulated_slip: sums.accumulated_slip.iter().fold(0.0, |a, &b| a.max(b)),
            friction_power: on_contact.friction_power,
            friction_dissipation: sums.friction_dissipation,
            viscous_power,
            viscous_dissipation: sums.viscous_dissipation,
            mean_damage,
            area_damage_below_half,
            velocity_kkt: velocity.stats.kkt_residual,
            damage_kkt: damage.stats.kkt_residual,
            newton_iterations: velocity.stats.newton_iterations,
            friction_iterations: velocity.stats.friction_iterations,
            damage_iterations: damage.stats.iterations,
            reactions: simulation
                .part_reactions(&velocity.reaction)
                .iter()
                .flatten()
                .copied()
                .collect(),
        };
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
                            &normal_pressure,
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
            // Γ3 fields on all space nodes (zero off the contact nodes)
            let nodes = space.num_nodes();
            let mut status = vec![0.0; nodes];
            let mut contact_node = vec![0.0; nodes];
            let mut pressure = vec![0.0; nodes];
            let mut tangential = vec![0.0; nodes * D];
            for (k, &node) in contact.nodes.iter().enumerate() {
                status[node] = match velocity.status[k] {
                    ContactStatus::Separated => 0.0,
                    ContactStatus::Stick => 1.0,
                    ContactStatus::Slip => 2.0,
                };
                contact_node[node] = 1.0;
                pressure[node] = normal_pressure[k];
                for i in 0..D - 1 {
                    let traction = -friction_bound[k] * velocity.multipliers[k * (D - 1) + i];
                    for j in 0..D {
                        tangential[node * D + j] += traction * contact.frames[k][(j, 1 + i)];
                    }
                }
            }
            let stress = cell_stress(setup, &space, state);
            write_vtu(
                &dir.join(solution_file(n)),
                &space,
                &[
                    PointData::Vector {
                        name: "displacement",
                        values: &state.displacement,
                    },
                    PointData::Vector {
                        name: "velocity",
                        values: &state.velocity,
                    },
                    PointData::Scalar {
                        name: "damage",
                        values: &state.damage,
                    },
                ],
                &[CellData::Tensor {
                    name: "stress",
                    values: &stress,
                }],
            )?;
            write_boundary_vtu(
                &dir.join(contact_file(n)),
                &space,
                BoundaryPart::Contact,
                &[
                    PointData::Scalar {
                        name: "status",
                        values: &status,
                    },
                    PointData::Scalar {
                        name: "contact_node",
                        values: &contact_node,
                    },
                    PointData::Scalar {
                        name: "normal_pressure",
                        values: &pressure,
                    },
                    PointData::Vector {
                        name: "tangential_traction",
                        values: &tangential,
                    },
                    PointData::Vector {
                        name: "displacement",
                        values: &state.displacement,
                    },
                ],
            )?;
            saved_steps.push(n);
            let time_step = simulation.time_step();
            let entries = |name: fn(usize) -> String| -> Vec<(f64, String)> {
                saved_steps
                    .iter()
                    .map(|&s| (s as f64 * time_step, name(s)))
                    .collect()
            };
            write_pvd(&dir.join("solution.pvd"), &entries(solution_file))?;
            write_pvd(&dir.join("contact.pvd"), &entries(contact_file))?;
            write_json_atomic(
                &state_path,
                &SavedState {
                    name: setup.name.clone(),
                    dim: D,
                    degree: space.degree(),
                    steps,
                    final_time: setup.problem.final_time,
                    nodes,
                    saved_steps: saved_steps.clone(),
                    step: n,
                    time: state.time,
                    displacement: state.displacement.clone(),
                    velocity: state.velocity.clone(),
                    damage: state.damage.clone(),
                    accumulated_slip: sums.accumulated_slip.clone(),
                    friction_dissipation: sums.friction_dissipation,
                    viscous_dissipation: sums.viscous_dissipation,
                    fingerprint: setup.fingerprint.clone(),
                },
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::history::tests::{setup, unit_square_space};

    #[test]
    fn cell_stress_is_viscous_plus_damaged_elastic_stress() {
        let setup = setup();
        let space = unit_square_space(2);
        // affine fields: ε(u) = [[0.1, 0.05], [0.05, -0.2]], ε(v) = [[0, 0.5], [0.5, 0.3]]
        let state = State {
            step: 0,
            time: 0.0,
            displacement: space.interpolate_vector(|x| [0.1 * x[0] + 0.1 * x[1], -0.2 * x[1]]),
            velocity: space.interpolate_vector(|x| [x[1], 0.3 * x[1]]),
            damage: vec![0.6; space.num_nodes()],
        };
        let stress = cell_stress(&setup, &space, &state);
        let strain = Tensor::<2>::new(0.1, 0.05, 0.05, -0.2);
        let rate = Tensor::<2>::new(0.0, 0.5, 0.5, 0.3);
        let identity = Tensor::<2>::identity();
        let expected = (rate * 2.0 * 0.5 + identity * 0.25 * rate.trace())
            + (strain * 2.0 * 2.0 + identity * 3.0 * strain.trace()) * 0.6;
        assert_eq!(stress.len(), space.mesh().num_cells() * 4);
        for sigma in stress.chunks(4) {
            for i in 0..2 {
                for j in 0..2 {
                    assert!((sigma[i * 2 + j] - expected[(i, j)]).abs() < 1e-13);
                }
            }
        }
    }
}
