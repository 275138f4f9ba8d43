//! The error quantity E(h, k) of Theorem 5.2 (docs/model.md §4), component by component:
//!
//! - `displacement`: max_n ‖u(t_n) − u_n^hk‖_V, with ‖w‖_V = ‖ε(w)‖_{L²} (3.3);
//! - `difference_quotient`: max_n ‖δu_n − δu_n^hk‖_V, δu_n = (u(t_n) − u(t_{n−1}))/k, δu_n^hk = v_n;
//! - `damage`: max_n ‖β(t_n) − β_n^hk‖_{L²};
//! - `damage_gradient`: (k Σ_n ‖∇(β(t_n) − β_n^hk)‖²_{L²})^{1/2};
//! - `total` = the sum of the four (E(h, k));
//! - `velocity`: max_n ‖u̇(t_n) − v_n‖_V (reported, not bounded by the theorem as stated).
//!
//! Integrals use a cell quadrature of degree 2l + 3 against the exact fields, or, for a
//! temporal self-convergence study, against a reference discrete solution on the same mesh.
//! The exact fields are evaluated by the case's compiled program over all quadrature points of
//! a chunk of cells at once, for a block of up to [`STATES_PER_BLOCK`] steps (the states are
//! kept until the block is full); chunks run in parallel and their sums are added in chunk
//! order, step by step, so the errors do not depend on the number of threads or the blocks.
//! Within a batch of points the squared differences are formed column by column (vectorized,
//! `exact_batch`) and added to the sums in point order: bitwise the sums of the point-by-point
//! evaluation.

mod exact_batch;

use crate::manufactured::data::ExactPrograms;
use crate::manufactured::programs::{Quantity, BATCH};
use contact_damage::fem::quadrature::QuadratureRule;
use contact_damage::fem::space::{LagrangeSpace, Tabulation};
use contact_damage::model::laws::Tensor;
use contact_damage::scheme::assembly::{field_strain, physical_gradients};
use contact_damage::scheme::State;
use exact_batch::{accumulate_batch, Batch, DiscreteColumns, ExactColumns, TensorColumns, Terms};
use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;
use serde::Serialize;
use std::sync::Arc;

/// The components of E(h, k) and the velocity error.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct ErrorComponents {
    /// max_n ‖ε(u(t_n) − u_n)‖.
    pub displacement: f64,
    /// max_n ‖ε(δu_n − δu_n^hk)‖.
    pub difference_quotient: f64,
    /// max_n ‖β(t_n) − β_n‖.
    pub damage: f64,
    /// (k Σ ‖∇(β(t_n) − β_n)‖²)^{1/2}.
    pub damage_gradient: f64,
    /// E(h, k): the sum of the four components above.
    pub total: f64,
    /// max_n ‖ε(u̇(t_n) − v_n)‖ (NaN when the reference is discrete).
    pub velocity: f64,
}

impl ErrorComponents {
    /// Names of the components, in the order of [`ErrorComponents::values`].
    pub const NAMES: [&'static str; 6] = [
        "displacement",
        "difference_quotient",
        "damage",
        "damage_gradient",
        "total",
        "velocity",
    ];

    /// The components in the order of [`ErrorComponents::NAMES`].
    pub fn values(&self) -> [f64; 6] {
        [
            self.displacement,
            self.difference_quotient,
            self.damage,
            self.damage_gradient,
            self.total,
            self.velocity,
        ]
    }
}

fn sym<const D: usize>(m: &SMatrix<f64, D, D>) -> Tensor<D> {
    (m + m.transpose()) * 0.5
}

/// Cells per parallel task of the error integrals.
const CHUNK_CELLS: usize = 32;

/// What the discrete solution is compared with.
pub enum Reference<const D: usize> {
    /// The manufactured exact solution (its compiled programs).
    Exact(Arc<ExactPrograms<D>>),
    /// A discrete solution on the same space; `states[i]` is the state at time `i·T/(states.len()−1)`.
    Discrete(Arc<Vec<State>>),
}

