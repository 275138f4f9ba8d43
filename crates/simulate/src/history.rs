//! Integral quantities of a run, one row of `history.csv` per time step.
//!
//! With the nodal contact rule of the scheme (ω_a = ∫_Γ3 φ_a, the rule of the friction term
//! j(u_{n−1}, v) in (5.1)), the Γ3 integrals are sums over the contact nodes a:
//! - `normal_force` = Σ_a ω_a p_ν(a), with p_ν(a) = p_ν(u_{n−1,ν}(a) − g(a)) as used in step n
//!   (p_ν(u_{n,ν}(a) − g(a)) with the implicit normal compliance);
//! - `tangential_force` = |Σ_a ω_a p_τ(a) R_a(0, λ_a)|, the magnitude of the resultant friction
//!   force, and `force_x`, `force_y`, `force_z` the components of the resultant force of the
//!   foundation on the body, F = Σ_a ω_a (−p_ν(a) ν_a − p_τ(a) R_a(0, λ_a)) (`force_z` = 0 in
//!   2D), and `moment_x`, `moment_y`, `moment_z` its moment about the point
//!   `output.moment_about` (default the origin; only `moment_z` is nonzero in 2D; see
//!   [`crate::zone`]);
//! - `contact_zone`: the measure (length in 2D, area in 3D) of the part of Γ3 where the
//!   interpolated penetration r = u_ν − g (at the displacement whose p_ν the step used) is
//!   positive, clipped at its zero crossing, and `zone_min`, `zone_max` its extent in the
//!   coordinate s of the line of `contact_history.csv` (empty when there is no contact; see
//!   [`crate::zone`] and [`crate::contact_line`]);
//! - `slip_zone` = Σ_{a slipping} ω_a: the measure of the slipping part of Γ3, by nodes;
//! - `slip_rate` = Σ_a ω_a |v_{n,τ}(a)| = ∫_Γ3 |v_τ|;
//! - `max_accumulated_slip` = max_a Σ_{m ≤ n} k |v_{m,τ}(a)|: the longest distance slipped
//!   by a point of Γ3 so far;
//! - `friction_power` = Σ_a ω_a p_τ(a) |v_{n,τ}(a)| = j(u_{n−1}, v_n), the frictional
//!   dissipation rate, and `friction_dissipation` = Σ_{m ≤ n} k j(u_{m−1}, v_m);
//!
//! and over Ω, by a quadrature rule of degree 2l:
//! - `mean_damage` = ∫_Ω β_n / |Ω| and `area_damage_below_half` = |{β_n < 1/2}| (an area in
//!   2D, a volume in 3D; the rule integrates the indicator);
//! - `viscous_power` = ∫_Ω 𝒜ε(v_n)·ε(v_n) and `viscous_dissipation` = Σ_{m ≤ n} k ∫_Ω
//!   𝒜ε(v_m)·ε(v_m).
//!
//! The running sums (`friction_dissipation`, `viscous_dissipation`, the accumulated slip of
//! every contact node) are part of the saved state, so that a resumed run continues them.

use crate::problem::ProblemSetup;
use contact_damage::fem::quadrature::QuadratureRule;
use contact_damage::fem::space::{strain, LagrangeSpace, Tabulation};
use contact_damage::model::contact::{ContactNodes, ContactStatus};
use contact_input::output::write_atomic;
use contact_input::InputError;
use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;
use std::ops::Range;
use std::path::Path;

/// Name of the time history.
pub const HISTORY_FILE: &str = "history.csv";
/// The fixed columns of the time history (see the module documentation); the reaction columns
/// of the parts of Γ1 follow them ([`history_header`]).
pub const HISTORY_HEADER: &str = "step,t,normal_force,tangential_force,force_x,force_y,force_z,moment_x,moment_y,moment_z,contact_zone,zone_min,zone_max,slip_zone,stick,slip,separated,slip_rate,max_accumulated_slip,friction_power,friction_dissipation,viscous_power,viscous_dissipation,mean_damage,area_damage_below_half,velocity_kkt,damage_kkt,newton_iterations,friction_iterations,damage_iterations";

/// The header of `history.csv` for the parts `parts` of Γ1 in dimension `dim`: the fixed
/// columns, then `reaction_<part>_x`, `…_y` (, `…_z`) per part — the resultant force that the
/// support of the part exerts on the body.
pub fn history_header(parts: &[String], dim: usize) -> String {
    let mut header = HISTORY_HEADER.to_string();
    for part in parts {
        for axis in &["x", "y", "z"][..dim] {
            header.push_str(&format!(",reaction_{part}_{axis}"));
        }
    }
    header
}

/// The running sums of a run after step n.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RunningSums {
    /// Σ_{m ≤ n} k |v_{m,τ}(a)| per contact node a.
    pub accumulated_slip: Vec<f64>,
    /// Σ_{m ≤ n} k j(u_{m−1}, v_m).
    pub friction_dissipation: f64,
    /// Σ_{m ≤ n} k ∫_Ω 𝒜ε(v_m)·ε(v_m).
    pub viscous_dissipation: f64,
}

