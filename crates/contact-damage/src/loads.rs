//! The right-hand sides of the scheme, (5.1) and (5.2): the time-independent quadrature data
//! (physical quadrature points, |det J| × weights, basis tabulations, the boundary facets of
//! each part with their points, normals and weighted basis values) computed once per mesh, and
//! per step the load vectors
//!
//! - velocity step (5.1): (f(t_n), w)_V = ∫_Ω f0·w + ∫_Γ2 f2·w (+ ∫_Γ3 f3·w, SPEC §4), minus
//!   the elastic term (G(ε(u_{n−1}), β_{n−1}), ε(w))_Q;
//! - damage step (5.2): (φ(ε(u_{n−1}), β_{n−1}) + q(t_n), ζ) + ∫_Γ κ ∂β/∂ν ζ.
//!
//! Each field is evaluated once per step over all quadrature points of a chunk of cells (rayon
//! over chunks) or of a boundary part; the element vectors are summed into the global vectors
//! in cell (and facet) order, so the loads do not depend on the number of threads.

use crate::assembly::{field_strain, physical_gradients, FacetPoints};
use crate::mesh::BoundaryPart;
use crate::quadrature::QuadratureRule;
use crate::scheme::{Data, Model, State};
use crate::space::{FacetRule, LagrangeSpace, Tabulation};
use nalgebra::SVector;
use rayon::prelude::*;

/// Cells per parallel task of the load assembly (the batch size of field evaluations is this
/// times the number of quadrature points per cell).
const CHUNK_CELLS: usize = 64;

/// The time-independent quadrature data of the loads, computed once per mesh.
#[derive(Debug, Clone)]
pub struct LoadQuadrature<const D: usize> {
    /// The cell rule (degree 2l + 2) tabulated on the reference element.
    tabulation: Tabulation<D>,
    /// Physical quadrature points, cell-major (`tabulation.len()` per cell).
    points: Vec<[f64; D]>,
    /// Reference weight × |det J| of every point.
    weights: Vec<f64>,
    /// Points on Γ2 (traction f2).
    neumann: FacetPoints<D>,
    /// Points on Γ3 (extra traction f3).
    contact: FacetPoints<D>,
    /// Points on all of Γ (damage flux).
    boundary: FacetPoints<D>,
}

impl<const D: usize> LoadQuadrature<D> {
    /// Rules of degree 2l + 2 on cells and facets of `space`.
    pub fn new(space: &LagrangeSpace<D>) -> Self {
        let degree = 2 * space.degree() + 2;
        let tabulation =
            Tabulation::cell_rule(space.element(), &QuadratureRule::<D>::simplex(degree));
        let cells = space.mesh().num_cells();
        let mut points = Vec::with_capacity(cells * tabulation.len());
        let mut weights = Vec::with_capacity(cells * tabulation.len());
        for cell in 0..cells {
            let geometry = space.geometry(cell);
            for (xi, w) in tabulation.points.iter().zip(&tabulation.weights) {
                points.push(geometry.point(xi));
                weights.push(w * geometry.det);
            }
        }
        let mesh = space.mesh();
        let rule = FacetRule::new(D, degree);
        Self {
            neumann: FacetPoints::new(space, &rule, |f| {
                mesh.facet_part(f) == BoundaryPart::Neumann
            }),
            contact: FacetPoints::new(space, &rule, |f| {
                mesh.facet_part(f) == BoundaryPart::Contact
            }),
            boundary: FacetPoints::new(space, &rule, |_| true),
            tabulation,
            points,
            weights,
        }
    }

    /// Number of quadrature points per cell.
    pub fn points_per_cell(&self) -> usize {
        self.tabulation.len()
    }

