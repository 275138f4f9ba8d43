use super::kkt::{clamp, project, Problem};
use super::projected_gauss_seidel::{
    projected_gauss_seidel, residual_gradient, FineRows, SETTLED, STALE,
};
use super::solver::coarse_obstacle;
use super::*;
use crate::algebra::multigrid::tests::laplacian;
use crate::algebra::multigrid::{Csr, Hierarchy};
use crate::error::{Error, Result};
use crate::solvers::box_qp_coarse::tests::{energy, gradient, layer_problem, sparse};
use crate::solvers::box_qp_coarse::{diffusion_dominance, COARSE_TOLERANCE};
use faer::sparse::{SparseColMat, Triplet};
use proptest::prelude::*;

pub(super) type DenseMatrix = Vec<Vec<f64>>;

pub(super) use crate::test_random::SeededRandom as TestRng;

pub(super) fn sparse_from_dense(dense: &[Vec<f64>]) -> SparseColMat<usize, f64> {
    let n = dense.len();
    let mut triplets = Vec::new();
    for (i, row) in dense.iter().enumerate() {
        for (j, &value) in row.iter().enumerate() {
            if value != 0.0 || i == j {
                triplets.push(Triplet::new(i, j, value));
            }
        }
    }
    SparseColMat::try_new_from_triplets(n, n, &triplets).unwrap()
}

fn dense_times(dense: &[Vec<f64>], x: &[f64]) -> Vec<f64> {
    dense
        .iter()
        .map(|row| row.iter().zip(x).map(|(a, x)| a * x).sum())
        .collect()
}

/// Gaussian elimination without pivoting (fine for SPD matrices).
#[allow(clippy::needless_range_loop)]
fn dense_solve(dense: &[Vec<f64>], rhs: &[f64]) -> Vec<f64> {
    let n = rhs.len();
    let mut a: Vec<Vec<f64>> = dense.to_vec();
    let mut b = rhs.to_vec();
    for k in 0..n {
        for r in k + 1..n {
            let factor = a[r][k] / a[k][k];
            for c in k..n {
                a[r][c] -= factor * a[k][c];
            }
            b[r] -= factor * b[k];
        }
    }
    let mut x = vec![0.0; n];
    for k in (0..n).rev() {
        let tail: f64 = (k + 1..n).map(|c| a[k][c] * x[c]).sum();
        x[k] = (b[k] - tail) / a[k][k];
    }
    x
}

/// Natural KKT residual computed densely, independently of the solver module.
pub(super) fn dense_kkt_residual(
    dense: &[Vec<f64>],
    b: &[f64],
    lower: &[f64],
    upper: &[f64],
    x: &[f64],
) -> f64 {
    let ax = dense_times(dense, x);
    let scale = b.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
    let mut residual = 0.0_f64;
    for i in 0..x.len() {
        let g = ax[i] - b[i];
        let projected = (x[i] - g).max(lower[i]).min(upper[i]);
        residual = residual.max((x[i] - projected).abs());
    }
    residual / scale
}

pub(super) fn assert_within_bounds(x: &[f64], lower: &[f64], upper: &[f64]) {
    for i in 0..x.len() {
        assert!(
            lower[i] <= x[i] && x[i] <= upper[i],
            "x[{i}] = {} outside [{}, {}]",
            x[i],
            lower[i],
            upper[i]
        );
    }
}

/// A = BᵀB + shift·I with a random sparse B (about three entries per row, both signs), so
/// that A is SPD with off-diagonal entries of both signs (not an M-matrix).
pub(super) fn random_spd(n: usize, rng: &mut TestRng, shift: f64) -> Vec<Vec<f64>> {
    let mut b_matrix = vec![vec![0.0; n]; n];
    for row in b_matrix.iter_mut() {
        for _ in 0..3 {
            row[rng.index(n)] = rng.range(-1.0, 1.0);
        }
    }
    let mut a = vec![vec![0.0; n]; n];
    for i in 0..n {
        for j in 0..n {
            a[i][j] = (0..n).map(|k| b_matrix[k][i] * b_matrix[k][j]).sum();
        }
        a[i][i] += shift;
    }
    a
}

/// Random bounds per index: one-sided (either side), equal, or an interval of width up to 1.
pub(super) fn random_bounds(n: usize, rng: &mut TestRng) -> (Vec<f64>, Vec<f64>) {
    (0..n)
        .map(|_| {
            let a = rng.range(-1.0, 1.0);
            match rng.index(5) {
                0 => (a, f64::INFINITY),
                1 => (f64::NEG_INFINITY, a),
                2 => (a, a),
                _ => (a, a + rng.range(0.0, 1.0)),
            }
        })
        .unzip()
}

/// Consistent P1 mass and stiffness matrices of a uniform 1D grid on [0, 1].
fn fe_1d(nodes: usize) -> (DenseMatrix, DenseMatrix) {
    let h = 1.0 / (nodes - 1) as f64;
    let mut mass = vec![vec![0.0; nodes]; nodes];
    let mut stiffness = vec![vec![0.0; nodes]; nodes];
    for e in 0..nodes - 1 {
        for (a, i) in [e, e + 1].into_iter().enumerate() {
            for (b, j) in [e, e + 1].into_iter().enumerate() {
                mass[i][j] += h / 6.0 * if a == b { 2.0 } else { 1.0 };
                stiffness[i][j] += if a == b { 1.0 } else { -1.0 } / h;
            }
        }
    }
    (mass, stiffness)
}

/// Consistent P1 mass and stiffness matrices on the unit square, m×m vertices, each cell cut
/// into two triangles.
pub(super) fn fe_2d(m: usize) -> (DenseMatrix, DenseMatrix, Vec<[f64; 2]>) {
    let h = 1.0 / (m - 1) as f64;
    let n = m * m;
    let vertex = |ix: usize, iy: usize| iy * m + ix;
    let coords: Vec<[f64; 2]> = (0..n)
        .map(|v| [(v % m) as f64 * h, (v / m) as f64 * h])
        .collect();
    let mut mass = vec![vec![0.0; n]; n];
    let mut stiffness = vec![vec![0.0; n]; n];
    for iy in 0..m - 1 {
        for ix in 0..m - 1 {
            let triangles = [
                [vertex(ix, iy), vertex(ix + 1, iy), vertex(ix + 1, iy + 1)],
                [vertex(ix, iy), vertex(ix + 1, iy + 1), vertex(ix, iy + 1)],
            ];
            for tri in triangles {
                let p: Vec<[f64; 2]> = tri.iter().map(|&v| coords[v]).collect();
                let det = (p[1][0] - p[0][0]) * (p[2][1] - p[0][1])
                    - (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]);
                let area = 0.5 * det.abs();
                // gradients of the barycentric coordinates
                let grads: Vec<[f64; 2]> = (0..3)
                    .map(|a| {
                        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
                        [(p[b][1] - p[c][1]) / det, (p[c][0] - p[b][0]) / det]
                    })
                    .collect();
                for a in 0..3 {
                    for b in 0..3 {
                        mass[tri[a]][tri[b]] += area / 12.0 * if a == b { 2.0 } else { 1.0 };
                        stiffness[tri[a]][tri[b]] +=
                            area * (grads[a][0] * grads[b][0] + grads[a][1] * grads[b][1]);
                    }
                }
            }
        }
    }
    (mass, stiffness, coords)
}

