//! The weighted squared differences of a batch of quadrature points against the exact
//! solution, column by column: each quantity of the batch is computed for all its points in
//! one loop over columns of [`BATCH`] values, which the compiler vectorizes (four points per
//! instruction with AVX2), and the differences are then added to the sums point after point.
//! Each point gets exactly the operations of `super::accumulate_parts` in the same order (the
//! symmetric parts, the difference quotient, and the Frobenius norms column after column as
//! `nalgebra` forms them), so the sums are bitwise those of the point-by-point evaluation.

use super::CellFields;
use crate::manufactured::programs::BATCH;

/// The exact fields at the points of one batch at one time t_n: columns of `count` values of
/// the error program's outputs.
#[derive(Clone, Copy)]
pub(super) struct ExactColumns<'a, const D: usize> {
    /// ∂u_i/∂x_j.
    pub gradient: [[&'a [f64]; D]; D],
    /// ∂u̇_i/∂x_j.
    pub rate_gradient: [[&'a [f64]; D]; D],
    /// β.
    pub damage: &'a [f64],
    /// ∂β/∂x_j.
    pub damage_gradient: [&'a [f64]; D],
}

/// The discrete solution at the points of one batch, as columns: entry (i, j) of ε(u_h) is
/// `strain[i][j][p]` at point p.
pub(super) struct DiscreteColumns<const D: usize> {
    pub strain: [[[f64; BATCH]; D]; D],
    /// ε(v_n).
    pub rate: [[[f64; BATCH]; D]; D],
    pub damage_gradient: [[f64; BATCH]; D],
}

impl<const D: usize> DiscreteColumns<D> {
    pub fn new() -> Self {
        Self {
            strain: [[[0.0; BATCH]; D]; D],
            rate: [[[0.0; BATCH]; D]; D],
            damage_gradient: [[0.0; BATCH]; D],
        }
    }

    /// The points `points` of the batch take the discrete fields `fields` (the points of one
    /// cell where the fields are constant on it, or one point).
    #[inline(always)]
    pub fn set(&mut self, points: std::ops::Range<usize>, fields: &CellFields<D>) {
        for i in 0..D {
            for j in 0..D {
                self.strain[i][j][points.clone()].fill(fields.strain[(i, j)]);
                self.rate[i][j][points.clone()].fill(fields.rate[(i, j)]);
            }
            self.damage_gradient[i][points.clone()].fill(fields.damage_gradient[i]);
        }
    }
}

/// The columns of a symmetric tensor field at the points of a batch.
pub(super) type TensorColumns<const D: usize> = [[[f64; BATCH]; D]; D];

/// The five weighted squared differences of each point of a batch, by component (a buffer
/// reused from batch to batch: every value read is written first).
pub(super) type Terms = [[f64; BATCH]; 5];

/// One batch of points at one time t_n: the exact and the discrete fields there, and the
/// batch's `count` weights and values of β_n^hk.
pub(super) struct Batch<'a, const D: usize> {
    pub count: usize,
    pub exact: ExactColumns<'a, D>,
    pub discrete: &'a DiscreteColumns<D>,
    /// Quadrature weight × |det J|.
    pub weights: &'a [f64],
    /// β_n^hk.
    pub damage_h: &'a [f64],
    /// k, for the difference quotient.
    pub time_step: f64,
}

/// Adds the weighted squared differences [u, δu, β, ∇β, v] of the points of `batch` to
/// `local`, in point order, and replaces `previous` (ε(u(t_{n−1})) at the points) by
/// ε(u(t_n)); `terms` is scratch.
pub(super) fn accumulate_batch<const D: usize>(
    local: &mut [f64; 5],
    batch: &Batch<'_, D>,
    previous: &mut TensorColumns<D>,
    terms: &mut Terms,
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the processor has AVX2.
        unsafe { batch_terms_avx2(batch, previous, terms) };
        add_in_point_order(local, terms, batch.count);
        return;
    }
    batch_terms(batch, previous, terms);
    add_in_point_order(local, terms, batch.count);
}

/// Each component's sum in point order, as the point-by-point evaluation adds them (the five
/// sums are independent, so they are added side by side: five chains of additions that run
/// at once, not one after the other).
fn add_in_point_order(local: &mut [f64; 5], terms: &Terms, count: usize) {
    let [t0, t1, t2, t3, t4] = terms.each_ref().map(|column| &column[..count]);
    for p in 0..count {
        local[0] += t0[p];
        local[1] += t1[p];
        local[2] += t2[p];
        local[3] += t3[p];
        local[4] += t4[p];
    }
}

/// [`batch_terms`] compiled for AVX2: the same operations lane by lane (Rust never contracts
/// `a * b + c` into a fused multiply–add), so bitwise the same values.
///
/// # Safety
/// The processor must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn batch_terms_avx2<const D: usize>(
    batch: &Batch<'_, D>,
    previous: &mut TensorColumns<D>,
    terms: &mut Terms,
) {
    batch_terms(batch, previous, terms)
}

/// The squared Frobenius norm of a D × D matrix given by its entries, as `nalgebra` forms it:
/// 0 plus the columns' sums of squares in column order, each summed down the column.
#[inline(always)]
fn frobenius_squared<const D: usize>(entry: impl Fn(usize, usize) -> f64) -> f64 {
    let mut norm = 0.0;
    for j in 0..D {
        norm += euclidean_squared::<D>(|i| entry(i, j));
    }
    norm
}

/// The dot product of a D-vector with itself, as `nalgebra` forms it for D = 2 and 3:
/// ((a₀² + a₁²) + a₂²).
#[inline(always)]
fn euclidean_squared<const D: usize>(entry: impl Fn(usize) -> f64) -> f64 {
    let mut sum = entry(0) * entry(0);
    for i in 1..D {
        sum += entry(i) * entry(i);
    }
    sum
}

/// The five weighted squared differences of each point of the batch into `terms`.
#[inline(always)]
fn batch_terms<const D: usize>(
    batch: &Batch<'_, D>,
    previous: &mut TensorColumns<D>,
    terms: &mut Terms,
) {
    let (count, exact, discrete, k) = (batch.count, &batch.exact, batch.discrete, batch.time_step);
    // Every column cut to `count` values, so that the loop below needs no bounds checks.
    let gradient = exact.gradient.map(|row| row.map(|column| &column[..count]));
    let rate_gradient = exact
        .rate_gradient
        .map(|row| row.map(|column| &column[..count]));
    let damage = &exact.damage[..count];
    let damage_gradient = exact.damage_gradient.map(|column| &column[..count]);
    let (weights, damage_h) = (&batch.weights[..count], &batch.damage_h[..count]);
    for p in 0..count {
        // ε(u(t_n)) and ε(u̇(t_n)): sym(m) = (m + mᵀ)·½ entry by entry.
        let strain: [[f64; D]; D] = std::array::from_fn(|i| {
            std::array::from_fn(|j| (gradient[i][j][p] + gradient[j][i][p]) * 0.5)
        });
        let rate: [[f64; D]; D] = std::array::from_fn(|i| {
            std::array::from_fn(|j| (rate_gradient[i][j][p] + rate_gradient[j][i][p]) * 0.5)
        });
        let weight = weights[p];
        terms[0][p] =
            weight * frobenius_squared::<D>(|i, j| strain[i][j] - discrete.strain[i][j][p]);
        terms[1][p] = weight
            * frobenius_squared::<D>(|i, j| {
                (strain[i][j] - previous[i][j][p]) / k - discrete.rate[i][j][p]
            });
        terms[2][p] = weight * (damage[p] - damage_h[p]).powi(2);
        terms[3][p] = weight
            * euclidean_squared::<D>(|j| damage_gradient[j][p] - discrete.damage_gradient[j][p]);
        terms[4][p] = weight * frobenius_squared::<D>(|i, j| rate[i][j] - discrete.rate[i][j][p]);
        for (i, row) in strain.iter().enumerate() {
            for (j, &value) in row.iter().enumerate() {
                previous[i][j][p] = value;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{accumulate_parts, sym, ReferencePoint};
    use super::*;
    use contact_damage::model::laws::Tensor;
    use nalgebra::{SMatrix, SVector};
    use proptest::prelude::*;

    /// One batch of random exact columns, discrete fields, weights, β_h, previous strains, k
    /// and starting sums.
    #[derive(Debug, Clone)]
    struct RandomBatch {
        count: usize,
        /// 2 · D² + 1 + D exact columns.
        exact: Vec<Vec<f64>>,
        /// Per point: ε(u_h) (D²), ε(v_h) (D²), ∇β_h (D).
        discrete: Vec<Vec<f64>>,
        weights: Vec<f64>,
        damage_h: Vec<f64>,
        previous: Vec<Vec<f64>>,
        k: f64,
        local: [f64; 5],
    }

    fn batch(dim: usize) -> impl Strategy<Value = RandomBatch> {
        (1..=BATCH).prop_flat_map(move |count| {
            let value = -10.0..10.0f64;
            let columns = |n: usize| {
                proptest::collection::vec(proptest::collection::vec(value.clone(), count), n)
            };
            (
                columns(2 * dim * dim + 1 + dim),
                proptest::collection::vec(
                    proptest::collection::vec(value.clone(), 2 * dim * dim + dim),
                    count,
                ),
                proptest::collection::vec(0.0..1.0f64, count),
                proptest::collection::vec(value.clone(), count),
                proptest::collection::vec(
                    proptest::collection::vec(value.clone(), dim * dim),
                    count,
                ),
                1e-3..1.0f64,
                proptest::array::uniform5(0.0..1.0f64),
            )
                .prop_map(
                    move |(exact, discrete, weights, damage_h, previous, k, local)| RandomBatch {
                        count,
                        exact,
                        discrete,
                        weights,
                        damage_h,
                        previous,
                        k,
                        local,
                    },
                )
        })
    }

    /// The sums and the new previous strains by the batch kernel and, point by point, by
    /// `accumulate_parts`, as bits.
    fn both<const D: usize>(batch: &RandomBatch) -> [(Vec<u64>, Vec<u64>); 2] {
        let (count, dd) = (batch.count, D * D);
        let column = |c: usize| &batch.exact[c][..];
        let exact = ExactColumns::<D> {
            gradient: std::array::from_fn(|i| std::array::from_fn(|j| column(i * D + j))),
            rate_gradient: std::array::from_fn(|i| std::array::from_fn(|j| column(dd + i * D + j))),
            damage: column(2 * dd),
            damage_gradient: std::array::from_fn(|j| column(2 * dd + 1 + j)),
        };
        let fields: Vec<CellFields<D>> = batch
            .discrete
            .iter()
            .map(|values| CellFields {
                strain: sym(&SMatrix::from_fn(|i, j| values[i * D + j])),
                rate: sym(&SMatrix::from_fn(|i, j| values[dd + i * D + j])),
                damage_gradient: SVector::from_fn(|j, _| values[2 * dd + j]),
            })
            .collect();
        let before: Vec<Tensor<D>> = batch
            .previous
            .iter()
            .map(|values| sym(&SMatrix::from_fn(|i, j| values[i * D + j])))
            .collect();
        // The kernel.
        let mut discrete = DiscreteColumns::<D>::new();
        let mut previous: TensorColumns<D> = [[[0.0; BATCH]; D]; D];
        for p in 0..count {
            discrete.set(p..p + 1, &fields[p]);
            for i in 0..D {
                for j in 0..D {
                    previous[i][j][p] = before[p][(i, j)];
                }
            }
        }
        let mut local = batch.local;
        accumulate_batch(
            &mut local,
            &Batch {
                count,
                exact,
                discrete: &discrete,
                weights: &batch.weights,
                damage_h: &batch.damage_h,
                time_step: batch.k,
            },
            &mut previous,
            &mut [[0.0; BATCH]; 5],
        );
        let kernel_strains = (0..count)
            .flat_map(|p| (0..dd).map(move |e| (p, e)))
            .map(|(p, e)| previous[e / D][e % D][p].to_bits())
            .collect();
        // Point by point.
        let mut expected = batch.local;
        let mut strains = Vec::new();
        for p in 0..count {
            let strain = sym(&SMatrix::<f64, D, D>::from_fn(|i, j| {
                exact.gradient[i][j][p]
            }));
            let reference = ReferencePoint {
                strain,
                quotient: (strain - before[p]) / batch.k,
                rate: Some(sym(&SMatrix::<f64, D, D>::from_fn(|i, j| {
                    exact.rate_gradient[i][j][p]
                }))),
                damage: exact.damage[p],
                damage_gradient: SVector::<f64, D>::from_fn(|j, _| exact.damage_gradient[j][p]),
            };
            accumulate_parts(
                &mut expected,
                batch.weights[p],
                &fields[p],
                batch.damage_h[p],
                &reference,
            );
            strains.extend(strain.transpose().iter().map(|value| value.to_bits()));
        }
        [
            (local.map(f64::to_bits).to_vec(), kernel_strains),
            (expected.map(f64::to_bits).to_vec(), strains),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        #[test]
        fn batched_error_sums_are_bitwise_those_point_by_point_in_2d(batch in batch(2)) {
            let [kernel, pointwise] = both::<2>(&batch);
            prop_assert_eq!(kernel, pointwise);
        }

        #[test]
        fn batched_error_sums_are_bitwise_those_point_by_point_in_3d(batch in batch(3)) {
            let [kernel, pointwise] = both::<3>(&batch);
            prop_assert_eq!(kernel, pointwise);
        }
    }
}
