//! The right-hand sides of the scheme, (5.1) and (5.2): the time-independent quadrature data
//! (physical quadrature points, |det J| × weights, basis tabulations, the boundary facets of
//! each part with their points, normals and weighted basis values) computed once per mesh, and
//! per step the load vectors
//!
//! - velocity step (5.1): (f(t_n), w)_V = ∫_Ω f0·w + ∫_Γ2 f2·w (and ∫_Γ3 f3·w, docs/model.md
//!   §5, and ∫_Ω S : ε(w) for a stress S given as data), minus the elastic term
//!   (G(ε(u_{n−1}), β_{n−1}), ε(w))_Q;
//! - damage step (5.2): (φ(ε(u_{n−1}), β_{n−1}) + q(t_n), ζ) + ∫_Γ κ ∂β/∂ν ζ.
//!
//! Each field is evaluated once per step over all quadrature points of a chunk of cells (rayon
//! over chunks) or of a boundary part; the element vectors are summed into the global vectors
//! in cell (and facet) order, so the loads do not depend on the number of threads. f0 and q,
//! when their fields ask for it, are evaluated ahead for a block of step times ([`BulkData`]),
//! bitwise the same values.

use crate::error::Result;
use crate::fem::mesh::BoundaryPart;
use crate::fem::quadrature::QuadratureRule;
use crate::fem::space::{FacetRule, LagrangeSpace, Tabulation};
use crate::model::problem::{Data, JumpPlane, Model};
use crate::scheme::assembly::{field_strain, physical_gradients, FacetPoints};
use crate::scheme::state::State;
use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;

/// Cells per parallel task of the load assembly (the batch size of field evaluations is this
/// times the number of quadrature points per cell).
const CHUNK_CELLS: usize = 256;

/// Chunks of cells per wave of the load assembly: the element vectors of a wave (about
/// 300 kB for P1 in 2D) are summed into the global vectors while the next wave is computed,
/// so they are read back from the cache. One array of all element vectors (38 MB at 512² in
/// 2D) was written and read through memory in every step, and at that size every step
/// allocated it afresh from the system (page faults, slower still on two threads).
const WAVE_CHUNKS: usize = 16;

/// The time-independent quadrature data of the loads, computed once per mesh.
#[derive(Debug, Clone)]
pub struct LoadQuadrature<const D: usize> {
    /// The cell rule (degree 2l + 2) tabulated on the reference element.
    tabulation: Tabulation<D>,
    /// Physical quadrature points, cell-major (`tabulation.len()` per cell).
    points: Vec<[f64; D]>,
    /// Reference weight × |det J| of every point.
    weights: Vec<f64>,
    /// The basis values of the cell rule node-major: φ_a(ξ_q) at `a * points + q`.
    values_by_node: Vec<f64>,
    /// Points on Γ2 (traction f2).
    neumann: FacetPoints<D>,
    /// Points on Γ3 (extra traction f3).
    contact: FacetPoints<D>,
    /// Points on all of Γ (damage flux).
    boundary: FacetPoints<D>,
}

/// Most bytes of a [`BulkData`] block (f0 and q at every cell quadrature point for several
/// step times).
pub const BULK_DATA_BYTES: usize = 64 << 20;

/// The bulk data f0 and q at every cell quadrature point for a block of upcoming step times,
/// evaluated ahead of the steps ([`LoadQuadrature::bulk_data`]) for fields that gain from
/// several times per call ([`crate::model::fields::BatchVectorField::times_per_evaluation`]).
///
/// Why: an implementation whose evaluation reads time-independent values per point (the
/// manufactured data of the verification harness keep them in memory, tens of MB per step
/// on fine meshes) reads them once for the whole block instead of once per step. The values
/// of each time are bitwise those of an evaluation at that time alone, and
/// [`LoadQuadrature::assemble`] sums them in the same order, so the loads do not depend on
/// the block (a resumed run is bitwise an uninterrupted one).
#[derive(Debug, Default)]
pub struct BulkData<const D: usize> {
    /// The step times of the block, as bits.
    times: Vec<u64>,
    /// The quadrature points it was evaluated at (their number: a block of another mesh is
    /// not used).
    points: usize,
    /// Per chunk of cells: f0 then q, time-major (empty for a field the data lack).
    chunks: Vec<(Vec<[f64; D]>, Vec<f64>)>,
}

impl<const D: usize> BulkData<D> {
    /// The index of `time` in the block, if it holds it.
    fn position(&self, time: f64) -> Option<usize> {
        self.times.iter().position(|&t| t == time.to_bits())
    }

    /// True if the block holds the values at `time` (bit for bit).
    pub fn holds(&self, time: f64) -> bool {
        self.position(time).is_some()
    }
}

