//! The problem file as written in TOML: one struct per table (serde refuses unknown keys), the
//! checks of `[solver]`, reading and parsing the file, and the error of a problem-file key.

use contact_damage::scheme::velocity::TangentUpdate;
use contact_damage::scheme::SchemeSettings;
use contact_damage::solvers::box_qp::BoxQpMethod;
use contact_input::file::parse_toml;
use contact_input::laws::LawsFile;
use contact_input::scheme::SchemeFile;
use contact_input::sides::GroupFile;
use contact_input::{FileKind, InputError};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// The problem file as written in TOML.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProblemFile {
    /// Short name (default: the file stem); names the default output folder.
    #[serde(default)]
    pub name: Option<String>,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// Space dimension d ∈ {2, 3}.
    pub dim: usize,
    /// Polynomial degree l ∈ {1, 2}.
    pub degree: usize,
    /// Final time T > 0.
    pub final_time: f64,
    /// Number of time steps N ≥ 1.
    pub steps: usize,
    /// Named constants usable in every expression.
    #[serde(default)]
    pub constants: BTreeMap<String, f64>,
    /// The mesh.
    pub mesh: MeshFile,
    /// Constitutive laws (as in the verification case files).
    pub laws: LawsFile,
    /// Loads, gap, initial data.
    #[serde(default)]
    pub loads: LoadsFile,
    /// What to save.
    #[serde(default)]
    pub output: OutputFile,
    /// Tolerances and iteration limits of the solvers.
    #[serde(default)]
    pub solver: SolverFile,
    /// Variants of the scheme (`contact = "explicit"` or `"implicit"`).
    #[serde(default)]
    pub scheme: SchemeFile,
    /// `[[displacement]]`: parts of Γ1 with prescribed components.
    #[serde(default)]
    pub displacement: Vec<DisplacementFile>,
}

/// One `[[displacement]]`: a box side or Gmsh group with prescribed components u_D,i(x, t).
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct DisplacementFile {
    /// A box side (`x_min`, …) or a Gmsh physical group name.
    pub part: String,
    /// u_D,x in x, y, z, t; absent: free.
    #[serde(default)]
    pub x: Option<String>,
    /// u_D,y.
    #[serde(default)]
    pub y: Option<String>,
    /// u_D,z (3D).
    #[serde(default)]
    pub z: Option<String>,
    /// The part is a symmetry plane: where it meets Γ3 it must fix components tangential to
    /// Γ3 only, so that its nodes there stay in the contact rule (checked when the run starts).
    #[serde(default)]
    pub symmetry: bool,
}

/// Most uniform refinements of a Gmsh mesh in a problem file (`mesh.gmsh.refinements`).
pub const MAX_REFINEMENTS: usize = 8;

/// `[mesh]`: exactly one of `box` and `gmsh`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshFile {
    /// A box refined into `cells` intervals per axis.
    #[serde(rename = "box", default)]
    pub box_mesh: Option<BoxFile>,
    /// A Gmsh MSH 4.1 file.
    #[serde(default)]
    pub gmsh: Option<GmshFile>,
}

/// `mesh.box`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxFile {
    /// Lower corner.
    pub lower: Vec<f64>,
    /// Upper corner.
    pub upper: Vec<f64>,
    /// Intervals per axis.
    pub cells: Vec<usize>,
    /// Side (`x_min`, …) → `clamped`, `traction` or `contact`; unlisted sides are traction.
    #[serde(default)]
    pub sides: BTreeMap<String, String>,
}

/// `mesh.gmsh`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GmshFile {
    /// Path of the `.msh` file, relative to the problem file.
    pub file: String,
    /// Groups of Γ1.
    #[serde(default)]
    pub clamped: Vec<GroupFile>,
    /// Groups of Γ2.
    #[serde(default)]
    pub traction: Vec<GroupFile>,
    /// Groups of Γ3.
    #[serde(default)]
    pub contact: Vec<GroupFile>,
    /// Uniform refinements applied to the mesh after reading it (each triangle into 4, each
    /// tetrahedron into 8; [`contact_damage::fem::mesh::refine_uniform`]); the groups are kept.
    #[serde(default)]
    pub refinements: usize,
}

