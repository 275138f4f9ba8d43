//! Γ1 in discrete form: which Cartesian components of which nodes are prescribed, the values
//! u_D(x, t) they take, and the reaction on each named part.
//!
//! The paper clamps Γ1, u = 0 (2.5). Here Γ1 may carry named parts with a prescribed
//! displacement u_i = u_D,i(x, t) for some components i (a prescribed approach, a moving
//! grip); the other components of a part are free with zero traction (a roller or symmetry
//! plane fixes the normal component only). The Γ1 facets of no part stay clamped, u = 0: the
//! paper's case. At a node shared by several facets the constraints add up; a component
//! given by a part takes that part's value, else 0 if the node lies on a clamped facet. Where
//! parts that prescribe one component meet, their values must agree at every time: a node
//! given two values is an error naming both parts, the node and the time. A part may carry a
//! traction on its free components (zero by default: a frictionless roller), added to the load
//! like f2 on Γ2 (2.6). Where a roller or symmetry plane meets Γ3, a node keeps the contact
//! rule when the components it fixes are tangential to Γ3 (see [`crate::model::contact`]); a
//! clamped node of Γ3 leaves it.

use crate::error::{Error, Result};
use crate::fem::mesh::BoundaryPart;
use crate::fem::space::LagrangeSpace;
use crate::model::fields::{PointBoundaryVectorField, PointScalarField};

/// A named part of Γ1 with prescribed displacement components u_D,i(x, t).
#[derive(Clone)]
pub struct PrescribedDisplacement<const D: usize> {
    /// The part's name (a box side, a Gmsh group): names it in errors and in the reactions.
    pub name: String,
    /// Its boundary facets (indices of [`crate::fem::mesh::Mesh::facet`]); each must lie on Γ1
    /// ([`BoundaryPart::Dirichlet`]).
    pub facets: Vec<usize>,
    /// u_D,i(x, t) for each prescribed component i; `None` leaves component i free.
    pub components: [Option<PointScalarField<D>>; D],
    /// Traction f(x, t, ν) on the part's free components (its prescribed components are
    /// ignored); `None` is zero traction.
    pub traction: Option<PointBoundaryVectorField<D>>,
}

/// Relative tolerance within which two parts that meet must give a shared unknown one value,
/// relative to the larger of the two and of the largest prescribed value at that time: the
/// same function written two ways differs by a few rounding errors, a conflicting one by far
/// more.
pub const AGREEMENT: f64 = 1e-12;

/// The name of the reaction entry of the clamped facets of Γ1 (those of no part).
pub const CLAMPED_PART: &str = "clamped";

/// Where the constrained unknowns are and which part gives their value.
#[derive(Clone)]
pub struct DirichletConstraints<const D: usize> {
    /// Constrained unknowns (Cartesian components, node-major).
    pub constrained: Vec<bool>,
    /// For each constrained unknown, in increasing order: (unknown, owner), owner the index in
    /// `names` (the index past the parts is [`CLAMPED_PART`], value 0).
    pub dofs: Vec<(usize, usize)>,
    /// The other parts that prescribe a constrained unknown (unknown, part), in increasing
    /// order: where parts meet, each must give the owner's value.
    pub shared: Vec<(usize, usize)>,
    /// Names of the parts, then [`CLAMPED_PART`] if some Γ1 facet belongs to no part.
    pub names: Vec<String>,
    /// For each boundary facet, the part it belongs to (the first listed).
    pub facet_owner: Vec<Option<usize>>,
    /// The parts.
    pub parts: Vec<PrescribedDisplacement<D>>,
}

