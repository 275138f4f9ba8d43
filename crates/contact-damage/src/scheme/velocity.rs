//! The velocity step (5.1): a Tresca-type variational inequality with the known normal load
//! p_ν(u_{n−1,ν} − g) and the known friction bound s = p_τ(u_{n−1,ν} − g).
//!
//! With the nodal rule of [`crate::model::contact`], (5.1) is the minimization of
//!
//! J(v) = Σ_K ∫_K Φ(ε(v)) dx − ⟨F, v⟩ + Σ_a w_a |v_τ(a)|,   w_a = ω_a s_a,
//!
//! (Φ the potential of 𝒜, F the load of the step). Unknowns are nodal velocities, expressed in
//! the frame (ν_a, t_1, …) at contact nodes; constrained unknowns (Γ1) keep identity rows.
//!
//! **Prescribed displacement.** On a constrained unknown c (a Cartesian component of a node of
//! Γ1; contact nodes are never constrained) the velocity is given, v_c = p_c (the scheme passes
//! p_c = (u_D(t_n) − u_{n−1,c})/k, so that u_n = u_D(t_n)); the paper's u = 0 on Γ1 is p = 0.
//! The constrained unknowns are eliminated: their rows are identity rows, their columns are
//! dropped from the operator, and the coupling is moved to the right-hand side (linear 𝒜:
//! F_f − K_fc p_c; nonlinear 𝒜: the Newton iterates carry v_c = p_c and the increments vanish
//! there). The friction condensation acts on the free tangential contact unknowns only, and the
//! KKT residual is measured on the free unknowns (plus |v_c − p_c| on the constrained ones). The
//! reaction on a constrained unknown is the residual of the equilibrium there,
//! R_c = ⟨𝒜ε(v), ε(φ_c)⟩ − F_c = ∫_Γ1 σν·φ_c dΓ (the force of the support on the body).
//!
//! **Algorithm.** Proximal Newton, a generalized Newton method on the whole nonsmooth system: at
//! an iterate v_k the smooth part is replaced by its second-order model with the exact tangent
//! matrix H_k = ∫ d𝒜(ε(v_k)) assembled at v_k, and the nonsmooth model problem
//! min ½ dᵀH_k d + ⟨N(v_k) − F, d⟩ + Σ_a w_a |v_τ(a) + d_τ(a)| is condensed exactly onto the
//! tangential contact unknowns c with the Schur complement S = (E_cᵀ H_k^{-1} E_c)^{-1} and
//! solved exactly by [`crate::solvers::friction`]. It is solved in increment form (right-hand side
//! F − N(v_k), no cancellation against H_k v_k). For a linear 𝒜 the model is J itself, so one
//! iteration solves (5.1) exactly, and H, its Cholesky factor and S are computed once per run
//! and reused in every time step. With the tangential unknowns eliminated last (a supernodal
//! factor P H Pᵀ = L Lᵀ, [`crate::algebra::linalg::CholeskySolver::trailing_factor`]) a model solve is
//! ONE sparse solve split in its halves: the forward half z = L⁻¹ P b gives the condensed
//! right-hand side S (H⁻¹ b)_c = L_cc z_c, the friction forces change only the trailing block
//! of z (z_c ← z_c − L_cc⁻¹ W λ), and the backward half gives the velocity
//! (`VelocityOperator::solve_model`; two solves with a simplicial factor).
//!
//! **Merit function and stop test (nonlinear 𝒜).** The KKT residual of an iterate v is computed
//! from v alone: the multipliers are the best ones at v ([`VelocityOperator::best_multipliers`]:
//! v_τ/|v_τ| at slipping nodes, the projection onto the unit ball of the tangential force
//! imbalance at the others), so dual feasibility and complementarity hold exactly and the
//! residual r(v) is the relative stationarity of [`VelocityOperator::kkt_residual`]. The
//! iteration stops when r(v) ≤ 10⁻² × tolerance (head room under the certificate); the stop test
//! and the reported residual are the same number.
//!
//! **Globalization.** A step v + α d, tried from α = 1 by halving, is accepted when either
//! (a) r(v + αd) ≤ ½ min_{j ≤ k} r(v_j) (a new record of the residual by a fixed factor), or
//! (b) the Armijo test J(v + αd) ≤ J(v) + σ α Δ, Δ = ⟨N(v) − F, d⟩ + Σ w_a(|v_τ + d_τ| − |v_τ|)
//! < 0, holds, with J(v + αd) − J(v) summed cell by cell.
//! Why both: (b) alone stalls at round-off, because near the solution the decrease of J is
//! O(r²) and falls below the rounding error of J (≈ 1e-16 |J|) long before r reaches 1e-12:
//! every step is then rejected (observed: residuals stuck near 1e-8 to 1e-10). Test (a) measures
//! progress in the quantity that is certified and that Newton's method reduces quadratically,
//! so in the region of fast convergence full steps are taken and the residual goes to the
//! rounding level in a few iterations. Global convergence from any start: if (a) is used
//! infinitely often, the record of r tends to 0 and, J being strongly convex, the record iterates
//! converge to the solution (‖v − v*‖ ≤ C r(v)); otherwise, after the last use of (a), the
//! iteration is the Armijo-damped proximal Newton method with a positive definite model, which
//! converges globally for a strongly convex J (Lee, Sun & Saunders, SIAM J. Optim. 24, 2014).
//! When no step passes either test, the iteration is at the rounding level: the step ends with
//! its residual if that meets the certificate, else with a no-convergence error carrying the
//! residual history.

use crate::algebra::linalg::{
    dot, max_abs, max_abs_free, multiply_symmetric, CholeskySolver, SparsityPattern,
};
use crate::algebra::ordering::{fill_reducing_node_order, NodeGraph};
use crate::error::{Error, Result};
use crate::fem::mesh::BoundaryPart;
use crate::fem::quadrature::QuadratureRule;
use crate::fem::space::{LagrangeSpace, Tabulation};
use crate::model::contact::{ContactNodes, ContactStatus};
use crate::model::laws::{ContactLaw, Viscosity};
use crate::scheme::assembly::viscous_element_matrix;
use crate::solvers::friction::{CondensedFriction, FrictionSettings};
use faer::sparse::{Pair, SparseColMat};
use faer::Mat;
use nalgebra::SVector;
use rayon::prelude::*;
use std::sync::Arc;

/// Settings of the velocity step solver.
#[derive(Debug, Clone, Copy)]
pub struct VelocitySettings {
    /// Stop when the relative KKT residual is below this value.
    pub tolerance: f64,
    /// Maximal number of (proximal) Newton iterations.
    pub max_newton: usize,
    /// Settings of the condensed friction solver.
    pub friction: FrictionSettings,
}

impl Default for VelocitySettings {
    fn default() -> Self {
        Self {
            tolerance: 1e-10,
            max_newton: 50,
            friction: FrictionSettings::default(),
        }
    }
}

/// Statistics of one velocity step.
#[derive(Debug, Clone, Default)]
pub struct VelocityStats {
    /// Outer (proximal) Newton iterations; for a linear 𝒜, 1 plus the refinement passes.
    pub newton_iterations: usize,
    /// Semismooth Newton iterations of the condensed friction problems.
    pub friction_iterations: usize,
    /// Proximal-gradient iterations of the condensed friction problems (globalization).
    pub friction_gradient_iterations: usize,
    /// Numeric Cholesky factorizations done in this step.
    pub factorizations: usize,
    /// Relative KKT residual of (5.1) on the full system, see [`VelocityOperator::kkt_residual`].
    pub kkt_residual: f64,
    /// The relative KKT residual after each outer iteration (the last entry is `kkt_residual`).
    pub residual_history: Vec<f64>,
}

/// The data of one velocity step in Cartesian node-major form.
pub struct VelocityData<'a> {
    /// Load vector ⟨f_n, φ_a e_i⟩ − ⟨G(ε(u_{n−1}), β_{n−1}), ε(φ_a e_i)⟩ (normal compliance excluded).
    pub load: &'a [f64],
    /// Normal pressure p_ν(u_{n−1,ν}(a) − g(a)) per contact node.
    pub normal_pressure: &'a [f64],
    /// Friction bound s_a = p_τ(u_{n−1,ν}(a) − g(a)) per contact node.
    pub friction_bound: &'a [f64],
    /// `Some` for the implicit variant of (5.1): the normal compliance is taken at
    /// u_n = u_{n−1} + k v_n instead of u_{n−1} (`normal_pressure` is then not used).
    pub implicit_contact: Option<ImplicitNormalCompliance>,
    /// Prescribed velocities p_c on the constrained unknowns (Cartesian, node-major, the size of
    /// `load`; the entries of free unknowns are ignored). `None` is p = 0 (u = 0 on Γ1, (2.5)).
    pub prescribed: Option<&'a [f64]>,
}

