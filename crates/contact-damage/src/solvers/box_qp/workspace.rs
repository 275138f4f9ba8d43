//! The work vectors of one solve, kept by the solver between calls, and the states of the
//! indices they hold.

use crate::algebra::pcg::PcgVectors;
use crate::solvers::box_qp::projected_gauss_seidel::STALE;

/// Position of an index relative to its bounds: in the active set classification, and in a
/// predicted bound set ([`BoxQpSolver::solve_predicted`](super::BoxQpSolver::solve_predicted)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BoundStatus {
    /// Strictly between its bounds (its gradient vanishes at the solution).
    Free,
    /// On its lower bound.
    AtLower,
    /// On its upper bound.
    AtUpper,
}

impl BoundStatus {
    /// Where `value` lies: on `lower` (or below), on `upper` (or above), or between.
    pub fn of(value: f64, lower: f64, upper: f64) -> Self {
        if value <= lower {
            BoundStatus::AtLower
        } else if value >= upper {
            BoundStatus::AtUpper
        } else {
            BoundStatus::Free
        }
    }
}

/// Work vectors of one solve.
pub(super) struct Workspace {
    pub(super) gradient: Vec<f64>,
    pub(super) trial: Vec<f64>,
    pub(super) trial_gradient: Vec<f64>,
    pub(super) projected: Vec<f64>,
    pub(super) projected_gradient: Vec<f64>,
    pub(super) direction: Vec<f64>,
    pub(super) product: Vec<f64>,
    pub(super) fixed: Vec<bool>,
    /// Per index, the [`SETTLED`](super::projected_gauss_seidel::SETTLED) and [`STALE`] marks of
    /// the monotone multigrid.
    pub(super) marks: Vec<u8>,
    pub(super) state: Vec<BoundStatus>,
    pub(super) next_state: Vec<BoundStatus>,
    pub(super) cg: CgWork,
}

/// Work vectors of the preconditioned conjugate gradient method: those of the iteration and
/// one more for the preconditioner.
pub(super) struct CgWork {
    pub(super) vectors: PcgVectors,
    pub(super) scratch: Vec<f64>,
}

impl Workspace {
    /// Zeroes every vector (as [`Workspace::new`] leaves them).
    pub(super) fn reset(&mut self) {
        for vector in [
            &mut self.gradient,
            &mut self.trial,
            &mut self.trial_gradient,
            &mut self.projected,
            &mut self.projected_gradient,
            &mut self.direction,
            &mut self.product,
            &mut self.cg.scratch,
        ] {
            vector.fill(0.0);
        }
        self.cg.vectors.fill_zero();
        self.fixed.fill(false);
        self.marks.fill(STALE);
        self.state.fill(BoundStatus::Free);
        self.next_state.fill(BoundStatus::Free);
    }

    pub(super) fn new(dimension: usize) -> Self {
        Self {
            gradient: vec![0.0; dimension],
            trial: vec![0.0; dimension],
            trial_gradient: vec![0.0; dimension],
            projected: vec![0.0; dimension],
            projected_gradient: vec![0.0; dimension],
            direction: vec![0.0; dimension],
            product: vec![0.0; dimension],
            fixed: vec![false; dimension],
            marks: vec![STALE; dimension],
            state: vec![BoundStatus::Free; dimension],
            next_state: vec![BoundStatus::Free; dimension],
            cg: CgWork {
                vectors: PcgVectors::new(dimension),
                scratch: vec![0.0; dimension],
            },
        }
    }
}
