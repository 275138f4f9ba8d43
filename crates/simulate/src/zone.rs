//! The contact zone of a step from the zero crossing of the interpolated penetration, and the
//! resultant force of the foundation on the body.
//!
//! **Zone.** Normal compliance presses where the penetration r = u_ν − g is positive
//! (p_ν(r) = 0 for r ≤ 0, (2.10)). Counting whole contact nodes overestimates the zone by up to
//! half an element at each end; instead r is interpolated on every facet of Γ3 from its values
//! at the facet's nodes — linearly on the facet (P1), linearly on the two halves of a P2 segment
//! (2D), and on a P2 triangle (3D) linearly through its edge midpoints, the only nodes of a
//! quadratic triangle with contact weight — and the zone is the part of Γ3 where that
//! interpolant is > 0, each (sub-)facet clipped at its zero crossing. Its measure (a length
//! in 2D, an area in 3D) and its extent in the coordinate s of the line of
//! `contact_history.csv` ([`crate::contact_line`]) are reported. r at a node uses the node's frame normal ν_a at contact
//! nodes and the facet normal elsewhere (nodes of Γ3 that carry no contact unknowns: on Γ1, or
//! of zero weight).
//!
//! **Force.** With the nodal contact rule the force of the foundation on the body is
//! F = Σ_a ω_a (−p_ν(a) ν_a − p_τ(a) R_a (0, λ_a)): the normal pressure pushes the body out of the
//! foundation and the friction traction −p_τ λ_a opposes the slip (the multipliers λ_a of
//! (5.1) in the tangent frame R_a of the node). Its moment about a point c is
//! M = Σ_a (x_a − c) × f_a, f_a the nodal force of node a in that sum and x_a its position in
//! the reference configuration (small displacements); in 2D only its z-component is nonzero.

use crate::contact_line::LineCoordinate;
use crate::pictures::ContactRecord;
use contact_damage::fem::mesh::BoundaryPart;
use contact_damage::fem::space::LagrangeSpace;
use contact_damage::model::contact::ContactNodes;
use nalgebra::SVector;

/// Sub-facets (as facet-local node indices) on which the penetration is interpolated linearly.
fn sub_facets(dim: usize, degree: usize) -> &'static [&'static [usize]] {
    match (dim, degree) {
        (2, 1) => &[&[0, 1]],
        // facet nodes v0, v1, m01
        (2, _) => &[&[0, 2], &[2, 1]],
        // the whole facet: at P2 its corner values come from the midpoints
        // ([`corner_values_from_midpoints`])
        _ => &[&[0, 1, 2]],
    }
}

/// The values at the corners v0, v1, v2 of the linear function through the values at the
/// edge midpoints m01, m12, m02 (facet-local nodes 3, 4, 5 of a 6-node triangle): r(v0) =
/// r(m01) + r(m02) − r(m12) and cyclically.
///
/// Why: the nodal weights ∫ φ_a of the quadratic triangle vanish at its vertices, so on a P2
/// face of Γ3 only the edge midpoints carry the contact rule; a vertex, pressed by nothing,
/// may sit on either side of the foundation by more than the midpoints' penetration p/c_ν,
/// and its value says nothing about contact (taking it clipped a 3D P2 zone to about half its
/// area).
fn corner_values_from_midpoints(values: [f64; 6]) -> [f64; 3] {
    let [_, _, _, m01, m12, m02] = values;
    [m01 + m02 - m12, m01 + m12 - m02, m12 + m02 - m01]
}

/// The part of Γ3 where the interpolated penetration is positive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactZone {
    /// Its measure (length in 2D, area in 3D).
    pub measure: f64,
    /// Smallest coordinate s of a point in it (NaN when the zone is empty).
    pub lower: f64,
    /// Largest coordinate s (NaN when empty).
    pub upper: f64,
}

