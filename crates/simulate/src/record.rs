//! What `simulate` derives from one step of the scheme for `history.csv`: the contact and damage
//! statistics of [`crate::history`], the contact zone of [`crate::zone`] and the reactions,
//! gathered in one function, so that the run loop and the per-step benchmark (`bench_step`)
//! time the same work.

use crate::contact_line::LineCoordinate;
use crate::history::{
    contact_integrals, damage_integrals, tangential_speed, viscous_power, ContactStep,
    DomainQuadrature, HistoryRow, RunningSums,
};
use crate::problem::ProblemSetup;
use crate::zone::{boundary_penetration, contact_resultant, contact_zone, ContactZone};
use contact_damage::model::contact::ContactNodes;
use contact_damage::scheme::{ContactTreatment, Simulation, StepOutcome};

/// The history row of a step and the per-node tangential speeds it was computed from (the
/// `slip_rate` column of `contact_history.csv`).
pub struct StepRecord {
    /// The row of `history.csv`.
    pub row: HistoryRow,
    /// |v_τ(a)| at every contact node.
    pub speed: Vec<f64>,
}

/// The step just done by `simulation` with outcome `outcome`, as a row of `history.csv`;
/// adds the step's contributions to the running sums `sums`. `quadrature` is the cell rule of
/// the Ω integrals and `coordinate` the coordinate s of the contact zone's extent (that of the
/// line of `contact_history.csv`).
pub fn record_step<const D: usize>(
    setup: &ProblemSetup<D>,
    simulation: &Simulation<D>,
    outcome: &StepOutcome,
    quadrature: &DomainQuadrature<D>,
    coordinate: &LineCoordinate,
    sums: &mut RunningSums,
) -> StepRecord {
    let StepOutcome {
        velocity,
        damage,
        normal_pressure,
        friction_bound,
    } = outcome;
    let state = simulation.state();
    let space = simulation.space();
    let contact = simulation.contact();
    let time_step = simulation.time_step();
    let (mean_damage, area_damage_below_half) = damage_integrals(space, quadrature, &state.damage);
    let speed = tangential_speed(contact, &state.velocity);
    let on_contact = contact_integrals(
        contact,
        &ContactStep {
            status: &velocity.status,
            normal_pressure,
            friction_bound,
        },
        &speed,
        time_step,
        sums,
    );
    let resultant = contact_resultant(
        space,
        contact,
        normal_pressure,
        friction_bound,
        &velocity.multipliers,
        &setup.moment_about,
    );
    let zone = step_contact_zone(setup, simulation, contact, coordinate);
    let viscous_power = viscous_power(setup, space, quadrature, &state.velocity);
    sums.viscous_dissipation += time_step * viscous_power;
    let row = HistoryRow {
        step: state.step,
        time: state.time,
        normal_force: on_contact.normal_force,
        tangential_force: resultant.friction,
        force: std::array::from_fn(|i| if i < D { resultant.force[i] } else { 0.0 }),
        moment: resultant.moment,
        contact_zone: zone.measure,
        zone_bounds: [zone.lower, zone.upper],
        slip_zone: on_contact.slip_zone,
        separated: on_contact.counts[0],
        stick: on_contact.counts[1],
        slip: on_contact.counts[2],
        slip_rate: on_contact.slip_rate,
        max_accumulated_slip: sums.accumulated_slip.iter().fold(0.0, |a, &b| a.max(b)),
        friction_power: on_contact.friction_power,
        friction_dissipation: sums.friction_dissipation,
        viscous_power,
        viscous_dissipation: sums.viscous_dissipation,
        mean_damage,
        area_damage_below_half,
        velocity_kkt: velocity.stats.kkt_residual,
        damage_kkt: damage.stats.kkt_residual,
        newton_iterations: velocity.stats.newton_iterations,
        friction_iterations: velocity.stats.friction_iterations,
        damage_iterations: damage.stats.iterations,
        reactions: simulation
            .part_reactions(&velocity.reaction)
            .iter()
            .flatten()
            .copied()
            .collect(),
    };
    StepRecord { row, speed }
}

/// The contact zone of the step just done, measured on the penetration whose p_ν the step
/// used: u_{n−1} − g(t_{n−1}) in (5.1), or u_n − g(t_n) with the implicit normal compliance.
fn step_contact_zone<const D: usize>(
    setup: &ProblemSetup<D>,
    simulation: &Simulation<D>,
    contact: &ContactNodes<D>,
    coordinate: &LineCoordinate,
) -> ContactZone {
    let state = simulation.state();
    let space = simulation.space();
    let (pressed, gap_time) = if setup.problem.settings.contact == ContactTreatment::Implicit {
        (state.displacement.clone(), state.time)
    } else {
        let k = simulation.time_step();
        let previous: Vec<f64> = state
            .displacement
            .iter()
            .zip(&state.velocity)
            .map(|(u, v)| u - k * v)
            .collect();
        (previous, state.time - k)
    };
    let gap = &setup.problem.data.gap;
    contact_zone(
        space,
        &boundary_penetration(space, contact, &pressed, |x| gap(x, gap_time)),
        coordinate,
    )
}
