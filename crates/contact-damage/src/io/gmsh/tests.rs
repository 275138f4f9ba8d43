use super::binary::nodes_per_element;
use super::*;
use proptest::prelude::*;
use std::collections::BTreeMap;
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

fn read_both<const D: usize>(name: &str, map: &PhysicalMap) -> (Result<Mesh<D>>, Result<Mesh<D>>) {
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
        format!(
            "m.msh: $Nodes at byte {first_block}: expected the entity dimension (0 to 3), found 7"
        )
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
    let brick = Mesh::<3>::box_mesh([0.0, -1.0, 0.5], [2.0, 0.5, 1.5], [2, 1, 2], sides3).unwrap();
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
