//! Manufactured solutions (docs/model.md §5): exact fields u, β given as expressions in
//! (x, y, z, t), and the data that make them exact — f0, f2, f3, q and the damage flux — derived
//! by automatic differentiation (num-dual) and the chain rule through the solver's constitutive
//! laws.
//!
//! The harness evaluates the exact fields and their derivatives with programs compiled once per
//! case by symbolic differentiation ([`programs`]), over batches of quadrature points, and
//! applies the chain rule through the laws per point on `f64` ([`data`]). The point-by-point
//! functions here evaluate the same derivatives by one nested dual evaluation of the syntax
//! tree, `Dual2Vec<Dual64, D>` (a second-order dual in space over a first-order dual in time):
//! the reference the compiled path is tested against. No derivative is written by hand on
//! either path, and both share the chain-rule functions (`*_at`).

pub mod data;
pub mod programs;

use crate::expr::Expr;
use contact_damage::model::laws::Tensor;
use contact_damage::scheme::Model;
use nalgebra::{Const, SMatrix, SVector};
use num_dual::{hessian, Dual2Vec, Dual64};

/// Value, time derivative, spatial gradient and Hessian of a scalar field and of its time derivative.
#[derive(Debug, Clone, Copy)]
pub struct Jet<const D: usize> {
    /// f(x, t).
    pub value: f64,
    /// ∂f/∂t.
    pub rate: f64,
    /// ∇f.
    pub gradient: SVector<f64, D>,
    /// ∇(∂f/∂t).
    pub rate_gradient: SVector<f64, D>,
    /// ∇²f.
    pub hessian: SMatrix<f64, D, D>,
    /// ∇²(∂f/∂t).
    pub rate_hessian: SMatrix<f64, D, D>,
}

/// Evaluates the jet of an expression in the variables (x, y, z, t) (z = 0 in 2D).
pub fn jet<const D: usize>(expr: &Expr, x: &[f64; D], t: f64) -> Jet<D> {
    let point = SVector::<Dual64, D>::from_fn(|i, _| Dual64::from(x[i]));
    let (value, gradient, hess) = hessian(
        |p: SVector<Dual2Vec<Dual64, Const<D>>, D>| {
            let time = Dual2Vec::from_re(Dual64::new(t, 1.0));
            let zero = Dual2Vec::from_re(Dual64::from(0.0));
            let vars = [p[0], p[1], if D == 3 { p[D - 1] } else { zero }, time];
            expr.eval(&vars)
        },
        &point,
    );
    Jet {
        value: value.re,
        rate: value.eps,
        gradient: gradient.map(|g| g.re),
        rate_gradient: gradient.map(|g| g.eps),
        hessian: hess.map(|h| h.re),
        rate_hessian: hess.map(|h| h.eps),
    }
}

/// Value and gradient of an expression at (x, t) (first-order duals only; for error norms).
pub fn value_gradient<const D: usize>(expr: &Expr, x: &[f64; D], t: f64) -> (f64, SVector<f64, D>) {
    let point = SVector::<f64, D>::from_column_slice(x);
    let (value, gradient) = num_dual::gradient(
        |p: SVector<num_dual::DualVec<f64, Const<D>>, D>| {
            let time = num_dual::DualVec::from_re(t);
            let zero = num_dual::DualVec::from_re(0.0);
            let vars = [p[0], p[1], if D == 3 { p[D - 1] } else { zero }, time];
            expr.eval(&vars)
        },
        &point,
    );
    (value, gradient)
}

/// Plain value of an expression at (x, t).
pub fn value<const D: usize>(expr: &Expr, x: &[f64; D], t: f64) -> f64 {
    let z = if D == 3 { x[D - 1] } else { 0.0 };
    expr.eval_f64(&[x[0], x[1], z, t])
}

/// The exact solution of a manufactured case and the auxiliary fields of docs/model.md §5.
#[derive(Clone)]
pub struct ExactSolution<const D: usize> {
    /// u_i(x, t), i = 1..D.
    pub displacement: [Expr; D],
    /// β(x, t).
    pub damage: Expr,
    /// ξ(x, t): the stick traction field (its tangential part is used), |ξ_τ| ≤ 1.
    pub stick_traction: [Expr; D],
    /// η(x, t) ∈ ∂ψ_K(β): ≥ 0 where β = 1, ≤ 0 where β = 0, 0 in between.
    pub damage_multiplier: Expr,
    /// g(x, t), may be negative (an obstacle pushed into the body).
    pub gap: Expr,
}

/// The constitutive laws the sources are derived with: the solver's own [`Model`], so the
/// manufactured data and the scheme use the same objects.
pub type Laws<const D: usize> = Model<D>;