/// The implicit normal compliance of a velocity step: ⟨p_ν(u_{n−1,ν} + k v_ν − g), w_ν⟩ in place
/// of the explicit p_ν(u_{n−1,ν} − g) of (5.1). It adds the convex term
/// Σ_a ω_a P(r_a + k v_ν(a))/k (P' = p_ν) to J, so the step stays a strongly convex minimization
/// and is solved by the nonlinear path (generalized Newton with the tangent ω_a k p_ν′). The
/// friction bound stays explicit, s_a = p_τ(r_a): the step is then an exact minimization, with
/// no fixed point on the bound.
#[derive(Clone)]
pub struct ImplicitNormalCompliance {
    /// r_a = u_{n−1,ν}(a) − g(a) per contact node.
    pub previous_penetration: Vec<f64>,
    /// The time step k > 0.
    pub time_step: f64,
    /// The law p_ν with its energy and derivative.
    pub law: Arc<dyn ContactLaw>,
}

impl ImplicitNormalCompliance {
    /// The penetration at the end of the step, r_a + k v_ν(a), at contact node `index`.
    pub fn penetration(&self, index: usize, normal_velocity: f64) -> f64 {
        self.previous_penetration[index] + self.time_step * normal_velocity
    }
}

/// Result of a velocity step.
#[derive(Debug, Clone)]
pub struct VelocitySolution {
    /// Nodal velocities, Cartesian, node-major.
    pub velocity: Vec<f64>,
    /// Friction multipliers λ_a (|λ_a| ≤ 1) per contact node, D−1 tangential components;
    /// the friction traction at node a is −s_a λ_a (in the tangent frame).
    pub multipliers: Vec<f64>,
    /// Status of each contact node.
    pub status: Vec<ContactStatus>,
    /// Reactions R_c = ⟨𝒜ε(v), ε(φ_c)⟩ − F_c on the constrained unknowns (Cartesian,
    /// node-major; zero on free unknowns): the force of the support on the body.
    pub reaction: Vec<f64>,
    /// Solver statistics.
    pub stats: VelocityStats,
}

/// Linear algebra of the velocity step for one mesh, law and contact boundary: the assembly
/// pattern (with frames and constrained rows), the Cholesky solver (symbolic analysis once) and
/// the condensed Schur complement on the tangential contact unknowns.
pub struct VelocityOperator<const D: usize> {
    space: Arc<LagrangeSpace<D>>,
    law: Arc<dyn Viscosity<D>>,
    contact: Arc<ContactNodes<D>>,
    /// Constrained unknowns (Cartesian components of Γ1 nodes), node-major.
    constrained: Vec<bool>,
    /// Cells with a constrained unknown (where the reactions and the lifting are assembled).
    constrained_cells: Vec<usize>,
    /// Prescribed velocities of the current step on the constrained unknowns (zero elsewhere).
    prescribed: Vec<f64>,
    /// max |(K p)_f| over the free unknowns of the current step (scale of the KKT residual).
    lifting_scale: f64,
    pattern: SparsityPattern,
    tabulation: Tabulation<D>,
    solver: CholeskySolver,
    matrix: SparseColMat<usize, f64>,
    /// System indices of the tangential contact unknowns, (D−1) per contact node.
    tangential: Vec<usize>,
    /// S = (E_cᵀ H^{-1} E_c)^{-1} for the current factorization.
    schur: Mat<f64>,
    /// The trailing block of a supernodal factor whose last unknowns are the tangential ones
    /// (then S = L_cc L_ccᵀ and a step needs one solve, [`Self::solve_model`]).
    trailing: Option<TrailingFactor>,
    /// The velocity at which H was last assembled (nonlinear 𝒜).
    linearized_at: Option<Vec<f64>>,
    /// The implicit normal compliance of the current step, if any.
    implicit: Option<ImplicitNormalCompliance>,
    /// True while `matrix` is the plain viscous operator (false after a Newton tangent).
    matrix_is_plain: bool,
}

