//! Reader of Gmsh meshes in the MSH 4.1 format, ASCII or binary (what Gmsh writes with
//! `Mesh.MshFileVersion = 4.1;` and `Mesh.Binary = 0;` or `Mesh.Binary = 1;`), producing a
//! validated [`Mesh`] whose boundary facets are tagged with the parts Γ1, Γ2, Γ3 of the paper
//! (§2) through physical groups. Both encodings are read into the same records and give the
//! same mesh.
//!
//! What is read:
//! - `$MeshFormat`: version 4.1 is required, with file-type 0 (ASCII) or 1 (binary);
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
//! Other sections (`$Periodic`, `$NodeData`, `$Comments`, …) are skipped up to their `$End…`
//! line; partitioned meshes (`$PartitionedEntities`) are rejected. Sections must come in the
//! order Gmsh writes them: `$MeshFormat`, `$PhysicalNames`, `$Entities`, `$Nodes`,
//! `$Elements`; all but `$PhysicalNames` are required (Gmsh always writes them).
//!
//! Second-order elements (3-node lines, type 8; 6-node triangles, type 9; 10-node tetrahedra,
//! type 11) are accepted: their vertex nodes are the mesh vertices, and the edge nodes of the
//! cells are the points of the mesh's edges ([`Mesh::with_curved_edges`]; Gmsh's edge order of
//! the 10-node tetrahedron, (0,1), (1,2), (2,0), (3,0), (3,2), (3,1), is mapped to the edges it
//! names). An edge node off its straight midpoint makes its cells curved, mapped
//! isoparametrically by the P2 space ([`crate::fem::curved`]); the edge nodes of boundary
//! elements repeat those of the cells and are not read.
//!
//! Nothing is changed silently: Gmsh orients triangles and tetrahedra positively by
//! convention (in 2D: when the surface normal is +z), and an inverted cell is reported by
//! [`Mesh::new`], never reoriented. In 2D every node used by a cell must have z = 0.
//!
//! # ASCII files
//! Records are read line by line, as Gmsh writes them: each header, node tag, coordinate line,
//! entity and element is one line; blank lines are ignored. Every error is an
//! [`Error::InvalidMesh`] of the form `origin:line: expected …, found …` with the 1-based line
//! number.
//!
//! # Binary files
//! The header line `4.1 1 8` is followed by the 4-byte integer 1 in binary, which must read
//! as 1 in little-endian byte order (files written on big-endian machines are rejected), and
//! the data size must be 8 (the size of `size_t`). Section headers and footers and the content
//! of `$PhysicalNames` stay ASCII lines; the contents of `$Entities`, `$Nodes` and `$Elements`
//! are little-endian binary fields, `int` = 4-byte signed integer, `size_t` = 8-byte unsigned
//! integer, `double` = 8-byte IEEE float, laid out as in the ASCII format without separators:
//! - `$Entities`: four `size_t` counts (points, curves, surfaces, volumes); per point `int`
//!   tag, 3 `double` coordinates, `size_t` number of physical tags and that many `int`; per
//!   curve, surface or volume `int` tag, 6 `double` (bounding box), `size_t` number of
//!   physical tags and that many `int`, `size_t` number of bounding entities and that many
//!   `int`;
//! - `$Nodes`: four `size_t` (number of blocks, number of nodes, smallest and largest tag);
//!   per block `int` entity dimension, `int` entity tag, `int` parametric flag, `size_t`
//!   number of nodes, then all the node tags (`size_t`), then all the coordinates (3 `double`
//!   per node, plus the entity dimension's number of parametric coordinates if parametric);
//! - `$Elements`: four `size_t` (number of blocks, number of elements, smallest and largest
//!   tag); per block `int` entity dimension, `int` entity tag, `int` element type, `size_t`
//!   number of elements, then per element its tag and node tags (`size_t`).
//!
//! Skipping a block of elements needs the number of nodes of its element type: the Gmsh types
//! 1 to 31 (points; lines, triangles and tetrahedra up to order 5; quadrangles, hexahedra,
//! prisms and pyramids up to order 2) are known; a skipped block of another
//! type is an error in a binary file (an ASCII file skips it line by line). Errors are
//! [`Error::InvalidMesh`] of the form `origin: $Nodes at byte 1234: expected …, found …`,
//! naming the section and the 0-based byte offset, from the start of the file, of the field,
//! entity, node, block or element in question (`origin: at byte 1234: …` between sections).
//!
//! In both encodings, errors found by [`Mesh::new`] after reading name the origin and explain
//! how its vertex and cell indices relate to the file.

