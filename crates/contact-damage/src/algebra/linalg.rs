//! Sparse linear algebra: assembly patterns (symbolic once, values many times) and a sparse
//! Cholesky solver whose symbolic analysis is reused across numeric factorizations (faer).

use crate::algebra::triangular;
use crate::error::{Error, Result};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::supernodal::{SupernodalLltRef, SymbolicSupernodalCholesky};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky,
    SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{Pair, SparseColMat, SymbolicSparseColMat};
use faer::{Conj, Mat, Side};
use rayon::prelude::*;
use std::sync::Arc;

/// The sparsity pattern of an assembled matrix together with the order in which element values
/// are summed into it. Entries whose row or column is negative are dropped (eliminated dofs).
///
/// Expensive analysis once, cheap reuse: [`SparsityPattern::from_pairs`] sorts the (row, column)
/// pairs of all element entries once (a counting sort: two passes over the entries);
/// [`SparsityPattern::matrix`] then sums the element values into the compressed columns with a
/// parallel gather, without sorting.
#[derive(Debug, Clone)]
pub struct SparsityPattern {
    size: usize,
    value_count: usize,
    symbolic: SymbolicSparseColMat<usize>,
    /// sources[starts[k]..starts[k + 1]]: the element values summed into stored entry k.
    starts: Vec<usize>,
    sources: Vec<u32>,
}

/// The values of `(key, value)` items with keys below `keys`, stably sorted by key.
fn counting_sort(keys: usize, items: impl Iterator<Item = (usize, u32)> + Clone) -> Vec<u32> {
    let mut next = vec![0usize; keys + 1];
    for (key, _) in items.clone() {
        next[key + 1] += 1;
    }
    for key in 0..keys {
        next[key + 1] += next[key];
    }
    let mut sorted = vec![0u32; next[keys]];
    for (key, value) in items {
        sorted[next[key]] = value;
        next[key] += 1;
    }
    sorted
}

impl SparsityPattern {
    /// Builds the pattern of a `size × size` matrix from (row, column) pairs, one per element value;
    /// pairs with a negative index are ignored when values are summed.
    pub fn from_pairs(size: usize, pairs: &[Pair<isize, isize>]) -> Result<Self> {
        if pairs.len() > u32::MAX as usize {
            return Err(Error::InvalidInput(format!(
                "{} element entries exceed the 2^32 supported by one pattern",
                pairs.len()
            )));
        }
        if let Some(bad) = pairs
            .iter()
            .find(|p| p.row >= size as isize || p.col >= size as isize)
        {
            return Err(Error::InvalidInput(format!(
                "pattern entry ({}, {}) outside a {size} × {size} matrix",
                bad.row, bad.col
            )));
        }
        // The entries in the order of (column, row), those of one position in the order of
        // `pairs`: a counting sort by row, then a stable counting sort by column (two passes
        // over the entries, against a comparison sort of them all).
        let kept = |p: &Pair<isize, isize>| p.row >= 0 && p.col >= 0;
        let by_row = counting_sort(
            size,
            pairs
                .iter()
                .enumerate()
                .filter(|(_, p)| kept(p))
                .map(|(i, p)| (p.row as usize, i as u32)),
        );
        let sources = counting_sort(
            size,
            by_row.iter().map(|&i| (pairs[i as usize].col as usize, i)),
        );
        let mut col_ptr = vec![0usize; size + 1];
        let mut row_idx = Vec::new();
        let mut starts = Vec::new();
        let mut previous = None;
        for (position, &i) in sources.iter().enumerate() {
            let pair = &pairs[i as usize];
            let entry = (pair.col as usize, pair.row as usize);
            if Some(entry) != previous {
                row_idx.push(entry.1);
                starts.push(position);
                col_ptr[entry.0 + 1] += 1;
                previous = Some(entry);
            }
        }
        starts.push(sources.len());
        for col in 0..size {
            col_ptr[col + 1] += col_ptr[col];
        }
        let symbolic =
            SymbolicSparseColMat::<usize>::new_checked(size, size, col_ptr, None, row_idx);
        Ok(Self {
            size,
            value_count: pairs.len(),
            symbolic,
            starts,
            sources,
        })
    }

    /// Number of rows (= columns).
    pub fn size(&self) -> usize {
        self.size
    }

    /// Number of element values expected by [`SparsityPattern::matrix`].
    pub fn value_count(&self) -> usize {
        self.value_count
    }

    /// Number of stored nonzeros.
    pub fn nnz(&self) -> usize {
        self.starts.len() - 1
    }

