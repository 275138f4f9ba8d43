//! Convergence studies: h-study, k-study and diagonal study (k ∝ h^r), run in parallel with
//! rayon, with observed rates (pairwise and least squares over the finest levels), the rates
//! expected from Theorem 5.2, and a verdict ([`Verdict`]) with one tolerance
//! ([`RATE_TOLERANCE`]): PASS only when the fitted and the finest rates reach the theorem's and
//! E(h, k) is in the asymptotic range.

use crate::case::{Case, LevelStudy, TimeStudy};
use crate::error_norms::{ErrorComponents, ErrorTracker, Reference};
use crate::manufactured::data::ExactPrograms;
use crate::output::{finite, finite_or_null, finite_or_null_each};
use crate::InputError;
use contact_damage::error::StepDatum;
use contact_damage::fem::quality::shape_regularity;
use contact_damage::scheme::{RunSummary, Simulation, State};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde::ser::SerializeMap;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Tolerance of every verdict: a bounded quantity passes when its least-squares rate over the
/// finest levels and its rate between the two finest levels are both ≥ expected −
/// `RATE_TOLERANCE`.
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
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
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

/// Solver statistics of one run. It is read back from a result file of the runs cache
/// ([`crate::sweep`]), where a value without a number (`null`) is read as NaN.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct RunStats {
    /// Unknowns of the velocity step (d × nodes).
    pub velocity_unknowns: usize,
    /// Largest KKT residual of a velocity step.
    #[serde(deserialize_with = "nan_if_null")]
    pub max_velocity_kkt: f64,
    /// Largest KKT residual of a damage step.
    #[serde(deserialize_with = "nan_if_null")]
    pub max_damage_kkt: f64,
    /// Outer Newton iterations of the velocity steps (5.1), all steps together.
    pub newton_iterations: usize,
    /// Newton iterations of one velocity step (5.1), mean over the steps
    /// (`newton_iterations / steps`; 0 for a run without steps).
    #[serde(deserialize_with = "nan_if_null")]
    pub mean_newton_iterations: f64,
    /// Newton iterations of one velocity step (5.1), the most over the steps.
    pub max_newton_iterations: usize,
    /// The relative KKT residual after each Newton iteration of the slowest velocity step (the
    /// first step with `max_newton_iterations` iterations); its last entry is that step's final
    /// residual, below the velocity tolerance. Empty for a run without steps.
    #[serde(
        serialize_with = "finite_or_null_each",
        deserialize_with = "nan_if_null_each"
    )]
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
    #[serde(deserialize_with = "nan_if_null")]
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
            steps_with_separation: summary.steps_with_status.separated,
            steps_with_stick: summary.steps_with_status.stick,
            steps_with_slip: summary.steps_with_status.slip,
            steps_with_lower_bound: summary.steps_with_lower_damage_bound,
            steps_with_upper_bound: summary.steps_with_upper_damage_bound,
            wall_seconds: seconds,
        }
    }
}

/// One run of a study (also the payload of a result file of the runs cache, [`crate::sweep`]).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RunResult {
    /// The level: cells per side (box domain) or uniform refinements of the Gmsh mesh.
    pub cells: usize,
    /// Mesh size h (largest cell diameter).
    #[serde(deserialize_with = "nan_if_null")]
    pub h: f64,
    /// Number of cells of the mesh.
    pub mesh_cells: usize,
    /// Shape-regularity measure of the mesh, max_K (h_K/ρ_K) normalized by the regular
    /// simplex ([`contact_damage::fem::quality::shape_regularity`]; Theorem 5.2 needs it bounded).
    #[serde(serialize_with = "finite_or_null")]
    pub shape_regularity: f64,
    /// Time steps N.
    pub steps: usize,
    /// k = T/N.
    #[serde(deserialize_with = "nan_if_null")]
    pub k: f64,
    /// Error components (in JSON, a component without a value, e.g. `velocity` against a
    /// discrete reference, is `null`).
    #[serde(
        serialize_with = "components_or_null",
        deserialize_with = "components_from_nulls"
    )]
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

/// Reads a number or `null` (NaN): the inverse of `finite_or_null`.
fn nan_if_null<'de, D: Deserializer<'de>>(deserializer: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(deserializer)?.unwrap_or(f64::NAN))
}

/// Reads a sequence of numbers or `null`s (NaN): the inverse of `finite_or_null_each`.
fn nan_if_null_each<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Vec<f64>, D::Error> {
    Ok(Vec::<Option<f64>>::deserialize(deserializer)?
        .into_iter()
        .map(|value| value.unwrap_or(f64::NAN))
        .collect())
}

