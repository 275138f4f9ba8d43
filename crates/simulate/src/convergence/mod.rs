//! Solution verification of a simulation: `simulate --convergence K PROBLEM.toml --out DIR`.
//!
//! The problem is run on K levels i = 0 … K−1 refined together in space and time by one ratio
//! r (`--ratio`, default 2): a box mesh gets `cells × r^i` intervals per axis and every level
//! `steps × r^i` time steps, so h and k shrink together by r from level to level (h is the
//! largest cell diameter of the built mesh, k = T/N). Each level is an ordinary run in
//! `DIR/level_i` (its `history.csv`, VTU files, pictures).
//!
//! The quantities of interest are read from the levels' `history.csv` (definitions in
//! [`crate::history`]): the total normal contact force and the measure of the contact zone at
//! the times of `--at` (default T/2 and T; each must be a time step of the coarsest level, hence
//! of every level), and at T the longest accumulated slip, the mean damage and the viscous and
//! frictional dissipated energies ∫_0^T (𝒜ε(u̇), ε(u̇)) dt and ∫_0^T ∫_Γ3 μ p_ν |u̇_τ| da dt by
//! the rectangle rule of the scheme. Each quantity goes through the procedure of [`gci`]
//! (Celik et al. 2008; [`report`] writes the files).

pub mod gci;
pub mod report;

use crate::history::HISTORY_FILE;
use crate::problem::{read_problem_file, ProblemFile, ProblemSetup, MAX_REFINEMENTS};
use crate::run::{run, RunOptions};
use contact_input::InputError;
use gci::{least_squares, triplets, LeastSquares, Triplet};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Options of `simulate --convergence`.
#[derive(Debug, Clone)]
pub struct ConvergenceOptions {
    /// K ≥ 3 levels.
    pub levels: usize,
    /// Refinement ratio r > 1 of h and k between levels.
    pub ratio: f64,
    /// Times of the contact force and zone (None: T/2 and T).
    pub at: Option<Vec<f64>>,
    /// Output folder: one `level_i` folder per level and the reports.
    pub out: PathBuf,
    /// Start afresh in level folders that hold a run.
    pub overwrite: bool,
    /// No progress lines.
    pub quiet: bool,
    /// Largest estimated memory of a level, in bytes (`--memory-limit`; default: the physical
    /// memory).
    pub memory_limit: Option<f64>,
}

/// The most levels of a study (`--convergence`): with the smallest whole ratio, 2, the finest
/// of 16 levels has 2¹⁵ times the cells per axis of the coarsest.
pub const MAX_LEVELS: usize = 16;

/// One level of the study.
#[derive(Debug, Clone, Serialize)]
pub struct Level {
    /// i (0 = coarsest).
    pub index: usize,
    /// Intervals per axis of a box mesh (empty for a Gmsh mesh).
    pub cells: Vec<usize>,
    /// Uniform refinements of a Gmsh mesh (`None` for a box).
    pub refinements: Option<usize>,
    /// N.
    pub steps: usize,
    /// Largest cell diameter.
    pub h: f64,
    /// k = T/N.
    pub k: f64,
    /// The run's folder, relative to `--out` (`level_i`).
    pub dir: String,
    /// Largest KKT residuals of the run.
    pub max_kkt: crate::run::MaxKkt,
}

/// A quantity of interest over the levels, with its GCI analysis.
#[derive(Debug, Clone, Serialize)]
pub struct Quantity {
    /// Column of `history.csv`.
    pub column: String,
    /// The time it is read at.
    pub time: f64,
    /// Its value per level, coarsest first.
    pub values: Vec<f64>,
    /// Consecutive triplets, finest first (the first is the headline: levels K−1, K−2, K−3).
    pub triplets: Vec<Triplet>,
    /// Eça–Hoekstra fit over all levels (K ≥ 4 only).
    pub least_squares: Option<LeastSquares>,
}

impl Quantity {
    /// Name with its time, e.g. `normal_force(t=2.5)`.
    pub fn label(&self) -> String {
        format!("{}(t={})", self.column, self.time)
    }

    /// The headline triplet (the three finest levels).
    pub fn finest(&self) -> &Triplet {
        &self.triplets[0]
    }

    /// True when every triplet converges monotonically: only then is an order reported.
    pub fn monotone(&self) -> bool {
        self.triplets.iter().all(|t| t.reported().is_some())
    }
}

