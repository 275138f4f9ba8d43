//! Convergence studies: h-study, k-study and diagonal study (k ∝ h^r), run in parallel with
//! rayon, with observed rates (pairwise and least squares over the finest levels), the rates
//! expected from Theorem 5.2, and a verdict with one tolerance ([`RATE_TOLERANCE`]).

use crate::case::{Case, LevelStudy, TimeStudy};
use crate::errors::{ErrorComponents, ErrorTracker, Reference};
use crate::output::{finite, finite_or_null, finite_or_null_each};
use crate::VerifyError;
use contact_damage::quality::shape_regularity;
use contact_damage::scheme::{RunSummary, Simulation, State};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde::ser::SerializeMap;
use serde::{Serialize, Serializer};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Tolerance of every verdict: a study passes when the least-squares rate over its finest
/// levels is ≥ expected − `RATE_TOLERANCE` for every quantity the theorem bounds.
///
/// Justification: Theorem 5.2 is an upper bound c(k + h^p); the observed rate over three levels
/// (a factor 4 in h or k) carries the pre-asymptotic influence of the other error terms, e.g. a
/// term c' h^{p+1} beside c h^p shifts the fitted slope by about (c'/c) h, and the time error
/// that an h-study keeps small (k ∝ h^2) still shifts it by a few hundredths. 0.15 is ten
/// percent of the smallest expected rate in h (1.5 for l = 2) and fails any study whose rate is
/// of a lower order (e.g. h^{1/2} instead of h, or k^{1/2} instead of k).
pub const RATE_TOLERANCE: f64 = 0.15;

/// Number of finest levels used by the least-squares rate.
pub const FIT_LEVELS: usize = 3;

/// The kind of a study.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StudyKind {
    /// Refine h with a time error kept negligible.
    H,
    /// Refine k on one mesh against a reference run with a much finer k.
    K,
    /// Refine h and k together (k ∝ h^r).
    Diagonal,
}

impl StudyKind {
    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            StudyKind::H => "h",
            StudyKind::K => "k",
            StudyKind::Diagonal => "diagonal",
        }
    }
}

/// Solver statistics of one run.
#[derive(Debug, Clone, Default, Serialize)]
pub struct RunStats {
    /// Unknowns of the velocity step (d × nodes).
    pub velocity_unknowns: usize,
    /// Largest KKT residual of a velocity step.
    pub max_velocity_kkt: f64,
    /// Largest KKT residual of a damage step.
    pub max_damage_kkt: f64,
    /// Outer Newton iterations of the velocity steps (5.1), all steps together.
    pub newton_iterations: usize,
    /// Newton iterations of one velocity step (5.1), mean over the steps
    /// (`newton_iterations / steps`; 0 for a run without steps).
    pub mean_newton_iterations: f64,
    /// Newton iterations of one velocity step (5.1), the most over the steps.
    pub max_newton_iterations: usize,
    /// The relative KKT residual after each Newton iteration of the slowest velocity step (the
    /// first step with `max_newton_iterations` iterations); its last entry is that step's final
    /// residual, below the velocity tolerance. Empty for a run without steps.
    #[serde(serialize_with = "finite_or_null_each")]
    pub slowest_newton_history: Vec<f64>,
    /// Semismooth Newton iterations of the friction problems (all steps).
    pub friction_iterations: usize,
    /// Active-set iterations of the damage steps (all steps).
    pub damage_iterations: usize,
    /// Steps in which some contact node was separated / stuck / slipping.
    pub steps_with_separation: usize,
    /// See `steps_with_separation`.
    pub steps_with_stick: usize,
    /// See `steps_with_separation`.
    pub steps_with_slip: usize,
    /// Steps in which the lower bound β = 0 was active at some node.
    pub steps_with_lower_bound: usize,
    /// Steps in which the upper bound β = 1 was active at some node.
    pub steps_with_upper_bound: usize,
    /// Wall time of the run in seconds.
    pub wall_seconds: f64,
}

