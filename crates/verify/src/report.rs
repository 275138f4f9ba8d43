//! Reports of a verification: `errors.csv` (one row per run), `rates.csv` (one row per study
//! and error component: pairwise and least-squares rates, standard error, 95 % interval,
//! drift flag, verdict), `summary.json` (everything), one SVG log–log plot per study, and
//! `report.md` and `tables.tex` made from the rows of the two CSV files ([`crate::tables`]),
//! all written atomically by [`write_reports`], the one entry point.
//!
//! No report holds `NaN` or `inf`: a value that does not exist (e.g. the velocity error of a
//! k-study, measured against a discrete reference) is `—` in `errors.csv`, `null` in
//! `summary.json`, and a component without any value is not drawn (nor in the legend).

use crate::error_norms::ErrorComponents;
use crate::output::{
    finite_or_null, format_or_dash, write_atomic, write_csv_atomic, write_json_atomic,
};
use crate::plot::{loglog_svg, ReferenceSlope, Series};
use crate::rows::{ErrorRow, RateRow};
use crate::study::{StudyResult, Verdict, RATE_TOLERANCE};
use crate::tables::{self, StudyHead};
use crate::InputError;
use serde::Serialize;
use std::path::{Path, PathBuf};

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
    /// The verdict of all studies ([`Verdict::combine`]).
    pub verdict: Verdict,
}

/// The file name of the plot of a study.
fn plot_name(study: &StudyResult) -> String {
    format!("{}-l{}.svg", study.kind.name(), study.degree)
}

/// Writes every report file of `studies` into `out`; returns the written paths.
pub fn write_reports(
    out: &Path,
    case: &str,
    origin: &str,
    dim: usize,
    studies: &[StudyResult],
) -> Result<Vec<PathBuf>, InputError> {
    let mut written = Vec::new();
    let rows = error_rows(case, dim, studies);
    written.push(write_csv(out, "errors.csv", &rows)?);
    let rate_rows = rate_rows(case, studies);
    written.push(write_csv(out, "rates.csv", &rate_rows)?);
    written.push(write_summary(out, case, origin, dim, studies)?);
    for study in studies {
        written.push(write_plot(out, case, dim, study)?);
    }
    written.extend(write_tables(
        out, case, origin, dim, studies, &rows, &rate_rows,
    )?);
    Ok(written)
}

/// The rows of `errors.csv`: one per run of every study.
fn error_rows(case: &str, dim: usize, studies: &[StudyResult]) -> Vec<ErrorRow> {
    studies
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
        .collect()
}

/// The `drifting` cell of a CSV row: `yes`, `no`, or `—` when undetermined.
pub(crate) fn drifting_cell(drifting: Option<bool>) -> String {
    match drifting {
        Some(true) => "yes".to_string(),
        Some(false) => "no".to_string(),
        None => crate::output::MISSING.to_string(),
    }
}

/// The rows of `rates.csv`: one per study and error component.
fn rate_rows(case: &str, studies: &[StudyResult]) -> Vec<RateRow> {
    studies
        .iter()
        .flat_map(|study| {
            study.rates.iter().map(move |rates| RateRow {
                case: case.to_string(),
                study: study.kind.name(),
                degree: study.degree,
                variable: study.variable,
                component: rates.component.clone(),
                pairwise: rates
                    .pairwise
                    .iter()
                    .map(|r| format_or_dash(*r, |r| r.to_string()))
                    .collect::<Vec<_>>()
                    .join(";"),
                least_squares: rates.least_squares,
                standard_error: rates.standard_error,
                ci95_low: rates.interval_95.first().copied().unwrap_or(f64::NAN),
                ci95_high: rates.interval_95.get(1).copied().unwrap_or(f64::NAN),
                drifting: drifting_cell(rates.drifting),
                expected: rates.expected.unwrap_or(f64::NAN),
                verdict: match rates.pass {
                    Some(true) => "pass".to_string(),
                    Some(false) => "fail".to_string(),
                    None => crate::output::MISSING.to_string(),
                },
            })
        })
        .collect()
}

/// Writes `rows` as the CSV file `name` of `out`; returns its path.
fn write_csv<T: Serialize>(out: &Path, name: &str, rows: &[T]) -> Result<PathBuf, InputError> {
    let path = out.join(name);
    write_csv_atomic(&path, rows)?;
    Ok(path)
}

/// Writes `summary.json` into `out`; returns its path.
fn write_summary(
    out: &Path,
    case: &str,
    origin: &str,
    dim: usize,
    studies: &[StudyResult],
) -> Result<PathBuf, InputError> {
    let summary = Summary {
        case,
        origin,
        dim,
        rate_tolerance: RATE_TOLERANCE,
        studies,
        verdict: Verdict::combine(studies.iter().map(|s| s.verdict)),
    };
    let json = out.join("summary.json");
    write_json_atomic(&json, &summary)?;
    Ok(json)
}

/// Writes the log–log plot of the errors of `study` into `out`; returns its path.
fn write_plot(
    out: &Path,
    case: &str,
    dim: usize,
    study: &StudyResult,
) -> Result<PathBuf, InputError> {
    let path = out.join(plot_name(study));
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
    Ok(path)
}

