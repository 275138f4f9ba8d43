//! The solver: its construction (checks of `A`, the factor's symbolic analysis or the
//! multigrid hierarchy, the coarse obstacle correction), the driver of one solve and its
//! statistics; the iterations themselves are in [`super::monotone_multigrid`],
//! [`super::active_set`] and [`super::reduced_solve`].

use faer::sparse::SparseColMat;

use crate::algebra::linalg::CholeskySolver;
use crate::algebra::multigrid::{inverse, Csr, Hierarchy};
use crate::error::{Error, History, Result};
use crate::solvers::box_qp::bound_set::BoundSetFactor;
use crate::solvers::box_qp::kkt::{
    box_qp_kkt_residual, gradient, project, scaled_kkt_residual, Problem,
};
use crate::solvers::box_qp::matrix_checks::{
    canonical_storage, validate_symmetric_positive_diagonal,
};
use crate::solvers::box_qp::projected_gauss_seidel::{FineRows, STALE};
use crate::solvers::box_qp::settings::{BoxQpMethod, BoxQpSettings, BoxQpStats};
use crate::solvers::box_qp::workspace::Workspace;
use crate::solvers::box_qp_coarse::{CoarseObstacle, NestedBoxQp};

/// Solver of the sparse box-constrained QP `min ½ xᵀAx − bᵀx, lower ≤ x ≤ upper` with SPD `A`.
///
/// Symbolic analysis done once per matrix pattern; numeric factorizations reused across solves.
pub struct BoxQpSolver {
    pub(super) matrix: SparseColMat<usize, f64>,
    pub(super) settings: BoxQpSettings,
    pub(super) diagonal: Vec<f64>,
    /// The Cholesky factor of `A` itself (symbolic analysis at construction, numeric
    /// factorization once, on the first solve that needs it; [`BoxQpMethod::ActiveSet`]).
    pub(super) factor: Option<CholeskySolver>,
    /// `A` by rows and its truncated multigrid hierarchy ([`BoxQpMethod::MonotoneMultigrid`],
    /// built at construction).
    pub(super) multigrid: Option<(FineRows, Hierarchy)>,
    /// The coarse obstacle correction on aggregates ([`BoxQpMethod::MonotoneMultigrid`], at
    /// least `coarse_obstacle::MIN_NESTED_SIZE` unknowns, diffusion dominated).
    pub(super) coarse: Option<CoarseObstacle<BoxQpSolver>>,
    /// Work vectors kept between calls (allocated by the first).
    pub(super) workspace: Option<Workspace>,
    /// The factor of the last predicted bound set ([`BoxQpSolver::solve_predicted`], created
    /// by its first call).
    pub(super) bound_set_factor: Option<BoundSetFactor>,
}

impl std::fmt::Debug for BoxQpSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BoxQpSolver")
            .field("dimension", &self.diagonal.len())
            .field("nonzeros", &self.matrix.val().len())
            .field("settings", &self.settings)
            .field(
                "factorized",
                &self
                    .factor
                    .as_ref()
                    .is_some_and(CholeskySolver::is_factorized),
            )
            .finish()
    }
}

impl BoxQpSolver {
    /// Validates (square, symmetric pattern, finite, positive diagonal) and analyses the pattern.
    ///
    /// The matrix must be stored with both triangles; its values must be symmetric up to a
    /// relative `1e-10` (measured against `√(A_ii A_jj)`). Positive definiteness itself is only
    /// detected by the Cholesky factorizations in [`BoxQpSolver::solve`]
    /// ([`Error::LinearAlgebra`]). Columns with unsorted row indices are sorted once here.
    pub fn new(matrix: SparseColMat<usize, f64>, settings: BoxQpSettings) -> Result<Self> {
        if !(settings.tolerance > 0.0 && settings.tolerance.is_finite()) {
            return Err(Error::parameter(
                "tolerance",
                settings.tolerance,
                "the KKT tolerance must be positive and finite",
            ));
        }
        if settings.max_iterations == 0 {
            return Err(Error::parameter(
                "max_iterations",
                0.0,
                "at least one iteration is needed",
            ));
        }
        let (nrows, ncols) = (matrix.nrows(), matrix.ncols());
        if nrows != ncols {
            return Err(Error::InvalidInput(format!(
                "box QP matrix must be square, got {nrows}×{ncols}"
            )));
        }
        if nrows == 0 {
            return Err(Error::InvalidInput("box QP matrix is empty (0×0)".into()));
        }
        let matrix = canonical_storage(matrix)?;
        let diagonal = validate_symmetric_positive_diagonal(&matrix)?;

        let factor = match settings.method {
            BoxQpMethod::ActiveSet => Some(CholeskySolver::analyse_as(
                &matrix,
                settings.factorization,
                "box QP Cholesky factor of A",
            )?),
            BoxQpMethod::MonotoneMultigrid => None,
        };
        let multigrid = (settings.method == BoxQpMethod::MonotoneMultigrid).then(|| {
            let rows = Csr::from_symmetric(&matrix);
            let hierarchy = Hierarchy::new(&rows);
            let fine = FineRows {
                lower_counts: rows.lower_counts(),
                inverse_diagonal: diagonal.iter().map(|&d| inverse(d)).collect(),
                rows,
            };
            (fine, hierarchy)
        });
        let coarse = match &multigrid {
            Some((fine, _)) => coarse_obstacle(&fine.rows, &diagonal, settings)?,
            None => None,
        };
        Ok(Self {
            matrix,
            settings,
            diagonal,
            factor,
            multigrid,
            coarse,
            workspace: None,
            bound_set_factor: None,
        })
    }

