//! Quadrature rules on the reference simplex {ξ_i ≥ 0, Σ ξ_i ≤ 1} ⊂ R^D.
//!
//! Arbitrary degrees use the conical-product (collapsed-coordinate, Duffy) construction of
//! Stroud: with ξ_1 = t and (ξ_2, …, ξ_D) = (1 − t) η, η in the reference simplex of dimension
//! D − 1, the Jacobian is (1 − t)^{D−1}, so
//!
//! ∫_{S_D} f dξ = ∫_0^1 (1 − t)^{D−1} ∫_{S_{D−1}} f(t, (1 − t) η) dη dt.
//!
//! A polynomial of total degree p in ξ is a polynomial of degree ≤ p in t and in η, so an n-point
//! Gauss–Jacobi rule for the weight (1 − t)^{D−1} on [0, 1] (exact to degree 2n − 1) nested with
//! the same construction in dimension D − 1 is exact to total degree 2n − 1. The 1D Gauss–Jacobi
//! nodes are the eigenvalues of the Jacobi (three-term recurrence) matrix (Golub–Welsch), found
//! here by Sturm-sequence bisection; the weights follow from the Christoffel formula
//! w_i = 1 / Σ_{k<n} p_k(x_i)² with orthonormal polynomials p_k.
//!
//! For low degrees, efficient symmetric rules with positive weights and interior points are used:
//! the centroid rule (degree 1), the 3-point triangle rule (degree 2), the 6-point triangle rule of
//! Strang–Fix/Dunavant (degree 4, closed form of Lyness–Jespersen) and the 4-point tetrahedron
//! rule (degree 2).

/// Quadrature rule on the reference simplex {ξ_i ≥ 0, Σ ξ_i ≤ 1} in R^D; weights sum to 1/D!.
///
/// All weights are positive and all points lie strictly inside the simplex.
#[derive(Debug, Clone)]
pub struct QuadratureRule<const D: usize> {
    /// Quadrature points in reference coordinates ξ.
    pub points: Vec<[f64; D]>,
    /// Quadrature weights (sum 1/D!, the volume of the reference simplex).
    pub weights: Vec<f64>,
    /// Guaranteed degree of exactness (≥ the degree that was asked for).
    degree: usize,
}

impl<const D: usize> QuadratureRule<D> {
    /// A rule exact for all polynomials of total degree ≤ `degree` (any degree).
    ///
    /// Degrees 0 and 1 give the 1-point centroid rule. In D = 2, degree 2 gives the symmetric
    /// 3-point rule, degrees 3–4 the symmetric 6-point rule, degree 5 Radon's 7-point rule and
    /// degree 6 Dunavant's 12-point rule; in D = 3, degree 2 gives the symmetric 4-point rule,
    /// degrees 4–5 the symmetric 14-point rule and degree 6 Keast's 24-point rule (all with
    /// positive weights and interior points). All other cases use the conical product of
    /// ⌊degree/2⌋ + 1
    /// Gauss–Jacobi points per direction. [`QuadratureRule::degree`] reports the degree the
    /// returned rule is actually exact to, which may exceed the requested one.
    pub fn simplex(degree: usize) -> Self {
        if degree <= 1 {
            return Self::centroid();
        }
        match (D, degree) {
            (2, 2) => Self::triangle_three_point(),
            (2, 3 | 4) => Self::triangle_six_point(),
            (2, 5) => Self::triangle_seven_point(),
            (2, 6) => Self::triangle_twelve_point(),
            (3, 2) => Self::tetrahedron_four_point(),
            (3, 4 | 5) => Self::tetrahedron_fourteen_point(),
            (3, 6) => Self::tetrahedron_twenty_four_point(),
            _ => Self::conical_product(degree / 2 + 1),
        }
    }

    /// The degree of exactness of the rule: every polynomial of total degree ≤ `degree()` is
    /// integrated exactly (up to rounding).
    pub fn degree(&self) -> usize {
        self.degree
    }

