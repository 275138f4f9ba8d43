//! The line of Γ3 whose contact history is recorded in `contact_history.csv` (and drawn in
//! `contact_history.svg`), with the coordinate s along it.
//!
//! - **Default**: in 2D every contact node, s the coordinate axis along which they spread
//!   most; in 3D the contact nodes of a band across the middle of the face — those whose other
//!   in-plane coordinate lies within half a node spacing (the median edge length of the Γ3
//!   facets over the degree) of the node coordinate nearest the middle. On a box mesh that is
//!   one grid line, on an unstructured mesh about one node per spacing along the face.
//! - **A profile line** (`output.profile = { from, to, width }`): the contact nodes within
//!   `width` (default half a node spacing) of the segment from `from` to `to`, s = (x − from)·e
//!   with e the unit vector from `from` to `to` — e.g. a radius of a Hertz contact from its
//!   centre, on any mesh. A segment that no contact node lies near is an error.
//!
//! In 3D at P2 the vertices of the quadratic faces of Γ3 are left out of both: they carry no
//! contact weight on flat faces and almost none on curved ones, so their p_ν is no traction.
//!
//! s also measures the extent of the contact zone (`zone_min`, `zone_max` of `history.csv`).

use contact_damage::fem::mesh::BoundaryPart;
use contact_damage::fem::space::LagrangeSpace;
use contact_damage::model::contact::{ContactNodes, ContactStatus};

/// Whether the contact node `node` is recorded on a line: not a vertex of a quadratic face in
/// 3D. Those carry no contact weight on a flat face (and are no contact nodes) and almost none
/// on a curved one, so their p_ν(u_ν − g) is no traction: the displacement there is held by the
/// body alone (the contact zone ignores them too, see [`crate::zone`]).
fn carries_pressure<const D: usize>(space: &LagrangeSpace<D>, node: usize) -> bool {
    D < 3 || space.degree() < 2 || node >= space.mesh().num_vertices()
}

/// Names of the coordinate axes.
pub(crate) const AXIS_NAMES: [&str; 3] = ["x", "y", "z"];

/// Index of the coordinate in which `points` spread least (`smallest = true`) or most.
pub(crate) fn axis_of_spread<const D: usize>(
    points: &[[f64; D]],
    smallest: bool,
    among: &[usize],
) -> usize {
    let spread = |axis: usize| {
        let (low, high) = points
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |acc, p| {
                (acc.0.min(p[axis]), acc.1.max(p[axis]))
            });
        high - low
    };
    let mut best = among[0];
    for &axis in &among[1..] {
        let better = if smallest {
            spread(axis) < spread(best)
        } else {
            spread(axis) > spread(best)
        };
        if better {
            best = axis;
        }
    }
    best
}

/// The typical distance between neighbouring nodes of Γ3: the median length of the edges of its
/// facets divided by the degree (P2 puts a node in the middle of every edge).
fn contact_node_spacing<const D: usize>(space: &LagrangeSpace<D>) -> f64 {
    let mesh = space.mesh();
    let mut lengths = Vec::new();
    for f in 0..mesh.num_facets() {
        if mesh.facet_part(f) != BoundaryPart::Contact {
            continue;
        }
        let vertices = mesh.facet(f);
        for (i, &a) in vertices.iter().enumerate() {
            for &b in &vertices[i + 1..] {
                let (p, q) = (mesh.vertex(a), mesh.vertex(b));
                lengths.push((0..D).map(|j| (p[j] - q[j]).powi(2)).sum::<f64>().sqrt());
            }
        }
    }
    if lengths.is_empty() {
        return 0.0;
    }
    lengths.sort_by(f64::total_cmp);
    lengths[lengths.len() / 2] / space.degree() as f64
}

/// `value` with four significant digits, for labels.
fn significant(value: f64) -> String {
    format!("{}", format!("{value:.3e}").parse::<f64>().unwrap_or(value))
}

/// A point written with four significant digits per coordinate, e.g. `(0, 0.5, 0)`.
fn point_label(point: &[f64]) -> String {
    let coordinates: Vec<String> = point.iter().map(|&x| significant(x)).collect();
    format!("({})", coordinates.join(", "))
}

/// A user-chosen profile line (`output.profile`): the segment from `from` to `to` and the
/// distance `width` from it within which contact nodes are recorded (None: half a node
/// spacing of Γ3).
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileSegment<const D: usize> {
    /// Start of the segment, where s = 0.
    pub from: [f64; D],
    /// End of the segment (≠ `from`).
    pub to: [f64; D],
    /// Largest distance of a recorded node from the segment (> 0).
    pub width: Option<f64>,
}

