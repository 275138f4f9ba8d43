//! The settings, data and results of a velocity step (5.1).

use crate::model::contact::ContactStatus;
use crate::model::laws::ContactLaw;
use crate::solvers::friction::FrictionSettings;
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
    /// How a nonlinear 𝒜's tangent is updated between iterations.
    pub tangent: TangentUpdate,
}

impl Default for VelocitySettings {
    fn default() -> Self {
        Self {
            tolerance: 1e-10,
            max_newton: 50,
            friction: FrictionSettings::default(),
            tangent: TangentUpdate::Frozen,
        }
    }
}

/// The model matrix of the proximal Newton iteration of a nonlinear 𝒜 (a linear 𝒜 and the
/// implicit contact block always use their exact tangent).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum TangentUpdate {
    /// The exact tangent at every iterate (assembled and factorized at each iteration).
    Newton,
    /// The last factorized tangent, kept across iterations and steps while an accepted step
    /// at least halves the KKT residual, refreshed at the iterate otherwise, and exact Newton
    /// in a step past half of [`VelocitySettings::max_newton`] iterations (a frozen tangent:
    /// any symmetric positive definite model keeps the globalization's convergence, at a
    /// linear rate). The default: on the nonlinear manufactured cases it runs 1.4–2.1 times
    /// faster than [`Self::Newton`] (`bench_tangent` in the performance guide).
    #[default]
    Frozen,
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
    /// Numeric Cholesky factorizations of the sparse velocity operator done in this step.
    pub factorizations: usize,
    /// Dense Cholesky factorizations of the contact block alone (Newton tangents of the
    /// implicit normal compliance with a linear 𝒜, the body's factor kept; see
    /// [`VelocityOperator::eliminate_normals_last`](super::VelocityOperator::eliminate_normals_last)).
    pub contact_block_factorizations: usize,
    /// Relative KKT residual of (5.1) on the full system, see
    /// [`VelocityOperator::kkt_residual`](super::VelocityOperator::kkt_residual).
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
