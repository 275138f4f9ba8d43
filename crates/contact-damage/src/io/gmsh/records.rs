//! The records read from `$PhysicalNames`, `$Entities`, `$Nodes` and `$Elements`, the same for
//! both encodings, and what is done with each element block.

use std::collections::{BTreeMap, HashMap};

use super::reader::{fail, Location};
use crate::error::Result;
use crate::fem::mesh::BoundaryPart;

/// Names of entities and of their dimensions in messages.
pub(super) const ENTITY_KINDS: [&str; 4] = ["point", "curve", "surface", "volume"];

/// One physical name: `dimension tag "name"`.
pub(super) struct PhysicalName {
    pub(super) dimension: usize,
    pub(super) tag: i32,
    pub(super) name: String,
}

/// A geometric entity with its physical tags.
pub(super) struct Entity {
    pub(super) physical_tags: Vec<i32>,
    pub(super) location: Location,
}

/// Entities by dimension (0 to 3) and tag.
pub(super) type Entities = [BTreeMap<i32, Entity>; 4];

/// A node with the location of its coordinates.
pub(super) struct Node {
    pub(super) coordinates: [f64; 3],
    pub(super) location: Location,
}

/// The cells and tagged boundary facets of `$Elements`, by node tag, in file order.
pub(super) struct Elements {
    /// The `$Elements` header.
    pub(super) section: Location,
    /// Vertex node tags of the cells, stride D + 1.
    pub(super) cell_nodes: Vec<u64>,
    /// The edges of second-order cells: (vertex tag, vertex tag, edge node tag).
    pub(super) edge_nodes: Vec<(u64, u64, u64)>,
    /// Vertex node tags of the boundary facets, stride D.
    pub(super) facet_nodes: Vec<u64>,
    pub(super) facet_parts: Vec<BoundaryPart>,
    pub(super) facet_locations: Vec<Location>,
    pub(super) facet_elements: Vec<u64>,
}

/// What the element blocks of `$Elements` are read against: the `$Elements` header, the nodes,
/// the entities, and the boundary part of each mapped entity of dimension D − 1.
pub(super) struct ElementBlocks<'s> {
    pub(super) section: Location,
    pub(super) nodes: &'s HashMap<u64, Node>,
    pub(super) entities: &'s Entities,
    pub(super) entity_parts: &'s BTreeMap<i32, BoundaryPart>,
}

impl Elements {
    /// No elements yet, for the `$Elements` section at `section`.
    pub(super) fn new(section: Location) -> Self {
        Elements {
            section,
            cell_nodes: Vec::new(),
            edge_nodes: Vec::new(),
            facet_nodes: Vec::new(),
            facet_parts: Vec::new(),
            facet_locations: Vec::new(),
            facet_elements: Vec::new(),
        }
    }
}

/// Adds an entity of `$Entities`; a tag seen before in the same dimension is an error.
pub(super) fn insert_entity(
    origin: &str,
    entities: &mut Entities,
    dimension: usize,
    tag: i32,
    entity: Entity,
) -> Result<()> {
    let location = entity.location;
    match entities[dimension].insert(tag, entity) {
        None => Ok(()),
        Some(previous) => {
            let kind = ENTITY_KINDS[dimension];
            Err(fail(
                origin,
                location,
                format!("distinct {kind} tags"),
                format!("{kind} {tag} again (first at {})", previous.location),
            ))
        }
    }
}

/// Adds a node of `$Nodes`; a tag seen before is an error.
pub(super) fn insert_node(
    origin: &str,
    nodes: &mut HashMap<u64, Node>,
    tag: u64,
    node: Node,
) -> Result<()> {
    let location = node.location;
    match nodes.insert(tag, node) {
        None => Ok(()),
        Some(previous) => Err(fail(
            origin,
            location,
            "distinct node tags",
            format!("node {tag} again (first at {})", previous.location),
        )),
    }
}

/// Gmsh element types used here: (type, number of nodes, number of vertices, name).
const ELEMENT_TYPES: [(i32, usize, usize, &str); 6] = [
    (1, 2, 2, "2-node line"),
    (8, 3, 2, "3-node line"),
    (2, 3, 3, "3-node triangle"),
    (9, 6, 3, "6-node triangle"),
    (4, 4, 4, "4-node tetrahedron"),
    (11, 10, 4, "10-node tetrahedron"),
];

/// The local vertex pairs of the edge nodes of the 6-node triangle and the 10-node
/// tetrahedron, in Gmsh's node order (nodes 3–5, 4–9).
const GMSH_EDGES: [&[[usize; 2]]; 2] = [
    &[[0, 1], [1, 2], [2, 0]],
    &[[0, 1], [1, 2], [2, 0], [3, 0], [3, 2], [3, 1]],
];

