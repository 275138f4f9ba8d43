//! Triangular solves with one right-hand side on a supernodal Cholesky factor L (faer's
//! storage: per supernode a column-major block of its columns, the dense diagonal block on top
//! of the rows of its pattern).
//!
//! faer solves supernode by supernode with dense kernels: a triangular solve with the diagonal
//! block and a matrix–vector product with the rest, through a workspace. With one right-hand
//! side and the narrow supernodes of 2D meshes (6–7 columns on average for P1) the fixed cost
//! of those kernels per supernode dominates: a column-by-column sweep over the same stored
//! values takes about half the time. Wide supernodes (the separators of 3D meshes) still gain
//! from the dense kernels, so supernodes of at least [`WIDE_SUPERNODE`] columns keep them.
//!
//! Measured on the velocity factor of the `simulate` examples on the unit box (one thread,
//! fastest of 30 interleaved repetitions, AMD EPYC, 2026-11-26), ms per solve:
//!
//! | factor | faer | column sweeps only | sweeps + dense kernels from 32 columns |
//! |---|---:|---:|---:|
//! | 2D P1 128² (33 k unknowns) | 5.0–5.7 | 2.9–3.1 | 2.7–2.9 |
//! | 2D P1 256² (132 k) | 26.2–27.8 | 16.1–16.2 | 14.9–15.0 |
//! | 3D P1 16³ (15 k) | 7.3–7.6 | 9.6–9.9 | 7.1–7.4 |
//! | 3D P1 32³ (108 k) | — (dense kernels everywhere: 134) | 219 | 136 |
//!
//! The sweeps sum in another order than faer's kernels: results differ at the rounding level
//! (a `simulate` history at 2D 128² by at most 3e-15 of each column's largest value, the
//! errors of `verify --dim 3` by at most 2e-14 relative).

use faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky;
use faer::{Accum, MatMut, MatRef, Par};

/// Supernodes with at least this many columns are solved with faer's dense kernels, narrower
/// ones column by column. Measured with 0, 8, 16, 32, 64 and ∞: 16 is 1.3× slower than 32 in
/// 2D 128², 64 1.2× slower in 3D 16³; 32 is within 3% of the best threshold in every case
/// of the table above.
pub(crate) const WIDE_SUPERNODE: usize = 32;

/// One supernode of the factor: its first column, its width, the rows of its pattern below the
/// diagonal block, and its values (column-major, `size + pattern.len()` rows).
struct Supernode<'a> {
    start: usize,
    size: usize,
    pattern: &'a [usize],
    block: &'a [f64],
}

impl Supernode<'_> {
    /// Rows of the stored block.
    fn rows(&self) -> usize {
        self.size + self.pattern.len()
    }

    /// Stored column `jj` of the supernode (the diagonal block's rows, then the pattern's).
    fn column(&self, jj: usize) -> &[f64] {
        let rows = self.rows();
        &self.block[jj * rows..(jj + 1) * rows]
    }

    fn is_wide(&self) -> bool {
        self.size >= WIDE_SUPERNODE
    }

    /// The diagonal block and the block below it as matrices.
    fn blocks(&self) -> (MatRef<'_, f64>, MatRef<'_, f64>) {
        MatRef::from_column_major_slice(self.block, self.rows(), self.size).split_at_row(self.size)
    }
}

/// The supernode `s` of the factor with stored values `values`.
fn supernode<'a>(
    symbolic: &'a SymbolicSupernodalCholesky<usize>,
    values: &'a [f64],
    s: usize,
) -> Supernode<'a> {
    let start = symbolic.supernode_begin()[s];
    let rows = symbolic.col_ptr_for_row_idx();
    let vals = symbolic.col_ptr_for_val();
    Supernode {
        start,
        size: symbolic.supernode_end()[s] - start,
        pattern: &symbolic.row_idx()[rows[s]..rows[s + 1]],
        block: &values[vals[s]..vals[s + 1]],
    }
}

/// z ← L⁻¹ z (z in elimination order).
pub(crate) fn forward(symbolic: &SymbolicSupernodalCholesky<usize>, values: &[f64], z: &mut [f64]) {
    forward_on(symbolic, values, z, 0..symbolic.n_supernodes());
}