    /// Number of quadrature points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True if the rule has no points (never the case for rules built by [`Self::simplex`]).
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The 1-point rule at the centroid (1/(D+1), …, 1/(D+1)), exact to degree 1.
    fn centroid() -> Self {
        let centroid = [1.0 / (D as f64 + 1.0); D];
        QuadratureRule {
            points: vec![centroid],
            weights: vec![1.0 / factorial(D)],
            degree: 1,
        }
    }

    /// Builds a rule from barycentric-orbit data: each entry lists points given by their D
    /// Cartesian reference coordinates (the first barycentric coordinate λ_0 = 1 − Σ ξ_i is
    /// implied) and the common weight of the orbit.
    fn from_orbits(orbits: &[(&[[f64; D]], f64)], degree: usize) -> Self {
        let mut points = Vec::new();
        let mut weights = Vec::new();
        for &(orbit, weight) in orbits {
            for point in orbit {
                points.push(*point);
                weights.push(weight);
            }
        }
        QuadratureRule {
            points,
            weights,
            degree,
        }
    }

    /// The 3 points of the triangle orbit (a, a, 1 − 2a) in barycentric coordinates. Only
    /// called with D = 2.
    fn triangle_orbit(a: f64) -> [[f64; D]; 3] {
        let c = 1.0 - 2.0 * a;
        [
            point_from_slice::<D>(&[a, a]),
            point_from_slice::<D>(&[c, a]),
            point_from_slice::<D>(&[a, c]),
        ]
    }

    /// The 4 points of the tetrahedron orbit (a, a, a, 1 − 3a) in barycentric coordinates. Only
    /// called with D = 3.
    fn tetrahedron_orbit(a: f64) -> [[f64; D]; 4] {
        let c = 1.0 - 3.0 * a;
        [
            point_from_slice::<D>(&[a, a, a]),
            point_from_slice::<D>(&[c, a, a]),
            point_from_slice::<D>(&[a, c, a]),
            point_from_slice::<D>(&[a, a, c]),
        ]
    }

    /// Symmetric 3-point triangle rule at (1/6, 1/6), (2/3, 1/6), (1/6, 2/3), weights 1/6
    /// (exact to degree 2). Only called with D = 2.
    fn triangle_three_point() -> Self {
        let (a, b) = (1.0 / 6.0, 2.0 / 3.0);
        let orbit = [
            point_from_slice::<D>(&[a, a]),
            point_from_slice::<D>(&[b, a]),
            point_from_slice::<D>(&[a, b]),
        ];
        Self::from_orbits(&[(&orbit, 1.0 / 6.0)], 2)
    }

    /// Symmetric 6-point triangle rule (Strang–Fix, Dunavant degree 4) in the closed form of
    /// Lyness & Jespersen (1975): orbits (a, a, 1 − 2a) with
    /// a = (8 − √10 ± √(38 − 44√(2/5)))/18 and weights (620 ± √(213125 − 53320√10))/3720 relative
    /// to the triangle area 1/2. Only called with D = 2.
    fn triangle_six_point() -> Self {
        let sqrt10 = 10f64.sqrt();
        let root = (38.0 - 44.0 * (0.4f64).sqrt()).sqrt();
        let weight_root = (213125.0 - 53320.0 * sqrt10).sqrt();
        let inner = Self::triangle_orbit((8.0 - sqrt10 + root) / 18.0);
        let outer = Self::triangle_orbit((8.0 - sqrt10 - root) / 18.0);
        let inner_weight = 0.5 * (620.0 + weight_root) / 3720.0;
        let outer_weight = 0.5 * (620.0 - weight_root) / 3720.0;
        Self::from_orbits(&[(&inner, inner_weight), (&outer, outer_weight)], 4)
    }

    /// Symmetric 4-point tetrahedron rule: orbit (a, a, a, b) with a = (5 − √5)/20,
    /// b = (5 + 3√5)/20, weights 1/24 (exact to degree 2). Only called with D = 3.
    fn tetrahedron_four_point() -> Self {
        let sqrt5 = 5f64.sqrt();
        let a = (5.0 - sqrt5) / 20.0;
        let b = (5.0 + 3.0 * sqrt5) / 20.0;
        let orbit = [
            point_from_slice::<D>(&[a, a, a]),
            point_from_slice::<D>(&[b, a, a]),
            point_from_slice::<D>(&[a, b, a]),
            point_from_slice::<D>(&[a, a, b]),
        ];
        Self::from_orbits(&[(&orbit, 1.0 / 24.0)], 2)
    }

