//! `--threads` of the `verify` and `simulate` commands: the size of the global worker pool.

use crate::error::InputError;

/// How many worker threads `--threads` may ask for: 4 × the available cores (at least 4).
/// More threads than that only contend for the cores; ten thousand of them spin for minutes.
pub fn max_threads() -> usize {
    4 * std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Checks `--threads` (1 ..= [`max_threads`]) and sets up the global worker pool with that
/// many threads; `None` keeps the default (all cores). Call before any parallel work.
pub fn set_threads(threads: Option<usize>) -> Result<(), InputError> {
    let Some(threads) = threads else {
        return Ok(());
    };
    let limit = max_threads();
    if !(1..=limit).contains(&threads) {
        return Err(InputError::InvalidInput(format!(
            "--threads {threads}: must lie in 1 ..= {limit} (4 × the {} available cores)",
            limit / 4
        )));
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global()
        .map_err(|e| InputError::InvalidInput(format!("--threads {threads}: {e}")))
}
