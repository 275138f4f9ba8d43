//! Work of the damage step (5.2) on the fixed moving-damage case of
//! `examples/common/moving_damage.rs`, for both box QP methods: an exact KKT certificate every
//! step and bounded outer and inner (preconditioned CG) iteration counts for N = 16, 32, 64;
//! one numeric factorization per run for the active set method, none for the monotone
//! multigrid. The counts for N up to 512 are in `docs/explanation/performance.md`
//! (`cargo run --release -p contact-damage --example damage_iterations [-- --active-set]`).

use contact_damage::solvers::box_qp::BoxQpMethod;

#[path = "../examples/common/moving_damage.rs"]
mod moving_damage;

/// Largest number of active-set iterations of one step allowed for N ≤ 64 (measured: 3, 3, 5).
/// The bounds of this file are the measured maxima plus a margin of about half, enough for
/// changes of rounding, small enough to catch an iteration that degrades.
const MAX_OUTER: usize = 6;
/// Largest number of CG iterations (solves with the factor) of one step for N ≤ 64
/// (measured: 5, 4, 8).
const MAX_INNER: usize = 12;

/// Largest number of monotone multigrid iterations of one step for N ≤ 64 (measured: 4, 3, 6).
const MAX_OUTER_MULTIGRID: usize = 9;
/// Largest number of CG iterations (V-cycles) of one multigrid step for N ≤ 64
/// (measured: 3, 3, 6).
const MAX_INNER_MULTIGRID: usize = 9;

#[test]
fn multigrid_damage_step_needs_no_factorization_and_its_iteration_counts_stay_bounded() {
    for cells in [16, 32, 64] {
        let stats = moving_damage::run(cells, BoxQpMethod::MonotoneMultigrid, moving_damage::STEPS)
            .unwrap();
        assert_eq!(stats.len(), moving_damage::STEPS);
        for (n, s) in stats.iter().enumerate() {
            let step = n + 1;
            assert_eq!(s.factorizations, 0, "N = {cells}, step {step}: {s:?}");
            assert!(s.kkt_residual <= 1e-10, "N = {cells}, step {step}: {s:?}");
            assert!(
                s.iterations <= MAX_OUTER_MULTIGRID && s.inner_iterations <= MAX_INNER_MULTIGRID,
                "N = {cells}, step {step}: {s:?}"
            );
        }
        let last = stats.last().unwrap();
        assert!(last.lower_active > 0 && last.upper_active > 0, "{last:?}");
    }
}

/// Most multigrid iterations over the 16 steps at N = 256 against N = 64 (measured 83 against
/// 80, 1.04; 102 against 80, 1.28, before the coarse obstacle corrections).
const MAX_GROWTH_TO_256: f64 = 1.2;

/// At N = 256 the damage matrix is diffusion dominated (a_ii / Σ_j a_ij ≈ 41: the layers
/// that leave a bound in one step are several cells wide) and the coarse obstacle
/// corrections keep the iteration count within a fifth of that at N = 64, where they are not
/// used (ratio ≈ 3).
#[test]
fn coarse_obstacle_corrections_keep_the_multigrid_iterations_from_growing_with_n() {
    let total = |cells: usize| {
        let stats = moving_damage::run(cells, BoxQpMethod::MonotoneMultigrid, moving_damage::STEPS)
            .unwrap();
        assert!(stats.iter().all(|s| s.kkt_residual <= 1e-10), "{stats:?}");
        let coarse: usize = stats.iter().map(|s| s.coarse_iterations).sum();
        let iterations: usize = stats.iter().map(|s| s.iterations).sum();
        (iterations, coarse)
    };
    let (coarse_grid, unused) = total(64);
    assert_eq!(unused, 0);
    let (fine_grid, used) = total(256);
    assert!(used > 0);
    assert!(
        fine_grid as f64 <= MAX_GROWTH_TO_256 * coarse_grid as f64,
        "{fine_grid} iterations at N = 256 against {coarse_grid} at N = 64"
    );
}

#[test]
fn damage_step_factorizes_once_and_its_iteration_counts_stay_bounded() {
    for cells in [16, 32, 64] {
        let stats =
            moving_damage::run(cells, BoxQpMethod::ActiveSet, moving_damage::STEPS).unwrap();
        assert_eq!(stats.len(), moving_damage::STEPS);
        let factorizations: usize = stats.iter().map(|s| s.factorizations).sum();
        assert_eq!(factorizations, 1, "N = {cells}: {stats:?}");
        for (n, s) in stats.iter().enumerate() {
            assert!(
                s.kkt_residual <= 1e-10,
                "N = {cells}, step {}: {s:?}",
                n + 1
            );
            assert!(!s.used_fallback, "N = {cells}, step {}: {s:?}", n + 1);
            assert!(
                s.iterations <= MAX_OUTER && s.inner_iterations <= MAX_INNER,
                "N = {cells}, step {}: {s:?}",
                n + 1
            );
        }
        // both bounds are active and the active sets move with the source
        let first = &stats[0];
        let last = stats.last().unwrap();
        assert!(last.lower_active > 0 && last.upper_active > 0, "{last:?}");
        assert_ne!(
            (first.lower_active, first.upper_active),
            (last.lower_active, last.upper_active)
        );
        assert!(stats.iter().all(|s| s.iterations >= 1));
    }
}
