//! The accelerated proximal-gradient method for the friction problem of (5.1): monotone FISTA
//! bursts with adaptive restart, and the step size control L ≥ λ_max(S).

use super::blocks::shrink;
use super::objective::{Energy, Problem};
use super::settings::KktResidual;
use crate::algebra::linalg::dot;

/// Power iterations used to estimate λ_max(S).
const POWER_ITERATIONS: usize = 30;
/// Safety factor on the power-iteration estimate of λ_max(S).
const LIPSCHITZ_SAFETY: f64 = 1.1;

/// Step size control of the proximal-gradient steps.
#[derive(Debug, Clone, Copy)]
pub(super) struct Lipschitz {
    /// Current L (≥ the power-iteration estimate, ≤ `upper`).
    value: f64,
    /// Guaranteed bound min(Gershgorin, Frobenius) ≥ λ_max(S).
    upper: f64,
}

impl Problem<'_> {
    /// Guaranteed bound min(Gershgorin, Frobenius) ≥ λ_max(S) and a power-iteration estimate.
    pub(super) fn lipschitz(&self) -> Lipschitz {
        let m = self.dimension();
        let mut gershgorin = 0.0_f64;
        let mut frobenius = 0.0_f64;
        for j in 0..m {
            // Column sums equal row sums: S is symmetric.
            let column = self.matrix.col(j);
            let mut sum = 0.0;
            for i in 0..m {
                sum += column[i].abs();
                frobenius += column[i] * column[i];
            }
            gershgorin = gershgorin.max(sum);
        }
        let upper = gershgorin.min(frobenius.sqrt());
        let mut vector: Vec<f64> = (0..m).map(|i| (1.0 + 2.3 * i as f64).sin() + 0.5).collect();
        let mut image = vec![0.0; m];
        let mut estimate = 0.0_f64;
        for _ in 0..POWER_ITERATIONS {
            let norm = dot(&vector, &vector).sqrt();
            if norm == 0.0 {
                break;
            }
            vector.iter_mut().for_each(|v| *v /= norm);
            self.apply(&vector, &mut image);
            estimate = estimate.max(dot(&vector, &image));
            std::mem::swap(&mut vector, &mut image);
        }
        Lipschitz {
            value: (LIPSCHITZ_SAFETY * estimate).clamp(f64::MIN_POSITIVE, upper),
            upper,
        }
    }

    /// Up to `steps` monotone FISTA steps from (x, S x); returns the number of steps taken.
    /// On exit x, sx, energy and report describe the best (= last accepted) iterate.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn gradient_burst(
        &self,
        x: &mut [f64],
        sx: &mut [f64],
        energy: &mut Energy,
        report: &mut KktResidual,
        lipschitz: &mut Lipschitz,
        steps: usize,
        tolerance: f64,
    ) -> usize {
        let m = self.dimension();
        let group = self.group;
        let mut extrapolated_point = x.to_vec();
        let mut extrapolated_image = sx.to_vec();
        let mut previous = x.to_vec();
        let mut previous_image = sx.to_vec();
        let mut trial = vec![0.0; m];
        let mut trial_image = vec![0.0; m];
        let mut momentum = 1.0_f64;
        let mut extrapolating = false;
        let mut used = 0;
        while used < steps {
            used += 1;
            // Proximal-gradient step from the extrapolated point, with backtracking on L.
            let base = self.smooth_energy(&extrapolated_point, &extrapolated_image);
            let mut smooth;
            loop {
                let step = 1.0 / lipschitz.value;
                for i in 0..m {
                    trial[i] = extrapolated_point[i] - step * (extrapolated_image[i] - self.rhs[i]);
                }
                for (block, &w) in trial.chunks_exact_mut(group).zip(self.weights) {
                    shrink(block, step * w);
                }
                self.apply(&trial, &mut trial_image);
                smooth = self.smooth_energy(&trial, &trial_image);
                let mut model = base.value;
                let mut distance = 0.0;
                for i in 0..m {
                    let difference = trial[i] - extrapolated_point[i];
                    model += (extrapolated_image[i] - self.rhs[i]) * difference;
                    distance += difference * difference;
                }
                model += 0.5 * lipschitz.value * distance;
                let band = self.rounding_band(base.magnitude + smooth.magnitude);
                if smooth.value <= model + band || lipschitz.value >= lipschitz.upper {
                    break;
                }
                lipschitz.value = (2.0 * lipschitz.value).min(lipschitz.upper);
            }
            let friction = self.friction(&trial);
            let candidate = Energy {
                value: smooth.value + friction,
                magnitude: smooth.magnitude + friction,
            };
            let allowance = if extrapolating {
                0.0
            } else {
                self.rounding_band(energy.magnitude + candidate.magnitude)
            };
            if candidate.value.is_finite() && candidate.value <= energy.value + allowance {
                previous.copy_from_slice(x);
                previous_image.copy_from_slice(sx);
                x.copy_from_slice(&trial);
                sx.copy_from_slice(&trial_image);
                *energy = candidate;
                *report = self.kkt(x, sx);
                if report.max() <= tolerance {
                    break;
                }
                let next = 0.5 * (1.0 + (1.0 + 4.0 * momentum * momentum).sqrt());
                let beta = (momentum - 1.0) / next;
                momentum = next;
                for i in 0..m {
                    extrapolated_point[i] = x[i] + beta * (x[i] - previous[i]);
                    extrapolated_image[i] = sx[i] + beta * (sx[i] - previous_image[i]);
                }
                extrapolating = beta > 0.0;
            } else if extrapolating {
                // Adaptive restart: drop the momentum, step again from the best iterate.
                momentum = 1.0;
                extrapolating = false;
                extrapolated_point.copy_from_slice(x);
                extrapolated_image.copy_from_slice(sx);
            } else {
                // A plain step cannot decrease J beyond rounding: nothing more to gain here.
                break;
            }
        }
        used
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::Mat;

    /// S = Q diag(λ) Qᵀ with a known spectrum: Q a product of two Householder reflections.
    fn matrix_with_spectrum(eigenvalues: &[f64]) -> (Mat<f64>, Vec<Vec<f64>>) {
        let m = eigenvalues.len();
        let reflect = |v: &[f64], x: &mut [f64]| {
            let vv = dot(v, v);
            let vx = dot(v, x);
            x.iter_mut()
                .zip(v)
                .for_each(|(x, v)| *x -= 2.0 * vx / vv * v);
        };
        let first: Vec<f64> = (0..m).map(|i| (0.7 * i as f64 + 0.3).sin()).collect();
        let second: Vec<f64> = (0..m).map(|i| (1.3 * i as f64 - 0.2).cos()).collect();
        let vectors: Vec<Vec<f64>> = (0..m)
            .map(|j| {
                let mut e = vec![0.0; m];
                e[j] = 1.0;
                reflect(&first, &mut e);
                reflect(&second, &mut e);
                e
            })
            .collect();
        let matrix = Mat::from_fn(m, m, |i, k| {
            (0..m)
                .map(|j| eigenvalues[j] * vectors[j][i] * vectors[j][k])
                .sum()
        });
        (matrix, vectors)
    }

    #[test]
    fn backtracking_accepts_a_step_only_where_the_quadratic_model_bounds_the_energy() {
        // Along the top eigenvector v of S the smooth energy of the step x = r/L from 0
        // (r = v, no friction) lies below the model J(0) − |r|²/L + L|x|²/2 iff L ≥ λ_max: the
        // first accepted L of the doubling sequence 0.3 λ_max, 0.6 λ_max, 1.2 λ_max is 1.2 λ_max.
        let eigenvalues = [0.5, 1.0, 2.0, 3.0, 5.0, 8.0];
        let top = 8.0;
        let (matrix, vectors) = matrix_with_spectrum(&eigenvalues);
        let rhs = vectors[5].clone();
        let weights = vec![0.0; 6];
        let problem = Problem::new(matrix.as_ref(), &rhs, &weights, 1);
        let mut x = vec![0.0; 6];
        let mut sx = vec![0.0; 6];
        let mut energy = problem.energy(&x, &sx);
        let mut report = problem.kkt(&x, &sx);
        let mut lipschitz = Lipschitz {
            value: 0.3 * top,
            upper: problem.lipschitz().upper,
        };
        assert!(lipschitz.upper >= top);
        let steps = problem.gradient_burst(
            &mut x,
            &mut sx,
            &mut energy,
            &mut report,
            &mut lipschitz,
            1,
            0.0,
        );
        assert_eq!(steps, 1);
        assert!(
            (lipschitz.value - 1.2 * top).abs() <= 1e-12 * top,
            "accepted L = {} (λ_max = {top})",
            lipschitz.value
        );
        // the step x = r / L was taken: J decreased
        assert!(energy.value < 0.0);
        for (xi, ri) in x.iter().zip(&rhs) {
            assert!((xi - ri / lipschitz.value).abs() <= 1e-14);
        }
    }
}
