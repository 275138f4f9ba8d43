//! Construction of the velocity operator of (5.1): the constrained unknowns (Γ1), the assembly
//! pattern, the quadrature and the symbolic analysis with the tangential contact unknowns
//! eliminated last.

use super::operator::VelocityOperator;
use crate::algebra::linalg::{CholeskySolver, FactorKind, SparsityPattern};
use crate::algebra::ordering::{
    fill_reducing_node_order, minimum_degree, minimum_degree_of_leading, NodeGraph,
};
use crate::error::{Error, Result};
use crate::fem::mesh::BoundaryPart;
use crate::fem::quadrature::QuadratureRule;
use crate::fem::space::{LagrangeSpace, Tabulation};
use crate::model::contact::{fixed_axis_column, ContactNodes};
use crate::model::laws::Viscosity;
use faer::sparse::{Pair, SparseColMat};
use std::sync::Arc;

impl<const D: usize> VelocityOperator<D> {
    /// Builds the pattern and does the symbolic analysis (expensive, once per mesh and law),
    /// with every component of every node of Γ1 constrained (the paper's u = 0 on Γ1, (2.5)).
    pub fn new(
        space: Arc<LagrangeSpace<D>>,
        law: Arc<dyn Viscosity<D>>,
        contact: Arc<ContactNodes<D>>,
    ) -> Result<Self> {
        let mut constrained = vec![false; space.num_nodes() * D];
        for node in space.boundary_nodes(BoundaryPart::Dirichlet) {
            constrained[node * D..node * D + D].fill(true);
        }
        Self::with_constraints(space, law, contact, constrained)
    }

    /// [`Self::new`] with the constrained unknowns given (Cartesian components, node-major):
    /// rollers and symmetry planes constrain some components of a node only. At a contact node
    /// the constraint acts in its frame: each fixed axis must be a tangent column of the frame
    /// ([`ContactNodes::with_constraints`] builds such frames; otherwise [`Error::InvalidInput`]
    /// naming the node).
    pub fn with_constraints(
        space: Arc<LagrangeSpace<D>>,
        law: Arc<dyn Viscosity<D>>,
        contact: Arc<ContactNodes<D>>,
        constrained_cartesian: Vec<bool>,
    ) -> Result<Self> {
        law.validate()?;
        let n_nodes = space.num_nodes();
        if constrained_cartesian.len() != n_nodes * D {
            return Err(Error::InvalidInput(format!(
                "{} constraint flags for {} unknowns",
                constrained_cartesian.len(),
                n_nodes * D
            )));
        }
        // the constrained unknowns of the system frame: at a contact node, the frame components
        // that are the fixed Cartesian axes
        let mut constrained = constrained_cartesian.clone();
        for (k, &node) in contact.nodes.iter().enumerate() {
            let frame = &contact.frames[k];
            let mut system = [false; D];
            for axis in 0..D {
                if !constrained_cartesian[node * D + axis] {
                    continue;
                }
                let column = fixed_axis_column(frame, axis).ok_or_else(|| {
                    Error::InvalidInput(format!(
                        "contact node {node} at {:?} has its component {axis} constrained, \
                         which is not a tangent axis of its contact frame (Γ1 fixes the \
                         normal displacement of a Γ3 node)",
                        space.node(node)
                    ))
                })?;
                system[column] = true;
            }
            constrained[node * D..node * D + D].copy_from_slice(&system);
        }
        let size = n_nodes * D;
        let n_local = space.nodes_per_cell() * D;
        let n_cells = space.mesh().num_cells();
        let constrained_count = constrained.iter().filter(|&&c| c).count();
        let mut pairs = Vec::with_capacity(n_cells * n_local * n_local + constrained_count);
        let mut dofs = vec![0isize; n_local];
        let mut constrained_cells = Vec::new();
        for cell in 0..n_cells {
            let mut touches = false;
            for (a, &node) in space.cell_nodes(cell).iter().enumerate() {
                for i in 0..D {
                    dofs[a * D + i] = if constrained[node * D + i] {
                        touches = true;
                        -1
                    } else {
                        (node * D + i) as isize
                    };
                }
            }
            if touches {
                constrained_cells.push(cell);
            }
            for &row in &dofs {
                for &col in &dofs {
                    pairs.push(Pair::new(row, col));
                }
            }
        }
        for (dof, _) in constrained.iter().enumerate().filter(|(_, &c)| c) {
            pairs.push(Pair::new(dof as isize, dof as isize));
        }
        let pattern = SparsityPattern::from_pairs(size, &pairs)?;
        drop(pairs);
        let degree = if law.is_linear() {
            2 * space.degree() - 2
        } else {
            2 * space.degree()
        };
        let tabulation =
            Tabulation::cell_rule(space.element(), &QuadratureRule::<D>::simplex(degree));
        let tangential = contact
            .nodes
            .iter()
            .flat_map(|&node| (1..D).map(move |i| node * D + i))
            .collect();
        let mut operator = Self {
            space,
            law,
            contact,
            constrained,
            constrained_cartesian,
            constrained_cells,
            prescribed: vec![0.0; size],
            prescribed_cartesian: vec![0.0; size],
            lifting_scale: 0.0,
            pattern,
            tabulation,
            solver: unanalysed_solver()?,
            matrix: SparseColMat::<usize, f64>::try_new_from_triplets(0, 0, &[]).map_err(|e| {
                Error::LinearAlgebra {
                    context: "velocity operator".into(),
                    message: format!("{e:?}"),
                }
            })?,
            tangential,
            schur: None,
            factor_generation: 0,
            reduction: None,
            trailing: None,
            linearized_at: None,
            frozen_contraction: f64::INFINITY,
            implicit: None,
            matrix_is_plain: true,
            normals_last: false,
            analysed: false,
        };
        operator.matrix = operator.assemble(None)?;
        // The symbolic analysis ([`Self::analyse`]) is made by the first factorization: an
        // elimination order with the tangential contact unknowns at the end, so that the
        // trailing block L_cc of the factor gives the condensed operator S = L_cc L_ccᵀ
        // directly, without m solves.
        Ok(operator)
    }

