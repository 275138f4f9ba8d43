"""Generates bracket_3d.msh, the mesh of the example bracket_3d.toml.

The bracket Ω = (0, 2) × (0, 1) × (0, 0.75) with two bolt holes through it along z, cylinders
of radius 0.12 about the vertical lines through (1.2, 0.25) and (1.2, 0.75), meshed with
linear tetrahedra of size about 0.2 (0.09 on the holes; 3940 tetrahedra, 1020 nodes) and
saved as BINARY MSH 4.1 (`Mesh.Binary = 1`), one of the two encodings read by
contact_damage::io::gmsh. Physical groups of surfaces (dimension 2), used by name in the problem
file:

    clamped  x = 0                                    (Γ1)
    contact  z = 0, the bottom face                   (Γ3, contact with the foundation)
    top      z = 0.75                                 (Γ2, loaded)
    free     y = 0, y = 1, x = 2 and the two holes    (Γ2, free)

and the physical volume `bracket` (so that Gmsh saves the tetrahedra).

The contact face carries the straight line y = 0.5 (between the holes) as a geometric curve,
split into MIDLINE_INTERVALS = 32 equal intervals: its nodes lie exactly on y = 0.5, the line
of contact nodes nearest the middle of the face, which is the line that `simulate` records in
contact_history.csv and draws in contact_history.svg (elsewhere on an unstructured face hardly
any nodes line up).

Regenerate (from the repository root; gmsh 4.15.2 from PyPI, `pip install gmsh==4.15.2`):

    python3 crates/simulate/examples/bracket_3d.py

The mesh is written beside this script. Gmsh's meshers are deterministic for a given version
(the 3D mesher runs single-threaded here), so the same version gives the same file.
"""

import math
import os
import sys

import gmsh

LENGTH, WIDTH, HEIGHT = 2.0, 1.0, 0.75
HOLE_CENTRES, HOLE_RADIUS = ((1.2, 0.25), (1.2, 0.75)), 0.12
MESH_SIZE, HOLE_MESH_SIZE = 0.2, 0.09
MIDLINE_Y, MIDLINE_INTERVALS = 0.5, 32
TOLERANCE = 1e-5  # OpenCASCADE bounding boxes are padded by about 1e-7


