//! The manufactured data f0, f2, f3, q and κ∂β/∂ν (SPEC §4) as batched fields of the solver
//! ([`contact_damage::fields`]): the exact fields' derivatives come from the programs compiled
//! once per case ([`ExactPrograms`]), evaluated over the scheme's batches of quadrature
//! points; the chain rule through the laws is applied per point (the `*_at` / `*_of_*`
//! formulas of the parent module): f0 by one call per law and point of its stress divergence
//! (`stress_divergence`, closed forms for the built-in laws) on strain jets read straight from
//! the columns, q by one batch call of φ (`DamageSource::source_batch`).

use super::programs::{
    body_force_quantities, boundary_quantities, error_quantities, flux_quantities,
    supply_quantities, Columns, Quantity, QuantityProgram, BATCH,
};
use super::{
    body_force_of_strains, contact_traction_at, damage_flux_at, damage_supply_of_source,
    traction_at, DamageJet, ExactSolution, Laws, PointState, StrainJet,
};
use contact_damage::fields::{
    BatchBoundaryScalarField, BatchBoundaryVectorField, BatchScalarField, BatchVectorField,
};
use contact_damage::laws::Tensor;
use nalgebra::{SMatrix, SVector};
use std::sync::Arc;

/// The compiled programs of one case (built once, shared by every run of its studies).
#[derive(Debug, Clone)]
pub struct ExactPrograms<const D: usize> {
    /// f0: first and second derivatives of u and u̇, β, ∇β.
    pub body_force: QuantityProgram<D>,
    /// f2, f3: u, u̇, ∇u, ∇u̇, β, ξ, g.
    pub boundary: QuantityProgram<D>,
    /// q: ∇u, β, β̇, Δβ, η.
    pub supply: QuantityProgram<D>,
    /// κ∂β/∂ν: ∇β.
    pub flux: QuantityProgram<D>,
    /// Error integrals: ∇u, ∇u̇, β, ∇β.
    pub errors: QuantityProgram<D>,
}

impl<const D: usize> ExactPrograms<D> {
    /// Differentiates and compiles the exact fields of `exact`.
    pub fn new(exact: &ExactSolution<D>) -> Self {
        Self {
            body_force: QuantityProgram::new(exact, &body_force_quantities::<D>()),
            boundary: QuantityProgram::new(exact, &boundary_quantities::<D>()),
            supply: QuantityProgram::new(exact, &supply_quantities::<D>()),
            flux: QuantityProgram::new(exact, &flux_quantities::<D>()),
            errors: QuantityProgram::new(exact, &error_quantities::<D>()),
        }
    }
}

