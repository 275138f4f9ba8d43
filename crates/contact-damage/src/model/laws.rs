//! Constitutive functions of the model (paper §2–3): the viscosity operator 𝒜, the
//! damage-dependent elasticity G, the damage source φ, and the contact functions p_ν, p_τ.
//!
//! Every law validates its parameters against the assumptions (3.4)–(3.7) of the theory, and an
//! error names the offending parameter.
//!
//! Besides the closed-form laws, two laws take user-written functions through small traits (the
//! verification harness implements them for expressions with automatic differentiation):
//! [`PotentialViscosity`], 𝒜 = ∂Φ/∂ε for a potential Φ(tr ε, |ε_D|) ([`InvariantPotential`]),
//! and [`ModuliElasticity`], G with moduli μ(β), λ(β) ([`DamageModuli`]). Their `validate` checks
//! (3.4), resp. the sign conditions of the moduli, at fixed samples.

use crate::error::{Error, Result};
use nalgebra::{DMatrix, SMatrix, SVector};
use std::sync::Arc;

/// A symmetric second-order tensor in R^D (strain, strain rate, stress).
pub type Tensor<const D: usize> = SMatrix<f64, D, D>;

fn trace<const D: usize>(tensor: &Tensor<D>) -> f64 {
    tensor.trace()
}

fn deviator<const D: usize>(tensor: &Tensor<D>) -> Tensor<D> {
    tensor - Tensor::<D>::identity() * (trace(tensor) / D as f64)
}

fn check_finite(name: &str, value: f64) -> Result<()> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(Error::parameter(name, value, "must be finite"))
    }
}

/// Viscosity operator 𝒜 of the Kelvin–Voigt law (2.1), acting on the strain rate ε(u̇).
///
/// Assumption (3.4): 𝒜 is Lipschitz and strongly monotone. The solver additionally uses a
/// potential Φ with ∇Φ = 𝒜, so that the velocity step (5.1) is a convex minimization and
/// Newton's method can be globalized by a line search.
pub trait Viscosity<const D: usize>: Send + Sync {
    /// 𝒜(ε).
    fn stress(&self, strain_rate: &Tensor<D>) -> Tensor<D>;
    /// Directional derivative d𝒜(ε)\[δε\] (the consistent tangent).
    fn tangent(&self, strain_rate: &Tensor<D>, direction: &Tensor<D>) -> Tensor<D>;
    /// Potential Φ(ε) with ∇Φ = 𝒜, Φ(0) = 0.
    fn potential(&self, strain_rate: &Tensor<D>) -> f64;
    /// True when 𝒜 is linear: the velocity operator is then factorized once per run.
    fn is_linear(&self) -> bool;
    /// Checks the parameters against (3.4).
    fn validate(&self) -> Result<()>;
    /// Div 𝒜(ε) at a point of a smooth strain-rate field ε(x), by the chain rule:
    /// (Div 𝒜(ε))_i = Σ_j (d𝒜(ε)\[∂_j ε\])_ij, from ε and its partial derivatives
    /// `derivatives[j]` = ∂_j ε.
    ///
    /// Not used by the scheme: manufactured solutions need it (f0 = −Div σ). The default applies
    /// the tangent once per direction and keeps column j of the j-th result; a law with a closed
    /// form overrides it (one call per point instead of D tangents).
    fn stress_divergence(
        &self,
        strain_rate: &Tensor<D>,
        derivatives: &[Tensor<D>; D],
    ) -> SVector<f64, D> {
        let mut divergence = SVector::<f64, D>::zeros();
        for (j, derivative) in derivatives.iter().enumerate() {
            divergence += self.tangent(strain_rate, derivative).column(j);
        }
        divergence
    }
    /// Σ_p w_p 𝒜(ε_p)·ε_p: the viscous power Σ_p w_p 𝒜ε·ε of a batch of strain rates with the
    /// weights of a quadrature rule (pairs beyond the shorter slice are ignored). One call
    /// through a trait object per batch, the law's own [`Viscosity::stress`] inlined in the loop.
    fn weighted_power_sum(&self, strain_rates: &[Tensor<D>], weights: &[f64]) -> f64 {
        strain_rates
            .iter()
            .zip(weights)
            .map(|(rate, weight)| weight * self.stress(rate).dot(rate))
            .sum()
    }
    /// [`Viscosity::stress_divergence`] at a batch of points, from the partial derivatives
    /// of the velocity field there (columns, see [`FieldJets`]): `out[i][p]` is component i
    /// at point p, for the first `out[0].len()` points. Bitwise the values point by point;
    /// one call through a trait object per batch, the law's own method inlined in the loop
    /// (where the strain rate itself is not needed, as for [`LinearViscosity`], it is not
    /// built).
    fn stress_divergence_of_jets(&self, velocity: &FieldJets<'_, D>, out: &mut [&mut [f64]; D]) {
        for p in 0..out[0].len() {
            let divergence =
                self.stress_divergence(&velocity.strain(p), &velocity.strain_derivatives(p));
            for (i, out) in out.iter_mut().enumerate() {
                out[p] = divergence[i];
            }
        }
    }
}

/// The first and second partial derivatives of a smooth vector field w at a batch of points,
/// one slice per derivative (structure of arrays, as a compiled program of the exact fields
/// writes them): `gradient[i][k][p]` = ∂w_i/∂x_k and `second[j][i][k][p]` = ∂²w_i/∂x_k∂x_j
/// at point p. The strain ε(w) and its derivatives ∂_j ε(w), which the laws' divergences take,
/// are their symmetric parts ([`FieldJets::strain`], [`FieldJets::strain_derivatives`]).
#[derive(Debug, Clone, Copy)]
pub struct FieldJets<'a, const D: usize> {
    /// ∂w_i/∂x_k, by i and k.
    pub gradient: [[&'a [f64]; D]; D],
    /// ∂²w_i/∂x_k∂x_j, by j, i and k.
    pub second: [[[&'a [f64]; D]; D]; D],
}

impl<const D: usize> FieldJets<'_, D> {
    /// ε(w) = (∇w + ∇wᵀ)/2 at point p.
    #[inline(always)]
    pub fn strain(&self, p: usize) -> Tensor<D> {
        Tensor::<D>::from_fn(|i, k| (self.gradient[i][k][p] + self.gradient[k][i][p]) * 0.5)
    }

    /// ∂_j ε(w) at point p, for j < D.
    #[inline(always)]
    pub fn strain_derivatives(&self, p: usize) -> [Tensor<D>; D] {
        std::array::from_fn(|j| {
            let second = &self.second[j];
            Tensor::<D>::from_fn(|i, k| (second[i][k][p] + second[k][i][p]) * 0.5)
        })
    }
}

/// Σ_j (∂_j ε)_ij and tr(∂_i ε) for i < D: the two contractions that the divergence of an
/// isotropic linear law 2a ε + b tr(ε) I needs, `(2a Σ_j (∂_j ε)_ij + b tr(∂_i ε))_i`.
fn isotropic_divergence<const D: usize>(
    twice_shear: f64,
    trace_factor: f64,
    derivatives: &[Tensor<D>; D],
) -> SVector<f64, D> {
    SVector::<f64, D>::from_fn(|i, _| {
        let mut column_sum = 0.0;
        for (j, derivative) in derivatives.iter().enumerate() {
            column_sum += derivative[(i, j)];
        }
        twice_shear * column_sum + trace_factor * trace(&derivatives[i])
    })
}

/// Linear isotropic viscosity 𝒜ε = 2η ε + ζ tr(ε) I.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearViscosity {
    /// Shear viscosity η > 0.
    pub shear: f64,
    /// Bulk viscosity ζ, with 2η + dζ > 0 (strong monotonicity).
    pub bulk: f64,
}

impl<const D: usize> Viscosity<D> for LinearViscosity {
    fn stress(&self, strain_rate: &Tensor<D>) -> Tensor<D> {
        strain_rate * (2.0 * self.shear)
            + Tensor::<D>::identity() * (self.bulk * trace(strain_rate))
    }
    fn tangent(&self, _strain_rate: &Tensor<D>, direction: &Tensor<D>) -> Tensor<D> {
        <Self as Viscosity<D>>::stress(self, direction)
    }
    fn potential(&self, strain_rate: &Tensor<D>) -> f64 {
        let tr = trace(strain_rate);
        self.shear * strain_rate.norm_squared() + 0.5 * self.bulk * tr * tr
    }
    fn is_linear(&self) -> bool {
        true
    }
    /// Div(2η ε + ζ tr(ε) I) = (2η Σ_j ∂_j ε_ij + ζ ∂_i tr ε)_i.
    fn stress_divergence(
        &self,
        _strain_rate: &Tensor<D>,
        derivatives: &[Tensor<D>; D],
    ) -> SVector<f64, D> {
        isotropic_divergence(2.0 * self.shear, self.bulk, derivatives)
    }
    fn validate(&self) -> Result<()> {
        check_finite("viscosity.shear", self.shear)?;
        check_finite("viscosity.bulk", self.bulk)?;
        if self.shear <= 0.0 {
            return Err(Error::parameter(
                "viscosity.shear",
                self.shear,
                "η must be > 0 for 𝒜 to be strongly monotone (3.4)",
            ));
        }
        if 2.0 * self.shear + D as f64 * self.bulk <= 0.0 {
            return Err(Error::parameter(
                "viscosity.bulk",
                self.bulk,
                format!(
                    "2η + dζ must be > 0 for 𝒜 to be strongly monotone (3.4); here η = {}",
                    self.shear
                ),
            ));
        }
        Ok(())
    }
}

/// Nonlinear viscosity with a rate-saturating deviatoric part:
/// 𝒜ε = 2η ε + ζ tr(ε) I + η₁ ε_D / √(1 + |ε_D|²/ε₀²).
///
/// It is the gradient of the convex potential η|ε|² + ζ/2 (tr ε)² + η₁ ε₀² (√(1 + |ε_D|²/ε₀²) − 1),
/// hence monotone; the linear part makes it strongly monotone and the extra part is Lipschitz with
/// constant η₁, so (3.4) holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SaturatingViscosity {
    /// Linear part (η, ζ).
    pub linear: LinearViscosity,
    /// Extra shear viscosity η₁ ≥ 0 at small rates.
    pub extra_shear: f64,
    /// Rate scale ε₀ > 0 above which the extra stress saturates.
    pub rate_scale: f64,
}

impl<const D: usize> Viscosity<D> for SaturatingViscosity {
    fn stress(&self, strain_rate: &Tensor<D>) -> Tensor<D> {
        let dev = deviator(strain_rate);
        let root = (1.0 + dev.norm_squared() / (self.rate_scale * self.rate_scale)).sqrt();
        <LinearViscosity as Viscosity<D>>::stress(&self.linear, strain_rate)
            + dev * (self.extra_shear / root)
    }
    fn tangent(&self, strain_rate: &Tensor<D>, direction: &Tensor<D>) -> Tensor<D> {
        let dev = deviator(strain_rate);
        let dir_dev = deviator(direction);
        let scale2 = self.rate_scale * self.rate_scale;
        let root = (1.0 + dev.norm_squared() / scale2).sqrt();
        let inner = dev.dot(&dir_dev);
        <LinearViscosity as Viscosity<D>>::stress(&self.linear, direction)
            + (dir_dev / root - dev * (inner / (scale2 * root * root * root))) * self.extra_shear
    }
    fn potential(&self, strain_rate: &Tensor<D>) -> f64 {
        let dev = deviator(strain_rate);
        let scale2 = self.rate_scale * self.rate_scale;
        <LinearViscosity as Viscosity<D>>::potential(&self.linear, strain_rate)
            + self.extra_shear * scale2 * ((1.0 + dev.norm_squared() / scale2).sqrt() - 1.0)
    }
    fn is_linear(&self) -> bool {
        self.extra_shear == 0.0
    }
    fn validate(&self) -> Result<()> {
        <LinearViscosity as Viscosity<D>>::validate(&self.linear)?;
        check_finite("viscosity.extra_shear", self.extra_shear)?;
        check_finite("viscosity.rate_scale", self.rate_scale)?;
        if self.extra_shear < 0.0 {
            return Err(Error::parameter(
                "viscosity.extra_shear",
                self.extra_shear,
                "η₁ must be ≥ 0 (monotonicity, (3.4))",
            ));
        }
        if self.rate_scale <= 0.0 {
            return Err(Error::parameter(
                "viscosity.rate_scale",
                self.rate_scale,
                "ε₀ must be > 0",
            ));
        }
        Ok(())
    }
}

/// First and second partial derivatives of an isotropic potential Φ(t, n) in the invariants
/// t = tr ε and n = |ε_D| of the strain rate (ε_D = ε − tr(ε)/d I, |·| the Frobenius norm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InvariantJet {
    /// Φ(t, n).
    pub value: f64,
    /// (Φ_t, Φ_n).
    pub gradient: [f64; 2],
    /// ((Φ_tt, Φ_tn), (Φ_nt, Φ_nn)).
    pub hessian: [[f64; 2]; 2],
}