impl<const D: usize> LoadQuadrature<D> {
    /// Rules of degree 2l + 2 on cells and facets of `space`.
    pub fn new(space: &LagrangeSpace<D>) -> Self {
        Self::with_jump_planes(space, &[]).expect("no plane splits a facet, so no facet is refused")
    }

    /// As [`LoadQuadrature::new`], with the boundary facets that a plane of
    /// [`Data::jump_planes`] crosses integrated piecewise, each side by the full rule. Refused,
    /// naming the facet and the plane: a plane that crosses a curved facet, two planes that cross
    /// one facet.
    pub fn with_jump_planes(space: &LagrangeSpace<D>, planes: &[JumpPlane<D>]) -> Result<Self> {
        let degree = 2 * space.degree() + 2;
        let tabulation =
            Tabulation::cell_rule(space.element(), &QuadratureRule::<D>::simplex(degree));
        let cells = space.mesh().num_cells();
        let mut points = Vec::with_capacity(cells * tabulation.len());
        let mut weights = Vec::with_capacity(cells * tabulation.len());
        for cell in 0..cells {
            for (xi, w) in tabulation.points.iter().zip(&tabulation.weights) {
                let geometry = space.geometry_at(cell, xi);
                points.push(geometry.point(xi));
                weights.push(w * geometry.det);
            }
        }
        let (nodes, nq) = (tabulation.nodes, tabulation.len());
        let values_by_node = (0..nodes * nq)
            .map(|i| tabulation.values[(i % nq) * nodes + i / nq])
            .collect();
        let mesh = space.mesh();
        let rule = FacetRule::new(D, degree);
        Ok(Self {
            neumann: FacetPoints::split_at(
                space,
                &rule,
                |f| mesh.facet_part(f) == BoundaryPart::Neumann,
                planes,
            )?,
            contact: FacetPoints::split_at(
                space,
                &rule,
                |f| mesh.facet_part(f) == BoundaryPart::Contact,
                planes,
            )?,
            boundary: FacetPoints::split_at(space, &rule, |_| true, planes)?,
            tabulation,
            points,
            weights,
            values_by_node,
        })
    }

    /// The first quadrature point of the loads (cell-major order) at which `reject(β)` holds
    /// for the damage `β_h = Σ_a β_a φ_a` there: the point and β. A run of points with one β
    /// (an undamaged region) asks `reject` once.
    pub fn first_damage_point(
        &self,
        space: &LagrangeSpace<D>,
        damage: &[f64],
        mut reject: impl FnMut(f64) -> bool,
    ) -> Option<([f64; D], f64)> {
        let (nodes, nq) = (self.tabulation.nodes, self.tabulation.len());
        let mut accepted = None;
        for cell in 0..space.mesh().num_cells() {
            let cell_nodes = space.cell_nodes(cell);
            for q in 0..nq {
                let values = &self.tabulation.values[q * nodes..(q + 1) * nodes];
                let mut beta = 0.0;
                for (&node, value) in cell_nodes.iter().zip(values) {
                    beta += damage[node] * value;
                }
                if accepted == Some(beta.to_bits()) {
                    continue;
                }
                if reject(beta) {
                    return Some((self.points[cell * nq + q], beta));
                }
                accepted = Some(beta.to_bits());
            }
        }
        None
    }

    /// Number of quadrature points per cell.
    pub fn points_per_cell(&self) -> usize {
        self.tabulation.len()
    }

    /// How many step times one [`BulkData`] block of `data` should hold: the fewest any
    /// present bulk field asks for ([`crate::model::fields::BatchVectorField::times_per_evaluation`]),
    /// at most what fits in [`BULK_DATA_BYTES`]; 1 (no block) when no bulk field asks for more.
    pub fn times_per_block(&self, data: &Data<D>) -> usize {
        let asked = [
            data.body_force.as_ref().map(|f| f.times_per_evaluation()),
            data.damage_supply
                .as_ref()
                .map(|q| q.times_per_evaluation()),
        ];
        let Some(asked) = asked.iter().flatten().min().copied() else {
            return 1;
        };
        let bytes_per_time = (self.points.len() * (D + 1) * std::mem::size_of::<f64>()).max(1);
        asked.min(BULK_DATA_BYTES / bytes_per_time).max(1)
    }

    /// f0 and q of `data` at every cell quadrature point at each of `times`, chunk by chunk of
    /// cells in parallel (on each thread f0, then q, at the same points and times).
    pub fn bulk_data(&self, data: &Data<D>, times: &[f64]) -> BulkData<D> {
        self.bulk_data_into(data, times, BulkData::default())
    }

