"""Generates plate_with_hole_2d.msh, the mesh of the example plate_with_hole_2d.toml.

The plate Ω = (0, 2) × (0, 1) minus the disc of radius 0.2 centred at (1.0, 0.5), meshed with
linear triangles of size about 0.05 (0.025 on the hole, so that the circle and the stress
concentration around it are resolved) and saved as MSH 4.1 ASCII, the format read by
contact_damage::io::gmsh. Physical groups of curves (dimension 1), used by name in the problem file:

    clamped  x = 0         (Γ1)
    bottom   y = 0         (Γ3, contact with the foundation)
    top      y = 1         (Γ2, loaded)
    right    x = 2         (Γ2, free)
    hole     the circle    (Γ2, free)

and the physical surface `plate` (so that Gmsh saves the triangles).

Regenerate (from the repository root; gmsh 4.15.2 from PyPI, `pip install gmsh==4.15.2`):

    python3 crates/simulate/examples/plate_with_hole_2d.py

The mesh is written beside this script. Gmsh's 2D mesher is deterministic for a given
version, so the same version gives the same file.
"""

import math
import os
import sys

import gmsh

LENGTH, HEIGHT = 2.0, 1.0
HOLE_CENTRE, HOLE_RADIUS = (1.0, 0.5), 0.2
MESH_SIZE, HOLE_MESH_SIZE = 0.05, 0.025
TOLERANCE = 1e-5  # OpenCASCADE bounding boxes are padded by about 1e-7


def main():
    output = os.path.join(os.path.dirname(os.path.abspath(__file__)), "plate_with_hole_2d.msh")
    gmsh.initialize()
    gmsh.option.setNumber("General.Verbosity", 2)  # errors and warnings only
    gmsh.model.add("plate_with_hole_2d")
    occ = gmsh.model.occ
    plate = occ.addRectangle(0.0, 0.0, 0.0, LENGTH, HEIGHT)
    disc = occ.addDisk(HOLE_CENTRE[0], HOLE_CENTRE[1], 0.0, HOLE_RADIUS, HOLE_RADIUS)
    (surface,), _ = occ.cut([(2, plate)], [(2, disc)])
    occ.synchronize()

    # classify the boundary curves of the plate by their bounding boxes
    groups = {"clamped": [], "bottom": [], "top": [], "right": [], "hole": []}
    for _, curve in gmsh.model.getBoundary([surface], oriented=False):
        xmin, ymin, _, xmax, ymax, _ = gmsh.model.getBoundingBox(1, curve)
        if xmax < TOLERANCE:
            groups["clamped"].append(curve)
        elif xmin > LENGTH - TOLERANCE:
            groups["right"].append(curve)
        elif ymax < TOLERANCE:
            groups["bottom"].append(curve)
        elif ymin > HEIGHT - TOLERANCE:
            groups["top"].append(curve)
        else:
            groups["hole"].append(curve)
    for name, curves in groups.items():
        if not curves:
            sys.exit(f"no boundary curve classified as {name}")
        gmsh.model.addPhysicalGroup(1, curves, name=name)
    gmsh.model.addPhysicalGroup(2, [surface[1]], name="plate")

    # size 0.05 everywhere, 0.025 on the points of the hole (Gmsh interpolates in between)
    gmsh.option.setNumber("Mesh.MeshSizeMin", HOLE_MESH_SIZE)
    gmsh.option.setNumber("Mesh.MeshSizeMax", MESH_SIZE)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 1)
    points = gmsh.model.getEntities(0)
    gmsh.model.mesh.setSize(points, MESH_SIZE)
    hole_points = gmsh.model.getBoundary(
        [(1, curve) for curve in groups["hole"]], combined=False, oriented=False
    )
    gmsh.model.mesh.setSize(hole_points, HOLE_MESH_SIZE)
    distance = gmsh.model.mesh.field.add("Distance")
    gmsh.model.mesh.field.setNumbers(distance, "CurvesList", groups["hole"])
    gmsh.model.mesh.field.setNumber(distance, "Sampling", 200)
    threshold = gmsh.model.mesh.field.add("Threshold")
    gmsh.model.mesh.field.setNumber(threshold, "InField", distance)
    gmsh.model.mesh.field.setNumber(threshold, "SizeMin", HOLE_MESH_SIZE)
    gmsh.model.mesh.field.setNumber(threshold, "SizeMax", MESH_SIZE)
    gmsh.model.mesh.field.setNumber(threshold, "DistMin", 0.0)
    gmsh.model.mesh.field.setNumber(threshold, "DistMax", 0.2)
    gmsh.model.mesh.field.setAsBackgroundMesh(threshold)

    gmsh.model.mesh.generate(2)

    # sanity checks: the nodes of the hole lie on the circle
    for curve in groups["hole"]:
        _, coordinates, _ = gmsh.model.mesh.getNodes(1, curve, includeBoundary=True)
        for i in range(0, len(coordinates), 3):
            x, y = coordinates[i], coordinates[i + 1]
            radius = math.hypot(x - HOLE_CENTRE[0], y - HOLE_CENTRE[1])
            if abs(radius - HOLE_RADIUS) > 1e-9:
                sys.exit(f"hole node ({x}, {y}) at distance {radius} from the centre")

    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 0)
    gmsh.option.setNumber("Mesh.SaveAll", 0)
    gmsh.write(output)
    _, triangles, _ = gmsh.model.mesh.getElements(2)
    nodes, _, _ = gmsh.model.mesh.getNodes()
    print(
        f"gmsh {gmsh.__version__}: wrote {output}: {len(nodes)} nodes, "
        f"{sum(len(t) for t in triangles)} triangles"
    )
    gmsh.finalize()


if __name__ == "__main__":
    main()
