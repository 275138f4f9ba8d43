//! The reduced Newton system A = S_NN + D of the semismooth Newton method for the friction
//! problem of (5.1): its data, its dense Cholesky factor (kept within one solve), and conjugate
//! gradients (the crate's [`pcg`]) preconditioned with the factor of a nearby system.

use crate::algebra::linalg::max_abs;
use crate::algebra::pcg::{pcg, BetaRule, PcgSettings, PcgStop, PcgSystem, PcgVectors};
use crate::error::{Error, Result};
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch};
use faer::linalg::cholesky::llt::solve::solve_in_place_with_conj;
use faer::prelude::*;
use faer::Conj;

/// Relative residual ‖b − A y‖_∞ / ‖b‖_∞ of the recursion at which the preconditioned
/// conjugate gradients of a Newton system stop ([`Problem::newton_point`]).
///
/// [`Problem::newton_point`]: super::objective::Problem::newton_point
pub(super) const NEWTON_PCG_TOLERANCE: f64 = 1e-14;
/// An accepted solution has a recomputed residual ‖b − A y‖_∞ of at most
/// [`NEWTON_PCG_TOLERANCE`] ‖b‖_∞ plus this many ulps of ‖A‖_∞ ‖y‖_∞, the rounding floor of
/// evaluating b − A y (the accuracy of a backward-stable factorization; nothing looser).
pub(super) const NEWTON_PCG_ROUNDING_ULPS: f64 = 16.0;
/// Iterations (products with the Newton matrix after the start) after which the preconditioned
/// conjugate gradients give up and the Newton system is factorized afresh.
pub(super) const NEWTON_PCG_ITERATIONS: usize = 24;

/// The non-stick unknowns N of a Newton system and its slip curvatures D (3D): blocks at
/// `position` in N with direction n and curvature c, D = c (I − n nᵀ).
pub(super) struct NewtonSystem {
    pub(super) unknowns: Vec<usize>,
    pub(super) slip_curvature: Vec<(usize, [f64; 2], f64)>,
}

/// Entry (k, l) of the slip curvature block c (I − n nᵀ).
pub(super) fn slip_entry(direction: [f64; 2], curvature: f64, k: usize, l: usize) -> f64 {
    let identity = if k == l { 1.0 } else { 0.0 };
    curvature * (identity - direction[k] * direction[l])
}

/// The factor of the last Newton system factorized in one solve, its non-stick unknowns, and
/// the buffer it lives in (m × m, allocated at the first factorization of the solve).
#[derive(Default)]
pub(super) struct NewtonCache {
    pub(super) unknowns: Vec<usize>,
    buffer: Option<Mat<f64>>,
    /// The leading n × n block of `buffer` holds the Cholesky factor L (lower triangle).
    factor: Option<usize>,
}

impl NewtonCache {
    /// Cholesky factor L of A = S_NN + D, in place in the buffer.
    pub(super) fn factorize(
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
    pub(super) fn factor_ref(&self) -> Option<MatRef<'_, f64>> {
        let n = self.factor?;
        Some(self.buffer.as_ref()?.as_ref().submatrix(0, 0, n, n))
    }
}

/// v ← (L Lᵀ)⁻¹ v with the lower triangle of `factor`.
pub(super) fn cholesky_solve(factor: MatRef<'_, f64>, v: &mut [f64]) {
    solve_in_place_with_conj(
        factor,
        Conj::No,
        ColMut::from_slice_mut(v).as_mat_mut(),
        Par::Seq,
        MemStack::new(&mut MemBuffer::new(StackReq::EMPTY)),
    );
}

/// y with A y = b by conjugate gradients preconditioned with the Cholesky factor L of a nearby
/// SPD matrix, from y = (L Lᵀ)⁻¹ b, until the recursive residual is ≤ [`NEWTON_PCG_TOLERANCE`]
/// ‖b‖_∞; None unless that happens within [`NEWTON_PCG_ITERATIONS`] iterations and the recomputed
/// residual is then within [`NEWTON_PCG_TOLERANCE`] ‖b‖_∞ + [`NEWTON_PCG_ROUNDING_ULPS`] ε
/// ‖A‖_∞ ‖y‖_∞. `apply(v, out)` sets out = A v; `matrix_norm` is ‖A‖_∞.
pub(super) fn preconditioned_cg(
    apply: impl FnMut(&[f64], &mut [f64]),
    factor: MatRef<'_, f64>,
    matrix_norm: f64,
    rhs: &[f64],
) -> Option<Vec<f64>> {
    let target = NEWTON_PCG_TOLERANCE * max_abs(rhs);
    let mut system = FactorPreconditioned { apply, factor };
    let mut solution = rhs.to_vec();
    cholesky_solve(factor, &mut solution);
    let mut vectors = PcgVectors::new(rhs.len());
    (system.apply)(&solution, &mut vectors.image);
    for ((residual, b), product) in vectors.residual.iter_mut().zip(rhs).zip(&vectors.image) {
        *residual = b - product;
    }
    let settings = PcgSettings {
        target,
        max_iterations: NEWTON_PCG_ITERATIONS,
        beta: BetaRule::FletcherReeves,
    };
    let Ok(outcome) = pcg(&mut system, &mut solution, &mut vectors, &settings);
    if outcome.stop != PcgStop::Converged {
        return None;
    }
    // the recursive residual drifts from the true one: confirm
    (system.apply)(&solution, &mut vectors.image);
    let mut true_residual = 0.0_f64;
    for (b, product) in rhs.iter().zip(&vectors.image) {
        true_residual = true_residual.max((b - product).abs());
    }
    let floor = NEWTON_PCG_ROUNDING_ULPS * f64::EPSILON * matrix_norm * max_abs(&solution);
    (true_residual <= target + floor).then_some(solution)
}

/// A Newton system `apply` preconditioned with a Cholesky factor.
struct FactorPreconditioned<'a, F> {
    apply: F,
    factor: MatRef<'a, f64>,
}

impl<F: FnMut(&[f64], &mut [f64])> PcgSystem for FactorPreconditioned<'_, F> {
    type Error = std::convert::Infallible;

    fn apply(&mut self, x: &[f64], image: &mut [f64]) -> Result<(), Self::Error> {
        (self.apply)(x, image);
        Ok(())
    }

    fn precondition(&mut self, residual: &[f64], z: &mut [f64]) -> Result<(), Self::Error> {
        z.copy_from_slice(residual);
        cholesky_solve(self.factor, z);
        Ok(())
    }
}