/// Reads the error components written by `components_or_null` (every key of
/// [`ErrorComponents::NAMES`] required, `null` read as NaN).
fn components_from_nulls<'de, D: Deserializer<'de>>(
    deserializer: D,
) -> Result<ErrorComponents, D::Error> {
    #[derive(Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Nullable {
        displacement: Option<f64>,
        difference_quotient: Option<f64>,
        damage: Option<f64>,
        damage_gradient: Option<f64>,
        total: Option<f64>,
        velocity: Option<f64>,
    }
    let n = Nullable::deserialize(deserializer)?;
    let value = |v: Option<f64>| v.unwrap_or(f64::NAN);
    Ok(ErrorComponents {
        displacement: value(n.displacement),
        difference_quotient: value(n.difference_quotient),
        damage: value(n.damage),
        damage_gradient: value(n.damage_gradient),
        total: value(n.total),
        velocity: value(n.velocity),
    })
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
    /// Standard error of that slope (see [`SlopeFit`]; not finite with fewer than three points).
    #[serde(serialize_with = "finite_or_null")]
    pub standard_error: f64,
    /// The 95 % confidence interval of the slope, slope ± t_{0.975, n−2} × standard error
    /// (Student's t; not finite with fewer than three points).
    #[serde(serialize_with = "finite_or_null_each")]
    pub interval_95: Vec<f64>,
    /// True when the pairwise rates over the fitted levels are not yet in the asymptotic range
    /// ([`is_drifting`]); None with fewer than two pairwise rates there.
    pub drifting: Option<bool>,
    /// Expected rate (None for quantities the theorem does not bound).
    pub expected: Option<f64>,
    /// The verdict: None for a quantity the theorem does not bound (it is not judged, whether it
    /// has values or not); for a bounded one, `least_squares` ≥ expected − tolerance and the
    /// finest pairwise rate ([`finest_pairwise_rate`]) ≥ expected − tolerance, which fails when
    /// either is missing (the study then shows nothing about it).
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
    /// The verdict ([`Verdict::of`] the rates).
    pub verdict: Verdict,
}

/// Expected h-exponent of Theorem 5.2: min(l, (l+1)/2).
pub fn expected_h_rate(degree: usize) -> f64 {
    (degree as f64).min((degree as f64 + 1.0) / 2.0)
}

/// Least-squares slope of log(error) against log(size).
pub fn least_squares_slope(points: &[(f64, f64)]) -> f64 {
    slope_fit(points).slope
}

/// The least-squares line through (log size, log error) with the uncertainty of its slope.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlopeFit {
    /// The slope (NaN with fewer than two usable points).
    pub slope: f64,
    /// Its standard error √(Σ r_i² / (n − 2) / Σ (x_i − x̄)²), r_i the residuals of the line
    /// (NaN with fewer than three points: two points leave no residual to estimate it from).
    pub standard_error: f64,
    /// Half-width of the 95 % interval, t_{0.975, n−2} × standard error.
    pub half_width_95: f64,
}

/// t_{0.975, ν} of Student's t distribution for ν = 1 … 10 degrees of freedom.
const STUDENT_T_975: [f64; 10] = [
    12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228,
];

/// t_{0.975, ν}: the table for ν ≤ 10, 2.0 (a slight overestimate of 1.96–2.2) above.
pub fn student_t_975(degrees_of_freedom: usize) -> f64 {
    match degrees_of_freedom {
        0 => f64::NAN,
        nu if nu <= STUDENT_T_975.len() => STUDENT_T_975[nu - 1],
        _ => 2.2,
    }
}