/// The gradients of the discrete solution at a point: ε(u_h), ε(v_h) and ∇β_h (on an affine
/// P1 cell the same at every point of the cell).
#[derive(Clone, Copy)]
struct CellFields<const D: usize> {
    strain: Tensor<D>,
    /// ε(v_n).
    rate: Tensor<D>,
    damage_gradient: SVector<f64, D>,
}

/// The discrete solution at one quadrature point.
struct DiscretePoint<const D: usize> {
    fields: CellFields<D>,
    damage: f64,
    /// Quadrature weight × |det J|.
    weight: f64,
}

/// The discrete quantities that are constant on an affine P1 cell: ε(u_h), ε(v_h), ∇β_h and
/// the discrete reference's ε(u), ε(u) at the previous time and ∇β.
#[derive(Clone, Copy)]
struct CellGradients<const D: usize> {
    fields: CellFields<D>,
    reference: (Tensor<D>, Tensor<D>, SVector<f64, D>),
}

/// ∇ of a nodal scalar field on a cell, from the physical basis gradients of its nodes.
fn scalar_gradient<const D: usize>(
    nodes: &[usize],
    grads: &[SVector<f64, D>],
    nodal: &[f64],
) -> SVector<f64, D> {
    nodes
        .iter()
        .enumerate()
        .map(|(a, &node)| grads[a] * nodal[node])
        .fold(SVector::<f64, D>::zeros(), |acc, g| acc + g)
}

/// ε(u_h), ε(v_h) and ∇β_h of `state` on a cell, from the physical basis gradients of its
/// nodes at a point.
fn cell_fields<const D: usize>(
    nodes: &[usize],
    grads: &[SVector<f64, D>],
    state: &State,
) -> CellFields<D> {
    CellFields {
        strain: field_strain(nodes, grads, &state.displacement),
        rate: field_strain(nodes, grads, &state.velocity),
        damage_gradient: scalar_gradient(nodes, grads, &state.damage),
    }
}

/// A nodal scalar field at a point, from the basis values there.
fn scalar_value(nodes: &[usize], values: &[f64], nodal: &[f64]) -> f64 {
    nodes
        .iter()
        .zip(values)
        .map(|(&node, v)| nodal[node] * v)
        .sum()
}

/// What the discrete solution is compared with at one quadrature point.
struct ReferencePoint<const D: usize> {
    strain: Tensor<D>,
    /// ε(δu_n).
    quotient: Tensor<D>,
    /// ε(u̇(t_n)) (None for a discrete reference).
    rate: Option<Tensor<D>>,
    damage: f64,
    damage_gradient: SVector<f64, D>,
}

/// Adds the weighted squared differences of one point to `local` = [u, δu, β, ∇β, v] (the
/// last NaN for a discrete reference, which has no ε(u̇)).
#[inline(always)]
fn accumulate<const D: usize>(
    local: &mut [f64; 5],
    discrete: &DiscretePoint<D>,
    reference: &ReferencePoint<D>,
) {
    accumulate_parts(
        local,
        discrete.weight,
        &discrete.fields,
        discrete.damage,
        reference,
    );
}

/// [`accumulate`] with the discrete values of the point given apart: its weight, its
/// gradients (those of its cell for affine P1) and β_h there.
#[inline(always)]
fn accumulate_parts<const D: usize>(
    local: &mut [f64; 5],
    weight: f64,
    discrete: &CellFields<D>,
    damage: f64,
    reference: &ReferencePoint<D>,
) {
    local[0] += weight * (reference.strain - discrete.strain).norm_squared();
    local[1] += weight * (reference.quotient - discrete.rate).norm_squared();
    local[2] += weight * (reference.damage - damage).powi(2);
    local[3] += weight * (reference.damage_gradient - discrete.damage_gradient).norm_squared();
    if let Some(rate) = reference.rate {
        local[4] += weight * (rate - discrete.rate).norm_squared();
    } else {
        local[4] = f64::NAN;
    }
}

