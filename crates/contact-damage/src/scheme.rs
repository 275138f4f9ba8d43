//! The fully discrete scheme, Problem P_V^hk (5.1)–(5.5): for n = 1, …, N, given u_{n−1} and
//! β_{n−1}, solve the velocity step (5.1) and the damage step (5.2) — concurrently, since both
//! depend only on step n−1 — then update u_n = u_{n−1} + k v_n (5.4)–(5.5). Initial data are
//! interpolated, u_0 = Π^h u0, β_0 = Π^h β0 (5.3), (5.30).

use crate::contact::{ContactNodes, ContactStatus};
use crate::damage::{DamageOperator, DamageSolution};
use crate::laws::{ContactLaw, DamageSource, Elasticity, Viscosity};
use crate::loads::LoadQuadrature;
use crate::mesh::{BoundaryPart, Mesh};
use crate::obstacle::{BoxQpSettings, BoxQpStats};
use crate::space::LagrangeSpace;
use crate::stability::{step_limit, StepLimit};
use crate::velocity::{
    ImplicitNormalCompliance, VelocityData, VelocityOperator, VelocitySettings, VelocitySolution,
    VelocityStats,
};
use crate::{Error, Result};
use nalgebra::SVector;
use std::sync::Arc;

pub use crate::fields::{BoundaryScalarField, BoundaryVectorField, ScalarField, VectorField};
/// A time-independent scalar field of x: g, β0.
pub type StaticScalarField<const D: usize> = Arc<dyn Fn(&[f64; D]) -> f64 + Send + Sync>;
/// A time-independent vector field of x: u0.
pub type StaticVectorField<const D: usize> = Arc<dyn Fn(&[f64; D]) -> [f64; D] + Send + Sync>;

/// The constitutive laws of Problem P (§2) and the damage diffusion κ of (2.2).
#[derive(Clone)]
pub struct Model<const D: usize> {
    /// 𝒜, acting on ε(u̇).
    pub viscosity: Arc<dyn Viscosity<D>>,
    /// G(ε(u), β).
    pub elasticity: Arc<dyn Elasticity<D>>,
    /// φ(ε(u), β).
    pub damage_source: Arc<dyn DamageSource<D>>,
    /// p_ν and p_τ.
    pub contact: Arc<dyn ContactLaw>,
    /// κ > 0.
    pub damage_diffusion: f64,
}

/// Loads, gap and initial data. Everything but the gap and the initial data is optional.
#[derive(Clone)]
pub struct Data<const D: usize> {
    /// Body force f0 (2.3).
    pub body_force: Option<VectorField<D>>,
    /// Traction f2 on Γ2 (2.6).
    pub traction: Option<BoundaryVectorField<D>>,
    /// Extra traction f3 on Γ3 (used by manufactured solutions, SPEC §4): adds ∫_Γ3 f3·w.
    pub contact_traction: Option<BoundaryVectorField<D>>,
    /// Extra damage supply q added to φ (manufactured solutions).
    pub damage_supply: Option<ScalarField<D>>,
    /// Damage flux κ ∂β/∂ν on Γ (zero in (2.4); nonzero for manufactured solutions).
    pub damage_flux: Option<BoundaryScalarField<D>>,
    /// Gap g ≥ 0 on Γ3, measured along the outward normal.
    pub gap: StaticScalarField<D>,
    /// u0 (must vanish on Γ1).
    pub initial_displacement: StaticVectorField<D>,
    /// β0 with values in [0, 1].
    pub initial_damage: StaticScalarField<D>,
}

/// Solver settings of both steps.
#[derive(Debug, Clone, Copy, Default)]
pub struct SchemeSettings {
    /// Velocity step (5.1).
    pub velocity: VelocitySettings,
    /// Damage step (5.2).
    pub damage: BoxQpSettings,
    /// Where the normal compliance of the velocity step is evaluated.
    pub contact: ContactTreatment,
    /// Whether the damage evolves by (5.2) or stays at β_0.
    pub damage_evolution: DamageEvolution,
}