mod ascii;
mod binary;
mod mapping;
mod reader;
mod records;

use std::collections::HashMap;
use std::fmt;
use std::path::Path;

use crate::error::{Error, Result};
use crate::fem::mesh::{BoundaryPart, Mesh};

use ascii::{read_elements, read_entities, read_nodes};
use binary::{read_elements_binary, read_entities_binary, read_nodes_binary, Cursor};
use mapping::{boundary_entity_parts, build_mesh, resolve_map};
use reader::{fail, printable, shorten, Location, Reader, Record};
use records::{ElementBlocks, Elements, Entities, Node, PhysicalName};

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

/// Reads a Gmsh MSH 4.1 file, ASCII or binary, into a mesh of dimension D ∈ {2, 3}; see the
/// module documentation for what is read and [`parse_msh_bytes`] for the errors. An unreadable
/// file, or a path that is not a regular file (refused before it is opened), is an
/// [`Error::InvalidInput`] naming the path.
pub fn read_msh<const D: usize>(path: &Path, map: &PhysicalMap) -> Result<Mesh<D>> {
    // only a regular file: a named pipe would block, a device be read without end
    if let Ok(metadata) = std::fs::metadata(path) {
        if !metadata.is_file() {
            return Err(Error::InvalidInput(format!(
                "mesh `{}` is not a regular file (a directory, a named pipe or a device): only regular files are read",
                path.display()
            )));
        }
    }
    let bytes = std::fs::read(path)
        .map_err(|error| Error::InvalidInput(format!("cannot read {}: {error}", path.display())))?;
    parse_msh_bytes(&bytes, &path.display().to_string(), map)
}

/// Parses the text of a Gmsh MSH 4.1 ASCII file into a mesh of dimension D ∈ {2, 3}; `origin`
/// names the text in error messages (usually the file name). Same as [`parse_msh_bytes`] on
/// the bytes of `text`.
pub fn parse_msh<const D: usize>(text: &str, origin: &str, map: &PhysicalMap) -> Result<Mesh<D>> {
    parse_msh_bytes(text.as_bytes(), origin, map)
}

