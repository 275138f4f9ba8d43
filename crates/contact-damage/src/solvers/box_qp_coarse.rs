//! Coarse obstacle corrections of the box QP of [`crate::solvers::box_qp`] on aggregates.
//!
//! The truncated nonsmooth Newton multigrid keeps every index that lies on a bound out of its
//! linear correction, and its projected Gauss–Seidel smoother frees an index only when the
//! gradient there points into the box. Where the bound set of the solution is smaller than the
//! current one by a band of indices whose gradients still point out of the box (the damage
//! field leaves β = 1 over a distance set by the diffusion length √(κk), i.e. over more cells
//! the finer the mesh at a fixed time step), each iteration frees only the indices next to the
//! free set, and the number of iterations grows with the width of the band in cells.
//!
//! Before each smoothing, a coarse correction minimizes the energy over the corrections that
//! are constant on the aggregates of the multigrid coarsening (the tentative prolongation
//! `P̂`, with one 1 per aggregated row): for a feasible `x` with gradient `g = Ax − b`,
//!
//! ```text
//!     minimize  ½ dᵀ (P̂ᵀAP̂) d + (P̂ᵀg)ᵀ d   subject to  max_{i∈J}(lower_i − x_i) ≤ d_J ≤ min_{i∈J}(upper_i − x_i),
//! ```
//!
//! so that `x + P̂d` stays feasible (the conservative bounds of monotone multigrid, Kornhuber
//! 1994) and `q(x + P̂d) ≤ q(x)` (d = 0 is feasible). This is a box QP of the same kind with
//! about a sixth of the unknowns in 2D; it is solved by the same method, which applies its
//! own coarse correction first, down to [`MIN_NESTED_SIZE`] unknowns or a matrix no longer
//! diffusion dominated ([`MIN_DIFFUSION_DOMINANCE`]). Unlike a single projected sweep on the
//! coarse levels, the coarse *minimizer* may lower a whole band of indices whose gradients
//! point out of the box: the coarse problem sees the band narrower in its own unknowns. The
//! coarse solves stop at a loose tolerance ([`COARSE_TOLERANCE`]): they only move the iterate
//! of the fine iteration, which certifies the result by its own KKT residual, and any
//! feasible coarse iterate lowers the energy, so the fine iteration stays monotone and
//! globally convergent.
//!
//! Measured on the moving-damage case (`examples/damage_iterations.rs`, k = 1/64): at most
//! 6, 6, 7 and 9 fine iterations per step at N = 64, 128, 256, 512 without the correction,
//! at most 6 at every N with it (it is used from N = 256 on; 5.2 and 6.0 iterations per step
//! on average against 6.4 and 8.1).
//!
//! **When.** A correction is computed while the fine residual is above the coarse tolerance,
//! and below it only where a band is left to free: more than [`BAND_FRACTION`]`·√n` indices
//! on a bound whose gradients point into the box ([`bound_violations`]; √n is the length of a
//! grid line of n unknowns in 2D), with a coarse tolerance of [`BAND_REDUCTION`] times the
//! fine residual, since a coarse gradient (a sum of fine ones) below the fixed tolerance would
//! stop the coarse solve at d = 0. Measured in `bench_step`'s 2D damage problem (κ = 0.01,
//! k = 1/128, the bound set β = 1 shrinking by about 1.6 k indices per step at 512²), steps
//! 25–32 solved in one process: at 512² the start residuals are 6e-8 to 1.5e-7 with 8–240
//! such indices, and the fine iterations of the eight steps fall from 41 / 74 (outer / CG) to
//! 30 / 47, the time per step from 195 to 167 ms; at 256² from 31 / 52 to 25 / 41 and from 36
//! to 32 ms. Without the band rule (a correction at every iteration) the same counts, but
//! `zones2d` at 128 cells, whose bound set does not move in bands (0–9 such indices in most
//! iterations), paid 516 coarse iterations for no fine one and 25 % more time in (5.2); with
//! it, 18 coarse iterations instead of 5, the same fine ones. The moving-damage case above
//! keeps its counts.

use faer::sparse::{SparseColMat, Triplet};

use crate::algebra::multigrid::{aggregate, Csr, UNASSIGNED};
use crate::error::{Error, Result};

