//! CI rate assertions. Every built-in case runs its convergence studies — the studies of its
//! case file, with the levels, steps and reference runs of the committed baseline
//! `reports/<case>/l<order>/` — and each study is held to what a wrong solver cannot meet:
//!
//! 1. **Pinned errors and counts**: every error component of every run equals that of the
//!    matching row of the baseline's `errors.csv` to [`common::PINNED_TOLERANCE`] (relative), and
//!    its solver iteration counts and contact-zone counts equal the row's exactly
//!    ([`common::PINNED_COUNTS`]). A solver that converges at the right rate to a wrong limit, or
//!    whose errors or work changed for any reason, fails here; the message names the row, the
//!    quantity and both values. `verify baseline` regenerates the baseline and lists what moved.
//! 2. **Certified rates** (the studies marked [`Check::Certified`]): the verdict is PASS, and is
//!    recomputed here from the run errors with Theorem 5.2's exponent and the tolerance restated
//!    below, independently of the library's constants: for every component the theorem bounds,
//!    the least-squares rate over the three finest levels and the rate between the two finest
//!    levels are ≥ expected − [`common::TOLERANCE`], and the pairwise rates of E(h, k) over the fit
//!    differ by at most [`common::TOLERANCE`] (the asymptotic range).
//! 3. Every step's KKT residual is below 1e-9, and the finest run shows the contact zones and
//!    the damage bound the case is built to exercise.
//!
//! The 2D studies run in full. In 3D, the studies whose finest level costs more than about a
//! minute (the nonlinear viscosities at l = 1 and 2, wear and the Gmsh tetrahedra at l = 1, and
//! the h-study of slip3d at l = 1) run their three coarsest levels as [`Check::PinnedOnly`]:
//! their errors are pinned, their rates are not judged (three coarse levels drift, and a
//! drifting study certifies nothing); each of those cases still has certified studies. The
//! h-studies of implicit2d are pinned only too: they drift at every affordable level (see its
//! case file).

use crate::common;

use common::{assert_pinned, case, restated_check, theorem_h_exponent, FIT, TOLERANCE};
use verify::case::{LevelStudy, TimeStudy};
use verify::study::{level_study, time_study, StudyKind, StudyResult, Verdict};

/// Largest KKT residual of any step.
const KKT_LIMIT: f64 = 1e-9;

/// What a CI study asserts.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Check {
    /// Pinned errors, verdict PASS and the restated rate check.
    Certified,
    /// Pinned errors only.
    PinnedOnly,
}

/// The contact zones and damage bounds a case is built to show in its finest run.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Zones {
    /// Separation, stick and slip on Γ3 at once, and the bound β = 1 active.
    All,
    /// Slip in every step, never separation or stick, no damage bound active.
    SlipOnly,
    /// Separation and slip on Γ3 in every step, never stick, no damage bound active.
    SeparationAndSlip,
}

fn print_study(name: &str, study: &StudyResult) {
    for rate in &study.rates {
        println!(
            "{name} {}-study l={}: {:<20} least squares {:.3} pairwise {:.3?}",
            study.kind.name(),
            study.degree,
            rate.component,
            rate.least_squares,
            rate.pairwise
        );
    }
}

