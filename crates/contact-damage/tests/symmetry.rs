//! Symmetry planes through the contact zone: a half model (2D) or quarter model (3D) whose
//! planes x = 0 (and y = 0) are rollers cutting Γ3 gives the whole model's solution on a
//! mirror-symmetric mesh, node for node, for P1 and P2, explicit and implicit normal compliance,
//! with friction:
//! - the nodes of Γ3 on a symmetry plane keep the contact rule (their normal displacement is
//!   free, the plane fixes a tangential component of the contact frame);
//! - u_n and β_n of every step agree with the whole model to 1e-9 of their size, and the contact
//!   pressures at the common contact nodes agree (the nodal weights of the cut model are the
//!   halves or quarters of the whole model's, the pressures are pointwise);
//! - the reaction of each plane is the force the other half would exert: the plane's resultant
//!   along its normal balances the half model, its other components vanish.

use crate::common;

use contact_damage::fem::mesh::{BoundaryPart, BoundaryPart::*, Mesh};
use contact_damage::scheme::{ContactTreatment, PrescribedDisplacement, Simulation};
use std::collections::HashMap;
use std::sync::Arc;

/// The mesh reflected across the plane x_axis = 0 and joined to itself: the vertices on the
/// plane are shared, the facets on the plane become interior, the reflected cells are
/// reoriented. The result is symmetric about the plane by construction.
fn mirrored<const D: usize>(mesh: &Mesh<D>, axis: usize) -> Mesh<D> {
    let mut vertices = mesh.vertices().to_vec();
    let mut image = vec![0; vertices.len()];
    for (v, x) in mesh.vertices().iter().enumerate() {
        image[v] = if x[axis] == 0.0 {
            v
        } else {
            let mut y = *x;
            y[axis] = -y[axis];
            vertices.push(y);
            vertices.len() - 1
        };
    }
    let mut cells = Vec::new();
    for c in 0..mesh.num_cells() {
        cells.extend_from_slice(mesh.cell(c));
    }
    for c in 0..mesh.num_cells() {
        let mut cell: Vec<usize> = mesh.cell(c).iter().map(|&v| image[v]).collect();
        cell.swap(0, 1);
        cells.extend(cell);
    }
    let mut facets = Vec::new();
    let mut parts = Vec::new();
    for f in 0..mesh.num_facets() {
        let on_plane = mesh.facet(f).iter().all(|&v| mesh.vertex(v)[axis] == 0.0);
        if on_plane {
            continue;
        }
        facets.extend_from_slice(mesh.facet(f));
        facets.extend(mesh.facet(f).iter().map(|&v| image[v]));
        parts.extend([mesh.facet_part(f); 2]);
    }
    Mesh::new(vertices, cells, facets, parts).unwrap()
}

/// Which model: the cut one (planes through the contact zone as rollers) or the whole one.
#[derive(Clone, Copy, PartialEq)]
enum Model {
    Cut,
    Whole,
}

/// A block pressed by its top face Γ1 (u = (0, …, −0.04 t)) onto a curved obstacle
/// g = 0.3 |x_∥|² under its bottom face Γ3, sides traction free: contact in the middle of Γ3,
/// stick near the centre and slip around it. The cut model is [0, 1]^{D−1} × [0, 1] with the
/// planes x_i = 0 (i < D − 1) as rollers u_i = 0; the whole model its mirror image.
fn block<const D: usize>(
    model: Model,
    cells: usize,
    degree: usize,
    contact: ContactTreatment,
) -> Simulation<D> {
    let vertical = D - 1;
    let mut sides = [[Neumann, Neumann]; D];
    for side in sides.iter_mut().take(vertical) {
        side[0] = Dirichlet;
    }
    sides[vertical] = [Contact, Dirichlet];
    let mut mesh = Mesh::box_mesh([0.0; D], [1.0; D], [cells; D], sides).unwrap();
    if model == Model::Whole {
        for axis in 0..vertical {
            mesh = mirrored(&mesh, axis);
        }
    }
    let top = mesh.boundary_facets_where(|x| x[vertical] == 1.0);
    let mut dirichlet = vec![PrescribedDisplacement {
        name: "top".into(),
        facets: top,
        components: std::array::from_fn(|i| {
            let field: contact_damage::scheme::PointScalarField<D> = if i == vertical {
                Arc::new(|_: &[f64; D], t: f64| -0.04 * t)
            } else {
                Arc::new(|_: &[f64; D], _: f64| 0.0)
            };
            Some(field)
        }),
        traction: None,
    }];
    if model == Model::Cut {
        for axis in 0..vertical {
            dirichlet.push(PrescribedDisplacement {
                name: format!("symmetry {axis}"),
                facets: mesh.boundary_facets_where(|x| x[axis] == 0.0),
                components: std::array::from_fn(|i| {
                    (i == axis).then(|| {
                        let zero: contact_damage::scheme::PointScalarField<D> =
                            Arc::new(|_: &[f64; D], _: f64| 0.0);
                        zero
                    })
                }),
                traction: None,
            });
        }
    }
    let mut data = common::quiet_data::<D>();
    data.dirichlet = dirichlet;
    data.gap = Arc::new(move |x: &[f64; D], _: f64| {
        0.3 * x[..vertical].iter().map(|c| c * c).sum::<f64>()
    });
    let mut problem = common::problem(mesh, degree, data, 1.0, 3);
    problem.settings.contact = contact;
    Simulation::new(problem).unwrap()
}

