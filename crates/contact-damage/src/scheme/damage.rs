//! The damage step (5.2): a parabolic obstacle problem, i.e. the box-constrained quadratic
//! program
//!
//! minimize ½ βᵀ (M/k + κ K) β − bᵀ β  over  𝒦^h = {β ∈ X^h : 0 ≤ β(x_a) ≤ 1 at every node a},
//! b = M β_{n−1}/k + ⟨φ(ε(u_{n−1}), β_{n−1}) + q_n, φ_a⟩ (+ boundary flux),
//!
//! with the **consistent** mass matrix M: it is the L² inner product ⟨·,·⟩ of (5.2) itself, so no
//! variational crime is added, and it is the only choice for P2 (row-sum lumping of P2 on
//! simplices gives zero or negative vertex masses). M/k + κK is then SPD but not an M-matrix
//! (positive off-diagonal mass entries), so the solver is one of the globally convergent
//! methods of [`crate::solvers::box_qp`]: by default the truncated nonsmooth Newton multigrid on an
//! algebraic hierarchy of M/k + κK, built once per run (no factorization); optionally the
//! active set method, which factorizes M/k + κK once (in the first step) and solves the reduced
//! systems of every step by conjugate gradients preconditioned with that factor. In 2D either
//! is preceded, when the nodes of β_{n−1} on each bound are those of β_{n−2}, by one linear
//! solve on that bound set ([`BoxQpSolver::solve_predicted`]), which is the solution when its
//! KKT residual says so ([`MAX_PREDICTION_FILL`]); or, with [`BoundSetPrediction::Followed`],
//! at every step by active set iterations on bound sets solved with the factor of an earlier
//! set bordered by the nodes that moved ([`BoxQpSolver::solve_following`]). For l = 2,
//! 𝒦^h is the set of P2 fields whose nodal values lie in [0, 1] (a field may leave [0, 1]
//! slightly between nodes).

use crate::algebra::linalg::{multiply_symmetric, SparsityPattern};
use crate::error::{Error, Result};
use crate::fem::quadrature::QuadratureRule;
use crate::fem::space::{LagrangeSpace, Tabulation};
use crate::scheme::assembly::damage_element_matrix;
use crate::solvers::box_qp::{BoundStatus, BoxQpSettings, BoxQpSolver, BoxQpStats};
use faer::sparse::{Pair, SparseColMat};
use rayon::prelude::*;
use std::sync::Arc;

/// Assembles the scalar matrix m·M + κ·K on the space (consistent mass, exact quadrature).
pub fn assemble_damage_matrix<const D: usize>(
    space: &LagrangeSpace<D>,
    mass_coefficient: f64,
    diffusion: f64,
) -> Result<SparseColMat<usize, f64>> {
    let n = space.nodes_per_cell();
    let n_cells = space.mesh().num_cells();
    let mut pairs = Vec::with_capacity(n_cells * n * n);
    for cell in 0..n_cells {
        let nodes = space.cell_nodes(cell);
        for &row in nodes {
            for &col in nodes {
                pairs.push(Pair::new(row as isize, col as isize));
            }
        }
    }
    let pattern = SparsityPattern::from_pairs(space.num_nodes(), &pairs)?;
    let tabulation = Tabulation::cell_rule(
        space.element(),
        &QuadratureRule::<D>::simplex(2 * space.degree()),
    );
    let mut values = vec![0.0; pairs.len()];
    values
        .par_chunks_mut(n * n)
        .enumerate()
        .for_each(|(cell, out)| {
            damage_element_matrix(space, &tabulation, cell, mass_coefficient, diffusion, out);
        });
    pattern.matrix(&values)
}

/// The damage operator of (5.2) for one mesh, κ and k: the matrix M/k + κK with its symbolic
/// analysis (once), and the mass matrix for the right-hand side.
pub struct DamageOperator<const D: usize> {
    space: Arc<LagrangeSpace<D>>,
    mass: SparseColMat<usize, f64>,
    time_step: f64,
    solver: BoxQpSolver,
    /// Whether a step whose bound set repeats is first solved on it
    /// ([`MAX_PREDICTION_FILL`]).
    predicts_bound_sets: bool,
    /// How a bound set is predicted where it is.
    prediction: BoundSetPrediction,
}

