//! Simplicial meshes 𝒯^h of the body Ω ⊂ R^D, D ∈ {2, 3}, with every boundary facet tagged by
//! the part of Γ = Γ1 ∪ Γ2 ∪ Γ3 it lies in (paper §2 and §5: "every boundary facet lies in exactly
//! one of Γ1, Γ2, Γ3").
//!
//! The constructor [`Mesh::new`] validates everything the discretization relies on (finite
//! coordinates, positively oriented non-degenerate cells, a conforming face structure, a complete
//! and unambiguous boundary tagging, meas(Γ1) > 0), so later stages can assume a valid mesh.
//! [`Mesh::box_mesh`] builds Kuhn (Freudenthal) triangulations of boxes.

use std::collections::HashMap;
use std::hash::Hasher;

use nalgebra::SMatrix;

use crate::error::{Error, Result};

pub use crate::fem::quality::shape_regularity;
pub use crate::fem::refine::{facet_children, refine_times, refine_uniform, refined_facets};

/// The three parts of the boundary (paper §2): Γ1 clamped (u = 0), Γ2 traction f2, Γ3 contact.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum BoundaryPart {
    /// Γ1: the body is clamped, u = 0 (2.5).
    Dirichlet,
    /// Γ2: surface traction σν = f2 (2.6).
    Neumann,
    /// Γ3: normal compliance and Coulomb friction (2.7)–(2.8).
    Contact,
}

impl BoundaryPart {
    /// Human-readable label: the part's name in the model and its role.
    pub fn label(self) -> &'static str {
        match self {
            BoundaryPart::Dirichlet => "Γ1 (Dirichlet)",
            BoundaryPart::Neumann => "Γ2 (Neumann)",
            BoundaryPart::Contact => "Γ3 (contact)",
        }
    }
}

/// Simplicial mesh in R^D: cells are D-simplices (D+1 vertex indices, positively oriented),
/// boundary facets are (D−1)-simplices (D vertex indices) each tagged with exactly one part.
#[derive(Debug, Clone)]
pub struct Mesh<const D: usize> {
    vertices: Vec<[f64; D]>,
    /// Flat cell connectivity, stride D + 1.
    cells: Vec<usize>,
    /// Flat boundary facet connectivity, stride D.
    facets: Vec<usize>,
    facet_parts: Vec<BoundaryPart>,
    /// The cell owning each boundary facet.
    facet_cells: Vec<usize>,
    /// Local index (0..=D) in `facet_cells[f]` of the vertex opposite facet f.
    facet_opposite: Vec<usize>,
    /// Largest cell diameter h.
    max_diameter: f64,
    /// Points of the curved edges (vertex pair, smaller index first → the edge's middle
    /// point), off their straight midpoints; empty for a straight mesh.
    curved_edges: HashMap<(usize, usize), [f64; D]>,
    /// Whether each cell has a curved edge (empty for a straight mesh).
    curved_cells: Vec<bool>,
}

/// Relative threshold of the degeneracy test: a cell is degenerate if |volume| ≤ 1e-12 · h^D.
const DEGENERACY_TOLERANCE: f64 = 1e-12;

impl<const D: usize> Mesh<D> {
    /// Validating constructor (for box generators and file readers).
    ///
    /// `cells` is flat with stride D + 1, `facets` flat with stride D, and `facet_parts[f]` tags
    /// facet f. Errors ([`Error::InvalidMesh`], naming the entity by index and coordinates):
    /// array lengths that do not match the strides; a vertex index out of range; a non-finite
    /// coordinate; a vertex used by no cell (its degrees of freedom would be undetermined); a
    /// degenerate cell (|volume| ≤ 1e-12·h^D, h its diameter); an inverted cell (negative
    /// orientation; never silently reoriented); a facet shared by more than two cells, or by two
    /// cells on the same side of it (overlapping cells; overlaps of cells that share no facet are
    /// not detected, nor is a facet of four cells met in the order +, −, +, − of orientations);
    /// a boundary facet (facet of exactly one
    /// cell) carrying no part; a facet tagged twice, or with two parts; a tagged facet that is
    /// not on the boundary (it belongs to 0 or 2 cells); no Dirichlet facet (meas(Γ1) > 0 is
    /// required by Korn's inequality). D must be 2 or 3 ([`Error::InvalidInput`] otherwise).
    pub fn new(
        vertices: Vec<[f64; D]>,
        cells: Vec<usize>,
        facets: Vec<usize>,
        facet_parts: Vec<BoundaryPart>,
    ) -> Result<Self> {
        check_dimension::<D>()?;
        let mut mesh = Mesh {
            vertices,
            cells,
            facets,
            facet_parts,
            facet_cells: Vec::new(),
            facet_opposite: Vec::new(),
            max_diameter: 0.0,
            curved_edges: HashMap::new(),
            curved_cells: Vec::new(),
        };
        mesh.check_sizes()?;
        mesh.check_vertices_and_cells()?;
        mesh.connect_boundary()?;
        Ok(mesh)
    }

