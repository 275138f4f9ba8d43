//! The `verify` command line: runs the studies of a case and writes its reports.

use crate::case::{parse_case_file, read_case_file, Case, CaseFile};
use crate::output::format_or_dash;
use crate::report::write_reports;
use crate::study::{level_study, time_study, StudyKind, StudyResult};
use crate::VerifyError;
use clap::Parser;
pub use contact_input::threads::{max_threads, set_threads};
use std::path::PathBuf;

/// Built-in cases: (name, TOML text). The files live in `verification/`; the meshes of the
/// cases on Gmsh meshes are built in too ([`crate::domain::BUILT_IN_MESHES`]).
pub const BUILT_IN_CASES: [(&str, &str); 15] = [
    ("slip2d", include_str!("../../../verification/slip2d.toml")),
    (
        "zones2d",
        include_str!("../../../verification/zones2d.toml"),
    ),
    ("slip3d", include_str!("../../../verification/slip3d.toml")),
    (
        "zones3d",
        include_str!("../../../verification/zones3d.toml"),
    ),
    ("mild2d", include_str!("../../../verification/mild2d.toml")),
    (
        "strong2d",
        include_str!("../../../verification/strong2d.toml"),
    ),
    ("wear2d", include_str!("../../../verification/wear2d.toml")),
    (
        "carreau2d",
        include_str!("../../../verification/carreau2d.toml"),
    ),
    (
        "implicit2d",
        include_str!("../../../verification/implicit2d.toml"),
    ),
    (
        "loads2d",
        include_str!("../../../verification/loads2d.toml"),
    ),
    ("mild3d", include_str!("../../../verification/mild3d.toml")),
    (
        "strong3d",
        include_str!("../../../verification/strong3d.toml"),
    ),
    ("wear3d", include_str!("../../../verification/wear3d.toml")),
    (
        "tilted2d",
        include_str!("../../../verification/tilted2d.toml"),
    ),
    (
        "tilted3d",
        include_str!("../../../verification/tilted3d.toml"),
    ),
];

/// Manufactured-solution convergence verification of the contact-damage scheme (Theorem 5.2).
#[derive(Debug, Parser)]
#[command(name = "verify", version, about)]
pub struct Cli {
    /// Polynomial degree l of the finite elements (1 or 2).
    #[arg(long, default_value_t = 1)]
    pub order: usize,
    /// Space dimension of the default case (2 or 3); ignored with --case.
    #[arg(long, default_value_t = 2)]
    pub dim: usize,
    /// A case file (TOML), or the name of a built-in case (slip2d, zones2d, slip3d, zones3d, mild2d, strong2d, wear2d, carreau2d, implicit2d, loads2d, mild3d, strong3d, wear3d, tilted2d, tilted3d).
    #[arg(long)]
    pub case: Option<String>,
    /// Use only the first (coarsest) N levels of every study.
    #[arg(long)]
    pub levels: Option<usize>,
    /// Which studies to run (comma-separated: h, k, diagonal).
    #[arg(long, value_delimiter = ',', default_value = "h,k,diagonal")]
    pub studies: Vec<String>,
    /// Output folder (default: `reports/<case>/l<order>`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Worker threads, 1 ..= 4 × the available cores (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
}

/// The names of `--studies`.
pub const STUDY_NAMES: [&str; 3] = ["h", "k", "diagonal"];

/// Checks `--studies` before anything is computed: every name is one of [`STUDY_NAMES`].
pub fn check_studies(studies: &[String]) -> Result<(), VerifyError> {
    match studies
        .iter()
        .find(|name| !STUDY_NAMES.contains(&name.as_str()))
    {
        Some(unknown) => Err(VerifyError::InvalidInput(format!(
            "--studies: unknown study `{unknown}` (use h, k, diagonal, comma-separated)"
        ))),
        None => Ok(()),
    }
}

