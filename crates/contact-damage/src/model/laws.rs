//! Constitutive functions of the model (paper §2–3): the viscosity operator 𝒜, the
//! damage-dependent elasticity G, the damage source φ, and the contact functions p_ν, p_τ.
//!
//! Every law validates its parameters against the assumptions (3.4)–(3.7) of the theory, and an
//! error names the offending parameter.
//!
//! Besides the closed-form laws, two laws take user-written functions through small traits (the
//! verification harness implements them for expressions with automatic differentiation):
//! [`PotentialViscosity`], 𝒜 = ∂Φ/∂ε for a potential Φ(tr ε, |ε_D|) ([`InvariantPotential`]),
//! and [`ModuliElasticity`], G with moduli μ(β), λ(β) ([`DamageModuli`]). Their `validate` checks
//! (3.4), resp. the sign conditions of the moduli, at fixed samples.

mod contact;
mod damage_source;
mod elasticity;
mod potential_viscosity;
mod tensor;
mod viscosity;

pub use contact::{ContactLaw, NormalComplianceCoulomb};
pub use damage_source::{points_per_cell, DamageSource, DamageSourceFn, TruncatedFremond};
pub use elasticity::{DamageModuli, DamagedHooke, Elasticity, ModuliElasticity};
pub use potential_viscosity::{InvariantJet, InvariantPotential, PotentialViscosity};
pub use tensor::{FieldJets, Tensor};
pub use viscosity::{LinearViscosity, SaturatingViscosity, Viscosity};

#[cfg(test)]
mod tests {
    use super::potential_viscosity::{
        sampled_rate_directions, symmetric_basis, Invariants, SMALL_DEVIATOR,
    };
    use super::tensor::deviator;
    use super::*;
    use crate::error::{Error, Result};
    use nalgebra::SVector;
    use std::sync::Arc;

    fn sample_tensor() -> Tensor<3> {
        let a = Tensor::<3>::new(0.3, -0.2, 0.5, 0.1, 0.7, -0.4, 0.2, 0.6, -0.1);
        (a + a.transpose()) * 0.5
    }

    /// Φ = η n² + (η/d + ζ/2) t² + η₁ ε₀² (√(1 + n²/ε₀²) − 1): the potential of
    /// [`SaturatingViscosity`] in the invariants (|ε|² = n² + t²/d), derivatives by hand.
    struct SaturatingInvariants {
        law: SaturatingViscosity,
        dim: f64,
    }

    impl InvariantPotential for SaturatingInvariants {
        fn value(&self, t: f64, n: f64) -> f64 {
            self.jet(t, n).value
        }
        fn jet(&self, t: f64, n: f64) -> InvariantJet {
            let (eta, zeta) = (self.law.linear.shear, self.law.linear.bulk);
            let (extra, s2) = (self.law.extra_shear, self.law.rate_scale.powi(2));
            let volumetric = eta / self.dim + zeta / 2.0;
            let w = (1.0 + n * n / s2).sqrt();
            InvariantJet {
                value: eta * n * n + volumetric * t * t + extra * s2 * (w - 1.0),
                gradient: [2.0 * volumetric * t, 2.0 * eta * n + extra * n / w],
                hessian: [
                    [2.0 * volumetric, 0.0],
                    [0.0, 2.0 * eta + extra / (w * w * w)],
                ],
            }
        }
    }

    /// Φ = a n² + b t² + c s² (√(1 + (n² + t²)/s²) − 1): convex, couples t and n; tangent ≥
    /// min(2a, 2bd).
    struct Coupled {
        a: f64,
        b: f64,
        c: f64,
        s: f64,
    }

    impl InvariantPotential for Coupled {
        fn value(&self, t: f64, n: f64) -> f64 {
            self.jet(t, n).value
        }
        fn jet(&self, t: f64, n: f64) -> InvariantJet {
            let (a, b, c, s2) = (self.a, self.b, self.c, self.s * self.s);
            let w = (1.0 + (n * n + t * t) / s2).sqrt();
            let w3 = w * w * w;
            let cross = -c * t * n / (s2 * w3);
            InvariantJet {
                value: a * n * n + b * t * t + c * s2 * (w - 1.0),
                gradient: [2.0 * b * t + c * t / w, 2.0 * a * n + c * n / w],
                hessian: [
                    [2.0 * b + c / w - c * t * t / (s2 * w3), cross],
                    [cross, 2.0 * a + c / w - c * n * n / (s2 * w3)],
                ],
            }
        }
    }

    fn coupled() -> PotentialViscosity {
        PotentialViscosity::new(Arc::new(Coupled {
            a: 0.8,
            b: 0.3,
            c: 1.5,
            s: 0.2,
        }))
    }

