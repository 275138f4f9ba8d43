use super::csr::Csr;
use super::dense_factor::DenseFactor;
use super::hierarchy::{Hierarchy, COARSEST_REDUCTION, COARSEST_SWEEPS};
use crate::algebra::linalg::max_abs;
use faer::sparse::SparseColMat;
use faer::sparse::Triplet;

/// 5-point Laplacian plus a small mass shift on an m×m grid.
pub(crate) fn laplacian(m: usize, shift: f64) -> SparseColMat<usize, f64> {
    let index = |i: usize, j: usize| i * m + j;
    let mut triplets = Vec::new();
    for i in 0..m {
        for j in 0..m {
            triplets.push(Triplet::new(index(i, j), index(i, j), 4.0 + shift));
            if i + 1 < m {
                triplets.push(Triplet::new(index(i, j), index(i + 1, j), -1.0));
                triplets.push(Triplet::new(index(i + 1, j), index(i, j), -1.0));
            }
            if j + 1 < m {
                triplets.push(Triplet::new(index(i, j), index(i, j + 1), -1.0));
                triplets.push(Triplet::new(index(i, j + 1), index(i, j), -1.0));
            }
        }
    }
    SparseColMat::try_new_from_triplets(m * m, m * m, &triplets).unwrap()
}

/// Energy-norm contraction of the V-cycle iteration `x ← x + B(b − A x)` on `A_FF`.
fn contraction(hierarchy: &mut Hierarchy, matrix: &Csr, fixed: &[bool]) -> f64 {
    let n = fixed.len();
    let _ = hierarchy.truncate(fixed);
    // Error iteration on a rough start, b = 0: e ← e − B A_FF e.
    let mut error: Vec<f64> = (0..n)
        .map(|i| {
            if fixed[i] {
                0.0
            } else {
                ((i * 7919) % 13) as f64 - 6.0
            }
        })
        .collect();
    let energy = |e: &[f64]| {
        let mut image = vec![0.0; n];
        matrix.multiply(e, &mut image);
        e.iter().zip(&image).map(|(a, b)| a * b).sum::<f64>().sqrt()
    };
    let mut image = vec![0.0; n];
    let mut correction = vec![0.0; n];
    let mut rate = 0.0;
    for _ in 0..8 {
        let before = energy(&error);
        matrix.multiply(&error, &mut image);
        for i in 0..n {
            if fixed[i] {
                image[i] = 0.0;
            }
        }
        hierarchy.cycle(&image, &mut correction);
        for i in 0..n {
            error[i] -= correction[i];
            assert!(!fixed[i] || correction[i] == 0.0);
        }
        rate = energy(&error) / before;
    }
    rate
}

/// Measured energy contraction of the V(1,1)-cycle on these grids: 0.34–0.37 for m = 32
/// to 512, untruncated and truncated alike; the bound leaves room for rounding and
/// ordering effects but fails if the rate grows with the grid.
const CONTRACTION_BOUND: f64 = 0.45;

#[test]
fn v_cycle_contracts_independently_of_the_grid() {
    for m in [32, 64, 128, 256] {
        let matrix = laplacian(m, 1e-3);
        let csr = Csr::from_symmetric(&matrix);
        let mut hierarchy = Hierarchy::new(&csr);
        assert!(
            hierarchy.sizes().len() >= 2,
            "sizes {:?}",
            hierarchy.sizes()
        );
        let rate = contraction(&mut hierarchy, &csr, &vec![false; m * m]);
        assert!(
            rate < CONTRACTION_BOUND,
            "m = {m}: V-cycle contraction {rate}"
        );
    }
}

/// A banded matrix with unit diagonal and `-coupling` on the `band` neighbours on each
/// side: every coupling below the strength threshold, so the coarsening stalls at once.
fn weakly_coupled(n: usize, band: usize, coupling: f64) -> Csr {
    let dense: Vec<Vec<f64>> = (0..n)
        .map(|i| {
            (0..n)
                .map(|j| match i.abs_diff(j) {
                    0 => 1.0,
                    d if d <= band => -coupling,
                    _ => 0.0,
                })
                .collect()
        })
        .collect();
    dense_rows(&dense)
}

