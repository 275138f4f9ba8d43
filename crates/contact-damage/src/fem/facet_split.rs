//! Facet rules split along a plane: boundary data that jump across a known plane (a friction
//! traction at a stick–slip front, a pressure applied on part of a face) are integrated
//! piecewise, each side of the plane by the full rule, so that the jump costs no quadrature
//! error. A fixed rule over a facet the jump crosses integrates a discontinuous integrand with
//! an error of the order of the facet's measure, whatever the degree of the rule.

use crate::fem::space::FacetRule;

/// Pieces whose share of the facet is below this are dropped (the plane through a vertex, up to
/// round-off): they carry no measurable weight.
const SLIVER: f64 = 1e-14;

impl FacetRule {
    /// The rule on the pieces into which the zero set of an affine function cuts the facet,
    /// given the function's values at the facet's vertices: each piece (a segment in 2D, a
    /// triangle of a fan in 3D) carries the whole rule, weighted by its share of the facet, so
    /// the result integrates exactly to the rule's degree every integrand that is a polynomial
    /// on each side. `None` when the zero set does not cross the facet's interior (all values of
    /// one sign, zeros allowed).
    pub fn split(&self, levels: &[f64]) -> Option<FacetRule> {
        let crosses = levels.iter().any(|&l| l > 0.0) && levels.iter().any(|&l| l < 0.0);
        if !crosses {
            return None;
        }
        let corners: Vec<Vec<f64>> = (0..levels.len())
            .map(|k| {
                (0..levels.len())
                    .map(|i| f64::from(u8::from(i == k)))
                    .collect()
            })
            .collect();
        let mut pieces = Vec::new();
        for side in [1.0, -1.0] {
            let kept = clip(&corners, levels, side);
            pieces.extend(simplices(&kept, levels.len()));
        }
        let mut barycentric = Vec::new();
        let mut weights = Vec::new();
        for piece in pieces {
            let share = share(&piece);
            if share < SLIVER {
                continue;
            }
            for (mu, &w) in self.barycentric.iter().zip(&self.weights) {
                barycentric.push(
                    (0..levels.len())
                        .map(|i| mu.iter().zip(&piece).map(|(m, v)| m * v[i]).sum())
                        .collect(),
                );
                weights.push(w * share);
            }
        }
        Some(FacetRule {
            barycentric,
            weights,
        })
    }
}

/// The part of the convex polygon (or segment) `polygon`, given by its corners in barycentric
/// coordinates, where `side` × level ≥ 0 (one Sutherland–Hodgman pass).
fn clip(polygon: &[Vec<f64>], levels: &[f64], side: f64) -> Vec<Vec<f64>> {
    let level = |p: &[f64]| side * p.iter().zip(levels).map(|(a, b)| a * b).sum::<f64>();
    let count = polygon.len();
    // a segment is not closed: its one edge is visited once
    let edges = if count == 2 { 1 } else { count };
    let mut kept: Vec<Vec<f64>> = Vec::new();
    let mut push = |p: Vec<f64>| {
        if kept.last() != Some(&p) && (count == 2 || kept.first() != Some(&p)) {
            kept.push(p);
        }
    };
    for e in 0..edges {
        let (a, b) = (&polygon[e], &polygon[(e + 1) % count]);
        let (la, lb) = (level(a), level(b));
        if la >= 0.0 {
            push(a.clone());
        }
        if (la > 0.0 && lb < 0.0) || (la < 0.0 && lb > 0.0) {
            let t = la / (la - lb);
            push(a.iter().zip(b).map(|(x, y)| x + t * (y - x)).collect());
        }
        if count == 2 && lb >= 0.0 {
            push(b.clone());
        }
    }
    kept
}

/// A convex polygon (or a segment) as simplices of the facet's dimension: the segment itself, or
/// the fan of triangles from the first corner.
fn simplices(polygon: &[Vec<f64>], vertices: usize) -> Vec<Vec<Vec<f64>>> {
    if vertices == 2 {
        return if polygon.len() == 2 {
            vec![polygon.to_vec()]
        } else {
            Vec::new()
        };
    }
    (1..polygon.len().saturating_sub(1))
        .map(|k| {
            vec![
                polygon[0].clone(),
                polygon[k].clone(),
                polygon[k + 1].clone(),
            ]
        })
        .collect()
}

