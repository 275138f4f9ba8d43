//! `[laws]` of case and problem files: the constitutive laws 𝒜 (viscosity), G (elasticity),
//! φ (damage source), p_ν, p_τ (normal compliance with Coulomb friction (2.10)–(2.12)) and κ,
//! read from TOML and built, validated, as the solver's [`Model`]. Laws given by expressions
//! (a viscosity potential, damage-dependent moduli, a damage source) are evaluated with
//! derivatives by dual numbers (num-dual).

use std::collections::BTreeMap;
use std::sync::Arc;

use contact_damage::model::laws::{
    points_per_cell, DamageModuli, DamageSource, DamageSourceFn, DamagedHooke, Elasticity,
    InvariantJet, InvariantPotential, LinearViscosity, ModuliElasticity, NormalComplianceCoulomb,
    PotentialViscosity, SaturatingViscosity, Tensor, TruncatedFremond, Viscosity,
};
use contact_damage::scheme::{DamageEvolution, Model};
use serde::{Deserialize, Serialize};

use crate::error::{FileKind, InputError};
use crate::expr::compiled::with_registers;
use crate::expr::compiled::Program;
use crate::expr::derivative::Tape;
use crate::expr::split::BATCH;
use crate::expr::Expr;
use crate::file::{parse_expr, positive};

/// The variables of a damage-source expression.
pub const SOURCE_VARIABLES: [&str; 3] = ["beta", "tr_eps", "eps_eps"];
/// The variables of a viscosity potential: the invariants tr ε and |ε_D| of the strain rate.
pub const POTENTIAL_VARIABLES: [&str; 2] = ["tr_eps", "dev_norm"];
/// The variable of the damage-dependent elastic moduli.
pub const MODULI_VARIABLES: [&str; 1] = ["beta"];

/// `[laws]`.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LawsFile {
    /// 𝒜.
    pub viscosity: ViscosityFile,
    /// G.
    pub elasticity: ElasticityFile,
    /// φ (may be left out when the damage is frozen, `[scheme] damage = false`).
    #[serde(default)]
    pub damage_source: Option<DamageSourceFile>,
    /// p_ν, p_τ.
    pub contact: ContactFile,
    /// κ (may be left out when the damage is frozen).
    #[serde(default)]
    pub damage_diffusion: Option<f64>,
}

/// Viscosity laws.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ViscosityFile {
    /// 𝒜ε = 2ηε + ζ tr(ε) I.
    Linear { shear: f64, bulk: f64 },
    /// Linear plus a saturating deviatoric part.
    Saturating {
        shear: f64,
        bulk: f64,
        extra_shear: f64,
        rate_scale: f64,
    },
    /// 𝒜 = ∂Φ/∂ε for a convex potential Φ written as an expression in `tr_eps` = tr ε and
    /// `dev_norm` = |ε_D| ([`PotentialViscosity`]; derivatives by automatic differentiation,
    /// checked for (3.4) at sampled strain rates when the file is loaded).
    Potential { potential: String },
}

/// Elasticity laws.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ElasticityFile {
    /// G = β(2με + λ tr(ε) I).
    DamagedHooke {
        shear_modulus: f64,
        lame_lambda: f64,
    },
    /// G = 2μ(β) ε + λ(β) tr(ε) I with μ, λ expressions in `beta` ([`ModuliElasticity`];
    /// β clamped to [0, 1], derivatives by automatic differentiation).
    Moduli {
        shear_modulus: String,
        lame_lambda: String,
    },
}

/// Damage sources.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum DamageSourceFile {
    /// The truncated Frémond source.
    Fremond {
        lambda_d: f64,
        lambda_w: f64,
        damage_floor: f64,
        strain_energy_cap: f64,
    },
    /// φ as an expression in `beta`, `tr_eps`, `eps_eps`.
    Expression { expr: String },
}