/// All derivatives of the exact fields at one point and time.
#[derive(Debug, Clone, Copy)]
pub struct PointState<const D: usize> {
    /// u.
    pub displacement: SVector<f64, D>,
    /// u̇.
    pub velocity: SVector<f64, D>,
    /// ∇u (∂u_i/∂x_j at (i, j)).
    pub displacement_gradient: SMatrix<f64, D, D>,
    /// ∇u̇.
    pub velocity_gradient: SMatrix<f64, D, D>,
    /// ∂_j ∇u for j = 0..D (∂²u_i/∂x_k∂x_j at (i, k) of entry j).
    pub displacement_second: [SMatrix<f64, D, D>; D],
    /// ∂_j ∇u̇.
    pub velocity_second: [SMatrix<f64, D, D>; D],
    /// β.
    pub damage: f64,
    /// ∇β.
    pub damage_gradient: SVector<f64, D>,
}

fn symmetric<const D: usize>(m: &SMatrix<f64, D, D>) -> Tensor<D> {
    (m + m.transpose()) * 0.5
}

impl<const D: usize> ExactSolution<D> {
    /// Evaluates every derivative needed by the source terms at (x, t).
    pub fn point_state(&self, x: &[f64; D], t: f64) -> PointState<D> {
        let jets: [Jet<D>; D] = std::array::from_fn(|i| jet(&self.displacement[i], x, t));
        let displacement = SVector::<f64, D>::from_fn(|i, _| jets[i].value);
        let velocity = SVector::<f64, D>::from_fn(|i, _| jets[i].rate);
        let displacement_gradient = SMatrix::<f64, D, D>::from_fn(|i, j| jets[i].gradient[j]);
        let velocity_gradient = SMatrix::<f64, D, D>::from_fn(|i, j| jets[i].rate_gradient[j]);
        let displacement_second =
            std::array::from_fn(|j| SMatrix::<f64, D, D>::from_fn(|i, k| jets[i].hessian[(k, j)]));
        let velocity_second = std::array::from_fn(|j| {
            SMatrix::<f64, D, D>::from_fn(|i, k| jets[i].rate_hessian[(k, j)])
        });
        let (damage, damage_gradient) = value_gradient(&self.damage, x, t);
        PointState {
            displacement,
            velocity,
            displacement_gradient,
            velocity_gradient,
            displacement_second,
            velocity_second,
            damage,
            damage_gradient,
        }
    }

    /// σ = 𝒜ε(u̇) + G(ε(u), β) at (x, t) (2.1).
    pub fn stress(&self, laws: &Laws<D>, state: &PointState<D>) -> Tensor<D> {
        stress_at(laws, state)
    }

    /// f0 = −Div σ at (x, t) (tree evaluation; see [`body_force_at`]).
    pub fn body_force(&self, laws: &Laws<D>, x: &[f64; D], t: f64) -> [f64; D] {
        body_force_at(laws, &self.point_state(x, t))
    }

    /// f2 = σν on Γ2 (2.6) (tree evaluation).
    pub fn traction(&self, laws: &Laws<D>, x: &[f64; D], t: f64, normal: &[f64; D]) -> [f64; D] {
        traction_at(laws, &self.point_state(x, t), normal)
    }

    /// Penetration r = u_ν − g(x, t) at a point of Γ3 (`state` at time t).
    pub fn penetration(
        &self,
        state: &PointState<D>,
        x: &[f64; D],
        t: f64,
        normal: &SVector<f64, D>,
    ) -> f64 {
        state.displacement.dot(normal) - value(&self.gap, x, t)
    }

    /// f3 = σν + p_ν(u_ν − g) ν + p_τ(u_ν − g) ξ̂ on Γ3 (docs/model.md §5) (tree evaluation).
    pub fn contact_traction(
        &self,
        laws: &Laws<D>,
        x: &[f64; D],
        t: f64,
        normal: &[f64; D],
    ) -> [f64; D] {
        let state = self.point_state(x, t);
        let xi = SVector::<f64, D>::from_fn(|i, _| value(&self.stick_traction[i], x, t));
        contact_traction_at(laws, &state, &xi, value(&self.gap, x, t), normal)
    }

