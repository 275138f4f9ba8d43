//! Bound sets followed from step to step ([`BoxQpSolver::solve_following`]; the
//! [module documentation](super), "Followed bound sets"): the solve on a bound set `S` with
//! the Cholesky factor of a nearby *reference* set, bordered by the few indices whose status
//! differs (a Schur complement update, as in the active set QP methods of Gill, Murray,
//! Saunders & Wright 1990), and the primal–dual active set iteration around it.
//!
//! With `R` the indices free in the reference, its factor is that of `A_RR` (the fixed rows
//! and columns replaced by the identity's, [`BoundSetFactor`]). An index freed since (fixed in
//! the reference, free in `S`) borders `A_RR` with its column `A_Rj` and its row; an index
//! fixed since (free in the reference, fixed in `S`) borders it with `e_j` and a multiplier
//! that takes over its row. The bordered system
//!
//! ```text
//!     [ A_RR  G ] [ x_R ]   [ c_R ]          G = [A_R,freed  e_fixed],
//!     [ Gᵀ    H ] [  y  ] = [ c_B ],         H = [A_freed,freed  0; 0  0],
//! ```
//!
//! with `c = b − A x_K` for the values `x_K` of the indices fixed in both sets, `c_B` = `c` on
//! the freed indices and their bound on the fixed ones, is the system `A_FF x_F = b_F −
//! A_FX x_X` of `S` (its rows of the fixed indices are the constraints `x_j = bound`). With
//! `A_RR = L Lᵀ` (in the factor's order) and `W = L⁻¹ G`, it is one solve with the reference
//! factor and a dense system with the Schur complement `H − WᵀW` of the border. The columns
//! of `W` are sparse: `L⁻¹` of a vector with a few nonzeros is nonzero on the elimination tree
//! paths from them to the root only (`CholeskySolver::forward_solve_sparse`). Each index costs
//! its column of `W` and its products with the others once per reference factor. The forward
//! half `L⁻¹ c_R` is made once per call for the reference set's own right-hand side; a set
//! changes it by columns of `W` (those of the indices fixed in the reference whose value
//! differs), so a set costs a backward solve, products with the border's columns and the
//! dense system of the border.

use std::collections::HashMap;

use faer::linalg::solvers::Solve;
use faer::sparse::SparseColMat;
use faer::{Col, Mat};

use crate::algebra::linalg::multiply_into;
use crate::algebra::triangular::SupernodeTree;
use crate::error::Result;
use crate::solvers::box_qp::active_set::classify;
use crate::solvers::box_qp::bound_set::{normalized_set, BoundSetFactor};
use crate::solvers::box_qp::kkt::{gradient, project, scaled_kkt_residual, Problem};
use crate::solvers::box_qp::settings::BoxQpStats;
use crate::solvers::box_qp::solver::BoxQpSolver;
use crate::solvers::box_qp::workspace::BoundStatus;

/// The largest border (indices whose free/fixed status differs from the reference set) solved
/// with the reference factor; a set further from it is factorized as the new reference. The
/// dense system of the border costs about m³/3 operations per set and the products with its
/// columns m times a column's length per solve, against a numeric factorization of about ten
/// solves with the factor (`cargo run --release -p contact-damage --example
/// damage_factor_cost`). Measured on the damage steps of `zones2d` at 128 cells (k = h, one
/// thread, three runs each): 0.46–0.50 s in all with 64 (17 factorizations), 0.47–0.50 s
/// with 128 (12), 0.55–0.61 s with 256 (7).
pub const MAX_BORDER: usize = 64;

/// Primal–dual active set iterations tried on followed bound sets before the solve falls back
/// to [`BoxQpSolver::solve`].
pub const MAX_FOLLOWED_ITERATIONS: usize = 4;

/// Whether the index is held at a bound in the set.
fn is_fixed(status: BoundStatus) -> bool {
    status != BoundStatus::Free
}

