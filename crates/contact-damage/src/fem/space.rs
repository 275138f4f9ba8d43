//! Continuous Lagrange finite element spaces X^h of degree l ∈ {1, 2} on a simplicial mesh
//! (paper §5): global node numbering (vertices, then edge midpoints for l = 2), cell and facet
//! node maps, the interpolant Π^h, and evaluation of fields and gradients inside cells.

use crate::error::{Error, Result};
use crate::fem::curved::CurvedMap;
use crate::fem::element::{simplex_edges, LagrangeElement};
use crate::fem::mesh::{BoundaryPart, Mesh};
use crate::fem::quadrature::QuadratureRule;
use nalgebra::{SMatrix, SVector};
use std::collections::HashMap;
use std::sync::Arc;

/// Reference-to-physical geometry of one cell: x = origin + J ξ.
#[derive(Debug, Clone, Copy)]
pub struct CellGeometry<const D: usize> {
    /// x_0, the image of ξ = 0.
    pub origin: SVector<f64, D>,
    /// The Jacobian J.
    pub jacobian: SMatrix<f64, D, D>,
    /// J^{-T}: maps reference gradients to physical gradients.
    pub inverse_transpose: SMatrix<f64, D, D>,
    /// |det J| (= D! × cell volume).
    pub det: f64,
}

impl<const D: usize> CellGeometry<D> {
    /// The geometry with Jacobian `jacobian` whose map sends ξ to `point`: the affine map
    /// itself, or the tangent map of a curved cell at ξ. None when J is singular.
    pub fn from_jacobian(
        xi: &[f64; D],
        point: &[f64; D],
        jacobian: SMatrix<f64, D, D>,
    ) -> Option<Self> {
        let inverse_transpose = jacobian.try_inverse()?.transpose();
        let origin = SVector::<f64, D>::from_column_slice(point)
            - jacobian * SVector::<f64, D>::from_column_slice(xi);
        Some(CellGeometry {
            origin,
            jacobian,
            inverse_transpose,
            det: crate::fem::mesh::determinant(&jacobian).abs(),
        })
    }

    /// Physical point of the reference point ξ.
    pub fn point(&self, xi: &[f64; D]) -> [f64; D] {
        let x = self.origin + self.jacobian * SVector::<f64, D>::from_column_slice(xi);
        std::array::from_fn(|i| x[i])
    }

    /// Reference point of the physical point x.
    pub fn reference_point(&self, x: &[f64; D]) -> [f64; D] {
        let xi = self.inverse_transpose.transpose()
            * (SVector::<f64, D>::from_column_slice(x) - self.origin);
        std::array::from_fn(|i| xi[i])
    }
}

/// Basis values and reference gradients of an element tabulated at the points of a rule.
#[derive(Debug, Clone)]
pub struct Tabulation<const D: usize> {
    /// Quadrature weights on the reference cell.
    pub weights: Vec<f64>,
    /// Reference points.
    pub points: Vec<[f64; D]>,
    /// values[q * n + a] = φ_a(ξ_q).
    pub values: Vec<f64>,
    /// gradients[q * n + a] = ∇̂φ_a(ξ_q).
    pub gradients: Vec<SVector<f64, D>>,
    /// Number of element nodes n.
    pub nodes: usize,
}

impl<const D: usize> Tabulation<D> {
    /// Tabulates `element` at reference points with weights.
    pub fn new(element: &LagrangeElement<D>, points: Vec<[f64; D]>, weights: Vec<f64>) -> Self {
        let nodes = element.num_nodes();
        let mut values = vec![0.0; points.len() * nodes];
        let mut grads = vec![[0.0; D]; nodes];
        let mut gradients = Vec::with_capacity(points.len() * nodes);
        for (q, xi) in points.iter().enumerate() {
            element.values(xi, &mut values[q * nodes..(q + 1) * nodes]);
            element.gradients(xi, &mut grads);
            gradients.extend(
                grads
                    .iter()
                    .map(|g| SVector::<f64, D>::from_column_slice(g)),
            );
        }
        Self {
            weights,
            points,
            values,
            gradients,
            nodes,
        }
    }

    /// Tabulates `element` at the points of a cell quadrature rule.
    pub fn cell_rule(element: &LagrangeElement<D>, rule: &QuadratureRule<D>) -> Self {
        Self::new(element, rule.points.clone(), rule.weights.clone())
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.weights.len()
    }

