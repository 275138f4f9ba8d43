//! `simulate`: runs Problem P of Han, Shillor & Sofonea (2001) — viscoelastic body, normal
//! compliance with Coulomb friction, damage — from a TOML problem file, with ParaView output
//! (VTU per saved step, PVD time series), a CSV time history and restarts.
//!
//! - [`problem`]: the problem file and its translation into the solver's problem;
//! - [`run`]: the time loop, the output files and `--resume`;
//! - [`convergence`]: `--convergence K`, solution verification of a problem by the Grid
//!   Convergence Index on K levels refined in h and k together;
//! - [`folder`]: which files of the output folder are ours, and what `--overwrite` and
//!   `--resume` may remove;
//! - [`history`]: the integral quantities of `history.csv` (forces, zones, slip, dissipation, damage);
//! - [`contact_line`]: the line of Γ3 recorded in `contact_history.csv` and the coordinate s
//!   along it;
//! - [`pictures`]: SVG pictures of the damage field and of the contact history on Γ3;
//! - [`zone`]: the contact zone from the zero crossing of the penetration, and the contact force.

pub mod contact_line;
pub mod convergence;
pub mod folder;
pub mod history;
pub mod pictures;
pub mod problem;
pub mod record;
pub mod resume;
pub mod run;
pub mod snapshot;
pub mod watch;
pub mod zone;

use contact_input::{FileKind, InputError};
use std::path::Path;

/// Reads the problem file at `path`, builds it in its dimension and runs it.
pub fn run_file(path: &Path, options: &run::RunOptions) -> Result<run::RunOutcome, InputError> {
    let file = problem::read_problem_file(path)?;
    if let Some(box_file) = &file.mesh.box_mesh {
        // before the mesh is built: a box of 10⁹ cells must not abort in an allocation
        run::check_memory(
            &path.display().to_string(),
            contact_damage::algebra::memory::estimate_box(&box_file.cells, file.degree),
            options,
        )?;
    }
    match file.dim {
        2 => run::run(&problem::ProblemSetup::<2>::new(file, path)?, options),
        3 => run::run(&problem::ProblemSetup::<3>::new(file, path)?, options),
        other => Err(FileKind::Problem.error(
            &path.display().to_string(),
            "dim",
            format!("must be 2 or 3, got {other}"),
        )),
    }
}