    /// Radon's symmetric 7-point triangle rule (degree 5): the centroid with weight 9/80 and the
    /// orbits (a, a, 1 − 2a) with a = (6 ∓ √15)/21 and weights (155 ∓ √15)/2400 (triangle area
    /// 1/2). Only called with D = 2.
    fn triangle_seven_point() -> Self {
        let sqrt15 = 15f64.sqrt();
        let centroid = [point_from_slice::<D>(&[1.0 / 3.0, 1.0 / 3.0])];
        let first = Self::triangle_orbit((6.0 - sqrt15) / 21.0);
        let second = Self::triangle_orbit((6.0 + sqrt15) / 21.0);
        Self::from_orbits(
            &[
                (&centroid, 9.0 / 80.0),
                (&first, (155.0 - sqrt15) / 2400.0),
                (&second, (155.0 + sqrt15) / 2400.0),
            ],
            5,
        )
    }

    /// Dunavant's symmetric 12-point triangle rule of degree 6 (1985): orbits (a, a, 1 − 2a) for
    /// two values of a and the 6 permutations of (a, b, 1 − a − b); parameters recomputed by
    /// Newton's method on the moment equations in 40-digit arithmetic (weights relative to the
    /// area 1/2). Only called with D = 2.
    #[allow(clippy::excessive_precision)]
    fn triangle_twelve_point() -> Self {
        let (a, b) = (0.053_145_049_844_816_947_35, 0.310_352_451_033_784_405_42);
        let c = 1.0 - a - b;
        let general = [
            point_from_slice::<D>(&[a, b]),
            point_from_slice::<D>(&[b, a]),
            point_from_slice::<D>(&[a, c]),
            point_from_slice::<D>(&[c, a]),
            point_from_slice::<D>(&[b, c]),
            point_from_slice::<D>(&[c, b]),
        ];
        let inner = Self::triangle_orbit(0.249_286_745_170_910_421_29);
        let outer = Self::triangle_orbit(0.063_089_014_491_502_228_34);
        Self::from_orbits(
            &[
                (&inner, 0.058_393_137_863_189_683_01),
                (&outer, 0.025_422_453_185_103_408_46),
                (&general, 0.041_425_537_809_186_787_60),
            ],
            6,
        )
    }

    /// Keast's symmetric 24-point tetrahedron rule of degree 6 (1986), positive weights: three
    /// orbits (a, a, a, 1 − 3a) and the 12 permutations of (a, a, b, 1 − 2a − b); parameters
    /// recomputed by Newton's method on the moment equations in 40-digit arithmetic. Only
    /// called with D = 3.
    #[allow(clippy::excessive_precision)]
    fn tetrahedron_twenty_four_point() -> Self {
        let (a, b) = (0.063_661_001_875_017_525_30, 0.269_672_331_458_315_808_03);
        let c = 1.0 - 2.0 * a - b;
        // the barycentric coordinates (λ0, λ1, λ2, λ3) run over the permutations of (a, a, b, c);
        // the point is (λ1, λ2, λ3)
        let general: Vec<[f64; D]> = [
            [a, a, b, c],
            [a, a, c, b],
            [a, b, a, c],
            [a, c, a, b],
            [a, b, c, a],
            [a, c, b, a],
            [b, a, a, c],
            [c, a, a, b],
            [b, a, c, a],
            [c, a, b, a],
            [b, c, a, a],
            [c, b, a, a],
        ]
        .iter()
        .map(|lambda| point_from_slice::<D>(&lambda[1..]))
        .collect();
        let first = Self::tetrahedron_orbit(0.214_602_871_259_152_029_29);
        let second = Self::tetrahedron_orbit(0.040_673_958_534_611_353_12);
        let third = Self::tetrahedron_orbit(0.322_337_890_142_275_510_34);
        Self::from_orbits(
            &[
                (&first, 0.006_653_791_709_694_582_02),
                (&second, 0.001_679_535_175_886_773_82),
                (&third, 0.009_226_196_923_942_453_68),
                (&general, 0.008_035_714_285_714_285_71),
            ],
            6,
        )
    }

