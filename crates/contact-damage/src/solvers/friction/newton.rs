//! The semismooth Newton method for the friction problem of (5.1): the Newton point predicted
//! by the primal–dual active set, the operator and norm of its reduced system, and the
//! directional derivative of J for the line search.

use super::blocks::block_norm;
use super::newton_system::{
    cholesky_solve, preconditioned_cg, slip_entry, NewtonCache, NewtonSystem,
};
use super::objective::Problem;
use crate::algebra::linalg::dot;
use crate::error::{Error, Result};

impl Problem<'_> {
    /// One-sided directional derivative J'(x; candidate − x).
    pub(super) fn directional_derivative(&self, x: &[f64], sx: &[f64], candidate: &[f64]) -> f64 {
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
    ///
    /// [`NEWTON_PCG_TOLERANCE`]: super::newton_system::NEWTON_PCG_TOLERANCE
    /// [`NEWTON_PCG_ITERATIONS`]: super::newton_system::NEWTON_PCG_ITERATIONS
    pub(super) fn newton_point(
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
        let apply = |v: &[f64], product: &mut [f64]| self.apply_newton(&system, v, product);
        let preconditioned = match cache.factor_ref() {
            Some(factor) if cache.unknowns == system.unknowns => {
                let norm = self.newton_matrix_norm(&system);
                preconditioned_cg(apply, factor, norm, &reduced_rhs)
            }
            _ => None,
        };
        let solution = match preconditioned {
            Some(solution) => solution,
            None => {
                let factor = cache.factorize(self.matrix, &system)?;
                let mut solution = reduced_rhs.clone();
                cholesky_solve(factor, &mut solution);
                // One step of iterative refinement with the same factorization.
                let mut correction = vec![0.0; n];
                self.apply_newton(&system, &solution, &mut correction);
                for (correction, b) in correction.iter_mut().zip(&reduced_rhs) {
                    *correction = b - *correction;
                }
                cholesky_solve(factor, &mut correction);
                for (value, correction) in solution.iter_mut().zip(&correction) {
                    *value += correction;
                }
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
    pub(super) fn apply_newton(&self, system: &NewtonSystem, v: &[f64], product: &mut [f64]) {
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
    pub(super) fn newton_matrix_norm(&self, system: &NewtonSystem) -> f64 {
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
}
