//! The rows of the two CSV reports, `errors.csv` (one row per run) and `rates.csv` (one row
//! per study and error component), from which [`crate::report`] writes the CSV files and
//! [`crate::tables`] the Markdown and LaTeX tables.

use crate::output::finite_or_dash;
use serde::Serialize;

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
    /// See [`ErrorComponents`](crate::error_norms::ErrorComponents).
    #[serde(serialize_with = "finite_or_dash")]
    pub difference_quotient: f64,
    /// See [`ErrorComponents`](crate::error_norms::ErrorComponents).
    #[serde(serialize_with = "finite_or_dash")]
    pub damage: f64,
    /// See [`ErrorComponents`](crate::error_norms::ErrorComponents).
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

/// One row of `rates.csv`: the rates of one error component in one study.
#[derive(Debug, Serialize)]
pub struct RateRow {
    /// Case name.
    pub case: String,
    /// Study kind.
    pub study: &'static str,
    /// Degree l.
    pub degree: usize,
    /// h or k.
    pub variable: &'static str,
    /// Component name.
    pub component: String,
    /// Pairwise rates, coarsest pair first, separated by `;` (`—` where there is none).
    pub pairwise: String,
    /// Least-squares rate over the finest levels.
    #[serde(serialize_with = "finite_or_dash")]
    pub least_squares: f64,
    /// Its standard error.
    #[serde(serialize_with = "finite_or_dash")]
    pub standard_error: f64,
    /// Lower end of its 95 % interval.
    #[serde(serialize_with = "finite_or_dash")]
    pub ci95_low: f64,
    /// Upper end of its 95 % interval.
    #[serde(serialize_with = "finite_or_dash")]
    pub ci95_high: f64,
    /// `yes` / `no` ([`crate::study::is_drifting`]), `—` when undetermined.
    pub drifting: String,
    /// Expected rate (`—` for a quantity the theorem does not bound).
    #[serde(serialize_with = "finite_or_dash")]
    pub expected: f64,
    /// `pass`, `fail`, or `—` when not judged.
    pub verdict: String,
}
