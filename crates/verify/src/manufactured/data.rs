//! The manufactured data f0, f2, f3, q and κ∂β/∂ν (docs/model.md §5) as batched fields of the
//! solver ([`contact_damage::model::fields`]): the exact fields' derivatives come from the programs
//! compiled once per case ([`ExactPrograms`]), evaluated over the scheme's batches of quadrature
//! points; the chain rule through the laws is applied per point (the `*_at` / `*_of_*`
//! formulas of the parent module): f0 by one call per law and batch of its stress divergence
//! straight from the program's output columns (`stress_divergence_of_jets`, the laws'
//! closed forms inlined there), q by one batch call of φ (`DamageSource::source_batch`). f0
//! and q, which the solver evaluates at the same points one after the other, come from one
//! program (see [`ManufacturedData`]).

use super::programs::{
    boundary_quantities, bulk_quantities, error_quantities, flux_quantities, supply_quantities,
    Columns, Quantity, QuantityProgram, BATCH,
};
use super::{
    contact_load_at, contact_traction_at, damage_flux_at, damage_supply_of_source, stress_at,
    traction_at, DamageJet, ExactSolution, Laws, PointState,
};
use contact_damage::model::fields::{
    BatchBoundaryScalarField, BatchBoundaryVectorField, BatchScalarField, BatchTensorField,
    BatchVectorField,
};
use contact_damage::model::laws::{FieldJets, Tensor};
use nalgebra::{SMatrix, SVector};
use std::cell::RefCell;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// The compiled programs of one case (built once, shared by every run of its studies).
#[derive(Debug, Clone)]
pub struct ExactPrograms<const D: usize> {
    /// f0 and q at once: first and second derivatives of u and u̇, β, ∇β, β̇, Δβ, η.
    pub bulk: QuantityProgram<D>,
    /// f2, f3: u, u̇, ∇u, ∇u̇, β, ξ, g.
    pub boundary: QuantityProgram<D>,
    /// q alone (where f0 was not just evaluated at the same points): ∇u, β, β̇, Δβ, η.
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
            bulk: QuantityProgram::new(exact, &bulk_quantities::<D>()),
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
///
/// f0 and q come from one program ([`ExactPrograms::bulk`]): the solver's load assembly
/// evaluates f0, then q, at the same points of a chunk on the same thread, so [`BodyForce`]
/// computes both and hands q over to this thread's next [`DamageSupply`] evaluation, which
/// takes it if it comes from the same data for the same time and the same points (compared
/// bit for bit); otherwise q is evaluated by its own program ([`ExactPrograms::supply`]).
/// Both ways give bitwise the same q (the same instructions on the same operands).
pub struct ManufacturedData<const D: usize> {
    programs: Arc<ExactPrograms<D>>,
    laws: Laws<D>,
    /// Names this data in a hand-over (unique per process).
    id: u64,
}

impl<const D: usize> ManufacturedData<D> {
    /// The data of `programs` with `laws`.
    pub fn new(programs: Arc<ExactPrograms<D>>, laws: Laws<D>) -> Arc<Self> {
        static NEXT_ID: AtomicU64 = AtomicU64::new(0);
        Arc::new(Self {
            programs,
            laws,
            id: NEXT_ID.fetch_add(1, Ordering::Relaxed),
        })
    }
}

/// q at the points of the last f0 evaluation on this thread (see [`ManufacturedData`]).
#[derive(Default)]
struct SupplyHandOver {
    /// [`ManufacturedData::id`], or None when empty.
    data: Option<u64>,
    /// The times, as bits.
    times: Vec<u64>,
    /// The coordinates, bit for bit.
    points: Vec<u64>,
    /// q at the points for each time, time-major.
    supply: Vec<f64>,
}

/// Step times per evaluation of f0 and q ([`BatchVectorField::times_per_evaluation`]): the
/// scheme then evaluates them ahead for this many steps, and the time-independent values
/// of the bulk program (28 per point in 2D) are read from memory once for all of them.
/// Measured over 196 608 points of `zones2d` (the 128-cell level), one thread: 52 ns per
/// point and time with one time per call, 41 with 2, 30 with 4, 27 with 8, 25 with 16 (the
/// rate of 16 384 points, whose values stay in the cache, is 25–27 ns). 16, as
/// [`crate::error_norms::STATES_PER_BLOCK`] (measured there); the solver caps a block at
/// [`contact_damage::scheme::loads::BULK_DATA_BYTES`] (14 times at 128 cells).
pub const TIMES_PER_EVALUATION: usize = 16;

thread_local! {
    static SUPPLY_HAND_OVER: RefCell<SupplyHandOver> = RefCell::new(SupplyHandOver::default());
}

/// The coordinates of `points` as bits.
fn coordinate_bits<const D: usize>(points: &[[f64; D]]) -> impl Iterator<Item = u64> + '_ {
    points.iter().flatten().map(|x| x.to_bits())
}