    /// Φ = a n² + b t² + c n + e n⁴ + f exp(t) (with the derivatives of each term).
    #[derive(Clone, Copy, Default)]
    struct Polynomial {
        a: f64,
        b: f64,
        c: f64,
        e: f64,
        f: f64,
    }

    impl InvariantPotential for Polynomial {
        fn value(&self, t: f64, n: f64) -> f64 {
            self.jet(t, n).value
        }
        fn jet(&self, t: f64, n: f64) -> InvariantJet {
            let Polynomial { a, b, c, e, f } = *self;
            let exp = if f == 0.0 { 0.0 } else { f * t.exp() };
            InvariantJet {
                value: a * n * n + b * t * t + c * n + e * n.powi(4) + exp,
                gradient: [2.0 * b * t + exp, 2.0 * a * n + c + 4.0 * e * n.powi(3)],
                hessian: [[2.0 * b + exp, 0.0], [0.0, 2.0 * a + 12.0 * e * n * n]],
            }
        }
    }

    fn saturating_pair<const D: usize>() -> (SaturatingViscosity, PotentialViscosity) {
        let law = SaturatingViscosity {
            linear: LinearViscosity {
                shear: 1.0,
                bulk: 0.5,
            },
            extra_shear: 0.5,
            rate_scale: 0.2,
        };
        let potential =
            PotentialViscosity::new(Arc::new(SaturatingInvariants { law, dim: D as f64 }));
        (law, potential)
    }

    /// Strain rates with ε_D = 0, tiny and exactly zero |ε_D| (with and without a trace), and
    /// generic ones.
    fn strain_rates<const D: usize>() -> Vec<Tensor<D>> {
        let generic = Tensor::<D>::from_fn(|i, j| {
            let (a, b) = (i.min(j) as f64, i.max(j) as f64);
            0.4 - 0.3 * a + 0.25 * b + 0.1 * a * b
        });
        let unit_deviator = deviator(&generic) / deviator(&generic).norm();
        let identity = Tensor::<D>::identity();
        let mut rates = vec![
            Tensor::<D>::zeros(),
            identity * 0.7,
            identity * -2.0,
            generic,
            generic * 30.0,
            unit_deviator * 0.05,
        ];
        for n in [1e-6, 1e-9, 1e-12, 1e-15] {
            rates.push(unit_deviator * n);
            rates.push(identity * 0.6 + unit_deviator * n);
        }
        rates
    }

    fn directions<const D: usize>() -> Vec<Tensor<D>> {
        let mut directions = symmetric_basis::<D>();
        directions.push(Tensor::<D>::from_fn(|i, j| {
            0.2 + 0.3 * (i + j) as f64 - 0.1 * (i * j) as f64
        }));
        directions
    }

    fn assert_close<const D: usize>(what: &str, a: &Tensor<D>, b: &Tensor<D>, tolerance: f64) {
        assert!(
            (a - b).norm() <= tolerance * b.norm(),
            "{what}: {a} vs {b} (relative difference {:e})",
            (a - b).norm() / b.norm()
        );
    }

    fn matches_saturating<const D: usize>() {
        let (saturating, potential) = saturating_pair::<D>();
        for rate in strain_rates::<D>() {
            let at = format!("D = {D}, ε = {rate}");
            assert_close(
                &format!("stress {at}"),
                &Viscosity::<D>::stress(&potential, &rate),
                &Viscosity::<D>::stress(&saturating, &rate),
                1e-12,
            );
            for direction in directions::<D>() {
                assert_close(
                    &format!("tangent {at}"),
                    &Viscosity::<D>::tangent(&potential, &rate, &direction),
                    &Viscosity::<D>::tangent(&saturating, &rate, &direction),
                    1e-12,
                );
            }
            let (ours, theirs) = (
                Viscosity::<D>::potential(&potential, &rate),
                Viscosity::<D>::potential(&saturating, &rate),
            );
            assert!(
                (ours - theirs).abs() <= 1e-12 * theirs.abs(),
                "potential {at}: {ours} vs {theirs}"
            );
        }
    }

    #[test]
    fn potential_viscosity_matches_saturating_law_in_2d_and_3d_also_at_zero_deviator() {
        matches_saturating::<2>();
        matches_saturating::<3>();
    }

