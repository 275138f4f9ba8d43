//! Merges the stored results of a manifest into its studies (rates and verdicts), and writes the
//! reports: the one entry point through which both a single-process `verify` and `verify merge`
//! write every report file.

use crate::case::parse_case_file;
use crate::report::write_reports;
use crate::study::{level_study_result, time_study_result, StudyKind, StudyResult, Verdict};
use crate::sweep::cache::{load_run, result_path, Stored};
use crate::sweep::plan::Manifest;
use crate::InputError;
use std::path::{Path, PathBuf};

/// The studies of a manifest from its stored results.
#[derive(Debug)]
pub struct Merged {
    /// The studies all of whose runs have a valid result.
    pub studies: Vec<StudyResult>,
    /// The runs without a valid result, each as `run ID: reason`; a study with such a run is
    /// not in `studies`.
    pub problems: Vec<String>,
}

impl Merged {
    /// The verdict of all studies ([`Verdict::combine`]); meaningful when no run lacks a
    /// result (`problems` is empty).
    pub fn verdict(&self) -> Verdict {
        Verdict::combine(self.studies.iter().map(|s| s.verdict))
    }
}

/// Collects the results of the studies of `manifest` from `results`: a missing or invalid
/// result is named by its run's id, never merged.
pub fn merge(manifest: &Manifest, results: &Path) -> Result<Merged, InputError> {
    let file = parse_case_file(&manifest.case_text, &manifest.origin)?;
    let mut merged = Merged {
        studies: Vec::new(),
        problems: Vec::new(),
    };
    for study in &manifest.studies {
        let mut runs = Vec::new();
        for id in &study.runs {
            let run = manifest.run(id).ok_or_else(|| {
                InputError::InvalidInput(format!("manifest: study run `{id}` is not listed"))
            })?;
            let path = result_path(results, run);
            let problem = match load_run(results, run) {
                Stored::Valid(result) => {
                    runs.push(result);
                    continue;
                }
                Stored::Missing => format!(
                    "run {id} (index {}): missing ({} does not exist)",
                    run.index,
                    path.display()
                ),
                Stored::Invalid(reason) => format!(
                    "run {id} (index {}): invalid result {}: {reason}",
                    run.index,
                    path.display()
                ),
            };
            // a run shared by two studies is named once
            if !merged.problems.contains(&problem) {
                merged.problems.push(problem);
            }
        }
        if runs.len() != study.runs.len() {
            continue;
        }
        merged.studies.push(match study.kind {
            StudyKind::K => {
                let reference_steps = study.reference_steps.unwrap_or(0);
                if reference_steps == 0 {
                    return Err(InputError::InvalidInput(
                        "manifest: a k-study without `reference_steps`".to_string(),
                    ));
                }
                let reference_k = file.final_time / reference_steps as f64;
                time_study_result(manifest.degree, reference_k, runs)
            }
            kind => level_study_result(kind, manifest.degree, runs),
        });
    }
    Ok(merged)
}

/// Writes every report file of the studies of `manifest` into `out` (through
/// [`write_reports`]); returns the written paths.
pub fn write_study_reports(
    out: &Path,
    manifest: &Manifest,
    studies: &[StudyResult],
) -> Result<Vec<PathBuf>, InputError> {
    write_reports(out, &manifest.case, &manifest.origin, manifest.dim, studies)
}