    /// q = β̇ − κΔβ + η − φ(ε(u), β) (docs/model.md §5) (tree evaluation).
    pub fn damage_supply(&self, laws: &Laws<D>, x: &[f64; D], t: f64) -> f64 {
        let damage = jet(&self.damage, x, t);
        let mut gradient = SMatrix::<f64, D, D>::zeros();
        for (i, component) in self.displacement.iter().enumerate() {
            let (_, row) = value_gradient(component, x, t);
            gradient.set_row(i, &row.transpose());
        }
        damage_supply_at(
            laws,
            &DamageJet {
                value: damage.value,
                rate: damage.rate,
                laplacian: damage.hessian.trace(),
                multiplier: value(&self.damage_multiplier, x, t),
            },
            &gradient,
        )
    }

    /// κ ∂β/∂ν on Γ (Neumann datum of the damage equation) (tree evaluation).
    pub fn damage_flux(&self, laws: &Laws<D>, x: &[f64; D], t: f64, normal: &[f64; D]) -> f64 {
        let (_, gradient) = value_gradient(&self.damage, x, t);
        damage_flux_at(laws, &gradient, normal)
    }
}

/// σ = 𝒜ε(u̇) + G(ε(u), β) (2.1).
#[inline]
pub fn stress_at<const D: usize>(laws: &Laws<D>, state: &PointState<D>) -> Tensor<D> {
    laws.viscosity.stress(&symmetric(&state.velocity_gradient))
        + laws
            .elasticity
            .stress(&symmetric(&state.displacement_gradient), state.damage)
}

/// f0 = −Div σ by the chain rule: Div σ = Div 𝒜(ε(u̇)) + Div G(ε(u), β), each law's
/// divergence from the strain (rate), its partial derivatives ∂_j ε and ∇β
/// ([`contact_damage::model::laws::Viscosity::stress_divergence`],
/// [`contact_damage::model::laws::Elasticity::stress_divergence`]).
#[inline]
pub fn body_force_at<const D: usize>(laws: &Laws<D>, state: &PointState<D>) -> [f64; D] {
    body_force_of_strains(
        laws,
        &StrainJet {
            strain: symmetric(&state.velocity_gradient),
            derivatives: std::array::from_fn(|j| symmetric(&state.velocity_second[j])),
        },
        &StrainJet {
            strain: symmetric(&state.displacement_gradient),
            derivatives: std::array::from_fn(|j| symmetric(&state.displacement_second[j])),
        },
        state.damage,
        &state.damage_gradient,
    )
}

/// A strain (or strain rate) ε at a point and its partial derivatives ∂_j ε.
pub struct StrainJet<const D: usize> {
    /// ε.
    pub strain: Tensor<D>,
    /// ∂_j ε for j < D.
    pub derivatives: [Tensor<D>; D],
}

/// f0 = −(Div 𝒜(ε(u̇)) + Div G(ε(u), β)) from the strain jets of u̇ and u, β and ∇β (the
/// formula of [`body_force_at`], which the batched data call on their columns).
#[inline]
pub fn body_force_of_strains<const D: usize>(
    laws: &Laws<D>,
    rate: &StrainJet<D>,
    strain: &StrainJet<D>,
    damage: f64,
    damage_gradient: &SVector<f64, D>,
) -> [f64; D] {
    let divergence = laws
        .viscosity
        .stress_divergence(&rate.strain, &rate.derivatives)
        + laws.elasticity.stress_divergence(
            &strain.strain,
            damage,
            &strain.derivatives,
            damage_gradient,
        );
    std::array::from_fn(|i| -divergence[i])
}

/// f2 = σν on Γ2 (2.6).
#[inline]
pub fn traction_at<const D: usize>(
    laws: &Laws<D>,
    state: &PointState<D>,
    normal: &[f64; D],
) -> [f64; D] {
    let sigma_n = stress_at(laws, state) * SVector::<f64, D>::from_column_slice(normal);
    std::array::from_fn(|i| sigma_n[i])
}

/// Relative size of the round-off in u̇_τ = u̇ − (u̇·ν)ν: a tangential speed at most
/// `SLIP_ROUNDOFF · |u̇|` is the round-off of a stuck point (whose u̇ is normal), not slip.
///
/// On a contact boundary that is not axis-aligned the projection of a normal velocity leaves a
/// tangential remainder of a few ulps in a direction that is noise; taking it for slip would put
/// a friction traction of full size p_τ in that direction into f3. The exact fields then solve
/// the problem with these data up to a tangential velocity of this round-off size.
pub const SLIP_ROUNDOFF: f64 = 16.0 * f64::EPSILON;

/// v_τ = v − (v·ν)ν, projected twice: one projection of a nearly normal v leaves a normal
/// remainder of the size of the round-off of v·ν, which the second removes (so that
/// |v_τ·ν| ≤ a few ulps of |v_τ|, also on boundaries that are not axis-aligned).
pub fn tangential_part<const D: usize>(
    v: &SVector<f64, D>,
    normal: &SVector<f64, D>,
) -> SVector<f64, D> {
    let once = v - normal * v.dot(normal);
    once - normal * once.dot(normal)
}

