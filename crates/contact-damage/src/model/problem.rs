//! Problem P of §2–3 as data: the constitutive laws and the damage diffusion ([`Model`]), and
//! the loads, gap, Dirichlet data and initial data ([`Data`]).

use crate::model::dirichlet::PrescribedDisplacement;
use crate::model::fields::{
    BoundaryScalarField, BoundaryVectorField, PointScalarField, ScalarField, StaticScalarField,
    StaticVectorField, TensorField, VectorField,
};
use crate::model::laws::{ContactLaw, DamageSource, Elasticity, Viscosity};
use std::sync::Arc;

/// The constitutive laws of Problem P (§2) and the damage diffusion κ of (2.2).
#[derive(Clone)]
pub struct Model<const D: usize> {
    /// 𝒜, acting on ε(u̇).
    pub viscosity: Arc<dyn Viscosity<D>>,
    /// G(ε(u), β).
    pub elasticity: Arc<dyn Elasticity<D>>,
    /// φ(ε(u), β).
    pub damage_source: Arc<dyn DamageSource<D>>,
    /// p_ν and p_τ.
    pub contact: Arc<dyn ContactLaw>,
    /// κ > 0.
    pub damage_diffusion: f64,
}

/// Loads, gap and initial data. Everything but the gap and the initial data is optional.
#[derive(Clone)]
pub struct Data<const D: usize> {
    /// Body force f0 (2.3).
    pub body_force: Option<VectorField<D>>,
    /// A stress S given as data: adds ∫_Ω S : ε(w) to the load of (5.1). By Green's formula this
    /// is the body force −Div S with the traction S ν on ∂Ω, written so that S is integrated
    /// rather than differentiated: the form in which manufactured data of limited smoothness
    /// keep their quadrature error at the order of the interpolation error (docs/model.md §5).
    pub body_stress: Option<TensorField<D>>,
    /// Traction f2 on Γ2 (2.6).
    pub traction: Option<BoundaryVectorField<D>>,
    /// Extra traction f3 on Γ3 (used by manufactured solutions, docs/model.md §5): adds ∫_Γ3 f3·w.
    pub contact_traction: Option<BoundaryVectorField<D>>,
    /// Extra damage supply q added to φ (manufactured solutions).
    pub damage_supply: Option<ScalarField<D>>,
    /// Damage flux κ ∂β/∂ν on Γ (zero in (2.4); nonzero for manufactured solutions).
    pub damage_flux: Option<BoundaryScalarField<D>>,
    /// Gap g(x, t) on Γ3, measured along the outward normal. It may move and be negative (a
    /// rigid obstacle pushed into the body); the explicit scheme (5.1) takes it at t_{n−1},
    /// with u_{n−1}, the implicit normal compliance at t_n (see [`ContactTreatment`](crate::scheme::ContactTreatment)).
    pub gap: PointScalarField<D>,
    /// Parts of Γ1 with a prescribed displacement u = u_D(x, t), some components or all; the
    /// Γ1 facets of no part are clamped, u = 0 (2.5). Empty: the paper's Γ1.
    pub dirichlet: Vec<PrescribedDisplacement<D>>,
    /// u0 (must equal u_D(·, 0) on the prescribed components of Γ1, 0 on the clamped ones).
    pub initial_displacement: StaticVectorField<D>,
    /// β0 with values in [0, 1].
    pub initial_damage: StaticScalarField<D>,
    /// Planes across which the boundary data f2, f3 and the damage flux jump (a pressure on part
    /// of a face, a friction traction at a stick–slip front): the facets a plane crosses are
    /// integrated piecewise, each side by the full rule
    /// ([`FacetRule::split`](crate::fem::space::FacetRule::split)), so the jump costs no
    /// quadrature error. Straight facets only; at most one plane per facet; a zero or non-finite
    /// normal or a non-finite offset is refused. Empty: none.
    pub jump_planes: Vec<JumpPlane<D>>,
}

/// The plane {x : normal · x = offset} (see [`Data::jump_planes`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JumpPlane<const D: usize> {
    /// A normal of the plane (any length but zero).
    pub normal: [f64; D],
    /// normal · x on the plane.
    pub offset: f64,
}

impl<const D: usize> JumpPlane<D> {
    /// normal · x − offset: of one sign on each side of the plane, affine in x.
    pub fn level(&self, x: &[f64; D]) -> f64 {
        self.normal.iter().zip(x).map(|(n, x)| n * x).sum::<f64>() - self.offset
    }
}
