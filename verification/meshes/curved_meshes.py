"""Generates the second-order meshes of the built-in manufactured cases curved2d and curved3d.

curved2d: the lower half of the unit disc, {x^2 + y^2 <= 1, y <= 0}, meshed by 6-node
triangles (Gmsh second order: the edge nodes of the arc lie on the circle). Physical curves:
    clamped   y = 0   (the flat side)
    contact   the arc x^2 + y^2 = 1, y < 0  (outward normal (x, y))
and the physical surface `body`. Triangles of size H, MSH 4.1 ASCII.

curved3d: the half cylinder {x^2 + y^2 <= 1, y <= 0, 0 <= z <= 0.5}, meshed by 10-node
tetrahedra (the edge nodes of the cylindrical face on it). Physical surfaces:
    clamped   y = 0   (the flat face)
    contact   the cylindrical face x^2 + y^2 = 1, y < 0  (outward normal (x, y, 0))
    traction  the two ends z = 0 and z = 0.5
and the physical volume `body`. Tetrahedra of size H_3D, MSH 4.1 binary.

Regenerate (from the repository root; gmsh 4.15.2 from PyPI, `pip install gmsh==4.15.2`):

    python3 verification/meshes/curved_meshes.py

Gmsh's mesher is deterministic for a given version.
"""

import os

import gmsh

HERE = os.path.dirname(os.path.abspath(__file__))
H = 0.4
H_3D = 0.4


def write_second_order(path, dimension, binary):
    """Meshes the model, raises it to second order and writes it in MSH 4.1."""
    gmsh.model.mesh.generate(dimension)
    gmsh.model.mesh.setOrder(2)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 1 if binary else 0)
    gmsh.write(path)
    _, tags, _ = gmsh.model.mesh.getElements(dimension)
    print(f"{path}: {len(tags[0])} second-order cells")
    gmsh.finalize()


def half_disc(path, size):
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("curved2d")
    geo = gmsh.model.geo
    centre = geo.addPoint(0.0, 0.0, 0.0, size)
    left = geo.addPoint(-1.0, 0.0, 0.0, size)
    bottom = geo.addPoint(0.0, -1.0, 0.0, size)
    right = geo.addPoint(1.0, 0.0, 0.0, size)
    flat = geo.addLine(right, left)
    arc_left = geo.addCircleArc(left, centre, bottom)
    arc_right = geo.addCircleArc(bottom, centre, right)
    loop = geo.addCurveLoop([flat, arc_left, arc_right])
    surface = geo.addPlaneSurface([loop])
    geo.synchronize()
    gmsh.model.addPhysicalGroup(1, [flat], name="clamped")
    gmsh.model.addPhysicalGroup(1, [arc_left, arc_right], name="contact")
    gmsh.model.addPhysicalGroup(2, [surface], name="body")
    write_second_order(path, 2, binary=False)


def half_cylinder(path, size):
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("curved3d")
    occ = gmsh.model.occ
    cylinder = occ.addCylinder(0.0, 0.0, 0.0, 0.0, 0.0, 0.5, 1.0)
    box = occ.addBox(-2.0, -2.0, -1.0, 4.0, 2.0, 3.0)
    occ.intersect([(3, cylinder)], [(3, box)])
    occ.synchronize()
    groups = {"clamped": [], "contact": [], "traction": []}
    for _, tag in gmsh.model.getEntities(2):
        x, y, z = occ.getCenterOfMass(2, tag)
        if abs(y) < 1e-9:
            groups["clamped"].append(tag)
        elif abs(z) < 1e-9 or abs(z - 0.5) < 1e-9:
            groups["traction"].append(tag)
        else:
            groups["contact"].append(tag)
    for name, tags in groups.items():
        gmsh.model.addPhysicalGroup(2, tags, name=name)
    gmsh.model.addPhysicalGroup(3, [tag for _, tag in gmsh.model.getEntities(3)], name="body")
    gmsh.option.setNumber("Mesh.MeshSizeMin", size)
    gmsh.option.setNumber("Mesh.MeshSizeMax", size)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    write_second_order(path, 3, binary=True)


if __name__ == "__main__":
    half_disc(os.path.join(HERE, "curved2d.msh"), H)
    half_cylinder(os.path.join(HERE, "curved3d.msh"), H_3D)
