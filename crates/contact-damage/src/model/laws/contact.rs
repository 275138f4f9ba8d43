//! The contact law on Γ3 (paper §2–3, assumption (3.7)): normal compliance (2.7), (2.10) with
//! the Coulomb friction bound (2.8), (2.11) and its wear-modified form (2.12).

use super::tensor::check_finite;
use crate::error::{Error, Result};

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
    /// True when p_τ ≡ 0 (frictionless contact): the velocity step then has no friction term
    /// and its tangential contact unknowns are ordinary unknowns. The default, false, is always
    /// safe.
    fn is_frictionless(&self) -> bool {
        false
    }
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
    /// μ = 0.
    fn is_frictionless(&self) -> bool {
        self.friction == 0.0
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