impl RunStats {
    fn from_summary(summary: &RunSummary, unknowns: usize, seconds: f64) -> Self {
        Self {
            velocity_unknowns: unknowns,
            max_velocity_kkt: summary.max_velocity_kkt,
            max_damage_kkt: summary.max_damage_kkt,
            newton_iterations: summary.velocity_newton_iterations,
            mean_newton_iterations: if summary.steps == 0 {
                0.0
            } else {
                summary.velocity_newton_iterations as f64 / summary.steps as f64
            },
            max_newton_iterations: summary.max_velocity_newton_iterations,
            slowest_newton_history: summary.slowest_velocity_history.clone(),
            friction_iterations: summary.friction_iterations,
            damage_iterations: summary.damage_iterations,
            steps_with_separation: summary.steps_with_status[0],
            steps_with_stick: summary.steps_with_status[1],
            steps_with_slip: summary.steps_with_status[2],
            steps_with_lower_bound: summary.steps_with_damage_bound[0],
            steps_with_upper_bound: summary.steps_with_damage_bound[1],
            wall_seconds: seconds,
        }
    }
}

/// One run of a study.
#[derive(Debug, Clone, Serialize)]
pub struct RunResult {
    /// The level: cells per side (box domain) or uniform refinements of the Gmsh mesh.
    pub cells: usize,
    /// Mesh size h (largest cell diameter).
    pub h: f64,
    /// Number of cells of the mesh.
    pub mesh_cells: usize,
    /// Shape-regularity measure of the mesh, max_K (h_K/ρ_K) normalized by the regular
    /// simplex ([`contact_damage::quality::shape_regularity`]; Theorem 5.2 needs it bounded).
    #[serde(serialize_with = "finite_or_null")]
    pub shape_regularity: f64,
    /// Time steps N.
    pub steps: usize,
    /// k = T/N.
    pub k: f64,
    /// Error components (in JSON, a component without a value, e.g. `velocity` against a
    /// discrete reference, is `null`).
    #[serde(serialize_with = "components_or_null")]
    pub errors: ErrorComponents,
    /// Solver statistics.
    pub stats: RunStats,
}

/// The error components as a JSON object with the keys of [`ErrorComponents::NAMES`], a
/// component without a (finite) value written as `null`.
fn components_or_null<S: Serializer>(
    errors: &ErrorComponents,
    serializer: S,
) -> Result<S::Ok, S::Error> {
    let mut map = serializer.serialize_map(Some(ErrorComponents::NAMES.len()))?;
    for (name, value) in ErrorComponents::NAMES.iter().zip(errors.values()) {
        map.serialize_entry(name, &finite(value))?;
    }
    map.end()
}

/// Rates of one error component.
///
/// A rate that cannot be measured (an error missing or zero at a level, e.g. the velocity error
/// of a k-study, which has no value) is not finite here, `null` in `summary.json`, and left out
/// or shown as `—` in the terminal.
#[derive(Debug, Clone, Serialize)]
pub struct ComponentRates {
    /// Component name.
    pub component: String,
    /// Rates between consecutive levels (not finite where there is none).
    #[serde(serialize_with = "finite_or_null_each")]
    pub pairwise: Vec<f64>,
    /// Least-squares slope over the finest [`FIT_LEVELS`] levels (not finite when fewer than two
    /// of them have a positive finite error).
    #[serde(serialize_with = "finite_or_null")]
    pub least_squares: f64,
    /// Expected rate (None for quantities the theorem does not bound).
    pub expected: Option<f64>,
    /// The verdict: None for a quantity the theorem does not bound (it is not judged, whether it
    /// has values or not); for a bounded one, `least_squares` ≥ expected − tolerance, which
    /// fails when `least_squares` is missing (the study then shows nothing about it).
    pub pass: Option<bool>,
}

impl ComponentRates {
    /// True when the component has no rate at all (no pairwise rate and no least-squares
    /// slope), e.g. the velocity error of a k-study.
    pub fn is_missing(&self) -> bool {
        !self.least_squares.is_finite() && self.pairwise.iter().all(|r| !r.is_finite())
    }
}

/// Result of a study.
#[derive(Debug, Clone, Serialize)]
pub struct StudyResult {
    /// The kind.
    pub kind: StudyKind,
    /// Polynomial degree l.
    pub degree: usize,
    /// "h" or "k": the variable the rates are measured in.
    pub variable: &'static str,
    /// Expected rate of E(h, k) in that variable.
    #[serde(serialize_with = "finite_or_null")]
    pub expected_rate: f64,
    /// The runs, coarsest first.
    pub runs: Vec<RunResult>,
    /// Rates per component.
    pub rates: Vec<ComponentRates>,
    /// True when every bounded component passes.
    pub pass: bool,
}

