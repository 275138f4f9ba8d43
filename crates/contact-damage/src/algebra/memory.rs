//! How much memory a run needs, estimated before anything large is allocated.
//!
//! The peak of a run is dominated by the sparse Cholesky factor of the velocity operator of
//! (5.1) and the assembled matrices, all proportional to the number of velocity unknowns with a
//! factor that grows with the fill of the factor. The per-unknown figures below are the peak
//! resident set sizes of `Simulation::new` and two steps measured by the benchmark
//! (`cargo run --release -p contact-damage --example bench`, reports/benchmark.md):
//! 2D P1 2.6–2.7 KiB per unknown from 132 k to 2.1 M unknowns, 3D P1 14.8–15.4 KiB per unknown
//! at 15 k and 108 k unknowns. In 3D the fill of a nested-dissection factor grows like n^{4/3},
//! so the 3D figure is scaled by (n / 10⁵)^{1/3} above 10⁵ unknowns; P2 couples each node to
//! about 2.5× (2D) and 3× (3D) as many others, which scales the figure accordingly. The estimate
//! is meant to be within a factor of two, enough to refuse a run that cannot fit long before it
//! aborts in an allocation.

use crate::error::{Error, Result};

/// Estimated peak memory of a run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MemoryEstimate {
    /// Velocity unknowns (D × Lagrange nodes).
    pub unknowns: f64,
    /// Peak bytes.
    pub bytes: f64,
}

/// Bytes per velocity unknown measured for P1 (see the module documentation).
fn bytes_per_unknown(dim: usize, degree: usize, unknowns: f64) -> f64 {
    let p1 = if dim == 2 {
        2.8 * 1024.0
    } else {
        15.5 * 1024.0 * (unknowns / 1e5).cbrt().max(1.0)
    };
    let coupling = match (dim, degree) {
        (_, 1) => 1.0,
        (2, _) => 2.5,
        _ => 3.0,
    };
    p1 * coupling
}

/// The estimate for a mesh with `vertices` vertices in dimension `dim` and degree `degree`
/// (P2 nodes: about 4 × the vertices of a triangle mesh, 8 × those of a tetrahedral one).
pub fn estimate(dim: usize, degree: usize, vertices: f64) -> MemoryEstimate {
    let nodes = if degree == 1 {
        vertices
    } else {
        vertices * 2f64.powi(dim as i32)
    };
    let unknowns = nodes * dim as f64;
    MemoryEstimate {
        unknowns,
        bytes: unknowns * bytes_per_unknown(dim, degree, unknowns),
    }
}

/// The estimate for the box mesh with `cells_per_side` (computed in floating point: no
/// overflow for absurd counts).
pub fn estimate_box(cells_per_side: &[usize], degree: usize) -> MemoryEstimate {
    let vertices: f64 = cells_per_side.iter().map(|&n| n as f64 + 1.0).product();
    estimate(cells_per_side.len(), degree, vertices)
}

/// The physical memory of this machine (`MemTotal` of /proc/meminfo), if known.
pub fn physical_memory() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|line| line.starts_with("MemTotal:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024.0)
}

/// The default limit: the physical memory, or 16 GiB where it cannot be read.
pub fn default_limit() -> f64 {
    physical_memory().unwrap_or(16.0 * GIB)
}

/// `bytes` in GiB, or in MiB below one GiB.
fn size(bytes: f64) -> String {
    if bytes >= GIB {
        format!("{:.1} GiB", bytes / GIB)
    } else {
        format!("{:.1} MiB", bytes / (1024.0 * 1024.0))
    }
}

/// One gibibyte.
pub const GIB: f64 = 1024.0 * 1024.0 * 1024.0;

/// Refuses `estimate` above `limit` bytes; `what` names the run ("the problem", "level 4 of
/// the h study") and `flag` the option that raises the limit.
pub fn check(estimate: MemoryEstimate, limit: f64, what: &str, flag: &str) -> Result<()> {
    if estimate.bytes <= limit {
        return Ok(());
    }
    Err(Error::InvalidInput(format!(
            "{what} has about {:.3e} velocity unknowns and needs an estimated {}, above the limit of {} (by default the physical memory of this machine); use a coarser mesh or a lower degree, or raise the limit with {flag} <GiB> if the estimate is too cautious",
            estimate.unknowns,
            size(estimate.bytes),
            size(limit),
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn estimates_reproduce_the_benchmark_within_a_factor_of_two() {
        // (cells per side, peak MiB) of reports/benchmark.md
        for (cells, peak_mib) in [
            (vec![256, 256], 365.0),
            (vec![512, 512], 1388.0),
            (vec![1024, 1024], 5646.0),
            (vec![16, 16, 16], 218.0),
            (vec![32, 32, 32], 1661.0),
        ] {
            let estimate = estimate_box(&cells, 1).bytes / (1024.0 * 1024.0);
            let ratio = estimate / peak_mib;
            assert!(
                (0.5..=2.0).contains(&ratio),
                "{cells:?}: {estimate} MiB vs {peak_mib}"
            );
        }
    }

    #[test]
    fn absurd_sizes_are_refused_without_overflow() {
        let estimate = estimate_box(&[1_000_000_000, 1_000_000_000], 2);
        assert!(estimate.bytes.is_finite() && estimate.bytes > 1e20);
        let error = check(estimate, 24.0 * GIB, "the problem", "--memory-limit")
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("GiB") && error.contains("--memory-limit"),
            "{error}"
        );
        check(
            estimate_box(&[8, 8], 1),
            24.0 * GIB,
            "the problem",
            "--memory-limit",
        )
        .unwrap();
    }
}
