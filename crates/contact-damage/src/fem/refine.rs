//! Uniform (red) refinement of simplicial meshes: every edge is halved, a triangle is split
//! into 4 and a tetrahedron into 8, and every boundary facet into the 2 (D = 2) or 4 (D = 3)
//! facets on its side, each keeping the boundary part Γ1, Γ2 or Γ3 (paper §2) of its parent.
//!
//! Theorem 5.2 assumes a regular family of meshes (h_K/ρ_K bounded). The 4 triangles of a
//! triangle are similar to it, so the shape measure ([`crate::fem::quality`]) does not change in
//! 2D. A tetrahedron gives 4 corner tetrahedra similar to it and an octahedron that is cut
//! along one of its three diagonals; the **shortest diagonal** is taken (ties: the first of
//! (x01, x23), (x02, x13), (x03, x12)), the rule of Zhang (1995) and Bank et al., which keeps
//! the shape measure bounded over refinements (checked by the tests below and reported per
//! level by `verify`). Every child is oriented positively (two vertices swapped if needed), so
//! the result passes [`Mesh::new`], which validates it.
//!
//! Numbering, so that callers can follow sets of vertices and facets through a refinement:
//! the vertices of the coarse mesh keep their indices and the edge midpoints follow, in the
//! order their edges are first met walking the cells; the children of cell c are the cells
//! 2^D·c .. 2^D·(c + 1), and the children of boundary facet f are the facets
//! 2^(D−1)·f .. 2^(D−1)·(f + 1) ([`facet_children`]). Midpoints are computed as
//! (a + b)/2, so the children's volumes add up to the parent's up to rounding.

use std::collections::HashMap;
use std::ops::Range;

use crate::error::Result;
use crate::fem::mesh::{determinant, Mesh};
use nalgebra::SMatrix;

/// The mesh refined once uniformly (see the module documentation); boundary parts are kept.
///
/// Errors: those of [`Mesh::new`] on the refined mesh (which cannot occur for a valid input
/// mesh, but are reported rather than assumed).
pub fn refine_uniform<const D: usize>(mesh: &Mesh<D>) -> Result<Mesh<D>> {
    let mut vertices = mesh.vertices().to_vec();
    let mut midpoints: HashMap<(usize, usize), usize> = HashMap::new();
    let mut midpoint = |a: usize, b: usize, vertices: &mut Vec<[f64; D]>| -> usize {
        let key = (a.min(b), a.max(b));
        *midpoints.entry(key).or_insert_with(|| {
            vertices.push(mesh.edge_point(a, b));
            vertices.len() - 1
        })
    };
    let mut curved_edges: Vec<((usize, usize), [f64; D])> = Vec::new();

    let mut cells = Vec::with_capacity((mesh.num_cells() * (D + 1)) << D);
    for c in 0..mesh.num_cells() {
        let v = mesh.cell(c).to_vec();
        // m[i][j]: midpoint of edge (i, j), m[i][i] = vertex i
        let mut m = [[0usize; 4]; 4];
        for i in 0..=D {
            m[i][i] = v[i];
            for j in i + 1..=D {
                m[i][j] = midpoint(v[i], v[j], &mut vertices);
                m[j][i] = m[i][j];
            }
        }
        let children: Vec<Vec<usize>> = if D == 2 {
            vec![
                vec![m[0][0], m[0][1], m[0][2]],
                vec![m[0][1], m[1][1], m[1][2]],
                vec![m[0][2], m[1][2], m[2][2]],
                vec![m[0][1], m[1][2], m[0][2]],
            ]
        } else {
            tetrahedron_children(&m, &vertices)
        };
        if mesh.is_cell_curved(c) {
            curved_child_edges(&mesh.curved_map(c), &m, &children, &mut curved_edges);
        }
        for mut child in children {
            orient_positively::<D>(&mut child, &vertices);
            cells.extend(child);
        }
    }

    let mut facets = Vec::with_capacity((mesh.num_facets() * D) << (D - 1));
    let mut parts = Vec::with_capacity(mesh.num_facets() << (D - 1));
    for f in 0..mesh.num_facets() {
        let v = mesh.facet(f).to_vec();
        let mut m = [[0usize; 3]; 3];
        for i in 0..D {
            m[i][i] = v[i];
            for j in i + 1..D {
                m[i][j] = midpoint(v[i], v[j], &mut vertices);
                m[j][i] = m[i][j];
            }
        }
        if D == 2 {
            facets.extend([m[0][0], m[0][1], m[0][1], m[1][1]]);
        } else {
            facets.extend([m[0][0], m[0][1], m[0][2]]);
            facets.extend([m[0][1], m[1][1], m[1][2]]);
            facets.extend([m[0][2], m[1][2], m[2][2]]);
            facets.extend([m[0][1], m[1][2], m[0][2]]);
        }
        parts.extend(std::iter::repeat_n(mesh.facet_part(f), 1 << (D - 1)));
    }
    let refined = Mesh::new(vertices, cells, facets, parts)?;
    if curved_edges.is_empty() {
        Ok(refined)
    } else {
        refined.with_curved_edges(curved_edges)
    }
}

