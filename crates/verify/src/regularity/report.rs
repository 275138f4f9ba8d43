//! The reports of a regularity sweep: `regularity.csv` (one row per value and error component),
//! `regularity.json` (the same with every rate of every study) and `regularity-l<l>.svg` (the
//! observed rates against the exponent, with the theorem's exponent where (5.7) holds, the
//! interpolation rate and the line p = l + 1/2 where the assumptions stop holding).

use std::path::{Path, PathBuf};

use plotters::element::DashedPathElement;
use plotters::prelude::*;
use serde::Serialize;

use super::Sweep;
use crate::output::{format_or_dash, write_atomic, write_csv_atomic, write_json_atomic};
use crate::study::StudyResult;
use crate::InputError;

/// The h-study of one value of a sweep.
#[derive(Debug, Clone, Serialize)]
pub struct SweepPoint {
    /// The value of the swept exponent.
    pub value: f64,
    /// Its h-study.
    pub study: StudyResult,
}

/// One row of `regularity.csv`.
#[derive(Debug, Serialize)]
struct Row {
    constant: String,
    value: f64,
    degree: usize,
    /// s + 1/2 with s the smallest exponent of the case at this value (the swept one or another).
    sobolev_index: f64,
    /// (5.7) holds: s > l + 1/2.
    inside_assumptions: bool,
    /// min(l, (l+1)/2) where the assumptions hold, else `—`.
    theorem_rate: String,
    /// min(l, s − 1/2).
    interpolation_rate: f64,
    component: String,
    least_squares: String,
    standard_error: String,
    finest_pairwise: String,
    drifting: String,
    /// The levels of the fit (cells or refinements), coarsest first.
    levels: String,
}

/// `value` in full, or `—`.
fn number(value: f64) -> String {
    format_or_dash(value, |v| format!("{v}"))
}

fn rows(sweep: &Sweep, points: &[SweepPoint]) -> Vec<Row> {
    let mut rows = Vec::new();
    for point in points {
        let profile = sweep.profile(point.value);
        let degree = point.study.degree;
        let levels: Vec<String> = point
            .study
            .runs
            .iter()
            .map(|run| run.cells.to_string())
            .collect();
        for rates in point.study.rates.iter().filter(|r| !r.is_missing()) {
            rows.push(Row {
                constant: sweep.name.clone(),
                value: point.value,
                degree,
                sobolev_index: profile.sobolev_index(),
                inside_assumptions: profile.inside_assumptions(degree),
                theorem_rate: number(profile.theorem_rate(degree).unwrap_or(f64::NAN)),
                interpolation_rate: profile.interpolation_rate(degree),
                component: rates.component.clone(),
                least_squares: number(rates.least_squares),
                standard_error: number(rates.standard_error),
                finest_pairwise: number(rates.pairwise.last().copied().unwrap_or(f64::NAN)),
                drifting: crate::report::drifting_cell(rates.drifting),
                levels: levels.join(" "),
            });
        }
    }
    rows
}

/// `regularity.json`.
#[derive(Serialize)]
struct Summary<'a> {
    case: &'a str,
    origin: &'a str,
    constant: &'a str,
    degree: usize,
    points: Vec<PointSummary<'a>>,
}

#[derive(Serialize)]
struct PointSummary<'a> {
    value: f64,
    sobolev_index: f64,
    inside_assumptions: bool,
    theorem_rate: Option<f64>,
    interpolation_rate: f64,
    study: &'a StudyResult,
}

/// The names of the files [`write_reports`] writes for degree `degree`.
pub fn report_names(degree: usize) -> [String; 3] {
    [
        "regularity.csv".to_string(),
        "regularity.json".to_string(),
        format!("regularity-l{degree}.svg"),
    ]
}

