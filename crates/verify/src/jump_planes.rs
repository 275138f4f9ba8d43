//! `exact.jump_planes` of a case file: the planes across which manufactured boundary data jump
//! (a stick traction strictly inside the friction bound that meets the slip traction at a
//! stick–slip front), each written as an affine function of the coordinates whose zero set is
//! the plane. The solver integrates the facets they cross piecewise
//! ([`contact_damage::scheme::Data::jump_planes`]).

use crate::expr::Expr;
use crate::manufactured::value;
use crate::InputError;
use contact_damage::scheme::JumpPlane;
use contact_input::file::parse_expr;
use contact_input::FileKind;
use std::collections::BTreeMap;

/// Points at which an expression must agree with the plane read from it (off the axes, of
/// several magnitudes, so that a term in x², x y or t shows).
const PROBES: [[f64; 3]; 4] = [
    [0.37, -1.3, 2.1],
    [-2.9, 0.61, -0.45],
    [5.3, 3.7, -4.1],
    [-0.13, -7.9, 0.88],
];

/// The planes of `sources` (`exact.jump_planes`): each expression is read as normal · x −
/// offset from its values at the origin and the unit points at t = 0, and must be that affine
/// function at other points and times (the plane does not move). Refused, naming the key: an
/// expression that does not parse, one that is not affine in x or depends on t, one with a
/// zero normal (no plane).
pub fn jump_planes<const D: usize>(
    origin: &str,
    sources: &[String],
    constants: &BTreeMap<String, f64>,
    final_time: f64,
) -> Result<Vec<JumpPlane<D>>, InputError> {
    sources
        .iter()
        .enumerate()
        .map(|(i, source)| {
            let key = format!("exact.jump_planes[{i}]");
            let expr = parse_expr(
                FileKind::Case,
                origin,
                &key,
                source,
                &crate::case::FIELD_VARIABLES,
                constants,
            )?;
            plane(origin, &key, source, &expr, final_time)
        })
        .collect()
}

fn plane<const D: usize>(
    origin: &str,
    key: &str,
    source: &str,
    expr: &Expr,
    final_time: f64,
) -> Result<JumpPlane<D>, InputError> {
    let error = |message: String| FileKind::Case.error(origin, key, message);
    let at_origin = value(expr, &[0.0; D], 0.0);
    let normal: [f64; D] = std::array::from_fn(|k| {
        let unit: [f64; D] = std::array::from_fn(|i| f64::from(u8::from(i == k)));
        value(expr, &unit, 0.0) - at_origin
    });
    let plane = JumpPlane {
        normal,
        offset: -at_origin,
    };
    let scale = normal.iter().map(|n| n.abs()).fold(0.0, f64::max);
    if !(scale.is_finite() && at_origin.is_finite()) {
        return Err(error(format!(
            "`{source}` is not finite at the origin or a unit point at t = 0"
        )));
    }
    if scale == 0.0 {
        return Err(error(format!(
            "`{source}` does not change with x: its zero set is no plane (write the plane as an affine function of the coordinates, e.g. `x - 0.5`)"
        )));
    }
    for probe in &PROBES {
        let x: [f64; D] = std::array::from_fn(|i| probe[i]);
        for t in [0.0, final_time] {
            let got = value(expr, &x, t);
            let affine = plane.level(&x);
            let size = scale * x.iter().map(|c| c.abs()).sum::<f64>() + plane.offset.abs();
            // a NaN value does not agree
            let agrees = (got - affine).abs() <= 1e-12 * size.max(1.0);
            if !agrees {
                return Err(error(format!(
                    "`{source}` is not an affine function of the coordinates constant in time: at x = {x:?}, t = {t} it is {got}, the plane through its values at the origin and the unit points gives {affine} (a jump plane is written as normal · x − offset)"
                )));
            }
        }
    }
    Ok(plane)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn planes<const D: usize>(sources: &[&str]) -> Result<Vec<JumpPlane<D>>, InputError> {
        let constants = BTreeMap::from([("c".to_string(), 0.25)]);
        let sources: Vec<String> = sources.iter().map(|s| s.to_string()).collect();
        jump_planes::<D>("case.toml", &sources, &constants, 1.0)
    }

    #[test]
    fn jump_plane_is_read_as_normal_and_offset() {
        let read = planes::<2>(&["x - c", "2*y + x - 1"]).unwrap();
        assert_eq!(read[0].normal, [1.0, 0.0]);
        assert_eq!(read[0].offset, 0.25);
        assert_eq!(read[1].normal, [1.0, 2.0]);
        assert_eq!(read[1].offset, 1.0);
        let read = planes::<3>(&["z - 0.5*x"]).unwrap();
        assert_eq!(read[0].normal, [-0.5, 0.0, 1.0]);
    }

    #[test]
    fn jump_plane_rejects_what_is_not_a_fixed_plane() {
        for (source, words) in [
            ("x*x - c", "not an affine function"),
            ("x - t", "constant in time"),
            ("1 + 0*x", "no plane"),
            ("x -", ""),
        ] {
            let err = planes::<2>(&["x", source]).unwrap_err().to_string();
            assert!(err.contains("exact.jump_planes[1]"), "{source}: {err}");
            assert!(err.contains("case.toml"), "{source}: {err}");
            assert!(err.contains(words), "{source}: {err}");
        }
    }
}