/// A = M/k + κK.
pub(super) fn damage_matrix(
    mass: &[Vec<f64>],
    stiffness: &[Vec<f64>],
    time_step: f64,
    kappa: f64,
) -> Vec<Vec<f64>> {
    mass.iter()
        .zip(stiffness)
        .map(|(m, s)| {
            m.iter()
                .zip(s)
                .map(|(m, s)| m / time_step + kappa * s)
                .collect()
        })
        .collect()
}

/// b = M (β_prev/k + φ).
pub(super) fn damage_rhs(
    mass: &[Vec<f64>],
    previous: &[f64],
    source: &[f64],
    time_step: f64,
) -> Vec<f64> {
    let load: Vec<f64> = previous
        .iter()
        .zip(source)
        .map(|(b, f)| b / time_step + f)
        .collect();
    dense_times(mass, &load)
}

fn has_positive_off_diagonal(dense: &[Vec<f64>]) -> bool {
    (0..dense.len()).any(|i| (0..dense.len()).any(|j| i != j && dense[i][j] > 0.0))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn box_qp_satisfies_kkt_on_random_spd(
        n in 1usize..60,
        seed in any::<u64>(),
        shift in 0.01f64..1.0,
        bound_kind in 0usize..4,
    ) {
        let mut rng = TestRng::new(seed);
        let dense = random_spd(n, &mut rng, shift);
        let b: Vec<f64> = (0..n).map(|_| rng.range(-5.0, 5.0)).collect();
        let (lower, upper): (Vec<f64>, Vec<f64>) = match bound_kind {
            // nothing active: no bounds at all
            0 => (vec![f64::NEG_INFINITY; n], vec![f64::INFINITY; n]),
            // a tight box: both bounds active for most data
            1 => (vec![-0.2; n], vec![0.2; n]),
            // random bounds: one-sided, two-sided, equal, infinite
            2 => random_bounds(n, &mut rng),
            // wide finite box that no solution reaches
            _ => (vec![-1e6; n], vec![1e6; n]),
        };
        let start: Vec<f64> = (0..n).map(|_| rng.range(-2.0, 2.0)).collect();
        let matrix = sparse_from_dense(&dense);
        for (name, mut solver) in solver_variants(&matrix) {
            let mut x = start.clone();
            let stats = solver.solve(&b, &lower, &upper, &mut x).unwrap();

            assert_within_bounds(&x, &lower, &upper);
            let residual = box_qp_kkt_residual(&matrix, &b, &lower, &upper, &x);
            prop_assert!(residual <= 1e-10, "{name}: KKT residual {residual:e}, stats {stats:?}");
            let independent = dense_kkt_residual(&dense, &b, &lower, &upper, &x);
            prop_assert!(independent <= 1e-10, "{name}: dense KKT residual {independent:e}");
            prop_assert!(stats.kkt_residual <= 1e-12, "{name}: {stats:?}");
            if bound_kind == 0 || bound_kind == 3 {
                prop_assert_eq!(stats.lower_active + stats.upper_active, 0);
            }
        }
    }

    /// The sweeps skip the indices marked settled and the gradient is recomputed on the
    /// stale rows only: the iterates and gradients are those of sweeps that visit every
    /// index and of a gradient computed on every row.
    #[test]
    fn skipped_rows_are_rows_a_sweep_leaves_unchanged(
        n in 2usize..60,
        seed in any::<u64>(),
        shift in 0.01f64..1.0,
    ) {
        let mut rng = TestRng::new(seed);
        let dense = random_spd(n, &mut rng, shift);
        let b: Vec<f64> = (0..n).map(|_| rng.range(-5.0, 5.0)).collect();
        // index 0 and about a quarter of the others fixed (lower = upper), the rest in a
        // tight box
        let (lower, upper): (Vec<f64>, Vec<f64>) = (0..n)
            .map(|i| match (i, rng.index(4)) {
                (0, _) | (_, 0) => (-0.1, -0.1),
                _ => (-0.2, 0.2),
            })
            .unzip();
        let rows = Csr::from_symmetric(&sparse_from_dense(&dense));
        let fine = FineRows {
            lower_counts: rows.lower_counts(),
            inverse_diagonal: (0..n).map(|i| 1.0 / dense[i][i]).collect(),
            rows,
        };
        let problem = Problem { rhs: &b, lower: &lower, upper: &upper, scale: 1.0, tie: 0.0 };
        let start: Vec<f64> = (0..n)
            .map(|i| clamp(rng.range(-0.3, 0.3), lower[i], upper[i]))
            .collect();
        let (mut skipping, mut visiting) = (start.clone(), start);
        let mut marks = vec![STALE; n];
        let (mut gradient, mut full_gradient) = (vec![0.0; n], vec![0.0; n]);
        let mut skipped = 0;
        for sweep in 0..8 {
            let backward = sweep % 2 == 1;
            skipped += marks.iter().filter(|&&m| m & SETTLED != 0).count();
            projected_gauss_seidel(&fine, &problem, &mut skipping, backward, &mut marks);
            projected_gauss_seidel(&fine, &problem, &mut visiting, backward, &mut vec![STALE; n]);
            prop_assert_eq!(&skipping, &visiting, "sweep {}", sweep);
            residual_gradient(&fine.rows, &skipping, &b, &mut gradient, &mut marks);
            residual_gradient(&fine.rows, &visiting, &b, &mut full_gradient, &mut vec![STALE; n]);
            prop_assert_eq!(&gradient, &full_gradient, "sweep {}", sweep);
        }
        // the fixed indices (index 0 at least) are settled after their first visit, so
        // the later sweeps skip them
        prop_assert!(skipped > 0);
    }
}

/// A solve does not depend on the solves before it (the work vectors kept between calls
/// are reset as far as they are read): the second of two problems solved by one solver
/// gives bitwise the iterate, residual and iteration counts of a fresh solver.
#[test]
fn a_solve_does_not_depend_on_earlier_solves() {
    let (mass, stiffness, _) = fe_2d(12);
    let dense = damage_matrix(&mass, &stiffness, 0.01, 0.05);
    let matrix = sparse_from_dense(&dense);
    let n = dense.len();
    // The first problem has its solution on the lower bound everywhere; the next "time
    // step" pushes up a patch in the middle and starts from that solution, so a sweep
    // that skipped the indices settled in the first solve would not move at all.
    let first_b = vec![-1.0 / n as f64; n];
    let first_start = vec![0.5; n];
    let b: Vec<f64> = (0..n)
        .map(|i| if (60..70).contains(&i) { 3.0 } else { -1.0 } / n as f64)
        .collect();
    let (lower, upper) = (vec![0.0; n], vec![1.0; n]);
    for ((name, mut used), (_, mut fresh)) in solver_variants(&matrix)
        .into_iter()
        .zip(solver_variants(&matrix))
    {
        let mut first = first_start.clone();
        used.solve(&first_b, &lower, &upper, &mut first).unwrap();
        let start = first;
        let (mut again, mut once) = (start.clone(), start.clone());
        let again_stats = used.solve(&b, &lower, &upper, &mut again).unwrap();
        let once_stats = fresh.solve(&b, &lower, &upper, &mut once).unwrap();
        assert!(
            once_stats.lower_active + once_stats.upper_active > 0,
            "{name}"
        );
        assert_eq!(again, once, "{name}");
        // (not the factorizations: the factor of `A` is computed once per solver; nor the
        // truncations: a hierarchy keeps its last one, and a truncation recomputes its rows
        // from scratch)
        let counts = |stats: &BoxQpStats| {
            (
                stats.iterations,
                stats.inner_iterations,
                stats.coarse_iterations,
                stats.kkt_residual.to_bits(),
                stats.lower_active,
                stats.upper_active,
                stats.used_fallback,
            )
        };
        assert_eq!(counts(&again_stats), counts(&once_stats), "{name}");
    }
}

