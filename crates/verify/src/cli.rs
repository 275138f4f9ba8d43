//! The `verify` command line: runs the studies of a case and writes its reports.

use crate::case::{parse_case_file, Case, CaseFile};
use crate::output::format_or_dash;
use crate::study::{StudyResult, Verdict};
use crate::sweep::merge::{merge, write_study_reports};
use crate::sweep::plan::{plan, read_manifest, write_manifest, Manifest};
use crate::sweep::run::{execute, Executed};
use crate::sweep::shard::{parse_shard, shard};
use crate::InputError;
use clap::Parser;
use contact_input::outln;
pub use contact_input::threads::{max_threads, set_threads};
use std::path::{Path, PathBuf};

/// Built-in cases: (name, TOML text). The files live in `verification/`; the meshes of the
/// cases on Gmsh meshes are built in too ([`crate::domain::BUILT_IN_MESHES`]).
pub const BUILT_IN_CASES: [(&str, &str); 18] = [
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
    (
        "loads3d",
        include_str!("../../../verification/loads3d.toml"),
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
    (
        "curved2d",
        include_str!("../../../verification/curved2d.toml"),
    ),
    (
        "curved3d",
        include_str!("../../../verification/curved3d.toml"),
    ),
];

/// Manufactured-solution convergence verification of the contact-damage scheme (Theorem 5.2).
///
/// Without a subcommand, runs the studies in this process, keeping every run's result in
/// `<out>/runs/` so that an interrupted study resumes where it stopped. `plan`, `run` and
/// `merge` split a study into independent runs for a cluster's scheduler.
#[derive(Debug, Parser)]
#[command(
    name = "verify",
    version,
    about,
    args_conflicts_with_subcommands = true
)]
pub struct Cli {
    /// plan / run / merge (without one: the whole study in this process).
    #[command(subcommand)]
    pub command: Option<Command>,
    /// The study and its options.
    #[command(flatten)]
    pub study: StudyArgs,
    /// Ignore the results cache `<out>/runs/`: recompute every run.
    #[arg(long)]
    pub fresh: bool,
    /// Regularity sweep: run the case's h-study once for each value of an exponent named in its
    /// `[regularity]` table, NAME=FROM:TO:STEP (both ends included) or NAME=V1,V2,…, and
    /// report the observed rates against the exponent (default folder
    /// `out/<case>/l<order>/regularity-<NAME>`).
    #[arg(long, value_name = "NAME=FROM:TO:STEP")]
    pub regularity: Option<String>,
}

/// The options that select a study (of a single-process run and of `verify plan`).
#[derive(Debug, Clone, clap::Args)]
pub struct StudyArgs {
    /// Polynomial degree l of the finite elements (1 or 2).
    #[arg(long, default_value_t = 1)]
    pub order: usize,
    /// Space dimension of the default case (2 or 3); ignored with --case.
    #[arg(long, default_value_t = 2)]
    pub dim: usize,
    /// A case file (TOML), or the name of a built-in case (slip2d, zones2d, slip3d, zones3d, mild2d, strong2d, wear2d, carreau2d, implicit2d, loads2d, loads3d, mild3d, strong3d, wear3d, tilted2d, tilted3d, curved2d, curved3d).
    #[arg(long)]
    pub case: Option<String>,
    /// Use only the first (coarsest) N levels of every study (N ≥ 2: a rate needs two levels).
    #[arg(long, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(2..))]
    pub levels: Option<usize>,
    /// Which studies to run (comma-separated: h, k, diagonal).
    #[arg(long, value_delimiter = ',', default_value = "h,k,diagonal")]
    pub studies: Vec<String>,
    /// Output folder (default: `out/<case>/l<order>`; the committed baseline in `reports/` is
    /// written only by `verify baseline`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Worker threads, 1 ..= 4 × the available cores (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Refuse studies whose estimated memory exceeds this many GiB (default: the physical
    /// memory of the machine).
    #[arg(long, value_name = "GiB")]
    pub memory_limit: Option<f64>,
    /// Replace files in the output folder of the names verify writes that verify did not write
    /// there (or that changed since); other files are never touched.
    #[arg(long)]
    pub overwrite: bool,
    /// Set a constant of the case's `[constants]` table, NAME=VALUE (repeatable); the case is
    /// renamed `<case>-<NAME><VALUE>`, so its default output folder differs from the case's.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
}