/// The border of the reference factor of a [`BoundSetFactor`]: the columns of `W = L⁻¹G` of
/// the indices met since the factor was computed, and their products.
#[derive(Default)]
pub(super) struct Border {
    /// The supernodal elimination tree of the factor (built on first use).
    tree: Option<SupernodeTree>,
    /// Position of each bordered index among `indices`.
    slot_of: HashMap<usize, usize>,
    indices: Vec<usize>,
    /// Per slot, the column of `W`: positions in the factor's order and values.
    columns: Vec<(Vec<usize>, Vec<f64>)>,
    /// `gram[s][t] = w_s · w_t` for `t ≤ s`.
    gram: Vec<Vec<f64>>,
    /// One zero per unknown between uses.
    scratch: Vec<f64>,
}

impl Border {
    /// Forgets the columns (a new reference factor; the elimination tree is that of the
    /// symbolic analysis, which stays).
    pub(super) fn clear(&mut self) {
        self.slot_of.clear();
        self.indices.clear();
        self.columns.clear();
        self.gram.clear();
    }

    /// Number of bordered indices kept for the current factor.
    fn len(&self) -> usize {
        self.indices.len()
    }

    /// The slot of index `j`, computing its column of `W` and its products when it is new.
    fn slot(
        &mut self,
        matrix: &SparseColMat<usize, f64>,
        factor: &BoundSetFactor,
        j: usize,
    ) -> Result<usize> {
        if let Some(&slot) = self.slot_of.get(&j) {
            return Ok(slot);
        }
        let n = matrix.nrows();
        if self.scratch.len() != n {
            self.scratch = vec![0.0; n];
        }
        let tree = match &mut self.tree {
            Some(tree) => tree,
            none => none.insert(factor.factor.supernode_tree().ok_or_else(|| {
                crate::error::Error::InvalidInput(
                    "box QP: followed bound sets need a supernodal factor".into(),
                )
            })?),
        };
        let entries: Vec<(usize, f64)> = if is_fixed(factor.set[j]) {
            // freed: the column of A on the indices free in the reference
            let range = matrix.col_ptr()[j]..matrix.col_ptr()[j + 1];
            matrix.row_idx()[range.clone()]
                .iter()
                .zip(&matrix.val()[range])
                .filter(|(&row, _)| !is_fixed(factor.set[row]))
                .map(|(&row, &value)| (row, value))
                .collect()
        } else {
            vec![(j, 1.0)]
        };
        let column = factor
            .factor
            .forward_solve_sparse(tree, &entries, &mut self.scratch)?;
        for (&row, &value) in column.0.iter().zip(&column.1) {
            self.scratch[row] = value;
        }
        let mut products: Vec<f64> = self
            .columns
            .iter()
            .map(|(rows, values)| dot_scattered(rows, values, &self.scratch))
            .collect();
        products.push(dot_scattered(&column.0, &column.1, &self.scratch));
        for &row in &column.0 {
            self.scratch[row] = 0.0;
        }
        let slot = self.indices.len();
        self.slot_of.insert(j, slot);
        self.indices.push(j);
        self.columns.push(column);
        self.gram.push(products);
        Ok(slot)
    }

    fn gram(&self, s: usize, t: usize) -> f64 {
        if t <= s {
            self.gram[s][t]
        } else {
            self.gram[t][s]
        }
    }
}

/// `Σ values_k · dense[rows_k]`.
fn dot_scattered(rows: &[usize], values: &[f64], dense: &[f64]) -> f64 {
    rows.iter()
        .zip(values)
        .map(|(&row, &v)| v * dense[row])
        .sum()
}

/// The entry `A_ij` (zero outside the pattern).
fn entry(matrix: &SparseColMat<usize, f64>, i: usize, j: usize) -> f64 {
    let range = matrix.col_ptr()[j]..matrix.col_ptr()[j + 1];
    matrix.row_idx()[range.clone()]
        .iter()
        .position(|&row| row == i)
        .map_or(0.0, |k| matrix.val()[range.start + k])
}

/// The indices whose free/fixed status differs between `reference` and `set`, ascending.
fn changed(reference: &[BoundStatus], set: &[BoundStatus]) -> Vec<usize> {
    reference
        .iter()
        .zip(set)
        .enumerate()
        .filter(|(_, (&a, &b))| is_fixed(a) != is_fixed(b))
        .map(|(i, _)| i)
        .collect()
}

