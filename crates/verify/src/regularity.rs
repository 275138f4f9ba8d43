//! Regularity studies: the observed h-rate of a manufactured case against the smoothness of its
//! solution (`verify --case F --regularity p=FROM:TO:STEP`).
//!
//! Theorem 5.2 assumes (5.6)–(5.8): u₀, v(t) ∈ H^{l+1}(Ω)^d, v_τ(t) ∈ H^{l+1}(Γ3)^d and
//! β(t) ∈ H^{l+1}(Ω). The cases of the regularity family (`verification/regularity/`) write
//! their fields with profiles `pospow(x - x_front, p)` = (d)₊^p across a front, a plane that
//! crosses the body and Γ3 (a stick–slip front, the edge of the contact zone), and declare the
//! exponents in `[regularity]`. What an exponent p of a displacement profile implies is the
//! same in 2D and 3D, since the profile depends on the distance to a plane only
//! ([`Profile`]):
//!
//! - (d)₊^p ∈ H^s for s < p + 1/2 (in Ω and on Γ3): the Sobolev index of the field;
//! - the body force f0 = −Div σ holds second derivatives, ∝ d^{p−2}: square-integrable iff
//!   p > 3/2. The tractions f2, f3 and the stress on Γ3 (∝ d^{p−1}) are in L²(Γ) for p > 1/2
//!   and the damage source (∝ |ε(u)|², d^{2p−2}) is bounded for p ≥ 1, so p > 3/2 is the
//!   condition on the data; a sweep that reaches p ≤ 3/2 is refused before anything runs;
//! - (5.7) holds at degree l iff p + 1/2 > l + 1, i.e. p > l + 1/2;
//! - the interpolation error of such a field in the energy norm ‖ε(·)‖ is of order
//!   h^{min(l, p − 1/2)}: the elements along the front (about 1/h^{d−1} of them) carry an
//!   error h^{p−1} over a volume h^d each. Where the front is a mesh plane and p is an integer,
//!   the field is a polynomial on each side and this loss disappears.
//!
//! The sweep runs the case's h-study (`[studies.order<l>] h`) once for each value, each in the
//! folder `<out>/<name>=<value>/` with the reports of an ordinary study, and writes
//! `regularity.csv`, `regularity.json` and `regularity-l<l>.svg` into `<out>`: the least-squares
//! rate of every error component with its standard error and asymptotic-range flag, beside
//! the theorem's exponent and the interpolation rate ([`report`]).

pub mod report;

use crate::case::CaseFile;
use crate::exponents;
use crate::study::expected_h_rate;
use crate::InputError;
use contact_input::FileKind;

/// Most values of one sweep (each is a whole h-study).
pub const MAX_VALUES: usize = 32;

/// What the exponent p of a displacement profile (d)₊^p implies (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Profile {
    /// The exponent p.
    pub exponent: f64,
}

impl Profile {
    /// s such that the field is in H^{s−ε} for every ε > 0 and not in H^s: p + 1/2.
    pub fn sobolev_index(self) -> f64 {
        self.exponent + 0.5
    }

    /// True when (5.7) holds at degree `degree`: v ∈ H^{l+1}, i.e. p > l + 1/2.
    pub fn inside_assumptions(self, degree: usize) -> bool {
        self.sobolev_index() > degree as f64 + 1.0
    }

    /// The rate of the interpolation error in the energy norm: min(l, p − 1/2).
    pub fn interpolation_rate(self, degree: usize) -> f64 {
        (degree as f64).min(self.exponent - 0.5)
    }

    /// The exponent of Theorem 5.2, min(l, (l+1)/2), where the assumptions hold (else none).
    pub fn theorem_rate(self, degree: usize) -> Option<f64> {
        self.inside_assumptions(degree)
            .then(|| expected_h_rate(degree))
    }
}

/// A sweep of one constant over a list of values.
#[derive(Debug, Clone, PartialEq)]
pub struct Sweep {
    /// The constant swept.
    pub name: String,
    /// Its values, increasing.
    pub values: Vec<f64>,
    /// The smallest value of the case's other exponents (∞ without any; set by
    /// [`check_sweep`]): the field is only as smooth as its roughest profile.
    pub others: f64,
}

impl Sweep {
    /// The profile that limits the smoothness at the swept value `value`: the smallest of it
    /// and the other exponents.
    pub fn profile(&self, value: f64) -> Profile {
        Profile {
            exponent: value.min(self.others),
        }
    }
}

