//! The problem file (TOML): mesh, laws, loads, T, N and output, validated and translated into
//! the solver's [`Problem`] (Problem P_V^hk of Han, Shillor & Sofonea 2001, (5.1)–(5.5)).
//!
//! ```toml
//! dim = 2                  # d ∈ {2, 3}
//! degree = 1               # l ∈ {1, 2}
//! final_time = 4.0         # T
//! steps = 80               # N, k = T/N
//! [constants]              # optional named constants for every expression
//! p = 0.2
//! [mesh]                   # either a refined box ...
//! box = { lower = [0, 0], upper = [4, 1], cells = [32, 8], sides = { x_min = "clamped", y_min = "contact" } }
//! # ... or a Gmsh 4.1 file (path relative to the problem file), groups by name or tag:
//! # gmsh = { file = "part.msh", clamped = ["left"], traction = ["top", 7], contact = ["bottom"] }
//! #        (optionally `refinements = r`: the mesh refined uniformly r times, groups kept)
//! [laws]                   # as in the verification case files (docs/reference/problem-file.md)
//! # ...
//! [loads]                  # all optional (zero, resp. β0 = 1)
//! body_force = ["0", "0"]                      # f0 in x, y, z, t
//! traction = ["0", "-p*max(0, ny)"]            # f2 on Γ2 in x, y, z, t, nx, ny, nz
//! traction_curve = [[0, 0], [1, 1], [4, 1]]    # load curve [[t, factor], …]: f2 × factor(t),
//!                                              # piecewise linear, constant outside its times
//! gap = "0"                                    # g in x, y, z, t; may be negative (an obstacle
//!                                              # pushed into the body)
//! initial_displacement = ["0", "0"]            # u0 in x, y, z (= u_D(x, 0) on prescribed parts)
//! initial_damage = "1"                         # β0 in x, y, z
//! [[displacement]]         # prescribed displacement u_i = u_D,i(x, t) on a part of Γ1 (any number)
//! part = "y_max"           # a box side, or a Gmsh group (of `clamped`, or listed nowhere)
//! y = "-0.01*t"            # x, y, z: components in x, y, z, t; a component not given is free
//! [[displacement]]         # a roller (symmetry plane): the normal component fixed, the
//! part = "x_min"           # tangential ones free with zero traction
//! x = "0"
//! [output]
//! every = 1                # save every N-th step (and the last one)
//! dir = "results/NAME"     # default results/<name>, name = file stem unless `name` is given
//! pictures = [2.5, 5.0]    # times of the damage pictures (SVG), default [T/2, T]
//! vtu = "binary"           # arrays of the VTU files: "binary" (base64, ParaView's default) or
//!                          # "ascii" (decimal text); both read back bitwise
//! [scheme]
//! contact = "explicit"     # p_ν at u_{n−1} as in (5.1); "implicit": at u_{n−1} + k v_n (stiff
//!                          # contact at any step; the friction bound stays at u_{n−1})
//! damage = true            # false: a pure contact problem — no damage step (5.2), β stays β0,
//!                          # no damage pictures; laws.damage_source and
//!                          # laws.damage_diffusion may then be left out
//! [solver]                 # all optional; the defaults are shown
//! velocity_tolerance = 1e-10      # relative KKT residual of the velocity step (5.1)
//! max_newton = 50                 # (proximal) Newton iterations of (5.1), nonlinear 𝒜
//! friction_tolerance = 1e-12      # condensed friction problems
//! friction_max_newton = 100
//! friction_max_gradient = 20000
//! damage_tolerance = 1e-12        # scaled KKT residual of the damage step (5.2)
//! damage_max_iterations = 100
//! damage_method = "multigrid"     # box QP of (5.2): "multigrid" (truncated nonsmooth Newton
//!                                 # multigrid, no factorization) or "active-set" (primal-dual
//!                                 # active set with one Cholesky factor, supernodal in 3D)
//! ```
//!
//! Tolerances must lie in (0, 1e-6]: a looser solve would compete with the discretization
//! error. Raising an iteration limit and `--resume` is the way out of a step that did not
//! converge.
//!
//! Box sides not listed are traction sides (Γ2), except the sides of a `[[displacement]]`,
//! which are Γ1. A clamped side or group of no `[[displacement]]` keeps u = 0 (2.5). A part
//! that is `contact` overlaps Γ3 and is refused, as is a `traction` part. The 2D problem is
//! plane strain. The traction may use the outward normal
//! (nx, ny, nz) to act on part of Γ2 only, e.g. `max(0, ny)` selects the top of a box.
//! Every error names the file, the key and the problem ([`InputError::File`] of kind [`FileKind::Problem`]).

use crate::watch::LoadWatch;
use contact_damage::algebra::linalg::FactorKind;
use contact_damage::fem::mesh::{BoundaryPart, Mesh};
use contact_damage::io::gmsh::{read_msh, GroupRef, PhysicalMap};
use contact_damage::io::vtk::VtuEncoding;
use contact_damage::model::fields::{BatchBoundaryVectorField, BatchVectorField};
use contact_damage::scheme::{
    Data, Model, PointScalarField, PrescribedDisplacement, Problem, SchemeSettings,
};
use contact_damage::solvers::box_qp::BoxQpMethod;
use contact_input::expr::compiled::with_registers;
use contact_input::expr::split::BATCH;
use contact_input::expr::{Expr, Program};
use contact_input::file::{parse_expr, parse_toml};
use contact_input::laws::LawsFile;
use contact_input::scheme::SchemeFile;
use contact_input::sides::{component_index, parse_sides, prescribed_sides, GroupFile};
use contact_input::{FileKind, InputError};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Variables of the body force: position and time.
pub const FIELD_VARIABLES: [&str; 4] = ["x", "y", "z", "t"];
/// Variables of the traction f2: position, time and outward unit normal.
pub const TRACTION_VARIABLES: [&str; 7] = ["x", "y", "z", "t", "nx", "ny", "nz"];
/// Variables of the gap and the initial data: position only.
pub const STATIC_VARIABLES: [&str; 3] = ["x", "y", "z"];

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
        }
    }
}

