//! The domain of a manufactured case (`[domain]`): a box with a boundary part per side, meshed
//! by Kuhn triangulations with `cells` intervals per side, or a Gmsh MSH 4.1 mesh (ASCII or
//! binary) whose physical groups of dimension d − 1 are mapped to Γ1 (`clamped`), Γ2
//! (`traction`) and Γ3 (`contact`), refined uniformly `refinements` times
//! ([`contact_damage::fem::refine`]) to make the levels of a study.
//!
//! ```toml
//! [domain]                       # a box ...
//! lower = [0.0, 0.0]
//! upper = [1.0, 1.0]
//! sides = { x_min = "clamped", y_min = "contact" }
//! ```
//! ```toml
//! [domain]                       # ... or a Gmsh mesh (path relative to the case file)
//! mesh = "meshes/tilted2d.msh"
//! clamped = ["clamped"]          # physical groups by name or tag
//! traction = ["traction", 7]
//! contact = ["contact"]
//! ```
//!
//! The mesh of a built-in case is compiled into the program ([`BUILT_IN_MESHES`]).

use crate::InputError;
use contact_damage::fem::mesh::{refine_times, BoundaryPart, Mesh};
use contact_damage::io::gmsh::{parse_msh_bytes, PhysicalMap};
use contact_input::sides::GroupFile;
use contact_input::FileKind;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

/// Meshes of the built-in cases: (path relative to `verification/`, bytes of the file).
pub const BUILT_IN_MESHES: [(&str, &[u8]); 4] = [
    (
        "meshes/tilted2d.msh",
        include_bytes!("../../../verification/meshes/tilted2d.msh"),
    ),
    (
        "meshes/tilted3d.msh",
        include_bytes!("../../../verification/meshes/tilted3d.msh"),
    ),
    (
        "meshes/curved2d.msh",
        include_bytes!("../../../verification/meshes/curved2d.msh"),
    ),
    (
        "meshes/curved3d.msh",
        include_bytes!("../../../verification/meshes/curved3d.msh"),
    ),
];

/// The most cells a refined level may have (a level beyond it is refused before it is built).
pub const MAX_LEVEL_CELLS: usize = 20_000_000;

/// `[domain]` as written: either `lower`, `upper`, `sides` (a box) or `mesh` with the groups.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DomainFile {
    /// Lower corner of the box.
    #[serde(default)]
    pub lower: Vec<f64>,
    /// Upper corner of the box.
    #[serde(default)]
    pub upper: Vec<f64>,
    /// Side name (`x_min`, `x_max`, `y_min`, `y_max`, `z_min`, `z_max`) → `clamped` (Γ1),
    /// `traction` (Γ2) or `contact` (Γ3).
    #[serde(default)]
    pub sides: BTreeMap<String, String>,
    /// A Gmsh MSH 4.1 file (ASCII or binary), path relative to the case file.
    #[serde(default)]
    pub mesh: Option<String>,
    /// Physical groups of Γ1 (with `mesh`).
    #[serde(default)]
    pub clamped: Vec<GroupFile>,
    /// Physical groups of Γ2 (with `mesh`).
    #[serde(default)]
    pub traction: Vec<GroupFile>,
    /// Physical groups of Γ3 (with `mesh`).
    #[serde(default)]
    pub contact: Vec<GroupFile>,
}

impl DomainFile {
    /// Whether the domain is a Gmsh mesh (else a box).
    pub fn is_mesh(&self) -> bool {
        self.mesh.is_some()
    }
}

/// The domain of a validated case.
#[derive(Debug, Clone)]
pub enum Domain<const D: usize> {
    /// The box [lower, upper] with the boundary part of each side.
    Box {
        /// Lower corner.
        lower: [f64; D],
        /// Upper corner.
        upper: [f64; D],
        /// `sides[axis] = [part of x_axis = lower, part of x_axis = upper]`.
        sides: [[BoundaryPart; 2]; D],
    },
    /// A mesh read from a Gmsh file: level r of a study is this mesh refined r times.
    Mesh {
        /// The file as named in the case (`domain.mesh`).
        file: String,
        /// The coarse mesh (level 0).
        mesh: Arc<Mesh<D>>,
    },
}

impl<const D: usize> Domain<D> {
    /// The mesh of a study level: a box with `level` intervals per side, or the Gmsh mesh
    /// refined `level` times.
    pub fn mesh(&self, level: usize) -> Result<Mesh<D>, contact_damage::Error> {
        match self {
            Domain::Box {
                lower,
                upper,
                sides,
            } => Mesh::box_mesh(*lower, *upper, [level; D], *sides),
            Domain::Mesh { mesh, .. } => refine_times(mesh, level),
        }
    }
}

fn case_error(origin: &str, key: &str, message: impl Into<String>) -> InputError {
    FileKind::Case.error(origin, key, message)
}

