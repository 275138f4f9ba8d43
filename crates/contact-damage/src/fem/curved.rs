//! Curved cells: the isoparametric P2 map of a simplex whose edges carry points off their
//! straight midpoints (a Gmsh second-order mesh, or the uniform refinement of one).
//!
//! A cell with vertices x_0, …, x_D and edge points x_e (e in
//! [`simplex_edges`](crate::fem::element::simplex_edges) order) is the image of the reference
//! simplex by the P2 Lagrange interpolant of those points,
//!
//! x(ξ) = Σ_a x_a φ_a(ξ),   J(ξ) = ∂x/∂ξ = Σ_a x_a ⊗ ∇̂φ_a(ξ),
//!
//! the map of the P2 element itself (isoparametric). Integrals over the cell are taken with
//! det J(ξ) at each quadrature point and gradients with J(ξ)^{-T}; the boundary facet is the
//! image of the reference facet, with its normal and measure from J (Nanson's formula). An
//! edge whose point is its straight midpoint gives back the affine map, so a mesh without
//! curved edges is treated exactly as before.

use crate::fem::element::{LagrangeElement, MAX_CELL_NODES};
use nalgebra::SMatrix;

/// The P2 map of one cell, from its geometry nodes (vertices, then edge points).
#[derive(Debug, Clone, Copy)]
pub struct CurvedMap<const D: usize> {
    nodes: [[f64; D]; MAX_CELL_NODES],
    count: usize,
}

impl<const D: usize> CurvedMap<D> {
    /// The map with geometry nodes `nodes` in P2 element order (D + 1 vertices, then the
    /// edge points).
    ///
    /// # Panics
    /// If `nodes` does not hold the (D + 1)(D + 2)/2 nodes of the P2 element.
    pub fn new(nodes: &[[f64; D]]) -> Self {
        let count = (D + 1) * (D + 2) / 2;
        assert_eq!(nodes.len(), count, "CurvedMap: P2 geometry nodes");
        let mut all = [[0.0; D]; MAX_CELL_NODES];
        all[..count].copy_from_slice(nodes);
        Self { nodes: all, count }
    }

    /// The geometry nodes (vertices, then edge points).
    pub fn nodes(&self) -> &[[f64; D]] {
        &self.nodes[..self.count]
    }

    fn element() -> LagrangeElement<D> {
        LagrangeElement::quadratic()
    }

    /// The physical point x(ξ).
    pub fn point(&self, xi: &[f64; D]) -> [f64; D] {
        let mut values = [0.0; MAX_CELL_NODES];
        Self::element().values(xi, &mut values[..self.count]);
        std::array::from_fn(|i| {
            self.nodes()
                .iter()
                .zip(&values)
                .map(|(node, value)| node[i] * value)
                .sum()
        })
    }

    /// The Jacobian J(ξ) (entry (i, j) = ∂x_i/∂ξ_j).
    pub fn jacobian(&self, xi: &[f64; D]) -> SMatrix<f64, D, D> {
        let mut gradients = [[0.0; D]; MAX_CELL_NODES];
        Self::element().gradients(xi, &mut gradients[..self.count]);
        let mut jacobian = SMatrix::<f64, D, D>::zeros();
        for (node, gradient) in self.nodes().iter().zip(&gradients) {
            for i in 0..D {
                for j in 0..D {
                    jacobian[(i, j)] += node[i] * gradient[j];
                }
            }
        }
        jacobian
    }

    /// Reference points where a cell map is checked for inversion: the P2 nodes and the
    /// points of the degree-4 rule (det J of a P2 map is a polynomial of degree D, sampled
    /// there, not bounded: an inversion between these points is not detected).
    pub fn check_points() -> Vec<[f64; D]> {
        let mut points = Self::element().reference_nodes();
        points.extend(crate::fem::quadrature::QuadratureRule::<D>::simplex(4).points);
        points
    }

    /// The reference point of the physical point x (Newton on x(ξ) = x from the centroid),
    /// or None when Newton does not converge in 20 iterations.
    pub fn reference_point(&self, x: &[f64; D]) -> Option<[f64; D]> {
        let mut xi = [1.0 / (D as f64 + 1.0); D];
        let scale = self
            .nodes()
            .iter()
            .flat_map(|node| node.iter())
            .fold(0.0f64, |m, v| m.max(v.abs()))
            .max(1.0);
        for _ in 0..20 {
            let point = self.point(&xi);
            let residual = nalgebra::SVector::<f64, D>::from_fn(|i, _| x[i] - point[i]);
            if residual.norm() <= 1e-14 * scale {
                return Some(xi);
            }
            let step = self.jacobian(&xi).try_inverse()? * residual;
            for (value, delta) in xi.iter_mut().zip(step.iter()) {
                *value += delta;
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The P2 map of a cell whose edge points are the midpoints is the affine map.
    #[test]
    fn straight_edges_give_the_affine_map() {
        let vertices = [[0.3, 0.1], [2.0, 0.4], [0.7, 1.9]];
        let mid = |a: usize, b: usize| -> [f64; 2] {
            std::array::from_fn(|i| 0.5 * (vertices[a][i] + vertices[b][i]))
        };
        let map = CurvedMap::new(&[
            vertices[0],
            vertices[1],
            vertices[2],
            mid(0, 1),
            mid(1, 2),
            mid(0, 2),
        ]);
        let affine = SMatrix::<f64, 2, 2>::from_fn(|i, j| vertices[j + 1][i] - vertices[0][i]);
        for xi in [[0.2, 0.3], [0.0, 1.0], [0.6, 0.1]] {
            assert!((map.jacobian(&xi) - affine).norm() < 1e-14);
            let x = map.point(&xi);
            let expected = [
                vertices[0][0] + affine[(0, 0)] * xi[0] + affine[(0, 1)] * xi[1],
                vertices[0][1] + affine[(1, 0)] * xi[0] + affine[(1, 1)] * xi[1],
            ];
            assert!((x[0] - expected[0]).abs() + (x[1] - expected[1]).abs() < 1e-14);
            let back = map.reference_point(&x).unwrap();
            assert!((back[0] - xi[0]).abs() + (back[1] - xi[1]).abs() < 1e-13);
        }
    }

    /// A triangle with one edge on the unit circle: the map sends the reference edge's nodes
    /// to the circle, and the cell's area (∫ det J) matches the exact area of the curved
    /// triangle to the accuracy of the quadratic arc.
    #[test]
    fn curved_triangle_area_converges_like_the_arc() {
        let area_error = |angle: f64| -> f64 {
            let (a, b) = ([1.0, 0.0], [angle.cos(), angle.sin()]);
            let half = [(0.5 * angle).cos(), (0.5 * angle).sin()];
            let map = CurvedMap::new(&[
                [0.0, 0.0],
                a,
                b,
                [0.5 * a[0], 0.5 * a[1]],
                half,
                [0.5 * b[0], 0.5 * b[1]],
            ]);
            let rule = crate::fem::quadrature::QuadratureRule::<2>::simplex(6);
            let area: f64 = rule
                .points
                .iter()
                .zip(&rule.weights)
                .map(|(xi, w)| w * map.jacobian(xi).determinant())
                .sum();
            (area - 0.5 * angle).abs()
        };
        let (coarse, fine) = (area_error(0.4), area_error(0.2));
        // the sector minus the P2 arc: O(angle^5) per cell
        let rate = (coarse / fine).log2();
        assert!(rate > 4.8 && rate < 5.2, "area error rate {rate}");
    }
}