/// The discrete solution `state` at every quadrature point of `cells` (cell-major) into
/// `discrete`, and the discrete reference (its state, the previous reference displacement and
/// k) at the same points into `references`. Affine P1
/// (`constant_gradients`): the gradients, hence the strains and the damage gradients, are the
/// same at every point of a cell and computed once.
#[allow(clippy::too_many_arguments)]
fn discrete_points<const D: usize>(
    space: &LagrangeSpace<D>,
    tab: &Tabulation<D>,
    constant_gradients: bool,
    state: &State,
    (reference, previous_displacement, k): (&State, &[f64], f64),
    cells: std::ops::Range<usize>,
    discrete: &mut Vec<DiscretePoint<D>>,
    references: &mut Vec<ReferencePoint<D>>,
) {
    let (nq, n_nodes) = (tab.len(), tab.nodes);
    let mut grads = [SVector::<f64, D>::zeros(); contact_damage::fem::element::MAX_CELL_NODES];
    for cell in cells {
        let nodes = space.cell_nodes(cell);
        let mut gradients_at = None;
        for q in 0..nq {
            let geometry = space.geometry_at(cell, &tab.points[q]);
            let cell_values = match gradients_at {
                Some(values) if constant_gradients => values,
                _ => {
                    physical_gradients(&geometry, tab, q, &mut grads);
                    let grads = &grads[..n_nodes];
                    let values = CellGradients {
                        fields: cell_fields(nodes, grads, state),
                        reference: (
                            field_strain(nodes, grads, &reference.displacement),
                            field_strain(nodes, grads, previous_displacement),
                            scalar_gradient(nodes, grads, &reference.damage),
                        ),
                    };
                    gradients_at = Some(values);
                    values
                }
            };
            let values = &tab.values[q * n_nodes..(q + 1) * n_nodes];
            discrete.push(DiscretePoint {
                fields: cell_values.fields,
                damage: scalar_value(nodes, values, &state.damage),
                weight: tab.weights[q] * geometry.det,
            });
            let (strain, previous, damage_gradient) = cell_values.reference;
            references.push(ReferencePoint {
                strain,
                quotient: (strain - previous) / k,
                rate: None,
                damage: scalar_value(nodes, values, &reference.damage),
                damage_gradient,
            });
        }
    }
}

/// The discrete solutions of a block of states on the cells of a chunk, state after state:
/// ε(u_h), ε(v_h) and ∇β_h once per cell on affine P1 cells (`constant_gradients`), else once
/// per quadrature point, and β_h at every quadrature point.
struct DiscreteChunk<const D: usize> {
    fields: Vec<CellFields<D>>,
    damage: Vec<f64>,
}

impl<const D: usize> DiscreteChunk<D> {
    fn new(
        space: &LagrangeSpace<D>,
        tab: &Tabulation<D>,
        constant_gradients: bool,
        states: &[State],
        cells: std::ops::Range<usize>,
    ) -> Self {
        let (nq, n_nodes) = (tab.len(), tab.nodes);
        let per_state = cells.len() * nq;
        let fields_per_state = if constant_gradients {
            cells.len()
        } else {
            per_state
        };
        let zero = CellFields {
            strain: Tensor::<D>::zeros(),
            rate: Tensor::<D>::zeros(),
            damage_gradient: SVector::<f64, D>::zeros(),
        };
        let mut fields = vec![zero; states.len() * fields_per_state];
        let mut damage = vec![0.0; states.len() * per_state];
        let mut grads = [SVector::<f64, D>::zeros(); contact_damage::fem::element::MAX_CELL_NODES];
        for (c, cell) in cells.enumerate() {
            let nodes = space.cell_nodes(cell);
            for q in 0..nq {
                let point = c * nq + q;
                if q == 0 || !constant_gradients {
                    let geometry = space.geometry_at(cell, &tab.points[q]);
                    physical_gradients(&geometry, tab, q, &mut grads);
                    let at = if constant_gradients { c } else { point };
                    for (s, state) in states.iter().enumerate() {
                        fields[s * fields_per_state + at] =
                            cell_fields(nodes, &grads[..n_nodes], state);
                    }
                }
                let values = &tab.values[q * n_nodes..(q + 1) * n_nodes];
                for (s, state) in states.iter().enumerate() {
                    damage[s * per_state + point] = scalar_value(nodes, values, &state.damage);
                }
            }
        }
        Self { fields, damage }
    }
}