/// The value of the bound an index is held at in a set (0 for a free index).
fn bound_value(status: BoundStatus, lower: f64, upper: f64) -> f64 {
    match status {
        BoundStatus::Free => 0.0,
        BoundStatus::AtLower => lower,
        BoundStatus::AtUpper => upper,
    }
}

impl BoundSetFactor {
    /// `z_ref = L⁻¹ P c_R` for the reference set itself: `c = b − A x_X` with the values of
    /// the indices fixed in the reference, on the indices free in it (one full forward solve).
    fn reference_forward(
        &mut self,
        matrix: &SparseColMat<usize, f64>,
        problem: &Problem<'_>,
    ) -> Result<Vec<f64>> {
        let n = self.set.len();
        for i in 0..n {
            self.reduced_rhs[i] = bound_value(self.set[i], problem.lower[i], problem.upper[i]);
        }
        multiply_into(matrix, &self.reduced_rhs, &mut self.product);
        for i in 0..n {
            self.reduced_rhs[i] = if is_fixed(self.set[i]) {
                0.0
            } else {
                problem.rhs[i] - self.product[i]
            };
        }
        Ok(self
            .factor
            .forward_solve(&self.reduced_rhs)?
            .expect("the bound-set factor is supernodal"))
    }

    /// The solution of the system of the bound set `set` (fixed values on their bounds, free
    /// values not projected) with the reference factor bordered by `changed` (the indices
    /// whose free/fixed status differs from the reference), from `reference`, the forward
    /// half of the reference set's own system ([`BoundSetFactor::reference_forward`]): the
    /// right-hand side of `set` differs from it by the columns of `A` of the indices fixed in
    /// the reference whose value differs in `set`, whose forward halves are columns of `W`.
    /// None when the dense border system gives no finite solution.
    fn bordered_solve(
        &mut self,
        matrix: &SparseColMat<usize, f64>,
        set: &[BoundStatus],
        changed: &[usize],
        reference: &[f64],
        problem: &Problem<'_>,
    ) -> Result<Option<Vec<f64>>> {
        let bound = |i: usize| bound_value(set[i], problem.lower[i], problem.upper[i]);
        let reference_bound =
            |i: usize| bound_value(self.set[i], problem.lower[i], problem.upper[i]);
        // the indices fixed in the reference whose value in `set` differs: freed ones (value
        // 0 in x_K) and ones moved to the other bound
        let moved: Vec<(usize, f64)> = (0..set.len())
            .filter(|&i| is_fixed(self.set[i]))
            .filter_map(|i| {
                let value = if is_fixed(set[i]) { bound(i) } else { 0.0 };
                let change = reference_bound(i) - value;
                (change != 0.0).then_some((i, change))
            })
            .collect();
        let mut border = std::mem::take(&mut self.border);
        let slots = changed
            .iter()
            .map(|&j| border.slot(matrix, self, j))
            .collect::<Result<Vec<_>>>();
        let moved_slots = moved
            .iter()
            .map(|&(j, _)| border.slot(matrix, self, j))
            .collect::<Result<Vec<_>>>();
        self.border = border;
        let (slots, moved_slots) = (slots?, moved_slots?);
        let border = &self.border;
        // z = L⁻¹ P c_R for c = b − A x_K
        let mut z = reference.to_vec();
        for (&(_, change), &slot) in moved.iter().zip(&moved_slots) {
            let (rows, values) = &border.columns[slot];
            for (&row, &w) in rows.iter().zip(values) {
                z[row] += change * w;
            }
        }
        // c_j = b_j − Σ_{k ∈ K} A_kj x_k on the freed indices
        let kept_value = |k: usize| {
            if is_fixed(self.set[k]) && is_fixed(set[k]) {
                bound(k)
            } else {
                0.0
            }
        };
        let column_rhs = |j: usize| {
            let range = matrix.col_ptr()[j]..matrix.col_ptr()[j + 1];
            let product: f64 = matrix.row_idx()[range.clone()]
                .iter()
                .zip(&matrix.val()[range])
                .map(|(&k, &a)| a * kept_value(k))
                .sum();
            problem.rhs[j] - product
        };
        let m = changed.len();
        let freed = |a: usize| is_fixed(self.set[changed[a]]);
        let schur = Mat::<f64>::from_fn(m, m, |a, b| {
            let h = if freed(a) && freed(b) {
                entry(matrix, changed[a], changed[b])
            } else {
                0.0
            };
            h - border.gram(slots[a], slots[b])
        });
        let rhs = Col::<f64>::from_fn(m, |a| {
            let j = changed[a];
            let c = if freed(a) { column_rhs(j) } else { bound(j) };
            let (rows, values) = &border.columns[slots[a]];
            c - dot_scattered(rows, values, &z)
        });
        let border_values = if m == 0 {
            Col::<f64>::zeros(0)
        } else {
            schur.partial_piv_lu().solve(rhs)
        };
        if border_values.iter().any(|v| !v.is_finite()) {
            return Ok(None);
        }
        for (a, &value) in border_values.iter().enumerate() {
            let (rows, values) = &border.columns[slots[a]];
            for (&row, &w) in rows.iter().zip(values) {
                z[row] -= w * value;
            }
        }
        let mut x = self
            .factor
            .backward_solve(&z)?
            .expect("the bound-set factor is supernodal");
        for (a, &j) in changed.iter().enumerate() {
            if freed(a) {
                x[j] = border_values[a];
            }
        }
        for (i, &status) in set.iter().enumerate() {
            if is_fixed(status) {
                x[i] = bound(i);
            }
        }
        Ok(x.iter().all(|v| v.is_finite()).then_some(x))
    }
}

