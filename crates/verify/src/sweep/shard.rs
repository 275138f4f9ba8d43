//! The shares of a manifest for `verify run --shard I/N`: greedy LPT by estimated cost.

use crate::sweep::plan::{Manifest, PlannedRun};
use crate::InputError;

/// Parses `--shard I/N` (0 ≤ I < N) for a manifest of `runs` runs: N is at most `runs` (a
/// share beyond them would hold no run), so that no count from the command line sizes an
/// allocation.
pub fn parse_shard(text: &str, runs: usize) -> Result<(usize, usize), InputError> {
    let refuse = || {
        InputError::InvalidInput(format!(
            "--shard `{text}`: expected I/N with 0 ≤ I < N, e.g. 0/4"
        ))
    };
    let (i, n) = text.split_once('/').ok_or_else(refuse)?;
    let i: usize = i.trim().parse().map_err(|_| refuse())?;
    let n: usize = n.trim().parse().map_err(|_| refuse())?;
    if n == 0 || i >= n {
        return Err(refuse());
    }
    if n > runs {
        return Err(InputError::InvalidInput(format!(
            "--shard `{text}`: N = {n} is above the {runs} runs of the manifest; N must be at most {runs} (a share beyond the runs would hold none)"
        )));
    }
    Ok((i, n))
}

/// The indices of the runs of share `shard` of `shards`: greedy LPT (the most costly run first,
/// each to the least loaded share, ties to the lowest share and index), deterministic. A run
/// against a reference carries the cost of its reference when that reference is in no share yet
/// (it computes it if it finds no stored result).
pub fn shard(manifest: &Manifest, shard: usize, shards: usize) -> Vec<usize> {
    let mut order: Vec<&PlannedRun> = manifest.runs.iter().collect();
    order.sort_by(|a, b| b.cost.total_cmp(&a.cost).then(a.index.cmp(&b.index)));
    let mut load = vec![0.0_f64; shards];
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); shards];
    for run in order {
        let lightest = (0..shards)
            .min_by(|&a, &b| load[a].total_cmp(&load[b]).then(a.cmp(&b)))
            .unwrap_or(0);
        load[lightest] += run.cost;
        members[lightest].push(run.index);
    }
    let mut mine = std::mem::take(&mut members[shard]);
    mine.sort_unstable();
    mine
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::plan::plan;

    const ZONES: &str = include_str!("../../../../verification/zones2d.toml");

    fn all() -> Vec<String> {
        ["h", "k", "diagonal"].map(String::from).to_vec()
    }

    #[test]
    fn shards_partition_the_runs_and_balance_the_cost() {
        let manifest = plan(ZONES, "zones2d", 1, &all(), None).unwrap();
        for shards in 1..=5 {
            let mut seen: Vec<usize> = (0..shards)
                .flat_map(|i| shard(&manifest, i, shards))
                .collect();
            seen.sort_unstable();
            assert_eq!(seen, (0..manifest.runs.len()).collect::<Vec<_>>());
        }
        let total: f64 = manifest.runs.iter().map(|r| r.cost).sum();
        let largest = manifest.runs.iter().map(|r| r.cost).fold(0.0, f64::max);
        let loads: Vec<f64> = (0..3)
            .map(|i| {
                shard(&manifest, i, 3)
                    .iter()
                    .map(|&r| manifest.runs[r].cost)
                    .sum()
            })
            .collect();
        // LPT: no share exceeds the mean by more than the largest run
        for load in loads {
            assert!(load <= total / 3.0 + largest, "{load} vs {total}");
        }
    }

    #[test]
    fn bad_shards_are_refused() {
        for text in [
            "3/3",
            "1",
            "a/2",
            "0/0",
            "-1/2",
            "0/6",
            "0/18446744073709551615",
        ] {
            assert!(parse_shard(text, 5).is_err(), "{text}");
        }
        assert_eq!(parse_shard("2/5", 5).unwrap(), (2, 5));
    }
}