/// Normal compliance with Coulomb friction (2.10)–(2.12).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ContactFile {
    /// c_ν.
    pub stiffness: f64,
    /// μ.
    pub friction: f64,
    /// δ.
    #[serde(default)]
    pub wear: f64,
}

impl LawsFile {
    /// Builds and validates the laws in dimension D: expressions are parsed with the given
    /// `constants` and the variables [`SOURCE_VARIABLES`] (damage source),
    /// [`POTENTIAL_VARIABLES`] (viscosity potential) or [`MODULI_VARIABLES`] (elastic moduli);
    /// every law is validated (a viscosity potential and elastic moduli by the sampling checks of
    /// [`PotentialViscosity`] and [`ModuliElasticity`]) and κ must be positive. Errors name
    /// the file (`kind`, `origin`) and the key under `laws` (e.g. `laws.viscosity.potential`, with the expression).
    /// With frozen damage (`damage`), `damage_source` and `damage_diffusion` may be absent
    /// (then φ = 0 and κ = 0, never used); with evolving damage their absence is an error.
    pub fn build<const D: usize>(
        &self,
        kind: FileKind,
        origin: &str,
        constants: &BTreeMap<String, f64>,
        damage: DamageEvolution,
    ) -> Result<Model<D>, InputError> {
        let laws_file = self;
        let viscosity: Arc<dyn Viscosity<D>> = match &laws_file.viscosity {
            &ViscosityFile::Linear { shear, bulk } => Arc::new(LinearViscosity { shear, bulk }),
            &ViscosityFile::Saturating {
                shear,
                bulk,
                extra_shear,
                rate_scale,
            } => Arc::new(SaturatingViscosity {
                linear: LinearViscosity { shear, bulk },
                extra_shear,
                rate_scale,
            }),
            ViscosityFile::Potential { potential } => Arc::new(PotentialViscosity::new(Arc::new(
                ExpressionPotential::new(parse_expr(
                    kind,
                    origin,
                    "laws.viscosity.potential",
                    potential,
                    &POTENTIAL_VARIABLES,
                    constants,
                )?),
            ))),
        };
        let elasticity: Arc<dyn Elasticity<D>> = match &laws_file.elasticity {
            &ElasticityFile::DamagedHooke {
                shear_modulus,
                lame_lambda,
            } => Arc::new(DamagedHooke {
                shear_modulus,
                lame_lambda,
            }),
            ElasticityFile::Moduli {
                shear_modulus,
                lame_lambda,
            } => Arc::new(ModuliElasticity::new(Arc::new(ExpressionModuli::new(
                parse_expr(
                    kind,
                    origin,
                    "laws.elasticity.shear_modulus",
                    shear_modulus,
                    &MODULI_VARIABLES,
                    constants,
                )?,
                parse_expr(
                    kind,
                    origin,
                    "laws.elasticity.lame_lambda",
                    lame_lambda,
                    &MODULI_VARIABLES,
                    constants,
                )?,
            )))),
        };
        let frozen = damage == DamageEvolution::Frozen;
        let missing = |key: &str| {
            kind.error(
                origin,
                key,
                "missing: the damage evolves by (5.2) (give the law, or set `[scheme] damage = false` for a pure contact problem)",
            )
        };
        let damage_source: Arc<dyn DamageSource<D>> = match &laws_file.damage_source {
            // frozen damage: φ is never used
            None if frozen => Arc::new(DamageSourceFn(|_: &Tensor<D>, _: f64| 0.0)),
            None => return Err(missing("laws.damage_source")),
            Some(DamageSourceFile::Fremond {
                lambda_d,
                lambda_w,
                damage_floor,
                strain_energy_cap,
            }) => Arc::new(TruncatedFremond {
                lambda_d: *lambda_d,
                lambda_w: *lambda_w,
                damage_floor: *damage_floor,
                strain_energy_cap: *strain_energy_cap,
            }),
            Some(DamageSourceFile::Expression { expr }) => {
                Arc::new(ExpressionDamageSource::new(parse_expr(
                    kind,
                    origin,
                    "laws.damage_source.expr",
                    expr,
                    &SOURCE_VARIABLES,
                    constants,
                )?))
            }
        };
        let contact = Arc::new(NormalComplianceCoulomb {
            stiffness: laws_file.contact.stiffness,
            friction: laws_file.contact.friction,
            wear: laws_file.contact.wear,
        });
        let laws = Model {
            viscosity,
            elasticity,
            damage_source,
            contact,
            // frozen damage: κ is never used
            damage_diffusion: match laws_file.damage_diffusion {
                Some(kappa) => kappa,
                None if frozen => 0.0,
                None => return Err(missing("laws.damage_diffusion")),
            },
        };
        let law_error = |e: contact_damage::Error| self.law_error(kind, origin, e);
        laws.viscosity.validate().map_err(law_error)?;
        laws.elasticity.validate().map_err(law_error)?;
        if laws_file.damage_source.is_some() {
            laws.damage_source.validate().map_err(law_error)?;
        }
        laws.contact.validate().map_err(law_error)?;
        if laws_file.damage_diffusion.is_some() {
            positive(kind, origin, "laws.damage_diffusion", laws.damage_diffusion)?;
        }
        Ok(laws)
    }
}

