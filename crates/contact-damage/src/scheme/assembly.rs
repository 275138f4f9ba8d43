//! Finite element assembly: element kernels for the velocity operator and the
//! damage operator, and point-wise facet integrals (the scheme's load vectors are assembled by
//! [`crate::scheme::loads`] from quadrature data computed once per mesh).
//!
//! Matrices are assembled against a [`SparsityPattern`](crate::algebra::linalg::SparsityPattern) built once per mesh: a numeric assembly
//! computes every element matrix in parallel into one flat array and sums it into the pattern.

use crate::error::{Error, Result};
use crate::fem::space::{CellGeometry, FacetRule, LagrangeSpace, Tabulation};
use crate::model::laws::{Tensor, Viscosity};
use crate::model::problem::JumpPlane;
use nalgebra::SVector;
use rayon::prelude::*;

/// Physical basis gradients ∇φ_a = J^{-T} ∇̂φ_a at point q of a tabulation.
#[inline]
pub fn physical_gradients<const D: usize>(
    geometry: &CellGeometry<D>,
    tabulation: &Tabulation<D>,
    q: usize,
    out: &mut [SVector<f64, D>],
) {
    let n = tabulation.nodes;
    for (a, grad) in out.iter_mut().enumerate().take(n) {
        *grad = geometry.inverse_transpose * tabulation.gradients[q * n + a];
    }
}

/// Symmetric gradient of the vector basis function φ_b e_j: ε(φ_b e_j) = sym(e_j ⊗ ∇φ_b).
#[inline]
pub fn basis_strain<const D: usize>(gradient: &SVector<f64, D>, component: usize) -> Tensor<D> {
    let mut strain = Tensor::<D>::zeros();
    for k in 0..D {
        strain[(component, k)] += 0.5 * gradient[k];
        strain[(k, component)] += 0.5 * gradient[k];
    }
    strain
}

/// Strain ε(u) at point q of cell c of a vector field with node-major nodal values.
#[inline]
pub fn field_strain<const D: usize>(
    nodes: &[usize],
    gradients: &[SVector<f64, D>],
    nodal: &[f64],
) -> Tensor<D> {
    let mut grad = [[0.0; D]; D];
    for (&node, gradient) in nodes.iter().zip(gradients) {
        let values = &nodal[node * D..node * D + D];
        for i in 0..D {
            for k in 0..D {
                grad[i][k] += values[i] * gradient[k];
            }
        }
    }
    Tensor::<D>::from_fn(|i, k| (grad[i][k] + grad[k][i]) * 0.5)
}

/// Element matrix of the linearized viscosity operator, with local dof (a, i) = a·D + i:
/// K[(a,i),(b,j)] = ∫_K d𝒜(ε(v))[ε(φ_b e_j)] : ε(φ_a e_i) dx — the bilinear form of (5.1)
/// linearized at the strain rate of `velocity` (ignored for a linear 𝒜).
pub fn viscous_element_matrix<const D: usize>(
    law: &dyn Viscosity<D>,
    space: &LagrangeSpace<D>,
    tabulation: &Tabulation<D>,
    cell: usize,
    velocity: Option<&[f64]>,
    out: &mut [f64],
) {
    let n = tabulation.nodes;
    let nd = n * D;
    out.fill(0.0);
    let nodes = space.cell_nodes(cell);
    let mut grads = [SVector::<f64, D>::zeros(); crate::fem::element::MAX_CELL_NODES];
    for q in 0..tabulation.len() {
        let geometry = space.geometry_at(cell, &tabulation.points[q]);
        physical_gradients(&geometry, tabulation, q, &mut grads);
        let rate = match velocity {
            Some(v) => field_strain(nodes, &grads[..n], v),
            None => Tensor::<D>::zeros(),
        };
        let weight = tabulation.weights[q] * geometry.det;
        for b in 0..n {
            for j in 0..D {
                let tangent = law.tangent(&rate, &basis_strain(&grads[b], j)) * weight;
                let col = b * D + j;
                for a in 0..n {
                    let traction = tangent * grads[a];
                    for i in 0..D {
                        out[(a * D + i) * nd + col] += traction[i];
                    }
                }
            }
        }
    }
}