/// `[loads]`: expressions; missing entries are zero (β0 = 1, g = 0).
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LoadsFile {
    /// f0 components in x, y, z, t.
    #[serde(default)]
    pub body_force: Option<Vec<String>>,
    /// f2 components on Γ2 in x, y, z, t, nx, ny, nz.
    #[serde(default)]
    pub traction: Option<Vec<String>>,
    /// Piecewise-linear load curve [[t, factor], …] multiplying f2.
    #[serde(default)]
    pub traction_curve: Option<Vec<Vec<f64>>>,
    /// g on Γ3 in x, y, z, t (may be negative).
    #[serde(default)]
    pub gap: Option<String>,
    /// u0 components in x, y, z.
    #[serde(default)]
    pub initial_displacement: Option<Vec<String>>,
    /// β0 ∈ [0, 1] in x, y, z.
    #[serde(default)]
    pub initial_damage: Option<String>,
}

/// `[output]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputFile {
    /// Save every `every`-th step (the last step is always saved).
    #[serde(default = "one")]
    pub every: usize,
    /// Output folder (relative to the working directory); default `results/<name>`.
    #[serde(default)]
    pub dir: Option<String>,
    /// Times of the damage pictures `damage_NNNNNN.svg` (each drawn at the nearest step);
    /// default T/2 and T.
    #[serde(default)]
    pub pictures: Option<Vec<f64>>,
    /// Encoding of the arrays of the VTU files: `"binary"` (default) or `"ascii"`.
    #[serde(default)]
    pub vtu: Option<String>,
    /// The line of Γ3 recorded in `contact_history.csv`; default a line across the middle of
    /// Γ3 ([`crate::contact_line`]).
    #[serde(default)]
    pub profile: Option<ProfileFile>,
    /// The point about which `history.csv` takes the moment of the contact tractions (default
    /// the origin).
    #[serde(default)]
    pub moment_about: Option<Vec<f64>>,
}

/// `output.profile`: the contact nodes within `width` of the segment from `from` to `to`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ProfileFile {
    /// Start of the segment (d coordinates), where s = 0.
    pub from: Vec<f64>,
    /// End of the segment (d coordinates).
    pub to: Vec<f64>,
    /// Largest distance of a recorded node from the segment (default half a node spacing of
    /// Γ3).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub width: Option<f64>,
}

/// `[solver]`: tolerances and iteration limits; missing entries keep the solver's defaults
/// ([`SchemeSettings::default`]).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverFile {
    /// Relative KKT residual at which the velocity step (5.1) stops (default 1e-10).
    pub velocity_tolerance: Option<f64>,
    /// Largest number of (proximal) Newton iterations of the velocity step (default 50).
    pub max_newton: Option<usize>,
    /// Relative KKT residual of the condensed friction problems (default 1e-12).
    pub friction_tolerance: Option<f64>,
    /// Largest number of semismooth Newton systems of a friction problem (default 100).
    pub friction_max_newton: Option<usize>,
    /// Largest number of proximal-gradient steps of a friction problem (default 20000).
    pub friction_max_gradient: Option<usize>,
    /// Scaled KKT residual at which the damage step (5.2) stops (default 1e-12).
    pub damage_tolerance: Option<f64>,
    /// Largest number of iterations of the damage step (default 100).
    pub damage_max_iterations: Option<usize>,
    /// Algorithm of the damage step: `"multigrid"` (default) or `"active-set"`
    /// ([`contact_damage::solvers::box_qp::BoxQpMethod`]).
    pub damage_method: Option<String>,
    /// Model matrix of the velocity step with a nonlinear 𝒜: `"frozen"` (default) or
    /// `"newton"` ([`contact_damage::scheme::velocity::TangentUpdate`]).
    pub tangent: Option<String>,
}

/// Largest tolerance accepted in `[solver]`: every variational inequality is solved to a
/// residual far below the discretization error, which no mesh of a simulation brings near 1e-6.
pub const LOOSEST_TOLERANCE: f64 = 1e-6;