    /// Unknowns per level of the multigrid hierarchy, finest first (empty for
    /// [`BoxQpMethod::ActiveSet`]).
    pub fn multigrid_levels(&self) -> Vec<usize> {
        self.multigrid
            .as_ref()
            .map_or_else(Vec::new, |(_, hierarchy)| hierarchy.sizes())
    }

    /// Whether the Cholesky factor of `A` is supernodal (see
    /// [`FactorKind`](crate::algebra::linalg::FactorKind)); `false` without
    /// a factor ([`BoxQpMethod::MonotoneMultigrid`]).
    pub fn is_supernodal(&self) -> bool {
        self.factor
            .as_ref()
            .is_some_and(CholeskySolver::is_supernodal)
    }

    /// The matrix `A` (in canonical storage: sorted row indices in each column).
    pub fn matrix(&self) -> &SparseColMat<usize, f64> {
        &self.matrix
    }

    /// Sets the scaled KKT tolerance of the next solves (the coarse obstacle corrections
    /// solve their box QP to a tolerance relative to the fine residual).
    pub(crate) fn set_tolerance(&mut self, tolerance: f64) {
        debug_assert!(tolerance > 0.0 && tolerance.is_finite());
        self.settings.tolerance = tolerance;
    }

    /// The settings given to [`BoxQpSolver::new`].
    pub fn settings(&self) -> BoxQpSettings {
        self.settings
    }

    /// Solve for x; `x` holds the start on entry (projected onto the box first) and the solution on exit.
    ///
    /// On success `lower ≤ x ≤ upper` holds exactly and the scaled KKT residual
    /// ([`box_qp_kkt_residual`]) is at most the tolerance; a start that already satisfies the
    /// tolerance is returned (projected) without iterating.
    ///
    /// Errors: length mismatch or `lower_i > upper_i` ([`Error::InvalidInput`] naming `i`),
    /// non-finite data ([`Error::NonFinite`]), a failed factorization (`A` not positive definite,
    /// [`Error::LinearAlgebra`]), and [`Error::NoConvergence`] with the history of KKT residuals.
    /// After an error `x` holds a feasible point but not the solution.
    pub fn solve(
        &mut self,
        rhs: &[f64],
        lower: &[f64],
        upper: &[f64],
        x: &mut [f64],
    ) -> Result<BoxQpStats> {
        self.check_problem(rhs, lower, upper, x)?;
        let problem = Problem::new(rhs, lower, upper, self.settings.tolerance);
        let mut stats = BoxQpStats::default();
        let mut history = Vec::new();
        // The work vectors of the previous call, reset (so that a solve never depends on the
        // calls before it, as `--resume` requires), without new allocations. The monotone
        // multigrid writes every vector before it reads it, except the marks; zeroing them
        // all took 27 MB of writes per solve at 263k unknowns.
        let mut work = match self.workspace.take() {
            Some(mut work) => {
                if self.settings.method == BoxQpMethod::MonotoneMultigrid {
                    work.marks.fill(STALE);
                } else {
                    work.reset();
                }
                work
            }
            None => Workspace::new(x.len()),
        };
        let result = self.solve_with(&problem, x, &mut stats, &mut history, &mut work);
        self.workspace = Some(work);
        result.map(|()| stats)
    }

    /// [`BoxQpSolver::solve`] after the checks, with the work vectors `work`.
    fn solve_with(
        &mut self,
        problem: &Problem<'_>,
        x: &mut [f64],
        stats: &mut BoxQpStats,
        history: &mut Vec<f64>,
        work: &mut Workspace,
    ) -> Result<()> {
        let (rhs, lower, upper) = (problem.rhs, problem.lower, problem.upper);

        project(x, lower, upper);
        gradient(&self.matrix, x, rhs, &mut work.gradient);
        let start_residual = scaled_kkt_residual(x, &work.gradient, problem);
        if start_residual <= self.settings.tolerance {
            self.finish(x, problem, stats);
            return Ok(());
        }
        history.push(start_residual);

        if self.settings.method == BoxQpMethod::MonotoneMultigrid {
            self.monotone_multigrid(problem, x, work, stats, history)?;
            self.finish(x, problem, stats);
            return Ok(());
        }
        if self.active_set_phase(problem, x, work, stats, history)? {
            self.finish(x, problem, stats);
            return Ok(());
        }
        stats.used_fallback = true;
        self.projected_newton_phase(problem, x, work, stats, history)?;
        self.finish(x, problem, stats);
        Ok(())
    }

