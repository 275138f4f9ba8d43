//! Is a manufactured field smooth and resolved, or does it hide a pole?
//!
//! Theorem 5.2 of Han, Shillor & Sofonea (2001) bounds the error of a *regular* solution; a
//! manufactured field with a singularity inside the domain (`0.1*x/(y - 0.3)`) is not one, and the
//! study would report a FAIL verdict with errors of 10³ where the fault lies in the case file. A
//! pole is rarely hit exactly by sample points, so checking the values for finiteness is not
//! enough. Instead the fundamental theorem of calculus is checked on every segment `[a, b]` of
//! the samples (the edges of a lattice of a box domain, or the edges of a mesh domain refined
//! once) at several times: Simpson's rule applied to the directional derivative,
//! `S = |b − a|/6 (g(a) + 4 g(m) + g(b))` with `g = ∇f · e`, `e = (b − a)/|b − a|` and `m` the
//! midpoint, must reproduce `f(b) − f(a)`:
//!
//! ```text
//!     |S − (f(b) − f(a))| ≤ TOLERANCE · (|f(b) − f(a)| + |b − a| max(|g(a)|, |g(m)|, |g(b)|))
//!                          + FLOOR + RELATIVE_FLOOR · max_samples |f|.
//! ```
//!
//! For a smooth field the left side is `|b − a|⁵ max|f⁽⁵⁾| / 2880`, far below the right side on
//! the lattices used here unless the field oscillates on the scale of the lattice spacing (then
//! the finest meshes of the studies would not resolve it either). Across a pole the derivative
//! keeps its sign while the values jump from −∞ to +∞, or the derivative at `m` is huge against
//! the secant: the relative mismatch is of order one. A field that is not finite at a sample
//! point is refused as well. A weak (integrable) singularity such as `log(abs(y - 0.7))` can pass:
//! the check guards against poles, not against every field outside the regularity of the theorem.

use crate::manufactured::value_gradient;
use contact_input::expr::Expr;
use contact_input::number::short;

/// Relative mismatch tolerated between Simpson's rule for the derivative and the difference of
/// the values (see the module documentation).
pub const TOLERANCE: f64 = 0.1;

/// Absolute floor of the test (round-off of fields of size one).
const FLOOR: f64 = 1e-9;

/// Mismatches below this fraction of the field's largest sampled value are not judged: a
/// piecewise-smooth field such as `max(0, x − c)^4` has Simpson errors of order one relative to
/// its tiny values on the segments where it just starts, while a pole makes mismatches of the
/// order of the field's values near it.
const RELATIVE_FLOOR: f64 = 1e-3;

/// The edges of the lattice of the box `[lower, upper]` with `per_axis` points per axis, as
/// segments `(a, b)` along the coordinate directions.
pub fn lattice_segments<const D: usize>(
    lower: [f64; D],
    upper: [f64; D],
    per_axis: usize,
) -> Vec<([f64; D], [f64; D])> {
    let spacing: [f64; D] = std::array::from_fn(|i| (upper[i] - lower[i]) / (per_axis - 1) as f64);
    let total = per_axis.pow(D as u32);
    let mut segments = Vec::with_capacity(D * total);
    for index in 0..total {
        let mut rest = index;
        let lattice: [usize; D] = std::array::from_fn(|_| {
            let i = rest % per_axis;
            rest /= per_axis;
            i
        });
        let a: [f64; D] = std::array::from_fn(|i| lower[i] + spacing[i] * lattice[i] as f64);
        for axis in (0..D).filter(|&axis| lattice[axis] + 1 < per_axis) {
            let mut b = a;
            b[axis] += spacing[axis];
            segments.push((a, b));
        }
    }
    segments
}

/// Checks the expression `field` on every segment `(a, b)` of `segments` at `times` (see the
/// module documentation: Simpson's rule for the derivative along the segment against the
/// difference of the values); returns a message naming the first segment that fails.
pub fn check_resolved<const D: usize>(
    field: &Expr,
    segments: &[([f64; D], [f64; D])],
    times: &[f64],
) -> Result<(), String> {
    for &t in times {
        let magnitude = segments
            .iter()
            .map(|(a, _)| crate::manufactured::value(field, a, t).abs())
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max);
        let floor = FLOOR + RELATIVE_FLOOR * magnitude;
        for (a, b) in segments {
            let direction: [f64; D] = std::array::from_fn(|i| b[i] - a[i]);
            let length = direction.iter().map(|d| d * d).sum::<f64>().sqrt();
            let m: [f64; D] = std::array::from_fn(|i| 0.5 * (a[i] + b[i]));
            let along = |gradient: nalgebra::SVector<f64, D>| {
                (0..D).map(|i| gradient[i] * direction[i]).sum::<f64>() / length
            };
            let (fa, ga) = value_gradient(field, a, t);
            let (fb, gb) = value_gradient(field, b, t);
            let (_, gm) = value_gradient(field, &m, t);
            let (ga, gm, gb) = (along(ga), along(gm), along(gb));
            let at = |x: &[f64; D]| format!("x = {x:?}, t = {}", short(t));
            if let Some(bad) = [fa, fb, ga, gm, gb].iter().find(|v| !v.is_finite()) {
                return Err(format!(
                    "not finite near {} (value or derivative {bad})",
                    at(&m)
                ));
            }
            let simpson = length / 6.0 * (ga + 4.0 * gm + gb);
            let difference = fb - fa;
            let scale = difference.abs() + length * ga.abs().max(gm.abs()).max(gb.abs());
            if (simpson - difference).abs() > TOLERANCE * scale + floor {
                return Err(format!(
                    "singular or not resolved between {} and {}: the values differ by {} but the derivative integrates to {} (a pole inside the domain, or an oscillation on the scale {} of the samples)",
                    at(a),
                    at(b),
                    short(difference),
                    short(simpson),
                    short(length),
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    fn expr(text: &str) -> Expr {
        Expr::parse(text, &["x", "y", "z", "t"], &BTreeMap::new()).unwrap()
    }

    #[test]
    fn smooth_fields_pass() {
        for text in [
            "0",
            "x^2*(1 - y)*(1 + t)",
            "sin(pi*x)*exp(-y)*cos(2*t)",
            "0.1*max(x - 0.4, 0)^3",
            "1/(y + 0.3)",
        ] {
            check_resolved(
                &expr(text),
                &lattice_segments([0.0; 2], [1.0; 2], 25),
                &[0.0, 1.0],
            )
            .unwrap_or_else(|e| panic!("{text}: {e}"));
        }
        let cube = lattice_segments([0.0; 3], [1.0; 3], 11);
        check_resolved(&expr("x*y*z*(1 + t)"), &cube, &[1.0]).unwrap();
        // a diagonal segment through a smooth region
        check_resolved(&expr("sin(x + y)"), &[([0.0, 0.0], [0.1, 0.1])], &[0.0]).unwrap();
    }

    #[test]
    fn a_pole_between_sample_points_is_found() {
        for text in ["0.1*x/(y - 0.3)", "1/(x - 0.51)^2", "tan(3*y)"] {
            let lattice = lattice_segments([0.0; 2], [1.0; 2], 25);
            let error = check_resolved(&expr(text), &lattice, &[0.5]).expect_err(text);
            assert!(
                error.contains("singular or not resolved") || error.contains("not finite"),
                "{text}: {error}"
            );
        }
    }
}