/// The row-parallel passes of the monotone multigrid (gradients, products, V-cycle
/// residuals and transfers) give bitwise the iterates of the sequential ones: a problem
/// large enough to be split into tasks, solved in a pool of one thread and of two.
#[test]
fn multigrid_solve_is_the_same_on_one_and_two_threads() {
    let m = 130; // 16 900 unknowns: at least two tasks of rows
    let matrix = crate::algebra::multigrid::tests::laplacian(m, 0.01);
    let n = m * m;
    // a source pushing a disc up to the upper bound, pulling the rest down to the lower
    let b: Vec<f64> = (0..n)
        .map(|i| {
            let (row, column) = ((i / m) as f64, (i % m) as f64);
            let r2 = (row - 60.0).powi(2) + (column - 70.0).powi(2);
            if r2 < 900.0 {
                0.5
            } else {
                -0.02
            }
        })
        .collect();
    let (lower, upper) = (vec![0.0; n], vec![1.0; n]);
    let solve = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut solver = BoxQpSolver::new(matrix.clone(), BoxQpSettings::default()).unwrap();
            let mut x = vec![0.5; n];
            let stats = solver.solve(&b, &lower, &upper, &mut x).unwrap();
            (x, stats)
        })
    };
    let (one, one_stats) = solve(1);
    let (two, two_stats) = solve(2);
    assert!(one_stats.lower_active > 0 && one_stats.upper_active > 0);
    assert!(one_stats.inner_iterations > 0);
    assert!(one
        .iter()
        .zip(&two)
        .all(|(a, b)| a.to_bits() == b.to_bits()));
    assert_eq!(
        (
            one_stats.iterations,
            one_stats.inner_iterations,
            one_stats.coarse_iterations
        ),
        (
            two_stats.iterations,
            two_stats.inner_iterations,
            two_stats.coarse_iterations
        )
    );
    assert_eq!(
        one_stats.kkt_residual.to_bits(),
        two_stats.kkt_residual.to_bits()
    );
}

/// The solver configurations every property test runs: the active set method, the
/// monotone multigrid as configured by default (one dense level for these sizes) and the
/// monotone multigrid on a hierarchy coarsened down to 4 unknowns (several levels).
fn solver_variants(matrix: &SparseColMat<usize, f64>) -> Vec<(&'static str, BoxQpSolver)> {
    let active_set = BoxQpSettings {
        method: BoxQpMethod::ActiveSet,
        ..BoxQpSettings::default()
    };
    let mut deep = BoxQpSolver::new(matrix.clone(), BoxQpSettings::default()).unwrap();
    if let Some((fine, hierarchy)) = deep.multigrid.as_mut() {
        *hierarchy = Hierarchy::with_coarsest_size(&fine.rows, 4);
    }
    vec![
        (
            "active set",
            BoxQpSolver::new(matrix.clone(), active_set).unwrap(),
        ),
        (
            "multigrid",
            BoxQpSolver::new(matrix.clone(), BoxQpSettings::default()).unwrap(),
        ),
        ("multigrid, deep", deep),
    ]
}

/// Settings of the active set method.
fn active_set() -> BoxQpSettings {
    BoxQpSettings {
        method: BoxQpMethod::ActiveSet,
        ..BoxQpSettings::default()
    }
}

#[test]
fn random_spd_generator_produces_non_m_matrices() {
    let mut rng = TestRng::new(7);
    let dense = random_spd(30, &mut rng, 0.1);
    assert!(has_positive_off_diagonal(&dense));
}

#[test]
fn damage_step_1d_activates_both_bounds_and_satisfies_kkt() {
    let nodes = 50;
    let (mass, stiffness) = fe_1d(nodes);
    let (time_step, kappa) = (0.01, 1e-3);
    let dense = damage_matrix(&mass, &stiffness, time_step, kappa);
    assert!(
        has_positive_off_diagonal(&dense),
        "test matrix should not be an M-matrix"
    );
    let previous = vec![0.5; nodes];
    let source: Vec<f64> = (0..nodes)
        .map(|i| match i * 3 / nodes {
            0 => 80.0,
            1 => 0.0,
            _ => -80.0,
        })
        .collect();
    let b = damage_rhs(&mass, &previous, &source, time_step);
    let (lower, upper) = (vec![0.0; nodes], vec![1.0; nodes]);
    let matrix = sparse_from_dense(&dense);
    let mut solver = BoxQpSolver::new(matrix.clone(), BoxQpSettings::default()).unwrap();
    let mut x = previous.clone();
    let stats = solver.solve(&b, &lower, &upper, &mut x).unwrap();
    assert!(
        stats.lower_active > 0 && stats.upper_active > 0,
        "{stats:?}"
    );
    assert!(stats.lower_active + stats.upper_active < nodes, "{stats:?}");
    assert_within_bounds(&x, &lower, &upper);
    assert!(box_qp_kkt_residual(&matrix, &b, &lower, &upper, &x) <= 1e-12);
    assert!(dense_kkt_residual(&dense, &b, &lower, &upper, &x) <= 1e-12);
}

#[test]
fn damage_step_2d_activates_both_bounds_and_satisfies_kkt() {
    let m = 7;
    let (mass, stiffness, coords) = fe_2d(m);
    let (time_step, kappa) = (0.01, 1e-3);
    let dense = damage_matrix(&mass, &stiffness, time_step, kappa);
    assert!(has_positive_off_diagonal(&dense));
    let n = m * m;
    let previous = vec![0.5; n];
    let source: Vec<f64> = coords
        .iter()
        .map(|p| {
            if p[0] < 0.34 {
                100.0
            } else if p[0] > 0.66 {
                -100.0
            } else {
                0.0
            }
        })
        .collect();
    let b = damage_rhs(&mass, &previous, &source, time_step);
    let (lower, upper) = (vec![0.0; n], vec![1.0; n]);
    let matrix = sparse_from_dense(&dense);
    let mut solver = BoxQpSolver::new(matrix.clone(), BoxQpSettings::default()).unwrap();
    let mut x = previous.clone();
    let stats = solver.solve(&b, &lower, &upper, &mut x).unwrap();
    assert!(
        stats.lower_active > 0 && stats.upper_active > 0,
        "{stats:?}"
    );
    assert_within_bounds(&x, &lower, &upper);
    assert!(dense_kkt_residual(&dense, &b, &lower, &upper, &x) <= 1e-12);
}