/// A validated problem file in dimension D, ready to run.
pub struct ProblemSetup<const D: usize> {
    /// The file as read.
    pub file: ProblemFile,
    /// Its path as given (names it in errors).
    pub origin: String,
    /// The problem name.
    pub name: String,
    /// The solver problem.
    pub problem: Problem<D>,
    /// Save every `every`-th step.
    pub every: usize,
    /// Default output folder.
    pub output_dir: PathBuf,
    /// Times of the damage pictures, each in (0, T].
    pub pictures: Vec<f64>,
    /// Encoding of the arrays of the VTU files.
    pub vtu: VtuEncoding,
    /// What a saved state must match to be resumed with this problem: `constants`, `laws`,
    /// `loads` (as canonical JSON) and `mesh` (SHA-256 of the vertices, cells and boundary
    /// parts of the built mesh, so that a changed Gmsh file is caught too). `dim`, `degree`,
    /// `final_time` and `steps` are checked on their own; `output` and `solver` may change
    /// between a run and its resumption.
    pub fingerprint: BTreeMap<String, String>,
    /// The first non-finite value of a load expression met during the run (names its key).
    pub load_watch: LoadWatch,
}

/// SHA-256 (hex) of the vertex coordinates, cells and boundary facets with their parts.
pub fn mesh_fingerprint<const D: usize>(mesh: &Mesh<D>) -> String {
    let mut hasher = Sha256::new();
    hasher.update((D as u64).to_le_bytes());
    hasher.update((mesh.num_vertices() as u64).to_le_bytes());
    for vertex in mesh.vertices() {
        for coordinate in vertex {
            hasher.update(coordinate.to_bits().to_le_bytes());
        }
    }
    hasher.update((mesh.num_cells() as u64).to_le_bytes());
    for c in 0..mesh.num_cells() {
        for &v in mesh.cell(c) {
            hasher.update((v as u64).to_le_bytes());
        }
    }
    hasher.update((mesh.num_facets() as u64).to_le_bytes());
    for f in 0..mesh.num_facets() {
        for &v in mesh.facet(f) {
            hasher.update((v as u64).to_le_bytes());
        }
        hasher.update([match mesh.facet_part(f) {
            BoundaryPart::Dirichlet => 1u8,
            BoundaryPart::Neumann => 2,
            BoundaryPart::Contact => 3,
        }]);
    }
    hasher
        .finalize()
        .iter()
        .map(|byte| format!("{byte:02x}"))
        .collect()
}

fn problem_error(origin: &str, key: &str, message: impl Into<String>) -> InputError {
    FileKind::Problem.error(origin, key, message)
}

/// Reads and parses a problem file (TOML errors carry line and column).
pub fn read_problem_file(path: &Path) -> Result<ProblemFile, InputError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| InputError::io("reading problem file", path, e))?;
    parse_problem_file(&text, &path.display().to_string())
}

/// Parses problem-file text; `origin` names it in errors.
pub fn parse_problem_file(text: &str, origin: &str) -> Result<ProblemFile, InputError> {
    parse_toml(text, FileKind::Problem, origin)
}

/// D expressions of a vector field.
fn parse_vector<const D: usize>(
    origin: &str,
    key: &str,
    sources: &[String],
    variables: &[&str],
    constants: &BTreeMap<String, f64>,
) -> Result<[Expr; D], InputError> {
    if sources.len() != D {
        return Err(problem_error(
            origin,
            key,
            format!("need {D} components, got {}", sources.len()),
        ));
    }
    let parsed: Vec<Expr> = sources
        .iter()
        .enumerate()
        .map(|(i, s)| {
            parse_expr(
                FileKind::Problem,
                origin,
                &format!("{key}[{i}]"),
                s,
                variables,
                constants,
            )
        })
        .collect::<Result<_, _>>()?;
    Ok(parsed
        .try_into()
        .unwrap_or_else(|_| unreachable!("the length was checked")))
}

/// The variable values of an expression: the position padded to (x, y, z), then `extra`
/// (t, then the normal for the traction).
fn point_values<const D: usize>(x: &[f64; D], extra: &[f64]) -> Vec<f64> {
    let mut values = [0.0; MAX_VARIABLES];
    let len = fill_point_values(x, extra, &mut values);
    values[..len].to_vec()
}

/// Most variables of a load expression: x, y, z, t and a normal ([`TRACTION_VARIABLES`]).
const MAX_VARIABLES: usize = TRACTION_VARIABLES.len();

/// Lays out the variables of a load expression at the point x in `values`: x, y, z (zero
/// beyond D), then `extra`; returns how many were written.
fn fill_point_values<const D: usize>(
    x: &[f64; D],
    extra: &[f64],
    values: &mut [f64; MAX_VARIABLES],
) -> usize {
    values[..D].copy_from_slice(x);
    values[D..3].fill(0.0);
    values[3..3 + extra.len()].copy_from_slice(extra);
    3 + extra.len()
}