/// The least-squares fit of log(error) against log(size), points with a non-positive or
/// non-finite value left out.
pub fn slope_fit(points: &[(f64, f64)]) -> SlopeFit {
    let logs: Vec<(f64, f64)> = points
        .iter()
        .filter(|(s, e)| *s > 0.0 && *e > 0.0 && e.is_finite() && s.is_finite())
        .map(|(s, e)| (s.ln(), e.ln()))
        .collect();
    let n = logs.len() as f64;
    if logs.len() < 2 {
        return SlopeFit {
            slope: f64::NAN,
            standard_error: f64::NAN,
            half_width_95: f64::NAN,
        };
    }
    let mean_x = logs.iter().map(|p| p.0).sum::<f64>() / n;
    let mean_y = logs.iter().map(|p| p.1).sum::<f64>() / n;
    let sxy: f64 = logs.iter().map(|(x, y)| (x - mean_x) * (y - mean_y)).sum();
    let sxx: f64 = logs.iter().map(|(x, _)| (x - mean_x).powi(2)).sum();
    let slope = sxy / sxx;
    let (standard_error, half_width_95) = if logs.len() < 3 {
        (f64::NAN, f64::NAN)
    } else {
        let residuals: f64 = logs
            .iter()
            .map(|(x, y)| (y - mean_y - slope * (x - mean_x)).powi(2))
            .sum();
        let se = (residuals / (n - 2.0) / sxx).sqrt();
        (se, student_t_975(logs.len() - 2) * se)
    };
    SlopeFit {
        slope,
        standard_error,
        half_width_95,
    }
}

/// Largest spread of the pairwise rates over the fitted levels that still counts as the
/// asymptotic range: [`RATE_TOLERANCE`].
pub const DRIFT_TOLERANCE: f64 = RATE_TOLERANCE;

/// The drift rule: the pairwise rates between consecutive levels of the fit (the finest
/// [`FIT_LEVELS`] levels) are "drifting" — not yet in the asymptotic range — when they differ
/// by more than [`DRIFT_TOLERANCE`] (max − min). None with fewer than two finite pairwise
/// rates there. Applied to E(h, k), it decides whether a study can be certified
/// ([`Verdict::Drifting`]); for the single components it informs.
pub fn is_drifting(pairwise_in_fit: &[f64]) -> Option<bool> {
    let finite: Vec<f64> = pairwise_in_fit
        .iter()
        .copied()
        .filter(|r| r.is_finite())
        .collect();
    if finite.len() < 2 {
        return None;
    }
    let max = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let min = finite.iter().copied().fold(f64::INFINITY, f64::min);
    Some(max - min > DRIFT_TOLERANCE)
}

/// The rate between the two finest levels at which `points` (size, error) have a positive
/// finite error (NaN when fewer than two have one): the rate the verdict reads beside the
/// least-squares fit, so that a fit drawn up by coarse levels cannot hide a finest rate below
/// the theorem's (an error floor).
pub fn finest_pairwise_rate(points: &[(f64, f64)]) -> f64 {
    let usable: Vec<&(f64, f64)> = points
        .iter()
        .filter(|(s, e)| *s > 0.0 && *e > 0.0 && e.is_finite() && s.is_finite())
        .collect();
    match usable[..] {
        [.., (s0, e0), (s1, e1)] => (e0 / e1).ln() / (s0 / s1).ln(),
        _ => f64::NAN,
    }
}

/// The verdict of a study; ordered from the best to the worst.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// Certified: every quantity Theorem 5.2 bounds converges at least at the expected rate
    /// (less [`RATE_TOLERANCE`]) by its least-squares rate and by its finest pairwise rate,
    /// and E(h, k) is in the asymptotic range (its pairwise rates over the fit do not drift).
    Pass,
    /// No rate is below the theorem's, but E(h, k) is not yet in the asymptotic range (its
    /// pairwise rates over the fitted levels differ by more than [`DRIFT_TOLERANCE`], or there
    /// are too few levels to tell): the study certifies nothing until a finer level is added.
    Drifting,
    /// Some bounded quantity converges more slowly than the theorem allows.
    Fail,
}

impl Verdict {
    /// The verdict of a study from the rates of its components ([`rates`]).
    pub fn of(rates: &[ComponentRates]) -> Self {
        if rates.iter().any(|r| r.pass == Some(false)) {
            Verdict::Fail
        } else if rates
            .iter()
            .any(|r| r.component == "total" && r.drifting != Some(false))
        {
            Verdict::Drifting
        } else {
            Verdict::Pass
        }
    }

    /// The verdict of several studies: FAIL if one fails, else DRIFTING if one drifts, else
    /// PASS (PASS for none).
    pub fn combine(verdicts: impl IntoIterator<Item = Verdict>) -> Self {
        verdicts.into_iter().max().unwrap_or(Verdict::Pass)
    }

