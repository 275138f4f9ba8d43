//! Curved P2 cells (isoparametric): a Gmsh second-order mesh of the half disc
//! {x² + y² ≤ 1, y ≤ 0} whose arc is Γ3, read, refined and integrated on.

use contact_damage::fem::mesh::{refine_times, BoundaryPart, Mesh};
use contact_damage::fem::quadrature::QuadratureRule;
use contact_damage::fem::space::{FacetRule, LagrangeSpace, Tabulation};
use contact_damage::io::gmsh::{parse_msh, GroupRef, PhysicalMap};
use contact_damage::model::contact::ContactNodes;
use std::f64::consts::PI;
use std::sync::Arc;

const HALF_DISC: &str = include_str!("../../../verification/meshes/curved2d.msh");

fn half_disc() -> Mesh<2> {
    let map = PhysicalMap::by_names(&["clamped"], &[], &["contact"]);
    parse_msh(HALF_DISC, "curved2d.msh", &map).expect("the half disc reads")
}

/// ∫_Ω 1 dx and ∫_Γ3 1 ds of a space, by its quadrature (rules of degree 4).
fn measures<const D: usize>(space: &LagrangeSpace<D>) -> (f64, f64) {
    let tabulation = Tabulation::cell_rule(space.element(), &QuadratureRule::<D>::simplex(4));
    let mut volume = 0.0;
    for c in 0..space.mesh().num_cells() {
        for (xi, w) in tabulation.points.iter().zip(&tabulation.weights) {
            volume += w * space.geometry_at(c, xi).det;
        }
    }
    let rule = FacetRule::new(D, 4);
    let mesh = space.mesh();
    let boundary = (0..mesh.num_facets())
        .filter(|&f| mesh.facet_part(f) == BoundaryPart::Contact)
        .flat_map(|f| space.facet_quadrature(f, &rule))
        .map(|p| p.weight * p.measure)
        .sum();
    (volume, boundary)
}

/// The edge nodes of the arc are on the circle, the P2 area and arc are those of the
/// piecewise quadratic arc (far closer to π/2 and π than the straight ones), and uniform
/// refinement keeps them (the children carry the parent's map).
#[test]
fn second_order_mesh_keeps_its_curved_geometry_under_refinement() {
    let mesh = half_disc();
    assert!(mesh.has_curved_edges());
    let space = LagrangeSpace::new(Arc::new(mesh.clone()), 2).unwrap();
    for &node in &space.boundary_nodes(BoundaryPart::Contact) {
        let x = space.node(node);
        let radius = x[0].hypot(x[1]);
        assert!(
            (radius - 1.0).abs() < 1e-12,
            "node {node} at {x:?}, r = {radius}"
        );
    }
    let (area, arc) = measures(&space);
    let straight = LagrangeSpace::new(Arc::new(mesh.clone()), 1).unwrap();
    let (straight_area, straight_arc) = measures(&straight);
    assert!((area - PI / 2.0).abs() < 0.02 * (straight_area - PI / 2.0).abs());
    assert!((arc - PI).abs() < 0.02 * (straight_arc - PI).abs());
    for times in 1..=2 {
        let refined = refine_times(&mesh, times).unwrap();
        let space = LagrangeSpace::new(Arc::new(refined), 2).unwrap();
        let (refined_area, refined_arc) = measures(&space);
        // det J is a polynomial the rule integrates exactly; the arc's |dx/dt| is the square
        // root of one, integrated to about 1e-7 by the degree-4 rule on either level
        assert!(
            (refined_area - area).abs() < 1e-13 && (refined_arc - arc).abs() < 1e-6,
            "refined {times}×: area {refined_area} (was {area}), arc {refined_arc} (was {arc})"
        );
    }
}

/// The isoparametric P2 space reproduces affine fields on curved cells: the interpolant of
/// u(x) = B x + c has the gradient B at every quadrature point of every cell (the patch test).
#[test]
fn isoparametric_p2_reproduces_affine_fields() {
    let space = LagrangeSpace::new(Arc::new(refine_times(&half_disc(), 1).unwrap()), 2).unwrap();
    assert!(space.has_curved_cells());
    let b = [[0.3, -1.2], [2.0, 0.7]];
    let nodal = space.interpolate_vector(|x| {
        [
            b[0][0] * x[0] + b[0][1] * x[1] + 0.5,
            b[1][0] * x[0] + b[1][1] * x[1] - 1.0,
        ]
    });
    let tabulation = Tabulation::cell_rule(space.element(), &QuadratureRule::<2>::simplex(4));
    for c in 0..space.mesh().num_cells() {
        for q in 0..tabulation.len() {
            let (_, gradient) = space.eval_vector_tabulated(c, &tabulation, q, &nodal);
            for i in 0..2 {
                for j in 0..2 {
                    assert!(
                        (gradient[(i, j)] - b[i][j]).abs() < 1e-12,
                        "cell {c}, point {q}: ∇u = {gradient}"
                    );
                }
            }
        }
    }
}

