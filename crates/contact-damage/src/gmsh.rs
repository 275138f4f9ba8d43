//! Reader of Gmsh meshes in the MSH 4.1 ASCII format (what Gmsh writes with
//! `Mesh.MshFileVersion = 4.1; Mesh.Binary = 0;`), producing a validated [`Mesh`] whose
//! boundary facets are tagged with the parts Γ1, Γ2, Γ3 of the paper (§2) through physical
//! groups.
//!
//! What is read:
//! - `$MeshFormat`: version 4.1 and file-type 0 (ASCII) are required;
//! - `$PhysicalNames` (optional): the names of physical groups, for [`GroupRef::Name`];
//! - `$Entities`: the physical tags of each geometric entity (point, curve, surface, volume);
//! - `$Nodes`: node coordinates. Node tags may be sparse; they are compacted: the mesh vertices
//!   are the nodes used by cells, in ascending tag order (nodes of no cell are dropped, since
//!   [`Mesh::new`] rejects vertices without cells);
//! - `$Elements`: in entity blocks of dimension D, the triangles (D = 2) or tetrahedra (D = 3)
//!   are the cells, in file order; in entity blocks of dimension D − 1 whose entity belongs to a
//!   physical group mapped to a boundary part by [`PhysicalMap`], the lines (D = 2) or
//!   triangles (D = 3) are the boundary facets of that part, in file order. Blocks of lower
//!   dimension (points, edges of a 3D mesh) and blocks of unmapped entities are skipped; their
//!   facets stay untagged, which [`Mesh::new`] reports if they lie on the boundary.
//!
//! Other sections (`$Periodic`, `$NodeData`, `$Comments`, …) are skipped; partitioned meshes
//! (`$PartitionedEntities`) are rejected. Sections must come in the order Gmsh writes them:
//! `$MeshFormat`, `$PhysicalNames`, `$Entities`, `$Nodes`, `$Elements`; all but
//! `$PhysicalNames` are required (Gmsh always writes them).
//!
//! Second-order elements (3-node lines, type 8; 6-node triangles, type 9; 10-node tetrahedra,
//! type 11) are accepted, but only their vertex nodes are used: the P2 space
//! ([`crate::space::LagrangeSpace`]) rebuilds its edge nodes as midpoints of straight edges, so
//! curved geometry is not represented.
//!
//! Nothing is changed silently: Gmsh orients triangles and tetrahedra positively by
//! convention (in 2D: when the surface normal is +z), and an inverted cell is reported by
//! [`Mesh::new`], never reoriented. In 2D every node used by a cell must have z = 0.
//!
//! Records are read line by line, as Gmsh writes them: each header, node tag, coordinate line,
//! entity and element is one line; blank lines are ignored. Every error is an
//! [`Error::InvalidMesh`] of the form `origin:line: expected …, found …` with the 1-based line
//! number; errors found by [`Mesh::new`] after reading name the origin and explain how its
//! vertex and cell indices relate to the file.

use std::collections::{BTreeMap, HashMap};
use std::fmt;
use std::path::Path;
use std::str::FromStr;

use crate::mesh::{BoundaryPart, Mesh};
use crate::{Error, Result};

/// A Gmsh physical group of dimension D − 1 (curves in 2D, surfaces in 3D).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum GroupRef {
    /// The group with this name in `$PhysicalNames` (every group of dimension D − 1 with it).
    Name(String),
    /// The group with this physical tag.
    Tag(i32),
}

impl fmt::Display for GroupRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GroupRef::Name(name) => write!(f, "\"{name}\""),
            GroupRef::Tag(tag) => write!(f, "tag {tag}"),
        }
    }
}

/// How physical groups of dimension D − 1 map to the boundary parts of the paper (§2): the
/// facets of an entity in one of the `dirichlet` groups lie on Γ1, `neumann` on Γ2, `contact`
/// on Γ3. A group may appear in one part only; every listed group must exist and contain at
/// least one entity of dimension D − 1.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct PhysicalMap {
    /// Groups of Γ1 (clamped, u = 0).
    pub dirichlet: Vec<GroupRef>,
    /// Groups of Γ2 (surface traction f2).
    pub neumann: Vec<GroupRef>,
    /// Groups of Γ3 (normal compliance and friction).
    pub contact: Vec<GroupRef>,
}

impl PhysicalMap {
    /// A map by group names: `PhysicalMap::by_names(&["clamped"], &["traction"], &["contact"])`.
    pub fn by_names(dirichlet: &[&str], neumann: &[&str], contact: &[&str]) -> Self {
        let refs = |names: &[&str]| {
            names
                .iter()
                .map(|name| GroupRef::Name(name.to_string()))
                .collect()
        };
        PhysicalMap {
            dirichlet: refs(dirichlet),
            neumann: refs(neumann),
            contact: refs(contact),
        }
    }

    fn parts(&self) -> [(BoundaryPart, &[GroupRef]); 3] {
        [
            (BoundaryPart::Dirichlet, &self.dirichlet),
            (BoundaryPart::Neumann, &self.neumann),
            (BoundaryPart::Contact, &self.contact),
        ]
    }
}

/// Reads a Gmsh MSH 4.1 ASCII file into a mesh of dimension D ∈ {2, 3}; see the module
/// documentation for what is read and [`parse_msh`] for the errors. An unreadable file is an
/// [`Error::InvalidInput`] naming the path. Bytes that are not UTF-8 are replaced (only names
/// in `$PhysicalNames` could contain them).
pub fn read_msh<const D: usize>(path: &Path, map: &PhysicalMap) -> Result<Mesh<D>> {
    let bytes = std::fs::read(path)
        .map_err(|error| Error::InvalidInput(format!("cannot read {}: {error}", path.display())))?;
    let text = String::from_utf8_lossy(&bytes);
    parse_msh(&text, &path.display().to_string(), map)
}