    /// The load vectors of the step at `time` from the state (u_{n−1}, β_{n−1}): the velocity
    /// load (Cartesian, node-major) and the damage source ⟨φ(ε(u_{n−1}), β_{n−1}) + q(t_n),
    /// φ_a⟩ + ∫_Γ κ∂β/∂ν φ_a.
    pub fn assemble(
        &self,
        space: &LagrangeSpace<D>,
        model: &Model<D>,
        data: &Data<D>,
        time: f64,
        state: &State,
    ) -> (Vec<f64>, Vec<f64>) {
        let elasticity = model.elasticity.as_ref();
        let damage_source = model.damage_source.as_ref();
        let (displacement, damage) = (&state.displacement, &state.damage);
        let tab = &self.tabulation;
        let n = tab.nodes;
        let nq = tab.len();
        let local = n * (D + 1);
        let mut locals = vec![0.0; space.mesh().num_cells() * local];
        locals
            .par_chunks_mut(CHUNK_CELLS * local)
            .enumerate()
            .for_each(|(chunk, out)| {
                let first = chunk * CHUNK_CELLS;
                let count = out.len() / local;
                let range = first * nq..(first + count) * nq;
                let points = &self.points[range.clone()];
                let weights = &self.weights[range];
                let mut force = Vec::new();
                if let Some(f) = &data.body_force {
                    force = vec![[0.0; D]; points.len()];
                    f.evaluate(points, time, &mut force);
                }
                let mut supply = Vec::new();
                if let Some(q) = &data.damage_supply {
                    supply = vec![0.0; points.len()];
                    q.evaluate(points, time, &mut supply);
                }
                // ε(u_{n−1}) and β_{n−1} at every point of the chunk, then φ over the batch.
                let mut grads = [SVector::<f64, D>::zeros(); crate::element::MAX_CELL_NODES];
                let mut strains = Vec::with_capacity(points.len());
                let mut betas = Vec::with_capacity(points.len());
                let mut point_grads = Vec::with_capacity(points.len() * n);
                for c in 0..count {
                    let cell = first + c;
                    let geometry = space.geometry(cell);
                    let nodes = space.cell_nodes(cell);
                    for q in 0..nq {
                        physical_gradients(geometry, tab, q, &mut grads);
                        let values = &tab.values[q * n..(q + 1) * n];
                        strains.push(field_strain(nodes, &grads[..n], displacement));
                        point_grads.extend_from_slice(&grads[..n]);
                        betas.push(
                            nodes
                                .iter()
                                .zip(values)
                                .map(|(&node, v)| damage[node] * v)
                                .sum::<f64>(),
                        );
                    }
                }
                let mut sources = vec![0.0; points.len()];
                damage_source.source_batch(&strains, &betas, &mut sources);
                for (c, out) in out.chunks_mut(local).enumerate() {
                    for q in 0..nq {
                        let p = c * nq + q;
                        let grads = &point_grads[p * n..(p + 1) * n];
                        let values = &tab.values[q * n..(q + 1) * n];
                        let (strain, beta) = (strains[p], betas[p]);
                        let weight = weights[p];
                        let stress = elasticity.stress(&strain, beta);
                        let mut source = sources[p];
                        if !supply.is_empty() {
                            source += supply[p];
                        }
                        for a in 0..n {
                            let internal = stress * grads[a];
                            for i in 0..D {
                                let mut value = -internal[i];
                                if !force.is_empty() {
                                    value += force[p][i] * values[a];
                                }
                                out[a * (D + 1) + i] += weight * value;
                            }
                            out[a * (D + 1) + D] += weight * source * values[a];
                        }
                    }
                }
            });
        let mut velocity_load = vec![0.0; space.num_nodes() * D];
        let mut damage_source = vec![0.0; space.num_nodes()];
        for (cell, chunk) in locals.chunks(local).enumerate() {
            for (a, &node) in space.cell_nodes(cell).iter().enumerate() {
                for i in 0..D {
                    velocity_load[node * D + i] += chunk[a * (D + 1) + i];
                }
                damage_source[node] += chunk[a * (D + 1) + D];
            }
        }
        let vector_part = |facets: &FacetPoints<D>,
                           field: &dyn crate::fields::BatchBoundaryVectorField<D>,
                           global: &mut [f64]| {
            let mut values = vec![[0.0; D]; facets.len()];
            field.evaluate(&facets.points, &facets.normals, time, &mut values);
            facets.scatter(space, D, values.as_flattened(), global);
        };
        if let Some(traction) = &data.traction {
            vector_part(&self.neumann, traction.as_ref(), &mut velocity_load);
        }
        if let Some(traction) = &data.contact_traction {
            vector_part(&self.contact, traction.as_ref(), &mut velocity_load);
        }
        if let Some(flux) = &data.damage_flux {
            let facets = &self.boundary;
            let mut values = vec![0.0; facets.len()];
            flux.evaluate(&facets.points, &facets.normals, time, &mut values);
            facets.scatter(space, 1, &values, &mut damage_source);
        }
        (velocity_load, damage_source)
    }
}