/// Runs the cut and the whole model step by step and compares them at the nodes of the cut
/// model: u and β relative to their largest value, the contact pressures at the common contact
/// nodes, and the contact set on the planes.
fn assert_cut_model_is_the_whole_model<const D: usize>(
    cells: usize,
    degree: usize,
    contact: ContactTreatment,
) {
    let mut cut = block::<D>(Model::Cut, cells, degree, contact);
    let mut whole = block::<D>(Model::Whole, cells, degree, contact);
    let key = |x: [f64; D]| x.map(|c| (c * 1e9).round() as i64);
    let whole_node: HashMap<[i64; D], usize> = (0..whole.space().num_nodes())
        .map(|node| (key(whole.space().node(node)), node))
        .collect();
    let pairs: Vec<(usize, usize)> = (0..cut.space().num_nodes())
        .map(|node| (node, whole_node[&key(cut.space().node(node))]))
        .collect();
    // the contact nodes of Γ3 on a symmetry plane are contact nodes of the cut model
    let on_plane = |x: &[f64; D]| x[D - 1] == 0.0 && x[..D - 1].contains(&0.0);
    let plane_nodes: Vec<usize> = (0..cut.space().num_nodes())
        .filter(|&node| on_plane(&cut.space().node(node)))
        .filter(|&node| whole.contact().index_of_node[pairs[node].1].is_some())
        .collect();
    assert!(!plane_nodes.is_empty());
    for &node in &plane_nodes {
        assert!(
            cut.contact().index_of_node[node].is_some(),
            "node {node} at {:?} on a symmetry plane left Γ3",
            cut.space().node(node)
        );
    }
    let mut pressed_on_plane = 0;
    for _ in 0..cut.steps() {
        let cut_outcome = cut.step().unwrap();
        let whole_outcome = whole.step().unwrap();
        assert!(cut_outcome.velocity.stats.kkt_residual < 1e-9);
        let (u_cut, u_whole) = (&cut.state().displacement, &whole.state().displacement);
        let scale = u_whole.iter().fold(0.0f64, |m, u| m.max(u.abs()));
        for &(a, b) in &pairs {
            for i in 0..D {
                let difference = (u_cut[a * D + i] - u_whole[b * D + i]).abs();
                assert!(
                    difference <= 1e-9 * scale,
                    "u_{i} at {:?}: cut {} whole {} (scale {scale:e})",
                    cut.space().node(a),
                    u_cut[a * D + i],
                    u_whole[b * D + i]
                );
            }
            let (beta_cut, beta_whole) = (cut.state().damage[a], whole.state().damage[b]);
            assert!(
                (beta_cut - beta_whole).abs() <= 1e-9,
                "β at {:?}: {beta_cut} vs {beta_whole}",
                cut.space().node(a)
            );
        }
        let pressure_scale = whole_outcome
            .normal_pressure
            .iter()
            .fold(0.0f64, |m, p| m.max(p.abs()));
        for (k, &node) in cut.contact().nodes.iter().enumerate() {
            let w = whole.contact().index_of_node[pairs[node].1].unwrap();
            let (p_cut, p_whole) = (
                cut_outcome.normal_pressure[k],
                whole_outcome.normal_pressure[w],
            );
            assert!(
                (p_cut - p_whole).abs() <= 1e-9 * pressure_scale,
                "p_ν at {:?}: cut {p_cut} whole {p_whole}",
                cut.space().node(node)
            );
            if plane_nodes.contains(&node) && p_cut > 0.0 {
                pressed_on_plane += 1;
            }
        }
    }
    assert!(
        pressed_on_plane > 0,
        "no node on a symmetry plane was pressed"
    );
}

#[test]
fn half_model_with_a_symmetry_plane_through_the_contact_zone_is_the_whole_model_2d() {
    for degree in [1, 2] {
        assert_cut_model_is_the_whole_model::<2>(8, degree, ContactTreatment::Explicit);
        assert_cut_model_is_the_whole_model::<2>(8, degree, ContactTreatment::Implicit);
    }
}

#[test]
fn quarter_model_with_two_symmetry_planes_through_the_contact_zone_is_the_whole_model_3d() {
    for degree in [1, 2] {
        assert_cut_model_is_the_whole_model::<3>(3, degree, ContactTreatment::Implicit);
    }
    assert_cut_model_is_the_whole_model::<3>(4, 1, ContactTreatment::Explicit);
}

#[test]
fn a_clamped_node_of_the_contact_boundary_leaves_it_and_a_roller_keeps_it() {
    // the corner (0, 0) of Γ3: clamped (every component) it leaves Γ3; on a roller fixing u_x
    // (tangential to Γ3) it stays; on a roller fixing u_y (the normal displacement) it leaves
    for (components, stays) in [
        ([true, true], false),
        ([true, false], true),
        ([false, true], false),
    ] {
        let mesh = Mesh::box_mesh(
            [0.0, 0.0],
            [1.0, 1.0],
            [4, 4],
            [[Dirichlet, Neumann], [Contact, Neumann]],
        )
        .unwrap();
        let space = contact_damage::fem::space::LagrangeSpace::new(Arc::new(mesh), 1).unwrap();
        let mut constrained = vec![false; space.num_nodes() * 2];
        for node in space.boundary_nodes(BoundaryPart::Dirichlet) {
            constrained[node * 2] = components[0];
            constrained[node * 2 + 1] = components[1];
        }
        let contact =
            contact_damage::model::contact::ContactNodes::with_constraints(&space, &constrained)
                .unwrap();
        let corner = (0..space.num_nodes())
            .find(|&node| space.node(node) == [0.0, 0.0])
            .unwrap();
        assert_eq!(
            contact.index_of_node[corner].is_some(),
            stays,
            "fixed components {components:?}"
        );
        if stays {
            let k = contact.index_of_node[corner].unwrap();
            let frame = contact.frames[k];
            assert_eq!(frame.column(0).as_slice(), &[0.0, -1.0]);
            assert_eq!(frame[(0, 1)].abs(), 1.0);
        }
    }
}