    /// Box [lower, upper] with `cells_per_side[i]` intervals on axis i, split into simplices by
    /// the Kuhn/Freudenthal subdivision: 2D: 2 right triangles per rectangle, all cut along the
    /// same diagonal (from the lower-left to the upper-right corner); 3D: 6 tetrahedra per brick
    /// around its main diagonal. For cubes both are non-obtuse. `sides[i] = [part of side
    /// x_i = lower_i, part of side x_i = upper_i]`.
    ///
    /// Errors: D ∉ {2, 3}; `cells_per_side[i] == 0`, a non-finite bound, or
    /// `lower[i] >= upper[i]` ([`Error::InvalidParameter`] naming `cells_per_side[i]`,
    /// `lower[i]` or `upper[i]`); everything [`Mesh::new`] checks (e.g. no side Dirichlet).
    pub fn box_mesh(
        lower: [f64; D],
        upper: [f64; D],
        cells_per_side: [usize; D],
        sides: [[BoundaryPart; 2]; D],
    ) -> Result<Self> {
        check_dimension::<D>()?;
        for axis in 0..D {
            if cells_per_side[axis] == 0 {
                return Err(Error::parameter(
                    format!("cells_per_side[{axis}]"),
                    0.0,
                    "every axis needs at least one interval",
                ));
            }
            if !lower[axis].is_finite() {
                return Err(Error::parameter(
                    format!("lower[{axis}]"),
                    lower[axis],
                    "box bounds must be finite",
                ));
            }
            if !upper[axis].is_finite() || upper[axis] <= lower[axis] {
                return Err(Error::parameter(
                    format!("upper[{axis}]"),
                    upper[axis],
                    format!(
                        "must be finite and greater than lower[{axis}] = {}",
                        lower[axis]
                    ),
                ));
            }
        }
        // Vertex (i_0, …, i_{D−1}) has index Σ i_a · stride_a.
        let mut strides = [1usize; D];
        let mut num_vertices = 1usize;
        let mut num_boxes = 1usize;
        for axis in 0..D {
            strides[axis] = num_vertices;
            num_vertices = num_vertices
                .checked_mul(cells_per_side[axis] + 1)
                .ok_or_else(|| too_many(axis, cells_per_side[axis]))?;
            num_boxes = num_boxes
                .checked_mul(cells_per_side[axis])
                .ok_or_else(|| too_many(axis, cells_per_side[axis]))?;
        }
        let num_cells = num_boxes
            .checked_mul((1..=D).product::<usize>())
            .ok_or_else(|| too_many(D - 1, cells_per_side[D - 1]))?;

        // Refuse before allocating what cannot be allocated (the machine's memory, or the
        // address space): an error naming the cell counts, not an abort.
        let mut vertices: Vec<[f64; D]> = Vec::new();
        let mut cells: Vec<usize> = Vec::new();
        vertices
            .try_reserve_exact(num_vertices)
            .and_then(|()| cells.try_reserve_exact(num_cells.saturating_mul(D + 1)))
            .map_err(|_| {
                Error::parameter(
                    "cells_per_side",
                    num_cells as f64,
                    format!(
                        "{cells_per_side:?} gives {num_cells} cells and {num_vertices} vertices, more than this machine can allocate ({:.1} GB for the mesh alone)",
                        mesh_bytes(num_vertices, num_cells, D) / 1e9
                    ),
                )
            })?;
        for index in 0..num_vertices {
            vertices.push(std::array::from_fn(|axis| {
                let i = (index / strides[axis]) % (cells_per_side[axis] + 1);
                let n = cells_per_side[axis];
                // Exact end points; interior points by convex combination.
                let s = i as f64 / n as f64;
                if i == n {
                    upper[axis]
                } else {
                    (1.0 - s) * lower[axis] + s * upper[axis]
                }
            }));
        }

        // Kuhn simplex of permutation π: x0, x0 + e_{π0}, x0 + e_{π0} + e_{π1}, …; its
        // orientation is sign(π), so odd permutations swap their last two vertices.
        let permutations = kuhn_permutations(D);
        for box_index in 0..num_boxes {
            let mut origin = 0;
            let mut rest = box_index;
            for axis in 0..D {
                origin += (rest % cells_per_side[axis]) * strides[axis];
                rest /= cells_per_side[axis];
            }
            for (permutation, sign) in &permutations {
                let start = cells.len();
                let mut vertex = origin;
                cells.push(vertex);
                for &axis in permutation {
                    vertex += strides[axis];
                    cells.push(vertex);
                }
                if *sign < 0 {
                    cells.swap(start + D - 1, start + D);
                }
            }
        }

        // Boundary facets: on side x_a = const, the Kuhn subdivision of the face square/segment
        // in the remaining axes (the traces of the Kuhn cells).
        let mut facets = Vec::new();
        let mut facet_parts = Vec::new();
        for axis in 0..D {
            let other_axes: Vec<usize> = (0..D).filter(|&a| a != axis).collect();
            let face_permutations = kuhn_permutations(D - 1);
            let face_counts: Vec<usize> = other_axes.iter().map(|&a| cells_per_side[a]).collect();
            let num_face_boxes: usize = face_counts.iter().product();
            for (side, &part) in sides[axis].iter().enumerate() {
                let layer = if side == 0 { 0 } else { cells_per_side[axis] };
                for face_box in 0..num_face_boxes {
                    let mut origin = layer * strides[axis];
                    let mut rest = face_box;
                    for (k, &a) in other_axes.iter().enumerate() {
                        origin += (rest % face_counts[k]) * strides[a];
                        rest /= face_counts[k];
                    }
                    for (permutation, _) in &face_permutations {
                        let mut vertex = origin;
                        facets.push(vertex);
                        for &k in permutation {
                            vertex += strides[other_axes[k]];
                            facets.push(vertex);
                        }
                        facet_parts.push(part);
                    }
                }
            }
        }
        Mesh::new(vertices, cells, facets, facet_parts)
    }

