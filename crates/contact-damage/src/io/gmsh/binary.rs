//! The binary section readers (file-type 1): `$Entities`, `$Nodes` and `$Elements` read as
//! little-endian fields through a [`Cursor`].

use std::collections::HashMap;
use std::fmt;

use super::reader::{fail, Location, Reader};
use super::records::{
    block_role, element_type_name, insert_entity, insert_node, push_element, BlockRole,
    ElementBlocks, Elements, Entities, Entity, Node, ENTITY_KINDS,
};
use crate::error::{Error, Result};

/// Reads the little-endian binary fields of a section of a binary file from the reader's
/// position, which it advances. Errors name the section and the byte offset.
pub(super) struct Cursor<'r, 'a> {
    pub(super) reader: &'r mut Reader<'a>,
}

/// Bytes of a node or element block header: three `int` and one `size_t`.
const BLOCK_HEADER_BYTES: usize = 3 * 4 + 8;

impl<'a> Cursor<'_, 'a> {
    /// Byte offset of the next field.
    pub(super) fn offset(&self) -> usize {
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
    pub(super) fn fail_at(
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
    pub(super) fn array<const N: usize>(&mut self, what: impl fmt::Display) -> Result<[u8; N]> {
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

/// `$Entities` (binary): four `size_t` counts, then per point `int` tag, 3 `double`, `size_t`
/// numPhysicalTags, that many `int`; per curve, surface or volume `int` tag, 6 `double`,
/// `size_t` numPhysicalTags, that many `int`, `size_t` numBounding, that many `int`.
pub(super) fn read_entities_binary(reader: &mut Reader) -> Result<Entities> {
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

/// `$Nodes` (binary): four `size_t` (numEntityBlocks numNodes minNodeTag maxNodeTag), then
/// blocks of `int` entityDim, `int` entityTag, `int` parametric, `size_t` numNodesInBlock,
/// the block's node tags (`size_t`), and their coordinates (3 `double`, followed by
/// `entityDim` parametric coordinates if parametric).
pub(super) fn read_nodes_binary(reader: &mut Reader) -> Result<HashMap<u64, Node>> {
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

/// Number of nodes of the Gmsh element types 1 to 31 (index: type − 1), as given by
/// `gmsh.model.mesh.getElementProperties`; needed to skip element blocks of binary files.
const NODES_PER_ELEMENT: [usize; 31] = [
    2, 3, 4, 4, 8, 6, 5, 3, 6, 9, 10, 27, 18, 14, 1, 8, 20, 15, 13, 9, 10, 12, 15, 15, 21, 4, 5, 6,
    20, 35, 56,
];

/// Number of nodes of a Gmsh element type, if known.
pub(super) fn nodes_per_element(element_type: i32) -> Option<usize> {
    let index = usize::try_from(element_type).ok()?.checked_sub(1)?;
    NODES_PER_ELEMENT.get(index).copied()
}

/// `$Elements` (binary): four `size_t` (numEntityBlocks numElements minElementTag
/// maxElementTag), then blocks of `int` entityDim, `int` entityTag, `int` elementType,
/// `size_t` numElementsInBlock, followed per element by its tag and node tags (`size_t`).
pub(super) fn read_elements_binary<const D: usize>(
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