    fn tangent_and_stress_match_finite_differences<const D: usize>() {
        let law = coupled();
        for rate in strain_rates::<D>() {
            let h = 1e-6 * rate.norm().max(1.0);
            for direction in directions::<D>() {
                let fd = (Viscosity::<D>::stress(&law, &(rate + direction * h))
                    - Viscosity::<D>::stress(&law, &(rate - direction * h)))
                    / (2.0 * h);
                let exact = Viscosity::<D>::tangent(&law, &rate, &direction);
                // the stress is C¹ but only Lipschitz-differentiable at ε_D = 0 in the direction
                // of δ_D: central differences are exact up to O(h²) away from it, O(h) near it
                assert!(
                    (fd - exact).norm() <= 1e-6 * exact.norm().max(1.0),
                    "D = {D}, ε = {rate}: tangent {exact} vs finite differences {fd}"
                );
                let fd = (Viscosity::<D>::potential(&law, &(rate + direction * h))
                    - Viscosity::<D>::potential(&law, &(rate - direction * h)))
                    / (2.0 * h);
                let exact = Viscosity::<D>::stress(&law, &rate).dot(&direction);
                assert!(
                    (fd - exact).abs() <= 1e-7 * exact.abs().max(1.0),
                    "D = {D}, ε = {rate}: σ:δ = {exact} vs finite differences of Φ {fd}"
                );
            }
        }
    }

    #[test]
    fn potential_viscosity_tangent_and_stress_match_finite_differences() {
        tangent_and_stress_match_finite_differences::<2>();
        tangent_and_stress_match_finite_differences::<3>();
    }

    #[test]
    fn potential_viscosity_is_continuous_across_the_limit_form_threshold() {
        // n/|ε| just below and just above SMALL_DEVIATOR: limit form and chain rule agree up to
        // the change of the t–n coupling terms, O(n) ≈ 1e-11 relative between the two points
        let law = coupled();
        let identity = Tensor::<3>::identity();
        let unit = deviator(&sample_tensor()) / deviator(&sample_tensor()).norm();
        let scale = (identity * 0.5).norm();
        let below = identity * 0.5 + unit * (0.99 * SMALL_DEVIATOR * scale);
        let above = identity * 0.5 + unit * (1.01 * SMALL_DEVIATOR * scale);
        assert!(Invariants::of(&below).near_axis && !Invariants::of(&above).near_axis);
        // at the same point, the limit form equals the chain rule to round-off
        let limit = Invariants::of(&below);
        let chain_rule = Invariants {
            near_axis: false,
            ..Invariants::of(&below)
        };
        assert_close(
            "stress: limit form vs chain rule",
            &law.stress_at(&limit),
            &law.stress_at(&chain_rule),
            1e-15,
        );
        for direction in directions::<3>() {
            assert_close(
                "tangent: limit form vs chain rule",
                &law.tangent_at(&limit, &direction),
                &law.tangent_at(&chain_rule, &direction),
                1e-15,
            );
        }
        for direction in directions::<3>() {
            assert_close(
                "tangent across the threshold",
                &Viscosity::<3>::tangent(&law, &below, &direction),
                &Viscosity::<3>::tangent(&law, &above, &direction),
                1e-10,
            );
        }
        assert_close(
            "stress across the threshold",
            &Viscosity::<3>::stress(&law, &below),
            &Viscosity::<3>::stress(&law, &above),
            1e-10,
        );
    }

    #[test]
    fn potential_viscosity_shifts_the_potential_to_vanish_at_zero() {
        let shifted = PotentialViscosity::new(Arc::new(Polynomial {
            a: 1.0,
            b: 1.0,
            f: 0.0,
            ..Polynomial::default()
        }));
        let offset = PotentialViscosity::new(Arc::new(Coupled {
            a: 1.0,
            b: 1.0,
            c: 0.0,
            s: 1.0,
        }));
        assert_eq!(
            Viscosity::<2>::potential(&shifted, &Tensor::<2>::zeros()),
            0.0
        );
        assert_eq!(
            Viscosity::<2>::potential(&offset, &Tensor::<2>::zeros()),
            0.0
        );
        let exp = PotentialViscosity::new(Arc::new(Polynomial {
            a: 1.0,
            b: 1.0,
            f: 1e-3,
            ..Polynomial::default()
        }));
        assert_eq!(Viscosity::<2>::potential(&exp, &Tensor::<2>::zeros()), 0.0);
        assert!(!Viscosity::<2>::is_linear(&exp));
    }

    #[test]
    fn potential_viscosity_check_accepts_convex_potentials_with_lipschitz_gradient() {
        let (_, saturating) = saturating_pair::<2>();
        Viscosity::<2>::validate(&saturating).unwrap();
        let (_, saturating) = saturating_pair::<3>();
        Viscosity::<3>::validate(&saturating).unwrap();
        Viscosity::<2>::validate(&coupled()).unwrap();
        Viscosity::<3>::validate(&coupled()).unwrap();
        // quartic growth stays within the 10⁸ spread up to |ε| = 1e3: accepted
        let quartic = Polynomial {
            a: 1.0,
            b: 1.0,
            e: 1.0,
            ..Polynomial::default()
        };
        Viscosity::<3>::validate(&PotentialViscosity::new(Arc::new(quartic))).unwrap();
        assert_eq!(sampled_rate_directions::<3>().len() * 15 + 1, 196);
    }