/// Element matrix of the damage operator m·M + κ·K for scalar P_l:
/// ∫ m φ_a φ_b + κ ∇φ_a·∇φ_b dx (the matrix of (5.2) with m = 1/k).
pub fn damage_element_matrix<const D: usize>(
    space: &LagrangeSpace<D>,
    tabulation: &Tabulation<D>,
    cell: usize,
    mass_coefficient: f64,
    diffusion: f64,
    out: &mut [f64],
) {
    let n = tabulation.nodes;
    out.fill(0.0);
    let mut grads = [SVector::<f64, D>::zeros(); crate::fem::element::MAX_CELL_NODES];
    for q in 0..tabulation.len() {
        let geometry = space.geometry_at(cell, &tabulation.points[q]);
        physical_gradients(&geometry, tabulation, q, &mut grads);
        let weight = tabulation.weights[q] * geometry.det;
        let values = &tabulation.values[q * n..(q + 1) * n];
        for a in 0..n {
            for b in 0..n {
                out[a * n + b] += weight
                    * (mass_coefficient * values[a] * values[b]
                        + diffusion * grads[a].dot(&grads[b]));
            }
        }
    }
}

/// Computes per-cell local vectors in parallel with `kernel(cell, local)` and sums them into a
/// global vector of `components` values per node (node-major).
pub fn assemble_cell_vector<const D: usize, K>(
    space: &LagrangeSpace<D>,
    components: usize,
    kernel: K,
) -> Vec<f64>
where
    K: Fn(usize, &mut [f64]) + Sync,
{
    let local = space.nodes_per_cell() * components;
    let mut locals = vec![0.0; space.mesh().num_cells() * local];
    locals
        .par_chunks_mut(local)
        .enumerate()
        .for_each(|(cell, out)| kernel(cell, out));
    let mut global = vec![0.0; space.num_nodes() * components];
    for (cell, chunk) in locals.chunks(local).enumerate() {
        for (a, &node) in space.cell_nodes(cell).iter().enumerate() {
            for i in 0..components {
                global[node * components + i] += chunk[a * components + i];
            }
        }
    }
    global
}

/// Quadrature points of a set of boundary facets, in facet order, with what the scatter needs.
#[derive(Debug, Clone, Default)]
pub(crate) struct FacetPoints<const D: usize> {
    /// Physical points.
    pub(crate) points: Vec<[f64; D]>,
    /// Outward unit normal at each point (of its facet, or of the curved facet there).
    pub(crate) normals: Vec<[f64; D]>,
    /// The cell of the facet of each point.
    pub(crate) cells: Vec<usize>,
    /// φ_a(x_p) × weight × facet measure, `nodes` per point.
    pub(crate) weighted_values: Vec<f64>,
}

impl<const D: usize> FacetPoints<D> {
    pub(crate) fn new(
        space: &LagrangeSpace<D>,
        rule: &FacetRule,
        select: impl Fn(usize) -> bool,
    ) -> Self {
        Self::split_at(space, rule, select, &[])
            .expect("no plane splits a facet, so no facet is refused")
    }