    /// Sums the element values (in the order of the pairs) into a sparse matrix.
    pub fn matrix(&self, values: &[f64]) -> Result<SparseColMat<usize, f64>> {
        if values.len() != self.value_count {
            return Err(Error::InvalidInput(format!(
                "pattern expects {} values, got {}",
                self.value_count,
                values.len()
            )));
        }
        let summed: Vec<f64> = self
            .starts
            .par_windows(2)
            .map(|range| {
                self.sources[range[0]..range[1]]
                    .iter()
                    .map(|&i| values[i as usize])
                    .sum()
            })
            .collect();
        Ok(SparseColMat::new(self.symbolic.clone(), summed))
    }
}

/// Which sparse Cholesky factorization faer computes: the simplicial (column by column) or the
/// supernodal (dense blocks of columns with the same pattern) one. [`FactorKind::Auto`] is
/// faer's own rule: supernodal when the flop count per factor nonzero exceeds a threshold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FactorKind {
    /// faer's flop-ratio heuristic.
    #[default]
    Auto,
    /// Always the simplicial factorization.
    Simplicial,
    /// Always the supernodal factorization.
    Supernodal,
}

impl FactorKind {
    /// The threshold of faer's symbolic analysis that realizes this choice.
    pub fn threshold(self) -> SupernodalThreshold {
        match self {
            FactorKind::Auto => SupernodalThreshold::AUTO,
            FactorKind::Simplicial => SupernodalThreshold::FORCE_SIMPLICIAL,
            FactorKind::Supernodal => SupernodalThreshold::FORCE_SUPERNODAL,
        }
    }
}

/// Sparse Cholesky solver for symmetric positive definite matrices of one fixed pattern: the
/// symbolic analysis (fill-reducing ordering, elimination tree, supernodes) is done once in
/// [`CholeskySolver::analyse`] or [`CholeskySolver::analyse_with_ordering`]; numeric
/// factorizations reuse it.
#[derive(Debug, Clone)]
pub struct CholeskySolver {
    size: usize,
    symbolic: Arc<SymbolicCholesky<usize>>,
    factor: Option<Vec<f64>>,
    context: &'static str,
}

impl CholeskySolver {
    /// Symbolic analysis of the pattern of `matrix` with an approximate minimum degree ordering
    /// (the lower triangle is read).
    pub fn analyse(matrix: &SparseColMat<usize, f64>, context: &'static str) -> Result<Self> {
        Self::analyse_ordered(matrix, None, FactorKind::Auto, context)
    }

    /// Symbolic analysis with an approximate minimum degree ordering and a chosen
    /// simplicial/supernodal factor (for measurements; [`CholeskySolver::analyse`] lets faer
    /// choose).
    pub fn analyse_as(
        matrix: &SparseColMat<usize, f64>,
        kind: FactorKind,
        context: &'static str,
    ) -> Result<Self> {
        Self::analyse_ordered(matrix, None, kind, context)
    }

    /// [`CholeskySolver::analyse_with_ordering`] with a chosen simplicial/supernodal factor.
    pub fn analyse_with_ordering_as(
        matrix: &SparseColMat<usize, f64>,
        ordering: &[usize],
        kind: FactorKind,
        context: &'static str,
    ) -> Result<Self> {
        Self::analyse_ordered(matrix, Some(ordering), kind, context)
    }

    /// Symbolic analysis with a given elimination order (`ordering[position] = unknown`), e.g. a
    /// nested dissection from [`crate::algebra::ordering`].
    pub fn analyse_with_ordering(
        matrix: &SparseColMat<usize, f64>,
        ordering: &[usize],
        context: &'static str,
    ) -> Result<Self> {
        Self::analyse_ordered(matrix, Some(ordering), FactorKind::Auto, context)
    }

