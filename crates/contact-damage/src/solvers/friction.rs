//! Exact solver for the condensed Tresca-friction problem of the velocity step (5.1).
//!
//! In the velocity step (5.1) the friction bound s = p_τ(u_{n−1,ν} − g) is known (the coupling is
//! explicit, see docs/model.md §3), so (5.1) is the minimization of a strongly convex quadratic
//! plus a weighted sum of Euclidean norms of the nodal tangential velocities on Γ3 (nodal
//! quadrature of the friction term j of (3.14), nodal tangent frames). After the interior
//! unknowns are condensed out (Schur complement), each step leaves the small dense problem
//!
//! ```text
//!     minimize J(x) = ½ xᵀ S x − rᵀ x + Σ_a w_a |x_a|,        x ∈ R^m, m = G · n_groups,
//! ```
//!
//! where x_a ∈ R^G is the a-th consecutive block of x (G = 1 in 2D: one tangential direction;
//! G = 2 in 3D: the tangential plane, |·| the Euclidean norm, i.e. the friction *disc*), S is
//! symmetric positive definite and w_a ≥ 0 (w_a = 0: no friction at that node, the block is
//! free). J is strongly convex, so the minimizer is unique and is characterized by the KKT system
//!
//! ```text
//!     S x − r + W λ = 0,   |λ_a| ≤ 1,   λ_a = x_a / |x_a| where x_a ≠ 0,
//! ```
//!
//! (W = diag(w_a I_G)). Groups are *stick* (x_a = 0, w_a > 0), *slip* (x_a ≠ 0, w_a > 0) and
//! *free* (w_a = 0). The friction traction at node a is −w_a λ_a.
//!
//! # KKT residual (what is reported)
//! With g = S x − r, σ = 1 / max_i S_ii and scale = max(‖r‖_∞, f64::MIN_POSITIVE):
//! - `natural` = ‖x − prox_{σW|·|}(x − σ g)‖_∞ / (σ · scale), where the prox is block
//!   soft-thresholding y_a ↦ max(0, 1 − σ w_a/|y_a|) y_a. It vanishes exactly at the minimizer.
//!   The factor σ makes it invariant under a common scaling of (S, r, w) and of (x, r, w); when
//!   max_i S_ii = 1 it is exactly ‖x − prox_{W|·|}(x − (S x − r))‖_∞ / max(‖r‖_∞, tiny).
//! - `stationarity` = ‖S x − r + W λ‖_∞ / scale with the multipliers λ that [`CondensedFriction::solve`]
//!   returns: λ_a = x_a/|x_a| on slip blocks, λ_a = 0 on free blocks, and on stick blocks the
//!   projection onto the unit ball of λ̂_a = (r − S x)_a / w_a (so the returned λ is always
//!   dual feasible, and the residual of stationarity carries any infeasibility of λ̂).
//! - `dual_infeasibility` = max over stick blocks of w_a (|λ̂_a| − 1)₊ / scale = (|g_a| − w_a)₊ /
//!   scale: the part of the stick-block stationarity residual due to projecting λ̂.
//!
//! The solver stops when the largest of the three is ≤ the tolerance. A tolerance below the
//! rounding level of evaluating S x (about ε κ(S) relative, ε the machine epsilon) cannot be met;
//! the solver then reports [`Error::NoConvergence`] after a few cycles in which neither J nor the
//! residual improves (instead of exhausting the iteration budgets).
//!
//! # Method
//! **Semismooth Newton (primal–dual active set).** The minimizer is the zero of
//! F(x) = x − prox_{σW|·|}(x − σ(S x − r)). With y = x − σ g, a block is predicted *stick* when
//! |y_a| ≤ σ w_a (in the notation of Hintermüller–Stadler: z_a = λ_a + c x_a with c = 1/(σ w_a),
//! |z_a| ≤ 1), *free* when w_a = 0 and *slip* otherwise, with direction n_a = y_a/|y_a|. A Newton
//! step on F with a generalized Jacobian of the prox, multiplied through by the (invertible) slip
//! block of that Jacobian, is the *primal* system
//!
//! ```text
//!     x⁺_a = 0 on stick blocks,
//!     (S_NN + D) x⁺_N = r_N − (w n)_N        on the non-stick blocks N,
//!     D = blockdiag( w_a (I − n_a n_aᵀ) / (|y_a| − σ w_a) ) on slip blocks (0 on free blocks),
//! ```
//!
//! whose matrix is symmetric positive definite (S_NN is SPD, D is PSD; D = 0 when G = 1), solved
//! by a dense Cholesky factorization plus one step of iterative refinement. At the solution
//! |y_a| − σ w_a = |x_a|, so D is the curvature w_a (I − n nᵀ)/|x_a| of the norm.
//!
//! **Globalization by the merit function J.** A Newton point x⁺ is used only along the segment
//! x + t(x⁺ − x), t = 1, ½, ¼, …, with the Armijo condition J(x + t d) ≤ J(x) + η t J'(x; d)
//! (J'(x; d) is the one-sided directional derivative, so the test needs J'(x; d) < 0). Near the
//! solution the decrease of J falls below its rounding error; the full step is then accepted
//! when J does not increase by more than a rounding band *and* the KKT residual at least halves.
//! The full step is tried first, by both tests; a damped step (t < 1) must in addition lower J
//! by more than the rounding band, since at the rounding level the Armijo test accepts noise
//! and a damped step in place of a converging full one stalls Newton. A Newton step counts as
//! *progress* when the full step was accepted and the KKT residual at least halved; otherwise a burst of accelerated proximal-gradient steps (FISTA with step 1/L,
//! made monotone by an adaptive restart whenever J would increase) is taken from the current,
//! best, iterate and Newton is retried. L starts from a power-iteration estimate of λ_max(S) and
//! is doubled (backtracking on the descent lemma) up to the guaranteed bound
//! min(Gershgorin, Frobenius) ≥ λ_max(S).
//!
//! **Why this converges from any start.** Every accepted step keeps J non-increasing (up to the
//! rounding band). Either Newton stops making progress infinitely often: then infinitely many
//! bursts occur, and the first step of each burst is a plain proximal-gradient step, which for
//! the μ-strongly convex J contracts J − J* by at least the factor (1 − μ/L); since nothing in
//! between increases J, J → J* and, by strong convexity, x → x*. Or Newton makes progress at
//! every step from some point on: then the residual halves at every step and tends to 0. Near x*
//! the method is the semismooth Newton method, locally superlinear (quadratic); once the stick /
//! slip partition is identified (finitely many steps) the last Newton step in 2D (G = 1, D = 0)
//! is the exact solution of a linear system, and in 3D the remaining smooth system converges
//! quadratically. No smoothing or penalty enters the answer: stick blocks are exactly 0.
//!
//! References: G. Stadler, Semismooth Newton and augmented Lagrangian methods for a simplified
//! friction problem, SIAM J. Optim. 15 (2004); M. Hintermüller, G. Stadler, An infeasible
//! primal–dual algorithm for total bounded variation–based inf-convolution-type image
//! restoration, SIAM J. Sci. Comput. 28 (2006); A. Beck, M. Teboulle, FISTA (2009);
//! B. O'Donoghue, E. Candès, Adaptive restart for accelerated gradient schemes (2015).

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch};
use faer::linalg::cholesky::llt::solve::solve_in_place_with_conj;
use faer::linalg::matmul::matmul;
use faer::prelude::*;
use faer::{Accum, Conj};

use crate::algebra::linalg::{dot, max_abs};
use crate::error::History;
use crate::error::{Error, Result};

/// Armijo constant η of the Newton line search.
const ARMIJO: f64 = 1e-4;
/// Smallest Newton step length tried before falling back to proximal-gradient steps.
const MIN_STEP: f64 = 1.0 / 1024.0;
/// Length of the first burst of proximal-gradient steps; it doubles while Newton makes no
/// progress, up to [`MAX_BURST`], and is reset after a successful Newton step.
const INITIAL_BURST: usize = 10;
/// Largest burst of proximal-gradient steps between two Newton attempts.
const MAX_BURST: usize = 640;
/// Consecutive Newton-plus-burst cycles without any improvement of J (beyond its rounding band)
/// or of the KKT residual after which the solver reports that it stagnated at the rounding level.
const STALL_LIMIT: usize = 5;
/// Power iterations used to estimate λ_max(S).
const POWER_ITERATIONS: usize = 30;
/// Safety factor on the power-iteration estimate of λ_max(S).
const LIPSCHITZ_SAFETY: f64 = 1.1;
/// Relative asymmetry |S_ij − S_ji| / sqrt(S_ii S_jj) tolerated by [`CondensedFriction::validate`].
pub const SYMMETRY_TOLERANCE: f64 = 1e-10;

/// Settings of [`CondensedFriction::solve`].
#[derive(Debug, Clone, Copy)]
pub struct FrictionSettings {
    /// Bound on the relative KKT residual ([`KktResidual::max`]); default 1e-12.
    pub tolerance: f64,
    /// Largest number of Newton systems solved; default 100.
    pub max_newton: usize,
    /// Largest number of proximal-gradient (FISTA) steps; default 20000.
    pub max_gradient: usize,
}

impl Default for FrictionSettings {
    fn default() -> Self {
        Self {
            tolerance: 1e-12,
            max_newton: 100,
            max_gradient: 20000,
        }
    }
}

/// The parts of the scale-aware KKT residual documented in the [module docs](self).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct KktResidual {
    /// ‖x − prox_{σW|·|}(x − σ(S x − r))‖_∞ / (σ · scale), σ = 1 / max_i S_ii.
    pub natural: f64,
    /// ‖S x − r + W λ‖_∞ / scale with the returned (dual-feasible) multipliers λ.
    pub stationarity: f64,
    /// max over stick blocks of (|(S x − r)_a| − w_a)₊ / scale.
    pub dual_infeasibility: f64,
}

impl KktResidual {
    /// The largest of the three parts: the quantity compared with the tolerance.
    pub fn max(&self) -> f64 {
        self.natural
            .max(self.stationarity)
            .max(self.dual_infeasibility)
    }
}