fn eval_vector<const D: usize>(exprs: &[Expr; D], values: &[f64]) -> [f64; D] {
    std::array::from_fn(|i| exprs[i].eval_f64(values))
}

/// The N components of a load field compiled into one program (common subexpressions shared),
/// evaluated per point on f64 without walking the expression trees.
struct CompiledField<const N: usize> {
    program: Program,
}

impl<const N: usize> CompiledField<N> {
    fn new(exprs: &[Expr; N]) -> Self {
        let components: Vec<&Expr> = exprs.iter().collect();
        Self {
            program: Program::fuse(&components),
        }
    }

    /// The components at the point x (the variables of [`fill_point_values`]).
    fn eval<const D: usize>(&self, x: &[f64; D], extra: &[f64]) -> [f64; N] {
        let mut values = [0.0; MAX_VARIABLES];
        let len = fill_point_values(x, extra, &mut values);
        with_registers(|registers: &mut Vec<f64>| {
            self.program.eval_array(&values[..len], registers)
        })
    }
}

/// f0 or f2 given by N expressions, evaluated over a whole batch of points per call (the
/// solver passes all quadrature points of a chunk of cells, or of the boundary facets): the
/// interpreter dispatches once per instruction and batch of [`BATCH`] points instead of once
/// per instruction and point ([`Program::eval_batch`], bitwise the values of
/// [`CompiledField::eval`]). A non-finite value is recorded by the watch under `key`.
struct BatchLoad<const N: usize> {
    field: CompiledField<N>,
    key: &'static str,
    symbol: &'static str,
    watch: LoadWatch,
    /// The factor of `loads.traction_curve` (f2 only).
    curve: Option<LoadCurve>,
}

impl<const N: usize> BatchLoad<N> {
    /// The field of `exprs`, its non-finite values recorded by `watch` under `key`.
    fn new(
        exprs: &[Expr; N],
        key: &'static str,
        symbol: &'static str,
        watch: &LoadWatch,
        curve: Option<LoadCurve>,
    ) -> Self {
        Self {
            field: CompiledField::new(exprs),
            key,
            symbol,
            watch: watch.clone(),
            curve,
        }
    }

    /// The values at `points` (and `normals`, the last variables of f2) at time `time`, with the
    /// curve factor: `each(p, values at points[p])`.
    fn for_points<const D: usize>(
        &self,
        points: &[[f64; D]],
        normals: Option<&[[f64; D]]>,
        time: f64,
        mut each: impl FnMut(usize, [f64; N]),
    ) {
        let program = &self.field.program;
        let variables = program.variable_count();
        let factor = self.curve.as_ref().map(|curve| curve.factor(time));
        with_registers(|registers: &mut Vec<f64>| {
            // x, y, z (zero beyond D), t, then the normal (zero beyond D).
            let mut inputs = [[0.0; BATCH]; MAX_VARIABLES];
            inputs[3] = [time; BATCH];
            for (batch, chunk) in points.chunks(BATCH).enumerate() {
                let offset = batch * BATCH;
                let count = chunk.len();
                for (p, x) in chunk.iter().enumerate() {
                    for (j, &xj) in x.iter().enumerate() {
                        inputs[j][p] = xj;
                    }
                    if let Some(normals) = normals {
                        for (j, &nj) in normals[offset + p].iter().enumerate() {
                            inputs[4 + j][p] = nj;
                        }
                    }
                }
                let columns: [&[f64]; MAX_VARIABLES] = std::array::from_fn(|v| &inputs[v][..count]);
                program.eval_batch(&columns[..variables], count, registers);
                for p in 0..count {
                    let values: [f64; N] = std::array::from_fn(|i| {
                        let value = program.batch_output(registers, count, i)[p];
                        factor.map_or(value, |factor| value * factor)
                    });
                    let point = offset + p;
                    each(
                        point,
                        self.watch
                            .check(self.key, self.symbol, values, &points[point], time),
                    );
                }
            }
        })
    }
}

impl<const D: usize> BatchVectorField<D> for BatchLoad<D> {
    fn evaluate(&self, points: &[[f64; D]], time: f64, out: &mut [[f64; D]]) {
        self.for_points(points, None, time, |p, values| out[p] = values);
    }
}

impl<const D: usize> BatchBoundaryVectorField<D> for BatchLoad<D> {
    fn evaluate(&self, points: &[[f64; D]], normals: &[[f64; D]], time: f64, out: &mut [[f64; D]]) {
        self.for_points(points, Some(normals), time, |p, values| out[p] = values);
    }
}

fn groups(list: &[GroupFile]) -> Vec<GroupRef> {
    list.iter().map(GroupFile::to_ref).collect()
}

impl<const D: usize> ProblemSetup<D> {
    /// Reads, validates and builds the problem of the file at `path`.
    pub fn from_path(path: &Path) -> Result<Self, InputError> {
        let file = read_problem_file(path)?;
        Self::new(file, path)
    }

