//! Exact solver for the condensed Tresca-friction problem of the velocity step (5.1).
//!
//! In the velocity step (5.1) the friction bound s = p_τ(u_{n−1,ν} − g) is known (the coupling is
//! explicit, see docs/model.md §3), so (5.1) is the minimization of a strongly convex quadratic
//! plus a weighted sum of Euclidean norms of the nodal tangential velocities on Γ3 (nodal
//! quadrature of the friction term j of (3.14), nodal tangent frames). After the interior
//! unknowns are condensed out (Schur complement), each step leaves the small dense problem
//!
//! ```text
//!     minimize J(x) = ½ xᵀ S x − rᵀ x + Σ_a w_a |x_a|,        x ∈ R^m, m = G · n_groups,
//! ```
//!
//! where x_a ∈ R^G is the a-th consecutive block of x (G = 1 in 2D: one tangential direction;
//! G = 2 in 3D: the tangential plane, |·| the Euclidean norm, i.e. the friction *disc*), S is
//! symmetric positive definite and w_a ≥ 0 (w_a = 0: no friction at that node, the block is
//! free). J is strongly convex, so the minimizer is unique and is characterized by the KKT system
//!
//! ```text
//!     S x − r + W λ = 0,   |λ_a| ≤ 1,   λ_a = x_a / |x_a| where x_a ≠ 0,
//! ```
//!
//! (W = diag(w_a I_G)). Groups are *stick* (x_a = 0, w_a > 0), *slip* (x_a ≠ 0, w_a > 0) and
//! *free* (w_a = 0). The friction traction at node a is −w_a λ_a.
//!
//! # KKT residual (what is reported)
//! With g = S x − r, σ = 1 / max_i S_ii and scale = max(‖r‖_∞, f64::MIN_POSITIVE):
//! - `natural` = ‖x − prox_{σW|·|}(x − σ g)‖_∞ / (σ · scale), where the prox is block
//!   soft-thresholding y_a ↦ max(0, 1 − σ w_a/|y_a|) y_a. It vanishes exactly at the minimizer.
//!   The factor σ makes it invariant under a common scaling of (S, r, w) and of (x, r, w); when
//!   max_i S_ii = 1 it is exactly ‖x − prox_{W|·|}(x − (S x − r))‖_∞ / max(‖r‖_∞, tiny).
//! - `stationarity` = ‖S x − r + W λ‖_∞ / scale with the multipliers λ that [`CondensedFriction::solve`]
//!   returns: λ_a = x_a/|x_a| on slip blocks, λ_a = 0 on free blocks, and on stick blocks the
//!   projection onto the unit ball of λ̂_a = (r − S x)_a / w_a (so the returned λ is always
//!   dual feasible, and the residual of stationarity carries any infeasibility of λ̂).
//! - `dual_infeasibility` = max over stick blocks of w_a (|λ̂_a| − 1)₊ / scale = (|g_a| − w_a)₊ /
//!   scale: the part of the stick-block stationarity residual due to projecting λ̂.
//!
//! The solver stops when the largest of the three is ≤ the tolerance. A tolerance below the
//! rounding level of evaluating S x (about ε κ(S) relative, ε the machine epsilon) cannot be met;
//! the solver then reports [`Error::NoConvergence`](crate::error::Error::NoConvergence) after a few cycles in which neither J nor the
//! residual improves (instead of exhausting the iteration budgets).
//!
//! # Method
//! **Semismooth Newton (primal–dual active set).** The minimizer is the zero of
//! F(x) = x − prox_{σW|·|}(x − σ(S x − r)). With y = x − σ g, a block is predicted *stick* when
//! |y_a| ≤ σ w_a (in the notation of Hintermüller–Stadler: z_a = λ_a + c x_a with c = 1/(σ w_a),
//! |z_a| ≤ 1), *free* when w_a = 0 and *slip* otherwise, with direction n_a = y_a/|y_a|. A Newton
//! step on F with a generalized Jacobian of the prox, multiplied through by the (invertible) slip
//! block of that Jacobian, is the *primal* system
//!
//! ```text
//!     x⁺_a = 0 on stick blocks,
//!     (S_NN + D) x⁺_N = r_N − (w n)_N        on the non-stick blocks N,
//!     D = blockdiag( w_a (I − n_a n_aᵀ) / (|y_a| − σ w_a) ) on slip blocks (0 on free blocks),
//! ```
//!
//! whose matrix is symmetric positive definite (S_NN is SPD, D is PSD; D = 0 when G = 1), solved
//! by a dense Cholesky factorization plus one step of iterative refinement. At the solution
//! |y_a| − σ w_a = |x_a|, so D is the curvature w_a (I − n nᵀ)/|x_a| of the norm.
//!
//! **Globalization by the merit function J.** A Newton point x⁺ is used only along the segment
//! x + t(x⁺ − x), t = 1, ½, ¼, …, with the Armijo condition J(x + t d) ≤ J(x) + η t J'(x; d)
//! (J'(x; d) is the one-sided directional derivative, so the test needs J'(x; d) < 0). Near the
//! solution the decrease of J falls below its rounding error; the full step is then accepted
//! when J does not increase by more than a rounding band *and* the KKT residual at least halves.
//! The full step is tried first, by both tests; a damped step (t < 1) must in addition lower J
//! by more than the rounding band, since at the rounding level the Armijo test accepts noise
//! and a damped step in place of a converging full one stalls Newton. A Newton step counts as
//! *progress* when the full step was accepted and the KKT residual at least halved; otherwise a burst of accelerated proximal-gradient steps (FISTA with step 1/L,
//! made monotone by an adaptive restart whenever J would increase) is taken from the current,
//! best, iterate and Newton is retried. L starts from a power-iteration estimate of λ_max(S) and
//! is doubled (backtracking on the descent lemma) up to the guaranteed bound
//! min(Gershgorin, Frobenius) ≥ λ_max(S).
//!
//! **Why this converges from any start.** Every accepted step keeps J non-increasing (up to the
//! rounding band). Either Newton stops making progress infinitely often: then infinitely many
//! bursts occur, and the first step of each burst is a plain proximal-gradient step, which for
//! the μ-strongly convex J contracts J − J* by at least the factor (1 − μ/L); since nothing in
//! between increases J, J → J* and, by strong convexity, x → x*. Or Newton makes progress at
//! every step from some point on: then the residual halves at every step and tends to 0. Near x*
//! the method is the semismooth Newton method, locally superlinear (quadratic); once the stick /
//! slip partition is identified (finitely many steps) the last Newton step in 2D (G = 1, D = 0)
//! is the exact solution of a linear system, and in 3D the remaining smooth system converges
//! quadratically. No smoothing or penalty enters the answer: stick blocks are exactly 0.
//!
//! References: G. Stadler, Semismooth Newton and augmented Lagrangian methods for a simplified
//! friction problem, SIAM J. Optim. 15 (2004); M. Hintermüller, G. Stadler, An infeasible
//! primal–dual algorithm for total bounded variation–based inf-convolution-type image
//! restoration, SIAM J. Sci. Comput. 28 (2006); A. Beck, M. Teboulle, FISTA (2009);
//! B. O'Donoghue, E. Candès, Adaptive restart for accelerated gradient schemes (2015).
//!
//! # Layout
//! `settings` (settings, KKT residual, statistics), `condensed` (the problem as given, its
//! validation and entry points), `objective` (the validated problem and J), `kkt` (the KKT
//! residual and the multipliers), `newton` (the semismooth Newton point), `newton_system` (its
//! reduced system: dense Cholesky factor and preconditioned CG), `blocks` (block norms and
//! soft-thresholding), `proximal_gradient` (FISTA bursts and the step size L) and `iteration`
//! (the globalized iteration that combines them).