    /// The symmetric 14-point tetrahedron rule of degree 5 with positive weights (Walkington
    /// 2000; Keast 1986): orbits (a, a, a, 1 − 3a) for two values of a and (b, b, ½ − b, ½ − b);
    /// the parameters below solve the moment equations of degree ≤ 5 to 1e-40 (recomputed by
    /// Newton's method in 40-digit arithmetic; the unit tests check exactness). Only called with
    /// D = 3. The literals keep the digits computed (the compiler rounds them correctly).
    #[allow(clippy::excessive_precision)]
    fn tetrahedron_fourteen_point() -> Self {
        let b = 0.045_503_704_125_649_649_49;
        let c = 0.5 - b;
        let edge_orbit = [
            point_from_slice::<D>(&[b, b, c]),
            point_from_slice::<D>(&[b, c, b]),
            point_from_slice::<D>(&[c, b, b]),
            point_from_slice::<D>(&[c, c, b]),
            point_from_slice::<D>(&[c, b, c]),
            point_from_slice::<D>(&[b, c, c]),
        ];
        let near_vertex = Self::tetrahedron_orbit(0.092_735_250_310_891_226_40);
        let near_face = Self::tetrahedron_orbit(0.310_885_919_263_300_609_80);
        Self::from_orbits(
            &[
                (&near_vertex, 0.012_248_840_519_393_658_26),
                (&near_face, 0.018_781_320_953_002_641_80),
                (&edge_orbit, 0.007_091_003_462_846_911_07),
            ],
            5,
        )
    }

    /// Conical product of `points_per_direction` Gauss–Jacobi points per direction, exact to
    /// degree 2·points_per_direction − 1.
    fn conical_product(points_per_direction: usize) -> Self {
        let (flat_points, weights) = conical_rule(D, points_per_direction);
        let points = flat_points
            .iter()
            .map(|p| point_from_slice::<D>(p))
            .collect();
        QuadratureRule {
            points,
            weights,
            degree: 2 * points_per_direction - 1,
        }
    }
}

/// Copies the first D entries of `coordinates` into an array.
fn point_from_slice<const D: usize>(coordinates: &[f64]) -> [f64; D] {
    std::array::from_fn(|i| coordinates[i])
}

/// n! as a float.
fn factorial(n: usize) -> f64 {
    (1..=n).map(|k| k as f64).product()
}

/// Conical-product rule on the reference simplex of dimension `dim` with `n` points per direction.
fn conical_rule(dim: usize, n: usize) -> (Vec<Vec<f64>>, Vec<f64>) {
    if dim == 0 {
        return (vec![Vec::new()], vec![1.0]);
    }
    let (inner_points, inner_weights) = conical_rule(dim - 1, n);
    let (nodes, node_weights) = gauss_jacobi_unit_interval(n, (dim - 1) as f64);
    let mut points = Vec::with_capacity(nodes.len() * inner_points.len());
    let mut weights = Vec::with_capacity(points.capacity());
    for (&t, &t_weight) in nodes.iter().zip(&node_weights) {
        for (eta, &eta_weight) in inner_points.iter().zip(&inner_weights) {
            let mut point = Vec::with_capacity(dim);
            point.push(t);
            point.extend(eta.iter().map(|&e| (1.0 - t) * e));
            points.push(point);
            weights.push(t_weight * eta_weight);
        }
    }
    (points, weights)
}