/// Accumulates the error components over the steps of one run (used inside the observer).
pub struct ErrorTracker<const D: usize> {
    reference: Reference<D>,
    tabulation: Tabulation<D>,
    /// The reference gradients are the same at every quadrature point (P1): the discrete
    /// gradients are then computed once per cell.
    constant_gradients: bool,
    /// Physical quadrature points, cell-major.
    points: Vec<[f64; D]>,
    /// Their weights × |det J|.
    weights: Vec<f64>,
    time_step: f64,
    steps: usize,
    /// Reference ε(u) at the quadrature points at the previous time.
    previous_strain: Vec<Tensor<D>>,
    /// The buffer of the next step's exact strains (the previous step's, reused: no
    /// allocation per step).
    spare_strain: Vec<Tensor<D>>,
    /// The previous reference state index or discrete displacement (discrete reference).
    previous_displacement: Vec<f64>,
    /// The states observed but not yet compared with the exact solution (at most
    /// `states_per_block`; see [`ErrorTracker::observe`]).
    pending: Vec<State>,
    states_per_block: usize,
    errors: ErrorComponents,
    gradient_sum: f64,
}

/// Most states an [`ErrorTracker`] keeps before it compares them with the exact solution.
/// The exact fields are then evaluated for all of them at once, and the time-independent
/// values of their program (17 per point in 2D) are read from memory once for the block: on
/// `zones2d` at 128 cells (229 376 points per step), one thread, 16.6 ns per point and step
/// with one state per evaluation, 13.6 with 8, 13.0 with 16 (`QuantityProgram`
/// micro-benchmark), and the exact ε(u(t_{n−1})) of the difference quotient is stored once
/// per block instead of once per step. 16 rather than 8, as
/// [`crate::manufactured::data::TIMES_PER_EVALUATION`]: `bench_harness` zones2d 128 cells,
/// one thread, four interleaved pairs, (data + errors) over the solves 1.16 / 1.16 / 1.13 /
/// 1.21 with 8 → 1.10 / 1.05 / 1.07 / 1.07 with 16; 32 with 32 times per evaluation is no
/// better.
pub const STATES_PER_BLOCK: usize = 16;

/// Most bytes the pending states of an [`ErrorTracker`] may hold.
const PENDING_BYTES: usize = 64 << 20;

impl<const D: usize> ErrorTracker<D> {
    /// A tracker for a run with N = `steps` steps of size k on `space`.
    pub fn new(
        space: &LagrangeSpace<D>,
        reference: Reference<D>,
        time_step: f64,
        steps: usize,
    ) -> Self {
        let rule = QuadratureRule::<D>::simplex(2 * space.degree() + 3);
        let tabulation = Tabulation::cell_rule(space.element(), &rule);
        let points = (0..space.mesh().num_cells())
            .flat_map(|cell| {
                tabulation
                    .points
                    .iter()
                    .map(move |xi| space.point_at(cell, xi))
            })
            .collect();
        let weights = (0..space.mesh().num_cells())
            .flat_map(|cell| {
                tabulation
                    .points
                    .iter()
                    .zip(&tabulation.weights)
                    .map(move |(xi, w)| w * space.geometry_at(cell, xi).det)
            })
            .collect();
        let nodes = tabulation.nodes;
        let constant_gradients = tabulation
            .gradients
            .chunks(nodes)
            .all(|at_point| at_point == &tabulation.gradients[..nodes]);
        let mut tracker = Self {
            reference,
            constant_gradients,
            tabulation,
            points,
            weights,
            time_step,
            steps,
            previous_strain: Vec::new(),
            spare_strain: Vec::new(),
            previous_displacement: Vec::new(),
            pending: Vec::new(),
            states_per_block: {
                let bytes = (space.num_nodes() * (2 * D + 1) * std::mem::size_of::<f64>()).max(1);
                STATES_PER_BLOCK.min(PENDING_BYTES / bytes).max(1)
            },
            errors: ErrorComponents::default(),
            gradient_sum: 0.0,
        };
        match &tracker.reference {
            Reference::Exact(exact) => {
                let exact = exact.clone();
                tracker.previous_strain = tracker.exact_strains(space, &exact, 0.0);
            }
            Reference::Discrete(states) => {
                tracker.previous_displacement = states[0].displacement.clone()
            }
        }
        tracker
    }

