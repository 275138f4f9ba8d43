//! The damage-dependent elasticity G(ε, β) of (2.1) (paper §2–3, assumption (3.5)): the trait,
//! the damaged Hooke law and the law with user moduli μ(β), λ(β).

use super::tensor::{
    check_finite, has_avx2, isotropic_divergence, isotropic_divergence_at, trace, FieldJets, Tensor,
};
use crate::error::{Error, Result};
use nalgebra::SVector;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

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
    /// Whether an evaluation of [`Elasticity::stress`] since the law was built met a damage at
    /// which [`Elasticity::damage_range_violation`] holds (a law whose admissible range
    /// [`Elasticity::validate`] can only sample notes it at no cost in the evaluation itself;
    /// the scheme then locates the point). Sticky: shared by every simulation of the law, so
    /// it says "look", not where. False by default.
    fn damage_range_suspect(&self) -> bool {
        false
    }
    /// What is wrong with G(·, β) at the damage β (before the clamp to [0, 1]), naming the
    /// key of the law: an error when G(·, β) is not positive semidefinite or not finite.
    /// `None` by default.
    fn damage_range_violation(&self, _damage: f64) -> Option<Error> {
        None
    }
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
    pub(super) fn undamaged<const D: usize>(&self, strain: &Tensor<D>) -> Tensor<D> {
        strain * (2.0 * self.shear_modulus)
            + Tensor::<D>::identity() * (self.lame_lambda * trace(strain))
    }

    /// [`Self::divergence_of_jets`] compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn divergence_of_jets_avx2<const D: usize>(
        &self,
        displacement: &FieldJets<'_, D>,
        damage: &[f64],
        damage_gradient: &[&[f64]; D],
        out: &mut [&mut [f64]; D],
    ) {
        self.divergence_of_jets(displacement, damage, damage_gradient, out)
    }

    /// The body of [`Elasticity::stress_divergence_of_jets`] for `out[0].len()` points.
    #[inline(always)]
    pub(super) fn divergence_of_jets<const D: usize>(
        &self,
        displacement: &FieldJets<'_, D>,
        damage: &[f64],
        damage_gradient: &[&[f64]; D],
        out: &mut [&mut [f64]; D],
    ) {
        let twice_shear = 2.0 * self.shear_modulus;
        let lambda = self.lame_lambda;
        let count = out[0].len();
        let displacement = displacement.first(count);
        let (gradient, second) = (&displacement.gradient, &displacement.second);
        let damage = &damage[..count];
        let damage_gradient = damage_gradient.map(|column| &column[..count]);
        let mut out = out.each_mut().map(|column| &mut column[..count]);
        for p in 0..count {
            // ε and tr ε at p
            let strain = |i: usize, k: usize| (gradient[i][k][p] + gradient[k][i][p]) * 0.5;
            let mut strain_trace = 0.0;
            for k in 0..D {
                strain_trace += strain(k, k);
            }
            let beta = damage[p];
            let clamped = beta.clamp(0.0, 1.0);
            let inside = (0.0..=1.0).contains(&beta);
            for (i, out) in out.iter_mut().enumerate() {
                let elastic = isotropic_divergence_at(twice_shear, lambda, second, p, i) * clamped;
                // (2μ ε + λ tr ε I) ∇β, row i, column by column
                let term = |k: usize| {
                    let identity = if i == k { 1.0 } else { 0.0 };
                    (strain(i, k) * twice_shear + identity * (lambda * strain_trace))
                        * damage_gradient[k][p]
                };
                let mut flux = term(0);
                for k in 1..D {
                    flux += term(k);
                }
                out[p] = if inside { elastic + flux } else { elastic };
            }
        }
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
    /// The batch of [`Elasticity::stress_divergence`] straight from the columns of the jets,
    /// without building the point's strain and strain-derivative tensors: the operations of
    /// the point-by-point form in the same order (nalgebra's trace from 0, its matrix–vector
    /// product column by column, the identity's zeros multiplied in), so bitwise its values
    /// (`stress_divergences_of_jets_are_bitwise_the_pointwise_divergences`). With the same
    /// for [`crate::model::laws::LinearViscosity`], the 3D data of a manufactured run take
    /// about a fifth less time. The loop runs over columns cut to the batch and is compiled for
    /// AVX2 where the processor has it (no fused multiply–add, so the same values); in 2D it
    /// is vectorized, four points per instruction, while in 3D, with 40 columns read per
    /// point, the compiler keeps it scalar.
    fn stress_divergence_of_jets(
        &self,
        displacement: &FieldJets<'_, D>,
        damage: &[f64],
        damage_gradient: &[&[f64]; D],
        out: &mut [&mut [f64]; D],
    ) {
        if has_avx2() {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the processor has AVX2.
            unsafe {
                return self.divergence_of_jets_avx2(displacement, damage, damage_gradient, out);
            }
        }
        self.divergence_of_jets(displacement, damage, damage_gradient, out)
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
/// `elasticity.lame_lambda`. Samples can miss a narrow excursion between them, so the scheme
/// also checks μ(β̄) ≥ 0, 2μ(β̄) + dλ(β̄) ≥ 0 and finite values wherever it evaluates G
/// ([`Elasticity::damage_range_suspect`], [`Elasticity::damage_range_violation`]).
#[derive(Clone)]
pub struct ModuliElasticity {
    /// μ(β), λ(β).
    pub moduli: Arc<dyn DamageModuli>,
    /// Set by [`Elasticity::stress`] when it meets μ(β̄) < 0, 2μ(β̄) + dλ(β̄) < 0 or a value that
    /// is not finite ([`Elasticity::damage_range_suspect`]).
    outside_range: Arc<AtomicBool>,
}

impl std::fmt::Debug for ModuliElasticity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ModuliElasticity").finish_non_exhaustive()
    }
}