/// n-point Gauss–Jacobi rule for ∫_0^1 (1 − t)^alpha g(t) dt (alpha > −1), exact for
/// polynomials g of degree ≤ 2n − 1. Returns (nodes, weights); nodes lie in (0, 1).
///
/// Built from the Jacobi polynomials P_k^{(alpha, 0)} on [−1, 1] with weight (1 − x)^alpha and
/// mapped by t = (1 + x)/2, so (1 − t)^alpha dt = 2^{−alpha−1} (1 − x)^alpha dx.
fn gauss_jacobi_unit_interval(n: usize, alpha: f64) -> (Vec<f64>, Vec<f64>) {
    let (nodes, weights) = gauss_jacobi(n, alpha, 0.0);
    let scale = 2f64.powf(-alpha - 1.0);
    (
        nodes.iter().map(|x| 0.5 * (1.0 + x)).collect(),
        weights.iter().map(|w| w * scale).collect(),
    )
}

/// n-point Gauss–Jacobi rule on [−1, 1] for the weight (1 − x)^alpha (1 + x)^beta.
///
/// Golub–Welsch: the nodes are the eigenvalues of the symmetric tridiagonal Jacobi matrix of
/// the orthonormal recurrence x p_k = b_{k+1} p_{k+1} + a_k p_k + b_k p_{k−1}; they are computed by
/// Sturm-sequence bisection (backward stable, accurate to a few ulps of ‖T‖). The weights are
/// w_i = 1 / Σ_{k<n} p_k(x_i)² with p_0 = 1/√μ_0, μ_0 = ∫ (1 − x)^alpha (1 + x)^beta dx.
fn gauss_jacobi(n: usize, alpha: f64, beta: f64) -> (Vec<f64>, Vec<f64>) {
    let (diagonal, off_diagonal) = jacobi_recurrence(n, alpha, beta);
    let mu0 = 2f64.powf(alpha + beta + 1.0) * gamma_ratio(alpha, beta);
    let nodes: Vec<f64> = (0..n)
        .map(|index| tridiagonal_eigenvalue(&diagonal, &off_diagonal, index))
        .collect();
    let weights = nodes
        .iter()
        .map(|&x| {
            // Orthonormal polynomials p_0..p_{n−1} at x by the three-term recurrence.
            let mut previous = 0.0;
            let mut current = 1.0 / mu0.sqrt();
            let mut sum_of_squares = current * current;
            for k in 0..n.saturating_sub(1) {
                let coupling_below = if k == 0 { 0.0 } else { off_diagonal[k - 1] };
                let next =
                    ((x - diagonal[k]) * current - coupling_below * previous) / off_diagonal[k];
                previous = current;
                current = next;
                sum_of_squares += current * current;
            }
            1.0 / sum_of_squares
        })
        .collect();
    (nodes, weights)
}

/// Γ(alpha + 1) Γ(beta + 1) / Γ(alpha + beta + 2) for nonnegative integer alpha and beta = 0, the
/// only case used here: it equals 1/(alpha + 1).
fn gamma_ratio(alpha: f64, beta: f64) -> f64 {
    debug_assert!(beta == 0.0 && alpha >= 0.0 && alpha.fract() == 0.0);
    1.0 / (alpha + beta + 1.0)
}

/// Recurrence coefficients of the orthonormal Jacobi polynomials for (1 − x)^alpha (1 + x)^beta:
/// diagonal a_0..a_{n−1} and off-diagonal b_1..b_{n−1} (stored at indices 0..n−2).
fn jacobi_recurrence(n: usize, alpha: f64, beta: f64) -> (Vec<f64>, Vec<f64>) {
    let sum = alpha + beta;
    let diagonal = (0..n)
        .map(|k| {
            let k = k as f64;
            if k == 0.0 {
                (beta - alpha) / (sum + 2.0)
            } else {
                (beta * beta - alpha * alpha) / ((2.0 * k + sum) * (2.0 * k + sum + 2.0))
            }
        })
        .collect();
    let off_diagonal = (1..n)
        .map(|k| {
            let k = k as f64;
            let s = 2.0 * k + sum;
            (4.0 * k * (k + alpha) * (k + beta) * (k + sum) / (s * s * (s + 1.0) * (s - 1.0)))
                .sqrt()
        })
        .collect();
    (diagonal, off_diagonal)
}