impl BoxQpSolver {
    /// Solves the box QP like [`BoxQpSolver::solve`], first by the primal–dual active set
    /// iteration (at most [`MAX_FOLLOWED_ITERATIONS`] sets) from the bound set of the start
    /// `x` (the indices lying on a bound), each set solved with the factor of the reference set
    /// kept from earlier calls, bordered by the indices whose status differs (at most
    /// [`MAX_BORDER`]; beyond, the set is factorized and becomes the reference). The result is
    /// the first solution whose projection has a scaled KKT residual within the tolerance
    /// ([`BoxQpStats::bound_set_solve`] set, the sets tried counted as iterations); when the
    /// iteration stalls or cycles, the solve proceeds by the chosen method from the start `x`.
    ///
    /// Unlike [`BoxQpSolver::solve_predicted`], the values depend on the reference factor, so
    /// on the calls made before (at the level of rounding: every result is certified by the
    /// same KKT residual). Errors: those of [`BoxQpSolver::solve`].
    pub fn solve_following(
        &mut self,
        rhs: &[f64],
        lower: &[f64],
        upper: &[f64],
        x: &mut [f64],
    ) -> Result<BoxQpStats> {
        self.check_problem(rhs, lower, upper, x)?;
        let n = x.len();
        let start: Vec<BoundStatus> = (0..n)
            .map(|i| BoundStatus::of(x[i], lower[i], upper[i]))
            .collect();
        let mut factorizations = 0;
        // faer analyses the smallest matrices as simplicial whatever it is asked for
        let supernodal = self.bound_set_factor()?.factor.is_supernodal();
        if let Some(mut set) = normalized_set(&start, lower, upper).filter(|_| supernodal) {
            let tolerance = self.settings.tolerance;
            let problem = Problem::new(rhs, lower, upper, tolerance);
            let mut visited: Vec<Vec<BoundStatus>> = Vec::new();
            let mut candidate_gradient = vec![0.0; n];
            let mut next = vec![BoundStatus::Free; n];
            let mut reference = None;
            for iteration in 1..=MAX_FOLLOWED_ITERATIONS {
                let factor = self.bound_set_factor.as_mut().expect("analysed above");
                let mut border = if factor.factor.is_factorized() {
                    changed(&factor.set, &set)
                } else {
                    Vec::new()
                };
                let new_reference = !factor.factor.is_factorized()
                    || border.len() > MAX_BORDER
                    || factor.border.len() + border.len() > 2 * MAX_BORDER;
                if new_reference && factorizations > 0 {
                    // the iteration moved far from the set factorized for it
                    break;
                }
                if new_reference {
                    if factor.prepare(&self.matrix, &set)? {
                        factorizations += 1;
                        reference = None;
                    }
                    border.clear();
                }
                let reference = match &mut reference {
                    Some(reference) => reference,
                    none => none.insert(factor.reference_forward(&self.matrix, &problem)?),
                };
                let Some(mut candidate) =
                    factor.bordered_solve(&self.matrix, &set, &border, reference, &problem)?
                else {
                    break;
                };
                gradient(&self.matrix, &candidate, rhs, &mut candidate_gradient);
                let inside = (0..n).all(|i| lower[i] <= candidate[i] && candidate[i] <= upper[i]);
                let residual = if inside {
                    scaled_kkt_residual(&candidate, &candidate_gradient, &problem)
                } else {
                    let mut projected = candidate.clone();
                    project(&mut projected, lower, upper);
                    let mut projected_gradient = vec![0.0; n];
                    gradient(&self.matrix, &projected, rhs, &mut projected_gradient);
                    scaled_kkt_residual(&projected, &projected_gradient, &problem)
                };
                if residual <= tolerance {
                    project(&mut candidate, lower, upper);
                    x.copy_from_slice(&candidate);
                    let mut stats = BoxQpStats {
                        iterations: iteration,
                        factorizations,
                        bound_set_solve: true,
                        ..BoxQpStats::default()
                    };
                    if inside {
                        self.finish_with_residual(x, &problem, residual, &mut stats);
                    } else {
                        self.finish(x, &problem, &mut stats);
                    }
                    return Ok(stats);
                }
                classify(
                    &candidate,
                    &candidate_gradient,
                    &problem,
                    &self.diagonal,
                    &mut next,
                );
                if next == set || visited.contains(&next) {
                    break;
                }
                visited.push(std::mem::replace(&mut set, next.clone()));
            }
        }
        let mut stats = self.solve(rhs, lower, upper, x)?;
        stats.factorizations += factorizations;
        Ok(stats)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solvers::box_qp::tests::{
        assert_within_bounds, bound_set_of, damage_matrix, damage_rhs, dense_kkt_residual, fe_2d,
        random_bounds, random_spd, sparse_from_dense, DenseMatrix, TestRng,
    };
    use crate::solvers::box_qp::BoxQpSettings;
    use proptest::prelude::*;

    /// A 2D damage step from β = 0.5 whose source pushes β to 1 left of `front` and to 0
    /// right of `1 − front`: moving `front` moves both bound sets by a few nodes. Returns the
    /// matrix and the right-hand side.
    fn damage_step(m: usize, front: f64) -> (DenseMatrix, Vec<f64>) {
        let (mass, stiffness, coords) = fe_2d(m);
        let (time_step, kappa) = (0.01, 1e-3);
        let dense = damage_matrix(&mass, &stiffness, time_step, kappa);
        let previous = vec![0.5; m * m];
        let source: Vec<f64> = coords
            .iter()
            .map(|p| {
                100.0 * f64::from(u8::from(p[0] < front))
                    - 100.0 * f64::from(u8::from(p[0] > 1.0 - front))
            })
            .collect();
        (dense, damage_rhs(&mass, &previous, &source, time_step))
    }

    #[test]
    fn a_set_near_the_reference_is_solved_with_its_factor_and_a_border() {
        let m = 12;
        let n = m * m;
        let (lower, upper) = (vec![0.0; n], vec![1.0; n]);
        let (dense, first_rhs) = damage_step(m, 0.3);
        let (_, second_rhs) = damage_step(m, 0.4);
        let matrix = sparse_from_dense(&dense);
        let start = vec![0.5; n];
        let mut plain = BoxQpSolver::new(matrix.clone(), BoxQpSettings::default()).unwrap();
        let mut first = start.clone();
        plain.solve(&first_rhs, &lower, &upper, &mut first).unwrap();
        let mut second = start.clone();
        plain
            .solve(&second_rhs, &lower, &upper, &mut second)
            .unwrap();
        let moved = changed(
            &bound_set_of(&first, &lower, &upper),
            &bound_set_of(&second, &lower, &upper),
        );
        assert!(
            (1..=MAX_BORDER).contains(&moved.len()),
            "{} indices moved",
            moved.len()
        );

        let mut solver = BoxQpSolver::new(matrix, BoxQpSettings::default()).unwrap();
        // the first solve, started at its solution, factorizes its bound set
        let mut x = first.clone();
        let stats = solver
            .solve_following(&first_rhs, &lower, &upper, &mut x)
            .unwrap();
        assert!(
            stats.bound_set_solve && stats.factorizations == 1,
            "{stats:?}"
        );
        // the second, started at the first solution, follows the set with that factor
        let mut x = first.clone();
        let stats = solver
            .solve_following(&second_rhs, &lower, &upper, &mut x)
            .unwrap();
        assert!(stats.bound_set_solve, "{stats:?}");
        assert_eq!(stats.factorizations, 0, "{stats:?}");
        assert!(
            stats.iterations >= 2,
            "the start's set is not the solution's: {stats:?}"
        );
        assert_within_bounds(&x, &lower, &upper);
        assert!(dense_kkt_residual(&dense, &second_rhs, &lower, &upper, &x) <= 1e-13);
        assert_eq!(
            bound_set_of(&x, &lower, &upper),
            bound_set_of(&second, &lower, &upper)
        );
        for i in 0..n {
            assert!(
                (x[i] - second[i]).abs() <= 1e-11,
                "x[{i}] = {} vs {}",
                x[i],
                second[i]
            );
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// On random SPD problems (not M-matrices) with random bounds, a sequence of followed
        /// solves (the same data from its solution, nearby data, unrelated data, each from a
        /// random or the previous point) returns the solution every time, certified by the
        /// KKT residual, whether the set is followed or the iteration falls back.
        #[test]
        fn followed_solves_satisfy_kkt_on_random_spd(
            n in 1usize..60,
            seed in any::<u64>(),
            shift in 0.01f64..1.0,
        ) {
            let mut rng = TestRng::new(seed);
            let dense = random_spd(n, &mut rng, shift);
            let (lower, upper) = random_bounds(n, &mut rng);
            let first: Vec<f64> = (0..n).map(|_| rng.range(-5.0, 5.0)).collect();
            let nearby: Vec<f64> = first.iter().map(|b| b + rng.range(-0.1, 0.1)).collect();
            let unrelated: Vec<f64> = (0..n).map(|_| rng.range(-5.0, 5.0)).collect();
            let mut solver = BoxQpSolver::new(sparse_from_dense(&dense), BoxQpSettings::default()).unwrap();
            let mut reference = BoxQpSolver::new(sparse_from_dense(&dense), BoxQpSettings::default()).unwrap();
            let mut previous: Vec<f64> = (0..n).map(|_| rng.range(-2.0, 2.0)).collect();
            for (name, b) in [("first", &first), ("again", &first), ("nearby", &nearby), ("unrelated", &unrelated)] {
                let mut x = previous.clone();
                let stats = solver.solve_following(b, &lower, &upper, &mut x).unwrap();
                assert_within_bounds(&x, &lower, &upper);
                let residual = dense_kkt_residual(&dense, b, &lower, &upper, &x);
                prop_assert!(residual <= 1e-10, "{name}: dense KKT residual {residual:e}, {stats:?}");
                prop_assert!(stats.kkt_residual <= 1e-12, "{name}: {stats:?}");
                // faer analyses the smallest matrices as simplicial, and then no set is followed
                let follows = solver.bound_set_factor().unwrap().factor.is_supernodal();
                if name == "again" && follows {
                    prop_assert!(stats.bound_set_solve && stats.factorizations == 0, "{name}: {stats:?}");
                }
                let mut solution = previous.clone();
                reference.solve(b, &lower, &upper, &mut solution).unwrap();
                for i in 0..n {
                    prop_assert!((x[i] - solution[i]).abs() <= 1e-8 * (1.0 + solution[i].abs()), "{name}: x[{i}] = {} vs {}", x[i], solution[i]);
                }
                previous = x;
            }
        }
    }
}