/// Parses the text of a Gmsh MSH 4.1 ASCII file into a mesh of dimension D ∈ {2, 3}; `origin`
/// names the text in error messages (usually the file name).
///
/// Errors ([`Error::InvalidMesh`], `origin:line: expected …, found …`): another format version
/// than 4.1; a binary file; a missing, duplicated, truncated or misplaced section; a malformed
/// record (wrong number of fields, a field that is not a number, a non-finite coordinate); a
/// duplicated node or entity tag; an element that refers to a node missing from `$Nodes`; a
/// block of dimension greater than D; elements other than triangles/tetrahedra in a block of
/// dimension D, or other than lines/triangles in a mapped block of dimension D − 1; a boundary
/// element on a node of no cell; a group of the map that does not exist, has no entity of
/// dimension D − 1, or is mapped to two parts; an entity whose groups map to two parts; a 2D
/// node off the plane z = 0; no cell at all; and everything [`Mesh::new`] checks (inverted or
/// degenerate cells, untagged boundary facets, no Dirichlet facet, …).
/// D ∉ {2, 3} is an [`Error::InvalidInput`].
pub fn parse_msh<const D: usize>(text: &str, origin: &str, map: &PhysicalMap) -> Result<Mesh<D>> {
    if D != 2 && D != 3 {
        return Err(Error::InvalidInput(format!(
            "Gmsh meshes can be read in dimension 2 or 3, not {D}"
        )));
    }
    let mut reader = Reader {
        origin,
        lines: text.lines().enumerate(),
        line: 0,
    };
    read_mesh_format(&mut reader)?;

    // Known sections in the order Gmsh writes them, with their rank.
    const ORDER: [&str; 4] = ["PhysicalNames", "Entities", "Nodes", "Elements"];
    let mut last_section: Option<(usize, Record)> = None;
    let mut physical_names: Option<(usize, Vec<PhysicalName>)> = None;
    let mut entities: Option<(usize, Entities)> = None;
    let mut nodes: Option<HashMap<u64, Node>> = None;
    let mut elements: Option<Elements> = None;

    while let Some(header) = reader.next_record() {
        let Some(name) = header.text.strip_prefix('$') else {
            return Err(header.fail("a section header `$Name`"));
        };
        if name == "PartitionedEntities" {
            return Err(header.fail(
                "an unpartitioned mesh (partitioned meshes are not supported; save without \
                 partitioning)",
            ));
        }
        if name == "MeshFormat" || name.starts_with("End") {
            return Err(header.fail("a section header other than `$MeshFormat` or `$End…`"));
        }
        let Some(rank) = ORDER.iter().position(|&known| known == name) else {
            skip_section(&mut reader, name)?;
            continue;
        };
        if let Some((last_rank, last)) = &last_section {
            if rank <= *last_rank {
                return Err(header.fail_with(
                    "the sections in the order `$MeshFormat`, `$PhysicalNames`, `$Entities`, \
                     `$Nodes`, `$Elements`, each at most once",
                    format!(
                        "`{}` after `{}` at line {}",
                        header.text, last.text, last.line
                    ),
                ));
            }
        }
        match rank {
            0 => physical_names = Some((header.line, read_physical_names(&mut reader)?)),
            1 => entities = Some((header.line, read_entities(&mut reader)?)),
            2 => {
                if entities.is_none() {
                    return Err(header.fail("an `$Entities` section before `$Nodes`"));
                }
                nodes = Some(read_nodes(&mut reader)?);
            }
            _ => {
                let (Some((entities_line, entities)), Some(nodes)) = (&entities, &nodes) else {
                    return Err(header.fail("`$Entities` and `$Nodes` sections before `$Elements`"));
                };
                let group_parts = resolve_map(
                    map,
                    physical_names.as_ref(),
                    entities,
                    *entities_line,
                    D - 1,
                    &header,
                )?;
                let entity_parts = boundary_entity_parts(origin, entities, &group_parts, D - 1)?;
                elements = Some(read_elements::<D>(
                    &mut reader,
                    &header,
                    nodes,
                    entities,
                    &entity_parts,
                )?);
            }
        }
        last_section = Some((rank, header));
    }
    let (Some(nodes), Some(elements)) = (nodes, elements) else {
        return Err(fail(
            origin,
            reader.line + 1,
            "`$Nodes` and `$Elements` sections",
            "end of file",
        ));
    };
    build_mesh::<D>(origin, &nodes, elements)
}

/// Names of entities and of their dimensions in messages.
const ENTITY_KINDS: [&str; 4] = ["point", "curve", "surface", "volume"];

/// One physical name: `dimension tag "name"`.
struct PhysicalName {
    dimension: usize,
    tag: i32,
    name: String,
}

/// A geometric entity with its physical tags.
struct Entity {
    physical_tags: Vec<i32>,
    line: usize,
}

/// Entities by dimension (0 to 3) and tag.
type Entities = [BTreeMap<i32, Entity>; 4];

/// A node with the line of its coordinates.
struct Node {
    coordinates: [f64; 3],
    line: usize,
}

/// The cells and tagged boundary facets of `$Elements`, by node tag, in file order.
struct Elements {
    header_line: usize,
    /// Vertex node tags of the cells, stride D + 1.
    cell_nodes: Vec<u64>,
    /// Vertex node tags of the boundary facets, stride D.
    facet_nodes: Vec<u64>,
    facet_parts: Vec<BoundaryPart>,
    facet_lines: Vec<usize>,
    facet_elements: Vec<u64>,
}

/// A non-blank line split into whitespace-separated fields.
struct Record<'a> {
    origin: &'a str,
    line: usize,
    text: &'a str,
    fields: Vec<&'a str>,
}

impl Record<'_> {
    /// The line, quoted and shortened for messages.
    fn quoted(&self) -> String {
        format!("`{}`", shorten(self.text))
    }

    /// Error at this line: expected …, found this line.
    fn fail(&self, expected: impl fmt::Display) -> Error {
        fail(self.origin, self.line, expected, self.quoted())
    }

    /// Error at this line with a custom "found" part.
    fn fail_with(&self, expected: impl fmt::Display, found: impl fmt::Display) -> Error {
        fail(self.origin, self.line, expected, found)
    }

    /// Requires exactly `count` fields.
    fn expect_fields(&self, count: usize, what: &str) -> Result<()> {
        if self.fields.len() == count {
            Ok(())
        } else {
            Err(self.fail_with(
                format!("{what} ({count} fields)"),
                format!(
                    "{} ({} field{})",
                    self.quoted(),
                    self.fields.len(),
                    if self.fields.len() == 1 { "" } else { "s" }
                ),
            ))
        }
    }

    /// Parses field `index` (0-based) as a `T`, `what` describing it.
    fn parse<T: FromStr>(&self, index: usize, what: &str) -> Result<T> {
        let Some(field) = self.fields.get(index) else {
            return Err(self.fail(format!("{what} as field {}", index + 1)));
        };
        field.parse().map_err(|_| {
            self.fail_with(
                format!("{what} as field {}", index + 1),
                format!("`{}` in {}", shorten(field), self.quoted()),
            )
        })
    }

    /// Parses field `index` as a finite coordinate.
    fn coordinate(&self, index: usize, what: &str) -> Result<f64> {
        let value: f64 = self.parse(index, what)?;
        if value.is_finite() {
            Ok(value)
        } else {
            Err(self.fail_with(
                format!("{what} (finite) as field {}", index + 1),
                format!("{value} in {}", self.quoted()),
            ))
        }
    }
}

/// Line-by-line reader that keeps the 1-based number of the last line read.
struct Reader<'a> {
    origin: &'a str,
    lines: std::iter::Enumerate<std::str::Lines<'a>>,
    line: usize,
}