    fn rejection<const D: usize>(potential: Polynomial) -> String {
        match Viscosity::<D>::validate(&PotentialViscosity::new(Arc::new(potential))) {
            Ok(()) => panic!("accepted"),
            Err(error) => {
                let message = error.to_string();
                assert!(message.contains("`viscosity.potential`"), "{message}");
                message
            }
        }
    }

    #[test]
    fn potential_viscosity_check_rejects_potentials_that_violate_3_4_naming_the_key() {
        let base = Polynomial {
            a: 1.0,
            b: 1.0,
            ..Polynomial::default()
        };
        // concave in the deviator
        let message = rejection::<2>(Polynomial { a: -1.0, ..base });
        assert!(message.contains("not convex"), "{message}");
        // no deviatoric stiffness (tr ε² only)
        let message = rejection::<3>(Polynomial { a: 0.0, ..base });
        assert!(message.contains("not strongly convex"), "{message}");
        // no volumetric stiffness
        let message = rejection::<2>(Polynomial { b: 0.0, ..base });
        assert!(message.contains("not strongly convex"), "{message}");
        // a term in |ε_D|: not differentiable at ε_D = 0
        let message = rejection::<2>(Polynomial { c: 1.0, ..base });
        assert!(message.contains("Φ_n(t, 0)"), "{message}");
        let message = rejection::<3>(Polynomial { c: 1e-9, ..base });
        assert!(message.contains("Φ_n(t, 0)"), "{message}");
        // loses convexity at large rates
        let message = rejection::<3>(Polynomial { e: -0.9, ..base });
        assert!(message.contains("not convex"), "{message}");
        // grows too fast: exp(tr ε) overflows at tr ε = √3 · 1e3
        let message = rejection::<3>(Polynomial { f: 1.0, ..base });
        assert!(message.contains("not finite"), "{message}");
    }

    #[test]
    fn potential_viscosity_check_rejects_a_tangent_spread_over_more_than_1e8() {
        // Φ = n² + t² + n⁶-like growth: modeled by a steep quartic, 12e n² ≈ 1.2e15 at n = 1e3
        let message = rejection::<2>(Polynomial {
            a: 1.0,
            b: 1.0,
            e: 1e9,
            ..Polynomial::default()
        });
        assert!(message.contains("spread over more than 10⁸"), "{message}");
    }

    /// A law with the trait's default methods (`weighted_stress_sum`, `stress_divergence`):
    /// the reference of the closed forms that laws override them with.
    struct TraitDefaults<L>(L);

    impl<L: Elasticity<3>> Elasticity<3> for TraitDefaults<L> {
        fn stress(&self, strain: &Tensor<3>, damage: f64) -> Tensor<3> {
            self.0.stress(strain, damage)
        }
        fn strain_derivative(
            &self,
            strain: &Tensor<3>,
            damage: f64,
            direction: &Tensor<3>,
        ) -> Tensor<3> {
            self.0.strain_derivative(strain, damage, direction)
        }
        fn damage_derivative(&self, strain: &Tensor<3>, damage: f64) -> Tensor<3> {
            self.0.damage_derivative(strain, damage)
        }
        fn validate(&self) -> Result<()> {
            self.0.validate()
        }
    }

    impl<L: Viscosity<3>> Viscosity<3> for TraitDefaults<L> {
        fn stress(&self, strain_rate: &Tensor<3>) -> Tensor<3> {
            self.0.stress(strain_rate)
        }
        fn tangent(&self, strain_rate: &Tensor<3>, direction: &Tensor<3>) -> Tensor<3> {
            self.0.tangent(strain_rate, direction)
        }
        fn potential(&self, strain_rate: &Tensor<3>) -> f64 {
            self.0.potential(strain_rate)
        }
        fn is_linear(&self) -> bool {
            self.0.is_linear()
        }
        fn validate(&self) -> Result<()> {
            self.0.validate()
        }
    }

    /// A symmetric tensor from 9 entries.
    fn symmetric_from(entries: &[f64]) -> Tensor<3> {
        let m = Tensor::<3>::from_column_slice(entries);
        (m + m.transpose()) * 0.5
    }

