//! Preconditioned conjugate gradients, the one Krylov solver of the crate: the reduced systems
//! `A_FF y_F = r_F` of the damage step's box QP (5.2) and of its multigrid correction, and the
//! Newton systems of the friction problem of the velocity step (5.1).
//!
//! The solver is split from what it solves: a [`PcgSystem`] applies the operator and the
//! preconditioner (each caller restricts them to its free set, counts its own work and may fail
//! with its own error type), [`PcgVectors`] are the work vectors kept between solves, and
//! [`pcg`] is the iteration. The caller chooses the start: `solution` holds the initial guess and
//! `vectors.residual` the residual `b − A·solution` on entry, so a start from zero costs no
//! product and a start from a preconditioned right-hand side costs one.

use crate::algebra::linalg::{dot, max_abs};

/// The operator `A` (symmetric positive definite on the vectors the caller iterates on) and
/// the preconditioner `B ≈ A⁻¹` (symmetric positive definite, or nearly so with
/// [`BetaRule::PolakRibiere`]) of one solve.
pub trait PcgSystem {
    /// What applying the operator or the preconditioner can fail with.
    type Error;
    /// `image = A x`.
    fn apply(&mut self, x: &[f64], image: &mut [f64]) -> Result<(), Self::Error>;
    /// `z = B r`.
    fn precondition(&mut self, residual: &[f64], z: &mut [f64]) -> Result<(), Self::Error>;
}

/// How the next search direction `s ← z + β s` is conjugated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BetaRule {
    /// `β = (r_{k+1}·z_{k+1}) / (r_k·z_k)`, the classical choice for a fixed SPD preconditioner.
    FletcherReeves,
    /// `β = (r_{k+1}·(z_{k+1} − z_k)) / (r_k·z_k)`, the flexible choice: robust when the
    /// preconditioner is not exactly symmetric (a Gauss–Seidel sweep in one direction, a
    /// factor of a nearby matrix).
    PolakRibiere,
}

/// When [`pcg`] stops.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PcgSettings {
    /// Converged once the recursively updated residual has `‖r‖_∞ ≤ target`.
    pub target: f64,
    /// Iteration cap (products with `A` after the start).
    pub max_iterations: usize,
    pub beta: BetaRule,
}

/// Why [`pcg`] stopped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PcgStop {
    /// `‖r‖_∞ ≤ target` for the recursive residual (callers that need the true residual
    /// recompute it).
    Converged,
    /// `sᵀ A s ≤ 0` or `rᵀ z ≤ 0`, or one of them not finite: at the rounding level when the
    /// residual is tiny, a sign of an indefinite operator when `curvature < 0`.
    Breakdown { curvature: f64 },
    /// The iteration cap was reached first.
    IterationCap,
}

/// The outcome of one [`pcg`] solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PcgOutcome {
    pub stop: PcgStop,
    /// Products with `A` made after the start.
    pub iterations: usize,
}

/// Work vectors of [`pcg`], all of the system's dimension.
#[derive(Debug, Clone, Default)]
pub struct PcgVectors {
    /// `r = b − A x`: set by the caller on entry, updated recursively.
    pub residual: Vec<f64>,
    /// `z = B r`.
    pub preconditioned: Vec<f64>,
    /// The previous `z` (for [`BetaRule::PolakRibiere`]).
    pub previous: Vec<f64>,
    /// The search direction `s`.
    pub search: Vec<f64>,
    /// `A s`.
    pub image: Vec<f64>,
}

impl PcgVectors {
    /// Zero vectors of the given dimension.
    pub fn new(dimension: usize) -> Self {
        Self {
            residual: vec![0.0; dimension],
            preconditioned: vec![0.0; dimension],
            previous: vec![0.0; dimension],
            search: vec![0.0; dimension],
            image: vec![0.0; dimension],
        }
    }

    /// Zeroes every vector (as [`PcgVectors::new`] leaves them).
    pub fn fill_zero(&mut self) {
        for vector in [
            &mut self.residual,
            &mut self.preconditioned,
            &mut self.previous,
            &mut self.search,
            &mut self.image,
        ] {
            vector.fill(0.0);
        }
    }
}

