//! The files of `simulate --convergence`: `convergence.csv`, `convergence.json`, one SVG per
//! quantity (`gci_<quantity>.svg`: value against h with the extrapolated value and the GCI
//! band φ1 (1 ± GCI_fine)), `report.md` and `tables.tex` (booktabs), all written atomically,
//! and the terminal table ([`table`]).
//!
//! A quantity whose triplets do not all converge monotonically gets its classification and no
//! order, extrapolated value or GCI (`—` in the tables, `null` in JSON).

use super::gci::Estimate;
use super::{Quantity, Study};
use contact_input::output::{write_atomic, write_json_atomic, MISSING};
use contact_input::InputError;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// Name of the CSV file.
pub const CSV_FILE: &str = "convergence.csv";
/// Name of the JSON file.
pub const JSON_FILE: &str = "convergence.json";
/// Name of the Markdown report.
pub const REPORT_FILE: &str = "report.md";
/// Name of the LaTeX tables.
pub const TABLES_FILE: &str = "tables.tex";

/// The reported estimate of a quantity: that of its finest triplet, only if every triplet
/// converges monotonically.
pub fn reported(quantity: &Quantity) -> Option<Estimate> {
    quantity
        .monotone()
        .then(|| quantity.finest().reported())
        .flatten()
}

fn number(value: f64) -> String {
    if value.is_finite() {
        format!("{value:.6e}")
    } else {
        MISSING.to_string()
    }
}

fn fixed(value: Option<f64>, decimals: usize) -> String {
    match value.filter(|v| v.is_finite()) {
        Some(v) => format!("{v:.decimals$}"),
        None => MISSING.to_string(),
    }
}

fn percent(value: Option<f64>) -> String {
    match value.filter(|v| v.is_finite()) {
        Some(v) => format!("{:.3}%", 100.0 * v),
        None => MISSING.to_string(),
    }
}

/// One line of every table: the columns of [`CSV_HEADER`] after the level values.
fn estimate_cells(quantity: &Quantity) -> [String; 7] {
    let estimate = reported(quantity);
    [
        quantity.finest().convergence.name().to_string(),
        fixed(estimate.map(|e| e.order), 3),
        estimate.map_or(MISSING.to_string(), |e| number(e.extrapolated)),
        percent(estimate.map(|e| e.approximate_relative_error)),
        percent(estimate.map(|e| e.extrapolated_relative_error)),
        percent(estimate.map(|e| e.gci_fine)),
        fixed(estimate.map(|e| e.asymptotic_ratio), 3),
    ]
}

/// The columns of `convergence.csv` after `quantity,t,` and the values per level
/// (`level_0` coarsest); relative errors and the GCI as fractions.
pub const CSV_HEADER: [&str; 7] = [
    "convergence",
    "order",
    "extrapolated",
    "approximate_relative_error",
    "extrapolated_relative_error",
    "gci_fine",
    "asymptotic_ratio",
];

/// The terminal table.
pub fn table(study: &Study) -> String {
    let mut lines = vec![format!(
        "{}: {} levels, h and k refined together by r = {} (cells × r^i, steps × r^i)",
        study.name,
        study.levels.len(),
        study.ratio
    )];
    for level in &study.levels {
        lines.push(format!(
            "  level {}: {}, steps {}, h = {:.4e}, k = {:.4e}, max KKT {:.1e} / {:.1e}",
            level.index,
            super::mesh_label(&level.cells, level.refinements),
            level.steps,
            level.h,
            level.k,
            level.max_kkt.velocity,
            level.max_kkt.damage
        ));
    }
    lines.push(format!(
        "{:<32} {:>13} {:>13} {:>12} {:>7} {:>13} {:>9} {:>9} {:>9} {:>7}",
        "quantity",
        "coarse",
        "fine",
        "convergence",
        "p",
        "extrapolated",
        "e_a",
        "e_ext",
        "GCI",
        "ratio"
    ));
    for quantity in &study.quantities {
        let [convergence, order, extrapolated, e_a, e_ext, gci, ratio] = estimate_cells(quantity);
        let convergence = if quantity.monotone() {
            convergence
        } else {
            format!("{convergence}*")
        };
        lines.push(format!(
            "{:<32} {:>13} {:>13} {:>12} {:>7} {:>13} {:>9} {:>9} {:>9} {:>7}",
            quantity.label(),
            number(quantity.values[0]),
            number(*quantity.values.last().unwrap_or(&f64::NAN)),
            convergence,
            order,
            extrapolated,
            e_a,
            e_ext,
            gci,
            ratio
        ));
    }
    if study.quantities.iter().any(|q| !q.monotone()) {
        lines.push(
            "* not monotone on every triplet of levels: no order, extrapolation or GCI is given"
                .to_string(),
        );
    }
    lines.join("\n")
}

