//! Constitutive functions of the model (paper §2–3): the viscosity operator 𝒜, the
//! damage-dependent elasticity G, the damage source φ, and the contact functions p_ν, p_τ.
//!
//! Every law validates its parameters against the assumptions (3.4)–(3.7) of the theory, and an
//! error names the offending parameter.

use crate::{Error, Result};
use nalgebra::SMatrix;

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

/// Damage source φ(ε, β) of (2.2). Assumption (3.6): Lipschitz in (ε, β).
pub trait DamageSource<const D: usize>: Send + Sync {
    /// φ(ε, β).
    fn source(&self, strain: &Tensor<D>, damage: f64) -> f64;
    /// Checks the parameters against (3.6).
    fn validate(&self) -> Result<()>;
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