/// The share of the facet a simplex of it covers (its measure over the facet's), from its
/// corners' barycentric coordinates.
fn share(piece: &[Vec<f64>]) -> f64 {
    if piece.len() == 2 {
        (piece[1][1] - piece[0][1]).abs()
    } else {
        let (a, b, c) = (&piece[0], &piece[1], &piece[2]);
        ((b[1] - a[1]) * (c[2] - a[2]) - (b[2] - a[2]) * (c[1] - a[1])).abs()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Σ w f(λ) over a rule.
    fn integrate(rule: &FacetRule, f: impl Fn(&[f64]) -> f64) -> f64 {
        rule.barycentric
            .iter()
            .zip(&rule.weights)
            .map(|(b, w)| w * f(b))
            .sum()
    }

    /// ∫ over the reference segment (normalized to measure 1) of the step s^m on the side
    /// λ1 > t of the cut and 0 elsewhere, with s = λ1, is (1 − t^{m+1})/(m + 1).
    #[test]
    fn split_segment_integrates_a_jumping_polynomial_exactly() {
        let rule = FacetRule::new(2, 6);
        for &t in &[0.1, 1.0 / 3.0, 0.5, 0.77] {
            // level λ1 − t at the vertices (λ1 = 0 at vertex 0, 1 at vertex 1)
            let split = rule.split(&[-t, 1.0 - t]).expect("the cut crosses");
            for m in 0..=6 {
                let exact = (1.0 - t.powi(m + 1)) / f64::from(m + 1);
                let got = integrate(&split, |b| if b[1] > t { b[1].powi(m) } else { 0.0 });
                assert!((got - exact).abs() < 1e-14, "t {t} m {m}: {got} vs {exact}");
            }
            // the plain rule misses the jump by O(1) (but at the midpoint, where its symmetry
            // puts half of its weight on each side)
            let plain = integrate(&rule, |b| if b[1] > t { 1.0 } else { 0.0 });
            assert!(t == 0.5 || (plain - (1.0 - t)).abs() > 1e-3, "t {t}");
        }
    }

    /// On the reference triangle (normalized to measure 1; λ1 = x, λ2 = y) cut by x + 2y = c:
    /// the weights still add up to 1, polynomials x^a y^b over both sides integrate as with the
    /// plain rule (exact for them), and the indicator of the side x + 2y < c integrates to that
    /// side's area in closed form.
    #[test]
    fn split_triangle_keeps_the_integral_and_measures_each_side() {
        let rule = FacetRule::new(3, 6);
        for &c in &[0.3, 0.9, 1.4] {
            let levels = [-c, 1.0 - c, 2.0 - c];
            let split = rule.split(&levels).expect("the cut crosses");
            let weight_sum: f64 = split.weights.iter().sum();
            assert!((weight_sum - 1.0).abs() < 1e-14);
            for (a, b) in [(0, 0), (2, 1), (3, 3), (1, 4)] {
                let poly = |l: &[f64]| l[1].powi(a) * l[2].powi(b);
                let whole = integrate(&rule, poly);
                assert!((integrate(&split, poly) - whole).abs() < 1e-14);
            }
            // the side x + 2y < c of the triangle {x, y ≥ 0, x + y ≤ 1}, over its area 1/2
            let below = |l: &[f64]| {
                if l[1] + 2.0 * l[2] < c {
                    1.0
                } else {
                    0.0
                }
            };
            let exact = if c <= 1.0 {
                c * c / 4.0
            } else {
                // the complement: x + 2y ≥ c inside the triangle is the triangle with corners
                // (0, c/2), (0, 1), (2 − c, c − 1)
                let complement = 0.5 * (1.0 - c / 2.0) * (2.0 - c);
                0.5 - complement
            } / 0.5;
            let got = integrate(&split, below);
            assert!((got - exact).abs() < 1e-14, "c {c}: {got} vs {exact}");
        }
    }

    /// A plane that does not cross the interior (through a vertex or an edge, or beside the
    /// facet) leaves the rule as it is.
    #[test]
    fn split_leaves_a_facet_the_plane_does_not_cross() {
        let rule = FacetRule::new(3, 4);
        assert!(rule.split(&[0.0, 1.0, 2.0]).is_none());
        assert!(rule.split(&[0.0, 0.0, -1.0]).is_none());
        assert!(rule.split(&[1.0, 2.0, 3.0]).is_none());
        assert!(FacetRule::new(2, 4).split(&[0.0, -1.0]).is_none());
    }

    proptest! {
        /// Random cuts of the triangle: the pieces tile it (weights sum to 1, every point
        /// inside), each lies on one side of the cut, and polynomials of the rule's degree
        /// integrate as with the plain rule.
        #[test]
        fn split_pieces_tile_the_facet_on_one_side_each(
            levels in prop::array::uniform3(-1.0f64..1.0),
        ) {
            let rule = FacetRule::new(3, 4);
            prop_assume!(levels.iter().any(|&l| l > 1e-6) && levels.iter().any(|&l| l < -1e-6));
            let split = rule.split(&levels).expect("the cut crosses");
            let sum: f64 = split.weights.iter().sum();
            prop_assert!((sum - 1.0).abs() < 1e-13);
            for b in &split.barycentric {
                prop_assert!(b.iter().all(|&x| x > -1e-14));
                prop_assert!((b.iter().sum::<f64>() - 1.0).abs() < 1e-13);
            }
            // each piece's points lie on one side: the rule's points come in blocks of its size
            for block in split.barycentric.chunks(rule.weights.len()) {
                let signs: Vec<f64> = block
                    .iter()
                    .map(|b| b.iter().zip(&levels).map(|(x, l)| x * l).sum::<f64>())
                    .collect();
                prop_assert!(signs.iter().all(|&s| s >= -1e-14) || signs.iter().all(|&s| s <= 1e-14));
            }
            let poly = |l: &[f64]| l[1].powi(3) * l[2] + l[0] * l[0];
            prop_assert!((integrate(&split, poly) - integrate(&rule, poly)).abs() < 1e-13);
        }
    }
}