impl<const D: usize> DirichletConstraints<D> {
    /// Collects the constraints of `parts` and of the clamped facets of Γ1 on `space`.
    ///
    /// Errors ([`Error::InvalidInput`] naming the part): a facet index out of range; a facet on
    /// Γ3 (the part overlaps the contact boundary) or on Γ2; a part with no facet or with no
    /// prescribed component; two parts with one name.
    pub fn new(space: &LagrangeSpace<D>, parts: &[PrescribedDisplacement<D>]) -> Result<Self> {
        let mesh = space.mesh();
        let mut facet_owner: Vec<Option<usize>> = vec![None; mesh.num_facets()];
        for (p, part) in parts.iter().enumerate() {
            let fail = |message: String| {
                Error::InvalidInput(format!(
                    "prescribed displacement part `{}`: {message}",
                    part.name
                ))
            };
            if parts[..p].iter().any(|other| other.name == part.name) {
                return Err(fail("two parts have this name".into()));
            }
            if part.facets.is_empty() {
                return Err(fail("the part has no boundary facet".into()));
            }
            if part.components.iter().all(Option::is_none) {
                return Err(fail("no component is prescribed".into()));
            }
            for &f in &part.facets {
                if f >= mesh.num_facets() {
                    return Err(fail(format!(
                        "facet {f} does not exist ({} boundary facets)",
                        mesh.num_facets()
                    )));
                }
                let at = || mesh.vertex(mesh.facet(f)[0]);
                match mesh.facet_part(f) {
                    BoundaryPart::Dirichlet => {}
                    BoundaryPart::Contact => {
                        return Err(fail(format!(
                            "overlaps the contact boundary Γ3 (facet {f} at {:?})",
                            at()
                        )))
                    }
                    BoundaryPart::Neumann => {
                        return Err(fail(format!(
                            "facet {f} at {:?} lies on the traction boundary Γ2, not on Γ1",
                            at()
                        )))
                    }
                }
                facet_owner[f].get_or_insert(p);
            }
        }
        let clamped = parts.len();
        let mut owner: Vec<Option<usize>> = vec![None; space.num_nodes() * D];
        let mut shared: Vec<(usize, usize)> = Vec::new();
        let mut any_clamped = false;
        for (f, owner_of_facet) in facet_owner.iter().enumerate() {
            if mesh.facet_part(f) == BoundaryPart::Dirichlet && owner_of_facet.is_none() {
                any_clamped = true;
                for &node in space.facet_nodes(f) {
                    owner[node * D..node * D + D].fill(Some(clamped));
                }
            }
        }
        for (p, part) in parts.iter().enumerate() {
            for &f in &part.facets {
                for &node in space.facet_nodes(f) {
                    for (i, component) in part.components.iter().enumerate() {
                        let slot = &mut owner[node * D + i];
                        if component.is_none() {
                            continue;
                        }
                        match *slot {
                            None => *slot = Some(p),
                            Some(o) if o == clamped => *slot = Some(p),
                            Some(o) if o != p => shared.push((node * D + i, p)),
                            Some(_) => {}
                        }
                    }
                }
            }
        }
        let mut names: Vec<String> = parts.iter().map(|p| p.name.clone()).collect();
        if any_clamped {
            names.push(CLAMPED_PART.to_string());
        }
        Ok(Self {
            constrained: owner.iter().map(Option::is_some).collect(),
            dofs: owner
                .iter()
                .enumerate()
                .filter_map(|(dof, o)| o.map(|o| (dof, o)))
                .collect(),
            shared: {
                shared.sort_unstable();
                shared.dedup();
                shared
            },
            names,
            facet_owner,
            parts: parts.to_vec(),
        })
    }

    /// u_D(t) on the constrained unknowns (Cartesian, node-major, zero elsewhere).
    /// A non-finite value is an [`Error::NonFinite`] naming the part, node and component; two
    /// parts that give one unknown values further apart than [`AGREEMENT`] are an
    /// [`Error::ConflictingParts`] naming both parts, the node, the component and the time.
    pub fn values(&self, space: &LagrangeSpace<D>, time: f64) -> Result<Vec<f64>> {
        let mut values = vec![0.0; self.constrained.len()];
        for &(dof, owner) in &self.dofs {
            let Some(part) = self.parts.get(owner) else {
                continue;
            };
            let (node, i) = (dof / D, dof % D);
            let Some(field) = &part.components[i] else {
                continue;
            };
            let x = space.node(node);
            let value = field(&x, time);
            if !value.is_finite() {
                return Err(Error::NonFinite(format!(
                    "prescribed displacement of part `{}`, component {i}, at node {node} {x:?}, t = {time}: {value}",
                    part.name
                )));
            }
            values[dof] = value;
        }
        let largest = values.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        for &(dof, other) in &self.shared {
            let (node, i) = (dof / D, dof % D);
            let Some(field) = &self.parts[other].components[i] else {
                continue;
            };
            let x = space.node(node);
            let (given, other_value) = (values[dof], field(&x, time));
            let scale = given.abs().max(other_value.abs()).max(largest);
            // false for a NaN of the other part as for values apart
            let agree = (given - other_value).abs() <= AGREEMENT * scale;
            if !agree {
                let owner = self
                    .dofs
                    .binary_search_by_key(&dof, |&(d, _)| d)
                    .map(|k| self.names[self.dofs[k].1].as_str())
                    .unwrap_or("?");
                return Err(Error::ConflictingParts(format!(
                    "prescribed displacement parts `{owner}` and `{}` meet at node {node} \
                     {x:?} and give component {i} two values at t = {time}: {given} and \
                     {other_value} (prescribe the component in one of them, or make the values \
                     agree where the parts meet)",
                    self.parts[other].name
                )));
            }
        }
        Ok(values)
    }

    /// The resultant reaction of each part (order of `names`) from the nodal reactions
    /// (Cartesian, node-major).
    pub fn resultants(&self, reaction: &[f64]) -> Vec<[f64; D]> {
        let mut totals = vec![[0.0; D]; self.names.len()];
        for &(dof, owner) in &self.dofs {
            totals[owner][dof % D] += reaction[dof];
        }
        totals
    }
}
