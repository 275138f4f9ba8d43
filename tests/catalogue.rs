//! The hostile-input catalogue of `verify`, generated: edits of the zones2d case file over a
//! range of keys and magnitudes — laws and data out of the scale of double precision, a domain
//! with no Γ1, manufactured fields outside their admissible sets, a law that leaves its range
//! during the runs. Every generated case must be refused with exit status 2 (no panic, no
//! signal, no verdict), within a minute, with a message that names the case file and the key.

use crate::process::{output_within_a_minute, refusal_fault};
use std::path::Path;
use std::process::Command;

const ZONES2D: &str = include_str!("../verification/zones2d.toml");

const VISCOSITY: &str = "viscosity = { kind = \"linear\", shear = 1.0, bulk = 0.5 }";
const ELASTICITY: &str =
    "elasticity = { kind = \"damaged_hooke\", shear_modulus = 1.0, lame_lambda = 1.0 }";
const CONTACT: &str = "contact = { stiffness = 10.0, friction = 0.4 }";
const GAP: &str = "gap = \"0.01\"";
const SIDES: &str =
    "sides = { x_min = \"clamped\", x_max = \"traction\", y_min = \"contact\", y_max = \"traction\" }";

/// One generated case: the edit of zones2d and the key its error must name.
struct Hostile {
    class: &'static str,
    from: &'static str,
    to: String,
    key: &'static str,
}

fn catalogue() -> Vec<Hostile> {
    let mut inputs = Vec::new();
    for magnitude in ["1e160", "1e200", "1e300"] {
        let class = "out of scale";
        for (from, parameter, key) in [
            (VISCOSITY, "shear = 1.0", "laws.viscosity.shear"),
            (VISCOSITY, "bulk = 0.5", "laws.viscosity.bulk"),
            (
                ELASTICITY,
                "shear_modulus = 1.0",
                "laws.elasticity.shear_modulus",
            ),
            (CONTACT, "stiffness = 10.0", "laws.contact.stiffness"),
        ] {
            let name = parameter.split(" = ").next().unwrap();
            inputs.push(Hostile {
                class,
                from,
                to: from.replace(parameter, &format!("{name} = {magnitude}")),
                key,
            });
        }
        for sign in ["", "-"] {
            inputs.push(Hostile {
                class,
                from: GAP,
                to: format!("gap = \"{sign}{magnitude}\""),
                key: "exact.gap",
            });
        }
    }
    for sides in [
        "sides = { x_max = \"traction\", y_min = \"contact\", y_max = \"traction\" }",
        "sides = { x_min = \"traction\", x_max = \"traction\", y_min = \"contact\", y_max = \"traction\" }",
    ] {
        inputs.push(Hostile {
            class: "no Γ1",
            from: SIDES,
            to: sides.to_string(),
            key: "domain.sides",
        });
    }
    // a jump plane must be a fixed plane: affine in the coordinates, constant in time
    for plane in ["x*x - 0.5", "x - t", "0*x + 1"] {
        inputs.push(Hostile {
            class: "jump plane that is no plane",
            from: GAP,
            to: format!("{GAP}\njump_planes = [\"{plane}\"]"),
            key: "exact.jump_planes[0]",
        });
    }
    // μ < 0 only in (pole − 0.002, pole): between the samples β = k/100 of the check at load;
    // the manufactured β (from 1 down to 0.35) crosses the band during the runs
    for pole in ["0.705", "0.805"] {
        inputs.push(Hostile {
            class: "law out of range during the runs",
            from: ELASTICITY,
            to: format!(
                "elasticity = {{ kind = \"moduli\", shear_modulus = \"1 + 0.002/(beta - {pole})\", lame_lambda = \"1\" }}"
            ),
            key: "laws.elasticity.shear_modulus",
        });
    }
    inputs
}

/// Runs one generated case; returns what is wrong with the outcome, if anything.
fn check(dir: &Path, index: usize, input: &Hostile) -> Option<String> {
    assert!(
        ZONES2D.contains(input.from),
        "{}: `{}`",
        input.class,
        input.from
    );
    let case = dir.join(format!("hostile-{index}.toml"));
    std::fs::write(&case, ZONES2D.replacen(input.from, &input.to, 1)).unwrap();
    let mut command = Command::new(env!("CARGO_BIN_EXE_verify"));
    command
        .arg("--case")
        .arg(&case)
        .args(["--levels", "2", "--threads", "1", "--out"])
        .arg(dir.join(format!("out-{index}")))
        .env("CI", "1");
    let output = output_within_a_minute(command);
    let expected = format!("case `{}`, key `{}`", case.display(), input.key);
    let fault = refusal_fault(&output, 2, &expected)?;
    Some(format!(
        "[{}] {} → {}: {fault}",
        input.class, input.from, input.to
    ))
}

#[test]
fn every_generated_hostile_case_is_refused_naming_its_file_and_key() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("verify-hostile-catalogue");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let inputs = catalogue();
    assert!(inputs.len() >= 20, "{} inputs", inputs.len());
    let failures: Vec<String> = inputs
        .iter()
        .enumerate()
        .filter_map(|(index, input)| check(&dir, index, input))
        .collect();
    assert!(
        failures.is_empty(),
        "{} of {} generated cases:\n{}",
        failures.len(),
        inputs.len(),
        failures.join("\n")
    );
}