    /// ε(u(t)) at every quadrature point.
    fn exact_strains(
        &self,
        space: &LagrangeSpace<D>,
        exact: &ExactPrograms<D>,
        t: f64,
    ) -> Vec<Tensor<D>> {
        let nq = self.tabulation.len();
        let mut strains = vec![Tensor::<D>::zeros(); space.mesh().num_cells() * nq];
        strains
            .par_chunks_mut(CHUNK_CELLS * nq)
            .enumerate()
            .for_each(|(chunk, out)| {
                let first = chunk * CHUNK_CELLS * nq;
                let points = &self.points[first..first + out.len()];
                exact.errors.for_batches(points, t, |offset, columns| {
                    let gradient: [[&[f64]; D]; D] = std::array::from_fn(|i| {
                        std::array::from_fn(|j| columns.get(Quantity::Gradient(i, j)))
                    });
                    for (p, slot) in out[offset..].iter_mut().take(BATCH).enumerate() {
                        *slot = sym(&SMatrix::from_fn(|i, j| gradient[i][j][p]));
                    }
                });
            });
        strains
    }

    /// Adds the errors of the state after step n (a state of the run of `steps` steps, in
    /// order). Against the exact solution the states are kept and compared in blocks of up
    /// to [`STATES_PER_BLOCK`], the last block at step N; the sums of every step, hence
    /// the errors, are bitwise those of one comparison per step.
    pub fn observe(&mut self, space: &LagrangeSpace<D>, state: &State) {
        let exact = match &self.reference {
            Reference::Exact(exact) => exact.clone(),
            Reference::Discrete(_) => return self.observe_discrete(space, state),
        };
        self.pending.push(State {
            step: state.step,
            time: state.time,
            displacement: state.displacement.clone(),
            velocity: state.velocity.clone(),
            damage: state.damage.clone(),
            previous_damage: Vec::new(),
        });
        if self.pending.len() >= self.states_per_block || state.step >= self.steps {
            self.compare_pending(space, &exact);
        }
    }