/// The CI assertions on one study of case `name` (see the module documentation).
fn assert_study(
    name: &str,
    study: &StudyResult,
    check: Check,
    zones: Zones,
    reference_k: Option<f64>,
) {
    print_study(name, study);
    assert_pinned(name, study);
    for run in &study.runs {
        assert!(
            // a residual is a norm: a negative one is as wrong as a large one
            (0.0..KKT_LIMIT).contains(&run.stats.max_velocity_kkt)
                && (0.0..KKT_LIMIT).contains(&run.stats.max_damage_kkt),
            "{name}: KKT residuals {:e} / {:e} at level {} with {} steps",
            run.stats.max_velocity_kkt,
            run.stats.max_damage_kkt,
            run.cells,
            run.steps
        );
    }
    if check == Check::Certified {
        let failures = restated_check(study, reference_k);
        assert!(
            failures.is_empty() && study.verdict == Verdict::Pass,
            "{name} {}-study l={}: verdict {}, restated check: {}",
            study.kind.name(),
            study.degree,
            study.verdict.label(),
            failures.join("; ")
        );
    }
    // the zones of the case in the finest run of the mesh studies (a k-study runs on one
    // coarse mesh, which need not resolve them)
    if study.kind == StudyKind::K {
        return;
    }
    let finest = study.runs.last().unwrap();
    let stats = &finest.stats;
    match zones {
        Zones::All => {
            assert!(
                stats.steps_with_separation > 0
                    && stats.steps_with_stick > 0
                    && stats.steps_with_slip > 0,
                "{name}: zones not all seen: {stats:?}"
            );
            assert!(
                stats.steps_with_upper_bound > 0,
                "{name}: damage bound β = 1 never active: {stats:?}"
            );
        }
        Zones::SlipOnly => {
            assert!(
                stats.steps_with_slip == finest.steps
                    && stats.steps_with_stick == 0
                    && stats.steps_with_separation == 0
                    && stats.steps_with_upper_bound == 0
                    && stats.steps_with_lower_bound == 0,
                "{name}: not slip alone with β inside (0, 1): {stats:?}"
            );
        }
        Zones::SeparationAndSlip => {
            assert!(
                stats.steps_with_slip == finest.steps
                    && stats.steps_with_separation == finest.steps
                    && stats.steps_with_stick == 0
                    && stats.steps_with_upper_bound == 0
                    && stats.steps_with_lower_bound == 0,
                "{name}: not separation and slip with β inside (0, 1): {stats:?}"
            );
        }
    }
}

/// The first `levels` levels of a level study (all with None).
fn first_levels(study: &LevelStudy, levels: Option<usize>) -> LevelStudy {
    let n = levels.unwrap_or(study.steps.len());
    LevelStudy {
        cells: study.cells.iter().copied().take(n).collect(),
        refinements: study.refinements.iter().copied().take(n).collect(),
        steps: study.steps[..n].to_vec(),
    }
}

/// Which studies of an order run, and how: the h-, k- and diagonal study, each with its check
/// and the number of its coarsest levels (None: all).
struct Plan {
    h: (Check, Option<usize>),
    k: Check,
    diagonal: (Check, Option<usize>),
}

/// Every study of the case file, in full and certified.
const FULL: Plan = Plan {
    h: (Check::Certified, None),
    k: Check::Certified,
    diagonal: (Check::Certified, None),
};

/// Runs and checks the studies of `name` at order `order` as `plan` says.
fn studies<const D: usize>(name: &str, order: usize, zones: Zones, plan: Plan) {
    let case = case::<D>(name);
    let set = &case.file.studies[&format!("order{order}")];
    for (kind, study, (check, levels)) in [
        (StudyKind::H, &set.h, plan.h),
        (StudyKind::Diagonal, &set.diagonal, plan.diagonal),
    ] {
        let study = study.as_ref().expect("the case file defines the study");
        let result = level_study(&case, order, kind, &first_levels(study, levels)).unwrap();
        assert_study(name, &result, check, zones, None);
    }
    let k: &TimeStudy = set.k.as_ref().expect("the case file defines the k-study");
    let result = time_study(&case, order, k).unwrap();
    let reference_k = case.file.final_time / k.reference_steps as f64;
    assert_study(name, &result, plan.k, zones, Some(reference_k));
}

#[test]
fn the_library_uses_the_theorem_exponent_and_the_restated_tolerance() {
    // loosening the library's constants must turn CI red, not loosen it silently
    assert_eq!(verify::study::RATE_TOLERANCE, TOLERANCE);
    assert_eq!(verify::study::DRIFT_TOLERANCE, TOLERANCE);
    assert_eq!(verify::study::FIT_LEVELS, FIT);
    for order in [1, 2] {
        assert_eq!(
            verify::study::expected_h_rate(order),
            theorem_h_exponent(order)
        );
    }
}

// The base cases: separation, stick and slip zones and the active bound β = 1 (zones), slip
// alone with a turning slip direction (slip).