impl RunningSums {
    /// Zero sums for `contact_nodes` contact nodes (the state before step 1).
    pub fn new(contact_nodes: usize) -> Self {
        Self {
            accumulated_slip: vec![0.0; contact_nodes],
            ..Self::default()
        }
    }
}

/// Integral quantities of one step (a row of `history.csv`).
#[derive(Debug, Clone, PartialEq)]
pub struct HistoryRow {
    /// n.
    pub step: usize,
    /// t_n.
    pub time: f64,
    /// Σ_a ω_a p_ν(a): total normal contact force.
    pub normal_force: f64,
    /// |Σ_a ω_a p_τ(a) R_a(0, λ_a)|: magnitude of the resultant friction force.
    pub tangential_force: f64,
    /// The resultant force of the foundation on the body (x, y, z; z = 0 in 2D).
    pub force: [f64; 3],
    /// Its moment about `output.moment_about` (x, y, z; only z in 2D).
    pub moment: [f64; 3],
    /// Measure of {r > 0} on Γ3 from the zero crossing of the interpolated penetration.
    pub contact_zone: f64,
    /// Extent of the contact zone in the coordinate s of `contact_history.csv` (NaN when
    /// empty).
    pub zone_bounds: [f64; 2],
    /// Σ ω_a over the slipping contact nodes.
    pub slip_zone: f64,
    /// Contact nodes sticking.
    pub stick: usize,
    /// Contact nodes slipping.
    pub slip: usize,
    /// Contact nodes separated.
    pub separated: usize,
    /// Σ_a ω_a |v_{n,τ}(a)|.
    pub slip_rate: f64,
    /// max_a Σ_{m ≤ n} k |v_{m,τ}(a)|.
    pub max_accumulated_slip: f64,
    /// j(u_{n−1}, v_n) = Σ_a ω_a p_τ(a) |v_{n,τ}(a)|.
    pub friction_power: f64,
    /// Σ_{m ≤ n} k j(u_{m−1}, v_m).
    pub friction_dissipation: f64,
    /// ∫_Ω 𝒜ε(v_n)·ε(v_n).
    pub viscous_power: f64,
    /// Σ_{m ≤ n} k ∫_Ω 𝒜ε(v_m)·ε(v_m).
    pub viscous_dissipation: f64,
    /// ∫_Ω β_n / |Ω|.
    pub mean_damage: f64,
    /// |{β_n < 1/2}|.
    pub area_damage_below_half: f64,
    /// KKT residual of the velocity step.
    pub velocity_kkt: f64,
    /// KKT residual of the damage step.
    pub damage_kkt: f64,
    /// Newton iterations of the velocity step.
    pub newton_iterations: usize,
    /// Semismooth Newton iterations of the friction problems.
    pub friction_iterations: usize,
    /// Active-set iterations of the damage step.
    pub damage_iterations: usize,
    /// The reaction of each part of Γ1 (D components per part, in the order of the header).
    pub reactions: Vec<f64>,
}

impl HistoryRow {
    /// The row as a line of `history.csv` (floats in their shortest round-trip form).
    pub fn csv_line(&self) -> String {
        format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{:e},{:e},{},{},{}{}\n",
            self.step,
            self.time,
            self.normal_force,
            self.tangential_force,
            self.force[0],
            self.force[1],
            self.force[2],
            self.moment[0],
            self.moment[1],
            self.moment[2],
            self.contact_zone,
            optional(self.zone_bounds[0]),
            optional(self.zone_bounds[1]),
            self.slip_zone,
            self.stick,
            self.slip,
            self.separated,
            self.slip_rate,
            self.max_accumulated_slip,
            self.friction_power,
            self.friction_dissipation,
            self.viscous_power,
            self.viscous_dissipation,
            self.mean_damage,
            self.area_damage_below_half,
            self.velocity_kkt,
            self.damage_kkt,
            self.newton_iterations,
            self.friction_iterations,
            self.damage_iterations,
            self.reactions
                .iter()
                .map(|r| format!(",{r}"))
                .collect::<String>()
        )
    }
}

/// A value, or an empty field for NaN (no such value, e.g. the bounds of an empty zone).
fn optional(value: f64) -> String {
    if value.is_nan() {
        String::new()
    } else {
        value.to_string()
    }
}

/// What one step did on Γ3, per contact node, as the solver returned it.
pub struct ContactStep<'a> {
    /// Status of every contact node.
    pub status: &'a [ContactStatus],
    /// p_ν(a) used in the step.
    pub normal_pressure: &'a [f64],
    /// p_τ(a) used in the step.
    pub friction_bound: &'a [f64],
}

