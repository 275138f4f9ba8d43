//! The tensor type shared by the constitutive laws (paper §2–3), its trace and deviator, the
//! jets of smooth fields that the laws' divergences take, and the check of their parameters
//! (finite, and within the scale of double precision).

use crate::algebra::linalg::MAGNITUDE_LIMIT;
use crate::error::{Error, Result};
use nalgebra::{SMatrix, SVector};

/// A symmetric second-order tensor in R^D (strain, strain rate, stress).
pub type Tensor<const D: usize> = SMatrix<f64, D, D>;

pub(super) fn trace<const D: usize>(tensor: &Tensor<D>) -> f64 {
    tensor.trace()
}

pub(super) fn deviator<const D: usize>(tensor: &Tensor<D>) -> Tensor<D> {
    tensor - Tensor::<D>::identity() * (trace(tensor) / D as f64)
}

/// A law parameter must be finite and at most [`MAGNITUDE_LIMIT`] in magnitude: stresses and
/// energies multiply it with strains and square the products.
pub(super) fn check_finite(name: &str, value: f64) -> Result<()> {
    if !value.is_finite() {
        Err(Error::parameter(name, value, "must be finite"))
    } else if value.abs() > MAGNITUDE_LIMIT {
        Err(Error::parameter(
            name,
            value,
            format!(
                "is beyond {MAGNITUDE_LIMIT:e} in magnitude, out of the scale of double precision (the stresses and energies square it; change the problem's units)"
            ),
        ))
    } else {
        Ok(())
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

impl<'a, const D: usize> FieldJets<'a, D> {
    /// The jets of the first `count` points: every column cut to `count` values, so that a
    /// loop over `0..count` reads them without bounds checks (and can be vectorized).
    ///
    /// # Panics
    /// If a column has fewer than `count` values.
    pub fn first(&self, count: usize) -> FieldJets<'a, D> {
        FieldJets {
            gradient: self.gradient.map(|row| row.map(|column| &column[..count])),
            second: self
                .second
                .map(|block| block.map(|row| row.map(|column| &column[..count]))),
        }
    }

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

/// Whether the processor has AVX2, for the batch kernels of the laws that have a copy compiled
/// for it (the answer is cached by the standard library).
#[inline]
pub(super) fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Component i of [`isotropic_divergence`] at point p of a batch of jets, from the columns of
/// the second derivatives (`second[j][a][b][p]` = ∂²w_a/∂x_b∂x_j, see [`FieldJets`]), without
/// building the point's tensors: the same operations in the same order as on them (sums from
/// 0), so bitwise its value.
#[inline(always)]
pub(super) fn isotropic_divergence_at<const D: usize>(
    twice_shear: f64,
    trace_factor: f64,
    second: &[[[&[f64]; D]; D]; D],
    p: usize,
    i: usize,
) -> f64 {
    // (∂_j ε)_ab = (∂²w_a/∂x_b∂x_j + ∂²w_b/∂x_a∂x_j) / 2
    let derivative = |j: usize, a: usize, b: usize| (second[j][a][b][p] + second[j][b][a][p]) * 0.5;
    let mut column_sum = 0.0;
    for j in 0..D {
        column_sum += derivative(j, i, j);
    }
    let mut derivative_trace = 0.0;
    for k in 0..D {
        derivative_trace += derivative(i, k, k);
    }
    twice_shear * column_sum + trace_factor * derivative_trace
}

/// Σ_j (∂_j ε)_ij and tr(∂_i ε) for i < D: the two contractions that the divergence of an
/// isotropic linear law 2a ε + b tr(ε) I needs, `(2a Σ_j (∂_j ε)_ij + b tr(∂_i ε))_i`.
pub(super) fn isotropic_divergence<const D: usize>(
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
