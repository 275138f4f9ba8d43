"""What the validation mesh scripts share: a mesh size graded towards a point, and the MSH 4.1
binary output read by contact_damage::io::gmsh."""

import gmsh


def grade_towards(point: int, size_min: float, size_max: float, dist_min: float, dist_max: float):
    """Sizes the mesh by the distance to the point `point` (a tag of the current model): size_min
    within dist_min of it, growing linearly to size_max at dist_max and beyond. Sizes from the
    boundary, the points and the curvature are switched off, so this field alone decides."""
    field = gmsh.model.mesh.field
    distance = field.add("Distance")
    field.setNumbers(distance, "PointsList", [point])
    threshold = field.add("Threshold")
    field.setNumber(threshold, "InField", distance)
    field.setNumber(threshold, "SizeMin", size_min)
    field.setNumber(threshold, "SizeMax", size_max)
    field.setNumber(threshold, "DistMin", dist_min)
    field.setNumber(threshold, "DistMax", dist_max)
    field.setAsBackgroundMesh(threshold)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)


def write_binary(path: str):
    """Writes the current mesh to `path` as MSH 4.1 binary."""
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 1)
    gmsh.write(path)
