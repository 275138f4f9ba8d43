//! The results folder: one file per run, named by the run's digest (`<digest>.result`), written
//! atomically, and checked when read.
//!
//! A result file is one header line of JSON — the format, the run's digest and id, the length and
//! the SHA-256 of the payload — followed by the payload: the run's [`RunResult`] as JSON, or,
//! for the reference run of a k-study, its stored states in binary (little-endian). A file whose
//! header does not parse, whose digest is not the run's, or whose payload is truncated or does
//! not match its checksum is invalid: it is reported and recomputed, never merged.

use crate::output::write_atomic;
use crate::study::RunResult;
use crate::sweep::plan::{sha256_hex, PlannedRun};
use crate::InputError;
use contact_damage::scheme::State;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The format tag of a result file.
pub const RESULT_FORMAT: &str = "verify-result/1";

/// The header line of a result file.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Header {
    format: String,
    digest: String,
    id: String,
    bytes: usize,
    sha256: String,
}

/// Why a stored result cannot be used.
#[derive(Debug, Clone, PartialEq)]
pub enum Stored<T> {
    /// A valid result.
    Valid(T),
    /// No result file.
    Missing,
    /// A result file that is not valid (the reason).
    Invalid(String),
}

/// The result file of `run` in `results`.
pub fn result_path(results: &Path, run: &PlannedRun) -> PathBuf {
    results.join(format!("{}.result", run.digest))
}

fn store(results: &Path, run: &PlannedRun, payload: &[u8]) -> Result<(), InputError> {
    let header = Header {
        format: RESULT_FORMAT.to_string(),
        digest: run.digest.clone(),
        id: run.id.clone(),
        bytes: payload.len(),
        sha256: sha256_hex(payload),
    };
    let mut bytes = serde_json::to_vec(&header).map_err(|e| InputError::Serialize {
        path: result_path(results, run),
        message: e.to_string(),
    })?;
    bytes.push(b'\n');
    bytes.extend_from_slice(payload);
    write_atomic(&result_path(results, run), &bytes)
}

/// Reads the payload of the result file of `run`, checked.
fn load(results: &Path, run: &PlannedRun) -> Stored<Vec<u8>> {
    let path = result_path(results, run);
    if let Err(error) = contact_input::regular::check_regular_file(&path, "result file") {
        return Stored::Invalid(error.to_string());
    }
    let bytes = match std::fs::read(&path) {
        Ok(bytes) => bytes,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Stored::Missing,
        Err(e) => return Stored::Invalid(format!("cannot read it: {e}")),
    };
    let Some(end) = bytes.iter().position(|&b| b == b'\n') else {
        return Stored::Invalid("no header line (truncated?)".to_string());
    };
    let header: Header = match serde_json::from_slice(&bytes[..end]) {
        Ok(header) => header,
        Err(e) => return Stored::Invalid(format!("header: {e}")),
    };
    let payload = &bytes[end + 1..];
    if header.format != RESULT_FORMAT {
        Stored::Invalid(format!(
            "format `{}`, expected `{RESULT_FORMAT}`",
            header.format
        ))
    } else if header.digest != run.digest || header.id != run.id {
        Stored::Invalid(format!(
            "it is the result of run {} ({}), not of this run",
            header.id, header.digest
        ))
    } else if payload.len() != header.bytes {
        Stored::Invalid(format!(
            "payload of {} bytes, the header says {} (truncated?)",
            payload.len(),
            header.bytes
        ))
    } else if sha256_hex(payload) != header.sha256 {
        Stored::Invalid("payload does not match its checksum (corrupt)".to_string())
    } else {
        Stored::Valid(payload.to_vec())
    }
}

/// Stores the result of a run (atomically).
pub fn store_run(results: &Path, run: &PlannedRun, result: &RunResult) -> Result<(), InputError> {
    let payload = serde_json::to_vec(result).map_err(|e| InputError::Serialize {
        path: result_path(results, run),
        message: e.to_string(),
    })?;
    store(results, run, &payload)
}

