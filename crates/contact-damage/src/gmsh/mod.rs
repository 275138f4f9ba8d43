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
//! type 11) are accepted, but only their vertex nodes are used: the P2 space
//! ([`crate::space::LagrangeSpace`]) rebuilds its edge nodes as midpoints of straight edges, so
//! curved geometry is not represented.
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

/// Reads a Gmsh MSH 4.1 file, ASCII or binary, into a mesh of dimension D ∈ {2, 3}; see the
/// module documentation for what is read and [`parse_msh_bytes`] for the errors. An unreadable
/// file is an [`Error::InvalidInput`] naming the path.
pub fn read_msh<const D: usize>(path: &Path, map: &PhysicalMap) -> Result<Mesh<D>> {
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

/// Names of entities and of their dimensions in messages.
const ENTITY_KINDS: [&str; 4] = ["point", "curve", "surface", "volume"];

/// Where a record or a binary field lies in the file, for messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Location {
    /// 1-based line number, in an ASCII file.
    Line(usize),
    /// 0-based byte offset from the start of a binary file, in a known section or between
    /// sections (None).
    Byte {
        section: Option<&'static str>,
        offset: usize,
    },
}

impl Location {
    /// The start of a message: `origin:line`, `origin: $Section at byte offset` or
    /// `origin: at byte offset`.
    fn prefix(self, origin: &str) -> String {
        match self {
            Location::Line(line) => format!("{origin}:{line}"),
            Location::Byte {
                section: Some(section),
                offset,
            } => format!("{origin}: {section} at byte {offset}"),
            Location::Byte {
                section: None,
                offset,
            } => format!("{origin}: at byte {offset}"),
        }
    }
}

impl fmt::Display for Location {
    /// `line 12` or `byte 1234`, for references to an earlier record.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(line) => write!(f, "line {line}"),
            Location::Byte { offset, .. } => write!(f, "byte {offset}"),
        }
    }
}

/// One physical name: `dimension tag "name"`.
struct PhysicalName {
    dimension: usize,
    tag: i32,
    name: String,
}

/// A geometric entity with its physical tags.
struct Entity {
    physical_tags: Vec<i32>,
    location: Location,
}

/// Entities by dimension (0 to 3) and tag.
type Entities = [BTreeMap<i32, Entity>; 4];

/// A node with the location of its coordinates.
struct Node {
    coordinates: [f64; 3],
    location: Location,
}

/// The cells and tagged boundary facets of `$Elements`, by node tag, in file order.
struct Elements {
    /// The `$Elements` header.
    section: Location,
    /// Vertex node tags of the cells, stride D + 1.
    cell_nodes: Vec<u64>,
    /// Vertex node tags of the boundary facets, stride D.
    facet_nodes: Vec<u64>,
    facet_parts: Vec<BoundaryPart>,
    facet_locations: Vec<Location>,
    facet_elements: Vec<u64>,
}

/// What the element blocks of `$Elements` are read against: the `$Elements` header, the nodes,
/// the entities, and the boundary part of each mapped entity of dimension D − 1.
struct ElementBlocks<'s> {
    section: Location,
    nodes: &'s HashMap<u64, Node>,
    entities: &'s Entities,
    entity_parts: &'s BTreeMap<i32, BoundaryPart>,
}

/// A non-blank line split into whitespace-separated fields (as bytes: only physical names
/// may hold text that is not ASCII).
struct Record<'a> {
    origin: &'a str,
    location: Location,
    /// Byte offset of the start of the line.
    offset: usize,
    text: &'a [u8],
    fields: Vec<&'a [u8]>,
}