    /// True when there are no points.
    pub fn is_empty(&self) -> bool {
        self.weights.is_empty()
    }
}

/// Quadrature on a (D−1)-simplex facet in barycentric form: a point is Σ_i λ_i X_i over the facet
/// vertices X_i; weights sum to 1 (multiply by the facet measure).
#[derive(Debug, Clone)]
pub struct FacetRule {
    /// Barycentric coordinates (D per point).
    pub barycentric: Vec<Vec<f64>>,
    /// Normalized weights (sum 1).
    pub weights: Vec<f64>,
}

impl FacetRule {
    /// A rule exact to `degree` on facets of a mesh of dimension `dim` ∈ {2, 3}.
    pub fn new(dim: usize, degree: usize) -> Self {
        fn from_rule<const M: usize>(rule: QuadratureRule<M>) -> FacetRule {
            let total: f64 = rule.weights.iter().sum();
            FacetRule {
                barycentric: rule
                    .points
                    .iter()
                    .map(|p| {
                        let mut b = vec![1.0 - p.iter().sum::<f64>()];
                        b.extend_from_slice(p);
                        b
                    })
                    .collect(),
                weights: rule.weights.iter().map(|w| w / total).collect(),
            }
        }
        match dim {
            2 => from_rule(QuadratureRule::<1>::simplex(degree)),
            _ => from_rule(QuadratureRule::<2>::simplex(degree)),
        }
    }

    /// The nodes of a facet of the Lagrange element of `degree` on a mesh of dimension `dim`,
    /// in [`LagrangeSpace::facet_nodes`] order (vertices, then edge midpoints), each with
    /// weight 1: to evaluate normals or fields at the nodes.
    pub fn facet_nodes(dim: usize, degree: usize) -> Self {
        let vertex =
            |k: usize| -> Vec<f64> { (0..dim).map(|i| f64::from(u8::from(i == k))).collect() };
        let mut barycentric: Vec<Vec<f64>> = (0..dim).map(vertex).collect();
        if degree == 2 {
            for &[a, b] in simplex_edges(dim - 1) {
                barycentric.push(
                    (0..dim)
                        .map(|i| if i == a || i == b { 0.5 } else { 0.0 })
                        .collect(),
                );
            }
        }
        let weights = vec![1.0; barycentric.len()];
        FacetRule {
            barycentric,
            weights,
        }
    }
}

/// A continuous Lagrange space X^h of degree 1 or 2 on a mesh.
#[derive(Debug, Clone)]
pub struct LagrangeSpace<const D: usize> {
    mesh: Arc<Mesh<D>>,
    element: LagrangeElement<D>,
    nodes: Vec<[f64; D]>,
    cell_nodes: Vec<usize>,
    facet_nodes: Vec<usize>,
    facet_node_count: usize,
    geometry: Vec<CellGeometry<D>>,
    /// For each cell, its index in `curved_maps`, or `u32::MAX` when the cell is affine (empty
    /// when no cell is curved or l = 1).
    curved_index: Vec<u32>,
    /// The P2 maps of the curved cells ([`crate::fem::curved`]).
    curved_maps: Vec<CurvedMap<D>>,
}

/// One point of a facet rule on a boundary facet, with what integrals over the facet need.
#[derive(Debug, Clone, Copy)]
pub struct FacetQuadraturePoint<const D: usize> {
    /// The physical point.
    pub point: [f64; D],
    /// Its reference coordinates in the facet's cell.
    pub reference: [f64; D],
    /// The outward unit normal there.
    pub normal: [f64; D],
    /// The rule's normalized weight (the weights of a rule sum to 1).
    pub weight: f64,
    /// The facet measure (straight facet) or the density of the curved facet's measure with
    /// respect to the normalized rule there: the point's share of ∫_F g ds is
    /// g × weight × measure.
    pub measure: f64,
}