    /// Validates the file and builds the problem; `path` names the file in errors and locates
    /// the Gmsh mesh. Loads are checked for finite values at the mesh vertices (f0), at the
    /// vertices of Γ2 (f2), of Γ3 (g) and of each `[[displacement]]` part (u_D) at
    /// t = 0, T/2, T (the solver checks g and u_D again wherever and whenever it evaluates them).
    pub fn new(file: ProblemFile, path: &Path) -> Result<Self, InputError> {
        let origin = path.display().to_string();
        let origin = origin.as_str();
        if file.dim != D {
            return Err(problem_error(
                origin,
                "dim",
                format!("expected {D}, got {}", file.dim),
            ));
        }
        if !(1..=2).contains(&file.degree) {
            return Err(problem_error(
                origin,
                "degree",
                format!("must be 1 or 2, got {}", file.degree),
            ));
        }
        if !(file.final_time.is_finite() && file.final_time > 0.0) {
            return Err(problem_error(
                origin,
                "final_time",
                format!(
                    "must be a positive number, got {}",
                    contact_input::number::short(file.final_time)
                ),
            ));
        }
        if file.steps == 0 {
            return Err(problem_error(origin, "steps", "must be at least 1"));
        }
        if file.output.every == 0 {
            return Err(problem_error(origin, "output.every", "must be at least 1"));
        }
        let pictures = file
            .output
            .pictures
            .clone()
            .unwrap_or_else(|| vec![0.5 * file.final_time, file.final_time]);
        if let Some(bad) = pictures
            .iter()
            .find(|&&t| !(t.is_finite() && t > 0.0 && t <= file.final_time))
        {
            return Err(problem_error(
                origin,
                "output.pictures",
                format!(
                    "every time must lie in (0, final_time = {}], got {bad}",
                    file.final_time
                ),
            ));
        }
        let vtu = match file.output.vtu.as_deref() {
            None | Some("binary") => VtuEncoding::Binary,
            Some("ascii") => VtuEncoding::Ascii,
            Some(other) => {
                return Err(problem_error(
                    origin,
                    "output.vtu",
                    format!("must be \"binary\" or \"ascii\", got \"{other}\""),
                ))
            }
        };
        let name = match &file.name {
            Some(name) => name.clone(),
            None => path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "problem".into()),
        };
        if name.is_empty() || name.contains(['/', '\\']) || name == "." || name == ".." {
            return Err(problem_error(
                origin,
                "name",
                format!("`{name}` cannot name a folder"),
            ));
        }
        let (mesh, part_facets) = Self::mesh(&file, path, origin)?;
        // the damage pictures of a 3D run are drawn on Γ3: refuse before the first step
        if D == 3 && !(0..mesh.num_facets()).any(|f| mesh.facet_part(f) == BoundaryPart::Contact) {
            let key = if file.mesh.gmsh.is_some() {
                "mesh.gmsh.contact"
            } else {
                "mesh.box.sides"
            };
            return Err(problem_error(
                origin,
                key,
                "a 3D problem needs a contact face Γ3 (its damage pictures are drawn on it), and no boundary facet is `contact`",
            ));
        }
        let mut settings = file.solver.settings(origin)?;
        settings.contact = file.scheme.contact_treatment();
        settings.damage_evolution = file.scheme.damage_evolution();
        if D == 3 {
            // the Cholesky factor of M/k + κK with `damage_method = "active-set"`: in 3D the
            // supernodal one (factorization 25× faster at 32³, see `contact_damage::solvers::box_qp`)
            settings.damage.factorization = FactorKind::Supernodal;
        }
        let canonical = |value: Result<String, serde_json::Error>| {
            value.unwrap_or_else(|e| unreachable!("plain data serializes to JSON: {e}"))
        };
        let fingerprint = BTreeMap::from([
            (
                "constants".to_string(),
                canonical(serde_json::to_string(&file.constants)),
            ),
            (
                "laws".to_string(),
                canonical(serde_json::to_string(&file.laws)),
            ),
            (
                "loads".to_string(),
                canonical(serde_json::to_string(&file.loads)),
            ),
            ("mesh".to_string(), mesh_fingerprint(&mesh)),
        ]);
        let mut fingerprint = fingerprint;
        if file.scheme != SchemeFile::default() {
            // a resumed run continues the same scheme (absent for the paper's default, so
            // that the states of earlier versions still resume)
            fingerprint.insert(
                "scheme".to_string(),
                canonical(serde_json::to_string(&file.scheme)),
            );
        }
        if !file.displacement.is_empty() {
            // a resumed run keeps the same prescribed displacements
            fingerprint.insert(
                "displacement".to_string(),
                canonical(serde_json::to_string(&file.displacement)),
            );
        }
        let constants = &file.constants;
        let laws = file.laws.build::<D>(
            FileKind::Problem,
            origin,
            constants,
            file.scheme.damage_evolution(),
        )?;

        let loads = &file.loads;
        let body_force = loads
            .body_force
            .as_ref()
            .map(|s| parse_vector::<D>(origin, "loads.body_force", s, &FIELD_VARIABLES, constants))
            .transpose()?;
        let traction = loads
            .traction
            .as_ref()
            .map(|s| parse_vector::<D>(origin, "loads.traction", s, &TRACTION_VARIABLES, constants))
            .transpose()?;
        let zero = vec!["0".to_string(); D];
        let initial_displacement = parse_vector::<D>(
            origin,
            "loads.initial_displacement",
            loads.initial_displacement.as_ref().unwrap_or(&zero),
            &STATIC_VARIABLES,
            constants,
        )?;
        let gap = parse_expr(
            FileKind::Problem,
            origin,
            "loads.gap",
            loads.gap.as_deref().unwrap_or("0"),
            &FIELD_VARIABLES,
            constants,
        )?;
        let curve = loads
            .traction_curve
            .as_ref()
            .map(|points| LoadCurve::new(origin, "loads.traction_curve", points))
            .transpose()?;
        let initial_damage = parse_expr(
            FileKind::Problem,
            origin,
            "loads.initial_damage",
            loads.initial_damage.as_deref().unwrap_or("1"),
            &STATIC_VARIABLES,
            constants,
        )?;