/// Whether the damage step (5.2) is solved.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum DamageEvolution {
    /// β_n from the damage step (5.2) (the paper's model, the default).
    #[default]
    Parabolic,
    /// β_n = β_0 for every n and no damage step: a pure contact problem (with β_0 = 1, the
    /// viscoelastic body of §2 without damage). The damage laws are not used.
    Frozen,
}

/// Where the velocity step takes the normal compliance p_ν.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum ContactTreatment {
    /// At u_{n−1}, as in the paper's scheme (5.1) (the default, verified against Theorem 5.2).
    /// Stable only while k c_ν is small against the viscous stiffness.
    #[default]
    Explicit,
    /// At u_n = u_{n−1} + k v_n (the friction bound stays at u_{n−1}): a strongly monotone step
    /// solved exactly by generalized Newton, stable for any k (stiff contact).
    Implicit,
}

/// Problem P_V^hk: mesh, degree l, model, data, T and N.
#[derive(Clone)]
pub struct Problem<const D: usize> {
    /// The mesh 𝒯^h.
    pub mesh: Arc<Mesh<D>>,
    /// Polynomial degree l ∈ {1, 2} of X^h.
    pub degree: usize,
    /// Constitutive laws.
    pub model: Model<D>,
    /// Loads and initial data.
    pub data: Data<D>,
    /// Final time T > 0.
    pub final_time: f64,
    /// Number of time steps N ≥ 1 (k = T/N).
    pub steps: usize,
    /// Solver settings.
    pub settings: SchemeSettings,
}

/// The discrete state after step n.
#[derive(Debug, Clone)]
pub struct State {
    /// Step index n.
    pub step: usize,
    /// t_n = n k.
    pub time: f64,
    /// u_n, Cartesian node-major.
    pub displacement: Vec<f64>,
    /// v_n (zero for n = 0).
    pub velocity: Vec<f64>,
    /// β_n, nodal.
    pub damage: Vec<f64>,
}

/// What the observer sees after each step.
pub struct StepReport<'a, const D: usize> {
    /// The state after the step.
    pub state: &'a State,
    /// The finite element space of every field.
    pub space: &'a LagrangeSpace<D>,
    /// The contact nodes (order of `contact_status` and `multipliers`).
    pub contact: &'a ContactNodes<D>,
    /// Status of each contact node in the velocity step.
    pub contact_status: &'a [ContactStatus],
    /// Normal pressure p_ν per contact node used in the step.
    pub normal_pressure: &'a [f64],
    /// Friction bound p_τ per contact node used in the step.
    pub friction_bound: &'a [f64],
    /// Friction multipliers (D−1 per contact node).
    pub multipliers: &'a [f64],
    /// Velocity step statistics.
    pub velocity_stats: &'a VelocityStats,
    /// Damage step statistics.
    pub damage_stats: &'a BoxQpStats,
}

/// Totals over a run.
#[derive(Debug, Clone, Default)]
pub struct RunSummary {
    /// Steps done.
    pub steps: usize,
    /// Largest KKT residual of a velocity step.
    pub max_velocity_kkt: f64,
    /// Largest KKT residual of a damage step.
    pub max_damage_kkt: f64,
    /// Newton iterations of all velocity steps.
    pub velocity_newton_iterations: usize,
    /// Largest number of Newton iterations of one velocity step.
    pub max_velocity_newton_iterations: usize,
    /// The KKT residual history of the velocity step that took the most Newton iterations
    /// (the first such step).
    pub slowest_velocity_history: Vec<f64>,
    /// Semismooth Newton iterations of the friction problems.
    pub friction_iterations: usize,
    /// Active-set iterations of all damage steps.
    pub damage_iterations: usize,
    /// Numeric factorizations of the velocity operator.
    pub velocity_factorizations: usize,
    /// Numeric factorizations in the damage steps.
    pub damage_factorizations: usize,
    /// Steps in which some contact node was in each state (separated, stick, slip).
    pub steps_with_status: [usize; 3],
    /// Steps in which the lower / upper damage bound was active at some node.
    pub steps_with_damage_bound: [usize; 2],
}

