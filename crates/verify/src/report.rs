//! Reports of a verification: `errors.csv` (one row per run), `summary.json` (everything), and
//! one SVG log–log plot per study, all written atomically.
//!
//! No report holds `NaN` or `inf`: a value that does not exist (e.g. the velocity error of a
//! k-study, measured against a discrete reference) is `—` in `errors.csv`, `null` in
//! `summary.json`, and a component without any value is not drawn (nor in the legend).

use crate::errors::ErrorComponents;
use crate::output::{
    finite_or_dash, finite_or_null, format_or_dash, write_csv_atomic, write_json_atomic,
};
use crate::plot::{loglog_svg, ReferenceSlope, Series};
use crate::study::{StudyResult, RATE_TOLERANCE};
use crate::VerifyError;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// One row of `errors.csv`. A cell without a value (not finite) is written as
/// [`MISSING`](crate::output::MISSING) (`—`).
#[derive(Debug, Serialize)]
pub struct ErrorRow {
    /// Case name.
    pub case: String,
    /// Study kind.
    pub study: &'static str,
    /// Dimension.
    pub dim: usize,
    /// Degree l.
    pub degree: usize,
    /// The level: cells per side (box) or refinements of the Gmsh mesh.
    pub cells: usize,
    /// h.
    #[serde(serialize_with = "finite_or_dash")]
    pub h: f64,
    /// Cells of the mesh.
    pub mesh_cells: usize,
    /// Shape-regularity measure of the mesh (max h_K/ρ_K, normalized).
    #[serde(serialize_with = "finite_or_dash")]
    pub shape_regularity: f64,
    /// N.
    pub steps: usize,
    /// k.
    #[serde(serialize_with = "finite_or_dash")]
    pub k: f64,
    /// Components.
    #[serde(serialize_with = "finite_or_dash")]
    pub displacement: f64,
    /// See [`ErrorComponents`].
    #[serde(serialize_with = "finite_or_dash")]
    pub difference_quotient: f64,
    /// See [`ErrorComponents`].
    #[serde(serialize_with = "finite_or_dash")]
    pub damage: f64,
    /// See [`ErrorComponents`].
    #[serde(serialize_with = "finite_or_dash")]
    pub damage_gradient: f64,
    /// E(h, k).
    #[serde(serialize_with = "finite_or_dash")]
    pub total: f64,
    /// Velocity error.
    #[serde(serialize_with = "finite_or_dash")]
    pub velocity: f64,
    /// Velocity unknowns.
    pub velocity_unknowns: usize,
    /// Largest KKT residual, velocity step.
    #[serde(serialize_with = "finite_or_dash")]
    pub max_velocity_kkt: f64,
    /// Largest KKT residual, damage step.
    #[serde(serialize_with = "finite_or_dash")]
    pub max_damage_kkt: f64,
    /// Newton iterations of the velocity steps (5.1), all steps together.
    pub newton_iterations: usize,
    /// Newton iterations of one velocity step, mean over the steps.
    #[serde(serialize_with = "finite_or_dash")]
    pub mean_newton_iterations: f64,
    /// Newton iterations of one velocity step, the most over the steps.
    pub max_newton_iterations: usize,
    /// Friction semismooth Newton iterations.
    pub friction_iterations: usize,
    /// Damage active-set iterations.
    pub damage_iterations: usize,
    /// Steps with separation / stick / slip / β = 0 active / β = 1 active.
    pub steps_with_separation: usize,
    /// See above.
    pub steps_with_stick: usize,
    /// See above.
    pub steps_with_slip: usize,
    /// See above.
    pub steps_with_lower_bound: usize,
    /// See above.
    pub steps_with_upper_bound: usize,
    /// Seconds.
    #[serde(serialize_with = "finite_or_dash")]
    pub wall_seconds: f64,
}

/// `summary.json`.
#[derive(Debug, Serialize)]
pub struct Summary<'a> {
    /// Case name.
    pub case: &'a str,
    /// Where the case came from.
    pub origin: &'a str,
    /// Dimension.
    pub dim: usize,
    /// The tolerance of every verdict.
    #[serde(serialize_with = "finite_or_null")]
    pub rate_tolerance: f64,
    /// Studies.
    pub studies: &'a [StudyResult],
    /// True when every study passes.
    pub pass: bool,
}

