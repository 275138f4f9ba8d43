//! The contact boundary Γ3 in discrete form: the nodal quadrature of the friction functional
//! j(u, w) of (3.14), nodal normals and tangent frames.
//!
//! The scheme integrates j with the **nodal rule**
//!
//! j_h(u, w) = Σ_a ω_a [ p_ν(u_ν(a) − g(a)) w_ν(a) + p_τ(u_ν(a) − g(a)) |w_τ(a)| ],
//! ω_a = ∫_Γ3 φ_a dΓ,
//!
//! over the nodes a of Γ3 (excluding the nodes where Γ1 fixes w, see below). ω_a is the exact
//! integral of the nodal
//! basis function: the trapezoidal rule for P1, Simpson's rule on P2 edges in 2D, and the
//! edge-midpoint rule on P2 triangles in 3D (whose vertex weights are zero). Each rule is exact
//! for polynomials of degree l on facets, so it does not lower the O(h^l) consistency of
//! the scheme. The normal ν_a is the measure-weighted mean of the normals of the Γ3 facets
//! around a (the facet normal on a flat part of Γ3). The rule makes j_h a sum of Euclidean
//! norms of nodal tangential velocities, which the velocity step (5.1) solves exactly.
//!
//! **Where Γ1 meets Γ3.** A node of Γ3 that also lies on Γ1 keeps the contact rule when the
//! components Γ1 fixes there are tangential to Γ3: a roller or symmetry plane that cuts the
//! contact zone (the plane x = 0 of a half model fixes u_x, and the contact normal lies in the
//! plane). Its normal is the Γ3 normal with the fixed Cartesian components removed, which is the
//! mean normal of the mirrored, whole body; its frame has the fixed axes ±e_i as tangent columns,
//! so that the constraint is a constraint on a component of the contact frame. The node leaves
//! Γ3 when every component is fixed (a clamp) or when the fixed components carry more than half
//! of the normal's length (|ν_free| < |ν|/√2: the constraint acts on the normal displacement,
//! and contact there is carried by Γ1).

use crate::error::{Error, Result};
use crate::fem::mesh::BoundaryPart;
use crate::fem::space::{FacetRule, LagrangeSpace};
use nalgebra::{SMatrix, SVector};

/// Contact nodes of Γ3 with their quadrature weights and orthonormal frames.
#[derive(Debug, Clone)]
pub struct ContactNodes<const D: usize> {
    /// Global node indices (nodes with ω_a > 0 not on Γ1).
    pub nodes: Vec<usize>,
    /// ω_a = ∫_Γ3 φ_a dΓ.
    pub weights: Vec<f64>,
    /// Frames R_a with columns (ν_a, t_1, …, t_{D−1}); ν_a the outward unit normal.
    pub frames: Vec<SMatrix<f64, D, D>>,
    /// For each global node: its index in `nodes`, if any.
    pub index_of_node: Vec<Option<usize>>,
    /// The nodes of Γ3 (ω_a > 0) taken out of the contact rule because their fixed components
    /// carry more than half of the normal (a roller across Γ3, not along it), with the Γ3
    /// normal there: a prescribed normal displacement replaces contact at those nodes.
    pub normal_fixed: Vec<(usize, SVector<f64, D>)>,
}

/// An orthonormal frame whose first column is the unit vector `normal`.
pub fn frame_from_normal<const D: usize>(normal: &SVector<f64, D>) -> SMatrix<f64, D, D> {
    let mut frame = SMatrix::<f64, D, D>::zeros();
    frame.set_column(0, normal);
    if D == 2 {
        frame[(0, 1)] = -normal[1];
        frame[(1, 1)] = normal[0];
    } else if D == 3 {
        let axis = (0..3)
            .min_by(|&i, &j| normal[i].abs().total_cmp(&normal[j].abs()))
            .unwrap_or(0);
        let mut e = SVector::<f64, 3>::zeros();
        e[axis] = 1.0;
        let n3 = SVector::<f64, 3>::new(normal[0], normal[1], normal[2]);
        let t1 = e.cross(&n3).normalize();
        let t2 = n3.cross(&t1);
        for i in 0..3 {
            frame[(i, 1)] = t1[i];
            frame[(i, 2)] = t2[i];
        }
    }
    frame
}

