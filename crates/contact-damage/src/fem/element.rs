//! Continuous Lagrange elements of degree l ∈ {1, 2} on the reference simplex of dimension
//! D ∈ {1, 2, 3} (the spaces X^h of the paper's Section 5, before the vector-valued V^h).
//!
//! Shape functions are written in the barycentric coordinates λ_0 = 1 − Σ ξ_i, λ_i = ξ_i:
//! - P1: φ_i = λ_i at the vertices;
//! - P2: φ_i = λ_i (2λ_i − 1) at the vertices, φ_e = 4 λ_a λ_b at the midpoint of edge e = [a, b].

use crate::error::{Error, Result};

/// Local edges of the reference simplex as vertex pairs: D=1: `[[0,1]]`;
/// D=2: `[[0,1],[1,2],[0,2]]`; D=3: `[[0,1],[1,2],[0,2],[0,3],[1,3],[2,3]]`.
/// `dim = 0` gives no edges.
///
/// # Panics
/// If `dim > 3` (a programming error: only simplices up to tetrahedra exist in this crate).
pub fn simplex_edges(dim: usize) -> &'static [[usize; 2]] {
    const EDGES: [[usize; 2]; 6] = [[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [2, 3]];
    match dim {
        0 => &[],
        1 => &EDGES[..1],
        2 => &EDGES[..3],
        3 => &EDGES[..6],
        _ => panic!("simplex_edges: dimension {dim} is not supported (only 0 to 3)"),
    }
}

/// The most nodes a cell has: 10, those of the P2 tetrahedron. Per-cell scratch arrays of
/// values and gradients are this long.
pub const MAX_CELL_NODES: usize = 10;

/// Continuous Lagrange element of degree 1 or 2 on the reference simplex of dimension D.
///
/// Node order: vertices first (0, e_1, …, e_D), then, for P2, the edge midpoints in
/// [`simplex_edges`]`(D)` order.
#[derive(Debug, Clone, Copy)]
pub struct LagrangeElement<const D: usize> {
    degree: usize,
}

impl<const D: usize> LagrangeElement<D> {
    /// The Lagrange element of the given degree; `degree` must be 1 or 2 and D ∈ {1, 2, 3},
    /// otherwise [`Error::InvalidInput`].
    pub fn new(degree: usize) -> Result<Self> {
        if !(1..=3).contains(&D) {
            return Err(Error::InvalidInput(format!(
                "Lagrange elements are implemented in dimensions 1, 2 and 3, not {D}"
            )));
        }
        if !(1..=2).contains(&degree) {
            return Err(Error::InvalidInput(format!(
                "Lagrange element degree {degree} is not supported (only degree 1 or 2)"
            )));
        }
        Ok(LagrangeElement { degree })
    }

    /// The P2 element (the geometry map of curved cells, [`crate::fem::curved`]).
    pub(crate) fn quadratic() -> Self {
        LagrangeElement { degree: 2 }
    }

    /// Polynomial degree l.
    pub fn degree(&self) -> usize {
        self.degree
    }

    /// Number of nodes: D + 1 for P1, (D + 1)(D + 2)/2 for P2.
    pub fn num_nodes(&self) -> usize {
        match self.degree {
            1 => D + 1,
            _ => (D + 1) * (D + 2) / 2,
        }
    }

    /// Reference nodes: vertices first (0, e_1, …, e_D), then edge midpoints in
    /// `simplex_edges(D)` order.
    pub fn reference_nodes(&self) -> Vec<[f64; D]> {
        let vertex =
            |i: usize| -> [f64; D] { std::array::from_fn(|k| if k + 1 == i { 1.0 } else { 0.0 }) };
        let mut nodes: Vec<[f64; D]> = (0..=D).map(vertex).collect();
        if self.degree == 2 {
            for &[a, b] in simplex_edges(D) {
                let (va, vb) = (vertex(a), vertex(b));
                nodes.push(std::array::from_fn(|k| 0.5 * (va[k] + vb[k])));
            }
        }
        nodes
    }

    /// Shape function values at the reference point `xi`, in node order.
    ///
    /// # Panics
    /// If `out.len() != self.num_nodes()`.
    pub fn values(&self, xi: &[f64; D], out: &mut [f64]) {
        assert_eq!(out.len(), self.num_nodes(), "values: output length");
        let lambda = barycentric(xi);
        match self.degree {
            1 => out.copy_from_slice(&lambda[..=D]),
            _ => {
                for i in 0..=D {
                    out[i] = lambda[i] * (2.0 * lambda[i] - 1.0);
                }
                for (e, &[a, b]) in simplex_edges(D).iter().enumerate() {
                    out[D + 1 + e] = 4.0 * lambda[a] * lambda[b];
                }
            }
        }
    }