/// A viscosity potential written in the invariants (t, n) = (tr ε, |ε_D|), n ≥ 0, of the strain
/// rate: the user-written part of [`PotentialViscosity`]. Derivatives in n at n = 0 are one-sided
/// (from n > 0); for Φ(ε) = Φ(tr ε, |ε_D|) to be differentiable at ε_D = 0, Φ_n(t, 0) = 0 is
/// needed (checked by [`PotentialViscosity`]'s `validate`).
pub trait InvariantPotential: Send + Sync {
    /// Φ(t, n).
    fn value(&self, trace: f64, dev_norm: f64) -> f64;
    /// Φ and its first and second partial derivatives at (t, n).
    fn jet(&self, trace: f64, dev_norm: f64) -> InvariantJet;
}

/// Below this ratio |ε_D| / |ε| the tangent and stress of [`PotentialViscosity`] use the limit form
/// at ε_D → 0 (Φ_n/n → Φ_nn, Φ_nn − Φ_n/n → 0).
///
/// The chain-rule form has bounded factors for any n > 0, but Φ_n/n amplifies the absolute
/// round-off of Φ_n by 1/n. The limit form is exact at n = 0 and, for Φ_n = a n + b n³ + … (Φ
/// smooth in ε), replaces Φ_n/n = a + b n² by Φ_nn = a + 3b n²: a relative change O((n/L)²) for a Φ
/// varying on a rate scale L (e.g. ε₀ of [`SaturatingViscosity`]), below 1e-12 at n ≤ 1e-10 |ε|
/// whenever L ≥ 1e-4 |ε|.
const SMALL_DEVIATOR: f64 = 1e-10;

/// Sampled magnitudes |ε| of the check of [`PotentialViscosity`]: 10^(k/2), k = −8, …, 6
/// (1e-4 to 1e3 on a log grid, 15 values).
fn sampled_rate_magnitudes() -> impl Iterator<Item = f64> {
    (-8..=6).map(|k| 10f64.powf(f64::from(k) / 2.0))
}

/// Sampled directions of the check of [`PotentialViscosity`]: unit strain rates cos θ I/√d +
/// sin θ E_D at 13 angles θ ∈ [0°, 180°] (pure volumetric at 0° and 180°, pure deviatoric at 90°,
/// mixed otherwise), E_D cycling through unit deviators (normal, shear and a generic one).
fn sampled_rate_directions<const D: usize>() -> Vec<Tensor<D>> {
    let volumetric = Tensor::<D>::identity() / (D as f64).sqrt();
    let mut deviators = Vec::new();
    let mut normal = Tensor::<D>::zeros();
    normal[(0, 0)] = 1.0;
    normal[(1, 1)] = -1.0;
    deviators.push(normal);
    let mut shear = Tensor::<D>::zeros();
    shear[(0, 1)] = 1.0;
    shear[(1, 0)] = 1.0;
    deviators.push(shear);
    let generic = Tensor::<D>::from_fn(|i, j| {
        let (a, b) = (i.min(j) as f64, i.max(j) as f64);
        0.3 + 0.7 * a - 0.45 * b + 0.2 * a * b
    });
    deviators.push(deviator(&generic));
    let deviators: Vec<Tensor<D>> = deviators.iter().map(|e| e / e.norm()).collect();
    [
        0.0, 10.0, 30.0, 45.0, 60.0, 80.0, 90.0, 100.0, 120.0, 135.0, 150.0, 170.0, 180.0,
    ]
    .iter()
    .enumerate()
    .map(|(i, degrees): (usize, &f64)| {
        let theta = degrees.to_radians();
        let (sin, cos) = if *degrees == 90.0 {
            (1.0, 0.0)
        } else if *degrees == 180.0 {
            (0.0, -1.0)
        } else {
            theta.sin_cos()
        };
        volumetric * cos + deviators[i % deviators.len()] * sin
    })
    .collect()
}

/// An orthonormal basis (Frobenius product) of the symmetric tensors of R^D: the D diagonal unit
/// tensors and (e_i ⊗ e_j + e_j ⊗ e_i)/√2 for i < j.
fn symmetric_basis<const D: usize>() -> Vec<Tensor<D>> {
    let mut basis = Vec::with_capacity(D * (D + 1) / 2);
    for i in 0..D {
        let mut e = Tensor::<D>::zeros();
        e[(i, i)] = 1.0;
        basis.push(e);
    }
    for i in 0..D {
        for j in i + 1..D {
            let mut e = Tensor::<D>::zeros();
            e[(i, j)] = std::f64::consts::FRAC_1_SQRT_2;
            e[(j, i)] = std::f64::consts::FRAC_1_SQRT_2;
            basis.push(e);
        }
    }
    basis
}

/// The invariants of a strain rate as [`PotentialViscosity`] uses them.
struct Invariants<const D: usize> {
    trace: f64,
    deviator: Tensor<D>,
    /// ε_D/|ε_D|, or 0 where ε_D = 0.
    unit_deviator: Tensor<D>,
    dev_norm: f64,
    /// |ε_D| ≤ SMALL_DEVIATOR |ε|: use the limit form.
    near_axis: bool,
}

impl<const D: usize> Invariants<D> {
    fn of(strain_rate: &Tensor<D>) -> Self {
        let trace = trace(strain_rate);
        let deviator = deviator(strain_rate);
        let dev_norm = deviator.norm();
        let unit_deviator = if dev_norm > 0.0 {
            deviator / dev_norm
        } else {
            Tensor::<D>::zeros()
        };
        Self {
            trace,
            deviator,
            unit_deviator,
            dev_norm,
            near_axis: dev_norm <= SMALL_DEVIATOR * strain_rate.norm(),
        }
    }

    /// (Φ_n/n, Φ_nn − Φ_n/n), by their limits (Φ_nn, 0) as n → 0 near the volumetric axis.
    fn deviatoric_slopes(&self, jet: &InvariantJet) -> (f64, f64) {
        if self.near_axis {
            (jet.hessian[1][1], 0.0)
        } else {
            let secant = jet.gradient[1] / self.dev_norm;
            (secant, jet.hessian[1][1] - secant)
        }
    }
}

/// Viscosity 𝒜 = ∂Φ/∂ε of a user potential Φ(ε) = Φ(tr ε, |ε_D|) of the strain rate, written in
/// its invariants t = tr ε and n = |ε_D| (an [`InvariantPotential`]); the Kelvin–Voigt law (2.1)
/// with 𝒜 the gradient of a convex potential, as the velocity step (5.1) needs.
///
/// By the chain rule (∂t/∂ε = I, ∂n/∂ε = ε_D/n):
///
/// σ = Φ_t I + Φ_n ε_D/n,
///
/// dσ\[δ\] = (Φ_tt tr δ + Φ_tn (ε_D:δ)/n) I + (Φ_n/n) δ_D
///          + ε_D \[Φ_nt tr δ/n + (Φ_nn/n² − Φ_n/n³)(ε_D:δ)\],
///
/// evaluated as (Φ_n/n) δ_D + e \[Φ_nt tr δ + (Φ_nn − Φ_n/n)(e:δ)\] with e = ε_D/n (bounded
/// factors, no 1/n²). Near the volumetric axis, n ≤ 10⁻¹⁰ |ε| (and at ε_D = 0 exactly), the
/// limits Φ_n/n → Φ_nn and Φ_nn − Φ_n/n → 0 (valid when Φ_n(t, 0) = 0) are used instead; their
/// error is O(n²) relative.
///
/// The potential is shifted so that Φ(0) = 0. The law is always treated as nonlinear
/// (`is_linear` is false, even for a quadratic Φ).
///
/// # Check (`validate`)
/// Assumption (3.4) (𝒜 Lipschitz and strongly monotone) means Φ strongly convex with a Lipschitz
/// gradient. It cannot be proved for an arbitrary Φ; `validate` rejects a Φ that *visibly*
/// violates it, at a fixed deterministic sample of 196 strain rates: ε = 0 and r (cos θ I/√d +
/// sin θ E_D) for 13 angles θ ∈ [0°, 180°] (pure volumetric, pure deviatoric and mixed; E_D cycling
/// through three unit deviators) and 15 magnitudes r = 10^(k/2), k = −8, …, 6 (1e-4 to 1e3).
/// At every sample:
/// - Φ(ε), σ(ε) and the tangent are finite;
/// - the tangent, as a matrix K on the symmetric tensors (an orthonormal basis: dimension 3 in
///   2D, 6 in 3D), is symmetric: max|K − Kᵀ| ≤ 10⁻⁸ max|K|;
/// - its smallest eigenvalue is ≥ m = 10⁻⁸ λ_max > 0, λ_max the largest eigenvalue over all
///   samples (strongly monotone, and a tangent whose spread over the samples exceeds 10⁸ is taken as
///   not Lipschitz);
///
/// and Φ_n(t, 0) = 0 (Φ differentiable at ε_D = 0): |Φ_n(t, 0)| ≤ 10⁻¹⁰ λ_max · 10⁻⁴ at t = 0 and
/// the traces of the pure volumetric samples (the jump of the stress across ε_D = 0 is below 10⁻¹⁰
/// of the stress at the smallest sampled rate). Errors name `viscosity.potential`.
#[derive(Clone)]
pub struct PotentialViscosity {
    potential: Arc<dyn InvariantPotential>,
    /// Φ(0, 0), subtracted so that the law's potential vanishes at ε = 0.
    offset: f64,
}

impl std::fmt::Debug for PotentialViscosity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PotentialViscosity")
            .field("offset", &self.offset)
            .finish_non_exhaustive()
    }
}

impl PotentialViscosity {
    /// The law of the potential Φ(t, n) (not validated: call `validate`).
    pub fn new(potential: Arc<dyn InvariantPotential>) -> Self {
        let offset = potential.value(0.0, 0.0);
        Self { potential, offset }
    }

    /// The potential in the invariants.
    pub fn invariant_potential(&self) -> &Arc<dyn InvariantPotential> {
        &self.potential
    }

