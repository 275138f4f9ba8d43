use super::*;
use crate::fem::mesh::BoundaryPart::{self, Contact, Dirichlet, Neumann};
use crate::fem::quality::shape_regularity;
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

/// The meshes of the built-in cases on Gmsh meshes (unstructured, tilted contact boundary).
const TILTED2D: &[u8] = include_bytes!("../../../../../verification/meshes/tilted2d.msh");
const TILTED3D: &[u8] = include_bytes!("../../../../../verification/meshes/tilted3d.msh");

fn groups() -> crate::io::gmsh::PhysicalMap {
    crate::io::gmsh::PhysicalMap::by_names(&["clamped"], &["traction"], &["contact"])
}

/// The facets of one physical group: the Γ1 facets of the file read with that group alone
/// as Γ1 (the reader keeps the order of the facets).
fn group_facets<const D: usize>(bytes: &[u8], group: &str) -> Vec<usize> {
    let others: Vec<&str> = ["clamped", "traction", "contact"]
        .into_iter()
        .filter(|g| *g != group)
        .collect();
    let map = crate::io::gmsh::PhysicalMap::by_names(&[group], &others, &[]);
    let mesh = crate::io::gmsh::parse_msh_bytes::<D>(bytes, "tilted.msh", &map).unwrap();
    (0..mesh.num_facets())
        .filter(|&f| mesh.facet_part(f) == Dirichlet)
        .collect()
}

/// Refinement of a Gmsh mesh keeps its physical groups: every level passes the mesh validity
/// checks, each group's facets map to the children (same part, same measure), and the
/// tetrahedra stay shape-regular.
fn check_gmsh_levels<const D: usize>(bytes: &[u8]) {
    let coarse = crate::io::gmsh::parse_msh_bytes::<D>(bytes, "tilted.msh", &groups()).unwrap();
    check_levels(&coarse);
    let q0 = shape_regularity(&coarse);
    let mut level = coarse.clone();
    let mut facets: Vec<(&str, Vec<usize>)> = ["clamped", "traction", "contact"]
        .into_iter()
        .map(|g| (g, group_facets::<D>(bytes, g)))
        .collect();
    let group_measure = |mesh: &Mesh<D>, facets: &[usize]| -> f64 {
        facets.iter().map(|&f| mesh.facet_measure(f)).sum()
    };
    let measures: Vec<f64> = facets
        .iter()
        .map(|(_, f)| group_measure(&coarse, f))
        .collect();
    for _ in 0..2 {
        level = refine_uniform(&level).unwrap();
        for ((name, group), measure) in facets.iter_mut().zip(&measures) {
            let part = level.facet_part(group[0] << (D - 1));
            *group = refined_facets::<D>(group);
            assert!(group.iter().all(|&f| level.facet_part(f) == part), "{name}");
            let refined = group_measure(&level, group);
            assert!(
                (refined - measure).abs() < 1e-12 * measure,
                "{name}: {refined} vs {measure}"
            );
        }
        assert!(shape_regularity(&level) <= 2.0 * q0);
    }
}

#[test]
fn refinement_of_gmsh_meshes_keeps_the_physical_groups() {
    check_gmsh_levels::<2>(TILTED2D);
    check_gmsh_levels::<3>(TILTED3D);
}