    /// `PASS`, `FAIL` or `DRIFTING`, as printed in the reports.
    pub fn label(self) -> &'static str {
        match self {
            Verdict::Pass => "PASS",
            Verdict::Fail => "FAIL",
            Verdict::Drifting => "DRIFTING",
        }
    }

    /// What the verdict means, in one clause (the last line of `verify`'s output).
    pub fn explanation(self) -> &'static str {
        match self {
            Verdict::Pass => {
                "every bounded rate ≥ expected − tolerance, E(h, k) in the asymptotic range"
            }
            Verdict::Fail => "a bounded rate is below expected − tolerance",
            Verdict::Drifting => {
                "not certified: E(h, k) is not yet in the asymptotic range (add a finer level)"
            }
        }
    }
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
            let pairwise: Vec<f64> = points
                .windows(2)
                .map(|w| (w[0].1 / w[1].1).ln() / (w[0].0 / w[1].0).ln())
                .collect();
            let fit = &points[points.len().saturating_sub(FIT_LEVELS)..];
            let line = slope_fit(fit);
            let least_squares = line.slope;
            let finest = finest_pairwise_rate(&points);
            let drifting = is_drifting(&pairwise[pairwise.len().saturating_sub(FIT_LEVELS - 1)..]);
            // Theorem 5.2 bounds the four terms of E(h, k) and their sum, not the velocity error
            let bounded = *name != "velocity";
            let at_least = |rate: f64| finite(rate).is_some_and(|r| r >= expected - RATE_TOLERANCE);
            let pass = bounded.then(|| at_least(least_squares) && at_least(finest));
            ComponentRates {
                component: name.to_string(),
                pairwise,
                least_squares,
                standard_error: line.standard_error,
                interval_95: vec![
                    least_squares - line.half_width_95,
                    least_squares + line.half_width_95,
                ],
                drifting,
                expected: bounded.then_some(expected),
                pass,
            }
        })
        .collect()
}

/// Runs one simulation of `case` at a level and measures its errors against `reference` (the
/// exact solution when None).
pub fn run_one<const D: usize>(
    case: &Case<D>,
    degree: usize,
    cells: usize,
    steps: usize,
    reference: Option<Arc<Vec<State>>>,
) -> Result<RunResult, InputError> {
    let started = Instant::now();
    let problem = case.problem(cells, degree, steps)?;
    run_problem(case, problem, cells, reference, started)
}

/// Runs the simulation of `problem` — a problem of `case` at the level `cells` ([`Case::problem`]),
/// possibly altered by the caller, e.g. a solver given other laws than those the manufactured
/// data were built from — and measures its errors against the exact solution of `case` (or
/// against `reference`); `started` is when the run's wall time starts.
pub fn run_problem<const D: usize>(
    case: &Case<D>,
    problem: contact_damage::scheme::Problem<D>,
    cells: usize,
    reference: Option<Arc<Vec<State>>>,
    started: Instant,
) -> Result<RunResult, InputError> {
    let steps = problem.steps;
    let h = problem.mesh.max_cell_diameter();
    let mesh_cells = problem.mesh.num_cells();
    let shape_regularity = shape_regularity(&problem.mesh);
    let mut simulation = Simulation::new(problem).map_err(|error| {
        InputError::from(error).located(contact_input::FileKind::Case, &case.origin)
    })?;
    let reference = match reference {
        Some(states) => {
            // stored states read from a results folder must fit this run's mesh and steps
            let nodes = simulation.space().num_nodes();
            let fits = |state: &State| {
                state.damage.len() == nodes
                    && state.displacement.len() == D * nodes
                    && state.velocity.len() == D * nodes
            };
            if states.len() < steps + 1 || !states.iter().all(fits) {
                return Err(InputError::InvalidInput(format!(
                    "the reference states do not fit this run: {} states for {} steps + 1, \
                     vectors of {} values for a space of {nodes} nodes; remove the reference \
                     run's result file so that it is recomputed",
                    states.len(),
                    steps,
                    states.first().map_or(0, |state| state.damage.len())
                )));
            }
            Reference::Discrete(states)
        }
        // Empty caches: the error points of this run only.
        None => Reference::Exact(Arc::new(ExactPrograms::clone(&case.programs))),
    };
    let k = simulation.time_step();
    let space = simulation.space().clone();
    let mut tracker = ErrorTracker::new(&space, reference, k, steps);
    let summary = simulation
        .run(|report| {
            tracker.observe(report.space, report.state);
            Ok(())
        })
        .map_err(|error| explain_failure(case, &mut simulation, cells, error))?;
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
) -> Result<Vec<State>, InputError> {
    let mut simulation = Simulation::new(case.problem(cells, degree, steps)?).map_err(|error| {
        InputError::from(error).located(contact_input::FileKind::Case, &case.origin)
    })?;
    let mut states = vec![simulation.state().clone()];
    simulation
        .run(|report| {
            states.push(report.state.clone());
            Ok(())
        })
        .map_err(|error| explain_failure(case, &mut simulation, cells, error))?;
    Ok(states)
}