        // finite loads at sample points
        let times = [0.0, 0.5 * file.final_time, file.final_time];
        if let Some(force) = &body_force {
            for x in mesh.vertices() {
                for &t in &times {
                    let value = eval_vector(force, &point_values(x, &[t]));
                    if value.iter().any(|v| !v.is_finite()) {
                        return Err(problem_error(
                            origin,
                            "loads.body_force",
                            format!("f0 = {value:?} is not finite at x = {x:?}, t = {t}"),
                        ));
                    }
                }
            }
        }
        for f in (0..mesh.num_facets()).filter(|&f| mesh.facet_part(f) == BoundaryPart::Contact) {
            for &vertex in mesh.facet(f) {
                let x = mesh.vertex(vertex);
                for &t in &times {
                    let value = gap.eval_f64(&point_values(&x, &[t]));
                    if !value.is_finite() {
                        return Err(problem_error(
                            origin,
                            "loads.gap",
                            format!("g = {value} is not finite at x = {x:?}, t = {t}"),
                        ));
                    }
                }
            }
        }
        let dirichlet =
            prescribed_displacements::<D>(&file, origin, constants, &mesh, part_facets, &times)?;
        if let Some(traction) = &traction {
            for f in (0..mesh.num_facets()).filter(|&f| mesh.facet_part(f) == BoundaryPart::Neumann)
            {
                let normal = mesh.facet_normal(f);
                for &vertex in mesh.facet(f) {
                    let x = mesh.vertex(vertex);
                    for &t in &times {
                        let mut extra = [t, 0.0, 0.0, 0.0];
                        extra[1..1 + D].copy_from_slice(&normal);
                        let value = eval_vector(traction, &point_values(&x, &extra));
                        if value.iter().any(|v| !v.is_finite()) {
                            return Err(problem_error(
                                origin,
                                "loads.traction",
                                format!("f2 = {value:?} is not finite at x = {x:?}, t = {t}"),
                            ));
                        }
                    }
                }
            }
        }