/// The coordinate s of a point along the recorded line.
#[derive(Debug, Clone, PartialEq)]
pub enum LineCoordinate {
    /// s = x_axis, a coordinate of the point.
    Axis(usize),
    /// s = (x − origin)·direction, `direction` a unit vector.
    Along {
        /// The point where s = 0.
        origin: Vec<f64>,
        /// The unit direction of s.
        direction: Vec<f64>,
    },
}

impl LineCoordinate {
    /// s at `point`.
    pub fn of(&self, point: &[f64]) -> f64 {
        match self {
            Self::Axis(axis) => point[*axis],
            Self::Along { origin, direction } => point
                .iter()
                .zip(origin)
                .zip(direction)
                .map(|((x, o), e)| (x - o) * e)
                .sum(),
        }
    }
}

/// The contact nodes whose history is recorded, in the order of their coordinate along Γ3.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactLine {
    /// Indices k into the contact nodes (`ContactNodes::nodes[k]`), sorted by `coordinates`.
    pub indices: Vec<usize>,
    /// Their coordinate s along Γ3.
    pub coordinates: Vec<f64>,
    /// What s is.
    pub coordinate: LineCoordinate,
    /// What s is, for the picture, e.g. `x on Γ3 (y = 0.5 ± 0.0625)`.
    pub description: String,
}