    fn analyse_ordered(
        matrix: &SparseColMat<usize, f64>,
        ordering: Option<&[usize]>,
        kind: FactorKind,
        context: &'static str,
    ) -> Result<Self> {
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: kind.threshold(),
            ..Default::default()
        };
        let size = matrix.nrows();
        let failure = |message: String| Error::LinearAlgebra {
            context: context.into(),
            message,
        };
        let symbolic = match ordering {
            None => factorize_symbolic_cholesky(
                matrix.symbolic(),
                Side::Lower,
                SymmetricOrdering::Amd,
                params,
            ),
            Some(forward) => {
                if forward.len() != size {
                    return Err(failure(format!(
                        "ordering has {} entries for {size} unknowns",
                        forward.len()
                    )));
                }
                let mut inverse = vec![usize::MAX; size];
                for (position, &unknown) in forward.iter().enumerate() {
                    if unknown >= size || inverse[unknown] != usize::MAX {
                        return Err(failure(format!(
                            "ordering is not a permutation (entry {unknown})"
                        )));
                    }
                    inverse[unknown] = position;
                }
                let permutation = PermRef::new_checked(forward, &inverse, size);
                factorize_symbolic_cholesky(
                    matrix.symbolic(),
                    Side::Lower,
                    SymmetricOrdering::Custom(permutation),
                    params,
                )
            }
        }
        .map_err(|e| failure(format!("symbolic Cholesky analysis failed: {e:?}")))?;
        Ok(Self {
            size,
            symbolic: Arc::new(symbolic),
            factor: None,
            context,
        })
    }

    /// Whether the factor is supernodal (else simplicial).
    pub fn is_supernodal(&self) -> bool {
        matches!(self.symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_))
    }

    /// The elimination order (`ordering[position] = unknown`) of the analysis.
    pub fn ordering(&self) -> Vec<usize> {
        match self.symbolic.perm() {
            Some(perm) => perm.arrays().0.to_vec(),
            None => (0..self.size).collect(),
        }
    }

    /// Number of stored values of the factor L (a measure of fill).
    pub fn factor_len(&self) -> usize {
        self.symbolic.len_val()
    }

    /// Floating-point operations of a numeric factorization, counted from the symbolic
    /// structure: for a supernode of w columns with r rows below its diagonal block, w³/3 for
    /// the dense Cholesky factorization of the block, r w² for the triangular solve of the rows
    /// below it and r² w for the update of the later columns (the lower half of an r × r
    /// product of inner dimension w); for a simplicial factor, Σ_j c_j² over its column
    /// counts c_j. The cost of the numeric factorization follows this count, not the number
    /// of stored values: two orderings with about the same fill can differ in cost by 25 %.
    pub fn factor_flops(&self) -> f64 {
        match self.symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(symbolic) => {
                let begin = symbolic.supernode_begin();
                let end = symbolic.supernode_end();
                let rows = symbolic.col_ptr_for_row_idx();
                (0..symbolic.n_supernodes())
                    .map(|s| {
                        let width = (end[s] - begin[s]) as f64;
                        let below = (rows[s + 1] - rows[s]) as f64;
                        width * width * width / 3.0 + below * width * width + below * below * width
                    })
                    .sum()
            }
            SymbolicCholeskyRaw::Simplicial(symbolic) => symbolic
                .col_ptr()
                .windows(2)
                .map(|pair| {
                    let count = (pair[1] - pair[0]) as f64;
                    count * count
                })
                .sum(),
        }
    }

    /// Numeric factorization of `matrix` (same pattern as analysed).
    pub fn factorize(&mut self, matrix: &SparseColMat<usize, f64>) -> Result<()> {
        let par = faer::get_global_parallelism();
        let mut values = self.factor.take().unwrap_or_default();
        values.resize(self.symbolic.len_val(), 0.0);
        let mut memory = MemBuffer::try_new(
            self.symbolic
                .factorize_numeric_llt_scratch::<f64>(par, Default::default()),
        )
        .map_err(|e| Error::LinearAlgebra {
            context: self.context.into(),
            message: format!("out of memory for the factorization workspace: {e:?}"),
        })?;
        self.symbolic
            .factorize_numeric_llt(
                &mut values,
                matrix.as_ref(),
                Side::Lower,
                LltRegularization::default(),
                par,
                MemStack::new(&mut memory),
                Default::default(),
            )
            .map_err(|e| Error::LinearAlgebra {
                context: self.context.into(),
                message: format!(
                    "Cholesky factorization failed (matrix not positive definite?): {e:?}"
                ),
            })?;
        self.factor = Some(values);
        Ok(())
    }

    /// The trailing `m × m` block L_cc of the factor (lower triangular, in elimination order) and
    /// the unknowns eliminated last, when the factor is supernodal. If the last `m` unknowns of
    /// the ordering are the set C, then L_cc L_ccᵀ is the Schur complement of A onto C.
    /// None for simplicial factors or before factorization.
    pub fn trailing_factor(&self, m: usize) -> Option<(Mat<f64>, Vec<usize>)> {
        let values = self.factor.as_ref()?;
        let SymbolicCholeskyRaw::Supernodal(symbolic) = self.symbolic.raw() else {
            return None;
        };
        let n = self.size;
        if m > n {
            return None;
        }
        let first = n - m;
        let factor = SupernodalLltRef::new(symbolic, values);
        let mut block = Mat::<f64>::zeros(m, m);
        for s in 0..symbolic.n_supernodes() {
            let node = factor.supernode(s);
            let start = node.start();
            let val = node.val();
            let width = val.ncols();
            if start + width <= first {
                continue;
            }
            for j in 0..width {
                let col = start + j;
                if col < first {
                    continue;
                }
                for i in j..width {
                    block[(start + i - first, col - first)] = val[(i, j)];
                }
                for (k, &row) in node.pattern().iter().enumerate() {
                    if row >= first {
                        block[(row - first, col - first)] = val[(width + k, j)];
                    }
                }
            }
        }
        let unknowns = match self.symbolic.perm() {
            Some(perm) => perm.arrays().0[first..].to_vec(),
            None => (first..n).collect(),
        };
        Some((block, unknowns))
    }

    /// True once a numeric factorization is available.
    pub fn is_factorized(&self) -> bool {
        self.factor.is_some()
    }

    /// Solves A x = b. With a supernodal factor this is [`CholeskySolver::forward_solve`] then
    /// [`CholeskySolver::backward_solve`] (bitwise): column sweeps over the narrow supernodes
    /// and faer's dense kernels over those of at least 32 columns, about twice as fast as
    /// faer's supernode-by-supernode solve on the narrow supernodes of 2D meshes.
    pub fn solve(&self, rhs: &[f64]) -> Result<Vec<f64>> {
        if rhs.len() != self.size {
            return Err(Error::InvalidInput(format!(
                "{}: right-hand side has length {}, expected {}",
                self.context,
                rhs.len(),
                self.size
            )));
        }
        if let Some(z) = self.forward_solve(rhs)? {
            return Ok(self.backward_solve(&z)?.expect("the factor is supernodal"));
        }
        let mut x = Mat::<f64>::from_fn(self.size, 1, |i, _| rhs[i]);
        self.solve_block(x.as_mut())?;
        Ok((0..self.size).map(|i| x[(i, 0)]).collect())
    }

    /// Solves A X = B in place for a block of right-hand sides (one column with a supernodal
    /// factor: by [`CholeskySolver::solve`]).
    pub fn solve_block(&self, mut block: faer::MatMut<'_, f64>) -> Result<()> {
        let values = self.factor.as_ref().ok_or_else(|| Error::LinearAlgebra {
            context: self.context.into(),
            message: "solve requested before factorization".into(),
        })?;
        if block.ncols() == 1 && self.is_supernodal() {
            let column: Vec<f64> = (0..block.nrows()).map(|i| block[(i, 0)]).collect();
            for (i, value) in self.solve(&column)?.into_iter().enumerate() {
                block[(i, 0)] = value;
            }
            return Ok(());
        }
        // Triangular solves are memory-bound: measured on 2 cores (2D, 0.5 M unknowns, 128
        // right-hand sides) the sequential solve took 3.8 s against 11.3 s with rayon, and the
        // velocity and damage steps already run concurrently.
        let par = faer::Par::Seq;
        let mut memory = MemBuffer::try_new(
            self.symbolic
                .solve_in_place_scratch::<f64>(block.ncols(), par),
        )
        .map_err(|e| Error::LinearAlgebra {
            context: self.context.into(),
            message: format!("out of memory for the solve workspace: {e:?}"),
        })?;
        LltRef::new(&self.symbolic, values).solve_in_place_with_conj(
            Conj::No,
            block,
            par,
            MemStack::new(&mut memory),
        );
        Ok(())
    }

    /// The forward half of a solve with a supernodal factor P A Pᵀ = L Lᵀ: z = L⁻¹ P b, in
    /// elimination order. With [`CholeskySolver::backward_solve`], x = Pᵀ L⁻ᵀ z = A⁻¹ b. None
    /// for a simplicial factor; an error before factorization or for a wrong length.
    ///
    /// Used where the trailing unknowns of the ordering carry a correction between the two
    /// halves: a right-hand side that changes only there changes only the trailing block of z
    /// (the velocity step (5.1) with its contact unknowns last, [`Self::trailing_factor`]).
    pub fn forward_solve(&self, rhs: &[f64]) -> Result<Option<Vec<f64>>> {
        let Some((symbolic, values)) = self.supernodal()? else {
            return Ok(None);
        };
        self.check_length(rhs.len())?;
        let mut z = match self.symbolic.perm() {
            Some(perm) => perm
                .arrays()
                .0
                .iter()
                .map(|&unknown| rhs[unknown])
                .collect(),
            None => rhs.to_vec(),
        };
        triangular::forward(symbolic, values, &mut z);
        Ok(Some(z))
    }

    /// The backward half: x = Pᵀ L⁻ᵀ z for z in elimination order (see
    /// [`CholeskySolver::forward_solve`]). None for a simplicial factor.
    pub fn backward_solve(&self, z: &[f64]) -> Result<Option<Vec<f64>>> {
        let Some((symbolic, values)) = self.supernodal()? else {
            return Ok(None);
        };
        self.check_length(z.len())?;
        let mut y = z.to_vec();
        triangular::backward(symbolic, values, &mut y);
        Ok(Some(match self.symbolic.perm() {
            Some(perm) => {
                let mut x = vec![0.0; self.size];
                for (&unknown, value) in perm.arrays().0.iter().zip(y) {
                    x[unknown] = value;
                }
                x
            }
            None => y,
        }))
    }

    /// The supernodal elimination tree of the factor, for
    /// [`CholeskySolver::forward_solve_sparse`]; None for a simplicial analysis.
    pub(crate) fn supernode_tree(&self) -> Option<triangular::SupernodeTree> {
        match self.symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(symbolic) => {
                Some(triangular::SupernodeTree::new(symbolic))
            }
            SymbolicCholeskyRaw::Simplicial(_) => None,
        }
    }

    /// The forward half z = L⁻¹ P b ([`CholeskySolver::forward_solve`]) of a right-hand side b
    /// with few nonzeros, `rhs` as (unknown, value) pairs: the sweep visits only the supernodes
    /// reachable from those unknowns in the elimination tree `tree` (from
    /// [`CholeskySolver::supernode_tree`]), with the operations of the full sweep on them.
    /// Returns the positions (elimination order, ascending) and values of z on the columns of
    /// those supernodes, every other entry of z being zero. `scratch` holds one zero per
    /// unknown, and again on return. Errors: a simplicial factor, no factor yet, lengths.
    pub(crate) fn forward_solve_sparse(
        &self,
        tree: &mut triangular::SupernodeTree,
        rhs: &[(usize, f64)],
        scratch: &mut [f64],
    ) -> Result<(Vec<usize>, Vec<f64>)> {
        let Some((symbolic, values)) = self.supernodal()? else {
            return Err(Error::LinearAlgebra {
                context: self.context.into(),
                message: "a sparse forward solve needs a supernodal factor".into(),
            });
        };
        self.check_length(scratch.len())?;
        let inverse = self.symbolic.perm().map(|perm| perm.arrays().1);
        let position = |unknown: usize| inverse.map_or(unknown, |inverse| inverse[unknown]);
        for &(unknown, value) in rhs {
            if unknown >= self.size {
                return Err(Error::InvalidInput(format!(
                    "{}: right-hand side entry at unknown {unknown}, expected < {}",
                    self.context, self.size
                )));
            }
            scratch[position(unknown)] += value;
        }
        let supernodes = tree.reach(rhs.iter().map(|&(unknown, _)| position(unknown)));
        triangular::forward_on(symbolic, values, scratch, supernodes.iter().copied());
        let mut rows = Vec::new();
        let mut entries = Vec::new();
        for &s in &supernodes {
            for row in tree.columns(s) {
                rows.push(row);
                entries.push(std::mem::take(&mut scratch[row]));
            }
        }
        Ok((rows, entries))
    }

    /// Supernodes of at least 32 columns (solved with dense kernels, the narrower ones column
    /// by column) and all supernodes of a supernodal analysis; None for a simplicial one.
    pub fn wide_supernodes(&self) -> Option<(usize, usize)> {
        match self.symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(symbolic) => {
                Some(triangular::wide_supernodes(symbolic))
            }
            SymbolicCholeskyRaw::Simplicial(_) => None,
        }
    }

    /// The supernodal symbolic factor and the factor's values, None if the factor is
    /// simplicial; an error before factorization.
    fn supernodal(&self) -> Result<Option<(&SymbolicSupernodalCholesky<usize>, &[f64])>> {
        let values = self.factor.as_ref().ok_or_else(|| Error::LinearAlgebra {
            context: self.context.into(),
            message: "solve requested before factorization".into(),
        })?;
        Ok(match self.symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(symbolic) => Some((symbolic, values.as_slice())),
            SymbolicCholeskyRaw::Simplicial(_) => None,
        })
    }

    /// An error unless `len` is the number of unknowns.
    fn check_length(&self, len: usize) -> Result<()> {
        if len == self.size {
            return Ok(());
        }
        Err(Error::InvalidInput(format!(
            "{}: right-hand side has length {len}, expected {}",
            self.context, self.size
        )))
    }
}