    /// The mesh with curved edges: `edge_points` gives, for edges (vertex pairs, in either
    /// order), the point the edge passes through at its middle (the edge node of a Gmsh
    /// second-order element). Cells with a curved edge are mapped isoparametrically
    /// ([`crate::fem::curved`]); a point within 1e-12 × the edge length of the straight midpoint
    /// leaves the edge straight.
    ///
    /// Errors ([`Error::InvalidMesh`], naming the entity): a vertex pair that is not an edge of
    /// a cell; a non-finite point; two different points for one edge; a curved cell whose map
    /// is inverted or degenerate (det J ≤ 1e-12 h^D at one of the P2 nodes or of the points
    /// of a degree-4 rule).
    pub fn with_curved_edges(
        mut self,
        edge_points: impl IntoIterator<Item = ((usize, usize), [f64; D])>,
    ) -> Result<Self> {
        let mut edges: HashMap<(usize, usize), usize> = HashMap::new();
        for c in 0..self.num_cells() {
            for &[a, b] in crate::fem::element::simplex_edges(D) {
                let (p, q) = (self.cell(c)[a], self.cell(c)[b]);
                edges.entry((p.min(q), p.max(q))).or_insert(c);
            }
        }
        let mut curved_edges: HashMap<(usize, usize), [f64; D]> = HashMap::new();
        for ((a, b), point) in edge_points {
            let key = (a.min(b), a.max(b));
            if !edges.contains_key(&key) {
                return Err(Error::InvalidMesh(format!(
                    "curved edge ({a}, {b}) is not an edge of any cell"
                )));
            }
            if point.iter().any(|v| !v.is_finite()) {
                return Err(Error::InvalidMesh(format!(
                    "curved edge ({a}, {b}) has a non-finite point {point:?}"
                )));
            }
            let (p, q) = (self.vertices[key.0], self.vertices[key.1]);
            let length = (0..D).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>().sqrt();
            let offset = (0..D)
                .map(|i| (point[i] - 0.5 * (p[i] + q[i])).powi(2))
                .sum::<f64>()
                .sqrt();
            let straight = offset <= 1e-12 * length;
            if let Some(previous) = curved_edges.get(&key) {
                if (0..D).any(|i| (previous[i] - point[i]).abs() > 1e-12 * length) {
                    return Err(Error::InvalidMesh(format!(
                        "edge ({a}, {b}) is given two different points, {previous:?} and {point:?}"
                    )));
                }
            } else if !straight {
                curved_edges.insert(key, point);
            }
        }
        self.curved_cells = if curved_edges.is_empty() {
            Vec::new()
        } else {
            (0..self.num_cells())
                .map(|c| {
                    crate::fem::element::simplex_edges(D).iter().any(|&[a, b]| {
                        let (p, q) = (self.cell(c)[a], self.cell(c)[b]);
                        curved_edges.contains_key(&(p.min(q), p.max(q)))
                    })
                })
                .collect()
        };
        self.curved_edges = curved_edges;
        let points = crate::fem::curved::CurvedMap::<D>::check_points();
        for c in (0..self.num_cells()).filter(|&c| self.is_cell_curved(c)) {
            let map = self.curved_map(c);
            let h = self.cell_diameter(c);
            for xi in &points {
                let det = determinant(&map.jacobian(xi));
                if det.is_nan() || det <= DEGENERACY_TOLERANCE * h.powi(D as i32) {
                    return Err(Error::InvalidMesh(format!(
                        "curved cell {c} (vertices {:?}, geometry nodes {:?}) is {} at the \
                         reference point {xi:?}: det J = {det:e} (straight: {:e})",
                        self.cell(c),
                        map.nodes(),
                        if det < 0.0 { "inverted" } else { "degenerate" },
                        determinant(&self.cell_map(c).1),
                    )));
                }
            }
        }
        Ok(self)
    }

    /// Whether some edge of the mesh is curved.
    pub fn has_curved_edges(&self) -> bool {
        !self.curved_edges.is_empty()
    }

    /// Whether cell c has a curved edge (and is mapped isoparametrically at P2).
    pub fn is_cell_curved(&self, c: usize) -> bool {
        self.curved_cells.get(c).copied().unwrap_or(false)
    }

    /// The point of edge (a, b) at its middle: its curved point, or the straight midpoint.
    pub fn edge_point(&self, a: usize, b: usize) -> [f64; D] {
        match self.curved_edges.get(&(a.min(b), a.max(b))) {
            Some(&point) => point,
            None => {
                let (p, q) = (self.vertices[a], self.vertices[b]);
                std::array::from_fn(|i| 0.5 * (p[i] + q[i]))
            }
        }
    }

    /// The curved edges: (vertex pair, smaller index first) → point.
    pub fn curved_edges(&self) -> &HashMap<(usize, usize), [f64; D]> {
        &self.curved_edges
    }

    /// The P2 geometry map of cell c (vertices, then edge points; affine when no edge of c
    /// is curved).
    pub fn curved_map(&self, c: usize) -> crate::fem::curved::CurvedMap<D> {
        let cell = self.cell(c);
        let mut nodes: Vec<[f64; D]> = cell.iter().map(|&v| self.vertices[v]).collect();
        for &[a, b] in crate::fem::element::simplex_edges(D) {
            nodes.push(self.edge_point(cell[a], cell[b]));
        }
        crate::fem::curved::CurvedMap::new(&nodes)
    }