    /// Compares the pending states with the exact solution `exact`, in step order.
    fn compare_pending(&mut self, space: &LagrangeSpace<D>, exact: &ExactPrograms<D>) {
        let states = std::mem::take(&mut self.pending);
        if states.is_empty() {
            return;
        }
        let tab = &self.tabulation;
        let nq = tab.len();
        let k = self.time_step;
        let times: Vec<f64> = states.iter().map(|state| state.time).collect();
        let mut new_strain = std::mem::take(&mut self.spare_strain);
        new_strain.resize(space.mesh().num_cells() * nq, Tensor::<D>::zeros());
        let previous_strain = &self.previous_strain;
        let points = &self.points;
        let weights = &self.weights;
        let constant_gradients = self.constant_gradients;
        // Per chunk: the weighted squared differences [u, δu, β, ∇β, v] of each state.
        let chunk_sums: Vec<Vec<[f64; 5]>> = new_strain
            .par_chunks_mut(CHUNK_CELLS * nq)
            .enumerate()
            .map(|(chunk, strain_out)| {
                let first_cell = chunk * CHUNK_CELLS;
                let cells = strain_out.len() / nq;
                let per_state = cells * nq;
                let discrete = DiscreteChunk::new(
                    space,
                    tab,
                    constant_gradients,
                    &states,
                    first_cell..first_cell + cells,
                );
                let fields_per_state = if constant_gradients { cells } else { per_state };
                let mut local = vec![[0.0; 5]; states.len()];
                // ε(u) at the points of the batch at the previous time, and the discrete
                // fields of the batch, as columns.
                let mut previous: TensorColumns<D> = [[[0.0; BATCH]; D]; D];
                let mut discrete_columns = DiscreteColumns::<D>::new();
                let mut terms: Terms = [[0.0; BATCH]; 5];
                let first_point = first_cell * nq;
                let range = first_point..first_point + per_state;
                let weights = &weights[range.clone()];
                let last = states.len() - 1;
                exact
                    .errors
                    .for_batches_at_times(&points[range], &times, |offset, at, columns| {
                        let exact_columns = ExactColumns {
                            gradient: std::array::from_fn(|i| {
                                std::array::from_fn(|j| columns.get(Quantity::Gradient(i, j)))
                            }),
                            rate_gradient: std::array::from_fn(|i| {
                                std::array::from_fn(|j| columns.get(Quantity::RateGradient(i, j)))
                            }),
                            damage: columns.get(Quantity::Damage),
                            damage_gradient: std::array::from_fn(|j| {
                                columns.get(Quantity::DamageGradient(j))
                            }),
                        };
                        let count = exact_columns.damage.len();
                        let fields =
                            &discrete.fields[at * fields_per_state..(at + 1) * fields_per_state];
                        let damage_h = &discrete.damage[at * per_state..(at + 1) * per_state];
                        if constant_gradients {
                            // the points of the batch cell by cell, from the cell of its first
                            let mut p = 0;
                            while p < count {
                                let point = offset + p;
                                let end = count.min(p + nq - point % nq);
                                discrete_columns.set(p..end, &fields[point / nq]);
                                p = end;
                            }
                        } else {
                            for p in 0..count {
                                discrete_columns.set(p..p + 1, &fields[offset + p]);
                            }
                        }
                        if at == 0 {
                            let before = &previous_strain[first_point + offset..][..count];
                            for (p, strain) in before.iter().enumerate() {
                                for i in 0..D {
                                    for j in 0..D {
                                        previous[i][j][p] = strain[(i, j)];
                                    }
                                }
                            }
                        }
                        let batch = Batch {
                            count,
                            exact: exact_columns,
                            discrete: &discrete_columns,
                            weights: &weights[offset..offset + count],
                            damage_h: &damage_h[offset..offset + count],
                            time_step: k,
                        };
                        accumulate_batch(&mut local[at], &batch, &mut previous, &mut terms);
                        if at == last {
                            for (p, out) in
                                strain_out[offset..offset + count].iter_mut().enumerate()
                            {
                                *out = Tensor::<D>::from_fn(|i, j| previous[i][j][p]);
                            }
                        }
                    });
                local
            })
            .collect();
        for at in 0..states.len() {
            // In chunk order: the same sums for any number of threads.
            let sums = chunk_sums
                .iter()
                .fold([0.0; 5], |a, b| std::array::from_fn(|i| a[i] + b[at][i]));
            self.add_step(&sums);
        }
        self.spare_strain = std::mem::replace(&mut self.previous_strain, new_strain);
        // The buffers of the states are dropped; the next block allocates its own.
    }

    /// The maxima and the sum of the errors with the squared norms `sums` = [u, δu, β, ∇β,
    /// v] of one step.
    fn add_step(&mut self, sums: &[f64; 5]) {
        let k = self.time_step;
        self.errors.displacement = self.errors.displacement.max(sums[0].sqrt());
        self.errors.difference_quotient = self.errors.difference_quotient.max(sums[1].sqrt());
        self.errors.damage = self.errors.damage.max(sums[2].sqrt());
        self.gradient_sum += k * sums[3];
        self.errors.velocity = if sums[4].is_nan() {
            f64::NAN
        } else {
            self.errors.velocity.max(sums[4].sqrt())
        };
    }