impl<const D: usize> LagrangeSpace<D> {
    /// Builds the global node numbering: the mesh vertices first, then (degree 2) one node at the
    /// midpoint of each edge, or at its point when the edge is curved (the cells with a curved
    /// edge are then mapped isoparametrically; at degree 1 every cell is affine). Cell-local order follows [`LagrangeElement::reference_nodes`];
    /// facet-local order is the facet vertices, then the facet edges in
    /// [`simplex_edges`]`(D − 1)` order.
    pub fn new(mesh: Arc<Mesh<D>>, degree: usize) -> Result<Self> {
        let element = LagrangeElement::<D>::new(degree)?;
        let mut nodes: Vec<[f64; D]> = mesh.vertices().to_vec();
        let n_local = element.num_nodes();
        let mut cell_nodes = Vec::with_capacity(mesh.num_cells() * n_local);
        let mut edge_index: HashMap<(usize, usize), usize> = HashMap::new();
        for c in 0..mesh.num_cells() {
            let cell = mesh.cell(c);
            cell_nodes.extend_from_slice(cell);
            if degree == 2 {
                for edge in simplex_edges(D) {
                    let (a, b) = (cell[edge[0]], cell[edge[1]]);
                    let key = (a.min(b), a.max(b));
                    let next = nodes.len();
                    let id = *edge_index.entry(key).or_insert(next);
                    if id == next {
                        nodes.push(mesh.edge_point(a, b));
                    }
                    cell_nodes.push(id);
                }
            }
        }
        let facet_node_count = if degree == 1 { D } else { D + D * (D - 1) / 2 };
        let mut facet_nodes = Vec::with_capacity(mesh.num_facets() * facet_node_count);
        for f in 0..mesh.num_facets() {
            let facet = mesh.facet(f);
            facet_nodes.extend_from_slice(facet);
            if degree == 2 {
                for edge in simplex_edges(D - 1) {
                    let (a, b) = (facet[edge[0]], facet[edge[1]]);
                    let id = edge_index
                        .get(&(a.min(b), a.max(b)))
                        .copied()
                        .ok_or_else(|| {
                            Error::InvalidMesh(format!(
                                "boundary facet {f} has an edge ({a}, {b}) that belongs to no cell"
                            ))
                        })?;
                    facet_nodes.push(id);
                }
            }
        }
        let geometry = (0..mesh.num_cells())
            .map(|c| {
                let (origin, jacobian) = mesh.cell_map(c);
                CellGeometry::from_jacobian(&[0.0; D], &origin, jacobian)
                    .ok_or_else(|| Error::InvalidMesh(format!("cell {c} has a singular Jacobian")))
            })
            .collect::<Result<Vec<_>>>()?;
        let mut curved_index = Vec::new();
        let mut curved_maps = Vec::new();
        if degree == 2 && mesh.has_curved_edges() {
            curved_index = vec![u32::MAX; mesh.num_cells()];
            for (c, index) in curved_index.iter_mut().enumerate() {
                if mesh.is_cell_curved(c) {
                    *index = u32::try_from(curved_maps.len()).map_err(|_| {
                        Error::InvalidMesh("more than 2^32 curved cells".to_string())
                    })?;
                    curved_maps.push(mesh.curved_map(c));
                }
            }
        }
        Ok(Self {
            mesh,
            element,
            nodes,
            cell_nodes,
            facet_nodes,
            facet_node_count,
            geometry,
            curved_index,
            curved_maps,
        })
    }

    /// The P2 map of cell c when it is curved (degree 2 on a mesh with curved edges).
    pub fn curved_map(&self, c: usize) -> Option<&CurvedMap<D>> {
        match self.curved_index.get(c) {
            Some(&index) if index != u32::MAX => Some(&self.curved_maps[index as usize]),
            _ => None,
        }
    }

    /// Whether some cell is mapped isoparametrically.
    pub fn has_curved_cells(&self) -> bool {
        !self.curved_maps.is_empty()
    }

    /// Geometry of cell c at the reference point ξ: the affine geometry of an affine cell
    /// ([`LagrangeSpace::geometry`]), the tangent map of the P2 map at ξ for a curved cell.
    #[inline]
    pub fn geometry_at(&self, c: usize, xi: &[f64; D]) -> CellGeometry<D> {
        match self.curved_map(c) {
            None => self.geometry[c],
            Some(map) => self.curved_geometry(c, map, xi),
        }
    }

    #[cold]
    fn curved_geometry(&self, c: usize, map: &CurvedMap<D>, xi: &[f64; D]) -> CellGeometry<D> {
        // The map was checked at construction (Mesh::with_curved_edges); a singular J between
        // the checked points falls back to the affine geometry rather than to NaN.
        CellGeometry::from_jacobian(xi, &map.point(xi), map.jacobian(xi))
            .unwrap_or(self.geometry[c])
    }