/// How the damage step predicts the bound set of β_n where the factor of a bound set is cheap
/// ([`MAX_PREDICTION_FILL`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum BoundSetPrediction {
    /// When the nodes of β_{n−1} on each bound are those of β_{n−2}, one linear solve on that
    /// set with a factor of it ([`BoxQpSolver::solve_predicted`]), else the box QP solve. Each
    /// step's values are a function of its data and start alone, so a run resumed from a
    /// snapshot is bitwise the uninterrupted one.
    #[default]
    Repeated,
    /// At every step the primal–dual active set iteration from the bound set of the start,
    /// each set solved with the factor of an earlier set bordered by the nodes that changed
    /// status ([`BoxQpSolver::solve_following`]), else the box QP solve: a few solves with a
    /// factor per step where the bound set moves by a few nodes, as a damage front does. The
    /// values depend on the steps solved before at the rounding level (each is certified by
    /// its KKT residual).
    Followed,
}

/// The largest fill of the bound-set factor ([`BoxQpSolver::bound_set_fill`]) at which the
/// damage step tries the bound set of the previous steps. The prediction pays when one solve
/// with the factor is much cheaper than the multigrid iterations it replaces, and a
/// factorization (about ten solves, at each new bound set) not much dearer than one such
/// step. Measured by `cargo run --release -p contact-damage --example damage_factor_cost`:
/// the fill is 4.4–7.1 in 2D (P1 at 64²–256², P2 at 64²), where a solve costs a ninth to a
/// tenth of a multigrid step of `zones2d` (k = h) and a factorization about one step, and
/// 9.7–25.8 in 3D (P1 at 12³–24³, P2 at 12³), where at 24³ a solve costs half a multigrid step
/// of `zones3d` and a factorization seven steps.
pub const MAX_PREDICTION_FILL: f64 = 8.0;

/// Result of a damage step.
#[derive(Debug, Clone)]
pub struct DamageSolution {
    /// Nodal damage values β_n ∈ [0, 1].
    pub damage: Vec<f64>,
    /// Statistics of the box-QP solver (iterations, KKT residual, active bounds).
    pub stats: BoxQpStats,
}

impl<const D: usize> DamageOperator<D> {
    /// Assembles M/k + κK and analyses it. Errors name κ or k when they are not positive.
    pub fn new(
        space: Arc<LagrangeSpace<D>>,
        diffusion: f64,
        time_step: f64,
        settings: BoxQpSettings,
    ) -> Result<Self> {
        if !(diffusion.is_finite() && diffusion > 0.0) {
            return Err(Error::parameter(
                "damage_diffusion",
                diffusion,
                "κ must be > 0 (2.2)",
            ));
        }
        if !(time_step.is_finite() && time_step > 0.0) {
            return Err(Error::parameter("time_step", time_step, "k must be > 0"));
        }
        let mass = assemble_damage_matrix(&space, 1.0, 0.0)?;
        let operator = assemble_damage_matrix(&space, 1.0 / time_step, diffusion)?;
        let mut solver = BoxQpSolver::new(operator, settings)?;
        let predicts_bound_sets = solver.bound_set_fill()? <= MAX_PREDICTION_FILL;
        if !predicts_bound_sets {
            solver.release_bound_set_factor();
        }
        Ok(Self {
            space,
            mass,
            time_step,
            solver,
            predicts_bound_sets,
            prediction: BoundSetPrediction::default(),
        })
    }

    /// Sets how bound sets are predicted (where they are, [`DamageOperator::predicts_bound_sets`]).
    pub fn set_bound_set_prediction(&mut self, prediction: BoundSetPrediction) {
        self.prediction = prediction;
    }

    /// Whether a step whose bound set repeats is first solved on it: when the fill of the
    /// bound-set factor is at most [`MAX_PREDICTION_FILL`] (in 2D).
    pub fn predicts_bound_sets(&self) -> bool {
        self.predicts_bound_sets
    }

    /// The box-QP solver (its matrix M/k + κK and its factor).
    pub fn solver(&self) -> &BoxQpSolver {
        &self.solver
    }

    /// The space of the damage field.
    pub fn space(&self) -> &Arc<LagrangeSpace<D>> {
        &self.space
    }

