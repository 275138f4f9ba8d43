"""Writes the Gmsh meshes used by the binary-format tests of `src/gmsh.rs`.

Each mesh is saved twice in the MSH 4.1 format, as ASCII (`<name>_ascii.msh`,
`Mesh.Binary = 0`) and as binary (`<name>_binary.msh`, `Mesh.Binary = 1`), from the same
meshing run, so both files describe the same nodes and elements (node coordinates are
rounded to 12 significant digits first, so that the ASCII file, written by Gmsh with `%.16g`,
holds the same doubles as the binary one; the script checks it):

- `unit_square`: the unit square [0, 1]^2, first order (triangles, lines);
- `unit_square_p2`: the same square, second order (6-node triangles, 3-node lines);
- `unit_cube`: the unit cube [0, 1]^3, first order (tetrahedra, triangles).

Physical groups (same tags and names in 2D and 3D; boundary groups have dimension D - 1):
1 "clamped" (x = 0), 2 "contact" (bottom: y = 0 in 2D, z = 0 in 3D), 3 "traction" (the other
sides), 4 "body" (the square or cube, dimension D); and groups the reader skips: 5 "corner"
(the point at the origin) and, in 3D, 6 "x axis" (the edge y = z = 0).

Rerun from the repository root (needs `pip install gmsh`, version 4.15.x; no system
libraries); with Gmsh 4.15.2 the output is byte-for-byte the committed files:

    cd crates/contact-damage/tests/meshes && python3 make_binary_meshes.py
"""

import struct

import gmsh

CLAMPED, CONTACT, TRACTION, BODY, CORNER, X_AXIS = 1, 2, 3, 4, 5, 6


def corner_point():
    """The geometric point at the origin."""
    for _, tag in gmsh.model.getEntities(0):
        if max(abs(x) for x in gmsh.model.getValue(0, tag, [])) < 1e-6:
            return tag
    raise RuntimeError("no point at the origin")


def x_axis_curves():
    """The curves on the x axis (y = z = 0)."""
    curves = []
    for _, tag in gmsh.model.getEntities(1):
        box = gmsh.model.getBoundingBox(1, tag)
        if max(abs(box[k]) for k in (1, 2, 4, 5)) < 1e-6:
            curves.append(tag)
    return curves


def boundary_groups(dim):
    """Sorts the boundary entities of dimension dim - 1 of the box [0, 1]^dim into groups."""
    groups = {CLAMPED: [], CONTACT: [], TRACTION: []}
    bottom_axis = dim - 1  # y in 2D, z in 3D
    for _, tag in gmsh.model.getEntities(dim - 1):
        box = gmsh.model.getBoundingBox(dim - 1, tag)
        xmin, xmax = box[0], box[3]
        bottom_min, bottom_max = box[bottom_axis], box[3 + bottom_axis]
        if abs(xmin) < 1e-6 and abs(xmax) < 1e-6:
            groups[CLAMPED].append(tag)
        elif abs(bottom_min) < 1e-6 and abs(bottom_max) < 1e-6:
            groups[CONTACT].append(tag)
        else:
            groups[TRACTION].append(tag)
    return groups


def snap_coordinates(dim):
    """Rounds every node coordinate to 12 significant digits.

    Gmsh writes ASCII coordinates with `%.16g`, which does not always give back the same
    double; rounded coordinates do, so the ASCII and binary files hold bitwise-equal nodes
    (checked by `check_same_nodes`). The nodes move by about 1e-12, keeping the mesh valid.
    """
    for entity_dim in range(dim + 1):
        for _, entity in gmsh.model.getEntities(entity_dim):
            tags, coords, params = gmsh.model.mesh.getNodes(entity_dim, entity)
            per_node = len(params) // len(tags) if len(tags) else 0
            for k, tag in enumerate(tags):
                rounded = [float(f"{x:.12g}") for x in coords[3 * k : 3 * k + 3]]
                param = list(params[per_node * k : per_node * (k + 1)])
                gmsh.model.mesh.setNode(tag, rounded, param)


def ascii_nodes(path):
    """Node tag -> coordinates of an MSH 4.1 ASCII file."""
    lines = open(path).read().split("\n")
    at = lines.index("$Nodes")
    blocks = int(lines[at + 1].split()[0])
    at += 2
    nodes = {}
    for _ in range(blocks):
        count = int(lines[at].split()[3])
        tags = [int(line) for line in lines[at + 1 : at + 1 + count]]
        at += 1 + count
        for tag in tags:
            nodes[tag] = [float(x) for x in lines[at].split()[:3]]
            at += 1
    return nodes


def binary_nodes(path):
    """Node tag -> coordinates of an MSH 4.1 binary file (little-endian, size_t = 8 bytes)."""
    data = open(path, "rb").read()
    at = data.index(b"$Nodes\n") + len(b"$Nodes\n")
    blocks = struct.unpack_from("<Q", data, at)[0]
    at += 32
    nodes = {}
    for _ in range(blocks):
        _dim, _entity, parametric = struct.unpack_from("<3i", data, at)
        count = struct.unpack_from("<Q", data, at + 12)[0]
        assert parametric == 0
        at += 20
        tags = struct.unpack_from(f"<{count}Q", data, at)
        at += 8 * count
        coords = struct.unpack_from(f"<{3 * count}d", data, at)
        at += 24 * count
        for k, tag in enumerate(tags):
            nodes[tag] = list(coords[3 * k : 3 * k + 3])
    return nodes


def check_same_nodes(name):
    ascii, binary = ascii_nodes(f"{name}_ascii.msh"), binary_nodes(f"{name}_binary.msh")
    assert ascii == binary, f"{name}: ASCII and binary node coordinates differ"


def write_mesh(name, dim, size, order):
    gmsh.model.add(name)
    if dim == 2:
        gmsh.model.occ.addRectangle(0, 0, 0, 1, 1)
    else:
        gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
    gmsh.model.occ.synchronize()
    names = {CLAMPED: "clamped", CONTACT: "contact", TRACTION: "traction"}
    for tag, entities in boundary_groups(dim).items():
        gmsh.model.addPhysicalGroup(dim - 1, entities, tag, names[tag])
    body = [tag for _, tag in gmsh.model.getEntities(dim)]
    gmsh.model.addPhysicalGroup(dim, body, BODY, "body")
    # Lower-dimensional groups, whose element blocks the reader skips: the corner at the
    # origin (1-node points) and, in 3D, the edges on the x axis (lines).
    gmsh.model.addPhysicalGroup(0, [corner_point()], CORNER, "corner")
    if dim == 3:
        gmsh.model.addPhysicalGroup(1, x_axis_curves(), X_AXIS, "x axis")
    gmsh.option.setNumber("Mesh.MeshSizeMin", size)
    gmsh.option.setNumber("Mesh.MeshSizeMax", size)
    gmsh.model.mesh.generate(dim)
    if order > 1:
        gmsh.model.mesh.setOrder(order)
    snap_coordinates(dim)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    for binary, suffix in [(0, "ascii"), (1, "binary")]:
        gmsh.option.setNumber("Mesh.Binary", binary)
        gmsh.write(f"{name}_{suffix}.msh")
    gmsh.model.remove()
    check_same_nodes(name)


gmsh.initialize()
gmsh.option.setNumber("General.Terminal", 0)
write_mesh("unit_square", 2, 0.25, 1)
write_mesh("unit_square_p2", 2, 0.5, 2)
write_mesh("unit_cube", 3, 0.5, 1)
gmsh.finalize()
