//! The validated friction problem of (5.1) with a symmetric matrix, and its objective
//! J(x) = ½ xᵀ S x − rᵀ x + Σ_a w_a |x_a| with the magnitude of its terms (for rounding bands).

use super::blocks::block_norm;
use crate::algebra::linalg::{dot, max_abs};
use faer::linalg::matmul::matmul;
use faer::prelude::*;
use faer::Accum;

/// J together with the magnitude of its terms (for rounding bands).
#[derive(Debug, Clone, Copy)]
pub(super) struct Energy {
    pub(super) value: f64,
    pub(super) magnitude: f64,
}

/// The validated problem with a symmetric matrix.
pub(super) struct Problem<'a> {
    pub(super) matrix: MatRef<'a, f64>,
    pub(super) rhs: &'a [f64],
    pub(super) weights: &'a [f64],
    pub(super) group: usize,
    /// σ = 1 / max_i S_ii: the step of the natural residual and of the active-set prediction.
    pub(super) sigma: f64,
    /// max(‖r‖_∞, f64::MIN_POSITIVE).
    pub(super) scale: f64,
}

impl<'a> Problem<'a> {
    pub(super) fn new(
        matrix: MatRef<'a, f64>,
        rhs: &'a [f64],
        weights: &'a [f64],
        group: usize,
    ) -> Self {
        let max_diagonal = (0..matrix.nrows()).fold(0.0_f64, |acc, i| acc.max(matrix[(i, i)]));
        let sigma = if max_diagonal > 0.0 {
            1.0 / max_diagonal
        } else {
            1.0
        };
        Self {
            matrix,
            rhs,
            weights,
            group,
            sigma,
            scale: max_abs(rhs).max(f64::MIN_POSITIVE),
        }
    }
}

impl Problem<'_> {
    pub(super) fn dimension(&self) -> usize {
        self.rhs.len()
    }

    /// Rounding band of a sum of `dimension` terms of total size `magnitude`.
    pub(super) fn rounding_band(&self, magnitude: f64) -> f64 {
        64.0 * f64::EPSILON * ((self.dimension() + 1) as f64).sqrt() * magnitude
    }

    /// out = S x.
    pub(super) fn apply(&self, x: &[f64], out: &mut [f64]) {
        matmul(
            ColMut::from_slice_mut(out).as_mat_mut(),
            Accum::Replace,
            self.matrix,
            ColRef::from_slice(x).as_mat(),
            1.0,
            Par::Seq,
        );
    }

    pub(super) fn friction(&self, x: &[f64]) -> f64 {
        x.chunks_exact(self.group)
            .zip(self.weights)
            .map(|(block, &w)| w * block_norm(block))
            .sum()
    }

    /// ½ xᵀ S x − rᵀ x without the friction term, and its magnitude.
    pub(super) fn smooth_energy(&self, x: &[f64], sx: &[f64]) -> Energy {
        let quadratic = 0.5 * dot(x, sx);
        let linear = dot(self.rhs, x);
        Energy {
            value: quadratic - linear,
            magnitude: quadratic.abs() + linear.abs(),
        }
    }

    pub(super) fn energy(&self, x: &[f64], sx: &[f64]) -> Energy {
        let smooth = self.smooth_energy(x, sx);
        let friction = self.friction(x);
        Energy {
            value: smooth.value + friction,
            magnitude: smooth.magnitude + friction,
        }
    }
}
