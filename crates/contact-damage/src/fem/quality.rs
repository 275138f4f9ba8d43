//! The shape-regularity measure of a mesh: Theorem 5.2 holds for a regular family of meshes,
//! h_K/ρ_K ≤ C for every cell K (h_K its diameter, ρ_K the radius of its inscribed ball).
//!
//! [`shape_regularity`] reports max_K (h_K/ρ_K) / (h/ρ of the regular simplex), which is 1 for
//! a mesh of regular simplices and grows without bound as cells flatten. The inradius is
//! ρ_K = D |K| / Σ_F |F| (volume over the facets' measures).

use crate::fem::mesh::Mesh;

/// h/ρ of the regular D-simplex: 2√3 for the equilateral triangle, 2√6 for the regular
/// tetrahedron.
pub fn regular_simplex_ratio(dim: usize) -> f64 {
    // ρ = a / √(2 d (d + 1)) for edge length a = h
    (2.0 * dim as f64 * (dim as f64 + 1.0)).sqrt()
}

/// h_K/ρ_K of cell c, normalized by [`regular_simplex_ratio`] (≥ 1, = 1 for a regular cell).
pub fn cell_shape_ratio<const D: usize>(mesh: &Mesh<D>, c: usize) -> f64 {
    let cell = mesh.cell(c);
    let facets: f64 = (0..=D)
        .map(|skip| {
            let corners: Vec<[f64; D]> = (0..=D)
                .filter(|&k| k != skip)
                .map(|k| mesh.vertex(cell[k]))
                .collect();
            simplex_measure(&corners)
        })
        .sum();
    let inradius = D as f64 * mesh.cell_volume(c) / facets;
    mesh.cell_diameter(c) / inradius / regular_simplex_ratio(D)
}

/// The shape-regularity measure of the mesh: the largest [`cell_shape_ratio`] over its cells.
pub fn shape_regularity<const D: usize>(mesh: &Mesh<D>) -> f64 {
    (0..mesh.num_cells())
        .map(|c| cell_shape_ratio(mesh, c))
        .fold(0.0, f64::max)
}

/// (D−1)-measure of the simplex with these D corners in R^D (a segment's length in 2D, a
/// triangle's area in 3D), from the Gram determinant of its edge vectors.
fn simplex_measure<const D: usize>(corners: &[[f64; D]]) -> f64 {
    let edge = |k: usize| -> [f64; D] { std::array::from_fn(|i| corners[k][i] - corners[0][i]) };
    let dot = |a: &[f64; D], b: &[f64; D]| -> f64 { (0..D).map(|i| a[i] * b[i]).sum() };
    match corners.len() {
        2 => dot(&edge(1), &edge(1)).sqrt(),
        3 => {
            let (a, b) = (edge(1), edge(2));
            0.5 * (dot(&a, &a) * dot(&b, &b) - dot(&a, &b).powi(2))
                .max(0.0)
                .sqrt()
        }
        _ => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::mesh::BoundaryPart::{Contact, Dirichlet, Neumann};

    #[test]
    fn regular_simplices_have_measure_one() {
        let h = 3f64.sqrt() / 2.0;
        let triangle = Mesh::<2>::new(
            vec![[0.0, 0.0], [1.0, 0.0], [0.5, h]],
            vec![0, 1, 2],
            vec![0, 1, 1, 2, 2, 0],
            vec![Dirichlet, Neumann, Contact],
        )
        .unwrap();
        assert!((shape_regularity(&triangle) - 1.0).abs() < 1e-14);
        let s = 1.0 / 2f64.sqrt();
        let tetrahedron = Mesh::<3>::new(
            vec![
                [1.0, 0.0, -s],
                [-1.0, 0.0, -s],
                [0.0, 1.0, s],
                [0.0, -1.0, s],
            ],
            vec![0, 1, 2, 3],
            vec![1, 2, 3, 0, 2, 3, 0, 1, 3, 0, 1, 2],
            vec![Dirichlet, Neumann, Neumann, Contact],
        );
        // orientation of this vertex order may be negative: try the swapped order
        let tetrahedron = tetrahedron.or_else(|_| {
            Mesh::<3>::new(
                vec![
                    [1.0, 0.0, -s],
                    [-1.0, 0.0, -s],
                    [0.0, 1.0, s],
                    [0.0, -1.0, s],
                ],
                vec![0, 1, 3, 2],
                vec![1, 2, 3, 0, 2, 3, 0, 1, 3, 0, 1, 2],
                vec![Dirichlet, Neumann, Neumann, Contact],
            )
        });
        assert!((shape_regularity(&tetrahedron.unwrap()) - 1.0).abs() < 1e-14);
    }

    #[test]
    fn flat_cells_have_a_large_measure() {
        let flat = Mesh::<2>::new(
            vec![[0.0, 0.0], [1.0, 0.0], [0.5, 0.01]],
            vec![0, 1, 2],
            vec![0, 1, 1, 2, 2, 0],
            vec![Dirichlet; 3],
        )
        .unwrap();
        // h = 1, |K| = 0.005, perimeter ≈ 2.0001: ρ ≈ 0.005, h/ρ ≈ 200, / 2√3 ≈ 57.7
        let measure = shape_regularity(&flat);
        assert!((measure - 200.01 / 3.4641016).abs() < 0.1, "{measure}");
    }
}
