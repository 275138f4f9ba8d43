"""Generates the meshes of the hemisphere validation (hemisphere.toml): a solid hemisphere of
radius R = 1.5 whose curved face rests on a rigid flat at its lowest point, the origin, and
whose flat face z = R is pressed down; as a whole, and as the quarter x > 0, y > 0 with the
symmetry planes x = 0 and y = 0 cutting the contact disc.

Second-order tetrahedra (10 nodes, curved edges on the sphere), graded towards the origin:
size 0.022 within a distance 0.16 of it (the contact radius is about 0.1), growing linearly to
0.32 at distance 1.0. Physical groups of surfaces, used by name in the problem file:

    top      the flat face z = R   (prescribed approach u_z = -delta)
    contact  the curved face       (contact with the flat)
    sym_x    the plane x = 0       (quarter only: symmetry, u_x = 0)
    sym_y    the plane y = 0       (quarter only: symmetry, u_y = 0)

and the physical volume `body`. Saved as MSH 4.1 binary: hemisphere_h0.022.msh (about 14 k
nodes, 42 k unknowns at P2) and hemisphere_quarter_h0.022.msh.

Regenerate (from the repository root; gmsh 4.15.2 from PyPI, `pip install gmsh==4.15.2`):

    python3 verification/validation/hemisphere_mesh.py

Gmsh's 3D mesher is deterministic for a given version and one thread.
"""

import os

import gmsh
from gmsh_grading import grade_towards, write_binary

RADIUS = 1.5
H_CONTACT = 0.022
H_FAR = 0.32
HERE = os.path.dirname(os.path.abspath(__file__))


def mesh(quarter: bool) -> str:
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.model.add("hemisphere")
    occ = gmsh.model.occ
    ball = occ.addSphere(0.0, 0.0, RADIUS, RADIUS)
    upper = occ.addBox(-2 * RADIUS, -2 * RADIUS, RADIUS, 4 * RADIUS, 4 * RADIUS, 2 * RADIUS)
    body = occ.cut([(3, ball)], [(3, upper)])[0]
    if quarter:
        corner = occ.addBox(0.0, 0.0, 0.0, 2 * RADIUS, 2 * RADIUS, 2 * RADIUS)
        body = occ.intersect(body, [(3, corner)])[0]
    occ.synchronize()
    faces = {}
    for dim, tag in gmsh.model.getEntities(2):
        x, y, z = occ.getCenterOfMass(dim, tag)
        if abs(z - RADIUS) < 1e-9:
            faces.setdefault("top", []).append(tag)
        elif quarter and abs(x) < 1e-9:
            faces.setdefault("sym_x", []).append(tag)
        elif quarter and abs(y) < 1e-9:
            faces.setdefault("sym_y", []).append(tag)
        else:
            faces.setdefault("contact", []).append(tag)
    for name, tags in faces.items():
        gmsh.model.addPhysicalGroup(2, tags, name=name)
    gmsh.model.addPhysicalGroup(3, [tag for _, tag in body], name="body")
    origin = occ.addPoint(0.0, 0.0, 0.0)
    occ.synchronize()
    grade_towards(origin, H_CONTACT, H_FAR, 0.16, 1.0)
    gmsh.model.mesh.generate(3)
    gmsh.model.mesh.setOrder(2)
    stem = "hemisphere_quarter" if quarter else "hemisphere"
    path = os.path.join(HERE, f"{stem}_h{H_CONTACT}.msh")
    write_binary(path)
    nodes = len(gmsh.model.mesh.getNodes()[0])
    gmsh.finalize()
    return f"{path}: {nodes} nodes"


if __name__ == "__main__":
    print(mesh(quarter=False))
    print(mesh(quarter=True))