/// z ← L⁻¹ z when z is zero outside the columns of `supernodes` (ascending, closed under the
/// parent of the supernodal elimination tree, [`SupernodeTree::reach`]): the sweep of
/// [`forward`] over those supernodes only, with the same operations on them. The columns of
/// the other supernodes would only subtract zero products.
pub(crate) fn forward_on(
    symbolic: &SymbolicSupernodalCholesky<usize>,
    values: &[f64],
    z: &mut [f64],
    supernodes: impl IntoIterator<Item = usize>,
) {
    // the pattern's products (forward) or values (backward) of a wide supernode
    let mut workspace = Vec::new();
    for s in supernodes {
        let node = supernode(symbolic, values, s);
        let (start, end) = (node.start, node.start + node.size);
        if node.is_wide() {
            let (diagonal, below) = node.blocks();
            let top = MatMut::from_column_major_slice_mut(&mut z[start..end], node.size, 1);
            faer::linalg::triangular_solve::solve_lower_triangular_in_place(
                diagonal,
                top,
                Par::Seq,
            );
            workspace.clear();
            workspace.resize(node.pattern.len(), 0.0);
            faer::linalg::matmul::matmul(
                MatMut::from_column_major_slice_mut(&mut workspace, node.pattern.len(), 1),
                Accum::Replace,
                below,
                MatRef::from_column_major_slice(&z[start..end], node.size, 1),
                1.0,
                Par::Seq,
            );
            for (&row, &product) in node.pattern.iter().zip(workspace.iter()) {
                z[row] -= product;
            }
            continue;
        }
        for jj in 0..node.size {
            let column = node.column(jj);
            let top = &mut z[start..end];
            let value = top[jj] / column[jj];
            top[jj] = value;
            for (entry, &l) in top[jj + 1..].iter_mut().zip(&column[jj + 1..node.size]) {
                *entry -= l * value;
            }
            for (&row, &l) in node.pattern.iter().zip(&column[node.size..]) {
                z[row] -= l * value;
            }
        }
    }
}

/// z ← L⁻ᵀ z (z in elimination order).
pub(crate) fn backward(
    symbolic: &SymbolicSupernodalCholesky<usize>,
    values: &[f64],
    z: &mut [f64],
) {
    // the pattern's products (forward) or values (backward) of a wide supernode
    let mut workspace = Vec::new();
    for s in (0..symbolic.n_supernodes()).rev() {
        let node = supernode(symbolic, values, s);
        let (start, end) = (node.start, node.start + node.size);
        if node.is_wide() {
            let (diagonal, below) = node.blocks();
            workspace.clear();
            workspace.extend(node.pattern.iter().map(|&row| z[row]));
            let mut top = MatMut::from_column_major_slice_mut(&mut z[start..end], node.size, 1);
            faer::linalg::matmul::matmul(
                top.as_mut(),
                Accum::Add,
                below.transpose(),
                MatRef::from_column_major_slice(&workspace, node.pattern.len(), 1),
                -1.0,
                Par::Seq,
            );
            faer::linalg::triangular_solve::solve_upper_triangular_in_place(
                diagonal.transpose(),
                top,
                Par::Seq,
            );
            continue;
        }
        for jj in (0..node.size).rev() {
            let column = node.column(jj);
            let mut sum = 0.0;
            for (&row, &l) in node.pattern.iter().zip(&column[node.size..]).rev() {
                sum += l * z[row];
            }
            for (&entry, &l) in z[start + jj + 1..end]
                .iter()
                .zip(&column[jj + 1..node.size])
                .rev()
            {
                sum += l * entry;
            }
            z[start + jj] = (z[start + jj] - sum) / column[jj];
        }
    }
}

/// The supernodal elimination tree of a factor: the supernode of each column and the parent
/// of each supernode (the supernode of the first row of its pattern), for solves with a
/// sparse right-hand side (Gilbert 1994: the nonzeros of L⁻¹ b are the columns reachable from
/// those of b in the elimination tree).
pub(crate) struct SupernodeTree {
    of_column: Vec<usize>,
    /// `usize::MAX` for a root.
    parent: Vec<usize>,
    begin: Vec<usize>,
    end: Vec<usize>,
    /// Marks of [`SupernodeTree::reach`], all false between calls.
    marked: Vec<bool>,
}