#[test]
fn rates_zones_2d_order1() {
    studies::<2>("zones2d", 1, Zones::All, FULL);
}

#[test]
fn rates_zones_2d_order2() {
    studies::<2>("zones2d", 2, Zones::All, FULL);
}

#[test]
fn rates_zones_3d_order1() {
    studies::<3>("zones3d", 1, Zones::All, FULL);
}

#[test]
fn rates_zones_3d_order2() {
    studies::<3>("zones3d", 2, Zones::All, FULL);
}

#[test]
fn rates_slip_2d_order1() {
    studies::<2>("slip2d", 1, Zones::SlipOnly, FULL);
}

#[test]
fn rates_slip_2d_order2() {
    studies::<2>("slip2d", 2, Zones::SlipOnly, FULL);
}

#[test]
fn rates_slip_3d_order1() {
    let plan = Plan {
        h: (Check::PinnedOnly, Some(3)),
        ..FULL
    };
    studies::<3>("slip3d", 1, Zones::SlipOnly, plan);
}

#[test]
fn rates_slip_3d_order2() {
    studies::<3>("slip3d", 2, Zones::SlipOnly, FULL);
}

// The whole model: nonlinear viscosity (mild and strong), the wear-modified bound (2.12), laws
// written in the case file (carreau2d), the implicit normal compliance with a stiff foundation
// (implicit2d), prescribed displacement, a roller and a moving, partly negative gap (loads2d).

#[test]
fn rates_mild_nonlinear_viscosity_2d_order1() {
    studies::<2>("mild2d", 1, Zones::All, FULL);
}

#[test]
fn rates_mild_nonlinear_viscosity_2d_order2() {
    studies::<2>("mild2d", 2, Zones::All, FULL);
}

#[test]
fn rates_strong_nonlinear_viscosity_2d_order1() {
    studies::<2>("strong2d", 1, Zones::All, FULL);
}

#[test]
fn rates_strong_nonlinear_viscosity_2d_order2() {
    studies::<2>("strong2d", 2, Zones::All, FULL);
}

#[test]
fn rates_wear_2d_order1() {
    studies::<2>("wear2d", 1, Zones::All, FULL);
}

#[test]
fn rates_wear_2d_order2() {
    studies::<2>("wear2d", 2, Zones::All, FULL);
}

#[test]
fn rates_user_written_laws_2d_order1() {
    studies::<2>("carreau2d", 1, Zones::All, FULL);
}

#[test]
fn rates_user_written_laws_2d_order2() {
    studies::<2>("carreau2d", 2, Zones::All, FULL);
}

/// The h-studies of implicit2d drift at every affordable level (see its case file): pinned, on
/// their levels up to 32 cells at l = 1.
const IMPLICIT: Plan = Plan {
    h: (Check::PinnedOnly, Some(4)),
    k: Check::Certified,
    diagonal: (Check::Certified, None),
};

#[test]
fn rates_implicit_contact_2d_order1() {
    studies::<2>("implicit2d", 1, Zones::All, IMPLICIT);
}

#[test]
fn rates_implicit_contact_2d_order2() {
    studies::<2>("implicit2d", 2, Zones::All, IMPLICIT);
}

#[test]
fn rates_prescribed_displacement_roller_moving_gap_2d_order1() {
    studies::<2>("loads2d", 1, Zones::All, FULL);
}

#[test]
fn rates_prescribed_displacement_roller_moving_gap_2d_order2() {
    studies::<2>("loads2d", 2, Zones::All, FULL);
}

/// A 3D study whose finest level is too costly for CI: its three coarsest levels, pinned; the
/// k-study (on one coarse mesh) certified.
const COARSE_3D: Plan = Plan {
    h: (Check::PinnedOnly, Some(3)),
    k: Check::Certified,
    diagonal: (Check::PinnedOnly, Some(3)),
};

#[test]
fn rates_prescribed_displacement_roller_moving_gap_3d_order1() {
    studies::<3>("loads3d", 1, Zones::All, COARSE_3D);
}

#[test]
fn rates_prescribed_displacement_roller_moving_gap_3d_order2() {
    studies::<3>("loads3d", 2, Zones::All, COARSE_3D);
}