    /// Solves (5.2): `source` holds ⟨φ_{n−1} + q_n, φ_a⟩ plus boundary fluxes; `previous` is
    /// β_{n−1} and `before_previous` β_{n−2}, or empty (at n = 1, or when it is not known).
    ///
    /// The box QP starts from the linear extrapolation clamp(2β_{n−1} − β_{n−2}, 0, 1), or from
    /// β_{n−1} when β_{n−2} is empty. The start only decides how many iterations the solver
    /// needs (the solution is the unique minimizer, to the solver's tolerance): for a smooth
    /// evolution the extrapolation is O(k²) from β_n where β_{n−1} is O(k). Measured on
    /// `zones2d` at 128 cells and 128 steps: 514 multigrid iterations in all from β_{n−1},
    /// 387 from the extrapolation.
    pub fn solve(
        &mut self,
        source: &[f64],
        previous: &[f64],
        before_previous: &[f64],
    ) -> Result<DamageSolution> {
        let n = self.space.num_nodes();
        if source.len() != n
            || previous.len() != n
            || !(before_previous.is_empty() || before_previous.len() == n)
        {
            return Err(Error::InvalidInput(format!(
                "damage step: source has {} values, previous damage {} and the one before {}, expected {n} (or 0 for the last)",
                source.len(),
                previous.len(),
                before_previous.len()
            )));
        }
        if let Some(i) = source.iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite(format!(
                "damage source at node {i} ({:?})",
                self.space.node(i)
            )));
        }
        let inertia = multiply_symmetric(&self.mass, previous);
        let rhs: Vec<f64> = inertia
            .iter()
            .zip(source)
            .map(|(m, s)| m / self.time_step + s)
            .collect();
        let mut damage = if before_previous.is_empty() {
            previous
                .iter()
                .map(|b| b.clamp(0.0, 1.0))
                .collect::<Vec<_>>()
        } else {
            previous
                .iter()
                .zip(before_previous)
                .map(|(b, before)| (2.0 * b - before).clamp(0.0, 1.0))
                .collect::<Vec<_>>()
        };
        let lower = vec![0.0; n];
        let upper = vec![1.0; n];
        if self.predicts_bound_sets && self.prediction == BoundSetPrediction::Followed {
            let stats = self
                .solver
                .solve_following(&rhs, &lower, &upper, &mut damage)?;
            return Ok(DamageSolution { damage, stats });
        }
        let predicted = self
            .predicts_bound_sets
            .then(|| repeated_bound_set(previous, before_previous))
            .flatten();
        let stats = match predicted {
            Some(predicted) => {
                self.solver
                    .solve_predicted(&rhs, &lower, &upper, &predicted, &mut damage)?
            }
            None => self.solver.solve(&rhs, &lower, &upper, &mut damage)?,
        };
        Ok(DamageSolution { damage, stats })
    }
}

/// Where the nodal damage `value` lies in 𝒦^h: on 0, on 1, or between.
fn bound_status(value: f64) -> BoundStatus {
    BoundStatus::of(value, 0.0, 1.0)
}