impl SupernodeTree {
    pub(crate) fn new(symbolic: &SymbolicSupernodalCholesky<usize>) -> Self {
        let count = symbolic.n_supernodes();
        let begin = symbolic.supernode_begin().to_vec();
        let end = symbolic.supernode_end().to_vec();
        let mut of_column = vec![0; end.last().copied().unwrap_or(0)];
        for s in 0..count {
            of_column[begin[s]..end[s]].fill(s);
        }
        let rows = symbolic.col_ptr_for_row_idx();
        let parent = (0..count)
            .map(|s| {
                let pattern = &symbolic.row_idx()[rows[s]..rows[s + 1]];
                pattern
                    .iter()
                    .min()
                    .map_or(usize::MAX, |&row| of_column[row])
            })
            .collect();
        Self {
            of_column,
            parent,
            begin,
            end,
            marked: vec![false; count],
        }
    }

    /// The supernodes whose columns L⁻¹ b may make nonzero, for b nonzero at `columns`
    /// (elimination order), ascending: the paths from their supernodes to the root.
    pub(crate) fn reach(&mut self, columns: impl IntoIterator<Item = usize>) -> Vec<usize> {
        let mut reached = Vec::new();
        for column in columns {
            let mut s = self.of_column[column];
            while s != usize::MAX && !self.marked[s] {
                self.marked[s] = true;
                reached.push(s);
                s = self.parent[s];
            }
        }
        for &s in &reached {
            self.marked[s] = false;
        }
        reached.sort_unstable();
        reached
    }

    /// The columns of the supernode `s`.
    pub(crate) fn columns(&self, s: usize) -> std::ops::Range<usize> {
        self.begin[s]..self.end[s]
    }
}

/// Number of supernodes of at least [`WIDE_SUPERNODE`] columns, and of all supernodes.
pub(crate) fn wide_supernodes(symbolic: &SymbolicSupernodalCholesky<usize>) -> (usize, usize) {
    let begin = symbolic.supernode_begin();
    let end = symbolic.supernode_end();
    let wide = (0..symbolic.n_supernodes())
        .filter(|&s| end[s] - begin[s] >= WIDE_SUPERNODE)
        .count();
    (wide, symbolic.n_supernodes())
}

#[cfg(test)]
mod tests {
    use crate::algebra::linalg::{CholeskySolver, FactorKind};
    use faer::sparse::{SparseColMat, Triplet};
    use proptest::prelude::*;

    /// A sparse SPD matrix of `n` unknowns: a random band of couplings (narrow supernodes)
    /// plus `dense` trailing unknowns coupled with each other and with every `stride`-th
    /// unknown (a wide trailing supernode, as the separators of a 3D factor).
    fn matrix(n: usize, dense: usize, stride: usize, seed: u64) -> SparseColMat<usize, f64> {
        let mut generator = crate::test_random::SeededRandom::new(seed);
        let mut random = || generator.range(-0.5, 0.5);
        let mut triplets = Vec::new();
        let mut diagonal = vec![1.0; n];
        let mut couple = |i: usize, j: usize, value: f64, diagonal: &mut Vec<f64>| {
            triplets.push(Triplet::new(i, j, value));
            triplets.push(Triplet::new(j, i, value));
            diagonal[i] += value.abs();
            diagonal[j] += value.abs();
        };
        let sparse = n - dense;
        for i in 0..sparse {
            for offset in [1, 2, 7] {
                if i + offset < sparse && random() > -0.2 {
                    couple(i, i + offset, random(), &mut diagonal);
                }
            }
        }
        for i in sparse..n {
            for j in sparse..i {
                couple(i, j, random(), &mut diagonal);
            }
            for j in (0..sparse).step_by(stride) {
                couple(i, j, random(), &mut diagonal);
            }
        }
        for (i, d) in diagonal.iter().enumerate() {
            triplets.push(Triplet::new(i, i, *d));
        }
        SparseColMat::try_new_from_triplets(n, n, &triplets).unwrap()
    }

    /// The supernodal factor of [`matrix`]`(n, dense, stride, seed)`.
    fn factor(n: usize, dense: usize, stride: usize, seed: u64) -> CholeskySolver {
        let a = matrix(n, dense, stride, seed);
        let mut solver = CholeskySolver::analyse_as(&a, FactorKind::Supernodal, "test").unwrap();
        solver.factorize(&a).unwrap();
        solver
    }

