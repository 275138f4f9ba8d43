//! The manifest of a study: every run of the selected studies of one case and degree, each with
//! a stable id, its parameters, an estimated relative cost and a digest of everything its result
//! depends on.

use crate::case::{parse_case_file, CaseFile, LevelStudy, TimeStudy};
use crate::study::StudyKind;
use crate::InputError;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::Path;

/// The format tag of a manifest file.
pub const MANIFEST_FORMAT: &str = "verify-manifest/1";

/// What a result depends on besides its parameters: the version of the harness, a fingerprint
/// of the sources of the solver, the input layer and the harness and of the locked dependencies
/// (computed by the build script), and the version of the result format. Part of every digest:
/// results cached by a build of other code are recomputed, not reused.
pub const CODE_VERSION: &str = concat!(
    "verify ",
    env!("CARGO_PKG_VERSION"),
    "; sources ",
    env!("VERIFY_SOURCE_FINGERPRINT"),
    "; result format 1"
);

/// What a run computes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RunKind {
    /// A run measured against the exact (manufactured) solution (h- and diagonal studies).
    Exact,
    /// The reference run of a k-study: its states every `stride` steps are stored.
    Reference,
    /// A k-study level measured against the states of its reference run.
    AgainstReference,
}

/// One run of a manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlannedRun {
    /// Position in the manifest (the `--index` of `verify run`).
    pub index: usize,
    /// Stable id, from the parameters (e.g. `l1-c8-n32`, `l1-c16-n4-ref128`, `l1-c16-ref128`).
    pub id: String,
    /// What the run computes.
    pub kind: RunKind,
    /// Cells per side.
    pub cells: usize,
    /// Time steps N.
    pub steps: usize,
    /// For a reference run: the stored states are those of the steps that are multiples of this.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stride: Option<usize>,
    /// For a run against a reference: the id of that reference run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference: Option<String>,
    /// Estimated relative cost: velocity unknowns × steps.
    pub cost: f64,
    /// SHA-256 (hex) of everything the result depends on ([`run_digest`]).
    pub digest: String,
    /// The studies that use the run, as `kind:level` (level 0 the coarsest).
    pub used_by: Vec<String>,
}

/// One study of a manifest: the ids of its runs, coarsest first.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlannedStudy {
    /// h, k or diagonal.
    pub kind: StudyKind,
    /// The runs of its levels, coarsest first.
    pub runs: Vec<String>,
    /// For a k-study: the id of its reference run and its number of steps.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference: Option<String>,
    /// For a k-study: the reference's number of steps.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_steps: Option<usize>,
}

/// The manifest of a study: self-contained (it holds the case file's text), so that any
/// machine can run any of its runs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// [`MANIFEST_FORMAT`].
    pub format: String,
    /// Case name.
    pub case: String,
    /// Where the case came from (a path or `built-in:NAME`).
    pub origin: String,
    /// Space dimension.
    pub dim: usize,
    /// Polynomial degree l.
    pub degree: usize,
    /// [`CODE_VERSION`] of the planning program.
    pub code_version: String,
    /// The case file's text.
    pub case_text: String,
    /// The studies, in the order of `--studies`.
    pub studies: Vec<PlannedStudy>,
    /// The runs, each once (a run shared by two studies, e.g. the coarsest level of the h- and
    /// the diagonal study, is listed once).
    pub runs: Vec<PlannedRun>,
}

/// The lowercase hex form of bytes.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// SHA-256 of bytes, in hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

/// The content of a case file that results depend on: its TOML with the `[studies]` table
/// removed (the levels of a run are its own parameters), written canonically (sorted keys, no
/// comments or layout), so that editing a study's levels or a comment invalidates no other run.
pub fn case_content(text: &str, origin: &str) -> Result<String, InputError> {
    let mut table: toml::Table = text.parse().map_err(|e: toml::de::Error| {
        InputError::InvalidInput(format!("{origin}: not a TOML file: {e}"))
    })?;
    table.remove("studies");
    serde_json::to_string(&table)
        .map_err(|e| InputError::InvalidInput(format!("{origin}: cannot canonicalize: {e}")))
}