#[test]
fn unconstrained_box_qp_equals_linear_solve() {
    let m = 7;
    let (mass, stiffness, _) = fe_2d(m);
    let dense = damage_matrix(&mass, &stiffness, 0.01, 1e-3);
    let n = m * m;
    let mut rng = TestRng::new(3);
    let b: Vec<f64> = (0..n).map(|_| rng.range(-1.0, 1.0)).collect();
    let expected = dense_solve(&dense, &b);
    for (lower, upper) in [
        (vec![f64::NEG_INFINITY; n], vec![f64::INFINITY; n]),
        (vec![-1e3; n], vec![1e3; n]),
    ] {
        for (name, mut solver) in solver_variants(&sparse_from_dense(&dense)) {
            let mut x = vec![0.0; n];
            let stats = solver.solve(&b, &lower, &upper, &mut x).unwrap();
            assert_eq!((stats.lower_active, stats.upper_active), (0, 0));
            if name == "active set" {
                assert_eq!((stats.iterations, stats.factorizations), (1, 1));
            } else {
                // Nothing on a bound: one smoothing sweep and one linear multigrid correction
                // per iteration, which converges linearly.
                assert_eq!(stats.factorizations, 0);
                assert!(stats.iterations <= 10, "{name}: {stats:?}");
            }
            assert!(!stats.used_fallback);
            let norm = expected.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            for i in 0..n {
                assert!(
                    (x[i] - expected[i]).abs() <= 1e-12 * norm,
                    "{name}: x[{i}] = {} vs {}",
                    x[i],
                    expected[i]
                );
            }
        }
    }
}

#[test]
fn all_active_box_qp_returns_the_bounds_exactly() {
    let nodes = 40;
    let (mass, stiffness) = fe_1d(nodes);
    let (time_step, kappa) = (0.01, 1e-3);
    let dense = damage_matrix(&mass, &stiffness, time_step, kappa);
    // K·1 = 0, so the unconstrained solution of A x = 10⁴ M 1 is x = 10⁴ k = 100 > 1.
    let b = dense_times(&mass, &vec![1e4; nodes]);
    let (lower, upper) = (vec![0.0; nodes], vec![1.0; nodes]);
    let mut solver = BoxQpSolver::new(sparse_from_dense(&dense), BoxQpSettings::default()).unwrap();
    let mut x = vec![0.3; nodes];
    let stats = solver.solve(&b, &lower, &upper, &mut x).unwrap();
    assert_eq!(stats.upper_active, nodes);
    assert_eq!(stats.lower_active, 0);
    assert!(x.iter().all(|&v| v == 1.0));
    assert!(stats.kkt_residual <= 1e-12);

    // Equal bounds fix every variable, whatever the data.
    let fixed: Vec<f64> = (0..nodes).map(|i| (i as f64 * 0.37).sin()).collect();
    let mut x = vec![0.0; nodes];
    let stats = solver.solve(&b, &fixed, &fixed, &mut x).unwrap();
    assert_eq!(x, fixed);
    assert_eq!((stats.lower_active, stats.upper_active), (nodes, 0));
    assert_eq!(stats.kkt_residual, 0.0);
}

#[test]
fn the_matrix_is_factorized_once_per_solver() {
    let nodes = 50;
    let (mass, stiffness) = fe_1d(nodes);
    let (time_step, kappa) = (0.01, 1e-3);
    let dense = damage_matrix(&mass, &stiffness, time_step, kappa);
    let previous = vec![0.5; nodes];
    let source: Vec<f64> = (0..nodes)
        .map(|i| match i * 3 / nodes {
            0 => 80.0,
            1 => 0.0,
            _ => -80.0,
        })
        .collect();
    let b = damage_rhs(&mass, &previous, &source, time_step);
    let (lower, upper) = (vec![0.0; nodes], vec![1.0; nodes]);
    let mut solver = BoxQpSolver::new(sparse_from_dense(&dense), active_set()).unwrap();
    let mut x = previous.clone();
    let first = solver.solve(&b, &lower, &upper, &mut x).unwrap();
    assert_eq!(first.factorizations, 1, "{first:?}");

    // Same data from the solution: nothing to do.
    let second = solver.solve(&b, &lower, &upper, &mut x).unwrap();
    assert_eq!(second.factorizations, 0, "{second:?}");

    // Slightly different data with the same active set: still no factorization.
    let perturbed: Vec<f64> = b.iter().map(|v| v * (1.0 + 1e-6)).collect();
    let third = solver.solve(&perturbed, &lower, &upper, &mut x).unwrap();
    assert_eq!(third.factorizations, 0, "{third:?}");
    assert!(third.iterations >= 1);
    assert_eq!(
        (third.lower_active, third.upper_active),
        (first.lower_active, first.upper_active)
    );
    assert!(third.kkt_residual <= 1e-12);
}

/// β_prev = 1 without a source on the left half: there x* = 1 with g* = 0 (degenerate), so
/// the sign of g is rounding noise; the iteration must still stop quickly, without fallback.
#[test]
fn degenerate_plateau_at_the_upper_bound_converges_quickly() {
    let nodes = 60;
    let (mass, stiffness) = fe_1d(nodes);
    let (time_step, kappa) = (0.01, 1e-3);
    let dense = damage_matrix(&mass, &stiffness, time_step, kappa);
    let previous: Vec<f64> = (0..nodes)
        .map(|i| if i < nodes / 2 { 1.0 } else { 0.5 })
        .collect();
    let source: Vec<f64> = (0..nodes)
        .map(|i| if i < 2 * nodes / 3 { 0.0 } else { -80.0 })
        .collect();
    let b = damage_rhs(&mass, &previous, &source, time_step);
    let (lower, upper) = (vec![0.0; nodes], vec![1.0; nodes]);
    let mut solver = BoxQpSolver::new(sparse_from_dense(&dense), BoxQpSettings::default()).unwrap();
    let mut x = previous.clone();
    let stats = solver.solve(&b, &lower, &upper, &mut x).unwrap();
    assert!(!stats.used_fallback && stats.iterations <= 4, "{stats:?}");
    assert!(stats.lower_active > 0, "{stats:?}");
    assert!(dense_kkt_residual(&dense, &b, &lower, &upper, &x) <= 1e-12);
    // The plateau stays at 1 up to rounding.
    assert!(
        x[..nodes / 4].iter().all(|&v| (v - 1.0).abs() <= 1e-13),
        "{x:?}"
    );
}

/// A 3×3 SPD (not M-) matrix for which plain PDAS for `x ≥ 0` has the 3-cycle
/// {1} → {0,1,2} → {2} → {1} of active sets (found by a search; checked in exact rational
/// arithmetic: every decision has a margin of at least 1/60). The solution is (11/30, 0, 0).
fn cycling_example() -> (Vec<Vec<f64>>, Vec<f64>) {
    let dense = vec![
        vec![30.0, 21.0, -19.0],
        vec![21.0, 19.0, -9.0],
        vec![-19.0, -9.0, 22.0],
    ];
    (dense, vec![11.0, 1.0, -13.0])
}

/// One plain PDAS step for `x ≥ 0` (c = 1), dense and independent of the solver.
fn plain_pdas_step(dense: &[Vec<f64>], b: &[f64], active: &[bool]) -> Vec<bool> {
    let n = b.len();
    let free: Vec<usize> = (0..n).filter(|&i| !active[i]).collect();
    let reduced: Vec<Vec<f64>> = free
        .iter()
        .map(|&i| free.iter().map(|&j| dense[i][j]).collect())
        .collect();
    let reduced_rhs: Vec<f64> = free.iter().map(|&i| b[i]).collect();
    let solution = dense_solve(&reduced, &reduced_rhs);
    let mut x = vec![0.0; n];
    for (k, &i) in free.iter().enumerate() {
        x[i] = solution[k];
    }
    let ax = dense_times(dense, &x);
    (0..n).map(|i| x[i] - (ax[i] - b[i]) < 0.0).collect()
}