/// q at one batch of the columns of [`ExactPrograms::bulk`] or [`ExactPrograms::supply`]:
/// φ(ε(u), β) by one call of the law, then q = β̇ − κΔβ + η − φ.
fn supply_batch<const D: usize>(laws: &Laws<D>, columns: &Columns<'_, D>, out: &mut [f64]) {
    let gradient = matrix_columns(columns, Quantity::Gradient);
    let mut strains = [Tensor::<D>::zeros(); BATCH];
    for (p, strain) in strains[..out.len()].iter_mut().enumerate() {
        *strain = symmetric_at(&gradient, p);
    }
    supply_of_strains(laws, columns, &strains[..out.len()], out);
}

/// [`supply_batch`] with the strains ε(u) of the batch already computed (by f0).
fn supply_of_strains<const D: usize>(
    laws: &Laws<D>,
    columns: &Columns<'_, D>,
    strains: &[Tensor<D>],
    out: &mut [f64],
) {
    let count = out.len();
    let beta = &columns.get(Quantity::Damage)[..count];
    let rate = columns.get(Quantity::DamageRate);
    let laplacian = columns.get(Quantity::DamageLaplacian);
    let multiplier = columns.get(Quantity::Multiplier);
    let mut sources = [0.0; BATCH];
    laws.damage_source
        .source_batch(strains, beta, &mut sources[..count]);
    for (p, value) in out.iter_mut().enumerate() {
        let jet = DamageJet {
            value: beta[p],
            rate: rate[p],
            laplacian: laplacian[p],
            multiplier: multiplier[p],
        };
        *value = damage_supply_of_source(laws, &jet, sources[p]);
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
        self.evaluate_at_times(points, &[time], out)
    }

    fn evaluate_at_times(&self, points: &[[f64; D]], times: &[f64], out: &mut [[f64; D]]) {
        let data = &self.0;
        let n = points.len();
        let mut supply = vec![0.0; n * times.len()];
        // The strains of a batch (for q) and the two divergences, by component.
        let mut strains = [Tensor::<D>::zeros(); BATCH];
        let mut viscous = [[0.0; BATCH]; D];
        let mut elastic = [[0.0; BATCH]; D];
        data.programs
            .bulk
            .for_batches_at_times(points, times, |offset, at, columns| {
                let count = points[offset..].len().min(BATCH);
                let velocity = FieldJets {
                    gradient: matrix_columns(columns, Quantity::RateGradient),
                    second: second_columns(columns, Quantity::RateHessian),
                };
                let displacement = FieldJets {
                    gradient: matrix_columns(columns, Quantity::Gradient),
                    second: second_columns(columns, Quantity::Hessian),
                };
                let damage_gradient: [&[f64]; D] =
                    std::array::from_fn(|j| columns.get(Quantity::DamageGradient(j)));
                // One call per law for the whole batch, straight from the columns (the
                // laws' per-point closed forms inlined there).
                data.laws.viscosity.stress_divergence_of_jets(
                    &velocity,
                    &mut viscous.each_mut().map(|column| &mut column[..count]),
                );
                data.laws.elasticity.stress_divergence_of_jets(
                    &displacement,
                    columns.get(Quantity::Damage),
                    &damage_gradient,
                    &mut elastic.each_mut().map(|column| &mut column[..count]),
                );
                let batch = at * n + offset..at * n + offset + count;
                for (p, value) in out[batch.clone()].iter_mut().enumerate() {
                    // f0 = −Div σ, as `manufactured::body_force_of_strains`.
                    *value = std::array::from_fn(|i| -(viscous[i][p] + elastic[i][p]));
                }
                for (p, strain) in strains[..count].iter_mut().enumerate() {
                    *strain = displacement.strain(p);
                }
                supply_of_strains(&data.laws, columns, &strains[..count], &mut supply[batch]);
            });
        SUPPLY_HAND_OVER.with_borrow_mut(|hand_over| {
            hand_over.data = Some(data.id);
            hand_over.times.clear();
            hand_over.times.extend(times.iter().map(|t| t.to_bits()));
            hand_over.points.clear();
            hand_over.points.extend(coordinate_bits(points));
            hand_over.supply = supply;
        });
    }

    fn times_per_evaluation(&self) -> usize {
        TIMES_PER_EVALUATION
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
        contact_batch(&self.0, points, normals, time, out, contact_traction_at);
    }
}