mod blocks;
mod condensed;
mod iteration;
mod kkt;
mod newton;
mod newton_system;
mod objective;
mod proximal_gradient;
mod settings;

pub use condensed::{CondensedFriction, SYMMETRY_TOLERANCE};
pub use settings::{FrictionSettings, FrictionStats, KktResidual};

#[cfg(test)]
mod tests {
    use super::blocks::block_norm;
    use super::newton_system::{cholesky_solve, preconditioned_cg, NewtonCache, NewtonSystem};
    use super::objective::Problem;
    use super::*;
    use crate::algebra::linalg::max_abs;
    use crate::error::Error;
    use faer::prelude::*;
    use faer::Side;
    use proptest::prelude::*;

    use crate::test_random::SeededRandom as Generator;

    /// Test data from [`Generator`].
    trait Vectors {
        fn vector(&mut self, len: usize, amplitude: f64) -> Vec<f64>;
    }

    impl Vectors for Generator {
        fn vector(&mut self, len: usize, amplitude: f64) -> Vec<f64> {
            (0..len)
                .map(|_| self.range(-amplitude, amplitude))
                .collect()
        }
    }

    /// S = BᵀB + αI with B a dense random m × m matrix (not diagonal), α ∈ [0.2, 1.2).
    fn random_spd(m: usize, generator: &mut Generator) -> Mat<f64> {
        let shift = generator.range(0.2, 1.2);
        random_spd_with_shift(m, shift, generator)
    }

    /// S = BᵀB + shift · I with B a dense random m × m matrix, entries of size 1/√m.
    fn random_spd_with_shift(m: usize, shift: f64, generator: &mut Generator) -> Mat<f64> {
        let scaling = 1.0 / (m as f64).sqrt();
        let factor = Mat::from_fn(m, m, |_, _| generator.range(-1.0, 1.0) * scaling);
        let mut matrix = factor.transpose() * &factor;
        for i in 0..m {
            matrix[(i, i)] += shift;
        }
        matrix
    }

    #[derive(Clone, Copy, PartialEq, Debug)]
    enum Kind {
        Stick,
        Slip,
        Free,
    }

