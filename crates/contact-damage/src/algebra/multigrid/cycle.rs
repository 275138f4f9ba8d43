//! The symmetric V(1,1)-cycle of the truncated hierarchy (the [module documentation](super),
//! "Cycle") and its Gauss–Seidel smoother.

use crate::algebra::multigrid::hierarchy::{Hierarchy, Level};
use crate::algebra::multigrid::parallel::for_each_row;

impl Level {
    /// One Gauss–Seidel sweep on `solution` for this level's `rhs` (forward or backward).
    pub(super) fn sweep(&mut self, backward: bool) {
        gauss_seidel(self, backward);
    }
}

impl Hierarchy {
    /// `z = B r`: one symmetric V-cycle for the truncated fine matrix from a zero start; `r`
    /// must vanish on the fixed indices, and so does `z`.
    pub(crate) fn cycle(&mut self, residual: &[f64], z: &mut [f64]) {
        self.levels[0].rhs.copy_from_slice(residual);
        self.cycle_level(0);
        z.copy_from_slice(&self.levels[0].solution);
    }

    fn cycle_level(&mut self, l: usize) {
        let last = self.levels.len() - 1;
        if l == last {
            let level = &mut self.levels[l];
            match &self.coarsest_factor {
                Some(factor) => factor.solve(&level.rhs, &mut level.solution, &mut level.residual),
                None => {
                    level.solution.fill(0.0);
                    for _ in 0..self.coarsest_sweeps {
                        level.sweep(false);
                        level.sweep(true);
                    }
                }
            }
            return;
        }
        {
            let level = &mut self.levels[l];
            level.solution.fill(0.0);
            level.sweep(false);
            // r = b − Ã_l z on the rows kept by the truncation (the others are zero rows).
            let (diagonal, rhs, matrix, solution) =
                (&level.diagonal, &level.rhs, &level.matrix, &level.solution);
            for_each_row(&mut level.residual, |i, residual| {
                *residual = if diagonal[i] > 0.0 {
                    rhs[i] - matrix.row_product(i, solution)
                } else {
                    0.0
                };
            });
        }
        {
            let (fine_levels, coarse_levels) = self.levels.split_at_mut(l + 1);
            let level = &fine_levels[l];
            let transfer = level.transfer.as_ref().expect("not the coarsest");
            transfer
                .restriction
                .multiply(&level.residual, &mut coarse_levels[0].rhs);
        }
        self.cycle_level(l + 1);
        {
            let (fine_levels, coarse_levels) = self.levels.split_at_mut(l + 1);
            let level = &mut fine_levels[l];
            let coarse = &coarse_levels[0];
            let prolongation = &level
                .transfer
                .as_ref()
                .expect("not the coarsest")
                .prolongation;
            let diagonal = &level.diagonal;
            for_each_row(&mut level.solution, |i, solution| {
                if diagonal[i] > 0.0 {
                    let (columns, values) = prolongation.row(i);
                    *solution += columns
                        .iter()
                        .zip(values)
                        .map(|(&j, p)| p * coarse.solution[j])
                        .sum::<f64>();
                }
            });
            level.sweep(true);
        }
    }
}

/// One Gauss–Seidel sweep of `level` for `Ã z = r` (forward or backward) on the rows with a
/// positive diagonal (the others are truncated away and stay zero).
fn gauss_seidel(level: &mut Level, backward: bool) {
    let n = level.solution.len();
    for step in 0..n {
        let i = if backward { n - 1 - step } else { step };
        if level.diagonal[i] <= 0.0 {
            continue;
        }
        let product =
            level
                .matrix
                .sweep_product(i, &level.solution, level.lower_counts[i], backward);
        level.solution[i] += (level.rhs[i] - product) * level.inverse_diagonal[i];
    }
}