/// A datum of Γ3 at a point from the laws, the exact state, ξ, g and the outward normal.
type ContactDatum<const D: usize> =
    fn(&Laws<D>, &PointState<D>, &SVector<f64, D>, f64, &[f64; D]) -> [f64; D];

/// The quantity `at` (f3, or f3 − σν) at the points of Γ3 with their outward normals.
fn contact_batch<const D: usize>(
    data: &ManufacturedData<D>,
    points: &[[f64; D]],
    normals: &[[f64; D]],
    time: f64,
    out: &mut [[f64; D]],
    at: ContactDatum<D>,
) {
    data.programs
        .boundary
        .for_batches(points, time, |offset, columns| {
            let count = points[offset..].len().min(BATCH);
            let xi: [&[f64]; D] = std::array::from_fn(|i| columns.get(Quantity::StickTraction(i)));
            let gap = columns.get(Quantity::Gap);
            point_states(columns, count, |p, state| {
                out[offset + p] = at(
                    &data.laws,
                    state,
                    &vector_at(&xi, p),
                    gap[p],
                    &normals[offset + p],
                );
            });
        });
}

/// The exact stress σ = 𝒜ε(u̇) + G(ε(u), β) as the data's stress S (loads in stress form).
pub struct BodyStress<const D: usize>(pub Arc<ManufacturedData<D>>);
/// f3 − σν = p_ν ν + p_τ ξ̂ on Γ3 (loads in stress form).
pub struct ContactLoad<const D: usize>(pub Arc<ManufacturedData<D>>);

impl<const D: usize> BatchTensorField<D> for BodyStress<D> {
    fn evaluate(&self, points: &[[f64; D]], time: f64, out: &mut [SMatrix<f64, D, D>]) {
        let data = &self.0;
        data.programs
            .boundary
            .for_batches(points, time, |offset, columns| {
                let count = points[offset..].len().min(BATCH);
                point_states(columns, count, |p, state| {
                    out[offset + p] = stress_at(&data.laws, state);
                });
            });
    }
}

impl<const D: usize> BatchBoundaryVectorField<D> for ContactLoad<D> {
    fn evaluate(&self, points: &[[f64; D]], normals: &[[f64; D]], time: f64, out: &mut [[f64; D]]) {
        contact_batch(&self.0, points, normals, time, out, contact_load_at);
    }
}

impl<const D: usize> BatchScalarField<D> for DamageSupply<D> {
    fn evaluate(&self, points: &[[f64; D]], time: f64, out: &mut [f64]) {
        self.evaluate_at_times(points, &[time], out)
    }