    /// Drops the friction term of (5.1) (a contact law with p_τ ≡ 0, μ = 0): the tangential
    /// contact unknowns become ordinary unknowns, eliminated where the fill-reducing order puts
    /// them, and no condensed friction problem is solved (a new symbolic analysis). A step
    /// with a positive friction bound is then refused.
    pub fn without_friction(&mut self) -> Result<()> {
        self.arrange_contact(false, self.normals_last)
    }

    /// Moves the normal contact unknowns to the trailing block of the factor, just before the
    /// tangential ones (a new symbolic analysis). With a linear 𝒜 and the implicit normal
    /// compliance, a Newton tangent H + D then changes only that block: each Newton iteration
    /// factorizes the dense Schur complement S_c + D of the contact unknowns instead of the
    /// whole body.
    pub fn eliminate_normals_last(&mut self) -> Result<()> {
        self.arrange_contact(!self.tangential.is_empty(), true)
    }

    /// [`Self::without_friction`] (`friction = false`) and [`Self::eliminate_normals_last`]
    /// (`normals_last = true`) in one symbolic analysis, done only if something changes.
    pub fn arrange_contact(&mut self, friction: bool, normals_last: bool) -> Result<()> {
        if friction && self.tangential.is_empty() && !self.contact.is_empty() {
            return Err(Error::InvalidInput(
                "velocity operator: friction cannot be restored once dropped".into(),
            ));
        }
        let drop_friction = !friction && !self.tangential.is_empty();
        if !drop_friction && normals_last == self.normals_last {
            return Ok(());
        }
        if drop_friction {
            self.tangential.clear();
            self.schur = None;
        }
        self.normals_last = normals_last;
        // analysed again by the next factorization
        self.solver = unanalysed_solver()?;
        self.trailing = None;
        self.analysed = false;
        Ok(())
    }