    /// The physical point of the reference point ξ of cell c (through the P2 map of a curved
    /// cell).
    pub fn point_at(&self, c: usize, xi: &[f64; D]) -> [f64; D] {
        match self.curved_map(c) {
            None => self.geometry[c].point(xi),
            Some(map) => map.point(xi),
        }
    }

    /// The points of `rule` on boundary facet f: physical and cell-reference coordinates,
    /// outward normal, weight and measure (see [`FacetQuadraturePoint`]). A straight facet has
    /// one normal and its measure at every point; a facet of a curved cell has the normal and
    /// measure density of the P2 map at each point (Nanson's formula through J(ξ)).
    pub fn facet_quadrature(&self, f: usize, rule: &FacetRule) -> Vec<FacetQuadraturePoint<D>> {
        let mesh = &self.mesh;
        let cell = mesh.facet_cell(f);
        let straight_normal = mesh.facet_normal(f);
        let Some(map) = self.curved_map(cell) else {
            let geometry = &self.geometry[cell];
            let measure = mesh.facet_measure(f);
            let vertices: Vec<[f64; D]> = mesh.facet(f).iter().map(|&v| mesh.vertex(v)).collect();
            return rule
                .barycentric
                .iter()
                .zip(&rule.weights)
                .map(|(bary, &weight)| {
                    let point: [f64; D] = std::array::from_fn(|i| {
                        bary.iter().zip(&vertices).map(|(l, p)| l * p[i]).sum()
                    });
                    FacetQuadraturePoint {
                        point,
                        reference: geometry.reference_point(&point),
                        normal: straight_normal,
                        weight,
                        measure,
                    }
                })
                .collect();
        };
        // reference coordinates of the facet's vertices in its cell
        let reference_vertices: Vec<[f64; D]> = mesh
            .facet(f)
            .iter()
            .map(|v| {
                let local = mesh.cell(cell).iter().position(|w| w == v).unwrap_or(0);
                std::array::from_fn(|k| if k + 1 == local { 1.0 } else { 0.0 })
            })
            .collect();
        rule.barycentric
            .iter()
            .zip(&rule.weights)
            .map(|(bary, &weight)| {
                let reference: [f64; D] = std::array::from_fn(|i| {
                    bary.iter()
                        .zip(&reference_vertices)
                        .map(|(l, p)| l * p[i])
                        .sum()
                });
                let jacobian = map.jacobian(&reference);
                let tangent = |k: usize| -> SVector<f64, D> {
                    let direction = SVector::<f64, D>::from_fn(|i, _| {
                        reference_vertices[k][i] - reference_vertices[0][i]
                    });
                    jacobian * direction
                };
                // the normal direction and the density of the facet measure with respect to
                // the normalized rule (whose parameter simplex has measure 1 in 2D, 1/2 in 3D)
                let (mut normal, measure) = if D == 2 {
                    let t = tangent(1);
                    let n = SVector::<f64, D>::from_fn(|i, _| if i == 0 { t[1] } else { -t[0] });
                    let length = n.norm();
                    (n / length, length)
                } else {
                    let (a, b) = (tangent(1), tangent(2));
                    let n = SVector::<f64, D>::from_fn(|i, _| {
                        let (j, k) = ((i + 1) % 3, (i + 2) % 3);
                        a[j] * b[k] - a[k] * b[j]
                    });
                    let area = n.norm();
                    (n / area, 0.5 * area)
                };
                let straight = SVector::<f64, D>::from_column_slice(&straight_normal);
                if normal.dot(&straight) < 0.0 {
                    normal = -normal;
                }
                FacetQuadraturePoint {
                    point: map.point(&reference),
                    reference,
                    normal: std::array::from_fn(|i| normal[i]),
                    weight,
                    measure,
                }
            })
            .collect()
    }