/// The subcommands for studies beyond one process.
#[derive(Debug, clap::Subcommand)]
pub enum Command {
    /// Writes the manifest of every run of a study (same options as a single-process run).
    Plan {
        /// The study and its options.
        #[command(flatten)]
        study: StudyArgs,
        /// The manifest to write (default: `<out>/manifest.json`).
        #[arg(long)]
        manifest: Option<PathBuf>,
    },
    /// Runs one run (`--index`) or a share of the runs (`--shard I/N`) of a manifest.
    Run {
        /// The manifest written by `verify plan`.
        #[arg(long)]
        manifest: PathBuf,
        /// The index of the run (0 ..= runs − 1; e.g. `$SLURM_ARRAY_TASK_ID`).
        #[arg(long, conflicts_with = "shard", required_unless_present = "shard")]
        index: Option<usize>,
        /// Share I of N (0 ≤ I < N), balanced by estimated cost.
        #[arg(long)]
        shard: Option<String>,
        /// The results folder (default: `runs/` beside the manifest).
        #[arg(long)]
        results: Option<PathBuf>,
        /// Recompute the runs even when they have a valid result.
        #[arg(long)]
        fresh: bool,
        /// Worker threads, 1 ..= 4 × the available cores (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
    },
    /// Regenerates the committed baseline `reports/<case>/l<order>/` (the full studies of the
    /// built-in cases) and lists every error that moved against the files it replaces.
    Baseline {
        /// Built-in cases to regenerate, comma-separated (default: all).
        #[arg(long = "case", value_delimiter = ',')]
        cases: Vec<String>,
        /// Orders l to regenerate, comma-separated.
        #[arg(long = "order", value_delimiter = ',', default_value = "1,2")]
        orders: Vec<usize>,
        /// The baseline folder.
        #[arg(long, default_value = crate::baseline::BASELINE_FOLDER)]
        reports: PathBuf,
        /// Relative change above which an error is listed as moved.
        #[arg(long, default_value_t = 1e-8)]
        tolerance: f64,
        /// Worker threads, 1 ..= 4 × the available cores (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// Recompute every run even when `runs/` holds a valid result.
        #[arg(long)]
        fresh: bool,
    },
    /// Merges the results of a manifest into the reports of a single-process run.
    Merge {
        /// The manifest written by `verify plan`.
        #[arg(long)]
        manifest: PathBuf,
        /// The results folder (default: `runs/` beside the manifest).
        #[arg(long)]
        results: Option<PathBuf>,
        /// Where to write the reports (default: the manifest's folder).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Replace report files in the output folder that verify did not write there (or that
        /// changed since); other files are never touched.
        #[arg(long)]
        overwrite: bool,
    },
}

/// The folder of a run's reports when `--out` is not given: `out/<case>/l<order>` (untracked,
/// so that running `verify` leaves a clone of the repository clean).
pub const DEFAULT_OUT: &str = "out";

/// The names of `--studies`.
pub const STUDY_NAMES: [&str; 3] = ["h", "k", "diagonal"];

/// Checks `--studies` before anything is computed: every name is one of [`STUDY_NAMES`].
pub fn check_study_names(studies: &[String]) -> Result<(), InputError> {
    match studies
        .iter()
        .find(|name| !STUDY_NAMES.contains(&name.as_str()))
    {
        Some(unknown) => Err(InputError::InvalidInput(format!(
            "--studies: unknown study `{unknown}` (use h, k, diagonal, comma-separated)"
        ))),
        None => Ok(()),
    }
}