/// The result of the study.
#[derive(Debug, Clone, Serialize)]
pub struct Study {
    /// Problem name.
    pub name: String,
    /// The problem file.
    pub origin: String,
    /// r.
    pub ratio: f64,
    /// T.
    pub final_time: f64,
    /// Levels, coarsest first.
    pub levels: Vec<Level>,
    /// The quantities.
    pub quantities: Vec<Quantity>,
}

/// The columns read at T only.
pub const FINAL_COLUMNS: [&str; 4] = [
    "max_accumulated_slip",
    "mean_damage",
    "viscous_dissipation",
    "friction_dissipation",
];
/// The columns read at every time of `--at`.
pub const TIMED_COLUMNS: [&str; 2] = ["normal_force", "contact_zone"];

fn invalid(message: String) -> InputError {
    InputError::InvalidInput(message)
}

/// `factor` as a whole number if `base × factor` is one (within rounding), for `what`.
fn scaled(base: usize, factor: f64, what: &str) -> Result<usize, InputError> {
    if base == 0 {
        return Err(invalid(format!("{what} must be at least 1, got 0")));
    }
    let value = base as f64 * factor;
    let whole = value.round();
    if (value - whole).abs() > 1e-9 * value.max(1.0) || whole < 1.0 {
        return Err(invalid(format!(
            "--ratio: {what} = {base} × {factor} = {value} is not a whole number; choose a ratio that keeps it whole (e.g. 2)"
        )));
    }
    Ok(whole as usize)
}

/// The problem file of level `index`: cells and steps multiplied by `ratio^index`.
pub fn level_file(
    file: &ProblemFile,
    origin: &str,
    ratio: f64,
    index: usize,
) -> Result<ProblemFile, InputError> {
    let factor = ratio.powi(index as i32);
    let mut level = file.clone();
    level.steps = scaled(file.steps, factor, &format!("{origin}: steps"))?;
    if let Some(mesh) = &mut level.mesh.box_mesh {
        for cells in mesh.cells.iter_mut() {
            *cells = scaled(*cells, factor, &format!("{origin}: mesh.box.cells"))?;
        }
    } else if let Some(gmsh) = &mut level.mesh.gmsh {
        // uniform refinement halves h: level i is the mesh refined i more times
        if index > 0 && (ratio - 2.0).abs() > 1e-12 {
            return Err(invalid(format!(
                "{origin}: mesh.gmsh `{}`: a Gmsh mesh is refined uniformly, which halves h; use --ratio 2",
                gmsh.file
            )));
        }
        gmsh.refinements += index;
    }
    Ok(level)
}

/// The mesh of a level in words: `cells [40, 20]` or `Gmsh mesh refined 2 times`.
pub fn mesh_label(cells: &[usize], refinements: Option<usize>) -> String {
    match refinements {
        Some(r) => format!("Gmsh mesh refined {r} times"),
        None => format!("cells {cells:?}"),
    }
}

/// The rows of a `history.csv`: the header and the values (an empty field is NaN).
pub fn read_history(path: &Path) -> Result<(Vec<String>, Vec<Vec<f64>>), InputError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| InputError::io("reading the history", path, e))?;
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .ok_or_else(|| invalid(format!("{}: empty", path.display())))?
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .enumerate()
        .map(|(i, line)| {
            line.split(',')
                .map(|field| {
                    if field.is_empty() {
                        Ok(f64::NAN)
                    } else {
                        field.parse::<f64>().map_err(|_| {
                            invalid(format!(
                                "{}: line {}: `{field}` is not a number",
                                path.display(),
                                i + 2
                            ))
                        })
                    }
                })
                .collect()
        })
        .collect::<Result<_, _>>()?;
    Ok((header, rows))
}

/// The value of `column` at step `step` of a history.
fn history_value(
    path: &Path,
    header: &[String],
    rows: &[Vec<f64>],
    column: &str,
    step: usize,
) -> Result<f64, InputError> {
    let c = header
        .iter()
        .position(|h| h == column)
        .ok_or_else(|| invalid(format!("{}: no column `{column}`", path.display())))?;
    let row = rows
        .iter()
        .find(|row| row.first() == Some(&(step as f64)))
        .ok_or_else(|| invalid(format!("{}: no row of step {step}", path.display())))?;
    let value = row[c];
    if !value.is_finite() {
        return Err(invalid(format!(
            "{}: `{column}` at step {step} has no finite value",
            path.display()
        )));
    }
    Ok(value)
}