    /// [`LoadQuadrature::bulk_data`] in the buffers of `spent`, a block whose values are no
    /// longer needed: the fields write every value, so the buffers are neither cleared nor
    /// given back to the system and taken again (as fresh pages, faulted in and zeroed by
    /// the kernel) from one block to the next.
    pub fn bulk_data_into(&self, data: &Data<D>, times: &[f64], spent: BulkData<D>) -> BulkData<D> {
        let nq = self.tabulation.len();
        let chunk_points = CHUNK_CELLS * nq;
        let mut buffers = spent.chunks;
        buffers.resize_with(self.points.len().div_ceil(chunk_points), Default::default);
        let chunks = self
            .points
            .par_chunks(chunk_points)
            .zip(buffers.into_par_iter())
            .map(|(points, (mut force, mut supply))| {
                // (a length kept or cut initializes nothing; only a longer one fills its tail)
                match &data.body_force {
                    Some(f) => {
                        force.resize(points.len() * times.len(), [0.0; D]);
                        f.evaluate_at_times(points, times, &mut force);
                    }
                    None => force.clear(),
                }
                match &data.damage_supply {
                    Some(q) => {
                        supply.resize(points.len() * times.len(), 0.0);
                        q.evaluate_at_times(points, times, &mut supply);
                    }
                    None => supply.clear(),
                }
                (force, supply)
            })
            .collect();
        BulkData {
            times: times.iter().map(|t| t.to_bits()).collect(),
            points: self.points.len(),
            chunks,
        }
    }