#[test]
fn plain_pdas_cycles_on_the_example() {
    let (dense, b) = cycling_example();
    let cycle = [
        vec![false, true, false],
        vec![true, true, true],
        vec![false, false, true],
    ];
    for k in 0..3 {
        assert_eq!(plain_pdas_step(&dense, &b, &cycle[k]), cycle[(k + 1) % 3]);
    }
}

#[test]
fn box_qp_converges_with_fallback_where_plain_pdas_cycles() {
    let (dense, b) = cycling_example();
    let (lower, upper) = (vec![0.0; 3], vec![f64::INFINITY; 3]);
    let mut solver = BoxQpSolver::new(sparse_from_dense(&dense), active_set()).unwrap();
    let mut x = vec![0.0; 3];
    let stats = solver.solve(&b, &lower, &upper, &mut x).unwrap();
    assert!(stats.used_fallback, "{stats:?}");
    assert!(stats.kkt_residual <= 1e-12);
    assert_eq!((stats.lower_active, stats.upper_active), (2, 0));
    assert!((x[0] - 11.0 / 30.0).abs() <= 1e-15, "{x:?}");
    assert_eq!(&x[1..], &[0.0, 0.0]);
}

#[test]
fn monotone_multigrid_solves_the_pdas_cycling_example() {
    let (dense, b) = cycling_example();
    let (lower, upper) = (vec![0.0; 3], vec![f64::INFINITY; 3]);
    for (name, mut solver) in solver_variants(&sparse_from_dense(&dense))
        .into_iter()
        .skip(1)
    {
        let mut x = vec![0.0; 3];
        let stats = solver.solve(&b, &lower, &upper, &mut x).unwrap();
        assert!(stats.kkt_residual <= 1e-12, "{name}: {stats:?}");
        assert_eq!((stats.lower_active, stats.upper_active), (2, 0), "{name}");
        assert!((x[0] - 11.0 / 30.0).abs() <= 1e-15, "{name}: {x:?}");
        assert_eq!(&x[1..], &[0.0, 0.0], "{name}");
    }
}

/// The monotone multigrid never increases q = ½xᵀAx − bᵀx (projected Gauss–Seidel and a
/// line search on a projected correction), checked iteration by iteration through the
/// iteration cap, on a 2D damage matrix with a four-level hierarchy.
#[test]
fn monotone_multigrid_decreases_the_energy_at_every_iteration() {
    let m = 24;
    let (mass, stiffness, coords) = fe_2d(m);
    let (time_step, kappa) = (0.01, 1e-2);
    let dense = damage_matrix(&mass, &stiffness, time_step, kappa);
    let previous: Vec<f64> = coords
        .iter()
        .map(|p| 0.5 + 0.5 * (6.0 * p[0]).sin())
        .collect();
    let source: Vec<f64> = coords
        .iter()
        .map(|p| if p[1] < 0.5 { 150.0 } else { -150.0 })
        .collect();
    let b = damage_rhs(&mass, &previous, &source, time_step);
    let n = m * m;
    let (lower, upper) = (vec![0.0; n], vec![1.0; n]);
    let matrix = sparse_from_dense(&dense);
    let energy = |x: &[f64]| {
        let ax = dense_times(&dense, x);
        (0..n)
            .map(|i| 0.5 * x[i] * ax[i] - b[i] * x[i])
            .sum::<f64>()
    };
    let mut x = previous.clone();
    project(&mut x, &lower, &upper);
    let mut last = energy(&x);
    let mut converged = false;
    for _ in 0..40 {
        let settings = BoxQpSettings {
            max_iterations: 1,
            ..BoxQpSettings::default()
        };
        let mut solver = BoxQpSolver::new(matrix.clone(), settings).unwrap();
        if let Some((fine, hierarchy)) = solver.multigrid.as_mut() {
            *hierarchy = Hierarchy::with_coarsest_size(&fine.rows, 8);
            assert!(hierarchy.sizes().len() >= 3, "{:?}", hierarchy.sizes());
        }
        let result = solver.solve(&b, &lower, &upper, &mut x);
        assert_within_bounds(&x, &lower, &upper);
        let now = energy(&x);
        assert!(
            now <= last + 1e-14 * last.abs(),
            "energy rose from {last} to {now}"
        );
        last = now;
        if let Ok(stats) = result {
            assert!(stats.kkt_residual <= 1e-12);
            converged = true;
            break;
        }
    }
    assert!(converged, "no convergence in 40 single iterations");
    assert!(dense_kkt_residual(&dense, &b, &lower, &upper, &x) <= 1e-12);
}

#[test]
fn box_qp_reports_no_convergence_with_history() {
    let (dense, b) = cycling_example();
    let settings = BoxQpSettings {
        tolerance: 1e-12,
        max_iterations: 2,
        ..active_set()
    };
    let mut solver = BoxQpSolver::new(sparse_from_dense(&dense), settings).unwrap();
    let mut x = vec![0.0; 3];
    match solver.solve(&b, &[0.0; 3], &[f64::INFINITY; 3], &mut x) {
        Err(Error::NoConvergence {
            iterations,
            history,
            ..
        }) => {
            assert_eq!(iterations, 2);
            assert!(history.0.len() >= 2);
        }
        other => panic!("expected NoConvergence, got {other:?}"),
    }
    assert_within_bounds(&x, &[0.0; 3], &[f64::INFINITY; 3]);
}

#[test]
fn box_qp_rejects_crossed_bounds() {
    let (dense, b) = cycling_example();
    let mut solver = BoxQpSolver::new(sparse_from_dense(&dense), BoxQpSettings::default()).unwrap();
    let mut x = vec![0.0; 3];
    let err = solver
        .solve(&b, &[0.0, 1.0, 0.0], &[1.0, 0.5, 1.0], &mut x)
        .unwrap_err();
    assert!(
        matches!(&err, Error::InvalidInput(message) if message.contains("index 1")),
        "{err}"
    );
}

#[test]
fn box_qp_rejects_length_mismatch_and_non_finite_data() {
    let (dense, b) = cycling_example();
    let mut solver = BoxQpSolver::new(sparse_from_dense(&dense), BoxQpSettings::default()).unwrap();
    let mut x = vec![0.0; 3];
    let err = solver
        .solve(&b[..2], &[0.0; 3], &[1.0; 3], &mut x)
        .unwrap_err();
    assert!(
        matches!(&err, Error::InvalidInput(message) if message.contains("`rhs`")),
        "{err}"
    );
    let mut short = vec![0.0; 2];
    let err = solver
        .solve(&b, &[0.0; 3], &[1.0; 3], &mut short)
        .unwrap_err();
    assert!(
        matches!(&err, Error::InvalidInput(message) if message.contains("`x`")),
        "{err}"
    );
    let err = solver
        .solve(&[1.0, f64::NAN, 0.0], &[0.0; 3], &[1.0; 3], &mut x)
        .unwrap_err();
    assert!(
        matches!(&err, Error::NonFinite(message) if message.contains("rhs[1]")),
        "{err}"
    );
    let err = solver
        .solve(&b, &[0.0, 0.0, f64::INFINITY], &[f64::INFINITY; 3], &mut x)
        .unwrap_err();
    assert!(
        matches!(&err, Error::InvalidInput(message) if message.contains("index 2")),
        "{err}"
    );
    assert_eq!(
        box_qp_kkt_residual(solver.matrix(), &b[..2], &[0.0; 3], &[1.0; 3], &x),
        f64::INFINITY
    );
}