/// y = A x for a sparse matrix in full (both triangles) storage.
pub fn multiply(matrix: &SparseColMat<usize, f64>, x: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; matrix.nrows()];
    multiply_into(matrix, x, &mut y);
    y
}

/// The Euclidean inner product `uᵀv`, summed in index order (the same bits on every run and
/// any number of threads).
pub fn dot(u: &[f64], v: &[f64]) -> f64 {
    u.iter().zip(v).map(|(a, b)| a * b).sum()
}

/// `product = A x` into a given vector (column-oriented scatter, valid for any stored matrix;
/// `product` has `A.nrows()` entries).
pub fn multiply_into(matrix: &SparseColMat<usize, f64>, x: &[f64], product: &mut [f64]) {
    product.fill(0.0);
    let col_ptr = matrix.symbolic().col_ptr();
    let row_idx = matrix.symbolic().row_idx();
    let values = matrix.val();
    for (col, &xc) in x.iter().enumerate().take(matrix.ncols()) {
        if xc == 0.0 {
            continue;
        }
        for k in col_ptr[col]..col_ptr[col + 1] {
            product[row_idx[k]] += values[k] * xc;
        }
    }
}

/// Partial maxima kept apart in the reductions [`max_abs`] and [`max_abs_free`].
const MAX_LANES: usize = 8;