/// The penetration r = u·ν − g at every node of Γ3 (NaN elsewhere), from the nodal displacement
/// `displacement` and the gap `gap(x)`; ν is the frame normal at contact nodes and the facet
/// normal at the other nodes of Γ3.
pub fn boundary_penetration<const D: usize>(
    space: &LagrangeSpace<D>,
    contact: &ContactNodes<D>,
    displacement: &[f64],
    gap: impl Fn(&[f64; D]) -> f64,
) -> Vec<f64> {
    let mesh = space.mesh();
    let mut penetration = vec![f64::NAN; space.num_nodes()];
    for f in 0..mesh.num_facets() {
        if mesh.facet_part(f) != BoundaryPart::Contact {
            continue;
        }
        let facet_normal = SVector::<f64, D>::from(mesh.facet_normal(f));
        for &node in space.facet_nodes(f) {
            if !penetration[node].is_nan() {
                continue;
            }
            let normal = match contact.index_of_node[node] {
                Some(k) => contact.normal(k),
                None => facet_normal,
            };
            let u = SVector::<f64, D>::from_column_slice(&displacement[node * D..node * D + D]);
            penetration[node] = u.dot(&normal) - gap(&space.node(node));
        }
    }
    penetration
}

/// The contact zone {r > 0} of the interpolated penetration `penetration` (nodal, as from
/// [`boundary_penetration`]), with its extent in the coordinate `coordinate`.
pub fn contact_zone<const D: usize>(
    space: &LagrangeSpace<D>,
    penetration: &[f64],
    coordinate: &LineCoordinate,
) -> ContactZone {
    let mesh = space.mesh();
    let mut zone = ContactZone {
        measure: 0.0,
        lower: f64::INFINITY,
        upper: f64::NEG_INFINITY,
    };
    let pieces = sub_facets(D, space.degree());
    for f in 0..mesh.num_facets() {
        if mesh.facet_part(f) != BoundaryPart::Contact {
            continue;
        }
        let nodes = space.facet_nodes(f);
        let from_midpoints = (D == 3 && nodes.len() == 6)
            .then(|| corner_values_from_midpoints(std::array::from_fn(|i| penetration[nodes[i]])));
        for piece in pieces {
            let corners: Vec<(SVector<f64, D>, f64)> = piece
                .iter()
                .map(|&i| {
                    let node = nodes[i];
                    let value = from_midpoints.map_or(penetration[node], |corners| corners[i]);
                    (SVector::from(space.node(node)), value)
                })
                .collect();
            let clipped = positive_part(&corners);
            if clipped.len() < D {
                continue;
            }
            zone.measure += polygon_measure::<D>(&clipped);
            for point in &clipped {
                let s = coordinate.of(point.as_slice());
                zone.lower = zone.lower.min(s);
                zone.upper = zone.upper.max(s);
            }
        }
    }
    if zone.measure == 0.0 {
        zone.lower = f64::NAN;
        zone.upper = f64::NAN;
    }
    zone
}

/// The polygon (segment in 2D) where the linear interpolant of the corner values is > 0: the
/// corners with r > 0 and the zero crossings on the edges whose ends have opposite signs, in
/// boundary order (Sutherland–Hodgman clipping of a simplex by a half-space).
fn positive_part<const D: usize>(corners: &[(SVector<f64, D>, f64)]) -> Vec<SVector<f64, D>> {
    let mut out = Vec::with_capacity(corners.len() + 1);
    let closed = corners.len() > 2;
    let edges = if closed {
        corners.len()
    } else {
        corners.len() - 1
    };
    if !closed && corners[0].1 > 0.0 {
        out.push(corners[0].0);
    }
    for e in 0..edges {
        let (a, ra) = corners[e];
        let (b, rb) = corners[(e + 1) % corners.len()];
        if (ra > 0.0) != (rb > 0.0) {
            let s = ra / (ra - rb);
            out.push(a + (b - a) * s);
        }
        if rb > 0.0 && (closed || e + 1 < corners.len()) {
            out.push(b);
        }
    }
    out
}

/// Length of a segment (2D) or area of a planar polygon (3D).
fn polygon_measure<const D: usize>(points: &[SVector<f64, D>]) -> f64 {
    if D == 2 {
        return (points[points.len() - 1] - points[0]).norm();
    }
    let mut twice_area = SVector::<f64, 3>::zeros();
    let first = points[0];
    for pair in points[1..].windows(2) {
        let u = pair[0] - first;
        let v = pair[1] - first;
        twice_area += SVector::<f64, 3>::new(u[0], u[1], u[2])
            .cross(&SVector::<f64, 3>::new(v[0], v[1], v[2]));
    }
    0.5 * twice_area.norm()
}