#[test]
fn box_qp_rejects_non_symmetric_pattern() {
    let triplets = [
        Triplet::new(0, 0, 2.0),
        Triplet::new(1, 1, 2.0),
        Triplet::new(0, 1, 0.5),
    ];
    let matrix = SparseColMat::try_new_from_triplets(2, 2, &triplets).unwrap();
    let err = BoxQpSolver::new(matrix, BoxQpSettings::default()).unwrap_err();
    assert!(
        matches!(&err, Error::InvalidInput(message) if message.contains("pattern is not symmetric")),
        "{err}"
    );

    let matrix = sparse_from_dense(&[vec![2.0, 0.5], vec![0.7, 2.0]]);
    let err = BoxQpSolver::new(matrix, BoxQpSettings::default()).unwrap_err();
    assert!(
        matches!(&err, Error::InvalidInput(message) if message.contains("not symmetric")),
        "{err}"
    );
}

#[test]
fn box_qp_rejects_non_positive_diagonal_and_bad_shapes() {
    let matrix = sparse_from_dense(&[vec![2.0, 0.5], vec![0.5, 0.0]]);
    let err = BoxQpSolver::new(matrix, BoxQpSettings::default()).unwrap_err();
    assert!(
        matches!(&err, Error::InvalidInput(message) if message.contains("A[1,1]")),
        "{err}"
    );

    let rectangular =
        SparseColMat::<usize, f64>::try_new_from_triplets(2, 3, &[Triplet::new(0, 0, 1.0)])
            .unwrap();
    let err = BoxQpSolver::new(rectangular, BoxQpSettings::default()).unwrap_err();
    assert!(matches!(err, Error::InvalidInput(_)), "{err}");

    let matrix = sparse_from_dense(&[vec![2.0]]);
    let settings = BoxQpSettings {
        tolerance: 0.0,
        max_iterations: 10,
        ..Default::default()
    };
    assert!(matches!(
        BoxQpSolver::new(matrix, settings),
        Err(Error::InvalidParameter { .. })
    ));
}

#[test]
fn indefinite_matrix_is_reported_by_the_factorization() {
    let matrix = sparse_from_dense(&[vec![1.0, 2.0], vec![2.0, 1.0]]);
    for (name, mut solver) in solver_variants(&matrix) {
        let err = unbounded_solve(&mut solver, &[1.0, 1.0]).unwrap_err();
        assert!(matches!(err, Error::LinearAlgebra { .. }), "{name}: {err}");
    }
}

/// Solves without bounds (a linear solve) from zero.
fn unbounded_solve(solver: &mut BoxQpSolver, b: &[f64]) -> Result<BoxQpStats> {
    let n = b.len();
    let mut x = vec![0.0; n];
    solver.solve(
        b,
        &vec![f64::NEG_INFINITY; n],
        &vec![f64::INFINITY; n],
        &mut x,
    )
}

/// An indefinite matrix on a multilevel hierarchy: a 2D Laplacian shifted by −0.5 has
/// negative eigenvalues; the multigrid reports negative curvature instead of diverging.
#[test]
fn indefinite_matrix_is_reported_by_the_multigrid() {
    let m = 20;
    let (_, stiffness, _) = fe_2d(m);
    let n = m * m;
    let mut dense = stiffness.clone();
    for (i, row) in dense.iter_mut().enumerate() {
        row[i] -= 0.5;
    }
    let matrix = sparse_from_dense(&dense);
    let mut solver = BoxQpSolver::new(matrix, BoxQpSettings::default()).unwrap();
    if let Some((fine, hierarchy)) = solver.multigrid.as_mut() {
        *hierarchy = Hierarchy::with_coarsest_size(&fine.rows, 16);
    }
    let b: Vec<f64> = (0..n).map(|i| ((i * 37) % 11) as f64 - 5.0).collect();
    let err = unbounded_solve(&mut solver, &b).unwrap_err();
    assert!(matches!(err, Error::LinearAlgebra { .. }), "{err}");
}

#[test]
fn monotone_multigrid_reports_no_convergence_with_history() {
    let m = 20;
    let (mass, stiffness, coords) = fe_2d(m);
    let dense = damage_matrix(&mass, &stiffness, 0.01, 1e-2);
    let n = m * m;
    let source: Vec<f64> = coords.iter().map(|p| 200.0 * (p[0] - 0.5)).collect();
    let b = damage_rhs(&mass, &vec![0.5; n], &source, 0.01);
    let settings = BoxQpSettings {
        max_iterations: 1,
        ..BoxQpSettings::default()
    };
    let mut solver = BoxQpSolver::new(sparse_from_dense(&dense), settings).unwrap();
    let mut x = vec![0.5; n];
    match solver.solve(&b, &vec![0.0; n], &vec![1.0; n], &mut x) {
        Err(Error::NoConvergence {
            iterations,
            history,
            solver,
            ..
        }) => {
            assert_eq!(iterations, 1);
            assert!(history.0.len() >= 2, "{history:?}");
            assert!(solver.contains("multigrid"), "{solver}");
        }
        other => panic!("expected NoConvergence, got {other:?}"),
    }
    assert_within_bounds(&x, &vec![0.0; n], &vec![1.0; n]);
}

#[test]
fn unsorted_column_storage_is_normalized() {
    use faer::sparse::SymbolicSparseColMat;
    // [[2, 1], [1, 3]] with the rows of column 0 stored in reverse order.
    let symbolic =
        SymbolicSparseColMat::new_unsorted_checked(2, 2, vec![0, 2, 4], None, vec![1, 0, 0, 1]);
    let matrix = SparseColMat::new(symbolic, vec![1.0, 2.0, 1.0, 3.0]);
    let mut solver = BoxQpSolver::new(matrix, BoxQpSettings::default()).unwrap();
    let mut x = vec![0.0; 2];
    solver
        .solve(
            &[3.0, 4.0],
            &[f64::NEG_INFINITY; 2],
            &[f64::INFINITY; 2],
            &mut x,
        )
        .unwrap();
    assert!(
        (x[0] - 1.0).abs() < 1e-14 && (x[1] - 1.0).abs() < 1e-14,
        "{x:?}"
    );
}

// The coarse obstacle corrections with the box QP solver as their nested solver.