impl Record<'_> {
    /// The line, quoted and shortened for messages.
    fn quoted(&self) -> String {
        format!("`{}`", shorten(&printable(self.text)))
    }

    /// Error at this line: expected …, found this line.
    fn fail(&self, expected: impl fmt::Display) -> Error {
        fail(self.origin, self.location, expected, self.quoted())
    }

    /// Error at this line with a custom "found" part.
    fn fail_with(&self, expected: impl fmt::Display, found: impl fmt::Display) -> Error {
        fail(self.origin, self.location, expected, found)
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
        let value = std::str::from_utf8(field)
            .ok()
            .and_then(|text| text.parse().ok());
        value.ok_or_else(|| {
            self.fail_with(
                format!("{what} as field {}", index + 1),
                format!("`{}` in {}", shorten(&printable(field)), self.quoted()),
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

/// Reader of the lines of an ASCII or binary file, and of the binary sections through a
/// [`Cursor`]. Keeps the byte offset of the next unread byte and the 1-based number of the
/// last line read (meaningful in ASCII files only).
struct Reader<'a> {
    origin: &'a str,
    bytes: &'a [u8],
    position: usize,
    line: usize,
    /// File-type 1: records are located by byte offset, and sections are read by a cursor.
    binary: bool,
    /// The known section being read, for locations in binary files.
    section: Option<&'static str>,
}

impl<'a> Reader<'a> {
    fn new(origin: &'a str, bytes: &'a [u8]) -> Self {
        Reader {
            origin,
            bytes,
            position: 0,
            line: 0,
            binary: false,
            section: None,
        }
    }

    /// The location of the line starting at byte `offset`: that offset in a binary file, the
    /// last line read in an ASCII file.
    fn location(&self, offset: usize) -> Location {
        if self.binary {
            Location::Byte {
                section: self.section,
                offset,
            }
        } else {
            Location::Line(self.line)
        }
    }

    /// The location of the end of the file.
    fn end_location(&self) -> Location {
        if self.binary {
            Location::Byte {
                section: self.section,
                offset: self.bytes.len(),
            }
        } else {
            Location::Line(self.line + 1)
        }
    }

    /// The record, located again after a change of section or of file-type.
    fn relocate(&self, record: Record<'a>) -> Record<'a> {
        if self.binary {
            Record {
                location: self.location(record.offset),
                ..record
            }
        } else {
            record
        }
    }

    /// The next line (without its `\n`) and the offset of its start, or None at the end.
    fn next_line(&mut self) -> Option<(usize, &'a [u8])> {
        let start = self.position;
        let rest = self.bytes.get(start..).filter(|rest| !rest.is_empty())?;
        let (line, consumed) = match rest.iter().position(|&byte| byte == b'\n') {
            Some(end) => (&rest[..end], end + 1),
            None => (rest, rest.len()),
        };
        self.position += consumed;
        self.line += 1;
        Some((start, line))
    }

    /// The next non-blank line, or None at the end of the file.
    fn next_record(&mut self) -> Option<Record<'a>> {
        while let Some((offset, line)) = self.next_line() {
            let text = line.trim_ascii();
            if !text.is_empty() {
                return Some(Record {
                    origin: self.origin,
                    location: self.location(offset),
                    offset,
                    text,
                    fields: text
                        .split(u8::is_ascii_whitespace)
                        .filter(|field| !field.is_empty())
                        .collect(),
                });
            }
        }
        None
    }

    /// The next non-blank line; at the end of the file an error expecting `expected`.
    fn expect_record(&mut self, expected: impl fmt::Display) -> Result<Record<'a>> {
        match self.next_record() {
            Some(record) => Ok(record),
            None => Err(fail(
                self.origin,
                self.end_location(),
                expected,
                "end of file",
            )),
        }
    }

    /// Requires the line `$End<section>` (after the `\n` that ends a binary section).
    fn expect_end(&mut self, section: &str) -> Result<()> {
        let end = format!("$End{section}");
        let record = self.expect_record(format!("`{end}`"))?;
        if record.text == end.as_bytes() {
            Ok(())
        } else {
            Err(record.fail(format!("`{end}`")))
        }
    }
}

/// Reads the little-endian binary fields of a section of a binary file from the reader's
/// position, which it advances. Errors name the section and the byte offset.
struct Cursor<'r, 'a> {
    reader: &'r mut Reader<'a>,
}

/// Bytes of a node or element block header: three `int` and one `size_t`.
const BLOCK_HEADER_BYTES: usize = 3 * 4 + 8;

impl<'a> Cursor<'_, 'a> {
    /// Byte offset of the next field.
    fn offset(&self) -> usize {
        self.reader.position
    }

    /// Number of bytes left in the file.
    fn remaining(&self) -> usize {
        self.reader.bytes.len() - self.reader.position
    }

    /// The location of byte `offset` in the current section.
    fn location(&self, offset: usize) -> Location {
        self.reader.location(offset)
    }

    /// Error at byte `offset`: expected …, found ….
    fn fail_at(
        &self,
        offset: usize,
        expected: impl fmt::Display,
        found: impl fmt::Display,
    ) -> Error {
        fail(self.reader.origin, self.location(offset), expected, found)
    }

    /// The next `count` bytes, `what` describing them.
    fn take(&mut self, count: usize, what: impl fmt::Display) -> Result<&'a [u8]> {
        let start = self.reader.position;
        if count > self.remaining() {
            return Err(self.fail_at(
                start,
                format!("{what} ({count} bytes)"),
                format!("the end of the file after {} bytes", self.remaining()),
            ));
        }
        self.reader.position += count;
        Ok(&self.reader.bytes[start..start + count])
    }

    /// The next `N` bytes.
    fn array<const N: usize>(&mut self, what: impl fmt::Display) -> Result<[u8; N]> {
        let mut array = [0; N];
        array.copy_from_slice(self.take(N, what)?);
        Ok(array)
    }

    /// An `int` (4-byte signed integer).
    fn int(&mut self, what: impl fmt::Display) -> Result<i32> {
        Ok(i32::from_le_bytes(self.array(what)?))
    }

    /// A `size_t` (8-byte unsigned integer).
    fn size(&mut self, what: impl fmt::Display) -> Result<u64> {
        Ok(u64::from_le_bytes(self.array(what)?))
    }

    /// A `size_t` counting items of at least `item_bytes` bytes each, which must fit in the
    /// rest of the file (so that a corrupted count fails here, before any allocation).
    fn count(&mut self, what: &str, item_bytes: usize) -> Result<usize> {
        let offset = self.offset();
        let count = self.size(what)?;
        let remaining = self.remaining();
        usize::try_from(count)
            .ok()
            .filter(|&count| {
                count
                    .checked_mul(item_bytes)
                    .is_some_and(|bytes| bytes <= remaining)
            })
            .ok_or_else(|| {
                self.fail_at(
                    offset,
                    format!(
                        "{what}, at most {} ({remaining} bytes left in the file, at least \
                         {item_bytes} per item)",
                        remaining / item_bytes.max(1)
                    ),
                    count,
                )
            })
    }

    /// An entity dimension: an `int` from 0 to 3.
    fn dimension(&mut self) -> Result<usize> {
        let offset = self.offset();
        let dimension = self.int("the entity dimension")?;
        usize::try_from(dimension)
            .ok()
            .filter(|&dimension| dimension <= 3)
            .ok_or_else(|| self.fail_at(offset, "the entity dimension (0 to 3)", dimension))
    }
}