    /// As [`FacetPoints::new`], with the facets that a plane of `planes` crosses integrated
    /// piecewise ([`FacetRule::split`]). Refused: a plane that crosses a curved facet (its
    /// pieces are not straight), two planes that cross one facet.
    pub(crate) fn split_at(
        space: &LagrangeSpace<D>,
        rule: &FacetRule,
        select: impl Fn(usize) -> bool,
        planes: &[JumpPlane<D>],
    ) -> Result<Self> {
        for (k, plane) in planes.iter().enumerate() {
            let finite = plane.normal.iter().all(|n| n.is_finite()) && plane.offset.is_finite();
            if !finite || plane.normal.iter().all(|&n| n == 0.0) {
                return Err(Error::parameter(
                    format!("jump_planes[{k}] (normal {:?})", plane.normal),
                    plane.offset,
                    "a jump plane needs a finite, nonzero normal and a finite offset",
                ));
            }
        }
        let mesh = space.mesh();
        let element = space.element();
        let n = element.num_nodes();
        let mut values = [0.0; crate::fem::element::MAX_CELL_NODES];
        let mut facets = Self::default();
        for f in (0..mesh.num_facets()).filter(|&f| select(f)) {
            let cell = mesh.facet_cell(f);
            let vertices: Vec<[f64; D]> = mesh.facet(f).iter().map(|&v| mesh.vertex(v)).collect();
            let mut split = None;
            for (k, plane) in planes.iter().enumerate() {
                let levels: Vec<f64> = vertices.iter().map(|x| plane.level(x)).collect();
                let Some(pieces) = rule.split(&levels) else {
                    continue;
                };
                if space.curved_map(cell).is_some() {
                    return Err(Error::InvalidInput(format!(
                        "jump plane {k} (normal {:?}, offset {}) crosses the curved boundary facet {f} of cell {cell} (vertices {vertices:?}); a facet is split along a plane only where it is straight",
                        plane.normal, plane.offset
                    )));
                }
                if split.is_some() {
                    return Err(Error::InvalidInput(format!(
                        "two jump planes cross the boundary facet {f} of cell {cell} (vertices {vertices:?}), the second plane {k} (normal {:?}, offset {}); a facet is split along one plane",
                        plane.normal, plane.offset
                    )));
                }
                split = Some(pieces);
            }
            for point in space.facet_quadrature(f, split.as_ref().unwrap_or(rule)) {
                element.values(&point.reference, &mut values[..n]);
                facets.points.push(point.point);
                facets.normals.push(point.normal);
                facets.cells.push(cell);
                facets
                    .weighted_values
                    .extend(values[..n].iter().map(|v| v * point.weight * point.measure));
            }
        }
        Ok(facets)
    }

    pub(crate) fn len(&self) -> usize {
        self.points.len()
    }

    /// Adds Σ_p φ_a(x_p) w_p data_p to `global` (`components` values per point and per node),
    /// in point order.
    pub(crate) fn scatter(
        &self,
        space: &LagrangeSpace<D>,
        components: usize,
        data: &[f64],
        global: &mut [f64],
    ) {
        let n = space.nodes_per_cell();
        for (p, &cell) in self.cells.iter().enumerate() {
            let phi = &self.weighted_values[p * n..(p + 1) * n];
            for (a, &node) in space.cell_nodes(cell).iter().enumerate() {
                if phi[a] != 0.0 {
                    for i in 0..components {
                        global[node * components + i] += phi[a] * data[p * components + i];
                    }
                }
            }
        }
    }
}