    /// Gradients of the shape functions with respect to the reference coordinates ξ at `xi`,
    /// in node order.
    ///
    /// # Panics
    /// If `out.len() != self.num_nodes()`.
    pub fn gradients(&self, xi: &[f64; D], out: &mut [[f64; D]]) {
        assert_eq!(out.len(), self.num_nodes(), "gradients: output length");
        let lambda = barycentric(xi);
        // ∇λ_0 = (−1, …, −1), ∇λ_i = e_i.
        let grad_lambda = |i: usize| -> [f64; D] {
            std::array::from_fn(|k| {
                if i == 0 {
                    -1.0
                } else if k + 1 == i {
                    1.0
                } else {
                    0.0
                }
            })
        };
        match self.degree {
            1 => {
                for (i, gradient) in out.iter_mut().enumerate() {
                    *gradient = grad_lambda(i);
                }
            }
            _ => {
                for i in 0..=D {
                    let factor = 4.0 * lambda[i] - 1.0;
                    out[i] = grad_lambda(i).map(|g| factor * g);
                }
                for (e, &[a, b]) in simplex_edges(D).iter().enumerate() {
                    let (grad_a, grad_b) = (grad_lambda(a), grad_lambda(b));
                    out[D + 1 + e] = std::array::from_fn(|k| {
                        4.0 * (lambda[a] * grad_b[k] + lambda[b] * grad_a[k])
                    });
                }
            }
        }
    }
}

