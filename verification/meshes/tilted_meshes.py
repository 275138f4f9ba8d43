"""Generates the meshes of the built-in manufactured cases tilted2d and tilted3d.

Both domains are given in local coordinates (X, Y[, Z]) and rotated rigidly into the global
(x, y[, z]) frame, so that the contact boundary is not aligned with any axis; the exact fields
of the case files are the fields of zones2d/zones3d written in the local coordinates.

tilted2d: the pentagon (0,0), (1,0), (1,0.6), (0.5,1), (0,1) in (X, Y), rotated by THETA_2D
about the origin: x = R (X, Y), R = [[cos, -sin], [sin, cos]]. Physical curves:
    clamped   X = 0
    contact   Y = 0   (the foundation side, outward normal -e_Y = (sin, -cos))
    traction  the three other sides
and the physical surface `body`. Unstructured triangles of size H_2D, MSH 4.1 ASCII.

tilted3d: the prism {(X, Y, Z): (X, Z) in the same pentagon, 0 <= Y <= 1}, rotated by
R_3D = Rz(ALPHA) Rx(BETA) (columns: the local axes e_X, e_Y, e_Z in global coordinates).
Physical surfaces: clamped (X = 0), contact (Z = 0), traction (the five others); physical
volume `body`. Unstructured tetrahedra of size H_3D, MSH 4.1 binary.

Regenerate (from the repository root; gmsh 4.15.2 from PyPI, `pip install gmsh==4.15.2`):

    python3 verification/meshes/tilted_meshes.py

It also prints the rotation matrices with 17 digits (the constants of the case files).
Gmsh's mesher is deterministic for a given version.
"""

import math
import os

import gmsh

HERE = os.path.dirname(os.path.abspath(__file__))
PENTAGON = [(0.0, 0.0), (1.0, 0.0), (1.0, 0.6), (0.5, 1.0), (0.0, 1.0)]
THETA_2D = math.radians(25.0)
ALPHA = math.radians(30.0)
BETA = math.radians(20.0)
H_2D = 0.3
H_3D = 0.4


def rotation_3d():
    ca, sa, cb, sb = math.cos(ALPHA), math.sin(ALPHA), math.cos(BETA), math.sin(BETA)
    rz = [[ca, -sa, 0.0], [sa, ca, 0.0], [0.0, 0.0, 1.0]]
    rx = [[1.0, 0.0, 0.0], [0.0, cb, -sb], [0.0, sb, cb]]
    return [[sum(rz[i][k] * rx[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def local(point, rotation):
    """Local coordinates R^T x of a global point."""
    n = len(rotation)
    return [sum(rotation[i][j] * point[i] for i in range(n)) for j in range(n)]


def mesh_2d():
    c, s = math.cos(THETA_2D), math.sin(THETA_2D)
    rotation = [[c, -s], [s, c]]
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("tilted2d")
    geo = gmsh.model.geo
    points = [geo.addPoint(c * X - s * Y, s * X + c * Y, 0.0, H_2D) for X, Y in PENTAGON]
    lines = [geo.addLine(points[i], points[(i + 1) % 5]) for i in range(5)]
    loop = geo.addCurveLoop(lines)
    surface = geo.addPlaneSurface([loop])
    geo.synchronize()
    # lines[0]: Y = 0 (contact), lines[4]: X = 0 (clamped), the rest traction
    gmsh.model.addPhysicalGroup(1, [lines[4]], name="clamped")
    gmsh.model.addPhysicalGroup(1, [lines[0]], name="contact")
    gmsh.model.addPhysicalGroup(1, lines[1:4], name="traction")
    gmsh.model.addPhysicalGroup(2, [surface], name="body")
    gmsh.model.mesh.generate(2)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 0)
    path = os.path.join(HERE, "tilted2d.msh")
    gmsh.write(path)
    _, tags, _ = gmsh.model.mesh.getElements(2)
    print(f"{path}: {len(tags[0])} triangles")
    gmsh.finalize()
    return rotation


def mesh_3d():
    rotation = rotation_3d()
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("tilted3d")
    occ = gmsh.model.occ

    def to_global(X, Y, Z):
        return [sum(rotation[i][j] * v for j, v in enumerate((X, Y, Z))) for i in range(3)]

    points = [occ.addPoint(*to_global(X, 0.0, Z)) for X, Z in PENTAGON]
    lines = [occ.addLine(points[i], points[(i + 1) % 5]) for i in range(5)]
    loop = occ.addCurveLoop(lines)
    face = occ.addPlaneSurface([loop])
    e_y = [rotation[i][1] for i in range(3)]
    occ.extrude([(2, face)], *e_y)
    occ.synchronize()
    volumes = gmsh.model.getEntities(3)
    groups = {"clamped": [], "contact": [], "traction": []}
    for _, tag in gmsh.model.getEntities(2):
        X, Y, Z = local(occ.getCenterOfMass(2, tag), rotation)
        if abs(X) < 1e-9:
            groups["clamped"].append(tag)
        elif abs(Z) < 1e-9:
            groups["contact"].append(tag)
        else:
            groups["traction"].append(tag)
    for name, tags in groups.items():
        gmsh.model.addPhysicalGroup(2, tags, name=name)
    gmsh.model.addPhysicalGroup(3, [tag for _, tag in volumes], name="body")
    gmsh.option.setNumber("Mesh.MeshSizeMin", H_3D)
    gmsh.option.setNumber("Mesh.MeshSizeMax", H_3D)
    gmsh.model.mesh.generate(3)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 1)
    path = os.path.join(HERE, "tilted3d.msh")
    gmsh.write(path)
    _, tags, _ = gmsh.model.mesh.getElements(3)
    print(f"{path}: {len(tags[0])} tetrahedra; groups {groups}")
    gmsh.finalize()
    return rotation


if __name__ == "__main__":
    r2 = mesh_2d()
    r3 = mesh_3d()
    print("2D rotation (columns e_X, e_Y):", [[f"{v:.17g}" for v in row] for row in r2])
    print("3D rotation (columns e_X, e_Y, e_Z):", [[f"{v:.17g}" for v in row] for row in r3])