#[test]
fn only_large_diffusion_dominated_problems_get_a_coarse_correction() {
    let settings = BoxQpSettings::default();
    let dominated = Csr::from_symmetric(&laplacian(60, 0.01));
    assert!(diffusion_dominance(&dominated, &dominated.diagonal()) > 400.0);
    let coarse = coarse_obstacle(&dominated, &dominated.diagonal(), settings).unwrap();
    assert!(coarse.is_some_and(|c| c.coarse_size() < 3600 / 2));
    // Mass-dominated (a_ii / Σ_j a_ij ≈ 1): the layers are a cell wide.
    let mass = Csr::from_symmetric(&laplacian(60, 10.0));
    assert!(diffusion_dominance(&mass, &mass.diagonal()) < 2.0);
    assert!(coarse_obstacle(&mass, &mass.diagonal(), settings)
        .unwrap()
        .is_none());
    // Too small to pay.
    let small = Csr::from_symmetric(&laplacian(40, 0.01));
    assert!(coarse_obstacle(&small, &small.diagonal(), settings)
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
    let mut coarse = coarse_obstacle(&rows, &rows.diagonal(), settings)
        .unwrap()
        .unwrap();
    let mut x = vec![1.0; n];
    let start = energy(&rows, &x, &rhs);
    let slope = gradient(&rows, &x, &rhs);
    let tolerance = coarse.coarse_tolerance();
    coarse
        .correct(&mut x, &slope, &lower, &upper, tolerance)
        .unwrap();
    let corrected = energy(&rows, &x, &rhs);
    let mut solution = vec![1.0; n];
    BoxQpSolver::new(sparse(&rows), settings)
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
    let mut coarse = coarse_obstacle(&rows, &rows.diagonal(), BoxQpSettings::default())
        .unwrap()
        .unwrap();
    let mut rng = TestRng::new(7);
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
        let tolerance = coarse.coarse_tolerance();
        coarse
            .correct(&mut x, &slope, &lower, &upper, tolerance)
            .unwrap();
        assert!((0..n).all(|i| lower[i] <= x[i] && x[i] <= upper[i]));
        let after = energy(&rows, &x, &rhs);
        assert!(
            after <= before + 1e-12 * before.abs().max(1.0),
            "{before} -> {after}"
        );
    }
}

#[test]
fn below_the_coarse_tolerance_only_a_band_gets_a_correction() {
    let (rows, _) = layer_problem(60);
    let settings = BoxQpSettings::default();
    let coarse = coarse_obstacle(&rows, &rows.diagonal(), settings)
        .unwrap()
        .unwrap();
    let n = 3600;
    // √n = 60: a band is more than 12 indices
    let never = || -> usize { panic!("counted above the coarse tolerance") };
    assert_eq!(coarse.tolerance_at(1e-3, n, never), Some(COARSE_TOLERANCE));
    assert_eq!(coarse.tolerance_at(1e-8, n, || 12), None);
    assert_eq!(coarse.tolerance_at(1e-8, n, || 13), Some(1e-9));
    assert_eq!(
        coarse.tolerance_at(5e-12, n, || 1000),
        Some(settings.tolerance)
    );
    assert_eq!(coarse.tolerance_at(settings.tolerance, n, || 1000), None);
}

/// The layer problem scaled by s = 5e-8 (right-hand side and bounds: the solution scales
/// with them): from the upper bound everywhere the start residual, at most s, is below
/// the coarse tolerance, yet the right half and the layer must leave the bound. The band rule
/// lets the coarse corrections act; without it (no coarse correction below the coarse
/// tolerance) the fine iteration frees the band a few cells per iteration.
#[test]
fn a_band_left_below_the_coarse_tolerance_is_freed_by_coarse_corrections() {
    let m = 80;
    let (rows, rhs) = layer_problem(m);
    let n = m * m;
    let scale = 5e-8;
    let rhs: Vec<f64> = rhs.iter().map(|b| b * scale).collect();
    let (lower, upper) = (vec![0.0; n], vec![scale; n]);
    let mut solver = BoxQpSolver::new(sparse(&rows), BoxQpSettings::default()).unwrap();
    let mut x = upper.clone();
    let start = gradient(&rows, &x, &rhs);
    let start_residual = (0..n)
        .map(|i| (x[i] - (x[i] - start[i]).clamp(lower[i], upper[i])).abs())
        .fold(0.0_f64, f64::max);
    assert!(start_residual < COARSE_TOLERANCE, "{start_residual}");
    let stats = solver.solve(&rhs, &lower, &upper, &mut x).unwrap();
    // 4 fine iterations (8 coarse ones) with the rule, 9 without it
    assert!(stats.coarse_iterations > 0, "{stats:?}");
    assert!(stats.iterations <= 5, "{stats:?}");
}

/// The reduced CG of the active set method solves A_FF y_F = r_F to its target within its
/// iteration cap, on a free set that differs from the whole index set by a few indices (the
/// preconditioned operator is then the identity plus a term of rank ≤ |I|, so CG needs about
/// |I| + 1 steps; the cap is 2 min(|F|, |I| + 1) + 20), and within |I| + 2 preconditioner
/// applications. The right-hand side is scaled by 1e3 so
/// that ρ = rᵀz is far from 1 (β = ρ_{k+1}/ρ_k then differs from ρ_{k+1}).
#[test]
fn reduced_cg_solves_the_free_block_within_its_cap() {
    let matrix = crate::algebra::multigrid::tests::laplacian(10, 0.1);
    let n = matrix.nrows();
    let mut solver = BoxQpSolver::new(matrix.clone(), active_set()).unwrap();
    let fixed: Vec<bool> = (0..n).map(|i| (40..44).contains(&i)).collect();
    let mut rng = TestRng::new(17);
    let rhs: Vec<f64> = (0..n)
        .map(|i| {
            if fixed[i] {
                0.0
            } else {
                1e3 * rng.range(-1.0, 1.0)
            }
        })
        .collect();
    let target = 1e-10 * rhs.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut solution = vec![0.0; n];
    let mut work = super::workspace::Workspace::new(n);
    let mut stats = BoxQpStats::default();
    solver
        .reduced_cg(
            &fixed,
            &rhs,
            &mut solution,
            target,
            &mut work.cg,
            &mut stats,
        )
        .unwrap();
    let mut image = vec![0.0; n];
    crate::algebra::linalg::multiply_into(&matrix, &solution, &mut image);
    let worst = (0..n)
        .filter(|&i| !fixed[i])
        .map(|i| (image[i] - rhs[i]).abs())
        .fold(0.0f64, f64::max);
    assert!(
        worst <= 10.0 * target,
        "|A_FF y − r|_∞ = {worst:e} > 10 × target {target:e} after {} preconditioner applications",
        stats.inner_iterations
    );
    assert!((0..n).filter(|&i| fixed[i]).all(|i| solution[i] == 0.0));
    // |I| + 1 steps in exact arithmetic (one preconditioner application each), one more for
    // rounding
    let interface = fixed.iter().filter(|&&f| f).count();
    assert!(
        stats.inner_iterations <= interface + 2,
        "{} preconditioner applications for |I| = {interface}",
        stats.inner_iterations
    );
}

/// The bound set of a solution: where it lies on each bound.
pub(super) fn bound_set_of(x: &[f64], lower: &[f64], upper: &[f64]) -> Vec<BoundStatus> {
    x.iter()
        .zip(lower.iter().zip(upper))
        .map(|(&x, (&lower, &upper))| BoundStatus::of(x, lower, upper))
        .collect()
}

