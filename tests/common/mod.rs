//! What the end-to-end tests share: the committed baseline and the comparison of new errors with
//! it (the pinned errors), and Theorem 5.2's rates restated independently of the library.
#![allow(dead_code)]

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use verify::case::{parse_case_file, Case};
use verify::cli::BUILT_IN_CASES;
use verify::error_norms::ErrorComponents;
use verify::study::{RunResult, StudyKind, StudyResult};

/// Relative tolerance of the pinned errors. One-ulp perturbations of the law constants move
/// the errors of the built-in studies by at most about 1e-12 relative: that is the size of what
/// changes bits between machines (the SIMD width of the dense kernels, the last bit of libm);
/// 1e-8 stays four orders above it. A change of the scheme, of the data or of where a solver
/// stops moves the errors by far more (replacing the damage step's solver by another one with
/// the same stopping rule moves them by up to 4e-7).
pub const PINNED_TOLERANCE: f64 = 1e-8;

/// The exponent of h in Theorem 5.2, min(l, (l + 1)/2), restated: l = 1 → 1, l = 2 → 3/2.
pub fn theorem_h_exponent(order: usize) -> f64 {
    match order {
        1 => 1.0,
        2 => 1.5,
        other => panic!("no Theorem 5.2 exponent for l = {other}"),
    }
}

/// The tolerance of every rate, restated (its justification is that of
/// `verify::study::RATE_TOLERANCE`: ten percent of the smallest expected rate in h).
pub const TOLERANCE: f64 = 0.15;

/// Levels of the least-squares fit, restated.
pub const FIT: usize = 3;

/// The solver's work and the contact zones of a run, pinned exactly: iteration counts of the
/// velocity step (5.1), of its friction problems and of the damage step (5.2), and the steps in
/// which each contact status and each damage bound occurred. They do not depend on round-off
/// (one-ulp perturbations of the law constants leave every count of every built-in study
/// unchanged), and a change of how a solver finds its solution — a Newton direction, a line
/// search, a stopping rule — shows in them even where the solution, certified to its tolerance,
/// does not move.
pub const PINNED_COUNTS: [&str; 9] = [
    "newton_iterations",
    "max_newton_iterations",
    "friction_iterations",
    "damage_iterations",
    "steps_with_separation",
    "steps_with_stick",
    "steps_with_slip",
    "steps_with_lower_bound",
    "steps_with_upper_bound",
];

/// The counts of [`PINNED_COUNTS`] of a run.
pub fn counts(run: &RunResult) -> [usize; 9] {
    let stats = &run.stats;
    [
        stats.newton_iterations,
        stats.max_newton_iterations,
        stats.friction_iterations,
        stats.damage_iterations,
        stats.steps_with_separation,
        stats.steps_with_stick,
        stats.steps_with_slip,
        stats.steps_with_lower_bound,
        stats.steps_with_upper_bound,
    ]
}

/// A row of a baseline.
pub struct BaselineRow {
    /// The error components in the order of `ErrorComponents::NAMES` (None for `—`).
    pub errors: Vec<Option<f64>>,
    /// The counts of [`PINNED_COUNTS`].
    pub counts: Vec<usize>,
}

/// The rows of a baseline by (study, level, steps).
pub type Baseline = BTreeMap<(String, usize, usize), BaselineRow>;

/// The rows of `reports/<case>/l<order>/errors.csv`, read here with the csv crate alone.
pub fn baseline(name: &str, order: usize) -> (PathBuf, Baseline) {
    let path = reports()
        .join(name)
        .join(format!("l{order}"))
        .join("errors.csv");
    let mut reader = csv::Reader::from_path(&path)
        .unwrap_or_else(|e| panic!("the committed baseline {}: {e}", path.display()));
    let headers = reader.headers().unwrap().clone();
    let column = |name: &str| {
        headers
            .iter()
            .position(|h| h == name)
            .unwrap_or_else(|| panic!("{}: no column {name}", path.display()))
    };
    let mut rows = Baseline::new();
    for record in reader.records() {
        let record = record.unwrap();
        let key = (
            record[column("study")].to_string(),
            record[column("cells")].parse().unwrap(),
            record[column("steps")].parse().unwrap(),
        );
        let errors = ErrorComponents::NAMES
            .iter()
            .map(|name| record[column(name)].parse::<f64>().ok())
            .collect();
        let counts = PINNED_COUNTS
            .iter()
            .map(|name| {
                record[column(name)]
                    .parse::<usize>()
                    .unwrap_or_else(|e| panic!("{}: {name}: {e}", path.display()))
            })
            .collect();
        rows.insert(key, BaselineRow { errors, counts });
    }
    (path, rows)
}