/// Parses `NAME=FROM:TO:STEP` (FROM, FROM + STEP, … up to TO, both included) or
/// `NAME=V1,V2,…`.
pub fn parse_sweep(text: &str) -> Result<Sweep, InputError> {
    let refuse = |reason: String| {
        InputError::InvalidInput(format!(
            "--regularity `{text}`: {reason} (write NAME=FROM:TO:STEP, e.g. p=2:4:0.5, or NAME=V1,V2,…)"
        ))
    };
    let (name, range) = text
        .split_once('=')
        .ok_or_else(|| refuse("no `=`".to_string()))?;
    let name = name.trim();
    if name.is_empty() {
        return Err(refuse("no constant named before `=`".to_string()));
    }
    let number = |word: &str| -> Result<f64, InputError> {
        match word.trim().parse::<f64>() {
            Ok(value) if value.is_finite() => Ok(value),
            _ => Err(refuse(format!("`{}` is not a finite number", word.trim()))),
        }
    };
    let values = if range.contains(':') {
        let parts: Vec<&str> = range.split(':').collect();
        let [from, to, step] = parts[..] else {
            return Err(refuse(format!(
                "a range has three parts FROM:TO:STEP, found {}",
                parts.len()
            )));
        };
        let (from, to, step) = (number(from)?, number(to)?, number(step)?);
        if step <= 0.0 {
            return Err(refuse(format!("the step {step} is not positive")));
        }
        if to < from {
            return Err(refuse(format!("TO = {to} is below FROM = {from}")));
        }
        // the count, robust to the rounding of (to − from)/step
        let intervals = ((to - from) / step + 1e-9).floor();
        if intervals + 1.0 > MAX_VALUES as f64 {
            return Err(refuse(format!(
                "{} values, at most {MAX_VALUES} (each is a whole h-study)",
                intervals + 1.0
            )));
        }
        (0..=intervals as usize)
            .map(|i| round_decimal(from + step * i as f64))
            .collect()
    } else {
        let values: Vec<f64> = range.split(',').map(number).collect::<Result<_, _>>()?;
        if values.len() > MAX_VALUES {
            return Err(refuse(format!(
                "{} values, at most {MAX_VALUES} (each is a whole h-study)",
                values.len()
            )));
        }
        if values.windows(2).any(|pair| pair[1] <= pair[0]) {
            return Err(refuse("the values must increase".to_string()));
        }
        values
    };
    Ok(Sweep {
        name: name.to_string(),
        values,
        others: f64::INFINITY,
    })
}

/// `value` rounded to 12 significant decimals: `2 + 3 × 0.1` is 2.3, not 2.3000000000000003.
fn round_decimal(value: f64) -> f64 {
    let text = format!("{value:.12e}");
    text.parse().unwrap_or(value)
}

/// Checks a sweep against the case file before anything runs: the constant is an exponent of
/// `[regularity]`, and every value keeps the data square-integrable; sets [`Sweep::others`].
pub fn check_sweep(sweep: &mut Sweep, file: &CaseFile, origin: &str) -> Result<(), InputError> {
    let Some(regularity) = &file.regularity else {
        return Err(InputError::InvalidInput(format!(
            "--regularity {}: {origin} has no [regularity] table naming the exponents a sweep may vary",
            sweep.name
        )));
    };
    if !regularity.exponents.contains(&sweep.name) {
        return Err(InputError::InvalidInput(format!(
            "--regularity {}: not an exponent of [regularity] in {origin} (exponents: {})",
            sweep.name,
            regularity.exponents.join(", ")
        )));
    }
    for &value in &sweep.values {
        exponents::check_value(origin, &sweep.name, value).map_err(|error| {
            InputError::InvalidInput(format!("--regularity {}: {error}", sweep.name))
        })?;
    }
    sweep.others = regularity
        .exponents
        .iter()
        .filter(|name| **name != sweep.name)
        .filter_map(|name| file.constants.get(name))
        .fold(f64::INFINITY, |smallest, &value| smallest.min(value));
    Ok(())
}

/// The folder name of one value of a sweep: `p=2.5`.
pub fn value_folder(name: &str, value: f64) -> String {
    format!("{name}={}", contact_input::number::short(value))
}