    /// The tangent dσ(ε) as a symmetric-tensor matrix in the basis of [`symmetric_basis`].
    fn tangent_matrix<const D: usize>(&self, strain_rate: &Tensor<D>) -> DMatrix<f64> {
        let basis = symmetric_basis::<D>();
        let columns: Vec<Tensor<D>> = basis
            .iter()
            .map(|e| <Self as Viscosity<D>>::tangent(self, strain_rate, e))
            .collect();
        DMatrix::from_fn(basis.len(), basis.len(), |a, b| basis[a].dot(&columns[b]))
    }

    fn invalid(value: f64, reason: String) -> Error {
        Error::parameter("viscosity.potential", value, reason)
    }

    fn stress_at<const D: usize>(&self, invariants: &Invariants<D>) -> Tensor<D> {
        let jet = self.potential.jet(invariants.trace, invariants.dev_norm);
        let (secant, _) = invariants.deviatoric_slopes(&jet);
        Tensor::<D>::identity() * jet.gradient[0] + invariants.deviator * secant
    }

    fn tangent_at<const D: usize>(
        &self,
        invariants: &Invariants<D>,
        direction: &Tensor<D>,
    ) -> Tensor<D> {
        let jet = self.potential.jet(invariants.trace, invariants.dev_norm);
        let (secant, curvature_gap) = invariants.deviatoric_slopes(&jet);
        let direction_trace = trace(direction);
        let direction_deviator = deviator(direction);
        let e = &invariants.unit_deviator;
        let along = e.dot(&direction_deviator);
        let [[phi_tt, phi_tn], [phi_nt, _]] = jet.hessian;
        Tensor::<D>::identity() * (phi_tt * direction_trace + phi_tn * along)
            + direction_deviator * secant
            + e * (phi_nt * direction_trace + curvature_gap * along)
    }
}

impl<const D: usize> Viscosity<D> for PotentialViscosity {
    fn stress(&self, strain_rate: &Tensor<D>) -> Tensor<D> {
        self.stress_at(&Invariants::of(strain_rate))
    }

    fn tangent(&self, strain_rate: &Tensor<D>, direction: &Tensor<D>) -> Tensor<D> {
        self.tangent_at(&Invariants::of(strain_rate), direction)
    }

    fn potential(&self, strain_rate: &Tensor<D>) -> f64 {
        let invariants = Invariants::of(strain_rate);
        self.potential.value(invariants.trace, invariants.dev_norm) - self.offset
    }

    fn is_linear(&self) -> bool {
        false
    }

    fn validate(&self) -> Result<()> {
        let describe = |rate: &Tensor<D>| {
            let invariants = Invariants::of(rate);
            if rate.norm() == 0.0 {
                return "ε = 0".to_string();
            }
            format!(
                "tr ε = {:.3e}, |ε_D| = {:.3e} (|ε| = {:.3e})",
                invariants.trace,
                invariants.dev_norm,
                rate.norm()
            )
        };
        let mut samples = vec![Tensor::<D>::zeros()];
        for direction in sampled_rate_directions::<D>() {
            samples.extend(sampled_rate_magnitudes().map(|r| direction * r));
        }
        // (λ_min, λ_max, sample) per sample, and the largest eigenvalue overall
        let mut smallest = Vec::with_capacity(samples.len());
        let mut largest = (f64::NEG_INFINITY, 0);
        for (index, rate) in samples.iter().enumerate() {
            let value = <Self as Viscosity<D>>::potential(self, rate);
            if !value.is_finite() {
                return Err(Self::invalid(
                    value,
                    format!("Φ is not finite at the strain rate with {}", describe(rate)),
                ));
            }
            let stress = <Self as Viscosity<D>>::stress(self, rate);
            if !stress.iter().all(|s| s.is_finite()) {
                return Err(Self::invalid(
                    stress.norm(),
                    format!(
                        "the stress ∂Φ/∂ε is not finite at the strain rate with {}",
                        describe(rate)
                    ),
                ));
            }
            let matrix = self.tangent_matrix::<D>(rate);
            if !matrix.iter().all(|k| k.is_finite()) {
                return Err(Self::invalid(
                    matrix.norm(),
                    format!(
                        "the tangent ∂²Φ/∂ε² is not finite at the strain rate with {}",
                        describe(rate)
                    ),
                ));
            }
            let asymmetry = (&matrix - matrix.transpose()).amax();
            if asymmetry > 1e-8 * matrix.amax() {
                return Err(Self::invalid(
                    asymmetry,
                    format!(
                        "the tangent ∂²Φ/∂ε² is not symmetric (max |K − Kᵀ| = {asymmetry:.3e}, \
                         max |K| = {:.3e}) at the strain rate with {}",
                        matrix.amax(),
                        describe(rate)
                    ),
                ));
            }
            let eigenvalues = ((&matrix + matrix.transpose()) * 0.5).symmetric_eigenvalues();
            smallest.push((eigenvalues.min(), eigenvalues.max(), index));
            if eigenvalues.max() > largest.0 {
                largest = (eigenvalues.max(), index);
            }
        }
        let (lambda_max, at_max) = largest;
        let smallest_rate = 1e-4;
        for t in std::iter::once(0.0).chain(sampled_rate_magnitudes().flat_map(|r| {
            let t = r * (D as f64).sqrt();
            [t, -t]
        })) {
            let slope = self.potential.jet(t, 0.0).gradient[1];
            if slope.is_nan() || slope.abs() > 1e-10 * lambda_max.max(0.0) * smallest_rate {
                return Err(Self::invalid(
                    slope,
                    format!(
                        "Φ_n(t, 0) = ∂Φ/∂|ε_D| at ε_D = 0 must be 0 for Φ to be differentiable \
                         (here {slope:.3e} at tr ε = {t:.3e}): the stress would jump across \
                         ε_D = 0 (e.g. a term in |ε_D| rather than |ε_D|²)"
                    ),
                ));
            }
        }
        let bound = 1e-8 * lambda_max;
        let (lambda_min, local_max, at_min) = smallest
            .iter()
            .copied()
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .unwrap_or((f64::NAN, f64::NAN, 0));
        if !(lambda_max > 0.0 && lambda_min >= bound) {
            // round-off relative to the tangent at that sample
            let round_off = 1e-12 * local_max.abs();
            let verdict = if lambda_min < -round_off {
                "Φ is not convex there (negative curvature)"
            } else if lambda_min <= round_off {
                "Φ is not strongly convex there (no curvature in some direction, up to round-off)"
            } else {
                "the eigenvalues of the tangent spread over more than 10⁸ across the samples: \
                 Φ is not visibly strongly convex with a Lipschitz gradient"
            };
            return Err(Self::invalid(
                lambda_min,
                format!(
                    "the tangent ∂²Φ/∂ε² at {} has smallest eigenvalue \
                     {lambda_min:.3e} < 10⁻⁸ × the largest eigenvalue {lambda_max:.3e} \
                     (at {}) over the sampled strain rates (|ε| from 1e-4 to 1e3): {verdict}, \
                     so 𝒜 = ∂Φ/∂ε would not be strongly monotone and Lipschitz (3.4)",
                    describe(&samples[at_min]),
                    describe(&samples[at_max])
                ),
            ));
        }
        Ok(())
    }
}

/// Damage-dependent elasticity G(ε, β) of (2.1). Assumption (3.5): Lipschitz in (ε, β).
///
/// The derivatives are not used by the scheme (G is explicit in (5.1)); they make the law usable for
/// manufactured solutions (f0 = −Div σ by the chain rule).
pub trait Elasticity<const D: usize>: Send + Sync {
    /// G(ε, β).
    fn stress(&self, strain: &Tensor<D>, damage: f64) -> Tensor<D>;
    /// ∂G/∂ε (ε, β)\[δε\].
    fn strain_derivative(
        &self,
        strain: &Tensor<D>,
        damage: f64,
        direction: &Tensor<D>,
    ) -> Tensor<D>;
    /// ∂G/∂β (ε, β).
    fn damage_derivative(&self, strain: &Tensor<D>, damage: f64) -> Tensor<D>;
    /// Checks the parameters against (3.5).
    fn validate(&self) -> Result<()>;
    /// Σ_q w_q G(ε, β_q): the stress integrated over a cell on which the strain is constant
    /// (P1 on an affine simplex) from the damage values and weights of its quadrature points.
    /// A law linear in its damage overrides it with one evaluation of G per cell.
    fn weighted_stress_sum(
        &self,
        strain: &Tensor<D>,
        damages: &[f64],
        weights: &[f64],
    ) -> Tensor<D> {
        let mut sum = Tensor::<D>::zeros();
        for (&damage, &weight) in damages.iter().zip(weights) {
            sum += self.stress(strain, damage) * weight;
        }
        sum
    }
    /// Div G(ε, β) at a point of smooth fields ε(x), β(x), by the chain rule:
    /// (Div G)_i = Σ_j (∂G/∂ε\[∂_j ε\] + ∂G/∂β ∂_j β)_ij, from ε, β, the partial derivatives
    /// `strain_derivatives[j]` = ∂_j ε and ∇β.
    ///
    /// Like the other derivatives, not used by the scheme (f0 = −Div σ of manufactured
    /// solutions). The default calls [`Elasticity::strain_derivative`] once per direction; a law
    /// with a closed form overrides it.
    fn stress_divergence(
        &self,
        strain: &Tensor<D>,
        damage: f64,
        strain_derivatives: &[Tensor<D>; D],
        damage_gradient: &SVector<f64, D>,
    ) -> SVector<f64, D> {
        let damage_slope = self.damage_derivative(strain, damage);
        let mut divergence = SVector::<f64, D>::zeros();
        for (j, derivative) in strain_derivatives.iter().enumerate() {
            divergence += (self.strain_derivative(strain, damage, derivative)
                + damage_slope * damage_gradient[j])
                .column(j);
        }
        divergence
    }
    /// [`Elasticity::stress_divergence`] at a batch of points, from the partial derivatives
    /// of the displacement field there (columns, see [`FieldJets`]), β and ∇β
    /// (`damage_gradient[j][p]` = ∂β/∂x_j): `out[i][p]` is component i at point p, for the
    /// first `out[0].len()` points. Bitwise the values point by point; one call through a
    /// trait object per batch.
    fn stress_divergence_of_jets(
        &self,
        displacement: &FieldJets<'_, D>,
        damage: &[f64],
        damage_gradient: &[&[f64]; D],
        out: &mut [&mut [f64]; D],
    ) {
        for p in 0..out[0].len() {
            let divergence = self.stress_divergence(
                &displacement.strain(p),
                damage[p],
                &displacement.strain_derivatives(p),
                &SVector::<f64, D>::from_fn(|j, _| damage_gradient[j][p]),
            );
            for (i, out) in out.iter_mut().enumerate() {
                out[p] = divergence[i];
            }
        }
    }
}

/// G(ε, β) = β̄ (2μ ε + λ tr(ε) I) with β̄ = min(max(β, 0), 1) (damage clamped to [0, 1] inside G,
/// which keeps G Lipschitz for any β).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DamagedHooke {
    /// Lamé shear modulus μ > 0.
    pub shear_modulus: f64,
    /// Lamé first parameter λ, with 2μ + dλ > 0.
    pub lame_lambda: f64,
}

impl DamagedHooke {
    fn undamaged<const D: usize>(&self, strain: &Tensor<D>) -> Tensor<D> {
        strain * (2.0 * self.shear_modulus)
            + Tensor::<D>::identity() * (self.lame_lambda * trace(strain))
    }
}