/// Smallest number of unknowns of a box QP that gets a coarse correction.
pub(crate) const MIN_NESTED_SIZE: usize = 2000;
/// Scaled KKT tolerance of the coarse solves.
pub(crate) const COARSE_TOLERANCE: f64 = 1e-6;
/// Most iterations of a coarse solve.
const COARSE_ITERATIONS: usize = 20;
/// Below the coarse tolerance a correction is computed only for more than this fraction of
/// √n indices on a bound with gradients pointing into the box (module documentation).
const BAND_FRACTION: f64 = 0.2;
/// Below the coarse tolerance the coarse solve stops at this fraction of the fine residual.
const BAND_REDUCTION: f64 = 0.1;
/// Coarsening too slow for a coarse correction to pay: more aggregates than this fraction of
/// the unknowns.
const STALLED: f64 = 0.5;
/// Smallest median of `a_ii / Σ_j a_ij` over the rows (see [`diffusion_dominance`]) that gets
/// a coarse correction.
pub(crate) const MIN_DIFFUSION_DOMINANCE: f64 = 20.0;

/// The median over the rows of `a_ii / Σ_j a_ij` (rows with a non-positive sum count as
/// infinitely dominated by their couplings). For the damage matrix `M/k + κK` the row sums
/// are those of `M/k` (`K` annihilates constants), so for P1 on a uniform triangulation in
/// 2D the ratio is `1/2 + 4κk/h²`: it measures how many cells the diffusion length `√(κk)`
/// spans, i.e. how wide the bands of indices that leave a bound in one step can be in
/// cells. The damage case of `examples/damage_iterations.rs` (κ = 0.01, k = 1/64) has
/// ratios 3.1, 10.7, 41 and 164 at N = 64, 128, 256 and 512; the iteration counts of the
/// plain iteration grow from N = 256 on.
pub(crate) fn diffusion_dominance(rows: &Csr, diagonal: &[f64]) -> f64 {
    let mut ratios: Vec<f64> = diagonal
        .iter()
        .enumerate()
        .map(|(i, &a)| {
            let sum: f64 = rows.row(i).1.iter().sum();
            if sum > 0.0 {
                a / sum
            } else {
                f64::INFINITY
            }
        })
        .collect();
    if ratios.is_empty() {
        return 0.0;
    }
    let middle = ratios.len() / 2;
    *ratios
        .select_nth_unstable_by(middle, |a, b| a.total_cmp(b))
        .1
}

/// The number of indices on a bound whose gradient `g = Ax − b` points into the box by more
/// than `tie`: `x_i = upper_i` with `g_i > tie`, or `x_i = lower_i` with `g_i < −tie` (the
/// indices that a Gauss–Seidel sweep would move off their bound; an index with
/// `lower_i = upper_i` never counts).
pub(crate) fn bound_violations(
    x: &[f64],
    gradient: &[f64],
    lower: &[f64],
    upper: &[f64],
    tie: f64,
) -> usize {
    let mut count = 0;
    for i in 0..x.len() {
        if lower[i] < upper[i]
            && ((x[i] == upper[i] && gradient[i] > tie) || (x[i] == lower[i] && gradient[i] < -tie))
        {
            count += 1;
        }
    }
    count
}

/// The coarse correction of one box QP (see the module documentation).
/// The solver of a coarse problem P̂ᵀAP̂: the box QP solver itself, with a coarse correction of
/// its own (recursively).
pub(crate) trait NestedBoxQp {
    /// Sets the scaled KKT tolerance of the next solves.
    fn set_tolerance(&mut self, tolerance: f64);
    /// Solves the box QP with right-hand side `rhs` and bounds `lower ≤ x ≤ upper` from the
    /// feasible `x`; returns the iterations at every level.
    fn solve_nested(
        &mut self,
        rhs: &[f64],
        lower: &[f64],
        upper: &[f64],
        x: &mut [f64],
    ) -> Result<usize>;
}

pub(crate) struct CoarseObstacle<S> {
    /// The KKT tolerance of the box QP this correction was built for (for the correction of
    /// a coarse problem, the coarse tolerance of the level above: the band rule acts on the
    /// finest level only).
    fine_tolerance: f64,
    /// The tolerance of the coarse solves above which every iteration gets a correction.
    coarse_tolerance: f64,
    /// The aggregate of every fine index ([`UNASSIGNED`]: not corrected).
    aggregates: Vec<usize>,
    /// The box QP solver of `P̂ᵀAP̂` (with its own coarse correction, recursively).
    solver: Box<S>,
    rhs: Vec<f64>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    correction: Vec<f64>,
}