/// The digest of a run: SHA-256 of the canonical case content ([`case_content`]), the
/// dimension, the degree, the run's kind, cells, steps, stride, its reference's digest (for a
/// run against a reference) and [`CODE_VERSION`].
#[allow(clippy::too_many_arguments)]
pub fn run_digest(
    content: &str,
    dim: usize,
    degree: usize,
    kind: RunKind,
    cells: usize,
    steps: usize,
    stride: Option<usize>,
    reference_digest: Option<&str>,
) -> String {
    let key = serde_json::json!({
        "code": CODE_VERSION,
        "case": content,
        "dim": dim,
        "degree": degree,
        "kind": kind,
        "cells": cells,
        "steps": steps,
        "stride": stride,
        "reference": reference_digest,
    });
    sha256_hex(key.to_string().as_bytes())
}

/// Estimated relative cost of a run: velocity unknowns d·(l·c + 1)^d times steps.
pub fn estimated_cost(dim: usize, degree: usize, cells: usize, steps: usize) -> f64 {
    dim as f64 * ((degree * cells + 1) as f64).powi(dim as i32) * steps as f64
}

fn greatest_common_divisor(a: usize, b: usize) -> usize {
    if b == 0 {
        a
    } else {
        greatest_common_divisor(b, a % b)
    }
}

/// Builds manifests; adds each run once.
struct Planner {
    content: String,
    dim: usize,
    degree: usize,
    runs: Vec<PlannedRun>,
}

impl Planner {
    fn add(
        &mut self,
        kind: RunKind,
        cells: usize,
        steps: usize,
        stride: Option<usize>,
        reference: Option<&PlannedRun>,
        user: String,
    ) -> PlannedRun {
        let digest = run_digest(
            &self.content,
            self.dim,
            self.degree,
            kind,
            cells,
            steps,
            stride,
            reference.map(|r| r.digest.as_str()),
        );
        if let Some(run) = self.runs.iter_mut().find(|r| r.digest == digest) {
            run.used_by.push(user);
            return run.clone();
        }
        let l = self.degree;
        let id = match (kind, reference) {
            (RunKind::Exact, _) => format!("l{l}-c{cells}-n{steps}"),
            (RunKind::Reference, _) => format!("l{l}-c{cells}-ref{steps}"),
            (RunKind::AgainstReference, Some(r)) => {
                format!("l{l}-c{cells}-n{steps}-ref{}", r.steps)
            }
            (RunKind::AgainstReference, None) => format!("l{l}-c{cells}-n{steps}-ref"),
        };
        let run = PlannedRun {
            index: self.runs.len(),
            id,
            kind,
            cells,
            steps,
            stride,
            reference: reference.map(|r| r.id.clone()),
            cost: estimated_cost(self.dim, self.degree, cells, steps),
            digest,
            used_by: vec![user],
        };
        self.runs.push(run.clone());
        run
    }
}

fn truncate<T: Clone>(values: &[T], levels: Option<usize>) -> Vec<T> {
    match levels {
        Some(n) => values[..n.min(values.len())].to_vec(),
        None => values.to_vec(),
    }
}

fn check_level_study(kind: StudyKind, degree: usize, study: &LevelStudy) -> Result<(), InputError> {
    if study.levels().len() != study.steps.len() || study.levels().len() < 2 {
        return Err(InputError::InvalidInput(format!(
            "{} study of order {degree}: `cells` (or `refinements`) and `steps` need the same length ≥ 2",
            kind.name()
        )));
    }
    Ok(())
}

fn check_time_study(degree: usize, study: &TimeStudy) -> Result<(), InputError> {
    if study.steps.len() < 2
        || study
            .steps
            .iter()
            .any(|&s| s == 0 || study.reference_steps % s != 0)
    {
        return Err(InputError::InvalidInput(format!(
            "k study of order {degree}: `reference_steps` = {} must be a multiple of every entry of `steps` {:?} (at least two levels)",
            study.reference_steps, study.steps
        )));
    }
    Ok(())
}