/// The frame of a contact node where Γ1 fixes the Cartesian axes `fixed` (not all of them):
/// columns (ν, e_i for each fixed axis i in increasing order, then the free tangent in 3D with
/// one fixed axis, ν × e_i). `normal` is a unit vector with zero components on the fixed axes,
/// so the columns are orthonormal and each fixed axis is exactly one column.
pub fn frame_with_fixed_axes<const D: usize>(
    normal: &SVector<f64, D>,
    fixed: &[bool; D],
) -> SMatrix<f64, D, D> {
    let mut frame = SMatrix::<f64, D, D>::zeros();
    frame.set_column(0, normal);
    let mut column = 1;
    for (i, _) in fixed.iter().enumerate().filter(|(_, &f)| f) {
        frame[(i, column)] = 1.0;
        column += 1;
    }
    if column < D {
        // 3D with one fixed axis i: the free tangent ν × e_i (unit, ⟂ ν and e_i)
        let i = fixed.iter().position(|&f| f).unwrap_or(0);
        let (j, k) = ((i + 1) % 3, (i + 2) % 3);
        // (ν × e_i)_j = ν_k, (ν × e_i)_k = −ν_j, (ν × e_i)_i = 0
        frame[(j, column)] = normal[k];
        frame[(k, column)] = -normal[j];
    }
    frame
}

/// The system component of a contact frame that is the fixed Cartesian axis `axis` (its column
/// ±e_axis), if any: where the constraint of Γ1 acts in the contact frame.
pub fn fixed_axis_column<const D: usize>(frame: &SMatrix<f64, D, D>, axis: usize) -> Option<usize> {
    (1..D).find(|&column| frame[(axis, column)].abs() == 1.0)
}

impl<const D: usize> ContactNodes<D> {
    /// Collects the Γ3 nodes of `space`, their weights ω_a and frames, with every component of
    /// every node of Γ1 fixed (the paper's clamp u = 0 on Γ1, (2.5)): no node of Γ1 is a contact
    /// node.
    pub fn new(space: &LagrangeSpace<D>) -> Result<Self> {
        let mut constrained = vec![false; space.num_nodes() * D];
        for node in space.boundary_nodes(BoundaryPart::Dirichlet) {
            constrained[node * D..node * D + D].fill(true);
        }
        Self::with_constraints(space, &constrained)
    }

    /// Collects the Γ3 nodes of `space` given the fixed Cartesian components of Γ1
    /// (`constrained`, node-major): a Γ3 node with fixed components stays a contact node when
    /// they are tangential (see the module documentation), with its normal projected off the
    /// fixed axes and those axes in its frame.
    pub fn with_constraints(space: &LagrangeSpace<D>, constrained: &[bool]) -> Result<Self> {
        let mesh = space.mesh();
        let n_nodes = space.num_nodes();
        if constrained.len() != n_nodes * D {
            return Err(Error::InvalidInput(format!(
                "{} constraint flags for {} unknowns",
                constrained.len(),
                n_nodes * D
            )));
        }
        let mut weights = vec![0.0; n_nodes];
        let mut normals = vec![SVector::<f64, D>::zeros(); n_nodes];
        let mut on_contact = vec![false; n_nodes];
        let rule = FacetRule::new(D, space.degree());
        let node_rule = FacetRule::facet_nodes(D, space.degree());
        let element = space.element();
        let n = element.num_nodes();
        let mut values = [0.0; crate::fem::element::MAX_CELL_NODES];
        for f in 0..mesh.num_facets() {
            if mesh.facet_part(f) != BoundaryPart::Contact {
                continue;
            }
            let cell = mesh.facet_cell(f);
            let points = space.facet_quadrature(f, &rule);
            if space.curved_map(cell).is_none() {
                let measure = mesh.facet_measure(f);
                let normal = SVector::<f64, D>::from_column_slice(&mesh.facet_normal(f));
                for &node in space.facet_nodes(f) {
                    on_contact[node] = true;
                    normals[node] += normal * measure;
                }
            } else {
                // a curved facet: the normal of the P2 map at each node, weighted by the
                // facet's measure
                let measure: f64 = points.iter().map(|p| p.weight * p.measure).sum();
                let at_nodes = space.facet_quadrature(f, &node_rule);
                for (&node, point) in space.facet_nodes(f).iter().zip(&at_nodes) {
                    on_contact[node] = true;
                    normals[node] += SVector::<f64, D>::from_column_slice(&point.normal) * measure;
                }
            }
            for point in &points {
                let (weight, measure) = (point.weight, point.measure);
                element.values(&point.reference, &mut values[..n]);
                for &node in space.facet_nodes(f) {
                    let local = space
                        .cell_nodes(cell)
                        .iter()
                        .position(|&m| m == node)
                        .ok_or_else(|| {
                            Error::InvalidMesh(format!(
                                "facet {f} node {node} is not a node of its cell {cell}"
                            ))
                        })?;
                    weights[node] += weight * measure * values[local];
                }
            }
        }
        let scale = mesh.max_cell_diameter().powi(D as i32 - 1);
        let mut result = Self {
            nodes: Vec::new(),
            weights: Vec::new(),
            frames: Vec::new(),
            index_of_node: vec![None; n_nodes],
            normal_fixed: Vec::new(),
        };
        for node in 0..n_nodes {
            if !on_contact[node] || weights[node] <= 1e-12 * scale {
                continue;
            }
            let fixed: [bool; D] = std::array::from_fn(|i| constrained[node * D + i]);
            if fixed.iter().all(|&f| f) {
                continue;
            }
            let norm = normals[node].norm();
            if norm == 0.0 {
                return Err(Error::InvalidMesh(format!(
                    "contact node {node} at {:?} has no well-defined normal (opposite Γ3 facets meet there)",
                    space.node(node)
                )));
            }
            let frame = if fixed.contains(&true) {
                let mut free = normals[node];
                for (i, &f) in fixed.iter().enumerate() {
                    if f {
                        free[i] = 0.0;
                    }
                }
                let free_norm = free.norm();
                if free_norm < norm * std::f64::consts::FRAC_1_SQRT_2 {
                    result.normal_fixed.push((node, normals[node] / norm));
                    continue;
                }
                frame_with_fixed_axes(&(free / free_norm), &fixed)
            } else {
                frame_from_normal(&(normals[node] / norm))
            };
            result.index_of_node[node] = Some(result.nodes.len());
            result.nodes.push(node);
            result.weights.push(weights[node]);
            result.frames.push(frame);
        }
        Ok(result)
    }