impl<S: NestedBoxQp> CoarseObstacle<S> {
    /// The coarse correction of the box QP with the rows `rows` of `A` (symmetric, both
    /// triangles) and its diagonal, or `None` when `A` is smaller than [`MIN_NESTED_SIZE`],
    /// its [`diffusion_dominance`] is below [`MIN_DIFFUSION_DOMINANCE`] (the bands that
    /// leave a bound are then a cell or two wide, and the plain iteration frees them as fast),
    /// or its aggregation does not coarsen enough. `fine_tolerance` is the KKT tolerance of the
    /// box QP; `nested(matrix, tolerance, max_iterations)` builds the solver of the coarse
    /// problem.
    pub(crate) fn new(
        rows: &Csr,
        diagonal: &[f64],
        fine_tolerance: f64,
        nested: impl FnOnce(SparseColMat<usize, f64>, f64, usize) -> Result<S>,
    ) -> Result<Option<Self>> {
        let n = rows.rows();
        if n < MIN_NESTED_SIZE || diffusion_dominance(rows, diagonal) < MIN_DIFFUSION_DOMINANCE {
            return Ok(None);
        }
        let (aggregates, coarse) = aggregate(rows, diagonal);
        if coarse == 0 || coarse as f64 > STALLED * n as f64 {
            return Ok(None);
        }
        // P̂ᵀAP̂: the entries of A summed by the aggregates of their row and column.
        let mut triplets = Vec::new();
        for i in 0..n {
            let row_aggregate = aggregates[i];
            if row_aggregate == UNASSIGNED {
                continue;
            }
            let (columns, values) = rows.row(i);
            for (&j, &a) in columns.iter().zip(values) {
                if aggregates[j] != UNASSIGNED {
                    triplets.push(Triplet::new(row_aggregate, aggregates[j], a));
                }
            }
        }
        let matrix =
            SparseColMat::try_new_from_triplets(coarse, coarse, &triplets).map_err(|err| {
                Error::LinearAlgebra {
                    context: "box QP coarse obstacle matrix P̂ᵀAP̂".into(),
                    message: format!("{err:?}"),
                }
            })?;
        let coarse_tolerance = COARSE_TOLERANCE.max(fine_tolerance);
        Ok(Some(Self {
            fine_tolerance,
            coarse_tolerance,
            aggregates,
            solver: Box::new(nested(matrix, coarse_tolerance, COARSE_ITERATIONS)?),
            rhs: vec![0.0; coarse],
            lower: vec![0.0; coarse],
            upper: vec![0.0; coarse],
            correction: vec![0.0; coarse],
        }))
    }

    /// The tolerance of the coarse solves above which every iteration gets a correction.
    #[cfg(test)]
    pub(crate) fn coarse_tolerance(&self) -> f64 {
        self.coarse_tolerance
    }

    /// The number of unknowns of the coarse problem.
    #[cfg(test)]
    pub(crate) fn coarse_size(&self) -> usize {
        self.correction.len()
    }

    /// The tolerance of a coarse correction at a fine iterate of `n` unknowns with the scaled
    /// KKT residual `residual`, or None where none is worth computing (module documentation):
    /// the coarse tolerance above it; below it, while the fine iteration has not converged,
    /// [`BAND_REDUCTION`] of the residual if `violations()` (the indices on a bound whose
    /// gradients point into the box, counted only then) exceed [`BAND_FRACTION`]`·√n`. Without
    /// such a band the coarse problem (whose gradient sums the fine one over the aggregates)
    /// is almost always solved by d = 0 already, and the correction would cost its set-up for
    /// nothing.
    pub(crate) fn tolerance_at(
        &self,
        residual: f64,
        n: usize,
        violations: impl FnOnce() -> usize,
    ) -> Option<f64> {
        if residual > self.coarse_tolerance {
            Some(self.coarse_tolerance)
        } else if residual > self.fine_tolerance
            && violations() as f64 > BAND_FRACTION * (n as f64).sqrt()
        {
            Some((BAND_REDUCTION * residual).max(self.fine_tolerance))
        } else {
            None
        }
    }

