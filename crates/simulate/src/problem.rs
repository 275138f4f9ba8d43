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
//! [laws]                   # as in the verification case files
//! # ...
//! [loads]                  # all optional (zero, resp. β0 = 1)
//! body_force = ["0", "0"]                      # f0 in x, y, z, t
//! traction = ["0", "-p*max(0, ny)"]            # f2 on Γ2 in x, y, z, t, nx, ny, nz
//! gap = "0"                                    # g in x, y, z
//! initial_displacement = ["0", "0"]            # u0 in x, y, z
//! initial_damage = "1"                         # β0 in x, y, z
//! [output]
//! every = 1                # save every N-th step (and the last one)
//! dir = "results/NAME"     # default results/<name>, name = file stem unless `name` is given
//! pictures = [2.5, 5.0]    # times of the damage pictures (SVG), default [T/2, T]
//! ```
//!
//! Box sides not listed are traction sides (Γ2). The traction may use the outward normal
//! (nx, ny, nz) to act on part of Γ2 only, e.g. `max(0, ny)` selects the top of a box.
//! Every error names the file, the key and the problem ([`VerifyError::Case`]).

use contact_damage::gmsh::{read_msh, GroupRef, PhysicalMap};
use contact_damage::mesh::{BoundaryPart, Mesh};
use contact_damage::scheme::{Data, Model, Problem, SchemeSettings};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use verify::case::{parse_sides, parse_toml, LawsFile};
use verify::expr::Expr;
use verify::VerifyError;

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
}

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

/// A physical group named or numbered.
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum GroupFile {
    /// By `$PhysicalNames` name.
    Name(String),
    /// By physical tag.
    Tag(i32),
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
}

/// `[loads]`: expressions; missing entries are zero (β0 = 1, g = 0).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoadsFile {
    /// f0 components in x, y, z, t.
    #[serde(default)]
    pub body_force: Option<Vec<String>>,
    /// f2 components on Γ2 in x, y, z, t, nx, ny, nz.
    #[serde(default)]
    pub traction: Option<Vec<String>>,
    /// g ≥ 0 on Γ3 in x, y, z.
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
}

fn problem_error(origin: &str, key: &str, message: impl Into<String>) -> VerifyError {
    VerifyError::Case {
        file: origin.to_string(),
        key: key.to_string(),
        message: message.into(),
    }
}

/// Reads and parses a problem file (TOML errors carry line and column).
pub fn read_problem_file(path: &Path) -> Result<ProblemFile, VerifyError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| VerifyError::io("reading problem file", path, e))?;
    parse_toml(&text, &path.display().to_string())
}

/// An expression of the problem file with the variables it is evaluated on.
fn parse_expr(
    origin: &str,
    key: &str,
    source: &str,
    variables: &[&str],
    constants: &BTreeMap<String, f64>,
) -> Result<Expr, VerifyError> {
    Expr::parse(source, variables, constants)
        .map_err(|e| problem_error(origin, key, format!("`{source}`: {e}")))
}

/// D expressions of a vector field.
fn parse_vector<const D: usize>(
    origin: &str,
    key: &str,
    sources: &[String],
    variables: &[&str],
    constants: &BTreeMap<String, f64>,
) -> Result<[Expr; D], VerifyError> {
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
        .map(|(i, s)| parse_expr(origin, &format!("{key}[{i}]"), s, variables, constants))
        .collect::<Result<_, _>>()?;
    Ok(parsed
        .try_into()
        .unwrap_or_else(|_| unreachable!("the length was checked")))
}

/// The variable values of an expression: the position padded to (x, y, z), then `extra`
/// (t, then the normal for the traction).
fn point_values<const D: usize>(x: &[f64; D], extra: &[f64]) -> Vec<f64> {
    let mut values = vec![0.0; 3 + extra.len()];
    values[..D].copy_from_slice(x);
    values[3..].copy_from_slice(extra);
    values
}