        let load_watch = LoadWatch::default();
        // The loads run at every quadrature point of every step: compiled once here.
        let body_force = body_force.map(|force| {
            Arc::new(BatchLoad::new(
                &force,
                "loads.body_force",
                "f0",
                &load_watch,
                None,
            )) as contact_damage::scheme::VectorField<D>
        });
        let traction = traction.map(|traction| {
            Arc::new(BatchLoad::new(
                &traction,
                "loads.traction",
                "f2",
                &load_watch,
                curve,
            )) as contact_damage::scheme::BoundaryVectorField<D>
        });
        let gap = CompiledField::new(&[gap]);
        let gap_watch = load_watch.clone();
        let problem = Problem {
            mesh: Arc::new(mesh),
            degree: file.degree,
            model: Model {
                viscosity: laws.viscosity,
                elasticity: laws.elasticity,
                damage_source: laws.damage_source,
                contact: laws.contact,
                damage_diffusion: laws.damage_diffusion,
            },
            data: Data {
                body_force,
                traction,
                contact_traction: None,
                damage_supply: None,
                damage_flux: None,
                gap: Arc::new(move |x, t| {
                    let value = gap.eval(x, &[t]);
                    gap_watch.check("loads.gap", "g", value, x, t)[0]
                }),
                dirichlet,
                initial_displacement: Arc::new(move |x| {
                    eval_vector(&initial_displacement, &point_values(x, &[]))
                }),
                initial_damage: Arc::new(move |x| initial_damage.eval_f64(&point_values(x, &[]))),
            },
            final_time: file.final_time,
            steps: file.steps,
            settings,
        };
        let output_dir = match &file.output.dir {
            Some(dir) => PathBuf::from(dir),
            None => Path::new("results").join(&name),
        };
        Ok(Self {
            origin: origin.to_string(),
            name,
            problem,
            every: file.output.every,
            output_dir,
            pictures,
            vtu,
            fingerprint,
            file,
            load_watch,
        })
    }

    /// The mesh and the facets of each `[[displacement]]` part.
    fn mesh(
        file: &ProblemFile,
        path: &Path,
        origin: &str,
    ) -> Result<(Mesh<D>, Vec<Vec<usize>>), InputError> {
        match (&file.mesh.box_mesh, &file.mesh.gmsh) {
            (Some(box_file), None) => {
                let coordinates = |key: &str, values: &[f64]| -> Result<[f64; D], InputError> {
                    if values.len() != D || values.iter().any(|v| !v.is_finite()) {
                        return Err(problem_error(
                            origin,
                            &format!("mesh.box.{key}"),
                            format!("need {D} finite coordinates, got {values:?}"),
                        ));
                    }
                    Ok(std::array::from_fn(|i| values[i]))
                };
                let lower = coordinates("lower", &box_file.lower)?;
                let upper = coordinates("upper", &box_file.upper)?;
                if box_file.cells.len() != D || box_file.cells.contains(&0) {
                    return Err(problem_error(
                        origin,
                        "mesh.box.cells",
                        format!("need {D} positive counts, got {:?}", box_file.cells),
                    ));
                }
                let cells = std::array::from_fn(|i| box_file.cells[i]);
                let mut sides =
                    parse_sides::<D>(FileKind::Problem, origin, "mesh.box.sides", &box_file.sides)?;
                let parts: Vec<(String, Vec<String>)> = file
                    .displacement
                    .iter()
                    .map(|d| (d.part.clone(), d.component_names()))
                    .collect();
                let prescribed = prescribed_sides::<D>(
                    FileKind::Problem,
                    origin,
                    "displacement",
                    &parts,
                    &box_file.sides,
                    &mut sides,
                )?;
                let mesh = Mesh::box_mesh(lower, upper, cells, sides)
                    .map_err(|e| problem_error(origin, "mesh.box", e.to_string()))?;
                let facets = prescribed
                    .iter()
                    .map(|side| {
                        let coordinate = [lower, upper][side.end][side.axis];
                        mesh.boundary_facets_where(|x| x[side.axis] == coordinate)
                    })
                    .collect();
                Ok((mesh, facets))
            }
            (None, Some(gmsh)) => {
                let msh = path
                    .parent()
                    .unwrap_or_else(|| Path::new(""))
                    .join(&gmsh.file);
                let mut map = PhysicalMap {
                    dirichlet: groups(&gmsh.clamped),
                    neumann: groups(&gmsh.traction),
                    contact: groups(&gmsh.contact),
                };
                for (i, part) in file.displacement.iter().enumerate() {
                    let group = GroupRef::Name(part.part.clone());
                    let key = format!("displacement[{i}].part");
                    if map.contact.contains(&group) {
                        return Err(problem_error(
                            origin,
                            &key,
                            format!("group \"{}\" is the contact boundary Γ3 (mesh.gmsh.contact): a prescribed displacement may not overlap Γ3", part.part),
                        ));
                    }
                    if map.neumann.contains(&group) {
                        return Err(problem_error(
                            origin,
                            &key,
                            format!("group \"{}\" is a traction group (mesh.gmsh.traction): a prescribed displacement acts on `clamped` groups or groups listed nowhere", part.part),
                        ));
                    }
                    if !map.dirichlet.contains(&group) {
                        map.dirichlet.push(group);
                    }
                }
                let mesh = read_msh::<D>(&msh, &map).map_err(|e| {
                    let message = e.to_string();
                    // a group named only by a `[[displacement]]` that the file lacks
                    let key =
                        file.displacement
                            .iter()
                            .position(|part| {
                                !gmsh.clamped.iter().any(
                                    |g| matches!(g, GroupFile::Name(name) if *name == part.part),
                                ) && message.contains(&format!("\"{}\"", part.part))
                            })
                            .map_or("mesh.gmsh".to_string(), |i| {
                                format!("displacement[{i}].part")
                            });
                    problem_error(origin, &key, message)
                })?;
                // the facets of a part: the Γ1 facets of the same file read with that group
                // alone as Γ1 (the reader keeps the order of the facets)
                let mut facets = Vec::new();
                for (i, part) in file.displacement.iter().enumerate() {
                    let group = GroupRef::Name(part.part.clone());
                    let alone = PhysicalMap {
                        dirichlet: vec![group.clone()],
                        neumann: map
                            .dirichlet
                            .iter()
                            .chain(&map.neumann)
                            .chain(&map.contact)
                            .filter(|g| **g != group)
                            .cloned()
                            .collect(),
                        contact: Vec::new(),
                    };
                    let key = format!("displacement[{i}].part");
                    let single = read_msh::<D>(&msh, &alone)
                        .map_err(|e| problem_error(origin, &key, e.to_string()))?;
                    if single.num_facets() != mesh.num_facets()
                        || (0..mesh.num_facets()).any(|f| single.facet(f) != mesh.facet(f))
                    {
                        return Err(problem_error(
                            origin,
                            &key,
                            format!("the facets of group \"{}\" could not be matched", part.part),
                        ));
                    }
                    facets.push(
                        (0..single.num_facets())
                            .filter(|&f| single.facet_part(f) == BoundaryPart::Dirichlet)
                            .collect(),
                    );
                }
                if gmsh.refinements == 0 {
                    return Ok((mesh, facets));
                }
                if gmsh.refinements > MAX_REFINEMENTS {
                    return Err(problem_error(
                        origin,
                        "mesh.gmsh.refinements",
                        format!(
                            "at most {MAX_REFINEMENTS} (each multiplies the cells by {}), got {}",
                            1 << D,
                            gmsh.refinements
                        ),
                    ));
                }
                let estimate = contact_damage::algebra::memory::estimate(
                    D,
                    file.degree,
                    mesh.num_vertices() as f64 * 2f64.powi((D * gmsh.refinements) as i32),
                );
                contact_damage::algebra::memory::check(
                    estimate,
                    contact_damage::algebra::memory::default_limit(),
                    &format!("the problem of {origin} refined {} times", gmsh.refinements),
                    "--memory-limit",
                )
                .map_err(|e| problem_error(origin, "mesh.gmsh.refinements", e.to_string()))?;
                let refined = contact_damage::fem::mesh::refine_times(&mesh, gmsh.refinements)
                    .map_err(|e| problem_error(origin, "mesh.gmsh.refinements", e.to_string()))?;
                let facets = facets
                    .iter()
                    .map(|part| {
                        let mut part = part.clone();
                        for _ in 0..gmsh.refinements {
                            part = contact_damage::fem::mesh::refined_facets::<D>(&part);
                        }
                        part
                    })
                    .collect();
                Ok((refined, facets))
            }
            _ => Err(problem_error(
                origin,
                "mesh",
                "give exactly one of `box = {…}` and `gmsh = {…}`",
            )),
        }
    }
}