/// The estimate columns of `convergence.csv`: full precision, relative errors as fractions,
/// `—` where there is none.
fn csv_cells(quantity: &Quantity) -> [String; 7] {
    let estimate = reported(quantity);
    let raw = |value: Option<f64>| match value.filter(|v| v.is_finite()) {
        Some(v) => v.to_string(),
        None => MISSING.to_string(),
    };
    [
        quantity.finest().convergence.name().to_string(),
        raw(estimate.map(|e| e.order)),
        raw(estimate.map(|e| e.extrapolated)),
        raw(estimate.map(|e| e.approximate_relative_error)),
        raw(estimate.map(|e| e.extrapolated_relative_error)),
        raw(estimate.map(|e| e.gci_fine)),
        raw(estimate.map(|e| e.asymptotic_ratio)),
    ]
}

fn csv_text(study: &Study) -> String {
    let mut header = vec!["quantity".to_string(), "t".to_string()];
    header.extend((0..study.levels.len()).map(|i| format!("level_{i}")));
    header.extend(CSV_HEADER.iter().map(|s| s.to_string()));
    let mut text = header.join(",") + "\n";
    for quantity in &study.quantities {
        let mut row = vec![quantity.column.clone(), quantity.time.to_string()];
        row.extend(quantity.values.iter().map(|v| v.to_string()));
        row.extend(csv_cells(quantity));
        text += &(row.join(",") + "\n");
    }
    text
}

fn svg_name(quantity: &Quantity) -> String {
    svg_file(&quantity.column, quantity.time)
}

/// The picture of the quantity `column` at `time`.
fn svg_file(column: &str, time: f64) -> String {
    format!("gci_{column}_t{time}.svg")
}

/// The names of the files [`write_files`] writes for the quantities `column` at `time`.
pub fn file_names<'a>(quantities: impl IntoIterator<Item = (&'a str, f64)>) -> Vec<String> {
    let mut names: Vec<String> = [CSV_FILE, JSON_FILE, REPORT_FILE, TABLES_FILE]
        .map(String::from)
        .to_vec();
    names.extend(
        quantities
            .into_iter()
            .map(|(column, time)| svg_file(column, time)),
    );
    names
}