/// The nodes of β_{n−1} on 0 and on 1, when they are those of β_{n−2} (`None` otherwise, and
/// when β_{n−2} is not known): the bound set predicted for β_n. Most steps of a damage
/// evolution leave it as it was (a plateau where β = 1, a region where β = 0), and the step is
/// then one linear solve on it ([`BoxQpSolver::solve_predicted`]); where it moves, the step is
/// the box QP solve without prediction. The rule reads the step's data only, so a step's
/// result does not depend on the steps solved before by the same operator (`--resume`).
fn repeated_bound_set(previous: &[f64], before_previous: &[f64]) -> Option<Vec<BoundStatus>> {
    if before_previous.len() != previous.len() {
        return None;
    }
    previous
        .iter()
        .zip(before_previous)
        .map(|(&value, &before)| {
            let status = bound_status(value);
            (status == bound_status(before)).then_some(status)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::mesh::{BoundaryPart, Mesh};
    use BoundaryPart::{Dirichlet, Neumann};

    fn square(cells: usize) -> Arc<LagrangeSpace<2>> {
        let sides = [[Dirichlet, Neumann], [Neumann, Neumann]];
        let mesh = Mesh::box_mesh([0.0; 2], [1.0; 2], [cells; 2], sides).unwrap();
        Arc::new(LagrangeSpace::new(Arc::new(mesh), 1).unwrap())
    }

    #[test]
    fn the_bound_set_is_predicted_only_when_it_repeats() {
        use BoundStatus::{AtLower, AtUpper, Free};
        let previous = [0.0, 0.5, 1.0];
        assert_eq!(
            repeated_bound_set(&previous, &[0.0, 0.3, 1.0]),
            Some(vec![AtLower, Free, AtUpper])
        );
        assert_eq!(repeated_bound_set(&previous, &[0.0, 1.0, 1.0]), None);
        assert_eq!(repeated_bound_set(&previous, &[0.2, 0.5, 1.0]), None);
        assert_eq!(repeated_bound_set(&previous, &[]), None);
    }

    #[test]
    fn bound_sets_are_predicted_in_2d_and_not_where_the_factor_fills_in() {
        let settings = BoxQpSettings::default;
        let plane = DamageOperator::new(square(16), 0.01, 1.0 / 16.0, settings()).unwrap();
        assert!(plane.predicts_bound_sets());
        let sides = [[Dirichlet, Neumann], [Neumann, Neumann], [Neumann, Neumann]];
        let mesh = Mesh::box_mesh([0.0; 3], [1.0; 3], [12; 3], sides).unwrap();
        let space = Arc::new(LagrangeSpace::new(Arc::new(mesh), 1).unwrap());
        let mut solid = DamageOperator::new(space, 0.01, 1.0 / 12.0, settings()).unwrap();
        assert!(!solid.predicts_bound_sets());
        assert!(solid.solver.bound_set_fill().unwrap() > MAX_PREDICTION_FILL);
    }

    /// A plateau β = 1 receding by a few nodes per step (a source pushing β up left of a front
    /// that moves right to left, and down beyond it): the followed bound sets solve every
    /// step after the first with the factor of an earlier set, certified by the KKT residual,
    /// and give the solution of the repeated-set prediction.
    #[test]
    fn followed_bound_sets_solve_a_receding_plateau() {
        let space = square(16);
        let n = space.num_nodes();
        let settings = BoxQpSettings::default;
        let mut repeated = DamageOperator::new(space.clone(), 0.01, 0.05, settings()).unwrap();
        let mut followed = DamageOperator::new(space.clone(), 0.01, 0.05, settings()).unwrap();
        followed.set_bound_set_prediction(BoundSetPrediction::Followed);
        let (mut before, mut previous) = (Vec::new(), vec![1.0; n]);
        let mut bordered = 0;
        for step in 1..=8 {
            let front = 0.8 - 0.05 * step as f64;
            let source: Vec<f64> = (0..n)
                .map(|i| {
                    let x = space.node(i)[0];
                    if x < front {
                        1.0
                    } else {
                        -2.0 * (x - front)
                    }
                })
                .collect();
            let expected = repeated.solve(&source, &previous, &before).unwrap();
            let solution = followed.solve(&source, &previous, &before).unwrap();
            assert!(solution.stats.kkt_residual <= 1e-12, "{:?}", solution.stats);
            if step > 1 {
                assert!(
                    solution.stats.bound_set_solve,
                    "step {step}: {:?}",
                    solution.stats
                );
                bordered += usize::from(solution.stats.factorizations == 0);
            }
            for (a, b) in solution.damage.iter().zip(&expected.damage) {
                assert!((a - b).abs() <= 1e-10, "step {step}: {a} vs {b}");
            }
            assert!(expected.stats.upper_active > 0 && expected.stats.upper_active < n);
            before = std::mem::replace(&mut previous, expected.damage);
        }
        assert!(
            bordered >= 4,
            "{bordered} steps solved without a new factorization"
        );
    }

    /// A source that keeps β = 1 everywhere: once β_{n−1} and β_{n−2} both are 1, the step is
    /// the solve on that bound set, certified by its KKT residual.
    #[test]
    fn a_step_whose_bound_set_repeats_is_one_solve_on_it() {
        let space = square(8);
        let mut operator =
            DamageOperator::new(space.clone(), 0.01, 0.1, BoxQpSettings::default()).unwrap();
        let n = space.num_nodes();
        let source = vec![1.0; n];
        let ones = vec![1.0; n];
        let first = operator.solve(&source, &ones, &[]).unwrap();
        assert!(!first.stats.bound_set_solve);
        let repeated = operator.solve(&source, &ones, &ones).unwrap();
        assert!(repeated.stats.bound_set_solve, "{:?}", repeated.stats);
        assert_eq!(repeated.stats.iterations, 1);
        assert_eq!(repeated.damage, ones);
        assert!(repeated.stats.kkt_residual <= 1e-12);
    }
}
