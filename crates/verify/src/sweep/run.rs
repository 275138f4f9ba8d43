//! Runs the runs of a manifest that have no valid result yet and stores each result.

use crate::case::Case;
use crate::study::{progress, reference_states, run_one};
use crate::sweep::cache::{load_run, load_states, result_path, store_run, store_states, Stored};
use crate::sweep::plan::{Manifest, PlannedRun, RunKind};
use crate::InputError;
use contact_damage::scheme::State;
use rayon::prelude::*;
use std::collections::HashMap;
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// What [`execute`] did.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Executed {
    /// Runs with a valid stored result, not recomputed.
    pub cached: usize,
    /// Runs computed (and stored).
    pub computed: usize,
    /// Runs whose stored result was invalid (they were recomputed): (id, reason).
    pub invalid: Vec<(String, String)>,
}

/// Whether the run has a valid stored result; an invalid one is reported on stderr.
fn has_result(results: &Path, run: &PlannedRun, invalid: &mut Vec<(String, String)>) -> bool {
    let stored = match run.kind {
        RunKind::Reference => match load_states(results, run) {
            Stored::Valid(_) => Stored::Valid(()),
            Stored::Missing => Stored::Missing,
            Stored::Invalid(reason) => Stored::Invalid(reason),
        },
        _ => match load_run(results, run) {
            Stored::Valid(_) => Stored::Valid(()),
            Stored::Missing => Stored::Missing,
            Stored::Invalid(reason) => Stored::Invalid(reason),
        },
    };
    match stored {
        Stored::Valid(()) => true,
        Stored::Missing => false,
        Stored::Invalid(reason) => {
            // a notice: when standard error is gone, the run goes on without it
            let _ = contact_input::errln!(
                "run {}: invalid result {}: {reason}; recomputing",
                run.id,
                result_path(results, run).display()
            );
            invalid.push((run.id.clone(), reason));
            false
        }
    }
}

/// The states of a reference run at its stride, from `known` (those already at hand), from the
/// results folder (unless `fresh`) or computed (and stored).
fn reference<const D: usize>(
    case: &Case<D>,
    manifest: &Manifest,
    run: &PlannedRun,
    results: &Path,
    known: &Mutex<HashMap<String, Arc<Vec<State>>>>,
    fresh: bool,
) -> Result<Arc<Vec<State>>, InputError> {
    // held while computing: the runs against one reference wait for it rather than repeat it
    let mut known = known
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    if let Some(states) = known.get(&run.id) {
        return Ok(states.clone());
    }
    let stored = if fresh {
        Stored::Missing
    } else {
        load_states(results, run)
    };
    let states = match stored {
        Stored::Valid(states) => states,
        _ => {
            let started = Instant::now();
            let stride = run.stride.unwrap_or(1).max(1);
            let states: Vec<State> = reference_states(case, manifest.degree, run.cells, run.steps)?
                .into_iter()
                .step_by(stride)
                .collect();
            store_states(results, run, &states)?;
            contact_input::outln!(
                "computed run {} in {:.2} s",
                run.id,
                started.elapsed().as_secs_f64()
            )?;
            states
        }
    };
    let states = Arc::new(states);
    known.insert(run.id.clone(), states.clone());
    Ok(states)
}

/// Computes one run (not a reference run) and stores its result.
fn compute<const D: usize>(
    case: &Case<D>,
    manifest: &Manifest,
    run: &PlannedRun,
    results: &Path,
    known: &Mutex<HashMap<String, Arc<Vec<State>>>>,
) -> Result<(), InputError> {
    let against = match (&run.kind, &run.reference) {
        (RunKind::AgainstReference, Some(id)) => {
            let planned = manifest.run(id).ok_or_else(|| {
                InputError::InvalidInput(format!("run {}: no reference run `{id}`", run.id))
            })?;
            let states = reference(case, manifest, planned, results, known, false)?;
            // the stored states are every `stride`-th step; this run needs every (R/N)-th
            let every = planned.steps / run.steps / planned.stride.unwrap_or(1).max(1);
            Some(Arc::new(
                states.iter().step_by(every.max(1)).cloned().collect(),
            ))
        }
        _ => None,
    };
    let result = run_one(case, manifest.degree, run.cells, run.steps, against)?;
    store_run(results, run, &result)?;
    contact_input::outln!(
        "computed run {} in {:.2} s",
        run.id,
        result.stats.wall_seconds
    )?;
    Ok(())
}