/// The trailing block L_cc of the velocity factor when the tangential contact unknowns are
/// eliminated last (elimination order), and the position in `tangential` of each of its
/// unknowns.
#[derive(Debug, Clone)]
struct TrailingFactor {
    factor: Mat<f64>,
    index: Vec<usize>,
}

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
    /// rollers and symmetry planes constrain some components of a node only. A contact node
    /// may not be constrained ([`Error::InvalidInput`] naming the node).
    pub fn with_constraints(
        space: Arc<LagrangeSpace<D>>,
        law: Arc<dyn Viscosity<D>>,
        contact: Arc<ContactNodes<D>>,
        constrained: Vec<bool>,
    ) -> Result<Self> {
        law.validate()?;
        let n_nodes = space.num_nodes();
        if constrained.len() != n_nodes * D {
            return Err(Error::InvalidInput(format!(
                "{} constraint flags for {} unknowns",
                constrained.len(),
                n_nodes * D
            )));
        }
        if let Some(&node) = contact
            .nodes
            .iter()
            .find(|&&node| constrained[node * D..node * D + D].contains(&true))
        {
            return Err(Error::InvalidInput(format!(
                "contact node {node} at {:?} has a constrained component (Γ1 and Γ3 overlap)",
                space.node(node)
            )));
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
            constrained_cells,
            prescribed: vec![0.0; size],
            lifting_scale: 0.0,
            pattern,
            tabulation,
            solver: CholeskySolver::analyse(
                &SparseColMat::<usize, f64>::try_new_from_triplets(0, 0, &[]).map_err(|e| {
                    Error::LinearAlgebra {
                        context: "velocity operator".into(),
                        message: format!("{e:?}"),
                    }
                })?,
                "velocity operator",
            )?,
            matrix: SparseColMat::<usize, f64>::try_new_from_triplets(0, 0, &[]).map_err(|e| {
                Error::LinearAlgebra {
                    context: "velocity operator".into(),
                    message: format!("{e:?}"),
                }
            })?,
            tangential,
            schur: Mat::zeros(0, 0),
            trailing: None,
            linearized_at: None,
            implicit: None,
            matrix_is_plain: true,
        };
        operator.matrix = operator.assemble(None)?;
        // Elimination order of the nodes (the D unknowns of a node together, see
        // `fill_reducing_node_order`), with the tangential contact unknowns moved to the end.
        // Then the trailing
        // block L_cc of the factor gives the condensed operator S = L_cc L_ccᵀ directly, without
        // m solves. (Measured, 3D P1 N = 32: nested dissection 0.98e8 factor entries against
        // 1.74e8 for AMD, 1.7× faster factorization; in 2D the two are within 15%.)
        let space = &operator.space;
        let graph = NodeGraph::from_cells(
            space.num_nodes(),
            (0..space.mesh().num_cells()).map(|c| space.cell_nodes(c)),
        );
        let node_order = fill_reducing_node_order(space.nodes(), &graph)?;
        let mut is_tangential = vec![false; operator.pattern.size()];
        for &dof in &operator.tangential {
            is_tangential[dof] = true;
        }
        let ordering: Vec<usize> = node_order
            .iter()
            .flat_map(|&node| (0..D).map(move |i| node * D + i))
            .filter(|&dof| !is_tangential[dof])
            .chain(operator.tangential.iter().copied())
            .collect();
        operator.solver = CholeskySolver::analyse_with_ordering(
            &operator.matrix,
            &ordering,
            "velocity operator (5.1)",
        )?;
        Ok(operator)
    }

    /// The Cholesky solver of the operator (its factor once a step has been solved); for
    /// benchmarks of the triangular solves.
    pub fn solver(&self) -> &CholeskySolver {
        &self.solver
    }

    /// Makes the held factor that of the viscous operator H (the matrix of a linear step,
    /// [`Self::assemble`]`(None)`), factorizing it now if the operator holds none or holds a
    /// Newton tangent: the step limit ([`crate::scheme::stability`]) solves with it before the first
    /// step, which then reuses it. Afterwards [`Self::solver`] solves with H and
    /// [`Self::factored_matrix`] is H.
    pub fn factorize_viscous(&mut self) -> Result<()> {
        if !self.matrix_is_plain {
            self.matrix = self.assemble(None)?;
            self.matrix_is_plain = true;
            self.linearized_at = None;
            self.factorize()
        } else if !self.solver.is_factorized() {
            self.factorize()
        } else {
            Ok(())
        }
    }

    /// The matrix of the held factor: H, or the Newton tangent of the last nonlinear step.
    pub fn factored_matrix(&self) -> &SparseColMat<usize, f64> {
        &self.matrix
    }

    /// The finite element space.
    pub fn space(&self) -> &Arc<LagrangeSpace<D>> {
        &self.space
    }

    /// The contact nodes.
    pub fn contact(&self) -> &Arc<ContactNodes<D>> {
        &self.contact
    }

    /// Number of unknowns (including constrained ones, which carry identity rows).
    pub fn size(&self) -> usize {
        self.pattern.size()
    }

    /// Number of stored nonzeros of the operator.
    pub fn nnz(&self) -> usize {
        self.pattern.nnz()
    }

    /// Assembles the (linearized) operator in the system frame, in parallel.
    pub fn assemble(&self, velocity_system: Option<&[f64]>) -> Result<SparseColMat<usize, f64>> {
        let cartesian = velocity_system.map(|v| self.to_cartesian(v));
        let n_local = self.space.nodes_per_cell() * D;
        let block = n_local * n_local;
        let n_cells = self.space.mesh().num_cells();
        let mut values = vec![0.0; self.pattern.value_count()];
        let (cell_values, constrained_values) = values.split_at_mut(n_cells * block);
        cell_values
            .par_chunks_mut(block)
            .enumerate()
            .for_each(|(cell, out)| {
                viscous_element_matrix(
                    self.law.as_ref(),
                    &self.space,
                    &self.tabulation,
                    cell,
                    cartesian.as_deref(),
                    out,
                );
                self.rotate_element_matrix(cell, out);
            });
        constrained_values.fill(1.0);
        let mut matrix = self.pattern.matrix(&values)?;
        if let (Some(implicit), Some(velocity)) = (&self.implicit, velocity_system) {
            // the tangent of the implicit normal compliance: ω_a k p_ν′(r_a + k v_ν(a))
            for (k, &node) in self.contact.nodes.iter().enumerate() {
                let dof = node * D;
                let stiffness = self.contact.weights[k]
                    * implicit.time_step
                    * implicit
                        .law
                        .normal_stiffness(implicit.penetration(k, velocity[dof]));
                add_to_diagonal(&mut matrix, dof, stiffness);
            }
        }
        Ok(matrix)
    }

    /// K ← Qᵀ K Q for the frames of the contact nodes of the cell.
    fn rotate_element_matrix(&self, cell: usize, out: &mut [f64]) {
        let nodes = self.space.cell_nodes(cell);
        let nd = nodes.len() * D;
        for (a, &node) in nodes.iter().enumerate() {
            let Some(k) = self.contact.index_of_node[node] else {
                continue;
            };
            let frame = &self.contact.frames[k];
            // rows: K[(a,·), :] ← R_aᵀ K[(a,·), :]
            for col in 0..nd {
                let old: SVector<f64, D> = SVector::from_fn(|i, _| out[(a * D + i) * nd + col]);
                let new = frame.transpose() * old;
                for i in 0..D {
                    out[(a * D + i) * nd + col] = new[i];
                }
            }
            // columns: K[:, (a,·)] ← K[:, (a,·)] R_a
            for row in 0..nd {
                let old: SVector<f64, D> = SVector::from_fn(|i, _| out[row * nd + a * D + i]);
                let new = frame.transpose() * old;
                for i in 0..D {
                    out[row * nd + a * D + i] = new[i];
                }
            }
        }
    }

    /// Cartesian node-major vector → system frame (frames at contact nodes, zero on the
    /// constrained unknowns).
    pub fn to_system(&self, cartesian: &[f64]) -> Vec<f64> {
        let mut system = self.rotate_to_system(cartesian);
        for (value, _) in system.iter_mut().zip(&self.constrained).filter(|(_, &c)| c) {
            *value = 0.0;
        }
        system
    }

    /// Cartesian node-major vector → system frame, keeping the constrained entries.
    fn rotate_to_system(&self, cartesian: &[f64]) -> Vec<f64> {
        let mut system = cartesian.to_vec();
        for (k, &node) in self.contact.nodes.iter().enumerate() {
            let local = self.contact.frames[k].transpose()
                * SVector::<f64, D>::from_column_slice(&cartesian[node * D..node * D + D]);
            system[node * D..node * D + D].copy_from_slice(local.as_slice());
        }
        system
    }

    /// A start vector in the system frame: `to_system(cartesian)` with the prescribed
    /// velocities of the step on the constrained unknowns.
    fn start_vector(&self, cartesian: &[f64]) -> Vec<f64> {
        let mut system = self.to_system(cartesian);
        for (dof, _) in self.constrained.iter().enumerate().filter(|(_, &c)| c) {
            system[dof] = self.prescribed[dof];
        }
        system
    }

    /// The constrained unknowns (Cartesian components, node-major).
    pub fn constrained(&self) -> &[bool] {
        &self.constrained
    }

    /// ⟨𝒜ε(v), ε(φ_a e_i)⟩ (Cartesian) summed over the cells that carry a constrained unknown
    /// only: exact on the constrained unknowns, and exact everywhere for a v that vanishes
    /// outside those cells (the lifting K p of the prescribed velocities, linear 𝒜).
    fn constrained_cell_force(&self, velocity_cartesian: &[f64]) -> Vec<f64> {
        let n_local = self.space.nodes_per_cell() * D;
        let tab = &self.tabulation;
        let n = tab.nodes;
        let mut locals = vec![0.0; self.constrained_cells.len() * n_local];
        locals
            .par_chunks_mut(n_local)
            .zip(&self.constrained_cells)
            .for_each(|(out, &cell)| {
                let geometry = self.space.geometry(cell);
                let nodes = self.space.cell_nodes(cell);
                let mut grads = [SVector::<f64, D>::zeros(); crate::fem::element::MAX_CELL_NODES];
                for q in 0..tab.len() {
                    crate::scheme::assembly::physical_gradients(geometry, tab, q, &mut grads);
                    let rate = crate::scheme::assembly::field_strain(
                        nodes,
                        &grads[..n],
                        velocity_cartesian,
                    );
                    let stress = self.law.stress(&rate) * (tab.weights[q] * geometry.det);
                    for a in 0..n {
                        let traction = stress * grads[a];
                        for i in 0..D {
                            out[a * D + i] += traction[i];
                        }
                    }
                }
            });
        let mut force = vec![0.0; self.size()];
        for (chunk, &cell) in locals.chunks(n_local).zip(&self.constrained_cells) {
            for (a, &node) in self.space.cell_nodes(cell).iter().enumerate() {
                for i in 0..D {
                    force[node * D + i] += chunk[a * D + i];
                }
            }
        }
        force
    }

    /// Reactions R_c = ⟨𝒜ε(v), ε(φ_c)⟩ − F_c on the constrained unknowns (Cartesian load and
    /// velocity; zero on the free unknowns): the residual of the equilibrium there.
    pub fn reactions(&self, load_cartesian: &[f64], velocity_cartesian: &[f64]) -> Vec<f64> {
        let mut reaction = self.constrained_cell_force(velocity_cartesian);
        for ((r, f), &c) in reaction
            .iter_mut()
            .zip(load_cartesian)
            .zip(&self.constrained)
        {
            *r = if c { *r - f } else { 0.0 };
        }
        reaction
    }

    /// System frame → Cartesian node-major.
    pub fn to_cartesian(&self, system: &[f64]) -> Vec<f64> {
        let mut cartesian = system.to_vec();
        for (k, &node) in self.contact.nodes.iter().enumerate() {
            let global = self.contact.frames[k]
                * SVector::<f64, D>::from_column_slice(&system[node * D..node * D + D]);
            cartesian[node * D..node * D + D].copy_from_slice(global.as_slice());
        }
        cartesian
    }

    /// Numeric factorization of the current matrix and the Schur complement on the tangential
    /// contact unknowns: Z = E_cᵀ H^{-1} E_c (block solves), S = Z^{-1}.
    fn factorize(&mut self) -> Result<()> {
        self.solver.factorize(&self.matrix)?;
        (self.schur, self.trailing) = match self.schur_from_trailing_factor() {
            Some((schur, trailing)) => (schur, Some(trailing)),
            None => (self.schur_from_solves()?, None),
        };
        // checked once here; every step solves with it (`condensed_friction`)
        CondensedFriction::validate_matrix(self.schur.as_ref())?;
        Ok(())
    }

    /// S = (E_cᵀ H^{-1} E_c)^{-1} by m solves in blocks and a dense inverse (used when the
    /// factor is simplicial, i.e. small).
    fn schur_from_solves(&self) -> Result<Mat<f64>> {
        let m = self.tangential.len();
        let n = self.size();
        if m == 0 {
            return Ok(Mat::zeros(0, 0));
        }
        let mut inverse_block = Mat::<f64>::zeros(m, m);
        // blocks of right-hand sides as wide as ~512 MB allow: wider blocks make the
        // supernodal triangular solves matrix–matrix products
        let block = (64_000_000 / n.max(1)).clamp(16, 256);
        let mut start = 0;
        while start < m {
            let width = block.min(m - start);
            let mut rhs = Mat::<f64>::zeros(n, width);
            for j in 0..width {
                rhs[(self.tangential[start + j], j)] = 1.0;
            }
            self.solver.solve_block(rhs.as_mut())?;
            for j in 0..width {
                for (i, &dof) in self.tangential.iter().enumerate() {
                    inverse_block[(i, start + j)] = rhs[(dof, j)];
                }
            }
            start += width;
        }
        // symmetrize against round-off, then invert through a dense Cholesky factorization
        let sym = Mat::<f64>::from_fn(m, m, |i, j| {
            0.5 * (inverse_block[(i, j)] + inverse_block[(j, i)])
        });
        let llt = sym
            .llt(faer::Side::Lower)
            .map_err(|e| Error::LinearAlgebra {
                context: "condensed velocity operator E_cᵀ H⁻¹ E_c".into(),
                message: format!("dense Cholesky failed: {e:?}"),
            })?;
        let inverse = faer::linalg::solvers::DenseSolveCore::inverse(&llt);
        Ok(Mat::<f64>::from_fn(m, m, |i, j| {
            0.5 * (inverse[(i, j)] + inverse[(j, i)])
        }))
    }

    /// S = L_cc L_ccᵀ from the trailing block of the factor, in the order of `tangential`, and
    /// that block; None when the factor is simplicial or its last unknowns are not the
    /// tangential ones (then [`Self::factorize`] falls back to m solves).
    fn schur_from_trailing_factor(&self) -> Option<(Mat<f64>, TrailingFactor)> {
        let m = self.tangential.len();
        if m == 0 {
            return None;
        }
        let (trailing, unknowns) = self.solver.trailing_factor(m)?;
        let mut position = vec![usize::MAX; self.size()];
        for (i, &dof) in self.tangential.iter().enumerate() {
            position[dof] = i;
        }
        let index: Vec<usize> = unknowns.iter().map(|&dof| position[dof]).collect();
        if index.contains(&usize::MAX) {
            return None;
        }
        let product = &trailing * trailing.transpose();
        let mut schur = Mat::<f64>::zeros(m, m);
        for (p, &i) in index.iter().enumerate() {
            for (q, &j) in index.iter().enumerate() {
                // exactly symmetric (the blocked product need not be, to rounding)
                schur[(i, j)] = 0.5 * (product[(p, q)] + product[(q, p)]);
            }
        }
        Some((
            schur,
            TrailingFactor {
                factor: trailing,
                index,
            },
        ))
    }

    /// The cell energies ∫_K Φ(ε(v)) dx and the internal force vector ⟨𝒜ε(v), ε(φ_a e_i)⟩ in
    /// the system frame (on every unknown, constrained ones included).
    fn energy_and_force(&self, velocity_system: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let cartesian = self.to_cartesian(velocity_system);
        let n_local = self.space.nodes_per_cell() * D;
        let n_cells = self.space.mesh().num_cells();
        let tab = &self.tabulation;
        let n = tab.nodes;
        let mut locals = vec![0.0; n_cells * (n_local + 1)];
        locals
            .par_chunks_mut(n_local + 1)
            .enumerate()
            .for_each(|(cell, out)| {
                let geometry = self.space.geometry(cell);
                let nodes = self.space.cell_nodes(cell);
                let mut grads = [SVector::<f64, D>::zeros(); crate::fem::element::MAX_CELL_NODES];
                for q in 0..tab.len() {
                    crate::scheme::assembly::physical_gradients(geometry, tab, q, &mut grads);
                    let rate =
                        crate::scheme::assembly::field_strain(nodes, &grads[..n], &cartesian);
                    let weight = tab.weights[q] * geometry.det;
                    out[n_local] += weight * self.law.potential(&rate);
                    let stress = self.law.stress(&rate) * weight;
                    for a in 0..n {
                        let traction = stress * grads[a];
                        for i in 0..D {
                            out[a * D + i] += traction[i];
                        }
                    }
                }
            });
        let mut force = vec![0.0; self.size()];
        let mut energy = vec![0.0; n_cells];
        for (cell, chunk) in locals.chunks(n_local + 1).enumerate() {
            energy[cell] = chunk[n_local];
            for (a, &node) in self.space.cell_nodes(cell).iter().enumerate() {
                for i in 0..D {
                    force[node * D + i] += chunk[a * D + i];
                }
            }
        }
        let mut force = self.rotate_to_system(&force);
        if let Some(implicit) = &self.implicit {
            // Σ_a ω_a P(r_a + k v_ν(a))/k and its gradient ω_a p_ν(r_a + k v_ν(a)) e_ν
            for (k, &node) in self.contact.nodes.iter().enumerate() {
                let penetration = implicit.penetration(k, velocity_system[node * D]);
                let weight = self.contact.weights[k];
                energy.push(weight * implicit.law.normal_energy(penetration) / implicit.time_step);
                force[node * D] += weight * implicit.law.normal_pressure(penetration);
            }
        }
        (energy, force)
    }

    fn friction_weights(&self, friction_bound: &[f64]) -> Vec<f64> {
        self.contact
            .weights
            .iter()
            .zip(friction_bound)
            .map(|(w, s)| w * s)
            .collect()
    }

    fn friction_term(&self, weights: &[f64], velocity_system: &[f64]) -> f64 {
        self.contact
            .nodes
            .iter()
            .zip(weights)
            .map(|(&node, w)| {
                w * velocity_system[node * D + 1..node * D + D]
                    .iter()
                    .map(|t| t * t)
                    .sum::<f64>()
                    .sqrt()
            })
            .sum()
    }

    /// Relative KKT residual of (5.1) for (v, λ) on the free unknowns:
    /// max of ‖N(v) − F + E_c W λ‖_∞ / max(‖F‖_∞, ‖N(v)‖_∞, ‖E_c W λ‖_∞) (stationarity,
    /// relative to the largest of the forces it balances; on a constrained unknown the entry
    /// is |v_c − p_c| instead), max_a (|λ_a| − 1)₊ (dual
    /// feasibility) and max over slipping nodes of |λ_a − v_τ(a)/|v_τ(a)||
    /// (complementarity); stick nodes have v_τ(a) = 0 exactly.
    ///
    /// The stationarity is scaled by all three forces, not by F alone: F (the loads minus the
    /// elastic forces of u_{n−1}) can be a small difference of large terms while the viscous
    /// and friction forces that balance it are large, and the rounding error of N(v) is
    /// relative to those (seen on an unstructured 3D mesh: ‖F‖_∞ = 2e-3 against forces ≈ 1.5).
    pub fn kkt_residual(
        &self,
        load_system: &[f64],
        weights: &[f64],
        velocity_system: &[f64],
        multipliers: &[f64],
    ) -> f64 {
        let force = if self.law.is_linear() && self.implicit.is_none() && self.matrix_is_plain {
            // H_ff v_f on the free rows (the load is lifted)
            multiply_symmetric(&self.matrix, velocity_system)
        } else {
            self.energy_and_force(velocity_system).1
        };
        self.kkt_residual_with_force(load_system, weights, velocity_system, multipliers, &force)
    }

    /// [`Self::kkt_residual`] with the internal force N(v) (system frame) already known. The
    /// scale takes the load and the internal force on the free unknowns, the friction forces
    /// and the force K_fc p_c of the prescribed velocities on the free unknowns (zero for the
    /// paper's u = 0 on Γ1; without it a body moved by its support alone would have no scale).
    fn kkt_residual_with_force(
        &self,
        load_system: &[f64],
        weights: &[f64],
        velocity_system: &[f64],
        multipliers: &[f64],
        force: &[f64],
    ) -> f64 {
        let mut residual: Vec<f64> = force.iter().zip(load_system).map(|(n, f)| n - f).collect();
        let load_scale = max_abs_free(load_system, &self.constrained);
        let force_scale = max_abs_free(force, &self.constrained).max(self.lifting_scale);
        for (dof, _) in self.constrained.iter().enumerate().filter(|(_, &c)| c) {
            residual[dof] = velocity_system[dof] - self.prescribed[dof];
        }
        let g = D - 1;
        let mut worst: f64 = 0.0;
        for (k, &node) in self.contact.nodes.iter().enumerate() {
            let lambda = &multipliers[k * g..(k + 1) * g];
            for i in 0..g {
                residual[node * D + 1 + i] += weights[k] * lambda[i];
            }
            let norm = lambda.iter().map(|l| l * l).sum::<f64>().sqrt();
            worst = worst.max(norm - 1.0);
            let tangential: Vec<f64> = (0..g).map(|i| velocity_system[node * D + 1 + i]).collect();
            let speed = tangential.iter().map(|t| t * t).sum::<f64>().sqrt();
            if speed > 0.0 && weights[k] > 0.0 {
                for i in 0..g {
                    worst = worst.max((lambda[i] - tangential[i] / speed).abs());
                }
            }
        }
        let friction_force = (0..self.contact.len())
            .map(|k| weights[k] * max_abs(&multipliers[k * g..(k + 1) * g]))
            .fold(0.0f64, f64::max);
        let scale = load_scale
            .max(force_scale)
            .max(friction_force)
            .max(f64::MIN_POSITIVE);
        let stationarity = max_abs(&residual) / scale;
        stationarity.max(worst)
    }

    /// Solves the velocity step (5.1) for the given data; `start` (Cartesian) is the initial
    /// guess of the outer Newton iteration (ignored for a linear 𝒜).
    pub fn solve(
        &mut self,
        data: &VelocityData<'_>,
        start: &[f64],
        settings: &VelocitySettings,
    ) -> Result<VelocitySolution> {
        let k_count = self.contact.len();
        let size = self.size();
        if data.load.len() != size
            || data.normal_pressure.len() != k_count
            || data.friction_bound.len() != k_count
        {
            return Err(Error::InvalidInput(format!(
                "velocity step data sizes: load {} (expected {size}), normal pressure {} and friction bound {} (expected {k_count})",
                data.load.len(),
                data.normal_pressure.len(),
                data.friction_bound.len()
            )));
        }
        if let Some(i) = data.load.iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite(format!(
                "velocity step load vector at dof {i} (node {}, component {})",
                i / D,
                i % D
            )));
        }
        for (name, values) in [
            ("normal pressure", data.normal_pressure),
            ("friction bound", data.friction_bound),
        ] {
            if let Some(k) = values.iter().position(|v| !v.is_finite() || *v < 0.0) {
                return Err(Error::NonFinite(format!(
                    "{name} {} at contact node {} ({:?}) must be finite and ≥ 0",
                    values[k],
                    self.contact.nodes[k],
                    self.space.node(self.contact.nodes[k])
                )));
            }
        }
        if let Some(implicit) = &data.implicit_contact {
            if implicit.previous_penetration.len() != k_count {
                return Err(Error::InvalidInput(format!(
                    "implicit normal compliance: {} penetrations for {k_count} contact nodes",
                    implicit.previous_penetration.len()
                )));
            }
            if !(implicit.time_step.is_finite() && implicit.time_step > 0.0) {
                return Err(Error::parameter(
                    "time_step",
                    implicit.time_step,
                    "the implicit normal compliance needs a finite time step k > 0",
                ));
            }
            if let Some(k) = implicit
                .previous_penetration
                .iter()
                .position(|r| !r.is_finite())
            {
                return Err(Error::NonFinite(format!(
                    "penetration u_ν − g = {} at contact node {} ({:?})",
                    implicit.previous_penetration[k],
                    self.contact.nodes[k],
                    self.space.node(self.contact.nodes[k])
                )));
            }
        }
        self.prescribed.fill(0.0);
        if let Some(prescribed) = data.prescribed {
            if prescribed.len() != size {
                return Err(Error::InvalidInput(format!(
                    "velocity step: {} prescribed velocities for {size} unknowns",
                    prescribed.len()
                )));
            }
            for (dof, _) in self.constrained.iter().enumerate().filter(|(_, &c)| c) {
                if !prescribed[dof].is_finite() {
                    return Err(Error::NonFinite(format!(
                        "prescribed velocity {} at node {} ({:?}), component {}",
                        prescribed[dof],
                        dof / D,
                        self.space.node(dof / D),
                        dof % D
                    )));
                }
                self.prescribed[dof] = prescribed[dof];
            }
        }
        // the force of the prescribed velocities on the free unknowns, K_fc p_c (linear 𝒜: its
        // lifting; nonlinear: its first-order part), in the system frame
        let lifting = if self.prescribed.iter().any(|&p| p != 0.0) {
            Some(self.to_system(&self.constrained_cell_force(&self.prescribed)))
        } else {
            None
        };
        self.lifting_scale = lifting.as_ref().map_or(0.0, |l| max_abs(l));
        // F in the system frame, with the explicit normal compliance load −ω_a p_ν on the
        // normal unknown (the implicit one is part of N(v) instead).
        let mut load = self.to_system(data.load);
        if data.implicit_contact.is_none() {
            for (k, &node) in self.contact.nodes.iter().enumerate() {
                load[node * D] -= self.contact.weights[k] * data.normal_pressure[k];
            }
        }
        let weights = self.friction_weights(data.friction_bound);
        self.implicit.clone_from(&data.implicit_contact);
        if self.implicit.is_some() {
            // the tangent depends on the step's penetrations, not only on v
            self.linearized_at = None;
        }
        let (velocity, multipliers, stats) = if self.law.is_linear() && self.implicit.is_none() {
            // eliminate the prescribed velocities: F_f − K_fc p_c on the free rows, p_c on the
            // constrained (identity) rows
            if let Some(lifting) = &lifting {
                for ((f, l), &c) in load.iter_mut().zip(lifting).zip(&self.constrained) {
                    if !c {
                        *f -= l;
                    }
                }
            }
            for (dof, _) in self.constrained.iter().enumerate().filter(|(_, &c)| c) {
                load[dof] = self.prescribed[dof];
            }
            self.solve_linear(&load, &weights, start, settings)?
        } else {
            self.solve_nonlinear(&load, &weights, start, settings)?
        };
        let status = self
            .contact
            .nodes
            .iter()
            .enumerate()
            .map(|(k, &node)| {
                let pressure = match &self.implicit {
                    Some(implicit) => implicit
                        .law
                        .normal_pressure(implicit.penetration(k, velocity[node * D])),
                    None => data.normal_pressure[k],
                };
                if pressure <= 0.0 {
                    ContactStatus::Separated
                } else if weights[k] > 0.0 && (1..D).all(|i| velocity[node * D + i] == 0.0) {
                    ContactStatus::Stick
                } else {
                    ContactStatus::Slip
                }
            })
            .collect();
        let velocity = self.to_cartesian(&velocity);
        let reaction = self.reactions(data.load, &velocity);
        Ok(VelocitySolution {
            velocity,
            multipliers,
            status,
            reaction,
            stats,
        })
    }

    /// Linear 𝒜: the model is (5.1) itself, so one exact model solve with the factor of the run
    /// solves the step; at most [`MAX_REFINEMENTS`] passes of iterative refinement follow when
    /// round-off leaves the KKT residual above the tolerance.
    fn solve_linear(
        &mut self,
        load: &[f64],
        weights: &[f64],
        start: &[f64],
        settings: &VelocitySettings,
    ) -> Result<(Vec<f64>, Vec<f64>, VelocityStats)> {
        let mut stats = VelocityStats::default();
        let mut multipliers = vec![0.0; self.contact.len() * (D - 1)];
        let mut velocity = self.start_vector(start);
        let mut history: Vec<f64> = Vec::new();
        if !self.matrix_is_plain {
            // a Newton tangent (implicit contact) replaced the operator of the run
            self.matrix = self.assemble(None)?;
            self.matrix_is_plain = true;
            self.factorize()?;
            stats.factorizations += 1;
        }
        loop {
            stats.newton_iterations += 1;
            if !self.solver.is_factorized() {
                self.factorize()?;
                stats.factorizations += 1;
            }
            let refinement = stats.newton_iterations > 1;
            // A refinement pass also asks the condensed friction problem for more digits: its
            // residual is relative to its own right-hand side r_c, which can exceed the forces
            // of (5.1) by orders of magnitude (r_c is the force that would stop all sliding),
            // so its default tolerance can leave the full KKT residual above `tolerance`.
            let mut friction_settings = settings.friction;
            let (rhs, base) = if let (true, Some(&reached)) = (refinement, history.last()) {
                friction_settings.tolerance = (friction_settings.tolerance
                    * (0.1 * settings.tolerance / reached))
                    .clamp(MIN_FRICTION_TOLERANCE, friction_settings.tolerance);
                let hv = multiply_symmetric(&self.matrix, &velocity);
                let residual: Vec<f64> = load.iter().zip(&hv).map(|(b, h)| b - h).collect();
                (residual, Some(velocity.as_slice()))
            } else {
                (load.to_vec(), None)
            };
            let trial = self.solve_model(
                &rhs,
                weights,
                &velocity,
                base,
                &mut multipliers,
                &friction_settings,
                &mut stats,
            );
            velocity = match trial {
                Ok(trial) => trial,
                // a refinement pass whose friction problem stagnates at the rounding level
                // ends the step with the velocity residual reached so far
                Err(Error::NoConvergence { .. }) if refinement => {
                    return Err(Error::NoConvergence {
                        solver: "velocity step (5.1), linear viscosity (with iterative refinement; the condensed friction problem reached its rounding level)",
                        iterations: stats.newton_iterations,
                        residual: stats.kkt_residual,
                        tolerance: settings.tolerance,
                        history: crate::error::History(history),
                    })
                }
                Err(error) => return Err(error),
            };
            stats.kkt_residual = self.kkt_residual(load, weights, &velocity, &multipliers);
            history.push(stats.kkt_residual);
            if stats.kkt_residual <= settings.tolerance {
                break;
            }
            if stats.newton_iterations > MAX_REFINEMENTS {
                return Err(Error::NoConvergence {
                    solver: "velocity step (5.1), linear viscosity (with iterative refinement)",
                    iterations: stats.newton_iterations,
                    residual: stats.kkt_residual,
                    tolerance: settings.tolerance,
                    history: crate::error::History(history),
                });
            }
        }
        stats.residual_history = history;
        Ok((velocity, multipliers, stats))
    }

    /// Nonlinear 𝒜: globalized proximal Newton, see the module documentation. Stops when the
    /// KKT residual of the iterate (multipliers from [`Self::best_multipliers`]) is at most
    /// `NEWTON_HEADROOM × tolerance`; the reported residual is that same number.
    fn solve_nonlinear(
        &mut self,
        load: &[f64],
        weights: &[f64],
        start: &[f64],
        settings: &VelocitySettings,
    ) -> Result<(Vec<f64>, Vec<f64>, VelocityStats)> {
        let mut stats = VelocityStats::default();
        let target = settings.tolerance * NEWTON_HEADROOM;
        let mut velocity = self.start_vector(start);
        let mut point = self.evaluate(load, weights, &velocity);
        let mut model_multipliers = point.multipliers.clone();
        let mut history: Vec<f64> = Vec::new();
        let mut best = point.residual;
        let failure =
            |stats: &VelocityStats, history: &[f64], solver: &'static str| Error::NoConvergence {
                solver,
                iterations: stats.newton_iterations,
                residual: history.last().copied().unwrap_or(f64::INFINITY),
                tolerance: target,
                history: crate::error::History(history.to_vec()),
            };
        while point.residual > target {
            if stats.newton_iterations >= settings.max_newton {
                if point.residual <= settings.tolerance {
                    break; // the certificate holds; the head room was not reached in time
                }
                return Err(failure(
                    &stats,
                    &history,
                    "velocity step (5.1), proximal Newton (iteration limit)",
                ));
            }
            stats.newton_iterations += 1;
            if self.linearized_at.as_deref() != Some(velocity.as_slice()) {
                self.matrix = self.assemble(Some(&velocity))?;
                self.matrix_is_plain = false;
                self.factorize()?;
                stats.factorizations += 1;
                self.linearized_at = Some(velocity.clone());
            }
            // the Newton model around v in increment form: b − Hv = F − N(v)
            // (zero on the constrained unknowns: the iterates keep v_c = p_c)
            let minus_gradient: Vec<f64> = load
                .iter()
                .zip(&point.force)
                .zip(&self.constrained)
                .map(|((f, n), &c)| if c { 0.0 } else { f - n })
                .collect();
            let mut friction_settings = settings.friction;
            friction_settings.tolerance = (friction_settings.tolerance * NEWTON_HEADROOM)
                .max(MIN_FRICTION_TOLERANCE)
                .min(settings.friction.tolerance);
            let mut solve = |friction_settings: &FrictionSettings, stats: &mut VelocityStats| {
                self.solve_model(
                    &minus_gradient,
                    weights,
                    &velocity,
                    Some(&velocity),
                    &mut model_multipliers,
                    friction_settings,
                    stats,
                )
            };
            let trial = match solve(&friction_settings, &mut stats) {
                Ok(trial) => trial,
                // the tighter friction tolerance can lie below the rounding level of a
                // badly conditioned S: retry with the configured one
                Err(Error::NoConvergence { .. }) => solve(&settings.friction, &mut stats)?,
                Err(error) => return Err(error),
            };
            let direction: Vec<f64> = trial.iter().zip(&velocity).map(|(t, v)| t - v).collect();
            let friction_now = self.friction_term(weights, &velocity);
            let predicted = -dot(&minus_gradient, &direction) + self.friction_term(weights, &trial)
                - friction_now;
            let load_along = dot(load, &direction);
            let mut step = 1.0;
            let mut accepted = None;
            for _ in 0..MAX_BACKTRACKS {
                let candidate: Vec<f64> = if step == 1.0 {
                    trial.clone()
                } else {
                    velocity
                        .iter()
                        .zip(&direction)
                        .map(|(v, d)| v + step * d)
                        .collect()
                };
                let evaluated = self.evaluate(load, weights, &candidate);
                // J(candidate) − J(v), summed cell by cell against cancellation
                let decrease = evaluated
                    .cell_energy
                    .iter()
                    .zip(&point.cell_energy)
                    .map(|(new, old)| new - old)
                    .sum::<f64>()
                    - step * load_along
                    + self.friction_term(weights, &candidate)
                    - friction_now;
                if evaluated.residual <= FAST_REDUCTION * best
                    || decrease <= ARMIJO * step * predicted.min(0.0) && predicted < 0.0
                {
                    accepted = Some((candidate, evaluated));
                    break;
                }
                step *= 0.5;
            }
            let Some((next, evaluated)) = accepted else {
                if point.residual <= settings.tolerance {
                    break; // rounding level reached below the certificate
                }
                return Err(failure(
                    &stats,
                    &history,
                    "velocity step (5.1), proximal Newton (no step decreases the KKT residual or J: rounding level)",
                ));
            };
            velocity = next;
            point = evaluated;
            history.push(point.residual);
            best = best.min(point.residual);
        }
        stats.kkt_residual = point.residual;
        stats.residual_history = history;
        Ok((velocity, point.multipliers, stats))
    }

    /// Cell energies, internal force, the best multipliers and the KKT residual at v.
    fn evaluate(&self, load: &[f64], weights: &[f64], velocity: &[f64]) -> Iterate {
        let (cell_energy, force) = self.energy_and_force(velocity);
        let multipliers = self.best_multipliers(load, weights, velocity, &force);
        let residual = self.kkt_residual_with_force(load, weights, velocity, &multipliers, &force);
        Iterate {
            cell_energy,
            force,
            multipliers,
            residual,
        }
    }

    /// The multipliers that satisfy the KKT conditions of (5.1) best at a given v: at a node that
    /// slips, λ_a = v_τ(a)/|v_τ(a)| (complementarity fixes it); at a node with v_τ(a) = 0, the
    /// projection of −(N(v) − F)_τ(a)/w_a onto the unit ball (the λ of the subdifferential closest
    /// to balancing the forces). With them, dual feasibility and complementarity hold exactly,
    /// and the KKT residual is the stationarity alone: a function of v, used as merit function.
    pub fn best_multipliers(
        &self,
        load_system: &[f64],
        weights: &[f64],
        velocity_system: &[f64],
        force_system: &[f64],
    ) -> Vec<f64> {
        let g = D - 1;
        let mut multipliers = vec![0.0; self.contact.len() * g];
        for (k, &node) in self.contact.nodes.iter().enumerate() {
            if weights[k] <= 0.0 {
                continue;
            }
            let lambda = &mut multipliers[k * g..(k + 1) * g];
            let tangential = &velocity_system[node * D + 1..node * D + D];
            let speed = tangential.iter().map(|t| t * t).sum::<f64>().sqrt();
            if speed > 0.0 {
                for (l, t) in lambda.iter_mut().zip(tangential) {
                    *l = t / speed;
                }
            } else {
                for (i, l) in lambda.iter_mut().enumerate() {
                    let dof = node * D + 1 + i;
                    *l = -(force_system[dof] - load_system[dof]) / weights[k];
                }
                let norm = lambda.iter().map(|l| l * l).sum::<f64>().sqrt();
                if norm > 1.0 {
                    lambda.iter_mut().for_each(|l| *l /= norm);
                }
            }
        }
        multipliers
    }

    /// Exact solution of the model problem min ½ yᵀHy − bᵀy + Σ w_a |y_τ(a)| by condensation
    /// onto the tangential contact unknowns.
    ///
    /// With `base = Some(v)`, `rhs` is the residual b − Hv and the two solves are done in
    /// correction form, y = v + H^{-1}(b − Hv − E_c W λ): this recovers the digits lost to
    /// round-off in the factor and in S (iterative refinement of the linear step), and it is the
    /// increment form of a Newton step, where b − Hv = F − N(v) is known without cancellation.
    #[allow(clippy::too_many_arguments)]
    fn solve_model(
        &self,
        rhs: &[f64],
        weights: &[f64],
        start: &[f64],
        base: Option<&[f64]>,
        multipliers: &mut [f64],
        friction_settings: &FrictionSettings,
        stats: &mut VelocityStats,
    ) -> Result<Vec<f64>> {
        if let Some(trailing) = &self.trailing {
            if let Some(solution) = self.solve_model_trailing(
                trailing,
                rhs,
                weights,
                start,
                base,
                multipliers,
                friction_settings,
                stats,
            )? {
                return Ok(solution);
            }
        }
        let solve = |b: &[f64]| -> Result<Vec<f64>> {
            match base {
                None => self.solver.solve(b),
                Some(v) => {
                    let correction = self.solver.solve(b)?;
                    Ok(v.iter().zip(&correction).map(|(v, c)| v + c).collect())
                }
            }
        };
        let free = solve(rhs)?;
        if self.tangential.is_empty() {
            return Ok(free);
        }
        // condensed rhs r_c = S (H^{-1} b)_c
        let reduced_rhs = self.schur_times_tangential(&free);
        let x = self.condensed_friction(
            &reduced_rhs,
            weights,
            start,
            multipliers,
            friction_settings,
            stats,
        )?;
        // y = H^{-1}(b − E_c W λ)
        let mut corrected = rhs.to_vec();
        let g = D - 1;
        for (i, &dof) in self.tangential.iter().enumerate() {
            corrected[dof] -= weights[i / g] * multipliers[i];
        }
        let mut solution = solve(&corrected)?;
        // the tangential unknowns are those of the condensed solution (exact zeros at stick nodes)
        for (i, &dof) in self.tangential.iter().enumerate() {
            solution[dof] = x[i];
        }
        Ok(solution)
    }

    /// [`Self::solve_model`] with the tangential unknowns eliminated last: one forward and one
    /// backward triangular solve instead of two solves. With z = L⁻¹ P b in elimination order,
    /// (H⁻¹ b)_c = L_cc⁻ᵀ z_c, so the condensed right-hand side S (H⁻¹ b)_c is L_cc z_c
    /// (S = L_cc L_ccᵀ); the friction forces E_c W λ change only the trailing block of z,
    /// z_c ← z_c − L_cc⁻¹ (W λ)_c; and one backward solve gives H⁻¹ (b − E_c W λ). None if the
    /// factor is not supernodal (then the two-solve path runs).
    #[allow(clippy::too_many_arguments)]
    fn solve_model_trailing(
        &self,
        trailing: &TrailingFactor,
        rhs: &[f64],
        weights: &[f64],
        start: &[f64],
        base: Option<&[f64]>,
        multipliers: &mut [f64],
        friction_settings: &FrictionSettings,
        stats: &mut VelocityStats,
    ) -> Result<Option<Vec<f64>>> {
        let Some(mut z) = self.solver.forward_solve(rhs)? else {
            return Ok(None);
        };
        let m = self.tangential.len();
        let first = z.len() - m;
        let z_c = Mat::<f64>::from_fn(m, 1, |p, _| z[first + p]);
        let condensed = sequential_product(trailing.factor.as_ref(), z_c.as_ref());
        let mut reduced_rhs = vec![0.0; m];
        for (p, &i) in trailing.index.iter().enumerate() {
            reduced_rhs[i] = condensed[(p, 0)];
        }
        if let Some(v) = base {
            // a refinement pass: the velocity is v + H⁻¹ r, so S (v_c + (H⁻¹ r)_c)
            for (value, schur_v) in reduced_rhs.iter_mut().zip(self.schur_times_tangential(v)) {
                *value += schur_v;
            }
        }
        let x = self.condensed_friction(
            &reduced_rhs,
            weights,
            start,
            multipliers,
            friction_settings,
            stats,
        )?;
        let g = D - 1;
        let mut forces = Mat::<f64>::from_fn(m, 1, |p, _| {
            let i = trailing.index[p];
            weights[i / g] * multipliers[i]
        });
        faer::linalg::triangular_solve::solve_lower_triangular_in_place(
            trailing.factor.as_ref(),
            forces.as_mut(),
            faer::Par::Seq,
        );
        for p in 0..m {
            z[first + p] -= forces[(p, 0)];
        }
        let Some(mut solution) = self.solver.backward_solve(&z)? else {
            return Ok(None);
        };
        if let Some(v) = base {
            for (value, v) in solution.iter_mut().zip(v) {
                *value += v;
            }
        }
        // the tangential unknowns are those of the condensed solution (exact zeros at stick nodes)
        for (i, &dof) in self.tangential.iter().enumerate() {
            solution[dof] = x[i];
        }
        Ok(Some(solution))
    }

    /// S v_c: the Schur complement times the tangential contact part of `v` (in the order of
    /// `tangential`).
    fn schur_times_tangential(&self, v: &[f64]) -> Vec<f64> {
        let m = self.tangential.len();
        let v_c = Mat::<f64>::from_fn(m, 1, |i, _| v[self.tangential[i]]);
        let product = sequential_product(self.schur.as_ref(), v_c.as_ref());
        (0..m).map(|i| product[(i, 0)]).collect()
    }

    /// The condensed friction problem of (5.1) with right-hand side `reduced_rhs` (in the order
    /// of `tangential`), started from the tangential part of `start`: the tangential velocities,
    /// and the multipliers in `multipliers`.
    fn condensed_friction(
        &self,
        reduced_rhs: &[f64],
        weights: &[f64],
        start: &[f64],
        multipliers: &mut [f64],
        friction_settings: &FrictionSettings,
        stats: &mut VelocityStats,
    ) -> Result<Vec<f64>> {
        let mut x: Vec<f64> = self.tangential.iter().map(|&dof| start[dof]).collect();
        let problem = CondensedFriction {
            matrix: self.schur.as_ref(),
            rhs: reduced_rhs,
            weights,
            group_size: D - 1,
        };
        // S was checked when it was computed (`factorize`)
        let friction = problem.solve_with_checked_matrix(&mut x, multipliers, friction_settings)?;
        stats.friction_iterations += friction.newton_iterations;
        stats.friction_gradient_iterations += friction.gradient_iterations;
        Ok(x)
    }
}