/// The bytes of the mesh file `file` of a case from `origin` (built in, or relative to the case
/// file's folder) and the path that names it in messages.
pub fn mesh_file(file: &str, origin: &str) -> Result<(Vec<u8>, String), InputError> {
    let (bytes, path) = if origin.starts_with("built-in:") {
        let bytes = BUILT_IN_MESHES
            .iter()
            .find(|(name, _)| *name == file)
            .map(|(_, bytes)| bytes.to_vec())
            .ok_or_else(|| {
                case_error(
                    origin,
                    "domain.mesh",
                    format!("`{file}` is not a built-in mesh"),
                )
            })?;
        (bytes, format!("verification/{file}"))
    } else {
        let path = Path::new(origin)
            .parent()
            .unwrap_or_else(|| Path::new(""))
            .join(file);
        contact_input::regular::check_regular_file(&path, "mesh")
            .map_err(|e| case_error(origin, "domain.mesh", e.to_string()))?;
        let bytes = std::fs::read(&path).map_err(|e| {
            case_error(
                origin,
                "domain.mesh",
                format!("cannot read `{}`: {e}", path.display()),
            )
        })?;
        (bytes, path.display().to_string())
    };
    Ok((bytes, path))
}

/// Reads the Gmsh mesh of `domain` for the case `origin`: a built-in mesh when `origin` is
/// `built-in:NAME`, else the file at `domain.mesh` relative to the folder of `origin`.
///
/// Errors (naming the case and the key): the file cannot be read (`domain.mesh`); a group
/// that the file lacks or that has no entity of dimension d − 1 (`domain.clamped`,
/// `domain.traction` or `domain.contact`, whichever lists it); anything else the reader or
/// the mesh validation reports (`domain.mesh`).
pub fn read_mesh<const D: usize>(
    domain: &DomainFile,
    origin: &str,
) -> Result<Domain<D>, InputError> {
    let Some(file) = &domain.mesh else {
        return Err(case_error(origin, "domain.mesh", "no mesh file given"));
    };
    let map = PhysicalMap {
        dirichlet: domain.clamped.iter().map(GroupFile::to_ref).collect(),
        neumann: domain.traction.iter().map(GroupFile::to_ref).collect(),
        contact: domain.contact.iter().map(GroupFile::to_ref).collect(),
    };
    let (bytes, path) = mesh_file(file, origin)?;
    let mesh = parse_msh_bytes::<D>(&bytes, &path, &map).map_err(|e| {
        let message = e.to_string();
        // a group named in the message is reported at the key that lists it
        let key = [
            ("domain.clamped", &domain.clamped),
            ("domain.traction", &domain.traction),
            ("domain.contact", &domain.contact),
        ]
        .into_iter()
        .find(|(_, groups)| {
            groups
                .iter()
                .any(|group| message.contains(&format!("group {}", group.to_ref())))
        })
        .map_or("domain.mesh", |(key, _)| key);
        case_error(origin, key, message)
    })?;
    Ok(Domain::Mesh {
        file: file.clone(),
        mesh: Arc::new(mesh),
    })
}

/// Checks that the refinement levels of a study are possible: the finest has at most
/// [`MAX_LEVEL_CELLS`] cells (`key` names the study's `refinements`).
pub fn check_levels<const D: usize>(
    mesh: &Mesh<D>,
    levels: &[usize],
    origin: &str,
    key: &str,
) -> Result<(), InputError> {
    for &level in levels {
        let cells = u32::try_from(D * level)
            .ok()
            .and_then(|shift| 1usize.checked_shl(shift))
            .and_then(|factor| factor.checked_mul(mesh.num_cells()));
        if cells.is_none_or(|cells| cells > MAX_LEVEL_CELLS) {
            return Err(case_error(
                origin,
                key,
                format!(
                    "{level} refinements of a mesh of {} cells give {} cells, more than the {MAX_LEVEL_CELLS} allowed",
                    mesh.num_cells(),
                    cells.map_or("too many".to_string(), |c| c.to_string())
                ),
            ));
        }
    }
    Ok(())
}

/// Points of a mesh domain where the case's fields are checked (as the lattice of a box):
/// every vertex of the mesh refined once (`interior`, with no boundary part), and the vertices
/// and centroid of every boundary facet with its part and outward normal (`boundary`).
pub struct SamplePoints<const D: usize> {
    /// Points of Ω̄.
    pub interior: Vec<[f64; D]>,
    /// Points of Γ with the part and the outward unit normal there.
    pub boundary: Vec<([f64; D], BoundaryPart, [f64; D])>,
}

/// The sample points of a mesh domain (see [`SamplePoints`]).
pub fn sample_points<const D: usize>(mesh: &Mesh<D>) -> Result<SamplePoints<D>, InputError> {
    let fine = refine_times(mesh, 1)?;
    let mut boundary = Vec::new();
    for f in 0..fine.num_facets() {
        let corners: Vec<[f64; D]> = fine.facet(f).iter().map(|&v| fine.vertex(v)).collect();
        let centroid: [f64; D] =
            std::array::from_fn(|i| corners.iter().map(|x| x[i]).sum::<f64>() / D as f64);
        for x in corners.into_iter().chain([centroid]) {
            boundary.push((x, fine.facet_part(f), fine.facet_normal(f)));
        }
    }
    Ok(SamplePoints {
        interior: fine.vertices().to_vec(),
        boundary,
    })
}