fn markdown(study: &Study) -> String {
    let mut md = format!(
        "# Solution verification: {}\n\nProblem `{}`, {} levels refined in space and time together by r = {} \
(box cells × r^i, time steps × r^i). Procedure of Celik et al., ASME J. Fluids Eng. 130 (2008) 078001: \
observed order p from the three finest levels (fixed-point iteration), Richardson extrapolation φ_ext, \
approximate and extrapolated relative errors e_a, e_ext, GCI_fine with safety factor 1.25; ratio = \
GCI_32 / (r^p GCI_21), near 1 in the asymptotic range. A quantity that does not converge monotonically \
(R = ε21/ε32 outside (0, 1)) on every triplet gets its classification and no order.\n\n",
        study.name,
        study.origin,
        study.levels.len(),
        study.ratio
    );
    md += "| level | mesh | steps | h | k | max KKT velocity | max KKT damage |\n|---|---|---|---|---|---|---|\n";
    for level in &study.levels {
        md += &format!(
            "| {} | {} | {} | {:.4e} | {:.4e} | {:.1e} | {:.1e} |\n",
            level.index,
            super::mesh_label(&level.cells, level.refinements),
            level.steps,
            level.h,
            level.k,
            level.max_kkt.velocity,
            level.max_kkt.damage
        );
    }
    md += "\n| quantity | t |";
    for i in 0..study.levels.len() {
        md += &format!(" level {i} |");
    }
    md += " convergence | p | φ_ext | e_a | e_ext | GCI_fine | ratio |\n|---|---|";
    md += &"---|".repeat(study.levels.len() + 7);
    md += "\n";
    for quantity in &study.quantities {
        md += &format!(
            "| {} | {} |",
            quantity.column.replace('_', "\\_"),
            quantity.time
        );
        for v in &quantity.values {
            md += &format!(" {} |", number(*v));
        }
        for cell in estimate_cells(quantity) {
            md += &format!(" {cell} |");
        }
        md += "\n";
    }
    let irregular: Vec<String> = study
        .quantities
        .iter()
        .filter(|q| !q.monotone())
        .map(|q| {
            let kinds: Vec<&str> = q.triplets.iter().map(|t| t.convergence.name()).collect();
            let same = q.values.iter().all(|v| *v == q.values[0]);
            format!(
                "- `{}`: {} (triplets finest first){}",
                q.label(),
                kinds.join(", "),
                if same {
                    "; the same value on every level, no discretization effect to measure"
                } else {
                    ""
                }
            )
        })
        .collect();
    if !irregular.is_empty() {
        md += "\nNot monotone, no order given:\n\n";
        md += &irregular.join("\n");
        md += "\n";
    }
    if study.quantities.iter().any(|q| q.least_squares.is_some()) {
        md += "\nLeast-squares fit φ ≈ φ0 + α h^p over all levels (Eça & Hoekstra):\n\n| quantity | p | φ0 | std. dev. |\n|---|---|---|---|\n";
        for q in study.quantities.iter().filter(|q| q.monotone()) {
            if let Some(fit) = q.least_squares {
                md += &format!(
                    "| {} | {:.3} | {} | {:.2e} |\n",
                    q.label(),
                    fit.order,
                    number(fit.extrapolated),
                    fit.standard_deviation
                );
            }
        }
    }
    md += "\n";
    for q in &study.quantities {
        md += &format!("![{}]({})\n", q.label(), svg_name(q));
    }
    md
}

fn latex_escape(text: &str) -> String {
    text.replace('_', "\\_").replace('%', "\\%")
}

fn latex(study: &Study) -> String {
    let columns = study.levels.len();
    let mut tex = format!(
        "% simulate --convergence: {} ({} levels, r = {}); needs \\usepackage{{booktabs}}\n\\begin{{tabular}}{{ll{}lrrrrrr}}\n\\toprule\n",
        latex_escape(&study.name),
        columns,
        study.ratio,
        "r".repeat(columns)
    );
    tex += "quantity & $t$";
    for i in 0..columns {
        tex += &format!(" & level {i}");
    }
    tex += " & convergence & $p$ & $\\phi_{ext}$ & $e_a$ & $e_{ext}$ & GCI$_{fine}$ & ratio \\\\\n\\midrule\n";
    for quantity in &study.quantities {
        tex += &format!("{} & {}", latex_escape(&quantity.column), quantity.time);
        for v in &quantity.values {
            tex += &format!(" & {}", number(*v));
        }
        for cell in estimate_cells(quantity) {
            let cell = if cell == MISSING {
                "--".to_string()
            } else {
                latex_escape(&cell)
            };
            tex += &format!(" & {cell}");
        }
        tex += " \\\\\n";
    }
    tex += "\\bottomrule\n\\end{tabular}\n";
    tex
}