    /// Adds the coarse correction, solved to the scaled KKT tolerance `tolerance`, to the
    /// feasible `x` with gradient `gradient = Ax − b`; returns the number of iterations of the
    /// coarse solves at every level, 0 when the coarse problem is solved by d = 0 to its
    /// tolerance and `x` is left as it was. `x` stays within `lower ≤ x ≤ upper` and `q(x)`
    /// does not increase; after a correction the caller recomputes the gradient.
    pub(crate) fn correct(
        &mut self,
        x: &mut [f64],
        gradient: &[f64],
        lower: &[f64],
        upper: &[f64],
        tolerance: f64,
    ) -> Result<usize> {
        self.solver.set_tolerance(tolerance);
        self.rhs.fill(0.0);
        self.lower.fill(f64::NEG_INFINITY);
        self.upper.fill(f64::INFINITY);
        for (i, &aggregate) in self.aggregates.iter().enumerate() {
            if aggregate == UNASSIGNED {
                continue;
            }
            self.rhs[aggregate] -= gradient[i];
            self.lower[aggregate] = self.lower[aggregate].max(lower[i] - x[i]);
            self.upper[aggregate] = self.upper[aggregate].min(upper[i] - x[i]);
        }
        self.correction.fill(0.0);
        let iterations = match self.solver.solve_nested(
            &self.rhs,
            &self.lower,
            &self.upper,
            &mut self.correction,
        ) {
            Ok(iterations) => iterations,
            // A feasible coarse iterate that did not reach the loose tolerance still lowers
            // the energy (the coarse iteration is monotone); the fine iteration goes on.
            Err(Error::NoConvergence { iterations, .. }) => iterations,
            // The correction is only an acceleration: without it the fine iteration, which
            // meets the same matrix, still converges or reports the failure itself.
            Err(Error::LinearAlgebra { .. }) => return Ok(0),
            Err(error) => return Err(error),
        };
        if iterations == 0 {
            return Ok(0);
        }
        for (i, &aggregate) in self.aggregates.iter().enumerate() {
            if aggregate != UNASSIGNED {
                // Within the box: lower_i − x_i ≤ d_J ≤ upper_i − x_i; the clamp only
                // removes the rounding of x_i + d_J.
                x[i] = (x[i] + self.correction[aggregate]).clamp(lower[i], upper[i]);
            }
        }
        Ok(iterations)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::algebra::multigrid::tests::laplacian;
    use faer::sparse::Triplet;

    /// ½ xᵀAx − bᵀx.
    pub(crate) fn energy(rows: &Csr, x: &[f64], rhs: &[f64]) -> f64 {
        let mut product = vec![0.0; x.len()];
        rows.multiply(x, &mut product);
        x.iter()
            .zip(&product)
            .zip(rhs)
            .map(|((x, ax), b)| 0.5 * x * ax - b * x)
            .sum()
    }

    /// `A x − b`.
    pub(crate) fn gradient(rows: &Csr, x: &[f64], rhs: &[f64]) -> Vec<f64> {
        let mut product = vec![0.0; x.len()];
        rows.multiply(x, &mut product);
        product.iter().zip(rhs).map(|(ax, b)| ax - b).collect()
    }

    /// A diffusion-dominated obstacle problem on an m×m grid (5-point Laplacian + 0.01 I,
    /// median ratio a_ii / Σ_j a_ij = 401): the rows, b = 0.01·f with f = 1.5 left of the
    /// middle and −1 right of it, so that the solution lies on the upper bound 1 on the left
    /// and on the lower bound 0 on the right, with a diffusion layer of about ten cells
    /// between them.
    pub(crate) fn layer_problem(m: usize) -> (Csr, Vec<f64>) {
        let rows = Csr::from_symmetric(&laplacian(m, 0.01));
        let rhs = (0..m * m)
            .map(|index| if index % m < m / 2 { 0.015 } else { -0.01 })
            .collect();
        (rows, rhs)
    }

    /// The rows of `rows` as a faer matrix (both triangles).
    pub(crate) fn sparse(rows: &Csr) -> SparseColMat<usize, f64> {
        let n = rows.rows();
        let triplets: Vec<_> = (0..n)
            .flat_map(|i| {
                let (columns, values) = rows.row(i);
                columns
                    .iter()
                    .zip(values)
                    .map(move |(&j, &a)| Triplet::new(i, j, a))
                    .collect::<Vec<_>>()
            })
            .collect();
        SparseColMat::try_new_from_triplets(n, n, &triplets).unwrap()
    }

    #[test]
    fn bound_violations_count_the_indices_a_sweep_would_move_off_their_bound() {
        let lower = [0.0, 0.0, 0.0, 0.0, 0.5, 0.0];
        let upper = [1.0, 1.0, 1.0, 1.0, 0.5, 1.0];
        let x = [1.0, 1.0, 0.0, 0.0, 0.5, 0.3];
        // at the upper bound pointing in, at it pointing out, at the lower bound pointing
        // in, within the tie, fixed, free
        let gradient = [2e-3, -1.0, -2e-3, -1e-9, 5.0, 7.0];
        assert_eq!(bound_violations(&x, &gradient, &lower, &upper, 1e-6), 2);
        assert_eq!(bound_violations(&x, &gradient, &lower, &upper, 1e-2), 0);
    }
}