/// `max_i |v_i|` (0 for an empty slice; a NaN entry is ignored, as by `f64::max`).
///
/// The running maximum is kept in eight independent partial maxima, so that the loop
/// is not one chain of dependent comparisons (each waiting for the one before) and
/// vectorizes. A maximum does not depend on the order of its terms, so the value is bitwise
/// that of the sequential fold `fold(0.0, |m, v| m.max(v.abs()))`.
pub fn max_abs(values: &[f64]) -> f64 {
    let mut lanes = [0.0_f64; MAX_LANES];
    let mut chunks = values.chunks_exact(MAX_LANES);
    for chunk in &mut chunks {
        for (lane, value) in lanes.iter_mut().zip(chunk) {
            *lane = lane.max(value.abs());
        }
    }
    for value in chunks.remainder() {
        lanes[0] = lanes[0].max(value.abs());
    }
    lanes.into_iter().fold(0.0, f64::max)
}

/// The largest magnitude of a datum of a step (a load entry, a pressure, a friction bound, a
/// prescribed velocity, a penetration) that the solvers accept. They form squared norms and
/// energies of these vectors: √f64::MAX ≈ 1.3e154, and 1e150 leaves room for sums of 10⁸
/// squares. Data beyond it are out of the scale of double precision, not a hard problem: the
/// remedy is to change the problem's units.
pub const MAGNITUDE_LIMIT: f64 = 1e150;

