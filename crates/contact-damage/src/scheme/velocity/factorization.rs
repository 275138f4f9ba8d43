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
        self.restore_plain_trailing();
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

    /// Numeric factorization of the current matrix (after the symbolic analysis, if the
    /// arrangement of the contact unknowns changed since the last one) and the Schur
    /// complement on the tangential contact unknowns: Z = E_cᵀ H^{-1} E_c (block solves),
    /// S = Z^{-1}.
    /// With a supernodal factor whose last unknowns are the contact ones, S is formed from its
    /// trailing block only when a step needs it ([`Self::prepare_condensation`]).
    pub(super) fn factorize(&mut self) -> Result<()> {
        if !self.analysed {
            self.analyse()?;
        }
        self.solver.factorize(&self.matrix)?;
        self.factor_generation += 1;
        self.trailing = self.trailing_from_factor();
        self.schur = None;
        if self.trailing.is_none() {
            let schur = self.schur_from_solves()?;
            // checked once here; every step solves with it (`condensed_friction`)
            CondensedFriction::validate_matrix(schur.as_ref())?;
            self.schur = Some(schur);
        }
        Ok(())
    }

    /// Forms S from the trailing factor if it is not held (checked once here, like the S of
    /// [`Self::factorize`]).
    pub(super) fn ensure_schur(&mut self) -> Result<()> {
        if self.schur.is_none() {
            if let Some(trailing) = &self.trailing {
                let schur = self.tangential_schur(trailing);
                CondensedFriction::validate_matrix(schur.as_ref())?;
                self.schur = Some(schur);
            }
        }
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

    /// S = L_tt L_ttᵀ from the trailing block of the factor (L_tt its tangential part), in the
    /// order of `tangential`, and that block; None when the factor is simplicial or its last
    /// unknowns are not the contact ones (then [`Self::factorize`] falls back to m solves).
    #[cfg(test)]
    pub(super) fn schur_from_trailing_factor(&self) -> Option<(Mat<f64>, TrailingFactor)> {
        let trailing = self.trailing_from_factor()?;
        Some((self.tangential_schur(&trailing), trailing))
    }

    /// The trailing block of the factor when its last unknowns are the contact ones (see
    /// [`TrailingFactor`]); None when the factor is simplicial or ordered otherwise.
    pub(super) fn trailing_from_factor(&self) -> Option<TrailingFactor> {
        let m = self.tangential.len();
        let leading = if self.normals_last {
            self.contact.len()
        } else {
            0
        };
        if leading + m == 0 {
            return None;
        }
        let (trailing, unknowns) = self.solver.trailing_factor(leading + m)?;
        let mut position = vec![usize::MAX; self.size()];
        for (i, &dof) in self.tangential.iter().enumerate() {
            position[dof] = i;
        }
        let mut normal_nodes = Vec::with_capacity(leading);
        for &dof in &unknowns[..leading] {
            match self.contact.index_of_node[dof / D] {
                Some(k) if dof % D == 0 => normal_nodes.push(k),
                _ => return None,
            }
        }
        let index: Vec<usize> = unknowns[leading..]
            .iter()
            .map(|&dof| position[dof])
            .collect();
        if index.contains(&usize::MAX) {
            return None;
        }
        let trailing = TrailingFactor {
            factor: trailing,
            index,
            leading,
            normal_nodes,
            plain: None,
            plain_schur: None,
        };
        Some(trailing)
    }

    /// S = L_tt L_ttᵀ in the order of `tangential`, L_tt the tangential part of the trailing
    /// factor (exactly symmetric: the blocked product need not be, to rounding).
    pub(super) fn tangential_schur(&self, trailing: &TrailingFactor) -> Mat<f64> {
        let m = self.tangential.len();
        let block = trailing
            .factor
            .as_ref()
            .submatrix(trailing.leading, trailing.leading, m, m);
        let product = block * block.transpose();
        let mut schur = Mat::<f64>::zeros(m, m);
        for (p, &i) in trailing.index.iter().enumerate() {
            for (q, &j) in trailing.index.iter().enumerate() {
                schur[(i, j)] = 0.5 * (product[(p, q)] + product[(q, p)]);
            }
        }
        schur
    }

    /// The Newton tangent H + D of a linear 𝒜 with the implicit normal compliance at the
    /// system velocity `velocity` (D = ω_a k p_ν′ on the normal unknowns), without touching the
    /// sparse factor of H: the trailing factor becomes L′ = chol(S_c + D) (see
    /// [`TrailingFactor`]) and S the Schur complement of the tangent on the tangential
    /// unknowns. Returns false (nothing changed) when the operator cannot do this (the normal
    /// unknowns are not in the trailing block, or no supernodal factor of H is held).
    pub(super) fn linearize_contact_in_trailing(&mut self, velocity: &[f64]) -> Result<bool> {
        let Some(implicit) = &self.implicit else {
            return Ok(false);
        };
        if !(self.law.is_linear() && self.matrix_is_plain && self.solver.is_factorized()) {
            return Ok(false);
        }
        let Some(trailing) = self.trailing.as_mut() else {
            return Ok(false);
        };
        if trailing.leading == 0 || trailing.leading != self.contact.len() {
            return Ok(false);
        }
        if trailing.plain.is_none() {
            trailing.plain = Some(trailing.factor.clone());
        }
        let plain = trailing.plain.as_ref().expect("kept above");
        let plain_schur = trailing
            .plain_schur
            .get_or_insert_with(|| lower_times_transpose(plain.as_ref()));
        // The tangent S_c + D is factorized in the buffer of the factor it replaces (the
        // plain factor's copy is kept in `plain`): a dense block of several thousand unknowns
        // is not allocated, and its pages not cleared by the system, at every iteration.
        let tangent = &mut trailing.factor;
        tangent.copy_from_triangular_lower(plain_schur.as_ref());
        for (p, &k) in trailing.normal_nodes.iter().enumerate() {
            let dof = self.contact.nodes[k] * D;
            tangent[(p, p)] += self.contact.weights[k]
                * implicit.time_step
                * implicit
                    .law
                    .normal_stiffness(implicit.penetration(k, velocity[dof]));
        }
        let factorized = cholesky_in_place_lower(tangent.as_mut());
        self.schur = None;
        self.factor_generation += 1;
        if let Err(e) = factorized {
            // the plain factor again, as if no tangent had been formed
            trailing.factor.copy_from(plain);
            return Err(Error::LinearAlgebra {
                context: "Newton tangent of the implicit normal compliance (contact block)".into(),
                message: format!("dense Cholesky failed: {e:?}"),
            });
        }
        Ok(true)
    }

    /// Makes the trailing factor that of H again after Newton tangents of the contact block.
    pub(super) fn restore_plain_trailing(&mut self) {
        let Some(mut trailing) = self.trailing.take() else {
            return;
        };
        if let Some(plain) = trailing.plain.take() {
            trailing.factor = plain;
            self.schur = None;
            self.factor_generation += 1;
        }
        self.trailing = Some(trailing);
    }
}

