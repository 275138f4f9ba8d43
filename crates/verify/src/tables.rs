//! `report.md` and `tables.tex` of a verification: the rows of `errors.csv` and `rates.csv`
//! (the same values, formatted with [`sci`]) as Markdown tables with the plots embedded by
//! relative links, and as booktabs LaTeX tables (`\usepackage{booktabs}`).

use crate::output::MISSING;
use crate::rows::{ErrorRow, RateRow};
use crate::study::Verdict;

/// A number as printed in both files: scientific with 3 decimals, or `missing` when not finite.
pub fn sci(value: f64, missing: &str) -> String {
    if value.is_finite() {
        format!("{value:.3e}")
    } else {
        missing.to_string()
    }
}

/// A rate with 3 decimals, or `missing`.
pub fn rate(value: f64, missing: &str) -> String {
    if value.is_finite() {
        format!("{value:.3}")
    } else {
        missing.to_string()
    }
}

/// The cells of a run row: cells, steps, h, k, the six error components, the largest KKT
/// residuals of the velocity and damage steps.
pub fn run_cells(row: &ErrorRow, missing: &str) -> Vec<String> {
    let mut cells = vec![row.cells.to_string(), row.steps.to_string()];
    for value in [
        row.h,
        row.k,
        row.displacement,
        row.difference_quotient,
        row.damage,
        row.damage_gradient,
        row.total,
        row.velocity,
        row.max_velocity_kkt,
        row.max_damage_kkt,
    ] {
        cells.push(sci(value, missing));
    }
    cells
}

/// `text`, or `missing` for the CSV's [`MISSING`].
fn or_missing(text: &str, missing: &str) -> String {
    if text == MISSING {
        missing.to_string()
    } else {
        text.to_string()
    }
}

/// The cells of a rate row: component, pairwise rates, least squares, standard error, 95 %
/// interval, drifting, expected, verdict.
pub fn rate_cells(row: &RateRow, missing: &str) -> Vec<String> {
    let pairwise: Vec<String> = row
        .pairwise
        .split(';')
        .map(|r| {
            r.parse::<f64>()
                .map_or(missing.to_string(), |r| rate(r, missing))
        })
        .collect();
    vec![
        row.component.clone(),
        pairwise.join(", "),
        rate(row.least_squares, missing),
        rate(row.standard_error, missing),
        if row.ci95_low.is_finite() && row.ci95_high.is_finite() {
            format!(
                "[{}, {}]",
                rate(row.ci95_low, missing),
                rate(row.ci95_high, missing)
            )
        } else {
            missing.to_string()
        },
        or_missing(&row.drifting, missing),
        rate(row.expected, missing),
        or_missing(&row.verdict, missing),
    ]
}

const RUN_HEADER: [&str; 12] = [
    "cells",
    "steps",
    "h",
    "k",
    "E_u",
    "E_du",
    "E_beta",
    "E_gradb",
    "E_total",
    "E_v",
    "KKT velocity",
    "KKT damage",
];
const RATE_HEADER: [&str; 8] = [
    "component",
    "pairwise",
    "least squares",
    "std. error",
    "95% interval",
    "drifting",
    "expected",
    "verdict",
];
const TEX_RUN_HEADER: [&str; 12] = [
    "cells",
    "$N$",
    "$h$",
    "$k$",
    "$E_u$",
    "$E_{\\delta u}$",
    "$E_\\beta$",
    "$E_{\\nabla\\beta}$",
    "$E$",
    "$E_v$",
    "KKT (5.1)",
    "KKT (5.2)",
];
const TEX_RATE_HEADER: [&str; 8] = [
    "component",
    "pairwise",
    "least squares",
    "s.e.",
    "95\\,\\% interval",
    "drifting",
    "expected",
    "verdict",
];

fn md_row(cells: &[String]) -> String {
    format!("| {} |\n", cells.join(" | "))
}

fn md_header(names: &[&str]) -> String {
    format!(
        "| {} |\n|{}\n",
        names.join(" | "),
        "---|".repeat(names.len())
    )
}