    proptest::proptest! {
        /// The closed-form divergences (one call per point) against the trait's chain rule
        /// through `tangent`, `strain_derivative` and `damage_derivative` (D calls each).
        #[test]
        fn closed_form_stress_divergences_equal_the_chain_rule(
            entries in proptest::collection::vec(-1.0f64..1.0, 39),
            damage in -0.5f64..1.5,
        ) {
            let strain = symmetric_from(&entries[..9]);
            let derivatives: [Tensor<3>; 3] =
                std::array::from_fn(|j| symmetric_from(&entries[9 * (j + 1)..9 * (j + 2)]));
            let damage_gradient = SVector::<f64, 3>::from_column_slice(&entries[36..39]);
            // the sums of the chain rule, term by term: a few roundings of this size apart
            let size = 10.0 * (1.0 + strain.norm())
                * (derivatives.iter().map(|d| d.norm()).sum::<f64>() + damage_gradient.norm());
            let close = |a: SVector<f64, 3>, b: SVector<f64, 3>| (a - b).norm() <= 1e-14 * size;
            let viscosity = LinearViscosity { shear: 0.7, bulk: -0.2 };
            let (ours, chain) = (
                viscosity.stress_divergence(&strain, &derivatives),
                TraitDefaults(viscosity).stress_divergence(&strain, &derivatives),
            );
            proptest::prop_assert!(close(ours, chain), "viscosity: {} vs {}", ours, chain);
            let hooke = DamagedHooke { shear_modulus: 1.3, lame_lambda: -0.4 };
            let moduli = || ModuliElasticity::new(Arc::new(PowerModuli {
                shear: 2.0, lambda: -0.5, lambda_shift: 0.1,
            }));
            let (ours, chain) = (
                hooke.stress_divergence(&strain, damage, &derivatives, &damage_gradient),
                TraitDefaults(hooke).stress_divergence(&strain, damage, &derivatives,
                    &damage_gradient),
            );
            proptest::prop_assert!(close(ours, chain), "damaged Hooke: {} vs {}", ours, chain);
            let (ours, chain) = (
                moduli().stress_divergence(&strain, damage, &derivatives, &damage_gradient),
                TraitDefaults(moduli()).stress_divergence(&strain, damage, &derivatives,
                    &damage_gradient),
            );
            proptest::prop_assert!(close(ours, chain), "moduli: {} vs {}", ours, chain);
        }
    }