impl<'a> Reader<'a> {
    /// The next non-blank line, or None at the end of the text.
    fn next_record(&mut self) -> Option<Record<'a>> {
        for (index, text) in self.lines.by_ref() {
            self.line = index + 1;
            let text = text.trim();
            if !text.is_empty() {
                return Some(Record {
                    origin: self.origin,
                    line: self.line,
                    text,
                    fields: text.split_whitespace().collect(),
                });
            }
        }
        None
    }

    /// The next non-blank line; at the end of the text an error expecting `expected`.
    fn expect_record(&mut self, expected: impl fmt::Display) -> Result<Record<'a>> {
        match self.next_record() {
            Some(record) => Ok(record),
            None => Err(fail(self.origin, self.line + 1, expected, "end of file")),
        }
    }

    /// Requires the line `$End<section>`.
    fn expect_end(&mut self, section: &str) -> Result<()> {
        let end = format!("$End{section}");
        let record = self.expect_record(format!("`{end}`"))?;
        if record.text == end {
            Ok(())
        } else {
            Err(record.fail(format!("`{end}`")))
        }
    }
}

/// `origin:line: expected …, found …`.
fn fail(origin: &str, line: usize, expected: impl fmt::Display, found: impl fmt::Display) -> Error {
    Error::InvalidMesh(format!(
        "{origin}:{line}: expected {expected}, found {found}"
    ))
}

/// At most 80 characters of `text` (cut at a character boundary).
fn shorten(text: &str) -> String {
    match text.char_indices().nth(77) {
        Some((cut, _)) if text.chars().count() > 80 => format!("{}…", &text[..cut]),
        _ => text.to_string(),
    }
}

/// `$MeshFormat` / `4.1 0 8` / `$EndMeshFormat`.
fn read_mesh_format(reader: &mut Reader) -> Result<()> {
    let first = reader.expect_record("`$MeshFormat`")?;
    if first.text != "$MeshFormat" {
        return Err(first.fail("`$MeshFormat` (the first line of a Gmsh .msh file)"));
    }
    const HEADER: &str = "the format header `version file-type data-size`";
    let header = reader.expect_record(HEADER)?;
    header.expect_fields(3, HEADER)?;
    let version = header.fields[0];
    if version.parse::<f64>().ok() != Some(4.1) {
        return Err(header.fail_with(
            "MSH format version 4.1 (save with `Mesh.MshFileVersion = 4.1;`)",
            format!("version `{}`", shorten(version)),
        ));
    }
    match header.fields[1] {
        "0" => {}
        "1" => {
            return Err(header.fail_with(
                "file-type 0 (ASCII)",
                "file-type 1: binary .msh not supported yet, save as ASCII (`Mesh.Binary = 0;`)",
            ))
        }
        other => {
            return Err(header.fail_with(
                "file-type 0 (ASCII)",
                format!("file-type `{}`", shorten(other)),
            ))
        }
    }
    header.parse::<usize>(2, "the data size (an integer)")?;
    reader.expect_end("MeshFormat")
}

/// Skips an unknown section up to its `$End<name>` line.
fn skip_section(reader: &mut Reader, name: &str) -> Result<()> {
    let end = format!("$End{name}");
    while let Some(record) = reader.next_record() {
        if record.text == end {
            return Ok(());
        }
    }
    Err(fail(
        reader.origin,
        reader.line + 1,
        format!("`{end}`"),
        "end of file",
    ))
}

/// `$PhysicalNames`: a count, then `dimension tag "name"` lines.
fn read_physical_names(reader: &mut Reader) -> Result<Vec<PhysicalName>> {
    const COUNT: &str = "the number of physical names";
    let header = reader.expect_record(COUNT)?;
    header.expect_fields(1, COUNT)?;
    let count: usize = header.parse(0, COUNT)?;
    let mut names = Vec::new();
    for _ in 0..count {
        const WHAT: &str = "a physical name `dimension tag \"name\"`";
        let record = reader.expect_record(WHAT)?;
        let dimension: usize = record.parse(0, "the dimension (0 to 3)")?;
        if dimension > 3 {
            return Err(record.fail("the dimension (0 to 3) as field 1"));
        }
        let tag: i32 = record.parse(1, "the physical tag")?;
        let quoted = skip_fields(record.text, 2);
        if quoted.len() < 2 || !quoted.starts_with('"') || !quoted.ends_with('"') {
            return Err(record.fail(WHAT));
        }
        names.push(PhysicalName {
            dimension,
            tag,
            name: quoted[1..quoted.len() - 1].to_string(),
        });
    }
    reader.expect_end("PhysicalNames")?;
    Ok(names)
}

/// The rest of `text` after its first `count` whitespace-separated fields, trimmed.
fn skip_fields(text: &str, count: usize) -> &str {
    let mut rest = text;
    for _ in 0..count {
        rest = rest.trim_start();
        let end = rest.find(char::is_whitespace).unwrap_or(rest.len());
        rest = &rest[end..];
    }
    rest.trim()
}

/// `$Entities`: counts of points, curves, surfaces, volumes, then one line per entity:
/// `tag X Y Z numPhysicalTags physicalTag…` for points and
/// `tag minX minY minZ maxX maxY maxZ numPhysicalTags physicalTag… numBounding boundingTag…`
/// for the others.
fn read_entities(reader: &mut Reader) -> Result<Entities> {
    const COUNTS: &str = "the entity counts `numPoints numCurves numSurfaces numVolumes`";
    let header = reader.expect_record(COUNTS)?;
    header.expect_fields(4, COUNTS)?;
    let mut counts = [0usize; 4];
    for (dimension, count) in counts.iter_mut().enumerate() {
        *count = header.parse(
            dimension,
            &format!("the number of {}s", ENTITY_KINDS[dimension]),
        )?;
    }
    let mut entities: Entities = Default::default();
    for (dimension, &count) in counts.iter().enumerate() {
        let kind = ENTITY_KINDS[dimension];
        for _ in 0..count {
            let record = reader.expect_record(format!("a {kind} entity"))?;
            let tag: i32 = record.parse(0, &format!("the {kind} tag"))?;
            let box_coordinates = if dimension == 0 { 3 } else { 6 };
            for index in 1..=box_coordinates {
                record.parse::<f64>(index, "a coordinate of the entity's position or box")?;
            }
            let count_index = 1 + box_coordinates;
            let physical_count: usize = record.parse(count_index, "the number of physical tags")?;
            if physical_count > record.fields.len() {
                return Err(record.fail(format!("{physical_count} physical tags")));
            }
            let physical_tags = (0..physical_count)
                .map(|k| record.parse(count_index + 1 + k, "a physical tag"))
                .collect::<Result<Vec<i32>>>()?;
            let mut end = count_index + 1 + physical_count;
            if dimension > 0 {
                let bounding: usize = record.parse(end, "the number of bounding entities")?;
                if bounding > record.fields.len() {
                    return Err(record.fail(format!("{bounding} bounding entity tags")));
                }
                for k in 0..bounding {
                    record.parse::<i32>(end + 1 + k, "a bounding entity tag")?;
                }
                end += 1 + bounding;
            }
            record.expect_fields(end, &format!("a {kind} entity"))?;
            let entity = Entity {
                physical_tags,
                line: record.line,
            };
            if let Some(previous) = entities[dimension].insert(tag, entity) {
                return Err(record.fail_with(
                    format!("distinct {kind} tags"),
                    format!("{kind} {tag} again (first at line {})", previous.line),
                ));
            }
        }
    }
    reader.expect_end("Entities")?;
    Ok(entities)
}