/// Passes of iterative refinement allowed after the exact solve of a linear velocity step.
const MAX_REFINEMENTS: usize = 3;
/// A nonlinear step iterates to `NEWTON_HEADROOM × tolerance` (1e-12 for the default 1e-10
/// certificate), so that the certificate holds with two digits to spare.
pub const NEWTON_HEADROOM: f64 = 1e-2;
/// A Newton step (full or damped) is accepted when it lowers the best KKT residual so far by
/// this factor (the region of fast convergence), whatever it does to J.
const FAST_REDUCTION: f64 = 0.5;
/// Armijo constant σ of the sufficient decrease J(v + αd) ≤ J(v) + σ α Δ.
const ARMIJO: f64 = 1e-4;
/// Halvings of the step before the line search gives up (2^-40 ≈ 1e-12).
const MAX_BACKTRACKS: usize = 41;

/// J's cell energies, the internal force, the best multipliers and the KKT residual at an
/// iterate of the nonlinear velocity step.
struct Iterate {
    cell_energy: Vec<f64>,
    force: Vec<f64>,
    multipliers: Vec<f64>,
    residual: f64,
}
/// Smallest tolerance a refinement pass asks of the condensed friction problem (relative to
/// its right-hand side; its rounding level is about ε κ(S)).
const MIN_FRICTION_TOLERANCE: f64 = 1e-15;