    /// The symbolic analysis: a fill-reducing order with the contact unknowns last. The
    /// candidates are the node orders of [`fill_reducing_node_order`] and, in 3D, minimum
    /// degree, each with the contact unknowns moved to the end, and, when some unknowns go
    /// last, minimum degree on the graph of the other unknowns alone
    /// ([`minimum_degree_of_leading`]: the order of the leading block that knows the trailing
    /// unknowns are eliminated after it). The candidate whose numeric factorization costs the
    /// fewest operations ([`CholeskySolver::factor_flops`]) is kept. Dissection wins on the
    /// structured box meshes; on the graded unstructured meshes of the 3D validation the
    /// leading-block order does, e.g. the P2 hemisphere (42 k unknowns, its 2111 normal contact
    /// unknowns last): 2.24e11 operations (8.6e7 factor entries) against 2.45e11 (8.9e7) for
    /// minimum degree moved and 2.49e11 (8.3e7) for dissection moved, one factorization on
    /// one thread 5.9 s against 6.3 s and 7.3 s. Counting the entries instead would keep the
    /// dearest of the three.
    pub(super) fn analyse(&mut self) -> Result<()> {
        let space = &self.space;
        let graph = NodeGraph::from_cells(
            space.num_nodes(),
            (0..space.mesh().num_cells()).map(|c| space.cell_nodes(c)),
        );
        let mut node_orders = vec![fill_reducing_node_order(space.nodes(), &graph)?];
        if D == 3 {
            node_orders.push(minimum_degree(&graph)?);
        }
        let normals: Vec<usize> = if self.normals_last {
            self.contact.nodes.iter().map(|&node| node * D).collect()
        } else {
            Vec::new()
        };
        let mut is_trailing = vec![false; self.pattern.size()];
        for &dof in self.tangential.iter().chain(&normals) {
            is_trailing[dof] = true;
        }
        // the contact block of a Newton tangent needs the supernodal factor's trailing block
        let kind = if self.normals_last {
            FactorKind::Supernodal
        } else {
            FactorKind::Auto
        };
        let trailing = || normals.iter().chain(&self.tangential).copied();
        let mut orderings: Vec<Vec<usize>> = node_orders
            .iter()
            .map(|node_order| {
                node_order
                    .iter()
                    .flat_map(|&node| (0..D).map(move |i| node * D + i))
                    .filter(|&dof| !is_trailing[dof])
                    .chain(trailing())
                    .collect()
            })
            .collect();
        if is_trailing.contains(&true) {
            let leading = minimum_degree_of_leading::<D>(&graph, &is_trailing)?;
            orderings.push(leading.into_iter().chain(trailing()).collect());
        }
        let mut best: Option<(f64, CholeskySolver)> = None;
        for ordering in &orderings {
            let solver = CholeskySolver::analyse_with_ordering_as(
                &self.matrix,
                ordering,
                kind,
                "velocity operator (5.1)",
            )?;
            let flops = solver.factor_flops();
            if best.as_ref().is_none_or(|(kept, _)| flops < *kept) {
                best = Some((flops, solver));
            }
        }
        if let Some((_, solver)) = best {
            self.solver = solver;
        }
        self.trailing = None;
        self.analysed = true;
        Ok(())
    }
}

/// The solver of an empty matrix: the place of the velocity factor before its analysis.
fn unanalysed_solver() -> Result<CholeskySolver> {
    CholeskySolver::analyse(
        &SparseColMat::<usize, f64>::try_new_from_triplets(0, 0, &[]).map_err(|e| {
            Error::LinearAlgebra {
                context: "velocity operator".into(),
                message: format!("{e:?}"),
            }
        })?,
        "velocity operator",
    )
}
