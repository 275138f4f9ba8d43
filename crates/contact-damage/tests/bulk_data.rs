//! Bulk data evaluated ahead of the steps ([`contact_damage::scheme::loads::BulkData`]): a field that
//! asks for several step times per evaluation gets them, and the run is bitwise the run that
//! evaluates each step's data at that step, uninterrupted or resumed at any step.

use crate::common;

use contact_damage::fem::space::LagrangeSpace;
use contact_damage::model::fields::{BatchScalarField, BatchVectorField};
use contact_damage::scheme::loads::{LoadQuadrature, BULK_DATA_BYTES};
use contact_damage::scheme::{Data, Simulation, State};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// A field of (x, t) that asks for `times` step times per evaluation and counts the
/// evaluations that received more than one.
struct Blocked<F> {
    field: F,
    times: usize,
    several: Arc<AtomicUsize>,
}

impl<F: Fn(&[f64; 2], f64) -> [f64; 2] + Send + Sync> BatchVectorField<2> for Blocked<F> {
    fn evaluate(&self, points: &[[f64; 2]], time: f64, out: &mut [[f64; 2]]) {
        for (x, value) in points.iter().zip(out) {
            *value = (self.field)(x, time);
        }
    }

    fn evaluate_at_times(&self, points: &[[f64; 2]], times: &[f64], out: &mut [[f64; 2]]) {
        if times.len() > 1 {
            self.several.fetch_add(1, Ordering::Relaxed);
        }
        for (&time, out) in times.iter().zip(out.chunks_mut(points.len())) {
            self.evaluate(points, time, out);
        }
    }

    fn times_per_evaluation(&self) -> usize {
        self.times
    }
}

impl BatchScalarField<2> for Blocked<fn(&[f64; 2], f64) -> f64> {
    fn evaluate(&self, points: &[[f64; 2]], time: f64, out: &mut [f64]) {
        for (x, value) in points.iter().zip(out) {
            *value = (self.field)(x, time);
        }
    }

    fn times_per_evaluation(&self) -> usize {
        self.times
    }
}

fn body_force(x: &[f64; 2], t: f64) -> [f64; 2] {
    [
        0.3 * (3.0 * x[0] + t).sin(),
        -0.2 * (2.0 * x[1]).cos() * (1.0 + t),
    ]
}

fn damage_supply(x: &[f64; 2], t: f64) -> f64 {
    -0.4 * (x[0] + 2.0 * t).sin().abs()
}

const STEPS: usize = 13;

/// Data whose f0 and q ask for `force_times` and `supply_times` step times per evaluation;
/// the counter of evaluations at several times.
fn data(force_times: usize, supply_times: usize) -> (Data<2>, Arc<AtomicUsize>) {
    let several = Arc::new(AtomicUsize::new(0));
    let mut data = common::quiet_data::<2>();
    data.body_force = Some(Arc::new(Blocked {
        field: body_force,
        times: force_times,
        several: several.clone(),
    }));
    data.damage_supply = Some(Arc::new(Blocked {
        field: damage_supply as fn(&[f64; 2], f64) -> f64,
        times: supply_times,
        several: several.clone(),
    }));
    (data, several)
}

/// A simulation whose f0 and q ask for `times` step times per evaluation; the counter of
/// evaluations at several times.
fn simulation(times: usize) -> (Simulation<2>, Arc<AtomicUsize>) {
    let (data, several) = data(times, times);
    let problem = common::problem(common::square(6), 1, data, 0.5, STEPS);
    (Simulation::new(problem).unwrap(), several)
}

/// The state after every step, as bits.
fn states(simulation: &mut Simulation<2>) -> Vec<Vec<u64>> {
    let mut states = Vec::new();
    simulation
        .run(|report| {
            let state = report.state;
            states.push(
                [&state.displacement, &state.velocity, &state.damage]
                    .into_iter()
                    .flatten()
                    .map(|v| v.to_bits())
                    .collect(),
            );
            Ok(())
        })
        .unwrap();
    states
}

#[test]
fn data_evaluated_ahead_leave_the_run_bitwise_unchanged() {
    let (mut step_by_step, several) = simulation(1);
    let expected = states(&mut step_by_step);
    assert_eq!(several.load(Ordering::Relaxed), 0);
    // The damage moved: the supply and the source matter.
    let last: &State = step_by_step.state();
    assert!(last.damage.iter().any(|&b| b < 0.99), "{:?}", last.damage);
    for times in [2, 5, 8] {
        let (mut blocked, several) = simulation(times);
        assert_eq!(
            states(&mut blocked),
            expected,
            "{times} times per evaluation"
        );
        // f0 in blocks of `times` (the last one shorter), one evaluation per chunk of cells.
        assert!(several.load(Ordering::Relaxed) >= STEPS / times);
    }
}

#[test]
fn a_run_resumed_with_data_evaluated_ahead_is_bitwise_the_uninterrupted_one() {
    let (mut uninterrupted, _) = simulation(5);
    let expected = states(&mut uninterrupted);
    // Stop after step 3 (inside the first block), start anew from that state: the blocks
    // now start at step 4 instead of 6.
    let (mut first, _) = simulation(5);
    for _ in 0..3 {
        first.step().unwrap();
    }
    let (mut resumed, _) = simulation(5);
    resumed.set_state(first.state().clone()).unwrap();
    assert_eq!(states(&mut resumed), expected[3..]);
}

#[test]
fn a_block_holds_the_fewest_times_asked_for_within_its_memory_budget() {
    let space = LagrangeSpace::new(Arc::new(common::square(6)), 1).unwrap();
    let quadrature = LoadQuadrature::new(&space);
    let with = |force_times: usize, supply_times: usize| {
        quadrature.times_per_block(&data(force_times, supply_times).0)
    };
    // Nothing asked: one time per evaluation, no block.
    assert_eq!(with(1, 1), 1);
    // The fewest of the two fields.
    assert_eq!(with(8, 5), 5);
    assert_eq!(with(3, 8), 3);
    // An ask beyond the budget is cut to what fits.
    let points = space.mesh().num_cells() * quadrature.points_per_cell();
    let per_time = points * 3 * std::mem::size_of::<f64>();
    let most = with(usize::MAX, usize::MAX);
    assert_eq!(most, BULK_DATA_BYTES / per_time);
    assert!(most > 8 && most * per_time <= BULK_DATA_BYTES);
}
