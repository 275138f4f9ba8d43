//! The viscosity 𝒜 = ∂Φ/∂ε of a user potential Φ(tr ε, |ε_D|) (paper (2.1), assumption (3.4)),
//! with the sampled check of (3.4).

use super::tensor::{deviator, trace, Tensor};
use super::viscosity::Viscosity;
use crate::error::{Error, Result};
use nalgebra::DMatrix;
use std::sync::Arc;

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
///
/// [`SaturatingViscosity`]: super::SaturatingViscosity
pub(super) const SMALL_DEVIATOR: f64 = 1e-10;

/// Sampled magnitudes |ε| of the check of [`PotentialViscosity`]: 10^(k/2), k = −8, …, 6
/// (1e-4 to 1e3 on a log grid, 15 values).
fn sampled_rate_magnitudes() -> impl Iterator<Item = f64> {
    (-8..=6).map(|k| 10f64.powf(f64::from(k) / 2.0))
}

/// Sampled directions of the check of [`PotentialViscosity`]: unit strain rates cos θ I/√d +
/// sin θ E_D at 13 angles θ ∈ [0°, 180°] (pure volumetric at 0° and 180°, pure deviatoric at 90°,
/// mixed otherwise), E_D cycling through unit deviators (normal, shear and a generic one).
pub(super) fn sampled_rate_directions<const D: usize>() -> Vec<Tensor<D>> {
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
pub(super) fn symmetric_basis<const D: usize>() -> Vec<Tensor<D>> {
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
pub(super) struct Invariants<const D: usize> {
    pub(super) trace: f64,
    pub(super) deviator: Tensor<D>,
    /// ε_D/|ε_D|, or 0 where ε_D = 0.
    pub(super) unit_deviator: Tensor<D>,
    pub(super) dev_norm: f64,
    /// |ε_D| ≤ SMALL_DEVIATOR |ε|: use the limit form.
    pub(super) near_axis: bool,
}

impl<const D: usize> Invariants<D> {
    pub(super) fn of(strain_rate: &Tensor<D>) -> Self {
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

    pub(super) fn stress_at<const D: usize>(&self, invariants: &Invariants<D>) -> Tensor<D> {
        let jet = self.potential.jet(invariants.trace, invariants.dev_norm);
        let (secant, _) = invariants.deviatoric_slopes(&jet);
        Tensor::<D>::identity() * jet.gradient[0] + invariants.deviator * secant
    }

    pub(super) fn tangent_at<const D: usize>(
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