/// A 2D damage step with both bounds active ([`damage_step_2d_activates_both_bounds_and_satisfies_kkt`]'s).
fn two_bound_damage_step(m: usize) -> (DenseMatrix, Vec<f64>, Vec<f64>) {
    let (mass, stiffness, coords) = fe_2d(m);
    let (time_step, kappa) = (0.01, 1e-3);
    let dense = damage_matrix(&mass, &stiffness, time_step, kappa);
    let previous = vec![0.5; m * m];
    let source: Vec<f64> = coords
        .iter()
        .map(|p| 100.0 * (p[0] < 0.34) as u8 as f64 - 100.0 * (p[0] > 0.66) as u8 as f64)
        .collect();
    let b = damage_rhs(&mass, &previous, &source, time_step);
    (dense, b, previous)
}

#[test]
fn the_solution_bound_set_gives_the_solution_in_one_solve() {
    let (dense, b, start) = two_bound_damage_step(9);
    let n = b.len();
    let (lower, upper) = (vec![0.0; n], vec![1.0; n]);
    let matrix = sparse_from_dense(&dense);
    let mut solver = BoxQpSolver::new(matrix, BoxQpSettings::default()).unwrap();
    let mut solution = start.clone();
    let stats = solver.solve(&b, &lower, &upper, &mut solution).unwrap();
    assert!(
        stats.lower_active > 0 && stats.upper_active > 0,
        "{stats:?}"
    );
    let set = bound_set_of(&solution, &lower, &upper);
    for call in 0..2 {
        let mut x = start.clone();
        let stats = solver
            .solve_predicted(&b, &lower, &upper, &set, &mut x)
            .unwrap();
        assert!(stats.bound_set_solve, "{stats:?}");
        assert_eq!(stats.iterations, 1);
        // one factorization for the new set, none when it repeats
        assert_eq!(stats.factorizations, usize::from(call == 0));
        assert_within_bounds(&x, &lower, &upper);
        assert!(dense_kkt_residual(&dense, &b, &lower, &upper, &x) <= 1e-14);
        assert_eq!(bound_set_of(&x, &lower, &upper), set);
        for i in 0..n {
            assert!(
                (x[i] - solution[i]).abs() <= 1e-11,
                "x[{i}]: {} vs {}",
                x[i],
                solution[i]
            );
        }
    }
}

#[test]
fn a_wrong_bound_set_leaves_the_solve_as_without_prediction() {
    let (dense, b, start) = two_bound_damage_step(9);
    let n = b.len();
    let (lower, upper) = (vec![0.0; n], vec![1.0; n]);
    let matrix = sparse_from_dense(&dense);
    let mut plain = start.clone();
    let plain_stats = BoxQpSolver::new(matrix.clone(), BoxQpSettings::default())
        .unwrap()
        .solve(&b, &lower, &upper, &mut plain)
        .unwrap();
    // nothing on a bound, everything on the upper bound, every other index on the lower one
    for set in [
        vec![BoundStatus::Free; n],
        vec![BoundStatus::AtUpper; n],
        (0..n)
            .map(|i| [BoundStatus::AtLower, BoundStatus::Free][i % 2])
            .collect(),
    ] {
        let mut solver = BoxQpSolver::new(matrix.clone(), BoxQpSettings::default()).unwrap();
        let mut x = start.clone();
        let stats = solver
            .solve_predicted(&b, &lower, &upper, &set, &mut x)
            .unwrap();
        assert!(!stats.bound_set_solve);
        assert_eq!(x, plain);
        assert_eq!(stats.iterations, plain_stats.iterations);
        assert_eq!(stats.factorizations, 1, "the factor of the predicted set");
    }
}

#[test]
fn a_predicted_solve_does_not_depend_on_the_factor_kept_from_earlier_calls() {
    let (dense, b, start) = two_bound_damage_step(9);
    let n = b.len();
    let (lower, upper) = (vec![0.0; n], vec![1.0; n]);
    let matrix = sparse_from_dense(&dense);
    let mut solution = start.clone();
    BoxQpSolver::new(matrix.clone(), BoxQpSettings::default())
        .unwrap()
        .solve(&b, &lower, &upper, &mut solution)
        .unwrap();
    let set = bound_set_of(&solution, &lower, &upper);
    let mut used = BoxQpSolver::new(matrix.clone(), BoxQpSettings::default()).unwrap();
    let mut earlier = start.clone();
    used.solve_predicted(
        &b,
        &lower,
        &upper,
        &vec![BoundStatus::Free; n],
        &mut earlier,
    )
    .unwrap();
    let (mut again, mut once) = (start.clone(), start.clone());
    let again_stats = used
        .solve_predicted(&b, &lower, &upper, &set, &mut again)
        .unwrap();
    let once_stats = BoxQpSolver::new(matrix, BoxQpSettings::default())
        .unwrap()
        .solve_predicted(&b, &lower, &upper, &set, &mut once)
        .unwrap();
    assert!(again_stats.bound_set_solve && once_stats.bound_set_solve);
    assert_eq!(again, once);
}

#[test]
fn a_predicted_bound_set_of_the_wrong_length_is_refused() {
    let (dense, b, start) = two_bound_damage_step(5);
    let n = b.len();
    let mut solver = BoxQpSolver::new(sparse_from_dense(&dense), BoxQpSettings::default()).unwrap();
    let mut x = start;
    let error = solver
        .solve_predicted(
            &b,
            &vec![0.0; n],
            &vec![1.0; n],
            &vec![BoundStatus::Free; n - 1],
            &mut x,
        )
        .unwrap_err();
    assert!(
        matches!(&error, Error::InvalidInput(message) if message.contains("predicted bound set has 24 entries")),
        "{error}"
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// On random SPD problems (not M-matrices) with random bounds, a solve with the bound set
    /// of the solution is certified by the prediction, and a solve with a random bound set is
    /// still the solution (by the fallback when the set is wrong).
    #[test]
    fn predicted_solve_satisfies_kkt_on_random_spd(
        n in 1usize..60,
        seed in any::<u64>(),
        shift in 0.01f64..1.0,
    ) {
        let mut rng = TestRng::new(seed);
        let dense = random_spd(n, &mut rng, shift);
        let b: Vec<f64> = (0..n).map(|_| rng.range(-5.0, 5.0)).collect();
        let (lower, upper) = random_bounds(n, &mut rng);
        let random_set: Vec<BoundStatus> = (0..n)
            .map(|_| [BoundStatus::Free, BoundStatus::AtLower, BoundStatus::AtUpper][rng.index(3)])
            .collect();
        let start: Vec<f64> = (0..n).map(|_| rng.range(-2.0, 2.0)).collect();
        let matrix = sparse_from_dense(&dense);
        let mut solver = BoxQpSolver::new(matrix, BoxQpSettings::default()).unwrap();
        let mut solution = start.clone();
        solver.solve(&b, &lower, &upper, &mut solution).unwrap();
        let solution_set = bound_set_of(&solution, &lower, &upper);
        for (name, set) in [("solution's set", &solution_set), ("random set", &random_set)] {
            let mut x = start.clone();
            let stats = solver.solve_predicted(&b, &lower, &upper, set, &mut x).unwrap();
            assert_within_bounds(&x, &lower, &upper);
            let residual = dense_kkt_residual(&dense, &b, &lower, &upper, &x);
            prop_assert!(residual <= 1e-10, "{name}: dense KKT residual {residual:e}, {stats:?}");
            prop_assert!(stats.kkt_residual <= 1e-12, "{name}: {stats:?}");
            if name == "solution's set" {
                prop_assert!(stats.bound_set_solve, "{name}: {stats:?}");
            }
        }
    }
}