/// Writes every report file of `studies` into `out`; returns the written paths.
pub fn write_reports(
    out: &Path,
    case: &str,
    origin: &str,
    dim: usize,
    studies: &[StudyResult],
) -> Result<Vec<PathBuf>, VerifyError> {
    let mut written = Vec::new();
    let rows: Vec<ErrorRow> = studies
        .iter()
        .flat_map(|study| {
            study.runs.iter().map(move |run| ErrorRow {
                case: case.to_string(),
                study: study.kind.name(),
                dim,
                degree: study.degree,
                cells: run.cells,
                h: run.h,
                mesh_cells: run.mesh_cells,
                shape_regularity: run.shape_regularity,
                steps: run.steps,
                k: run.k,
                displacement: run.errors.displacement,
                difference_quotient: run.errors.difference_quotient,
                damage: run.errors.damage,
                damage_gradient: run.errors.damage_gradient,
                total: run.errors.total,
                velocity: run.errors.velocity,
                velocity_unknowns: run.stats.velocity_unknowns,
                max_velocity_kkt: run.stats.max_velocity_kkt,
                max_damage_kkt: run.stats.max_damage_kkt,
                newton_iterations: run.stats.newton_iterations,
                mean_newton_iterations: run.stats.mean_newton_iterations,
                max_newton_iterations: run.stats.max_newton_iterations,
                friction_iterations: run.stats.friction_iterations,
                damage_iterations: run.stats.damage_iterations,
                steps_with_separation: run.stats.steps_with_separation,
                steps_with_stick: run.stats.steps_with_stick,
                steps_with_slip: run.stats.steps_with_slip,
                steps_with_lower_bound: run.stats.steps_with_lower_bound,
                steps_with_upper_bound: run.stats.steps_with_upper_bound,
                wall_seconds: run.stats.wall_seconds,
            })
        })
        .collect();
    let csv = out.join("errors.csv");
    write_csv_atomic(&csv, &rows)?;
    written.push(csv);
    let summary = Summary {
        case,
        origin,
        dim,
        rate_tolerance: RATE_TOLERANCE,
        studies,
        pass: studies.iter().all(|s| s.pass),
    };
    let json = out.join("summary.json");
    write_json_atomic(&json, &summary)?;
    written.push(json);
    for study in studies {
        let path = out.join(format!("{}-l{}.svg", study.kind.name(), study.degree));
        // a component without any value (the velocity error of a k-study) is left out, and
        // with it its legend entry; `loglog_svg` skips single points without a value
        let series: Vec<Series> = ErrorComponents::NAMES
            .iter()
            .enumerate()
            .filter(|(c, _)| study.runs.iter().any(|r| r.errors.values()[*c].is_finite()))
            .map(|(c, name)| Series {
                label: name.replace('_', " "),
                points: study
                    .runs
                    .iter()
                    .map(|r| {
                        (
                            if study.variable == "h" { r.h } else { r.k },
                            r.errors.values()[c],
                        )
                    })
                    .collect(),
            })
            .collect();
        let title = format!(
            "{case}: {}-study, d = {dim}, l = {} (expected rate {})",
            study.kind.name(),
            study.degree,
            format_or_dash(study.expected_rate, |rate| format!("{rate:.2}"))
        );
        let mut references = Vec::new();
        if study.expected_rate.is_finite() {
            references.push(ReferenceSlope::order(study.expected_rate, study.variable));
        }
        if study.variable == "h" && (study.expected_rate - 1.0).abs() > 1e-12 {
            references.push(ReferenceSlope::order(1.0, study.variable));
        }
        loglog_svg(&path, &title, study.variable, "error", &series, &references)?;
        written.push(path);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::{rates, RunResult, RunStats, StudyKind};

    /// A k-study whose velocity error has no value (its reference is discrete).
    fn k_study() -> StudyResult {
        let runs: Vec<RunResult> = [0.5, 0.25, 0.125]
            .iter()
            .map(|&k| RunResult {
                cells: 4,
                h: 0.35,
                mesh_cells: 32,
                shape_regularity: 1.2,
                steps: (1.0 / k) as usize,
                k,
                errors: ErrorComponents {
                    displacement: k,
                    difference_quotient: 2.0 * k,
                    damage: 0.5 * k,
                    damage_gradient: k,
                    total: 4.5 * k,
                    velocity: f64::NAN,
                },
                stats: RunStats {
                    newton_iterations: 3,
                    mean_newton_iterations: 1.5,
                    max_newton_iterations: 2,
                    slowest_newton_history: vec![1e-4, 1e-12],
                    ..RunStats::default()
                },
            })
            .collect();
        let rates = rates(&runs, |r| r.k, 1.0);
        StudyResult {
            kind: StudyKind::K,
            degree: 1,
            variable: "k",
            expected_rate: 1.0,
            pass: rates.iter().all(|r| r.pass != Some(false)),
            runs,
            rates,
        }
    }

    #[test]
    fn reports_of_a_k_study_have_no_nan_and_no_velocity_curve() {
        let scratch = tempfile::tempdir().unwrap();
        let written = write_reports(scratch.path(), "test", "inline", 2, &[k_study()]).unwrap();
        assert_eq!(written.len(), 3);
        for path in &written {
            let text = std::fs::read_to_string(path).unwrap();
            assert!(
                !text.contains("NaN") && !text.contains("inf"),
                "{}: {text}",
                path.display()
            );
        }
        let csv = std::fs::read_to_string(scratch.path().join("errors.csv")).unwrap();
        let mut reader = csv::Reader::from_reader(csv.as_bytes());
        let header = reader.headers().unwrap().clone();
        let column = |name: &str| header.iter().position(|h| h == name).unwrap();
        let records: Vec<csv::StringRecord> = reader.records().map(|r| r.unwrap()).collect();
        assert_eq!(records.len(), 3);
        for record in &records {
            assert_eq!(&record[column("velocity")], "—");
            assert!(record[column("total")].parse::<f64>().is_ok());
            assert_eq!(&record[column("mean_newton_iterations")], "1.5");
            assert_eq!(&record[column("max_newton_iterations")], "2");
        }
        let svg = std::fs::read_to_string(scratch.path().join("k-l1.svg")).unwrap();
        assert!(svg.contains("damage gradient") && !svg.contains("velocity"));
        let json: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(scratch.path().join("summary.json")).unwrap(),
        )
        .unwrap();
        let study = &json["studies"][0];
        assert!(study["runs"][0]["errors"]["velocity"].is_null());
        assert_eq!(study["runs"][0]["stats"]["max_newton_iterations"], 2);
        assert_eq!(study["rates"][5]["component"], "velocity");
        assert!(study["rates"][5]["least_squares"].is_null());
    }
}