/// Writes `report.md` and `tables.tex` into `out`, made from the rows of `errors.csv` and
/// `rates.csv` ([`crate::tables`]); returns their paths.
fn write_tables(
    out: &Path,
    case: &str,
    origin: &str,
    dim: usize,
    studies: &[StudyResult],
    rows: &[ErrorRow],
    rate_rows: &[RateRow],
) -> Result<[PathBuf; 2], InputError> {
    let heads: Vec<StudyHead> = studies
        .iter()
        .map(|study| StudyHead {
            kind: study.kind.name(),
            degree: study.degree,
            variable: study.variable,
            expected: study.expected_rate,
            verdict: study.verdict,
            plot: plot_name(study),
        })
        .collect();
    let md = out.join("report.md");
    let text = tables::markdown(case, origin, dim, RATE_TOLERANCE, &heads, rows, rate_rows);
    write_atomic(&md, text.as_bytes())?;
    let tex = out.join("tables.tex");
    write_atomic(
        &tex,
        tables::latex(case, &heads, rows, rate_rows).as_bytes(),
    )?;
    Ok([md, tex])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::{rates, RunResult, RunStats, StudyKind, Verdict};

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
            verdict: Verdict::of(&rates),
            runs,
            rates,
        }
    }

    #[test]
    fn reports_of_a_k_study_have_no_nan_and_no_velocity_curve() {
        let scratch = tempfile::tempdir().unwrap();
        let written = write_reports(scratch.path(), "test", "inline", 2, &[k_study()]).unwrap();
        assert_eq!(written.len(), 6);
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

    /// A CSV cell as printed in report.md (`missing` = `—`) or tables.tex (`missing` = `--`).
    fn printed(cell: &str, missing: &str, rate: bool) -> String {
        match cell.parse::<f64>() {
            Ok(v) if rate => format!("{v:.3}"),
            Ok(v) => format!("{v:.3e}"),
            Err(_) => {
                assert_eq!(cell, "—");
                missing.to_string()
            }
        }
    }

    #[test]
    fn report_md_and_tables_tex_hold_the_rows_of_the_csv_files() {
        let scratch = tempfile::tempdir().unwrap();
        let mut h_study = k_study();
        h_study.kind = StudyKind::H;
        h_study.variable = "h";
        for (i, run) in h_study.runs.iter_mut().enumerate() {
            run.errors.velocity = 0.3 * run.k * (1.0 + 0.2 * i as f64);
            run.stats.max_velocity_kkt = 1e-12 * (i + 1) as f64;
        }
        h_study.rates = rates(&h_study.runs, |r| r.k, 1.0);
        write_reports(
            scratch.path(),
            "test_case",
            "inline",
            2,
            &[k_study(), h_study],
        )
        .unwrap();
        let md = std::fs::read_to_string(scratch.path().join("report.md")).unwrap();
        let tex = std::fs::read_to_string(scratch.path().join("tables.tex")).unwrap();
        assert!(md.contains("![k-study, l = 1](k-l1.svg)") && md.contains("(h-l1.svg)"));
        assert!(tex.contains("\\toprule") && tex.contains("\\bottomrule"));
        assert!(tex.contains("test\\_case"));

        let read = |name: &str| {
            let text = std::fs::read_to_string(scratch.path().join(name)).unwrap();
            let mut reader = csv::Reader::from_reader(text.as_bytes());
            let header = reader.headers().unwrap().clone();
            let records: Vec<csv::StringRecord> = reader.records().map(|r| r.unwrap()).collect();
            (header, records)
        };
        let (header, records) = read("errors.csv");
        assert_eq!(records.len(), 6);
        let column = |name: &str| header.iter().position(|h| h == name).unwrap();
        for record in &records {
            for (missing, text, separator, end) in
                [("—", &md, " | ", " |"), ("--", &tex, " & ", " \\\\")]
            {
                let mut cells = vec![
                    record[column("cells")].to_string(),
                    record[column("steps")].to_string(),
                ];
                for name in [
                    "h",
                    "k",
                    "displacement",
                    "difference_quotient",
                    "damage",
                    "damage_gradient",
                    "total",
                    "velocity",
                    "max_velocity_kkt",
                    "max_damage_kkt",
                ] {
                    cells.push(printed(&record[column(name)], missing, false));
                }
                let line = cells.join(separator) + end;
                assert!(text.contains(&line), "{line} not in\n{text}");
            }
        }
        let (header, records) = read("rates.csv");
        assert_eq!(records.len(), 12);
        let column = |name: &str| header.iter().position(|h| h == name).unwrap();
        for record in &records {
            for (missing, text, separator) in [("—", &md, " | "), ("--", &tex, " & ")] {
                let pairwise: Vec<String> = record[column("pairwise")]
                    .split(';')
                    .map(|r| printed(r, missing, true))
                    .collect();
                let low = printed(&record[column("ci95_low")], missing, true);
                let high = printed(&record[column("ci95_high")], missing, true);
                let interval = if low == missing {
                    missing.to_string()
                } else {
                    format!("[{low}, {high}]")
                };
                let drifting = match &record[column("drifting")] {
                    "—" => missing.to_string(),
                    other => other.to_string(),
                };
                let verdict = match &record[column("verdict")] {
                    "—" => missing.to_string(),
                    other => other.to_string(),
                };
                let component = if missing == "--" {
                    record[column("component")].replace('_', "\\_")
                } else {
                    record[column("component")].to_string()
                };
                let line = [
                    component,
                    pairwise.join(", "),
                    printed(&record[column("least_squares")], missing, true),
                    printed(&record[column("standard_error")], missing, true),
                    interval,
                    drifting,
                    printed(&record[column("expected")], missing, true),
                    verdict,
                ]
                .join(separator);
                assert!(text.contains(&line), "{line} not in\n{text}");
            }
        }
    }
}