    /// Checks lengths, finiteness and the ordering of the bounds.
    pub(super) fn check_problem(
        &self,
        rhs: &[f64],
        lower: &[f64],
        upper: &[f64],
        x: &[f64],
    ) -> Result<()> {
        let dimension = self.diagonal.len();
        for (name, len) in [
            ("rhs", rhs.len()),
            ("lower", lower.len()),
            ("upper", upper.len()),
            ("x", x.len()),
        ] {
            if len != dimension {
                return Err(Error::InvalidInput(format!(
                    "box QP: `{name}` has length {len} but the matrix has dimension {dimension}"
                )));
            }
        }
        for i in 0..dimension {
            if !rhs[i].is_finite() {
                return Err(Error::NonFinite(format!(
                    "box QP right-hand side rhs[{i}] = {}",
                    rhs[i]
                )));
            }
            if !x[i].is_finite() {
                return Err(Error::NonFinite(format!("box QP start x[{i}] = {}", x[i])));
            }
            if lower[i].is_nan() || upper[i].is_nan() {
                return Err(Error::NonFinite(format!(
                    "box QP bounds at index {i}: lower = {}, upper = {}",
                    lower[i], upper[i]
                )));
            }
            if lower[i] > upper[i] {
                return Err(Error::InvalidInput(format!(
                    "box QP bounds crossed at index {i}: lower[{i}] = {} > upper[{i}] = {}",
                    lower[i], upper[i]
                )));
            }
            if lower[i] == f64::INFINITY || upper[i] == f64::NEG_INFINITY {
                return Err(Error::InvalidInput(format!(
                    "box QP bounds at index {i} leave no finite value: lower = {}, upper = {}",
                    lower[i], upper[i]
                )));
            }
        }
        Ok(())
    }

    /// Fills the final statistics for the feasible point `x`.
    pub(super) fn finish(&self, x: &[f64], problem: &Problem<'_>, stats: &mut BoxQpStats) {
        let residual =
            box_qp_kkt_residual(&self.matrix, problem.rhs, problem.lower, problem.upper, x);
        self.finish_with_residual(x, problem, residual, stats);
    }

    /// [`BoxQpSolver::finish`] for a feasible `x` whose scaled KKT residual is known.
    pub(super) fn finish_with_residual(
        &self,
        x: &[f64],
        problem: &Problem<'_>,
        residual: f64,
        stats: &mut BoxQpStats,
    ) {
        stats.kkt_residual = residual;
        stats.lower_active = x
            .iter()
            .zip(problem.lower)
            .filter(|(value, lower)| value == lower)
            .count();
        stats.upper_active = x
            .iter()
            .zip(problem.lower.iter().zip(problem.upper))
            .filter(|(value, (lower, upper))| lower < upper && value == upper)
            .count();
    }

    pub(super) fn no_convergence(
        &self,
        iterations: usize,
        residual: f64,
        history: &[f64],
    ) -> Error {
        Error::NoConvergence {
            solver: match self.settings.method {
                BoxQpMethod::MonotoneMultigrid => "box QP (truncated nonsmooth Newton multigrid)",
                BoxQpMethod::ActiveSet => "box QP (primal-dual active set + projected Newton)",
            },
            iterations,
            residual,
            tolerance: self.settings.tolerance,
            history: History(history.to_vec()),
        }
    }
}

/// The coarse correction of the box QP with the rows `rows` of `A` and its diagonal
/// ([`CoarseObstacle::new`]), whose coarse problem is solved by a box QP solver with the fine
/// one's settings but the coarse tolerance and iteration limit.
pub(crate) fn coarse_obstacle(
    rows: &Csr,
    diagonal: &[f64],
    settings: BoxQpSettings,
) -> Result<Option<CoarseObstacle<BoxQpSolver>>> {
    CoarseObstacle::new(
        rows,
        diagonal,
        settings.tolerance,
        |matrix, tolerance, max_iterations| {
            BoxQpSolver::new(
                matrix,
                BoxQpSettings {
                    tolerance,
                    max_iterations,
                    ..settings
                },
            )
        },
    )
}

impl NestedBoxQp for BoxQpSolver {
    fn set_tolerance(&mut self, tolerance: f64) {
        BoxQpSolver::set_tolerance(self, tolerance);
    }

    fn solve_nested(
        &mut self,
        rhs: &[f64],
        lower: &[f64],
        upper: &[f64],
        x: &mut [f64],
    ) -> Result<usize> {
        self.solve(rhs, lower, upper, x)
            .map(|stats| stats.iterations + stats.coarse_iterations)
    }
}