    fn evaluate_at_times(&self, points: &[[f64; D]], times: &[f64], out: &mut [f64]) {
        let data = &self.0;
        let handed_over = SUPPLY_HAND_OVER.with_borrow_mut(|hand_over| {
            let same = hand_over.data == Some(data.id)
                && hand_over
                    .times
                    .iter()
                    .copied()
                    .eq(times.iter().map(|t| t.to_bits()))
                && hand_over.supply.len() == out.len()
                && hand_over.points.iter().copied().eq(coordinate_bits(points));
            if same {
                out.copy_from_slice(&hand_over.supply);
            }
            hand_over.data = None;
            same
        });
        if handed_over {
            return;
        }
        let n = points.len();
        data.programs
            .supply
            .for_batches_at_times(points, times, |offset, at, columns| {
                let count = points[offset..].len().min(BATCH);
                let batch = at * n + offset..at * n + offset + count;
                supply_batch(&data.laws, columns, &mut out[batch]);
            });
    }

    fn times_per_evaluation(&self) -> usize {
        TIMES_PER_EVALUATION
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
            // More than two batches, spread over the box by a fixed sequence.
            let points: Vec<[f64; D]> = (0..2 * BATCH + 44)
                .map(|p| std::array::from_fn(|i| ((p * (7 + 4 * i) + 3 * i) % 97) as f64 / 96.0))
                .collect();
            let normals: Vec<[f64; D]> = (0..2 * BATCH + 44)
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

    /// The built-in case `name`.
    fn built_in<const D: usize>(name: &str) -> Case<D> {
        let text = BUILT_IN_CASES
            .iter()
            .find(|(case, _)| *case == name)
            .unwrap()
            .1;
        Case::<D>::new(parse_case_file(text, name).unwrap(), name).unwrap()
    }

    /// q evaluated by itself at `points`, `t` (a fresh data object: nothing handed over).
    fn supply_alone<const D: usize>(case: &Case<D>, points: &[[f64; D]], t: f64) -> Vec<u64> {
        let data = ManufacturedData::new(case.programs.clone(), case.laws.clone());
        let mut q = vec![0.0; points.len()];
        DamageSupply(data).evaluate(points, t, &mut q);
        q.iter().map(|v| v.to_bits()).collect()
    }

    fn supply_hand_over_is_bitwise_and_only_for_the_same_points_and_time<const D: usize>(
        name: &str,
    ) {
        let case = built_in::<D>(name);
        let data = ManufacturedData::new(case.programs.clone(), case.laws.clone());
        let points: Vec<[f64; D]> = (0..100)
            .map(|p| std::array::from_fn(|i| ((p * (5 + 2 * i) + i) % 41) as f64 / 40.0))
            .collect();
        let mut moved = points.clone();
        moved[57][0] += 0.01;
        let mut forces = vec![[0.0; D]; points.len()];
        let mut q = vec![0.0; points.len()];
        let bits = |q: &[f64]| q.iter().map(|v| v.to_bits()).collect::<Vec<u64>>();
        let handed_over = || SUPPLY_HAND_OVER.with_borrow(|hand_over| hand_over.data);
        // Same data, points and time: q is taken from the f0 evaluation, bitwise its own value.
        BodyForce(data.clone()).evaluate(&points, 0.6, &mut forces);
        assert_eq!(handed_over(), Some(data.id));
        DamageSupply(data.clone()).evaluate(&points, 0.6, &mut q);
        assert_eq!(handed_over(), None, "the hand-over is taken once");
        assert_eq!(bits(&q), supply_alone(&case, &points, 0.6));
        // Another time, other points, or other data: evaluated anew.
        BodyForce(data.clone()).evaluate(&points, 0.6, &mut forces);
        DamageSupply(data.clone()).evaluate(&points, 0.7, &mut q);
        assert_eq!(bits(&q), supply_alone(&case, &points, 0.7));
        BodyForce(data.clone()).evaluate(&points, 0.6, &mut forces);
        DamageSupply(data.clone()).evaluate(&moved, 0.6, &mut q);
        assert_eq!(bits(&q), supply_alone(&case, &moved, 0.6));
        assert_ne!(bits(&q)[57], supply_alone(&case, &points, 0.6)[57]);
        let other = {
            let mut laws = case.laws.clone();
            laws.damage_diffusion *= 2.0;
            ManufacturedData::new(case.programs.clone(), laws)
        };
        BodyForce(data.clone()).evaluate(&points, 0.6, &mut forces);
        DamageSupply(other).evaluate(&points, 0.6, &mut q);
        assert_ne!(bits(&q), supply_alone(&case, &points, 0.6));
    }

    /// f0 and q at several times at once (as the scheme asks for them, [`TIMES_PER_EVALUATION`])
    /// are bitwise their values at each time alone, and q is handed over for the same times
    /// only.
    fn several_times_at_once_are_bitwise_each_time_alone<const D: usize>(name: &str) {
        let case = built_in::<D>(name);
        let data = ManufacturedData::new(case.programs.clone(), case.laws.clone());
        assert_eq!(
            BodyForce(data.clone()).times_per_evaluation(),
            TIMES_PER_EVALUATION
        );
        // Two full batches and a partial one.
        let points: Vec<[f64; D]> = (0..2 * BATCH + 6)
            .map(|p| std::array::from_fn(|i| ((p * (5 + 2 * i) + i) % 41) as f64 / 40.0))
            .collect();
        let times = [0.25, 0.5, 0.75, 1.0];
        let n = points.len();
        let bits = |q: &[f64]| q.iter().map(|v| v.to_bits()).collect::<Vec<u64>>();
        let mut forces = vec![[0.0; D]; n * times.len()];
        let mut q = vec![0.0; n * times.len()];
        BodyForce(data.clone()).evaluate_at_times(&points, &times, &mut forces);
        DamageSupply(data.clone()).evaluate_at_times(&points, &times, &mut q);
        for (at, &t) in times.iter().enumerate() {
            let mut alone = vec![[0.0; D]; n];
            BodyForce(data.clone()).evaluate(&points, t, &mut alone);
            assert_eq!(
                bits(forces[at * n..(at + 1) * n].as_flattened()),
                bits(alone.as_flattened()),
                "{name}: f0 at t = {t}"
            );
            assert_eq!(
                bits(&q[at * n..(at + 1) * n]),
                supply_alone(&case, &points, t),
                "{name}: q at t = {t}"
            );
        }
        // The hand-over of other times is not taken: q evaluated anew, bitwise the same.
        BodyForce(data.clone()).evaluate_at_times(&points, &times, &mut forces);
        let shifted = [0.5, 0.75, 1.0, 1.25];
        DamageSupply(data.clone()).evaluate_at_times(&points, &shifted, &mut q);
        for (at, &t) in shifted.iter().enumerate() {
            assert_eq!(
                bits(&q[at * n..(at + 1) * n]),
                supply_alone(&case, &points, t)
            );
        }
    }

    #[test]
    fn several_times_at_once_are_bitwise_each_time_alone_in_2d_and_3d() {
        several_times_at_once_are_bitwise_each_time_alone::<2>("zones2d");
        several_times_at_once_are_bitwise_each_time_alone::<3>("zones3d");
    }

    #[test]
    fn supply_hand_over_is_bitwise_and_only_for_the_same_points_and_time_in_2d() {
        supply_hand_over_is_bitwise_and_only_for_the_same_points_and_time::<2>("zones2d");
    }

    #[test]
    fn supply_hand_over_is_bitwise_and_only_for_the_same_points_and_time_in_3d() {
        supply_hand_over_is_bitwise_and_only_for_the_same_points_and_time::<3>("zones3d");
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