/// The case text with the constant `name` set to `value` and the case renamed
/// `<name>-<constant><value>`, and its origin `<origin> (<constant> = <value>)`.
pub fn case_with(
    text: &str,
    origin: &str,
    name: &str,
    value: f64,
) -> Result<(String, String), InputError> {
    let parse_error = |message: String| {
        FileKind::Case.error(origin, "constants", format!("cannot set {name}: {message}"))
    };
    let mut table: toml::Table = toml::from_str(text).map_err(|e| parse_error(e.to_string()))?;
    let short = contact_input::number::short(value);
    let constants = table
        .entry("constants")
        .or_insert_with(|| toml::Value::Table(toml::Table::new()));
    let toml::Value::Table(constants) = constants else {
        return Err(parse_error("[constants] is not a table".to_string()));
    };
    constants.insert(name.to_string(), toml::Value::Float(value));
    if let Some(toml::Value::String(case_name)) = table.get_mut("name") {
        *case_name = format!("{case_name}-{name}{short}");
    }
    let text = toml::to_string(&table).map_err(|e| parse_error(e.to_string()))?;
    Ok((text, format!("{origin} ({name} = {short})")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_range_includes_both_ends_and_rounds_to_decimals() {
        let sweep = parse_sweep("p=2:3:0.1").unwrap();
        assert_eq!(sweep.name, "p");
        assert_eq!(sweep.values.len(), 11);
        assert_eq!(sweep.values[3], 2.3);
        assert_eq!(*sweep.values.last().unwrap(), 3.0);
        assert_eq!(
            parse_sweep(" q = 1.75, 2.5 ,4").unwrap(),
            Sweep {
                name: "q".to_string(),
                values: vec![1.75, 2.5, 4.0],
                others: f64::INFINITY,
            }
        );
    }

    #[test]
    fn a_malformed_sweep_is_refused_with_the_reason() {
        for (text, reason) in [
            ("p", "no `=`"),
            ("=1:2:1", "no constant"),
            ("p=1:2", "three parts"),
            ("p=1:2:0", "not positive"),
            ("p=3:2:0.5", "below FROM"),
            ("p=2:x:1", "`x` is not a finite number"),
            ("p=2:1e300:1e-300", "at most 32"),
            ("p=2,nan", "`nan` is not a finite number"),
            ("p=2,2", "must increase"),
        ] {
            let error = parse_sweep(text).unwrap_err().to_string();
            assert!(error.contains(reason), "{text}: {error}");
            assert!(error.contains("--regularity"), "{text}: {error}");
        }
    }

    #[test]
    fn the_profile_rules_follow_the_sobolev_index() {
        let profile = |p| Profile { exponent: p };
        // l = 1: (5.7) needs p > 3/2, as the data do
        assert!(profile(1.6).inside_assumptions(1));
        assert_eq!(profile(1.6).theorem_rate(1), Some(1.0));
        // l = 2: p > 5/2; the interpolation rate is p − 1/2 below that
        assert!(!profile(2.5).inside_assumptions(2));
        assert_eq!(profile(2.5).theorem_rate(2), None);
        assert!(profile(2.75).inside_assumptions(2));
        assert_eq!(profile(2.75).theorem_rate(2), Some(1.5));
        assert_eq!(profile(2.0).interpolation_rate(2), 1.5);
        assert_eq!(profile(4.0).interpolation_rate(2), 2.0);
        // the roughest profile limits: q = 4 swept beside p = 2.5 is outside (5.7) at l = 2
        let sweep = Sweep {
            name: "q".to_string(),
            values: vec![4.0],
            others: 2.5,
        };
        assert!(!sweep.profile(4.0).inside_assumptions(2));
        assert_eq!(sweep.profile(2.0).exponent, 2.0);
    }

    #[test]
    fn the_case_text_gets_the_value_and_a_new_name() {
        let text = "name = \"front\"\n[constants]\np = 4.0\nx = 0.5\n";
        let (changed, origin) = case_with(text, "front.toml", "p", 2.25).unwrap();
        let table: toml::Table = toml::from_str(&changed).unwrap();
        assert_eq!(table["name"].as_str(), Some("front-p2.25"));
        assert_eq!(table["constants"]["p"].as_float(), Some(2.25));
        assert_eq!(table["constants"]["x"].as_float(), Some(0.5));
        assert_eq!(origin, "front.toml (p = 2.25)");
        assert_eq!(value_folder("p", 2.25), "p=2.25");
    }
}