/// Conjugate gradients for `A x = b` preconditioned with `B`: `solution` holds the start `x₀`
/// and `vectors.residual` the residual `b − A x₀` on entry (all vectors of `vectors` have the
/// length of `solution`); on return `solution` holds the last iterate and `vectors.residual` its
/// recursive residual. Stops as [`PcgStop`] says; errors only when the system's operator or
/// preconditioner does.
#[allow(clippy::needless_range_loop)] // componentwise kernels over several vectors
pub fn pcg<S: PcgSystem>(
    system: &mut S,
    solution: &mut [f64],
    vectors: &mut PcgVectors,
    settings: &PcgSettings,
) -> Result<PcgOutcome, S::Error> {
    let n = solution.len();
    let outcome = |stop, iterations| Ok(PcgOutcome { stop, iterations });
    if max_abs(&vectors.residual) <= settings.target {
        return outcome(PcgStop::Converged, 0);
    }
    system.precondition(&vectors.residual, &mut vectors.preconditioned)?;
    vectors.search.copy_from_slice(&vectors.preconditioned);
    let mut rho = dot(&vectors.residual, &vectors.preconditioned);
    for iteration in 1..=settings.max_iterations {
        system.apply(&vectors.search, &mut vectors.image)?;
        let curvature = dot(&vectors.search, &vectors.image);
        if !(curvature > 0.0 && rho > 0.0 && curvature.is_finite() && rho.is_finite()) {
            return outcome(PcgStop::Breakdown { curvature }, iteration);
        }
        let alpha = rho / curvature;
        for i in 0..n {
            solution[i] += alpha * vectors.search[i];
            vectors.residual[i] -= alpha * vectors.image[i];
        }
        if max_abs(&vectors.residual) <= settings.target {
            return outcome(PcgStop::Converged, iteration);
        }
        if settings.beta == BetaRule::PolakRibiere {
            vectors.previous.copy_from_slice(&vectors.preconditioned);
        }
        system.precondition(&vectors.residual, &mut vectors.preconditioned)?;
        let next_rho = dot(&vectors.residual, &vectors.preconditioned);
        let beta = match settings.beta {
            BetaRule::FletcherReeves => next_rho / rho,
            BetaRule::PolakRibiere => (next_rho - dot(&vectors.residual, &vectors.previous)) / rho,
        };
        rho = next_rho;
        for i in 0..n {
            vectors.search[i] = vectors.preconditioned[i] + beta * vectors.search[i];
        }
    }
    outcome(PcgStop::IterationCap, settings.max_iterations)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_random::SeededRandom as Generator;

    /// A dense SPD matrix with a diagonal (Jacobi) or identity preconditioner.
    struct Dense {
        matrix: Vec<Vec<f64>>,
        jacobi: bool,
        products: usize,
    }

    impl PcgSystem for Dense {
        type Error = std::convert::Infallible;
        fn apply(&mut self, x: &[f64], image: &mut [f64]) -> Result<(), Self::Error> {
            self.products += 1;
            for (row, value) in self.matrix.iter().zip(image.iter_mut()) {
                *value = dot(row, x);
            }
            Ok(())
        }
        fn precondition(&mut self, residual: &[f64], z: &mut [f64]) -> Result<(), Self::Error> {
            for i in 0..z.len() {
                z[i] = if self.jacobi {
                    residual[i] / self.matrix[i][i]
                } else {
                    residual[i]
                };
            }
            Ok(())
        }
    }

    /// `M Mᵀ + n I` for a random `M`, scaled by a wide diagonal.
    fn random_spd(n: usize, generator: &mut Generator) -> Vec<Vec<f64>> {
        let factor: Vec<Vec<f64>> = (0..n)
            .map(|_| (0..n).map(|_| generator.range(-1.0, 1.0)).collect())
            .collect();
        let scale: Vec<f64> = (0..n)
            .map(|i| 10f64.powf(3.0 * i as f64 / n as f64))
            .collect();
        (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| {
                        let product =
                            dot(&factor[i], &factor[j]) + if i == j { n as f64 } else { 0.0 };
                        product * scale[i].sqrt() * scale[j].sqrt()
                    })
                    .collect()
            })
            .collect()
    }

    fn solve(system: &mut Dense, rhs: &[f64], settings: &PcgSettings) -> (Vec<f64>, PcgOutcome) {
        let mut solution = vec![0.0; rhs.len()];
        let mut vectors = PcgVectors::new(rhs.len());
        vectors.residual.copy_from_slice(rhs);
        let outcome = pcg(system, &mut solution, &mut vectors, settings).unwrap();
        (solution, outcome)
    }

    #[test]
    fn pcg_converges_to_the_solution_with_either_beta_rule() {
        let mut generator = Generator::new(5);
        let n = 30;
        let matrix = random_spd(n, &mut generator);
        let rhs: Vec<f64> = (0..n).map(|_| generator.range(-1.0, 1.0)).collect();
        for beta in [BetaRule::FletcherReeves, BetaRule::PolakRibiere] {
            let mut system = Dense {
                matrix: matrix.clone(),
                jacobi: true,
                products: 0,
            };
            let settings = PcgSettings {
                target: 1e-12 * max_abs(&rhs),
                max_iterations: 10 * n,
                beta,
            };
            let (solution, outcome) = solve(&mut system, &rhs, &settings);
            assert_eq!(outcome.stop, PcgStop::Converged, "{beta:?}");
            assert_eq!(outcome.iterations, system.products);
            let residual: Vec<f64> = matrix
                .iter()
                .zip(&rhs)
                .map(|(row, b)| b - dot(row, &solution))
                .collect();
            // the true residual agrees with the recursive one up to rounding
            assert!(max_abs(&residual) <= 1e-10 * max_abs(&rhs), "{beta:?}");
        }
    }

    #[test]
    fn pcg_with_a_zero_residual_makes_no_product() {
        let mut generator = Generator::new(6);
        let mut system = Dense {
            matrix: random_spd(8, &mut generator),
            jacobi: false,
            products: 0,
        };
        let settings = PcgSettings {
            target: 0.0,
            max_iterations: 10,
            beta: BetaRule::FletcherReeves,
        };
        let (solution, outcome) = solve(&mut system, &[0.0; 8], &settings);
        assert_eq!(outcome.stop, PcgStop::Converged);
        assert_eq!((outcome.iterations, system.products), (0, 0));
        assert!(solution.iter().all(|x| *x == 0.0));
    }

    #[test]
    fn pcg_reports_the_iteration_cap() {
        // eigenvalues 1 … 1e8 and no preconditioner: far more than 5 iterations are needed
        let n = 40;
        let matrix = (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| {
                        if i == j {
                            10f64.powf(8.0 * i as f64 / (n - 1) as f64)
                        } else {
                            0.0
                        }
                    })
                    .collect()
            })
            .collect();
        let mut system = Dense {
            matrix,
            jacobi: false,
            products: 0,
        };
        let settings = PcgSettings {
            target: 1e-12,
            max_iterations: 5,
            beta: BetaRule::FletcherReeves,
        };
        let (_, outcome) = solve(&mut system, &vec![1.0; n], &settings);
        assert_eq!(outcome.stop, PcgStop::IterationCap);
        assert_eq!((outcome.iterations, system.products), (5, 5));
    }

    #[test]
    fn pcg_reports_negative_curvature() {
        let mut system = Dense {
            matrix: vec![vec![1.0, 0.0], vec![0.0, -1.0]],
            jacobi: false,
            products: 0,
        };
        let settings = PcgSettings {
            target: 1e-14,
            max_iterations: 10,
            beta: BetaRule::FletcherReeves,
        };
        let (_, outcome) = solve(&mut system, &[0.0, 1.0], &settings);
        assert_eq!(outcome.stop, PcgStop::Breakdown { curvature: -1.0 });
    }
}