    /// The load vectors of the step at `time` from the state (u_{n−1}, β_{n−1}): the velocity
    /// load (Cartesian, node-major) and the damage source ⟨φ(ε(u_{n−1}), β_{n−1}) + q(t_n),
    /// φ_a⟩ + ∫_Γ κ∂β/∂ν φ_a. f0 and q are read from `bulk` if it holds `time`, else
    /// evaluated now (bitwise the same values).
    pub fn assemble(
        &self,
        space: &LagrangeSpace<D>,
        model: &Model<D>,
        data: &Data<D>,
        time: f64,
        state: &State,
        bulk: Option<&BulkData<D>>,
    ) -> (Vec<f64>, Vec<f64>) {
        let bulk = bulk
            .filter(|block| block.points == self.points.len())
            .and_then(|block| Some((block, block.position(time)?)));
        let local = self.tabulation.nodes * (D + 1);
        let cells = space.mesh().num_cells();
        let mut velocity_load = vec![0.0; space.num_nodes() * D];
        let mut damage_source = vec![0.0; space.num_nodes()];
        // The element vectors of a wave of chunks, computed in parallel into one of two
        // buffers while the previous wave, in the other one, is summed in cell order.
        let wave_cells = WAVE_CHUNKS * CHUNK_CELLS;
        let mut buffers = [
            vec![0.0; wave_cells.min(cells) * local],
            vec![0.0; wave_cells.min(cells) * local],
        ];
        let compute = |first_cell: usize, buffer: &mut [f64]| {
            buffer
                .par_chunks_mut(CHUNK_CELLS * local)
                .enumerate()
                .for_each(|(k, out)| {
                    let first = first_cell + k * CHUNK_CELLS;
                    let bulk = bulk.map(|(block, at)| (&block.chunks[first / CHUNK_CELLS], at));
                    out.fill(0.0);
                    self.cell_chunk(space, model, data, time, state, bulk, first, out)
                });
        };
        let sum = |first_cell: usize,
                   buffer: &[f64],
                   velocity_load: &mut [f64],
                   damage_source: &mut [f64]| {
            for (c, element) in buffer.chunks_exact(local).enumerate() {
                for (a, &node) in space.cell_nodes(first_cell + c).iter().enumerate() {
                    for i in 0..D {
                        velocity_load[node * D + i] += element[a * (D + 1) + i];
                    }
                    damage_source[node] += element[a * (D + 1) + D];
                }
            }
        };
        // One entry into the thread pool for all waves (every parallel call from outside it
        // waits for a pool thread: tens of µs per wave).
        rayon::scope(|_| {
            // the wave whose element vectors wait to be summed: (first cell, cells, wave)
            let mut pending: Option<(usize, usize, usize)> = None;
            for (wave, first_cell) in (0..cells).step_by(wave_cells).enumerate() {
                let count = wave_cells.min(cells - first_cell);
                let [even, odd] = &mut buffers;
                let (current, previous) = if wave % 2 == 0 {
                    (even, odd)
                } else {
                    (odd, even)
                };
                let current = &mut current[..count * local];
                match pending {
                    Some((first, count, _)) => {
                        rayon::join(
                            || {
                                sum(
                                    first,
                                    &previous[..count * local],
                                    &mut velocity_load,
                                    &mut damage_source,
                                )
                            },
                            || compute(first_cell, current),
                        );
                    }
                    None => compute(first_cell, current),
                }
                pending = Some((first_cell, count, wave));
            }
            if let Some((first, count, wave)) = pending {
                sum(
                    first,
                    &buffers[wave % 2][..count * local],
                    &mut velocity_load,
                    &mut damage_source,
                );
            }
        });
        let vector_part = |facets: &FacetPoints<D>,
                           field: &dyn crate::model::fields::BatchBoundaryVectorField<D>,
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

    /// The element load vectors of the cells `first..` filling `out` (`(D + 1)` values per
    /// local node: the velocity load, then the damage source), one batch of field evaluations
    /// over all quadrature points of the chunk, or f0 and q read from the chunk's block
    /// `bulk` = (f0, q of the chunk, index of `time`).
    #[allow(clippy::too_many_arguments, clippy::type_complexity)]
    fn cell_chunk(
        &self,
        space: &LagrangeSpace<D>,
        model: &Model<D>,
        data: &Data<D>,
        time: f64,
        state: &State,
        bulk: Option<(&(Vec<[f64; D]>, Vec<f64>), usize)>,
        first: usize,
        out: &mut [f64],
    ) {
        let tab = &self.tabulation;
        let nq = tab.len();
        let count = out.len() / (tab.nodes * (D + 1));
        let range = first * nq..(first + count) * nq;
        let points = &self.points[range.clone()];
        let (mut own_force, mut own_supply) = (Vec::new(), Vec::new());
        let (force, supply): (&[[f64; D]], &[f64]) = match bulk {
            Some(((force, supply), at)) => {
                let at_time =
                    |values_per_time: usize| at * values_per_time..(at + 1) * values_per_time;
                (
                    if force.is_empty() {
                        &[]
                    } else {
                        &force[at_time(points.len())]
                    },
                    if supply.is_empty() {
                        &[]
                    } else {
                        &supply[at_time(points.len())]
                    },
                )
            }
            None => {
                if let Some(f) = &data.body_force {
                    own_force = vec![[0.0; D]; points.len()];
                    f.evaluate(points, time, &mut own_force);
                }
                if let Some(q) = &data.damage_supply {
                    own_supply = vec![0.0; points.len()];
                    q.evaluate(points, time, &mut own_supply);
                }
                (&own_force, &own_supply)
            }
        };
        let mut stress = Vec::new();
        if let Some(body_stress) = &data.body_stress {
            stress = vec![SMatrix::<f64, D, D>::zeros(); points.len()];
            body_stress.evaluate(points, time, &mut stress);
        }
        let chunk = Chunk {
            first,
            weights: &self.weights[range],
            force,
            supply,
            stress: &stress,
        };
        // P1 on affine simplices (D + 1 nodes): the basis gradients, hence ε(u_{n−1}), are
        // constant per cell.
        match (space.degree(), tab.nodes) {
            (1, 3) => self.affine_cells::<3>(space, model, state, &chunk, out),
            (1, 4) => self.affine_cells::<4>(space, model, state, &chunk, out),
            _ => self.pointwise_cells(space, model, state, &chunk, out),
        }
    }

    /// [`Self::cell_chunk`] for P1 on affine simplices with `N = D + 1` nodes: ε(u_{n−1}) once
    /// per cell, β_{n−1} at every point, φ over the chunk, then per cell the stress integrated
    /// first ([`crate::model::laws::Elasticity::weighted_stress_sum`], one evaluation of G for a law
    /// linear in β) and contracted with each basis gradient once. The element arrays have
    /// the fixed size of the element.
    fn affine_cells<const N: usize>(
        &self,
        space: &LagrangeSpace<D>,
        model: &Model<D>,
        state: &State,
        chunk: &Chunk<'_, D>,
        out: &mut [f64],
    ) {
        let tab = &self.tabulation;
        let nq = tab.len();
        let local = N * (D + 1);
        let count = out.len() / local;
        let (displacement, damage) = (&state.displacement, &state.damage);
        let reference_gradients: [SVector<f64, D>; N] = std::array::from_fn(|a| tab.gradients[a]);
        let mut strains = Vec::with_capacity(count);
        let mut gradients = Vec::with_capacity(count);
        let mut betas = vec![0.0; count * nq];
        for (c, cell_betas) in betas.chunks_exact_mut(nq).enumerate() {
            let cell = chunk.first + c;
            let geometry = space.geometry(cell);
            let nodes: &[usize; N] = space
                .cell_nodes(cell)
                .try_into()
                .expect("an affine P1 cell has N nodes");
            let grads: [SVector<f64, D>; N] =
                std::array::from_fn(|a| geometry.inverse_transpose * reference_gradients[a]);
            strains.push(field_strain(nodes, &grads, displacement));
            gradients.push(grads);
            let nodal: [f64; N] = std::array::from_fn(|a| damage[nodes[a]]);
            // β_{n−1} at the points of the cell
            for (beta, values) in cell_betas.iter_mut().zip(tab.values.chunks_exact(N)) {
                let mut sum = 0.0;
                for a in 0..N {
                    sum += nodal[a] * values[a];
                }
                *beta = sum;
            }
        }
        let mut sources = vec![0.0; betas.len()];
        model
            .damage_source
            .source_cells(&strains, &betas, &mut sources);
        let elasticity = model.elasticity.as_ref();
        let mut weighted_sources = vec![0.0; nq];
        for (c, out) in out.chunks_exact_mut(local).enumerate() {
            let cell_points = c * nq..(c + 1) * nq;
            let weights = &chunk.weights[cell_points.clone()];
            let mut stress =
                elasticity.weighted_stress_sum(&strains[c], &betas[cell_points.clone()], weights);
            if !chunk.stress.is_empty() {
                // the data's stress S enters as −S: the load is ∫ (S − G) : ε(w)
                for (weight, body_stress) in weights.iter().zip(&chunk.stress[cell_points.clone()])
                {
                    stress -= body_stress * *weight;
                }
            }
            for (a, grad) in gradients[c].iter().enumerate() {
                let internal = stress * grad;
                for i in 0..D {
                    out[a * (D + 1) + i] -= internal[i];
                }
            }
            if !chunk.force.is_empty() {
                let force = &chunk.force[cell_points.clone()];
                for ((values, weight), f) in tab.values.chunks_exact(N).zip(weights).zip(force) {
                    for a in 0..N {
                        for i in 0..D {
                            out[a * (D + 1) + i] += weight * (f[i] * values[a]);
                        }
                    }
                }
            }
            self.add_damage_sources(chunk, &sources, c, &mut weighted_sources, out);
        }
    }

    /// [`Self::cell_chunk`] for any element: ε(u_{n−1}) and β_{n−1} at every point of the
    /// chunk, φ over the batch, then G at every point contracted with the basis gradients
    /// there.
    fn pointwise_cells(
        &self,
        space: &LagrangeSpace<D>,
        model: &Model<D>,
        state: &State,
        chunk: &Chunk<'_, D>,
        out: &mut [f64],
    ) {
        let elasticity = model.elasticity.as_ref();
        let (displacement, damage) = (&state.displacement, &state.damage);
        let tab = &self.tabulation;
        let n = tab.nodes;
        let nq = tab.len();
        let local = n * (D + 1);
        let count = out.len() / local;
        let mut grads = [SVector::<f64, D>::zeros(); crate::fem::element::MAX_CELL_NODES];
        let mut strains = Vec::with_capacity(count * nq);
        let mut betas = Vec::with_capacity(count * nq);
        let mut point_grads = Vec::with_capacity(count * nq * n);
        let mut nodal_damage = [0.0; crate::fem::element::MAX_CELL_NODES];
        for c in 0..count {
            let cell = chunk.first + c;
            let nodes = space.cell_nodes(cell);
            for (value, &node) in nodal_damage.iter_mut().zip(nodes) {
                *value = damage[node];
            }
            for q in 0..nq {
                let geometry = space.geometry_at(cell, &tab.points[q]);
                physical_gradients(&geometry, tab, q, &mut grads);
                strains.push(field_strain(nodes, &grads[..n], displacement));
                point_grads.extend_from_slice(&grads[..n]);
                let values = &tab.values[q * n..(q + 1) * n];
                // β_{n−1} at the point
                let mut beta = 0.0;
                for (b, v) in nodal_damage[..n].iter().zip(values) {
                    beta += b * v;
                }
                betas.push(beta);
            }
        }
        let mut sources = vec![0.0; betas.len()];
        model
            .damage_source
            .source_batch(&strains, &betas, &mut sources);
        let mut weighted_sources = vec![0.0; nq];
        for (c, out) in out.chunks_mut(local).enumerate() {
            for q in 0..nq {
                let p = c * nq + q;
                let values = &tab.values[q * n..(q + 1) * n];
                let weight = chunk.weights[p];
                let grads = &point_grads[p * n..(p + 1) * n];
                let mut stress = elasticity.stress(&strains[p], betas[p]);
                if !chunk.stress.is_empty() {
                    stress -= chunk.stress[p];
                }
                for (a, grad) in grads.iter().enumerate() {
                    let internal = stress * grad;
                    for i in 0..D {
                        out[a * (D + 1) + i] -= weight * internal[i];
                    }
                }
                if !chunk.force.is_empty() {
                    for (a, value) in values.iter().enumerate() {
                        for i in 0..D {
                            out[a * (D + 1) + i] += weight * (chunk.force[p][i] * value);
                        }
                    }
                }
            }
            self.add_damage_sources(chunk, &sources, c, &mut weighted_sources, out);
        }
    }

    /// ⟨φ + q, φ_a⟩ on cell `c` of `chunk` added to its element vector `out` (the last of the
    /// `D + 1` values of each node): the weighted sources of its points (`sources` = φ at the
    /// points of the chunk, `weighted` a scratch of one value per point), one sum per node.
    // inlined into both cell loops: as a call per cell the loads at 128² took about 3 % longer
    #[inline(always)]
    fn add_damage_sources(
        &self,
        chunk: &Chunk<'_, D>,
        sources: &[f64],
        c: usize,
        weighted: &mut [f64],
        out: &mut [f64],
    ) {
        let nq = weighted.len();
        for (q, weighted) in weighted.iter_mut().enumerate() {
            let p = c * nq + q;
            let supplied = if chunk.supply.is_empty() {
                0.0
            } else {
                chunk.supply[p]
            };
            *weighted = chunk.weights[p] * (sources[p] + supplied);
        }
        for (a, node_values) in self.values_by_node.chunks_exact(nq).enumerate() {
            let mut sum = 0.0;
            for (weighted, value) in weighted.iter().zip(node_values) {
                sum += weighted * value;
            }
            out[a * (D + 1) + D] += sum;
        }
    }
}

/// The per-point data of a chunk of cells for [`LoadQuadrature::cell_chunk`]: its first cell,
/// reference weight × |det J| of its points, f0, q and the data's stress S there (empty when
/// the data lack them).
struct Chunk<'a, const D: usize> {
    first: usize,
    weights: &'a [f64],
    force: &'a [[f64; D]],
    supply: &'a [f64],
    stress: &'a [SMatrix<f64, D, D>],
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::mesh::{BoundaryPart::*, Mesh};
    use crate::model::laws::{
        DamagedHooke, LinearViscosity, NormalComplianceCoulomb, TruncatedFremond,
    };
    use std::sync::Arc;