    /// Number of contact nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// True when Γ3 carries no node with positive weight.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Outward normal ν_a of contact node number `k`.
    pub fn normal(&self, k: usize) -> SVector<f64, D> {
        self.frames[k].column(0).into_owned()
    }
}

/// State of a contact node in a step of (5.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ContactStatus {
    /// u_ν < g: no normal pressure, no friction.
    Separated,
    /// In contact with a positive friction bound and zero tangential velocity.
    Stick,
    /// In contact with a nonzero tangential velocity (or frictionless contact).
    Slip,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::mesh::Mesh;
    use std::sync::Arc;
    use BoundaryPart::*;

    #[test]
    fn frames_are_orthonormal_with_normal_first() {
        let normal = SVector::<f64, 3>::new(0.2, -0.5, 0.7).normalize();
        let frame = frame_from_normal(&normal);
        assert!((frame.transpose() * frame - SMatrix::<f64, 3, 3>::identity()).norm() < 1e-14);
        assert!((frame.column(0) - normal).norm() < 1e-15);
        assert!(frame.determinant() > 0.0);
    }

    #[test]
    fn nodal_weights_sum_to_contact_measure() {
        for degree in [1, 2] {
            let mesh = Arc::new(
                Mesh::box_mesh(
                    [0.0, 0.0],
                    [2.0, 1.0],
                    [4, 3],
                    [[Dirichlet, Neumann], [Contact, Neumann]],
                )
                .unwrap(),
            );
            let space = LagrangeSpace::new(mesh, degree).unwrap();
            let contact = ContactNodes::new(&space).unwrap();
            // the clamped corner node (0, 0) is excluded: its weight is h/2 (P1) or h/6 (P2) of the element
            let excluded = if degree == 1 { 0.25 } else { 0.5 / 6.0 };
            let total: f64 = contact.weights.iter().sum();
            assert!(
                (total - (2.0 - excluded)).abs() < 1e-13,
                "degree {degree}: {total}"
            );
            for k in 0..contact.len() {
                assert!((contact.normal(k) - SVector::<f64, 2>::new(0.0, -1.0)).norm() < 1e-15);
            }
        }
        let cube = Arc::new(
            Mesh::box_mesh(
                [0.0; 3],
                [1.0; 3],
                [2, 2, 2],
                [[Dirichlet, Neumann], [Neumann, Neumann], [Contact, Neumann]],
            )
            .unwrap(),
        );
        let space = LagrangeSpace::new(cube, 2).unwrap();
        let contact = ContactNodes::new(&space).unwrap();
        // P2 on triangles: vertex weights vanish, only edge midpoints carry weight
        for &node in &contact.nodes {
            let p = space.node(node);
            let on_vertex = p
                .iter()
                .all(|v| ((v * 2.0).round() - v * 2.0).abs() < 1e-12);
            assert!(
                !on_vertex,
                "vertex node {node} at {p:?} should have zero weight"
            );
        }
    }
}