/// The points of the edges of the children of a curved cell: the parent's P2 map at the middle
/// of each child edge in the parent's reference coordinates (vertex i at ê_i, the midpoint of
/// edge (i, j) at (ê_i + ê_j)/2; `m` as in [`refine_uniform`]), so that the children carry the
/// parent's geometry exactly (its map restricted to a child is quadratic).
fn curved_child_edges<const D: usize>(
    map: &crate::fem::curved::CurvedMap<D>,
    m: &[[usize; 4]; 4],
    children: &[Vec<usize>],
    out: &mut Vec<((usize, usize), [f64; D])>,
) {
    let unit = |i: usize| -> [f64; D] { std::array::from_fn(|k| f64::from(u8::from(k + 1 == i))) };
    let reference_of = |id: usize| -> [f64; D] {
        for (i, row) in m.iter().enumerate().take(D + 1) {
            if let Some(j) = (i..=D).find(|&j| row[j] == id) {
                let (a, b) = (unit(i), unit(j));
                return std::array::from_fn(|k| 0.5 * (a[k] + b[k]));
            }
        }
        unreachable!("a child vertex is a vertex or an edge midpoint of its parent")
    };
    for child in children {
        for (k, &p) in child.iter().enumerate() {
            for &q in &child[k + 1..] {
                let (a, b) = (reference_of(p), reference_of(q));
                let middle: [f64; D] = std::array::from_fn(|i| 0.5 * (a[i] + b[i]));
                out.push(((p, q), map.point(&middle)));
            }
        }
    }
}

/// The mesh refined `times` times by [`refine_uniform`] (`times = 0`: a copy).
pub fn refine_times<const D: usize>(mesh: &Mesh<D>, times: usize) -> Result<Mesh<D>> {
    let mut current = mesh.clone();
    for _ in 0..times {
        current = refine_uniform(&current)?;
    }
    Ok(current)
}

/// The indices, in the refined mesh, of the boundary facets that boundary facet `f` of the
/// coarse mesh is split into by [`refine_uniform`].
pub fn facet_children<const D: usize>(f: usize) -> Range<usize> {
    let n = 1 << (D - 1);
    n * f..n * (f + 1)
}

/// The children, in the refined mesh, of a set of boundary facets of the coarse mesh (e.g. the
/// facets of one physical group), in order.
pub fn refined_facets<const D: usize>(facets: &[usize]) -> Vec<usize> {
    facets
        .iter()
        .flat_map(|&f| facet_children::<D>(f))
        .collect()
}

fn squared_distance<const D: usize>(vertices: &[[f64; D]], a: usize, b: usize) -> f64 {
    (0..D)
        .map(|i| (vertices[a][i] - vertices[b][i]).powi(2))
        .sum()
}

/// The 8 children of a tetrahedron with vertex/midpoint table `m`: 4 corners and the
/// octahedron cut along its shortest diagonal.
fn tetrahedron_children<const D: usize>(
    m: &[[usize; 4]; 4],
    vertices: &[[f64; D]],
) -> Vec<Vec<usize>> {
    let mut children: Vec<Vec<usize>> = (0..4).map(|i| (0..4).map(|j| m[i][j]).collect()).collect();
    // the three diagonals of the octahedron join midpoints of opposite edges
    let pairs = [((0, 1), (2, 3)), ((0, 2), (1, 3)), ((0, 3), (1, 2))];
    let length = |k: usize| {
        let ((a, b), (c, d)) = pairs[k];
        squared_distance(vertices, m[a][b], m[c][d])
    };
    let shortest = (0..3)
        .min_by(|&a, &b| length(a).total_cmp(&length(b)).then(a.cmp(&b)))
        .unwrap_or(0);
    let ((a, b), (c, d)) = pairs[shortest];
    let (p, q) = (m[a][b], m[c][d]);
    // the other two pairs of opposite midpoints, (r, r') and (s, s'): the cycle r, s, r', s'
    let others: Vec<_> = (0..3)
        .filter(|&k| k != shortest)
        .map(|k| pairs[k])
        .collect();
    let ((r0, r1), (r2, r3)) = others[0];
    let ((s0, s1), (s2, s3)) = others[1];
    let ring = [m[r0][r1], m[s0][s1], m[r2][r3], m[s2][s3]];
    for k in 0..4 {
        children.push(vec![p, q, ring[k], ring[(k + 1) % 4]]);
    }
    children
}

/// Swaps the last two vertices of `simplex` if its orientation is negative.
fn orient_positively<const D: usize>(simplex: &mut [usize], vertices: &[[f64; D]]) {
    let origin = vertices[simplex[0]];
    let jacobian = SMatrix::<f64, D, D>::from_fn(|i, j| vertices[simplex[j + 1]][i] - origin[i]);
    if determinant(&jacobian) < 0.0 {
        simplex.swap(D - 1, D);
    }
}

#[cfg(test)]
mod tests;