impl DisplacementFile {
    /// The components given (`"x"`, `"y"`, `"z"`).
    fn component_names(&self) -> Vec<String> {
        [("x", &self.x), ("y", &self.y), ("z", &self.z)]
            .iter()
            .filter(|(_, expr)| expr.is_some())
            .map(|(name, _)| name.to_string())
            .collect()
    }
}

/// The `[[displacement]]` parts as the solver's prescribed displacements on their facets: each
/// component parsed in x, y, z, t and checked finite at the part's vertices at `times`.
fn prescribed_displacements<const D: usize>(
    file: &ProblemFile,
    origin: &str,
    constants: &BTreeMap<String, f64>,
    mesh: &Mesh<D>,
    part_facets: Vec<Vec<usize>>,
    times: &[f64],
) -> Result<Vec<PrescribedDisplacement<D>>, InputError> {
    let mut parts = Vec::new();
    for (i, (part, facets)) in file.displacement.iter().zip(part_facets).enumerate() {
        let mut components: [Option<PointScalarField<D>>; D] = std::array::from_fn(|_| None);
        let given = [("x", &part.x), ("y", &part.y), ("z", &part.z)];
        if given.iter().all(|(_, e)| e.is_none()) {
            return Err(problem_error(
                origin,
                &format!("displacement[{i}]"),
                "give at least one component (x, y, z) of the prescribed displacement",
            ));
        }
        for (name, source) in given {
            let Some(source) = source else { continue };
            let key = format!("displacement[{i}].{name}");
            let Some(c) = component_index::<D>(name) else {
                return Err(problem_error(
                    origin,
                    &key,
                    format!("a {D}D problem has no component `{name}`"),
                ));
            };
            let expr = parse_expr(
                FileKind::Problem,
                origin,
                &key,
                source,
                &FIELD_VARIABLES,
                constants,
            )?;
            for &f in &facets {
                for &vertex in mesh.facet(f) {
                    let x = mesh.vertex(vertex);
                    for &t in times {
                        let value = expr.eval_f64(&point_values(&x, &[t]));
                        if !value.is_finite() {
                            return Err(problem_error(
                                origin,
                                &key,
                                format!("u_D = {value} is not finite at x = {x:?}, t = {t}"),
                            ));
                        }
                    }
                }
            }
            let compiled = CompiledField::new(&[expr]);
            components[c] = Some(Arc::new(move |x: &[f64; D], t: f64| {
                let [value] = compiled.eval(x, &[t]);
                value
            }) as PointScalarField<D>);
        }
        parts.push(PrescribedDisplacement {
            name: part.part.clone(),
            facets,
            components,
            traction: None,
        });
    }
    Ok(parts)
}

/// A piecewise-linear load curve [[t, factor], …]: linear between its points, constant
/// outside them.
#[derive(Debug, Clone)]
pub struct LoadCurve {
    points: Vec<(f64, f64)>,
}

impl LoadCurve {
    /// Checks the points (at least one; pairs of finite numbers; times strictly increasing);
    /// errors name `origin` and `key`.
    pub fn new(origin: &str, key: &str, points: &[Vec<f64>]) -> Result<Self, InputError> {
        if points.is_empty() {
            return Err(problem_error(
                origin,
                key,
                "give at least one [t, factor] point",
            ));
        }
        let mut parsed: Vec<(f64, f64)> = Vec::with_capacity(points.len());
        for (i, point) in points.iter().enumerate() {
            let &[t, factor] = point.as_slice() else {
                return Err(problem_error(
                    origin,
                    &format!("{key}[{i}]"),
                    format!("a point is [t, factor], got {point:?}"),
                ));
            };
            if !(t.is_finite() && factor.is_finite()) {
                return Err(problem_error(
                    origin,
                    &format!("{key}[{i}]"),
                    format!("t and factor must be finite, got {point:?}"),
                ));
            }
            if let Some(&(previous, _)) = parsed.last() {
                if t <= previous {
                    return Err(problem_error(
                        origin,
                        &format!("{key}[{i}]"),
                        format!("times must increase strictly, got {t} after {previous}"),
                    ));
                }
            }
            parsed.push((t, factor));
        }
        Ok(Self { points: parsed })
    }