/// What a stored run result must satisfy to be used: the run's level and steps, a finite
/// positive h and k, error components finite and ≥ 0 (`velocity` may have no value), finite
/// non-negative KKT residuals and iteration means, and some velocity unknowns. A checksum
/// without a key detects accidents only; these checks keep a forged or stale result from
/// reaching a report.
fn check_run(result: &RunResult, run: &PlannedRun) -> Result<(), String> {
    if result.cells != run.cells || result.steps != run.steps {
        return Err(format!(
            "it holds level {} with {} steps, the run is level {} with {} steps",
            result.cells, result.steps, run.cells, run.steps
        ));
    }
    for (name, value) in [("h", result.h), ("k", result.k)] {
        if !(value.is_finite() && value > 0.0) {
            return Err(format!("{name} = {value} (must be finite and > 0)"));
        }
    }
    let names = crate::error_norms::ErrorComponents::NAMES;
    for (name, value) in names.iter().zip(result.errors.values()) {
        // only `velocity` may have no value (a run against a discrete reference)
        let absent_allowed = *name == "velocity" && value.is_nan();
        let admissible = value.is_finite() && value >= 0.0;
        if !(absent_allowed || admissible) {
            return Err(format!("error `{name}` = {value} (must be finite and ≥ 0)"));
        }
    }
    let stats = &result.stats;
    for (name, value) in [
        ("max_velocity_kkt", stats.max_velocity_kkt),
        ("max_damage_kkt", stats.max_damage_kkt),
        ("mean_newton_iterations", stats.mean_newton_iterations),
    ] {
        if !(value.is_finite() && value >= 0.0) {
            return Err(format!("`{name}` = {value} (must be finite and ≥ 0)"));
        }
    }
    if stats.velocity_unknowns == 0 {
        return Err("no velocity unknowns".to_string());
    }
    Ok(())
}

/// Loads the checked result of a run (its header, checksum and what it holds: level, steps,
/// finite non-negative errors and residuals).
pub fn load_run(results: &Path, run: &PlannedRun) -> Stored<RunResult> {
    match load(results, run) {
        Stored::Valid(payload) => match serde_json::from_slice::<RunResult>(&payload) {
            Ok(result) => match check_run(&result, run) {
                Ok(()) => Stored::Valid(result),
                Err(reason) => Stored::Invalid(reason),
            },
            Err(e) => Stored::Invalid(format!("payload: {e}")),
        },
        Stored::Missing => Stored::Missing,
        Stored::Invalid(reason) => Stored::Invalid(reason),
    }
}

fn push_vector(bytes: &mut Vec<u8>, values: &[f64]) {
    bytes.extend_from_slice(&(values.len() as u64).to_le_bytes());
    for value in values {
        bytes.extend_from_slice(&value.to_le_bytes());
    }
}

/// Stores the states of a reference run (binary: count, then per state step, time and the
/// displacement, velocity and damage vectors with their lengths; all little-endian).
pub fn store_states(results: &Path, run: &PlannedRun, states: &[State]) -> Result<(), InputError> {
    let mut bytes = Vec::new();
    bytes.extend_from_slice(&(states.len() as u64).to_le_bytes());
    for state in states {
        bytes.extend_from_slice(&(state.step as u64).to_le_bytes());
        bytes.extend_from_slice(&state.time.to_le_bytes());
        push_vector(&mut bytes, &state.displacement);
        push_vector(&mut bytes, &state.velocity);
        push_vector(&mut bytes, &state.damage);
    }
    store(results, run, &bytes)
}

/// Reads the binary layout of [`store_states`].
struct Reader<'a> {
    bytes: &'a [u8],
}

impl Reader<'_> {
    fn word(&mut self) -> Option<[u8; 8]> {
        let (head, rest) = self.bytes.split_first_chunk::<8>()?;
        self.bytes = rest;
        Some(*head)
    }

    fn count(&mut self) -> Option<usize> {
        usize::try_from(u64::from_le_bytes(self.word()?)).ok()
    }

    fn vector(&mut self) -> Option<Vec<f64>> {
        let n = self.count()?;
        if n > self.bytes.len() / 8 {
            return None;
        }
        (0..n)
            .map(|_| Some(f64::from_le_bytes(self.word()?)))
            .collect()
    }

    fn state(&mut self) -> Option<State> {
        Some(State {
            step: self.count()?,
            time: f64::from_le_bytes(self.word()?),
            displacement: self.vector()?,
            velocity: self.vector()?,
            damage: self.vector()?,
            previous_damage: Vec::new(),
        })
    }
}

