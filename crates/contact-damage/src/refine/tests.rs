use super::*;
use crate::mesh::BoundaryPart::{self, Contact, Dirichlet, Neumann};
use crate::quality::shape_regularity;
use std::collections::BTreeSet;

fn square() -> Mesh<2> {
    Mesh::box_mesh(
        [0.0, -1.0],
        [2.0, 0.5],
        [3, 2],
        [[Dirichlet, Neumann], [Contact, Neumann]],
    )
    .unwrap()
}

fn brick() -> Mesh<3> {
    Mesh::box_mesh(
        [0.0, -1.0, 0.5],
        [2.0, 0.5, 1.5],
        [2, 3, 2],
        [[Dirichlet, Neumann], [Neumann, Contact], [Contact, Neumann]],
    )
    .unwrap()
}

/// An irregular tetrahedral mesh: the brick's interior vertices moved off the lattice.
fn skewed_brick() -> Mesh<3> {
    let mesh = Mesh::box_mesh(
        [0.0; 3],
        [1.0; 3],
        [2, 2, 2],
        [[Dirichlet, Neumann], [Neumann, Neumann], [Contact, Neumann]],
    )
    .unwrap();
    let vertices = mesh
        .vertices()
        .iter()
        .map(|x| {
            if x.iter().all(|&c| c > 0.0 && c < 1.0) {
                [x[0] + 0.13, x[1] - 0.08, x[2] + 0.11]
            } else {
                *x
            }
        })
        .collect();
    let cells = (0..mesh.num_cells())
        .flat_map(|c| mesh.cell(c).to_vec())
        .collect();
    let facets = (0..mesh.num_facets())
        .flat_map(|f| mesh.facet(f).to_vec())
        .collect();
    let parts = (0..mesh.num_facets()).map(|f| mesh.facet_part(f)).collect();
    Mesh::new(vertices, cells, facets, parts).unwrap()
}

fn volume<const D: usize>(mesh: &Mesh<D>) -> f64 {
    (0..mesh.num_cells()).map(|c| mesh.cell_volume(c)).sum()
}

fn part_measure<const D: usize>(mesh: &Mesh<D>, part: BoundaryPart) -> f64 {
    (0..mesh.num_facets())
        .filter(|&f| mesh.facet_part(f) == part)
        .map(|f| mesh.facet_measure(f))
        .sum()
}

fn edges<const D: usize>(mesh: &Mesh<D>) -> usize {
    let mut edges = BTreeSet::new();
    for c in 0..mesh.num_cells() {
        let cell = mesh.cell(c);
        for i in 0..=D {
            for j in i + 1..=D {
                edges.insert((cell[i].min(cell[j]), cell[i].max(cell[j])));
            }
        }
    }
    edges.len()
}

/// Everything a refinement must keep, checked on three levels.
fn check_levels<const D: usize>(mesh: &Mesh<D>) {
    let mut coarse = mesh.clone();
    for level in 1..=3 {
        let fine = refine_uniform(&coarse).unwrap();
        // node, cell and facet counts: one new vertex per edge
        assert_eq!(fine.num_vertices(), coarse.num_vertices() + edges(&coarse));
        assert_eq!(fine.num_cells(), coarse.num_cells() << D);
        assert_eq!(fine.num_facets(), coarse.num_facets() << (D - 1));
        // every cell positive; the volume and the parts' measures kept
        assert!((0..fine.num_cells()).all(|c| fine.cell_volume(c) > 0.0));
        // (exact up to the rounding of the midpoints and of the sums over the cells)
        let rounding = 4.0 * f64::EPSILON * fine.num_cells() as f64;
        let (v0, v1) = (volume(&coarse), volume(&fine));
        assert!(
            (v1 - v0).abs() <= rounding * v0,
            "level {level}: {v1} vs {v0}"
        );
        for part in [Dirichlet, Neumann, Contact] {
            let (m0, m1) = (part_measure(&coarse, part), part_measure(&fine, part));
            assert!(
                (m1 - m0).abs() <= rounding * m0.max(1.0),
                "{part:?}: {m1} vs {m0}"
            );
        }
        // each facet's children carry its part, lie on it and cover it
        for f in 0..coarse.num_facets() {
            let normal = coarse.facet_normal(f);
            let mut measure = 0.0;
            for child in facet_children::<D>(f) {
                assert_eq!(fine.facet_part(child), coarse.facet_part(f));
                let n = fine.facet_normal(child);
                assert!(
                    (0..D).all(|i| (n[i] - normal[i]).abs() < 1e-12),
                    "{n:?} vs {normal:?}"
                );
                measure += fine.facet_measure(child);
            }
            assert!((measure - coarse.facet_measure(f)).abs() < 1e-14);
        }
        // the coarse vertices keep their indices, h halves
        assert_eq!(&fine.vertices()[..coarse.num_vertices()], coarse.vertices());
        assert!(
            (fine.max_cell_diameter() - 0.5 * coarse.max_cell_diameter()).abs() < 1e-14 || D == 3,
            "2D: similar triangles"
        );
        coarse = fine;
    }
}

#[test]
fn refined_triangles_keep_volume_parts_and_counts() {
    check_levels(&square());
}

#[test]
fn refined_tetrahedra_keep_volume_parts_and_counts() {
    check_levels(&brick());
    check_levels(&skewed_brick());
}

#[test]
fn refined_triangles_are_similar_to_their_parents() {
    let mesh = square();
    let fine = refine_times(&mesh, 2).unwrap();
    assert!((shape_regularity(&fine) - shape_regularity(&mesh)).abs() < 1e-12);
    assert!((fine.max_cell_diameter() - 0.25 * mesh.max_cell_diameter()).abs() < 1e-15);
}

#[test]
fn tetrahedra_stay_shape_regular_over_three_refinements() {
    for mesh in [brick(), skewed_brick()] {
        let q0 = shape_regularity(&mesh);
        let mut level = mesh.clone();
        let mut qualities = vec![q0];
        for _ in 0..3 {
            level = refine_uniform(&level).unwrap();
            qualities.push(shape_regularity(&level));
        }
        // bounded by a modest multiple of the coarse mesh's measure, and no longer growing
        // from level 2 to 3 (the shortest-diagonal rule reaches its set of shapes)
        assert!(qualities.iter().all(|&q| q <= 2.0 * q0), "{qualities:?}");
        assert!(qualities[3] <= qualities[2] * (1.0 + 1e-9), "{qualities:?}");
    }
}

#[test]
fn refined_facets_follow_their_parents() {
    assert_eq!(refined_facets::<2>(&[0, 3]), vec![0, 1, 6, 7]);
    assert_eq!(refined_facets::<3>(&[1]), vec![4, 5, 6, 7]);
    let mesh = refine_times(&square(), 0).unwrap();
    assert_eq!(mesh.num_cells(), square().num_cells());
}