    /// On a matrix of two uncoupled tridiagonal blocks, the sparse forward solve of a unit
    /// vector of the first block visits no column of the second: it is sparse, not the full
    /// sweep.
    #[test]
    fn sparse_forward_solve_stays_in_the_block_of_its_right_hand_side() {
        let block = 50;
        let mut triplets = Vec::new();
        for i in 0..2 * block {
            triplets.push(Triplet::new(i, i, 4.0));
            if i + 1 < 2 * block && i + 1 != block {
                triplets.push(Triplet::new(i, i + 1, -1.0));
                triplets.push(Triplet::new(i + 1, i, -1.0));
            }
        }
        let a = SparseColMat::try_new_from_triplets(2 * block, 2 * block, &triplets).unwrap();
        let mut solver = CholeskySolver::analyse_as(&a, FactorKind::Supernodal, "test").unwrap();
        solver.factorize(&a).unwrap();
        let ordering = solver.ordering();
        let mut tree = solver.supernode_tree().unwrap();
        let mut scratch = vec![0.0; 2 * block];
        let (rows, values) = solver
            .forward_solve_sparse(&mut tree, &[(3, 1.0)], &mut scratch)
            .unwrap();
        assert!(
            !rows.is_empty() && rows.len() <= block,
            "{} rows",
            rows.len()
        );
        assert!(rows.iter().all(|&row| ordering[row] < block));
        assert!(values.iter().any(|&v| v != 0.0));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        /// The column sweeps and dense kernels of `forward`/`backward` solve as faer's own
        /// supernodal solve does (to 1e-13 relative), on factors with both narrow and wide
        /// supernodes, and the two halves compose bitwise to `CholeskySolver::solve`.
        #[test]
        fn supernodal_sweeps_solve_like_faer_on_narrow_and_wide_supernodes(
            sparse in 60usize..400,
            dense in 33usize..80,
            stride in 3usize..20,
            seed in any::<u64>(),
        ) {
            let n = sparse + dense;
            let solver = factor(n, dense, stride, seed);
            let (wide, all) = solver.wide_supernodes().unwrap();
            prop_assert!(wide >= 1 && wide < all, "wide {wide} of {all} supernodes");
            let rhs: Vec<f64> = (0..n).map(|i| ((i * 7919 + seed as usize % 97) % 101) as f64 / 50.0 - 1.0).collect();
            let x = solver.solve(&rhs).unwrap();
            // faer's solve: two right-hand sides take its supernodal path
            let mut block = faer::Mat::<f64>::from_fn(n, 2, |i, _| rhs[i]);
            solver.solve_block(block.as_mut()).unwrap();
            let scale = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for (i, value) in x.iter().enumerate() {
                prop_assert!((value - block[(i, 0)]).abs() <= 1e-13 * scale, "{i}: {value} vs {}", block[(i, 0)]);
            }
            let z = solver.forward_solve(&rhs).unwrap().unwrap();
            let halves = solver.backward_solve(&z).unwrap().unwrap();
            prop_assert_eq!(
                halves.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                x.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
            );
        }

        /// A forward solve with a right-hand side of a few nonzeros, over the supernodes
        /// reachable from them only, gives the values of the full forward solve on the columns
        /// it returns, and the full solve is zero on every other column.
        #[test]
        fn sparse_forward_solve_is_the_full_one_on_its_reach(
            sparse in 60usize..400,
            dense in 33usize..80,
            stride in 3usize..20,
            seed in any::<u64>(),
            picks in proptest::collection::vec((any::<prop::sample::Index>(), -2.0f64..2.0), 1..4),
        ) {
            let n = sparse + dense;
            let solver = factor(n, dense, stride, seed);
            let rhs: Vec<(usize, f64)> = picks.iter().map(|(index, value)| (index.index(n), *value)).collect();
            let mut dense_rhs = vec![0.0; n];
            for &(unknown, value) in &rhs {
                dense_rhs[unknown] += value;
            }
            let full = solver.forward_solve(&dense_rhs).unwrap().unwrap();
            let mut tree = solver.supernode_tree().unwrap();
            let mut scratch = vec![0.0; n];
            let (rows, values) = solver.forward_solve_sparse(&mut tree, &rhs, &mut scratch).unwrap();
            prop_assert!(scratch.iter().all(|&v| v == 0.0), "the scratch is left zero");
            prop_assert!(rows.windows(2).all(|pair| pair[0] < pair[1]));
            let mut on_reach = vec![false; n];
            for (&row, &value) in rows.iter().zip(&values) {
                on_reach[row] = true;
                prop_assert_eq!(value.to_bits(), full[row].to_bits(), "row {}", row);
            }
            for (row, &value) in full.iter().enumerate() {
                prop_assert!(on_reach[row] || value == 0.0, "row {} off the reach holds {}", row, value);
            }
        }
    }
}