    /// Number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.vertices.len()
    }

    /// Number of cells (D-simplices).
    pub fn num_cells(&self) -> usize {
        self.cells.len() / (D + 1)
    }

    /// Number of boundary facets.
    pub fn num_facets(&self) -> usize {
        self.facet_parts.len()
    }

    /// Coordinates of vertex i.
    pub fn vertex(&self, i: usize) -> [f64; D] {
        self.vertices[i]
    }

    /// All vertex coordinates.
    pub fn vertices(&self) -> &[[f64; D]] {
        &self.vertices
    }

    /// The D + 1 vertex indices of cell c (positively oriented).
    pub fn cell(&self, c: usize) -> &[usize] {
        &self.cells[c * (D + 1)..(c + 1) * (D + 1)]
    }

    /// The D vertex indices of boundary facet f (in the order given at construction).
    pub fn facet(&self, f: usize) -> &[usize] {
        &self.facets[f * D..(f + 1) * D]
    }

    /// The boundary part facet f belongs to.
    pub fn facet_part(&self, f: usize) -> BoundaryPart {
        self.facet_parts[f]
    }

    /// The (unique) cell that has boundary facet f as a facet.
    pub fn facet_cell(&self, f: usize) -> usize {
        self.facet_cells[f]
    }

    /// Local index (0..=D) in `cell(facet_cell(f))` of the vertex opposite boundary facet f;
    /// the facet's vertices are the cell's other D vertices.
    pub fn facet_opposite_vertex(&self, f: usize) -> usize {
        self.facet_opposite[f]
    }

    /// Affine map of cell c: x = x0 + J ξ; returns (x0, J with columns x_i − x_0); det J > 0.
    pub fn cell_map(&self, c: usize) -> ([f64; D], SMatrix<f64, D, D>) {
        affine_map(&self.vertices, self.cell(c))
    }

    /// Volume (D-measure) of cell c: det J / D!.
    pub fn cell_volume(&self, c: usize) -> f64 {
        determinant(&self.cell_map(c).1) / factorial(D)
    }

    /// Diameter (longest edge) of cell c.
    pub fn cell_diameter(&self, c: usize) -> f64 {
        simplex_diameter(&self.vertices, self.cell(c))
    }

    /// Outward unit normal of boundary facet f (outward with respect to `facet_cell(f)`).
    ///
    /// Computed as ν = −∇λ_k / |∇λ_k| with λ_k the barycentric coordinate of the opposite
    /// vertex k, ∇λ_k = J^{−T} ∇_ξ λ_k.
    pub fn facet_normal(&self, f: usize) -> [f64; D] {
        let gradient = self.opposite_barycentric_gradient(f);
        let norm = gradient.norm();
        std::array::from_fn(|i| -gradient[i] / norm)
    }

    /// (D−1)-measure of boundary facet f (length in 2D, area in 3D).
    ///
    /// Uses volume = measure · height / D and |∇λ_k| = 1/height.
    pub fn facet_measure(&self, f: usize) -> f64 {
        let gradient = self.opposite_barycentric_gradient(f);
        D as f64 * self.cell_volume(self.facet_cells[f]) * gradient.norm()
    }

    /// Largest cell diameter h.
    pub fn max_cell_diameter(&self) -> f64 {
        self.max_diameter
    }

    /// The boundary facets all of whose vertices satisfy `inside` (e.g. a side of a box:
    /// `|x| x[0] == 0.0`, exact for [`Mesh::box_mesh`], whose side vertices are exact).
    pub fn boundary_facets_where(&self, inside: impl Fn(&[f64; D]) -> bool) -> Vec<usize> {
        (0..self.num_facets())
            .filter(|&f| self.facet(f).iter().all(|&v| inside(&self.vertices[v])))
            .collect()
    }

    /// Physical gradient of the barycentric coordinate of the vertex opposite facet f.
    fn opposite_barycentric_gradient(&self, f: usize) -> nalgebra::SVector<f64, D> {
        let (_, jacobian) = self.cell_map(self.facet_cells[f]);
        let inverse = jacobian
            .try_inverse()
            .expect("cells were checked to be non-degenerate");
        let k = self.facet_opposite[f];
        let reference_gradient = nalgebra::SVector::<f64, D>::from_fn(|i, _| {
            if k == 0 {
                -1.0
            } else if i + 1 == k {
                1.0
            } else {
                0.0
            }
        });
        inverse.transpose() * reference_gradient
    }

    fn check_sizes(&self) -> Result<()> {
        if self.cells.is_empty() {
            return Err(Error::InvalidMesh("the mesh has no cells".into()));
        }
        if self.cells.len() % (D + 1) != 0 {
            return Err(Error::InvalidMesh(format!(
                "cell connectivity has {} entries, not a multiple of D + 1 = {}",
                self.cells.len(),
                D + 1
            )));
        }
        if self.facets.len() % D != 0 {
            return Err(Error::InvalidMesh(format!(
                "facet connectivity has {} entries, not a multiple of D = {D}",
                self.facets.len()
            )));
        }
        if self.facets.len() / D != self.facet_parts.len() {
            return Err(Error::InvalidMesh(format!(
                "{} facets but {} facet parts",
                self.facets.len() / D,
                self.facet_parts.len()
            )));
        }
        Ok(())
    }

    fn check_vertices_and_cells(&mut self) -> Result<()> {
        for (i, x) in self.vertices.iter().enumerate() {
            if x.iter().any(|c| !c.is_finite()) {
                return Err(Error::InvalidMesh(format!(
                    "vertex {i} at {x:?} has a non-finite coordinate"
                )));
            }
        }
        let num_vertices = self.vertices.len();
        let mut used = vec![false; num_vertices];
        let mut max_diameter: f64 = 0.0;
        for (c, cell) in self.cells.chunks_exact(D + 1).enumerate() {
            if let Some(&v) = cell.iter().find(|&&v| v >= num_vertices) {
                return Err(Error::InvalidMesh(format!(
                    "cell {c} {cell:?} refers to vertex {v}, but the mesh has {num_vertices} vertices"
                )));
            }
            for (k, &v) in cell.iter().enumerate() {
                if cell[..k].contains(&v) {
                    return Err(Error::InvalidMesh(format!(
                        "cell {c} {cell:?} repeats vertex {v} at {:?}",
                        self.vertices[v]
                    )));
                }
                used[v] = true;
            }
            let diameter = simplex_diameter(&self.vertices, cell);
            let volume = determinant(&affine_map(&self.vertices, cell).1) / factorial(D);
            if volume.abs() <= DEGENERACY_TOLERANCE * diameter.powi(D as i32) {
                return Err(Error::InvalidMesh(format!(
                    "cell {c} {cell:?} with vertices {} is degenerate: volume {volume:e} <= {DEGENERACY_TOLERANCE:e} * h^{D}, h = {diameter:e}",
                    self.describe_vertices(cell)
                )));
            }
            if volume < 0.0 {
                return Err(Error::InvalidMesh(format!(
                    "cell {c} {cell:?} with vertices {} is inverted (negatively oriented, volume {volume:e}); list its vertices in positive order",
                    self.describe_vertices(cell)
                )));
            }
            max_diameter = max_diameter.max(diameter);
        }
        if let Some(v) = used.iter().position(|&u| !u) {
            return Err(Error::InvalidMesh(format!(
                "vertex {v} at {:?} belongs to no cell",
                self.vertices[v]
            )));
        }
        self.max_diameter = max_diameter;
        Ok(())
    }

    /// Finds the facets of exactly one cell, checks the tagging and records the owning cells.
    ///
    /// Pass 1 scans all cell faces with a hash map over sorted vertex tuples, removing a face
    /// when its second cell is seen (after checking that the two cells lie on opposite sides of
    /// it, i.e. induce opposite orientations). The map thus only holds the current "front" and
    /// ends with the boundary faces, which keeps it small and cache-resident for reasonably
    /// numbered meshes. Pass 2 rescans the faces to make sure every remaining face belongs to
    /// exactly one cell (a face of three cells would survive pass 1) and to count the cells of
    /// tagged facets that are not boundary faces, for the error message.
    fn connect_boundary(&mut self) -> Result<()> {
        use std::collections::hash_map::Entry;
        let num_facets = self.facet_parts.len();
        let mut boundary: HashMap<FaceKey<D>, FaceRecord, FastBuildHasher> =
            HashMap::with_capacity_and_hasher(num_facets + 16, FastBuildHasher::default());
        for (c, cell) in self.cells.chunks_exact(D + 1).enumerate() {
            for opposite in 0..=D {
                let (key, parity) = sorted_face(cell, opposite);
                // Orientation induced on the face by the (positively oriented) cell.
                let orientation = if opposite % 2 == 0 { parity } else { -parity };
                match boundary.entry(key) {
                    Entry::Vacant(entry) => {
                        entry.insert(FaceRecord {
                            cell: c,
                            opposite,
                            orientation,
                        });
                    }
                    Entry::Occupied(entry) => {
                        let first = *entry.get();
                        if first.orientation == orientation {
                            return Err(Error::InvalidMesh(format!(
                                "cells {} and {c} overlap: both lie on the same side of their common facet with vertices {}",
                                first.cell,
                                self.describe_vertices(&key.0)
                            )));
                        }
                        entry.remove();
                    }
                }
            }
        }

        // Tagged facets: vertex range, duplicates.
        let num_vertices = self.vertices.len();
        let mut tagged: HashMap<FaceKey<D>, usize, FastBuildHasher> =
            HashMap::with_capacity_and_hasher(num_facets, FastBuildHasher::default());
        for f in 0..num_facets {
            let facet = &self.facets[f * D..(f + 1) * D];
            let part = self.facet_parts[f];
            if let Some(&v) = facet.iter().find(|&&v| v >= num_vertices) {
                return Err(Error::InvalidMesh(format!(
                    "facet {f} {facet:?} ({part:?}) refers to vertex {v}, but the mesh has {num_vertices} vertices"
                )));
            }
            let key = FaceKey::sorted(std::array::from_fn(|i| facet[i]));
            if let Some(&first) = tagged.get(&key) {
                let first_part = self.facet_parts[first];
                let problem = if first_part == part {
                    format!("is tagged twice ({part:?}, as facets {first} and {f})")
                } else {
                    format!(
                        "is tagged with two parts ({first_part:?} as facet {first}, {part:?} as facet {f})"
                    )
                };
                return Err(Error::InvalidMesh(format!(
                    "facet {f} {facet:?} with vertices {} {problem}",
                    self.describe_vertices(facet)
                )));
            }
            tagged.insert(key, f);
        }
        // Tagged facets that are not boundary faces, with the cells containing them.
        let mut stray: HashMap<FaceKey<D>, (usize, Vec<usize>), FastBuildHasher> = tagged
            .iter()
            .filter(|(key, _)| !boundary.contains_key(*key))
            .map(|(key, &f)| (*key, (f, Vec::new())))
            .collect();

        // Pass 2.
        for (c, cell) in self.cells.chunks_exact(D + 1).enumerate() {
            for opposite in 0..=D {
                let (key, _) = sorted_face(cell, opposite);
                if let Some(record) = boundary.get(&key) {
                    if (record.cell, record.opposite) != (c, opposite) {
                        return Err(Error::InvalidMesh(format!(
                            "facet with vertices {} is shared by more than two cells (among them cells {} and {c})",
                            self.describe_vertices(&key.0),
                            record.cell
                        )));
                    }
                }
                if !stray.is_empty() {
                    if let Some((_, cells)) = stray.get_mut(&key) {
                        cells.push(c);
                    }
                }
            }
        }
        if let Some((f, cells)) = stray.values().min_by_key(|(f, _)| *f) {
            let facet = self.facet(*f);
            let owners = if cells.is_empty() {
                "it is a facet of no cell".to_string()
            } else {
                format!("it is shared by {} cells {cells:?}", cells.len())
            };
            return Err(Error::InvalidMesh(format!(
                "facet {f} {facet:?} with vertices {} is tagged {:?} but is not on the boundary: {owners}",
                self.describe_vertices(facet),
                self.facet_parts[*f]
            )));
        }

        // Every boundary face must be tagged; report the first in cell order.
        let untagged = boundary
            .iter()
            .filter(|(key, _)| !tagged.contains_key(*key))
            .min_by_key(|(_, record)| (record.cell, record.opposite));
        if let Some((key, record)) = untagged {
            return Err(Error::InvalidMesh(format!(
                "boundary facet with vertices {} (of cell {}) carries no boundary part",
                self.describe_vertices(&key.0),
                record.cell
            )));
        }

        self.facet_cells = Vec::with_capacity(num_facets);
        self.facet_opposite = Vec::with_capacity(num_facets);
        for f in 0..num_facets {
            let key = FaceKey::sorted(std::array::from_fn(|i| self.facets[f * D + i]));
            let record = boundary[&key];
            self.facet_cells.push(record.cell);
            self.facet_opposite.push(record.opposite);
        }

        if !self.facet_parts.contains(&BoundaryPart::Dirichlet) {
            return Err(Error::InvalidMesh(
                "no boundary facet is tagged Dirichlet: meas(Γ1) > 0 is required (Korn's inequality)"
                    .into(),
            ));
        }
        Ok(())
    }

    /// "v (x, y), w (x, y), …" for error messages.
    fn describe_vertices(&self, indices: &[usize]) -> String {
        indices
            .iter()
            .map(|&v| format!("{v} {:?}", self.vertices[v]))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// Determinant of a D×D matrix, D ∈ {1, 2, 3} (nalgebra's `determinant` needs typenum bounds
/// that a generic `const D` does not satisfy).
///
/// # Panics
/// If D > 3.
pub fn determinant<const D: usize>(matrix: &SMatrix<f64, D, D>) -> f64 {
    let m = |r: usize, c: usize| matrix[(r, c)];
    match D {
        0 => 1.0,
        1 => m(0, 0),
        2 => m(0, 0) * m(1, 1) - m(0, 1) * m(1, 0),
        3 => {
            m(0, 0) * (m(1, 1) * m(2, 2) - m(1, 2) * m(2, 1))
                - m(0, 1) * (m(1, 0) * m(2, 2) - m(1, 2) * m(2, 0))
                + m(0, 2) * (m(1, 0) * m(2, 1) - m(1, 1) * m(2, 0))
        }
        _ => panic!("determinant: dimension {D} is not supported (only 0 to 3)"),
    }
}

/// Record of a face while scanning the cells: its first cell.
#[derive(Clone, Copy)]
struct FaceRecord {
    /// First cell containing the face.
    cell: usize,
    /// Local index of the vertex of `cell` opposite the face.
    opposite: usize,
    /// Orientation (±1) induced on the face by `cell`.
    orientation: i8,
}

/// The face of `cell` opposite local vertex `opposite`, as sorted vertex indices, with the parity
/// (±1) of the permutation that sorts it from the cell's order.
fn sorted_face<const D: usize>(cell: &[usize], opposite: usize) -> (FaceKey<D>, i8) {
    let mut key: [usize; D] =
        std::array::from_fn(|i| if i < opposite { cell[i] } else { cell[i + 1] });
    // Insertion sort counting transpositions (D ≤ 3).
    let mut parity = 1i8;
    for i in 1..D {
        let mut j = i;
        while j > 0 && key[j - 1] > key[j] {
            key.swap(j - 1, j);
            parity = -parity;
            j -= 1;
        }
    }
    (FaceKey(key), parity)
}

/// Sorted vertex indices of a face, hashed word by word.
#[derive(Clone, Copy, PartialEq, Eq)]
struct FaceKey<const D: usize>([usize; D]);

impl<const D: usize> FaceKey<D> {
    fn sorted(mut vertices: [usize; D]) -> Self {
        vertices.sort_unstable();
        FaceKey(vertices)
    }
}

impl<const D: usize> std::hash::Hash for FaceKey<D> {
    fn hash<H: Hasher>(&self, state: &mut H) {
        for &v in &self.0 {
            state.write_usize(v);
        }
    }
}

/// Affine map x = x0 + J ξ of the simplex with the given vertices.
fn affine_map<const D: usize>(
    vertices: &[[f64; D]],
    simplex: &[usize],
) -> ([f64; D], SMatrix<f64, D, D>) {
    let origin = vertices[simplex[0]];
    let jacobian = SMatrix::<f64, D, D>::from_fn(|r, c| vertices[simplex[c + 1]][r] - origin[r]);
    (origin, jacobian)
}

/// Longest edge of a simplex.
fn simplex_diameter<const D: usize>(vertices: &[[f64; D]], simplex: &[usize]) -> f64 {
    let mut longest: f64 = 0.0;
    for (k, &a) in simplex.iter().enumerate() {
        for &b in &simplex[k + 1..] {
            let squared: f64 = (0..D)
                .map(|i| (vertices[a][i] - vertices[b][i]).powi(2))
                .sum();
            longest = longest.max(squared.sqrt());
        }
    }
    longest
}

fn check_dimension<const D: usize>() -> Result<()> {
    if D == 2 || D == 3 {
        Ok(())
    } else {
        Err(Error::InvalidInput(format!(
            "meshes are supported in dimensions 2 and 3, not {D}"
        )))
    }
}

/// Bytes of the vertex coordinates and cell connectivity of a mesh.
fn mesh_bytes(vertices: usize, cells: usize, dim: usize) -> f64 {
    vertices as f64 * (dim * std::mem::size_of::<f64>()) as f64
        + cells as f64 * ((dim + 1) * std::mem::size_of::<usize>()) as f64
}

fn too_many(axis: usize, count: usize) -> Error {
    Error::parameter(
        format!("cells_per_side[{axis}]"),
        count as f64,
        "the mesh size overflows the index type",
    )
}

fn factorial(n: usize) -> f64 {
    (1..=n).map(|k| k as f64).product()
}

/// All permutations of 0..n with their signs (Kuhn simplices of the unit n-cube).
fn kuhn_permutations(n: usize) -> Vec<(Vec<usize>, i8)> {
    fn recurse(prefix: &mut Vec<usize>, n: usize, out: &mut Vec<(Vec<usize>, i8)>) {
        if prefix.len() == n {
            let inversions = (0..n)
                .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
                .filter(|&(i, j)| prefix[i] > prefix[j])
                .count();
            out.push((prefix.clone(), if inversions % 2 == 0 { 1 } else { -1 }));
            return;
        }
        for axis in 0..n {
            if !prefix.contains(&axis) {
                prefix.push(axis);
                recurse(prefix, n, out);
                prefix.pop();
            }
        }
    }
    let mut out = Vec::new();
    recurse(&mut Vec::new(), n, &mut out);
    out
}

/// Fast non-cryptographic hasher for face keys (rustc's Fx hash).
type FastBuildHasher = rustc_hash::FxBuildHasher;

#[cfg(test)]
mod tests {
    use super::*;
    use BoundaryPart::{Contact, Dirichlet, Neumann};

    fn unit_square(n: usize) -> Mesh<2> {
        Mesh::box_mesh(
            [0.0, 0.0],
            [1.0, 1.0],
            [n, n],
            [[Dirichlet, Neumann], [Contact, Neumann]],
        )
        .unwrap()
    }

    fn brick() -> Mesh<3> {
        Mesh::box_mesh(
            [0.0, -1.0, 0.5],
            [2.0, 0.5, 1.5],
            [3, 4, 2],
            [[Dirichlet, Neumann], [Neumann, Neumann], [Contact, Neumann]],
        )
        .unwrap()
    }

    /// The unit right triangle with all three edges tagged.
    fn triangle_parts(
        parts: [BoundaryPart; 3],
    ) -> (Vec<[f64; 2]>, Vec<usize>, Vec<usize>, Vec<BoundaryPart>) {
        (
            vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
            vec![0, 1, 2],
            vec![0, 1, 1, 2, 2, 0],
            parts.to_vec(),
        )
    }

    fn error_message<T: std::fmt::Debug>(result: Result<T>) -> String {
        result.unwrap_err().to_string()
    }

    #[test]
    fn box_mesh_counts_match_kuhn_subdivision() {
        for n in [1, 3, 8] {
            let mesh = unit_square(n);
            assert_eq!(mesh.num_cells(), 2 * n * n);
            assert_eq!(mesh.num_facets(), 4 * n);
            assert_eq!(mesh.num_vertices(), (n + 1) * (n + 1));
            let cube = Mesh::<3>::box_mesh(
                [0.0; 3],
                [1.0; 3],
                [n; 3],
                [[Dirichlet, Neumann], [Contact, Neumann], [Neumann, Neumann]],
            )
            .unwrap();
            assert_eq!(cube.num_cells(), 6 * n * n * n);
            assert_eq!(cube.num_facets(), 12 * n * n);
            assert_eq!(cube.num_vertices(), (n + 1).pow(3));
        }
    }

    #[test]
    fn cells_are_positively_oriented_and_fill_the_box() {
        let square = Mesh::<2>::box_mesh(
            [-1.0, 2.0],
            [3.0, 2.5],
            [5, 3],
            [[Dirichlet, Contact], [Neumann, Neumann]],
        )
        .unwrap();
        let total: f64 = (0..square.num_cells()).map(|c| square.cell_volume(c)).sum();
        assert!((total - 4.0 * 0.5).abs() < 1e-13, "{total}");
        assert!((0..square.num_cells()).all(|c| determinant(&square.cell_map(c).1) > 0.0));

        let brick = brick();
        let total: f64 = (0..brick.num_cells()).map(|c| brick.cell_volume(c)).sum();
        assert!((total - 2.0 * 1.5 * 1.0).abs() < 1e-13, "{total}");
        assert!((0..brick.num_cells()).all(|c| brick.cell_volume(c) > 0.0));
    }

    /// Σ facet measures per side equals the side's area, the side is identified by the normal,
    /// and the normal points out of the box.
    fn check_sides<const D: usize>(
        mesh: &Mesh<D>,
        lower: [f64; D],
        upper: [f64; D],
        sides: [[BoundaryPart; 2]; D],
    ) {
        let mut side_measure = [[0.0f64; 2]; D];
        for f in 0..mesh.num_facets() {
            let normal = mesh.facet_normal(f);
            let norm: f64 = normal.iter().map(|x| x * x).sum::<f64>().sqrt();
            assert!((norm - 1.0).abs() < 1e-14);
            let axis = (0..D)
                .max_by(|&a, &b| normal[a].abs().total_cmp(&normal[b].abs()))
                .unwrap();
            let side = if normal[axis] > 0.0 { 1 } else { 0 };
            assert!(
                (normal[axis].abs() - 1.0).abs() < 1e-14,
                "normal {normal:?} not axis-aligned"
            );
            assert_eq!(mesh.facet_part(f), sides[axis][side]);
            side_measure[axis][side] += mesh.facet_measure(f);
            // Centroid + ε ν is outside the box, centroid − ε ν inside.
            let facet = mesh.facet(f);
            let centroid: [f64; D] = std::array::from_fn(|i| {
                facet.iter().map(|&v| mesh.vertex(v)[i]).sum::<f64>() / D as f64
            });
            let epsilon = 1e-6;
            let outside = (0..D).any(|i| {
                let x = centroid[i] + epsilon * normal[i];
                x < lower[i] || x > upper[i]
            });
            let inside = (0..D).all(|i| {
                let x = centroid[i] - epsilon * normal[i];
                x > lower[i] && x < upper[i]
            });
            assert!(
                outside && inside,
                "facet {f}: normal {normal:?} at {centroid:?}"
            );
            // The owning cell contains the facet's vertices and not the opposite one.
            let cell = mesh.cell(mesh.facet_cell(f));
            assert!(facet.iter().all(|v| cell.contains(v)));
            assert!(!facet.contains(&cell[mesh.facet_opposite_vertex(f)]));
        }
        for (axis, measures) in side_measure.iter().enumerate() {
            let area: f64 = (0..D)
                .filter(|&a| a != axis)
                .map(|a| upper[a] - lower[a])
                .product();
            for (side, measure) in measures.iter().enumerate() {
                assert!(
                    (measure - area).abs() < 1e-13,
                    "axis {axis} side {side}: {measure} vs {area}"
                );
            }
        }
    }

    #[test]
    fn facet_measures_and_outward_normals_match_box_sides() {
        let sides2 = [[Dirichlet, Contact], [Neumann, Contact]];
        let (lower, upper) = ([-1.0, 2.0], [3.0, 2.5]);
        check_sides(
            &Mesh::<2>::box_mesh(lower, upper, [5, 3], sides2).unwrap(),
            lower,
            upper,
            sides2,
        );
        let sides3 = [[Dirichlet, Neumann], [Neumann, Neumann], [Contact, Neumann]];
        check_sides(&brick(), [0.0, -1.0, 0.5], [2.0, 0.5, 1.5], sides3);
    }

    #[test]
    fn kuhn_triangles_are_non_obtuse() {
        let mesh = unit_square(4);
        for c in 0..mesh.num_cells() {
            let cell = mesh.cell(c);
            for k in 0..3 {
                let p = mesh.vertex(cell[k]);
                let a = mesh.vertex(cell[(k + 1) % 3]);
                let b = mesh.vertex(cell[(k + 2) % 3]);
                let (u, v) = ([a[0] - p[0], a[1] - p[1]], [b[0] - p[0], b[1] - p[1]]);
                let cosine =
                    (u[0] * v[0] + u[1] * v[1]) / ((u[0].hypot(u[1])) * (v[0].hypot(v[1])));
                let angle = cosine.clamp(-1.0, 1.0).acos();
                assert!(
                    angle <= std::f64::consts::FRAC_PI_2 + 1e-12,
                    "cell {c} angle {angle}"
                );
            }
        }
    }

    #[test]
    fn max_cell_diameter_is_the_box_diagonal() {
        let mesh = unit_square(4);
        assert!((mesh.max_cell_diameter() - 0.25 * 2f64.sqrt()).abs() < 1e-15);
        let brick = brick();
        let diagonal = ((2.0f64 / 3.0).powi(2) + 0.375f64.powi(2) + 0.5f64.powi(2)).sqrt();
        assert!((brick.max_cell_diameter() - diagonal).abs() < 1e-14);
    }

    #[test]
    fn mesh_accepts_a_valid_hand_made_triangle() {
        let (v, c, f, p) = triangle_parts([Dirichlet, Contact, Neumann]);
        let mesh = Mesh::new(v, c, f, p).unwrap();
        assert_eq!(mesh.facet_cell(1), 0);
        assert_eq!(mesh.facet_opposite_vertex(1), 0);
        let normal = mesh.facet_normal(1); // hypotenuse
        assert!(
            (normal[0] - 0.5f64.sqrt()).abs() < 1e-15 && (normal[1] - 0.5f64.sqrt()).abs() < 1e-15
        );
        assert!((mesh.facet_measure(1) - 2f64.sqrt()).abs() < 1e-15);
    }

    #[test]
    fn mesh_rejects_inverted_cell() {
        let (v, _, f, p) = triangle_parts([Dirichlet, Contact, Neumann]);
        let message = error_message(Mesh::new(v, vec![0, 2, 1], f, p));
        assert!(
            message.contains("cell 0") && message.contains("inverted"),
            "{message}"
        );
        assert!(message.contains("[0.0, 1.0]"), "{message}");
    }

    #[test]
    fn mesh_rejects_degenerate_cell() {
        let vertices = vec![[0.0, 0.0], [1.0, 0.0], [2.0, 1e-13]];
        let message = error_message(Mesh::new(
            vertices,
            vec![0, 1, 2],
            vec![0, 1, 1, 2, 2, 0],
            vec![Dirichlet; 3],
        ));
        assert!(
            message.contains("cell 0") && message.contains("degenerate"),
            "{message}"
        );
        assert!(message.contains("[2.0, 1e-13]"), "{message}");
    }

    #[test]
    fn mesh_rejects_untagged_boundary_facet() {
        let (v, c, _, _) = triangle_parts([Dirichlet; 3]);
        let message = error_message(Mesh::new(v, c, vec![0, 1, 1, 2], vec![Dirichlet, Contact]));
        assert!(message.contains("carries no boundary part"), "{message}");
        assert!(
            message.contains("0 [0.0, 0.0]") && message.contains("2 [0.0, 1.0]"),
            "{message}"
        );
    }

    #[test]
    fn mesh_rejects_facet_on_two_parts() {
        let (v, c, _, _) = triangle_parts([Dirichlet; 3]);
        let facets = vec![0, 1, 1, 2, 2, 0, 2, 1];
        let parts = vec![Dirichlet, Contact, Neumann, Neumann];
        let message = error_message(Mesh::new(v.clone(), c.clone(), facets.clone(), parts));
        assert!(
            message.contains("two parts") && message.contains("facet 3"),
            "{message}"
        );
        assert!(
            message.contains("Contact") && message.contains("Neumann"),
            "{message}"
        );
        assert!(message.contains("[1.0, 0.0]"), "{message}");
        let twice = error_message(Mesh::new(
            v,
            c,
            facets,
            vec![Dirichlet, Contact, Neumann, Contact],
        ));
        assert!(
            twice.contains("tagged twice") && twice.contains("facet 3"),
            "{twice}"
        );
    }

    #[test]
    fn mesh_rejects_interior_facet_tag() {
        // Two triangles sharing the diagonal 0–2 of the unit square; the diagonal is tagged.
        let vertices = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let cells = vec![0, 1, 2, 0, 2, 3];
        let mut facets = vec![0, 1, 1, 2, 2, 3, 3, 0];
        let mut parts = vec![Dirichlet; 4];
        Mesh::new(
            vertices.clone(),
            cells.clone(),
            facets.clone(),
            parts.clone(),
        )
        .unwrap();
        facets.extend([0, 2]);
        parts.push(Contact);
        let message = error_message(Mesh::new(
            vertices.clone(),
            cells.clone(),
            facets.clone(),
            parts.clone(),
        ));
        assert!(
            message.contains("facet 4") && message.contains("not on the boundary"),
            "{message}"
        );
        assert!(
            message.contains("2 cells") && message.contains("[1.0, 1.0]"),
            "{message}"
        );
        // A tagged segment that is no facet of any cell (the other diagonal).
        *facets.last_mut().unwrap() = 3;
        facets[8] = 1;
        let message = error_message(Mesh::new(vertices, cells, facets, parts));
        assert!(
            message.contains("facet 4") && message.contains("no cell"),
            "{message}"
        );
    }

    #[test]
    fn mesh_rejects_empty_dirichlet_part() {
        let (v, c, f, p) = triangle_parts([Neumann, Contact, Neumann]);
        let message = error_message(Mesh::new(v, c, f, p));
        assert!(
            message.contains("meas(Γ1) > 0 is required (Korn's inequality)"),
            "{message}"
        );
        let message = error_message(Mesh::<2>::box_mesh(
            [0.0; 2],
            [1.0; 2],
            [2, 2],
            [[Neumann, Contact]; 2],
        ));
        assert!(message.contains("Korn"), "{message}");
    }

    #[test]
    fn box_mesh_refuses_sizes_it_cannot_allocate_naming_the_cells() {
        // 1e9 × 1e9 intervals: the index type holds the counts, the address space does not
        let error = Mesh::<2>::box_mesh(
            [0.0; 2],
            [1.0; 2],
            [1_000_000_000; 2],
            [[BoundaryPart::Dirichlet, BoundaryPart::Neumann]; 2],
        )
        .unwrap_err()
        .to_string();
        assert!(
            error.contains("cells_per_side")
                && error.contains("more than this machine can allocate"),
            "{error}"
        );
    }

    #[test]
    fn box_mesh_rejects_zero_cells() {
        let sides = [[Dirichlet, Neumann]; 3];
        let message = error_message(Mesh::<3>::box_mesh([0.0; 3], [1.0; 3], [2, 0, 2], sides));
        assert!(message.contains("cells_per_side[1]"), "{message}");
        let message = error_message(Mesh::<3>::box_mesh(
            [0.0; 3],
            [1.0, 1.0, 0.0],
            [2, 2, 2],
            sides,
        ));
        assert!(message.contains("upper[2]"), "{message}");
    }

    #[test]
    fn mesh_rejects_other_invalid_input() {
        let (v, c, f, p) = triangle_parts([Dirichlet; 3]);
        let message = error_message(Mesh::new(v.clone(), vec![0, 1, 5], f.clone(), p.clone()));
        assert!(
            message.contains("cell 0") && message.contains("vertex 5"),
            "{message}"
        );
        let mut bad = v.clone();
        bad[1] = [f64::NAN, 0.0];
        let message = error_message(Mesh::new(bad, c.clone(), f.clone(), p.clone()));
        assert!(
            message.contains("vertex 1") && message.contains("NaN"),
            "{message}"
        );
        let mut extra = v.clone();
        extra.push([5.0, 5.0]);
        let message = error_message(Mesh::new(extra, c.clone(), f.clone(), p.clone()));
        assert!(
            message.contains("vertex 3") && message.contains("no cell"),
            "{message}"
        );
        // The same triangle twice: overlapping cells.
        let message = error_message(Mesh::new(v, vec![0, 1, 2, 1, 2, 0], f, p));
        assert!(message.contains("overlap"), "{message}");
        assert!(matches!(
            Mesh::<1>::new(vec![[0.0], [1.0]], vec![0, 1], vec![0], vec![Dirichlet]),
            Err(Error::InvalidInput(_))
        ));
    }

    #[test]
    fn mesh_rejects_facet_of_three_cells() {
        // Cells 0 and 2 lie above the segment 0–1, cell 1 below it.
        let vertices = vec![[0.0, 0.0], [1.0, 0.0], [0.5, 1.0], [0.5, -1.0], [0.5, 2.0]];
        let cells = vec![0, 1, 2, 1, 0, 3, 0, 1, 4];
        let facets = vec![1, 2, 2, 0, 0, 3, 3, 1, 1, 4, 4, 0, 0, 1];
        let message = error_message(Mesh::new(vertices, cells, facets, vec![Dirichlet; 7]));
        assert!(message.contains("more than two cells"), "{message}");
        assert!(message.contains("0 [0.0, 0.0], 1 [1.0, 0.0]"), "{message}");
    }
}