/// What stored reference states must satisfy: one state per stored step (every `stride`-th of
/// the run's steps, from 0), finite times and values, and vectors of one length per kind with D
/// displacement and velocity values per damage value (D = 2 or 3). Whether they fit the mesh is
/// checked where they are used.
fn check_states(states: &[State], run: &PlannedRun) -> Result<(), String> {
    let stride = run.stride.unwrap_or(1).max(1);
    let expected = run.steps / stride + 1;
    if states.len() != expected {
        return Err(format!(
            "{} states, the run stores {expected} (every {stride}-th of {} steps)",
            states.len(),
            run.steps
        ));
    }
    let first = &states[0];
    let nodes = first.damage.len();
    let dim_ok = nodes > 0
        && (first.displacement.len() == 2 * nodes || first.displacement.len() == 3 * nodes);
    if !dim_ok {
        return Err(format!(
            "state vectors of {} displacement and {nodes} damage values",
            first.displacement.len()
        ));
    }
    for (i, state) in states.iter().enumerate() {
        if state.step != i * stride || !state.time.is_finite() {
            return Err(format!(
                "state {i}: step {}, t = {}",
                state.step, state.time
            ));
        }
        let lengths_fit = state.damage.len() == nodes
            && state.displacement.len() == first.displacement.len()
            && state.velocity.len() == first.displacement.len();
        if !lengths_fit {
            return Err(format!("state {i}: vectors of another length than state 0"));
        }
        let finite = state
            .displacement
            .iter()
            .chain(&state.velocity)
            .chain(&state.damage)
            .all(|v| v.is_finite());
        if !finite {
            return Err(format!("state {i}: a value that is not finite"));
        }
    }
    Ok(())
}