/// Barycentric coordinates (λ_0, …, λ_D) of a reference point, in an array of length 4
/// (entries beyond D are zero).
fn barycentric<const D: usize>(xi: &[f64; D]) -> [f64; 4] {
    let mut lambda = [0.0; 4];
    lambda[0] = 1.0 - xi.iter().sum::<f64>();
    lambda[1..=D].copy_from_slice(xi);
    lambda
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::test_random::SeededRandom as Points;

    /// Random points of the reference simplex.
    trait SimplexPoints {
        fn point_in_simplex<const D: usize>(&mut self) -> [f64; D];
    }

    impl SimplexPoints for Points {
        /// A point of the reference simplex (possibly on its boundary region).
        fn point_in_simplex<const D: usize>(&mut self) -> [f64; D] {
            loop {
                let p: [f64; D] = std::array::from_fn(|_| self.unit());
                if p.iter().sum::<f64>() <= 1.0 {
                    return p;
                }
            }
        }
    }

    fn elements<const D: usize>() -> Vec<LagrangeElement<D>> {
        vec![
            LagrangeElement::new(1).unwrap(),
            LagrangeElement::new(2).unwrap(),
        ]
    }

    fn check_kronecker<const D: usize>() {
        for element in elements::<D>() {
            let nodes = element.reference_nodes();
            assert_eq!(nodes.len(), element.num_nodes());
            let mut values = vec![0.0; element.num_nodes()];
            for (j, node) in nodes.iter().enumerate() {
                element.values(node, &mut values);
                for (i, &v) in values.iter().enumerate() {
                    let expected = if i == j { 1.0 } else { 0.0 };
                    assert!(
                        (v - expected).abs() < 1e-15,
                        "P{} D={D}: φ_{i}(x_{j}) = {v}",
                        element.degree()
                    );
                }
            }
        }
    }

    fn check_partition_of_unity_and_gradient_sum<const D: usize>() {
        let mut rng = Points::new(7);
        for element in elements::<D>() {
            let mut values = vec![0.0; element.num_nodes()];
            let mut gradients = vec![[0.0; D]; element.num_nodes()];
            for _ in 0..50 {
                let xi = rng.point_in_simplex::<D>();
                element.values(&xi, &mut values);
                element.gradients(&xi, &mut gradients);
                assert!((values.iter().sum::<f64>() - 1.0).abs() < 1e-14);
                for k in 0..D {
                    let sum: f64 = gradients.iter().map(|g| g[k]).sum();
                    assert!(
                        sum.abs() < 1e-13,
                        "P{} D={D}: Σ ∂_{k}φ = {sum}",
                        element.degree()
                    );
                }
            }
        }
    }

    fn check_gradients_by_finite_differences<const D: usize>() {
        let mut rng = Points::new(11);
        let step = 1e-6;
        for element in elements::<D>() {
            let n = element.num_nodes();
            let (mut plus, mut minus) = (vec![0.0; n], vec![0.0; n]);
            let mut gradients = vec![[0.0; D]; n];
            for _ in 0..20 {
                let xi = rng.point_in_simplex::<D>();
                element.gradients(&xi, &mut gradients);
                for k in 0..D {
                    let mut forward = xi;
                    forward[k] += step;
                    let mut backward = xi;
                    backward[k] -= step;
                    element.values(&forward, &mut plus);
                    element.values(&backward, &mut minus);
                    for i in 0..n {
                        // Central differences are exact for quadratics up to rounding (~1e-10).
                        let difference = (plus[i] - minus[i]) / (2.0 * step);
                        assert!(
                            (difference - gradients[i][k]).abs() < 1e-8,
                            "P{} D={D}: ∂_{k}φ_{i} = {} vs finite difference {difference}",
                            element.degree(),
                            gradients[i][k]
                        );
                    }
                }
            }
        }
    }

    /// Interpolates a random polynomial of degree ≤ the element degree at the nodes and checks
    /// that the interpolant and its gradient equal the polynomial and its gradient everywhere.
    #[allow(clippy::needless_range_loop)] // index notation of the quadratic form ξᵀAξ
    fn check_polynomial_reproduction<const D: usize>() {
        let mut rng = Points::new(13);
        for element in elements::<D>() {
            // p(ξ) = c + b·ξ + (if P2) ξᵀ A ξ with A symmetric.
            let constant = rng.unit() - 0.5;
            let linear: [f64; D] = std::array::from_fn(|_| rng.unit() - 0.5);
            let mut quadratic = [[0.0; D]; D];
            if element.degree() == 2 {
                for r in 0..D {
                    for c in r..D {
                        quadratic[r][c] = rng.unit() - 0.5;
                        quadratic[c][r] = quadratic[r][c];
                    }
                }
            }
            let polynomial = |x: &[f64; D]| {
                let mut value = constant;
                for r in 0..D {
                    value += linear[r] * x[r];
                    for c in 0..D {
                        value += quadratic[r][c] * x[r] * x[c];
                    }
                }
                value
            };
            let polynomial_gradient = |x: &[f64; D]| -> [f64; D] {
                std::array::from_fn(|r| {
                    linear[r] + 2.0 * (0..D).map(|c| quadratic[r][c] * x[c]).sum::<f64>()
                })
            };
            let nodal: Vec<f64> = element.reference_nodes().iter().map(polynomial).collect();
            let mut values = vec![0.0; element.num_nodes()];
            let mut gradients = vec![[0.0; D]; element.num_nodes()];
            for _ in 0..50 {
                let xi = rng.point_in_simplex::<D>();
                element.values(&xi, &mut values);
                element.gradients(&xi, &mut gradients);
                let interpolant: f64 = values.iter().zip(&nodal).map(|(v, p)| v * p).sum();
                assert!(
                    (interpolant - polynomial(&xi)).abs() < 1e-14,
                    "P{} D={D}",
                    element.degree()
                );
                let expected_gradient = polynomial_gradient(&xi);
                for k in 0..D {
                    let derivative: f64 = gradients.iter().zip(&nodal).map(|(g, p)| g[k] * p).sum();
                    assert!(
                        (derivative - expected_gradient[k]).abs() < 1e-13,
                        "P{} D={D}",
                        element.degree()
                    );
                }
            }
        }
    }

    #[test]
    fn shape_functions_are_kronecker_at_nodes() {
        check_kronecker::<1>();
        check_kronecker::<2>();
        check_kronecker::<3>();
    }

    #[test]
    fn shape_functions_sum_to_one_and_gradients_to_zero() {
        check_partition_of_unity_and_gradient_sum::<1>();
        check_partition_of_unity_and_gradient_sum::<2>();
        check_partition_of_unity_and_gradient_sum::<3>();
    }

    #[test]
    fn gradients_match_finite_differences() {
        check_gradients_by_finite_differences::<1>();
        check_gradients_by_finite_differences::<2>();
        check_gradients_by_finite_differences::<3>();
    }

    #[test]
    fn elements_reproduce_polynomials_of_their_degree() {
        check_polynomial_reproduction::<1>();
        check_polynomial_reproduction::<2>();
        check_polynomial_reproduction::<3>();
    }

    #[test]
    fn p1_does_not_reproduce_quadratics() {
        // Shows the reproduction test can fail: x² interpolated by P1 on [0, 1] is x, not x².
        let element = LagrangeElement::<1>::new(1).unwrap();
        let nodal: Vec<f64> = element
            .reference_nodes()
            .iter()
            .map(|x| x[0] * x[0])
            .collect();
        let mut values = vec![0.0; 2];
        element.values(&[0.5], &mut values);
        let interpolant: f64 = values.iter().zip(&nodal).map(|(v, p)| v * p).sum();
        assert!((interpolant - 0.25).abs() > 0.2);
    }

    #[test]
    fn node_counts_and_order() {
        let p2 = LagrangeElement::<3>::new(2).unwrap();
        assert_eq!(p2.num_nodes(), 10);
        assert_eq!(LagrangeElement::<2>::new(2).unwrap().num_nodes(), 6);
        assert_eq!(LagrangeElement::<2>::new(1).unwrap().num_nodes(), 3);
        let nodes = p2.reference_nodes();
        assert_eq!(nodes[0], [0.0, 0.0, 0.0]);
        assert_eq!(nodes[3], [0.0, 0.0, 1.0]);
        assert_eq!(nodes[4], [0.5, 0.0, 0.0]); // edge [0, 1]
        assert_eq!(nodes[5], [0.5, 0.5, 0.0]); // edge [1, 2]
        assert_eq!(nodes[9], [0.0, 0.5, 0.5]); // edge [2, 3]
    }

    #[test]
    fn element_rejects_unsupported_degree() {
        for degree in [0, 3] {
            let message = LagrangeElement::<2>::new(degree).unwrap_err().to_string();
            assert!(message.contains(&format!("degree {degree}")), "{message}");
        }
        assert!(LagrangeElement::<4>::new(1).is_err());
    }
}