/// The differences between the runs of `study` (of case `name`) and the committed baseline:
/// every error component of every run against the baseline row with the same study kind, level
/// and steps (a difference above [`PINNED_TOLERANCE`], relative), and every count of
/// [`PINNED_COUNTS`] (any difference), each as one line naming the row, the quantity and both
/// values; a missing row as one line.
pub fn pinned_mismatches(name: &str, study: &StudyResult) -> Vec<String> {
    let (path, rows) = baseline(name, study.degree);
    let mut mismatches = Vec::new();
    for run in &study.runs {
        let key = (study.kind.name().to_string(), run.cells, run.steps);
        let Some(pinned) = rows.get(&key) else {
            mismatches.push(format!(
                "{}-study level {} with {} steps: no such row in {}",
                key.0,
                key.1,
                key.2,
                path.display()
            ));
            continue;
        };
        for ((component, value), pinned) in ErrorComponents::NAMES
            .iter()
            .zip(run.errors.values())
            .zip(&pinned.errors)
        {
            let now = value.is_finite().then_some(value);
            let agrees = match (now, *pinned) {
                (Some(now), Some(pinned)) => {
                    (now - pinned).abs() <= PINNED_TOLERANCE * pinned.abs()
                }
                (None, None) => true,
                _ => false,
            };
            if !agrees {
                mismatches.push(format!(
                    "{}-study level {} with {} steps, {component}: now {now:?}, baseline {pinned:?}",
                    key.0, key.1, key.2
                ));
            }
        }
        for ((name, now), pinned) in PINNED_COUNTS.iter().zip(counts(run)).zip(&pinned.counts) {
            if now != *pinned {
                mismatches.push(format!(
                    "{}-study level {} with {} steps, {name}: now {now}, baseline {pinned}",
                    key.0, key.1, key.2
                ));
            }
        }
    }
    mismatches
}

/// Fails unless the errors and counts of `study` equal the committed baseline
/// ([`pinned_mismatches`]).
pub fn assert_pinned(name: &str, study: &StudyResult) {
    let mismatches = pinned_mismatches(name, study);
    assert!(
        mismatches.is_empty(),
        "{name} l{}: errors (by more than {PINNED_TOLERANCE:e}, relative) or counts differ from the committed baseline; \
         if the change is intended, regenerate it with `cargo run --release -p verify -- baseline --case {name}` \
         and review the values it lists as moved:\n{}",
        study.degree,
        mismatches.join("\n")
    );
}

/// Least-squares slope of log e against log s.
pub fn slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let (xs, ys): (Vec<f64>, Vec<f64>) = points.iter().map(|(s, e)| (s.ln(), e.ln())).unzip();
    let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
    let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
    sxy / sxx
}

pub fn pairwise(points: &[(f64, f64)]) -> Vec<f64> {
    points
        .windows(2)
        .map(|w| (w[0].1 / w[1].1).ln() / (w[0].0 / w[1].0).ln())
        .collect()
}

/// The verdict of `study` recomputed from its runs with the restated exponent and tolerance;
/// `reference_k` is the time step of a k-study's reference run. Returns the reasons it fails.
pub fn restated_check(study: &StudyResult, reference_k: Option<f64>) -> Vec<String> {
    let runs = &study.runs;
    assert!(runs.len() >= FIT, "a certified study needs {FIT} levels");
    let fit = &runs[runs.len() - FIT..];
    let exponent = theorem_h_exponent(study.degree);
    // the size a rate is measured in: h, or k − k_ref for a k-study (whose reference run
    // carries its own first-order error)
    let offset = match study.kind {
        StudyKind::K => reference_k.expect("a k-study has a reference"),
        _ => 0.0,
    };
    let size = |r: &RunResult| match study.kind {
        StudyKind::K => r.k - offset,
        _ => r.h,
    };
    let expected = match study.kind {
        StudyKind::H => exponent,
        StudyKind::K => 1.0,
        // k ∝ h^r converges like h^min(r, exponent)
        StudyKind::Diagonal => {
            exponent.min(slope(&fit.iter().map(|r| (r.h, r.k)).collect::<Vec<_>>()))
        }
    };
    assert!(
        (study.expected_rate - expected).abs() < 1e-12,
        "{}-study l={}: the library expects {}, Theorem 5.2 gives {expected}",
        study.kind.name(),
        study.degree,
        study.expected_rate
    );
    let mut failures = Vec::new();
    // the four terms of E(h, k) and their sum; the velocity error is not bounded by the theorem
    for component in ErrorComponents::NAMES.iter().filter(|c| **c != "velocity") {
        let index = ErrorComponents::NAMES
            .iter()
            .position(|c| c == component)
            .unwrap();
        let points: Vec<(f64, f64)> = fit
            .iter()
            .map(|r| (size(r), r.errors.values()[index]))
            .collect();
        let fitted = slope(&points);
        let rates = pairwise(&points);
        let finest = rates[rates.len() - 1];
        if !(fitted >= expected - TOLERANCE && finest >= expected - TOLERANCE) {
            failures.push(format!(
                "{component}: least squares {fitted:.3}, finest pairwise {finest:.3}, expected {expected:.3} − {TOLERANCE}"
            ));
        }
        if *component == "total" {
            let spread = rates.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                - rates.iter().copied().fold(f64::INFINITY, f64::min);
            if spread > TOLERANCE {
                failures.push(format!(
                    "total: pairwise rates {rates:.3?} over the fit differ by {spread:.3} > {TOLERANCE}: not in the asymptotic range"
                ));
            }
        }
    }
    failures
}

pub fn case<const D: usize>(name: &str) -> Case<D> {
    let (_, text) = BUILT_IN_CASES
        .iter()
        .find(|(n, _)| *n == name)
        .expect("built-in case");
    let origin = format!("built-in:{name}");
    Case::new(parse_case_file(text, &origin).unwrap(), &origin).unwrap()
}

pub fn reports() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../reports")
}