/// Makes sure that the reports can be written into the folder `out` (`--out`) before anything
/// is computed: it is a folder or can be created as one, and a file can be created in it.
pub fn check_out(out: &std::path::Path) -> Result<(), VerifyError> {
    let refuse =
        |reason: String| VerifyError::InvalidInput(format!("--out `{}`: {reason}", out.display()));
    // the nearest existing ancestor must be a folder
    let mut existing = out;
    while !existing.as_os_str().is_empty() && !existing.exists() {
        existing = existing.parent().unwrap_or(std::path::Path::new(""));
    }
    if !existing.as_os_str().is_empty() && !existing.is_dir() {
        return Err(refuse(if existing == out {
            "exists and is not a folder".to_string()
        } else {
            format!("`{}` is a file, not a folder", existing.display())
        }));
    }
    std::fs::create_dir_all(out).map_err(|e| refuse(format!("cannot create the folder: {e}")))?;
    // a probe file, created exclusively and removed at once
    let probe = out.join(format!(".verify-write-probe.{}", std::process::id()));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
        .map_err(|e| refuse(format!("cannot write into the folder: {e}")))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// Loads the case named on the command line (or the default one for the dimension).
pub fn load_case(cli: &Cli) -> Result<(CaseFile, String), VerifyError> {
    let name = match &cli.case {
        Some(name) => name.clone(),
        None => match cli.dim {
            2 => "zones2d".to_string(),
            3 => "zones3d".to_string(),
            other => {
                return Err(VerifyError::InvalidInput(format!(
                    "--dim must be 2 or 3, got {other}"
                )))
            }
        },
    };
    if let Some((builtin, text)) = BUILT_IN_CASES.iter().find(|(n, _)| *n == name) {
        let origin = format!("built-in:{builtin}");
        return Ok((parse_case_file(text, &origin)?, origin));
    }
    let path = PathBuf::from(&name);
    Ok((read_case_file(&path)?, path.display().to_string()))
}

fn truncate<T: Clone>(values: &[T], levels: Option<usize>) -> Vec<T> {
    match levels {
        Some(n) => values[..n.min(values.len())].to_vec(),
        None => values.to_vec(),
    }
}

/// Runs the requested studies of a case in dimension D.
pub fn run_studies<const D: usize>(
    case: &Case<D>,
    cli: &Cli,
) -> Result<Vec<StudyResult>, VerifyError> {
    let key = format!("order{}", cli.order);
    let set = case.file.studies.get(&key).ok_or_else(|| {
        VerifyError::InvalidInput(format!(
            "case `{}` defines no studies for l = {} (no [studies.{key}])",
            case.origin, cli.order
        ))
    })?;
    let mut results = Vec::new();
    for name in &cli.studies {
        match name.as_str() {
            "h" => {
                if let Some(study) = &set.h {
                    let mut study = study.clone();
                    study.cells = truncate(&study.cells, cli.levels);
                    study.refinements = truncate(&study.refinements, cli.levels);
                    study.steps = truncate(&study.steps, cli.levels);
                    results.push(level_study(case, cli.order, StudyKind::H, &study)?);
                }
            }
            "diagonal" => {
                if let Some(study) = &set.diagonal {
                    let mut study = study.clone();
                    study.cells = truncate(&study.cells, cli.levels);
                    study.refinements = truncate(&study.refinements, cli.levels);
                    study.steps = truncate(&study.steps, cli.levels);
                    results.push(level_study(case, cli.order, StudyKind::Diagonal, &study)?);
                }
            }
            "k" => {
                if let Some(study) = &set.k {
                    let mut study = study.clone();
                    study.steps = truncate(&study.steps, cli.levels);
                    results.push(time_study(case, cli.order, &study)?);
                }
            }
            other => {
                return Err(VerifyError::InvalidInput(format!(
                    "unknown study `{other}` (use h, k, diagonal)"
                )))
            }
        }
    }
    Ok(results)
}

/// `value` in scientific notation with `precision` digits, or `—` when it has no value.
fn sci(value: f64, precision: usize) -> String {
    format_or_dash(value, |v| format!("{v:.precision$e}"))
}

/// `value` with `precision` decimals, or `—` when it has no value.
fn fixed(value: f64, precision: usize) -> String {
    format_or_dash(value, |v| format!("{v:.precision$}"))
}

/// The table of a study, as printed by [`print_study`]: one line per run (errors, largest KKT
/// residual, Newton iterations of one velocity step (5.1) as mean/max over the steps, wall
/// time), then one line of rates per error component that has any. A missing value is `—`.
pub fn study_table(study: &StudyResult) -> String {
    let mut lines = vec![format!(
        "{}-study, l = {}: rates in {} (expected {}, verdict {})",
        study.kind.name(),
        study.degree,
        study.variable,
        fixed(study.expected_rate, 2),
        if study.pass { "PASS" } else { "FAIL" }
    )];
    lines.push(format!(
        "{:>6} {:>6} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10} {:>9} {:>11} {:>7}",
        "cells",
        "steps",
        "h",
        "k",
        "E_u",
        "E_du",
        "E_beta",
        "E_gradb",
        "E_total",
        "max KKT",
        "Newton m/M",
        "time s"
    ));
    for run in &study.runs {
        lines.push(format!(
            "{:>6} {:>6} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10} {:>9} {:>11} {:>7}",
            run.cells,
            run.steps,
            sci(run.h, 3),
            sci(run.k, 3),
            sci(run.errors.displacement, 3),
            sci(run.errors.difference_quotient, 3),
            sci(run.errors.damage, 3),
            sci(run.errors.damage_gradient, 3),
            sci(run.errors.total, 3),
            sci(run.stats.max_velocity_kkt.max(run.stats.max_damage_kkt), 1),
            format!(
                "{}/{}",
                fixed(run.stats.mean_newton_iterations, 2),
                run.stats.max_newton_iterations
            ),
            fixed(run.stats.wall_seconds, 2)
        ));
    }
    // a component without any rate (the velocity error of a k-study) is left out
    for rates in study.rates.iter().filter(|r| !r.is_missing()) {
        let pairwise: Vec<String> = rates.pairwise.iter().map(|&r| fixed(r, 2)).collect();
        lines.push(format!(
            "  {:<20} pairwise [{}]  least squares {}{}",
            rates.component,
            pairwise.join(", "),
            fixed(rates.least_squares, 3),
            match rates.pass {
                Some(true) => "  ok",
                Some(false) => "  BELOW EXPECTED",
                None => "",
            }
        ));
    }
    lines.join("\n")
}

/// Prints the table of a study ([`study_table`]) to stdout.
pub fn print_study(study: &StudyResult) {
    println!("\n{}", study_table(study));
}

/// Runs the command line; returns whether every verdict passed.
pub fn main_with(cli: Cli) -> Result<bool, VerifyError> {
    if !(1..=2).contains(&cli.order) {
        return Err(VerifyError::InvalidInput(format!(
            "--order must be 1 or 2, got {}",
            cli.order
        )));
    }
    set_threads(cli.threads)?;
    check_studies(&cli.studies)?;
    let (file, origin) = load_case(&cli)?;
    let name = file.name.clone();
    let dim = file.dim;
    let out = cli.out.clone().unwrap_or_else(|| {
        PathBuf::from("reports")
            .join(&name)
            .join(format!("l{}", cli.order))
    });
    check_out(&out)?;
    let started = std::time::Instant::now();
    let studies = match dim {
        2 => run_studies(&Case::<2>::new(file, &origin)?, &cli)?,
        3 => run_studies(&Case::<3>::new(file, &origin)?, &cli)?,
        other => {
            return Err(VerifyError::InvalidInput(format!(
                "{origin}: dim must be 2 or 3, got {other}"
            )))
        }
    };
    for study in &studies {
        print_study(study);
    }
    let written = write_reports(&out, &name, &origin, dim, &studies)?;
    println!(
        "\ncase {name} ({origin}), d = {dim}, l = {}: {:.1} s",
        cli.order,
        started.elapsed().as_secs_f64()
    );
    for path in written {
        println!("wrote {}", path.display());
    }
    let pass = studies.iter().all(|s| s.pass);
    println!("verdict: {}", if pass { "PASS" } else { "FAIL" });
    Ok(pass)
}