#[test]
fn rates_mild_nonlinear_viscosity_3d_order1() {
    studies::<3>("mild3d", 1, Zones::All, COARSE_3D);
}

#[test]
fn rates_mild_nonlinear_viscosity_3d_order2() {
    studies::<3>("mild3d", 2, Zones::All, COARSE_3D);
}

#[test]
fn rates_strong_nonlinear_viscosity_3d_order1() {
    studies::<3>("strong3d", 1, Zones::All, COARSE_3D);
}

#[test]
fn rates_strong_nonlinear_viscosity_3d_order2() {
    studies::<3>("strong3d", 2, Zones::All, COARSE_3D);
}

#[test]
fn rates_wear_3d_order1() {
    studies::<3>("wear3d", 1, Zones::All, COARSE_3D);
}

#[test]
fn rates_wear_3d_order2() {
    studies::<3>("wear3d", 2, Zones::All, FULL);
}

// Cases on Gmsh meshes: unstructured triangles and tetrahedra, levels by uniform refinement,
// a tilted contact boundary (the normal frames are not axis-aligned).

#[test]
fn rates_gmsh_mesh_tilted_contact_2d_order1() {
    studies::<2>("tilted2d", 1, Zones::All, FULL);
}

#[test]
fn rates_gmsh_mesh_tilted_contact_2d_order2() {
    studies::<2>("tilted2d", 2, Zones::All, FULL);
}

#[test]
fn rates_gmsh_mesh_unstructured_tetrahedra_3d_order1() {
    let plan = Plan {
        h: (Check::PinnedOnly, Some(3)),
        ..FULL
    };
    studies::<3>("tilted3d", 1, Zones::All, plan);
}

#[test]
fn rates_gmsh_mesh_unstructured_tetrahedra_3d_order2() {
    // the diagonal study's fourth level (about 400 k P2 unknowns) is beyond the baseline: its
    // three levels drift, so they are pinned
    let plan = Plan {
        diagonal: (Check::PinnedOnly, None),
        ..FULL
    };
    studies::<3>("tilted3d", 2, Zones::All, plan);
}

// A curved domain: the half disc from a Gmsh second-order mesh, isoparametric at l = 2 (every
// level carries the same P2 arc), its straight chords at l = 1.

#[test]
fn rates_curved_contact_boundary_2d_order1() {
    studies::<2>("curved2d", 1, Zones::SeparationAndSlip, FULL);
}

#[test]
fn rates_curved_contact_boundary_isoparametric_2d_order2() {
    studies::<2>("curved2d", 2, Zones::SeparationAndSlip, FULL);
}

#[test]
fn rates_curved_contact_boundary_3d_order1() {
    // the h-study's finest level (128 steps with about 1100 contact nodes in slip) costs two
    // minutes: its three coarsest levels are pinned
    let plan = Plan {
        h: (Check::PinnedOnly, Some(3)),
        ..FULL
    };
    studies::<3>("curved3d", 1, Zones::SeparationAndSlip, plan);
}

#[test]
fn rates_curved_contact_boundary_isoparametric_3d_order2() {
    // the diagonal study's three levels drift (pairwise rates of E(h, k) 1.89, 1.45): pinned
    let plan = Plan {
        diagonal: (Check::PinnedOnly, None),
        ..FULL
    };
    studies::<3>("curved3d", 2, Zones::SeparationAndSlip, plan);
}

#[test]
fn tetrahedra_refined_uniformly_keep_their_shape_regularity() {
    let case = case::<3>("tilted3d");
    let levels = LevelStudy {
        cells: Vec::new(),
        refinements: vec![0, 1],
        steps: vec![2, 8],
    };
    let h = level_study(&case, 1, StudyKind::H, &levels).unwrap();
    let (q0, q1) = (h.runs[0].shape_regularity, h.runs[1].shape_regularity);
    assert!(q0 >= 1.0 && q1 <= 2.0 * q0, "shape regularity {q0} → {q1}");
    assert_eq!(h.runs[1].mesh_cells, 8 * h.runs[0].mesh_cells);
}