impl LawsFile {
    /// A law's validation error as an error of the file: the key is `laws.` followed by the parameter
    /// the law names (`laws` when it names none), and the message starts with the expression
    /// when the parameter is one.
    fn law_error(&self, kind: FileKind, origin: &str, error: contact_damage::Error) -> InputError {
        let name = match &error {
            contact_damage::Error::InvalidParameter { name, .. } => Some(name.as_str()),
            _ => None,
        };
        // the leading key-like part of the name (`damage_source(0, β)` → `damage_source`)
        let path = name.map_or("", |name| {
            let end = name
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == '.'))
                .unwrap_or(name.len());
            name[..end].trim_matches('.')
        });
        let key = if path.is_empty() || path == "laws" {
            "laws".to_string()
        } else if path.starts_with("laws.") {
            path.to_string()
        } else {
            format!("laws.{path}")
        };
        let expression = match (key.as_str(), &self.viscosity, &self.elasticity) {
            ("laws.viscosity.potential", ViscosityFile::Potential { potential }, _) => {
                Some(potential)
            }
            ("laws.elasticity.shear_modulus", _, ElasticityFile::Moduli { shear_modulus, .. }) => {
                Some(shear_modulus)
            }
            ("laws.elasticity.lame_lambda", _, ElasticityFile::Moduli { lame_lambda, .. }) => {
                Some(lame_lambda)
            }
            _ => None,
        };
        match expression {
            Some(source) => kind.error(origin, &key, format!("`{source}`: {error}")),
            None => kind.error(origin, &key, error.to_string()),
        }
    }
}

/// A viscosity potential Φ(tr ε, |ε_D|) given by an expression in [`POTENTIAL_VARIABLES`]. Φ
/// and its first and second derivatives are differentiated symbolically once and compiled into
/// one program ([`Tape`]), evaluated per point on `f64` (the velocity step's Newton iteration
/// calls [`InvariantPotential::jet`] at every quadrature point of every iteration; the tree
/// walk on second-order dual numbers it replaces took about half of the time of `carreau2d`).
/// The program agrees with nested dual numbers to 1e-13 (proptest
/// `symbolic_derivatives_in_batches_agree_with_nested_duals_on_random_expressions`).
pub struct ExpressionPotential {
    /// Φ, Φ_t, Φ_n, Φ_tt, Φ_tn, Φ_nn.
    jet: Program,
}