/// The key of μ(β) in errors about [`ModuliElasticity`].
const SHEAR_MODULUS_KEY: &str = "elasticity.shear_modulus";
/// The key of λ(β) in errors about [`ModuliElasticity`].
const LAME_LAMBDA_KEY: &str = "elasticity.lame_lambda";

impl ModuliElasticity {
    /// The law of the moduli `moduli`.
    pub fn new(moduli: Arc<dyn DamageModuli>) -> Self {
        Self {
            moduli,
            outside_range: Arc::new(AtomicBool::new(false)),
        }
    }

    /// Notes moduli outside the admissible range: μ ≥ 0 and 2μ + dλ ≥ 0, both finite.
    fn note_range(&self, shear: f64, lambda: f64, dimension: usize) {
        let bulk = 2.0 * shear + dimension as f64 * lambda;
        let admissible = shear >= 0.0 && bulk >= 0.0 && bulk.is_finite();
        if !admissible {
            self.outside_range.store(true, Ordering::Relaxed);
        }
    }

    fn hooke<const D: usize>(shear: f64, lambda: f64, strain: &Tensor<D>) -> Tensor<D> {
        strain * (2.0 * shear) + Tensor::<D>::identity() * (lambda * trace(strain))
    }
}

impl<const D: usize> Elasticity<D> for ModuliElasticity {
    fn stress(&self, strain: &Tensor<D>, damage: f64) -> Tensor<D> {
        let beta = damage.clamp(0.0, 1.0);
        let (shear, _) = self.moduli.shear_modulus(beta);
        let (lambda, _) = self.moduli.lame_lambda(beta);
        self.note_range(shear, lambda, D);
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
    fn damage_range_suspect(&self) -> bool {
        self.outside_range.load(Ordering::Relaxed)
    }
    fn damage_range_violation(&self, damage: f64) -> Option<Error> {
        let beta = damage.clamp(0.0, 1.0);
        let (shear, _) = self.moduli.shear_modulus(beta);
        let (lambda, _) = self.moduli.lame_lambda(beta);
        let bulk = 2.0 * shear + D as f64 * lambda;
        if !shear.is_finite() || shear < 0.0 {
            Some(Error::parameter(
                SHEAR_MODULUS_KEY,
                shear,
                format!(
                    "μ(β) must be finite and ≥ 0 (G positive semidefinite); μ({beta}) = {shear}"
                ),
            ))
        } else if !lambda.is_finite() || bulk < 0.0 {
            Some(Error::parameter(
                LAME_LAMBDA_KEY,
                lambda,
                format!(
                    "λ(β) must be finite and 2μ(β) + dλ(β) ≥ 0 (G positive semidefinite); at \
                     β = {beta}: 2μ + dλ = {bulk:.3e} with μ = {shear}"
                ),
            ))
        } else {
            None
        }
    }
    fn validate(&self) -> Result<()> {
        const SHEAR: &str = SHEAR_MODULUS_KEY;
        const LAMBDA: &str = LAME_LAMBDA_KEY;
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