impl<const D: usize> Elasticity<D> for DamagedHooke {
    fn stress(&self, strain: &Tensor<D>, damage: f64) -> Tensor<D> {
        self.undamaged(strain) * damage.clamp(0.0, 1.0)
    }
    /// G is linear in β̄: Σ_q w_q G(ε, β_q) = (Σ_q w_q β̄_q) (2μ ε + λ tr(ε) I).
    fn weighted_stress_sum(
        &self,
        strain: &Tensor<D>,
        damages: &[f64],
        weights: &[f64],
    ) -> Tensor<D> {
        let mut weighted_damage = 0.0;
        for (&damage, &weight) in damages.iter().zip(weights) {
            weighted_damage += weight * damage.clamp(0.0, 1.0);
        }
        self.undamaged(strain) * weighted_damage
    }
    fn strain_derivative(
        &self,
        _strain: &Tensor<D>,
        damage: f64,
        direction: &Tensor<D>,
    ) -> Tensor<D> {
        self.undamaged(direction) * damage.clamp(0.0, 1.0)
    }
    /// One-sided derivative from inside [0, 1] (the clamp is inactive on the closed interval).
    fn damage_derivative(&self, strain: &Tensor<D>, damage: f64) -> Tensor<D> {
        if (0.0..=1.0).contains(&damage) {
            self.undamaged(strain)
        } else {
            Tensor::<D>::zeros()
        }
    }
    /// β̄ (2μ Σ_j ∂_j ε_ij + λ ∂_i tr ε) + ((2μ ε + λ tr(ε) I) ∇β)_i, the last term only for
    /// β ∈ [0, 1] (as [`Elasticity::damage_derivative`]).
    fn stress_divergence(
        &self,
        strain: &Tensor<D>,
        damage: f64,
        strain_derivatives: &[Tensor<D>; D],
        damage_gradient: &SVector<f64, D>,
    ) -> SVector<f64, D> {
        let elastic = isotropic_divergence(
            2.0 * self.shear_modulus,
            self.lame_lambda,
            strain_derivatives,
        ) * damage.clamp(0.0, 1.0);
        if (0.0..=1.0).contains(&damage) {
            elastic + self.undamaged(strain) * damage_gradient
        } else {
            elastic
        }
    }
    fn validate(&self) -> Result<()> {
        check_finite("elasticity.shear_modulus", self.shear_modulus)?;
        check_finite("elasticity.lame_lambda", self.lame_lambda)?;
        if self.shear_modulus <= 0.0 {
            return Err(Error::parameter(
                "elasticity.shear_modulus",
                self.shear_modulus,
                "μ must be > 0",
            ));
        }
        if 2.0 * self.shear_modulus + D as f64 * self.lame_lambda <= 0.0 {
            return Err(Error::parameter(
                "elasticity.lame_lambda",
                self.lame_lambda,
                "2μ + dλ must be > 0 (positive bulk modulus)",
            ));
        }
        Ok(())
    }
}

/// Damage-dependent Lamé moduli μ(β), λ(β) with their derivatives: the user-written part of
/// [`ModuliElasticity`]. Called with β ∈ [0, 1] only.
pub trait DamageModuli: Send + Sync {
    /// (μ(β), μ'(β)).
    fn shear_modulus(&self, damage: f64) -> (f64, f64);
    /// (λ(β), λ'(β)).
    fn lame_lambda(&self, damage: f64) -> (f64, f64);
}

/// G(ε, β) = 2μ(β̄) ε + λ(β̄) tr(ε) I with β̄ = min(max(β, 0), 1) and user moduli μ(β), λ(β)
/// ([`DamageModuli`]); [`DamagedHooke`] is the case μ(β) = μβ, λ(β) = λβ. With the clamp and
/// moduli that are C¹ on [0, 1], G is Lipschitz in ε and, for bounded ε, in β; (3.5) asks for a
/// constant uniform in ε, which a strain-weighted law cannot give (docs/model.md §2).
///
/// `damage_derivative` is the one-sided derivative from inside [0, 1] (μ'(β), λ'(β) at the ends),
/// zero outside [0, 1] where the clamp is active, as for [`DamagedHooke`].
///
/// # Check (`validate`)
/// At the 101 damages β = k/100, k = 0, …, 100: μ, μ', λ, λ' are finite, μ(β) ≥ 0 and
/// 2μ(β) + dλ(β) ≥ 0 (G(·, β) positive semidefinite), and at β = 1 (undamaged) μ(1) > 0 and
/// 2μ(1) + dλ(1) > 0 (positive definite). Errors name `elasticity.shear_modulus` or
/// `elasticity.lame_lambda`.
#[derive(Clone)]
pub struct ModuliElasticity {
    /// μ(β), λ(β).
    pub moduli: Arc<dyn DamageModuli>,
}

impl std::fmt::Debug for ModuliElasticity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ModuliElasticity").finish_non_exhaustive()
    }
}

impl ModuliElasticity {
    fn hooke<const D: usize>(shear: f64, lambda: f64, strain: &Tensor<D>) -> Tensor<D> {
        strain * (2.0 * shear) + Tensor::<D>::identity() * (lambda * trace(strain))
    }
}