/// Number of nodes and of vertices of a simplex element type with `vertices` vertices, or
/// None for other types.
fn simplex_type(element_type: i32, vertices: usize) -> Option<usize> {
    ELEMENT_TYPES
        .iter()
        .find(|&&(code, _, count, _)| code == element_type && count == vertices)
        .map(|&(_, nodes, _, _)| nodes)
}

/// Name of a Gmsh element type for messages.
pub(super) fn element_type_name(element_type: i32) -> String {
    const OTHERS: [(i32, &str); 6] = [
        (3, "4-node quadrangle"),
        (5, "8-node hexahedron"),
        (6, "6-node prism"),
        (7, "5-node pyramid"),
        (10, "9-node quadrangle"),
        (15, "1-node point"),
    ];
    let known = ELEMENT_TYPES
        .iter()
        .map(|&(code, _, _, name)| (code, name))
        .chain(OTHERS)
        .find(|&(code, _)| code == element_type);
    match known {
        Some((_, name)) => format!("element type {element_type} ({name})"),
        None => format!("element type {element_type}"),
    }
}

/// What is done with the elements of one block.
#[derive(Clone, Copy)]
pub(super) enum BlockRole {
    Skip,
    Cells { nodes: usize },
    Facets { nodes: usize, part: BoundaryPart },
}

/// The role of an element block of dimension `dimension` on entity `entity` with elements of
/// type `element_type`: cells for dimension D, facets for a mapped entity of dimension D − 1,
/// skipped otherwise. Blocks of dimension greater than D, cells that are not triangles
/// (tetrahedra) and mapped facets that are not lines (triangles) are errors at `location`.
pub(super) fn block_role<const D: usize>(
    origin: &str,
    location: Location,
    dimension: usize,
    entity: i32,
    element_type: i32,
    blocks: &ElementBlocks,
) -> Result<BlockRole> {
    let (cell_name, facet_name) = if D == 2 {
        ("triangle", "line")
    } else {
        ("tetrahedron", "triangle")
    };
    if dimension > D {
        return Err(fail(
            origin,
            location,
            format!("entity blocks of dimension at most {D} in a {D}D mesh"),
            format!(
                "a block of {} on {} {entity}",
                element_type_name(element_type),
                ENTITY_KINDS[dimension]
            ),
        ));
    }
    if dimension == D {
        return match simplex_type(element_type, D + 1) {
            Some(nodes) => Ok(BlockRole::Cells { nodes }),
            None => Err(fail(
                origin,
                location,
                format!("{cell_name}s (first or second order) in a {D}D entity block"),
                element_type_name(element_type),
            )),
        };
    }
    if dimension + 1 < D {
        return Ok(BlockRole::Skip);
    }
    let kind = ENTITY_KINDS[dimension];
    if !blocks.entities[dimension].contains_key(&entity) {
        return Err(fail(
            origin,
            location,
            format!("a {kind} tag declared in `$Entities`"),
            format!("{kind} {entity}"),
        ));
    }
    let Some(&part) = blocks.entity_parts.get(&entity) else {
        return Ok(BlockRole::Skip);
    };
    match simplex_type(element_type, D) {
        Some(nodes) => Ok(BlockRole::Facets { nodes, part }),
        None => Err(fail(
            origin,
            location,
            format!(
                "{facet_name}s (first or second order) on {kind} {entity} of {}",
                part.label()
            ),
            element_type_name(element_type),
        )),
    }
}

/// Adds element `tag` with nodes `node_tags` of a block of role `role` (cells or facets;
/// skipped blocks add nothing) to `elements`; a node missing from `$Nodes` is an error at
/// `location`.
pub(super) fn push_element<const D: usize>(
    origin: &str,
    location: Location,
    elements: &mut Elements,
    role: BlockRole,
    tag: u64,
    node_tags: &[u64],
    nodes: &HashMap<u64, Node>,
) -> Result<()> {
    let (vertices, part) = match role {
        BlockRole::Skip => return Ok(()),
        BlockRole::Cells { .. } => (D + 1, None),
        BlockRole::Facets { part, .. } => (D, Some(part)),
    };
    if let Some(missing) = node_tags.iter().find(|node| !nodes.contains_key(node)) {
        return Err(fail(
            origin,
            location,
            "node tags defined in `$Nodes`",
            format!("node {missing} in element {tag}"),
        ));
    }
    match part {
        None => {
            elements
                .cell_nodes
                .extend_from_slice(&node_tags[..vertices]);
            if node_tags.len() > vertices {
                for (k, &[a, b]) in GMSH_EDGES[vertices - 3].iter().enumerate() {
                    let edge = (node_tags[a], node_tags[b], node_tags[vertices + k]);
                    elements.edge_nodes.push(edge);
                }
            }
        }
        Some(part) => {
            elements
                .facet_nodes
                .extend_from_slice(&node_tags[..vertices]);
            elements.facet_parts.push(part);
            elements.facet_locations.push(location);
            elements.facet_elements.push(tag);
        }
    }
    Ok(())
}