/// The friction direction ξ̂ of docs/model.md §5: u̇_τ/|u̇_τ| where the body slips, else the
/// tangential part of the stick field ξ (stick: |u̇_τ| ≤ [`SLIP_ROUNDOFF`] · |u̇|, i.e. u̇_τ = 0
/// up to round-off).
pub fn friction_direction<const D: usize>(
    state: &PointState<D>,
    stick_traction: &SVector<f64, D>,
    normal: &SVector<f64, D>,
) -> SVector<f64, D> {
    let slip = tangential_part(&state.velocity, normal);
    let speed = slip.norm();
    if speed > SLIP_ROUNDOFF * state.velocity.norm() {
        slip / speed
    } else {
        tangential_part(stick_traction, normal)
    }
}

/// f3 = σν + p_ν(r) ν + p_τ(r) ξ̂ on Γ3 with the penetration r = u_ν − g (docs/model.md §5).
#[inline]
pub fn contact_traction_at<const D: usize>(
    laws: &Laws<D>,
    state: &PointState<D>,
    stick_traction: &SVector<f64, D>,
    gap: f64,
    normal: &[f64; D],
) -> [f64; D] {
    let (nu, pressure, friction) = contact_parts(laws, state, stick_traction, gap, normal);
    let f3 = stress_at(laws, state) * nu + pressure + friction;
    std::array::from_fn(|i| f3[i])
}

/// ν, p_ν(r) ν and p_τ(r) ξ̂ at a point of Γ3 with the penetration r = u_ν − g.
#[inline]
fn contact_parts<const D: usize>(
    laws: &Laws<D>,
    state: &PointState<D>,
    stick_traction: &SVector<f64, D>,
    gap: f64,
    normal: &[f64; D],
) -> (SVector<f64, D>, SVector<f64, D>, SVector<f64, D>) {
    let nu = SVector::<f64, D>::from_column_slice(normal);
    let r = state.displacement.dot(&nu) - gap;
    let pressure = nu * laws.contact.normal_pressure(r);
    let friction = friction_direction(state, stick_traction, &nu) * laws.contact.friction_bound(r);
    (nu, pressure, friction)
}

/// f3 − σν = p_ν(r) ν + p_τ(r) ξ̂ on Γ3: the contact part of f3, the Γ3 load of the data in
/// stress form (where σ enters as ∫_Ω σ : ε(w), [`crate::case::LoadForm::Stress`]).
#[inline]
pub fn contact_load_at<const D: usize>(
    laws: &Laws<D>,
    state: &PointState<D>,
    stick_traction: &SVector<f64, D>,
    gap: f64,
    normal: &[f64; D],
) -> [f64; D] {
    let (_, pressure, friction) = contact_parts(laws, state, stick_traction, gap, normal);
    let load = pressure + friction;
    std::array::from_fn(|i| load[i])
}

/// β, β̇, Δβ and η at one point (what the damage supply needs besides ∇u).
#[derive(Debug, Clone, Copy)]
pub struct DamageJet {
    /// β.
    pub value: f64,
    /// β̇.
    pub rate: f64,
    /// Δβ.
    pub laplacian: f64,
    /// η.
    pub multiplier: f64,
}

/// q = β̇ − κΔβ + η − φ(ε(u), β) (docs/model.md §5).
#[inline]
pub fn damage_supply_at<const D: usize>(
    laws: &Laws<D>,
    damage: &DamageJet,
    displacement_gradient: &SMatrix<f64, D, D>,
) -> f64 {
    let strain = symmetric(displacement_gradient);
    damage_supply_of_source(
        laws,
        damage,
        laws.damage_source.source(&strain, damage.value),
    )
}

/// q = β̇ − κΔβ + η − φ from the value `source` = φ(ε(u), β) (the formula of
/// [`damage_supply_at`], which the batched data call after one batch evaluation of φ).
#[inline]
pub fn damage_supply_of_source<const D: usize>(
    laws: &Laws<D>,
    damage: &DamageJet,
    source: f64,
) -> f64 {
    damage.rate - laws.damage_diffusion * damage.laplacian + damage.multiplier - source
}

/// κ ∂β/∂ν.
#[inline]
pub fn damage_flux_at<const D: usize>(
    laws: &Laws<D>,
    damage_gradient: &SVector<f64, D>,
    normal: &[f64; D],
) -> f64 {
    laws.damage_diffusion * damage_gradient.dot(&SVector::<f64, D>::from_column_slice(normal))
}