impl SolverFile {
    /// The solver settings: the defaults with the entries of the file, each checked.
    pub fn settings(&self, origin: &str) -> Result<SchemeSettings, InputError> {
        let mut settings = SchemeSettings::default();
        let tolerance = |key: &str, value: Option<f64>, target: &mut f64| {
            if let Some(value) = value {
                if !(value > 0.0 && value <= LOOSEST_TOLERANCE) {
                    return Err(problem_error(
                        origin,
                        &format!("solver.{key}"),
                        format!(
                            "must lie in (0, {LOOSEST_TOLERANCE:e}] so that the solve stays far below the discretization error, got {value}"
                        ),
                    ));
                }
                *target = value;
            }
            Ok(())
        };
        let limit = |key: &str, value: Option<usize>, target: &mut usize| {
            if let Some(value) = value {
                if value == 0 {
                    return Err(problem_error(
                        origin,
                        &format!("solver.{key}"),
                        "must be at least 1",
                    ));
                }
                *target = value;
            }
            Ok(())
        };
        let velocity = &mut settings.velocity;
        tolerance(
            "velocity_tolerance",
            self.velocity_tolerance,
            &mut velocity.tolerance,
        )?;
        limit("max_newton", self.max_newton, &mut velocity.max_newton)?;
        tolerance(
            "friction_tolerance",
            self.friction_tolerance,
            &mut velocity.friction.tolerance,
        )?;
        limit(
            "friction_max_newton",
            self.friction_max_newton,
            &mut velocity.friction.max_newton,
        )?;
        limit(
            "friction_max_gradient",
            self.friction_max_gradient,
            &mut velocity.friction.max_gradient,
        )?;
        tolerance(
            "damage_tolerance",
            self.damage_tolerance,
            &mut settings.damage.tolerance,
        )?;
        limit(
            "damage_max_iterations",
            self.damage_max_iterations,
            &mut settings.damage.max_iterations,
        )?;
        if let Some(method) = &self.damage_method {
            settings.damage.method = match method.as_str() {
                "multigrid" => BoxQpMethod::MonotoneMultigrid,
                "active-set" => BoxQpMethod::ActiveSet,
                other => {
                    return Err(problem_error(
                        origin,
                        "solver.damage_method",
                        format!("must be \"multigrid\" or \"active-set\", got \"{other}\""),
                    ))
                }
            };
        }
        if let Some(tangent) = &self.tangent {
            settings.velocity.tangent = match tangent.as_str() {
                "frozen" => TangentUpdate::Frozen,
                "newton" => TangentUpdate::Newton,
                other => {
                    return Err(problem_error(
                        origin,
                        "solver.tangent",
                        format!("must be \"frozen\" or \"newton\", got \"{other}\""),
                    ))
                }
            };
        }
        Ok(settings)
    }
}

fn one() -> usize {
    1
}

impl Default for OutputFile {
    fn default() -> Self {
        Self {
            every: 1,
            dir: None,
            pictures: None,
            vtu: None,
            profile: None,
            moment_about: None,
        }
    }
}

impl DisplacementFile {
    /// The components given (`"x"`, `"y"`, `"z"`).
    pub(super) fn component_names(&self) -> Vec<String> {
        [("x", &self.x), ("y", &self.y), ("z", &self.z)]
            .iter()
            .filter(|(_, expr)| expr.is_some())
            .map(|(name, _)| name.to_string())
            .collect()
    }
}

/// The error of `key` in the problem file `origin`.
pub(super) fn problem_error(origin: &str, key: &str, message: impl Into<String>) -> InputError {
    FileKind::Problem.error(origin, key, message)
}

/// Reads and parses a problem file (TOML errors carry line and column).
pub fn read_problem_file(path: &Path) -> Result<ProblemFile, InputError> {
    contact_input::regular::check_regular_file(path, "problem file")?;
    let text = std::fs::read_to_string(path)
        .map_err(|e| InputError::io("reading problem file", path, e))?;
    parse_problem_file(&text, &path.display().to_string())
}

/// Parses problem-file text; `origin` names it in errors.
pub fn parse_problem_file(text: &str, origin: &str) -> Result<ProblemFile, InputError> {
    parse_toml(text, FileKind::Problem, origin)
}