/// `origin:line: expected …, found …` (or `origin: $Section at byte offset: …`).
fn fail(
    origin: &str,
    location: Location,
    expected: impl fmt::Display,
    found: impl fmt::Display,
) -> Error {
    Error::InvalidMesh(format!(
        "{}: expected {expected}, found {found}",
        location.prefix(origin)
    ))
}

/// `bytes` as text for messages: invalid UTF-8 replaced by U+FFFD, control characters (as
/// found in binary data) escaped.
fn printable(bytes: &[u8]) -> String {
    let mut text = String::new();
    for character in String::from_utf8_lossy(bytes).chars() {
        if character.is_control() {
            text.extend(character.escape_default());
        } else {
            text.push(character);
        }
    }
    text
}

/// At most 80 characters of `text` (cut at a character boundary).
fn shorten(text: &str) -> String {
    match text.char_indices().nth(77) {
        Some((cut, _)) if text.chars().count() > 80 => format!("{}…", &text[..cut]),
        _ => text.to_string(),
    }
}

/// `$MeshFormat` / `4.1 0 8` (ASCII) or `4.1 1 8` and the binary integer 1 (binary) /
/// `$EndMeshFormat`. Switches the reader to binary for file-type 1.
fn read_mesh_format(reader: &mut Reader) -> Result<()> {
    let first = reader.expect_record("`$MeshFormat`")?;
    if first.text != b"$MeshFormat" {
        return Err(first.fail("`$MeshFormat` (the first line of a Gmsh .msh file)"));
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

/// Adds an entity of `$Entities`; a tag seen before in the same dimension is an error.
fn insert_entity(
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

/// `$Entities` (ASCII): counts of points, curves, surfaces, volumes, then one line per entity:
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
                location: record.location,
            };
            insert_entity(reader.origin, &mut entities, dimension, tag, entity)?;
        }
    }
    reader.expect_end("Entities")?;
    Ok(entities)
}

/// `$Entities` (binary): four `size_t` counts, then per point `int` tag, 3 `double`, `size_t`
/// numPhysicalTags, that many `int`; per curve, surface or volume `int` tag, 6 `double`,
/// `size_t` numPhysicalTags, that many `int`, `size_t` numBounding, that many `int`.
fn read_entities_binary(reader: &mut Reader) -> Result<Entities> {
    let origin = reader.origin;
    let mut cursor = Cursor { reader };
    // The smallest entity, a point without physical tags: int, 3 double, size_t.
    const SMALLEST_ENTITY_BYTES: usize = 4 + 3 * 8 + 8;
    let mut counts = [0usize; 4];
    for (dimension, count) in counts.iter_mut().enumerate() {
        let what = format!("the number of {}s", ENTITY_KINDS[dimension]);
        *count = cursor.count(&what, SMALLEST_ENTITY_BYTES)?;
    }
    let mut entities: Entities = Default::default();
    for (dimension, &count) in counts.iter().enumerate() {
        let kind = ENTITY_KINDS[dimension];
        for _ in 0..count {
            let offset = cursor.offset();
            let tag = cursor.int(format_args!("the {kind} tag"))?;
            let box_coordinates = if dimension == 0 { 3 } else { 6 };
            cursor.take(
                8 * box_coordinates,
                format_args!("the {box_coordinates} coordinates of the {kind}'s position or box"),
            )?;
            let physical_count = cursor.count("the number of physical tags", 4)?;
            let physical_tags = (0..physical_count)
                .map(|_| cursor.int("a physical tag"))
                .collect::<Result<Vec<i32>>>()?;
            if dimension > 0 {
                let bounding = cursor.count("the number of bounding entities", 4)?;
                cursor.take(4 * bounding, "the bounding entity tags")?;
            }
            let entity = Entity {
                physical_tags,
                location: cursor.location(offset),
            };
            insert_entity(origin, &mut entities, dimension, tag, entity)?;
        }
    }
    reader.expect_end("Entities")?;
    Ok(entities)
}