/// The Cholesky factor L of the symmetric matrix whose lower triangle `matrix` holds, in place:
/// L in the lower triangle, zeros above it. The operations of faer's `Mat::llt` (the same
/// blocked factorization and parallelism), without its copy of the matrix.
fn cholesky_in_place_lower(
    mut matrix: faer::MatMut<'_, f64>,
) -> Result<(), faer::linalg::cholesky::llt::factor::LltError> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch};
    let n = matrix.nrows();
    let par = faer::get_global_parallelism();
    let mut memory = MemBuffer::new(cholesky_in_place_scratch::<f64>(n, par, Default::default()));
    cholesky_in_place(
        matrix.as_mut(),
        Default::default(),
        par,
        MemStack::new(&mut memory),
        Default::default(),
    )?;
    for j in 0..n {
        for i in 0..j {
            matrix[(i, j)] = 0.0;
        }
    }
    Ok(())
}

/// L Lᵀ for a lower triangular L, exactly symmetric: the lower triangle by a triangular product
/// (a sixth of the flops of the full product), mirrored.
fn lower_times_transpose(lower: faer::MatRef<'_, f64>) -> Mat<f64> {
    use faer::linalg::matmul::triangular::{matmul, BlockStructure};
    let n = lower.nrows();
    let mut product = Mat::<f64>::zeros(n, n);
    matmul(
        product.as_mut(),
        BlockStructure::TriangularLower,
        faer::Accum::Replace,
        lower,
        BlockStructure::TriangularLower,
        lower.transpose(),
        BlockStructure::TriangularUpper,
        1.0,
        faer::get_global_parallelism(),
    );
    for j in 0..n {
        for i in 0..j {
            product[(i, j)] = product[(j, i)];
        }
    }
    product
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn in_place_cholesky_is_bitwise_that_of_faer_llt_and_zero_above_the_diagonal() {
        // an SPD matrix of 300 unknowns (several blocks of the blocked factorization)
        let n = 300;
        let random = |i: usize, j: usize| (((i * 7919 + j * 104_729) % 1009) as f64) / 1009.0 - 0.5;
        let factor = Mat::<f64>::from_fn(n, n, |i, j| if i >= j { random(i, j) } else { 0.0 });
        let mut matrix = lower_times_transpose(factor.as_ref());
        for i in 0..n {
            matrix[(i, i)] += 1.0;
        }
        let expected = matrix.llt(faer::Side::Lower).unwrap().L().to_owned();
        // the upper triangle of the buffer holds other values: they must not be read
        let mut buffer = Mat::<f64>::from_fn(n, n, |i, j| if i < j { f64::NAN } else { 0.0 });
        buffer.copy_from_triangular_lower(matrix.as_ref());
        cholesky_in_place_lower(buffer.as_mut()).unwrap();
        for j in 0..n {
            for i in 0..n {
                assert_eq!(
                    buffer[(i, j)].to_bits(),
                    expected[(i, j)].to_bits(),
                    "entry ({i}, {j})"
                );
            }
        }
        // an indefinite matrix is refused
        matrix[(0, 0)] = -1.0;
        buffer.copy_from_triangular_lower(matrix.as_ref());
        assert!(cholesky_in_place_lower(buffer.as_mut()).is_err());
    }
}