/// Plans the studies `studies` (names h, k, diagonal) of the case `text` (from `origin`) for
/// degree `degree`, each cut to its first `levels` levels.
pub fn plan(
    text: &str,
    origin: &str,
    degree: usize,
    studies: &[String],
    levels: Option<usize>,
) -> Result<Manifest, InputError> {
    let file: CaseFile = parse_case_file(text, origin)?;
    let key = format!("order{degree}");
    let set = file.studies.get(&key).ok_or_else(|| {
        InputError::InvalidInput(format!(
            "case `{origin}` defines no studies for l = {degree} (no [studies.{key}])"
        ))
    })?;
    let mut content = case_content(text, origin)?;
    if let Some(mesh) = &file.domain.mesh {
        // the results depend on the mesh file as much as on the case file
        let (bytes, _) = crate::domain::mesh_file(mesh, origin)?;
        content.push_str(&format!("\nmesh {}", sha256_hex(&bytes)));
    }
    let mut planner = Planner {
        content,
        dim: file.dim,
        degree,
        runs: Vec::new(),
    };
    let mut planned = Vec::new();
    for name in studies {
        match name.as_str() {
            "h" | "diagonal" => {
                let (kind, study) = if name == "h" {
                    (StudyKind::H, &set.h)
                } else {
                    (StudyKind::Diagonal, &set.diagonal)
                };
                let Some(study) = study else { continue };
                check_level_study(kind, degree, study)?;
                let cells = truncate(study.levels(), levels);
                let steps = truncate(&study.steps, levels);
                let runs = cells
                    .iter()
                    .zip(&steps)
                    .enumerate()
                    .map(|(level, (&c, &n))| {
                        let user = format!("{name}:{level}");
                        planner.add(RunKind::Exact, c, n, None, None, user).id
                    })
                    .collect();
                planned.push(PlannedStudy {
                    kind,
                    runs,
                    reference: None,
                    reference_steps: None,
                });
            }
            "k" => {
                let Some(study) = &set.k else { continue };
                check_time_study(degree, study)?;
                let steps = truncate(&study.steps, levels);
                let stride = steps
                    .iter()
                    .map(|&s| study.reference_steps / s)
                    .fold(0, greatest_common_divisor);
                let reference = planner.add(
                    RunKind::Reference,
                    study.level(),
                    study.reference_steps,
                    Some(stride),
                    None,
                    "k:reference".to_string(),
                );
                let runs = steps
                    .iter()
                    .enumerate()
                    .map(|(level, &n)| {
                        let user = format!("k:{level}");
                        let kind = RunKind::AgainstReference;
                        planner
                            .add(kind, study.level(), n, None, Some(&reference), user)
                            .id
                    })
                    .collect();
                planned.push(PlannedStudy {
                    kind: StudyKind::K,
                    runs,
                    reference: Some(reference.id),
                    reference_steps: Some(study.reference_steps),
                });
            }
            other => {
                return Err(InputError::InvalidInput(format!(
                    "--studies: unknown study `{other}` (use h, k, diagonal, comma-separated)"
                )))
            }
        }
    }
    Ok(Manifest {
        format: MANIFEST_FORMAT.to_string(),
        case: file.name,
        origin: origin.to_string(),
        dim: file.dim,
        degree,
        code_version: CODE_VERSION.to_string(),
        case_text: text.to_string(),
        studies: planned,
        runs: planner.runs,
    })
}

impl Manifest {
    /// The run with id `id`.
    pub fn run(&self, id: &str) -> Option<&PlannedRun> {
        self.runs.iter().find(|r| r.id == id)
    }

