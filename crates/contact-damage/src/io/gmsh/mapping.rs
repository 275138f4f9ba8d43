//! From the records to the mesh: the physical map resolved into boundary parts of the
//! entities, and the compaction of the nodes into the vertices of a [`Mesh`].

use std::collections::{BTreeMap, HashMap};

use super::reader::{fail, Location, Record};
use super::records::{Elements, Entities, Node, PhysicalName, ENTITY_KINDS};
use super::{GroupRef, PhysicalMap};
use crate::error::{Error, Result};
use crate::fem::mesh::{BoundaryPart, Mesh};

/// Resolves the physical map into physical tag → part for groups of dimension
/// `boundary_dimension`, checking that every referenced group exists, contains an entity of
/// that dimension, and is mapped to one part only. `at` is the record where the map is needed
/// (the `$Elements` header), for errors without a better location.
pub(super) fn resolve_map(
    map: &PhysicalMap,
    physical_names: Option<&(Location, Vec<PhysicalName>)>,
    entities: &Entities,
    entities_location: Location,
    boundary_dimension: usize,
    at: &Record,
) -> Result<BTreeMap<i32, BoundaryPart>> {
    let kind = ENTITY_KINDS[boundary_dimension];
    let mut group_parts: BTreeMap<i32, BoundaryPart> = BTreeMap::new();
    for (part, refs) in map.parts() {
        for group in refs {
            let tags: Vec<i32> = match group {
                GroupRef::Tag(tag) => vec![*tag],
                GroupRef::Name(name) => {
                    let Some((names_location, names)) = physical_names else {
                        return Err(at.fail_with(
                            format!(
                                "a `$PhysicalNames` section defining the group \"{name}\" of \
                                 {}",
                                part.label()
                            ),
                            "no `$PhysicalNames` section",
                        ));
                    };
                    let tags: Vec<i32> = names
                        .iter()
                        .filter(|n| n.name == *name && n.dimension == boundary_dimension)
                        .map(|n| n.tag)
                        .collect();
                    if tags.is_empty() {
                        let available: Vec<String> = names
                            .iter()
                            .map(|n| format!("\"{}\" (dimension {})", n.name, n.dimension))
                            .collect();
                        return Err(fail(
                            at.origin,
                            *names_location,
                            format!(
                                "a physical group \"{name}\" of dimension {boundary_dimension} \
                                 (mapped to {})",
                                part.label()
                            ),
                            if available.is_empty() {
                                "no named groups".to_string()
                            } else {
                                available.join(", ")
                            },
                        ));
                    }
                    tags
                }
            };
            for tag in tags {
                let used = entities[boundary_dimension]
                    .values()
                    .any(|entity| entity.physical_tags.contains(&tag));
                if !used {
                    return Err(fail(
                        at.origin,
                        entities_location,
                        format!(
                            "a {kind} in physical group {tag} ({group}, mapped to {})",
                            part.label()
                        ),
                        format!("no {kind} of that group in `$Entities`"),
                    ));
                }
                if let Some(&other) = group_parts.get(&tag) {
                    if other != part {
                        return Err(fail(
                            at.origin,
                            entities_location,
                            format!("physical group {tag} ({group}) to be mapped to one part"),
                            format!("it mapped to both {} and {}", other.label(), part.label()),
                        ));
                    }
                }
                group_parts.insert(tag, part);
            }
        }
    }
    Ok(group_parts)
}

/// The boundary part of each entity of dimension `boundary_dimension` in a mapped group;
/// an entity in groups of two different parts is an error.
pub(super) fn boundary_entity_parts(
    origin: &str,
    entities: &Entities,
    group_parts: &BTreeMap<i32, BoundaryPart>,
    boundary_dimension: usize,
) -> Result<BTreeMap<i32, BoundaryPart>> {
    let kind = ENTITY_KINDS[boundary_dimension];
    let mut entity_parts = BTreeMap::new();
    for (&tag, entity) in &entities[boundary_dimension] {
        let mut found: Option<(i32, BoundaryPart)> = None;
        for &group in &entity.physical_tags {
            let Some(&part) = group_parts.get(&group) else {
                continue;
            };
            match found {
                Some((first_group, first_part)) if first_part != part => {
                    return Err(fail(
                        origin,
                        entity.location,
                        format!("{kind} {tag} to lie in one boundary part"),
                        format!(
                            "physical groups {first_group} ({}) and {group} ({})",
                            first_part.label(),
                            part.label()
                        ),
                    ));
                }
                Some(_) => {}
                None => found = Some((group, part)),
            }
        }
        if let Some((_, part)) = found {
            entity_parts.insert(tag, part);
        }
    }
    Ok(entity_parts)
}