/// The step of the coarsest level at time `t`, which must be one of its time steps.
fn coarse_step(t: f64, final_time: f64, steps: usize) -> Result<usize, InputError> {
    let k = final_time / steps as f64;
    let n = (t / k).round();
    if !(t > 0.0 && t <= final_time) || (n * k - t).abs() > 1e-9 * final_time {
        return Err(invalid(format!(
            "--at: {t} must be a time step of the coarsest level in (0, T = {final_time}] (a multiple of k = {k})"
        )));
    }
    Ok(n as usize)
}

/// Refuses, unless `overwrite`, an output folder `out` that holds a file (or anything else) of
/// one of the report `names`; refuses an `out` that exists and is no folder.
fn check_fresh_reports(out: &Path, names: &[String], overwrite: bool) -> Result<(), InputError> {
    if out.exists() && !out.is_dir() {
        return Err(invalid(format!(
            "output folder `{}` (--out) exists and is not a folder; choose another --out",
            out.display()
        )));
    }
    if overwrite {
        return Ok(());
    }
    let present: Vec<String> = names
        .iter()
        .filter(|name| std::fs::symlink_metadata(out.join(name)).is_ok())
        .map(|name| format!("`{name}`"))
        .collect();
    if present.is_empty() {
        return Ok(());
    }
    Err(invalid(format!(
        "output folder `{}` (--out) holds {}, a report name of --convergence: not overwriting it; start afresh with --overwrite (which replaces only the files of the names this command writes) or choose another --out",
        out.display(),
        present.join(", ")
    )))
}

/// A level's history: its path, its header and its rows.
type History = (PathBuf, Vec<String>, Vec<Vec<f64>>);

/// Checks every level of a study before the first run: its size from its file, finest first,
/// before any mesh is built, then the level built and validated (e.g. a Gmsh mesh refined
/// beyond the memory).
fn check_levels(
    files: &[ProblemFile],
    options: &ConvergenceOptions,
    origin: &str,
    path: &Path,
) -> Result<(), InputError> {
    let limit = RunOptions {
        memory_limit: options.memory_limit,
        ..RunOptions::default()
    }
    .memory_limit();
    for (index, level) in files.iter().enumerate().rev() {
        if let Some(gmsh) = &level.mesh.gmsh {
            if gmsh.refinements > MAX_REFINEMENTS {
                return Err(invalid(format!(
                    "--convergence {}: level {index} would refine the Gmsh mesh {} times, above the limit of {MAX_REFINEMENTS} (mesh.gmsh.refinements + level); use fewer levels",
                    options.levels, gmsh.refinements
                )));
            }
        }
        if let Some(mesh) = &level.mesh.box_mesh {
            contact_damage::algebra::memory::check(
                contact_damage::algebra::memory::estimate_box(&mesh.cells, level.degree),
                limit,
                &format!(
                    "--convergence {}: level {index} ({}) of {origin}",
                    options.levels,
                    mesh_label(&mesh.cells, None)
                ),
                "--memory-limit",
            )?;
        }
    }
    for level in files {
        match level.dim {
            2 => drop(ProblemSetup::<2>::new(level.clone(), path)?),
            3 => drop(ProblemSetup::<3>::new(level.clone(), path)?),
            other => {
                return Err(invalid(format!(
                    "{origin}: dim must be 2 or 3, got {other}"
                )));
            }
        }
    }
    Ok(())
}

/// The quantities of the study: each timed column at each time and each final column, its
/// value on every level (read from the level's history at the step of that time), the GCI
/// triplets and, from four levels on, the least-squares fit.
fn study_quantities(
    times: &[f64],
    coarse_steps: &[usize],
    file: &ProblemFile,
    histories: &[History],
    levels: &[Level],
) -> Result<Vec<Quantity>, InputError> {
    let final_time = file.final_time;
    let mut wanted: Vec<(String, f64, usize)> = Vec::new();
    for (&t, &n) in times.iter().zip(coarse_steps) {
        for column in TIMED_COLUMNS {
            wanted.push((column.to_string(), t, n));
        }
    }
    for column in FINAL_COLUMNS {
        wanted.push((column.to_string(), final_time, file.steps));
    }
    let h_finest_first: Vec<f64> = levels.iter().rev().map(|l| l.h).collect();
    let mut quantities = Vec::new();
    for (column, time, coarse) in wanted {
        let values: Vec<f64> = histories
            .iter()
            .zip(levels)
            .map(|((path, header, rows), level)| {
                let step = coarse * level.steps / file.steps;
                history_value(path, header, rows, &column, step)
            })
            .collect::<Result<_, _>>()?;
        let finest_first: Vec<f64> = values.iter().rev().copied().collect();
        let triplets = triplets(&h_finest_first, &finest_first)
            .map_err(|e| invalid(format!("{column} at t = {time}: {e}")))?;
        let least_squares = (values.len() > 3)
            .then(|| least_squares(&h_finest_first, &finest_first))
            .flatten();
        quantities.push(Quantity {
            column,
            time,
            values,
            triplets,
            least_squares,
        });
    }
    Ok(quantities)
}