    /// Checks a manifest read from `path`: its format and code version, the case text, and
    /// that every run's digest and index are those its parameters give (a manifest edited by
    /// hand, or planned by another version, is refused).
    pub fn check(&self, path: &Path) -> Result<(), InputError> {
        let refuse = |message: String| {
            InputError::InvalidInput(format!("manifest `{}`: {message}", path.display()))
        };
        if self.format != MANIFEST_FORMAT {
            return Err(refuse(format!(
                "format `{}`, expected `{MANIFEST_FORMAT}`",
                self.format
            )));
        }
        if self.code_version != CODE_VERSION {
            return Err(refuse(format!(
                "planned by `{}`, this is `{CODE_VERSION}`: plan again",
                self.code_version
            )));
        }
        let names: Vec<String> = self
            .studies
            .iter()
            .map(|s| s.kind.name().to_string())
            .collect();
        let levels = self.studies.iter().map(|s| s.runs.len()).max();
        let again = plan(&self.case_text, &self.origin, self.degree, &names, levels)
            .map_err(|e| refuse(format!("case_text: {e}")))?;
        for (run, planned) in self.runs.iter().zip(&again.runs) {
            if run != planned {
                return Err(refuse(format!(
                    "run {} (index {}) does not match its parameters (edited by hand?): plan again",
                    run.id, run.index
                )));
            }
        }
        if self.runs.len() != again.runs.len() || self.studies != again.studies {
            return Err(refuse(
                "its runs or studies do not match its case and options: plan again".to_string(),
            ));
        }
        Ok(())
    }
}

/// Writes a manifest (pretty JSON, atomically).
pub fn write_manifest(path: &Path, manifest: &Manifest) -> Result<(), InputError> {
    crate::output::write_json_atomic(path, manifest)
}

/// Reads and checks a manifest ([`Manifest::check`]).
pub fn read_manifest(path: &Path) -> Result<Manifest, InputError> {
    contact_input::regular::check_regular_file(path, "manifest")?;
    let text = std::fs::read_to_string(path)
        .map_err(|e| InputError::io("reading the manifest", path, e))?;
    let manifest: Manifest = serde_json::from_str(&text).map_err(|e| {
        InputError::InvalidInput(format!(
            "manifest `{}`: not a manifest of `verify plan`: {e}",
            path.display()
        ))
    })?;
    manifest.check(path)?;
    Ok(manifest)
}

#[cfg(test)]
mod tests {
    use super::*;

    const ZONES: &str = include_str!("../../../../verification/zones2d.toml");

    fn all() -> Vec<String> {
        ["h", "k", "diagonal"].map(String::from).to_vec()
    }

    #[test]
    fn shared_runs_are_listed_once_and_ids_are_unique() {
        let manifest = plan(ZONES, "zones2d", 1, &all(), Some(2)).unwrap();
        // h: (4,2),(8,8); diagonal: (4,2),(8,4); k: reference + 2 levels
        assert_eq!(manifest.runs.len(), 6);
        let shared = manifest.run("l1-c4-n2").unwrap();
        assert_eq!(shared.used_by, ["h:0", "diagonal:0"]);
        let mut ids: Vec<&str> = manifest.runs.iter().map(|r| r.id.as_str()).collect();
        ids.sort_unstable();
        ids.dedup();
        assert_eq!(ids.len(), 6);
        let reference = manifest.run("l1-c16-ref128").unwrap();
        // the levels 2 and 4 of 128 steps need every 32nd state
        assert_eq!(reference.stride, Some(32));
    }

    #[test]
    fn the_digest_ignores_studies_and_comments_but_not_the_laws() {
        let a = plan(ZONES, "a", 1, &all(), Some(2)).unwrap();
        let commented = format!("# a comment\n{ZONES}");
        let b = plan(&commented, "b", 1, &all(), Some(2)).unwrap();
        for run in &a.runs {
            assert_eq!(b.run(&run.id).unwrap().digest, run.digest, "{}", run.id);
        }
        // a third level adds runs and keeps the digests of the h- and diagonal runs; the k
        // reference now stores every 16th state instead of every 32nd: it and its levels change
        let more = plan(ZONES, "more", 1, &all(), Some(3)).unwrap();
        for run in &a.runs {
            let digest = &more.run(&run.id).unwrap().digest;
            assert_eq!(
                digest == &run.digest,
                run.kind == RunKind::Exact,
                "{}",
                run.id
            );
        }
        let changed = ZONES.replacen("final_time = ", "final_time = 2.0\n# was ", 1);
        let c = plan(&changed, "c", 1, &all(), Some(2)).unwrap();
        for run in &a.runs {
            assert_ne!(c.run(&run.id).unwrap().digest, run.digest, "{}", run.id);
        }
    }
}
