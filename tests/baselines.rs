//! The committed baselines measure their rates in the asymptotic range (issue 9 item 3).
//!
//! For every study of every committed baseline (`reports/<case>/l<order>/summary.json`, the
//! output of `verify --case <case> --order <order>`), the rate of the total error E(h, k) between
//! its two finest levels must lie within [`DRIFT`] of the least-squares rate over its three
//! finest levels ([`verify::study::FIT_LEVELS`]).
//!
//! Why 0.1: it is the bound issue 9 sets, two thirds of the verdicts' rate tolerance
//! ([`verify::study::RATE_TOLERANCE`] = 0.15). A study whose last pairwise rate differs from its
//! fitted rate by more than that is still moving at the scale at which the verdict compares the
//! fitted rate with Theorem 5.2: the fit then describes coarser, pre-asymptotic levels, and the
//! study needs a finer level before its rate can be read against the theorem.
//!
//! One study is exempt, with its reason: see [`EXEMPT`].

use serde_json::Value;
use std::path::{Path, PathBuf};

/// Largest difference between the finest pairwise rate and the least-squares rate.
const DRIFT: f64 = 0.1;

/// Studies (case, order, study) not required to pass, and why.
const EXEMPT: &[(&str, u64, &str, &str)] = &[(
    "tilted3d",
    2,
    "diagonal",
    "a fourth level (three refinements of the 192-tetrahedron mesh, 98 k tetrahedra) has about \
     400 k P2 unknowns: beyond this machine; its finest pairwise rate (1.48) matches the \
     theorem's 1.5, its fit is drawn up by the coarsest mesh",
)];

fn reports() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../reports")
}

/// (case, order, study kind, last pairwise rate, least-squares rate over the finest levels).
fn studies() -> Vec<(String, u64, String, f64, f64)> {
    let mut found = Vec::new();
    let mut cases: Vec<_> = std::fs::read_dir(reports())
        .expect("reports/ exists")
        .map(|entry| entry.expect("a directory entry").path())
        .collect();
    cases.sort();
    for case in cases {
        for order in 1..=2u64 {
            let path = case.join(format!("l{order}")).join("summary.json");
            let Ok(text) = std::fs::read_to_string(&path) else {
                continue;
            };
            let summary: Value = serde_json::from_str(&text)
                .unwrap_or_else(|error| panic!("{}: {error}", path.display()));
            let name = summary["case"].as_str().expect("case name").to_string();
            for study in summary["studies"].as_array().expect("studies") {
                let kind = study["kind"].as_str().expect("study kind").to_string();
                let variable = study["variable"].as_str().expect("study variable");
                let points: Vec<(f64, f64)> = study["runs"]
                    .as_array()
                    .expect("runs")
                    .iter()
                    .map(|run| {
                        (
                            run[variable].as_f64().expect("h or k"),
                            run["errors"]["total"].as_f64().expect("E(h, k)"),
                        )
                    })
                    .collect();
                let fitted = &points[points.len().saturating_sub(verify::study::FIT_LEVELS)..];
                let [.., (x0, e0), (x1, e1)] = fitted else {
                    panic!("{name} l{order} {kind}: fewer than two levels");
                };
                let pairwise = (e0 / e1).ln() / (x0 / x1).ln();
                found.push((name.clone(), order, kind, pairwise, slope(fitted)));
            }
        }
    }
    found
}

/// Least-squares slope of log e against log x.
fn slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let (xs, ys): (Vec<f64>, Vec<f64>) = points.iter().map(|(x, e)| (x.ln(), e.ln())).unzip();
    let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
    let covariance: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let variance: f64 = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
    covariance / variance
}

#[test]
fn committed_baselines_have_their_finest_rate_within_the_tolerance_of_the_fit() {
    let studies = studies();
    assert!(
        studies.len() >= 70,
        "only {} studies found under {}",
        studies.len(),
        reports().display()
    );
    let drifting: Vec<String> = studies
        .iter()
        .filter(|(case, order, kind, pairwise, fitted)| {
            let exempt = EXEMPT
                .iter()
                .any(|(c, o, k, _)| c == case && o == order && k == kind);
            !exempt && (pairwise - fitted).abs() > DRIFT
        })
        .map(|(case, order, kind, pairwise, fitted)| {
            format!(
                "{case} l{order} {kind}: finest pairwise {pairwise:.2}, least squares {fitted:.2}"
            )
        })
        .collect();
    assert!(
        drifting.is_empty(),
        "studies not yet in the asymptotic range (|pairwise − fit| > {DRIFT}):\n{}",
        drifting.join("\n")
    );
}

#[test]
fn exempt_studies_exist_and_still_drift() {
    // An exemption that is no longer needed (the study was deepened) must be removed.
    let studies = studies();
    for (case, order, kind, why) in EXEMPT {
        let (_, _, _, pairwise, fitted) = studies
            .iter()
            .find(|(c, o, k, _, _)| c == case && o == order && k == kind)
            .unwrap_or_else(|| panic!("exempt study {case} l{order} {kind} not found"));
        assert!(
            (pairwise - fitted).abs() > DRIFT,
            "{case} l{order} {kind} is exempt ({why}) but no longer drifts: remove the exemption"
        );
    }
}
