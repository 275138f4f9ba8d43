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
//! profile = { from = [0, 0], to = [4, 0], width = 0.01 }  # the line of Γ3 recorded in
//!                          # contact_history.csv: the contact nodes within `width` (default
//!                          # half a node spacing) of the segment; default a line across Γ3
//! moment_about = [2, 0]    # point of the moment of the contact tractions (default the origin)
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
//! tangent = "frozen"              # model matrix of (5.1) with a nonlinear 𝒜: "frozen" (the
//!                                 # last tangent, kept while it converges) or "newton" (exact)
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
//!
//! The file's tables are in [`ProblemFile`] and its sub-structs; [`ProblemSetup::new`] checks
//! them and builds the problem in named steps: the entries that need no mesh, the mesh with the
//! facets of the `[[displacement]]` parts, the settings, the resume fingerprint, the laws, and
//! the data of `[loads]` and `[[displacement]]` (parsed, checked finite, compiled).

mod data;
mod fields;
mod file;
mod fingerprint;
mod mesh;
mod validate;

pub use fields::{LoadCurve, FIELD_VARIABLES, STATIC_VARIABLES, TRACTION_VARIABLES};
pub use file::{
    parse_problem_file, read_problem_file, BoxFile, DisplacementFile, GmshFile, LoadsFile,
    MeshFile, OutputFile, ProblemFile, ProfileFile, SolverFile, LOOSEST_TOLERANCE, MAX_REFINEMENTS,
};
pub use fingerprint::mesh_fingerprint;

use crate::contact_line::ProfileSegment;
use crate::watch::LoadWatch;
use contact_damage::algebra::linalg::FactorKind;
use contact_damage::io::vtk::VtuEncoding;
use contact_damage::scheme::{Model, Problem, SchemeSettings};
use contact_input::{FileKind, InputError};
use data::{prescribed_displacements, LoadExpressions};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

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
    /// The profile line of `output.profile` (None: the default line of Γ3).
    pub profile: Option<ProfileSegment<D>>,
    /// The point about which the moment of the contact tractions is taken.
    pub moment_about: [f64; D],
    /// What a saved state must match to be resumed with this problem: `constants`, `laws`,
    /// `loads` (as canonical JSON) and `mesh` (SHA-256 of the vertices, cells and boundary
    /// parts of the built mesh, so that a changed Gmsh file is caught too). `dim`, `degree`,
    /// `final_time` and `steps` are checked on their own; `output` and `solver` may change
    /// between a run and its resumption.
    pub fingerprint: BTreeMap<String, String>,
    /// The first non-finite value of a load expression met during the run (names its key).
    pub load_watch: LoadWatch,
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
        validate::check_sizes::<D>(&file, origin)?;
        let pictures = validate::picture_times(&file, origin)?;
        let vtu = validate::vtu_encoding(&file, origin)?;
        let profile = validate::profile_segment::<D>(&file, origin)?;
        let moment_about = validate::moment_point::<D>(&file, origin)?;
        let name = validate::problem_name(&file, path, origin)?;
        let (mesh, part_facets) = mesh::build_mesh::<D>(&file, path, origin)?;
        validate::check_contact_face(&file, &mesh, origin)?;
        let settings = scheme_settings::<D>(&file, origin)?;
        let fingerprint = fingerprint::fingerprint(&file, &mesh);
        let constants = &file.constants;
        let laws = file.laws.build::<D>(
            FileKind::Problem,
            origin,
            constants,
            file.scheme.damage_evolution(),
        )?;
        let loads = LoadExpressions::<D>::parse(&file, origin)?;

        // finite loads at sample points
        let times = [0.0, 0.5 * file.final_time, file.final_time];
        loads.check_body_force(&mesh, &times, origin)?;
        loads.check_gap(&mesh, &times, origin)?;
        let load_watch = LoadWatch::default();
        let dirichlet = prescribed_displacements::<D>(
            &file,
            origin,
            constants,
            &mesh,
            part_facets,
            &times,
            &load_watch,
        )?;
        loads.check_traction(&mesh, &times, origin)?;

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
            data: loads.into_data(dirichlet, &load_watch),
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
            profile,
            moment_about,
            fingerprint,
            file,
            load_watch,
        })
    }
}

/// The solver settings: those of `[solver]` with the variant of `[scheme]`, and in 3D the
/// supernodal Cholesky factor.
fn scheme_settings<const D: usize>(
    file: &ProblemFile,
    origin: &str,
) -> Result<SchemeSettings, InputError> {
    let mut settings = file.solver.settings(origin)?;
    settings.contact = file.scheme.contact_treatment();
    settings.damage_evolution = file.scheme.damage_evolution();
    if D == 3 {
        // the Cholesky factor of M/k + κK with `damage_method = "active-set"`: in 3D the
        // supernodal one (factorization 25× faster at 32³, see `contact_damage::solvers::box_qp`)
        settings.damage.factorization = FactorKind::Supernodal;
    }
    Ok(settings)
}