/// Parses the bytes of a Gmsh MSH 4.1 file, ASCII or binary, into a mesh of dimension
/// D ∈ {2, 3}; `origin` names the file in error messages (usually the file name). Bytes that
/// are not UTF-8 in a physical name are replaced by U+FFFD.
///
/// Errors ([`Error::InvalidMesh`], `origin:line: expected …, found …` in ASCII files,
/// `origin: $Section at byte offset: expected …, found …` in binary files): another format
/// version than 4.1; another file-type than 0 (ASCII) or 1 (binary); in a binary file, a
/// data size other than 8, a byte-order integer that is not 1 in little-endian order, or an
/// element type of unknown node count in a skipped block; a missing, duplicated, truncated or
/// misplaced section; a malformed record (wrong number of fields, a field that is not a
/// number, a count larger than the rest of the file, a non-finite coordinate); a duplicated
/// node or entity tag; an element that refers to a node missing from `$Nodes`; a block of
/// dimension greater than D; elements other than triangles/tetrahedra in a block of
/// dimension D, or other than lines/triangles in a mapped block of dimension D − 1; a boundary
/// element on a node of no cell; a group of the map that does not exist, has no entity of
/// dimension D − 1, or is mapped to two parts; an entity whose groups map to two parts; a 2D
/// node off the plane z = 0; no cell at all; and everything [`Mesh::new`] checks (inverted or
/// degenerate cells, untagged boundary facets, no Dirichlet facet, …).
/// D ∉ {2, 3} is an [`Error::InvalidInput`].
pub fn parse_msh_bytes<const D: usize>(
    bytes: &[u8],
    origin: &str,
    map: &PhysicalMap,
) -> Result<Mesh<D>> {
    if D != 2 && D != 3 {
        return Err(Error::InvalidInput(format!(
            "Gmsh meshes can be read in dimension 2 or 3, not {D}"
        )));
    }
    let mut reader = Reader::new(origin, bytes);
    read_mesh_format(&mut reader)?;

    // Known sections in the order Gmsh writes them, with their rank.
    const ORDER: [&str; 4] = ["PhysicalNames", "Entities", "Nodes", "Elements"];
    const SECTIONS: [&str; 4] = ["$PhysicalNames", "$Entities", "$Nodes", "$Elements"];
    let mut last_section: Option<(usize, Record)> = None;
    let mut physical_names: Option<(Location, Vec<PhysicalName>)> = None;
    let mut entities: Option<(Location, Entities)> = None;
    let mut nodes: Option<HashMap<u64, Node>> = None;
    let mut elements: Option<Elements> = None;

    while let Some(header) = reader.next_record() {
        let Some(name) = header.text.strip_prefix(b"$") else {
            return Err(header.fail("a section header `$Name`"));
        };
        if name == b"PartitionedEntities" {
            return Err(header.fail(
                "an unpartitioned mesh (partitioned meshes are not supported; save without \
                 partitioning)",
            ));
        }
        if name == b"MeshFormat" || name.starts_with(b"End") {
            return Err(header.fail("a section header other than `$MeshFormat` or `$End…`"));
        }
        let Some(rank) = ORDER.iter().position(|known| known.as_bytes() == name) else {
            skip_section(&mut reader, name)?;
            continue;
        };
        if let Some((last_rank, last)) = &last_section {
            if rank <= *last_rank {
                return Err(header.fail_with(
                    "the sections in the order `$MeshFormat`, `$PhysicalNames`, `$Entities`, \
                     `$Nodes`, `$Elements`, each at most once",
                    format!(
                        "{} after {} at {}",
                        header.quoted(),
                        last.quoted(),
                        last.location
                    ),
                ));
            }
        }
        reader.section = Some(SECTIONS[rank]);
        let header = reader.relocate(header);
        let binary = reader.binary;
        match rank {
            0 => physical_names = Some((header.location, read_physical_names(&mut reader)?)),
            1 => {
                let read = if binary {
                    read_entities_binary(&mut reader)?
                } else {
                    read_entities(&mut reader)?
                };
                entities = Some((header.location, read));
            }
            2 => {
                if entities.is_none() {
                    return Err(header.fail("an `$Entities` section before `$Nodes`"));
                }
                nodes = Some(if binary {
                    read_nodes_binary(&mut reader)?
                } else {
                    read_nodes(&mut reader)?
                });
            }
            _ => {
                let (Some((entities_location, entities)), Some(nodes)) = (&entities, &nodes) else {
                    return Err(header.fail("`$Entities` and `$Nodes` sections before `$Elements`"));
                };
                let group_parts = resolve_map(
                    map,
                    physical_names.as_ref(),
                    entities,
                    *entities_location,
                    D - 1,
                    &header,
                )?;
                let entity_parts = boundary_entity_parts(origin, entities, &group_parts, D - 1)?;
                let blocks = ElementBlocks {
                    section: header.location,
                    nodes,
                    entities,
                    entity_parts: &entity_parts,
                };
                elements = Some(if binary {
                    read_elements_binary::<D>(&mut reader, &blocks)?
                } else {
                    read_elements::<D>(&mut reader, &blocks)?
                });
            }
        }
        reader.section = None;
        last_section = Some((rank, header));
    }
    let (Some(nodes), Some(elements)) = (nodes, elements) else {
        return Err(fail(
            origin,
            reader.end_location(),
            "`$Nodes` and `$Elements` sections",
            "end of file",
        ));
    };
    build_mesh::<D>(origin, &nodes, elements)
}