    /// The mesh.
    pub fn mesh(&self) -> &Arc<Mesh<D>> {
        &self.mesh
    }
    /// The reference element.
    pub fn element(&self) -> &LagrangeElement<D> {
        &self.element
    }
    /// Polynomial degree l.
    pub fn degree(&self) -> usize {
        self.element.degree()
    }
    /// Number of scalar nodes (= dim X^h).
    pub fn num_nodes(&self) -> usize {
        self.nodes.len()
    }
    /// Coordinates of node i.
    pub fn node(&self, i: usize) -> [f64; D] {
        self.nodes[i]
    }
    /// All node coordinates.
    pub fn nodes(&self) -> &[[f64; D]] {
        &self.nodes
    }
    /// Number of nodes per cell.
    pub fn nodes_per_cell(&self) -> usize {
        self.element.num_nodes()
    }
    /// Global nodes of cell c, in reference order.
    pub fn cell_nodes(&self, c: usize) -> &[usize] {
        let n = self.element.num_nodes();
        &self.cell_nodes[c * n..(c + 1) * n]
    }
    /// Number of nodes per boundary facet.
    pub fn nodes_per_facet(&self) -> usize {
        self.facet_node_count
    }
    /// Global nodes of boundary facet f (vertices, then edge midpoints).
    pub fn facet_nodes(&self, f: usize) -> &[usize] {
        let n = self.facet_node_count;
        &self.facet_nodes[f * n..(f + 1) * n]
    }
    /// Affine geometry of cell c (of its straight simplex); a curved cell's geometry changes
    /// from point to point: [`LagrangeSpace::geometry_at`].
    pub fn geometry(&self, c: usize) -> &CellGeometry<D> {
        &self.geometry[c]
    }

    /// Nodes lying on boundary facets of the given part.
    pub fn boundary_nodes(&self, part: BoundaryPart) -> Vec<usize> {
        let mut marked = vec![false; self.num_nodes()];
        for f in 0..self.mesh.num_facets() {
            if self.mesh.facet_part(f) == part {
                for &n in self.facet_nodes(f) {
                    marked[n] = true;
                }
            }
        }
        (0..self.num_nodes()).filter(|&n| marked[n]).collect()
    }

    /// Interpolant Π^h of a scalar function: nodal values.
    pub fn interpolate_scalar(&self, f: impl Fn(&[f64; D]) -> f64) -> Vec<f64> {
        self.nodes.iter().map(f).collect()
    }

    /// Interpolant Π^h of a vector function: nodal values, node-major (node·D + component).
    pub fn interpolate_vector(&self, f: impl Fn(&[f64; D]) -> [f64; D]) -> Vec<f64> {
        self.nodes.iter().flat_map(f).collect()
    }

    /// Value and physical gradient at reference point ξ of cell c of the scalar field with the
    /// given nodal values.
    pub fn eval_scalar(&self, c: usize, xi: &[f64; D], nodal: &[f64]) -> (f64, SVector<f64, D>) {
        let n = self.element.num_nodes();
        let mut values = [0.0; crate::fem::element::MAX_CELL_NODES];
        let mut grads = [[0.0; D]; crate::fem::element::MAX_CELL_NODES];
        self.element.values(xi, &mut values[..n]);
        self.element.gradients(xi, &mut grads[..n]);
        self.scalar_from_basis(
            c,
            xi,
            &values[..n],
            |a| SVector::from_column_slice(&grads[a]),
            nodal,
        )
    }

    /// Value and gradient (∂u_i/∂x_j at (i, j)) at reference point ξ of cell c of the vector field
    /// with node-major nodal values.
    pub fn eval_vector(
        &self,
        c: usize,
        xi: &[f64; D],
        nodal: &[f64],
    ) -> (SVector<f64, D>, SMatrix<f64, D, D>) {
        let n = self.element.num_nodes();
        let mut values = [0.0; crate::fem::element::MAX_CELL_NODES];
        let mut grads = [[0.0; D]; crate::fem::element::MAX_CELL_NODES];
        self.element.values(xi, &mut values[..n]);
        self.element.gradients(xi, &mut grads[..n]);
        self.vector_from_basis(
            c,
            xi,
            &values[..n],
            |a| SVector::from_column_slice(&grads[a]),
            nodal,
        )
    }

    /// [`LagrangeSpace::eval_scalar`] at point q of `tabulation` (the basis tabulated once for
    /// all cells, e.g. at the centroid): bitwise the same value and gradient.
    pub fn eval_scalar_tabulated(
        &self,
        c: usize,
        tabulation: &Tabulation<D>,
        q: usize,
        nodal: &[f64],
    ) -> (f64, SVector<f64, D>) {
        let n = tabulation.nodes;
        let values = &tabulation.values[q * n..(q + 1) * n];
        let xi = &tabulation.points[q];
        self.scalar_from_basis(c, xi, values, |a| tabulation.gradients[q * n + a], nodal)
    }

