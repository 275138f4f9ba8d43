//! The settings, the KKT residual and the statistics of the condensed friction solver of
//! (5.1).

/// Settings of [`CondensedFriction::solve`](super::CondensedFriction::solve).
#[derive(Debug, Clone, Copy)]
pub struct FrictionSettings {
    /// Bound on the relative KKT residual ([`KktResidual::max`]); default 1e-12.
    pub tolerance: f64,
    /// Largest number of Newton systems solved; default 100.
    pub max_newton: usize,
    /// Largest number of proximal-gradient (FISTA) steps; default 20000.
    pub max_gradient: usize,
}

impl Default for FrictionSettings {
    fn default() -> Self {
        Self {
            tolerance: 1e-12,
            max_newton: 100,
            max_gradient: 20000,
        }
    }
}

/// The parts of the scale-aware KKT residual documented in the [module docs](super).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct KktResidual {
    /// ‖x − prox_{σW|·|}(x − σ(S x − r))‖_∞ / (σ · scale), σ = 1 / max_i S_ii.
    pub natural: f64,
    /// ‖S x − r + W λ‖_∞ / scale with the returned (dual-feasible) multipliers λ.
    pub stationarity: f64,
    /// max over stick blocks of (|(S x − r)_a| − w_a)₊ / scale.
    pub dual_infeasibility: f64,
}

impl KktResidual {
    /// The largest of the three parts: the quantity compared with the tolerance.
    pub fn max(&self) -> f64 {
        self.natural
            .max(self.stationarity)
            .max(self.dual_infeasibility)
    }
}

/// What [`CondensedFriction::solve`](super::CondensedFriction::solve) did and where it ended.
#[derive(Debug, Clone, Default)]
pub struct FrictionStats {
    /// Newton systems solved (each one a dense Cholesky factorization).
    pub newton_iterations: usize,
    /// Proximal-gradient (FISTA) steps taken, restarts included.
    pub gradient_iterations: usize,
    /// Natural part of the KKT residual at the solution ([`KktResidual::natural`]).
    pub kkt_residual: f64,
    /// Stationarity part ([`KktResidual::stationarity`]).
    pub stationarity: f64,
    /// Dual-infeasibility part ([`KktResidual::dual_infeasibility`]).
    pub dual_infeasibility: f64,
    /// Groups with w_a > 0 and x_a = 0.
    pub stick: usize,
    /// Groups with w_a > 0 and x_a ≠ 0.
    pub slip: usize,
    /// Groups with w_a = 0.
    pub free: usize,
}
