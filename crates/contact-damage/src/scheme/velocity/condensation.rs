//! The contact/friction coupling of the velocity step (5.1): the model problem condensed onto
//! the tangential contact unknowns of Γ3 and solved exactly by [`crate::solvers::friction`].

use super::operator::{TrailingFactor, VelocityOperator};
use super::types::VelocityStats;
use crate::error::{Error, Result};
use crate::solvers::friction::{CondensedFriction, FrictionSettings};
use faer::Mat;

impl<const D: usize> VelocityOperator<D> {
    /// Exact solution of the model problem min ½ yᵀHy − bᵀy + Σ w_a |y_τ(a)| by condensation
    /// onto the tangential contact unknowns.
    ///
    /// With `base = Some(v)`, `rhs` is the residual b − Hv and the two solves are done in
    /// correction form, y = v + H^{-1}(b − Hv − E_c W λ): this recovers the digits lost to
    /// round-off in the factor and in S (iterative refinement of the linear step), and it is the
    /// increment form of a Newton step, where b − Hv = F − N(v) is known without cancellation.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn solve_model(
        &self,
        rhs: &[f64],
        weights: &[f64],
        start: &[f64],
        base: Option<&[f64]>,
        multipliers: &mut [f64],
        friction_settings: &FrictionSettings,
        stats: &mut VelocityStats,
    ) -> Result<Vec<f64>> {
        if let Some(trailing) = &self.trailing {
            if let Some(solution) = self.solve_model_trailing(
                trailing,
                rhs,
                weights,
                start,
                base,
                multipliers,
                friction_settings,
                stats,
            )? {
                return Ok(solution);
            }
        }
        let solve = |b: &[f64]| -> Result<Vec<f64>> {
            match base {
                None => self.solver.solve(b),
                Some(v) => {
                    let correction = self.solver.solve(b)?;
                    Ok(v.iter().zip(&correction).map(|(v, c)| v + c).collect())
                }
            }
        };
        let free = solve(rhs)?;
        if self.tangential.is_empty() {
            return Ok(free);
        }
        // condensed rhs r_c = S (H^{-1} b)_c
        let reduced_rhs = self.schur_times_tangential(&free)?;
        let x = self.condensed_friction(
            &reduced_rhs,
            weights,
            start,
            multipliers,
            friction_settings,
            stats,
        )?;
        // y = H^{-1}(b − E_c W λ)
        let mut corrected = rhs.to_vec();
        let g = D - 1;
        for (i, &dof) in self.tangential.iter().enumerate() {
            corrected[dof] -= weights[i / g] * multipliers[i];
        }
        let mut solution = solve(&corrected)?;
        // the tangential unknowns are those of the condensed solution (exact zeros at stick nodes)
        for (i, &dof) in self.tangential.iter().enumerate() {
            solution[dof] = x[i];
        }
        Ok(solution)
    }

    /// [`Self::solve_model`] with the contact unknowns eliminated last: one forward and one
    /// backward triangular solve instead of two solves (with the trailing block mapped to the
    /// current operator's when it is a Newton tangent of the contact block, see
    /// [`TrailingFactor`]). With z = L⁻¹ P b in elimination order,
    /// (H⁻¹ b)_c = L_cc⁻ᵀ z_c, so the condensed right-hand side S (H⁻¹ b)_c is L_cc z_c
    /// (S = L_cc L_ccᵀ); the friction forces E_c W λ change only the trailing block of z,
    /// z_c ← z_c − L_cc⁻¹ (W λ)_c; and one backward solve gives H⁻¹ (b − E_c W λ). None if the
    /// factor is not supernodal (then the two-solve path runs).
    #[allow(clippy::too_many_arguments)]
    fn solve_model_trailing(
        &self,
        trailing: &TrailingFactor,
        rhs: &[f64],
        weights: &[f64],
        start: &[f64],
        base: Option<&[f64]>,
        multipliers: &mut [f64],
        friction_settings: &FrictionSettings,
        stats: &mut VelocityStats,
    ) -> Result<Option<Vec<f64>>> {
        let Some(mut z) = self.solver.forward_solve(rhs)? else {
            return Ok(None);
        };
        let m = self.tangential.len();
        let leading = trailing.leading;
        let first = z.len() - m - leading;
        // the trailing block of z for the current operator: z′_c = L′⁻¹ L_cc z_c after a
        // Newton tangent of the contact block, z_c itself otherwise
        let mut z_c = Mat::<f64>::from_fn(leading + m, 1, |p, _| z[first + p]);
        if let Some(plain) = &trailing.plain {
            let mut mapped = sequential_product(plain.as_ref(), z_c.as_ref());
            faer::linalg::triangular_solve::solve_lower_triangular_in_place(
                trailing.factor.as_ref(),
                mapped.as_mut(),
                faer::Par::Seq,
            );
            z_c = mapped;
        }
        let factor_tt = trailing.factor.as_ref().submatrix(leading, leading, m, m);
        let g = D - 1;
        // the friction forces in the trailing block, L_tt⁻¹ (W λ)_c, and the tangential
        // velocities of the condensed solution (index into `tangential`, value)
        let (forces, tangential_solution) = match self.reduction.as_ref().filter(|reduction| {
            reduction.generation == self.factor_generation && reduction.matches(weights)
        }) {
            Some(reduction) => {
                // onto the nodes with friction: r̃ = S̃ (Yᵀ z_t + v_P)
                let mut projected =
                    sequential_product(reduction.y.transpose(), z_c.as_ref().subrows(leading, m));
                if let Some(v) = base {
                    for (j, &i) in reduction.unknowns.iter().enumerate() {
                        projected[(j, 0)] += v[self.tangential[i]];
                    }
                }
                let reduced_rhs: Vec<f64> =
                    sequential_product(reduction.schur.as_ref(), projected.as_ref())
                        .col(0)
                        .iter()
                        .copied()
                        .collect();
                let reduced_weights: Vec<f64> =
                    reduction.groups.iter().map(|&k| weights[k]).collect();
                let mut x: Vec<f64> = reduction
                    .unknowns
                    .iter()
                    .map(|&i| start[self.tangential[i]])
                    .collect();
                let mut reduced_multipliers = vec![0.0; x.len()];
                if !x.is_empty() {
                    let problem = CondensedFriction {
                        matrix: reduction.schur.as_ref(),
                        rhs: &reduced_rhs,
                        weights: &reduced_weights,
                        group_size: g,
                    };
                    let friction = problem.solve_with_checked_matrix(
                        &mut x,
                        &mut reduced_multipliers,
                        friction_settings,
                    )?;
                    stats.friction_iterations += friction.newton_iterations;
                    stats.friction_gradient_iterations += friction.gradient_iterations;
                }
                // free nodes carry no friction force (λ = 0, as the friction solver returns)
                multipliers.fill(0.0);
                for (j, &i) in reduction.unknowns.iter().enumerate() {
                    multipliers[i] = reduced_multipliers[j];
                }
                let weighted = Mat::<f64>::from_fn(x.len(), 1, |j, _| {
                    weights[reduction.unknowns[j] / g] * reduced_multipliers[j]
                });
                let forces = sequential_product(reduction.y.as_ref(), weighted.as_ref());
                let solution: Vec<(usize, f64)> =
                    reduction.unknowns.iter().copied().zip(x).collect();
                (forces, solution)
            }
            None => {
                let condensed = sequential_product(factor_tt, z_c.as_ref().subrows(leading, m));
                let mut reduced_rhs = vec![0.0; m];
                for (p, &i) in trailing.index.iter().enumerate() {
                    reduced_rhs[i] = condensed[(p, 0)];
                }
                if let Some(v) = base {
                    // a refinement pass: the velocity is v + H⁻¹ r, so S (v_c + (H⁻¹ r)_c)
                    for (value, schur_v) in
                        reduced_rhs.iter_mut().zip(self.schur_times_tangential(v)?)
                    {
                        *value += schur_v;
                    }
                }
                let x = self.condensed_friction(
                    &reduced_rhs,
                    weights,
                    start,
                    multipliers,
                    friction_settings,
                    stats,
                )?;
                let mut forces = Mat::<f64>::from_fn(m, 1, |p, _| {
                    let i = trailing.index[p];
                    weights[i / g] * multipliers[i]
                });
                faer::linalg::triangular_solve::solve_lower_triangular_in_place(
                    factor_tt,
                    forces.as_mut(),
                    faer::Par::Seq,
                );
                (forces, x.into_iter().enumerate().collect())
            }
        };
        for p in 0..m {
            z_c[(leading + p, 0)] -= forces[(p, 0)];
        }
        if let Some(plain) = &trailing.plain {
            // back to the sparse factor of H: w_c = L_ccᵀ L′⁻ᵀ z′_c
            faer::linalg::triangular_solve::solve_upper_triangular_in_place(
                trailing.factor.as_ref().transpose(),
                z_c.as_mut(),
                faer::Par::Seq,
            );
            z_c = sequential_product(plain.as_ref().transpose(), z_c.as_ref());
        }
        for p in 0..leading + m {
            z[first + p] = z_c[(p, 0)];
        }
        let Some(mut solution) = self.solver.backward_solve(&z)? else {
            return Ok(None);
        };
        if let Some(v) = base {
            for (value, v) in solution.iter_mut().zip(v) {
                *value += v;
            }
        }
        // the tangential unknowns are those of the condensed solution (exact zeros at stick nodes)
        for (i, value) in tangential_solution {
            solution[self.tangential[i]] = value;
        }
        Ok(Some(solution))
    }

    /// S v_c: the Schur complement times the tangential contact part of `v` (in the order of
    /// `tangential`).
    fn schur_times_tangential(&self, v: &[f64]) -> Result<Vec<f64>> {
        let m = self.tangential.len();
        let v_c = Mat::<f64>::from_fn(m, 1, |i, _| v[self.tangential[i]]);
        let product = sequential_product(self.schur()?.as_ref(), v_c.as_ref());
        Ok((0..m).map(|i| product[(i, 0)]).collect())
    }

    /// S, formed by [`Self::prepare_condensation`] before a step solves with it.
    fn schur(&self) -> Result<&Mat<f64>> {
        self.schur.as_ref().ok_or_else(|| Error::LinearAlgebra {
            context: "velocity step (5.1)".into(),
            message: "the condensed operator S was not formed before the solve".into(),
        })
    }

    /// The condensed friction problem of (5.1) with right-hand side `reduced_rhs` (in the order
    /// of `tangential`), started from the tangential part of `start`: the tangential velocities,
    /// and the multipliers in `multipliers`.
    fn condensed_friction(
        &self,
        reduced_rhs: &[f64],
        weights: &[f64],
        start: &[f64],
        multipliers: &mut [f64],
        friction_settings: &FrictionSettings,
        stats: &mut VelocityStats,
    ) -> Result<Vec<f64>> {
        let mut x: Vec<f64> = self.tangential.iter().map(|&dof| start[dof]).collect();
        if self.tangential.is_empty() {
            // frictionless (`without_friction`; `solve` refused positive bounds)
            return Ok(x);
        }
        let problem = CondensedFriction {
            matrix: self.schur()?.as_ref(),
            rhs: reduced_rhs,
            weights,
            group_size: D - 1,
        };
        // S was checked when it was computed (`factorize`)
        let friction = problem.solve_with_checked_matrix(&mut x, multipliers, friction_settings)?;
        stats.friction_iterations += friction.newton_iterations;
        stats.friction_gradient_iterations += friction.gradient_iterations;
        Ok(x)
    }
}

/// `A B` on the calling thread. faer's `*` takes the global parallelism, and its parallel
/// matrix–vector product sums in an order that depends on the number of threads; the products
/// of every step go through this one, so that a run gives the same bits on any number of
/// threads (`simulate`'s `run_is_the_same_on_one_two_and_three_threads`).
fn sequential_product(a: faer::MatRef<'_, f64>, b: faer::MatRef<'_, f64>) -> Mat<f64> {
    let mut product = Mat::<f64>::zeros(a.nrows(), b.ncols());
    faer::linalg::matmul::matmul(
        product.as_mut(),
        faer::Accum::Replace,
        a,
        b,
        1.0,
        faer::Par::Seq,
    );
    product
}
