//! The viscosity operator 𝒜 of the Kelvin–Voigt law (2.1) (paper §2–3, assumption (3.4)): the
//! trait and the closed-form laws, linear and rate-saturating.

use super::tensor::{
    check_finite, deviator, has_avx2, isotropic_divergence, isotropic_divergence_at, trace,
    FieldJets, Tensor,
};
use crate::error::{Error, Result};
use nalgebra::SVector;

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

/// Linear isotropic viscosity 𝒜ε = 2η ε + ζ tr(ε) I.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearViscosity {
    /// Shear viscosity η > 0.
    pub shear: f64,
    /// Bulk viscosity ζ, with 2η + dζ > 0 (strong monotonicity).
    pub bulk: f64,
}

impl LinearViscosity {
    /// [`Self::divergence_of_jets`] compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn divergence_of_jets_avx2<const D: usize>(
        &self,
        velocity: &FieldJets<'_, D>,
        out: &mut [&mut [f64]; D],
    ) {
        self.divergence_of_jets(velocity, out)
    }

    /// The body of [`Viscosity::stress_divergence_of_jets`] for `out[0].len()` points.
    #[inline(always)]
    pub(super) fn divergence_of_jets<const D: usize>(
        &self,
        velocity: &FieldJets<'_, D>,
        out: &mut [&mut [f64]; D],
    ) {
        let twice_shear = 2.0 * self.shear;
        let count = out[0].len();
        let velocity = velocity.first(count);
        let mut out = out.each_mut().map(|column| &mut column[..count]);
        for p in 0..count {
            for (i, out) in out.iter_mut().enumerate() {
                out[p] = isotropic_divergence_at(twice_shear, self.bulk, &velocity.second, p, i);
            }
        }
    }
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
    /// The batch straight from the columns of the jets, without the point's tensors, bitwise
    /// [`Self::stress_divergence`] at each point; vectorized over columns cut to the batch,
    /// compiled for AVX2 where the processor has it (as the damaged Hooke law's).
    fn stress_divergence_of_jets(&self, velocity: &FieldJets<'_, D>, out: &mut [&mut [f64]; D]) {
        if has_avx2() {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the processor has AVX2.
            unsafe {
                return self.divergence_of_jets_avx2(velocity, out);
            }
        }
        self.divergence_of_jets(velocity, out)
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