    /// A problem with known solution: pick x*, λ* consistent with the kinds, set r = S x* + W λ*.
    struct Manufactured {
        matrix: Mat<f64>,
        rhs: Vec<f64>,
        weights: Vec<f64>,
        solution: Vec<f64>,
        group: usize,
    }

    impl Manufactured {
        fn new(
            kinds: &[Kind],
            group: usize,
            weight_range: (f64, f64),
            generator: &mut Generator,
        ) -> Self {
            let m = kinds.len() * group;
            let matrix = random_spd(m, generator);
            let mut solution = vec![0.0; m];
            let mut multiplier = vec![0.0; m];
            let mut weights = vec![0.0; kinds.len()];
            for (a, kind) in kinds.iter().enumerate() {
                let range = a * group..(a + 1) * group;
                match kind {
                    Kind::Free => {
                        solution[range].copy_from_slice(&generator.vector(group, 2.0));
                    }
                    Kind::Slip => {
                        weights[a] = generator.range(weight_range.0, weight_range.1);
                        let block = loop {
                            let candidate = generator.vector(group, 2.0);
                            if block_norm(&candidate) > 0.5 {
                                break candidate;
                            }
                        };
                        let norm = block_norm(&block);
                        for (k, i) in range.enumerate() {
                            solution[i] = block[k];
                            multiplier[i] = block[k] / norm;
                        }
                    }
                    Kind::Stick => {
                        weights[a] = generator.range(weight_range.0, weight_range.1);
                        let block = generator.vector(group, 1.0);
                        let norm = block_norm(&block).max(1e-300);
                        let radius = generator.range(0.0, 0.9);
                        for (k, i) in range.enumerate() {
                            multiplier[i] = block[k] * radius.min(norm) / norm;
                        }
                    }
                }
            }
            let mut rhs = vec![0.0; m];
            for i in 0..m {
                let mut sum = 0.0;
                for j in 0..m {
                    sum += matrix[(i, j)] * solution[j];
                }
                rhs[i] = sum + weights[i / group] * multiplier[i];
            }
            Self {
                matrix,
                rhs,
                weights,
                solution,
                group,
            }
        }

        fn problem(&self) -> CondensedFriction<'_> {
            CondensedFriction {
                matrix: self.matrix.as_ref(),
                rhs: &self.rhs,
                weights: &self.weights,
                group_size: self.group,
            }
        }

        fn count(kinds: &[Kind], kind: Kind) -> usize {
            kinds.iter().filter(|&&k| k == kind).count()
        }

