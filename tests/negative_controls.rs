//! Negative controls: the CI assertions of `tests/rates.rs` run on deliberately wrong solvers and
//! wrong data must fail. Each control runs the h- and diagonal studies of zones2d (l = 1 and 2,
//! the levels of the committed baseline) with the solver's problem altered — a law a few per
//! cent off the one the manufactured data were built from, or a boundary term dropped — and
//! asserts that the pinned errors of every study differ from the baseline and that the verdict
//! of some study is FAIL: a consistency error of a few per cent leaves an error floor that the
//! finest levels at l = 2 (errors of 1e-4 to 1e-3) see, while at l = 1 a rate can still look
//! right — there the pinned errors catch it.
//!
//! The last control is an error floor added to the errors of the correct solver (a solver
//! converging at the right rate to a limit about 20 % off in ‖ε(u)‖): its verdict must be FAIL.

use crate::common;

use common::{case, pinned_mismatches, restated_check};
use contact_damage::scheme::Problem;
use rayon::prelude::*;
use std::time::Instant;
use verify::case::{parse_case_file, Case, LevelStudy};
use verify::cli::BUILT_IN_CASES;
use verify::study::{
    level_study, level_study_result, run_problem, StudyKind, StudyResult, Verdict,
};

/// The zones2d case with `from` replaced by `to` in its file.
fn altered_case(from: &str, to: &str) -> Case<2> {
    let (_, text) = BUILT_IN_CASES
        .iter()
        .find(|(n, _)| *n == "zones2d")
        .unwrap();
    assert!(text.contains(from), "zones2d has no `{from}`");
    let text = text.replacen(from, to, 1);
    Case::new(parse_case_file(&text, "altered").unwrap(), "altered").unwrap()
}

/// The study `kind` of zones2d at `order` with every problem altered by `alter` before it is
/// solved; the errors are measured against the exact solution of zones2d.
fn altered_study(
    order: usize,
    kind: StudyKind,
    alter: &(dyn Fn(&mut Problem<2>) + Sync),
) -> StudyResult {
    let case = case::<2>("zones2d");
    let set = &case.file.studies[&format!("order{order}")];
    let levels: &LevelStudy = match kind {
        StudyKind::H => set.h.as_ref().unwrap(),
        _ => set.diagonal.as_ref().unwrap(),
    };
    let runs = levels
        .cells
        .par_iter()
        .zip(&levels.steps)
        .map(|(&cells, &steps)| {
            let started = Instant::now();
            let mut problem = case.problem(cells, order, steps).unwrap();
            alter(&mut problem);
            run_problem(&case, problem, cells, None, started).unwrap()
        })
        .collect();
    level_study_result(kind, order, runs)
}

/// How a control fared: (order, study, verdict, pinned errors that moved, the restated check's
/// failures).
struct Outcome {
    order: usize,
    kind: StudyKind,
    verdict: Verdict,
    moved: usize,
    restated_failures: usize,
}

/// Runs the h- and diagonal studies at l = 1 and 2 with the solver's problem altered.
fn control(name: &str, alter: &(dyn Fn(&mut Problem<2>) + Sync)) -> Vec<Outcome> {
    let mut outcomes = Vec::new();
    for order in [1, 2] {
        for kind in [StudyKind::H, StudyKind::Diagonal] {
            let study = altered_study(order, kind, alter);
            let outcome = Outcome {
                order,
                kind,
                verdict: study.verdict,
                moved: pinned_mismatches("zones2d", &study).len(),
                restated_failures: restated_check(&study, None).len(),
            };
            println!(
                "{name}: l = {order} {}-study: verdict {}, {} pinned errors moved, restated check {}",
                kind.name(),
                outcome.verdict.label(),
                outcome.moved,
                if outcome.restated_failures == 0 { "passes" } else { "fails" }
            );
            outcomes.push(outcome);
        }
    }
    outcomes
}

/// Every study of the control moved pinned errors (the CI check that fails).
fn assert_caught_by_pinned_errors(name: &str, outcomes: &[Outcome]) {
    for outcome in outcomes {
        assert!(
            outcome.moved > 0,
            "{name}: the l = {} {}-study matches the baseline",
            outcome.order,
            outcome.kind.name()
        );
    }
}

/// The verdict of some study of the control is FAIL, and the restated check fails it too.
fn assert_some_verdict_fails(name: &str, outcomes: &[Outcome]) {
    assert!(
        outcomes
            .iter()
            .any(|o| o.verdict == Verdict::Fail && o.restated_failures > 0),
        "{name}: no study of the wrong solver fails its verdict"
    );
}

/// The solver takes the laws of zones2d with `from` replaced by `to`; the data stay those of
/// the true laws.
fn wrong_law(from: &str, to: &str) -> impl Fn(&mut Problem<2>) + Sync {
    let laws = altered_case(from, to).laws;
    move |problem: &mut Problem<2>| problem.model = laws.clone()
}