/// Writes the reports of a sweep of case `case` (from `origin`) at degree `degree` into
/// `out`; returns their paths.
pub fn write_reports(
    out: &Path,
    case: &str,
    origin: &str,
    degree: usize,
    sweep: &Sweep,
    points: &[SweepPoint],
) -> Result<Vec<PathBuf>, InputError> {
    let [csv, json, svg] = report_names(degree).map(|name| out.join(name));
    write_csv_atomic(&csv, &rows(sweep, points))?;
    let summary = Summary {
        case,
        origin,
        constant: &sweep.name,
        degree,
        points: points
            .iter()
            .map(|point| {
                let profile = sweep.profile(point.value);
                PointSummary {
                    value: point.value,
                    sobolev_index: profile.sobolev_index(),
                    inside_assumptions: profile.inside_assumptions(degree),
                    theorem_rate: profile.theorem_rate(degree),
                    interpolation_rate: profile.interpolation_rate(degree),
                    study: &point.study,
                }
            })
            .collect(),
    };
    write_json_atomic(&json, &summary)?;
    rate_svg(&svg, case, degree, sweep, points)?;
    Ok(vec![csv, json, svg])
}

/// The error components that have rates, in the order of the studies.
fn components(points: &[SweepPoint]) -> Vec<&str> {
    points.first().map_or_else(Vec::new, |first| {
        first
            .study
            .rates
            .iter()
            .filter(|r| !r.is_missing())
            .map(|r| r.component.as_str())
            .collect()
    })
}

/// The short name of an error component in the printed table (as in the table of a study).
fn short_name(component: &str) -> &str {
    match component {
        "displacement" => "E_u",
        "difference_quotient" => "E_du",
        "damage" => "E_beta",
        "damage_gradient" => "E_gradb",
        "total" => "E_total",
        "velocity" => "E_v",
        other => other,
    }
}

/// The table printed after a sweep: one line per value, the least-squares rate ± standard
/// error of each component, `*` where the pairwise rates drift.
pub fn table(sweep: &Sweep, points: &[SweepPoint]) -> String {
    let Some(first) = points.first() else {
        return String::new();
    };
    let components = components(points);
    let degree = first.study.degree;
    let mut lines = vec![format!(
        "regularity sweep of {}, l = {degree}: least-squares h-rates ± standard error (* drifting)",
        sweep.name
    )];
    let mut header = format!(
        "{:>6} {:>6} {:>7} {:>7}",
        sweep.name, "(5.7)", "theorem", "interp"
    );
    for component in &components {
        header += &format!(" {:>15}", short_name(component));
    }
    lines.push(header);
    for point in points {
        let profile = sweep.profile(point.value);
        let mut line = format!(
            "{:>6} {:>6} {:>7} {:>7.3}",
            contact_input::number::short(point.value),
            if profile.inside_assumptions(degree) {
                "holds"
            } else {
                "fails"
            },
            format_or_dash(profile.theorem_rate(degree).unwrap_or(f64::NAN), |v| {
                format!("{v:.2}")
            }),
            profile.interpolation_rate(degree)
        );
        for component in &components {
            let cell = match point.study.rates.iter().find(|r| r.component == *component) {
                Some(rates) => format!(
                    "{} ± {}{}",
                    format_or_dash(rates.least_squares, |v| format!("{v:.3}")),
                    format_or_dash(rates.standard_error, |v| format!("{v:.3}")),
                    if rates.drifting == Some(true) {
                        "*"
                    } else {
                        " "
                    }
                ),
                None => crate::output::MISSING.to_string(),
            };
            line += &format!(" {cell:>15}");
        }
        lines.push(line);
    }
    lines.join("\n")
}

/// (exponent, least-squares rate, its standard error or 0) of one component at one value.
type RatePoint = (f64, f64, f64);

/// Per error component, the (exponent, least-squares rate, standard error) of every value whose
/// rate is finite (an undefined standard error drawn as 0).
fn rate_curves(points: &[SweepPoint]) -> Vec<(&str, Vec<RatePoint>)> {
    components(points)
        .into_iter()
        .map(|component| {
            let values = points
                .iter()
                .filter_map(|point| {
                    let rates = point
                        .study
                        .rates
                        .iter()
                        .find(|r| r.component == component)?;
                    rates.least_squares.is_finite().then_some((
                        point.value,
                        rates.least_squares,
                        if rates.standard_error.is_finite() {
                            rates.standard_error
                        } else {
                            0.0
                        },
                    ))
                })
                .collect();
            (component, values)
        })
        .collect()
}