        /// Solves from `start` and checks KKT, the known solution and the group counts.
        fn check(&self, kinds: &[Kind], start: Vec<f64>) -> FrictionStats {
            let problem = self.problem();
            let mut x = start;
            let mut multipliers = vec![0.0; x.len()];
            let stats = problem
                .solve(&mut x, &mut multipliers, &FrictionSettings::default())
                .unwrap();
            assert_kkt(&problem, &x, &multipliers);
            let size = 1.0 + max_abs(&self.solution);
            for (computed, exact) in x.iter().zip(&self.solution) {
                assert!(
                    (computed - exact).abs() <= 1e-9 * size,
                    "solution {computed} differs from the manufactured {exact}"
                );
            }
            for (a, kind) in kinds.iter().enumerate() {
                if *kind == Kind::Stick {
                    assert!(x[a * self.group..(a + 1) * self.group]
                        .iter()
                        .all(|&v| v == 0.0));
                }
            }
            assert_eq!(stats.stick, Self::count(kinds, Kind::Stick));
            assert_eq!(stats.slip, Self::count(kinds, Kind::Slip));
            assert_eq!(stats.free, Self::count(kinds, Kind::Free));
            stats
        }
    }

    /// Independent check of the KKT system S x − r + W λ = 0, |λ_a| ≤ 1, λ_a = x_a/|x_a| on slip,
    /// computed with plain loops (not with the solver's helpers).
    fn assert_kkt(problem: &CondensedFriction<'_>, x: &[f64], multipliers: &[f64]) {
        let m = x.len();
        let group = problem.group_size;
        let scale = problem.rhs.iter().fold(0.0_f64, |acc, v| acc.max(v.abs()));
        for (i, multiplier) in multipliers.iter().enumerate() {
            let product: f64 = (0..m).map(|j| problem.matrix[(i, j)] * x[j]).sum();
            let stationarity = product - problem.rhs[i] + problem.weights[i / group] * multiplier;
            assert!(
                stationarity.abs() <= 1e-10 * scale,
                "stationarity residual {stationarity:e} at component {i} (scale {scale:e})"
            );
        }
        for (a, &w) in problem.weights.iter().enumerate() {
            let block = &x[a * group..(a + 1) * group];
            let lambda = &multipliers[a * group..(a + 1) * group];
            let lambda_norm = lambda.iter().map(|v| v * v).sum::<f64>().sqrt();
            assert!(lambda_norm <= 1.0 + 1e-12, "|λ_{a}| = {lambda_norm}");
            let norm = block.iter().map(|v| v * v).sum::<f64>().sqrt();
            if w > 0.0 && norm > 0.0 {
                for k in 0..group {
                    assert!(
                        (lambda[k] - block[k] / norm).abs() <= 1e-10,
                        "slip block {a}: λ = {lambda:?} is not x/|x| for x = {block:?}"
                    );
                }
            }
        }
    }

    fn random_kinds(groups: usize, generator: &mut Generator) -> Vec<Kind> {
        let mut kinds: Vec<Kind> = (0..groups)
            .map(|_| match generator.unit() {
                u if u < 0.4 => Kind::Stick,
                u if u < 0.9 => Kind::Slip,
                _ => Kind::Free,
            })
            .collect();
        kinds[0] = Kind::Stick;
        if groups > 1 {
            kinds[1] = Kind::Slip;
        }
        kinds
    }

    /// Random data over wide ranges: condition number of S up to ~10⁴, loads of size 10^±3,
    /// weights log-uniform over three decades (20 % free), starts of size up to 10⁶ · load.
    fn solve_random(group: usize, groups: usize, seed: u64) {
        let mut generator = Generator::new(seed);
        let m = group * groups;
        let shift = 10f64.powf(generator.range(-4.0, 0.0));
        let matrix = random_spd_with_shift(m, shift, &mut generator);
        let amplitude = 10f64.powf(generator.range(-3.0, 3.0));
        let rhs = generator.vector(m, amplitude);
        let weights: Vec<f64> = (0..groups)
            .map(|_| {
                if generator.unit() < 0.2 {
                    0.0
                } else {
                    amplitude * 10f64.powf(generator.range(-2.0, 1.0))
                }
            })
            .collect();
        let problem = CondensedFriction {
            matrix: matrix.as_ref(),
            rhs: &rhs,
            weights: &weights,
            group_size: group,
        };
        let start_amplitude = amplitude * 10f64.powf(generator.range(-2.0, 6.0));
        let mut x = generator.vector(m, start_amplitude);
        let mut multipliers = vec![0.0; m];
        let stats = problem
            .solve(&mut x, &mut multipliers, &FrictionSettings::default())
            .unwrap();
        assert_kkt(&problem, &x, &multipliers);
        assert!(stats.kkt_residual <= 1e-12);
        assert!(problem.kkt_report(&x).max() <= 1e-12);
        assert_eq!(stats.stick + stats.slip + stats.free, groups);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        #[test]
        fn friction_solver_satisfies_kkt_in_2d(groups in 1usize..=40, seed in any::<u64>()) {
            solve_random(1, groups, seed);
        }

        #[test]
        fn friction_solver_satisfies_kkt_in_3d(groups in 1usize..=40, seed in any::<u64>()) {
            solve_random(2, groups, seed);
        }

        #[test]
        fn mixed_stick_slip_free_solution_is_recovered(
            group in 1usize..=2, groups in 2usize..=40, seed in any::<u64>()
        ) {
            let mut generator = Generator::new(seed);
            let kinds = random_kinds(groups, &mut generator);
            let problem = Manufactured::new(&kinds, group, (0.5, 2.0), &mut generator);
            let stats = problem.check(&kinds, vec![0.0; group * groups]);
            prop_assert!(stats.stick > 0 && stats.slip > 0);
        }

        #[test]
        fn start_far_away_still_converges(
            group in 1usize..=2, groups in 2usize..=40, seed in any::<u64>()
        ) {
            let mut generator = Generator::new(seed);
            let kinds = random_kinds(groups, &mut generator);
            let problem = Manufactured::new(&kinds, group, (0.5, 2.0), &mut generator);
            let start = generator.vector(group * groups, 1e6);
            problem.check(&kinds, start);
        }

        #[test]
        fn all_slip_with_small_weights(
            group in 1usize..=2, groups in 1usize..=40, seed in any::<u64>()
        ) {
            let mut generator = Generator::new(seed);
            let kinds = vec![Kind::Slip; groups];
            let problem = Manufactured::new(&kinds, group, (1e-3, 1e-1), &mut generator);
            let stats = problem.check(&kinds, generator.vector(group * groups, 1.0));
            prop_assert_eq!(stats.slip, groups);
        }

        #[test]
        fn all_stick_when_weights_exceed_the_load(
            group in 1usize..=2, groups in 1usize..=40, seed in any::<u64>()
        ) {
            let mut generator = Generator::new(seed);
            let m = group * groups;
            let matrix = random_spd(m, &mut generator);
            let rhs = generator.vector(m, 5.0);
            // |r_a| < w_a: x = 0 with λ_a = r_a / w_a satisfies the KKT system.
            let weights: Vec<f64> = rhs
                .chunks_exact(group)
                .map(|block| block_norm(block) * generator.range(1.01, 3.0) + 0.01)
                .collect();
            let problem = CondensedFriction {
                matrix: matrix.as_ref(),
                rhs: &rhs,
                weights: &weights,
                group_size: group,
            };
            let mut x = generator.vector(m, 3.0);
            let mut multipliers = vec![0.0; m];
            let stats = problem
                .solve(&mut x, &mut multipliers, &FrictionSettings::default())
                .unwrap();
            prop_assert!(x.iter().all(|&v| v == 0.0));
            prop_assert_eq!(stats.stick, groups);
            assert_kkt(&problem, &x, &multipliers);
        }

        #[test]
        fn no_contact_is_the_linear_solve(
            group in 1usize..=2, groups in 1usize..=40, seed in any::<u64>()
        ) {
            let mut generator = Generator::new(seed);
            let m = group * groups;
            let matrix = random_spd(m, &mut generator);
            let rhs = generator.vector(m, 5.0);
            let weights = vec![0.0; groups];
            let problem = CondensedFriction {
                matrix: matrix.as_ref(),
                rhs: &rhs,
                weights: &weights,
                group_size: group,
            };
            let mut x = generator.vector(m, 3.0);
            let mut multipliers = vec![1.0; m];
            let stats = problem
                .solve(&mut x, &mut multipliers, &FrictionSettings::default())
                .unwrap();
            prop_assert_eq!(stats.free, groups);
            prop_assert!(multipliers.iter().all(|&v| v == 0.0));
            // Independent reference: LU with partial pivoting of the full matrix.
            let reference = matrix.partial_piv_lu().solve(Col::from_fn(m, |i| rhs[i]));
            for i in 0..m {
                prop_assert!((x[i] - reference[i]).abs() <= 1e-10 * (1.0 + reference[i].abs()));
            }
        }

        #[test]
        fn single_group_with_scalar_matrix_is_shrinkage(
            group in 1usize..=2,
            stiffness in 1e-3f64..1e3,
            weight in 0.0f64..10.0,
            load in prop::collection::vec(-10.0f64..10.0, 2),
        ) {
            // S = s I_G: x = max(0, 1 − w/|r|) r / s.
            let matrix = Mat::from_fn(group, group, |i, j| if i == j { stiffness } else { 0.0 });
            let rhs = &load[..group];
            let weights = [weight];
            let problem = CondensedFriction {
                matrix: matrix.as_ref(),
                rhs,
                weights: &weights,
                group_size: group,
            };
            let mut x = vec![1.0; group];
            let mut multipliers = vec![0.0; group];
            problem
                .solve(&mut x, &mut multipliers, &FrictionSettings::default())
                .unwrap();
            let norm = block_norm(rhs);
            let factor = if norm > weight { 1.0 - weight / norm } else { 0.0 };
            for k in 0..group {
                let exact = factor * rhs[k] / stiffness;
                prop_assert!((x[k] - exact).abs() <= 1e-12 * (norm / stiffness));
            }
        }
    }

    /// A Newton step whose full length converges is taken at full length: near the solution
    /// the Armijo test of a damped step compares values of J that differ by rounding only,
    /// and accepting such a damped step in place of the full one stalled Newton into a burst
    /// of proximal-gradient steps (about half of the solves below did so before the full step
    /// was tried first).
    #[test]
    fn newton_converges_without_gradient_steps_from_near_the_solution() {
        let mut bursts = Vec::new();
        for seed in 0..24 {
            let mut generator = Generator::new(100 + seed);
            let kinds: Vec<Kind> = (0..30)
                .map(|a| if a % 5 == 0 { Kind::Free } else { Kind::Slip })
                .collect();
            let manufactured = Manufactured::new(&kinds, 2, (0.5, 2.0), &mut generator);
            let start: Vec<f64> = manufactured
                .solution
                .iter()
                .map(|v| v + generator.range(-1e-3, 1e-3))
                .collect();
            let stats = manufactured.check(&kinds, start);
            if stats.gradient_iterations > 0 {
                bursts.push((seed, stats.newton_iterations, stats.gradient_iterations));
            }
        }
        assert!(
            bursts.is_empty(),
            "(seed, Newton, gradient steps): {bursts:?}"
        );
    }

    /// The Newton system as an operator, (S ṽ)_N + D v, and its factor in the cache's buffer
    /// agree with the assembled matrix A = S_NN + D (stick blocks removed, slip curvatures on
    /// their 2 × 2 blocks).
    #[test]
    fn newton_operator_and_factor_match_the_assembled_system() {
        let mut generator = Generator::new(5);
        let m = 24;
        let matrix = random_spd(m, &mut generator);
        let rhs = generator.vector(m, 1.0);
        let weights = vec![1.0; m / 2];
        let problem = Problem::new(matrix.as_ref(), &rhs, &weights, 2);
        // blocks 0..12: 2 and 7 stick; the others slip with a curvature
        let unknowns: Vec<usize> = (0..m).filter(|i| ![2, 7].contains(&(i / 2))).collect();
        let n = unknowns.len();
        let slip_curvature: Vec<(usize, [f64; 2], f64)> = (0..n / 2)
            .map(|b| {
                let angle = generator.range(0.0, 6.3);
                (2 * b, [angle.cos(), angle.sin()], generator.range(0.1, 3.0))
            })
            .collect();
        let system = NewtonSystem {
            unknowns: unknowns.clone(),
            slip_curvature: slip_curvature.clone(),
        };
        let mut assembled = Mat::from_fn(n, n, |i, j| matrix[(unknowns[i], unknowns[j])]);
        for &(position, direction, curvature) in &slip_curvature {
            for k in 0..2 {
                for l in 0..2 {
                    let identity = if k == l { 1.0 } else { 0.0 };
                    assembled[(position + k, position + l)] +=
                        curvature * (identity - direction[k] * direction[l]);
                }
            }
        }
        let v = Col::from_fn(n, |_| generator.range(-1.0, 1.0));
        let mut product = vec![0.0; n];
        problem.apply_newton(
            &system,
            &v.iter().copied().collect::<Vec<_>>(),
            &mut product,
        );
        let expected = &assembled * &v;
        let row_norm = (0..n)
            .map(|i| (0..n).map(|j| assembled[(i, j)].abs()).sum::<f64>())
            .fold(0.0, f64::max);
        for i in 0..n {
            assert!((product[i] - expected[i]).abs() <= 1e-14 * row_norm);
        }
        assert!((problem.newton_matrix_norm(&system) - row_norm).abs() <= 1e-14 * row_norm);
        let mut cache = NewtonCache::default();
        let factor = cache.factorize(matrix.as_ref(), &system).unwrap();
        let lower = Mat::from_fn(n, n, |i, j| if i >= j { factor[(i, j)] } else { 0.0 });
        let reconstructed = &lower * lower.transpose();
        for i in 0..n {
            for j in 0..n {
                assert!((reconstructed[(i, j)] - assembled[(i, j)]).abs() <= 1e-13 * row_norm);
            }
        }
        let mut solution: Vec<f64> = expected.iter().copied().collect();
        cholesky_solve(cache.factor_ref().unwrap(), &mut solution);
        for i in 0..n {
            assert!((solution[i] - v[i]).abs() <= 1e-11);
        }
    }

    #[test]
    fn newton_system_is_solved_with_the_factor_of_a_nearby_one() {
        let mut generator = Generator::new(11);
        let n = 40;
        let matrix = random_spd(n, &mut generator);
        // the previous Newton system: other slip curvatures on a few diagonal 2 × 2 blocks
        let mut nearby = matrix.clone();
        for block in [3, 7, 12] {
            for k in 0..2 {
                nearby[(2 * block + k, 2 * block + k)] += generator.range(0.0, 0.5);
            }
        }
        let factor = nearby.llt(Side::Lower).unwrap();
        let rhs = Col::from_fn(n, |_| generator.range(-1.0, 1.0));
        let norm_of_matrix = (0..n)
            .map(|i| (0..n).map(|j| matrix[(i, j)].abs()).sum::<f64>())
            .fold(0.0, f64::max);
        let apply = |v: &[f64], out: &mut [f64]| {
            ColMut::from_slice_mut(out).copy_from(&matrix * ColRef::from_slice(v))
        };
        let solution = preconditioned_cg(
            apply,
            factor.L(),
            norm_of_matrix,
            &rhs.iter().copied().collect::<Vec<_>>(),
        )
        .expect("a nearby factor preconditions to convergence");
        let solution = Col::from_fn(n, |i| solution[i]);
        let exact = matrix.llt(Side::Lower).unwrap().solve(&rhs);
        let residual = &rhs - &matrix * &solution;
        let norm = |v: &Col<f64>| v.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        assert!(norm(&residual) <= 1e-13 * norm(&rhs), "{}", norm(&residual));
        assert!(norm(&(&solution - &exact)) <= 1e-12 * norm(&exact));
    }

    #[test]
    fn newton_system_is_factorized_when_the_preconditioner_is_far_off() {
        // eigenvalues from 1 to 1e8, preconditioned with the identity: CG needs far more than
        // NEWTON_PCG_ITERATIONS iterations, so the caller factorizes instead
        let n = 60;
        let matrix = Mat::from_fn(n, n, |i, j| {
            if i == j {
                10f64.powf(8.0 * i as f64 / (n - 1) as f64)
            } else {
                0.0
            }
        });
        let identity = Mat::<f64>::identity(n, n);
        let rhs = Col::from_fn(n, |i| 1.0 + i as f64);
        let apply = |v: &[f64], out: &mut [f64]| {
            ColMut::from_slice_mut(out).copy_from(&matrix * ColRef::from_slice(v))
        };
        assert!(preconditioned_cg(
            apply,
            identity.as_ref(),
            1e8,
            &rhs.iter().copied().collect::<Vec<_>>()
        )
        .is_none());
    }

    #[test]
    fn proximal_gradient_alone_converges_exactly() {
        let mut generator = Generator::new(7);
        let kinds = random_kinds(20, &mut generator);
        let manufactured = Manufactured::new(&kinds, 2, (0.5, 2.0), &mut generator);
        let problem = manufactured.problem();
        let mut x = vec![0.0; 40];
        let mut multipliers = vec![0.0; 40];
        let settings = FrictionSettings {
            max_newton: 0,
            ..FrictionSettings::default()
        };
        let stats = problem.solve(&mut x, &mut multipliers, &settings).unwrap();
        assert_eq!(stats.newton_iterations, 0);
        assert!(stats.gradient_iterations > 0);
        assert_kkt(&problem, &x, &multipliers);
    }

    #[test]
    fn exhausted_budget_reports_no_convergence() {
        let mut generator = Generator::new(11);
        let kinds = random_kinds(10, &mut generator);
        let manufactured = Manufactured::new(&kinds, 1, (0.5, 2.0), &mut generator);
        let mut x = vec![0.0; 10];
        let mut multipliers = vec![0.0; 10];
        let settings = FrictionSettings {
            max_newton: 0,
            max_gradient: 2,
            ..FrictionSettings::default()
        };
        match manufactured
            .problem()
            .solve(&mut x, &mut multipliers, &settings)
        {
            Err(Error::NoConvergence { history, .. }) => assert!(!history.0.is_empty()),
            other => panic!("expected NoConvergence, got {other:?}"),
        }
    }

    #[test]
    fn solution_as_start_needs_no_iteration() {
        let mut generator = Generator::new(3);
        let kinds = random_kinds(15, &mut generator);
        let manufactured = Manufactured::new(&kinds, 1, (0.5, 2.0), &mut generator);
        let first = manufactured.check(&kinds, vec![0.0; 15]);
        assert!(first.newton_iterations > 0);
        let problem = manufactured.problem();
        let mut x = vec![0.0; 15];
        let mut multipliers = vec![0.0; 15];
        problem
            .solve(&mut x, &mut multipliers, &FrictionSettings::default())
            .unwrap();
        let again = problem
            .solve(&mut x, &mut multipliers, &FrictionSettings::default())
            .unwrap();
        assert_eq!(again.newton_iterations + again.gradient_iterations, 0);
    }

    #[test]
    fn zero_load_gives_zero_velocity() {
        let mut generator = Generator::new(5);
        let matrix = random_spd(6, &mut generator);
        let rhs = vec![0.0; 6];
        let weights = [1.0, 0.0, 2.0];
        let problem = CondensedFriction {
            matrix: matrix.as_ref(),
            rhs: &rhs,
            weights: &weights,
            group_size: 2,
        };
        let mut x = generator.vector(6, 1.0);
        let mut multipliers = vec![0.0; 6];
        problem
            .solve(&mut x, &mut multipliers, &FrictionSettings::default())
            .unwrap();
        assert!(x.iter().all(|&v| v == 0.0), "{x:?}");
    }

    #[test]
    fn empty_problem_is_solved_trivially() {
        let matrix = Mat::<f64>::zeros(0, 0);
        let problem = CondensedFriction {
            matrix: matrix.as_ref(),
            rhs: &[],
            weights: &[],
            group_size: 2,
        };
        let stats = problem
            .solve(&mut [], &mut [], &FrictionSettings::default())
            .unwrap();
        assert_eq!(stats.newton_iterations + stats.stick + stats.slip, 0);
    }

    #[test]
    fn slightly_asymmetric_matrix_is_used_through_its_symmetric_part() {
        let mut generator = Generator::new(9);
        let kinds = random_kinds(12, &mut generator);
        let mut manufactured = Manufactured::new(&kinds, 2, (0.5, 2.0), &mut generator);
        // Perturb antisymmetrically: the symmetric part (and so the solution) is unchanged.
        manufactured.matrix[(3, 1)] += 1e-13;
        manufactured.matrix[(1, 3)] -= 1e-13;
        manufactured.check(&kinds, vec![0.0; 24]);
    }

    #[test]
    fn objective_and_residual_vanish_where_expected() {
        let mut generator = Generator::new(13);
        let kinds = random_kinds(8, &mut generator);
        let manufactured = Manufactured::new(&kinds, 2, (0.5, 2.0), &mut generator);
        let problem = manufactured.problem();
        let at_solution = problem.kkt_residual(&manufactured.solution);
        assert!((0.0..=1e-13).contains(&at_solution), "{at_solution:e}");
        let report = problem.kkt_report(&[0.0; 16]);
        assert!(report.natural > 1e-3);
        assert_eq!(problem.kkt_residual(&[0.0; 16]), report.natural);
        // J at the solution is below J at nearby points (strict convexity).
        let best = problem.objective(&manufactured.solution);
        for _ in 0..10 {
            let nearby: Vec<f64> = manufactured
                .solution
                .iter()
                .map(|v| v + generator.range(-1e-3, 1e-3))
                .collect();
            assert!(problem.objective(&nearby) > best);
        }
    }

    fn small_problem_error(
        matrix: &Mat<f64>,
        rhs: &[f64],
        weights: &[f64],
        group_size: usize,
        start_len: usize,
    ) -> Error {
        let problem = CondensedFriction {
            matrix: matrix.as_ref(),
            rhs,
            weights,
            group_size,
        };
        let mut x = vec![0.0; start_len];
        let mut multipliers = vec![0.0; start_len];
        problem
            .solve(&mut x, &mut multipliers, &FrictionSettings::default())
            .unwrap_err()
    }

    fn identity(m: usize) -> Mat<f64> {
        Mat::from_fn(m, m, |i, j| if i == j { 1.0 } else { 0.0 })
    }

    #[test]
    fn friction_rejects_negative_weight() {
        let error = small_problem_error(&identity(3), &[1.0; 3], &[1.0, 0.5, -0.1], 1, 3);
        match error {
            Error::InvalidParameter { name, value, .. } => {
                assert_eq!(name, "weights[2]");
                assert_eq!(value, -0.1);
            }
            other => panic!("expected InvalidParameter, got {other}"),
        }
    }

    #[test]
    fn friction_rejects_size_mismatch() {
        // Matrix 3×3 for 2 groups of size 2.
        let error = small_problem_error(&identity(3), &[1.0; 4], &[1.0; 2], 2, 4);
        assert!(matches!(error, Error::InvalidInput(ref message) if message.contains("3×3")));
        // Right-hand side of the wrong length.
        let error = small_problem_error(&identity(4), &[1.0; 3], &[1.0; 2], 2, 4);
        assert!(matches!(error, Error::InvalidInput(ref message) if message.contains("length 3")));
        // Start vector of the wrong length.
        let error = small_problem_error(&identity(4), &[1.0; 4], &[1.0; 2], 2, 5);
        assert!(matches!(error, Error::InvalidInput(ref message) if message.contains("start")));
        // Unsupported group size.
        let error = small_problem_error(&identity(3), &[1.0; 3], &[1.0; 1], 3, 3);
        assert!(matches!(error, Error::InvalidParameter { ref name, .. } if name == "group_size"));
    }

    #[test]
    fn friction_rejects_non_finite_data() {
        let error = small_problem_error(&identity(2), &[1.0, f64::NAN], &[1.0; 2], 1, 2);
        assert!(matches!(error, Error::NonFinite(ref message) if message.contains("rhs[1]")));
        let mut matrix = identity(2);
        matrix[(1, 0)] = f64::INFINITY;
        let error = small_problem_error(&matrix, &[1.0; 2], &[1.0; 2], 1, 2);
        assert!(matches!(error, Error::NonFinite(ref message) if message.contains("(1, 0)")));
        let error = small_problem_error(&identity(2), &[1.0; 2], &[f64::NAN, 1.0], 1, 2);
        assert!(matches!(error, Error::InvalidParameter { ref name, .. } if name == "weights[0]"));
        let matrix = identity(2);
        let problem = CondensedFriction {
            matrix: matrix.as_ref(),
            rhs: &[1.0; 2],
            weights: &[1.0; 2],
            group_size: 1,
        };
        let error = problem
            .solve(
                &mut [0.0, f64::INFINITY],
                &mut [0.0; 2],
                &FrictionSettings::default(),
            )
            .unwrap_err();
        assert!(matches!(error, Error::NonFinite(ref message) if message.contains("x[1]")));
    }

    #[test]
    fn friction_rejects_matrices_that_are_not_spd() {
        let mut asymmetric = identity(3);
        asymmetric[(2, 0)] = 0.5;
        let error = small_problem_error(&asymmetric, &[1.0; 3], &[1.0; 3], 1, 3);
        assert!(matches!(error, Error::InvalidInput(ref message) if message.contains("symmetric")));
        let mut zero_diagonal = identity(3);
        zero_diagonal[(1, 1)] = 0.0;
        let error = small_problem_error(&zero_diagonal, &[1.0; 3], &[1.0; 3], 1, 3);
        assert!(matches!(error, Error::InvalidInput(ref message) if message.contains("(1, 1)")));
        // Symmetric, positive diagonal, indefinite: the Newton factorization reports it.
        let indefinite = Mat::from_fn(2, 2, |i, j| if i == j { 1.0 } else { 2.0 });
        let error = small_problem_error(&indefinite, &[1.0; 2], &[0.0; 2], 1, 2);
        assert!(matches!(error, Error::LinearAlgebra { .. }), "{error}");
    }

    #[test]
    #[should_panic(expected = "weights[0]")]
    fn objective_of_an_invalid_problem_panics_with_the_reason() {
        let matrix = identity(1);
        let problem = CondensedFriction {
            matrix: matrix.as_ref(),
            rhs: &[1.0],
            weights: &[-1.0],
            group_size: 1,
        };
        problem.objective(&[0.0]);
    }

    #[test]
    fn friction_rejects_bad_tolerance() {
        let matrix = identity(2);
        let problem = CondensedFriction {
            matrix: matrix.as_ref(),
            rhs: &[1.0; 2],
            weights: &[1.0; 2],
            group_size: 1,
        };
        let settings = FrictionSettings {
            tolerance: 0.0,
            ..FrictionSettings::default()
        };
        let error = problem
            .solve(&mut [0.0; 2], &mut [0.0; 2], &settings)
            .unwrap_err();
        assert!(matches!(error, Error::InvalidParameter { ref name, .. } if name == "tolerance"));
    }
}