/// Value against h: the levels, the extrapolated value (dashed) and the band φ1 (1 ± GCI_fine)
/// (only for a monotone quantity).
fn svg(path: &Path, study: &Study, quantity: &Quantity) -> Result<(), InputError> {
    let plot_error = |e: &dyn std::fmt::Display| InputError::Plot {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let points: Vec<(f64, f64)> = study
        .levels
        .iter()
        .zip(&quantity.values)
        .map(|(l, v)| (l.h, *v))
        .collect();
    let estimate = reported(quantity);
    let fine = *quantity.values.last().unwrap_or(&0.0);
    let mut y: Vec<f64> = quantity.values.clone();
    if let Some(e) = estimate {
        y.push(e.extrapolated);
        y.push(fine * (1.0 + e.gci_fine));
        y.push(fine * (1.0 - e.gci_fine));
    }
    let (low, high) = y
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let pad = if high > low {
        0.1 * (high - low)
    } else {
        0.1 * high.abs().max(1e-12)
    };
    let x_high = 1.1 * study.levels.iter().map(|l| l.h).fold(0.0, f64::max);
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, (800, 600)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_error(&e))?;
        let title = format!(
            "{}: {} ({})",
            study.name,
            quantity.label(),
            quantity.finest().convergence.name()
        );
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(90)
            .build_cartesian_2d(0.0..x_high, (low - pad)..(high + pad))
            .map_err(|e| plot_error(&e))?;
        chart
            .configure_mesh()
            .x_desc("h (k refined with it)")
            .y_desc(&quantity.column)
            .draw()
            .map_err(|e| plot_error(&e))?;
        if let Some(e) = estimate {
            let band = fine * e.gci_fine;
            chart
                .draw_series([Rectangle::new(
                    [(0.0, fine - band.abs()), (x_high, fine + band.abs())],
                    BLUE.mix(0.15).filled(),
                )])
                .map_err(|e| plot_error(&e))?
                .label("fine value ± GCI_fine")
                .legend(|(x, y)| {
                    Rectangle::new([(x, y - 5), (x + 20, y + 5)], BLUE.mix(0.15).filled())
                });
            let style = BLACK.stroke_width(1);
            chart
                .draw_series(DashedLineSeries::new(
                    [(0.0, e.extrapolated), (x_high, e.extrapolated)],
                    8,
                    5,
                    style,
                ))
                .map_err(|e| plot_error(&e))?
                .label(format!("extrapolated (p = {:.2})", e.order))
                .legend(move |(x, y)| {
                    DashedPathElement::new(vec![(x, y), (x + 20, y)], 5, 3, style)
                });
        }
        chart
            .draw_series(LineSeries::new(points.clone(), RED.stroke_width(2)).point_size(4))
            .map_err(|e| plot_error(&e))?
            .label("levels")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(2)));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| plot_error(&e))?;
        root.present().map_err(|e| plot_error(&e))?;
    }
    write_atomic(path, text.as_bytes())
}

/// Writes every file of the study into `out`; returns their paths.
pub fn write_files(out: &Path, study: &Study) -> Result<Vec<PathBuf>, InputError> {
    let mut written = Vec::new();
    let csv = out.join(CSV_FILE);
    write_atomic(&csv, csv_text(study).as_bytes())?;
    written.push(csv);
    let json = out.join(JSON_FILE);
    write_json_atomic(&json, study)?;
    written.push(json);
    for quantity in &study.quantities {
        let path = out.join(svg_name(quantity));
        svg(&path, study, quantity)?;
        written.push(path);
    }
    let md = out.join(REPORT_FILE);
    write_atomic(&md, markdown(study).as_bytes())?;
    written.push(md);
    let tex = out.join(TABLES_FILE);
    write_atomic(&tex, latex(study).as_bytes())?;
    written.push(tex);
    Ok(written)
}
