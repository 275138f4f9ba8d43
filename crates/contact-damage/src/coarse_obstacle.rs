//! Coarse obstacle corrections of the box QP of [`crate::obstacle`] on aggregates.
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

use faer::sparse::{SparseColMat, Triplet};

use crate::error::{Error, Result};
use crate::multigrid::{aggregate, Csr, UNASSIGNED};
use crate::obstacle::{BoxQpSettings, BoxQpSolver};

/// Smallest number of unknowns of a box QP that gets a coarse correction.
pub(crate) const MIN_NESTED_SIZE: usize = 2000;
/// Scaled KKT tolerance of the coarse solves.
const COARSE_TOLERANCE: f64 = 1e-6;
/// Most iterations of a coarse solve.
const COARSE_ITERATIONS: usize = 20;
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

/// The coarse correction of one box QP (see the module documentation).
pub(crate) struct CoarseObstacle {
    /// The aggregate of every fine index ([`UNASSIGNED`]: not corrected).
    aggregates: Vec<usize>,
    /// The box QP solver of `P̂ᵀAP̂` (with its own coarse correction, recursively).
    solver: Box<BoxQpSolver>,
    rhs: Vec<f64>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    correction: Vec<f64>,
}

impl CoarseObstacle {
    /// The coarse correction of the box QP with the rows `rows` of `A` (symmetric, both
    /// triangles) and its diagonal, or `None` when `A` is smaller than [`MIN_NESTED_SIZE`],
    /// its [`diffusion_dominance`] is below [`MIN_DIFFUSION_DOMINANCE`] (the bands that
    /// leave a bound are then a cell or two wide, and the plain iteration frees them as fast),
    /// or its aggregation does not coarsen enough.
    pub(crate) fn new(
        rows: &Csr,
        diagonal: &[f64],
        settings: BoxQpSettings,
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
        let coarse_settings = BoxQpSettings {
            tolerance: COARSE_TOLERANCE.max(settings.tolerance),
            max_iterations: COARSE_ITERATIONS,
            ..settings
        };
        Ok(Some(Self {
            aggregates,
            solver: Box::new(BoxQpSolver::new(matrix, coarse_settings)?),
            rhs: vec![0.0; coarse],
            lower: vec![0.0; coarse],
            upper: vec![0.0; coarse],
            correction: vec![0.0; coarse],
        }))
    }

    /// Whether a coarse correction is worth computing at a fine iterate with the scaled KKT
    /// residual `residual`: not once it is below the coarse tolerance, where the coarse
    /// problem (whose gradient sums the fine one over the aggregates) is almost always solved
    /// by d = 0 already and the correction would cost its set-up for nothing.
    pub(crate) fn applies_at(&self, residual: f64) -> bool {
        residual > self.solver.settings().tolerance
    }