/// Wall time spent so far in the parts of the steps (for benchmarks; a few clock reads per step).
#[derive(Debug, Clone, Copy, Default)]
pub struct StepTimings {
    /// Load vectors of (5.1) and (5.2), the data fields' evaluation included.
    pub loads: std::time::Duration,
    /// The velocity step (5.1) (concurrent with the damage step when threads are free).
    pub velocity: std::time::Duration,
    /// The damage step (5.2).
    pub damage: std::time::Duration,
}

/// A running simulation of Problem P_V^hk.
pub struct Simulation<const D: usize> {
    problem: Problem<D>,
    space: Arc<LagrangeSpace<D>>,
    contact: Arc<ContactNodes<D>>,
    velocity: VelocityOperator<D>,
    /// None when the damage is frozen ([`DamageEvolution::Frozen`]).
    damage: Option<DamageOperator<D>>,
    loads: LoadQuadrature<D>,
    gap: Vec<f64>,
    state: State,
    timings: StepTimings,
}

impl<const D: usize> Simulation<D> {
    /// Validates the problem, builds the spaces and operators (symbolic analyses), and sets the
    /// initial state u_0 = Π^h u0, β_0 = Π^h β0.
    pub fn new(problem: Problem<D>) -> Result<Self> {
        let model = &problem.model;
        model.viscosity.validate()?;
        model.elasticity.validate()?;
        if problem.settings.damage_evolution == DamageEvolution::Parabolic {
            model.damage_source.validate()?;
        }
        model.contact.validate()?;
        if !(problem.final_time.is_finite() && problem.final_time > 0.0) {
            return Err(Error::parameter(
                "final_time",
                problem.final_time,
                "T must be > 0",
            ));
        }
        if problem.steps == 0 {
            return Err(Error::parameter(
                "steps",
                0.0,
                "the number of time steps N must be ≥ 1",
            ));
        }
        let space = Arc::new(LagrangeSpace::new(problem.mesh.clone(), problem.degree)?);
        let contact = Arc::new(ContactNodes::new(&space)?);
        let velocity =
            VelocityOperator::new(space.clone(), model.viscosity.clone(), contact.clone())?;
        let time_step = problem.final_time / problem.steps as f64;
        let damage = match problem.settings.damage_evolution {
            DamageEvolution::Parabolic => Some(DamageOperator::new(
                space.clone(),
                model.damage_diffusion,
                time_step,
                problem.settings.damage,
            )?),
            DamageEvolution::Frozen => None,
        };
        let loads = LoadQuadrature::new(&space);
        let gap: Vec<f64> = contact
            .nodes
            .iter()
            .map(|&node| (problem.data.gap)(&space.node(node)))
            .collect();
        if let Some(k) = gap.iter().position(|g| !g.is_finite() || *g < 0.0) {
            return Err(Error::parameter(
                format!(
                    "gap at contact node {} {:?}",
                    contact.nodes[k],
                    space.node(contact.nodes[k])
                ),
                gap[k],
                "g must be finite and ≥ 0",
            ));
        }
        let displacement = space.interpolate_vector(|x| (problem.data.initial_displacement)(x));
        for node in space.boundary_nodes(BoundaryPart::Dirichlet) {
            let u = &displacement[node * D..node * D + D];
            if u.iter().any(|v| v.abs() > 1e-12) {
                return Err(Error::parameter(
                    format!(
                        "initial_displacement at clamped node {node} {:?}",
                        space.node(node)
                    ),
                    u.iter().fold(0.0f64, |m, v| m.max(v.abs())),
                    "u0 must vanish on Γ1 (2.5)",
                ));
            }
        }
        let damage_values = space.interpolate_scalar(|x| (problem.data.initial_damage)(x));
        if let Some(i) = damage_values.iter().position(|b| !(0.0..=1.0).contains(b)) {
            return Err(Error::parameter(
                format!("initial_damage at node {i} {:?}", space.node(i)),
                damage_values[i],
                "β0 must take values in [0, 1]",
            ));
        }
        if let Some(i) = displacement.iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite(format!(
                "initial displacement at node {}",
                i / D
            )));
        }
        let state = State {
            step: 0,
            time: 0.0,
            velocity: vec![0.0; displacement.len()],
            displacement,
            damage: damage_values,
        };
        Ok(Self {
            problem,
            space,
            contact,
            velocity,
            damage,
            loads,
            gap,
            state,
            timings: StepTimings::default(),
        })
    }

    /// Wall time spent so far in the loads and the two solves of the steps.
    pub fn timings(&self) -> &StepTimings {
        &self.timings
    }

    /// The current state.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// Replaces the current state (restart from saved fields).
    pub fn set_state(&mut self, state: State) -> Result<()> {
        let n = self.space.num_nodes();
        if state.displacement.len() != n * D
            || state.velocity.len() != n * D
            || state.damage.len() != n
        {
            return Err(Error::InvalidInput(
                "state does not match the finite element space".into(),
            ));
        }
        self.state = state;
        Ok(())
    }

    /// The finite element space.
    pub fn space(&self) -> &Arc<LagrangeSpace<D>> {
        &self.space
    }

    /// The contact nodes.
    pub fn contact(&self) -> &Arc<ContactNodes<D>> {
        &self.contact
    }

    /// The velocity operator (sizes, for reporting).
    pub fn velocity_operator(&self) -> &VelocityOperator<D> {
        &self.velocity
    }

    /// Time step k = T/N.
    pub fn time_step(&self) -> f64 {
        self.problem.final_time / self.problem.steps as f64
    }

    /// Number of steps N.
    pub fn steps(&self) -> usize {
        self.problem.steps
    }

    /// Loads of step n at t_n from the state n−1: the velocity load (Cartesian, node-major) and
    /// the damage source ⟨φ(ε(u_{n−1}), β_{n−1}) + q(t_n), φ_a⟩ + ∫_Γ κ∂β/∂ν φ_a.
    pub fn step_loads(&self, time: f64) -> (Vec<f64>, Vec<f64>) {
        self.loads.assemble(
            &self.space,
            &self.problem.model,
            &self.problem.data,
            time,
            &self.state,
        )
    }

    /// The step limit of the explicit terms of (5.1) at the current state ([`crate::stability`]):
    /// with the paper's explicit normal compliance the elastic and contact stiffness, with the
    /// implicit one the elastic stiffness only. A run with k above it is unstable.
    pub fn step_limit(&self) -> Result<StepLimit> {
        step_limit(
            &self.velocity,
            self.problem.model.elasticity.as_ref(),
            self.problem.model.contact.as_ref(),
            &self.penetrations(),
            self.problem.settings.contact == ContactTreatment::Explicit,
        )
    }

    /// Penetrations u_{n−1,ν}(a) − g(a) at the contact nodes.
    fn penetrations(&self) -> Vec<f64> {
        (0..self.contact.len())
            .map(|k| {
                let node = self.contact.nodes[k];
                let u = SVector::<f64, D>::from_column_slice(
                    &self.state.displacement[node * D..node * D + D],
                );
                u.dot(&self.contact.normal(k)) - self.gap[k]
            })
            .collect()
    }

    /// One step of the scheme: (5.1) and (5.2) concurrently, then (5.4)–(5.5).
    pub fn step(&mut self) -> Result<(VelocitySolution, DamageSolution, Vec<f64>, Vec<f64>)> {
        let n = self.state.step + 1;
        let time = n as f64 * self.time_step();
        let started = std::time::Instant::now();
        let (velocity_load, damage_source) = self.step_loads(time);
        self.timings.loads += started.elapsed();
        let penetrations = self.penetrations();
        let law = &self.problem.model.contact;
        let normal_pressure: Vec<f64> = penetrations
            .iter()
            .map(|&r| law.normal_pressure(r))
            .collect();
        let friction_bound: Vec<f64> = penetrations
            .iter()
            .map(|&r| law.friction_bound(r))
            .collect();
        let implicit = self.problem.settings.contact == ContactTreatment::Implicit;
        let data = VelocityData {
            load: &velocity_load,
            normal_pressure: &normal_pressure,
            friction_bound: &friction_bound,
            implicit_contact: implicit.then(|| ImplicitNormalCompliance {
                previous_penetration: penetrations,
                time_step: self.time_step(),
                law: law.clone(),
            }),
        };
        let settings = self.problem.settings.velocity;
        let previous_velocity = &self.state.velocity;
        let previous_damage = &self.state.damage;
        let velocity_op = &mut self.velocity;
        let damage_op = &mut self.damage;
        let ((velocity, velocity_time), (damage, damage_time)) = rayon::join(
            || {
                let started = std::time::Instant::now();
                let velocity = velocity_op.solve(&data, previous_velocity, &settings);
                (velocity, started.elapsed())
            },
            || {
                let started = std::time::Instant::now();
                let damage = match damage_op {
                    Some(operator) => operator.solve(&damage_source, previous_damage),
                    None => Ok(DamageSolution {
                        damage: previous_damage.clone(),
                        stats: BoxQpStats::default(),
                    }),
                };
                (damage, started.elapsed())
            },
        );
        self.timings.velocity += velocity_time;
        self.timings.damage += damage_time;
        let velocity = velocity?;
        let damage = damage?;
        let k = self.time_step();
        for (u, v) in self.state.displacement.iter_mut().zip(&velocity.velocity) {
            *u += k * v;
        }
        self.state.velocity.clone_from(&velocity.velocity);
        self.state.damage.clone_from(&damage.damage);
        self.state.step = n;
        self.state.time = time;
        // the pressure the step used: p_ν at u_{n−1} (5.1), or at u_n = u_{n−1} + k v_n
        let normal_pressure = if implicit {
            let law = &self.problem.model.contact;
            self.penetrations()
                .iter()
                .map(|&r| law.normal_pressure(r))
                .collect()
        } else {
            normal_pressure
        };
        Ok((velocity, damage, normal_pressure, friction_bound))
    }

    /// Runs the remaining steps up to N, calling `observer` after each.
    pub fn run(
        &mut self,
        mut observer: impl FnMut(&StepReport<'_, D>) -> Result<()>,
    ) -> Result<RunSummary> {
        let mut summary = RunSummary::default();
        while self.state.step < self.problem.steps {
            let (velocity, damage, normal_pressure, friction_bound) = self.step()?;
            summary.steps += 1;
            summary.max_velocity_kkt = summary.max_velocity_kkt.max(velocity.stats.kkt_residual);
            summary.max_damage_kkt = summary.max_damage_kkt.max(damage.stats.kkt_residual);
            summary.velocity_newton_iterations += velocity.stats.newton_iterations;
            if velocity.stats.newton_iterations > summary.max_velocity_newton_iterations {
                summary.max_velocity_newton_iterations = velocity.stats.newton_iterations;
                summary
                    .slowest_velocity_history
                    .clone_from(&velocity.stats.residual_history);
            }
            summary.friction_iterations += velocity.stats.friction_iterations;
            summary.damage_iterations += damage.stats.iterations;
            summary.velocity_factorizations += velocity.stats.factorizations;
            summary.damage_factorizations += damage.stats.factorizations;
            for (slot, status) in [
                ContactStatus::Separated,
                ContactStatus::Stick,
                ContactStatus::Slip,
            ]
            .iter()
            .enumerate()
            {
                if velocity.status.contains(status) {
                    summary.steps_with_status[slot] += 1;
                }
            }
            if damage.stats.lower_active > 0 {
                summary.steps_with_damage_bound[0] += 1;
            }
            if damage.stats.upper_active > 0 {
                summary.steps_with_damage_bound[1] += 1;
            }
            observer(&StepReport {
                state: &self.state,
                space: &self.space,
                contact: &self.contact,
                contact_status: &velocity.status,
                normal_pressure: &normal_pressure,
                friction_bound: &friction_bound,
                multipliers: &velocity.multipliers,
                velocity_stats: &velocity.stats,
                damage_stats: &damage.stats,
            })?;
        }
        Ok(summary)
    }
}