#[test]
fn a_stalled_coarsest_level_gets_the_sweeps_its_dominance_needs() {
    let n = 200;
    // (band, coupling, ρ = 2·band·coupling, sweeps = ⌈ln 0.1 / (2 ln ρ)⌉ capped at 4)
    for (band, coupling, sweeps) in [
        (3, 0.04, 1),  // ρ = 0.24: ρ² = 0.058
        (3, 0.075, 2), // ρ = 0.45: ρ² = 0.20, ρ⁴ = 0.041
        (6, 0.075, 4), // ρ = 0.90: ρ⁸ = 0.43, capped
        (7, 0.075, 4), // ρ = 1.05: no bound
    ] {
        let matrix = weakly_coupled(n, band, coupling);
        let mut hierarchy = Hierarchy::with_coarsest_size(&matrix, 1);
        assert_eq!(
            hierarchy.sizes(),
            vec![n],
            "band {band}: the coarsening stalls"
        );
        assert!(hierarchy.coarsest_factor.is_none());
        assert_eq!(
            hierarchy.coarsest_sweeps, sweeps,
            "band {band}, coupling {coupling}"
        );
        let dominance = 2.0 * band as f64 * coupling;
        if dominance < 1.0 {
            // the cycle is the sweeps from zero: the error of A z = A x* shrinks by ρ^{2s}
            let exact: Vec<f64> = (0..n).map(|i| ((i * 37) % 11) as f64 - 5.0).collect();
            let mut rhs = vec![0.0; n];
            matrix.multiply(&exact, &mut rhs);
            let mut z = vec![0.0; n];
            hierarchy.cycle(&rhs, &mut z);
            let difference: Vec<f64> = exact.iter().zip(&z).map(|(x, z)| x - z).collect();
            let error = max_abs(&difference);
            let bound = dominance.powi(2 * sweeps as i32) * max_abs(&exact);
            assert!(error <= bound, "band {band}: error {error} > {bound}");
            if sweeps < COARSEST_SWEEPS {
                assert!(bound <= COARSEST_REDUCTION * max_abs(&exact));
            }
        }
    }
}

#[test]
fn truncated_v_cycle_contracts_on_the_free_set() {
    let m = 64;
    let matrix = laplacian(m, 1e-3);
    let csr = Csr::from_symmetric(&matrix);
    let mut hierarchy = Hierarchy::new(&csr);
    // Fixed: a disc in the middle and a strip along one side.
    let fixed: Vec<bool> = (0..m * m)
        .map(|k| {
            let (i, j) = ((k / m) as f64, (k % m) as f64);
            (i - 32.0).powi(2) + (j - 30.0).powi(2) < 150.0 || j < 5.0
        })
        .collect();
    let rate = contraction(&mut hierarchy, &csr, &fixed);
    assert!(
        rate < CONTRACTION_BOUND,
        "truncated V-cycle contraction {rate}"
    );
    // Untruncating again restores the original contraction.
    let rate = contraction(&mut hierarchy, &csr, &vec![false; m * m]);
    assert!(
        rate < CONTRACTION_BOUND,
        "restored V-cycle contraction {rate}"
    );
}
/// The products in sweep order are the row products up to rounding, in both directions,
/// on rows with and without a stored diagonal entry (a row without one also has no lower
/// or no upper part here), and the Gauss–Seidel sweep built on them solves the system.
#[test]
fn sweep_products_are_the_row_products_in_both_directions() {
    let m = 12;
    let matrix = Csr::from_symmetric(&laplacian(m, 0.5));
    // a row without its diagonal entry: drop it from the pattern of row 0 and the last
    let n = m * m;
    let mut offsets = vec![0];
    let (mut indices, mut values) = (Vec::new(), Vec::new());
    for i in 0..n {
        let (columns, entries) = matrix.row(i);
        for (&j, &a) in columns.iter().zip(entries) {
            if !(j == i && (i == 0 || i == n - 1)) {
                indices.push(j);
                // distinct values, so that a dropped or repeated term shows
                values.push(a * (1.0 + 0.01 * ((i * 7 + j * 3) % 11) as f64));
            }
        }
        offsets.push(indices.len());
    }
    let without_diagonal = Csr {
        cols: n,
        offsets,
        indices,
        values,
    };
    let x: Vec<f64> = (0..n).map(|i| ((i * 13) % 17) as f64 - 8.3).collect();
    for csr in [&matrix, &without_diagonal] {
        for (i, &lower) in csr.lower_counts().iter().enumerate() {
            let exact = csr.row_product(i, &x);
            let size: f64 = csr
                .row(i)
                .0
                .iter()
                .zip(csr.row(i).1)
                .map(|(&j, a)| (a * x[j]).abs())
                .sum();
            for backward in [false, true] {
                let swept = csr.sweep_product(i, &x, lower, backward);
                assert!(
                    (swept - exact).abs() <= 1e-14 * size,
                    "row {i}, backward {backward}: {swept} vs {exact}"
                );
            }
        }
    }
    // Symmetric Gauss–Seidel on the finest level of an untruncated hierarchy converges to
    // the solution of A z = r.
    let hierarchy = Hierarchy::new(&matrix);
    let mut level = hierarchy.levels[0].clone();
    level.rhs = (0..n).map(|i| (i % 5) as f64 - 2.0).collect();
    level.solution.fill(0.0);
    for _ in 0..400 {
        level.sweep(false);
        level.sweep(true);
    }
    let mut residual = vec![0.0; n];
    matrix.multiply(&level.solution, &mut residual);
    let worst = residual
        .iter()
        .zip(&level.rhs)
        .fold(0.0_f64, |w, (a, b)| w.max((a - b).abs()));
    assert!(worst < 1e-10, "Gauss–Seidel residual {worst}");
}