#[test]
fn the_correct_solver_passes_these_studies() {
    // the control of the controls: unaltered, the same studies pass and match the baseline
    let outcomes = control("unaltered", &|_: &mut Problem<2>| {});
    for outcome in &outcomes {
        assert!(
            outcome.verdict == Verdict::Pass
                && outcome.moved == 0
                && outcome.restated_failures == 0,
            "the correct solver: l = {} {}-study verdict {}, {} pinned errors moved",
            outcome.order,
            outcome.kind.name(),
            outcome.verdict.label(),
            outcome.moved
        );
    }
}

#[test]
fn a_friction_coefficient_three_percent_off_is_caught() {
    let outcomes = control(
        "friction +3 %",
        &wrong_law("friction = 0.4 }", "friction = 0.412 }"),
    );
    assert_caught_by_pinned_errors("friction", &outcomes);
    assert_some_verdict_fails("friction", &outcomes);
}

#[test]
fn a_contact_stiffness_three_percent_off_is_caught() {
    let outcomes = control(
        "stiffness +3 %",
        &wrong_law("stiffness = 10.0,", "stiffness = 10.3,"),
    );
    assert_caught_by_pinned_errors("stiffness", &outcomes);
    assert_some_verdict_fails("stiffness", &outcomes);
}

#[test]
fn a_damage_diffusion_three_percent_off_is_caught() {
    let outcomes = control(
        "diffusion +3 %",
        &wrong_law("damage_diffusion = 0.1", "damage_diffusion = 0.103"),
    );
    assert_caught_by_pinned_errors("diffusion", &outcomes);
    assert_some_verdict_fails("diffusion", &outcomes);
}

#[test]
fn a_viscosity_three_percent_off_is_caught() {
    let outcomes = control(
        "viscosity +3 %",
        &wrong_law("shear = 1.0, bulk = 0.5", "shear = 1.03, bulk = 0.5"),
    );
    assert_caught_by_pinned_errors("viscosity", &outcomes);
    assert_some_verdict_fails("viscosity", &outcomes);
}

#[test]
fn an_elasticity_three_percent_off_is_caught() {
    let outcomes = control(
        "elasticity +3 %",
        &wrong_law("shear_modulus = 1.0,", "shear_modulus = 1.03,"),
    );
    assert_caught_by_pinned_errors("elasticity", &outcomes);
    assert_some_verdict_fails("elasticity", &outcomes);
}

#[test]
fn a_dropped_traction_on_the_neumann_boundary_is_caught() {
    let outcomes = control("no traction f2", &|problem: &mut Problem<2>| {
        problem.data.traction = None
    });
    assert_caught_by_pinned_errors("traction", &outcomes);
    assert_some_verdict_fails("traction", &outcomes);
}

#[test]
fn a_dropped_traction_on_the_contact_boundary_is_caught() {
    let outcomes = control("no traction f3", &|problem: &mut Problem<2>| {
        problem.data.contact_traction = None
    });
    assert_caught_by_pinned_errors("contact traction", &outcomes);
    assert_some_verdict_fails("contact traction", &outcomes);
}

#[test]
fn a_dropped_damage_flux_is_caught() {
    let outcomes = control("no damage flux", &|problem: &mut Problem<2>| {
        problem.data.damage_flux = None
    });
    assert_caught_by_pinned_errors("damage flux", &outcomes);
    assert_some_verdict_fails("damage flux", &outcomes);
}

#[test]
fn a_limit_twenty_percent_off_fails_the_verdict() {
    // a solver whose displacement and difference-quotient errors level off at 0.03 (about 20 %
    // of ‖ε(u)‖ at these levels): the errors of the correct solver plus that floor
    let case = case::<2>("zones2d");
    let set = &case.file.studies["order1"];
    for (kind, levels) in [
        (StudyKind::H, set.h.as_ref().unwrap()),
        (StudyKind::Diagonal, set.diagonal.as_ref().unwrap()),
    ] {
        let correct = level_study(&case, 1, kind, levels).unwrap();
        assert_eq!(correct.verdict, Verdict::Pass);
        let floored: Vec<_> = correct
            .runs
            .iter()
            .cloned()
            .map(|mut run| {
                run.errors.displacement += 0.03;
                run.errors.difference_quotient += 0.03;
                run.errors.total += 0.06;
                run
            })
            .collect();
        let wrong = level_study_result(kind, 1, floored);
        println!(
            "error floor 0.03: {}-study verdict {}",
            kind.name(),
            wrong.verdict.label()
        );
        assert_eq!(wrong.verdict, Verdict::Fail, "{}-study", kind.name());
        assert!(!restated_check(&wrong, None).is_empty());
        assert!(!pinned_mismatches("zones2d", &wrong).is_empty());
    }
}
