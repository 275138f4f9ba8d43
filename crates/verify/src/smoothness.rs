//! Is a manufactured field smooth and resolved, or does it hide a pole?
//!
//! Theorem 5.2 of Han, Shillor & Sofonea (2001) bounds the error of a *regular* solution; a
//! manufactured field with a singularity inside the domain (`0.1*x/(y - 0.3)`) is not one, and the
//! study would report a FAIL verdict with errors of 10³ where the fault lies in the case file. A
//! pole is rarely hit exactly by sample points, so checking the values for finiteness is not
//! enough. Instead the fundamental theorem of calculus is checked on every edge `[a, b]` of a
//! sample lattice of the box, for every coordinate direction `e` and several times: Simpson's
//! rule applied to the directional derivative, `S = |b − a|/6 (g(a) + 4 g(m) + g(b))` with
//! `g = ∇f · e` and `m` the midpoint, must reproduce `f(b) − f(a)`:
//!
//! ```text
//!     |S − (f(b) − f(a))| ≤ TOLERANCE · (|f(b) − f(a)| + |b − a| max(|g(a)|, |g(m)|, |g(b)|)) + FLOOR.
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

/// Checks the expression `field` on the lattice of the box `[lower, upper]` with `per_axis`
/// points per axis at `times`; returns a message naming the first edge that fails.
pub fn check_resolved<const D: usize>(
    field: &Expr,
    lower: [f64; D],
    upper: [f64; D],
    per_axis: usize,
    times: &[f64],
) -> Result<(), String> {
    let spacing: [f64; D] = std::array::from_fn(|i| (upper[i] - lower[i]) / (per_axis - 1) as f64);
    let total = per_axis.pow(D as u32);
    for &t in times {
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
                let mut m = a;
                m[axis] += 0.5 * spacing[axis];
                let (fa, ga) = value_gradient(field, &a, t);
                let (fb, gb) = value_gradient(field, &b, t);
                let (_, gm) = value_gradient(field, &m, t);
                let (ga, gm, gb) = (ga[axis], gm[axis], gb[axis]);
                let at = |x: &[f64; D]| format!("x = {x:?}, t = {}", short(t));
                if let Some(bad) = [fa, fb, ga, gm, gb].iter().find(|v| !v.is_finite()) {
                    return Err(format!(
                        "not finite near {} (value or derivative {bad})",
                        at(&m)
                    ));
                }
                let simpson = spacing[axis] / 6.0 * (ga + 4.0 * gm + gb);
                let difference = fb - fa;
                let scale = difference.abs() + spacing[axis] * ga.abs().max(gm.abs()).max(gb.abs());
                if (simpson - difference).abs() > TOLERANCE * scale + FLOOR {
                    return Err(format!(
                        "singular or not resolved between {} and {}: the values differ by {} but the derivative integrates to {} (a pole inside the domain, or an oscillation on the scale {} of the sample lattice)",
                        at(&a),
                        at(&b),
                        short(difference),
                        short(simpson),
                        short(spacing[axis]),
                    ));
                }
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
            check_resolved::<2>(&expr(text), [0.0; 2], [1.0; 2], 25, &[0.0, 1.0])
                .unwrap_or_else(|e| panic!("{text}: {e}"));
        }
        check_resolved::<3>(&expr("x*y*z*(1 + t)"), [0.0; 3], [1.0; 3], 11, &[1.0]).unwrap();
    }

    #[test]
    fn a_pole_between_sample_points_is_found() {
        for text in ["0.1*x/(y - 0.3)", "1/(x - 0.51)^2", "tan(3*y)"] {
            let error =
                check_resolved::<2>(&expr(text), [0.0; 2], [1.0; 2], 25, &[0.5]).expect_err(text);
            assert!(
                error.contains("singular or not resolved") || error.contains("not finite"),
                "{text}: {error}"
            );
        }
    }
}