fn eval_vector<const D: usize>(exprs: &[Expr; D], values: &[f64]) -> [f64; D] {
    std::array::from_fn(|i| exprs[i].eval_f64(values))
}

fn groups(list: &[GroupFile]) -> Vec<GroupRef> {
    list.iter()
        .map(|g| match g {
            GroupFile::Name(name) => GroupRef::Name(name.clone()),
            GroupFile::Tag(tag) => GroupRef::Tag(*tag),
        })
        .collect()
}

impl<const D: usize> ProblemSetup<D> {
    /// Reads, validates and builds the problem of the file at `path`.
    pub fn from_path(path: &Path) -> Result<Self, VerifyError> {
        let file = read_problem_file(path)?;
        Self::new(file, path)
    }

    /// Validates the file and builds the problem; `path` names the file in errors and locates
    /// the Gmsh mesh. Loads are checked for finite values at the mesh vertices (f0) and at the
    /// vertices of Γ2 (f2) at t = 0, T/2, T.
    pub fn new(file: ProblemFile, path: &Path) -> Result<Self, VerifyError> {
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
                format!("must be a positive number, got {}", file.final_time),
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
        let mesh = Self::mesh(&file, path, origin)?;
        let constants = &file.constants;
        let laws = file.laws.build::<D>(origin, constants)?;

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
            origin,
            "loads.gap",
            loads.gap.as_deref().unwrap_or("0"),
            &STATIC_VARIABLES,
            constants,
        )?;
        let initial_damage = parse_expr(
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

        let body_force: Option<contact_damage::scheme::VectorField<D>> = body_force.map(|force| {
            Arc::new(move |x: &[f64; D], t: f64| eval_vector(&force, &point_values(x, &[t])))
                as contact_damage::scheme::VectorField<D>
        });
        let traction = traction.map(|traction| {
            Arc::new(move |x: &[f64; D], t: f64, normal: &[f64; D]| {
                let mut extra = [t, 0.0, 0.0, 0.0];
                extra[1..1 + D].copy_from_slice(normal);
                eval_vector(&traction, &point_values(x, &extra))
            }) as contact_damage::scheme::BoundaryVectorField<D>
        });
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
                gap: Arc::new(move |x| gap.eval_f64(&point_values(x, &[]))),
                initial_displacement: Arc::new(move |x| {
                    eval_vector(&initial_displacement, &point_values(x, &[]))
                }),
                initial_damage: Arc::new(move |x| initial_damage.eval_f64(&point_values(x, &[]))),
            },
            final_time: file.final_time,
            steps: file.steps,
            settings: SchemeSettings::default(),
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
            file,
        })
    }

    fn mesh(file: &ProblemFile, path: &Path, origin: &str) -> Result<Mesh<D>, VerifyError> {
        match (&file.mesh.box_mesh, &file.mesh.gmsh) {
            (Some(box_file), None) => {
                let coordinates = |key: &str, values: &[f64]| -> Result<[f64; D], VerifyError> {
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
                let sides = parse_sides::<D>(origin, "mesh.box.sides", &box_file.sides)?;
                Mesh::box_mesh(lower, upper, cells, sides)
                    .map_err(|e| problem_error(origin, "mesh.box", e.to_string()))
            }
            (None, Some(gmsh)) => {
                let msh = path
                    .parent()
                    .unwrap_or_else(|| Path::new(""))
                    .join(&gmsh.file);
                let map = PhysicalMap {
                    dirichlet: groups(&gmsh.clamped),
                    neumann: groups(&gmsh.traction),
                    contact: groups(&gmsh.contact),
                };
                read_msh::<D>(&msh, &map)
                    .map_err(|e| problem_error(origin, "mesh.gmsh", e.to_string()))
            }
            _ => Err(problem_error(
                origin,
                "mesh",
                "give exactly one of `box = {…}` and `gmsh = {…}`",
            )),
        }
    }
}
