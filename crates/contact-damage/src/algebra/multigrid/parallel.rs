//! The row-parallel passes of the multigrid and of the monotone multigrid of
//! [`crate::solvers::box_qp`]: one entry per row, in tasks of rows on a pool of several threads.

use rayon::prelude::*;

/// Rows per task of the row-parallel passes ([`for_each_row`]).
const PARALLEL_ROWS: usize = 8192;

/// `value(i, &mut y[i])` for every row `i`: in tasks of [`PARALLEL_ROWS`] rows when the
/// thread pool has more than one thread and `y` has at least two tasks' worth of rows, on
/// the calling thread otherwise. Every entry is computed by the same expression either way,
/// so the result is bitwise the same on any number of threads.
pub(crate) fn for_each_row<T: Send>(y: &mut [T], value: impl Fn(usize, &mut T) + Sync) {
    if y.len() >= 2 * PARALLEL_ROWS && rayon::current_num_threads() > 1 {
        y.par_chunks_mut(PARALLEL_ROWS)
            .enumerate()
            .for_each(|(chunk, entries)| {
                let first = chunk * PARALLEL_ROWS;
                for (k, entry) in entries.iter_mut().enumerate() {
                    value(first + k, entry);
                }
            });
    } else {
        for (i, entry) in y.iter_mut().enumerate() {
            value(i, entry);
        }
    }
}