/// `$MeshFormat` / `4.1 0 8` (ASCII) or `4.1 1 8` and the binary integer 1 (binary) /
/// `$EndMeshFormat`. Switches the reader to binary for file-type 1.
fn read_mesh_format(reader: &mut Reader) -> Result<()> {
    let first = reader.expect_record("`$MeshFormat`")?;
    if first.text != b"$MeshFormat" {
        // not quoted: the file may be anything (a mesh path that names another file), and
        // its first line is not for the message
        return Err(first.fail_with(
            "`$MeshFormat` (the first line of a Gmsh .msh file)",
            "a line that is not Gmsh: this is not a Gmsh mesh file",
        ));
    }
    const HEADER: &str = "the format header `version file-type data-size`";
    let header = reader.expect_record(HEADER)?;
    header.expect_fields(3, HEADER)?;
    let version = header.fields[0];
    let version_number = std::str::from_utf8(version)
        .ok()
        .and_then(|text| text.parse::<f64>().ok());
    if version_number != Some(4.1) {
        return Err(header.fail_with(
            "MSH format version 4.1 (save with `Mesh.MshFileVersion = 4.1;`)",
            format!("version `{}`", shorten(&printable(version))),
        ));
    }
    match header.fields[1] {
        b"0" => {
            header.parse::<usize>(2, "the data size (an integer)")?;
        }
        b"1" => {
            reader.binary = true;
            reader.section = Some("$MeshFormat");
            let header = reader.relocate(header);
            let data_size: usize = header.parse(2, "the data size (an integer)")?;
            if data_size != 8 {
                return Err(header.fail_with(
                    "data-size 8 in a binary file (8-byte `size_t`, as Gmsh writes on 64-bit \
                     machines)",
                    format!("data-size {data_size}"),
                ));
            }
            let mut cursor = Cursor { reader };
            let offset = cursor.offset();
            let marker: [u8; 4] = cursor.array("the byte-order integer 1")?;
            if i32::from_le_bytes(marker) != 1 {
                let found = if i32::from_be_bytes(marker) == 1 {
                    "1 in big-endian byte order (files written on big-endian machines are not \
                     supported)"
                        .to_string()
                } else {
                    format!("the bytes {marker:02x?}")
                };
                return Err(cursor.fail_at(
                    offset,
                    "the integer 1 in little-endian byte order after the header",
                    found,
                ));
            }
        }
        other => {
            return Err(header.fail_with(
                "file-type 0 (ASCII) or 1 (binary)",
                format!("file-type `{}`", shorten(&printable(other))),
            ))
        }
    }
    reader.expect_end("MeshFormat")?;
    reader.section = None;
    Ok(())
}

/// Skips an unknown section up to its `$End<name>` line (binary content included).
fn skip_section(reader: &mut Reader, name: &[u8]) -> Result<()> {
    let end = [b"$End", name].concat();
    while let Some((_, line)) = reader.next_line() {
        if line.trim_ascii() == end.as_slice() {
            return Ok(());
        }
    }
    Err(fail(
        reader.origin,
        reader.end_location(),
        format!("`{}`", shorten(&printable(&end))),
        "end of file",
    ))
}

/// `$PhysicalNames` (ASCII in both file-types): a count, then `dimension tag "name"` lines.
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
        if quoted.len() < 2 || !quoted.starts_with(b"\"") || !quoted.ends_with(b"\"") {
            return Err(record.fail(WHAT));
        }
        names.push(PhysicalName {
            dimension,
            tag,
            name: String::from_utf8_lossy(&quoted[1..quoted.len() - 1]).into_owned(),
        });
    }
    reader.expect_end("PhysicalNames")?;
    Ok(names)
}

/// The rest of `text` after its first `count` whitespace-separated fields, trimmed.
fn skip_fields(text: &[u8], count: usize) -> &[u8] {
    let mut rest = text;
    for _ in 0..count {
        rest = rest.trim_ascii_start();
        let end = rest
            .iter()
            .position(u8::is_ascii_whitespace)
            .unwrap_or(rest.len());
        rest = &rest[end..];
    }
    rest.trim_ascii()
}

#[cfg(test)]
mod tests;