/// |v_τ(a)| at every contact node: the norm of the tangential components of v_a in the
/// node's frame.
pub fn tangential_speed<const D: usize>(contact: &ContactNodes<D>, velocity: &[f64]) -> Vec<f64> {
    contact
        .nodes
        .iter()
        .zip(&contact.frames)
        .map(|(&node, frame)| {
            let v = SVector::<f64, D>::from_column_slice(&velocity[node * D..node * D + D]);
            let local = frame.transpose() * v;
            local.rows(1, D - 1).norm()
        })
        .collect()
}

/// The Γ3 columns of a step (normal force, zones, node counts, slip and friction power) and
/// the update of the accumulated slip and friction dissipation in `sums`.
pub struct ContactIntegrals {
    /// Σ ω_a p_ν(a).
    pub normal_force: f64,
    /// Σ ω_a over slipping nodes.
    pub slip_zone: f64,
    /// Node counts (separated, stick, slip).
    pub counts: [usize; 3],
    /// Σ ω_a |v_τ(a)|.
    pub slip_rate: f64,
    /// Σ ω_a p_τ(a) |v_τ(a)|.
    pub friction_power: f64,
}

/// Computes the Γ3 integrals of a step with the tangential speeds `speed` and adds k |v_τ(a)|
/// and k j(u_{n−1}, v_n) to the running sums.
pub fn contact_integrals<const D: usize>(
    contact: &ContactNodes<D>,
    step: &ContactStep<'_>,
    speed: &[f64],
    time_step: f64,
    sums: &mut RunningSums,
) -> ContactIntegrals {
    let mut integrals = ContactIntegrals {
        normal_force: 0.0,
        slip_zone: 0.0,
        counts: [0; 3],
        slip_rate: 0.0,
        friction_power: 0.0,
    };
    for (a, &weight) in contact.weights.iter().enumerate() {
        integrals.normal_force += weight * step.normal_pressure[a];
        match step.status[a] {
            ContactStatus::Separated => integrals.counts[0] += 1,
            ContactStatus::Stick => integrals.counts[1] += 1,
            ContactStatus::Slip => {
                integrals.counts[2] += 1;
                integrals.slip_zone += weight;
            }
        }
        integrals.slip_rate += weight * speed[a];
        integrals.friction_power += weight * step.friction_bound[a] * speed[a];
        sums.accumulated_slip[a] += time_step * speed[a];
    }
    sums.friction_dissipation += time_step * integrals.friction_power;
    integrals
}

/// Steps over which a cycle of the normal contact force is recognized.
pub const CYCLE_WINDOW_STEPS: usize = 12;

/// Watches the total normal contact force for a cycle of period two — the signature of a step
/// above the stability limit of the explicit normal compliance where p_ν switches off on
/// separation (see `contact_damage::scheme::stability`): over the last [`CYCLE_WINDOW_STEPS`] steps every
/// change reverses the previous one, the changes are not small (above 1e-8 of the force) and
/// they do not decay. A damped oscillation, a load that varies smoothly or a force at rest is
/// no cycle.
#[derive(Debug, Clone, Default)]
pub struct ForceCycle {
    recent: std::collections::VecDeque<f64>,
}

impl ForceCycle {
    /// Adds the force of the next step; returns the smallest and largest force of the window
    /// when the window is a cycle.
    pub fn push(&mut self, normal_force: f64) -> Option<(f64, f64)> {
        self.recent.push_back(normal_force);
        if self.recent.len() > CYCLE_WINDOW_STEPS {
            self.recent.pop_front();
        }
        if self.recent.len() < CYCLE_WINDOW_STEPS {
            return None;
        }
        let values: Vec<f64> = self.recent.iter().copied().collect();
        let changes: Vec<f64> = values.windows(2).map(|w| w[1] - w[0]).collect();
        let scale = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let alternating = changes.windows(2).all(|w| w[0] * w[1] < 0.0);
        let large = changes.iter().all(|c| c.abs() > 1e-8 * scale);
        let sustained = changes[changes.len() - 1].abs() >= changes[0].abs();
        (alternating && large && sustained).then(|| {
            values
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(low, high), &v| {
                    (low.min(v), high.max(v))
                })
        })
    }
}

/// Cells per task of the parallel cell sums.
const CELL_CHUNK: usize = 4096;

/// Σ over the cells of `cell_sum(range)` for consecutive ranges of [`CELL_CHUNK`] cells,
/// computed in parallel and added in a fixed order: the result does not depend on the number
/// of threads (a resumed run writes the same history bit for bit).
fn sum_over_cells<const N: usize>(
    cells: usize,
    cell_sum: impl Fn(Range<usize>) -> [f64; N] + Sync,
) -> [f64; N] {
    let partial: Vec<[f64; N]> = (0..cells.div_ceil(CELL_CHUNK))
        .into_par_iter()
        .map(|chunk| cell_sum(chunk * CELL_CHUNK..((chunk + 1) * CELL_CHUNK).min(cells)))
        .collect();
    partial.iter().fold([0.0; N], |mut total, part| {
        for (t, p) in total.iter_mut().zip(part) {
            *t += p;
        }
        total
    })
}