def main():
    output = os.path.join(os.path.dirname(os.path.abspath(__file__)), "bracket_3d.msh")
    gmsh.initialize()
    gmsh.option.setNumber("General.Verbosity", 2)  # errors and warnings only
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.model.add("bracket_3d")
    occ = gmsh.model.occ
    block = occ.addBox(0.0, 0.0, 0.0, LENGTH, WIDTH, HEIGHT)
    holes = [
        (3, occ.addCylinder(x, y, 0.0, 0.0, 0.0, HEIGHT, HOLE_RADIUS)) for x, y in HOLE_CENTRES
    ]
    (body,), _ = occ.cut([(3, block)], holes)
    # imprint the line y = 0.5 on the bottom face
    start = occ.addPoint(0.0, MIDLINE_Y, 0.0)
    end = occ.addPoint(LENGTH, MIDLINE_Y, 0.0)
    midline = occ.addLine(start, end)
    fragments, _ = occ.fragment([body], [(1, midline)])
    occ.synchronize()
    volumes = [tag for dim, tag in fragments if dim == 3]
    if len(volumes) != 1:
        sys.exit(f"expected one volume after imprinting the midline, found {volumes}")
    midlines = [
        tag
        for _, tag in gmsh.model.getEntitiesInBoundingBox(
            -TOLERANCE, MIDLINE_Y - TOLERANCE, -TOLERANCE,
            LENGTH + TOLERANCE, MIDLINE_Y + TOLERANCE, TOLERANCE, dim=1,
        )
    ]
    if len(midlines) != 1:
        sys.exit(f"expected the midline as one curve, found {midlines}")

    # classify the boundary surfaces of the bracket by their bounding boxes
    groups = {"clamped": [], "contact": [], "top": [], "free": []}
    hole_surfaces = []
    for _, surface in gmsh.model.getBoundary([(3, volumes[0])], oriented=False):
        xmin, ymin, zmin, xmax, ymax, zmax = gmsh.model.getBoundingBox(2, surface)
        if xmax < TOLERANCE:
            groups["clamped"].append(surface)
        elif zmax < TOLERANCE:
            groups["contact"].append(surface)
        elif zmin > HEIGHT - TOLERANCE:
            groups["top"].append(surface)
        else:
            groups["free"].append(surface)
            if xmin > TOLERANCE and xmax < LENGTH - TOLERANCE:
                if ymin > TOLERANCE and ymax < WIDTH - TOLERANCE:
                    hole_surfaces.append(surface)
    for name, surfaces in groups.items():
        if not surfaces:
            sys.exit(f"no boundary surface classified as {name}")
    if len(hole_surfaces) != len(HOLE_CENTRES):
        sys.exit(f"expected {len(HOLE_CENTRES)} hole surfaces, found {hole_surfaces}")
    for name, surfaces in groups.items():
        gmsh.model.addPhysicalGroup(2, surfaces, name=name)
    gmsh.model.addPhysicalGroup(3, volumes, name="bracket")

    # size 0.2 everywhere, 0.09 near the holes (a distance field), and the midline in
    # MIDLINE_INTERVALS equal intervals
    gmsh.option.setNumber("Mesh.MeshSizeMin", HOLE_MESH_SIZE)
    gmsh.option.setNumber("Mesh.MeshSizeMax", MESH_SIZE)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 1)
    gmsh.model.mesh.setSize(gmsh.model.getEntities(0), MESH_SIZE)
    distance = gmsh.model.mesh.field.add("Distance")
    gmsh.model.mesh.field.setNumbers(distance, "SurfacesList", hole_surfaces)
    gmsh.model.mesh.field.setNumber(distance, "Sampling", 100)
    threshold = gmsh.model.mesh.field.add("Threshold")
    gmsh.model.mesh.field.setNumber(threshold, "InField", distance)
    gmsh.model.mesh.field.setNumber(threshold, "SizeMin", HOLE_MESH_SIZE)
    gmsh.model.mesh.field.setNumber(threshold, "SizeMax", MESH_SIZE)
    gmsh.model.mesh.field.setNumber(threshold, "DistMin", 0.0)
    gmsh.model.mesh.field.setNumber(threshold, "DistMax", 0.25)
    gmsh.model.mesh.field.setAsBackgroundMesh(threshold)
    gmsh.model.mesh.setTransfiniteCurve(midlines[0], MIDLINE_INTERVALS + 1)

    gmsh.model.mesh.generate(3)

    # sanity checks: the nodes of the holes lie on their cylinders, those of the midline on it
    for surface in hole_surfaces:
        _, coordinates, _ = gmsh.model.mesh.getNodes(2, surface, includeBoundary=True)
        for i in range(0, len(coordinates), 3):
            x, y = coordinates[i], coordinates[i + 1]
            radius = min(math.hypot(x - cx, y - cy) for cx, cy in HOLE_CENTRES)
            if abs(radius - HOLE_RADIUS) > 1e-9:
                sys.exit(f"hole node ({x}, {y}) at distance {radius} from the axes")
    _, coordinates, _ = gmsh.model.mesh.getNodes(1, midlines[0], includeBoundary=True)
    if len(coordinates) != 3 * (MIDLINE_INTERVALS + 1):
        sys.exit(f"{len(coordinates) // 3} nodes on the midline")
    if any(abs(coordinates[i + 1] - MIDLINE_Y) > 1e-12 for i in range(0, len(coordinates), 3)):
        sys.exit("a node of the midline is off y = 0.5")

    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 1)
    gmsh.option.setNumber("Mesh.SaveAll", 0)
    gmsh.write(output)
    _, tetrahedra, _ = gmsh.model.mesh.getElements(3)
    nodes, _, _ = gmsh.model.mesh.getNodes()
    print(
        f"gmsh {gmsh.__version__}: wrote {output} ({os.path.getsize(output)} bytes): "
        f"{len(nodes)} nodes, {sum(len(t) for t in tetrahedra)} tetrahedra"
    )
    gmsh.finalize()


if __name__ == "__main__":
    main()