/// The `index`-th smallest eigenvalue of the symmetric tridiagonal matrix with the given
/// diagonal and off-diagonal, by bisection on the Sturm count (number of eigenvalues < x).
fn tridiagonal_eigenvalue(diagonal: &[f64], off_diagonal: &[f64], index: usize) -> f64 {
    // Gershgorin bounds.
    let n = diagonal.len();
    let mut lower = f64::INFINITY;
    let mut upper = f64::NEG_INFINITY;
    for i in 0..n {
        let radius = if i > 0 {
            off_diagonal[i - 1].abs()
        } else {
            0.0
        } + if i + 1 < n {
            off_diagonal[i].abs()
        } else {
            0.0
        };
        lower = lower.min(diagonal[i] - radius);
        upper = upper.max(diagonal[i] + radius);
    }
    let count_below = |x: f64| {
        // Signs of the pivots of the LDLᵀ factorization of T − x I.
        let mut count = 0;
        let mut pivot = 1.0;
        for i in 0..n {
            let coupling = if i > 0 { off_diagonal[i - 1] } else { 0.0 };
            pivot = diagonal[i]
                - x
                - if i > 0 {
                    coupling * coupling / pivot
                } else {
                    0.0
                };
            if pivot == 0.0 {
                pivot = -f64::EPSILON * (x.abs() + 1.0);
            }
            if pivot < 0.0 {
                count += 1;
            }
        }
        count
    };
    loop {
        let middle = 0.5 * (lower + upper);
        if middle <= lower || middle >= upper {
            return middle;
        }
        if count_below(middle) > index {
            upper = middle;
        } else {
            lower = middle;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// All multi-indices α ∈ N^D with |α| = total.
    fn multi_indices<const D: usize>(total: usize) -> Vec<[usize; D]> {
        fn recurse(
            prefix: &mut Vec<usize>,
            remaining_dims: usize,
            total: usize,
            out: &mut Vec<Vec<usize>>,
        ) {
            if remaining_dims == 1 {
                prefix.push(total);
                out.push(prefix.clone());
                prefix.pop();
                return;
            }
            for first in 0..=total {
                prefix.push(first);
                recurse(prefix, remaining_dims - 1, total - first, out);
                prefix.pop();
            }
        }
        let mut out = Vec::new();
        recurse(&mut Vec::new(), D, total, &mut out);
        out.into_iter()
            .map(|v| std::array::from_fn(|i| v[i]))
            .collect()
    }

    /// ∫_{S_D} ξ^α dξ = α_1!…α_D! / (|α| + D)!.
    fn exact_monomial_integral<const D: usize>(alpha: &[usize; D]) -> f64 {
        let total: usize = alpha.iter().sum();
        alpha.iter().map(|&a| factorial(a)).product::<f64>() / factorial(total + D)
    }

    /// Relative error of the rule on ξ^α.
    fn relative_error<const D: usize>(rule: &QuadratureRule<D>, alpha: &[usize; D]) -> f64 {
        let approx: f64 = rule
            .points
            .iter()
            .zip(&rule.weights)
            .map(|(p, w)| w * (0..D).map(|i| p[i].powi(alpha[i] as i32)).product::<f64>())
            .sum();
        let exact = exact_monomial_integral(alpha);
        (approx - exact).abs() / exact
    }

    fn max_error_at_total_degree<const D: usize>(rule: &QuadratureRule<D>, total: usize) -> f64 {
        multi_indices::<D>(total)
            .iter()
            .map(|alpha| relative_error(rule, alpha))
            .fold(0.0, f64::max)
    }

    fn check_exactness<const D: usize>(max_degree: usize) {
        for degree in 0..=max_degree {
            let rule = QuadratureRule::<D>::simplex(degree);
            assert!(
                rule.degree() >= degree,
                "D={D}: rule for {degree} has degree {}",
                rule.degree()
            );
            assert_eq!(rule.len(), rule.weights.len());
            assert!(!rule.is_empty());
            for total in 0..=rule.degree() {
                let error = max_error_at_total_degree(&rule, total);
                assert!(
                    error < 1e-13,
                    "D={D}, requested degree {degree}: relative error {error:e} at |α| = {total}"
                );
            }
        }
    }

    fn check_inexact_beyond_degree<const D: usize>(max_degree: usize) {
        for degree in 0..=max_degree {
            let rule = QuadratureRule::<D>::simplex(degree);
            // Gauss errors for ξ^(2n) decay fast with n (≈ 1e-8 relative at n = 7), so the
            // threshold is set three orders above the exactness tolerance 1e-13.
            let error = max_error_at_total_degree(&rule, rule.degree() + 1);
            assert!(
                error > 1e-10,
                "D={D}, rule of degree {}: unexpectedly exact at degree + 1 (error {error:e})",
                rule.degree()
            );
        }
    }

    fn check_positive_interior<const D: usize>(max_degree: usize) {
        for degree in 0..=max_degree {
            let rule = QuadratureRule::<D>::simplex(degree);
            let total_weight: f64 = rule.weights.iter().sum();
            assert!((total_weight * factorial(D) - 1.0).abs() < 1e-14);
            assert!(rule.weights.iter().all(|&w| w > 0.0));
            for point in &rule.points {
                assert!(point.iter().all(|&x| x > 0.0), "{point:?} not interior");
                assert!(point.iter().sum::<f64>() < 1.0, "{point:?} not interior");
            }
        }
    }

    #[test]
    fn quadrature_is_exact_to_its_degree_on_segments() {
        check_exactness::<1>(20);
    }

    #[test]
    fn quadrature_is_exact_to_its_degree_on_triangles() {
        check_exactness::<2>(20);
    }

    #[test]
    fn quadrature_is_exact_to_its_degree_on_tetrahedra() {
        check_exactness::<3>(20);
    }

    #[test]
    fn quadrature_is_not_exact_beyond_its_degree() {
        check_inexact_beyond_degree::<1>(12);
        check_inexact_beyond_degree::<2>(12);
        check_inexact_beyond_degree::<3>(12);
    }

    #[test]
    fn quadrature_weights_are_positive_and_points_interior() {
        check_positive_interior::<1>(20);
        check_positive_interior::<2>(20);
        check_positive_interior::<3>(20);
    }

    #[test]
    fn low_degree_rules_are_the_efficient_symmetric_ones() {
        assert_eq!(QuadratureRule::<2>::simplex(0).len(), 1);
        assert_eq!(QuadratureRule::<3>::simplex(1).len(), 1);
        assert_eq!(QuadratureRule::<2>::simplex(2).len(), 3);
        assert_eq!(QuadratureRule::<2>::simplex(3).len(), 6);
        assert_eq!(QuadratureRule::<2>::simplex(4).len(), 6);
        assert_eq!(QuadratureRule::<3>::simplex(2).len(), 4);
        // Conical rules: (⌊p/2⌋ + 1)^D points.
        assert_eq!(QuadratureRule::<1>::simplex(5).len(), 3);
        assert_eq!(QuadratureRule::<2>::simplex(5).len(), 7);
        assert_eq!(QuadratureRule::<3>::simplex(4).len(), 14);
        assert_eq!(QuadratureRule::<3>::simplex(5).len(), 14);
        assert_eq!(QuadratureRule::<2>::simplex(6).len(), 12);
        assert_eq!(QuadratureRule::<3>::simplex(6).len(), 24);
        assert_eq!(QuadratureRule::<2>::simplex(7).len(), 16);
        assert_eq!(QuadratureRule::<3>::simplex(3).len(), 8);
    }

    #[test]
    fn gauss_legendre_nodes_match_closed_form() {
        // Three-point Gauss–Legendre on [−1, 1]: 0, ±√(3/5), weights 8/9, 5/9.
        let (nodes, weights) = gauss_jacobi(3, 0.0, 0.0);
        let expected = [-(0.6f64).sqrt(), 0.0, (0.6f64).sqrt()];
        for (x, e) in nodes.iter().zip(&expected) {
            assert!((x - e).abs() < 1e-15, "{x} vs {e}");
        }
        for (w, e) in weights.iter().zip(&[5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0]) {
            assert!((w - e).abs() < 1e-15, "{w} vs {e}");
        }
    }
}