/// Terms per partial sum of [`blocked_sum`].
const SUM_BLOCK: usize = 1024;

/// Σ_{i < len} term(i) as the sum of the partial sums of consecutive blocks of [`SUM_BLOCK`]
/// terms: a sum of n terms of one sign then errs by about SUM_BLOCK + n/SUM_BLOCK roundings
/// instead of n. A mesh of equal cells adds the same weight 10⁵ times: at the last step of the
/// 128² run of `bench_run`, the mean damage Σ_a β_a ∫φ_a / |Ω| (with |Ω| the sum of the point
/// weights) erred by 1.5e-12 relative with one running sum and by 5e-15 in blocks; with
/// |Ω| = Σ_a ∫φ_a in blocks by 3e-16 (against the exact rational sums of the same nodal values;
/// sums per cell: 1.8e-13).
fn blocked_sum(len: usize, term: impl Fn(usize) -> f64) -> f64 {
    (0..len)
        .step_by(SUM_BLOCK)
        .map(|start| {
            (start..(start + SUM_BLOCK).min(len))
                .map(&term)
                .sum::<f64>()
        })
        .sum()
}

/// The quadrature rule of the integrals over Ω in `history.csv`, with what does not change
/// during a run computed once: the weight × |det J| of every point, ∫_Ω φ_a of every basis
/// function (∫_Ω β_h = Σ_a β_a ∫_Ω φ_a, one pass over the nodes per step), and for P1, whose
/// basis gradients are constant on a cell, the physical gradients and the measure of every
/// cell.
#[derive(Debug, Clone)]
pub struct DomainQuadrature<const D: usize> {
    tabulation: Tabulation<D>,
    /// w_q |det J| at every point, cell-major.
    weights: Vec<f64>,
    /// ∫_Ω φ_a by the rule, by node.
    node_integrals: Vec<f64>,
    /// |Ω| by the rule, as Σ_a ∫_Ω φ_a.
    volume: f64,
    /// Whether every basis function is ≥ 0 at every point of the rule (P1 with interior
    /// points): β_h at a point is then a convex combination of the nodal values of its cell,
    /// so a cell whose nodal values are all ≥ 1/2 adds nothing to |{β < 1/2}|.
    convex: bool,
    /// P1: the physical basis gradients of every cell, `nodes` per cell (empty for l ≥ 2).
    gradients: Vec<SVector<f64, D>>,
    /// P1: the measure of every cell by the rule (empty for l ≥ 2).
    measures: Vec<f64>,
}

impl<const D: usize> DomainQuadrature<D> {
    /// The simplex rule of `degree` (2l in `simulate`) on the cells of `space`.
    pub fn new(space: &LagrangeSpace<D>, degree: usize) -> Self {
        let tabulation =
            Tabulation::cell_rule(space.element(), &QuadratureRule::<D>::simplex(degree));
        let (n, points) = (tabulation.nodes, tabulation.len());
        let cells = space.mesh().num_cells();
        let reference_measure: f64 = tabulation.weights.iter().sum();
        let mut weights = Vec::with_capacity(cells * points);
        let mut node_integrals = vec![0.0; space.num_nodes()];
        let linear = space.degree() == 1;
        let mut gradients = Vec::with_capacity(if linear { cells * n } else { 0 });
        let mut measures = Vec::with_capacity(if linear { cells } else { 0 });
        for c in 0..cells {
            let geometry = space.geometry(c);
            let nodes = space.cell_nodes(c);
            for q in 0..points {
                let det = space.geometry_at(c, &tabulation.points[q]).det.abs();
                let weight = tabulation.weights[q] * det;
                weights.push(weight);
                for (a, &node) in nodes.iter().enumerate() {
                    node_integrals[node] += weight * tabulation.values[q * n + a];
                }
            }
            if linear {
                gradients.extend(
                    tabulation.gradients[..n]
                        .iter()
                        .map(|reference| geometry.inverse_transpose * reference),
                );
                measures.push(reference_measure * geometry.det.abs());
            }
        }
        Self {
            // Σ_a ∫φ_a, summed as ∫β_h is: a field β ≡ 1 has the mean 1 exactly
            volume: blocked_sum(node_integrals.len(), |a| node_integrals[a]),
            convex: tabulation.values.iter().all(|&value| value >= 0.0),
            tabulation,
            weights,
            node_integrals,
            gradients,
            measures,
        }
    }
}