/// A dense symmetric matrix as rows.
fn dense_rows(dense: &[Vec<f64>]) -> Csr {
    let n = dense.len();
    let mut triplets = Vec::new();
    for (i, row) in dense.iter().enumerate() {
        for (j, &value) in row.iter().enumerate() {
            if value != 0.0 {
                triplets.push(Triplet::new(i, j, value));
            }
        }
    }
    Csr::from_symmetric(&SparseColMat::try_new_from_triplets(n, n, &triplets).unwrap())
}

/// `max_i |(A x − b)_i|` over the rows `kept`.
fn residual_on(dense: &[Vec<f64>], x: &[f64], rhs: &[f64]) -> f64 {
    dense
        .iter()
        .zip(rhs)
        .map(|(row, b)| (row.iter().zip(x).map(|(a, x)| a * x).sum::<f64>() - b).abs())
        .fold(0.0, f64::max)
}

/// The truncated coarsest matrix (38 unknowns, 6 of them truncated away) that the
/// Cholesky factor without pivoting reported indefinite (a pivot of −1.3e-5 times the
/// largest diagonal entry) although its eigenvalues are ≥ −2e-20 (positive semidefinite
/// up to rounding): met in a coarse obstacle problem whose aggregates touch both bounds.
/// With diagonal pivoting it is factorized, and a consistent system is solved to
/// rounding; a genuinely indefinite matrix is still reported.
#[test]
fn pivoted_dense_factor_solves_a_semidefinite_coarsest_matrix_and_detects_indefinite_ones() {
    let dense: Vec<Vec<f64>> = include_str!("../../../tests/data/truncated_coarsest_38.txt")
        .lines()
        .filter(|line| !line.trim().is_empty())
        .map(|line| {
            line.split_whitespace()
                .map(|v| v.parse().unwrap())
                .collect()
        })
        .collect();
    let n = dense.len();
    assert_eq!(n, 38);
    let rows = dense_rows(&dense);
    let diagonal = rows.diagonal();
    let scale = diagonal.iter().fold(0.0_f64, |acc, d| acc.max(*d));
    let factor = DenseFactor::new(&rows, &diagonal, scale);
    assert!(!factor.indefinite);
    assert!(factor.rank < n, "rank {}", factor.rank);
    // A right-hand side in the range: b = A y.
    let y: Vec<f64> = (0..n).map(|i| ((i * 7 % 11) as f64 - 5.0) / 5.0).collect();
    let rhs: Vec<f64> = dense
        .iter()
        .map(|row| row.iter().zip(&y).map(|(a, y)| a * y).sum())
        .collect();
    let mut x = vec![0.0; n];
    factor.solve(&rhs, &mut x, &mut vec![0.0; n]);
    let size = rhs.iter().fold(0.0_f64, |acc, b| acc.max(b.abs()));
    assert!(
        residual_on(&dense, &x, &rhs) <= 1e-8 * size,
        "residual {} against {size}",
        residual_on(&dense, &x, &rhs)
    );
    // The truncated unknowns (zero rows) are dropped and set to zero.
    for i in 0..n {
        if diagonal[i] == 0.0 {
            assert_eq!(x[i], 0.0);
        }
    }
    let indefinite = vec![
        vec![2.0, 0.0, 1.0],
        vec![0.0, -1.0, 0.0],
        vec![1.0, 0.0, 3.0],
    ];
    let rows = dense_rows(&indefinite);
    let diagonal = rows.diagonal();
    assert!(DenseFactor::new(&rows, &diagonal, 3.0).indefinite);
}