/// The columns of a D×D matrix quantity, `at(i, j)`.
fn matrix_columns<'a, const D: usize>(
    columns: &'a Columns<'_, D>,
    at: impl Fn(usize, usize) -> Quantity,
) -> [[&'a [f64]; D]; D] {
    std::array::from_fn(|i| std::array::from_fn(|j| columns.get(at(i, j))))
}

/// Point p of matrix columns.
fn matrix_at<const D: usize>(columns: &[[&[f64]; D]; D], p: usize) -> SMatrix<f64, D, D> {
    SMatrix::<f64, D, D>::from_fn(|i, j| columns[i][j][p])
}

/// Point p of the symmetric part of matrix columns, (m + mᵀ)/2 (entry by entry as
/// `manufactured::symmetric`).
fn symmetric_at<const D: usize>(columns: &[[&[f64]; D]; D], p: usize) -> Tensor<D> {
    Tensor::<D>::from_fn(|i, j| (columns[i][j][p] + columns[j][i][p]) * 0.5)
}

/// The columns of ∂_j ∇w for j < D (`at(i, k, j)` = ∂²w_i/∂x_k∂x_j), by j.
fn second_columns<'a, const D: usize>(
    columns: &'a Columns<'_, D>,
    at: impl Fn(usize, usize, usize) -> Quantity,
) -> [[[&'a [f64]; D]; D]; D] {
    std::array::from_fn(|j| matrix_columns(columns, |i, k| at(i, k, j)))
}

/// Point p of vector columns.
fn vector_at<const D: usize>(columns: &[&[f64]; D], p: usize) -> SVector<f64, D> {
    SVector::<f64, D>::from_fn(|i, _| columns[i][p])
}

/// The [`PointState`]s of one batch for the boundary data, `each(p, state)`: u, u̇, ∇u, ∇u̇, β
/// (the second derivatives and ∇β, which only f0 needs, are 0; f0 reads its columns directly).
fn point_states<const D: usize>(
    columns: &Columns<'_, D>,
    count: usize,
    mut each: impl FnMut(usize, &PointState<D>),
) {
    let gradient = matrix_columns(columns, Quantity::Gradient);
    let rate_gradient = matrix_columns(columns, Quantity::RateGradient);
    let u: [&[f64]; D] = std::array::from_fn(|i| columns.get(Quantity::U(i)));
    let rate: [&[f64]; D] = std::array::from_fn(|i| columns.get(Quantity::Rate(i)));
    let damage = columns.get(Quantity::Damage);
    let zero = SMatrix::<f64, D, D>::zeros();
    for (p, &beta) in damage.iter().enumerate().take(count) {
        let state = PointState {
            displacement: vector_at(&u, p),
            velocity: vector_at(&rate, p),
            displacement_gradient: matrix_at(&gradient, p),
            velocity_gradient: matrix_at(&rate_gradient, p),
            displacement_second: [zero; D],
            velocity_second: [zero; D],
            damage: beta,
            damage_gradient: SVector::zeros(),
        };
        each(p, &state);
    }
}

/// f0, f2, f3, q and the damage flux of one case with its laws, as solver fields.
pub struct ManufacturedData<const D: usize> {
    programs: Arc<ExactPrograms<D>>,
    laws: Laws<D>,
}

impl<const D: usize> ManufacturedData<D> {
    /// The data of `programs` with `laws`.
    pub fn new(programs: Arc<ExactPrograms<D>>, laws: Laws<D>) -> Arc<Self> {
        Arc::new(Self { programs, laws })
    }
}

/// f0 = −Div σ.
pub struct BodyForce<const D: usize>(pub Arc<ManufacturedData<D>>);
/// f2 = σν on Γ2.
pub struct Traction<const D: usize>(pub Arc<ManufacturedData<D>>);
/// f3 = σν + p_ν ν + p_τ ξ̂ on Γ3.
pub struct ContactTraction<const D: usize>(pub Arc<ManufacturedData<D>>);
/// q = β̇ − κΔβ + η − φ.
pub struct DamageSupply<const D: usize>(pub Arc<ManufacturedData<D>>);
/// κ∂β/∂ν on Γ.
pub struct DamageFlux<const D: usize>(pub Arc<ManufacturedData<D>>);

impl<const D: usize> BatchVectorField<D> for BodyForce<D> {
    fn evaluate(&self, points: &[[f64; D]], time: f64, out: &mut [[f64; D]]) {
        let data = &self.0;
        data.programs
            .body_force
            .for_batches(points, time, |offset, columns| {
                // Straight from the columns to the strain jets (no point state per point).
                let count = points[offset..].len().min(BATCH);
                let gradient = matrix_columns(columns, Quantity::Gradient);
                let rate_gradient = matrix_columns(columns, Quantity::RateGradient);
                let second = second_columns(columns, Quantity::Hessian);
                let rate_second = second_columns(columns, Quantity::RateHessian);
                let damage = columns.get(Quantity::Damage);
                let damage_gradient: [&[f64]; D] =
                    std::array::from_fn(|j| columns.get(Quantity::DamageGradient(j)));
                // Jets filled in place point after point (building them anew per point costs
                // a copy of D tensors each).
                let empty = || StrainJet {
                    strain: Tensor::<D>::zeros(),
                    derivatives: [Tensor::<D>::zeros(); D],
                };
                let (mut rate, mut strain) = (empty(), empty());
                for (p, value) in out[offset..offset + count].iter_mut().enumerate() {
                    rate.strain = symmetric_at(&rate_gradient, p);
                    strain.strain = symmetric_at(&gradient, p);
                    for j in 0..D {
                        rate.derivatives[j] = symmetric_at(&rate_second[j], p);
                        strain.derivatives[j] = symmetric_at(&second[j], p);
                    }
                    *value = body_force_of_strains(
                        &data.laws,
                        &rate,
                        &strain,
                        damage[p],
                        &vector_at(&damage_gradient, p),
                    );
                }
            });
    }
}

impl<const D: usize> BatchBoundaryVectorField<D> for Traction<D> {
    fn evaluate(&self, points: &[[f64; D]], normals: &[[f64; D]], time: f64, out: &mut [[f64; D]]) {
        let data = &self.0;
        data.programs
            .boundary
            .for_batches(points, time, |offset, columns| {
                let count = points[offset..].len().min(BATCH);
                point_states(columns, count, |p, state| {
                    out[offset + p] = traction_at(&data.laws, state, &normals[offset + p]);
                });
            });
    }
}

impl<const D: usize> BatchBoundaryVectorField<D> for ContactTraction<D> {
    fn evaluate(&self, points: &[[f64; D]], normals: &[[f64; D]], time: f64, out: &mut [[f64; D]]) {
        let data = &self.0;
        data.programs
            .boundary
            .for_batches(points, time, |offset, columns| {
                let count = points[offset..].len().min(BATCH);
                let xi: [&[f64]; D] =
                    std::array::from_fn(|i| columns.get(Quantity::StickTraction(i)));
                let gap = columns.get(Quantity::Gap);
                point_states(columns, count, |p, state| {
                    out[offset + p] = contact_traction_at(
                        &data.laws,
                        state,
                        &vector_at(&xi, p),
                        gap[p],
                        &normals[offset + p],
                    );
                });
            });
    }
}

impl<const D: usize> BatchScalarField<D> for DamageSupply<D> {
    fn evaluate(&self, points: &[[f64; D]], time: f64, out: &mut [f64]) {
        let data = &self.0;
        data.programs
            .supply
            .for_batches(points, time, |offset, columns| {
                let count = points[offset..].len().min(BATCH);
                let gradient = matrix_columns(columns, Quantity::Gradient);
                let beta = &columns.get(Quantity::Damage)[..count];
                let rate = columns.get(Quantity::DamageRate);
                let laplacian = columns.get(Quantity::DamageLaplacian);
                let multiplier = columns.get(Quantity::Multiplier);
                // φ(ε(u), β) over the batch in one call of the law.
                let mut strains = [Tensor::<D>::zeros(); BATCH];
                for (p, strain) in strains[..count].iter_mut().enumerate() {
                    *strain = symmetric_at(&gradient, p);
                }
                let mut sources = [0.0; BATCH];
                data.laws.damage_source.source_batch(
                    &strains[..count],
                    beta,
                    &mut sources[..count],
                );
                for (p, value) in out[offset..offset + count].iter_mut().enumerate() {
                    let jet = DamageJet {
                        value: beta[p],
                        rate: rate[p],
                        laplacian: laplacian[p],
                        multiplier: multiplier[p],
                    };
                    *value = damage_supply_of_source(&data.laws, &jet, sources[p]);
                }
            });
    }
}

impl<const D: usize> BatchBoundaryScalarField<D> for DamageFlux<D> {
    fn evaluate(&self, points: &[[f64; D]], normals: &[[f64; D]], time: f64, out: &mut [f64]) {
        let data = &self.0;
        data.programs
            .flux
            .for_batches(points, time, |offset, columns| {
                let count = points[offset..].len().min(BATCH);
                let gradient: [&[f64]; D] =
                    std::array::from_fn(|j| columns.get(Quantity::DamageGradient(j)));
                for p in 0..count {
                    out[offset + p] =
                        damage_flux_at(&data.laws, &vector_at(&gradient, p), &normals[offset + p]);
                }
            });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::{parse_case_file, Case};
    use crate::cli::BUILT_IN_CASES;

    /// |a − b| ≤ 1e-12 (1 + |b|) componentwise.
    fn close(what: &str, a: &[f64], b: &[f64]) {
        for (x, y) in a.iter().zip(b) {
            assert!(
                (x - y).abs() <= 1e-12 * (1.0 + y.abs()),
                "{what}: {a:?} vs {b:?}"
            );
        }
    }

    /// The batched data (compiled symbolic derivatives) against the tree evaluation on nested
    /// duals, point by point, for every built-in case of dimension D.
    fn batched_data_match_the_tree<const D: usize>() {
        let mut checked = 0;
        for (name, text) in BUILT_IN_CASES {
            let origin = format!("built-in:{name}");
            let file = parse_case_file(text, &origin).unwrap();
            if file.dim != D {
                continue;
            }
            let case = Case::<D>::new(file, &origin).unwrap();
            let data = ManufacturedData::new(case.programs.clone(), case.laws.clone());
            // 300 points (more than two batches), spread over the box by a fixed sequence.
            let points: Vec<[f64; D]> = (0..300)
                .map(|p| std::array::from_fn(|i| ((p * (7 + 4 * i) + 3 * i) % 97) as f64 / 96.0))
                .collect();
            let normals: Vec<[f64; D]> = (0..300)
                .map(|p| std::array::from_fn(|i| if i == p % D { -1.0 } else { 0.0 }))
                .collect();
            for t in [0.0, 0.37, 1.0] {
                let mut vectors = vec![[0.0; D]; points.len()];
                let mut scalars = vec![0.0; points.len()];
                BodyForce(data.clone()).evaluate(&points, t, &mut vectors);
                for (x, f) in points.iter().zip(&vectors) {
                    close(name, f, &case.exact.body_force(&case.laws, x, t));
                }
                Traction(data.clone()).evaluate(&points, &normals, t, &mut vectors);
                for ((x, n), f) in points.iter().zip(&normals).zip(&vectors) {
                    close(name, f, &case.exact.traction(&case.laws, x, t, n));
                }
                ContactTraction(data.clone()).evaluate(&points, &normals, t, &mut vectors);
                for ((x, n), f) in points.iter().zip(&normals).zip(&vectors) {
                    close(name, f, &case.exact.contact_traction(&case.laws, x, t, n));
                }
                DamageSupply(data.clone()).evaluate(&points, t, &mut scalars);
                for (x, q) in points.iter().zip(&scalars) {
                    close(name, &[*q], &[case.exact.damage_supply(&case.laws, x, t)]);
                }
                DamageFlux(data.clone()).evaluate(&points, &normals, t, &mut scalars);
                for ((x, n), q) in points.iter().zip(&normals).zip(&scalars) {
                    close(name, &[*q], &[case.exact.damage_flux(&case.laws, x, t, n)]);
                }
            }
            checked += 1;
        }
        assert!(
            checked >= 4,
            "only {checked} built-in cases of dimension {D}"
        );
    }

    #[test]
    fn batched_data_match_the_tree_in_2d() {
        batched_data_match_the_tree::<2>();
    }

    #[test]
    fn batched_data_match_the_tree_in_3d() {
        batched_data_match_the_tree::<3>();
    }
}