/// ∫_Ω β / |Ω| and |{β < 1/2}|, both by the rule of `quadrature`.
pub fn damage_integrals<const D: usize>(
    space: &LagrangeSpace<D>,
    quadrature: &DomainQuadrature<D>,
    damage: &[f64],
) -> (f64, f64) {
    let node_integrals = &quadrature.node_integrals;
    let integral = blocked_sum(node_integrals.len(), |a| node_integrals[a] * damage[a]);
    let tabulation = &quadrature.tabulation;
    let (n, points) = (tabulation.nodes, tabulation.len());
    let undamaged = |nodes: &[usize]| nodes.iter().all(|&a| damage[a] >= 0.5);
    let weak_area = if quadrature.convex && damage.iter().all(|&beta| beta >= 0.5) {
        0.0
    } else {
        let [area] = sum_over_cells(space.mesh().num_cells(), |cells| {
            let mut area = 0.0;
            for c in cells {
                let nodes = space.cell_nodes(c);
                if quadrature.convex && undamaged(nodes) {
                    continue;
                }
                for q in 0..points {
                    let values = &tabulation.values[q * n..(q + 1) * n];
                    let beta: f64 = nodes.iter().zip(values).map(|(&a, v)| damage[a] * v).sum();
                    if beta < 0.5 {
                        area += quadrature.weights[c * points + q];
                    }
                }
            }
            [area]
        });
        area
    };
    (integral / quadrature.volume, weak_area)
}

/// ∫_Ω 𝒜ε(v)·ε(v) by the rule of `quadrature` (exact for a linear 𝒜 when the rule has
/// degree ≥ 2(l − 1)). The velocity gradient at a point is Σ_a v_a ⊗ J⁻ᵀ∇̂φ_a with the
/// reference gradients tabulated once; for l = 1 it is constant on a cell, and so is the
/// integrand (𝒜 depends on ε only): one evaluation per cell with the cell's physical
/// gradients and measure computed once ([`DomainQuadrature`]).
pub fn viscous_power<const D: usize>(
    setup: &ProblemSetup<D>,
    space: &LagrangeSpace<D>,
    quadrature: &DomainQuadrature<D>,
    velocity: &[f64],
) -> f64 {
    let viscosity = &setup.problem.model.viscosity;
    let tabulation = &quadrature.tabulation;
    let (n, points) = (tabulation.nodes, tabulation.len());
    let nodal =
        |node: usize| SVector::<f64, D>::from_column_slice(&velocity[node * D..node * D + D]);
    // P1: the cells' gradients and measures were computed once
    let p1 = !quadrature.measures.is_empty();
    let [power] = sum_over_cells(space.mesh().num_cells(), |cells| {
        // the strain rates of the cells (P1) or points (l ≥ 2) of the range, then one call of
        // the law for all of them
        let mut rates = Vec::with_capacity(cells.len() * points);
        if p1 {
            for c in cells.clone() {
                let gradients = &quadrature.gradients[c * n..(c + 1) * n];
                let mut gradient = SMatrix::<f64, D, D>::zeros();
                for (&node, physical) in space.cell_nodes(c).iter().zip(gradients) {
                    gradient += nodal(node) * physical.transpose();
                }
                rates.push(strain(&gradient));
            }
        } else {
            for c in cells.clone() {
                let nodes = space.cell_nodes(c);
                for q in 0..points {
                    let geometry = space.geometry_at(c, &tabulation.points[q]);
                    // Σ_a v_a ⊗ ∇̂φ_a(ξ_q), then the chain rule ∇v = (Σ_a v_a ⊗ ∇̂φ_a) J⁻¹
                    let mut reference_gradient = SMatrix::<f64, D, D>::zeros();
                    for (a, &node) in nodes.iter().enumerate() {
                        reference_gradient +=
                            nodal(node) * tabulation.gradients[q * n + a].transpose();
                    }
                    rates.push(strain(
                        &(reference_gradient * geometry.inverse_transpose.transpose()),
                    ));
                }
            }
        }
        let weights = if p1 {
            &quadrature.measures[cells]
        } else {
            &quadrature.weights[cells.start * points..cells.end * points]
        };
        [viscosity.weighted_power_sum(&rates, weights)]
    });
    power
}