/// Makes sure that the reports can be written into the folder `out` (`--out`) before anything
/// is computed: it is a folder or can be created as one, and a file can be created in it.
pub fn check_out(out: &std::path::Path) -> Result<(), InputError> {
    let refuse =
        |reason: String| InputError::InvalidInput(format!("--out `{}`: {reason}", out.display()));
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

/// The text and origin of the case named on the command line (or the default one for the
/// dimension).
pub fn load_case(args: &StudyArgs) -> Result<(String, String), InputError> {
    let name = match &args.case {
        Some(name) => name.clone(),
        None => match args.dim {
            2 => "zones2d".to_string(),
            3 => "zones3d".to_string(),
            other => {
                return Err(InputError::InvalidInput(format!(
                    "--dim must be 2 or 3, got {other}"
                )))
            }
        },
    };
    let (mut text, mut origin) =
        if let Some((builtin, text)) = BUILT_IN_CASES.iter().find(|(n, _)| *n == name) {
            (text.to_string(), format!("built-in:{builtin}"))
        } else {
            let path = PathBuf::from(&name);
            contact_input::regular::check_regular_file(&path, "case file")?;
            let text = std::fs::read_to_string(&path)
                .map_err(|e| InputError::io("reading case file", &path, e))?;
            (text, path.display().to_string())
        };
    for assignment in &args.set {
        (text, origin) = set_constant(&text, &origin, assignment)?;
    }
    Ok((text, origin))
}

/// The case `text` with `--set NAME=VALUE` applied ([`crate::regularity::case_with`]): NAME
/// must be a constant of the case and VALUE a finite number.
fn set_constant(
    text: &str,
    origin: &str,
    assignment: &str,
) -> Result<(String, String), InputError> {
    let refuse =
        |reason: String| InputError::InvalidInput(format!("--set `{assignment}`: {reason}"));
    let (name, value) = assignment
        .split_once('=')
        .ok_or_else(|| refuse("write NAME=VALUE".to_string()))?;
    let name = name.trim();
    let value: f64 = match value.trim().parse() {
        Ok(value) if f64::is_finite(value) => value,
        _ => return Err(refuse(format!("`{}` is not a finite number", value.trim()))),
    };
    let file = parse_case_file(text, origin)?;
    if !file.constants.contains_key(name) {
        let known: Vec<&str> = file.constants.keys().map(String::as_str).collect();
        return Err(refuse(format!(
            "{origin} has no constant `{name}` (its constants: {})",
            if known.is_empty() {
                "none".to_string()
            } else {
                known.join(", ")
            }
        )));
    }
    crate::regularity::case_with(text, origin, name, value)
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
/// time), then one line of rates per error component that has any: pairwise rates, the
/// least-squares rate ± its standard error, `drifting` when the pairwise rates are not yet in
/// the asymptotic range ([`crate::study::is_drifting`]), the verdict. A missing value is `—`.
pub fn study_table(study: &StudyResult) -> String {
    let mut lines = vec![format!(
        "{}-study, l = {}: rates in {} (expected {}, verdict {})",
        study.kind.name(),
        study.degree,
        study.variable,
        fixed(study.expected_rate, 2),
        study.verdict.label()
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
            "  {:<20} pairwise [{}]  least squares {} ± {} (SE){}{}",
            rates.component,
            pairwise.join(", "),
            fixed(rates.least_squares, 3),
            fixed(rates.standard_error, 3),
            if rates.drifting == Some(true) {
                "  drifting"
            } else {
                ""
            },
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
pub fn print_study(study: &StudyResult) -> Result<(), InputError> {
    outln!("\n{}", study_table(study))?;
    Ok(())
}

/// The names of the files a merge of `manifest` writes into its output folder (the reports).
fn report_names(manifest: &Manifest) -> Vec<String> {
    let mut names: Vec<String> = [
        "errors.csv",
        "rates.csv",
        "summary.json",
        "report.md",
        "tables.tex",
    ]
    .map(String::from)
    .to_vec();
    for study in &manifest.studies {
        names.push(format!("{}-l{}.svg", study.kind.name(), manifest.degree));
    }
    names
}

/// The folder and name of a file path (the folder `.` for a bare name).
fn folder_and_name(path: &Path) -> (PathBuf, Vec<String>) {
    let folder = match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .into_iter()
        .collect();
    (folder, name)
}

/// Checks the options of a study, then plans it; returns the manifest and the report folder.
fn plan_study(args: &StudyArgs) -> Result<(Manifest, PathBuf), InputError> {
    check_study_options(args)?;
    let (text, origin) = load_case(args)?;
    plan_case(args, &text, &origin)
}

/// Checks the options of a study that do not depend on the case: the order, the threads and the
/// study names.
fn check_study_options(args: &StudyArgs) -> Result<(), InputError> {
    if !(1..=2).contains(&args.order) {
        return Err(InputError::InvalidInput(format!(
            "--order must be 1 or 2, got {}",
            args.order
        )));
    }
    set_threads(args.threads)?;
    check_study_names(&args.studies)
}

/// Plans the studies `args` asks for of the case `text` (from `origin`): the case is validated in
/// full and its studies are checked against the memory first. Returns the manifest and the
/// report folder.
fn plan_case(
    args: &StudyArgs,
    text: &str,
    origin: &str,
) -> Result<(Manifest, PathBuf), InputError> {
    let memory_limit = match args.memory_limit {
        None => contact_damage::algebra::memory::default_limit(),
        Some(gib) if gib.is_finite() && gib > 0.0 => gib * contact_damage::algebra::memory::GIB,
        Some(gib) => {
            return Err(InputError::InvalidInput(format!(
                "--memory-limit {gib}: must be a positive number of GiB"
            )))
        }
    };
    // the case is validated in full (laws, exact fields) and its studies are checked against
    // the memory before anything is planned or created
    let file = parse_case_file(text, origin)?;
    with_case(file.clone(), origin, |case| {
        let (order, studies, levels) = (args.order, &args.studies, args.levels);
        match case {
            CaseRef::Two(case) => {
                crate::budget::check_memory(case, order, studies, levels, memory_limit)
            }
            CaseRef::Three(case) => {
                crate::budget::check_memory(case, order, studies, levels, memory_limit)
            }
        }
    })?;
    let manifest = plan(text, origin, args.order, &args.studies, args.levels)?;
    let out = args.out.clone().unwrap_or_else(|| {
        PathBuf::from(DEFAULT_OUT)
            .join(&file.name)
            .join(format!("l{}", args.order))
    });
    Ok((manifest, out))
}

/// Builds the case of dimension 2 or 3 and calls `work` with it.
fn with_case<T>(
    file: CaseFile,
    origin: &str,
    work: impl FnOnce(CaseRef<'_>) -> Result<T, InputError>,
) -> Result<T, InputError> {
    match file.dim {
        2 => work(CaseRef::Two(&Case::<2>::new(file, origin)?)),
        3 => work(CaseRef::Three(&Case::<3>::new(file, origin)?)),
        other => Err(InputError::InvalidInput(format!(
            "{origin}: dim must be 2 or 3, got {other}"
        ))),
    }
}

/// A case of dimension 2 or 3.
enum CaseRef<'a> {
    Two(&'a Case<2>),
    Three(&'a Case<3>),
}

/// Runs the runs `selection` of `manifest` that `results` does not hold yet ([`execute`]).
fn execute_manifest(
    manifest: &Manifest,
    selection: &[usize],
    results: &Path,
    fresh: bool,
) -> Result<Executed, InputError> {
    let file = parse_case_file(&manifest.case_text, &manifest.origin)?;
    with_case(file, &manifest.origin, |case| match case {
        CaseRef::Two(case) => execute(case, manifest, selection, results, fresh),
        CaseRef::Three(case) => execute(case, manifest, selection, results, fresh),
    })
}

/// The results folder: `results`, or `runs/` beside the manifest.
fn results_folder(manifest: &Path, results: Option<PathBuf>) -> PathBuf {
    results.unwrap_or_else(|| manifest.parent().unwrap_or(Path::new("")).join("runs"))
}

/// How a command ended, for the exit status of `verify`; ordered from the best to the worst.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Outcome {
    /// Done; for studies, every verdict PASS (status 0).
    Success,
    /// No study failed, but one is DRIFTING: not certified (status 3).
    NotCertified,
    /// A study FAILed, or runs of a merge have no valid result (status 1).
    Failure,
}

impl Outcome {
    /// The outcome of studies with the combined verdict `verdict`.
    pub fn of(verdict: Verdict) -> Self {
        match verdict {
            Verdict::Pass => Outcome::Success,
            Verdict::Fail => Outcome::Failure,
            Verdict::Drifting => Outcome::NotCertified,
        }
    }

    /// The process exit status: 0, 1 or 3 (2 is an error, see `main`).
    pub fn exit_status(self) -> u8 {
        match self {
            Outcome::Success => 0,
            Outcome::Failure => 1,
            Outcome::NotCertified => 3,
        }
    }
}

/// Merges the results of `manifest`, prints the tables and writes the reports into `out`;
/// returns the outcome (the combined verdict, or a failure when a run has no valid result) and
/// the studies (none in that case).
fn merge_and_report(
    manifest: &Manifest,
    results: &Path,
    out: &Path,
) -> Result<(Outcome, Vec<StudyResult>), InputError> {
    let merged = merge(manifest, results)?;
    let folder = if out.as_os_str().is_empty() {
        Path::new(".")
    } else {
        out
    };
    if !merged.problems.is_empty() {
        outln!(
            "{} runs without a valid result (run them with `verify run`, then merge again):",
            merged.problems.len()
        )?;
        for problem in &merged.problems {
            outln!("  {problem}")?;
        }
        outln!("no reports written")?;
        outln!("verdict: INCOMPLETE")?;
        return Ok((Outcome::Failure, Vec::new()));
    }
    for study in &merged.studies {
        print_study(study)?;
    }
    let written = write_study_reports(out, manifest, &merged.studies)?;
    contact_input::written::record(folder, &written)?;
    outln!(
        "\ncase {} ({}), d = {}, l = {}",
        manifest.case,
        manifest.origin,
        manifest.dim,
        manifest.degree
    )?;
    for path in written {
        outln!("wrote {}", path.display())?;
    }
    let verdict = merged.verdict();
    outln!("verdict: {} ({})", verdict.label(), verdict.explanation())?;
    Ok((Outcome::of(verdict), merged.studies))
}

/// Runs the command line; returns how it ended ([`Outcome`]).
pub fn main_with(cli: Cli) -> Result<Outcome, InputError> {
    match cli.command {
        None => match &cli.regularity {
            Some(sweep) => run_regularity(&cli.study, sweep, cli.fresh),
            None => run_in_process(&cli.study, cli.fresh),
        },
        Some(Command::Plan { study, manifest }) => {
            let (planned, out) = plan_study(&study)?;
            let path = manifest.unwrap_or_else(|| out.join("manifest.json"));
            let (folder, name) = folder_and_name(&path);
            contact_input::written::check_replaceable(&folder, &name, study.overwrite)?;
            write_manifest(&path, &planned)?;
            contact_input::written::record(&folder, std::slice::from_ref(&path))?;
            let cost: f64 = planned.runs.iter().map(|r| r.cost).sum();
            outln!(
                "wrote {} (estimated cost {cost:.3e} unknowns × steps)",
                path.display()
            )?;
            // for scripts: the size of a job array
            outln!("runs: {}", planned.runs.len())?;
            Ok(Outcome::Success)
        }
        Some(Command::Run {
            manifest,
            index,
            shard: share,
            results,
            fresh,
            threads,
        }) => {
            set_threads(threads)?;
            let planned = read_manifest(&manifest)?;
            let selection = match (index, share) {
                (Some(index), _) if index >= planned.runs.len() => {
                    return Err(InputError::InvalidInput(format!(
                        "--index {index}: the manifest has {} runs (0 ..= {})",
                        planned.runs.len(),
                        planned.runs.len().saturating_sub(1)
                    )))
                }
                (Some(index), _) => vec![index],
                (None, Some(text)) => {
                    let (i, n) = parse_shard(&text, planned.runs.len())?;
                    shard(&planned, i, n)
                }
                (None, None) => {
                    return Err(InputError::InvalidInput(
                        "verify run: give --index I or --shard I/N".to_string(),
                    ))
                }
            };
            let results = results_folder(&manifest, results);
            let executed = execute_manifest(&planned, &selection, &results, fresh)?;
            outln!(
                "cached: {} runs, computed: {} runs (results in {})",
                executed.cached,
                executed.computed,
                results.display()
            )?;
            Ok(Outcome::Success)
        }
        Some(Command::Baseline {
            cases,
            orders,
            reports,
            tolerance,
            threads,
            fresh,
        }) => regenerate_baseline(&cases, &orders, &reports, tolerance, threads, fresh),
        Some(Command::Merge {
            manifest,
            results,
            out,
            overwrite,
        }) => {
            let planned = read_manifest(&manifest)?;
            let results = results_folder(&manifest, results);
            let out =
                out.unwrap_or_else(|| manifest.parent().unwrap_or(Path::new("")).to_path_buf());
            if !out.as_os_str().is_empty() {
                check_out(&out)?;
            }
            let folder = if out.as_os_str().is_empty() {
                Path::new(".")
            } else {
                &out
            };
            contact_input::written::check_replaceable(folder, &report_names(&planned), overwrite)?;
            Ok(merge_and_report(&planned, &results, &out)?.0)
        }
    }
}

/// A whole study in this process: plan (the manifest `<out>/manifest.json`), run the runs that
/// `<out>/runs/` does not hold yet (all with `fresh`), merge and report.
fn run_in_process(args: &StudyArgs, fresh: bool) -> Result<Outcome, InputError> {
    let (manifest, out) = plan_study(args)?;
    check_planned_out(&manifest, &out, args.overwrite)?;
    Ok(run_planned(&manifest, &out, fresh)?.0)
}

/// Checks that the reports of `manifest` and the manifest itself can be written into `out`.
fn check_planned_out(manifest: &Manifest, out: &Path, overwrite: bool) -> Result<(), InputError> {
    check_out(out)?;
    let mut names = report_names(manifest);
    names.push("manifest.json".to_string());
    contact_input::written::check_replaceable(out, &names, overwrite)
}

/// Runs a planned study in this process: writes the manifest into `out`, runs the runs that
/// `<out>/runs/` does not hold yet (all with `fresh`), merges and reports.
fn run_planned(
    manifest: &Manifest,
    out: &Path,
    fresh: bool,
) -> Result<(Outcome, Vec<StudyResult>), InputError> {
    let started = std::time::Instant::now();
    let path = out.join("manifest.json");
    write_manifest(&path, manifest)?;
    contact_input::written::record(out, std::slice::from_ref(&path))?;
    let results = out.join("runs");
    let all: Vec<usize> = (0..manifest.runs.len()).collect();
    let executed = execute_manifest(manifest, &all, &results, fresh)?;
    outln!(
        "cached: {} runs, computed: {} runs (results in {})",
        executed.cached,
        executed.computed,
        results.display()
    )?;
    let outcome = merge_and_report(manifest, &results, out)?;
    outln!("{:.1} s", started.elapsed().as_secs_f64())?;
    Ok(outcome)
}

/// `verify --regularity NAME=…`: the h-study of the case for each value of the exponent NAME
/// ([`crate::regularity`]), each in `<out>/NAME=<value>/`, then the sweep's reports in `<out>`.
/// Every value is planned (its case validated, its studies checked against the memory) and
/// every output folder checked before the first run. The outcome is a failure when a run has
/// no result or a study whose case satisfies (5.7) fails the theorem's rate; outside the
/// assumptions the rates are reported, not judged.
fn run_regularity(args: &StudyArgs, sweep: &str, fresh: bool) -> Result<Outcome, InputError> {
    use crate::regularity::report::{report_names, table, write_reports, SweepPoint};
    use crate::regularity::{case_with, check_sweep, parse_sweep, value_folder};
    check_study_options(args)?;
    let mut sweep = parse_sweep(sweep)?;
    let (text, origin) = load_case(args)?;
    let file = parse_case_file(&text, &origin)?;
    check_sweep(&mut sweep, &file, &origin)?;
    let out = args.out.clone().unwrap_or_else(|| {
        PathBuf::from(DEFAULT_OUT)
            .join(&file.name)
            .join(format!("l{}", args.order))
            .join(format!("regularity-{}", sweep.name))
    });
    let mut planned = Vec::with_capacity(sweep.values.len());
    for &value in &sweep.values {
        let (value_text, value_origin) = case_with(&text, &origin, &sweep.name, value)?;
        let value_args = StudyArgs {
            studies: vec!["h".to_string()],
            out: Some(out.join(value_folder(&sweep.name, value))),
            ..args.clone()
        };
        let (manifest, value_out) = plan_case(&value_args, &value_text, &value_origin)?;
        planned.push((value, manifest, value_out));
    }
    check_out(&out)?;
    contact_input::written::check_replaceable(&out, &report_names(args.order), args.overwrite)?;
    for (_, manifest, value_out) in &planned {
        check_planned_out(manifest, value_out, args.overwrite)?;
    }
    let started = std::time::Instant::now();
    let mut points = Vec::with_capacity(planned.len());
    let mut outcome = Outcome::Success;
    for (value, manifest, value_out) in &planned {
        outln!("\n{} = {value}", sweep.name)?;
        let (value_outcome, studies) = run_planned(manifest, value_out, fresh)?;
        let Some(study) = studies.into_iter().next() else {
            outcome = Outcome::Failure;
            continue;
        };
        let judged = sweep.profile(*value).inside_assumptions(args.order);
        if value_outcome == Outcome::Failure && judged {
            outcome = Outcome::Failure;
        }
        points.push(SweepPoint {
            value: *value,
            study,
        });
    }
    outln!("\n{}", table(&sweep, &points))?;
    if points.is_empty() {
        outln!("no study has a result: no sweep reports written")?;
        return Ok(Outcome::Failure);
    }
    let written = write_reports(&out, &file.name, &origin, args.order, &sweep, &points)?;
    contact_input::written::record(&out, &written)?;
    for path in written {
        outln!("wrote {}", path.display())?;
    }
    outln!("{:.1} s", started.elapsed().as_secs_f64())?;
    Ok(outcome)
}

/// `verify baseline`: regenerates `reports/<case>/l<order>/` for the named built-in cases (all
/// when none is named) and orders, each as a whole study in this process, and prints, per
/// baseline, how many runs were compared and every error whose relative change exceeds
/// `tolerance` against the `errors.csv` it replaced. Everything is checked before the first
/// study runs.
fn regenerate_baseline(
    cases: &[String],
    orders: &[usize],
    reports: &Path,
    tolerance: f64,
    threads: Option<usize>,
    fresh: bool,
) -> Result<Outcome, InputError> {
    use crate::baseline::{baseline_path, BaselineErrors};
    if let Some(unknown) = cases
        .iter()
        .find(|name| !BUILT_IN_CASES.iter().any(|(n, _)| n == name))
    {
        return Err(InputError::InvalidInput(format!(
            "--case `{unknown}`: the baseline holds the built-in cases only ({})",
            BUILT_IN_CASES.map(|(n, _)| n).join(", ")
        )));
    }
    if let Some(order) = orders.iter().find(|o| !(1..=2).contains(*o)) {
        return Err(InputError::InvalidInput(format!(
            "--order must be 1 or 2, got {order}"
        )));
    }
    if !(tolerance.is_finite() && tolerance >= 0.0) {
        return Err(InputError::InvalidInput(format!(
            "--tolerance {tolerance}: must be a finite number ≥ 0"
        )));
    }
    set_threads(threads)?;
    let selected: Vec<&str> = BUILT_IN_CASES
        .iter()
        .map(|(name, _)| *name)
        .filter(|name| cases.is_empty() || cases.iter().any(|c| c == name))
        .collect();
    let mut verdicts = Vec::new();
    let mut lines = Vec::new();
    for case in selected {
        for &order in orders {
            let out = baseline_path(reports, case, order);
            let errors = out.join("errors.csv");
            let old = if errors.exists() {
                Some(BaselineErrors::read(&errors)?)
            } else {
                None
            };
            let args = StudyArgs {
                order,
                dim: 2,
                case: Some(case.to_string()),
                levels: None,
                studies: STUDY_NAMES.map(String::from).to_vec(),
                out: Some(out.clone()),
                // the pool is set up once, above
                threads: None,
                memory_limit: None,
                // regenerating the baseline replaces its files, and only those
                overwrite: true,
                // the baseline holds the built-in cases as written
                set: Vec::new(),
            };
            verdicts.push(run_in_process(&args, fresh)?);
            let new = BaselineErrors::read(&errors)?;
            lines.push(match old {
                None => format!("{}: new baseline, {} runs", out.display(), new.rows.len()),
                Some(old) => {
                    let comparison = old.compare(&new, tolerance);
                    let mut text = format!(
                        "{}: {} runs compared ({} removed, {} added), largest relative change {:.1e}, {} errors moved beyond {tolerance:.0e}",
                        out.display(),
                        comparison.compared,
                        comparison.only_old,
                        comparison.only_new,
                        comparison.largest,
                        comparison.moved.len()
                    );
                    for moved in &comparison.moved {
                        let (study, level, steps) = &moved.run;
                        text += &format!(
                            "\n    {study}-study level {level}, {steps} steps: {} {} -> {}",
                            moved.component,
                            format_or_dash(moved.old.unwrap_or(f64::NAN), |v| format!("{v:.9e}")),
                            format_or_dash(moved.new.unwrap_or(f64::NAN), |v| format!("{v:.9e}")),
                        );
                    }
                    text
                }
            });
        }
    }
    outln!("\nbaseline:")?;
    for line in lines {
        outln!("  {line}")?;
    }
    Ok(verdicts.into_iter().max().unwrap_or(Outcome::Success))
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    /// `verify --help` names every built-in case under `--case`.
    #[test]
    fn case_help_names_every_built_in_case() {
        let command = Cli::command();
        let case = command
            .get_arguments()
            .find(|a| a.get_id() == "case")
            .expect("--case is an option of the single-process run");
        let help = case.get_help().expect("--case has a help text").to_string();
        for (name, _) in BUILT_IN_CASES {
            assert!(help.contains(name), "--case help lacks {name}: {help}");
        }
    }
}