    /// Adds the errors of the state after step n against a discrete reference.
    fn observe_discrete(&mut self, space: &LagrangeSpace<D>, state: &State) {
        let Reference::Discrete(states) = &self.reference else {
            return;
        };
        let tab = &self.tabulation;
        let nq = tab.len();
        let k = self.time_step;
        let stride = (states.len() - 1) / self.steps;
        let reference_state = &states[state.step * stride];
        let previous_displacement = &self.previous_displacement;
        let constant_gradients = self.constant_gradients;
        let chunks = space.mesh().num_cells().div_ceil(CHUNK_CELLS);
        let chunk_sums: Vec<[f64; 5]> = (0..chunks)
            .into_par_iter()
            .map(|chunk| {
                let first_cell = chunk * CHUNK_CELLS;
                let cells = CHUNK_CELLS.min(space.mesh().num_cells() - first_cell);
                let mut discrete = Vec::with_capacity(cells * nq);
                let mut references = Vec::with_capacity(cells * nq);
                discrete_points(
                    space,
                    tab,
                    constant_gradients,
                    state,
                    (reference_state, previous_displacement, k),
                    first_cell..first_cell + cells,
                    &mut discrete,
                    &mut references,
                );
                let mut local = [0.0; 5];
                for (point, reference) in discrete.iter().zip(&references) {
                    accumulate(&mut local, point, reference);
                }
                local
            })
            .collect();
        // In chunk order: the same sums for any number of threads.
        let sums = chunk_sums
            .iter()
            .fold([0.0; 5], |a, b| std::array::from_fn(|i| a[i] + b[i]));
        let displacement = reference_state.displacement.clone();
        self.add_step(&sums);
        self.previous_displacement = displacement;
    }

    /// The accumulated components (call after the last step: its [`ErrorTracker::observe`]
    /// compares the states still pending).
    pub fn finish(&self) -> ErrorComponents {
        let mut errors = self.errors;
        errors.damage_gradient = self.gradient_sum.sqrt();
        errors.total = errors.displacement
            + errors.difference_quotient
            + errors.damage
            + errors.damage_gradient;
        errors
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::{parse_case_file, Case};
    use crate::cli::BUILT_IN_CASES;
    use contact_damage::scheme::Simulation;

    /// The errors of a zones2d run of `steps` steps, with at most `states_per_block` states
    /// compared at once.
    fn errors(steps: usize, states_per_block: usize) -> [u64; 6] {
        let text = BUILT_IN_CASES
            .iter()
            .find(|(case, _)| *case == "zones2d")
            .unwrap()
            .1;
        let case = Case::<2>::new(parse_case_file(text, "zones2d").unwrap(), "zones2d").unwrap();
        let mut simulation = Simulation::new(case.problem(6, 1, steps).unwrap()).unwrap();
        let space = simulation.space().clone();
        let reference = Reference::Exact(Arc::new(ExactPrograms::clone(&case.programs)));
        let mut tracker = ErrorTracker::new(&space, reference, simulation.time_step(), steps);
        assert_eq!(tracker.states_per_block, STATES_PER_BLOCK);
        tracker.states_per_block = states_per_block;
        simulation
            .run(|report| {
                tracker.observe(report.space, report.state);
                Ok(())
            })
            .unwrap();
        assert!(tracker.pending.is_empty(), "the last block is compared");
        tracker.finish().values().map(f64::to_bits)
    }

    #[test]
    fn errors_compared_in_blocks_are_bitwise_those_of_each_step() {
        // 11 steps: blocks of 8 and 3, of 4, 4 and 3, and of 1.
        let each_step = errors(11, 1);
        assert!(f64::from_bits(each_step[4]) > 0.0);
        for states_per_block in [STATES_PER_BLOCK, 4, 11, 20] {
            assert_eq!(
                errors(11, states_per_block),
                each_step,
                "{states_per_block}"
            );
        }
    }
}