/// What [`CondensedFriction::solve`] did and where it ended.
#[derive(Debug, Clone, Default)]
pub struct FrictionStats {
    /// Newton systems solved (each one a dense Cholesky factorization).
    pub newton_iterations: usize,
    /// Proximal-gradient (FISTA) steps taken, restarts included.
    pub gradient_iterations: usize,
    /// Natural part of the KKT residual at the solution ([`KktResidual::natural`]).
    pub kkt_residual: f64,
    /// Stationarity part ([`KktResidual::stationarity`]).
    pub stationarity: f64,
    /// Dual-infeasibility part ([`KktResidual::dual_infeasibility`]).
    pub dual_infeasibility: f64,
    /// Groups with w_a > 0 and x_a = 0.
    pub stick: usize,
    /// Groups with w_a > 0 and x_a ≠ 0.
    pub slip: usize,
    /// Groups with w_a = 0.
    pub free: usize,
}

/// The condensed friction problem min ½ xᵀ S x − rᵀ x + Σ_a w_a |x_a|; borrows its data.
///
/// `matrix` is S (m × m, symmetric positive definite; it is used through its symmetric part
/// ½(S + Sᵀ), and [`validate`](Self::validate) rejects asymmetry beyond [`SYMMETRY_TOLERANCE`]),
/// `rhs` is r (length m), `weights` holds w_a ≥ 0 (one per group: the friction bound times the
/// nodal quadrature weight), `group_size` is G ∈ {1, 2} and m = G · weights.len().
pub struct CondensedFriction<'a> {
    /// S: dense, symmetric positive definite, m × m.
    pub matrix: MatRef<'a, f64>,
    /// r: length m.
    pub rhs: &'a [f64],
    /// w_a ≥ 0, one per group.
    pub weights: &'a [f64],
    /// G: 1 (2D, one tangential direction) or 2 (3D, tangential plane).
    pub group_size: usize,
}

impl CondensedFriction<'_> {
    /// Number of unknowns m = group_size · weights.len().
    pub fn dimension(&self) -> usize {
        self.group_size * self.weights.len()
    }

    /// Validates sizes (m = group_size · weights.len(), group_size ∈ {1, 2}), finiteness of S,
    /// r and w, w ≥ 0, a positive diagonal of S and symmetry of S to [`SYMMETRY_TOLERANCE`].
    /// Errors name the offending index. Positive definiteness is not checked here (it would cost
    /// a factorization); a failing Cholesky factorization in [`solve`](Self::solve) reports it.
    pub fn validate(&self) -> Result<()> {
        self.validate_vectors()?;
        Self::validate_matrix(self.matrix)
    }

    /// The O(m) part of [`validate`](Self::validate): sizes (S's too), w and r, not the entries
    /// of S.
    fn validate_vectors(&self) -> Result<()> {
        if self.group_size != 1 && self.group_size != 2 {
            return Err(Error::parameter(
                "group_size",
                self.group_size as f64,
                "must be 1 (2D: one tangential direction) or 2 (3D: tangential plane)",
            ));
        }
        let m = self.dimension();
        if self.matrix.nrows() != m || self.matrix.ncols() != m {
            return Err(Error::InvalidInput(format!(
                "friction matrix is {}×{} but group_size · weights.len() = {} · {} = {m}",
                self.matrix.nrows(),
                self.matrix.ncols(),
                self.group_size,
                self.weights.len()
            )));
        }
        if self.rhs.len() != m {
            return Err(Error::InvalidInput(format!(
                "friction right-hand side has length {} but m = {m}",
                self.rhs.len()
            )));
        }
        for (a, &w) in self.weights.iter().enumerate() {
            if !w.is_finite() || w < 0.0 {
                return Err(Error::parameter(
                    format!("weights[{a}]"),
                    w,
                    "friction weight must be finite and ≥ 0",
                ));
            }
        }
        if let Some(i) = self.rhs.iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite(format!(
                "friction right-hand side rhs[{i}] = {}",
                self.rhs[i]
            )));
        }
        Ok(())
    }

    /// The O(m²) part of [`validate`](Self::validate), for S alone: square, finite, a positive
    /// diagonal, symmetric to [`SYMMETRY_TOLERANCE`]. A caller that solves many problems with
    /// one S checks it once here and then calls
    /// [`solve_with_checked_matrix`](Self::solve_with_checked_matrix).
    pub fn validate_matrix(matrix: MatRef<'_, f64>) -> Result<()> {
        let m = matrix.nrows();
        if matrix.ncols() != m {
            return Err(Error::InvalidInput(format!(
                "friction matrix is {}×{}, not square",
                matrix.nrows(),
                matrix.ncols()
            )));
        }
        for j in 0..m {
            for i in 0..m {
                let value = matrix[(i, j)];
                if !value.is_finite() {
                    return Err(Error::NonFinite(format!(
                        "friction matrix entry ({i}, {j}) = {value}"
                    )));
                }
            }
        }
        for i in 0..m {
            let value = matrix[(i, i)];
            if value <= 0.0 {
                return Err(Error::InvalidInput(format!(
                    "friction matrix diagonal entry ({i}, {i}) = {value} ≤ 0: S must be positive definite"
                )));
            }
        }
        for j in 0..m {
            for i in (j + 1)..m {
                let asymmetry = (matrix[(i, j)] - matrix[(j, i)]).abs();
                let size = (matrix[(i, i)] * matrix[(j, j)]).sqrt();
                if asymmetry > SYMMETRY_TOLERANCE * size {
                    return Err(Error::InvalidInput(format!(
                        "friction matrix is not symmetric: entries ({i}, {j}) = {} and ({j}, {i}) = {} differ by {asymmetry:.3e} > {SYMMETRY_TOLERANCE:.0e} · sqrt(S_ii S_jj)",
                        matrix[(i, j)],
                        matrix[(j, i)]
                    )));
                }
            }
        }
        Ok(())
    }

    /// J(x) = ½ xᵀ S x − rᵀ x + Σ_a w_a |x_a| (S through its symmetric part).
    ///
    /// # Panics
    /// If the problem fails [`validate`](Self::validate) or `x.len()` differs from
    /// [`dimension`](Self::dimension) (programming errors; [`solve`](Self::solve) returns errors).
    pub fn objective(&self, x: &[f64]) -> f64 {
        self.assert_length(x);
        self.with_problem(|problem| {
            let mut sx = vec![0.0; x.len()];
            problem.apply(x, &mut sx);
            problem.energy(x, &sx).value
        })
    }

    /// The natural part of the KKT residual at x, [`KktResidual::natural`]: ‖x − prox_{σW|·|}(x −
    /// σ(S x − r))‖_∞ / (σ max(‖r‖_∞, tiny)) with σ = 1/max_i S_ii (see the module docs).
    ///
    /// # Panics
    /// If the problem fails [`validate`](Self::validate) or `x.len()` differs from
    /// [`dimension`](Self::dimension) (programming errors; [`solve`](Self::solve) returns errors).
    pub fn kkt_residual(&self, x: &[f64]) -> f64 {
        self.kkt_report(x).natural
    }

    /// All three parts of the KKT residual at x (natural, stationarity, dual infeasibility).
    ///
    /// # Panics
    /// If the problem fails [`validate`](Self::validate) or `x.len()` differs from
    /// [`dimension`](Self::dimension) (programming errors; [`solve`](Self::solve) returns errors).
    pub fn kkt_report(&self, x: &[f64]) -> KktResidual {
        self.assert_length(x);
        self.with_problem(|problem| {
            let mut sx = vec![0.0; x.len()];
            problem.apply(x, &mut sx);
            problem.kkt(x, &sx)
        })
    }

    /// Solve in place: `x` is the start on entry (any finite vector), the solution on exit;
    /// `multipliers` (length m) receives λ (traction on node a = −w_a λ_a), see the module docs
    /// for the definition on stick, slip and free blocks.
    ///
    /// Errors: invalid data ([`validate`](Self::validate)), wrong lengths of `x` or `multipliers`,
    /// a non-finite start, invalid settings, a failed Cholesky factorization (S not positive
    /// definite) and [`Error::NoConvergence`] (with the KKT-residual history, one entry per
    /// Newton attempt or gradient burst) when the iteration budgets run out.
    pub fn solve(
        &self,
        x: &mut [f64],
        multipliers: &mut [f64],
        settings: &FrictionSettings,
    ) -> Result<FrictionStats> {
        self.validate()?;
        self.check_solve_arguments(x, multipliers, settings)?;
        self.with_problem(|problem| problem.solve(x, multipliers, settings))
    }

    /// [`solve`](Self::solve) for a matrix S already checked by
    /// [`validate_matrix`](Self::validate_matrix) and **exactly** symmetric: the O(m²) checks
    /// of S and the scan for its symmetric part are skipped (the velocity step checks its
    /// condensed operator once per factorization and solves with it at every step; at 3D 32³,
    /// m = 2178, the checks cost about as much as a Newton iteration's products). Everything
    /// else is checked as in [`solve`](Self::solve).
    ///
    /// # Panics
    /// In debug builds, if S is not exactly symmetric (a programming error).
    pub fn solve_with_checked_matrix(
        &self,
        x: &mut [f64],
        multipliers: &mut [f64],
        settings: &FrictionSettings,
    ) -> Result<FrictionStats> {
        // sizes (S included), w and r
        self.validate_vectors()?;
        let m = self.dimension();
        debug_assert!(
            (0..m).all(|j| (j + 1..m).all(|i| self.matrix[(i, j)] == self.matrix[(j, i)])),
            "solve_with_checked_matrix: S is not exactly symmetric"
        );
        self.check_solve_arguments(x, multipliers, settings)?;
        Problem::new(self.matrix, self.rhs, self.weights, self.group_size).solve(
            x,
            multipliers,
            settings,
        )
    }

    /// The settings, the lengths of `x` and `multipliers` and a finite start.
    fn check_solve_arguments(
        &self,
        x: &[f64],
        multipliers: &[f64],
        settings: &FrictionSettings,
    ) -> Result<()> {
        if !(settings.tolerance.is_finite() && settings.tolerance > 0.0) {
            return Err(Error::parameter(
                "tolerance",
                settings.tolerance,
                "friction solver tolerance must be finite and > 0",
            ));
        }
        let m = self.dimension();
        if x.len() != m {
            return Err(Error::InvalidInput(format!(
                "friction start vector has length {} but m = {m}",
                x.len()
            )));
        }
        if multipliers.len() != m {
            return Err(Error::InvalidInput(format!(
                "friction multiplier vector has length {} but m = {m}",
                multipliers.len()
            )));
        }
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite(format!(
                "friction start vector x[{i}] = {}",
                x[i]
            )));
        }
        Ok(())
    }

    fn assert_length(&self, x: &[f64]) {
        if let Err(error) = self.validate() {
            panic!("invalid condensed friction problem: {error}");
        }
        assert_eq!(
            x.len(),
            self.dimension(),
            "friction vector length must be m = group_size · weights.len()"
        );
    }

    /// Runs `body` on the problem with S replaced by its symmetric part (a copy is made only when
    /// S is not exactly symmetric).
    fn with_problem<R>(&self, body: impl FnOnce(&Problem<'_>) -> R) -> R {
        let m = self.matrix.nrows().min(self.matrix.ncols());
        let symmetric =
            (0..m).all(|j| (j + 1..m).all(|i| self.matrix[(i, j)] == self.matrix[(j, i)]));
        let owned = (!symmetric).then(|| {
            Mat::from_fn(m, m, |i, j| {
                0.5 * (self.matrix[(i, j)] + self.matrix[(j, i)])
            })
        });
        let matrix = owned.as_ref().map_or(self.matrix, |copy| copy.as_ref());
        body(&Problem::new(
            matrix,
            self.rhs,
            self.weights,
            self.group_size,
        ))
    }
}