    /// The factor at time t.
    pub fn factor(&self, t: f64) -> f64 {
        let points = &self.points;
        let after = points.partition_point(|&(time, _)| time <= t);
        if after == 0 {
            return points[0].1;
        }
        if after == points.len() {
            return points[after - 1].1;
        }
        let ((t0, f0), (t1, f1)) = (points[after - 1], points[after]);
        f0 + (f1 - f0) * (t - t0) / (t1 - t0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The compiled loads give the values of the expression trees, bit for bit, at points
    /// spread over a box and over time.
    #[test]
    fn compiled_loads_are_bitwise_the_expression_trees() {
        let constants: BTreeMap<String, f64> = [
            ("pressure", 1.2),
            ("width", 0.4),
            ("center", 1.2),
            ("period", 1.0),
        ]
        .map(|(k, v)| (k.to_string(), v))
        .into_iter()
        .collect();
        let parse =
            |source: &str, variables: &[&str]| Expr::parse(source, variables, &constants).unwrap();
        let traction = [
            parse(
                "0.3*pressure*max(0, ny)*exp(-((x - center)/width)^2)*(1 - cos(2*pi*t/period))/2",
                &TRACTION_VARIABLES,
            ),
            parse(
                "-pressure*max(0, nz + ny)*exp(-((x - center)/width)^2)*(1 - cos(2*pi*t/period))/2",
                &TRACTION_VARIABLES,
            ),
            parse("sqrt(1 + x^2 + z^2)*sin(t)/(2 + nx)", &TRACTION_VARIABLES),
        ];
        let force = [
            parse("x*y - z^3 + t", &FIELD_VARIABLES),
            parse("tanh(x - t)*log(2 + y)", &FIELD_VARIABLES),
            parse("min(x, y)^2.5 + abs(z - 0.5)", &FIELD_VARIABLES),
        ];
        let compiled_traction = CompiledField::new(&traction);
        let compiled_force = CompiledField::new(&force);
        for p in 0..200 {
            let x: [f64; 3] =
                std::array::from_fn(|i| ((p * (7 + 4 * i) + 3 * i) % 97) as f64 / 48.0);
            let t = (p % 13) as f64 / 6.0;
            let normal = [[0.0, -1.0, 0.0], [0.6, 0.8, 0.0], [0.0, 0.0, 1.0]][p % 3];
            let extra = [t, normal[0], normal[1], normal[2]];
            let expected = eval_vector(&traction, &point_values(&x, &extra));
            let compiled = compiled_traction.eval(&x, &extra);
            let expected_force = eval_vector(&force, &point_values(&x, &[t]));
            let compiled_force = compiled_force.eval(&x, &[t]);
            for (a, b) in compiled
                .iter()
                .chain(&compiled_force)
                .zip(expected.iter().chain(&expected_force))
            {
                assert_eq!(a.to_bits(), b.to_bits(), "{a} vs {b} at x = {x:?}, t = {t}");
            }
        }
    }

    /// The batched loads (f0 over cell points, f2 over facet points with their normals and the
    /// load curve) give the point-by-point compiled values bit for bit, over more than two
    /// batches, in 2D and 3D.
    fn batched_loads_are_bitwise_the_compiled_loads<const D: usize>() {
        let constants = BTreeMap::new();
        let parse =
            |source: &str, variables: &[&str]| Expr::parse(source, variables, &constants).unwrap();
        let traction: [Expr; D] = std::array::from_fn(|i| {
            parse(
                [
                    "0.3*max(0, ny)*exp(-((x - 0.5)/0.4)^2)*(1 - cos(2*pi*t))/2 + nx*y",
                    "-max(0, nz + ny)*sqrt(1 + x^2 + z^2)*sin(t)/(2 + nx)",
                    "min(x, y)^2.5 + abs(z - 0.5)*nz",
                ][i],
                &TRACTION_VARIABLES,
            )
        });
        let force: [Expr; D] = std::array::from_fn(|i| {
            parse(
                [
                    "x*y - z^3 + t",
                    "tanh(x - t)*log(2 + y)",
                    "min(x, y)^2.5 + abs(z - 0.5)",
                ][i],
                &FIELD_VARIABLES,
            )
        });
        let curve = LoadCurve::new(
            "test",
            "curve",
            &[vec![0.0, 0.0], vec![0.7, 1.3], vec![2.0, 0.4]],
        )
        .unwrap();
        let batched = |exprs: &[Expr; D], curve: Option<LoadCurve>| {
            BatchLoad::<D>::new(exprs, "key", "f", &LoadWatch::default(), curve)
        };
        let (batched_force, batched_traction) = (
            batched(&force, None),
            batched(&traction, Some(curve.clone())),
        );
        let (compiled_force, compiled_traction) =
            (CompiledField::new(&force), CompiledField::new(&traction));
        let points: Vec<[f64; D]> = (0..2 * BATCH + 13)
            .map(|p| std::array::from_fn(|i| ((p * (7 + 4 * i) + 3 * i) % 97) as f64 / 48.0))
            .collect();
        let normals: Vec<[f64; D]> = (0..2 * BATCH + 13)
            .map(|p| {
                let angle = 0.37 * p as f64;
                std::array::from_fn(|i| [angle.cos(), angle.sin(), 0.0][i])
            })
            .collect();
        for t in [0.0, 0.45, 1.5] {
            let mut forces = vec![[0.0; D]; points.len()];
            BatchVectorField::evaluate(&batched_force, &points, t, &mut forces);
            let mut tractions = vec![[0.0; D]; points.len()];
            BatchBoundaryVectorField::evaluate(
                &batched_traction,
                &points,
                &normals,
                t,
                &mut tractions,
            );
            for (p, x) in points.iter().enumerate() {
                let mut extra = [t, 0.0, 0.0, 0.0];
                extra[1..1 + D].copy_from_slice(&normals[p]);
                let expected_traction = compiled_traction
                    .eval(x, &extra)
                    .map(|f| f * curve.factor(t));
                let expected_force = compiled_force.eval(x, &[t]);
                for (a, b) in forces[p]
                    .iter()
                    .chain(&tractions[p])
                    .zip(expected_force.iter().chain(&expected_traction))
                {
                    assert_eq!(a.to_bits(), b.to_bits(), "{a} vs {b} at x = {x:?}, t = {t}");
                }
            }
        }
    }

    #[test]
    fn batched_loads_are_bitwise_the_compiled_loads_in_2d_and_3d() {
        batched_loads_are_bitwise_the_compiled_loads::<2>();
        batched_loads_are_bitwise_the_compiled_loads::<3>();
    }
}
