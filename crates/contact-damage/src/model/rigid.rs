//! Rigid-body motions left free by the constraints of Γ1.
//!
//! The paper clamps a part of Γ1 of positive measure (2.5), so that Korn's inequality makes the
//! viscous operator of (5.1) coercive. With prescribed components instead of a clamp (rollers,
//! symmetry planes, a grip moving one component) the constrained unknowns must still stop every
//! rigid motion r(x) = a + ω × x of every connected piece of the body: normal compliance does
//! not hold a body that separates from the foundation, and a free rigid motion makes the matrix
//! of (5.1) singular (a Cholesky pivot that is not positive, a NaN in the stability estimate).
//! [`check_rigid_motions`] tells this before anything is factorized, naming the motion and the
//! parts of Γ1 that would have to stop it.

use nalgebra::{SMatrix, SVector};

use crate::error::{Error, Result};
use crate::fem::space::LagrangeSpace;
use crate::model::dirichlet::DirichletConstraints;

/// A rigid motion whose Gram value over the constrained unknowns is below this fraction of the
/// largest one is free: an exactly free motion gives a rounding-level ratio (about 1e-16), a
/// stopped one at least (l/L)² for constraints spread over a length l of a body of size L.
const FREE_RATIO: f64 = 1e-12;

/// The rigid motions of dimension `D`: D translations, then the rotations (one in 2D, three
/// in 3D) about `center`, scaled by `1 / size` so that all are of order one on the body;
/// component `i` of motion `k` at `x`.
fn rigid_motion<const D: usize>(
    k: usize,
    i: usize,
    x: &[f64; D],
    center: &[f64; D],
    size: f64,
) -> f64 {
    if k < D {
        return if i == k { 1.0 } else { 0.0 };
    }
    let mut arm = [0.0; 3];
    for j in 0..D {
        arm[j] = (x[j] - center[j]) / size;
    }
    if D == 2 {
        // ω e_z × (x − c) = ω (−(y − c_y), x − c_x)
        return [-arm[1], arm[0]][i];
    }
    // e_axis × (x − c)
    let axis = k - D;
    let cross = match axis {
        0 => [0.0, -arm[2], arm[1]],
        1 => [arm[2], 0.0, -arm[0]],
        _ => [-arm[1], arm[0], 0.0],
    };
    cross[i]
}

/// The name of rigid motion `k` in dimension `dim`.
fn motion_name(k: usize, dim: usize) -> String {
    const AXES: [&str; 3] = ["x", "y", "z"];
    if k < dim {
        format!("translation along {}", AXES[k])
    } else if dim == 2 {
        "rotation in the plane".to_string()
    } else {
        format!("rotation about {}", AXES[k - dim])
    }
}

/// The connected pieces of the mesh (cells sharing a vertex): the piece of every space node.
fn pieces<const D: usize>(space: &LagrangeSpace<D>) -> (Vec<usize>, usize) {
    let mesh = space.mesh();
    let mut parent: Vec<usize> = (0..mesh.num_vertices()).collect();
    fn root(parent: &mut [usize], mut v: usize) -> usize {
        while parent[v] != v {
            parent[v] = parent[parent[v]];
            v = parent[v];
        }
        v
    }
    for c in 0..mesh.num_cells() {
        let cell = mesh.cell(c);
        let first = root(&mut parent, cell[0]);
        for &v in &cell[1..] {
            let other = root(&mut parent, v);
            parent[other] = first;
        }
    }
    let mut label = vec![usize::MAX; mesh.num_vertices()];
    let mut count = 0;
    let mut piece_of_node = vec![usize::MAX; space.num_nodes()];
    for c in 0..mesh.num_cells() {
        let r = root(&mut parent, mesh.cell(c)[0]);
        if label[r] == usize::MAX {
            label[r] = count;
            count += 1;
        }
        for &node in space.cell_nodes(c) {
            piece_of_node[node] = label[r];
        }
    }
    (piece_of_node, count)
}