/// Keeps the header and the rows of steps 1, …, `step` of `history.csv` (rewritten
/// atomically). Rows after them — steps done after the last saved step, possibly a line cut
/// short by a crash — are dropped; a missing, reordered or malformed row among them is an error.
pub fn truncate_history(path: &Path, step: usize, header: &str) -> Result<(), InputError> {
    let text = std::fs::read_to_string(path).map_err(|e| InputError::io("reading", path, e))?;
    let mut lines = text.lines();
    if lines.next() != Some(header) {
        return Err(InputError::InvalidInput(format!(
            "{}: the first line is not the history header of this version",
            path.display()
        )));
    }
    let columns = header.split(',').count();
    let mut kept = format!("{header}\n");
    for expected in 1..=step {
        let line = lines.next().unwrap_or("");
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() != columns || fields[0] != expected.to_string() {
            return Err(InputError::InvalidInput(format!(
                "{}:{}: expected the complete row of step {expected}, found `{line}`",
                path.display(),
                expected + 1
            )));
        }
        kept.push_str(line);
        kept.push('\n');
    }
    write_atomic(path, kept.as_bytes())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use contact_damage::fem::mesh::{BoundaryPart::*, Mesh};
    use contact_damage::fem::quadrature::QuadratureRule;
    use std::sync::Arc;

    /// P_l on (0, 1) × (0, 2), 3 × 4 cells, clamped at x = 0, contact at y = 0.
    pub(crate) fn unit_square_space(degree: usize) -> LagrangeSpace<2> {
        let mesh = Mesh::box_mesh(
            [0.0, 0.0],
            [1.0, 2.0],
            [3, 4],
            [[Dirichlet, Neumann], [Contact, Neumann]],
        )
        .unwrap();
        LagrangeSpace::new(Arc::new(mesh), degree).unwrap()
    }

    /// A problem on the mesh of [`unit_square_space`]: linear viscosity (η, ζ) = (0.5, 0.25),
    /// damaged Hooke (μ, λ) = (2, 3).
    pub(crate) fn setup() -> ProblemSetup<2> {
        let text = r#"
            dim = 2
            degree = 1
            final_time = 1.0
            steps = 1
            [mesh]
            box = { lower = [0.0, 0.0], upper = [1.0, 2.0], cells = [3, 4], sides = { x_min = "clamped", y_min = "contact" } }
            [laws]
            viscosity = { kind = "linear", shear = 0.5, bulk = 0.25 }
            elasticity = { kind = "damaged_hooke", shear_modulus = 2.0, lame_lambda = 3.0 }
            damage_source = { kind = "fremond", lambda_d = 0.1, lambda_w = 0.05, damage_floor = 0.1, strain_energy_cap = 10.0 }
            contact = { stiffness = 10.0, friction = 0.4 }
            damage_diffusion = 0.1
        "#;
        let file = crate::problem::parse_problem_file(text, "inline").unwrap();
        ProblemSetup::<2>::new(file, Path::new("inline.toml")).unwrap()
    }

    /// |{β < 1/2}| point by point over every cell, in cell order (one chunk of cells).
    fn weak_area_of_every_point(space: &LagrangeSpace<2>, degree: usize, damage: &[f64]) -> f64 {
        let tabulation =
            Tabulation::cell_rule(space.element(), &QuadratureRule::<2>::simplex(degree));
        let n = tabulation.nodes;
        let mut area = 0.0;
        for c in 0..space.mesh().num_cells() {
            for q in 0..tabulation.len() {
                let det = space.geometry_at(c, &tabulation.points[q]).det.abs();
                let values = &tabulation.values[q * n..(q + 1) * n];
                let beta: f64 = space
                    .cell_nodes(c)
                    .iter()
                    .zip(values)
                    .map(|(&a, v)| damage[a] * v)
                    .sum();
                if beta < 0.5 {
                    area += tabulation.weights[q] * det;
                }
            }
        }
        area
    }

    #[test]
    fn weak_area_skips_only_cells_that_cannot_add_to_it() {
        for degree in [1, 2] {
            let space = unit_square_space(degree);
            let quadrature = DomainQuadrature::new(&space, 2 * degree);
            // nodal values on both sides of 1/2: the skipped cells add nothing, so the area is
            // bitwise the sum over every point
            let damage: Vec<f64> = (0..space.num_nodes())
                .map(|a| ((a * 37 % 23) as f64) / 22.0)
                .collect();
            let (_, area) = damage_integrals(&space, &quadrature, &damage);
            assert!(area > 0.0);
            assert_eq!(area, weak_area_of_every_point(&space, 2 * degree, &damage));
        }
        // P2: vertices at 1 and edge midpoints at 1/2, all nodal values ≥ 1/2, yet β_h = 1/3 at
        // the centroid of every cell (the P2 basis is negative at interior points): no skip
        let space = unit_square_space(2);
        let quadrature = DomainQuadrature::new(&space, 4);
        let vertices = space.mesh().num_vertices();
        let damage: Vec<f64> = (0..space.num_nodes())
            .map(|a| if a < vertices { 1.0 } else { 0.5 })
            .collect();
        let (_, area) = damage_integrals(&space, &quadrature, &damage);
        assert!(area > 0.0);
        assert_eq!(area, weak_area_of_every_point(&space, 4, &damage));
    }

    #[test]
    fn damage_integrals_are_exact_for_linear_fields() {
        for degree in [1, 2] {
            let space = unit_square_space(degree);
            let quadrature = DomainQuadrature::new(&space, 2 * degree);
            // β = 0.2 + 0.3 x + 0.1 y on (0, 1) × (0, 2): mean 0.2 + 0.15 + 0.1
            let damage = space.interpolate_scalar(|x| 0.2 + 0.3 * x[0] + 0.1 * x[1]);
            let (mean, weak) = damage_integrals(&space, &quadrature, &damage);
            assert!((mean - 0.45).abs() < 1e-14, "{mean}");
            // |{β < 1/2}| = |{y < 3 − 3x}| = 2/3 + 2/3 = 4/3. The rule counts the weights of the
            // points where β_h = β < 1/2: exact on the cells the line β = 1/2 does not cross,
            // off on the four it crosses, which on this mesh form two pairs symmetric about a
            // point of the line ((1/2, 3/2) and (5/6, 1/2)). The point reflection maps the Kuhn
            // triangles and the symmetric rules onto themselves and changes the sign of
            // β − 1/2, so the errors of the two cells of a pair cancel: the count is 4/3 up to
            // the rounding of its sum (observed: 8.9e-16 for P1, 1.1e-15 for P2).
            assert!(
                (weak - 4.0 / 3.0).abs() <= 1e-14,
                "|{{β < 1/2}}| = {weak}, exact 4/3"
            );
            let (_, all) = damage_integrals(&space, &quadrature, &vec![0.3; damage.len()]);
            let (_, none) = damage_integrals(&space, &quadrature, &vec![0.7; damage.len()]);
            assert!((all - 2.0).abs() < 1e-14 && none == 0.0);
        }
    }

    #[test]
    fn viscous_power_is_exact_for_affine_velocities() {
        let setup = setup();
        for degree in [1, 2] {
            let space = unit_square_space(degree);
            let quadrature = DomainQuadrature::new(&space, 2 * degree);
            // ε(v) = [[0, 0.5], [0.5, 0.3]]: 𝒜ε·ε = 2·0.5 ε·ε + 0.25 (tr ε)² = 0.59 + 0.0225
            let velocity = space.interpolate_vector(|x| [x[1], 0.3 * x[1]]);
            let power = viscous_power(&setup, &space, &quadrature, &velocity);
            let expected = (0.59 + 0.0225) * 2.0;
            assert!((power - expected).abs() < 1e-13, "{power} vs {expected}");
            // a rigid motion dissipates nothing
            let rigid = space.interpolate_vector(|x| [0.3 - x[1], 0.1 + x[0]]);
            assert!(viscous_power(&setup, &space, &quadrature, &rigid).abs() < 1e-13);
        }
    }

    #[test]
    fn viscous_power_is_exact_for_quadratic_velocities_in_p2() {
        let setup = setup();
        let space = unit_square_space(2);
        let quadrature = DomainQuadrature::new(&space, 4);
        // v = (x y, x²): ε(v) = [[y, 1.5 x], [1.5 x, 0]], 𝒜ε·ε = ε·ε + 0.25 (tr ε)²
        // = 1.25 y² + 4.5 x², whose integral over (0, 1) × (0, 2) is 10/3 + 3
        let velocity = space.interpolate_vector(|x| [x[0] * x[1], x[0] * x[0]]);
        let power = viscous_power(&setup, &space, &quadrature, &velocity);
        let expected = 10.0 / 3.0 + 3.0;
        assert!((power - expected).abs() < 1e-13, "{power} vs {expected}");
    }

    #[test]
    fn cell_sums_do_not_depend_on_the_number_of_threads() {
        // sums over 3 chunks and a partial one, with values whose addition is not associative
        let cells = 3 * CELL_CHUNK + 17;
        let value = |c: usize| 1.0 / (c as f64 + 1.0) + 1e16 * ((c % 7) as f64 - 3.0);
        let sum = || sum_over_cells(cells, |range| [range.map(value).sum::<f64>()]);
        let pool = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
        };
        let one = pool(1).install(sum);
        let three = pool(3).install(sum);
        assert_eq!(one[0].to_bits(), three[0].to_bits());
        // and they are the chunks added in order
        let mut expected = 0.0;
        for chunk in 0..4 {
            let range = chunk * CELL_CHUNK..((chunk + 1) * CELL_CHUNK).min(cells);
            expected += range.map(value).sum::<f64>();
        }
        assert_eq!(one[0].to_bits(), expected.to_bits());
    }

    #[test]
    fn contact_integrals_sum_weights_speeds_and_running_sums() {
        let space = unit_square_space(1);
        let contact = ContactNodes::new(&space).unwrap();
        let count = contact.len();
        assert!(count >= 3);
        // every contact node slides with v = (0.2, −0.1): |v_τ| = 0.2 on y = 0
        let mut velocity = vec![0.0; space.num_nodes() * 2];
        for &node in &contact.nodes {
            velocity[node * 2] = 0.2;
            velocity[node * 2 + 1] = -0.1;
        }
        let speed = tangential_speed(&contact, &velocity);
        assert!(speed.iter().all(|s| (s - 0.2).abs() < 1e-15), "{speed:?}");
        let mut status = vec![ContactStatus::Slip; count];
        status[0] = ContactStatus::Separated;
        status[1] = ContactStatus::Stick;
        let normal_pressure = vec![2.0; count];
        let friction_bound = vec![0.5; count];
        let step = ContactStep {
            status: &status,
            normal_pressure: &normal_pressure,
            friction_bound: &friction_bound,
        };
        let mut sums = RunningSums::new(count);
        let total: f64 = contact.weights.iter().sum();
        let integrals = contact_integrals(&contact, &step, &speed, 0.1, &mut sums);
        assert!((integrals.normal_force - 2.0 * total).abs() < 1e-14);
        assert!(
            (integrals.slip_zone - (total - contact.weights[0] - contact.weights[1])).abs() < 1e-14
        );
        assert_eq!(integrals.counts, [1, 1, count - 2]);
        assert!((integrals.slip_rate - 0.2 * total).abs() < 1e-14);
        assert!((integrals.friction_power - 0.1 * total).abs() < 1e-14);
        contact_integrals(&contact, &step, &speed, 0.1, &mut sums);
        assert!(sums
            .accumulated_slip
            .iter()
            .all(|s| (s - 0.04).abs() < 1e-15));
        assert!((sums.friction_dissipation - 0.02 * total).abs() < 1e-15);
    }

    #[test]
    fn force_cycle_is_a_sustained_alternation() {
        let feed = |values: &mut dyn Iterator<Item = f64>| {
            let mut cycle = ForceCycle::default();
            values.map(|v| cycle.push(v)).last().flatten()
        };
        // a period-2 cycle ±19 % around 1 (a step above the stability limit)
        let period_two = (0..30).map(|n| if n % 2 == 0 { 1.19 } else { 0.81 });
        assert_eq!(feed(&mut period_two.clone()), Some((0.81, 1.19)));
        // growing: an instability
        let growing =
            (0..30).map(|n| 1.0 + 0.01 * 1.1f64.powi(n) * if n % 2 == 0 { 1.0 } else { -1.0 });
        assert!(feed(&mut growing.clone()).is_some());
        // damped (|1 − kλ| = 0.9), smooth, at rest, or too short: no cycle
        let damped = (0..30).map(|n| 1.0 + 0.2 * (-0.9f64).powi(n));
        assert_eq!(feed(&mut damped.clone()), None);
        let smooth = (0..30).map(|n| (0.3 * n as f64).sin());
        assert_eq!(feed(&mut smooth.clone()), None);
        assert_eq!(feed(&mut std::iter::repeat_n(0.7, 30)), None);
        assert_eq!(feed(&mut period_two.take(CYCLE_WINDOW_STEPS - 1)), None);
        // round-off flutter at rest is no cycle
        let flutter = (0..30).map(|n| 1.0 + 1e-15 * if n % 2 == 0 { 1.0 } else { -1.0 });
        assert_eq!(feed(&mut flutter.clone()), None);
    }

    #[test]
    fn history_is_truncated_to_the_saved_step() {
        let dir = std::env::temp_dir().join(format!("simulate-history-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(HISTORY_FILE);
        let row = |n: usize| {
            HistoryRow {
                step: n,
                time: 0.1 * n as f64,
                normal_force: 0.0,
                tangential_force: 0.0,
                force: [0.0; 3],
                moment: [0.0; 3],
                contact_zone: 0.0,
                zone_bounds: [f64::NAN; 2],
                slip_zone: 0.0,
                stick: 0,
                slip: 0,
                separated: 1,
                slip_rate: 0.0,
                max_accumulated_slip: 0.0,
                friction_power: 0.0,
                friction_dissipation: 0.0,
                viscous_power: 0.5,
                viscous_dissipation: 0.05 * n as f64,
                mean_damage: 1.0,
                area_damage_below_half: 0.0,
                velocity_kkt: 0.0,
                damage_kkt: 0.0,
                newton_iterations: 1,
                friction_iterations: 1,
                damage_iterations: 1,
                reactions: Vec::new(),
            }
            .csv_line()
        };
        assert_eq!(
            row(1).trim_end().split(',').count(),
            HISTORY_HEADER.split(',').count()
        );
        // rows 1..3 complete, then a row cut short by a crash
        let text = format!("{HISTORY_HEADER}\n{}{}{}4,0.4,0", row(1), row(2), row(3));
        std::fs::write(&path, &text).unwrap();
        truncate_history(&path, 3, HISTORY_HEADER).unwrap();
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            format!("{HISTORY_HEADER}\n{}{}{}", row(1), row(2), row(3))
        );
        truncate_history(&path, 1, HISTORY_HEADER).unwrap();
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            format!("{HISTORY_HEADER}\n{}", row(1))
        );
        // a missing row is an error naming the line
        let error = truncate_history(&path, 2, HISTORY_HEADER)
            .unwrap_err()
            .to_string();
        assert!(
            error.contains(":3: expected the complete row of step 2"),
            "{error}"
        );
        std::fs::write(&path, "step,t\n").unwrap();
        assert!(truncate_history(&path, 0, HISTORY_HEADER).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