/// The plot of the observed rates against the exponent (linear axes).
fn rate_svg(
    path: &Path,
    case: &str,
    degree: usize,
    sweep: &Sweep,
    points: &[SweepPoint],
) -> Result<(), InputError> {
    let plot_error = |message: String| InputError::Plot {
        path: path.to_path_buf(),
        message,
    };
    let drawing_error = |error: &dyn std::fmt::Display| plot_error(error.to_string());
    if points.is_empty() {
        return Err(plot_error("no value to plot".to_string()));
    }
    let curves = rate_curves(points);
    let (p_low, p_high) = (
        sweep.values.first().copied().unwrap_or(0.0),
        sweep.values.last().copied().unwrap_or(1.0),
    );
    let limit = degree as f64 + 0.5;
    let x_low = p_low.min(limit) - 0.25;
    let x_high = p_high.max(limit) + 0.25;
    let mut y_high = degree as f64 + 0.5;
    let mut y_low: f64 = 0.0;
    for (_, values) in &curves {
        for &(_, rate, error) in values {
            y_high = y_high.max(rate + error + 0.25);
            y_low = y_low.min(rate - error - 0.25);
        }
    }
    let interpolation = |p: f64| sweep.profile(p).interpolation_rate(degree);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (800, 600)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| drawing_error(&e))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!(
                    "{case}: observed h-rate against {}, l = {degree}",
                    sweep.name
                ),
                ("sans-serif", 22),
            )
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(x_low..x_high, y_low..y_high)
            .map_err(|e| drawing_error(&e))?;
        chart
            .configure_mesh()
            .x_desc(format!(
                "exponent {} of the profile (d)₊^{}",
                sweep.name, sweep.name
            ))
            .y_desc("least-squares rate in h (± standard error)")
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 16))
            .draw()
            .map_err(|e| drawing_error(&e))?;
        for (index, (label, values)) in curves.iter().enumerate() {
            let color = Palette99::pick(index).to_rgba();
            chart
                .draw_series(
                    LineSeries::new(
                        values.iter().map(|&(p, r, _)| (p, r)),
                        color.stroke_width(2),
                    )
                    .point_size(4),
                )
                .map_err(|e| drawing_error(&e))?
                .label(*label)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
            chart
                .draw_series(values.iter().map(|&(p, r, e)| {
                    PathElement::new(vec![(p, r - e), (p, r + e)], color.stroke_width(1))
                }))
                .map_err(|e| drawing_error(&e))?;
        }
        // the interpolation rate min(l, p − 1/2), with its kink at p = l + 1/2
        let mut kinked = vec![(x_low, interpolation(x_low))];
        if limit > x_low && limit < x_high {
            kinked.push((limit, interpolation(limit)));
        }
        kinked.push((x_high, interpolation(x_high)));
        let dashed = BLACK.mix(0.6).stroke_width(1);
        chart
            .draw_series(DashedLineSeries::new(kinked, 8, 5, dashed))
            .map_err(|e| drawing_error(&e))?
            .label("interpolation rate min(l, p − 1/2)")
            .legend(move |(x, y)| DashedPathElement::new(vec![(x, y), (x + 20, y)], 5, 3, dashed));
        // Theorem 5.2 where (5.7) holds
        let theorem = crate::study::expected_h_rate(degree);
        let red = RED.mix(0.8).stroke_width(2);
        chart
            .draw_series(LineSeries::new(
                [(limit.max(x_low), theorem), (x_high, theorem)],
                red,
            ))
            .map_err(|e| drawing_error(&e))?
            .label("Theorem 5.2: min(l, (l+1)/2), where (5.7) holds")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], red));
        let grey = BLACK.mix(0.35).stroke_width(1);
        chart
            .draw_series(DashedLineSeries::new(
                [(limit, y_low), (limit, y_high)],
                3,
                3,
                grey,
            ))
            .map_err(|e| drawing_error(&e))?
            .label("p = l + 1/2: (5.7) holds to the right")
            .legend(move |(x, y)| DashedPathElement::new(vec![(x, y), (x + 20, y)], 2, 2, grey));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .label_font(("sans-serif", 13))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(|e| drawing_error(&e))?;
        root.present().map_err(|e| drawing_error(&e))?;
    }
    write_atomic(path, svg.as_bytes())
}