/// Relative residual ‖b − A y‖_∞ / ‖b‖_∞ of the recursion at which the preconditioned
/// conjugate gradients of a Newton system stop ([`Problem::newton_point`]).
const NEWTON_PCG_TOLERANCE: f64 = 1e-14;
/// An accepted solution has a recomputed residual ‖b − A y‖_∞ of at most
/// [`NEWTON_PCG_TOLERANCE`] ‖b‖_∞ plus this many ulps of ‖A‖_∞ ‖y‖_∞, the rounding floor of
/// evaluating b − A y (the accuracy of a backward-stable factorization; nothing looser).
const NEWTON_PCG_ROUNDING_ULPS: f64 = 16.0;
/// Iterations after which the preconditioned conjugate gradients give up and the Newton system
/// is factorized afresh.
const NEWTON_PCG_ITERATIONS: usize = 25;

/// The non-stick unknowns N of a Newton system and its slip curvatures D (3D): blocks at
/// `position` in N with direction n and curvature c, D = c (I − n nᵀ).
struct NewtonSystem {
    unknowns: Vec<usize>,
    slip_curvature: Vec<(usize, [f64; 2], f64)>,
}

/// Entry (k, l) of the slip curvature block c (I − n nᵀ).
fn slip_entry(direction: [f64; 2], curvature: f64, k: usize, l: usize) -> f64 {
    let identity = if k == l { 1.0 } else { 0.0 };
    curvature * (identity - direction[k] * direction[l])
}

/// The factor of the last Newton system factorized in one solve, its non-stick unknowns, and
/// the buffer it lives in (m × m, allocated at the first factorization of the solve).
#[derive(Default)]
struct NewtonCache {
    unknowns: Vec<usize>,
    buffer: Option<Mat<f64>>,
    /// The leading n × n block of `buffer` holds the Cholesky factor L (lower triangle).
    factor: Option<usize>,
}

impl NewtonCache {
    /// Cholesky factor L of A = S_NN + D, in place in the buffer.
    fn factorize(
        &mut self,
        matrix: MatRef<'_, f64>,
        system: &NewtonSystem,
    ) -> Result<MatRef<'_, f64>> {
        let m = matrix.nrows();
        let n = system.unknowns.len();
        self.factor = None;
        let buffer = self.buffer.get_or_insert_with(|| Mat::zeros(m, m));
        let mut reduced = buffer.as_mut().submatrix_mut(0, 0, n, n);
        // lower triangle of S_NN, column by column (contiguous columns of S)
        for (j, &column_index) in system.unknowns.iter().enumerate() {
            let column = matrix.col(column_index);
            let mut target = reduced.rb_mut().col_mut(j);
            for i in j..n {
                target[i] = column[system.unknowns[i]];
            }
        }
        for &(position, direction, curvature) in &system.slip_curvature {
            for k in 0..2 {
                for l in 0..=k {
                    reduced[(position + k, position + l)] += slip_entry(direction, curvature, k, l);
                }
            }
        }
        let parallelism = faer::get_global_parallelism();
        let mut memory = MemBuffer::try_new(cholesky_in_place_scratch::<f64>(
            n,
            parallelism,
            Default::default(),
        ))
        .map_err(|_| Error::LinearAlgebra {
            context: "friction Newton system".into(),
            message: format!(
                "no memory for the workspace of a dense Cholesky factorization of size {n}"
            ),
        })?;
        cholesky_in_place(
            reduced.rb_mut(),
            Default::default(),
            parallelism,
            MemStack::new(&mut memory),
            Default::default(),
        )
        .map_err(|err| Error::LinearAlgebra {
            context: "friction Newton system (S restricted to the non-stick blocks)".into(),
            message: format!("Cholesky factorization failed ({err:?}): S is not positive definite"),
        })?;
        self.unknowns.clone_from(&system.unknowns);
        self.factor = Some(n);
        Ok(self.factor_ref().expect("just factorized"))
    }

    /// The factor L of the last factorized system, if any.
    fn factor_ref(&self) -> Option<MatRef<'_, f64>> {
        let n = self.factor?;
        Some(self.buffer.as_ref()?.as_ref().submatrix(0, 0, n, n))
    }
}

/// v ← (L Lᵀ)⁻¹ v with the lower triangle of `factor`.
fn cholesky_solve(factor: MatRef<'_, f64>, v: &mut Col<f64>) {
    solve_in_place_with_conj(
        factor,
        Conj::No,
        v.as_mat_mut(),
        Par::Seq,
        MemStack::new(&mut MemBuffer::new(StackReq::EMPTY)),
    );
}

/// y with A y = b by conjugate gradients preconditioned with the Cholesky factor L of a nearby
/// SPD matrix, from y = (L Lᵀ)⁻¹ b, until the recursive residual is ≤ [`NEWTON_PCG_TOLERANCE`]
/// ‖b‖_∞; None unless that happens within [`NEWTON_PCG_ITERATIONS`] iterations and the recomputed
/// residual is then within [`NEWTON_PCG_TOLERANCE`] ‖b‖_∞ + [`NEWTON_PCG_ROUNDING_ULPS`] ε
/// ‖A‖_∞ ‖y‖_∞. `apply(v, out)` sets out = A v; `matrix_norm` is ‖A‖_∞.
fn preconditioned_cg(
    apply: impl Fn(&Col<f64>, &mut Col<f64>),
    factor: MatRef<'_, f64>,
    matrix_norm: f64,
    rhs: &Col<f64>,
) -> Option<Col<f64>> {
    let norm = |v: &Col<f64>| v.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    let target = NEWTON_PCG_TOLERANCE * norm(rhs);
    let mut product = Col::<f64>::zeros(rhs.nrows());
    let mut solution = rhs.clone();
    cholesky_solve(factor, &mut solution);
    apply(&solution, &mut product);
    let mut residual = rhs - &product;
    let mut preconditioned = residual.clone();
    cholesky_solve(factor, &mut preconditioned);
    let mut direction = preconditioned.clone();
    let mut rz = column_dot(&residual, &preconditioned);
    for _ in 0..NEWTON_PCG_ITERATIONS {
        if norm(&residual) <= target {
            // the recursive residual drifts from the true one: confirm
            apply(&solution, &mut product);
            let true_residual = rhs - &product;
            let floor = NEWTON_PCG_ROUNDING_ULPS * f64::EPSILON * matrix_norm * norm(&solution);
            return (norm(&true_residual) <= target + floor).then_some(solution);
        }
        apply(&direction, &mut product);
        let curvature = column_dot(&direction, &product);
        if !(curvature > 0.0 && rz.is_finite()) {
            return None;
        }
        let alpha = rz / curvature;
        solution += alpha * &direction;
        residual -= alpha * &product;
        preconditioned.copy_from(&residual);
        cholesky_solve(factor, &mut preconditioned);
        let next = column_dot(&residual, &preconditioned);
        let beta = next / rz;
        rz = next;
        direction = &preconditioned + beta * &direction;
    }
    None
}

/// aᵀb of two columns.
fn column_dot(a: &Col<f64>, b: &Col<f64>) -> f64 {
    a.iter().zip(b.iter()).map(|(x, y)| x * y).sum()
}

/// J together with the magnitude of its terms (for rounding bands).
#[derive(Debug, Clone, Copy)]
struct Energy {
    value: f64,
    magnitude: f64,
}

/// Step size control of the proximal-gradient steps.
#[derive(Debug, Clone, Copy)]
struct Lipschitz {
    /// Current L (≥ the power-iteration estimate, ≤ `upper`).
    value: f64,
    /// Guaranteed bound min(Gershgorin, Frobenius) ≥ λ_max(S).
    upper: f64,
}

/// The validated problem with a symmetric matrix.
struct Problem<'a> {
    matrix: MatRef<'a, f64>,
    rhs: &'a [f64],
    weights: &'a [f64],
    group: usize,
    /// σ = 1 / max_i S_ii: the step of the natural residual and of the active-set prediction.
    sigma: f64,
    /// max(‖r‖_∞, f64::MIN_POSITIVE).
    scale: f64,
}

fn block_norm(block: &[f64]) -> f64 {
    match block {
        [single] => single.abs(),
        [first, second] => first.hypot(*second),
        _ => block.iter().map(|v| v * v).sum::<f64>().sqrt(),
    }
}

/// Block soft-thresholding y ↦ max(0, 1 − threshold/|y|) y, in place.
fn shrink(block: &mut [f64], threshold: f64) {
    let norm = block_norm(block);
    let factor = if norm > threshold {
        1.0 - threshold / norm
    } else {
        0.0
    };
    for value in block.iter_mut() {
        *value *= factor;
    }
}

impl<'a> Problem<'a> {
    fn new(matrix: MatRef<'a, f64>, rhs: &'a [f64], weights: &'a [f64], group: usize) -> Self {
        let max_diagonal = (0..matrix.nrows()).fold(0.0_f64, |acc, i| acc.max(matrix[(i, i)]));
        let sigma = if max_diagonal > 0.0 {
            1.0 / max_diagonal
        } else {
            1.0
        };
        Self {
            matrix,
            rhs,
            weights,
            group,
            sigma,
            scale: max_abs(rhs).max(f64::MIN_POSITIVE),
        }
    }