    /// Adds the coarse correction to the feasible `x` with gradient `gradient = Ax − b`;
    /// returns the number of iterations of the coarse solves at every level, 0 when the coarse
    /// problem is solved by d = 0 to its tolerance and `x` is left as it was. `x` stays within
    /// `lower ≤ x ≤ upper` and `q(x)` does not increase; after a correction the caller
    /// recomputes the gradient.
    pub(crate) fn correct(
        &mut self,
        x: &mut [f64],
        gradient: &[f64],
        lower: &[f64],
        upper: &[f64],
    ) -> Result<usize> {
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
        let iterations =
            match self
                .solver
                .solve(&self.rhs, &self.lower, &self.upper, &mut self.correction)
            {
                Ok(stats) => stats.iterations + stats.coarse_iterations,
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
mod tests {
    use super::*;
    use crate::multigrid::tests::laplacian;
    use crate::test_random::SeededRandom;
    use faer::sparse::Triplet;

    /// ½ xᵀAx − bᵀx.
    fn energy(rows: &Csr, x: &[f64], rhs: &[f64]) -> f64 {
        let mut product = vec![0.0; x.len()];
        rows.multiply(x, &mut product);
        x.iter()
            .zip(&product)
            .zip(rhs)
            .map(|((x, ax), b)| 0.5 * x * ax - b * x)
            .sum()
    }

    /// `A x − b`.
    fn gradient(rows: &Csr, x: &[f64], rhs: &[f64]) -> Vec<f64> {
        let mut product = vec![0.0; x.len()];
        rows.multiply(x, &mut product);
        product.iter().zip(rhs).map(|(ax, b)| ax - b).collect()
    }

    /// A diffusion-dominated obstacle problem on an m×m grid (5-point Laplacian + 0.01 I,
    /// median ratio a_ii / Σ_j a_ij = 401): the rows, b = 0.01·f with f = 1.5 left of the
    /// middle and −1 right of it, so that the solution lies on the upper bound 1 on the left
    /// and on the lower bound 0 on the right, with a diffusion layer of about ten cells
    /// between them.
    fn layer_problem(m: usize) -> (Csr, Vec<f64>) {
        let rows = Csr::from_symmetric(&laplacian(m, 0.01));
        let rhs = (0..m * m)
            .map(|index| if index % m < m / 2 { 0.015 } else { -0.01 })
            .collect();
        (rows, rhs)
    }

    #[test]
    fn only_large_diffusion_dominated_problems_get_a_coarse_correction() {
        let settings = BoxQpSettings::default();
        let dominated = Csr::from_symmetric(&laplacian(60, 0.01));
        assert!(diffusion_dominance(&dominated, &dominated.diagonal()) > 400.0);
        let coarse = CoarseObstacle::new(&dominated, &dominated.diagonal(), settings).unwrap();
        assert!(coarse.is_some_and(|c| c.correction.len() < 3600 / 2));
        // Mass-dominated (a_ii / Σ_j a_ij ≈ 1): the layers are a cell wide.
        let mass = Csr::from_symmetric(&laplacian(60, 10.0));
        assert!(diffusion_dominance(&mass, &mass.diagonal()) < 2.0);
        assert!(CoarseObstacle::new(&mass, &mass.diagonal(), settings)
            .unwrap()
            .is_none());
        // Too small to pay.
        let small = Csr::from_symmetric(&laplacian(40, 0.01));
        assert!(CoarseObstacle::new(&small, &small.diagonal(), settings)
            .unwrap()
            .is_none());
    }

    /// From the upper bound everywhere (the layer and the right half must leave it), the
    /// coarse correction alone removes most of the energy gap to the solution, which the fine
    /// iteration's smoother frees a layer of cells at a time.
    #[test]
    fn coarse_correction_frees_a_layer_far_from_the_start() {
        let m = 60;
        let (rows, rhs) = layer_problem(m);
        let n = m * m;
        let (lower, upper) = (vec![0.0; n], vec![1.0; n]);
        let settings = BoxQpSettings::default();
        let mut coarse = CoarseObstacle::new(&rows, &rows.diagonal(), settings)
            .unwrap()
            .unwrap();
        let mut x = vec![1.0; n];
        let start = energy(&rows, &x, &rhs);
        let slope = gradient(&rows, &x, &rhs);
        coarse.correct(&mut x, &slope, &lower, &upper).unwrap();
        let corrected = energy(&rows, &x, &rhs);
        let matrix = SparseColMat::try_new_from_triplets(
            n,
            n,
            &(0..n)
                .flat_map(|i| {
                    let (columns, values) = rows.row(i);
                    columns
                        .iter()
                        .zip(values)
                        .map(move |(&j, &a)| Triplet::new(i, j, a))
                        .collect::<Vec<_>>()
                })
                .collect::<Vec<_>>(),
        )
        .unwrap();
        let mut solution = vec![1.0; n];
        BoxQpSolver::new(matrix, settings)
            .unwrap()
            .solve(&rhs, &lower, &upper, &mut solution)
            .unwrap();
        let optimum = energy(&rows, &solution, &rhs);
        let removed = (start - corrected) / (start - optimum);
        assert!(removed > 0.9, "removed {removed} of the energy gap");
        assert!(x.iter().all(|v| (0.0..=1.0).contains(v)));
    }

    /// On random data (bounds with fixed indices, infinite ones, a random feasible start) the
    /// corrected point stays in the box and its energy does not increase.
    #[test]
    fn coarse_correction_stays_in_the_box_and_never_raises_the_energy() {
        let m = 50;
        let (rows, _) = layer_problem(m);
        let n = m * m;
        let mut coarse = CoarseObstacle::new(&rows, &rows.diagonal(), BoxQpSettings::default())
            .unwrap()
            .unwrap();
        let mut rng = SeededRandom::new(7);
        for _ in 0..8 {
            let rhs: Vec<f64> = (0..n).map(|_| rng.range(-0.05, 0.05)).collect();
            let mut lower = Vec::with_capacity(n);
            let mut upper = Vec::with_capacity(n);
            for _ in 0..n {
                let (a, b) = (rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
                match rng.index(10) {
                    0 => (lower.push(a), upper.push(a)),
                    1 => (lower.push(f64::NEG_INFINITY), upper.push(a.max(b))),
                    2 => (lower.push(a.min(b)), upper.push(f64::INFINITY)),
                    _ => (lower.push(a.min(b)), upper.push(a.max(b))),
                };
            }
            let mut x: Vec<f64> = (0..n)
                .map(|i| {
                    let (l, u) = (lower[i].max(-2.0), upper[i].min(2.0));
                    l + rng.range(0.0, 1.0) * (u - l)
                })
                .collect();
            let before = energy(&rows, &x, &rhs);
            let slope = gradient(&rows, &x, &rhs);
            coarse.correct(&mut x, &slope, &lower, &upper).unwrap();
            assert!((0..n).all(|i| lower[i] <= x[i] && x[i] <= upper[i]));
            let after = energy(&rows, &x, &rhs);
            assert!(
                after <= before + 1e-12 * before.abs().max(1.0),
                "{before} -> {after}"
            );
        }
    }
}