    fn model<const D: usize>() -> Model<D> {
        Model {
            viscosity: Arc::new(LinearViscosity {
                shear: 1.0,
                bulk: 0.5,
            }),
            elasticity: Arc::new(DamagedHooke {
                shear_modulus: 1.3,
                lame_lambda: 0.7,
            }),
            damage_source: Arc::new(TruncatedFremond {
                lambda_d: 0.1,
                lambda_w: 0.05,
                damage_floor: 0.1,
                strain_energy_cap: 10.0,
            }),
            contact: Arc::new(NormalComplianceCoulomb {
                stiffness: 10.0,
                friction: 0.4,
                wear: 0.0,
            }),
            damage_diffusion: 0.1,
        }
    }

    fn data<const D: usize>() -> Data<D> {
        Data {
            body_force: None,
            body_stress: None,
            traction: None,
            contact_traction: None,
            damage_supply: None,
            damage_flux: None,
            gap: Arc::new(|_, _| 0.0),
            dirichlet: Vec::new(),
            initial_displacement: Arc::new(|_| [0.0; D]),
            initial_damage: Arc::new(|_| 1.0),
            jump_planes: Vec::new(),
        }
    }

    /// −(G(ε(u), β), ε(w)) and (φ(ε(u), β), ζ) point by point, the textbook way.
    fn reference<const D: usize>(
        space: &LagrangeSpace<D>,
        model: &Model<D>,
        state: &State,
    ) -> (Vec<f64>, Vec<f64>) {
        let tab = Tabulation::cell_rule(
            space.element(),
            &QuadratureRule::<D>::simplex(2 * space.degree() + 2),
        );
        let n = tab.nodes;
        let mut velocity = vec![0.0; space.num_nodes() * D];
        let mut damage = vec![0.0; space.num_nodes()];
        let mut grads = [SVector::<f64, D>::zeros(); crate::fem::element::MAX_CELL_NODES];
        for cell in 0..space.mesh().num_cells() {
            let nodes = space.cell_nodes(cell);
            for q in 0..tab.len() {
                let geometry = space.geometry_at(cell, &tab.points[q]);
                physical_gradients(&geometry, &tab, q, &mut grads);
                let values = &tab.values[q * n..(q + 1) * n];
                let strain = field_strain(nodes, &grads[..n], &state.displacement);
                let beta: f64 = nodes
                    .iter()
                    .zip(values)
                    .map(|(&node, v)| state.damage[node] * v)
                    .sum();
                let weight = tab.weights[q] * geometry.det;
                let stress = model.elasticity.stress(&strain, beta);
                let mut source = [0.0];
                model
                    .damage_source
                    .source_batch(&[strain], &[beta], &mut source);
                for a in 0..n {
                    let internal = stress * grads[a];
                    for i in 0..D {
                        velocity[nodes[a] * D + i] -= weight * internal[i];
                    }
                    damage[nodes[a]] += weight * source[0] * values[a];
                }
            }
        }
        (velocity, damage)
    }