/// Expected h-exponent of Theorem 5.2: min(l, (l+1)/2).
pub fn expected_h_rate(degree: usize) -> f64 {
    (degree as f64).min((degree as f64 + 1.0) / 2.0)
}

/// Least-squares slope of log(error) against log(size).
pub fn least_squares_slope(points: &[(f64, f64)]) -> f64 {
    let logs: Vec<(f64, f64)> = points
        .iter()
        .filter(|(s, e)| *s > 0.0 && *e > 0.0 && e.is_finite())
        .map(|(s, e)| (s.ln(), e.ln()))
        .collect();
    let n = logs.len() as f64;
    if logs.len() < 2 {
        return f64::NAN;
    }
    let mean_x = logs.iter().map(|p| p.0).sum::<f64>() / n;
    let mean_y = logs.iter().map(|p| p.1).sum::<f64>() / n;
    let sxy: f64 = logs.iter().map(|(x, y)| (x - mean_x) * (y - mean_y)).sum();
    let sxx: f64 = logs.iter().map(|(x, _)| (x - mean_x).powi(2)).sum();
    sxy / sxx
}

/// Rates of all components over runs, against the size `size(run)` (h or k).
pub fn rates(
    runs: &[RunResult],
    size: impl Fn(&RunResult) -> f64,
    expected: f64,
) -> Vec<ComponentRates> {
    ErrorComponents::NAMES
        .iter()
        .enumerate()
        .map(|(c, name)| {
            let points: Vec<(f64, f64)> = runs
                .iter()
                .map(|r| (size(r), r.errors.values()[c]))
                .collect();
            let pairwise = points
                .windows(2)
                .map(|w| (w[0].1 / w[1].1).ln() / (w[0].0 / w[1].0).ln())
                .collect();
            let fit = &points[points.len().saturating_sub(FIT_LEVELS)..];
            let least_squares = least_squares_slope(fit);
            // Theorem 5.2 bounds the four terms of E(h, k) and their sum, not the velocity error
            let bounded = *name != "velocity";
            let pass = bounded.then(|| {
                finite(least_squares).is_some_and(|rate| rate >= expected - RATE_TOLERANCE)
            });
            ComponentRates {
                component: name.to_string(),
                pairwise,
                least_squares,
                expected: bounded.then_some(expected),
                pass,
            }
        })
        .collect()
}

/// Runs one simulation and measures its errors against `reference`.
pub fn run_one<const D: usize>(
    case: &Case<D>,
    degree: usize,
    cells: usize,
    steps: usize,
    reference: Option<Arc<Vec<State>>>,
) -> Result<RunResult, VerifyError> {
    let started = Instant::now();
    let problem = case.problem(cells, degree, steps)?;
    let h = problem.mesh.max_cell_diameter();
    let mesh_cells = problem.mesh.num_cells();
    let shape_regularity = shape_regularity(&problem.mesh);
    let mut simulation = Simulation::new(problem)?;
    let reference = match reference {
        Some(states) => Reference::Discrete(states),
        None => Reference::Exact(case.programs.clone()),
    };
    let k = simulation.time_step();
    let space = simulation.space().clone();
    let mut tracker = ErrorTracker::new(&space, reference, k, steps);
    let summary = simulation.run(|report| {
        tracker.observe(report.space, report.state);
        Ok(())
    })?;
    let unknowns = simulation.velocity_operator().size();
    Ok(RunResult {
        cells,
        h,
        mesh_cells,
        shape_regularity,
        steps,
        k,
        errors: tracker.finish(),
        stats: RunStats::from_summary(&summary, unknowns, started.elapsed().as_secs_f64()),
    })
}

/// Runs a reference simulation and keeps every state (for the k-study).
pub fn reference_states<const D: usize>(
    case: &Case<D>,
    degree: usize,
    cells: usize,
    steps: usize,
) -> Result<Vec<State>, VerifyError> {
    let mut simulation = Simulation::new(case.problem(cells, degree, steps)?)?;
    let mut states = vec![simulation.state().clone()];
    simulation.run(|report| {
        states.push(report.state.clone());
        Ok(())
    })?;
    Ok(states)
}

