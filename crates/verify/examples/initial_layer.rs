//! The discrete initial layer of the damage equation, step by step (docs/explanation/rates.md).
//!
//! ```text
//! cargo run --release -p verify --example initial_layer -- [CASE.toml …] [--cells N] [--order l] [--reference-steps M]
//! ```
//!
//! For each 2D case (default: `verification/zones2d.toml` and `verification/layer2d.toml`) it
//! runs the scheme on one mesh with N = 8, 16, …, 128 steps and once with M steps (default
//! 1024) as the reference, and prints per N: the damage components of the k-study,
//! (kΣ‖∇(β_ref − β_n)‖²)^½ and max_n ‖β_ref − β_n‖ with their rates, the share of the first two
//! steps in kΣ‖∇·‖², and the gradient error ‖∇(β_ref(t_n) − β_n)‖ at n = 1, 2, 3, N/2, N.
//! An initial layer shows as a first-step error that does not decrease with k.

use contact_damage::fem::quadrature::QuadratureRule;
use contact_damage::fem::space::LagrangeSpace;
use contact_damage::scheme::{Simulation, State};
use std::process::ExitCode;
use verify::case::{read_case_file, Case};
use verify::InputError;

/// ‖∇e‖² and ‖e‖² of the nodal field `e` by a rule of degree 2l.
fn squared_norms(space: &LagrangeSpace<2>, rule: &QuadratureRule<2>, error: &[f64]) -> (f64, f64) {
    let (mut gradient, mut value) = (0.0, 0.0);
    for c in 0..space.mesh().num_cells() {
        let det = space.geometry(c).det.abs();
        for (point, weight) in rule.points.iter().zip(&rule.weights) {
            let (e, grad) = space.eval_scalar(c, point, error);
            gradient += weight * det * grad.norm_squared();
            value += weight * det * e * e;
        }
    }
    (gradient, value)
}

fn all_states(
    case: &Case<2>,
    cells: usize,
    degree: usize,
    steps: usize,
) -> Result<Vec<State>, InputError> {
    let mut simulation = Simulation::new(case.problem(cells, degree, steps)?)?;
    let mut states = vec![simulation.state().clone()];
    simulation.run(|report| {
        states.push(report.state.clone());
        Ok(())
    })?;
    Ok(states)
}

fn profile(
    path: &str,
    cells: usize,
    degree: usize,
    reference_steps: usize,
) -> Result<(), InputError> {
    let file = read_case_file(std::path::Path::new(path))?;
    if file.dim != 2 {
        return Err(InputError::InvalidInput(format!(
            "{path}: a 2D case is needed"
        )));
    }
    let case = Case::<2>::new(file, path)?;
    let final_time = case.file.final_time;
    let reference = all_states(&case, cells, degree, reference_steps)?;
    let space = Simulation::new(case.problem(cells, degree, 1)?)?
        .space()
        .clone();
    let rule = QuadratureRule::<2>::simplex(2 * degree);
    println!("{path}: {cells} cells, l = {degree}, reference N = {reference_steps}");
    println!("     N   (kΣ‖∇e‖²)^½  rate   max‖e‖     rate   first 2 steps   ‖∇e_n‖ at n = 1, 2, 3, N/2, N");
    let mut previous: Option<(f64, f64)> = None;
    for steps in [8usize, 16, 32, 64, 128] {
        if reference_steps % steps != 0 || steps >= reference_steps {
            continue;
        }
        let run = all_states(&case, cells, degree, steps)?;
        let stride = reference_steps / steps;
        let k = final_time / steps as f64;
        let (mut sum, mut max_value, mut gradients) = (0.0, 0.0f64, Vec::new());
        for n in 1..=steps {
            let error: Vec<f64> = run[n]
                .damage
                .iter()
                .zip(&reference[n * stride].damage)
                .map(|(a, b)| a - b)
                .collect();
            let (gradient, value) = squared_norms(&space, &rule, &error);
            sum += k * gradient;
            max_value = max_value.max(value.sqrt());
            gradients.push(gradient.sqrt());
        }
        let first_two: f64 = gradients.iter().take(2).map(|g| k * g * g).sum();
        let gradient_norm = sum.sqrt();
        // rates against k − k_ref, as in the k-study
        let shift = final_time / reference_steps as f64;
        let rate = |now: f64, before: f64| {
            ((before / now).ln() / ((2.0 * k - shift) / (k - shift)).ln()).to_string()
        };
        let (gradient_rate, value_rate) = match previous {
            Some((g, v)) => (rate(gradient_norm, g), rate(max_value, v)),
            None => ("-".into(), "-".into()),
        };
        println!(
            "  {steps:4}   {gradient_norm:.3e}   {:>4.4}   {max_value:.3e}  {:>4.4}   {:>5.1}%          {:.2e} {:.2e} {:.2e} {:.2e} {:.2e}",
            gradient_rate,
            value_rate,
            100.0 * first_two / sum,
            gradients[0],
            gradients[1],
            gradients[2],
            gradients[steps / 2 - 1],
            gradients[steps - 1]
        );
        previous = Some((gradient_norm, max_value));
    }
    Ok(())
}

fn main() -> ExitCode {
    let mut cases = Vec::new();
    let (mut cells, mut degree, mut reference_steps) = (16usize, 1usize, 1024usize);
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut number = |name: &str| -> Option<usize> {
            let value = args.next().and_then(|v| v.parse().ok());
            if value.is_none() {
                eprintln!("initial_layer: {name} needs a positive integer");
            }
            value.filter(|&v| v > 0)
        };
        let parsed = match arg.as_str() {
            "--cells" => number("--cells").map(|v| cells = v),
            "--order" => number("--order").map(|v| degree = v),
            "--reference-steps" => number("--reference-steps").map(|v| reference_steps = v),
            _ => {
                cases.push(arg);
                Some(())
            }
        };
        if parsed.is_none() {
            return ExitCode::from(2);
        }
    }
    if cases.is_empty() {
        cases = vec![
            "verification/zones2d.toml".into(),
            "verification/layer2d.toml".into(),
        ];
    }
    for path in &cases {
        if let Err(error) = profile(path, cells, degree, reference_steps) {
            eprintln!("initial_layer: {error}");
            return ExitCode::from(2);
        }
        println!();
    }
    ExitCode::SUCCESS
}