    proptest::proptest! {
        /// The batch divergences from the columns of the fields' derivatives (one call
        /// through the trait object per batch) are bitwise the point-by-point divergences of
        /// the strain jets built from the same numbers, for the closed forms and the trait's
        /// chain rule. Point p holds 39 numbers: ∇w (column-major), ∂_j ∇w for j < 3 (the
        /// columns `second[j]`), ∇β; the columns need not be symmetric in (j, k).
        #[test]
        fn stress_divergences_of_jets_are_bitwise_the_pointwise_divergences(
            entries in proptest::collection::vec(-1.0f64..1.0, 39 * 19),
            damages in proptest::collection::vec(-0.5f64..1.5, 19),
            count in 0usize..20,
        ) {
            let at = |p: usize, offset: usize| entries[39 * p + offset];
            let column = |offset: usize| -> Vec<f64> { (0..count).map(|p| at(p, offset)).collect() };
            let gradient: Vec<Vec<Vec<f64>>> =
                (0..3).map(|i| (0..3).map(|k| column(i + 3 * k)).collect()).collect();
            let second: Vec<Vec<Vec<Vec<f64>>>> = (0..3)
                .map(|j| {
                    (0..3)
                        .map(|i| (0..3).map(|k| column(9 * (j + 1) + i + 3 * k)).collect())
                        .collect()
                })
                .collect();
            let damage_gradient: Vec<Vec<f64>> = (0..3).map(|j| column(36 + j)).collect();
            let jets = FieldJets::<3> {
                gradient: std::array::from_fn(|i| std::array::from_fn(|k| &gradient[i][k][..])),
                second: std::array::from_fn(|j| {
                    std::array::from_fn(|i| std::array::from_fn(|k| &second[j][i][k][..]))
                }),
            };
            let damage_gradient: [&[f64]; 3] = std::array::from_fn(|j| &damage_gradient[j][..]);
            // The jets of point p built directly from its numbers.
            let point = |p: usize| {
                let numbers = &entries[39 * p..39 * (p + 1)];
                let strain = symmetric_from(&numbers[..9]);
                let derivatives: [Tensor<3>; 3] =
                    std::array::from_fn(|j| symmetric_from(&numbers[9 * (j + 1)..9 * (j + 2)]));
                (strain, derivatives, SVector::<f64, 3>::from_column_slice(&numbers[36..39]))
            };
            let bits = |columns: &[Vec<f64>; 3]| -> Vec<u64> {
                (0..count).flat_map(|p| (0..3).map(move |i| columns[i][p].to_bits())).collect()
            };
            let pointwise_bits = |values: Vec<SVector<f64, 3>>| -> Vec<u64> {
                values.iter().flat_map(|v| v.iter().map(|x| x.to_bits())).collect()
            };
            let viscosity = LinearViscosity { shear: 0.7, bulk: -0.2 };
            let saturating = SaturatingViscosity {
                linear: viscosity,
                extra_shear: 0.5,
                rate_scale: 0.3,
            };
            let viscosities: [&dyn Viscosity<3>; 3] =
                [&viscosity, &saturating, &TraitDefaults(viscosity)];
            for law in viscosities {
                let mut columns: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; count]);
                law.stress_divergence_of_jets(&jets, &mut columns.each_mut().map(|c| &mut c[..]));
                let pointwise = (0..count)
                    .map(|p| {
                        let (strain, derivatives, _) = point(p);
                        law.stress_divergence(&strain, &derivatives)
                    })
                    .collect();
                proptest::prop_assert_eq!(bits(&columns), pointwise_bits(pointwise));
            }
            // The batch kernels compiled for the baseline target, which `stress_divergence_of_jets`
            // calls where the processor lacks AVX2.
            let mut columns: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; count]);
            viscosity.divergence_of_jets(&jets, &mut columns.each_mut().map(|c| &mut c[..]));
            let mut dispatched: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; count]);
            Viscosity::stress_divergence_of_jets(
                &viscosity,
                &jets,
                &mut dispatched.each_mut().map(|c| &mut c[..]),
            );
            proptest::prop_assert_eq!(bits(&columns), bits(&dispatched));
            let hooke = DamagedHooke { shear_modulus: 1.3, lame_lambda: -0.4 };
            let mut columns: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; count]);
            hooke.divergence_of_jets(
                &jets,
                &damages[..count],
                &damage_gradient,
                &mut columns.each_mut().map(|c| &mut c[..]),
            );
            let mut dispatched: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; count]);
            Elasticity::stress_divergence_of_jets(
                &hooke,
                &jets,
                &damages[..count],
                &damage_gradient,
                &mut dispatched.each_mut().map(|c| &mut c[..]),
            );
            proptest::prop_assert_eq!(bits(&columns), bits(&dispatched));
            let moduli = ModuliElasticity::new(Arc::new(PowerModuli {
                shear: 2.0, lambda: -0.5, lambda_shift: 0.1,
            }));
            let elasticities: [&dyn Elasticity<3>; 3] = [&hooke, &moduli, &TraitDefaults(hooke)];
            for law in elasticities {
                let mut columns: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; count]);
                law.stress_divergence_of_jets(
                    &jets,
                    &damages[..count],
                    &damage_gradient,
                    &mut columns.each_mut().map(|c| &mut c[..]),
                );
                let pointwise = (0..count)
                    .map(|p| {
                        let (strain, derivatives, gradient) = point(p);
                        law.stress_divergence(&strain, damages[p], &derivatives, &gradient)
                    })
                    .collect();
                proptest::prop_assert_eq!(bits(&columns), pointwise_bits(pointwise));
            }
        }
    }

    proptest::proptest! {
        /// One strain per cell (the P1 load path): the Frémond source with its strain energy
        /// once per cell and the trait's default (repeated strains through `source`) give
        /// bitwise the point-by-point values, with β on both sides of the floor and of 1 and
        /// strain energies on both sides of the cap.
        #[test]
        fn source_cells_is_bitwise_the_pointwise_source(
            entries in proptest::collection::vec(-3.0f64..3.0, 9 * 7),
            damages in proptest::collection::vec(-0.5f64..1.5, 7 * 5),
            per_cell in 1usize..6,
        ) {
            let strains: Vec<Tensor<3>> = entries.chunks(9).map(symmetric_from).collect();
            let point_damages = &damages[..strains.len() * per_cell];
            let fremond = TruncatedFremond {
                lambda_d: 0.3,
                lambda_w: -0.05,
                damage_floor: 0.1,
                strain_energy_cap: 4.0,
            };
            let closure = DamageSourceFn(|strain: &Tensor<3>, damage: f64| {
                damage * damage - strain.trace() * strain.norm()
            });
            let laws: [&dyn DamageSource<3>; 2] = [&fremond, &closure];
            for law in laws {
                let mut values = vec![f64::NAN; point_damages.len()];
                law.source_cells(&strains, point_damages, &mut values);
                for (p, value) in values.iter().enumerate() {
                    let pointwise = law.source(&strains[p / per_cell], point_damages[p]);
                    proptest::prop_assert_eq!(value.to_bits(), pointwise.to_bits());
                }
            }
        }
    }

    proptest::proptest! {
        #[test]
        fn damaged_hooke_cell_stress_equals_the_sum_of_point_stresses(
            entries in proptest::collection::vec(-1.0f64..1.0, 9),
            damages in proptest::collection::vec(-0.5f64..1.5, 1..12),
            scale in 0.01f64..1.0,
        ) {
            let law = DamagedHooke { shear_modulus: 1.3, lame_lambda: -0.4 };
            let strain = Tensor::<3>::from_column_slice(&entries);
            let strain = (strain + strain.transpose()) * 0.5;
            let weights: Vec<f64> = (0..damages.len()).map(|q| scale * (1.0 + q as f64)).collect();
            let cell = law.weighted_stress_sum(&strain, &damages, &weights);
            let points = TraitDefaults(law).weighted_stress_sum(&strain, &damages, &weights);
            // the same sum in another order: a few roundings of the largest term apart
            let size = law.undamaged(&strain).norm() * weights.iter().sum::<f64>();
            proptest::prop_assert!((cell - points).norm() <= 1e-14 * size.max(1e-300),
                "{} vs {}", cell, points);
        }

        #[test]
        fn potential_viscosity_tangent_is_symmetric_and_strongly_monotone(
            entries in proptest::collection::vec(-1.0f64..1.0, 12),
            log_scale in -6.0f64..3.0,
        ) {
            let law = coupled();
            let symmetric = |values: &[f64]| {
                let m = Tensor::<3>::from_column_slice(values);
                (m + m.transpose()) * 0.5
            };
            let rate = symmetric(&entries[..9]) * 10f64.powf(log_scale);
            let first = symmetric(&entries[3..12]);
            let second = symmetric(&[entries[0], entries[5], entries[7], entries[1], entries[11],
                entries[2], entries[4], entries[9], entries[6]]);
            let a = first.dot(&Viscosity::<3>::tangent(&law, &rate, &second));
            let b = second.dot(&Viscosity::<3>::tangent(&law, &rate, &first));
            let size = first.norm() * second.norm();
            proptest::prop_assert!((a - b).abs() <= 1e-12 * size.max(1e-300), "{} vs {}", a, b);
            // tangent ≥ min(2a, 2bd) = min(1.6, 1.8)
            let quadratic = first.dot(&Viscosity::<3>::tangent(&law, &rate, &first));
            proptest::prop_assert!(quadratic >= 1.6 * first.norm_squared() * (1.0 - 1e-12));
        }
    }

    /// μ(β) = μ₀ β², λ(β) = λ₀ β³ (+ `lambda_shift`), derivatives by hand.
    struct PowerModuli {
        shear: f64,
        lambda: f64,
        lambda_shift: f64,
    }

    impl DamageModuli for PowerModuli {
        fn shear_modulus(&self, beta: f64) -> (f64, f64) {
            (self.shear * beta * beta, 2.0 * self.shear * beta)
        }
        fn lame_lambda(&self, beta: f64) -> (f64, f64) {
            (
                self.lambda * beta.powi(3) + self.lambda_shift,
                3.0 * self.lambda * beta * beta,
            )
        }
    }

    /// μ(β) = μ β, λ(β) = λ β: the moduli of [`DamagedHooke`].
    struct LinearModuli(DamagedHooke);

    impl DamageModuli for LinearModuli {
        fn shear_modulus(&self, beta: f64) -> (f64, f64) {
            (self.0.shear_modulus * beta, self.0.shear_modulus)
        }
        fn lame_lambda(&self, beta: f64) -> (f64, f64) {
            (self.0.lame_lambda * beta, self.0.lame_lambda)
        }
    }

    #[test]
    fn moduli_elasticity_with_linear_moduli_is_damaged_hooke() {
        let hooke = DamagedHooke {
            shear_modulus: 1.3,
            lame_lambda: 0.7,
        };
        let law = ModuliElasticity::new(Arc::new(LinearModuli(hooke)));
        let eps = sample_tensor();
        let dir = Tensor::<3>::new(0.1, 0.2, 0.0, 0.2, -0.3, 0.4, 0.0, 0.4, 0.25);
        for beta in [-0.5, 0.0, 0.3, 1.0, 1.4] {
            assert_close(
                "stress",
                &Elasticity::<3>::stress(&law, &eps, beta),
                &Elasticity::<3>::stress(&hooke, &eps, beta),
                1e-15,
            );
            assert_close(
                "strain derivative",
                &Elasticity::<3>::strain_derivative(&law, &eps, beta, &dir),
                &Elasticity::<3>::strain_derivative(&hooke, &eps, beta, &dir),
                1e-15,
            );
            assert_eq!(
                Elasticity::<3>::damage_derivative(&law, &eps, beta),
                Elasticity::<3>::damage_derivative(&hooke, &eps, beta)
            );
        }
        Elasticity::<3>::validate(&law).unwrap();
    }

    #[test]
    fn moduli_elasticity_derivatives_match_finite_differences_and_clamp() {
        let law = ModuliElasticity::new(Arc::new(PowerModuli {
            shear: 2.0,
            lambda: -0.5,
            lambda_shift: 0.0,
        }));
        Elasticity::<2>::validate(&law).unwrap();
        let eps = Tensor::<2>::new(0.1, 0.2, 0.2, -0.3);
        let dir = Tensor::<2>::new(-0.4, 0.1, 0.1, 0.6);
        let h = 1e-6;
        for beta in [0.2, 0.5, 0.9] {
            let fd = (Elasticity::<2>::stress(&law, &eps, beta + h)
                - Elasticity::<2>::stress(&law, &eps, beta - h))
                / (2.0 * h);
            assert_close(
                "∂G/∂β",
                &Elasticity::<2>::damage_derivative(&law, &eps, beta),
                &fd,
                1e-8,
            );
            let fd = (Elasticity::<2>::stress(&law, &(eps + dir * h), beta)
                - Elasticity::<2>::stress(&law, &(eps - dir * h), beta))
                / (2.0 * h);
            assert_close(
                "∂G/∂ε",
                &Elasticity::<2>::strain_derivative(&law, &eps, beta, &dir),
                &fd,
                1e-8,
            );
        }
        // clamped outside [0, 1], one-sided derivative at the ends
        assert_eq!(
            Elasticity::<2>::stress(&law, &eps, 1.5),
            Elasticity::<2>::stress(&law, &eps, 1.0)
        );
        assert_eq!(
            Elasticity::<2>::stress(&law, &eps, -1.0),
            Tensor::<2>::zeros()
        );
        assert_eq!(
            Elasticity::<2>::damage_derivative(&law, &eps, 1.2),
            Tensor::<2>::zeros()
        );
        let at_one = eps * 8.0 + Tensor::<2>::identity() * (-1.5 * eps.trace());
        assert_close(
            "∂G/∂β at β = 1",
            &Elasticity::<2>::damage_derivative(&law, &eps, 1.0),
            &at_one,
            1e-15,
        );
    }

    #[test]
    fn moduli_elasticity_notes_evaluations_outside_its_range_and_names_them() {
        // λ(0) = −0.1: 2μ + 3λ = −0.3 < 0 at β = 0, ≥ 0 from β ≈ 0.23 on
        let law = ModuliElasticity::new(Arc::new(PowerModuli {
            shear: 1.0,
            lambda: 0.5,
            lambda_shift: -0.1,
        }));
        let strain = sample_tensor();
        let _ = Elasticity::<3>::stress(&law, &strain, 0.9);
        assert!(!Elasticity::<3>::damage_range_suspect(&law));
        assert!(Elasticity::<3>::damage_range_violation(&law, 0.9).is_none());
        let copy = law.clone();
        let _ = Elasticity::<3>::stress(&law, &strain, 0.0);
        // sticky, and seen by every holder of the law
        assert!(Elasticity::<3>::damage_range_suspect(&copy));
        let message = Elasticity::<3>::damage_range_violation(&law, -0.5)
            .unwrap()
            .to_string();
        assert!(
            message.contains("`elasticity.lame_lambda`") && message.contains("β = 0"),
            "{message}"
        );
        let message =
            Elasticity::<3>::damage_range_violation(&law, f64::NAN).map(|e| e.to_string());
        assert!(
            message.is_some(),
            "a NaN damage is clamped to NaN moduli: {message:?}"
        );
        // the default of a law with no range to note
        let hooke = DamagedHooke {
            shear_modulus: 1.0,
            lame_lambda: 1.0,
        };
        let _ = Elasticity::<3>::stress(&hooke, &strain, 0.0);
        assert!(!Elasticity::<3>::damage_range_suspect(&hooke));
    }

    #[test]
    fn moduli_elasticity_check_rejects_indefinite_or_degenerate_moduli_naming_the_key() {
        let check = |shear: f64, lambda: f64, lambda_shift: f64| {
            Elasticity::<3>::validate(&ModuliElasticity::new(Arc::new(PowerModuli {
                shear,
                lambda,
                lambda_shift,
            })))
            .map_err(|e| e.to_string())
        };
        assert!(check(1.0, 0.5, 0.0).is_ok());
        let message = check(-1.0, 0.5, 0.0).unwrap_err();
        assert!(message.contains("`elasticity.shear_modulus`"), "{message}");
        let message = check(0.0, 0.5, 0.0).unwrap_err();
        assert!(
            message.contains("`elasticity.shear_modulus`") && message.contains("μ(1)"),
            "{message}"
        );
        // 2μ + 3λ < 0 near β = 1 only
        let message = check(1.0, -1.0, 0.0).unwrap_err();
        assert!(message.contains("`elasticity.lame_lambda`"), "{message}");
        // 2μ + 3λ < 0 at β = 0 (λ(0) = −0.1)
        let message = check(1.0, 0.5, -0.1).unwrap_err();
        assert!(
            message.contains("`elasticity.lame_lambda`") && message.contains("β = 0"),
            "{message}"
        );
        let message = check(f64::NAN, 0.5, 0.0).unwrap_err();
        assert!(
            message.contains("`elasticity.shear_modulus`") && message.contains("not finite"),
            "{message}"
        );
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
