//! Reports of a verification: `errors.csv` (one row per run), `summary.json` (everything), and
//! one SVG log–log plot per study, all written atomically.

use crate::errors::ErrorComponents;
use crate::output::{write_csv_atomic, write_json_atomic};
use crate::plot::{loglog_svg, ReferenceSlope, Series};
use crate::study::{StudyResult, RATE_TOLERANCE};
use crate::VerifyError;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// One row of `errors.csv`.
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
    /// Cells per side.
    pub cells: usize,
    /// h.
    pub h: f64,
    /// N.
    pub steps: usize,
    /// k.
    pub k: f64,
    /// Components.
    pub displacement: f64,
    /// See [`ErrorComponents`].
    pub difference_quotient: f64,
    /// See [`ErrorComponents`].
    pub damage: f64,
    /// See [`ErrorComponents`].
    pub damage_gradient: f64,
    /// E(h, k).
    pub total: f64,
    /// Velocity error.
    pub velocity: f64,
    /// Velocity unknowns.
    pub velocity_unknowns: usize,
    /// Largest KKT residual, velocity step.
    pub max_velocity_kkt: f64,
    /// Largest KKT residual, damage step.
    pub max_damage_kkt: f64,
    /// Newton iterations.
    pub newton_iterations: usize,
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
        let series: Vec<Series> = ErrorComponents::NAMES
            .iter()
            .enumerate()
            .filter(|(_, name)| **name != "velocity" || study.variable == "h")
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
            "{case}: {}-study, d = {dim}, l = {} (expected rate {:.2})",
            study.kind.name(),
            study.degree,
            study.expected_rate
        );
        let mut references = vec![ReferenceSlope::order(study.expected_rate, study.variable)];
        if study.variable == "h" && (study.expected_rate - 1.0).abs() > 1e-12 {
            references.push(ReferenceSlope::order(1.0, study.variable));
        }
        loglog_svg(&path, &title, study.variable, "error", &series, &references)?;
        written.push(path);
    }
    Ok(written)
}
