//! Smoothed aggregation (Vaněk, Mandel & Brezina 1996; steps 1–3 of the [module
//! documentation](super), "Construction"): the strength of connection, the greedy aggregates
//! and the Jacobi-smoothed prolongation.

use crate::algebra::multigrid::csr::Csr;

/// Strength-of-connection threshold θ.
const STRENGTH: f64 = 0.08;
/// Marker of an unaggregated node.
pub(crate) const UNASSIGNED: usize = usize::MAX;

/// Greedy aggregation on the strong connections; returns the aggregate of every node
/// ([`UNASSIGNED`] for the nodes without strong neighbours) and the number of aggregates.
pub(crate) fn aggregate(matrix: &Csr, diagonal: &[f64]) -> (Vec<usize>, usize) {
    let n = matrix.rows();
    let strong = |i: usize, j: usize, a: f64| {
        i != j && a.abs() >= STRENGTH * (diagonal[i] * diagonal[j]).abs().sqrt()
    };
    let mut aggregates = vec![UNASSIGNED; n];
    let mut count = 0;
    // Pass 1: roots whose strong neighbourhood is untouched.
    for i in 0..n {
        if aggregates[i] != UNASSIGNED {
            continue;
        }
        let (columns, values) = matrix.row(i);
        let mut has_strong = false;
        let mut untouched = true;
        for (&j, &a) in columns.iter().zip(values) {
            if strong(i, j, a) {
                has_strong = true;
                untouched &= aggregates[j] == UNASSIGNED;
            }
        }
        if has_strong && untouched {
            aggregates[i] = count;
            for (&j, &a) in columns.iter().zip(values) {
                if strong(i, j, a) {
                    aggregates[j] = count;
                }
            }
            count += 1;
        }
    }
    // Pass 2: join the aggregate of the strongest aggregated neighbour (of pass 1).
    let first_pass = aggregates.clone();
    for i in 0..n {
        if first_pass[i] != UNASSIGNED {
            continue;
        }
        let (columns, values) = matrix.row(i);
        let mut best: Option<(f64, usize)> = None;
        for (&j, &a) in columns.iter().zip(values) {
            if strong(i, j, a) && first_pass[j] != UNASSIGNED {
                let weight = a.abs() / (diagonal[i] * diagonal[j]).abs().sqrt();
                if best.is_none_or(|(strongest, _)| weight > strongest) {
                    best = Some((weight, first_pass[j]));
                }
            }
        }
        if let Some((_, aggregate)) = best {
            aggregates[i] = aggregate;
        }
    }
    // Pass 3: what is left forms aggregates with its unaggregated strong neighbours; a node
    // without strong neighbours stays unaggregated (its row is dominated by the diagonal, and
    // the smoother alone reduces its error).
    for i in 0..n {
        if aggregates[i] != UNASSIGNED {
            continue;
        }
        let (columns, values) = matrix.row(i);
        if !columns.iter().zip(values).any(|(&j, &a)| strong(i, j, a)) {
            continue;
        }
        aggregates[i] = count;
        for (&j, &a) in columns.iter().zip(values) {
            if strong(i, j, a) && aggregates[j] == UNASSIGNED {
                aggregates[j] = count;
            }
        }
        count += 1;
    }
    (aggregates, count)
}

/// `P = (I − ω D⁻¹A) P̂` with the tentative (piecewise constant) `P̂`; returns `(P, Pᵀ)`.
pub(super) fn smoothed_prolongation(
    matrix: &Csr,
    diagonal: &[f64],
    aggregates: &[usize],
    coarse: usize,
) -> (Csr, Csr) {
    let n = matrix.rows();
    let spectral_bound = (0..n)
        .map(|i| {
            let (_, values) = matrix.row(i);
            values.iter().map(|a| a.abs()).sum::<f64>() / diagonal[i]
        })
        .fold(0.0_f64, f64::max);
    let omega = 4.0 / (3.0 * spectral_bound);
    let mut offsets = vec![0];
    let mut indices = Vec::new();
    let mut values = Vec::new();
    let mut row: Vec<(usize, f64)> = Vec::new();
    for i in 0..n {
        row.clear();
        if aggregates[i] != UNASSIGNED {
            row.push((aggregates[i], 1.0));
        }
        let (columns, entries) = matrix.row(i);
        for (&j, &a) in columns.iter().zip(entries) {
            if aggregates[j] != UNASSIGNED {
                row.push((aggregates[j], -omega * a / diagonal[i]));
            }
        }
        row.sort_unstable_by_key(|&(column, _)| column);
        let start = indices.len();
        for &(column, value) in &row {
            if indices.len() > start && indices[indices.len() - 1] == column {
                *values.last_mut().expect("same length") += value;
            } else {
                indices.push(column);
                values.push(value);
            }
        }
        offsets.push(indices.len());
    }
    let prolongation = Csr {
        cols: coarse,
        offsets,
        indices,
        values,
    };
    let restriction = prolongation.transpose();
    (prolongation, restriction)
}
