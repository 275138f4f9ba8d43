"""Generates the second-order mesh of the built-in manufactured case curved2d.

curved2d: the lower half of the unit disc, {x^2 + y^2 <= 1, y <= 0}, meshed by 6-node
triangles (Gmsh second order: the edge nodes of the arc lie on the circle). Physical curves:
    clamped   y = 0   (the flat side)
    contact   the arc x^2 + y^2 = 1, y < 0  (outward normal (x, y))
and the physical surface `body`. Triangles of size H, MSH 4.1 ASCII. The levels of a study
are uniform refinements of this mesh, whose new nodes follow the P2 map of each curved cell
(so every level has the same, piecewise quadratic, arc).

Regenerate (from the repository root; gmsh 4.15.2 from PyPI, `pip install gmsh==4.15.2`):

    python3 verification/meshes/curved_meshes.py

Gmsh's mesher is deterministic for a given version.
"""

import os

import gmsh

HERE = os.path.dirname(os.path.abspath(__file__))
H = 0.4


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
    gmsh.model.mesh.generate(2)
    gmsh.model.mesh.setOrder(2)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 0)
    gmsh.write(path)
    _, tags, _ = gmsh.model.mesh.getElements(2)
    print(f"{path}: {len(tags[0])} six-node triangles")
    gmsh.finalize()


if __name__ == "__main__":
    half_disc(os.path.join(HERE, "curved2d.msh"), H)
