//! Convergence studies: h-study, k-study and diagonal study (k ∝ h^r), run in parallel with
//! rayon, with observed rates (pairwise and least squares over the finest levels), the rates
//! expected from Theorem 5.2, and a verdict with one tolerance ([`RATE_TOLERANCE`]).

use crate::case::{Case, LevelStudy, TimeStudy};
use crate::errors::{ErrorComponents, ErrorTracker, Reference};
use crate::VerifyError;
use contact_damage::scheme::{RunSummary, Simulation, State};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde::Serialize;
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
    /// Outer Newton iterations (all steps).
    pub newton_iterations: usize,
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
    /// Cells per side.
    pub cells: usize,
    /// Mesh size h (largest cell diameter).
    pub h: f64,
    /// Time steps N.
    pub steps: usize,
    /// k = T/N.
    pub k: f64,
    /// Error components.
    pub errors: ErrorComponents,
    /// Solver statistics.
    pub stats: RunStats,
}

/// Rates of one error component.
#[derive(Debug, Clone, Serialize)]
pub struct ComponentRates {
    /// Component name.
    pub component: String,
    /// Rates between consecutive levels.
    pub pairwise: Vec<f64>,
    /// Least-squares slope over the finest [`FIT_LEVELS`] levels.
    pub least_squares: f64,
    /// Expected rate (None for quantities the theorem does not bound).
    pub expected: Option<f64>,
    /// observed ≥ expected − tolerance (None when not bounded).
    pub pass: Option<bool>,
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
            let bounded = *name != "velocity";
            ComponentRates {
                component: name.to_string(),
                pairwise,
                least_squares,
                expected: bounded.then_some(expected),
                pass: bounded.then_some(least_squares >= expected - RATE_TOLERANCE),
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
    let mut simulation = Simulation::new(problem)?;
    let reference = match reference {
        Some(states) => Reference::Discrete(states),
        None => Reference::Exact(Arc::new(case.exact.clone())),
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
    if study.cells.len() != study.steps.len() || study.cells.len() < 2 {
        return Err(VerifyError::InvalidInput(format!(
            "{} study of order {degree}: `cells` and `steps` need the same length ≥ 2",
            kind.name()
        )));
    }
    let bar = progress(
        study.cells.len(),
        &format!("{}-study l={degree}", kind.name()),
    );
    let runs: Vec<RunResult> = study
        .cells
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
        study.cells,
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
            let result = run_one(case, degree, study.cells, steps, Some(states));
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