    fn loads_match_the_pointwise_assembly<const D: usize>(mesh: Mesh<D>) {
        let mesh = Arc::new(mesh);
        for degree in [1, 2] {
            let space = LagrangeSpace::new(mesh.clone(), degree).unwrap();
            let nodes = space.nodes();
            let state = State {
                step: 0,
                time: 0.0,
                displacement: nodes
                    .iter()
                    .flat_map(|x| {
                        let mut u = [0.0; D];
                        for (i, value) in u.iter_mut().enumerate() {
                            *value = 0.1 * ((i + 1) as f64 * x[0] + x[D - 1] * x[0]).sin();
                        }
                        u
                    })
                    .collect(),
                velocity: vec![0.0; nodes.len() * D],
                damage: nodes
                    .iter()
                    .map(|x| 0.3 + 0.6 * (3.0 * x[1]).cos().abs())
                    .collect(),
                previous_damage: Vec::new(),
            };
            let (model, data) = (model::<D>(), data::<D>());
            let loads =
                LoadQuadrature::new(&space).assemble(&space, &model, &data, 0.0, &state, None);
            let expected = reference(&space, &model, &state);
            for (computed, expected) in [(&loads.0, &expected.0), (&loads.1, &expected.1)] {
                let scale = expected.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
                assert!(scale > 0.0);
                for (c, e) in computed.iter().zip(expected) {
                    assert!(
                        (c - e).abs() <= 1e-13 * scale,
                        "D = {D}, l = {degree}: {c} vs {e}"
                    );
                }
            }
        }
    }

