//! Resuming a run from `state.json`: the restart file, and the checks that it belongs to the
//! problem and holds admissible values before the time loop continues from it.

use crate::folder;
use crate::folder::STATE_FILE;
use crate::history::RunningSums;
use crate::problem::{ProblemSetup, ProfileFile};
use contact_damage::scheme::{Simulation, State};
use contact_input::{FileKind, InputError};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

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
    /// β_{n−1} (empty at n = 0), the other start value of the next damage step
    /// ([`State::previous_damage`]). Absent from the files of earlier versions: the run then
    /// continues with the damage step started from β_n, which changes the results by no more
    /// than the solver's tolerance.
    #[serde(default)]
    pub previous_damage: Vec<f64>,
    /// Σ_{m ≤ n} k |v_{m,τ}(a)| per contact node (see [`crate::history`]).
    pub accumulated_slip: Vec<f64>,
    /// Σ_{m ≤ n} k j(u_{m−1}, v_m).
    pub friction_dissipation: f64,
    /// Σ_{m ≤ n} k ∫_Ω 𝒜ε(v_m)·ε(v_m).
    pub viscous_dissipation: f64,
    /// [`ProblemSetup::fingerprint`] of the problem that was run.
    pub fingerprint: BTreeMap<String, String>,
    /// `output.every` of the run: which steps have rows in `contact_history.csv` (a resumed
    /// run must keep it). Absent from the files of earlier versions: not checked then.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output_every: Option<usize>,
    /// The line of `contact_history.csv` and the point of the moment in `history.csv` of the
    /// run (a resumed run must keep them). Absent from the files of earlier versions: not
    /// checked then.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact_output: Option<ContactOutput>,
}

/// What decides the contact columns of the run's files: `output.profile` and
/// `output.moment_about`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactOutput {
    /// `output.profile` (None: the default line).
    pub profile: Option<ProfileFile>,
    /// `output.moment_about` (d coordinates).
    pub moment_about: Vec<f64>,
}

impl ContactOutput {
    /// Those of the problem `setup`.
    pub fn of<const D: usize>(setup: &ProblemSetup<D>) -> Self {
        Self {
            profile: setup.file.output.profile.clone(),
            moment_about: setup.moment_about.to_vec(),
        }
    }
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
        (
            "previous_damage",
            &saved.previous_damage,
            if saved.previous_damage.is_empty() {
                0
            } else {
                saved.nodes
            },
        ),
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
    for (field, values) in [
        ("damage", &saved.damage),
        ("previous_damage", &saved.previous_damage),
    ] {
        if let Some(i) = values.iter().position(|b| !(0.0..=1.0).contains(b)) {
            return Err(bad(
                field,
                format!("[{i}] = {} lies outside [0, 1]", values[i]),
            ));
        }
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
    contact_input::regular::check_regular_file(&path, "saved state")?;
    let text = std::fs::read_to_string(&path)
        .map_err(|e| InputError::io("reading saved state", &path, e))?;
    serde_json::from_str(&text)
        .map_err(|e| InputError::InvalidInput(format!("{}: {e}", path.display())))
}

/// What a resumed run continues from.
pub(crate) struct Resumed {
    /// Steps saved so far (the PVD entries).
    pub saved_steps: Vec<usize>,
    /// The running sums of the history at the saved step.
    pub sums: RunningSums,
    /// The saved step n.
    pub step: usize,
}

/// Reads `state.json` of `dir`, checks that it belongs to `setup` (dimension, degree, N, T,
/// nodes, contact nodes, the time of the step, the fingerprint of constants, laws, loads, mesh
/// and scheme) and that its values are admissible, removes the temporaries a killed run left,
/// and sets the state of `simulation` to the saved one.
pub(crate) fn resume<const D: usize>(
    setup: &ProblemSetup<D>,
    simulation: &mut Simulation<D>,
    dir: &Path,
    contact_nodes: usize,
) -> Result<Resumed, InputError> {
    let state_path = dir.join(STATE_FILE);
    let space = simulation.space().clone();
    let steps = simulation.steps();
    let invalid = |message: String| InputError::InvalidInput(message);
    let saved = read_saved_state(dir)?;
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
    if let Some(every) = saved.output_every.filter(|&every| every != setup.every) {
        return Err(FileKind::Problem.error(
            &setup.origin,
            "output.every",
            format!(
                "{} here, but the run saved in {} wrote its contact history every {every} \
                 steps; a resumed run continues the files of that run, so resume with \
                 output.every = {every} (or start afresh with --overwrite)",
                setup.every,
                state_path.display()
            ),
        ));
    }
    if let Some(saved_output) = &saved.contact_output {
        let current = ContactOutput::of(setup);
        let changed = if saved_output.profile != current.profile {
            Some((
                "output.profile",
                "recorded its contact history on another line",
            ))
        } else if saved_output.moment_about != current.moment_about {
            Some((
                "output.moment_about",
                "took the moment of the contact tractions about another point",
            ))
        } else {
            None
        };
        if let Some((key, what)) = changed {
            return Err(FileKind::Problem.error(
                &setup.origin,
                key,
                format!(
                    "changed since the run saved in {}, which {what}; a resumed run continues \
                     the files of that run, so resume with the same value (or start afresh \
                     with --overwrite)",
                    state_path.display()
                ),
            ));
        }
    }
    if saved.accumulated_slip.len() != contact_nodes {
        return Err(mismatch(
            "the number of contact nodes",
            saved.accumulated_slip.len().to_string(),
            contact_nodes.to_string(),
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
    folder::remove_stale_temporaries(dir)?;
    let saved_steps = saved.saved_steps.clone();
    let step = saved.step;
    let sums = RunningSums {
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
        previous_damage: saved.previous_damage,
    })?;
    Ok(Resumed {
        saved_steps,
        sums,
        step,
    })
}