/// The studies as `(kind, degree, variable, expected, pass, svg file)`, in the order of the rows.
pub struct StudyHead {
    /// Study kind.
    pub kind: &'static str,
    /// l.
    pub degree: usize,
    /// h or k.
    pub variable: &'static str,
    /// Expected rate of E.
    pub expected: f64,
    /// Verdict.
    pub verdict: Verdict,
    /// Its plot, relative to the report.
    pub plot: String,
}

/// `report.md`.
pub fn markdown(
    case: &str,
    origin: &str,
    dim: usize,
    tolerance: f64,
    studies: &[StudyHead],
    runs: &[ErrorRow],
    rates: &[RateRow],
) -> String {
    let verdict = Verdict::combine(studies.iter().map(|s| s.verdict));
    let mut md = format!(
        "# Verification of `{case}`\n\nCase {origin}, d = {dim}. Errors E(h, k) of Theorem 5.2 against the \
manufactured solution. A component the theorem bounds passes when its least-squares rate over the finest levels \
and its rate between the two finest levels are both ≥ expected − {tolerance}. Standard error and 95 % interval of \
the least-squares slope (Student's t); \"drifting\": the pairwise rates over the fitted levels differ by more \
than {tolerance} (not yet asymptotic). A study is PASS when every bounded component passes and E_total does not \
drift, FAIL when a component fails, DRIFTING (not certified) when E_total drifts. Verdict: **{}**.\n",
        verdict.label()
    );
    for study in studies {
        md += &format!(
            "\n## {}-study, l = {}: rates in {} (expected {}), {}\n\n",
            study.kind,
            study.degree,
            study.variable,
            rate(study.expected, MISSING),
            study.verdict.label()
        );
        md += &md_header(&RUN_HEADER);
        for row in runs
            .iter()
            .filter(|r| r.study == study.kind && r.degree == study.degree)
        {
            md += &md_row(&run_cells(row, MISSING));
        }
        md += "\n";
        md += &md_header(&RATE_HEADER);
        for row in rates
            .iter()
            .filter(|r| r.study == study.kind && r.degree == study.degree)
        {
            md += &md_row(&rate_cells(row, MISSING));
        }
        md += &format!(
            "\n![{}-study, l = {}]({})\n",
            study.kind, study.degree, study.plot
        );
    }
    md
}

fn tex_escape(text: &str) -> String {
    text.replace('_', "\\_").replace('%', "\\%")
}

fn tex_row(cells: &[String]) -> String {
    let cells: Vec<String> = cells.iter().map(|c| tex_escape(c)).collect();
    format!("{} \\\\\n", cells.join(" & "))
}

/// `tables.tex`: per study, a table of the runs and one of the rates.
pub fn latex(case: &str, studies: &[StudyHead], runs: &[ErrorRow], rates: &[RateRow]) -> String {
    let mut tex = format!(
        "% verify: {case}; needs \\usepackage{{booktabs}}; -- = no value\n",
        case = tex_escape(case)
    );
    for study in studies {
        tex += &format!(
            "\n% {}-study, l = {}: rates in {}, expected {}, {}\n\\begin{{tabular}}{{rr{}}}\n\\toprule\n{} \\\\\n\\midrule\n",
            study.kind,
            study.degree,
            study.variable,
            rate(study.expected, "--"),
            study.verdict.label(),
            "r".repeat(RUN_HEADER.len() - 2),
            TEX_RUN_HEADER.join(" & ")
        );
        for row in runs
            .iter()
            .filter(|r| r.study == study.kind && r.degree == study.degree)
        {
            tex += &tex_row(&run_cells(row, "--"));
        }
        tex += "\\bottomrule\n\\end{tabular}\n\n";
        tex += &format!(
            "\\begin{{tabular}}{{llrrlcrl}}\n\\toprule\n{} \\\\\n\\midrule\n",
            TEX_RATE_HEADER.join(" & ")
        );
        for row in rates
            .iter()
            .filter(|r| r.study == study.kind && r.degree == study.degree)
        {
            tex += &tex_row(&rate_cells(row, "--"));
        }
        tex += "\\bottomrule\n\\end{tabular}\n";
    }
    tex
}
