//! The KKT residual of the friction problem of (5.1) (natural, stationarity and dual
//! infeasibility parts, see the module docs of [`crate::solvers::friction`]) and the
//! multipliers λ at a point.

use super::blocks::{block_norm, shrink};
use super::objective::Problem;
use super::settings::KktResidual;
use crate::algebra::linalg::max_abs;

impl Problem<'_> {
    pub(super) fn kkt(&self, x: &[f64], sx: &[f64]) -> KktResidual {
        let group = self.group;
        let mut natural = 0.0_f64;
        let mut stationarity = 0.0_f64;
        let mut dual = 0.0_f64;
        let mut gradient = [0.0; 2];
        let mut shifted = [0.0; 2];
        for (a, &w) in self.weights.iter().enumerate() {
            let range = a * group..(a + 1) * group;
            let block = &x[range.clone()];
            let gradient = &mut gradient[..group];
            let shifted = &mut shifted[..group];
            for (k, i) in range.enumerate() {
                gradient[k] = sx[i] - self.rhs[i];
                shifted[k] = x[i] - self.sigma * gradient[k];
            }
            shrink(shifted, self.sigma * w);
            for k in 0..group {
                natural = natural.max((block[k] - shifted[k]).abs() / self.sigma);
            }
            let norm = block_norm(block);
            let gradient_norm = block_norm(gradient);
            if w == 0.0 {
                stationarity = stationarity.max(max_abs(gradient));
            } else if norm > 0.0 {
                for k in 0..group {
                    stationarity = stationarity.max((gradient[k] + w * block[k] / norm).abs());
                }
            } else if gradient_norm > w {
                let excess = 1.0 - w / gradient_norm;
                stationarity = stationarity.max(excess * max_abs(gradient));
                dual = dual.max(gradient_norm - w);
            }
        }
        KktResidual {
            natural: natural / self.scale,
            stationarity: stationarity / self.scale,
            dual_infeasibility: dual / self.scale,
        }
    }

    /// The multipliers λ at x (documented in the module docs).
    pub(super) fn multipliers(&self, x: &[f64], sx: &[f64], out: &mut [f64]) {
        let group = self.group;
        for (a, &w) in self.weights.iter().enumerate() {
            let range = a * group..(a + 1) * group;
            let norm = block_norm(&x[range.clone()]);
            if w == 0.0 {
                out[range].fill(0.0);
            } else if norm > 0.0 {
                for i in range {
                    out[i] = x[i] / norm;
                }
            } else {
                for i in range.clone() {
                    out[i] = (self.rhs[i] - sx[i]) / w;
                }
                let lambda_norm = block_norm(&out[range.clone()]);
                if lambda_norm > 1.0 {
                    for value in &mut out[range] {
                        *value /= lambda_norm;
                    }
                }
            }
        }
    }
}