/// The resultant of the contact tractions on the body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactResultant<const D: usize> {
    /// F = Σ_a ω_a (−p_ν(a) ν_a − p_τ(a) R_a (0, λ_a)) (Cartesian).
    pub force: SVector<f64, D>,
    /// The magnitude of its friction part |Σ_a ω_a p_τ(a) R_a (0, λ_a)|.
    pub friction: f64,
    /// M = Σ_a (x_a − c) × f_a about the point c (x, y, z; only z in 2D).
    pub moment: [f64; 3],
}

/// The force of the foundation on the body, the magnitude of its friction part, and its
/// moment about `moment_about` (see the module documentation).
pub fn contact_resultant<const D: usize>(
    space: &LagrangeSpace<D>,
    contact: &ContactNodes<D>,
    normal_pressure: &[f64],
    friction_bound: &[f64],
    multipliers: &[f64],
    moment_about: &[f64; D],
) -> ContactResultant<D> {
    let mut normal_part = SVector::<f64, D>::zeros();
    let mut friction_part = SVector::<f64, D>::zeros();
    let mut moment = SVector::<f64, 3>::zeros();
    for (k, frame) in contact.frames.iter().enumerate() {
        let weight = contact.weights[k];
        let normal_force = frame.column(0) * (weight * normal_pressure[k]);
        normal_part -= normal_force;
        let mut friction_force = SVector::<f64, D>::zeros();
        for j in 1..D {
            let term =
                frame.column(j) * (weight * friction_bound[k] * multipliers[k * (D - 1) + j - 1]);
            // accumulated term by term into the resultant, as the sum was always taken
            friction_part -= term;
            friction_force -= term;
        }
        let position = space.node(contact.nodes[k]);
        let lever = embed::<D>(std::array::from_fn(|i| position[i] - moment_about[i]));
        moment += lever.cross(&embed::<D>(std::array::from_fn(|i| {
            friction_force[i] - normal_force[i]
        })));
    }
    ContactResultant {
        force: normal_part + friction_part,
        friction: friction_part.norm(),
        moment: moment.into(),
    }
}

/// A vector of dimension D as a 3-vector (z = 0 in 2D).
fn embed<const D: usize>(vector: [f64; D]) -> SVector<f64, 3> {
    SVector::<f64, 3>::from_fn(|i, _| if i < D { vector[i] } else { 0.0 })
}

/// The peak p0 and the half-width a of the ellipse p0 √(1 − x²/a²) through nodal pressures
/// `(x, p)` along Γ3 (a Hertz profile centred at x = 0): a is the mean of |x| / √(1 − (p/p0)²)
/// over the nodes with 0.2 p0 < p < 0.9 p0 (away from the peak, where the formula divides by a
/// small number, and from the edge, where the mesh resolves the profile worst). None with fewer
/// than two such nodes.
pub fn pressure_ellipse(pressures: &[(f64, f64)]) -> Option<(f64, f64)> {
    let peak = pressures.iter().fold(0.0f64, |m, p| m.max(p.1));
    let widths: Vec<f64> = pressures
        .iter()
        .filter(|(_, p)| *p > 0.2 * peak && *p < 0.9 * peak)
        .map(|(x, p)| x.abs() / (1.0 - (p / peak).powi(2)).sqrt())
        .collect();
    (widths.len() >= 2).then(|| (peak, widths.iter().sum::<f64>() / widths.len() as f64))
}

/// The half-width and the centre of the stick zone of one step along Γ3: half the extent and
/// the midpoint of the loaded (p_ν > 0) sticking nodes among `(s, status, p_ν)`, with the status
/// numbered as in `contact_history.csv` (1 = stick). Node-quantized: within half a node spacing
/// per end. None when no loaded node sticks.
pub fn stick_extent(nodes: impl IntoIterator<Item = (f64, usize, f64)>) -> Option<(f64, f64)> {
    let (low, high) = nodes
        .into_iter()
        .filter(|&(_, status, pressure)| status == 1 && pressure > 0.0)
        .fold(
            (f64::INFINITY, f64::NEG_INFINITY),
            |(low, high), (s, _, _)| (low.min(s), high.max(s)),
        );
    (low <= high).then_some((0.5 * (high - low), 0.5 * (high + low)))
}

