//! The committed baseline: `reports/<case>/l<order>/`, the reports of the full default studies
//! of every built-in case, whose `errors.csv` the CI rate tests pin the solver to. This module
//! reads the errors of a baseline and lists the values that moved between two of them; `verify
//! baseline` ([`crate::cli`]) regenerates the baseline and prints that list.

use crate::error_norms::ErrorComponents;
use crate::InputError;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The folder of the committed baseline, relative to the repository root.
pub const BASELINE_FOLDER: &str = "reports";

/// The folder of the baseline of `case` at order `order` inside `reports`.
pub fn baseline_path(reports: &Path, case: &str, order: usize) -> PathBuf {
    reports.join(case).join(format!("l{order}"))
}

/// A run of a baseline: the study kind (`h`, `k`, `diagonal`), the level (cells per side or
/// refinements) and the number of steps.
pub type RunKey = (String, usize, usize);

/// The error components of a run in the order of [`ErrorComponents::NAMES`] (None for a value
/// written as `—`).
pub type Components = [Option<f64>; ErrorComponents::NAMES.len()];

/// The errors of every run of one `errors.csv`.
#[derive(Debug, Clone, Default)]
pub struct BaselineErrors {
    /// The rows, by run.
    pub rows: BTreeMap<RunKey, Components>,
}

/// An error that differs between two baselines by more than the tolerance.
#[derive(Debug, Clone, PartialEq)]
pub struct Moved {
    /// The run.
    pub run: RunKey,
    /// The component ([`ErrorComponents::NAMES`]).
    pub component: &'static str,
    /// Its value in the older baseline.
    pub old: Option<f64>,
    /// Its value in the newer one.
    pub new: Option<f64>,
}

/// The comparison of two baselines ([`BaselineErrors::compare`]).
#[derive(Debug, Clone, Default)]
pub struct Comparison {
    /// Runs present in both.
    pub compared: usize,
    /// Runs only in the older one.
    pub only_old: usize,
    /// Runs only in the newer one.
    pub only_new: usize,
    /// The largest relative difference over the compared values (infinite where a value
    /// exists in one baseline only).
    pub largest: f64,
    /// The values whose relative difference exceeds the tolerance.
    pub moved: Vec<Moved>,
}

/// |new − old| / |old|, infinite when exactly one of them has a value, 0 when neither has.
pub fn relative_difference(old: Option<f64>, new: Option<f64>) -> f64 {
    match (old, new) {
        (Some(old), Some(new)) if old == new => 0.0,
        (Some(old), Some(new)) => (new - old).abs() / old.abs().max(f64::MIN_POSITIVE),
        (None, None) => 0.0,
        _ => f64::INFINITY,
    }
}

impl BaselineErrors {
    /// Reads `errors.csv` as written by [`crate::report::write_reports`]; an unreadable file, a
    /// missing column or a value that is neither a number nor `—` is an error naming the file
    /// and the line.
    pub fn read(path: &Path) -> Result<Self, InputError> {
        let bad = |message: String| {
            InputError::InvalidInput(format!("baseline {}: {message}", path.display()))
        };
        let mut reader = csv::Reader::from_path(path).map_err(|e| bad(e.to_string()))?;
        let headers = reader.headers().map_err(|e| bad(e.to_string()))?.clone();
        let column = |name: &str| {
            headers
                .iter()
                .position(|h| h == name)
                .ok_or_else(|| bad(format!("no column `{name}`")))
        };
        let (study, cells, steps) = (column("study")?, column("cells")?, column("steps")?);
        let values: Vec<usize> = ErrorComponents::NAMES
            .iter()
            .map(|name| column(name))
            .collect::<Result<_, _>>()?;
        let mut rows = BTreeMap::new();
        for (index, record) in reader.records().enumerate() {
            // line 1 is the header
            let line = index + 2;
            let record = record.map_err(|e| bad(e.to_string()))?;
            let count = |c: usize| {
                record[c]
                    .parse::<usize>()
                    .map_err(|_| bad(format!("line {line}: `{}` is not a count", &record[c])))
            };
            let key = (record[study].to_string(), count(cells)?, count(steps)?);
            let mut components: Components = [None; ErrorComponents::NAMES.len()];
            for (slot, &c) in components.iter_mut().zip(&values) {
                *slot = match &record[c] {
                    crate::output::MISSING => None,
                    text => Some(text.parse::<f64>().map_err(|_| {
                        bad(format!(
                            "line {line}: `{text}` in column `{}` is not a number",
                            &headers[c]
                        ))
                    })?),
                };
            }
            rows.insert(key, components);
        }
        Ok(Self { rows })
    }