impl ExpressionPotential {
    /// The potential Φ = `expr`, an expression in [`POTENTIAL_VARIABLES`].
    pub fn new(expr: Expr) -> Self {
        let mut tape = Tape::new(POTENTIAL_VARIABLES.len());
        let value = tape.expression(&expr);
        let (trace, dev_norm) = (tape.derivative(value, 0), tape.derivative(value, 1));
        let outputs = [
            value,
            trace,
            dev_norm,
            tape.derivative(trace, 0),
            tape.derivative(trace, 1),
            tape.derivative(dev_norm, 1),
        ];
        Self {
            jet: tape.compile(&outputs),
        }
    }
}

impl InvariantPotential for ExpressionPotential {
    fn value(&self, trace: f64, dev_norm: f64) -> f64 {
        self.jet(trace, dev_norm).value
    }

    fn jet(&self, trace: f64, dev_norm: f64) -> InvariantJet {
        let [value, d_t, d_n, d_tt, d_tn, d_nn] = with_registers(|registers: &mut Vec<f64>| {
            self.jet.eval_array(&[trace, dev_norm], registers)
        });
        InvariantJet {
            value,
            gradient: [d_t, d_n],
            hessian: [[d_tt, d_tn], [d_tn, d_nn]],
        }
    }
}

/// Elastic moduli μ(β), λ(β) given by expressions in [`MODULI_VARIABLES`]; the moduli and their
/// slopes are differentiated symbolically once and compiled into one program ([`Tape`]).
pub struct ExpressionModuli {
    /// μ, μ', λ, λ'.
    moduli: Program,
}

impl ExpressionModuli {
    /// The moduli μ = `shear_modulus`, λ = `lame_lambda`, expressions in [`MODULI_VARIABLES`].
    pub fn new(shear_modulus: Expr, lame_lambda: Expr) -> Self {
        let mut tape = Tape::new(MODULI_VARIABLES.len());
        let shear = tape.expression(&shear_modulus);
        let lambda = tape.expression(&lame_lambda);
        let outputs = [
            shear,
            tape.derivative(shear, 0),
            lambda,
            tape.derivative(lambda, 0),
        ];
        Self {
            moduli: tape.compile(&outputs),
        }
    }

    /// (μ, μ', λ, λ') at β.
    fn evaluate(&self, damage: f64) -> [f64; 4] {
        with_registers(|registers: &mut Vec<f64>| self.moduli.eval_array(&[damage], registers))
    }
}

impl DamageModuli for ExpressionModuli {
    fn shear_modulus(&self, damage: f64) -> (f64, f64) {
        let [value, slope, ..] = self.evaluate(damage);
        (value, slope)
    }

    fn lame_lambda(&self, damage: f64) -> (f64, f64) {
        let [.., value, slope] = self.evaluate(damage);
        (value, slope)
    }
}

/// A damage source given by an expression in β, tr ε and ε:ε, compiled once; the load
/// assembly evaluates it over each chunk of quadrature points (batch, instruction-major), with
/// values bitwise those of the tree ([`crate::expr::compiled`]).
pub struct ExpressionDamageSource {
    expr: Expr,
    program: Program,
}

impl ExpressionDamageSource {
    /// The source φ = `expr`, an expression in [`SOURCE_VARIABLES`].
    pub fn new(expr: Expr) -> Self {
        let program = Program::fuse(&[&expr]);
        Self { expr, program }
    }
}