/// Whether `value` is at most [`MAGNITUDE_LIMIT`] in magnitude (false for a NaN).
pub fn within_scale(value: f64) -> bool {
    value.abs() <= MAGNITUDE_LIMIT
}

/// The first index whose value is not [`within_scale`] (a NaN included).
pub fn first_out_of_scale(values: &[f64]) -> Option<usize> {
    values.iter().position(|&v| !within_scale(v))
}

/// `max |v_i|` over the indices with `excluded[i] == false`, as [`max_abs`] (bitwise the
/// sequential fold over those indices).
///
/// # Panics
/// If `values` and `excluded` differ in length.
pub fn max_abs_free(values: &[f64], excluded: &[bool]) -> f64 {
    assert_eq!(values.len(), excluded.len(), "one flag per value");
    let mut lanes = [0.0_f64; MAX_LANES];
    let mut chunks = values.chunks_exact(MAX_LANES);
    let mut flags = excluded.chunks_exact(MAX_LANES);
    for (chunk, flags) in (&mut chunks).zip(&mut flags) {
        for ((lane, value), &excluded) in lanes.iter_mut().zip(chunk).zip(flags) {
            *lane = lane.max(if excluded { 0.0 } else { value.abs() });
        }
    }
    for (value, &excluded) in chunks.remainder().iter().zip(flags.remainder()) {
        if !excluded {
            lanes[0] = lanes[0].max(value.abs());
        }
    }
    lanes.into_iter().fold(0.0, f64::max)
}

/// y = A x for a symmetric matrix in full (both triangles) storage: see
/// [`multiply_symmetric_into`].
pub fn multiply_symmetric(matrix: &SparseColMat<usize, f64>, x: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; matrix.nrows()];
    multiply_symmetric_into(matrix, x, &mut y);
    y
}