/// `$Nodes`: `numEntityBlocks numNodes minNodeTag maxNodeTag`, then blocks
/// `entityDim entityTag parametric numNodesInBlock`, the block's node tags one per line, and
/// their coordinates `x y z` (followed by `entityDim` parametric coordinates if parametric).
fn read_nodes(reader: &mut Reader) -> Result<HashMap<u64, Node>> {
    const HEADER: &str = "the node header `numEntityBlocks numNodes minNodeTag maxNodeTag`";
    let header = reader.expect_record(HEADER)?;
    header.expect_fields(4, HEADER)?;
    let blocks: usize = header.parse(0, "the number of entity blocks")?;
    let total: usize = header.parse(1, "the number of nodes")?;
    header.parse::<u64>(2, "the smallest node tag")?;
    header.parse::<u64>(3, "the largest node tag")?;
    let mut nodes: HashMap<u64, Node> = HashMap::new();
    let mut read = 0usize;
    for _ in 0..blocks {
        const BLOCK: &str = "a node block header `entityDim entityTag parametric numNodesInBlock`";
        let block = reader.expect_record(BLOCK)?;
        block.expect_fields(4, BLOCK)?;
        let dimension: usize = block.parse(0, "the entity dimension (0 to 3)")?;
        if dimension > 3 {
            return Err(block.fail("the entity dimension (0 to 3) as field 1"));
        }
        block.parse::<i32>(1, "the entity tag")?;
        let parametric = match block.fields[2] {
            "0" => false,
            "1" => true,
            _ => return Err(block.fail("the parametric flag 0 or 1 as field 3")),
        };
        let count: usize = block.parse(3, "the number of nodes in the block")?;
        let mut tags = Vec::new();
        for k in 0..count {
            let what = format!(
                "the tag of node {} of {count} of the block at line {}",
                k + 1,
                block.line
            );
            let record = reader.expect_record(&what)?;
            record.expect_fields(1, &what)?;
            tags.push(record.parse::<u64>(0, "a node tag")?);
        }
        let fields = 3 + if parametric { dimension } else { 0 };
        for tag in tags {
            let what = format!("the coordinates `x y z` of node {tag}");
            let record = reader.expect_record(&what)?;
            record.expect_fields(fields, &what)?;
            let mut coordinates = [0.0; 3];
            for (k, coordinate) in coordinates.iter_mut().enumerate() {
                *coordinate = record.coordinate(k, &format!("coordinate {k} of node {tag}"))?;
            }
            let node = Node {
                coordinates,
                line: record.line,
            };
            if let Some(previous) = nodes.insert(tag, node) {
                return Err(record.fail_with(
                    "distinct node tags",
                    format!("node {tag} again (first at line {})", previous.line),
                ));
            }
        }
        read += count;
    }
    if read != total {
        return Err(header.fail_with(
            format!("{total} nodes, as announced by the header"),
            format!("{read} nodes in the blocks"),
        ));
    }
    reader.expect_end("Nodes")?;
    Ok(nodes)
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

/// Number of nodes and of vertices of a simplex element type with `vertices` vertices, or
/// None for other types.
fn simplex_type(element_type: i32, vertices: usize) -> Option<usize> {
    ELEMENT_TYPES
        .iter()
        .find(|&&(code, _, count, _)| code == element_type && count == vertices)
        .map(|&(_, nodes, _, _)| nodes)
}

/// Name of a Gmsh element type for messages.
fn element_type_name(element_type: i32) -> String {
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

/// Human-readable label of a boundary part.
fn part_label(part: BoundaryPart) -> &'static str {
    match part {
        BoundaryPart::Dirichlet => "Γ1 (Dirichlet)",
        BoundaryPart::Neumann => "Γ2 (Neumann)",
        BoundaryPart::Contact => "Γ3 (contact)",
    }
}

/// Resolves the physical map into physical tag → part for groups of dimension
/// `boundary_dimension`, checking that every referenced group exists, contains an entity of
/// that dimension, and is mapped to one part only. `at` is the record where the map is needed
/// (the `$Elements` header), for errors without a better line.
fn resolve_map(
    map: &PhysicalMap,
    physical_names: Option<&(usize, Vec<PhysicalName>)>,
    entities: &Entities,
    entities_line: usize,
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
                    let Some((names_line, names)) = physical_names else {
                        return Err(at.fail_with(
                            format!(
                                "a `$PhysicalNames` section defining the group \"{name}\" of \
                                 {}",
                                part_label(part)
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
                            *names_line,
                            format!(
                                "a physical group \"{name}\" of dimension {boundary_dimension} \
                                 (mapped to {})",
                                part_label(part)
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
                        entities_line,
                        format!(
                            "a {kind} in physical group {tag} ({group}, mapped to {})",
                            part_label(part)
                        ),
                        format!("no {kind} of that group in `$Entities`"),
                    ));
                }
                if let Some(&other) = group_parts.get(&tag) {
                    if other != part {
                        return Err(fail(
                            at.origin,
                            entities_line,
                            format!("physical group {tag} ({group}) to be mapped to one part"),
                            format!(
                                "it mapped to both {} and {}",
                                part_label(other),
                                part_label(part)
                            ),
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
fn boundary_entity_parts(
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
                        entity.line,
                        format!("{kind} {tag} to lie in one boundary part"),
                        format!(
                            "physical groups {first_group} ({}) and {group} ({})",
                            part_label(first_part),
                            part_label(part)
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

/// What is done with the elements of one block.
enum BlockRole {
    Skip,
    Cells { nodes: usize },
    Facets { nodes: usize, part: BoundaryPart },
}

/// `$Elements`: `numEntityBlocks numElements minElementTag maxElementTag`, then blocks
/// `entityDim entityTag elementType numElementsInBlock` followed by one line
/// `elementTag nodeTag…` per element.
fn read_elements<const D: usize>(
    reader: &mut Reader,
    section: &Record,
    nodes: &HashMap<u64, Node>,
    entities: &Entities,
    entity_parts: &BTreeMap<i32, BoundaryPart>,
) -> Result<Elements> {
    const HEADER: &str =
        "the element header `numEntityBlocks numElements minElementTag maxElementTag`";
    let (cell_name, facet_name) = if D == 2 {
        ("triangle", "line")
    } else {
        ("tetrahedron", "triangle")
    };
    let header = reader.expect_record(HEADER)?;
    header.expect_fields(4, HEADER)?;
    let blocks: usize = header.parse(0, "the number of entity blocks")?;
    let total: usize = header.parse(1, "the number of elements")?;
    header.parse::<u64>(2, "the smallest element tag")?;
    header.parse::<u64>(3, "the largest element tag")?;
    let mut elements = Elements {
        header_line: section.line,
        cell_nodes: Vec::new(),
        facet_nodes: Vec::new(),
        facet_parts: Vec::new(),
        facet_lines: Vec::new(),
        facet_elements: Vec::new(),
    };
    let mut read = 0usize;
    for _ in 0..blocks {
        const BLOCK: &str =
            "an element block header `entityDim entityTag elementType numElementsInBlock`";
        let block = reader.expect_record(BLOCK)?;
        block.expect_fields(4, BLOCK)?;
        let dimension: usize = block.parse(0, "the entity dimension (0 to 3)")?;
        if dimension > 3 {
            return Err(block.fail("the entity dimension (0 to 3) as field 1"));
        }
        let entity: i32 = block.parse(1, "the entity tag")?;
        let element_type: i32 = block.parse(2, "the element type")?;
        let count: usize = block.parse(3, "the number of elements in the block")?;
        let role = if dimension > D {
            return Err(block.fail_with(
                format!("entity blocks of dimension at most {D} in a {D}D mesh"),
                format!(
                    "a block of {} on {} {entity}",
                    element_type_name(element_type),
                    ENTITY_KINDS[dimension]
                ),
            ));
        } else if dimension == D {
            match simplex_type(element_type, D + 1) {
                Some(nodes) => BlockRole::Cells { nodes },
                None => {
                    return Err(block.fail_with(
                        format!("{cell_name}s (first or second order) in a {D}D entity block"),
                        element_type_name(element_type),
                    ))
                }
            }
        } else if dimension + 1 == D {
            let kind = ENTITY_KINDS[dimension];
            if !entities[dimension].contains_key(&entity) {
                return Err(block.fail_with(
                    format!("a {kind} tag declared in `$Entities`"),
                    format!("{kind} {entity}"),
                ));
            }
            match entity_parts.get(&entity) {
                None => BlockRole::Skip,
                Some(&part) => match simplex_type(element_type, D) {
                    Some(nodes) => BlockRole::Facets { nodes, part },
                    None => {
                        return Err(block.fail_with(
                            format!(
                                "{facet_name}s (first or second order) on {kind} {entity} of {}",
                                part_label(part)
                            ),
                            element_type_name(element_type),
                        ))
                    }
                },
            }
        } else {
            BlockRole::Skip
        };
        for k in 0..count {
            let what = format!(
                "element {} of {count} of the block at line {}",
                k + 1,
                block.line
            );
            let record = reader.expect_record(&what)?;
            let (element_nodes, facet_part) = match role {
                BlockRole::Skip => {
                    if record.text.starts_with('$') {
                        return Err(record.fail(what));
                    }
                    continue;
                }
                BlockRole::Cells { nodes } => (nodes, None),
                BlockRole::Facets { nodes, part } => (nodes, Some(part)),
            };
            record.expect_fields(
                1 + element_nodes,
                &format!("an element tag and {element_nodes} node tags"),
            )?;
            let tag: u64 = record.parse(0, "the element tag")?;
            let vertices = if facet_part.is_some() { D } else { D + 1 };
            for index in 0..element_nodes {
                let node: u64 = record.parse(1 + index, "a node tag")?;
                if !nodes.contains_key(&node) {
                    return Err(record.fail_with(
                        "node tags defined in `$Nodes`",
                        format!("node {node} in element {tag}"),
                    ));
                }
                if index < vertices {
                    match facet_part {
                        Some(_) => elements.facet_nodes.push(node),
                        None => elements.cell_nodes.push(node),
                    }
                }
            }
            if let Some(part) = facet_part {
                elements.facet_parts.push(part);
                elements.facet_lines.push(record.line);
                elements.facet_elements.push(tag);
            }
        }
        read += count;
    }
    if read != total {
        return Err(header.fail_with(
            format!("{total} elements, as announced by the header"),
            format!("{read} elements in the blocks"),
        ));
    }
    reader.expect_end("Elements")?;
    Ok(elements)
}

/// Compacts the nodes used by cells into vertices (ascending tag order) and builds the mesh.
fn build_mesh<const D: usize>(
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
            elements.header_line,
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
                elements.header_line,
                "node tags defined in `$Nodes`",
                format!("node {tag}"),
            )
        })?;
        if D == 2 && node.coordinates[2] != 0.0 {
            return Err(fail(
                origin,
                node.line,
                "z = 0 for the nodes of a 2D mesh",
                format!("z = {} for node {tag}", node.coordinates[2]),
            ));
        }
        vertices.push(std::array::from_fn(|k| node.coordinates[k]));
    }
    let cells: Vec<usize> = elements.cell_nodes.iter().map(|tag| index[tag]).collect();
    let mut facets = Vec::with_capacity(elements.facet_nodes.len());
    for (f, facet) in elements.facet_nodes.chunks_exact(D).enumerate() {
        for tag in facet {
            let Some(&vertex) = index.get(tag) else {
                return Err(fail(
                    origin,
                    elements.facet_lines[f],
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
    Mesh::new(vertices, cells, facets, elements.facet_parts).map_err(|error| match error {
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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::fmt::Write as _;
    use std::path::PathBuf;
    use BoundaryPart::*;

    fn mesh_file(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/meshes")
            .join(name)
    }

    fn square_text() -> String {
        std::fs::read_to_string(mesh_file("square.msh")).unwrap()
    }

    fn names_map() -> PhysicalMap {
        PhysicalMap::by_names(&["clamped"], &["traction"], &["contact"])
    }

    fn error_message<T: fmt::Debug>(result: Result<T>) -> String {
        match result {
            Err(Error::InvalidMesh(message)) => message,
            other => panic!("expected an invalid-mesh error, got {other:?}"),
        }
    }

    /// 1-based number of the first line of `text` equal to `line`.
    fn line_number(text: &str, line: &str) -> usize {
        text.lines().position(|l| l == line).unwrap() + 1
    }

    fn assert_same_mesh<const D: usize>(read: &Mesh<D>, expected: &Mesh<D>) {
        assert_eq!(read.vertices(), expected.vertices());
        let cells = |m: &Mesh<D>| {
            (0..m.num_cells())
                .map(|c| m.cell(c).to_vec())
                .collect::<Vec<_>>()
        };
        assert_eq!(cells(read), cells(expected));
        let facets = |m: &Mesh<D>| {
            (0..m.num_facets())
                .map(|f| (m.facet(f).to_vec(), m.facet_part(f)))
                .collect::<Vec<_>>()
        };
        assert_eq!(facets(read), facets(expected));
    }

    /// Gmsh's local edge order of 3-node lines, 6-node triangles and 10-node tetrahedra.
    const GMSH_EDGES: [[usize; 2]; 6] = [[0, 1], [1, 2], [2, 0], [3, 0], [3, 2], [3, 1]];

    /// A small MSH 4.1 writer: one boundary entity per run of consecutive facets of the same
    /// part; physical groups 1 "clamped", 2 "traction", 3 "contact" of dimension D − 1 and
    /// 4 "body" of dimension D; node tags 1.. in vertex order. With `second_order`, edge
    /// midpoints get the tags after the vertices and the elements are of type 8/9/11.
    fn msh_text<const D: usize>(mesh: &Mesh<D>, second_order: bool) -> String {
        let boundary = D - 1;
        let group = |part: BoundaryPart| match part {
            Dirichlet => 1,
            Neumann => 2,
            Contact => 3,
        };
        let mut out = String::new();
        writeln!(out, "$MeshFormat\n4.1 0 8\n$EndMeshFormat").unwrap();
        writeln!(
            out,
            "$PhysicalNames\n4\n{boundary} 1 \"clamped\"\n{boundary} 2 \"traction\"\n\
             {boundary} 3 \"contact\"\n{D} 4 \"body\"\n$EndPhysicalNames"
        )
        .unwrap();
        let mut runs: Vec<(BoundaryPart, Vec<usize>)> = Vec::new();
        for f in 0..mesh.num_facets() {
            let part = mesh.facet_part(f);
            match runs.last_mut() {
                Some((last, facets)) if *last == part => facets.push(f),
                _ => runs.push((part, vec![f])),
            }
        }
        let mut counts = [0; 4];
        counts[boundary] = runs.len();
        counts[D] = 1;
        writeln!(
            out,
            "$Entities\n{} {} {} {}",
            counts[0], counts[1], counts[2], counts[3]
        )
        .unwrap();
        for (i, (part, _)) in runs.iter().enumerate() {
            writeln!(out, "{} 0 0 0 1 1 1 1 {} 0", i + 1, group(*part)).unwrap();
        }
        writeln!(out, "1 0 0 0 1 1 1 1 4 0\n$EndEntities").unwrap();

        let edges = |dim: usize| -> &[[usize; 2]] {
            match dim {
                1 => &GMSH_EDGES[..1],
                2 => &GMSH_EDGES[..3],
                _ => &GMSH_EDGES[..],
            }
        };
        let mut coordinates: Vec<[f64; 3]> = mesh
            .vertices()
            .iter()
            .map(|x| std::array::from_fn(|k| if k < D { x[k] } else { 0.0 }))
            .collect();
        let mut midpoints: BTreeMap<(usize, usize), usize> = BTreeMap::new();
        let mut element_nodes = |vertices: &[usize], dim: usize| -> Vec<usize> {
            let mut list = vertices.to_vec();
            if second_order {
                for &[a, b] in edges(dim) {
                    let (a, b) = (vertices[a], vertices[b]);
                    let next = coordinates.len();
                    let id = *midpoints.entry((a.min(b), a.max(b))).or_insert(next);
                    if id == next {
                        let (p, q) = (coordinates[a], coordinates[b]);
                        coordinates.push(std::array::from_fn(|k| 0.5 * (p[k] + q[k])));
                    }
                    list.push(id);
                }
            }
            list
        };
        let cells: Vec<Vec<usize>> = (0..mesh.num_cells())
            .map(|c| element_nodes(mesh.cell(c), D))
            .collect();
        let facet_blocks: Vec<Vec<Vec<usize>>> = runs
            .iter()
            .map(|(_, facets)| {
                facets
                    .iter()
                    .map(|&f| element_nodes(mesh.facet(f), D - 1))
                    .collect()
            })
            .collect();

        let total = coordinates.len();
        writeln!(out, "$Nodes\n1 {total} 1 {total}\n{D} 1 0 {total}").unwrap();
        for tag in 1..=total {
            writeln!(out, "{tag}").unwrap();
        }
        for x in &coordinates {
            writeln!(out, "{} {} {}", x[0], x[1], x[2]).unwrap();
        }
        writeln!(out, "$EndNodes").unwrap();

        let (cell_type, facet_type) = match (D, second_order) {
            (2, false) => (2, 1),
            (2, true) => (9, 8),
            (_, false) => (4, 2),
            (_, true) => (11, 9),
        };
        let elements = mesh.num_cells() + mesh.num_facets();
        writeln!(out, "$Elements\n{} {elements} 1 {elements}", 1 + runs.len()).unwrap();
        let mut tag = 0;
        let mut write_element = |out: &mut String, nodes: &[usize]| {
            tag += 1;
            write!(out, "{tag}").unwrap();
            for node in nodes {
                write!(out, " {}", node + 1).unwrap();
            }
            writeln!(out).unwrap();
        };
        writeln!(out, "{D} 1 {cell_type} {}", cells.len()).unwrap();
        for cell in &cells {
            write_element(&mut out, cell);
        }
        for (i, block) in facet_blocks.iter().enumerate() {
            writeln!(out, "{boundary} {} {facet_type} {}", i + 1, block.len()).unwrap();
            for facet in block {
                write_element(&mut out, facet);
            }
        }
        writeln!(out, "$EndElements").unwrap();
        out
    }

    #[test]
    fn square_is_read_with_compacted_nodes_and_tagged_facets() {
        let mesh = read_msh::<2>(&mesh_file("square.msh"), &names_map()).unwrap();
        // Node tags 1, 2, 3, 4, 7, 10 in ascending order; tag 20 belongs to no triangle.
        let vertices = [
            [0.0, 0.0],
            [1.0, 0.0],
            [1.0, 1.0],
            [0.0, 1.0],
            [0.5, 0.0],
            [0.5, 0.5],
        ];
        assert_eq!(mesh.vertices(), &vertices);
        assert_eq!(mesh.num_cells(), 5);
        assert_eq!(mesh.cell(0), &[0, 4, 5]);
        assert_eq!(mesh.cell(4), &[3, 0, 5]);
        let facets: Vec<(Vec<usize>, BoundaryPart)> = (0..mesh.num_facets())
            .map(|f| (mesh.facet(f).to_vec(), mesh.facet_part(f)))
            .collect();
        let expected = vec![
            (vec![0, 4], Contact),
            (vec![4, 1], Contact),
            (vec![1, 2], Neumann),
            (vec![2, 3], Neumann),
            (vec![3, 0], Dirichlet),
        ];
        assert_eq!(facets, expected);
        let area: f64 = (0..mesh.num_cells()).map(|c| mesh.cell_volume(c)).sum();
        assert!((area - 1.0).abs() < 1e-15);
    }

    #[test]
    fn physical_groups_can_be_referenced_by_tag() {
        let map = PhysicalMap {
            dirichlet: vec![GroupRef::Tag(1)],
            neumann: vec![GroupRef::Tag(3)],
            contact: vec![GroupRef::Tag(2)],
        };
        let by_tag = parse_msh::<2>(&square_text(), "square.msh", &map).unwrap();
        let by_name = parse_msh::<2>(&square_text(), "square.msh", &names_map()).unwrap();
        assert_same_mesh(&by_tag, &by_name);
    }

    #[test]
    fn unmapped_boundary_entity_leaves_its_facets_untagged() {
        let map = PhysicalMap::by_names(&["clamped"], &[], &["contact"]);
        let message = error_message(parse_msh::<2>(&square_text(), "square.msh", &map));
        assert!(message.starts_with("square.msh: "), "{message}");
        assert!(message.contains("carries no boundary part"), "{message}");
    }

    #[test]
    fn gmsh_reader_rejects_unknown_version() {
        let path = mesh_file("wrong_version.msh");
        let message = error_message(read_msh::<2>(&path, &names_map()));
        let prefix = format!("{}:2: expected MSH format version 4.1", path.display());
        assert!(message.starts_with(&prefix), "{message}");
        assert!(message.contains("found version `2.2`"), "{message}");
    }

    #[test]
    fn gmsh_reader_rejects_binary_files() {
        let path = mesh_file("binary_header.msh");
        let message = error_message(read_msh::<3>(&path, &names_map()));
        assert!(
            message.starts_with(&format!("{}:2: ", path.display())),
            "{message}"
        );
        assert!(
            message.contains("binary .msh not supported yet, save as ASCII"),
            "{message}"
        );
    }

    #[test]
    fn unreadable_file_is_reported_with_its_path() {
        let path = mesh_file("does_not_exist.msh");
        match read_msh::<2>(&path, &names_map()) {
            Err(Error::InvalidInput(message)) => {
                assert!(message.contains("does_not_exist.msh"), "{message}")
            }
            other => panic!("expected an input error, got {other:?}"),
        }
    }

    #[test]
    fn truncated_nodes_block_is_reported_with_its_line() {
        // The last block announces nodes 10 and 20 but lists only the coordinates of 10.
        let text = square_text().replace("0.5 0.5 0\n2 2 0\n", "0.5 0.5 0\n");
        let line = line_number(&text, "$EndNodes");
        let message = error_message(parse_msh::<2>(&text, "cut.msh", &names_map()));
        assert!(
            message.starts_with(&format!(
                "cut.msh:{line}: expected the coordinates `x y z` of node 20"
            )),
            "{message}"
        );
        assert!(message.contains("found `$EndNodes` (1 field)"), "{message}");
        // The file ends inside $Nodes.
        let end = square_text();
        let cut = &end[..end.find("0.5 0 0\n").unwrap()];
        let message = error_message(parse_msh::<2>(cut, "cut.msh", &names_map()));
        let line = cut.lines().count() + 1;
        assert!(
            message.starts_with(&format!(
                "cut.msh:{line}: expected the coordinates `x y z` of node 7, found end of file"
            )),
            "{message}"
        );
    }

    #[test]
    fn element_referencing_missing_node_is_reported() {
        let text = square_text().replace("\n9 2 3 10\n", "\n9 2 3 99\n");
        let line = line_number(&text, "9 2 3 99");
        let message = error_message(parse_msh::<2>(&text, "bad.msh", &names_map()));
        assert_eq!(
            message,
            format!(
                "bad.msh:{line}: expected node tags defined in `$Nodes`, found node 99 in \
                 element 9"
            )
        );
    }

    #[test]
    fn unknown_physical_name_in_the_map_is_reported() {
        let map = PhysicalMap::by_names(&["clamped"], &["traction"], &["contakt"]);
        let message = error_message(parse_msh::<2>(&square_text(), "sq.msh", &map));
        assert!(
            message.starts_with(
                "sq.msh:4: expected a physical group \"contakt\" of dimension 1 (mapped to Γ3"
            ),
            "{message}"
        );
        assert!(message.contains("\"contact\" (dimension 1)"), "{message}");
        // A name of the wrong dimension, and a tag no curve carries.
        let map = PhysicalMap::by_names(&["clamped"], &["body"], &["contact"]);
        let message = error_message(parse_msh::<2>(&square_text(), "sq.msh", &map));
        assert!(message.contains("\"body\" (dimension 2)"), "{message}");
        let map = PhysicalMap {
            contact: vec![GroupRef::Tag(4)],
            ..names_map()
        };
        let message = error_message(parse_msh::<2>(&square_text(), "sq.msh", &map));
        let line = line_number(&square_text(), "$Entities");
        assert!(
            message.starts_with(&format!(
                "sq.msh:{line}: expected a curve in physical group 4 (tag 4, mapped to Γ3"
            )),
            "{message}"
        );
    }

    #[test]
    fn conflicting_parts_are_rejected() {
        let map = PhysicalMap::by_names(&["clamped"], &["traction", "contact"], &["contact"]);
        let message = error_message(parse_msh::<2>(&square_text(), "sq.msh", &map));
        assert!(
            message.contains("physical group 2 (\"contact\") to be mapped to one part"),
            "{message}"
        );
        // Curve 2 in the groups "traction" and "clamped".
        let text = square_text().replace(
            "\n2 1 0 0 1 1 0 1 3 2 2 -3\n",
            "\n2 1 0 0 1 1 0 2 3 1 2 2 -3\n",
        );
        let line = line_number(&text, "2 1 0 0 1 1 0 2 3 1 2 2 -3");
        let message = error_message(parse_msh::<2>(&text, "sq.msh", &names_map()));
        assert!(
            message.starts_with(&format!(
                "sq.msh:{line}: expected curve 2 to lie in one boundary part, found physical \
                 groups 3 (Γ2 (Neumann)) and 1 (Γ1 (Dirichlet))"
            )),
            "{message}"
        );
    }

    #[test]
    fn unsupported_elements_and_dimensions_are_rejected() {
        let text = square_text().replace("\n2 1 2 5\n", "\n2 1 3 5\n");
        let message = error_message(parse_msh::<2>(&text, "q.msh", &names_map()));
        assert!(
            message.contains(
                "expected triangles (first or second order) in a 2D entity block, \
                              found element type 3 (4-node quadrangle)"
            ),
            "{message}"
        );
        // A 3D mesh read as 2D, a 2D mesh read as 3D (with an empty map: the named groups
        // have the wrong dimension, which is reported first otherwise).
        let cube = read_to_string_cube();
        let no_map = PhysicalMap::default();
        let message = error_message(parse_msh::<2>(&cube, "cube.msh", &no_map));
        assert!(
            message.contains("expected entity blocks of dimension at most 2 in a 2D mesh"),
            "{message}"
        );
        let message = error_message(parse_msh::<3>(&square_text(), "sq.msh", &no_map));
        assert!(
            message.contains(
                "expected tetrahedra (element type 4 or 11) in an entity block of \
                              dimension 3, found none"
            ),
            "{message}"
        );
        assert!(matches!(
            parse_msh::<1>(&square_text(), "sq.msh", &names_map()),
            Err(Error::InvalidInput(_))
        ));
    }

    fn read_to_string_cube() -> String {
        std::fs::read_to_string(mesh_file("cube.msh")).unwrap()
    }

    #[test]
    fn nodes_off_the_plane_are_rejected_in_2d() {
        let text = square_text().replace("\n0.5 0.5 0\n", "\n0.5 0.5 0.25\n");
        let line = line_number(&text, "0.5 0.5 0.25");
        let message = error_message(parse_msh::<2>(&text, "z.msh", &names_map()));
        assert_eq!(
            message,
            format!(
                "z.msh:{line}: expected z = 0 for the nodes of a 2D mesh, found z = 0.25 for \
                 node 10"
            )
        );
        // The unused node 20 may lie anywhere.
        let text = square_text().replace("\n2 2 0\n", "\n2 2 7\n");
        parse_msh::<2>(&text, "z.msh", &names_map()).unwrap();
    }

    #[test]
    fn inverted_triangle_is_reported_not_reoriented() {
        let text = square_text().replace("\n7 1 7 10\n", "\n7 7 1 10\n");
        let message = error_message(parse_msh::<2>(&text, "inv.msh", &names_map()));
        assert!(message.starts_with("inv.msh: cell 0"), "{message}");
        assert!(message.contains("inverted"), "{message}");
        assert!(message.contains("ReverseMesh"), "{message}");
    }

    #[test]
    fn boundary_element_off_the_cells_is_reported() {
        let text = square_text().replace("\n5 3 4\n", "\n5 3 20\n");
        let line = line_number(&text, "5 3 20");
        let message = error_message(parse_msh::<2>(&text, "off.msh", &names_map()));
        assert_eq!(
            message,
            format!(
                "off.msh:{line}: expected the nodes of boundary element 5 to be vertices of \
                 triangles, found node 20, which belongs to no triangle"
            )
        );
    }

    #[test]
    fn sections_are_checked_for_order_and_presence() {
        let text = square_text();
        let without_entities = {
            let start = text.find("$Entities").unwrap();
            let end = text.find("$Nodes").unwrap();
            format!("{}{}", &text[..start], &text[end..])
        };
        let message = error_message(parse_msh::<2>(&without_entities, "e.msh", &names_map()));
        assert!(
            message.starts_with("e.msh:11: expected an `$Entities` section before `$Nodes`"),
            "{message}"
        );
        let twice = format!("{text}$Nodes\n0 0 0 0\n$EndNodes\n");
        let message = error_message(parse_msh::<2>(&twice, "t.msh", &names_map()));
        assert!(message.contains("each at most once"), "{message}");
        let without_elements = &text[..text.find("$Elements").unwrap()];
        let message = error_message(parse_msh::<2>(without_elements, "n.msh", &names_map()));
        assert!(message.contains("found end of file"), "{message}");
        let partitioned = text.replace(
            "$Nodes\n",
            "$PartitionedEntities\n$EndPartitionedEntities\n$Nodes\n",
        );
        let message = error_message(parse_msh::<2>(&partitioned, "p.msh", &names_map()));
        assert!(
            message.contains("partitioned meshes are not supported"),
            "{message}"
        );
    }

    #[test]
    fn unknown_sections_and_blank_lines_are_skipped() {
        let text = square_text()
            .replace(
                "$Nodes\n",
                "$Comments\nanything $Nodes\n\n$EndComments\n\n$Nodes\n",
            )
            .replace("\r", "")
            .replace('\n', "\r\n");
        let text = format!("{text}$NodeData\n1\n\"u\"\n$EndNodeData\n");
        let mesh = parse_msh::<2>(&text, "c.msh", &names_map()).unwrap();
        assert_same_mesh(
            &mesh,
            &parse_msh::<2>(&square_text(), "s.msh", &names_map()).unwrap(),
        );
    }

    #[test]
    fn box_meshes_round_trip_through_msh_text() {
        let sides2 = [[Dirichlet, Neumann], [Contact, Neumann]];
        let square = Mesh::<2>::box_mesh([-1.0, 0.5], [2.0, 1.25], [3, 2], sides2).unwrap();
        let sides3 = [[Dirichlet, Neumann], [Neumann, Neumann], [Contact, Neumann]];
        let brick =
            Mesh::<3>::box_mesh([0.0, -1.0, 0.5], [2.0, 0.5, 1.5], [2, 1, 2], sides3).unwrap();
        for second_order in [false, true] {
            let text = msh_text(&square, second_order);
            assert_same_mesh(&parse_msh::<2>(&text, "s", &names_map()).unwrap(), &square);
            let text = msh_text(&brick, second_order);
            assert_same_mesh(&parse_msh::<3>(&text, "b", &names_map()).unwrap(), &brick);
        }
    }

    #[test]
    fn committed_cube_matches_box_mesh() {
        let sides = [[Dirichlet, Neumann], [Neumann, Neumann], [Contact, Neumann]];
        let cube = Mesh::<3>::box_mesh([0.0; 3], [1.0; 3], [1, 1, 1], sides).unwrap();
        let read = read_msh::<3>(&mesh_file("cube.msh"), &names_map()).unwrap();
        assert_same_mesh(&read, &cube);
    }

    /// Replacement fields for the mutation test: counts, tags, types, junk, section markers.
    const FIELDS: [&str; 24] = [
        "-1",
        "0",
        "1",
        "2",
        "3",
        "4",
        "9",
        "11",
        "15",
        "99",
        "18446744073709551616",
        "2147483648",
        "1e400",
        "nan",
        "inf",
        "-0",
        "0.5",
        "$EndNodes",
        "$Nodes",
        "$Elements",
        "\"x\"",
        "abc",
        "é",
        "",
    ];

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(128))]
        #[test]
        fn mutated_or_truncated_files_never_panic(
            cube in any::<bool>(),
            edits in prop::collection::vec(
                (0usize..4, any::<prop::sample::Index>(), any::<prop::sample::Index>(),
                 0usize..FIELDS.len()),
                1..4,
            ),
        ) {
            let text = if cube { read_to_string_cube() } else { square_text() };
            let mut lines: Vec<String> = text.lines().map(String::from).collect();
            for (kind, at, field, replacement) in edits {
                if lines.is_empty() {
                    break;
                }
                let i = at.index(lines.len());
                match kind {
                    0 => {
                        lines.remove(i);
                    }
                    1 => {
                        let copy = lines[i].clone();
                        lines.insert(i, copy);
                    }
                    2 => {
                        let mut fields: Vec<&str> = lines[i].split_whitespace().collect();
                        if !fields.is_empty() {
                            let k = field.index(fields.len());
                            fields[k] = FIELDS[replacement];
                        }
                        lines[i] = fields.join(" ");
                    }
                    _ => {
                        lines.truncate(i + 1);
                        let last = &lines[i];
                        let cut = last
                            .char_indices()
                            .nth(field.index(last.chars().count() + 1))
                            .map_or(last.len(), |(c, _)| c);
                        lines[i].truncate(cut);
                    }
                }
            }
            let text = lines.join("\n");
            let _ = parse_msh::<2>(&text, "mutated.msh", &names_map());
            let _ = parse_msh::<3>(&text, "mutated.msh", &names_map());
        }
    }
}