impl ContactLine {
    /// The default line of contact nodes of `contact`: all of them in 2D, a band across the
    /// middle of the face in 3D (see the module documentation).
    pub fn new<const D: usize>(space: &LagrangeSpace<D>, contact: &ContactNodes<D>) -> Self {
        let points: Vec<[f64; D]> = contact.nodes.iter().map(|&a| space.node(a)).collect();
        if points.is_empty() {
            return Self {
                indices: Vec::new(),
                coordinates: Vec::new(),
                coordinate: LineCoordinate::Axis(0),
                description: "Γ3 (no contact nodes)".into(),
            };
        }
        let all: Vec<usize> = (0..D).collect();
        let normal = axis_of_spread(&points, true, &all);
        let in_plane: Vec<usize> = all.iter().copied().filter(|&i| i != normal).collect();
        let axis = axis_of_spread(&points, false, &in_plane);
        let mut description = format!("{} on Γ3", AXIS_NAMES[axis]);
        let mut indices: Vec<usize> = (0..points.len())
            .filter(|&k| carries_pressure(space, contact.nodes[k]))
            .collect();
        if D == 3 {
            let across = in_plane[0] + in_plane[1] - axis;
            let (low, high) = points
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |acc, p| {
                    (acc.0.min(p[across]), acc.1.max(p[across]))
                });
            let middle = 0.5 * (low + high);
            let nearest = points
                .iter()
                .map(|p| p[across])
                .min_by(|a, b| (a - middle).abs().total_cmp(&(b - middle).abs()))
                .unwrap_or(middle);
            let half_width = 0.5 * contact_node_spacing(space);
            indices.retain(|&k| (points[k][across] - nearest).abs() < half_width);
            description = format!(
                "{description} ({} = {} ± {})",
                AXIS_NAMES[across],
                significant(nearest),
                significant(half_width)
            );
        }
        Self::sorted(&points, indices, LineCoordinate::Axis(axis), description)
    }

    /// The contact nodes of `contact` within the width of `segment` (see the module
    /// documentation); the error says that none is, with the segment and the width.
    pub fn along<const D: usize>(
        space: &LagrangeSpace<D>,
        contact: &ContactNodes<D>,
        segment: &ProfileSegment<D>,
    ) -> Result<Self, String> {
        let points: Vec<[f64; D]> = contact.nodes.iter().map(|&a| space.node(a)).collect();
        let width = segment
            .width
            .unwrap_or_else(|| 0.5 * contact_node_spacing(space));
        let chord: [f64; D] = std::array::from_fn(|i| segment.to[i] - segment.from[i]);
        let length = chord.iter().map(|c| c * c).sum::<f64>().sqrt();
        let direction: Vec<f64> = chord.iter().map(|c| c / length).collect();
        let coordinate = LineCoordinate::Along {
            origin: segment.from.to_vec(),
            direction: direction.clone(),
        };
        let distance = |point: &[f64; D]| {
            let along = coordinate.of(point).clamp(0.0, length);
            (0..D)
                .map(|i| (point[i] - segment.from[i] - along * direction[i]).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        let indices: Vec<usize> = (0..points.len())
            .filter(|&k| carries_pressure(space, contact.nodes[k]) && distance(&points[k]) <= width)
            .collect();
        let (from, to) = (point_label(&segment.from), point_label(&segment.to));
        if indices.is_empty() {
            return Err(format!(
                "no contact node of Γ3 lies within {} of the segment from {from} to {to} \
                 ({} contact nodes; widen `width` or move the segment onto Γ3)",
                significant(width),
                points.len()
            ));
        }
        let description = format!(
            "s on Γ3 from {from} towards {to} (± {})",
            significant(width)
        );
        Ok(Self::sorted(&points, indices, coordinate, description))
    }

    /// The line of the nodes `indices`, sorted by their coordinate s.
    fn sorted<const D: usize>(
        points: &[[f64; D]],
        mut indices: Vec<usize>,
        coordinate: LineCoordinate,
        description: String,
    ) -> Self {
        let coordinates_of: Vec<f64> = points.iter().map(|p| coordinate.of(p)).collect();
        indices.sort_by(|&a, &b| coordinates_of[a].total_cmp(&coordinates_of[b]));
        let coordinates = indices.iter().map(|&k| coordinates_of[k]).collect();
        Self {
            indices,
            coordinates,
            coordinate,
            description,
        }
    }

    /// Rows of `contact_history.csv` of step n: status, p_ν, |v_τ| and the accumulated slip
    /// of the nodes of the line (the slices are indexed by contact node).
    pub fn csv_rows(
        &self,
        step: usize,
        time: f64,
        status: &[ContactStatus],
        normal_pressure: &[f64],
        slip_rate: &[f64],
        accumulated_slip: &[f64],
    ) -> String {
        let mut rows = String::new();
        for (&k, s) in self.indices.iter().zip(&self.coordinates) {
            let code = match status[k] {
                ContactStatus::Separated => 0,
                ContactStatus::Stick => 1,
                ContactStatus::Slip => 2,
            };
            rows.push_str(&format!(
                "{step},{time},{s},{code},{},{},{}\n",
                normal_pressure[k], slip_rate[k], accumulated_slip[k]
            ));
        }
        rows
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use contact_damage::fem::mesh::{BoundaryPart::*, Mesh};
    use std::sync::Arc;

    /// The unit cube with Γ3 = {z = 0}, 8 cells per side, the vertices of the open face z = 0
    /// moved within the face by up to a quarter cell (`jitter` = 0.25) or not at all: an
    /// unstructured contact face on which no line of nodes is straight.
    fn cube_with_jittered_contact_face(jitter: f64, degree: usize) -> LagrangeSpace<3> {
        let cube = Mesh::box_mesh(
            [0.0; 3],
            [1.0; 3],
            [8; 3],
            [[Dirichlet, Neumann], [Neumann, Neumann], [Contact, Neumann]],
        )
        .unwrap();
        let mut vertices = cube.vertices().to_vec();
        for (v, x) in vertices.iter_mut().enumerate() {
            let inside = x[0] > 0.0 && x[0] < 1.0 && x[1] > 0.0 && x[1] < 1.0;
            if x[2] == 0.0 && inside {
                x[0] += jitter / 8.0 * (1.7 * v as f64).sin();
                x[1] += jitter / 8.0 * (2.3 * v as f64 + 0.4).cos();
            }
        }
        let cells = (0..cube.num_cells())
            .flat_map(|c| cube.cell(c).to_vec())
            .collect();
        let facets = (0..cube.num_facets())
            .flat_map(|f| cube.facet(f).to_vec())
            .collect();
        let parts = (0..cube.num_facets()).map(|f| cube.facet_part(f)).collect();
        let mesh = Mesh::new(vertices, cells, facets, parts).unwrap();
        LagrangeSpace::new(Arc::new(mesh), degree).unwrap()
    }

    #[test]
    fn contact_line_in_3d_is_a_grid_line_on_a_box_and_a_band_on_an_unstructured_face() {
        for degree in [1, 2] {
            // box mesh: one grid line across the middle, every contact node of it
            let space = cube_with_jittered_contact_face(0.0, degree);
            let contact = ContactNodes::new(&space).unwrap();
            let line = ContactLine::new(&space, &contact);
            let LineCoordinate::Axis(axis) = line.coordinate else {
                panic!("the default line runs along a coordinate axis")
            };
            let across = 1 - axis;
            let at = space.node(contact.nodes[line.indices[0]])[across];
            assert!((at - 0.5).abs() <= 1.0 / 16.0, "line at {at}");
            let on_line = contact
                .nodes
                .iter()
                .filter(|&&a| (space.node(a)[across] - at).abs() < 1e-12)
                .count();
            assert_eq!(line.indices.len(), on_line, "degree {degree}");
            assert!(line
                .indices
                .iter()
                .all(|&k| (space.node(contact.nodes[k])[across] - at).abs() < 1e-12));
            // jittered face: a band with nodes spread along the whole face, at most a node
            // spacing apart
            let space = cube_with_jittered_contact_face(0.25, degree);
            let contact = ContactNodes::new(&space).unwrap();
            let line = ContactLine::new(&space, &contact);
            let gaps = line.coordinates.windows(2).map(|w| w[1] - w[0]);
            let spacing = 1.0 / (8 * degree) as f64;
            assert!(
                gaps.clone().all(|gap| gap <= 2.5 * spacing),
                "{:?}",
                line.coordinates
            );
            assert!(line.coordinates[0] <= 2.0 * spacing);
            assert!(*line.coordinates.last().unwrap() >= 1.0 - 2.0 * spacing);
        }
    }

    #[test]
    fn profile_line_follows_a_diagonal_of_an_unstructured_face_and_refuses_to_miss_it() {
        for degree in [1, 2] {
            let space = cube_with_jittered_contact_face(0.25, degree);
            let contact = ContactNodes::new(&space).unwrap();
            // a radius from the centre of the face to its corner, across the grid lines
            let spacing = 1.0 / (8 * degree) as f64;
            let segment = ProfileSegment {
                from: [0.5, 0.5, 0.0],
                to: [1.0, 1.0, 0.0],
                width: None,
            };
            let line = ContactLine::along(&space, &contact, &segment).unwrap();
            // the default width: half the median spacing of the nodes of Γ3 (edges and
            // diagonals of its facets)
            let width = 0.5 * contact_node_spacing(&space);
            assert!(line.description.contains(&format!(
                "from (0.5, 0.5, 0) towards (1, 1, 0) (± {}",
                significant(width)
            )));
            let diagonal = 0.5 * 2.0f64.sqrt();
            for (&k, &s) in line.indices.iter().zip(&line.coordinates) {
                let x = space.node(contact.nodes[k]);
                // s is the distance from the centre along the diagonal; the node lies within
                // the width of the segment
                let along = ((x[0] - 0.5) + (x[1] - 0.5)) / 2.0f64.sqrt();
                assert!((s - along).abs() < 1e-14, "{s} vs {along}");
                let off = ((x[0] - 0.5) - (x[1] - 0.5)).abs() / 2.0f64.sqrt();
                assert!(off <= width + 1e-14 && x[2] == 0.0, "{x:?}");
                assert!(s >= -width && s <= diagonal + width);
            }
            // sorted, and spread along the whole radius without holes
            assert!(line.coordinates.windows(2).all(|w| w[0] <= w[1]));
            assert!(line.coordinates[0] <= 2.0 * spacing);
            assert!(*line.coordinates.last().unwrap() >= diagonal - 2.0 * spacing);
            let gaps = line.coordinates.windows(2).map(|w| w[1] - w[0]);
            assert!(
                gaps.clone().all(|gap| gap <= 3.0 * spacing),
                "{:?}",
                line.coordinates
            );
            // a wider band holds more nodes, a narrower one fewer
            for (factor, more) in [(3.0, true), (0.3, false)] {
                let other = ProfileSegment {
                    width: Some(factor * width),
                    ..segment.clone()
                };
                let other = ContactLine::along(&space, &contact, &other).unwrap();
                assert_eq!(other.indices.len() > line.indices.len(), more);
            }
            // the same segment lifted off the face misses Γ3
            let lifted = ProfileSegment {
                from: [0.5, 0.5, 0.3],
                to: [1.0, 1.0, 0.3],
                width: Some(0.2),
            };
            let error = ContactLine::along(&space, &contact, &lifted).unwrap_err();
            assert!(
                error.contains("no contact node of Γ3 lies within")
                    && error.contains("(0.5, 0.5, 0.3)"),
                "{error}"
            );
        }
    }

    #[test]
    fn default_line_coordinate_is_the_node_coordinate_itself() {
        let coordinate = LineCoordinate::Axis(1);
        assert_eq!(
            coordinate.of(&[0.25, -0.0, 3.0]).to_bits(),
            (-0.0f64).to_bits()
        );
        let along = LineCoordinate::Along {
            origin: vec![1.0, 1.0],
            direction: vec![0.6, 0.8],
        };
        assert!((along.of(&[4.0, 5.0]) - 5.0).abs() < 1e-15);
    }
}