impl<const D: usize> Elasticity<D> for ModuliElasticity {
    fn stress(&self, strain: &Tensor<D>, damage: f64) -> Tensor<D> {
        let beta = damage.clamp(0.0, 1.0);
        let (shear, _) = self.moduli.shear_modulus(beta);
        let (lambda, _) = self.moduli.lame_lambda(beta);
        Self::hooke(shear, lambda, strain)
    }
    fn strain_derivative(
        &self,
        _strain: &Tensor<D>,
        damage: f64,
        direction: &Tensor<D>,
    ) -> Tensor<D> {
        <Self as Elasticity<D>>::stress(self, direction, damage)
    }
    /// One-sided derivative from inside [0, 1] (the clamp is inactive on the closed interval).
    fn damage_derivative(&self, strain: &Tensor<D>, damage: f64) -> Tensor<D> {
        if (0.0..=1.0).contains(&damage) {
            let (_, shear_slope) = self.moduli.shear_modulus(damage);
            let (_, lambda_slope) = self.moduli.lame_lambda(damage);
            Self::hooke(shear_slope, lambda_slope, strain)
        } else {
            Tensor::<D>::zeros()
        }
    }
    /// (2μ(β̄) Σ_j ∂_j ε_ij + λ(β̄) ∂_i tr ε) + ((2μ'(β) ε + λ'(β) tr(ε) I) ∇β)_i, the last term
    /// only for β ∈ [0, 1] (as [`Elasticity::damage_derivative`]): the moduli once per point.
    fn stress_divergence(
        &self,
        strain: &Tensor<D>,
        damage: f64,
        strain_derivatives: &[Tensor<D>; D],
        damage_gradient: &SVector<f64, D>,
    ) -> SVector<f64, D> {
        // Inside [0, 1] β̄ = β: one evaluation of each modulus gives value and slope.
        let (shear, shear_slope) = self.moduli.shear_modulus(damage.clamp(0.0, 1.0));
        let (lambda, lambda_slope) = self.moduli.lame_lambda(damage.clamp(0.0, 1.0));
        let elastic = isotropic_divergence(2.0 * shear, lambda, strain_derivatives);
        if (0.0..=1.0).contains(&damage) {
            elastic + Self::hooke(shear_slope, lambda_slope, strain) * damage_gradient
        } else {
            elastic
        }
    }
    fn validate(&self) -> Result<()> {
        const SHEAR: &str = "elasticity.shear_modulus";
        const LAMBDA: &str = "elasticity.lame_lambda";
        let d = D as f64;
        for k in 0..=100 {
            let beta = f64::from(k) / 100.0;
            let (shear, shear_slope) = self.moduli.shear_modulus(beta);
            let (lambda, lambda_slope) = self.moduli.lame_lambda(beta);
            for (name, what, value) in [
                (SHEAR, "μ", shear),
                (SHEAR, "μ'", shear_slope),
                (LAMBDA, "λ", lambda),
                (LAMBDA, "λ'", lambda_slope),
            ] {
                if !value.is_finite() {
                    return Err(Error::parameter(
                        name,
                        value,
                        format!("{what}(β) is not finite at β = {beta}"),
                    ));
                }
            }
            if shear < 0.0 {
                return Err(Error::parameter(
                    SHEAR,
                    shear,
                    format!("μ(β) must be ≥ 0 on [0, 1] (G positive semidefinite); μ({beta}) < 0"),
                ));
            }
            let bulk = 2.0 * shear + d * lambda;
            if bulk < 0.0 {
                return Err(Error::parameter(
                    LAMBDA,
                    lambda,
                    format!(
                        "2μ(β) + dλ(β) must be ≥ 0 on [0, 1] (G positive semidefinite); at \
                         β = {beta}: 2μ + dλ = {bulk:.3e} with μ = {shear}"
                    ),
                ));
            }
            if beta == 1.0 && shear <= 0.0 {
                return Err(Error::parameter(
                    SHEAR,
                    shear,
                    "μ(1) must be > 0 (the undamaged material is elastic)",
                ));
            }
            if beta == 1.0 && bulk <= 0.0 {
                return Err(Error::parameter(
                    LAMBDA,
                    lambda,
                    format!(
                        "2μ(1) + dλ(1) must be > 0 (positive bulk modulus of the undamaged \
                         material); here μ(1) = {shear}"
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// Damage source φ(ε, β) of (2.2). Assumption (3.6): Lipschitz in (ε, β).
pub trait DamageSource<const D: usize>: Send + Sync {
    /// φ(ε, β).
    fn source(&self, strain: &Tensor<D>, damage: f64) -> f64;
    /// φ at a batch of points: `out[p] = φ(strains[p], damages[p])` (all slices of one
    /// length). The load assembly calls this once per chunk of cells; the default calls
    /// [`DamageSource::source`] point by point, a law given by an interpreted expression
    /// evaluates it over the whole batch.
    fn source_batch(&self, strains: &[Tensor<D>], damages: &[f64], out: &mut [f64]) {
        for ((strain, &damage), value) in strains.iter().zip(damages).zip(out) {
            *value = self.source(strain, damage);
        }
    }
    /// φ at the points of cells on each of which the strain is constant (P1 on affine
    /// simplices, where the load assembly (5.2) has one ε(u_{n−1}) per cell): with `m` =
    /// `damages.len() / cell_strains.len()` points per cell, in cell order,
    /// `out[p] = φ(cell_strains[p / m], damages[p])`. `damages` and `out` have one length, a
    /// multiple of the number of cells. The default repeats each strain for the points of its
    /// cell and calls [`DamageSource::source_batch`]; a law that reduces ε to invariants
    /// overrides it to compute them once per cell, with bitwise the same values.
    fn source_cells(&self, cell_strains: &[Tensor<D>], damages: &[f64], out: &mut [f64]) {
        let per_cell = points_per_cell(cell_strains.len(), damages.len());
        let strains: Vec<Tensor<D>> = cell_strains
            .iter()
            .flat_map(|strain| std::iter::repeat_n(*strain, per_cell))
            .collect();
        self.source_batch(&strains, damages, out);
    }
    /// Checks the parameters against (3.6).
    fn validate(&self) -> Result<()>;
}

/// The number of points per cell of [`DamageSource::source_cells`]: `points / cells`, which
/// must divide exactly (0 without cells).
pub fn points_per_cell(cells: usize, points: usize) -> usize {
    let per_cell = points.checked_div(cells).unwrap_or(0);
    debug_assert_eq!(
        per_cell * cells,
        points,
        "points not a multiple of the cells"
    );
    per_cell
}

/// Truncated Frémond–Nedjar source (paper §2 and the remark after (3.7)):
///
/// φ(ε, β) = λ_D (1 − β̂)/β̂ − ½ min(ε·ε, E_max) + λ_w,  β̂ = min(max(β, β_*), 1).
///
/// The physical source φ_Fr = λ_D (1 − β)/β − ½ ε·ε + λ_w is not Lipschitz (it blows up as β → 0
/// and grows quadratically in ε). The truncation replaces β by β̂ ≥ β_* > 0 (Lipschitz constant
/// λ_D/β_*² in β) and caps the strain energy density ε·ε at E_max (Lipschitz constant √E_max in ε),
/// so (3.6) holds; it coincides with φ_Fr wherever β ≥ β_* and ε·ε ≤ E_max.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruncatedFremond {
    /// λ_D ≥ 0.
    pub lambda_d: f64,
    /// λ_w (the energy threshold term; any sign).
    pub lambda_w: f64,
    /// β_* ∈ (0, 1].
    pub damage_floor: f64,
    /// E_max > 0: cap of ε·ε.
    pub strain_energy_cap: f64,
}

impl<const D: usize> DamageSource<D> for TruncatedFremond {
    fn source(&self, strain: &Tensor<D>, damage: f64) -> f64 {
        let beta_hat = damage.clamp(self.damage_floor, 1.0);
        self.lambda_d * (1.0 - beta_hat) / beta_hat
            - 0.5 * strain.norm_squared().min(self.strain_energy_cap)
            + self.lambda_w
    }
    /// The strain energy term once per cell.
    fn source_cells(&self, cell_strains: &[Tensor<D>], damages: &[f64], out: &mut [f64]) {
        let per_cell = points_per_cell(cell_strains.len(), damages.len());
        if per_cell == 0 {
            return;
        }
        for (strain, (damages, out)) in cell_strains
            .iter()
            .zip(damages.chunks(per_cell).zip(out.chunks_mut(per_cell)))
        {
            let energy = 0.5 * strain.norm_squared().min(self.strain_energy_cap);
            for (value, &damage) in out.iter_mut().zip(damages) {
                let beta_hat = damage.clamp(self.damage_floor, 1.0);
                *value = self.lambda_d * (1.0 - beta_hat) / beta_hat - energy + self.lambda_w;
            }
        }
    }
    fn validate(&self) -> Result<()> {
        check_finite("damage_source.lambda_d", self.lambda_d)?;
        check_finite("damage_source.lambda_w", self.lambda_w)?;
        check_finite("damage_source.damage_floor", self.damage_floor)?;
        check_finite("damage_source.strain_energy_cap", self.strain_energy_cap)?;
        if self.lambda_d < 0.0 {
            return Err(Error::parameter(
                "damage_source.lambda_d",
                self.lambda_d,
                "λ_D must be ≥ 0",
            ));
        }
        if !(self.damage_floor > 0.0 && self.damage_floor <= 1.0) {
            return Err(Error::parameter(
                "damage_source.damage_floor",
                self.damage_floor,
                "β_* must lie in (0, 1] for φ to be Lipschitz (3.6)",
            ));
        }
        if self.strain_energy_cap <= 0.0 {
            return Err(Error::parameter(
                "damage_source.strain_energy_cap",
                self.strain_energy_cap,
                "E_max must be > 0",
            ));
        }
        Ok(())
    }
}

/// A user damage source given by a closure `(strain, damage) -> φ`. The user is responsible for
/// (3.6); `validate` only checks that φ is finite at ε = 0 for β ∈ {0, ½, 1}.
pub struct DamageSourceFn<F>(pub F);

impl<const D: usize, F> DamageSource<D> for DamageSourceFn<F>
where
    F: Fn(&Tensor<D>, f64) -> f64 + Send + Sync,
{
    fn source(&self, strain: &Tensor<D>, damage: f64) -> f64 {
        (self.0)(strain, damage)
    }
    fn validate(&self) -> Result<()> {
        for beta in [0.0, 0.5, 1.0] {
            let value = (self.0)(&Tensor::<D>::zeros(), beta);
            if !value.is_finite() {
                return Err(Error::parameter(
                    "damage_source(0, β)",
                    beta,
                    "user damage source is not finite",
                ));
            }
        }
        Ok(())
    }
}

/// Contact law on Γ3: normal compliance p_ν (2.7) and friction bound p_τ (2.8).
/// Assumption (3.7): both Lipschitz, zero for r ≤ 0 (r = u_ν − g is the penetration).
pub trait ContactLaw: Send + Sync {
    /// p_ν(r).
    fn normal_pressure(&self, penetration: f64) -> f64;
    /// The normal compliance energy P(r) = ∫₀^r p_ν(s) ds (convex, as p_ν is nondecreasing):
    /// the potential of the normal compliance when it is taken implicitly in the velocity step.
    fn normal_energy(&self, penetration: f64) -> f64;
    /// A derivative of p_ν at r (an element of Clarke's generalized derivative where p_ν has a
    /// kink): the tangent of the implicit normal compliance in Newton's method.
    fn normal_stiffness(&self, penetration: f64) -> f64;
    /// p_τ(r).
    fn friction_bound(&self, penetration: f64) -> f64;
    /// Checks the parameters against (3.7).
    fn validate(&self) -> Result<()>;
}

/// p_ν(r) = c_ν r₊ (2.10) with the Coulomb bound p_τ = μ p_ν (2.11), or, when δ > 0, the
/// wear-modified bound p_τ = μ p_ν (1 − δ p_ν)₊ (2.12).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalComplianceCoulomb {
    /// Surface stiffness c_ν > 0.
    pub stiffness: f64,
    /// Friction coefficient μ ≥ 0.
    pub friction: f64,
    /// Wear/hardness constant δ ≥ 0 (δ = 0 gives (2.11)).
    pub wear: f64,
}

impl ContactLaw for NormalComplianceCoulomb {
    fn normal_pressure(&self, penetration: f64) -> f64 {
        self.stiffness * penetration.max(0.0)
    }
    /// P(r) = c_ν r₊²/2.
    fn normal_energy(&self, penetration: f64) -> f64 {
        0.5 * self.stiffness * penetration.max(0.0).powi(2)
    }
    /// c_ν for r > 0, 0 for r ≤ 0.
    fn normal_stiffness(&self, penetration: f64) -> f64 {
        if penetration > 0.0 {
            self.stiffness
        } else {
            0.0
        }
    }
    fn friction_bound(&self, penetration: f64) -> f64 {
        let pressure = self.normal_pressure(penetration);
        self.friction * pressure * (1.0 - self.wear * pressure).max(0.0)
    }
    fn validate(&self) -> Result<()> {
        check_finite("contact.stiffness", self.stiffness)?;
        check_finite("contact.friction", self.friction)?;
        check_finite("contact.wear", self.wear)?;
        if self.stiffness <= 0.0 {
            return Err(Error::parameter(
                "contact.stiffness",
                self.stiffness,
                "c_ν must be > 0 (2.10)",
            ));
        }
        if self.friction < 0.0 {
            return Err(Error::parameter(
                "contact.friction",
                self.friction,
                "μ must be ≥ 0",
            ));
        }
        if self.wear < 0.0 {
            return Err(Error::parameter(
                "contact.wear",
                self.wear,
                "δ must be ≥ 0 (2.12)",
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_tensor() -> Tensor<3> {
        let a = Tensor::<3>::new(0.3, -0.2, 0.5, 0.1, 0.7, -0.4, 0.2, 0.6, -0.1);
        (a + a.transpose()) * 0.5
    }

    /// Φ = η n² + (η/d + ζ/2) t² + η₁ ε₀² (√(1 + n²/ε₀²) − 1): the potential of
    /// [`SaturatingViscosity`] in the invariants (|ε|² = n² + t²/d), derivatives by hand.
    struct SaturatingInvariants {
        law: SaturatingViscosity,
        dim: f64,
    }

    impl InvariantPotential for SaturatingInvariants {
        fn value(&self, t: f64, n: f64) -> f64 {
            self.jet(t, n).value
        }
        fn jet(&self, t: f64, n: f64) -> InvariantJet {
            let (eta, zeta) = (self.law.linear.shear, self.law.linear.bulk);
            let (extra, s2) = (self.law.extra_shear, self.law.rate_scale.powi(2));
            let volumetric = eta / self.dim + zeta / 2.0;
            let w = (1.0 + n * n / s2).sqrt();
            InvariantJet {
                value: eta * n * n + volumetric * t * t + extra * s2 * (w - 1.0),
                gradient: [2.0 * volumetric * t, 2.0 * eta * n + extra * n / w],
                hessian: [
                    [2.0 * volumetric, 0.0],
                    [0.0, 2.0 * eta + extra / (w * w * w)],
                ],
            }
        }
    }

    /// Φ = a n² + b t² + c s² (√(1 + (n² + t²)/s²) − 1): convex, couples t and n; tangent ≥
    /// min(2a, 2bd).
    struct Coupled {
        a: f64,
        b: f64,
        c: f64,
        s: f64,
    }

    impl InvariantPotential for Coupled {
        fn value(&self, t: f64, n: f64) -> f64 {
            self.jet(t, n).value
        }
        fn jet(&self, t: f64, n: f64) -> InvariantJet {
            let (a, b, c, s2) = (self.a, self.b, self.c, self.s * self.s);
            let w = (1.0 + (n * n + t * t) / s2).sqrt();
            let w3 = w * w * w;
            let cross = -c * t * n / (s2 * w3);
            InvariantJet {
                value: a * n * n + b * t * t + c * s2 * (w - 1.0),
                gradient: [2.0 * b * t + c * t / w, 2.0 * a * n + c * n / w],
                hessian: [
                    [2.0 * b + c / w - c * t * t / (s2 * w3), cross],
                    [cross, 2.0 * a + c / w - c * n * n / (s2 * w3)],
                ],
            }
        }
    }

    fn coupled() -> PotentialViscosity {
        PotentialViscosity::new(Arc::new(Coupled {
            a: 0.8,
            b: 0.3,
            c: 1.5,
            s: 0.2,
        }))
    }

    /// Φ = a n² + b t² + c n + e n⁴ + f exp(t) (with the derivatives of each term).
    #[derive(Clone, Copy, Default)]
    struct Polynomial {
        a: f64,
        b: f64,
        c: f64,
        e: f64,
        f: f64,
    }

    impl InvariantPotential for Polynomial {
        fn value(&self, t: f64, n: f64) -> f64 {
            self.jet(t, n).value
        }
        fn jet(&self, t: f64, n: f64) -> InvariantJet {
            let Polynomial { a, b, c, e, f } = *self;
            let exp = if f == 0.0 { 0.0 } else { f * t.exp() };
            InvariantJet {
                value: a * n * n + b * t * t + c * n + e * n.powi(4) + exp,
                gradient: [2.0 * b * t + exp, 2.0 * a * n + c + 4.0 * e * n.powi(3)],
                hessian: [[2.0 * b + exp, 0.0], [0.0, 2.0 * a + 12.0 * e * n * n]],
            }
        }
    }

    fn saturating_pair<const D: usize>() -> (SaturatingViscosity, PotentialViscosity) {
        let law = SaturatingViscosity {
            linear: LinearViscosity {
                shear: 1.0,
                bulk: 0.5,
            },
            extra_shear: 0.5,
            rate_scale: 0.2,
        };
        let potential =
            PotentialViscosity::new(Arc::new(SaturatingInvariants { law, dim: D as f64 }));
        (law, potential)
    }

    /// Strain rates with ε_D = 0, tiny and exactly zero |ε_D| (with and without a trace), and
    /// generic ones.
    fn strain_rates<const D: usize>() -> Vec<Tensor<D>> {
        let generic = Tensor::<D>::from_fn(|i, j| {
            let (a, b) = (i.min(j) as f64, i.max(j) as f64);
            0.4 - 0.3 * a + 0.25 * b + 0.1 * a * b
        });
        let unit_deviator = deviator(&generic) / deviator(&generic).norm();
        let identity = Tensor::<D>::identity();
        let mut rates = vec![
            Tensor::<D>::zeros(),
            identity * 0.7,
            identity * -2.0,
            generic,
            generic * 30.0,
            unit_deviator * 0.05,
        ];
        for n in [1e-6, 1e-9, 1e-12, 1e-15] {
            rates.push(unit_deviator * n);
            rates.push(identity * 0.6 + unit_deviator * n);
        }
        rates
    }

    fn directions<const D: usize>() -> Vec<Tensor<D>> {
        let mut directions = symmetric_basis::<D>();
        directions.push(Tensor::<D>::from_fn(|i, j| {
            0.2 + 0.3 * (i + j) as f64 - 0.1 * (i * j) as f64
        }));
        directions
    }

    fn assert_close<const D: usize>(what: &str, a: &Tensor<D>, b: &Tensor<D>, tolerance: f64) {
        assert!(
            (a - b).norm() <= tolerance * b.norm(),
            "{what}: {a} vs {b} (relative difference {:e})",
            (a - b).norm() / b.norm()
        );
    }

    fn matches_saturating<const D: usize>() {
        let (saturating, potential) = saturating_pair::<D>();
        for rate in strain_rates::<D>() {
            let at = format!("D = {D}, ε = {rate}");
            assert_close(
                &format!("stress {at}"),
                &Viscosity::<D>::stress(&potential, &rate),
                &Viscosity::<D>::stress(&saturating, &rate),
                1e-12,
            );
            for direction in directions::<D>() {
                assert_close(
                    &format!("tangent {at}"),
                    &Viscosity::<D>::tangent(&potential, &rate, &direction),
                    &Viscosity::<D>::tangent(&saturating, &rate, &direction),
                    1e-12,
                );
            }
            let (ours, theirs) = (
                Viscosity::<D>::potential(&potential, &rate),
                Viscosity::<D>::potential(&saturating, &rate),
            );
            assert!(
                (ours - theirs).abs() <= 1e-12 * theirs.abs(),
                "potential {at}: {ours} vs {theirs}"
            );
        }
    }

    #[test]
    fn potential_viscosity_matches_saturating_law_in_2d_and_3d_also_at_zero_deviator() {
        matches_saturating::<2>();
        matches_saturating::<3>();
    }

    fn tangent_and_stress_match_finite_differences<const D: usize>() {
        let law = coupled();
        for rate in strain_rates::<D>() {
            let h = 1e-6 * rate.norm().max(1.0);
            for direction in directions::<D>() {
                let fd = (Viscosity::<D>::stress(&law, &(rate + direction * h))
                    - Viscosity::<D>::stress(&law, &(rate - direction * h)))
                    / (2.0 * h);
                let exact = Viscosity::<D>::tangent(&law, &rate, &direction);
                // the stress is C¹ but only Lipschitz-differentiable at ε_D = 0 in the direction
                // of δ_D: central differences are exact up to O(h²) away from it, O(h) near it
                assert!(
                    (fd - exact).norm() <= 1e-6 * exact.norm().max(1.0),
                    "D = {D}, ε = {rate}: tangent {exact} vs finite differences {fd}"
                );
                let fd = (Viscosity::<D>::potential(&law, &(rate + direction * h))
                    - Viscosity::<D>::potential(&law, &(rate - direction * h)))
                    / (2.0 * h);
                let exact = Viscosity::<D>::stress(&law, &rate).dot(&direction);
                assert!(
                    (fd - exact).abs() <= 1e-7 * exact.abs().max(1.0),
                    "D = {D}, ε = {rate}: σ:δ = {exact} vs finite differences of Φ {fd}"
                );
            }
        }
    }

    #[test]
    fn potential_viscosity_tangent_and_stress_match_finite_differences() {
        tangent_and_stress_match_finite_differences::<2>();
        tangent_and_stress_match_finite_differences::<3>();
    }

    #[test]
    fn potential_viscosity_is_continuous_across_the_limit_form_threshold() {
        // n/|ε| just below and just above SMALL_DEVIATOR: limit form and chain rule agree up to
        // the change of the t–n coupling terms, O(n) ≈ 1e-11 relative between the two points
        let law = coupled();
        let identity = Tensor::<3>::identity();
        let unit = deviator(&sample_tensor()) / deviator(&sample_tensor()).norm();
        let scale = (identity * 0.5).norm();
        let below = identity * 0.5 + unit * (0.99 * SMALL_DEVIATOR * scale);
        let above = identity * 0.5 + unit * (1.01 * SMALL_DEVIATOR * scale);
        assert!(Invariants::of(&below).near_axis && !Invariants::of(&above).near_axis);
        // at the same point, the limit form equals the chain rule to round-off
        let limit = Invariants::of(&below);
        let chain_rule = Invariants {
            near_axis: false,
            ..Invariants::of(&below)
        };
        assert_close(
            "stress: limit form vs chain rule",
            &law.stress_at(&limit),
            &law.stress_at(&chain_rule),
            1e-15,
        );
        for direction in directions::<3>() {
            assert_close(
                "tangent: limit form vs chain rule",
                &law.tangent_at(&limit, &direction),
                &law.tangent_at(&chain_rule, &direction),
                1e-15,
            );
        }
        for direction in directions::<3>() {
            assert_close(
                "tangent across the threshold",
                &Viscosity::<3>::tangent(&law, &below, &direction),
                &Viscosity::<3>::tangent(&law, &above, &direction),
                1e-10,
            );
        }
        assert_close(
            "stress across the threshold",
            &Viscosity::<3>::stress(&law, &below),
            &Viscosity::<3>::stress(&law, &above),
            1e-10,
        );
    }

    #[test]
    fn potential_viscosity_shifts_the_potential_to_vanish_at_zero() {
        let shifted = PotentialViscosity::new(Arc::new(Polynomial {
            a: 1.0,
            b: 1.0,
            f: 0.0,
            ..Polynomial::default()
        }));
        let offset = PotentialViscosity::new(Arc::new(Coupled {
            a: 1.0,
            b: 1.0,
            c: 0.0,
            s: 1.0,
        }));
        assert_eq!(
            Viscosity::<2>::potential(&shifted, &Tensor::<2>::zeros()),
            0.0
        );
        assert_eq!(
            Viscosity::<2>::potential(&offset, &Tensor::<2>::zeros()),
            0.0
        );
        let exp = PotentialViscosity::new(Arc::new(Polynomial {
            a: 1.0,
            b: 1.0,
            f: 1e-3,
            ..Polynomial::default()
        }));
        assert_eq!(Viscosity::<2>::potential(&exp, &Tensor::<2>::zeros()), 0.0);
        assert!(!Viscosity::<2>::is_linear(&exp));
    }

    #[test]
    fn potential_viscosity_check_accepts_convex_potentials_with_lipschitz_gradient() {
        let (_, saturating) = saturating_pair::<2>();
        Viscosity::<2>::validate(&saturating).unwrap();
        let (_, saturating) = saturating_pair::<3>();
        Viscosity::<3>::validate(&saturating).unwrap();
        Viscosity::<2>::validate(&coupled()).unwrap();
        Viscosity::<3>::validate(&coupled()).unwrap();
        // quartic growth stays within the 10⁸ spread up to |ε| = 1e3: accepted
        let quartic = Polynomial {
            a: 1.0,
            b: 1.0,
            e: 1.0,
            ..Polynomial::default()
        };
        Viscosity::<3>::validate(&PotentialViscosity::new(Arc::new(quartic))).unwrap();
        assert_eq!(sampled_rate_directions::<3>().len() * 15 + 1, 196);
    }

    fn rejection<const D: usize>(potential: Polynomial) -> String {
        match Viscosity::<D>::validate(&PotentialViscosity::new(Arc::new(potential))) {
            Ok(()) => panic!("accepted"),
            Err(error) => {
                let message = error.to_string();
                assert!(message.contains("`viscosity.potential`"), "{message}");
                message
            }
        }
    }

    #[test]
    fn potential_viscosity_check_rejects_potentials_that_violate_3_4_naming_the_key() {
        let base = Polynomial {
            a: 1.0,
            b: 1.0,
            ..Polynomial::default()
        };
        // concave in the deviator
        let message = rejection::<2>(Polynomial { a: -1.0, ..base });
        assert!(message.contains("not convex"), "{message}");
        // no deviatoric stiffness (tr ε² only)
        let message = rejection::<3>(Polynomial { a: 0.0, ..base });
        assert!(message.contains("not strongly convex"), "{message}");
        // no volumetric stiffness
        let message = rejection::<2>(Polynomial { b: 0.0, ..base });
        assert!(message.contains("not strongly convex"), "{message}");
        // a term in |ε_D|: not differentiable at ε_D = 0
        let message = rejection::<2>(Polynomial { c: 1.0, ..base });
        assert!(message.contains("Φ_n(t, 0)"), "{message}");
        let message = rejection::<3>(Polynomial { c: 1e-9, ..base });
        assert!(message.contains("Φ_n(t, 0)"), "{message}");
        // loses convexity at large rates
        let message = rejection::<3>(Polynomial { e: -0.9, ..base });
        assert!(message.contains("not convex"), "{message}");
        // grows too fast: exp(tr ε) overflows at tr ε = √3 · 1e3
        let message = rejection::<3>(Polynomial { f: 1.0, ..base });
        assert!(message.contains("not finite"), "{message}");
    }

    #[test]
    fn potential_viscosity_check_rejects_a_tangent_spread_over_more_than_1e8() {
        // Φ = n² + t² + n⁶-like growth: modeled by a steep quartic, 12e n² ≈ 1.2e15 at n = 1e3
        let message = rejection::<2>(Polynomial {
            a: 1.0,
            b: 1.0,
            e: 1e9,
            ..Polynomial::default()
        });
        assert!(message.contains("spread over more than 10⁸"), "{message}");
    }

    /// A law with the trait's default methods (`weighted_stress_sum`, `stress_divergence`):
    /// the reference of the closed forms that laws override them with.
    struct TraitDefaults<L>(L);

    impl<L: Elasticity<3>> Elasticity<3> for TraitDefaults<L> {
        fn stress(&self, strain: &Tensor<3>, damage: f64) -> Tensor<3> {
            self.0.stress(strain, damage)
        }
        fn strain_derivative(
            &self,
            strain: &Tensor<3>,
            damage: f64,
            direction: &Tensor<3>,
        ) -> Tensor<3> {
            self.0.strain_derivative(strain, damage, direction)
        }
        fn damage_derivative(&self, strain: &Tensor<3>, damage: f64) -> Tensor<3> {
            self.0.damage_derivative(strain, damage)
        }
        fn validate(&self) -> Result<()> {
            self.0.validate()
        }
    }

    impl<L: Viscosity<3>> Viscosity<3> for TraitDefaults<L> {
        fn stress(&self, strain_rate: &Tensor<3>) -> Tensor<3> {
            self.0.stress(strain_rate)
        }
        fn tangent(&self, strain_rate: &Tensor<3>, direction: &Tensor<3>) -> Tensor<3> {
            self.0.tangent(strain_rate, direction)
        }
        fn potential(&self, strain_rate: &Tensor<3>) -> f64 {
            self.0.potential(strain_rate)
        }
        fn is_linear(&self) -> bool {
            self.0.is_linear()
        }
        fn validate(&self) -> Result<()> {
            self.0.validate()
        }
    }

    /// A symmetric tensor from 9 entries.
    fn symmetric_from(entries: &[f64]) -> Tensor<3> {
        let m = Tensor::<3>::from_column_slice(entries);
        (m + m.transpose()) * 0.5
    }

    proptest::proptest! {
        /// The closed-form divergences (one call per point) against the trait's chain rule
        /// through `tangent`, `strain_derivative` and `damage_derivative` (D calls each).
        #[test]
        fn closed_form_stress_divergences_equal_the_chain_rule(
            entries in proptest::collection::vec(-1.0f64..1.0, 39),
            damage in -0.5f64..1.5,
        ) {
            let strain = symmetric_from(&entries[..9]);
            let derivatives: [Tensor<3>; 3] =
                std::array::from_fn(|j| symmetric_from(&entries[9 * (j + 1)..9 * (j + 2)]));
            let damage_gradient = SVector::<f64, 3>::from_column_slice(&entries[36..39]);
            // the sums of the chain rule, term by term: a few roundings of this size apart
            let size = 10.0 * (1.0 + strain.norm())
                * (derivatives.iter().map(|d| d.norm()).sum::<f64>() + damage_gradient.norm());
            let close = |a: SVector<f64, 3>, b: SVector<f64, 3>| (a - b).norm() <= 1e-14 * size;
            let viscosity = LinearViscosity { shear: 0.7, bulk: -0.2 };
            let (ours, chain) = (
                viscosity.stress_divergence(&strain, &derivatives),
                TraitDefaults(viscosity).stress_divergence(&strain, &derivatives),
            );
            proptest::prop_assert!(close(ours, chain), "viscosity: {} vs {}", ours, chain);
            let hooke = DamagedHooke { shear_modulus: 1.3, lame_lambda: -0.4 };
            let moduli = || ModuliElasticity {
                moduli: Arc::new(PowerModuli { shear: 2.0, lambda: -0.5, lambda_shift: 0.1 }),
            };
            let (ours, chain) = (
                hooke.stress_divergence(&strain, damage, &derivatives, &damage_gradient),
                TraitDefaults(hooke).stress_divergence(&strain, damage, &derivatives,
                    &damage_gradient),
            );
            proptest::prop_assert!(close(ours, chain), "damaged Hooke: {} vs {}", ours, chain);
            let (ours, chain) = (
                moduli().stress_divergence(&strain, damage, &derivatives, &damage_gradient),
                TraitDefaults(moduli()).stress_divergence(&strain, damage, &derivatives,
                    &damage_gradient),
            );
            proptest::prop_assert!(close(ours, chain), "moduli: {} vs {}", ours, chain);
        }
    }

    proptest::proptest! {
        /// The batch divergences from the columns of the fields' derivatives (one call
        /// through the trait object per batch) are bitwise the point-by-point divergences of
        /// the strain jets built from the same numbers, for the closed forms and the trait's
        /// chain rule. Point p holds 39 numbers: ∇w (column-major), ∂_j ∇w for j < 3 (the
        /// columns `second[j]`), ∇β; the columns need not be symmetric in (j, k).
        #[test]
        fn stress_divergences_of_jets_are_bitwise_the_pointwise_divergences(
            entries in proptest::collection::vec(-1.0f64..1.0, 39 * 4),
            damages in proptest::collection::vec(-0.5f64..1.5, 4),
            count in 0usize..5,
        ) {
            let at = |p: usize, offset: usize| entries[39 * p + offset];
            let column = |offset: usize| -> Vec<f64> { (0..count).map(|p| at(p, offset)).collect() };
            let gradient: Vec<Vec<Vec<f64>>> =
                (0..3).map(|i| (0..3).map(|k| column(i + 3 * k)).collect()).collect();
            let second: Vec<Vec<Vec<Vec<f64>>>> = (0..3)
                .map(|j| {
                    (0..3)
                        .map(|i| (0..3).map(|k| column(9 * (j + 1) + i + 3 * k)).collect())
                        .collect()
                })
                .collect();
            let damage_gradient: Vec<Vec<f64>> = (0..3).map(|j| column(36 + j)).collect();
            let jets = FieldJets::<3> {
                gradient: std::array::from_fn(|i| std::array::from_fn(|k| &gradient[i][k][..])),
                second: std::array::from_fn(|j| {
                    std::array::from_fn(|i| std::array::from_fn(|k| &second[j][i][k][..]))
                }),
            };
            let damage_gradient: [&[f64]; 3] = std::array::from_fn(|j| &damage_gradient[j][..]);
            // The jets of point p built directly from its numbers.
            let point = |p: usize| {
                let numbers = &entries[39 * p..39 * (p + 1)];
                let strain = symmetric_from(&numbers[..9]);
                let derivatives: [Tensor<3>; 3] =
                    std::array::from_fn(|j| symmetric_from(&numbers[9 * (j + 1)..9 * (j + 2)]));
                (strain, derivatives, SVector::<f64, 3>::from_column_slice(&numbers[36..39]))
            };
            let bits = |columns: &[Vec<f64>; 3]| -> Vec<u64> {
                (0..count).flat_map(|p| (0..3).map(move |i| columns[i][p].to_bits())).collect()
            };
            let pointwise_bits = |values: Vec<SVector<f64, 3>>| -> Vec<u64> {
                values.iter().flat_map(|v| v.iter().map(|x| x.to_bits())).collect()
            };
            let viscosity = LinearViscosity { shear: 0.7, bulk: -0.2 };
            let saturating = SaturatingViscosity {
                linear: viscosity,
                extra_shear: 0.5,
                rate_scale: 0.3,
            };
            let viscosities: [&dyn Viscosity<3>; 3] =
                [&viscosity, &saturating, &TraitDefaults(viscosity)];
            for law in viscosities {
                let mut columns: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; count]);
                law.stress_divergence_of_jets(&jets, &mut columns.each_mut().map(|c| &mut c[..]));
                let pointwise = (0..count)
                    .map(|p| {
                        let (strain, derivatives, _) = point(p);
                        law.stress_divergence(&strain, &derivatives)
                    })
                    .collect();
                proptest::prop_assert_eq!(bits(&columns), pointwise_bits(pointwise));
            }
            let hooke = DamagedHooke { shear_modulus: 1.3, lame_lambda: -0.4 };
            let moduli = ModuliElasticity {
                moduli: Arc::new(PowerModuli { shear: 2.0, lambda: -0.5, lambda_shift: 0.1 }),
            };
            let elasticities: [&dyn Elasticity<3>; 3] = [&hooke, &moduli, &TraitDefaults(hooke)];
            for law in elasticities {
                let mut columns: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; count]);
                law.stress_divergence_of_jets(
                    &jets,
                    &damages[..count],
                    &damage_gradient,
                    &mut columns.each_mut().map(|c| &mut c[..]),
                );
                let pointwise = (0..count)
                    .map(|p| {
                        let (strain, derivatives, gradient) = point(p);
                        law.stress_divergence(&strain, damages[p], &derivatives, &gradient)
                    })
                    .collect();
                proptest::prop_assert_eq!(bits(&columns), pointwise_bits(pointwise));
            }
        }
    }

    proptest::proptest! {
        /// One strain per cell (the P1 load path): the Frémond source with its strain energy
        /// once per cell and the trait's default (repeated strains through `source`) give
        /// bitwise the point-by-point values, with β on both sides of the floor and of 1 and
        /// strain energies on both sides of the cap.
        #[test]
        fn source_cells_is_bitwise_the_pointwise_source(
            entries in proptest::collection::vec(-3.0f64..3.0, 9 * 7),
            damages in proptest::collection::vec(-0.5f64..1.5, 7 * 5),
            per_cell in 1usize..6,
        ) {
            let strains: Vec<Tensor<3>> = entries.chunks(9).map(symmetric_from).collect();
            let point_damages = &damages[..strains.len() * per_cell];
            let fremond = TruncatedFremond {
                lambda_d: 0.3,
                lambda_w: -0.05,
                damage_floor: 0.1,
                strain_energy_cap: 4.0,
            };
            let closure = DamageSourceFn(|strain: &Tensor<3>, damage: f64| {
                damage * damage - strain.trace() * strain.norm()
            });
            let laws: [&dyn DamageSource<3>; 2] = [&fremond, &closure];
            for law in laws {
                let mut values = vec![f64::NAN; point_damages.len()];
                law.source_cells(&strains, point_damages, &mut values);
                for (p, value) in values.iter().enumerate() {
                    let pointwise = law.source(&strains[p / per_cell], point_damages[p]);
                    proptest::prop_assert_eq!(value.to_bits(), pointwise.to_bits());
                }
            }
        }
    }

    proptest::proptest! {
        #[test]
        fn damaged_hooke_cell_stress_equals_the_sum_of_point_stresses(
            entries in proptest::collection::vec(-1.0f64..1.0, 9),
            damages in proptest::collection::vec(-0.5f64..1.5, 1..12),
            scale in 0.01f64..1.0,
        ) {
            let law = DamagedHooke { shear_modulus: 1.3, lame_lambda: -0.4 };
            let strain = Tensor::<3>::from_column_slice(&entries);
            let strain = (strain + strain.transpose()) * 0.5;
            let weights: Vec<f64> = (0..damages.len()).map(|q| scale * (1.0 + q as f64)).collect();
            let cell = law.weighted_stress_sum(&strain, &damages, &weights);
            let points = TraitDefaults(law).weighted_stress_sum(&strain, &damages, &weights);
            // the same sum in another order: a few roundings of the largest term apart
            let size = law.undamaged(&strain).norm() * weights.iter().sum::<f64>();
            proptest::prop_assert!((cell - points).norm() <= 1e-14 * size.max(1e-300),
                "{} vs {}", cell, points);
        }

        #[test]
        fn potential_viscosity_tangent_is_symmetric_and_strongly_monotone(
            entries in proptest::collection::vec(-1.0f64..1.0, 12),
            log_scale in -6.0f64..3.0,
        ) {
            let law = coupled();
            let symmetric = |values: &[f64]| {
                let m = Tensor::<3>::from_column_slice(values);
                (m + m.transpose()) * 0.5
            };
            let rate = symmetric(&entries[..9]) * 10f64.powf(log_scale);
            let first = symmetric(&entries[3..12]);
            let second = symmetric(&[entries[0], entries[5], entries[7], entries[1], entries[11],
                entries[2], entries[4], entries[9], entries[6]]);
            let a = first.dot(&Viscosity::<3>::tangent(&law, &rate, &second));
            let b = second.dot(&Viscosity::<3>::tangent(&law, &rate, &first));
            let size = first.norm() * second.norm();
            proptest::prop_assert!((a - b).abs() <= 1e-12 * size.max(1e-300), "{} vs {}", a, b);
            // tangent ≥ min(2a, 2bd) = min(1.6, 1.8)
            let quadratic = first.dot(&Viscosity::<3>::tangent(&law, &rate, &first));
            proptest::prop_assert!(quadratic >= 1.6 * first.norm_squared() * (1.0 - 1e-12));
        }
    }

    /// μ(β) = μ₀ β², λ(β) = λ₀ β³ (+ `lambda_shift`), derivatives by hand.
    struct PowerModuli {
        shear: f64,
        lambda: f64,
        lambda_shift: f64,
    }

    impl DamageModuli for PowerModuli {
        fn shear_modulus(&self, beta: f64) -> (f64, f64) {
            (self.shear * beta * beta, 2.0 * self.shear * beta)
        }
        fn lame_lambda(&self, beta: f64) -> (f64, f64) {
            (
                self.lambda * beta.powi(3) + self.lambda_shift,
                3.0 * self.lambda * beta * beta,
            )
        }
    }

    /// μ(β) = μ β, λ(β) = λ β: the moduli of [`DamagedHooke`].
    struct LinearModuli(DamagedHooke);

    impl DamageModuli for LinearModuli {
        fn shear_modulus(&self, beta: f64) -> (f64, f64) {
            (self.0.shear_modulus * beta, self.0.shear_modulus)
        }
        fn lame_lambda(&self, beta: f64) -> (f64, f64) {
            (self.0.lame_lambda * beta, self.0.lame_lambda)
        }
    }

    #[test]
    fn moduli_elasticity_with_linear_moduli_is_damaged_hooke() {
        let hooke = DamagedHooke {
            shear_modulus: 1.3,
            lame_lambda: 0.7,
        };
        let law = ModuliElasticity {
            moduli: Arc::new(LinearModuli(hooke)),
        };
        let eps = sample_tensor();
        let dir = Tensor::<3>::new(0.1, 0.2, 0.0, 0.2, -0.3, 0.4, 0.0, 0.4, 0.25);
        for beta in [-0.5, 0.0, 0.3, 1.0, 1.4] {
            assert_close(
                "stress",
                &Elasticity::<3>::stress(&law, &eps, beta),
                &Elasticity::<3>::stress(&hooke, &eps, beta),
                1e-15,
            );
            assert_close(
                "strain derivative",
                &Elasticity::<3>::strain_derivative(&law, &eps, beta, &dir),
                &Elasticity::<3>::strain_derivative(&hooke, &eps, beta, &dir),
                1e-15,
            );
            assert_eq!(
                Elasticity::<3>::damage_derivative(&law, &eps, beta),
                Elasticity::<3>::damage_derivative(&hooke, &eps, beta)
            );
        }
        Elasticity::<3>::validate(&law).unwrap();
    }

    #[test]
    fn moduli_elasticity_derivatives_match_finite_differences_and_clamp() {
        let law = ModuliElasticity {
            moduli: Arc::new(PowerModuli {
                shear: 2.0,
                lambda: -0.5,
                lambda_shift: 0.0,
            }),
        };
        Elasticity::<2>::validate(&law).unwrap();
        let eps = Tensor::<2>::new(0.1, 0.2, 0.2, -0.3);
        let dir = Tensor::<2>::new(-0.4, 0.1, 0.1, 0.6);
        let h = 1e-6;
        for beta in [0.2, 0.5, 0.9] {
            let fd = (Elasticity::<2>::stress(&law, &eps, beta + h)
                - Elasticity::<2>::stress(&law, &eps, beta - h))
                / (2.0 * h);
            assert_close(
                "∂G/∂β",
                &Elasticity::<2>::damage_derivative(&law, &eps, beta),
                &fd,
                1e-8,
            );
            let fd = (Elasticity::<2>::stress(&law, &(eps + dir * h), beta)
                - Elasticity::<2>::stress(&law, &(eps - dir * h), beta))
                / (2.0 * h);
            assert_close(
                "∂G/∂ε",
                &Elasticity::<2>::strain_derivative(&law, &eps, beta, &dir),
                &fd,
                1e-8,
            );
        }
        // clamped outside [0, 1], one-sided derivative at the ends
        assert_eq!(
            Elasticity::<2>::stress(&law, &eps, 1.5),
            Elasticity::<2>::stress(&law, &eps, 1.0)
        );
        assert_eq!(
            Elasticity::<2>::stress(&law, &eps, -1.0),
            Tensor::<2>::zeros()
        );
        assert_eq!(
            Elasticity::<2>::damage_derivative(&law, &eps, 1.2),
            Tensor::<2>::zeros()
        );
        let at_one = eps * 8.0 + Tensor::<2>::identity() * (-1.5 * eps.trace());
        assert_close(
            "∂G/∂β at β = 1",
            &Elasticity::<2>::damage_derivative(&law, &eps, 1.0),
            &at_one,
            1e-15,
        );
    }

    #[test]
    fn moduli_elasticity_check_rejects_indefinite_or_degenerate_moduli_naming_the_key() {
        let check = |shear: f64, lambda: f64, lambda_shift: f64| {
            Elasticity::<3>::validate(&ModuliElasticity {
                moduli: Arc::new(PowerModuli {
                    shear,
                    lambda,
                    lambda_shift,
                }),
            })
            .map_err(|e| e.to_string())
        };
        assert!(check(1.0, 0.5, 0.0).is_ok());
        let message = check(-1.0, 0.5, 0.0).unwrap_err();
        assert!(message.contains("`elasticity.shear_modulus`"), "{message}");
        let message = check(0.0, 0.5, 0.0).unwrap_err();
        assert!(
            message.contains("`elasticity.shear_modulus`") && message.contains("μ(1)"),
            "{message}"
        );
        // 2μ + 3λ < 0 near β = 1 only
        let message = check(1.0, -1.0, 0.0).unwrap_err();
        assert!(message.contains("`elasticity.lame_lambda`"), "{message}");
        // 2μ + 3λ < 0 at β = 0 (λ(0) = −0.1)
        let message = check(1.0, 0.5, -0.1).unwrap_err();
        assert!(
            message.contains("`elasticity.lame_lambda`") && message.contains("β = 0"),
            "{message}"
        );
        let message = check(f64::NAN, 0.5, 0.0).unwrap_err();
        assert!(
            message.contains("`elasticity.shear_modulus`") && message.contains("not finite"),
            "{message}"
        );
    }

    #[test]
    fn saturating_viscosity_tangent_matches_finite_differences() {
        let law = SaturatingViscosity {
            linear: LinearViscosity {
                shear: 1.0,
                bulk: 0.5,
            },
            extra_shear: 2.0,
            rate_scale: 0.3,
        };
        let eps = sample_tensor();
        let dir = Tensor::<3>::new(0.1, 0.2, 0.0, 0.2, -0.3, 0.4, 0.0, 0.4, 0.25);
        let h = 1e-6;
        let fd = (Viscosity::<3>::stress(&law, &(eps + dir * h))
            - Viscosity::<3>::stress(&law, &(eps - dir * h)))
            / (2.0 * h);
        let exact = Viscosity::<3>::tangent(&law, &eps, &dir);
        assert!((fd - exact).norm() < 1e-8, "{fd} vs {exact}");
    }

    #[test]
    fn viscosity_stress_is_gradient_of_potential() {
        let law = SaturatingViscosity {
            linear: LinearViscosity {
                shear: 0.7,
                bulk: 0.2,
            },
            extra_shear: 1.5,
            rate_scale: 0.2,
        };
        let eps = sample_tensor();
        let dir = Tensor::<3>::new(0.3, 0.1, -0.2, 0.1, 0.5, 0.0, -0.2, 0.0, -0.4);
        let h = 1e-6;
        let fd = (Viscosity::<3>::potential(&law, &(eps + dir * h))
            - Viscosity::<3>::potential(&law, &(eps - dir * h)))
            / (2.0 * h);
        let exact = Viscosity::<3>::stress(&law, &eps).dot(&dir);
        assert!((fd - exact).abs() < 1e-8);
    }

    #[test]
    fn saturating_viscosity_is_strongly_monotone() {
        let law = SaturatingViscosity {
            linear: LinearViscosity {
                shear: 1.0,
                bulk: 0.0,
            },
            extra_shear: 5.0,
            rate_scale: 0.1,
        };
        let a = sample_tensor();
        let b = a * -2.0 + Tensor::<3>::identity() * 0.3;
        let diff = Viscosity::<3>::stress(&law, &a) - Viscosity::<3>::stress(&law, &b);
        let monotone = diff.dot(&(a - b));
        assert!(monotone >= 2.0 * (a - b).norm_squared() - 1e-12);
    }

    #[test]
    fn damaged_hooke_clamps_damage() {
        let law = DamagedHooke {
            shear_modulus: 1.0,
            lame_lambda: 2.0,
        };
        let eps = Tensor::<2>::new(0.1, 0.2, 0.2, -0.3);
        assert_eq!(
            Elasticity::<2>::stress(&law, &eps, 1.7),
            Elasticity::<2>::stress(&law, &eps, 1.0)
        );
        assert_eq!(
            Elasticity::<2>::stress(&law, &eps, -0.5),
            Tensor::<2>::zeros()
        );
        let half = Elasticity::<2>::stress(&law, &eps, 0.5);
        assert!((half - Elasticity::<2>::damage_derivative(&law, &eps, 0.5) * 0.5).norm() < 1e-15);
    }

    #[test]
    fn truncated_fremond_matches_fremond_inside_and_is_bounded_outside() {
        let law = TruncatedFremond {
            lambda_d: 0.5,
            lambda_w: 0.1,
            damage_floor: 0.1,
            strain_energy_cap: 1.0,
        };
        let eps = Tensor::<2>::new(0.1, 0.0, 0.0, 0.2);
        let beta = 0.4;
        let fremond = 0.5 * (1.0 - beta) / beta - 0.5 * eps.norm_squared() + 0.1;
        assert!((DamageSource::<2>::source(&law, &eps, beta) - fremond).abs() < 1e-15);
        let at_floor = DamageSource::<2>::source(&law, &eps, 0.1);
        assert_eq!(DamageSource::<2>::source(&law, &eps, 0.0), at_floor);
        let big = Tensor::<2>::identity() * 10.0;
        assert_eq!(DamageSource::<2>::source(&law, &big, 1.0), -0.5 + 0.1);
    }

    #[test]
    fn contact_bounds_follow_2_10_to_2_12() {
        let coulomb = NormalComplianceCoulomb {
            stiffness: 10.0,
            friction: 0.3,
            wear: 0.0,
        };
        assert_eq!(coulomb.normal_pressure(-0.1), 0.0);
        assert_eq!(coulomb.friction_bound(-0.1), 0.0);
        assert!((coulomb.normal_pressure(0.2) - 2.0).abs() < 1e-15);
        assert!((coulomb.friction_bound(0.2) - 0.6).abs() < 1e-15);
        let wear = NormalComplianceCoulomb {
            wear: 0.25,
            ..coulomb
        };
        assert!((wear.friction_bound(0.2) - 0.6 * 0.5).abs() < 1e-15);
        assert_eq!(wear.friction_bound(1.0), 0.0);
    }

    #[test]
    fn invalid_parameters_are_named() {
        let message = |e: Error| e.to_string();
        let err = Viscosity::<2>::validate(&LinearViscosity {
            shear: 0.0,
            bulk: 1.0,
        })
        .unwrap_err();
        assert!(message(err).contains("viscosity.shear"));
        let err = Viscosity::<3>::validate(&LinearViscosity {
            shear: 1.0,
            bulk: -1.0,
        })
        .unwrap_err();
        assert!(message(err).contains("viscosity.bulk"));
        let err = NormalComplianceCoulomb {
            stiffness: -1.0,
            friction: 0.1,
            wear: 0.0,
        }
        .validate()
        .unwrap_err();
        assert!(message(err).contains("contact.stiffness"));
        let err = NormalComplianceCoulomb {
            stiffness: 1.0,
            friction: -0.1,
            wear: 0.0,
        }
        .validate()
        .unwrap_err();
        assert!(message(err).contains("contact.friction"));
        let err = NormalComplianceCoulomb {
            stiffness: 1.0,
            friction: 0.1,
            wear: -1.0,
        }
        .validate()
        .unwrap_err();
        assert!(message(err).contains("contact.wear"));
        let law = TruncatedFremond {
            lambda_d: 1.0,
            lambda_w: 0.0,
            damage_floor: 0.0,
            strain_energy_cap: 1.0,
        };
        let err = DamageSource::<2>::validate(&law).unwrap_err();
        assert!(message(err).contains("damage_floor"));
        let err = Elasticity::<2>::validate(&DamagedHooke {
            shear_modulus: 1.0,
            lame_lambda: f64::NAN,
        })
        .unwrap_err();
        assert!(message(err).contains("lame_lambda"));
    }
}
