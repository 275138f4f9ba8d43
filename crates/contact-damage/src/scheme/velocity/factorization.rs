//! Numeric factorization of the velocity operator of (5.1) and the condensed operator
//! S = (E_cᵀ H⁻¹ E_c)⁻¹ on the tangential contact unknowns.

use super::operator::{TrailingFactor, VelocityOperator};
use crate::error::{Error, Result};
use crate::solvers::friction::CondensedFriction;
use faer::Mat;

impl<const D: usize> VelocityOperator<D> {
    /// Makes the held factor that of the viscous operator H (the matrix of a linear step,
    /// [`Self::assemble`]`(None)`), factorizing it now if the operator holds none or holds a
    /// Newton tangent: the step limit ([`crate::scheme::stability`]) solves with it before the first
    /// step, which then reuses it. Afterwards [`Self::solver`] solves with H and
    /// [`Self::factored_matrix`] is H.
    pub fn factorize_viscous(&mut self) -> Result<()> {
        if !self.matrix_is_plain {
            self.matrix = self.assemble(None)?;
            self.matrix_is_plain = true;
            self.linearized_at = None;
            self.factorize()
        } else if !self.solver.is_factorized() {
            self.factorize()
        } else {
            Ok(())
        }
    }

    /// Numeric factorization of the current matrix and the Schur complement on the tangential
    /// contact unknowns: Z = E_cᵀ H^{-1} E_c (block solves), S = Z^{-1}.
    pub(super) fn factorize(&mut self) -> Result<()> {
        self.solver.factorize(&self.matrix)?;
        (self.schur, self.trailing) = match self.schur_from_trailing_factor() {
            Some((schur, trailing)) => (schur, Some(trailing)),
            None => (self.schur_from_solves()?, None),
        };
        // checked once here; every step solves with it (`condensed_friction`)
        CondensedFriction::validate_matrix(self.schur.as_ref())?;
        Ok(())
    }

    /// S = (E_cᵀ H^{-1} E_c)^{-1} by m solves in blocks and a dense inverse (used when the
    /// factor is simplicial, i.e. small).
    pub(super) fn schur_from_solves(&self) -> Result<Mat<f64>> {
        let m = self.tangential.len();
        let n = self.size();
        if m == 0 {
            return Ok(Mat::zeros(0, 0));
        }
        let mut inverse_block = Mat::<f64>::zeros(m, m);
        // blocks of right-hand sides as wide as ~512 MB allow: wider blocks make the
        // supernodal triangular solves matrix–matrix products
        let block = (64_000_000 / n.max(1)).clamp(16, 256);
        let mut start = 0;
        while start < m {
            let width = block.min(m - start);
            let mut rhs = Mat::<f64>::zeros(n, width);
            for j in 0..width {
                rhs[(self.tangential[start + j], j)] = 1.0;
            }
            self.solver.solve_block(rhs.as_mut())?;
            for j in 0..width {
                for (i, &dof) in self.tangential.iter().enumerate() {
                    inverse_block[(i, start + j)] = rhs[(dof, j)];
                }
            }
            start += width;
        }
        // symmetrize against round-off, then invert through a dense Cholesky factorization
        let sym = Mat::<f64>::from_fn(m, m, |i, j| {
            0.5 * (inverse_block[(i, j)] + inverse_block[(j, i)])
        });
        let llt = sym
            .llt(faer::Side::Lower)
            .map_err(|e| Error::LinearAlgebra {
                context: "condensed velocity operator E_cᵀ H⁻¹ E_c".into(),
                message: format!("dense Cholesky failed: {e:?}"),
            })?;
        let inverse = faer::linalg::solvers::DenseSolveCore::inverse(&llt);
        Ok(Mat::<f64>::from_fn(m, m, |i, j| {
            0.5 * (inverse[(i, j)] + inverse[(j, i)])
        }))
    }

    /// S = L_cc L_ccᵀ from the trailing block of the factor, in the order of `tangential`, and
    /// that block; None when the factor is simplicial or its last unknowns are not the
    /// tangential ones (then [`Self::factorize`] falls back to m solves).
    pub(super) fn schur_from_trailing_factor(&self) -> Option<(Mat<f64>, TrailingFactor)> {
        let m = self.tangential.len();
        if m == 0 {
            return None;
        }
        let (trailing, unknowns) = self.solver.trailing_factor(m)?;
        let mut position = vec![usize::MAX; self.size()];
        for (i, &dof) in self.tangential.iter().enumerate() {
            position[dof] = i;
        }
        let index: Vec<usize> = unknowns.iter().map(|&dof| position[dof]).collect();
        if index.contains(&usize::MAX) {
            return None;
        }
        let product = &trailing * trailing.transpose();
        let mut schur = Mat::<f64>::zeros(m, m);
        for (p, &i) in index.iter().enumerate() {
            for (q, &j) in index.iter().enumerate() {
                // exactly symmetric (the blocked product need not be, to rounding)
                schur[(i, j)] = 0.5 * (product[(p, q)] + product[(q, p)]);
            }
        }
        Some((
            schur,
            TrailingFactor {
                factor: trailing,
                index,
            },
        ))
    }
}