    /// Compares the runs present in both baselines, value by value.
    pub fn compare(&self, newer: &BaselineErrors, tolerance: f64) -> Comparison {
        let mut comparison = Comparison::default();
        for (run, old) in &self.rows {
            let Some(new) = newer.rows.get(run) else {
                comparison.only_old += 1;
                continue;
            };
            comparison.compared += 1;
            for ((component, &old), &new) in ErrorComponents::NAMES.iter().zip(old).zip(new) {
                let difference = relative_difference(old, new);
                comparison.largest = comparison.largest.max(difference);
                if difference > tolerance {
                    comparison.moved.push(Moved {
                        run: run.clone(),
                        component,
                        old,
                        new,
                    });
                }
            }
        }
        comparison.only_new = newer
            .rows
            .keys()
            .filter(|run| !self.rows.contains_key(*run))
            .count();
        comparison
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEADER: &str =
        "case,study,cells,steps,displacement,difference_quotient,damage,damage_gradient,total,velocity,wall_seconds\n";

    fn baseline(rows: &str) -> Result<BaselineErrors, InputError> {
        let scratch = tempfile::tempdir().unwrap();
        let path = scratch.path().join("errors.csv");
        std::fs::write(&path, format!("{HEADER}{rows}")).unwrap();
        BaselineErrors::read(&path)
    }

    #[test]
    fn baseline_comparison_lists_the_values_that_moved() {
        let old = baseline(
            "c,h,4,2,0.1,0.2,0.3,0.4,1.0,—,0.1\nc,h,8,8,0.05,0.1,0.15,0.2,0.5,—,0.2\nc,k,4,2,1,1,1,1,4,—,0\n",
        )
        .unwrap();
        let new = baseline(
            "c,h,4,2,0.1,0.2,0.3,0.4,1.0,—,9.9\nc,h,8,8,0.05,0.1000001,0.15,0.2,0.5,0.7,0.2\nc,h,16,32,1,1,1,1,4,—,0\n",
        )
        .unwrap();
        let comparison = old.compare(&new, 1e-8);
        assert_eq!(
            (
                comparison.compared,
                comparison.only_old,
                comparison.only_new
            ),
            (2, 1, 1)
        );
        assert_eq!(comparison.largest, f64::INFINITY);
        let moved: Vec<(&str, Option<f64>, Option<f64>)> = comparison
            .moved
            .iter()
            .map(|m| (m.component, m.old, m.new))
            .collect();
        assert_eq!(
            moved,
            [
                ("difference_quotient", Some(0.1), Some(0.1000001)),
                ("velocity", None, Some(0.7)),
            ]
        );
        assert_eq!(comparison.moved[0].run, ("h".to_string(), 8, 8));
        // wall time is not an error: its change is not listed
        assert!(old.compare(&old, 0.0).moved.is_empty());
    }

    #[test]
    fn baseline_reader_names_the_line_of_a_bad_value() {
        let error = baseline("c,h,4,2,0.1,oops,0.3,0.4,1.0,—,0.1\n")
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("line 2")
                && error.contains("oops")
                && error.contains("difference_quotient"),
            "{error}"
        );
        let error = baseline("c,h,four,2,0.1,0.2,0.3,0.4,1.0,—,0.1\n")
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("line 2") && error.contains("four"),
            "{error}"
        );
    }
}