/// Loads the checked states of a reference run (header, checksum, one finite state per stored
/// step with vectors of consistent lengths).
pub fn load_states(results: &Path, run: &PlannedRun) -> Stored<Vec<State>> {
    match load(results, run) {
        Stored::Valid(payload) => {
            let mut reader = Reader { bytes: &payload };
            let states = reader
                .count()
                .and_then(|n| (0..n).map(|_| reader.state()).collect::<Option<Vec<_>>>());
            match states {
                Some(states) if reader.bytes.is_empty() => match check_states(&states, run) {
                    Ok(()) => Stored::Valid(states),
                    Err(reason) => Stored::Invalid(reason),
                },
                _ => Stored::Invalid("payload is not a list of states".to_string()),
            }
        }
        Stored::Missing => Stored::Missing,
        Stored::Invalid(reason) => Stored::Invalid(reason),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::plan::RunKind;

    fn planned(digest: &str) -> PlannedRun {
        PlannedRun {
            index: 0,
            id: "l1-c2-ref4".to_string(),
            kind: RunKind::Reference,
            cells: 2,
            steps: 4,
            stride: Some(2),
            reference: None,
            cost: 1.0,
            digest: digest.to_string(),
            used_by: vec![],
        }
    }

    #[test]
    fn states_round_trip_and_damage_is_detected() {
        let scratch = tempfile::tempdir().unwrap();
        let run = planned("abc");
        let states: Vec<State> = (0..3)
            .map(|n| State {
                step: 2 * n,
                time: 0.1 * n as f64,
                displacement: vec![1.0 / 3.0, -2.5e-300],
                velocity: vec![f64::MIN_POSITIVE, 7.0],
                damage: vec![0.999],
                previous_damage: Vec::new(),
            })
            .collect();
        store_states(scratch.path(), &run, &states).unwrap();
        let Stored::Valid(back) = load_states(scratch.path(), &run) else {
            panic!("not valid")
        };
        assert_eq!(back.len(), 3);
        for (a, b) in states.iter().zip(&back) {
            assert_eq!(
                (a.step, a.time, &a.displacement),
                (b.step, b.time, &b.displacement)
            );
            assert_eq!((&a.velocity, &a.damage), (&b.velocity, &b.damage));
        }
        // another run's digest
        assert!(matches!(
            load_states(scratch.path(), &planned("abd")),
            Stored::Missing
        ));
        let path = result_path(scratch.path(), &run);
        let bytes = std::fs::read(&path).unwrap();
        // truncated
        std::fs::write(&path, &bytes[..bytes.len() - 5]).unwrap();
        assert!(
            matches!(load_states(scratch.path(), &run), Stored::Invalid(r) if r.contains("truncated"))
        );
        // one byte flipped in the payload
        let mut flipped = bytes.clone();
        let last = flipped.len() - 1;
        flipped[last] ^= 1;
        std::fs::write(&path, &flipped).unwrap();
        assert!(
            matches!(load_states(scratch.path(), &run), Stored::Invalid(r) if r.contains("checksum"))
        );
    }

    fn run_result(run: &PlannedRun, damage_error: f64) -> RunResult {
        RunResult {
            cells: run.cells,
            h: 0.7,
            mesh_cells: 8,
            shape_regularity: 1.0,
            steps: run.steps,
            k: 0.25,
            errors: crate::error_norms::ErrorComponents {
                displacement: 0.1,
                difference_quotient: 0.2,
                damage: damage_error,
                damage_gradient: 0.3,
                total: 0.6,
                velocity: f64::NAN,
            },
            stats: crate::study::RunStats {
                velocity_unknowns: 18,
                ..Default::default()
            },
        }
    }

    #[test]
    fn stored_results_with_a_valid_checksum_are_still_checked_like_input() {
        let scratch = tempfile::tempdir().unwrap();
        let run = PlannedRun {
            kind: RunKind::Exact,
            ..planned("run")
        };
        store_run(scratch.path(), &run, &run_result(&run, 0.05)).unwrap();
        assert!(matches!(load_run(scratch.path(), &run), Stored::Valid(_)));
        // forged with a recomputed checksum: a negative error, an error without a value
        for (error, reason) in [(-1e-3, "damage"), (f64::NAN, "damage")] {
            store_run(scratch.path(), &run, &run_result(&run, error)).unwrap();
            let stored = load_run(scratch.path(), &run);
            assert!(
                matches!(&stored, Stored::Invalid(r) if r.contains(reason)),
                "{error}: {stored:?}"
            );
        }
        // another level than the run's
        let mut other = run_result(&run, 0.05);
        other.cells += 1;
        store_run(scratch.path(), &run, &other).unwrap();
        assert!(
            matches!(load_run(scratch.path(), &run), Stored::Invalid(r) if r.contains("level"))
        );
        // reference states: one vector cut to a single value, a NaN, a missing state
        let reference = planned("reference");
        let good: Vec<State> = (0..3)
            .map(|n| State {
                step: 2 * n,
                time: 0.1 * n as f64,
                displacement: vec![0.0; 4],
                velocity: vec![0.0; 4],
                damage: vec![1.0; 2],
                previous_damage: Vec::new(),
            })
            .collect();
        let mut short = good.clone();
        short[1].displacement.truncate(1);
        let mut nan = good.clone();
        nan[2].velocity[0] = f64::NAN;
        let missing = good[..2].to_vec();
        for (states, reason) in [(&short, "length"), (&nan, "finite"), (&missing, "states")] {
            store_states(scratch.path(), &reference, states).unwrap();
            let stored = load_states(scratch.path(), &reference);
            assert!(
                matches!(&stored, Stored::Invalid(r) if r.contains(reason)),
                "{reason}: {stored:?}"
            );
        }
        store_states(scratch.path(), &reference, &good).unwrap();
        assert!(matches!(
            load_states(scratch.path(), &reference),
            Stored::Valid(_)
        ));
    }
}