/// A failed run of `simulation` whose time step lies above the stability limit of the explicit
/// terms of (5.1) ([`contact_damage::scheme::stability`]) is reported as such, naming the case and the
/// level; the solver's own error (typically a Newton or friction solve that no longer
/// converges) follows as the symptom. Other failures (and, whatever the step, loads that are
/// not finite or out of scale and laws that leave their range) pass unchanged, located at their key in the case file when
/// the solver names one ([`InputError::located`]).
fn explain_failure<const D: usize>(
    case: &Case<D>,
    simulation: &mut Simulation<D>,
    cells: usize,
    error: contact_damage::Error,
) -> InputError {
    let step = simulation.time_step();
    // loads that cannot be used and laws out of their range are the cause, not a symptom of an
    // unstable step (a contact pressure out of scale may be one: it grows with u_(n−1))
    let data = matches!(
        error,
        contact_damage::Error::StepData {
            quantity: StepDatum::Load | StepDatum::PrescribedVelocity,
            ..
        } | contact_damage::Error::InvalidParameter { .. }
    );
    match simulation.step_limit() {
        Ok(limit) if step > limit.time_step && !data => InputError::InvalidInput(format!(
            "case `{}`, level with {cells} cells and {} steps: the time step k = {step:.3e} exceeds the stability limit k_max = {:.3e} of the explicit terms of (5.1) (λ_max(H⁻¹B) = {:.3e}); lower `laws.contact.stiffness` or the elasticity against the viscosity, or take more steps (the solver stopped with: {error})",
            case.origin,
            simulation.steps(),
            limit.time_step,
            limit.largest_rate,
        )),
        _ => InputError::from(error).located(contact_input::FileKind::Case, &case.origin),
    }
}