fn progress(total: usize, label: &str) -> ProgressBar {
    let bar = ProgressBar::new(total as u64);
    bar.set_style(
        ProgressStyle::with_template(
            "{prefix:>12} [{bar:30}] {pos}/{len} runs, {elapsed} elapsed, ~{eta} left",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    bar.set_prefix(label.to_string());
    if std::env::var_os("CI").is_some() {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    bar
}

/// Runs a level study (h or diagonal), all levels in parallel.
pub fn level_study<const D: usize>(
    case: &Case<D>,
    degree: usize,
    kind: StudyKind,
    study: &LevelStudy,
) -> Result<StudyResult, VerifyError> {
    if study.levels().len() != study.steps.len() || study.levels().len() < 2 {
        return Err(VerifyError::InvalidInput(format!(
            "{} study of order {degree}: the levels (`cells` or `refinements`) and `steps` need the same length ≥ 2",
            kind.name()
        )));
    }
    let bar = progress(
        study.levels().len(),
        &format!("{}-study l={degree}", kind.name()),
    );
    let runs: Vec<RunResult> = study
        .levels()
        .par_iter()
        .zip(&study.steps)
        .map(|(&cells, &steps)| {
            let result = run_one(case, degree, cells, steps, None);
            bar.inc(1);
            result
        })
        .collect::<Result<_, _>>()?;
    bar.finish_and_clear();
    // a diagonal study with k ∝ h^r converges like h^min(r, p)
    let expected = match kind {
        StudyKind::Diagonal => {
            let fit = &runs[runs.len().saturating_sub(FIT_LEVELS)..];
            let coupling = least_squares_slope(&fit.iter().map(|r| (r.h, r.k)).collect::<Vec<_>>());
            expected_h_rate(degree).min(coupling)
        }
        _ => expected_h_rate(degree),
    };
    let rates = rates(&runs, |r| r.h, expected);
    let pass = rates.iter().all(|r| r.pass != Some(false));
    Ok(StudyResult {
        kind,
        degree,
        variable: "h",
        expected_rate: expected,
        runs,
        rates,
        pass,
    })
}

/// Runs a k-study: a reference run with `reference_steps`, then every level in parallel.
pub fn time_study<const D: usize>(
    case: &Case<D>,
    degree: usize,
    study: &TimeStudy,
) -> Result<StudyResult, VerifyError> {
    if study.steps.len() < 2
        || study
            .steps
            .iter()
            .any(|&s| s == 0 || study.reference_steps % s != 0)
    {
        return Err(VerifyError::InvalidInput(format!(
            "k study of order {degree}: `reference_steps` = {} must be a multiple of every entry of `steps` {:?} (at least two levels)",
            study.reference_steps, study.steps
        )));
    }
    let bar = progress(study.steps.len() + 1, &format!("k-study l={degree}"));
    let reference = Arc::new(reference_states(
        case,
        degree,
        study.level(),
        study.reference_steps,
    )?);
    bar.inc(1);
    let coarse: Vec<Arc<Vec<State>>> = study
        .steps
        .iter()
        .map(|&steps| {
            let stride = study.reference_steps / steps;
            Arc::new(reference.iter().step_by(stride).cloned().collect())
        })
        .collect();
    let done = Mutex::new(());
    let runs: Vec<RunResult> = study
        .steps
        .par_iter()
        .zip(coarse)
        .map(|(&steps, states)| {
            let result = run_one(case, degree, study.level(), steps, Some(states));
            let _guard = done.lock();
            bar.inc(1);
            result
        })
        .collect::<Result<_, _>>()?;
    bar.finish_and_clear();
    // The reference carries its own first-order error c·k_ref, so e(k) ≈ c (k − k_ref): the
    // rate is measured against k − k_ref (with k_ref = k_min/8 using k alone would report
    // log2(15/7) ≈ 1.1 for an exactly first-order error between the two finest levels).
    let reference_k = case.file.final_time / study.reference_steps as f64;
    let rates = rates(&runs, |r| r.k - reference_k, 1.0);
    let pass = rates.iter().all(|r| r.pass != Some(false));
    Ok(StudyResult {
        kind: StudyKind::K,
        degree,
        variable: "k",
        expected_rate: 1.0,
        runs,
        rates,
        pass,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run at size `h` whose components are `errors` (in the order of `ErrorComponents::NAMES`).
    fn run(h: f64, errors: [f64; 6]) -> RunResult {
        let [displacement, difference_quotient, damage, damage_gradient, total, velocity] = errors;
        RunResult {
            cells: 1,
            h,
            mesh_cells: 1,
            shape_regularity: 1.0,
            steps: 1,
            k: h,
            errors: ErrorComponents {
                displacement,
                difference_quotient,
                damage,
                damage_gradient,
                total,
                velocity,
            },
            stats: RunStats::default(),
        }
    }

    /// Three levels: every bounded component first order, the velocity error missing (as in a
    /// k-study), except `damage`, which is missing at the finest level.
    fn runs() -> Vec<RunResult> {
        [0.4, 0.2, 0.1]
            .iter()
            .map(|&h| {
                let damage = if h < 0.15 { f64::NAN } else { h };
                run(h, [h, h, damage, h, 4.0 * h, f64::NAN])
            })
            .collect()
    }

    #[test]
    fn a_component_without_values_has_no_rates_and_no_verdict() {
        let rates = rates(&runs(), |r| r.h, 1.0);
        let velocity = rates.iter().find(|r| r.component == "velocity").unwrap();
        assert!(velocity.is_missing());
        assert_eq!((velocity.expected, velocity.pass), (None, None));
        let total = rates.iter().find(|r| r.component == "total").unwrap();
        assert!(!total.is_missing());
        assert!((total.least_squares - 1.0).abs() < 1e-12);
        assert_eq!(total.pass, Some(true));
    }

    #[test]
    fn a_bounded_component_missing_at_a_level_is_judged_on_the_others() {
        let rates = rates(&runs(), |r| r.h, 1.0);
        let damage = rates.iter().find(|r| r.component == "damage").unwrap();
        assert!(!damage.is_missing());
        assert!(damage.pairwise[0].is_finite() && !damage.pairwise[1].is_finite());
        assert!((damage.least_squares - 1.0).abs() < 1e-12);
        assert_eq!(damage.pass, Some(true));
    }

    #[test]
    fn a_bounded_component_without_a_rate_fails() {
        let runs: Vec<RunResult> = [0.2, 0.1]
            .iter()
            .map(|&h| run(h, [f64::NAN, h, h, h, f64::NAN, h]))
            .collect();
        let rates = rates(&runs, |r| r.h, 1.0);
        let displacement = &rates[0];
        assert!(displacement.is_missing());
        assert_eq!(displacement.pass, Some(false));
        let velocity = rates.iter().find(|r| r.component == "velocity").unwrap();
        assert_eq!(velocity.pass, None);
    }

    #[test]
    fn summary_json_has_null_for_missing_values_and_newton_statistics() {
        let mut runs = runs();
        runs[0].stats = RunStats::from_summary(
            &RunSummary {
                steps: 4,
                velocity_newton_iterations: 6,
                max_velocity_newton_iterations: 3,
                slowest_velocity_history: vec![1e-3, 1e-8, 1e-13],
                ..RunSummary::default()
            },
            10,
            0.5,
        );
        let rates = rates(&runs, |r| r.h, 1.0);
        let text = serde_json::to_string(&(&runs, &rates)).unwrap();
        assert!(!text.contains("NaN") && !text.contains("inf"), "{text}");
        let json: serde_json::Value = serde_json::from_str(&text).unwrap();
        let stats = &json[0][0]["stats"];
        assert_eq!(stats["newton_iterations"], 6);
        assert_eq!(stats["mean_newton_iterations"], 1.5);
        assert_eq!(stats["max_newton_iterations"], 3);
        assert_eq!(
            stats["slowest_newton_history"],
            serde_json::json!([1e-3, 1e-8, 1e-13])
        );
        assert!(json[0][0]["errors"]["velocity"].is_null());
        assert_eq!(json[0][0]["errors"]["total"], 1.6);
        assert!(json[0][2]["errors"]["damage"].is_null());
        let velocity = &json[1][5];
        assert_eq!(velocity["component"], "velocity");
        assert_eq!(velocity["pairwise"], serde_json::json!([null, null]));
        assert!(velocity["least_squares"].is_null() && velocity["pass"].is_null());
    }
}