/// `product = A x` for a symmetric matrix A in full (both triangles) storage, gathered: column
/// j of A is row j, so each entry of the product is one sequential sum over a stored column,
/// with no scattered writes (about twice as fast as [`multiply_into`]'s scatter on the
/// velocity operator). For a matrix stored bitwise symmetric (the mass matrices and the 2D P1
/// velocity operators of this crate) the result is bitwise that of [`multiply_into`]: both sum
/// the terms of a row in increasing column order, starting from zero; where the stored values
/// differ from their transposes by rounding (the P2 and the 3D velocity operators), so do the
/// products.
pub fn multiply_symmetric_into(matrix: &SparseColMat<usize, f64>, x: &[f64], product: &mut [f64]) {
    let col_ptr = matrix.symbolic().col_ptr();
    let row_idx = matrix.symbolic().row_idx();
    let values = matrix.val();
    for (j, entry) in product.iter_mut().enumerate().take(matrix.ncols()) {
        let range = col_ptr[j]..col_ptr[j + 1];
        let mut sum = 0.0;
        for (&i, &a) in row_idx[range.clone()].iter().zip(&values[range]) {
            sum += a * x[i];
        }
        *entry = sum;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The lane-wise maxima equal the sequential folds bit for bit, for any length (full
        /// lanes and a remainder), signs, NaN entries (ignored by both) and exclusions.
        #[test]
        fn max_abs_is_the_sequential_fold(
            values in proptest::collection::vec(
                prop_oneof![8 => -1e3..1e3_f64, 1 => Just(f64::NAN), 1 => Just(-0.0)],
                0..40,
            ),
            excluded_seed in any::<u64>(),
        ) {
            let sequential = values.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            prop_assert_eq!(max_abs(&values).to_bits(), sequential.to_bits());
            let excluded: Vec<bool> =
                (0..values.len()).map(|i| (excluded_seed >> (i % 64)) & 1 == 1).collect();
            let free = values
                .iter()
                .zip(&excluded)
                .filter(|(_, &e)| !e)
                .fold(0.0_f64, |m, (v, _)| m.max(v.abs()));
            prop_assert_eq!(max_abs_free(&values, &excluded).to_bits(), free.to_bits());
        }
    }

    #[test]
    fn pattern_sums_duplicates_and_drops_negative_indices() {
        let pairs = [
            Pair::new(0isize, 0isize),
            Pair::new(0, 0),
            Pair::new(1, 0),
            Pair::new(0, 1),
            Pair::new(1, 1),
            Pair::new(-1, 1),
        ];
        let pattern = SparsityPattern::from_pairs(2, &pairs).unwrap();
        let matrix = pattern.matrix(&[1.0, 2.0, -1.0, -1.0, 4.0, 100.0]).unwrap();
        let x = multiply(&matrix, &[1.0, 1.0]);
        assert_eq!(x, vec![2.0, 3.0]);
        let mut solver = CholeskySolver::analyse(&matrix, "test").unwrap();
        assert!(solver.solve(&[1.0, 0.0]).is_err());
        solver.factorize(&matrix).unwrap();
        let y = solver.solve(&[2.0, 3.0]).unwrap();
        assert!((y[0] - 1.0).abs() < 1e-14 && (y[1] - 1.0).abs() < 1e-14);
    }

    #[test]
    fn pattern_sums_the_values_of_each_entry_in_the_order_of_the_pairs() {
        // random pairs with many duplicates and some negative indices, random values
        let (size, count) = (17, 2000);
        let mut generator = crate::test_random::SeededRandom::new(2026);
        let mut pairs = Vec::new();
        let mut values = Vec::new();
        let index = |generator: &mut crate::test_random::SeededRandom| {
            generator.index(size + 2) as isize - 2
        };
        for _ in 0..count {
            let (row, col) = (index(&mut generator), index(&mut generator));
            pairs.push(Pair::new(row, col));
            values.push(generator.range(-1.0, 1.0));
        }
        let matrix = SparsityPattern::from_pairs(size, &pairs)
            .unwrap()
            .matrix(&values)
            .unwrap();
        // The reference: each entry's values added in the order of the pairs.
        let mut sums = std::collections::BTreeMap::<(usize, usize), f64>::new();
        for (pair, value) in pairs.iter().zip(&values) {
            if pair.row >= 0 && pair.col >= 0 {
                let sum = sums
                    .entry((pair.col as usize, pair.row as usize))
                    .or_insert(-0.0);
                *sum += value;
            }
        }
        let mut entries = Vec::new();
        for col in 0..size {
            let rows = matrix.symbolic().row_idx_of_col_raw(col);
            assert!(
                rows.windows(2).all(|w| w[0] < w[1]),
                "column {col}: rows sorted"
            );
            for (&row, value) in rows.iter().zip(matrix.val_of_col(col)) {
                entries.push(((col, row), value.to_bits()));
            }
        }
        let expected: Vec<((usize, usize), u64)> = sums
            .into_iter()
            .map(|(entry, sum)| (entry, sum.to_bits()))
            .collect();
        assert_eq!(entries, expected);
    }

    #[test]
    fn symmetric_product_is_bitwise_the_scatter_product_of_a_symmetric_matrix() {
        // a bitwise symmetric matrix with a random pattern and values, and a vector with zeros
        let n = 60;
        let mut generator = crate::test_random::SeededRandom::new(12345);
        let mut random = || generator.range(-0.5, 0.5);
        let mut triplets = Vec::new();
        for i in 0..n {
            triplets.push(faer::sparse::Triplet::new(i, i, 4.0 + random()));
            for j in 0..i {
                if random() > 0.3 {
                    let value = random();
                    triplets.push(faer::sparse::Triplet::new(i, j, value));
                    triplets.push(faer::sparse::Triplet::new(j, i, value));
                }
            }
        }
        let matrix = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &triplets).unwrap();
        let x: Vec<f64> = (0..n)
            .map(|i| if i % 7 == 0 { 0.0 } else { random() * 1e3 })
            .collect();
        let scatter = multiply(&matrix, &x);
        let gather = multiply_symmetric(&matrix, &x);
        assert_eq!(
            scatter.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            gather.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
        assert!(scatter.iter().any(|v| *v != 0.0));
    }

    #[test]
    fn forward_and_backward_halves_compose_to_a_solve() {
        // the 2D five-point Laplacian plus identity on a 12 × 12 grid
        let side = 12;
        let n = side * side;
        let mut triplets = Vec::new();
        for i in 0..side {
            for j in 0..side {
                let row = i * side + j;
                triplets.push(faer::sparse::Triplet::new(row, row, 5.0));
                for (di, dj) in [(0, 1), (1, 0)] {
                    let (k, l) = (i + di, j + dj);
                    if k < side && l < side {
                        let col = k * side + l;
                        triplets.push(faer::sparse::Triplet::new(row, col, -1.0));
                        triplets.push(faer::sparse::Triplet::new(col, row, -1.0));
                    }
                }
            }
        }
        let matrix = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &triplets).unwrap();
        let rhs: Vec<f64> = (0..n)
            .map(|i| ((i * 7919) % 101) as f64 / 50.0 - 1.0)
            .collect();
        for kind in [FactorKind::Supernodal, FactorKind::Simplicial] {
            let mut solver = CholeskySolver::analyse_as(&matrix, kind, "test matrix").unwrap();
            assert!(solver.forward_solve(&rhs).is_err(), "before factorization");
            solver.factorize(&matrix).unwrap();
            let direct = solver.solve(&rhs).unwrap();
            match solver.forward_solve(&rhs).unwrap() {
                Some(z) => {
                    assert_eq!(kind, FactorKind::Supernodal);
                    let halves = solver.backward_solve(&z).unwrap().unwrap();
                    for (a, b) in halves.iter().zip(&direct) {
                        assert!((a - b).abs() <= 1e-13, "{a} vs {b}");
                    }
                    assert!(solver.forward_solve(&rhs[1..]).is_err(), "wrong length");
                }
                None => assert_eq!(kind, FactorKind::Simplicial),
            }
        }
    }

    #[test]
    fn factor_flops_count_the_operations_of_a_dense_and_a_tridiagonal_factor() {
        let matrix = |n: usize, coupled: &dyn Fn(usize, usize) -> bool| {
            let mut triplets = Vec::new();
            for i in 0..n {
                for j in 0..n {
                    if i == j {
                        triplets.push(faer::sparse::Triplet::new(i, j, 2.0 * n as f64));
                    } else if coupled(i, j) {
                        triplets.push(faer::sparse::Triplet::new(i, j, -1.0));
                    }
                }
            }
            SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &triplets).unwrap()
        };
        let natural = |n: usize| (0..n).collect::<Vec<usize>>();
        let dense = matrix(6, &|_, _| true);
        let chain = matrix(10, &|i, j| i.abs_diff(j) == 1);
        let flops = |matrix: &SparseColMat<usize, f64>, kind| {
            let n = matrix.nrows();
            CholeskySolver::analyse_with_ordering_as(matrix, &natural(n), kind, "test matrix")
                .unwrap()
                .factor_flops()
        };
        // simplicial: Σ_j c_j² over the column counts with the diagonal, 6² + 5² + … + 1²
        // for the dense matrix and 9 · 2² + 1 for the chain
        assert_eq!(flops(&dense, FactorKind::Simplicial), 91.0);
        assert_eq!(flops(&chain, FactorKind::Simplicial), 37.0);
        // supernodal: the dense matrix is one supernode of 6 columns with nothing below, 6³/3
        assert_eq!(flops(&dense, FactorKind::Supernodal), 72.0);
    }

    #[test]
    fn cholesky_rejects_indefinite_matrix() {
        let pairs = [Pair::new(0isize, 0isize), Pair::new(1, 1)];
        let pattern = SparsityPattern::from_pairs(2, &pairs).unwrap();
        let matrix = pattern.matrix(&[1.0, -1.0]).unwrap();
        let mut solver = CholeskySolver::analyse(&matrix, "test matrix").unwrap();
        let err = solver.factorize(&matrix).unwrap_err();
        assert!(err.to_string().contains("test matrix"));
    }
}