/// A progress bar of `total` runs (hidden under `CI`).
pub(crate) fn progress(total: usize, label: &str) -> ProgressBar {
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
) -> Result<StudyResult, InputError> {
    if study.levels().len() != study.steps.len() || study.levels().len() < 2 {
        return Err(InputError::InvalidInput(format!(
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
    Ok(level_study_result(kind, degree, runs))
}

/// The result of a level study (h or diagonal) from its runs, coarsest first: the expected
/// rate (Theorem 5.2; for a diagonal study with k ∝ h^r, min(r, p) with r fitted over the
/// finest levels), the rates and the verdict.
pub fn level_study_result(kind: StudyKind, degree: usize, runs: Vec<RunResult>) -> StudyResult {
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
    StudyResult {
        kind,
        degree,
        variable: "h",
        expected_rate: expected,
        runs,
        verdict: Verdict::of(&rates),
        rates,
    }
}

/// Runs a k-study: a reference run with `reference_steps`, then every level in parallel.
pub fn time_study<const D: usize>(
    case: &Case<D>,
    degree: usize,
    study: &TimeStudy,
) -> Result<StudyResult, InputError> {
    if study.steps.len() < 2
        || study
            .steps
            .iter()
            .any(|&s| s == 0 || study.reference_steps % s != 0)
    {
        return Err(InputError::InvalidInput(format!(
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
    Ok(time_study_result(
        degree,
        case.file.final_time / study.reference_steps as f64,
        runs,
    ))
}

/// The result of a k-study from its runs, coarsest first, measured against a reference run
/// with time step `reference_k`: rates in k − k_ref (expected 1, Theorem 5.2) and the verdict.
pub fn time_study_result(degree: usize, reference_k: f64, runs: Vec<RunResult>) -> StudyResult {
    // The reference carries its own first-order error c·k_ref, so e(k) ≈ c (k − k_ref): the
    // rate is measured against k − k_ref (with k_ref = k_min/8 using k alone would report
    // log2(15/7) ≈ 1.1 for an exactly first-order error between the two finest levels).
    let rates = rates(&runs, |r| r.k - reference_k, 1.0);
    StudyResult {
        kind: StudyKind::K,
        degree,
        variable: "k",
        expected_rate: 1.0,
        runs,
        verdict: Verdict::of(&rates),
        rates,
    }
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
    fn the_slope_has_a_standard_error_and_a_drift_flag() {
        // e = h exactly: slope 1, no residual, no drift
        let exact = slope_fit(&[(0.4, 0.4), (0.2, 0.2), (0.1, 0.1)]);
        assert!((exact.slope - 1.0).abs() < 1e-12 && exact.standard_error < 1e-12);
        // log e = log h + (0, δ, 0): residuals (−δ/3, 2δ/3, −δ/3), Σ r² = 2δ²/3, one degree of
        // freedom, Σ (x − x̄)² = 2 ln² 2, so se = δ/(√3 ln 2)
        let delta: f64 = 0.1;
        let bumped = slope_fit(&[(0.4, 0.4), (0.2, 0.2 * delta.exp()), (0.1, 0.1)]);
        let se = delta / (3f64.sqrt() * 2f64.ln());
        assert!((bumped.standard_error - se).abs() < 1e-12, "{bumped:?}");
        assert!((bumped.half_width_95 - 12.706 * se).abs() < 1e-12);
        assert!(slope_fit(&[(0.2, 0.2), (0.1, 0.1)]).standard_error.is_nan());
        // pairwise rates 1 ± δ/ln 2 spread by 2δ/ln 2 = 0.29 > 0.15: drifting
        let runs: Vec<RunResult> = [(0.4, 0.4), (0.2, 0.2 * delta.exp()), (0.1, 0.1)]
            .iter()
            .map(|&(h, e)| run(h, [e, h, h, h, 4.0 * h, f64::NAN]))
            .collect();
        let rates = rates(&runs, |r| r.h, 1.0);
        assert_eq!(rates[0].drifting, Some(true));
        assert_eq!(rates[1].drifting, Some(false));
        assert_eq!(rates[5].drifting, None);
        // the verdict ignores the flag
        assert_eq!(rates[0].pass, Some(true));
        assert!(
            (rates[0].interval_95[1] - rates[0].interval_95[0] - 2.0 * 12.706 * se).abs() < 1e-9
        );
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

    /// A level study at h = 0.4, 0.2, 0.1, 0.05 whose every bounded component is `error(h)`.
    fn study_of(error: impl Fn(f64) -> f64) -> StudyResult {
        let runs = [0.4, 0.2, 0.1, 0.05]
            .iter()
            .map(|&h| {
                let e = error(h);
                run(h, [e, e, e, e, 4.0 * e, f64::NAN])
            })
            .collect();
        level_study_result(StudyKind::H, 1, runs)
    }

    #[test]
    fn an_error_floor_hidden_by_the_fit_fails_the_verdict() {
        // e = h + h²: pairwise rates 1.22, 1.13, 1.07: certified
        assert_eq!(study_of(|h| h + h * h).verdict, Verdict::Pass);
        // a floor of 0.03 under 4h²: pairwise 1.82, 1.44, 0.81: the fit over the three finest
        // levels (1.12) passes, the finest pair does not
        let floored = study_of(|h| 4.0 * h * h + 0.03);
        let total = &floored.rates[4];
        assert!(total.least_squares >= 0.85, "{total:?}");
        assert!(*total.pairwise.last().unwrap() < 0.85, "{total:?}");
        assert_eq!(total.pass, Some(false));
        assert_eq!(floored.verdict, Verdict::Fail);
    }

    #[test]
    fn a_drifting_total_error_is_not_certified() {
        // e = h² + 0.1 h: every rate ≥ 1, but the pairwise rates fall 1.74, 1.59, 1.42: drifting
        let drifting = study_of(|h| h * h + 0.1 * h);
        assert!(drifting.rates.iter().all(|r| r.pass != Some(false)));
        assert_eq!(drifting.rates[4].drifting, Some(true));
        assert_eq!(drifting.verdict, Verdict::Drifting);
        // two levels have a single pairwise rate: nothing tells whether it is asymptotic
        let two = level_study_result(
            StudyKind::H,
            1,
            [0.2, 0.1]
                .iter()
                .map(|&h| run(h, [h, h, h, h, 4.0 * h, f64::NAN]))
                .collect(),
        );
        assert_eq!(two.rates[4].drifting, None);
        assert_eq!(two.verdict, Verdict::Drifting);
    }

    #[test]
    fn verdicts_combine_to_the_worst() {
        use Verdict::{Drifting, Fail, Pass};
        assert_eq!(Verdict::combine([]), Pass);
        assert_eq!(Verdict::combine([Pass, Pass]), Pass);
        assert_eq!(Verdict::combine([Pass, Drifting, Pass]), Drifting);
        assert_eq!(Verdict::combine([Drifting, Fail, Pass]), Fail);
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