    fn dimension(&self) -> usize {
        self.rhs.len()
    }

    /// Rounding band of a sum of `dimension` terms of total size `magnitude`.
    fn rounding_band(&self, magnitude: f64) -> f64 {
        64.0 * f64::EPSILON * ((self.dimension() + 1) as f64).sqrt() * magnitude
    }

    /// out = S x.
    fn apply(&self, x: &[f64], out: &mut [f64]) {
        matmul(
            ColMut::from_slice_mut(out).as_mat_mut(),
            Accum::Replace,
            self.matrix,
            ColRef::from_slice(x).as_mat(),
            1.0,
            Par::Seq,
        );
    }

    fn friction(&self, x: &[f64]) -> f64 {
        x.chunks_exact(self.group)
            .zip(self.weights)
            .map(|(block, &w)| w * block_norm(block))
            .sum()
    }

    /// ½ xᵀ S x − rᵀ x without the friction term, and its magnitude.
    fn smooth_energy(&self, x: &[f64], sx: &[f64]) -> Energy {
        let quadratic = 0.5 * dot(x, sx);
        let linear = dot(self.rhs, x);
        Energy {
            value: quadratic - linear,
            magnitude: quadratic.abs() + linear.abs(),
        }
    }

    fn energy(&self, x: &[f64], sx: &[f64]) -> Energy {
        let smooth = self.smooth_energy(x, sx);
        let friction = self.friction(x);
        Energy {
            value: smooth.value + friction,
            magnitude: smooth.magnitude + friction,
        }
    }

    fn kkt(&self, x: &[f64], sx: &[f64]) -> KktResidual {
        let group = self.group;
        let mut natural = 0.0_f64;
        let mut stationarity = 0.0_f64;
        let mut dual = 0.0_f64;
        let mut gradient = [0.0; 2];
        let mut shifted = [0.0; 2];
        for (a, &w) in self.weights.iter().enumerate() {
            let range = a * group..(a + 1) * group;
            let block = &x[range.clone()];
            let gradient = &mut gradient[..group];
            let shifted = &mut shifted[..group];
            for (k, i) in range.enumerate() {
                gradient[k] = sx[i] - self.rhs[i];
                shifted[k] = x[i] - self.sigma * gradient[k];
            }
            shrink(shifted, self.sigma * w);
            for k in 0..group {
                natural = natural.max((block[k] - shifted[k]).abs() / self.sigma);
            }
            let norm = block_norm(block);
            let gradient_norm = block_norm(gradient);
            if w == 0.0 {
                stationarity = stationarity.max(max_abs(gradient));
            } else if norm > 0.0 {
                for k in 0..group {
                    stationarity = stationarity.max((gradient[k] + w * block[k] / norm).abs());
                }
            } else if gradient_norm > w {
                let excess = 1.0 - w / gradient_norm;
                stationarity = stationarity.max(excess * max_abs(gradient));
                dual = dual.max(gradient_norm - w);
            }
        }
        KktResidual {
            natural: natural / self.scale,
            stationarity: stationarity / self.scale,
            dual_infeasibility: dual / self.scale,
        }
    }

    /// The multipliers λ at x (documented in the module docs).
    fn multipliers(&self, x: &[f64], sx: &[f64], out: &mut [f64]) {
        let group = self.group;
        for (a, &w) in self.weights.iter().enumerate() {
            let range = a * group..(a + 1) * group;
            let norm = block_norm(&x[range.clone()]);
            if w == 0.0 {
                out[range].fill(0.0);
            } else if norm > 0.0 {
                for i in range {
                    out[i] = x[i] / norm;
                }
            } else {
                for i in range.clone() {
                    out[i] = (self.rhs[i] - sx[i]) / w;
                }
                let lambda_norm = block_norm(&out[range.clone()]);
                if lambda_norm > 1.0 {
                    for value in &mut out[range] {
                        *value /= lambda_norm;
                    }
                }
            }
        }
    }

    /// One-sided directional derivative J'(x; candidate − x).
    fn directional_derivative(&self, x: &[f64], sx: &[f64], candidate: &[f64]) -> f64 {
        let group = self.group;
        let mut slope = 0.0;
        let mut direction = [0.0; 2];
        for (a, &w) in self.weights.iter().enumerate() {
            let range = a * group..(a + 1) * group;
            let direction = &mut direction[..group];
            for (k, i) in range.clone().enumerate() {
                direction[k] = candidate[i] - x[i];
                slope += (sx[i] - self.rhs[i]) * direction[k];
            }
            if w > 0.0 {
                let block = &x[range];
                let norm = block_norm(block);
                if norm > 0.0 {
                    slope += w * dot(block, direction) / norm;
                } else {
                    slope += w * block_norm(direction);
                }
            }
        }
        slope
    }