    /// [`LagrangeSpace::eval_vector`] at point q of `tabulation` (the basis tabulated once for
    /// all cells): bitwise the same value and gradient.
    pub fn eval_vector_tabulated(
        &self,
        c: usize,
        tabulation: &Tabulation<D>,
        q: usize,
        nodal: &[f64],
    ) -> (SVector<f64, D>, SMatrix<f64, D, D>) {
        let n = tabulation.nodes;
        let values = &tabulation.values[q * n..(q + 1) * n];
        let xi = &tabulation.points[q];
        self.vector_from_basis(c, xi, values, |a| tabulation.gradients[q * n + a], nodal)
    }

    /// A scalar field on cell c from the basis values and reference gradients at a point.
    fn scalar_from_basis(
        &self,
        c: usize,
        xi: &[f64; D],
        values: &[f64],
        reference_gradient: impl Fn(usize) -> SVector<f64, D>,
        nodal: &[f64],
    ) -> (f64, SVector<f64, D>) {
        let geom = self.geometry_at(c, xi);
        let mut value = 0.0;
        let mut grad_ref = SVector::<f64, D>::zeros();
        for (a, &node) in self.cell_nodes(c).iter().enumerate() {
            value += values[a] * nodal[node];
            grad_ref += reference_gradient(a) * nodal[node];
        }
        (value, geom.inverse_transpose * grad_ref)
    }

    /// A vector field on cell c from the basis values and reference gradients at a point.
    fn vector_from_basis(
        &self,
        c: usize,
        xi: &[f64; D],
        values: &[f64],
        reference_gradient: impl Fn(usize) -> SVector<f64, D>,
        nodal: &[f64],
    ) -> (SVector<f64, D>, SMatrix<f64, D, D>) {
        let geom = self.geometry_at(c, xi);
        let mut value = SVector::<f64, D>::zeros();
        let mut grad = SMatrix::<f64, D, D>::zeros();
        for (a, &node) in self.cell_nodes(c).iter().enumerate() {
            let physical = geom.inverse_transpose * reference_gradient(a);
            let u = SVector::<f64, D>::from_column_slice(&nodal[node * D..node * D + D]);
            value += u * values[a];
            grad += u * physical.transpose();
        }
        (value, grad)
    }

    /// Finds a cell containing the physical point x (linear search with a tolerance) and returns
    /// it with the reference coordinates of x. None when x is outside the mesh.
    pub fn locate(&self, x: &[f64; D]) -> Option<(usize, [f64; D])> {
        let tol = 1e-12;
        self.geometry.iter().enumerate().find_map(|(c, geom)| {
            let xi = match self.curved_map(c) {
                None => geom.reference_point(x),
                Some(map) => {
                    // a curved cell lies near its straight simplex: skip it when x is far
                    // outside the latter
                    let straight = geom.reference_point(x);
                    if straight.iter().any(|&v| v < -0.5) || straight.iter().sum::<f64>() > 1.5 {
                        return None;
                    }
                    map.reference_point(x)?
                }
            };
            let inside = xi.iter().all(|&v| v >= -tol) && xi.iter().sum::<f64>() <= 1.0 + tol;
            inside.then_some((c, xi))
        })
    }
}

/// Symmetric gradient ε = ½(∇u + ∇uᵀ).
pub fn strain<const D: usize>(gradient: &SMatrix<f64, D, D>) -> SMatrix<f64, D, D> {
    (gradient + gradient.transpose()) * 0.5
}

#[cfg(test)]
mod tests {
    use super::*;
    use BoundaryPart::*;

    fn square(n: usize) -> Arc<Mesh<2>> {
        Arc::new(
            Mesh::box_mesh(
                [0.0, 0.0],
                [1.0, 2.0],
                [n, n],
                [[Dirichlet, Neumann], [Contact, Neumann]],
            )
            .unwrap(),
        )
    }