    /// The P1 path integrates the stresses of a cell before contracting them with the
    /// (constant) basis gradients; it must agree with the point-by-point assembly, and the P2
    /// path with it too.
    #[test]
    fn loads_match_the_pointwise_assembly_in_2d_and_3d() {
        let sides2 = [[Dirichlet, Neumann], [Contact, Neumann]];
        loads_match_the_pointwise_assembly(
            Mesh::box_mesh([0.0, 0.0], [1.0, 0.7], [5, 4], sides2).unwrap(),
        );
        // more cells than two waves (the last one partial): the element vectors of one wave
        // are summed while the next is computed
        let cells = [64, 70];
        assert!(cells[0] * cells[1] * 2 > 2 * WAVE_CHUNKS * CHUNK_CELLS);
        loads_match_the_pointwise_assembly(
            Mesh::box_mesh([0.0, 0.0], [1.0, 0.7], cells, sides2).unwrap(),
        );
        let sides3 = [[Dirichlet, Neumann], [Neumann, Neumann], [Contact, Neumann]];
        loads_match_the_pointwise_assembly(
            Mesh::box_mesh([0.0; 3], [1.0, 0.8, 0.6], [3, 3, 2], sides3).unwrap(),
        );
    }

    /// A stress S given as data is the body force −Div S with the traction Sν (Green's
    /// formula): for a field S linear in x, which every rule integrates exactly, both loads
    /// agree at every node off Γ1 (on Γ1 the stress form also holds the reaction Sν, which the
    /// scheme drops with the constrained rows).
    fn stress_form_matches_its_divergence_and_traction<const D: usize>(mesh: Mesh<D>) {
        use nalgebra::SMatrix;
        // S_ij(x) = c_ij + Σ_k a_ijk x_k, symmetric
        let stress = |x: &[f64; D]| {
            SMatrix::<f64, D, D>::from_fn(|i, j| {
                let (low, high) = (i.min(j), i.max(j));
                let mut value = 0.3 + 0.1 * (low + 2 * high) as f64;
                for (k, xk) in x.iter().enumerate() {
                    value += 0.05 * ((low + 1) * (high + 2) + k) as f64 * xk;
                }
                value
            })
        };
        // −Div S: the constant −Σ_j ∂_j S_ij
        let divergence: [f64; D] = std::array::from_fn(|i| {
            -(0..D)
                .map(|j| {
                    let (low, high) = (i.min(j), i.max(j));
                    0.05 * ((low + 1) * (high + 2) + j) as f64
                })
                .sum::<f64>()
        });
        let traction = move |x: &[f64; D], _t: f64, normal: &[f64; D]| {
            let sigma_n = stress(x) * SVector::<f64, D>::from_column_slice(normal);
            std::array::from_fn(|i| sigma_n[i])
        };
        let mesh = Arc::new(mesh);
        for degree in [1, 2] {
            let space = LagrangeSpace::new(mesh.clone(), degree).unwrap();
            let state = State {
                step: 0,
                time: 0.0,
                displacement: vec![0.0; space.num_nodes() * D],
                velocity: vec![0.0; space.num_nodes() * D],
                damage: vec![1.0; space.num_nodes()],
                previous_damage: Vec::new(),
            };
            let model = model::<D>();
            let stress_form = Data {
                body_stress: Some(Arc::new(move |x: &[f64; D], _t: f64| stress(x))),
                ..data::<D>()
            };
            let divergence_form = Data {
                body_force: Some(Arc::new(move |_x: &[f64; D], _t: f64| divergence)),
                traction: Some(Arc::new(traction)),
                contact_traction: Some(Arc::new(traction)),
                ..data::<D>()
            };
            let quadrature = LoadQuadrature::new(&space);
            let (weak, _) = quadrature.assemble(&space, &model, &stress_form, 0.0, &state, None);
            let (strong, _) =
                quadrature.assemble(&space, &model, &divergence_form, 0.0, &state, None);
            let on_gamma1 = space.boundary_nodes(BoundaryPart::Dirichlet);
            let scale = strong.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            assert!(scale > 0.0);
            let mut compared = 0;
            for node in (0..space.num_nodes()).filter(|n| !on_gamma1.contains(n)) {
                for i in 0..D {
                    let (w, s) = (weak[node * D + i], strong[node * D + i]);
                    assert!(
                        (w - s).abs() <= 1e-12 * scale,
                        "D = {D}, l = {degree}, node {node}, component {i}: {w} vs {s}"
                    );
                    compared += 1;
                }
            }
            assert!(compared > 0);
        }
    }