/// Runs the study of the problem file at `path`.
pub fn run_convergence(path: &Path, options: &ConvergenceOptions) -> Result<Study, InputError> {
    if options.levels < 3 {
        return Err(invalid(format!(
            "--convergence: needs at least 3 levels, got {}",
            options.levels
        )));
    }
    if options.levels > MAX_LEVELS {
        return Err(invalid(format!(
            "--convergence {}: at most {MAX_LEVELS} levels (each multiplies the cells per axis by --ratio)",
            options.levels
        )));
    }
    if !(options.ratio.is_finite() && options.ratio > 1.0) {
        return Err(invalid(format!(
            "--ratio: must be a number > 1, got {}",
            options.ratio
        )));
    }
    let file = read_problem_file(path)?;
    let origin = path.display().to_string();
    let final_time = file.final_time;
    let times = options
        .at
        .clone()
        .unwrap_or_else(|| vec![0.5 * final_time, final_time]);
    let mut coarse_steps = Vec::new();
    for &t in &times {
        coarse_steps.push(coarse_step(t, final_time, file.steps.max(1))?);
    }
    // the fresh-folder rule of a run, for the reports: none of their names may exist unless
    // --overwrite (which replaces those names only)
    let quantities = times
        .iter()
        .flat_map(|&t| TIMED_COLUMNS.map(|column| (column, t)))
        .chain(FINAL_COLUMNS.map(|column| (column, final_time)));
    check_fresh_reports(
        &options.out,
        &report::file_names(quantities),
        options.overwrite,
    )?;
    let files: Vec<ProblemFile> = (0..options.levels)
        .map(|i| level_file(&file, &origin, options.ratio, i))
        .collect::<Result<_, _>>()?;
    check_levels(&files, options, &origin, path)?;
    let mut levels = Vec::new();
    let mut histories = Vec::new();
    for (index, level) in files.into_iter().enumerate() {
        let name = format!("level_{index}");
        let dir = options.out.join(&name);
        let cells = level
            .mesh
            .box_mesh
            .as_ref()
            .map(|b| b.cells.clone())
            .unwrap_or_default();
        let refinements = level.mesh.gmsh.as_ref().map(|g| g.refinements);
        let steps = level.steps;
        if !options.quiet {
            contact_input::outln!(
                "level {index}: {}, steps {steps} → {}",
                mesh_label(&cells, refinements),
                dir.display()
            )?;
        }
        let run_options = RunOptions {
            out: Some(dir.clone()),
            overwrite: options.overwrite,
            quiet: options.quiet,
            memory_limit: options.memory_limit,
            ..RunOptions::default()
        };
        let (h, outcome) = match level.dim {
            2 => {
                let setup = ProblemSetup::<2>::new(level, path)?;
                (
                    setup.problem.mesh.max_cell_diameter(),
                    run(&setup, &run_options)?,
                )
            }
            3 => {
                let setup = ProblemSetup::<3>::new(level, path)?;
                (
                    setup.problem.mesh.max_cell_diameter(),
                    run(&setup, &run_options)?,
                )
            }
            other => {
                return Err(invalid(format!(
                    "{origin}: dim must be 2 or 3, got {other}"
                )));
            }
        };
        let history_path = dir.join(HISTORY_FILE);
        let (header, rows) = read_history(&history_path)?;
        histories.push((history_path, header, rows));
        levels.push(Level {
            index,
            cells,
            refinements,
            steps,
            h,
            k: final_time / steps as f64,
            dir: name,
            max_kkt: outcome.max_kkt,
        });
    }
    let quantities = study_quantities(&times, &coarse_steps, &file, &histories, &levels)?;
    Ok(Study {
        name: file.name.clone().unwrap_or_else(|| {
            path.file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "problem".into())
        }),
        origin,
        ratio: options.ratio,
        final_time,
        levels,
        quantities,
    })
}