/// Adds ∫_F g·φ_a dΓ over the boundary facets F selected by `select`, for a `components`-valued
/// integrand `integrand(x, normal, out)`, with a facet rule of the given degree (point by point;
/// the scheme keeps its facet points once per mesh instead).
pub fn add_facet_integrals<const D: usize>(
    space: &LagrangeSpace<D>,
    degree: usize,
    components: usize,
    select: impl Fn(usize) -> bool,
    integrand: impl Fn(&[f64; D], &[f64; D], &mut [f64]),
    global: &mut [f64],
) {
    let facets = FacetPoints::new(space, &FacetRule::new(D, degree), select);
    let mut data = vec![0.0; facets.len() * components];
    for ((x, normal), out) in facets
        .points
        .iter()
        .zip(&facets.normals)
        .zip(data.chunks_mut(components))
    {
        integrand(x, normal, out);
    }
    facets.scatter(space, components, &data, global);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::mesh::{BoundaryPart, Mesh};
    use std::sync::Arc;

    /// Σ_p Σ_a φ_a(x_p) w_p f(x_p) = ∫ f over the selected facets (the basis sums to 1).
    fn facet_integral<const D: usize>(
        points: &FacetPoints<D>,
        f: impl Fn(&[f64; D]) -> f64,
    ) -> f64 {
        let nodes = points.weighted_values.len() / points.len();
        points
            .points
            .iter()
            .enumerate()
            .map(|(p, x)| {
                points.weighted_values[p * nodes..(p + 1) * nodes]
                    .iter()
                    .sum::<f64>()
                    * f(x)
            })
            .sum()
    }

    fn neumann_points<const D: usize>(
        mesh: Mesh<D>,
        degree: usize,
        planes: &[JumpPlane<D>],
    ) -> Result<FacetPoints<D>> {
        let space = LagrangeSpace::new(Arc::new(mesh), degree)?;
        let mesh = space.mesh().clone();
        FacetPoints::split_at(
            &space,
            &FacetRule::new(D, 4),
            |f| mesh.facet_part(f) == BoundaryPart::Neumann,
            planes,
        )
    }

    /// The unit square in 4 × 4 cells, clamped on x = 0 and y = 0, Γ2 on the other sides.
    fn unit_square() -> Mesh<2> {
        use BoundaryPart::{Dirichlet, Neumann};
        Mesh::box_mesh(
            [0.0; 2],
            [1.0; 2],
            [4, 4],
            [[Dirichlet, Neumann], [Dirichlet, Neumann]],
        )
        .unwrap()
    }

    /// The plane x = offset in 2D.
    fn plane_x(offset: f64) -> JumpPlane<2> {
        JumpPlane {
            normal: [1.0, 0.0],
            offset,
        }
    }

    /// A traction that jumps across a plane inside the facets it crosses is integrated exactly
    /// once the plane is declared (each side by the full rule), and not without: in 2D x² on
    /// x > 0.3 of the top of the unit square, (1 − 0.3³)/3; in 3D the indicator of x + y > 0.7
    /// on the top of the unit cube, 1 − 0.7²/2; at l = 1 and 2.
    #[test]
    fn split_facet_points_integrate_a_jumping_traction_exactly() {
        use BoundaryPart::{Dirichlet, Neumann};
        for degree in [1, 2] {
            let traction = |x: &[f64; 2]| {
                if x[1] > 1.0 - 1e-9 && x[0] > 0.3 {
                    x[0] * x[0]
                } else {
                    0.0
                }
            };
            let exact = (1.0 - 0.3_f64.powi(3)) / 3.0;
            let split = neumann_points(unit_square(), degree, &[plane_x(0.3)]).unwrap();
            assert!((facet_integral(&split, traction) - exact).abs() < 1e-14);
            let plain = neumann_points(unit_square(), degree, &[]).unwrap();
            assert!((facet_integral(&plain, traction) - exact).abs() > 1e-4);

            let cube = || {
                Mesh::box_mesh(
                    [0.0; 3],
                    [1.0; 3],
                    [3, 3, 3],
                    [
                        [Dirichlet, Dirichlet],
                        [Dirichlet, Dirichlet],
                        [Dirichlet, Neumann],
                    ],
                )
                .unwrap()
            };
            let plane = JumpPlane {
                normal: [1.0, 1.0, 0.0],
                offset: 0.7,
            };
            let traction = |x: &[f64; 3]| f64::from(u8::from(x[0] + x[1] > 0.7));
            let exact = 1.0 - 0.7 * 0.7 / 2.0;
            let split = neumann_points(cube(), degree, &[plane]).unwrap();
            assert!((facet_integral(&split, traction) - exact).abs() < 1e-14);
            let plain = neumann_points(cube(), degree, &[]).unwrap();
            assert!((facet_integral(&plain, traction) - exact).abs() > 1e-4);
        }
    }

    /// A facet is split along one plane, and only where it is straight: two planes through one
    /// facet, and a plane through a curved facet, are refused naming the facet; a plane without
    /// a finite nonzero normal and a finite offset is refused naming it.
    #[test]
    fn split_facet_points_refuse_two_planes_and_curved_facets() {
        let square = unit_square();
        let Err(error) = neumann_points(square.clone(), 1, &[plane_x(0.3), plane_x(0.4)]) else {
            panic!("two planes through one facet are refused");
        };
        assert!(
            error
                .to_string()
                .contains("two jump planes cross the boundary facet"),
            "{error}"
        );
        // bulge the top edge from (0.25, 1) to (0.5, 1) outwards
        let vertex = |x: [f64; 2]| square.vertices().iter().position(|v| *v == x).unwrap();
        let edge = (vertex([0.25, 1.0]), vertex([0.5, 1.0]));
        let curved = square
            .clone()
            .with_curved_edges([(edge, [0.375, 1.02])])
            .unwrap();
        let Err(error) = neumann_points(curved.clone(), 2, &[plane_x(0.3)]) else {
            panic!("a plane through a curved facet is refused");
        };
        assert!(
            error
                .to_string()
                .contains("crosses the curved boundary facet"),
            "{error}"
        );
        // a plane through a straight facet of the same mesh is taken
        assert!(neumann_points(curved, 2, &[plane_x(0.6)]).is_ok());
        // a plane with no normal, or with a non-finite datum, is no plane
        for plane in [
            JumpPlane {
                normal: [0.0, 0.0],
                offset: 0.3,
            },
            JumpPlane {
                normal: [f64::NAN, 1.0],
                offset: 0.3,
            },
            plane_x(f64::INFINITY),
        ] {
            let Err(error) = neumann_points(unit_square(), 1, &[plane]) else {
                panic!("{plane:?} is refused");
            };
            assert!(error.to_string().contains("jump_planes[0]"), "{error}");
        }
    }

    fn unit<const D: usize>(k: usize) -> SVector<f64, D> {
        SVector::<f64, D>::from_fn(|i, _| if i == k { 1.0 } else { 0.0 })
    }

    /// The P1 basis gradients of the reference simplex: −(1, …, 1), then e_1, …, e_D.
    fn reference_gradients<const D: usize>() -> Vec<SVector<f64, D>> {
        std::iter::once(SVector::<f64, D>::repeat(-1.0))
            .chain((0..D).map(unit::<D>))
            .collect()
    }

    /// u(x) = B x + c at the vertices of the reference simplex (node-major, nodes 0..=D).
    fn affine_nodal<const D: usize>(b: &Tensor<D>, c: &SVector<f64, D>) -> Vec<f64> {
        std::iter::once(SVector::<f64, D>::zeros())
            .chain((0..D).map(unit::<D>))
            .flat_map(|x| (b * x + c).iter().copied().collect::<Vec<_>>())
            .collect()
    }

    fn check<const D: usize>(b: Tensor<D>, c: SVector<f64, D>) {
        let nodes: Vec<usize> = (0..=D).collect();
        let strain = field_strain(&nodes, &reference_gradients::<D>(), &affine_nodal(&b, &c));
        assert_eq!(strain, (b + b.transpose()) * 0.5);
    }

    /// ε(u) of a P1 field that interpolates an affine u(x) = Bx + c is sym(B), exactly (the
    /// data are small integers), also where nodal values vanish (c = 0 makes node 0 zero,
    /// rows of B that vanish make components zero) or are −0.
    #[test]
    fn field_strain_is_the_symmetric_gradient_of_an_affine_field() {
        check::<2>(
            Tensor::<2>::new(1.0, -2.0, 3.0, 4.0),
            SVector::<f64, 2>::new(5.0, -1.0),
        );
        check::<2>(
            Tensor::<2>::new(0.0, 0.0, 3.0, -4.0),
            SVector::<f64, 2>::zeros(),
        );
        check::<2>(
            Tensor::<2>::new(-0.0, 2.0, 0.0, 0.0),
            SVector::<f64, 2>::new(-0.0, 0.0),
        );
        check::<3>(
            Tensor::<3>::new(1.0, 2.0, -3.0, 0.0, 5.0, 6.0, -7.0, 8.0, 0.0),
            SVector::<f64, 3>::new(1.0, 0.0, -2.0),
        );
        check::<3>(Tensor::<3>::zeros(), SVector::<f64, 3>::zeros());
    }
}
