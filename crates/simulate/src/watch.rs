//! The first non-finite value of a load expression, with its key, point and time.
//!
//! The problem file's expressions are checked at load at the vertices and at t = 0, T/2 and T,
//! but an expression may still be undefined at another time or quadrature point (`1/(t − 0.2)`).
//! The solver then stops with "non-finite value" and the degree of freedom concerned; it knows
//! nothing of the problem file. Every load closure of a problem is wrapped so that the first
//! non-finite value it returns is recorded here, and [`LoadWatch::explain`] turns the solver's
//! error into one that names the file, the key, the point and the time. A law the solver finds
//! outside its admissible range during the run is named by its key in the file the same way.

use contact_input::number::short;
use contact_input::{FileKind, InputError};
use std::sync::{Arc, Mutex};

/// Shared record of the first non-finite load value.
#[derive(Clone, Default)]
pub struct LoadWatch {
    first: Arc<Mutex<Option<(String, String)>>>,
}

impl LoadWatch {
    /// Records `values` of the expression under `key` if one of them is not finite and nothing
    /// was recorded before; returns `values` unchanged (the solver still detects them).
    pub fn check<const N: usize>(
        &self,
        key: &str,
        symbol: &str,
        values: [f64; N],
        point: &[f64],
        time: f64,
    ) -> [f64; N] {
        if values.iter().any(|value| !value.is_finite()) {
            let mut first = self
                .first
                .lock()
                .unwrap_or_else(|poison| poison.into_inner());
            if first.is_none() {
                let shown = if N == 1 {
                    format!("{}", values[0])
                } else {
                    format!("{values:?}")
                };
                *first = Some((
                    key.to_string(),
                    format!(
                        "{symbol} = {shown} is not finite at x = {point:?}, t = {}",
                        short(time)
                    ),
                ));
            }
        }
        values
    }

    /// The solver's `error`, replaced by the recorded non-finite load value if there is one;
    /// otherwise located at its key in the file if the solver named one
    /// ([`InputError::located`]).
    pub fn explain(&self, origin: &str, error: InputError) -> InputError {
        let first = self
            .first
            .lock()
            .unwrap_or_else(|poison| poison.into_inner());
        match first.as_ref() {
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
}