    /// The semismooth Newton point (primal form, see the module docs) predicted at x.
    ///
    /// The reduced system A y = b, A = S_NN + D on the non-stick unknowns N, is solved with a
    /// dense Cholesky factorization of A, or, when the previous Newton system of the same solve
    /// had the same non-stick unknowns (`cache`), by conjugate gradients preconditioned with
    /// that system's factor: the two matrices then differ only in the slip curvatures D, so a
    /// few O(m²) iterations replace an O(n³) factorization (n = 2112 on the 3D block at 32³
    /// cells: one factorization ≈ 3.1 Gflop, 80 ms on one core). The iteration runs to a
    /// residual of [`NEWTON_PCG_TOLERANCE`] relative to the right-hand side; if it does not get
    /// there in [`NEWTON_PCG_ITERATIONS`], or the recomputed residual is above its rounding
    /// floor, the system is factorized.
    ///
    /// A is never assembled for the iteration: A v = (S ṽ)_N + D v with ṽ the extension of v by
    /// zeros, so a product reads S once (at 32³, S takes 36 MB: copying A cost as much as two
    /// iterations). The factorization is done in place in the cache's buffer, allocated once
    /// per solve. Nothing is kept from one solve to the next, so a step's result does not
    /// depend on the steps before it.
    fn newton_point(
        &self,
        x: &[f64],
        sx: &[f64],
        out: &mut [f64],
        cache: &mut NewtonCache,
    ) -> Result<()> {
        let group = self.group;
        let sigma = self.sigma;
        // Unknowns of the reduced system (components of the non-stick blocks), its right-hand
        // side, and the slip blocks with their position, direction n and curvature.
        let mut system = NewtonSystem {
            unknowns: Vec::with_capacity(x.len()),
            slip_curvature: Vec::new(),
        };
        let mut reduced_rhs = Vec::with_capacity(x.len());
        let mut shifted = [0.0; 2];
        for (a, &w) in self.weights.iter().enumerate() {
            let range = a * group..(a + 1) * group;
            if w == 0.0 {
                for i in range {
                    system.unknowns.push(i);
                    reduced_rhs.push(self.rhs[i]);
                }
                continue;
            }
            let shifted = &mut shifted[..group];
            for (k, i) in range.clone().enumerate() {
                shifted[k] = x[i] - sigma * (sx[i] - self.rhs[i]);
            }
            let norm = block_norm(shifted);
            if norm <= sigma * w {
                continue; // stick
            }
            let mut direction = [0.0; 2];
            for k in 0..group {
                direction[k] = shifted[k] / norm;
            }
            let position = system.unknowns.len();
            for (k, i) in range.enumerate() {
                system.unknowns.push(i);
                reduced_rhs.push(self.rhs[i] - w * direction[k]);
            }
            if group == 2 {
                system
                    .slip_curvature
                    .push((position, direction, w / (norm - sigma * w)));
            }
        }
        out.fill(0.0);
        let n = system.unknowns.len();
        if n == 0 {
            return Ok(());
        }
        let rhs_column = Col::from_fn(n, |i| reduced_rhs[i]);
        let apply = |v: &Col<f64>, product: &mut Col<f64>| self.apply_newton(&system, v, product);
        let preconditioned = match cache.factor_ref() {
            Some(factor) if cache.unknowns == system.unknowns => {
                let norm = self.newton_matrix_norm(&system);
                preconditioned_cg(apply, factor, norm, &rhs_column)
            }
            _ => None,
        };
        let solution = match preconditioned {
            Some(solution) => solution,
            None => {
                let factor = cache.factorize(self.matrix, &system)?;
                let mut solution = rhs_column.clone();
                cholesky_solve(factor, &mut solution);
                // One step of iterative refinement with the same factorization.
                let mut correction = Col::<f64>::zeros(n);
                apply(&solution, &mut correction);
                let mut correction = &rhs_column - &correction;
                cholesky_solve(factor, &mut correction);
                solution += &correction;
                solution
            }
        };
        for (k, &i) in system.unknowns.iter().enumerate() {
            out[i] = solution[k];
        }
        if out.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(Error::NonFinite(
                "friction Newton point (S is numerically singular)".into(),
            ))
        }
    }

    /// product = A v for the Newton system A = S_NN + D: (S ṽ)_N with ṽ = v on N, 0 elsewhere
    /// (adding the products of exact zeros changes no bit of a finite sum), plus the slip
    /// curvatures.
    fn apply_newton(&self, system: &NewtonSystem, v: &Col<f64>, product: &mut Col<f64>) {
        let m = self.dimension();
        let n = system.unknowns.len();
        let mut extended = vec![0.0; m];
        for (k, &i) in system.unknowns.iter().enumerate() {
            extended[i] = v[k];
        }
        let mut image = vec![0.0; m];
        self.apply(&extended, &mut image);
        for k in 0..n {
            product[k] = image[system.unknowns[k]];
        }
        for &(position, direction, curvature) in &system.slip_curvature {
            let along = direction[0] * v[position] + direction[1] * v[position + 1];
            for k in 0..2 {
                product[position + k] += curvature * (v[position + k] - direction[k] * along);
            }
        }
    }

    /// ‖A‖_∞ of the Newton system A = S_NN + D (largest row sum; S is symmetric, so the column
    /// sums of its contiguous columns are used).
    fn newton_matrix_norm(&self, system: &NewtonSystem) -> f64 {
        let mut sums: Vec<f64> = system
            .unknowns
            .iter()
            .map(|&j| {
                let column = self.matrix.col(j);
                system.unknowns.iter().map(|&i| column[i].abs()).sum()
            })
            .collect();
        // within a slip block the entries are S + D: replace |S| by |S + D| there
        for &(position, direction, curvature) in &system.slip_curvature {
            for k in 0..2 {
                for l in 0..2 {
                    let entry =
                        self.matrix[(system.unknowns[position + k], system.unknowns[position + l])];
                    let curved = entry + slip_entry(direction, curvature, k, l);
                    sums[position + k] += curved.abs() - entry.abs();
                }
            }
        }
        sums.into_iter().fold(0.0, f64::max)
    }

    /// Guaranteed bound min(Gershgorin, Frobenius) ≥ λ_max(S) and a power-iteration estimate.
    fn lipschitz(&self) -> Lipschitz {
        let m = self.dimension();
        let mut gershgorin = 0.0_f64;
        let mut frobenius = 0.0_f64;
        for j in 0..m {
            // Column sums equal row sums: S is symmetric.
            let column = self.matrix.col(j);
            let mut sum = 0.0;
            for i in 0..m {
                sum += column[i].abs();
                frobenius += column[i] * column[i];
            }
            gershgorin = gershgorin.max(sum);
        }
        let upper = gershgorin.min(frobenius.sqrt());
        let mut vector: Vec<f64> = (0..m).map(|i| (1.0 + 2.3 * i as f64).sin() + 0.5).collect();
        let mut image = vec![0.0; m];
        let mut estimate = 0.0_f64;
        for _ in 0..POWER_ITERATIONS {
            let norm = dot(&vector, &vector).sqrt();
            if norm == 0.0 {
                break;
            }
            vector.iter_mut().for_each(|v| *v /= norm);
            self.apply(&vector, &mut image);
            estimate = estimate.max(dot(&vector, &image));
            std::mem::swap(&mut vector, &mut image);
        }
        Lipschitz {
            value: (LIPSCHITZ_SAFETY * estimate).clamp(f64::MIN_POSITIVE, upper),
            upper,
        }
    }

    /// Up to `steps` monotone FISTA steps from (x, S x); returns the number of steps taken.
    /// On exit x, sx, energy and report describe the best (= last accepted) iterate.
    #[allow(clippy::too_many_arguments)]
    fn gradient_burst(
        &self,
        x: &mut [f64],
        sx: &mut [f64],
        energy: &mut Energy,
        report: &mut KktResidual,
        lipschitz: &mut Lipschitz,
        steps: usize,
        tolerance: f64,
    ) -> usize {
        let m = self.dimension();
        let group = self.group;
        let mut extrapolated_point = x.to_vec();
        let mut extrapolated_image = sx.to_vec();
        let mut previous = x.to_vec();
        let mut previous_image = sx.to_vec();
        let mut trial = vec![0.0; m];
        let mut trial_image = vec![0.0; m];
        let mut momentum = 1.0_f64;
        let mut extrapolating = false;
        let mut used = 0;
        while used < steps {
            used += 1;
            // Proximal-gradient step from the extrapolated point, with backtracking on L.
            let base = self.smooth_energy(&extrapolated_point, &extrapolated_image);
            let mut smooth;
            loop {
                let step = 1.0 / lipschitz.value;
                for i in 0..m {
                    trial[i] = extrapolated_point[i] - step * (extrapolated_image[i] - self.rhs[i]);
                }
                for (block, &w) in trial.chunks_exact_mut(group).zip(self.weights) {
                    shrink(block, step * w);
                }
                self.apply(&trial, &mut trial_image);
                smooth = self.smooth_energy(&trial, &trial_image);
                let mut model = base.value;
                let mut distance = 0.0;
                for i in 0..m {
                    let difference = trial[i] - extrapolated_point[i];
                    model += (extrapolated_image[i] - self.rhs[i]) * difference;
                    distance += difference * difference;
                }
                model += 0.5 * lipschitz.value * distance;
                let band = self.rounding_band(base.magnitude + smooth.magnitude);
                if smooth.value <= model + band || lipschitz.value >= lipschitz.upper {
                    break;
                }
                lipschitz.value = (2.0 * lipschitz.value).min(lipschitz.upper);
            }
            let friction = self.friction(&trial);
            let candidate = Energy {
                value: smooth.value + friction,
                magnitude: smooth.magnitude + friction,
            };
            let allowance = if extrapolating {
                0.0
            } else {
                self.rounding_band(energy.magnitude + candidate.magnitude)
            };
            if candidate.value.is_finite() && candidate.value <= energy.value + allowance {
                previous.copy_from_slice(x);
                previous_image.copy_from_slice(sx);
                x.copy_from_slice(&trial);
                sx.copy_from_slice(&trial_image);
                *energy = candidate;
                *report = self.kkt(x, sx);
                if report.max() <= tolerance {
                    break;
                }
                let next = 0.5 * (1.0 + (1.0 + 4.0 * momentum * momentum).sqrt());
                let beta = (momentum - 1.0) / next;
                momentum = next;
                for i in 0..m {
                    extrapolated_point[i] = x[i] + beta * (x[i] - previous[i]);
                    extrapolated_image[i] = sx[i] + beta * (sx[i] - previous_image[i]);
                }
                extrapolating = beta > 0.0;
            } else if extrapolating {
                // Adaptive restart: drop the momentum, step again from the best iterate.
                momentum = 1.0;
                extrapolating = false;
                extrapolated_point.copy_from_slice(x);
                extrapolated_image.copy_from_slice(sx);
            } else {
                // A plain step cannot decrease J beyond rounding: nothing more to gain here.
                break;
            }
        }
        used
    }

    fn solve(
        &self,
        x: &mut [f64],
        multipliers: &mut [f64],
        settings: &FrictionSettings,
    ) -> Result<FrictionStats> {
        let m = self.dimension();
        let tolerance = settings.tolerance;
        let mut sx = vec![0.0; m];
        self.apply(x, &mut sx);
        let mut energy = self.energy(x, &sx);
        let mut report = self.kkt(x, &sx);
        let mut history = vec![report.max()];
        let mut stats = FrictionStats::default();
        let mut lipschitz: Option<Lipschitz> = None;
        let mut burst = INITIAL_BURST;
        let mut candidate = vec![0.0; m];
        let mut candidate_image = vec![0.0; m];
        let mut trial = vec![0.0; m];
        let mut trial_image = vec![0.0; m];
        let mut best_residual = report.max();
        let mut best_energy = energy.value;
        let mut stalled_cycles = 0;
        let mut newton_cache = NewtonCache::default();
        while report.max() > tolerance {
            let exhausted = stats.newton_iterations >= settings.max_newton
                && stats.gradient_iterations >= settings.max_gradient;
            if exhausted || stalled_cycles >= STALL_LIMIT {
                return Err(Error::NoConvergence {
                    solver: if exhausted {
                        "friction semismooth Newton / FISTA"
                    } else {
                        "friction semismooth Newton / FISTA (stagnated at the rounding level)"
                    },
                    iterations: stats.newton_iterations + stats.gradient_iterations,
                    residual: report.max(),
                    tolerance,
                    history: History(history),
                });
            }
            let mut progress = false;
            if stats.newton_iterations < settings.max_newton {
                stats.newton_iterations += 1;
                self.newton_point(x, &sx, &mut candidate, &mut newton_cache)?;
                self.apply(&candidate, &mut candidate_image);
                let slope = self.directional_derivative(x, &sx, &candidate);
                // The full step first: by Armijo, or by the rounding clause (J flat to
                // rounding, but the residual at least halves: near the solution the decrease
                // of J falls below its rounding error).
                let full_energy = self.energy(&candidate, &candidate_image);
                let band = self.rounding_band(energy.magnitude + full_energy.magnitude);
                let full_step = (slope < 0.0 && full_energy.value <= energy.value + ARMIJO * slope)
                    || (full_energy.value <= energy.value + band
                        && self.kkt(&candidate, &candidate_image).max() <= 0.5 * report.max());
                let mut accepted = None;
                if full_step {
                    trial.copy_from_slice(&candidate);
                    trial_image.copy_from_slice(&candidate_image);
                    accepted = Some((1.0, full_energy));
                } else if slope < 0.0 {
                    // Damped steps count only with a decrease of J beyond its rounding band:
                    // an Armijo test whose slope is at the rounding level accepts noise, and a
                    // damped step in place of a full one that would have converged stalls
                    // Newton (it was the cause of most proximal-gradient bursts in 3D).
                    let mut step = 0.5;
                    while step >= MIN_STEP {
                        for i in 0..m {
                            trial[i] = x[i] + step * (candidate[i] - x[i]);
                            trial_image[i] = sx[i] + step * (candidate_image[i] - sx[i]);
                        }
                        let trial_energy = self.energy(&trial, &trial_image);
                        let band = self.rounding_band(energy.magnitude + trial_energy.magnitude);
                        if trial_energy.value <= energy.value + ARMIJO * step * slope
                            && trial_energy.value < energy.value - band
                        {
                            accepted = Some((step, trial_energy));
                            break;
                        }
                        step *= 0.5;
                    }
                }
                if let Some((step, trial_energy)) = accepted {
                    x.copy_from_slice(&trial);
                    sx.copy_from_slice(&trial_image);
                    energy = trial_energy;
                    let previous = report.max();
                    report = self.kkt(x, &sx);
                    progress = step == 1.0 && report.max() <= 0.5 * previous;
                }
                history.push(report.max());
            }
            if progress {
                burst = INITIAL_BURST;
            } else if report.max() > tolerance && stats.gradient_iterations < settings.max_gradient
            {
                let lipschitz = lipschitz.get_or_insert_with(|| self.lipschitz());
                let steps = burst.min(settings.max_gradient - stats.gradient_iterations);
                stats.gradient_iterations += self.gradient_burst(
                    x,
                    &mut sx,
                    &mut energy,
                    &mut report,
                    lipschitz,
                    steps,
                    tolerance,
                );
                history.push(report.max());
                burst = (2 * burst).min(MAX_BURST);
            }
            // Stagnation: neither J (beyond its rounding band) nor the residual improved.
            let band = self.rounding_band(energy.magnitude);
            if report.max() < (1.0 - 1e-3) * best_residual || energy.value < best_energy - band {
                stalled_cycles = 0;
            } else {
                stalled_cycles += 1;
            }
            best_residual = best_residual.min(report.max());
            best_energy = best_energy.min(energy.value);
        }
        self.multipliers(x, &sx, multipliers);
        for (block, &w) in x.chunks_exact(self.group).zip(self.weights) {
            if w == 0.0 {
                stats.free += 1;
            } else if block_norm(block) > 0.0 {
                stats.slip += 1;
            } else {
                stats.stick += 1;
            }
        }
        stats.kkt_residual = report.natural;
        stats.stationarity = report.stationarity;
        stats.dual_infeasibility = report.dual_infeasibility;
        Ok(stats)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::Side;
    use proptest::prelude::*;

    use crate::test_random::SeededRandom as Generator;

    /// Test data from [`Generator`].
    trait Vectors {
        fn vector(&mut self, len: usize, amplitude: f64) -> Vec<f64>;
    }

    impl Vectors for Generator {
        fn vector(&mut self, len: usize, amplitude: f64) -> Vec<f64> {
            (0..len)
                .map(|_| self.range(-amplitude, amplitude))
                .collect()
        }
    }

    /// S = BᵀB + αI with B a dense random m × m matrix (not diagonal), α ∈ [0.2, 1.2).
    fn random_spd(m: usize, generator: &mut Generator) -> Mat<f64> {
        let shift = generator.range(0.2, 1.2);
        random_spd_with_shift(m, shift, generator)
    }

    /// S = BᵀB + shift · I with B a dense random m × m matrix, entries of size 1/√m.
    fn random_spd_with_shift(m: usize, shift: f64, generator: &mut Generator) -> Mat<f64> {
        let scaling = 1.0 / (m as f64).sqrt();
        let factor = Mat::from_fn(m, m, |_, _| generator.range(-1.0, 1.0) * scaling);
        let mut matrix = factor.transpose() * &factor;
        for i in 0..m {
            matrix[(i, i)] += shift;
        }
        matrix
    }

    #[derive(Clone, Copy, PartialEq, Debug)]
    enum Kind {
        Stick,
        Slip,
        Free,
    }

    /// A problem with known solution: pick x*, λ* consistent with the kinds, set r = S x* + W λ*.
    struct Manufactured {
        matrix: Mat<f64>,
        rhs: Vec<f64>,
        weights: Vec<f64>,
        solution: Vec<f64>,
        group: usize,
    }

    impl Manufactured {
        fn new(
            kinds: &[Kind],
            group: usize,
            weight_range: (f64, f64),
            generator: &mut Generator,
        ) -> Self {
            let m = kinds.len() * group;
            let matrix = random_spd(m, generator);
            let mut solution = vec![0.0; m];
            let mut multiplier = vec![0.0; m];
            let mut weights = vec![0.0; kinds.len()];
            for (a, kind) in kinds.iter().enumerate() {
                let range = a * group..(a + 1) * group;
                match kind {
                    Kind::Free => {
                        solution[range].copy_from_slice(&generator.vector(group, 2.0));
                    }
                    Kind::Slip => {
                        weights[a] = generator.range(weight_range.0, weight_range.1);
                        let block = loop {
                            let candidate = generator.vector(group, 2.0);
                            if block_norm(&candidate) > 0.5 {
                                break candidate;
                            }
                        };
                        let norm = block_norm(&block);
                        for (k, i) in range.enumerate() {
                            solution[i] = block[k];
                            multiplier[i] = block[k] / norm;
                        }
                    }
                    Kind::Stick => {
                        weights[a] = generator.range(weight_range.0, weight_range.1);
                        let block = generator.vector(group, 1.0);
                        let norm = block_norm(&block).max(1e-300);
                        let radius = generator.range(0.0, 0.9);
                        for (k, i) in range.enumerate() {
                            multiplier[i] = block[k] * radius.min(norm) / norm;
                        }
                    }
                }
            }
            let mut rhs = vec![0.0; m];
            for i in 0..m {
                let mut sum = 0.0;
                for j in 0..m {
                    sum += matrix[(i, j)] * solution[j];
                }
                rhs[i] = sum + weights[i / group] * multiplier[i];
            }
            Self {
                matrix,
                rhs,
                weights,
                solution,
                group,
            }
        }

        fn problem(&self) -> CondensedFriction<'_> {
            CondensedFriction {
                matrix: self.matrix.as_ref(),
                rhs: &self.rhs,
                weights: &self.weights,
                group_size: self.group,
            }
        }

        fn count(kinds: &[Kind], kind: Kind) -> usize {
            kinds.iter().filter(|&&k| k == kind).count()
        }

        /// Solves from `start` and checks KKT, the known solution and the group counts.
        fn check(&self, kinds: &[Kind], start: Vec<f64>) -> FrictionStats {
            let problem = self.problem();
            let mut x = start;
            let mut multipliers = vec![0.0; x.len()];
            let stats = problem
                .solve(&mut x, &mut multipliers, &FrictionSettings::default())
                .unwrap();
            assert_kkt(&problem, &x, &multipliers);
            let size = 1.0 + max_abs(&self.solution);
            for (computed, exact) in x.iter().zip(&self.solution) {
                assert!(
                    (computed - exact).abs() <= 1e-9 * size,
                    "solution {computed} differs from the manufactured {exact}"
                );
            }
            for (a, kind) in kinds.iter().enumerate() {
                if *kind == Kind::Stick {
                    assert!(x[a * self.group..(a + 1) * self.group]
                        .iter()
                        .all(|&v| v == 0.0));
                }
            }
            assert_eq!(stats.stick, Self::count(kinds, Kind::Stick));
            assert_eq!(stats.slip, Self::count(kinds, Kind::Slip));
            assert_eq!(stats.free, Self::count(kinds, Kind::Free));
            stats
        }
    }

    /// Independent check of the KKT system S x − r + W λ = 0, |λ_a| ≤ 1, λ_a = x_a/|x_a| on slip,
    /// computed with plain loops (not with the solver's helpers).
    fn assert_kkt(problem: &CondensedFriction<'_>, x: &[f64], multipliers: &[f64]) {
        let m = x.len();
        let group = problem.group_size;
        let scale = problem.rhs.iter().fold(0.0_f64, |acc, v| acc.max(v.abs()));
        for (i, multiplier) in multipliers.iter().enumerate() {
            let product: f64 = (0..m).map(|j| problem.matrix[(i, j)] * x[j]).sum();
            let stationarity = product - problem.rhs[i] + problem.weights[i / group] * multiplier;
            assert!(
                stationarity.abs() <= 1e-10 * scale,
                "stationarity residual {stationarity:e} at component {i} (scale {scale:e})"
            );
        }
        for (a, &w) in problem.weights.iter().enumerate() {
            let block = &x[a * group..(a + 1) * group];
            let lambda = &multipliers[a * group..(a + 1) * group];
            let lambda_norm = lambda.iter().map(|v| v * v).sum::<f64>().sqrt();
            assert!(lambda_norm <= 1.0 + 1e-12, "|λ_{a}| = {lambda_norm}");
            let norm = block.iter().map(|v| v * v).sum::<f64>().sqrt();
            if w > 0.0 && norm > 0.0 {
                for k in 0..group {
                    assert!(
                        (lambda[k] - block[k] / norm).abs() <= 1e-10,
                        "slip block {a}: λ = {lambda:?} is not x/|x| for x = {block:?}"
                    );
                }
            }
        }
    }

    fn random_kinds(groups: usize, generator: &mut Generator) -> Vec<Kind> {
        let mut kinds: Vec<Kind> = (0..groups)
            .map(|_| match generator.unit() {
                u if u < 0.4 => Kind::Stick,
                u if u < 0.9 => Kind::Slip,
                _ => Kind::Free,
            })
            .collect();
        kinds[0] = Kind::Stick;
        if groups > 1 {
            kinds[1] = Kind::Slip;
        }
        kinds
    }

    /// Random data over wide ranges: condition number of S up to ~10⁴, loads of size 10^±3,
    /// weights log-uniform over three decades (20 % free), starts of size up to 10⁶ · load.
    fn solve_random(group: usize, groups: usize, seed: u64) {
        let mut generator = Generator::new(seed);
        let m = group * groups;
        let shift = 10f64.powf(generator.range(-4.0, 0.0));
        let matrix = random_spd_with_shift(m, shift, &mut generator);
        let amplitude = 10f64.powf(generator.range(-3.0, 3.0));
        let rhs = generator.vector(m, amplitude);
        let weights: Vec<f64> = (0..groups)
            .map(|_| {
                if generator.unit() < 0.2 {
                    0.0
                } else {
                    amplitude * 10f64.powf(generator.range(-2.0, 1.0))
                }
            })
            .collect();
        let problem = CondensedFriction {
            matrix: matrix.as_ref(),
            rhs: &rhs,
            weights: &weights,
            group_size: group,
        };
        let start_amplitude = amplitude * 10f64.powf(generator.range(-2.0, 6.0));
        let mut x = generator.vector(m, start_amplitude);
        let mut multipliers = vec![0.0; m];
        let stats = problem
            .solve(&mut x, &mut multipliers, &FrictionSettings::default())
            .unwrap();
        assert_kkt(&problem, &x, &multipliers);
        assert!(stats.kkt_residual <= 1e-12);
        assert!(problem.kkt_report(&x).max() <= 1e-12);
        assert_eq!(stats.stick + stats.slip + stats.free, groups);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        #[test]
        fn friction_solver_satisfies_kkt_in_2d(groups in 1usize..=40, seed in any::<u64>()) {
            solve_random(1, groups, seed);
        }

        #[test]
        fn friction_solver_satisfies_kkt_in_3d(groups in 1usize..=40, seed in any::<u64>()) {
            solve_random(2, groups, seed);
        }

        #[test]
        fn mixed_stick_slip_free_solution_is_recovered(
            group in 1usize..=2, groups in 2usize..=40, seed in any::<u64>()
        ) {
            let mut generator = Generator::new(seed);
            let kinds = random_kinds(groups, &mut generator);
            let problem = Manufactured::new(&kinds, group, (0.5, 2.0), &mut generator);
            let stats = problem.check(&kinds, vec![0.0; group * groups]);
            prop_assert!(stats.stick > 0 && stats.slip > 0);
        }

        #[test]
        fn start_far_away_still_converges(
            group in 1usize..=2, groups in 2usize..=40, seed in any::<u64>()
        ) {
            let mut generator = Generator::new(seed);
            let kinds = random_kinds(groups, &mut generator);
            let problem = Manufactured::new(&kinds, group, (0.5, 2.0), &mut generator);
            let start = generator.vector(group * groups, 1e6);
            problem.check(&kinds, start);
        }

        #[test]
        fn all_slip_with_small_weights(
            group in 1usize..=2, groups in 1usize..=40, seed in any::<u64>()
        ) {
            let mut generator = Generator::new(seed);
            let kinds = vec![Kind::Slip; groups];
            let problem = Manufactured::new(&kinds, group, (1e-3, 1e-1), &mut generator);
            let stats = problem.check(&kinds, generator.vector(group * groups, 1.0));
            prop_assert_eq!(stats.slip, groups);
        }

        #[test]
        fn all_stick_when_weights_exceed_the_load(
            group in 1usize..=2, groups in 1usize..=40, seed in any::<u64>()
        ) {
            let mut generator = Generator::new(seed);
            let m = group * groups;
            let matrix = random_spd(m, &mut generator);
            let rhs = generator.vector(m, 5.0);
            // |r_a| < w_a: x = 0 with λ_a = r_a / w_a satisfies the KKT system.
            let weights: Vec<f64> = rhs
                .chunks_exact(group)
                .map(|block| block_norm(block) * generator.range(1.01, 3.0) + 0.01)
                .collect();
            let problem = CondensedFriction {
                matrix: matrix.as_ref(),
                rhs: &rhs,
                weights: &weights,
                group_size: group,
            };
            let mut x = generator.vector(m, 3.0);
            let mut multipliers = vec![0.0; m];
            let stats = problem
                .solve(&mut x, &mut multipliers, &FrictionSettings::default())
                .unwrap();
            prop_assert!(x.iter().all(|&v| v == 0.0));
            prop_assert_eq!(stats.stick, groups);
            assert_kkt(&problem, &x, &multipliers);
        }

        #[test]
        fn no_contact_is_the_linear_solve(
            group in 1usize..=2, groups in 1usize..=40, seed in any::<u64>()
        ) {
            let mut generator = Generator::new(seed);
            let m = group * groups;
            let matrix = random_spd(m, &mut generator);
            let rhs = generator.vector(m, 5.0);
            let weights = vec![0.0; groups];
            let problem = CondensedFriction {
                matrix: matrix.as_ref(),
                rhs: &rhs,
                weights: &weights,
                group_size: group,
            };
            let mut x = generator.vector(m, 3.0);
            let mut multipliers = vec![1.0; m];
            let stats = problem
                .solve(&mut x, &mut multipliers, &FrictionSettings::default())
                .unwrap();
            prop_assert_eq!(stats.free, groups);
            prop_assert!(multipliers.iter().all(|&v| v == 0.0));
            // Independent reference: LU with partial pivoting of the full matrix.
            let reference = matrix.partial_piv_lu().solve(Col::from_fn(m, |i| rhs[i]));
            for i in 0..m {
                prop_assert!((x[i] - reference[i]).abs() <= 1e-10 * (1.0 + reference[i].abs()));
            }
        }

        #[test]
        fn single_group_with_scalar_matrix_is_shrinkage(
            group in 1usize..=2,
            stiffness in 1e-3f64..1e3,
            weight in 0.0f64..10.0,
            load in prop::collection::vec(-10.0f64..10.0, 2),
        ) {
            // S = s I_G: x = max(0, 1 − w/|r|) r / s.
            let matrix = Mat::from_fn(group, group, |i, j| if i == j { stiffness } else { 0.0 });
            let rhs = &load[..group];
            let weights = [weight];
            let problem = CondensedFriction {
                matrix: matrix.as_ref(),
                rhs,
                weights: &weights,
                group_size: group,
            };
            let mut x = vec![1.0; group];
            let mut multipliers = vec![0.0; group];
            problem
                .solve(&mut x, &mut multipliers, &FrictionSettings::default())
                .unwrap();
            let norm = block_norm(rhs);
            let factor = if norm > weight { 1.0 - weight / norm } else { 0.0 };
            for k in 0..group {
                let exact = factor * rhs[k] / stiffness;
                prop_assert!((x[k] - exact).abs() <= 1e-12 * (norm / stiffness));
            }
        }
    }

    /// A Newton step whose full length converges is taken at full length: near the solution
    /// the Armijo test of a damped step compares values of J that differ by rounding only,
    /// and accepting such a damped step in place of the full one stalled Newton into a burst
    /// of proximal-gradient steps (about half of the solves below did so before the full step
    /// was tried first).
    #[test]
    fn newton_converges_without_gradient_steps_from_near_the_solution() {
        let mut bursts = Vec::new();
        for seed in 0..24 {
            let mut generator = Generator::new(100 + seed);
            let kinds: Vec<Kind> = (0..30)
                .map(|a| if a % 5 == 0 { Kind::Free } else { Kind::Slip })
                .collect();
            let manufactured = Manufactured::new(&kinds, 2, (0.5, 2.0), &mut generator);
            let start: Vec<f64> = manufactured
                .solution
                .iter()
                .map(|v| v + generator.range(-1e-3, 1e-3))
                .collect();
            let stats = manufactured.check(&kinds, start);
            if stats.gradient_iterations > 0 {
                bursts.push((seed, stats.newton_iterations, stats.gradient_iterations));
            }
        }
        assert!(
            bursts.is_empty(),
            "(seed, Newton, gradient steps): {bursts:?}"
        );
    }

    /// The Newton system as an operator, (S ṽ)_N + D v, and its factor in the cache's buffer
    /// agree with the assembled matrix A = S_NN + D (stick blocks removed, slip curvatures on
    /// their 2 × 2 blocks).
    #[test]
    fn newton_operator_and_factor_match_the_assembled_system() {
        let mut generator = Generator::new(5);
        let m = 24;
        let matrix = random_spd(m, &mut generator);
        let rhs = generator.vector(m, 1.0);
        let weights = vec![1.0; m / 2];
        let problem = Problem::new(matrix.as_ref(), &rhs, &weights, 2);
        // blocks 0..12: 2 and 7 stick; the others slip with a curvature
        let unknowns: Vec<usize> = (0..m).filter(|i| ![2, 7].contains(&(i / 2))).collect();
        let n = unknowns.len();
        let slip_curvature: Vec<(usize, [f64; 2], f64)> = (0..n / 2)
            .map(|b| {
                let angle = generator.range(0.0, 6.3);
                (2 * b, [angle.cos(), angle.sin()], generator.range(0.1, 3.0))
            })
            .collect();
        let system = NewtonSystem {
            unknowns: unknowns.clone(),
            slip_curvature: slip_curvature.clone(),
        };
        let mut assembled = Mat::from_fn(n, n, |i, j| matrix[(unknowns[i], unknowns[j])]);
        for &(position, direction, curvature) in &slip_curvature {
            for k in 0..2 {
                for l in 0..2 {
                    let identity = if k == l { 1.0 } else { 0.0 };
                    assembled[(position + k, position + l)] +=
                        curvature * (identity - direction[k] * direction[l]);
                }
            }
        }
        let v = Col::from_fn(n, |_| generator.range(-1.0, 1.0));
        let mut product = Col::zeros(n);
        problem.apply_newton(&system, &v, &mut product);
        let expected = &assembled * &v;
        let row_norm = (0..n)
            .map(|i| (0..n).map(|j| assembled[(i, j)].abs()).sum::<f64>())
            .fold(0.0, f64::max);
        for i in 0..n {
            assert!((product[i] - expected[i]).abs() <= 1e-14 * row_norm);
        }
        assert!((problem.newton_matrix_norm(&system) - row_norm).abs() <= 1e-14 * row_norm);
        let mut cache = NewtonCache::default();
        let factor = cache.factorize(matrix.as_ref(), &system).unwrap();
        let lower = Mat::from_fn(n, n, |i, j| if i >= j { factor[(i, j)] } else { 0.0 });
        let reconstructed = &lower * lower.transpose();
        for i in 0..n {
            for j in 0..n {
                assert!((reconstructed[(i, j)] - assembled[(i, j)]).abs() <= 1e-13 * row_norm);
            }
        }
        let mut solution = expected.clone();
        cholesky_solve(cache.factor_ref().unwrap(), &mut solution);
        for i in 0..n {
            assert!((solution[i] - v[i]).abs() <= 1e-11);
        }
    }

    #[test]
    fn newton_system_is_solved_with_the_factor_of_a_nearby_one() {
        let mut generator = Generator::new(11);
        let n = 40;
        let matrix = random_spd(n, &mut generator);
        // the previous Newton system: other slip curvatures on a few diagonal 2 × 2 blocks
        let mut nearby = matrix.clone();
        for block in [3, 7, 12] {
            for k in 0..2 {
                nearby[(2 * block + k, 2 * block + k)] += generator.range(0.0, 0.5);
            }
        }
        let factor = nearby.llt(Side::Lower).unwrap();
        let rhs = Col::from_fn(n, |_| generator.range(-1.0, 1.0));
        let norm_of_matrix = (0..n)
            .map(|i| (0..n).map(|j| matrix[(i, j)].abs()).sum::<f64>())
            .fold(0.0, f64::max);
        let apply = |v: &Col<f64>, out: &mut Col<f64>| out.copy_from(&matrix * v);
        let solution = preconditioned_cg(apply, factor.L(), norm_of_matrix, &rhs)
            .expect("a nearby factor preconditions to convergence");
        let exact = matrix.llt(Side::Lower).unwrap().solve(&rhs);
        let residual = &rhs - &matrix * &solution;
        let norm = |v: &Col<f64>| v.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        assert!(norm(&residual) <= 1e-13 * norm(&rhs), "{}", norm(&residual));
        assert!(norm(&(&solution - &exact)) <= 1e-12 * norm(&exact));
    }

    #[test]
    fn newton_system_is_factorized_when_the_preconditioner_is_far_off() {
        // eigenvalues from 1 to 1e8, preconditioned with the identity: CG needs far more than
        // NEWTON_PCG_ITERATIONS iterations, so the caller factorizes instead
        let n = 60;
        let matrix = Mat::from_fn(n, n, |i, j| {
            if i == j {
                10f64.powf(8.0 * i as f64 / (n - 1) as f64)
            } else {
                0.0
            }
        });
        let identity = Mat::<f64>::identity(n, n);
        let rhs = Col::from_fn(n, |i| 1.0 + i as f64);
        let apply = |v: &Col<f64>, out: &mut Col<f64>| out.copy_from(&matrix * v);
        assert!(preconditioned_cg(apply, identity.as_ref(), 1e8, &rhs).is_none());
    }

    #[test]
    fn proximal_gradient_alone_converges_exactly() {
        let mut generator = Generator::new(7);
        let kinds = random_kinds(20, &mut generator);
        let manufactured = Manufactured::new(&kinds, 2, (0.5, 2.0), &mut generator);
        let problem = manufactured.problem();
        let mut x = vec![0.0; 40];
        let mut multipliers = vec![0.0; 40];
        let settings = FrictionSettings {
            max_newton: 0,
            ..FrictionSettings::default()
        };
        let stats = problem.solve(&mut x, &mut multipliers, &settings).unwrap();
        assert_eq!(stats.newton_iterations, 0);
        assert!(stats.gradient_iterations > 0);
        assert_kkt(&problem, &x, &multipliers);
    }

    #[test]
    fn exhausted_budget_reports_no_convergence() {
        let mut generator = Generator::new(11);
        let kinds = random_kinds(10, &mut generator);
        let manufactured = Manufactured::new(&kinds, 1, (0.5, 2.0), &mut generator);
        let mut x = vec![0.0; 10];
        let mut multipliers = vec![0.0; 10];
        let settings = FrictionSettings {
            max_newton: 0,
            max_gradient: 2,
            ..FrictionSettings::default()
        };
        match manufactured
            .problem()
            .solve(&mut x, &mut multipliers, &settings)
        {
            Err(Error::NoConvergence { history, .. }) => assert!(!history.0.is_empty()),
            other => panic!("expected NoConvergence, got {other:?}"),
        }
    }

    #[test]
    fn solution_as_start_needs_no_iteration() {
        let mut generator = Generator::new(3);
        let kinds = random_kinds(15, &mut generator);
        let manufactured = Manufactured::new(&kinds, 1, (0.5, 2.0), &mut generator);
        let first = manufactured.check(&kinds, vec![0.0; 15]);
        assert!(first.newton_iterations > 0);
        let problem = manufactured.problem();
        let mut x = vec![0.0; 15];
        let mut multipliers = vec![0.0; 15];
        problem
            .solve(&mut x, &mut multipliers, &FrictionSettings::default())
            .unwrap();
        let again = problem
            .solve(&mut x, &mut multipliers, &FrictionSettings::default())
            .unwrap();
        assert_eq!(again.newton_iterations + again.gradient_iterations, 0);
    }

    #[test]
    fn zero_load_gives_zero_velocity() {
        let mut generator = Generator::new(5);
        let matrix = random_spd(6, &mut generator);
        let rhs = vec![0.0; 6];
        let weights = [1.0, 0.0, 2.0];
        let problem = CondensedFriction {
            matrix: matrix.as_ref(),
            rhs: &rhs,
            weights: &weights,
            group_size: 2,
        };
        let mut x = generator.vector(6, 1.0);
        let mut multipliers = vec![0.0; 6];
        problem
            .solve(&mut x, &mut multipliers, &FrictionSettings::default())
            .unwrap();
        assert!(x.iter().all(|&v| v == 0.0), "{x:?}");
    }

    #[test]
    fn empty_problem_is_solved_trivially() {
        let matrix = Mat::<f64>::zeros(0, 0);
        let problem = CondensedFriction {
            matrix: matrix.as_ref(),
            rhs: &[],
            weights: &[],
            group_size: 2,
        };
        let stats = problem
            .solve(&mut [], &mut [], &FrictionSettings::default())
            .unwrap();
        assert_eq!(stats.newton_iterations + stats.stick + stats.slip, 0);
    }

    #[test]
    fn slightly_asymmetric_matrix_is_used_through_its_symmetric_part() {
        let mut generator = Generator::new(9);
        let kinds = random_kinds(12, &mut generator);
        let mut manufactured = Manufactured::new(&kinds, 2, (0.5, 2.0), &mut generator);
        // Perturb antisymmetrically: the symmetric part (and so the solution) is unchanged.
        manufactured.matrix[(3, 1)] += 1e-13;
        manufactured.matrix[(1, 3)] -= 1e-13;
        manufactured.check(&kinds, vec![0.0; 24]);
    }

    #[test]
    fn objective_and_residual_vanish_where_expected() {
        let mut generator = Generator::new(13);
        let kinds = random_kinds(8, &mut generator);
        let manufactured = Manufactured::new(&kinds, 2, (0.5, 2.0), &mut generator);
        let problem = manufactured.problem();
        let at_solution = problem.kkt_residual(&manufactured.solution);
        assert!((0.0..=1e-13).contains(&at_solution), "{at_solution:e}");
        let report = problem.kkt_report(&[0.0; 16]);
        assert!(report.natural > 1e-3);
        assert_eq!(problem.kkt_residual(&[0.0; 16]), report.natural);
        // J at the solution is below J at nearby points (strict convexity).
        let best = problem.objective(&manufactured.solution);
        for _ in 0..10 {
            let nearby: Vec<f64> = manufactured
                .solution
                .iter()
                .map(|v| v + generator.range(-1e-3, 1e-3))
                .collect();
            assert!(problem.objective(&nearby) > best);
        }
    }

    fn small_problem_error(
        matrix: &Mat<f64>,
        rhs: &[f64],
        weights: &[f64],
        group_size: usize,
        start_len: usize,
    ) -> Error {
        let problem = CondensedFriction {
            matrix: matrix.as_ref(),
            rhs,
            weights,
            group_size,
        };
        let mut x = vec![0.0; start_len];
        let mut multipliers = vec![0.0; start_len];
        problem
            .solve(&mut x, &mut multipliers, &FrictionSettings::default())
            .unwrap_err()
    }

    fn identity(m: usize) -> Mat<f64> {
        Mat::from_fn(m, m, |i, j| if i == j { 1.0 } else { 0.0 })
    }

    #[test]
    fn friction_rejects_negative_weight() {
        let error = small_problem_error(&identity(3), &[1.0; 3], &[1.0, 0.5, -0.1], 1, 3);
        match error {
            Error::InvalidParameter { name, value, .. } => {
                assert_eq!(name, "weights[2]");
                assert_eq!(value, -0.1);
            }
            other => panic!("expected InvalidParameter, got {other}"),
        }
    }

    #[test]
    fn friction_rejects_size_mismatch() {
        // Matrix 3×3 for 2 groups of size 2.
        let error = small_problem_error(&identity(3), &[1.0; 4], &[1.0; 2], 2, 4);
        assert!(matches!(error, Error::InvalidInput(ref message) if message.contains("3×3")));
        // Right-hand side of the wrong length.
        let error = small_problem_error(&identity(4), &[1.0; 3], &[1.0; 2], 2, 4);
        assert!(matches!(error, Error::InvalidInput(ref message) if message.contains("length 3")));
        // Start vector of the wrong length.
        let error = small_problem_error(&identity(4), &[1.0; 4], &[1.0; 2], 2, 5);
        assert!(matches!(error, Error::InvalidInput(ref message) if message.contains("start")));
        // Unsupported group size.
        let error = small_problem_error(&identity(3), &[1.0; 3], &[1.0; 1], 3, 3);
        assert!(matches!(error, Error::InvalidParameter { ref name, .. } if name == "group_size"));
    }

    #[test]
    fn friction_rejects_non_finite_data() {
        let error = small_problem_error(&identity(2), &[1.0, f64::NAN], &[1.0; 2], 1, 2);
        assert!(matches!(error, Error::NonFinite(ref message) if message.contains("rhs[1]")));
        let mut matrix = identity(2);
        matrix[(1, 0)] = f64::INFINITY;
        let error = small_problem_error(&matrix, &[1.0; 2], &[1.0; 2], 1, 2);
        assert!(matches!(error, Error::NonFinite(ref message) if message.contains("(1, 0)")));
        let error = small_problem_error(&identity(2), &[1.0; 2], &[f64::NAN, 1.0], 1, 2);
        assert!(matches!(error, Error::InvalidParameter { ref name, .. } if name == "weights[0]"));
        let matrix = identity(2);
        let problem = CondensedFriction {
            matrix: matrix.as_ref(),
            rhs: &[1.0; 2],
            weights: &[1.0; 2],
            group_size: 1,
        };
        let error = problem
            .solve(
                &mut [0.0, f64::INFINITY],
                &mut [0.0; 2],
                &FrictionSettings::default(),
            )
            .unwrap_err();
        assert!(matches!(error, Error::NonFinite(ref message) if message.contains("x[1]")));
    }

    #[test]
    fn friction_rejects_matrices_that_are_not_spd() {
        let mut asymmetric = identity(3);
        asymmetric[(2, 0)] = 0.5;
        let error = small_problem_error(&asymmetric, &[1.0; 3], &[1.0; 3], 1, 3);
        assert!(matches!(error, Error::InvalidInput(ref message) if message.contains("symmetric")));
        let mut zero_diagonal = identity(3);
        zero_diagonal[(1, 1)] = 0.0;
        let error = small_problem_error(&zero_diagonal, &[1.0; 3], &[1.0; 3], 1, 3);
        assert!(matches!(error, Error::InvalidInput(ref message) if message.contains("(1, 1)")));
        // Symmetric, positive diagonal, indefinite: the Newton factorization reports it.
        let indefinite = Mat::from_fn(2, 2, |i, j| if i == j { 1.0 } else { 2.0 });
        let error = small_problem_error(&indefinite, &[1.0; 2], &[0.0; 2], 1, 2);
        assert!(matches!(error, Error::LinearAlgebra { .. }), "{error}");
    }

    #[test]
    #[should_panic(expected = "weights[0]")]
    fn objective_of_an_invalid_problem_panics_with_the_reason() {
        let matrix = identity(1);
        let problem = CondensedFriction {
            matrix: matrix.as_ref(),
            rhs: &[1.0],
            weights: &[-1.0],
            group_size: 1,
        };
        problem.objective(&[0.0]);
    }

    #[test]
    fn friction_rejects_bad_tolerance() {
        let matrix = identity(2);
        let problem = CondensedFriction {
            matrix: matrix.as_ref(),
            rhs: &[1.0; 2],
            weights: &[1.0; 2],
            group_size: 1,
        };
        let settings = FrictionSettings {
            tolerance: 0.0,
            ..FrictionSettings::default()
        };
        let error = problem
            .solve(&mut [0.0; 2], &mut [0.0; 2], &settings)
            .unwrap_err();
        assert!(matches!(error, Error::InvalidParameter { ref name, .. } if name == "tolerance"));
    }
}
