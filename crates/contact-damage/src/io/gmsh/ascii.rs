//! The ASCII section readers (file-type 0): `$Entities`, `$Nodes` and `$Elements`, one record
//! per line.

use std::collections::HashMap;

use super::reader::Reader;
use super::records::{
    block_role, insert_entity, insert_node, push_element, BlockRole, ElementBlocks, Elements,
    Entities, Entity, Node, ENTITY_KINDS,
};
use crate::error::Result;

/// `$Entities` (ASCII): counts of points, curves, surfaces, volumes, then one line per entity:
/// `tag X Y Z numPhysicalTags physicalTag…` for points and
/// `tag minX minY minZ maxX maxY maxZ numPhysicalTags physicalTag… numBounding boundingTag…`
/// for the others.
pub(super) fn read_entities(reader: &mut Reader) -> Result<Entities> {
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

/// `$Nodes` (ASCII): `numEntityBlocks numNodes minNodeTag maxNodeTag`, then blocks
/// `entityDim entityTag parametric numNodesInBlock`, the block's node tags one per line, and
/// their coordinates `x y z` (followed by `entityDim` parametric coordinates if parametric).
pub(super) fn read_nodes(reader: &mut Reader) -> Result<HashMap<u64, Node>> {
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

/// `$Elements` (ASCII): `numEntityBlocks numElements minElementTag maxElementTag`, then blocks
/// `entityDim entityTag elementType numElementsInBlock` followed by one line
/// `elementTag nodeTag…` per element.
pub(super) fn read_elements<const D: usize>(
    reader: &mut Reader,
    blocks: &ElementBlocks,
) -> Result<Elements> {
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
