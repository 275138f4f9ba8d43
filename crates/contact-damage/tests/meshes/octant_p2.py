"""Generates octant_p2.msh: the octant {x, y, z >= 0, |x| <= 1} of the unit ball meshed by
10-node tetrahedra (Gmsh second order: the edge nodes on the sphere lie on it). Physical
surfaces `planes` (the three coordinate planes) and `sphere`; physical volume `ball`.

Regenerate (gmsh 4.15.2 from PyPI): python3 crates/contact-damage/tests/meshes/octant_p2.py
"""

import os

import gmsh

HERE = os.path.dirname(os.path.abspath(__file__))

gmsh.initialize()
gmsh.option.setNumber("General.Terminal", 0)
gmsh.model.add("octant")
occ = gmsh.model.occ
ball = occ.addSphere(0, 0, 0, 1.0)
box = occ.addBox(0, 0, 0, 2, 2, 2)
occ.intersect([(3, ball)], [(3, box)])
occ.synchronize()
planes, sphere = [], []
for _, tag in gmsh.model.getEntities(2):
    centre = occ.getCenterOfMass(2, tag)
    (planes if min(abs(c) for c in centre) < 1e-9 else sphere).append(tag)
gmsh.model.addPhysicalGroup(2, planes, name="planes")
gmsh.model.addPhysicalGroup(2, sphere, name="sphere")
gmsh.model.addPhysicalGroup(3, [tag for _, tag in gmsh.model.getEntities(3)], name="ball")
gmsh.option.setNumber("Mesh.MeshSizeMax", 0.8)
gmsh.model.mesh.generate(3)
gmsh.model.mesh.setOrder(2)
gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
gmsh.option.setNumber("Mesh.Binary", 0)
gmsh.write(os.path.join(HERE, "octant_p2.msh"))
print(len(gmsh.model.mesh.getElements(3)[1][0]), "ten-node tetrahedra")
gmsh.finalize()