    #[test]
    fn p2_space_counts_vertices_and_edges() {
        let n = 4;
        let space = LagrangeSpace::new(square(n), 2).unwrap();
        let vertices = (n + 1) * (n + 1);
        let edges = 2 * n * (n + 1) + n * n;
        assert_eq!(space.num_nodes(), vertices + edges);
        let cube = Arc::new(
            Mesh::box_mesh(
                [0.0; 3],
                [1.0; 3],
                [2, 2, 2],
                [[Dirichlet, Neumann], [Contact, Neumann], [Neumann, Neumann]],
            )
            .unwrap(),
        );
        let space3 = LagrangeSpace::new(cube, 2).unwrap();
        // the P2 nodes of a Kuhn mesh of a box with 2 cells per side are the vertices of the 4^3 grid
        // together with the cell-diagonal midpoints: count them through the (2n+1)^3 lattice of
        // half-points that lie on edges; every P2 node lies on that lattice.
        for p in space3.nodes() {
            for v in p {
                assert!(((v * 4.0).round() - v * 4.0).abs() < 1e-12);
            }
        }
        assert_eq!(space3.nodes_per_facet(), 6);
    }

    #[test]
    fn tabulated_evaluation_is_bitwise_the_evaluation_at_the_point() {
        let points = vec![[1.0 / 3.0, 1.0 / 3.0], [0.1, 0.7], [0.0, 0.0]];
        for degree in [1, 2] {
            let space = LagrangeSpace::new(square(3), degree).unwrap();
            let tabulation = Tabulation::new(space.element(), points.clone(), vec![1.0; 3]);
            let scalar = space.interpolate_scalar(|x| (3.0 * x[0]).sin() + x[1] * x[1] / 7.0);
            let vector = space.interpolate_vector(|x| [x[0] * x[1] - 0.3, (x[0] + 2.0).ln()]);
            for c in 0..space.mesh().num_cells() {
                for (q, xi) in points.iter().enumerate() {
                    let (value, gradient) = space.eval_scalar(c, xi, &scalar);
                    let (tab_value, tab_gradient) =
                        space.eval_scalar_tabulated(c, &tabulation, q, &scalar);
                    assert_eq!(value.to_bits(), tab_value.to_bits());
                    assert_eq!(gradient, tab_gradient);
                    assert_eq!(
                        space.eval_vector(c, xi, &vector),
                        space.eval_vector_tabulated(c, &tabulation, q, &vector)
                    );
                }
            }
        }
    }

    #[test]
    fn p2_interpolant_reproduces_quadratics_with_gradients() {
        let space = LagrangeSpace::new(square(3), 2).unwrap();
        let f = |x: &[f64; 2]| {
            1.0 + 2.0 * x[0] - x[1] + 0.5 * x[0] * x[0] + 3.0 * x[0] * x[1] - x[1] * x[1]
        };
        let nodal = space.interpolate_scalar(f);
        for c in [0, 5, 11] {
            let xi = [0.21, 0.37];
            let x = space.geometry(c).point(&xi);
            let (value, grad) = space.eval_scalar(c, &xi, &nodal);
            assert!((value - f(&x)).abs() < 1e-13);
            assert!((grad[0] - (2.0 + x[0] + 3.0 * x[1])).abs() < 1e-12);
            assert!((grad[1] - (-1.0 + 3.0 * x[0] - 2.0 * x[1])).abs() < 1e-12);
        }
    }

    #[test]
    fn facet_nodes_lie_on_their_facet() {
        for degree in [1, 2] {
            let space = LagrangeSpace::new(square(2), degree).unwrap();
            for f in 0..space.mesh().num_facets() {
                let verts = space.mesh().facet(f);
                let (a, b) = (space.mesh().vertex(verts[0]), space.mesh().vertex(verts[1]));
                for &node in space.facet_nodes(f) {
                    let p = space.node(node);
                    let cross = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
                    assert!(cross.abs() < 1e-14);
                }
            }
        }
    }

    #[test]
    fn locate_finds_points_and_rejects_outside() {
        let space = LagrangeSpace::new(square(3), 1).unwrap();
        let (c, xi) = space.locate(&[0.4, 1.3]).unwrap();
        let x = space.geometry(c).point(&xi);
        assert!((x[0] - 0.4).abs() < 1e-14 && (x[1] - 1.3).abs() < 1e-14);
        assert!(space.locate(&[1.5, 0.5]).is_none());
    }
}
