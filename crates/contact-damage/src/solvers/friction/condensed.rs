//! The condensed Tresca-friction problem of (5.1), min ½ xᵀ S x − rᵀ x + Σ_a w_a |x_a|, as
//! given by its caller: validation of its data and the entry points of the solver.

use super::objective::Problem;
use super::settings::{FrictionSettings, FrictionStats, KktResidual};
use crate::error::{Error, Result};
use faer::prelude::*;

/// Relative asymmetry |S_ij − S_ji| / sqrt(S_ii S_jj) tolerated by [`CondensedFriction::validate`].
pub const SYMMETRY_TOLERANCE: f64 = 1e-10;

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
