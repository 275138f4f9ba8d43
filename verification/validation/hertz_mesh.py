"""Generates the meshes of the Hertz line-contact validation (hertz.toml).

A half-disc of radius R = 1 (plane strain): centre (0, 1), the flat side y = 1 on top and the
arc y = 1 - sqrt(1 - x^2) below, touching the rigid flat foundation y = 0 at the origin.
Physical groups of curves, used by name in the problem file:

    top   the flat side y = 1  (prescribed approach u = (0, -delta))
    arc   the arc             (contact with the foundation; the gap grows like x^2/2R)

and the physical surface `disc`. The mesh is graded towards the first contact point: size
H_CONTACT within a distance 0.12 of the origin (the contact half-width is about 0.04-0.05),
growing linearly to 0.08 at distance 0.6. Three meshes, h = 0.01, 0.005, 0.0025 at the
contact, saved as MSH 4.1 binary (the format read by contact_damage::io::gmsh):
hertz_h0.01.msh, hertz_h0.005.msh, hertz_h0.0025.msh. The two coarser ones are also saved as
second-order meshes of the same triangles (6-node triangles, the edge nodes of the arc on the
circle): hertz_h0.01_order2.msh, hertz_h0.005_order2.msh.

Regenerate (from the repository root; gmsh 4.15.2 from PyPI, `pip install gmsh==4.15.2`):

    python3 verification/validation/hertz_mesh.py

Gmsh's 2D mesher is deterministic for a given version.
"""

import os

import gmsh
from gmsh_grading import grade_towards, write_binary

RADIUS = 1.0
SIZES = [0.01, 0.005, 0.0025]
SECOND_ORDER = [0.01, 0.005]
HERE = os.path.dirname(os.path.abspath(__file__))


def mesh(h_contact: float) -> str:
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("hertz")
    occ = gmsh.model.occ
    centre = occ.addPoint(0.0, RADIUS, 0.0)
    left = occ.addPoint(-RADIUS, RADIUS, 0.0)
    bottom = occ.addPoint(0.0, 0.0, 0.0)
    right = occ.addPoint(RADIUS, RADIUS, 0.0)
    arc_left = occ.addCircleArc(left, centre, bottom)
    arc_right = occ.addCircleArc(bottom, centre, right)
    top = occ.addLine(right, left)
    loop = occ.addCurveLoop([arc_left, arc_right, top])
    surface = occ.addPlaneSurface([loop])
    occ.synchronize()
    gmsh.model.addPhysicalGroup(1, [top], name="top")
    gmsh.model.addPhysicalGroup(1, [arc_left, arc_right], name="arc")
    gmsh.model.addPhysicalGroup(2, [surface], name="disc")
    grade_towards(bottom, h_contact, 0.08, 0.12, 0.6)
    gmsh.option.setNumber("Mesh.Algorithm", 6)
    gmsh.model.mesh.generate(2)
    path = os.path.join(HERE, f"hertz_h{h_contact}.msh")
    write_binary(path)
    nodes = len(gmsh.model.mesh.getNodes()[0])
    if h_contact in SECOND_ORDER:
        gmsh.model.mesh.setOrder(2)
        write_binary(os.path.join(HERE, f"hertz_h{h_contact}_order2.msh"))
    gmsh.finalize()
    return f"{path}: {nodes} nodes"


if __name__ == "__main__":
    for size in SIZES:
        print(mesh(size))