/// Runs the runs `selection` (indices of `manifest.runs`) of the case `case` that have no valid
/// result in `results` (all of them with `fresh`), the reference runs first, the others in
/// parallel, and stores each result as soon as it is computed. A run that fails does not stop
/// the others; the failed runs are then named in the error.
pub fn execute<const D: usize>(
    case: &Case<D>,
    manifest: &Manifest,
    selection: &[usize],
    results: &Path,
    fresh: bool,
) -> Result<Executed, InputError> {
    let mut executed = Executed::default();
    let mut pending: Vec<&PlannedRun> = Vec::new();
    for &index in selection {
        let run = manifest.runs.get(index).ok_or_else(|| {
            InputError::InvalidInput(format!(
                "--index {index}: the manifest has {} runs (0 ..= {})",
                manifest.runs.len(),
                manifest.runs.len().saturating_sub(1)
            ))
        })?;
        if !fresh && has_result(results, run, &mut executed.invalid) {
            executed.cached += 1;
        } else {
            pending.push(run);
        }
    }
    executed.computed = pending.len();
    let known = Mutex::new(HashMap::new());
    let bar = progress(pending.len(), &format!("runs l={}", manifest.degree));
    let mut failed = Vec::new();
    let (references, others): (Vec<&PlannedRun>, Vec<&PlannedRun>) = pending
        .into_iter()
        .partition(|run| run.kind == RunKind::Reference);
    for batch in [references, others] {
        let outcomes: Vec<(String, Result<(), InputError>)> = batch
            .par_iter()
            .map(|run| {
                let outcome = match run.kind {
                    RunKind::Reference => {
                        reference(case, manifest, run, results, &known, fresh).map(|_| ())
                    }
                    _ => compute(case, manifest, run, results, &known),
                };
                bar.inc(1);
                (run.id.clone(), outcome)
            })
            .collect();
        failed.extend(
            outcomes
                .into_iter()
                .filter_map(|(id, outcome)| outcome.err().map(|e| (id, e.to_string()))),
        );
    }
    bar.finish_and_clear();
    if failed.is_empty() {
        Ok(executed)
    } else {
        Err(InputError::InvalidInput(format!(
            "{} of {} runs failed:\n  {}",
            failed.len(),
            executed.computed,
            failures_by_message(&failed).join("\n  ")
        )))
    }
}

/// The failures (run id, message) grouped by message, in the order of their first run: "run
/// A: message" for one run, "runs A, B and C: message" for a few, the first three and how many
/// more for many (a case that cannot run fails every run the same way).
fn failures_by_message(failed: &[(String, String)]) -> Vec<String> {
    let mut groups: Vec<(&str, Vec<&str>)> = Vec::new();
    for (id, message) in failed {
        match groups.iter_mut().find(|(known, _)| *known == message) {
            Some((_, ids)) => ids.push(id),
            None => groups.push((message, vec![id])),
        }
    }
    groups
        .into_iter()
        .map(|(message, ids)| match ids.as_slice() {
            [one] => format!("run {one}: {message}"),
            [first @ .., last] if ids.len() <= 4 => {
                format!("runs {} and {last}: {message}", first.join(", "))
            }
            _ => format!(
                "runs {} and {} more: {message}",
                ids[..3].join(", "),
                ids.len() - 3
            ),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::failures_by_message;

    fn failures(list: &[(&str, &str)]) -> Vec<(String, String)> {
        list.iter()
            .map(|(id, message)| (id.to_string(), message.to_string()))
            .collect()
    }

    #[test]
    fn run_failures_with_one_message_are_listed_once() {
        let same: Vec<(String, String)> = (0..12)
            .map(|i| {
                (
                    format!("r{i}"),
                    "case `c.toml`, key `exact`: bad".to_string(),
                )
            })
            .collect();
        assert_eq!(
            failures_by_message(&same),
            ["runs r0, r1, r2 and 9 more: case `c.toml`, key `exact`: bad"]
        );
        assert_eq!(
            failures_by_message(&failures(&[("a", "x"), ("b", "y"), ("c", "x"), ("d", "x")])),
            ["runs a, c and d: x", "run b: y"]
        );
    }
}