/// matrix[(index, index)] += value (the entry is in the pattern: a node couples with itself).
fn add_to_diagonal(matrix: &mut SparseColMat<usize, f64>, index: usize, value: f64) {
    let symbolic = matrix.symbolic();
    let start = symbolic.col_ptr()[index];
    let end = symbolic.col_ptr()[index + 1];
    let position = symbolic.row_idx()[start..end]
        .iter()
        .position(|&row| row == index)
        .map(|p| start + p);
    if let Some(position) = position {
        matrix.val_mut()[position] += value;
    }
}

/// `A B` on the calling thread. faer's `*` takes the global parallelism, and its parallel
/// matrix–vector product sums in an order that depends on the number of threads; the products
/// of every step go through this one, so that a run gives the same bits on any number of
/// threads (`simulate`'s `run_is_the_same_on_one_two_and_three_threads`).
fn sequential_product(a: faer::MatRef<'_, f64>, b: faer::MatRef<'_, f64>) -> Mat<f64> {
    let mut product = Mat::<f64>::zeros(a.nrows(), b.ncols());
    faer::linalg::matmul::matmul(
        product.as_mut(),
        faer::Accum::Replace,
        a,
        b,
        1.0,
        faer::Par::Seq,
    );
    product
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::mesh::{BoundaryPart::*, Mesh};
    use crate::model::laws::LinearViscosity;

    fn operator<const D: usize>(mesh: Mesh<D>) -> VelocityOperator<D> {
        let space = Arc::new(LagrangeSpace::new(Arc::new(mesh), 1).unwrap());
        let contact = Arc::new(ContactNodes::new(&space).unwrap());
        let mut operator = VelocityOperator::new(
            space,
            Arc::new(LinearViscosity {
                shear: 1.0,
                bulk: 0.5,
            }),
            contact,
        )
        .unwrap();
        operator.solver.factorize(&operator.matrix).unwrap();
        operator
    }

    /// The unit square clamped at x = 0, in contact at y = 0.
    fn square_with_contact(cells: [usize; 2]) -> Mesh<2> {
        Mesh::box_mesh(
            [0.0; 2],
            [1.0; 2],
            cells,
            [[Dirichlet, Neumann], [Contact, Neumann]],
        )
        .unwrap()
    }

    /// The unit cube clamped at x = 0, in contact at z = 0.
    fn cube_with_contact(cells: [usize; 3]) -> Mesh<3> {
        Mesh::box_mesh(
            [0.0; 3],
            [1.0; 3],
            cells,
            [[Dirichlet, Neumann], [Neumann, Neumann], [Contact, Neumann]],
        )
        .unwrap()
    }

    fn assert_schur_paths_agree<const D: usize>(operator: &VelocityOperator<D>) {
        let from_factor = operator
            .schur_from_trailing_factor()
            .map(|(schur, _)| schur)
            .expect("a supernodal factor with the contact unknowns last");
        let from_solves = operator.schur_from_solves().unwrap();
        let m = operator.tangential.len();
        let scale = (0..m)
            .map(|i| from_solves[(i, i)].abs())
            .fold(0.0, f64::max);
        let mut worst: f64 = 0.0;
        for i in 0..m {
            for j in 0..m {
                worst = worst.max((from_factor[(i, j)] - from_solves[(i, j)]).abs());
            }
        }
        assert!(
            worst <= 1e-10 * scale,
            "Schur complements differ by {worst:e} (scale {scale:e})"
        );
    }

    /// Both ways of solving the condensed model of (5.1), on random loads and friction bounds
    /// (stick and slip nodes), plain and as a refinement pass: the one-solve path with the
    /// trailing factor and the two-solve path.
    fn assert_one_solve_path_matches_two_solves<const D: usize>(
        mut operator: VelocityOperator<D>,
        seed: u64,
        largest_bound: f64,
    ) {
        operator.factorize().unwrap();
        assert!(
            operator.trailing.is_some(),
            "a supernodal factor, contact last"
        );
        let mut random = crate::test_random::SeededRandom::new(seed);
        let n = operator.size();
        let m = operator.tangential.len();
        let rhs: Vec<f64> = (0..n).map(|_| random.range(-1.0, 1.0)).collect();
        let weights: Vec<f64> = (0..m / (D - 1))
            .map(|_| random.range(0.0, largest_bound))
            .collect();
        let base: Vec<f64> = (0..n).map(|_| random.range(-0.1, 0.1)).collect();
        let settings = FrictionSettings::default();
        for base in [None, Some(base.as_slice())] {
            let solve = |operator: &VelocityOperator<D>| {
                let mut multipliers = vec![0.0; m];
                let mut stats = VelocityStats::default();
                let velocity = operator
                    .solve_model(
                        &rhs,
                        &weights,
                        &vec![0.0; n],
                        base,
                        &mut multipliers,
                        &settings,
                        &mut stats,
                    )
                    .unwrap();
                (velocity, multipliers)
            };
            let (one, one_multipliers) = solve(&operator);
            let trailing = operator.trailing.take();
            let (two, two_multipliers) = solve(&operator);
            operator.trailing = trailing;
            let scale = two.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let worst = one
                .iter()
                .zip(&two)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(
                worst <= 1e-10 * scale,
                "velocities differ by {worst:e} of {scale:e}"
            );
            let stuck = two_multipliers
                .chunks(D - 1)
                .zip(&weights)
                .filter(|(l, w)| {
                    l.iter().map(|x| x * x).sum::<f64>().sqrt() < 1.0 - 1e-6 || **w == 0.0
                })
                .count();
            assert!(
                stuck > 0 && stuck < weights.len(),
                "stick and slip nodes: {stuck}"
            );
            for (a, b) in one_multipliers.iter().zip(&two_multipliers) {
                assert!((a - b).abs() <= 1e-8, "multipliers {a} vs {b}");
            }
        }
    }

    #[test]
    fn one_solve_velocity_step_matches_two_solves_2d() {
        let mesh = square_with_contact([96, 48]);
        assert_one_solve_path_matches_two_solves(operator(mesh), 7, 0.5);
    }

    #[test]
    fn one_solve_velocity_step_matches_two_solves_3d() {
        let mesh = cube_with_contact([6; 3]);
        assert_one_solve_path_matches_two_solves(operator(mesh), 11, 20.0);
    }

    #[test]
    fn schur_complement_from_trailing_factor_matches_solves_2d() {
        let mesh = square_with_contact([128, 128]);
        assert_schur_paths_agree(&operator(mesh));
    }

    #[test]
    fn schur_complement_from_trailing_factor_matches_solves_3d() {
        let mesh = cube_with_contact([8; 3]);
        assert_schur_paths_agree(&operator(mesh));
    }
}