/// The contact zone of step `step` of a contact-history profile (`records`, as read by
/// [`crate::pictures::read_contact_history`]), with `origin` subtracted from s so that a contact
/// centred at s = origin is centred at 0: the half-width of its pressure ellipse
/// ([`pressure_ellipse`]; None with fewer than two nodes on it) and its stick zone, half-width
/// and centre ([`stick_extent`]; None when no loaded node sticks).
pub fn profile_zone(
    records: &[ContactRecord],
    step: usize,
    origin: f64,
) -> Option<(f64, Option<(f64, f64)>)> {
    let nodes: Vec<(f64, usize, f64)> = records
        .iter()
        .filter(|record| record.step == step)
        .map(|record| {
            (
                record.coordinate - origin,
                record.status,
                record.normal_pressure,
            )
        })
        .collect();
    let pressures: Vec<(f64, f64)> = nodes.iter().map(|&(s, _, p)| (s, p)).collect();
    let (_, half_width) = pressure_ellipse(&pressures)?;
    Some((half_width, stick_extent(nodes)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::history::tests::unit_square_space;
    use contact_damage::fem::mesh::{BoundaryPart::*, Mesh};
    use std::sync::Arc;

    #[test]
    fn zone_of_a_linear_penetration_ends_at_its_zero_crossing() {
        // Γ3 = {y = 0} of (0, 1) × (0, 2), 3 cells along x; r = 0.4 − x on Γ3 (u = 0, g = x − 0.4)
        for degree in [1, 2] {
            let space = unit_square_space(degree);
            let contact = ContactNodes::new(&space).unwrap();
            let displacement = vec![0.0; space.num_nodes() * 2];
            let r = boundary_penetration(&space, &contact, &displacement, |x| x[0] - 0.4);
            let zone = contact_zone(&space, &r, &LineCoordinate::Axis(0));
            // the clamped corner x = 0 is on Γ3 too: the zone is [0, 0.4]
            assert!((zone.measure - 0.4).abs() < 1e-14, "{zone:?}");
            assert!(zone.lower.abs() < 1e-14 && (zone.upper - 0.4).abs() < 1e-14);
        }
    }

    #[test]
    fn zone_of_a_p2_penetration_uses_the_midpoints() {
        // r = 0.1 at the vertices, −0.1 at the midpoints: a positive sliver at every vertex, of
        // half-width (h/2)/2 on each side; whole nodes would count all of Γ3
        let space = unit_square_space(2);
        let contact = ContactNodes::new(&space).unwrap();
        let displacement = vec![0.0; space.num_nodes() * 2];
        let vertices = space.mesh().num_vertices();
        let mut r = boundary_penetration(&space, &contact, &displacement, |_| 0.0);
        for (node, value) in r.iter_mut().enumerate() {
            if !value.is_nan() {
                *value = if node < vertices { 0.1 } else { -0.1 };
            }
        }
        let zone = contact_zone(&space, &r, &LineCoordinate::Axis(0));
        // 3 cells of h = 1/3: 6 half-sub-segments of length h/4
        assert!(
            (zone.measure - 6.0 * (1.0 / 12.0)).abs() < 1e-14,
            "{zone:?}"
        );
        assert!(zone.lower.abs() < 1e-14 && (zone.upper - 1.0).abs() < 1e-14);
    }

    #[test]
    fn zone_on_a_3d_face_is_the_clipped_area() {
        // unit cube, Γ3 = {z = 0}; r = 0.3 − x: the zone is [0, 0.3] × [0, 1], area 0.3
        let mesh = Mesh::box_mesh(
            [0.0; 3],
            [1.0; 3],
            [3, 2, 2],
            [[Neumann, Neumann], [Dirichlet, Neumann], [Contact, Neumann]],
        )
        .unwrap();
        for degree in [1, 2] {
            let space = LagrangeSpace::new(Arc::new(mesh.clone()), degree).unwrap();
            let contact = ContactNodes::new(&space).unwrap();
            let displacement = vec![0.0; space.num_nodes() * 3];
            let r = boundary_penetration(&space, &contact, &displacement, |x| x[0] - 0.3);
            let zone = contact_zone(&space, &r, &LineCoordinate::Axis(0));
            assert!((zone.measure - 0.3).abs() < 1e-14, "{zone:?}");
            assert!(zone.lower.abs() < 1e-14 && (zone.upper - 0.3).abs() < 1e-14);
        }
    }

    #[test]
    fn zone_on_a_p2_face_ignores_the_vertices_that_carry_no_contact_weight() {
        // r = 0.3 − x at the edge midpoints and r = ±1 alternating at the vertices (unpressed
        // vertices, on either side of the foundation): the zone is that of the midpoints,
        // [0, 0.3] × [0, 1]
        let mesh = Mesh::box_mesh(
            [0.0; 3],
            [1.0; 3],
            [4, 3, 2],
            [[Neumann, Neumann], [Dirichlet, Neumann], [Contact, Neumann]],
        )
        .unwrap();
        let space = LagrangeSpace::new(Arc::new(mesh), 2).unwrap();
        let contact = ContactNodes::new(&space).unwrap();
        let vertices = space.mesh().num_vertices();
        let displacement = vec![0.0; space.num_nodes() * 3];
        let mut r = boundary_penetration(&space, &contact, &displacement, |x| x[0] - 0.3);
        let mut sign = 1.0;
        for value in r.iter_mut().take(vertices) {
            if !value.is_nan() {
                *value = sign;
                sign = -sign;
            }
        }
        let zone = contact_zone(&space, &r, &LineCoordinate::Axis(0));
        assert!((zone.measure - 0.3).abs() < 1e-14, "{zone:?}");
        assert!(zone.lower.abs() < 1e-14 && (zone.upper - 0.3).abs() < 1e-14);
    }

    #[test]
    fn pressure_ellipse_recovers_a_hertz_profile() {
        let (peak, width) = (0.03, 0.045);
        let pressures: Vec<(f64, f64)> = (-40..=40)
            .map(|i| {
                let x = 0.00125 * i as f64;
                (x, peak * (1.0 - (x / width).powi(2)).max(0.0).sqrt())
            })
            .collect();
        let (p0, a) = pressure_ellipse(&pressures).unwrap();
        assert!(
            (p0 - peak).abs() < 1e-15 && (a - width).abs() < 1e-14,
            "{p0} {a}"
        );
        assert_eq!(pressure_ellipse(&[(0.0, 1.0), (0.1, 0.0)]), None);
    }

    #[test]
    fn stick_extent_spans_the_loaded_sticking_nodes() {
        let nodes = [
            (-0.3, 1, 0.0), // sticks without load: not counted
            (-0.2, 2, 1.0),
            (-0.1, 1, 2.0),
            (0.0, 1, 3.0),
            (0.3, 1, 1.0),
            (0.4, 0, 0.0),
        ];
        let (half_width, centre) = stick_extent(nodes).unwrap();
        assert!((half_width - 0.2).abs() < 1e-15 && (centre - 0.1).abs() < 1e-15);
        assert_eq!(stick_extent([(0.0, 2, 1.0)]), None);
    }

    #[test]
    fn profile_zone_reads_one_step_centred_at_its_origin() {
        // a Hertz profile of half-width 0.5 centred at s = 1, sticking on [0.9, 1.1], at step 2;
        // step 1 holds other values that must not enter
        let record = |step, s: f64, status| ContactRecord {
            step,
            time: 0.1 * step as f64,
            coordinate: s,
            status,
            normal_pressure: (1.0 - ((s - 1.0) / 0.5).powi(2)).max(0.0).sqrt(),
            slip_rate: 0.0,
            accumulated_slip: 0.0,
        };
        let mut records: Vec<ContactRecord> = (0..=20)
            .map(|i| record(2, 0.4 + 0.06 * i as f64, 2))
            .map(|r| ContactRecord {
                status: if (r.coordinate - 1.0).abs() <= 0.1 + 1e-12 {
                    1
                } else {
                    2
                },
                ..r
            })
            .collect();
        records.push(ContactRecord {
            normal_pressure: 100.0,
            ..record(1, 1.0, 1)
        });
        let (half_width, stick) = profile_zone(&records, 2, 1.0).unwrap();
        assert!((half_width - 0.5).abs() < 1e-12, "{half_width}");
        let (stick_half_width, centre) = stick.unwrap();
        assert!(stick_half_width > 0.05 && stick_half_width <= 0.1 + 1e-12);
        assert!(centre.abs() < 1e-12, "{centre}");
        assert_eq!(profile_zone(&records, 3, 1.0), None);
    }

    #[test]
    fn empty_zone_has_no_bounds() {
        let space = unit_square_space(1);
        let contact = ContactNodes::new(&space).unwrap();
        let displacement = vec![0.0; space.num_nodes() * 2];
        let r = boundary_penetration(&space, &contact, &displacement, |_| 0.1);
        let zone = contact_zone(&space, &r, &LineCoordinate::Axis(0));
        assert_eq!(zone.measure, 0.0);
        assert!(zone.lower.is_nan() && zone.upper.is_nan());
    }

    #[test]
    fn contact_force_is_the_weighted_sum_of_the_nodal_tractions() {
        // Γ3 = {y = 0}, outward normal (0, −1): pressure p pushes up, friction with λ = 1 along
        // the tangent t_1 pushes against it
        let space = unit_square_space(1);
        let contact = ContactNodes::new(&space).unwrap();
        let count = contact.len();
        let total: f64 = contact.weights.iter().sum();
        let pressure = vec![2.0; count];
        let bound = vec![0.5; count];
        let multipliers = vec![1.0; count];
        let resultant =
            contact_resultant(&space, &contact, &pressure, &bound, &multipliers, &[0.0; 2]);
        let tangent = contact.frames[0].column(1).into_owned();
        let expected = SVector::<f64, 2>::new(0.0, 2.0 * total) - tangent * (0.5 * total);
        let force = resultant.force;
        assert!((force - expected).norm() < 1e-14, "{force} vs {expected}");
        assert!((resultant.friction - 0.5 * total).abs() < 1e-14);
    }

    #[test]
    fn contact_moment_is_the_moment_of_the_nodal_forces() {
        // Γ3 = {z = 0} of the unit cube, outward normal −e_z, a uniform pressure p_ν = 1: the
        // force (0, 0, 1) acts at the centre of the face, so its moment about the origin is
        // ∫ x × (0, 0, 1) = (∫ y, −∫ x, 0) = (1/2, −1/2, 0) and about the centre zero, exactly
        // for the nodal rule (it integrates linear functions exactly at P1 and P2). Any other
        // point c' moves the moment by (c − c') × F, friction included.
        let mesh = Mesh::box_mesh(
            [0.0; 3],
            [1.0; 3],
            [4, 3, 2],
            [[Neumann, Neumann], [Neumann, Neumann], [Contact, Dirichlet]],
        )
        .unwrap();
        for degree in [1, 2] {
            let space = LagrangeSpace::new(Arc::new(mesh.clone()), degree).unwrap();
            let contact = ContactNodes::new(&space).unwrap();
            let pressure = vec![1.0; contact.len()];
            let none = vec![0.0; contact.len()];
            let centre = [0.5, 0.5, 0.0];
            let multipliers = vec![0.0; 2 * contact.len()];
            for (point, expected) in [([0.0; 3], [0.5, -0.5, 0.0]), (centre, [0.0; 3])] {
                let pressed =
                    contact_resultant(&space, &contact, &pressure, &none, &multipliers, &point);
                for (moment, expected) in pressed.moment.iter().zip(expected) {
                    assert!(
                        (moment - expected).abs() < 1e-14,
                        "degree {degree}: {:?}",
                        pressed.moment
                    );
                }
            }
            let pressed =
                contact_resultant(&space, &contact, &pressure, &none, &multipliers, &centre);
            assert!((pressed.force[2] - 1.0).abs() < 1e-14);
            // with friction: the change of point is (c − c') × F
            let bound = vec![0.3; contact.len()];
            // λ_1 = x + y: a friction traction that grows across the face, which turns the body
            let multipliers: Vec<f64> = contact
                .nodes
                .iter()
                .flat_map(|&a| [space.node(a)[0] + space.node(a)[1], 0.2])
                .collect();
            let other = [0.1, -0.4, 0.7];
            let at_centre =
                contact_resultant(&space, &contact, &pressure, &bound, &multipliers, &centre);
            let at_other =
                contact_resultant(&space, &contact, &pressure, &bound, &multipliers, &other);
            let shift = SVector::<f64, 3>::from(std::array::from_fn(|i| centre[i] - other[i]))
                .cross(&at_centre.force);
            for i in 0..3 {
                assert!(
                    (at_other.moment[i] - at_centre.moment[i] - shift[i]).abs() < 1e-14,
                    "degree {degree}"
                );
            }
            assert!(at_centre.moment[2].abs() > 1e-3, "friction turns the body");
        }
    }
}
