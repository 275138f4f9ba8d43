//! The condensed friction problem of (5.1) posed on the Γ3 nodes with friction only.
//!
//! Where the friction weight vanishes (w_a = 0: a node out of contact, or with p_τ = 0) the
//! tangential velocity is an ordinary unknown of the model problem. With P the tangential
//! unknowns of the nodes with w_a > 0, the friction problem condensed onto P has
//!
//! ```text
//!     S̃ = (E_Pᵀ H⁻¹ E_P)⁻¹ = ((S⁻¹)_PP)⁻¹,    r̃ = S̃ (H⁻¹ b)_P,
//! ```
//!
//! and the trailing factor gives both without S: with S = L_tt L_ttᵀ and Y = L_tt⁻¹ E_P (E_P
//! the columns of P in the elimination order), (S⁻¹)_PP = Yᵀ Y and, for the forward half z of
//! the solve, (H⁻¹ b)_P = Yᵀ z_t; the friction forces enter the trailing block of z as
//! Y (W λ)_P. For m tangential unknowns and p = |P| this costs about m² p + m p² + p³ once
//! per factor and set of nodes, where S costs 2 m³ and the friction Newton systems run over
//! all of Γ3. Used when at most half of the contact nodes have friction: a contact zone small
//! against Γ3 (Hertz, Mindlin: a tenth of the nodes of Γ3 press).

use super::operator::VelocityOperator;
use crate::error::{Error, Result};
use crate::solvers::friction::CondensedFriction;
use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::solve_lower_triangular_in_place;
use faer::{Accum, Mat, Par};

/// The condensation onto the tangential unknowns of the nodes with friction, for one factor
/// and one set of nodes.
pub(crate) struct ReducedCondensation {
    /// The [`VelocityOperator::factor_generation`] it was made for.
    pub(super) generation: u64,
    /// The contact nodes (indices into the contact nodes) with w_a > 0.
    pub(super) groups: Vec<usize>,
    /// Their tangential unknowns, as indices into `tangential` (D − 1 per node, in order).
    pub(super) unknowns: Vec<usize>,
    /// Y = L_tt⁻¹ E_P: m × p, rows in the elimination order of the trailing block.
    pub(super) y: Mat<f64>,
    /// S̃ = (Yᵀ Y)⁻¹, p × p, exactly symmetric.
    pub(super) schur: Mat<f64>,
}

impl ReducedCondensation {
    /// Whether the nodes with friction of `weights` are exactly those it was made for.
    pub(super) fn matches(&self, weights: &[f64]) -> bool {
        weights.iter().filter(|&&w| w > 0.0).count() == self.groups.len()
            && self.groups.iter().all(|&k| weights[k] > 0.0)
    }
}

impl<const D: usize> VelocityOperator<D> {
    /// Prepares the condensation of a step whose friction weights are `weights`: with a
    /// trailing factor and at most half of the contact nodes with friction, the reduced
    /// condensation (kept while the factor and the set of nodes stay the same); otherwise the
    /// condensation onto all of Γ3 with S.
    pub(super) fn prepare_condensation(&mut self, weights: &[f64]) -> Result<()> {
        let g = D - 1;
        let groups: Vec<usize> = (0..weights.len()).filter(|&k| weights[k] > 0.0).collect();
        let Some(trailing) = self.trailing.as_ref() else {
            self.reduction = None;
            return self.ensure_schur();
        };
        if self.tangential.is_empty() || 2 * groups.len() > weights.len() {
            self.reduction = None;
            return self.ensure_schur();
        }
        if let Some(reduction) = &self.reduction {
            if reduction.generation == self.factor_generation && reduction.matches(weights) {
                return Ok(());
            }
        }
        let m = self.tangential.len();
        let mut position = vec![0; m];
        for (p, &i) in trailing.index.iter().enumerate() {
            position[i] = p;
        }
        let unknowns: Vec<usize> = groups
            .iter()
            .flat_map(|&k| (0..g).map(move |i| k * g + i))
            .collect();
        let p = unknowns.len();
        let factor_tt =
            trailing
                .factor
                .as_ref()
                .submatrix(trailing.leading, trailing.leading, m, m);
        let mut y = Mat::<f64>::zeros(m, p);
        for (j, &i) in unknowns.iter().enumerate() {
            y[(position[i], j)] = 1.0;
        }
        solve_lower_triangular_in_place(factor_tt, y.as_mut(), Par::Seq);
        let mut gram = Mat::<f64>::zeros(p, p);
        matmul(
            gram.as_mut(),
            Accum::Replace,
            y.transpose(),
            y.as_ref(),
            1.0,
            Par::Seq,
        );
        let gram = Mat::<f64>::from_fn(p, p, |i, j| 0.5 * (gram[(i, j)] + gram[(j, i)]));
        let schur = if p == 0 {
            Mat::zeros(0, 0)
        } else {
            let llt = gram
                .llt(faer::Side::Lower)
                .map_err(|e| Error::LinearAlgebra {
                    context: "condensed velocity operator on the nodes with friction, (S⁻¹)_PP"
                        .into(),
                    message: format!("dense Cholesky failed: {e:?}"),
                })?;
            let inverse = faer::linalg::solvers::DenseSolveCore::inverse(&llt);
            Mat::<f64>::from_fn(p, p, |i, j| 0.5 * (inverse[(i, j)] + inverse[(j, i)]))
        };
        CondensedFriction::validate_matrix(schur.as_ref())?;
        self.reduction = Some(ReducedCondensation {
            generation: self.factor_generation,
            groups,
            unknowns,
            y,
            schur,
        });
        Ok(())
    }
}
