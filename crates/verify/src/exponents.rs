//! The exponents p of the regularity profiles (d)₊^p a case file declares in `[regularity]`:
//! which values keep the manufactured data square-integrable. Read by the case parser and by
//! the regularity sweeps ([`crate::regularity`]).

use std::collections::BTreeMap;

use crate::InputError;
use contact_input::FileKind;

/// The data are square-integrable for p above this: f0 = −Div σ ∝ d^{p−2} ∈ L² iff p > 3/2.
pub const DATA_LIMIT: f64 = 1.5;

/// Checks the `exponents` of `[regularity]` of a case file: every one names a constant of
/// `[constants]` whose value keeps the data square-integrable ([`DATA_LIMIT`]).
pub fn check_exponents(
    origin: &str,
    exponents: &[String],
    constants: &BTreeMap<String, f64>,
) -> Result<(), InputError> {
    if exponents.is_empty() {
        return Err(FileKind::Case.error(
            origin,
            "regularity.exponents",
            "names no constant (list the exponents a regularity sweep may vary, e.g. [\"p\"])",
        ));
    }
    for name in exponents {
        let Some(&value) = constants.get(name) else {
            return Err(FileKind::Case.error(
                origin,
                "regularity.exponents",
                format!("`{name}` is not a constant of [constants]"),
            ));
        };
        check_value(origin, name, value)?;
    }
    Ok(())
}

/// The exponent `name` may take `value`: the data stay square-integrable.
pub fn check_value(origin: &str, name: &str, value: f64) -> Result<(), InputError> {
    if value > DATA_LIMIT {
        Ok(())
    } else {
        Err(FileKind::Case.error(
            origin,
            &format!("constants.{name}"),
            format!(
                "{name} = {value}: the body force f0 = −Div σ of a profile (d)₊^{name} behaves like d^({name}−2), which is not square-integrable for {name} ≤ 3/2; choose {name} > 3/2"
            ),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exponents_that_leave_the_data_outside_l2_are_refused_naming_the_key() {
        let constants = BTreeMap::from([("p".to_string(), 1.5), ("q".to_string(), 3.0)]);
        let regularity =
            |names: &[&str]| -> Vec<String> { names.iter().map(|n| n.to_string()).collect() };
        let error = check_exponents("c.toml", &regularity(&["q", "p"]), &constants)
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("constants.p") && error.contains("not square-integrable"),
            "{error}"
        );
        let error = check_exponents("c.toml", &regularity(&["r"]), &constants)
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("regularity.exponents") && error.contains("`r`"),
            "{error}"
        );
        assert!(check_exponents("c.toml", &regularity(&["q"]), &constants).is_ok());
    }
}