impl<const D: usize> DamageSource<D> for ExpressionDamageSource {
    fn source(&self, strain: &Tensor<D>, damage: f64) -> f64 {
        self.expr
            .eval_f64(&[damage, strain.trace(), strain.norm_squared()])
    }
    fn source_batch(&self, strains: &[Tensor<D>], damages: &[f64], out: &mut [f64]) {
        with_registers(|registers: &mut Vec<f64>| {
            let mut inputs = [[0.0; BATCH]; 3];
            for ((strains, damages), out) in strains
                .chunks(BATCH)
                .zip(damages.chunks(BATCH))
                .zip(out.chunks_mut(BATCH))
            {
                let count = strains.len();
                for (p, (strain, &damage)) in strains.iter().zip(damages).enumerate() {
                    inputs[0][p] = damage;
                    inputs[1][p] = strain.trace();
                    inputs[2][p] = strain.norm_squared();
                }
                let columns: [&[f64]; 3] = std::array::from_fn(|v| &inputs[v][..count]);
                self.program.eval_batch(&columns, count, registers);
                out.copy_from_slice(self.program.batch_output(registers, count, 0));
            }
        });
    }
    /// tr ε and ε:ε once per cell, then the program over batches of points.
    fn source_cells(&self, cell_strains: &[Tensor<D>], damages: &[f64], out: &mut [f64]) {
        let per_cell = points_per_cell(cell_strains.len(), damages.len());
        let mut traces = Vec::with_capacity(damages.len());
        let mut norms_squared = Vec::with_capacity(damages.len());
        for strain in cell_strains {
            traces.extend(std::iter::repeat_n(strain.trace(), per_cell));
            norms_squared.extend(std::iter::repeat_n(strain.norm_squared(), per_cell));
        }
        with_registers(|registers: &mut Vec<f64>| {
            for start in (0..damages.len()).step_by(BATCH) {
                let batch = start..(start + BATCH).min(damages.len());
                let count = batch.len();
                let columns = [
                    &damages[batch.clone()],
                    &traces[batch.clone()],
                    &norms_squared[batch.clone()],
                ];
                self.program.eval_batch(&columns, count, registers);
                out[batch].copy_from_slice(self.program.batch_output(registers, count, 0));
            }
        });
    }
    fn validate(&self) -> contact_damage::Result<()> {
        for beta in [0.0, 0.5, 1.0] {
            let v = self.expr.eval_f64(&[beta, 0.0, 0.0]);
            if !v.is_finite() {
                return Err(contact_damage::Error::parameter(
                    "laws.damage_source.expr at ε = 0",
                    beta,
                    "the damage source expression is not finite",
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use contact_damage::model::laws::Tensor;
    use proptest::prelude::*;

    fn potential(source: &str) -> (Expr, ExpressionPotential) {
        let constants = BTreeMap::from([("eta1".to_string(), 0.5), ("eps0".to_string(), 0.2)]);
        let expr = Expr::parse(source, &POTENTIAL_VARIABLES, &constants).unwrap();
        (expr.clone(), ExpressionPotential::new(expr))
    }

    proptest! {
        /// The compiled symbolic jet of a potential agrees with second-order dual numbers on the
        /// tree to 1e-13 relative to the jet's size.
        #[test]
        fn expression_potential_jet_agrees_with_dual_numbers(
            trace in -1.0..1.0f64,
            dev_norm in 0.0..2.0f64,
        ) {
            use nalgebra::SVector;
            use num_dual::Dual2SVec64;
            for source in [
                "dev_norm^2 + 0.75*tr_eps^2 + eta1*eps0^2*((1 + dev_norm^2/eps0^2)^0.75 - 1)/1.5",
                "exp(tr_eps)*sqrt(1 + dev_norm^2) + max(0, tr_eps)^3",
            ] {
                let (expr, law) = potential(source);
                let (value, gradient, hessian) = num_dual::hessian(
                    |v: SVector<Dual2SVec64<2>, 2>| expr.eval(&[v[0], v[1]]),
                    &SVector::from([trace, dev_norm]),
                );
                let jet = law.jet(trace, dev_norm);
                let expected = [
                    value, gradient[0], gradient[1],
                    hessian[(0, 0)], hessian[(0, 1)], hessian[(1, 1)],
                ];
                let computed = [
                    jet.value, jet.gradient[0], jet.gradient[1],
                    jet.hessian[0][0], jet.hessian[0][1], jet.hessian[1][1],
                ];
                let scale = expected.iter().fold(1.0f64, |m, e| m.max(e.abs()));
                for (c, e) in computed.iter().zip(&expected) {
                    prop_assert!((c - e).abs() <= 1e-13 * scale, "`{source}`: {computed:?} vs {expected:?}");
                }
                prop_assert_eq!(jet.hessian[1][0], jet.hessian[0][1]);
                prop_assert_eq!(law.value(trace, dev_norm).to_bits(), jet.value.to_bits());
            }
        }

        /// The compiled moduli and slopes agree with first-order dual numbers on the tree.
        #[test]
        fn expression_moduli_agree_with_dual_numbers(damage in 0.0..1.0f64) {
            use num_dual::Dual64;
            let parse = |s: &str| Expr::parse(s, &MODULI_VARIABLES, &BTreeMap::new()).unwrap();
            let (shear, lambda) = (parse("beta^2 + 0.1*sin(3*beta)"), parse("beta/(1 + beta)"));
            let law = ExpressionModuli::new(shear.clone(), lambda.clone());
            for (expr, (value, slope)) in [
                (&shear, law.shear_modulus(damage)),
                (&lambda, law.lame_lambda(damage)),
            ] {
                let dual = expr.eval(&[Dual64::new(damage, 1.0)]);
                prop_assert!((value - dual.re).abs() <= 1e-15 * dual.re.abs().max(1.0));
                prop_assert!((slope - dual.eps).abs() <= 1e-14 * dual.eps.abs().max(1.0));
            }
        }
    }

    /// The expression source of the batch tests (all three variables, a kink, a transcendental).
    fn test_source() -> ExpressionDamageSource {
        let expr = Expr::parse(
            "0.02*(1 - beta)/max(beta, 0.05) - 10*min(eps_eps, 0.2) + exp(tr_eps)^2",
            &SOURCE_VARIABLES,
            &BTreeMap::new(),
        )
        .unwrap();
        ExpressionDamageSource::new(expr)
    }

    proptest! {
        /// The batch of the load assembly gives bitwise the point-by-point values, across
        /// batch boundaries.
        #[test]
        fn expression_source_batch_is_bitwise_pointwise(
            points in proptest::collection::vec(
                (-2.0..2.0f64, -1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64), 1..300),
        ) {
            let law = test_source();
            let strains: Vec<Tensor<2>> = points
                .iter()
                .map(|&(_, a, b, c)| Tensor::<2>::new(a, b, b, c))
                .collect();
            let damages: Vec<f64> = points.iter().map(|p| p.0).collect();
            let mut batch = vec![f64::NAN; points.len()];
            DamageSource::<2>::source_batch(&law, &strains, &damages, &mut batch);
            for ((strain, &damage), value) in strains.iter().zip(&damages).zip(&batch) {
                let pointwise = DamageSource::<2>::source(&law, strain, damage);
                prop_assert_eq!(value.to_bits(), pointwise.to_bits());
            }
        }

        /// The P1 path of the load assembly (one strain per cell, invariants once per cell)
        /// gives bitwise the point-by-point values, across batch boundaries and cells.
        #[test]
        fn expression_source_cells_is_bitwise_pointwise(
            cells in proptest::collection::vec(
                (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64,
                 -1.0..1.0f64), 1..60),
            damages in proptest::collection::vec(-2.0..2.0f64, 14),
            per_cell in 1..15usize,
        ) {
            let law = test_source();
            let strains: Vec<Tensor<3>> = cells
                .iter()
                .map(|&(a, b, c, d, e, f)| Tensor::<3>::new(a, b, c, b, d, e, c, e, f))
                .collect();
            let point_damages: Vec<f64> =
                (0..cells.len() * per_cell).map(|p| damages[p % 14]).collect();
            let mut values = vec![f64::NAN; point_damages.len()];
            DamageSource::<3>::source_cells(&law, &strains, &point_damages, &mut values);
            for (p, value) in values.iter().enumerate() {
                let pointwise =
                    DamageSource::<3>::source(&law, &strains[p / per_cell], point_damages[p]);
                prop_assert_eq!(value.to_bits(), pointwise.to_bits());
            }
        }
    }
}
