//! The mesh of a problem file: a refined box (`mesh.box`) or a Gmsh file (`mesh.gmsh`, refined
//! `refinements` times), and the boundary facets of each `[[displacement]]` part.

use super::file::{problem_error, BoxFile, GmshFile, ProblemFile, MAX_REFINEMENTS};
use contact_damage::fem::mesh::{BoundaryPart, Mesh};
use contact_damage::io::gmsh::{read_msh, GroupRef, PhysicalMap};
use contact_input::sides::{parse_sides, prescribed_sides, GroupFile};
use contact_input::{FileKind, InputError};
use std::path::Path;

/// A mesh and the facets of each `[[displacement]]` part, in the order of the parts.
type MeshWithParts<const D: usize> = (Mesh<D>, Vec<Vec<usize>>);

/// The mesh and the facets of each `[[displacement]]` part.
pub(super) fn build_mesh<const D: usize>(
    file: &ProblemFile,
    path: &Path,
    origin: &str,
) -> Result<MeshWithParts<D>, InputError> {
    match (&file.mesh.box_mesh, &file.mesh.gmsh) {
        (Some(box_file), None) => box_mesh(file, box_file, origin),
        (None, Some(gmsh)) => gmsh_mesh(file, gmsh, path, origin),
        _ => Err(problem_error(
            origin,
            "mesh",
            "give exactly one of `box = {…}` and `gmsh = {…}`",
        )),
    }
}

/// `mesh.box`: the box refined into `cells` intervals per axis with its sides, and the facets
/// of each prescribed side.
fn box_mesh<const D: usize>(
    file: &ProblemFile,
    box_file: &BoxFile,
    origin: &str,
) -> Result<MeshWithParts<D>, InputError> {
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
    let mut sides = parse_sides::<D>(FileKind::Problem, origin, "mesh.box.sides", &box_file.sides)?;
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

/// `mesh.gmsh`: the Gmsh file (relative to the problem file at `path`) with its groups, the
/// facets of each `[[displacement]]` group, and the uniform refinements.
fn gmsh_mesh<const D: usize>(
    file: &ProblemFile,
    gmsh: &GmshFile,
    path: &Path,
    origin: &str,
) -> Result<MeshWithParts<D>, InputError> {
    let msh = path
        .parent()
        .unwrap_or_else(|| Path::new(""))
        .join(&gmsh.file);
    let map = physical_map(file, gmsh, origin)?;
    let mesh = read_gmsh_mesh::<D>(file, gmsh, &msh, &map, origin)?;
    let facets = displacement_facets(file, &msh, &map, &mesh, origin)?;
    if gmsh.refinements == 0 {
        return Ok((mesh, facets));
    }
    refine_gmsh_mesh(file, gmsh, &mesh, &facets, origin)
}

fn groups(list: &[GroupFile]) -> Vec<GroupRef> {
    list.iter().map(GroupFile::to_ref).collect()
}

/// The groups of Γ1, Γ2 and Γ3: those of `mesh.gmsh`, and every `[[displacement]]` group in
/// Γ1; a `[[displacement]]` group of Γ2 or Γ3 is refused.
fn physical_map(
    file: &ProblemFile,
    gmsh: &GmshFile,
    origin: &str,
) -> Result<PhysicalMap, InputError> {
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
    Ok(map)
}

/// Reads the Gmsh file `msh` with the groups of `map`; an error about a group named only by a
/// `[[displacement]]` names that part's key.
fn read_gmsh_mesh<const D: usize>(
    file: &ProblemFile,
    gmsh: &GmshFile,
    msh: &Path,
    map: &PhysicalMap,
    origin: &str,
) -> Result<Mesh<D>, InputError> {
    read_msh::<D>(msh, map).map_err(|e| {
        let message = e.to_string();
        // a group named only by a `[[displacement]]` that the file lacks
        let key = file
            .displacement
            .iter()
            .position(|part| {
                !gmsh
                    .clamped
                    .iter()
                    .any(|g| matches!(g, GroupFile::Name(name) if *name == part.part))
                    && message.contains(&format!("\"{}\"", part.part))
            })
            .map_or("mesh.gmsh".to_string(), |i| {
                format!("displacement[{i}].part")
            });
        problem_error(origin, &key, message)
    })
}

/// The facets of each `[[displacement]]` group: the Γ1 facets of the same file read with that
/// group alone as Γ1 (the reader keeps the order of the facets).
fn displacement_facets<const D: usize>(
    file: &ProblemFile,
    msh: &Path,
    map: &PhysicalMap,
    mesh: &Mesh<D>,
    origin: &str,
) -> Result<Vec<Vec<usize>>, InputError> {
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
        let single =
            read_msh::<D>(msh, &alone).map_err(|e| problem_error(origin, &key, e.to_string()))?;
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
    Ok(facets)
}

/// The Gmsh mesh refined `mesh.gmsh.refinements` times (at most [`MAX_REFINEMENTS`], and
/// within the default memory limit), and the facets of each part refined alike.
fn refine_gmsh_mesh<const D: usize>(
    file: &ProblemFile,
    gmsh: &GmshFile,
    mesh: &Mesh<D>,
    facets: &[Vec<usize>],
    origin: &str,
) -> Result<MeshWithParts<D>, InputError> {
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
    let refined = contact_damage::fem::mesh::refine_times(mesh, gmsh.refinements)
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
