//! The contact boundary Γ3 in discrete form: the nodal quadrature of the friction functional
//! j(u, w) of (3.14), nodal normals and tangent frames.
//!
//! The scheme integrates j with the **nodal rule**
//!
//! j_h(u, w) = Σ_a ω_a [ p_ν(u_ν(a) − g(a)) w_ν(a) + p_τ(u_ν(a) − g(a)) |w_τ(a)| ],
//! ω_a = ∫_Γ3 φ_a dΓ,
//!
//! over the nodes a of Γ3 (excluding Γ1, where w = 0). ω_a is the exact integral of the nodal
//! basis function: the trapezoidal rule for P1, Simpson's rule on P2 edges in 2D, and the
//! edge-midpoint rule on P2 triangles in 3D (whose vertex weights are zero). Each rule is exact
//! for polynomials of degree l on facets, so it does not lower the O(h^l) consistency of
//! the scheme. The normal ν_a is the measure-weighted mean of the normals of the Γ3 facets
//! around a (the facet normal on a flat part of Γ3). The rule makes j_h a sum of Euclidean
//! norms of nodal tangential velocities, which the velocity step (5.1) solves exactly.

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

impl<const D: usize> ContactNodes<D> {
    /// Collects the Γ3 nodes of `space`, their weights ω_a and frames.
    pub fn new(space: &LagrangeSpace<D>) -> Result<Self> {
        let mesh = space.mesh();
        let n_nodes = space.num_nodes();
        let mut clamped = vec![false; n_nodes];
        for node in space.boundary_nodes(BoundaryPart::Dirichlet) {
            clamped[node] = true;
        }
        let mut weights = vec![0.0; n_nodes];
        let mut normals = vec![SVector::<f64, D>::zeros(); n_nodes];
        let mut on_contact = vec![false; n_nodes];
        let rule = FacetRule::new(D, space.degree());
        let element = space.element();
        let n = element.num_nodes();
        let mut values = [0.0; crate::fem::element::MAX_CELL_NODES];
        for f in 0..mesh.num_facets() {
            if mesh.facet_part(f) != BoundaryPart::Contact {
                continue;
            }
            let cell = mesh.facet_cell(f);
            let geometry = space.geometry(cell);
            let measure = mesh.facet_measure(f);
            let normal = SVector::<f64, D>::from_column_slice(&mesh.facet_normal(f));
            let vertices: Vec<[f64; D]> = mesh.facet(f).iter().map(|&v| mesh.vertex(v)).collect();
            for &node in space.facet_nodes(f) {
                on_contact[node] = true;
                normals[node] += normal * measure;
            }
            for (bary, &weight) in rule.barycentric.iter().zip(&rule.weights) {
                let x: [f64; D] = std::array::from_fn(|i| {
                    bary.iter().zip(&vertices).map(|(l, p)| l * p[i]).sum()
                });
                element.values(&geometry.reference_point(&x), &mut values[..n]);
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
        };
        for node in 0..n_nodes {
            if !on_contact[node] || clamped[node] || weights[node] <= 1e-12 * scale {
                continue;
            }
            let norm = normals[node].norm();
            if norm == 0.0 {
                return Err(Error::InvalidMesh(format!(
                    "contact node {node} at {:?} has no well-defined normal (opposite Γ3 facets meet there)",
                    space.node(node)
                )));
            }
            result.index_of_node[node] = Some(result.nodes.len());
            result.nodes.push(node);
            result.weights.push(weights[node]);
            result
                .frames
                .push(frame_from_normal(&(normals[node] / norm)));
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