/// Checks that the constrained unknowns of `dirichlet` stop every rigid motion of every
/// connected piece of the body; otherwise an [`Error::RigidMotion`] that names the free motion,
/// the piece (when there are several) and the parts of Γ1 that constrain it.
pub fn check_rigid_motions<const D: usize>(
    space: &LagrangeSpace<D>,
    dirichlet: &DirichletConstraints<D>,
) -> Result<()> {
    let (piece_of_node, count) = pieces(space);
    let motions = if D == 2 { 3 } else { 6 };
    // per piece, in passes over the nodes and the constrained unknowns: the first node, the
    // centroid, the size (largest distance from the centroid), the Gram matrix of the rigid
    // motions over the constrained unknowns, and the parts that constrain it
    let mut first_node = vec![usize::MAX; count];
    let mut nodes_in = vec![0usize; count];
    let mut centers = vec![[0.0; D]; count];
    // a vertex in no cell (possible in a mesh given by its arrays) belongs to no piece
    let in_pieces = || {
        piece_of_node
            .iter()
            .enumerate()
            .filter(|(_, &piece)| piece != usize::MAX)
    };
    for (node, &piece) in in_pieces() {
        first_node[piece] = first_node[piece].min(node);
        nodes_in[piece] += 1;
        let x = space.node(node);
        for j in 0..D {
            centers[piece][j] += x[j];
        }
    }
    for (center, &n) in centers.iter_mut().zip(&nodes_in) {
        for value in center.iter_mut() {
            *value /= n as f64;
        }
    }
    let mut sizes = vec![f64::MIN_POSITIVE; count];
    for (node, &piece) in in_pieces() {
        let x = space.node(node);
        let distance = (0..D)
            .map(|j| (x[j] - centers[piece][j]).powi(2))
            .sum::<f64>()
            .sqrt();
        sizes[piece] = sizes[piece].max(distance);
    }
    let mut grams = vec![SMatrix::<f64, 6, 6>::zeros(); count];
    let mut owners: Vec<Vec<usize>> = vec![Vec::new(); count];
    for &(dof, owner) in &dirichlet.dofs {
        let piece = piece_of_node[dof / D];
        if piece == usize::MAX {
            continue;
        }
        let x = space.node(dof / D);
        let mut values = SVector::<f64, 6>::zeros();
        for (k, value) in values.iter_mut().take(motions).enumerate() {
            *value = rigid_motion::<D>(k, dof % D, &x, &centers[piece], sizes[piece]);
        }
        grams[piece] += values * values.transpose();
        if !owners[piece].contains(&owner) {
            owners[piece].push(owner);
        }
    }
    for piece in 0..count {
        let gram = grams[piece].view((0, 0), (motions, motions)).clone_owned();
        let eigen = gram.symmetric_eigen();
        let (weakest, smallest) = eigen
            .eigenvalues
            .iter()
            .copied()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .expect("at least three rigid motions");
        let largest = eigen.eigenvalues.iter().copied().fold(0.0_f64, f64::max);
        if smallest > FREE_RATIO * largest && largest > 0.0 {
            continue;
        }
        let direction = eigen.eigenvectors.column(weakest);
        let scale = direction.amax();
        let motion: Vec<String> = (0..motions)
            .filter(|&k| direction[k].abs() > 0.3 * scale)
            .map(|k| motion_name(k, D))
            .collect();
        let where_ = if count > 1 {
            let node = first_node[piece];
            let x = space.node(node);
            format!(
                "the piece of the mesh with node {node} {x:?} ({} of {count} unconnected pieces)",
                piece + 1
            )
        } else {
            "the body".to_string()
        };
        let owners = &mut owners[piece];
        owners.sort_unstable();
        let constraints = if owners.is_empty() {
            "no clamped facet and no prescribed displacement part touch it".to_string()
        } else {
            let names: Vec<String> = owners
                .iter()
                .map(|&o| format!("`{}`", dirichlet.names[o]))
                .collect();
            format!(
                "its constraints on Γ1 ({}) do not stop it",
                names.join(", ")
            )
        };
        return Err(Error::RigidMotion(format!(
            "{where_} can move rigidly ({}): {constraints}; normal compliance does not hold a \
             body that separates from the foundation and the velocity step (5.1) needs the \
             constraints of Γ1 to stop every rigid motion (clamp a part of Γ1, or prescribe \
             the missing component on a part)",
            motion.join(" with ")
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::mesh::{BoundaryPart::*, Mesh};
    use crate::model::dirichlet::PrescribedDisplacement;
    use crate::model::fields::PointScalarField;
    use std::sync::Arc;

    fn zero<const D: usize>() -> Option<PointScalarField<D>> {
        Some(Arc::new(|_: &[f64; D], _: f64| 0.0))
    }

    /// The unit square, Γ1 = {x = 0}, Γ3 = {y = 0}, the rest Γ2, with the parts `parts` on
    /// the side x = 0 (none: the side is clamped).
    fn square(parts: Vec<[Option<PointScalarField<2>>; 2]>) -> Result<()> {
        let mesh = Mesh::box_mesh(
            [0.0, 0.0],
            [1.0, 1.0],
            [4, 4],
            [[Dirichlet, Neumann], [Contact, Neumann]],
        )
        .unwrap();
        let space = LagrangeSpace::new(Arc::new(mesh), 2).unwrap();
        let left = space.mesh().boundary_facets_where(|x| x[0] == 0.0);
        let parts: Vec<PrescribedDisplacement<2>> = parts
            .into_iter()
            .enumerate()
            .map(|(i, components)| PrescribedDisplacement {
                name: format!("part{i}"),
                facets: left.clone(),
                components,
                traction: None,
            })
            .collect();
        let dirichlet = DirichletConstraints::new(&space, &parts)?;
        check_rigid_motions(&space, &dirichlet)
    }

    #[test]
    fn clamped_or_fully_prescribed_sides_stop_every_rigid_motion() {
        square(vec![]).unwrap();
        square(vec![[zero(), zero()]]).unwrap();
    }

    #[test]
    fn a_roller_alone_leaves_the_translation_along_it_free() {
        // u_x = 0 on x = 0: translation along y free (rotation is stopped by u_x = −ω y)
        let message = square(vec![[zero(), None]]).unwrap_err().to_string();
        assert!(
            message.contains("translation along y") && message.contains("`part0`"),
            "{message}"
        );
        assert!(!message.contains("rotation"), "{message}");
        // u_y = 0 on x = 0: the translation along x and a rotation about a point of the side
        // are free
        let message = square(vec![[None, zero()]]).unwrap_err().to_string();
        assert!(
            message.contains("can move rigidly") && message.contains("`part0`"),
            "{message}"
        );
    }

    #[test]
    fn in_3d_a_clamped_face_stops_every_motion_and_a_roller_does_not() {
        let cube = Mesh::box_mesh(
            [0.0; 3],
            [1.0; 3],
            [2, 2, 2],
            [[Dirichlet, Neumann], [Neumann, Neumann], [Contact, Neumann]],
        )
        .unwrap();
        let space = LagrangeSpace::new(Arc::new(cube), 1).unwrap();
        let clamped = DirichletConstraints::new(&space, &[]).unwrap();
        check_rigid_motions(&space, &clamped).unwrap();
        // u_x = 0 on x = 0 stops the translation along x and the rotations about y and z; the
        // translations along y and z and the rotation about x stay free
        let face = space.mesh().boundary_facets_where(|x| x[0] == 0.0);
        let roller = PrescribedDisplacement {
            name: "roller".into(),
            facets: face,
            components: [zero(), None, None],
            traction: None,
        };
        let dirichlet = DirichletConstraints::new(&space, &[roller]).unwrap();
        let message = check_rigid_motions(&space, &dirichlet)
            .unwrap_err()
            .to_string();
        assert!(
            message.contains("can move rigidly") && message.contains("`roller`"),
            "{message}"
        );
        assert!(!message.contains("translation along x"), "{message}");
    }

    #[test]
    fn an_unconnected_floating_piece_is_named() {
        // two squares side by side without a shared vertex: the right one has no Γ1
        let mesh = Mesh::box_mesh(
            [0.0, 0.0],
            [1.0, 1.0],
            [2, 2],
            [[Dirichlet, Neumann], [Contact, Neumann]],
        )
        .unwrap();
        let mut vertices = mesh.vertices().to_vec();
        let shift = vertices.len();
        vertices.extend(mesh.vertices().iter().map(|x| [x[0] + 2.0, x[1]]));
        let mut cells: Vec<usize> = (0..mesh.num_cells())
            .flat_map(|c| mesh.cell(c).to_vec())
            .collect();
        cells.extend((0..mesh.num_cells()).flat_map(|c| mesh.cell(c).iter().map(|v| v + shift)));
        let mut facets: Vec<usize> = (0..mesh.num_facets())
            .flat_map(|f| mesh.facet(f).to_vec())
            .collect();
        facets.extend((0..mesh.num_facets()).flat_map(|f| mesh.facet(f).iter().map(|v| v + shift)));
        let mut parts: Vec<_> = (0..mesh.num_facets()).map(|f| mesh.facet_part(f)).collect();
        parts.extend((0..mesh.num_facets()).map(|f| match mesh.facet_part(f) {
            Dirichlet => Neumann,
            other => other,
        }));
        let two = Mesh::new(vertices, cells, facets, parts).unwrap();
        let space = LagrangeSpace::new(Arc::new(two), 1).unwrap();
        let dirichlet = DirichletConstraints::new(&space, &[]).unwrap();
        let message = check_rigid_motions(&space, &dirichlet)
            .unwrap_err()
            .to_string();
        assert!(
            message.contains("2 of 2 unconnected pieces") && message.contains("no clamped facet"),
            "{message}"
        );
    }
}
