//! The first non-finite or out-of-scale value of a load expression, with its key, point and
//! time.
//!
//! The problem file's expressions are checked at load at the vertices and at t = 0, T/2 and T,
//! but an expression may still be undefined at another time or quadrature point (`1/(t − 0.2)`),
//! or finite but too large for double precision (a gap of −1e200): the solver then stops with
//! "non-finite value" or "out of scale" and the degree of freedom concerned; it knows nothing
//! of the problem file. Every load closure of a problem is wrapped so that the first such value
//! it returns is recorded here, and [`LoadWatch::explain`] turns the solver's error into one that
//! names the file, the key, the point and the time. A law the solver finds outside its
//! admissible range during the run is named by its key in the file the same way.

use contact_damage::algebra::linalg::{within_scale, MAGNITUDE_LIMIT};
use contact_input::number::short;
use contact_input::{FileKind, InputError};
use std::sync::{Arc, Mutex};

/// The first recorded value of each kind: (key, message).
#[derive(Default)]
struct Records {
    non_finite: Option<(String, String)>,
    out_of_scale: Option<(String, String)>,
}

/// Shared record of the first non-finite and of the first out-of-scale load value.
#[derive(Clone, Default)]
pub struct LoadWatch {
    first: Arc<Mutex<Records>>,
}

impl LoadWatch {
    /// Records `values` of the expression under `key` if one of them is not finite, or beyond
    /// [`MAGNITUDE_LIMIT`] in magnitude, and nothing of that kind was recorded before; returns
    /// `values` unchanged (the solver still detects them).
    pub fn check<const N: usize>(
        &self,
        key: &str,
        symbol: &str,
        values: [f64; N],
        point: &[f64],
        time: f64,
    ) -> [f64; N] {
        // one comparison per value on the common path (a NaN fails it too)
        if values.iter().any(|&value| !within_scale(value)) {
            let finite = values.iter().all(|value| value.is_finite());
            let mut records = self
                .first
                .lock()
                .unwrap_or_else(|poison| poison.into_inner());
            let record = if finite {
                &mut records.out_of_scale
            } else {
                &mut records.non_finite
            };
            if record.is_none() {
                let shown = match (N, finite) {
                    (1, false) => format!("{}", values[0]),
                    (_, false) => format!("{values:?}"),
                    (1, true) => format!("{:e}", values[0]),
                    (_, true) => {
                        let each: Vec<String> = values.iter().map(|v| format!("{v:e}")).collect();
                        format!("[{}]", each.join(", "))
                    }
                };
                let (before, after) = if finite {
                    ("", format!(" is beyond {MAGNITUDE_LIMIT:e} in magnitude"))
                } else {
                    (" is not finite", String::new())
                };
                *record = Some((
                    key.to_string(),
                    format!(
                        "{symbol} = {shown}{before} at x = {point:?}, t = {}{after}",
                        short(time)
                    ),
                ));
            }
        }
        values
    }

    /// The solver's `error`, replaced by the recorded non-finite load value if there is one
    /// (or, for an out-of-scale error of the solver, by the recorded out-of-scale value);
    /// otherwise located at its key in the file if the solver named one
    /// ([`InputError::located`]).
    pub fn explain(&self, origin: &str, error: InputError) -> InputError {
        let records = self
            .first
            .lock()
            .unwrap_or_else(|poison| poison.into_inner());
        let out_of_scale = matches!(
            error,
            InputError::Solver(contact_damage::Error::StepData {
                out_of_scale: true,
                ..
            })
        );
        let record = match (&records.non_finite, &records.out_of_scale) {
            (Some(record), _) => Some(record),
            (None, Some(record)) if out_of_scale => Some(record),
            _ => None,
        };
        match record {
            Some((key, message)) => FileKind::Problem.error(
                origin,
                key,
                format!("{message} (the solver stopped with: {error})"),
            ),
            None => error.located(FileKind::Problem, origin),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn explain_names_the_key_of_the_first_non_finite_value() {
        let watch = LoadWatch::default();
        assert_eq!(
            watch.check("loads.gap", "g", [1.0], &[0.5, 0.0], 0.1),
            [1.0]
        );
        let nan = watch.check("loads.gap", "g", [f64::NAN], &[0.5, 0.0], 0.2);
        assert!(nan[0].is_nan());
        watch.check(
            "loads.traction",
            "f2",
            [f64::INFINITY, 0.0],
            &[1.0, 1.0],
            0.3,
        );
        let solver = InputError::InvalidInput("non-finite value at dof 3".into());
        let message = watch.explain("p.toml", solver).to_string();
        assert!(message.contains("p.toml"), "{message}");
        assert!(message.contains("loads.gap"), "{message}");
        assert!(message.contains("t = 0.2"), "{message}");
        assert!(!message.contains("loads.traction"), "{message}");
    }

    #[test]
    fn an_out_of_scale_value_names_its_key_only_when_the_solver_finds_the_data_out_of_scale() {
        let watch = LoadWatch::default();
        // a huge positive gap is harmless (never in contact): recorded, but not blamed for
        // another failure
        watch.check("loads.gap", "g", [1e200], &[0.5, 0.0], 0.1);
        let other = InputError::InvalidInput("a friction solve stagnated".into());
        let message = watch.explain("p.toml", other).to_string();
        assert!(!message.contains("loads.gap"), "{message}");
        let solver = InputError::Solver(contact_damage::Error::StepData {
            quantity: contact_damage::error::StepDatum::Contact,
            out_of_scale: true,
            message: "out of scale: the normal pressure at contact node 1 is 4e200".into(),
        });
        let message = watch.explain("p.toml", solver).to_string();
        assert!(
            message.starts_with(
                "problem file `p.toml`, key `loads.gap`: g = 1e200 at x = [0.5, 0.0], t = 0.1 is beyond 1e150 in magnitude"
            ),
            "{message}"
        );
    }
}
