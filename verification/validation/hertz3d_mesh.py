"""Generates the meshes of the 3D Hertz and Mindlin validations (hertz3d.toml, mindlin3d.toml).

A quarter of a block, (0, 1) x (0, 1) x (0, 1), whose face z = 0 is pressed onto a rigid
paraboloid (the gap is (x^2 + y^2)/2R): by symmetry a quarter of the body, the planes x = 0
and y = 0 cutting the contact disc. Physical groups of surfaces, used by name in the problem
file:

    top      the face z = 1   (prescribed approach u_z = -delta)
    contact  the face z = 0   (contact with the indenter)
    sym_x    the plane x = 0  (symmetry: u_x = 0)
    sym_y    the plane y = 0  (symmetry: u_y = 0)
    sides    the faces x = 1 and y = 1 (traction free)

and the physical volume `block`. The tetrahedra are graded towards the centre of the contact:
size H_CONTACT within a distance 0.1 of the origin (the contact radius is about 0.06), growing
linearly to 0.2 at distance 0.8. Three meshes, h = 0.02, 0.01, 0.007 at the contact, saved as
MSH 4.1 binary (the format read by contact_damage::io::gmsh): hertz3d_h0.02.msh,
hertz3d_h0.01.msh, hertz3d_h0.007.msh.

For Mindlin's tangential load along x, a half of the block, (-1, 1) x (0, 1) x (0, 1), with
the same groups but no sym_x (the faces x = -1 and x = 1 are `sides`), graded the same way:
mindlin3d_h0.02.msh, mindlin3d_h0.01.msh.

Regenerate (from the repository root; gmsh 4.15.2 from PyPI, `pip install gmsh==4.15.2`):

    python3 verification/validation/hertz3d_mesh.py

Gmsh's 3D mesher is deterministic for a given version and one thread.
"""

import os

import gmsh
from gmsh_grading import grade_towards, write_binary

SIZES = [0.02, 0.01, 0.007]
HALF_SIZES = [0.02, 0.01]
HERE = os.path.dirname(os.path.abspath(__file__))


def mesh(h_contact: float, half: bool = False) -> str:
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.model.add("mindlin3d" if half else "hertz3d")
    occ = gmsh.model.occ
    x_min = -1.0 if half else 0.0
    block = occ.addBox(x_min, 0.0, 0.0, 1.0 - x_min, 1.0, 1.0)
    occ.synchronize()
    faces = {}
    for dim, tag in gmsh.model.getEntities(2):
        x, y, z = gmsh.model.occ.getCenterOfMass(dim, tag)
        if abs(z - 1.0) < 1e-9:
            faces.setdefault("top", []).append(tag)
        elif abs(z) < 1e-9:
            faces.setdefault("contact", []).append(tag)
        elif abs(x) < 1e-9 and not half:
            faces.setdefault("sym_x", []).append(tag)
        elif abs(y) < 1e-9:
            faces.setdefault("sym_y", []).append(tag)
        else:
            faces.setdefault("sides", []).append(tag)
    names = ["top", "contact", "sym_y", "sides"] if half else ["top", "contact", "sym_x", "sym_y", "sides"]
    for name in names:
        gmsh.model.addPhysicalGroup(2, faces[name], name=name)
    gmsh.model.addPhysicalGroup(3, [block], name="block")
    origin = occ.addPoint(0.0, 0.0, 0.0)
    occ.synchronize()
    grade_towards(origin, h_contact, 0.2, 0.1, 0.8)
    gmsh.model.mesh.generate(3)
    stem = "mindlin3d" if half else "hertz3d"
    path = os.path.join(HERE, f"{stem}_h{h_contact}.msh")
    write_binary(path)
    nodes = len(gmsh.model.mesh.getNodes()[0])
    tetrahedra = len(gmsh.model.mesh.getElementsByType(4)[0])
    gmsh.finalize()
    return f"{path}: {nodes} nodes, {tetrahedra} tetrahedra"


if __name__ == "__main__":
    for size in SIZES:
        print(mesh(size))
    for size in HALF_SIZES:
        print(mesh(size, half=True))