/// The contact nodes of the arc carry the circle's normal (x, y) to the accuracy of the P2 arc,
/// and their weights add up to the arc's length (all nodes of Γ3 kept, the corners on Γ1
/// included).
#[test]
fn curved_contact_nodes_have_the_circle_normal() {
    let space = LagrangeSpace::new(Arc::new(refine_times(&half_disc(), 1).unwrap()), 2).unwrap();
    let free = vec![false; space.num_nodes() * 2];
    let contact = ContactNodes::with_constraints(&space, &free).unwrap();
    let (_, arc) = measures(&space);
    let total: f64 = contact.weights.iter().sum();
    // the weights take the facet rule of degree l = 2, the arc that of degree 4: both
    // integrate |dx/dt| (not a polynomial) to a few 1e-6
    assert!((total - arc).abs() < 1e-5, "weights {total}, arc {arc}");
    let mut worst: f64 = 0.0;
    for k in 0..contact.len() {
        let x = space.node(contact.nodes[k]);
        let normal = contact.normal(k);
        worst = worst.max((normal[0] - x[0]).hypot(normal[1] - x[1]));
    }
    assert!(worst < 2e-3, "normal off the circle's by {worst}");
}

/// A second-order triangle whose edge node is pulled across the opposite vertex is refused,
/// naming the curved cell.
#[test]
fn gmsh_reader_rejects_an_inverted_curved_triangle() {
    let text = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n\
        $Entities\n0 1 1 0\n1 0 0 0 1 0 0 1 1 0\n1 0 0 0 1 1 0 0 1 1\n$EndEntities\n\
        $Nodes\n2 6 1 6\n1 1 0 3\n1\n2\n3\n0 0 0\n1 0 0\n0 1 0\n2 1 0 3\n4\n5\n6\n\
        0.5 1.2 0\n0.5 0.5 0\n0 0.5 0\n$EndNodes\n\
        $Elements\n2 4 1 4\n1 1 1 3\n1 1 2\n2 2 3\n3 3 1\n2 1 9 1\n4 1 2 3 4 5 6\n$EndElements\n";
    let map = PhysicalMap {
        dirichlet: vec![GroupRef::Tag(1)],
        ..PhysicalMap::default()
    };
    let error = parse_msh::<2>(text, "bent.msh", &map)
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("bent.msh") && error.contains("curved cell 0") && error.contains("inverted"),
        "{error}"
    );
}

const OCTANT: &str = include_str!("meshes/octant_p2.msh");

/// The octant of the unit ball from 10-node tetrahedra: the sphere's edge nodes are read onto
/// the right edges (Gmsh's edge order differs from the element's), so that the P2 volume and
/// sphere area are those of a piecewise quadratic sphere — far closer to π/6 and π/2 than the
/// straight ones — kept by refinement, and affine fields are reproduced exactly.
#[test]
fn ten_node_tetrahedra_map_the_sphere_isoparametrically() {
    let map = PhysicalMap::by_names(&["planes"], &[], &["sphere"]);
    let mesh = parse_msh::<3>(OCTANT, "octant_p2.msh", &map).expect("the octant reads");
    let space = LagrangeSpace::new(Arc::new(mesh.clone()), 2).unwrap();
    for &node in &space.boundary_nodes(BoundaryPart::Contact) {
        let x = space.node(node);
        let radius = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
        assert!(
            (radius - 1.0).abs() < 1e-12,
            "node {node} at {x:?}, r = {radius}"
        );
    }
    let (volume, area) = measures(&space);
    let (straight_volume, straight_area) =
        measures(&LagrangeSpace::new(Arc::new(mesh.clone()), 1).unwrap());
    assert!((volume - PI / 6.0).abs() < 0.05 * (straight_volume - PI / 6.0).abs());
    assert!((area - PI / 2.0).abs() < 0.05 * (straight_area - PI / 2.0).abs());
    let refined = LagrangeSpace::new(Arc::new(refine_times(&mesh, 1).unwrap()), 2).unwrap();
    let (refined_volume, refined_area) = measures(&refined);
    // det J is a polynomial of degree 3 (exact); the area density is not (see the 2D test)
    assert!(
        (refined_volume - volume).abs() < 1e-13,
        "{refined_volume} vs {volume}"
    );
    assert!(
        (refined_area - area).abs() < 1e-5,
        "{refined_area} vs {area}"
    );
    let nodal = refined.interpolate_vector(|x| {
        [
            x[0] - 2.0 * x[2] + 0.1,
            0.5 * x[1] + x[2],
            3.0 * x[0] - x[1],
        ]
    });
    let expected = [[1.0, 0.0, -2.0], [0.0, 0.5, 1.0], [3.0, -1.0, 0.0]];
    for c in 0..refined.mesh().num_cells() {
        let (_, gradient) = refined.eval_vector(c, &[0.2, 0.3, 0.1], &nodal);
        for (i, row) in expected.iter().enumerate() {
            for (j, value) in row.iter().enumerate() {
                assert!(
                    (gradient[(i, j)] - value).abs() < 1e-11,
                    "cell {c}: ∇u = {gradient}"
                );
            }
        }
    }
}