/// The D coordinates of node `tag`; a 2D mesh's nodes must have z = 0.
fn coordinates<const D: usize>(origin: &str, node: &Node, tag: u64) -> Result<[f64; D]> {
    if D == 2 && node.coordinates[2] != 0.0 {
        return Err(fail(
            origin,
            node.location,
            "z = 0 for the nodes of a 2D mesh",
            format!("z = {} for node {tag}", node.coordinates[2]),
        ));
    }
    Ok(std::array::from_fn(|k| node.coordinates[k]))
}

/// Compacts the nodes used by cells into vertices (ascending tag order) and builds the mesh.
pub(super) fn build_mesh<const D: usize>(
    origin: &str,
    nodes: &HashMap<u64, Node>,
    elements: Elements,
) -> Result<Mesh<D>> {
    let (cell_name, cells_name) = if D == 2 {
        ("triangle", "triangles (element type 2 or 9)")
    } else {
        ("tetrahedron", "tetrahedra (element type 4 or 11)")
    };
    if elements.cell_nodes.is_empty() {
        return Err(fail(
            origin,
            elements.section,
            format!("{cells_name} in an entity block of dimension {D}"),
            "none in `$Elements`",
        ));
    }
    let mut used = elements.cell_nodes.clone();
    used.sort_unstable();
    used.dedup();
    let index: HashMap<u64, usize> = used.iter().enumerate().map(|(i, &t)| (t, i)).collect();
    let mut vertices = Vec::with_capacity(used.len());
    for tag in &used {
        let node = nodes.get(tag).ok_or_else(|| {
            fail(
                origin,
                elements.section,
                "node tags defined in `$Nodes`",
                format!("node {tag}"),
            )
        })?;
        vertices.push(coordinates::<D>(origin, node, *tag)?);
    }
    let cells: Vec<usize> = elements.cell_nodes.iter().map(|tag| index[tag]).collect();
    let mut facets = Vec::with_capacity(elements.facet_nodes.len());
    for (f, facet) in elements.facet_nodes.chunks_exact(D).enumerate() {
        for tag in facet {
            let Some(&vertex) = index.get(tag) else {
                return Err(fail(
                    origin,
                    elements.facet_locations[f],
                    format!(
                        "the nodes of boundary element {} to be vertices of {cell_name}s",
                        elements.facet_elements[f]
                    ),
                    format!("node {tag}, which belongs to no {cell_name}"),
                ));
            };
            facets.push(vertex);
        }
    }
    let mut edge_points = Vec::with_capacity(elements.edge_nodes.len());
    for &(a, b, middle) in &elements.edge_nodes {
        let point = coordinates::<D>(origin, &nodes[&middle], middle)?;
        edge_points.push(((index[&a], index[&b]), point));
    }
    let mesh = Mesh::new(vertices, cells, facets, elements.facet_parts)
        .and_then(|mesh| mesh.with_curved_edges(edge_points));
    mesh.map_err(|error| match error {
        Error::InvalidMesh(message) => {
            let hint = if D == 2 && message.contains("inverted") {
                "; a clockwise triangle usually means the Gmsh surface's normal points to −z: \
                 reverse its curve loop or use `ReverseMesh Surface{…};`"
            } else {
                ""
            };
            Error::InvalidMesh(format!(
                "{origin}: {message} (vertices are the nodes of {cell_name}s numbered from 0 in \
                 ascending node-tag order; cells and boundary facets are numbered from 0 in \
                 `$Elements` order{hint})"
            ))
        }
        other => other,
    })
}