/// Adds a node of `$Nodes`; a tag seen before is an error.
fn insert_node(origin: &str, nodes: &mut HashMap<u64, Node>, tag: u64, node: Node) -> Result<()> {
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

/// `$Nodes` (ASCII): `numEntityBlocks numNodes minNodeTag maxNodeTag`, then blocks
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
            b"0" => false,
            b"1" => true,
            _ => return Err(block.fail("the parametric flag 0 or 1 as field 3")),
        };
        let count: usize = block.parse(3, "the number of nodes in the block")?;
        let mut tags = Vec::new();
        for k in 0..count {
            let what = format!(
                "the tag of node {} of {count} of the block at {}",
                k + 1,
                block.location
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
                location: record.location,
            };
            insert_node(reader.origin, &mut nodes, tag, node)?;
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

/// `$Nodes` (binary): four `size_t` (numEntityBlocks numNodes minNodeTag maxNodeTag), then
/// blocks of `int` entityDim, `int` entityTag, `int` parametric, `size_t` numNodesInBlock,
/// the block's node tags (`size_t`), and their coordinates (3 `double`, followed by
/// `entityDim` parametric coordinates if parametric).
fn read_nodes_binary(reader: &mut Reader) -> Result<HashMap<u64, Node>> {
    let origin = reader.origin;
    let mut cursor = Cursor { reader };
    let header = cursor.offset();
    let blocks = cursor.count("the number of entity blocks", BLOCK_HEADER_BYTES)?;
    let total = cursor.size("the number of nodes")?;
    cursor.size("the smallest node tag")?;
    cursor.size("the largest node tag")?;
    let mut nodes: HashMap<u64, Node> = HashMap::new();
    let mut read = 0u64;
    for _ in 0..blocks {
        let block = cursor.offset();
        let dimension = cursor.dimension()?;
        cursor.int("the entity tag")?;
        let flag = cursor.offset();
        let parametric = match cursor.int("the parametric flag")? {
            0 => false,
            1 => true,
            other => return Err(cursor.fail_at(flag, "the parametric flag 0 or 1", other)),
        };
        let values = 3 + if parametric { dimension } else { 0 };
        let count = cursor.count("the number of nodes in the block", 8 + 8 * values)?;
        let mut tags = Vec::with_capacity(count);
        for k in 0..count {
            tags.push(cursor.size(format_args!(
                "the tag of node {} of {count} of the block at byte {block}",
                k + 1
            ))?);
        }
        for tag in tags {
            let offset = cursor.offset();
            let bytes = cursor.take(
                8 * values,
                format_args!("the coordinates `x y z` of node {tag}"),
            )?;
            let mut coordinates = [0.0; 3];
            for (k, coordinate) in coordinates.iter_mut().enumerate() {
                let mut value = [0; 8];
                value.copy_from_slice(&bytes[8 * k..8 * k + 8]);
                *coordinate = f64::from_le_bytes(value);
                if !coordinate.is_finite() {
                    return Err(cursor.fail_at(
                        offset + 8 * k,
                        format!("coordinate {k} of node {tag} (finite)"),
                        *coordinate,
                    ));
                }
            }
            let node = Node {
                coordinates,
                location: cursor.location(offset),
            };
            insert_node(origin, &mut nodes, tag, node)?;
        }
        read += count as u64;
    }
    if read != total {
        return Err(cursor.fail_at(
            header,
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
/// (the `$Elements` header), for errors without a better location.
fn resolve_map(
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
                            *names_location,
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
                        entities_location,
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
                            entities_location,
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
                        entity.location,
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

/// Number of nodes of the Gmsh element types 1 to 31 (index: type − 1), as given by
/// `gmsh.model.mesh.getElementProperties`; needed to skip element blocks of binary files.
const NODES_PER_ELEMENT: [usize; 31] = [
    2, 3, 4, 4, 8, 6, 5, 3, 6, 9, 10, 27, 18, 14, 1, 8, 20, 15, 13, 9, 10, 12, 15, 15, 21, 4, 5, 6,
    20, 35, 56,
];

/// Number of nodes of a Gmsh element type, if known.
fn nodes_per_element(element_type: i32) -> Option<usize> {
    let index = usize::try_from(element_type).ok()?.checked_sub(1)?;
    NODES_PER_ELEMENT.get(index).copied()
}

/// What is done with the elements of one block.
#[derive(Clone, Copy)]
enum BlockRole {
    Skip,
    Cells { nodes: usize },
    Facets { nodes: usize, part: BoundaryPart },
}

/// The role of an element block of dimension `dimension` on entity `entity` with elements of
/// type `element_type`: cells for dimension D, facets for a mapped entity of dimension D − 1,
/// skipped otherwise. Blocks of dimension greater than D, cells that are not triangles
/// (tetrahedra) and mapped facets that are not lines (triangles) are errors at `location`.
fn block_role<const D: usize>(
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
                part_label(part)
            ),
            element_type_name(element_type),
        )),
    }
}

/// Adds element `tag` with nodes `node_tags` of a block of role `role` (cells or facets;
/// skipped blocks add nothing) to `elements`; a node missing from `$Nodes` is an error at
/// `location`.
fn push_element<const D: usize>(
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
        None => elements
            .cell_nodes
            .extend_from_slice(&node_tags[..vertices]),
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

impl Elements {
    /// No elements yet, for the `$Elements` section at `section`.
    fn new(section: Location) -> Self {
        Elements {
            section,
            cell_nodes: Vec::new(),
            facet_nodes: Vec::new(),
            facet_parts: Vec::new(),
            facet_locations: Vec::new(),
            facet_elements: Vec::new(),
        }
    }
}

/// `$Elements` (ASCII): `numEntityBlocks numElements minElementTag maxElementTag`, then blocks
/// `entityDim entityTag elementType numElementsInBlock` followed by one line
/// `elementTag nodeTag…` per element.
fn read_elements<const D: usize>(reader: &mut Reader, blocks: &ElementBlocks) -> Result<Elements> {
    const HEADER: &str =
        "the element header `numEntityBlocks numElements minElementTag maxElementTag`";
    let header = reader.expect_record(HEADER)?;
    header.expect_fields(4, HEADER)?;
    let block_count: usize = header.parse(0, "the number of entity blocks")?;
    let total: usize = header.parse(1, "the number of elements")?;
    header.parse::<u64>(2, "the smallest element tag")?;
    header.parse::<u64>(3, "the largest element tag")?;
    let mut elements = Elements::new(blocks.section);
    let mut node_tags = Vec::new();
    let mut read = 0usize;
    for _ in 0..block_count {
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
        let role = block_role::<D>(
            reader.origin,
            block.location,
            dimension,
            entity,
            element_type,
            blocks,
        )?;
        for k in 0..count {
            let what = format!(
                "element {} of {count} of the block at {}",
                k + 1,
                block.location
            );
            let record = reader.expect_record(&what)?;
            let element_nodes = match role {
                BlockRole::Skip => {
                    if record.text.starts_with(b"$") {
                        return Err(record.fail(what));
                    }
                    continue;
                }
                BlockRole::Cells { nodes } | BlockRole::Facets { nodes, .. } => nodes,
            };
            record.expect_fields(
                1 + element_nodes,
                &format!("an element tag and {element_nodes} node tags"),
            )?;
            let tag: u64 = record.parse(0, "the element tag")?;
            node_tags.clear();
            for index in 0..element_nodes {
                node_tags.push(record.parse::<u64>(1 + index, "a node tag")?);
            }
            push_element::<D>(
                reader.origin,
                record.location,
                &mut elements,
                role,
                tag,
                &node_tags,
                blocks.nodes,
            )?;
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

/// `$Elements` (binary): four `size_t` (numEntityBlocks numElements minElementTag
/// maxElementTag), then blocks of `int` entityDim, `int` entityTag, `int` elementType,
/// `size_t` numElementsInBlock, followed per element by its tag and node tags (`size_t`).
fn read_elements_binary<const D: usize>(
    reader: &mut Reader,
    blocks: &ElementBlocks,
) -> Result<Elements> {
    let origin = reader.origin;
    let mut cursor = Cursor { reader };
    let header = cursor.offset();
    let block_count = cursor.count("the number of entity blocks", BLOCK_HEADER_BYTES)?;
    let total = cursor.size("the number of elements")?;
    cursor.size("the smallest element tag")?;
    cursor.size("the largest element tag")?;
    let mut elements = Elements::new(blocks.section);
    let mut node_tags = Vec::new();
    let mut read = 0u64;
    for _ in 0..block_count {
        let block = cursor.offset();
        let dimension = cursor.dimension()?;
        let entity = cursor.int("the entity tag")?;
        let element_type = cursor.int("the element type")?;
        let location = cursor.location(block);
        let role = block_role::<D>(origin, location, dimension, entity, element_type, blocks)?;
        let element_nodes = match role {
            BlockRole::Skip => nodes_per_element(element_type).ok_or_else(|| {
                cursor.fail_at(
                    block,
                    "a block of element types 1 to 31 (whose number of nodes is known, to skip \
                     the block)",
                    element_type_name(element_type),
                )
            })?,
            BlockRole::Cells { nodes } | BlockRole::Facets { nodes, .. } => nodes,
        };
        let element_bytes = 8 * (1 + element_nodes);
        let count = cursor.count("the number of elements in the block", element_bytes)?;
        if let BlockRole::Skip = role {
            cursor.take(
                count * element_bytes,
                format_args!("the {count} elements of the block at byte {block}"),
            )?;
        } else {
            for k in 0..count {
                let offset = cursor.offset();
                let tag = cursor.size(format_args!(
                    "element {} of {count} of the block at byte {block}",
                    k + 1
                ))?;
                node_tags.clear();
                for _ in 0..element_nodes {
                    node_tags.push(cursor.size(format_args!("a node tag of element {tag}"))?);
                }
                let location = cursor.location(offset);
                push_element::<D>(
                    origin,
                    location,
                    &mut elements,
                    role,
                    tag,
                    &node_tags,
                    blocks.nodes,
                )?;
            }
        }
        read += count as u64;
    }
    if read != total {
        return Err(cursor.fail_at(
            header,
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
        if D == 2 && node.coordinates[2] != 0.0 {
            return Err(fail(
                origin,
                node.location,
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

    /// The Gmsh-written meshes of `tests/meshes/make_binary_meshes.py`: (name, dimension).
    const GMSH_MESHES: [(&str, usize); 3] =
        [("unit_square", 2), ("unit_square_p2", 2), ("unit_cube", 3)];

    fn gmsh_bytes(name: &str, encoding: &str) -> Vec<u8> {
        std::fs::read(mesh_file(&format!("{name}_{encoding}.msh"))).unwrap()
    }

    /// Every assignment of the groups "clamped" (1), "contact" (2), "traction" (3) to Γ1, Γ2,
    /// Γ3, by name and by tag.
    fn all_group_maps() -> Vec<PhysicalMap> {
        let groups = [("clamped", 1), ("contact", 2), ("traction", 3)];
        let orders = [
            [0, 1, 2],
            [0, 2, 1],
            [1, 0, 2],
            [1, 2, 0],
            [2, 0, 1],
            [2, 1, 0],
        ];
        let mut maps = Vec::new();
        for order in orders {
            let [dirichlet, neumann, contact] = order.map(|k| groups[k]);
            maps.push(PhysicalMap::by_names(
                &[dirichlet.0],
                &[neumann.0],
                &[contact.0],
            ));
            maps.push(PhysicalMap {
                dirichlet: vec![GroupRef::Tag(dirichlet.1)],
                neumann: vec![GroupRef::Tag(neumann.1)],
                contact: vec![GroupRef::Tag(contact.1)],
            });
        }
        maps
    }

    /// Same vertices bit for bit, same cells, same facets with the same parts.
    fn assert_bitwise_same_mesh<const D: usize>(read: &Mesh<D>, expected: &Mesh<D>) {
        let bits = |m: &Mesh<D>| {
            m.vertices()
                .iter()
                .map(|x| x.map(f64::to_bits))
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(read), bits(expected));
        assert_same_mesh(read, expected);
    }

    fn read_both<const D: usize>(
        name: &str,
        map: &PhysicalMap,
    ) -> (Result<Mesh<D>>, Result<Mesh<D>>) {
        let ascii = parse_msh_bytes::<D>(&gmsh_bytes(name, "ascii"), "m.msh", map);
        let binary = parse_msh_bytes::<D>(&gmsh_bytes(name, "binary"), "m.msh", map);
        (ascii, binary)
    }

    fn assert_binary_equals_ascii<const D: usize>(name: &str) {
        for map in all_group_maps() {
            let (ascii, binary) = read_both::<D>(name, &map);
            assert_bitwise_same_mesh(&binary.unwrap(), &ascii.unwrap());
        }
        // A group left unmapped: the same error from both.
        let map = PhysicalMap::by_names(&["clamped"], &[], &["contact"]);
        let (ascii, binary) = read_both::<D>(name, &map);
        let message = error_message(binary);
        assert!(message.contains("carries no boundary part"), "{message}");
        assert_eq!(message, error_message(ascii));
    }

    #[test]
    fn binary_and_ascii_gmsh_files_give_identical_meshes() {
        for (name, dimension) in GMSH_MESHES {
            match dimension {
                2 => assert_binary_equals_ascii::<2>(name),
                _ => assert_binary_equals_ascii::<3>(name),
            }
        }
    }

    /// Measures of the whole mesh and of Γ1, Γ2, Γ3.
    fn measures<const D: usize>(mesh: &Mesh<D>) -> [f64; 4] {
        let mut measures = [0.0; 4];
        measures[0] = (0..mesh.num_cells()).map(|c| mesh.cell_volume(c)).sum();
        for f in 0..mesh.num_facets() {
            let k = match mesh.facet_part(f) {
                Dirichlet => 1,
                Neumann => 2,
                Contact => 3,
            };
            measures[k] += mesh.facet_measure(f);
        }
        measures
    }

    #[test]
    fn binary_gmsh_meshes_carry_the_named_groups() {
        // The script rounds coordinates to 12 significant digits: measures hold to ~1e-12.
        let close = |a: [f64; 4], b: [f64; 4]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-10);
        for name in ["unit_square", "unit_square_p2"] {
            let bytes = gmsh_bytes(name, "binary");
            let mesh = parse_msh_bytes::<2>(&bytes, name, &names_map()).unwrap();
            assert!(mesh.num_cells() >= 8, "{name}: {} cells", mesh.num_cells());
            let found = measures(&mesh);
            assert!(close(found, [1.0, 1.0, 2.0, 1.0]), "{name}: {found:?}");
        }
        let bytes = gmsh_bytes("unit_cube", "binary");
        let mesh = parse_msh_bytes::<3>(&bytes, "unit_cube", &names_map()).unwrap();
        assert!(mesh.num_cells() >= 24, "{} cells", mesh.num_cells());
        let found = measures(&mesh);
        assert!(close(found, [1.0, 1.0, 4.0, 1.0]), "{found:?}");
        // read_msh reads binary files too.
        let read = read_msh::<3>(&mesh_file("unit_cube_binary.msh"), &names_map()).unwrap();
        assert_bitwise_same_mesh(&read, &mesh);
    }

    /// Byte offset of the first occurrence of `pattern` in `bytes`.
    fn find(bytes: &[u8], pattern: &[u8]) -> usize {
        bytes
            .windows(pattern.len())
            .position(|window| window == pattern)
            .unwrap()
    }

    #[test]
    fn unknown_sections_of_binary_files_are_skipped() {
        let bytes = gmsh_bytes("unit_square", "binary");
        let nodes = find(&bytes, b"$Nodes\n");
        let mut edited = bytes[..nodes].to_vec();
        edited.extend_from_slice(b"$Comments\n\x00\x01\n\xff$Nodes\n\x0a\x00\n$EndComments\n");
        edited.extend_from_slice(&bytes[nodes..]);
        edited.extend_from_slice(b"$NodeData\n1\n\"u\"\n\x00\x00\x80\x3f\n$EndNodeData\n");
        let expected = parse_msh_bytes::<2>(&bytes, "s.msh", &names_map()).unwrap();
        let read = parse_msh_bytes::<2>(&edited, "s.msh", &names_map()).unwrap();
        assert_bitwise_same_mesh(&read, &expected);
    }

    /// The byte offset in a message `origin: $Section at byte offset: …`.
    fn error_offset(message: &str, origin: &str, section: &str) -> usize {
        let prefix = format!("{origin}: {section} at byte ");
        let rest = message
            .strip_prefix(&prefix)
            .unwrap_or_else(|| panic!("expected `{prefix}…`, found {message}"));
        rest[..rest.find(':').unwrap()].parse().unwrap()
    }

    #[test]
    fn truncated_binary_files_are_rejected_with_section_and_offset() {
        for (name, dimension) in GMSH_MESHES {
            let bytes = gmsh_bytes(name, "binary");
            let marker = find(&bytes, b"4.1 1 8\n") + 8;
            let entities = find(&bytes, b"$Entities\n") + 10;
            let nodes = find(&bytes, b"$Nodes\n") + 7;
            let end_nodes = find(&bytes, b"\n$EndNodes\n");
            let elements = find(&bytes, b"$Elements\n") + 10;
            let end_elements = find(&bytes, b"\n$EndElements\n");
            let cuts = [
                (marker + 2, "$MeshFormat", marker),
                (entities + 20, "$Entities", entities),
                (nodes + 5, "$Nodes", nodes),
                ((nodes + end_nodes) / 2, "$Nodes", nodes),
                (end_nodes - 3, "$Nodes", nodes),
                (elements + 40, "$Elements", elements),
                ((elements + end_elements) / 2, "$Elements", elements),
                (end_elements - 1, "$Elements", elements),
                // The binary data is complete, `$EndElements` is missing.
                (end_elements + 1, "$Elements", elements),
            ];
            for (cut, section, start) in cuts {
                let result = match dimension {
                    2 => parse_msh_bytes::<2>(&bytes[..cut], "cut.msh", &names_map()).map(|_| ()),
                    _ => parse_msh_bytes::<3>(&bytes[..cut], "cut.msh", &names_map()).map(|_| ()),
                };
                let message = error_message(result);
                let offset = error_offset(&message, "cut.msh", section);
                assert!(
                    start <= offset && offset <= cut,
                    "{name} cut at {cut}: {message}"
                );
                assert!(
                    message.contains("found the end of the file after")
                        || message.contains("bytes left in the file")
                        || message.ends_with("found end of file"),
                    "{name} cut at {cut}: {message}"
                );
            }
        }
    }

    #[test]
    fn truncation_messages_say_what_was_expected_where() {
        let bytes = gmsh_bytes("unit_square", "binary");
        let message = error_message(parse_msh_bytes::<2>(&bytes[..22], "cut.msh", &names_map()));
        assert_eq!(
            message,
            "cut.msh: $MeshFormat at byte 20: expected the byte-order integer 1 (4 bytes), \
             found the end of the file after 2 bytes"
        );
        let entities = find(&bytes, b"$Entities\n") + 10;
        let cut = &bytes[..entities + 20];
        let message = error_message(parse_msh_bytes::<2>(cut, "cut.msh", &names_map()));
        assert_eq!(
            message,
            format!(
                "cut.msh: $Entities at byte {entities}: expected the number of points, at most 0 \
                 (12 bytes left in the file, at least 36 per item), found 4"
            )
        );
    }

    #[test]
    fn big_endian_files_and_other_data_sizes_are_rejected() {
        let bytes = gmsh_bytes("unit_square", "binary");
        let marker = find(&bytes, b"4.1 1 8\n") + 8;
        assert_eq!(marker, 20);
        let mut big_endian = bytes.clone();
        big_endian[marker..marker + 4].copy_from_slice(&1i32.to_be_bytes());
        let message = error_message(parse_msh_bytes::<2>(&big_endian, "be.msh", &names_map()));
        assert_eq!(
            message,
            "be.msh: $MeshFormat at byte 20: expected the integer 1 in little-endian byte order \
             after the header, found 1 in big-endian byte order (files written on big-endian \
             machines are not supported)"
        );
        big_endian[marker..marker + 4].copy_from_slice(&[7, 0, 0, 0]);
        let message = error_message(parse_msh_bytes::<2>(&big_endian, "be.msh", &names_map()));
        assert!(
            message.ends_with("found the bytes [07, 00, 00, 00]"),
            "{message}"
        );

        let mut data_size_4 = bytes.clone();
        data_size_4[18] = b'4';
        assert_eq!(&data_size_4[12..19], b"4.1 1 4");
        let message = error_message(parse_msh_bytes::<2>(&data_size_4, "ds.msh", &names_map()));
        assert_eq!(
            message,
            "ds.msh: $MeshFormat at byte 12: expected data-size 8 in a binary file (8-byte \
             `size_t`, as Gmsh writes on 64-bit machines), found data-size 4"
        );
        let mut file_type_2 = bytes;
        file_type_2[16] = b'2';
        let message = error_message(parse_msh_bytes::<2>(&file_type_2, "ft.msh", &names_map()));
        assert!(
            message.starts_with("ft.msh:2: expected file-type 0 (ASCII) or 1 (binary)"),
            "{message}"
        );
    }

    /// Element blocks of a binary file: (offset of the block, dimension, element type, number
    /// of elements, bytes per element).
    fn binary_element_blocks(bytes: &[u8]) -> Vec<(usize, i32, i32, usize, usize)> {
        let int = |at: usize| i32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
        let size = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
        let mut at = find(bytes, b"$Elements\n") + 10;
        let count = size(at);
        at += 32;
        let mut blocks = Vec::new();
        for _ in 0..count {
            let (dimension, element_type, elements) = (int(at), int(at + 8), size(at + 12));
            let element_bytes = 8 * (1 + nodes_per_element(element_type).unwrap());
            blocks.push((at, dimension, element_type, elements, element_bytes));
            at += 20 + elements * element_bytes;
        }
        blocks
    }

    #[test]
    fn binary_content_errors_name_section_and_offset() {
        let bytes = gmsh_bytes("unit_square", "binary");
        let blocks = binary_element_blocks(&bytes);
        // An element on a missing node.
        let &(cells, ..) = blocks.iter().find(|block| block.1 == 2).unwrap();
        let element = cells + 20;
        let tag = u64::from_le_bytes(bytes[element..element + 8].try_into().unwrap());
        let mut edited = bytes.clone();
        edited[element + 8..element + 16].copy_from_slice(&99999u64.to_le_bytes());
        let message = error_message(parse_msh_bytes::<2>(&edited, "m.msh", &names_map()));
        assert_eq!(
            message,
            format!(
                "m.msh: $Elements at byte {element}: expected node tags defined in `$Nodes`, \
                 found node 99999 in element {tag}"
            )
        );
        // A skipped block (the corner point) of an element type of unknown node count.
        let &(points, dimension, element_type, ..) = blocks.first().unwrap();
        assert_eq!((dimension, element_type), (0, 15));
        let mut edited = bytes.clone();
        edited[points + 8..points + 12].copy_from_slice(&99i32.to_le_bytes());
        let message = error_message(parse_msh_bytes::<2>(&edited, "m.msh", &names_map()));
        assert!(
            message.starts_with(&format!(
                "m.msh: $Elements at byte {points}: expected a block of element types 1 to 31"
            )),
            "{message}"
        );
        assert!(message.ends_with("found element type 99"), "{message}");
        // A cell block of quadrangles.
        let mut edited = bytes.clone();
        edited[cells + 8..cells + 12].copy_from_slice(&3i32.to_le_bytes());
        let message = error_message(parse_msh_bytes::<2>(&edited, "m.msh", &names_map()));
        assert_eq!(
            message,
            format!(
                "m.msh: $Elements at byte {cells}: expected triangles (first or second order) \
                 in a 2D entity block, found element type 3 (4-node quadrangle)"
            )
        );
        // A non-finite coordinate: the first node of the first block.
        let nodes = find(&bytes, b"$Nodes\n") + 7;
        let first_block = nodes + 32;
        let count = u64::from_le_bytes(
            bytes[first_block + 12..first_block + 20]
                .try_into()
                .unwrap(),
        );
        let node_tag = u64::from_le_bytes(
            bytes[first_block + 20..first_block + 28]
                .try_into()
                .unwrap(),
        );
        let y = first_block + 20 + 8 * count as usize + 8;
        let mut edited = bytes.clone();
        edited[y..y + 8].copy_from_slice(&f64::NAN.to_le_bytes());
        let message = error_message(parse_msh_bytes::<2>(&edited, "m.msh", &names_map()));
        assert_eq!(
            message,
            format!(
                "m.msh: $Nodes at byte {y}: expected coordinate 1 of node {node_tag} (finite), \
                 found NaN"
            )
        );
        // A node block of dimension 7.
        let mut edited = bytes;
        edited[first_block..first_block + 4].copy_from_slice(&7i32.to_le_bytes());
        let message = error_message(parse_msh_bytes::<2>(&edited, "m.msh", &names_map()));
        assert_eq!(
            message,
            format!("m.msh: $Nodes at byte {first_block}: expected the entity dimension (0 to 3), found 7")
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn mutated_or_truncated_binary_files_never_panic(
            cube in any::<bool>(),
            edits in prop::collection::vec(
                (0usize..3, any::<prop::sample::Index>(), any::<u64>()),
                1..4,
            ),
        ) {
            let name = if cube { "unit_cube" } else { "unit_square" };
            let mut bytes = gmsh_bytes(name, "binary");
            for (kind, at, value) in edits {
                if bytes.is_empty() {
                    break;
                }
                let i = at.index(bytes.len());
                match kind {
                    // Cut the file.
                    0 => bytes.truncate(i),
                    // Flip bits of one byte.
                    1 => bytes[i] ^= (value as u8).max(1),
                    // Overwrite up to 8 bytes (a count, tag or coordinate) with a random value.
                    _ => {
                        let end = (i + 8).min(bytes.len());
                        bytes[i..end].copy_from_slice(&value.to_le_bytes()[..end - i]);
                    }
                }
            }
            let two = parse_msh_bytes::<2>(&bytes, "mutated.msh", &names_map());
            let three = parse_msh_bytes::<3>(&bytes, "mutated.msh", &names_map());
            // Only Ok or an invalid-mesh error: no panic, no other kind of error.
            prop_assert!(matches!(two, Ok(_) | Err(Error::InvalidMesh(_))), "{two:?}");
            prop_assert!(matches!(three, Ok(_) | Err(Error::InvalidMesh(_))), "{three:?}");
        }
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
