//! The hostile-input catalogue of `simulate`, generated: for each class of input that a
//! problem file can get wrong at run time or at scale — data out of the scale of double
//! precision, data undefined at one step, initial data out of range, constraints that leave the
//! body free, parts that disagree on a shared node, a law that leaves its range during the run
//! — edits of the small example are generated over a range of keys, magnitudes, signs and
//! times. Every generated file must be refused by the binary with exit status 1 (no panic, no
//! signal, no success, no stagnating solver), within a minute, with a message that names the
//! file and the key the input came from.

use crate::common::scratch;
use crate::process::{output_within_a_minute, refusal_fault};
use std::path::Path;
use std::process::Command;

const EXAMPLE: &str = include_str!("../examples/rectangle_2d.toml");

/// The 2D example on an 8 × 4 mesh with 8 steps of 0.05, saved every 4.
pub fn small_example() -> String {
    let text = EXAMPLE
        .replace("cells = [40, 20]", "cells = [8, 4]")
        .replace("steps = 250", "steps = 8")
        .replace("final_time = 5.0", "final_time = 0.4")
        .replace("every = 10", "every = 4");
    assert_ne!(text, EXAMPLE);
    text
}

/// One generated input: the edits (text → replacement) applied to the small example and the
/// key its error must name.
struct Hostile {
    class: &'static str,
    edits: Vec<(&'static str, String)>,
    key: String,
}

fn hostile(class: &'static str, from: &'static str, to: String, key: &str) -> Hostile {
    Hostile {
        class,
        edits: vec![(from, to)],
        key: key.to_string(),
    }
}

const GAP: &str = "gap = \"0.02*x\"";
const TRACTION: &str = "\"-pressure*max(0, ny)";
const PRESSURE: &str = "pressure = 1.2 ";
const VISCOSITY: &str = "viscosity = { kind = \"linear\", shear = 3.0, bulk = 1.5 }";
const ELASTICITY: &str =
    "elasticity = { kind = \"damaged_hooke\", shear_modulus = 1.0, lame_lambda = 1.0 }";
const CONTACT: &str = "contact = { stiffness = 4.0, friction = 0.4 }";
const LOADS: &str = "[loads]";
const OUTPUT: &str = "[output]";

/// Finite data too large for the squared norms of the solvers, at every place they can enter.
fn out_of_scale() -> Vec<Hostile> {
    let mut inputs = Vec::new();
    for magnitude in ["1e160", "1e200", "1e300"] {
        let class = "out of scale";
        // a gap this negative presses with c_ν |g| (a positive one only separates)
        inputs.push(hostile(
            class,
            GAP,
            format!("gap = \"-{magnitude}*(1 + x)\""),
            "loads.gap",
        ));
        for sign in ["", "-"] {
            inputs.push(hostile(
                class,
                PRESSURE,
                format!("pressure = {sign}{magnitude} "),
                "loads.traction",
            ));
            inputs.push(hostile(
                class,
                GAP,
                format!("{GAP}\ntraction_curve = [[0.0, 1.0], [0.1, {sign}{magnitude}]]"),
                "loads.traction",
            ));
            inputs.push(hostile(
                class,
                LOADS,
                format!("{LOADS}\nbody_force = [\"{sign}{magnitude}*t\", \"0\"]"),
                "loads.body_force",
            ));
            inputs.push(hostile(
                class,
                OUTPUT,
                format!(
                    "[[displacement]]\npart = \"x_min\"\nx = \"{sign}{magnitude}*t\"\ny = \"0\"\n\n{OUTPUT}"
                ),
                "displacement[0].x",
            ));
        }
        inputs.push(hostile(
            class,
            VISCOSITY,
            VISCOSITY.replace("shear = 3.0", &format!("shear = {magnitude}")),
            "laws.viscosity.shear",
        ));
        inputs.push(hostile(
            class,
            ELASTICITY,
            ELASTICITY.replace("lame_lambda = 1.0", &format!("lame_lambda = {magnitude}")),
            "laws.elasticity.lame_lambda",
        ));
        inputs.push(hostile(
            class,
            CONTACT,
            CONTACT.replace("stiffness = 4.0", &format!("stiffness = {magnitude}")),
            "laws.contact.stiffness",
        ));
    }
    inputs
}

/// Data defined at the times checked at load (0, T/2, T) but not at one step time between
/// them (t = 0.05 and 0.1, which the steps hit exactly), by a pole or a logarithm of zero (a
/// logarithm of a negative number at t = 0 is refused at load, at the same key).
fn undefined_at_one_step() -> Vec<Hostile> {
    let mut inputs = Vec::new();
    for time in ["0.05", "0.1"] {
        for undefined in [format!("0/(t - {time})"), format!("0*log(t - {time})")] {
            let class = "undefined at one step";
            inputs.push(hostile(
                class,
                GAP,
                format!("gap = \"0.02*x + {undefined}\""),
                "loads.gap",
            ));
            inputs.push(hostile(
                class,
                TRACTION,
                format!("\"-pressure*(1 + {undefined})*max(0, ny)"),
                "loads.traction",
            ));
            inputs.push(hostile(
                class,
                LOADS,
                format!("{LOADS}\nbody_force = [\"0\", \"{undefined}\"]"),
                "loads.body_force",
            ));
            for component in ["x", "y"] {
                let other = if component == "x" { "y" } else { "x" };
                inputs.push(hostile(
                    class,
                    OUTPUT,
                    format!(
                        "[[displacement]]\npart = \"x_min\"\n{component} = \"0.001*t + {undefined}\"\n{other} = \"0\"\n\n{OUTPUT}"
                    ),
                    &format!("displacement[0].{component}"),
                ));
            }
        }
    }
    inputs
}

/// Initial data outside the admissible set: β0 ∉ [0, 1], u0 ≠ u_D(x, 0) on Γ1.
fn initial_data() -> Vec<Hostile> {
    let mut inputs = Vec::new();
    for beta in ["1.5", "-0.2", "x - 0.5", "1 + 0/(x - 1)"] {
        inputs.push(hostile(
            "initial data",
            LOADS,
            format!("{LOADS}\ninitial_damage = \"{beta}\""),
            "loads.initial_damage",
        ));
    }
    for u0 in ["[\"0.1\", \"0\"]", "[\"0\", \"y\"]"] {
        inputs.push(hostile(
            "initial data",
            LOADS,
            format!("{LOADS}\ninitial_displacement = {u0}"),
            "loads.initial_displacement",
        ));
    }
    inputs
}

/// Constraints on Γ1 that leave a rigid motion free: a roller in either direction on the
/// only Γ1 side.
fn rigid_motion() -> Vec<Hostile> {
    ["x", "y"]
        .into_iter()
        .map(|component| {
            hostile(
                "rigid motion",
                OUTPUT,
                format!("[[displacement]]\npart = \"x_min\"\n{component} = \"0\"\n\n{OUTPUT}"),
                "displacement",
            )
        })
        .collect()
}

/// Two parts that prescribe different values on the corner node they share (the top side
/// made a second Γ1 part).
fn conflicting_parts() -> Vec<Hostile> {
    ["0.05*t", "-0.01", "0.03*t*t"]
        .into_iter()
        .map(|value| {
            hostile(
                "conflicting parts",
                OUTPUT,
                format!(
                    "[[displacement]]\npart = \"x_min\"\nx = \"0\"\ny = \"0\"\n\n\
                     [[displacement]]\npart = \"y_max\"\nx = \"{value}\"\n\n{OUTPUT}"
                ),
                "displacement",
            )
        })
        .collect()
}

/// Elastic moduli that pass the sampled check at load but leave their range between two
/// samples, where the run's damage takes them.
fn law_out_of_range() -> Vec<Hostile> {
    [("0.704", "0.705"), ("0.304", "0.305")]
        .into_iter()
        .map(|(initial, pole)| Hostile {
            class: "law out of range during the run",
            edits: vec![
                (
                    ELASTICITY,
                    format!(
                        "elasticity = {{ kind = \"moduli\", shear_modulus = \"1 + 0.002/(beta - {pole})\", lame_lambda = \"1\" }}"
                    ),
                ),
                (LOADS, format!("{LOADS}\ninitial_damage = \"{initial}\"")),
            ],
            key: "laws.elasticity.shear_modulus".into(),
        })
        .collect()
}

fn catalogue() -> Vec<Hostile> {
    [
        out_of_scale(),
        undefined_at_one_step(),
        initial_data(),
        rigid_motion(),
        conflicting_parts(),
        law_out_of_range(),
    ]
    .into_iter()
    .flatten()
    .collect()
}

/// Runs one generated input; returns what is wrong with the outcome, if anything.
fn check(dir: &Path, index: usize, input: &Hostile, base: &str) -> Option<String> {
    let mut text = base.to_string();
    for (from, to) in &input.edits {
        assert!(text.contains(from), "{}: `{from}`", input.class);
        text = text.replacen(from, to, 1);
    }
    let problem = dir.join(format!("hostile-{index}.toml"));
    std::fs::write(&problem, &text).unwrap();
    let mut command = Command::new(env!("CARGO_BIN_EXE_simulate"));
    command
        .arg(&problem)
        .arg("--out")
        .arg(dir.join(format!("out-{index}")))
        .arg("--quiet");
    let output = output_within_a_minute(command);
    let expected = format!("problem file `{}`, key `{}`", problem.display(), input.key);
    let fault = refusal_fault(&output, 1, &expected)?;
    let edits: Vec<String> = input
        .edits
        .iter()
        .map(|(from, to)| format!("{from} → {to}"))
        .collect();
    Some(format!("[{}] {}: {fault}", input.class, edits.join("; ")))
}

#[test]
fn every_generated_hostile_problem_is_refused_naming_its_file_and_key() {
    let dir = scratch("hostile-catalogue");
    let base = small_example();
    let inputs = catalogue();
    assert!(inputs.len() >= 50, "{} inputs", inputs.len());
    let failures: Vec<String> = inputs
        .iter()
        .enumerate()
        .filter_map(|(index, input)| check(&dir, index, input, &base))
        .collect();
    assert!(
        failures.is_empty(),
        "{} of {} generated inputs:\n{}",
        failures.len(),
        inputs.len(),
        failures.join("\n")
    );
}
