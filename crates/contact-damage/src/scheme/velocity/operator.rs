//! The velocity operator of (5.1) for one mesh, law and contact boundary: its fields and
//! accessors. It is built in `construction`, assembled in `assembly`, factorized in
//! `factorization` and solved with in `step`, `newton` and `condensation`.

use super::reduction::ReducedCondensation;
use super::types::ImplicitNormalCompliance;
use crate::algebra::linalg::{CholeskySolver, SparsityPattern};
use crate::fem::space::{LagrangeSpace, Tabulation};
use crate::model::contact::ContactNodes;
use crate::model::laws::Viscosity;
use faer::sparse::SparseColMat;
use faer::Mat;
use std::sync::Arc;

/// Linear algebra of the velocity step for one mesh, law and contact boundary: the assembly
/// pattern (with frames and constrained rows), the Cholesky solver (symbolic analysis once) and
/// the condensed Schur complement on the tangential contact unknowns.
pub struct VelocityOperator<const D: usize> {
    pub(super) space: Arc<LagrangeSpace<D>>,
    pub(super) law: Arc<dyn Viscosity<D>>,
    pub(super) contact: Arc<ContactNodes<D>>,
    /// Constrained unknowns of the system frame, node-major: Cartesian components of Γ1 nodes,
    /// frame components at the contact nodes that a roller or symmetry plane of Γ1 fixes
    /// (tangential, [`ContactNodes::with_constraints`]).
    pub(super) constrained: Vec<bool>,
    /// The constrained Cartesian components (where the reactions are).
    pub(super) constrained_cartesian: Vec<bool>,
    /// Cells with a constrained unknown (where the reactions and the lifting are assembled).
    pub(super) constrained_cells: Vec<usize>,
    /// Prescribed velocities of the current step on the constrained unknowns of the system
    /// frame (zero elsewhere).
    pub(super) prescribed: Vec<f64>,
    /// The same on the constrained Cartesian components (the lifting is assembled from them).
    pub(super) prescribed_cartesian: Vec<f64>,
    /// max |(K p)_f| over the free unknowns of the current step (scale of the KKT residual).
    pub(super) lifting_scale: f64,
    pub(super) pattern: SparsityPattern,
    pub(super) tabulation: Tabulation<D>,
    pub(super) solver: CholeskySolver,
    pub(super) matrix: SparseColMat<usize, f64>,
    /// System indices of the tangential contact unknowns, (D−1) per contact node.
    pub(super) tangential: Vec<usize>,
    /// S = (E_cᵀ H^{-1} E_c)^{-1} for the current factorization; with a trailing factor, formed
    /// from it only when a step condenses onto all of Γ3 ([`Self::prepare_condensation`]).
    pub(super) schur: Option<Mat<f64>>,
    /// Counts the changes of the factor (numeric factorizations and Newton tangents of the
    /// contact block): the key of `reduction`.
    pub(super) factor_generation: u64,
    /// The condensation onto the Γ3 nodes with friction of the current step, when most of Γ3
    /// has none ([`ReducedCondensation`]).
    pub(super) reduction: Option<ReducedCondensation>,
    /// The trailing block of a supernodal factor whose last unknowns are the tangential ones
    /// (then S = L_cc L_ccᵀ and a step needs one solve, [`Self::solve_model`]).
    pub(super) trailing: Option<TrailingFactor>,
    /// The velocity at which H was last assembled (nonlinear 𝒜).
    pub(super) linearized_at: Option<Vec<f64>>,
    /// The KKT residual's ratio over the last accepted step of the nonlinear iteration: a
    /// frozen tangent ([`super::TangentUpdate::Frozen`]) is kept while it is at most ½.
    pub(super) frozen_contraction: f64,
    /// The implicit normal compliance of the current step, if any.
    pub(super) implicit: Option<ImplicitNormalCompliance>,
    /// True while `matrix` is the plain viscous operator (false after a Newton tangent).
    pub(super) matrix_is_plain: bool,
    /// The normal contact unknowns are eliminated just before the tangential ones
    /// ([`Self::eliminate_normals_last`]).
    pub(super) normals_last: bool,
    /// Whether `solver` holds the symbolic analysis of the current arrangement of the contact
    /// unknowns: the analysis is made by the first factorization after a change, so that
    /// arranging the contact unknowns after construction costs one analysis, not two.
    pub(super) analysed: bool,
}

/// The trailing block of the velocity factor when the contact unknowns are eliminated last
/// (elimination order): the tangential ones, preceded by the normal ones when the implicit
/// normal compliance is to be linearized without refactorizing the body
/// ([`VelocityOperator::eliminate_normals_last`]).
///
/// With P H Pᵀ = L Lᵀ and the block split into body b and contact c unknowns,
/// L = [[L_bb, 0], [L_cb, L_cc]], the Schur complement of H on c is S_c = L_cc L_ccᵀ. A Newton
/// tangent H + D of the implicit normal compliance (D diagonal, on the normal unknowns of c)
/// keeps L_bb and L_cb: its factor is L with L_cc replaced by L′ = chol(S_c + D). The solves
/// then use the sparse factor of H and map the trailing block: z′_c = L′⁻¹ L_cc z_c forward,
/// w_c = L_ccᵀ L′⁻ᵀ z′_c backward.
#[derive(Debug, Clone)]
pub(super) struct TrailingFactor {
    /// The trailing factor of the current operator: L_cc of the sparse factor, or L′ of a
    /// Newton tangent when `plain` is set.
    pub(super) factor: Mat<f64>,
    /// For each tangential unknown of the block (after the `leading` normal ones): its position
    /// in `tangential`.
    pub(super) index: Vec<usize>,
    /// Number of normal contact unknowns at the head of the block (0 unless normals are
    /// eliminated last).
    pub(super) leading: usize,
    /// The contact node (index into the contact nodes) of each leading normal unknown.
    pub(super) normal_nodes: Vec<usize>,
    /// L_cc of the sparse factor (of H) when `factor` is the L′ of a Newton tangent.
    pub(super) plain: Option<Mat<f64>>,
    /// S_c = L_cc L_ccᵀ of the sparse factor, formed at the first Newton tangent.
    pub(super) plain_schur: Option<Mat<f64>>,
}

impl<const D: usize> VelocityOperator<D> {
    /// The Cholesky solver of the operator (its analysis and factor once a step has been
    /// solved: before the first factorization it is the solver of an empty matrix); for
    /// benchmarks of the triangular solves.
    pub fn solver(&self) -> &CholeskySolver {
        &self.solver
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

    /// The constrained unknowns (Cartesian components, node-major). (The field `constrained`
    /// holds the same in the system frame, which differs at contact nodes on a symmetry plane.)
    #[allow(clippy::misnamed_getters)]
    pub fn constrained(&self) -> &[bool] {
        &self.constrained_cartesian
    }
}