    /// A block evaluated in the buffers of a spent one (longer, shorter, or lacking a field)
    /// holds bitwise the values of a block evaluated afresh.
    #[test]
    fn a_block_in_spent_buffers_is_bitwise_a_fresh_block() {
        let sides = [[Dirichlet, Neumann], [Contact, Neumann]];
        let mesh = Arc::new(Mesh::box_mesh([0.0, 0.0], [1.0, 0.7], [9, 8], sides).unwrap());
        let space = LagrangeSpace::new(mesh, 1).unwrap();
        let quadrature = LoadQuadrature::new(&space);
        let fields = Data {
            body_force: Some(Arc::new(|x: &[f64; 2], t: f64| {
                [x[0] * t + 1.0, (x[1] - t).sin()]
            })),
            damage_supply: Some(Arc::new(|x: &[f64; 2], t: f64| x[0] * x[1] + t * t)),
            ..data::<2>()
        };
        let bits = |block: &BulkData<2>| -> Vec<u64> {
            block
                .chunks
                .iter()
                .flat_map(|(force, supply)| {
                    force.iter().flatten().chain(supply).map(|v| v.to_bits())
                })
                .collect()
        };
        let times = [0.25, 0.5, 0.75];
        let fresh = quadrature.bulk_data(&fields, &times);
        assert!(bits(&fresh).iter().any(|&b| b != 0));
        for spent_times in [&[0.1, 0.2, 0.3, 0.4, 0.5][..], &[0.9], &times] {
            let spent = quadrature.bulk_data(&fields, spent_times);
            let recycled = quadrature.bulk_data_into(&fields, &times, spent);
            assert_eq!(bits(&recycled), bits(&fresh), "spent at {spent_times:?}");
            assert!(recycled.holds(0.5) && !recycled.holds(0.1));
        }
        // a spent block of data with f0 and q, reused for data without q
        let without_supply = Data {
            damage_supply: None,
            ..fields.clone()
        };
        let spent = quadrature.bulk_data(&fields, &times);
        let recycled = quadrature.bulk_data_into(&without_supply, &times, spent);
        assert!(recycled.chunks.iter().all(|(_, supply)| supply.is_empty()));
        assert_eq!(
            bits(&recycled),
            bits(&quadrature.bulk_data(&without_supply, &times))
        );
    }

    #[test]
    fn a_stress_given_as_data_is_its_divergence_with_its_traction() {
        let sides2 = [[Dirichlet, Neumann], [Contact, Neumann]];
        stress_form_matches_its_divergence_and_traction(
            Mesh::box_mesh([0.0, 0.0], [1.0, 0.7], [5, 4], sides2).unwrap(),
        );
        let sides3 = [[Dirichlet, Neumann], [Neumann, Neumann], [Contact, Neumann]];
        stress_form_matches_its_divergence_and_traction(
            Mesh::box_mesh([0.0; 3], [1.0, 0.8, 0.6], [3, 3, 2], sides3).unwrap(),
        );
    }
}
